//! What an experiment measured (`results.json`) and the summary computed from it.

use serde::{Deserialize, Serialize};

use crate::cameras::CameraSpec;

/// Frame times of one technique on one view (seconds).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Median of the timed repeats.
    pub median_s: f64,
    /// Fastest repeat.
    pub min_s: f64,
    /// Slowest repeat.
    pub max_s: f64,
    /// Timed repeats (after the warm-up frames).
    pub repeats: u32,
}

impl Timing {
    /// Median, min and max of `samples` (seconds); zeros when empty.
    pub fn from_samples(samples: &[f64]) -> Self {
        let mut v = samples.to_vec();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = match n {
            0 => 0.0,
            _ if n % 2 == 1 => v[n / 2],
            _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
        };
        Self {
            median_s: median,
            min_s: v.first().copied().unwrap_or(0.0),
            max_s: v.last().copied().unwrap_or(0.0),
            repeats: n as u32,
        }
    }
}

/// The errors of one technique against the reference at one bounce limit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorSet {
    /// The reference's bounce limit (`"1"`, `"inf"`...).
    pub bounces: String,
    /// Metric name and value, in the experiment's metric order.
    pub metrics: Vec<(String, f64)>,
    /// Pixels strictly closer to the reference than the baseline's (per-pixel distance: the
    /// sum over channels of the absolute difference); `None` for the baseline itself.
    pub pixels_closer: Option<u64>,
    /// Pixels strictly farther from the reference than the baseline's (`None` for the
    /// baseline); the rest are ties (background, emitters, untouched pixels).
    #[serde(default)]
    pub pixels_farther: Option<u64>,
    /// Pixels compared.
    pub pixels: u64,
    /// The path tracer's samples per pixel (and time) at which its own error equals this
    /// technique's error (`None` without a ladder, or for the reference's bounce limit
    /// when the ladder's error does not fall with the sample count).
    #[serde(default)]
    pub equal_error: Option<EqualError>,
    /// The error over lit surfaces ([`surface_error`]): emitters, background and the
    /// reference's brightest 1% left out, with the bias per channel.
    #[serde(default)]
    pub surface: Option<SurfaceError>,
}

/// Error over lit surfaces: the pixels whose centre sees a reflecting surface (not an
/// emitter, not the background), less the reference's brightest 1% of those (fireflies and
/// highlights at emitter edges). Whole-image means dilute a method's bias under emitters
/// that every method copies exactly; this is the figure that shows it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SurfaceError {
    /// Pixels measured.
    pub pixels: u64,
    /// Mean over those pixels and the three channels of `|test - reference|` (eq. 19's
    /// mean error restricted to lit surfaces).
    pub mean_error: f64,
    /// Per channel, `(sum test - sum reference) / sum reference` over those pixels: -0.1
    /// is 10% dark (0 where the reference is black there).
    pub bias: [f64; 3],
}

/// Share of the brightest lit-surface pixels of the reference left out of [`SurfaceError`].
pub const SURFACE_BRIGHTEST_EXCLUDED: f64 = 0.01;

/// The lit-surface mask of a view: `surface[i]` says pixel `i`'s centre sees a reflecting
/// surface ([`scene_core::reference::PixelClass::Surface`]); of those, the pixels whose
/// reference luminance is above the 99th percentile are left out.
pub fn surface_mask(surface: &[bool], reference: &scene_core::Image) -> Vec<bool> {
    let lum = |i: usize| scene_core::luminance(reference.pixels[i]);
    let mut values: Vec<f32> = (0..surface.len().min(reference.pixels.len()))
        .filter(|&i| surface[i])
        .map(lum)
        .filter(|v| v.is_finite())
        .collect();
    if values.is_empty() {
        return vec![false; surface.len()];
    }
    values.sort_by(f32::total_cmp);
    let keep = ((values.len() as f64) * (1.0 - SURFACE_BRIGHTEST_EXCLUDED)).ceil() as usize;
    let limit = values[keep.clamp(1, values.len()) - 1];
    (0..surface.len())
        .map(|i| surface[i] && i < reference.pixels.len() && lum(i) <= limit)
        .collect()
}

/// [`SurfaceError`] of `test` against `reference` over `mask` ([`surface_mask`]); `None`
/// when the mask is empty or the sizes differ.
pub fn surface_error(
    reference: &scene_core::Image,
    test: &scene_core::Image,
    mask: &[bool],
) -> Option<SurfaceError> {
    if reference.pixels.len() != test.pixels.len() || mask.len() != reference.pixels.len() {
        return None;
    }
    let (mut abs, mut sum_t, mut sum_r, mut n) = (0.0f64, [0.0f64; 3], [0.0f64; 3], 0u64);
    for ((r, t), &m) in reference.pixels.iter().zip(&test.pixels).zip(mask) {
        if !m {
            continue;
        }
        let (r, t) = (r.as_dvec3(), t.as_dvec3());
        abs += (r - t).abs().element_sum();
        for c in 0..3 {
            sum_t[c] += t[c];
            sum_r[c] += r[c];
        }
        n += 1;
    }
    if n == 0 {
        return None;
    }
    let bias = std::array::from_fn(|c| {
        if sum_r[c] > 0.0 {
            (sum_t[c] - sum_r[c]) / sum_r[c]
        } else {
            0.0
        }
    });
    let mean_error = abs / (3 * n) as f64;
    (mean_error.is_finite() && bias.iter().all(|b: &f64| b.is_finite())).then_some(SurfaceError {
        pixels: n,
        mean_error,
        bias,
    })
}

/// One rung of the equal-error ladder: the path tracer at a lower sample count (another
/// seed) against the high-spp reference.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LadderPoint {
    /// Samples per pixel.
    pub spp: u32,
    /// Seconds of the render.
    pub seconds: f64,
    /// Its error against the reference (the experiment's error metric).
    pub error: f64,
}

/// Where a technique's error lies against the equal-error ladder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum LadderBound {
    /// Between two rungs: the spp is interpolated and the speedup is a measurement.
    Within,
    /// Closer than the finest rung: the path tracer needs more than that rung's spp, and
    /// the speedup is at least the one given (a lower bound, shown "> N x").
    AboveFinest,
    /// Farther than the coarsest rung (1 spp): the path tracer needs fewer samples, and the
    /// speedup is at most the one given (an upper bound, shown "< N x").
    BelowCoarsest,
}

/// The path tracer's cost at a technique's error.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EqualError {
    /// Samples per pixel at which the path tracer's error equals the technique's
    /// (interpolated in log-log between the bracketing rungs; the outside rung's spp when
    /// `bound` is not [`LadderBound::Within`]).
    pub spp: f64,
    /// Seconds the path tracer takes at that sample count (its measured seconds per spp).
    pub seconds: f64,
    /// `seconds` over the technique's median frame time: how many times faster the
    /// technique is at equal error (above 1: the technique wins); a bound unless `bound` is
    /// [`LadderBound::Within`].
    pub speedup: f64,
    /// Whether the ladder brackets the error. Never extrapolated: outside the ladder the
    /// figure is a bound and is left out of medians.
    pub bound: LadderBound,
}

impl EqualError {
    /// The speedup as shown: `123.4`, `> 123.4` or `< 0.5`.
    pub fn shown(&self) -> String {
        let v = crate::format::fmt_2(self.speedup);
        match self.bound {
            LadderBound::Within => v,
            LadderBound::AboveFinest => format!("> {v}"),
            LadderBound::BelowCoarsest => format!("< {v}"),
        }
    }
}

/// The equal-error point of `error` on `ladder` for a technique whose frame takes
/// `frame_s` seconds: the ladder is read as `log e = a + k log spp` between the two rungs
/// that bracket `error`. An error outside the ladder gives the outside rung as a bound
/// ([`LadderBound`]), never an extrapolation. `None` with fewer than two rungs or a
/// non-positive error.
pub fn equal_error(ladder: &[LadderPoint], error: f64, frame_s: f64) -> Option<EqualError> {
    let mut l: Vec<LadderPoint> = ladder
        .iter()
        .copied()
        .filter(|p| p.spp > 0 && p.error > 0.0 && p.error.is_finite())
        .collect();
    l.sort_by_key(|p| p.spp);
    if l.len() < 2 || !(error > 0.0 && error.is_finite()) {
        return None;
    }
    let n = l.len();
    let top = l[n - 1];
    let per_spp = top.seconds / top.spp as f64;
    let speedup = |seconds: f64| {
        if frame_s > 0.0 {
            seconds / frame_s
        } else {
            f64::INFINITY
        }
    };
    let at = |spp: f64, bound| {
        let seconds = spp * per_spp;
        Some(EqualError {
            spp,
            seconds,
            speedup: speedup(seconds),
            bound,
        })
    };
    if error > l[0].error {
        return at(l[0].spp as f64, LadderBound::BelowCoarsest);
    }
    // The first rung at or below `error` closes the bracketing segment.
    let Some(k) = l.iter().position(|p| p.error <= error) else {
        return at(top.spp as f64, LadderBound::AboveFinest);
    };
    if k == 0 {
        return at(l[0].spp as f64, LadderBound::Within);
    }
    let (a, b) = (l[k - 1], l[k]);
    let (x0, x1) = ((a.spp as f64).ln(), (b.spp as f64).ln());
    // `a` is above `error` and `b` at or below it, so the segment falls.
    let (y0, y1) = (a.error.ln(), b.error.ln());
    let x = x0 + (error.ln() - y0) * (x1 - x0) / (y1 - y0);
    at(x.exp(), LadderBound::Within)
}

impl ErrorSet {
    /// The value of metric `name`.
    pub fn metric(&self, name: &str) -> Option<f64> {
        self.metrics.iter().find(|(n, _)| n == name).map(|m| m.1)
    }
}

/// One technique on one view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TechniqueResult {
    /// The technique's label (unique in the experiment).
    pub label: String,
    /// Precomputation time for the view's scene (seconds; the run that computed the view).
    pub prepare_s: f64,
    /// Frame times of a moving camera: every timed frame is a view the technique had not
    /// rendered before, so per-view work (caches a frame fills) is inside. The report,
    /// the ranking and the equal-error speedups use these.
    pub frame: Timing,
    /// Frame times of a still camera: the same view rendered again, reusing per-view work
    /// (a second, labelled figure; `None` when not measured).
    #[serde(default)]
    pub still: Option<Timing>,
    /// How `frame` and `still` were measured: `None` for the harness's wall clock around
    /// the technique's whole render; else the technique's own device clock (GPU timestamps,
    /// or the wall clock from recording its frame to the device's completion), which leaves
    /// out what the harness does around the method (its G-buffer, the readback for scoring).
    #[serde(default)]
    pub clock: Option<String>,
    /// When `frame` is the technique's device time: the harness's wall-clock times of the
    /// same moving-camera frames (G-buffer, method, readback), a second, labelled figure.
    #[serde(default)]
    pub harness: Option<Timing>,
    /// Errors per reference bounce limit.
    pub errors: Vec<ErrorSet>,
    /// The technique's own estimate of its lit-surface error for the view's scene
    /// ([`scene_core::Technique::stated_error`]); `None` for methods that state none.
    #[serde(default)]
    pub stated_error: Option<f64>,
}

/// A reference image of one view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceResult {
    /// Bounce limit.
    pub bounces: String,
    /// Samples per pixel.
    pub spp: u32,
    /// Seconds the path tracer took (when it was rendered, even if cached since).
    pub seconds: f64,
    /// The cache key (hex).
    pub key: String,
    /// The equal-error ladder: the path tracer at lower sample counts against this
    /// reference (empty when not asked).
    #[serde(default)]
    pub ladder: Vec<LadderPoint>,
}

/// Everything measured on one view (scene and camera).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewResult {
    /// The scene's id in the experiment.
    pub scene: String,
    /// Index of the camera in the scene's list.
    pub camera_index: usize,
    /// The camera.
    pub camera: CameraSpec,
    /// Fingerprint of the settings that produced this view (a changed setting recomputes).
    pub config: String,
    /// The reference images.
    pub references: Vec<ReferenceResult>,
    /// The techniques, in the experiment's order.
    pub techniques: Vec<TechniqueResult>,
}

/// `Err` naming `what` unless `v` is a time or an error value: finite and at least 0.
fn non_negative(what: impl FnOnce() -> String, v: f64) -> Result<(), String> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(format!("{} is {v:?}, not a finite value >= 0", what()))
    }
}

impl ViewResult {
    /// Checks what a saved view holds before it is reported as measured (a resume file is
    /// read back like user input): every time and error finite and at least 0, frame
    /// times ordered (min <= median <= max) from at least one repeat, metric values
    /// finite (and at least 0 for the metrics `lower_is_better` names: errors), pixel
    /// counts within the image, sample counts positive. The error names the technique and
    /// the field.
    pub fn check(&self, lower_is_better: &dyn Fn(&str) -> bool) -> Result<(), String> {
        for r in &self.references {
            let b = &r.bounces;
            non_negative(|| format!("reference (bounces {b}) seconds"), r.seconds)?;
            if r.spp == 0 {
                return Err(format!("reference (bounces {b}) has 0 spp"));
            }
            for p in &r.ladder {
                non_negative(|| format!("ladder rung {} spp seconds", p.spp), p.seconds)?;
                non_negative(|| format!("ladder rung {} spp error", p.spp), p.error)?;
            }
        }
        for t in &self.techniques {
            let l = &t.label;
            non_negative(|| format!("{l}: precomputation seconds"), t.prepare_s)?;
            if let Some(e) = t.stated_error {
                non_negative(|| format!("{l}: stated error"), e)?;
            }
            let f = &t.frame;
            for (kind, f) in std::iter::once(("frame", f))
                .chain(t.still.iter().map(|s| ("still", s)))
                .chain(t.harness.iter().map(|s| ("harness", s)))
            {
                for (name, v) in [("min", f.min_s), ("median", f.median_s), ("max", f.max_s)] {
                    non_negative(|| format!("{l}: {kind} {name} seconds"), v)?;
                }
                if !(f.min_s <= f.median_s && f.median_s <= f.max_s && f.repeats > 0) {
                    return Err(format!(
                        "{l}: {kind} times min {} median {} max {} over {} repeats are not ordered",
                        f.min_s, f.median_s, f.max_s, f.repeats
                    ));
                }
            }
            for e in &t.errors {
                for (m, v) in &e.metrics {
                    if !v.is_finite() || (lower_is_better(m) && *v < 0.0) {
                        return Err(format!(
                            "{l}: {m} (bounces {}) is {v:?}, not a measured value",
                            e.bounces
                        ));
                    }
                }
                let counted = e.pixels_closer.unwrap_or(0) + e.pixels_farther.unwrap_or(0);
                if counted > e.pixels {
                    return Err(format!(
                        "{l}: {counted} pixels closer or farther of {}",
                        e.pixels
                    ));
                }
                if let Some(x) = &e.surface {
                    non_negative(|| format!("{l}: surface error"), x.mean_error)?;
                    if x.pixels > e.pixels || x.bias.iter().any(|b| !b.is_finite() || *b < -1.0) {
                        return Err(format!(
                            "{l}: surface error over {} of {} pixels with bias {:?} is not a measurement",
                            x.pixels, e.pixels, x.bias
                        ));
                    }
                }
                if let Some(q) = &e.equal_error {
                    non_negative(|| format!("{l}: equal-error spp"), q.spp)?;
                    non_negative(|| format!("{l}: equal-error seconds"), q.seconds)?;
                    non_negative(|| format!("{l}: equal-error speedup"), q.speedup)?;
                }
            }
        }
        Ok(())
    }

    /// The camera's name.
    pub fn camera_name(&self) -> String {
        self.camera
            .name
            .clone()
            .unwrap_or_else(|| format!("view{}", self.camera_index))
    }

    /// The result of technique `label`.
    pub fn technique(&self, label: &str) -> Option<&TechniqueResult> {
        self.techniques.iter().find(|t| t.label == label)
    }

    /// The value of `metric` for `label` at `bounces`.
    pub fn error(&self, label: &str, bounces: &str, metric: &str) -> Option<f64> {
        self.technique(label)?
            .errors
            .iter()
            .find(|e| e.bounces == bounces)?
            .metric(metric)
    }
}

/// One technique as the experiment describes it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TechniqueInfo {
    /// Unique label (`dl`, `isr-80`...).
    pub label: String,
    /// Family (`dl`, `isr`...): the rows of Table 2.
    pub family: String,
    /// Parameters in words.
    pub description: String,
}

/// A row of the thesis' Table 2: frame time over all views.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TimeRow {
    /// Technique label, or `reference (bounces N)`.
    pub label: String,
    /// Views rendered.
    pub views: usize,
    /// Total of the per-view median frame times (seconds).
    pub total_s: f64,
    /// Average frame time (milliseconds).
    pub avg_frame_ms: f64,
    /// Average frames per second (`views / total`).
    pub avg_fps: f64,
    /// Precomputation summed over scenes (seconds; 0 for the reference).
    pub prepare_s: f64,
    /// Average still-camera frame time (milliseconds; the same view again), when measured.
    #[serde(default)]
    pub still_frame_ms: Option<f64>,
    /// The clock of the frame times when it is the technique's own device clock (see
    /// [`TechniqueResult::clock`]); `None`: the harness's wall clock.
    #[serde(default)]
    pub clock: Option<String>,
    /// With a device clock: the average of the harness's wall-clock frame times
    /// (milliseconds; G-buffer, method and readback together), labelled as such.
    #[serde(default)]
    pub harness_frame_ms: Option<f64>,
}

/// The thesis' summary statistics of one technique against the baseline at one bounce limit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    /// The technique.
    pub technique: String,
    /// The baseline (DL).
    pub baseline: String,
    /// The reference's bounce limit.
    pub bounces: String,
    /// Views compared.
    pub views: usize,
    /// Share of views where the technique's mean error (eq. 19) is below the baseline's.
    pub share_views_better: f64,
    /// Mean over views of the quality gain `(e_baseline - e_technique) / e_baseline`.
    pub mean_gain: f64,
    /// Mean error of the technique over views.
    pub mean_error: f64,
    /// Mean error of the baseline over views.
    pub baseline_mean_error: f64,
    /// Mean Pearson correlation (eq. 20) of the technique, when the metric was run.
    pub mean_pearson: Option<f64>,
    /// Mean Pearson correlation of the baseline.
    pub baseline_mean_pearson: Option<f64>,
    /// Share of all pixels (over all views) closer to the reference than the baseline's.
    pub share_pixels_closer: f64,
    /// Share of the pixels that differ in distance from the baseline's (ties left out)
    /// where the technique is closer.
    #[serde(default)]
    pub share_changed_pixels_closer: f64,
}

/// One point of the speed-against-error plot of a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpeedErrorPoint {
    /// Technique label.
    pub label: String,
    /// Mean over the scene's views of the median frame time (milliseconds).
    pub frame_ms: f64,
    /// Mean error over the scene's views.
    pub error: f64,
    /// True when no other point is both faster and closer (the Pareto front).
    pub pareto: bool,
}

/// The speed-against-error points of one scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneSpeedError {
    /// Scene id.
    pub scene: String,
    /// Bounce limit of the reference the error is measured against.
    pub bounces: String,
    /// One point per technique.
    pub points: Vec<SpeedErrorPoint>,
}

/// The path tracer at a technique's error, over the views of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EqualErrorRow {
    /// Technique label.
    pub technique: String,
    /// The reference's bounce limit.
    pub bounces: String,
    /// Views with an equal-error point.
    pub views: usize,
    /// Of those, views whose error is closer than the ladder's finest rung (their speedup
    /// is a lower bound, left out of the median).
    pub above_ladder: usize,
    /// Views whose error is farther than the ladder's coarsest rung (an upper bound, left
    /// out of the median).
    #[serde(default)]
    pub below_ladder: usize,
    /// Mean over views of the technique's error.
    pub mean_error: f64,
    /// Median over views of the path tracer's spp at that error.
    pub median_spp: f64,
    /// Mean over views of the path tracer's seconds at that error.
    pub mean_path_tracer_s: f64,
    /// Mean over views of the technique's median frame time (seconds).
    pub mean_frame_s: f64,
    /// Median, over the views the ladder brackets, of the path tracer's seconds at the
    /// technique's error over the technique's (moving-camera) frame time: above 1 the
    /// technique is faster at equal error. `None` when the ladder brackets no view.
    pub speedup: Option<f64>,
    /// When no view is bracketed and every view is above the ladder: the median of their
    /// lower bounds (the median speedup is at least this; shown "> N").
    #[serde(default)]
    pub speedup_at_least: Option<f64>,
    /// Mean over views of the error over lit surfaces, when measured.
    #[serde(default)]
    pub surface_error: Option<f64>,
}

impl EqualErrorRow {
    /// The speedup as shown: a median of measured points, `> N` for a bound, `-` for none.
    pub fn shown(&self) -> String {
        match (self.speedup, self.speedup_at_least) {
            (Some(v), _) => crate::format::fmt_2(v),
            (None, Some(b)) => format!("> {}", crate::format::fmt_2(b)),
            _ => "-".into(),
        }
    }
}

/// A technique's error over lit surfaces on one scene ([`SurfaceError`], averaged over the
/// scene's views).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SurfaceRow {
    /// Technique label.
    pub technique: String,
    /// Scene id.
    pub scene: String,
    /// The reference's bounce limit.
    pub bounces: String,
    /// Views.
    pub views: usize,
    /// Mean over views of the lit-surface mean error.
    pub mean_error: f64,
    /// Mean over views of the whole-image error (the experiment's error metric), beside.
    pub image_error: f64,
    /// Mean over views of the per-channel bias on lit surfaces.
    pub bias: [f64; 3],
    /// The technique's own estimate of its lit-surface error on the scene
    /// ([`TechniqueResult::stated_error`], the scene's first view); `None` when it states
    /// none.
    #[serde(default)]
    pub stated_error: Option<f64>,
}

/// A technique's place in the run's ranking.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RankRow {
    /// 1 for the closest to the reference.
    pub rank: usize,
    /// Technique label.
    pub technique: String,
    /// The bounce limit ranked on (the run's last: unlimited in the default run).
    pub bounces: String,
    /// Mean error over every view at that limit.
    pub mean_error: f64,
    /// Average frame time (milliseconds).
    pub frame_ms: f64,
    /// Precomputation summed over scenes (seconds).
    pub prepare_s: f64,
    /// Scenes where the technique is on the Pareto front at that limit.
    pub pareto_scenes: usize,
    /// Speedup over the path tracer at equal error, when a ladder was run, as shown
    /// ([`EqualErrorRow::shown`]: a median of bracketed views or a bound).
    pub speedup: Option<String>,
    /// Average still-camera frame time (milliseconds), when measured.
    #[serde(default)]
    pub still_frame_ms: Option<f64>,
    /// Mean over views of the error over lit surfaces at that limit.
    #[serde(default)]
    pub surface_error: Option<f64>,
    /// Mean over views of the per-channel bias on lit surfaces at that limit.
    #[serde(default)]
    pub surface_bias: Option<[f64; 3]>,
}

/// Summary of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Table 2: one row per technique, then one per reference bounce limit.
    pub times: Vec<TimeRow>,
    /// Every technique but the baseline against it, per bounce limit.
    pub comparisons: Vec<Comparison>,
    /// Speed against error per scene and bounce limit.
    pub speed_error: Vec<SceneSpeedError>,
    /// The path tracer's spp and time at each technique's error, per bounce limit (empty
    /// without a ladder).
    #[serde(default)]
    pub equal_error: Vec<EqualErrorRow>,
    /// The techniques ranked by mean error at the last bounce limit, closest first.
    #[serde(default)]
    pub ranking: Vec<RankRow>,
    /// Error over lit surfaces per technique, scene and bounce limit.
    #[serde(default)]
    pub surface: Vec<SurfaceRow>,
}

/// The settings of a run, as recorded.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Reference samples per pixel.
    pub spp: u32,
    /// Reference bounce limits.
    pub bounces: Vec<String>,
    /// Reference seed.
    pub seed: u64,
    /// Warm-up frames per view and technique.
    pub warmup: u32,
    /// Timed frames per view and technique (moving camera: each a new view).
    pub repeats: u32,
    /// Timed still-camera frames per view and technique (0: not measured).
    #[serde(default)]
    pub still_repeats: u32,
    /// What rendered the references and the equal-error ladder, in words (empty in
    /// results written before the choice existed: the CPU path tracer).
    #[serde(default)]
    pub reference_renderer: String,
    /// Baseline technique label.
    pub baseline: String,
    /// The metric that decides "closer" (eq. 19).
    pub error_metric: String,
    /// The correlation metric (eq. 20).
    pub correlation_metric: String,
}

/// The content of `results.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Results {
    /// Settings.
    pub settings: RunSettings,
    /// Techniques.
    pub techniques: Vec<TechniqueInfo>,
    /// Metric names.
    pub metrics: Vec<String>,
    /// Every view, in run order.
    pub views: Vec<ViewResult>,
    /// The summary.
    pub summary: Summary,
    /// The relighting sequence, when one was run.
    #[serde(default)]
    pub sequence: Option<crate::sequence::SequenceResult>,
    /// How, when and where the run was made.
    #[serde(default)]
    pub run: RunInfo,
}

impl Results {
    /// Checks a `results.json` read back as input (a results document is generated from it,
    /// shards are merged from it): image size and samples within their stated ranges, at
    /// least one repeat, every view as [`ViewResult::check`] checks it and of a scene of the
    /// run, and no text longer than 4 096 bytes ([`check_text_lengths`]). `lower_is_better(metric)` names the
    /// metrics that are errors (never below 0).
    pub fn check(&self, lower_is_better: &dyn Fn(&str) -> bool) -> Result<(), String> {
        use scene_core::range::{IMAGE_SIDE, SPP, check};
        let s = &self.settings;
        let e = |e: scene_core::range::OutOfRange| e.to_string();
        check("settings.width", s.width, IMAGE_SIDE).map_err(e)?;
        check("settings.height", s.height, IMAGE_SIDE).map_err(e)?;
        check("settings.spp", s.spp, SPP).map_err(e)?;
        check("settings.repeats", s.repeats, 1..=1000).map_err(e)?;
        for v in &self.views {
            if !self.run.scenes.is_empty() && !self.run.scenes.contains(&v.scene) {
                return Err(format!(
                    "view {} / {} is of a scene the run does not list ({})",
                    v.scene,
                    v.camera_index,
                    self.run.scenes.join(", ")
                ));
            }
            v.check(lower_is_better)
                .map_err(|e| format!("view {} / {}: {e}", v.scene, v.camera_index))?;
        }
        non_negative(|| "run.seconds".into(), self.run.seconds)?;
        let value = serde_json::to_value(self).map_err(|e| e.to_string())?;
        check_text_lengths(&value, "results")
    }
}

/// The longest text a results file may hold in one field.
const TEXT_MAX: usize = 4096;

/// Refuses any string in `v` (a results file as JSON) longer than 4 096 bytes (names,
/// labels and the command are short; a document copies them). The error names the field by
/// its JSON path.
pub fn check_text_lengths(v: &serde_json::Value, path: &str) -> Result<(), String> {
    use serde_json::Value;
    match v {
        Value::String(t) if t.len() > TEXT_MAX => {
            Err(format!("{path} is {} bytes long, over {TEXT_MAX}", t.len()))
        }
        Value::Array(a) => a
            .iter()
            .enumerate()
            .try_for_each(|(i, x)| check_text_lengths(x, &format!("{path}[{i}]"))),
        Value::Object(o) => o
            .iter()
            .try_for_each(|(k, x)| check_text_lengths(x, &format!("{path}.{k}"))),
        _ => Ok(()),
    }
}

/// `t` as Markdown shows it as written inside a table or a paragraph: control characters
/// (a line break would end a table row or start a heading) become spaces, `&`, `<` and `>`
/// entities, `|` (a cell border) `\|`, and a backtick that would leave a code span open
/// `` \` `` (a balanced pair is kept: the texts this project writes quote commands so).
pub fn markdown_text(t: &str) -> String {
    let open_span = t.matches('`').count() % 2 == 1;
    let mut o = String::with_capacity(t.len());
    for c in t.chars() {
        match c {
            c if c.is_control() => o.push(' '),
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '|' => o.push_str("\\|"),
            '`' if open_span => o.push_str("\\`"),
            c => o.push(c),
        }
    }
    o
}

impl Results {
    /// The same results with every text (names, labels, the command, notes) passed through
    /// [`markdown_text`], for a document that copies them into Markdown: every copy of a
    /// label changes alike, so lookups by label still match.
    pub fn escaped_for_markdown(&self) -> Results {
        fn walk(v: &mut serde_json::Value) {
            match v {
                serde_json::Value::String(t) => *t = markdown_text(t),
                serde_json::Value::Array(a) => a.iter_mut().for_each(walk),
                serde_json::Value::Object(o) => o.values_mut().for_each(walk),
                _ => {}
            }
        }
        let Ok(mut value) = serde_json::to_value(self) else {
            return self.clone();
        };
        walk(&mut value);
        serde_json::from_value(value).unwrap_or_else(|_| self.clone())
    }
}

/// The current UTC date and minute, `2026-11-25 09:41 UTC` (from the system clock).
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let (days, rest) = ((secs / 86_400) as i64, secs % 86_400);
    // Days since 1970-01-01 to a proleptic Gregorian date, by 400-year eras of 146 097
    // days counted from 0000-03-01 (so the leap day ends a year).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1_460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02} {:02}:{:02} UTC",
        rest / 3600,
        rest % 3600 / 60
    )
}

/// The provenance of a run: what a generated document quotes beside its numbers.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// UTC date and time the run finished (`2026-11-25 09:41 UTC`).
    #[serde(default)]
    pub date: String,
    /// The command that made it.
    #[serde(default)]
    pub command: String,
    /// The preset (`default`, `full`), or empty.
    #[serde(default)]
    pub preset: String,
    /// Worker threads.
    #[serde(default)]
    pub threads: usize,
    /// Wall-clock seconds of the run (of the longest shard for a merged run).
    #[serde(default)]
    pub seconds: f64,
    /// The scenes in run order (views of a merged run are put back in this order).
    #[serde(default)]
    pub scenes: Vec<String>,
    /// The share of the work this run did (`None`: all of it, or a merge of every share).
    #[serde(default)]
    pub shard: Option<crate::run::Shard>,
    /// Shards merged into this result (0: a single run).
    #[serde(default)]
    pub merged_shards: usize,
    /// True when the run was set up with a relighting sequence.
    #[serde(default)]
    pub sequence_expected: bool,
    /// Where the defaults of the methods measured were tuned (held out from these views).
    #[serde(default)]
    pub tuning: Vec<String>,
    /// The content hash of each scene (geometry, materials, lights, cameras), in the order of
    /// `scenes`, as 16 hex digits: [`crate::merge()`] refuses shards made from different
    /// versions of a scene file.
    #[serde(default)]
    pub scene_hashes: Vec<String>,
    /// The version of the tool that made the run ([`tool_version`]): shards of different
    /// versions are not merged.
    #[serde(default)]
    pub tool_version: String,
}

/// This build's version as results record it: the crate's version and the reference
/// tracer's.
pub fn tool_version() -> String {
    format!(
        "bench-harness {} (tracer version {})",
        env!("CARGO_PKG_VERSION"),
        crate::cache::TRACER_VERSION
    )
}

fn mean(v: impl IntoIterator<Item = f64>) -> Option<f64> {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x;
        n += 1;
    }
    (n > 0).then(|| s / n as f64)
}

/// Computes the summary of `views` (see [`Summary`]).
pub fn summarize(
    settings: &RunSettings,
    techniques: &[TechniqueInfo],
    views: &[ViewResult],
) -> Summary {
    let mut times = Vec::new();
    for t in techniques {
        let frames: Vec<f64> = views
            .iter()
            .filter_map(|v| v.technique(&t.label))
            .map(|r| r.frame.median_s)
            .collect();
        // Precomputation once per scene.
        let mut prepare = 0.0;
        let mut seen: Vec<&str> = Vec::new();
        for v in views {
            if !seen.contains(&v.scene.as_str())
                && let Some(r) = v.technique(&t.label)
            {
                seen.push(&v.scene);
                prepare += r.prepare_s;
            }
        }
        let still: Vec<f64> = views
            .iter()
            .filter_map(|v| v.technique(&t.label)?.still.as_ref())
            .map(|s| s.median_s * 1e3)
            .collect();
        let harness: Vec<f64> = views
            .iter()
            .filter_map(|v| v.technique(&t.label)?.harness.as_ref())
            .map(|s| s.median_s * 1e3)
            .collect();
        let mut row = time_row(t.label.clone(), &frames, prepare);
        row.still_frame_ms = mean(still);
        row.harness_frame_ms = mean(harness);
        row.clock = views
            .iter()
            .find_map(|v| v.technique(&t.label)?.clock.clone());
        times.push(row);
    }
    for b in &settings.bounces {
        let frames: Vec<f64> = views
            .iter()
            .filter_map(|v| v.references.iter().find(|r| &r.bounces == b))
            .map(|r| r.seconds)
            .collect();
        times.push(time_row(format!("reference (bounces {b})"), &frames, 0.0));
    }

    let mut comparisons = Vec::new();
    let (em, cm, base) = (
        &settings.error_metric,
        &settings.correlation_metric,
        &settings.baseline,
    );
    for t in techniques.iter().filter(|t| &t.label != base) {
        for b in &settings.bounces {
            let mut pairs = Vec::new();
            let (mut closer, mut farther, mut pixels) = (0u64, 0u64, 0u64);
            for v in views {
                if let (Some(et), Some(eb)) = (v.error(&t.label, b, em), v.error(base, b, em)) {
                    pairs.push((et, eb, v));
                    if let Some(set) = v
                        .technique(&t.label)
                        .and_then(|r| r.errors.iter().find(|e| &e.bounces == b))
                    {
                        closer += set.pixels_closer.unwrap_or(0);
                        farther += set.pixels_farther.unwrap_or(0);
                        pixels += set.pixels;
                    }
                }
            }
            if pairs.is_empty() {
                continue;
            }
            let n = pairs.len();
            comparisons.push(Comparison {
                technique: t.label.clone(),
                baseline: base.clone(),
                bounces: b.clone(),
                views: n,
                share_views_better: pairs.iter().filter(|(et, eb, _)| et < eb).count() as f64
                    / n as f64,
                mean_gain: mean(pairs.iter().map(|(et, eb, _)| gain(*eb, *et))).unwrap_or(0.0),
                mean_error: mean(pairs.iter().map(|p| p.0)).unwrap_or(0.0),
                baseline_mean_error: mean(pairs.iter().map(|p| p.1)).unwrap_or(0.0),
                mean_pearson: mean(
                    pairs
                        .iter()
                        .filter_map(|(_, _, v)| v.error(&t.label, b, cm)),
                ),
                baseline_mean_pearson: mean(
                    pairs.iter().filter_map(|(_, _, v)| v.error(base, b, cm)),
                ),
                share_pixels_closer: if pixels > 0 {
                    closer as f64 / pixels as f64
                } else {
                    0.0
                },
                share_changed_pixels_closer: if closer + farther > 0 {
                    closer as f64 / (closer + farther) as f64
                } else {
                    0.0
                },
            });
        }
    }

    let mut equal_error_rows = Vec::new();
    for t in techniques {
        for b in &settings.bounces {
            let sets: Vec<(&ErrorSet, f64)> = views
                .iter()
                .filter_map(|v| {
                    let r = v.technique(&t.label)?;
                    Some((r.errors.iter().find(|e| &e.bounces == b)?, r.frame.median_s))
                })
                .collect();
            let points: Vec<(f64, EqualError, f64)> = sets
                .iter()
                .filter_map(|(set, f)| Some((set.metric(em)?, set.equal_error?, *f)))
                .collect();
            if points.is_empty() {
                continue;
            }
            let within: Vec<&(f64, EqualError, f64)> = points
                .iter()
                .filter(|p| p.1.bound == LadderBound::Within)
                .collect();
            let above: Vec<f64> = points
                .iter()
                .filter(|p| p.1.bound == LadderBound::AboveFinest)
                .map(|p| p.1.speedup.min(f64::MAX))
                .collect();
            let median = |v: Vec<f64>| Timing::from_samples(&v).median_s;
            let speedup = (!within.is_empty())
                .then(|| median(within.iter().map(|p| p.1.speedup.min(f64::MAX)).collect()));
            equal_error_rows.push(EqualErrorRow {
                technique: t.label.clone(),
                bounces: b.clone(),
                views: points.len(),
                above_ladder: above.len(),
                below_ladder: points
                    .iter()
                    .filter(|p| p.1.bound == LadderBound::BelowCoarsest)
                    .count(),
                mean_error: mean(points.iter().map(|p| p.0)).unwrap_or(0.0),
                median_spp: median(within.iter().map(|p| p.1.spp).collect()),
                mean_path_tracer_s: mean(within.iter().map(|p| p.1.seconds)).unwrap_or(0.0),
                mean_frame_s: mean(points.iter().map(|p| p.2)).unwrap_or(0.0),
                speedup,
                speedup_at_least: (speedup.is_none() && above.len() == points.len())
                    .then(|| median(above)),
                surface_error: mean(
                    sets.iter()
                        .filter_map(|(s, _)| s.surface.map(|x| x.mean_error)),
                ),
            });
        }
    }

    let mut speed_error = Vec::new();
    for b in &settings.bounces {
        let mut scenes: Vec<&str> = Vec::new();
        for v in views {
            if !scenes.contains(&v.scene.as_str()) {
                scenes.push(&v.scene);
            }
        }
        for s in scenes {
            let sv: Vec<&ViewResult> = views.iter().filter(|v| v.scene == s).collect();
            let mut points: Vec<SpeedErrorPoint> = techniques
                .iter()
                .filter_map(|t| {
                    let frame = mean(
                        sv.iter()
                            .filter_map(|v| v.technique(&t.label))
                            .map(|r| r.frame.median_s * 1e3),
                    )?;
                    let error = mean(sv.iter().filter_map(|v| v.error(&t.label, b, em)))?;
                    Some(SpeedErrorPoint {
                        label: t.label.clone(),
                        frame_ms: frame,
                        error,
                        pareto: false,
                    })
                })
                .collect();
            mark_pareto(&mut points);
            speed_error.push(SceneSpeedError {
                scene: s.to_string(),
                bounces: b.clone(),
                points,
            });
        }
    }
    let surface_of = |label: &str, b: &str, vs: &mut dyn Iterator<Item = &ViewResult>| {
        let sets: Vec<SurfaceError> = vs
            .filter_map(|v| {
                v.technique(label)?
                    .errors
                    .iter()
                    .find(|e| e.bounces == b)?
                    .surface
            })
            .collect();
        let n = sets.len();
        (n > 0).then(|| {
            (
                n,
                sets.iter().map(|x| x.mean_error).sum::<f64>() / n as f64,
                std::array::from_fn::<f64, 3, _>(|c| {
                    sets.iter().map(|x| x.bias[c]).sum::<f64>() / n as f64
                }),
            )
        })
    };
    let mut surface = Vec::new();
    for t in techniques {
        for b in &settings.bounces {
            let mut scenes: Vec<&str> = Vec::new();
            for v in views {
                if !scenes.contains(&v.scene.as_str()) {
                    scenes.push(&v.scene);
                }
            }
            for sc in scenes {
                let Some((n, e, bias)) =
                    surface_of(&t.label, b, &mut views.iter().filter(|v| v.scene == sc))
                else {
                    continue;
                };
                surface.push(SurfaceRow {
                    technique: t.label.clone(),
                    scene: sc.to_string(),
                    bounces: b.clone(),
                    views: n,
                    mean_error: e,
                    image_error: mean(
                        views
                            .iter()
                            .filter(|v| v.scene == sc)
                            .filter_map(|v| v.error(&t.label, b, em)),
                    )
                    .unwrap_or(0.0),
                    bias,
                    stated_error: views
                        .iter()
                        .filter(|v| v.scene == sc)
                        .find_map(|v| v.technique(&t.label)?.stated_error),
                });
            }
        }
    }
    let mut ranking = Vec::new();
    if let Some(b) = settings.bounces.last() {
        for t in techniques {
            let Some(e) = mean(views.iter().filter_map(|v| v.error(&t.label, b, em))) else {
                continue;
            };
            let row = times.iter().find(|r| r.label == t.label);
            let surf = surface_of(&t.label, b, &mut views.iter());
            ranking.push(RankRow {
                rank: 0,
                technique: t.label.clone(),
                bounces: b.clone(),
                mean_error: e,
                frame_ms: row.map(|r| r.avg_frame_ms).unwrap_or(0.0),
                prepare_s: row.map(|r| r.prepare_s).unwrap_or(0.0),
                pareto_scenes: speed_error
                    .iter()
                    .filter(|s| &s.bounces == b)
                    .filter(|s| s.points.iter().any(|p| p.label == t.label && p.pareto))
                    .count(),
                speedup: equal_error_rows
                    .iter()
                    .find(|r| r.technique == t.label && &r.bounces == b)
                    .map(|r| r.shown()),
                still_frame_ms: row.and_then(|r| r.still_frame_ms),
                surface_error: surf.map(|x| x.1),
                surface_bias: surf.map(|x| x.2),
            });
        }
        ranking.sort_by(|a, b| a.mean_error.total_cmp(&b.mean_error));
        for (i, r) in ranking.iter_mut().enumerate() {
            r.rank = i + 1;
        }
    }
    Summary {
        times,
        comparisons,
        speed_error,
        equal_error: equal_error_rows,
        ranking,
        surface,
    }
}

/// When technique A (precomputation `prepare_a` seconds, `frame_a` seconds a frame) costs
/// less in total than technique B over `N` frames of one scene: `prepare + N frame`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BreakEven {
    /// A is never dearer (no more precomputation, frames no slower).
    Always,
    /// A is never cheaper (no less precomputation, frames no faster).
    Never,
    /// A's faster frames pay for its longer precomputation after this many frames.
    After(f64),
    /// A's shorter precomputation keeps it cheaper for this many frames only.
    Until(f64),
}

/// [`BreakEven`] of A against B.
pub fn break_even(prepare_a: f64, frame_a: f64, prepare_b: f64, frame_b: f64) -> BreakEven {
    let (dp, df) = (prepare_a - prepare_b, frame_b - frame_a);
    if dp <= 0.0 && df >= 0.0 {
        BreakEven::Always
    } else if dp >= 0.0 && df <= 0.0 {
        BreakEven::Never
    } else if df > 0.0 {
        BreakEven::After(dp / df)
    } else {
        BreakEven::Until(dp / df)
    }
}

/// The thesis' quality gain `(e_baseline - e) / e_baseline` (0 when the baseline is exact).
pub fn gain(baseline_error: f64, error: f64) -> f64 {
    if baseline_error > 0.0 {
        (baseline_error - error) / baseline_error
    } else {
        0.0
    }
}

fn time_row(label: String, frames: &[f64], prepare_s: f64) -> TimeRow {
    let total: f64 = frames.iter().sum();
    let n = frames.len();
    TimeRow {
        label,
        views: n,
        total_s: total,
        avg_frame_ms: if n > 0 { total / n as f64 * 1e3 } else { 0.0 },
        avg_fps: if total > 0.0 { n as f64 / total } else { 0.0 },
        prepare_s,
        still_frame_ms: None,
        clock: None,
        harness_frame_ms: None,
    }
}

/// Marks the points no other point dominates (at most as slow and at most as wrong, and
/// better in one of the two).
pub fn mark_pareto(points: &mut [SpeedErrorPoint]) {
    let snapshot: Vec<(f64, f64)> = points.iter().map(|p| (p.frame_ms, p.error)).collect();
    for p in points.iter_mut() {
        p.pareto = !snapshot
            .iter()
            .any(|&(t, e)| t <= p.frame_ms && e <= p.error && (t < p.frame_ms || e < p.error));
    }
}

#[cfg(test)]
mod break_even_tests {
    use super::*;

    fn frames(b: BreakEven) -> f64 {
        match b {
            BreakEven::After(n) | BreakEven::Until(n) => n,
            _ => f64::NAN,
        }
    }

    #[test]
    fn break_even_frames_follow_from_precomputation_and_frame_time() {
        // 20 s of precomputation and 2 ms frames against none and 12 ms: 2000 frames, as
        // 20 + 2000 x 0.002 = 2000 x 0.012.
        let a = break_even(20.0, 0.002, 0.0, 0.012);
        assert!(
            matches!(a, BreakEven::After(_)) && (frames(a) - 2000.0).abs() < 1e-6,
            "{a:?}"
        );
        let b = break_even(0.0, 0.012, 20.0, 0.002);
        assert!(
            matches!(b, BreakEven::Until(_)) && (frames(b) - 2000.0).abs() < 1e-6,
            "{b:?}"
        );
        assert_eq!(break_even(0.0, 0.001, 1.0, 0.002), BreakEven::Always);
        assert_eq!(break_even(1.0, 0.002, 0.0, 0.001), BreakEven::Never);
        assert_eq!(break_even(1.0, 0.001, 1.0, 0.001), BreakEven::Always);
    }
}
