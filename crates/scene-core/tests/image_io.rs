//! Image I/O: EXR exact, PNG within 8-bit quantisation, bad files give typed errors and leave
//! nothing half-written.

use scene_core::glam::Vec3;
use scene_core::image::{linear_to_srgb, luminance, srgb_to_linear};
use scene_core::sampling::Rng;
use scene_core::{Image, ImageError};

fn temp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("scene-core-img-{}-{name}", std::process::id()))
}

fn random_image(w: u32, h: u32, seed: u64) -> Image {
    let mut rng = Rng::new(seed, 0);
    let px = (0..w * h)
        .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 3.0)
        .collect();
    Image::from_pixels(w, h, px).unwrap()
}

#[test]
fn exr_round_trips_exactly() {
    let img = random_image(13, 7, 1);
    let p = temp("a.exr");
    img.write_exr(&p).unwrap();
    assert_eq!(Image::read_exr(&p).unwrap(), img);
    assert_eq!(Image::read(&p).unwrap(), img);
    std::fs::remove_file(p).ok();
}

#[test]
fn png_round_trips_within_quantisation() {
    let mut img = random_image(9, 5, 2);
    for p in &mut img.pixels {
        *p = p.min(Vec3::ONE);
    }
    let p = temp("a.png");
    img.write_png(&p, 0.0).unwrap();
    let back = Image::read_png(&p).unwrap();
    std::fs::remove_file(&p).ok();
    for (a, b) in img.pixels.iter().zip(&back.pixels) {
        // Half an 8-bit step in sRGB, mapped back to linear.
        for c in 0..3 {
            let (x, y) = (a[c], b[c]);
            let s = linear_to_srgb(x);
            let bound = (srgb_to_linear((s + 0.5 / 255.0).min(1.0)) - x)
                .abs()
                .max((x - srgb_to_linear((s - 0.5 / 255.0).max(0.0))).abs());
            assert!((x - y).abs() <= bound + 1e-6, "{x} vs {y}");
        }
    }
}

#[test]
fn exposure_scales_before_encoding() {
    let img = Image::filled(2, 2, Vec3::splat(0.25));
    let p = temp("exp.png");
    img.write_png(&p, 1.0).unwrap();
    let back = Image::read_png(&p).unwrap();
    std::fs::remove_file(&p).ok();
    assert!((back.get(0, 0).x - 0.5).abs() < 0.005);
}

#[test]
fn srgb_curve_is_inverse_and_matches_known_values() {
    assert!((linear_to_srgb(0.5) - 0.735_357).abs() < 1e-5);
    assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
    for i in 0..=100 {
        let x = i as f32 / 100.0;
        assert!((srgb_to_linear(linear_to_srgb(x)) - x).abs() < 1e-5);
    }
}

#[test]
fn luminance_uses_eq_17_weights() {
    assert_eq!(luminance(Vec3::X), 0.27);
    assert_eq!(luminance(Vec3::Y), 0.67);
    assert_eq!(luminance(Vec3::Z), 0.06);
    assert!((luminance(Vec3::ONE) - 1.0).abs() < 1e-6);
}

#[test]
fn truncated_and_garbage_files_are_typed_errors() {
    let img = random_image(16, 16, 3);
    for ext in ["exr", "png"] {
        let good = temp(&format!("good.{ext}"));
        if ext == "exr" {
            img.write_exr(&good).unwrap()
        } else {
            img.write_png(&good, 0.0).unwrap()
        }
        let bytes = std::fs::read(&good).unwrap();
        // (A PNG missing only its trailing IEND chunk still holds every pixel and decodes, so
        // the cuts fall inside the pixel data.)
        for cut in [0, 8, bytes.len() / 3, bytes.len() / 2] {
            let bad = temp(&format!("bad{cut}.{ext}"));
            std::fs::write(&bad, &bytes[..cut]).unwrap();
            match Image::read(&bad) {
                Err(ImageError::Read { path, .. }) => assert_eq!(path, bad),
                other => panic!("{ext} cut at {cut}: {other:?}"),
            }
            std::fs::remove_file(&bad).ok();
        }
        std::fs::remove_file(&good).ok();
    }
    assert!(matches!(
        Image::read(&temp("missing.exr")),
        Err(ImageError::Read { .. })
    ));
    assert!(matches!(
        Image::read(&temp("x.jpg")),
        Err(ImageError::Read { .. })
    ));
}

#[test]
fn zero_size_and_bad_length_are_rejected_and_nothing_is_written() {
    let p = temp("zero.exr");
    assert!(matches!(
        Image::new(0, 5).write_exr(&p),
        Err(ImageError::ZeroSize { .. })
    ));
    assert!(!p.exists());
    assert!(matches!(
        Image::from_pixels(2, 2, vec![Vec3::ZERO; 3]),
        Err(ImageError::BadLength { .. })
    ));
    // A write into a missing directory fails without leaving a temporary file.
    let dir = temp("no-such-dir");
    let p = dir.join("a.png");
    assert!(matches!(
        Image::new(2, 2).write_png(&p, 0.0),
        Err(ImageError::Write { .. })
    ));
    assert!(!dir.exists());
}

#[test]
fn nan_pixels_are_counted_and_written_black_in_png() {
    let mut img = Image::filled(2, 1, Vec3::splat(0.5));
    img.pixels[0] = Vec3::new(f32::NAN, 0.5, 0.5);
    assert_eq!(img.non_finite_count(), 1);
    let p = temp("nan.png");
    img.write_png(&p, 0.0).unwrap();
    let back = Image::read_png(&p).unwrap();
    std::fs::remove_file(&p).ok();
    assert_eq!(back.get(0, 0).x, 0.0);
}
