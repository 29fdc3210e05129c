//! The image-based radiosity representation as an engine plug-in: the engine's own device,
//! camera matrices and compact G-buffer, the light recoloured every frame without
//! rebuilding the layered depth cube, through the one frame contract
//! (`scene_core::gpu::GpuFrame`).
//!
//! The "engine" creates its own wgpu device (the IBRR runs on it through
//! `GpuContext::from_device`), a camera as a reverse-Z projection with the far plane at
//! infinity (as Bevy builds it) and a G-buffer in its own compact formats: 8-bit sRGB
//! albedo, octahedral half-float normals, its reverse-Z `Depth32Float` depth buffer, no
//! triangle ids (stood in for here by scene-core's ray caster, packed by
//! `EngineGBuffer`). Once, the IBRR builds its LDC for the Cornell box (light kept per
//! source). Each frame converts the engine's G-buffer (`HostGBufferPass`) and records
//! `IbrrFrame::encode` into the engine's encoder and its target texture: the layers' light
//! recombined for the frame's colour of the ceiling panel on the CPU, the relit values
//! copied in, the reconstruction. Without ids the panel's own pixels do not glow (docs/
//! engine.md). The last line counts the GPU objects a steady-state frame created (wgpu's
//! counters): all zero.
//!
//! Run with `cargo run --release -p ibrr-ldc --example ibrr_engine`.

use std::sync::Arc;

use glam::Vec3;
use ibrr_ldc::{IbrrFrame, IbrrSettings, IbrrTechnique};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::{
    FrameInputs, GpuContext, GpuFrame, GpuGBuffer, HostGBufferPass, ObjectCounts,
};
use scene_core::lights::{LightId, LightState, light_ids};
use scene_core::testing::EngineGBuffer;
use scene_core::{GBufferRenderer, Technique, View, builtin};

const W: u32 = 160;
const H: u32 = 120;

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

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (device, queue) = engine_device()?;
    let ctx = GpuContext::from_device(device, queue);
    println!("adapter: {}", ctx.adapter_summary());

    // Once: the LDC, its light kept per source.
    let scene = Arc::new(builtin::scene("cornell")?);
    let settings = IbrrSettings {
        resolution: 96,
        irpls: 48,
        ..Default::default()
    };
    let mut ibrr = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    ibrr.prepare(scene.clone())?;
    let layers = ibrr.ldc().ok_or("the LDC was not built")?.layer_count();
    let mut method = IbrrFrame::new(&ctx, ibrr, scene.clone())?;
    println!("LDC: {layers} layers");

    // The engine's camera (the scene's, as engine matrices: reverse-Z, infinite far).
    let cam = &scene.cameras[0];
    let view_m = glam::camera::rh::view::look_at_mat4(cam.position, cam.target, cam.up);
    let proj_m = glam::camera::rh::proj::directx::perspective_infinite_reverse(
        cam.fov_y,
        W as f32 / H as f32,
        cam.near,
    );
    let (view, depth) = View::from_host_matrices(view_m, proj_m)?;
    println!(
        "camera: reverse-Z {}, infinite far {}",
        depth.reverse, depth.infinite
    );
    // The engine's G-buffer in its compact formats, converted each frame.
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

    let panel = *light_ids(&scene)
        .iter()
        .find(|i| matches!(i, LightId::Emissive(_)))
        .ok_or("the scene has no emissive panel")?;
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
        state.set_color(panel, colour);
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
        println!("panel {colour}: mean radiance {mean:.4}");
        means.push(mean);
    }
    // The amber light dims blue to 0.2: the frame followed the light change.
    assert!(means[1].z < 0.3 * means[0].z && means[1].x > 0.9 * means[0].x);
    println!("{}", steady.steady_state_line(&ctx.device));
    Ok(())
}
