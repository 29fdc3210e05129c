//! The GPU path against the CPU path (the readable reference) on the built-in scenes, and
//! its error handling. Skipped without an adapter unless `REQUIRE_GPU` is set (CI runs it
//! on Mesa's lavapipe).

mod common;

use common::{
    Setup, assert_gpu_twin, image_mean, max_difference, mean_error, modes, small_shadows,
};
use isr::{Backend, Blur, GpuIsr, GpuIsrInputs, IsrError, IsrSettings, IsrTechnique, render_cpu};
use std::sync::Arc;

use scene_core::FrameRequest;
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::{GpuContext, GpuGBuffer, ObjectCounts};
use scene_core::testing::gpu_test_context;
use scene_core::{Technique, builtin};

fn all_settings() -> Vec<(&'static str, IsrSettings)> {
    let mut v = modes();
    v.push(("dl", IsrSettings::dl()));
    v.push((
        "edge-aware, normal weight, AO on indirect, 24 samples",
        IsrSettings {
            blur: Blur::EdgeAware,
            upsample_normal_power: 8.0,
            ao_indirect_only: true,
            samples: 24,
            ..IsrSettings::screen_space()
        },
    ));
    v
}

fn output(ctx: &GpuContext, w: u32, h: u32, format: wgpu::TextureFormat) -> wgpu::Texture {
    let usage = wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC;
    ctx.create_texture_2d("test output", w, h, format, usage)
}

#[test]
fn gpu_matches_cpu_on_the_builtin_scenes() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    eprintln!("GPU tests on {}", ctx.adapter_summary());
    for name in builtin::SMALL_INSTANCES {
        let setup = Setup::builtin(name, 0, 96, 72);
        let mut gpu = GpuIsr::new(&ctx, &setup.prepared).unwrap();
        for (mode, s) in all_settings() {
            let cpu = render_cpu(&setup.prepared, &setup.inputs(), &s).unwrap();
            // The same coarse buffer...
            let (img, _) = gpu
                .render_gbuffer(&setup.full, Some(&setup.coarse), &setup.view, &s)
                .unwrap();
            // Every pixel, not only the mean (common::assert_gpu_twin).
            assert_gpu_twin(&format!("{name} {mode}"), &cpu.image, &img);
            // ... and the coarse buffer downsampled on the GPU.
            let (img, _) = gpu
                .render_gbuffer(&setup.full, None, &setup.view, &s)
                .unwrap();
            assert_gpu_twin(&format!("{name} {mode}, GPU downsample"), &cpu.image, &img);
        }
    }
}

#[test]
fn engine_integration_records_into_the_callers_encoder_and_texture() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let setup = Setup::builtin("cornell", 0, 64, 48);
    let mut gpu = GpuIsr::new(&ctx, &setup.prepared).unwrap();
    let full = GpuGBuffer::upload(&ctx, &setup.full).unwrap();
    let s = IsrSettings::screen_space();
    let cpu = render_cpu(&setup.prepared, &setup.inputs(), &s)
        .unwrap()
        .image;
    for format in [
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureFormat::Rgba16Float,
    ] {
        let target = output(&ctx, 64, 48, format);
        let inputs = GpuIsrInputs {
            full: &full,
            coarse: None,
            view: &setup.view,
        };
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        gpu.encode(&mut encoder, &inputs, &s, &target).unwrap();
        ctx.queue.submit([encoder.finish()]);
        let bytes = ctx.read_texture_bytes(&target).unwrap();
        let pixels: Vec<glam::Vec3> = if format == wgpu::TextureFormat::Rgba32Float {
            bytes
                .chunks_exact(16)
                .map(|c| {
                    let f: [f32; 4] = bytemuck::pod_read_unaligned(c);
                    glam::Vec3::new(f[0], f[1], f[2])
                })
                .collect()
        } else {
            bytes
                .chunks_exact(8)
                .map(|c| {
                    let h: [u16; 4] = bytemuck::pod_read_unaligned(c);
                    glam::Vec3::new(half(h[0]), half(h[1]), half(h[2]))
                })
                .collect()
        };
        let img = scene_core::Image::from_pixels(64, 48, pixels).unwrap();
        let tolerance = if format == wgpu::TextureFormat::Rgba16Float {
            // Half floats carry 11 significant bits.
            2e-3
        } else {
            1e-3
        };
        let e = mean_error(&cpu, &img);
        assert!(e < tolerance * image_mean(&cpu), "{format:?}: {e}");
        let peak = cpu
            .pixels
            .iter()
            .map(|p| p.max_element())
            .fold(1.0f32, f32::max);
        let (dmax, at) = max_difference(&cpu, &img);
        assert!(
            dmax <= f64::from(tolerance as f32 * peak),
            "{format:?}: max |cpu - gpu| = {dmax:.3e} at pixel {at}"
        );
    }
}

/// IEEE half to f32 (normal numbers and zero are enough here).
fn half(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as i32;
    let frac = (h & 0x3ff) as f32;
    if exp == 0 {
        sign * frac * 2f32.powi(-24)
    } else {
        sign * (1.0 + frac / 1024.0) * 2f32.powi(exp - 15)
    }
}

#[test]
fn bad_outputs_and_inputs_are_typed_errors() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let setup = Setup::builtin("cornell-point", 0, 32, 24);
    let mut gpu = GpuIsr::new(&ctx, &setup.prepared).unwrap();
    let full = GpuGBuffer::upload(&ctx, &setup.full).unwrap();
    let inputs = GpuIsrInputs {
        full: &full,
        coarse: None,
        view: &setup.view,
    };
    let s = IsrSettings::screen_space();
    let wrong_size = output(&ctx, 16, 24, wgpu::TextureFormat::Rgba32Float);
    assert!(matches!(
        ctx.submit_encoded(|e| gpu.encode(e, &inputs, &s, &wrong_size))
            .unwrap_err(),
        IsrError::SizeMismatch(_)
    ));
    let wrong_format = output(&ctx, 32, 24, wgpu::TextureFormat::Rgba8Unorm);
    assert!(matches!(
        ctx.submit_encoded(|e| gpu.encode(e, &inputs, &s, &wrong_format))
            .unwrap_err(),
        IsrError::Gpu(_)
    ));
    let no_storage = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d {
            width: 32,
            height: 24,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    });
    assert!(
        ctx.submit_encoded(|e| gpu.encode(e, &inputs, &s, &no_storage))
            .is_err()
    );
    let bad = IsrSettings { samples: 0, ..s };
    let ok = output(&ctx, 32, 24, wgpu::TextureFormat::Rgba32Float);
    assert!(matches!(
        ctx.submit_encoded(|e| gpu.encode(e, &inputs, &bad, &ok))
            .unwrap_err(),
        IsrError::InvalidSetting { .. }
    ));
    // NaN in a CPU G-buffer is caught before upload.
    let mut nan = setup.full.clone();
    let i = nan.triangle_id.iter().position(|&t| t != u32::MAX).unwrap();
    nan.normal[i].x = f32::NAN;
    assert!(matches!(
        gpu.render_gbuffer(&nan, None, &setup.view, &s).unwrap_err(),
        IsrError::NonFinite { .. }
    ));
    // A 1x1 frame.
    let one = Setup::builtin("cornell", 0, 1, 1);
    let mut gpu = GpuIsr::new(&ctx, &one.prepared).unwrap();
    let (img, _) = gpu.render_gbuffer(&one.full, None, &one.view, &s).unwrap();
    assert!(img.pixels[0].is_finite());
}

#[test]
fn the_technique_runs_on_the_gpu() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let scene = builtin::scene("primitives").unwrap();
    let mut cpu = IsrTechnique::new(IsrSettings::default(), Box::new(RayCastRenderer::new()))
        .with_shadows(small_shadows());
    let mut gpu = IsrTechnique::new(IsrSettings::default(), Box::new(RayCastRenderer::new()))
        .with_shadows(small_shadows())
        .with_backend(Backend::Gpu(ctx));
    cpu.prepare(Arc::new(scene.clone())).unwrap();
    gpu.prepare(Arc::new(scene.clone())).unwrap();
    let a = cpu
        .render(&FrameRequest::camera(&scene.cameras[0], 48, 36))
        .unwrap();
    let b = gpu
        .render(&FrameRequest::camera(&scene.cameras[0], 48, 36))
        .unwrap();
    assert!(mean_error(&a, &b) < 1e-3 * image_mean(&a));
    assert!(gpu.last_timings().lighting > std::time::Duration::ZERO);
}

/// A frame recorded into the caller's encoder creates no GPU object once its inputs have
/// been seen, while the lights change colour every frame (wgpu's counters just before and just after `encode`, before the submit could
/// free anything), and none compiles a pipeline, not even the first. Two views encoded
/// before one submit each get their own uniforms.
#[test]
fn steady_state_frames_create_no_gpu_objects() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let setup = Setup::builtin("cornell", 0, 64, 48);
    let mut gpu = GpuIsr::new(&ctx, &setup.prepared).unwrap();
    let full = GpuGBuffer::upload(&ctx, &setup.full).unwrap();
    let target = output(&ctx, 64, 48, wgpu::TextureFormat::Rgba32Float);
    assert!(
        ObjectCounts::available(&ctx.device),
        "wgpu's counters read zero: built without its `counters` feature"
    );
    for (name, s) in [
        ("default", IsrSettings::screen_space()),
        ("dl", IsrSettings::dl()),
    ] {
        for frame in 0..5 {
            let inputs = GpuIsrInputs {
                full: &full,
                coarse: None,
                view: &setup.view,
            };
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            // The light changes colour every frame.
            let mut state = scene_core::LightState::default();
            for id in scene_core::lights::light_ids(&setup.scene) {
                state.set_color(id, glam::Vec3::new(1.0, 0.5 + 0.1 * frame as f32, 0.7));
            }
            let (result, created) = ObjectCounts::during(&ctx.device, || {
                gpu.apply(&state);
                gpu.encode(&mut encoder, &inputs, &s, &target)
            });
            result.unwrap();
            ctx.queue.submit([encoder.finish()]);
            gpu.wait().unwrap();
            assert_eq!(created.pipelines, 0, "{name}, frame {frame}: {created}");
            if frame >= 2 {
                assert!(created.is_zero(), "{name}, frame {frame}: {created}");
            }
        }
    }
    // Two views before one submit: each as when rendered alone.
    let other = {
        let mut v = setup.view;
        v.eye += v.right() * 0.05;
        v
    };
    let s = IsrSettings::screen_space();
    let alone = |view: &scene_core::View, gpu: &mut GpuIsr| {
        let t = output(&ctx, 64, 48, wgpu::TextureFormat::Rgba32Float);
        let inputs = GpuIsrInputs {
            full: &full,
            coarse: None,
            view,
        };
        ctx.submit_encoded(|e| gpu.encode(e, &inputs, &s, &t))
            .unwrap();
        ctx.read_texture_bytes(&t).unwrap()
    };
    let (a_alone, b_alone) = (alone(&setup.view, &mut gpu), alone(&other, &mut gpu));
    assert_ne!(
        a_alone, b_alone,
        "the two views must differ for the check to mean anything"
    );
    let (ta, tb) = (
        output(&ctx, 64, 48, wgpu::TextureFormat::Rgba32Float),
        output(&ctx, 64, 48, wgpu::TextureFormat::Rgba32Float),
    );
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    for (view, t) in [(&setup.view, &ta), (&other, &tb)] {
        let inputs = GpuIsrInputs {
            full: &full,
            coarse: None,
            view,
        };
        gpu.encode(&mut encoder, &inputs, &s, t).unwrap();
    }
    ctx.queue.submit([encoder.finish()]);
    assert!(
        ctx.read_texture_bytes(&ta).unwrap() == a_alone,
        "first view"
    );
    assert!(
        ctx.read_texture_bytes(&tb).unwrap() == b_alone,
        "second view"
    );
}

/// A renderer whose G-buffers stay on the GPU and which refuses to render one on the CPU.
struct GpuOnly {
    inner: RayCastRenderer,
    ctx: scene_core::gpu::GpuContext,
}

impl scene_core::GBufferRenderer for GpuOnly {
    fn name(&self) -> &str {
        "gpu-only"
    }

    fn prepare(&mut self, scene: Arc<scene_core::Scene>) -> Result<(), scene_core::Error> {
        self.inner.prepare(scene)
    }

    fn prepared_scene(&self) -> Option<&Arc<scene_core::Scene>> {
        self.inner.prepared_scene()
    }

    fn render_views(
        &mut self,
        _: &[scene_core::ViewTarget],
    ) -> Result<Vec<scene_core::GBuffer>, scene_core::Error> {
        Err(scene_core::Error::InvalidArgument(
            "a G-buffer was asked for on the CPU".into(),
        ))
    }

    fn render_views_gpu(
        &mut self,
        views: &[scene_core::ViewTarget],
    ) -> Result<Option<Vec<GpuGBuffer>>, scene_core::Error> {
        let on_cpu = self.inner.render_views(views)?;
        let mut out = Vec::new();
        for g in &on_cpu {
            out.push(GpuGBuffer::upload(&self.ctx, g)?);
        }
        Ok(Some(out))
    }
}

/// The GPU technique takes a G-buffer that its renderer keeps on the GPU where it is (no
/// read-back and upload again): with a renderer that refuses CPU G-buffers it renders, and
/// its image is the one of the same G-buffer uploaded.
#[test]
fn the_gpu_technique_takes_a_gpu_gbuffer_where_it_is() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let scene = Arc::new(builtin::scene("cornell").unwrap());
    let frame = FrameRequest::camera(&scene.cameras[0], 48, 36);
    let mut uploaded = IsrTechnique::new(IsrSettings::default(), Box::new(RayCastRenderer::new()))
        .with_shadows(small_shadows())
        .with_backend(Backend::Gpu(ctx.clone()));
    let gpu_only = GpuOnly {
        inner: RayCastRenderer::new(),
        ctx: ctx.clone(),
    };
    let mut resident = IsrTechnique::new(IsrSettings::default(), Box::new(gpu_only))
        .with_shadows(small_shadows())
        .with_backend(Backend::Gpu(ctx.clone()));
    uploaded.prepare(scene.clone()).unwrap();
    resident.prepare(scene.clone()).unwrap();
    let a = uploaded.render(&frame).unwrap();
    let b = resident.render(&frame).unwrap();
    assert!(image_mean(&a) > 0.0);
    assert!(
        a.pixels == b.pixels,
        "the same G-buffer gives the same image"
    );
    // On the CPU backend the renderer's refusal surfaces as the technique's error.
    let mut cpu = IsrTechnique::new(
        IsrSettings::default(),
        Box::new(GpuOnly {
            inner: RayCastRenderer::new(),
            ctx,
        }),
    )
    .with_shadows(small_shadows());
    cpu.prepare(scene.clone()).unwrap();
    assert!(cpu.render(&frame).is_err());
}
