//! Walkthrough files: `--record FILE.json` writes one, `--replay FILE.json` plays one back,
//! one step per frame.
//!
//! A file is `{"version": 1, "steps": [...]}`; each step may set the camera (a scene camera
//! by index, or a position and a point looked at), the mode, the layout, light settings
//! (by id as `point:N`, `directional:N` or `emissive:N`), ask for an IBRR rebuild, wait for
//! the reference to reach a number of samples per pixel, and save a screenshot:
//!
//! ```json
//! {"version": 1, "steps": [
//!   {"scene_camera": 0, "mode": "isr", "screenshot": "isr"},
//!   {"lights": [{"light": "point:0", "color": [1.0, 0.3, 0.3]}], "mode": "relight"},
//!   {"camera": {"position": [0, 1, 3], "target": [0, 1, 0]}, "mode": "reference",
//!    "reference_spp": 16, "screenshot": "truth"}
//! ]}
//! ```
//!
//! Unknown fields, modes, layouts and light ids are errors that name the step, so a typo
//! never replays silently as something else. A replay waits for every precomputation it
//! needs (relighting's solve, the IBRR's construction), so its frames are those of the
//! library whatever the machine's speed.

use std::path::Path;

use glam::Vec3;
use scene_core::{LightId, LightSetting, LightState, Scene};
use serde::{Deserialize, Serialize};

use crate::mode::Mode;

/// The file format's version.
pub const VERSION: u32 = 1;

/// The largest replay file read: 64 MiB (a recorded hour at 60 frames a second is about
/// 40 MiB).
pub const MAX_SCRIPT_BYTES: u64 = 64 << 20;

/// A walkthrough.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Script {
    /// Always [`VERSION`].
    pub version: u32,
    /// One step per frame.
    #[serde(default)]
    pub steps: Vec<Step>,
}

/// A camera placed by position and a point looked at.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// Eye position.
    pub position: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
}

/// A change of one light's setting; fields left out keep their value.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightChange {
    /// The light: `point:N`, `directional:N` or `emissive:N`.
    pub light: String,
    /// On or off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub enabled: Option<bool>,
    /// Multiplier of the light's emission per channel (colour times intensity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<[f32; 3]>,
    /// Multiplier of its direct light.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direct: Option<f32>,
    /// Multiplier of its indirect light.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indirect: Option<f32>,
}

/// One frame of a walkthrough.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Step {
    /// Jump to the scene's camera of this index.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene_camera: Option<usize>,
    /// Place the camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<Pose>,
    /// The mode (left of a split, or the one whose error is shown).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mode: Option<String>,
    /// `single`, `split` or `error`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layout: Option<String>,
    /// The mode right of a split.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub right: Option<String>,
    /// The split's divider, a fraction of the width.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub divider: Option<f32>,
    /// Light changes.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<LightChange>,
    /// Rebuild the IBRR for the current lights (and wait for it).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub rebuild_ibrr: bool,
    /// Wait until the reference holds exactly this many samples per pixel of this view.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_spp: Option<u32>,
    /// Take this step's frame without waiting for the precomputations of the modes on
    /// screen (a replay otherwise waits, so that its frames show finished methods): a
    /// method still precomputing shows direct light, as it does to a user.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub no_wait: bool,
    /// Save the frame as `NAME.exr`, `NAME.png` and `NAME.json` in the screenshot folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub screenshot: Option<String>,
    /// The frame's duration when recorded, in seconds (informational).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt: Option<f32>,
}

/// A step checked against a scene: names resolved, numbers finite.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CheckedStep {
    /// Jump to this scene camera.
    pub scene_camera: Option<usize>,
    /// Place the camera.
    pub camera: Option<(Vec3, Vec3)>,
    /// The mode.
    pub mode: Option<Mode>,
    /// The layout's name.
    pub layout: Option<String>,
    /// The right mode of a split.
    pub right: Option<Mode>,
    /// The divider.
    pub divider: Option<f32>,
    /// Light changes, resolved.
    pub lights: Vec<(LightId, LightChange)>,
    /// Rebuild the IBRR.
    pub rebuild_ibrr: bool,
    /// Reference samples per pixel to wait for.
    pub reference_spp: Option<u32>,
    /// Do not wait for precomputations.
    pub no_wait: bool,
    /// Screenshot name.
    pub screenshot: Option<String>,
}

impl LightChange {
    /// `setting` with this change applied.
    pub fn apply(&self, setting: LightSetting) -> LightSetting {
        LightSetting {
            enabled: self.enabled.unwrap_or(setting.enabled),
            color: self.color.map_or(setting.color, Vec3::from),
            direct: self.direct.unwrap_or(setting.direct),
            indirect: self.indirect.unwrap_or(setting.indirect),
        }
    }
}

/// Applies resolved light changes to `state`.
pub fn apply_lights(state: &mut LightState, changes: &[(LightId, LightChange)]) {
    for (id, change) in changes {
        let s = change.apply(state.get(*id));
        state.set(*id, s);
    }
}

impl Script {
    /// Reads and parses a file; the error names the file and the fault. Only a regular
    /// file of at most [`MAX_SCRIPT_BYTES`] is read (a FIFO or a device such as /dev/zero
    /// is refused at once, before it is opened for reading).
    pub fn read(path: &Path) -> Result<Script, String> {
        let budget = scene_core::Budget {
            file_bytes: MAX_SCRIPT_BYTES,
            ..Default::default()
        };
        let bytes = scene_core::budget::read_file(path, &budget)
            .map_err(|e| format!("replay file '{}': {e}", path.display()))?;
        serde_json::from_slice(&bytes).map_err(|e| format!("replay file '{}': {e}", path.display()))
    }

    /// Writes the file (through a temporary file renamed into place, so a reader never
    /// sees half of it).
    pub fn write(&self, path: &Path) -> Result<(), String> {
        let text = serde_json::to_string_pretty(self).map_err(|e| e.to_string())?;
        let tmp = path.with_extension("json.tmp");
        std::fs::write(&tmp, text)
            .and_then(|_| std::fs::rename(&tmp, path))
            .map_err(|e| format!("cannot write '{}': {e}", path.display()))
    }

    /// Checks every step against `scene`; the error names the step (from 0) and its fault.
    pub fn check(&self, scene: &Scene) -> Result<Vec<CheckedStep>, String> {
        if self.version != VERSION {
            return Err(format!(
                "replay version {} is not supported (this viewer reads version {VERSION})",
                self.version
            ));
        }
        // Each step's light changes build on the state before it: the running state is
        // checked too, so that multipliers set in separate steps cannot multiply past what
        // a method can sum.
        let mut lights = LightState::default();
        self.steps
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let checked = s
                    .check(scene)
                    .map_err(|e| format!("replay step {i}: {e}"))?;
                apply_lights(&mut lights, &checked.lights);
                lights
                    .check(scene)
                    .map_err(|e| format!("replay step {i}: with the steps before it, {e}"))?;
                Ok(checked)
            })
            .collect()
    }
}

fn finite3(what: &str, v: [f32; 3]) -> Result<Vec3, String> {
    let v = Vec3::from(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{what} {v} is not finite"))
    }
}

/// The coarsest f32 spacing at a replay camera's position or target, as a fraction of the
/// scene's extent (a 10 m room allows a camera up to about 800 km away).
const CAMERA_PRECISION: f32 = 1e-2;

impl Step {
    /// This step checked against `scene`.
    pub fn check(&self, scene: &Scene) -> Result<CheckedStep, String> {
        if let Some(i) = self.scene_camera
            && i >= scene.cameras.len()
        {
            return Err(format!(
                "scene camera {i} does not exist (scene '{}' has {})",
                scene.name,
                scene.cameras.len()
            ));
        }
        let camera = match self.camera {
            Some(p) => {
                let position = finite3("camera position", p.position)?;
                let target = finite3("camera target", p.target)?;
                if (target - position).length() <= 0.0 {
                    return Err("camera target equals its position".into());
                }
                // f32 must place the camera to a hundredth of the scene's extent, or every
                // method's view of the scene breaks down (found here, before the window
                // opens, naming the step).
                let extent = scene.extent();
                let limit = CAMERA_PRECISION * extent;
                for (what, v) in [("camera position", position), ("camera target", target)] {
                    let spacing = v.abs().max_element() * f32::EPSILON;
                    if spacing.is_nan() || spacing > limit {
                        return Err(format!(
                            "{what} {v} lies so far from the origin that f32 places it only \
                             to {spacing:e}, coarser than {CAMERA_PRECISION} of the scene's \
                             extent {extent:e}"
                        ));
                    }
                }
                Some((position, target))
            }
            None => None,
        };
        let mode = self.mode.as_deref().map(Mode::parse).transpose()?;
        let right = self.right.as_deref().map(Mode::parse).transpose()?;
        if let Some(l) = &self.layout
            && !["single", "split", "error"].contains(&l.as_str())
        {
            return Err(format!(
                "unknown layout '{l}' (known: single, split, error)"
            ));
        }
        if let Some(d) = self.divider
            && !(0.0..=1.0).contains(&d)
        {
            return Err(format!("divider {d} is outside [0, 1]"));
        }
        let mut lights = Vec::new();
        for change in &self.lights {
            let id = LightId::find(scene, &change.light).map_err(|e| e.to_string())?;
            let s = change.apply(LightSetting::default());
            let mut probe = LightState::default();
            probe.set(id, s);
            probe.check(scene).map_err(|e| e.to_string())?;
            lights.push((id, change.clone()));
        }
        if let Some(name) = &self.screenshot {
            let ok = !name.is_empty()
                && name.len() <= 100
                && !name.starts_with('.')
                && name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
            if !ok {
                return Err(format!(
                    "screenshot name '{name}' must be 1 to 100 letters, digits, '-', '_' or '.' \
                     (not starting with '.')"
                ));
            }
        }
        scene_core::range::check_opt("reference_spp", self.reference_spp, scene_core::range::SPP)
            .map_err(|e| e.to_string())?;
        Ok(CheckedStep {
            scene_camera: self.scene_camera,
            camera,
            mode,
            layout: self.layout.clone(),
            right,
            divider: self.divider,
            lights,
            rebuild_ibrr: self.rebuild_ibrr,
            reference_spp: self.reference_spp,
            no_wait: self.no_wait,
            screenshot: self.screenshot.clone(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cornell() -> Scene {
        scene_core::builtin::scene("cornell").unwrap()
    }

    fn check(json: &str) -> Result<Vec<CheckedStep>, String> {
        let s: Script = serde_json::from_str(json).map_err(|e| e.to_string())?;
        s.check(&cornell())
    }

    /// A replay file is read only when it is a regular file: a device or a FIFO is refused
    /// at once (reading /dev/zero grew without bound; opening a FIFO blocked forever).
    #[test]
    fn special_files_are_refused_at_once() {
        let start = std::time::Instant::now();
        let e = Script::read(Path::new("/dev/zero")).unwrap_err();
        assert!(
            e.contains("/dev/zero") && e.contains("not a regular file"),
            "{e}"
        );
        let dir = std::env::temp_dir().join(format!("viewer-fifo-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("replay.json");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success());
        if made {
            let e = Script::read(&fifo).unwrap_err();
            assert!(e.contains("not a regular file"), "{e}");
        }
        let e = Script::read(&dir).unwrap_err();
        assert!(e.contains("not a regular file"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
        assert!(start.elapsed() < std::time::Duration::from_secs(5));
    }

    #[test]
    fn reference_spp_out_of_range_is_refused_naming_it() {
        let e = check(r#"{"version": 1, "steps": [{"reference_spp": 0}]}"#).unwrap_err();
        assert!(e.contains("reference_spp = 0 is outside its range"), "{e}");
    }

    #[test]
    fn a_walkthrough_reads_back_as_written() {
        let script = Script {
            version: VERSION,
            steps: vec![Step {
                camera: Some(Pose {
                    position: [0.1, 0.2, 0.3],
                    target: [0.0, 0.2, 0.0],
                }),
                mode: Some("relight".into()),
                lights: vec![LightChange {
                    light: "emissive:0".into(),
                    color: Some([1.0, 0.5, 0.25]),
                    ..Default::default()
                }],
                screenshot: Some("a".into()),
                ..Default::default()
            }],
        };
        let text = serde_json::to_string(&script).unwrap();
        let back: Script = serde_json::from_str(&text).unwrap();
        assert_eq!(back, script);
    }

    #[test]
    fn bad_names_are_errors_that_name_the_step() {
        let e = check(r#"{"version":1,"steps":[{},{"mode":"radiosity"}]}"#).unwrap_err();
        assert!(
            e.contains("step 1") && e.contains("unknown mode 'radiosity'"),
            "{e}"
        );
        let e = check(r#"{"version":1,"steps":[{"lights":[{"light":"point:7"}]}]}"#).unwrap_err();
        assert!(
            e.contains("step 0") && e.contains("no light 'point:7'"),
            "{e}"
        );
        let e = check(
            r#"{"version":1,"steps":[{},{"camera":{"position":[1e20,0,0],"target":[0,0,0]}}]}"#,
        )
        .unwrap_err();
        assert!(e.contains("step 1") && e.contains("camera position"), "{e}");
        let e = check(r#"{"version":1,"steps":[{"layout":"grid"}]}"#).unwrap_err();
        assert!(e.contains("unknown layout 'grid'"), "{e}");
        let e = check(r#"{"version":1,"steps":[{"screenshot":"../x"}]}"#).unwrap_err();
        assert!(e.contains("screenshot name"), "{e}");
        let e = check(r#"{"version":1,"steps":[{"scene_camera":9}]}"#).unwrap_err();
        assert!(e.contains("scene camera 9 does not exist"), "{e}");
        let e = check(r#"{"version":2,"steps":[]}"#).unwrap_err();
        assert!(e.contains("version 2"), "{e}");
        let e = check(r#"{"version":1,"steps":[{"mdoe":"isr"}]}"#).unwrap_err();
        assert!(e.contains("unknown field `mdoe`"), "{e}");
        let key = scene_core::lights::light_ids(&cornell())[0].key();
        let e = check(&format!(
            r#"{{"version":1,"steps":[{{"lights":[{{"light":"{key}","color":[-1,0,0]}}]}}]}}"#
        ))
        .unwrap_err();
        assert!(e.contains("negative"), "{e}");
        // Multipliers each finite, whose product with the light overflows: in one step,
        // and spread over two steps (the running state is checked).
        let e = check(&format!(
            r#"{{"version":1,"steps":[{{"lights":[{{"light":"{key}","color":[1e30,1e30,1e30]}}]}}]}}"#
        ))
        .unwrap_err();
        assert!(e.contains("step 0") && e.contains("overflow"), "{e}");
        let e = check(&format!(
            r#"{{"version":1,"steps":[{{"lights":[{{"light":"{key}","color":[1e5,1e5,1e5]}}]}},{{"lights":[{{"light":"{key}","direct":1e9}}]}}]}}"#
        ))
        .unwrap_err();
        assert!(
            e.contains("step 1")
                && e.contains("with the steps before it")
                && e.contains("overflow"),
            "{e}"
        );
    }

    #[test]
    fn light_changes_keep_what_they_leave_out() {
        let key = scene_core::lights::light_ids(&cornell())[0].key();
        let steps = check(&format!(
            r#"{{"version":1,"steps":[{{"lights":[{{"light":"{key}","direct":0.5}}]}}]}}"#
        ))
        .unwrap();
        let mut state = LightState::default();
        state.set_color(steps[0].lights[0].0, Vec3::new(2.0, 2.0, 2.0));
        apply_lights(&mut state, &steps[0].lights);
        let s = state.get(steps[0].lights[0].0);
        assert_eq!(s.color, Vec3::splat(2.0));
        assert_eq!(s.direct, 0.5);
        assert_eq!(s.indirect, 1.0);
    }
}
