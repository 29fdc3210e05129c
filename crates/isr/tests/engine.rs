//! ISR without a scene-core `Scene`, as an engine runs it: its own light list and shadow
//! casters ([`LightSet::from_lights`]), its own G-buffer textures
//! ([`GpuGBuffer::from_textures`]), several views per submission.

mod common;

use common::{Setup, image_mean, max_difference, mean_error, small_shadows};
use glam::Vec3;
use isr::{GpuIsr, GpuIsrInputs, IsrSettings, Light, LightSet, ShadowSettings};
use scene_core::gpu::{GpuError, GpuGBuffer};
use scene_core::lights::LightId;
use scene_core::testing::gpu_test_context;
use scene_core::{Image, Scene, builtin};

/// The scene's triangles, as an engine would hand them over.
fn triangles(scene: &Scene) -> Vec<[Vec3; 3]> {
    scene.triangle_corners()
}

/// The scene's point lights, as an engine's light list.
fn engine_lights(scene: &Scene) -> Vec<Light> {
    scene
        .point_lights
        .iter()
        .enumerate()
        .map(|(i, l)| Light::point(LightId::Point(i as u32), l.position, l.intensity))
        .collect()
}

#[test]
fn an_engine_light_list_and_casters_give_the_scene_path_s_frame() {
    let scene = builtin::scene("cornell-point").unwrap();
    let shadows = small_shadows();
    let from_scene = Setup::with_prepared(
        scene.clone(),
        LightSet::new(&scene, &shadows).unwrap(),
        0,
        48,
        36,
    );
    let engine =
        LightSet::from_lights(engine_lights(&scene), &triangles(&scene), &shadows).unwrap();
    assert_eq!(engine.extent, from_scene.prepared.extent);
    assert_eq!(engine.shadow_texels, from_scene.prepared.shadow_texels);
    let a = from_scene.render(&IsrSettings::screen_space());
    let b =
        Setup::with_prepared(scene.clone(), engine, 0, 48, 36).render(&IsrSettings::screen_space());
    assert_eq!(a.pixels, b.pixels);

    // No casters: unshadowed, as the scene path with shadows off.
    let off = ShadowSettings {
        enabled: false,
        ..shadows
    };
    let unshadowed = LightSet::from_lights(engine_lights(&scene), &[], &shadows).unwrap();
    assert!(!unshadowed.shadows.enabled && unshadowed.shadow_texels.is_empty());
    // The extent differs (the light's position alone against the box), which scales ISR's
    // sampling radius, so the direct-light image is the one to compare exactly.
    let dl = IsrSettings::dl();
    let c = Setup::with_prepared(scene.clone(), unshadowed, 0, 48, 36).render(&dl);
    let d = Setup::with_prepared(
        scene.clone(),
        LightSet::new(&scene, &off).unwrap(),
        0,
        48,
        36,
    )
    .render(&dl);
    assert_eq!(c.pixels, d.pixels);
    // Unshadowed light reaches the floor under the blocks: brighter than with shadows.
    let shadowed = from_scene.render(&dl);
    assert!(image_mean(&c) > image_mean(&shadowed));
}

#[test]
fn bad_engine_lights_are_refused_by_name() {
    let nan = Light::point(LightId::Point(3), Vec3::new(f32::NAN, 0.0, 0.0), Vec3::ONE);
    let e = LightSet::from_lights(vec![nan], &[], &ShadowSettings::default()).unwrap_err();
    assert!(e.to_string().contains("Point(3)"), "{e}");
    let nodir = Light::directional(LightId::Directional(0), Vec3::ZERO, Vec3::ONE);
    let e = LightSet::from_lights(vec![nodir], &[], &ShadowSettings::default()).unwrap_err();
    assert!(e.to_string().contains("no direction"), "{e}");
    let bad_caster = [[Vec3::ZERO, Vec3::X, Vec3::splat(f32::INFINITY)]];
    let ok = Light::point(LightId::Point(0), Vec3::Y, Vec3::ONE);
    let e = LightSet::from_lights(vec![ok], &bad_caster, &ShadowSettings::default()).unwrap_err();
    assert!(e.to_string().contains("caster #0"), "{e}");
}

fn texture(
    ctx: &scene_core::gpu::GpuContext,
    format: wgpu::TextureFormat,
    w: u32,
    h: u32,
) -> wgpu::Texture {
    let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
    ctx.create_texture_2d("engine texture", w, h, format, usage)
}

#[test]
fn engine_textures_are_checked_and_two_views_share_one_submission() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    use wgpu::TextureFormat as F;
    // Formats are checked, naming the expected one.
    let wrong = GpuGBuffer::from_textures(
        texture(&ctx, F::Rgba8Unorm, 8, 8),
        texture(&ctx, F::Rgba32Float, 8, 8),
        texture(&ctx, F::R32Float, 8, 8),
        texture(&ctx, F::R32Uint, 8, 8),
    )
    .unwrap_err();
    assert!(
        matches!(
            wrong,
            GpuError::WrongFormat {
                expected: "Rgba32Float",
                ..
            }
        ),
        "{wrong}"
    );
    let size = GpuGBuffer::from_textures(
        texture(&ctx, F::Rgba32Float, 8, 8),
        texture(&ctx, F::Rgba32Float, 8, 8),
        texture(&ctx, F::R32Float, 8, 4),
        texture(&ctx, F::R32Uint, 8, 8),
    )
    .unwrap_err();
    assert!(size.to_string().contains("depth"), "{size}");

    // Two cameras of one scene, encoded into one command buffer, each with its own
    // uniforms: each output equals that view rendered alone.
    let mut scene = builtin::scene("cornell-point").unwrap();
    let mut moved = scene.cameras[0].clone();
    moved.position += Vec3::new(0.08, 0.03, -0.05);
    scene.cameras.push(moved);
    let prepared = LightSet::new(&scene, &small_shadows()).unwrap();
    let setups = [0, 1].map(|c| Setup::with_prepared(scene.clone(), prepared.clone(), c, 40, 30));
    assert_ne!(setups[0].full, setups[1].full);
    let mut isr = GpuIsr::new(&ctx, &prepared).unwrap();
    let alone: Vec<Image> = setups
        .iter()
        .map(|s| {
            isr.render_gbuffer(&s.full, None, &s.view, &IsrSettings::screen_space())
                .unwrap()
                .0
        })
        .collect();
    let fulls: Vec<GpuGBuffer> = setups
        .iter()
        .map(|s| GpuGBuffer::upload(&ctx, &s.full).unwrap())
        .collect();
    let outputs: Vec<wgpu::Texture> = (0..2)
        .map(|_| isr.output_texture(40, 30).unwrap())
        .collect();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    for ((s, g), out) in setups.iter().zip(&fulls).zip(&outputs) {
        let inputs = GpuIsrInputs {
            full: g,
            coarse: None,
            view: &s.view,
        };
        isr.encode(&mut encoder, &inputs, &IsrSettings::screen_space(), out)
            .unwrap();
    }
    ctx.queue.submit([encoder.finish()]);
    for (k, out) in outputs.iter().enumerate() {
        let img = ctx.read_texture_image(out).unwrap();
        let (d, at) = max_difference(&img, &alone[k]);
        assert!(d == 0.0, "view {k}: batched differs by {d} at {at}");
    }
}

/// ISR from an engine's G-buffer converted by `HostGBufferPass` (float formats, its ids) in
/// the standard and the reverse-Z infinite depth conventions, against ISR from the
/// toolkit's own G-buffer of the same view. The conversion rounds each distance by at most
/// a few f32 units in the last place (scene-core's host_gbuffer test measures 2.6e-5
/// standard, 8.8e-8 reversed), so the pictures agree to the same order: the mean
/// difference within 1e-4 of the image's mean, and no pixel off by more than 1e-3 of the
/// peak except where a sample sits on one of ISR's depth thresholds (at most 0.5 % of the
/// pixels).
#[test]
fn reverse_z_and_infinite_inputs_give_the_standard_image() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    use scene_core::gpu::HostGBufferPass;
    use scene_core::testing::EngineGBuffer;
    let setup = Setup::builtin("cornell", 0, 64, 48);
    let (w, h) = (64, 48);
    let s = IsrSettings::screen_space();
    let render = |g: &GpuGBuffer, view: &scene_core::View| {
        let mut gpu = GpuIsr::new(&ctx, &setup.prepared).unwrap();
        let target = gpu.output_texture(w, h).unwrap();
        let inputs = GpuIsrInputs {
            full: g,
            coarse: None,
            view,
        };
        ctx.submit_encoded(|e| gpu.encode(e, &inputs, &s, &target))
            .unwrap();
        ctx.read_texture_image(&target).unwrap()
    };
    let own = render(&GpuGBuffer::upload(&ctx, &setup.full).unwrap(), &setup.view);
    let g = &setup.full;
    let cam = setup.scene.cameras[0].with_aspect(w as f32 / h as f32);
    let mut convert = HostGBufferPass::new(&ctx).unwrap();
    for (name, projection) in [
        ("standard", setup.view.projection_matrix()),
        (
            "reverse-Z, infinite far",
            glam::camera::rh::proj::directx::perspective_infinite_reverse(
                cam.fov_y, cam.aspect, cam.near,
            ),
        ),
    ] {
        let (view, convention) =
            scene_core::View::from_host_matrices(setup.view.view_matrix(), projection).unwrap();
        // The engine's float textures, its ids and its depth buffer in this convention.
        let engine = EngineGBuffer::float(&ctx, g, setup.view.far, &convention, true).unwrap();
        let host = engine.host();
        let converted = GpuGBuffer::new(&ctx, w, h).unwrap();
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        convert
            .encode(&mut encoder, &host, &convention, &converted)
            .unwrap();
        ctx.queue.submit([encoder.finish()]);
        let img = render(&converted, &view);
        let e = mean_error(&own, &img);
        let peak = own
            .pixels
            .iter()
            .map(|p| p.max_element())
            .fold(0.0f32, f32::max);
        let off = own
            .pixels
            .iter()
            .zip(&img.pixels)
            .filter(|(a, b)| (**a - **b).abs().max_element() > 1e-3 * peak)
            .count();
        let (dmax, at) = max_difference(&own, &img);
        eprintln!(
            "{name}: mean difference {e:.2e} ({:.2e} of the mean), {off} pixels above 1e-3 of \
             the peak, largest {dmax:.2e} at {at}",
            e / image_mean(&own)
        );
        assert!(e <= 1e-4 * image_mean(&own), "{name}: {e}");
        assert!(off * 200 <= own.pixels.len(), "{name}: {off} pixels");
    }
}

/// ISR and DL on the frame contract (`IsrFrame` as a `GpuFrame`): the target of each frame
/// holds what `GpuIsr::render` writes for the same light state (bit for bit: the same
/// passes), a light change shows in the next frame, a target of the wrong size is refused,
/// and steady frames create no GPU object.
#[test]
fn the_frame_contract_gives_isr_and_dl_and_creates_nothing_per_frame() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    use isr::IsrFrame;
    use scene_core::LightState;
    use scene_core::gpu::{FrameInputs, GpuFrame, ObjectCounts};
    let setup = Setup::builtin("cornell-point", 0, 48, 36);
    let (w, h) = (48, 36);
    let gg = GpuGBuffer::upload(&ctx, &setup.full).unwrap();
    let mut dim = LightState::default();
    dim.set_color(LightId::Point(0), Vec3::new(1.0, 0.5, 0.25));
    let target = |label| {
        ctx.create_texture_2d(
            label,
            w,
            h,
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        )
    };
    for (name, settings) in [
        ("isr-ss", IsrSettings::screen_space()),
        ("dl", IsrSettings::dl()),
    ] {
        // The library's frames, one GpuIsr per light state.
        let expected: Vec<Vec<[f32; 4]>> = [LightState::default(), dim.clone()]
            .iter()
            .map(|state| {
                let mut gpu = GpuIsr::new(&ctx, &setup.prepared).unwrap();
                gpu.apply(state);
                let out = target("expected");
                let inputs = GpuIsrInputs {
                    full: &gg,
                    coarse: None,
                    view: &setup.view,
                };
                ctx.submit_encoded(|e| gpu.encode(e, &inputs, &settings, &out))
                    .unwrap();
                ctx.read_texture_rgba32f(&out).unwrap()
            })
            .collect();
        assert_ne!(expected[0], expected[1], "{name}: the light change shows");
        // The CPU twin gives the same frames (the viewer draws its ISR modes through this
        // contract): the GPU-against-CPU bounds of `tests/gpu.rs`, the mean within 1e-3 of
        // the image's mean and every pixel within 1e-4 of the peak.
        for (state, frame) in [LightState::default(), dim.clone()].iter().zip(&expected) {
            let mut lights = setup.prepared.clone();
            lights.apply(state);
            let cpu = isr::render_image(&lights, &setup.inputs(), &settings).unwrap();
            let gpu = Image::from_pixels(
                w,
                h,
                frame.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect(),
            )
            .unwrap();
            let m = image_mean(&cpu);
            let peak = cpu
                .pixels
                .iter()
                .map(|p| p.max_element())
                .fold(0.0f32, f32::max);
            let (dmax, _) = max_difference(&cpu, &gpu);
            assert!(mean_error(&cpu, &gpu) < 1e-3 * m, "{name}: mean");
            assert!(dmax <= 1e-4 * f64::from(peak.max(1.0)), "{name}: {dmax}");
        }
        let mut method = IsrFrame::prepare(&ctx, &setup.prepared, settings).unwrap();
        assert_eq!(method.name(), name);
        let out = target("frame");
        let default = LightState::default();
        let wrong = ctx.create_texture_2d(
            "wrong",
            w,
            h + 1,
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::STORAGE_BINDING,
        );
        let inputs = |lights| FrameInputs {
            gbuffer: &gg,
            view: &setup.view,
            lights,
        };
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        assert!(
            method
                .encode(&mut encoder, &inputs(&default), &wrong)
                .is_err()
        );
        for (k, state) in [&default, &default, &dim, &default, &dim, &dim]
            .into_iter()
            .enumerate()
        {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            let (result, created) = ObjectCounts::during(&ctx.device, || {
                method.encode(&mut encoder, &inputs(state), &out)
            });
            result.unwrap();
            ctx.queue.submit([encoder.finish()]);
            let got = ctx.read_texture_rgba32f(&out).unwrap();
            assert!(
                got == expected[usize::from(state != &default)],
                "{name} frame {k}: not the library's frame"
            );
            assert_eq!(created.pipelines, 0, "{name} frame {k}: {created}");
            if k >= 2 {
                assert!(created.is_zero(), "{name} frame {k}: {created}");
            }
        }
    }
}

/// Shadow maps the GPU renders from the engine's vertex and index buffers
/// (`ShadowMapPass`), copied into ISR by `copy_shadow_texels`, give the frame of the CPU's
/// ray-cast maps of the same lights and casters (the maps agree to rounding, scene-core's
/// `shadow_maps_gpu` test); before the copy the planned maps are empty and the frame is
/// unshadowed, so the copy is what brings the shadows.
#[test]
fn shadow_maps_rendered_on_the_gpu_give_the_ray_cast_maps_frame() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    use scene_core::shadowed_lights::gpu_maps::{CasterVertices, ShadowMapPass};
    let scene = builtin::scene("cornell-point").unwrap();
    let shadows = small_shadows();
    let casters = triangles(&scene);
    let cpu = LightSet::from_lights(engine_lights(&scene), &casters, &shadows).unwrap();
    let vertices = CasterVertices::new(&ctx, &casters).unwrap();
    let (planned, plan) =
        LightSet::planned(engine_lights(&scene), vertices.bounds(), &shadows).unwrap();
    let maps = ShadowMapPass::new(&ctx, &planned, &plan, CasterVertices::LAYOUT).unwrap();

    let setup = Setup::with_prepared(scene.clone(), cpu.clone(), 0, 48, 36);
    let g = GpuGBuffer::upload(&ctx, &setup.full).unwrap();
    let s = IsrSettings::screen_space();
    let render = |gpu: &mut GpuIsr| {
        let target = gpu.output_texture(48, 36).unwrap();
        let inputs = GpuIsrInputs {
            full: &g,
            coarse: None,
            view: &setup.view,
        };
        ctx.submit_encoded(|e| gpu.encode(e, &inputs, &s, &target))
            .unwrap();
        ctx.read_texture_rgba32f(&target).unwrap()
    };
    let expected = render(&mut GpuIsr::new(&ctx, &cpu).unwrap());
    let mut isr = GpuIsr::new(&ctx, &planned).unwrap();
    let unshadowed = render(&mut isr);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    maps.encode(&mut encoder, &planned, &vertices.casters())
        .unwrap();
    isr.copy_shadow_texels(&mut encoder, &maps).unwrap();
    ctx.queue.submit([encoder.finish()]);
    let got = render(&mut isr);
    // The blocks' shadows hold a few per cent of the image's light (2.8 % measured in ISR).
    scene_core::testing::assert_gpu_shadow_maps_match(&expected, &unshadowed, &got);
}
