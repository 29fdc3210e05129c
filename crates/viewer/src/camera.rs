//! The fly camera: a [`Camera`] moved by WASD and turned by the mouse, at a speed scaled
//! to the scene's extent.

use glam::{Quat, Vec3};
use scene_core::{Camera, View};

/// A walkable camera. Its state is a plain [`Camera`], so a scene camera chosen by its
/// number key is used exactly as the scene gives it until the user moves.
#[derive(Clone, Debug)]
pub struct FlyCamera {
    /// The camera (its aspect ratio is replaced by the window's at each frame).
    pub camera: Camera,
    /// Metres per second at the default speed: a quarter of the scene's extent.
    pub base_speed: f32,
    /// Multiplier of `base_speed` (the mouse wheel changes it).
    pub speed_scale: f32,
}

/// What the keyboard holds down this frame, each -1, 0 or 1.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Motion {
    /// Forward (W) minus backward (S).
    pub forward: f32,
    /// Right (D) minus left (A).
    pub right: f32,
    /// Up (E) minus down (Q), along the camera's up hint.
    pub up: f32,
    /// Shift: four times faster.
    pub fast: bool,
}

impl Motion {
    /// True when nothing moves.
    pub fn is_still(&self) -> bool {
        self.forward == 0.0 && self.right == 0.0 && self.up == 0.0
    }
}

impl FlyCamera {
    /// A fly camera starting at `camera` in a scene of `extent`.
    pub fn new(camera: &Camera, extent: f32) -> Self {
        let extent = if extent.is_finite() && extent > 0.0 {
            extent
        } else {
            1.0
        };
        Self {
            camera: camera.clone(),
            base_speed: 0.25 * extent,
            speed_scale: 1.0,
        }
    }

    /// The unit view direction.
    pub fn forward(&self) -> Vec3 {
        (self.camera.target - self.camera.position).normalize_or(Vec3::NEG_Z)
    }

    /// The unit up hint.
    fn up(&self) -> Vec3 {
        self.camera.up.normalize_or(Vec3::Y)
    }

    /// Moves by `motion` for `dt` seconds; returns true when the camera moved.
    pub fn advance(&mut self, motion: &Motion, dt: f32) -> bool {
        if motion.is_still() || dt.is_nan() || dt <= 0.0 {
            return false;
        }
        let f = self.forward();
        let up = self.up();
        let right = f.cross(up).normalize_or(Vec3::X);
        let speed = self.base_speed * self.speed_scale * if motion.fast { 4.0 } else { 1.0 };
        let step = (f * motion.forward + right * motion.right + up * motion.up) * speed * dt;
        if !step.is_finite() || step == Vec3::ZERO {
            return false;
        }
        self.camera.position += step;
        self.camera.target += step;
        true
    }

    /// Turns by `dx`, `dy` pixels of mouse motion (`radians_per_pixel` each): yaw about
    /// the up hint, pitch about the camera's right axis, kept off the poles. Returns true
    /// when the view changed.
    pub fn look(&mut self, dx: f32, dy: f32, radians_per_pixel: f32) -> bool {
        if (dx == 0.0 && dy == 0.0) || !dx.is_finite() || !dy.is_finite() {
            return false;
        }
        let up = self.up();
        let f = self.forward();
        let right = f.cross(up).normalize_or(Vec3::X);
        let yawed = Quat::from_axis_angle(up, -dx * radians_per_pixel) * f;
        let pitched = Quat::from_axis_angle(right, -dy * radians_per_pixel) * yawed;
        // Keep at least ~8 degrees from the up hint, where the basis would degenerate.
        let f = if pitched.dot(up).abs() < 0.99 {
            pitched
        } else {
            yawed
        };
        let distance = (self.camera.target - self.camera.position)
            .length()
            .max(1e-3);
        self.camera.target = self.camera.position + f.normalize() * distance;
        true
    }

    /// The camera at `width x height` (aspect ratio replaced).
    pub fn camera_at(&self, width: u32, height: u32) -> Camera {
        self.camera
            .with_aspect(width.max(1) as f32 / height.max(1) as f32)
    }

    /// The view at `width x height`.
    pub fn view(&self, width: u32, height: u32) -> View {
        View::from_camera(&self.camera_at(width, height))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            name: "c".into(),
            position: Vec3::new(0.0, 1.0, 5.0),
            target: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            fov_y: 0.8,
            aspect: 1.0,
            near: 0.01,
            far: 100.0,
        }
    }

    #[test]
    fn walking_forward_for_one_second_covers_a_quarter_of_the_extent() {
        let mut c = FlyCamera::new(&camera(), 8.0);
        let moved = c.advance(
            &Motion {
                forward: 1.0,
                ..Default::default()
            },
            1.0,
        );
        assert!(moved);
        assert!((c.camera.position - Vec3::new(0.0, 1.0, 3.0)).length() < 1e-5);
        assert!((c.forward() - Vec3::NEG_Z).length() < 1e-6);
    }

    #[test]
    fn turning_keeps_off_the_pole_and_standing_still_changes_nothing() {
        let mut c = FlyCamera::new(&camera(), 8.0);
        assert!(!c.advance(&Motion::default(), 1.0));
        // A huge upward pitch is refused rather than flipping over the pole.
        c.look(0.0, -10_000.0, 0.01);
        assert!(c.forward().dot(Vec3::Y).abs() < 0.99);
        // Mouse right by 90 degrees of yaw: from -Z to +X (the right axis).
        let mut c = FlyCamera::new(&camera(), 8.0);
        c.look(std::f32::consts::FRAC_PI_2 / 0.01, 0.0, 0.01);
        assert!((c.forward() - Vec3::X).length() < 1e-4, "{}", c.forward());
    }
}
