//! The scene model: only what diffuse light transport needs.
//!
//! A [`Scene`] holds world-space triangle meshes, diffuse materials, point and directional
//! lights, an optional sky ([`crate::sky`]) and cameras. Units are metres, the frame is
//! right-handed with +Y up (as glTF), and colours are linear RGB. [`Scene::validate`]
//! checks the invariants every technique relies on and repairs what can be repaired
//! without guessing (degenerate triangles are dropped, zero-length normals are recomputed).

use glam::{Vec2, Vec3};

use crate::error::SceneError;

/// A world-space triangle mesh. Every triangle carries its own material index.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Name, used in error messages.
    pub name: String,
    /// Vertex positions in world space (metres).
    pub positions: Vec<Vec3>,
    /// Vertex normals in world space, one per position (unit length after validation).
    pub normals: Vec<Vec3>,
    /// Optional texture coordinates, one per position.
    pub uvs: Option<Vec<Vec2>>,
    /// Optional vertex colours (glTF's `COLOR_0`, linear RGB in [0, 1]), one per position,
    /// multiplying the material's albedo (interpolated over each triangle).
    pub colors: Option<Vec<Vec3>>,
    /// Triangles as indices into `positions`.
    pub indices: Vec<[u32; 3]>,
    /// Material index per triangle (into [`Scene::materials`]).
    pub material_ids: Vec<u32>,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    /// The vertex colour of triangle `triangle` at barycentric weights `w` of its three
    /// vertices (white without colours, or for an index out of range).
    pub fn color_at(&self, triangle: usize, w: [f32; 3]) -> Vec3 {
        let (Some(colors), Some(t)) = (&self.colors, self.indices.get(triangle)) else {
            return Vec3::ONE;
        };
        (0..3)
            .map(|k| colors.get(t[k] as usize).copied().unwrap_or(Vec3::ONE) * w[k])
            .sum()
    }

    /// Appends a planar quad `a, b, c, d` (counter-clockwise seen from the side its normal
    /// faces) with one material, as two triangles with flat normals.
    pub fn push_quad(&mut self, corners: [Vec3; 4], material: u32) {
        let n = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .normalize_or_zero();
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&corners);
        self.normals.extend_from_slice(&[n; 4]);
        if let Some(uvs) = &mut self.uvs {
            uvs.extend_from_slice(&[
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(0.0, 1.0),
            ]);
        }
        if let Some(colors) = &mut self.colors {
            colors.extend_from_slice(&[Vec3::ONE; 4]);
        }
        self.indices.push([base, base + 1, base + 2]);
        self.indices.push([base, base + 2, base + 3]);
        self.material_ids.extend_from_slice(&[material, material]);
    }

    /// Appends a box of half extents `half` about `centre`, rotated by `yaw` radians about
    /// +Y, with outward faces (six quads, flat normals).
    pub fn push_box(&mut self, centre: Vec3, half: Vec3, yaw: f32, material: u32) {
        let rot = glam::Quat::from_rotation_y(yaw);
        let corner = |sx: f32, sy: f32, sz: f32| centre + rot * (half * Vec3::new(sx, sy, sz));
        let faces = [
            [
                corner(1., -1., -1.),
                corner(1., 1., -1.),
                corner(1., 1., 1.),
                corner(1., -1., 1.),
            ],
            [
                corner(-1., -1., 1.),
                corner(-1., 1., 1.),
                corner(-1., 1., -1.),
                corner(-1., -1., -1.),
            ],
            [
                corner(-1., 1., -1.),
                corner(-1., 1., 1.),
                corner(1., 1., 1.),
                corner(1., 1., -1.),
            ],
            [
                corner(-1., -1., 1.),
                corner(-1., -1., -1.),
                corner(1., -1., -1.),
                corner(1., -1., 1.),
            ],
            [
                corner(-1., -1., 1.),
                corner(1., -1., 1.),
                corner(1., 1., 1.),
                corner(-1., 1., 1.),
            ],
            [
                corner(1., -1., -1.),
                corner(-1., -1., -1.),
                corner(-1., 1., -1.),
                corner(1., 1., -1.),
            ],
        ];
        for c in faces {
            let fc = (c[0] + c[1] + c[2] + c[3]) * 0.25;
            self.push_quad_facing(c, material, 2.0 * fc - centre);
        }
    }

    /// Appends a planar quad with one material, wound so that its normal points towards
    /// `towards` (either winding given).
    pub fn push_quad_facing(&mut self, c: [Vec3; 4], material: u32, towards: Vec3) {
        let n = (c[1] - c[0]).cross(c[2] - c[0]);
        let centre = (c[0] + c[1] + c[2] + c[3]) * 0.25;
        if n.dot(towards - centre) < 0.0 {
            self.push_quad([c[3], c[2], c[1], c[0]], material);
        } else {
            self.push_quad(c, material);
        }
    }

    /// Appends a single triangle with flat normal.
    pub fn push_triangle(&mut self, p: [Vec3; 3], material: u32) {
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&p);
        self.normals.extend_from_slice(&[n; 3]);
        if let Some(uvs) = &mut self.uvs {
            uvs.extend_from_slice(&[Vec2::ZERO, Vec2::X, Vec2::Y]);
        }
        if let Some(colors) = &mut self.colors {
            colors.extend_from_slice(&[Vec3::ONE; 3]);
        }
        self.indices.push([base, base + 1, base + 2]);
        self.material_ids.push(material);
    }
}

/// A linear-RGB texture (already converted from sRGB where the source was sRGB).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Name, used in error messages.
    pub name: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major texels, top row first, linear RGB.
    pub texels: Vec<Vec3>,
    /// Optional alpha per texel (same order as `texels`, each in [0, 1]): kept only where a
    /// material with an [`Material::alpha_cutoff`] reads it; `None` reads as alpha 1.
    pub alpha: Option<Vec<f32>>,
    /// How coordinates outside [0, 1] wrap and whether texels are filtered.
    pub sampler: Sampler,
}

/// How a texture coordinate outside [0, 1] maps onto the image (glTF's `wrapS`/`wrapT`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// The image tiles (glTF's default).
    #[default]
    Repeat,
    /// The edge texels extend.
    ClampToEdge,
    /// The image tiles, every other copy mirrored.
    MirroredRepeat,
}

impl Wrap {
    /// The texel index `i` of a row of `n` under this wrap, in `0..n` (`n` at least 1).
    pub fn texel(self, i: i64, n: i64) -> i64 {
        if (0..n).contains(&i) {
            // Inside the row every mode is the identity (and no division is needed).
            return i;
        }
        match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::ClampToEdge => i.clamp(0, n - 1),
            Wrap::MirroredRepeat => {
                let m = i.rem_euclid(2 * n);
                if m < n { m } else { 2 * n - 1 - m }
            }
        }
    }

    /// `t` brought into the coordinate range the wrap repeats over, so that huge
    /// coordinates cannot overflow a texel index: `[0, 1)` (repeat), `[0, 2)` (mirrored
    /// repeat) or `[0, 1]` (clamp).
    pub fn reduce(self, t: f32) -> f32 {
        match self {
            Wrap::Repeat => t - t.floor(),
            Wrap::ClampToEdge => t.clamp(0.0, 1.0),
            Wrap::MirroredRepeat => t - 2.0 * (t * 0.5).floor(),
        }
    }

    /// The code the shaders use: 0 repeat, 1 clamp to edge, 2 mirrored repeat.
    pub fn code(self) -> u32 {
        match self {
            Wrap::Repeat => 0,
            Wrap::ClampToEdge => 1,
            Wrap::MirroredRepeat => 2,
        }
    }
}

/// A texture's sampling: wrap per axis and filter (glTF's sampler; the default is glTF's,
/// repeat and bilinear).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Sampler {
    /// Wrap along u (glTF's `wrapS`).
    pub wrap_u: Wrap,
    /// Wrap along v (glTF's `wrapT`).
    pub wrap_v: Wrap,
    /// Nearest texel instead of bilinear filtering (glTF's `magFilter` `NEAREST`).
    pub nearest: bool,
}

impl Sampler {
    /// The shaders' packed form: bits 0-1 the u wrap code, 2-3 the v wrap code, bit 4
    /// nearest.
    pub fn bits(self) -> u32 {
        self.wrap_u.code() | (self.wrap_v.code() << 2) | (u32::from(self.nearest) << 4)
    }
}

impl Texture {
    /// The texture's lookup at `uv` by its [`Sampler`] (bilinear or nearest, each axis
    /// wrapped by its mode); `uv` (0, 0) is the top-left corner of the image, as in glTF,
    /// and texel centres lie at half-integers. Black for an empty texture or a non-finite
    /// coordinate.
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        self.filter(uv, Vec3::ZERO, |i| self.texels[i], Vec3::lerp)
    }

    /// The texture's alpha at `uv`, filtered as [`Texture::sample`] filters colour: 1
    /// where the texture has no alpha, 0 for an empty texture or a non-finite coordinate.
    pub fn sample_alpha(&self, uv: Vec2) -> f32 {
        match &self.alpha {
            None => 1.0,
            Some(a) => self.filter(uv, 0.0, |i| a[i], |x, y, t| x + (y - x) * t),
        }
    }

    /// The sampler's lookup of one channel set: `at(i)` reads texel `i` (row-major),
    /// `lerp` blends two values.
    fn filter<T: Copy>(
        &self,
        uv: Vec2,
        empty: T,
        at: impl Fn(usize) -> T,
        lerp: impl Fn(T, T, f32) -> T,
    ) -> T {
        if self.width == 0 || self.height == 0 || !uv.is_finite() {
            return empty;
        }
        let (w, h) = (self.width as i64, self.height as i64);
        let Sampler {
            wrap_u,
            wrap_v,
            nearest,
        } = self.sampler;
        // Reduce first so that huge coordinates cannot overflow the integer texel index.
        let x = wrap_u.reduce(uv.x) * self.width as f32;
        let y = wrap_v.reduce(uv.y) * self.height as f32;
        let row = self.width as usize;
        if nearest {
            let xi = wrap_u.texel(x.floor() as i64, w) as usize;
            let yi = wrap_v.texel(y.floor() as i64, h) as usize;
            return at(yi * row + xi);
        }
        let (x, y) = (x - 0.5, y - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        // The two columns and the two rows, each wrapped once (not once per texel).
        let [c0, c1] = [x0, x0 + 1].map(|i| wrap_u.texel(i, w) as usize);
        let [r0, r1] = [y0, y0 + 1].map(|i| wrap_v.texel(i, h) as usize * row);
        let top = lerp(at(r0 + c0), at(r0 + c1), fx);
        let bottom = lerp(at(r1 + c0), at(r1 + c1), fx);
        lerp(top, bottom, fy)
    }
}

/// A diffuse (Lambertian) material: albedo = `albedo` x texture, plus emitted radiance.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name, used in error messages.
    pub name: String,
    /// Linear RGB albedo factor, each channel in [0, 1).
    pub albedo: Vec3,
    /// Optional base-colour texture (index into [`Scene::textures`]) multiplied with `albedo`.
    pub albedo_texture: Option<u32>,
    /// Emitted radiance (linear RGB, the scene's emission units), non-negative.
    pub emission: Vec3,
    /// Optional emission texture (index into [`Scene::textures`], glTF's
    /// `emissiveTexture`) multiplied with `emission` ([`Scene::emission_at`]): a lamp
    /// drawn as an emissive map.
    pub emission_texture: Option<u32>,
    /// Alpha masking (glTF's `alphaMode: MASK`): where set, the surface exists only where
    /// the albedo texture's alpha ([`Texture::sample_alpha`]; 1 without a texture or
    /// without alpha) is at least this value, and is a hole elsewhere: for rays, rasterised
    /// G-buffers and shadow maps alike. glTF's `alphaCutoff / baseColorFactor.a`, so a
    /// value above 1 makes the whole surface a hole. `None` (and 0) is opaque.
    pub alpha_cutoff: Option<f32>,
}

impl Material {
    /// A non-emissive diffuse material.
    pub fn diffuse(name: &str, albedo: Vec3) -> Self {
        Self {
            name: name.to_string(),
            albedo,
            albedo_texture: None,
            emission: Vec3::ZERO,
            emission_texture: None,
            alpha_cutoff: None,
        }
    }

    /// An emitter with the given albedo and emitted radiance.
    pub fn emissive(name: &str, albedo: Vec3, emission: Vec3) -> Self {
        Self {
            name: name.to_string(),
            albedo,
            albedo_texture: None,
            emission,
            emission_texture: None,
            alpha_cutoff: None,
        }
    }

    /// True when the material emits light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// True when the material has holes: an alpha cutoff above 0.
    pub fn is_masked(&self) -> bool {
        self.alpha_cutoff.is_some_and(|c| c > 0.0)
    }
}

/// A point light.
///
/// The irradiance it gives a surface at distance `d` facing it is `intensity * falloff(d)`.
/// The falloff is the physical inverse square `1 / d^2` unless `radius` is set, in which case
/// it is the thesis' windowed falloff (eq. 16): `saturate(1 - (d / radius)^2)`.
#[derive(Clone, Debug, PartialEq)]
pub struct PointLight {
    /// Name, used in error messages.
    pub name: String,
    /// Position in world space.
    pub position: Vec3,
    /// Radiant intensity, linear RGB (W/sr in the scene's units).
    pub intensity: Vec3,
    /// Optional radius of the windowed falloff of eq. 16.
    pub radius: Option<f32>,
    /// The cone of a spot light (`None`: light in every direction).
    pub cone: Option<crate::lights::SpotCone>,
}

impl PointLight {
    /// A point light sending `intensity` in every direction, inverse-square falloff.
    pub fn new(name: &str, position: Vec3, intensity: Vec3) -> Self {
        Self {
            name: name.into(),
            position,
            intensity,
            radius: None,
            cone: None,
        }
    }

    /// The factor on the intensity towards unit direction `w` (from the light): the spot
    /// cone's [`crate::lights::SpotCone::attenuation`], 1 without a cone.
    pub fn attenuation(&self, w: Vec3) -> f32 {
        self.cone.map_or(1.0, |c| c.attenuation(w))
    }

    /// The intensity towards unit direction `w` (from the light).
    pub fn intensity_towards(&self, w: Vec3) -> Vec3 {
        self.intensity * self.attenuation(w)
    }

    /// The solid angle its intensity is sent over: 4 pi, or the cone's
    /// [`crate::lights::SpotCone::solid_angle`]. Its power is `intensity` times this.
    pub fn solid_angle(&self) -> f32 {
        self.cone
            .map_or(4.0 * std::f32::consts::PI, |c| c.solid_angle())
    }

    /// The distance falloff: `1/d^2`, or eq. 16's `saturate(1 - (d/r)^2)` when a radius is set.
    /// Never infinite: 0 at zero distance, and at most `f32::MAX` for tiny distances.
    pub fn falloff(&self, distance: f32) -> f32 {
        crate::lights::falloff(self.radius, distance)
    }
}

/// A directional light (the sun): parallel rays along `direction`.
#[derive(Clone, Debug, PartialEq)]
pub struct DirectionalLight {
    /// Name, used in error messages.
    pub name: String,
    /// Unit direction the light travels in (from the light towards the scene).
    pub direction: Vec3,
    /// Irradiance on a surface perpendicular to `direction`, linear RGB.
    pub irradiance: Vec3,
}

/// A perspective camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Name, used in error messages and output files.
    pub name: String,
    /// Eye position.
    pub position: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Up hint (need not be orthogonal to the view direction).
    pub up: Vec3,
    /// Vertical field of view in radians.
    pub fov_y: f32,
    /// Width / height.
    pub aspect: f32,
    /// Near plane distance (> 0).
    pub near: f32,
    /// Far plane distance (> near).
    pub far: f32,
}

impl Camera {
    /// The same camera with another aspect ratio (for rendering at a given resolution).
    pub fn with_aspect(&self, aspect: f32) -> Self {
        Self {
            aspect,
            ..self.clone()
        }
    }

    /// The up vector its views use: [`Camera::up`] unless that is zero or parallel to the
    /// view direction (a camera looking straight up or down with the default +Y), then the
    /// first of -Z, +Y, +X that is not, so every camera with a view direction has a view.
    pub fn view_up(&self) -> Vec3 {
        let forward = (self.target - self.position).normalize_or_zero();
        [self.up, Vec3::NEG_Z, Vec3::Y, Vec3::X]
            .into_iter()
            .map(|c| (c / c.abs().max_element()).normalize_or_zero())
            .find(|c| forward.cross(*c).length_squared() > 1e-6)
            .unwrap_or(Vec3::Y)
    }

    /// Checks what every view of this camera needs: finite position, target and up; a view
    /// direction of non-zero length (up may be zero or parallel to it: [`Camera::view_up`]
    /// picks one); a vertical field of view in (0, [`FOV_MAX`]]; finite aspect > 0; planes
    /// with 0 < near < far, far / near at most [`DEPTH_RANGE_MAX`] and near x far finite.
    /// The error names the camera (`index` labels an unnamed one) and says what is wrong.
    /// [`Scene::validate`] and every loader of cameras (glTF, camera lists) use this one
    /// check.
    pub fn check(&self, index: usize) -> Result<(), SceneError> {
        let dir = self.target - self.position;
        let reason = if !(self.position.is_finite()
            && self.target.is_finite()
            && self.up.is_finite())
        {
            Some("position, target or up is not finite".to_string())
        } else if dir.length_squared() == 0.0 || !dir.length_squared().is_finite() {
            Some("target equals position (or lies too far to measure)".into())
        } else if !(self.fov_y > 0.0 && self.fov_y <= FOV_MAX) {
            Some(format!(
                "vertical field of view {} rad ({:.2} degrees) is outside (0, {:.0} degrees]: \
                     wider, the rasterising methods clip at the near plane what the path \
                     tracer sees",
                self.fov_y,
                self.fov_y.to_degrees(),
                FOV_MAX.to_degrees()
            ))
        } else if !(self.aspect > 0.0 && self.aspect.is_finite()) {
            Some(format!(
                "aspect ratio {} is not finite and > 0",
                self.aspect
            ))
        } else if !(self.near > 0.0 && self.far > self.near && self.far.is_finite()) {
            Some(format!(
                "planes near {} and far {} break 0 < near < far < infinity",
                self.near, self.far
            ))
        } else if !(self.far / self.near <= DEPTH_RANGE_MAX && (self.near * self.far).is_finite()) {
            Some(format!(
                "planes near {:e} and far {:e}: far / near is {:e}, above {DEPTH_RANGE_MAX:e} \
                     (or near x far overflows), so f32 depth cannot tell near from far and \
                     the rasterising methods draw nothing",
                self.near,
                self.far,
                self.far / self.near
            ))
        } else {
            None
        };
        match reason {
            None => Ok(()),
            Some(reason) => Err(SceneError::InvalidCamera {
                camera: label_or_index(&self.name, "camera", index),
                reason,
            }),
        }
    }
}

/// The widest vertical field of view a camera may have: 170 degrees. Wider, the rasterising
/// methods (DL, ISR, relighting, the IBRR) clip at the near plane much of what the path
/// tracer, whose rays start at the eye, sees.
pub const FOV_MAX: f32 = 170.0 * std::f32::consts::PI / 180.0;

/// The largest far / near ratio a camera may have: beyond it f32 depth (z / w of a
/// perspective projection) rounds near and far geometry to the same value and the
/// rasterisers draw nothing.
pub const DEPTH_RANGE_MAX: f32 = 1e6;

/// A scene: meshes, materials, textures, lights and cameras.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    /// Name of the scene (built-in name or file stem).
    pub name: String,
    /// Triangle meshes in world space.
    pub meshes: Vec<Mesh>,
    /// Materials referenced by the meshes' `material_ids`.
    pub materials: Vec<Material>,
    /// Textures referenced by materials.
    pub textures: Vec<Texture>,
    /// Point lights.
    pub point_lights: Vec<PointLight>,
    /// Directional lights.
    pub directional_lights: Vec<DirectionalLight>,
    /// The sky, if the scene is open to one ([`crate::sky`]): one light source
    /// ([`crate::LightId::Sky`]).
    pub sky: Option<crate::sky::Sky>,
    /// Cameras; the first is the default view.
    pub cameras: Vec<Camera>,
}

/// What [`Scene::validate`] repaired.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ValidationReport {
    /// Degenerate (zero-area) triangles dropped, per mesh: (mesh name, count).
    pub degenerate_dropped: Vec<(String, usize)>,
    /// Normals recomputed from faces because they were missing, zero or not finite.
    pub normals_recomputed: usize,
    /// Triangles dropped because an earlier triangle (of any mesh) has the same three
    /// vertex positions, per mesh: (mesh name, count). Coincident faces have no defined
    /// radiosity between them (their form factor is singular) and only z-fight when drawn.
    pub duplicates_dropped: Vec<(String, usize)>,
}

impl ValidationReport {
    /// Total number of degenerate triangles dropped.
    pub fn total_degenerate(&self) -> usize {
        self.degenerate_dropped.iter().map(|(_, n)| n).sum()
    }
}

/// Identifies one triangle of a scene by mesh and local index, and by global id.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TriangleRef {
    /// Index of the mesh.
    pub mesh: u32,
    /// Index of the triangle in its mesh.
    pub local: u32,
}

/// Axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Bounds {
    /// The empty box (min = +inf, max = -inf).
    pub const EMPTY: Bounds = Bounds {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The box around `points` (empty for none).
    pub fn around(points: impl IntoIterator<Item = Vec3>) -> Self {
        let mut b = Self::EMPTY;
        points.into_iter().for_each(|p| b.grow(p));
        b
    }

    /// Grows the box to contain `p`.
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// True when nothing was added.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }

    /// Length of the diagonal (0 for an empty box).
    pub fn diagonal(&self) -> f32 {
        if self.is_empty() {
            0.0
        } else {
            (self.max - self.min).length()
        }
    }

    /// Centre of the box.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
}

/// Triangles whose area is below this fraction of the squared scene extent are degenerate.
const DEGENERATE_REL_AREA: f32 = 1e-14;

/// The largest albedo a channel may have. Radiosity diverges at 1, and a light path (or a
/// progressive solve) in a closed room of albedo rho needs about 1 / (1 - rho) bounces: at
/// 0.999 a thousand, the most a reference render or a solve can afford. The glTF importer
/// clamps to it with a note.
pub const ALBEDO_MAX: f32 = 0.999;

/// The largest emitted radiance, point-light intensity or directional irradiance a scene may
/// give (any channel). The sun's disc is about 2e7 W/(m^2 sr); this bound leaves f32 about
/// 26 orders of magnitude for the sums, the inverse-square gains of nearby lights and the
/// squares (variances, errors) every method takes of radiance.
pub const RADIOMETRIC_MAX: f32 = 1e12;

/// [`SceneError::OutOfRange`] unless every channel of `v` lies in `[0, max]` (NaN fails).
fn check_channels(what: impl FnOnce() -> String, v: Vec3, max: f32) -> Result<(), SceneError> {
    let ok = |x: f32| (0.0..=max).contains(&x);
    match v.to_array().into_iter().find(|&x| !ok(x)) {
        None => Ok(()),
        Some(bad) => Err(SceneError::OutOfRange {
            what: what(),
            value: bad,
            min: 0.0,
            max,
        }),
    }
}

impl Scene {
    /// An empty scene with a name.
    pub fn new(name: &str) -> Self {
        Self {
            name: name.to_string(),
            ..Default::default()
        }
    }

    /// Total number of triangles over all meshes.
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.indices.len()).sum()
    }

    /// Prefix sums of triangle counts: global id of the first triangle of each mesh, plus the
    /// total at the end. Global triangle ids number the triangles mesh by mesh.
    pub fn mesh_offsets(&self) -> Vec<u32> {
        let mut offsets = Vec::with_capacity(self.meshes.len() + 1);
        let mut acc = 0u32;
        for m in &self.meshes {
            offsets.push(acc);
            acc += m.indices.len() as u32;
        }
        offsets.push(acc);
        offsets
    }

    /// Every triangle's world-space corners in global triangle-id order (what an engine's
    /// shadow casters or an id raster of the scene are; a corner past a mesh's positions,
    /// which validation refuses, reads as the origin).
    pub fn triangle_corners(&self) -> Vec<[Vec3; 3]> {
        self.meshes
            .iter()
            .flat_map(|m| {
                m.indices
                    .iter()
                    .map(|t| t.map(|i| m.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO)))
            })
            .collect()
    }

    /// The bounding box of all mesh vertices.
    pub fn bounds(&self) -> Bounds {
        let mut b = Bounds::EMPTY;
        for m in &self.meshes {
            for &p in &m.positions {
                b.grow(p);
            }
        }
        b
    }

    /// A characteristic length of the scene: the diagonal of its bounds (1 when empty), used
    /// to size epsilons and sample radii relative to the scene.
    pub fn extent(&self) -> f32 {
        let d = self.bounds().diagonal();
        if d > 0.0 && d.is_finite() { d } else { 1.0 }
    }

    /// Albedo of a material at texture coordinates `uv` (factor x bilinear texture sample).
    pub fn albedo_at(&self, material: u32, uv: Option<Vec2>) -> Vec3 {
        let m = &self.materials[material as usize];
        match (m.albedo_texture, uv) {
            (Some(t), Some(uv)) => m.albedo * self.textures[t as usize].sample(uv),
            _ => m.albedo,
        }
    }

    /// Emitted radiance of a material at texture coordinates `uv` (factor x emission
    /// texture; the factor alone without a texture or coordinates).
    pub fn emission_at(&self, material: u32, uv: Option<Vec2>) -> Vec3 {
        let m = &self.materials[material as usize];
        match (m.emission_texture, uv) {
            (Some(t), Some(uv)) if m.is_emissive() => {
                m.emission * self.textures[t as usize].sample(uv)
            }
            _ => m.emission,
        }
    }

    /// The mean emitted radiance over triangle `local` of mesh `mesh`: the material's
    /// emission, or with an emission texture its mean over the triangle from 64 samples
    /// ([`crate::cutout::triangle_samples`]). What methods that treat a triangle as one
    /// emitter (its power, its colour on screen) use.
    pub fn triangle_emission(&self, mesh: usize, local: usize) -> Vec3 {
        let m = &self.meshes[mesh];
        let material = m.material_ids[local];
        let mat = &self.materials[material as usize];
        let Some(uvs) = m
            .uvs
            .as_ref()
            .filter(|_| mat.emission_texture.is_some() && mat.is_emissive())
        else {
            return mat.emission;
        };
        let t = m.indices[local].map(|i| uvs[i as usize]);
        let n = 8;
        crate::cutout::triangle_samples(n)
            .map(|b| {
                self.emission_at(
                    material,
                    Some(t[0] * (1.0 - b.x - b.y) + t[1] * b.x + t[2] * b.y),
                )
            })
            .sum::<Vec3>()
            / (n * n) as f32
    }

    /// True where a surface of `material` exists at texture coordinates `uv`: always for an
    /// unmasked material, else where the albedo texture's alpha reaches the cutoff
    /// ([`Material::alpha_cutoff`]). Without coordinates or a texture the alpha is 1.
    pub fn opaque_at(&self, material: u32, uv: Option<Vec2>) -> bool {
        let m = &self.materials[material as usize];
        let Some(cutoff) = m.alpha_cutoff.filter(|&c| c > 0.0) else {
            return true;
        };
        let alpha = match (m.albedo_texture, uv) {
            (Some(t), Some(uv)) => self.textures[t as usize].sample_alpha(uv),
            _ => 1.0,
        };
        alpha >= cutoff
    }

    /// Checks the scene and repairs what can be repaired.
    ///
    /// Errors (each names the mesh, triangle, material or light at fault): non-finite
    /// positions or UVs, UV or material-id counts that do not match, indices out of range,
    /// material ids out of range, albedo outside [0, [`ALBEDO_MAX`]] (radiosity diverges at
    /// 1), negative or non-finite emission, non-finite or negative light data, emission,
    /// intensity or irradiance above [`RADIOMETRIC_MAX`] ([`SceneError::OutOfRange`]),
    /// invalid cameras. What a method needs of the whole scene (geometry, precision) is
    /// checked by [`crate::contract::check`].
    /// Repairs: degenerate triangles, and triangles that repeat an earlier one's positions
    /// (coincident faces), are dropped and counted; missing, zero-length or
    /// non-finite normals are recomputed from the faces (a normal array whose length does not
    /// match the positions is replaced whole, every vertex counted).
    pub fn validate(&mut self) -> Result<ValidationReport, SceneError> {
        let mut report = ValidationReport::default();
        self.validate_materials()?;
        self.validate_lights()?;
        self.validate_cameras()?;
        // Extent from finite positions only: non-finite ones are reported below.
        let mut bounds = Bounds::EMPTY;
        for (mi, mesh) in self.meshes.iter().enumerate() {
            for (vi, p) in mesh.positions.iter().enumerate() {
                if !p.is_finite() {
                    return Err(SceneError::NonFinitePosition {
                        mesh: mesh_label(mesh, mi),
                        vertex: vi,
                    });
                }
                bounds.grow(*p);
            }
        }
        // In f64: the square of a huge (finite) extent must not overflow to infinity.
        let extent = (bounds.max - bounds.min).as_dvec3().length();
        let min_area = DEGENERATE_REL_AREA as f64 * extent * extent;
        let material_count = self.materials.len();
        for (mi, mesh) in self.meshes.iter_mut().enumerate() {
            let label = mesh_label(mesh, mi);
            let nverts = mesh.positions.len();
            if mesh.material_ids.len() != mesh.indices.len() {
                return Err(SceneError::MaterialCountMismatch {
                    mesh: label,
                    triangles: mesh.indices.len(),
                    material_ids: mesh.material_ids.len(),
                });
            }
            if let Some(uvs) = &mesh.uvs {
                if uvs.len() != nverts {
                    return Err(SceneError::AttributeCountMismatch {
                        mesh: label,
                        attribute: "uvs",
                        expected: nverts,
                        found: uvs.len(),
                    });
                }
                if let Some(v) = uvs.iter().position(|uv| !uv.is_finite()) {
                    return Err(SceneError::NonFiniteAttribute {
                        mesh: label,
                        attribute: "uvs",
                        vertex: v,
                    });
                }
            }
            if let Some(colors) = &mesh.colors {
                if colors.len() != nverts {
                    return Err(SceneError::AttributeCountMismatch {
                        mesh: label,
                        attribute: "colors",
                        expected: nverts,
                        found: colors.len(),
                    });
                }
                let outside = |c: &Vec3| !(c.min_element() >= 0.0 && c.max_element() <= 1.0);
                if let Some(v) = colors.iter().position(outside) {
                    return Err(SceneError::NonFiniteAttribute {
                        mesh: label,
                        attribute: "colors (outside [0, 1])",
                        vertex: v,
                    });
                }
            }
            for (ti, (tri, &mat)) in mesh.indices.iter().zip(&mesh.material_ids).enumerate() {
                if let Some(&bad) = tri.iter().find(|&&i| i as usize >= nverts) {
                    return Err(SceneError::IndexOutOfRange {
                        mesh: label,
                        triangle: ti,
                        index: bad,
                        vertex_count: nverts,
                    });
                }
                if mat as usize >= material_count {
                    return Err(SceneError::MaterialOutOfRange {
                        mesh: label,
                        triangle: ti,
                        material: mat,
                        material_count,
                    });
                }
            }
            // Drop degenerate triangles.
            let before = mesh.indices.len();
            let positions = &mesh.positions;
            let keep: Vec<bool> = mesh
                .indices
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| positions[i as usize]);
                    let [a, b, c] = [a, b, c].map(|p| p.as_dvec3());
                    0.5 * (b - a).cross(c - a).length() > min_area
                })
                .collect();
            let mut k = keep.iter();
            mesh.indices.retain(|_| *k.next().unwrap_or(&true));
            let mut k = keep.iter();
            mesh.material_ids.retain(|_| *k.next().unwrap_or(&true));
            let dropped = before - mesh.indices.len();
            if dropped > 0 {
                report.degenerate_dropped.push((label.clone(), dropped));
            }
            // Repair normals.
            if mesh.normals.len() != nverts {
                mesh.normals = vec![Vec3::ZERO; nverts];
            }
            let needs: Vec<bool> = mesh
                .normals
                .iter()
                .map(|n| n.try_normalize().is_none() || n.length_squared() < 1e-24)
                .collect();
            let count = needs.iter().filter(|&&b| b).count();
            if count > 0 {
                let face = face_normal_sums(mesh);
                for (v, need) in needs.iter().enumerate() {
                    if *need {
                        // A vertex used by no triangle, or whose face normals cancel, gets +Y:
                        // it is never shaded by a triangle that reads a cancelled sum.
                        mesh.normals[v] = face[v].try_normalize().unwrap_or(Vec3::Y);
                    }
                }
                report.normals_recomputed += count;
            }
            for n in &mut mesh.normals {
                *n = n.normalize();
            }
        }
        self.drop_duplicate_triangles(&mut report);
        Ok(report)
    }

    /// Drops every triangle whose three vertex positions (in any order) equal those of an
    /// earlier triangle, meshes in order; the first keeps its material. Deterministic, and
    /// 16 bytes a triangle of scratch (a sorted list of position hashes).
    fn drop_duplicate_triangles(&mut self, report: &mut ValidationReport) {
        use rayon::slice::ParallelSliceMut;
        use std::hash::{Hash, Hasher};
        let key = |m: &Mesh, t: usize| -> [[u32; 3]; 3] {
            let mut k = m.indices[t].map(|i| m.positions[i as usize].to_array().map(f32::to_bits));
            k.sort_unstable();
            k
        };
        let mut entries: Vec<(u64, u32, u32)> = Vec::with_capacity(self.triangle_count());
        for (mi, m) in self.meshes.iter().enumerate() {
            for t in 0..m.indices.len() {
                let mut h = std::hash::DefaultHasher::new();
                key(m, t).hash(&mut h);
                entries.push((h.finish(), mi as u32, t as u32));
            }
        }
        entries.par_sort_unstable();
        let mut drop: Vec<Vec<bool>> = self
            .meshes
            .iter()
            .map(|m| vec![false; m.indices.len()])
            .collect();
        let mut any = false;
        for group in entries.chunk_by(|a, b| a.0 == b.0) {
            // Within one hash: each triangle is a duplicate when an earlier one of the group
            // has exactly its positions (the group is in mesh, triangle order).
            for (i, &(_, mi, t)) in group.iter().enumerate().skip(1) {
                let k = key(&self.meshes[mi as usize], t as usize);
                let seen = group[..i]
                    .iter()
                    .any(|&(_, mj, u)| key(&self.meshes[mj as usize], u as usize) == k);
                if seen {
                    drop[mi as usize][t as usize] = true;
                    any = true;
                }
            }
        }
        if !any {
            return;
        }
        for (mi, (mesh, drop)) in self.meshes.iter_mut().zip(&drop).enumerate() {
            let count = drop.iter().filter(|&&d| d).count();
            if count == 0 {
                continue;
            }
            let mut d = drop.iter();
            mesh.indices.retain(|_| !*d.next().unwrap_or(&false));
            let mut d = drop.iter();
            mesh.material_ids.retain(|_| !*d.next().unwrap_or(&false));
            report
                .duplicates_dropped
                .push((mesh_label(mesh, mi), count));
        }
    }

    fn validate_materials(&self) -> Result<(), SceneError> {
        for (i, m) in self.materials.iter().enumerate() {
            let name = label_or_index(&m.name, "material", i);
            if !m.albedo.is_finite()
                || m.albedo.min_element() < 0.0
                || m.albedo.max_element() > ALBEDO_MAX
            {
                return Err(SceneError::AlbedoOutOfRange {
                    material: name,
                    albedo: m.albedo.to_array(),
                });
            }
            if !m.emission.is_finite() || m.emission.min_element() < 0.0 {
                return Err(SceneError::InvalidEmission {
                    material: name,
                    emission: m.emission.to_array(),
                });
            }
            check_channels(|| format!("{name}: emission"), m.emission, RADIOMETRIC_MAX)?;
            if let Some(t) = m.emission_texture
                && self.textures.get(t as usize).is_none_or(|tex| {
                    tex.texels.len() != tex.width as usize * tex.height as usize
                        || tex
                            .texels
                            .iter()
                            .any(|c| !c.is_finite() || c.min_element() < 0.0)
                })
            {
                return Err(SceneError::InvalidMaterial {
                    material: name,
                    reason: format!(
                        "emission texture {t} does not exist or is malformed (the scene has {})",
                        self.textures.len()
                    ),
                });
            }
            if let Some(t) = m.albedo_texture {
                let Some(tex) = self.textures.get(t as usize) else {
                    return Err(SceneError::TextureOutOfRange {
                        material: name,
                        texture: t,
                        texture_count: self.textures.len(),
                    });
                };
                if tex.texels.len() != tex.width as usize * tex.height as usize
                    || tex.texels.is_empty()
                {
                    return Err(SceneError::InvalidTexture {
                        texture: label_or_index(&tex.name, "texture", t as usize),
                        reason: format!(
                            "{} texels for {}x{}",
                            tex.texels.len(),
                            tex.width,
                            tex.height
                        ),
                    });
                }
                if tex
                    .texels
                    .iter()
                    .any(|c| !c.is_finite() || c.min_element() < 0.0 || c.max_element() > 1.0)
                {
                    return Err(SceneError::InvalidTexture {
                        texture: label_or_index(&tex.name, "texture", t as usize),
                        reason: "texel outside [0, 1] or not finite".into(),
                    });
                }
                if let Some(a) = &tex.alpha {
                    if a.len() != tex.texels.len() {
                        return Err(SceneError::InvalidTexture {
                            texture: label_or_index(&tex.name, "texture", t as usize),
                            reason: format!(
                                "{} alpha values for {} texels",
                                a.len(),
                                tex.texels.len()
                            ),
                        });
                    }
                    if a.iter().any(|v| !(0.0..=1.0).contains(v)) {
                        return Err(SceneError::InvalidTexture {
                            texture: label_or_index(&tex.name, "texture", t as usize),
                            reason: "alpha outside [0, 1] or not finite".into(),
                        });
                    }
                }
            }
            if let Some(c) = m.alpha_cutoff
                && !(c.is_finite() && c >= 0.0)
            {
                return Err(SceneError::InvalidMaterial {
                    material: name,
                    reason: format!("alpha cutoff {c} is not a finite value of at least 0"),
                });
            }
        }
        Ok(())
    }

    fn validate_lights(&self) -> Result<(), SceneError> {
        for (i, l) in self.point_lights.iter().enumerate() {
            let bad = !l.position.is_finite()
                || !l.intensity.is_finite()
                || l.intensity.min_element() < 0.0
                || l.radius.is_some_and(|r| !(r.is_finite() && r > 0.0));
            if bad {
                return Err(SceneError::InvalidLight {
                    light: label_or_index(&l.name, "point light", i),
                    reason: "position, intensity or radius not finite, or negative".into(),
                });
            }
            if let Some(reason) = l.cone.as_ref().and_then(|c| c.fault()) {
                return Err(SceneError::InvalidLight {
                    light: label_or_index(&l.name, "point light", i),
                    reason,
                });
            }
            check_channels(
                || format!("{}: intensity", label_or_index(&l.name, "point light", i)),
                l.intensity,
                RADIOMETRIC_MAX,
            )?;
        }
        for (i, l) in self.directional_lights.iter().enumerate() {
            let bad = !l.direction.is_finite()
                || l.direction.length_squared() < 1e-12
                || !l.irradiance.is_finite()
                || l.irradiance.min_element() < 0.0;
            if bad {
                return Err(SceneError::InvalidLight {
                    light: label_or_index(&l.name, "directional light", i),
                    reason: "direction zero or not finite, or irradiance negative or not finite"
                        .into(),
                });
            }
            check_channels(
                || {
                    format!(
                        "{}: irradiance",
                        label_or_index(&l.name, "directional light", i)
                    )
                },
                l.irradiance,
                RADIOMETRIC_MAX,
            )?;
        }
        Ok(())
    }

    fn validate_cameras(&self) -> Result<(), SceneError> {
        for (i, c) in self.cameras.iter().enumerate() {
            c.check(i)?;
        }
        Ok(())
    }

    /// The scene with every length multiplied by `k` (positions, cameras and their planes,
    /// point lights and their radii). Point intensities are multiplied by `k^2` so that the
    /// irradiance they give is unchanged; emitted radiance, albedo and directional irradiance
    /// are scale-free. A renderer whose parameters are relative to the scene gives the same
    /// picture of `s.scaled(k)` as of `s`: the scale-invariance tests rest on this.
    pub fn scaled(mut self, k: f32) -> Scene {
        for m in &mut self.meshes {
            for p in &mut m.positions {
                *p *= k;
            }
        }
        for c in &mut self.cameras {
            c.position *= k;
            c.target *= k;
            c.near *= k;
            c.far *= k;
        }
        for l in &mut self.point_lights {
            l.position *= k;
            l.intensity *= k * k;
            l.radius = l.radius.map(|r| r * k);
        }
        self
    }

    /// Maps a global triangle id to its mesh and local index (binary search over offsets).
    pub fn triangle_ref(&self, offsets: &[u32], global: u32) -> Option<TriangleRef> {
        if offsets.is_empty() || global >= *offsets.last()? {
            return None;
        }
        let mesh = offsets.partition_point(|&o| o <= global) - 1;
        Some(TriangleRef {
            mesh: mesh as u32,
            local: global - offsets[mesh],
        })
    }
}

fn face_normal_sums(mesh: &Mesh) -> Vec<Vec3> {
    let mut sums = vec![Vec3::ZERO; mesh.positions.len()];
    for t in &mesh.indices {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        // Area-weighted face normal.
        let n = (b - a).cross(c - a);
        for &i in t {
            sums[i as usize] += n;
        }
    }
    sums
}

pub(crate) fn mesh_label(mesh: &Mesh, index: usize) -> String {
    label_or_index(&mesh.name, "mesh", index)
}

pub(crate) fn label_or_index(name: &str, kind: &str, index: usize) -> String {
    if name.is_empty() {
        format!("{kind} #{index}")
    } else {
        format!("{kind} #{index} '{name}'")
    }
}
