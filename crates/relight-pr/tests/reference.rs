//! Relighting against the reference path tracer (unlimited bounces): the error falls as
//! the element count grows, and one light's relit solution matches a reference render with
//! only that light on.

use std::sync::Arc;

use relight_pr::direct::DirectLight;
use relight_pr::{MeshSettings, RelightTechnique, SolverSettings};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::lights::{LightId, LightState};
use scene_core::reference::{Bounces, ReferenceSettings, render_lit};
use scene_core::{FrameRequest, Image, Technique, View, builtin};

const W: u32 = 48;
const H: u32 = 36;

fn reference(scene: &scene_core::Scene, state: &LightState) -> Image {
    reference_seeded(scene, state, 3)
}

fn reference_seeded(scene: &scene_core::Scene, state: &LightState, seed: u64) -> Image {
    reference_at(scene, &scene.cameras[0], state, seed)
}

fn reference_at(
    scene: &scene_core::Scene,
    camera: &scene_core::Camera,
    state: &LightState,
    seed: u64,
) -> Image {
    let view = View::from_camera(&camera.with_aspect(W as f32 / H as f32));
    let settings = ReferenceSettings {
        width: W,
        height: H,
        spp: 512,
        bounces: Bounces::Unlimited,
        seed,
    };
    render_lit(scene, &view, &settings, state, None).image
}

fn relit(scene: &Arc<scene_core::Scene>, elements: usize, state: &LightState) -> Image {
    relit_with(scene, elements, &[DirectLight::default()], state).remove(0)
}

/// The technique prepared on `scene` at `elements` (solved to 0.1 % unshot, 8 visibility
/// rays).
fn solved(scene: &Arc<scene_core::Scene>, elements: usize) -> RelightTechnique {
    let mut t = RelightTechnique::new(
        MeshSettings::elements(elements),
        SolverSettings {
            max_unshot: 1e-3,
            visibility_samples: 8,
            ..Default::default()
        },
        Box::new(RayCastRenderer::new()),
    );
    t.prepare(scene.clone()).unwrap();
    t
}

/// One solve at `elements`, displayed with each of `directs`.
fn relit_with(
    scene: &Arc<scene_core::Scene>,
    elements: usize,
    directs: &[DirectLight],
    state: &LightState,
) -> Vec<Image> {
    let mut t = solved(scene, elements);
    directs
        .iter()
        .map(|&d| {
            t.direct = d;
            t.render(&FrameRequest::from_camera(&scene.cameras[0], W, H, state))
                .unwrap()
        })
        .collect()
}

/// Mean absolute error (eq. 19) and bias of the image mean, both relative to the
/// reference's mean, over the pixels where the relit G-buffer does not see an emitter
/// (visible emitters are point-sampled by the G-buffer and area-averaged by the reference:
/// their edges alone would dominate at this size).
fn errors(relit: &Image, truth: &Image, emitter: &[bool]) -> (f64, f64) {
    let keep: Vec<usize> = (0..relit.pixels.len()).filter(|&i| !emitter[i]).collect();
    let sum = |img: &Image| {
        keep.iter()
            .map(|&i| img.pixels[i].element_sum() as f64)
            .sum::<f64>()
    };
    let abs: f64 = keep
        .iter()
        .map(|&i| (relit.pixels[i] - truth.pixels[i]).abs().element_sum() as f64)
        .sum();
    let m = sum(truth);
    (abs / m, sum(relit) / m - 1.0)
}

/// Pixels whose G-buffer triangle is an emitter.
fn emitter_pixels(scene: &scene_core::Scene) -> Vec<bool> {
    emitter_pixels_at(scene, &scene.cameras[0])
}

/// Pixels whose G-buffer triangle is an emitter, seen by `camera`.
fn emitter_pixels_at(scene: &scene_core::Scene, camera: &scene_core::Camera) -> Vec<bool> {
    use scene_core::GBufferRenderer;
    let view = View::from_camera(&camera.with_aspect(W as f32 / H as f32));
    let g = RayCastRenderer::new().render(scene, &view, W, H).unwrap();
    g.emitter_mask(scene)
}

#[test]
fn error_against_the_reference_falls_with_the_element_count() {
    let scene = Arc::new(builtin::scene("cornell-point").unwrap());
    let truth = reference(&scene, &LightState::default());
    let emitter = emitter_pixels(&scene);
    // The reference's own noise: a second render with another seed is this far from it.
    let (floor, _) = errors(
        &reference_seeded(&scene, &LightState::default(), 4),
        &truth,
        &emitter,
    );
    eprintln!(
        "reference noise: a second seed differs by {:.1} %",
        100.0 * floor
    );
    let modes = [DirectLight::Elements, DirectLight::default()];
    // measured[n][mode] = (mean error, bias)
    let measured: Vec<Vec<(f64, f64)>> = [64usize, 256, 1024, 4096]
        .iter()
        .map(|&n| {
            relit_with(&scene, n, &modes, &LightState::default())
                .iter()
                .zip(&modes)
                .map(|(image, direct)| {
                    let (e, bias) = errors(image, &truth, &emitter);
                    eprintln!(
                        "cornell-point, {n} elements, direct {direct:?}: mean error {:.1} %, bias {:+.1} % of the mean",
                        100.0 * e,
                        100.0 * bias
                    );
                    (e, bias)
                })
                .collect()
        })
        .collect();
    // The paper's display: the error falls with every refinement of the mesh.
    for w in measured.windows(2) {
        assert!(w[1][0].0 < w[0][0].0, "{measured:?}");
    }
    // Direct light per pixel: better than the paper's display at every element count, and
    // at the default count (4096) the image mean within a few percent of the reference.
    // Measured: mean error 24 / 23 / 23 / 23 % against 64 / 50 / 39 / 37 %; bias -6.2 %
    // at 4096 (the hot spot 1 cm under the ceiling: two pixels hold a tenth of the image).
    for row in &measured {
        assert!(row[1].0 < 0.75 * row[0].0, "{measured:?}");
    }
    assert!(measured[3][1].1.abs() < 0.08, "{measured:?}");
}

#[test]
fn one_light_relit_alone_matches_the_reference_with_only_that_light() {
    let scene = Arc::new(builtin::scene("corridor").unwrap());
    let emitter = emitter_pixels(&scene);
    let all = relit(&scene, 1024, &LightState::default());
    let truth_all = reference(&scene, &LightState::default());
    let (e_all, b_all) = errors(&all, &truth_all, &emitter);
    assert!(b_all.abs() < 0.15, "all lights: bias {b_all}");
    eprintln!(
        "corridor, all lights: mean error {:.1} %, bias {:+.1} %",
        100.0 * e_all,
        100.0 * b_all
    );
    for id in [LightId::Point(0), LightId::Point(2)] {
        let only = LightState::only(&scene, id);
        let (e, bias) = errors(
            &relit(&scene, 1024, &only),
            &reference(&scene, &only),
            &emitter,
        );
        eprintln!(
            "corridor, {id:?} alone: mean error {:.1} %, bias {:+.1} %",
            100.0 * e,
            100.0 * bias
        );
        // One light carries about a quarter of the corridor's light: a solution holding
        // another light's energy would be off by tens of percent, or several times over.
        // Measured: mean error 12 % and 25 %, bias -5 % and -6 % (all lights: 10 %, -3.5 %).
        assert!(bias.abs() < 0.15, "{id:?}: bias {bias}");
        assert!(
            e < 1.5 * e_all.max(0.2),
            "{id:?}: error {e} against {e_all} for all lights"
        );
    }
}

#[test]
fn the_image_mean_at_the_default_element_count_is_the_references_over_whole_pixels() {
    // The reference averages jittered samples over each pixel; a G-buffer samples its
    // centre. Rendered at 4 x 4 samples per pixel and box-filtered, relighting's image is
    // compared like for like, every pixel counted (emitters too). Measured against a
    // 4096-spp reference: cornell-point mean error 8.0 %, bias -0.1 % (one sample per
    // pixel: 12.5 %, -4.4 %); cornell 2.5 %, +0.3 % (one sample: 36 %, -13.5 %, nearly all
    // of it the light's edges). Against this test's 512-spp reference: -0.57 % and +0.60 %
    // (cornell measured once, left out of the suite for its time).
    let name = "cornell-point";
    let scene = Arc::new(builtin::scene(name).unwrap());
    let truth = reference(&scene, &LightState::default());
    let mut t = solved(&scene, 4096);
    let big = t
        .render(&FrameRequest::camera(&scene.cameras[0], 4 * W, 4 * H))
        .unwrap();
    let image = big.box_down(4);
    let everything = vec![false; image.pixels.len()];
    let (e, bias) = errors(&image, &truth, &everything);
    eprintln!(
        "{name}, 4096 elements, 4 x 4 samples per pixel: mean error {:.1} %, bias {:+.2} %",
        100.0 * e,
        100.0 * bias
    );
    assert!(bias.abs() < 0.02, "{name}: bias {bias}");
}

/// A moving camera (three views along a short path): with [`DirectLight::ShadowMaps`] every
/// frame evaluates its direct light from the shadow maps (nothing is kept from the view
/// before), and its error against the reference stays within 1.2x of the per-pixel
/// gather's, the still camera's quality, on both Cornell boxes (area light and point light)
/// and the corridor (four point lights between pillars). The window room lit by a sun and
/// a sky is `tests/tests/sky.rs`'s.
#[test]
fn shadow_mapped_direct_on_a_moving_camera_is_within_1_2x_of_the_gather() {
    for name in ["cornell", "cornell-point", "corridor"] {
        let scene = Arc::new(builtin::scene(name).unwrap());
        let mut t = solved(&scene, 1024);
        let c0 = scene.cameras[0].clone();
        let forward = (c0.target - c0.position).normalize();
        let right = forward.cross(c0.up).normalize();
        let step = 0.06 * scene.extent();
        let path: Vec<scene_core::Camera> = [(0.0, 0.0), (1.0, 0.0), (-1.0, 0.7)]
            .iter()
            .map(|&(r, u)| scene_core::Camera {
                position: c0.position + right * (r * step) + c0.up.normalize() * (u * step),
                ..c0.clone()
            })
            .collect();
        for (f, camera) in path.iter().enumerate() {
            let state = LightState::default();
            let truth = reference_at(&scene, camera, &state, 11 + f as u64);
            // The emitter's pixels and their neighbours: a pixel the panel's edge crosses is
            // mostly the panel's glow in the reference and none in either display.
            let centre = emitter_pixels_at(&scene, camera);
            let emitter: Vec<bool> = (0..centre.len())
                .map(|i| {
                    let (x, y) = ((i as u32 % W) as i64, (i as u32 / W) as i64);
                    (-1..=1).any(|dy| {
                        (-1..=1).any(|dx| {
                            let (u, v) = (x + dx, y + dy);
                            (0..W as i64).contains(&u)
                                && (0..H as i64).contains(&v)
                                && centre[(v * W as i64 + u) as usize]
                        })
                    })
                })
                .collect();
            let mut frame = |direct: DirectLight| {
                t.direct = direct;
                let image = t
                    .render(&FrameRequest::from_camera(camera, W, H, &state))
                    .unwrap();
                (errors(&image, &truth, &emitter), t.last_timings().direct)
            };
            let ((gather, gather_bias), gather_time) = frame(DirectLight::default());
            let ((maps, maps_bias), maps_time) = frame(DirectLight::shadow_maps());
            eprintln!(
                "{name} frame {f}: per-pixel gather {:.1} % (bias {:+.1} %, {:.0} ms), shadow maps {:.1} % (bias {:+.1} %, {:.1} ms), ratio {:.2}",
                100.0 * gather,
                100.0 * gather_bias,
                1e3 * gather_time.as_secs_f64(),
                100.0 * maps,
                100.0 * maps_bias,
                1e3 * maps_time.as_secs_f64(),
                maps / gather
            );
            assert!(
                maps <= 1.2 * gather,
                "{name} frame {f}: {maps} against {gather}"
            );
        }
    }
}

/// The per-pixel gather averages each pixel's footprint on its surface's own plane. The
/// Cornell box's red wall is a non-planar quad (the original data) whose second triangle
/// carries the first one's normal, 0.47 degrees off its plane: a footprint on the shading
/// normal's plane sat behind the wall a few footprint widths out, its visibility rays met
/// the wall, and the wall's upper half came out 14-24 % dark at 64 x 64 (issue 49's red
/// deficit). Direct light only, against the reference's direct light (no bounce), over the
/// pixels inside the red wall: each channel's mean within 2 %.
#[test]
fn the_gathered_direct_light_on_a_non_planar_wall_is_the_references() {
    use relight_pr::direct::DirectGather;
    use relight_pr::display::pixel_direct;
    use scene_core::GBufferRenderer;
    let scene = Arc::new(builtin::scene("cornell").unwrap());
    let view = View::from_camera(&scene.cameras[0].with_aspect(W as f32 / H as f32));
    let settings = ReferenceSettings {
        width: W,
        height: H,
        spp: 1024,
        bounces: Bounces::Limited(0),
        seed: 5,
    };
    let truth = render_lit(&scene, &view, &settings, &LightState::default(), None).image;

    let t = solved(&scene, 1024);
    let p = t.prepared().unwrap();
    let gather = DirectGather::new(&p.scene, &p.meshing, &p.solution.sources, 4);
    let mut renderer = RayCastRenderer::new();
    renderer
        .prepare(Arc::new(p.meshing.element_scene(&p.scene)))
        .unwrap();
    let g = renderer.render_view(&view, W, H).unwrap();
    let direct = pixel_direct(&gather, &p.rays, &g, &view, 8);
    assert_eq!(p.solution.sources.len(), 1, "one emissive source");

    let red = scene
        .materials
        .iter()
        .position(|m| m.name == "red")
        .unwrap() as u32;
    let is_red = |x: i64, y: i64| {
        let i = (y * W as i64 + x) as usize;
        (0..W as i64).contains(&x)
            && (0..H as i64).contains(&y)
            && !g.is_background(i)
            && p.meshing.elements[g.triangle_id[i] as usize].material == red
    };
    // Inside the wall: a pixel and its eight neighbours on it (the reference's pixel
    // averages its whole area, and a white neighbour's share would swamp the wall's green
    // and blue, 1/10 of white's).
    let on_red: Vec<usize> = (0..g.len())
        .filter(|&i| {
            let (x, y) = ((i % W as usize) as i64, (i / W as usize) as i64);
            (-1..=1).all(|dy| (-1..=1).all(|dx| is_red(x + dx, y + dy)))
        })
        .collect();
    assert!(on_red.len() > 50, "{} red-wall pixels", on_red.len());
    let mean = |f: &dyn Fn(usize) -> glam::Vec3| {
        on_red.iter().map(|&i| f(i).as_dvec3()).sum::<glam::DVec3>() / on_red.len() as f64
    };
    let gathered = mean(&|i| g.albedo[i].truncate() * std::f32::consts::FRAC_1_PI * direct[i]);
    let reference = mean(&|i| truth.pixels[i]);
    let bias = gathered / reference - glam::DVec3::ONE;
    eprintln!(
        "red wall, direct light only, {} pixels: bias {:+.2} / {:+.2} / {:+.2} %",
        on_red.len(),
        100.0 * bias.x,
        100.0 * bias.y,
        100.0 * bias.z
    );
    assert!(bias.abs().max_element() < 0.02, "bias {bias}");
}
