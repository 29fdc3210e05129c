//! The hierarchical solve (`relight_pr::hierarchical`) against the progressive one it
//! replaces on large scenes: the same element radiance within a stated bound on the
//! built-in scenes, the furnace, recolouring through the light state equal to re-solving,
//! and the same result bit for bit on one thread and on several.

mod common;

use common::{furnace_scene, unit_box};
use glam::Vec3;
use relight_pr::mesh::{MeshSettings, Meshing};
use relight_pr::solver::{self, Solution, SolverSettings};
use relight_pr::{HierarchySettings, relight};
use scene_core::Scene;
use scene_core::lights::{LightId, LightState};
use scene_core::ray::RayScene;

fn hierarchical() -> SolverSettings {
    SolverSettings {
        hierarchy: Some(HierarchySettings::default()),
        hierarchy_above: 0,
        ..Default::default()
    }
}

fn solve(scene: &Scene, meshing: &Meshing, settings: &SolverSettings) -> Solution {
    let rays = RayScene::build(scene);
    solver::solve(scene, meshing, &rays, settings, &mut |_| {}).unwrap()
}

/// Area-weighted mean |a - b| over the mean of `b`, and the mean of `a - b` over the mean
/// of `b` (luminance; hidden elements and emitters left out).
fn difference(meshing: &Meshing, a: &[Vec3], b: &[Vec3]) -> (f64, f64) {
    let (mut diff, mut bias, mut sum) = (0.0f64, 0.0f64, 0.0f64);
    for (j, e) in meshing.elements.iter().enumerate() {
        if e.hidden || e.emission != Vec3::ZERO {
            continue;
        }
        let w = e.area as f64;
        let (x, y) = (
            scene_core::luminance(a[j]) as f64,
            scene_core::luminance(b[j]) as f64,
        );
        diff += w * (x - y).abs();
        bias += w * (x - y);
        sum += w * y;
    }
    (diff / sum, bias / sum)
}

/// The bound this solve is held to on the built-in scenes at 1024 elements: each
/// element's radiance within 6 % of the progressive solve's on average, and the mean
/// within 2 % (the progressive solve to 1e-4 unshot, both with their default visibility
/// rays, so part of the difference is the noise of either).
const MEAN_BOUND: f64 = 0.06;
const BIAS_BOUND: f64 = 0.02;

#[test]
fn the_hierarchical_solve_matches_the_progressive_one_on_the_built_in_scenes() {
    for name in ["cornell", "cornell-point", "corridor", "primitives"] {
        let scene = scene_core::builtin::scene(name).unwrap();
        let k = scene_core::lights::light_ids(&scene).len();
        let meshing = Meshing::new(&scene, &MeshSettings::elements(1024), k).unwrap();
        let progressive = solve(
            &scene,
            &meshing,
            &SolverSettings {
                max_unshot: 1e-4,
                ..Default::default()
            },
        );
        let h = solve(&scene, &meshing, &hierarchical());
        let state = LightState::default();
        let (a, b) = (
            relight::radiance(&meshing, &h, &state),
            relight::radiance(&meshing, &progressive, &state),
        );
        assert!(a.iter().all(|c| c.is_finite() && c.min_element() >= 0.0));
        let (mean, bias) = difference(&meshing, &a, &b);
        let stats = h.stats.hierarchy.unwrap();
        eprintln!(
            "{name}: {} elements; hierarchical {:.2?} ({} far + {} near links, {} bounces), \
             progressive {:.2?}; |difference| {mean:.4}, bias {bias:+.4}",
            meshing.elements.len(),
            h.stats.time,
            stats.far_links + stats.direct_far_links,
            stats.near_links + stats.direct_near_links,
            stats.bounces,
            progressive.stats.time
        );
        assert!(mean <= MEAN_BOUND, "{name}: mean |difference| {mean}");
        assert!(bias.abs() <= BIAS_BOUND, "{name}: bias {bias}");
        // Direct and indirect stay apart: the direct light is the progressive solve's
        // first shot (the same analytic light, or the emitters' light).
        let direct = |s: &Solution| -> Vec<Vec3> {
            (0..meshing.elements.len())
                .map(|j| {
                    let g = s.slot(&meshing, j);
                    (0..s.k()).map(|m| s.direct[g * s.k() + m]).sum()
                })
                .collect()
        };
        let (da, db) = (direct(&h), direct(&progressive));
        let (mean, bias) = difference(&meshing, &da, &db);
        eprintln!("{name}: direct |difference| {mean:.4}, bias {bias:+.4}");
        assert!(mean <= MEAN_BOUND && bias.abs() <= BIAS_BOUND);
    }
}

#[test]
fn the_hierarchical_furnace_holds() {
    // The closed unit box emitting 1 and reflecting rho everywhere: L / (1 - rho).
    let mesh = unit_box();
    for rho in [0.3f32, 0.5] {
        let scene = furnace_scene(rho, mesh.clone());
        let meshing = Meshing::new(&scene, &MeshSettings::elements(768), 1).unwrap();
        let s = solve(&scene, &meshing, &hierarchical());
        let out = relight::radiance(&meshing, &s, &LightState::default());
        let expect = 1.0 / (1.0 - rho);
        let worst = out
            .iter()
            .zip(&meshing.elements)
            .filter(|(_, e)| !e.hidden)
            .map(|(c, _)| (c.x - expect).abs() / expect)
            .fold(0.0f32, f32::max);
        eprintln!("furnace rho {rho}: worst element {worst:.4}");
        assert!(worst <= 0.02, "rho {rho}: worst {worst}");
    }
}

#[test]
fn recolouring_a_hierarchical_solution_equals_solving_again() {
    // Over clusters of mesh elements (512 asked: one value per mesh element) and between
    // the element budget's groups (256 asked: groups of about 15 mesh elements).
    recolouring_equals_solving_again(512, &hierarchical());
    recolouring_equals_solving_again(256, &by_groups());
}

fn recolouring_equals_solving_again(target: usize, settings: &SolverSettings) {
    // The corridor's four lights: light 0 recoloured, light 1 off, through the state; and
    // the same scene with those emissions, solved again.
    let scene = scene_core::builtin::scene("corridor").unwrap();
    let ids = scene_core::lights::light_ids(&scene);
    let meshing = Meshing::new(&scene, &MeshSettings::elements(target), ids.len()).unwrap();
    let solution = solve(&scene, &meshing, settings);
    let mut state = LightState::default();
    let colour = Vec3::new(0.3, 1.0, 2.0);
    state.set_color(ids[0], colour);
    state.set_enabled(ids[1], false);
    let relit = relight::radiance(&meshing, &solution, &state);
    let mut changed = scene.clone();
    let scale = |scene: &mut Scene, id: LightId, c: Vec3| match id {
        LightId::Point(i) => scene.point_lights[i as usize].intensity *= c,
        LightId::Directional(i) => scene.directional_lights[i as usize].irradiance *= c,
        other => panic!("the corridor's lights are analytic, not {other:?}"),
    };
    scale(&mut changed, ids[0], colour);
    scale(&mut changed, ids[1], Vec3::ZERO);
    let again = solve(&changed, &meshing, settings);
    let resolved = relight::radiance(&meshing, &again, &LightState::default());
    let (mean, bias) = difference(&meshing, &relit, &resolved);
    eprintln!(
        "{target} elements asked: recoloured against re-solved: |difference| {mean:.5}, bias \
         {bias:+.5}"
    );
    // The links of the re-solve are refined against other powers, so they differ a little.
    assert!(mean <= 0.01 && bias.abs() <= 0.005);
}

#[test]
fn the_hierarchical_solve_is_the_same_on_one_thread_and_on_several() {
    let scene = scene_core::builtin::scene("cornell").unwrap();
    let meshing = Meshing::new(&scene, &MeshSettings::elements(512), 1).unwrap();
    same_on_one_thread_and_on_three(&scene, &meshing, &hierarchical());
}

/// Solves `meshing` on 1 and on 3 threads, checks the solutions bit for bit and their links
/// alike, and returns the first.
fn same_on_one_thread_and_on_three(
    scene: &Scene,
    meshing: &Meshing,
    settings: &SolverSettings,
) -> Solution {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| solve(scene, meshing, settings))
    };
    let (one, three) = (run(1), run(3));
    assert_eq!(one.direct, three.direct);
    assert_eq!(one.indirect, three.indirect);
    let links = |s: &Solution| {
        s.stats
            .hierarchy
            .map(|h| (h.far_links, h.near_links, h.cluster_links, h.by_group))
    };
    assert_eq!(links(&one), links(&three));
    one
}

#[test]
fn bad_hierarchy_settings_are_refused_by_name() {
    let scene = scene_core::builtin::scene("cornell").unwrap();
    let meshing = Meshing::new(&scene, &MeshSettings::elements(64), 1).unwrap();
    let rays = RayScene::build(&scene);
    for h in [
        HierarchySettings {
            opening: 0.0,
            ..Default::default()
        },
        HierarchySettings {
            link_error: f64::NAN,
            ..Default::default()
        },
        HierarchySettings {
            visibility_rays: 0,
            ..Default::default()
        },
    ] {
        let settings = SolverSettings {
            hierarchy: Some(h),
            hierarchy_above: 0,
            ..Default::default()
        };
        let e = solver::solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap_err();
        assert!(e.to_string().contains("hierarchy"), "{e}");
    }
    // The hemicube and separate solves are the progressive solver's alone.
    let settings = SolverSettings {
        strategy: relight_pr::Strategy::Separate,
        ..hierarchical()
    };
    let e = solver::solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("hierarchical"), "{e}");
    // A budget of links too small is refused by name, not run out of memory.
    let settings = SolverSettings {
        hierarchy: Some(HierarchySettings {
            max_links: 100,
            ..Default::default()
        }),
        hierarchy_above: 0,
        ..Default::default()
    };
    let e = solver::solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("links"), "{e}");
}

#[test]
fn the_hierarchical_solve_reports_its_progress_from_one_to_zero() {
    let scene = scene_core::builtin::scene("cornell").unwrap();
    let meshing = Meshing::new(&scene, &MeshSettings::elements(256), 1).unwrap();
    let rays = RayScene::build(&scene);
    let mut seen = Vec::new();
    solver::solve(&scene, &meshing, &rays, &hierarchical(), &mut |f| {
        seen.push(f)
    })
    .unwrap();
    assert_eq!(seen.first(), Some(&1.0));
    assert_eq!(seen.last(), Some(&0.0));
    assert!(seen.windows(2).all(|w| w[1] <= w[0]), "{seen:?}");
    // The links (most of the time) move it, not only the bounces: the reflected light's
    // links report 32 parts, down to 0.1 (to rounding).
    let during_links = seen.iter().filter(|&&f| f > 0.1 - 1e-9 && f < 1.0).count();
    assert!(during_links >= 32, "{seen:?}");
}

#[test]
fn hard_cases_stay_finite_in_the_hierarchical_solve() {
    // A closed box without lights solves to no sources and relights black; the same box
    // emitting everywhere with an albedo of 0.999 (thousands of bounces to converge) stops
    // at the bounce cap with every element finite, at least the first bounce's light and
    // below the furnace's limit.
    let mesh = unit_box();
    let mut dark = furnace_scene(0.5, mesh.clone());
    dark.materials[0].emission = Vec3::ZERO;
    let meshing = Meshing::new(&dark, &MeshSettings::elements(256), 0).unwrap();
    let s = solve(&dark, &meshing, &hierarchical());
    assert_eq!(s.k(), 0);
    let out = relight::radiance(&meshing, &s, &LightState::default());
    assert!(out.iter().all(|c| *c == Vec3::ZERO));

    let rho = 0.999f32;
    let white = furnace_scene(rho, mesh);
    let meshing = Meshing::new(&white, &MeshSettings::elements(256), 1).unwrap();
    let s = solve(&white, &meshing, &hierarchical());
    let h = s.stats.hierarchy.unwrap();
    assert_eq!(h.bounces, HierarchySettings::default().max_bounces);
    let out = relight::radiance(&meshing, &s, &LightState::default());
    for (c, e) in out.iter().zip(&meshing.elements) {
        if e.hidden {
            continue;
        }
        assert!(c.is_finite(), "{c}");
        assert!(c.x >= 1.0 + rho * 0.9 && c.x <= 1.02 / (1.0 - rho), "{c}");
    }
}

/// Element radiance under the default light state.
fn radiance(meshing: &Meshing, s: &Solution) -> Vec<Vec3> {
    relight::radiance(meshing, s, &LightState::default())
}

/// All links of a hierarchical solve.
fn links(s: &Solution) -> usize {
    let h = s.stats.hierarchy.unwrap();
    h.far_links
        + h.near_links
        + h.cluster_links
        + h.direct_far_links
        + h.direct_near_links
        + h.direct_cluster_links
}

/// The element budget's clusters at `r` target radii, over the mesh elements (never
/// between the groups: [`HierarchySettings::solve_groups_above`]).
fn with_cluster_radius(r: f32) -> SolverSettings {
    SolverSettings {
        hierarchy: Some(HierarchySettings {
            cluster_radius: r,
            solve_groups_above: f32::INFINITY,
            ..Default::default()
        }),
        hierarchy_above: 0,
        ..Default::default()
    }
}

/// The element budget ([`HierarchySettings::cluster_radius`]) on a file's small triangles:
/// the unit box cut into 24 x 24 quads a face (6 912 triangles, not merged) and meshed at a
/// target of 48 elements, so that every triangle is an element far below the size asked
/// for. Solved as clusters of about an element's size, it makes a fraction of the links of
/// the solve down to the triangles, and the furnace still holds on every element: the
/// cluster links' form factors sum to what the room's do.
#[test]
fn the_element_budget_clusters_small_triangles_and_the_furnace_holds() {
    let g = 24;
    let mesh = common::gridded_unit_box(g);
    let rho = 0.5f32;
    let scene = furnace_scene(rho, mesh);
    let meshing = Meshing::new(
        &scene,
        &MeshSettings {
            merge_coplanar: false,
            ..MeshSettings::elements(48)
        },
        1,
    )
    .unwrap();
    assert_eq!(meshing.elements.len(), 6 * g * g * 2);
    let expect = 1.0 / (1.0 - rho);
    let mut counts = Vec::new();
    for r in [1.0, 0.0] {
        let s = solve(&scene, &meshing, &with_cluster_radius(r));
        let h = s.stats.hierarchy.unwrap();
        let (mean_error, worst) = furnace_errors(&meshing, &s, expect);
        eprintln!(
            "cluster_radius {r}: {} links ({} cluster, {} budget nodes), {:.2?}, mean error \
             {mean_error:.4}, worst element {worst:.4}",
            links(&s),
            h.cluster_links + h.direct_cluster_links,
            h.budget_nodes,
            s.stats.time
        );
        // Down to the triangles the bound of the built-in furnace (2 %) holds; the cluster
        // links are Monte Carlo estimates (8 points a link, 16 for the emitters' light,
        // which is not normalised), so single clusters stray further: the mean within 1 %,
        // the worst within 4 % (measured 0.51 % and 3.1 %).
        let (mean_bound, worst_bound) = if r > 0.0 { (0.01, 0.04) } else { (0.01, 0.02) };
        assert!(
            mean_error <= mean_bound,
            "cluster_radius {r}: mean {mean_error}"
        );
        assert!(worst <= worst_bound, "cluster_radius {r}: worst {worst}");
        counts.push(links(&s));
    }
    assert!(counts[0] * 4 < counts[1], "{counts:?}");
}

/// On a room cluttered with small and thin objects (shelves, books, legs; 2 400 triangles
/// at `cluttered_room(40)`) meshed at 256 elements, the solve at the element budget
/// matches the progressive solve within the bound of the built-in scenes, with fewer links
/// than the solve down to the triangles.
#[test]
fn the_element_budget_on_a_cluttered_room_matches_the_progressive_solve() {
    let scene = scene_core::builtin::cluttered_room(40, 1);
    let k = scene_core::lights::light_ids(&scene).len();
    let meshing = Meshing::new(
        &scene,
        &MeshSettings {
            split_depth: 2,
            ..MeshSettings::elements(256)
        },
        k,
    )
    .unwrap();
    let progressive = progressive_to_1e4(&scene, &meshing);
    let reference = radiance(&meshing, &progressive);
    let mut counts = Vec::new();
    for r in [1.0, 0.0] {
        let s = solve(&scene, &meshing, &with_cluster_radius(r));
        let h = s.stats.hierarchy.unwrap();
        let (mean, bias) = difference(&meshing, &radiance(&meshing, &s), &reference);
        eprintln!(
            "cluttered room, {} elements, cluster_radius {r}: {} links ({} cluster, {} budget \
             nodes), {:.2?} (progressive {:.2?}); |difference| {mean:.4}, bias {bias:+.4}",
            meshing.elements.len(),
            links(&s),
            h.cluster_links + h.direct_cluster_links,
            h.budget_nodes,
            s.stats.time,
            progressive.stats.time
        );
        counts.push((links(&s), mean, bias));
    }
    for (r, (_, mean, bias)) in [1.0, 0.0].iter().zip(&counts) {
        assert!(
            *mean <= MEAN_BOUND,
            "cluster_radius {r}: |difference| {mean}"
        );
        assert!(bias.abs() <= BIAS_BOUND, "cluster_radius {r}: bias {bias}");
    }
    assert!(counts[0].0 < counts[1].0, "{counts:?}");
}

/// The progressive solve of `meshing` to 1e-4 unshot: what the hierarchical solve is held
/// to.
fn progressive_to_1e4(scene: &Scene, meshing: &Meshing) -> Solution {
    let settings = SolverSettings {
        max_unshot: 1e-4,
        hierarchy: None,
        ..Default::default()
    };
    solve(scene, meshing, &settings)
}

/// The mean and the largest relative error of every mesh element's radiance (red) against
/// the furnace's `expect`.
fn furnace_errors(meshing: &Meshing, s: &Solution, expect: f32) -> (f32, f32) {
    let out = radiance(meshing, s);
    let mean = out.iter().map(|c| (c.x - expect).abs()).sum::<f32>() / (out.len() as f32 * expect);
    let worst = out
        .iter()
        .map(|c| (c.x - expect).abs() / expect)
        .fold(0.0f32, f32::max);
    (mean, worst)
}

/// Solved between the element budget's groups wherever the meshing has groups
/// ([`HierarchySettings::solve_groups_above`] 0).
fn by_groups() -> SolverSettings {
    SolverSettings {
        hierarchy: Some(HierarchySettings {
            solve_groups_above: 0.0,
            ..Default::default()
        }),
        hierarchy_above: 0,
        ..Default::default()
    }
}

/// The unit box cut into `g` x `g` quads a face (not merged), reflecting 0.6, lit by a point
/// light off its centre.
fn gridded_box_with_a_lamp(g: usize) -> Scene {
    let mut scene = Scene::new("gridded box");
    scene.materials.push(scene_core::scene::Material::diffuse(
        "walls",
        Vec3::splat(0.6),
    ));
    scene.meshes.push(common::gridded_unit_box(g));
    scene.point_lights.push(scene_core::scene::PointLight {
        name: "lamp".into(),
        position: Vec3::new(0.2, 0.8, 0.3),
        intensity: Vec3::ONE,
        radius: None,
        cone: None,
    });
    scene
}

/// Solving between the element budget's groups (the solve as large as the solution asked
/// for, not as the file): the furnace holds on a box of 6 912 small triangles in 60 groups,
/// and on a lamp-lit box of small triangles and on the corridor the solution stays within
/// the bounds the hierarchical solve is held to against the progressive solve.
#[test]
fn the_solve_between_groups_holds_the_furnace_and_matches_the_progressive_solve() {
    let g = 24;
    let mesh = common::gridded_unit_box(g);
    let rho = 0.5f32;
    let scene = furnace_scene(rho, mesh);
    let unmerged = |target: usize| MeshSettings {
        merge_coplanar: false,
        ..MeshSettings::elements(target)
    };
    let meshing = Meshing::new(&scene, &unmerged(48), 1).unwrap();
    assert!(
        meshing.groups.count <= 60,
        "{} groups",
        meshing.groups.count
    );
    let s = solve(&scene, &meshing, &by_groups());
    assert!(s.stats.hierarchy.unwrap().by_group);
    let expect = 1.0 / (1.0 - rho);
    let (mean_error, worst) = furnace_errors(&meshing, &s, expect);
    eprintln!("furnace between groups: mean error {mean_error:.4}, worst {worst:.4}");
    // The bounds of the clusters of mesh elements above (Monte Carlo cluster links).
    assert!(mean_error <= 0.01 && worst <= 0.04, "{mean_error} {worst}");

    for (name, scene, mesh) in [
        ("gridded box", gridded_box_with_a_lamp(16), unmerged(64)),
        (
            "corridor",
            scene_core::builtin::scene("corridor").unwrap(),
            MeshSettings::elements(1024),
        ),
    ] {
        let k = scene_core::lights::light_ids(&scene).len();
        let meshing = Meshing::new(&scene, &mesh, k).unwrap();
        let progressive = progressive_to_1e4(&scene, &meshing);
        let s = solve(&scene, &meshing, &by_groups());
        let h = s.stats.hierarchy.unwrap();
        assert!(h.by_group && h.budget_nodes <= meshing.groups.count);
        let (mean, bias) = difference(
            &meshing,
            &radiance(&meshing, &s),
            &radiance(&meshing, &progressive),
        );
        eprintln!(
            "{name}: {} mesh elements in {} groups, {} links, {:.2?} (progressive {:.2?}); \
             |difference| {mean:.4}, bias {bias:+.4}",
            meshing.elements.len(),
            meshing.groups.count,
            links(&s),
            s.stats.time,
            progressive.stats.time
        );
        assert!(mean <= MEAN_BOUND, "{name}: |difference| {mean}");
        assert!(bias.abs() <= BIAS_BOUND, "{name}: bias {bias}");
    }
}

#[test]
fn the_solve_between_groups_is_the_same_on_one_thread_and_on_several() {
    let scene = scene_core::builtin::scene("corridor").unwrap();
    let meshing = Meshing::new(&scene, &MeshSettings::elements(256), 4).unwrap();
    assert!(!meshing.groups.is_identity());
    let solution = same_on_one_thread_and_on_three(&scene, &meshing, &by_groups());
    assert!(solution.stats.hierarchy.unwrap().by_group);
}
