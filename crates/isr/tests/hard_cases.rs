//! The hard cases of the design (numerical stability) and bad input, on the CPU path.

mod common;

use common::{Setup, image_mean, mean_error, modes, small_shadows};
use glam::{Vec3, Vec4};
use isr::{
    Blur, IsrError, IsrInputs, IsrSettings, IsrTechnique, LightSet, ShadowSettings, render_cpu,
};
use std::sync::Arc;

use scene_core::FrameRequest;
use scene_core::gbuffer::RayCastRenderer;
use scene_core::{
    Camera, GBuffer, Material, Mesh, PointLight, Projection, Scene, Technique, View, builtin,
};

fn all_settings() -> Vec<(&'static str, IsrSettings)> {
    let mut v = modes();
    v.push(("dl", IsrSettings::dl()));
    v.push((
        "edge-aware, normal-weighted upsampling, AO on indirect",
        IsrSettings {
            blur: Blur::EdgeAware,
            upsample_normal_power: 8.0,
            ao_indirect_only: true,
            ..IsrSettings::screen_space()
        },
    ));
    v
}

/// A big floor quad at y = 0 under a point light, seen by `camera`.
fn floor_scene(camera: Camera) -> Scene {
    let mut s = Scene::new("floor");
    s.materials
        .push(Material::diffuse("grey", Vec3::splat(0.5)));
    let mut m = Mesh::default();
    let g = 100.0;
    m.push_quad(
        [
            Vec3::new(-g, 0.0, g),
            Vec3::new(g, 0.0, g),
            Vec3::new(g, 0.0, -g),
            Vec3::new(-g, 0.0, -g),
        ],
        0,
    );
    s.meshes.push(m);
    s.point_lights.push(PointLight {
        name: "lamp".into(),
        position: Vec3::new(0.0, 3.0, -5.0),
        intensity: Vec3::splat(20.0),
        radius: None,
        cone: None,
    });
    s.cameras.push(camera);
    s.validate().unwrap();
    s
}

#[test]
fn grazing_and_coplanar_surfaces_add_no_light_to_themselves() {
    // A camera 1 cm above an endless floor: every neighbour is coplanar with the receiver and
    // the footprints are extremely stretched. A plane cannot light or occlude itself.
    let cam = Camera {
        name: "grazing".into(),
        position: Vec3::new(0.0, 0.01, 0.0),
        target: Vec3::new(0.0, 0.0, -50.0),
        up: Vec3::Y,
        fov_y: 0.8,
        aspect: 4.0 / 3.0,
        near: 0.001,
        far: 300.0,
    };
    let setup = Setup::new(floor_scene(cam), 0, 64, 48);
    let dl = setup.render(&IsrSettings::dl());
    assert!(image_mean(&dl) > 0.0);
    for (name, s) in all_settings() {
        let img = setup.render(&s);
        assert_eq!(img.non_finite_count(), 0, "{name}");
        let e = mean_error(&img, &dl);
        assert!(
            e <= 1e-3 * image_mean(&dl),
            "{name}: differs from DL by {e}"
        );
    }
}

#[test]
fn neighbours_at_equal_depth_give_finite_light() {
    // A wall facing the camera: every pixel has the same linear depth (the bilateral weight
    // 1/|dz| is singular everywhere) ...
    let cam = Camera {
        name: "facing".into(),
        position: Vec3::new(0.0, 0.0, 5.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y: 0.5,
        aspect: 4.0 / 3.0,
        near: 0.01,
        far: 20.0,
    };
    let mut scene = floor_scene(cam);
    for p in &mut scene.meshes[0].positions {
        *p = Vec3::new(p.x, p.z, 0.0);
    }
    scene.meshes[0].normals = vec![Vec3::Z; 4];
    scene.point_lights[0].position = Vec3::new(0.0, 0.0, 2.0);
    let setup = Setup::new(scene, 0, 40, 30);
    assert!(
        setup
            .full
            .depth
            .windows(2)
            .all(|w| (w[0] - w[1]).abs() < 1e-5)
    );
    let dl = setup.render(&IsrSettings::dl());
    for (name, s) in all_settings() {
        let img = setup.render(&s);
        assert_eq!(img.non_finite_count(), 0, "{name}");
        assert!(mean_error(&img, &dl) <= 1e-3 * image_mean(&dl), "{name}");
    }
    // ... and a synthetic crease: equal depths, alternating normals 90 degrees apart.
    let mut g = setup.full.clone();
    for (i, n) in g.normal.iter_mut().enumerate() {
        *n = if i % 2 == 0 {
            Vec3::Z
        } else {
            Vec3::new(1.0, 0.0, 1.0).normalize()
        };
    }
    let coarse = isr::downsample(&g, isr::DownsampleMode::NearestSurface);
    let inputs = IsrInputs {
        full: &g,
        coarse: &coarse,
        view: &setup.view,
    };
    for (name, s) in all_settings() {
        let f = render_cpu(&setup.prepared, &inputs, &s).unwrap();
        assert_eq!(f.image.non_finite_count(), 0, "{name}");
        assert!(f.upsampled.iter().all(|v| v.is_finite()), "{name}");
    }
}

#[test]
fn background_pixels_and_background_neighbourhoods() {
    let setup = Setup::builtin("cornell-point", 0, 32, 24);
    // All background: a black image.
    let bg = GBuffer::background(32, 24);
    let cbg = GBuffer::background(16, 12);
    let inputs = IsrInputs {
        full: &bg,
        coarse: &cbg,
        view: &setup.view,
    };
    for (name, s) in all_settings() {
        let f = render_cpu(&setup.prepared, &inputs, &s).unwrap();
        assert!(f.image.pixels.iter().all(|p| *p == Vec3::ZERO), "{name}");
    }
    // One surface pixel in a sea of background: its neighbourhood is all background.
    let mut one = GBuffer::background(32, 24);
    let i = 12 * 32 + 16;
    one.albedo[i] = setup.full.albedo[i];
    one.normal[i] = setup.full.normal[i];
    one.depth[i] = setup.full.depth[i];
    one.triangle_id[i] = setup.full.triangle_id[i];
    let coarse = isr::downsample(&one, isr::DownsampleMode::NearestSurface);
    let inputs = IsrInputs {
        full: &one,
        coarse: &coarse,
        view: &setup.view,
    };
    let dl = render_cpu(&setup.prepared, &inputs, &IsrSettings::dl())
        .unwrap()
        .image;
    for (name, s) in all_settings() {
        let f = render_cpu(&setup.prepared, &inputs, &s).unwrap();
        assert_eq!(f.image.non_finite_count(), 0, "{name}");
        // No neighbours: no indirect light, no occlusion.
        assert!(
            (f.image.pixels[i] - dl.pixels[i]).abs().max_element() <= 1e-6,
            "{name}"
        );
        assert!(
            f.image
                .pixels
                .iter()
                .enumerate()
                .all(|(k, p)| k == i || *p == Vec3::ZERO)
        );
    }
}

#[test]
fn vanished_upsampling_weights_and_cancelled_normals() {
    let setup = Setup::builtin("cornell-point", 0, 32, 24);
    // Coarse normals all zero (cancelled in someone's downsample) and opposite to the
    // full-resolution ones for the normal weight: every weight of eq. 27 vanishes.
    let mut coarse = setup.coarse.clone();
    for n in &mut coarse.normal {
        *n = Vec3::ZERO;
    }
    let inputs = IsrInputs {
        full: &setup.full,
        coarse: &coarse,
        view: &setup.view,
    };
    for (name, s) in all_settings() {
        let f = render_cpu(&setup.prepared, &inputs, &s).unwrap();
        assert_eq!(f.image.non_finite_count(), 0, "{name}");
        assert!(f.radiosity.iter().all(|v| v.is_finite()), "{name}");
    }
    // Full-resolution normals all +Z, coarse ones all -Z: the normal weight of every coarse
    // sample is zero.
    let mut full = setup.full.clone();
    for n in &mut full.normal {
        *n = Vec3::Z;
    }
    let mut flipped = setup.coarse.clone();
    for n in &mut flipped.normal {
        *n = -Vec3::Z;
    }
    let inputs = IsrInputs {
        full: &full,
        coarse: &flipped,
        view: &setup.view,
    };
    let s = IsrSettings {
        upsample_normal_power: 2.0,
        ..IsrSettings::screen_space()
    };
    let f = render_cpu(&setup.prepared, &inputs, &s).unwrap();
    assert_eq!(f.image.non_finite_count(), 0);
    // Every surface pixel took the fallback: one of the blurred coarse values exactly.
    for (i, v) in f.upsampled.iter().enumerate() {
        if !setup.full.is_background(i) {
            assert!(
                f.blurred.contains(v),
                "pixel {i}: {v} is not a coarse value"
            );
        }
    }
}

#[test]
fn one_pixel_images() {
    for name in ["cornell", "primitives"] {
        let scene = builtin::scene(name).unwrap();
        let mut t = IsrTechnique::new(IsrSettings::default(), Box::new(RayCastRenderer::new()))
            .with_shadows(small_shadows());
        t.prepare(Arc::new(scene.clone())).unwrap();
        let img = t
            .render(&FrameRequest::camera(&scene.cameras[0], 1, 1))
            .unwrap();
        assert_eq!(img.pixels.len(), 1);
        assert!(img.pixels[0].is_finite(), "{name}: {}", img.pixels[0]);
        assert!(
            t.render(&FrameRequest::camera(&scene.cameras[0], 0, 1))
                .is_err()
        );
    }
}

#[test]
fn scenes_in_millimetres_and_kilometres_give_the_same_picture() {
    for name in ["cornell-point", "cornell", "primitives"] {
        let base = Setup::builtin(name, 0, 48, 36);
        for (mode, s) in all_settings() {
            let reference = base.render(&s);
            for k in [1e-3f32, 1e4] {
                let mut scene = builtin::scene(name).unwrap().scaled(k);
                scene.validate().unwrap();
                let setup = Setup::new(scene, 0, 48, 36);
                let img = setup.render(&s);
                let e = mean_error(&reference, &img);
                assert!(
                    e <= 1e-3 * image_mean(&reference),
                    "{name} x{k} {mode}: mean difference {e} vs mean {}",
                    image_mean(&reference)
                );
            }
        }
    }
}

#[test]
fn shadow_exponent_at_the_f32_limit() {
    // The corridor: four point lights behind pillars, so the cube-map ESM decides real
    // shadows (the empty Cornell box has no occluder to test).
    let scene = builtin::scene("corridor").unwrap();
    let render = |c: f32| {
        let shadows = ShadowSettings {
            esm_exponent: c,
            ..small_shadows()
        };
        let prepared = LightSet::new(&scene, &shadows).unwrap();
        assert!(
            prepared.shadow_texels.iter().all(|t| t.is_finite()),
            "c = {c}"
        );
        let setup = Setup::with_prepared(scene.clone(), prepared, 0, 48, 36);
        let img = setup.render(&IsrSettings::screen_space());
        assert_eq!(img.non_finite_count(), 0, "c = {c}");
        img
    };
    // ESM's visibility is min(1, exp(c (z_occluder - z))): as c grows it tends to the hard
    // depth test, which a large finite c (1e3, far past exp's f32 range of 88.72 in a
    // naive map) already reaches on every pixel a texel or more from a shadow edge.
    let hard = render(1e3);
    let mean = image_mean(&hard);
    // ln(f32::MAX) = 88.72: exp(c * depth) of a naive ESM overflows from here on; the log
    // space maps do not, even with the largest finite exponent, and give the hard test.
    for c in [1e4f32, f32::MAX] {
        let img = render(c);
        let e = mean_error(&img, &hard);
        eprintln!("c = {c}: mean difference to c = 1e3 {e:.3e} of mean {mean:.5}");
        // Past 1e3 only pixels within a fraction of a texel of an edge can change: a
        // thousandth of the mean allows for them, a broken map (all lit, all dark, NaN
        // turned 0) is off by tens of percent.
        assert!(
            e <= 1e-4 * mean,
            "c = {c}: mean difference {e:.3e}, mean {mean:.5}"
        );
    }
    // At the overflow threshold itself the shadows are softer but the picture the same:
    // the difference to the hard test is the penumbra's, measured 0.16 % of the mean here,
    // while a map whose shadows vanished differs by the shadows' whole share, 2.6 %
    // (checked below): 1 % separates the two.
    let soft = render(88.72);
    let e = mean_error(&soft, &hard);
    eprintln!("c = 88.72: mean difference to c = 1e3 {e:.3e} of mean {mean:.5}");
    assert!(
        e <= 1e-2 * mean,
        "c = 88.72: mean difference {e:.3e}, mean {mean:.5}"
    );
    // And the shadows are there: without shadows the picture is brighter by far.
    let unshadowed = {
        let shadows = ShadowSettings {
            enabled: false,
            ..small_shadows()
        };
        let prepared = LightSet::new(&scene, &shadows).unwrap();
        Setup::with_prepared(scene.clone(), prepared, 0, 48, 36)
            .render(&IsrSettings::screen_space())
    };
    let lit = mean_error(&unshadowed, &hard);
    eprintln!("no shadows: mean difference {lit:.3e}");
    assert!(
        lit > 2e-2 * mean,
        "shadows change only {lit:.3e} of {mean:.5}"
    );
}

#[test]
fn a_scene_without_lights_is_black() {
    let mut scene = builtin::scene("cornell-point").unwrap();
    scene.point_lights.clear();
    let setup = Setup::new(scene, 0, 32, 24);
    for (name, s) in all_settings() {
        let img = setup.render(&s);
        assert!(img.pixels.iter().all(|p| *p == Vec3::ZERO), "{name}");
    }
    // Emitters with no samples only show themselves.
    let scene = builtin::scene("cornell").unwrap();
    let prepared = LightSet::new(
        &scene,
        &ShadowSettings {
            emitter_samples: 0,
            ..small_shadows()
        },
    )
    .unwrap();
    assert!(prepared.lights.is_empty());
    let setup = Setup::with_prepared(scene, prepared, 0, 32, 24);
    let img = setup.render(&IsrSettings::screen_space());
    let lit = img.pixels.iter().filter(|p| **p != Vec3::ZERO).count();
    assert!(lit > 0 && lit < 40, "{lit} pixels see the light");
    // An empty scene is refused naming the fault (the scene contract).
    let mut empty = Scene::new("empty");
    empty
        .cameras
        .push(builtin::scene("cornell").unwrap().cameras[0].clone());
    let mut t = IsrTechnique::new(IsrSettings::default(), Box::new(RayCastRenderer::new()));
    let e = t.prepare(Arc::new(empty)).unwrap_err();
    assert!(
        matches!(
            e,
            scene_core::Error::Scene(scene_core::SceneError::NoGeometry { .. })
        ),
        "{e}"
    );
}

#[test]
fn sixty_four_coincident_lights_equal_one() {
    let one = builtin::scene("cornell-point").unwrap();
    let mut many = one.clone();
    let l = many.point_lights.remove(0);
    for _ in 0..64 {
        many.point_lights.push(PointLight {
            intensity: l.intensity / 64.0,
            ..l.clone()
        });
    }
    let shadows = ShadowSettings {
        cube_resolution: 32,
        ..small_shadows()
    };
    let a = Setup::with_prepared(
        one.clone(),
        LightSet::new(&one, &shadows).unwrap(),
        0,
        32,
        24,
    );
    let b = Setup::with_prepared(
        many.clone(),
        LightSet::new(&many, &shadows).unwrap(),
        0,
        32,
        24,
    );
    for (name, s) in all_settings() {
        let x = a.render(&s);
        let y = b.render(&s);
        assert_eq!(y.non_finite_count(), 0);
        let e = mean_error(&x, &y);
        assert!(e <= 1e-5 * image_mean(&x).max(1e-6), "{name}: {e}");
    }
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let setup = Setup::builtin("corridor", 0, 40, 30);
    for (name, s) in all_settings() {
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| setup.render(&s));
        let three = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap()
            .install(|| setup.render(&s));
        assert_eq!(one, three, "{name}");
    }
}

#[test]
fn bad_input_gives_typed_errors() {
    let setup = Setup::builtin("cornell-point", 0, 16, 12);
    let run = |full: &GBuffer, coarse: &GBuffer, s: &IsrSettings| {
        render_cpu(
            &setup.prepared,
            &IsrInputs {
                full,
                coarse,
                view: &setup.view,
            },
            s,
        )
    };
    let s = IsrSettings::screen_space();
    // NaN depth on a surface pixel.
    let mut bad = setup.full.clone();
    let i = bad.triangle_id.iter().position(|&t| t != u32::MAX).unwrap();
    bad.depth[i] = f32::NAN;
    let e = run(&bad, &setup.coarse, &s).unwrap_err();
    assert!(
        matches!(
            e,
            IsrError::NonFinite {
                channel: "depth",
                ..
            }
        ),
        "{e}"
    );
    // Infinite albedo in the coarse buffer.
    let mut bad = setup.coarse.clone();
    let i = bad.triangle_id.iter().position(|&t| t != u32::MAX).unwrap();
    bad.albedo[i] = Vec4::INFINITY;
    assert!(matches!(
        run(&setup.full, &bad, &s).unwrap_err(),
        IsrError::NonFinite {
            which: "coarse",
            channel: "albedo",
            ..
        }
    ));
    // Truncated channel, zero size.
    let mut short = setup.full.clone();
    short.normal.pop();
    assert!(matches!(
        run(&short, &setup.coarse, &s).unwrap_err(),
        IsrError::BadLength { .. }
    ));
    let zero = GBuffer::background(0, 5);
    assert!(matches!(
        run(&zero, &setup.coarse, &s).unwrap_err(),
        IsrError::ZeroSize { .. }
    ));
    // Bad settings.
    for bad in [
        IsrSettings { samples: 1000, ..s },
        IsrSettings {
            blur_sigma: 0.0,
            ..s
        },
        IsrSettings {
            upsample_epsilon: f32::NAN,
            ..s
        },
        IsrSettings { k_isr: -1.0, ..s },
    ] {
        assert!(matches!(
            run(&setup.full, &setup.coarse, &bad).unwrap_err(),
            IsrError::InvalidSetting { .. }
        ));
    }
    // NaN on a background pixel is ignored (background is never read).
    let mut bg_nan = setup.full.clone();
    if let Some(j) = bg_nan.triangle_id.iter().position(|&t| t == u32::MAX) {
        bg_nan.depth[j] = f32::NAN;
        assert!(run(&bg_nan, &setup.coarse, &s).is_ok());
    }
    // An orthographic view works too.
    let ortho = View::orthographic_fit(Vec3::new(0.28, 0.27, 0.28), Vec3::Z, 0.5);
    assert!(matches!(ortho.projection, Projection::Orthographic { .. }));
    let scene = builtin::scene("cornell-point").unwrap();
    let mut r = RayCastRenderer::new();
    let full = scene_core::GBufferRenderer::render(&mut r, &scene, &ortho, 24, 24).unwrap();
    let coarse = isr::downsample(&full, isr::DownsampleMode::NearestSurface);
    let f = render_cpu(
        &setup.prepared,
        &IsrInputs {
            full: &full,
            coarse: &coarse,
            view: &ortho,
        },
        &s,
    )
    .unwrap();
    assert_eq!(f.image.non_finite_count(), 0);
}

#[test]
fn errors_keep_their_kind_across_the_technique_trait() {
    let scene = Arc::new(builtin::scene("cornell-point").unwrap());
    let bad = IsrSettings {
        samples: 0,
        ..Default::default()
    };
    let mut t =
        IsrTechnique::new(bad, Box::new(RayCastRenderer::new())).with_shadows(small_shadows());
    t.prepare(scene.clone()).unwrap();
    let e = t
        .render(&FrameRequest::camera(&scene.cameras[0], 16, 12))
        .unwrap_err();
    // A scene_core::Error on the outside, ISR's own error inside, kind intact.
    match e.method_error::<IsrError>() {
        Some(IsrError::InvalidSetting { name, .. }) => assert_eq!(*name, "samples"),
        other => panic!("expected ISR's InvalidSetting, got {other:?} from {e}"),
    }
    assert!(e.to_string().contains("samples"), "{e}");
}
