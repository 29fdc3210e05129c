//! `cargo xtask ci`: formatting, clippy, the dependency rule, what each library crate costs
//! (built alone with its features, and the dependencies it must not pull in), the declared
//! minimum Rust versions against the dependencies', and the shaders.

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

/// The library crates a team may pick one by one (packaged and built alone in CI), with
/// whether each has cargo features to turn off.
pub const LIBRARIES: [(&str, bool); 7] = [
    ("scene-core", true),
    ("gbuffer", false),
    ("isr", false),
    ("ibrr-ldc", false),
    ("relight-pr", false),
    ("imalyzer", true),
    ("bench-harness", false),
];

/// What a library must not pull in with its default features (`cargo tree -e normal`):
/// image comparison needs no GPU, glTF or BVH; ISR, a G-buffer post-process, no glTF or EXR.
pub const MUST_NOT_PULL: [(&str, &[&str]); 2] = [
    ("imalyzer", &["wgpu", "gltf", "obvhs"]),
    ("isr", &["gltf", "exr"]),
];

/// What a library's test build must not pull in (`cargo tree -e normal,dev`): imalyzer's
/// tests take the reference path tracer's variance, and need no GPU or glTF; ISR's read
/// EXR golden images, and need no glTF.
pub const TESTS_MUST_NOT_PULL: [(&str, &[&str]); 2] = [
    ("imalyzer", &["wgpu", "naga_oil", "gltf"]),
    ("isr", &["gltf"]),
];

/// The scene-core features that `member` names, with what they imply: the `features` of
/// its dependencies on scene-core (normal and dev), scene-core's defaults where such a
/// dependency keeps them, and what its own default features forward (`scene-core/x`).
/// `meta` is `cargo metadata --no-deps`.
pub fn named_core_features(
    meta: &serde_json::Value,
    member: &str,
) -> std::collections::BTreeSet<String> {
    use std::collections::BTreeSet;
    let package = |name: &str| {
        meta["packages"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|p| p["name"].as_str() == Some(name))
    };
    let strings = |v: &serde_json::Value| -> Vec<String> {
        v.as_array()
            .into_iter()
            .flatten()
            .filter_map(|f| f.as_str().map(String::from))
            .collect()
    };
    // A package's features reachable from `start` (its own feature table, transitively).
    let closure = |table: &serde_json::Value, start: Vec<String>| -> Vec<String> {
        let mut seen: BTreeSet<String> = BTreeSet::new();
        let mut open = start;
        while let Some(f) = open.pop() {
            if seen.insert(f.clone()) {
                open.extend(strings(&table[&f]));
            }
        }
        seen.into_iter().collect()
    };
    let mut named = Vec::new();
    if let Some(p) = package(member) {
        for d in p["dependencies"].as_array().into_iter().flatten() {
            if d["name"].as_str() == Some("scene-core") {
                named.extend(strings(&d["features"]));
                if d["uses_default_features"].as_bool().unwrap_or(true) {
                    named.push("default".to_string());
                }
            }
        }
        let own = closure(&p["features"], vec!["default".to_string()]);
        named.extend(
            own.iter()
                .filter_map(|f| f.strip_prefix("scene-core/").map(String::from)),
        );
    }
    let core = package("scene-core").map(|p| &p["features"]);
    closure(core.unwrap_or(&serde_json::Value::Null), named)
        .into_iter()
        .filter(|f| f != "default" && !f.starts_with("dep:") && !f.contains('/'))
        .collect()
}

/// The features scene-core is built with in a `cargo tree -f '{p} [{f}]' --prefix none`
/// listing (the first scene-core line).
pub fn core_features_in_tree(tree: &str) -> std::collections::BTreeSet<String> {
    tree.lines()
        .find(|l| l.starts_with("scene-core "))
        .and_then(|l| l.rsplit_once('[')?.1.split_once(']').map(|(f, _)| f))
        .into_iter()
        .flat_map(|f| f.split(','))
        .filter(|f| !f.is_empty())
        .map(String::from)
        .collect()
}

/// Fails when a spoke's test build (`-e normal,dev`, its default features) turns on a
/// scene-core feature its manifest does not name, or pulls in what
/// [`TESTS_MUST_NOT_PULL`] bans.
pub fn test_build_features() -> Result<(), String> {
    let meta = workspace_metadata()?;
    for spoke in SPOKES {
        let tree = cargo_output(&[
            "tree",
            "-p",
            spoke,
            "-e",
            "normal,dev",
            "-f",
            "{p} [{f}]",
            "--prefix",
            "none",
        ])?;
        let named = named_core_features(&meta, spoke);
        let pulled = core_features_in_tree(&tree);
        let unnamed: Vec<&String> = pulled.difference(&named).collect();
        if !unnamed.is_empty() {
            return Err(format!(
                "{spoke}'s test build turns on scene-core feature(s) {unnamed:?} that its \
                 Cargo.toml does not name (it names {named:?})"
            ));
        }
        eprintln!("{spoke}'s test build: scene-core {pulled:?}, as named");
    }
    for (krate, banned) in TESTS_MUST_NOT_PULL {
        let tree = cargo_output(&["tree", "-p", krate, "-e", "normal,dev", "--prefix", "none"])?;
        let found = pulled_in(&tree, banned);
        if !found.is_empty() {
            return Err(format!(
                "{krate}'s test build pulls in {}",
                found.join(", ")
            ));
        }
        eprintln!(
            "{krate}'s test build pulls in none of {}",
            banned.join(", ")
        );
    }
    Ok(())
}

fn cargo_output(args: &[&str]) -> Result<String, String> {
    let out = Command::new(env!("CARGO"))
        .args(args)
        .output()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "`cargo {}` failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The crates of `banned` that a `cargo tree --prefix none` listing names.
pub fn pulled_in<'a>(tree: &str, banned: &[&'a str]) -> Vec<&'a str> {
    banned
        .iter()
        .copied()
        .filter(|b| {
            tree.lines()
                .any(|l| l.split_whitespace().next() == Some(*b))
        })
        .collect()
}

/// Builds each library crate alone (every target with its default features, the library
/// with none where it has features) and checks [`MUST_NOT_PULL`].
pub fn hub_costs() -> Result<(), String> {
    for (krate, banned) in MUST_NOT_PULL {
        let tree = cargo_output(&["tree", "-p", krate, "-e", "normal", "--prefix", "none"])?;
        let found = pulled_in(&tree, banned);
        if !found.is_empty() {
            return Err(format!(
                "{krate} with its default features pulls in {}",
                found.join(", ")
            ));
        }
        eprintln!("{krate} pulls in none of {}", banned.join(", "));
    }
    for (krate, has_features) in LIBRARIES {
        // Every target, tests and examples too: the features a crate names suffice for
        // its own tests (the workspace's test run unifies features and would not tell).
        cargo(&["check", "-p", krate, "--all-targets"])?;
        if has_features {
            cargo(&["check", "-p", krate, "--lib", "--no-default-features"])?;
        }
    }
    Ok(())
}

/// Each workspace member's declared `rust-version` against the highest one among its
/// normal and build dependencies (transitively): a member that declares less than a
/// dependency needs is named.
pub fn msrv_violations(meta: &serde_json::Value) -> Vec<String> {
    use std::collections::HashMap;
    let parse = |v: &serde_json::Value| -> Option<Vec<u32>> {
        // "1.88" and "1.88.0" are the same version: three components, missing ones zero.
        let mut parts: Vec<u32> = v
            .as_str()?
            .split('.')
            .map(|p| p.parse().unwrap_or(0))
            .collect();
        parts.resize(3, 0);
        Some(parts)
    };
    let packages: HashMap<&str, (&str, Option<Vec<u32>>)> = meta["packages"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|p| {
            Some((
                p["id"].as_str()?,
                (p["name"].as_str()?, parse(&p["rust_version"])),
            ))
        })
        .collect();
    let deps: HashMap<&str, Vec<&str>> = meta["resolve"]["nodes"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|n| {
            let id = n["id"].as_str()?;
            let ds = n["deps"]
                .as_array()
                .into_iter()
                .flatten()
                .filter(|d| {
                    d["dep_kinds"]
                        .as_array()
                        .into_iter()
                        .flatten()
                        .any(|k| matches!(k["kind"].as_str(), None | Some("build")))
                })
                .filter_map(|d| d["pkg"].as_str())
                .collect();
            Some((id, ds))
        })
        .collect();
    let mut violations = Vec::new();
    for member in meta["workspace_members"].as_array().into_iter().flatten() {
        let Some(member) = member.as_str() else {
            continue;
        };
        let Some((name, declared)) = packages.get(member) else {
            continue;
        };
        let mut seen = std::collections::HashSet::new();
        let mut stack = vec![member];
        let mut need: Option<(Vec<u32>, &str)> = None;
        while let Some(id) = stack.pop() {
            for d in deps.get(id).into_iter().flatten() {
                if seen.insert(*d) {
                    stack.push(d);
                    if let Some((dname, Some(v))) = packages.get(d)
                        && need.as_ref().is_none_or(|(n, _)| v > n)
                    {
                        need = Some((v.clone(), dname));
                    }
                }
            }
        }
        let Some((need, by)) = need else { continue };
        let show = |v: &[u32]| {
            format!("{}.{}", v[0], v[1])
                + &if v[2] > 0 {
                    format!(".{}", v[2])
                } else {
                    String::new()
                }
        };
        match declared {
            Some(d) if *d >= need => {}
            Some(d) => violations.push(format!(
                "{name} declares rust-version {} but its dependency {by} needs {}",
                show(d),
                show(&need)
            )),
            None => violations.push(format!(
                "{name} declares no rust-version; its dependency {by} needs {}",
                show(&need)
            )),
        }
    }
    violations
}

/// [`msrv_violations`] over this workspace.
pub fn msrv() -> Result<(), String> {
    let out = cargo_output(&["metadata", "--format-version", "1"])?;
    let meta: serde_json::Value =
        serde_json::from_str(&out).map_err(|e| format!("cargo metadata: {e}"))?;
    let v = msrv_violations(&meta);
    if v.is_empty() {
        eprintln!("every member's rust-version covers its dependencies'");
        Ok(())
    } else {
        Err(format!("rust-version too low:\n  {}", v.join("\n  ")))
    }
}

/// The workspace's members as `cargo metadata --no-deps` describes them (their manifests:
/// dependencies with kinds and features, feature tables).
fn workspace_metadata() -> Result<serde_json::Value, String> {
    let out = cargo_output(&["metadata", "--format-version", "1", "--no-deps"])?;
    serde_json::from_str(&out).map_err(|e| format!("cargo metadata: {e}"))
}

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

/// Builds the API documentation as docs.rs would (`cargo doc --no-deps`, every warning an
/// error), with the default features and with all features: an unresolved intra-doc link,
/// a link to a private item or an unclosed HTML tag fails. `manifest` is the workspace's
/// by default (a test points it at a crate of its own).
pub fn api_docs(manifest: Option<&std::path::Path>) -> Result<(), String> {
    for features in [None, Some("--all-features")] {
        let mut args = vec!["doc", "--no-deps", "--workspace"];
        args.extend(features);
        let manifest = manifest.map(|m| m.to_string_lossy().into_owned());
        if let Some(m) = &manifest {
            args.extend(["--manifest-path", m.as_str()]);
        }
        eprintln!("$ RUSTDOCFLAGS='-D warnings' cargo {}", args.join(" "));
        let status = Command::new(env!("CARGO"))
            .args(&args)
            .env("RUSTDOCFLAGS", "-D warnings")
            .status()
            .map_err(|e| format!("cannot run cargo: {e}"))?;
        if !status.success() {
            return Err(format!(
                "the API documentation warns (`cargo {}` with RUSTDOCFLAGS='-D warnings' \
                 failed, {status})",
                args.join(" ")
            ));
        }
    }
    Ok(())
}

/// Fails when a spoke names a sibling among its normal or build dependencies, or does not
/// depend on scene-core, or when a spoke or scene-core depends on a composition point.
pub fn dependency_rule() -> Result<(), String> {
    let violations = rule_violations(&workspace_metadata()?);
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
    msrv()?;
    hub_costs()?;
    test_build_features()?;
    let n = crate::shaders::validate_all(None)?;
    eprintln!("{n} shader(s) valid");
    api_docs(None)?;
    if with_tests {
        cargo(&["test", "--workspace"])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spoke names `reference` (which implies `rays`) for its tests and forwards `exr`
    /// from its default `cli` feature: those three are named; `gpu`, which a dependency
    /// keeping scene-core's defaults would turn on, is not.
    #[test]
    fn named_features_follow_implications_defaults_and_forwarding() {
        let meta = |uses_default: bool| {
            serde_json::json!({"packages": [
                {"name": "scene-core", "dependencies": [], "features": {
                    "default": ["gpu", "reference"], "gpu": ["dep:wgpu"], "rays": ["dep:obvhs"],
                    "reference": ["rays"], "exr": ["dep:exr"]}},
                {"name": "imalyzer", "features": {"default": ["cli"], "cli": ["dep:clap", "scene-core/exr"]},
                 "dependencies": [
                    {"name": "scene-core", "kind": null, "features": [], "uses_default_features": false},
                    {"name": "scene-core", "kind": "dev", "features": ["reference"], "uses_default_features": uses_default}]}
            ]})
        };
        let names = |m: &serde_json::Value| -> Vec<String> {
            named_core_features(m, "imalyzer").into_iter().collect()
        };
        assert_eq!(names(&meta(false)), ["exr", "rays", "reference"]);
        assert_eq!(names(&meta(true)), ["exr", "gpu", "rays", "reference"]);
        // A tree whose scene-core carries gpu: unnamed without the defaults.
        let tree = "imalyzer v0.1.0 (/w/crates/imalyzer) [cli,default]\n\
                    scene-core v0.1.0 (/w/crates/scene-core) [exr,gpu,rays,reference]\n";
        let pulled = core_features_in_tree(tree);
        let named = named_core_features(&meta(false), "imalyzer");
        assert_eq!(
            pulled.difference(&named).collect::<Vec<_>>(),
            [&"gpu".to_string()]
        );
        assert!(core_features_in_tree("scene-core v0.1.0 (/w) []\n").is_empty());
    }

    /// The documentation check fails on a crate whose docs link to nothing, and passes once
    /// the link is plain text.
    #[test]
    fn api_docs_fail_on_a_broken_intra_doc_link() {
        let dir = std::env::temp_dir().join(format!("api-docs-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("src")).unwrap();
        std::fs::write(
            dir.join("Cargo.toml"),
            "[package]\nname = \"docs-probe\"\nversion = \"0.1.0\"\nedition = \"2021\"\n\
             [workspace]\n",
        )
        .unwrap();
        let lib = dir.join("src/lib.rs");
        std::fs::write(&lib, "//! See [`Nowhere`].\npub fn f() {}\n").unwrap();
        let manifest = dir.join("Cargo.toml");
        let e = api_docs(Some(&manifest)).unwrap_err();
        assert!(e.contains("API documentation warns"), "{e}");
        std::fs::write(&lib, "//! See `Nowhere`.\npub fn f() {}\n").unwrap();
        api_docs(Some(&manifest)).unwrap();
        std::fs::remove_dir_all(&dir).ok();
    }

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

    /// A member `m` (declaring `declared`) depending on `a` (normal) which depends on `b`
    /// (normal or dev), with `b` declaring 1.90.
    fn msrv_meta(declared: Option<&str>, b_kind: Option<&str>) -> serde_json::Value {
        let dep = |pkg: &str, kind: Option<&str>| serde_json::json!({"pkg": pkg, "dep_kinds": [{"kind": kind}]});
        serde_json::json!({
            "packages": [
                {"id": "m", "name": "m", "rust_version": declared},
                {"id": "a", "name": "a", "rust_version": "1.80"},
                {"id": "b", "name": "b", "rust_version": "1.90"},
            ],
            "workspace_members": ["m"],
            "resolve": {"nodes": [
                {"id": "m", "deps": [dep("a", None)]},
                {"id": "a", "deps": [dep("b", b_kind)]},
                {"id": "b", "deps": []},
            ]},
        })
    }

    #[test]
    fn a_rust_version_below_a_transitive_dependency_is_named() {
        assert!(msrv_violations(&msrv_meta(Some("1.90"), None)).is_empty());
        assert!(msrv_violations(&msrv_meta(Some("1.95.1"), None)).is_empty());
        assert!(msrv_violations(&msrv_meta(Some("1.90.0"), None)).is_empty());
        let v = msrv_violations(&msrv_meta(Some("1.88"), None));
        assert_eq!(
            v,
            ["m declares rust-version 1.88 but its dependency b needs 1.90"]
        );
        assert_eq!(msrv_violations(&msrv_meta(None, None)).len(), 1);
        // Build dependencies count, dev-dependencies do not.
        assert_eq!(
            msrv_violations(&msrv_meta(Some("1.88"), Some("build"))).len(),
            1
        );
        assert!(msrv_violations(&msrv_meta(Some("1.88"), Some("dev"))).is_empty());
    }

    #[test]
    fn a_banned_crate_in_a_tree_listing_is_found_by_its_name_only() {
        let tree = "imalyzer v0.1.0 (/w/crates/imalyzer)\nscene-core v0.1.0\nwgpu v30.0.1\nwgpu-core v30.0.1\n";
        assert_eq!(pulled_in(tree, &["wgpu", "gltf"]), ["wgpu"]);
        assert!(pulled_in("wgpu-core v30.0.1\ngltf-json v1.4.1\n", &["wgpu", "gltf"]).is_empty());
    }
}
