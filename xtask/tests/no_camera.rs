//! Every command that takes `--scene FILE` works on a glTF file without a camera: camera 0
//! is then the default framing view (`scene_core::Camera::framing`), which sees the scene.

mod common;

use common::xtask;

#[test]
fn commands_on_a_file_without_a_camera_use_the_framing_view() {
    let dir = std::env::temp_dir().join(format!("xtask-no-camera-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut scene = scene_core::builtin::scene("cornell-point").unwrap();
    scene.cameras.clear();
    let file = dir.join("no-camera.gltf");
    scene_core::gltf_io::export(&scene, &file).unwrap();
    assert!(
        scene_core::gltf_io::import(&file)
            .unwrap()
            .scene
            .cameras
            .is_empty()
    );
    let runs: [(&str, &[&str]); 3] = [
        (
            "reference",
            &[
                "--spp",
                "2",
                "--width",
                "16",
                "--height",
                "12",
                "--bounces",
                "0",
            ],
        ),
        (
            "relight",
            &[
                "--elements",
                "64",
                "--width",
                "16",
                "--height",
                "12",
                "--max-unshot",
                "0.05",
            ],
        ),
        (
            "ibrr",
            &[
                "--ldc", "24", "--irpls", "4", "--width", "16", "--height", "12",
            ],
        ),
    ];
    for (command, args) in runs {
        let out = dir.join(command);
        let o = xtask()
            .arg(command)
            .arg("--scene")
            .arg(&file)
            .args(args)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{command}: {err}");
        assert!(
            err.contains("no camera"),
            "{command} does not say it framed the scene: {err}"
        );
        let image = scene_core::Image::read(&out.join("no-camera.exr")).unwrap();
        // The framing view sees the box: most pixels are lit.
        let lit = image
            .pixels
            .iter()
            .filter(|p| p.max_element() > 0.0)
            .count();
        assert!(
            lit * 2 > image.pixels.len(),
            "{command}: {lit} of {} pixels lit",
            image.pixels.len()
        );
    }
    // Another camera index is still an error that names it.
    let o = xtask()
        .args(["ibrr", "--camera", "1", "--scene"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--camera 1"));
    let _ = std::fs::remove_dir_all(&dir);
}
