//! Helpers shared by the integration tests.
#![allow(dead_code)]

use isr::{Estimator, IsrInputs, IsrSettings, LightSet, Sender, ShadowSettings, downsample};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::{GBuffer, GBufferRenderer, Image, Scene, View, builtin};

/// Small shadow maps: fast to build in the dev profile.
pub fn small_shadows() -> ShadowSettings {
    ShadowSettings {
        directional_resolution: 256,
        cube_resolution: 64,
        emitter_samples: 8,
        emitter_cube_resolution: 32,
        ..Default::default()
    }
}

/// A scene's G-buffers from camera `camera` at `w x h`.
pub struct Setup {
    pub scene: Scene,
    pub prepared: LightSet,
    pub view: View,
    pub full: GBuffer,
    pub coarse: GBuffer,
}

impl Setup {
    pub fn new(scene: Scene, camera: usize, w: u32, h: u32) -> Self {
        let prepared = LightSet::new(&scene, &small_shadows()).unwrap();
        Self::with_prepared(scene, prepared, camera, w, h)
    }

    pub fn builtin(name: &str, camera: usize, w: u32, h: u32) -> Self {
        Self::new(builtin::scene(name).unwrap(), camera, w, h)
    }

    pub fn with_prepared(scene: Scene, prepared: LightSet, camera: usize, w: u32, h: u32) -> Self {
        let cam = scene.cameras[camera].with_aspect(w as f32 / h as f32);
        let view = View::from_camera(&cam);
        let full = RayCastRenderer::new().render(&scene, &view, w, h).unwrap();
        let coarse = downsample(&full, isr::DownsampleMode::NearestSurface);
        Self {
            scene,
            prepared,
            view,
            full,
            coarse,
        }
    }

    pub fn inputs(&self) -> IsrInputs<'_> {
        IsrInputs {
            full: &self.full,
            coarse: &self.coarse,
            view: &self.view,
        }
    }

    pub fn render(&self, settings: &IsrSettings) -> Image {
        isr::render_image(&self.prepared, &self.inputs(), settings).unwrap()
    }
}

/// Every mode combination, named.
pub fn modes() -> Vec<(&'static str, IsrSettings)> {
    let mut v = Vec::new();
    for (name, estimator, sender) in [
        ("thesis-albedo", Estimator::Thesis, Sender::Albedo),
        ("thesis-lit", Estimator::Thesis, Sender::Lit),
        ("patch-albedo", Estimator::Patch, Sender::Albedo),
        ("patch-lit", Estimator::Patch, Sender::Lit),
    ] {
        v.push((
            name,
            IsrSettings {
                estimator,
                sender,
                ..IsrSettings::thesis_constants()
            },
        ));
    }
    v
}

/// Eq. 19: mean over pixels and channels of |a - b|.
pub fn mean_error(a: &Image, b: &Image) -> f64 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (*p - *q).abs().element_sum() as f64)
        .sum::<f64>()
        / (3.0 * a.pixels.len() as f64)
}

/// The largest absolute channel difference between two images of one size, and the pixel
/// where it is.
pub fn max_difference(a: &Image, b: &Image) -> (f64, usize) {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (*p - *q).abs().max_element() as f64)
        .enumerate()
        .fold(
            (0.0, 0),
            |(m, at), (i, d)| if d > m { (d, i) } else { (m, at) },
        )
}

/// Mean of all channels of an image.
pub fn image_mean(a: &Image) -> f64 {
    a.pixels.iter().map(|p| p.element_sum() as f64).sum::<f64>() / (3.0 * a.pixels.len() as f64)
}

/// The GPU twin's bounds against the CPU image `cpu` (printed, then asserted, naming `what`):
/// the mean difference under 1e-3 of the image mean, and every pixel within 1e-4 of the
/// peak (at least 1). Both paths compute in f32 and differ by rounding (measured on
/// lavapipe: at most 4e-6 against peaks of 35, about 1e-7 of the peak); 1e-4 of the peak
/// leaves room for GPUs' faster transcendentals and catches any pixel that takes another
/// branch (a shadow test, a depth guard).
pub fn assert_gpu_twin(what: &str, cpu: &Image, gpu: &Image) {
    assert_eq!(gpu.non_finite_count(), 0, "{what}");
    let m = image_mean(cpu);
    let e = mean_error(cpu, gpu);
    let (dmax, at) = max_difference(cpu, gpu);
    let peak = cpu
        .pixels
        .iter()
        .map(|p| p.max_element())
        .fold(0.0f32, f32::max);
    eprintln!(
        "{what}: mean {m:.4}, rel diff {:.2e}, max {dmax:.3e} at {at} (peak {peak:.3})",
        e / m
    );
    assert!(
        e < 1e-3 * m,
        "{what}: mean |cpu - gpu| = {e:.3e}, image mean {m:.4}"
    );
    let bound = 1e-4 * f64::from(peak.max(1.0));
    assert!(
        dmax <= bound,
        "{what}: max |cpu - gpu| = {dmax:.3e} at pixel {at}, over {bound:.3e}"
    );
}
