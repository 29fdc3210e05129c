//! `cargo xtask bench relight`: the radiosity relighting paper's two tables, measured here.
//!
//! - Table 1: solve time of 100 shots on the corridor with 1, 3 and 8 point lights:
//!   standard progressive refinement on the combined emission, k separate solves, and the
//!   light-tagged solve; hemicube 128 (the CPU rasteriser) and ray-cast form factors. One
//!   run of each (a solve is seconds long); the ratios come from the same run.
//! - Table 2: relight frame time (eq. 1 over every element) for 960, 10^4, 10^5 and 10^6
//!   elements x 1, 3, 8 sources, CPU (the given threads, f32 and f16) and GPU (whatever
//!   adapter wgpu picks), with the bytes streamed per second beside the machine's measured
//!   memory bandwidth (a parallel sum over 512 MiB). Synthetic solutions of the right
//!   shape: the time of eq. 1 does not depend on the values.
//! - The solve time to 1e-3 unshot for about 10^4 elements (ray-cast form factors).
//! - Dynamic scenes (section 2.4, `cargo xtask bench relight-dynamic` alone): the patch
//!   transfer's solve time and memory, and the frame time of moving point lights (direct
//!   shot plus blend) and of a dynamic object's shadows, beside a full re-solve with the
//!   light at its new place; cornell-point without its own light, two element counts.

use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;
use relight_pr::packed::{Packed, Precision};
use relight_pr::{FormFactorMethod, MeshSettings, Meshing, SolverSettings, Strategy};
use scene_core::ray::RayScene;
use scene_core::{PointLight, Scene, builtin};

use crate::bench::{gpu_or_say_why, median, time_ms, worker_pool};

/// The corridor with `k` point lights (its own four, then copies moved along the corridor).
fn corridor_with(k: usize) -> Result<Scene, String> {
    let mut scene = builtin::scene("corridor").map_err(|e| e.to_string())?;
    let own = scene.point_lights.clone();
    let extent = scene.extent();
    scene.point_lights = (0..k)
        .map(|i| {
            let base = &own[i % own.len()];
            PointLight {
                name: format!("{} #{i}", base.name),
                position: base.position
                    + Vec3::new(0.0, 0.0, 0.05 * extent * (i / own.len()) as f32),
                ..base.clone()
            }
        })
        .collect();
    Ok(scene)
}

fn table1(pool: &rayon::ThreadPool) -> Result<(), String> {
    println!("Table 1: 100 shots on the corridor (seconds; one run each)");
    println!(
        "{:<14} {:>3} {:>9} {:>10} {:>10} {:>9} {:>16}",
        "form factors", "k", "elements", "combined", "separate", "tagged", "separate/tagged"
    );
    for method in [
        FormFactorMethod::Hemicube { resolution: 128 },
        FormFactorMethod::Rays,
    ] {
        for k in [1usize, 3, 8] {
            let scene = corridor_with(k)?;
            // Uniform meshing, as in the paper's Table 1.
            let uniform = MeshSettings {
                split_depth: 0,
                ..MeshSettings::elements(1024)
            };
            let rays = RayScene::build(&scene);
            let meshing =
                Meshing::with_rays(&scene, &uniform, k, &rays).map_err(|e| e.to_string())?;
            let mut times = Vec::new();
            for strategy in [Strategy::Combined, Strategy::Separate, Strategy::Tagged] {
                let settings = SolverSettings {
                    form_factors: method,
                    max_unshot: 0.0,
                    max_shots: 100,
                    strategy,
                    ..Default::default()
                };
                let mut renderer = gbuffer::CpuRasterizer::new();
                let t0 = Instant::now();
                pool.install(|| {
                    relight_pr::solve_with(
                        &scene,
                        &meshing,
                        &rays,
                        Some(&mut renderer),
                        &settings,
                        &mut |_| {},
                    )
                })
                .map_err(|e| e.to_string())?;
                times.push(t0.elapsed().as_secs_f64());
            }
            let name = match method {
                FormFactorMethod::Rays => "rays 16".to_string(),
                FormFactorMethod::Hemicube { resolution } => format!("hemicube {resolution}"),
            };
            println!(
                "{name:<14} {k:>3} {:>9} {:>10.2} {:>10.2} {:>9.2} {:>15.2}x",
                meshing.elements.len(),
                times[0],
                times[1],
                times[2],
                times[1] / times[2]
            );
        }
    }
    Ok(())
}

/// Memory bandwidth: a parallel wrapping sum over 512 MiB of u32 (vectorised, so the
/// memory and not the adder is the limit), median of `repeats`, in bytes/s.
fn bandwidth(pool: &rayon::ThreadPool, repeats: usize) -> Result<f64, String> {
    use rayon::prelude::*;
    let data = vec![1u32; 128 << 20];
    let mut sink = 0u32;
    let ms = time_ms(repeats, || {
        sink = sink.wrapping_add(pool.install(|| {
            data.par_chunks(1 << 16)
                .map(|c| c.iter().fold(0u32, |a, &b| a.wrapping_add(b)))
                .reduce(|| 0, u32::wrapping_add)
        }));
        Ok(())
    })?;
    std::hint::black_box(sink);
    Ok((data.len() * 4) as f64 / (ms * 1e-3))
}

fn table2(pool: &rayon::ThreadPool, threads: usize, repeats: usize) -> Result<(), String> {
    let bw = bandwidth(pool, repeats)?;
    println!(
        "\nTable 2: relight frame (eq. 1 over every element), ms; CPU {threads} threads; memory bandwidth measured {:.1} GB/s",
        bw / 1e9
    );
    let gpu = gpu_or_say_why();
    if let Some(ctx) = &gpu {
        println!("GPU: {}", ctx.adapter_summary());
    }
    println!(
        "{:>9} {:>3} {:>10} {:>9} {:>8} {:>9} {:>8} {:>9} {:>9}",
        "elements", "k", "f32 bytes", "CPU f32", "GB/s", "CPU f16", "GB/s", "GPU f32", "GPU f16"
    );
    for n in [960usize, 10_000, 100_000, 1_000_000] {
        for k in [1usize, 3, 8] {
            // Synthetic values of the solution's shape (a fixed pattern; values do not
            // change the time).
            let values: Vec<Vec3> = (0..n * k)
                .map(|i| Vec3::new((i % 7) as f32, (i % 5) as f32, (i % 3) as f32) * 0.1)
                .collect();
            let factors: Vec<(Vec3, Vec3)> = (0..k)
                .map(|m| (Vec3::splat(1.0 + m as f32), Vec3::ONE))
                .collect();
            let mut row = format!("{n:>9} {k:>3}");
            let cpu = |precision| -> Result<(u64, f64), String> {
                let packed = Packed::new(&values, &values, k, precision);
                let mut out = vec![Vec3::ZERO; n];
                let ms = time_ms(repeats, || {
                    pool.install(|| packed.relight_into(&factors, Vec3::ZERO, &mut out));
                    Ok(())
                })?;
                Ok((packed.bytes(), ms))
            };
            let (b32, ms32) = cpu(Precision::F32)?;
            let (b16, ms16) = cpu(Precision::F16)?;
            row += &format!(
                " {b32:>10} {ms32:>9.3} {:>8.1} {ms16:>9.3} {:>8.1}",
                b32 as f64 / (ms32 * 1e-3) / 1e9,
                b16 as f64 / (ms16 * 1e-3) / 1e9
            );
            for precision in [Precision::F32, Precision::F16] {
                let cell = match &gpu {
                    None => "-".to_string(),
                    Some(ctx) => {
                        let packed = Packed::new(&values, &values, k, precision);
                        match relight_pr::gpu::GpuRelight::relight_only(ctx, &packed) {
                            Err(e) => {
                                eprintln!("GPU {n} x {k} {precision:?}: {e}");
                                "budget".to_string()
                            }
                            Ok(g) => {
                                g.time_relight(&factors).map_err(|e| e.to_string())?;
                                let mut t = Vec::new();
                                for _ in 0..repeats.max(1) {
                                    t.push(
                                        g.time_relight(&factors)
                                            .map_err(|e| e.to_string())?
                                            .as_secs_f64()
                                            * 1e3,
                                    );
                                }
                                format!("{:.3}", median(t))
                            }
                        }
                    }
                };
                row += &format!(" {cell:>9}");
            }
            println!("{row}");
        }
    }
    Ok(())
}

fn solve_1e4(pool: &rayon::ThreadPool) -> Result<(), String> {
    let scene = Arc::new(builtin::scene("corridor").map_err(|e| e.to_string())?);
    let k = scene_core::lights::light_ids(&scene).len();
    let uniform = MeshSettings {
        split_depth: 0,
        ..MeshSettings::elements(10_000)
    };
    let rays = RayScene::build(&scene);
    let meshing = Meshing::with_rays(&scene, &uniform, k, &rays).map_err(|e| e.to_string())?;
    let settings = SolverSettings::default();
    let t0 = Instant::now();
    let solution = pool
        .install(|| relight_pr::solve(&scene, &meshing, &rays, &settings, &mut |_| {}))
        .map_err(|e| e.to_string())?;
    println!(
        "\nSolve to 1e-3 unshot: corridor, {} elements, {} sources, rays 16: {:.1} s ({} shots, unshot {:.1e})",
        meshing.elements.len(),
        k,
        t0.elapsed().as_secs_f64(),
        solution.stats.shots,
        solution.stats.unshot_fraction
    );
    Ok(())
}

/// Table 2 alone (`cargo xtask bench relight-frames`): seconds instead of minutes.
pub fn frames(threads: usize, repeats: usize) -> Result<(), String> {
    table2(&worker_pool(threads)?, threads, repeats)
}

fn dynamic(pool: &rayon::ThreadPool, repeats: usize) -> Result<(), String> {
    use relight_pr::dynamic::{DynamicScene, Transfer};
    println!("\nDynamic scenes (section 2.4): cornell-point, its light moving");
    println!(
        "{:>8} {:>7} {:>10} {:>7} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "elements",
        "patches",
        "transfer s",
        "shots",
        "memory MB",
        "1 light ms",
        "4 lights ms",
        "object ms",
        "re-solve ms"
    );
    let lit = builtin::scene("cornell-point").map_err(|e| e.to_string())?;
    let mut dark = lit.clone();
    let light = dark.point_lights.remove(0);
    let settings = SolverSettings::default();
    let rays = RayScene::build(&dark);
    for target in [256usize, 1024] {
        let meshing = Meshing::with_rays(&dark, &MeshSettings::elements(target), 1, &rays)
            .map_err(|e| e.to_string())?;
        let t0 = Instant::now();
        let transfer = pool
            .install(|| Transfer::solve(&dark, &meshing, &rays, &settings, 16 << 30, &mut |_| {}))
            .map_err(|e| e.to_string())?;
        let transfer_s = t0.elapsed().as_secs_f64();
        let (shots, bytes) = (transfer.stats.shots, transfer.bytes());
        let empty = relight_pr::solve(&dark, &meshing, &rays, &settings, &mut |_| {})
            .map_err(|e| e.to_string())?;
        let mut scene = DynamicScene::with_transfer(transfer);
        let state = scene_core::LightState::default();
        let extent = lit.extent();
        let frame_ms = |scene: &DynamicScene| -> Result<f64, String> {
            let mut t = Vec::new();
            for _ in 0..=repeats {
                let t0 = Instant::now();
                pool.install(|| scene.frame(&dark, &meshing, &empty, &rays, &state))
                    .map_err(|e| e.to_string())?;
                t.push(t0.elapsed().as_secs_f64() * 1e3);
            }
            t.remove(0);
            Ok(median(t))
        };
        scene.moving = vec![light.clone()];
        let one = frame_ms(&scene)?;
        scene.moving = (0..4)
            .map(|i| PointLight {
                position: light.position + Vec3::new(0.05 * i as f32, -0.05, 0.0) * extent,
                ..light.clone()
            })
            .collect();
        let four = frame_ms(&scene)?;
        let b = lit.bounds();
        let c = (b.min + b.max) * 0.5;
        let h = 0.08 * extent;
        let q = |x: f32, z: f32| c + Vec3::new(x * h, 0.0, z * h);
        scene.set_objects(&[
            [q(-1.0, -1.0), q(1.0, -1.0), q(1.0, 1.0)],
            [q(-1.0, -1.0), q(1.0, 1.0), q(-1.0, 1.0)],
        ]);
        scene.moving = vec![light.clone()];
        let object = frame_ms(&scene)?;
        let t0 = Instant::now();
        let combined = SolverSettings {
            strategy: Strategy::Combined,
            ..settings.clone()
        };
        pool.install(|| relight_pr::solve(&lit, &meshing, &rays, &combined, &mut |_| {}))
            .map_err(|e| e.to_string())?;
        let resolve = t0.elapsed().as_secs_f64() * 1e3;
        println!(
            "{:>8} {:>7} {:>10.2} {:>7} {:>10.2} {:>10.3} {:>10.3} {:>10.3} {:>10.1}",
            meshing.elements.len(),
            meshing.patches.len(),
            transfer_s,
            shots,
            bytes as f64 / 1e6,
            one,
            four,
            object,
            resolve
        );
    }
    Ok(())
}

/// The dynamic-scene rows alone (`cargo xtask bench relight-dynamic`).
pub fn dynamic_only(threads: usize, repeats: usize) -> Result<(), String> {
    dynamic(&worker_pool(threads)?, repeats)
}

/// Runs the benchmark.
pub fn run(threads: usize, repeats: usize) -> Result<(), String> {
    let pool = worker_pool(threads)?;
    table1(&pool)?;
    table2(&pool, threads, repeats)?;
    dynamic(&pool, repeats)?;
    solve_1e4(&pool)
}

/// `cargo xtask bench relight-direct`: what a new view's direct light costs at 256 x 192 on
/// the built-in scenes (camera 0, 1024-element solve): the per-pixel ray gather
/// (`DirectLight::PerPixel`, 8 footprint points, 4 emitter rays) and the shadow-mapped
/// lights (`DirectLight::ShadowMaps`, 3 x 3 footprint points) on the CPU (the given
/// threads), and on the GPU (whatever adapter wgpu picks) the display with the gathered
/// values uploaded against the display with the shadow-map pass in its encoder, each with
/// its readback; the shadow maps' one-time build beside. Medians of `repeats` after a
/// warm-up.
pub fn direct(threads: usize, repeats: usize) -> Result<(), String> {
    use relight_pr::direct::DirectGather;
    use relight_pr::display::{Welding, light_slots, pixel_direct, pixel_direct_shadowed};
    use scene_core::GBufferRenderer;
    use scene_core::gbuffer::RayCastRenderer;
    use scene_core::shadowed_lights::{LightSet, ShadowSettings};

    let pool = worker_pool(threads)?;
    let gpu = gpu_or_say_why();
    let (w, h) = (256u32, 192u32);
    println!(
        "\nRelighting's direct light for a new view, {w} x {h}, ms (CPU {threads} threads{})",
        gpu.as_ref()
            .map_or(String::new(), |c| format!("; GPU {}", c.adapter_summary()))
    );
    println!(
        "{:>14} {:>11} {:>11} {:>11} {:>13} {:>13}",
        "scene", "maps build", "CPU gather", "CPU maps", "GPU gathered", "GPU maps"
    );
    for name in ["cornell", "cornell-point", "corridor"] {
        let scene = Arc::new(builtin::scene(name).map_err(|e| e.to_string())?);
        let k = scene_core::lights::light_ids(&scene).len();
        let meshing =
            Meshing::new(&scene, &MeshSettings::elements(1024), k).map_err(|e| e.to_string())?;
        let rays = RayScene::build(&scene);
        let settings = SolverSettings {
            max_unshot: 1e-3,
            ..Default::default()
        };
        let solution = pool
            .install(|| relight_pr::solve(&scene, &meshing, &rays, &settings, &mut |_| {}))
            .map_err(|e| e.to_string())?;
        let view =
            scene_core::View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
        let mut renderer = RayCastRenderer::new();
        renderer
            .prepare(Arc::new(meshing.element_scene(&scene)))
            .map_err(|e| e.to_string())?;
        let g = renderer
            .render_view(&view, w, h)
            .map_err(|e| e.to_string())?;
        let t0 = Instant::now();
        let set = pool
            .install(|| LightSet::new(&scene, &ShadowSettings::default()))
            .map_err(|e| e.to_string())?;
        let build = t0.elapsed().as_secs_f64() * 1e3;
        let slots = light_slots(&set, &solution.sources);
        let gather = DirectGather::new(&scene, &meshing, &solution.sources, 4);
        let planes = meshing.plane_normals();
        let mut values = Vec::new();
        let cpu_gather = time_ms(repeats, || {
            values = pool.install(|| pixel_direct(&gather, &rays, &g, &view, 8));
            Ok(())
        })?;
        let cpu_maps = time_ms(repeats, || {
            pool.install(|| {
                pixel_direct_shadowed(&set, &slots, solution.k(), &g, &view, 3, Some(&planes))
            });
            Ok(())
        })?;
        let (gpu_gathered, gpu_maps) = match &gpu {
            None => ("-".to_string(), "-".to_string()),
            Some(ctx) => {
                let welding = Welding::new(&meshing, scene.extent());
                let mut relit = relight_pr::gpu::GpuRelight::new(
                    ctx,
                    &meshing,
                    &welding,
                    &solution,
                    Precision::F32,
                )
                .map_err(|e| e.to_string())?;
                relit
                    .set_shadowed_direct(&set, &slots, 3)
                    .map_err(|e| e.to_string())?;
                let gg = scene_core::gpu::GpuGBuffer::upload(ctx, &g).map_err(|e| e.to_string())?;
                let (f, base) = relight_pr::relight::weights(
                    &solution,
                    &scene_core::LightState::default(),
                    true,
                );
                let gathered = time_ms(repeats, || {
                    relit
                        .display(&gg, &view, &f, base, Some(&values))
                        .map(|_| ())
                        .map_err(|e| e.to_string())
                })?;
                let maps = time_ms(repeats, || {
                    relit
                        .display_shadowed(&gg, &view, &f, base)
                        .map(|_| ())
                        .map_err(|e| e.to_string())
                })?;
                (format!("{gathered:.1}"), format!("{maps:.1}"))
            }
        };
        println!(
            "{name:>14} {build:>11.1} {cpu_gather:>11.1} {cpu_maps:>11.1} {gpu_gathered:>13} {gpu_maps:>13}"
        );
    }
    println!(
        "(GPU gathered: the display with the CPU gather's values uploaded, the gather itself not included; GPU maps: the shadow-map pass and the display.)"
    );
    Ok(())
}
