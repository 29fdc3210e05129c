//! The IBRR's bias on lit surfaces against the reference path tracer: cornell (area light)
//! and cornell-point (point light), the default IRPL count, the mean over 24 seeds of each
//! channel's `sum(test) / sum(reference) - 1` over the pixels whose centre sees a
//! reflecting surface (emitters, background and the reference's brightest 1 % left out,
//! as the main job's surface error). One build's level moves by 4 to 7 % with its seed
//! (Monte Carlo over some 60 particle paths), so a single build says little about bias;
//! the mean over seeds, with its standard error, does. The LDC is at 64 (its resolution
//! does not move the bias: the furnace read 0.949, 0.952 and 0.949 at 64, 128 and 256).

mod common;

use std::sync::Arc;

use ibrr_ldc::IbrrSettings;
use scene_core::builtin;
use scene_core::reference::Bounces;

const SIZE: u32 = 32;
const SEEDS: u64 = 24;

fn bias_over_seeds(name: &str) -> ([f64; 3], [f64; 3]) {
    let scene = Arc::new(builtin::scene(name).unwrap());
    let reference = common::reference(&scene, SIZE, 4096, Bounces::Unlimited);
    let pixels = common::lit_surface_pixels(&scene, &reference, SIZE);
    let per_seed: Vec<[f64; 3]> = (1..=SEEDS)
        .map(|seed| {
            let settings = IbrrSettings {
                target_error: 0.0,
                resolution: 64,
                seed,
                ..Default::default()
            };
            let (img, _) = common::ibrr_image(&scene, settings, SIZE);
            common::channel_bias(&img, &reference, &pixels)
        })
        .collect();
    let n = per_seed.len() as f64;
    let mean = [0, 1, 2].map(|c| per_seed.iter().map(|b| b[c]).sum::<f64>() / n);
    let se = [0, 1, 2].map(|c| {
        let var = per_seed
            .iter()
            .map(|b| (b[c] - mean[c]).powi(2))
            .sum::<f64>()
            / (n - 1.0);
        (var / n).sqrt()
    });
    println!("{name}: lit-surface bias over {SEEDS} seeds {mean:+.4?} (standard error {se:.4?})");
    (mean, se)
}

#[test]
fn lit_surfaces_are_within_two_percent_of_the_reference_on_cornell_and_cornell_point() {
    for name in ["cornell", "cornell-point"] {
        let (mean, se) = bias_over_seeds(name);
        for c in 0..3 {
            // The test has the power to see a 2 % bias: its standard error is below that.
            assert!(
                se[c] < 0.02,
                "{name} channel {c}: standard error {:.4}",
                se[c]
            );
            // A bias beyond 2 % fails when the seeds show it (more than two standard errors
            // past 2 %, one-sided, about 98 % confidence). Measured 2026-11-25 at the
            // defaults (clamp 0.1, local compensation): cornell -1.5 / -1.3 / -0.4 %,
            // cornell-point -1.7 / -2.1 / -0.8 % (standard errors 0.9 to 1.4 %): a dark bias
            // of 1 to 2 % remains, the 2 % bound met on cornell and at its edge on
            // cornell-point's green (docs/ibrr-ldc.md).
            assert!(
                mean[c].abs() <= 0.02 + 2.0 * se[c],
                "{name} channel {c}: bias {:+.4} (standard error {:.4})",
                mean[c],
                se[c]
            );
        }
    }
}
