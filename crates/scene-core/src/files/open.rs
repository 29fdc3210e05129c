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
use crate::scene::Scene;

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
    if is_gltf_path(spec) {
        if !Path::new(spec).exists() {
            return Err(OpenError::NoSuchFile(PathBuf::from(spec)));
        }
        open_gltf(spec)
    } else {
        let scene = builtin::scene(spec).map_err(OpenError::UnknownBuiltin)?;
        OpenedScene {
            scene,
            notes: Vec::new(),
            translation: glam::Vec3::ZERO,
        }
        .checked(spec)
    }
}

/// Without the `gltf` feature a file can only be refused, by name.
#[cfg(not(feature = "gltf"))]
fn open_gltf(spec: &str) -> Result<OpenedScene, OpenError> {
    Err(OpenError::NotBuiltIn(spec.to_string()))
}

/// Imports `spec` under the environment's budget and checks the contract.
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
    OpenedScene {
        scene: imported.scene,
        notes,
        translation: glam::Vec3::ZERO,
    }
    .checked(spec)
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
}
