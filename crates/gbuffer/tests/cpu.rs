//! CPU rasteriser, coarse buffers, reconstruction and packing: tests that need no GPU.

mod common;

use common::*;
use gbuffer::{
    CpuRasterizer, DownsampleMode, FrustumReconstruction, InverseMatrixReconstruction,
    ReconstructionMethod, coarse_size, compare_with_direct, downsample, reconstruct_buffer,
};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::glam::{Vec2, Vec3, Vec4};
use scene_core::{
    BACKGROUND_ID, Error, GBuffer, GBufferRenderer, HemicubeFace, Mesh, Projection, Scene, View,
    builtin,
};

fn camera_view(scene: &Scene, camera: usize, w: u32, h: u32) -> View {
    View::from_camera(&scene.cameras[camera].with_aspect(w as f32 / h as f32))
}

/// Asserts that the CPU rasteriser and primary rays agree on at least 99.5 % of the
/// triangle ids, and closely on depth, normal and albedo where they agree.
fn assert_matches_rays(scene: &Scene, view: &View, w: u32, h: u32, what: &str) {
    let cpu = CpuRasterizer::new().render(scene, view, w, h).unwrap();
    let rays = RayCastRenderer::new().render(scene, view, w, h).unwrap();
    check_invariants(&cpu, view, scene);
    let d = diff(&cpu, &rays);
    assert!(
        d.id_fraction() >= 0.995,
        "{what}: ids agree on {:.3} % of pixels",
        100.0 * d.id_fraction()
    );
    assert!(
        d.max_depth < 1e-4,
        "{what}: depth differs by {}",
        d.max_depth
    );
    assert!(
        d.max_normal < 1e-3,
        "{what}: normal differs by {}",
        d.max_normal
    );
    assert!(
        d.max_albedo < 1e-4,
        "{what}: albedo differs by {}",
        d.max_albedo
    );
}

#[test]
fn cpu_matches_primary_rays_on_every_builtin_scene_and_camera() {
    for name in builtin::SMALL_INSTANCES {
        let scene = builtin::scene(name).unwrap();
        for (c, cam) in scene.cameras.iter().enumerate() {
            let (w, h) = (160, 120);
            let view = camera_view(&scene, c, w, h);
            assert_matches_rays(&scene, &view, w, h, &format!("{name} / {}", cam.name));
        }
    }
}

#[test]
fn cpu_matches_primary_rays_on_hemicube_faces_and_orthographic_views() {
    let scene = std::sync::Arc::new(builtin::scene("cornell").unwrap());
    let mut cpu = CpuRasterizer::new();
    cpu.prepare(scene.clone()).unwrap();
    // A point on the floor of the box, and one on the tall block's side.
    for (point, normal) in [
        (Vec3::new(0.3, 0.0005, 0.25), Vec3::Y),
        (Vec3::new(0.2, 0.2, 0.35), Vec3::new(-0.3, 0.1, -0.9)),
    ] {
        let faces = cpu.render_hemicube(point, normal, 64, 1e-3, 2.0).unwrap();
        assert_eq!(faces.len(), 5);
        for f in &faces {
            let (w, h) = f.face.size(64);
            assert_eq!((f.gbuffer.width, f.gbuffer.height), (w, h));
            assert_matches_rays(&scene, &f.view, w, h, &format!("hemicube {:?}", f.face));
        }
        // The front face sees mostly the box (its open front lets some background in).
        let front = &faces[0];
        assert_eq!(front.face, HemicubeFace::Front);
        let bg = front
            .gbuffer
            .background_mask()
            .iter()
            .filter(|&&b| b)
            .count();
        assert!(bg < front.gbuffer.len() / 2, "{bg} background pixels");
    }
    for name in ["primitives", "many-boxes 50"] {
        let scene = builtin::scene(name).unwrap();
        let b = scene.bounds();
        let sun = scene.directional_lights[0].direction;
        let view = View::orthographic_fit(b.center(), sun, 0.5 * b.diagonal());
        assert_matches_rays(&scene, &view, 128, 128, &format!("{name} shadow-map view"));
    }
}

#[test]
fn shared_edges_cover_every_pixel_exactly_once_with_exact_ties() {
    // Vertices on pixel centres, so edges pass exactly through pixel centres: the fill rule
    // alone decides. Orthographic view of z = 0 with window [-1, 1]^2 at 64x64: pixel
    // centres lie at -1 + (i + 0.5) / 32, and so do the grid vertices (2-pixel spacing).
    let step = 2.0 / 32.0;
    let x0 = -1.0 + 0.5 / 32.0 - 3.0 * step;
    let mesh = grid_mesh(40, x0, step, 0.0, 0.0);
    let scene = one_mesh_scene("grid", mesh);
    let view = View {
        eye: Vec3::new(0.0, 0.0, 1.0),
        forward: -Vec3::Z,
        up: Vec3::Y,
        projection: Projection::Orthographic {
            left: -1.0,
            right: 1.0,
            bottom: -1.0,
            top: 1.0,
        },
        near: 0.1,
        far: 2.0,
    };
    let counts = CpuRasterizer::new()
        .coverage(&scene, &view, 64, 64)
        .unwrap();
    let bad: Vec<usize> = (0..counts.len()).filter(|&i| counts[i] != 1).collect();
    assert!(
        bad.is_empty(),
        "{} pixels not covered once, e.g. {:?}",
        bad.len(),
        &bad[..bad.len().min(8)]
    );
    // The G-buffer agrees: no background, ids from the grid.
    let g = CpuRasterizer::new().render(&scene, &view, 64, 64).unwrap();
    assert!(g.triangle_id.iter().all(|&id| id != BACKGROUND_ID));
}

#[test]
fn shared_edges_of_a_jittered_mesh_in_perspective_crossing_the_near_plane() {
    // 120 x 120 jittered quads over [-30, 30]^2 in the plane z = 0, seen from just above
    // it at a grazing angle, so the near plane cuts the mesh and some triangles are
    // clipped and fanned.
    // (Jitter 0.3: stronger jitter makes some of these sub-pixel slivers near the horizon
    // flip orientation when snapped to 1/256 pixel, and a folded mesh is covered more than
    // once there, on the CPU as on GPUs; see docs/gbuffer.md.)
    let mesh = grid_mesh(120, -30.0, 0.5, 0.0, 0.3);
    let scene = one_mesh_scene("jittered", mesh);
    for (eye, target, near) in [
        (Vec3::new(0.3, -0.2, 0.05), Vec3::new(4.0, 6.0, -1.5), 0.2),
        (Vec3::new(0.0, 0.0, 2.0), Vec3::new(0.5, 0.7, 0.0), 0.5),
    ] {
        let (w, h) = (97, 61);
        let view = look_at(eye, target, 70.0, w as f32 / h as f32, near, 100.0);
        let counts = CpuRasterizer::new().coverage(&scene, &view, w, h).unwrap();
        let mut covered = 0;
        for (i, &c) in counts.iter().enumerate() {
            assert!(c <= 1, "pixel {i} covered {c} times");
            // Analytic expectation: the pixel ray meets z = 0 inside the grid, beyond the
            // near plane and before the far plane (pixels close to those limits skipped).
            let uv = Vec2::new(
                ((i as u32 % w) as f32 + 0.5) / w as f32,
                ((i as u32 / w) as f32 + 0.5) / h as f32,
            );
            let (o, d) = view.ray(uv);
            if d.z.abs() < 1e-6 {
                continue;
            }
            let t = -o.z / d.z;
            let p = o + d * t;
            let depth = (p - view.eye).dot(view.forward);
            let inside = t > 0.0 && p.x.abs() < 30.0 && p.y.abs() < 30.0 && depth < 100.0;
            let margin = (depth - near).abs() < 0.02 * near
                || (p.x.abs() - 30.0).abs() < 0.5
                || (p.y.abs() - 30.0).abs() < 0.5
                || (depth - 100.0).abs() < 1.0;
            if margin || t <= 0.0 {
                continue;
            }
            let expected = u32::from(inside && depth > near);
            assert_eq!(
                c, expected,
                "pixel {i}: coverage {c}, expected {expected} (depth {depth})"
            );
            covered += c;
        }
        assert!(covered > 100, "only {covered} covered pixels");
    }
}

#[test]
fn output_is_bit_identical_for_any_thread_count() {
    let scene = builtin::scene("many-boxes 3000").unwrap();
    let view = camera_view(&scene, 1, 211, 157);
    let render = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            (
                CpuRasterizer::new()
                    .render(&scene, &view, 211, 157)
                    .unwrap(),
                CpuRasterizer::new()
                    .coverage(&scene, &view, 211, 157)
                    .unwrap(),
            )
        })
    };
    let one = render(1);
    for threads in [2, 3, 5] {
        let other = render(threads);
        assert!(one.0 == other.0, "G-buffer differs with {threads} threads");
        assert!(one.1 == other.1, "coverage differs with {threads} threads");
    }
}

#[test]
fn triangles_crossing_the_near_plane_match_primary_rays() {
    // A camera close to the box's back wall, looking along it: the wall and the floor cross
    // the near plane.
    let scene = builtin::scene("cornell").unwrap();
    let view = look_at(
        Vec3::new(0.05, 0.02, 0.5),
        Vec3::new(0.5, 0.2, 0.56),
        80.0,
        4.0 / 3.0,
        0.03,
        2.0,
    );
    assert_matches_rays(&scene, &view, 160, 120, "near-plane crossing");
    // One huge triangle through the eye's plane: its part behind the near plane is clipped.
    let mut m = Mesh::default();
    m.push_triangle(
        [
            Vec3::new(-50.0, -1.0, 10.0),
            Vec3::new(50.0, -1.0, 10.0),
            Vec3::new(0.0, -1.0, -60.0),
        ],
        0,
    );
    let scene = one_mesh_scene("big", m);
    let view = look_at(Vec3::ZERO, Vec3::new(0.0, -0.5, -1.0), 90.0, 1.5, 0.5, 80.0);
    assert_matches_rays(
        &scene,
        &view,
        150,
        100,
        "huge triangle through the near plane",
    );
}

#[test]
fn camera_inside_geometry_sees_inner_faces_facing_it() {
    // Inside one of the tall block's corners of the Cornell box, and inside a closed cube.
    let scene = builtin::scene("cornell").unwrap();
    let inside_block = look_at(
        Vec3::new(0.35, 0.15, 0.35),
        Vec3::new(0.2, 0.1, 0.3),
        60.0,
        1.0,
        1e-3,
        2.0,
    );
    let g = CpuRasterizer::new()
        .render(&scene, &inside_block, 64, 64)
        .unwrap();
    check_invariants(&g, &inside_block, &scene);
    assert_matches_rays(&scene, &inside_block, 64, 64, "inside the tall block");

    let mut cube = Mesh::default();
    let c = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let faces = [
        [
            c(-1., -1., -1.),
            c(1., -1., -1.),
            c(1., 1., -1.),
            c(-1., 1., -1.),
        ],
        [
            c(-1., -1., 1.),
            c(-1., 1., 1.),
            c(1., 1., 1.),
            c(1., -1., 1.),
        ],
        [
            c(-1., -1., -1.),
            c(-1., 1., -1.),
            c(-1., 1., 1.),
            c(-1., -1., 1.),
        ],
        [
            c(1., -1., -1.),
            c(1., -1., 1.),
            c(1., 1., 1.),
            c(1., 1., -1.),
        ],
        [
            c(-1., -1., -1.),
            c(-1., -1., 1.),
            c(1., -1., 1.),
            c(1., -1., -1.),
        ],
        [
            c(-1., 1., -1.),
            c(1., 1., -1.),
            c(1., 1., 1.),
            c(-1., 1., 1.),
        ],
    ];
    for f in faces {
        cube.push_quad(f, 0);
    }
    let scene = one_mesh_scene("cube", cube);
    for target in [Vec3::X, Vec3::Y, Vec3::new(0.3, -0.4, 1.0)] {
        let view = look_at(Vec3::new(0.1, 0.2, -0.3), target, 100.0, 1.25, 0.01, 10.0);
        let g = CpuRasterizer::new().render(&scene, &view, 80, 64).unwrap();
        assert!(
            g.triangle_id.iter().all(|&id| id != BACKGROUND_ID),
            "holes inside the cube"
        );
        check_invariants(&g, &view, &scene);
    }
}

#[test]
fn empty_scene_and_zero_size_targets() {
    let scene = Scene::new("empty");
    let view = look_at(Vec3::ZERO, -Vec3::Z, 60.0, 1.0, 0.1, 10.0);
    let g = CpuRasterizer::new().render(&scene, &view, 17, 9).unwrap();
    assert_eq!(g, GBuffer::background(17, 9));
    let full = builtin::scene("cornell").unwrap();
    for (w, h) in [(0, 0), (0, 4), (4, 0)] {
        let err = CpuRasterizer::new().render(&full, &view, w, h).unwrap_err();
        assert!(matches!(err, Error::InvalidArgument(_)), "{err}");
    }
    assert!(
        CpuRasterizer::new()
            .render(&full, &view, 20_000, 2)
            .is_err()
    );
    let mut bad = view;
    bad.far = bad.near;
    assert!(matches!(
        CpuRasterizer::new().render(&full, &bad, 4, 4),
        Err(Error::InvalidArgument(_))
    ));
    bad = view;
    bad.eye.x = f32::NAN;
    assert!(CpuRasterizer::new().render(&full, &bad, 4, 4).is_err());
}

#[test]
fn one_pixel_and_odd_size_targets() {
    let scene = builtin::scene("cornell").unwrap();
    for c in 0..scene.cameras.len() {
        let view = camera_view(&scene, c, 1, 1);
        let cpu = CpuRasterizer::new().render(&scene, &view, 1, 1).unwrap();
        let rays = RayCastRenderer::new().render(&scene, &view, 1, 1).unwrap();
        assert_eq!(cpu.triangle_id, rays.triangle_id);
        assert!((cpu.depth[0] - rays.depth[0]).abs() < 1e-5);
    }
    let view = camera_view(&scene, 0, 1023, 767);
    assert_matches_rays(&scene, &view, 1023, 767, "cornell at 1023x767");
}

#[test]
fn degenerate_sliver_and_invalid_triangles_are_harmless() {
    let mut m = Mesh::default();
    let p = |x: f32, y: f32| Vec3::new(x, y, 0.0);
    // Zero-area triangles: repeated vertices, collinear vertices.
    m.push_triangle([p(0.0, 0.0), p(0.0, 0.0), p(0.5, 0.5)], 0);
    m.push_triangle([p(-1.0, -1.0), p(0.0, 0.0), p(1.0, 1.0)], 0);
    // Slivers: a fan of needles 1/1000 wide, and one far thinner than a pixel.
    for k in 0..20 {
        let a = k as f32 * 0.3;
        let dir = Vec3::new(a.cos(), a.sin(), 0.0);
        let side = Vec3::new(-dir.y, dir.x, 0.0) * 1e-3;
        m.push_triangle([p(0.0, 0.0), dir - side, dir + side], 0);
    }
    m.push_triangle([p(-0.9, 0.9), p(0.9, 0.9 + 1e-6), p(0.9, 0.9)], 0);
    let mut scene = one_mesh_scene("slivers", m);
    let view = look_at(Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO, 70.0, 1.0, 0.1, 10.0);
    assert_matches_rays(&scene, &view, 128, 128, "slivers");
    // Unvalidated junk: NaN vertices, out-of-range indices and material ids are skipped.
    let mesh = &mut scene.meshes[0];
    mesh.positions.push(Vec3::new(f32::NAN, 0.0, 0.0));
    mesh.normals.push(Vec3::Z);
    let nan = mesh.positions.len() as u32 - 1;
    mesh.indices.push([0, 2, nan]);
    mesh.indices.push([0, 2, 9999]);
    mesh.indices.push([0, 2, 3]);
    mesh.material_ids.extend([0, 0, 77]);
    let g = CpuRasterizer::new().render(&scene, &view, 64, 64).unwrap();
    check_invariants(&g, &view, &scene);
}

#[test]
fn bilinear_textures_match_the_scene_lookup() {
    let scene = textured_quad_scene();
    for (eye, target) in [
        (Vec3::new(0.0, 0.0, 2.5), Vec3::ZERO),
        (Vec3::new(1.5, -1.0, 0.8), Vec3::new(-0.2, 0.3, 0.0)),
    ] {
        let view = look_at(eye, target, 60.0, 1.0, 0.05, 10.0);
        assert_matches_rays(&scene, &view, 96, 96, "textured quad");
        let g = CpuRasterizer::new().render(&scene, &view, 96, 96).unwrap();
        let distinct: std::collections::HashSet<[u32; 3]> = g
            .albedo
            .iter()
            .filter(|a| a.w == 1.0)
            .map(|a| a.truncate().to_array().map(f32::to_bits))
            .collect();
        assert!(
            distinct.len() > 100,
            "texture not sampled ({} colours)",
            distinct.len()
        );
    }
}

#[test]
fn a_million_triangles() {
    let scene = builtin::scene(&format!("many-boxes {}", builtin::MAX_BOXES)).unwrap();
    assert!(scene.triangle_count() >= 999_990);
    // Thousands of sub-pixel boxes per pixel row far away: at 256x192 most differences
    // are still exact ties on edges, all of them on triangle edges.
    for camera in 0..2 {
        let view = camera_view(&scene, camera, 256, 192);
        let g = CpuRasterizer::new()
            .render(&scene, &view, 256, 192)
            .unwrap();
        check_invariants(&g, &view, &scene);
        let rays = RayCastRenderer::new()
            .render(&scene, &view, 256, 192)
            .unwrap();
        let d = diff(&g, &rays);
        assert!(
            d.id_fraction() >= 0.995,
            "ids agree on {:.3} %",
            100.0 * d.id_fraction()
        );
        assert!(
            d.off_edge.is_empty(),
            "differences off edges: {:?}",
            d.off_edge
        );
    }
}

// ---------------------------------------------------------------------------------------
// Coarse buffers

fn pixel(albedo: Vec4, normal: Vec3, depth: f32, id: u32) -> (Vec4, Vec3, f32, u32) {
    (albedo, normal, depth, id)
}

fn gbuffer_from(w: u32, h: u32, px: &[(Vec4, Vec3, f32, u32)]) -> GBuffer {
    let mut g = GBuffer::background(w, h);
    for (i, &(a, n, d, id)) in px.iter().enumerate() {
        g.albedo[i] = a;
        g.normal[i] = n;
        g.depth[i] = d;
        g.triangle_id[i] = id;
    }
    g
}

#[test]
fn downsampling_handles_cancelling_normals_background_and_odd_sizes() {
    let bg = pixel(Vec4::ZERO, Vec3::ZERO, 1.0, BACKGROUND_ID);
    let up = pixel(Vec4::new(0.5, 0.5, 0.5, 1.0), Vec3::Y, 0.3, 1);
    let down = pixel(Vec4::new(0.1, 0.2, 0.3, 1.0), -Vec3::Y, 0.3, 2);
    // A 2x2 block whose normals cancel exactly (a thin double-sided sheet).
    let g = gbuffer_from(2, 2, &[up, down, down, up]);
    for mode in DownsampleMode::ALL {
        let c = downsample(&g, mode);
        assert_eq!((c.width, c.height), (1, 1));
        assert!(
            (c.normal[0].length() - 1.0).abs() < 1e-6,
            "{mode:?}: {}",
            c.normal[0]
        );
        assert!(c.albedo[0].is_finite() && c.depth[0] == 0.3);
    }
    // All background stays background; a single pixel stays itself.
    let g = gbuffer_from(2, 2, &[bg, bg, bg, bg]);
    for mode in DownsampleMode::ALL {
        assert_eq!(downsample(&g, mode), GBuffer::background(1, 1), "{mode:?}");
        let one = gbuffer_from(1, 1, &[up]);
        assert_eq!(downsample(&one, mode), one, "{mode:?}");
    }
    // A silhouette: two samples at 0.2, two background. Average invents depth 0.6 with a
    // mask of 0.5; the median choice keeps a real sample; surface-average keeps the surface.
    let near = pixel(Vec4::new(0.8, 0.1, 0.1, 1.0), Vec3::Z, 0.2, 7);
    let g = gbuffer_from(2, 2, &[near, bg, near, bg]);
    let avg = downsample(&g, DownsampleMode::Average);
    assert!((avg.depth[0] - 0.6).abs() < 1e-6 && (avg.albedo[0].w - 0.5).abs() < 1e-6);
    let med = downsample(&g, DownsampleMode::NearestToMedian);
    assert_eq!((med.depth[0], med.triangle_id[0]), (0.2, 7));
    let surf = downsample(&g, DownsampleMode::SurfaceAverage);
    assert_eq!(
        (surf.depth[0], surf.triangle_id[0], surf.albedo[0].w),
        (0.2, 7, 1.0)
    );
    // Odd sizes: 1023x767 -> 512x384, 3x1 -> 2x1.
    assert_eq!(coarse_size(1023, 767), (512, 384));
    let g = gbuffer_from(3, 1, &[near, up, down]);
    let c = downsample(&g, DownsampleMode::Average);
    assert_eq!((c.width, c.height), (2, 1));
    assert_eq!((c.depth[1], c.triangle_id[1]), (0.3, 2));
    assert!(downsample(&GBuffer::background(0, 0), DownsampleMode::Average).is_empty());
}

#[test]
fn depth_aware_downsampling_invents_no_surfaces_where_averaging_does() {
    for name in ["primitives", "corridor", "many-boxes 500"] {
        let scene = builtin::scene(name).unwrap();
        let (w, h) = (256, 192);
        let view = camera_view(&scene, 0, w, h);
        let fine = CpuRasterizer::new().render(&scene, &view, w, h).unwrap();
        let direct = CpuRasterizer::new()
            .render(&scene, &view, w / 2, h / 2)
            .unwrap();
        let stats = |mode| compare_with_direct(&downsample(&fine, mode), &direct, &fine);
        let avg = stats(DownsampleMode::Average);
        let med = stats(DownsampleMode::NearestToMedian);
        let surf = stats(DownsampleMode::SurfaceAverage);
        assert_eq!(med.invented_depth, 0, "{name}: {med:?}");
        assert_eq!(med.invented_normal, 0, "{name}: {med:?}");
        assert_eq!(surf.invented_depth, 0, "{name}: {surf:?}");
        assert!(avg.invented_depth > 0, "{name}: {avg:?}");
        for s in [avg, med, surf] {
            assert!(s.mean_normal_error_deg.is_finite() && s.mean_albedo_error.is_finite());
        }
    }
}

// ---------------------------------------------------------------------------------------
// Position reconstruction

fn test_views() -> Vec<(String, View)> {
    let mut views = Vec::new();
    for name in ["cornell", "corridor", "many-boxes 50"] {
        let scene = builtin::scene(name).unwrap();
        for (c, cam) in scene.cameras.iter().enumerate() {
            views.push((
                format!("{name}/{}", cam.name),
                camera_view(&scene, c, 1024, 768),
            ));
        }
    }
    for face in HemicubeFace::ALL {
        views.push((
            format!("hemicube {face:?}"),
            View::hemicube(
                Vec3::new(0.3, 0.1, -0.2),
                Vec3::new(0.2, 1.0, 0.1),
                face,
                1e-3,
                3.0,
            ),
        ));
    }
    views.push((
        "shadow map".into(),
        View::orthographic_fit(Vec3::new(1.0, 2.0, 3.0), Vec3::new(-0.3, -1.0, 0.2), 12.0),
    ));
    views
}

#[test]
fn reconstruction_error_is_below_1e4_of_the_depth_range() {
    let mut state = 12345u64;
    let mut rnd = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    for (name, view) in test_views() {
        let fr = FrustumReconstruction::new(&view);
        let inv = InverseMatrixReconstruction::new(&view);
        let range = view.far - view.near;
        let (mut e_fr, mut e_inv, mut e_view, mut e_hw) = (0f32, 0f32, 0f32, 0f32);
        for _ in 0..4000 {
            // A random point inside the frustum: random pixel direction and depth.
            let uv = Vec2::new(rnd(), rnd());
            let t = view.near / view.far + rnd() * (1.0 - view.near / view.far);
            let truth = view.reconstruct_world(uv, t);
            // The G-buffer stores what the view computes for it.
            let d = view.linear_depth(truth);
            let uv = view.project_uv(truth).unwrap();
            e_fr = e_fr.max((fr.world(uv, d) - truth).length());
            e_inv = e_inv.max((inv.world(uv, d) - truth).length());
            let vs = view.view_matrix().transform_point3(truth);
            e_view = e_view
                .max((fr.view_space(uv, d) - vs).length())
                .max((inv.view_space(uv, d) - vs).length());
            e_hw = e_hw.max((inv.world_from_ndc(uv, inv.ndc_depth(d)) - truth).length());
        }
        assert!(
            e_fr < 1e-4 * range,
            "{name}: frustum error {e_fr} (range {range})"
        );
        assert!(
            e_inv < 1e-4 * range,
            "{name}: inverse error {e_inv} (range {range})"
        );
        assert!(e_view < 1e-4 * range, "{name}: view-space error {e_view}");
        // From a 32-bit hyperbolic z-buffer the far field loses precision; it stays usable.
        assert!(
            e_hw < 1e-2 * range,
            "{name}: z-buffer error {e_hw} (range {range})"
        );
    }
}

#[test]
fn reconstruction_of_a_rendered_buffer_hits_its_triangles() {
    let scene = builtin::scene("cornell").unwrap();
    let (w, h) = (96, 72);
    let view = camera_view(&scene, 1, w, h);
    let g = CpuRasterizer::new().render(&scene, &view, w, h).unwrap();
    let offsets = scene.mesh_offsets();
    for method in [
        ReconstructionMethod::FrustumCorners,
        ReconstructionMethod::InverseMatrix,
    ] {
        let pos = reconstruct_buffer(&view, method, &g.depth, w, h, 1);
        for i in (0..g.len()).filter(|&i| !g.is_background(i)) {
            let r = scene.triangle_ref(&offsets, g.triangle_id[i]).unwrap();
            let mesh = &scene.meshes[r.mesh as usize];
            let t = mesh.indices[r.local as usize].map(|k| mesh.positions[k as usize]);
            let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
            assert!(
                n.dot(pos[i] - t[0]).abs() < 1e-4,
                "{method:?} pixel {i}: off its plane"
            );
        }
        // Taps average neighbours: the 24-tap result is finite and near the 1-tap one.
        let many = reconstruct_buffer(&view, method, &g.depth, w, h, 24);
        assert!(many.iter().all(|p| p.is_finite()));
    }
}

#[test]
fn eq22_normal_packing_error_is_as_documented() {
    let (angle, length) = gbuffer::packing::max_packing_error(20_000);
    assert!(angle > 0.05 && angle < 0.45, "worst angle {angle} degrees");
    assert!(length < 0.007, "worst length deviation {length}");
    eprintln!("eq. 22: worst angle {angle} degrees, worst length deviation {length}");
    let n = Vec3::new(0.0, 1.0, 0.0);
    assert_eq!(gbuffer::packing::pack_normal_unorm8(n), [128, 255, 128]);
}
