//! Camera importance (`WalkSettings::camera_importance`): on a room lit by a sun through
//! its window and standing on a wide ground, most particles light the ground outside,
//! which the camera inside never sees. Keeping those IRPLs one in eight (eight times as
//! strong) leaves the instant-radiosity estimate's expectation where it was and spends the
//! budget inside: its spread over seeds falls. And on the same room the walks carry each
//! bounce's light to the camera's points as the reference path tracer does.

use glam::Vec3;
use ibrr_ldc::irpl::{CameraImportance, IrplKind, WalkSettings, generate};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::lights::LightState;
use scene_core::ray::RayScene;
use scene_core::reference::{Accumulator, Bounces, PathTracer};
use scene_core::{Camera, DirectionalLight, GBufferRenderer, Material, Mesh, Scene, View};

/// A 2 m room with a 1 x 0.8 m window in its +z wall on a 12 m ground, a sun travelling
/// through the window and down, a camera inside looking away from the window.
fn room_on_a_ground() -> Scene {
    let mut s = Scene::new("room on a ground");
    s.materials
        .push(Material::diffuse("ground", Vec3::splat(0.5)));
    s.materials
        .push(Material::diffuse("wall", Vec3::new(0.75, 0.7, 0.6)));
    let p = Vec3::new;
    let mut m = Mesh {
        name: "ground and room".into(),
        ..Default::default()
    };
    // The ground 10 cm below the room's floor, so that no plane runs under a wall.
    let g = -0.1;
    m.push_quad(
        [
            p(-6.0, g, -6.0),
            p(-6.0, g, 6.0),
            p(6.0, g, 6.0),
            p(6.0, g, -6.0),
        ],
        0,
    );
    m.push_quad(
        [
            p(-1.0, 0.0, -1.0),
            p(-1.0, 0.0, 1.0),
            p(1.0, 0.0, 1.0),
            p(1.0, 0.0, -1.0),
        ],
        1,
    );
    // Ceiling, the walls at -x, +x and -z, and the +z wall around its window, down to the
    // ground.
    m.push_quad(
        [
            p(-1.0, 2.0, -1.0),
            p(1.0, 2.0, -1.0),
            p(1.0, 2.0, 1.0),
            p(-1.0, 2.0, 1.0),
        ],
        1,
    );
    m.push_quad(
        [
            p(-1.0, g, -1.0),
            p(-1.0, 2.0, -1.0),
            p(-1.0, 2.0, 1.0),
            p(-1.0, g, 1.0),
        ],
        1,
    );
    m.push_quad(
        [
            p(1.0, g, -1.0),
            p(1.0, g, 1.0),
            p(1.0, 2.0, 1.0),
            p(1.0, 2.0, -1.0),
        ],
        1,
    );
    m.push_quad(
        [
            p(-1.0, g, -1.0),
            p(1.0, g, -1.0),
            p(1.0, 2.0, -1.0),
            p(-1.0, 2.0, -1.0),
        ],
        1,
    );
    let (x0, x1, y0, y1) = (-0.5, 0.5, 0.8, 1.6);
    for (a, b, c, d) in [
        (-1.0, 1.0, g, y0),
        (-1.0, 1.0, y1, 2.0),
        (-1.0, x0, y0, y1),
        (x1, 1.0, y0, y1),
    ] {
        m.push_quad([p(a, c, 1.0), p(b, c, 1.0), p(b, d, 1.0), p(a, d, 1.0)], 1);
    }
    s.meshes.push(m);
    s.directional_lights.push(DirectionalLight {
        name: "sun".into(),
        direction: Vec3::new(0.1, -0.6, -1.0).normalize(),
        irradiance: Vec3::splat(4.0),
    });
    s.cameras.push(Camera {
        name: "inside".into(),
        position: p(0.0, 1.3, 0.8),
        target: p(0.0, 0.4, -0.9),
        up: Vec3::Y,
        fov_y: 70f32.to_radians(),
        aspect: 1.0,
        near: 0.01,
        far: 20.0,
    });
    s.validate().unwrap();
    s
}

/// Mean and standard deviation over `seeds` of the IRPLs' light (clamped at 0.3 m, as the
/// LDC's default clamp does) at the surface points the camera sees, and the mean number of
/// path IRPLs.
fn over_seeds(
    scene: &Scene,
    rays: &RayScene,
    points: &[(Vec3, Vec3)],
    importance: bool,
    entry: bool,
    seeds: u64,
) -> (f64, f64, f64) {
    let r = 0.3f32;
    let g_max = std::f32::consts::FRAC_1_PI / (r * r);
    let mut count = 0.0;
    let levels: Vec<f64> = (1..=seeds)
        .map(|seed| {
            let set = generate(
                scene,
                rays,
                &LightState::default(),
                &WalkSettings {
                    irpls: 64,
                    seed,
                    max_depth: 32,
                    paths: 0,
                    camera_importance: importance,
                    entry_importance: entry,
                },
            );
            let mut sum = 0.0f64;
            for irpl in set.irpls.iter().filter(|i| i.kind == IrplKind::Bounce) {
                count += 1.0;
                for &(y, ny) in points {
                    let d = y - irpl.position;
                    let len = d.length();
                    if len > 0.0 && !rays.occluded(irpl.position, d / len, 0.0, len * 0.9999) {
                        sum += f64::from(irpl.irradiance_clamped(y, ny, g_max).y);
                    }
                }
            }
            sum / set.paths as f64 / points.len() as f64
        })
        .collect();
    let n = levels.len() as f64;
    let mean = levels.iter().sum::<f64>() / n;
    let var = levels.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt(), count / n)
}

/// The camera's points and points no camera sees (the ground outside, lit by the IRPLs
/// an importance makes fewer and stronger there), on the window room.
fn camera_and_outside_points(
    scene: &Scene,
    rays: &RayScene,
) -> [(&'static str, Vec<(Vec3, Vec3)>); 2] {
    let seen = CameraImportance::of(scene, rays).points;
    assert!(seen.len() > 500, "{} camera points", seen.len());
    let outside: Vec<(Vec3, Vec3)> = (0..400)
        .map(|k| {
            let (x, z) = ((k % 20) as f32 * 0.5 - 4.75, (k / 20) as f32 * 0.5 - 4.75);
            (Vec3::new(x, -0.1, z), Vec3::Y)
        })
        .filter(|(p, _)| p.x.abs() > 1.2 || p.z.abs() > 1.2)
        .collect();
    [
        ("the camera's points", seen),
        ("the ground outside", outside),
    ]
}

/// Over 96 seeds at each point set, the IRPLs' light with uniform walks against walks with
/// `camera` and `entry` importance: the two means agree within three standard errors of
/// their difference (unbiased), the IRPL counts within 25 %, and at the camera's points
/// the importance's spread is below `spread` times the uniform walks'.
fn importance_keeps_the_mean_and_lowers_the_spread(camera: bool, entry: bool, spread: f64) {
    let scene = room_on_a_ground();
    let rays = RayScene::build(&scene);
    const SEEDS: u64 = 96;
    for (name, points) in camera_and_outside_points(&scene, &rays) {
        let (plain, plain_sd, plain_n) = over_seeds(&scene, &rays, &points, false, false, SEEDS);
        let (imp, imp_sd, imp_n) = over_seeds(&scene, &rays, &points, camera, entry, SEEDS);
        println!(
            "indirect light at {name} over {SEEDS} seeds (about 64 IRPLs): uniform walks {plain:.5} (sd {plain_sd:.5}, {plain_n:.0} IRPLs), camera importance {camera}, entry importance {entry}: {imp:.5} (sd {imp_sd:.5}, {imp_n:.0} IRPLs)"
        );
        let se = ((plain_sd.powi(2) + imp_sd.powi(2)) / SEEDS as f64).sqrt();
        assert!(
            (imp - plain).abs() < 3.0 * se,
            "{name}: {imp} against {plain} (se {se})"
        );
        assert!(
            (imp_n / plain_n - 1.0).abs() < 0.25,
            "{imp_n} IRPLs against {plain_n}"
        );
        if name.starts_with("the camera") {
            assert!(imp_sd < spread * plain_sd, "sd {imp_sd} against {plain_sd}");
        }
    }
}

#[test]
fn camera_importance_keeps_the_estimate_and_lowers_its_spread_over_seeds() {
    // IRPLs no camera point sees kept one in eight at eight times their power.
    importance_keeps_the_mean_and_lowers_the_spread(true, false, 0.75);
}

/// Entry importance (`WalkSettings::entry_importance`): the sun's particles start where
/// its light enters what the camera sees (the window, found by pilot rays), the rest fewer
/// and stronger; where the camera looks the spread falls below half the uniform starts'.
#[test]
fn entry_importance_keeps_the_estimate_and_lowers_its_spread_over_seeds() {
    importance_keeps_the_mean_and_lowers_the_spread(false, true, 0.5);
}

/// The particle walks carry the right light at every depth on the window room, where a
/// build's image once read 58 % too bright on its second bounce (one seed's noise,
/// docs/ibrr-ldc.md): at the camera's pixels, the IRPLs of each depth (summed with
/// ray-cast visibility, no clamp, shaded `rho / pi`) against the reference's increment per
/// bounce limit (4096 spp at 24 x 24), each within three standard errors of the mean over
/// 64 seeds plus the reference's own (half the difference of its two 2048-spp halves,
/// doubled). A walk that forgot to divide by its survival probability reads depth 2 about
/// 25 % and depth 3 about 44 % dark (the walls' largest albedo channel is 0.75) and fails.
#[test]
fn the_walks_carry_each_bounce_of_the_window_rooms_light() {
    let scene = room_on_a_ground();
    let rays = RayScene::build(&scene);
    let (w, h) = (24u32, 24u32);
    let view = View::from_camera(&scene.cameras[0]);
    let tracer = PathTracer::new(&scene);
    // The reference's image mean (green) at bounce limits 0 to 3, in two halves.
    let halves: Vec<[f64; 2]> = (0..=3u32)
        .map(|b| {
            [11u64, 12].map(|seed| {
                let mut acc = Accumulator::new(w, h);
                acc.add_pass(&tracer, &view, Bounces::Limited(b), seed, 2048, None);
                let img = acc.image();
                img.pixels.iter().map(|p| f64::from(p.y)).sum::<f64>() / img.pixels.len() as f64
            })
        })
        .collect();
    let g = RayCastRenderer::new().render(&scene, &view, w, h).unwrap();
    let lift = scene.extent() * 1e-4;
    let points: Vec<(Vec3, Vec3, f32)> = (0..g.len())
        .filter(|&i| !g.is_background(i))
        .map(|i| {
            let uv = glam::Vec2::new(
                ((i as u32 % w) as f32 + 0.5) / w as f32,
                ((i as u32 / w) as f32 + 0.5) / h as f32,
            );
            (
                view.reconstruct_world(uv, g.depth[i]),
                g.normal[i],
                g.albedo[i].y,
            )
        })
        .collect();
    const SEEDS: u64 = 64;
    let per_seed: Vec<[f64; 3]> = (1..=SEEDS)
        .map(|seed| {
            let set = generate(
                &scene,
                &rays,
                &LightState::default(),
                &WalkSettings {
                    irpls: 512,
                    seed,
                    max_depth: 3,
                    paths: 0,
                    camera_importance: false,
                    entry_importance: false,
                },
            );
            let mut sums = [0.0f64; 3];
            for irpl in set.irpls.iter().filter(|i| i.kind == IrplKind::Bounce) {
                for &(y, ny, rho) in &points {
                    let d = y + ny * lift - irpl.position;
                    let len = d.length();
                    if len > 0.0 && !rays.occluded(irpl.position, d / len, 0.0, len * 0.9999) {
                        sums[irpl.depth as usize - 1] +=
                            f64::from(irpl.irradiance_at(y, ny).y * rho / std::f32::consts::PI);
                    }
                }
            }
            sums.map(|s| s / set.paths as f64 / f64::from(w * h))
        })
        .collect();
    for depth in 1..=3usize {
        let full = |b: usize| 0.5 * (halves[b][0] + halves[b][1]);
        let reference = full(depth) - full(depth - 1);
        // The increment's standard error from the halves' spread (two images per limit).
        let ref_se = (0..2)
            .map(|k| 0.5 * (halves[depth - k][0] - halves[depth - k][1]).abs())
            .map(|x| x * x)
            .sum::<f64>()
            .sqrt();
        let values: Vec<f64> = per_seed.iter().map(|v| v[depth - 1]).collect();
        let mean = values.iter().sum::<f64>() / SEEDS as f64;
        let sd =
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (SEEDS - 1) as f64).sqrt();
        let se = sd / (SEEDS as f64).sqrt();
        println!(
            "depth {depth}: IRPLs {mean:.5} (se {se:.5}, sd per seed {sd:.5}) against the reference's increment {reference:.5} (se {ref_se:.5})"
        );
        assert!(reference > 0.0);
        assert!(
            (mean - reference).abs() < 3.0 * (se + ref_se),
            "depth {depth}: {mean} against {reference}"
        );
    }
}
