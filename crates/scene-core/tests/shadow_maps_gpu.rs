//! Shadow maps rendered on the GPU from an engine's vertex and index buffers
//! (`ShadowMapPass`, docs/engine.md) against the CPU's ray-cast maps of the same lights and
//! casters (`LightSet::from_lights`): the texels agree but where a caster's edge passes
//! within rounding of a texel centre, and the shadowed irradiance they give over the
//! Cornell box's visible surfaces agrees to rounding; a layout the pass cannot draw and
//! casters that are not a triangle list are refused by name.

use glam::Vec3;
use scene_core::gbuffer::RayCastRenderer;
use scene_core::lights::LightId;
use scene_core::shadowed_lights::gpu_maps::{CasterLayout, Casters, ShadowMapPass};
use scene_core::shadowed_lights::{Light, LightSet, ShadowSettings};
use scene_core::testing::gpu_test_context;
use scene_core::{Bounds, GBufferRenderer, Scene, View, builtin};
use wgpu::util::DeviceExt;

/// The Cornell box's point lights and emitter samples, and a sun through it.
fn lights(scene: &Scene, shadows: &ShadowSettings) -> Vec<Light> {
    let mut lights = LightSet::new(scene, shadows).unwrap().lights;
    lights.push(Light::directional(
        LightId::Directional(0),
        Vec3::new(-0.3, -1.0, -0.2),
        Vec3::splat(2.0),
    ));
    lights
}

#[test]
fn gpu_shadow_maps_equal_the_ray_cast_maps() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    // The default (the cube maps prefiltered, the orthographic ones not) and the other way
    // round.
    for (filter_radius, directional_filter_radius) in [(1, 0), (0, 1)] {
        eprintln!(
            "prefilter radius {filter_radius} (cubes), {directional_filter_radius} (orthographic):"
        );
        gpu_maps_equal_ray_cast_maps(&ctx, filter_radius, directional_filter_radius);
    }
}

fn gpu_maps_equal_ray_cast_maps(
    ctx: &scene_core::gpu::GpuContext,
    filter_radius: u32,
    directional_filter_radius: u32,
) {
    let scene = builtin::scene("cornell").unwrap();
    let shadows = ShadowSettings {
        cube_resolution: 64,
        emitter_samples: 6,
        emitter_cube_resolution: 32,
        directional_resolution: 128,
        filter_radius,
        directional_filter_radius,
        ..Default::default()
    };
    let casters = scene.triangle_corners();
    let lights = lights(&scene, &shadows);
    let cpu = LightSet::from_lights(lights.clone(), &casters, &shadows).unwrap();
    let bounds = Bounds::around(casters.iter().flatten().copied());
    let (mut gpu_set, plan) = LightSet::planned(lights, bounds, &shadows).unwrap();
    assert_eq!(gpu_set.extent, cpu.extent);
    assert_eq!(gpu_set.shadow_texels.len(), cpu.shadow_texels.len());
    assert_eq!(plan.len(), gpu_set.lights.len());

    // The engine's buffers: positions with a normal beside them (stride 24), u32 indices.
    let vertices: Vec<[f32; 6]> = casters
        .iter()
        .flatten()
        .map(|p| [p.x, p.y, p.z, 0.0, 1.0, 0.0])
        .collect();
    let indices: Vec<u32> = (0..vertices.len() as u32).collect();
    let vb = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("engine vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
    let ib = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("engine indices"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
    let layout = CasterLayout {
        stride: 24,
        offset: 0,
    };
    let pass = ShadowMapPass::new(ctx, &gpu_set, &plan, layout).unwrap();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    let bad = Casters {
        vertices: &vb,
        indices: Some((&ib, wgpu::IndexFormat::Uint32)),
        count: 4,
    };
    let e = pass.encode(&mut encoder, &gpu_set, &bad).unwrap_err();
    assert!(e.to_string().contains("multiple of 3"), "{e}");
    pass.encode(
        &mut encoder,
        &gpu_set,
        &Casters {
            count: indices.len() as u32,
            ..bad
        },
    )
    .unwrap();
    ctx.queue.submit([encoder.finish()]);
    let texels = pass.read_texels(ctx).unwrap();

    let n = texels.len();
    let diffs: Vec<f32> = texels
        .iter()
        .zip(&cpu.shadow_texels)
        .map(|(g, c)| (g - c).abs())
        .collect();
    let worst = diffs.iter().copied().fold(0.0f32, f32::max);
    let off = diffs.iter().filter(|&&d| d > 1e-4).count();
    let mean = diffs.iter().map(|&d| f64::from(d)).sum::<f64>() / n as f64;
    eprintln!(
        "{n} texels: {off} off by more than 1e-4 extents, mean difference {mean:.2e}, worst {worst:.3}"
    );
    // A texel whose centre an edge passes within rounding of may see either surface, and
    // the filter spreads it to its 3 x 3 neighbours: 9 texels per flip. Nothing else is
    // off by more than rounding.
    assert!(off * 100 <= n, "{off} of {n} texels");

    // What the maps give: the shadowed irradiance at the box's visible points.
    gpu_set.shadow_texels = texels;
    let (w, h) = (48, 36);
    let view = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
    let g = RayCastRenderer::new().render(&scene, &view, w, h).unwrap();
    let (mut sum_cpu, mut sum_gpu, mut sum_diff) = (0.0f64, 0.0f64, 0.0f64);
    for i in 0..g.len() {
        if g.is_background(i) {
            continue;
        }
        let uv = glam::Vec2::new(
            ((i as u32 % w) as f32 + 0.5) / w as f32,
            ((i as u32 / w) as f32 + 0.5) / h as f32,
        );
        let p = view.reconstruct_world(uv, g.depth[i]);
        let n = g.normal[i];
        let a = cpu.irradiance(p, n, scene_core::shadowed_lights::Part::Direct);
        let b = gpu_set.irradiance(p, n, scene_core::shadowed_lights::Part::Direct);
        sum_cpu += f64::from(a.element_sum());
        sum_gpu += f64::from(b.element_sum());
        sum_diff += f64::from((a - b).abs().element_sum());
    }
    eprintln!(
        "irradiance over the view: CPU maps {sum_cpu:.4}, GPU maps {sum_gpu:.4}, mean \
         absolute difference {:.2e} of it",
        sum_diff / sum_cpu
    );
    assert!(sum_cpu > 0.0);
    assert!(sum_diff <= 1e-3 * sum_cpu, "{sum_diff} of {sum_cpu}");
}

#[test]
fn the_shadow_map_pass_refuses_a_layout_it_cannot_draw() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let lights = vec![Light::point(LightId::Point(0), Vec3::Y, Vec3::ONE)];
    let bounds = Bounds {
        min: Vec3::splat(-1.0),
        max: Vec3::splat(1.0),
    };
    let (set, plan) = LightSet::planned(lights, bounds, &ShadowSettings::default()).unwrap();
    for (stride, offset) in [(8, 0), (24, 16), (14, 0)] {
        let e = ShadowMapPass::new(&ctx, &set, &plan, CasterLayout { stride, offset })
            .unwrap_err()
            .to_string();
        assert!(e.contains("caster vertex layout"), "{stride}/{offset}: {e}");
    }
    let bad_bounds = Bounds {
        min: Vec3::splat(f32::NAN),
        max: Vec3::ONE,
    };
    let lights = vec![Light::point(LightId::Point(0), Vec3::Y, Vec3::ONE)];
    assert!(LightSet::planned(lights, bad_bounds, &ShadowSettings::default()).is_err());
}
