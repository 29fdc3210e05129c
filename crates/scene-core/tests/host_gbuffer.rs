//! An engine's G-buffer in its own formats (`gpu::HostGBufferPass`) against the toolkit's own
//! G-buffer of the same view: compact albedo and normals within their formats' quantisation
//! (bounds derived below, per pixel), the engine's depth buffer in the standard and the
//! reverse-Z infinite conventions within the rounding of an f32 depth value, ids passed
//! through or marked `SURFACE_WITHOUT_ID`, and textures that cannot be read refused by name.
//! Skipped without an adapter unless `REQUIRE_GPU` is set.

use glam::Vec3;
use scene_core::gbuffer::RayCastRenderer;
use scene_core::gpu::{
    GpuContext, GpuError, GpuGBuffer, HostGBuffer, HostGBufferPass, ObjectCounts,
    SURFACE_WITHOUT_ID,
};
use scene_core::testing::gpu_test_context;
use scene_core::{BACKGROUND_ID, DepthConvention, GBuffer, GBufferRenderer, View, builtin};

const W: u32 = 64;
const H: u32 = 48;

fn srgb_encode(l: f32) -> f32 {
    if l <= 0.0031308 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

fn srgb_decode(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn octahedral(n: Vec3) -> [f32; 2] {
    let p = n / (n.x.abs() + n.y.abs() + n.z.abs());
    if p.z >= 0.0 {
        [p.x, p.y]
    } else {
        let s = |v: f32| if v >= 0.0 { 1.0 } else { -1.0 };
        [(1.0 - p.y.abs()) * s(p.x), (1.0 - p.x.abs()) * s(p.y)]
    }
}

fn texture(
    ctx: &GpuContext,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
    bytes: Option<&[u8]>,
) -> wgpu::Texture {
    match bytes {
        Some(bytes) => ctx.texture_with("engine", (W, H), format, usage, bytes),
        // COPY_DST keeps a texture without TEXTURE_BINDING a valid texture to refuse.
        None => ctx.create_texture_2d(
            "engine",
            W,
            H,
            format,
            usage | wgpu::TextureUsages::COPY_DST,
        ),
    }
}

fn depth_buffer(ctx: &GpuContext, values: &[f32]) -> wgpu::Texture {
    scene_core::testing::depth_texture_from(ctx, W, H, values).unwrap()
}

/// The engine's depth buffer of `g` (the toolkit's G-buffer from `view`) under `depth`.
fn engine_depth(g: &GBuffer, view: &View, depth: &DepthConvention) -> Vec<f32> {
    let clear = if depth.reverse { 0.0 } else { 1.0 };
    (0..g.len())
        .map(|i| {
            if g.triangle_id[i] == BACKGROUND_ID {
                clear
            } else {
                depth.depth(g.depth[i] * view.far)
            }
        })
        .collect()
}

fn read4(ctx: &GpuContext, t: &wgpu::Texture) -> Vec<[f32; 4]> {
    ctx.read_texture_rgba32f(t).unwrap()
}

#[test]
fn an_engines_compact_gbuffer_reads_as_the_toolkits() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let scene = builtin::scene("cornell").unwrap();
    let cam = scene.cameras[0].with_aspect(W as f32 / H as f32);
    let view = View::from_camera(&cam);
    let g = RayCastRenderer::new().render(&scene, &view, W, H).unwrap();
    let bind = wgpu::TextureUsages::TEXTURE_BINDING;
    // Albedo as 8-bit sRGB: each channel decodes to within half an 8-bit step of its code.
    let codes: Vec<u8> = g
        .albedo
        .iter()
        .flat_map(|a| {
            [a.x, a.y, a.z, 1.0].map(|c| (srgb_encode(c.clamp(0.0, 1.0)) * 255.0).round() as u8)
        })
        .collect();
    let albedo = texture(
        &ctx,
        wgpu::TextureFormat::Rgba8UnormSrgb,
        bind,
        Some(&codes),
    );
    // Normals as half floats, xyz and octahedral.
    let halves = |v: &[f32]| -> Vec<u8> {
        v.iter()
            .flat_map(|&x| half::f16::from_f32(x).to_bits().to_le_bytes())
            .collect()
    };
    let xyz: Vec<f32> = g.normal.iter().flat_map(|n| [n.x, n.y, n.z, 0.0]).collect();
    let oct: Vec<f32> = g
        .normal
        .iter()
        .flat_map(|&n| {
            if n == Vec3::ZERO {
                [0.0; 2]
            } else {
                octahedral(n)
            }
        })
        .collect();
    let normal_xyz = texture(
        &ctx,
        wgpu::TextureFormat::Rgba16Float,
        bind,
        Some(&halves(&xyz)),
    );
    let normal_oct = texture(
        &ctx,
        wgpu::TextureFormat::Rg16Float,
        bind,
        Some(&halves(&oct)),
    );
    let ids = texture(
        &ctx,
        wgpu::TextureFormat::R32Uint,
        bind,
        Some(bytemuck::cast_slice(&g.triangle_id)),
    );
    let cases = [
        ("standard", view.projection_matrix()),
        (
            "reverse-Z, infinite far",
            glam::camera::rh::proj::directx::perspective_infinite_reverse(
                cam.fov_y, cam.aspect, cam.near,
            ),
        ),
    ];
    let mut pass = HostGBufferPass::new(&ctx).unwrap();
    for (name, projection) in cases {
        let (host_view, convention) =
            View::from_host_matrices(view.view_matrix(), projection).unwrap();
        let values = engine_depth(&g, &view, &convention);
        let depth = depth_buffer(&ctx, &values);
        for (normal, encoding, with_ids) in [
            (&normal_xyz, "xyz", true),
            (&normal_oct, "octahedral", false),
        ] {
            let host = HostGBuffer {
                albedo: &albedo,
                normal,
                depth: &depth,
                triangle_id: with_ids.then_some(&ids),
            };
            let out = GpuGBuffer::new(&ctx, W, H).unwrap();
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            pass.encode(&mut encoder, &host, &convention, &out).unwrap();
            ctx.queue.submit([encoder.finish()]);
            let (a, n) = (read4(&ctx, &out.albedo), read4(&ctx, &out.normal));
            let d: Vec<f32> =
                bytemuck::cast_slice(&ctx.read_texture_bytes(&out.depth).unwrap()).to_vec();
            let id: Vec<u32> =
                bytemuck::cast_slice(&ctx.read_texture_bytes(&out.triangle_id).unwrap()).to_vec();
            let (mut worst_d, mut surfaces) = (0.0f32, 0);
            for i in 0..g.len() {
                let at = format!("{name}, {encoding}: pixel {i}");
                if g.triangle_id[i] == BACKGROUND_ID {
                    assert_eq!(id[i], BACKGROUND_ID, "{at}");
                    assert_eq!(d[i], 1.0, "{at}");
                    continue;
                }
                surfaces += 1;
                let want = if with_ids {
                    g.triangle_id[i]
                } else {
                    SURFACE_WITHOUT_ID
                };
                assert_eq!(id[i], want, "{at}");
                // Albedo: the decoded code lies within half a step of the code either side.
                for c in 0..3 {
                    let code = codes[4 * i + c] as f32;
                    let lo = srgb_decode(((code - 0.5) / 255.0).max(0.0));
                    let hi = srgb_decode(((code + 0.5) / 255.0).min(1.0));
                    let v = g.albedo[i][c];
                    assert!(
                        (a[i][c] - v).abs() <= (hi - lo) + 1e-6,
                        "{at}: albedo {} vs {v}",
                        a[i][c]
                    );
                }
                // Normals: a half float keeps 11 significant bits, so each stored coordinate
                // is within 2^-11 of the exact one (coordinates are at most 1 in size); the
                // octahedral decode stretches a coordinate's error by at most 2 per output
                // coordinate, and renormalising a vector off by e in length changes it by at
                // most e: 2 * 2 * 2^-11 < 2e-3 for octahedral, 2 * 2^-11 < 1e-3 for xyz.
                let bound = if encoding == "xyz" { 1e-3 } else { 2e-3 };
                let got = Vec3::new(n[i][0], n[i][1], n[i][2]);
                assert!(
                    (got - g.normal[i]).abs().max_element() <= bound,
                    "{at}: normal {got} vs {}",
                    g.normal[i]
                );
                // Depth: the engine's f32 depth is within half a unit in the last place of
                // the exact one; the distance moves by |dt/dd| = t^2 / |m32| per unit of d,
                // plus the shader's own f32 rounding of the sum and quotient (4 ulps of t).
                let t = g.depth[i] * view.far;
                let (_, m32, _) = convention.parts();
                let dd = values[i].abs().max(f32::MIN_POSITIVE) * f32::EPSILON;
                let bound = t * t / m32.abs() * dd + 4.0 * t * f32::EPSILON;
                let got_t = d[i] * host_view.far;
                worst_d = worst_d.max((got_t - t).abs() / t);
                assert!(
                    (got_t - t).abs() <= bound,
                    "{at}: distance {got_t} vs {t} (bound {bound:e})"
                );
            }
            eprintln!(
                "{name}, {encoding}: {surfaces} surface pixels, worst relative distance error {worst_d:.2e}"
            );
            assert!(surfaces > 1000);
        }
    }
    // A steady stream of frames creates nothing once the textures have been seen.
    let (_, convention) =
        View::from_host_matrices(view.view_matrix(), view.projection_matrix()).unwrap();
    let depth = depth_buffer(&ctx, &engine_depth(&g, &view, &convention));
    let host = HostGBuffer {
        albedo: &albedo,
        normal: &normal_xyz,
        depth: &depth,
        triangle_id: None,
    };
    let out = GpuGBuffer::new(&ctx, W, H).unwrap();
    for frame in 0..4 {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let (r, created) = ObjectCounts::during(&ctx.device, || {
            pass.encode(&mut encoder, &host, &convention, &out)
        });
        r.unwrap();
        ctx.queue.submit([encoder.finish()]);
        ctx.device
            .poll(wgpu::PollType::wait_indefinitely())
            .unwrap();
        if frame >= 2 {
            assert!(created.is_zero(), "frame {frame}: {created}");
        }
    }
}

#[test]
fn textures_an_engine_cannot_hand_over_are_refused_by_name() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    let bind = wgpu::TextureUsages::TEXTURE_BINDING;
    let rgba = texture(&ctx, wgpu::TextureFormat::Rgba16Float, bind, None);
    let r32 = texture(&ctx, wgpu::TextureFormat::R32Float, bind, None);
    let depth = texture(&ctx, wgpu::TextureFormat::Depth32Float, bind, None);
    let unbound = texture(
        &ctx,
        wgpu::TextureFormat::Rgba16Float,
        wgpu::TextureUsages::empty(),
        None,
    );
    let small = ctx.create_texture_2d("small", 8, 8, wgpu::TextureFormat::Rgba16Float, bind);
    let named = |h: HostGBuffer<'_>| match h.check() {
        Err(GpuError::HostTexture { texture, .. }) => texture,
        other => panic!("expected a named fault, got {other:?}"),
    };
    let ok = HostGBuffer {
        albedo: &rgba,
        normal: &rgba,
        depth: &depth,
        triangle_id: None,
    };
    assert!(ok.check().is_ok());
    assert_eq!(named(HostGBuffer { albedo: &r32, ..ok }), "albedo");
    assert_eq!(named(HostGBuffer { normal: &r32, ..ok }), "normal");
    assert_eq!(named(HostGBuffer { depth: &r32, ..ok }), "depth");
    assert_eq!(
        named(HostGBuffer {
            triangle_id: Some(&r32),
            ..ok
        }),
        "triangle id"
    );
    assert_eq!(
        named(HostGBuffer {
            normal: &unbound,
            ..ok
        }),
        "normal"
    );
    assert_eq!(
        named(HostGBuffer {
            normal: &small,
            ..ok
        }),
        "normal"
    );
}

/// `EngineGBuffer::compact` (what the examples stand in for an engine with) packs a G-buffer as this
/// file's own encoders do: the same 8-bit sRGB codes and the same octahedral half floats on
/// every surface pixel.
#[test]
fn compact_gbuffer_packs_as_the_independent_encoders() {
    let Some(ctx) = gpu_test_context() else {
        return;
    };
    use scene_core::testing::EngineGBuffer;
    let scene = builtin::scene("cornell").unwrap();
    let view = View::from_camera(&scene.cameras[0].with_aspect(W as f32 / H as f32));
    let g = RayCastRenderer::new().render(&scene, &view, W, H).unwrap();
    let (_, convention) = View::from_host_matrices(
        view.view_matrix(),
        glam::camera::rh::proj::directx::perspective_infinite_reverse(
            scene.cameras[0].fov_y,
            W as f32 / H as f32,
            scene.cameras[0].near,
        ),
    )
    .unwrap();
    let packed = EngineGBuffer::compact(&ctx, &g, view.far, &convention).unwrap();
    let albedo = ctx.read_texture_bytes(&packed.albedo).unwrap();
    let normal: Vec<u16> =
        bytemuck::cast_slice(&ctx.read_texture_bytes(&packed.normal).unwrap()).to_vec();
    let mut surfaces = 0;
    for i in 0..g.len() {
        if g.is_background(i) {
            continue;
        }
        surfaces += 1;
        let a = g.albedo[i];
        let want: Vec<u8> = [a.x, a.y, a.z, 1.0]
            .iter()
            .map(|c| (srgb_encode(c.clamp(0.0, 1.0)) * 255.0).round() as u8)
            .collect();
        assert_eq!(&albedo[4 * i..4 * i + 4], &want[..], "albedo at {i}");
        let o = octahedral(g.normal[i]).map(|x| half::f16::from_f32(x).to_bits());
        assert_eq!(&normal[2 * i..2 * i + 2], &o[..], "normal at {i}");
    }
    assert!(surfaces > 1000);
}
