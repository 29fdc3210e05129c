//! The sky's particles (`irpl::generate`): a sky is shaded as its median-cut directions
//! where a method needs fixed directions (the IBRR's exact sources of direct light), but
//! its particles must carry the sky as it is. Through an opening, light from a few fixed
//! directions lands in a few displaced copies of the opening, and the first bounce they
//! found (and every bounce after it) sits in the wrong place whatever the IRPL count: a
//! bias no seed averages away. On the Breakfast Room (a window and a uniform sky of 64
//! directions) that structure was one part of the sky's error (docs/ibrr-ldc.md).

use glam::{DVec3, Vec3};
use ibrr_ldc::irpl::{IrplKind, WalkSettings, generate};
use scene_core::lights::LightState;
use scene_core::ray::RayScene;
use scene_core::sky::Sky;
use scene_core::{Material, Mesh, Scene};

/// Half the side of the floor and of the roof.
const HALF: f32 = 5.0;
/// Height of the roof above the floor.
const ROOF: f32 = 1.0;
/// Half the side of the square hole in the roof's middle.
const HOLE: f32 = 0.5;
const ALBEDO: f32 = 0.5;
const SKY: f32 = 0.8;

/// A floor under a roof with a square hole in its middle, under a uniform sky of
/// `directions` directions.
fn skylight(directions: u32) -> Scene {
    let mut s = Scene::new("skylight");
    s.materials
        .push(Material::diffuse("grey", Vec3::splat(ALBEDO)));
    let p = Vec3::new;
    let mut m = Mesh {
        name: "floor and roof".into(),
        ..Default::default()
    };
    let (h, r) = (HALF, HOLE);
    m.push_quad_facing(
        [p(-h, 0.0, -h), p(h, 0.0, -h), p(h, 0.0, h), p(-h, 0.0, h)],
        0,
        p(0.0, 1.0, 0.0),
    );
    // The roof as four quads around the hole.
    for [x0, z0, x1, z1] in [
        [-h, -h, h, -r],
        [-h, r, h, h],
        [-h, -r, -r, r],
        [r, -r, h, r],
    ] {
        m.push_quad_facing(
            [
                p(x0, ROOF, z0),
                p(x1, ROOF, z0),
                p(x1, ROOF, z1),
                p(x0, ROOF, z1),
            ],
            0,
            p(0.0, 0.0, 0.0),
        );
    }
    s.meshes.push(m);
    s.sky = Some(
        Sky::uniform(Vec3::splat(SKY))
            .unwrap()
            .with_directions(directions)
            .unwrap(),
    );
    s.validate().unwrap();
    s
}

/// The sky's power landing on the floor under the hole (`|x|, |z| <= HOLE`), by the
/// definition and nothing of the toolkit: `L * pi * (the cosine-weighted share of
/// directions that pass the roof)` integrated over the square, by a stratified sum.
fn power_under_the_hole() -> f64 {
    const N: u32 = 48; // positions per side
    const D: u32 = 48; // directions per side (cosine-weighted, stratified)
    let r = f64::from(HOLE);
    let mut seen = 0u64;
    for i in 0..N {
        for j in 0..N {
            let x = -r + 2.0 * r * (f64::from(i) + 0.5) / f64::from(N);
            let z = -r + 2.0 * r * (f64::from(j) + 0.5) / f64::from(N);
            for a in 0..D {
                for b in 0..D {
                    // Malley's method: uniform on the unit disk, lifted to the hemisphere.
                    let u = (f64::from(a) + 0.5) / f64::from(D);
                    let v = (f64::from(b) + 0.5) / f64::from(D);
                    let (rad, phi) = (u.sqrt(), std::f64::consts::TAU * v);
                    let w = DVec3::new(rad * phi.cos(), (1.0 - u).max(0.0).sqrt(), rad * phi.sin());
                    let t = f64::from(ROOF) / w.y;
                    let (hx, hz) = (x + w.x * t, z + w.z * t);
                    let half = f64::from(HALF);
                    let through_hole = hx.abs() < r && hz.abs() < r;
                    let past_roof = hx.abs() > half || hz.abs() > half;
                    if through_hole || past_roof {
                        seen += 1;
                    }
                }
            }
        }
    }
    let share = seen as f64 / f64::from(N * N * D * D);
    f64::from(SKY) * std::f64::consts::PI * share * (2.0 * r) * (2.0 * r)
}

/// Mean and standard error over `seeds` of the first bounce's IRPL power under the hole
/// (green), divided by the albedo: the sky's power landing there as the walks carry it.
fn walked_power_under_the_hole(scene: &Scene, seeds: u64) -> (f64, f64) {
    let rays = RayScene::build(scene);
    let values: Vec<f64> = (1..=seeds)
        .map(|seed| {
            let set = generate(
                scene,
                &rays,
                &LightState::default(),
                &WalkSettings {
                    irpls: 0,
                    seed,
                    max_depth: 1,
                    paths: 100_000,
                    camera_importance: false,
                    entry_importance: false,
                },
            );
            let under: f64 = set
                .irpls
                .iter()
                .filter(|i| i.kind == IrplKind::Bounce && i.depth == 1)
                .filter(|i| {
                    i.position.y < 0.5 * ROOF
                        && i.position.x.abs() < HOLE
                        && i.position.z.abs() < HOLE
                })
                .map(|i| f64::from(i.power.y))
                .sum();
            under / set.paths as f64 / f64::from(ALBEDO)
        })
        .collect();
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    (mean, sd / n.sqrt())
}

/// Whatever the sky's count of directions, the particles land under a skylight the power
/// the sky sends there, within three standard errors over 16 seeds. With the particles
/// on the sky's fixed directions (the walks before 2026-11-27) the light passing the hole
/// landed in displaced copies of it: none under the hole with 4 directions, +5.7 % (seven
/// standard errors) with the default 64.
#[test]
fn the_skys_particles_land_where_the_sky_shines_through_an_opening() {
    let truth = power_under_the_hole();
    assert!(truth > 0.0);
    for directions in [4, 64] {
        let scene = skylight(directions);
        let (mean, se) = walked_power_under_the_hole(&scene, 16);
        println!(
            "{directions} directions: walked {mean:.5} (se {se:.5}) against {truth:.5} ({:+.2} %)",
            100.0 * (mean / truth - 1.0)
        );
        assert!(se < 0.05 * truth, "too noisy to tell: se {se} of {truth}");
        assert!(
            (mean - truth).abs() < 3.0 * se,
            "{directions} directions: {mean} against {truth}"
        );
    }
}
