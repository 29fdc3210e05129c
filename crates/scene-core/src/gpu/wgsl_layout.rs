//! Rust structs written into GPU buffers, checked against the WGSL structs that read them.
//!
//! A `#[repr(C)]` struct uploaded with `bytemuck` must put every field at the offset WGSL's
//! layout rules give its counterpart (16-byte alignment of `vec3`/`vec4`, struct sizes
//! rounded to their alignment). Padding written by hand drifts when a field is added on one
//! side only, and the shader then reads the wrong bytes without any error. naga (the WGSL
//! front end wgpu itself uses) lays out the shader's structs; [`check`] compares that
//! layout, member by member, with the Rust struct's `offset_of!` and `size_of`. Every crate
//! runs it in a unit test for each struct it shares with a shader, through [`check_layout!`](crate::check_layout):
//!
//! ```
//! # #[derive(Clone, Copy)]
//! #[repr(C)]
//! struct Params {
//!     color: [f32; 3],
//!     count: u32,
//!     scale: [f32; 2],
//!     pad: [u32; 2],
//! }
//! let module = naga::front::wgsl::parse_str(
//!     "struct Params { color: vec3<f32>, count: u32, scale: vec2<f32>, pad: vec2<u32> }
//!      @group(0) @binding(0) var<uniform> params: Params;",
//! )
//! .unwrap();
//! scene_core::check_layout!(&module, "Params", Params { color, count, scale, pad }).unwrap();
//! // A WGSL member whose Rust field has another name (or lives inside an array) is given as
//! // `wgsl_name: rust_field + byte_offset`.
//! scene_core::check_layout!(&module, "Params", Params { color, count: count + 0, scale, pad })
//!     .unwrap();
//! # use scene_core::gpu::naga;
//! ```

pub use wgpu::naga;

/// A WGSL struct as naga lays it out.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WgslStruct {
    /// `(member name, byte offset)` in declaration order.
    pub members: Vec<(String, u32)>,
    /// The struct's size in bytes (its span, a multiple of its alignment).
    pub size: u32,
}

/// The layout of struct `name` in `module` (a name decorated by a shader composer's module
/// mangling matches by its undecorated prefix), or why there is none.
pub fn wgsl_struct(module: &naga::Module, name: &str) -> Result<WgslStruct, String> {
    let mut layouter = naga::proc::Layouter::default();
    layouter
        .update(module.to_ctx())
        .map_err(|e| format!("naga cannot lay the module's types out: {e}"))?;
    for (handle, ty) in module.types.iter() {
        let Some(ty_name) = ty.name.as_deref() else {
            continue;
        };
        if !same_name(ty_name, name) {
            continue;
        }
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            return Err(format!("WGSL type {name} is not a struct"));
        };
        if layouter[handle].size != *span {
            return Err(format!(
                "WGSL struct {name}: naga's layout size {} differs from its span {span}",
                layouter[handle].size
            ));
        }
        return Ok(WgslStruct {
            members: members
                .iter()
                .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                .collect(),
            size: *span,
        });
    }
    Err(format!("no WGSL struct {name} in the module"))
}

/// True when `declared` is `name`, or `name` decorated by a composer (`nameX_naga_oil_...`).
fn same_name(declared: &str, name: &str) -> bool {
    declared == name
        || declared
            .strip_prefix(name)
            .is_some_and(|rest| rest.starts_with("X_naga_oil"))
}

/// Compares WGSL struct `name` in `module` with a Rust struct of `rust_size` bytes whose
/// fields, in WGSL's member order, are `rust_members` (`(WGSL member name, Rust offset)`).
/// The error names the first member whose name or offset differs, or the sizes.
pub fn check(
    module: &naga::Module,
    name: &str,
    rust_size: usize,
    rust_members: &[(&str, usize)],
) -> Result<(), String> {
    let wgsl = wgsl_struct(module, name)?;
    if wgsl.members.len() != rust_members.len() {
        return Err(format!(
            "WGSL struct {name} has {} members {:?}, the Rust struct lists {} {:?}",
            wgsl.members.len(),
            wgsl.members.iter().map(|m| &m.0).collect::<Vec<_>>(),
            rust_members.len(),
            rust_members.iter().map(|m| m.0).collect::<Vec<_>>()
        ));
    }
    for ((wname, woff), (rname, roff)) in wgsl.members.iter().zip(rust_members) {
        if wname != rname || *woff as usize != *roff {
            return Err(format!(
                "WGSL struct {name}: member {wname} at byte {woff}, the Rust struct has {rname} \
                 at byte {roff}"
            ));
        }
    }
    if wgsl.size as usize != rust_size {
        return Err(format!(
            "WGSL struct {name} is {} bytes, the Rust struct {rust_size}",
            wgsl.size
        ));
    }
    Ok(())
}

/// Checks a Rust struct against a WGSL struct ([`check`]):
/// `check_layout!(&module, "WgslName", RustType { field, wgsl_member: rust_field + 16, .. })`,
/// members in WGSL order; a bare `field` means the same name on both sides.
#[macro_export]
macro_rules! check_layout {
    ($module:expr, $wgsl:expr, $ty:ty { $($member:ident $(: $field:ident $(+ $add:expr)?)?),* $(,)? }) => {
        $crate::gpu::wgsl_layout::check(
            $module,
            $wgsl,
            ::core::mem::size_of::<$ty>(),
            &[$((
                stringify!($member),
                $crate::check_layout!(@offset $ty, $member $(: $field $(+ $add)?)?),
            )),*],
        )
    };
    (@offset $ty:ty, $member:ident) => { ::core::mem::offset_of!($ty, $member) };
    (@offset $ty:ty, $member:ident : $field:ident) => { ::core::mem::offset_of!($ty, $field) };
    (@offset $ty:ty, $member:ident : $field:ident + $add:expr) => {
        ::core::mem::offset_of!($ty, $field) + $add
    };
}

#[cfg(test)]
mod tests {
    use super::naga;

    #[allow(dead_code)]
    #[repr(C)]
    struct Light {
        position: [f32; 3],
        kind: u32,
        color: [f32; 4],
    }

    const WGSL: &str = "struct Light { position: vec3<f32>, kind: u32, color: vec4<f32> }
        @group(0) @binding(0) var<storage> lights: array<Light>;";

    #[test]
    fn a_matching_struct_passes_and_every_kind_of_drift_is_named() {
        let module = naga::front::wgsl::parse_str(WGSL).unwrap();
        crate::check_layout!(
            &module,
            "Light",
            Light {
                position,
                kind,
                color
            }
        )
        .unwrap();
        // A member moved by four bytes.
        let e = crate::check_layout!(
            &module,
            "Light",
            Light {
                position,
                kind,
                color: color + 4
            }
        )
        .unwrap_err();
        assert!(
            e.contains("member color at byte 16") && e.contains("byte 20"),
            "{e}"
        );
        // A renamed member, a missing member, a wrong size, an unknown struct.
        let e = crate::check_layout!(
            &module,
            "Light",
            Light {
                position,
                kind: color,
                color
            }
        )
        .unwrap_err();
        assert!(e.contains("kind at byte 12"), "{e}");
        let e = crate::check_layout!(&module, "Light", Light { position, kind }).unwrap_err();
        assert!(e.contains("3 members"), "{e}");
        let e = super::check(
            &module,
            "Light",
            48,
            &[("position", 0), ("kind", 12), ("color", 16)],
        )
        .unwrap_err();
        assert!(e.contains("32 bytes, the Rust struct 48"), "{e}");
        assert!(super::wgsl_struct(&module, "Lamp").is_err());
        // A composer's decorated name still matches.
        assert!(super::same_name(
            "LightX_naga_oil_mod_XMJSXM6K7MJXXE2LFHMXHI4TBORUXSX",
            "Light"
        ));
        assert!(!super::same_name("LightSet", "Light"));
    }
}
