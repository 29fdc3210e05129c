//! An experiment: scenes x cameras x techniques x metrics, run view by view with resume.

use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use scene_core::reference::{Bounces, PathTracer, PixelClass, ReferenceSettings};

use scene_core::{Camera, FrameRequest, Image, LightState, Metric};

use crate::HarnessError;
use crate::cache::{Fnv, ReferenceCache, scene_hash};
use crate::cameras::CameraSpec;
use crate::results::{
    ErrorSet, LadderPoint, ReferenceResult, Results, RunInfo, RunSettings, TechniqueInfo,
    TechniqueResult, Timing, ViewResult, summarize,
};
pub use crate::run::{
    ExperimentSettings, SceneSetup, SequenceSpec, Shard, TechniqueSetup, default_ladder,
    ladder_seed, neighbour, slug, view_dir,
};
use crate::sequence::{SequenceResult, SequenceSettings};

/// Version of the per-view result format; views written by another version are recomputed.
pub const RESULTS_VERSION: u64 = 4;

/// What a run did.
#[derive(Clone, Debug)]
pub struct RunOutcome {
    /// The results (every finished view, this run's and resumed ones).
    pub results: Results,
    /// Views computed by this run.
    pub views_computed: usize,
    /// Views taken from an earlier run's per-view files.
    pub views_resumed: usize,
    /// `Technique::render` calls made by this run.
    pub technique_renders: u64,
    /// Reference images rendered by this run (the others came from the cache).
    pub reference_renders: u64,
    /// True when the run stopped early ([`ExperimentSettings::stop_after_views`]).
    pub interrupted: bool,
    /// `results.json`.
    pub results_json: PathBuf,
    /// `report.md` (not written when interrupted).
    pub report_md: PathBuf,
    /// `report.html` (not written when interrupted).
    pub report_html: PathBuf,
    /// Wall-clock seconds of the run.
    pub seconds: f64,
}

/// Scenes x cameras x techniques x metrics.
pub struct Experiment {
    /// Settings.
    pub settings: ExperimentSettings,
    /// Scenes with their cameras.
    pub scenes: Vec<SceneSetup>,
    /// Techniques (labels unique; one must be the baseline).
    pub techniques: Vec<TechniqueSetup>,
    /// Metrics (must include the error metric).
    pub metrics: Vec<Box<dyn Metric>>,
}

/// The top of the error maps' colour scale, as a share of the reference's mean value.
pub const ERROR_MAP_TOP: f32 = 0.5;

/// The error map of `test` against `reference`: per pixel the distance (sum over channels of
/// the absolute difference) over three times the reference's mean channel value, so that
/// [`ERROR_MAP_TOP`] (and above) is an error of half the image's mean, through the viridis
/// colour map (perceptually uniform). Linear RGB, so the PNG shows viridis' colours.
pub fn error_map(reference: &Image, test: &Image) -> Image {
    let mut out = Image::new(reference.width, reference.height);
    let mean = reference.mean().element_sum() / 3.0;
    let scale = if mean > 0.0 && mean.is_finite() {
        1.0 / (3.0 * mean * ERROR_MAP_TOP)
    } else {
        0.0
    };
    let lin = scene_core::image::srgb_to_linear;
    for ((o, r), t) in out
        .pixels
        .iter_mut()
        .zip(&reference.pixels)
        .zip(&test.pixels)
    {
        let d = (*r - *t).abs().element_sum() * scale;
        let d = if d.is_finite() { d } else { 1.0 };
        let [cr, cg, cb] = crate::plots::viridis(f64::from(d));
        *o = scene_core::glam::Vec3::new(
            lin(f32::from(cr) / 255.0),
            lin(f32::from(cg) / 255.0),
            lin(f32::from(cb) / 255.0),
        );
    }
    out
}

/// A bar drawn through `multi` when shown (never under `CI`), hidden otherwise.
fn bar(multi: &MultiProgress, show: bool, len: u64, template: &str, msg: String) -> ProgressBar {
    let b = if show && std::env::var_os("CI").is_none() {
        multi.add(ProgressBar::new(len))
    } else {
        ProgressBar::hidden()
    };
    b.set_style(
        ProgressStyle::with_template(template)
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    b.set_message(msg);
    b
}

/// Per-pixel distance `sum_c |a - b|` (the thesis' pixel-level comparison).
fn pixel_distance(a: glam::Vec3, b: glam::Vec3) -> f32 {
    (a - b).abs().element_sum()
}

/// `|reference - test|` per channel.
pub fn difference(reference: &Image, test: &Image) -> Image {
    Image {
        width: reference.width,
        height: reference.height,
        pixels: reference
            .pixels
            .iter()
            .zip(&test.pixels)
            .map(|(r, t)| (*r - *t).abs())
            .collect(),
    }
}

impl Experiment {
    fn run_settings(&self) -> RunSettings {
        let s = &self.settings;
        RunSettings {
            width: s.width,
            height: s.height,
            spp: s.spp,
            bounces: s.bounces.iter().map(|b| b.to_string()).collect(),
            seed: s.seed,
            warmup: s.warmup,
            repeats: s.repeats,
            still_repeats: s.still_repeats,
            reference_renderer: self.reference_renderer().describe(),
            baseline: s.baseline.clone(),
            error_metric: s.error_metric.clone(),
            correlation_metric: s.correlation_metric.clone(),
        }
    }

    /// What renders the references and the ladder.
    fn reference_renderer(&self) -> std::sync::Arc<dyn crate::ReferenceRenderer> {
        self.settings
            .reference_renderer
            .clone()
            .unwrap_or_else(|| std::sync::Arc::new(crate::CpuReference))
    }

    fn infos(&self) -> Vec<TechniqueInfo> {
        self.techniques
            .iter()
            .map(|t| TechniqueInfo {
                label: t.label.clone(),
                family: t.family.clone(),
                description: t.description.clone(),
            })
            .collect()
    }

    /// The fingerprint a per-view file must carry to be reused.
    fn config_key(&self, scene_hash: u64) -> String {
        let s = &self.settings;
        let mut h = Fnv::default();
        // The tracer's version too: a view saved against another path tracer's references
        // (whose noise, ladder and equal-error figures differ) is measured again.
        h.u64(RESULTS_VERSION)
            .u64(u64::from(crate::cache::TRACER_VERSION))
            .u64(scene_hash)
            .u64(s.width as u64)
            .u64(s.height as u64)
            .u64(s.spp as u64)
            .u64(s.seed)
            .u64(s.warmup as u64)
            .u64(s.repeats as u64)
            .u64(s.still_repeats as u64)
            .u64(s.ladder_extend as u64)
            .str(&s.baseline)
            .str(&s.error_metric)
            .str(self.reference_renderer().key_tag());
        for b in &s.bounces {
            h.str(&b.to_string());
        }
        for n in &s.ladder_spp {
            h.u64(u64::from(*n));
        }
        for t in &self.techniques {
            h.str(&t.label)
                .str(&t.description)
                .u64(t.single_frame as u64);
        }
        for m in &self.metrics {
            h.str(m.name());
        }
        format!("{:016x}", h.finish())
    }

    fn validate(&self) -> Result<(), HarnessError> {
        let s = &self.settings;
        if s.width == 0 || s.height == 0 || s.spp == 0 || s.repeats == 0 {
            return Err(HarnessError::Invalid(format!(
                "size, spp and repeats must be positive (got {}x{}, {} spp, {} repeats)",
                s.width, s.height, s.spp, s.repeats
            )));
        }
        if s.bounces.is_empty() {
            return Err(HarnessError::Invalid("no reference bounce limit".into()));
        }
        let mut labels: Vec<&str> = Vec::new();
        for t in &self.techniques {
            if labels.contains(&t.label.as_str()) {
                return Err(HarnessError::Invalid(format!(
                    "technique label '{}' appears twice",
                    t.label
                )));
            }
            labels.push(&t.label);
        }
        if !labels.contains(&s.baseline.as_str()) {
            return Err(HarnessError::Invalid(format!(
                "the baseline '{}' is not among the techniques ({})",
                s.baseline,
                labels.join(", ")
            )));
        }
        if !self.metrics.iter().any(|m| m.name() == s.error_metric) {
            return Err(HarnessError::Invalid(format!(
                "the error metric '{}' is not among the metrics",
                s.error_metric
            )));
        }
        for sc in &self.scenes {
            if sc.cameras.is_empty() {
                return Err(HarnessError::Invalid(format!(
                    "scene '{}' has no camera",
                    sc.id
                )));
            }
        }
        Ok(())
    }

    /// Runs the experiment: every view not already finished (a per-view file in
    /// `<out>/views/` with the same settings) is computed and its file written as soon as it
    /// is done; then `results.json`, `report.md` and `report.html` are written from all views.
    pub fn run(&mut self) -> Result<RunOutcome, HarnessError> {
        self.validate()?;
        let start = Instant::now();
        let out = self.settings.out_dir.clone();
        let views_dir = out.join("views");
        std::fs::create_dir_all(&views_dir).map_err(|e| HarnessError::io(&views_dir, e))?;
        let cache = ReferenceCache::with_renderer(
            self.settings
                .cache_dir
                .clone()
                .unwrap_or_else(|| out.join("reference-cache")),
            self.reference_renderer(),
        );
        let total_views: usize = self.scenes.iter().map(|s| s.cameras.len()).sum();
        let multi = MultiProgress::new();
        let views_bar = bar(
            &multi,
            self.settings.progress,
            total_views as u64,
            "{msg:30} [{bar:30}] {pos}/{len} views, eta {eta}",
            "experiment".into(),
        );
        let mut outcome_views = Vec::new();
        let (mut computed, mut resumed, mut renders, mut ref_renders) =
            (0usize, 0usize, 0u64, 0u64);
        let mut interrupted = false;
        let scenes = std::mem::take(&mut self.scenes);
        let shard = self.settings.shard;
        let mut job = 0usize;
        let mut last_prepared: Option<(String, Vec<f64>)> = None;
        let result = (|| -> Result<(), HarnessError> {
            for sc in &scenes {
                let hash = scene_hash(&sc.scene);
                let config = self.config_key(hash);
                let mut prepared: Option<Vec<f64>> = None;
                let mut tracer: Option<PathTracer<'_>> = None;
                for (ci, camera) in sc.cameras.iter().enumerate() {
                    job += 1;
                    if shard.is_some_and(|k| !k.owns(job - 1)) {
                        continue;
                    }
                    let file = views_dir.join(format!(
                        "{}--{ci:02}-{}.json",
                        slug(&sc.id),
                        slug(&camera.name)
                    ));
                    let lower_is_better = |name: &str| {
                        self.metrics
                            .iter()
                            .any(|m| m.name() == name && m.lower_is_better())
                    };
                    if let Some(v) = read_view(&file, &config, camera, &lower_is_better) {
                        outcome_views.push(v);
                        resumed += 1;
                        views_bar.inc(1);
                        continue;
                    }
                    if let Some(limit) = self.settings.stop_after_views
                        && computed >= limit
                    {
                        interrupted = true;
                        return Ok(());
                    }
                    views_bar.set_message(format!("{} / {}", sc.id, camera.name));
                    // Precomputation once per scene, timed apart from the frames.
                    if prepared.is_none() {
                        let mut times = Vec::new();
                        for t in &mut self.techniques {
                            views_bar.set_message(format!("{}: preparing {}", sc.id, t.label));
                            let t0 = Instant::now();
                            t.technique.prepare(sc.scene.clone()).map_err(|e| {
                                HarnessError::Technique {
                                    label: t.label.clone(),
                                    scene: sc.id.clone(),
                                    source: Box::new(e),
                                }
                            })?;
                            times.push(t0.elapsed().as_secs_f64());
                        }
                        last_prepared = Some((sc.id.clone(), times.clone()));
                        prepared = Some(times);
                    }
                    let prepare_times = prepared.clone().unwrap_or_default();
                    let tracer = tracer.get_or_insert_with(|| PathTracer::new(&sc.scene));
                    let (view, n_renders, n_refs) = self.run_view(
                        sc,
                        hash,
                        ci,
                        camera,
                        &config,
                        &prepare_times,
                        &cache,
                        tracer,
                        &out,
                        (&multi, &views_bar),
                    )?;
                    renders += n_renders;
                    ref_renders += n_refs;
                    crate::write_json(&file, &view)?;
                    outcome_views.push(view);
                    computed += 1;
                    views_bar.inc(1);
                }
            }
            Ok(())
        })();
        self.scenes = scenes;
        views_bar.finish_and_clear();
        result?;
        // The sequence is the last job.
        let sequence = if interrupted || shard.is_some_and(|k| !k.owns(job)) {
            None
        } else {
            self.sequence(&cache, &views_dir, &out, &mut renders, last_prepared)?
        };

        let settings = self.run_settings();
        let infos = self.infos();
        let summary = summarize(&settings, &infos, &outcome_views);
        let results = Results {
            settings,
            techniques: infos,
            metrics: self.metrics.iter().map(|m| m.name().to_string()).collect(),
            views: outcome_views,
            summary,
            sequence,
            run: RunInfo {
                scenes: self.scenes.iter().map(|s| s.id.clone()).collect(),
                scene_hashes: self
                    .scenes
                    .iter()
                    .map(|s| format!("{:016x}", scene_hash(&s.scene)))
                    .collect(),
                tool_version: crate::results::tool_version(),
                shard,
                sequence_expected: self.settings.sequence.is_some(),
                seconds: start.elapsed().as_secs_f64(),
                date: crate::results::utc_now(),
                ..self.settings.run_info.clone()
            },
        };
        let results_json = out.join("results.json");
        let report_md = out.join("report.md");
        let report_html = out.join("report.html");
        crate::write_json(&results_json, &results)?;
        if !interrupted && shard.is_none() {
            let headline = self.settings.headline.clone().or_else(|| {
                self.techniques
                    .iter()
                    .find(|t| t.label != self.settings.baseline)
                    .map(|t| t.label.clone())
            });
            write_text(
                &report_md,
                &crate::report::markdown(&results, headline.as_deref()),
            )?;
            write_text(
                &report_html,
                &crate::report::html(&results, headline.as_deref(), &out),
            )?;
        }
        Ok(RunOutcome {
            results,
            views_computed: computed,
            views_resumed: resumed,
            technique_renders: renders,
            reference_renders: ref_renders,
            interrupted,
            results_json,
            report_md,
            report_html,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Runs the relighting sequence, or reads it back from `views/sequence.json` when the
    /// settings are unchanged.
    fn sequence(
        &mut self,
        cache: &ReferenceCache,
        views_dir: &Path,
        out: &Path,
        renders: &mut u64,
        last_prepared: Option<(String, Vec<f64>)>,
    ) -> Result<Option<SequenceResult>, HarnessError> {
        let Some(spec) = self.settings.sequence.clone() else {
            return Ok(None);
        };
        let Some(sc) = self.scenes.iter().find(|s| s.id == spec.scene) else {
            return Err(HarnessError::Invalid(format!(
                "the sequence's scene '{}' is not in the run",
                spec.scene
            )));
        };
        let Some(camera) = sc.cameras.get(spec.camera).cloned() else {
            return Err(HarnessError::Invalid(format!(
                "the sequence's camera {} does not exist ({} camera(s) in '{}')",
                spec.camera,
                sc.cameras.len(),
                spec.scene
            )));
        };
        let scene = sc.scene.clone();
        let hash = scene_hash(&scene);
        let config = format!(
            "{}-{}-{}-{}-{}-{}",
            self.config_key(hash),
            spec.scene,
            spec.camera,
            spec.frames,
            spec.spp,
            spec.bounces
        );
        let file = views_dir.join("sequence.json");
        if let Ok(bytes) = scene_core::budget::read_file(&file, &scene_core::Budget::default())
            && let Ok(saved) = serde_json::from_slice::<SavedSequence>(&bytes)
            && saved.config == config
        {
            match saved.result.check() {
                Ok(()) => return Ok(Some(saved.result)),
                Err(why) => eprintln!(
                    "note: resume file {}: {why}; measuring the sequence again",
                    file.display()
                ),
            }
        }
        let Some(metric) = self
            .metrics
            .iter()
            .find(|m| m.name() == self.settings.error_metric)
        else {
            return Ok(None);
        };
        let frames = crate::sequence::light_sequence(&scene, spec.frames);
        // The techniques are still prepared for the sequence's scene when it was the last
        // scene of the views: reuse that precomputation (and its times).
        let prepared = last_prepared
            .filter(|(id, _)| *id == spec.scene)
            .map(|(_, times)| times);
        if self.settings.progress {
            eprintln!(
                "relighting sequence: {} frames on {} / {}, {} technique(s) {}, a {}-spp \
                 reference per frame",
                frames.len(),
                spec.scene,
                camera.name,
                self.techniques.len(),
                if prepared.is_some() {
                    "as prepared for the views"
                } else {
                    "prepared again"
                },
                spec.spp
            );
        }
        let settings = SequenceSettings {
            width: self.settings.width,
            height: self.settings.height,
            spp: spec.spp,
            bounces: spec.bounces,
            seed: self.settings.seed,
        };
        let images = out.join("sequence");
        let result = crate::sequence::run_sequence(
            &spec.scene,
            &scene,
            Some(hash),
            &camera,
            &mut self.techniques,
            metric.as_ref(),
            &frames,
            &settings,
            cache,
            Some(&images),
            prepared.as_deref(),
        )?;
        *renders += (self.techniques.len() * (frames.len() + 1)) as u64;
        crate::write_json(
            &file,
            &SavedSequence {
                config,
                result: result.clone(),
            },
        )?;
        Ok(Some(result))
    }

    /// The equal-error ladder of one view at bounce limit `b`: the path tracer at each
    /// ladder spp below the reference's, with the ladder seed, measured against `reference`
    /// by the error metric. Returns the rungs and the number of renders made (not cached).
    #[allow(clippy::too_many_arguments)]
    fn ladder(
        &self,
        sc: &SceneSetup,
        hash: u64,
        cam: &Camera,
        b: Bounces,
        reference: &Image,
        cache: &ReferenceCache,
        spps: &[u32],
    ) -> Result<(Vec<LadderPoint>, u64), HarnessError> {
        let s = &self.settings;
        let Some(metric) = self.metrics.iter().find(|m| m.name() == s.error_metric) else {
            return Ok((Vec::new(), 0));
        };
        let mut rungs = Vec::new();
        let mut renders = 0;
        for &spp in spps.iter().filter(|&&n| n > 0 && n < s.spp) {
            let rs = ReferenceSettings {
                width: s.width,
                height: s.height,
                spp,
                bounces: b,
                seed: ladder_seed(s.seed),
            };
            let r = cache.get_or_render(&sc.scene, hash, cam, &rs, None)?;
            renders += u64::from(!r.from_cache);
            let v = metric
                .compare(reference, &r.image)
                .map_err(|e| HarnessError::Metric {
                    name: metric.name().to_string(),
                    source: Box::new(e),
                })?;
            rungs.push(LadderPoint {
                spp,
                seconds: r.seconds,
                error: v.value,
            });
        }
        Ok((rungs, renders))
    }

    #[allow(clippy::too_many_arguments)]
    fn run_view(
        &mut self,
        sc: &SceneSetup,
        hash: u64,
        ci: usize,
        camera: &Camera,
        config: &str,
        prepare_times: &[f64],
        cache: &ReferenceCache,
        tracer: &PathTracer<'_>,
        out: &Path,
        (multi, views_bar): (&MultiProgress, &ProgressBar),
    ) -> Result<(ViewResult, u64, u64), HarnessError> {
        let s = self.settings.clone();
        let cam = camera.with_aspect(s.width as f32 / s.height as f32);
        let dir_rel = view_dir(&sc.id, ci, &camera.name);
        let dir = out.join(&dir_rel);
        std::fs::create_dir_all(&dir).map_err(|e| HarnessError::io(&dir, e))?;
        // References.
        let mut references = Vec::new();
        let mut ref_images = Vec::new();
        let mut ref_renders = 0;
        for b in &s.bounces {
            let rs = ReferenceSettings {
                width: s.width,
                height: s.height,
                spp: s.spp,
                bounces: *b,
                seed: s.seed,
            };
            let rows = bar(
                multi,
                s.progress && !views_bar.is_hidden(),
                s.height as u64,
                "{msg:30} [{bar:30}] {pos}/{len} rows",
                format!("reference, bounces {b}"),
            );
            let report = |done: u64, _total: u64| rows.set_position(done);
            let r = cache.get_or_render(&sc.scene, hash, &cam, &rs, Some(&report))?;
            rows.finish_and_clear();
            multi.remove(&rows);
            if !r.from_cache {
                ref_renders += 1;
            }
            let stem = format!("reference-b{b}");
            write_image(&dir, &stem, &r.image, s.exposure, true)?;
            let ladder = self.ladder(sc, hash, &cam, *b, &r.image, cache, &s.ladder_spp)?;
            ref_renders += ladder.1;
            references.push(ReferenceResult {
                bounces: b.to_string(),
                spp: s.spp,
                seconds: r.seconds,
                key: format!("{:016x}", r.key),
                ladder: ladder.0,
            });
            ref_images.push(r.image);
        }
        // Techniques: warm-up on neighbours of the view, then timed moving-camera frames
        // (the view itself first, then neighbours: every one new to the technique), then
        // timed still-camera frames (the view again). The view's first frame is measured.
        let mut renders = 0;
        let mut images = Vec::new();
        let mut results = Vec::new();
        let (w, h) = (s.width, s.height);
        for (ti, t) in self.techniques.iter_mut().enumerate() {
            let fail = |e| HarnessError::Technique {
                label: t.label.clone(),
                scene: sc.id.clone(),
                source: Box::new(e),
            };
            let lights = LightState::default();
            // Each frame's time: the technique's own device time when it measures one (the
            // harness's wall time of the whole render kept beside it), else the wall time.
            let mut clock = None;
            let mut walls = Vec::new();
            let mut frame = |c: &Camera| -> Result<(Image, f64), HarnessError> {
                let t0 = Instant::now();
                let img = t
                    .technique
                    .render(&FrameRequest::from_camera(c, w, h, &lights))
                    .map_err(fail)?;
                let wall = t0.elapsed().as_secs_f64();
                renders += 1;
                walls.push(wall);
                Ok(match t.technique.device_time() {
                    Some(d) => {
                        clock = Some(d.clock);
                        (img, d.seconds)
                    }
                    None => (img, wall),
                })
            };
            let (warmup, repeats, still) = if t.single_frame {
                (0, 1, 0)
            } else {
                (s.warmup, s.repeats, s.still_repeats)
            };
            // Neighbours 1..=warmup warm up; warmup+1.. are the moving frames' others.
            for k in 0..warmup {
                frame(&neighbour(&cam, 1 + k))?;
            }
            let (img, first) = frame(&cam)?;
            let mut moving = vec![first];
            for k in 1..repeats {
                moving.push(frame(&neighbour(&cam, warmup + k))?.1);
            }
            let mut still_samples = Vec::new();
            for _ in 0..still {
                still_samples.push(frame(&cam)?.1);
            }
            // The harness's wall times of the moving-camera frames (after the warm-up).
            let moving_walls = &walls[warmup as usize..(warmup + repeats) as usize];
            let harness = clock.map(|_| Timing::from_samples(moving_walls));
            if img.width != s.width || img.height != s.height {
                return Err(HarnessError::Invalid(format!(
                    "technique '{}' returned {}x{} for {}x{}",
                    t.label, img.width, img.height, s.width, s.height
                )));
            }
            write_image(&dir, &slug(&t.label), &img, s.exposure, s.write_images)?;
            results.push(TechniqueResult {
                label: t.label.clone(),
                prepare_s: prepare_times.get(ti).copied().unwrap_or(0.0),
                frame: Timing::from_samples(&moving),
                still: (!still_samples.is_empty()).then(|| Timing::from_samples(&still_samples)),
                clock: clock.map(|c| c.describe().to_string()),
                harness,
                errors: Vec::new(),
                stated_error: t.technique.stated_error(),
            });
            images.push(img);
        }
        // The lit-surface mask of each reference (what the pixel centres see, less the
        // reference's brightest 1%).
        let surface: Vec<bool> = tracer
            .pixel_classes(&scene_core::View::from_camera(&cam), w, h)
            .into_iter()
            .map(|c| c == PixelClass::Surface)
            .collect();
        let masks: Vec<Vec<bool>> = ref_images
            .iter()
            .map(|r| crate::results::surface_mask(&surface, r))
            .collect();
        // Errors against every reference, and the pixel comparison with the baseline.
        let base = self
            .techniques
            .iter()
            .position(|t| t.label == s.baseline)
            .unwrap_or(0);
        for (ri, (b, reference)) in s.bounces.iter().zip(&ref_images).enumerate() {
            for (ti, img) in images.iter().enumerate() {
                let mut metrics = Vec::new();
                for m in &self.metrics {
                    let v = m
                        .compare(reference, img)
                        .map_err(|e| HarnessError::Metric {
                            name: m.name().to_string(),
                            source: Box::new(e),
                        })?;
                    metrics.push((m.name().to_string(), v.value));
                }
                let (closer, farther) = if ti == base {
                    (None, None)
                } else {
                    let (mut c, mut f) = (0u64, 0u64);
                    for ((r, t), d) in reference
                        .pixels
                        .iter()
                        .zip(&img.pixels)
                        .zip(&images[base].pixels)
                    {
                        let (dt, db) = (pixel_distance(*r, *t), pixel_distance(*r, *d));
                        if dt < db {
                            c += 1;
                        } else if dt > db {
                            f += 1;
                        }
                    }
                    (Some(c), Some(f))
                };
                let label = &results[ti].label;
                error_map(reference, img)
                    .write_png(&dir.join(format!("errmap-{}-b{b}.png", slug(label))), 0.0)
                    .map_err(|e| HarnessError::from(scene_core::Error::from(e)))?;
                let diff = difference(reference, img);
                // Difference images: every one when asked, the gallery's always.
                write_image(
                    &dir,
                    &format!("diff-{}-b{b}", slug(label)),
                    &diff,
                    s.exposure + 3.0,
                    s.write_images || ri == 0,
                )?;
                results[ti].errors.push(ErrorSet {
                    bounces: b.to_string(),
                    metrics,
                    pixels_closer: closer,
                    pixels_farther: farther,
                    pixels: reference.pixels.len() as u64,
                    equal_error: None,
                    surface: crate::results::surface_error(reference, img, &masks[ri]),
                });
            }
        }
        // The ladder extended until it brackets every technique's error (or reaches half
        // the reference's spp), then each technique's point on it.
        for (ri, (b, reference)) in s.bounces.iter().zip(&ref_images).enumerate() {
            let error = |r: &TechniqueResult| r.errors[ri].metric(&s.error_metric);
            let closest = results
                .iter()
                .filter_map(error)
                .filter(|e| *e > 0.0)
                .fold(f64::INFINITY, f64::min);
            while s.ladder_extend && !references[ri].ladder.is_empty() {
                let finest = *references[ri]
                    .ladder
                    .iter()
                    .max_by_key(|p| p.spp)
                    .expect("non-empty");
                let next = finest.spp.saturating_mul(2);
                if finest.error <= closest || next > s.spp / 2 {
                    break;
                }
                let (rung, n) = self.ladder(sc, hash, &cam, *b, reference, cache, &[next])?;
                ref_renders += n;
                references[ri].ladder.extend(rung);
            }
            for r in results.iter_mut() {
                let q = error(r).and_then(|e| {
                    crate::results::equal_error(&references[ri].ladder, e, r.frame.median_s)
                });
                r.errors[ri].equal_error = q;
            }
        }
        Ok((
            ViewResult {
                scene: sc.id.clone(),
                camera_index: ci,
                camera: CameraSpec::from_camera(camera),
                config: config.to_string(),
                references,
                techniques: results,
            },
            renders,
            ref_renders,
        ))
    }
}

#[derive(serde::Serialize, serde::Deserialize)]
struct SavedSequence {
    config: String,
    result: SequenceResult,
}

/// A saved view result to resume from: read within the default file budget (never from a
/// device), and used only when its configuration and its camera are exactly this run's (a
/// camera is checked once, when its list is loaded; a saved file does not bring its own).
fn read_view(
    path: &Path,
    config: &str,
    camera: &Camera,
    lower_is_better: &dyn Fn(&str) -> bool,
) -> Option<ViewResult> {
    let bytes = scene_core::budget::read_file(path, &scene_core::Budget::default()).ok()?;
    let v: ViewResult = match serde_json::from_slice(&bytes) {
        Ok(v) => v,
        Err(e) => {
            // A value JSON cannot hold (a NaN or an infinity is written as null) or a file
            // cut short: say so rather than measuring again in silence.
            eprintln!(
                "note: resume file {} does not read back ({e}); computing the view again",
                path.display()
            );
            return None;
        }
    };
    if !(v.config == config && v.camera == CameraSpec::from_camera(camera)) {
        return None;
    }
    // A resume file is read back like user input: values that are not measurements are
    // computed again, with a note naming the file.
    match v.check(lower_is_better) {
        Ok(()) => Some(v),
        Err(why) => {
            eprintln!(
                "note: resume file {}: {why}; computing the view again",
                path.display()
            );
            None
        }
    }
}

/// Writes `<dir>/<stem>.png` always and `<dir>/<stem>.exr` when `exr` is set.
fn write_image(
    dir: &Path,
    stem: &str,
    image: &Image,
    exposure: f32,
    exr: bool,
) -> Result<(), HarnessError> {
    image
        .write_png(&dir.join(format!("{stem}.png")), exposure)
        .map_err(|e| HarnessError::from(scene_core::Error::from(e)))?;
    if exr {
        image
            .write_exr(&dir.join(format!("{stem}.exr")))
            .map_err(|e| HarnessError::from(scene_core::Error::from(e)))?;
    }
    Ok(())
}

pub(crate) fn write_text(path: &Path, text: &str) -> Result<(), HarnessError> {
    scene_core::image::write_via_temp(
        path,
        |tmp| std::fs::write(tmp, text).map_err(|e| HarnessError::io(path, e)),
        |e| HarnessError::io(path, e),
    )
}
