//! The reference path tracer under a `LightState`: each light alone, recoloured, switched
//! off, and its direct and indirect light apart. With the same seed the random decisions of
//! a path do not depend on which point or directional lights shine, so sums that must hold
//! exactly are checked to rounding; where an emitter's sampling table changes (an emissive
//! mesh switched off) the check is statistical, from the per-pixel variance.

use glam::Vec3;
use scene_core::lights::{LightId, LightSetting, LightState, light_ids};
use scene_core::reference::{Bounces, ReferenceSettings, render, render_lit};
use scene_core::{Image, PointLight, Scene, View, builtin};

fn settings(spp: u32, bounces: Bounces) -> ReferenceSettings {
    ReferenceSettings {
        width: 24,
        height: 18,
        spp,
        bounces,
        seed: 5,
    }
}

fn view(scene: &Scene) -> View {
    View::from_camera(&scene.cameras[0].with_aspect(24.0 / 18.0))
}

/// Largest |a - b| over channels, relative to the largest value of `b` (at least 1e-6).
fn max_rel(a: &Image, b: &Image) -> f32 {
    let peak = b
        .pixels
        .iter()
        .map(|p| p.max_element())
        .fold(1e-6f32, f32::max);
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (*p - *q).abs().max_element())
        .fold(0.0f32, f32::max)
        / peak
}

fn sum(images: &[Image]) -> Image {
    let mut out = Image::new(images[0].width, images[0].height);
    for img in images {
        for (o, p) in out.pixels.iter_mut().zip(&img.pixels) {
            *o += *p;
        }
    }
    out
}

#[test]
fn the_default_state_is_the_scene_and_every_light_alone_sums_to_all() {
    for name in ["corridor", "primitives", "cornell-point"] {
        let scene = builtin::scene(name).unwrap();
        let s = settings(16, Bounces::Unlimited);
        let all = render(&scene, &view(&scene), &s, None).image;
        let explicit = render_lit(&scene, &view(&scene), &s, &LightState::default(), None).image;
        assert_eq!(all, explicit, "{name}");
        let ids = light_ids(&scene);
        assert!(!ids.is_empty());
        let alone: Vec<Image> = ids
            .iter()
            .map(|&id| {
                render_lit(
                    &scene,
                    &view(&scene),
                    &s,
                    &LightState::only(&scene, id),
                    None,
                )
                .image
            })
            .collect();
        // Point and directional lights consume no random numbers: the same paths, so the
        // per-light images add up to the full one to rounding.
        let r = max_rel(&sum(&alone), &all);
        assert!(
            r < 1e-5,
            "{name}: sum of lights alone off by {r:.2e} of the peak"
        );
        // And each alone is neither black nor everything (when there are several).
        if ids.len() > 1 {
            for (id, img) in ids.iter().zip(&alone) {
                let m = img.mean().max_element();
                assert!(
                    m > 0.0 && m < all.mean().max_element(),
                    "{name} {id:?}: {m}"
                );
            }
        }
    }
}

#[test]
fn direct_and_indirect_factors_split_each_path_exactly() {
    for name in ["cornell", "corridor", "primitives"] {
        let scene = builtin::scene(name).unwrap();
        let s = settings(16, Bounces::Unlimited);
        let all = render(&scene, &view(&scene), &s, None).image;
        let with = |direct: f32, indirect: f32| {
            let mut state = LightState::default();
            for id in light_ids(&scene) {
                state.set(
                    id,
                    LightSetting {
                        direct,
                        indirect,
                        ..Default::default()
                    },
                );
            }
            render_lit(&scene, &view(&scene), &s, &state, None).image
        };
        let direct = with(1.0, 0.0);
        let indirect = with(0.0, 1.0);
        let r = max_rel(&sum(&[direct.clone(), indirect.clone()]), &all);
        assert!(r < 1e-5, "{name}: direct + indirect off by {r:.2e}");
        // Direct alone is the bounce-0 picture (the same paths' first terms), checked on
        // the mean against an independent bounce-0 render within 4 standard errors.
        let zero = render(
            &scene,
            &view(&scene),
            &settings(64, Bounces::Limited(0)),
            None,
        );
        let n = zero.image.pixels.len() as f64;
        let se = zero
            .variance
            .pixels
            .iter()
            .map(|v| f64::from(v.element_sum()) / 3.0 / 64.0)
            .sum::<f64>()
            .sqrt()
            / n;
        let md = f64::from(direct.mean().element_sum()) / 3.0;
        let mz = f64::from(zero.image.mean().element_sum()) / 3.0;
        // The 16-spp direct image has its own noise, twice the 64-spp standard error: 4
        // standard errors of the difference, sqrt(1 + 2^2) se.
        assert!(
            (md - mz).abs() < 4.0 * se * 5f64.sqrt() + 1e-9,
            "{name}: direct-only mean {md} vs bounce-0 mean {mz} (se {se})"
        );
        // Indirect light is there and smaller than the whole.
        let mi = f64::from(indirect.mean().element_sum());
        assert!(
            mi > 0.0 && mi < f64::from(all.mean().element_sum()),
            "{name}: {mi}"
        );
    }
}

#[test]
fn colour_multipliers_scale_exactly_and_off_is_black() {
    let scene = builtin::scene("corridor").unwrap();
    let s = settings(8, Bounces::Limited(2));
    let id = LightId::Point(2);
    let alone = render_lit(
        &scene,
        &view(&scene),
        &s,
        &LightState::only(&scene, id),
        None,
    )
    .image;
    let mut tinted = LightState::only(&scene, id);
    tinted.set_color(id, Vec3::new(2.0, 0.5, 0.0));
    let img = render_lit(&scene, &view(&scene), &s, &tinted, None).image;
    for (a, b) in alone.pixels.iter().zip(&img.pixels) {
        assert!((b.x - 2.0 * a.x).abs() <= 1e-6 * a.x.max(1e-6), "{a} {b}");
        assert!((b.y - 0.5 * a.y).abs() <= 1e-6 * a.y.max(1e-6), "{a} {b}");
        assert_eq!(b.z, 0.0);
    }
    let mut off = LightState::default();
    for l in light_ids(&scene) {
        off.set_enabled(l, false);
    }
    let black = render_lit(&scene, &view(&scene), &s, &off, None).image;
    assert!(black.pixels.iter().all(|p| *p == Vec3::ZERO));
    // An emissive mesh switched off does not glow either (Cornell's light, seen directly).
    let cornell = builtin::scene("cornell").unwrap();
    let mut dark = LightState::default();
    dark.set_enabled(light_ids(&cornell)[0], false);
    let img = render_lit(&cornell, &view(&cornell), &s, &dark, None).image;
    assert!(img.pixels.iter().all(|p| *p == Vec3::ZERO));
}

#[test]
fn an_emitter_and_a_point_light_alone_add_up_within_noise() {
    // The Cornell box with an extra point light: switching the emissive mesh off changes
    // its sampling table, so the paths differ; the sum must agree within the noise.
    let mut scene = builtin::scene("cornell").unwrap();
    scene.point_lights.push(PointLight {
        name: "extra".into(),
        position: Vec3::new(0.15, 0.45, 0.2),
        intensity: Vec3::splat(0.05),
        radius: None,
        cone: None,
    });
    scene.validate().unwrap();
    let s = settings(64, Bounces::Limited(2));
    let v = view(&scene);
    let all = render(&scene, &v, &s, None);
    let ids = light_ids(&scene);
    assert_eq!(ids.len(), 2);
    let parts: Vec<_> = ids
        .iter()
        .map(|&id| render_lit(&scene, &v, &s, &LightState::only(&scene, id), None))
        .collect();
    let n = all.image.pixels.len() as f64;
    let mean = |img: &Image| f64::from(img.mean().element_sum()) / 3.0;
    let var_of_mean = |o: &scene_core::reference::ReferenceOutput| {
        o.variance
            .pixels
            .iter()
            .map(|v| f64::from(v.element_sum()) / 3.0 / f64::from(o.spp))
            .sum::<f64>()
            / (n * n)
    };
    let lhs = parts.iter().map(|p| mean(&p.image)).sum::<f64>();
    let rhs = mean(&all.image);
    let se = (parts.iter().map(var_of_mean).sum::<f64>() + var_of_mean(&all)).sqrt();
    assert!(
        (lhs - rhs).abs() < 4.0 * se,
        "sum of the lights alone {lhs:.6} vs all {rhs:.6}, standard error {se:.2e}"
    );
    assert!(parts.iter().all(|p| mean(&p.image) > 0.0));
}
