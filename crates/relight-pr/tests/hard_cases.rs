//! Hard cases of the solver, each against the furnace (a closed enclosure where every
//! surface emits `L` and reflects `rho` has radiance `L / (1 - rho)` wherever a point sees
//! only such surfaces): sliver and degenerate triangles, surfaces touching face to face
//! (1/r^2 at zero distance), albedo near and at 1. Never a NaN, never a panic.

mod common;

use common::furnace_scene;
use glam::Vec3;
use relight_pr::mesh::{MeshSettings, Meshing};
use relight_pr::relight;
use relight_pr::solver::{self, SolverSettings};
use scene_core::Scene;
use scene_core::lights::LightState;
use scene_core::ray::RayScene;
use scene_core::scene::Mesh;

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// The unit furnace box's walls but the floor (counter-clockwise seen from inside).
fn walls(mesh: &mut Mesh) {
    for q in &common::unit_box_faces()[1..] {
        mesh.push_quad(*q, 0);
    }
}

/// The furnace box, floor included.
fn enclosure() -> Mesh {
    let mut mesh = Mesh::default();
    walls(&mut mesh);
    mesh.push_quad(
        [v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 1.), v(1., 0., 0.)],
        0,
    );
    mesh
}

/// A box resting on the floor and a slab pressed against a wall (corners).
const SOLIDS: [(Vec3, Vec3); 2] = [
    (Vec3::new(0.3, 0.0, 0.3), Vec3::new(0.6, 0.25, 0.6)),
    (Vec3::new(0.0, 0.5, 0.2), Vec3::new(0.1, 0.9, 0.7)),
];

/// Whether an element (just off its surface at `x`) faces out of the enclosure or into
/// one of the solids: no light reaches it.
fn pressed_or_outside(x: Vec3) -> bool {
    let outside = !(x.cmpge(Vec3::ZERO).all() && x.cmple(Vec3::ONE).all());
    outside
        || SOLIDS
            .iter()
            .any(|(lo, hi)| x.cmpgt(*lo).all() && x.cmplt(*hi).all())
}

fn solve(scene: &Scene, elements: usize, settings: &SolverSettings) -> (Meshing, Vec<Vec3>) {
    solve_meshed(scene, &MeshSettings::elements(elements), settings)
}

fn solve_meshed(
    scene: &Scene,
    mesh: &MeshSettings,
    settings: &SolverSettings,
) -> (Meshing, Vec<Vec3>) {
    let meshing = Meshing::new(scene, mesh, 1).unwrap();
    let rays = RayScene::build(scene);
    let s = solver::solve(scene, &meshing, &rays, settings, &mut |_| {}).unwrap();
    let out = relight::radiance(&meshing, &s, &LightState::default());
    (meshing, out)
}

fn ambient() -> SolverSettings {
    SolverSettings {
        max_unshot: 1e-2,
        visibility_samples: 4,
        ..Default::default()
    }
}

#[test]
fn slivers_and_degenerate_triangles_keep_the_furnace() {
    // The floor as a fan around a point 1e-6 from a corner: two slivers of aspect ~1e6 and
    // two large triangles; plus a zero-area triangle and one with a NaN-free but collinear
    // corner, both skipped.
    let mut mesh = Mesh::default();
    walls(&mut mesh);
    let c = v(1e-6, 0.0, 1e-6);
    for (a, b) in [
        (v(0., 0., 0.), v(0., 0., 1.)),
        (v(0., 0., 1.), v(1., 0., 1.)),
        (v(1., 0., 1.), v(1., 0., 0.)),
        (v(1., 0., 0.), v(0., 0., 0.)),
    ] {
        mesh.push_triangle([c, a, b], 0);
    }
    mesh.push_triangle([v(0.5, 0.0, 0.5); 3], 0);
    mesh.push_triangle([v(0.2, 0.0, 0.2), v(0.4, 0.0, 0.4), v(0.6, 0.0, 0.6)], 0);
    let rho = 0.5;
    let scene = furnace_scene(rho, mesh);
    // Unmerged: merging coplanar triangles would remove the fan's centre and its slivers.
    let unmerged = MeshSettings {
        merge_coplanar: false,
        ..MeshSettings::elements(384)
    };
    let (meshing, out) = solve_meshed(&scene, &unmerged, &ambient());
    assert_eq!(meshing.skipped_triangles, 2);
    let expect = 1.0 / (1.0 - rho);
    let slivers: Vec<usize> = (0..meshing.elements.len())
        .filter(|&j| meshing.elements[j].area < 1e-5)
        .collect();
    assert!(!slivers.is_empty(), "the fan makes sliver elements");
    for (j, c) in out.iter().enumerate() {
        assert!(c.is_finite(), "element {j}: {c}");
        assert!(
            (c.x - expect).abs() <= 0.02 * expect,
            "element {j} (area {:.1e}): {} against {expect}",
            meshing.elements[j].area,
            c.x
        );
    }
}

#[test]
fn surfaces_touching_face_to_face_stay_finite() {
    // A box resting on the floor and a slab pressed against a wall: faces at zero distance
    // from the floor and the wall, facing them (a 1/r^2 kernel would blow up there).
    let mut mesh = enclosure();
    let solids = SOLIDS;
    for (lo, hi) in solids {
        mesh.push_box((lo + hi) * 0.5, (hi - lo) * 0.5, 0.0, 0);
    }
    let rho = 0.5;
    let scene = furnace_scene(rho, mesh);
    let settings = SolverSettings {
        visibility_samples: 64,
        ..ambient()
    };
    let (meshing, out) = solve(&scene, 768, &settings);
    let expect = 1.0 / (1.0 - rho);
    let mut hidden = 0;
    let (mut sum, mut area) = (0.0f32, 0.0f32);
    for (j, (e, c)) in meshing.elements.iter().zip(&out).enumerate() {
        assert!(c.is_finite(), "element {j}: {c}");
        // Hidden: pressed against another surface (the floor under the box, the wall
        // behind the slab), or facing out of the enclosure through it (the box's bottom):
        // no light reaches it; only its own emission.
        let x = e.centroid + e.normal * 1e-4;
        if pressed_or_outside(x) {
            hidden += 1;
            assert!(
                c.x >= 1.0 / std::f32::consts::PI && c.x <= expect * 1.02,
                "{j}: {c}"
            );
        } else {
            // Measured: the worst elements, 8 % low, are on the ceiling right above the
            // slab's top, 0.1 below it, next to the wall the slab is pressed against (not
            // explained yet; docs/relight-pr.md); the mean is within 0.5 %.
            assert!(
                (c.x - expect).abs() <= 0.1 * expect,
                "visible element {j} at {}: {} against {expect}",
                e.centroid,
                c.x
            );
            sum += c.x * e.area;
            area += e.area;
        }
    }
    let mean = sum / area;
    eprintln!("visible mean {mean} against {expect}");
    assert!(
        (mean - expect).abs() <= 0.01 * expect,
        "visible mean {mean}"
    );
    assert!(hidden > 0, "some elements are pressed against others");
}

#[test]
fn albedo_near_and_at_one() {
    let mut mesh = Mesh::default();
    walls(&mut mesh);
    mesh.push_quad(
        [v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 1.), v(1., 0., 0.)],
        0,
    );
    // 0.99: slow (about 100 reflections), the ambient term carries what is left.
    let scene = furnace_scene(0.99, mesh.clone());
    let settings = SolverSettings {
        max_shots: 3000,
        ..ambient()
    };
    let (meshing, out) = solve(&scene, 96, &settings);
    let expect = 1.0 / (1.0 - 0.99);
    let total: f32 = meshing.elements.iter().map(|e| e.area).sum();
    let mean = out
        .iter()
        .zip(&meshing.elements)
        .map(|(c, e)| c.x * e.area)
        .sum::<f32>()
        / total;
    assert!((mean - expect).abs() <= 0.01 * expect, "rho 0.99: {mean}");
    // 1 (refused by Scene::validate, so only an unvalidated scene gets here): no
    // convergence; the shot cap stops it and every value stays finite.
    let mut scene = furnace_scene(1.0, mesh);
    let meshing = Meshing::new(&scene, &MeshSettings::elements(96), 1).unwrap();
    let rays = RayScene::build(&scene);
    let settings = SolverSettings {
        max_shots: 500,
        ..ambient()
    };
    let s = solver::solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap();
    assert_eq!(s.stats.shots, 500);
    assert!(s.stats.unshot_fraction > 0.5, "{}", s.stats.unshot_fraction);
    let out = relight::radiance(&meshing, &s, &LightState::default());
    assert!(out.iter().all(|c| c.is_finite() && c.min_element() > 0.0));
    assert!(scene.validate().is_err(), "validation refuses albedo 1");
}

/// Surfaces touching face to face in the hierarchical solve at the element budget: the
/// box on the floor and the slab against the wall, their faces cut into 2 cm quads
/// (merging off) and meshed at a target of 48 elements, so that they are clusters far
/// below the budget, touching the floor and the wall (the close cluster links' case).
/// Every element stays finite and the visible ones keep the furnace.
#[test]
fn touching_clusters_stay_finite_and_keep_the_furnace() {
    let mut mesh = enclosure();
    let solids = SOLIDS;
    // Each solid's six faces as grids of quads about 2 cm across, facing out.
    for (lo, hi) in solids {
        let (c, h) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let n = Vec3::AXES[axis] * sign;
                let (u, w) = (Vec3::AXES[(axis + 1) % 3], Vec3::AXES[(axis + 2) % 3]);
                let (hu, hw) = (h[(axis + 1) % 3], h[(axis + 2) % 3]);
                let (nu, nw) = ((hu / 0.01).ceil() as usize, (hw / 0.01).ceil() as usize);
                let at = |i: usize, j: usize| {
                    c + n * h[axis]
                        + u * hu * (2.0 * i as f32 / nu as f32 - 1.0)
                        + w * hw * (2.0 * j as f32 / nw as f32 - 1.0)
                };
                for i in 0..nu {
                    for j in 0..nw {
                        let q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                        // Counter-clockwise seen from outside (along n).
                        let flip = (q[1] - q[0]).cross(q[3] - q[0]).dot(n) < 0.0;
                        mesh.push_quad(if flip { [q[0], q[3], q[2], q[1]] } else { q }, 0);
                    }
                }
            }
        }
    }
    let rho = 0.5;
    let scene = furnace_scene(rho, mesh);
    let settings = SolverSettings {
        hierarchy: Some(relight_pr::HierarchySettings::default()),
        hierarchy_above: 0,
        ..Default::default()
    };
    let (meshing, out) = solve_meshed(
        &scene,
        &MeshSettings {
            merge_coplanar: false,
            // The solve's clusters element by element (5 960 mesh elements; held to the
            // budget of 48, whole slabs would share one value).
            hold_budget: false,
            ..MeshSettings::elements(48)
        },
        &settings,
    );
    let expect = 1.0 / (1.0 - rho);
    let (mut sum, mut area, mut worst) = (0.0f32, 0.0f32, 0.0f32);
    for (j, (e, c)) in meshing.elements.iter().zip(&out).enumerate() {
        assert!(c.is_finite() && c.min_element() >= 0.0, "element {j}: {c}");
        if e.hidden {
            continue;
        }
        let x = e.centroid + e.normal * 1e-4;
        if !pressed_or_outside(x) {
            worst = worst.max((c.x - expect).abs() / expect);
            sum += c.x * e.area;
            area += e.area;
        }
    }
    let mean = sum / area;
    eprintln!(
        "{} elements: visible mean {mean} against {expect}, worst element {worst}",
        meshing.elements.len()
    );
    assert!(
        (mean - expect).abs() <= 0.01 * expect,
        "visible mean {mean}"
    );
    // The progressive solve's bound on this scene (10 %). Measured 7.2 % (4.7 % with
    // `cluster_radius: 0`); 15.6 % when a slab's face and the wall it stands against,
    // their cone a rounding error wide, were kept together as furniture.
    assert!(worst <= 0.1, "worst visible element {worst}");
}
