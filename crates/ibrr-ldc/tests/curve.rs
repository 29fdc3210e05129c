//! The error against the IRPL count (docs/ibrr-ldc.md, "Error against the IRPL count"), a
//! measurement run by hand (`cargo test --release -p ibrr-ldc --test curve -- --ignored
//! --nocapture`, about 3 minutes on 2 cores): cornell and cornell-point, camera 0 at 32 x
//! 32 (4 x 4 G-buffer samples a pixel), LDC 64, 8 seeds per count, lit surfaces (as
//! `tests/bias.rs`) against a 4096-spp unlimited reference. Printed per count: the mean
//! error as a share of the surfaces' mean (averaged over the seeds), and the level's
//! bias and spread over the seeds. The mean error must fall at every doubling.

mod common;

use std::sync::Arc;

use ibrr_ldc::IbrrSettings;
use scene_core::reference::Bounces;
use scene_core::{builtin, luminance};

const SIZE: u32 = 32;
const SEEDS: u64 = 8;

#[test]
#[ignore = "a measurement (about 3 minutes in release): run by hand"]
fn the_error_falls_as_irpls_are_added() {
    for name in ["cornell", "cornell-point"] {
        let scene = Arc::new(builtin::scene(name).unwrap());
        let reference = common::reference(&scene, SIZE, 4096, Bounces::Unlimited);
        let pixels = common::lit_surface_pixels(&scene, &reference, SIZE);
        let ref_sum: f64 = pixels
            .iter()
            .map(|&i| f64::from(luminance(reference.pixels[i])))
            .sum();
        let mut last = f64::INFINITY;
        for irpls in [44u32, 88, 177, 354, 708] {
            let (mut errors, mut levels) = (Vec::new(), Vec::new());
            for seed in 1..=SEEDS {
                let settings = IbrrSettings {
                    target_error: 0.0,
                    resolution: 64,
                    irpls,
                    seed,
                    ..Default::default()
                };
                let (img, _) = common::ibrr_image(&scene, settings, SIZE);
                let (mut e, mut t) = (0.0f64, 0.0f64);
                for &i in &pixels {
                    let (a, b) = (luminance(img.pixels[i]), luminance(reference.pixels[i]));
                    e += f64::from((a - b).abs());
                    t += f64::from(a);
                }
                errors.push(e / ref_sum);
                levels.push(t / ref_sum - 1.0);
            }
            let n = SEEDS as f64;
            let error = errors.iter().sum::<f64>() / n;
            let bias = levels.iter().sum::<f64>() / n;
            let spread =
                (levels.iter().map(|l| (l - bias).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            println!(
                "{name}: {irpls} IRPLs: error {:.1} %, level bias {:+.1} %, spread {:.1} %",
                100.0 * error,
                100.0 * bias,
                100.0 * spread
            );
            assert!(
                error < last,
                "{name}: {error} at {irpls} IRPLs after {last}"
            );
            last = error;
        }
    }
}
