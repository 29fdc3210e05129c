//! What `gltf_io::export` writes passes Khronos' glTF validator (npm `gltf-validator`) with
//! no error and no warning: every built-in scene, as `.gltf` and `.glb`.
//!
//! The validator runs under Node. It is looked for in `$GLTF_VALIDATOR_DIR/node_modules`,
//! else in `target/gltf-validator/node_modules` (where `.ci/run` installs it:
//! `npm install --prefix target/gltf-validator gltf-validator`). Without Node or the
//! package the test says so and passes, unless `REQUIRE_GLTF_VALIDATOR` is set (CI sets it).

use std::path::PathBuf;
use std::process::Command;

use scene_core::{builtin, gltf_io};

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

fn validator_dir() -> PathBuf {
    match std::env::var_os("GLTF_VALIDATOR_DIR") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/gltf-validator"),
    }
}

#[test]
fn exported_builtin_scenes_pass_the_khronos_validator() {
    let dir = validator_dir();
    let module = dir.join("node_modules").join("gltf-validator");
    let node = Command::new("node").arg("--version").output();
    if !module.exists() || !node.is_ok_and(|o| o.status.success()) {
        let why = format!(
            "Node or the gltf-validator package is missing (looked in {}); install it with \
             `npm install --prefix target/gltf-validator gltf-validator`",
            module.display()
        );
        assert!(
            std::env::var_os("REQUIRE_GLTF_VALIDATOR").is_none(),
            "{why}"
        );
        eprintln!("not validated: {why}");
        return;
    }
    let out = std::env::temp_dir().join(format!("gltf-validator-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let mut files = Vec::new();
    for name in [
        "cornell",
        "cornell-point",
        "primitives",
        "corridor",
        "many-boxes 20",
    ] {
        let scene = builtin::scene(name).unwrap();
        for ext in ["gltf", "glb"] {
            let path = out.join(format!("{}.{ext}", name.replace(' ', "-")));
            gltf_io::export(&scene, &path).unwrap();
            files.push(path);
        }
    }
    let script = out.join("validate.js");
    std::fs::write(&script, SCRIPT).unwrap();
    let run = Command::new("node")
        .arg(&script)
        .args(&files)
        .env("NODE_PATH", dir.join("node_modules"))
        .output()
        .expect("run node");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "validator failed: {}{stdout}",
        String::from_utf8_lossy(&run.stderr)
    );
    let reports: serde_json::Value = serde_json::from_str(stdout.trim()).expect("JSON report");
    let reports = reports.as_array().unwrap();
    assert_eq!(reports.len(), files.len());
    for r in reports {
        assert_eq!(r["errors"], 0, "{r}");
        assert_eq!(r["warnings"], 0, "{r}");
    }
    eprintln!("{} files validated: 0 errors, 0 warnings", reports.len());
    std::fs::remove_dir_all(&out).ok();
}
