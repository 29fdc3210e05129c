//! `cargo xtask ibrr`: writes the view and a summary whose figures agree with the files and
//! with each other, bakes a given light colour in, and refuses bad options with a message
//! that names them.

mod common;

use common::{run_with_summary, xtask};

#[test]
fn ibrr_writes_the_view_and_the_summary() {
    let out = std::env::temp_dir().join(format!("xtask-ibrr-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let run = |extra: &[&str]| {
        let mut c = xtask();
        c.args([
            "ibrr",
            "--scene",
            "cornell-point",
            "--ldc",
            "32",
            "--irpls",
            "12",
        ])
        .args(["--width", "32", "--height", "24"])
        .args(extra);
        run_with_summary(c, &out, "cornell-point")
    };
    let (summary, white) = run(&[]);
    assert!(out.join("cornell-point.png").is_file());
    assert_eq!((white.width, white.height), (32, 24));
    assert_eq!(summary["ldc_resolution"], 32);
    let layers = summary["layers"].as_u64().unwrap();
    // Memory: 4 bytes per pixel of the three LDIs (plus one), 40 per layer, and 24 per
    // layer and light source (one point light).
    assert_eq!(summary["light_sources"], 1);
    assert_eq!(
        summary["memory_bytes_per_source"].as_u64().unwrap(),
        24 * layers
    );
    assert_eq!(
        summary["memory_bytes"].as_u64().unwrap(),
        (3 * 32 * 32 + 1) * 4 + (40 + 24) * layers
    );
    assert!(summary["irpls"].as_u64().unwrap() >= 1);
    // The build states its own error and what ended its rounds: at the default target
    // (2 %) a build of 12 IRPLs runs into its budget (twice that) first.
    let stated = summary["error_estimate"].as_f64().unwrap();
    let rgb: Vec<f64> = summary["error_estimate_rgb"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(rgb.iter().copied().fold(0.0, f64::max), stated);
    assert!(stated > 0.02, "{stated}");
    assert_eq!(summary["stopped_by"], "irpl budget");
    assert_eq!(summary["irpl_budget"], 24);
    assert!(summary["rounds"].as_u64().unwrap() >= 2);
    assert!(summary["irpls"].as_u64().unwrap() <= 24 + 4);
    assert!(summary["construction_seconds"].as_f64().unwrap() > 0.0);
    assert!(summary["pixels_without_layer"].is_u64());
    // `served.exr` marks how each pixel found its light: its counts are the summary's.
    let served = scene_core::Image::read(&out.join("served.exr")).unwrap();
    assert_eq!((served.width, served.height), (32, 24));
    let count = |f: fn(glam::Vec3) -> f32| served.pixels.iter().filter(|p| f(**p) > 0.5).count();
    assert!(count(|p| p.x) > 0, "no pixel from a layer");
    // Yellow (red and green) is the hole fill's, blue what nothing served.
    assert_eq!(
        served
            .pixels
            .iter()
            .filter(|p| p.x > 0.5 && p.y > 0.5)
            .count() as u64,
        summary["pixels_filled"].as_u64().unwrap()
    );
    assert_eq!(
        count(|p| p.y) as u64,
        summary["pixels_from_fallback"].as_u64().unwrap()
            + summary["pixels_filled"].as_u64().unwrap()
    );
    assert_eq!(
        count(|p| p.z) as u64,
        summary["pixels_without_layer"].as_u64().unwrap()
    );
    // The light's colour is applied by relighting, not by a rebuild: red only.
    let (red_summary, red) = run(&["--light", "point:0=1,0,0"]);
    assert_eq!(red_summary["rebuild_ms"].as_f64().unwrap(), 0.0);
    assert!(red_summary["relight_ms"].as_f64().unwrap() > 0.0);
    let (w, r) = (white.mean(), red.mean());
    assert!(r.x > 0.0 && r.y == 0.0 && r.z == 0.0, "{r}");
    assert!(w.y > 0.0);
    // `--bounces 0`: the light's own exact source and no particle path, so a darker image
    // (cornell-point's walls lit only by the lamp).
    let (direct_summary, direct) = run(&["--bounces", "0"]);
    assert_eq!(direct_summary["bounces"], 0);
    assert_eq!(direct_summary["irpls"], direct_summary["exact_sources"]);
    // No paths: nothing to estimate from, and no round added.
    assert!(direct_summary["error_estimate"].is_null());
    assert_eq!(direct_summary["stopped_by"], "no estimate");
    assert!(summary["irpls"].as_u64() > direct_summary["irpls"].as_u64());
    let d = direct.mean();
    assert!(d.y > 0.0 && d.y < w.y, "direct {d}, all bounces {w}");
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn ibrr_refuses_bad_options_by_name() {
    for (args, says) in [
        (vec!["--splat", "round"], "--splat"),
        (vec!["--compensation", "global"], "--compensation"),
        (
            vec!["--ldc", "0"],
            "--ldc = 0 is outside its range [8, 2048]",
        ),
        (
            vec!["--irpls", "0"],
            "--irpls = 0 is outside its range [1, 100000]",
        ),
        (
            vec!["--target-error", "2"],
            "--target-error = 2.0 is outside its range [0.0, 1.0]",
        ),
        (
            vec!["--irpls", "12", "--irpl-budget", "5"],
            "--irpl-budget (5) must be at least --irpls (12)",
        ),
        (
            vec!["--time-budget", "NaN"],
            "--time-budget = NaN is outside its range",
        ),
        (
            vec!["--fill-radius", "65"],
            "--fill-radius = 65 is outside its range [0, 64]",
        ),
        (
            vec!["--bounces", "2000"],
            "--bounces = 2000 is outside its range [0, 1024]",
        ),
        (
            vec!["--direct-render", "9000"],
            "--direct-render = 9000 is outside its range [0, 8192]",
        ),
        (
            vec!["--indirect-render", "9000"],
            "--indirect-render = 9000 is outside its range [0, 8192]",
        ),
        (
            vec!["--exposure", "NaN"],
            "--exposure = NaN is outside its range [-20.0, 20.0]",
        ),
        (vec!["--camera", "7"], "--camera 7"),
        (vec!["--light", "point:9=1,1,1"], "point:0"),
    ] {
        let o = xtask()
            .args(["ibrr", "--scene", "cornell-point"])
            .args(&args)
            .output()
            .unwrap();
        assert!(!o.status.success(), "{args:?} succeeded");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
    }
}
