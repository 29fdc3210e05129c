//! ISR honours the frame's light state (scene-core's `LightState`) on the CPU and the GPU:
//! the image is linear in every light's emission, so one-light-at-a-time images sum to the
//! full image, a recoloured light changes exactly its own share, the direct and indirect
//! multipliers split the image into two parts that sum to it, and a light switched off
//! is gone, visible emitters included. Nothing is re-prepared between frames.

mod common;

use std::sync::Arc;

use common::{image_mean, max_difference, small_shadows};
use glam::Vec3;
use isr::{Backend, IsrSettings, IsrTechnique};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::lights::{LightId, LightSetting, LightState, light_ids};
use scene_core::testing::gpu_test_context;
use scene_core::{FrameRequest, Image, Scene, Technique, builtin};

const W: u32 = 48;
const H: u32 = 36;

fn backends() -> Vec<(&'static str, Backend)> {
    let mut b = vec![("cpu", Backend::Cpu)];
    if let Some(ctx) = gpu_test_context() {
        b.push(("gpu", Backend::Gpu(ctx)));
    }
    b
}

fn technique(scene: &Arc<Scene>, backend: Backend) -> IsrTechnique {
    let mut t = IsrTechnique::new(IsrSettings::default(), Box::new(RayCastRenderer::new()))
        .with_shadows(small_shadows())
        .with_backend(backend);
    t.prepare(scene.clone()).unwrap();
    t
}

fn render(t: &mut IsrTechnique, scene: &Scene, state: &LightState) -> Image {
    t.render(&FrameRequest::from_camera(&scene.cameras[0], W, H, state))
        .unwrap()
}

fn sum(images: &[Image]) -> Image {
    let mut out = Image::new(W, H);
    for img in images {
        for (o, p) in out.pixels.iter_mut().zip(&img.pixels) {
            *o += *p;
        }
    }
    out
}

fn peak(img: &Image) -> f64 {
    img.pixels
        .iter()
        .map(|p| p.max_element() as f64)
        .fold(0.0, f64::max)
}

/// Asserts `a` and `b` agree to `1e-4` of `reference`'s brightest channel everywhere.
fn assert_same(a: &Image, b: &Image, reference: &Image, what: &str) {
    let (d, at) = max_difference(a, b);
    assert!(
        d <= 1e-4 * peak(reference),
        "{what}: differs by {d} at pixel {at} (peak {})",
        peak(reference)
    );
}

#[test]
fn one_light_at_a_time_sums_to_all_lights_and_recolouring_changes_only_its_share() {
    let scene = Arc::new(builtin::scene("corridor").unwrap());
    let ids = light_ids(&scene);
    assert_eq!(ids.len(), 4);
    for (name, backend) in backends() {
        let mut t = technique(&scene, backend);
        let all = render(&mut t, &scene, &LightState::default());
        let alone: Vec<Image> = ids
            .iter()
            .map(|&id| render(&mut t, &scene, &LightState::only(&scene, id)))
            .collect();
        for (id, img) in ids.iter().zip(&alone) {
            assert!(
                image_mean(img) > 1e-3 * image_mean(&all),
                "{name}: {id:?} alone is dark"
            );
        }
        assert_same(
            &sum(&alone),
            &all,
            &all,
            &format!("{name}: sum of single lights"),
        );
        // Recolour light 0: its share changes per channel, the others' do not.
        let tint = Vec3::new(1.0, 0.2, 0.05);
        let mut state = LightState::default();
        state.set_color(LightId::Point(0), tint);
        let recoloured = render(&mut t, &scene, &state);
        let mut expect = all.clone();
        for ((e, a0), _) in expect.pixels.iter_mut().zip(&alone[0].pixels).zip(0..) {
            *e += *a0 * (tint - Vec3::ONE);
        }
        assert_same(
            &recoloured,
            &expect,
            &all,
            &format!("{name}: recoloured light"),
        );
        // The same technique, back to the default state: the first image again (no stale
        // light buffers).
        let again = render(&mut t, &scene, &LightState::default());
        assert_same(&again, &all, &all, &format!("{name}: default state again"));
    }
}

#[test]
fn direct_and_indirect_multipliers_split_the_image() {
    let scene = Arc::new(builtin::scene("cornell-point").unwrap());
    let id = LightId::Point(0);
    for (name, backend) in backends() {
        let mut t = technique(&scene, backend);
        let all = render(&mut t, &scene, &LightState::default());
        let part = |t: &mut IsrTechnique, direct: f32, indirect: f32| {
            let mut s = LightState::default();
            s.set(
                id,
                LightSetting {
                    direct,
                    indirect,
                    ..Default::default()
                },
            );
            render(t, &scene, &s)
        };
        let direct = part(&mut t, 1.0, 0.0);
        let indirect = part(&mut t, 0.0, 1.0);
        assert!(
            image_mean(&indirect) > 0.02 * image_mean(&all),
            "{name}: the indirect part is {} of {}",
            image_mean(&indirect),
            image_mean(&all)
        );
        assert!(image_mean(&direct) < image_mean(&all), "{name}");
        assert_same(
            &sum(&[direct, indirect.clone()]),
            &all,
            &all,
            &format!("{name}: parts"),
        );
        // Doubling the indirect multiplier doubles that part only.
        let double = part(&mut t, 1.0, 2.0);
        assert_same(
            &double,
            &sum(&[all.clone(), indirect]),
            &all,
            &format!("{name}: indirect x 2"),
        );
    }
}

#[test]
fn switched_off_emitters_neither_light_nor_glow() {
    let scene = Arc::new(builtin::scene("cornell").unwrap());
    let ids = light_ids(&scene);
    assert!(
        ids.iter().all(|id| matches!(id, LightId::Emissive(_))),
        "{ids:?}"
    );
    for (name, backend) in backends() {
        let mut t = technique(&scene, backend);
        let all = render(&mut t, &scene, &LightState::default());
        let mut off = LightState::default();
        for &id in &ids {
            off.set_enabled(id, false);
        }
        let dark = render(&mut t, &scene, &off);
        assert!(image_mean(&all) > 0.0);
        assert!(
            dark.pixels.iter().all(|p| *p == Vec3::ZERO),
            "{name}: light left with every emitter off (mean {})",
            image_mean(&dark)
        );
        // Dimmed to a half: half the picture, glow included.
        let mut half = LightState::default();
        for &id in &ids {
            half.set_color(id, Vec3::splat(0.5));
        }
        let dim = render(&mut t, &scene, &half);
        let mut expect = all.clone();
        expect.pixels.iter_mut().for_each(|p| *p *= 0.5);
        assert_same(&dim, &expect, &all, &format!("{name}: dimmed"));
    }
}
