//! The id raster a method renders for itself (`TriangleIdPass`, docs/engine.md) against
//! scene-core's ray caster: the same triangle at every pixel centre, but where an edge
//! passes within rounding of a centre; background where no triangle is; typed refusals of
//! a corner that is not finite and of an empty size; and nothing created per frame.

use std::sync::Arc;

use glam::Vec3;
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::{NO_TRIANGLE, ObjectCounts, TriangleIdPass, gpu_test_context};
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
                ObjectCounts::during(&ctx.device, || pass.encode(&mut encoder, &view, w, h));
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
    assert!(pass.encode(&mut encoder, &view, 0, 4).is_err());
    // No triangles: every pixel is background.
    let t = pass.encode(&mut encoder, &view, 8, 4).unwrap();
    ctx.queue.submit([encoder.finish()]);
    assert!(
        ctx.read_texture_r32u(&t)
            .unwrap()
            .iter()
            .all(|&i| i == NO_TRIANGLE)
    );
}
