//! The image-based radiosity representation as an engine plug-in: the engine's own device,
//! camera matrices and compact G-buffer, the light recoloured every frame without
//! rebuilding the layered depth cube, through the one frame contract
//! (`scene_core::gpu::GpuFrame`).
//!
//! The engine's device, reverse-Z camera, compact G-buffer without ids and frame loop are
//! scene-core's `ExampleHost`, shared by every method's example. Particular to the IBRR:
//! once, it builds its LDC for the Cornell box (light kept per source) and is prepared on
//! the engine's device (`IbrrFrame::prepare`); each frame recombines the layers' light for
//! the frame's colour of the ceiling panel on the CPU, copies the relit values in and
//! reconstructs into the engine's target. Without ids the panel's own pixels do not glow
//! (docs/engine.md). The last line counts the GPU objects a steady-state frame created:
//! all zero.
//!
//! Run with `cargo run --release -p ibrr-ldc --example ibrr_engine`.

use std::sync::Arc;

use ibrr_ldc::{IbrrFrame, IbrrSettings, IbrrTechnique};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::lights::{LightId, light_ids};
use scene_core::testing::{ExampleError, ExampleHost};
use scene_core::{Technique, builtin};

const SIZE: (u32, u32) = (160, 120);

fn main() -> Result<(), ExampleError> {
    let ctx = ExampleHost::engine_context()?;

    // Once: the LDC, its light kept per source, prepared on the engine's device.
    let scene = Arc::new(builtin::scene("cornell")?);
    let settings = IbrrSettings {
        resolution: 96,
        irpls: 48,
        ..Default::default()
    };
    let mut ibrr = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
    ibrr.prepare(scene.clone())?;
    let layers = ibrr.ldc().ok_or("the LDC was not built")?.layer_count();
    println!("LDC: {layers} layers");
    let mut method = IbrrFrame::prepare(&ctx, ibrr)?;

    // The engine: the scene's camera as its matrices, its G-buffer of the same room.
    let cam = &scene.cameras[0];
    let matrices = ExampleHost::engine_matrices(cam.position, cam.target, cam.fov_y, SIZE);
    let mut host = ExampleHost::new(ctx, matrices, SIZE, ExampleHost::ray_cast(&scene, SIZE))?;

    let panel = *light_ids(&scene)
        .iter()
        .find(|i| matches!(i, LightId::Emissive(_)))
        .ok_or("the scene has no emissive panel")?;
    host.run_light_cycle(&mut method, panel)?;
    Ok(())
}
