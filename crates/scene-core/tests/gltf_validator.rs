//! What `gltf_io::export` writes passes Khronos' glTF validator (npm `gltf-validator`) with
//! no error and no warning: every built-in scene, as `.gltf` and `.glb`, and a scene with
//! extra vertex attributes (`export_with`); bad attributes are refused.
//!
//! The validator runs under Node ([`scene_core::testing::gltf_validator`]). Without Node or the
//! package the test says so and passes, unless `REQUIRE_GLTF_VALIDATOR` is set (CI sets it).

use scene_core::gltf_io;
use scene_core::testing::gltf_validator as validator;
use scene_core::{Scene, builtin};

#[test]
fn exported_builtin_scenes_pass_the_khronos_validator() {
    let out = std::env::temp_dir().join(format!("gltf-validator-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let mut files = Vec::new();
    for name in [
        "cornell",
        "cornell-point",
        "primitives",
        "corridor",
        "many-boxes 20",
    ] {
        let scene = builtin::scene(name).unwrap();
        for ext in ["gltf", "glb"] {
            let path = out.join(format!("{}.{ext}", name.replace(' ', "-")));
            gltf_io::export(&scene, &path).unwrap();
            files.push(path);
        }
    }
    // Extra vertex attributes: an application-specific one and COLOR_0.
    let scene = builtin::scene("cornell").unwrap();
    let with = |s: &Scene| {
        s.meshes
            .iter()
            .enumerate()
            .flat_map(|(m, mesh)| {
                let n = mesh.positions.len();
                [
                    gltf_io::VertexAttribute {
                        name: "_RADIOSITY_TEST".into(),
                        mesh: m,
                        values: vec![glam::Vec3::new(3.0, 20.0, 0.5); n],
                    },
                    gltf_io::VertexAttribute {
                        name: "COLOR_0".into(),
                        mesh: m,
                        values: vec![glam::Vec3::new(0.25, 1.0, 0.0); n],
                    },
                ]
            })
            .collect::<Vec<_>>()
    };
    for ext in ["gltf", "glb"] {
        let path = out.join(format!("cornell-attributes.{ext}"));
        gltf_io::export_with(&scene, &path, &with(&scene)).unwrap();
        let back = gltf_io::import(&path).unwrap();
        assert_eq!(back.scene.triangle_count(), scene.triangle_count());
        files.push(path);
    }
    // An alpha-masked material (alphaMode MASK, an RGBA texture with a sampler) on a mesh
    // with vertex colours.
    let masked = masked_quad();
    for ext in ["gltf", "glb"] {
        let path = out.join(format!("masked.{ext}"));
        gltf_io::export(&masked, &path).unwrap();
        files.push(path);
    }
    let paths: Vec<&std::path::Path> = files.iter().map(|p| p.as_path()).collect();
    if validator::assert_valid(&paths) {
        eprintln!("{} files validated: 0 errors, 0 warnings", files.len());
    }
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn bad_vertex_attributes_are_refused_before_writing() {
    let scene = builtin::scene("cornell").unwrap();
    let out = std::env::temp_dir().join(format!("gltf-attr-{}.gltf", std::process::id()));
    let n = scene.meshes[0].positions.len();
    let attr = |name: &str, mesh: usize, values: Vec<glam::Vec3>| gltf_io::VertexAttribute {
        name: name.into(),
        mesh,
        values,
    };
    for (a, fault) in [
        (
            attr("RADIOSITY", 0, vec![glam::Vec3::ZERO; n]),
            "start with '_'",
        ),
        (attr("_X", 99, vec![]), "mesh 99 does not exist"),
        (
            attr("_X", 0, vec![glam::Vec3::ZERO; n + 1]),
            "values for mesh 0",
        ),
        (attr("_X", 0, vec![glam::Vec3::NAN; n]), "not finite"),
        (
            attr("COLOR_0", 0, vec![glam::Vec3::splat(2.0); n]),
            "outside [0, 1]",
        ),
    ] {
        let e = gltf_io::export_with(&scene, &out, &[a])
            .unwrap_err()
            .to_string();
        assert!(e.contains(fault), "{e}");
        assert!(!out.exists());
    }
}

/// A unit quad with texture coordinates and vertex colours (`COLOR_0`) under a 2 x 2
/// texture whose alpha is a checkerboard, masked at 0.5.
fn masked_quad() -> Scene {
    use glam::{Vec2, Vec3};
    let mut s = Scene::new("masked");
    s.textures.push(scene_core::Texture {
        name: "checker".into(),
        width: 2,
        height: 2,
        texels: vec![Vec3::new(0.2, 0.5, 0.8); 4],
        alpha: Some(vec![1.0, 0.0, 0.0, 1.0]),
        sampler: scene_core::Sampler {
            nearest: true,
            ..Default::default()
        },
    });
    s.materials.push(scene_core::Material {
        albedo_texture: Some(0),
        alpha_cutoff: Some(0.5),
        ..scene_core::Material::diffuse("leaf", Vec3::splat(0.8))
    });
    let mut m = scene_core::Mesh {
        name: "quad".into(),
        uvs: Some(Vec::new()),
        ..Default::default()
    };
    m.push_quad([Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y], 0);
    m.uvs = Some(
        m.positions
            .iter()
            .map(|p| Vec2::new(p.x, 1.0 - p.y))
            .collect(),
    );
    s.meshes.push(m);
    s.validate().unwrap();
    s
}
