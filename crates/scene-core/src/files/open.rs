//! Opening a scene by what a user types on a command line: a built-in scene's name
//! ([`crate::builtin::NAMES`]) or the path of a `.gltf`/`.glb` file, imported under the
//! budget that `DIFFUSE_GI_BUDGET` sets ([`Budget::from_env`]).
//! Every composition point (xtask, the viewer) opens scenes through [`open_scene`], so a
//! name means the same scene everywhere.

use std::path::{Path, PathBuf};

#[cfg(feature = "gltf")]
use crate::budget::Budget;
use crate::builtin;
#[cfg(feature = "gltf")]
use crate::gltf_io;
use crate::scene::{DirectionalLight, PointLight, Scene};

/// Why [`open_scene`] could not open a scene: a caller can tell a typo (no such file, an
/// unknown built-in name) from a broken file or a scene the methods cannot take.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The path names a `.gltf`/`.glb` file that does not exist.
    #[error("scene file '{}' does not exist", .0.display())]
    NoSuchFile(PathBuf),
    /// Not a glTF path, and no built-in scene has this name (the error lists them).
    #[error(transparent)]
    UnknownBuiltin(crate::SceneError),
    /// `DIFFUSE_GI_BUDGET` does not parse.
    #[error("{0}")]
    BudgetSetting(String),
    /// The file could not be imported.
    #[cfg(feature = "gltf")]
    #[error(transparent)]
    Import(#[from] crate::GltfError),
    /// This build of scene-core has no glTF support (feature `gltf`).
    #[error(
        "scene file '{0}': opening glTF needs scene-core's `gltf` feature, which this build lacks"
    )]
    NotBuiltIn(String),
    /// A light added on the command line ([`AddedLights`]) is invalid (the error names it).
    #[error("{spec}: added light: {source}")]
    AddedLight {
        /// What was opened.
        spec: String,
        /// What validation said of the added light.
        source: crate::SceneError,
    },
    /// The scene breaks the contract every method holds ([`crate::contract::check`]).
    #[error("{spec}: {source}")]
    Contract {
        /// What was opened.
        spec: String,
        /// The contract's verdict.
        source: crate::SceneError,
    },
}

/// A scene opened by [`open_scene`], with what the import ignored or warned about.
#[derive(Debug)]
pub struct OpenedScene {
    /// The scene.
    pub scene: Scene,
    /// One line per import note (the import summary, then each warning), then what the
    /// scene contract noted ([`crate::contract::check`]: no light, a recentring); empty for
    /// a built-in scene that needs no note.
    pub notes: Vec<String>,
    /// The translation applied to the file's coordinates ([`Scene::recentred`]): zero unless
    /// its geometry lay farther from the origin than its extent. Cameras given in the file's
    /// coordinates elsewhere (camera lists) must be moved by it too.
    pub translation: glam::Vec3,
}

impl OpenedScene {
    /// Checks the scene contract ([`crate::contract::check`]: refuses a scene without
    /// geometry or beyond f32's precision), then moves the scene to the origin when it lies
    /// farther from it than its extent, noting both.
    fn checked(mut self, spec: &str) -> Result<Self, OpenError> {
        let contract =
            crate::contract::check(&self.scene).map_err(|source| OpenError::Contract {
                spec: spec.to_string(),
                source,
            })?;
        self.notes
            .extend(contract.notes.into_iter().map(|n| format!("note: {n}")));
        let (scene, t) = self.scene.recentred();
        self.scene = scene;
        self.translation = t;
        if t != glam::Vec3::ZERO {
            self.notes.push(format!(
                "note: {}: moved by ({}, {}, {}) to the origin (cameras, lights and outputs \
                 are in the moved coordinates)",
                self.scene.name, t.x, t.y, t.z
            ));
        }
        Ok(self)
    }
}

/// Lights a user adds to a scene as it is opened, so that a file without lights renders in
/// one command (`--sun DIR=RGB`, `--point POS=RGB`, `--sky RGB|FILE.exr` on the command
/// lines). They are added in
/// the file's coordinates before the scene contract is checked, so a scene moved to the
/// origin moves them with it, and named `sun N` and `point N` (from 1) in
/// [`crate::lights::light_ids`] order after the file's own.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AddedLights {
    /// Directional lights.
    pub suns: Vec<DirectionalLight>,
    /// Point lights.
    pub points: Vec<PointLight>,
    /// A sky (it replaces the scene's own, if it has one).
    pub sky: Option<crate::sky::Sky>,
}

impl AddedLights {
    /// True when nothing is added.
    pub fn is_empty(&self) -> bool {
        self.suns.is_empty() && self.points.is_empty() && self.sky.is_none()
    }

    /// Parses `R,G,B` (or one number, grey): a uniform sky of that radiance over the upper
    /// hemisphere ([`crate::sky::Sky::uniform`]); or `FILE.exr`: an equirectangular
    /// environment map read within the default [`crate::Budget`]
    /// ([`crate::sky::Sky::from_image`]). The error names the flag, the file or the number.
    pub fn parse_sky(&mut self, spec: &str) -> Result<(), String> {
        let sky = if spec.to_ascii_lowercase().ends_with(".exr") {
            read_sky_map(spec)?
        } else {
            let bad = |why: &str| format!("--sky {spec}: {why} (expected R,G,B or FILE.exr)");
            crate::sky::Sky::uniform(parse_rgb(spec, &bad)?)
        };
        self.sky = Some(sky.map_err(|e| format!("--sky {spec}: {e}"))?);
        Ok(())
    }

    /// Parses `DX,DY,DZ=R,G,B`: a sun travelling along `(DX, DY, DZ)` (normalised; `0,-1,0`
    /// shines straight down) giving irradiance `(R, G, B)` on a surface facing it. A single
    /// number for the colour is grey.
    pub fn parse_sun(&mut self, spec: &str) -> Result<(), String> {
        let (d, rgb) = parse_pair(spec, "--sun", "DX,DY,DZ=R,G,B")?;
        let direction = d
            .try_normalize()
            .ok_or_else(|| format!("--sun {spec}: the direction is zero or not finite"))?;
        self.suns.push(DirectionalLight {
            name: format!("sun {}", self.suns.len() + 1),
            direction,
            irradiance: rgb,
        });
        Ok(())
    }

    /// Parses `X,Y,Z=R,G,B`: a point light at `(X, Y, Z)` (the file's coordinates) of
    /// intensity `(R, G, B)` (W/sr, inverse-square falloff). A single number for the colour
    /// is grey.
    pub fn parse_point(&mut self, spec: &str) -> Result<(), String> {
        let (position, rgb) = parse_pair(spec, "--point", "X,Y,Z=R,G,B")?;
        self.points.push(PointLight::new(
            &format!("point {}", self.points.len() + 1),
            position,
            rgb,
        ));
        Ok(())
    }

    /// Sets how many directional lights the added sky becomes for the methods that do not
    /// integrate it (`--sky-directions N`, 1 to [`crate::sky::MAX_DIRECTIONS`]); an error
    /// without a sky or out of range, naming the flag.
    pub fn set_sky_directions(&mut self, n: u32) -> Result<(), String> {
        let sky = self
            .sky
            .as_ref()
            .ok_or_else(|| format!("--sky-directions {n}: there is no --sky to apply it to"))?;
        self.sky = Some(
            sky.with_directions(n)
                .map_err(|e| format!("--sky-directions {n}: {e}"))?,
        );
        Ok(())
    }

    /// Adds the lights to `scene` and checks them with the scene's own validation.
    fn add_to(&self, scene: &mut Scene) -> Result<Vec<String>, crate::SceneError> {
        scene.directional_lights.extend(self.suns.iter().cloned());
        scene.point_lights.extend(self.points.iter().cloned());
        let replaced = self.sky.is_some() && scene.sky.is_some();
        if let Some(sky) = &self.sky {
            scene.sky = Some(sky.clone());
        }
        scene.validate()?;
        let mut notes: Vec<String> = self
            .suns
            .iter()
            .map(|l| {
                let (d, e) = (l.direction, l.irradiance);
                format!(
                    "note: added '{}' travelling ({}, {}, {}), irradiance ({}, {}, {})",
                    l.name, d.x, d.y, d.z, e.x, e.y, e.z
                )
            })
            .collect();
        notes.extend(self.points.iter().map(|l| {
            let (p, i) = (l.position, l.intensity);
            format!(
                "note: added '{}' at ({}, {}, {}), intensity ({}, {}, {})",
                l.name, p.x, p.y, p.z, i.x, i.y, i.z
            )
        }));
        if let Some(sky) = &self.sky {
            let (w, h) = sky.size();
            let e = sky.irradiance(glam::Vec3::Y);
            notes.push(format!(
                "note: added sky '{}' ({w}x{h} map{}, as {} directions where a method does \
                 not integrate it): an open floor receives ({}, {}, {})",
                sky.name,
                if replaced {
                    ", replacing the scene's"
                } else {
                    ""
                },
                sky.lights().len(),
                e.x,
                e.y,
                e.z
            ));
        }
        Ok(notes)
    }
}

/// An equirectangular EXR as a sky (the error names the flag and the file).
#[cfg(feature = "exr")]
fn read_sky_map(spec: &str) -> Result<Result<crate::sky::Sky, crate::SceneError>, String> {
    let path = Path::new(spec);
    let image = crate::image::Image::read_exr_with(path, &crate::Budget::default())
        .map_err(|e| format!("--sky {spec}: {e}"))?;
    let name = path
        .file_name()
        .map_or_else(|| spec.to_string(), |n| n.to_string_lossy().into_owned());
    Ok(crate::sky::Sky::from_image(&name, &image))
}

/// Without the `exr` feature a sky map can only be refused, by name.
#[cfg(not(feature = "exr"))]
fn read_sky_map(spec: &str) -> Result<Result<crate::sky::Sky, crate::SceneError>, String> {
    Err(format!(
        "--sky {spec}: this build reads no EXR (scene-core's `exr` feature is off)"
    ))
}

/// `A,B,C=R,G,B` (or `=V` for grey) as two vectors, every number finite; the error names
/// the flag and the form it expects.
fn parse_pair(spec: &str, flag: &str, form: &str) -> Result<(glam::Vec3, glam::Vec3), String> {
    let bad = |why: &str| format!("{flag} {spec}: {why} (expected {form})");
    let (a, b) = spec.split_once('=').ok_or_else(|| bad("no '='"))?;
    let [x, y, z] = parse_numbers(a, &bad)?[..] else {
        return Err(bad("three numbers before '='"));
    };
    Ok((glam::Vec3::new(x, y, z), parse_rgb(b, &bad)?))
}

/// `R,G,B` or one number (grey), finite and not negative; `bad` words the error.
fn parse_rgb(s: &str, bad: &dyn Fn(&str) -> String) -> Result<glam::Vec3, String> {
    let rgb = match parse_numbers(s, bad)?[..] {
        [v] => glam::Vec3::splat(v),
        [r, g, b] => glam::Vec3::new(r, g, b),
        _ => return Err(bad("one or three numbers for the colour")),
    };
    if rgb.min_element() < 0.0 {
        return Err(bad("a negative colour"));
    }
    Ok(rgb)
}

/// Comma-separated finite numbers; `bad` words the error.
fn parse_numbers(s: &str, bad: &dyn Fn(&str) -> String) -> Result<Vec<f32>, String> {
    s.split(',')
        .map(|x| {
            let v: f32 = x
                .trim()
                .parse()
                .map_err(|_| bad(&format!("'{x}' is not a number")))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(bad(&format!("'{x}' is not finite")))
            }
        })
        .collect()
}

/// True when `spec` names a glTF file (by its extension) rather than a built-in scene.
pub fn is_gltf_path(spec: &str) -> bool {
    let lower = spec.to_ascii_lowercase();
    lower.ends_with(".gltf") || lower.ends_with(".glb")
}

/// Opens a built-in scene by name, or a glTF file when `spec` ends in `.gltf`/`.glb`. The
/// error names the fault: a file that does not exist, an import error, or an unknown
/// built-in name with the list of known ones, or a scene that breaks the contract
/// ([`crate::contract::check`]). A scene far from the origin is moved to it
/// ([`OpenedScene::translation`]).
pub fn open_scene(spec: &str) -> Result<OpenedScene, OpenError> {
    open_scene_with(spec, &AddedLights::default())
}

/// [`open_scene`] with `added` lights put into the scene (in the file's coordinates, before
/// the contract's check and the move to the origin), each noted; an invalid one is an
/// [`OpenError::AddedLight`] naming it.
pub fn open_scene_with(spec: &str, added: &AddedLights) -> Result<OpenedScene, OpenError> {
    let mut opened = if is_gltf_path(spec) {
        if !Path::new(spec).exists() {
            return Err(OpenError::NoSuchFile(PathBuf::from(spec)));
        }
        open_gltf(spec)?
    } else {
        let scene = builtin::scene(spec).map_err(OpenError::UnknownBuiltin)?;
        OpenedScene {
            scene,
            notes: Vec::new(),
            translation: glam::Vec3::ZERO,
        }
    };
    if !added.is_empty() {
        let notes = added
            .add_to(&mut opened.scene)
            .map_err(|source| OpenError::AddedLight {
                spec: spec.to_string(),
                source,
            })?;
        opened.notes.extend(notes);
    }
    opened.checked(spec)
}

/// Without the `gltf` feature a file can only be refused, by name.
#[cfg(not(feature = "gltf"))]
fn open_gltf(spec: &str) -> Result<OpenedScene, OpenError> {
    Err(OpenError::NotBuiltIn(spec.to_string()))
}

/// Imports `spec` under the environment's budget (the caller checks the contract).
#[cfg(feature = "gltf")]
fn open_gltf(spec: &str) -> Result<OpenedScene, OpenError> {
    let options = gltf_io::ImportOptions {
        budget: Budget::from_env().map_err(OpenError::BudgetSetting)?,
        ..Default::default()
    };
    let imported = gltf_io::import_with(Path::new(spec), &options)?;
    let mut notes = Vec::new();
    let summary = imported.summary();
    if !summary.is_empty() {
        notes.push(summary);
    }
    notes.extend(imported.warnings.iter().map(|w| format!("warning: {w}")));
    Ok(OpenedScene {
        scene: imported.scene,
        notes,
        translation: glam::Vec3::ZERO,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_paths_open_or_say_why_not() {
        let cornell = open_scene("cornell").unwrap();
        assert_eq!(cornell.scene.name, "cornell");
        assert!(cornell.notes.is_empty());
        let e = open_scene("no-such-scene").unwrap_err();
        assert!(matches!(e, OpenError::UnknownBuiltin(_)), "{e}");
        assert!(e.to_string().contains("no-such-scene"), "{e}");
        let e = open_scene("/nonexistent/scene.GLB").unwrap_err();
        assert!(matches!(&e, OpenError::NoSuchFile(p) if p == Path::new("/nonexistent/scene.GLB")));
        assert_eq!(
            e.to_string(),
            "scene file '/nonexistent/scene.GLB' does not exist"
        );
        assert!(is_gltf_path("a.gltf") && is_gltf_path("B.Glb") && !is_gltf_path("cornell"));
    }

    #[test]
    fn added_lights_parse_check_and_follow_the_scene() {
        let mut added = AddedLights::default();
        added.parse_sun("0,-2,0=3").unwrap();
        added.parse_point("0.5, 1.5, 0.5=1,2,3").unwrap();
        assert_eq!(added.suns[0].direction, glam::Vec3::NEG_Y);
        assert_eq!(added.suns[0].irradiance, glam::Vec3::splat(3.0));
        assert_eq!(added.points[0].intensity, glam::Vec3::new(1.0, 2.0, 3.0));
        let base = open_scene("cornell").unwrap().scene;
        let opened = open_scene_with("cornell", &added).unwrap();
        assert_eq!(
            opened.scene.directional_lights.len(),
            base.directional_lights.len() + 1
        );
        assert_eq!(opened.scene.point_lights.len(), base.point_lights.len() + 1);
        assert_eq!(opened.scene.point_lights.last().unwrap().name, "point 1");
        assert!(
            opened.notes.iter().any(|n| n.contains("added 'sun 1'")),
            "{:?}",
            opened.notes
        );
        // Malformed specs name the flag and the form.
        let mut a = AddedLights::default();
        for (spec, why) in [
            ("0,0,0=1", "zero"),
            ("1,2=1", "three numbers"),
            ("0,-1,0", "no '='"),
            ("0,-1,0=1,2", "one or three"),
            ("0,-1,0=-1", "negative"),
            ("0,nan,0=1", "not finite"),
            ("0,x,0=1", "not a number"),
        ] {
            let e = a.parse_sun(spec).unwrap_err();
            assert!(e.contains("--sun") && e.contains(why), "{spec}: {e}");
        }
        // Beyond the radiometric range: the scene's validation names the added light.
        let mut huge = AddedLights::default();
        huge.parse_point("0,1,0=1e30").unwrap();
        let e = open_scene_with("cornell", &huge).unwrap_err();
        assert!(matches!(e, OpenError::AddedLight { .. }), "{e}");
        assert!(e.to_string().contains("point 1"), "{e}");
    }

    #[cfg(feature = "gltf")]
    #[test]
    fn added_lights_move_with_a_recentred_file() {
        let offset = glam::Vec3::new(100.0, 0.0, -200.0);
        let mut far = builtin::scene("cornell").unwrap();
        for m in &mut far.meshes {
            m.positions.iter_mut().for_each(|p| *p += offset);
        }
        far.point_lights.clear();
        far.cameras.clear();
        let dir = std::env::temp_dir().join(format!("added-lights-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("far.glb");
        crate::gltf_io::export(&far, &path).unwrap();
        let spec = path.to_str().unwrap();
        // The added point light is where the user put it in the file's coordinates, moved
        // with the scene.
        let plain = open_scene(spec).unwrap();
        let mut added = AddedLights::default();
        let at = offset + glam::Vec3::new(0.5, 0.9, 0.5);
        added
            .parse_point(&format!("{},{},{}=2", at.x, at.y, at.z))
            .unwrap();
        let opened = open_scene_with(spec, &added).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        assert_ne!(opened.translation, glam::Vec3::ZERO);
        let p = opened.scene.point_lights[0].position;
        assert!(
            (p - (at + opened.translation)).length() < 1e-2,
            "{p} {}",
            opened.translation
        );
        assert_eq!(opened.translation, plain.translation);
    }
}
