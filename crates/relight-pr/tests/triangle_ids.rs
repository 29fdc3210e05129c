//! The id raster a method renders for itself (`TriangleIdPass`, docs/engine.md) against
//! scene-core's ray caster: the same triangle at every pixel centre, but where an edge
//! passes within rounding of a centre; background where no triangle is; typed refusals of
//! a corner that is not finite and of an empty size; and nothing created per frame.

use std::sync::Arc;

use glam::Vec3;
use relight_pr::element_ids::{NO_TRIANGLE, TriangleIdPass};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::ObjectCounts;
use scene_core::testing::gpu_test_context;
use scene_core::{GBufferRenderer, View, builtin};

#[test]
fn the_id_raster_gives_the_ray_casters_triangles() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    for name in ["cornell", "corridor"] {
        let scene = Arc::new(builtin::scene(name).unwrap());
        let pass = TriangleIdPass::for_scene(&ctx, &scene).unwrap();
        assert_eq!(pass.triangles() as usize, scene.triangle_count());
        let (w, h) = (96, 64);
        let view = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
        let g = RayCastRenderer::new().render(&scene, &view, w, h).unwrap();
        let mut ids = Vec::new();
        for frame in 0..3 {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            let (texture, created) =
                ObjectCounts::during(&ctx.device, || pass.encode(&mut encoder, &view, w, h, None));
            let texture = texture.unwrap();
            if frame > 0 {
                assert!(created.is_zero(), "{name} frame {frame}: {created}");
            }
            ctx.queue.submit([encoder.finish()]);
            ids = ctx.read_texture_r32u(&texture).unwrap();
        }
        let background = |id: u32| id == NO_TRIANGLE;
        let differ = ids
            .iter()
            .zip(&g.triangle_id)
            .filter(|(a, b)| a != b)
            .count();
        let mismatched_background = ids
            .iter()
            .zip(&g.triangle_id)
            .filter(|(a, b)| background(**a) != background(**b))
            .count();
        eprintln!(
            "{name}: {differ} of {} pixels name another triangle, {mismatched_background} \
             disagree on background",
            ids.len()
        );
        assert!(
            ids.iter().any(|&i| !background(i)),
            "{name}: geometry in view"
        );
        // An edge within rounding of a pixel centre may fall on either side: at most 1 %
        // of the pixels (a 96 x 64 image of a few hundred triangles has some 1 500 edge
        // pixels, of which only those whose centre lies within rounding may flip).
        assert!(differ * 100 <= ids.len(), "{name}: {differ} pixels differ");
        assert!(mismatched_background * 200 <= ids.len(), "{name}");
    }
}

#[test]
fn the_id_raster_refuses_what_it_cannot_draw() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let bad = [[Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)]];
    let err = TriangleIdPass::new(&ctx, &bad).unwrap_err().to_string();
    assert!(err.contains("triangle 0"), "{err}");
    let pass = TriangleIdPass::new(&ctx, &[]).unwrap();
    let view = View::from_camera(&builtin::scene("cornell").unwrap().cameras[0]);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    assert!(pass.encode(&mut encoder, &view, 0, 4, None).is_err());
    // No triangles: every pixel is background.
    let t = pass.encode(&mut encoder, &view, 8, 4, None).unwrap();
    ctx.queue.submit([encoder.finish()]);
    assert!(
        ctx.read_texture_r32u(&t)
            .unwrap()
            .iter()
            .all(|&i| i == NO_TRIANGLE)
    );
}

/// With the host's depth, a triangle the host does not show at a pixel cannot claim it:
/// the Cornell box's tall block, left out of the host's G-buffer (as a masked surface the
/// host sees through would be), appears only along its contact with the floor, and every
/// other pixel keeps the ray caster's triangle of the full box where the two G-buffers see
/// the same surface.
#[test]
fn the_hosts_depth_keeps_triangles_it_does_not_show_off_the_ids() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let scene = builtin::scene("cornell").unwrap();
    let (w, h) = (96, 64);
    let view = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
    // The mesh to leave out: the one with most pixels that is not the room's largest.
    let full = RayCastRenderer::new().render(&scene, &view, w, h).unwrap();
    let offsets = scene.mesh_offsets();
    let mesh_of = |id: u32| offsets.iter().rposition(|&o| o <= id).unwrap();
    let mut pixels = vec![0usize; scene.meshes.len()];
    for &id in &full.triangle_id {
        if id != NO_TRIANGLE {
            pixels[mesh_of(id)] += 1;
        }
    }
    let mut order: Vec<usize> = (0..scene.meshes.len()).collect();
    order.sort_by_key(|&m| std::cmp::Reverse(pixels[m]));
    let gone = order[1];
    let mut without = scene.clone();
    without.meshes[gone].indices.clear();
    without.meshes[gone].material_ids.clear();
    let host = RayCastRenderer::new()
        .render(&without, &view, w, h)
        .unwrap();
    let host_gpu = scene_core::gpu::GpuGBuffer::upload(&ctx, &host).unwrap();
    let pass = TriangleIdPass::for_scene(&ctx, &scene).unwrap();
    let range = offsets[gone]..offsets[gone] + scene.meshes[gone].indices.len() as u32;
    for matched in [false, true] {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let depth = matched.then_some(&host_gpu.depth);
        let t = pass.encode(&mut encoder, &view, w, h, depth).unwrap();
        ctx.queue.submit([encoder.finish()]);
        let ids = ctx.read_texture_r32u(&t).unwrap();
        let of_gone = ids.iter().filter(|i| range.contains(i)).count();
        eprintln!(
            "match_depth {matched}: {of_gone} pixels of mesh {gone} ({} in view)",
            pixels[gone]
        );
        if matched {
            // Only where the block touches what the host shows (its base on the floor)
            // are the two within 1e-3 of a pixel's depth: a contact line, not its faces.
            assert!(
                of_gone * 100 <= pixels[gone],
                "{of_gone} of {}",
                pixels[gone]
            );
            // Where both G-buffers see the same surface, the full box's triangle.
            let same = (0..ids.len())
                .filter(|&i| {
                    full.triangle_id[i] != NO_TRIANGLE && !range.contains(&full.triangle_id[i])
                })
                .filter(|&i| ids[i] != full.triangle_id[i])
                .count();
            assert!(same * 100 <= ids.len(), "{same} pixels");
        } else {
            assert!(of_gone * 2 >= pixels[gone], "{of_gone} of {}", pixels[gone]);
        }
    }
}
