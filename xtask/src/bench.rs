//! `cargo xtask bench reference`: rays per second of the reference path tracer.
//! Figures are printed (median of repeats after a warm-up); nothing is asserted.

use std::time::Instant;

use scene_core::View;
use scene_core::builtin;
use scene_core::reference::{Accumulator, Bounces, PathTracer};

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The rayon pool a benchmark runs its CPU work in.
pub(crate) fn worker_pool(threads: usize) -> Result<rayon::ThreadPool, String> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| e.to_string())
}

/// A GPU context for the GPU columns, or `None` after printing why there are none.
pub(crate) fn gpu_or_say_why() -> Option<scene_core::gpu::GpuContext> {
    scene_core::gpu::GpuContext::new()
        .map_err(|e| println!("no GPU figures: {e}"))
        .ok()
}

/// `cargo xtask bench isr`: ISR per-frame milliseconds at 1024x768 (512x384 coarse) with 24,
/// 48 and 80 samples, split by pass, on the CPU (`threads` workers) and the GPU (whatever
/// adapter wgpu picks; lavapipe without a GPU); DL (direct light only) for comparison.
/// Medians of `repeats` frames after one warm-up.
pub fn isr(threads: usize, repeats: usize) -> Result<(), String> {
    use isr::{GpuIsr, GpuIsrInputs, IsrInputs, IsrSettings, LightSet, PassTimings};
    use scene_core::GBufferRenderer;
    use scene_core::gbuffer::RayCastRenderer;
    use scene_core::gpu::GpuGBuffer;

    let (w, h) = (1024u32, 768u32);
    let (pool, gpu) = (worker_pool(threads)?, gpu_or_say_why());
    let err = |e: isr::IsrError| e.to_string();
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    // Per-pass medians of a list of frame timings.
    let medians = |frames: &[PassTimings]| -> [f64; 7] {
        let col = |f: &dyn Fn(&PassTimings) -> std::time::Duration| {
            median(frames.iter().map(|t| ms(f(t))).collect())
        };
        [
            col(&|t| t.downsample),
            col(&|t| t.senders),
            col(&|t| t.radiosity),
            col(&|t| t.blur),
            col(&|t| t.upsample),
            col(&|t| t.lighting),
            col(&|t| t.total()),
        ]
    };
    let row = |label: &str, m: [f64; 7]| {
        println!(
            "{label:<26} {:>10.2} {:>9.2} {:>10.2} {:>8.2} {:>9.2} {:>9.2} {:>9.2}",
            m[0], m[1], m[2], m[3], m[4], m[5], m[6]
        );
    };
    println!(
        "ISR at {w}x{h} output, {}x{} coarse; CPU on {threads} thread(s); GPU: {}; median of {repeats} frames after 1 warm-up (ms)",
        w / 2,
        h / 2,
        gpu.as_ref()
            .map_or("none".to_string(), |c| c.adapter_summary())
    );
    for name in ["corridor", "cornell"] {
        let scene = builtin::scene(name).map_err(|e| e.to_string())?;
        let view = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
        let t0 = Instant::now();
        let prepared = pool
            .install(|| LightSet::new(&scene, &isr::ShadowSettings::default()))
            .map_err(|e| e.to_string())?;
        let prepare = t0.elapsed();
        let full = RayCastRenderer::new()
            .render(&scene, &view, w, h)
            .map_err(|e| e.to_string())?;
        println!(
            "\n{name}: {} lights (emitter samples included), shadow maps built in {:.0} ms ({} texels)",
            prepared.lights.len(),
            ms(prepare),
            prepared.shadow_texels.len()
        );
        println!(
            "{:<26} {:>10} {:>9} {:>10} {:>8} {:>9} {:>9} {:>9}",
            "", "downsample", "senders", "ISR+SSAO", "blur", "upsample", "lighting", "frame"
        );
        let configs: Vec<(String, IsrSettings)> = [24u32, 48, 80]
            .iter()
            .map(|&n| {
                (
                    format!("ISR {n} samples, screen space"),
                    IsrSettings {
                        samples: n,
                        ..IsrSettings::screen_space()
                    },
                )
            })
            .chain([("DL".to_string(), IsrSettings::dl())])
            .collect();
        for (label, s) in &configs {
            let mut frames = Vec::new();
            for i in 0..=repeats {
                let frame = pool.install(|| {
                    let t = Instant::now();
                    let coarse = isr::downsample(&full, s.downsample);
                    let down = t.elapsed();
                    let inputs = IsrInputs {
                        full: &full,
                        coarse: &coarse,
                        view: &view,
                    };
                    isr::render_cpu(&prepared, &inputs, s).map(|f| PassTimings {
                        downsample: down,
                        ..f.timings
                    })
                });
                let t = frame.map_err(err)?;
                if i > 0 {
                    frames.push(t);
                }
            }
            row(&format!("CPU {label}"), medians(&frames));
        }
        let Some(ctx) = &gpu else {
            continue;
        };
        let mut g = GpuIsr::new(ctx, &prepared).map_err(err)?;
        let gfull = GpuGBuffer::upload(ctx, &full).map_err(|e| e.to_string())?;
        let out = g.output_texture(w, h).map_err(err)?;
        let inputs = GpuIsrInputs {
            full: &gfull,
            coarse: None,
            view: &view,
        };
        for (label, s) in &configs {
            let mut frames = Vec::new();
            let mut whole = Vec::new();
            for i in 0..=repeats {
                let t = g.render_timed(&inputs, s, &out).map_err(err)?;
                let start = Instant::now();
                ctx.submit_encoded(|e| g.encode(e, &inputs, s, &out))
                    .map_err(err)?;
                g.wait().map_err(err)?;
                if i > 0 {
                    frames.push(t);
                    whole.push(ms(start.elapsed()));
                }
            }
            let source = if frames.first().is_some_and(|t| t.gpu_timestamps) {
                "timestamps"
            } else {
                "wall clock"
            };
            row(&format!("GPU {label} ({source})"), medians(&frames));
            println!("{:<26} one submit per frame: {:.2}", "", median(whole));
        }
    }
    println!(
        "\n(GPU per-pass figures come from timestamp queries where the adapter has them, else from submitting and waiting for each pass; 'one submit per frame' is the wall-clock time of the whole frame in one command buffer.)"
    );
    Ok(())
}

/// Benchmarks the reference path tracer on `cornell` and `many-boxes` at about 10^6
/// triangles with `threads` workers.
pub fn reference(threads: usize, repeats: usize) -> Result<(), String> {
    let pool = worker_pool(threads)?;
    println!(
        "reference path tracer, {threads} thread(s), 160x120, 8 spp, unlimited bounces; median of {repeats} after 1 warm-up"
    );
    println!(
        "{:<22} {:>10} {:>12} {:>10} {:>12} {:>14}",
        "scene", "triangles", "BVH build", "ms/frame", "Mrays/s", "Mrays/s/core"
    );
    let scenes = [
        "cornell".to_string(),
        format!("many-boxes {}", builtin::MAX_BOXES),
    ];
    for name in scenes {
        let scene = builtin::scene(&name).map_err(|e| e.to_string())?;
        let cam = scene.cameras[0].with_aspect(160.0 / 120.0);
        let view = View::from_camera(&cam);
        let t0 = Instant::now();
        let tracer = pool.install(|| PathTracer::new(&scene));
        let build = t0.elapsed().as_secs_f64();
        let mut rates = Vec::new();
        let mut times = Vec::new();
        for i in 0..=repeats {
            let mut acc = Accumulator::new(160, 120);
            let stats = pool
                .install(|| acc.add_pass(&tracer, &view, Bounces::Unlimited, i as u64, 8, None));
            if i > 0 {
                rates.push(stats.rays_per_second());
                times.push(stats.seconds);
            }
        }
        let rate = median(rates);
        println!(
            "{:<22} {:>10} {:>10.1} s {:>10.1} {:>12.2} {:>14.2}",
            name,
            scene.triangle_count(),
            build,
            median(times) * 1e3,
            rate / 1e6,
            rate / 1e6 / threads.max(1) as f64
        );
    }
    Ok(())
}

/// Milliseconds of `f`, median of `repeats` runs after one warm-up run.
pub(crate) fn time_ms(
    repeats: usize,
    mut f: impl FnMut() -> Result<(), String>,
) -> Result<f64, String> {
    f()?;
    let mut times = Vec::with_capacity(repeats);
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        f()?;
        times.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    Ok(median(times))
}

/// `cargo xtask bench gbuffer`: G-buffer ms per frame at 1024x768 on the CPU (`threads`
/// workers) and the GPU (whatever adapter wgpu picks; lavapipe without a GPU), the coarse
/// downsampling passes, the quality of each downsampling mode against a G-buffer rendered
/// directly at half resolution, and the position-reconstruction micro-benchmark.
pub fn gbuffer(threads: usize, repeats: usize) -> Result<(), String> {
    use gbuffer::{CpuRasterizer, DownsampleMode, GpuDownsampler, GpuRasterizer};
    use scene_core::GBufferRenderer;
    use scene_core::gpu::GpuGBuffer;

    let (w, h) = (1024u32, 768u32);
    let (pool, gpu) = (worker_pool(threads)?, gpu_or_say_why());
    let err = |e: scene_core::Error| e.to_string();
    let gerr = |e: scene_core::gpu::GpuError| e.to_string();
    println!(
        "G-buffer at {w}x{h}; CPU on {threads} thread(s); GPU: {}; median of {repeats} after 1 warm-up",
        gpu.as_ref()
            .map_or("none".to_string(), |c| c.adapter_summary())
    );
    println!(
        "{:<22} {:>10} {:>10} {:>12} {:>12} {:>14} {:>12} {:>16} {:>12}",
        "scene",
        "triangles",
        "CPU ms",
        "CPU trait",
        "GPU ms",
        "GPU readback",
        "GPU upload",
        "GPU trait+read",
        "scene hash"
    );
    let rast = match &gpu {
        Some(ctx) => Some(GpuRasterizer::new(ctx).map_err(gerr)?),
        None => None,
    };
    let scenes = [
        "cornell".to_string(),
        "corridor".to_string(),
        format!("many-boxes {}", builtin::MAX_BOXES),
    ];
    for name in &scenes {
        let scene = builtin::scene(name).map_err(|e| e.to_string())?;
        let view = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
        // Steady state: one target reused frame after frame (like the GPU's).
        let mut target = scene_core::GBuffer::background(w, h);
        let cpu_ms = time_ms(repeats, || {
            pool.install(|| CpuRasterizer::new().render_into(&scene, &view, &mut target))
                .map_err(err)
        })?;
        // The GBufferRenderer path: a new G-buffer per call.
        let cpu_trait_ms = time_ms(repeats, || {
            pool.install(|| CpuRasterizer::new().render(&scene, &view, w, h))
                .map(|_| ())
                .map_err(err)
        })?;
        let mut cols = vec![format!("{cpu_ms:>10.2}"), format!("{cpu_trait_ms:>12.2}")];
        if let (Some(ctx), Some(rast)) = (&gpu, &rast) {
            let t0 = Instant::now();
            let prepared = rast.upload(&scene).map_err(gerr)?;
            rast.wait().map_err(gerr)?;
            let upload_ms = t0.elapsed().as_secs_f64() * 1e3;
            let target = GpuGBuffer::new(ctx, w, h).map_err(gerr)?;
            let gpu_ms = time_ms(repeats, || {
                rast.render_to(&prepared, &view, &target).map_err(err)?;
                rast.wait().map_err(gerr)
            })?;
            let read_ms = time_ms(repeats, || target.read_back(ctx).map(|_| ()).map_err(gerr))?;
            let mut trait_rast = GpuRasterizer::new(ctx).map_err(gerr)?;
            trait_rast
                .prepare(std::sync::Arc::new(scene.clone()))
                .map_err(err)?;
            let trait_ms = time_ms(repeats, || {
                trait_rast.render_view(&view, w, h).map(|_| ()).map_err(err)
            })?;
            cols.push(format!("{gpu_ms:>12.2}"));
            cols.push(format!("{read_ms:>14.2}"));
            cols.push(format!("{upload_ms:>12.1}"));
            cols.push(format!("{trait_ms:>16.2}"));
        }
        let fingerprint_ms = time_ms(repeats, || {
            pool.install(|| scene_core::hash::scene_content_hash(&scene));
            Ok(())
        })?;
        println!(
            "{:<22} {:>10} {} {:>12.2}",
            name,
            scene.triangle_count(),
            cols.join(" "),
            fingerprint_ms
        );
    }

    // Downsampling passes (corridor, camera 0).
    let scene = builtin::scene("corridor").map_err(|e| e.to_string())?;
    let view = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
    let fine = pool
        .install(|| CpuRasterizer::new().render_gbuffer(&scene, &view, w, h))
        .map_err(err)?;
    println!(
        "(CPU ms: render_into a reused target; CPU trait: GBufferRenderer::render, a new G-buffer per frame; GPU ms: the MRT pass into a reused GpuGBuffer, waited for; GPU readback: GpuGBuffer::read_back; GPU upload: scene upload, once; GPU trait+read: GBufferRenderer::render_view after prepare (the scene uploaded once), new targets and readback; scene hash: scene_core::hash::scene_content_hash, CPU)"
    );
    println!();
    println!("downsampling {w}x{h} -> {}x{} (corridor)", w / 2, h / 2);
    println!("{:<22} {:>10} {:>10}", "mode", "CPU ms", "GPU ms");
    let gpu_fine = match (&gpu, &rast) {
        (Some(ctx), Some(rast)) => {
            let prepared = rast.upload(&scene).map_err(gerr)?;
            let target = GpuGBuffer::new(ctx, w, h).map_err(gerr)?;
            rast.render_to(&prepared, &view, &target).map_err(err)?;
            rast.wait().map_err(gerr)?;
            Some((GpuDownsampler::new(ctx).map_err(gerr)?, target, ctx, rast))
        }
        _ => None,
    };
    for mode in DownsampleMode::ALL {
        let cpu_ms = time_ms(repeats, || {
            pool.install(|| gbuffer::downsample(&fine, mode));
            Ok(())
        })?;
        let gpu_ms = match &gpu_fine {
            Some((down, target, ctx, rast)) => {
                let (cw, ch) = gbuffer::coarse_size(w, h);
                let coarse = GpuGBuffer::new(ctx, cw, ch).map_err(gerr)?;
                let ms = time_ms(repeats, || {
                    let mut enc = ctx.device.create_command_encoder(&Default::default());
                    down.encode(&mut enc, target, &coarse, mode).map_err(gerr)?;
                    ctx.queue.submit([enc.finish()]);
                    rast.wait().map_err(gerr)
                })?;
                format!("{ms:>10.2}")
            }
            None => format!("{:>10}", "-"),
        };
        println!("{:<22} {cpu_ms:>10.2} {gpu_ms}", mode.name());
    }

    downsampling_quality(&pool, w, h)?;
    reconstruction(&pool, gpu.as_ref(), rast.as_ref(), w, h, repeats)
}

/// Each downsampling mode against G-buffers rendered directly at half resolution, summed
/// over the built-in scenes' cameras.
fn downsampling_quality(pool: &rayon::ThreadPool, w: u32, h: u32) -> Result<(), String> {
    use gbuffer::{CpuRasterizer, DownsampleMode, DownsampleStats};
    let (cw, ch) = gbuffer::coarse_size(w, h);
    println!();
    println!(
        "downsampling quality: coarse {cw}x{ch} from {w}x{h} against a direct {cw}x{ch} render, every camera"
    );
    println!(
        "{:<22} {:<18} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "scene",
        "mode",
        "inv.depth",
        "inv.norm",
        "bg diff",
        "depth>5%",
        "id diff",
        "normal°",
        "albedo"
    );
    let scenes = [
        "cornell".to_string(),
        "primitives".to_string(),
        "corridor".to_string(),
        "many-boxes 1000".to_string(),
        format!("many-boxes {}", builtin::MAX_BOXES),
    ];
    let pct = |n: usize, d: usize| 100.0 * n as f64 / d.max(1) as f64;
    let mut totals = vec![(DownsampleStats::default(), 0.0f64, 0.0f64); DownsampleMode::ALL.len()];
    for name in &scenes {
        let scene = builtin::scene(name).map_err(|e| e.to_string())?;
        let mut per_scene =
            vec![(DownsampleStats::default(), 0.0f64, 0.0f64); DownsampleMode::ALL.len()];
        for cam in &scene.cameras {
            let view = View::from_camera(&cam.with_aspect(w as f32 / h as f32));
            let (fine, direct) = pool.install(|| {
                (
                    CpuRasterizer::new().render_gbuffer(&scene, &view, w, h),
                    CpuRasterizer::new().render_gbuffer(&scene, &view, cw, ch),
                )
            });
            let (fine, direct) = (
                fine.map_err(|e| e.to_string())?,
                direct.map_err(|e| e.to_string())?,
            );
            for (k, mode) in DownsampleMode::ALL.into_iter().enumerate() {
                let coarse = pool.install(|| gbuffer::downsample(&fine, mode));
                let s = gbuffer::compare_with_direct(&coarse, &direct, &fine);
                for acc in [&mut per_scene[k], &mut totals[k]] {
                    acc.0.pixels += s.pixels;
                    acc.0.invented_depth += s.invented_depth;
                    acc.0.invented_normal += s.invented_normal;
                    acc.0.background_mismatch += s.background_mismatch;
                    acc.0.depth_mismatch += s.depth_mismatch;
                    acc.0.id_mismatch += s.id_mismatch;
                    acc.0.geometry_pixels += s.geometry_pixels;
                    acc.1 += s.mean_normal_error_deg * s.geometry_pixels as f64;
                    acc.2 += s.mean_albedo_error * s.geometry_pixels as f64;
                }
            }
        }
        let print = |label: &str, rows: &[(DownsampleStats, f64, f64)]| {
            for (k, mode) in DownsampleMode::ALL.into_iter().enumerate() {
                let (s, nsum, asum) = &rows[k];
                let g = s.geometry_pixels.max(1) as f64;
                println!(
                    "{:<22} {:<18} {:>8.3}% {:>8.3}% {:>8.3}% {:>8.3}% {:>8.3}% {:>9.3} {:>9.4}",
                    if k == 0 { label } else { "" },
                    mode.name(),
                    pct(s.invented_depth, s.pixels),
                    pct(s.invented_normal, s.pixels),
                    pct(s.background_mismatch, s.pixels),
                    pct(s.depth_mismatch, s.pixels),
                    pct(s.id_mismatch, s.pixels),
                    nsum / g,
                    asum / g
                );
            }
        };
        print(name, &per_scene);
        if name == scenes.last().unwrap_or(name) {
            print("all", &totals);
        }
    }
    println!(
        "(inv.depth: coarse depth > 5 % from every sample of its block; inv.norm: coarse normal > 30 deg from every geometry sample; the other columns compare with the direct render)"
    );
    Ok(())
}

/// Position reconstruction micro-benchmark: frustum corners (eq. 24) against inverse
/// matrices, CPU and GPU, 1 and 24 taps per pixel, with the error of each method.
fn reconstruction(
    pool: &rayon::ThreadPool,
    gpu: Option<&scene_core::gpu::GpuContext>,
    rast: Option<&gbuffer::GpuRasterizer>,
    w: u32,
    h: u32,
    repeats: usize,
) -> Result<(), String> {
    use gbuffer::{
        CpuRasterizer, GpuReconstructor, InverseMatrixReconstruction, ReconstructionMethod,
    };
    use scene_core::gpu::GpuGBuffer;
    let scene = builtin::scene("corridor").map_err(|e| e.to_string())?;
    let view = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
    let g = pool
        .install(|| CpuRasterizer::new().render_gbuffer(&scene, &view, w, h))
        .map_err(|e| e.to_string())?;
    let inv = InverseMatrixReconstruction::new(&view);
    let gpu_target = match (gpu, rast) {
        (Some(ctx), Some(rast)) => {
            let prepared = rast.upload(&scene).map_err(|e| e.to_string())?;
            let target = GpuGBuffer::new(ctx, w, h).map_err(|e| e.to_string())?;
            rast.render_to(&prepared, &view, &target)
                .map_err(|e| e.to_string())?;
            rast.wait().map_err(|e| e.to_string())?;
            Some((ctx, rast, target))
        }
        _ => None,
    };
    // Hardware depth: the GPU's depth attachment when there is one, else computed.
    let hw: Vec<f32> = match &gpu_target {
        Some((ctx, _, target)) => ctx
            .read_texture_r32f(target.depth_attachment().map_err(|e| e.to_string())?)
            .map_err(|e| e.to_string())?,
        None => g.depth.iter().map(|&d| inv.ndc_depth(d)).collect(),
    };
    println!();
    println!(
        "position reconstruction at {w}x{h} (corridor), ms per pass; taps = positions per pixel"
    );
    println!(
        "{:<30} {:>10} {:>10} {:>10} {:>10} {:>14} {:>14}",
        "method", "CPU 1", "CPU 24", "GPU 1", "GPU 24", "max err/range", "mean err/range"
    );
    // Reference: eq. 24 evaluated in f64 from the stored linear depth.
    let c = view
        .frustum_corners()
        .ok_or("corridor camera is not perspective")?;
    let range = (view.far - view.near) as f64;
    let reference = |i: usize| {
        let (x, y) = ((i as u32 % w) as f64, (i as u32 / w) as f64);
        let (u, v) = ((x + 0.5) / w as f64, (y + 0.5) / h as f64);
        let d = g.depth[i] as f64;
        let (o, du, dv, e) = (
            c.origin.as_dvec3(),
            c.du.as_dvec3(),
            c.dv.as_dvec3(),
            view.eye.as_dvec3(),
        );
        e + (o + du * u + dv * v) * d
    };
    let recon = match gpu {
        Some(ctx) => Some(GpuReconstructor::new(ctx).map_err(|e| e.to_string())?),
        None => None,
    };
    // ms per method: [CPU 1 tap, CPU 24 taps, GPU 1 tap, GPU 24 taps].
    let mut times = [[f64::NAN; 4]; 3];
    for (m, method) in ReconstructionMethod::ALL.into_iter().enumerate() {
        let input = match method {
            ReconstructionMethod::InverseMatrixHardwareDepth => &hw,
            _ => &g.depth,
        };
        let mut cols = Vec::new();
        let mut out = vec![scene_core::glam::Vec3::ZERO; (w * h) as usize];
        for (k, taps) in [1u32, 24].into_iter().enumerate() {
            let ms = time_ms(repeats, || {
                pool.install(|| {
                    gbuffer::reconstruct_into(&view, method, input, w, h, taps, &mut out)
                });
                Ok(())
            })?;
            times[m][k] = ms;
            cols.push(format!("{ms:>10.2}"));
        }
        for (k, taps) in [1u32, 24].into_iter().enumerate() {
            match (&gpu_target, &recon) {
                (Some((ctx, rast, target)), Some(recon)) => {
                    let out = recon.output_texture(w, h).map_err(|e| e.to_string())?;
                    let ms = time_ms(repeats, || {
                        let mut enc = ctx.device.create_command_encoder(&Default::default());
                        recon
                            .encode(&mut enc, &view, target, method, taps, &out)
                            .map_err(|e| e.to_string())?;
                        ctx.queue.submit([enc.finish()]);
                        rast.wait().map_err(|e| e.to_string())
                    })?;
                    times[m][2 + k] = ms;
                    cols.push(format!("{ms:>10.2}"));
                }
                _ => cols.push(format!("{:>10}", "-")),
            }
        }
        let pos = gbuffer::reconstruct_buffer(&view, method, input, w, h, 1);
        let (mut max, mut sum, mut n) = (0.0f64, 0.0f64, 0usize);
        for (i, p) in pos.iter().enumerate() {
            if g.is_background(i) {
                continue;
            }
            let e = (p.as_dvec3() - reference(i)).length() / range;
            max = max.max(e);
            sum += e;
            n += 1;
        }
        println!(
            "{:<30} {} {:>14.2e} {:>14.2e}",
            method.name(),
            cols.join(" "),
            max,
            sum / n.max(1) as f64
        );
    }
    println!(
        "(errors against eq. 24 in f64 from the same stored depth; the z-buffer row reads the GPU's depth attachment{})",
        if gpu_target.is_some() {
            ""
        } else {
            " (computed: no GPU)"
        }
    );
    for (m, method) in ReconstructionMethod::ALL.into_iter().enumerate().skip(1) {
        let r: Vec<String> = (0..4)
            .map(|k| format!("{:.2}", times[m][k] / times[0][k]))
            .collect();
        println!(
            "time ratio {} / frustum corners: CPU 1 tap {}, 24 taps {}; GPU 1 tap {}, 24 taps {}",
            method.name(),
            r[0],
            r[1],
            r[2],
            r[3]
        );
    }
    Ok(())
}
