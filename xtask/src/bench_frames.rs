//! `cargo xtask bench frames`: what a frame of each method costs an engine that hosts it
//! through the frame contract (`scene_core::gpu::GpuFrame`, docs/engine.md): the engine's
//! G-buffer in compact formats (8-bit sRGB albedo, octahedral half normals, its reverse-Z
//! infinite-far depth buffer, no ids) converted by `HostGBufferPass`, then the method's
//! `encode` into an `Rgba16Float` target, submitted and waited for. Each figure is the
//! wall-clock time from recording to completion, median of `repeats` frames after one
//! warm-up: a frame under the previous frame's light state, and a frame whose light changes
//! colour (relighting's factors, ISR's light buffers, the IBRR's per-source recombination on
//! the CPU). Beside the wall-clock time, where the adapter has timestamp queries and is not
//! a CPU, the GPU's own time from the frame's first command to its last (two empty compute
//! passes marking them), and the method's commands alone (the conversion left out, what the
//! main job with `--gpu` times): on a fast GPU a small frame's wall-clock time is mostly
//! submission and wake-up latency. Timed frames run at the device's working clocks: after an
//! idle second, the method's frames saturate the device first (gpu_frames' `Warmth`). Every
//! method's precomputation is done before the clock starts and reported beside. Figures are
//! printed; nothing is asserted. With `--cold-cache`, 256 MiB are written through the device
//! (submitted and waited for, untimed) before each timed frame, so that the frame finds its
//! caches as an engine's other passes leave them. The "GPU method" span begins with a timestamp written when
//! the method's first command is reached, which may be before the conversion has finished.

use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::{
    FrameInputs, GpuContext, GpuError, GpuGBuffer, HostGBuffer, HostGBufferPass, ObjectCounts,
};
use scene_core::lights::{LightState, light_ids};
use scene_core::shadowed_lights::{LightSet, ShadowSettings};
use scene_core::testing::EngineGBuffer;
use scene_core::view::DepthConvention;
use scene_core::{GBufferRenderer, Scene, View, builtin};

use crate::gpu_frames::{BoxedFrame, GpuSpan, Warmth, ibrr_maker, isr_maker, relight_maker};

use crate::bench::median;

/// Relighting's element target (the main job's larger one).
const RELIGHT_ELEMENTS: usize = 1024;

/// Parses `WxH`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("--sizes: '{s}' is not WIDTHxHEIGHT"))?;
    let side = |v: &str, what: &str| -> Result<u32, String> {
        let n: u32 = v
            .trim()
            .parse()
            .map_err(|_| format!("--sizes: '{s}': the {what} is not a whole number"))?;
        crate::ranged(what, n, scene_core::range::IMAGE_SIDE)
    };
    Ok((side(w, "width")?, side(h, "height")?))
}

/// A method on the frame contract and its precomputation time in seconds.
type Prepared = (BoxedFrame, f64);

/// The methods (DL, screen-space ISR, ISR at its defaults with the light-space senders of the `isr-N` techniques,
/// relighting at [`RELIGHT_ELEMENTS`] in half precision, the IBRR at its defaults), prepared for `scene` on `ctx`'s device, with their precomputation times.
fn methods(ctx: &GpuContext, scene: &Arc<Scene>, threads: usize) -> Result<Vec<Prepared>, String> {
    let pool = crate::bench::worker_pool(threads)?;
    pool.install(|| {
        let makers = [
            isr_maker(isr::IsrSettings::dl()),
            isr_maker(isr::IsrSettings::screen_space()),
            isr_maker(isr::IsrSettings::default()),
            relight_maker(RELIGHT_ELEMENTS, relight_pr::packed::Precision::F16),
            ibrr_maker(ibrr_ldc::IbrrSettings::default().fixed_count()),
        ];
        let mut out: Vec<Prepared> = Vec::new();
        for mut make in makers {
            let t0 = Instant::now();
            let frame = make(ctx, scene).map_err(|e| e.to_string())?;
            out.push((frame, t0.elapsed().as_secs_f64()));
        }
        Ok(out)
    })
}

/// An engine's frame at one size: its compact G-buffer converted by `HostGBufferPass`, then
/// a method's `encode` into an `Rgba16Float` target, all recorded into the engine's encoder.
struct EngineFrame<'a> {
    convert: HostGBufferPass,
    host: HostGBuffer<'a>,
    convention: DepthConvention,
    converted: GpuGBuffer,
    view: View,
    target: wgpu::Texture,
}

impl EngineFrame<'_> {
    /// Records the conversion and `method`'s frame under `lights`; `marks` (when given)
    /// brackets the method's own commands.
    fn record(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        method: &mut BoxedFrame,
        lights: &LightState,
        marks: Option<&GpuSpan>,
    ) -> Result<(), GpuError> {
        self.convert
            .encode(encoder, &self.host, &self.convention, &self.converted)?;
        if let Some(span) = marks {
            span.mark(encoder, false);
        }
        let inputs = FrameInputs {
            gbuffer: &self.converted,
            view: &self.view,
            lights,
        };
        method
            .encode(encoder, &inputs, &self.target)
            .map_err(|e| GpuError::Validation(e.to_string()))?;
        if let Some(span) = marks {
            span.mark(encoder, true);
        }
        Ok(())
    }
}

/// Bytes written through the device before each timed frame with `--cold-cache`: several
/// times the last-level cache of current GPUs (an H100's or H200's L2 holds 50-60 MiB).
const COLD_CACHE_BYTES: u64 = 256 << 20;

/// `cargo xtask bench frames` (module docs) on the built-in `scene` at each of `sizes`;
/// `cold_cache` writes [`COLD_CACHE_BYTES`] through the device (submitted and waited for,
/// outside the timed frame) before each timed frame.
pub fn run(
    scene_name: &str,
    threads: usize,
    repeats: usize,
    sizes: &[(u32, u32)],
    cold_cache: bool,
) -> Result<(), String> {
    let ctx = GpuContext::new().map_err(|e| e.to_string())?;
    let flush = cold_cache.then(|| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench frames cache flush"),
            size: COLD_CACHE_BYTES.min(ctx.device.limits().max_buffer_size),
            usage: wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    });
    let scene = Arc::new(builtin::scene(scene_name).map_err(|e| e.to_string())?);
    let first = *light_ids(&scene)
        .first()
        .ok_or_else(|| format!("{scene_name} has no light to recolour"))?;
    println!(
        "frames through the frame contract on {scene_name}; GPU: {}; CPU work on {threads} \
         thread(s); median of {repeats} frames after 1 warm-up, recording to completion (ms){}",
        ctx.adapter_summary(),
        if flush.is_some() {
            "; each frame after 256 MiB written through the device (cold caches)"
        } else {
            ""
        }
    );
    let span = GpuSpan::new(&ctx);
    // A second span inside the first: the method's own commands, the conversion left out.
    let method_span = GpuSpan::new(&ctx);
    if span.is_none() {
        println!("  (no GPU time: this adapter has no timestamp queries, or is a CPU)");
    }
    let mut prepared = methods(&ctx, &scene, threads)?;
    for (method, seconds) in &prepared {
        println!("  {:<8} prepared in {seconds:.2} s", method.name());
    }
    shadow_maps(&ctx, &scene, threads, repeats, span.as_ref())?;
    light_senders(&ctx, &scene, threads, repeats)?;
    let mut renderer = RayCastRenderer::new();
    for &(w, h) in sizes {
        let cam = scene.cameras[0].with_aspect(w as f32 / h as f32);
        let own = View::from_camera(&cam);
        let projection = glam::camera::rh::proj::directx::perspective_infinite_reverse(
            cam.fov_y, cam.aspect, cam.near,
        );
        let (view, convention) =
            View::from_host_matrices(own.view_matrix(), projection).map_err(|e| e.to_string())?;
        let g = renderer
            .render(&scene, &view, w, h)
            .map_err(|e| e.to_string())?;
        let engine =
            EngineGBuffer::compact(&ctx, &g, view.far, &convention).map_err(|e| e.to_string())?;
        let mut engine_frame = EngineFrame {
            convert: HostGBufferPass::new(&ctx).map_err(|e| e.to_string())?,
            host: engine.host(),
            convention,
            converted: GpuGBuffer::new(&ctx, w, h).map_err(|e| e.to_string())?,
            view,
            target: ctx.create_texture_2d(
                "bench frame target",
                w,
                h,
                wgpu::TextureFormat::Rgba16Float,
                wgpu::TextureUsages::STORAGE_BINDING,
            ),
        };
        let wait = || {
            ctx.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        // The conversion alone.
        let mut convert_ms = Vec::new();
        for i in 0..=repeats {
            let t0 = Instant::now();
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            let f = &mut engine_frame;
            f.convert
                .encode(&mut encoder, &f.host, &f.convention, &f.converted)
                .map_err(|e| e.to_string())?;
            ctx.queue.submit([encoder.finish()]);
            wait()?;
            if i > 0 {
                convert_ms.push(t0.elapsed().as_secs_f64() * 1e3);
            }
        }
        println!();
        println!(
            "{w}x{h}: G-buffer conversion alone {:.2} ms",
            median(convert_ms)
        );
        println!(
            "  {:<8} {:>12} {:>10} {:>10} {:>12} {:>10} {:>26}",
            "method",
            "steady wall",
            "GPU",
            "GPU method",
            "change wall",
            "GPU",
            "created per steady frame"
        );
        for (method, _) in prepared.iter_mut() {
            let colour = |i: usize| {
                let mut s = LightState::default();
                s.set_color(first, Vec3::new(1.0, 0.5 + 0.1 * (i % 5) as f32, 0.5));
                s
            };
            let still = colour(0);
            // On a device that has cooled, saturated first until its clocks are up
            // (gpu_frames' `Warmth`).
            let cooled = Warmth::cooled();
            Warmth::before_timing(
                span.is_some() && cooled,
                &ctx.device,
                |encoder| engine_frame.record(encoder, method, &still, None),
                |encoder| {
                    ctx.queue.submit([encoder.finish()]);
                    wait().map_err(GpuError::Validation)
                },
            )
            .map_err(|e| format!("{}: {e}", method.name()))?;
            let mut frame = |lights: &LightState| -> Result<(f64, f64, f64, ObjectCounts), String> {
                if let Some(flush) = &flush {
                    let mut encoder = ctx.device.create_command_encoder(&Default::default());
                    encoder.clear_buffer(flush, 0, None);
                    ctx.queue.submit([encoder.finish()]);
                    wait()?;
                }
                let t0 = Instant::now();
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                if let Some(span) = &span {
                    span.mark(&mut encoder, false);
                }
                let (result, created) = ObjectCounts::during(&ctx.device, || {
                    engine_frame.record(&mut encoder, method, lights, method_span.as_ref())
                });
                result.map_err(|e| format!("{}: {e}", method.name()))?;
                if let Some(span) = &span {
                    span.mark(&mut encoder, true);
                }
                ctx.queue.submit([encoder.finish()]);
                wait()?;
                let wall = t0.elapsed().as_secs_f64() * 1e3;
                Warmth::busy();
                let read = |s: &Option<GpuSpan>| match s {
                    Some(s) => s.read(&ctx),
                    None => Ok(f64::NAN),
                };
                Ok((wall, read(&span)?, read(&method_span)?, created))
            };
            frame(&still)?;
            let (mut steady, mut steady_gpu, mut steady_method) =
                (Vec::new(), Vec::new(), Vec::new());
            let mut created = ObjectCounts::default();
            for _ in 0..repeats {
                let (ms, gpu, alone, c) = frame(&still)?;
                steady.push(ms);
                steady_gpu.push(gpu);
                steady_method.push(alone);
                created = c;
            }
            frame(&colour(1))?;
            let (mut changing, mut changing_gpu) = (Vec::new(), Vec::new());
            for i in 0..repeats {
                let (ms, gpu, _, _) = frame(&colour(i + 2))?;
                changing.push(ms);
                changing_gpu.push(gpu);
            }
            let gpu_ms = |v: Vec<f64>| {
                if span.is_some() {
                    format!("{:.3}", median(v))
                } else {
                    "n/a".into()
                }
            };
            println!(
                "  {:<8} {:>12.2} {:>10} {:>10} {:>12.2} {:>10} {:>26}",
                method.name(),
                median(steady),
                gpu_ms(steady_gpu),
                gpu_ms(steady_method),
                median(changing),
                gpu_ms(changing_gpu),
                if ObjectCounts::available(&ctx.device) {
                    format!(
                        "{}b {}t {}g {}p",
                        created.buffers, created.textures, created.bind_groups, created.pipelines
                    )
                } else {
                    "(no counters)".into()
                }
            );
        }
    }
    Ok(())
}

/// The default ISR's light-space senders (`isr::DEFAULT_LIGHT_SENDERS`, one bounce, their
/// visibility maps): traced on the CPU (`threads` workers, the scene's tree built once
/// beforehand) against traced on the GPU through the GPU path tracer's tree
/// (`LightSenders::on_gpu`, with its readbacks), what a light that moves costs. Wall
/// clock, median of `repeats` after a warm-up.
fn light_senders(
    ctx: &GpuContext,
    scene: &Scene,
    threads: usize,
    repeats: usize,
) -> Result<(), String> {
    use isr::LightSenders;
    use scene_core::ray::RayScene;
    use scene_core::reference::{Bounces, GpuPathTracer};
    let set = LightSet::new(scene, &ShadowSettings::default()).map_err(|e| e.to_string())?;
    let budget = isr::DEFAULT_LIGHT_SENDERS;
    let tree = Arc::new(RayScene::build(scene));
    let pool = crate::bench::worker_pool(threads)?;
    let cpu_ms = pool.install(|| {
        crate::bench::time_ms(repeats, || {
            LightSenders::with_rays(scene, Some(tree.clone()), &set, budget, Bounces::Limited(1))
                .map(|_| ())
                .map_err(|e| e.to_string())
        })
    })?;
    let tracer =
        GpuPathTracer::new(ctx, scene, &LightState::default()).map_err(|e| e.to_string())?;
    let mut count = 0;
    let gpu_ms = pool.install(|| {
        crate::bench::time_ms(repeats, || {
            count = LightSenders::on_gpu(scene, &tracer, &set, budget, Bounces::Limited(1))
                .map_err(|e| e.to_string())?
                .senders
                .len();
            Ok(())
        })
    })?;
    println!(
        "  light-space senders ({count}, {} visibility rays): traced on the CPU {cpu_ms:.1} ms; \
         on the GPU {gpu_ms:.1} ms wall (readbacks included)",
        count * (isr::light_senders::DEPTH_RES * isr::light_senders::DEPTH_RES) as usize
    );
    Ok(())
}

/// The scene's shadow maps at the default settings (what ISR, DL and relighting read):
/// ray cast on the CPU (`LightSet::from_lights`, `threads` workers) against rasterised on
/// the GPU from a vertex buffer (`ShadowMapPass`), what a light or caster that moves costs.
fn shadow_maps(
    ctx: &GpuContext,
    scene: &Scene,
    threads: usize,
    repeats: usize,
    span: Option<&GpuSpan>,
) -> Result<(), String> {
    use scene_core::shadowed_lights::gpu_maps::{CasterVertices, ShadowMapPass};
    let shadows = ShadowSettings::default();
    let lights = LightSet::new(scene, &shadows)
        .map_err(|e| e.to_string())?
        .lights;
    let casters = scene.triangle_corners();
    let pool = crate::bench::worker_pool(threads)?;
    let cpu_ms = pool.install(|| {
        crate::bench::time_ms(repeats, || {
            LightSet::from_lights(lights.clone(), &casters, &shadows)
                .map(|_| ())
                .map_err(|e| e.to_string())
        })
    })?;
    let vertices = CasterVertices::new(ctx, &casters).map_err(|e| e.to_string())?;
    let (set, plan) = LightSet::planned(lights.clone(), vertices.bounds(), &shadows)
        .map_err(|e| e.to_string())?;
    let pass =
        ShadowMapPass::new(ctx, &set, &plan, CasterVertices::LAYOUT).map_err(|e| e.to_string())?;
    let casters_in = vertices.casters();
    let (mut wall, mut gpu) = (Vec::new(), Vec::new());
    for i in 0..=repeats {
        let t0 = Instant::now();
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        if let Some(span) = span {
            span.mark(&mut encoder, false);
        }
        pass.encode(&mut encoder, &set, &casters_in)
            .map_err(|e| e.to_string())?;
        if let Some(span) = span {
            span.mark(&mut encoder, true);
        }
        ctx.queue.submit([encoder.finish()]);
        ctx.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| e.to_string())?;
        if i > 0 {
            wall.push(t0.elapsed().as_secs_f64() * 1e3);
            if let Some(span) = span {
                gpu.push(span.read(ctx)?);
            }
        }
    }
    println!(
        "  shadow maps ({} maps, {} texels): CPU ray cast {cpu_ms:.2} ms; GPU raster {:.2} ms wall{}",
        plan.len(),
        pass.texel_count(),
        median(wall),
        if span.is_some() {
            format!(", {:.3} ms GPU", median(gpu))
        } else {
            String::new()
        }
    );
    Ok(())
}
