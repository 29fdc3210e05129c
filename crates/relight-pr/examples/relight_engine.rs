//! Radiosity relighting as an engine plug-in: the engine's own device, camera matrices and
//! geometry arrays, the light recoloured every frame at the cost of a few factors.
//!
//! The "engine" creates its own wgpu device (relighting runs on it through
//! `GpuContext::from_device`), holds a room as raw vertex, index and material arrays (a
//! floor, a ceiling, four walls and a block, lit by a point light) and a camera as a
//! reverse-Z projection with the far plane at infinity (as Bevy builds it). Once, the example
//! builds a scene-core `Scene` from those arrays, solves it with the light tagged and builds
//! the light's shadow maps (`scene_core::shadowed_lights`); each frame records the element
//! ids, the direct light from the shadow maps at every pixel and the display (eq. 1 per
//! pixel) into the engine's encoder with the frame's light colour (nothing is kept from one view to the next, so a
//! moving camera costs the same). The last line counts the GPU objects a steady-state frame
//! created (wgpu's counters): all zero.
//!
//! The frame is relighting on the one frame contract (`RelightFrame` as a `GpuFrame`): it
//! reads the engine's G-buffer in compact formats without triangle ids, converted each frame
//! by scene-core's `HostGBufferPass`, and renders its own element ids (one raster pass of
//! the element triangles).
//!
//! Run with `cargo run --release -p relight-pr --example relight_engine`.

use std::sync::Arc;

use glam::{Mat4, Vec3};
use relight_pr::display::{Welding, light_slots};
use relight_pr::gpu::GpuRelight;
use relight_pr::gpu_frame::RelightFrame;
use relight_pr::packed::Precision;
use relight_pr::{MeshSettings, Meshing, SolverSettings, solve};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::{
    FrameInputs, GpuContext, GpuFrame, GpuGBuffer, HostGBufferPass, ObjectCounts,
};
use scene_core::lights::{LightId, LightState, light_ids};
use scene_core::ray::RayScene;
use scene_core::shadowed_lights::{LightSet, ShadowSettings};
use scene_core::testing::EngineGBuffer;
use scene_core::{GBufferRenderer, Material, Mesh, PointLight, Scene, View};

const W: u32 = 160;
const H: u32 = 120;

/// The engine's geometry: positions, indices and a material per triangle, as its own
/// arrays. A 4 x 3 x 4 m room (inward-facing quads) with a 1 m block on the floor.
fn engine_arrays() -> (Vec<[f32; 3]>, Vec<u32>, Vec<u32>) {
    let (mut p, mut idx, mut mat) = (Vec::new(), Vec::new(), Vec::new());
    let mut quad = |c: [[f32; 3]; 4], m: u32| {
        let b = p.len() as u32;
        p.extend(c);
        idx.extend([b, b + 1, b + 2, b, b + 2, b + 3]);
        mat.extend([m, m]);
    };
    // Room (seen from inside): floor, ceiling, back, front, left (red), right (green).
    quad(
        [[-2., 0., -2.], [-2., 0., 2.], [2., 0., 2.], [2., 0., -2.]],
        0,
    );
    quad(
        [[-2., 3., -2.], [2., 3., -2.], [2., 3., 2.], [-2., 3., 2.]],
        0,
    );
    quad(
        [[-2., 0., -2.], [2., 0., -2.], [2., 3., -2.], [-2., 3., -2.]],
        0,
    );
    quad(
        [[-2., 0., 2.], [-2., 3., 2.], [2., 3., 2.], [2., 0., 2.]],
        0,
    );
    quad(
        [[-2., 0., -2.], [-2., 3., -2.], [-2., 3., 2.], [-2., 0., 2.]],
        1,
    );
    quad(
        [[2., 0., -2.], [2., 0., 2.], [2., 3., 2.], [2., 3., -2.]],
        2,
    );
    // The block (outward-facing): top and four sides.
    let (lo, hi) = ([-0.8f32, 0.0, -0.9], [0.2f32, 1.0, 0.1]);
    quad(
        [
            [lo[0], hi[1], lo[2]],
            [lo[0], hi[1], hi[2]],
            [hi[0], hi[1], hi[2]],
            [hi[0], hi[1], lo[2]],
        ],
        0,
    );
    quad(
        [
            [lo[0], lo[1], hi[2]],
            [hi[0], lo[1], hi[2]],
            [hi[0], hi[1], hi[2]],
            [lo[0], hi[1], hi[2]],
        ],
        0,
    );
    quad(
        [
            [lo[0], lo[1], lo[2]],
            [lo[0], hi[1], lo[2]],
            [hi[0], hi[1], lo[2]],
            [hi[0], lo[1], lo[2]],
        ],
        0,
    );
    quad(
        [
            [lo[0], lo[1], lo[2]],
            [lo[0], lo[1], hi[2]],
            [lo[0], hi[1], hi[2]],
            [lo[0], hi[1], lo[2]],
        ],
        0,
    );
    quad(
        [
            [hi[0], lo[1], lo[2]],
            [hi[0], hi[1], lo[2]],
            [hi[0], hi[1], hi[2]],
            [hi[0], lo[1], hi[2]],
        ],
        0,
    );
    (p, idx, mat)
}

/// A scene-core `Scene` from the engine's arrays (flat normals from the winding).
fn scene_from_arrays() -> Result<Scene, Box<dyn std::error::Error>> {
    let (p, idx, mat) = engine_arrays();
    let positions: Vec<Vec3> = p.iter().map(|&v| Vec3::from(v)).collect();
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for t in idx.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
        let n = (b - a).cross(c - a).normalize_or_zero();
        for &i in t {
            normals[i as usize] = n;
        }
    }
    let mut scene = Scene::new("engine room");
    scene.meshes.push(Mesh {
        name: "room".into(),
        positions,
        normals,
        indices: idx.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        material_ids: mat,
        ..Default::default()
    });
    scene.materials = vec![
        Material::diffuse("white", Vec3::splat(0.7)),
        Material::diffuse("red", Vec3::new(0.7, 0.15, 0.1)),
        Material::diffuse("green", Vec3::new(0.15, 0.6, 0.15)),
    ];
    scene.point_lights.push(PointLight::new(
        "lamp",
        Vec3::new(0.8, 2.6, 0.8),
        Vec3::splat(8.0),
    ));
    scene.validate()?;
    Ok(scene)
}

/// The engine's own device and queue (any wgpu device will do).
fn engine_device() -> Result<(wgpu::Device, wgpu::Queue), Box<dyn std::error::Error>> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("engine"),
        required_limits: adapter.limits(),
        ..Default::default()
    }))?;
    Ok((device, queue))
}

/// The engine's camera: right-handed, depth in [0, 1], reversed with the far plane at
/// infinity.
fn matrices() -> (Mat4, Mat4) {
    let view = glam::camera::rh::view::look_at_mat4(
        Vec3::new(0.0, 1.5, 1.9),
        Vec3::new(-0.2, 0.9, -1.0),
        Vec3::Y,
    );
    let proj = glam::camera::rh::proj::directx::perspective_infinite_reverse(
        1.2,
        W as f32 / H as f32,
        0.05,
    );
    (view, proj)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (device, queue) = engine_device()?;
    let ctx = GpuContext::from_device(device, queue);
    println!("adapter: {}", ctx.adapter_summary());

    // Once: the scene from the engine's arrays, meshed and solved with the lamp tagged.
    let scene = Arc::new(scene_from_arrays()?);
    let k = light_ids(&scene).len();
    let meshing = Meshing::new(&scene, &MeshSettings::elements(600), k)?;
    let rays = RayScene::build(&scene);
    let solution = solve(
        &scene,
        &meshing,
        &rays,
        &SolverSettings::default(),
        &mut |_| {},
    )?;
    let welding = Welding::new(&meshing, scene.extent());
    let mut gpu = GpuRelight::new(&ctx, &meshing, &welding, &solution, Precision::F16)?;
    // The direct light per frame: the lamp's shadow map, evaluated over each pixel's
    // footprint on a 3 x 3 grid.
    let lights = LightSet::new(&scene, &ShadowSettings::default())?;
    gpu.set_shadowed_direct(&lights, &light_slots(&lights, &solution.sources), 3)?;
    println!(
        "solved: {} elements, {} light source(s), {} KiB on the GPU",
        meshing.elements.len(),
        solution.k(),
        gpu.bytes() / 1024
    );

    let mut method = RelightFrame::new(&ctx, gpu, &meshing, solution.sources.clone())?;

    // The camera from the engine's matrices.
    let (view_m, proj_m) = matrices();
    let (view, depth) = View::from_host_matrices(view_m, proj_m)?;
    println!(
        "camera: reverse-Z {}, infinite far {} (the toolkit's far plane {:.0} m)",
        depth.reverse, depth.infinite, view.far
    );
    // The engine's G-buffer of its own triangles in its compact formats (8-bit sRGB
    // albedo, octahedral half-float normals, its reverse-Z depth buffer, no ids), drawn
    // here by scene-core's ray caster where an engine has its own raster pass, and
    // converted each frame. The frame renders its element ids itself.
    let own = RayCastRenderer::new().render(&scene, &view, W, H)?;
    let engine = EngineGBuffer::compact(&ctx, &own, view.far, &depth)?;
    let mut convert = HostGBufferPass::new(&ctx)?;
    let g = GpuGBuffer::new(&ctx, W, H)?;
    let target = ctx.create_texture_2d(
        "engine frame",
        W,
        H,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
    );

    let mut steady = ObjectCounts::default();
    let mut means = Vec::new();
    for (frame, colour) in [
        Vec3::ONE,
        Vec3::new(1.0, 0.6, 0.2),
        Vec3::new(0.3, 0.5, 1.0),
        Vec3::new(1.0, 0.6, 0.2),
    ]
    .into_iter()
    .enumerate()
    {
        let mut state = LightState::new();
        state.set_color(LightId::Point(0), colour);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let (result, created) = ObjectCounts::during(&ctx.device, || {
            convert.encode(&mut encoder, &engine.host(), &depth, &g)?;
            let inputs = FrameInputs {
                gbuffer: &g,
                view: &view,
                lights: &state,
            };
            method.encode(&mut encoder, &inputs, &target)
        });
        result?;
        if frame > 0 {
            steady = created;
        }
        ctx.queue.submit([encoder.finish()]);
        let pixels = ctx.read_texture_rgba32f(&target)?;
        let mean = pixels
            .iter()
            .fold(Vec3::ZERO, |s, p| s + Vec3::new(p[0], p[1], p[2]))
            / (W * H) as f32;
        println!("light {colour}: mean radiance {mean:.4}");
        means.push(mean);
    }
    // The amber light dims blue to 0.2: the frame followed the light change.
    assert!(means[1].z < 0.3 * means[0].z && means[1].x > 0.9 * means[0].x);
    println!("{}", steady.steady_state_line(&ctx.device));
    Ok(())
}
