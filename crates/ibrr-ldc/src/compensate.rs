//! Local bias compensation of the clamp, after Kollig and Keller ("Illumination in the
//! presence of weak singularities", Monte Carlo and Quasi-Monte Carlo Methods 2004).
//!
//! Clamping an IRPL's geometry term `g = cos_i cos_x / (pi r^2)` at `g_max` removes its
//! `1/r^2` hot spot and, with it, the light that travels less than `r_max = 1 / sqrt(pi
//! g_max)` between two surfaces. That light is recovered where it was lost: from each
//! layer's centre `q` (normal `n`), cosine-distributed rays no longer than `r_max` find the
//! surfaces `y` close enough for `g(q, y) > g_max`, and each adds the part of their
//! radiance the clamp took away, `max(0, 1 - g_max / g)`:
//!
//! `E_res(q) = pi / M sum_k (1 - g_max / g_k)+ L(y_k)`,
//!
//! with `L(y) = rho(y) / pi E(y)` read from the (clamped) LDC at `y`, plus the emission of
//! `y` seen from its emitting side. The reflected part is one more bounce (indirect light
//! of each source), the emission direct light of its emitter; both are kept per source so
//! relighting stays exact. One level: the residual's own short-range bounces are not
//! compensated again.

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use scene_core::Scene;
use scene_core::lights::LightId;
use scene_core::ray::RayScene;
use scene_core::sampling::{Rng, cosine_hemisphere, hash_seed, r2};

use crate::ldc::Ldc;

/// Figures of one compensation pass.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompensationStats {
    /// Rays traced.
    pub rays: u64,
    /// Rays that found a surface within the clamp's reach and added light.
    pub compensating: u64,
}

/// Per pixel: the light added to its layers (layer, source, direct, indirect), the rays
/// traced and those that added light.
type PixelAdds = (Vec<(usize, usize, Vec3, Vec3)>, u64, u64);

/// How [`compensate`] runs.
pub(crate) struct Options {
    /// The clamp: the largest geometry term kept.
    pub g_max: f32,
    /// Rays a layer.
    pub rays: u32,
    /// Levels (at least 1).
    pub levels: u32,
    /// Seed of the rays.
    pub seed: u64,
    /// False for walks without bounces (direct light only): only emitters' light is
    /// recovered.
    pub reflected: bool,
}

/// Adds to every layer of `ldc` (values per unit of the sources' factors, sources in
/// `sources`' order) the light the clamp at `o.g_max` removed, from `o.rays`
/// cosine-distributed rays a layer, seeded by `o.seed` (deterministic whatever the thread
/// count), over `o.levels` levels: the first reads the clamped LDC at the surfaces it reaches, each further level
/// reads the LDC compensated by the level before (so the recovered light's own short
/// bounces are recovered too), the same rays each time.
pub(crate) fn compensate(
    scene: &Scene,
    ldc: &mut Ldc,
    sources: &[LightId],
    o: &Options,
) -> CompensationStats {
    let (g_max, rays, levels) = (o.g_max, o.rays, o.levels);
    if !(g_max.is_finite() && g_max > 0.0) || rays == 0 || ldc.layer_count() == 0 {
        return CompensationStats::default();
    }
    let tracer = RayScene::build(scene);
    let clamped = ldc.sources.clone();
    let mut stats = CompensationStats::default();
    for _ in 0..levels.max(1) {
        let added = residuals(scene, &tracer, ldc, sources, o);
        ldc.sources = clamped.clone();
        stats = CompensationStats::default();
        for (list, traced, hits) in added {
            stats.rays += traced;
            stats.compensating += hits;
            for (l, src, d, i) in list {
                ldc.sources.add(l, src, [d, i]);
            }
        }
    }
    stats
}

/// One level of [`compensate`]: per pixel of the LDC, the light to add to its layers.
fn residuals(
    scene: &Scene,
    tracer: &RayScene,
    ldc: &Ldc,
    sources: &[LightId],
    o: &Options,
) -> Vec<PixelAdds> {
    let (g_max, rays, seed, reflected) = (o.g_max, o.rays, o.seed, o.reflected);
    let reach = (std::f32::consts::FRAC_1_PI / g_max).sqrt();
    let offsets = scene.mesh_offsets();
    let lift = scene.extent() * 1e-5;
    let frame = ldc.frame;
    let r = frame.resolution as usize;
    let n_sources = ldc.sources.sources();
    let source_of = |id: LightId| sources.iter().position(|&s| s == id);
    let ldc_ref = ldc;
    (0..frame.pixel_count())
        .into_par_iter()
        .map(|k| {
            let mut out = Vec::new();
            let (mut traced, mut hits) = (0u64, 0u64);
            let range = ldc_ref.range(k);
            if range.is_empty() {
                return (out, 0, 0);
            }
            let (axis, rest) = (k / (r * r), k % (r * r));
            let (i, j) = ((rest % r) as i64, (rest / r) as i64);
            let mut weights = Vec::new();
            let mut res = vec![[Vec3::ZERO; 2]; n_sources];
            for l in range {
                let plane = ldc_ref.planes[l];
                let Some(q) = frame.point_on_plane(axis, i, j, plane) else {
                    continue;
                };
                let n = plane.truncate();
                res.iter_mut().for_each(|v| *v = [Vec3::ZERO; 2]);
                // Seeded by the LDI pixel and the layer's normal (to 1e-3), not by the
                // layer's index, which depends on the order the IRPLs founded the layers.
                let key = n.to_array().iter().fold(k as u64, |h, c| {
                    hash_seed(h, 0xc0e5, ((c * 1000.0).round() as i64) as u64)
                });
                let mut rng = Rng::new(hash_seed(seed, key, 0x5eed), 0);
                let offset = Vec2::new(rng.next_f32(), rng.next_f32());
                let mut any = false;
                for m in 0..rays {
                    let d = cosine_hemisphere(n, r2(u64::from(m), offset));
                    traced += 1;
                    let Some(hit) = tracer.closest_hit(q + n * lift, d, 0.0, reach) else {
                        continue;
                    };
                    let Some(t) = scene.triangle_ref(&offsets, hit.triangle) else {
                        continue;
                    };
                    let mesh = &scene.meshes[t.mesh as usize];
                    let tri = mesh.indices[t.local as usize].map(|v| mesh.positions[v as usize]);
                    let winding = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize_or_zero();
                    let cos_y = winding.dot(d).abs();
                    let cos_q = n.dot(d);
                    let dist = hit.t.max(1e-12);
                    let g = cos_q * cos_y * std::f32::consts::FRAC_1_PI / (dist * dist);
                    if g <= g_max || !g.is_finite() {
                        continue;
                    }
                    let w = 1.0 - g_max / g;
                    let Some(s) = crate::irpl::surface_at(scene, &offsets, &hit, q, d) else {
                        continue;
                    };
                    hits += 1;
                    any = true;
                    // Reflected: rho / pi E(y), per source (one more bounce: indirect),
                    // unless the walks make no bounce (direct light only).
                    if !reflected {
                        weights.clear();
                    } else {
                        ldc_ref.layer_weights(s.p, s.ns, &mut weights);
                    }
                    for &(layer, wl) in &weights {
                        for (src, v) in res.iter_mut().enumerate() {
                            let e = ldc_ref.sources.get(layer, src);
                            v[1] += (e[0] + e[1]) * s.albedo * (wl * w / rays as f32);
                        }
                    }
                    // Emitted, one-sided: the emitter's direct light.
                    let mat = &scene.materials[mesh.material_ids[t.local as usize] as usize];
                    if mat.is_emissive()
                        && winding.dot(d) < 0.0
                        && let Some(src) = source_of(LightId::Emissive(t.mesh))
                    {
                        let le = scene.triangle_emission(t.mesh as usize, t.local as usize);
                        res[src][0] += le * (std::f32::consts::PI * w / rays as f32);
                    }
                }
                if any {
                    for (src, v) in res.iter().enumerate() {
                        if v[0] != Vec3::ZERO || v[1] != Vec3::ZERO {
                            out.push((l, src, v[0], v[1]));
                        }
                    }
                }
            }
            (out, traced, hits)
        })
        .collect()
}
