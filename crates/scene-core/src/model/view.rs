//! Views: cameras, hemicube faces and shadow-map views, with their matrices and the
//! far-plane frustum-corner vectors of the thesis' section 4.3 (eqs. 23-24).
//!
//! View space is right-handed: +X right, +Y up, the view looks down -Z. Clip space follows
//! wgpu: depth in [0, 1]. "Linear depth" is the distance along the view direction divided by
//! `far` (the thesis' stored depth), so it lies in [near/far, 1] for visible points.
//! Image coordinates `(u, v)` are in [0, 1]², `(0, 0)` the top-left corner.

use glam::{Mat3, Mat4, Vec2, Vec3};

use crate::scene::Camera;

/// The projection of a view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Perspective; the frustum's side planes at view-space `x/(-z)` in `[left, right]` and
    /// `y/(-z)` in `[bottom, top]` (tangents of the half-angles; symmetric for cameras,
    /// off-axis for the half faces of a hemicube).
    Perspective {
        /// Tangent of the left half-angle (negative for a frustum containing the axis).
        left: f32,
        /// Tangent of the right half-angle.
        right: f32,
        /// Tangent of the bottom half-angle.
        bottom: f32,
        /// Tangent of the top half-angle.
        top: f32,
    },
    /// Orthographic: view-space x in `[left, right]`, y in `[bottom, top]` (metres).
    Orthographic {
        /// Left edge.
        left: f32,
        /// Right edge.
        right: f32,
        /// Bottom edge.
        bottom: f32,
        /// Top edge.
        top: f32,
    },
}

/// A view: an eye with an orthonormal frame, a projection and near/far planes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Eye position in world space.
    pub eye: Vec3,
    /// Unit view direction.
    pub forward: Vec3,
    /// Unit up vector, orthogonal to `forward`.
    pub up: Vec3,
    /// The projection.
    pub projection: Projection,
    /// Near plane distance.
    pub near: f32,
    /// Far plane distance.
    pub far: f32,
}

/// How an engine's depth buffer encodes distance, read off its projection matrix by
/// [`View::from_host_matrices`]: standard or reversed, with a finite far plane or one at
/// infinity, perspective or orthographic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthConvention {
    /// Depth 1 at the near plane, falling with distance (reverse-Z).
    pub reverse: bool,
    /// The far plane at infinity (depth 1, or 0 reversed, never reached).
    pub infinite: bool,
    /// Depth linear in distance.
    pub orthographic: bool,
    /// The projection's z row: depth `d = (m32 - m22 t) / t` at distance `t` in perspective,
    /// `d = m32 - m22 t` orthographic.
    m22: f64,
    m32: f64,
    /// The view's far plane, which the toolkit's linear depth divides by.
    far: f32,
}

impl DepthConvention {
    /// The distance along the view direction of a point at hardware depth `d` (infinite at
    /// an infinite far plane, not finite for depths the projection never writes).
    pub fn distance(&self, d: f32) -> f32 {
        let d = f64::from(d);
        let t = if self.orthographic {
            (self.m32 - d) / self.m22
        } else if d + self.m22 == 0.0 {
            // The far plane at infinity (whichever sign the zero has).
            f64::INFINITY
        } else {
            self.m32 / (d + self.m22)
        };
        t as f32
    }

    /// The toolkit's linear depth (distance / the view's far plane, see the module
    /// documentation) of hardware depth `d`, in [0, 1]: a point beyond the view's far plane
    /// (only with an infinite far plane: `near x` [`crate::scene::DEPTH_RANGE_MAX`]) reads
    /// as 1.
    pub fn linear_depth(&self, d: f32) -> f32 {
        let t = self.distance(d) / self.far;
        if t.is_nan() { 1.0 } else { t.clamp(0.0, 1.0) }
    }

    /// The projection's `m22` and `m32` and the view's far plane, as the GPU reads them
    /// (`crate::gpu::host`).
    pub fn parts(&self) -> (f32, f32, f32) {
        (self.m22 as f32, self.m32 as f32, self.far)
    }

    /// The hardware depth of a point at distance `t` (the inverse of
    /// [`DepthConvention::distance`]).
    pub fn depth(&self, t: f32) -> f32 {
        let t = f64::from(t);
        let d = if self.orthographic {
            self.m32 - self.m22 * t
        } else {
            (self.m32 - self.m22 * t) / t
        };
        d as f32
    }
}

/// The centre of pixel `(x, y)` of a `width x height` image in image coordinates
/// (`(0, 0)` top-left, `(1, 1)` bottom-right): where every G-buffer renderer samples and
/// every image-space pass reconstructs.
#[inline]
pub fn pixel_uv(x: u32, y: u32, width: u32, height: u32) -> Vec2 {
    Vec2::new(
        (x as f32 + 0.5) / width as f32,
        (y as f32 + 0.5) / height as f32,
    )
}

/// Far-plane frustum vectors of eq. 24: world-space position of the point seen at image
/// coordinates `(u, v)` with linear depth `d` is `eye + (o + u * du + v * dv) * d`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrustumCorners {
    /// `f_o`: from the eye to the far plane's top-left corner.
    pub origin: Vec3,
    /// `f_u`: across the far plane, left to right.
    pub du: Vec3,
    /// `f_v`: down the far plane, top to bottom.
    pub dv: Vec3,
}

/// Eqs. 23-24: positions as `base(uv) + ray(uv) * depth`, both affine in `(u, v)`: the one
/// reconstruction of world (and view-space) positions from a G-buffer's linear depth that
/// [`View::reconstruct_world`], the `gbuffer` crate and ISR use. Six multiply-adds per
/// position. Orthographic views take the same affine form with the roles swapped: the base
/// point moves with `(u, v)` and the depth direction is constant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrustumReconstruction {
    /// World space: `base = base[0] + u base[1] + v base[2]` (the eye and two zeros for
    /// perspective views).
    pub base: [Vec3; 3],
    /// World space: `ray = ray[0] + u ray[1] + v ray[2]` (`f_o`, `f_u`, `f_v` for
    /// perspective views; `far * forward` and two zeros for orthographic ones).
    pub ray: [Vec3; 3],
    /// The same in view space (right-handed, looking down -Z; eq. 23's corner is
    /// `(left far, top far, -far)`).
    pub view_base: [Vec3; 3],
    /// View-space `ray` terms.
    pub view_ray: [Vec3; 3],
}

impl FrustumReconstruction {
    /// The vectors of `view`. For perspective views `ray` is [`View::frustum_corners`].
    pub fn new(view: &View) -> Self {
        let (r, u, f) = (view.right(), view.up, view.forward);
        let far = view.far;
        match view.projection {
            Projection::Perspective {
                left,
                right,
                bottom,
                top,
            } => {
                let vo = Vec3::new(left * far, top * far, -far);
                let vu = Vec3::new((right - left) * far, 0.0, 0.0);
                let vv = Vec3::new(0.0, (bottom - top) * far, 0.0);
                let c = view.frustum_corners().unwrap_or(FrustumCorners::ZERO);
                Self {
                    base: [view.eye, Vec3::ZERO, Vec3::ZERO],
                    ray: [c.origin, c.du, c.dv],
                    view_base: [Vec3::ZERO; 3],
                    view_ray: [vo, vu, vv],
                }
            }
            Projection::Orthographic {
                left,
                right,
                bottom,
                top,
            } => Self {
                base: [
                    view.eye + r * left + u * top,
                    r * (right - left),
                    u * (bottom - top),
                ],
                ray: [f * far, Vec3::ZERO, Vec3::ZERO],
                view_base: [
                    Vec3::new(left, top, 0.0),
                    Vec3::new(right - left, 0.0, 0.0),
                    Vec3::new(0.0, bottom - top, 0.0),
                ],
                view_ray: [Vec3::new(0.0, 0.0, -far), Vec3::ZERO, Vec3::ZERO],
            },
        }
    }

    /// World-space position at image coordinates `uv` with linear depth `depth`.
    #[inline]
    pub fn world(&self, uv: Vec2, depth: f32) -> Vec3 {
        let base = self.base[0] + self.base[1] * uv.x + self.base[2] * uv.y;
        let ray = self.ray[0] + self.ray[1] * uv.x + self.ray[2] * uv.y;
        base + ray * depth
    }

    /// The world-space vectors as the `FrustumReconstruction` struct of
    /// `shaders/scene-core/reconstruct.wgsl` (six `vec4`s, `w` = 0): `base0, base_u, base_v,
    /// ray0, ray_u, ray_v`.
    pub fn uniform(&self) -> [[f32; 4]; 6] {
        let [b0, bu, bv] = self.base;
        let [r0, ru, rv] = self.ray;
        [b0, bu, bv, r0, ru, rv].map(|v| v.extend(0.0).to_array())
    }

    /// View-space position at image coordinates `uv` with linear depth `depth`.
    #[inline]
    pub fn view_space(&self, uv: Vec2, depth: f32) -> Vec3 {
        let base = self.view_base[0] + self.view_base[1] * uv.x + self.view_base[2] * uv.y;
        let ray = self.view_ray[0] + self.view_ray[1] * uv.x + self.view_ray[2] * uv.y;
        base + ray * depth
    }
}

impl FrustumCorners {
    /// All three vectors zero.
    pub const ZERO: Self = Self {
        origin: Vec3::ZERO,
        du: Vec3::ZERO,
        dv: Vec3::ZERO,
    };
}

/// Which face of a hemicube a [`View`] from [`View::hemicube`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HemicubeFace {
    /// Looking along the normal; a full square face.
    Front,
    /// Looking along +tangent; the half face above the surface.
    Right,
    /// Looking along -tangent.
    Left,
    /// Looking along +bitangent.
    Up,
    /// Looking along -bitangent.
    Down,
}

impl HemicubeFace {
    /// The five faces in a fixed order.
    pub const ALL: [HemicubeFace; 5] = [
        HemicubeFace::Front,
        HemicubeFace::Right,
        HemicubeFace::Left,
        HemicubeFace::Up,
        HemicubeFace::Down,
    ];

    /// Image size of this face for a hemicube of `resolution` (full face `res x res`, side
    /// faces `res x res/2`, rounded up).
    pub fn size(self, resolution: u32) -> (u32, u32) {
        match self {
            HemicubeFace::Front => (resolution, resolution),
            _ => (resolution, resolution.div_ceil(2)),
        }
    }
}

/// Two unit vectors `(t, b)` completing unit `n` to a right-handed orthonormal frame
/// (`t x b = n`; Duff et al.'s branchless construction).
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let bt = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    (t, bt)
}

/// The unit shading normal of a hit: `interpolated` (the vertex normals blended at the hit)
/// normalised and turned to the side of `ng`, the unit geometric normal already facing the
/// incoming ray; `ng` itself where `interpolated` vanishes or is not finite. The rule the
/// reference tracer reflects with (its GPU twin's `shading_normal`), the IBRR's walks and
/// the tests that compare the two tracers share.
pub fn shading_normal(ng: Vec3, interpolated: Vec3) -> Vec3 {
    let ns = interpolated.normalize_or_zero();
    if ns == Vec3::ZERO {
        ng
    } else if ns.dot(ng) < 0.0 {
        -ns
    } else {
        ns
    }
}

impl View {
    /// A perspective view from a camera (its aspect ratio is the camera's; its up is
    /// [`Camera::view_up`], so a camera looking straight up or down has a view too).
    pub fn from_camera(camera: &Camera) -> View {
        let forward = (camera.target - camera.position).normalize();
        let right = forward.cross(camera.view_up()).normalize();
        let up = right.cross(forward);
        let ty = (camera.fov_y * 0.5).tan();
        let tx = ty * camera.aspect;
        View {
            eye: camera.position,
            forward,
            up,
            projection: Projection::Perspective {
                left: -tx,
                right: tx,
                bottom: -ty,
                top: ty,
            },
            near: camera.near,
            far: camera.far,
        }
    }

    /// The view of an engine's own matrices: `view` maps world to view space (right-handed,
    /// looking down -Z, +Y up, no scale) and `projection` maps view space to clip space with
    /// depth in [0, 1] (wgpu's and Direct3D's range), in any of the conventions engines use:
    /// standard (depth 0 at the near plane) or reversed (depth 1 at the near plane, as Bevy
    /// and most current engines), with a finite far plane or one at infinity (glam's
    /// `perspective_rh`, `perspective_infinite_rh`, `perspective_infinite_reverse_rh` and
    /// `orthographic_rh`, their off-axis forms, and each with near and far swapped).
    /// [`View::from_host_matrices`] also returns how the engine's depth buffer encodes
    /// distance.
    ///
    /// The view's own depth (the toolkit's G-buffers) is always standard and finite: a far
    /// plane at infinity becomes `near x` [`crate::scene::DEPTH_RANGE_MAX`], the deepest
    /// range the toolkit renders.
    ///
    /// OpenGL-style matrices (depth in [-1, 1]) cannot be told apart from a [0, 1] matrix
    /// with other planes and must be converted first. Errors name what does not fit: a view
    /// matrix that is not a rotation and a translation, a projection that is neither
    /// perspective nor orthographic, a depth that does not vary with distance, planes that do
    /// not satisfy `0 < near < far` (`0 <= near` for orthographic), or an orthographic
    /// projection without a far plane.
    pub fn from_matrices(view: Mat4, projection: Mat4) -> Result<View, crate::Error> {
        Self::from_host_matrices(view, projection).map(|(v, _)| v)
    }

    /// [`View::from_matrices`] with the engine's depth convention, which turns the values of
    /// its depth buffer into distances ([`DepthConvention::distance`]) and into the
    /// toolkit's linear depth ([`DepthConvention::linear_depth`]).
    pub fn from_host_matrices(
        view: Mat4,
        projection: Mat4,
    ) -> Result<(View, DepthConvention), crate::Error> {
        let bad = |why: String| {
            Err(crate::Error::InvalidArgument(format!(
                "View::from_matrices: {why}"
            )))
        };
        if !(view.is_finite() && projection.is_finite()) {
            return bad("the matrices must be finite".into());
        }
        let (r, u, b) = (
            view.row(0).truncate(),
            view.row(1).truncate(),
            view.row(2).truncate(),
        );
        let orthonormal = [r, u, b].iter().all(|v| (v.length() - 1.0).abs() < 1e-3)
            && r.dot(u).abs() < 1e-3
            && r.dot(b).abs() < 1e-3
            && u.dot(b).abs() < 1e-3
            && view.row(3).abs_diff_eq(glam::Vec4::W, 1e-6);
        if !orthonormal {
            return bad(
                "the view matrix must be a rotation and a translation (no scale, no shear)".into(),
            );
        }
        if r.cross(u).dot(b) < 0.0 {
            return bad("the view matrix is left-handed; a right-handed one looks down -Z".into());
        }
        let eye = -(Mat3::from_cols(r, u, b) * view.w_axis.truncate());
        let p = projection;
        let (a, bb) = (p.x_axis.x, p.y_axis.y);
        if a == 0.0 || bb == 0.0 {
            return bad("the projection has a zero scale".into());
        }
        // Hardware depth at distance t along the view: (m32 - m22 t) / t for a perspective,
        // m32 - m22 t for an orthographic projection. In f64: with far/near large, 1 + m22
        // is a small difference.
        let (m22, m32) = (f64::from(p.z_axis.z), f64::from(p.w_axis.z));
        let perspective = p.z_axis.w == -1.0 && p.w_axis.w == 0.0;
        let orthographic = p.z_axis.w == 0.0 && p.w_axis.w == 1.0;
        if !(perspective || orthographic) {
            return bad(
                "the projection is neither perspective (w = -z) nor orthographic (w = 1)".into(),
            );
        }
        // The distances where depth is 0 and where it is 1 (infinite where never).
        let (at0, at1) = if perspective {
            if m32 == 0.0 {
                return bad(
                    "the perspective projection's depth does not vary with distance (z row 0)"
                        .into(),
                );
            }
            // A zero denominator is a plane at infinity (m22 = 0 reversed, -1 standard).
            let at = |den: f64| if den == 0.0 { f64::INFINITY } else { m32 / den };
            (at(m22), at(1.0 + m22))
        } else {
            if m22 == 0.0 {
                return bad(
                    "the orthographic projection's depth does not vary with distance (no far \
                     plane)"
                        .into(),
                );
            }
            (m32 / m22, (m32 - 1.0) / m22)
        };
        // Perspective depth falls with distance where m32 > 0; orthographic where m22 > 0.
        let reverse = if perspective { m32 > 0.0 } else { m22 > 0.0 };
        let (near, far) = if reverse { (at1, at0) } else { (at0, at1) };
        let infinite = far == f64::INFINITY;
        let near_ok = if perspective { near > 0.0 } else { near >= 0.0 };
        if !(near_ok && far > near && near.is_finite()) {
            return bad(format!(
                "near {near} and far {far} do not satisfy 0 {} near < far",
                if perspective { "<" } else { "<=" }
            ));
        }
        let (near, far) = (near as f32, far as f32);
        let far = if infinite {
            near * crate::scene::DEPTH_RANGE_MAX
        } else {
            far
        };
        if !(far.is_finite() && far > near) {
            return bad(format!(
                "near {near} and far {far} are not a usable depth range"
            ));
        }
        let proj = if perspective {
            let (c, d) = (p.z_axis.x, p.z_axis.y);
            Projection::Perspective {
                left: (c - 1.0) / a,
                right: (c + 1.0) / a,
                bottom: (d - 1.0) / bb,
                top: (d + 1.0) / bb,
            }
        } else {
            let (e, g) = (p.w_axis.x, p.w_axis.y);
            Projection::Orthographic {
                left: (-1.0 - e) / a,
                right: (1.0 - e) / a,
                bottom: (-1.0 - g) / bb,
                top: (1.0 - g) / bb,
            }
        };
        let v = View {
            eye,
            forward: -b.normalize(),
            up: u.normalize(),
            projection: proj,
            near,
            far,
        };
        let convention = DepthConvention {
            reverse,
            infinite,
            orthographic,
            m22,
            m32,
            far,
        };
        Ok((v, convention))
    }

    /// The camera of a symmetric perspective view (`None` for off-axis or orthographic
    /// views), named `name`: the inverse of [`View::from_camera`].
    pub fn to_camera(&self, name: &str) -> Option<Camera> {
        let Projection::Perspective {
            left,
            right,
            bottom,
            top,
        } = self.projection
        else {
            return None;
        };
        let symmetric =
            (left + right).abs() <= 1e-5 * right.abs() && (bottom + top).abs() <= 1e-5 * top.abs();
        if !symmetric || top <= 0.0 {
            return None;
        }
        Some(Camera {
            name: name.into(),
            position: self.eye,
            target: self.eye + self.forward,
            up: self.up,
            fov_y: 2.0 * top.atan(),
            aspect: right / top,
            near: self.near,
            far: self.far,
        })
    }

    /// An orthographic view looking along `direction` that contains the sphere of radius
    /// `half_extent` around `center` (a shadow-map view for a directional light; pass half
    /// the scene's bounding-box diagonal to contain the whole box).
    pub fn orthographic_fit(center: Vec3, direction: Vec3, half_extent: f32) -> View {
        let forward = direction.normalize();
        let (_, up) = orthonormal_basis(forward);
        View {
            eye: center - forward * (2.0 * half_extent),
            forward,
            up,
            projection: Projection::Orthographic {
                left: -half_extent,
                right: half_extent,
                bottom: -half_extent,
                top: half_extent,
            },
            near: half_extent * 1e-3,
            far: 4.0 * half_extent,
        }
    }

    /// One face of a hemicube at `point` with unit `normal` (90 degree faces). Side faces look
    /// along the tangent directions and cover only the half above the surface, their image up
    /// being the normal. `near`/`far` bound the depth range.
    pub fn hemicube(point: Vec3, normal: Vec3, face: HemicubeFace, near: f32, far: f32) -> View {
        let n = normal.normalize();
        let (t, b) = orthonormal_basis(n);
        let (forward, up) = match face {
            HemicubeFace::Front => (n, b),
            HemicubeFace::Right => (t, n),
            HemicubeFace::Left => (-t, n),
            HemicubeFace::Up => (b, n),
            HemicubeFace::Down => (-b, n),
        };
        let projection = match face {
            HemicubeFace::Front => Projection::Perspective {
                left: -1.0,
                right: 1.0,
                bottom: -1.0,
                top: 1.0,
            },
            _ => Projection::Perspective {
                left: -1.0,
                right: 1.0,
                bottom: 0.0,
                top: 1.0,
            },
        };
        View {
            eye: point,
            forward,
            up,
            projection,
            near,
            far,
        }
    }

    /// The unit right vector (`forward x up`).
    pub fn right(&self) -> Vec3 {
        self.forward.cross(self.up)
    }

    /// World-to-view matrix.
    pub fn view_matrix(&self) -> Mat4 {
        // Rows: right, up, -forward (right-handed, looking down -Z).
        let (r, u, f) = (self.right(), self.up, self.forward);
        Mat4::from_cols(
            glam::Vec4::new(r.x, u.x, -f.x, 0.0),
            glam::Vec4::new(r.y, u.y, -f.y, 0.0),
            glam::Vec4::new(r.z, u.z, -f.z, 0.0),
            glam::Vec4::new(-r.dot(self.eye), -u.dot(self.eye), f.dot(self.eye), 1.0),
        )
    }

    /// View-to-clip matrix (wgpu convention, depth in [0, 1]).
    pub fn projection_matrix(&self) -> Mat4 {
        let (n, f) = (self.near, self.far);
        match self.projection {
            Projection::Perspective {
                left,
                right,
                bottom,
                top,
            } => Mat4::from_cols_array(&[
                2.0 / (right - left),
                0.0,
                0.0,
                0.0,
                0.0,
                2.0 / (top - bottom),
                0.0,
                0.0,
                (right + left) / (right - left),
                (top + bottom) / (top - bottom),
                f / (n - f),
                -1.0,
                0.0,
                0.0,
                n * f / (n - f),
                0.0,
            ]),
            Projection::Orthographic {
                left,
                right,
                bottom,
                top,
            } => Mat4::from_cols_array(&[
                2.0 / (right - left),
                0.0,
                0.0,
                0.0,
                0.0,
                2.0 / (top - bottom),
                0.0,
                0.0,
                0.0,
                0.0,
                1.0 / (n - f),
                0.0,
                -(right + left) / (right - left),
                -(top + bottom) / (top - bottom),
                n / (n - f),
                1.0,
            ]),
        }
    }

    /// World-to-clip matrix.
    pub fn view_projection(&self) -> Mat4 {
        self.projection_matrix() * self.view_matrix()
    }

    /// The far-plane frustum vectors of eqs. 23-24 in world space, for perspective views.
    ///
    /// The thesis writes `f_x = z_f tan(theta/2)` and `f_y = aspect * f_x` with `theta` the
    /// vertical field of view; the physically sound reading, used here, is
    /// `f_y = z_f tan(theta/2)` and `f_x = aspect * f_y` (the general off-axis form takes the
    /// frustum's four tangents).
    pub fn frustum_corners(&self) -> Option<FrustumCorners> {
        let Projection::Perspective {
            left,
            right,
            bottom,
            top,
        } = self.projection
        else {
            return None;
        };
        let (r, u, f) = (self.right(), self.up, self.forward);
        let far = self.far;
        Some(FrustumCorners {
            origin: (r * left + u * top + f) * far,
            du: r * ((right - left) * far),
            dv: -u * ((top - bottom) * far),
        })
    }

    /// World-space position of the point at image coordinates `uv` with linear depth
    /// `depth` (distance along `forward` / far), by the frustum vectors (eq. 24) for
    /// perspective views and by the view frame for orthographic ones.
    pub fn reconstruct_world(&self, uv: Vec2, depth: f32) -> Vec3 {
        FrustumReconstruction::new(self).world(uv, depth)
    }

    /// The primary ray through image coordinates `uv`: origin and unit direction. The ray
    /// starts at the eye, not at the near plane (the path tracer sees what a rasteriser's
    /// near plane would clip).
    pub fn ray(&self, uv: Vec2) -> (Vec3, Vec3) {
        match self.projection {
            Projection::Perspective {
                left,
                right,
                bottom,
                top,
            } => {
                let x = left + (right - left) * uv.x;
                let y = top + (bottom - top) * uv.y;
                let d = (self.right() * x + self.up * y + self.forward).normalize();
                (self.eye, d)
            }
            Projection::Orthographic { .. } => (self.reconstruct_world(uv, 0.0), self.forward),
        }
    }

    /// Linear depth (distance along the view direction / far) of a world-space point.
    pub fn linear_depth(&self, p: Vec3) -> f32 {
        (p - self.eye).dot(self.forward) / self.far
    }

    /// Image coordinates `(u, v)` of a world-space point (may fall outside [0, 1]); `None`
    /// behind a perspective eye.
    pub fn project_uv(&self, p: Vec3) -> Option<Vec2> {
        let clip = self.view_projection() * p.extend(1.0);
        if clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        Some(Vec2::new(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5))
    }
}
