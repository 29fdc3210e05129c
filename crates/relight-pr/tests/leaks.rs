//! No light leaks: two closed rooms side by side, sharing a wall 1 % of the room thick, a
//! point light in one. The other room stays dark (below 1e-4 of the lit room's mean) with
//! both form-factor methods, the ambient term on.

use std::sync::Arc;

use glam::Vec3;
use relight_pr::{FormFactorMethod, MeshSettings, Meshing, SolverSettings, relight, solve_with};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::lights::LightState;
use scene_core::ray::RayScene;
use scene_core::{Material, Mesh, PointLight, Scene};

/// A closed box `[lo, hi]` with inward faces (counter-clockwise seen from inside).
fn room(mesh: &mut Mesh, lo: Vec3, hi: Vec3) {
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let (a, b) = (lo, hi);
    for q in [
        [
            v(a.x, a.y, a.z),
            v(a.x, a.y, b.z),
            v(b.x, a.y, b.z),
            v(b.x, a.y, a.z),
        ],
        [
            v(a.x, b.y, a.z),
            v(b.x, b.y, a.z),
            v(b.x, b.y, b.z),
            v(a.x, b.y, b.z),
        ],
        [
            v(a.x, a.y, a.z),
            v(b.x, a.y, a.z),
            v(b.x, b.y, a.z),
            v(a.x, b.y, a.z),
        ],
        [
            v(a.x, a.y, b.z),
            v(a.x, b.y, b.z),
            v(b.x, b.y, b.z),
            v(b.x, a.y, b.z),
        ],
        [
            v(a.x, a.y, a.z),
            v(a.x, b.y, a.z),
            v(a.x, b.y, b.z),
            v(a.x, a.y, b.z),
        ],
        [
            v(b.x, a.y, a.z),
            v(b.x, a.y, b.z),
            v(b.x, b.y, b.z),
            v(b.x, b.y, a.z),
        ],
    ] {
        mesh.push_quad(q, 0);
    }
}

fn two_rooms() -> Scene {
    let mut scene = Scene::new("two rooms");
    scene.materials.push(Material {
        name: "white".into(),
        albedo: Vec3::splat(0.8),
        albedo_texture: None,
        emission: Vec3::ZERO,
    });
    let mut mesh = Mesh {
        name: "rooms".into(),
        ..Default::default()
    };
    room(&mut mesh, Vec3::ZERO, Vec3::ONE);
    // The wall between them: x from 1 to 1.01.
    room(
        &mut mesh,
        Vec3::new(1.01, 0.0, 0.0),
        Vec3::new(2.01, 1.0, 1.0),
    );
    scene.meshes.push(mesh);
    scene.point_lights.push(PointLight {
        name: "lamp".into(),
        // Close to the shared wall, where a leak would show first.
        position: Vec3::new(0.9, 0.5, 0.5),
        intensity: Vec3::splat(1.0),
        radius: None,
    });
    scene
}

#[test]
fn the_dark_room_stays_dark_with_both_form_factor_methods() {
    let scene = Arc::new(two_rooms());
    let meshing = Meshing::new(&scene, &MeshSettings::elements(768), 1).unwrap();
    let rays = RayScene::build(&scene);
    for method in [
        FormFactorMethod::Rays,
        FormFactorMethod::Hemicube { resolution: 64 },
    ] {
        let settings = SolverSettings {
            form_factors: method,
            max_unshot: 1e-2,
            visibility_samples: 8,
            ..Default::default()
        };
        let mut renderer = RayCastRenderer::new();
        let solution = solve_with(
            &scene,
            &meshing,
            &rays,
            Some(&mut renderer),
            &settings,
            &mut |_| {},
        )
        .unwrap();
        assert!(
            solution.ambient[0].max_element() > 0.0,
            "the ambient term is on"
        );
        let radiance = relight::radiance(&meshing, &solution, &LightState::default());
        let (mut lit, mut dark) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
        for (e, r) in meshing.elements.iter().zip(&radiance) {
            let side = if e.centroid.x < 1.005 {
                &mut lit
            } else {
                &mut dark
            };
            side.0 += (r.element_sum() * e.area) as f64;
            side.1 += e.area as f64;
        }
        let (lit, dark) = (lit.0 / lit.1, dark.0 / dark.1);
        eprintln!("{method:?}: lit room mean {lit:.4e}, dark room mean {dark:.3e}");
        assert!(lit > 0.0);
        assert!(dark < 1e-4 * lit, "{method:?}: {dark} against {lit}");
    }
}
