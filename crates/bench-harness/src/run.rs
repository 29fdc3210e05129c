//! The vocabulary of a run, which the orchestrator (`experiment`), the merge of shards,
//! the reports and the commands all speak: what is run (scenes with their cameras,
//! techniques with their labels, the settings, a relighting sequence, a shard of the
//! views) and where its files go (`slug`, `view_dir`). In `experiment.rs` until 2026-11-27;
//! `experiment` re-exports it.

use std::path::PathBuf;
use std::sync::Arc;

use scene_core::reference::Bounces;
use scene_core::{Camera, Scene, Technique};

/// A scene and the cameras to render it from.
pub struct SceneSetup {
    /// Id used in reports and file names.
    pub id: String,
    /// The scene (shared with the techniques prepared for it).
    pub scene: Arc<Scene>,
    /// The views (their aspect ratio is replaced by the image's).
    pub cameras: Vec<Camera>,
}

/// A technique with its label.
pub struct TechniqueSetup {
    /// Unique label (`dl`, `isr-80`, `isr-thesis-24`...).
    pub label: String,
    /// Family: the technique's kind (`dl`, `isr`).
    pub family: String,
    /// Its parameters in words.
    pub description: String,
    /// The technique.
    pub technique: Box<dyn Technique>,
    /// Render a single timed frame per view (no warm-up, no repeats), for slow offline
    /// renderers such as POV-Ray.
    pub single_frame: bool,
}

/// The settings of an experiment.
#[derive(Clone, Debug)]
pub struct ExperimentSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Reference samples per pixel.
    pub spp: u32,
    /// Reference bounce limits (default: 1 and unlimited); the first drives the plots.
    pub bounces: Vec<Bounces>,
    /// Reference seed.
    pub seed: u64,
    /// Untimed frames before the timed ones, each from a neighbour of the view (never the
    /// view itself, so that per-view work stays inside the timed frames).
    pub warmup: u32,
    /// Timed moving-camera frames (median, min, max reported): the view itself, then
    /// neighbours of it ([`neighbour`]), each new to the technique.
    pub repeats: u32,
    /// Timed still-camera frames after those: the view again, reusing whatever per-view
    /// work the technique keeps (0: not measured). Reported beside, never instead of, the
    /// moving-camera figure.
    pub still_repeats: u32,
    /// Extend the equal-error ladder with rungs at twice the finest, up to half the
    /// reference's spp (the reference's own noise floor), until it brackets every
    /// technique's error.
    pub ladder_extend: bool,
    /// Provenance written into `results.json` (date, command, preset, tuning); the harness
    /// fills in the scenes, the shard and the seconds.
    pub run_info: crate::results::RunInfo,
    /// Run only the `k`-th of `n` shares of the work (views and the sequence, dealt round
    /// the shards in run order); [`crate::merge()`] combines the shards' output folders.
    pub shard: Option<Shard>,
    /// Output folder.
    pub out_dir: PathBuf,
    /// Reference cache folder (default `<out_dir>/reference-cache`).
    pub cache_dir: Option<PathBuf>,
    /// What renders the references and the equal-error ladder (`None`: the CPU path
    /// tracer); a GPU twin makes the ladder's speedups those over the GPU path tracer.
    pub reference_renderer: Option<std::sync::Arc<dyn crate::ReferenceRenderer>>,
    /// Label of the baseline technique (DL).
    pub baseline: String,
    /// The metric whose value decides which image is closer (eq. 19's mean error).
    pub error_metric: String,
    /// The correlation metric (eq. 20).
    pub correlation_metric: String,
    /// Technique label shown against the baseline in the per-view plots and the gallery
    /// (default: the first technique that is not the baseline).
    pub headline: Option<String>,
    /// Show progress bars.
    pub progress: bool,
    /// Stop after computing this many views (simulates an interrupted run).
    pub stop_after_views: Option<usize>,
    /// PNG exposure in stops.
    pub exposure: f32,
    /// Write every image (EXR and PNG, and difference images); off keeps only the gallery.
    pub write_images: bool,
    /// The equal-error ladder: sample counts (below `spp`) at which the path tracer also
    /// renders each view with another seed, to find the spp at which its error equals each
    /// technique's ([`crate::results::equal_error`]). Empty: no ladder.
    pub ladder_spp: Vec<u32>,
    /// A relighting sequence to run after the views (see [`crate::sequence`]).
    pub sequence: Option<SequenceSpec>,
}

/// Which relighting sequence an experiment runs.
#[derive(Clone, Debug, PartialEq)]
pub struct SequenceSpec {
    /// The scene's id (one of the experiment's scenes).
    pub scene: String,
    /// The camera's index in that scene's list.
    pub camera: usize,
    /// Frames ([`crate::sequence::light_sequence`]).
    pub frames: usize,
    /// Samples per pixel of each frame's reference.
    pub spp: u32,
    /// The references' bounce limit.
    pub bounces: Bounces,
}

/// The default equal-error ladder for a reference of `spp` samples: powers of two from 1 up
/// to `spp / 8` (the rungs together cost about a quarter of the reference).
pub fn default_ladder(spp: u32) -> Vec<u32> {
    let mut v = Vec::new();
    let mut n = 1u32;
    while n <= spp / 8 {
        v.push(n);
        n *= 2;
    }
    v
}

/// One share of an experiment's work: the `index`-th (0-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Shard {
    /// Which share, `0..count`.
    pub index: usize,
    /// How many shares.
    pub count: usize,
}

impl Shard {
    /// Parses `K/N`: share `K` (1-based) of `N`. A runner that numbers its tasks from 0
    /// (a Kubernetes Indexed Job) passes `$((INDEX + 1))/N`.
    pub fn parse(s: &str) -> Result<Self, String> {
        let bad = || format!("--shard takes K/N with 1 <= K <= N <= 4096, got '{s}'");
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let k: usize = k.trim().parse().map_err(|_| bad())?;
        let n: usize = n.trim().parse().map_err(|_| bad())?;
        if !(1..=4096).contains(&n) || !(1..=n).contains(&k) {
            return Err(bad());
        }
        Ok(Self {
            index: k - 1,
            count: n,
        })
    }

    /// True when job number `job` (in run order) is this shard's.
    pub fn owns(&self, job: usize) -> bool {
        job % self.count == self.index
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index + 1, self.count)
    }
}

/// The `k`-th neighbour of a camera (`k >= 1`): moved sideways by `k` x 0.5% of its
/// viewing distance, target with it. Frames timed from neighbours are views a technique
/// has not rendered before, at the same cost as the view itself.
pub fn neighbour(camera: &Camera, k: u32) -> Camera {
    let d = camera.target - camera.position;
    let right = d.cross(camera.view_up()).normalize_or_zero();
    let shift = right * d.length() * 5e-3 * k as f32;
    Camera {
        position: camera.position + shift,
        target: camera.target + shift,
        ..camera.clone()
    }
}

/// The seed of the ladder's renders: independent of the reference's.
pub fn ladder_seed(seed: u64) -> u64 {
    seed ^ 0x1add_e5ee_d000_0001
}

impl Default for ExperimentSettings {
    fn default() -> Self {
        Self {
            width: 160,
            height: 120,
            spp: 64,
            bounces: vec![Bounces::Limited(1), Bounces::Unlimited],
            seed: 1,
            warmup: 1,
            repeats: 3,
            still_repeats: 0,
            ladder_extend: true,
            shard: None,
            run_info: Default::default(),
            out_dir: PathBuf::from("out/experiment"),
            cache_dir: None,
            reference_renderer: None,
            baseline: "dl".into(),
            error_metric: "mean-error".into(),
            correlation_metric: "pearson".into(),
            headline: None,
            progress: true,
            stop_after_views: None,
            exposure: 0.0,
            write_images: true,
            ladder_spp: Vec::new(),
            sequence: None,
        }
    }
}

/// File-name-safe form of a label.
pub fn slug(s: &str) -> String {
    let mut out: String = s
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if out.is_empty() {
        out.push('_');
    }
    out
}

/// The folder of a view's images, relative to the output folder.
pub fn view_dir(scene: &str, camera_index: usize, camera_name: &str) -> PathBuf {
    PathBuf::from("images")
        .join(slug(scene))
        .join(format!("{camera_index:02}-{}", slug(camera_name)))
}
