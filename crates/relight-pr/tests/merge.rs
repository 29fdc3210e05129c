//! Merging coplanar triangles (`relight_pr::merge`) and the one-element patches of small
//! triangles: the merged surface is the input's (area, coverage, texture coordinates,
//! orientation, and what rays hit in the built-in building), what must not merge does not,
//! and the furnace holds with merging on and off.

mod common;

use glam::{Vec2, Vec3};
use relight_pr::merge::merge_coplanar;
use relight_pr::mesh::{MeshSettings, Meshing};
use relight_pr::relight;
use relight_pr::solver::{self, SolverSettings};
use scene_core::Scene;
use scene_core::lights::LightState;
use scene_core::ray::RayScene;
use scene_core::sampling::Rng;
use scene_core::scene::{Material, Mesh};

fn material(name: &str) -> Material {
    Material {
        name: name.into(),
        albedo: Vec3::splat(0.5),
        albedo_texture: None,
        emission: Vec3::ZERO,
        alpha_cutoff: None,
        emission_texture: None,
    }
}

/// A `nx` x `ny` grid of `cell`-sized quads in the plane z = 0 facing +z, without the
/// cells `hole` (`[i0, i1, j0, j1]`, half-open), material per cell from `material_of`,
/// texture coordinates from `uv_of` (per vertex, unwelded like a modeller's export).
fn grid(
    nx: u32,
    ny: u32,
    cell: f32,
    hole: [u32; 4],
    material_of: impl Fn(u32, u32) -> u32,
    uv_of: impl Fn(Vec3) -> Vec2,
) -> Mesh {
    let mut mesh = Mesh {
        name: "grid".into(),
        uvs: Some(Vec::new()),
        ..Default::default()
    };
    for j in 0..ny {
        for i in 0..nx {
            if (hole[0]..hole[1]).contains(&i) && (hole[2]..hole[3]).contains(&j) {
                continue;
            }
            let p = |a: u32, b: u32| Vec3::new(a as f32 * cell, b as f32 * cell, 0.0);
            mesh.push_quad(
                [p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)],
                material_of(i, j),
            );
        }
    }
    mesh.uvs = Some(mesh.positions.iter().map(|&p| uv_of(p)).collect());
    mesh
}

fn scene_of(mesh: Mesh, materials: usize) -> Scene {
    let mut scene = Scene::new("grid");
    for m in 0..materials {
        scene.materials.push(material(&format!("m{m}")));
    }
    scene.meshes.push(mesh);
    scene
}

/// The triangle of `mesh` containing `x` (in the plane z = 0) and its barycentric
/// coordinates.
fn locate(mesh: &Mesh, x: Vec2) -> Option<(usize, [f32; 3])> {
    mesh.indices.iter().enumerate().find_map(|(t, idx)| {
        let [a, b, c] = idx.map(|i| mesh.positions[i as usize].truncate());
        let area = (b - a).perp_dot(c - a);
        let l = [
            (c - b).perp_dot(x - b) / area,
            (a - c).perp_dot(x - c) / area,
            (b - a).perp_dot(x - a) / area,
        ];
        l.iter().all(|&w| w >= -1e-6).then_some((t, l))
    })
}

fn area(scene: &Scene) -> f64 {
    scene
        .meshes
        .iter()
        .flat_map(|m| {
            m.indices.iter().map(move |t| {
                let p = t.map(|i| m.positions[i as usize]);
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length() as f64
            })
        })
        .sum()
}

#[test]
fn a_gridded_wall_with_a_hole_merges_to_its_outline_and_keeps_its_surface() {
    // 3 m x 2 m in 10 cm cells with a window of 1 m x 0.6 m: 1 140 quads.
    let planar = |p: Vec3| Vec2::new(0.7 * p.x + 0.2 * p.y + 0.1, -0.3 * p.x + 0.9 * p.y);
    let scene = scene_of(grid(30, 20, 0.1, [10, 20, 8, 14], |_, _| 0, planar), 1);
    let merged = merge_coplanar(&scene);
    let out = &merged.scene.meshes[0];
    assert_eq!(merged.stats.triangles_before, 2 * (600 - 60));
    // The outline has 8 corners: a polygon with one hole and 8 vertices needs 8 triangles.
    assert_eq!(merged.stats.triangles_after, 8, "{:?}", merged.stats);
    assert_eq!(merged.origin.len(), 8);
    assert!((area(&merged.scene) - area(&scene)).abs() < 1e-5 * area(&scene));
    // Same coverage, same texture coordinates, every triangle facing +z.
    for t in &out.indices {
        let p = t.map(|i| out.positions[i as usize]);
        assert!((p[1] - p[0]).cross(p[2] - p[0]).normalize().z > 0.999_999);
    }
    let uvs = out.uvs.as_ref().unwrap();
    let mut checked = 0;
    for j in 0..97 {
        for i in 0..143 {
            let x = Vec2::new(
                (i as f32 + 0.37) * 3.0 / 143.0,
                (j as f32 + 0.61) * 2.0 / 97.0,
            );
            let before = locate(&scene.meshes[0], x).is_some();
            let after = locate(out, x);
            assert_eq!(before, after.is_some(), "coverage differs at {x}");
            if let Some((t, l)) = after {
                let q = out.indices[t].map(|i| uvs[i as usize]);
                let uv = q[0] * l[0] + q[1] * l[1] + q[2] * l[2];
                let expect = planar(x.extend(0.0));
                assert!(
                    uv.distance(expect) < 1e-5,
                    "uv {uv} against {expect} at {x}"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 10_000);
}

#[test]
fn curves_material_borders_and_non_affine_textures_are_left_alone() {
    // A checkerboard of two materials: every vertex touches both or is a corner.
    let checker = scene_of(
        grid(6, 6, 0.1, [0; 4], |i, j| (i + j) % 2, |p| p.truncate()),
        2,
    );
    assert_eq!(merge_coplanar(&checker).stats.vertices_removed, 0);
    // Texture coordinates that bend (u = x^2): no fan has an affine map.
    let bent = scene_of(
        grid(
            6,
            6,
            0.1,
            [0; 4],
            |_, _| 0,
            |p| Vec2::new(p.x * p.x, p.y * p.x),
        ),
        1,
    );
    assert_eq!(merge_coplanar(&bent).stats.vertices_removed, 0);
    // The built-in scenes (spheres, boxes, quads) have nothing to merge.
    for name in ["cornell", "primitives", "corridor"] {
        let scene = scene_core::builtin::scene(name).unwrap();
        let merged = merge_coplanar(&scene);
        assert_eq!(merged.stats.vertices_removed, 0, "{name}");
        assert!(merged.scene == scene, "{name}: the scene changed");
    }
}

#[test]
fn the_merged_building_is_the_same_surface_to_rays() {
    let scene = scene_core::builtin::scene("building 2x1").unwrap();
    let merged = merge_coplanar(&scene);
    let (before, after) = (merged.stats.triangles_before, merged.stats.triangles_after);
    assert!(after * 4 < before, "{before} -> {after} triangles");
    assert!((area(&merged.scene) - area(&scene)).abs() < 1e-6 * area(&scene));
    let (a, b) = (RayScene::build(&scene), RayScene::build(&merged.scene));
    let bounds = scene.bounds();
    let mut rng = Rng::new(7, 0);
    let mut hits = 0;
    for _ in 0..20_000 {
        let o = bounds.min
            + (bounds.max - bounds.min) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let d = Vec3::new(
            rng.next_f32() - 0.5,
            rng.next_f32() - 0.5,
            rng.next_f32() - 0.5,
        )
        .normalize_or_zero();
        if d == Vec3::ZERO {
            continue;
        }
        let (ha, hb) = (
            a.closest_hit(o, d, 0.0, f32::MAX),
            b.closest_hit(o, d, 0.0, f32::MAX),
        );
        assert_eq!(ha.is_some(), hb.is_some(), "ray from {o} along {d}");
        if let (Some(ha), Some(hb)) = (ha, hb) {
            assert!(
                (ha.t - hb.t).abs() <= 1e-4 * ha.t.max(1.0),
                "{} against {}",
                ha.t,
                hb.t
            );
            hits += 1;
        }
    }
    assert!(hits > 5_000, "{hits} hits");
    // Flat triangles keep normals that agree with their winding (each corner takes its
    // input vertex from a triangle of the same plane, also at creases).
    for (before, after) in scene.meshes.iter().zip(&merged.scene.meshes) {
        let flat = |m: &Mesh, t: &[u32; 3]| {
            let p = t.map(|i| m.positions[i as usize]);
            let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            t.iter().all(|&i| m.normals[i as usize].dot(n) > 0.9999)
        };
        let count = |m: &Mesh| m.indices.iter().filter(|t| !flat(m, t)).count();
        assert_eq!(count(before), count(after), "{}", before.name);
    }
}

/// The unit furnace (every surface emits 1, reflects `rho`), each face an `n` x `n` grid.
fn gridded_furnace(n: u32, rho: f32) -> Scene {
    let mut mesh = Mesh::default();
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    // Faces as (origin, u, v), counter-clockwise seen from inside.
    let faces = [
        (v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 0.)),
        (v(0., 1., 0.), v(1., 0., 0.), v(0., 0., 1.)),
        (v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)),
        (v(0., 0., 1.), v(0., 1., 0.), v(1., 0., 0.)),
        (v(0., 0., 0.), v(0., 1., 0.), v(0., 0., 1.)),
        (v(1., 0., 0.), v(0., 0., 1.), v(0., 1., 0.)),
    ];
    let s = 1.0 / n as f32;
    for (o, u, w) in faces {
        for j in 0..n {
            for i in 0..n {
                let p = |a: u32, b: u32| o + u * (a as f32 * s) + w * (b as f32 * s);
                mesh.push_quad([p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)], 0);
            }
        }
    }
    common::furnace_scene(rho, mesh)
}

#[test]
fn the_furnace_holds_merged_and_with_one_element_patches() {
    let rho = 0.5;
    let scene = gridded_furnace(8, rho);
    let rays = RayScene::build(&scene);
    let settings = SolverSettings {
        max_unshot: 1e-2,
        visibility_samples: 4,
        ..Default::default()
    };
    let expect = 1.0 / (1.0 - rho);
    for merge in [true, false] {
        let mesh = MeshSettings {
            merge_coplanar: merge,
            ..MeshSettings::elements(96)
        };
        let meshing = Meshing::with_rays(&scene, &mesh, 1, &rays).unwrap();
        if merge {
            // Each face is two triangles again, meshed as the plain box would be.
            assert_eq!(meshing.merge.unwrap().triangles_after, 12);
            assert!(meshing.patches.iter().all(|p| p.element_count == 4));
        } else {
            // 768 triangles, each smaller than an element: one element each.
            assert_eq!(meshing.elements.len(), 768);
            assert!(meshing.patches.iter().all(|p| p.element_count == 1));
        }
        let s = solver::solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap();
        let out = relight::radiance(&meshing, &s, &LightState::default());
        for (j, c) in out.iter().enumerate() {
            assert!(
                (c.x - expect).abs() <= 0.02 * expect,
                "merge {merge}, element {j}: {} against {expect}",
                c.x
            );
        }
    }
}

#[test]
fn small_patches_shot_in_clusters_give_the_solution_of_shooting_each_alone() {
    // The primitives' spheres are 3 072 triangles smaller than an element at 256: patches
    // of one element, shot in clusters by default.
    let scene = scene_core::builtin::scene("primitives").unwrap();
    let rays = RayScene::build(&scene);
    let k = scene_core::lights::light_ids(&scene).len();
    let meshing = Meshing::with_rays(&scene, &MeshSettings::elements(256), k, &rays).unwrap();
    let small = meshing
        .patches
        .iter()
        .filter(|p| p.element_count == 1)
        .count();
    assert!(small > 3000, "{small} patches of one element");
    let solve = |members: usize| {
        let settings = SolverSettings {
            cluster_members: members,
            ..Default::default()
        };
        let s = solver::solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap();
        (
            relight::radiance(&meshing, &s, &LightState::default()),
            s.stats,
        )
    };
    let (clustered, stats) = solve(32);
    let (alone, alone_stats) = solve(1);
    assert_eq!(alone_stats.cluster_shots, 0);
    assert!(
        stats.cluster_shots > 0 && stats.shots * 2 < alone_stats.shots,
        "{stats:?} against {alone_stats:?}"
    );
    let (diff, bias) = relative_difference(&meshing, &clustered, &alone);
    eprintln!(
        "clustered: {stats:?}; alone: {alone_stats:?}; mean difference {diff:.4}, bias {bias:.4}"
    );
    assert!(diff < 0.01, "mean difference {diff}");
    assert!(bias.abs() < 0.005, "bias {bias}");
}

/// The area-weighted mean of |lum(a) - lum(b)| and of lum(a) - lum(b) over the open
/// elements, each over the area-weighted mean of lum(b).
fn relative_difference(meshing: &Meshing, a: &[Vec3], b: &[Vec3]) -> (f64, f64) {
    let lum = scene_core::luminance;
    let (mut diff, mut sum, mut bias) = (0.0f64, 0.0f64, 0.0f64);
    for (j, e) in meshing
        .elements
        .iter()
        .enumerate()
        .filter(|(_, e)| !e.hidden)
    {
        let w = e.area as f64;
        diff += w * (lum(a[j]) - lum(b[j])).abs() as f64;
        bias += w * (lum(a[j]) - lum(b[j])) as f64;
        sum += w * lum(b[j]) as f64;
    }
    (diff / sum, bias / sum)
}

#[test]
fn fewer_rays_to_far_receivers_give_the_solution_of_full_rays() {
    // The corridor's pillars cast the shadows that visibility rays resolve; receivers get
    // fewer rays below the default full_visibility_at, all 16 with 0.
    let scene = scene_core::builtin::scene("corridor").unwrap();
    let rays = RayScene::build(&scene);
    let k = scene_core::lights::light_ids(&scene).len();
    let meshing = Meshing::with_rays(&scene, &MeshSettings::elements(256), k, &rays).unwrap();
    let solve = |full_visibility_at: f32| {
        let settings = SolverSettings {
            full_visibility_at,
            ..Default::default()
        };
        let s = solver::solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap();
        relight::radiance(&meshing, &s, &LightState::default())
    };
    let adaptive = solve(SolverSettings::default().full_visibility_at);
    let full = solve(0.0);
    assert!(adaptive != full, "the ray counts did not change");
    let (diff, bias) = relative_difference(&meshing, &adaptive, &full);
    eprintln!("adaptive against full rays: mean difference {diff:.4}, bias {bias:.4}");
    assert!(diff < 0.01, "mean difference {diff}");
    assert!(bias.abs() < 0.005, "bias {bias}");
}
