//! Instant-radiosity point lights (IRPLs) from particle walks (paper section 4.2, after
//! Keller).
//!
//! Every light source emits particles in proportion to its power under the frame's
//! [`LightState`]: start points are quasi-random (padded, Owen-scrambled Sobol' pairs:
//! which light, where on it, which direction; the paths dealt into [`BATCHES`] batches, each
//! scrambled by its own seed), bounces are cosine-weighted and stratified per depth, and a
//! particle survives a bounce with probability equal to the
//! largest channel of the albedo there (so the carried power never grows; at most
//! [`crate::IbrrSettings::max_depth`] bounces), its power divided by that probability.
//!
//! Each surface a particle reaches holds an IRPL: a Lambertian point emitter of power
//! `Phi` (RGB, W), whose irradiance at `x` is `Phi cos_i cos_x / (pi r^2)`, eq. 2's
//! `I_i g_i(x)`. Powers are per path: the LDC divides their sum by the number of paths.
//!
//! Point and directional lights are not sampled for their direct light: each gets one
//! exact "node 0" ([`IrplKind::PointSource`], [`IrplKind::DirectionalSource`]) rendered
//! once (a full cube around a point light, an orthographic view for a directional one).
//! Emissive surfaces give every path its own node 0 on the emitter
//! ([`IrplKind::EmitterSample`]).
//!
//! With [`WalkSettings::camera_importance`] (beyond the paper, which is view-independent),
//! a path IRPL that no surface point seen by the scene's cameras can see is kept with
//! probability [`CameraImportance::UNSEEN_KEEP`] and its power divided by it: a Russian
//! roulette on storing, so the expectation is unchanged everywhere while the IRPL budget
//! buys more paths, whose IRPLs land where the cameras look (a room lit through a window:
//! most particles would light the walls' outside).

use glam::{Vec2, Vec3};
use scene_core::Scene;
use scene_core::lights::{Emitters, LightId, LightState};
use scene_core::ray::RayScene;
use scene_core::sampling::{
    Rng, cosine_hemisphere, hash_seed, sobol_1d, sobol_2d, uniform_sphere, uniform_triangle,
};

/// What an IRPL is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IrplKind {
    /// A point light's own direct light (exact, once): intensity `power` W/sr, the
    /// scene's falloff.
    PointSource {
        /// The light's falloff radius (`None`: inverse square).
        radius: Option<f32>,
        /// A spot light's cone ramp ([`scene_core::lights::SpotRamp::NONE`]: every
        /// direction).
        spot: scene_core::lights::SpotRamp,
    },
    /// A directional light's own direct light: irradiance `power` on a surface facing
    /// it, travelling along `direction`.
    DirectionalSource {
        /// Unit direction the light travels.
        direction: Vec3,
    },
    /// A point on an emissive surface, the first node of one path (direct light).
    EmitterSample,
    /// A surface reached by a particle after one or more steps (indirect light).
    Bounce,
}

/// One instant-radiosity point light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Irpl {
    /// Where (lifted off its surface by a tiny distance).
    pub position: Vec3,
    /// Unit normal of the side it emits from (zero for point and directional sources).
    pub normal: Vec3,
    /// Power (W, per path), intensity (point source) or irradiance (directional source).
    pub power: Vec3,
    /// What it is.
    pub kind: IrplKind,
    /// The light source the particle came from.
    pub light: LightId,
    /// The path it belongs to (`u32::MAX` for exact sources).
    pub path: u32,
    /// Bounces since the light (0: on the light).
    pub depth: u32,
}

impl Irpl {
    /// True for the nodes of particle paths (emitter samples and bounces), whose geometry
    /// term may be clamped.
    pub fn is_path_node(&self) -> bool {
        matches!(self.kind, IrplKind::EmitterSample | IrplKind::Bounce)
    }

    /// True for the first node of a path or an exact source (direct light).
    pub fn is_direct(&self) -> bool {
        self.depth == 0
    }

    /// Irradiance this IRPL gives a point `p` with unit normal `n` facing it, ignoring
    /// visibility (the hemicube render decides that): eq. 2's `I_i g_i(x)` with
    /// `g = cos_i cos_x / (pi r^2)`, computed in full precision (never clamped).
    #[inline]
    pub fn irradiance_at(&self, p: Vec3, n: Vec3) -> Vec3 {
        self.irradiance_clamped(p, n, f32::INFINITY)
    }

    /// [`Irpl::irradiance_at`] with the geometry term of path nodes
    /// ([`IrplKind::EmitterSample`], [`IrplKind::Bounce`]) clamped to `g_max`; the exact
    /// sources are never clamped.
    #[inline]
    pub fn irradiance_clamped(&self, p: Vec3, n: Vec3, g_max: f32) -> Vec3 {
        match self.kind {
            IrplKind::DirectionalSource { direction } => self.power * (-n.dot(direction)).max(0.0),
            IrplKind::PointSource { radius, spot } => {
                let d = self.position - p;
                let r = d.length();
                if r <= 0.0 {
                    return Vec3::ZERO;
                }
                let cos_x = (n.dot(d) / r).max(0.0);
                let spot = spot.attenuation(-d / r);
                self.power * (scene_core::lights::falloff(radius, r) * cos_x * spot)
            }
            IrplKind::EmitterSample | IrplKind::Bounce => {
                let d = p - self.position;
                let r2 = d.length_squared();
                if r2 <= 0.0 {
                    return Vec3::ZERO;
                }
                let r = r2.sqrt();
                let cos_i = (self.normal.dot(d) / r).max(0.0);
                let cos_x = (-n.dot(d) / r).max(0.0);
                let g = (cos_i * cos_x * std::f32::consts::FRAC_1_PI / r2).min(g_max);
                if g.is_finite() {
                    self.power * g
                } else {
                    Vec3::ZERO
                }
            }
        }
    }
}

/// The IRPLs of a scene.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IrplSet {
    /// Exact sources first, then the paths' nodes path by path.
    pub irpls: Vec<Irpl>,
    /// Number of particle paths started (the divisor of path sums).
    pub paths: u64,
    /// For each path, the index one past its last IRPL.
    pub path_ends: Vec<usize>,
    /// Number of exact sources at the front of `irpls`.
    pub exact: usize,
}

/// A light's share of the particles.
#[derive(Clone, Copy, Debug)]
enum Start {
    Point {
        light: u32,
    },
    /// A directional light: its unit travel direction.
    Directional {
        direction: Vec3,
    },
    /// One of the sky's median-cut regions ([`scene_core::sky::Sky::lights`]): each
    /// particle draws its own direction within the region
    /// ([`scene_core::sky::Sky::sample_light`]), so the paths carry the sky as it is, not
    /// its fixed directions (which stay the exact sources of its direct light).
    SkyRegion {
        region: u32,
    },
    Emitter {
        triangle: usize,
    },
}

/// The surface a walk hit: scene-core's.
pub(crate) use scene_core::ray::surface_at;

/// Settings of the particle walks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkSettings {
    /// About this many IRPLs (exact sources included, except the sky's directions, which
    /// come on top): the path count is the remainder divided by the mean IRPLs per path of
    /// a pilot of 256 independent walks.
    pub irpls: u32,
    /// Seed of the Sobol' scrambling (per batch) and the generators.
    pub seed: u64,
    /// Most bounces a particle makes.
    pub max_depth: u32,
    /// Number of paths; 0: from `irpls` and a pilot.
    pub paths: u32,
    /// Keep the IRPLs that no scene camera's surface point sees with probability
    /// [`CameraImportance::UNSEEN_KEEP`] (their power divided by it): the budget goes to
    /// the light the cameras see, the estimate stays unbiased everywhere. No effect on a
    /// scene without cameras.
    pub camera_importance: bool,
    /// Start the particles of suns and sky regions where their light enters what the
    /// scene's cameras see ([`EntryImportance`]): more of them through a window, the rest
    /// fewer and stronger (unbiased). No effect on a scene without cameras or without
    /// directional light.
    pub entry_importance: bool,
}

/// Where the particles of a directional light (a sun, a sky region) start on the disk
/// across the scene's bounding sphere ([`WalkSettings::entry_importance`]; beyond the
/// paper). A grid of [`EntryImportance::SIDE`]^2 cells over the unit square that maps onto
/// the disk; from each cell's centre one pilot ray travels along the light, and the cell
/// counts as an entry when the surface it first meets is seen by one of (up to
/// [`EntryImportance::WITNESSES`]) points the scene's cameras see. A start is drawn from
/// a mixture: with probability [`EntryImportance::ENTRY_SHARE`] uniformly over the entry
/// cells, else uniformly over the whole disk (so every start stays possible, and the light
/// arriving elsewhere is carried at most `1 / (1 - ENTRY_SHARE)` times stronger), its
/// power divided by the density there: the estimate is unchanged while a room lit
/// through its window gets half its particles through the window, however small the
/// window is against the disk. The geometry finds the openings: nothing is marked.
#[derive(Clone, Debug)]
pub struct EntryImportance {
    /// Cumulative weights over the cells (row-major), the last 1.
    cdf: Vec<f64>,
    /// Per cell, its density relative to a uniform start.
    density: Vec<f32>,
    /// Cells that are entries.
    pub entries: usize,
}

impl EntryImportance {
    /// Cells along each side of the grid.
    pub const SIDE: u32 = 48;
    /// The share of the particles drawn over the entry cells alone.
    pub const ENTRY_SHARE: f64 = 0.5;
    /// Most camera points a pilot's surface is tested against.
    pub const WITNESSES: usize = 32;

    /// The starts of light travelling along the unit `dir`, from the disk of `radius`
    /// across `centre` (`disk`: a point of the unit square to the disk), seen from
    /// `witnesses`; `None` when no cell is an entry (the uniform start).
    fn new(
        scene: &Scene,
        rays: &RayScene,
        witnesses: &CameraImportance,
        dir: Vec3,
        disk: &(dyn Fn(Vec2) -> Vec3 + Sync),
        lift: f32,
    ) -> Option<Self> {
        use rayon::prelude::*;
        let side = Self::SIDE;
        let offsets = scene.mesh_offsets();
        let entry: Vec<bool> = (0..side * side)
            .into_par_iter()
            .map(|c| {
                let u = Vec2::new(
                    ((c % side) as f32 + 0.5) / side as f32,
                    ((c / side) as f32 + 0.5) / side as f32,
                );
                let o = disk(u);
                rays.closest_hit(o, dir, 0.0, f32::INFINITY)
                    .and_then(|hit| surface_at(scene, &offsets, &hit, o, dir))
                    .is_some_and(|s| witnesses.sees(rays, s.p + s.ng * lift, s.ng))
            })
            .collect();
        let entries = entry.iter().filter(|&&e| e).count();
        if entries == 0 {
            return None;
        }
        // Each cell's probability: the mixture of the entries alone and the whole disk.
        let n = entry.len() as f64;
        let share = Self::ENTRY_SHARE;
        let w: Vec<f64> = entry
            .iter()
            .map(|&e| (1.0 - share) / n + if e { share / entries as f64 } else { 0.0 })
            .collect();
        let total: f64 = w.iter().sum();
        let mut acc = 0.0;
        let cdf = w
            .iter()
            .map(|x| {
                acc += x / total;
                acc
            })
            .collect();
        let density = w.iter().map(|x| (x * n / total) as f32).collect();
        Some(Self {
            cdf,
            density,
            entries,
        })
    }

    /// A point of the unit square drawn by the cells' weights from `u` in [0, 1)^2 (`u.x`
    /// picks the cell and, rescaled, the column within it; `u.y` the row), and its density
    /// relative to a uniform draw.
    fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let side = Self::SIDE;
        let x = f64::from(u.x);
        let k = self
            .cdf
            .partition_point(|&c| c <= x)
            .min(self.cdf.len() - 1);
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let t = ((x - lo) / (self.cdf[k] - lo).max(f64::MIN_POSITIVE)).clamp(0.0, 1.0 - 1e-7);
        let (i, j) = ((k as u32 % side) as f32, (k as u32 / side) as f32);
        (
            Vec2::new((i + t as f32) / side as f32, (j + u.y) / side as f32),
            self.density[k],
        )
    }
}

/// Surface points the scene's cameras see, for [`WalkSettings::camera_importance`]: a
/// grid of primary rays per camera, each hit lifted off its surface on the camera's side.
#[derive(Clone, Debug, Default)]
pub struct CameraImportance {
    /// Lifted position and unit geometric normal (facing the camera) of every point.
    pub points: Vec<(Vec3, Vec3)>,
}

impl CameraImportance {
    /// Columns of the grid of primary rays per camera (rows follow its aspect).
    pub const COLUMNS: u32 = 32;
    /// The probability of keeping an IRPL that sees none of the points.
    pub const UNSEEN_KEEP: f32 = 0.125;

    /// The points of `scene`'s cameras (empty without cameras).
    pub fn of(scene: &Scene, rays: &RayScene) -> Self {
        let offsets = scene.mesh_offsets();
        let lift = scene.extent() * 1e-4;
        let mut points = Vec::new();
        for camera in &scene.cameras {
            let view = scene_core::View::from_camera(camera);
            let cols = Self::COLUMNS;
            let rows = ((cols as f32 / camera.aspect.max(1e-3)).round() as u32).clamp(1, 4 * cols);
            for y in 0..rows {
                for x in 0..cols {
                    let uv = scene_core::view::pixel_uv(x, y, cols, rows);
                    let (o, d) = view.ray(uv);
                    let Some(hit) = rays.closest_hit(o, d, 0.0, f32::INFINITY) else {
                        continue;
                    };
                    if let Some(s) = surface_at(scene, &offsets, &hit, o, d) {
                        points.push((s.p + s.ng * lift, s.ng));
                    }
                }
            }
        }
        Self { points }
    }

    /// Whether an IRPL at `x` with normal `n` sees any of the points (each on its front,
    /// and the IRPL on the point's front).
    pub fn sees(&self, rays: &RayScene, x: Vec3, n: Vec3) -> bool {
        self.points.iter().any(|&(y, ny)| {
            let d = y - x;
            let len = d.length();
            len > 0.0
                && d.dot(n) > 0.0
                && d.dot(ny) < 0.0
                && !rays.occluded(x, d / len, 0.0, len * (1.0 - 1e-4))
        })
    }
}

/// Generates the IRPLs of `scene` under `lights`. Deterministic for a seed.
pub fn generate(
    scene: &Scene,
    rays: &RayScene,
    lights: &LightState,
    settings: &WalkSettings,
) -> IrplSet {
    walks(scene, rays, lights, settings, None)
}

/// Appends `more` particle paths to `set` (made by [`generate`] with the same scene,
/// lights and settings): paths `set.paths..set.paths + more`, exactly those a single
/// [`generate`] asked for `set.paths + more` paths would walk (a path depends only on its
/// index and the seed). Returns the index of the first new IRPL.
pub fn extend(
    scene: &Scene,
    rays: &RayScene,
    lights: &LightState,
    settings: &WalkSettings,
    set: &mut IrplSet,
    more: u64,
) -> usize {
    let first = set.irpls.len();
    let extra = walks(
        scene,
        rays,
        lights,
        &WalkSettings {
            paths: more.min(u64::from(u32::MAX)) as u32,
            ..*settings
        },
        Some(set.paths),
    );
    for end in extra.path_ends {
        set.path_ends.push(first + end);
    }
    set.irpls.extend(extra.irpls);
    set.paths += extra.paths;
    first
}

/// The walks of [`generate`] (`first_path` `None`: exact sources, then the paths a pilot
/// or `settings.paths` asks for) or of [`extend`] (`Some(p)`: `settings.paths` paths from
/// index `p`, no exact sources).
fn walks(
    scene: &Scene,
    rays: &RayScene,
    lights: &LightState,
    settings: &WalkSettings,
    first_path: Option<u64>,
) -> IrplSet {
    let mut set = IrplSet::default();
    let extent = scene.extent();
    let lift = extent * 1e-5;
    let bounds = scene.bounds();
    let centre = if bounds.is_empty() {
        Vec3::ZERO
    } else {
        bounds.center()
    };
    let radius = 0.5 * extent * 1.01;
    // Exact sources and the particle budget of each light: (start, rgb power, weight).
    let mut starts: Vec<(Start, Vec3, LightId)> = Vec::new();
    for (i, l) in scene.point_lights.iter().enumerate() {
        let id = LightId::Point(i as u32);
        let s = lights.get(id);
        if !s.enabled {
            continue;
        }
        let direct = l.intensity * s.direct_factor();
        if direct.max_element() > 0.0 {
            set.irpls.push(Irpl {
                position: l.position,
                normal: Vec3::ZERO,
                power: direct,
                kind: IrplKind::PointSource {
                    radius: l.radius,
                    spot: scene_core::lights::SpotRamp::of(l.cone.as_ref()),
                },
                light: id,
                path: u32::MAX,
                depth: 0,
            });
        }
        // Its power: the intensity over the solid angle it sends it (4 pi, or a spot's
        // cone attenuation integrated).
        starts.push((
            Start::Point { light: i as u32 },
            l.intensity * s.color * l.solid_angle() * s.indirect,
            id,
        ));
    }
    // The scene's directional lights, then the sky as its median-cut directions.
    let mut sky_region = 0u32;
    for (id, l) in scene_core::lights::directional_sources(scene) {
        let dir = l.direction.normalize_or_zero();
        let start = if id == LightId::Sky {
            sky_region += 1;
            Start::SkyRegion {
                region: sky_region - 1,
            }
        } else {
            Start::Directional { direction: dir }
        };
        let s = lights.get(id);
        if !s.enabled || dir == Vec3::ZERO {
            continue;
        }
        let direct = l.irradiance * s.direct_factor();
        if direct.max_element() > 0.0 {
            set.irpls.push(Irpl {
                position: centre - dir * (2.0 * radius),
                normal: Vec3::ZERO,
                power: direct,
                kind: IrplKind::DirectionalSource { direction: dir },
                light: id,
                path: u32::MAX,
                depth: 0,
            });
        }
        // Its power through the disk the particles start on (for a sky region, the
        // region's light along its mean direction: the share of the paths it gets; each
        // particle's own power comes from its direction's draw).
        starts.push((
            start,
            l.irradiance * s.color * (std::f32::consts::PI * radius * radius) * s.indirect,
            id,
        ));
    }
    if first_path.is_some() {
        set.irpls.clear();
    }
    set.exact = set.irpls.len();
    let emitters = Emitters::new(scene, lights);
    for (k, t) in emitters.triangles.iter().enumerate() {
        let s = lights.get(LightId::Emissive(t.mesh));
        if !s.enabled || t.area <= 0.0 || t.normal == Vec3::ZERO {
            continue;
        }
        // Emitted power pi Le A; paths carry both its direct and its indirect part.
        let power =
            t.emission * s.color * (std::f32::consts::PI * t.area) * s.direct.max(s.indirect);
        starts.push((
            Start::Emitter { triangle: k },
            power,
            LightId::Emissive(t.mesh),
        ));
    }
    let weights: Vec<f64> = starts
        .iter()
        .map(|(_, p, _)| scene_core::lights::sampling_weight(*p))
        .collect();
    let total: f64 = weights.iter().sum();
    // The sky's directions (one exact source each, `scene_core::sky`) come on top of the
    // budget, so that a sky does not take the paths' share: the budget counts the other
    // exact sources and the paths.
    let budgeted_exact = set.irpls.iter().filter(|i| i.light != LightId::Sky).count();
    if total <= 0.0
        || (first_path.is_none()
            && settings.paths == 0
            && settings.irpls as usize <= budgeted_exact)
    {
        return set;
    }
    let mut cdf = Vec::with_capacity(weights.len());
    let mut acc = 0.0;
    for w in &weights {
        acc += w / total;
        cdf.push(acc);
    }
    let importance = (settings.camera_importance && !scene.cameras.is_empty())
        .then(|| CameraImportance::of(scene, rays))
        .filter(|i| !i.points.is_empty());
    // Where each directional start's particles enter what the cameras see.
    let on_disk = |dir: Vec3| {
        let (t, b) = scene_core::view::orthonormal_basis(dir);
        move |u: Vec2| {
            let disk = scene_core::sampling::concentric_disk(u) * radius;
            centre - dir * (2.0 * radius) + t * disk.x + b * disk.y
        }
    };
    let witnesses = (settings.entry_importance && !scene.cameras.is_empty())
        .then(|| {
            let all = CameraImportance::of(scene, rays).points;
            let step = all.len().div_ceil(EntryImportance::WITNESSES).max(1);
            CameraImportance {
                points: all.into_iter().step_by(step).collect(),
            }
        })
        .filter(|w| !w.points.is_empty());
    let entries: Vec<Option<EntryImportance>> = starts
        .iter()
        .map(|(start, _, _)| {
            let w = witnesses.as_ref()?;
            let dir = match *start {
                Start::Directional { direction } => direction,
                Start::SkyRegion { region } => scene
                    .sky
                    .as_ref()?
                    .lights()
                    .get(region as usize)?
                    .direction
                    .normalize_or_zero(),
                _ => return None,
            };
            EntryImportance::new(scene, rays, w, dir, &on_disk(dir), lift)
        })
        .collect();
    let walker = Walker {
        entries: &entries,
        importance: importance.as_ref(),
        scene,
        rays,
        lights,
        starts: &starts,
        weights: &weights,
        cdf: &cdf,
        total,
        emitters: &emitters,
        offsets: scene.mesh_offsets(),
        lift,
        centre,
        radius,
        max_depth: settings.max_depth,
    };
    // The number of paths is fixed before the walks that count, from a pilot of
    // independent walks: stopping once the IRPLs reach the target would make the path
    // count depend on the paths' lengths and bias the mean.
    const PILOT: u64 = 256;
    let paths = if settings.paths > 0 || first_path.is_some() {
        u64::from(settings.paths)
    } else {
        let pilot_seed = scene_core::sampling::hash_seed(settings.seed, 0x9e37, 1);
        let mut scratch = Vec::new();
        for k in 0..PILOT {
            walker.walk(k, pilot_seed, &mut scratch);
        }
        let per_path = scratch.len() as f64 / PILOT as f64;
        let wanted = (settings.irpls as usize).saturating_sub(budgeted_exact) as f64;
        if per_path > 0.0 {
            (wanted / per_path).round().max(1.0) as u64
        } else {
            1
        }
    };
    let first = first_path.unwrap_or(0);
    for path in first..first + paths {
        walker.walk(path, settings.seed, &mut set.irpls);
        set.path_ends.push(set.irpls.len());
    }
    set.paths = paths;
    set
}

/// Everything one particle walk needs.
struct Walker<'a> {
    /// Per start, where its particles enter ([`EntryImportance`]; `None`: uniform).
    entries: &'a [Option<EntryImportance>],
    importance: Option<&'a CameraImportance>,
    scene: &'a Scene,
    rays: &'a RayScene,
    lights: &'a LightState,
    starts: &'a [(Start, Vec3, LightId)],
    weights: &'a [f64],
    cdf: &'a [f64],
    total: f64,
    emitters: &'a Emitters,
    offsets: Vec<u32>,
    lift: f32,
    centre: Vec3,
    radius: f32,
    max_depth: u32,
}

impl Walker<'_> {
    /// Walks path `path` (walk `path / BATCHES` of its batch) with `seed`, pushing its IRPLs
    /// to `out`.
    fn walk(&self, path: u64, seed_value: u64, out: &mut Vec<Irpl>) {
        let (scene, lights, emitters) = (self.scene, self.lights, self.emitters);
        let (starts, weights, cdf, total) = (self.starts, self.weights, self.cdf, self.total);
        let (lift, centre, radius) = (self.lift, self.centre, self.radius);
        // Path `path` is walk `path / BATCHES` of batch `path % BATCHES`, whose sequences
        // are scrambled by the batch's own seed: the batches are independent replicates of
        // one randomised quasi-Monte Carlo estimate (the build's error estimate,
        // `crate::estimate`, compares them).
        let (batch, index) = (batch_of(path as u32) as u64, path / BATCHES as u64);
        let seed_value = batch_seed(seed_value, batch);
        // The start's numbers: padded, Owen-scrambled Sobol' (which light; where on it;
        // which way), each pair stratified at every power-of-two count of a batch's
        // walks. Scrambled Halton did this until 2026-11-29; with a few walks a batch its
        // large bases left a batch's first two walks 1/7 and 1/11 apart in the direction's
        // numbers, and a second walk a batch lowered the error no more than none.
        let i = index as u32;
        let start_seed = |k: u64| hash_seed(seed_value, 0x57a7, k);
        let u0 = f64::from(sobol_1d(i, start_seed(0)));
        let k = cdf.partition_point(|&c| c <= u0).min(starts.len() - 1);
        let pick = weights[k] / total;
        if pick <= 0.0 {
            return;
        }
        let (start, power, id) = starts[k];
        let power = power / pick as f32;
        let (u1, u2) = sobol_2d(i, start_seed(1)).into();
        let (u3, u4) = sobol_2d(i, start_seed(2)).into();
        let mut rng = Rng::new(seed_value, index);
        let path_id = path as u32;
        // A particle travelling along `dir` from afar starts on the disk across the
        // scene's bounding sphere, `2 radius` before its centre: uniformly, or where its
        // light enters what the cameras see ([`EntryImportance`]), its power divided by
        // the density there.
        let entry = self.entries.get(k).and_then(Option::as_ref);
        let on_disk = |dir: Vec3| {
            let (u, density) = match entry {
                Some(e) => e.sample(Vec2::new(u1, u2)),
                None => (Vec2::new(u1, u2), 1.0),
            };
            let (t, b) = scene_core::view::orthonormal_basis(dir);
            let disk = scene_core::sampling::concentric_disk(u) * radius;
            (
                centre - dir * (2.0 * radius) + t * disk.x + b * disk.y,
                1.0 / density,
            )
        };
        // The particle: origin, direction, carried power (before reflection).
        let (mut o, mut d, mut carried) = match start {
            Start::Point { light } => {
                let l = &scene.point_lights[light as usize];
                match &l.cone {
                    None => (l.position, uniform_sphere(Vec2::new(u1, u2)), power),
                    // A spot: directions uniform within its outer cone, each particle's
                    // power weighted by the attenuation over its mean (the cone's solid
                    // angle over the outer cone's), so the paths carry the spot's power.
                    Some(cone) => {
                        let dir = uniform_cone(cone, Vec2::new(u1, u2));
                        let weight = cone.attenuation(dir) * cone.outer_solid_angle()
                            / cone.solid_angle().max(f32::MIN_POSITIVE);
                        (l.position, dir, power * weight)
                    }
                }
            }
            Start::Directional { direction: dir } => {
                let (o, weight) = on_disk(dir);
                (o, dir, power * weight)
            }
            Start::SkyRegion { region } => {
                // The region's light `int L dw` times the disk's area, drawn as a
                // direction with weight `L dw / p` ([`Sky::sample_light`]): the particle
                // carries that weight in place of the region's mean, rescaled from the
                // share the start was picked with.
                let Some(sky) = scene.sky.as_ref() else {
                    return;
                };
                let Some(light) = sky.lights().get(region as usize) else {
                    return;
                };
                let u = Vec3::new(u3, u4, sobol_1d(i, start_seed(3)));
                let Some((towards_sky, weight)) = sky.sample_light(region as usize, u) else {
                    return;
                };
                let mean = light.irradiance;
                let scale = Vec3::select(mean.cmpgt(Vec3::ZERO), weight / mean, Vec3::ZERO);
                let (o, weight) = on_disk(-towards_sky);
                (o, -towards_sky, power * scale * weight)
            }
            Start::Emitter { triangle } => {
                let t = &emitters.triangles[triangle];
                let s = lights.get(id);
                let bary = uniform_triangle(Vec2::new(u1, u2));
                // A point an alpha mask cuts away emits nothing (as in the reference): the
                // path carries no light, so the emitter's light is its power times the share
                // of its area that exists.
                if !self.rays.cutouts().opaque(t.triangle, bary) {
                    return;
                }
                let p = t.corners[0] * (1.0 - bary.x - bary.y)
                    + t.corners[1] * bary.x
                    + t.corners[2] * bary.y;
                let position = p + t.normal * lift;
                // Node 0 carries the direct part, the particle the indirect part.
                let scale = s.direct.max(s.indirect);
                let (fd, fi) = if scale > 0.0 {
                    (s.direct / scale, s.indirect / scale)
                } else {
                    (0.0, 0.0)
                };
                if fd > 0.0 {
                    out.push(Irpl {
                        position,
                        normal: t.normal,
                        power: power * fd,
                        kind: IrplKind::EmitterSample,
                        light: id,
                        path: path_id,
                        depth: 0,
                    });
                }
                (
                    position,
                    cosine_hemisphere(t.normal, Vec2::new(u3, u4)),
                    power * fi,
                )
            }
        };
        let mut depth = 0;
        let mut t_min = 0.0;
        while depth < self.max_depth && carried.max_element() > 0.0 {
            let Some(hit) = self.rays.closest_hit(o, d, t_min, f32::INFINITY) else {
                break;
            };
            let Some(s) = surface_at(scene, &self.offsets, &hit, o, d) else {
                break;
            };
            // A point light with a falloff radius delivers falloff(r) r^2 of the
            // inverse-square power along the first segment.
            if depth == 0
                && let Start::Point { light } = start
            {
                let l = &scene.point_lights[light as usize];
                carried *= scene_core::lights::falloff(l.radius, hit.t) * hit.t * hit.t;
            }
            depth += 1;
            let reflected = carried * s.albedo;
            if reflected.max_element() <= 0.0 || !reflected.is_finite() {
                break;
            }
            let position = s.p + s.ng * lift;
            // Camera importance: an IRPL no camera point sees is kept with probability
            // `UNSEEN_KEEP`, its power divided by it (the walk goes on either way).
            let keep = match self.importance {
                Some(imp) if !imp.sees(self.rays, position, s.ns) => (rng.next_f32()
                    < CameraImportance::UNSEEN_KEEP)
                    .then_some(1.0 / CameraImportance::UNSEEN_KEEP),
                _ => Some(1.0),
            };
            if let Some(weight) = keep {
                out.push(Irpl {
                    position,
                    normal: s.ns,
                    power: reflected * weight,
                    kind: IrplKind::Bounce,
                    light: id,
                    path: path_id,
                    depth,
                });
            }
            // Survival equals the albedo's largest channel (at most 0.999,
            // `scene_core::scene::ALBEDO_MAX`), so the carried power never grows: a cap below
            // the albedo multiplied it by rho / cap at every bounce.
            // Survival and the bounce's direction are stratified over the paths, one
            // padded scrambled-Sobol sequence per depth (`sobol_1d`, `sobol_2d`): the
            // paths that reach a depth split between surviving and absorbed, and share
            // out the hemisphere, in the proportions asked, instead of by chance.
            let q = s.albedo.max_element().min(1.0);
            let at_depth = |k: u64| hash_seed(seed_value, k, u64::from(depth));
            if q <= 0.0 || sobol_1d(index as u32, at_depth(0x5a)) >= q {
                break;
            }
            carried = reflected / q;
            let nd = cosine_hemisphere(s.ns, sobol_2d(index as u32, at_depth(0xd1)));
            if nd.dot(s.ng) <= 0.0 {
                break;
            }
            o = position;
            d = nd;
            t_min = 0.0;
        }
    }
}

/// Independent batches the paths are dealt into, round robin: path `p` belongs to batch
/// `p % BATCHES` ([`batch_of`]), each batch walking its own scrambled sequences
/// (`batch_seed`). The build's error estimate ([`crate::estimate`]) is the spread of the
/// batches' estimates.
pub const BATCHES: u32 = 16;

/// The batch of path `path` ([`BATCHES`]).
#[inline]
pub fn batch_of(path: u32) -> usize {
    (path % BATCHES) as usize
}

/// The seed of batch `batch`'s sequences under the build's `seed`.
#[inline]
fn batch_seed(seed: u64, batch: u64) -> u64 {
    hash_seed(seed, 0x0ba7_c4e5, batch)
}

/// Paths of batch `batch` among the first `paths` paths.
pub fn paths_in_batch(paths: u64, batch: usize) -> u64 {
    let b = u64::from(BATCHES);
    paths / b + u64::from((batch as u64) < paths % b)
}

/// A direction uniform within `cone`'s outer cone (about its axis) from `u` in [0, 1)^2:
/// `cos` uniform in `[cos(outer), 1]`, the azimuth uniform.
fn uniform_cone(cone: &scene_core::lights::SpotCone, u: Vec2) -> Vec3 {
    let cos_outer = cone.outer.cos();
    let cos = 1.0 - u.x * (1.0 - cos_outer);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u.y;
    let (t, b) = scene_core::view::orthonormal_basis(cone.axis());
    (t * (sin * phi.cos()) + b * (sin * phi.sin()) + cone.axis() * cos).normalize_or_zero()
}
