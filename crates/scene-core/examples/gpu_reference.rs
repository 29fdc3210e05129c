//! The GPU path tracer beside the CPU one on a scene: paths per second of each on this
//! machine, and how far their images are apart (the image means, and a z-test of every 8x8
//! block's mean per channel with the two variance images, at alpha 0.001).
//!
//! `cargo run --release -p scene-core --example gpu_reference -- [scene] [size] [spp] [bounces] [daylight|sun|sky]`
//! (defaults: cornell 256 64 inf). `scene` is a built-in name or a glTF file; `daylight` adds
//! the sun and the uniform sky that docs/results-interior.md lights the Breakfast Room with
//! (`sun` or `sky` one of them alone).
//! The CPU tracer uses every core (rayon).

use scene_core::glam::Vec3;
use scene_core::reference::{Bounces, ReferenceSettings, block_z_tests, render_gpu, render_lit};
use scene_core::{AddedLights, DirectionalLight, LightState, View, gpu::GpuContext, sky::Sky};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map_or("cornell", String::as_str);
    let size: u32 = args.get(1).map_or(Ok(256), |s| s.parse())?;
    let spp: u32 = args.get(2).map_or(Ok(64), |s| s.parse())?;
    let bounces: Bounces = args.get(3).map_or(Ok(Bounces::Unlimited), |s| s.parse())?;
    if !(8..=8192).contains(&size) || !(2..=1 << 16).contains(&spp) {
        return Err(format!("size must be 8..=8192 and spp 2..=65536 (got {size}, {spp})").into());
    }
    let mut added = AddedLights::default();
    let light = args.get(4).map_or("", String::as_str);
    if light == "daylight" || light == "sun" {
        added.suns.push(DirectionalLight {
            name: "sun".into(),
            direction: Vec3::new(-1.0, -0.8, 0.35),
            irradiance: Vec3::new(12.0, 11.0, 9.5),
        });
    }
    if light == "daylight" || light == "sky" {
        added.sky = Some(Sky::uniform(Vec3::new(0.5, 0.6, 0.8))?);
    }
    let scene = scene_core::open_scene_with(name, &added)?.scene;
    let camera = scene.cameras.first().ok_or("the scene has no camera")?;
    let view = View::from_camera(&camera.with_aspect(1.0));
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
    let mean =
        |p: &[Vec3]| p.iter().map(|c| f64::from(c.element_sum())).sum::<f64>() / p.len() as f64;
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
    // Block z-tests.
    let blocks = block_z_tests(
        (&cpu.image, &cpu.variance),
        (&gpu.image, &gpu.variance),
        spp,
        8,
    );
    let tests = blocks.len();
    let rejected = blocks.iter().filter(|t| t.z().abs() > 3.29).count();
    let resolved = blocks.iter().filter(|t| 3.0 * t.se < 0.03 * t.a).count();
    for t in blocks.iter().filter(|t| t.z().abs() > 3.29) {
        println!(
            "  block {:?} channel {}: CPU {:.5}, GPU {:.5} ({:+.2} %, z {:.1})",
            t.block,
            t.channel,
            t.a,
            t.b,
            (t.b / t.a - 1.0) * 100.0,
            t.z()
        );
    }
    println!(
        "block z-tests (8x8, per channel, alpha 0.001): {rejected} of {tests} rejected \
         ({:.2} expected by chance); {resolved} resolve 3 %",
        tests as f64 * 0.001
    );
    Ok(())
}
