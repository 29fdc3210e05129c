//! The packed layout and the GPU passes against the CPU: eq. 1 from packed f32 words equals
//! the solution's own relight, f16 storage stays within half-float rounding, the GPU
//! relight pass equals the CPU one at both precisions, and the hardware display equals
//! the CPU display (with direct light from the elements, per pixel, and from the
//! shadow-mapped lights evaluated per frame by the GPU's own direct pass).

use std::sync::Arc;

use glam::Vec3;
use relight_pr::direct::DirectGather;
use relight_pr::display::{
    PixelDirect, Shading, Welding, compose, light_slots, pixel_direct, pixel_direct_shadowed,
};
use relight_pr::gpu::GpuRelight;
use relight_pr::packed::{Packed, Precision};
use relight_pr::{MeshSettings, Meshing, Solution, SolverSettings, relight, solve};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::GpuGBuffer;
use scene_core::lights::{LightId, LightState};
use scene_core::ray::RayScene;
use scene_core::shadowed_lights::{LightSet, ShadowSettings};
use scene_core::testing::gpu_test_context;
use scene_core::{GBufferRenderer, Scene, View, builtin};

fn solved() -> (Arc<Scene>, Meshing, Solution, RayScene) {
    let scene = Arc::new(builtin::scene("corridor").unwrap());
    let k = scene_core::lights::light_ids(&scene).len();
    let meshing = Meshing::new(&scene, &MeshSettings::elements(400), k).unwrap();
    let rays = RayScene::build(&scene);
    let settings = SolverSettings {
        max_unshot: 0.02,
        visibility_samples: 4,
        ..Default::default()
    };
    let solution = solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap();
    (scene, meshing, solution, rays)
}

/// A light state that recolours, dims and switches lights, direct and indirect apart.
fn edited(scene: &Scene) -> LightState {
    let mut state = LightState::default();
    state.set_color(LightId::Point(0), Vec3::new(2.0, 0.5, 0.1));
    state.set_enabled(LightId::Point(1), false);
    if let Some(id) = scene_core::lights::light_ids(scene).get(2) {
        let setting = state.get(*id);
        state.set(
            *id,
            scene_core::lights::LightSetting {
                indirect: 3.0,
                direct: 0.5,
                ..setting
            },
        );
    }
    state
}

/// Largest difference relative to the largest magnitude of `b`.
/// The element G-buffer of `scene`'s camera 0 at `w x h`, on the CPU and uploaded.
fn element_gbuffer(
    ctx: &scene_core::gpu::GpuContext,
    scene: &Scene,
    meshing: &Meshing,
    w: u32,
    h: u32,
) -> (View, scene_core::GBuffer, GpuGBuffer) {
    let view = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
    let mut renderer = RayCastRenderer::new();
    renderer
        .prepare(Arc::new(meshing.element_scene(scene)))
        .unwrap();
    let g = renderer.render_view(&view, w, h).unwrap();
    let gg = GpuGBuffer::upload(ctx, &g).unwrap();
    (view, g, gg)
}

/// The CPU display of `g` under `state` (smooth shading): with per-pixel direct `values`
/// the elements carry the indirect light only and each pixel adds its own direct light
/// times the state's direct factors; without, the elements carry both.
fn cpu_display(
    meshing: &Meshing,
    welding: &Welding,
    solution: &Solution,
    state: &LightState,
    (g, view): (&scene_core::GBuffer, &View),
    values: Option<&[Vec3]>,
) -> scene_core::Image {
    let e = match values {
        Some(_) => relight::indirect_irradiance(solution, state),
        None => relight::irradiance(solution, state),
    };
    let glow = relight::Glow::new(meshing, solution, state);
    let (f, _) = relight::weights(solution, state, true);
    let factors: Vec<Vec3> = f.iter().map(|(d, _)| *d).collect();
    compose(
        meshing,
        welding,
        g,
        view,
        &e,
        &glow,
        Shading::Smooth,
        values.map(|values| PixelDirect {
            values,
            factors: &factors,
        }),
    )
}

fn rel_max(a: &[Vec3], b: &[Vec3]) -> f32 {
    let scale = b.iter().map(|v| v.abs().max_element()).fold(0.0, f32::max);
    assert!(scale > 0.0);
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).abs().max_element())
        .fold(0.0, f32::max)
        / scale
}

#[test]
fn packed_relight_equals_the_solution_relight_and_f16_stays_within_rounding() {
    let (scene, _, solution, _) = solved();
    let state = edited(&scene);
    let want = relight::irradiance(&solution, &state);
    let (f, base) = relight::weights(&solution, &state, true);
    let f32s = Packed::new(
        &solution.direct,
        &solution.indirect,
        solution.k(),
        Precision::F32,
    );
    let f16s = Packed::new(
        &solution.direct,
        &solution.indirect,
        solution.k(),
        Precision::F16,
    );
    assert_eq!(f16s.bytes() * 2, f32s.bytes());
    assert_eq!(
        f32s.relight(&f, base),
        want,
        "f32 words are the same numbers, summed in the same order"
    );
    // Each stored value rounds to 2^-11 relative; factors are non-negative, so the sum
    // does too (plus f32 rounding).
    let got = f16s.relight(&f, base);
    for (g, w) in got.iter().zip(&want) {
        assert!(
            (*g - *w).abs().max_element() <= 5e-4 * w.abs().max_element() + 1e-30,
            "{g} vs {w}"
        );
    }
    // And a relight with a factor beyond half range stays finite: values saturate.
    let huge = Packed::new(&[Vec3::splat(1e9)], &[Vec3::splat(-1e9)], 1, Precision::F16);
    let (d, i) = huge.get(0, 0);
    assert_eq!((d, i), (Vec3::splat(65504.0), Vec3::splat(-65504.0)));
    // Counted, not silent.
    assert_eq!(huge.saturated, 6);
    assert_eq!(f16s.saturated, 0);
}

#[test]
fn gpu_f16_storage_that_would_saturate_is_refused() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let (scene, meshing, mut solution, _) = solved();
    let welding = Welding::new(&meshing, scene.extent());
    // A light a million times brighter: its solution passes f16's range.
    for v in solution
        .direct
        .iter_mut()
        .chain(solution.indirect.iter_mut())
    {
        *v *= 1e6;
    }
    let Err(e) = GpuRelight::new(&ctx, &meshing, &welding, &solution, Precision::F16) else {
        panic!("an f16 solution past 65504 is refused");
    };
    assert!(e.to_string().contains("saturate"), "{e}");
    assert!(GpuRelight::new(&ctx, &meshing, &welding, &solution, Precision::F32).is_ok());
}

#[test]
fn gpu_relight_equals_cpu_at_both_precisions() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let (scene, meshing, solution, _) = solved();
    let welding = Welding::new(&meshing, scene.extent());
    let state = edited(&scene);
    let (f, base) = relight::weights(&solution, &state, true);
    for precision in [Precision::F32, Precision::F16] {
        let cpu = Packed::new(
            &solution.direct,
            &solution.indirect,
            solution.k(),
            precision,
        )
        .relight(&f, base);
        let gpu = GpuRelight::new(&ctx, &meshing, &welding, &solution, precision).unwrap();
        let got = gpu.relight(&f, base).unwrap();
        let e = rel_max(&got, &cpu);
        eprintln!("{precision:?}: GPU relight differs from the CPU by {e:.2e} of the peak");
        assert!(e < 1e-5, "{precision:?}: {e}");
        // A factor list of the wrong length is a typed error.
        assert!(gpu.relight(&f[1..], base).is_err());
    }
}

#[test]
fn hardware_display_equals_the_cpu_display() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let (scene, meshing, solution, rays) = solved();
    let welding = Welding::new(&meshing, scene.extent());
    let state = edited(&scene);
    let (w, h) = (64, 48);
    let (view, g, gg) = element_gbuffer(&ctx, &scene, &meshing, w, h);
    let gpu = GpuRelight::new(&ctx, &meshing, &welding, &solution, Precision::F32).unwrap();
    let (f, base) = relight::weights(&solution, &state, true);

    // Direct light from the elements (the paper's display).
    let cpu = cpu_display(&meshing, &welding, &solution, &state, (&g, &view), None);
    let got = gpu.display(&gg, &view, &f, base, None).unwrap();
    let err = rel_max(&got.pixels, &cpu.pixels);
    eprintln!("hardware display, direct from elements: {err:.2e} of the peak");
    assert!(err < 1e-4, "{err}");

    // Direct light per pixel.
    let gather = DirectGather::new(&scene, &meshing, &solution.sources, 4);
    let values = pixel_direct(&gather, &rays, &g, &view, 4);
    let cpu = cpu_display(
        &meshing,
        &welding,
        &solution,
        &state,
        (&g, &view),
        Some(&values),
    );
    let got = gpu.display(&gg, &view, &f, base, Some(&values)).unwrap();
    let err = rel_max(&got.pixels, &cpu.pixels);
    eprintln!("hardware display, direct per pixel: {err:.2e} of the peak");
    assert!(err < 1e-4, "{err}");
    assert!(
        gpu.display(&gg, &view, &f, base, Some(&values[1..]))
            .is_err()
    );
}

/// A scene without lights solves to zero sources; the hardware display (what the viewer
/// draws) binds its buffers and shows black, as the CPU display does.
#[test]
fn a_scene_without_lights_displays_black_on_the_gpu() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let mut scene = builtin::scene("corridor").unwrap();
    scene.point_lights.clear();
    let scene = Arc::new(scene);
    assert!(!scene_core::contract::is_lit(&scene));
    let meshing = Meshing::new(&scene, &MeshSettings::elements(100), 0).unwrap();
    let rays = RayScene::build(&scene);
    let solution = solve(
        &scene,
        &meshing,
        &rays,
        &SolverSettings::default(),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!((solution.k(), solution.elements), (0, meshing.groups.count));
    let welding = Welding::new(&meshing, scene.extent());
    let (w, h) = (16, 12);
    let (view, _, gg) = element_gbuffer(&ctx, &scene, &meshing, w, h);
    let gpu = GpuRelight::new(&ctx, &meshing, &welding, &solution, Precision::F32).unwrap();
    let state = LightState::default();
    let (f, base) = relight::weights(&solution, &state, true);
    let got = gpu.display(&gg, &view, &f, base, None).unwrap();
    assert_eq!(got.pixels.len(), (w * h) as usize);
    assert!(got.pixels.iter().all(|p| *p == Vec3::ZERO));
    assert_eq!(
        relight::irradiance(&solution, &state).len(),
        meshing.groups.count
    );
}

/// Frames recorded into the caller's encoder (relight, then the display with per-pixel
/// direct light) create no GPU object once their inputs have been seen, while the lights
/// change colour every frame (wgpu's counters just before and after recording); and a
/// relight and a display of two light states encoded before one submit each use their own
/// factors.
#[test]
fn steady_state_frames_create_no_gpu_objects() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    use scene_core::gpu::ObjectCounts;
    assert!(
        ObjectCounts::available(&ctx.device),
        "wgpu built without `counters`"
    );
    let (scene, meshing, solution, rays) = solved();
    let welding = Welding::new(&meshing, scene.extent());
    let (w, h) = (48, 32);
    let (view, g, gg) = element_gbuffer(&ctx, &scene, &meshing, w, h);
    let gpu = GpuRelight::new(&ctx, &meshing, &welding, &solution, Precision::F32).unwrap();
    let gather = DirectGather::new(&scene, &meshing, &solution.sources, 4);
    let values = pixel_direct(&gather, &rays, &g, &view, 4);
    let output = ctx.pixel_buffer("display", w, h);
    let mut frames = Vec::new();
    for frame in 0..6 {
        let mut state = LightState::default();
        state.set_color(LightId::Point(0), Vec3::new(1.0, 0.2 * frame as f32, 0.5));
        let (f, base) = relight::weights(&solution, &state, true);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let (result, created) = ObjectCounts::during(&ctx.device, || {
            gpu.encode_relight(&mut encoder, &f, base, None)?;
            gpu.encode_display(&mut encoder, &gg, &view, &f, base, Some(&values), &output)
        });
        result.unwrap();
        ctx.queue.submit([encoder.finish()]);
        let image: Vec<[f32; 4]> = ctx.read_buffer_as(&output).unwrap();
        frames.push(image);
        assert_eq!(created.pipelines, 0, "frame {frame}: {created}");
        if frame >= 2 {
            assert!(created.is_zero(), "frame {frame}: {created}");
        }
    }
    assert_ne!(frames[0], frames[5], "the colour change must show");
    // Two states in one submission: each display as when submitted alone.
    let (a, b) = (ctx.pixel_buffer("a", w, h), ctx.pixel_buffer("b", w, h));
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    for (frame, out) in [(0, &a), (5, &b)] {
        let mut state = LightState::default();
        state.set_color(LightId::Point(0), Vec3::new(1.0, 0.2 * frame as f32, 0.5));
        let (f, base) = relight::weights(&solution, &state, true);
        gpu.encode_display(&mut encoder, &gg, &view, &f, base, Some(&values), out)
            .unwrap();
    }
    ctx.queue.submit([encoder.finish()]);
    assert!(
        ctx.read_buffer_as::<[f32; 4]>(&a).unwrap() == frames[0],
        "first state"
    );
    assert!(
        ctx.read_buffer_as::<[f32; 4]>(&b).unwrap() == frames[5],
        "second state"
    );
}

/// Small shadow maps for the tests (the defaults' 256-texel cube faces cost seconds in an
/// unoptimised test build).
fn test_shadows() -> ShadowSettings {
    ShadowSettings {
        cube_resolution: 64,
        emitter_samples: 8,
        emitter_cube_resolution: 32,
        directional_resolution: 256,
        ..Default::default()
    }
}

/// The per-frame direct light of the shadow-mapped lights, evaluated by the GPU's direct
/// pass in the display's encoder, equals the CPU twin (`pixel_direct_shadowed` + `compose`)
/// per pixel within rounding, under a light state that recolours, dims and switches; a
/// display asked for before the lights are set, or with a slot list of another length, is
/// a typed error; and steady frames create no GPU object.
#[test]
fn shadowed_direct_display_equals_the_cpu_twin() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let (scene, meshing, solution, _) = solved();
    let welding = Welding::new(&meshing, scene.extent());
    let state = edited(&scene);
    let (w, h) = (64, 48);
    let (view, g, gg) = element_gbuffer(&ctx, &scene, &meshing, w, h);
    let mut gpu = GpuRelight::new(&ctx, &meshing, &welding, &solution, Precision::F32).unwrap();
    let (f, base) = relight::weights(&solution, &state, true);
    assert!(gpu.display_shadowed(&gg, &view, &f, base).is_err());

    let set = LightSet::new(&scene, &test_shadows()).unwrap();
    let slots = light_slots(&set, &solution.sources);
    assert!(
        slots.iter().all(Option::is_some),
        "every light has a source"
    );
    assert!(gpu.set_shadowed_direct(&set, &slots[1..], 3).is_err());
    assert!(gpu.set_shadowed_direct(&set, &slots, 0).is_err());
    assert!(gpu.set_shadowed_direct(&set, &slots, 5).is_err());
    gpu.set_shadowed_direct(&set, &slots, 3).unwrap();

    let planes = meshing.plane_normals();
    let values = pixel_direct_shadowed(&set, &slots, solution.k(), &g, &view, 3, Some(&planes));
    let cpu = cpu_display(
        &meshing,
        &welding,
        &solution,
        &state,
        (&g, &view),
        Some(&values),
    );
    let lit = values.iter().filter(|v| v.max_element() > 0.0).count();
    assert!(lit > values.len() / 4, "the maps light the corridor: {lit}");
    let got = gpu.display_shadowed(&gg, &view, &f, base).unwrap();
    let err = rel_max(&got.pixels, &cpu.pixels);
    eprintln!("hardware display, direct from shadow maps: {err:.2e} of the peak");
    assert!(err < 1e-4, "{err}");

    use scene_core::gpu::ObjectCounts;
    let output = ctx.pixel_buffer("display", w, h);
    for frame in 0..4 {
        let mut state = LightState::default();
        state.set_color(LightId::Point(0), Vec3::new(1.0, 0.3 * frame as f32, 0.5));
        let (f, base) = relight::weights(&solution, &state, true);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let (result, created) = ObjectCounts::during(&ctx.device, || {
            gpu.encode_relight(&mut encoder, &f, base, None)?;
            gpu.encode_display_shadowed(&mut encoder, &gg, &view, &f, base, &output)
        });
        result.unwrap();
        ctx.queue.submit([encoder.finish()]);
        let image: Vec<[f32; 4]> = ctx.read_buffer_as(&output).unwrap();
        assert!(image.iter().any(|p| p[0] > 0.0), "frame {frame} is lit");
        assert_eq!(created.pipelines, 0, "frame {frame}: {created}");
        if frame >= 2 {
            assert!(created.is_zero(), "frame {frame}: {created}");
        }
    }
}
