//! Scene validation: one test per fault, each error names the thing at fault.

use scene_core::SceneError;
use scene_core::glam::Vec3;
use scene_core::scene::{Camera, Material, Mesh, PointLight, Scene};

fn one_quad() -> Scene {
    let mut s = Scene::new("t");
    s.materials
        .push(Material::diffuse("grey", Vec3::splat(0.5)));
    let mut m = Mesh {
        name: "floor".into(),
        ..Default::default()
    };
    m.push_quad([Vec3::ZERO, Vec3::X, Vec3::new(1., 1., 0.), Vec3::Y], 0);
    s.meshes.push(m);
    s
}

#[test]
fn valid_scene_passes_unchanged() {
    let mut s = one_quad();
    let before = s.clone();
    let report = s.validate().unwrap();
    assert_eq!(report.total_degenerate(), 0);
    assert_eq!(report.normals_recomputed, 0);
    assert_eq!(s, before);
}

#[test]
fn nan_and_inf_positions_are_errors_naming_the_mesh() {
    for bad in [f32::NAN, f32::INFINITY] {
        let mut s = one_quad();
        s.meshes[0].positions[2].y = bad;
        let e = s.validate().unwrap_err();
        assert_eq!(
            e,
            SceneError::NonFinitePosition {
                mesh: "mesh #0 'floor'".into(),
                vertex: 2
            }
        );
        assert!(e.to_string().contains("floor"));
    }
}

#[test]
fn index_out_of_range_names_mesh_and_triangle() {
    let mut s = one_quad();
    s.meshes[0].indices[1][2] = 99;
    match s.validate().unwrap_err() {
        SceneError::IndexOutOfRange {
            mesh,
            triangle,
            index,
            vertex_count,
        } => {
            assert!(mesh.contains("floor"));
            assert_eq!((triangle, index, vertex_count), (1, 99, 4));
        }
        e => panic!("{e:?}"),
    }
}

#[test]
fn material_id_out_of_range_is_an_error() {
    let mut s = one_quad();
    s.meshes[0].material_ids[0] = 5;
    assert!(matches!(
        s.validate(),
        Err(SceneError::MaterialOutOfRange {
            triangle: 0,
            material: 5,
            ..
        })
    ));
}

#[test]
fn degenerate_triangles_are_dropped_and_counted() {
    let mut s = one_quad();
    // A zero-area triangle (collinear) and one with a repeated vertex.
    s.meshes[0].push_triangle([Vec3::ZERO, Vec3::X, Vec3::X * 2.0], 0);
    s.meshes[0].indices.push([0, 0, 1]);
    s.meshes[0].material_ids.push(0);
    let report = s.validate().unwrap();
    assert_eq!(report.total_degenerate(), 2);
    assert_eq!(report.degenerate_dropped[0].0, "mesh #0 'floor'");
    assert_eq!(s.meshes[0].indices.len(), 2);
    assert_eq!(s.meshes[0].material_ids.len(), 2);
}

#[test]
fn sliver_triangles_are_kept() {
    // Thin but not degenerate: area 5e-7 of a 1 m scene is far above the threshold.
    let mut s = one_quad();
    s.meshes[0].push_triangle([Vec3::ZERO, Vec3::X, Vec3::new(0.5, 1e-6, 0.0)], 0);
    assert_eq!(s.validate().unwrap().total_degenerate(), 0);
}

#[test]
fn zero_and_nan_normals_are_recomputed_from_faces() {
    let mut s = one_quad();
    s.meshes[0].normals[0] = Vec3::ZERO;
    s.meshes[0].normals[1] = Vec3::NAN;
    let report = s.validate().unwrap();
    assert_eq!(report.normals_recomputed, 2);
    // The quad's face normal (counter-clockwise in the xy plane) is +z.
    assert!((s.meshes[0].normals[0] - Vec3::Z).length() < 1e-6);
    assert!((s.meshes[0].normals[1] - Vec3::Z).length() < 1e-6);
    // Missing normals entirely.
    let mut s = one_quad();
    s.meshes[0].normals.clear();
    assert_eq!(s.validate().unwrap().normals_recomputed, 4);
    assert!(
        s.meshes[0]
            .normals
            .iter()
            .all(|n| (*n - Vec3::Z).length() < 1e-6)
    );
}

#[test]
fn normals_that_cancel_get_a_unit_fallback_not_nan() {
    // Two coincident triangles of opposite winding: face normals cancel at shared vertices.
    let mut s = Scene::new("cancel");
    s.materials
        .push(Material::diffuse("grey", Vec3::splat(0.5)));
    let mut m = Mesh {
        name: "pair".into(),
        ..Default::default()
    };
    m.positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
    m.indices = vec![[0, 1, 2], [0, 2, 1]];
    m.material_ids = vec![0, 0];
    s.meshes.push(m);
    s.validate().unwrap();
    assert!(
        s.meshes[0]
            .normals
            .iter()
            .all(|n| n.is_finite() && (n.length() - 1.0).abs() < 1e-6)
    );
}

#[test]
fn albedo_outside_zero_one_is_an_error() {
    for albedo in [
        Vec3::new(1.0, 0.5, 0.5),
        Vec3::new(0.5, -0.1, 0.5),
        Vec3::new(0.5, f32::NAN, 0.5),
    ] {
        let mut s = one_quad();
        s.materials[0].albedo = albedo;
        match s.validate().unwrap_err() {
            SceneError::AlbedoOutOfRange { material, .. } => assert!(material.contains("grey")),
            e => panic!("{e:?}"),
        }
    }
}

#[test]
fn negative_or_nan_emission_is_an_error() {
    for e in [Vec3::new(-1.0, 0.0, 0.0), Vec3::splat(f32::INFINITY)] {
        let mut s = one_quad();
        s.materials[0].emission = e;
        assert!(matches!(
            s.validate(),
            Err(SceneError::InvalidEmission { .. })
        ));
    }
}

#[test]
fn bad_lights_and_cameras_are_errors() {
    let mut s = one_quad();
    s.point_lights.push(PointLight {
        name: "bulb".into(),
        position: Vec3::NAN,
        intensity: Vec3::ONE,
        radius: None,
        cone: None,
    });
    let e = s.validate().unwrap_err();
    assert!(e.to_string().contains("bulb"), "{e}");
    // Spot cones outside glTF's range, or without a direction, are refused naming the light
    // and the fault.
    for (inner, outer, direction, fault) in [
        (0.2, 1.7, Vec3::NEG_Y, "outer 1.7"),
        (0.5, 0.4, Vec3::NEG_Y, "inner 0.5"),
        (0.0, 0.0, Vec3::NEG_Y, "outer 0"),
        (0.1, 0.3, Vec3::ZERO, "direction"),
        (0.1, 0.3, Vec3::new(f32::NAN, -1.0, 0.0), "direction"),
    ] {
        let mut s = one_quad();
        s.point_lights.push(PointLight {
            cone: Some(scene_core::lights::SpotCone {
                direction,
                inner,
                outer,
            }),
            ..PointLight::new("spot", Vec3::Y, Vec3::ONE)
        });
        match s.validate().unwrap_err() {
            SceneError::InvalidLight { light, reason } => {
                assert_eq!(light, "point light #0 'spot'");
                assert!(reason.contains(fault), "{reason}");
            }
            other => panic!("expected InvalidLight, got {other}"),
        }
    }
    let mut s = one_quad();
    s.cameras.push(Camera {
        name: "eye".into(),
        position: Vec3::ZERO,
        target: Vec3::Y,
        up: Vec3::Y,
        fov_y: 1.0,
        aspect: 1.0,
        near: 0.1,
        far: 1.0,
    });
    // Looking straight up with +Y up is a camera: its view takes another up.
    s.validate().unwrap();
    let v = scene_core::View::from_camera(&s.cameras[0]);
    assert!(
        v.up.is_finite() && v.up.dot(v.forward).abs() < 1e-6,
        "{v:?}"
    );
    s.cameras[0].fov_y = 3.0;
    match s.validate().unwrap_err() {
        SceneError::InvalidCamera { camera, reason } => {
            assert_eq!(camera, "camera #0 'eye'");
            assert!(reason.contains("field of view"), "{reason}");
        }
        other => panic!("expected InvalidCamera, got {other}"),
    }
}

#[test]
fn mismatched_attribute_counts_are_errors() {
    let mut s = one_quad();
    s.meshes[0].uvs = Some(vec![Default::default(); 3]);
    assert!(matches!(
        s.validate(),
        Err(SceneError::AttributeCountMismatch {
            attribute: "uvs",
            ..
        })
    ));
    let mut s = one_quad();
    s.meshes[0].material_ids.pop();
    assert!(matches!(
        s.validate(),
        Err(SceneError::MaterialCountMismatch { .. })
    ));
}

#[test]
fn empty_scene_is_valid() {
    assert!(Scene::new("empty").validate().is_ok());
}

#[test]
fn degenerate_threshold_is_relative_to_scene_scale() {
    // The same quad at 1e-3 and 1e4 units keeps both triangles.
    for scale in [1e-3f32, 1e4] {
        let mut s = one_quad();
        for p in &mut s.meshes[0].positions {
            *p *= scale;
        }
        assert_eq!(s.validate().unwrap().total_degenerate(), 0, "scale {scale}");
        assert_eq!(s.meshes[0].indices.len(), 2);
    }
}

#[test]
fn huge_but_finite_values_neither_panic_nor_drop_everything() {
    // Normals with huge components are renormalised to unit length, not zeroed.
    let mut s = one_quad();
    s.meshes[0].normals[0] = Vec3::new(0.0, 0.0, 3e19);
    s.validate().unwrap();
    assert!((s.meshes[0].normals[0] - Vec3::Z).length() < 1e-6);
    // Coordinates near 1e19: the squared extent would overflow f32; triangles are kept.
    let mut s = one_quad();
    for p in &mut s.meshes[0].positions {
        *p *= 1e19;
    }
    assert_eq!(s.validate().unwrap().total_degenerate(), 0);
    // A texture sampled at huge coordinates wraps instead of overflowing.
    let tex = scene_core::Texture {
        name: "t".into(),
        width: 3,
        height: 2,
        texels: vec![Vec3::splat(0.5); 6],
        alpha: None,
        sampler: Default::default(),
    };
    let c = tex.sample(scene_core::glam::Vec2::new(3e19, -7e20));
    assert!((c - Vec3::splat(0.5)).length() < 1e-6);
}

/// Texture lookups by glTF's sampler modes, against values worked out by hand on a 2x1
/// texture [a, b] (texel centres at u = 0.25 and 0.75): nearest and bilinear, repeat,
/// clamp to edge and mirrored repeat, inside, past and before [0, 1].
#[test]
fn texture_sampling_wraps_and_filters_as_gltf_says() {
    use scene_core::glam::Vec2;
    use scene_core::{Sampler, Wrap};
    let (a, b) = (Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
    let tex = |wrap: Wrap, nearest: bool| scene_core::Texture {
        name: "ab".into(),
        width: 2,
        height: 1,
        texels: vec![a, b],
        alpha: None,
        sampler: Sampler {
            wrap_u: wrap,
            wrap_v: Wrap::Repeat,
            nearest,
        },
    };
    let mid = (a + b) * 0.5;
    let cases = [
        (
            Wrap::Repeat,
            true,
            [(0.25, a), (0.75, b), (1.25, a), (-0.25, b), (7.75, b)],
        ),
        (
            Wrap::ClampToEdge,
            true,
            [(0.25, a), (1.5, b), (-3.0, a), (0.99, b), (1e30, b)],
        ),
        (
            Wrap::MirroredRepeat,
            true,
            [(0.25, a), (1.25, b), (1.75, a), (-0.25, a), (2.25, a)],
        ),
        (
            Wrap::Repeat,
            false,
            [(0.25, a), (0.5, mid), (0.0, mid), (1.0, mid), (0.75, b)],
        ),
        (
            Wrap::ClampToEdge,
            false,
            [(0.0, a), (1.0, b), (0.5, mid), (-5.0, a), (6.0, b)],
        ),
        (
            Wrap::MirroredRepeat,
            false,
            [(0.0, a), (1.0, b), (0.5, mid), (1.5, mid), (2.0, a)],
        ),
    ];
    for (wrap, nearest, points) in cases {
        let t = tex(wrap, nearest);
        for (u, expected) in points {
            let got = t.sample(Vec2::new(u, 0.5));
            assert!(
                (got - expected).length() < 1e-5,
                "{wrap:?} nearest {nearest} at u = {u}: {got} vs {expected}"
            );
        }
    }
    assert_eq!(Wrap::MirroredRepeat.texel(-1, 2), 0);
    assert_eq!(Wrap::MirroredRepeat.texel(2, 2), 1);
    assert_eq!(Wrap::MirroredRepeat.texel(4, 2), 0);
    assert_eq!(Wrap::ClampToEdge.texel(-9, 2), 0);
}
