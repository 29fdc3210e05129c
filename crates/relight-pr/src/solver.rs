//! Light-tagged progressive refinement (the paper's figure 2) with substructuring, direct
//! and indirect energy stored apart (section 2.4) and an ambient term per light (section
//! 2.3, after Cohen et al.), and the two baselines of the paper's Table 1 in the same code
//! path: standard progressive refinement on the combined emission, and k separate solves.
//!
//! Units: each element stores the irradiance `E` (W/m^2) it has received from each light
//! source, directly and after reflections; its radiosity is `rho E` (plus its emission),
//! its radiance `rho E / pi` (plus its emitted radiance). Patches carry unshot radiosity.
//! A source is solved with its emission as the scene gives it (multiplier 1, the paper's
//! unit emission with the colour pulled out: [`crate::relight`] multiplies it back).

use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;
use scene_core::lights::{LightId, light_ids};
use scene_core::ray::RayScene;
use scene_core::{Scene, luminance};

use crate::RelightError;
use crate::direct;
use crate::form_factor::point_to_triangle_adaptive;
use crate::mesh::Meshing;
use crate::visibility;

/// Bytes of a `k`-source solution over `n` elements and `p` patches (direct and indirect
/// per element, two unshot values per patch, RGB f32).
pub fn solution_bytes(n: usize, p: usize, k: usize) -> u64 {
    (n as u64 * 2 + p as u64 * 2) * k as u64 * 12
}

/// How the energy of the lights is organised while solving (the paper's Table 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strategy {
    /// The paper's method: one shot distributes every source's unshot energy with one row
    /// of form factors; k solutions at once.
    Tagged,
    /// Standard progressive refinement of the combined emission (one solution: it cannot
    /// be relit per light).
    Combined,
    /// One progressive refinement per source, one after the other.
    Separate,
}

/// How a shot's row of form factors is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormFactorMethod {
    /// Closed-form point-to-patch form factors at each element's receiver points, with
    /// ray-cast visibility ([`crate::form_factor::point_to_triangle`]): the accurate one.
    Rays,
    /// The paper's hemicube at the shooting patch's centre: five faces of `resolution`
    /// rendered by a `scene_core::GBufferRenderer`, integrated with delta form factors
    /// ([`crate::form_factor::hemicube_row`]).
    Hemicube {
        /// Pixels along the top face (128 in the paper).
        resolution: u32,
    },
}

/// Solver parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverSettings {
    /// How form factors are computed. Default [`FormFactorMethod::Rays`].
    pub form_factors: FormFactorMethod,
    /// Stratified visibility rays per form factor (receiver to patch). Default 16.
    pub visibility_samples: u32,
    /// Stop when the unshot fraction of the emitted energy (luminance-weighted) is below
    /// this. Default 1e-3.
    pub max_unshot: f64,
    /// Stop after this many shots anyway. Default 200 000.
    pub max_shots: usize,
    /// Add Cohen's ambient term per source (the unshot energy spread uniformly).
    /// Default on.
    pub ambient: bool,
    /// Light banks (Dorsey et al.): groups of lights solved as one source. Lights not in a
    /// bank are sources of their own. Default none.
    pub banks: Vec<Vec<LightId>>,
    /// The strategy. Default [`Strategy::Tagged`].
    pub strategy: Strategy,
    /// Patches of one element (whole scene triangles smaller than an element: books,
    /// finely tessellated curves) shoot together in clusters of up to this many spatial
    /// neighbours, no wider than a patch of the target size ([`small_patch_clusters`]):
    /// one row of small-disk form factors for the cluster instead of one shot each. On a
    /// scene of tens of thousands of such patches the unshot energy left among them
    /// otherwise takes tens of thousands of shots. 0 or 1 shoots each alone; hemicube
    /// form factors always do. At most [`MAX_CLUSTER_MEMBERS`]. Default 32.
    pub cluster_members: usize,
    /// The unoccluded form factor at which a receiver gets all `visibility_samples` rays;
    /// below it, rays in proportion, at least one
    /// ([`crate::form_factor::point_to_triangle_adaptive`]). Receivers that get a sliver of
    /// a shot's light (far away, or in another room behind a wall) then cost one ray
    /// instead of 16; the estimate stays unbiased. 0 gives every receiver all rays.
    /// Default 0.01 (a facing receiver within about five patch sizes of the shooter).
    pub full_visibility_at: f32,
    /// Bytes of memory the solve may keep computed form-factor rows in. A patch's row
    /// (its form factors to every element, [`FormFactorMethod::Rays`] seeded by patch and
    /// receiver, or [`FormFactorMethod::Hemicube`] rendered from the patch's centre) is the
    /// same every time the patch shoots, and in a bright closed room a patch shoots tens or
    /// hundreds of times before the unshot energy falls below [`Self::max_unshot`]; a kept
    /// row is reused instead of cast again, and the solution is bit-for-bit the one
    /// without the cache. Rows are kept sparse (8 bytes per receiver with a form factor
    /// above 0) in the order patches first shoot, until the next row would pass this
    /// budget; later rows are computed at every shot. 0 keeps none. Shots of small-patch
    /// clusters ([`Self::cluster_members`]) are never kept (their rays differ per shot).
    /// Default 256 MiB.
    pub row_cache_bytes: usize,
    /// The hierarchical solve's settings ([`crate::hierarchical`], hierarchical radiosity
    /// with clustering: links between clusters of elements where their error allows, so
    /// that the cost follows the links, not elements times shots), used for meshings of
    /// more than [`SolverSettings::hierarchy_above`] elements. `max_unshot`, `max_shots`,
    /// `cluster_members` and `row_cache_bytes` do not apply to it; it takes the
    /// [`Strategy::Tagged`] or [`Strategy::Combined`] strategy and
    /// [`FormFactorMethod::Rays`]. `None`: always progressive refinement, the paper's.
    /// Default the hierarchical defaults.
    pub hierarchy: Option<crate::hierarchical::HierarchySettings>,
    /// Meshings of more elements than this are solved hierarchically (with `hierarchy`
    /// set): the progressive solve's cost grows as its elements times its shots (396 s for
    /// the `building`'s 125 306 elements on 2 cores, against 29 s hierarchically), and a
    /// file of 10^5 triangles meshes into at least as many elements whatever the target.
    /// Default 8 192 (the built-in rooms at the main job's targets stay progressive, the
    /// paper's method); 0 solves every meshing hierarchically. Where the strategy or the
    /// form factors do not allow the hierarchical solve, a threshold above 0 keeps the
    /// progressive one, and 0 is refused.
    pub hierarchy_above: usize,
}

impl SolverSettings {
    /// The hierarchical settings a solve of `elements` elements runs with, or `None` for
    /// the progressive solve ([`SolverSettings::hierarchy_above`]).
    pub fn hierarchy_for(&self, elements: usize) -> Option<crate::hierarchical::HierarchySettings> {
        let allowed = matches!(self.strategy, Strategy::Tagged | Strategy::Combined)
            && matches!(self.form_factors, FormFactorMethod::Rays);
        self.hierarchy
            .filter(|_| elements > self.hierarchy_above && (allowed || self.hierarchy_above == 0))
    }
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            form_factors: FormFactorMethod::Rays,
            visibility_samples: 16,
            max_unshot: 1e-3,
            max_shots: 200_000,
            ambient: true,
            banks: Vec::new(),
            strategy: Strategy::Tagged,
            cluster_members: 32,
            full_visibility_at: 0.01,
            row_cache_bytes: 256 << 20,
            hierarchy: Some(crate::hierarchical::HierarchySettings::default()),
            hierarchy_above: 1 << 13,
        }
    }
}

/// One light source of a solution: a light, or a bank of lights.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Source {
    /// The lights it holds (one unless it is a bank).
    pub lights: Vec<LightId>,
}

/// What a solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveStats {
    /// Patches shot.
    pub shots: usize,
    /// Rows of form factors computed (one per shot that found no kept row and, for
    /// separate solves, per source).
    pub form_factor_rows: usize,
    /// Shots that reused a kept row ([`SolverSettings::row_cache_bytes`]) instead of
    /// computing it.
    pub reused_rows: usize,
    /// Bytes of the kept rows at the end of the solve (the largest over sources for
    /// separate solves).
    pub row_cache_bytes: usize,
    /// Of the shots, those of a cluster of small patches
    /// ([`SolverSettings::cluster_members`]).
    pub cluster_shots: usize,
    /// The unshot fraction left (the largest over sources for separate solves).
    pub unshot_fraction: f64,
    /// Wall-clock time.
    pub time: Duration,
    /// What the hierarchical solve built (`None` for progressive refinement).
    pub hierarchy: Option<crate::hierarchical::HierarchyStats>,
}

/// k single-source solutions over one meshing.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// The sources, in solution order.
    pub sources: Vec<Source>,
    /// Number of elements (the element-major arrays hold `elements * k` values; with no
    /// source they are empty, and relighting still gives one value per element).
    pub elements: usize,
    /// Irradiance received straight from each source, element-major: `direct[j * k + m]`.
    pub direct: Vec<Vec3>,
    /// Irradiance received after one or more reflections, the same layout.
    pub indirect: Vec<Vec3>,
    /// Cohen's ambient irradiance per source (zero when off), for reporting: it is already
    /// added to the indirect irradiance of every element the source reached (directly or
    /// after reflections), and to no other.
    pub ambient: Vec<Vec3>,
    /// What the solve did.
    pub stats: SolveStats,
}

impl Solution {
    /// Number of sources.
    pub fn k(&self) -> usize {
        self.sources.len()
    }

    /// The source holding light `id`.
    pub fn source_of(&self, id: LightId) -> Option<usize> {
        self.sources.iter().position(|s| s.lights.contains(&id))
    }

    /// This solution, solved over `meshing`'s mesh elements, reduced to one value per
    /// group of [`Meshing::groups`] (unchanged when each element is a group of its own).
    pub fn into_groups(mut self, meshing: &Meshing) -> Self {
        let groups = &meshing.groups;
        if self.elements != meshing.elements.len() || groups.is_identity() {
            return self;
        }
        let k = self.k();
        self.direct = groups.reduce(&meshing.elements, &self.direct, k);
        self.indirect = groups.reduce(&meshing.elements, &self.indirect, k);
        self.elements = groups.count;
        self
    }

    /// The index of mesh element `j`'s values in this solution's element-major arrays
    /// (times the source count): its group's ([`Meshing::groups`]).
    pub fn slot(&self, meshing: &Meshing, j: usize) -> usize {
        meshing.slot(j, self.elements)
    }
}

/// The sources of `scene` under `banks`: each bank, then every light in no bank.
pub fn sources(scene: &Scene, banks: &[Vec<LightId>]) -> Result<Vec<Source>, RelightError> {
    let ids = light_ids(scene);
    let mut out: Vec<Source> = Vec::new();
    for bank in banks {
        for id in bank {
            if !ids.contains(id) {
                return Err(RelightError::UnknownLight(format!(
                    "{id:?} (the scene's lights: {ids:?})"
                )));
            }
            if out.iter().any(|s| s.lights.contains(id)) {
                return Err(RelightError::InvalidSetting(format!(
                    "{id:?} is in two banks"
                )));
            }
        }
        if !bank.is_empty() {
            out.push(Source {
                lights: bank.clone(),
            });
        }
    }
    for id in ids {
        if !out.iter().any(|s| s.lights.contains(&id)) {
            out.push(Source { lights: vec![id] });
        }
    }
    Ok(out)
}

/// Solves `meshing` of `scene` with `settings` (its strategy and banks). `rays` must be
/// built from `scene` (the visibility of form factors and of point and directional
/// lights). `progress` is called after each shot with the unshot fraction (the
/// hierarchical solve, [`SolverSettings::hierarchy`], calls it with the share of its work
/// left, from 1 to 0). The ray-cast
/// method needs no renderer; for [`FormFactorMethod::Hemicube`] use [`solve_with`].
pub fn solve(
    scene: &Scene,
    meshing: &Meshing,
    rays: &RayScene,
    settings: &SolverSettings,
    progress: &mut dyn FnMut(f64),
) -> Result<Solution, RelightError> {
    solve_with(scene, meshing, rays, None, settings, progress)
}

/// [`solve`] with a G-buffer renderer for hemicube form factors (it is prepared here with
/// the element scene, [`Meshing::element_scene`]).
pub fn solve_with(
    scene: &Scene,
    meshing: &Meshing,
    rays: &RayScene,
    mut renderer: Option<&mut (dyn scene_core::GBufferRenderer + Send)>,
    settings: &SolverSettings,
    progress: &mut dyn FnMut(f64),
) -> Result<Solution, RelightError> {
    check_and_prepare(scene, meshing, &mut renderer, settings)?;
    let start = Instant::now();
    let sources = sources(scene, &settings.banks)?;
    if let Some(h) = &settings.hierarchy_for(meshing.elements.len()) {
        let sources = match (settings.strategy, settings.form_factors) {
            (Strategy::Tagged, FormFactorMethod::Rays) => sources,
            (Strategy::Combined, FormFactorMethod::Rays) => vec![Source {
                lights: sources.iter().flat_map(|s| s.lights.clone()).collect(),
            }],
            _ => {
                return Err(RelightError::InvalidSetting(
                    "the hierarchical solve takes the tagged or combined strategy with ray-cast \
                     form factors"
                        .into(),
                ));
            }
        };
        return crate::hierarchical::solve(scene, meshing, rays, sources, settings, h, progress)
            .map(|s| s.into_groups(meshing));
    }
    let mut solution = match settings.strategy {
        Strategy::Tagged => solve_tagged(
            scene,
            meshing,
            rays,
            &mut renderer,
            sources,
            settings,
            progress,
        )?,
        Strategy::Combined => {
            let all = Source {
                lights: sources.iter().flat_map(|s| s.lights.clone()).collect(),
            };
            solve_tagged(
                scene,
                meshing,
                rays,
                &mut renderer,
                vec![all],
                settings,
                progress,
            )?
        }
        Strategy::Separate => {
            let n = meshing.elements.len();
            let k = sources.len();
            let mut direct = vec![Vec3::ZERO; n * k];
            let mut indirect = vec![Vec3::ZERO; n * k];
            let mut ambient = vec![Vec3::ZERO; k];
            let mut stats = SolveStats::default();
            for (m, source) in sources.iter().enumerate() {
                let one = solve_tagged(
                    scene,
                    meshing,
                    rays,
                    &mut renderer,
                    vec![source.clone()],
                    settings,
                    progress,
                )?;
                for j in 0..n {
                    direct[j * k + m] = one.direct[j];
                    indirect[j * k + m] = one.indirect[j];
                }
                ambient[m] = one.ambient[0];
                stats.shots += one.stats.shots;
                stats.form_factor_rows += one.stats.form_factor_rows;
                stats.reused_rows += one.stats.reused_rows;
                stats.row_cache_bytes = stats.row_cache_bytes.max(one.stats.row_cache_bytes);
                stats.unshot_fraction = stats.unshot_fraction.max(one.stats.unshot_fraction);
            }
            Solution {
                sources,
                elements: n,
                direct,
                indirect,
                ambient,
                stats,
            }
        }
    };
    solution.stats.time = start.elapsed();
    Ok(solution.into_groups(meshing))
}

/// Checks `settings` (visibility samples, unshot limit, hemicube resolution and renderer)
/// and, for hemicube form factors, prepares the renderer with `meshing`'s element scene:
/// what every solve over a meshing does first.
pub(crate) fn check_and_prepare(
    scene: &Scene,
    meshing: &Meshing,
    renderer: &mut Option<&mut (dyn scene_core::GBufferRenderer + Send)>,
    settings: &SolverSettings,
) -> Result<(), RelightError> {
    if let FormFactorMethod::Hemicube { resolution } = settings.form_factors {
        if !(MIN_HEMICUBE..=8192).contains(&resolution) {
            return Err(RelightError::InvalidSetting(format!(
                "hemicube resolution {resolution} is outside [{MIN_HEMICUBE}, 8192] (a coarser \
                 hemicube's pixels carry form factors above 1 and the solve gains energy)"
            )));
        }
        let Some(r) = renderer.as_deref_mut() else {
            return Err(RelightError::InvalidSetting(
                "hemicube form factors need a G-buffer renderer (solve_with)".into(),
            ));
        };
        r.prepare(std::sync::Arc::new(meshing.element_scene(scene)))
            .map_err(|e| RelightError::Render(Box::new(e)))?;
    }
    if settings.visibility_samples == 0 || settings.max_unshot.is_nan() || settings.max_unshot < 0.0
    {
        return Err(RelightError::InvalidSetting(format!(
            "visibility_samples {} (at least 1), max_unshot {} (at least 0)",
            settings.visibility_samples, settings.max_unshot
        )));
    }
    Ok(())
}

/// The figure 2 loop for `sources` at once.
fn solve_tagged(
    scene: &Scene,
    meshing: &Meshing,
    rays: &RayScene,
    renderer: &mut Option<&mut (dyn scene_core::GBufferRenderer + Send)>,
    sources: Vec<Source>,
    settings: &SolverSettings,
    progress: &mut dyn FnMut(f64),
) -> Result<Solution, RelightError> {
    let (n, np, k) = (meshing.elements.len(), meshing.patches.len(), sources.len());
    let els = &meshing.elements;
    let patches = &meshing.patches;
    let source_of = |id: LightId| sources.iter().position(|s| s.lights.contains(&id));
    let mut direct = vec![Vec3::ZERO; n * k];
    let indirect = vec![Vec3::ZERO; n * k];
    // Unshot radiosity per patch and source: emission (shot as direct light) and reflected.
    let mut unshot_emit = vec![Vec3::ZERO; np * k];
    let mut unshot_refl = vec![Vec3::ZERO; np * k];
    for (p, patch) in patches.iter().enumerate() {
        if let Some(m) = patch.light.and_then(source_of) {
            let e = els[patch.first_element as usize].emission;
            unshot_emit[p * k + m] = e * std::f32::consts::PI;
        }
    }
    // Point and directional lights and the sky shoot their first energy analytically, with
    // rays.
    let extent = scene.extent();
    analytic_direct(scene, meshing, rays, &sources, &mut direct);
    // What the analytic shots left on the patches to reflect.
    reflect_onto_patches(meshing, &direct, k, &mut unshot_refl);
    let mut state = Shooting {
        k,
        direct,
        indirect,
        unshot_emit,
        unshot_refl,
    };
    let (stats, ambient) = propagate(
        meshing, rays, extent, renderer, &mut state, settings, progress,
    )?;
    let Shooting {
        direct, indirect, ..
    } = state;
    Ok(Solution {
        sources,
        elements: meshing.elements.len(),
        direct,
        indirect,
        ambient,
        stats,
    })
}

/// Adds to `direct` (element-major, `j * k + m` for the `k` `sources`) each element's mean
/// irradiance from the analytic lights of each source: point and spot lights, directional
/// lights and the sky ([`direct::element_from_analytic`], visibility at the element's
/// The fewest items a task of the solver's cheap per-element passes (adding a shot's
/// energy, spreading it over a patch) takes: on a small mesh a task per element cost more
/// in thread wake-ups than the pass (a 38-triangle room with a 64-direction sky spent most
/// of its solve in the scheduler). Each item is computed alone, so the split changes no
/// figure.
const CHEAP_MIN_LEN: usize = 512;

/// receiver points). Emissive meshes are left to the solve.
pub(crate) fn analytic_direct(
    scene: &Scene,
    meshing: &Meshing,
    rays: &RayScene,
    sources: &[Source],
    direct: &mut [Vec3],
) {
    let (els, k, extent) = (&meshing.elements, sources.len(), scene.extent());
    for (m, source) in sources.iter().enumerate() {
        for &id in &source.lights {
            if matches!(id, LightId::Emissive(_)) {
                continue;
            }
            let received: Vec<Vec3> = els
                .par_iter()
                .map(|e| direct::element_from_analytic(scene, id, rays, e, extent))
                .collect();
            for (j, r) in received.into_iter().enumerate() {
                direct[j * k + m] += r;
            }
        }
    }
}

/// The coarsest hemicube form factors are taken with: at a resolution of 1 the top face's
/// single pixel carries a delta form factor of 4/pi.
pub const MIN_HEMICUBE: u32 = 16;

/// The unshot fraction above which a solve has gained energy. Each shot of an
/// energy-conserving solve (albedo below 1, form factors summing to at most 1) leaves less
/// unshot energy than it found, so the fraction starts at 1 and falls; estimated form
/// factors may sum slightly above 1, and 1.5 leaves room for that noise.
pub const DIVERGED_FRACTION: f64 = 1.5;

/// [`RelightError::Diverged`] when the unshot `fraction` is non-finite or above
/// [`DIVERGED_FRACTION`]: checked before every shot, so a diverging solve stops at once
/// rather than at the shot cap.
pub fn check_energy(shots: usize, fraction: f64) -> Result<(), RelightError> {
    if fraction.is_finite() && fraction <= DIVERGED_FRACTION {
        Ok(())
    } else {
        Err(RelightError::Diverged { shots, fraction })
    }
}

/// The state of a progressive refinement with `k` tagged sources: irradiance received
/// (direct and indirect, element-major `j * k + m`) and unshot radiosity per patch
/// (emitted and reflected, patch-major `p * k + m`).
pub(crate) struct Shooting {
    pub(crate) k: usize,
    pub(crate) direct: Vec<Vec3>,
    pub(crate) indirect: Vec<Vec3>,
    pub(crate) unshot_emit: Vec<Vec3>,
    pub(crate) unshot_refl: Vec<Vec3>,
}

/// Adds what the elements' `direct` irradiance reflects to their patches' unshot radiosity:
/// `sum_e rho_e E_e A_e / A_p` per patch and source.
pub(crate) fn reflect_onto_patches(
    meshing: &Meshing,
    direct: &[Vec3],
    k: usize,
    unshot_refl: &mut [Vec3],
) {
    let els = &meshing.elements;
    for (p, patch) in meshing.patches.iter().enumerate() {
        let first = patch.first_element as usize;
        if patch.open_area <= 0.0 {
            continue;
        }
        for m in 0..k {
            let mut sum = Vec3::ZERO;
            for e in (first..first + patch.element_count as usize).filter(|&e| !els[e].hidden) {
                sum += els[e].albedo * direct[e * k + m] * els[e].area;
            }
            unshot_refl[p * k + m] += sum / patch.open_area;
        }
    }
}

/// Figure 2's loop from `state` until the unshot fraction (of the energy emitted and
/// received directly at the start) is below the settings' limit or the shot cap is met;
/// then Cohen's ambient term per source, added to the elements each source reached.
/// Returns the stats and the ambient irradiance per source.
pub(crate) fn propagate(
    meshing: &Meshing,
    rays: &RayScene,
    extent: f32,
    renderer: &mut Option<&mut (dyn scene_core::GBufferRenderer + Send)>,
    state: &mut Shooting,
    settings: &SolverSettings,
    progress: &mut dyn FnMut(f64),
) -> Result<(SolveStats, Vec<Vec3>), RelightError> {
    let (n, np, k) = (meshing.elements.len(), meshing.patches.len(), state.k);
    let els = &meshing.elements;
    let patches = &meshing.patches;
    let Shooting {
        direct,
        indirect,
        unshot_emit,
        unshot_refl,
        ..
    } = state;
    let power = |u: &[Vec3], p: usize| -> f64 {
        (0..k).map(|m| luminance(u[p * k + m]) as f64).sum::<f64>() * patches[p].open_area as f64
    };
    let unshot_power =
        |ue: &[Vec3], ur: &[Vec3]| -> f64 { (0..np).map(|p| power(ue, p) + power(ur, p)).sum() };
    // The emitted energy the fraction is measured against: the emitters' radiosity and
    // what the point and directional lights delivered, reflected or not.
    let emitted = {
        let received: f64 = (0..n)
            .map(|j| {
                (0..k)
                    .map(|m| luminance(direct[j * k + m]) as f64)
                    .sum::<f64>()
                    * els[j].area as f64
            })
            .sum();
        (0..np).map(|p| power(unshot_emit, p)).sum::<f64>() + received
    };
    if !emitted.is_finite() {
        return Err(RelightError::Diverged {
            shots: 0,
            fraction: emitted,
        });
    }
    let mut stats = SolveStats {
        unshot_fraction: if emitted > 0.0 { 1.0 } else { 0.0 },
        ..Default::default()
    };
    let samples = settings.visibility_samples;
    let element_area = (meshing.patch_area * 0.25).max(f32::MIN_POSITIVE);
    let normals: Vec<Vec3> = els.iter().map(|e| e.normal).collect();
    let mut form = vec![0.0f32; n];
    // Kept rows: the receivers with a form factor above 0 and their form factors.
    let mut kept: Vec<Option<Vec<(u32, f32)>>> = vec![None; np];
    // Clusters of small patches, shot together (rays only).
    let clusters = match settings.form_factors {
        FormFactorMethod::Rays if settings.cluster_members > 1 => {
            small_patch_clusters(meshing, settings.cluster_members)
        }
        _ => Vec::new(),
    };
    let mut cluster_of = vec![u32::MAX; np];
    for (c, members) in clusters.iter().enumerate() {
        for &p in members {
            cluster_of[p as usize] = c as u32;
        }
    }
    let mut cluster_power = vec![0.0f64; clusters.len()];
    let mut gains = if clusters.is_empty() {
        (Vec::new(), Vec::new())
    } else {
        (vec![Vec3::ZERO; n * k], vec![Vec3::ZERO; n * k])
    };
    while emitted > 0.0 && stats.shots < settings.max_shots {
        // One pass over the patches gives the unshot total and the patch or cluster with
        // the most unshot energy over all sources (ties: the first patch, then the first
        // cluster).
        let (mut unshot, mut best) = (0.0f64, (0usize, -1.0f64));
        cluster_power.iter_mut().for_each(|w| *w = 0.0);
        for (p, &cluster) in cluster_of.iter().enumerate() {
            let w = power(unshot_emit, p) + power(unshot_refl, p);
            unshot += w;
            match cluster {
                u32::MAX if w > best.1 => best = (p, w),
                u32::MAX => {}
                c => cluster_power[c as usize] += w,
            }
        }
        let fraction = unshot / emitted;
        stats.unshot_fraction = fraction;
        check_energy(stats.shots, fraction)?;
        if fraction <= settings.max_unshot {
            break;
        }
        let (mut best_cluster, mut top) = (None, best.1);
        for (c, &w) in cluster_power.iter().enumerate() {
            if w > top {
                (best_cluster, top) = (Some(c), w);
            }
        }
        if let Some(c) = best_cluster {
            shoot_cluster(
                meshing,
                rays,
                &clusters[c],
                state_parts(direct, indirect, unshot_emit, unshot_refl, k),
                &mut gains,
                (
                    samples,
                    element_area,
                    settings.full_visibility_at,
                    stats.shots as u64,
                ),
            );
            stats.shots += 1;
            stats.form_factor_rows += 1;
            stats.cluster_shots += 1;
            progress(fraction);
            continue;
        }
        let p = best.0;
        let patch = patches[p];
        if let Some(row) = &kept[p] {
            form.iter_mut().for_each(|f| *f = 0.0);
            for &(j, f) in row {
                form[j as usize] = f;
            }
            stats.reused_rows += 1;
        } else if let (FormFactorMethod::Hemicube { resolution }, Some(r)) =
            (settings.form_factors, renderer.as_deref_mut())
        {
            let centre = (patch.corners[0] + patch.corners[1] + patch.corners[2]) / 3.0;
            let row = crate::form_factor::hemicube_row(
                r,
                centre + patch.normal * (1e-5 * extent),
                patch.normal,
                resolution,
                1e-5 * extent,
                2.0 * extent,
                &normals,
            )
            .map_err(|e| RelightError::Render(Box::new(e)))?;
            // Patch-to-element form factors to the receivers' form: F_ji = F_ij A_i / A_j.
            // An alpha-masked receiver shows the hemicube its solid part only: its
            // irradiance is what that part receives over that part's area.
            for (j, f) in form.iter_mut().enumerate() {
                let e = &els[j];
                *f = if e.patch as usize == p || e.coverage <= 0.0 {
                    0.0
                } else {
                    row[j] * patch.area / (e.area * e.coverage)
                };
            }
        } else {
            form.par_iter_mut().enumerate().for_each(|(j, f)| {
                let e = &els[j];
                *f = if e.patch as usize == p {
                    0.0
                } else {
                    // The element's average over its open receiver points, the visibility
                    // rays shared out among them. An element that is a whole triangle
                    // smaller than an element of the target size gets rays in proportion
                    // to its area (at least one), and when they are fewer than its open
                    // points, receives at one of them (its centroid where open).
                    let (points, count) = e.open_receiver_points();
                    let budget = receiver_rays(meshing, j, samples, element_area);
                    let chosen = if (budget as usize) < count {
                        &points[count - 1..count]
                    } else {
                        &points[..count]
                    };
                    let count = chosen.len();
                    let per_point = budget.div_ceil(count.max(1) as u32);
                    chosen
                        .iter()
                        .map(|&(r, x)| {
                            point_to_triangle_adaptive(
                                x,
                                e.normal,
                                &patch.corners,
                                patch.normal,
                                rays,
                                (per_point, settings.full_visibility_at),
                                ((p as u64) << 34) | ((j as u64) << 2) | r as u64,
                            )
                        })
                        .sum::<f32>()
                        / count.max(1) as f32
                };
            });
        }
        if kept[p].is_none() {
            stats.form_factor_rows += 1;
            // Counted before anything is allocated: once the budget is spent, a new row
            // costs one pass over the form factors and no allocation.
            let bytes =
                std::mem::size_of::<(u32, f32)>() * form.iter().filter(|&&f| f > 0.0).count();
            if stats.row_cache_bytes + bytes <= settings.row_cache_bytes {
                stats.row_cache_bytes += bytes;
                let row = form.iter().enumerate().filter(|&(_, &f)| f > 0.0);
                kept[p] = Some(row.map(|(j, &f)| (j as u32, f)).collect());
            }
        }
        let ue: Vec<Vec3> = unshot_emit[p * k..p * k + k].to_vec();
        let ur: Vec<Vec3> = unshot_refl[p * k..p * k + k].to_vec();
        for m in 0..k {
            unshot_emit[p * k + m] = Vec3::ZERO;
            unshot_refl[p * k + m] = Vec3::ZERO;
        }
        direct
            .par_chunks_mut(k)
            .zip(indirect.par_chunks_mut(k))
            .zip(form.par_iter())
            .with_min_len(CHEAP_MIN_LEN)
            .for_each(|((d, i), &f)| {
                if f > 0.0 {
                    for m in 0..k {
                        d[m] += ue[m] * f;
                        i[m] += ur[m] * f;
                    }
                }
            });
        // Receivers' reflected energy onto their patches, patch by patch (deterministic).
        unshot_refl
            .par_chunks_mut(k)
            .enumerate()
            .with_min_len(CHEAP_MIN_LEN)
            .for_each(|(q, u)| {
                let first = patches[q].first_element as usize;
                if patches[q].open_area <= 0.0 {
                    return;
                }
                let inv = 1.0 / patches[q].open_area;
                let count = patches[q].element_count as usize;
                for e in (first..first + count).filter(|&e| !els[e].hidden) {
                    let f = form[e];
                    if f > 0.0 {
                        let w = els[e].albedo * (f * els[e].area * inv);
                        for m in 0..k {
                            u[m] += w * (ue[m] + ur[m]);
                        }
                    }
                }
            });
        stats.shots += 1;
        progress(fraction);
    }
    if emitted > 0.0 {
        stats.unshot_fraction = unshot_power(unshot_emit, unshot_refl) / emitted;
    }
    // Cohen's ambient term: the unshot radiosity spread over the scene, reflected
    // R = 1 / (1 - rho_avg) times.
    let mut ambient = vec![Vec3::ZERO; k];
    if settings.ambient {
        let open = || els.iter().filter(|e| !e.hidden);
        let total_area: f32 = open().map(|e| e.area).sum();
        if total_area > 0.0 {
            let rho: Vec3 = open().map(|e| e.albedo * e.area).sum::<Vec3>() / total_area;
            let r = Vec3::ONE / (Vec3::ONE - rho).max(Vec3::splat(1e-3));
            for (m, a) in ambient.iter_mut().enumerate() {
                let u: Vec3 = (0..np)
                    .map(|p| {
                        (unshot_emit[p * k + m] + unshot_refl[p * k + m]) * patches[p].open_area
                    })
                    .sum();
                *a = r * u / total_area;
            }
        }
    }
    // The ambient term goes into the indirect light of the elements the source reached,
    // not to every element: a room the source cannot see stays dark (a global term would
    // leak the unshot fraction through every wall).
    if ambient.iter().any(|a| *a != Vec3::ZERO) {
        indirect
            .par_chunks_mut(k)
            .zip(direct.par_chunks(k))
            .with_min_len(CHEAP_MIN_LEN)
            .for_each(|(i, d)| {
                for m in 0..k {
                    if d[m] != Vec3::ZERO || i[m] != Vec3::ZERO {
                        i[m] += ambient[m];
                    }
                }
            });
    }
    Ok((stats, ambient))
}

/// The visibility rays of receiver `j` (before [`SolverSettings::full_visibility_at`]):
/// `samples`, or for an element that is a whole triangle smaller than an element of the
/// target size (`element_area`), rays in proportion to its area, at least one.
fn receiver_rays(meshing: &Meshing, j: usize, samples: u32, element_area: f32) -> u32 {
    let e = &meshing.elements[j];
    if meshing.patches[e.patch as usize].element_count == 1 {
        ((samples as f32 * e.area / element_area).ceil() as u32).clamp(1, samples)
    } else {
        samples
    }
}

/// The most members a cluster holds, whatever [`SolverSettings::cluster_members`] asks.
pub const MAX_CLUSTER_MEMBERS: usize = 64;

/// The patches of one element (whole triangles smaller than an element) in clusters of
/// spatial neighbours: sorted along a Morton curve of their centres (over the scene's
/// bounds, 2^10 cells a side), then cut into runs of at most `max_members` whose bounding
/// box stays within the side of a target patch (`sqrt(patch_area)`). Hidden patches (no
/// open area, nothing to shoot) and runs of one are left out: those shoot alone.
pub fn small_patch_clusters(meshing: &Meshing, max_members: usize) -> Vec<Vec<u32>> {
    let centre = |p: &crate::mesh::Patch| (p.corners[0] + p.corners[1] + p.corners[2]) / 3.0;
    let small: Vec<u32> = (0..meshing.patches.len() as u32)
        .filter(|&p| {
            let patch = &meshing.patches[p as usize];
            patch.element_count == 1 && patch.open_area > 0.0
        })
        .collect();
    let max_members = max_members.min(MAX_CLUSTER_MEMBERS);
    if small.len() < 2 || max_members < 2 {
        return Vec::new();
    }
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for &p in &small {
        let c = centre(&meshing.patches[p as usize]);
        lo = lo.min(c);
        hi = hi.max(c);
    }
    let size = (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE));
    let spread = |v: u32| -> u64 {
        // The 10 bits of v, two zero bits between each.
        let mut out = 0u64;
        for b in 0..10 {
            out |= u64::from((v >> b) & 1) << (3 * b);
        }
        out
    };
    let mut keyed: Vec<(u64, u32)> = small
        .iter()
        .map(|&p| {
            let q = ((centre(&meshing.patches[p as usize]) - lo) / size * 1023.0)
                .clamp(Vec3::ZERO, Vec3::splat(1023.0));
            let code = spread(q.x as u32) | spread(q.y as u32) << 1 | spread(q.z as u32) << 2;
            (code, p)
        })
        .collect();
    keyed.sort_unstable();
    let side = meshing.patch_area.sqrt();
    let mut clusters = Vec::new();
    let mut run: Vec<u32> = Vec::new();
    let (mut rlo, mut rhi) = (Vec3::ZERO, Vec3::ZERO);
    for (_, p) in keyed {
        let patch = &meshing.patches[p as usize];
        let (plo, phi) = patch.corners.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(a, b), &c| (a.min(c), b.max(c)),
        );
        let fits = !run.is_empty()
            && run.len() < max_members
            && (rhi.max(phi) - rlo.min(plo)).max_element() <= side;
        if fits {
            run.push(p);
            rlo = rlo.min(plo);
            rhi = rhi.max(phi);
        } else {
            if run.len() > 1 {
                clusters.push(std::mem::take(&mut run));
            }
            run.clear();
            run.push(p);
            (rlo, rhi) = (plo, phi);
        }
    }
    if run.len() > 1 {
        clusters.push(run);
    }
    clusters
}

/// The parts of a [`Shooting`] a cluster shot changes.
type ShootingParts<'a> = (
    &'a mut [Vec3],
    &'a mut [Vec3],
    &'a mut [Vec3],
    &'a mut [Vec3],
    usize,
);

fn state_parts<'a>(
    direct: &'a mut [Vec3],
    indirect: &'a mut [Vec3],
    unshot_emit: &'a mut [Vec3],
    unshot_refl: &'a mut [Vec3],
    k: usize,
) -> ShootingParts<'a> {
    (direct, indirect, unshot_emit, unshot_refl, k)
}

/// One shot of a cluster of small patches (`members`), every source at once. Each member
/// is a small disk of its area: an element at `x` (normal `n`) would receive
/// `B_m F_m`, `F_m = A_m cos_x cos_m / (pi r^2 + A_m)` (the disk form factor, bounded where
/// `r` is small; the exact closed form within four member sizes). The sum over members is
/// estimated by importance sampling with visibility: each visibility ray goes to a member
/// picked (stratified) with probability `p_m` proportional to `F_m` times its unshot
/// luminance, and a ray that arrives adds `F_m B_m / p_m` over the ray count. Only members
/// the element sees give it energy, so a cluster spanning both sides of a wall does not
/// carry light through it. The rays follow the rule of a patch's shot: `samples`, or fewer
/// for a receiver that is itself small. `gains` are scratch (emitted and reflected
/// irradiance per element and source).
fn shoot_cluster(
    meshing: &Meshing,
    rays: &RayScene,
    members: &[u32],
    (direct, indirect, unshot_emit, unshot_refl, k): ShootingParts<'_>,
    gains: &mut (Vec<Vec3>, Vec<Vec3>),
    (samples, element_area, full_at, shot): (u32, f32, f32, u64),
) {
    let els = &meshing.elements;
    let patches = &meshing.patches;
    struct Member {
        centre: Vec3,
        corners: [Vec3; 3],
        normal: Vec3,
        area: f32,
        /// Its open fraction (open area over area).
        open: f32,
        patch: u32,
        /// The sources it has unshot energy of, with (emitted, reflected) radiosity.
        energy: Vec<(usize, Vec3, Vec3)>,
        weight: f32,
    }
    let members: Vec<Member> = members
        .iter()
        .map(|&p| {
            let patch = &patches[p as usize];
            let energy: Vec<(usize, Vec3, Vec3)> = (0..k)
                .filter_map(|m| {
                    let (e, r) = (
                        unshot_emit[p as usize * k + m],
                        unshot_refl[p as usize * k + m],
                    );
                    (e != Vec3::ZERO || r != Vec3::ZERO).then_some((m, e, r))
                })
                .collect();
            let weight = energy.iter().map(|(_, e, r)| luminance(*e + *r)).sum();
            Member {
                centre: (patch.corners[0] + patch.corners[1] + patch.corners[2]) / 3.0,
                corners: patch.corners,
                normal: patch.normal,
                area: patch.open_area,
                open: patch.open_area / patch.area.max(f32::MIN_POSITIVE),
                patch: p,
                energy,
                weight,
            }
        })
        .collect();
    for &p in members.iter().map(|m| &m.patch) {
        for m in 0..k {
            unshot_emit[p as usize * k + m] = Vec3::ZERO;
            unshot_refl[p as usize * k + m] = Vec3::ZERO;
        }
    }
    let (gain_emit, gain_refl) = gains;
    gain_emit
        .par_chunks_mut(k)
        .zip(gain_refl.par_chunks_mut(k))
        .enumerate()
        .for_each(|(j, (ge, gr))| {
            ge.fill(Vec3::ZERO);
            gr.fill(Vec3::ZERO);
            let e = &els[j];
            let (points, count) = e.open_receiver_points();
            if count == 0 {
                return;
            }
            // The receiver point: its centroid where open (the last of its open points).
            let x = points[count - 1].1;
            let n = e.normal;
            let mut f = [0.0f32; MAX_CLUSTER_MEMBERS];
            let (mut total, mut f_sum) = (0.0f32, 0.0f32);
            for (i, m) in members.iter().enumerate() {
                f[i] = 0.0;
                if m.patch == e.patch || m.weight <= 0.0 {
                    continue;
                }
                let d = m.centre - x;
                let r2 = d.length_squared();
                let r = r2.sqrt();
                let (cx, cm) = (n.dot(d) / r, -m.normal.dot(d) / r);
                if !(cx > 0.0 && cm > 0.0) {
                    continue;
                }
                // Near a member (within four of its sizes) the disk is too coarse: its
                // exact closed form, as a patch's shot uses.
                f[i] = if r2 < 16.0 * m.area {
                    crate::form_factor::point_to_polygon(x, n, &m.corners) * m.open
                } else {
                    m.area * cx * cm / (std::f32::consts::PI * r2 + m.area)
                };
                total += f[i] * m.weight;
                f_sum += f[i];
            }
            if total <= 0.0 {
                return;
            }
            // Visibility: stratified picks among the members in proportion to f * weight.
            let budget = receiver_rays(meshing, j, samples, element_area);
            let budget = crate::form_factor::adaptive_samples(f_sum, budget, full_at);
            let mut rng = scene_core::sampling::Rng::new(shot, j as u64);
            let offset = rng.next_f32();
            for s in 0..budget {
                let target = (s as f32 + offset) / budget as f32 * total;
                let mut acc = 0.0;
                let mut pick = None;
                for (i, m) in members.iter().enumerate() {
                    acc += f[i] * m.weight;
                    if f[i] > 0.0 {
                        pick = Some(i);
                        if acc >= target {
                            break;
                        }
                    }
                }
                let Some(i) = pick else { break };
                let m = &members[i];
                let dist = m.centre.distance(x);
                if dist > 0.0 && visibility::sees_surface_point(rays, x, n, m.centre, dist) {
                    // The member's share, f_i u_i / p_i with p_i = f_i w_i / total.
                    let scale = total / (m.weight * budget as f32);
                    for &(src, em, rf) in &m.energy {
                        ge[src] += em * scale;
                        gr[src] += rf * scale;
                    }
                }
            }
        });
    direct
        .par_iter_mut()
        .zip(indirect.par_iter_mut())
        .zip(gain_emit.par_iter().zip(gain_refl.par_iter()))
        .with_min_len(CHEAP_MIN_LEN)
        .for_each(|((d, i), (ge, gr))| {
            *d += *ge;
            *i += *gr;
        });
    // The receivers reflect what they got onto their patches.
    unshot_refl
        .par_chunks_mut(k)
        .enumerate()
        .with_min_len(CHEAP_MIN_LEN)
        .for_each(|(q, u)| {
            let patch = &patches[q];
            if patch.open_area <= 0.0 {
                return;
            }
            let first = patch.first_element as usize;
            let inv = 1.0 / patch.open_area;
            for e in (first..first + patch.element_count as usize).filter(|&e| !els[e].hidden) {
                let w = els[e].albedo * (els[e].area * inv);
                for m in 0..k {
                    let g = gain_emit[e * k + m] + gain_refl[e * k + m];
                    if g != Vec3::ZERO {
                        u[m] += w * g;
                    }
                }
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The solver is chosen by the meshing's size: progressive up to the threshold,
    /// hierarchical above it; a strategy or form factors the hierarchical solve cannot run
    /// keep the progressive one unless the threshold is 0 (which the solve refuses).
    #[test]
    fn the_solver_is_chosen_by_the_element_count() {
        let d = SolverSettings::default();
        assert_eq!(d.hierarchy_for(d.hierarchy_above), None);
        assert_eq!(d.hierarchy_for(d.hierarchy_above + 1), d.hierarchy);
        let never = SolverSettings {
            hierarchy: None,
            ..Default::default()
        };
        assert_eq!(never.hierarchy_for(usize::MAX), None);
        let always = SolverSettings {
            hierarchy_above: 0,
            ..Default::default()
        };
        assert_eq!(always.hierarchy_for(1), d.hierarchy);
        let hemicube = SolverSettings {
            form_factors: FormFactorMethod::Hemicube { resolution: 64 },
            ..Default::default()
        };
        assert_eq!(hemicube.hierarchy_for(1 << 20), None);
        let separate = SolverSettings {
            strategy: Strategy::Separate,
            hierarchy_above: 0,
            ..Default::default()
        };
        assert!(separate.hierarchy_for(1).is_some());
    }
}
