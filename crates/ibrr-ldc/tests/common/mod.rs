//! Helpers shared by the IBRR tests.
#![allow(dead_code)]

use std::sync::Arc;

use ibrr_ldc::{IbrrSettings, IbrrTechnique};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::reference::{Bounces, PathTracer, PixelClass, ReferenceSettings, render};
use scene_core::{FrameRequest, Image, Scene, Technique, View, luminance};

/// Relative mean absolute error and relative bias of `a` against `b` (luminance, over all
/// pixels): `sum |a - b| / sum b` and `sum (a - b) / sum b`.
pub fn errors(a: &Image, b: &Image) -> (f64, f64) {
    let (mut abs, mut bias, mut tot) = (0.0f64, 0.0f64, 0.0f64);
    for (x, y) in a.pixels.iter().zip(&b.pixels) {
        let (la, lb) = (f64::from(luminance(*x)), f64::from(luminance(*y)));
        abs += (la - lb).abs();
        bias += la - lb;
        tot += lb;
    }
    (abs / tot, bias / tot)
}

/// [`errors`] over the pixels whose reference luminance is at most the `q` quantile (a
/// point light's hot spot, whose pixel integral neither image resolves, left out).
pub fn errors_below_quantile(a: &Image, b: &Image, q: f64) -> (f64, f64) {
    let mut l: Vec<f32> = b.pixels.iter().map(|p| luminance(*p)).collect();
    l.sort_by(f32::total_cmp);
    let cut = l[((l.len() - 1) as f64 * q) as usize];
    let (mut abs, mut bias, mut tot) = (0.0f64, 0.0f64, 0.0f64);
    for (x, y) in a.pixels.iter().zip(&b.pixels) {
        let (la, lb) = (f64::from(luminance(*x)), f64::from(luminance(*y)));
        if lb > f64::from(cut) {
            continue;
        }
        abs += (la - lb).abs();
        bias += la - lb;
        tot += lb;
    }
    (abs / tot, bias / tot)
}

/// The mean luminance of an image.
pub fn mean(a: &Image) -> f64 {
    a.pixels
        .iter()
        .map(|p| f64::from(luminance(*p)))
        .sum::<f64>()
        / a.pixels.len().max(1) as f64
}

/// The IBRR of `scene` with `settings`, seen from camera 0 at `size x size`, each pixel
/// the mean of 4 x 4 G-buffer samples (the reference jitters over the pixel, so edge
/// pixels mix surfaces; one G-buffer sample per pixel would count that aliasing as the
/// method's error).
pub fn ibrr_image(scene: &Arc<Scene>, settings: IbrrSettings, size: u32) -> (Image, IbrrTechnique) {
    let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    t.prepare(scene.clone()).unwrap();
    const SS: u32 = 4;
    let big = t
        .render(&FrameRequest::camera(
            &scene.cameras[0],
            size * SS,
            size * SS,
        ))
        .unwrap();
    (big.box_down(SS), t)
}

/// The reference of `scene` from camera 0.
pub fn reference(scene: &Scene, size: u32, spp: u32, bounces: Bounces) -> Image {
    let frame = FrameRequest::camera(&scene.cameras[0], size, size);
    let view: View = frame.view;
    render(
        scene,
        &view,
        &ReferenceSettings {
            width: size,
            height: size,
            spp,
            bounces,
            seed: 7,
        },
        None,
    )
    .image
}

/// The lit-surface pixels of camera 0's view of `scene` at `size x size`, as the main job
/// counts them: pixels whose centre sees a reflecting surface (emitters and background
/// left out) and whose `reference` luminance is at most its 99th percentile over them.
pub fn lit_surface_pixels(scene: &Scene, reference: &Image, size: u32) -> Vec<usize> {
    let frame = FrameRequest::camera(&scene.cameras[0], size, size);
    let classes = PathTracer::new(scene).pixel_classes(&frame.view, size, size);
    let mut lum: Vec<f32> = (0..classes.len())
        .filter(|&i| classes[i] == PixelClass::Surface)
        .map(|i| luminance(reference.pixels[i]))
        .collect();
    lum.sort_by(f32::total_cmp);
    let cut = lum[((lum.len() as f64) * 0.99).ceil() as usize - 1];
    (0..classes.len())
        .filter(|&i| classes[i] == PixelClass::Surface && luminance(reference.pixels[i]) <= cut)
        .collect()
}

/// Each channel's `sum(test) / sum(reference) - 1` over `pixels` (the lit-surface bias of
/// one image, as the main job's surface error measures it).
#[allow(dead_code)]
pub fn channel_bias(test: &Image, reference: &Image, pixels: &[usize]) -> [f64; 3] {
    let (mut t, mut r) = ([0.0f64; 3], [0.0f64; 3]);
    for &i in pixels {
        for c in 0..3 {
            t[c] += f64::from(test.pixels[i][c]);
            r[c] += f64::from(reference.pixels[i][c]);
        }
    }
    [0, 1, 2].map(|c| t[c] / r[c] - 1.0)
}
