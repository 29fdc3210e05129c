//! The layered depth cube on its own: the plane test of section 3.1 (figure 3), one IRPL
//! above a plane against the analytic irradiance, budgets and settings.

mod common;

use std::sync::Arc;

use glam::{Vec3, Vec4};
use ibrr_ldc::irpl::{Irpl, IrplKind, IrplSet};
use ibrr_ldc::ldc::{Channel, Combine, LdcBuilder, SourcePrecision};
use ibrr_ldc::{Construction, IbrrError, IbrrSettings, LdcFrame, Lookup, Splat, lookup};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::lights::LightId;
use scene_core::{Material, Mesh, Scene};

fn frame() -> LdcFrame {
    // A unit cube at 100 pixels: pixel 0.01, eps_d 0.005.
    LdcFrame::around(Vec3::ZERO, Vec3::ONE, 100, 0.5, 0.05, 0.1)
}

#[test]
fn figure_3_plane_matching() {
    let f = frame();
    let h = f.pixel_size();
    // A floor pixel (normal +y at y = 0.3).
    let plane = Vec4::new(0.0, 1.0, 0.0, 0.3);
    // Grazing: a point on the same surface far along it still matches (a depth test along
    // the LDI axis would have had to compare depths that differ by much more than eps).
    let tilted = Vec3::new(1.0, 0.02, 0.0).normalize();
    let plane_t = tilted.extend(tilted.dot(Vec3::new(0.5, 0.3, 0.5)));
    let far_along = Vec3::new(0.5, 0.3, 0.5) + tilted.cross(Vec3::Z).normalize() * (3.0 * h);
    assert!(f.matches(plane_t, far_along, tilted).is_some());
    // A parallel surface one eps away does not match; just inside eps does.
    assert!(
        f.matches(
            plane,
            Vec3::new(0.4, 0.3 + f.eps_distance * 1.01, 0.4),
            Vec3::Y
        )
        .is_none()
    );
    assert!(
        f.matches(
            plane,
            Vec3::new(0.4, 0.3 + f.eps_distance * 0.9, 0.4),
            Vec3::Y
        )
        .is_some()
    );
    // The other side of a thin wall (opposite normal, same place) never matches.
    assert!(
        f.matches(plane, Vec3::new(0.4, 0.3, 0.4), -Vec3::Y)
            .is_none()
    );
    // Small geometry with another normal in the same pixel gets its own layer.
    let mut b = LdcBuilder::new(f, 1 << 30, 1).unwrap();
    b.begin();
    let p = Vec3::new(0.405, 0.3, 0.405);
    b.splat(1, 40, 40, p, Vec3::Y, Vec3::ONE, 0.0, 1.0, Combine::Nearest)
        .unwrap();
    let n45 = Vec3::new(1.0, 1.0, 0.0).normalize();
    b.splat(
        1,
        40,
        40,
        p,
        n45,
        Vec3::splat(2.0),
        0.0,
        1.0,
        Combine::Nearest,
    )
    .unwrap();
    // The same surface again merges.
    b.splat(
        1,
        40,
        40,
        p + Vec3::new(0.001, 0.0, 0.0),
        Vec3::Y,
        Vec3::ONE,
        0.1,
        1.0,
        Combine::Nearest,
    )
    .unwrap();
    b.finish(Channel::Exact, 0);
    let ldc = b.compact(1, SourcePrecision::F32, &[]).unwrap();
    assert_eq!(ldc.layer_count(), 2);
    let i = f.pixel_index(1, 40, 40).unwrap();
    assert_eq!(ldc.range(i).len(), 2);
    let flat = ldc.find(i, p, Vec3::Y).unwrap();
    let tilt = ldc.find(i, p, n45).unwrap();
    assert_ne!(flat, tilt);
    // Overlapping splats of one IRPL are combined, not summed.
    assert_eq!(ldc.direct[flat], Vec3::ONE);
    assert_eq!(ldc.direct[tilt], Vec3::splat(2.0));
}

/// A square floor of side `2 half` at y = 0, one white-ish material.
fn floor(half: f32) -> Scene {
    let mut s = Scene::new("floor");
    s.materials
        .push(Material::diffuse("floor", Vec3::splat(0.5)));
    let mut m = Mesh {
        name: "floor".into(),
        ..Default::default()
    };
    m.push_quad(
        [
            Vec3::new(-half, 0.0, -half),
            Vec3::new(-half, 0.0, half),
            Vec3::new(half, 0.0, half),
            Vec3::new(half, 0.0, -half),
        ],
        0,
    );
    s.meshes.push(m);
    s.validate().unwrap();
    s
}

/// The LDC built from `irpl` alone over `scene`.
fn ldc_of_one(scene: &Arc<Scene>, irpl: Irpl, settings: &IbrrSettings) -> ibrr_ldc::Ldc {
    let set = IrplSet {
        irpls: vec![irpl],
        paths: 1,
        path_ends: vec![1],
        exact: 0,
    };
    ldc_of(scene, set, settings)
}

/// The LDC built from `set` over `scene`.
fn ldc_of(scene: &Arc<Scene>, set: IrplSet, settings: &IbrrSettings) -> ibrr_ldc::Ldc {
    let mut c = Construction::with_irpls(scene.clone(), set, settings).unwrap();
    let mut r = RayCastRenderer::new();
    c.prepare_renderer(&mut r).unwrap();
    while !c.is_done() {
        c.step(&mut r, 1).unwrap();
    }
    c.ldc().unwrap()
}

#[test]
fn one_irpl_above_a_plane_gives_the_analytic_irradiance() {
    let scene = Arc::new(floor(1.0));
    let height = 0.3f32;
    let power = Vec3::new(2.0, 1.0, 0.5);
    let irpl = Irpl {
        position: Vec3::new(0.1, height, -0.05),
        normal: -Vec3::Y,
        power,
        kind: IrplKind::Bounce,
        light: LightId::Point(0),
        path: 0,
        depth: 1,
    };
    for splat in [Splat::Exact, Splat::Nearest, Splat::Gaussian] {
        let settings = IbrrSettings {
            target_error: 0.0,
            resolution: 128,
            direct_hemicube: 128,
            indirect_hemicube: 128,
            splat,
            ..Default::default()
        };
        let ldc = ldc_of_one(&scene, irpl, &settings);
        let mut worst = [0.0f32; 3];
        // The paper's kernels copy a sample's value over its footprint: their error at a
        // point is bounded by the falloff's relative slope there, 4 s / (h^2 + s^2) at
        // horizontal distance s, times the distance to the farthest sample that may serve it
        // (a render pixel's footprint, 2 r (2 / 128) / cos at distance r, up to twice that
        // at a hemicube face's edge, plus half an LDI pixel diagonal).
        let mut paper_excess = [f32::NEG_INFINITY; 3];
        let pixel = ldc.frame.pixel_size();
        for k in 0..400 {
            let (x, z) = (
                -0.9 + 1.8 * ((k % 20) as f32 + 0.5) / 20.0,
                -0.9 + 1.8 * ((k / 20) as f32 + 0.5) / 20.0,
            );
            let p = Vec3::new(x, 0.0, z);
            // rho I cos cos / (pi r^2) with rho = 1 (the LDC holds irradiance).
            let d = irpl.position - p;
            let r2 = d.length_squared();
            let cos = height / r2.sqrt();
            let expected = power * (cos * cos / (std::f32::consts::PI * r2));
            for (m, mode) in [
                Lookup::Nearest,
                Lookup::Bilinear,
                Lookup::Average { radius: 1 },
            ]
            .into_iter()
            .enumerate()
            {
                let (direct, indirect) =
                    lookup(&ldc, p, Vec3::Y, mode, 0).expect("every floor point has a layer");
                assert_eq!(direct, Vec3::ZERO);
                let rel = ((indirect - expected).abs() / expected).max_element();
                worst[m] = worst[m].max(rel);
                let s = (p - Vec3::new(irpl.position.x, 0.0, irpl.position.z)).length();
                let slope = 4.0 * s / (height * height + s * s) + 2.0 / height * 0.05;
                let reach = 2.0 * 2.0 * r2.sqrt() * (2.0 / 128.0) / cos
                    + pixel * if m == 2 { 2.2 } else { 1.0 };
                paper_excess[m] = paper_excess[m].max(rel - slope * reach);
            }
        }
        if splat != Splat::Exact {
            println!(
                "{splat:?}: worst relative error nearest {:.4}, bilinear {:.4}, average {:.4}; worst excess over the per-point bound {paper_excess:?}",
                worst[0], worst[1], worst[2]
            );
            assert!(
                paper_excess.iter().all(|&e| e < 0.0),
                "{splat:?}: {paper_excess:?}"
            );
            continue;
        }
        // Exact values at LDI pixel centres. The nearest lookup is off by at most the
        // falloff's steepest relative slope, |d ln(h^2 / (h^2 + s^2)^2) / ds| <= 2 / h at
        // s = h, times half a pixel diagonal; bilinear interpolation by the curvature over a
        // pixel, (1/2) |f''| pixel^2 / 4 = pixel^2 / (2 h^2) relative at the peak; the 3 x 3
        // average (centred on the pixel holding the point, as the nearest lookup) by the
        // nearest's slope plus the curvature over +-1 pixel, 2 pixel^2 / h^2 x 2/3.
        let nearest_bound = 2.0 / height * pixel * std::f32::consts::FRAC_1_SQRT_2;
        println!(
            "{splat:?}: worst relative error nearest {:.4} (bound {nearest_bound:.4}), bilinear {:.4}, average {:.4}",
            worst[0], worst[1], worst[2]
        );
        assert!(worst[0] < nearest_bound, "{splat:?}: nearest {}", worst[0]);
        let curvature = (pixel / height).powi(2);
        assert!(
            worst[1] < 0.5 * curvature + 1e-3,
            "{splat:?}: bilinear {}",
            worst[1]
        );
        assert!(
            worst[2] < nearest_bound + 4.0 / 3.0 * curvature,
            "{splat:?}: average {}",
            worst[2]
        );
        // Nothing below the floor: a lookup from underneath finds no layer.
        assert!(
            lookup(
                &ldc,
                Vec3::new(0.0, 0.0, 0.0),
                -Vec3::Y,
                Lookup::Bilinear,
                2
            )
            .is_none()
        );
    }
}

#[test]
fn the_memory_budget_fails_typed_before_allocating() {
    let f = LdcFrame::around(Vec3::ZERO, Vec3::ONE, 1000, 0.5, 0.05, 0.1);
    // Heads: 3 x 1000 x 1000 x 4 bytes = 12 MB > 1 MB.
    match LdcBuilder::new(f, 1 << 20, 1) {
        Err(IbrrError::Budget { needed, limit, .. }) => {
            assert_eq!(needed, 12_000_000);
            assert_eq!(limit, 1 << 20);
        }
        other => panic!("expected a budget error, got {other:?}"),
    }
    // Layers: a budget that holds the heads and a few layers fails on the next one.
    let scene = Arc::new(scene_core::builtin::scene("cornell").unwrap());
    let settings = IbrrSettings {
        target_error: 0.0,
        resolution: 32,
        irpls: 4,
        max_bytes: 3 * 32 * 32 * 4 + 1000,
        ..Default::default()
    };
    let mut t = ibrr_ldc::IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    let err = scene_core::Technique::prepare(&mut t, scene).unwrap_err();
    let e = err
        .method_error::<IbrrError>()
        .expect("the IBRR's own error");
    assert!(matches!(e, IbrrError::Budget { .. }), "{e}");
    assert!(
        t.ldc().is_none() && t.construction().is_none(),
        "nothing half-built is kept"
    );
    // Renders: hemicubes of 4096 (three faces' worth of 4096^2 pixels, 4.8 GB with the
    // warp's samples) do not fit the default 2 GiB beside a small LDC: refused before any is
    // rendered.
    let settings = IbrrSettings {
        target_error: 0.0,
        resolution: 64,
        irpls: 4,
        direct_hemicube: 4096,
        ..Default::default()
    };
    let mut t = ibrr_ldc::IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    let scene = Arc::new(scene_core::builtin::scene("cornell-point").unwrap());
    let err = scene_core::Technique::prepare(&mut t, scene).unwrap_err();
    match err.method_error::<IbrrError>() {
        Some(IbrrError::Budget {
            what,
            needed,
            limit,
        }) => {
            assert!(what.contains("renders"), "{what}");
            assert!(needed > limit);
        }
        other => panic!("expected a budget error for the renders, got {other:?}"),
    }
}

#[test]
fn settings_out_of_range_are_named() {
    let bad = [
        IbrrSettings {
            target_error: 0.0,
            resolution: 0,
            ..Default::default()
        },
        IbrrSettings {
            target_error: 0.0,
            eps_distance_px: f32::NAN,
            ..Default::default()
        },
        IbrrSettings {
            target_error: 0.0,
            eps_normal: 0.0,
            ..Default::default()
        },
        IbrrSettings {
            target_error: 0.0,
            band: 1.0,
            ..Default::default()
        },
        IbrrSettings {
            target_error: 0.0,
            max_splat_px: 0.0,
            ..Default::default()
        },
    ];
    let names = [
        "resolution",
        "eps_distance_px",
        "eps_normal",
        "band",
        "max_splat_px",
    ];
    for (s, name) in bad.iter().zip(names) {
        let e = s.check().unwrap_err();
        assert!(e.to_string().contains(name), "{e}");
    }
}

#[test]
fn a_clamped_irpl_rescaled_keeps_its_power_and_loses_its_hot_spot() {
    let scene = Arc::new(floor(1.0));
    // Near-singular: 2.5% of the floor's side above it.
    let height = 0.05f32;
    let irpl = Irpl {
        position: Vec3::new(0.0, height, 0.0),
        normal: -Vec3::Y,
        power: Vec3::ONE,
        kind: IrplKind::Bounce,
        light: LightId::Point(0),
        path: 0,
        depth: 1,
    };
    let integrate = |clamp: f32| {
        let settings = IbrrSettings {
            target_error: 0.0,
            resolution: 256,
            direct_hemicube: 256,
            indirect_hemicube: 256,
            clamp,
            // A lone IRPL in the air: no surface near it for the local compensation to
            // recover the clamped light from (`tests/clamp.rs` tests that one).
            compensation: ibrr_ldc::Compensation::Rescale,
            ..Default::default()
        };
        let ldc = ldc_of_one(&scene, irpl, &settings);
        // Power received by the floor (a 400 x 400 grid of lookups) and the peak.
        let (n, mut power, mut peak) = (400, 0.0f64, 0.0f32);
        let cell = 2.0 / n as f32;
        for j in 0..n {
            for i in 0..n {
                let p = Vec3::new(
                    -1.0 + (i as f32 + 0.5) * cell,
                    0.0,
                    -1.0 + (j as f32 + 0.5) * cell,
                );
                let e = lookup(&ldc, p, Vec3::Y, Lookup::Bilinear, 2).map_or(0.0, |v| v.1.x);
                power += f64::from(e * cell * cell);
                peak = peak.max(e);
            }
        }
        (power, peak)
    };
    let (free, free_peak) = integrate(0.0);
    // Analytic: the floor of half-side 1 at height h receives 1 - h^2 / (h^2 + 1)... of a
    // Lambertian emitter's power through the square; the disk of radius 1 gets
    // 1 / (1 + h^2) of it, the square a little more.
    assert!(
        free > 1.0 / (1.0 + f64::from(height * height)) * 0.97 && free < 1.0,
        "unclamped floor power {free}"
    );
    // Clamped at 5% of the extent (0.14, about 3 h): the peak falls to about 1 / (pi r^2)
    // times the compensation, and the power stays.
    let (kept, kept_peak) = integrate(0.05);
    let r = 0.05 * scene.extent();
    println!(
        "unclamped: power {free:.4}, peak {free_peak:.2}; clamped: power {kept:.4}, peak {kept_peak:.2} (bound {:.2})",
        1.0 / (std::f32::consts::PI * r * r)
    );
    // Unclamped the peak is 1 / (pi h^2); clamped, k / (pi r^2) with the compensation k < 2
    // (more than half the power arrives where g is below the clamp), so the ratio is below
    // 2 (h / r)^2.
    let bound = 2.0 * (height / r).powi(2);
    assert!(
        kept_peak < bound * free_peak,
        "the hot spot stays: {kept_peak} vs {free_peak} (ratio bound {bound})"
    );
    assert!(
        (kept / free - 1.0).abs() < 0.01,
        "clamped power {kept} vs {free}"
    );
}

/// The floor of [`floor`] under a grating of thin horizontal slats at `height` (slats of
/// width `period / 2` every `period` along x, over `|x|, |z| < 0.5`): half of any direction's
/// light passes it, whatever the direction (the slats have no depth).
fn floor_under_a_grating(height: f32, period: f32) -> Scene {
    let mut s = floor(1.0);
    let mut m = Mesh {
        name: "grating".into(),
        ..Default::default()
    };
    let mut x = -0.5f32;
    while x < 0.5 {
        let x1 = (x + 0.5 * period).min(0.5);
        m.push_quad(
            [
                Vec3::new(x, height, -0.5),
                Vec3::new(x, height, 0.5),
                Vec3::new(x1, height, 0.5),
                Vec3::new(x1, height, -0.5),
            ],
            0,
        );
        x += period;
    }
    s.meshes.push(m);
    s.validate().unwrap();
    s
}

/// Occluders finer than an LDI pixel (a window blind's slats) hide part of it: a layer that
/// one of the sun's render samples reaches through a gap is not wholly lit. A sun through a
/// grating that stops half its light must give half its irradiance on the floor below, on
/// average; lighting every layer a sample reached (the old exact mode) read the floor
/// nearly fully lit (the Breakfast Room's sun through its blind 2.7 to 4 times too bright).
#[test]
fn a_sun_through_slats_finer_than_an_ldi_pixel_lights_the_share_they_let_through() {
    let height = 0.3f32;
    let period = 0.0073f32;
    let scene = Arc::new(floor_under_a_grating(height, period));
    let direction = Vec3::new(0.3, -1.0, 0.2).normalize();
    let irradiance = Vec3::new(3.0, 2.0, 1.0);
    let irpl = Irpl {
        position: Vec3::ZERO,
        normal: Vec3::ZERO,
        power: irradiance,
        kind: IrplKind::DirectionalSource { direction },
        light: LightId::Directional(0),
        path: u32::MAX,
        depth: 0,
    };
    let set = IrplSet {
        irpls: vec![irpl],
        paths: 0,
        path_ends: vec![],
        exact: 1,
    };
    // The sun's render at four times the LDC's resolution: a dozen samples an LDI pixel.
    let settings = IbrrSettings {
        target_error: 0.0,
        resolution: 128,
        direct_hemicube: 512,
        ..Default::default()
    };
    let ldc = ldc_of(&scene, set, &settings);
    let pixel = ldc.frame.pixel_size();
    assert!(
        period < 0.5 * pixel,
        "the slats must be finer than an LDI pixel"
    );
    // Floor points whose path to the sun crosses the grating well inside it, and points
    // beside it (fully lit: the control).
    let cos = -direction.y;
    let expected = irradiance.x * cos;
    let mean_over = |x0: f32, z0: f32, half: f32| {
        let n = 120;
        let mut sum = 0.0f64;
        for k in 0..n * n {
            let x = x0 + half * (2.0 * ((k % n) as f32 + 0.5) / n as f32 - 1.0);
            let z = z0 + half * (2.0 * ((k / n) as f32 + 0.5) / n as f32 - 1.0);
            let (direct, _) = lookup(&ldc, Vec3::new(x, 0.0, z), Vec3::Y, Lookup::Bilinear, 2)
                .expect("every floor point has a layer");
            sum += f64::from(direct.x);
        }
        sum / (n * n) as f64 / f64::from(expected)
    };
    // The grating's shadow is shifted by height * (dx, dz) / cos.
    let (sx, sz) = (direction.x / cos * height, direction.z / cos * height);
    let under = mean_over(sx, sz, 0.3);
    let beside = mean_over(0.8, 0.8, 0.1);
    println!(
        "sun through a 50 % grating of period {period} (LDI pixel {pixel:.4}): {under:.4} of the open floor's irradiance under it, {beside:.4} beside it"
    );
    assert!((beside - 1.0).abs() < 0.01, "open floor: {beside}");
    // Point visibility at the layers' centres samples the slats' pattern; over some 1 500
    // layers its mean is within a tenth of the half it lets through.
    assert!((under - 0.5).abs() < 0.05, "under the grating: {under}");
}
