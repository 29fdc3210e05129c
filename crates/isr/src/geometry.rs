//! Screen geometry shared by the passes: world positions from linear depth by the frustum
//! vectors of eqs. 23-24 (section 4.3), pixel footprints (figure 4.4) and the screen-space
//! size of a world-space radius. The GPU passes get the same numbers through
//! [`Screen::uniform`].

use glam::{Vec2, Vec3};
use scene_core::view::FrustumReconstruction;
use scene_core::{Projection, View};

/// Normals shorter than this are treated as missing (cancelled in a downsample).
pub const MIN_NORMAL_LEN2: f32 = 1e-12;
/// Smallest `|n . q|` of a footprint: a surface seen at grazing incidence covers at most
/// `1 / MIN_FOOTPRINT_COS` times its fronto-parallel area per pixel.
pub const MIN_FOOTPRINT_COS: f32 = 0.1;

/// The view of a G-buffer, in the form the passes use.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Screen {
    /// Eye position (perspective) .
    pub eye: Vec3,
    /// Perspective: `f_o` of eq. 24 (eye to the far plane's top-left corner). Orthographic:
    /// world position of the top-left corner of the view at depth 0.
    pub corner: Vec3,
    /// Perspective: `f_u`; orthographic: the view's width vector.
    pub du: Vec3,
    /// Perspective: `f_v`; orthographic: the view's height vector (downwards).
    pub dv: Vec3,
    /// Unit view direction.
    pub forward: Vec3,
    /// Far plane distance.
    pub far: f32,
    /// Width of the image plane: in tangent units at distance 1 (perspective) or metres.
    pub span_u: f32,
    /// Height of the image plane, like `span_u`.
    pub span_v: f32,
    /// True for an orthographic view.
    pub ortho: bool,
    /// Eq. 24 positions from linear depth: scene-core's one reconstruction.
    pub reconstruction: FrustumReconstruction,
}

impl Screen {
    /// The geometry of `view`: the affine vectors come from scene-core's
    /// [`FrustumReconstruction`] (its ray terms for perspective views, its base terms for
    /// orthographic ones).
    pub fn new(view: &View) -> Self {
        let (left, right, bottom, top, ortho) = match view.projection {
            Projection::Perspective {
                left,
                right,
                bottom,
                top,
            } => (left, right, bottom, top, false),
            Projection::Orthographic {
                left,
                right,
                bottom,
                top,
            } => (left, right, bottom, top, true),
        };
        let reconstruction = FrustumReconstruction::new(view);
        let [corner, du, dv] = if ortho {
            reconstruction.base
        } else {
            reconstruction.ray
        };
        Self {
            eye: view.eye,
            corner,
            du,
            dv,
            forward: view.forward,
            far: view.far,
            span_u: right - left,
            span_v: top - bottom,
            ortho,
            reconstruction,
        }
    }

    /// World position at image coordinates `uv` with linear depth `depth` (eq. 24:
    /// `eye + (f_o + u f_u + v f_v) depth`; orthographic: the corner plus the offsets plus
    /// `forward * depth * far`).
    pub fn world(&self, uv: Vec2, depth: f32) -> Vec3 {
        self.reconstruction.world(uv, depth)
    }

    /// The view ray direction at `uv`, scaled so its component along `forward` is 1
    /// (orthographic: `forward`).
    pub fn ray_q(&self, uv: Vec2) -> Vec3 {
        if self.ortho {
            self.forward
        } else {
            (self.corner + self.du * uv.x + self.dv * uv.y) / self.far
        }
    }

    /// The unit direction from a surface point at `uv` towards the viewer.
    pub fn to_viewer(&self, uv: Vec2) -> Vec3 {
        -self.ray_q(uv).normalize_or(self.forward)
    }

    /// Metres per unit of image-plane span at linear depth `depth`: the view-space depth
    /// `depth * far` for perspective views, 1 for orthographic ones.
    pub fn scale(&self, depth: f32) -> f32 {
        if self.ortho { 1.0 } else { depth * self.far }
    }

    /// World area covered by an image-plane area `plane_area` (in `span` units squared) at
    /// `uv`, linear depth `depth`, on a surface of unit normal `n`: `s^2 plane_area / |n . q|`
    /// with `|n . q|` at least [`MIN_FOOTPRINT_COS`].
    pub fn footprint(&self, uv: Vec2, depth: f32, n: Vec3, plane_area: f32) -> f32 {
        let s = self.scale(depth);
        let c = n.dot(self.ray_q(uv)).abs().max(MIN_FOOTPRINT_COS);
        s * s * plane_area / c
    }

    /// Fronto-parallel world area of one pixel of a `width x height` image at `depth`
    /// (figure 4.4: the patch area from the depth alone).
    pub fn pixel_area(&self, depth: f32, width: u32, height: u32) -> f32 {
        let s = self.scale(depth);
        s * s * (self.span_u / width as f32) * (self.span_v / height as f32)
    }

    /// The radius, in image-plane span units, of a world-space radius `r` around a point at
    /// linear depth `depth`.
    pub fn plane_radius(&self, depth: f32, r: f32) -> f32 {
        r / self.scale(depth).max(f32::MIN_POSITIVE)
    }

    /// The uniform block the GPU passes read (see `Globals` in the shaders).
    pub fn uniform(&self) -> [[f32; 4]; 5] {
        [
            [self.eye.x, self.eye.y, self.eye.z, self.far],
            [
                self.corner.x,
                self.corner.y,
                self.corner.z,
                if self.ortho { 1.0 } else { 0.0 },
            ],
            [self.du.x, self.du.y, self.du.z, self.span_u],
            [self.dv.x, self.dv.y, self.dv.z, self.span_v],
            [self.forward.x, self.forward.y, self.forward.z, 0.0],
        ]
    }
}

/// The centre of a pixel in image coordinates: scene-core's [`scene_core::view::pixel_uv`].
pub use scene_core::view::pixel_uv;

/// `n` if it is a usable normal, otherwise `fallback` (a normal that cancelled in a
/// downsample, or garbage).
pub fn usable_normal(n: Vec3, fallback: Vec3) -> Vec3 {
    let l2 = n.length_squared();
    if l2 > MIN_NORMAL_LEN2 && l2.is_finite() {
        n / l2.sqrt()
    } else {
        fallback
    }
}

/// `n` if it is a usable normal, otherwise the direction towards the viewer at `uv` (computed
/// only then).
pub fn normal_or_viewer(n: Vec3, screen: &Screen, uv: Vec2) -> Vec3 {
    let l2 = n.length_squared();
    if l2 > MIN_NORMAL_LEN2 && l2.is_finite() {
        n / l2.sqrt()
    } else {
        screen.to_viewer(uv)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene_core::builtin;

    #[test]
    fn world_matches_the_views_reconstruction() {
        let scene = builtin::scene("cornell").unwrap();
        let view = View::from_camera(&scene.cameras[0]);
        let s = Screen::new(&view);
        for (u, v, z) in [(0.1f32, 0.2f32, 0.5f32), (0.9, 0.7, 0.3), (0.5, 0.5, 1.0)] {
            let uv = Vec2::new(u, v);
            let a = s.world(uv, z);
            let b = view.reconstruct_world(uv, z);
            assert!((a - b).length() < 1e-5, "{a} vs {b}");
            // ray_q has unit forward component and points at the reconstructed point.
            let q = s.ray_q(uv);
            assert!((q.dot(view.forward) - 1.0).abs() < 1e-5);
            let p = view.eye + q * (z * view.far);
            assert!((p - a).length() < 1e-4);
        }
        let ortho = View::orthographic_fit(Vec3::ZERO, Vec3::new(0.0, -1.0, 0.2), 3.0);
        let s = Screen::new(&ortho);
        let uv = Vec2::new(0.3, 0.8);
        assert!((s.world(uv, 0.4) - ortho.reconstruct_world(uv, 0.4)).length() < 1e-5);
    }

    #[test]
    fn footprint_of_a_fronto_parallel_pixel() {
        let scene = builtin::scene("cornell").unwrap();
        let view = View::from_camera(&scene.cameras[0]);
        let s = Screen::new(&view);
        let uv = Vec2::new(0.5, 0.5);
        let a = s.footprint(uv, 0.5, -view.forward, s.span_u * s.span_v / 100.0);
        assert!((a - s.pixel_area(0.5, 10, 10)).abs() < 1e-6 * a);
        // Grazing: bounded.
        let g = s.footprint(uv, 0.5, view.right(), 1.0);
        assert!(g.is_finite() && g > 0.0);
    }
}
