//! `cargo xtask shaders`: every shader pass of every crate composed by scene-core's shader
//! composer (`scene_core::gpu::shader`, naga_oil's `#import`), exactly as the crate composes
//! it at run time, validated by naga and translated to SPIR-V, MSL and HLSL, so that a
//! shader a backend cannot take fails CI, not a user. Every `.wgsl` file under the
//! top-level `shaders/` must belong to some pass (as its main file or an imported module),
//! and each pass' embedded text must be that file's: a file nobody composes, or a crate
//! that embeds a stale copy, fails too.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use naga::back::{hlsl, msl, spv};
use naga::valid::{Capabilities, ValidationFlags, Validator};
use scene_core::gpu::shader::{ShaderPass, Wgsl};

/// Every file under `dir` (recursively) whose extension is `ext`, appended to `out`.
fn files_with_extension(dir: &Path, ext: &str, out: &mut Vec<PathBuf>) -> Result<(), String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for entry in entries {
        let path = entry.map_err(|e| e.to_string())?.path();
        if path.is_dir() {
            files_with_extension(&path, ext, out)?;
        } else if path.extension().is_some_and(|e| e == ext) {
            out.push(path);
        }
    }
    Ok(())
}

fn wgsl_files(dir: &Path, out: &mut Vec<PathBuf>) -> Result<(), String> {
    files_with_extension(dir, "wgsl", out)
}

/// The workspace root (xtask lives one level below it).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
}

/// Every library crate's shader passes (their `SHADER_PASSES`), then the viewer's: xtask does
/// not link the viewer (a composition point with a windowing stack), and its passes import
/// nothing, so each `shaders/viewer/*.wgsl` is composed as a pass of its own (the viewer's
/// tests compose its `SHADER_PASSES` through the same entry point).
pub fn all_passes(root: &Path) -> Result<Vec<ShaderPass>, String> {
    let mut passes = [
        scene_core::SHADER_PASSES,
        gbuffer::SHADER_PASSES,
        isr::SHADER_PASSES,
        ibrr_ldc::SHADER_PASSES,
        relight_pr::SHADER_PASSES,
    ]
    .concat();
    let mut viewer = Vec::new();
    wgsl_files(&root.join("viewer"), &mut viewer)?;
    viewer.sort();
    for file in viewer {
        let rel = file
            .strip_prefix(root)
            .unwrap_or(&file)
            .display()
            .to_string();
        let source = std::fs::read_to_string(&file).map_err(|e| format!("{rel}: {e}"))?;
        let path: &'static str = Box::leak(rel.into_boxed_str());
        let source: &'static str = Box::leak(source.into_boxed_str());
        passes.push(ShaderPass::new(path, Wgsl { path, source }, &[]));
    }
    Ok(passes)
}

/// Validates and translates one composed module; returns the SPIR-V word count, MSL and HLSL.
pub fn check_module(name: &str, module: &naga::Module) -> Result<(usize, String, String), String> {
    let info = Validator::new(ValidationFlags::all(), Capabilities::all())
        .validate(module)
        .map_err(|e| format!("{name}: validation error: {e}"))?;
    // Pipeline-overridable constants take their defaults, as a pipeline that sets none.
    let (module, info) =
        naga::back::pipeline_constants::process_overrides(module, &info, None, &Default::default())
            .map_err(|e| format!("{name}: overridable constants: {e}"))?;
    let (module, info) = (module.as_ref(), info.as_ref());
    let words = spv::write_vec(module, info, &spv::Options::default(), None)
        .map_err(|e| format!("{name}: SPIR-V: {e}"))?;
    let (msl_src, _) = msl::write_string(
        module,
        info,
        &msl::Options::default(),
        &msl::PipelineOptions::default(),
    )
    .map_err(|e| format!("{name}: MSL: {e}"))?;
    let mut hlsl_src = String::new();
    let options = hlsl::Options::default();
    let pipeline = hlsl::PipelineOptions::default();
    let mut writer = hlsl::Writer::new(&mut hlsl_src, &options, &pipeline);
    writer
        .write(module, info, None)
        .map_err(|e| format!("{name}: HLSL: {e}"))?;
    Ok((words.len(), msl_src, hlsl_src))
}

/// Composes, validates and translates every pass of `passes` (with `out`, writes `.metal`
/// and `.hlsl` translations there), and checks them against the files under `root`: each
/// embedded file's text equals `root/<path>`, and every `.wgsl` under `root` is used by some
/// pass. Returns the number of passes.
pub fn validate_passes(
    root: &Path,
    passes: &[ShaderPass],
    out: Option<&Path>,
) -> Result<usize, String> {
    let mut errors = Vec::new();
    let mut used = BTreeSet::new();
    for pass in passes {
        for file in std::iter::once(&pass.main).chain(pass.library) {
            used.insert(root.join(file.path));
            match std::fs::read_to_string(root.join(file.path)) {
                Ok(text) if text == file.source => {}
                Ok(_) => errors.push(format!(
                    "{}: the text embedded for {} differs from the file (a stale copy?)",
                    pass.name, file.path
                )),
                Err(e) => errors.push(format!("{}: {}: {e}", pass.name, file.path)),
            }
        }
        let start = std::time::Instant::now();
        let composed = pass.compose_uncached().map_err(|e| e.to_string());
        let compose_ms = start.elapsed().as_secs_f64() * 1e3;
        let result = composed.and_then(|module| check_module(pass.name, &module));
        match result {
            Ok((words, msl_src, hlsl_src)) => {
                eprintln!(
                    "ok  {} (composed in {compose_ms:.2} ms; SPIR-V {words} words, MSL {} B, HLSL {} B)",
                    pass.name,
                    msl_src.len(),
                    hlsl_src.len()
                );
                if let Some(dir) = out {
                    let stem = dir.join(pass.name.replace([' ', '(', ')'], "_"));
                    if let Some(parent) = stem.parent() {
                        std::fs::create_dir_all(parent).map_err(|e| e.to_string())?;
                    }
                    std::fs::write(stem.with_extension("metal"), msl_src)
                        .map_err(|e| e.to_string())?;
                    std::fs::write(stem.with_extension("hlsl"), hlsl_src)
                        .map_err(|e| e.to_string())?;
                }
            }
            Err(e) => errors.push(e),
        }
    }
    let mut files = Vec::new();
    wgsl_files(root, &mut files)?;
    for f in files {
        if !used.contains(&f) {
            errors.push(format!(
                "{}: no crate's SHADER_PASSES composes this file",
                f.display()
            ));
        }
        let rel = f
            .strip_prefix(root)
            .unwrap_or(&f)
            .to_string_lossy()
            .replace('\\', "/");
        let text = std::fs::read_to_string(&f).map_err(|e| format!("{}: {e}", f.display()))?;
        errors.extend(shared_constants_written_out(&rel, &text));
    }
    if errors.is_empty() {
        Ok(passes.len())
    } else {
        Err(errors.join("\n"))
    }
}

/// The constants `scene_core::limits` holds (`shaders/scene-core/limits.wgsl`): a shader
/// imports them rather than writing them out.
const SHARED_CONSTANTS: [&str; 2] = ["BACKGROUND", "MAX_FINITE"];

/// One error per shared constant the shader at `path` (relative to `shaders/`) defines for
/// itself, given its text (any file but the module that holds them).
fn shared_constants_written_out(path: &str, source: &str) -> Vec<String> {
    if path == "scene-core/limits.wgsl" {
        return Vec::new();
    }
    SHARED_CONSTANTS
        .iter()
        .filter(|name| {
            source.lines().any(|l| {
                l.trim_start()
                    .strip_prefix("const ")
                    .and_then(|r| r.strip_prefix(**name))
                    .is_some_and(|r| {
                        r.trim_start().starts_with(':') || r.trim_start().starts_with('=')
                    })
            })
        })
        .map(|name| {
            format!("{path}: defines {name} itself: import it (#import scene_core::limits::{name})")
        })
        .collect()
}

/// Rust files under `dirs` that hand wgpu WGSL text of their own (`ShaderSource::Wgsl`)
/// instead of a module from the composer (`scene_core::gpu::shader`, the one file allowed).
pub fn wgsl_outside_the_composer(dirs: &[PathBuf]) -> Result<Vec<String>, String> {
    let mut files = Vec::new();
    for dir in dirs.iter().filter(|d| d.is_dir()) {
        files_with_extension(dir, "rs", &mut files)?;
    }
    files.sort();
    let needle = ["ShaderSource", "::Wgsl("].concat();
    Ok(files
        .into_iter()
        .filter(|f| !f.ends_with("scene-core/src/gpu/shader.rs"))
        .filter(|f| std::fs::read_to_string(f).is_ok_and(|t| t.contains(&needle)))
        .map(|f| {
            format!(
                "{}: WGSL handed to wgpu outside the composer (use a ShaderPass)",
                f.display()
            )
        })
        .collect())
}

/// [`validate_passes`] over every crate's passes and the workspace's `shaders/`, and
/// [`wgsl_outside_the_composer`] over every crate's sources, examples and tests.
pub fn validate_all(out: Option<&Path>) -> Result<usize, String> {
    let workspace = workspace_root();
    let root = workspace.join("shaders");
    let n = validate_passes(&root, &all_passes(&root)?, out)?;
    let mut dirs = vec![workspace.join("xtask"), workspace.join("tests")];
    for entry in std::fs::read_dir(workspace.join("crates")).map_err(|e| e.to_string())? {
        dirs.push(entry.map_err(|e| e.to_string())?.path());
    }
    let outside = wgsl_outside_the_composer(&dirs)?;
    if outside.is_empty() {
        Ok(n)
    } else {
        Err(outside.join("\n"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_project_shaders_are_valid() {
        assert!(validate_all(None).unwrap() >= 10);
    }

    #[test]
    fn stale_copies_unused_files_and_broken_passes_are_rejected() {
        let root = std::env::temp_dir().join(format!("xtask-shaders-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(root.join("t")).unwrap();
        const PART: Wgsl = Wgsl {
            path: "t/part.wgsl",
            source: "#define_import_path t::part\nfn half(v: f32) -> f32 { return 0.5 * v; }\n",
        };
        const MAIN: Wgsl = Wgsl {
            path: "t/main.wgsl",
            source: "#import t::part::half\n@compute @workgroup_size(1) fn main() { let x: f32 = half(1.0); }\n",
        };
        std::fs::write(root.join(PART.path), PART.source).unwrap();
        std::fs::write(root.join(MAIN.path), MAIN.source).unwrap();
        let pass = ShaderPass::new("t", MAIN, &[PART]);
        assert_eq!(validate_passes(&root, &[pass], None), Ok(1));
        // Without the module it imports, the pass does not compose.
        let e = validate_passes(&root, &[ShaderPass::new("t", MAIN, &[])], None).unwrap_err();
        assert!(e.contains("t::part"), "{e}");
        // A file no pass uses.
        std::fs::write(root.join("t/orphan.wgsl"), "fn f() {}").unwrap();
        let e = validate_passes(&root, &[pass], None).unwrap_err();
        assert!(e.contains("orphan.wgsl"), "{e}");
        std::fs::remove_file(root.join("t/orphan.wgsl")).unwrap();
        // A crate's embedded text that is not the file's.
        std::fs::write(root.join(PART.path), "// edited\n").unwrap();
        let e = validate_passes(&root, &[pass], None).unwrap_err();
        assert!(e.contains("t/part.wgsl") && e.contains("differs"), "{e}");
        // A pass that composes but does not validate (type mismatch).
        const BAD: Wgsl = Wgsl {
            path: "t/main.wgsl",
            source: "@compute @workgroup_size(1) fn main() { let x: f32 = 1u; }\n",
        };
        std::fs::write(root.join(BAD.path), BAD.source).unwrap();
        std::fs::write(root.join(PART.path), PART.source).unwrap();
        assert!(validate_passes(&root, &[ShaderPass::new("bad", BAD, &[PART])], None).is_err());
        std::fs::remove_dir_all(&root).unwrap();
    }

    /// A shader writing out a shared constant is named; importing it, or a longer name that
    /// starts the same, is not.
    #[test]
    fn shared_constants_written_out_are_named() {
        let e = shared_constants_written_out(
            "t/main.wgsl",
            "const BACKGROUND: u32 = 0xffffffffu;\n  const MAX_FINITE = 3.4e38;\n",
        );
        assert_eq!(e.len(), 2, "{e:?}");
        assert!(
            e[0].contains("t/main.wgsl") && e[0].contains("BACKGROUND"),
            "{e:?}"
        );
        assert!(
            shared_constants_written_out(
                "t/main.wgsl",
                "#import scene_core::limits::{BACKGROUND, MAX_FINITE}\nconst BACKGROUND_TINT: f32 = 1.0;\n"
            )
            .is_empty()
        );
        assert!(
            shared_constants_written_out(
                "scene-core/limits.wgsl",
                "const BACKGROUND: u32 = 0xffffffffu;\n"
            )
            .is_empty()
        );
        // Through the whole check: a file under the root that writes one out fails it.
        let root = std::env::temp_dir().join(format!("xtask-limits-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(root.join("t")).unwrap();
        const OWN: Wgsl = Wgsl {
            path: "t/main.wgsl",
            source: "const MAX_FINITE: f32 = 3.40282347e38;\n@compute @workgroup_size(1) fn main() { let x: f32 = MAX_FINITE; }\n",
        };
        std::fs::write(root.join(OWN.path), OWN.source).unwrap();
        let e = validate_passes(&root, &[ShaderPass::new("t", OWN, &[])], None).unwrap_err();
        assert!(e.contains("t/main.wgsl: defines MAX_FINITE itself"), "{e}");
        std::fs::remove_dir_all(&root).unwrap();
    }

    /// Rust that hands wgpu WGSL of its own is named; the composer's file is allowed.
    #[test]
    fn wgsl_built_outside_the_composer_is_named() {
        let root = std::env::temp_dir().join(format!("xtask-composer-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let own = root.join("crates/a/src");
        let composer = root.join("crates/scene-core/src/gpu");
        std::fs::create_dir_all(&own).unwrap();
        std::fs::create_dir_all(&composer).unwrap();
        let call = ["wgpu::ShaderSource", "::Wgsl(src.into())"].concat();
        std::fs::write(own.join("lib.rs"), format!("fn f() {{ {call}; }}")).unwrap();
        std::fs::write(composer.join("shader.rs"), format!("fn g() {{ {call}; }}")).unwrap();
        std::fs::write(own.join("ok.rs"), "fn h() {}").unwrap();
        let found = wgsl_outside_the_composer(&[root.join("crates")]).unwrap();
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(found[0].contains("crates/a/src/lib.rs"), "{found:?}");
        // The project's own sources hand wgpu nothing of their own.
        let workspace = workspace_root();
        assert!(
            wgsl_outside_the_composer(&[workspace.join("crates"), workspace.join("xtask")])
                .unwrap()
                .is_empty()
        );
        std::fs::remove_dir_all(&root).unwrap();
    }
}
