//! ISR as an engine plug-in: the engine's own G-buffer, camera matrices and light list,
//! with no scene-core `Scene`, through the one frame contract (`scene_core::gpu::GpuFrame`).
//!
//! The engine's device, reverse-Z camera and frame loop are scene-core's `ExampleHost`,
//! shared by every method's example. Particular to ISR: the engine draws a room corner by
//! casting rays into a G-buffer in its own formats (8-bit sRGB albedo, octahedral normals,
//! reverse-Z depth, no ids) and hands ISR a point light and the triangles that cast
//! shadows. The last lines give the GPU objects a steady-state frame created (all zero)
//! and each pass's time.
//!
//! Run with `cargo run --release -p isr --example isr_engine`.

use glam::{Vec2, Vec3};
use isr::{GpuIsrInputs, IsrFrame, IsrSettings, Light, LightSet, ShadowSettings};
use scene_core::gpu::GpuContext;
use scene_core::lights::LightId;
use scene_core::testing::{EngineGBuffer, ExampleError, ExampleHost, octahedral_f16, srgb8};
use scene_core::{DepthConvention, StageTimings, View};

const SIZE: (u32, u32) = (320, 240);
/// Where the engine's point light is.
const LAMP: Vec3 = Vec3::new(0.5, 2.2, 2.5);
/// The engine's planes run 4 m along x from this corner, and along their `edge`.
const CORNER: Vec3 = Vec3::new(-2.0, 0.0, 0.0);
/// Each plane's normal, edge and albedo: a grey floor (y = 0), a red back wall (z = 0).
const PLANES: [(Vec3, Vec3, [f32; 3]); 2] = [
    (Vec3::Y, Vec3::new(0.0, 0.0, 4.0), [0.6; 3]),
    (Vec3::Z, Vec3::new(0.0, 3.0, 0.0), [0.7, 0.15, 0.1]),
];

/// The planes as triangles: the engine's shadow casters.
fn casters() -> Vec<[Vec3; 3]> {
    let (o, u) = (CORNER, Vec3::X * 4.0);
    let quad = |v| [[o, o + u, o + u + v], [o, o + u + v, o + v]];
    PLANES.iter().flat_map(|&(_, v, _)| quad(v)).collect()
}

/// The engine's G-buffer pass (rays against the planes) in its own formats.
fn draw(
    ctx: &GpuContext,
    view: &View,
    depth_of: &DepthConvention,
) -> Result<EngineGBuffer, ExampleError> {
    let n = (SIZE.0 * SIZE.1) as usize;
    let (mut albedo, mut normal, mut depth) = (vec![[0; 4]; n], vec![[0; 2]; n], vec![0.0; n]);
    for i in 0..n {
        let pixel = Vec2::new((i as u32 % SIZE.0) as f32, (i as u32 / SIZE.0) as f32) + 0.5;
        let (o, d) = view.ray(pixel / Vec2::new(SIZE.0 as f32, SIZE.1 as f32));
        let hits = PLANES.iter().filter_map(|&(nrm, edge, c)| {
            let t = (CORNER - o).dot(nrm) / d.dot(nrm);
            let q = o + d * t - CORNER;
            let inside = (0.0..=4.0).contains(&q.x)
                && (0.0..=1.0).contains(&(q.dot(edge) / edge.length_squared()));
            (t > 0.0 && inside).then_some((t, nrm, c))
        });
        if let Some((t, nrm, c)) = hits.min_by(|a, b| a.0.total_cmp(&b.0)) {
            albedo[i] = [srgb8(c[0]), srgb8(c[1]), srgb8(c[2]), 255];
            normal[i] = octahedral_f16(nrm);
            depth[i] = depth_of.depth((o + d * t - view.eye).dot(view.forward));
        }
    }
    Ok(EngineGBuffer::from_texels(
        ctx, SIZE, &albedo, &normal, &depth,
    )?)
}

fn main() -> Result<(), ExampleError> {
    let ctx = ExampleHost::engine_context()?;
    // Once: the engine's light and shadow casters, and ISR prepared on its device.
    let lamp = Light::point(LightId::Point(0), LAMP, Vec3::splat(6.0));
    let lights = LightSet::from_lights(vec![lamp], &casters(), &ShadowSettings::default())?;
    let mut method = IsrFrame::prepare(&ctx, &lights, IsrSettings::screen_space())?;

    let (eye, target) = (Vec3::new(0.0, 1.6, 5.5), Vec3::new(0.0, 0.8, 0.0));
    let matrices = ExampleHost::engine_matrices(eye, target, 1.0, SIZE);
    let mut host = ExampleHost::new(ctx, matrices, SIZE, draw)?;
    host.run_light_cycle(&mut method, LightId::Point(0))?;

    // Each pass's time (GPU timestamps where the adapter has them).
    let inputs = GpuIsrInputs {
        full: host.gbuffer(),
        coarse: None,
        view: &host.view,
    };
    let t = method
        .isr
        .render_timed(&inputs, &method.settings, host.target())?;
    println!(
        "pass times (timestamps: {}): {}",
        t.gpu_timestamps,
        t.describe()
    );
    Ok(())
}
