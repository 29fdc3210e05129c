//! `cargo xtask shaders`: every WGSL file parsed and validated by naga, then translated to
//! SPIR-V, MSL and HLSL, so that a shader a backend cannot take fails CI, not a user.
//!
//! WGSL has no `#include`, so a directory's shared declarations go in a file named
//! `common.wgsl`: it is validated on its own, and prepended to every other `.wgsl` in the same
//! directory (not in its subdirectories) before that file is validated. The crate embedding
//! such a pass must do the same, e.g.
//! `concat!(include_str!(".../common.wgsl"), include_str!(".../pass.wgsl"))` (or
//! `scene_core::wgsl!` when a part is another crate's constant); a pass that
//! must not get the common part goes in a subdirectory.
//!
//! A pass made of several files (one per Rust module it mirrors, or a part shared across
//! crates such as `shaders/scene-core/reconstruct.wgsl`) says so on its first line,
//! `// after: a.wgsl ../other/b.wgsl`: those files (paths relative to its directory) come
//! before it, in that order (not transitively; a `common.wgsl`'s parts come before the
//! common file), and the embedding crate concatenates the same.

use std::path::{Path, PathBuf};

use naga::back::{hlsl, msl, spv};
use naga::valid::{Capabilities, ValidationFlags, Validator};

fn wgsl_files(dir: &Path, out: &mut Vec<PathBuf>) -> Result<(), String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for entry in entries {
        let path = entry.map_err(|e| e.to_string())?.path();
        if path.is_dir() {
            wgsl_files(&path, out)?;
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            out.push(path);
        }
    }
    Ok(())
}

/// The workspace root (xtask lives one level below it).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
}

/// Validates and translates one WGSL source; returns the SPIR-V word count, MSL and HLSL.
pub fn check_source(name: &str, source: &str) -> Result<(usize, String, String), String> {
    let module = naga::front::wgsl::parse_str(source)
        .map_err(|e| format!("{name}: parse error:\n{}", e.emit_to_string(source)))?;
    let info = Validator::new(ValidationFlags::all(), Capabilities::all())
        .validate(&module)
        .map_err(|e| format!("{name}: validation error:\n{}", e.emit_to_string(source)))?;
    // Pipeline-overridable constants take their defaults, as a pipeline that sets none.
    let (module, info) = naga::back::pipeline_constants::process_overrides(
        &module,
        &info,
        None,
        &Default::default(),
    )
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

/// The name of a directory's shared prelude; see the module documentation.
pub const COMMON: &str = "common.wgsl";

/// The source to validate for `file`: its text, after its directory's `common.wgsl` unless it
/// is that file or there is none.
fn source_of(file: &Path, rel: &str) -> Result<String, String> {
    let mut source = String::new();
    let common = file.with_file_name(COMMON);
    if common.is_file() && file.file_name().is_some_and(|n| n != COMMON) {
        source = with_parts(&common, rel)?;
    }
    Ok(source + &with_parts(file, rel)?)
}

/// `file`'s text after the parts its `// after:` line names (paths relative to its
/// directory, e.g. `../scene-core/reconstruct.wgsl`).
fn with_parts(file: &Path, rel: &str) -> Result<String, String> {
    let own = std::fs::read_to_string(file).map_err(|e| format!("{}: {e}", file.display()))?;
    let mut source = String::new();
    for part in after(&own) {
        let path = file.with_file_name(part);
        let text = std::fs::read_to_string(&path)
            .map_err(|e| format!("{rel}: its `// after:` part {part}: {e}"))?;
        source.push_str(&text);
    }
    Ok(source + &own)
}

/// The files a WGSL source's first line, `// after: a.wgsl b.wgsl`, says come before it.
fn after(source: &str) -> Vec<&str> {
    source
        .lines()
        .next()
        .and_then(|l| l.strip_prefix("// after:"))
        .map(|rest| rest.split_whitespace().collect())
        .unwrap_or_default()
}

/// Validates every `**/*.wgsl` under `root` (each after its directory's `common.wgsl`, see the
/// module documentation); with `out`, writes `.metal` and `.hlsl` translations there. Returns
/// the number of shaders. Fails when there are none.
pub fn validate_all(root: &Path, out: Option<&Path>) -> Result<usize, String> {
    let mut files = Vec::new();
    wgsl_files(root, &mut files)?;
    files.sort();
    if files.is_empty() {
        return Err(format!("no .wgsl files under {}", root.display()));
    }
    let mut errors = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(root).unwrap_or(f).display().to_string();
        let source = source_of(f, &rel)?;
        let with_common =
            f.file_name().is_some_and(|n| n != COMMON) && f.with_file_name(COMMON).is_file();
        let name = if with_common {
            format!("{rel} (after its directory's {COMMON})")
        } else {
            rel.clone()
        };
        match check_source(&name, &source) {
            Ok((words, msl_src, hlsl_src)) => {
                eprintln!(
                    "ok  {name} (SPIR-V {words} words, MSL {} B, HLSL {} B)",
                    msl_src.len(),
                    hlsl_src.len()
                );
                if let Some(dir) = out {
                    let stem = dir.join(rel.replace(".wgsl", ""));
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
    if errors.is_empty() {
        Ok(files.len())
    } else {
        Err(errors.join("\n"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn broken_shaders_are_rejected() {
        let good = "@compute @workgroup_size(1) fn main() {}";
        assert!(check_source("good", good).is_ok());
        // Syntax error.
        assert!(
            check_source("bad", "fn main( {")
                .unwrap_err()
                .contains("parse error")
        );
        // Parses but fails validation (type mismatch).
        let invalid = "@compute @workgroup_size(1) fn main() { let x: f32 = 1u; }";
        assert!(check_source("invalid", invalid).is_err());
    }

    #[test]
    fn the_project_shaders_are_valid() {
        assert!(validate_all(&workspace_root().join("shaders"), None).unwrap() >= 1);
    }

    #[test]
    fn common_wgsl_is_prepended_to_its_directory() {
        let root = std::env::temp_dir().join(format!("xtask-common-wgsl-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let dir = root.join("pass");
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let pass = "@compute @workgroup_size(1) fn main() { let x: f32 = twice(1.0); }";
        std::fs::write(dir.join("pass.wgsl"), pass).unwrap();
        // Without common.wgsl, `twice` is undefined.
        assert!(validate_all(&root, None).is_err());
        // With it, the pass validates, and so does the common file on its own.
        let common = "fn twice(v: f32) -> f32 { return 2.0 * v; }\n";
        std::fs::write(dir.join(COMMON), common).unwrap();
        assert_eq!(validate_all(&root, None), Ok(2));
        // Only the same directory gets it, not a subdirectory.
        std::fs::write(dir.join("sub").join("other.wgsl"), pass).unwrap();
        assert!(
            validate_all(&root, None)
                .unwrap_err()
                .contains("other.wgsl")
        );
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn after_parts_come_before_a_file_across_directories() {
        let root = std::env::temp_dir().join(format!("xtask-after-wgsl-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(root.join("a")).unwrap();
        std::fs::create_dir_all(root.join("b")).unwrap();
        std::fs::write(
            root.join("a").join("part.wgsl"),
            "fn half(v: f32) -> f32 { return 0.5 * v; }\n",
        )
        .unwrap();
        let pass = "@compute @workgroup_size(1) fn main() { let x: f32 = half(1.0); }\n";
        // Without its `// after:` line the pass does not know `half`.
        std::fs::write(root.join("b").join("pass.wgsl"), pass).unwrap();
        assert!(validate_all(&root, None).unwrap_err().contains("pass.wgsl"));
        std::fs::write(
            root.join("b").join("pass.wgsl"),
            format!("// after: ../a/part.wgsl\n{pass}"),
        )
        .unwrap();
        assert_eq!(validate_all(&root, None), Ok(2));
        // A part that does not exist is named.
        std::fs::write(
            root.join("b").join("pass.wgsl"),
            format!("// after: ../a/missing.wgsl\n{pass}"),
        )
        .unwrap();
        assert!(
            validate_all(&root, None)
                .unwrap_err()
                .contains("missing.wgsl")
        );
        std::fs::remove_dir_all(&root).unwrap();
    }
}
