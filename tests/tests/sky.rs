//! The sky (`scene_core::sky`) in every method against the reference path tracer, which
//! integrates it exactly while the other methods see its median-cut directions:
//! - an open floor under a uniform sky, an uneven map, a one-pixel map and a one-row map
//!   reflects `albedo / pi` times the sky's irradiance (the analytic value) in the
//!   reference and in every method;
//! - a closed room lit only through one window by a sky: each method within its usual
//!   error of the reference (its error on the same room lit by a point light), and black
//!   with the sky switched off.

use std::sync::Arc;

use golden_tests::scenes::{self, relative_difference as rel};
use scene_core::glam::Vec3;
use scene_core::lights::{LightId, LightState};
use scene_core::reference::{ReferenceSettings, ReferenceTechnique};
use scene_core::scene::{Camera, Material, Mesh, Scene};
use scene_core::sky::Sky;
use scene_core::{FrameRequest, Image, Technique};

const W: u32 = 48;
const H: u32 = 36;
/// Samples per pixel of the window room's references: light through a small window is
/// noisy (two seeds at 512 differ by 0.19 of the image; at 2048 by half that).
const ROOM_SPP: u32 = 2048;
/// How many of the IBRR's builds (seeds 1, 2, ...) the window room judges it over.
const IBRR_BUILDS: u64 = 4;

fn reference(scene: &Scene, spp: u32, seed: u64) -> Image {
    scenes::reference_image(scene, spp, seed, W, H)
}

fn render(t: &mut dyn Technique, scene: &Scene) -> Image {
    scenes::render_image(t, scene, W, H)
}

fn methods() -> Vec<(&'static str, Box<dyn Technique>)> {
    scenes::compared_methods()
}

/// A grey floor seen from above, nothing else: under a sky it reflects `albedo / pi` times
/// the sky's irradiance on a surface facing up, everywhere.
fn open_floor(sky: Sky, albedo: f32) -> Scene {
    let mut s = Scene::new("open floor");
    s.materials
        .push(Material::diffuse("grey", Vec3::splat(albedo)));
    let mut m = Mesh {
        name: "floor".into(),
        ..Default::default()
    };
    m.push_quad_facing(
        [
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(2.0, 0.0, -2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(-2.0, 0.0, 2.0),
        ],
        0,
        Vec3::Y,
    );
    s.meshes.push(m);
    s.cameras.push(Camera {
        name: "above".into(),
        position: Vec3::new(0.0, 3.0, 0.5),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y: 0.6,
        aspect: W as f32 / H as f32,
        near: 0.01,
        far: 10.0,
    });
    s.sky = Some(sky);
    s.validate().expect("the floor is valid");
    s
}

/// An uneven map: a dim blue sky with a bright warm patch high in it, black below the
/// horizon.
fn uneven_sky() -> Sky {
    let (w, h) = (32u32, 16u32);
    let map = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if y >= h / 2 {
                Vec3::ZERO
            } else if (3..6).contains(&y) && (10..14).contains(&x) {
                Vec3::new(8.0, 6.0, 4.0)
            } else {
                Vec3::new(0.2, 0.3, 0.6)
            }
        })
        .collect();
    Sky::from_map("uneven", w, h, map, 64).unwrap()
}

/// A large map (2048x1024, two million pixels): a gradient from a pale horizon to a deeper
/// zenith, a small bright sun, and a dim ground below the horizon.
fn huge_sky() -> Sky {
    let (w, h) = (2048u32, 1024u32);
    let map = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if y >= h / 2 {
                Vec3::new(0.05, 0.04, 0.03)
            } else if (300..310).contains(&y) && (700..712).contains(&x) {
                Vec3::new(2e3, 1.8e3, 1.5e3)
            } else {
                let t = y as f32 / (h / 2) as f32;
                Vec3::new(0.3, 0.45, 0.9) * (1.0 - t) + Vec3::new(0.9, 0.9, 0.85) * t
            }
        })
        .collect();
    Sky::from_map("huge", w, h, map, 64).unwrap()
}

#[test]
fn an_open_floor_reflects_the_sky_irradiance_in_every_method() {
    let albedo = 0.5;
    // Degenerate maps too: one pixel over the whole sphere, one row of uneven azimuths
    // centred on the horizon, and a map of two million pixels (held refined for the median cut; DL and ISR received nothing
    // from them, the IBRR 0-22 % of the reference's light).
    let row: Vec<Vec3> = (0..7)
        .map(|i| Vec3::new(0.2 + 0.3 * i as f32, 0.5, 1.0 - 0.1 * i as f32))
        .collect();
    for sky in [
        Sky::uniform(Vec3::new(1.0, 0.8, 0.6)).unwrap(),
        uneven_sky(),
        Sky::from_map("one pixel", 1, 1, vec![Vec3::new(0.9, 0.7, 0.4)], 64).unwrap(),
        Sky::from_map("one row", 7, 1, row, 64).unwrap(),
        huge_sky(),
    ] {
        let expected = sky.irradiance(Vec3::Y) * albedo / std::f32::consts::PI;
        let scene = open_floor(sky.clone(), albedo);
        // The reference: every pixel's mean over the floor within 1% (it integrates the
        // sky; the floor sees nothing else).
        let r = reference(&scene, 64, 3);
        let mean = r.mean();
        eprintln!("{}: expected {expected}, reference {mean}", sky.name);
        assert!(
            (mean - expected).abs().max_element() < 0.01 * expected.max_element(),
            "{}: reference {mean}, expected {expected}",
            sky.name
        );
        // Every method: the directions are exact for a surface that sees the whole sky
        // above its horizon, so each is within 2% of the value (ISR's SSAO and the IBRR's
        // lookups darken nothing on an open plane).
        for (name, mut t) in methods() {
            let img = render(t.as_mut(), &scene);
            let m = img.mean();
            eprintln!("{}: {name} {m}", sky.name);
            assert!(
                (m - expected).abs().max_element() < 0.02 * expected.max_element(),
                "{}: {name} {m}, expected {expected}",
                sky.name
            );
        }
    }
}

/// The lit room's walls with a window in the +X wall (the rest as `scenes::lit_room`),
/// lit by nothing but `sky`.
fn room_with_window(sky: Option<Sky>) -> Scene {
    let mut s = scenes::lit_room(false, false);
    // Replace the +X wall (x = 1) by four quads around a window.
    let (x, lo, hi) = (1.0f32, Vec3::ZERO, Vec3::new(1.0, 0.8, 1.2));
    let (y0, y1, z0, z1) = (0.3, 0.65, 0.35, 0.85);
    let m = &mut s.meshes[0];
    let keep: Vec<usize> = (0..m.indices.len())
        .filter(|&t| {
            !m.indices[t]
                .iter()
                .all(|&i| (m.positions[i as usize].x - x).abs() < 1e-6)
        })
        .collect();
    m.indices = keep.iter().map(|&t| m.indices[t]).collect();
    m.material_ids = keep.iter().map(|&t| m.material_ids[t]).collect();
    let inside = Vec3::new(0.5, 0.4, 0.6);
    let q = |a: (f32, f32), b: (f32, f32)| {
        [
            Vec3::new(x, a.0, a.1),
            Vec3::new(x, b.0, a.1),
            Vec3::new(x, b.0, b.1),
            Vec3::new(x, a.0, b.1),
        ]
    };
    for c in [
        q((lo.y, lo.z), (y0, hi.z)),
        q((y1, lo.z), (hi.y, hi.z)),
        q((y0, lo.z), (y1, z0)),
        q((y0, z1), (y1, hi.z)),
    ] {
        m.push_quad_facing(c, 0, inside);
    }
    s.sky = sky;
    s.validate().expect("the room is valid");
    s
}

#[test]
fn a_room_lit_through_a_window_by_the_sky_matches_the_reference_in_every_method() {
    window_room_matches_the_reference(Sky::uniform(Vec3::new(1.0, 0.9, 0.8)).unwrap());
}

/// A one-pixel map: one radiance over the whole sphere, so light also comes up through the
/// window from below the horizon and lights the ceiling.
#[test]
fn a_room_lit_through_a_window_by_a_one_pixel_sky_matches_the_reference_in_every_method() {
    window_room_matches_the_reference(
        Sky::from_map("one pixel", 1, 1, vec![Vec3::new(0.9, 0.7, 0.4)], 64).unwrap(),
    );
}

fn window_room_matches_the_reference(sky: Sky) {
    let room = room_with_window(Some(sky));
    let ref_sky = reference(&room, ROOM_SPP, 5);
    assert!(
        ref_sky.mean().min_element() > 0.0,
        "the window lets light in"
    );
    // The same room lit through the same window by a sun instead, which every method
    // carries natively: each method's usual error on light through a window.
    let mut sunlit = room_with_window(None);
    sunlit
        .directional_lights
        .push(scene_core::DirectionalLight {
            name: "sun".into(),
            direction: Vec3::new(-1.0, -0.8, 0.1).normalize(),
            irradiance: Vec3::splat(3.0),
        });
    let ref_sun = reference(&sunlit, ROOM_SPP, 5);
    // What the directional stand-in costs the reference itself: the same room lit by the
    // sky's median-cut directions as directional lights.
    let mut as_suns = room.clone();
    as_suns.directional_lights = as_suns.sky.take().unwrap().lights().to_vec();
    let stand_in = rel(&reference(&as_suns, ROOM_SPP, 5), &ref_sky);
    let noise = rel(&reference(&room, ROOM_SPP, 6), &ref_sky);
    eprintln!(
        "reference: the sky's {} directions differ from the sky by {stand_in:.3} (two seeds \
         by {noise:.3})",
        room.sky.as_ref().unwrap().lights().len()
    );
    let off = {
        let mut s = LightState::default();
        s.set_enabled(LightId::Sky, false);
        s
    };
    let camera = room.cameras[0].clone();
    let mut checked = 0;
    let names: Vec<&str> = methods().iter().map(|(name, _)| *name).collect();
    for (i, name) in names.into_iter().enumerate() {
        // The IBRR is judged over its first IBRR_BUILDS builds: one build at 64 IRPLs
        // spreads widely in a room lit through a window (under a one-pixel sky, seed 1 read
        // 0.794 off with camera importance while 8 seeds averaged 0.44, the same as under
        // the uniform sky's 0.44), and its per-build error is issue 48's subject. Every
        // build's figures are printed. It is built as for a room lit through a window,
        // with entry importance (docs/ibrr-ldc.md). Since its walks are dealt into 16
        // independent batches (2026-11-29), uniform starts read 0.73 off under this sky
        // over 8 builds (0.45 to 1.10 each) against 0.46 for the sun, past the bound
        // below; with entry importance the sky reads 0.43 to 0.47 over 4 builds, within
        // even the uniform starts' bound, while the sun through the window reads 0.56 to
        // 0.84 (0.38 to 0.68 uniform), which is not understood yet.
        let builds = if name.starts_with("ibrr") {
            IBRR_BUILDS
        } else {
            1
        };
        let (mut e_sky, mut e_usual) = (0.0, 0.0);
        for seed in 1..=builds {
            let mut t = scenes::compared_methods_with(seed, true).swap_remove(i).1;
            let mut usual = scenes::compared_methods_with(seed, true).swap_remove(i).1;
            let image = render(t.as_mut(), &room);
            let (e, u) = (
                rel(&image, &ref_sky),
                rel(&render(usual.as_mut(), &sunlit), &ref_sun),
            );
            eprintln!(
                "{} / {name} (build {seed}): sky {e:.3} off the reference (mean {:.3} of \
                 it), a sun through the window {u:.3}",
                room.sky.as_ref().unwrap().name,
                image.mean().element_sum() / ref_sky.mean().element_sum()
            );
            e_sky += e / builds as f32;
            e_usual += u / builds as f32;
            if seed == 1 {
                // The sky switched off through the light state: black.
                let dark = t
                    .render(&FrameRequest::from_camera(&camera, W, H, &off))
                    .unwrap();
                let max = dark
                    .pixels
                    .iter()
                    .map(|p| p.max_element())
                    .fold(0.0, f32::max);
                assert_eq!(max, 0.0, "{name}: the sky is off");
            }
        }
        // The sky may cost a method half its usual error more, or what its median-cut
        // directions cost the reference itself (`stand_in`, 0.21 here: the methods shade
        // those directions, the reference integrates the sky), whichever is larger. With
        // `e_usual + 0.05` in place of the latter, the IBRR with camera importance (low
        // noise, so the directions' error is most of its error) read 1.44 x its usual
        // error on average over 8 seeds (0.427 against 0.297) and passed on seed 1 only
        // by chance.
        assert!(
            e_sky <= (1.5 * e_usual).max(e_usual + stand_in),
            "{name}: sky {e_sky}, usual {e_usual}, stand-in {stand_in} (over {builds} builds)"
        );
        checked += 1;
    }
    assert!(checked >= 4, "{checked} methods");
    let dark = ReferenceTechnique::new(ReferenceSettings {
        spp: 8,
        ..Default::default()
    });
    let mut dark = dark;
    dark.prepare(Arc::new(room.clone())).unwrap();
    let img = dark
        .render(&FrameRequest::from_camera(&camera, W, H, &off))
        .unwrap();
    assert!(
        img.pixels.iter().all(|p| *p == Vec3::ZERO),
        "reference, sky off"
    );
}

/// The reference gives a uniform sky no next-event estimate of its own (the cosine-weighted
/// bounce alone samples it), and draws every other sky from its map with MIS. Both
/// estimate the same light: the window room under a uniform sky and under the same sky
/// with one zenith pixel a millionth brighter (so it is sampled from its map; the change
/// is 10^-9 of its light) agree in every 12x12 block of the image and over the whole image
/// within five standard errors. The standard errors come from the spread of 16 renders of
/// each at seeds of their own (the per-sample variance over-states a stratified render's
/// error several times, and would hide a bias of a few percent).
#[test]
fn a_uniform_sky_without_its_own_estimate_equals_one_drawn_from_its_map() {
    let l = Vec3::new(1.0, 0.9, 0.8);
    let uniform = Sky::uniform(l).unwrap();
    let (w, h) = uniform.size();
    let mut map = uniform.map().to_vec();
    map[0] *= 1.0 + 1e-6;
    let drawn = Sky::from_map("drawn", w, h, map, 64).unwrap();
    assert!(uniform.is_uniform() && !drawn.is_uniform());
    const SEEDS: u64 = 16;
    // Per sky, per block (12x12 blocks, then the whole image): the mean over seeds of the
    // block's mean, and its standard error from the seeds' spread.
    let blocks = |sky: Sky, first_seed: u64| {
        let room = room_with_window(Some(sky));
        let view = scene_core::View::from_camera(&room.cameras[0]);
        let per_seed: Vec<Vec<Vec3>> = (first_seed..first_seed + SEEDS)
            .map(|seed| {
                let settings = ReferenceSettings {
                    width: W,
                    height: H,
                    spp: 64,
                    bounces: scene_core::reference::Bounces::Unlimited,
                    seed,
                };
                let img = scene_core::reference::render(&room, &view, &settings, None).image;
                let mean = |x0: u32, y0: u32, k: u32| {
                    let (mut sum, mut n) = (Vec3::ZERO, 0.0);
                    for y in y0..(y0 + k).min(H) {
                        for x in x0..(x0 + k).min(W) {
                            sum += img.get(x, y);
                            n += 1.0;
                        }
                    }
                    sum / n
                };
                let mut m: Vec<Vec3> = (0..H)
                    .step_by(12)
                    .flat_map(|y| (0..W).step_by(12).map(move |x| (x, y)))
                    .map(|(x, y)| mean(x, y, 12))
                    .collect();
                m.push(mean(0, 0, W.max(H)));
                m
            })
            .collect();
        (0..per_seed[0].len())
            .map(|b| {
                let n = SEEDS as f32;
                let mean = per_seed.iter().map(|m| m[b]).sum::<Vec3>() / n;
                let var = per_seed
                    .iter()
                    .map(|m| (m[b] - mean) * (m[b] - mean))
                    .sum::<Vec3>()
                    / (n - 1.0);
                (mean, (var / n).powf(0.5))
            })
            .collect::<Vec<_>>()
    };
    let (a, b) = (blocks(uniform, 1), blocks(drawn, 1 + SEEDS));
    for (i, ((ma, sa), (mb, sb))) in a.iter().zip(&b).enumerate() {
        let se = (*sa * *sa + *sb * *sb).powf(0.5);
        let z = (*ma - *mb).abs() / se.max(Vec3::splat(1e-12));
        eprintln!("block {i}: uniform {ma}, drawn {mb}, {z} standard errors");
        assert!(
            z.max_element() <= 5.0,
            "block {i}: uniform {ma} and drawn {mb} differ by {z} standard errors"
        );
    }
}

/// `--sky` as the command lines parse it: a grey or RGB uniform sky, an EXR map, and
/// errors that name the fault.
#[test]
fn the_sky_flag_parses_colours_and_exr_maps_and_names_its_faults() {
    let mut a = scene_core::AddedLights::default();
    a.parse_sky("0.5").unwrap();
    assert_eq!(a.sky.as_ref().unwrap().radiance(Vec3::Y), Vec3::splat(0.5));
    a.parse_sky("1,2,3").unwrap();
    assert_eq!(
        a.sky.as_ref().unwrap().radiance(Vec3::Y),
        Vec3::new(1.0, 2.0, 3.0)
    );
    let dir = std::env::temp_dir().join(format!("sky-flag-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exr = dir.join("env.exr");
    let sky = uneven_sky();
    let (w, h) = sky.size();
    Image::from_pixels(w, h, sky.map().to_vec())
        .unwrap()
        .write_exr(&exr)
        .unwrap();
    a.parse_sky(exr.to_str().unwrap()).unwrap();
    let read = a.sky.as_ref().unwrap();
    assert_eq!(read.map(), sky.map());
    assert_eq!(read.name, "env.exr");
    for (spec, says) in [
        ("blue", "'blue' is not a number"),
        ("-1", "negative"),
        ("1,2", "one or three numbers"),
        ("nan", "not finite"),
    ] {
        let e = a.parse_sky(spec).unwrap_err();
        assert!(e.contains("--sky") && e.contains(says), "{spec}: {e}");
    }
    a.set_sky_directions(256).unwrap();
    assert_eq!(a.sky.as_ref().unwrap().lights().len(), 256);
    for n in [0, 1025] {
        let e = a.set_sky_directions(n).unwrap_err();
        assert!(
            e.contains("--sky-directions") && e.contains("1 to 1024"),
            "{e}"
        );
    }
    let e = scene_core::AddedLights::default()
        .set_sky_directions(8)
        .unwrap_err();
    assert!(e.contains("no --sky"), "{e}");
    let missing = dir.join("missing.exr");
    let e = a.parse_sky(missing.to_str().unwrap()).unwrap_err();
    assert!(e.contains("missing.exr"), "{e}");
    std::fs::write(dir.join("bad.exr"), b"not an exr").unwrap();
    let e = a
        .parse_sky(dir.join("bad.exr").to_str().unwrap())
        .unwrap_err();
    assert!(e.contains("bad.exr"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
    // Added to a lightless scene it lights it, and the note says so.
    let mut added = scene_core::AddedLights::default();
    added.parse_sky("1").unwrap();
    let opened = scene_core::open_scene_with("cornell", &added).unwrap();
    assert!(opened.scene.sky.is_some());
    assert!(
        opened.notes.iter().any(|n| n.contains("added sky")),
        "{:?}",
        opened.notes
    );
}

/// The measurement behind the default count of directions (run with `--ignored
/// --nocapture`): the window room's error against the reference for the reference itself
/// fed the directions as directional lights, and for each method, at 16 to 1024 directions.
#[test]
#[ignore = "a measurement: prints the error of each method per count of directions"]
fn sky_directions_sweep() {
    let base = Sky::uniform(Vec3::new(1.0, 0.9, 0.8)).unwrap();
    let room = room_with_window(Some(base.clone()));
    let ref_sky = reference(&room, 8192, 5);
    for n in [16, 64, 256] {
        let sky = base.with_directions(n).unwrap();
        let scene = room_with_window(Some(sky.clone()));
        let mut as_suns = scene.clone();
        as_suns.directional_lights = as_suns.sky.take().unwrap().lights().to_vec();
        let t0 = std::time::Instant::now();
        let stand_in = rel(&reference(&as_suns, 1024, 5), &ref_sky);
        eprintln!(
            "{n} directions: reference fed the directions {stand_in:.3} ({:?})",
            t0.elapsed()
        );
        for (name, mut t) in methods() {
            let t0 = std::time::Instant::now();
            let e = rel(&render(t.as_mut(), &scene), &ref_sky);
            eprintln!("{n} directions: {name} {e:.3} ({:.2?})", t0.elapsed());
        }
    }
}

/// The window room lit through its window by a sun (3 / 2.8 / 2.4) and a uniform sky
/// (0.5 / 0.6 / 0.8).
fn sun_and_sky_room() -> Scene {
    let mut room = room_with_window(Some(Sky::uniform(Vec3::new(0.5, 0.6, 0.8)).unwrap()));
    room.directional_lights.push(scene_core::DirectionalLight {
        name: "sun".into(),
        direction: Vec3::new(-1.0, -0.8, 0.1).normalize(),
        irradiance: Vec3::new(3.0, 2.8, 2.4),
    });
    room
}

/// Relighting's shadow-mapped direct light (`DirectLight::shadow_maps`, what a new view
/// costs a frame) in the window room lit by a sun and a sky: along a short camera path its
/// error against the reference stays within 1.2x of the per-pixel gather's (issue 49),
/// with hard lookups (the default) and with soft ones (`ShadowSettings::penumbrae`, each
/// sky direction casting its region's penumbra). The gather draws one direction within
/// each of the sky's regions per footprint point, so its shadows are soft. Each figure is
/// printed (2026-12-01: hard 1.04 / 0.97 / 1.09, soft 0.86 / 0.86 / 0.91; nine footprint
/// points a sky direction, as before, read 1.27 on the first view). Since the sun's deep
/// shadow at a pixel's centre also asks the footprint's corners (2026-12-03): hard 1.12 /
/// 1.05 / 1.16, soft 0.95 / 0.93 / 0.98. Eight to eleven pixels a view changed, where the
/// footprint's plane runs past the surface into the sunlight; the gather reads them as
/// bright (docs/relight-pr.md).
#[test]
fn relighting_shadow_maps_in_a_sun_and_sky_room_are_within_1_2x_of_the_gather() {
    let room = Arc::new(sun_and_sky_room());
    let mut t = relight_pr::RelightTechnique::new(
        relight_pr::MeshSettings::elements(1024),
        relight_pr::SolverSettings::default(),
        Box::new(gbuffer::CpuRasterizer::new()),
    );
    t.prepare(room.clone()).unwrap();
    let c0 = room.cameras[0].clone();
    let forward = (c0.target - c0.position).normalize();
    let right = forward.cross(c0.up).normalize();
    let step = 0.06 * room.extent();
    let state = LightState::default();
    let mut worst: f32 = 0.0;
    for (f, (r, u)) in [(0.0f32, 0.0f32), (1.0, 0.0), (-1.0, 0.7)]
        .into_iter()
        .enumerate()
    {
        let camera = Camera {
            position: c0.position + right * (r * step) + c0.up.normalize() * (u * step),
            ..c0.clone()
        };
        let mut view = (*room).clone();
        view.cameras = vec![camera.clone()];
        let truth = reference(&view, ROOM_SPP, 5 + f as u64);
        let mut frame = |direct: relight_pr::direct::DirectLight| {
            t.direct = direct;
            let image = t
                .render(&FrameRequest::from_camera(&camera, W, H, &state))
                .unwrap();
            (rel(&image, &truth), t.last_timings().direct)
        };
        let (gather, gather_time) = frame(relight_pr::direct::DirectLight::default());
        for penumbrae in [false, true] {
            let (maps, maps_time) = frame(if penumbrae {
                relight_pr::direct::DirectLight::soft_shadow_maps()
            } else {
                relight_pr::direct::DirectLight::shadow_maps()
            });
            eprintln!(
                "sun and sky, view {f}: per-pixel gather {gather:.3} ({:.1} ms), shadow maps \
                 ({}) {maps:.3} ({:.1} ms), ratio {:.2}",
                1e3 * gather_time.as_secs_f64(),
                if penumbrae { "soft" } else { "hard" },
                1e3 * maps_time.as_secs_f64(),
                maps / gather
            );
            worst = worst.max(maps / gather);
        }
    }
    assert!(worst <= 1.2, "shadow maps {worst:.2}x the gather's error");
}

/// The soft lookup of the sky's maps (`scene_core::shadow`'s `soft_pcf`, the WGSL twin of
/// `esm::soft_pcf`, with `ShadowSettings::penumbrae`) gives on the GPU the images the CPU
/// gives: in the window room under a sun and a sky, DL (the ISR crate's lighting pass) and
/// relighting's shadow-mapped direct light, each within 1e-3 of the image's mean on
/// average and of its peak at every pixel (a tap's texel is `floor(x + 1/2)` in both, so
/// that only rounding can move a tap); and the soft lookups change the image (they are
/// the ones compared).
#[test]
fn soft_sky_shadows_on_the_gpu_equal_the_cpu_twin() {
    let Some(ctx) = scene_core::testing::gpu_test_context() else {
        return;
    };
    let room = sun_and_sky_room();
    let dl = |penumbrae: bool, gpu: bool| {
        let mut t = isr::IsrTechnique::new(
            isr::IsrSettings::dl(),
            Box::new(gbuffer::CpuRasterizer::new()),
        );
        if gpu {
            t = t.with_backend(isr::Backend::Gpu(ctx.clone()));
        }
        t.shadows.penumbrae = penumbrae;
        Box::new(t) as Box<dyn Technique>
    };
    let relight = |penumbrae: bool, gpu: bool| {
        let mut t = relight_pr::RelightTechnique::new(
            relight_pr::MeshSettings::elements(64),
            relight_pr::SolverSettings::default(),
            Box::new(gbuffer::CpuRasterizer::new()),
        );
        t.direct = if penumbrae {
            relight_pr::direct::DirectLight::soft_shadow_maps()
        } else {
            relight_pr::direct::DirectLight::shadow_maps()
        };
        if gpu {
            t = t.on_gpu(ctx.clone());
        }
        Box::new(t) as Box<dyn Technique>
    };
    let mut images: std::collections::HashMap<&str, Image> = Default::default();
    for (name, mut t) in [
        ("dl", dl(true, false)),
        ("dl-gpu", dl(true, true)),
        ("dl-hard", dl(false, false)),
        ("relight-maps", relight(true, false)),
        ("relight-gpu", relight(true, true)),
        ("relight-hard", relight(false, false)),
    ] {
        images.insert(name, render(t.as_mut(), &room));
    }
    let truth = reference(&room, ROOM_SPP, 5);
    for (soft, hard) in [("dl", "dl-hard"), ("relight-maps", "relight-hard")] {
        let moved = rel(&images[soft], &images[hard]);
        eprintln!(
            "{soft}: soft lookups move the image by {moved:.3}; off the reference soft {:.3}, \
             hard {:.3}",
            rel(&images[soft], &truth),
            rel(&images[hard], &truth)
        );
        assert!(
            moved > 0.01,
            "{soft}: soft and hard lookups agree ({moved})"
        );
    }
    for (cpu, gpu) in [("dl", "dl-gpu"), ("relight-maps", "relight-gpu")] {
        let (a, b) = (&images[cpu], &images[gpu]);
        let mean = a.mean().element_sum() / 3.0;
        let peak = a.pixels.iter().map(|p| p.max_element()).fold(0.0, f32::max);
        let diffs: Vec<f32> = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(p, q)| (*p - *q).abs().max_element())
            .collect();
        let avg = diffs.iter().sum::<f32>() / diffs.len() as f32;
        let max = diffs.iter().copied().fold(0.0, f32::max);
        eprintln!(
            "{cpu} against {gpu}: mean |cpu - gpu| {avg:.2e} (image mean {mean:.3e}), max {max:.2e} (peak {peak:.3e})"
        );
        assert!(mean > 0.0, "{cpu}: the room is lit");
        assert!(avg <= 1e-3 * mean, "{cpu}: mean difference {avg}");
        assert!(max <= 1e-3 * peak, "{cpu}: max difference {max}");
    }
}
