//! `cargo xtask relight`: writes the view, the glTF export (validated) and a summary with
//! the lights it was given, a
//! switched-off light leaves the picture black, and an unknown light id is an error that
//! lists the scene's ids.

mod common;

use common::{run_with_summary, xtask};

#[test]
fn relight_writes_the_view_and_the_summary_with_the_given_lights() {
    let out = std::env::temp_dir().join(format!("xtask-relight-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let run = |light: &str| {
        let mut c = xtask();
        c.args(["relight", "--scene", "cornell-point", "--elements", "128"])
            .args(["--width", "32", "--height", "24", "--max-unshot", "0.01"])
            .args(["--light", light]);
        run_with_summary(c, &out, "cornell-point")
    };
    let (summary, lit) = run("point:0=3,2,1");
    assert_eq!(summary["lights"][0]["id"], "point:0");
    assert_eq!(
        summary["lights"][0]["emission"],
        serde_json::json!([3.0, 2.0, 1.0])
    );
    // The solution holds at most 1.25x the elements asked (the meshing's 456 mesh
    // elements grouped), at least half of them.
    let elements = summary["elements"].as_u64().unwrap();
    assert!((64..=160).contains(&elements), "{elements} elements");
    assert_eq!(summary["elements_asked"], 128);
    assert!(summary["mesh_elements"].as_u64().unwrap() > elements);
    assert!(summary["unshot_fraction"].as_f64().unwrap() <= 0.01);
    assert!(out.join("cornell-point.png").is_file());
    // The engine export: per-light radiosity and a preview colour per vertex, one
    // triangle per mesh element, accepted by Khronos' validator.
    let gltf = out.join("cornell-point.gltf");
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&gltf).unwrap()).unwrap();
    let attributes = &doc["meshes"][0]["primitives"][0]["attributes"];
    assert!(attributes["_RADIOSITY_POINT_0"].is_u64(), "{attributes}");
    assert!(attributes["COLOR_0"].is_u64(), "{attributes}");
    let back = scene_core::gltf_io::import(&gltf).unwrap().scene;
    assert_eq!(
        back.triangle_count() as u64,
        summary["mesh_elements"].as_u64().unwrap()
    );
    assert_eq!(back.point_lights.len(), 1);
    scene_core::testing::gltf_validator::assert_valid(&[gltf.as_path()]);
    let mean = |img: &scene_core::Image| img.mean();
    // Red above green above blue, as the light.
    let m = mean(&lit);
    assert!(m.x > m.y && m.y > m.z && m.z > 0.0, "{m}");
    let (_, dark) = run("point:0=0,0,0");
    assert_eq!(mean(&dark), scene_core::glam::Vec3::ZERO);
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn an_unknown_light_id_lists_the_scene_s_lights() {
    let o = xtask()
        .args(["relight", "--scene", "corridor", "--light", "lamp=1,1,1"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("no light 'lamp'") && err.contains("point:0, point:1, point:2, point:3"),
        "{err}"
    );
}

#[test]
fn the_hierarchical_solver_renders_what_the_progressive_one_does() {
    let dir = std::env::temp_dir().join(format!("xtask-relight-h-{}", std::process::id()));
    let run = |solver: &str| {
        let mut c = xtask();
        c.args(["relight", "--scene", "cornell", "--elements", "256"])
            .args(["--width", "32", "--height", "24", "--max-unshot", "0.001"])
            .args(["--solver", solver]);
        run_with_summary(c, &dir.join(solver), "cornell")
    };
    let (p, progressive) = run("progressive");
    let (h, hierarchical) = run("hierarchical");
    assert_eq!(h["solver"], "hierarchical");
    assert_eq!(p["solver"], "progressive");
    assert!(p["hierarchy"].is_null());
    // The default picks by the meshing's size: cornell's 256-element target stays
    // progressive, and says so.
    let (auto, _) = run("auto");
    assert_eq!(auto["solver_asked"], "auto");
    assert_eq!(auto["solver"], "progressive");
    assert!(h["hierarchy"]["far_links"].as_u64().unwrap() > 0, "{h}");
    assert!(h["hierarchy"]["link_bytes"].as_u64().unwrap() > 0, "{h}");
    // The same picture: per-pixel direct light is the same gather; the indirect light
    // comes from either solve (within the solves' 6 % bound of tests/hierarchical.rs).
    let (a, b) = (hierarchical.mean(), progressive.mean());
    assert!(
        (a - b).abs().max_element() <= 0.06 * b.max_element(),
        "{a} against {b}"
    );
    let bad = xtask()
        .args(["relight", "--scene", "cornell", "--solver", "gauss-seidel"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("--solver gauss-seidel"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
