//! `cargo xtask bench ibrr`: the IBRR paper's Table 1, measured here.
//!
//! - LDC 128, 256 and 512 with 184 IRPLs on seeded box fields of about 15k and 97k
//!   triangles (the paper's scenes A and B): construction time (one run), reconstruction
//!   frames per second at 512 x 512 (median of the repeats after a warm-up), memory.
//!   Construction renders its hemicubes with the CPU rasteriser and, in the GPU rows, the
//!   GPU rasteriser; frames are the CPU lookup (the given threads) over a CPU G-buffer, and
//!   the GPU lookup over a GPU G-buffer; the lookup alone is its own column (the frame
//!   adds the camera's G-buffer, which does depend on the triangles).
//! - 200, 371, 589 and 751 IRPLs at LDC 256 on a field of about 26k triangles (scene C):
//!   memory and layers (CPU construction).

use std::sync::Arc;
use std::time::Instant;

use ibrr_ldc::{IbrrSettings, IbrrTechnique};
use scene_core::{FrameRequest, Scene, Technique, builtin};

use crate::bench::{gpu_or_say_why, median, worker_pool};

/// A box field of about `triangles` triangles (`many_boxes`: 12 n + 2).
fn field(triangles: u32) -> Scene {
    builtin::many_boxes((triangles.saturating_sub(2)) / 12, 7)
}

struct Row {
    build_s: f64,
    fps: f64,
    lookup_ms: f64,
    bytes: u64,
    layers: usize,
    irpls: usize,
    missing: u64,
}

fn measure(
    scene: &Arc<Scene>,
    settings: IbrrSettings,
    gpu: Option<&scene_core::gpu::GpuContext>,
    repeats: usize,
) -> Result<Row, String> {
    let mut t = match gpu {
        Some(ctx) => IbrrTechnique::new(
            settings,
            Box::new(gbuffer::GpuRasterizer::new(ctx).map_err(|e| e.to_string())?),
        )
        .on_gpu(ctx.clone()),
        None => IbrrTechnique::new(settings, Box::new(gbuffer::CpuRasterizer::new())),
    };
    let t0 = Instant::now();
    t.prepare(scene.clone()).map_err(|e| e.to_string())?;
    let build_s = t0.elapsed().as_secs_f64();
    let frame = FrameRequest::camera(&scene.cameras[0], 512, 512);
    t.render(&frame).map_err(|e| e.to_string())?;
    let (mut times, mut lookups) = (Vec::new(), Vec::new());
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        t.render(&frame).map_err(|e| e.to_string())?;
        times.push(t0.elapsed().as_secs_f64());
        lookups.push(t.last_timings().lookup.as_secs_f64() * 1e3);
    }
    let ldc = t.ldc().expect("prepared");
    Ok(Row {
        build_s,
        fps: 1.0 / median(times),
        lookup_ms: median(lookups),
        bytes: ldc.bytes(),
        layers: ldc.layer_count(),
        irpls: t.construction().map_or(0, |c| c.irpls.irpls.len()),
        missing: t.last_timings().missing,
    })
}

/// Runs the benchmark.
pub fn run(threads: usize, repeats: usize) -> Result<(), String> {
    let pool = worker_pool(threads)?;
    let gpu = gpu_or_say_why();
    if let Some(ctx) = &gpu {
        println!("GPU: {}", ctx.adapter_summary());
    }
    println!(
        "Table 1 (A, B): 184 IRPLs, frames at 512x512; CPU with {threads} threads; construction one run, frames median of {repeats}"
    );
    println!(
        "{:<6} {:>9} {:>5} {:>4} {:>6} {:>11} {:>9} {:>9} {:>10} {:>9} {:>8}",
        "scene",
        "triangles",
        "LDC",
        "on",
        "IRPLs",
        "construct s",
        "frame fps",
        "lookup ms",
        "memory KB",
        "layers",
        "no layer"
    );
    for (label, tris) in [("A", 15_000u32), ("B", 97_000)] {
        let scene = Arc::new(field(tris));
        for res in [128u32, 256, 512] {
            let settings = IbrrSettings {
                target_error: 0.0,
                resolution: res,
                irpls: 184,
                ..Default::default()
            };
            let mut rows = vec![(
                "cpu",
                pool.install(|| measure(&scene, settings, None, repeats))?,
            )];
            if let Some(ctx) = &gpu {
                rows.push((
                    "gpu",
                    pool.install(|| measure(&scene, settings, Some(ctx), repeats))?,
                ));
            }
            for (on, r) in rows {
                println!(
                    "{label:<6} {:>9} {res:>5} {on:>4} {:>6} {:>11.2} {:>9.2} {:>9.2} {:>10.0} {:>9} {:>8}",
                    scene.triangle_count(),
                    r.irpls,
                    r.build_s,
                    r.fps,
                    r.lookup_ms,
                    r.bytes as f64 / 1024.0,
                    r.layers,
                    r.missing
                );
            }
        }
    }
    println!("Table 1 (C): LDC 256, memory against the IRPL count (CPU construction)");
    println!(
        "{:<6} {:>9} {:>6} {:>11} {:>10} {:>9}",
        "scene", "triangles", "IRPLs", "construct s", "memory KB", "layers"
    );
    let scene = Arc::new(field(26_000));
    for irpls in [200u32, 371, 589, 751] {
        let settings = IbrrSettings {
            target_error: 0.0,
            resolution: 256,
            irpls,
            ..Default::default()
        };
        let r = pool.install(|| measure(&scene, settings, None, 1))?;
        println!(
            "{:<6} {:>9} {:>6} {:>11.2} {:>10.0} {:>9}",
            "C",
            scene.triangle_count(),
            r.irpls,
            r.build_s,
            r.bytes as f64 / 1024.0,
            r.layers
        );
    }
    Ok(())
}
