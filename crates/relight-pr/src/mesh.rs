//! Meshing with substructuring (the paper's section 2.2, after Cohen et al.): the scene's
//! triangles are split by midpoint subdivision into **patches**, which shoot, and every
//! patch into four **elements**, which receive. Sizes come from the scene: a target
//! element count gives the target patch area (the scene's surface area over a quarter of
//! the count), and each triangle is subdivided until its patches are no larger. Counts are
//! known before anything is allocated and checked against a [`MeshBudget`].

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use scene_core::Scene;
use scene_core::lights::LightId;
use scene_core::ray::RayScene;

use crate::RelightError;

/// How finely to mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshSettings {
    /// The element count aimed at (the result is within a factor of about 4 of it, since
    /// each triangle's patches halve their edges at once). Default 4096.
    pub target_elements: usize,
    /// Limits checked before allocating.
    pub budget: MeshBudget,
    /// Extra subdivision levels for patches that straddle other geometry (a floor running
    /// under a wall, a box standing on a table): a patch whose centre cannot see its own
    /// corners and edge midpoints (just above its surface, by ray) is split again, up to
    /// this many levels, so that no element mixes light from both sides of a wall (parts
    /// inside a closed solid, such as the floor under a wall's slab, do not count). 0 turns
    /// it off. Default 6 (patch edges down to 1/64, and pieces no smaller than the
    /// target's patch area over `4^split_depth`: a triangle already far below the element
    /// size asked for is not split further).
    pub split_depth: u32,
    /// Merge coplanar triangles first ([`crate::merge::merge_coplanar`]), so that a flat
    /// wall cut into a fine grid by its modeller meshes like one polygon. Default true.
    pub merge_coplanar: bool,
    /// Hold the element budget: where the meshing made more than 1.25 x
    /// `target_elements` mesh elements (a file's small triangles, one element each at the
    /// least; the pieces split at walls; the factor of up to 4 of the uniform
    /// subdivision), they are clustered into at most [`BUDGET_SLACK`] x `target_elements`
    /// groups ([`ElementGroups`]), and the solution, the relight and the export hold one
    /// value per group. The mesh elements stay as the geometry that the display draws and the
    /// per-pixel direct light gathers on. Default true; false keeps one value per mesh
    /// element, whatever their number.
    pub hold_budget: bool,
}

impl MeshSettings {
    /// Default settings aiming at `target_elements` elements.
    pub fn elements(target_elements: usize) -> Self {
        Self {
            target_elements,
            ..Default::default()
        }
    }
}

impl Default for MeshSettings {
    fn default() -> Self {
        Self {
            target_elements: 4096,
            budget: MeshBudget::default(),
            split_depth: 6,
            merge_coplanar: true,
            hold_budget: true,
        }
    }
}

/// Limits of a meshing and of the solution it will hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshBudget {
    /// Most elements. Default 2^22.
    pub max_elements: usize,
    /// Most bytes of the k x n solution (direct, indirect and unshot energy per element
    /// and light). Default 4 GiB.
    pub max_solution_bytes: u64,
}

impl Default for MeshBudget {
    fn default() -> Self {
        Self {
            max_elements: 1 << 22,
            max_solution_bytes: 4 << 30,
        }
    }
}

/// One receiving element: a triangle of a patch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Element {
    /// Corners, counter-clockwise as the source triangle.
    pub corners: [Vec3; 3],
    /// Centroid: where the element receives.
    pub centroid: Vec3,
    /// Unit normal of the side that receives and reflects (the scene's shading normal at
    /// the centroid; the winding's normal where the scene has none).
    pub normal: Vec3,
    /// Area.
    pub area: f32,
    /// Albedo averaged over the element (the texture sampled at four points), times its
    /// [`Element::coverage`]: an alpha-masked element reflects from its solid part only.
    pub albedo: Vec3,
    /// The fraction of the element that exists (1 unless its material is alpha-masked,
    /// [`scene_core::Material::alpha_cutoff`]; from 64 samples otherwise). Rays pass
    /// through its holes; the element keeps its whole area, reflecting `coverage` of what
    /// it receives, which is the power its solid part reflects.
    pub coverage: f32,
    /// Emitted radiance (zero for non-emitters): its patch's mean over the patch's whole
    /// area, where the holes of an alpha mask count as black, so that the patch's area times
    /// it is the power its solid part emits. What a viewer sees on the solid part is
    /// [`Meshing::seen_emission`].
    pub emission: Vec3,
    /// The patch it belongs to.
    pub patch: u32,
    /// Global id of the scene triangle it was cut from (with coplanar triangles merged,
    /// [`MeshSettings::merge_coplanar`], one of the scene triangles of its flat region:
    /// [`crate::merge::Merged::origin`]).
    pub source_triangle: u32,
    /// The scene material of that triangle.
    pub material: u32,
    /// Texture coordinates of the corners, when the scene triangle has them.
    pub uvs: Option<[Vec2; 3]>,
    /// Vertex colours at the corners, when the scene triangle's mesh has them.
    pub colors: Option<[Vec3; 3]>,
    /// Pressed against or inside other geometry (the floor under a box, the bottom of a
    /// box resting on it): its centroid, just off its surface, is inside a solid or lifts
    /// through another surface. It receives nothing from outside, does not reflect onto
    /// its patch (which shoots from its open part only), and the display leaves it out of
    /// vertex averages. An element is hidden when all four of its receiver points are.
    pub hidden: bool,
    /// Which of its four receiver points ([`Element::receiver_points`]) are open (bit `r`
    /// for point `r`): an element partly under a box receives as the mean over its open
    /// points, not as if the covered ones were dark.
    pub open_points: u8,
}

/// A point uniform over the triangle `corners`, from a point `u` of the unit square (what
/// [`Element::uniform_point`] and the hierarchy's leaves and clipped pieces draw).
pub(crate) fn uniform_point_on(corners: &[Vec3; 3], u: Vec2) -> Vec3 {
    let t = scene_core::sampling::uniform_triangle(u);
    corners[0] * (1.0 - t.x - t.y) + corners[1] * t.x + corners[2] * t.y
}

impl Element {
    /// A point uniform over the element, from a point `u` of the unit square.
    pub fn uniform_point(&self, u: Vec2) -> Vec3 {
        uniform_point_on(&self.corners, u)
    }

    /// The unit normal of the element's own plane (its corners' winding), turned to the
    /// side of its shading normal ([`Element::normal`], which tilts away from the plane
    /// where the scene's normals are not the faces': a non-planar quad such as the Cornell
    /// box's red wall, a smooth mesh); the shading normal where the corners span no plane
    /// or the two are perpendicular. A pixel's footprint lies on this plane.
    pub fn plane_normal(&self) -> Vec3 {
        let [a, b, c] = self.corners;
        let g = (b - a).cross(c - a).normalize_or_zero();
        match g.dot(self.normal) {
            d if d > 0.0 => g,
            d if d < 0.0 => -g,
            _ => self.normal,
        }
    }

    /// Where the element receives: the centroids of its four midpoint-subdivision
    /// children, equal weights (exact for irradiance that varies linearly over it). Four
    /// points instead of the centroid alone make an element's value its average, which
    /// matters where irradiance changes fast (a point light near a wall).
    pub fn receiver_points(&self) -> [Vec3; 4] {
        let [a, b, c] = self.corners;
        [
            (a * 4.0 + b + c) / 6.0,
            (a + b * 4.0 + c) / 6.0,
            (a + b + c * 4.0) / 6.0,
            self.centroid,
        ]
    }

    /// The receiver points that are open (not inside or pressed against other geometry),
    /// with their index among the four, and how many there are.
    pub fn open_receiver_points(&self) -> ([(usize, Vec3); 4], usize) {
        let mut out = [(0, Vec3::ZERO); 4];
        let mut count = 0;
        for (r, x) in self.receiver_points().into_iter().enumerate() {
            if self.open_points & (1 << r) != 0 {
                out[count] = (r, x);
                count += 1;
            }
        }
        (out, count)
    }
}

/// One shooting patch: four consecutive elements, or one where the scene triangle is
/// itself no larger than an element (a book's face in a room meshed at metre-sized
/// elements: cutting it in four would only multiply the receivers).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    /// Corners.
    pub corners: [Vec3; 3],
    /// Unit normal of its emitting side.
    pub normal: Vec3,
    /// Area.
    pub area: f32,
    /// First of its elements.
    pub first_element: u32,
    /// How many consecutive elements it has: 4, or 1 for a triangle no larger than an
    /// element.
    pub element_count: u32,
    /// The area of its elements that are not hidden ([`Element::hidden`]): what reflects.
    pub open_area: f32,
    /// The emissive mesh whose light it emits, if it emits.
    pub light: Option<LightId>,
}

/// A scene meshed into patches and elements.
#[derive(Clone, Debug, PartialEq)]
pub struct Meshing {
    /// Receiving elements, four per patch, in patch order.
    pub elements: Vec<Element>,
    /// Shooting patches.
    pub patches: Vec<Patch>,
    /// The target patch area used.
    pub patch_area: f32,
    /// Scene triangles skipped as degenerate (zero or non-finite area).
    pub skipped_triangles: usize,
    /// Patches split again because they straddled other geometry
    /// ([`MeshSettings::split_depth`]).
    pub split_patches: usize,
    /// What merging coplanar triangles did ([`MeshSettings::merge_coplanar`]), when on.
    pub merge: Option<crate::merge::MergeStats>,
    /// The solution's elements: which group each mesh element's value is held in
    /// ([`MeshSettings::hold_budget`]); one group per mesh element when the budget did
    /// not need them.
    pub groups: ElementGroups,
}

/// The most solution elements per element asked for ([`MeshSettings::hold_budget`]): a
/// meshing within it is kept one value per mesh element; a grouping aims at the target and
/// may reach this only to split groups that would reach through a wall.
pub const BUDGET_SLACK: f64 = 1.25;

/// The elements a solution holds values for, as groups of mesh elements
/// ([`MeshSettings::hold_budget`]). The groups are a cut through the hierarchical
/// solve's cluster tree (grouped by orientation, then in space; a floor running under a
/// wall is split at the wall): each is a patch of surface about one target element in
/// area, facing one way. A group's value is the area-weighted mean of its open mesh
/// elements' values ([`ElementGroups::reduce`]); hidden mesh elements and those of no
/// area share one group of their own, whose value is the mean of theirs (zero: they
/// receive nothing).
#[derive(Clone, Debug, PartialEq)]
pub struct ElementGroups {
    /// The group of each mesh element.
    pub of_element: Vec<u32>,
    /// Number of groups: the solution's element count.
    pub count: usize,
}

impl ElementGroups {
    /// One group per mesh element.
    pub fn identity(elements: usize) -> Self {
        Self {
            of_element: (0..elements as u32).collect(),
            count: elements,
        }
    }

    /// Whether every mesh element is a group of its own, in order.
    pub fn is_identity(&self) -> bool {
        self.count == self.of_element.len()
            && self
                .of_element
                .iter()
                .enumerate()
                .all(|(j, &g)| g == j as u32)
    }

    /// The group of mesh element `j`.
    pub fn of(&self, j: usize) -> usize {
        self.of_element[j] as usize
    }

    /// Per group and source, the area-weighted mean of `values` (per mesh element and
    /// source, element-major `j * k + m`) over the group's open mesh elements (over all of
    /// them where none is open; zero where they have no area).
    pub fn reduce(&self, elements: &[Element], values: &[Vec3], k: usize) -> Vec<Vec3> {
        let mut sum = vec![Vec3::ZERO; self.count * k];
        let mut weight = vec![[0.0f64; 2]; self.count];
        // An element's area where finite and positive, else 0.
        let area = |e: &Element| {
            if e.area.is_finite() {
                e.area.max(0.0)
            } else {
                0.0
            }
        };
        for (j, e) in elements.iter().enumerate() {
            weight[self.of(j)][usize::from(e.hidden)] += area(e) as f64;
        }
        for (j, e) in elements.iter().enumerate() {
            let g = self.of(j);
            let area = area(e);
            let [open, hidden] = weight[g];
            let w = match (e.hidden, open > 0.0) {
                (false, _) => area as f64 / open,
                (true, false) if hidden > 0.0 => area as f64 / hidden,
                _ => 0.0,
            };
            if w > 0.0 {
                for m in 0..k {
                    sum[g * k + m] += values[j * k + m] * w as f32;
                }
            }
        }
        sum
    }

    /// Groups `meshing`'s elements to at most `target` when there are more than 1.25 x
    /// `target` ([`MeshSettings::hold_budget`]); one per element otherwise.
    fn for_meshing(meshing: &Meshing, rays: Option<&RayScene>, target: usize) -> Self {
        let n = meshing.elements.len();
        if (n as f64) <= BUDGET_SLACK * target as f64 {
            return Self::identity(n);
        }
        // The hidden elements' group counts against the target too.
        let outside = meshing
            .elements
            .iter()
            .any(|e| e.hidden || !(e.area.is_finite() && e.area > 0.0));
        let cut = target.saturating_sub(usize::from(outside)).max(1);
        let cap = ((target as f64 * BUDGET_SLACK) as usize).saturating_sub(usize::from(outside));
        let (mut of_element, mut count) =
            crate::hierarchical::budget_cut(meshing, rays, cut, cap.max(cut));
        if of_element.contains(&u32::MAX) {
            for g in of_element.iter_mut().filter(|g| **g == u32::MAX) {
                *g = count as u32;
            }
            count += 1;
        }
        Self { of_element, count }
    }
}

/// A triangle of the subdivision, with the barycentric coordinates of its corners in its
/// scene triangle.
#[derive(Clone, Copy)]
struct Piece {
    bary: [Vec2; 3],
}

impl Piece {
    fn children(&self) -> [Piece; 4] {
        let [a, b, c] = self.bary;
        let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
        [
            Piece { bary: [a, ab, ca] },
            Piece { bary: [ab, b, bc] },
            Piece { bary: [ca, bc, c] },
            Piece { bary: [ab, bc, ca] },
        ]
    }
}

/// The subdivision level of a triangle of `area` for patches of at most `patch_area`
/// (with a relative slack of 1e-4, so that rounding in a scaled copy of the scene does not
/// change the level of a triangle whose area is right at a boundary).
fn level(area: f32, patch_area: f32) -> u32 {
    let mut l = 0;
    let mut a = area;
    while a > patch_area * (1.0 + 1e-4) && l < 12 {
        a *= 0.25;
        l += 1;
    }
    l
}

/// Whether `x` (on a surface with unit normal `n`) lies inside a solid: of five rays, one
/// along `n` and four tilted 60 degrees from it, at least three see the back of the first
/// surface they meet. A floor point under a pillar that runs up to the ceiling without a cap
/// is inside (the four tilted rays meet the pillar's sides from within), a point in a room
/// is not (every ray meets a surface's front or escapes).
fn inside_solid(rays: &RayScene, face_normals: &[Vec3], x: Vec3, n: Vec3) -> bool {
    let (t, b) = n.any_orthonormal_pair();
    let (s, c) = (60f32.to_radians().sin(), 60f32.to_radians().cos());
    let dirs = [
        n,
        n * c + t * s,
        n * c - t * s,
        n * c + b * s,
        n * c - b * s,
    ];
    dirs.iter()
        .filter(|&&d| {
            rays.closest_hit(x, d, 0.0, f32::MAX)
                .is_some_and(|h| face_normals[h.triangle as usize].dot(d) > 0.0)
        })
        .count()
        >= 3
}

/// Whether a patch with corners `c` (unit normal `n`) straddles other geometry so that its
/// parts lie on two sides of it: of seven points (its centre, and its corners and edge
/// midpoints pulled 2 % towards the centre), each lifted by `lift` along `n`, those not
/// inside a solid ([`inside_solid`]) and not lifted through another surface are taken, and the patch straddles when the segment
/// between two of them is blocked: a patch whose part runs under a wall's slab is
/// therefore not split for the part inside the slab, only when it reaches the far side.
/// `face_normals` are the scene's triangles' winding normals by global id.
fn straddles(rays: &RayScene, face_normals: &[Vec3], c: [Vec3; 3], n: Vec3, lift: f32) -> bool {
    let centre = (c[0] + c[1] + c[2]) / 3.0;
    let mut points = [Vec3::ZERO; 7];
    let mut kept = 0;
    for q in [
        centre,
        c[0],
        c[1],
        c[2],
        (c[0] + c[1]) * 0.5,
        (c[1] + c[2]) * 0.5,
        (c[2] + c[0]) * 0.5,
    ] {
        let on = centre + (q - centre) * 0.98;
        let x = on + n * lift;
        // A point whose lift crosses another surface touches it (a sphere resting on the
        // floor): it is in neither region.
        let touching = rays.occluded(on, n, 0.01 * lift, lift);
        let inside = touching || inside_solid(rays, face_normals, x, n);
        if !inside {
            points[kept] = x;
            kept += 1;
        }
    }
    let points = &points[..kept];
    points.iter().enumerate().any(|(i, &a)| {
        points[i + 1..]
            .iter()
            .any(|&b| crate::visibility::segment_blocked(rays, a, b))
    })
}

impl Meshing {
    /// The radiance element `j`'s emitter shows where it exists: its
    /// [`Element::emission`] over its patch's mean [`Element::coverage`] (the same value
    /// but for an alpha-masked emitter, whose holes the emission counts as black and which
    /// is not drawn where they are).
    pub fn seen_emission(&self, j: usize) -> Vec3 {
        let e = &self.elements[j];
        if e.coverage >= 1.0 {
            return e.emission;
        }
        let p = &self.patches[e.patch as usize];
        let first = p.first_element as usize;
        let els = &self.elements[first..first + p.element_count as usize];
        let mean = els.iter().map(|x| x.coverage).sum::<f32>() / els.len().max(1) as f32;
        if mean > 0.0 {
            e.emission / mean
        } else {
            Vec3::ZERO
        }
    }

    /// Meshes `scene` (which should be validated). Errors with [`RelightError::Budget`]
    /// before allocating when the element count or a `lights`-light solution would exceed
    /// `settings.budget`. Builds the scene's rays (for the splits at walls and the hidden
    /// elements); a caller that has them already uses [`Meshing::with_rays`].
    pub fn new(
        scene: &Scene,
        settings: &MeshSettings,
        lights: usize,
    ) -> Result<Self, RelightError> {
        Self::with_rays(scene, settings, lights, &RayScene::build(scene))
    }

    /// [`Meshing::new`] with the scene's rays already built (`rays` from `scene`; the
    /// solver needs the same).
    pub fn with_rays(
        scene: &Scene,
        settings: &MeshSettings,
        lights: usize,
        rays: &RayScene,
    ) -> Result<Self, RelightError> {
        if settings.target_elements < 4 {
            return Err(RelightError::InvalidSetting(format!(
                "target_elements = {}: at least 4 (one patch)",
                settings.target_elements
            )));
        }
        // Coplanar triangles merged first; the rays and the face normals stay those of the
        // input scene (same surfaces).
        let merged = settings
            .merge_coplanar
            .then(|| crate::merge::merge_coplanar(scene));
        let source = merged.as_ref().map_or(scene, |m| &m.scene);
        let mut areas = Vec::with_capacity(source.triangle_count());
        for mesh in &source.meshes {
            for t in &mesh.indices {
                let p = t.map(|i| mesh.positions[i as usize]);
                areas.push(0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length());
            }
        }
        let total: f64 = areas
            .iter()
            .filter(|a| a.is_finite() && **a > 0.0)
            .map(|&a| a as f64)
            .sum();
        let patch_area =
            (total / (settings.target_elements as f64 / 4.0)).max(f64::MIN_POSITIVE) as f32;
        // A whole triangle (level 0) no larger than an element is a patch of one element;
        // pieces cut from a triangle, by the uniform subdivision or at walls, have four.
        let elements_per = |piece_area: f32, level: u32| -> u64 {
            if level == 0 && piece_area <= patch_area * 0.25 * (1.0 + 1e-4) {
                1
            } else {
                4
            }
        };
        // Count before allocating: the uniform subdivision first.
        let (mut count, mut patch_count) = (0u64, 0u64);
        for &a in &areas {
            if a.is_finite() && a > 0.0 {
                let l = level(a, patch_area);
                let pieces = 4u64.pow(l);
                count += pieces * elements_per(a / pieces as f32, l);
                patch_count += pieces;
            }
        }
        let budget = &settings.budget;
        let over = |count: u64| {
            RelightError::Budget(scene_core::BudgetExceeded {
                what: "the meshing".into(),
                needed: count,
                limit: budget.max_elements as u64,
                unit: "elements",
                hint: "MeshBudget::max_elements".into(),
            })
        };
        if count > budget.max_elements as u64 {
            return Err(over(count));
        }
        // The patches of each triangle: its uniform pieces, those that straddle other
        // geometry split again. Every split is counted before it is kept.
        let rays = (count > 0).then_some(rays);
        let face_normals: Vec<Vec3> = match rays {
            Some(_) => scene
                .meshes
                .iter()
                .flat_map(|m| {
                    m.indices.iter().map(|t| {
                        let p = t.map(|i| m.positions[i as usize]);
                        (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero()
                    })
                })
                .collect(),
            None => Vec::new(),
        };
        let lift = 1e-4 * scene.extent();
        // The finest split is relative to the target's patch size, not to the triangle's: a
        // chair's 1 cm triangle on the floor stays whole instead of splitting into 4^6
        // pieces far below the element size asked for.
        let finest = patch_area / 4f32.powi(settings.split_depth as i32) * (1.0 + 1e-4);
        let mut leaves: Vec<(u32, Piece, u32)> = Vec::new();
        let mut split_patches = 0usize;
        let mut global = 0u32;
        for mesh in &source.meshes {
            for t in &mesh.indices {
                let id = global;
                global += 1;
                let area = areas[id as usize];
                if !(area.is_finite() && area > 0.0) {
                    continue;
                }
                let p = t.map(|i| mesh.positions[i as usize]);
                let geometric = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
                let at = |b: Vec2| p[0] * (1.0 - b.x - b.y) + p[1] * b.x + p[2] * b.y;
                let base = level(area, patch_area);
                let mut stack = vec![(
                    Piece {
                        bary: [Vec2::ZERO, Vec2::X, Vec2::Y],
                    },
                    0u32,
                )];
                while let Some((piece, l)) = stack.pop() {
                    if l < base {
                        stack.extend(piece.children().map(|c| (c, l + 1)));
                        continue;
                    }
                    let piece_area = area / 4f32.powi(l as i32);
                    let straddles = rays.as_ref().is_some_and(|r| {
                        l < base + settings.split_depth
                            && piece_area > finest
                            && straddles(r, &face_normals, piece.bary.map(at), geometric, lift)
                    });
                    if straddles {
                        count += 16 - elements_per(piece_area, l);
                        patch_count += 3;
                        if count > budget.max_elements as u64 {
                            return Err(over(count));
                        }
                        split_patches += 1;
                        stack.extend(piece.children().map(|c| (c, l + 1)));
                    } else {
                        leaves.push((id, piece, l));
                    }
                }
            }
        }
        let bytes =
            crate::solver::solution_bytes(count as usize, patch_count as usize, lights.max(1));
        if bytes > budget.max_solution_bytes {
            return Err(RelightError::Budget(scene_core::BudgetExceeded {
                what: format!("a {lights}-light solution over {count} elements"),
                needed: bytes,
                limit: budget.max_solution_bytes,
                unit: "bytes",
                hint: "MeshBudget::max_solution_bytes".into(),
            }));
        }
        // Where each triangle starts: its mesh and index within it.
        let mut owner = Vec::with_capacity(areas.len());
        for (mi, mesh) in source.meshes.iter().enumerate() {
            for ti in 0..mesh.indices.len() {
                owner.push((mi, ti));
            }
        }
        let skipped = areas
            .iter()
            .filter(|a| !(a.is_finite() && **a > 0.0))
            .count();
        let mut elements = Vec::with_capacity(count as usize);
        let mut patches = Vec::with_capacity(patch_count as usize);
        for (id, piece, l) in leaves {
            let (mi, ti) = owner[id as usize];
            let mesh = &source.meshes[mi];
            let t = mesh.indices[ti];
            let area = areas[id as usize];
            let p = t.map(|i| mesh.positions[i as usize]);
            let geometric = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            let ns = t.map(|i| mesh.normals.get(i as usize).copied().unwrap_or(geometric));
            let uvs = mesh.uvs.as_ref().map(|uv| t.map(|i| uv[i as usize]));
            let material = mesh.material_ids[ti];
            let factor = source.materials[material as usize].emission;
            let light = (factor.max_element() > 0.0).then_some(LightId::Emissive(mi as u32));
            let at = |b: Vec2| p[0] * (1.0 - b.x - b.y) + p[1] * b.x + p[2] * b.y;
            let normal_at = |b: Vec2| {
                let n = ns[0] * (1.0 - b.x - b.y) + ns[1] * b.x + ns[2] * b.y;
                let n = n.normalize_or_zero();
                if n == Vec3::ZERO { geometric } else { n }
            };
            let uv_of = |b: Vec2| uvs.map(|q| q[0] * (1.0 - b.x - b.y) + q[1] * b.x + q[2] * b.y);
            let colors = mesh.colors.as_ref().map(|c| t.map(|i| c[i as usize]));
            let color_of =
                |b: Vec2| colors.map(|c| c[0] * (1.0 - b.x - b.y) + c[1] * b.x + c[2] * b.y);
            let albedo_at =
                |b: Vec2| source.albedo_at(material, uv_of(b)) * color_of(b).unwrap_or(Vec3::ONE);
            let textured = source.materials[material as usize]
                .emission_texture
                .is_some()
                && uvs.is_some();
            let masked = source.materials[material as usize].is_masked();
            let patch_area = area / 4f32.powi(l as i32);
            let one = elements_per(patch_area, l) == 1;
            let pieces: &[Piece] = if one { &[piece] } else { &piece.children() };
            // Each element's share that exists under an alpha mask and, for a masked
            // emitter, its mean emission with the holes black: one pass over the same 64
            // samples (the centroids `cutout::coverage` counts).
            let masked_emitter = masked && light.is_some();
            let per_element: Vec<(f32, Vec3)> = pieces
                .iter()
                .map(|e| {
                    if !masked {
                        return (1.0, Vec3::ZERO);
                    }
                    let (mut solid, mut glow) = (0u32, Vec3::ZERO);
                    for b in scene_core::cutout::triangle_samples(8) {
                        let b = e.bary[0] * (1.0 - b.x - b.y) + e.bary[1] * b.x + e.bary[2] * b.y;
                        if !source.opaque_at(material, uv_of(b)) {
                            continue;
                        }
                        solid += 1;
                        if masked_emitter {
                            glow += if textured {
                                source.emission_at(material, uv_of(b))
                            } else {
                                factor
                            };
                        }
                    }
                    (solid as f32 / 64.0, glow / 64.0)
                })
                .collect();
            // The patch's emission: the factor, or with an emission texture its mean over the
            // patch (64 samples), shared by the patch's elements (the solver shoots a patch's
            // emission as one). An alpha mask's holes emit nothing (as in the reference): a
            // masked emitter's mean counts them as black (over its elements' own samples, so
            // that it is the radiance seen times their mean coverage exactly,
            // [`Meshing::seen_emission`]), and the patch, which keeps its whole area, emits
            // the power of its solid part (its albedo is scaled alike).
            let emission = if masked_emitter {
                per_element.iter().map(|(_, g)| *g).sum::<Vec3>() / pieces.len() as f32
            } else if textured {
                scene_core::cutout::triangle_samples(8)
                    .map(|b| {
                        let b = piece.bary[0] * (1.0 - b.x - b.y)
                            + piece.bary[1] * b.x
                            + piece.bary[2] * b.y;
                        source.emission_at(material, uv_of(b))
                    })
                    .sum::<Vec3>()
                    / 64.0
            } else {
                factor
            };
            let source_triangle = merged.as_ref().map_or(id, |m| m.origin[id as usize]);
            let centre = (piece.bary[0] + piece.bary[1] + piece.bary[2]) / 3.0;
            patches.push(Patch {
                corners: piece.bary.map(at),
                normal: normal_at(centre),
                area: patch_area,
                first_element: elements.len() as u32,
                element_count: if one { 1 } else { 4 },
                open_area: 0.0,
                light,
            });
            let patch = patches.len() as u32 - 1;
            let element_area = patch_area / pieces.len() as f32;
            for (e, &(coverage, _)) in pieces.iter().zip(&per_element) {
                let c = (e.bary[0] + e.bary[1] + e.bary[2]) / 3.0;
                // Four albedo samples: the centroid and the midpoints towards each corner.
                let albedo = (albedo_at(c)
                    + e.bary
                        .iter()
                        .map(|&v| albedo_at((c + v) * 0.5))
                        .sum::<Vec3>())
                    * (0.25 * coverage);
                let corner_uvs = uvs.map(|_| e.bary.map(|b| uv_of(b).unwrap_or_default()));
                let corner_colors =
                    colors.map(|_| e.bary.map(|b| color_of(b).unwrap_or(Vec3::ONE)));
                elements.push(Element {
                    corners: e.bary.map(at),
                    centroid: at(c),
                    normal: normal_at(c),
                    area: element_area,
                    albedo,
                    coverage,
                    emission,
                    patch,
                    source_triangle,
                    material,
                    uvs: corner_uvs,
                    colors: corner_colors,
                    hidden: false,
                    open_points: 0b1111,
                });
            }
        }
        // Hidden elements, and the open area of each patch.
        if let Some(r) = rays.as_ref() {
            let open: Vec<u8> = elements
                .par_iter()
                .map(|e| {
                    let n = e.normal;
                    let mut mask = 0u8;
                    for (i, x) in e.receiver_points().into_iter().enumerate() {
                        let covered = r.occluded(x, n, 0.01 * lift, lift)
                            || inside_solid(r, &face_normals, x + n * lift, n);
                        if !covered {
                            mask |= 1 << i;
                        }
                    }
                    mask
                })
                .collect();
            for (e, mask) in elements.iter_mut().zip(open) {
                e.open_points = mask;
                e.hidden = mask == 0;
            }
        }
        for p in patches.iter_mut() {
            let first = p.first_element as usize;
            p.open_area = elements[first..first + p.element_count as usize]
                .iter()
                .filter(|e| !e.hidden)
                .map(|e| e.area)
                .sum();
        }
        let count = elements.len();
        let mut meshing = Self {
            elements,
            patches,
            patch_area,
            skipped_triangles: skipped,
            split_patches,
            merge: merged.map(|m| m.stats),
            groups: ElementGroups::identity(count),
        };
        if settings.hold_budget {
            meshing.groups = ElementGroups::for_meshing(&meshing, rays, settings.target_elements);
        }
        Ok(meshing)
    }

    /// The elements as a scene of their own (one mesh, element `j` is triangle `j`, the
    /// scene's materials and textures, the corners' vertex colours, flat element normals): what a G-buffer renderer
    /// draws so that its triangle ids are element ids.
    pub fn element_scene(&self, scene: &Scene) -> Scene {
        let mut mesh = scene_core::Mesh {
            name: "elements".into(),
            ..Default::default()
        };
        let textured = self.elements.iter().any(|e| e.uvs.is_some());
        let coloured = self.elements.iter().any(|e| e.colors.is_some());
        let mut uvs = Vec::new();
        let mut colors = Vec::new();
        for (j, e) in self.elements.iter().enumerate() {
            mesh.positions.extend_from_slice(&e.corners);
            mesh.normals.extend_from_slice(&[e.normal; 3]);
            if textured {
                uvs.extend_from_slice(&e.uvs.unwrap_or([Vec2::ZERO; 3]));
            }
            if coloured {
                colors.extend_from_slice(&e.colors.unwrap_or([Vec3::ONE; 3]));
            }
            let b = 3 * j as u32;
            mesh.indices.push([b, b + 1, b + 2]);
            mesh.material_ids.push(e.material);
        }
        if textured {
            mesh.uvs = Some(uvs);
        }
        if coloured {
            mesh.colors = Some(colors);
        }
        let mut out = Scene::new(&format!("{} (elements)", scene.name));
        out.materials = scene.materials.clone();
        out.textures = scene.textures.clone();
        out.cameras = scene.cameras.clone();
        out.meshes.push(mesh);
        out
    }

    /// Where mesh element `j`'s value lies in per-element values of length `len`: at `j`
    /// when they hold one per mesh element, at its group ([`Meshing::groups`]) when they
    /// hold one per solution element.
    pub fn slot(&self, j: usize, len: usize) -> usize {
        if len == self.elements.len() {
            j
        } else {
            debug_assert_eq!(len, self.groups.count, "values of neither kind");
            self.groups.of(j)
        }
    }

    /// Every element's own plane ([`Element::plane_normal`]), where a pixel's footprint
    /// lies for the per-pixel and the shadow-mapped direct light.
    pub fn plane_normals(&self) -> Vec<Vec3> {
        self.elements.iter().map(Element::plane_normal).collect()
    }

    /// The elements of patch `p`.
    pub fn elements_of(&self, p: usize) -> &[Element] {
        let patch = &self.patches[p];
        let first = patch.first_element as usize;
        &self.elements[first..first + patch.element_count as usize]
    }
}
