//! `cargo xtask bench reference`: rays per second of the reference path tracer.
//! Figures are printed (median of repeats after a warm-up); nothing is asserted.

use std::time::Instant;

use scene_core::View;
use scene_core::builtin;
use scene_core::reference::{Accumulator, Bounces, PathTracer};

fn median(mut v: Vec<f64>) -> f64 {
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

/// Benchmarks the reference path tracer on `cornell` and `many-boxes` at about 10^6
/// triangles with `threads` workers.
pub fn reference(threads: usize, repeats: usize) -> Result<(), String> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| e.to_string())?;
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
