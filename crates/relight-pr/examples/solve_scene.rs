//! Mesh and solve a built-in scene (or a glTF file), printing the meshing's counts
//! (merged triangles, one-element patches, splits, hidden elements), progress every 10 s and
//! the solve's statistics: how the figures in `docs/relight-pr.md` ("Large scenes") were
//! measured.
//!
//! `cargo run --release -p relight-pr --example solve_scene -- [SCENE] [ELEMENTS] [MAX_UNSHOT]`
//! (default `building 1024 0.001`). `FULL=F` sets `full_visibility_at`. `COMPARE=U` solves
//! again to unshot fraction `U` (with `MEMBERS=N` cluster members and `FULL2=F`) and prints
//! the area-weighted mean difference between the two solutions' element radiance.
//! `SPLIT_DEPTH=N` sets the meshing's splits at walls (default 6). `ROW_CACHE_MIB=M` sets
//! the first solve's `row_cache_bytes` (default 256). `DUMP=FILE` writes the first solve's
//! element radiance (RGB f32, little-endian) to `FILE`, and `AGAINST=FILE` compares the
//! first solve with such a file (emitters left out). `HIER=1` makes the first solve
//! hierarchical (`OPENING`, `LINK_ERROR`, `VIS_RAYS`, `NEAR_RAYS`, `TOLERANCE`, `CLUSTER`
//! set its settings). `SUN=DIR=RGB` and `SKY=RGB` add lights as `--sun` and `--sky` do. `PART=direct|indirect` dumps and compares one part of the light.
use relight_pr::mesh::{MeshSettings, Meshing};
use relight_pr::solver::{self, SolverSettings};
fn main() {
    let name = std::env::args().nth(1).unwrap_or("building".into());
    let elements: usize = std::env::args().nth(2).map_or(1024, |s| s.parse().unwrap());
    let unshot: f64 = std::env::args().nth(3).map_or(1e-3, |s| s.parse().unwrap());
    // A built-in name or a glTF file (opened as xtask does), with `SUN=DIR=RGB` and
    // `SKY=RGB` added as `--sun` and `--sky` add them.
    let mut added = scene_core::AddedLights::default();
    if let Ok(sun) = std::env::var("SUN") {
        added.parse_sun(&sun).unwrap();
    }
    if let Ok(sky) = std::env::var("SKY") {
        added.parse_sky(&sky).unwrap();
    }
    let scene = scene_core::open_scene_with(&name, &added).unwrap().scene;
    let t = std::time::Instant::now();
    let rays = scene_core::ray::RayScene::build(&scene);
    println!("rays {:.2?}", t.elapsed());
    let t = std::time::Instant::now();
    let m = Meshing::with_rays(
        &scene,
        &MeshSettings {
            split_depth: std::env::var("SPLIT_DEPTH").map_or(6, |v| v.parse().unwrap()),
            ..MeshSettings::elements(elements)
        },
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
        hierarchy_above: 0,
        hierarchy: std::env::var("HIER").ok().map(|_| {
            let var = |name: &str, default: f64| {
                std::env::var(name).map_or(default, |v| v.parse::<f64>().unwrap())
            };
            let d = relight_pr::HierarchySettings::default();
            relight_pr::HierarchySettings {
                opening: var("OPENING", d.opening as f64) as f32,
                link_error: var("LINK_ERROR", d.link_error),
                visibility_rays: var("VIS_RAYS", d.visibility_rays as f64) as u32,
                near_rays: var("NEAR_RAYS", d.near_rays as f64) as u32,
                tolerance: var("TOLERANCE", d.tolerance),
                cluster_radius: var("CLUSTER", d.cluster_radius as f64) as f32,
                ..d
            }
        }),
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
    if let Ok(path) = std::env::var("DUMP") {
        // Element radiance (RGB f32, little-endian) under the default light state.
        let st = part_state(&scene);
        let r = relight_pr::relight::radiance(&m, &s, &st);
        let bytes: Vec<u8> = r
            .iter()
            .flat_map(|c| c.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        std::fs::write(&path, bytes).unwrap();
        println!("wrote {path}");
    }
    if let Ok(path) = std::env::var("AGAINST") {
        // The area-weighted mean difference from a dumped solution (same meshing).
        let st = part_state(&scene);
        let a = relight_pr::relight::radiance(&m, &s, &st);
        let bytes = std::fs::read(&path).unwrap();
        let b: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        let (mut diff, mut sum, mut bias) = (0.0f64, 0.0f64, 0.0f64);
        for (j, e) in m.elements.iter().enumerate() {
            if e.hidden || e.emission != glam::Vec3::ZERO {
                continue;
            }
            let w = e.area as f64;
            let other = scene_core::luminance(glam::Vec3::from_slice(&b[3 * j..3 * j + 3]));
            let mine = scene_core::luminance(a[j]);
            diff += w * (mine - other).abs() as f64;
            bias += w * (mine - other) as f64;
            sum += w * other as f64;
        }
        println!(
            "against {path}: area-weighted |diff| / mean {:.4}, bias {:.4}",
            diff / sum,
            bias / sum
        );
    }
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
                hierarchy: None,
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

/// The light state of `PART=direct|indirect` (every light's other part at 0), else the
/// default.
fn part_state(scene: &scene_core::Scene) -> scene_core::lights::LightState {
    let mut st = scene_core::lights::LightState::default();
    if let Ok(part) = std::env::var("PART") {
        for id in scene_core::lights::light_ids(scene) {
            let mut setting = st.get(id);
            match part.as_str() {
                "direct" => setting.indirect = 0.0,
                "indirect" => setting.direct = 0.0,
                other => panic!("PART={other}: direct or indirect"),
            }
            st.set(id, setting);
        }
    }
    st
}
