//! The generated large interior (`building`): exported as glTF it passes Khronos' validator,
//! imports with every triangle, material, texture and light, gets random cameras inside its
//! rooms, and runs the main job end to end at a small size.

mod common;

use common::xtask;
use scene_core::glam::Vec3;

#[test]
fn the_generated_building_exports_imports_validates_and_runs_the_experiment() {
    let dir = std::env::temp_dir().join(format!("xtask-building-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("building.gltf");
    let o = xtask()
        .args(["export-gltf", "--scene", "building", "--out"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    scene_core::testing::gltf_validator::assert_valid(&[&file]);

    // The file holds what the generator built: a large textured interior with a lamp per
    // room and a sun.
    let built = scene_core::builtin::scene("building").unwrap();
    let imported = scene_core::gltf_io::import(&file).unwrap();
    let mut scene = imported.scene;
    scene.validate().unwrap();
    assert_eq!(scene.triangle_count(), built.triangle_count());
    assert!(
        scene.triangle_count() >= 200_000,
        "{}",
        scene.triangle_count()
    );
    assert!(
        scene.materials.len() >= 24,
        "{} materials",
        scene.materials.len()
    );
    assert_eq!(scene.textures.len(), built.textures.len());
    assert!(scene.textures.len() >= 5);
    assert!(
        scene
            .materials
            .iter()
            .filter(|m| m.albedo_texture.is_some())
            .count()
            >= 20
    );
    assert_eq!(scene.point_lights.len(), 12);
    assert_eq!(scene.directional_lights.len(), 1);

    // Random cameras land inside the rooms (not on the ground outside or above the roof).
    let cams = bench_harness::random_cameras(&scene, 4, &Default::default()).unwrap();
    for c in &cams {
        let p = c.position;
        assert!(
            p.cmpgt(Vec3::new(0.0, 0.0, 0.0)).all() && p.cmplt(Vec3::new(20.0, 3.0, 15.0)).all(),
            "{} at {p} is outside the building",
            c.name
        );
    }

    // The main job on the file at a small size, one view from the file and one random.
    let out = dir.join("experiment");
    let o = xtask()
        .args(["experiment", "--scene"])
        .arg(&file)
        .args([
            "--views",
            "2",
            "--size",
            "32x24",
            "--spp",
            "16",
            "--repeats",
            "1",
        ])
        .args([
            "--techniques",
            "dl,isr-24,ibrr-32-16",
            "--sequence-frames",
            "2",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: bench_harness::Results =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    assert_eq!(r.views.len(), 2);
    for v in &r.views {
        for t in &v.techniques {
            for e in &t.errors {
                assert!(e.metrics.iter().all(|(_, x)| x.is_finite()), "{}", t.label);
            }
        }
    }
    assert_eq!(r.sequence.as_ref().map(|q| q.frames.len()), Some(2));
    assert!(out.join("report.html").is_file());
    std::fs::remove_dir_all(&dir).ok();
}
