//! Vertex colours (glTF's `COLOR_0`, `scene_core::Mesh::colors`) multiply the albedo in
//! every method: the lit room with its walls and block coloured one colour renders as the
//! same room whose materials' albedo is multiplied by that colour (its twin), in every
//! method, on the CPU and the GPU; a colour ramp over a quad is interpolated alike by the
//! three G-buffer renderers and matches its formula; colours survive a glTF round trip.

use std::sync::Arc;

use golden_tests::scenes::{self, relative_difference as rel, techniques};
use scene_core::glam::{Vec2, Vec3};
use scene_core::scene::{Material, Mesh, Scene};
use scene_core::{GBufferRenderer, Image, Technique, View};

const W: u32 = 48;
const H: u32 = 36;
const TINT: Vec3 = Vec3::new(0.9, 0.55, 0.3);

/// The lit room (a point light) with every vertex of its walls and block tinted, or (the
/// twin) its materials' albedo multiplied by the tint.
fn room(coloured: bool) -> Scene {
    let mut s = scenes::lit_room(true, false);
    if coloured {
        let m = &mut s.meshes[0];
        m.colors = Some(vec![TINT; m.positions.len()]);
    } else {
        for m in &mut s.materials {
            m.albedo *= TINT;
        }
    }
    s.validate().expect("the tinted room is valid");
    s
}

fn render(t: &mut dyn Technique, scene: &Scene) -> Image {
    scenes::render_image(t, scene, W, H)
}

#[test]
fn vertex_colours_multiply_the_albedo_in_every_method() {
    let (coloured, twin) = (room(true), room(false));
    let plain = scenes::lit_room(true, false);
    let ctx = scene_core::testing::gpu_test_context();
    let mut checked = 0;
    let methods = || techniques(ctx.as_ref());
    for (((name, mut a), (_, mut b)), (_, mut c)) in
        methods().into_iter().zip(methods()).zip(methods())
    {
        let on_coloured = render(a.as_mut(), &coloured);
        let on_twin = render(b.as_mut(), &twin);
        let on_plain = render(c.as_mut(), &plain);
        let (d, d_plain) = (rel(&on_coloured, &on_twin), rel(&on_plain, &on_twin));
        eprintln!("{name}: coloured vs twin {d:.5}; uncoloured vs twin {d_plain:.3}");
        // Interpolating one colour may round differently from multiplying it in.
        assert!(d < 1e-3, "{name}: {d}");
        assert!(d_plain > 0.2, "{name}: {d_plain}");
        checked += 1;
    }
    assert!(checked >= 5, "{checked} methods");
}

/// A quad whose four corners carry red, green, blue and white: the G-buffer albedo at a
/// pixel is the material's albedo times the barycentric blend of its triangle's corners,
/// the same in the CPU rasteriser, the ray caster and the GPU rasteriser.
#[test]
fn gbuffers_interpolate_vertex_colours() {
    let mut s = Scene::new("ramp");
    s.materials.push(Material::diffuse("m", Vec3::splat(0.8)));
    let mut m = Mesh {
        name: "quad".into(),
        colors: Some(Vec::new()),
        ..Default::default()
    };
    let corners = [
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    m.push_quad(corners, 0);
    m.colors = Some(vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE]);
    s.meshes.push(m);
    s.cameras.push(scene_core::Camera {
        name: "front".into(),
        position: Vec3::new(0.0, 0.0, 3.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y: 1.0,
        aspect: 1.0,
        near: 0.1,
        far: 10.0,
    });
    s.validate().unwrap();
    let view = View::from_camera(&s.cameras[0]);
    let (w, h) = (64, 64);
    let mut renderers: Vec<(&str, Box<dyn GBufferRenderer>)> = vec![
        ("cpu", Box::new(gbuffer::CpuRasterizer::new())),
        (
            "rays",
            Box::new(scene_core::gbuffer::RayCastRenderer::new()),
        ),
    ];
    if let Some(ctx) = scene_core::testing::gpu_test_context() {
        renderers.push(("gpu", Box::new(gbuffer::GpuRasterizer::new(&ctx).unwrap())));
    }
    // The expected albedo where the ray through a pixel centre meets the quad.
    let expected = |x: u32, y: u32| -> Option<Vec3> {
        let (o, d) = view.ray(scene_core::view::pixel_uv(x, y, w, h));
        let t = -o.z / d.z;
        let p = o + d * t;
        if p.x.abs() >= 0.999 || p.y.abs() >= 0.999 {
            return None;
        }
        let q = Vec2::new(p.x, p.y);
        // Triangles (0, 1, 2) and (0, 2, 3) of push_quad.
        let blend = |a: Vec2, b: Vec2, c: Vec2, ca: Vec3, cb: Vec3, cc: Vec3| {
            let (e1, e2, dq) = (b - a, c - a, q - a);
            let det = e1.perp_dot(e2);
            let (u, v) = (dq.perp_dot(e2) / det, e1.perp_dot(dq) / det);
            (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then(|| ca * (1.0 - u - v) + cb * u + cc * v)
        };
        let c2 = |v: Vec3| Vec2::new(v.x, v.y);
        let [a, b, c, d] = corners.map(c2);
        blend(a, b, c, Vec3::X, Vec3::Y, Vec3::Z)
            .or_else(|| blend(a, c, d, Vec3::X, Vec3::Z, Vec3::ONE))
            .map(|c| c * 0.8)
    };
    for (name, mut r) in renderers {
        r.prepare(Arc::new(s.clone())).unwrap();
        let g = r.render_view(&view, w, h).unwrap();
        let mut worst = 0.0f32;
        let mut seen = 0;
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                let Some(want) = expected(x, y) else { continue };
                if g.triangle_id[i] == scene_core::BACKGROUND_ID {
                    continue;
                }
                worst = worst.max((g.albedo[i].truncate() - want).abs().max_element());
                seen += 1;
            }
        }
        eprintln!("{name}: {seen} pixels, worst albedo error {worst:.2e}");
        assert!(seen > 1000, "{name}: {seen}");
        assert!(worst < 1e-3, "{name}: {worst}");
    }
}

#[test]
fn vertex_colours_round_trip_through_gltf() {
    let coloured = room(true);
    let dir = std::env::temp_dir().join(format!("colour-round-trip-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("tinted.glb");
    scene_core::gltf_io::export(&coloured, &path).unwrap();
    let back = scene_core::gltf_io::import(&path).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert!(back.ignored.is_empty(), "{:?}", back.ignored);
    let colors = back.scene.meshes[0]
        .colors
        .as_ref()
        .expect("COLOR_0 came back");
    assert!(
        colors
            .iter()
            .all(|c| (*c - TINT).abs().max_element() < 1e-6)
    );
    // The walls mesh only: the other meshes of the file have none.
    assert_eq!(colors.len(), back.scene.meshes[0].positions.len());
}

#[test]
fn relighting_exports_a_coloured_scene_with_its_colours_beside_the_preview() {
    // `xtask relight` exited 1 on any glTF with COLOR_0: the export's preview is COLOR_0
    // too. The scene's colours now travel as `_SOURCE_COLOR_0` and the file re-imports.
    let coloured = Arc::new(room(true));
    let mut t = relight_pr::RelightTechnique::new(
        relight_pr::MeshSettings::elements(64),
        relight_pr::SolverSettings::default(),
        Box::new(gbuffer::CpuRasterizer::new()),
    );
    t.prepare(coloured.clone()).unwrap();
    let p = t.prepared().unwrap();
    let dir = std::env::temp_dir().join(format!("colour-export-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("relit.gltf");
    relight_pr::export::gltf(
        &coloured,
        &p.meshing,
        &p.welding,
        &p.solution,
        &Default::default(),
        0.0,
        &path,
    )
    .expect("a scene with vertex colours exports");
    let text = std::fs::read_to_string(&path).unwrap();
    let back = scene_core::gltf_io::import(&path).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert!(text.contains("_SOURCE_COLOR_0") && text.contains("\"COLOR_0\""));
    let preview = back.scene.meshes[0].colors.as_ref().expect("the preview");
    assert!(preview.iter().any(|c| c.max_element() > 0.0));
}
