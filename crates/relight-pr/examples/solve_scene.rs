//! Mesh and solve a built-in scene, printing the meshing's counts (merged triangles,
//! one-element patches, splits, hidden elements), progress every 10 s and the solve's
//! statistics: how the figures in `docs/relight-pr.md` ("Large scenes") were measured.
//!
//! `cargo run --release -p relight-pr --example solve_scene -- [SCENE] [ELEMENTS] [MAX_UNSHOT]`
//! (default `building 1024 0.001`). `FULL=F` sets `full_visibility_at`. `COMPARE=U` solves
//! again to unshot fraction `U` (with `MEMBERS=N` cluster members and `FULL2=F`) and prints
//! the area-weighted mean difference between the two solutions' element radiance.
//! `ROW_CACHE_MIB=M` sets the first solve's `row_cache_bytes` (default 256).
use relight_pr::mesh::{MeshSettings, Meshing};
use relight_pr::solver::{self, SolverSettings};
fn main() {
    let name = std::env::args().nth(1).unwrap_or("building".into());
    let elements: usize = std::env::args().nth(2).map_or(1024, |s| s.parse().unwrap());
    let unshot: f64 = std::env::args().nth(3).map_or(1e-3, |s| s.parse().unwrap());
    let scene = scene_core::builtin::scene(&name).unwrap();
    let t = std::time::Instant::now();
    let rays = scene_core::ray::RayScene::build(&scene);
    println!("rays {:.2?}", t.elapsed());
    let t = std::time::Instant::now();
    let m = Meshing::with_rays(
        &scene,
        &MeshSettings::elements(elements),
        scene_core::lights::light_ids(&scene).len(),
        &rays,
    )
    .unwrap();
    let one = m.patches.iter().filter(|p| p.element_count == 1).count();
    println!(
        "meshing {:.2?}: {} elements, {} patches ({one} of one element), split {}, hidden {}, {:?}",
        t.elapsed(),
        m.elements.len(),
        m.patches.len(),
        m.split_patches,
        m.elements.iter().filter(|e| e.hidden).count(),
        m.merge
    );
    let t = std::time::Instant::now();
    let mut last = std::time::Instant::now();
    let mut shots = 0;
    let settings = SolverSettings {
        max_unshot: unshot,
        full_visibility_at: std::env::var("FULL").map_or(0.01, |m| m.parse().unwrap()),
        row_cache_bytes: std::env::var("ROW_CACHE_MIB")
            .map_or(256 << 20, |m| m.parse::<usize>().unwrap() << 20),
        ..Default::default()
    };
    let s = solver::solve(&scene, &m, &rays, &settings, &mut |f| {
        shots += 1;
        if last.elapsed().as_secs_f32() > 10.0 {
            println!("{:.1?}: shot {shots}, unshot {f:.4}", t.elapsed());
            last = std::time::Instant::now();
        }
    })
    .unwrap();
    println!("solve {:.2?}: {:?}", t.elapsed(), s.stats);
    if let Ok(c) = std::env::var("COMPARE") {
        let c: f64 = c.parse().unwrap();
        let t = std::time::Instant::now();
        let s2 = solver::solve(
            &scene,
            &m,
            &rays,
            &SolverSettings {
                max_unshot: c,
                cluster_members: std::env::var("MEMBERS").map_or(32, |m| m.parse().unwrap()),
                full_visibility_at: std::env::var("FULL2").map_or(0.01, |m| m.parse().unwrap()),
                ..Default::default()
            },
            &mut |_| {},
        )
        .unwrap();
        println!("solve {:.2?}: {:?}", t.elapsed(), s2.stats);
        let st = scene_core::lights::LightState::default();
        let (a, b) = (
            relight_pr::relight::radiance(&m, &s, &st),
            relight_pr::relight::radiance(&m, &s2, &st),
        );
        let (mut diff, mut sum, mut bias) = (0.0f64, 0.0f64, 0.0f64);
        for (j, e) in m.elements.iter().enumerate() {
            if e.hidden {
                continue;
            }
            let w = e.area as f64;
            diff += w * (scene_core::luminance(a[j]) - scene_core::luminance(b[j])).abs() as f64;
            bias += w * (scene_core::luminance(b[j]) - scene_core::luminance(a[j])) as f64;
            sum += w * scene_core::luminance(a[j]) as f64;
        }
        println!(
            "area-weighted |diff| / mean: {:.4}, bias {:.4}",
            diff / sum,
            bias / sum
        );
    }
}
