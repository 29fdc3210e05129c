//! Ray throughput of [`scene_core::ray::RayScene`] on a scene's own view: the three kinds of
//! ray a path tracer casts, timed apart. Camera rays (closest hit, coherent), cosine bounce
//! rays from where they land (closest hit, incoherent) and shadow rays from the same points
//! towards a sun (occlusion). Median of the repeats after a warm-up, every core.
//!
//! ```sh
//! cargo run --release -p scene-core --features gltf --example ray_throughput -- FILE.gltf
//! cargo run --release -p scene-core --example ray_throughput -- cornell 128 72 16 5
//! ```
//!
//! Arguments: scene (built-in name or glTF), width, height, rays per pixel, repeats.

use std::time::Instant;

use rayon::prelude::*;
use scene_core::glam::{Vec2, Vec3};
use scene_core::ray::RayScene;
use scene_core::sampling::{Rng, cosine_hemisphere, hash_seed};
use scene_core::{View, builtin};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map(String::as_str).unwrap_or("cornell");
    let num = |i: usize, d: u32| -> Result<u32, Box<dyn std::error::Error>> {
        Ok(args.get(i).map(|s| s.parse()).transpose()?.unwrap_or(d))
    };
    let (w, h, spp, repeats) = (num(1, 128)?, num(2, 72)?, num(3, 16)?, num(4, 5)?.max(1));
    #[cfg(feature = "gltf")]
    let scene = if name.ends_with(".gltf") || name.ends_with(".glb") {
        scene_core::gltf_io::import(name.as_ref())?.scene
    } else {
        builtin::scene(name)?
    };
    #[cfg(not(feature = "gltf"))]
    let scene = builtin::scene(name)?;
    let camera = scene.cameras.first().ok_or("the scene has no camera")?;
    let view = View::from_camera(&camera.with_aspect(w as f32 / h as f32));
    let t0 = Instant::now();
    let rays = RayScene::build(&scene);
    println!(
        "{}: {} triangles, BVH built in {:.2} s, {:.1} MB",
        scene.name,
        scene.triangle_count(),
        t0.elapsed().as_secs_f64(),
        rays.bvh_bytes() as f64 / 1e6
    );
    let corners = scene.triangle_corners();
    let n = (w * h * spp) as u64;
    let sun = Vec3::new(1.0, 0.8, -0.35).normalize();
    let eps = 1e-4 * scene.bounds().diagonal().max(1e-6);

    let camera_ray = |i: u64| {
        let mut rng = Rng::new(hash_seed(7, i, 0), 0);
        let px = (i / spp as u64) as u32;
        let uv = Vec2::new(
            ((px % w) as f32 + rng.next_f32()) / w as f32,
            ((px / w) as f32 + rng.next_f32()) / h as f32,
        );
        view.ray(uv)
    };
    // Where each camera ray lands, with the normal facing it: the origins of the others.
    let landed: Vec<Option<(Vec3, Vec3)>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let (o, d) = camera_ray(i);
            let hit = rays.closest_hit(o, d, 0.0, f32::INFINITY)?;
            let [a, b, c] = corners[hit.triangle as usize];
            let g = (b - a).cross(c - a).normalize_or_zero();
            let g = if g.dot(d) > 0.0 { -g } else { g };
            Some((o + d * hit.t + g * eps, g))
        })
        .collect();
    let points: Vec<(u64, Vec3, Vec3)> = landed
        .iter()
        .enumerate()
        .filter_map(|(i, l)| l.map(|(p, g)| (i as u64, p, g)))
        .collect();

    let time = |f: &(dyn Fn() -> u64 + Sync)| {
        f(); // warm-up
        let mut times: Vec<f64> = (0..repeats)
            .map(|_| {
                let t = Instant::now();
                std::hint::black_box(f());
                t.elapsed().as_secs_f64()
            })
            .collect();
        times.sort_by(f64::total_cmp);
        (times[times.len() / 2], f())
    };
    let primary = time(&|| {
        (0..n)
            .into_par_iter()
            .map(|i| {
                let (o, d) = camera_ray(i);
                u64::from(rays.closest_hit(o, d, 0.0, f32::INFINITY).is_some())
            })
            .sum()
    });
    let bounce = time(&|| {
        points
            .par_iter()
            .map(|&(i, p, g)| {
                let mut rng = Rng::new(hash_seed(9, i, 0), 0);
                let d = cosine_hemisphere(g, Vec2::new(rng.next_f32(), rng.next_f32()));
                u64::from(rays.closest_hit(p, d, 0.0, f32::INFINITY).is_some())
            })
            .sum()
    });
    let shadow = time(&|| {
        points
            .par_iter()
            .map(|&(_, p, _)| u64::from(rays.occluded(p, sun, 0.0, f32::INFINITY)))
            .sum()
    });
    println!("| rays | count | hits | median s | Mrays/s |");
    println!("|---|---|---|---|---|");
    for (label, count, (s, hits)) in [
        ("camera (closest)", n, primary),
        ("bounce (closest)", points.len() as u64, bounce),
        ("shadow (occlusion)", points.len() as u64, shadow),
    ] {
        println!(
            "| {label} | {count} | {hits} | {s:.3} | {:.2} |",
            count as f64 / s / 1e6
        );
    }
    Ok(())
}
