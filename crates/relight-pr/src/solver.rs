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
use crate::form_factor::point_to_triangle;
use crate::mesh::Meshing;

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
    /// Rows of form factors computed (one per shot and, for separate solves, per source).
    pub form_factor_rows: usize,
    /// The unshot fraction left (the largest over sources for separate solves).
    pub unshot_fraction: f64,
    /// Wall-clock time.
    pub time: Duration,
}

/// k single-source solutions over one meshing.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// The sources, in solution order.
    pub sources: Vec<Source>,
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
/// lights). `progress` is called after each shot with the unshot fraction. The ray-cast
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
                stats.unshot_fraction = stats.unshot_fraction.max(one.stats.unshot_fraction);
            }
            Solution {
                sources,
                direct,
                indirect,
                ambient,
                stats,
            }
        }
    };
    solution.stats.time = start.elapsed();
    Ok(solution)
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
        if resolution == 0 {
            return Err(RelightError::InvalidSetting("hemicube resolution 0".into()));
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
    // Point and directional lights shoot their first energy analytically, with rays.
    let extent = scene.extent();
    for (m, source) in sources.iter().enumerate() {
        for &id in &source.lights {
            // The element's mean irradiance (visibility at its four receiver points).
            let shoot: Box<dyn Fn(&crate::mesh::Element) -> Vec3 + Sync> = match id {
                LightId::Point(i) => {
                    let l = &scene.point_lights[i as usize];
                    Box::new(move |e| direct::element_from_point(l, rays, e))
                }
                LightId::Directional(i) => {
                    let l = &scene.directional_lights[i as usize];
                    Box::new(move |e| direct::element_from_directional(l, rays, e, extent))
                }
                LightId::Emissive(_) => continue,
            };
            let received: Vec<Vec3> = els.par_iter().map(&shoot).collect();
            for (j, r) in received.into_iter().enumerate() {
                direct[j * k + m] += r;
            }
        }
    }
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
        direct,
        indirect,
        ambient,
        stats,
    })
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
            for e in (first..first + 4).filter(|&e| !els[e].hidden) {
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
    let mut stats = SolveStats {
        unshot_fraction: if emitted > 0.0 { 1.0 } else { 0.0 },
        ..Default::default()
    };
    let samples = settings.visibility_samples;
    let normals: Vec<Vec3> = els.iter().map(|e| e.normal).collect();
    let mut form = vec![0.0f32; n];
    while emitted > 0.0 && stats.shots < settings.max_shots {
        let fraction = unshot_power(unshot_emit, unshot_refl) / emitted;
        stats.unshot_fraction = fraction;
        if fraction <= settings.max_unshot {
            break;
        }
        // The patch with the most unshot energy over all sources (ties: the first).
        let mut best = (0usize, -1.0f64);
        for p in 0..np {
            let w = power(unshot_emit, p) + power(unshot_refl, p);
            if w > best.1 {
                best = (p, w);
            }
        }
        let p = best.0;
        let patch = patches[p];
        if let (FormFactorMethod::Hemicube { resolution }, Some(r)) =
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
            for (j, f) in form.iter_mut().enumerate() {
                *f = if els[j].patch as usize == p {
                    0.0
                } else {
                    row[j] * patch.area / els[j].area
                };
            }
        } else {
            form.par_iter_mut().enumerate().for_each(|(j, f)| {
                let e = &els[j];
                *f = if e.patch as usize == p {
                    0.0
                } else {
                    // The element's average over its open receiver points, the visibility
                    // rays shared out among them.
                    let (points, count) = e.open_receiver_points();
                    let per_point = samples.div_ceil(count.max(1) as u32);
                    points[..count]
                        .iter()
                        .map(|&(r, x)| {
                            point_to_triangle(
                                x,
                                e.normal,
                                &patch.corners,
                                patch.normal,
                                Some(rays),
                                per_point,
                                ((p as u64) << 34) | ((j as u64) << 2) | r as u64,
                            )
                        })
                        .sum::<f32>()
                        / count.max(1) as f32
                };
            });
        }
        stats.form_factor_rows += 1;
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
            .for_each(|(q, u)| {
                let first = patches[q].first_element as usize;
                if patches[q].open_area <= 0.0 {
                    return;
                }
                let inv = 1.0 / patches[q].open_area;
                for e in (first..first + 4).filter(|&e| !els[e].hidden) {
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
