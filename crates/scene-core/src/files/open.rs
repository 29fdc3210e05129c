//! Opening a scene by what a user types on a command line: a built-in scene's name
//! ([`crate::builtin::NAMES`]) or the path of a `.gltf`/`.glb` file, imported under the
//! budget that `DIFFUSE_GI_BUDGET` sets ([`Budget::from_env`]).
//! Every composition point (xtask, the viewer) opens scenes through [`open_scene`], so a
//! name means the same scene everywhere.

use std::path::Path;

use crate::budget::Budget;
use crate::builtin;
use crate::gltf_io;
use crate::scene::Scene;

/// A scene opened by [`open_scene`], with what the import ignored or warned about.
#[derive(Debug)]
pub struct OpenedScene {
    /// The scene.
    pub scene: Scene,
    /// One line per import note (the import summary, then each warning); empty for a
    /// built-in scene.
    pub notes: Vec<String>,
}

/// True when `spec` names a glTF file (by its extension) rather than a built-in scene.
pub fn is_gltf_path(spec: &str) -> bool {
    let lower = spec.to_ascii_lowercase();
    lower.ends_with(".gltf") || lower.ends_with(".glb")
}

/// Opens a built-in scene by name, or a glTF file when `spec` ends in `.gltf`/`.glb`. The
/// error names the fault: a file that does not exist, an import error, or an unknown
/// built-in name with the list of known ones.
pub fn open_scene(spec: &str) -> Result<OpenedScene, String> {
    if is_gltf_path(spec) {
        if !Path::new(spec).exists() {
            return Err(format!("scene file '{spec}' does not exist"));
        }
        let options = gltf_io::ImportOptions {
            budget: Budget::from_env()?,
            ..Default::default()
        };
        let imported =
            gltf_io::import_with(Path::new(spec), &options).map_err(|e| e.to_string())?;
        let mut notes = Vec::new();
        let summary = imported.summary();
        if !summary.is_empty() {
            notes.push(summary);
        }
        notes.extend(imported.warnings.iter().map(|w| format!("warning: {w}")));
        Ok(OpenedScene {
            scene: imported.scene,
            notes,
        })
    } else {
        let scene = builtin::scene(spec).map_err(|e| e.to_string())?;
        Ok(OpenedScene {
            scene,
            notes: Vec::new(),
        })
    }
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
        assert!(e.contains("no-such-scene"), "{e}");
        let e = open_scene("/nonexistent/scene.GLB").unwrap_err();
        assert_eq!(e, "scene file '/nonexistent/scene.GLB' does not exist");
        assert!(is_gltf_path("a.gltf") && is_gltf_path("B.Glb") && !is_gltf_path("cornell"));
    }
}
