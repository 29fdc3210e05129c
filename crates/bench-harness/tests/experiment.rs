//! A tiny experiment end to end with stand-in techniques and a mean-error metric: every
//! output, report numbers equal to results.json, resume after an interruption, bad input.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use bench_harness::cameras::parse_camera_list;
use bench_harness::experiment::view_dir;
use bench_harness::{
    Experiment, ExperimentSettings, HarnessError, Results, SceneSetup, TechniqueSetup,
    random_cameras,
};
use scene_core::glam::Vec3;
use scene_core::reference::Bounces;
use scene_core::{Error, FrameRequest, Image, Metric, MetricValue, Scene, Technique, builtin};

/// Primary-ray albedo times a constant: a cheap technique whose error depends on the gain.
struct Flat {
    gain: f32,
    renders: Arc<AtomicU64>,
    scene: Option<Arc<Scene>>,
}

impl Technique for Flat {
    fn name(&self) -> &str {
        "flat"
    }
    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        self.scene = Some(scene);
        Ok(())
    }
    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        let Some(scene) = self.scene.as_deref() else {
            return Err(Error::NotPrepared("flat".into()));
        };
        self.renders.fetch_add(1, Ordering::SeqCst);
        let (w, h, view) = (frame.width, frame.height, frame.view);
        let rays = scene_core::ray::RayScene::build(scene);
        let offsets = scene.mesh_offsets();
        let mut img = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let uv = scene_core::glam::Vec2::new(
                    (x as f32 + 0.5) / w as f32,
                    (y as f32 + 0.5) / h as f32,
                );
                let (o, d) = view.ray(uv);
                if let Some(hit) = rays.closest_hit(o, d, 0.0, f32::INFINITY) {
                    let t = scene.triangle_ref(&offsets, hit.triangle).unwrap();
                    let m = scene.meshes[t.mesh as usize].material_ids[t.local as usize];
                    let mat = &scene.materials[m as usize];
                    img.set(x, y, mat.albedo * self.gain + mat.emission);
                }
            }
        }
        Ok(img)
    }
}

/// Eq. 19's mean absolute difference.
struct MeanError;
impl Metric for MeanError {
    fn name(&self) -> &str {
        "mean-error"
    }
    fn lower_is_better(&self) -> bool {
        true
    }
    fn compare(&self, r: &Image, t: &Image) -> Result<MetricValue, Error> {
        let s: f64 = r
            .pixels
            .iter()
            .zip(&t.pixels)
            .map(|(a, b)| (*a - *b).abs().element_sum() as f64)
            .sum();
        Ok(MetricValue {
            value: s / (3 * r.pixels.len()) as f64,
            map: None,
        })
    }
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bench-harness-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn experiment(out: &Path, renders: &Arc<AtomicU64>) -> Experiment {
    let scene = builtin::scene("cornell").unwrap();
    let tech = |label: &str, gain: f32| TechniqueSetup {
        label: label.into(),
        family: label.split('-').next().unwrap().into(),
        description: format!("albedo x {gain}"),
        technique: Box::new(Flat {
            gain,
            renders: renders.clone(),
            scene: None,
        }),
        single_frame: false,
    };
    Experiment {
        settings: ExperimentSettings {
            width: 64,
            height: 48,
            spp: 4,
            bounces: vec![Bounces::Limited(1), Bounces::Unlimited],
            repeats: 2,
            out_dir: out.to_path_buf(),
            cache_dir: Some(out.join("cache")),
            progress: false,
            ..Default::default()
        },
        scenes: vec![SceneSetup {
            id: "cornell".into(),
            cameras: scene.cameras[..2].to_vec(),
            scene: Arc::new(scene),
        }],
        techniques: vec![tech("dl", 0.05), tech("isr-a", 0.3), tech("isr-b", 0.6)],
        metrics: vec![Box::new(MeanError)],
    }
}

/// (camera, technique, metric values) of every error set.
type Errors = Vec<(String, String, Vec<(String, f64)>)>;

fn errors(r: &Results) -> Errors {
    r.views
        .iter()
        .flat_map(|v| {
            v.techniques.iter().flat_map(move |t| {
                t.errors
                    .iter()
                    .map(move |e| (v.camera_name(), t.label.clone(), e.metrics.clone()))
            })
        })
        .collect()
}

/// The cells of the Markdown table row that starts with `| first |`, and optionally whose
/// second cell is `second`.
fn row(md: &str, first: &str, second: Option<&str>) -> Vec<String> {
    md.lines()
        .map(|l| {
            l.trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect::<Vec<_>>()
        })
        .find(|c| {
            c.first().map(String::as_str) == Some(first)
                && second.is_none_or(|s| c.get(1).map(String::as_str) == Some(s))
        })
        .unwrap_or_else(|| panic!("no row {first} {second:?} in report.md"))
}

/// The text of the report section whose heading starts with `heading`.
fn section<'a>(md: &'a str, heading: &str) -> &'a str {
    let start = md
        .find(heading)
        .unwrap_or_else(|| panic!("no section {heading}"));
    let rest = &md[start + heading.len()..];
    &rest[..rest.find("\n## ").unwrap_or(rest.len())]
}

fn num(cell: &str) -> (f64, f64) {
    // Value and the half-unit of its last printed digit.
    let pct = cell.ends_with('%');
    let t = cell.trim_end_matches('%');
    let decimals = t.split_once('.').map_or(0, |(_, d)| d.len());
    let v: f64 = t.parse().unwrap_or_else(|_| panic!("not a number: {cell}"));
    let scale = if pct { 100.0 } else { 1.0 };
    (
        v / scale,
        0.5 * 10f64.powi(-(decimals as i32)) / scale + 1e-12,
    )
}

fn assert_cell(cell: &str, expected: f64) {
    let (v, tol) = num(cell);
    assert!(
        (v - expected).abs() <= tol,
        "report shows {cell}, results.json has {expected}"
    );
}

#[test]
fn tiny_experiment_writes_every_output_and_the_report_matches_results_json() {
    let out = temp_dir("tiny");
    let renders = Arc::new(AtomicU64::new(0));
    let outcome = experiment(&out, &renders).run().unwrap();
    assert_eq!(outcome.views_computed, 2);
    assert!(!outcome.interrupted);
    // 2 views x 3 techniques x (1 warm-up + 2 repeats).
    assert_eq!(renders.load(Ordering::SeqCst), 18);
    assert_eq!(outcome.reference_renders, 4);
    for f in ["results.json", "report.md", "report.html"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    for v in &outcome.results.views {
        let dir = out.join(view_dir(&v.scene, v.camera_index, &v.camera_name()));
        for stem in ["reference-b1", "reference-binf", "dl", "isr-a", "isr-b"] {
            for ext in ["png", "exr"] {
                assert!(dir.join(format!("{stem}.{ext}")).is_file(), "{stem}.{ext}");
            }
        }
        for stem in ["diff-dl-b1", "diff-isr-a-binf", "diff-isr-b-b1"] {
            assert!(dir.join(format!("{stem}.png")).is_file(), "{stem}");
            assert!(dir.join(format!("{stem}.exr")).is_file(), "{stem}");
        }
        // Timings: median within [min, max].
        for t in &v.techniques {
            assert!(t.frame.min_s <= t.frame.median_s && t.frame.median_s <= t.frame.max_s);
            assert_eq!(t.frame.repeats, 2);
        }
    }

    // results.json is what the run returned.
    let text = std::fs::read_to_string(out.join("results.json")).unwrap();
    let json: Results = serde_json::from_str(&text).unwrap();
    assert_eq!(json, outcome.results);

    // Every number of Table 2 and of the comparisons in report.md equals results.json's.
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let times = section(&md, "## Time");
    for t in &json.summary.times {
        let c = row(times, &t.label, None);
        assert_eq!(c[1], t.views.to_string());
        assert_cell(&c[2], t.total_s);
        assert_cell(&c[3], t.avg_frame_ms);
        assert_cell(&c[4], t.avg_fps);
        assert_eq!(c[5], "-", "no still-camera frames were asked for");
        assert_cell(&c[6], t.prepare_s);
    }
    assert_eq!(json.summary.comparisons.len(), 4);
    let against = section(&md, "## Against the baseline");
    for cmp in &json.summary.comparisons {
        let c = row(against, &cmp.technique, Some(&cmp.bounces));
        assert_eq!(c[2], cmp.views.to_string());
        assert_cell(&c[3], cmp.share_views_better);
        assert_cell(&c[4], cmp.mean_gain);
        assert_cell(&c[5], cmp.mean_error);
        assert_cell(&c[6], cmp.baseline_mean_error);
        assert_cell(&c[9], cmp.share_pixels_closer);
        assert_cell(&c[10], cmp.share_changed_pixels_closer);
        // The summary is consistent with the per-view numbers.
        let per_view: Vec<(f64, f64)> = json
            .views
            .iter()
            .map(|v| {
                (
                    v.error(&cmp.technique, &cmp.bounces, "mean-error").unwrap(),
                    v.error("dl", &cmp.bounces, "mean-error").unwrap(),
                )
            })
            .collect();
        let mean_gain = per_view.iter().map(|(e, b)| (b - e) / b).sum::<f64>() / 2.0;
        assert!((mean_gain - cmp.mean_gain).abs() < 1e-12);
    }
    // The speed-against-error table and its Pareto front.
    let se = &json.summary.speed_error[0];
    assert_eq!(se.points.len(), 3);
    assert!(se.points.iter().any(|p| p.pareto));
    let speed = section(&md, "### cornell");
    for p in &se.points {
        let c = row(speed, &p.label, None);
        assert_cell(&c[1], p.frame_ms);
        assert_cell(&c[2], p.error);
        assert_eq!(c[3] == "yes", p.pareto);
    }
    // The ranking: by mean error at the last bounce limit, the same numbers in report.md,
    // report.html and results.json.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let rank = section(&md, "## Ranking");
    assert_eq!(json.summary.ranking.len(), 3);
    for (i, k) in json.summary.ranking.iter().enumerate() {
        assert_eq!(k.rank, i + 1);
        assert_eq!(k.bounces, "inf");
        let mean: f64 = json
            .views
            .iter()
            .map(|v| v.error(&k.technique, "inf", "mean-error").unwrap())
            .sum::<f64>()
            / 2.0;
        assert!((mean - k.mean_error).abs() < 1e-12);
        let c = row(rank, &k.rank.to_string(), None);
        assert_eq!(c[1], k.technique);
        assert_cell(&c[2], k.mean_error);
        let cells = format!(
            "<td>{}</td><td>{}</td><td>{}</td>",
            k.rank,
            k.technique,
            bench_harness::report::fmt_err(k.mean_error)
        );
        assert!(html.contains(&cells), "{cells} not in report.html");
    }
    assert!(
        json.summary
            .ranking
            .windows(2)
            .all(|w| w[0].mean_error <= w[1].mean_error)
    );
    // The page: plots drawn, every image it links exists (reference, every technique and
    // its error map, per view).
    assert!(html.contains("<svg") && html.contains("speed against error"));
    assert!(html.contains("<table>") && html.contains("<th>technique</th>"));
    let srcs: Vec<&str> = html
        .split("<img src=\"")
        .skip(1)
        .map(|t| t.split('"').next().unwrap())
        .collect();
    assert_eq!(srcs.len(), 2 * (1 + 3 + 3), "{srcs:?}");
    for src in &srcs {
        assert!(out.join(src).is_file(), "{src} missing");
    }
    assert!(srcs.iter().any(|s| s.contains("errmap-isr-b-binf.png")));

    // A second run reuses everything: no render, no reference.
    let renders2 = Arc::new(AtomicU64::new(0));
    let again = experiment(&out, &renders2).run().unwrap();
    assert_eq!(again.views_resumed, 2);
    assert_eq!(renders2.load(Ordering::SeqCst), 0);
    assert_eq!(errors(&again.results), errors(&outcome.results));
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn an_interrupted_run_resumes_without_recomputing_finished_views() {
    let out = temp_dir("resume");
    let renders = Arc::new(AtomicU64::new(0));
    let mut first = experiment(&out, &renders);
    first.settings.stop_after_views = Some(1);
    let partial = first.run().unwrap();
    assert!(partial.interrupted);
    assert_eq!(partial.views_computed, 1);
    assert_eq!(renders.load(Ordering::SeqCst), 9);
    assert!(!out.join("report.md").exists());

    let renders2 = Arc::new(AtomicU64::new(0));
    let resumed = experiment(&out, &renders2).run().unwrap();
    assert_eq!(resumed.views_resumed, 1);
    assert_eq!(resumed.views_computed, 1);
    // Only the second view was rendered.
    assert_eq!(renders2.load(Ordering::SeqCst), 9);
    // The first view keeps its recorded timings.
    assert_eq!(resumed.results.views[0], partial.results.views[0]);

    // The same errors as an uninterrupted run elsewhere.
    let fresh_dir = temp_dir("resume-fresh");
    let fresh = experiment(&fresh_dir, &Arc::new(AtomicU64::new(0)))
        .run()
        .unwrap();
    assert_eq!(errors(&resumed.results), errors(&fresh.results));
    std::fs::remove_dir_all(&out).ok();
    std::fs::remove_dir_all(&fresh_dir).ok();
}

#[test]
fn references_are_cached_across_output_folders() {
    let base = temp_dir("cache");
    let cache = base.join("shared-cache");
    let renders = Arc::new(AtomicU64::new(0));
    let mut a = experiment(&base.join("a"), &renders);
    a.settings.cache_dir = Some(cache.clone());
    a.settings.bounces = vec![Bounces::Limited(1)];
    assert_eq!(a.run().unwrap().reference_renders, 2);
    let mut b = experiment(&base.join("b"), &renders);
    b.settings.cache_dir = Some(cache.clone());
    b.settings.bounces = vec![Bounces::Limited(1)];
    assert_eq!(b.run().unwrap().reference_renders, 0);
    // Another spp is another key.
    let mut c = experiment(&base.join("c"), &renders);
    c.settings.cache_dir = Some(cache);
    c.settings.bounces = vec![Bounces::Limited(1)];
    c.settings.spp = 5;
    assert_eq!(c.run().unwrap().reference_renders, 2);
    std::fs::remove_dir_all(&base).ok();
}

#[test]
fn bad_camera_lists_and_setups_give_clear_errors() {
    let scene = builtin::scene("cornell").unwrap();
    let e = parse_camera_list("[{\"position\": [0, 1", &scene, "cams.json").unwrap_err();
    assert!(matches!(e, HarnessError::CameraList { .. }));
    assert!(e.to_string().contains("cams.json"), "{e}");
    let e = parse_camera_list(
        "[{\"position\": [0,0,0], \"target\": [0,0,0], \"fov\": 40}]",
        &scene,
        "same.json",
    )
    .unwrap_err();
    assert!(e.to_string().contains("target equals position"), "{e}");
    let e = parse_camera_list(
        "[{\"position\": [0,0,0], \"target\": [0,0,1], \"fov\": 200}]",
        &scene,
        "fov.json",
    )
    .unwrap_err();
    assert!(e.to_string().contains("fov"), "{e}");
    let e = bench_harness::load_camera_list(Path::new("/no/such/cams.json"), &scene).unwrap_err();
    assert!(e.to_string().contains("/no/such/cams.json"), "{e}");

    let ok = parse_camera_list(
        "{\"cameras\": [{\"name\": \"a\", \"position\": [0.278, 0.273, -0.8], \"target\": [0.278, 0.273, 0], \"fov\": 40}]}",
        &scene,
        "ok.json",
    )
    .unwrap();
    assert_eq!(ok[0].name, "a");
    assert!((ok[0].fov_y.to_degrees() - 40.0).abs() < 1e-4);

    // A baseline that is not among the techniques.
    let out = temp_dir("bad");
    let renders = Arc::new(AtomicU64::new(0));
    let mut x = experiment(&out, &renders);
    x.settings.baseline = "nope".into();
    let e = x.run().err().unwrap();
    assert!(e.to_string().contains("baseline 'nope'"), "{e}");
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn random_cameras_are_seeded_in_free_space_and_see_geometry() {
    let scene = builtin::scene("cornell").unwrap();
    let s = bench_harness::RandomCameraSettings::default();
    let a = random_cameras(&scene, 3, &s).unwrap();
    let b = random_cameras(&scene, 3, &s).unwrap();
    assert_eq!(a, b);
    let bounds = scene.bounds();
    for c in &a {
        assert!(c.position.cmpge(bounds.min).all() && c.position.cmple(bounds.max).all());
        assert!((c.target - c.position).length() > 0.0);
    }
    let other = random_cameras(
        &scene,
        3,
        &bench_harness::RandomCameraSettings { seed: 2, ..s },
    )
    .unwrap();
    assert_ne!(a, other);
    // A scene with no geometry cannot place cameras.
    let empty = Scene::new("empty");
    assert!(random_cameras(&empty, 1, &s).is_err());
    let _ = Vec3::ZERO;
}

/// The reference path tracer itself at `spp` samples with its own seed: a technique whose
/// image is the reference at a known lower sample count.
struct PathTracerAt {
    spp: u32,
    seed: u64,
    scene: Option<Arc<Scene>>,
}

impl Technique for PathTracerAt {
    fn name(&self) -> &str {
        "path-tracer"
    }
    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        self.scene = Some(scene);
        Ok(())
    }
    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        let scene = self
            .scene
            .as_deref()
            .ok_or(Error::NotPrepared("pt".into()))?;
        let settings = scene_core::reference::ReferenceSettings {
            width: frame.width,
            height: frame.height,
            spp: self.spp,
            bounces: Bounces::Limited(1),
            seed: self.seed,
        };
        Ok(scene_core::reference::render(scene, &frame.view, &settings, None).image)
    }
}

#[test]
fn the_equal_error_spp_of_a_path_tracer_at_a_lower_spp_is_that_spp() {
    let out = temp_dir("equal-error");
    // The sun-lit primitives: direct light without a hot spot, so the path tracer's error
    // falls smoothly with the sample count (a point light's hot spot gives fireflies whose
    // mean error is not monotone in the spp at these sizes).
    let scene = builtin::scene("primitives").unwrap();
    let pt = |label: &str, spp: u32, seed: u64| TechniqueSetup {
        label: label.into(),
        family: "pt".into(),
        description: format!("path tracer, {spp} spp"),
        technique: Box::new(PathTracerAt {
            spp,
            seed,
            scene: None,
        }),
        single_frame: false,
    };
    let mut x = Experiment {
        settings: ExperimentSettings {
            width: 96,
            height: 72,
            spp: 256,
            bounces: vec![Bounces::Limited(1)],
            repeats: 1,
            out_dir: out.clone(),
            progress: false,
            baseline: "pt-2".into(),
            ladder_spp: bench_harness::experiment::default_ladder(256),
            ..Default::default()
        },
        scenes: vec![SceneSetup {
            id: "primitives".into(),
            cameras: scene.cameras[..1].to_vec(),
            scene: Arc::new(scene),
        }],
        // Seeds other than the reference's (1) and the ladder's. pt-256 is as good as the
        // reference itself: closer than any rung the ladder may add (up to 128 spp).
        techniques: vec![
            pt("pt-2", 2, 77),
            pt("pt-6", 6, 78),
            pt("pt-12", 12, 79),
            pt("pt-256", 256, 80),
        ],
        metrics: vec![Box::new(MeanError)],
    };
    let r = x.run().unwrap().results;
    let ladder = &r.views[0].references[0].ladder;
    // The default ladder (1 to 32 spp) extended to half the reference's spp to bracket
    // pt-256, which it cannot.
    assert_eq!(
        ladder.iter().map(|p| p.spp).collect::<Vec<_>>(),
        [1, 2, 4, 8, 16, 32, 64, 128]
    );
    // The ladder's error falls with the sample count.
    assert!(
        ladder.windows(2).all(|w| w[1].error < w[0].error),
        "{ladder:?}"
    );
    for (label, spp) in [("pt-2", 2.0), ("pt-6", 6.0), ("pt-12", 12.0)] {
        let e = r.views[0].technique(label).unwrap().errors[0]
            .equal_error
            .unwrap_or_else(|| panic!("{label}: no equal-error point"));
        eprintln!("{label}: equal-error spp {:.2}", e.spp);
        // Within the noise of one 96 x 72 image's mean error (measured 2.12, 5.79 and
        // 12.05 for 2, 6 and 12 spp).
        assert!(
            (e.spp / spp - 1.0).abs() < 0.15
                && e.bound == bench_harness::results::LadderBound::Within,
            "{label}: {e:?}"
        );
        // The path tracer's time at that spp, from its measured seconds per sample.
        let top = ladder.last().unwrap();
        let per_spp = top.seconds / top.spp as f64;
        assert!((e.seconds - e.spp * per_spp).abs() < 1e-9 * e.seconds.max(1.0));
    }
    let rows = &r.summary.equal_error;
    assert_eq!(rows.len(), 4);
    // pt-256 lies above the ladder: a bound, left out of the median, shown as one.
    let best = rows.iter().find(|x| x.technique == "pt-256").unwrap();
    let point = r.views[0].technique("pt-256").unwrap().errors[0]
        .equal_error
        .unwrap();
    assert_eq!(
        point.bound,
        bench_harness::results::LadderBound::AboveFinest
    );
    assert_eq!((best.above_ladder, best.speedup), (1, None), "{best:?}");
    assert_eq!(best.speedup_at_least, Some(point.speedup));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("## Equal error"), "no equal-error section");
    let row = section(&md, "## Equal error")
        .lines()
        .find(|l| l.starts_with("| pt-256 | 1 |"))
        .expect("pt-256's equal-error row");
    assert!(row.contains("| > "), "{row}");
    assert!(
        rows.iter()
            .filter(|x| x.technique != "pt-256")
            .all(|x| x.speedup.is_some() && x.above_ladder == 0),
        "{rows:?}"
    );
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn equal_error_interpolates_in_log_log_and_gives_bounds_outside_the_ladder() {
    use bench_harness::results::{LadderBound, LadderPoint, equal_error};
    // e = 0.4 / sqrt(spp), 0.01 s per sample.
    let ladder: Vec<LadderPoint> = [1u32, 4, 16, 64]
        .iter()
        .map(|&spp| LadderPoint {
            spp,
            seconds: 0.01 * spp as f64,
            error: 0.4 / (spp as f64).sqrt(),
        })
        .collect();
    let e = equal_error(&ladder, 0.4 / 8f64.sqrt(), 0.002).unwrap();
    assert!(
        (e.spp - 8.0).abs() < 1e-9 && e.bound == LadderBound::Within,
        "{e:?}"
    );
    assert!((e.seconds - 0.08).abs() < 1e-12 && (e.speedup - 40.0).abs() < 1e-9);
    // Closer than the finest rung: the finest rung's spp and speedup as a lower bound,
    // never the 256 spp an extrapolation along the slope would claim.
    let closer = equal_error(&ladder, 0.4 / 256f64.sqrt(), 0.002).unwrap();
    assert_eq!(closer.bound, LadderBound::AboveFinest);
    assert!((closer.spp - 64.0).abs() < 1e-9 && (closer.speedup - 320.0).abs() < 1e-9);
    assert_eq!(closer.shown(), "> 320.00");
    // Farther than 1 spp: an upper bound at the coarsest rung.
    let farther = equal_error(&ladder, 0.8, 0.002).unwrap();
    assert_eq!(farther.bound, LadderBound::BelowCoarsest);
    assert!((farther.spp - 1.0).abs() < 1e-9 && farther.shown() == "< 5.00");
    assert!(equal_error(&ladder[..1], 0.1, 0.002).is_none());
    assert!(equal_error(&ladder, f64::NAN, 0.002).is_none());
    // A ladder whose error does not fall brackets nothing below it: a bound, not a guess.
    let flat: Vec<LadderPoint> = ladder
        .iter()
        .map(|p| LadderPoint { error: 0.1, ..*p })
        .collect();
    let f = equal_error(&flat, 0.05, 0.002).unwrap();
    assert_eq!((f.bound, f.spp), (LadderBound::AboveFinest, 64.0));
}

#[test]
fn bad_cache_entries_and_resume_files_are_computed_again_not_reported() {
    let base = temp_dir("readback");
    let cache = base.join("cache");
    let renders = Arc::new(AtomicU64::new(0));
    let run = |out: &Path| {
        let mut x = experiment(out, &renders);
        x.settings.cache_dir = Some(cache.clone());
        x.settings.bounces = vec![Bounces::Limited(1)];
        x.run().unwrap()
    };
    let first = run(&base.join("a"));
    assert_eq!(first.reference_renders, 2);
    // A cached reference with a NaN pixel, and another whose sidecar has negative seconds:
    // both are rendered again (in a fresh output folder, so no view is resumed).
    let mut exrs: Vec<_> = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "exr"))
        .collect();
    exrs.sort();
    assert_eq!(exrs.len(), 2);
    let mut img = scene_core::Image::read_exr(&exrs[0]).unwrap();
    img.pixels[3].y = f32::NAN;
    img.write_exr(&exrs[0]).unwrap();
    let sidecar = exrs[1].with_extension("json");
    let text = std::fs::read_to_string(&sidecar).unwrap();
    let mut meta: serde_json::Value = serde_json::from_str(&text).unwrap();
    meta["seconds"] = serde_json::json!(-5.0);
    std::fs::write(&sidecar, meta.to_string()).unwrap();
    let second = run(&base.join("b"));
    assert_eq!(
        second.reference_renders, 2,
        "both bad entries rendered again"
    );
    assert_eq!(errors(&second.results), errors(&first.results));
    let errors_only = |name: &str| name != "ssim";
    assert!(
        second
            .results
            .views
            .iter()
            .all(|v| v.check(&errors_only).is_ok())
    );
    // A resume file whose frame time is negative and whose error is -1e308: that view is
    // computed again, the other resumed.
    let views = base.join("b").join("views");
    let mut files: Vec<_> = std::fs::read_dir(&views)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&files[0]).unwrap()).unwrap();
    let metric = v["techniques"][0]["errors"][0]["metrics"][0][0]
        .as_str()
        .unwrap()
        .to_string();
    assert!(errors_only(&metric), "{metric}");
    v["techniques"][0]["errors"][0]["metrics"][0][1] = serde_json::json!(-1e308);
    let saved: bench_harness::results::ViewResult = serde_json::from_value(v.clone()).unwrap();
    let e = saved.check(&errors_only).unwrap_err();
    assert!(e.contains("-1e308") && e.contains(&metric), "{e}");
    v["techniques"][0]["frame"]["median_s"] = serde_json::json!(-1.0);
    let saved: bench_harness::results::ViewResult = serde_json::from_value(v.clone()).unwrap();
    let e = saved.check(&errors_only).unwrap_err();
    assert!(e.contains("frame median seconds is -1"), "{e}");
    std::fs::write(&files[0], v.to_string()).unwrap();
    let third = run(&base.join("b"));
    assert_eq!((third.views_resumed, third.views_computed), (1, 1));
    assert_eq!(errors(&third.results), errors(&first.results));
    std::fs::remove_dir_all(&base).ok();
}

/// A technique with a per-view cache: the first frame of a view it has not rendered before
/// sleeps [`FIRST_VIEW`], a frame of the view it rendered last is free.
struct PerViewCache {
    last: Option<scene_core::View>,
}

const FIRST_VIEW: std::time::Duration = std::time::Duration::from_millis(40);

impl Technique for PerViewCache {
    fn name(&self) -> &str {
        "per-view-cache"
    }
    fn prepare(&mut self, _: Arc<Scene>) -> Result<(), Error> {
        self.last = None;
        Ok(())
    }
    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        if self.last != Some(frame.view) {
            std::thread::sleep(FIRST_VIEW);
            self.last = Some(frame.view);
        }
        Ok(Image::filled(frame.width, frame.height, Vec3::splat(0.1)))
    }
}

#[test]
fn a_per_view_cache_is_inside_the_reported_frame_time_and_the_still_camera_apart() {
    let out = temp_dir("per-view-cache");
    let renders = Arc::new(AtomicU64::new(0));
    let mut x = experiment(&out, &renders);
    x.settings.still_repeats = 3;
    x.settings.repeats = 3;
    x.techniques.push(TechniqueSetup {
        label: "cached".into(),
        family: "cached".into(),
        description: "sleeps on a new view".into(),
        technique: Box::new(PerViewCache { last: None }),
        single_frame: false,
    });
    let r = x.run().unwrap().results;
    let first = FIRST_VIEW.as_secs_f64();
    for v in &r.views {
        let t = v.technique("cached").unwrap();
        // Every moving-camera frame is a new view: each pays the first-view cost, even
        // after the warm-up.
        assert!(t.frame.min_s >= first, "{:?}", t.frame);
        let still = t.still.as_ref().expect("still-camera frames");
        assert!(still.median_s < first / 4.0, "{still:?}");
    }
    let row = r
        .summary
        .ranking
        .iter()
        .find(|k| k.technique == "cached")
        .unwrap();
    assert!(row.frame_ms >= first * 1e3, "{row:?}");
    assert!(row.still_frame_ms.unwrap() < first * 1e3 / 4.0, "{row:?}");
    // The report shows the sleep in the ranking's frame column.
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let cells = row_cells(&md, "cached");
    let frame_col = 5;
    assert!(
        cells[frame_col].parse::<f64>().unwrap() >= first * 1e3,
        "{cells:?}"
    );
    std::fs::remove_dir_all(&out).ok();
}

/// The cells of the first Markdown table row whose second cell is `label`.
fn row_cells(md: &str, label: &str) -> Vec<String> {
    md.lines()
        .map(|l| {
            l.trim()
                .trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect::<Vec<_>>()
        })
        .find(|c| c.len() > 2 && c[1] == label)
        .unwrap_or_else(|| panic!("no row for {label}"))
}

#[test]
fn surface_error_shows_a_bias_that_the_whole_image_dilutes() {
    use bench_harness::results::{surface_error, surface_mask};
    use scene_core::reference::{PathTracer, PixelClass, ReferenceSettings};
    let scene = builtin::scene("cornell").unwrap();
    let (w, h) = (48, 36);
    let cam = scene.cameras[0].with_aspect(w as f32 / h as f32);
    let view = scene_core::View::from_camera(&cam);
    let classes = PathTracer::new(&scene).pixel_classes(&view, w, h);
    let emitters = classes
        .iter()
        .filter(|c| **c == PixelClass::Emitter)
        .count();
    assert!(emitters > 0, "the default camera sees cornell's light");
    let reference = scene_core::reference::render(
        &scene,
        &view,
        &ReferenceSettings {
            width: w,
            height: h,
            spp: 4,
            bounces: Bounces::Unlimited,
            seed: 3,
        },
        None,
    )
    .image;
    // 10% dark on every surface, exact on emitters.
    let mut test = reference.clone();
    for (p, c) in test.pixels.iter_mut().zip(&classes) {
        if *c == PixelClass::Surface {
            *p *= 0.9;
        }
    }
    let surface: Vec<bool> = classes.iter().map(|c| *c == PixelClass::Surface).collect();
    let mask = surface_mask(&surface, &reference);
    // The brightest 1% of the surface pixels are left out, emitters always.
    let kept = mask.iter().filter(|m| **m).count();
    let surfaces = surface.iter().filter(|m| **m).count();
    assert!(
        kept < surfaces && kept as f64 >= 0.985 * surfaces as f64,
        "{kept} of {surfaces}"
    );
    let s = surface_error(&reference, &test, &mask).unwrap();
    for b in s.bias {
        assert!((b + 0.1).abs() < 1e-5, "{:?}", s.bias);
    }
    let whole = surface_error(&reference, &test, &vec![true; mask.len()]).unwrap();
    for c in 0..3 {
        assert!(
            whole.bias[c] > -0.1 + 0.01 && whole.bias[c] < 0.0,
            "whole-image bias {:?} does not read less than the surfaces' -10%",
            whole.bias
        );
    }
}

#[test]
fn a_run_split_in_shards_and_merged_equals_the_unsplit_run() {
    let base = temp_dir("shards");
    let renders = Arc::new(AtomicU64::new(0));
    let setup = |out: &Path, shard: Option<bench_harness::Shard>| {
        let mut x = experiment(out, &renders);
        x.settings.cache_dir = Some(base.join("cache"));
        x.settings.ladder_spp = vec![1, 2];
        x.settings.spp = 8;
        x.settings.shard = shard;
        // A second scene: three views dealt over two shards, the sequence a fourth job.
        let point = builtin::scene("cornell-point").unwrap();
        x.scenes.push(SceneSetup {
            id: "cornell-point".into(),
            cameras: point.cameras[..1].to_vec(),
            scene: Arc::new(point),
        });
        x.settings.sequence = Some(bench_harness::SequenceSpec {
            scene: "cornell-point".into(),
            camera: 0,
            frames: 3,
            spp: 4,
            bounces: Bounces::Unlimited,
        });
        x
    };
    let whole = setup(&base.join("whole"), None).run().unwrap().results;
    let mut dirs = Vec::new();
    for k in 1..=2 {
        let dir = base.join(format!("shard{k}"));
        let shard = bench_harness::Shard::parse(&format!("{k}/2")).unwrap();
        let o = setup(&dir, Some(shard)).run().unwrap();
        assert!(!o.report_md.exists(), "a shard writes results.json only");
        assert!(o.results.views.len() < whole.views.len());
        dirs.push(dir);
    }
    // A missing share is refused, naming it.
    let e = bench_harness::merge(&dirs[..1], &base.join("bad"), None).unwrap_err();
    assert!(e.to_string().contains("2/2 is missing"), "{e}");
    // An output folder that is a shard (or inside one) is refused, and the shard is kept.
    let shard1 = std::fs::read(dirs[0].join("results.json")).unwrap();
    for out in [dirs[0].clone(), dirs[0].join("."), dirs[0].join("images")] {
        let e = bench_harness::merge(&dirs, &out, None).unwrap_err();
        assert!(e.to_string().contains("would overwrite that shard"), "{e}");
    }
    assert_eq!(std::fs::read(dirs[0].join("results.json")).unwrap(), shard1);
    assert!(!dirs[0].join("report.md").exists());
    // Shards of different versions of a scene file, or of the tool, are refused.
    let tampered = base.join("tampered");
    let tamper = |edit: &dyn Fn(&mut Results)| {
        std::fs::create_dir_all(&tampered).unwrap();
        let mut r: Results = serde_json::from_slice(&shard1).unwrap();
        edit(&mut r);
        std::fs::write(
            tampered.join("results.json"),
            serde_json::to_vec(&r).unwrap(),
        )
        .unwrap();
        let both = [tampered.clone(), dirs[1].clone()];
        bench_harness::merge(&both, &base.join("bad"), None)
            .unwrap_err()
            .to_string()
    };
    let e = tamper(&|r| r.run.scene_hashes[1] = "0123456789abcdef".into());
    assert!(e.contains("scene 'cornell-point' differs"), "{e}");
    let e = tamper(&|r| r.run.tool_version = "bench-harness 0.0.1".into());
    assert!(
        e.contains("was made by") && e.contains("by bench-harness 0.0.1"),
        "{e}"
    );
    let e = tamper(&|r| r.run.scene_hashes.clear());
    assert!(e.contains("older version"), "{e}");
    // A shard whose images are gone is refused before anything is written.
    let e = tamper(&|_| {});
    assert!(e.contains("is missing images/"), "{e}");
    assert!(
        !base.join("bad").exists(),
        "nothing is written for a refused merge"
    );
    let merged = bench_harness::merge(&dirs, &base.join("merged"), None)
        .unwrap()
        .results;
    assert!(base.join("merged/report.md").exists());
    // Errors bit-identical, views in the same order, the same ranking and surface rows.
    assert_eq!(errors(&merged), errors(&whole));
    let surf = |r: &Results| -> Vec<_> {
        r.views
            .iter()
            .flat_map(|v| {
                v.techniques
                    .iter()
                    .map(|t| t.errors.iter().map(|e| e.surface).collect::<Vec<_>>())
            })
            .collect()
    };
    assert_eq!(surf(&merged), surf(&whole));
    let ranks = |r: &Results| -> Vec<(String, f64, Option<f64>)> {
        r.summary
            .ranking
            .iter()
            .map(|k| (k.technique.clone(), k.mean_error, k.surface_error))
            .collect()
    };
    assert_eq!(ranks(&merged), ranks(&whole));
    assert_eq!(merged.summary.surface, whole.summary.surface);
    let seq_errors = |r: &Results| -> Vec<f64> {
        r.sequence
            .as_ref()
            .unwrap()
            .frames
            .iter()
            .flat_map(|f| f.techniques.iter().map(|t| t.error))
            .collect()
    };
    assert_eq!(seq_errors(&merged), seq_errors(&whole));
    assert_eq!(merged.run.merged_shards, 2);
    std::fs::remove_dir_all(&base).ok();
}

/// A technique whose harness work (a sleep) is much longer than the time it reports for
/// its device ([`DEVICE`]).
struct DeviceTimed;

const DEVICE: f64 = 0.002;
const AROUND: std::time::Duration = std::time::Duration::from_millis(20);

impl Technique for DeviceTimed {
    fn name(&self) -> &str {
        "device-timed"
    }
    fn prepare(&mut self, _: Arc<Scene>) -> Result<(), Error> {
        Ok(())
    }
    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        std::thread::sleep(AROUND);
        Ok(Image::filled(frame.width, frame.height, Vec3::splat(0.1)))
    }
    fn device_time(&self) -> Option<scene_core::DeviceTime> {
        Some(scene_core::DeviceTime {
            seconds: DEVICE,
            clock: scene_core::DeviceClock::Timestamps,
        })
    }
}

/// The CPU path tracer with another key tag, counting its renders.
#[derive(Debug)]
struct Tagged(Arc<AtomicU64>);

impl bench_harness::ReferenceRenderer for Tagged {
    fn describe(&self) -> String {
        "a tagged tracer".into()
    }
    fn key_tag(&self) -> &str {
        "tagged"
    }
    fn render(
        &self,
        scene: &Scene,
        view: &scene_core::View,
        settings: &scene_core::reference::ReferenceSettings,
        lights: &scene_core::LightState,
        progress: Option<&(dyn Fn(u64, u64) + Sync)>,
    ) -> Result<bench_harness::RenderedReference, HarnessError> {
        self.0.fetch_add(1, Ordering::SeqCst);
        bench_harness::CpuReference.render(scene, view, settings, lights, progress)
    }
}

#[test]
fn a_device_clock_is_the_frame_time_and_the_harness_wall_a_labelled_second_figure() {
    let out = temp_dir("device-clock");
    let renders = Arc::new(AtomicU64::new(0));
    let tagged = Arc::new(AtomicU64::new(0));
    let mut x = experiment(&out, &renders);
    x.settings.reference_renderer = Some(Arc::new(Tagged(tagged.clone())));
    x.settings.ladder_spp = vec![1, 2];
    x.settings.ladder_extend = false;
    x.techniques.push(TechniqueSetup {
        label: "device".into(),
        family: "device".into(),
        description: "reports its device time".into(),
        technique: Box::new(DeviceTimed),
        single_frame: false,
    });
    let r = x.run().unwrap().results;
    assert_eq!(r.settings.reference_renderer, "a tagged tracer");
    // Every reference and rung of every view came from the renderer given.
    let rungs: usize = r
        .views
        .iter()
        .flat_map(|v| &v.references)
        .map(|rf| 1 + rf.ladder.len())
        .sum();
    assert_eq!(tagged.load(Ordering::SeqCst) as usize, rungs);
    for v in &r.views {
        let t = v.technique("device").unwrap();
        assert_eq!(t.frame.median_s, DEVICE, "{:?}", t.frame);
        assert_eq!(t.clock.as_deref(), Some("GPU timestamps"));
        let harness = t.harness.as_ref().expect("the harness wall time beside");
        assert!(harness.min_s >= AROUND.as_secs_f64(), "{harness:?}");
        assert_eq!(harness.repeats, 2);
        // A technique without a clock keeps the harness's wall time as its frame time.
        let flat = v.technique("dl").unwrap();
        assert!(flat.clock.is_none() && flat.harness.is_none());
    }
    let times = r
        .summary
        .times
        .iter()
        .find(|t| t.label == "device")
        .unwrap();
    assert!(
        (times.avg_frame_ms - DEVICE * 1e3).abs() < 1e-9,
        "{times:?}"
    );
    assert!(
        times.harness_frame_ms.unwrap() >= AROUND.as_secs_f64() * 1e3,
        "{times:?}"
    );
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("References and the equal-error ladder: a tagged tracer."));
    let time = section(&md, "## Time");
    let cells = row(time, "device", None);
    assert!(cells.contains(&"GPU timestamps".to_string()), "{cells:?}");
    // The tagged tracer's entries are not the CPU tracer's: a run with the CPU tracer on
    // the same cache renders every reference again.
    let second = temp_dir("device-clock-cpu");
    let mut y = experiment(&second, &renders);
    y.settings.cache_dir = Some(out.join("cache"));
    y.settings.ladder_spp = vec![1, 2];
    y.settings.ladder_extend = false;
    let outcome = y.run().unwrap();
    assert_eq!(outcome.reference_renders as usize, rungs);
    std::fs::remove_dir_all(&out).ok();
    std::fs::remove_dir_all(&second).ok();
}
