//! Golden images at 128x96 for each mode, compared with a threshold (eq. 19's mean error
//! relative to the image mean), not bit for bit. `ISR_BLESS=1 cargo test -p isr --test
//! golden` rewrites them after an intended change.

mod common;

use std::path::PathBuf;

use common::{Setup, image_mean, mean_error, modes};
use isr::{Blur, DlTechnique, IsrSettings, IsrTechnique};
use std::sync::Arc;

use scene_core::FrameRequest;
use scene_core::gbuffer::RayCastRenderer;
use scene_core::{Image, Technique, builtin};

/// Largest mean error against a golden image, relative to its mean.
const THRESHOLD: f64 = 2e-3;

fn golden_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

fn check(name: &str, img: &Image) {
    let path = golden_dir().join(format!("{name}.exr"));
    if std::env::var("ISR_BLESS").is_ok_and(|v| v == "1") {
        std::fs::create_dir_all(golden_dir()).unwrap();
        img.write_exr(&path).unwrap();
        return;
    }
    let golden = Image::read_exr(&path).unwrap_or_else(|e| {
        panic!("{e}: run `ISR_BLESS=1 cargo test -p isr --test golden` to create it")
    });
    let e = mean_error(&golden, img);
    let m = image_mean(&golden);
    assert!(
        e <= THRESHOLD * m,
        "{name}: mean error {e:.3e} against the golden image (mean {m:.4}), threshold {:.3e}",
        THRESHOLD * m
    );
}

#[test]
fn golden_images_of_every_mode() {
    let cornell = Setup::builtin("cornell", 0, 128, 96);
    for (name, s) in modes() {
        check(&format!("cornell-{name}"), &cornell.render(&s));
    }
    check("cornell-dl", &cornell.render(&IsrSettings::dl()));
    check(
        "cornell-edge-aware-ao-indirect",
        &cornell.render(&IsrSettings {
            blur: Blur::EdgeAware,
            ao_indirect_only: true,
            upsample_normal_power: 8.0,
            ..IsrSettings::thesis_constants()
        }),
    );
    let primitives = Setup::builtin("primitives", 0, 128, 96);
    check(
        "primitives-patch-lit",
        &primitives.render(&IsrSettings::thesis_constants()),
    );
    // The screen-space setting (measured k_isr, no AO).
    check(
        "primitives-default",
        &primitives.render(&IsrSettings::screen_space()),
    );
}

#[test]
fn isr_and_dl_are_techniques() {
    let scene = builtin::scene("cornell-point").unwrap();
    let shadows = common::small_shadows();
    let mut isr = IsrTechnique::new(IsrSettings::default(), Box::new(RayCastRenderer::new()))
        .with_shadows(shadows);
    let mut dl = DlTechnique::new(Box::new(RayCastRenderer::new()));
    dl.0.shadows = shadows;
    let techniques: [&mut dyn Technique; 2] = [&mut isr, &mut dl];
    let mut images = Vec::new();
    for t in techniques {
        t.prepare(Arc::new(scene.clone())).unwrap();
        images.push(
            t.render(&FrameRequest::camera(&scene.cameras[0], 40, 30))
                .unwrap(),
        );
    }
    assert_eq!(isr.name(), "isr");
    assert_eq!(dl.name(), "dl");
    assert!(image_mean(&images[0]) > image_mean(&images[1]));
    let t = isr.last_timings();
    assert!(t.radiosity > std::time::Duration::ZERO && t.total() >= t.lighting);
    // A technique renders only what it was prepared for: before `prepare`, a typed error.
    let other = builtin::scene("primitives").unwrap();
    let mut fresh = IsrTechnique::new(IsrSettings::default(), Box::new(RayCastRenderer::new()));
    let e = fresh
        .render(&FrameRequest::camera(&other.cameras[1], 40, 30))
        .unwrap_err();
    assert!(matches!(e, scene_core::Error::NotPrepared(_)), "{e}");
    // Preparing another scene replaces the first.
    isr.prepare(Arc::new(other.clone())).unwrap();
    let img = isr
        .render(&FrameRequest::camera(&other.cameras[1], 40, 30))
        .unwrap();
    assert!(image_mean(&img) > 0.1);
    assert_eq!(isr.prepared().unwrap().lights.len(), 1);
}
