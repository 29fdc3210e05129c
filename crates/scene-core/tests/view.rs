//! Views: matrices, frustum-corner reconstruction (eqs. 23-24), hemicube faces.

use scene_core::glam::{Vec2, Vec3, Vec4Swizzles};
use scene_core::sampling::{Rng, uniform_sphere};
use scene_core::scene::Camera;
use scene_core::view::{HemicubeFace, Projection, View};

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

/// An engine's matrices give back the view they came from: a camera, an off-axis hemicube
/// side face and an orthographic shadow view, each through glam-built matrices as an engine
/// would hand them over.
#[test]
fn views_round_trip_through_engine_matrices() {
    let scene = scene_core::builtin::scene("cornell").unwrap();
    let camera = View::from_camera(&scene.cameras[0]);
    let side = View::hemicube(
        glam::Vec3::new(0.3, 0.001, 0.25),
        glam::Vec3::new(0.2, 1.0, -0.1).normalize(),
        HemicubeFace::Left,
        1e-3,
        2.0,
    );
    let ortho = View::orthographic_fit(
        glam::Vec3::splat(0.3),
        glam::Vec3::new(-1.0, -2.0, 0.5),
        0.6,
    );
    for (name, v) in [
        ("camera", camera),
        ("hemicube side", side),
        ("ortho", ortho),
    ] {
        let back = View::from_matrices(v.view_matrix(), v.projection_matrix()).unwrap();
        assert!(
            back.eye.abs_diff_eq(v.eye, 1e-5),
            "{name}: eye {} vs {}",
            back.eye,
            v.eye
        );
        assert!(back.forward.abs_diff_eq(v.forward, 1e-5), "{name}: forward");
        assert!(back.up.abs_diff_eq(v.up, 1e-5), "{name}: up");
        assert!(
            (back.near - v.near).abs() < 1e-4 * v.near.max(1e-3),
            "{name}: near {}",
            back.near
        );
        // The matrix holds far only to about f32 epsilon times far / near (1 + m22 is a
        // difference of nearly equal numbers).
        let far_tol = 4.0 * f32::EPSILON * v.far / v.near.max(1e-3) * v.far;
        assert!(
            (back.far - v.far).abs() <= far_tol.max(1e-5 * v.far),
            "{name}: far {}",
            back.far
        );
        let (a, b) = match (back.projection, v.projection) {
            (
                Projection::Perspective {
                    left,
                    right,
                    bottom,
                    top,
                },
                Projection::Perspective {
                    left: l,
                    right: r,
                    bottom: bo,
                    top: t,
                },
            )
            | (
                Projection::Orthographic {
                    left,
                    right,
                    bottom,
                    top,
                },
                Projection::Orthographic {
                    left: l,
                    right: r,
                    bottom: bo,
                    top: t,
                },
            ) => ([left, right, bottom, top], [l, r, bo, t]),
            _ => panic!("{name}: projection kind changed"),
        };
        for (x, y) in a.iter().zip(b) {
            assert!(
                (x - y).abs() < 1e-4 * y.abs().max(1.0),
                "{name}: {a:?} vs {b:?}"
            );
        }
    }
    // The textbook look-at and perspective matrices (right-handed, depth in [0, 1]) as an
    // engine builds them, and the camera they stand for.
    let eye = glam::Vec3::new(1.0, 2.0, 3.0);
    let f = (-eye).normalize();
    let side = f.cross(glam::Vec3::Y).normalize();
    let up = side.cross(f);
    let m = glam::Mat4::from_cols(
        glam::Vec4::new(side.x, up.x, -f.x, 0.0),
        glam::Vec4::new(side.y, up.y, -f.y, 0.0),
        glam::Vec4::new(side.z, up.z, -f.z, 0.0),
        glam::Vec4::new(-side.dot(eye), -up.dot(eye), f.dot(eye), 1.0),
    );
    let (fov, aspect, near, far) = (0.8f32, 1.5f32, 0.1f32, 50.0f32);
    let h = 1.0 / (0.5 * fov).tan();
    let p = glam::Mat4::from_cols(
        glam::Vec4::new(h / aspect, 0.0, 0.0, 0.0),
        glam::Vec4::new(0.0, h, 0.0, 0.0),
        glam::Vec4::new(0.0, 0.0, far / (near - far), -1.0),
        glam::Vec4::new(0.0, 0.0, near * far / (near - far), 0.0),
    );
    let v = View::from_matrices(m, p).unwrap();
    let cam = v.to_camera("engine").unwrap();
    assert!((cam.fov_y - 0.8).abs() < 1e-5 && (cam.aspect - 1.5).abs() < 1e-5);
    assert!((cam.near - 0.1).abs() < 1e-5 && (cam.far - 50.0).abs() < 1e-2);
    assert!(cam.position.abs_diff_eq(eye, 1e-5));
    assert!(v.forward.abs_diff_eq(-eye.normalize(), 1e-5));
    // What is not a view is refused, naming why.
    let scaled = m * glam::Mat4::from_scale(glam::Vec3::splat(2.0));
    let e = View::from_matrices(scaled, p).unwrap_err().to_string();
    assert!(e.contains("rotation"), "{e}");
    assert!(View::from_matrices(m, glam::Mat4::IDENTITY * 0.0).is_err());
}
