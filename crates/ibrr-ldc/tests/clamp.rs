//! The clamp with local bias compensation: hot spots near IRPLs fall, and the energy the
//! clamp removes comes back where it was lost (near corners and contacts, where surfaces
//! are within the clamp's reach of each other), not spread over the scene.

mod common;

use std::sync::Arc;

use ibrr_ldc::{Compensation, IbrrSettings};
use scene_core::reference::{Bounces, PathTracer, PixelClass};
use scene_core::view::{FrustumReconstruction, pixel_uv};
use scene_core::{FrameRequest, GBufferRenderer, Image, builtin, luminance};

const SIZE: u32 = 32;

struct Measures {
    /// Mean absolute luminance error near corners, over the reference's mean there.
    corner_error: f64,
    /// Lit-surface level against the reference (sum test / sum reference - 1).
    level: f64,
    /// Largest luminance excess over the reference on lit surfaces, over the reference's
    /// mean: the hot spots' peak.
    peak: f64,
}

fn measure(img: &Image, reference: &Image, surface: &[bool], corner: &[bool]) -> Measures {
    let (mut e, mut r, mut n) = (0.0f64, 0.0f64, 0u64);
    let (mut st, mut sr) = (0.0f64, 0.0f64);
    let mut peak = 0.0f64;
    for i in 0..img.pixels.len() {
        let (a, b) = (
            f64::from(luminance(img.pixels[i])),
            f64::from(luminance(reference.pixels[i])),
        );
        if surface[i] {
            st += a;
            sr += b;
            peak = peak.max(a - b);
        }
        if corner[i] {
            e += (a - b).abs();
            r += b;
            n += 1;
        }
    }
    let mean_surface = sr / surface.iter().filter(|s| **s).count().max(1) as f64;
    assert!(n > 0 && r > 0.0);
    Measures {
        corner_error: e / r,
        level: st / sr - 1.0,
        peak: peak / mean_surface,
    }
}

#[test]
fn the_clamp_with_local_compensation_lowers_hot_spots_and_keeps_the_energy_near_corners() {
    let scene = Arc::new(builtin::scene("cornell").unwrap());
    let reference = common::reference(&scene, SIZE, 2048, Bounces::Unlimited);
    let frame = FrameRequest::camera(&scene.cameras[0], SIZE, SIZE);
    let classes = PathTracer::new(&scene).pixel_classes(&frame.view, SIZE, SIZE);
    let surface: Vec<bool> = classes.iter().map(|c| *c == PixelClass::Surface).collect();
    // Near a corner: within 6 % of the box's side of two of its faces.
    let g = scene_core::gbuffer::RayCastRenderer::new()
        .render(&scene, &frame.view, SIZE, SIZE)
        .unwrap();
    let recon = FrustumReconstruction::new(&frame.view);
    let b = scene.bounds();
    let near = 0.06 * (b.max - b.min).max_element();
    let corner: Vec<bool> = (0..g.len())
        .map(|i| {
            if !surface[i] || g.is_background(i) {
                return false;
            }
            let p = recon.world(
                pixel_uv(i as u32 % SIZE, i as u32 / SIZE, SIZE, SIZE),
                g.depth[i],
            );
            let faces = (0..3)
                .map(|a| usize::from(p[a] - b.min[a] < near) + usize::from(b.max[a] - p[a] < near))
                .sum::<usize>();
            faces >= 2
        })
        .collect();
    let base = IbrrSettings {
        target_error: 0.0,
        resolution: 128,
        clamp: 0.0,
        ..Default::default()
    };
    let (plain, _) = common::ibrr_image(&scene, base, SIZE);
    let clamped = |compensation| {
        common::ibrr_image(
            &scene,
            IbrrSettings {
                target_error: 0.0,
                clamp: 0.1,
                compensation,
                ..base
            },
            SIZE,
        )
    };
    let (local, t) = clamped(Compensation::Local);
    let (rescale, _) = clamped(Compensation::Rescale);
    let stats = t.construction().unwrap().stats();
    let (p, l, r) = (
        measure(&plain, &reference, &surface, &corner),
        measure(&local, &reference, &surface, &corner),
        measure(&rescale, &reference, &surface, &corner),
    );
    println!(
        "corner pixels {}; unclamped: corner error {:.4}, level {:+.4}, peak {:.3}; local: {:.4}, {:+.4}, {:.3} ({} of {} rays compensating, {:.2} s); rescale: {:.4}, {:+.4}, {:.3}",
        corner.iter().filter(|c| **c).count(),
        p.corner_error,
        p.level,
        p.peak,
        l.corner_error,
        l.level,
        l.peak,
        stats.compensation.compensating,
        stats.compensation.rays,
        stats.compensation_time.as_secs_f64(),
        r.corner_error,
        r.level,
        r.peak
    );
    assert!(stats.compensation.compensating > 0);
    // Near corners the clamped and compensated image is as close to the reference as the
    // unclamped one, and its hot spots are lower.
    assert!(
        l.corner_error <= p.corner_error,
        "corner error {:.4} > {:.4}",
        l.corner_error,
        p.corner_error
    );
    assert!(l.peak < p.peak, "peak {:.3} >= {:.3}", l.peak, p.peak);
}
