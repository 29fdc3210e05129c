//! ISR as an engine plug-in: the engine's own G-buffer textures, camera matrices and light
//! list, with no scene-core `Scene`.
//!
//! The "engine" here creates its own wgpu device (ISR runs on it through
//! `GpuContext::from_device`), builds its camera matrices (reverse-Z with the far plane at
//! infinity, as Bevy does), draws a room corner (a floor and a back wall) by casting rays
//! analytically into a G-buffer in its own compact formats (8-bit sRGB albedo, octahedral
//! half-float normals, its `Depth32Float` depth buffer, no triangle ids), which
//! `HostGBufferPass` turns into the toolkit's each frame, and hands ISR a point light and
//! the triangles that cast shadows. ISR, on the frame contract (`IsrFrame` as a `GpuFrame`,
//! like the other methods' examples), records its passes into the engine's command
//! encoder; a light change between frames only rewrites a buffer, and a steady-state frame
//! creates no GPU object (the last line counts them from wgpu's counters).
//!
//! Run with `cargo run --release -p isr --example isr_engine`.

use glam::{Mat4, Vec3};
use isr::{GpuIsr, GpuIsrInputs, IsrFrame, IsrSettings, Light, LightSet, ShadowSettings};
use scene_core::gpu::{
    FrameInputs, GpuContext, GpuFrame, GpuGBuffer, HostGBuffer, HostGBufferPass, ObjectCounts,
};
use scene_core::lights::{LightId, LightState};
use scene_core::testing::{octahedral_f16, srgb8};
use scene_core::{DepthConvention, View};

const W: u32 = 320;
const H: u32 = 240;

/// The engine's scene: a 4 m floor (y = 0, grey) and back wall (z = 0, red), as triangles.
fn casters() -> Vec<[Vec3; 3]> {
    let quad = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| [[a, b, c], [a, c, d]];
    let mut t = Vec::new();
    t.extend(quad(
        Vec3::new(-2.0, 0.0, 0.0),
        Vec3::new(-2.0, 0.0, 4.0),
        Vec3::new(2.0, 0.0, 4.0),
        Vec3::new(2.0, 0.0, 0.0),
    ));
    t.extend(quad(
        Vec3::new(-2.0, 0.0, 0.0),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(2.0, 3.0, 0.0),
        Vec3::new(-2.0, 3.0, 0.0),
    ));
    t
}

/// The engine's camera matrices: right-handed, depth in [0, 1], reversed (1 at the near
/// plane) with the far plane at infinity.
fn matrices(eye: Vec3, target: Vec3) -> (Mat4, Mat4) {
    let view = glam::camera::rh::view::look_at_mat4(eye, target, Vec3::Y);
    let proj = glam::camera::rh::proj::directx::perspective_infinite_reverse(
        1.0,
        W as f32 / H as f32,
        0.05,
    );
    (view, proj)
}

/// The engine's G-buffer texels in its own compact formats: albedo as 8-bit sRGB, normals
/// as octahedral half floats, depth in its reverse-Z convention (0 where nothing is drawn),
/// no triangle ids.
struct EngineGBuffer {
    albedo: Vec<[u8; 4]>,
    normal: Vec<[u16; 2]>,
    depth: Vec<f32>,
}

/// The engine's G-buffer pass (here: rays against the two planes), writing its depth in
/// the convention of its projection.
fn gbuffer(view: &View, depth_of: &DepthConvention) -> EngineGBuffer {
    let n = (W * H) as usize;
    let (mut albedo, mut normal) = (vec![[0u8; 4]; n], vec![[0u16; 2]; n]);
    let mut depth = vec![0.0f32; n];
    for y in 0..H {
        for x in 0..W {
            let uv = glam::Vec2::new((x as f32 + 0.5) / W as f32, (y as f32 + 0.5) / H as f32);
            let (o, d) = view.ray(uv);
            let floor = (-o.y / d.y, Vec3::Y, [0.6, 0.6, 0.6]);
            let wall = (-o.z / d.z, Vec3::Z, [0.7, 0.15, 0.1]);
            let hit = [floor, wall]
                .into_iter()
                .filter(|(t, ..)| *t > 0.0)
                .filter(|(t, ..)| {
                    let p = o + d * *t;
                    p.x.abs() <= 2.0 && (0.0..=4.0).contains(&p.z) && (0.0..=3.0).contains(&p.y)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((t, nrm, c)) = hit {
                let i = (y * W + x) as usize;
                albedo[i] = [srgb8(c[0]), srgb8(c[1]), srgb8(c[2]), 255];
                normal[i] = octahedral_f16(nrm);
                depth[i] = depth_of.depth((o + d * t - view.eye).dot(view.forward));
            }
        }
    }
    EngineGBuffer {
        albedo,
        normal,
        depth,
    }
}

fn texture(ctx: &GpuContext, format: wgpu::TextureFormat, data: &[u8]) -> wgpu::Texture {
    let usage = wgpu::TextureUsages::TEXTURE_BINDING;
    ctx.texture_with("engine gbuffer", (W, H), format, usage, data)
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

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (device, queue) = engine_device()?;
    let ctx = GpuContext::from_device(device, queue);
    println!("adapter: {}", ctx.adapter_summary());

    // Once: the engine's lights and shadow casters.
    let light = Light::point(
        LightId::Point(0),
        Vec3::new(0.5, 2.2, 2.5),
        Vec3::splat(6.0),
    );
    let lights = LightSet::from_lights(vec![light], &casters(), &ShadowSettings::default())?;
    // The method on the frame contract: prepared once on the engine's device.
    let mut isr = IsrFrame::new(GpuIsr::new(&ctx, &lights)?, IsrSettings::default());

    // The engine's matrices and G-buffer textures in its own formats; each frame turns
    // them into the toolkit's (one compute pass in the engine's encoder).
    let (view_m, proj_m) = matrices(Vec3::new(0.0, 1.6, 5.5), Vec3::new(0.0, 0.8, 0.0));
    let (view, depth_of) = View::from_host_matrices(view_m, proj_m)?;
    let e = gbuffer(&view, &depth_of);
    use wgpu::TextureFormat as F;
    let albedo = texture(&ctx, F::Rgba8UnormSrgb, bytemuck::cast_slice(&e.albedo));
    let normal = texture(&ctx, F::Rg16Float, bytemuck::cast_slice(&e.normal));
    let depth = scene_core::testing::depth_texture_from(&ctx, W, H, &e.depth)?;
    let host = HostGBuffer {
        albedo: &albedo,
        normal: &normal,
        depth: &depth,
        triangle_id: None,
    };
    let mut convert = HostGBufferPass::new(&ctx)?;
    let g = GpuGBuffer::new(&ctx, W, H)?;
    // The engine's HDR target (Rgba16Float works too; Rgba32Float here to read it back).
    let target = isr.isr.output_texture(W, H)?;
    let mut means = Vec::new();
    let mut steady = ObjectCounts::default();
    for (frame, (label, colour)) in [
        ("white light", Vec3::ONE),
        ("amber light", Vec3::new(1.0, 0.6, 0.2)),
        ("blue light", Vec3::new(0.3, 0.5, 1.0)),
        ("amber light", Vec3::new(1.0, 0.6, 0.2)),
    ]
    .into_iter()
    .enumerate()
    {
        let mut state = LightState::new();
        state.set_color(LightId::Point(0), colour);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let (result, created) = ObjectCounts::during(&ctx.device, || {
            convert.encode(&mut encoder, &host, &depth_of, &g)?;
            // The frame applies the light state (the light buffer is rewritten; nothing
            // is recompiled) and records ISR's passes into the engine's encoder.
            let inputs = FrameInputs {
                gbuffer: &g,
                view: &view,
                lights: &state,
            };
            isr.encode(&mut encoder, &inputs, &target)
                .map_err(Box::<dyn std::error::Error>::from)
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
            / pixels.len() as f32;
        println!("{label}: mean radiance {mean:.4}");
        means.push(mean);
    }
    let inputs = GpuIsrInputs {
        full: &g,
        coarse: None,
        view: &view,
    };
    let t = isr.isr.render_timed(&inputs, &isr.settings, &target)?;
    println!(
        "pass times ({}): radiosity {:.2} ms, blur {:.2} ms, upsample {:.2} ms, lighting {:.2} ms",
        if t.gpu_timestamps {
            "GPU timestamps"
        } else {
            "wall clock"
        },
        t.radiosity.as_secs_f64() * 1e3,
        t.blur.as_secs_f64() * 1e3,
        t.upsample.as_secs_f64() * 1e3,
        t.lighting.as_secs_f64() * 1e3
    );
    // Blue is dimmed to 0.2 by the amber light: the frame followed the light change.
    assert!(means[1].z < 0.3 * means[0].z && means[1].x > 0.9 * means[0].x);
    println!("{}", steady.steady_state_line(&ctx.device));
    Ok(())
}
