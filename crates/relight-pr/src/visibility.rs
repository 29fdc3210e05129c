//! Visibility queries between points, shared by the solver's shots and form factors, the
//! hierarchy's links, the meshing's splits, the dynamic objects and the direct light: the
//! [`Occlusion`] trait (the scene's BVH, or the scene with dynamic objects inserted,
//! section 2.4), and the segment and surface-point tests built on it. (In `direct.rs` until
//! 2026-11-27, which the solver and the hierarchy then had to reach into.)

use glam::Vec3;
use scene_core::ray::RayScene;

/// Anything that answers shadow rays: the scene's BVH ([`RayScene`]), or the scene with
/// dynamic objects inserted ([`WithDynamic`], section 2.4).
pub trait Occlusion: Sync {
    /// Whether anything lies along `origin + t direction` for `t` in `[t_min, t_max]`.
    fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool;
}

impl Occlusion for RayScene {
    fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        RayScene::occluded(self, origin, direction, t_min, t_max)
    }
}

/// Whether anything lies on the segment from `a` to `b` (false for a degenerate one).
pub fn segment_blocked<O: Occlusion + ?Sized>(rays: &O, a: Vec3, b: Vec3) -> bool {
    let d = b - a;
    let len = d.length();
    len > 0.0 && len.is_finite() && rays.occluded(a, d / len, 0.0, len)
}

/// Whether a receiver at `x` on a surface with unit normal `n` sees the surface point `q`
/// (at distance `dist` from it): the segment from `x` lifted by `1e-4 dist` along `n` to
/// just short of `q` (a relative `2e-4`) is open. Measured from the lifted origin, so a
/// lift towards `q`'s surface cannot reach that surface first: a grazing ray from a slab
/// under a ceiling lost 6 % of the ceiling's form factor when the length was the unlifted
/// one.
pub fn sees_surface_point<O: Occlusion + ?Sized>(
    rays: &O,
    x: Vec3,
    n: Vec3,
    q: Vec3,
    dist: f32,
) -> bool {
    let from = x + n * (1e-4 * dist);
    let seg = q - from;
    let len = seg.length();
    !rays.occluded(from, seg / len, 0.0, len * (1.0 - 2e-4))
}

/// The static scene's rays with dynamic objects' rays (the paper's section 2.4: objects
/// inserted after the solve shadow the direct light only): a ray is blocked when either
/// blocks it. The objects' BVH is small and rebuilt when they move; the scene's is not.
#[derive(Clone, Copy, Debug)]
pub struct WithDynamic<'a> {
    /// The static scene.
    pub scene: &'a RayScene,
    /// The dynamic objects (e.g. [`RayScene::from_triangles`]).
    pub objects: &'a RayScene,
}

impl Occlusion for WithDynamic<'_> {
    fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        self.objects.occluded(origin, direction, t_min, t_max)
            || self.scene.occluded(origin, direction, t_min, t_max)
    }
}
