//! The IBRR on an engine's G-buffer (docs/engine.md): the engine's albedo and normal
//! textures and its depth buffer in the reverse-Z, infinite-far convention most engines
//! use, converted by scene-core's `HostGBufferPass`, with the engine's triangle ids and
//! without any, give the reconstruction of the toolkit's own G-buffer of the same view.

use std::sync::Arc;

use glam::Vec3;
use ibrr_ldc::{GpuLdc, IbrrSettings, IbrrTechnique};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::{GpuGBuffer, HostGBuffer, HostGBufferPass};
use scene_core::lights::LightState;
use scene_core::testing::{EngineGBuffer, gpu_test_context};
use scene_core::{FrameRequest, GBufferRenderer, Image, Technique, View, builtin};

/// The conversion rounds each distance by a few f32 units in the last place (scene-core's
/// host G-buffer test measures 8.8e-8 reversed), so the images agree to that order: the
/// mean difference within 1e-4 of the image's mean, and no more than 0.5 % of the pixels
/// off by over 1e-3 of the peak (a sample on one of the reconstruction's plane or
/// visibility thresholds may flip). Without ids, the pixels of emitters lose their glow
/// (the methods treat a surface without an id as one that emits nothing) and are left out.
#[test]
fn an_engine_gbuffer_in_reverse_z_gives_the_own_gbuffers_image() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let scene = Arc::new(builtin::scene("cornell").unwrap());
    let settings = IbrrSettings {
        target_error: 0.0,
        resolution: 48,
        irpls: 24,
        ..Default::default()
    };
    let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    t.prepare(scene.clone()).unwrap();
    let ldc = t.ldc().unwrap();
    let (w, h) = (64, 48);
    let frame = FrameRequest::camera(&scene.cameras[0], w, h);
    let g = RayCastRenderer::new()
        .render(&scene, &frame.view, w, h)
        .unwrap();
    let lights = LightState::default();
    let mut gpu_ldc = GpuLdc::new(&ctx, ldc, settings.reading()).unwrap();
    let (own, _) = gpu_ldc
        .render(
            &scene,
            &GpuGBuffer::upload(&ctx, &g).unwrap(),
            &frame.view,
            &lights,
        )
        .unwrap();
    let emitters = g.emitter_mask(&scene);
    assert!(emitters.iter().any(|e| *e), "the panel is in view");

    let cam = scene.cameras[0].with_aspect(w as f32 / h as f32);
    let projection = glam::camera::rh::proj::directx::perspective_infinite_reverse(
        cam.fov_y, cam.aspect, cam.near,
    );
    let (view, convention) =
        View::from_host_matrices(frame.view.view_matrix(), projection).unwrap();
    assert!(convention.reverse);
    let engine = EngineGBuffer::float(&ctx, &g, frame.view.far, &convention, true).unwrap();
    let mut convert = HostGBufferPass::new(&ctx).unwrap();
    for (name, triangle_id) in [
        ("with ids", engine.triangle_id.as_ref()),
        ("without ids", None),
    ] {
        let host = HostGBuffer {
            triangle_id,
            ..engine.host()
        };
        let converted = GpuGBuffer::new(&ctx, w, h).unwrap();
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        convert
            .encode(&mut encoder, &host, &convention, &converted)
            .unwrap();
        ctx.queue.submit([encoder.finish()]);
        let (img, _) = gpu_ldc.render(&scene, &converted, &view, &lights).unwrap();
        let keep: Vec<usize> = (0..g.len())
            .filter(|&i| triangle_id.is_some() || !emitters[i])
            .collect();
        let mean = |image: &Image| {
            keep.iter()
                .map(|&i| f64::from(image.pixels[i].element_sum()))
                .sum::<f64>()
                / keep.len() as f64
        };
        let diff = keep
            .iter()
            .map(|&i| f64::from((own.pixels[i] - img.pixels[i]).abs().element_sum()))
            .sum::<f64>()
            / keep.len() as f64;
        let peak = keep
            .iter()
            .map(|&i| own.pixels[i].max_element())
            .fold(0.0f32, f32::max);
        let off = keep
            .iter()
            .filter(|&&i| (own.pixels[i] - img.pixels[i]).abs().max_element() > 1e-3 * peak)
            .count();
        let m = mean(&own);
        eprintln!(
            "{name}: mean difference {:.2e} of the mean, {off} of {} pixels above 1e-3 of the peak",
            diff / m,
            keep.len()
        );
        assert!(m > 0.0 && mean(&img) > 0.0, "{name}: lit");
        assert!(diff <= 1e-4 * m, "{name}: {diff} against a mean of {m}");
        assert!(off * 200 <= keep.len(), "{name}: {off} pixels");
        if triangle_id.is_none() {
            // The emitters' own pixels: the glow is gone, what they reflect is kept.
            let glowing = (0..g.len()).filter(|&i| emitters[i]).collect::<Vec<_>>();
            let own_sum: Vec3 = glowing.iter().map(|&i| own.pixels[i]).sum();
            let got_sum: Vec3 = glowing.iter().map(|&i| img.pixels[i]).sum();
            assert!(got_sum.element_sum() < 0.5 * own_sum.element_sum());
        }
    }
}

/// The IBRR on the frame contract (`IbrrFrame` as a `GpuFrame`): its target holds the
/// reconstruction `GpuLdc` reads back (same pass, then the copy into the texture), under the
/// default light state and after a recolouring (against a second construction from the
/// same seed relit on its own); a frame under an unchanged light state creates no GPU
/// object, and a light change only staging buffers.
#[test]
fn the_frame_contract_gives_the_reconstruction_and_creates_nothing_per_frame() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    use scene_core::gpu::{FrameInputs, GpuFrame, ObjectCounts};
    use scene_core::lights::{LightId, light_ids};
    let scene = Arc::new(builtin::scene("cornell").unwrap());
    let settings = IbrrSettings {
        target_error: 0.0,
        resolution: 32,
        irpls: 16,
        ..Default::default()
    };
    let technique = || {
        let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
        t.prepare(scene.clone()).unwrap();
        t
    };
    let (w, h) = (48, 36);
    let frame = FrameRequest::camera(&scene.cameras[0], w, h);
    let g = RayCastRenderer::new()
        .render(&scene, &frame.view, w, h)
        .unwrap();
    let gg = GpuGBuffer::upload(&ctx, &g).unwrap();
    let emitter = *light_ids(&scene)
        .iter()
        .find(|i| matches!(i, LightId::Emissive(_)))
        .unwrap();
    let recoloured = {
        let mut s = LightState::default();
        s.set_color(emitter, Vec3::new(1.0, 0.4, 0.1));
        s
    };
    // The library's images: a second construction, relit and read back by GpuLdc.
    let mut other = technique();
    let expected: Vec<Image> = [LightState::default(), recoloured.clone()]
        .iter()
        .map(|state| {
            other.relight(state).unwrap().unwrap();
            let mut gpu = GpuLdc::new(&ctx, other.ldc().unwrap(), settings.reading()).unwrap();
            gpu.render(&scene, &gg, &frame.view, state).unwrap().0
        })
        .collect();

    let mut method = ibrr_ldc::IbrrFrame::prepare(&ctx, technique()).unwrap();
    assert_eq!(method.name(), "ibrr");
    let target = ctx.create_texture_2d(
        "frame target",
        w,
        h,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
    );
    let wrong = ctx.create_texture_2d(
        "wrong target",
        w + 1,
        h,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::STORAGE_BINDING,
    );
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    let default = LightState::default();
    let inputs = |lights| FrameInputs {
        gbuffer: &gg,
        view: &frame.view,
        lights,
    };
    assert!(
        method
            .encode(&mut encoder, &inputs(&default), &wrong)
            .is_err()
    );
    let states = [
        &default,
        &default,
        &recoloured,
        &recoloured,
        &default,
        &default,
    ];
    for (k, state) in states.into_iter().enumerate() {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let (result, created) = ObjectCounts::during(&ctx.device, || {
            method.encode(&mut encoder, &inputs(state), &target)
        });
        result.unwrap();
        ctx.queue.submit([encoder.finish()]);
        let got = ctx.read_texture_image(&target).unwrap().pixels;
        let want = &expected[usize::from(state != &default)];
        let worst = got
            .iter()
            .zip(&want.pixels)
            .map(|(a, b)| (*a - *b).abs().max_element())
            .fold(0.0f32, f32::max);
        let peak = want
            .pixels
            .iter()
            .map(|p| p.max_element())
            .fold(0.0f32, f32::max);
        eprintln!(
            "frame {k}: worst difference {worst:.2e} of a peak {peak:.2e}; created {created}"
        );
        assert!(worst <= 1e-5 * peak, "frame {k}: {worst}");
        assert_eq!(created.pipelines, 0, "frame {k}: {created}");
        let changed = k > 0 && states[k] != states[k - 1];
        if changed {
            // A light change stages the recombined values (every layer's light, far more
            // than a frame's uniforms) in the writer's belt, which may take a new staging
            // chunk while the last one is still on its way back: only staging buffers.
            assert!(
                created.textures == 0 && created.bind_groups == 0 && created.texture_views == 0,
                "frame {k}: {created}"
            );
        } else if k > 0 {
            assert!(created.is_zero(), "frame {k}: {created}");
        }
    }
}
