//! Camera lists: JSON files of views per scene, and seeded random cameras drawn inside a
//! scene's free space (the thesis drew random views too).
//!
//! A camera list is a JSON array of [`CameraSpec`]s, or an object `{"cameras": [...]}`:
//!
//! ```json
//! [{"name": "front", "position": [0, 1, 5], "target": [0, 1, 0], "up": [0, 1, 0], "fov": 45}]
//! ```
//!
//! `fov` is the vertical field of view in degrees; `name`, `up` (default +Y), `near` and
//! `far` (default: from the scene's extent) may be left out.

use std::path::Path;

use glam::Vec3;
use scene_core::ray::RayScene;
use scene_core::sampling::{Rng, uniform_sphere};
use scene_core::{Camera, Scene, View};
use serde::{Deserialize, Serialize};

use crate::HarnessError;

/// One camera of a camera list, as written in JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraSpec {
    /// Name used in output file names (default: `view<i>`).
    #[serde(default)]
    pub name: Option<String>,
    /// Eye position.
    pub position: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
    /// Up hint (default +Y).
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees.
    pub fov: f32,
    /// Near plane (default: the scene's extent times 1e-3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub near: Option<f32>,
    /// Far plane (default: twice the scene's extent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub far: Option<f32>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Deserialize)]
#[serde(untagged)]
enum CameraFile {
    List(Vec<CameraSpec>),
    Object { cameras: Vec<CameraSpec> },
}

impl CameraSpec {
    /// The spec of an existing camera.
    pub fn from_camera(camera: &Camera) -> Self {
        Self {
            name: Some(camera.name.clone()),
            position: camera.position.to_array(),
            target: camera.target.to_array(),
            up: camera.up.to_array(),
            fov: camera.fov_y.to_degrees(),
            near: Some(camera.near),
            far: Some(camera.far),
        }
    }

    /// The camera for `scene` (aspect 1; the harness sets the image's aspect). `index` names
    /// unnamed cameras. Fails on a field of view outside (0, 180) degrees and on whatever
    /// [`Camera::check`] refuses (non-finite values, a zero view direction, a field of view
    /// above 170 degrees, planes out of order or too far apart), exactly as for a scene's
    /// own cameras.
    pub fn to_camera(&self, scene: &Scene, index: usize) -> Result<Camera, String> {
        let p = Vec3::from_array(self.position);
        let t = Vec3::from_array(self.target);
        let up = Vec3::from_array(self.up);
        let name = self.name.clone().unwrap_or_else(|| format!("view{index}"));
        if !(self.fov > 0.0 && self.fov < 180.0) {
            return Err(format!(
                "camera '{name}': fov must be in (0, 180) degrees, got {}",
                self.fov
            ));
        }
        let extent = scene.extent().max(1e-6);
        let far = self
            .far
            .unwrap_or_else(|| (p - scene.bounds().center()).length() + extent * 2.0);
        let near = self.near.unwrap_or(extent * 1e-3);
        let camera = Camera {
            name,
            position: p,
            target: t,
            up,
            fov_y: self.fov.to_radians(),
            aspect: 1.0,
            near,
            far,
        };
        // The same check as a scene's own cameras (values that JSON's f64 turned into
        // infinity or zero when narrowed to f32 fail here).
        camera.check(index).map_err(|e| e.to_string())?;
        Ok(camera)
    }
}

/// Parses a camera list (JSON text) for `scene`; `source` names the file in errors.
pub fn parse_camera_list(
    text: &str,
    scene: &Scene,
    source: &str,
) -> Result<Vec<Camera>, HarnessError> {
    let bad = |message: String| HarnessError::CameraList {
        path: source.into(),
        message,
    };
    let file: CameraFile = serde_json::from_str(text).map_err(|e| {
        bad(format!(
            "{e} (expected a JSON array of {{position, target, up, fov}} objects)"
        ))
    })?;
    let specs = match file {
        CameraFile::List(v) | CameraFile::Object { cameras: v } => v,
    };
    if specs.is_empty() {
        return Err(bad("the list holds no camera".into()));
    }
    specs
        .iter()
        .enumerate()
        .map(|(i, s)| s.to_camera(scene, i).map_err(&bad))
        .collect()
}

/// Reads a camera list file for `scene`.
pub fn load_camera_list(path: &Path, scene: &Scene) -> Result<Vec<Camera>, HarnessError> {
    let bad = |message: String| HarnessError::CameraList {
        path: path.display().to_string(),
        message,
    };
    // Within the file budget, and never from a device or FIFO.
    let bytes = scene_core::budget::read_file(path, &scene_core::Budget::default())
        .map_err(|e| bad(e.to_string()))?;
    let text = String::from_utf8(bytes).map_err(|e| bad(format!("not UTF-8: {e}")))?;
    parse_camera_list(&text, scene, &path.display().to_string())
}

/// Writes `cameras` as a camera list file.
pub fn save_camera_list(path: &Path, cameras: &[Camera]) -> Result<(), HarnessError> {
    let specs: Vec<CameraSpec> = cameras.iter().map(CameraSpec::from_camera).collect();
    crate::write_json(path, &specs)
}

/// Settings of [`random_cameras`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RandomCameraSettings {
    /// Seed of every draw.
    pub seed: u64,
    /// Vertical field of view in degrees.
    pub fov: f32,
    /// Smallest share of probe rays through the image that must hit geometry.
    pub min_coverage: f32,
    /// Fewest distinct triangles the probe rays must hit (so a view is not one flat wall
    /// or the bare ground).
    pub min_triangles: usize,
    /// Candidates tried per camera before giving up.
    pub max_attempts: u32,
}

impl Default for RandomCameraSettings {
    fn default() -> Self {
        Self {
            seed: 1,
            fov: 55.0,
            min_coverage: 0.7,
            min_triangles: 4,
            max_attempts: 2000,
        }
    }
}

/// How the geometry around a candidate point looks from it, from one set of probe rays.
struct Surroundings {
    /// Inside a solid: most probes hit the back of a triangle (its winding-and-normal side
    /// faces away from the ray origin).
    inside: bool,
    /// Share of probes that hit anything: 1 in a closed room.
    enclosure: f32,
}

fn surroundings(scene: &Scene, rays: &RayScene, offsets: &[u32], p: Vec3) -> Surroundings {
    let (mut back, mut hits) = (0, 0);
    for d in probes() {
        let Some(hit) = rays.closest_hit(p, d, 0.0, f32::INFINITY) else {
            continue;
        };
        hits += 1;
        if let Some(tri) = scene.triangle_ref(offsets, hit.triangle) {
            let mesh = &scene.meshes[tri.mesh as usize];
            let [a, b, c] = mesh.indices[tri.local as usize].map(|i| i as usize);
            let mut n = (mesh.positions[b] - mesh.positions[a])
                .cross(mesh.positions[c] - mesh.positions[a]);
            // Orient the face normal as the shading normals (they point outwards).
            let shading = mesh.normals.get(a).copied().unwrap_or(Vec3::ZERO)
                + mesh.normals.get(b).copied().unwrap_or(Vec3::ZERO)
                + mesh.normals.get(c).copied().unwrap_or(Vec3::ZERO);
            if n.dot(shading) < 0.0 {
                n = -n;
            }
            if n.dot(d) > 0.0 {
                back += 1;
            }
        }
    }
    Surroundings {
        inside: back * 2 > PROBES,
        enclosure: hits as f32 / PROBES as f32,
    }
}

/// Probe rays per point.
const PROBES: u32 = 26;

/// [`PROBES`] directions evenly spread over the sphere (a Fibonacci sphere).
fn probes() -> impl Iterator<Item = Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5.0f32.sqrt());
    (0..PROBES).map(move |i| {
        let y = 1.0 - 2.0 * (i as f32 + 0.5) / PROBES as f32;
        let r = (1.0 - y * y).max(0.0).sqrt();
        let phi = golden * i as f32;
        Vec3::new(r * phi.cos(), y, r * phi.sin())
    })
}

/// Enclosure a point must have to count as indoors.
const INDOORS: f32 = 0.95;

/// True when `scene` is an interior: of 256 seeded points in its bounds that lie in free
/// space, at least 5 % are enclosed (every probe ray hits something). Open scenes (a ground
/// under the sky, a box open at the front) have none.
fn is_interior(scene: &Scene, rays: &RayScene, offsets: &[u32], lo: Vec3, hi: Vec3) -> bool {
    let mut rng = Rng::new(0x1d00, 0x0e7c);
    let (mut free, mut enclosed) = (0u32, 0u32);
    for _ in 0..256 {
        let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let p = lo + (hi - lo) * u;
        let around = surroundings(scene, rays, offsets, p);
        if around.inside {
            continue;
        }
        free += 1;
        if around.enclosure >= INDOORS {
            enclosed += 1;
        }
    }
    free > 0 && enclosed * 20 >= free
}

/// Share of an 8 x 6 grid of rays through `camera`'s image that hit geometry, the median
/// hit distance and the number of distinct triangles hit.
fn coverage(rays: &RayScene, camera: &Camera) -> (f32, f32, usize) {
    let view = View::from_camera(camera);
    let (mut hits, mut dists, mut tris) = (0u32, Vec::new(), Vec::new());
    for y in 0..6 {
        for x in 0..8 {
            let uv = glam::Vec2::new((x as f32 + 0.5) / 8.0, (y as f32 + 0.5) / 6.0);
            let (o, d) = view.ray(uv);
            if let Some(h) = rays.closest_hit(o, d, 0.0, camera.far) {
                hits += 1;
                dists.push(h.t);
                if !tris.contains(&h.triangle) {
                    tris.push(h.triangle);
                }
            }
        }
    }
    dists.sort_by(f32::total_cmp);
    let median = dists.get(dists.len() / 2).copied().unwrap_or(0.0);
    (hits as f32 / 48.0, median, tris.len())
}

/// `count` seeded random cameras inside `scene`'s bounds: each eye lies in free space (not
/// inside a solid, not closer to a surface than 2 % of the extent; in an interior, such as a
/// building standing on a ground, inside a room: enclosed on every side), looks in a random
/// direction that is not too steep, and sees geometry through at least `min_coverage` of
/// its image, made of at least `min_triangles` triangles. Deterministic for a seed. Fails when the scene is empty or no candidate
/// passes within `max_attempts` tries.
pub fn random_cameras(
    scene: &Scene,
    count: usize,
    settings: &RandomCameraSettings,
) -> Result<Vec<Camera>, HarnessError> {
    let bounds = scene.bounds();
    if bounds.is_empty() || scene.triangle_count() == 0 {
        return Err(HarnessError::Cameras(format!(
            "scene '{}' has no geometry to place random cameras in",
            scene.name
        )));
    }
    let rays = RayScene::build(scene);
    let offsets = scene.mesh_offsets();
    let extent = scene.extent();
    let mut rng = Rng::new(settings.seed, 0x00ca_3e7a);
    let mut out = Vec::with_capacity(count);
    let mut attempts = 0u32;
    // Shrink the box a little so eyes do not sit on the outer walls.
    let lo = bounds.min + (bounds.max - bounds.min) * 0.05;
    let hi = bounds.max - (bounds.max - bounds.min) * 0.05;
    let indoors = is_interior(scene, &rays, &offsets, lo, hi);
    while out.len() < count {
        attempts += 1;
        if attempts > settings.max_attempts * count.max(1) as u32 {
            return Err(HarnessError::Cameras(format!(
                "scene '{}': only {} of {count} random cameras found free space and enough \
                 geometry in view",
                scene.name,
                out.len()
            )));
        }
        let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let p = lo + (hi - lo) * u;
        let d = uniform_sphere(rng.next_vec2());
        if d.y.abs() > 0.6 {
            continue;
        }
        let around = surroundings(scene, &rays, &offsets, p);
        if around.inside || indoors && around.enclosure < INDOORS {
            continue;
        }
        let spec = CameraSpec {
            name: Some(format!("random{}", out.len())),
            position: p.to_array(),
            target: (p + d).to_array(),
            up: default_up(),
            fov: settings.fov,
            near: None,
            far: None,
        };
        let Ok(camera) = spec.to_camera(scene, out.len()) else {
            continue;
        };
        let (cov, median, tris) = coverage(&rays, &camera.with_aspect(4.0 / 3.0));
        if cov >= settings.min_coverage && median > 0.02 * extent && tris >= settings.min_triangles
        {
            out.push(camera);
        }
    }
    Ok(out)
}

/// The first `count` cameras: `given` first, then seeded random ones.
pub fn cameras_for(
    scene: &Scene,
    given: &[Camera],
    count: usize,
    settings: &RandomCameraSettings,
) -> Result<Vec<Camera>, HarnessError> {
    let mut cams: Vec<Camera> = given.iter().take(count).cloned().collect();
    if cams.len() < count {
        cams.extend(random_cameras(scene, count - cams.len(), settings)?);
    }
    Ok(cams)
}
