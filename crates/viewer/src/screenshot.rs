//! Screenshots: the composed frame as a linear EXR, an 8-bit sRGB PNG at the display's
//! exposure, and a JSON sidecar naming everything needed to render the same frame with
//! the library (camera, size, mode, layout, light settings, reference samples).

use std::path::{Path, PathBuf};

use scene_core::{Camera, Image, LightState};
use serde_json::{Value, json};

/// What a screenshot shows, for its sidecar.
#[derive(Clone, Debug)]
pub struct Shot<'a> {
    /// File stem.
    pub name: &'a str,
    /// The camera (its aspect ratio that of the frame).
    pub camera: &'a Camera,
    /// Light settings.
    pub lights: &'a LightState,
    /// The (left) mode's name.
    pub mode: &'a str,
    /// The layout's name.
    pub layout: &'a str,
    /// The right mode of a split.
    pub right: Option<&'a str>,
    /// The split's divider.
    pub divider: Option<f32>,
    /// Samples per pixel of the reference on screen, if any.
    pub reference_spp: Option<u32>,
    /// The error view's eq. 19 mean error, if shown.
    pub mean_error: Option<f64>,
    /// Exposure of the PNG, in stops.
    pub exposure: f32,
}

fn vec3(v: glam::Vec3) -> Value {
    json!([v.x, v.y, v.z])
}

/// The sidecar's camera object.
pub fn camera_json(c: &Camera) -> Value {
    json!({
        "name": c.name,
        "position": vec3(c.position),
        "target": vec3(c.target),
        "up": vec3(c.up),
        "fov_y": c.fov_y,
        "aspect": c.aspect,
        "near": c.near,
        "far": c.far,
    })
}

fn lights_json(lights: &LightState) -> Value {
    Value::Array(
        lights
            .changed()
            .map(|(id, s)| {
                json!({
                    "light": id.key(),
                    "enabled": s.enabled,
                    "color": vec3(s.color),
                    "direct": s.direct,
                    "indirect": s.indirect,
                })
            })
            .collect(),
    )
}

/// Writes `DIR/NAME.exr`, `DIR/NAME.png` and `DIR/NAME.json` (creating `DIR`); returns
/// the EXR's path.
pub fn save(dir: &Path, image: &Image, shot: &Shot<'_>) -> Result<PathBuf, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let exr = dir.join(format!("{}.exr", shot.name));
    let png = dir.join(format!("{}.png", shot.name));
    let sidecar = dir.join(format!("{}.json", shot.name));
    image.write_exr(&exr).map_err(|e| e.to_string())?;
    image
        .write_png(&png, shot.exposure)
        .map_err(|e| e.to_string())?;
    let value = json!({
        "name": shot.name,
        "width": image.width,
        "height": image.height,
        "mode": shot.mode,
        "layout": shot.layout,
        "right": shot.right,
        "divider": shot.divider,
        "camera": camera_json(shot.camera),
        "lights": lights_json(shot.lights),
        "reference_spp": shot.reference_spp,
        "mean_error": shot.mean_error,
        "exposure": shot.exposure,
    });
    let text = serde_json::to_string_pretty(&value).map_err(|e| e.to_string())?;
    let tmp = sidecar.with_extension("json.tmp");
    std::fs::write(&tmp, text)
        .and_then(|_| std::fs::rename(&tmp, &sidecar))
        .map_err(|e| format!("{}: {e}", sidecar.display()))?;
    Ok(exr)
}
