//! The scene contract across every method (DL, ISR, relighting, the IBRR, the reference;
//! CPU and, where an adapter exists, GPU): each hard case gets a finite image that agrees
//! with the reference, or the same typed refusal from every method
//! (`scene_core::contract`, docs/hostile-files.md).

use std::sync::Arc;

use golden_tests::scenes::{self, Outcome, keeps_contract, run, techniques};
use scene_core::glam::Vec3;
use scene_core::scene::Scene;
use scene_core::{SceneError, builtin};

const W: u32 = 24;
const H: u32 = 18;

fn gpu() -> Option<scene_core::gpu::GpuContext> {
    scene_core::testing::gpu_test_context()
}

/// Every technique's outcome for `scene`, each checked against the contract.
fn outcomes(scene: Scene) -> Vec<(&'static str, Outcome)> {
    let scene = Arc::new(scene);
    let ctx = gpu();
    techniques(ctx.as_ref())
        .into_iter()
        .map(|(name, mut t)| {
            let o = run(t.as_mut(), &scene, W, H);
            if let Err(e) = keeps_contract(&o, W, H) {
                panic!("{name} on {}: {e}", scene.name);
            }
            (name, o)
        })
        .collect()
}

#[test]
fn scenes_without_light_render_black_in_every_method() {
    for scene in [
        scenes::unlit_room(),
        scenes::single_triangle(),
        scenes::degenerate_emitter(),
    ] {
        let name = scene.name.clone();
        let contract = scene_core::contract::check(&scene).unwrap();
        assert!(!contract.lit, "{name}");
        assert!(
            contract.notes.iter().any(|n| n.contains("no light")),
            "{name}: {:?}",
            contract.notes
        );
        for (technique, o) in outcomes(scene) {
            let img = o.image(technique);
            assert!(
                img.pixels.iter().all(|p| *p == Vec3::ZERO),
                "{technique} on {name}: a scene without light must be black"
            );
        }
    }
}

#[test]
fn scenes_without_geometry_are_refused_by_every_method() {
    for scene in [scenes::empty_scene(), scenes::all_degenerate()] {
        let name = scene.name.clone();
        for (technique, o) in outcomes(scene) {
            match o.scene_error() {
                Some(SceneError::NoGeometry { scene, .. }) => assert_eq!(scene, &name),
                _ => panic!("{technique} on {name}: expected NoGeometry, got {o:?}"),
            }
        }
    }
}

#[test]
fn far_off_geometry_is_refused_by_every_method_naming_offset_and_extent() {
    for offset in [1e7f32, 1e30] {
        let scene = scenes::lit_room(true, false).translated(Vec3::new(offset, 0.0, 0.0));
        for (technique, o) in outcomes(scene) {
            match o.scene_error() {
                Some(SceneError::PrecisionLost {
                    offset: off,
                    extent,
                    ..
                }) => {
                    assert!((off / offset - 1.0).abs() < 1e-3, "{technique}: {off}");
                    // The f32 positions have lost their precision already: the extent
                    // is what is left of the room's 1.755.
                    assert!(*extent > 0.0 && *extent < 4.0, "{technique}: {extent}");
                }
                _ => panic!("{technique} at offset {offset}: expected PrecisionLost, got {o:?}"),
            }
        }
    }
}

#[test]
fn out_of_range_lights_and_albedos_are_refused_at_validation_naming_the_field() {
    let mut s = scenes::lit_room(true, true);
    s.point_lights[0].intensity = Vec3::splat(1e38);
    match s.validate() {
        Err(SceneError::OutOfRange {
            what, value, max, ..
        }) => {
            assert!(
                what.contains("bulb") && what.contains("intensity"),
                "{what}"
            );
            assert_eq!((value, max), (1e38, 1e12));
        }
        other => panic!("{other:?}"),
    }
    let mut s = scenes::lit_room(true, true);
    s.directional_lights.push(scene_core::DirectionalLight {
        name: "sun".into(),
        direction: Vec3::NEG_Y,
        irradiance: Vec3::new(1.0, 1e13, 1.0),
    });
    assert!(
        matches!(s.validate(), Err(SceneError::OutOfRange { what, .. }) if what.contains("sun"))
    );
    let mut s = scenes::lit_room(true, true);
    s.materials[2].emission = Vec3::splat(f32::MAX);
    assert!(
        matches!(s.validate(), Err(SceneError::OutOfRange { what, .. }) if what.contains("lamp"))
    );
    let mut s = scenes::lit_room(true, true);
    s.materials[0].albedo = Vec3::splat(0.9995);
    assert!(matches!(
        s.validate(),
        Err(SceneError::AlbedoOutOfRange { .. })
    ));
}

/// Mean absolute pixel difference over the mean of `a`, a per-pixel agreement measure:
/// [`scenes::relative_difference`] of `b` against `a`.
fn pixel_rel(a: &scene_core::Image, b: &scene_core::Image) -> f32 {
    scenes::relative_difference(b, a)
}

#[test]
fn cameras_looking_straight_down_or_up_render_in_every_method() {
    // Straight down or up with the default +Y up: the view takes -Z as its up hint, the
    // limit of a camera tilted by a milliradian towards -Z (down) or +Z (up), and every
    // method renders what it renders from that tilted camera.
    let base = scenes::lit_room(true, true);
    for (dir, tilt) in [(Vec3::NEG_Y, Vec3::NEG_Z), (Vec3::Y, Vec3::Z)] {
        let with_dir = |d: Vec3| {
            let mut s = base.clone();
            let c = &mut s.cameras[0];
            c.position = Vec3::new(0.5, 0.4, 0.6);
            c.target = c.position + d;
            c.up = Vec3::Y;
            s.validate().unwrap();
            s
        };
        let exact = outcomes(with_dir(dir));
        let tilted = outcomes(with_dir(dir + tilt * 1e-3));
        for ((technique, a), (_, b)) in exact.iter().zip(&tilted) {
            let (a, b) = (a.image(technique), b.image(technique));
            assert!(
                a.mean().max_element() > 0.0,
                "{technique} looking {dir}: black"
            );
            let e = pixel_rel(b, a);
            eprintln!("looking {dir}: {technique} differs from the tilted camera by {e:.4}");
            assert!(e < 0.05, "{technique} looking {dir}: {e}");
        }
    }
}

#[test]
fn extreme_camera_fields_are_refused_at_validation_naming_the_field() {
    let base = scenes::lit_room(true, true);
    type Edit = fn(&mut scene_core::Camera);
    let cases: [(&str, Edit); 4] = [
        ("field of view", |c| c.fov_y = 179.9f32.to_radians()),
        ("far / near", |c| {
            c.near = 1e-30;
            c.far = 1e30
        }),
        ("far / near", |c| c.near = 1e-9),
        ("far / near", |c| {
            c.near = 1e20;
            c.far = 1e21
        }),
    ];
    for (field, edit) in cases {
        let mut s = base.clone();
        edit(&mut s.cameras[0]);
        match s.validate() {
            Err(SceneError::InvalidCamera { camera, reason }) => {
                assert!(camera.contains("inside"), "{camera}");
                assert!(reason.contains(field), "{reason}");
            }
            other => panic!("{field}: {other:?}"),
        }
    }
    // The widest accepted camera renders in every method.
    let mut s = base.clone();
    s.cameras[0].fov_y = scene_core::scene::FOV_MAX;
    s.validate().unwrap();
    for (technique, o) in outcomes(s) {
        assert!(o.image(technique).mean().max_element() > 0.0, "{technique}");
    }
}

/// Each method's image of a scene and of the same scene moved by `offset` (its camera and
/// lights too) agree: translation invariance. Returns the worst per-pixel relative
/// difference per method.
fn translation_errors(offset: Vec3) -> Vec<(&'static str, f32)> {
    let base = scenes::lit_room(true, true);
    let moved = base.clone().translated(offset);
    let a = outcomes(base);
    let b = outcomes(moved);
    a.iter()
        .zip(&b)
        .map(|((n, oa), (_, ob))| (*n, pixel_rel(oa.image(n), ob.image(n))))
        .collect()
}

#[test]
fn a_moved_scene_renders_like_the_original_and_recentring_restores_it() {
    // 50 extents from the origin: within f32's precision, so every method accepts it and
    // must give the picture of the original.
    let offset = Vec3::new(60.0, -35.0, 70.0);
    for (technique, e) in translation_errors(offset) {
        eprintln!("moved by {offset}: {technique} differs by {e:.4} (mean |d| / mean)");
        assert!(e < 0.05, "{technique}: {e}");
    }
    // Recentring undoes a translation exactly up to rounding: the recentred scene renders
    // the same image as the original in every method.
    let base = scenes::lit_room(true, true);
    let far = base.clone().translated(Vec3::new(1000.0, 0.0, 0.0));
    let contract = scene_core::contract::check(&far).unwrap();
    assert!(contract.notes.iter().any(|n| n.contains("from the origin")));
    let (back, t) = far.recentred();
    assert!((t.x + 1000.5).abs() < 0.01, "{t}");
    let a = outcomes(base);
    let b = outcomes(back);
    for ((n, oa), (_, ob)) in a.iter().zip(&b) {
        let e = pixel_rel(oa.image(n), ob.image(n));
        eprintln!("recentred from 1000: {n} differs by {e:.5}");
        assert!(e < 0.02, "{n}: {e}");
    }
}

#[test]
fn scaled_scenes_render_like_the_original_in_every_method() {
    let base = scenes::lit_room(true, true);
    let a = outcomes(base.clone());
    for k in [1e-3f32, 1e3] {
        let b = outcomes(base.clone().scaled(k));
        for ((n, oa), (_, ob)) in a.iter().zip(&b) {
            let e = pixel_rel(oa.image(n), ob.image(n));
            eprintln!("scaled by {k}: {n} differs by {e:.5}");
            assert!(e < 0.05, "{n} scaled by {k}: {e}");
        }
    }
}

#[test]
fn built_in_scenes_keep_the_contract_and_are_lit() {
    for name in ["cornell", "cornell-point", "primitives", "corridor"] {
        let s = builtin::scene(name).unwrap();
        let c = scene_core::contract::check(&s).unwrap();
        assert!(c.lit && c.notes.is_empty(), "{name}: {c:?}");
    }
}

#[test]
fn coincident_faces_are_dropped_at_validation_keeping_the_first() {
    let base = scenes::lit_room(true, true);
    let mut doubled = base.clone();
    let m = &mut doubled.meshes[0];
    let n = m.indices.len();
    for i in 0..n {
        // Each face again, wound the other way (the same positions in another order).
        let [a, b, c] = m.indices[i];
        m.indices.push([a, c, b]);
        let id = m.material_ids[i];
        m.material_ids.push(id);
    }
    let report = doubled.validate().unwrap();
    assert_eq!(
        report.duplicates_dropped,
        vec![("mesh #0 'walls'".to_string(), n)]
    );
    assert_eq!(doubled, base, "the first of each pair is kept, as it was");
}

#[test]
fn a_diverging_relighting_solve_stops_at_once_naming_the_fault() {
    use relight_pr::RelightError;
    use relight_pr::solver::{DIVERGED_FRACTION, check_energy};
    assert!(check_energy(3, 1.0).is_ok() && check_energy(3, DIVERGED_FRACTION).is_ok());
    for bad in [f64::NAN, f64::INFINITY, 2.0] {
        match check_energy(7, bad) {
            Err(RelightError::Diverged { shots: 7, fraction }) => {
                assert!(fraction.is_nan() == bad.is_nan())
            }
            other => panic!("{bad}: {other:?}"),
        }
    }
    // A hemicube of one pixel a face gains energy: refused before the solve.
    let scene = scenes::lit_room(true, true);
    let meshing =
        relight_pr::Meshing::new(&scene, &relight_pr::MeshSettings::elements(64), 1).unwrap();
    let rays = scene_core::ray::RayScene::build(&scene);
    let mut renderer = gbuffer::CpuRasterizer::new();
    let settings = relight_pr::SolverSettings {
        form_factors: relight_pr::FormFactorMethod::Hemicube { resolution: 1 },
        ..Default::default()
    };
    let e = relight_pr::solver::solve_with(
        &scene,
        &meshing,
        &rays,
        Some(&mut renderer),
        &settings,
        &mut |_| {},
    )
    .unwrap_err();
    assert!(
        matches!(&e, RelightError::InvalidSetting(m) if m.contains("hemicube resolution 1")),
        "{e}"
    );
}

/// The scene fuzz target on a fixed budget with fixed seeds (its own seeds and 24 random
/// scenes): every method keeps the contract on each (a broken contract panics inside the
/// target, naming the method and the fault). `cargo xtask fuzz --target scenes` mutates
/// these further.
#[test]
fn the_scene_fuzz_target_keeps_the_contract_on_fixed_seeds() {
    let target = golden_tests::fuzz::targets()
        .into_iter()
        .find(|t| t.name == "scenes")
        .unwrap();
    let dir = golden_tests::hostile::scratch_dir("scene-specs");
    let ctx = golden_tests::fuzz::Context::new(golden_tests::fuzz::fuzz_budget(), &dir);
    let mut inputs = (target.seeds)();
    inputs.extend((100..124).map(|i| format!("{{\"seed\": {i}}}").into_bytes()));
    let (mut rendered, mut refused) = (0, 0);
    for input in &inputs {
        match golden_tests::fuzz::run(&target, input, &ctx) {
            golden_tests::fuzz::Outcome::Ok => rendered += 1,
            golden_tests::fuzz::Outcome::Refused(_) => refused += 1,
            golden_tests::fuzz::Outcome::Panicked(p) => {
                panic!("{}: {p}", String::from_utf8_lossy(input))
            }
        }
    }
    eprintln!("scene specs: {rendered} rendered by every method, {refused} refused");
    assert!(rendered > 0 && refused > 0, "{rendered} {refused}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Faces that overlap without repeating positions (each wall again, a thousandth of the way
/// to the room's centre, above the ray offsets of 2e-5 of the extent) are not dropped: every
/// method renders the room finite and close to its own image of the room without the
/// copies, or refuses by name (relighting's solve stops with `Diverged` if its form factors
/// gain energy). Closer than the ray offsets, two faces act as one face emitting twice
/// (every method, the reference too, sees both lamps of a doubled emitter).
#[test]
fn nearly_coincident_faces_render_like_single_faces_or_are_refused_by_name() {
    let base = scenes::lit_room(true, true);
    let mut doubled = base.clone();
    let m = &mut doubled.meshes[0];
    let centre = scene_core::glam::Vec3::new(0.5, 0.4, 0.6);
    let (n, v) = (m.indices.len(), m.positions.len());
    for i in 0..v {
        let p = m.positions[i];
        let nn = m.normals[i];
        m.positions.push(p + (centre - p) * 1e-3);
        m.normals.push(nn);
    }
    for i in 0..n {
        let t = m.indices[i].map(|x| x + v as u32);
        m.indices.push(t);
        let id = m.material_ids[i];
        m.material_ids.push(id);
    }
    let report = doubled.validate().unwrap();
    assert!(report.duplicates_dropped.is_empty());
    let a = outcomes(base);
    let b = outcomes(doubled);
    for ((name, oa), (_, ob)) in a.iter().zip(&b) {
        match ob {
            Outcome::Image(img) => {
                let e = pixel_rel(oa.image(name), img);
                eprintln!("nearly coincident faces: {name} differs by {e:.4}");
                // Relighting counts both of two near-coincident faces that face the same way
                // (docs/relight-pr.md, Known errors): the red block's doubled top, 1e-4 above
                // the original, receives and reflects twice. Measured 0.102 on 2026-11-25,
                // once the block's shading normals faced out (before, relighting found the
                // block's top hidden and never lit it); every other method stays below 0.01.
                let bound = if name.starts_with("relight") {
                    0.15
                } else {
                    0.1
                };
                assert!(e < bound, "{name}: {e}");
            }
            Outcome::Refused(e) => {
                let d = e
                    .method_error::<relight_pr::RelightError>()
                    .is_some_and(|r| matches!(r, relight_pr::RelightError::Diverged { .. }));
                assert!(d, "{name} refused without naming divergence: {e}");
            }
        }
    }
}

/// A view built in code (no camera check at load) whose planes f32 depth cannot resolve:
/// every rasterising method refuses the frame naming the planes, where it drew a black
/// image before; the path tracer (rays from the eye) renders it.
#[test]
fn frames_whose_planes_f32_depth_cannot_resolve_are_refused_by_rasterising_methods() {
    let scene = Arc::new(scenes::lit_room(true, true));
    let ctx = gpu();
    let mut view =
        scene_core::View::from_camera(&scene.cameras[0].with_aspect(W as f32 / H as f32));
    view.near = 1e-30;
    view.far = 1e30;
    let lights = scene_core::LightState::default();
    let frame = scene_core::FrameRequest {
        view,
        width: W,
        height: H,
        lights: &lights,
    };
    for (name, mut t) in techniques(ctx.as_ref()) {
        t.prepare(scene.clone()).unwrap();
        match t.render(&frame) {
            Ok(img) => {
                assert_eq!(name, "reference", "{name} rendered planes 1e-30 / 1e30");
                assert!(img.mean().max_element() > 0.0);
            }
            Err(e) => assert!(e.to_string().contains("far / near"), "{name}: {e}"),
        }
    }
}
