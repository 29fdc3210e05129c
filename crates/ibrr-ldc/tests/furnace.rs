//! The IBRR in a furnace: a closed cube whose walls all emit `Le` and reflect `rho`, seen
//! from inside, has radiance `Le / (1 - rho)` everywhere (emission seen directly plus every
//! order of reflection). One build's image mean moves with its particle paths' lengths
//! (Russian roulette), so the check is on the mean over seeds, against its own standard
//! error: unbiased construction in every bounce, direct light exact for the first.

mod common;

use std::sync::Arc;

use ibrr_ldc::IbrrSettings;
use scene_core::{Scene, luminance};

fn furnace(albedo: f32, emission: f32) -> Scene {
    let mut s = scene_core::builtin::furnace(albedo, emission);
    s.validate().unwrap();
    s
}

/// The image mean of one build with `seed`.
fn mean_of(scene: &Arc<Scene>, settings: IbrrSettings) -> f64 {
    let (img, _) = common::ibrr_image(scene, settings, 16);
    img.pixels
        .iter()
        .map(|p| f64::from(luminance(*p)))
        .sum::<f64>()
        / img.pixels.len() as f64
}

#[test]
fn the_furnace_converges_to_le_over_one_minus_rho_over_seeds() {
    // Bounce-limited sums first (IRPLs of depth at most `d` give the orders 0 to d + 1):
    // the orders are each right. Then every order.
    let rho = 0.5f32;
    let scene = Arc::new(furnace(rho, 1.0));
    for (max_depth, expected) in [
        (0u32, 1.0 + 0.5),
        (1, 1.0 + 0.5 + 0.25),
        (32, 1.0 / (1.0 - f64::from(rho))),
    ] {
        let means: Vec<f64> = (1..=24u64)
            .map(|seed| {
                mean_of(
                    &scene,
                    IbrrSettings {
                        target_error: 0.0,
                        resolution: 32,
                        irpls: 256,
                        max_depth,
                        seed,
                        ..Default::default()
                    },
                )
            })
            .collect();
        let n = means.len() as f64;
        let m = means.iter().sum::<f64>() / n;
        let var = means.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
        let se = (var / n).sqrt();
        eprintln!(
            "max depth {max_depth}: mean over seeds {m:.4} (standard error {se:.4}), expected {expected:.4}; per seed {means:.3?}"
        );
        // The standard error must be small enough for the check to mean something.
        assert!(se < 0.02 * expected, "standard error {se} too large");
        assert!(
            (m - expected).abs() < 3.0 * se + 0.005 * expected,
            "max depth {max_depth}: {m} against {expected} (standard error {se})"
        );
    }
}
