//! Meshing with substructuring (the paper's section 2.2, after Cohen et al.): the scene's
//! triangles are split by midpoint subdivision into **patches**, which shoot, and every
//! patch into four **elements**, which receive. Sizes come from the scene: a target
//! element count gives the target patch area (the scene's surface area over a quarter of
//! the count), and each triangle is subdivided until its patches are no larger. Counts are
//! known before anything is allocated and checked against a [`MeshBudget`].

use glam::{Vec2, Vec3};
use scene_core::Scene;
use scene_core::lights::LightId;

use crate::RelightError;

/// How finely to mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshSettings {
    /// The element count aimed at (the result is within a factor of about 4 of it, since
    /// each triangle's patches halve their edges at once). Default 4096.
    pub target_elements: usize,
    /// Limits checked before allocating.
    pub budget: MeshBudget,
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
    /// Albedo averaged over the element (the texture sampled at four points).
    pub albedo: Vec3,
    /// Emitted radiance (zero for non-emitters).
    pub emission: Vec3,
    /// The patch it belongs to.
    pub patch: u32,
    /// Global id of the scene triangle it was cut from.
    pub source_triangle: u32,
    /// The scene material of that triangle.
    pub material: u32,
    /// Texture coordinates of the corners, when the scene triangle has them.
    pub uvs: Option<[Vec2; 3]>,
}

impl Element {
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
}

/// One shooting patch: four consecutive elements.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    /// Corners.
    pub corners: [Vec3; 3],
    /// Unit normal of its emitting side.
    pub normal: Vec3,
    /// Area.
    pub area: f32,
    /// First of its four elements.
    pub first_element: u32,
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

impl Meshing {
    /// Meshes `scene` (which should be validated). Errors with [`RelightError::Budget`]
    /// before allocating when the element count or a `lights`-light solution would exceed
    /// `settings.budget`.
    pub fn new(
        scene: &Scene,
        settings: &MeshSettings,
        lights: usize,
    ) -> Result<Self, RelightError> {
        if settings.target_elements < 4 {
            return Err(RelightError::InvalidSetting(format!(
                "target_elements = {}: at least 4 (one patch)",
                settings.target_elements
            )));
        }
        let mut areas = Vec::with_capacity(scene.triangle_count());
        for mesh in &scene.meshes {
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
        // Count before allocating.
        let mut count: u64 = 0;
        for &a in &areas {
            if a.is_finite() && a > 0.0 {
                count += 4u64 * 4u64.pow(level(a, patch_area));
            }
        }
        let budget = &settings.budget;
        if count > budget.max_elements as u64 {
            return Err(RelightError::Budget(format!(
                "{count} elements asked for, over the budget of {} (MeshBudget::max_elements)",
                budget.max_elements
            )));
        }
        let bytes =
            crate::solver::solution_bytes(count as usize, count as usize / 4, lights.max(1));
        if bytes > budget.max_solution_bytes {
            return Err(RelightError::Budget(format!(
                "a {lights}-light solution over {count} elements needs {bytes} bytes, over the \
                 budget of {} (MeshBudget::max_solution_bytes)",
                budget.max_solution_bytes
            )));
        }
        let mut elements = Vec::with_capacity(count as usize);
        let mut patches = Vec::with_capacity(count as usize / 4);
        let mut skipped = 0;
        let mut global = 0u32;
        for (mi, mesh) in scene.meshes.iter().enumerate() {
            for (ti, t) in mesh.indices.iter().enumerate() {
                let id = global;
                global += 1;
                let area = areas[id as usize];
                if !(area.is_finite() && area > 0.0) {
                    skipped += 1;
                    continue;
                }
                let p = t.map(|i| mesh.positions[i as usize]);
                let geometric = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
                let ns = t.map(|i| mesh.normals.get(i as usize).copied().unwrap_or(geometric));
                let uvs = mesh.uvs.as_ref().map(|uv| t.map(|i| uv[i as usize]));
                let material = mesh.material_ids[ti];
                let emission = scene.materials[material as usize].emission;
                let light = (emission.max_element() > 0.0).then_some(LightId::Emissive(mi as u32));
                let at = |b: Vec2| p[0] * (1.0 - b.x - b.y) + p[1] * b.x + p[2] * b.y;
                let normal_at = |b: Vec2| {
                    let n = ns[0] * (1.0 - b.x - b.y) + ns[1] * b.x + ns[2] * b.y;
                    let n = n.normalize_or_zero();
                    if n == Vec3::ZERO { geometric } else { n }
                };
                let albedo_at = |b: Vec2| {
                    let uv = uvs.map(|q| q[0] * (1.0 - b.x - b.y) + q[1] * b.x + q[2] * b.y);
                    scene.albedo_at(material, uv)
                };
                let mut pieces = vec![Piece {
                    bary: [Vec2::ZERO, Vec2::X, Vec2::Y],
                }];
                for _ in 0..level(area, patch_area) {
                    pieces = pieces.iter().flat_map(|q| q.children()).collect();
                }
                for piece in pieces {
                    let corners = piece.bary.map(at);
                    let centre = (piece.bary[0] + piece.bary[1] + piece.bary[2]) / 3.0;
                    patches.push(Patch {
                        corners,
                        normal: normal_at(centre),
                        area: area / 4f32.powi(level(area, patch_area) as i32),
                        first_element: elements.len() as u32,
                        light,
                    });
                    let patch = patches.len() as u32 - 1;
                    for e in piece.children() {
                        let c = (e.bary[0] + e.bary[1] + e.bary[2]) / 3.0;
                        // Four albedo samples: the centroid and the midpoints towards each
                        // corner.
                        let albedo = (albedo_at(c)
                            + e.bary
                                .iter()
                                .map(|&v| albedo_at((c + v) * 0.5))
                                .sum::<Vec3>())
                            * 0.25;
                        let corners = e.bary.map(at);
                        let uv_of = |b: Vec2| {
                            uvs.map(|q| q[0] * (1.0 - b.x - b.y) + q[1] * b.x + q[2] * b.y)
                        };
                        let corner_uvs = uvs.map(|_| e.bary.map(|b| uv_of(b).unwrap_or_default()));
                        elements.push(Element {
                            corners,
                            centroid: at(c),
                            normal: normal_at(c),
                            area: patches[patch as usize].area * 0.25,
                            albedo,
                            emission,
                            patch,
                            source_triangle: id,
                            material,
                            uvs: corner_uvs,
                        });
                    }
                }
            }
        }
        Ok(Self {
            elements,
            patches,
            patch_area,
            skipped_triangles: skipped,
        })
    }

    /// The elements as a scene of their own (one mesh, element `j` is triangle `j`, the
    /// scene's materials and textures, flat element normals): what a G-buffer renderer
    /// draws so that its triangle ids are element ids.
    pub fn element_scene(&self, scene: &Scene) -> Scene {
        let mut mesh = scene_core::Mesh {
            name: "elements".into(),
            ..Default::default()
        };
        let textured = self.elements.iter().any(|e| e.uvs.is_some());
        let mut uvs = Vec::new();
        for (j, e) in self.elements.iter().enumerate() {
            mesh.positions.extend_from_slice(&e.corners);
            mesh.normals.extend_from_slice(&[e.normal; 3]);
            if textured {
                uvs.extend_from_slice(&e.uvs.unwrap_or([Vec2::ZERO; 3]));
            }
            let b = 3 * j as u32;
            mesh.indices.push([b, b + 1, b + 2]);
            mesh.material_ids.push(e.material);
        }
        if textured {
            mesh.uvs = Some(uvs);
        }
        let mut out = Scene::new(&format!("{} (elements)", scene.name));
        out.materials = scene.materials.clone();
        out.textures = scene.textures.clone();
        out.cameras = scene.cameras.clone();
        out.meshes.push(mesh);
        out
    }

    /// The elements of patch `p`.
    pub fn elements_of(&self, p: usize) -> &[Element] {
        let first = self.patches[p].first_element as usize;
        &self.elements[first..first + 4]
    }
}
