//! The GPU path tracer beside the CPU one on a built-in scene: paths per second of each on
//! this machine, and how far their images are apart.
//!
//! `cargo run --release -p scene-core --example gpu_reference -- [scene] [size] [spp] [bounces]`
//! (defaults: cornell 256 64 inf). The CPU tracer uses every core (rayon).

use scene_core::reference::{Bounces, ReferenceSettings, render_gpu, render_lit};
use scene_core::{LightState, View, builtin, gpu::GpuContext};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map_or("cornell", String::as_str);
    let size: u32 = args.get(1).map_or(Ok(256), |s| s.parse())?;
    let spp: u32 = args.get(2).map_or(Ok(64), |s| s.parse())?;
    let bounces: Bounces = args.get(3).map_or(Ok(Bounces::Unlimited), |s| s.parse())?;
    if !(1..=8192).contains(&size) || !(1..=1 << 16).contains(&spp) {
        return Err(format!("size must be 1..=8192 and spp 1..=65536 (got {size}, {spp})").into());
    }
    let scene = builtin::scene(name)?;
    let view = View::from_camera(&scene.cameras[0].with_aspect(1.0));
    let settings = ReferenceSettings {
        width: size,
        height: size,
        spp,
        bounces,
        seed: 1,
    };
    let lights = LightState::default();
    let ctx = GpuContext::new()?;
    let paths = f64::from(size) * f64::from(size) * f64::from(spp);
    // A first small render warms the pipeline cache and the driver.
    let warm = ReferenceSettings {
        width: 8,
        height: 8,
        spp: 1,
        ..settings
    };
    render_gpu(&ctx, &scene, &view, &warm, &lights, None)?;
    let gpu = render_gpu(&ctx, &scene, &view, &settings, &lights, None)?;
    let cpu = render_lit(&scene, &view, &settings, &lights, None);
    let mean = |p: &[scene_core::glam::Vec3]| {
        p.iter().map(|c| f64::from(c.x + c.y + c.z)).sum::<f64>() / p.len() as f64
    };
    let (mc, mg) = (mean(&cpu.image.pixels), mean(&gpu.image.pixels));
    println!(
        "{name} {size}x{size} {spp} spp bounces {bounces}: GPU ({}) {:.3} s, {:.3e} paths/s \
         (upload and pipeline {:.3} s); CPU ({} threads) {:.3} s, {:.3e} paths/s; image means \
         CPU {mc:.5} GPU {mg:.5} ({:+.3} %)",
        ctx.adapter_summary(),
        gpu.seconds,
        gpu.samples_per_second(),
        gpu.prepare_seconds,
        rayon::current_num_threads(),
        cpu.stats.seconds,
        paths / cpu.stats.seconds,
        (mg / mc - 1.0) * 100.0
    );
    Ok(())
}
