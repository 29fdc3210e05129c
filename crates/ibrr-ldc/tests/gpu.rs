//! The GPU reconstruction against the CPU one: the same LDC read through the same camera
//! G-buffer gives the same image (all three kernels, with the fallback and the camera's
//! visibility test at work), and the same counts of pixels without a layer.

use std::sync::Arc;

use ibrr_ldc::{GpuLdc, IbrrSettings, IbrrTechnique, Lookup, Reading, reconstruct, shade};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::GpuGBuffer;
use scene_core::lights::{LightId, LightState, light_ids};
use scene_core::testing::gpu_test_context;
use scene_core::{FrameRequest, GBufferRenderer, Technique, builtin};

#[test]
fn gpu_reconstruction_equals_the_cpu_one() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let mut filled = 0;
    for name in ["cornell", "primitives"] {
        let scene = Arc::new(builtin::scene(name).unwrap());
        // A coarse LDC and few IRPLs, so that the fallback and missing pixels occur.
        let settings = IbrrSettings {
            target_error: 0.0,
            resolution: 48,
            irpls: 24,
            ..Default::default()
        };
        let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
        t.prepare(scene.clone()).unwrap();
        let ldc = t.ldc().unwrap();
        let frame = FrameRequest::camera(&scene.cameras[0], 96, 72);
        let g = RayCastRenderer::new()
            .render(&scene, &frame.view, 96, 72)
            .unwrap();
        let gg = GpuGBuffer::upload(&ctx, &g).unwrap();
        let mut lights = LightState::default();
        // The glow follows the light state (the LDC itself was built for the default).
        if let Some(&LightId::Emissive(m)) = light_ids(&scene)
            .iter()
            .find(|i| matches!(i, LightId::Emissive(_)))
        {
            lights.set_color(LightId::Emissive(m), glam::Vec3::new(0.5, 1.0, 2.0));
        }
        for lookup in [
            Lookup::Nearest,
            Lookup::Average { radius: 1 },
            Lookup::Bilinear,
        ] {
            let reading = Reading {
                lookup,
                ..settings.reading()
            };
            let r = reconstruct(ldc, &g, &frame.view, reading);
            let cpu = shade(&scene, &g, &frame.view, &r, &lights);
            let mut gpu_ldc = GpuLdc::new(&ctx, ldc, reading).unwrap();
            let (gpu, counts) = gpu_ldc.render(&scene, &gg, &frame.view, &lights).unwrap();
            let peak = cpu
                .pixels
                .iter()
                .map(|p| p.max_element())
                .fold(0.0f32, f32::max);
            let mut off = 0;
            let mut worst = 0.0f32;
            for (a, b) in cpu.pixels.iter().zip(&gpu.pixels) {
                let d = (*a - *b).abs().max_element();
                worst = worst.max(d);
                // f32 rounding may flip a plane or visibility threshold on a pixel or two.
                if d > 1e-4 * peak {
                    off += 1;
                }
            }
            println!(
                "{name} {lookup:?}: {off} of {} pixels differ, worst {worst:.2e} of peak {peak:.2e}; missing {} / {}, fallback {} / {}, filled {} / {}",
                cpu.pixels.len(),
                r.missing,
                counts.missing,
                r.fallback,
                counts.fallback,
                r.filled,
                counts.filled
            );
            assert!(
                off <= cpu.pixels.len() / 500,
                "{name} {lookup:?}: {off} pixels differ"
            );
            assert!(
                r.missing.abs_diff(counts.missing) <= 2
                    && r.fallback.abs_diff(counts.fallback) <= 2
                    && r.filled.abs_diff(counts.filled) <= 2
            );
            filled += r.filled;
        }
    }
    // The coarse LDC leaves holes, so the twins' hole fills are compared too.
    assert!(filled > 0, "no pixel was filled: the fill went untested");
}

#[test]
fn the_technique_on_the_gpu_renders_what_it_renders_on_the_cpu() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let scene = Arc::new(builtin::scene("cornell-point").unwrap());
    let settings = IbrrSettings {
        target_error: 0.0,
        resolution: 48,
        irpls: 16,
        ..Default::default()
    };
    let mut cpu = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    let mut gpu = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new())).on_gpu(ctx);
    cpu.prepare(scene.clone()).unwrap();
    gpu.prepare(scene.clone()).unwrap();
    let frame = FrameRequest::camera(&scene.cameras[0], 64, 48);
    let (a, b) = (cpu.render(&frame).unwrap(), gpu.render(&frame).unwrap());
    let peak = a
        .pixels
        .iter()
        .map(|p| p.max_element())
        .fold(0.0f32, f32::max);
    let off = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(x, y)| (**x - **y).abs().max_element() > 1e-4 * peak)
        .count();
    assert!(
        peak > 0.0 && off <= a.pixels.len() / 500,
        "{off} pixels differ"
    );
    assert_eq!(cpu.last_timings().missing, gpu.last_timings().missing);
}

#[test]
fn the_gpu_gather_builds_the_ldc_the_cpu_gather_builds() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    for name in ["cornell-point", "primitives"] {
        let scene = Arc::new(builtin::scene(name).unwrap());
        let settings = IbrrSettings {
            target_error: 0.0,
            resolution: 48,
            irpls: 12,
            clamp: 0.02,
            ..Default::default()
        };
        let build = |on_gpu: bool| {
            let mut c =
                ibrr_ldc::Construction::new(scene.clone(), &LightState::default(), &settings)
                    .unwrap();
            if on_gpu {
                c.gather_on_gpu(&ctx).unwrap();
            }
            let mut r = RayCastRenderer::new();
            c.prepare_renderer(&mut r).unwrap();
            while !c.is_done() {
                c.step(&mut r, 4).unwrap();
            }
            c.ldc().unwrap()
        };
        let (cpu, gpu) = (build(false), build(true));
        assert_eq!(
            cpu.layer_count(),
            gpu.layer_count(),
            "{name}: the scatter is the same"
        );
        assert!(cpu.layer_count() > 0);
        let peak = cpu
            .indirect
            .iter()
            .chain(&cpu.direct)
            .map(|v| v.max_element())
            .fold(0.0f32, f32::max);
        let off = (0..cpu.layer_count())
            .filter(|&l| {
                (cpu.direct[l] - gpu.direct[l]).abs().max_element() > 1e-4 * peak
                    || (cpu.indirect[l] - gpu.indirect[l]).abs().max_element() > 1e-4 * peak
            })
            .count();
        println!("{name}: {off} of {} layers differ", cpu.layer_count());
        // f32 rounding may flip a visibility threshold on a layer or two.
        assert!(
            off <= cpu.layer_count() / 1000,
            "{name}: {off} layers differ"
        );
    }
}

/// Frames recorded into the caller's encoder create no GPU object once their inputs have
/// been seen, while an emitter changes colour every frame (the glow table is rewritten in
/// place): wgpu's counters just before and after `encode`. Two light states encoded before
/// one submit each get their own parameters and glow.
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
    let scene = Arc::new(builtin::scene("cornell").unwrap());
    let settings = IbrrSettings {
        target_error: 0.0,
        resolution: 32,
        irpls: 16,
        ..Default::default()
    };
    let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    t.prepare(scene.clone()).unwrap();
    let ldc = t.ldc().unwrap();
    let (w, h) = (48, 36);
    let frame = FrameRequest::camera(&scene.cameras[0], w, h);
    let g = RayCastRenderer::new()
        .render(&scene, &frame.view, w, h)
        .unwrap();
    let gg = GpuGBuffer::upload(&ctx, &g).unwrap();
    let emitter = *light_ids(&scene)
        .iter()
        .find(|i| matches!(i, LightId::Emissive(_)))
        .expect("cornell has an emissive panel");
    let state = |k: usize| {
        let mut s = LightState::default();
        s.set_color(emitter, glam::Vec3::new(1.0, 0.3 * k as f32, 0.5));
        s
    };
    let mut gpu_ldc = GpuLdc::new(&ctx, ldc, Reading::with_lookup(Lookup::Nearest)).unwrap();
    let output = ctx.pixel_buffer("ibrr", w, h);
    let mut images = Vec::new();
    for k in 0..6 {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let (result, created) = ObjectCounts::during(&ctx.device, || {
            gpu_ldc.encode(&mut encoder, &scene, &gg, &frame.view, &state(k), &output)
        });
        result.unwrap();
        ctx.queue.submit([encoder.finish()]);
        images.push(ctx.read_buffer_as::<[f32; 4]>(&output).unwrap());
        assert_eq!(created.pipelines, 0, "frame {k}: {created}");
        if k >= 2 {
            assert!(created.is_zero(), "frame {k}: {created}");
        }
    }
    assert_ne!(images[0], images[5], "the glow's colour must show");
    let (a, b) = (ctx.pixel_buffer("a", w, h), ctx.pixel_buffer("b", w, h));
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    for (k, out) in [(0, &a), (5, &b)] {
        gpu_ldc
            .encode(&mut encoder, &scene, &gg, &frame.view, &state(k), out)
            .unwrap();
    }
    ctx.queue.submit([encoder.finish()]);
    assert!(
        ctx.read_buffer_as::<[f32; 4]>(&a).unwrap() == images[0],
        "first state"
    );
    assert!(
        ctx.read_buffer_as::<[f32; 4]>(&b).unwrap() == images[5],
        "second state"
    );
}
