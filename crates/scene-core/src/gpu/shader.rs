//! The toolkit's one shader composer: WGSL files that share declarations through
//! `#import`, composed by [naga_oil](https://crates.io/crates/naga_oil) into one naga module.
//!
//! A file meant to be imported names itself on its first lines,
//! `#define_import_path isr::common`; a file that uses it imports what it needs,
//! `#import isr::common::{Globals, globals}` (or the module, and writes `common::Globals`).
//! Shared WGSL lives in the crate that owns it and is exported as a [`Wgsl`] constant, e.g.
//! [`RECONSTRUCT`] (`scene_core::reconstruct`, eq. 24 of the ISR thesis), which every crate
//! that reconstructs positions from depth lists in its passes' library.
//!
//! Each crate describes its passes as [`ShaderPass`]es (a main file, the library files it
//! may import from, and the shader defs of this variant) and lists them in a
//! `SHADER_PASSES` constant. The crate compiles a pass with [`ShaderPass::create_module`];
//! `cargo xtask shaders` composes every crate's `SHADER_PASSES` through the same
//! [`ShaderPass::compose`], validates the result with naga and translates it to SPIR-V, MSL
//! and HLSL. Composing costs 10 to 30 ms a pass once per process (then a clone from a
//! cache) and happens when a pipeline is created, never per frame.
//!
//! ```
//! use scene_core::gpu::shader::{ShaderPass, Wgsl, RECONSTRUCT};
//!
//! const MAIN: Wgsl = Wgsl {
//!     path: "example/depth_to_x.wgsl",
//!     source: "#import scene_core::reconstruct::{FrustumReconstruction, reconstruct}
//!         @group(0) @binding(0) var<uniform> frustum: FrustumReconstruction;
//!         @group(0) @binding(1) var<storage, read_write> out: array<f32>;
//!         @compute @workgroup_size(1)
//!         fn main() { out[0] = reconstruct(frustum, vec2<f32>(0.5), 1.0).x; }",
//! };
//! const PASS: ShaderPass = ShaderPass::new("depth to x", MAIN, &[RECONSTRUCT]);
//! let module = PASS.compose().unwrap();
//! assert_eq!(module.entry_points[0].name, "main");
//! ```

use std::borrow::Cow;
use std::collections::HashMap;

use naga_oil::compose::{
    ComposableModuleDescriptor, Composer, NagaModuleDescriptor, ShaderDefValue,
    get_preprocessor_data,
};

use super::GpuError;
pub use wgpu::naga;

/// One WGSL file embedded in a crate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wgsl {
    /// Its path under the workspace's top-level `shaders/` directory (`isr/common.wgsl`):
    /// errors name it, and `cargo xtask shaders` checks that the text is that file's.
    pub path: &'static str,
    /// The text.
    pub source: &'static str,
}

/// A [`Wgsl`] of the calling crate: `wgsl_file!("isr", "common.wgsl")` embeds the crate's
/// `shaders/common.wgsl` (its link to the top-level `shaders/isr/`) with the path
/// `isr/common.wgsl`.
#[macro_export]
macro_rules! wgsl_file {
    ($dir:literal, $file:literal) => {
        $crate::gpu::shader::Wgsl {
            path: concat!($dir, "/", $file),
            source: include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/shaders/", $file)),
        }
    };
}

/// WGSL of world positions from linear depth (eq. 24 of the ISR thesis, generalised to
/// orthographic views), the module `scene_core::reconstruct`: the struct
/// `FrustumReconstruction` (see [`crate::view::FrustumReconstruction`]) and
/// `fn reconstruct(f, uv, d) -> vec3<f32>`.
pub const RECONSTRUCT: Wgsl = crate::wgsl_file!("scene-core", "reconstruct.wgsl");

/// `scene_core::limits` (`shaders/scene-core/limits.wgsl`): `BACKGROUND` (the id of a pixel
/// without a surface, [`crate::BACKGROUND_ID`]) and `MAX_FINITE` (`f32::MAX`), which every
/// pass imports instead of writing them out.
pub const LIMITS: Wgsl = crate::wgsl_file!("scene-core", "limits.wgsl");

/// `scene_core::texture_wrap` (`shaders/scene-core/texture_wrap.wgsl`): a texture lookup
/// as [`crate::Texture::sample`] makes it, `texel_taps` (the four texels and weights, each
/// axis wrapped by [`crate::Wrap`]'s mode, nearest or bilinear) and `blend_taps`; each
/// shader fetches the taps from its own binding. The G-buffer pass and the GPU path
/// tracer sample textures through it.
pub const TEXTURE_WRAP: Wgsl = crate::wgsl_file!("scene-core", "texture_wrap.wgsl");

/// One compiled shader: a main file, the library files it may import (directly or through
/// each other, in any order) and the boolean shader defs (`#ifdef NAME`) of this variant.
#[derive(Clone, Copy, Debug)]
pub struct ShaderPass {
    /// What the pass is called in errors and in `cargo xtask shaders`.
    pub name: &'static str,
    /// The file holding the entry points.
    pub main: Wgsl,
    /// The files it may import.
    pub library: &'static [Wgsl],
    /// The shader defs set for this variant.
    pub defs: &'static [&'static str],
}

impl ShaderPass {
    /// A pass without shader defs.
    pub const fn new(name: &'static str, main: Wgsl, library: &'static [Wgsl]) -> Self {
        Self {
            name,
            main,
            library,
            defs: &[],
        }
    }

    /// The same pass with the shader defs `defs` set.
    pub const fn with_defs(self, name: &'static str, defs: &'static [&'static str]) -> Self {
        Self { name, defs, ..self }
    }

    /// Composes the pass into one validated naga module. The error names the pass and the
    /// file, with naga_oil's report (undecorated names, source lines).
    ///
    /// Composing is not cheap (10 to 30 ms a pass on a 2-core machine: naga_oil builds its
    /// regular expressions, rewrites and re-parses every module), so a composed module is
    /// kept for the life of the process, keyed by the texts and defs: the second
    /// `GpuIsr::new` (or any pipeline of a pass composed before) costs a clone.
    pub fn compose(&self) -> Result<naga::Module, GpuError> {
        use std::sync::{Mutex, OnceLock};
        static COMPOSED: OnceLock<Mutex<HashMap<u64, naga::Module>>> = OnceLock::new();
        let key = self.key();
        let cache = COMPOSED.get_or_init(Default::default);
        if let Some(m) = cache.lock().ok().and_then(|c| c.get(&key).cloned()) {
            return Ok(m);
        }
        let module = self.compose_uncached()?;
        if let Ok(mut c) = cache.lock() {
            c.insert(key, module.clone());
        }
        Ok(module)
    }

    /// What identifies a composition: every text (main and library, with their paths) and
    /// every def.
    fn key(&self) -> u64 {
        let mut h = crate::hash::Fnv::default();
        for file in std::iter::once(&self.main).chain(self.library) {
            h.str(file.path).str(file.source);
        }
        for d in self.defs {
            h.str(d);
        }
        h.finish()
    }

    /// [`ShaderPass::compose`] without the cache (what `cargo xtask shaders` times).
    pub fn compose_uncached(&self) -> Result<naga::Module, GpuError> {
        let fail = |message: String| GpuError::Shader {
            pass: self.name.to_string(),
            message,
        };
        let mut composer = Composer::default().with_capabilities(naga::valid::Capabilities::all());
        let defs: HashMap<String, ShaderDefValue> = self
            .defs
            .iter()
            .map(|d| (d.to_string(), ShaderDefValue::Bool(true)))
            .collect();
        let mut by_name = HashMap::new();
        for file in self.library {
            let (name, _, _) = get_preprocessor_data(file.source);
            let name = name.ok_or_else(|| {
                fail(format!(
                    "library file {} has no `#define_import_path` line",
                    file.path
                ))
            })?;
            by_name.insert(name, *file);
        }
        let (_, imports, _) = get_preprocessor_data(self.main.source);
        for import in imports {
            add_module(
                &mut composer,
                &by_name,
                &import.import,
                &defs,
                &mut Vec::new(),
            )
            .map_err(fail)?;
        }
        composer
            .make_naga_module(NagaModuleDescriptor {
                source: self.main.source,
                file_path: self.main.path,
                shader_defs: defs.clone(),
                ..Default::default()
            })
            .map_err(|e| fail(e.emit_to_string(&composer)))
    }

    /// Composes the pass ([`ShaderPass::compose`]) and hands the module to `device`.
    pub fn create_module(&self, device: &wgpu::Device) -> Result<wgpu::ShaderModule, GpuError> {
        let module = self.compose()?;
        Ok(device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(self.name),
            source: wgpu::ShaderSource::Naga(Cow::Owned(module)),
        }))
    }
}

/// Adds module `name` to `composer` after the modules it imports. `path` holds the modules
/// being added, to name an import cycle.
fn add_module(
    composer: &mut Composer,
    by_name: &HashMap<String, Wgsl>,
    name: &str,
    defs: &HashMap<String, ShaderDefValue>,
    path: &mut Vec<String>,
) -> Result<(), String> {
    if composer.contains_module(name) {
        return Ok(());
    }
    let Some(file) = by_name.get(name) else {
        return Err(format!(
            "`#import {name}`: no library file of the pass defines it (it has {:?})",
            by_name.keys().collect::<Vec<_>>()
        ));
    };
    if path.iter().any(|p| p == name) {
        return Err(format!("import cycle: {} -> {name}", path.join(" -> ")));
    }
    path.push(name.to_string());
    let (_, imports, _) = get_preprocessor_data(file.source);
    for import in imports {
        add_module(composer, by_name, &import.import, defs, path)?;
    }
    path.pop();
    composer
        .add_composable_module(ComposableModuleDescriptor {
            source: file.source,
            file_path: file.path,
            shader_defs: defs.clone(),
            ..Default::default()
        })
        .map(|_| ())
        .map_err(|e| e.emit_to_string(composer))
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: Wgsl = Wgsl {
        path: "t/a.wgsl",
        source: "#define_import_path t::a\nfn twice(x: f32) -> f32 { return 2.0 * x; }",
    };
    const B: Wgsl = Wgsl {
        path: "t/b.wgsl",
        source: "#define_import_path t::b\n#import t::a::twice\nfn four(x: f32) -> f32 { return twice(twice(x)); }",
    };
    const MAIN: Wgsl = Wgsl {
        path: "t/main.wgsl",
        source: "#import t::b::four
            @group(0) @binding(0) var<storage, read_write> out: array<f32>;
            override SCALE: f32 = 1.0;
            @compute @workgroup_size(1)
            fn main() {
            #ifdef NEGATE
                out[0] = -four(SCALE);
            #else
                out[0] = four(SCALE);
            #endif
            }",
    };

    #[test]
    fn imports_resolve_through_the_library_in_any_order_and_defs_select_code() {
        // B imports A: listed in either order, the pass composes.
        for library in [&[A, B][..], &[B, A][..]] {
            let pass = ShaderPass {
                name: "t",
                main: MAIN,
                library: Box::leak(library.to_vec().into_boxed_slice()),
                defs: &[],
            };
            let m = pass.compose().unwrap();
            // The main file's pipeline constant keeps its name (pipelines set it by name).
            assert!(
                m.overrides
                    .iter()
                    .any(|(_, o)| o.name.as_deref() == Some("SCALE"))
            );
        }
        // The def changes the code: the negated variant has one more unary expression.
        let plain = ShaderPass::new("t", MAIN, &[A, B]);
        let negated = plain.with_defs("t negated", &["NEGATE"]);
        let count = |m: &naga::Module| {
            m.entry_points[0]
                .function
                .expressions
                .iter()
                .filter(|(_, e)| matches!(e, naga::Expression::Unary { .. }))
                .count()
        };
        assert_eq!(
            count(&negated.compose().unwrap()),
            count(&plain.compose().unwrap()) + 1
        );
    }

    #[test]
    fn the_cache_keys_on_the_texts_not_the_names() {
        // The same pass name and file paths with another text of `t::a`: the composed
        // module is the new text's, not the one composed before.
        const A3: Wgsl = Wgsl {
            path: "t/a.wgsl",
            source: "#define_import_path t::a\nfn twice(x: f32) -> f32 { return 3.0 * x + 0.0; }",
        };
        let literals = |m: &naga::Module| {
            m.functions
                .iter()
                .flat_map(|(_, f)| f.expressions.iter())
                .filter(|(_, e)| matches!(e, naga::Expression::Literal(_)))
                .count()
        };
        let two = ShaderPass::new("cached", MAIN, &[A, B]).compose().unwrap();
        let three = ShaderPass::new("cached", MAIN, &[A3, B]).compose().unwrap();
        assert_eq!(literals(&three), literals(&two) + 1);
        // Composed again, each is what it was.
        assert_eq!(
            literals(&ShaderPass::new("cached", MAIN, &[A, B]).compose().unwrap()),
            literals(&two)
        );
    }

    #[test]
    fn a_missing_module_and_a_broken_file_are_named() {
        let e = ShaderPass::new("lonely", MAIN, &[B])
            .compose()
            .unwrap_err()
            .to_string();
        assert!(e.contains("lonely") && e.contains("t::a"), "{e}");
        const BAD: Wgsl = Wgsl {
            path: "t/bad.wgsl",
            source: "#define_import_path t::a\nfn twice(x: f32) -> f32 { return 2.0 * y; }",
        };
        let e = ShaderPass::new("broken", MAIN, &[BAD, B])
            .compose()
            .unwrap_err()
            .to_string();
        assert!(e.contains("broken") && e.contains("t/bad.wgsl"), "{e}");
        const NAMELESS: Wgsl = Wgsl {
            path: "t/nameless.wgsl",
            source: "fn f() {}",
        };
        let e = ShaderPass::new("p", MAIN, &[NAMELESS])
            .compose()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t/nameless.wgsl") && e.contains("define_import_path"),
            "{e}"
        );
    }
}
