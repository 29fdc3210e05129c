//! A scene and a camera as a POV-Ray scene file, with the radiosity block of the thesis'
//! Table 1 (the V-Engine exporter's output, listing 9), so POV-Ray can render an independent
//! reference.
//!
//! What is exported: every mesh as a `mesh2` with per-triangle textures (diffuse albedo
//! factor, emission as `emission`; textures are left out), point lights (inverse square
//! through `fade_power 2` with a small `fade_distance` and a compensated colour; the windowed
//! falloff of eq. 16 only roughly),
//! directional lights as `parallel` lights, the camera (right-handed scene mirrored in x,
//! since POV-Ray is left-handed). Radiance is in the scene's units; POV-Ray's light model is
//! not physically identical, so the render is a second opinion, not the ground truth.

use std::fmt::Write as _;
use std::path::Path;

use scene_core::{Camera, Scene};

use crate::HarnessError;

/// The radiosity block of the thesis' Table 1 (`recursion_limit 2`: direct light + one
/// bounce, ISR's scope).
pub const THESIS_RADIOSITY: &str = "radiosity {\n  brightness 2.4\n  pretrace_start 0.08\n  pretrace_end 0.01\n  count 250\n  error_bound 0.25\n  recursion_limit 2\n}";

/// A POV-Ray vector from a right-handed +Y-up point (x mirrored into POV-Ray's left-handed
/// frame).
fn v(p: glam::Vec3) -> String {
    format!("<{},{},{}>", -p.x, p.y, p.z)
}

/// The scene file text for `scene` seen from `camera` at aspect `width / height`.
pub fn export(scene: &Scene, camera: &Camera, width: u32, height: u32) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "#version 3.7;\n// Exported by bench-harness from scene '{}', camera '{}'.\n\
         // Render: povray +W{width} +H{height} +FE +O<out>.exr <this file>\n",
        scene.name, camera.name
    );
    let _ = writeln!(
        o,
        "global_settings {{\n  assumed_gamma 1.0\n  max_trace_level 5\n{}\n}}\n",
        THESIS_RADIOSITY
            .lines()
            .map(|l| format!("  {l}"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    let aspect = width as f32 / height.max(1) as f32;
    let fov_x = 2.0 * ((camera.fov_y * 0.5).tan() * aspect).atan();
    let _ = writeln!(
        o,
        "camera {{\n  perspective\n  location {}\n  look_at {}\n  sky {}\n  right x*{aspect}\n  angle {}\n}}\n",
        v(camera.position),
        v(camera.target),
        v(camera.view_up()),
        fov_x.to_degrees()
    );
    // POV-Ray's diffuse finish has no 1/pi and attenuates by 2 / (1 + (d / f)^2): with a
    // small f that is 2 f^2 / d^2, so the colour I / (2 pi f^2) gives the scene's I / d^2.
    let extent = scene.extent().max(1e-3);
    let f = extent * 1e-3;
    for l in &scene.point_lights {
        let (c, fade) = match l.radius {
            Some(r) => (
                l.intensity / (2.0 * std::f32::consts::PI),
                format!("fade_distance {} fade_power 2", r * 0.5),
            ),
            None => (
                l.intensity / (2.0 * std::f32::consts::PI * f * f),
                format!("fade_distance {f} fade_power 2"),
            ),
        };
        // A spot: POV-Ray's spotlight, full inside `radius` (the inner angle) and dark past
        // `falloff` (the outer one); its ramp between them is POV-Ray's own, not glTF's
        // squared one, so only the full and the dark regions compare exactly.
        let spot = l.cone.map_or(String::new(), |cone| {
            format!(
                " spotlight point_at {} radius {} falloff {} tightness 0",
                v(l.position + cone.axis()),
                cone.inner.to_degrees(),
                cone.outer.to_degrees()
            )
        });
        let _ = writeln!(
            o,
            "light_source {{ {} rgb <{},{},{}> {fade}{spot} }}",
            v(l.position),
            c.x,
            c.y,
            c.z
        );
    }
    let centre = scene.bounds().center();
    // The sky goes as its median-cut directions (parallel lights), as the methods see it.
    for (_, l) in scene_core::lights::directional_sources(scene) {
        let from = centre - l.direction.normalize() * extent * 10.0;
        let c = l.irradiance / std::f32::consts::PI;
        let _ = writeln!(
            o,
            "light_source {{ {} rgb <{},{},{}> parallel point_at {} }}",
            v(from),
            c.x,
            c.y,
            c.z,
            v(centre)
        );
    }
    let _ = writeln!(o);
    for m in &scene.meshes {
        let _ = writeln!(o, "// mesh '{}'\nmesh2 {{", m.name);
        let verts: Vec<String> = m.positions.iter().map(|p| v(*p)).collect();
        let _ = writeln!(
            o,
            "  vertex_vectors {{ {}, {} }}",
            verts.len(),
            verts.join(", ")
        );
        let normals: Vec<String> = m.normals.iter().map(|p| v(*p)).collect();
        let _ = writeln!(
            o,
            "  normal_vectors {{ {}, {} }}",
            normals.len(),
            normals.join(", ")
        );
        let textures: Vec<String> = scene
            .materials
            .iter()
            .map(|mat| {
                let a = mat.albedo;
                let e = mat.emission;
                format!(
                    "texture {{ pigment {{ rgb <{},{},{}> }} finish {{ diffuse 1 ambient 0 emission <{},{},{}> }} }}",
                    a.x, a.y, a.z, e.x, e.y, e.z
                )
            })
            .collect();
        let _ = writeln!(
            o,
            "  texture_list {{ {},\n    {}\n  }}",
            textures.len(),
            textures.join(",\n    ")
        );
        let faces: Vec<String> = m
            .indices
            .iter()
            .zip(&m.material_ids)
            .map(|(t, mat)| format!("<{},{},{}>,{}", t[0], t[1], t[2], mat))
            .collect();
        let _ = writeln!(
            o,
            "  face_indices {{ {}, {} }}\n}}",
            faces.len(),
            faces.join(", ")
        );
    }
    o
}

/// Writes [`export`] to `path`.
pub fn write(
    path: &Path,
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
) -> Result<(), HarnessError> {
    let text = export(scene, camera, width, height);
    scene_core::image::write_via_temp(
        path,
        |tmp| std::fs::write(tmp, &text).map_err(|e| HarnessError::io(path, e)),
        |e| HarnessError::io(path, e),
    )
}

/// True when a `povray` executable is on `PATH`.
pub fn povray_available() -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|d| d.join("povray").is_file()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_export_holds_the_thesis_radiosity_block_the_camera_and_every_triangle() {
        let scene = scene_core::builtin::scene("cornell-point").unwrap();
        let text = export(&scene, &scene.cameras[0], 64, 48);
        for line in [
            "brightness 2.4",
            "pretrace_start 0.08",
            "pretrace_end 0.01",
            "count 250",
            "error_bound 0.25",
            "recursion_limit 2",
        ] {
            assert!(text.contains(line), "{line}");
        }
        assert!(text.contains("camera {") && text.contains("look_at"));
        assert_eq!(text.matches("mesh2 {").count(), scene.meshes.len());
        let faces: usize = scene.meshes.iter().map(|m| m.indices.len()).sum();
        let exported: usize = text
            .lines()
            .filter_map(|l| l.trim().strip_prefix("face_indices { "))
            .map(|l| {
                l.split(',')
                    .next()
                    .unwrap()
                    .trim()
                    .parse::<usize>()
                    .unwrap()
            })
            .sum();
        assert_eq!(exported, faces);
        assert_eq!(
            text.matches("light_source").count(),
            scene.point_lights.len()
        );
        assert!(!text.contains("NaN") && !text.contains("inf"));
    }
}
