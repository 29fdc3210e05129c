//! A user's glTF without lights renders in one command: `--sun DIR=RGB`, `--point
//! POS=RGB` and `--sky RGB|FILE.exr` add lights to the scene every command opens (in the file's coordinates), noted
//! on stderr; malformed values are refused before any work, naming the flag.

mod common;

use common::xtask;

fn lit_fraction(image: &scene_core::Image) -> f32 {
    image
        .pixels
        .iter()
        .filter(|p| p.max_element() > 0.0)
        .count() as f32
        / image.pixels.len() as f32
}

#[test]
fn a_lightless_file_renders_with_added_lights() {
    let dir = std::env::temp_dir().join(format!("xtask-added-lights-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut scene = scene_core::builtin::scene("cornell-point").unwrap();
    let light = scene.point_lights.remove(0);
    assert!(scene.materials.iter().all(|m| !m.is_emissive()));
    let file = dir.join("dark.gltf");
    scene_core::gltf_io::export(&scene, &file).unwrap();
    let small = ["--width", "16", "--height", "12"];
    let run = |command: &str, extra: &[&str], out: &str| {
        xtask()
            .arg(command)
            .arg("--scene")
            .arg(&file)
            .args(small)
            .args(extra)
            .arg("--out")
            .arg(dir.join(out))
            .output()
            .unwrap()
    };
    let reference = ["--spp", "4", "--bounces", "1"];
    // Without lights: black, and said.
    let o = run("reference", &reference, "dark");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("no light"), "{err}");
    let dark = scene_core::Image::read(&dir.join("dark/dark.exr")).unwrap();
    assert_eq!(lit_fraction(&dark), 0.0);
    // The file's own light put back by --point: the same picture as the scene with it.
    let p = light.position;
    let i = light.intensity;
    let spec = format!("{},{},{}={},{},{}", p.x, p.y, p.z, i.x, i.y, i.z);
    let o = run(
        "reference",
        &[&reference[..], &["--point", &spec]].concat(),
        "point",
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("added 'point 1'"), "{err}");
    let lit = scene_core::Image::read(&dir.join("point/dark.exr")).unwrap();
    let original = scene_core::builtin::scene("cornell-point").unwrap();
    let path = dir.join("original.gltf");
    scene_core::gltf_io::export(&original, &path).unwrap();
    let o = xtask()
        .arg("reference")
        .arg("--scene")
        .arg(&path)
        .args(small)
        .args(reference)
        .arg("--out")
        .arg(dir.join("original"))
        .output()
        .unwrap();
    assert!(o.status.success());
    let want = scene_core::Image::read(&dir.join("original/original.exr")).unwrap();
    let diff: f32 = lit
        .pixels
        .iter()
        .zip(&want.pixels)
        .map(|(a, b)| (*a - *b).abs().element_sum())
        .sum::<f32>()
        / want.pixels.iter().map(|p| p.element_sum()).sum::<f32>();
    // Same scene, same seed: only the light's name and the file's order may differ.
    assert!(diff < 0.05, "{diff}");
    assert!(lit_fraction(&lit) > 0.5);
    // A sun through relighting (a global flag, before or after the command).
    let o = xtask()
        .args(["--sun", "0.2,-1,0.3=2"])
        .arg("relight")
        .arg("--scene")
        .arg(&file)
        .args(small)
        .args(["--elements", "64", "--max-unshot", "0.05", "--out"])
        .arg(dir.join("sun"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("added 'sun 1'"), "{err}");
    // A uniform sky through the box's open front, in the reference and in the IBRR.
    for (command, extra) in [
        ("reference", &reference[..]),
        ("ibrr", &["--ldc", "32", "--irpls", "8"][..]),
    ] {
        let out = format!("sky-{command}");
        let o = run(command, &[extra, &["--sky", "0.8,0.9,1"]].concat(), &out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{command}: {err}");
        assert!(err.contains("added sky 'uniform sky'"), "{command}: {err}");
        let image = scene_core::Image::read(&dir.join(&out).join("dark.exr")).unwrap();
        assert!(
            lit_fraction(&image) > 0.3,
            "{command}: {}",
            lit_fraction(&image)
        );
    }
    // Malformed values: refused, naming the flag, nothing written.
    for (flag, value) in [
        ("--sun", "0,0,0=1"),
        ("--point", "1,2=3"),
        ("--sun", "0,-1,0=-2"),
        ("--sky", "blue"),
        ("--sky", "no-such-sky.exr"),
    ] {
        let out = format!("bad{}", flag.len());
        let o = run(
            "reference",
            &[&reference[..], &[flag, value]].concat(),
            &out,
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{flag} {value}");
        assert!(err.contains(flag), "{flag} {value}: {err}");
        assert!(!dir.join(&out).exists(), "{flag} {value} wrote output");
    }
    std::fs::remove_dir_all(&dir).ok();
}
