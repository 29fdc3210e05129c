//! Dynamic scenes (the paper's section 2.4): a moving light blended from the patch transfer
//! solution equals a full re-solve with the light at its new place; dynamic objects shadow
//! the direct light exactly as the same objects in the static scene would, and change no
//! indirect light of the static lights; the transfer's memory is budgeted before it is
//! allocated.

mod common;
use common::max_relative;
use glam::Vec3;
use relight_pr::dynamic::{DynamicScene, Transfer, transfer_bytes};
use relight_pr::{MeshSettings, Meshing, RelightError, SolverSettings, Strategy, solve};

/// One value per mesh element: these tests compare the section 2.4 machinery (which works
/// on the mesh elements) with a re-solve element by element.
fn per_element(target: usize) -> MeshSettings {
    MeshSettings {
        hold_budget: false,
        ..MeshSettings::elements(target)
    }
}
use scene_core::lights::LightState;
use scene_core::ray::RayScene;
use scene_core::{Scene, builtin};

/// A built-in scene meshed at 256 elements and solved tight, for the object tests.
fn solved(name: &str) -> (Scene, Meshing, RayScene, relight_pr::Solution) {
    let scene = builtin::scene(name).unwrap();
    let meshing = Meshing::new(&scene, &per_element(256), 1).unwrap();
    let rays = RayScene::build(&scene);
    let solution = solve(&scene, &meshing, &rays, &tight(), &mut |_| {}).unwrap();
    (scene, meshing, rays, solution)
}

fn tight() -> SolverSettings {
    SolverSettings {
        max_unshot: 1e-5,
        ambient: false,
        visibility_samples: 8,
        // Every patch shot alone: a cluster shot's small-disk approximation depends on
        // which members still hold energy, so a transfer and a re-solve (shots in
        // another order) would agree only to about 2e-3.
        cluster_members: 0,
        ..Default::default()
    }
}

/// A closed cube of half size `h` centred at `c` (outward faces), as triangles.
fn cube(c: Vec3, h: f32) -> Vec<[Vec3; 3]> {
    let mut mesh = scene_core::Mesh::default();
    mesh.push_box(c, Vec3::splat(h), 0.0, 0);
    mesh.indices
        .iter()
        .map(|t| t.map(|i| mesh.positions[i as usize]))
        .collect()
}

#[test]
fn a_moving_light_blended_from_the_transfer_equals_a_re_solve() {
    let lit = builtin::scene("cornell-point").unwrap();
    let mut dark = lit.clone();
    let light = dark.point_lights.remove(0);
    let meshing = Meshing::new(&dark, &per_element(256), 1).unwrap();
    let rays = RayScene::build(&dark);
    let transfer =
        Transfer::solve(&dark, &meshing, &rays, &tight(), u64::MAX, &mut |_| {}).expect("transfer");
    println!(
        "transfer: {} patches x {} elements, {} shots, {:.2} s, {} bytes",
        transfer.patches(),
        meshing.elements.len(),
        transfer.stats.shots,
        transfer.stats.time.as_secs_f64(),
        transfer.bytes()
    );
    assert_eq!(transfer.patches(), meshing.patches.len());
    assert_eq!(
        transfer.bytes(),
        (meshing.elements.len() * meshing.patches.len() * 12) as u64
    );
    let static_solution = solve(&dark, &meshing, &rays, &tight(), &mut |_| {}).unwrap();
    let mut dynamic = DynamicScene::with_transfer(transfer);
    let b = lit.bounds();
    let size = b.max - b.min;
    // Three places: the scene's own, lower and to the side, 2 % of the box from a wall.
    for offset in [
        Vec3::ZERO,
        Vec3::new(0.2, -0.3, 0.1) * size,
        Vec3::new(
            b.min.x + 0.02 * size.x - light.position.x,
            -0.2 * size.y,
            0.0,
        ),
    ] {
        let mut moved = light.clone();
        moved.position += offset;
        dynamic.moving = vec![moved.clone()];
        let frame = dynamic
            .frame(
                &dark,
                &meshing,
                &static_solution,
                &rays,
                &LightState::default(),
            )
            .unwrap();
        let mut scene = dark.clone();
        scene.point_lights.push(moved);
        let settings = SolverSettings {
            strategy: Strategy::Combined,
            ..tight()
        };
        let resolved = solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap();
        // The same first shot: exactly the re-solve's direct light.
        assert_eq!(frame.direct, resolved.direct, "offset {offset}");
        let rel = max_relative(&frame.indirect, &resolved.indirect);
        println!(
            "offset {offset}: indirect within {rel:.2e} of the peak; frame {:?}",
            frame.timings
        );
        assert!(
            rel < 2e-4,
            "indirect differs by {rel} of the peak at {offset}"
        );
        assert!(frame.indirect.iter().any(|v| v.max_element() > 0.0));
    }
}

#[test]
fn dynamic_objects_shadow_the_direct_light_only() {
    let (scene, meshing, rays, solution) = solved("cornell-point");
    // Objects only: no transfer, no moving lights.
    let mut dynamic = DynamicScene::new();
    let state = LightState::default();
    let plain = dynamic
        .frame(&scene, &meshing, &solution, &rays, &state)
        .unwrap();
    // A box under the light, a quarter of the way down.
    let b = scene.bounds();
    let (lo, hi) = (b.min, b.max);
    let centre = (lo + hi) * 0.5;
    let h = 0.08 * scene.extent();
    let object = cube(Vec3::new(centre.x, hi.y - 0.3 * (hi.y - lo.y), centre.z), h);
    dynamic.set_objects(&object);
    let shadowed = dynamic
        .frame(&scene, &meshing, &solution, &rays, &state)
        .unwrap();
    // The static lights' indirect light does not change; the direct light equals the direct
    // light of the same object inserted into the static scene.
    assert_eq!(shadowed.indirect, plain.indirect);
    let mut with_object = scene.clone();
    let mut mesh = scene_core::Mesh::default();
    for t in &object {
        mesh.push_triangle(*t, 0);
    }
    with_object.meshes.push(mesh);
    let rays_with = RayScene::build(&with_object);
    let expected: Vec<Vec3> = meshing
        .elements
        .iter()
        .map(|e| relight_pr::direct::element_from_point(&scene.point_lights[0], &rays_with, e))
        .collect();
    let rel = max_relative(&shadowed.direct, &expected);
    assert!(rel < 1e-6, "direct differs by {rel} of the peak");
    let darker = shadowed
        .direct
        .iter()
        .zip(&plain.direct)
        .filter(|(s, p)| s.max_element() < 0.5 * p.max_element())
        .count();
    assert!(darker >= 4, "the object's shadow covers {darker} elements");
    assert!(
        shadowed
            .direct
            .iter()
            .zip(&plain.direct)
            .all(|(s, p)| s.cmple(*p).all())
    );
    // Far outside the box, it shadows nothing.
    dynamic.set_objects(&cube(hi + Vec3::splat(10.0 * scene.extent()), h));
    let far = dynamic
        .frame(&scene, &meshing, &solution, &rays, &state)
        .unwrap();
    assert_eq!(far.direct, plain.direct);
    assert_eq!(far.radiance, plain.radiance);
}

#[test]
fn dynamic_objects_shadow_an_area_light() {
    let (scene, meshing, rays, solution) = solved("cornell");
    let mut dynamic = DynamicScene::new();
    let state = LightState::default();
    let plain = dynamic
        .frame(&scene, &meshing, &solution, &rays, &state)
        .unwrap();
    assert_eq!(plain.direct.len(), meshing.elements.len());
    let b = scene.bounds();
    let (lo, hi) = (b.min, b.max);
    let centre = (lo + hi) * 0.5;
    // A slab right under the area light: the floor below loses most of its direct light.
    let s = 0.25 * (hi.x - lo.x);
    let y = hi.y - 0.1 * (hi.y - lo.y);
    let mut slab = Vec::new();
    let q = [
        Vec3::new(centre.x - s, y, centre.z - s),
        Vec3::new(centre.x + s, y, centre.z - s),
        Vec3::new(centre.x + s, y, centre.z + s),
        Vec3::new(centre.x - s, y, centre.z + s),
    ];
    slab.push([q[0], q[1], q[2]]);
    slab.push([q[0], q[2], q[3]]);
    dynamic.set_objects(&slab);
    let shadowed = dynamic
        .frame(&scene, &meshing, &solution, &rays, &state)
        .unwrap();
    assert_eq!(shadowed.indirect, plain.indirect);
    // Floor elements under the slab's middle.
    let under: Vec<usize> = (0..meshing.elements.len())
        .filter(|&j| {
            let e = &meshing.elements[j];
            e.normal.y > 0.9
                && e.centroid.y < lo.y + 0.05 * (hi.y - lo.y)
                && (e.centroid.x - centre.x).abs() < s
                && (e.centroid.z - centre.z).abs() < s
                && plain.direct[j].max_element() > 0.0
        })
        .collect();
    println!("{} floor elements under the slab", under.len());
    assert!(
        under.len() >= 2,
        "{} floor elements under the slab",
        under.len()
    );
    for &j in &under {
        let (a, b) = (
            shadowed.direct[j].max_element(),
            plain.direct[j].max_element(),
        );
        assert!(a < 0.2 * b, "element {j} keeps {a} of {b}");
    }
    // Nothing gains light; the ceiling (above the slab) keeps its own.
    assert!(
        shadowed
            .direct
            .iter()
            .zip(&plain.direct)
            .all(|(s, p)| s.cmple(*p).all())
    );
    dynamic.set_objects(&[]);
    let cleared = dynamic
        .frame(&scene, &meshing, &solution, &rays, &state)
        .unwrap();
    assert_eq!(cleared.direct, plain.direct);
    assert_eq!(cleared.radiance, plain.radiance);
    // Moving lights need a transfer.
    dynamic.moving.push(scene_core::PointLight {
        name: "moving".into(),
        position: centre,
        intensity: Vec3::ONE,
        radius: None,
        cone: None,
    });
    assert!(matches!(
        dynamic.frame(&scene, &meshing, &solution, &rays, &state),
        Err(RelightError::InvalidSetting(_))
    ));
}

#[test]
fn the_transfer_budget_is_checked_before_allocating() {
    let scene = builtin::scene("cornell").unwrap();
    let meshing = Meshing::new(&scene, &MeshSettings::elements(1024), 1).unwrap();
    let rays = RayScene::build(&scene);
    let need = transfer_bytes(meshing.elements.len(), meshing.patches.len());
    let err =
        Transfer::solve(&scene, &meshing, &rays, &tight(), need - 1, &mut |_| {}).unwrap_err();
    match err {
        RelightError::Budget(b) => assert_eq!(b.needed, need, "{b}"),
        other => panic!("expected a budget error, got {other}"),
    }
}
