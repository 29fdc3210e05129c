//! Camera importance (`WalkSettings::camera_importance`): on a room lit by a sun through
//! its window and standing on a wide ground, most particles light the ground outside,
//! which the camera inside never sees. Keeping those IRPLs one in eight (eight times as
//! strong) leaves the instant-radiosity estimate's expectation where it was and spends the
//! budget inside: its spread over seeds falls.

use glam::Vec3;
use ibrr_ldc::irpl::{CameraImportance, IrplKind, WalkSettings, generate};
use scene_core::lights::LightState;
use scene_core::ray::RayScene;
use scene_core::{Camera, DirectionalLight, Material, Mesh, Scene};

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

#[test]
fn camera_importance_keeps_the_estimate_and_lowers_its_spread_over_seeds() {
    let scene = room_on_a_ground();
    let rays = RayScene::build(&scene);
    const SEEDS: u64 = 24;
    let seen = CameraImportance::of(&scene, &rays).points;
    assert!(seen.len() > 500, "{} camera points", seen.len());
    // Points no camera sees: the ground outside, lit by the IRPLs that importance keeps
    // one in eight at eight times their power.
    let outside: Vec<(Vec3, Vec3)> = (0..400)
        .map(|k| {
            let (x, z) = ((k % 20) as f32 * 0.5 - 4.75, (k / 20) as f32 * 0.5 - 4.75);
            (Vec3::new(x, -0.1, z), Vec3::Y)
        })
        .filter(|(p, _)| p.x.abs() > 1.2 || p.z.abs() > 1.2)
        .collect();
    for (name, points) in [
        ("the camera's points", &seen),
        ("the ground outside", &outside),
    ] {
        let (plain, plain_sd, plain_n) = over_seeds(&scene, &rays, points, false, SEEDS);
        let (imp, imp_sd, imp_n) = over_seeds(&scene, &rays, points, true, SEEDS);
        println!(
            "indirect light at {name} over {SEEDS} seeds (about 64 IRPLs): every surface alike {plain:.5} (sd {plain_sd:.5}, {plain_n:.0} IRPLs), camera importance {imp:.5} (sd {imp_sd:.5}, {imp_n:.0} IRPLs)"
        );
        // Unbiased: the two means agree within three standard errors of their difference.
        let se = ((plain_sd.powi(2) + imp_sd.powi(2)) / SEEDS as f64).sqrt();
        assert!(
            (imp - plain).abs() < 3.0 * se,
            "{name}: {imp} against {plain} (se {se})"
        );
        assert!(
            (imp_n / plain_n - 1.0).abs() < 0.25,
            "{imp_n} IRPLs against {plain_n}"
        );
        // Where the camera looks, the budget spent inside: a smaller spread.
        if name.starts_with("the camera") {
            assert!(imp_sd < 0.75 * plain_sd, "sd {imp_sd} against {plain_sd}");
        }
    }
}
