//! No light leaks through a thin wall: two rooms whose floor, ceiling, back and front
//! walls run on under a wall 1% of the room thick (the same planes with the same normals
//! on both sides, the hardest case for a representation of planes), one room lit. Every
//! splat mode, the default exact one included; a control without the wall shows that the
//! measurement sees light where there is some.

mod common;

use std::sync::Arc;

use common::mean;
use glam::Vec3;
use ibrr_ldc::{IbrrSettings, IbrrTechnique, Splat};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::{Camera, FrameRequest, Material, Mesh, PointLight, Scene, Technique};

fn two_rooms(with_wall: bool) -> Scene {
    let mut s = Scene::new("two rooms");
    s.materials
        .push(Material::diffuse("white", Vec3::splat(0.8)));
    let mut m = Mesh {
        name: "rooms".into(),
        ..Default::default()
    };
    let (x1, wall) = (2.01f32, 0.01f32);
    let q = |m: &mut Mesh, c: [[f32; 3]; 4]| m.push_quad(c.map(Vec3::from), 0);
    q(
        &mut m,
        [
            [0.0, 0.0, 0.0],
            [x1, 0.0, 0.0],
            [x1, 0.0, 1.0],
            [0.0, 0.0, 1.0],
        ],
    ); // floor
    q(
        &mut m,
        [
            [0.0, 1.0, 0.0],
            [0.0, 1.0, 1.0],
            [x1, 1.0, 1.0],
            [x1, 1.0, 0.0],
        ],
    ); // ceiling
    q(
        &mut m,
        [
            [0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [x1, 1.0, 0.0],
            [x1, 0.0, 0.0],
        ],
    ); // back
    q(
        &mut m,
        [
            [0.0, 0.0, 1.0],
            [x1, 0.0, 1.0],
            [x1, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ],
    ); // front
    q(
        &mut m,
        [
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
            [0.0, 1.0, 0.0],
        ],
    ); // left
    q(
        &mut m,
        [
            [x1, 0.0, 0.0],
            [x1, 1.0, 0.0],
            [x1, 1.0, 1.0],
            [x1, 0.0, 1.0],
        ],
    ); // right
    for x in [1.0, 1.0 + wall].into_iter().filter(|_| with_wall) {
        q(
            &mut m,
            [[x, 0.0, 0.0], [x, 1.0, 0.0], [x, 1.0, 1.0], [x, 0.0, 1.0]],
        ); // the wall's faces
    }
    s.meshes.push(m);
    s.point_lights.push(PointLight {
        name: "lamp".into(),
        // Close to the wall, where a leak would show first.
        position: Vec3::new(0.9, 0.5, 0.5),
        intensity: Vec3::ONE,
        radius: None,
        cone: None,
    });
    let cam = |x: f32, tx: f32| Camera {
        name: String::new(),
        position: Vec3::new(x, 0.5, 0.5),
        target: Vec3::new(tx, 0.45, 0.5),
        up: Vec3::Y,
        fov_y: 1.4,
        aspect: 1.0,
        near: 0.01,
        far: 10.0,
    };
    s.cameras.push(cam(0.05, 1.0)); // lit room, facing the wall
    s.cameras.push(cam(1.96, 1.0)); // dark room, facing the wall
    s.validate().unwrap();
    s
}

/// The lit and the far room's mean under `splat`.
fn means(scene: &Arc<Scene>, splat: Splat) -> (f64, f64) {
    let settings = IbrrSettings {
        target_error: 0.0,
        resolution: 128,
        irpls: 64,
        splat,
        ..Default::default()
    };
    let mut t = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    t.prepare(scene.clone()).unwrap();
    let lit = t
        .render(&FrameRequest::camera(&scene.cameras[0], 64, 64))
        .unwrap();
    let dark = t
        .render(&FrameRequest::camera(&scene.cameras[1], 64, 64))
        .unwrap();
    (mean(&lit), mean(&dark))
}

#[test]
fn the_dark_room_stays_dark() {
    let scene = Arc::new(two_rooms(true));
    for splat in [Splat::Nearest, Splat::Gaussian, Splat::Exact] {
        let (l, d) = means(&scene, splat);
        println!(
            "{splat:?}: lit room mean {l:.4e}, dark room mean {d:.4e}, ratio {:.2e}",
            d / l
        );
        assert!(l > 0.0);
        // The docs say exactly 0; 1e-6 leaves room for nothing but rounding.
        assert!(
            d <= 1e-6 * l,
            "{splat:?}: the dark room receives {:.2e} of the lit room's mean",
            d / l
        );
    }
    // The control: without the wall the far half is lit, and the same measurement says so.
    let open = Arc::new(two_rooms(false));
    for splat in [Splat::Nearest, Splat::Gaussian, Splat::Exact] {
        let (l, d) = means(&open, splat);
        println!("{splat:?} without the wall: near {l:.4e}, far {d:.4e}");
        assert!(
            d > 0.05 * l,
            "{splat:?}: the far half reads {:.2e} of the near",
            d / l
        );
    }
}
