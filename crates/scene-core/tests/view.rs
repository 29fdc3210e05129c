//! Views: matrices, frustum-corner reconstruction (eqs. 23-24), hemicube faces.

use scene_core::glam::{Vec2, Vec3, Vec4Swizzles};
use scene_core::sampling::{Rng, uniform_sphere};
use scene_core::scene::Camera;
use scene_core::view::{HemicubeFace, View};

fn camera() -> Camera {
    Camera {
        name: "c".into(),
        position: Vec3::new(1.0, 2.0, 3.0),
        target: Vec3::new(0.2, 1.5, -1.0),
        up: Vec3::Y,
        fov_y: 0.8,
        aspect: 1.5,
        near: 0.1,
        far: 50.0,
    }
}

#[test]
fn projection_maps_near_to_zero_and_far_to_one() {
    let v = View::from_camera(&camera());
    let vp = v.view_projection();
    for (dist, z) in [(v.near, 0.0), (v.far, 1.0)] {
        let c = vp * (v.eye + v.forward * dist).extend(1.0);
        assert!((c.z / c.w - z).abs() < 1e-4, "{}", c.z / c.w);
        assert!((c.xy() / c.w).length() < 1e-4);
    }
}

#[test]
fn frustum_corners_reconstruct_projected_points() {
    let cam = camera();
    let v = View::from_camera(&cam);
    let mut rng = Rng::new(1, 0);
    for _ in 0..1000 {
        let uv = rng.next_vec2();
        let depth = 0.01 + 0.98 * rng.next_f32();
        let p = v.reconstruct_world(uv, depth);
        // Projects back to the same uv, has the same linear depth.
        let back = v.project_uv(p).unwrap();
        assert!((back - uv).abs().max_element() < 1e-4, "{back} vs {uv}");
        assert!((v.linear_depth(p) - depth).abs() < 1e-5);
        // And lies on the primary ray through uv.
        let (o, d) = v.ray(uv);
        let t = (p - o).dot(d);
        assert!((o + d * t - p).length() < 1e-4 * v.far);
    }
    // The corner vectors span the far plane: top-left, top-right and bottom-left corners.
    let c = v.frustum_corners().unwrap();
    let ty = (cam.fov_y * 0.5).tan() * cam.far;
    assert!((c.dv.length() - 2.0 * ty).abs() < 1e-3);
    assert!((c.du.length() - 2.0 * ty * cam.aspect).abs() < 1e-3);
    assert!((c.origin.dot(v.forward) - cam.far).abs() < 1e-3);
}

#[test]
fn orthographic_reconstruction_round_trips() {
    let v = View::orthographic_fit(Vec3::new(0.5, 0.0, 0.0), Vec3::new(-0.3, -1.0, 0.2), 4.0);
    let mut rng = Rng::new(2, 0);
    for _ in 0..200 {
        let uv = rng.next_vec2();
        let depth = rng.next_f32();
        let p = v.reconstruct_world(uv, depth);
        assert!((v.project_uv(p).unwrap() - uv).abs().max_element() < 1e-4);
        assert!((v.linear_depth(p) - depth).abs() < 1e-5);
    }
}

#[test]
fn hemicube_faces_cover_the_hemisphere_once() {
    let n = Vec3::new(0.2, 0.9, -0.3).normalize();
    let p = Vec3::new(1.0, -2.0, 0.5);
    let faces: Vec<View> = HemicubeFace::ALL
        .iter()
        .map(|&f| View::hemicube(p, n, f, 0.01, 10.0))
        .collect();
    let mut rng = Rng::new(3, 0);
    for _ in 0..5000 {
        let mut d = uniform_sphere(rng.next_vec2());
        if d.dot(n) < 0.0 {
            d = -d;
        }
        if d.dot(n) < 1e-3 {
            continue;
        }
        let inside = faces
            .iter()
            .filter(|v| {
                v.project_uv(p + d)
                    .is_some_and(|uv| uv.cmpge(Vec2::ZERO).all() && uv.cmple(Vec2::ONE).all())
                    && d.dot(v.forward) > 0.0
            })
            .count();
        // Directions on a shared cube edge may fall into two faces.
        assert!(
            (1..=2).contains(&inside),
            "direction {d} seen by {inside} faces"
        );
    }
    // Side faces see nothing below the surface.
    let side = &faces[1];
    let below = p + side.forward - n * 0.5;
    let uv = side.project_uv(below).unwrap();
    assert!(uv.y > 1.0, "{uv}");
    assert_eq!(HemicubeFace::Right.size(64), (64, 32));
}
