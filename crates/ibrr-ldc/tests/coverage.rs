//! Coverage on a cluttered room (`builtin::cluttered_room`: shelves and table tops 2 cm
//! thick, legs and posts 2 to 3 cm square, books, small boxes), the surfaces real
//! interiors are made of and the LDC's pixels (about 2.3 cm here at the default 256) are
//! as large as: every visible surface pixel finds a layer or the documented fallback,
//! the fallback's share and its error are reported, and the lit-surface bias against the
//! reference path tracer, taken over seeds (one build's level moves by about 5 % with its
//! seed), stays within 5 %.

use std::sync::Arc;

use ibrr_ldc::{IbrrSettings, IbrrTechnique, Served, reconstruct, shade};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::reference::{Bounces, PathTracer, PixelClass, ReferenceSettings, render};
use scene_core::{FrameRequest, GBufferRenderer, Scene, Technique, builtin};

const W: u32 = 48;
const H: u32 = 36;

fn room() -> Arc<Scene> {
    let mut s = builtin::cluttered_room(40, 1);
    s.validate().unwrap();
    Arc::new(s)
}

/// G-buffer samples per pixel side: the camera's G-buffer is the IBRR's visibility test
/// at lookup, so it is rendered at a working resolution (192 x 144) and the image
/// averaged down to the reference's pixels, as the reference averages over each pixel.
const SS: u32 = 4;

#[test]
fn every_surface_pixel_of_a_cluttered_room_finds_a_layer_and_the_bias_stays_within_five_percent() {
    let scene = room();
    let frame = FrameRequest::camera(&scene.cameras[0], W, H);
    let reference = render(
        &scene,
        &frame.view,
        &ReferenceSettings {
            width: W,
            height: H,
            spp: 512,
            bounces: Bounces::Unlimited,
            seed: 3,
        },
        None,
    )
    .image;
    let classes = PathTracer::new(&scene).pixel_classes(&frame.view, W, H);
    let (bw, bh) = (W * SS, H * SS);
    let big_classes = PathTracer::new(&scene).pixel_classes(&frame.view, bw, bh);
    let g = RayCastRenderer::new()
        .render(&scene, &frame.view, bw, bh)
        .unwrap();
    let (mut sum_test, mut sum_ref) = ([0.0f64; 3], [0.0f64; 3]);
    let (mut fallback_samples, mut surface_samples) = (0u64, 0u64);
    let mut surface = 0u64;
    let mut missing_samples = 0u64;
    let (mut err_layer, mut n_layer, mut err_fallback, mut n_fallback) =
        (0.0f64, 0u64, 0.0f64, 0u64);
    let mut biases = Vec::new();
    for seed in 1..=6u64 {
        let settings = IbrrSettings {
            target_error: 0.0,
            seed,
            ..Default::default()
        };
        let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
        t.prepare(scene.clone()).unwrap();
        let ldc = t.ldc().unwrap();
        let r = reconstruct(
            ldc,
            &g,
            &frame.view,
            settings.lookup,
            settings.fallback_radius,
        );
        let mut missing = 0;
        for (i, class) in big_classes.iter().enumerate() {
            if *class != PixelClass::Surface || g.is_background(i) {
                continue;
            }
            surface_samples += 1;
            match r.served[i] {
                Served::Fallback => fallback_samples += 1,
                Served::Missing => missing += 1,
                _ => {}
            }
        }
        missing_samples += missing;
        let img = shade(&scene, &g, &frame.view, &r, frame.lights).box_down(SS);
        let (mut st, mut sr) = ([0.0f64; 3], [0.0f64; 3]);
        for (i, class) in classes.iter().enumerate() {
            if *class != PixelClass::Surface {
                continue;
            }
            surface += 1;
            let (a, b) = (img.pixels[i], reference.pixels[i]);
            let e = f64::from((a - b).abs().element_sum() / 3.0);
            // A pixel is the fallback's when most of its samples came from it.
            let (x, y) = (i as u32 % W, i as u32 / W);
            let from_fallback = (0..SS * SS)
                .filter(|k| {
                    let j = ((y * SS + k / SS) * bw + x * SS + k % SS) as usize;
                    r.served[j] == Served::Fallback
                })
                .count() as u32;
            if 2 * from_fallback > SS * SS {
                err_fallback += e;
                n_fallback += 1;
            } else {
                err_layer += e;
                n_layer += 1;
            }
            for c in 0..3 {
                st[c] += f64::from(a[c]);
                sr[c] += f64::from(b[c]);
            }
        }
        biases.push([0, 1, 2].map(|c| st[c] / sr[c] - 1.0));
        for c in 0..3 {
            sum_test[c] += st[c];
            sum_ref[c] += sr[c];
        }
    }
    let mean_ref = sum_ref.iter().sum::<f64>() / 3.0 / surface as f64;
    let bias = [0, 1, 2].map(|c| sum_test[c] / sum_ref[c] - 1.0);
    println!(
        "cluttered room: {fallback_samples} of {surface_samples} surface samples ({:.1} %) from the fallback, {missing_samples} without a layer; {n_fallback} of {surface} pixels mostly from it, mean error there {:.3} of the surfaces' mean, {:.3} elsewhere; bias per seed {biases:+.3?}, over the seeds {bias:+.4?}",
        100.0 * fallback_samples as f64 / surface_samples as f64,
        err_fallback / n_fallback.max(1) as f64 / mean_ref,
        err_layer / n_layer.max(1) as f64 / mean_ref,
    );
    assert!(surface > 0 && n_layer > 0);
    // Nearly every surface sample finds a layer or the fallback; the rest (slivers of
    // wall behind posts and boards whose layer centres the camera sees hidden, surfaces
    // no IRPL's render sampled) are black and counted in `FrameTimings::missing`: 0.49 %
    // measured (2026-11-25), 0.73 % with the stratified bounces (2026-11-27: other walks,
    // other renders), 4.3 % before the last resort. The bound of 1 % guards against that
    // regression.
    assert!(
        missing_samples * 100 <= surface_samples,
        "{missing_samples} of {surface_samples} surface samples without a layer"
    );
    for (c, b) in bias.iter().enumerate() {
        assert!(b.abs() <= 0.05, "channel {c}: bias {b:+.4}");
    }
}
