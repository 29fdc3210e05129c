//! GPU renderer, downsampling and reconstruction against their CPU twins. They run on any
//! wgpu adapter (Mesa's lavapipe in CI, where `REQUIRE_GPU=1` turns a missing adapter
//! into a failure) and skip with a message where there is none.

mod common;

use common::*;
use gbuffer::{
    CpuRasterizer, DownsampleMode, GpuDownsampler, GpuRasterizer, GpuReconstructor,
    ReconstructionMethod, downsample, reconstruct_buffer,
};
use scene_core::glam::Vec3;
use scene_core::gpu::{GpuContext, GpuGBuffer};
use scene_core::testing::gpu_test_context;
use scene_core::{
    BACKGROUND_ID, Error, GBuffer, GBufferRenderer, HemicubeFace, Mesh, Scene, View, builtin,
};

fn camera_view(scene: &Scene, camera: usize, w: u32, h: u32) -> View {
    View::from_camera(&scene.cameras[camera].with_aspect(w as f32 / h as f32))
}

/// The criterion: triangle ids equal on at least 99.5 % of pixels and different
/// only on triangle edges; depth, normals (and albedo) within 1e-4 elsewhere.
fn assert_gpu_matches_cpu(cpu: &GBuffer, gpu: &GBuffer, what: &str) {
    let d = diff(cpu, gpu);
    assert!(
        d.id_fraction() >= 0.995,
        "{what}: ids agree on {:.3} % of pixels",
        100.0 * d.id_fraction()
    );
    assert!(
        d.off_edge.is_empty(),
        "{what}: ids differ off triangle edges at {:?}",
        d.off_edge
    );
    assert!(
        d.max_depth <= 1e-4,
        "{what}: depth differs by {}",
        d.max_depth
    );
    assert!(
        d.max_normal <= 1e-4,
        "{what}: normal differs by {}",
        d.max_normal
    );
    assert!(
        d.max_albedo <= 1e-4,
        "{what}: albedo differs by {}",
        d.max_albedo
    );
}

fn compare(gpu: &mut GpuRasterizer, scene: &Scene, view: &View, w: u32, h: u32, what: &str) {
    let cpu_g = CpuRasterizer::new().render(scene, view, w, h).unwrap();
    let gpu_g = gpu.render(scene, view, w, h).unwrap();
    check_invariants(&gpu_g, view, scene);
    assert_gpu_matches_cpu(&cpu_g, &gpu_g, what);
}

fn context() -> Option<(GpuContext, GpuRasterizer)> {
    let ctx = gpu_test_context()?;
    let rast = GpuRasterizer::new(&ctx).unwrap();
    Some((ctx, rast))
}

#[test]
fn gpu_matches_cpu_on_every_builtin_scene_and_camera() {
    let Some((ctx, mut gpu)) = context() else {
        return;
    };
    eprintln!("GPU tests on {}", ctx.adapter_summary());
    for name in builtin::SMALL_INSTANCES {
        let scene = builtin::scene(name).unwrap();
        for (c, cam) in scene.cameras.iter().enumerate() {
            let (w, h) = (200, 150);
            let view = camera_view(&scene, c, w, h);
            compare(
                &mut gpu,
                &scene,
                &view,
                w,
                h,
                &format!("{name} / {}", cam.name),
            );
        }
    }
}

#[test]
fn gpu_matches_cpu_on_hemicubes_shadow_maps_and_textures() {
    let Some((_ctx, mut gpu)) = context() else {
        return;
    };
    let scene = std::sync::Arc::new(builtin::scene("cornell").unwrap());
    let point = Vec3::new(0.3, 0.0005, 0.25);
    let mut cpu = CpuRasterizer::new();
    cpu.prepare(scene.clone()).unwrap();
    gpu.prepare(scene.clone()).unwrap();
    let cpu_faces = cpu.render_hemicube(point, Vec3::Y, 48, 1e-3, 2.0).unwrap();
    let gpu_faces = gpu.render_hemicube(point, Vec3::Y, 48, 1e-3, 2.0).unwrap();
    for (c, g) in cpu_faces.iter().zip(&gpu_faces) {
        assert_gpu_matches_cpu(&c.gbuffer, &g.gbuffer, &format!("hemicube {:?}", c.face));
    }
    // The batched GPU hemicube gives the same buffers as the trait path.
    let prepared = gpu.upload(&scene).unwrap();
    let batched = gpu
        .render_hemicube_gpu(&prepared, point, Vec3::Y, 48, 1e-3, 2.0)
        .unwrap();
    assert_eq!(batched.len(), 5);
    for ((face, view, target), g) in batched.iter().zip(&gpu_faces) {
        assert_eq!((*face, *view), (g.face, g.view));
        assert_eq!(target.read_back(gpu.context()).unwrap(), g.gbuffer);
    }
    assert_eq!(batched[1].0, HemicubeFace::Right);
    for name in ["primitives", "many-boxes 50"] {
        let scene = builtin::scene(name).unwrap();
        let b = scene.bounds();
        let sun = scene.directional_lights[0].direction;
        let view = View::orthographic_fit(b.center(), sun, 0.5 * b.diagonal());
        compare(
            &mut gpu,
            &scene,
            &view,
            128,
            128,
            &format!("{name} shadow map"),
        );
    }
    let scene = textured_quad_scene();
    let view = look_at(
        Vec3::new(1.5, -1.0, 0.8),
        Vec3::new(-0.2, 0.3, 0.0),
        60.0,
        1.0,
        0.05,
        10.0,
    );
    compare(&mut gpu, &scene, &view, 96, 96, "textured quad");
    // glTF's other samplers: coordinates over [-0.6, 1.9] under clamp, mirrored repeat and
    // nearest filtering, the GPU's lookup against scene-core's.
    let mut scene = scene;
    for uv in scene.meshes[0].uvs.iter_mut().flatten() {
        *uv = *uv * 1.25 - scene_core::glam::Vec2::splat(0.6);
    }
    use scene_core::{Sampler, Wrap};
    for (wrap_u, wrap_v, nearest) in [
        (Wrap::ClampToEdge, Wrap::MirroredRepeat, false),
        (Wrap::MirroredRepeat, Wrap::ClampToEdge, true),
        (Wrap::Repeat, Wrap::MirroredRepeat, true),
    ] {
        scene.textures[0].sampler = Sampler {
            wrap_u,
            wrap_v,
            nearest,
        };
        let name = format!("textured quad, {wrap_u:?}/{wrap_v:?}, nearest {nearest}");
        compare(&mut gpu, &scene, &view, 96, 96, &name);
    }
}

#[test]
fn gpu_hard_cases() {
    let Some((ctx, mut gpu)) = context() else {
        return;
    };
    let cornell = builtin::scene("cornell").unwrap();
    // 1x1 and odd size.
    let view = camera_view(&cornell, 0, 1, 1);
    compare(&mut gpu, &cornell, &view, 1, 1, "1x1");
    let view = camera_view(&cornell, 2, 1023, 767);
    compare(&mut gpu, &cornell, &view, 1023, 767, "1023x767");
    // Near-plane crossing and a camera inside geometry.
    let view = look_at(
        Vec3::new(0.05, 0.02, 0.5),
        Vec3::new(0.5, 0.2, 0.56),
        80.0,
        4.0 / 3.0,
        0.03,
        2.0,
    );
    compare(&mut gpu, &cornell, &view, 160, 120, "near-plane crossing");
    let view = look_at(
        Vec3::new(0.35, 0.15, 0.35),
        Vec3::new(0.2, 0.1, 0.3),
        60.0,
        1.0,
        1e-3,
        2.0,
    );
    compare(&mut gpu, &cornell, &view, 64, 64, "inside the tall block");
    let mut m = Mesh::default();
    m.push_triangle(
        [
            Vec3::new(-50.0, -1.0, 10.0),
            Vec3::new(50.0, -1.0, 10.0),
            Vec3::new(0.0, -1.0, -60.0),
        ],
        0,
    );
    let big = one_mesh_scene("big", m);
    let view = look_at(Vec3::ZERO, Vec3::new(0.0, -0.5, -1.0), 90.0, 1.5, 0.5, 80.0);
    compare(&mut gpu, &big, &view, 150, 100, "huge triangle");
    // Slivers and degenerate triangles.
    let mut m = Mesh::default();
    let p = |x: f32, y: f32| Vec3::new(x, y, 0.0);
    m.push_triangle([p(0.0, 0.0), p(0.0, 0.0), p(0.5, 0.5)], 0);
    for k in 0..20 {
        let a = k as f32 * 0.3;
        let dir = Vec3::new(a.cos(), a.sin(), 0.0);
        let side = Vec3::new(-dir.y, dir.x, 0.0) * 1e-3;
        m.push_triangle([p(0.0, 0.0), dir - side, dir + side], 0);
    }
    let slivers = one_mesh_scene("slivers", m);
    let view = look_at(Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO, 70.0, 1.0, 0.1, 10.0);
    let cpu_g = CpuRasterizer::new()
        .render(&slivers, &view, 128, 128)
        .unwrap();
    let gpu_g = gpu.render(&slivers, &view, 128, 128).unwrap();
    // Needles a fraction of a pixel wide: coverage is all edge, so only ids that agree are
    // compared.
    let d = diff(&cpu_g, &gpu_g);
    assert!(d.max_depth <= 1e-4 && d.max_normal <= 1e-4, "{d:?}");
    // Empty scene: background only, read back.
    let empty = Scene::new("empty");
    let g = gpu.render(&empty, &view, 7, 5).unwrap();
    assert_eq!(g, GBuffer::background(7, 5));
    // Zero size is an error, not a panic.
    assert!(matches!(
        gpu.render(&cornell, &view, 0, 3),
        Err(Error::InvalidArgument(_))
    ));
    let _ = ctx;
}

#[test]
fn gpu_result_stays_on_the_gpu_until_read_back_and_the_cache_follows_the_scene() {
    let Some((ctx, mut gpu)) = context() else {
        return;
    };
    let mut scene = builtin::scene("cornell").unwrap();
    let view = camera_view(&scene, 0, 64, 48);
    let prepared = gpu.upload(&scene).unwrap();
    let target: GpuGBuffer = gpu.render_gpu(&prepared, &view, 64, 48).unwrap();
    let depth_attachment = ctx
        .read_texture_r32f(target.depth_attachment().unwrap())
        .unwrap();
    let explicit = target.read_back(&ctx).unwrap();
    assert_eq!(explicit, gpu.render(&scene, &view, 64, 48).unwrap());
    // The hardware depth is the clip-space z of the same surfaces: 1 exactly on background.
    for (i, &z) in depth_attachment.iter().enumerate() {
        assert_eq!(z == 1.0, explicit.is_background(i), "pixel {i}: z {z}");
    }
    // Recolour a material: the cached upload must be replaced.
    let before = gpu.render(&scene, &view, 64, 48).unwrap();
    scene.materials[0].albedo = Vec3::new(0.1, 0.2, 0.3);
    let after = gpu.render(&scene, &view, 64, 48).unwrap();
    assert_ne!(before.albedo, after.albedo);
    let cpu_after = CpuRasterizer::new().render(&scene, &view, 64, 48).unwrap();
    assert_gpu_matches_cpu(&cpu_after, &after, "after recolouring");
}

#[test]
fn gpu_downsampling_matches_cpu() {
    let Some((ctx, mut gpu)) = context() else {
        return;
    };
    let down = GpuDownsampler::new(&ctx).unwrap();
    for (name, w, h) in [
        ("primitives", 157, 93),
        ("corridor", 128, 96),
        ("cornell", 1, 1),
    ] {
        let scene = builtin::scene(name).unwrap();
        let view = camera_view(&scene, 0, w, h);
        let prepared = gpu.upload(&scene).unwrap();
        let fine = gpu.render_gpu(&prepared, &view, w, h).unwrap();
        let fine_cpu = fine.read_back(&ctx).unwrap();
        for mode in DownsampleMode::ALL {
            let coarse = down.run(&fine, mode).unwrap().read_back(&ctx).unwrap();
            let expected = downsample(&fine_cpu, mode);
            assert_eq!(
                (coarse.width, coarse.height),
                (expected.width, expected.height)
            );
            assert_eq!(coarse.triangle_id, expected.triangle_id, "{name} {mode:?}");
            for i in 0..coarse.len() {
                let close = |a: f32, b: f32| (a - b).abs() <= 1e-6;
                assert!(
                    close(coarse.depth[i], expected.depth[i]),
                    "{name} {mode:?} {i}"
                );
                assert!(
                    (coarse.normal[i] - expected.normal[i]).abs().max_element() <= 1e-6,
                    "{name} {mode:?} {i}: {} vs {}",
                    coarse.normal[i],
                    expected.normal[i]
                );
                assert!(
                    (coarse.albedo[i] - expected.albedo[i]).abs().max_element() <= 1e-6,
                    "{name} {mode:?} {i}"
                );
            }
        }
        let _ = gpu.render(&scene, &view, w, h).unwrap();
    }
    // A coarse buffer of the wrong size is refused.
    let fine = GpuGBuffer::new(&ctx, 8, 8).unwrap();
    let wrong = GpuGBuffer::new(&ctx, 3, 4).unwrap();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    assert!(
        down.encode(&mut enc, &fine, &wrong, DownsampleMode::Average)
            .is_err()
    );
}

#[test]
fn gpu_reconstruction_matches_cpu() {
    let Some((ctx, gpu)) = context() else {
        return;
    };
    let recon = GpuReconstructor::new(&ctx).unwrap();
    for name in ["cornell", "corridor"] {
        let scene = builtin::scene(name).unwrap();
        let (w, h) = (101, 77);
        let view = camera_view(&scene, 0, w, h);
        let prepared = gpu.upload(&scene).unwrap();
        let target = gpu.render_gpu(&prepared, &view, w, h).unwrap();
        let g = target.read_back(&ctx).unwrap();
        let hw = ctx
            .read_texture_r32f(target.depth_attachment().unwrap())
            .unwrap();
        let range = view.far - view.near;
        for method in ReconstructionMethod::ALL {
            let input = match method {
                ReconstructionMethod::InverseMatrixHardwareDepth => &hw,
                _ => &g.depth,
            };
            for taps in [1, 24] {
                let gpu_pos = recon.run(&view, &target, method, taps).unwrap();
                let cpu_pos = reconstruct_buffer(&view, method, input, w, h, taps);
                let worst = gpu_pos
                    .iter()
                    .zip(&cpu_pos)
                    .map(|(a, b)| (*a - *b).length())
                    .fold(0.0f32, f32::max);
                // The z-buffer route is ill-conditioned (see reconstruct.rs): rounding
                // differences between drivers grow about tenfold there.
                let tolerance = match method {
                    ReconstructionMethod::InverseMatrixHardwareDepth => 1e-4,
                    _ => 1e-5,
                };
                assert!(
                    worst < tolerance * range,
                    "{name} {method:?} taps {taps}: GPU and CPU differ by {worst}"
                );
            }
        }
        // Frustum corners against the geometry: every geometry pixel lies on its triangle.
        let pos = recon
            .run(&view, &target, ReconstructionMethod::FrustumCorners, 1)
            .unwrap();
        let offsets = scene.mesh_offsets();
        for i in (0..g.len()).filter(|&i| g.triangle_id[i] != BACKGROUND_ID) {
            let r = scene.triangle_ref(&offsets, g.triangle_id[i]).unwrap();
            let mesh = &scene.meshes[r.mesh as usize];
            let t = mesh.indices[r.local as usize].map(|k| mesh.positions[k as usize]);
            let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
            assert!(
                n.dot(pos[i] - t[0]).abs() < 1e-4 * range,
                "{name} pixel {i}"
            );
        }
    }
}

#[test]
fn gpu_a_million_triangles() {
    let Some((_ctx, mut gpu)) = context() else {
        return;
    };
    let scene = builtin::scene(&format!("many-boxes {}", builtin::MAX_BOXES)).unwrap();
    let view = camera_view(&scene, 1, 256, 192);
    compare(
        &mut gpu,
        &scene,
        &view,
        256,
        192,
        "many-boxes 10^6 triangles",
    );
}

/// Prepared once, a renderer draws batches of views with no further upload: the batch
/// equals one-off renders view by view, the GPU batch can stay on the GPU, and nothing
/// renders before `prepare`.
#[test]
fn prepared_batches_equal_one_off_renders_and_can_stay_on_the_gpu() {
    let Some((ctx, mut gpu)) = context() else {
        return;
    };
    let scene = std::sync::Arc::new(builtin::scene("cornell").unwrap());
    let e = gpu
        .render_views(&[scene_core::ViewTarget::new(
            View::from_camera(&scene.cameras[0]),
            8,
            8,
        )])
        .unwrap_err();
    assert!(matches!(e, Error::NotPrepared(_)), "{e}");
    gpu.prepare(scene.clone()).unwrap();
    let camera = View::from_camera(&scene.cameras[0]);
    let face = View::hemicube(
        Vec3::new(0.3, 0.001, 0.25),
        Vec3::Y,
        HemicubeFace::Up,
        1e-3,
        2.0,
    );
    let targets = [
        scene_core::ViewTarget::new(camera, 40, 30),
        scene_core::ViewTarget::new(face, 32, 16),
        scene_core::ViewTarget::new(camera, 17, 9),
    ];
    let batch = gpu.render_views(&targets).unwrap();
    let on_gpu = gpu
        .render_views_gpu(&targets)
        .unwrap()
        .expect("the GPU keeps its G-buffers");
    let mut cpu = CpuRasterizer::new();
    assert!(cpu.render_views_gpu(&targets).unwrap().is_none());
    for ((t, b), g) in targets.iter().zip(&batch).zip(&on_gpu) {
        let alone = gpu.render(&scene, &t.view, t.width, t.height).unwrap();
        assert_eq!(b, &alone, "{}x{}", t.width, t.height);
        assert_eq!(&g.read_back(&ctx).unwrap(), b);
    }
}
