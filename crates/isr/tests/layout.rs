//! The uniform and storage layouts written from Rust agree with the structs the shaders
//! declare: naga (the WGSL front end wgpu itself uses) computes each WGSL struct's member
//! offsets and size, and they must equal the `#[repr(C)]` Rust struct's.

use isr::gpu::{Globals, GpuLight};

/// `(member name, offset)` of WGSL struct `name` in `source`, and its size.
fn wgsl_layout(source: &str, name: &str) -> (Vec<(String, u32)>, u32) {
    let module = naga::front::wgsl::parse_str(source).expect("the pass source parses");
    let mut layouter = naga::proc::Layouter::default();
    layouter
        .update(module.to_ctx())
        .expect("naga lays the types out");
    for (handle, ty) in module.types.iter() {
        if ty.name.as_deref() != Some(name) {
            continue;
        }
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("{name} is not a struct");
        };
        assert_eq!(layouter[handle].size, *span);
        let fields = members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
            .collect();
        return (fields, *span);
    }
    panic!("no struct {name} in the source");
}

/// The WGSL members, in order, have the Rust names and offsets.
fn assert_same_members(wgsl: &[(String, u32)], rust: &[(&str, usize)]) {
    assert_eq!(wgsl.len(), rust.len(), "{wgsl:?}");
    for ((wname, woff), (rname, roff)) in wgsl.iter().zip(rust) {
        assert_eq!((wname.as_str(), *woff as usize), (*rname, *roff));
    }
}

#[test]
fn globals_match_common_wgsl() {
    let (fields, size) = wgsl_layout(isr::lighting::WGSL, "Globals");
    assert_eq!(size as usize, std::mem::size_of::<Globals>());
    // Rust keeps the five view rows in one array (Screen::uniform); WGSL names them.
    let rust = [
        ("eye_far", std::mem::offset_of!(Globals, view)),
        ("corner_ortho", std::mem::offset_of!(Globals, view) + 16),
        ("du_span", std::mem::offset_of!(Globals, view) + 32),
        ("dv_span", std::mem::offset_of!(Globals, view) + 48),
        ("forward_extent", std::mem::offset_of!(Globals, view) + 64),
        ("sizes", std::mem::offset_of!(Globals, sizes)),
        ("config", std::mem::offset_of!(Globals, config)),
        ("k", std::mem::offset_of!(Globals, k)),
        ("filters", std::mem::offset_of!(Globals, filters)),
        ("shadow", std::mem::offset_of!(Globals, shadow)),
        ("frustum", std::mem::offset_of!(Globals, frustum)),
    ];
    assert_same_members(&fields, &rust);
}

#[test]
fn lights_match_light_set_wgsl() {
    let (fields, size) = wgsl_layout(isr::lighting::WGSL, "Light");
    assert_eq!(size as usize, std::mem::size_of::<GpuLight>());
    let rust = [
        ("position", std::mem::offset_of!(GpuLight, position)),
        ("kind", std::mem::offset_of!(GpuLight, kind)),
        ("color", std::mem::offset_of!(GpuLight, color)),
        ("radius", std::mem::offset_of!(GpuLight, radius)),
        ("direction", std::mem::offset_of!(GpuLight, direction)),
        ("area", std::mem::offset_of!(GpuLight, area)),
        ("right", std::mem::offset_of!(GpuLight, right)),
        ("half_extent", std::mem::offset_of!(GpuLight, half_extent)),
        ("up", std::mem::offset_of!(GpuLight, up)),
        ("map_res", std::mem::offset_of!(GpuLight, map_res)),
        ("eye", std::mem::offset_of!(GpuLight, eye)),
        ("map_offset", std::mem::offset_of!(GpuLight, map_offset)),
        ("forward", std::mem::offset_of!(GpuLight, forward)),
        ("map_kind", std::mem::offset_of!(GpuLight, map_kind)),
        ("direct", std::mem::offset_of!(GpuLight, direct)),
        ("pad0", std::mem::offset_of!(GpuLight, pad0)),
        ("indirect", std::mem::offset_of!(GpuLight, indirect)),
        ("pad1", std::mem::offset_of!(GpuLight, pad1)),
    ];
    assert_same_members(&fields, &rust);
}

#[test]
fn every_pass_source_compiles_in_naga() {
    for (name, source) in [
        ("lighting", isr::lighting::WGSL),
        ("lighting rgba16f", isr::lighting::WGSL_RGBA16F),
        ("radiosity", isr::radiosity::WGSL),
        ("blur", isr::blur::WGSL),
        ("upsample", isr::upsample::WGSL),
    ] {
        let module = naga::front::wgsl::parse_str(source)
            .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    }
}
