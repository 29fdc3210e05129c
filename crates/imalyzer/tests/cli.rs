//! The `imalyzer` binary: outputs, files written, exit codes and error messages.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use imalyzer::scene_core::Image;
use imalyzer::scene_core::glam::Vec3;
use imalyzer::{Pair, negative_difference, srgb8};
use serde_json::Value;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// A fresh scratch directory for one test.
fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("imalyzer-cli-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imalyzer"))
        .args(args)
        .output()
        .expect("run imalyzer")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Runs and expects failure with `code`; returns stderr, which must not show a panic.
fn fails(args: &[&str], code: i32) -> String {
    let out = run(args);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    assert!(
        out.stdout.is_empty() || code == 3,
        "{args:?} printed {}",
        text(&out.stdout)
    );
    err
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn compare_prints_a_table_of_every_measure() {
    let (r, t) = (data("ref.png"), data("noisy.png"));
    let out = run(&["compare", s(&r), s(&t)]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    for name in [
        "mean-error ",
        "mean-error-8bit",
        "pearson",
        "rmse",
        "psnr",
        "relmse",
        "smape",
        "ssim",
        "flip",
    ] {
        assert!(table.contains(name), "{name} missing from\n{table}");
    }
    assert!(
        !table.contains("hdr-flip"),
        "PNG inputs use LDR-FLIP:\n{table}"
    );
    assert!(table.contains("64x48"));
}

#[test]
fn compare_json_matches_the_library() {
    let (r, t) = (data("ref.png"), data("blurred.png"));
    let out = run(&[
        "compare",
        s(&r),
        s(&t),
        "--metrics",
        "mean,mean8,pearson,ssim,flip",
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let doc: Value = serde_json::from_slice(&out.stdout).unwrap();
    let (a, b) = (Image::read(&r).unwrap(), Image::read(&t).unwrap());
    let p = Pair::new(&a, &b).unwrap();
    let m = &doc["metrics"];
    assert_eq!(m["mean-error"].as_f64().unwrap(), p.mean_error());
    assert_eq!(m["mean-error-8bit"].as_f64().unwrap(), p.mean_error_8bit());
    assert_eq!(m["pearson"].as_f64().unwrap(), p.pearson());
    assert_eq!(m["ssim"].as_f64().unwrap(), p.ssim().mean);
    assert_eq!(m["flip"].as_f64().unwrap(), p.flip().mean);
    assert_eq!(m.as_object().unwrap().len(), 5);
    assert_eq!(doc["width"], 64);
    assert_eq!(doc["pixels_excluded"], 0);
    // EXR inputs: `flip` is HDR-FLIP, with its exposures; identical images give PSNR null.
    let h = data("hdr_ref.exr");
    let out = run(&["compare", s(&h), s(&h), "--json"]);
    let doc: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(doc["metrics"]["hdr-flip"].as_f64(), Some(0.0));
    assert!(doc["metrics"]["psnr"].is_null());
    assert_eq!(doc["metrics"]["pearson"].as_f64(), Some(1.0));
    assert_eq!(doc["hdr_flip_exposures"].as_array().unwrap().len(), 6);
    // --flip ldr overrides.
    let out = run(&[
        "compare",
        s(&h),
        s(&data("hdr_dim.exr")),
        "--metrics",
        "flip",
        "--flip",
        "ldr",
        "--json",
    ]);
    let doc: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(doc["metrics"]["flip"].as_f64().unwrap() > 0.0);
}

#[test]
fn compare_writes_difference_images_and_maps() {
    let dir = scratch("maps");
    let (r, t) = (data("ref.png"), data("shifted.png"));
    let (diff_png, diff_exr) = (dir.join("diff.png"), dir.join("diff.exr"));
    let (flip_png, ssim_exr, abs_png) = (
        dir.join("flip.png"),
        dir.join("ssim.exr"),
        dir.join("abs.png"),
    );
    let out = run(&[
        "compare",
        s(&r),
        s(&t),
        "--metrics",
        "mean",
        "--diff",
        s(&diff_png),
        "--map",
        "flip",
        s(&flip_png),
        "--map",
        "ssim",
        s(&ssim_exr),
        "--map",
        "abs",
        s(&abs_png),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let (a, b) = (Image::read(&r).unwrap(), Image::read(&t).unwrap());
    let p = Pair::new(&a, &b).unwrap();
    // The negative difference PNG holds exactly the thesis' 8-bit codes.
    let neg = Image::read(&diff_png).unwrap();
    let want = negative_difference(&a, &b).unwrap();
    for (px, codes) in neg.pixels.iter().zip(&want) {
        assert_eq!(px.to_array().map(srgb8), *codes);
    }
    // The EXR difference is |a - b|.
    let out = run(&[
        "compare",
        s(&r),
        s(&t),
        "--metrics",
        "mean",
        "--diff",
        s(&diff_exr),
    ]);
    assert!(out.status.success());
    assert_eq!(Image::read(&diff_exr).unwrap(), p.difference());
    // The SSIM map in EXR holds the raw values; the PNG maps are grey levels of the error.
    let ssim = Image::read(&ssim_exr).unwrap();
    let map = p.ssim().map;
    assert!(ssim.pixels.iter().zip(&map).all(|(px, v)| px.x == *v));
    let flip = Image::read(&flip_png).unwrap();
    let fmap = p.flip().map;
    for (px, v) in flip.pixels.iter().zip(&fmap) {
        assert_eq!(srgb8(px.x), (v.clamp(0.0, 1.0) * 255.0).round() as u8);
    }
    assert_eq!(Image::read(&abs_png).unwrap().width, 64);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn quality_reports_the_quality_function_and_pixel_share() {
    let (m, i1, i2) = (data("ref.png"), data("blurred.png"), data("noisy.png"));
    let out = run(&["quality", s(&m), s(&i1), s(&i2), "--json"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let doc: Value = serde_json::from_slice(&out.stdout).unwrap();
    let q = imalyzer::quality(
        &Image::read(&m).unwrap(),
        &Image::read(&i1).unwrap(),
        &Image::read(&i2).unwrap(),
    )
    .unwrap();
    assert_eq!(doc["linear"]["f_q"], q.linear.f_q as i64);
    assert_eq!(doc["srgb8"]["f_q"], -1);
    assert_eq!(
        doc["linear"]["share_closer"].as_f64().unwrap(),
        q.linear.share_closer()
    );
    assert_eq!(doc["pixels_compared"], 3072);
    let out = run(&["quality", s(&m), s(&i1), s(&i2)]);
    assert!(text(&out.stdout).contains("f_q (eq. 21)"));
}

#[test]
fn bad_input_exits_non_zero_naming_the_file() {
    let dir = scratch("bad");
    let r = data("ref.png");
    // Missing file.
    let missing = dir.join("missing.png");
    let err = fails(&["compare", s(&r), s(&missing)], 1);
    assert!(err.contains("missing.png"), "{err}");
    // Truncated PNG.
    let truncated = dir.join("truncated.png");
    let bytes = std::fs::read(&r).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 3]).unwrap();
    let err = fails(&["compare", s(&r), s(&truncated)], 1);
    assert!(err.contains("truncated.png"), "{err}");
    // Truncated EXR and an empty file.
    let exr = dir.join("cut.exr");
    let bytes = std::fs::read(data("hdr_ref.exr")).unwrap();
    std::fs::write(&exr, &bytes[..bytes.len() / 2]).unwrap();
    let err = fails(&["compare", s(&exr), s(&r)], 1);
    assert!(err.contains("cut.exr"), "{err}");
    let empty = dir.join("empty.png");
    std::fs::write(&empty, b"").unwrap();
    let err = fails(&["quality", s(&r), s(&r), s(&empty)], 1);
    assert!(err.contains("empty.png"), "{err}");
    // Unknown extension.
    let txt = dir.join("image.txt");
    std::fs::write(&txt, b"not an image").unwrap();
    let err = fails(&["compare", s(&txt), s(&r)], 1);
    assert!(err.contains("image.txt"), "{err}");
    // Different sizes: both files named with their sizes.
    let small = dir.join("small.exr");
    Image::filled(8, 8, Vec3::ONE).write_exr(&small).unwrap();
    let err = fails(&["compare", s(&r), s(&small)], 1);
    assert!(
        err.contains("ref.png") && err.contains("small.exr") && err.contains("64x48"),
        "{err}"
    );
    let err = fails(&["quality", s(&small), s(&r), s(&r)], 1);
    assert!(err.contains("small.exr"), "{err}");
    // Bad requests fail before reading anything.
    let err = fails(&["compare", s(&r), s(&r), "--metrics", "mean,bogus"], 1);
    assert!(err.contains("bogus"), "{err}");
    let err = fails(&["compare", s(&r), s(&r), "--map", "colour", "x.png"], 1);
    assert!(err.contains("colour"), "{err}");
    let err = fails(
        &["compare", s(&r), s(&r), "--diff", s(&dir.join("d.jpg"))],
        1,
    );
    assert!(err.contains("d.jpg"), "{err}");
    let err = fails(
        &["compare", s(&r), s(&r), "--ppd=-3", "--metrics", "flip"],
        1,
    );
    assert!(err.contains("pixels per degree"), "{err}");
    // Usage errors are clap's (exit 2).
    fails(&["compare", s(&r)], 2);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn non_finite_values_are_refused_or_excluded_on_request() {
    let dir = scratch("nan");
    let a = Image::filled(16, 16, Vec3::splat(0.5));
    let mut b = a.clone();
    b.set(3, 4, Vec3::new(0.5, f32::NAN, 0.5));
    b.set(5, 6, Vec3::splat(f32::INFINITY));
    b.set(7, 7, Vec3::splat(0.6));
    let (pa, pb) = (dir.join("a.exr"), dir.join("b.exr"));
    a.write_exr(&pa).unwrap();
    b.write_exr(&pb).unwrap();
    let err = fails(&["compare", s(&pa), s(&pb)], 1);
    assert!(
        err.contains("b.exr") && err.contains("2 pixel(s)") && err.contains("x=3, y=4"),
        "{err}"
    );
    let out = run(&["compare", s(&pa), s(&pb), "--exclude-non-finite", "--json"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let doc: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(doc["pixels_excluded"], 2);
    assert_eq!(doc["non_finite_pixels"]["test"], 2);
    assert_eq!(doc["pixels_compared"], 254);
    // One pixel off by 0.1 in every channel among 254 compared.
    let mean = doc["metrics"]["mean-error"].as_f64().unwrap();
    assert!((mean - 0.1 / 254.0).abs() < 1e-7, "{mean}");
    assert!(doc["metrics"]["hdr-flip"].as_f64().unwrap().is_finite());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ztest_passes_and_fails_with_exit_codes() {
    let dir = scratch("ztest");
    let reference = Image::filled(16, 16, Vec3::splat(0.5));
    let variance = Image::filled(16, 16, Vec3::splat(1e-4));
    let (pr, pv) = (dir.join("ref.exr"), dir.join("var.exr"));
    reference.write_exr(&pr).unwrap();
    variance.write_exr(&pv).unwrap();
    // Identical: pass (exit 0).
    let out = run(&["ztest", s(&pr), s(&pr), "--variance", s(&pv), "--spp", "16"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(text(&out.stdout).starts_with("PASS"));
    // 2% brighter with a standard error of sqrt(1e-4 / 16) = 0.0025: z = 4 everywhere, below
    // the corrected critical z of 768 channels (about 4.4): pass. At 64 spp, z = 8: fail
    // (exit 3).
    let bright = Image::filled(16, 16, Vec3::splat(0.51));
    let pb = dir.join("bright.exr");
    bright.write_exr(&pb).unwrap();
    let args = |spp: &'static str| {
        vec![
            "ztest".to_string(),
            s(&pr).to_string(),
            s(&pb).to_string(),
            "--variance".into(),
            s(&pv).into(),
            "--spp".into(),
            spp.into(),
        ]
    };
    let a16: Vec<String> = args("16");
    let out = run(&a16.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(out.status.success(), "{}", text(&out.stdout));
    let a64 = args("64");
    let err = fails(&a64.iter().map(String::as_str).collect::<Vec<_>>(), 3);
    assert!(err.contains("bright.exr"), "{err}");
    // Against a noisy 16-spp reference the variances add (z = 3.6): the same 64-spp render
    // passes.
    let mut with_ref = a64.clone();
    with_ref.extend([
        "--ref-variance".into(),
        s(&pv).into(),
        "--ref-spp".into(),
        "16".into(),
    ]);
    let out = run(&with_ref.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(out.status.success(), "{}", text(&out.stdout));
    let _ = std::fs::remove_dir_all(&dir);
}
