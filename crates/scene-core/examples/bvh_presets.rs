//! Compares the BVH build presets ([`scene_core::ray::BvhQuality`]) on seeded box fields:
//! build seconds and the closest-hit rate of incoherent rays (random origins over the field,
//! uniform directions), the numbers behind `BvhQuality::for_triangles`.
//!
//! ```sh
//! cargo run --release -p scene-core --example bvh_presets -- 1000000 10000000
//! ```

use std::time::Instant;

use rayon::prelude::*;
use scene_core::builtin;
use scene_core::glam::{Vec2, Vec3};
use scene_core::ray::{BvhQuality, RayScene};
use scene_core::sampling::{Rng, hash_seed, uniform_sphere};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let sizes: Vec<u64> = std::env::args()
        .skip(1)
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    let sizes = if sizes.is_empty() {
        vec![100_000, 1_000_000]
    } else {
        sizes
    };
    let rays = 2_000_000u64;
    println!("| triangles | preset | build s | Mrays/s (incoherent closest hit) |");
    println!("|---|---|---|---|");
    for n in sizes {
        let scene = builtin::many_boxes(((n.max(14) - 2) / 12) as u32, 7);
        let b = scene.bounds();
        for q in [BvhQuality::Medium, BvhQuality::Slow, BvhQuality::VerySlow] {
            if q == BvhQuality::VerySlow && scene.triangle_count() > 4 * BvhQuality::VERY_SLOW_UP_TO
            {
                println!(
                    "| {} | {q:?} | not run (minutes: `cargo xtask bench scaling`) | |",
                    scene.triangle_count()
                );
                continue;
            }
            let t0 = Instant::now();
            let bvh = RayScene::build_with(&scene, q);
            let build = t0.elapsed().as_secs_f64();
            let t0 = Instant::now();
            let hits: u64 = (0..rays)
                .into_par_iter()
                .map(|i| {
                    let mut rng = Rng::new(hash_seed(3, i, 0), 0);
                    let u = Vec3::new(rng.next_f32(), rng.next_f32() * 0.1, rng.next_f32());
                    let o = b.min + (b.max - b.min) * u + Vec3::Y * 0.05;
                    let d = uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                    u64::from(bvh.closest_hit(o, d, 0.0, f32::INFINITY).is_some())
                })
                .sum();
            let rate = rays as f64 / t0.elapsed().as_secs_f64() / 1e6;
            println!(
                "| {} | {q:?} | {build:.2} | {rate:.2} ({:.0}% hit) |",
                scene.triangle_count(),
                100.0 * hits as f64 / rays as f64
            );
        }
    }
    Ok(())
}
