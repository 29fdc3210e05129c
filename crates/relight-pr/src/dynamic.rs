//! Dynamic scenes, the paper's section 2.4: **moving lights** and **dynamic objects** over a
//! static scene solved once.
//!
//! *Moving lights.* "By regarding patches as light sources during sampling, we obtain a
//! solution in which the emitted energy from each patch can be changed individually."
//! [`Transfer`] is that solution: figure 2's tagged loop with every patch a source of its
//! own (unit radiosity, white), so it holds, for every element `j` and patch `p`, the
//! irradiance `T_jp` that one unit of radiosity leaving `p` delivers to `j` after every
//! reflection. Each frame ([`DynamicScene::frame`]): the moving point lights shoot their
//! direct light onto the elements (closed form, visibility by rays, exactly as the solver's
//! first shot), each patch's emission is set to what it reflects of that light
//! (`B_p = sum_e rho_e E_e A_e / A_p`), and the indirect light is the blend
//! `E_ind,j = sum_p T_jp B_p`. Nothing is solved per frame; the cost is the direct light
//! (rays per element and light) plus the blend (n x P). Its memory, n x P x 12 bytes, is
//! what the paper warns of ("memory intensive for scenes with many patches"): it is
//! checked against a budget before anything is allocated and reported
//! ([`Transfer::bytes`]).
//!
//! *Dynamic objects* "will cast shadows, \[but\] they will not transmit or receive indirect
//! illumination, nor cast shadows due to the indirect illumination." Inserted as triangles
//! ([`DynamicScene::set_objects`]), they block the direct light of every light: the point and
//! directional lights of the static solution are re-shot through the scene's rays and the
//! objects' ([`WithDynamic`]), exactly as the solver shoots them; the direct light of an
//! emissive source keeps its solved value times the fraction of rays to its emitting
//! patches that the objects leave unblocked ([`emitter_visibility`]); the moving lights'
//! direct light is shot through both. The static lights' indirect light is the solved one
//! (the objects do not change it); the moving lights' indirect light is reflected from
//! their shadowed direct light. The objects themselves are not part of the element mesh:
//! an engine draws them with its own direct lighting.

use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;
use scene_core::lights::LightId;
use scene_core::ray::RayScene;
use scene_core::sampling::{hash_seed, r2, uniform_triangle};
use scene_core::{GBufferRenderer, LightState, PointLight, Scene};

use crate::RelightError;
use crate::direct;
use crate::mesh::Meshing;
use crate::relight;
use crate::solver::{self, Shooting, Solution, SolveStats, SolverSettings};
use crate::visibility::{self, Occlusion, WithDynamic};

/// Peak bytes of a patch transfer solution over `n` elements and `p` patches while it is
/// solved: direct and indirect irradiance per element and patch, two unshot values per
/// patch and patch (RGB f32). The kept solution is a third of the first term
/// ([`Transfer::bytes`]).
pub fn transfer_bytes(n: usize, p: usize) -> u64 {
    (n as u64 * p as u64 * 2 + p as u64 * p as u64 * 2) * 12
}

/// Every patch as a light source of its own (section 2.4): the irradiance each element
/// receives per unit radiosity leaving each patch, after every reflection.
#[derive(Clone, Debug, PartialEq)]
pub struct Transfer {
    patches: usize,
    /// `T_jp`, element-major: `values[j * P + p]` is the irradiance at element `j` (W/m^2
    /// per channel) when patch `p` sends out 1 W/m^2 in every channel, first arrival and
    /// every reflection (and the ambient term when the settings ask for it). A patch's own
    /// elements receive nothing at the first arrival.
    pub values: Vec<Vec3>,
    /// What the solve did (shots, rows of form factors, unshot fraction, time).
    pub stats: SolveStats,
}

impl Transfer {
    /// Solves the transfer of `meshing` with ray-cast form factors
    /// ([`Transfer::solve_with`] without a renderer).
    pub fn solve(
        scene: &Scene,
        meshing: &Meshing,
        rays: &RayScene,
        settings: &SolverSettings,
        max_bytes: u64,
        progress: &mut dyn FnMut(f64),
    ) -> Result<Self, RelightError> {
        Self::solve_with(scene, meshing, rays, None, settings, max_bytes, progress)
    }

    /// Solves the transfer of `meshing` of `scene`: figure 2's tagged loop with one source
    /// per patch, `settings` giving the form factors (a renderer is needed for
    /// [`crate::FormFactorMethod::Hemicube`]; it is prepared here with the element scene), the
    /// convergence and the ambient term (its strategy and banks do not apply). Errors with
    /// [`RelightError::Budget`] before allocating when [`transfer_bytes`] exceeds
    /// `max_bytes`. `progress` gets the unshot fraction after every shot.
    pub fn solve_with(
        scene: &Scene,
        meshing: &Meshing,
        rays: &RayScene,
        mut renderer: Option<&mut (dyn GBufferRenderer + Send)>,
        settings: &SolverSettings,
        max_bytes: u64,
        progress: &mut dyn FnMut(f64),
    ) -> Result<Self, RelightError> {
        let (n, np) = (meshing.elements.len(), meshing.patches.len());
        let bytes = transfer_bytes(n, np);
        if bytes > max_bytes {
            return Err(RelightError::Budget(scene_core::BudgetExceeded {
                what: format!("a transfer solution of {np} patches over {n} elements"),
                needed: bytes,
                limit: max_bytes,
                unit: "bytes",
                hint: "the memory budget while solving".into(),
            }));
        }
        solver::check_and_prepare(scene, meshing, &mut renderer, settings)?;
        let start = Instant::now();
        let k = np;
        let mut unshot_emit = vec![Vec3::ZERO; np * k];
        for p in 0..np {
            unshot_emit[p * k + p] = Vec3::ONE;
        }
        let mut state = Shooting {
            k,
            direct: vec![Vec3::ZERO; n * k],
            indirect: vec![Vec3::ZERO; n * k],
            unshot_emit,
            unshot_refl: vec![Vec3::ZERO; np * k],
        };
        let (mut stats, _) = solver::propagate(
            meshing,
            rays,
            scene.extent(),
            &mut renderer,
            &mut state,
            settings,
            progress,
        )?;
        let Shooting {
            mut direct,
            indirect,
            ..
        } = state;
        direct
            .par_iter_mut()
            .zip(indirect.par_iter())
            .for_each(|(d, i)| *d += *i);
        stats.time = start.elapsed();
        Ok(Self {
            patches: np,
            values: direct,
            stats,
        })
    }

    /// Number of patches (sources of the transfer).
    pub fn patches(&self) -> usize {
        self.patches
    }

    /// Bytes of the kept solution (n x P RGB f32).
    pub fn bytes(&self) -> u64 {
        self.values.len() as u64 * 12
    }

    /// The indirect irradiance of every element when the elements receive `direct`
    /// irradiance (one value per element) from lights that are not in the solution: each
    /// patch emits what it reflects, `B_p = sum_e rho_e E_e A_e / A_p`, and
    /// `E_ind,j = sum_p T_jp B_p` (per channel).
    pub fn indirect(&self, meshing: &Meshing, direct: &[Vec3]) -> Vec<Vec3> {
        let np = self.patches;
        if np == 0 {
            return vec![Vec3::ZERO; meshing.elements.len()];
        }
        let mut emit = vec![Vec3::ZERO; np];
        solver::reflect_onto_patches(meshing, direct, 1, &mut emit);
        let active: Vec<(usize, Vec3)> = emit
            .iter()
            .enumerate()
            .filter(|(_, b)| **b != Vec3::ZERO && b.is_finite())
            .map(|(p, b)| (p, *b))
            .collect();
        self.values
            .par_chunks(np)
            .map(|row| active.iter().map(|&(p, b)| row[p] * b).sum())
            .collect()
    }
}

/// The mean direct irradiance over every element from point lights `lights` (closed-form
/// solid angle, visibility at the four receiver points through `occlusion`): the solver's
/// first shot for lights that are not in the solution.
pub fn direct_from_points<O: Occlusion + ?Sized>(
    meshing: &Meshing,
    occlusion: &O,
    lights: &[PointLight],
) -> Vec<Vec3> {
    meshing
        .elements
        .par_iter()
        .map(|e| {
            lights
                .iter()
                .map(|l| direct::element_from_point(l, occlusion, e))
                .sum()
        })
        .collect()
}

/// The fraction of element `e`'s view of the emitting patches `emitters` (triangle and
/// emitting normal) that `objects` leave unblocked: `samples` stratified points on the
/// emitters (spread by area) from each of the element's four receiver points, each
/// weighted by the unoccluded point-to-point kernel `cos cos / r^2`. One when nothing
/// of the emitters is in front of the element.
pub fn emitter_visibility(
    e: &crate::mesh::Element,
    emitters: &[([Vec3; 3], Vec3, f32)],
    objects: &RayScene,
    samples: u32,
    seed: u64,
) -> f32 {
    let total: f32 = emitters.iter().map(|t| t.2).sum();
    if emitters.is_empty() || total.is_nan() || total <= 0.0 {
        return 1.0;
    }
    let (mut seen, mut all) = (0.0f32, 0.0f32);
    let offset = r2(hash_seed(seed, 0xd7a, 0), glam::Vec2::ZERO);
    for (r, &x) in e.receiver_points().iter().enumerate() {
        for s in 0..samples.max(1) {
            let u = r2(s as u64 + (r as u64) * samples as u64, offset);
            // Pick an emitter by area with u.x, reuse the rest of u.x inside it.
            let mut pick = u.x * total;
            let mut chosen = emitters.len() - 1;
            for (q, t) in emitters.iter().enumerate() {
                if pick < t.2 {
                    chosen = q;
                    break;
                }
                pick -= t.2;
            }
            let (tri, tn, area) = emitters[chosen];
            let v = ((pick / area.max(f32::MIN_POSITIVE)).clamp(0.0, 1.0), u.y);
            let b = uniform_triangle(glam::Vec2::new(v.0, v.1));
            let q = tri[0] * (1.0 - b.x - b.y) + tri[1] * b.x + tri[2] * b.y;
            let d = q - x;
            let dist2 = d.length_squared();
            if dist2.is_nan() || dist2 <= 0.0 || !dist2.is_finite() {
                continue;
            }
            let dist = dist2.sqrt();
            let w = d / dist;
            let (ci, co) = (e.normal.dot(w), -tn.dot(w));
            if ci <= 0.0 || co <= 0.0 {
                continue;
            }
            let kernel = ci * co / dist2;
            all += kernel;
            if visibility::sees_surface_point(objects, x, e.normal, q, dist) {
                seen += kernel;
            }
        }
    }
    if all > 0.0 && all.is_finite() {
        (seen / all).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Each source's direct irradiance at the elements with `objects` inserted into the scene
/// (the same layout as [`Solution::direct`]): point and directional lights re-shot through
/// the scene's `rays` and the objects' ([`WithDynamic`]), emissive sources' solved direct
/// light times [`emitter_visibility`] (`samples` rays per receiver point).
pub fn shadowed_direct(
    scene: &Scene,
    meshing: &Meshing,
    solution: &Solution,
    rays: &RayScene,
    objects: &RayScene,
    samples: u32,
) -> Vec<Vec3> {
    let k = solution.k();
    let occlusion = WithDynamic {
        scene: rays,
        objects,
    };
    let extent = scene.extent();
    // Per source, its emitting patches (triangle, normal, area).
    let emitters: Vec<Vec<([Vec3; 3], Vec3, f32)>> = solution
        .sources
        .iter()
        .map(|s| {
            meshing
                .patches
                .iter()
                .filter(|p| p.light.is_some_and(|id| s.lights.contains(&id)))
                .map(|p| (p.corners, p.normal, p.area))
                .collect()
        })
        .collect();
    let mut out = vec![Vec3::ZERO; meshing.elements.len() * k];
    out.par_chunks_mut(k.max(1)).enumerate().for_each(|(j, o)| {
        let e = &meshing.elements[j];
        for (m, source) in solution.sources.iter().enumerate() {
            let mut sum = Vec3::ZERO;
            let mut emissive = false;
            for &id in &source.lights {
                match id {
                    LightId::Emissive(_) => emissive = true,
                    _ => sum += direct::element_from_analytic(scene, id, &occlusion, e, extent),
                }
            }
            if emissive {
                // The solved direct light holds the point and directional lights of a
                // bank too; a bank that mixes kinds is re-shot for its analytic
                // lights and keeps the emitters' share scaled.
                let analytic: Vec3 = source
                    .lights
                    .iter()
                    .map(|&id| direct::element_from_analytic(scene, id, rays, e, extent))
                    .sum();
                let s = solution.slot(meshing, j);
                let solved = (solution.direct[s * k + m] - analytic).max(Vec3::ZERO);
                if solved != Vec3::ZERO {
                    let v = emitter_visibility(
                        e,
                        &emitters[m],
                        objects,
                        samples,
                        (j as u64) << 8 | m as u64,
                    );
                    sum += solved * v;
                }
            }
            o[m] = sum;
        }
    });
    out
}

/// Times of one dynamic frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DynamicTimings {
    /// Re-shooting the static lights' direct light past the dynamic objects (zero without
    /// objects).
    pub shadows: Duration,
    /// The moving lights' direct light onto the elements.
    pub moving_direct: Duration,
    /// The blend `sum_p T_jp B_p`.
    pub blend: Duration,
    /// Eq. 1 for the static lights.
    pub relight: Duration,
}

/// One frame of a dynamic scene, per element.
#[derive(Clone, Debug, PartialEq)]
pub struct DynamicFrame {
    /// Direct irradiance: the static lights' (scaled by the light state, shadowed by the
    /// objects) plus the moving lights'.
    pub direct: Vec<Vec3>,
    /// Indirect irradiance: the static lights' solved indirect light (scaled by the light
    /// state) plus the moving lights' blend.
    pub indirect: Vec<Vec3>,
    /// Outgoing radiance, `albedo (direct + indirect) / pi` plus emission.
    pub radiance: Vec<Vec3>,
    /// What each part took.
    pub timings: DynamicTimings,
}

impl DynamicFrame {
    /// Direct plus indirect irradiance per element (what [`crate::display::compose`]
    /// interpolates).
    pub fn irradiance(&self) -> Vec<Vec3> {
        self.direct
            .iter()
            .zip(&self.indirect)
            .map(|(d, i)| *d + *i)
            .collect()
    }
}

/// A solved static scene with moving point lights and dynamic objects (section 2.4).
#[derive(Debug, Default)]
pub struct DynamicScene {
    transfer: Option<Transfer>,
    /// The moving point lights (not lights of the static scene): move, recolour or add them
    /// between frames freely.
    pub moving: Vec<PointLight>,
    objects: Option<RayScene>,
    /// Rays per receiver point for the visibility of emissive sources past the objects.
    /// Default 8.
    pub emitter_samples: u32,
}

impl DynamicScene {
    /// A dynamic scene for objects only: no transfer, so no moving lights.
    pub fn new() -> Self {
        Self {
            emitter_samples: 8,
            ..Default::default()
        }
    }

    /// A dynamic scene over a solved transfer (moving lights and objects), with no moving
    /// lights and no objects yet.
    pub fn with_transfer(transfer: Transfer) -> Self {
        Self {
            transfer: Some(transfer),
            ..Self::new()
        }
    }

    /// The transfer solution, if any.
    pub fn transfer(&self) -> Option<&Transfer> {
        self.transfer.as_ref()
    }

    /// Inserts dynamic objects (triangles in world space, replacing any earlier ones; an
    /// empty list removes them). Their BVH is built here, not per frame.
    pub fn set_objects(&mut self, triangles: &[[Vec3; 3]]) {
        self.objects = (!triangles.is_empty()).then(|| RayScene::from_triangles(triangles));
    }

    /// The frame under `state` (the static lights' settings) with the current moving
    /// lights and objects: `meshing`, `solution` and `rays` are the static scene's, the
    /// meshing the one the transfer was solved on. Errors with
    /// [`RelightError::InvalidSetting`] when there are moving lights but no transfer, or
    /// the transfer or the solution belongs to another meshing.
    pub fn frame(
        &self,
        scene: &Scene,
        meshing: &Meshing,
        solution: &Solution,
        rays: &RayScene,
        state: &LightState,
    ) -> Result<DynamicFrame, RelightError> {
        let k = solution.k();
        let n = meshing.elements.len();
        let of_meshing = solution.elements == n || solution.elements == meshing.groups.count;
        let len = solution.elements * k;
        if !of_meshing || solution.direct.len() != len || solution.indirect.len() != len {
            return Err(RelightError::InvalidSetting(format!(
                "the solution holds {} values, not {k} sources x {} elements of this meshing",
                solution.direct.len(),
                meshing.groups.count
            )));
        }
        match &self.transfer {
            Some(t) if t.patches != meshing.patches.len() || t.values.len() != n * t.patches => {
                return Err(RelightError::InvalidSetting(format!(
                    "the transfer was solved for {} patches and {} values, this meshing has {} \
                     patches and {n} elements",
                    t.patches,
                    t.values.len(),
                    meshing.patches.len()
                )));
            }
            None if !self.moving.is_empty() => {
                return Err(RelightError::InvalidSetting(format!(
                    "{} moving light(s) but no transfer solution (DynamicScene::with_transfer)",
                    self.moving.len()
                )));
            }
            _ => {}
        }
        let t0 = Instant::now();
        let shadowed = self
            .objects
            .as_ref()
            .map(|o| shadowed_direct(scene, meshing, solution, rays, o, self.emitter_samples));
        let shadows = if self.objects.is_some() {
            t0.elapsed()
        } else {
            Duration::ZERO
        };
        let t1 = Instant::now();
        let moving = match &self.objects {
            Some(objects) => direct_from_points(
                meshing,
                &WithDynamic {
                    scene: rays,
                    objects,
                },
                &self.moving,
            ),
            None => direct_from_points(meshing, rays, &self.moving),
        };
        let moving_direct = t1.elapsed();
        let t2 = Instant::now();
        let blend = match &self.transfer {
            Some(t) if !self.moving.is_empty() => t.indirect(meshing, &moving),
            _ => vec![Vec3::ZERO; n],
        };
        let blend_time = t2.elapsed();
        let t3 = Instant::now();
        let f = relight::factors(solution, state);
        let static_direct = shadowed.as_deref().unwrap_or(&solution.direct);
        let (direct, indirect): (Vec<Vec3>, Vec<Vec3>) = (0..meshing.elements.len())
            .into_par_iter()
            .map(|j| {
                let (mut d, mut i) = (moving[j], blend[j]);
                // The shadowed direct light is per mesh element, the solution per group.
                let sd = static_direct
                    .len()
                    .checked_div(k)
                    .map_or(j, |len| meshing.slot(j, len));
                let s = solution.slot(meshing, j);
                for m in 0..k {
                    d += static_direct[sd * k + m] * f[m].0;
                    i += solution.indirect[s * k + m] * f[m].1;
                }
                (d, i)
            })
            .unzip();
        let glow = relight::glow(meshing, solution, state);
        let radiance = meshing
            .elements
            .par_iter()
            .zip(direct.par_iter().zip(indirect.par_iter()))
            .zip(glow.par_iter())
            .map(|((el, (d, i)), g)| el.albedo * (*d + *i) * std::f32::consts::FRAC_1_PI + *g)
            .collect();
        Ok(DynamicFrame {
            direct,
            indirect,
            radiance,
            timings: DynamicTimings {
                shadows,
                moving_direct,
                blend: blend_time,
                relight: t3.elapsed(),
            },
        })
    }
}
