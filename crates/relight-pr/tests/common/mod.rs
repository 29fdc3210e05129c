//! Helpers shared by relight-pr's integration tests (each test file uses some of them).
#![allow(dead_code)]

use glam::Vec3;
use scene_core::Scene;
use scene_core::scene::{Material, Mesh};

/// A furnace: `mesh` with one material of albedo `rho` that emits 1 everywhere.
pub fn furnace_scene(rho: f32, mesh: Mesh) -> Scene {
    let mut scene = Scene::new("furnace");
    scene.materials.push(Material {
        name: "m".into(),
        albedo: Vec3::splat(rho),
        albedo_texture: None,
        emission: Vec3::ONE,
        alpha_cutoff: None,
        emission_texture: None,
    });
    scene.meshes.push(mesh);
    scene
}

/// The largest difference between `a` and `b` over the largest value of `b`.
pub fn max_relative(a: &[Vec3], b: &[Vec3]) -> f32 {
    let peak = b.iter().map(|v| v.max_element()).fold(0.0f32, f32::max);
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).abs().max_element())
        .fold(0.0f32, f32::max)
        / peak
}

/// The faces of the unit box `[0, 1]^3` facing in (counter-clockwise seen from inside):
/// the floor first, then the ceiling and the four walls.
pub fn unit_box_faces() -> [[Vec3; 4]; 6] {
    let v = Vec3::new;
    [
        [v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 1.), v(1., 0., 0.)],
        [v(0., 1., 0.), v(1., 1., 0.), v(1., 1., 1.), v(0., 1., 1.)],
        [v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)],
        [v(0., 0., 1.), v(0., 1., 1.), v(1., 1., 1.), v(1., 0., 1.)],
        [v(0., 0., 0.), v(0., 1., 0.), v(0., 1., 1.), v(0., 0., 1.)],
        [v(1., 0., 0.), v(1., 0., 1.), v(1., 1., 1.), v(1., 1., 0.)],
    ]
}

/// The unit box `[0, 1]^3` as six quads facing in.
pub fn unit_box() -> Mesh {
    let mut mesh = Mesh::default();
    for q in unit_box_faces() {
        mesh.push_quad(q, 0);
    }
    mesh
}

/// The unit box `[0, 1]^3` facing in, each face cut into `g` x `g` quads: a file's small
/// triangles (`2 g^2` a face).
pub fn gridded_unit_box(g: usize) -> Mesh {
    let mut mesh = Mesh::default();
    for q in unit_box_faces() {
        let at = |i: usize, j: usize| {
            let (u, v) = (i as f32 / g as f32, j as f32 / g as f32);
            q[0] + (q[1] - q[0]) * u + (q[3] - q[0]) * v
        };
        for a in 0..g {
            for b in 0..g {
                mesh.push_quad([at(a, b), at(a + 1, b), at(a + 1, b + 1), at(a, b + 1)], 0);
            }
        }
    }
    mesh
}
