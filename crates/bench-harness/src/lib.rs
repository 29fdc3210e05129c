//! # bench-harness
//!
//! Runs any [`scene_core::Technique`] against any [`scene_core::Metric`] and reports speed
//! and error together: an [`Experiment`] is scenes x cameras x techniques x metrics. For
//! every view it renders (or takes from a disk cache) the reference path tracer's images at
//! the bounce limits asked for, times each technique (precomputation apart from frames;
//! warm-up, then repeats: median, min, max), compares every frame with every reference, and
//! writes images, per-view results, `results.json`, `report.md` and `report.html`.
//!
//! ```
//! use bench_harness::{Experiment, ExperimentSettings, SceneSetup, TechniqueSetup};
//! use std::sync::Arc;
//! use scene_core::{builtin, Error, FrameRequest, Image, Metric, MetricValue, Scene, Technique};
//! use scene_core::reference::Bounces;
//!
//! /// A "technique" that renders a constant grey.
//! struct Grey(f32);
//! impl Technique for Grey {
//!     fn name(&self) -> &str { "grey" }
//!     fn prepare(&mut self, _: Arc<Scene>) -> Result<(), Error> { Ok(()) }
//!     fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
//!         Ok(Image::filled(frame.width, frame.height, scene_core::glam::Vec3::splat(self.0)))
//!     }
//! }
//! /// Mean absolute difference.
//! struct Mae;
//! impl Metric for Mae {
//!     fn name(&self) -> &str { "mean-error" }
//!     fn lower_is_better(&self) -> bool { true }
//!     fn compare(&self, r: &Image, t: &Image) -> Result<MetricValue, Error> {
//!         let s: f32 = r.pixels.iter().zip(&t.pixels).map(|(a, b)| (*a - *b).abs().element_sum()).sum();
//!         Ok(MetricValue { value: s as f64 / (3 * r.pixels.len()) as f64, map: None })
//!     }
//! }
//!
//! let scene = builtin::scene("cornell").unwrap();
//! let out = std::env::temp_dir().join(format!("bench-harness-doc-{}", std::process::id()));
//! let mut experiment = Experiment {
//!     settings: ExperimentSettings {
//!         width: 16, height: 12, spp: 2, bounces: vec![Bounces::Limited(1)],
//!         repeats: 1, out_dir: out.clone(), progress: false, ..Default::default()
//!     },
//!     scenes: vec![SceneSetup { id: "cornell".into(), cameras: scene.cameras[..1].to_vec(), scene: Arc::new(scene) }],
//!     techniques: vec![
//!         TechniqueSetup { label: "dl".into(), family: "dl".into(), description: "black".into(), technique: Box::new(Grey(0.0)), single_frame: false },
//!         TechniqueSetup { label: "grey".into(), family: "grey".into(), description: "0.1".into(), technique: Box::new(Grey(0.1)), single_frame: false },
//!     ],
//!     metrics: vec![Box::new(Mae)],
//! };
//! let outcome = experiment.run().unwrap();
//! assert_eq!(outcome.views_computed, 1);
//! assert!(outcome.report_md.exists() && outcome.report_html.exists());
//! assert_eq!(outcome.results.summary.comparisons[0].technique, "grey");
//! # std::fs::remove_dir_all(&out).ok();
//! ```
//!
//! The pieces: [`experiment`] (the run, resume, timing), [`cache`] (reference images keyed by
//! a hash of scene, camera, settings and spp), [`cameras`] (JSON camera lists and seeded
//! random cameras in a scene's free space), [`results`] (`results.json` and the summary
//! statistics of the thesis' chapter 5), [`report`] (Markdown and HTML with inline SVG
//! plots), [`povray`] (a scene and camera as a POV-Ray file with the thesis' radiosity
//! settings).
//!
//! The crate composes nothing concrete: `cargo xtask experiment` plugs in the ISR and DL
//! techniques, the G-buffer rasteriser and imalyzer's metrics.

pub mod cache;
pub mod cameras;
pub mod experiment;
pub mod format;
pub mod merge;
pub mod mitsuba;
pub mod plots;
pub mod povray;
pub mod report;
pub mod results;
pub mod run;
pub mod sequence;

use std::path::{Path, PathBuf};

pub use cache::{CpuReference, ReferenceCache, ReferenceRenderer, RenderedReference, scene_hash};
pub use cameras::{
    CameraSpec, RandomCameraSettings, cameras_for, load_camera_list, parse_camera_list,
    random_cameras,
};
pub use experiment::{
    Experiment, ExperimentSettings, RunOutcome, SceneSetup, SequenceSpec, Shard, TechniqueSetup,
};
pub use merge::merge;
pub use results::{Comparison, Results, RunInfo, Summary, TimeRow, ViewResult};
pub use scene_core;

/// An error of the harness.
#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    /// A camera list file could not be read or parsed.
    #[error("camera list {path}: {message}")]
    CameraList {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// Cameras could not be generated.
    #[error("cameras: {0}")]
    Cameras(String),
    /// A technique failed.
    #[error("technique '{label}' on scene '{scene}': {source}")]
    Technique {
        /// The technique's label.
        label: String,
        /// The scene.
        scene: String,
        /// The failure.
        source: Box<scene_core::Error>,
    },
    /// A metric failed.
    #[error("metric '{name}': {source}")]
    Metric {
        /// The metric.
        name: String,
        /// The failure.
        source: Box<scene_core::Error>,
    },
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The experiment is set up wrongly.
    #[error("invalid experiment: {0}")]
    Invalid(String),
    /// An error of the shared layer.
    #[error(transparent)]
    Core(Box<scene_core::Error>),
}

impl From<scene_core::Error> for HarnessError {
    fn from(e: scene_core::Error) -> Self {
        HarnessError::Core(Box::new(e))
    }
}

impl HarnessError {
    /// An I/O error on `path`.
    pub fn io(path: &Path, e: impl std::fmt::Display) -> Self {
        HarnessError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    }
}

/// Writes `value` as pretty JSON through a temporary file (never half-written).
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<(), HarnessError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| HarnessError::io(path, e))?;
    scene_core::image::write_via_temp(
        path,
        |tmp| std::fs::write(tmp, &text).map_err(|e| HarnessError::io(path, e)),
        |e| HarnessError::io(path, e),
    )
}
