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

/// The projections engines use, built by glam's Direct3D-range (depth in [0, 1]) helpers
/// (Bevy's camera is `perspective_infinite_reverse_rh`, the same matrix): each gives the same view as the standard finite one,
/// a far plane at infinity becomes `near x DEPTH_RANGE_MAX`, and the convention turns the
/// depth each matrix writes back into the distance it was written at.
#[test]
fn reverse_z_and_infinite_projections_are_read() {
    use glam::Vec4;
    use glam::camera::rh::proj::directx as dx;
    use scene_core::scene::DEPTH_RANGE_MAX;
    let (fov, aspect, near, far) = (0.9f32, 1.6f32, 0.05f32, 80.0f32);
    let eye = glam::Vec3::new(1.0, 2.0, 3.0);
    let m =
        glam::camera::rh::view::look_at_mat4(eye, glam::Vec3::new(0.5, 1.0, -2.0), glam::Vec3::Y);
    let standard = View::from_matrices(m, dx::perspective(fov, aspect, near, far)).unwrap();
    let cases = [
        (
            "standard",
            dx::perspective(fov, aspect, near, far),
            false,
            false,
        ),
        (
            "reverse",
            dx::perspective(fov, aspect, far, near),
            true,
            false,
        ),
        (
            "infinite",
            dx::perspective_infinite(fov, aspect, near),
            false,
            true,
        ),
        (
            "infinite reverse (Bevy)",
            dx::perspective_infinite_reverse(fov, aspect, near),
            true,
            true,
        ),
    ];
    for (name, p, reverse, infinite) in cases {
        let (v, depth) = View::from_host_matrices(m, p).unwrap();
        assert_eq!(
            (depth.reverse, depth.infinite),
            (reverse, infinite),
            "{name}"
        );
        assert!(!depth.orthographic, "{name}");
        assert!(v.eye.abs_diff_eq(standard.eye, 1e-5), "{name}");
        assert!(v.forward.abs_diff_eq(standard.forward, 1e-6), "{name}");
        assert!(v.up.abs_diff_eq(standard.up, 1e-6), "{name}");
        assert_eq!(v.projection, standard.projection, "{name}");
        assert!(
            (v.near - near).abs() < 1e-6 * near,
            "{name}: near {}",
            v.near
        );
        let want_far = if infinite {
            near * DEPTH_RANGE_MAX
        } else {
            far
        };
        assert!(
            (v.far - want_far).abs() < 1e-4 * want_far,
            "{name}: far {}",
            v.far
        );
        // The depth the matrix writes at distance t, read back.
        for t in [near, 0.3, 1.0, 7.5, 79.0] {
            let clip = p * Vec4::new(0.0, 0.0, -t, 1.0);
            let d = clip.z / clip.w;
            assert!((0.0..=1.0).contains(&d), "{name}: depth {d} at {t}");
            assert!(
                (depth.depth(t) - d).abs() < 1e-6,
                "{name}: {} vs {d}",
                depth.depth(t)
            );
            let back = depth.distance(d);
            // Reversed depth keeps its precision far away; standard depth loses it as 1 / d.
            let tol = if reverse { 1e-5 } else { 2e-3 };
            assert!((back - t).abs() < tol * t, "{name}: {back} at {t}");
            assert!(
                (depth.linear_depth(d) - t / v.far).abs() < tol * t / v.far,
                "{name}"
            );
        }
        // The far plane: a point at infinity reads as the end of the toolkit's range.
        if infinite {
            let d_inf = if reverse { 0.0 } else { 1.0 };
            assert_eq!(depth.linear_depth(d_inf), 1.0, "{name}");
        }
    }
    // Orthographic, standard and reversed.
    let o = dx::orthographic(-2.0, 2.0, -1.0, 1.0, 0.5, 30.0);
    let o_rev = dx::orthographic(-2.0, 2.0, -1.0, 1.0, 30.0, 0.5);
    let (a, da) = View::from_host_matrices(m, o).unwrap();
    let (b, db) = View::from_host_matrices(m, o_rev).unwrap();
    assert!(da.orthographic && !da.reverse && db.reverse);
    assert_eq!(a.projection, b.projection);
    assert!((a.near - 0.5).abs() < 1e-5 && (b.near - 0.5).abs() < 1e-5);
    assert!((a.far - 30.0).abs() < 1e-3 && (b.far - 30.0).abs() < 1e-3);
    assert!((db.distance(db.depth(12.0)) - 12.0).abs() < 1e-4);
    // What cannot be read is refused, naming it.
    let mut flat = dx::perspective_infinite_reverse(fov, aspect, near);
    flat.w_axis.z = 0.0;
    let e = View::from_matrices(m, flat).unwrap_err().to_string();
    assert!(e.contains("does not vary"), "{e}");
    let mut ortho_inf = o;
    ortho_inf.z_axis.z = 0.0;
    let e = View::from_matrices(m, ortho_inf).unwrap_err().to_string();
    assert!(e.contains("no far plane"), "{e}");
    // Near behind the eye (a perspective whose depth is 0 at a negative distance).
    let e = View::from_matrices(m, dx::perspective(fov, aspect, -1.0, far))
        .unwrap_err()
        .to_string();
    assert!(e.contains("near"), "{e}");
}
