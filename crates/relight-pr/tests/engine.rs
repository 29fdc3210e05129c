//! Relighting on the frame contract (`RelightFrame` as a `GpuFrame`, docs/engine.md): fed an
//! engine's G-buffer (the scene's own triangles, no ids, reverse-Z infinite depth,
//! converted by scene-core's `HostGBufferPass`), the frame renders its element ids itself
//! and gives the library's display of the element scene's G-buffer; a steady stream of
//! frames whose light changes colour every frame creates no GPU object.

use std::sync::Arc;

use glam::Vec3;
use relight_pr::display::{Welding, light_slots};
use relight_pr::gpu::GpuRelight;
use relight_pr::packed::Precision;
use relight_pr::{
    MeshSettings, Meshing, Prepared, RelightFrame, RelightFrameSettings, SolverSettings, relight,
    solve,
};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::{
    FrameInputs, GpuFrame, GpuGBuffer, HostGBuffer, HostGBufferPass, ObjectCounts,
};
use scene_core::lights::{LightId, LightState, light_ids};
use scene_core::ray::RayScene;
use scene_core::shadowed_lights::{LightSet, ShadowSettings};
use scene_core::testing::{EngineGBuffer, gpu_test_context};
use scene_core::{GBufferRenderer, View, builtin};

/// How an image agrees with the one it should equal.
struct Agreement {
    /// The expected image's mean (the channels' sum per pixel).
    mean: f64,
    /// The mean absolute difference, in the same units.
    diff: f64,
    /// Pixels off by more than 1e-3 of the expected image's peak channel.
    off: usize,
}

fn agreement(got: &[Vec3], want: &[Vec3]) -> Agreement {
    let n = want.len() as f64;
    let peak = want.iter().map(|p| p.max_element()).fold(0.0f32, f32::max);
    Agreement {
        mean: want.iter().map(|p| f64::from(p.element_sum())).sum::<f64>() / n,
        diff: got
            .iter()
            .zip(want)
            .map(|(a, b)| f64::from((*a - *b).abs().element_sum()))
            .sum::<f64>()
            / n,
        off: got
            .iter()
            .zip(want)
            .filter(|(a, b)| (**a - **b).abs().max_element() > 1e-3 * peak)
            .count(),
    }
}

/// The Cornell box meshed into about `elements` elements and solved (to 2 % unshot, 4
/// visibility samples), with its welding.
fn solved_cornell(elements: usize) -> Prepared {
    let scene = Arc::new(builtin::scene("cornell").unwrap());
    let k = light_ids(&scene).len();
    let meshing = Meshing::new(&scene, &MeshSettings::elements(elements), k).unwrap();
    let rays = RayScene::build(&scene);
    let settings = SolverSettings {
        max_unshot: 0.02,
        visibility_samples: 4,
        ..Default::default()
    };
    let solution = solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap();
    let welding = Welding::new(&meshing, scene.extent());
    Prepared {
        scene,
        meshing,
        solution,
        welding,
        rays,
    }
}

/// Bounds. The frame's ids come from a raster of the element triangles, the library's from
/// the ray caster: both sample pixel centres, so they differ only where an element's edge
/// passes within rounding of a centre. Inside a surface a neighbouring element gives almost
/// the same value (the display interpolates welded vertices); on a silhouette the host's
/// depth and the raster's id may name different surfaces. The engine's depth rounds each
/// distance by a few f32 units in the last place (scene-core's host G-buffer test). So, as
/// for the IBRR's engine test: the mean difference within 1e-4 of the image's mean, and no
/// more than 0.5 % of the pixels off by over 1e-3 of the peak.
#[test]
fn the_frame_contract_gives_the_display_from_an_engine_gbuffer_and_creates_nothing_per_frame() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let prepared = solved_cornell(300);
    let (scene, meshing, solution, welding) = (
        &prepared.scene,
        &prepared.meshing,
        &prepared.solution,
        &prepared.welding,
    );
    let shadows = ShadowSettings {
        cube_resolution: 64,
        emitter_samples: 8,
        emitter_cube_resolution: 32,
        directional_resolution: 256,
        ..Default::default()
    };
    let lights = LightSet::new(scene, &shadows).unwrap();
    let slots = light_slots(&lights, &solution.sources);
    let upload = || {
        let mut gpu = GpuRelight::new(&ctx, meshing, welding, solution, Precision::F32).unwrap();
        gpu.set_shadowed_direct(&lights, &slots, 3).unwrap();
        gpu
    };

    let (w, h) = (64, 48);
    let cam = scene.cameras[0].with_aspect(w as f32 / h as f32);
    let own_view = View::from_camera(&cam);
    // The library's image: the element scene's G-buffer, ids from the ray caster.
    let mut renderer = RayCastRenderer::new();
    renderer
        .prepare(Arc::new(meshing.element_scene(scene)))
        .unwrap();
    let elements_g =
        GpuGBuffer::upload(&ctx, &renderer.render_view(&own_view, w, h).unwrap()).unwrap();
    let library = upload();
    let emitter = *light_ids(scene)
        .iter()
        .find(|i| matches!(i, LightId::Emissive(_)))
        .unwrap();
    let state = |frame: usize| {
        let mut s = LightState::default();
        s.set_color(emitter, Vec3::new(1.0, 0.15 * frame as f32, 0.4));
        s
    };
    let expected = |s: &LightState| {
        let (f, base) = relight::weights(solution, s, true);
        library
            .display_shadowed(&elements_g, &own_view, &f, base)
            .unwrap()
    };

    // The engine's G-buffer: the scene's own triangles, float textures, no ids, its depth
    // buffer reversed with the far plane at infinity.
    let g = RayCastRenderer::new()
        .render(scene, &own_view, w, h)
        .unwrap();
    let projection = glam::camera::rh::proj::directx::perspective_infinite_reverse(
        cam.fov_y, cam.aspect, cam.near,
    );
    let (view, convention) = View::from_host_matrices(own_view.view_matrix(), projection).unwrap();
    assert!(convention.reverse && convention.infinite);
    let engine = EngineGBuffer::float(&ctx, &g, own_view.far, &convention, false).unwrap();
    let host = HostGBuffer {
        triangle_id: None,
        ..engine.host()
    };
    let mut convert = HostGBufferPass::new(&ctx).unwrap();
    let converted = GpuGBuffer::new(&ctx, w, h).unwrap();
    let target = ctx.create_texture_2d(
        "frame target",
        w,
        h,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
    );

    let settings = RelightFrameSettings {
        precision: Precision::F32,
        shadowed_direct: Some((&lights, 3)),
    };
    let mut method = RelightFrame::prepare(&ctx, &prepared, &settings).unwrap();
    assert_eq!(method.name(), "relight");
    let wrong = ctx.create_texture_2d(
        "wrong target",
        w,
        h + 1,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::STORAGE_BINDING,
    );
    let default = LightState::default();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    let refused = method.encode(
        &mut encoder,
        &FrameInputs {
            gbuffer: &converted,
            view: &view,
            lights: &default,
        },
        &wrong,
    );
    assert!(refused.is_err(), "a target of the wrong size is refused");

    let mut images = Vec::new();
    for frame in 0..5 {
        let lights = state(frame);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let (result, created) = ObjectCounts::during(&ctx.device, || {
            convert.encode(&mut encoder, &host, &convention, &converted)?;
            method
                .encode(
                    &mut encoder,
                    &FrameInputs {
                        gbuffer: &converted,
                        view: &view,
                        lights: &lights,
                    },
                    &target,
                )
                .map_err(|e| scene_core::gpu::GpuError::Validation(e.to_string()))
        });
        result.unwrap();
        ctx.queue.submit([encoder.finish()]);
        let got = ctx.read_texture_image(&target).unwrap().pixels;
        let want = expected(&lights);
        let Agreement { mean, diff, off } = agreement(&got, &want.pixels);
        eprintln!(
            "frame {frame}: mean difference {:.2e} of the mean, {off} of {} pixels above 1e-3 \
             of the peak; created {created}",
            diff / mean,
            got.len()
        );
        assert!(mean > 0.0, "lit");
        assert!(
            diff <= 1e-4 * mean,
            "frame {frame}: {diff} against a mean of {mean}"
        );
        assert!(off * 200 <= got.len(), "frame {frame}: {off} pixels");
        assert_eq!(created.pipelines, 0, "frame {frame}: {created}");
        if frame >= 2 {
            assert!(created.is_zero(), "frame {frame}: {created}");
        }
        images.push(got);
    }
    assert_ne!(images[0], images[4], "the colour change shows");
}

/// Shadow maps rendered on the GPU from the engine's vertex buffer (`ShadowMapPass`) and
/// copied into relighting's direct pass (`copy_shadow_texels`) give the frame of the CPU's
/// ray-cast maps of the same lights and casters.
#[test]
fn shadow_maps_rendered_on_the_gpu_give_the_ray_cast_maps_frame() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    use scene_core::shadowed_lights::gpu_maps::{CasterVertices, ShadowMapPass};
    let prepared = solved_cornell(200);
    let scene = &prepared.scene;
    let shadows = ShadowSettings {
        cube_resolution: 32,
        emitter_samples: 4,
        emitter_cube_resolution: 32,
        ..Default::default()
    };
    let casters = scene.triangle_corners();
    let lights = LightSet::new(scene, &shadows).unwrap().lights;
    let cpu = LightSet::from_lights(lights.clone(), &casters, &shadows).unwrap();
    let vertices = CasterVertices::new(&ctx, &casters).unwrap();
    let (planned, plan) = LightSet::planned(lights, vertices.bounds(), &shadows).unwrap();
    let maps = ShadowMapPass::new(&ctx, &planned, &plan, CasterVertices::LAYOUT).unwrap();
    let (w, h) = (48, 36);
    let view = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
    let g = GpuGBuffer::upload(
        &ctx,
        &RayCastRenderer::new().render(scene, &view, w, h).unwrap(),
    )
    .unwrap();
    let target = ctx.create_texture_2d(
        "frame target",
        w,
        h,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
    );
    let lights_state = LightState::default();
    let frame_of = |set: &LightSet, copy: bool| {
        let settings = RelightFrameSettings {
            precision: Precision::F32,
            shadowed_direct: Some((set, 3)),
        };
        let mut method = RelightFrame::prepare(&ctx, &prepared, &settings).unwrap();
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        if copy {
            maps.encode(&mut encoder, set, &vertices.casters()).unwrap();
            method
                .gpu()
                .copy_shadow_texels(&mut encoder, &maps)
                .unwrap();
        }
        let inputs = FrameInputs {
            gbuffer: &g,
            view: &view,
            lights: &lights_state,
        };
        method.encode(&mut encoder, &inputs, &target).unwrap();
        ctx.queue.submit([encoder.finish()]);
        ctx.read_texture_rgba32f(&target).unwrap()
    };
    let expected = frame_of(&cpu, false);
    let unshadowed = frame_of(&planned, false);
    let got = frame_of(&planned, true);
    // The blocks' shadows hold a few per cent of the image's light (2.8 % measured in ISR).
    scene_core::testing::assert_gpu_shadow_maps_match(&expected, &unshadowed, &got);
}

/// The relighting `Technique` on the GPU (`on_gpu`: the display on the frame contract, only
/// the image read back) gives the CPU technique's image, with each source of direct light:
/// the shadow maps evaluated per pixel, the per-pixel gather, the elements. Bounds as the
/// GPU display's own tests (rounding of the same sums in another order): the mean
/// difference within 1e-4 of the mean, no more than 0.5 % of the pixels off by over 1e-3 of
/// the peak.
#[test]
fn the_gpu_technique_gives_the_cpu_techniques_image() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    use relight_pr::RelightTechnique;
    use relight_pr::direct::DirectLight;
    use scene_core::{FrameRequest, Technique};
    let scene = Arc::new(builtin::scene("cornell").unwrap());
    let (w, h) = (48, 36);
    let request = FrameRequest::camera(&scene.cameras[0], w, h);
    let mut state = LightState::default();
    let emitter = *light_ids(&scene)
        .iter()
        .find(|i| matches!(i, LightId::Emissive(_)))
        .unwrap();
    state.set_color(emitter, Vec3::new(1.0, 0.5, 0.2));
    let frame = FrameRequest {
        lights: &state,
        ..request
    };
    let technique = |direct: DirectLight| {
        let settings = SolverSettings {
            max_unshot: 0.02,
            visibility_samples: 4,
            ..Default::default()
        };
        let mut t = RelightTechnique::new(
            MeshSettings::elements(300),
            settings,
            Box::new(RayCastRenderer::new()),
        );
        t.direct = direct;
        t
    };
    for direct in [
        DirectLight::shadow_maps(),
        DirectLight::PerPixel {
            subpixels: 2,
            emitter_rays: 2,
        },
        DirectLight::Elements,
    ] {
        let mut cpu = technique(direct);
        cpu.prepare(scene.clone()).unwrap();
        let want = cpu.render(&frame).unwrap();
        let mut gpu = technique(direct).on_gpu(ctx.clone());
        gpu.prepare(scene.clone()).unwrap();
        let got = gpu.render(&frame).unwrap();
        let Agreement { mean, diff, off } = agreement(&got.pixels, &want.pixels);
        eprintln!(
            "{direct:?}: mean difference {:.2e} of the mean, {off} of {} pixels above 1e-3 of \
             the peak",
            diff / mean,
            got.pixels.len()
        );
        assert!(mean > 0.0);
        assert!(diff <= 1e-4 * mean, "{direct:?}: {diff} against {mean}");
        assert!(off * 200 <= got.pixels.len(), "{direct:?}: {off} pixels");
        // Prepared again for another scene, as the main job does with one technique per
        // column: the frame is the new scene's (the GPU frame kept the first scene's
        // solution, and the corridor came out black on an H100).
        let corridor = Arc::new(builtin::scene("corridor").unwrap());
        let other = FrameRequest::camera(&corridor.cameras[0], w, h);
        cpu.prepare(corridor.clone()).unwrap();
        gpu.prepare(corridor.clone()).unwrap();
        let (a, b) = (cpu.render(&other).unwrap(), gpu.render(&other).unwrap());
        let Agreement {
            mean: m, diff: d, ..
        } = agreement(&b.pixels, &a.pixels);
        assert!(
            m > 0.0 && d <= 1e-4 * m,
            "{direct:?} re-prepared: {d} against {m}"
        );
    }
}
