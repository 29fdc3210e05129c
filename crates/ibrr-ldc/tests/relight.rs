//! The relightable LDC: every layer keeps its light per source, so a light state is applied
//! by recombining the layers, not by rebuilding. Checked against what it replaces: a
//! rebuild from the same particle paths (common random numbers) with the new emissions
//! put into the scene and the IRPLs' powers, which must give the same image to float
//! rounding, on the CPU, on the GPU and in f16 storage.

use std::sync::Arc;

use glam::Vec3;
use ibrr_ldc::ldc::SourcePrecision;
use ibrr_ldc::{Construction, IbrrSettings, IbrrTechnique, IrplKind, IrplSet, reconstruct, shade};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::lights::{LightId, LightSetting, LightState, light_ids};
use scene_core::{FrameRequest, GBufferRenderer, Image, Scene, Technique, builtin};

const W: u32 = 64;
const H: u32 = 48;

fn settings() -> IbrrSettings {
    IbrrSettings {
        target_error: 0.0,
        resolution: 64,
        irpls: 48,
        ..Default::default()
    }
}

fn built(scene: &Arc<Scene>, settings: IbrrSettings) -> IbrrTechnique {
    let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    t.prepare(scene.clone()).unwrap();
    t
}

fn mean(img: &Image) -> f64 {
    img.pixels
        .iter()
        .map(|p| f64::from(p.x + p.y + p.z) / 3.0)
        .sum::<f64>()
        / img.pixels.len() as f64
}

/// The largest per-pixel, per-channel difference as a share of `b`'s image mean.
fn worst(a: &Image, b: &Image) -> f64 {
    let m = mean(b);
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(x, y)| f64::from((*x - *y).abs().max_element()))
        .fold(0.0, f64::max)
        / m
}

/// What the relit LDC replaces: the scene with each point light's intensity multiplied by
/// its colour, and an LDC built from `irpls` (the technique's own walks) with each IRPL's
/// power multiplied by its light's direct (exact sources) or indirect (path nodes) factor,
/// seen with the default light state.
fn rebuild(scene: &Scene, irpls: &IrplSet, state: &LightState, settings: IbrrSettings) -> Image {
    let mut changed = scene.clone();
    for (i, l) in changed.point_lights.iter_mut().enumerate() {
        l.intensity *= state.get(LightId::Point(i as u32)).color;
    }
    let mut set = irpls.clone();
    for irpl in &mut set.irpls {
        let s = state.get(irpl.light);
        let factor = match irpl.kind {
            IrplKind::PointSource { .. } | IrplKind::DirectionalSource { .. } => s.direct_factor(),
            IrplKind::EmitterSample => s.direct_factor(),
            IrplKind::Bounce => s.indirect_factor(),
        };
        irpl.power *= factor;
    }
    let changed = Arc::new(changed);
    let mut c = Construction::with_irpls(changed.clone(), set, &settings).unwrap();
    let mut r = RayCastRenderer::new();
    c.prepare_renderer(&mut r).unwrap();
    while !c.is_done() {
        c.step(&mut r, 8).unwrap();
    }
    let ldc = c.ldc().unwrap();
    let frame = FrameRequest::camera(&changed.cameras[0], W, H);
    let g = r.render(&changed, &frame.view, W, H).unwrap();
    let rec = reconstruct(&ldc, &g, &frame.view, settings.reading());
    shade(&changed, &g, &frame.view, &rec, &LightState::default())
}

/// Every light recoloured (a different colour each), one dimmed, one with its direct and
/// indirect multipliers apart, one switched off.
fn new_state(scene: &Scene) -> LightState {
    let mut state = LightState::default();
    let colours = [
        Vec3::new(1.0, 0.3, 0.2),
        Vec3::new(0.2, 0.5, 1.5),
        Vec3::new(0.4, 1.2, 0.4),
        Vec3::new(2.0, 2.0, 0.5),
    ];
    for (k, id) in light_ids(scene).into_iter().enumerate() {
        let mut s = LightSetting {
            color: colours[k % colours.len()],
            ..Default::default()
        };
        match k % 4 {
            1 => s.color *= 0.25,
            2 => {
                s.direct = 0.0;
                s.indirect = 3.0;
            }
            3 => s.enabled = false,
            _ => {}
        }
        state.set(id, s);
    }
    state
}

#[test]
fn relighting_the_corridor_equals_rebuilding_with_the_new_emissions() {
    let scene = Arc::new(builtin::scene("corridor").unwrap());
    assert!(
        light_ids(&scene).len() >= 4,
        "every kind of change is tried"
    );
    // Unclamped first: every kind of change, the direct and indirect multipliers apart
    // included. (With the clamp, the light its compensation recovers at a surface is
    // indirect light and follows the indirect multiplier, which scaling the IRPLs'
    // powers cannot reproduce when the two multipliers differ; below.)
    let settings = IbrrSettings {
        target_error: 0.0,
        clamp: 0.0,
        ..settings()
    };
    let mut t = built(&scene, settings);
    let irpls = t.construction().unwrap().irpls.clone();
    let state = new_state(&scene);
    let relit = t
        .render(&FrameRequest::from_camera(&scene.cameras[0], W, H, &state))
        .unwrap();
    let timings = t.last_timings();
    assert!(timings.rebuild.is_zero() && !timings.relight.is_zero());
    let expected = rebuild(&scene, &irpls, &state, settings);
    let w = worst(&relit, &expected);
    println!(
        "corridor relit against rebuilt: worst pixel {w:.2e} of the image mean {:.4}",
        mean(&expected)
    );
    assert!(mean(&expected) > 0.0);
    assert!(
        w <= 1e-4,
        "relit differs from rebuilt by {w:.2e} of the mean"
    );
    // Each light alone, recoloured: the relit image equals that light's rebuild too.
    for id in light_ids(&scene) {
        let mut one = LightState::only(&scene, id);
        one.set_color(id, Vec3::new(0.3, 0.9, 2.0));
        let relit = t
            .render(&FrameRequest::from_camera(&scene.cameras[0], W, H, &one))
            .unwrap();
        let expected = rebuild(&scene, &irpls, &one, settings);
        let w = worst(&relit, &expected);
        assert!(w <= 1e-4, "{}: {w:.2e}", id.key());
    }
    // At the defaults (clamp and local compensation): recoloured, dimmed and switched off.
    let settings = self::settings();
    let mut t = built(&scene, settings);
    assert!(t.construction().unwrap().stats().compensation.compensating > 0);
    let irpls = t.construction().unwrap().irpls.clone();
    let mut state = new_state(&scene);
    for id in light_ids(&scene) {
        let s = state.get(id);
        state.set(
            id,
            LightSetting {
                direct: 1.0,
                indirect: 1.0,
                ..s
            },
        );
    }
    let relit = t
        .render(&FrameRequest::from_camera(&scene.cameras[0], W, H, &state))
        .unwrap();
    let expected = rebuild(&scene, &irpls, &state, settings);
    let w = worst(&relit, &expected);
    println!("with the clamp's compensation: worst pixel {w:.2e} of the image mean");
    assert!(w <= 1e-4, "with the compensation: {w:.2e}");
}

#[test]
fn every_light_off_is_black_and_back_on_is_the_first_image() {
    let scene = Arc::new(builtin::scene("cornell-point").unwrap());
    let mut t = built(&scene, settings());
    let frame = FrameRequest::camera(&scene.cameras[0], W, H);
    let first = t.render(&frame).unwrap();
    assert!(mean(&first) > 0.0);
    let mut off = LightState::default();
    for id in light_ids(&scene) {
        off.set_enabled(id, false);
    }
    let dark = t
        .render(&FrameRequest {
            lights: &off,
            ..frame
        })
        .unwrap();
    assert!(dark.pixels.iter().all(|p| *p == Vec3::ZERO));
    let again = t.render(&frame).unwrap();
    assert!(worst(&again, &first) <= 1e-6);
    assert!(t.last_timings().rebuild.is_zero());
}

#[test]
fn a_build_with_a_light_off_rebuilds_once_that_light_is_on() {
    let scene = Arc::new(builtin::scene("cornell-point").unwrap());
    let id = light_ids(&scene)[0];
    let mut off = LightState::default();
    off.set_enabled(id, false);
    let mut t = IbrrTechnique::new(settings(), Box::new(RayCastRenderer::new()));
    t.prepare_lit(scene.clone(), &off, &mut |_, _| {}).unwrap();
    let frame = FrameRequest::camera(&scene.cameras[0], W, H);
    let lit = t.render(&frame).unwrap();
    assert!(
        !t.last_timings().rebuild.is_zero(),
        "the light had no IRPLs"
    );
    let fresh = built(&scene, settings()).render(&frame).unwrap();
    assert!(worst(&lit, &fresh) <= 1e-6);
    // Switching it off again is a relight.
    t.render(&FrameRequest {
        lights: &off,
        ..frame
    })
    .unwrap();
    assert!(t.last_timings().rebuild.is_zero());
}

#[test]
fn f16_storage_relights_like_f32() {
    // At the corridor's own brightness, and 1e7 times brighter: each source keeps its
    // values over a scale of its own, so a bright light does not saturate f16 at 65504
    // (it did: such a scene rendered about 1e5 times too dark).
    for bright in [1.0f32, 1e7] {
        f16_relights_like_f32_at(bright);
    }
}

fn f16_relights_like_f32_at(bright: f32) {
    let mut scene = builtin::scene("corridor").unwrap();
    for m in &mut scene.materials {
        m.emission *= bright;
    }
    for l in &mut scene.point_lights {
        l.intensity *= bright;
    }
    for l in &mut scene.directional_lights {
        l.irradiance *= bright;
    }
    let scene = Arc::new(scene);
    let state = new_state(&scene);
    let frame = FrameRequest::from_camera(&scene.cameras[0], W, H, &state);
    let a = built(&scene, settings()).render(&frame).unwrap();
    let half = IbrrSettings {
        target_error: 0.0,
        source_precision: SourcePrecision::F16,
        ..settings()
    };
    let mut t = built(&scene, half);
    let b = t.render(&frame).unwrap();
    let ldc = t.ldc().unwrap();
    // f16 keeps 11 significant bits: every stored value within 2^-11 of itself, and every
    // pixel a sum of such values with positive weights, so within 2^-11 of itself too
    // (2^-10 allowed for the f32 sums on top).
    let mut worst_rel = 0.0f32;
    for (x, y) in b.pixels.iter().zip(&a.pixels) {
        for c in 0..3 {
            let d = (x[c] - y[c]).abs();
            assert!(d <= y[c] / 1024.0 + 1e-9, "{} against {}", x[c], y[c]);
            if y[c] > 0.0 {
                worst_rel = worst_rel.max(d / y[c]);
            }
        }
    }
    let top = a.pixels.iter().map(|p| p.max_element()).fold(0.0, f32::max);
    println!(
        "lights x {bright:e}: f16 against f32: worst pixel off by {worst_rel:.2e} of itself \
         (brightest pixel {top:e})"
    );
    assert!(worst_rel > 0.0, "f16 rounds");
    assert_eq!(ldc.sources.saturated(), 0);
    let sources = ldc.sources.sources() as u64;
    assert_eq!(
        ldc.sources.bytes(),
        ldc.layer_count() as u64 * sources * 12 + 4 * sources,
        "12 bytes a layer and source, and a scale per source"
    );
}

#[test]
fn relighting_on_the_gpu_equals_relighting_on_the_cpu() {
    let Some(ctx) = scene_core::testing::gpu_test_context() else {
        return;
    };
    let scene = Arc::new(builtin::scene("corridor").unwrap());
    let mut cpu = built(&scene, settings());
    let mut gpu = IbrrTechnique::new(settings(), Box::new(RayCastRenderer::new())).on_gpu(ctx);
    gpu.prepare(scene.clone()).unwrap();
    let frame = FrameRequest::camera(&scene.cameras[0], W, H);
    // A frame first, so that the GPU copy exists and is updated in place by the relight.
    gpu.render(&frame).unwrap();
    let state = new_state(&scene);
    let frame = FrameRequest {
        lights: &state,
        ..frame
    };
    let (a, b) = (cpu.render(&frame).unwrap(), gpu.render(&frame).unwrap());
    let m = mean(&a);
    let off = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(x, y)| f64::from((**x - **y).abs().max_element()) > 1e-4 * m)
        .count();
    assert!(
        m > 0.0 && off <= a.pixels.len() / 500,
        "{off} pixels differ"
    );
    assert!(gpu.last_timings().rebuild.is_zero());
}

#[test]
fn the_per_source_light_counts_against_the_memory_budget() {
    // Each layer takes 24 bytes a light source beside its own while building: a budget
    // that 100 layers of one source fit in refuses them with four sources, typed, before
    // allocating past it.
    use ibrr_ldc::ldc::{BUILD_LAYER_BYTES, BUILD_SOURCE_BYTES, LdcBuilder};
    let frame = ibrr_ldc::LdcFrame::around(Vec3::ZERO, Vec3::ONE, 16, 0.5, 0.05, 0.1);
    let heads = frame.pixel_count() as u64 * 4;
    let budget = heads + 100 * (BUILD_LAYER_BYTES + BUILD_SOURCE_BYTES);
    let fill = |sources: usize| -> Result<usize, ibrr_ldc::IbrrError> {
        let mut b = LdcBuilder::new(frame, budget, sources)?;
        for k in 0..100i64 {
            let p = Vec3::new(
                (k % 10) as f32 / 10.0 + 0.05,
                0.5,
                (k / 10) as f32 / 10.0 + 0.05,
            );
            let c = frame.pixel_coords(1, p);
            b.found(1, c.x.floor() as i64, c.y.floor() as i64, p, Vec3::Y)?;
        }
        assert!(b.bytes() <= budget);
        Ok(b.layer_count())
    };
    assert_eq!(fill(1).unwrap(), 100);
    match fill(4) {
        Err(ibrr_ldc::IbrrError::Budget {
            needed,
            limit,
            what,
        }) => {
            assert!(
                needed > limit && limit == budget && what.contains("layer"),
                "{what}"
            );
        }
        other => panic!("expected a budget error, got {other:?}"),
    }
}
