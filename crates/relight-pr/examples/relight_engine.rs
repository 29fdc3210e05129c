//! Radiosity relighting as an engine plug-in: the engine's own device, camera matrices and
//! geometry, the light recoloured every frame at the cost of a few factors, through the
//! one frame contract (`scene_core::gpu::GpuFrame`).
//!
//! The engine's device, reverse-Z camera, compact G-buffer without ids and frame loop are
//! scene-core's `ExampleHost`, shared by every method's example. Particular to relighting:
//! once, the engine's room is meshed and solved with its lamp tagged (`Prepared::solve`)
//! and prepared on the engine's device with the lamp's shadow map; each frame renders the
//! element ids itself, evaluates the direct light from the shadow map over each pixel's
//! footprint and displays eq. 1 per pixel. The last line counts the GPU objects a
//! steady-state frame created: all zero.
//!
//! Run with `cargo run --release -p relight-pr --example relight_engine`.

use std::sync::Arc;

use glam::Vec3;
use relight_pr::packed::Precision;
use relight_pr::{MeshSettings, Prepared, RelightFrame, RelightFrameSettings, SolverSettings};
use scene_core::lights::LightId;
use scene_core::shadowed_lights::{LightSet, ShadowSettings};
use scene_core::testing::{ExampleError, ExampleHost};
use scene_core::{Material, Mesh, PointLight, Scene};

const SIZE: (u32, u32) = (160, 120);

/// The engine's room: 4 x 3 x 4 m, walls facing in (the left one red, the right one green),
/// a 1 m block on the floor, a lamp under the ceiling.
fn engine_room() -> Result<Scene, ExampleError> {
    let c = Vec3::new;
    let mut room = Mesh {
        name: "room".into(),
        ..Default::default()
    };
    let floor = [(-2., -2.), (2., -2.), (2., 2.), (-2., 2.)].map(|(x, z)| c(x, 0., z));
    let ceiling = floor.map(|p| p + Vec3::Y * 3.0);
    let wall = |a: Vec3, b: Vec3| [a, b, b + Vec3::Y * 3.0, a + Vec3::Y * 3.0];
    for (quad, material) in [
        (floor, 0),
        (ceiling, 0),
        (wall(floor[0], floor[1]), 0),
        (wall(floor[3], floor[2]), 0),
        (wall(floor[0], floor[3]), 1),
        (wall(floor[1], floor[2]), 2),
    ] {
        room.push_quad_facing(quad, material, c(0.0, 1.5, 0.0));
    }
    room.push_box(c(-0.3, 0.5, -0.4), Vec3::splat(0.5), 0.0, 0);
    let mut scene = Scene::new("engine room");
    scene.meshes.push(room);
    scene.materials = vec![
        Material::diffuse("white", Vec3::splat(0.7)),
        Material::diffuse("red", c(0.7, 0.15, 0.1)),
        Material::diffuse("green", c(0.15, 0.6, 0.15)),
    ];
    let lamp = PointLight::new("lamp", c(0.8, 2.6, 0.8), Vec3::splat(8.0));
    scene.point_lights.push(lamp);
    scene.validate()?;
    Ok(scene)
}

fn main() -> Result<(), ExampleError> {
    let ctx = ExampleHost::engine_context()?;

    // Once: the room meshed and solved with the lamp tagged, the lamp's shadow map, and the
    // solution prepared on the engine's device.
    let scene = Arc::new(engine_room()?);
    let (mesh, solver) = (MeshSettings::elements(600), SolverSettings::default());
    let prepared = Prepared::solve(scene.clone(), &mesh, &solver, &mut |_| {})?;
    let lights = LightSet::new(&scene, &ShadowSettings::default())?;
    let settings = RelightFrameSettings {
        precision: Precision::F16,
        shadowed_direct: Some((&lights, 3)),
    };
    let mut method = RelightFrame::prepare(&ctx, &prepared, &settings)?;
    println!(
        "solved: {} elements, {} light source(s), {} KiB on the GPU",
        prepared.meshing.elements.len(),
        prepared.solution.k(),
        method.gpu().bytes() / 1024
    );

    // The engine's camera and its G-buffer of its own triangles.
    let (eye, target) = (Vec3::new(0.0, 1.5, 1.9), Vec3::new(-0.2, 0.9, -1.0));
    let matrices = ExampleHost::engine_matrices(eye, target, 1.2, SIZE);
    let mut host = ExampleHost::new(ctx, matrices, SIZE, ExampleHost::ray_cast(&scene, SIZE))?;
    host.run_light_cycle(&mut method, LightId::Point(0))?;
    Ok(())
}
