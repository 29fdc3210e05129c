//! The statistical test: renders of the reference path tracer at another seed pass, a
//! render 2% too bright fails; synthetic Gaussian noise of known variance checks the
//! exact-reference form and the bookkeeping.

use imalyzer::scene_core::glam::Vec3;
use imalyzer::scene_core::reference::{Bounces, ReferenceOutput, ReferenceSettings, render};
use imalyzer::scene_core::sampling::Rng;
use imalyzer::scene_core::{Image, View, builtin};
use imalyzer::{CompareError, Estimate, NonFinite, ZTestOptions, z_test, z_test_noisy_reference};

/// Boxes and spheres under a sun, direct light plus one bounce: bright enough that the
/// variance floor does not hide a 2% bias, noisy enough to exercise the test.
fn primitives(seed: u64) -> ReferenceOutput {
    let scene = builtin::scene("primitives").unwrap();
    let view = View::from_camera(&scene.cameras[0]);
    let settings = ReferenceSettings {
        width: 24,
        height: 24,
        spp: 128,
        bounces: Bounces::Limited(1),
        seed,
    };
    render(&scene, &view, &settings, None)
}

fn scaled(img: &Image, s: f32) -> Image {
    Image {
        pixels: img.pixels.iter().map(|p| *p * s).collect(),
        ..img.clone()
    }
}

#[test]
fn renders_at_other_seeds_pass_and_a_two_percent_bias_fails() {
    let reference = primitives(1);
    let options = ZTestOptions::default();
    for seed in [2, 3] {
        let test = primitives(seed);
        let r = z_test_noisy_reference(&(&reference).into(), &(&test).into(), &options).unwrap();
        eprintln!("seed {seed}: {r:?}");
        assert!(r.passed, "seed {seed} rejected: {r:?}");
        assert_eq!(r.channels, 3 * 24 * 24);
        assert!(r.max_z < r.z_critical);
    }
    let test = primitives(2);
    // 2% brighter: the mean and its standard deviation scale together.
    let (image, variance) = (
        scaled(&test.image, 1.02),
        scaled(&test.variance, 1.02 * 1.02),
    );
    let biased = Estimate {
        image: &image,
        variance: &variance,
        spp: test.spp,
    };
    let r = z_test_noisy_reference(&(&reference).into(), &biased, &options).unwrap();
    eprintln!("biased: {r:?}");
    assert!(!r.passed, "2% bias accepted: {r:?}");
    assert!(r.failed as f64 > 0.01 * r.channels as f64);
    assert!((r.relative_bias - 0.02).abs() < 0.01, "{}", r.relative_bias);
    // The darker direction fails too.
    let (image, variance) = (
        scaled(&test.image, 0.98),
        scaled(&test.variance, 0.98 * 0.98),
    );
    let darker = Estimate {
        image: &image,
        variance: &variance,
        spp: test.spp,
    };
    assert!(
        !z_test_noisy_reference(&(&reference).into(), &darker, &options)
            .unwrap()
            .passed
    );
}

/// A 64x64 "render" of a constant 0.5 with Gaussian noise of per-sample variance `var` at
/// `spp` samples.
fn synthetic(seed: u64, var: f32, spp: u32, bias: f32) -> (Image, Image) {
    let mut rng = Rng::new(seed, 0);
    let sd = (var / spp as f32).sqrt();
    let mut gauss = || {
        // Box-Muller.
        let u = rng.next_vec2();
        (-2.0 * (1.0 - u.x).ln()).sqrt() * (std::f32::consts::TAU * u.y).cos()
    };
    let pixels = (0..64 * 64)
        .map(|_| Vec3::new(gauss(), gauss(), gauss()) * sd + Vec3::splat(0.5 * (1.0 + bias)))
        .collect();
    (
        Image::from_pixels(64, 64, pixels).unwrap(),
        Image::filled(64, 64, Vec3::splat(var)),
    )
}

#[test]
fn exact_reference_form_on_known_noise() {
    let reference = Image::filled(64, 64, Vec3::splat(0.5));
    let options = ZTestOptions::default();
    let (img, var) = synthetic(7, 0.04, 64, 0.0);
    let est = Estimate {
        image: &img,
        variance: &var,
        spp: 64,
    };
    let ok = z_test(&reference, &est, &options).unwrap();
    assert!(ok.passed && ok.failed == 0, "{ok:?}");
    // Šidák: N = 12288 channels at alpha 0.01 (the direct formula cancels: 1e-9 relative).
    let want = 1.0 - (1.0f64 - 0.01).powf(1.0 / 12288.0);
    assert!(
        ((ok.channel_level - want) / want).abs() < 1e-9,
        "{}",
        ok.channel_level
    );
    assert!(
        ok.z_critical > 4.0 && ok.z_critical < 5.5,
        "{}",
        ok.z_critical
    );

    // sigma of the mean = 0.025; a 2% bias is 0.01 = 0.4 sigma per channel: too small to
    // see per pixel at this noise level, so the test (rightly) passes ...
    let (img, var) = synthetic(8, 0.04, 64, 0.02);
    let weak = Estimate {
        image: &img,
        variance: &var,
        spp: 64,
    };
    assert!(z_test(&reference, &weak, &options).unwrap().passed);
    // ... and at 64x less variance (sigma 0.003, bias 3.2 sigma) it fails.
    let (img, var) = synthetic(8, 0.04 / 64.0, 64, 0.02);
    let strong = Estimate {
        image: &img,
        variance: &var,
        spp: 64,
    };
    let r = z_test(&reference, &strong, &options).unwrap();
    assert!(!r.passed, "{r:?}");
    // One pixel-channel off by 1 in an otherwise exact image: 1 failure of 12288, which is
    // within the 0.25% allowance.
    let mut one = reference.clone();
    one.set(3, 5, Vec3::new(0.5, 1.5, 0.5));
    let zero = Image::new(64, 64);
    let r = z_test(
        &reference,
        &Estimate {
            image: &one,
            variance: &zero,
            spp: 4,
        },
        &options,
    )
    .unwrap();
    assert_eq!((r.failed, r.worst), (1, (3, 5, 1)));
    // z = 1 * sqrt(4 / 1e-4) = 200 through the variance floor.
    assert!((r.max_z - 200.0).abs() < 1e-3, "{}", r.max_z);
    assert!(r.passed);
}

#[test]
fn bad_input_is_refused() {
    let a = Image::filled(4, 4, Vec3::ONE);
    let small = Image::filled(4, 3, Vec3::ONE);
    let est = |img: &'static Image, spp| Estimate {
        image: img,
        variance: img,
        spp,
    };
    let leak = |i: Image| -> &'static Image { Box::leak(Box::new(i)) };
    let options = ZTestOptions::default();
    let e = z_test(&a, &est(leak(small), 4), &options).unwrap_err();
    assert!(matches!(e, CompareError::SizeMismatch { .. }), "{e}");
    let e = z_test(&a, &est(leak(a.clone()), 0), &options).unwrap_err();
    assert!(e.to_string().contains("0 samples"), "{e}");
    let mut nan = a.clone();
    nan.set(1, 2, Vec3::new(0.0, f32::NAN, 0.0));
    let nan = leak(nan);
    let e = z_test(&a, &est(nan, 4), &options).unwrap_err();
    assert!(e.to_string().contains("x=1, y=2"), "{e}");
    let excluding = ZTestOptions {
        non_finite: NonFinite::Exclude,
        ..options
    };
    let r = z_test(&a, &est(nan, 4), &excluding).unwrap();
    assert_eq!(r.channels, 3 * 15);
    let bad = ZTestOptions {
        significance: 0.0,
        ..options
    };
    assert!(z_test(&a, &est(leak(a.clone()), 4), &bad).is_err());
}
