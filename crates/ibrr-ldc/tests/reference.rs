//! The IBRR against the reference path tracer: direct light alone at bounce limit 0, and
//! unlimited bounces, with the error falling as the LDC resolution and the IRPL count
//! grow. The IBRR images average 4 x 4 G-buffer samples per pixel, as the reference
//! averages its jittered samples (see `common::ibrr_image`).

mod common;

use std::sync::Arc;

use common::{errors, errors_below_quantile, ibrr_image, reference};
use ibrr_ldc::IbrrSettings;
use scene_core::builtin;
use scene_core::reference::Bounces;

#[test]
fn cornell_point_direct_light_matches_the_reference_at_bounce_zero() {
    let scene = Arc::new(builtin::scene("cornell-point").unwrap());
    let reference = reference(&scene, 48, 16, Bounces::Limited(0));
    let mut maes = Vec::new();
    for res in [48u32, 128] {
        // One IRPL: the point light's own cube, no paths.
        let settings = IbrrSettings {
            target_error: 0.0,
            resolution: res,
            irpls: 1,
            ..Default::default()
        };
        let (img, t) = ibrr_image(&scene, settings, 48);
        assert_eq!(t.construction().unwrap().irpls.irpls.len(), 1);
        let (mae, bias) = errors(&img, &reference);
        let (mae_98, bias_98) = errors_below_quantile(&img, &reference, 0.98);
        println!(
            "LDC {res}: mean abs error {mae:.4}, bias {bias:+.4}; without the brightest 2%: {mae_98:.4}, {bias_98:+.4}"
        );
        maes.push((mae_98, bias_98));
    }
    // Most of the whole image's error (0.13 at LDC 128) is the hot spot on the ceiling 1 cm
    // above the light, which changes faster than an LDI pixel and than the reference's 16
    // jittered samples resolve; the rest of the image is held to a tighter bound.
    assert!(maes[1].0 < maes[0].0, "{maes:?}");
    assert!(maes[1].0 < 0.06 && maes[1].1.abs() < 0.03, "{maes:?}");
}

#[test]
fn unlimited_bounces_against_the_reference() {
    for (name, spp, max_mae) in [("cornell", 512, 0.12), ("cornell-point", 1024, 0.19)] {
        let scene = Arc::new(builtin::scene(name).unwrap());
        let reference = reference(&scene, 48, spp, Bounces::Unlimited);
        let mut out = Vec::new();
        for (res, irpls) in [(48u32, 32u32), (128, 184)] {
            let settings = IbrrSettings {
                target_error: 0.0,
                resolution: res,
                irpls,
                ..Default::default()
            };
            let (img, t) = ibrr_image(&scene, settings, 48);
            let (mae, bias) = errors(&img, &reference);
            let ldc = t.ldc().unwrap();
            println!(
                "{name}: LDC {res}, {} IRPLs: mean abs error {mae:.4}, bias {bias:+.4}, {} layers, {} bytes",
                t.construction().unwrap().irpls.irpls.len(),
                ldc.layer_count(),
                ldc.bytes()
            );
            out.push((mae, bias));
        }
        // The reference's own noise is part of the error: cornell-point's at 1024 spp is
        // about 0.15 of the mean (its 512 spp image differs from a 2048 spp one by 0.21).
        assert!(out[1].0 < out[0].0, "{name}: error does not fall: {out:?}");
        assert!(
            out[1].0 < max_mae && out[1].1.abs() < 0.05,
            "{name}: {out:?}"
        );
    }
}
