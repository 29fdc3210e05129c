//! The uniform and storage layouts written from Rust agree with the structs the shaders
//! declare: naga (the WGSL front end wgpu itself uses) lays out each WGSL struct of the
//! module scene-core's composer builds, and every member's offset and the size must equal
//! the `#[repr(C)]` Rust struct's (`scene_core::check_layout!`).

use isr::GpuLightSender;
use isr::gpu::{Globals, GpuLight};
use isr::passes::{LIGHT_SENDERS, LIGHTING, SHADER_PASSES};
use scene_core::check_layout;

#[test]
fn globals_match_common_wgsl() {
    // Every pass imports isr::common: each composed module carries the same Globals.
    for pass in SHADER_PASSES {
        let module = pass.compose().unwrap();
        // Rust keeps the five view rows in one array (Screen::uniform); WGSL names them.
        check_layout!(
            &module,
            "Globals",
            Globals {
                eye_far: view,
                corner_ortho: view + 16,
                du_span: view + 32,
                dv_span: view + 48,
                forward_extent: view + 64,
                sizes,
                config,
                k,
                filters,
                shadow,
                frustum,
                view_proj,
                senders,
                sender_phases,
            }
        )
        .unwrap_or_else(|e| panic!("{}: {e}", pass.name));
    }
}

#[test]
fn light_senders_match_light_senders_wgsl() {
    let module = LIGHT_SENDERS.compose().unwrap();
    check_layout!(
        &module,
        "LightSender",
        GpuLightSender {
            position_area,
            normal_light,
            power,
            tangent,
        }
    )
    .unwrap();
}

#[test]
fn lights_match_light_set_wgsl() {
    let module = LIGHTING.compose().unwrap();
    check_layout!(
        &module,
        "Light",
        GpuLight {
            position,
            kind,
            color,
            radius,
            direction,
            area,
            right,
            half_extent,
            up,
            map_res,
            eye,
            map_offset,
            forward,
            map_kind,
            direct,
            spot_scale,
            indirect,
            spot_offset,
        }
    )
    .unwrap();
}
