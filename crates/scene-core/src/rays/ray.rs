//! Ray queries over a four-wide BVH (obvhs builds the binary tree, a private module folds it
//! for vector traversal): closest hit and occlusion, single and batched with rayon.

use std::time::Duration;

use glam::{Vec2, Vec3, Vec3A};
use obvhs::{BvhBuildParams, triangle::Triangle as BvhTriangle};

use super::bvh4::{Bvh4, PreparedRay, intersect_one};
use rayon::prelude::*;

use crate::cutout::Cutouts;
use crate::scene::Scene;

/// A closest hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Global triangle id (see [`Scene::mesh_offsets`]).
    pub triangle: u32,
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Barycentric coordinates of vertices 1 and 2 (vertex 0 has `1 - u - v`).
    pub barycentric: Vec2,
}

/// The surface a ray hit, as diffuse transport needs it ([`surface_at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// Where the ray hit.
    pub p: Vec3,
    /// Unit geometric normal, on the side the ray came from.
    pub ng: Vec3,
    /// Unit shading normal on the same side ([`crate::view::shading_normal`]).
    pub ns: Vec3,
    /// Diffuse albedo there: the material's (texture included) times the vertex colour.
    pub albedo: Vec3,
}

/// The surface at `hit` of a ray from `o` travelling along the unit `d` (`offsets`:
/// [`Scene::mesh_offsets`]); `None` for an id outside the scene or a degenerate triangle.
pub fn surface_at(
    scene: &Scene,
    offsets: &[u32],
    hit: &Hit,
    o: Vec3,
    d: Vec3,
) -> Option<SurfacePoint> {
    let r = scene.triangle_ref(offsets, hit.triangle)?;
    let mesh = &scene.meshes[r.mesh as usize];
    let tri = mesh.indices[r.local as usize];
    let b = [
        1.0 - hit.barycentric.x - hit.barycentric.y,
        hit.barycentric.x,
        hit.barycentric.y,
    ];
    let pos = tri.map(|i| mesh.positions[i as usize]);
    let mut ng = (pos[1] - pos[0]).cross(pos[2] - pos[0]).normalize_or_zero();
    if ng == Vec3::ZERO {
        return None;
    }
    if ng.dot(d) > 0.0 {
        ng = -ng;
    }
    let ns = crate::view::shading_normal(
        ng,
        (0..3)
            .map(|k| mesh.normals.get(tri[k] as usize).copied().unwrap_or(ng) * b[k])
            .sum::<Vec3>(),
    );
    let uv = mesh
        .uvs
        .as_ref()
        .map(|uvs| (0..3).map(|k| uvs[tri[k] as usize] * b[k]).sum::<Vec2>());
    let albedo = scene.albedo_at(mesh.material_ids[r.local as usize], uv)
        * mesh.color_at(r.local as usize, b);
    Some(SurfacePoint {
        p: o + d * hit.t,
        ng,
        ns,
        albedo,
    })
}

/// A ray for batched queries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayQuery {
    /// Origin.
    pub origin: Vec3,
    /// Direction (need not be unit; `t` is measured in its units).
    pub direction: Vec3,
    /// Hits closer than this are ignored.
    pub t_min: f32,
    /// Hits farther than this are ignored.
    pub t_max: f32,
}

/// Nodes, packets and whether the tree is too deep for a fixed stack ([`Bvh4::gpu_words`]).
#[cfg(all(feature = "gpu", feature = "reference"))]
pub(crate) type GpuTree = (Vec<[u32; 32]>, Vec<[u32; 40]>, bool);

/// A scene's triangles in a four-wide BVH, ready for ray queries.
pub struct RayScene {
    bvh: Option<Bvh4>,
    /// Number of distinct triangles.
    count: usize,
    /// The power of two the geometry is stored scaled by (see [`RayScene::from_triangles`]).
    scale: f32,
    /// Alpha-masked triangles, by global id: a hit where the mask cuts a hole is passed
    /// through (an any-hit test), for closest hits and occlusion alike.
    cutouts: Cutouts,
    /// Time the BVH build took.
    pub build_time: Duration,
}

impl std::fmt::Debug for RayScene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RayScene")
            .field("triangles", &self.count)
            .field("scale", &self.scale)
            .field("build_time", &self.build_time)
            .finish_non_exhaustive()
    }
}

/// The farthest a ray's origin may lie from the origin, in the tree's scaled units (about
/// 10^4 a scene), for the traversal to take it as it is: past it, the ray starts where it
/// enters the tree's box ([`RayScene::closest_hit`]). 10^14 scene extents away, no scene
/// a user builds comes near it.
const FAR_ORIGIN: f32 = 1e18;

/// The power of two that brings a scene of diagonal `diagonal` to about 10^4 units.
///
/// obvhs' wide-BVH (CWBVH) traversal, used until 2026-11-27, clamped every node's entry
/// distance to at least 1e-4 (an absolute constant), so in a scene measured in millimetres
/// it skipped every hit closer than 0.1 mm. The four-wide traversal has no such constant;
/// the scale stays because a power of two scales every coordinate and every distance
/// exactly: the binary build sees the same numbers in every unit, so the tree, and every
/// hit, barycentric and distance, are the same bits in any unit that differs by a power of
/// two (rays are scaled on the way in, distances on the way out).
fn scale_for(diagonal: f32) -> f32 {
    if !(diagonal.is_finite() && diagonal > 0.0) {
        return 1.0;
    }
    let e = (1e4f32 / diagonal).log2().round().clamp(-60.0, 60.0) as i32;
    2f32.powi(e)
}

/// How much the BVH build spends on the tree's quality: obvhs' presets (PLOC clustering,
/// then reinsertion; the slow ones with spatial pre-splits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BvhQuality {
    /// No pre-splits, a twentieth of the nodes reinserted per pass.
    Medium,
    /// Pre-splits, a fifth of the nodes reinserted per pass.
    Slow,
    /// Pre-splits, every node reinserted per pass, the deepest search.
    VerySlow,
}

impl BvhQuality {
    /// Above this many triangles [`RayScene::build`] takes [`BvhQuality::Medium`].
    pub const VERY_SLOW_UP_TO: usize = 1 << 21;

    /// The preset [`RayScene::build`] takes for `n` triangles: the best tree up to
    /// [`BvhQuality::VERY_SLOW_UP_TO`] triangles, where it costs seconds and pays for itself
    /// in any reference render; beyond, `Medium`, the one preset whose build grows about as
    /// `n log n`. Measured on box fields on 2 cores (`cargo run --release -p scene-core
    /// --example bvh_presets -- 1000000 10000000`; incoherent closest-hit rays). The 10^7
    /// row is of 2026-11-26, with obvhs' CWBVH traversal; the 10^6 row of 2026-11-27, with
    /// the four-wide one (median of three runs; the CWBVH read 0.6 s, 2.90 / 1.1 s, 3.74 /
    /// 2.8 s, 5.78 in the same session: on this field both traverse at the same rate):
    ///
    /// | triangles | Medium | Slow | VerySlow |
    /// |---|---|---|---|
    /// | 10^6 | 0.53 s, 3.02 Mrays/s | 0.90 s, 3.69 | 2.45 s, 5.95 |
    /// | 10^7 | 13.7 s, 0.41 | 41.3 s, 0.68 | 168 s (`cargo xtask bench scaling`) |
    ///
    /// At 10^7 `Slow` pays back its 28 s only after about 28 million rays (a reference
    /// frame of 128x96 at 512 spp), and every method builds the BVH at least once.
    pub fn for_triangles(n: usize) -> Self {
        if n <= Self::VERY_SLOW_UP_TO {
            BvhQuality::VerySlow
        } else {
            BvhQuality::Medium
        }
    }

    fn params(self) -> BvhBuildParams {
        match self {
            BvhQuality::Medium => BvhBuildParams::medium_build(),
            BvhQuality::Slow => BvhBuildParams::slow_build(),
            BvhQuality::VerySlow => BvhBuildParams::very_slow_build(),
        }
    }
}

impl RayScene {
    /// Builds the BVH over all triangles of `scene` (which should be validated), with the
    /// preset [`BvhQuality::for_triangles`] picks: obvhs' highest-quality one up to 2^21
    /// triangles, the medium one beyond (the highest-quality tree doubles the ray rate on a
    /// 10^6-triangle box field for seconds of build: [`BvhQuality::for_triangles`]). Alpha-masked
    /// materials ([`crate::Material::alpha_cutoff`]) cut holes that rays pass through.
    pub fn build(scene: &Scene) -> Self {
        Self::build_with(scene, BvhQuality::for_triangles(scene.triangle_count()))
    }

    /// [`RayScene::build`] with a chosen preset.
    pub fn build_with(scene: &Scene, quality: BvhQuality) -> Self {
        let mut tris = Vec::with_capacity(scene.triangle_count());
        for mesh in &scene.meshes {
            for t in &mesh.indices {
                tris.push(t.map(|i| mesh.positions[i as usize]));
            }
        }
        let mut this = Self::from_triangles_with(&tris, quality);
        this.cutouts = Cutouts::of(scene);
        this
    }

    /// The alpha-masked triangles rays pass through where their masks cut holes.
    pub fn cutouts(&self) -> &Cutouts {
        &self.cutouts
    }

    /// Builds the BVH over bare triangles (for callers with geometry but no [`Scene`], such
    /// as an engine handing ISR its shadow casters); hit ids are indices into `triangles`.
    pub fn from_triangles(triangles: &[[Vec3; 3]]) -> Self {
        Self::from_triangles_with(triangles, BvhQuality::for_triangles(triangles.len()))
    }

    /// [`RayScene::from_triangles`] with a chosen preset.
    pub fn from_triangles_with(triangles: &[[Vec3; 3]], quality: BvhQuality) -> Self {
        let start = std::time::Instant::now();
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in triangles.iter().flatten().filter(|p| p.is_finite()) {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let scale = scale_for((hi - lo).length());
        let tris: Vec<BvhTriangle> = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|p| Vec3A::from(p * scale));
                BvhTriangle {
                    v0: a,
                    v1: b,
                    v2: c,
                }
            })
            .collect();
        Self {
            bvh: (!tris.is_empty()).then(|| Bvh4::build(&tris, quality.params())),
            count: tris.len(),
            scale,
            cutouts: Cutouts::default(),
            build_time: start.elapsed(),
        }
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.count
    }

    /// The closest hit along `origin + t * direction` for `t` in `[t_min, t_max)`; among
    /// equally near hits the lowest triangle id.
    pub fn closest_hit(
        &self,
        origin: Vec3,
        direction: Vec3,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        let (bvh, ray, shift) = self.prepare(origin, direction, t_min, t_max)?;
        let found = bvh.closest(&ray, |id, u, v| self.exists(id, u, v))?;
        let t = if shift == 0.0 {
            found.t / self.scale
        } else {
            ((f64::from(found.t) + shift) / f64::from(self.scale)) as f32
        };
        Some(Hit {
            triangle: found.id,
            t,
            barycentric: Vec2::new(found.u, found.v),
        })
    }

    /// True when something lies along the ray for `t` in `[t_min, t_max)` (a segment that
    /// ends on a surface is not blocked by it).
    pub fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        self.prepare(origin, direction, t_min, t_max)
            .is_some_and(|(bvh, ray, _)| bvh.any(&ray, |id, u, v| self.exists(id, u, v)))
    }

    /// The tree and the ray in its scaled units, and the distance (scaled) the ray's start
    /// was moved along it (0 but for the far origins below); `None` for an empty scene, a
    /// non-finite ray or a zero direction (which meet nothing).
    ///
    /// An origin beyond [`FAR_ORIGIN`] once scaled (a light placed near f32's limit, 1e38,
    /// in a scene of a few metres: the triangle test's products overflow there) starts the
    /// ray where it enters the tree's box, found in f64 (or not at all when it misses the
    /// box); the hit's distance adds that start back.
    #[inline(always)]
    fn prepare(
        &self,
        origin: Vec3,
        direction: Vec3,
        t_min: f32,
        t_max: f32,
    ) -> Option<(&Bvh4, PreparedRay, f64)> {
        let bvh = self.bvh.as_ref()?;
        if !origin.is_finite() || !direction.is_finite() || direction == Vec3::ZERO {
            return None;
        }
        let s = self.scale;
        let scaled = origin * s;
        if scaled.abs().max_element() <= FAR_ORIGIN {
            let ray = PreparedRay::new(scaled.into(), direction.into(), t_min * s, t_max * s);
            return Some((bvh, ray, 0.0));
        }
        let (lo, hi) = bvh.bounds();
        let sd = f64::from(s);
        let (o, d) = (origin.as_dvec3() * sd, direction.as_dvec3());
        let (mut t0, mut t1) = (f64::from(t_min) * sd, f64::from(t_max) * sd);
        // The axis whose face the ray enters through, and that face.
        let mut entry: Option<(usize, f64)> = None;
        for a in 0..3 {
            let (l, h) = (f64::from(lo[a]), f64::from(hi[a]));
            if d[a] == 0.0 {
                if o[a] < l || o[a] > h {
                    return None;
                }
                continue;
            }
            let (n, f) = ((l - o[a]) / d[a], (h - o[a]) / d[a]);
            if n.min(f) > t0 {
                t0 = n.min(f);
                entry = Some((a, if d[a] > 0.0 { l } else { h }));
            }
            t1 = t1.min(n.max(f));
        }
        // A miss, or NaN from an infinite range.
        if t0.is_nan() || t1.is_nan() || t0 > t1 {
            return None;
        }
        // Start a little before the box (a thousandth of its diagonal), so that rounding
        // the start to f32 cannot step past a surface on the box's face. The start is
        // placed on its entry face exactly (`o + d t0` would cancel: f64 spaces 1e23 by
        // 1e7); along the other axes it is as exact as the ray itself.
        let margin = 1e-3 * f64::from((hi - lo).length()).max(f64::MIN_POSITIVE);
        let shift = t0 - margin;
        let mut start = o + d * shift;
        if let Some((a, face)) = entry {
            start[a] = face - d[a] * margin;
        }
        let start = start.as_vec3();
        // Nothing lies between the start and the box: the range starts at the start unless
        // the caller's own `t_min` lies beyond it.
        let ray = PreparedRay::new(
            start.into(),
            direction.into(),
            (f64::from(t_min) * sd - shift).max(0.0) as f32,
            (f64::from(t_max) * sd - shift) as f32,
        );
        Some((bvh, ray, shift))
    }

    /// The tree for the GPU path tracer ([`Bvh4::gpu_words`]) and the power-of-two scale
    /// of its coordinates; `None` for an empty scene.
    #[cfg(all(feature = "gpu", feature = "reference"))]
    pub(crate) fn gpu_tree(&self) -> Option<(GpuTree, f32)> {
        self.bvh.as_ref().map(|b| (b.gpu_words(), self.scale))
    }

    /// Heap bytes of the tree (nodes and triangle packets).
    pub fn bvh_bytes(&self) -> usize {
        self.bvh.as_ref().map_or(0, Bvh4::bytes)
    }

    /// True unless triangle `id` is masked and its mask cuts a hole at `(u, v)`.
    #[inline(always)]
    fn exists(&self, id: u32, u: f32, v: f32) -> bool {
        self.cutouts.is_empty() || self.cutouts.opaque(id, Vec2::new(u, v))
    }

    /// Closest hits for many rays, in parallel (results in input order).
    pub fn closest_hits(&self, rays: &[RayQuery]) -> Vec<Option<Hit>> {
        rays.par_iter()
            .with_min_len(256)
            .map(|r| self.closest_hit(r.origin, r.direction, r.t_min, r.t_max))
            .collect()
    }

    /// Occlusion for many rays, in parallel (results in input order).
    pub fn occluded_batch(&self, rays: &[RayQuery]) -> Vec<bool> {
        rays.par_iter()
            .with_min_len(256)
            .map(|r| self.occluded(r.origin, r.direction, r.t_min, r.t_max))
            .collect()
    }
}

/// Brute-force closest hit over all triangles of `scene` (the test oracle for the BVH).
pub fn brute_force_closest(
    scene: &Scene,
    origin: Vec3,
    direction: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<Hit> {
    let (o, d) = (Vec3A::from(origin), Vec3A::from(direction));
    let mut best: Option<Hit> = None;
    let mut global = 0u32;
    let cutouts = Cutouts::of(scene);
    for mesh in &scene.meshes {
        for t in &mesh.indices {
            let [a, b, c] = t.map(|i| Vec3A::from(mesh.positions[i as usize]));
            let limit = best.map_or(t_max, |h| h.t);
            if let Some((t, u, v)) = intersect_one(a, b - a, c - a, o, d, t_min, limit)
                && best.is_none_or(|h| t < h.t)
                && cutouts.opaque(global, Vec2::new(u, v))
            {
                best = Some(Hit {
                    triangle: global,
                    t,
                    barycentric: Vec2::new(u, v),
                });
            }
            global += 1;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, uniform_sphere};
    use crate::scene::{Material, Mesh};

    fn random_scene(seed: u64, n: usize) -> Scene {
        let mut rng = Rng::new(seed, 0);
        let mut mesh = Mesh {
            name: "soup".into(),
            ..Default::default()
        };
        for _ in 0..n {
            let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
            let p = [0, 1, 2].map(|_| c + uniform_sphere(rng.next_vec2()) * (0.2 + rng.next_f32()));
            mesh.push_triangle(p, 0);
        }
        let mut s = Scene::new("random");
        s.materials
            .push(Material::diffuse("grey", Vec3::splat(0.5)));
        s.meshes.push(mesh);
        s
    }

    #[test]
    fn bvh_matches_brute_force_on_random_scenes() {
        for seed in 0..3u64 {
            let scene = random_scene(seed, 2000);
            let rs = RayScene::build(&scene);
            let mut rng = Rng::new(seed, 1);
            let mut hits = 0;
            for _ in 0..2000 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - 2.0;
                let d = uniform_sphere(rng.next_vec2());
                let a = rs.closest_hit(o, d, 0.0, f32::INFINITY);
                let b = brute_force_closest(&scene, o, d, 0.0, f32::INFINITY);
                match (a, b) {
                    (Some(a), Some(b)) => {
                        hits += 1;
                        assert!((a.t - b.t).abs() <= 1e-5 * b.t.max(1.0), "{a:?} {b:?}");
                        // Ties at equal distance may pick either triangle.
                        if a.triangle != b.triangle {
                            assert!((a.t - b.t).abs() < 1e-6);
                        } else {
                            assert!((a.barycentric - b.barycentric).abs().max_element() < 1e-4);
                        }
                    }
                    (None, None) => {}
                    _ => panic!("bvh {a:?} vs brute force {b:?}"),
                }
                let occ = rs.occluded(o, d, 0.0, 5.0);
                let brute_occ = b.is_some_and(|h| h.t <= 5.0);
                assert_eq!(occ, brute_occ);
            }
            assert!(hits > 200, "too few hits ({hits}) to test anything");
        }
    }

    #[test]
    fn batched_queries_equal_single_queries() {
        let scene = random_scene(9, 500);
        let rs = RayScene::build(&scene);
        let mut rng = Rng::new(9, 2);
        let rays: Vec<RayQuery> = (0..3000)
            .map(|_| RayQuery {
                origin: Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0,
                direction: uniform_sphere(rng.next_vec2()),
                t_min: 0.0,
                t_max: 3.0,
            })
            .collect();
        let batch = rs.closest_hits(&rays);
        let occ = rs.occluded_batch(&rays);
        for (i, r) in rays.iter().enumerate() {
            assert_eq!(
                batch[i],
                rs.closest_hit(r.origin, r.direction, r.t_min, r.t_max)
            );
            assert_eq!(occ[i], batch[i].is_some());
        }
    }

    #[test]
    fn empty_scene_and_bad_rays_miss() {
        let rs = RayScene::build(&Scene::new("empty"));
        assert_eq!(rs.closest_hit(Vec3::ZERO, Vec3::X, 0.0, 1e9), None);
        assert!(!rs.occluded(Vec3::ZERO, Vec3::X, 0.0, 1e9));
        let rs = RayScene::build(&random_scene(1, 10));
        assert_eq!(rs.closest_hit(Vec3::NAN, Vec3::X, 0.0, 1e9), None);
        assert_eq!(rs.closest_hit(Vec3::ZERO, Vec3::ZERO, 0.0, 1e9), None);
    }

    /// Rays from and towards f32's limits never panic (a point light at 1e38 in a scene of
    /// a few metres indexed an empty slot of the tree: its slab distances were NaN once the
    /// scaled origin overflowed), and a ray from far away still finds what it points at.
    #[test]
    fn rays_near_f32_limits_never_panic_and_far_origins_still_hit() {
        let scene = crate::builtin::scene("cornell").unwrap();
        let rs = RayScene::build(&scene);
        // Off the middle, away from the diagonals of the box's quads.
        let centre = scene.bounds().min.midpoint(scene.bounds().max) + Vec3::new(0.061, 0.0, 0.037);
        // From far along +Y, straight down onto the middle of the box: the first hit is the
        // top of the box, as from nearby (the same triangle and barycentrics, the distance
        // within f32's spacing at that distance).
        let near = rs
            .closest_hit(centre + Vec3::Y * 10.0, -Vec3::Y, 0.0, f32::INFINITY)
            .expect("the box from above");
        for far in [1e20f32, 1e30, 1e37, 1e38, 3e38] {
            let hit = rs
                .closest_hit(centre + Vec3::Y * far, -Vec3::Y, 0.0, f32::INFINITY)
                .unwrap_or_else(|| panic!("the box from {far:e} above"));
            assert_eq!(hit.triangle, near.triangle, "from {far:e}");
            assert!(
                (hit.barycentric - near.barycentric).abs().max_element() < 1e-3,
                "from {far:e}: {:?} against {:?}",
                hit.barycentric,
                near.barycentric
            );
            assert!(
                (hit.t - far).abs() <= 20.0 + far * 1e-6,
                "from {far:e}: t {}",
                hit.t
            );
            assert!(rs.occluded(centre + Vec3::Y * far, -Vec3::Y, 0.0, f32::INFINITY));
            // Pointing away from the box, or passing beside it: nothing.
            assert!(
                rs.closest_hit(centre + Vec3::Y * far, Vec3::Y, 0.0, f32::INFINITY)
                    .is_none()
            );
            assert!(
                rs.closest_hit(
                    centre + Vec3::new(far, far, 0.0),
                    -Vec3::Y,
                    0.0,
                    f32::INFINITY
                )
                .is_none()
            );
        }
        // Every mix of extreme origins, directions and ranges returns without panicking.
        let big = [
            0.0,
            1e-30,
            -1e-30,
            1.0,
            -1.0,
            1e30,
            -1e30,
            1e38,
            -1e38,
            f32::MAX,
            -f32::MAX,
        ];
        let mut rng = Rng::new(3, 0);
        for _ in 0..20_000 {
            let mut pick = || big[(rng.next_f32() * big.len() as f32) as usize % big.len()];
            let o = Vec3::new(pick(), pick(), pick());
            let d = Vec3::new(pick(), pick(), pick());
            let (t0, t1) = (pick().abs(), pick().abs());
            let _ = rs.closest_hit(o, d, t0.min(t1), t0.max(t1));
            let _ = rs.occluded(o, d, 0.0, f32::INFINITY);
            let n = d.normalize_or_zero();
            let _ = rs.closest_hit(o, n, 0.0, f32::INFINITY);
        }
    }

    /// obvhs skips box entries closer than an absolute 1e-4: a millimetre-scale scene lost
    /// every hit nearer than 0.1 mm. The geometry is now stored scaled by a power of two,
    /// so the same rays in any unit give the same hits (bit for bit when the unit changes
    /// by a power of two; to rounding otherwise).
    #[test]
    fn near_hits_are_found_in_any_unit() {
        let base = crate::builtin::scene("cornell-point").unwrap();
        let mut rng = Rng::new(11, 0);
        for k in [1e-4f32, 1e-3, 2f32.powi(-12), 1.0, 1e3] {
            let exact = k.log2().fract() == 0.0;
            let scene = base.clone().scaled(k);
            let rays = RayScene::build(&scene);
            let unit = RayScene::build(&base);
            for _ in 0..200 {
                // From a point near the floor towards a random direction, short range.
                let o = Vec3::new(
                    0.1 + 0.35 * rng.next_f32(),
                    1e-3,
                    0.1 + 0.35 * rng.next_f32(),
                );
                let d = uniform_sphere(rng.next_vec2());
                let a = unit.closest_hit(o, d, 0.0, f32::INFINITY);
                let b = rays.closest_hit(o * k, d, 0.0, f32::INFINITY);
                let brute = brute_force_closest(&scene, o * k, d, 0.0, f32::INFINITY);
                assert_eq!(b.map(|h| h.triangle), brute.map(|h| h.triangle), "x{k}");
                assert_eq!(a.map(|h| h.triangle), b.map(|h| h.triangle), "x{k}");
                if let (Some(a), Some(b)) = (a, b) {
                    if exact {
                        assert_eq!(b.t / k, a.t, "x{k}");
                    }
                    assert!(
                        (b.t / k - a.t).abs() <= 1e-4 * a.t.max(1e-3),
                        "x{k}: {} vs {}",
                        b.t / k,
                        a.t
                    );
                    assert!(
                        rays.occluded(o * k, d, 0.0, b.t * 1.001),
                        "x{k}: a hit at {} is not an occluder",
                        b.t
                    );
                }
            }
        }
    }
}
