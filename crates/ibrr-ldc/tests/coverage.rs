//! Coverage on a cluttered room (`builtin::cluttered_room`: shelves and table tops 2 cm
//! thick, legs and posts 2 to 3 cm square, books, small boxes), the surfaces real
//! interiors are made of and the LDC's pixels (about 2.3 cm here at the default 256) are
//! as large as: every visible surface pixel finds a layer, the documented fallback or the
//! hole fill (none is black), the fallback's and the fill's shares and errors are
//! reported, and the lit-surface bias against the
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
fn no_surface_pixel_of_a_cluttered_room_is_black_and_the_bias_stays_within_five_percent() {
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
    let (mut missing_samples, mut filled_samples, mut black_samples) = (0u64, 0u64, 0u64);
    let (mut err_layer, mut n_layer, mut err_fallback, mut n_fallback) =
        (0.0f64, 0u64, 0.0f64, 0u64);
    let (mut err_filled, mut n_filled) = (0.0f64, 0u64);
    let mut biases = Vec::new();
    // Per build (seed): surface samples filled, and those no fill reached.
    let mut per_seed = Vec::new();
    for seed in 1..=6u64 {
        let settings = IbrrSettings {
            target_error: 0.0,
            seed,
            ..Default::default()
        };
        let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
        t.prepare(scene.clone()).unwrap();
        let ldc = t.ldc().unwrap();
        let r = reconstruct(ldc, &g, &frame.view, settings.reading());
        let full = shade(&scene, &g, &frame.view, &r, frame.lights);
        let (filled_before, missing_before) = (filled_samples, missing_samples);
        for (i, class) in big_classes.iter().enumerate() {
            if *class != PixelClass::Surface || g.is_background(i) {
                continue;
            }
            surface_samples += 1;
            match r.served[i] {
                Served::Fallback => fallback_samples += 1,
                Served::Missing => missing_samples += 1,
                Served::Filled => filled_samples += 1,
                _ => {}
            }
            // Every surface of this closed room is lit (the reference has no black
            // surface pixel); a sample of a reflecting surface shaded black is a hole.
            if g.albedo[i].truncate().max_element() > 0.0 && full.pixels[i] == glam::Vec3::ZERO {
                black_samples += 1;
            }
        }
        per_seed.push((
            filled_samples - filled_before,
            missing_samples - missing_before,
        ));
        let img = full.box_down(SS);
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
            let from = |how: Served| {
                (0..SS * SS)
                    .filter(|k| {
                        let j = ((y * SS + k / SS) * bw + x * SS + k % SS) as usize;
                        r.served[j] == how
                    })
                    .count() as u32
            };
            if 2 * from(Served::Filled) > SS * SS {
                err_filled += e;
                n_filled += 1;
            } else if 2 * from(Served::Fallback) > SS * SS {
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
        "cluttered room: {fallback_samples} of {surface_samples} surface samples ({:.2} %) from the fallback, {filled_samples} ({:.2} %) filled, {missing_samples} without a layer or a fill, {black_samples} black; {n_fallback} of {surface} pixels mostly from the fallback, mean error there {:.3} of the surfaces' mean, {n_filled} mostly filled, {:.3} there, {:.3} elsewhere; filled / unfilled samples per seed {per_seed:?}; bias per seed {biases:+.3?}, over the seeds {bias:+.4?}",
        100.0 * fallback_samples as f64 / surface_samples as f64,
        100.0 * filled_samples as f64 / surface_samples as f64,
        err_fallback / n_fallback.max(1) as f64 / mean_ref,
        err_filled / n_filled.max(1) as f64 / mean_ref,
        err_layer / n_layer.max(1) as f64 / mean_ref,
    );
    assert!(surface > 0 && n_layer > 0);
    // Nearly every surface sample finds a layer or the fallback; the rest (slivers of
    // wall behind posts and boards whose layer centres the camera sees hidden, surfaces
    // no IRPL's render sampled: 0.73 % before the hole fill, 2026-11-27) are filled from
    // the pixels around them. None is left black.
    assert_eq!(
        (missing_samples, black_samples),
        (0, 0),
        "surface samples of {surface_samples} without a layer or a fill, and black"
    );
    for (c, b) in bias.iter().enumerate() {
        assert!(b.abs() <= 0.05, "channel {c}: bias {b:+.4}");
    }
}

/// The hole fill against what it stands for: on cornell, blocks of 3 x 3 and of 5 x 5
/// pixels that the LDC's layers served are knocked out (made holes) and filled from the
/// pixels around them; their filled indirect irradiance (a hole keeps no direct light) is
/// held against the layers' own, summed over the blocks, to the bounds this file holds the
/// fallback to (its pixels' mean error, 10 to 15 % of the surfaces' mean) and, on 3 x 3
/// holes, the bias to (5 %). A ring's mean is exact for light that varies linearly across
/// the hole; where it curves or the ring is cut by the image's border, it is not.
#[test]
fn the_hole_fill_estimates_knocked_out_pixels_from_the_pixels_around_them() {
    let scene = Arc::new(builtin::scene("cornell").unwrap());
    let settings = IbrrSettings {
        resolution: 128,
        irpls: 64,
        ..IbrrSettings::default().fixed_count()
    };
    let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    t.prepare(scene.clone()).unwrap();
    let ldc = t.ldc().unwrap();
    let (w, h) = (96u32, 72u32);
    let frame = FrameRequest::camera(&scene.cameras[0], w, h);
    let g = RayCastRenderer::new()
        .render(&scene, &frame.view, w, h)
        .unwrap();
    let full = reconstruct(ldc, &g, &frame.view, settings.reading());
    for half in [1u32, 2] {
        let mut holed = full.clone();
        let mut knocked = Vec::new();
        for cy in (6..h - 6).step_by(12) {
            for cx in (6..w - 6).step_by(12) {
                for y in cy - half..=cy + half {
                    for x in cx - half..=cx + half {
                        let i = (y * w + x) as usize;
                        if full.served[i] == Served::Layer {
                            holed.served[i] = Served::Missing;
                            holed.direct[i] = glam::Vec3::ZERO;
                            holed.indirect[i] = glam::Vec3::ZERO;
                            knocked.push(i);
                        }
                    }
                }
            }
        }
        ibrr_ldc::fill_holes(ldc, &g, &frame.view, settings.fill_radius, &mut holed);
        let e = |r: &ibrr_ldc::Reconstruction, i: usize| r.indirect[i];
        let (mut abs, mut sum, mut filled_sum) = (0.0f64, 0.0f64, 0.0f64);
        for &i in &knocked {
            assert_eq!(holed.served[i], Served::Filled, "pixel {i} not filled");
            assert_eq!(holed.direct[i], glam::Vec3::ZERO);
            let (a, b) = (e(&holed, i), e(&full, i));
            abs += f64::from((a - b).abs().element_sum());
            sum += f64::from(b.element_sum());
            filled_sum += f64::from(a.element_sum());
        }
        let (mae, bias) = (abs / sum, filled_sum / sum - 1.0);
        let side = 2 * half + 1;
        println!(
            "hole fill on cornell, {side} x {side} holes: {} pixels knocked out, mean |error| {:.2} % of their indirect irradiance, bias {:+.2} %",
            knocked.len(),
            100.0 * mae,
            100.0 * bias
        );
        assert!(knocked.len() > 150);
        assert_eq!(holed.filled, knocked.len() as u64 + full.filled);
        // Holes as real ones are (the cluttered room's are one or two samples wide) are held
        // to both bounds; at 5 x 5 the ring's mean also meets the light's curvature (the
        // floor at the boxes' feet, blocks 43 to 55 % bright), and its bias is printed.
        assert!(mae < 0.15, "{side} x {side}: mae {mae}");
        if side == 3 {
            assert!(bias.abs() < 0.05, "{side} x {side}: bias {bias}");
        }
    }
}
