//! The Mitsuba export (`bench_harness::mitsuba`) against the scene it was made from: every
//! triangle written once, with its own material's BSDF, and the lights and bounce limit as
//! Mitsuba reads them. (Rendering it needs Mitsuba, which the toolkit does not depend on:
//! docs/reference.md has the comparison.)

use std::path::Path;

use bench_harness::mitsuba;
use scene_core::builtin;

/// (vertex count, face count) from a binary PLY's header, and the body's length.
fn ply_counts(path: &Path) -> (usize, usize, usize) {
    let bytes = std::fs::read(path).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    let count = |what: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {what} ")))
            .unwrap()
            .parse()
            .unwrap()
    };
    (count("vertex"), count("face"), bytes.len() - end)
}

#[test]
fn every_triangle_is_written_once_with_its_material() {
    let dir = std::env::temp_dir().join(format!("bench-harness-mitsuba-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for (name, bounces, depth) in [("cornell", None, "-1"), ("cornell-point", Some(1), "3")] {
        let scene = builtin::scene(name).unwrap();
        let xml = mitsuba::export(&scene, &scene.cameras[0], 32, 24, 4, bounces, &dir).unwrap();
        let text = std::fs::read_to_string(&xml).unwrap();
        assert!(
            text.contains(&format!("name=\"max_depth\" value=\"{depth}\"")),
            "{name}"
        );
        let mut faces = 0;
        let mut shapes = 0;
        for (mi, mesh) in scene.meshes.iter().enumerate() {
            let mut ids = mesh.material_ids.clone();
            ids.sort_unstable();
            ids.dedup();
            for m in ids {
                let file = format!("mesh_{mi}_{m}.ply");
                let (v, f, body) = ply_counts(&dir.join(&file));
                let expected = mesh.material_ids.iter().filter(|&&x| x == m).count();
                assert_eq!(f, expected, "{name} {file}");
                // 8 floats a vertex, a count byte and 3 indices a face.
                assert_eq!(body, v * 32 + f * 13, "{name} {file}");
                let shape = format!("value=\"{file}\"/>\n    <ref id=\"m{m}\"/>");
                assert!(
                    text.contains(&shape),
                    "{name}: {file} without material m{m}"
                );
                faces += f;
                shapes += 1;
            }
        }
        assert_eq!(faces, scene.triangle_count(), "{name}");
        // Every material reflects on both sides, as the toolkit's do.
        assert_eq!(
            text.matches("type=\"twosided\"").count(),
            scene.materials.len(),
            "{name}"
        );
        assert_eq!(text.matches("<shape ").count(), shapes, "{name}");
        let emitters = scene.materials.iter().filter(|m| m.is_emissive()).count();
        assert_eq!(emitters > 0, text.contains("type=\"area\""), "{name}");
        assert_eq!(
            text.matches("type=\"point\"").count(),
            scene.point_lights.len(),
            "{name}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
