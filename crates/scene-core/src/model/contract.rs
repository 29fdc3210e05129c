//! The scene contract: what every method (DL, ISR, relighting, the IBRR, the reference path
//! tracer) needs of a scene before it starts work, checked once and the same way everywhere.
//!
//! [`Scene::validate`] checks each item on its own (finite data, albedo and radiometric
//! ranges, cameras); [`check`] adds what only the scene as a whole can say:
//!
//! | case | outcome |
//! |---|---|
//! | no triangle (none given, or every one dropped as degenerate) | refused: [`SceneError::NoGeometry`] |
//! | no light (no point or directional light with power, no sky, no emissive triangle that its alpha mask leaves) | legal: a black image; [`Contract::notes`] says why |
//! | every triangle cut away by its alpha mask | legal: a black image; [`Contract::notes`] says why |
//! | coordinates so far from the origin that f32 spaces them more than [`PRECISION_LIMIT`] of the extent apart | refused: [`SceneError::PrecisionLost`] (the file's own f32 positions have already lost it) |
//! | geometry off the origin by more than its extent, within the limit | [`Scene::recentred`] moves it (every position, light and camera) to the origin; [`crate::open_scene`] does this with a note |
//!
//! Every technique calls [`check`] in `prepare`, and every command opens scenes through
//! [`crate::open_scene`], which calls it too, so a scene is refused before any work.

use glam::Vec3;

use crate::error::SceneError;
use crate::scene::{Bounds, Scene};

/// The finest coordinate spacing a scene's geometry may have, as a fraction of its extent:
/// the f32 spacing at the largest coordinate, `|x| * 2^-23`, must not exceed this. At the
/// limit a 10 m room lies about 8 km from the origin and its vertices are placed to 1 mm.
pub const PRECISION_LIMIT: f32 = 1e-4;

/// What [`check`] found about a scene that it accepts.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Contract {
    /// True when some light gives power (a point or directional light, or an emissive
    /// triangle): without one every method renders black.
    pub lit: bool,
    /// One line per thing a user should know (no light; geometry far from the origin).
    pub notes: Vec<String>,
}

/// The f32 spacing of coordinates of magnitude `x`.
fn spacing(x: f32) -> f32 {
    x.abs() * f32::EPSILON
}

/// Checks the scene contract (table in the module doc). `scene` should already be
/// validated ([`Scene::validate`]); the outcome is the same for any thread count.
pub fn check(scene: &Scene) -> Result<Contract, SceneError> {
    let mut contract = Contract::default();
    if scene.triangle_count() == 0 {
        let reason = if scene.meshes.iter().any(|m| !m.positions.is_empty()) {
            "vertices but no triangle (degenerate triangles are dropped by validation)"
        } else {
            "no triangle"
        };
        return Err(SceneError::NoGeometry {
            scene: scene.name.clone(),
            reason: reason.into(),
        });
    }
    let bounds = triangle_bounds(scene);
    let (offset, extent) = offset_and_extent(&bounds);
    if extent <= 0.0 || !extent.is_finite() {
        return Err(SceneError::NoGeometry {
            scene: scene.name.clone(),
            reason: format!("its triangles span {extent} (no area)"),
        });
    }
    let largest = bounds.min.abs().max(bounds.max.abs()).max_element();
    if spacing(largest) > PRECISION_LIMIT * extent {
        return Err(SceneError::PrecisionLost {
            scene: scene.name.clone(),
            offset,
            extent,
        });
    }
    if offset > extent {
        contract.notes.push(format!(
            "{}: geometry lies {offset:.4e} from the origin, {:.0} times its extent; \
             Scene::recentred moves it to the origin",
            scene.name,
            offset / extent
        ));
    }
    if masked_away(scene) {
        contract.notes.push(format!(
            "{}: every triangle is cut away by its alpha mask (no sample of any triangle \
             reaches its material's alphaCutoff): every method renders nothing but black",
            scene.name
        ));
    }
    contract.lit = is_lit(scene);
    if !contract.lit {
        contract.notes.push(format!(
            "{}: the scene has no light (no point or directional light with power, no sky, no \
             emissive triangle): every method renders it black",
            scene.name
        ));
    }
    Ok(contract)
}

/// Samples per side of a triangle's subdivision when the contract asks whether an alpha
/// mask leaves anything of it ([`crate::cutout::coverage`]: 64 samples).
const MASK_SAMPLES: u32 = 8;

/// True when something of global triangle `t` exists under its alpha mask (always for an
/// unmasked triangle).
fn exists(cutouts: &crate::cutout::Cutouts, t: u32) -> bool {
    !cutouts.is_masked(t) || crate::cutout::coverage(MASK_SAMPLES, |b| cutouts.opaque(t, b)) > 0.0
}

/// True when the scene has triangles and every one is cut away by its alpha mask.
fn masked_away(scene: &Scene) -> bool {
    let cutouts = crate::cutout::Cutouts::of(scene);
    let n = scene.triangle_count() as u32;
    cutouts.masked_triangles() as u32 == n && n > 0 && !(0..n).any(|t| exists(&cutouts, t))
}

/// True when some light of the scene gives power (an emissive triangle counts when its
/// alpha mask leaves some of it).
pub fn is_lit(scene: &Scene) -> bool {
    let cutouts = crate::cutout::Cutouts::of(scene);
    let mut global = 0u32;
    let emissive_triangle = scene.meshes.iter().any(|m| {
        m.material_ids.iter().any(|&id| {
            global += 1;
            scene
                .materials
                .get(id as usize)
                .is_some_and(|mat| mat.emission.max_element() > 0.0)
                && exists(&cutouts, global - 1)
        })
    });
    emissive_triangle
        || scene
            .point_lights
            .iter()
            .any(|l| l.intensity.max_element() > 0.0)
        || scene
            .directional_lights
            .iter()
            .any(|l| l.irradiance.max_element() > 0.0)
        || scene.sky.as_ref().is_some_and(|s| !s.is_black())
}

/// Bounds of the vertices that triangles use (a stray unused vertex far away does not
/// count).
fn triangle_bounds(scene: &Scene) -> Bounds {
    let mut b = Bounds::EMPTY;
    for m in &scene.meshes {
        for t in &m.indices {
            for &i in t {
                if let Some(&p) = m.positions.get(i as usize) {
                    b.grow(p);
                }
            }
        }
    }
    b
}

/// The distance of the bounds' centre from the origin and the bounds' diagonal, in f64 and
/// rounded once.
fn offset_and_extent(b: &Bounds) -> (f32, f32) {
    let (min, max) = (b.min.as_dvec3(), b.max.as_dvec3());
    (
        ((min + max) * 0.5).length() as f32,
        (max - min).length() as f32,
    )
}

impl Scene {
    /// The translation [`Scene::recentred`] would apply: minus the centre of the bounds of
    /// the triangles' vertices, or zero when that centre lies within the extent of the
    /// origin (or the scene has no triangle).
    pub fn recentring(&self) -> Vec3 {
        if self.triangle_count() == 0 {
            return Vec3::ZERO;
        }
        let b = triangle_bounds(self);
        let (offset, extent) = offset_and_extent(&b);
        if offset > extent && offset.is_finite() {
            -((b.min.as_dvec3() + b.max.as_dvec3()) * 0.5).as_vec3()
        } else {
            Vec3::ZERO
        }
    }

    /// The scene moved by `t`: every vertex, point light and camera (position and target).
    /// Directions, intensities and materials are unchanged, so every method renders the
    /// same picture of it from the moved cameras. Each sum is taken in f64 and rounded once.
    pub fn translated(mut self, t: Vec3) -> Scene {
        let t = t.as_dvec3();
        let add = |p: &mut Vec3| *p = (p.as_dvec3() + t).as_vec3();
        for m in &mut self.meshes {
            m.positions.iter_mut().for_each(add);
        }
        for c in &mut self.cameras {
            add(&mut c.position);
            add(&mut c.target);
        }
        for l in &mut self.point_lights {
            add(&mut l.position);
        }
        self
    }

    /// The scene moved to the origin when its geometry lies farther from it than its extent
    /// ([`Scene::recentring`]), with the translation applied (zero when none was needed).
    /// Moving a scene near the origin gives f32 its full precision for the ray offsets,
    /// depth buffers and view matrices of every method.
    pub fn recentred(self) -> (Scene, Vec3) {
        let t = self.recentring();
        if t == Vec3::ZERO {
            (self, t)
        } else {
            (self.translated(t), t)
        }
    }
}
