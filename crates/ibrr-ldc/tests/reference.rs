//! The IBRR against the reference path tracer.

mod common;

use std::sync::Arc;

use common::{errors, ibrr_image, reference};
use ibrr_ldc::IbrrSettings;
use scene_core::builtin;
use scene_core::reference::Bounces;

#[test]
fn cornell_point_direct_light_matches_the_reference_at_bounce_zero() {
    let scene = Arc::new(builtin::scene("cornell-point").unwrap());
    let reference = reference(&scene, 64, 16, Bounces::Limited(0));
    for res in [64u32, 128, 256] {
        // One IRPL: the point light's own cube, no paths.
        let settings = IbrrSettings { resolution: res, irpls: 1, ..Default::default() };
        let (img, t) = ibrr_image(&scene, settings, 64);
        let (mae, bias) = errors(&img, &reference);
        println!("res {res}: mae {mae:.4} bias {bias:.4} layers {} missing {}", t.ldc().unwrap().layer_count(), t.last_timings().missing);
    }
}

#[test]
fn unlimited_bounces_against_the_reference() {
    for name in ["cornell", "cornell-point"] {
        let scene = Arc::new(builtin::scene(name).unwrap());
        let reference = reference(&scene, 48, 512, Bounces::Unlimited);
        for (res, irpls) in [(64u32, 32u32), (128, 96), (128, 184)] {
            let settings = IbrrSettings { resolution: res, irpls, ..Default::default() };
            let t0 = std::time::Instant::now();
            let (img, t) = ibrr_image(&scene, settings, 48);
            let (mae, bias) = errors(&img, &reference);
            println!("{name} res {res} irpls {irpls}: mae {mae:.4} bias {bias:.4} layers {} missing {} {:?}", t.ldc().unwrap().layer_count(), t.last_timings().missing, t0.elapsed());
        }
    }
}
