//! Tests of glTF import and export, and of their round trip.

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use base64::Engine as _;
use glam::{Quat, Vec2, Vec3};
use serde_json::{Value, json};

use super::export::{BinWriter, GL_ELEMENT_ARRAY_BUFFER, GL_UNSIGNED_INT};
use super::*;
use crate::error::GltfError;
use crate::scene::{Camera, DirectionalLight, Material, Mesh, PointLight, Scene, Texture};

/// A unique path in the temporary directory.
fn temp_file(name: &str) -> std::path::PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!(
        "scene_core_gltf_io_{}_{n}_{name}",
        std::process::id()
    ))
}

fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    (a - b).abs().max_element() <= tol * a.abs().max_element().max(1.0)
}

#[track_caller]
fn assert_close(a: Vec3, b: Vec3, tol: f32, what: &str) {
    assert!(close(a, b, tol), "{what}: {a} vs {b}");
}

/// Two meshes with material runs 0,0,1,1,0,0 / 2,3; a textured, an emissive (> 1) and a
/// dim emissive material; point lights with and without radius; a sun; two cameras.
fn test_scene() -> Scene {
    let mut s = Scene::new("test");
    s.materials = vec![
        Material::diffuse("white", Vec3::new(0.7, 0.7, 0.7)),
        Material {
            albedo_texture: Some(0),
            ..Material::diffuse("checker", Vec3::new(0.9, 0.8, 0.5))
        },
        Material::emissive("lamp", Vec3::splat(0.78), Vec3::new(17.0, 12.0, 4.0)),
        Material::emissive("dim", Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.5, 0.25, 0.0)),
    ];
    s.textures = vec![Texture {
        name: "checker".into(),
        width: 2,
        height: 2,
        texels: vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(0.2, 0.4, 0.6),
            Vec3::new(0.05, 0.5, 0.9),
        ],
        alpha: None,
        // Not glTF's default sampler, so the round trips carry one.
        sampler: crate::scene::Sampler {
            wrap_u: crate::scene::Wrap::ClampToEdge,
            wrap_v: crate::scene::Wrap::MirroredRepeat,
            nearest: true,
        },
    }];
    let mut room = Mesh {
        name: "room".into(),
        uvs: Some(Vec::new()),
        ..Default::default()
    };
    let q = |x: f32| {
        [
            Vec3::new(x, 0.0, 0.0),
            Vec3::new(x + 1.0, 0.0, 0.0),
            Vec3::new(x + 1.0, 1.0, 0.5),
            Vec3::new(x, 1.0, 0.5),
        ]
    };
    room.push_quad(q(0.0), 0);
    room.push_quad(q(1.0), 1);
    room.push_quad(q(2.0), 0);
    // Unnamed: names must survive the round trip even when empty.
    let mut lamp = Mesh::default();
    lamp.push_triangle(
        [
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(0.0, 2.0, 1.0),
            Vec3::new(1.0, 2.0, 0.0),
        ],
        2,
    );
    lamp.push_triangle(
        [
            Vec3::new(0.0, 3.0, 0.0),
            Vec3::new(1.0, 3.0, 1.0),
            Vec3::new(1.0, 3.0, 0.0),
        ],
        3,
    );
    s.meshes = vec![room, lamp];
    s.point_lights = vec![
        PointLight {
            name: "bulb".into(),
            position: Vec3::new(0.5, 1.5, 0.5),
            intensity: Vec3::new(3.0, 2.0, 1.0),
            radius: Some(4.0),
            cone: None,
        },
        PointLight {
            name: "candle".into(),
            position: Vec3::new(-1.0, 0.25, 2.0),
            intensity: Vec3::new(0.5, 0.5, 0.25),
            radius: None,
            cone: None,
        },
    ];
    s.directional_lights = vec![DirectionalLight {
        name: "sun".into(),
        direction: Vec3::new(0.3, -1.0, 0.2).normalize(),
        irradiance: Vec3::new(2.0, 1.9, 1.7),
    }];
    s.cameras = vec![
        Camera {
            name: "main".into(),
            position: Vec3::new(1.5, 0.5, 4.0),
            target: Vec3::new(1.5, 0.5, 0.0),
            up: Vec3::Y,
            fov_y: 0.7,
            aspect: 1.5,
            near: 0.05,
            far: 40.0,
        },
        Camera {
            name: "top".into(),
            position: Vec3::new(1.0, 6.0, 1.0),
            target: Vec3::new(1.2, 0.0, 0.9),
            up: Vec3::Z,
            fov_y: 1.1,
            aspect: 0.75,
            near: 0.1,
            far: 20.0,
        },
    ];
    s.validate().expect("test scene is valid");
    s
}

/// Same triangles (positions, normals, UVs of textured triangles), materials, textures,
/// lights and cameras.
#[track_caller]
fn assert_round_trip(a: &Scene, b: &Scene) {
    assert_eq!(a.meshes.len(), b.meshes.len(), "mesh count");
    for (ma, mb) in a.meshes.iter().zip(&b.meshes) {
        assert_eq!(ma.name, mb.name);
        assert_eq!(
            ma.indices.len(),
            mb.indices.len(),
            "{}: triangle count",
            ma.name
        );
        assert_eq!(
            ma.material_ids, mb.material_ids,
            "{}: material ids",
            ma.name
        );
        for (t, (ta, tb)) in ma.indices.iter().zip(&mb.indices).enumerate() {
            let textured = a.materials[ma.material_ids[t] as usize]
                .albedo_texture
                .is_some();
            for k in 0..3 {
                let (va, vb) = (ta[k] as usize, tb[k] as usize);
                let what = format!("{} triangle {t} corner {k}", ma.name);
                assert_close(ma.positions[va], mb.positions[vb], 1e-5, &what);
                assert_close(ma.normals[va], mb.normals[vb], 1e-5, &what);
                if textured {
                    let (ua, ub) = (ma.uvs.as_ref().unwrap()[va], mb.uvs.as_ref().unwrap()[vb]);
                    assert!(
                        (ua - ub).abs().max_element() < 1e-6,
                        "{what}: uv {ua} vs {ub}"
                    );
                }
            }
        }
    }
    assert_eq!(a.materials.len(), b.materials.len(), "material count");
    for (x, y) in a.materials.iter().zip(&b.materials) {
        assert_eq!(x.name, y.name);
        assert_close(x.albedo, y.albedo, 1e-5, &x.name);
        assert_close(x.emission, y.emission, 1e-5, &x.name);
        assert_eq!(x.albedo_texture, y.albedo_texture, "{}", x.name);
    }
    assert_eq!(a.textures.len(), b.textures.len(), "texture count");
    for (x, y) in a.textures.iter().zip(&b.textures) {
        assert_eq!(x.sampler, y.sampler, "{}", x.name);
        assert_eq!((&x.name, x.width, x.height), (&y.name, y.width, y.height));
        for (p, q) in x.texels.iter().zip(&y.texels) {
            // 8-bit sRGB quantisation.
            assert!((*p - *q).abs().max_element() < 6e-3, "texel {p} vs {q}");
        }
    }
    assert_eq!(a.point_lights.len(), b.point_lights.len());
    for (x, y) in a.point_lights.iter().zip(&b.point_lights) {
        assert_eq!(x.name, y.name);
        assert_close(x.position, y.position, 1e-5, &x.name);
        assert_close(x.intensity, y.intensity, 1e-5, &x.name);
        assert_eq!(x.radius, y.radius);
        assert_eq!(x.cone.is_some(), y.cone.is_some(), "{}", x.name);
        if let (Some(cx), Some(cy)) = (&x.cone, &y.cone) {
            assert_close(cx.axis(), cy.axis(), 1e-5, &x.name);
            assert_eq!((cx.inner, cx.outer), (cy.inner, cy.outer), "{}", x.name);
        }
    }
    assert_eq!(a.directional_lights.len(), b.directional_lights.len());
    for (x, y) in a.directional_lights.iter().zip(&b.directional_lights) {
        assert_eq!(x.name, y.name);
        assert_close(x.direction, y.direction, 1e-5, &x.name);
        assert_close(x.irradiance, y.irradiance, 1e-5, &x.name);
    }
    assert_eq!(a.cameras.len(), b.cameras.len());
    for (x, y) in a.cameras.iter().zip(&b.cameras) {
        assert_eq!(x.name, y.name);
        assert_close(x.position, y.position, 1e-5, &x.name);
        let (da, db) = (x.target - x.position, y.target - y.position);
        assert_close(da.normalize(), db.normalize(), 1e-5, &x.name);
        assert!((da.length() - db.length()).abs() <= 1e-5 * da.length().max(1.0));
        // The up vector may be re-orthogonalised but must keep its side.
        assert!(x.up.normalize().dot(y.up) > 0.0 && db.cross(y.up).length() > 1e-3);
        assert!((x.fov_y - y.fov_y).abs() < 1e-5);
        assert!((x.aspect - y.aspect).abs() < 1e-5);
        assert!((x.near - y.near).abs() < 1e-5 * x.near.max(1.0));
        assert!((x.far - y.far).abs() < 1e-5 * x.far.max(1.0));
    }
}

fn export_bytes(scene: &Scene, ext: &str) -> Vec<u8> {
    let path = temp_file(&format!("bytes.{ext}"));
    export(scene, &path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    bytes
}

fn round_trip_file(scene: &Scene, ext: &str) -> ImportResult {
    let path = temp_file(&format!("round_trip.{ext}"));
    export(scene, &path).unwrap();
    let result = import(&path);
    std::fs::remove_file(&path).unwrap();
    result.unwrap()
}

#[test]
fn round_trip_gltf() {
    let s = test_scene();
    let r = round_trip_file(&s, "gltf");
    assert_round_trip(&s, &r.scene);
    assert!(r.ignored.is_empty(), "{:?}", r.ignored);
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert_eq!(r.summary(), "ignored: nothing");
}

/// The embedded buffer is encoded straight into the file around a marker; a scene whose
/// own names hold the marker takes the in-memory way and writes the same file otherwise.
#[test]
fn gltf_buffer_is_streamed_and_a_name_holding_the_marker_is_kept() {
    use base64::Engine as _;
    let s = test_scene();
    let mut marked = s.clone();
    marked.meshes[0].name = format!("mesh {}", super::export::BUFFER_MARKER);
    for scene in [&s, &marked] {
        let bytes = export_bytes(scene, "gltf");
        let root: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
        let buffer = &root["buffers"][0];
        let uri = buffer["uri"].as_str().unwrap();
        let data = uri
            .strip_prefix("data:application/octet-stream;base64,")
            .unwrap();
        let decoded = base64::engine::general_purpose::STANDARD
            .decode(data)
            .unwrap();
        assert_eq!(decoded.len() as u64, buffer["byteLength"].as_u64().unwrap());
        let text = String::from_utf8(bytes).unwrap();
        let markers = text.matches(super::export::BUFFER_MARKER).count();
        // Only the names hold it (the mesh's and its node's).
        assert_eq!(markers > 0, std::ptr::eq(scene, &marked), "{text:.300}");
        let r = round_trip_file(scene, "gltf");
        assert_round_trip(scene, &r.scene);
    }
    // The same buffer either way.
    let uri = |scene: &Scene| {
        let root: serde_json::Value = serde_json::from_slice(&export_bytes(scene, "gltf")).unwrap();
        root["buffers"][0]["uri"].as_str().unwrap().to_string()
    };
    assert_eq!(uri(&s), uri(&marked));
}

#[test]
fn round_trip_glb_file_and_slice() {
    let s = test_scene();
    let r = round_trip_file(&s, "GLB");
    assert_round_trip(&s, &r.scene);
    assert!(r.ignored.is_empty() && r.warnings.is_empty(), "{r:?}");
    let bytes = export_bytes(&s, "glb");
    assert!(bytes.starts_with(b"glTF"));
    let r = import_slice(&bytes, Path::new("mem.glb")).unwrap();
    assert_eq!(r.scene.name, "mem");
    assert_round_trip(&s, &r.scene);
}

#[test]
fn export_layout_is_spec_shaped() {
    let s = test_scene();
    let bytes = export_bytes(&s, "gltf");
    let root: Value = serde_json::from_slice(&bytes).unwrap();
    assert_eq!(root["asset"]["version"], "2.0");
    let used: Vec<&str> = root["extensionsUsed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(used, [EXT_LIGHTS, EXT_EMISSIVE_STRENGTH]);
    // One primitive per contiguous material run: 0,0 | 1,1 | 0,0 and 2 | 3.
    let prims = |m: usize| root["meshes"][m]["primitives"].as_array().unwrap().clone();
    let mats: Vec<u64> = prims(0)
        .iter()
        .map(|p| p["material"].as_u64().unwrap())
        .collect();
    assert_eq!(mats, [0, 1, 0]);
    assert_eq!(prims(1).len(), 2);
    for p in prims(0) {
        let pos = &root["accessors"][p["attributes"]["POSITION"].as_u64().unwrap() as usize];
        assert!(pos["min"].is_array() && pos["max"].is_array());
        assert!(p["attributes"]["TEXCOORD_0"].is_u64());
        let idx = &root["accessors"][p["indices"].as_u64().unwrap() as usize];
        assert_eq!(idx["componentType"], GL_UNSIGNED_INT);
        let view = &root["bufferViews"][idx["bufferView"].as_u64().unwrap() as usize];
        assert_eq!(view["target"], GL_ELEMENT_ARRAY_BUFFER);
    }
    assert!(
        root["buffers"][0]["uri"]
            .as_str()
            .unwrap()
            .starts_with("data:application/octet-stream;base64,")
    );
    let lamp = &root["materials"][2];
    assert_eq!(
        lamp["extensions"][EXT_EMISSIVE_STRENGTH]["emissiveStrength"],
        17.0
    );
    assert_eq!(lamp["emissiveFactor"][0], 1.0);
    assert!(root["materials"][3]["extensions"].is_null());
    // A file that gltf itself accepts (it validates the JSON).
    assert!(gltf::Gltf::from_slice(&bytes).is_ok());
}

#[test]
fn export_rejects_invalid_scenes_and_unknown_extensions() {
    let mut s = test_scene();
    let path = temp_file("bad.obj");
    assert!(matches!(export(&s, &path), Err(GltfError::Write { .. })));
    assert!(!path.exists());
    s.materials[0].albedo = Vec3::ONE;
    let path = temp_file("bad.gltf");
    match export(&s, &path) {
        Err(GltfError::Invalid { path: p, source }) => {
            assert_eq!(p, path);
            assert!(matches!(source, crate::SceneError::AlbedoOutOfRange { .. }));
        }
        other => panic!("expected Invalid, got {other:?}"),
    }
    assert!(!path.exists());
}

#[test]
fn round_trip_builtins() {
    for name in crate::builtin::SMALL_INSTANCES {
        let s = crate::builtin::scene(name).unwrap();
        for ext in ["gltf", "glb"] {
            let r = round_trip_file(&s, ext);
            assert_round_trip(&s, &r.scene);
            assert!(r.warnings.is_empty(), "{name}: {:?}", r.warnings);
        }
    }
}

/// A self-contained .gltf with one mesh (one primitive of `mode`), node 0 showing it in
/// scene 0; `edit` adjusts the JSON before it is serialised.
fn doc(
    positions: &[[f32; 3]],
    normals: Option<&[[f32; 3]]>,
    indices: Option<&[u32]>,
    mode: u32,
    edit: impl FnOnce(&mut Value),
) -> Vec<u8> {
    let mut w = BinWriter::default();
    let pos: Vec<Vec3> = positions.iter().map(|&p| Vec3::from(p)).collect();
    let mut attributes = json!({ "POSITION": w.vec3(&pos, true) });
    if let Some(n) = normals {
        let n: Vec<Vec3> = n.iter().map(|&p| Vec3::from(p)).collect();
        attributes["NORMAL"] = json!(w.vec3(&n, false));
    }
    let mut prim = json!({ "attributes": attributes, "mode": mode });
    if let Some(i) = indices {
        prim["indices"] = json!(w.indices(i));
    }
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&w.bin)
    );
    let mut root = json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0, "name": "tri" }],
        "meshes": [{ "primitives": [prim] }],
        "buffers": [{ "byteLength": w.bin.len(), "uri": uri }],
        "bufferViews": w.views,
        "accessors": w.accessors,
    });
    edit(&mut root);
    serde_json::to_vec(&root).unwrap()
}

const TRI: [[f32; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
const TRI_N: [[f32; 3]; 3] = [[0.577_350_26; 3]; 3];

fn face_normal(m: &Mesh, t: usize) -> Vec3 {
    let [a, b, c] = m.indices[t].map(|i| m.positions[i as usize]);
    (b - a).cross(c - a).normalize()
}

#[test]
fn node_hierarchy_is_flattened() {
    let s45 = std::f32::consts::FRAC_1_SQRT_2;
    let (sy, cy) = (15f32.to_radians().sin(), 15f32.to_radians().cos());
    let bytes = doc(&TRI, Some(&TRI_N), None, 4, |root| {
        root["nodes"] = json!([
            { "name": "parent", "translation": [10, 0, 0], "scale": [2, 2, 2], "children": [1] },
            { "name": "child", "mesh": 0, "translation": [0, 1, 0], "rotation": [0, 0, s45, s45] },
            { "name": "mirror", "mesh": 0, "scale": [-1, 1, 1] },
            { "name": "skew", "mesh": 0, "scale": [3, 1, 1], "rotation": [0, sy, 0, cy] },
            { "name": "matrix", "mesh": 0,
              "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 5, 1] },
        ]);
        root["scenes"] = json!([{ "nodes": [0, 2, 3, 4] }]);
    });
    let r = import_slice(&bytes, Path::new("hierarchy.gltf")).unwrap();
    let m = &r.scene.meshes;
    let names: Vec<&str> = m.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["child", "mirror", "skew", "matrix"]);

    // parent(T(10,0,0) S(2)) * child(T(0,1,0) Rz(90)).
    let child = &m[0];
    let expected = [
        Vec3::new(10.0, 4.0, 0.0),
        Vec3::new(8.0, 2.0, 0.0),
        Vec3::new(10.0, 2.0, 2.0),
    ];
    for (p, e) in child.positions.iter().zip(expected) {
        assert_close(*p, e, 1e-5, "child position");
    }
    assert_close(
        child.normals[0],
        Vec3::new(-1.0, 1.0, 1.0).normalize(),
        1e-5,
        "child normal",
    );
    assert_eq!(child.indices, [[0, 1, 2]]);

    // Mirror: positions mirrored, normal by the inverse transpose, winding flipped.
    let mirror = &m[1];
    assert_close(
        mirror.positions[0],
        Vec3::new(-1.0, 0.0, 0.0),
        1e-6,
        "mirror",
    );
    assert_close(
        mirror.normals[0],
        Vec3::new(-1.0, 1.0, 1.0).normalize(),
        1e-5,
        "mirror normal",
    );
    assert_eq!(mirror.indices, [[0, 2, 1]]);
    assert!(face_normal(mirror, 0).dot(mirror.normals[0]) > 0.99);

    // Non-uniform scale: the normal stays perpendicular to the surface and unit length.
    let skew = &m[2];
    let n = skew.normals[0];
    assert!((n.length() - 1.0).abs() < 1e-5);
    assert!(
        (face_normal(skew, 0).dot(n) - 1.0).abs() < 1e-5,
        "skew normal {n}"
    );
    let [a, b, c] = [0, 1, 2].map(|i| skew.positions[i]);
    assert_close(
        a,
        Quat::from_rotation_y(30f32.to_radians()) * Vec3::new(3.0, 0.0, 0.0),
        1e-5,
        "skew",
    );
    assert!((b - a).dot(n).abs() < 1e-5 && (c - a).dot(n).abs() < 1e-5);

    assert_close(m[3].positions[0], Vec3::new(1.0, 0.0, 5.0), 1e-6, "matrix");
}

#[test]
fn emissive_strength_multiplies_and_default_albedo_is_clamped() {
    let bytes = doc(&TRI, Some(&TRI_N), None, 4, |root| {
        root["materials"] = json!([{
            "name": "glow",
            "emissiveFactor": [1.0, 0.5, 0.25],
            "extensions": { EXT_EMISSIVE_STRENGTH: { "emissiveStrength": 4.0 } },
        }]);
        root["meshes"][0]["primitives"][0]["material"] = json!(0);
        root["extensionsUsed"] = json!([EXT_EMISSIVE_STRENGTH]);
    });
    let r = import_slice(&bytes, Path::new("glow.gltf")).unwrap();
    let m = &r.scene.materials[0];
    assert_eq!(m.emission, Vec3::new(4.0, 2.0, 1.0));
    assert_eq!(m.albedo, Vec3::splat(ALBEDO_MAX));
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("'glow'") && w.contains("albedo clamped below 1"))
    );
    // glTF's default metallicFactor is 1.
    assert_eq!(r.summary(), "ignored: 1 metallic/roughness setting");
}

#[test]
fn lights_and_cameras_from_nodes() {
    // Half of a -45 degree turn about X: -Z turns to (0, -1, -1) / sqrt 2.
    let (s, c) = ((-22.5f32).to_radians().sin(), (-22.5f32).to_radians().cos());
    let bytes = doc(&TRI, Some(&TRI_N), None, 4, |root| {
        root["extensionsUsed"] = json!([EXT_LIGHTS, "KHR_materials_clearcoat"]);
        root["extensions"] = json!({ EXT_LIGHTS: { "lights": [
            { "name": "cone", "type": "spot", "color": [1.0, 0.5, 0.5], "intensity": 10.0,
              "range": 5.0, "spot": { "outerConeAngle": 0.5 } },
            { "name": "sun", "type": "directional", "intensity": 3.0 },
            { "type": "point", "color": [0.0, 1.0, 0.0], "intensity": 2.0 },
        ]}});
        root["cameras"] = json!([
            { "name": "persp", "type": "perspective", "perspective": { "yfov": 0.8, "znear": 0.1 } },
            { "type": "orthographic", "orthographic": { "xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10 } },
        ]);
        root["nodes"] = json!([
            { "mesh": 0 },
            { "translation": [1, 2, 3], "rotation": [0.3, 0.2, 0.1, 0.927],
              "extensions": { EXT_LIGHTS: { "light": 0 } } },
            { "rotation": [s, 0, 0, c], "translation": [5, 5, 5],
              "extensions": { EXT_LIGHTS: { "light": 1 } } },
            { "translation": [0, 0, 1], "children": [4] },
            { "translation": [0, 1, 0], "extensions": { EXT_LIGHTS: { "light": 2 } } },
            { "camera": 0, "translation": [0, 1, 5] },
            { "camera": 1 },
        ]);
        root["scenes"] =
            json!([{ "nodes": [0, 1, 2, 3, 5, 6] }, { "name": "unused", "nodes": [] }]);
        root["animations"] = json!([]);
    });
    let r = import_slice(&bytes, Path::new("lights.gltf")).unwrap();
    let sc = &r.scene;
    assert_eq!(sc.point_lights.len(), 2);
    let cone = &sc.point_lights[0];
    assert_eq!(cone.name, "cone");
    assert_close(
        cone.position,
        Vec3::new(1.0, 2.0, 3.0),
        1e-6,
        "spot position",
    );
    assert_eq!(cone.intensity, Vec3::new(10.0, 5.0, 5.0));
    assert_eq!(cone.radius, Some(5.0));
    // The spot keeps its cone (glTF's default inner angle 0) along the node's -Z.
    let spot = cone.cone.expect("a spot cone");
    assert_eq!((spot.inner, spot.outer), (0.0, 0.5));
    let q = Quat::from_xyzw(0.3, 0.2, 0.1, 0.927).normalize();
    assert_close(spot.axis(), q * Vec3::NEG_Z, 1e-5, "spot axis");
    assert!(
        r.warnings.iter().all(|w| !w.contains("spot")),
        "{:?}",
        r.warnings
    );
    let green = &sc.point_lights[1];
    assert_close(
        green.position,
        Vec3::new(0.0, 1.0, 1.0),
        1e-6,
        "nested light",
    );
    assert_eq!(
        (green.intensity, green.radius),
        (Vec3::new(0.0, 2.0, 0.0), None)
    );

    let sun = &sc.directional_lights[0];
    assert_close(
        sun.direction,
        Vec3::new(0.0, -1.0, -1.0).normalize(),
        1e-5,
        "sun",
    );
    assert_eq!(sun.irradiance, Vec3::splat(3.0));

    assert_eq!(sc.cameras.len(), 1);
    let cam = &sc.cameras[0];
    assert_eq!(cam.name, "persp");
    assert_eq!(cam.position, Vec3::new(0.0, 1.0, 5.0));
    assert_close(
        (cam.target - cam.position).normalize(),
        Vec3::NEG_Z,
        1e-6,
        "view",
    );
    assert_close(cam.up, Vec3::Y, 1e-6, "up");
    assert_eq!((cam.fov_y, cam.aspect, cam.near), (0.8, 1.0, 0.1));
    assert!(cam.far >= 100.0 && cam.far.is_finite(), "far {}", cam.far);

    assert_eq!(
        r.summary(),
        "ignored: 1 extension, 1 other scene, 1 orthographic camera"
    );
    assert!(
        r.ignored
            .contains(&"extension: KHR_materials_clearcoat".to_string())
    );
}

#[test]
fn strips_fans_lines_and_default_material() {
    let quad = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ];
    // The triangles as index triples into `quad` (without normals every corner is a
    // vertex of its own, carrying the file's position).
    let triples = |m: &Mesh| -> Vec<[usize; 3]> {
        m.indices
            .iter()
            .map(|t| {
                t.map(|i| {
                    let p = m.positions[i as usize];
                    quad.iter().position(|q| Vec3::from(*q) == p).unwrap()
                })
            })
            .collect()
    };
    // Strip without indices: sequential indices, odd triangles reversed.
    let r = import_slice(&doc(&quad, None, None, 5, |_| {}), Path::new("strip.gltf")).unwrap();
    let m = &r.scene.meshes[0];
    assert_eq!(triples(m), [[0, 1, 2], [1, 3, 2]]);
    assert!(
        m.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6),
        "flat normals"
    );
    assert_eq!(r.scene.materials.len(), 1);
    assert_eq!(r.scene.materials[0].name, DEFAULT_MATERIAL_NAME);
    assert_eq!(r.scene.materials[0].albedo, Vec3::splat(DEFAULT_ALBEDO));
    assert_eq!(m.material_ids, [0, 0]);

    let r = import_slice(
        &doc(&quad, None, Some(&[0, 1, 3, 2]), 6, |_| {}),
        Path::new("fan.gltf"),
    )
    .unwrap();
    assert_eq!(triples(&r.scene.meshes[0]), [[1, 3, 0], [3, 2, 0]]);

    // Lines are skipped and listed, not an error.
    let lines = doc(&quad, None, Some(&[0, 1, 1, 2]), 1, |root| {
        let tri = root["meshes"][0]["primitives"][0].clone();
        let mut tri = tri;
        tri["mode"] = json!(4);
        tri.as_object_mut().unwrap().remove("indices");
        root["meshes"][0]["primitives"]
            .as_array_mut()
            .unwrap()
            .push(tri);
    });
    let r = import_slice(&lines, Path::new("lines.gltf")).unwrap();
    assert_eq!(r.scene.meshes[0].indices.len(), 1);
    assert_eq!(r.summary(), "ignored: 1 point/line primitive");
    assert!(r.ignored[0].contains("primitive 0"), "{:?}", r.ignored);
}

#[test]
fn summary_groups_and_pluralises() {
    let r = ImportResult {
        scene: Scene::default(),
        ignored: vec![
            "metallic-roughness texture: a".into(),
            "orthographic camera: s".into(),
            "metallic-roughness texture: b".into(),
            "animation: x".into(),
            "metallic-roughness texture: c".into(),
            "animation: y".into(),
        ],
        warnings: vec![],
    };
    assert_eq!(
        r.summary(),
        "ignored: 3 metallic-roughness textures, 1 orthographic camera, 2 animations"
    );
}

#[test]
fn missing_file_is_a_read_error_naming_the_path() {
    let path = temp_file("does_not_exist.glb");
    match import(&path) {
        Err(GltfError::Read { path: p, message }) => {
            assert_eq!(p, path);
            assert!(!message.is_empty());
        }
        other => panic!("expected Read, got {other:?}"),
    }
}

#[track_caller]
fn assert_read_err(bytes: &[u8], what: &str) {
    match import_slice(bytes, Path::new("corrupt.gltf")) {
        Err(GltfError::Read { path, .. }) => assert_eq!(path, Path::new("corrupt.gltf")),
        other => panic!("{what}: expected Read error, got {other:?}"),
    }
}

#[test]
fn truncated_and_corrupted_files_are_errors() {
    let s = test_scene();
    for ext in ["gltf", "glb"] {
        let bytes = export_bytes(&s, ext);
        for frac in [0.1, 0.5, 0.9] {
            let cut = (bytes.len() as f64 * frac) as usize;
            assert_read_err(&bytes[..cut], &format!("{ext} cut at {frac}"));
        }
        // Every shorter length fails too (sampled).
        for cut in (0..bytes.len()).step_by(97) {
            assert!(
                import_slice(&bytes[..cut], Path::new("x")).is_err(),
                "{ext} cut {cut}"
            );
        }
    }
    // Bytes flipped in the middle of a .gltf (JSON or base64 text) are never valid.
    let gltf = export_bytes(&s, "gltf");
    let mut flipped = gltf.clone();
    let mid = flipped.len() / 2;
    for b in &mut flipped[mid..mid + 4] {
        *b ^= 0xFF;
    }
    assert_read_err(&flipped, "gltf flipped");
    // In a .glb, flipping bytes of the JSON chunk is detected.
    let glb = export_bytes(&s, "glb");
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut flipped = glb.clone();
    let mid = 20 + json_len / 2;
    for b in &mut flipped[mid..mid + 4] {
        *b ^= 0xFF;
    }
    assert_read_err(&flipped, "glb JSON flipped");
    // A GLB header length below the header size (gltf 1.4 would underflow).
    let mut short = glb.clone();
    short[8..12].copy_from_slice(&4u32.to_le_bytes());
    assert_read_err(&short, "glb length 4");
    // Not JSON at all.
    assert_read_err(b"{ \"asset\": { \"version\": \"2.0\" ", "unterminated JSON");
    assert_read_err(b"\x00\x01garbage", "garbage");
    assert_read_err(b"", "empty");
}

#[test]
fn flipping_any_byte_never_panics() {
    let s = test_scene();
    for ext in ["glb", "gltf"] {
        let bytes = export_bytes(&s, ext);
        let step = (bytes.len() / 400).max(1);
        for i in (0..bytes.len()).step_by(step) {
            for mask in [0xFF, 0x01, 0x80] {
                let mut b = bytes.clone();
                b[i] ^= mask;
                // Binary payload flips may still import; they must not panic.
                let _ = import_slice(&b, Path::new("fuzz"));
            }
        }
    }
}

/// Edits the JSON of the exported test scene and imports it.
fn import_edited(edit: impl FnOnce(&mut Value)) -> Result<ImportResult, GltfError> {
    let bytes = export_bytes(&test_scene(), "gltf");
    let mut root: Value = serde_json::from_slice(&bytes).unwrap();
    edit(&mut root);
    import_slice(
        &serde_json::to_vec(&root).unwrap(),
        Path::new("edited.gltf"),
    )
}

#[test]
fn out_of_range_references_are_errors() {
    type Edit = fn(&mut Value);
    let read_errors: [(&str, Edit); 9] = [
        ("POSITION accessor index", |r| {
            r["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(999)
        }),
        ("NORMAL accessor index", |r| {
            r["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(999)
        }),
        ("indices accessor index", |r| {
            r["meshes"][0]["primitives"][0]["indices"] = json!(999)
        }),
        ("material index", |r| {
            r["meshes"][0]["primitives"][0]["material"] = json!(99)
        }),
        ("node mesh index", |r| r["nodes"][0]["mesh"] = json!(99)),
        ("huge accessor count", |r| {
            r["accessors"][0]["count"] = json!(1u64 << 40)
        }),
        ("view past buffer", |r| {
            r["bufferViews"][0]["byteOffset"] = json!(1u64 << 20)
        }),
        ("accessor offset past view", |r| {
            r["accessors"][0]["byteOffset"] = json!(4096)
        }),
        ("image without mime type", |r| {
            r["images"][0].as_object_mut().unwrap().remove("mimeType");
        }),
    ];
    for (what, edit) in read_errors {
        match import_edited(edit) {
            Err(GltfError::Read { message, .. }) => assert!(!message.is_empty()),
            other => panic!("{what}: expected Read error, got {other:?}"),
        }
    }
    let content_errors: [(&str, Edit); 3] = [
        ("POSITION is VEC2", |r| {
            r["accessors"][0]["type"] = json!("VEC2")
        }),
        ("accessor count 0", |r| {
            r["accessors"][0]["count"] = json!(0)
        }),
        ("node cycle", |r| {
            r["nodes"][0]["children"] = json!([1]);
            r["nodes"][1]["children"] = json!([0]);
        }),
    ];
    for (what, edit) in content_errors {
        match import_edited(edit) {
            Err(GltfError::Content { .. }) => {}
            other => panic!("{what}: expected Content error, got {other:?}"),
        }
    }
    // Percent-encoded URIs that are not UTF-8 (gltf 1.4 would panic decoding them).
    let r = import_edited(|r| r["buffers"][0]["uri"] = json!("%FF%FE.bin"));
    assert!(matches!(r, Err(GltfError::RefusedUri { .. })), "{r:?}");
}

#[test]
fn index_past_vertex_count_is_a_content_error_naming_the_primitive() {
    let bytes = doc(&TRI, None, Some(&[0, 1, 3]), 4, |_| {});
    match import_slice(&bytes, Path::new("idx.gltf")) {
        Err(GltfError::Content { message, .. }) => {
            assert!(
                message.contains("primitive 0") && message.contains("index 3"),
                "{message}"
            );
        }
        other => panic!("expected Content error, got {other:?}"),
    }
}

#[test]
fn invalid_scene_is_reported() {
    let bytes = doc(&TRI, None, None, 4, |root| {
        root["materials"] = json!([{ "emissiveFactor": [1.0, 1.0, 1.0],
            "extensions": { EXT_EMISSIVE_STRENGTH: { "emissiveStrength": -2.0 } } }]);
        root["meshes"][0]["primitives"][0]["material"] = json!(0);
    });
    match import_slice(&bytes, Path::new("neg.gltf")) {
        Err(GltfError::Invalid { source, .. }) => {
            assert!(matches!(source, crate::SceneError::InvalidEmission { .. }));
        }
        other => panic!("expected Invalid, got {other:?}"),
    }
}

#[test]
fn zero_rotations_are_refused_and_unnormalised_ones_normalised() {
    let with_rotation = |rotation: serde_json::Value| {
        doc(&TRI, Some(&TRI_N), None, 4, |root| {
            root["extensionsUsed"] = json!([EXT_LIGHTS]);
            root["extensions"] = json!({ EXT_LIGHTS: { "lights": [
                { "name": "sun", "type": "directional", "intensity": 3.0 },
            ]}});
            root["nodes"] = json!([
                { "mesh": 0 },
                { "name": "sun-node", "rotation": rotation,
                  "extensions": { EXT_LIGHTS: { "light": 0 } } },
            ]);
            root["scenes"] = json!([{ "nodes": [0, 1] }]);
        })
    };
    let e = import_slice(&with_rotation(json!([0, 0, 0, 0])), Path::new("zero.gltf")).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("zero.gltf") && msg.contains("'sun-node'") && msg.contains("unit quaternion"),
        "{msg}"
    );
    // Twice a -45 degree turn about X: read as the unit quaternion, with a warning.
    let (s, c) = ((-22.5f32).to_radians().sin(), (-22.5f32).to_radians().cos());
    let r = import_slice(
        &with_rotation(json!([2.0 * s, 0, 0, 2.0 * c])),
        Path::new("two.gltf"),
    )
    .unwrap();
    assert_close(
        r.scene.directional_lights[0].direction,
        Vec3::new(0.0, -1.0, -1.0).normalize(),
        1e-5,
        "normalised rotation",
    );
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("'sun-node'") && w.contains("normalised"))
    );
}

/// glTF 2.0 (3.7.2.1): without `NORMAL` a client computes flat normals. A roof of two
/// triangles sharing an edge at a right angle (four shared vertices, no normals) imports
/// with three vertices per triangle, each carrying its face's normal (smoothing would give
/// the ridge the mean of both), under a plain, a mirroring and a non-uniform transform; a
/// vertex budget that holds the file's four vertices but not the six corners refuses it.
#[test]
fn missing_normals_are_flat() {
    let roof = [
        [0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [1.0, 1.0, 1.0],
        [0.0, 0.0, 1.0],
        [2.0, 0.0, 0.0],
        [2.0, 0.0, 1.0],
    ];
    // Left slope (0, 3, 2, 1) and right slope (1, 2, 5, 4), both facing up and out; the
    // ridge vertices 1 and 2 are shared.
    let indices = [0, 3, 2, 0, 2, 1, 1, 2, 5, 1, 5, 4];
    let bytes = doc(&roof, None, Some(&indices), 4, |root| {
        root["nodes"] = json!([
            { "name": "plain", "mesh": 0 },
            { "name": "mirror", "mesh": 0, "scale": [-1, 1, 1] },
            { "name": "skew", "mesh": 0, "scale": [3, 1, 0.5], "rotation": [0, 0.2588, 0, 0.9659] },
        ]);
        root["scenes"] = json!([{ "nodes": [0, 1, 2] }]);
    });
    let r = import_slice(&bytes, Path::new("roof.gltf")).unwrap();
    assert_eq!(r.scene.meshes.len(), 3);
    for m in &r.scene.meshes {
        assert_eq!(m.indices.len(), 4, "{}", m.name);
        assert_eq!(m.positions.len(), 12, "{}: a vertex per corner", m.name);
        for t in 0..m.indices.len() {
            let face = face_normal(m, t);
            assert!(face.y > 0.5, "{}: triangle {t} faces {face}", m.name);
            for i in m.indices[t] {
                let n = m.normals[i as usize];
                assert!(
                    n.dot(face) > 1.0 - 1e-6,
                    "{}: triangle {t} corner {i}: normal {n}, face {face}",
                    m.name
                );
            }
        }
        // The two slopes meet at a right angle (an obtuse one once scaled by 3 along x):
        // no corner carries their mean.
        let (a, b) = (face_normal(m, 0), face_normal(m, 2));
        let cos = if m.name == "skew" { 0.8 } else { 0.0 };
        assert!((a.dot(b) - cos).abs() < 1e-3, "{}: {a} {b}", m.name);
    }
    // The plain node's corners are the file's positions in index order.
    let plain = &r.scene.meshes[0];
    for (k, &i) in indices.iter().enumerate() {
        let [t, c] = [k / 3, k % 3];
        let p = plain.positions[plain.indices[t][c] as usize];
        assert_close(p, Vec3::from(roof[i as usize]), 0.0, "corner");
    }
    // Budget: 6 vertices per node in the file, 12 corners after flat normals (3 nodes).
    let budget = |vertices| ImportOptions {
        budget: crate::budget::Budget {
            vertices,
            ..Default::default()
        },
        ..Default::default()
    };
    assert!(import_slice_with(&bytes, Path::new("roof.gltf"), &budget(36)).is_ok());
    let e = import_slice_with(&bytes, Path::new("roof.gltf"), &budget(35)).unwrap_err();
    assert!(matches!(e, GltfError::Budget(_)), "{e}");
}

/// `KHR_texture_transform` on a base colour texture is baked into the texture coordinates:
/// the test scene exported, its textured material given an offset, a rotation and a scale,
/// imports with every textured vertex's coordinates moved as the extension says
/// (`uv' = R (scale * uv) + offset`, R: `(u cos + v sin, v cos - u sin)`), and the
/// extension is no longer listed as ignored.
#[test]
fn texture_transforms_are_baked_into_texture_coordinates() {
    let s = test_scene();
    let plain = export_bytes(&s, "gltf");
    let mut root: Value = serde_json::from_slice(&plain).unwrap();
    let (offset, rotation, scale) = (Vec2::new(0.5, -0.25), 0.3f32, Vec2::new(2.0, 3.0));
    // Material 1 ("checker") is the textured one.
    root["materials"][1]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] = json!({
        "KHR_texture_transform": {
            "offset": offset.to_array(), "rotation": rotation, "scale": scale.to_array()
        }
    });
    root["extensionsUsed"]
        .as_array_mut()
        .map(|a| a.push(json!("KHR_texture_transform")))
        .unwrap_or_else(|| root["extensionsUsed"] = json!(["KHR_texture_transform"]));
    let moved = serde_json::to_vec(&root).unwrap();
    let a = import_slice(&plain, Path::new("plain.gltf")).unwrap();
    let b = import_slice(&moved, Path::new("moved.gltf")).unwrap();
    assert!(
        b.ignored
            .iter()
            .all(|i| !i.contains("KHR_texture_transform")),
        "{:?}",
        b.ignored
    );
    let (sin, cos) = rotation.sin_cos();
    let mut checked = 0;
    for (ma, mb) in a.scene.meshes.iter().zip(&b.scene.meshes) {
        for (t, tri) in ma.indices.iter().enumerate() {
            if ma.material_ids[t] != 1 {
                continue;
            }
            for &v in tri {
                let uv = ma.uvs.as_ref().unwrap()[v as usize] * scale;
                let expected = Vec2::new(uv.x * cos + uv.y * sin, uv.y * cos - uv.x * sin) + offset;
                let got = mb.uvs.as_ref().unwrap()[v as usize];
                assert!((got - expected).length() < 1e-5, "{got} vs {expected}");
                checked += 1;
            }
        }
    }
    assert!(checked >= 6, "{checked} textured corners");
}

#[test]
fn alpha_modes_become_cutoffs() {
    let r = import_edited(|r| {
        let m = &mut r["materials"];
        m[0]["alphaMode"] = json!("BLEND");
        m[1]["alphaMode"] = json!("MASK");
        m[1]["alphaCutoff"] = json!(0.3);
        m[1]["pbrMetallicRoughness"]["baseColorFactor"][3] = json!(0.6);
        m[2]["alphaMode"] = json!("MASK");
        m[2]["pbrMetallicRoughness"]["baseColorFactor"][3] = json!(0.0);
        m[3]["pbrMetallicRoughness"]["baseColorFactor"][3] = json!(0.5);
    })
    .unwrap();
    let cutoffs: Vec<Option<f32>> = r.scene.materials.iter().map(|m| m.alpha_cutoff).collect();
    // BLEND read as a mask at 0.5; MASK's cutoff over the factor's alpha (0.3 / 0.6); a
    // factor of 0 leaves no surface (a cutoff above 1); OPAQUE ignores alpha.
    assert_eq!(cutoffs[0], Some(0.5));
    assert!((cutoffs[1].unwrap() - 0.5).abs() < 1e-6, "{cutoffs:?}");
    assert!(cutoffs[2].unwrap() > 1.0, "{cutoffs:?}");
    assert_eq!(cutoffs[3], None);
    assert!(
        r.summary().contains("1 blended material"),
        "{}",
        r.summary()
    );
    // The masked material's texture was read with its alpha: the exported RGB PNG has
    // none, so it reads as 1 (opaque under a cutoff of 0.5).
    let t = r.scene.materials[1].albedo_texture.unwrap() as usize;
    assert_eq!(r.scene.textures[t].alpha, None);
    assert!(r.scene.opaque_at(1, Some(Vec2::new(0.5, 0.5))));
    // The emissive quad whose factor has alpha 0 is a hole everywhere.
    assert!(!r.scene.opaque_at(2, None));
}

/// glTF multiplies COLOR_0's alpha into a masked material's alpha; the importer cuts holes
/// by the texture's alpha only, so a vertex alpha below 1 under a mask is reported as
/// ignored, and one on an opaque material (where glTF ignores alpha too) is not.
#[test]
fn vertex_alpha_on_a_masked_material_is_reported() {
    for (mode, alpha, reported) in [
        ("MASK", 0.5, true),
        ("MASK", 1.0, false),
        ("OPAQUE", 0.5, false),
    ] {
        let bytes = doc(&TRI, Some(&TRI_N), None, 4, |root| {
            let rgba: Vec<f32> = (0..3).flat_map(|_| [1.0f32, 1.0, 1.0, alpha]).collect();
            push_colors(root, &rgba, "VEC4");
            root["meshes"][0]["primitives"][0]["material"] = json!(0);
            root["materials"] = json!([{ "alphaMode": mode }]);
        });
        let r = import_slice(&bytes, Path::new("tinted.gltf")).unwrap();
        let found = r.ignored.iter().any(|i| i.contains("COLOR_0's alpha"));
        assert_eq!(
            found, reported,
            "{mode} with alpha {alpha}: {:?}",
            r.ignored
        );
        assert!(
            r.scene.meshes[0].colors.is_some(),
            "{mode}: the colours are read"
        );
    }
}

/// Adds float `values` as the first primitive's COLOR_0 (`kind` "VEC3" or "VEC4", three
/// vertices) in a buffer of their own.
fn push_colors(root: &mut Value, values: &[f32], kind: &str) {
    let data: Vec<u8> = values.iter().flat_map(|x| x.to_le_bytes()).collect();
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&data)
    );
    let bytes = data.len();
    let buffer = root["buffers"].as_array().unwrap().len();
    root["buffers"]
        .as_array_mut()
        .unwrap()
        .push(json!({ "byteLength": bytes, "uri": uri }));
    let view = root["bufferViews"].as_array().unwrap().len();
    root["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(json!({ "buffer": buffer, "byteLength": bytes }));
    let accessor = root["accessors"].as_array().unwrap().len();
    root["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({ "bufferView": view, "componentType": 5126, "count": 3, "type": kind }));
    root["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(accessor);
}

/// A triangle whose COLOR_0 (float RGB) is `rgb` at every vertex, under an opaque material.
fn tinted(rgb: [f32; 3]) -> Vec<u8> {
    doc(&TRI, Some(&TRI_N), None, 4, |root| {
        let data: Vec<f32> = (0..3).flat_map(|_| rgb).collect();
        push_colors(root, &data, "VEC3");
    })
}

#[test]
fn vertex_colours_that_are_not_finite_are_refused_and_outside_0_1_clamped_with_a_warning() {
    let r = import_slice(&tinted([0.2, 0.5, 0.9]), Path::new("tinted.gltf")).unwrap();
    assert!(
        r.warnings.iter().all(|w| !w.contains("COLOR_0")),
        "{:?}",
        r.warnings
    );
    let e = import_slice(&tinted([f32::NAN, 0.5, 0.5]), Path::new("nan.gltf")).unwrap_err();
    assert!(
        e.to_string().contains("COLOR_0 of vertex 0") && e.to_string().contains("not finite"),
        "{e}"
    );
    let r = import_slice(&tinted([2.0, -0.5, 0.5]), Path::new("bright.gltf")).unwrap();
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("COLOR_0 of 3 of 3 vertices lies outside [0, 1]")),
        "{:?}",
        r.warnings
    );
    assert_eq!(
        r.scene.meshes[0].colors.as_ref().unwrap()[0],
        Vec3::new(1.0, 0.0, 0.5)
    );
}

#[test]
fn a_negative_alpha_cutoff_is_an_invalid_material() {
    for cutoff in [json!(-0.25), json!(-1e30)] {
        let e = import_edited(|r| {
            let m = &mut r["materials"];
            m[1]["alphaMode"] = json!("MASK");
            m[1]["alphaCutoff"] = cutoff.clone();
        })
        .unwrap_err();
        assert!(
            e.to_string().contains("alphaCutoff") && e.to_string().contains("invalid material"),
            "{e}"
        );
    }
}
