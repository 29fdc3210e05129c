//! Khronos' glTF validator (npm `gltf-validator`, run under Node) as an independent check
//! of what the toolkit exports.
//!
//! The package is looked for in `$GLTF_VALIDATOR_DIR/node_modules`, else in
//! `target/gltf-validator/node_modules` of the workspace (where `.ci/run` installs it:
//! `npm install --prefix target/gltf-validator gltf-validator`).

use std::path::{Path, PathBuf};
use std::process::Command;

const SCRIPT: &str = r#"
const v = require('gltf-validator');
const fs = require('fs');
(async () => {
  const out = [];
  for (const f of process.argv.slice(2)) {
    const r = await v.validateBytes(new Uint8Array(fs.readFileSync(f)), { uri: f });
    out.push({ file: f, errors: r.issues.numErrors, warnings: r.issues.numWarnings,
               messages: r.issues.messages.filter(m => m.severity <= 1) });
  }
  console.log(JSON.stringify(out));
})().catch(e => { console.error(e); process.exit(2); });
"#;

/// The validator's verdict on one file.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// The file.
    pub file: PathBuf,
    /// Number of errors.
    pub errors: u64,
    /// Number of warnings.
    pub warnings: u64,
    /// The errors' and warnings' messages, as the validator's JSON.
    pub messages: String,
}

fn validator_dir() -> PathBuf {
    match std::env::var_os("GLTF_VALIDATOR_DIR") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/gltf-validator"),
    }
}

/// Validates `files`. `Ok(None)` when Node or the package is missing (the message says
/// where it looked); an `Err` when the validator could not run or answered nonsense.
pub fn validate(files: &[&Path]) -> Result<Option<Vec<Report>>, String> {
    let dir = validator_dir();
    let module = dir.join("node_modules").join("gltf-validator");
    let node = Command::new("node").arg("--version").output();
    if !module.exists() || !node.is_ok_and(|o| o.status.success()) {
        return Ok(None);
    }
    let script = std::env::temp_dir().join(format!("gltf-validate-{}.js", std::process::id()));
    std::fs::write(&script, SCRIPT).map_err(|e| format!("{}: {e}", script.display()))?;
    let run = Command::new("node")
        .arg(&script)
        .args(files)
        .env("NODE_PATH", dir.join("node_modules"))
        .output()
        .map_err(|e| format!("node: {e}"));
    std::fs::remove_file(&script).ok();
    let run = run?;
    let stdout = String::from_utf8_lossy(&run.stdout);
    if !run.status.success() {
        return Err(format!(
            "validator failed: {}{stdout}",
            String::from_utf8_lossy(&run.stderr)
        ));
    }
    let reports: serde_json::Value =
        serde_json::from_str(stdout.trim()).map_err(|e| format!("validator output: {e}"))?;
    let reports = reports.as_array().ok_or("validator output is not a list")?;
    Ok(Some(
        reports
            .iter()
            .map(|r| Report {
                file: PathBuf::from(r["file"].as_str().unwrap_or_default()),
                errors: r["errors"].as_u64().unwrap_or(u64::MAX),
                warnings: r["warnings"].as_u64().unwrap_or(u64::MAX),
                messages: r["messages"].to_string(),
            })
            .collect(),
    ))
}

/// [`validate`] for tests: panics on any error or warning; without the validator, says so
/// and returns `false`, unless `REQUIRE_GLTF_VALIDATOR` is set (CI sets it), then panics.
pub fn assert_valid(files: &[&Path]) -> bool {
    match validate(files) {
        Ok(Some(reports)) => {
            assert_eq!(reports.len(), files.len());
            for r in &reports {
                assert!(
                    r.errors == 0 && r.warnings == 0,
                    "{}: {} errors, {} warnings: {}",
                    r.file.display(),
                    r.errors,
                    r.warnings,
                    r.messages
                );
            }
            true
        }
        Ok(None) => {
            let why = format!(
                "Node or the gltf-validator package is missing (looked in {}); install it with \
                 `npm install --prefix target/gltf-validator gltf-validator`",
                validator_dir().display()
            );
            assert!(
                std::env::var_os("REQUIRE_GLTF_VALIDATOR").is_none(),
                "{why}"
            );
            eprintln!("not validated: {why}");
            false
        }
        Err(e) => panic!("{e}"),
    }
}
