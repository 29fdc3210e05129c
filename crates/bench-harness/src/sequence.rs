//! Relighting sequences: after one precomputation the lights change over a run of frames
//! (recolour, dim, switch off, switch banks); every technique renders every frame under that
//! frame's light state, timed, and is compared with a reference rendered under the same state
//! (cached by the state).

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use scene_core::glam::Vec3;
use scene_core::lights::{LightId, LightState, light_ids};
use scene_core::reference::{Bounces, ReferenceSettings};
use scene_core::{Camera, FrameRequest, Metric, Scene};
use serde::{Deserialize, Serialize};

use crate::HarnessError;
use crate::cache::ReferenceCache;
use crate::run::TechniqueSetup;

/// One frame of a sequence: a light state with a caption.
#[derive(Clone, Debug, PartialEq)]
pub struct SequenceFrame {
    /// What changed, in words (`"lamp 0 dimmed to 25%"`).
    pub caption: String,
    /// The lights in this frame.
    pub lights: LightState,
}

/// The standard relighting scenario of `scene` in `frames` frames: as authored, the first
/// light recoloured warm, dimmed to a quarter, recoloured cold, then (with two or more
/// lights) the first light switched off, each half of the lights alone (two banks), every
/// light recoloured, and back to the scene as authored; the list repeats when longer.
/// A scene without lights gets `frames` default frames.
pub fn light_sequence(scene: &Scene, frames: usize) -> Vec<SequenceFrame> {
    let ids = light_ids(scene);
    let name = |id: LightId| id.label(scene);
    let mut steps: Vec<SequenceFrame> = vec![SequenceFrame {
        caption: "as authored".into(),
        lights: LightState::default(),
    }];
    if let Some(&first) = ids.first() {
        let with = |f: &dyn Fn(&mut LightState)| {
            let mut s = LightState::default();
            f(&mut s);
            s
        };
        steps.push(SequenceFrame {
            caption: format!("{} recoloured warm", name(first)),
            lights: with(&|s| s.set_color(first, Vec3::new(1.0, 0.55, 0.25))),
        });
        steps.push(SequenceFrame {
            caption: format!("{} dimmed to 25%", name(first)),
            lights: with(&|s| s.set_color(first, Vec3::splat(0.25))),
        });
        steps.push(SequenceFrame {
            caption: format!("{} recoloured cold", name(first)),
            lights: with(&|s| s.set_color(first, Vec3::new(0.3, 0.6, 1.2))),
        });
        if ids.len() >= 2 {
            steps.push(SequenceFrame {
                caption: format!("{} off", name(first)),
                lights: with(&|s| s.set_enabled(first, false)),
            });
            let half = ids.len() / 2;
            for (bank, range) in [("first", 0..half), ("second", half..ids.len())] {
                let lights = with(&|s| {
                    for (i, &id) in ids.iter().enumerate() {
                        s.set_enabled(id, range.contains(&i));
                    }
                });
                steps.push(SequenceFrame {
                    caption: format!("{bank} bank only"),
                    lights,
                });
            }
            steps.push(SequenceFrame {
                caption: "every light recoloured".into(),
                lights: with(&|s| {
                    for (i, &id) in ids.iter().enumerate() {
                        let c = if i % 2 == 0 {
                            Vec3::new(1.2, 0.7, 0.4)
                        } else {
                            Vec3::new(0.4, 0.7, 1.2)
                        };
                        s.set_color(id, c);
                    }
                }),
            });
        }
        steps.push(SequenceFrame {
            caption: "as authored again".into(),
            lights: LightState::default(),
        });
    }
    (0..frames)
        .map(|i| steps[i % steps.len()].clone())
        .collect()
}

/// How a sequence is rendered and measured.
#[derive(Clone, Debug)]
pub struct SequenceSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel of each frame's reference.
    pub spp: u32,
    /// The references' bounce limit.
    pub bounces: Bounces,
    /// Reference seed.
    pub seed: u64,
}

/// One technique in one frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SequenceSample {
    /// Technique label.
    pub label: String,
    /// Seconds of the frame (the render under the new light state: a relight, a re-lit
    /// G-buffer, or a rebuild for a technique that must rebuild).
    pub frame_s: f64,
    /// Error against the frame's reference (the experiment's error metric).
    pub error: f64,
    /// Error over lit surfaces, with the bias per channel.
    #[serde(default)]
    pub surface: Option<crate::results::SurfaceError>,
}

/// One frame of a sequence, measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SequenceFrameResult {
    /// What changed.
    pub caption: String,
    /// Seconds of the frame's reference render (when rendered, even if cached since).
    pub reference_s: f64,
    /// Every technique, in the experiment's order.
    pub techniques: Vec<SequenceSample>,
}

/// A measured sequence.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SequenceResult {
    /// Scene id.
    pub scene: String,
    /// Camera name.
    pub camera: String,
    /// The references' bounce limit.
    pub bounces: String,
    /// Samples per pixel of the references.
    pub spp: u32,
    /// The error metric.
    pub metric: String,
    /// Precomputation of each technique before the first frame (seconds), which is also
    /// the cost of solving again from scratch.
    pub prepare_s: Vec<(String, f64)>,
    /// The frames.
    pub frames: Vec<SequenceFrameResult>,
}

impl SequenceResult {
    /// Checks a saved sequence before it is reported as measured: every time and error
    /// finite and at least 0. The error names the frame, the technique and the field.
    pub fn check(&self) -> Result<(), String> {
        let bad = |what: String, v: f64| {
            (!(v.is_finite() && v >= 0.0))
                .then(|| format!("{what} is {v:?}, not a finite value >= 0"))
        };
        for (label, s) in &self.prepare_s {
            if let Some(e) = bad(format!("{label}: precomputation seconds"), *s) {
                return Err(e);
            }
        }
        for (i, f) in self.frames.iter().enumerate() {
            if let Some(e) = bad(format!("frame {i}: reference seconds"), f.reference_s) {
                return Err(e);
            }
            for t in &f.techniques {
                if let Some(e) = bad(format!("frame {i}: {} seconds", t.label), t.frame_s)
                    .or_else(|| bad(format!("frame {i}: {} error", t.label), t.error))
                {
                    return Err(e);
                }
            }
        }
        Ok(())
    }

    /// The (frame time, error) series of technique `label`.
    pub fn series(&self, label: &str) -> Vec<(f64, f64)> {
        self.frames
            .iter()
            .filter_map(|f| f.techniques.iter().find(|t| t.label == label))
            .map(|t| (t.frame_s, t.error))
            .collect()
    }
}

/// Runs `frames` on `scene` from `camera`: each technique is prepared once (timed; or, when
/// `prepared` gives its times, taken as already prepared for `scene`), renders one untimed
/// warm-up frame as authored, then renders every frame under its light state (timed) and is
/// compared by `metric` with the frame's reference from `cache` (keyed by `scene_hash`,
/// computed when not given), over the whole image and over lit surfaces. The camera stays
/// still: frame times are still-camera figures (per-view work is reused), which is what a
/// relighting session costs. The frame's images go to `images` (PNG) when given.
#[allow(clippy::too_many_arguments)]
pub fn run_sequence(
    scene_id: &str,
    scene: &Arc<Scene>,
    scene_hash: Option<u64>,
    camera: &Camera,
    techniques: &mut [TechniqueSetup],
    metric: &dyn Metric,
    frames: &[SequenceFrame],
    settings: &SequenceSettings,
    cache: &ReferenceCache,
    images: Option<&Path>,
    prepared: Option<&[f64]>,
) -> Result<SequenceResult, HarnessError> {
    let hash = scene_hash.unwrap_or_else(|| crate::cache::scene_hash(scene));
    let cam = camera.with_aspect(settings.width as f32 / settings.height as f32);
    let (w, h) = (settings.width, settings.height);
    let fail = |label: &str, e| HarnessError::Technique {
        label: label.to_string(),
        scene: scene_id.to_string(),
        source: Box::new(e),
    };
    let mut prepare_s = Vec::new();
    let prepared = prepared.filter(|p| p.len() == techniques.len());
    for (ti, t) in techniques.iter_mut().enumerate() {
        let seconds = match prepared {
            Some(p) => p[ti],
            None => {
                let t0 = Instant::now();
                t.technique
                    .prepare(scene.clone())
                    .map_err(|e| fail(&t.label, e))?;
                t0.elapsed().as_secs_f64()
            }
        };
        prepare_s.push((t.label.clone(), seconds));
        t.technique
            .render(&FrameRequest::from_camera(
                &cam,
                w,
                h,
                &LightState::default(),
            ))
            .map_err(|e| fail(&t.label, e))?;
    }
    if let Some(dir) = images {
        std::fs::create_dir_all(dir).map_err(|e| HarnessError::io(dir, e))?;
    }
    let surface: Vec<bool> = scene_core::reference::PathTracer::new(scene)
        .pixel_classes(&scene_core::View::from_camera(&cam), w, h)
        .into_iter()
        .map(|c| c == scene_core::reference::PixelClass::Surface)
        .collect();
    let mut out = Vec::new();
    for (fi, frame) in frames.iter().enumerate() {
        frame
            .lights
            .check(scene)
            .map_err(|m| HarnessError::Invalid(format!("sequence frame {fi}: {m}")))?;
        let rs = ReferenceSettings {
            width: w,
            height: h,
            spp: settings.spp,
            bounces: settings.bounces,
            seed: settings.seed,
        };
        let reference = cache.get_or_render_lit(scene, hash, &cam, &rs, &frame.lights, None)?;
        let mask = crate::results::surface_mask(&surface, &reference.image);
        let mut samples = Vec::new();
        for t in techniques.iter_mut() {
            let t0 = Instant::now();
            let img = t
                .technique
                .render(&FrameRequest::from_camera(&cam, w, h, &frame.lights))
                .map_err(|e| fail(&t.label, e))?;
            let frame_s = t0.elapsed().as_secs_f64();
            let error = metric
                .compare(&reference.image, &img)
                .map_err(|e| HarnessError::Metric {
                    name: metric.name().to_string(),
                    source: Box::new(e),
                })?
                .value;
            if let Some(dir) = images {
                let file = dir.join(format!("{fi:02}-{}.png", crate::run::slug(&t.label)));
                img.write_png(&file, 0.0)
                    .map_err(|e| HarnessError::from(scene_core::Error::from(e)))?;
            }
            samples.push(SequenceSample {
                label: t.label.clone(),
                frame_s,
                error,
                surface: crate::results::surface_error(&reference.image, &img, &mask),
            });
        }
        if let Some(dir) = images {
            let file = dir.join(format!("{fi:02}-reference.png"));
            reference
                .image
                .write_png(&file, 0.0)
                .map_err(|e| HarnessError::from(scene_core::Error::from(e)))?;
        }
        out.push(SequenceFrameResult {
            caption: frame.caption.clone(),
            reference_s: reference.seconds,
            techniques: samples,
        });
    }
    Ok(SequenceResult {
        scene: scene_id.to_string(),
        camera: camera.name.clone(),
        bounces: settings.bounces.to_string(),
        spp: settings.spp,
        metric: metric.name().to_string(),
        prepare_s,
        frames: out,
    })
}
