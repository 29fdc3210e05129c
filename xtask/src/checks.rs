//! `cargo xtask ci` and the dependency rule.

use std::process::Command;

/// The composition points: they may use every crate, and nothing of the library (the
/// spokes and scene-core) may depend on them.
pub const COMPOSITION_POINTS: [&str; 3] = ["xtask", "golden-tests", "viewer"];

/// The six spokes: each depends on scene-core and on no sibling.
pub const SPOKES: [&str; 6] = [
    "gbuffer",
    "isr",
    "ibrr-ldc",
    "relight-pr",
    "imalyzer",
    "bench-harness",
];

fn cargo(args: &[&str]) -> Result<(), String> {
    eprintln!("$ cargo {}", args.join(" "));
    let status = Command::new(env!("CARGO"))
        .args(args)
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("`cargo {}` failed ({status})", args.join(" ")))
    }
}

/// Fails when a spoke names a sibling among its normal or build dependencies, or does not
/// depend on scene-core, or when a spoke or scene-core depends on a composition point.
pub fn dependency_rule() -> Result<(), String> {
    let out = Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .output()
        .map_err(|e| format!("cannot run cargo metadata: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "cargo metadata failed: {}",
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let meta: serde_json::Value =
        serde_json::from_slice(&out.stdout).map_err(|e| format!("cargo metadata: {e}"))?;
    let violations = rule_violations(&meta);
    if violations.is_empty() {
        eprintln!(
            "dependency rule holds: every spoke depends on scene-core and no sibling, and nothing \
             of the library depends on a composition point"
        );
        Ok(())
    } else {
        Err(format!(
            "dependency rule broken:\n  {}",
            violations.join("\n  ")
        ))
    }
}

/// The violations of the rule in `cargo metadata` output.
pub fn rule_violations(meta: &serde_json::Value) -> Vec<String> {
    let mut violations = Vec::new();
    let empty = Vec::new();
    for pkg in meta["packages"].as_array().unwrap_or(&empty) {
        let name = pkg["name"].as_str().unwrap_or_default();
        if !SPOKES.contains(&name) && name != "scene-core" {
            continue;
        }
        let deps = pkg["dependencies"].as_array().unwrap_or(&empty);
        for dep in deps {
            let dep_name = dep["name"].as_str().unwrap_or_default();
            if COMPOSITION_POINTS.contains(&dep_name) {
                violations.push(format!(
                    "{name} depends on the composition point {dep_name}; only xtask, the golden \
                     tests and the viewer compose the library"
                ));
            }
        }
        if name == "scene-core" {
            continue;
        }
        let mut has_core = false;
        for dep in deps {
            let dep_name = dep["name"].as_str().unwrap_or_default();
            let kind = dep["kind"].as_str().unwrap_or("normal");
            if dep_name == "scene-core" && kind == "normal" {
                has_core = true;
            }
            if SPOKES.contains(&dep_name) && kind != "dev" {
                violations.push(format!(
                    "{name} depends on sibling {dep_name}; share a type or trait through scene-core instead"
                ));
            }
        }
        if !has_core {
            violations.push(format!("{name} does not depend on scene-core"));
        }
    }
    violations
}

/// Runs every check CI runs.
pub fn ci(with_tests: bool) -> Result<(), String> {
    cargo(&["fmt", "--all", "--", "--check"])?;
    cargo(&[
        "clippy",
        "--workspace",
        "--all-targets",
        "--",
        "-D",
        "warnings",
    ])?;
    dependency_rule()?;
    let n = crate::shaders::validate_all(&crate::shaders::workspace_root().join("shaders"), None)?;
    eprintln!("{n} shader(s) valid");
    if with_tests {
        cargo(&["test", "--workspace"])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta(deps: &[(&str, &str)]) -> serde_json::Value {
        let deps: Vec<_> = deps
            .iter()
            .map(|(n, k)| {
                let kind = if *k == "normal" {
                    serde_json::Value::Null
                } else {
                    serde_json::Value::String(k.to_string())
                };
                serde_json::json!({"name": n, "kind": kind})
            })
            .collect();
        serde_json::json!({"packages": [{"name": "isr", "dependencies": deps}]})
    }

    #[test]
    fn sibling_dependency_is_a_violation() {
        assert!(rule_violations(&meta(&[("scene-core", "normal")])).is_empty());
        let v = rule_violations(&meta(&[("scene-core", "normal"), ("gbuffer", "normal")]));
        assert_eq!(v.len(), 1);
        assert!(v[0].contains("isr depends on sibling gbuffer"));
        assert_eq!(
            rule_violations(&meta(&[("scene-core", "normal"), ("gbuffer", "build")])).len(),
            1
        );
        // Missing scene-core is flagged too.
        assert_eq!(rule_violations(&meta(&[])).len(), 1);
    }

    #[test]
    fn depending_on_a_composition_point_is_a_violation() {
        for point in COMPOSITION_POINTS {
            // Even as a dev-dependency: a spoke's tests must not need the viewer.
            let v = rule_violations(&meta(&[("scene-core", "normal"), (point, "dev")]));
            assert_eq!(v.len(), 1, "{point}: {v:?}");
            assert!(v[0].contains(&format!("isr depends on the composition point {point}")));
        }
        let core = serde_json::json!({"packages": [{"name": "scene-core",
            "dependencies": [{"name": "viewer", "kind": null}]}]});
        assert_eq!(rule_violations(&core).len(), 1);
    }
}
