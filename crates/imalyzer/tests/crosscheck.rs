//! Agreement with independent implementations on fixed image pairs: SSIM with
//! scikit-image, LDR- and HDR-FLIP with NVIDIA's flip-evaluator, the simple measures with
//! numpy. `tests/data/generate.py` made the images and `tests/data/expected.json`.

use std::path::{Path, PathBuf};

use imalyzer::scene_core::Image;
use imalyzer::scene_core::glam::Vec3;
use imalyzer::{FlipOptions, Pair};
use serde_json::Value;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn expected() -> Vec<Value> {
    let text = std::fs::read_to_string(data("expected.json")).unwrap();
    let doc: Value = serde_json::from_str(&text).unwrap();
    doc["pairs"].as_array().unwrap().clone()
}

fn images(entry: &Value) -> (Image, Image, String) {
    let r = entry["reference"].as_str().unwrap();
    let t = entry["test"].as_str().unwrap();
    (
        Image::read(&data(r)).unwrap(),
        Image::read(&data(t)).unwrap(),
        format!("{r} vs {t}"),
    )
}

fn close(name: &str, what: &str, got: f64, want: f64, tol: f64) {
    eprintln!(
        "{name:28} {what:16} imalyzer {got:.7}  expected {want:.7}  diff {:.2e}",
        (got - want).abs()
    );
    assert!(
        (got - want).abs() <= tol,
        "{name}: {what} = {got}, expected {want} within {tol}"
    );
}

#[test]
fn ssim_agrees_with_scikit_image() {
    for e in expected() {
        let (a, b, name) = images(&e);
        let pair = Pair::new(&a, &b).unwrap();
        close(
            &name,
            "ssim",
            pair.ssim().mean,
            e["ssim"].as_f64().unwrap(),
            1e-4,
        );
    }
}

#[test]
fn ldr_flip_agrees_with_flip_evaluator() {
    for e in expected() {
        let (a, b, name) = images(&e);
        let pair = Pair::new(&a, &b).unwrap();
        close(
            &name,
            "flip",
            pair.flip().mean,
            e["flip"].as_f64().unwrap(),
            1e-3,
        );
    }
}

#[test]
fn hdr_flip_agrees_with_flip_evaluator() {
    for e in expected().iter().filter(|e| e.get("hdr_flip").is_some()) {
        let (a, b, name) = images(e);
        let pair = Pair::new(&a, &b).unwrap();
        let (start, stop, n) = pair.hdr_exposures(&FlipOptions::default()).unwrap();
        close(
            &name,
            "start exposure",
            start as f64,
            e["hdr_start_exposure"].as_f64().unwrap(),
            1e-5,
        );
        close(
            &name,
            "stop exposure",
            stop as f64,
            e["hdr_stop_exposure"].as_f64().unwrap(),
            1e-5,
        );
        assert_eq!(n as u64, e["hdr_exposures"].as_u64().unwrap());
        let f = pair.hdr_flip();
        assert_eq!(f.exposures.len(), n);
        close(
            &name,
            "hdr-flip",
            f.mean,
            e["hdr_flip"].as_f64().unwrap(),
            1e-3,
        );
    }
}

#[test]
fn simple_measures_agree_with_numpy() {
    for e in expected() {
        let (a, b, name) = images(&e);
        let p = Pair::new(&a, &b).unwrap();
        let want = |k: &str| e[k].as_f64().unwrap();
        close(
            &name,
            "mean error",
            p.mean_error(),
            want("mean_error"),
            1e-6 * want("mean_error").max(1.0),
        );
        close(
            &name,
            "mean error 8-bit",
            p.mean_error_8bit(),
            want("mean_error_8bit"),
            1e-9,
        );
        close(&name, "pearson", p.pearson(), want("pearson"), 1e-6);
        close(
            &name,
            "rmse",
            p.rmse(),
            want("rmse"),
            1e-6 * want("rmse").max(1.0),
        );
        close(&name, "psnr", p.psnr(), want("psnr"), 1e-4);
        close(
            &name,
            "relmse",
            p.relmse(),
            want("relmse"),
            1e-6 * want("relmse").max(1.0),
        );
        close(&name, "smape", p.smape(), want("smape"), 1e-6);
    }
}

#[test]
fn flip_of_uniform_images_and_a_firefly_agree_with_flip_evaluator() {
    let text = std::fs::read_to_string(data("expected.json")).unwrap();
    let doc: Value = serde_json::from_str(&text).unwrap();
    for u in doc["uniform"].as_array().unwrap() {
        let (a, b) = (
            u["reference"].as_f64().unwrap() as f32,
            u["test"].as_f64().unwrap() as f32,
        );
        let ra = Image::filled(16, 16, Vec3::splat(a));
        let rb = Image::filled(16, 16, Vec3::splat(b));
        let f = Pair::new(&ra, &rb).unwrap().flip();
        close(
            &format!("uniform {a} vs {b}"),
            "flip",
            f.mean,
            u["flip"].as_f64().unwrap(),
            1e-4,
        );
    }
    let black = Image::new(16, 16);
    let mut spot = black.clone();
    spot.set(8, 8, Vec3::ONE);
    let f = Pair::new(&black, &spot).unwrap().flip();
    let want = &doc["firefly"];
    close(
        "firefly",
        "flip",
        f.mean,
        want["flip"].as_f64().unwrap(),
        1e-4,
    );
    close(
        "firefly",
        "flip at (8, 8)",
        f.map[8 * 16 + 8] as f64,
        want["flip_at_8_8"].as_f64().unwrap(),
        1e-4,
    );
    let max = f.map.iter().copied().fold(0.0f32, f32::max);
    close(
        "firefly",
        "flip max",
        max as f64,
        want["flip_max"].as_f64().unwrap(),
        1e-4,
    );
}
