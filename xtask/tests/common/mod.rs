//! Helpers shared by the CLI tests (each test file uses some of them).
#![allow(dead_code)]

use std::process::Command;

/// The built xtask binary, with `CI` set so that progress bars stay hidden.
pub fn xtask() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_xtask"));
    c.env("CI", "1");
    c
}

/// Runs `command` (an xtask command writing into `out`), asserts it succeeded, and reads
/// back the `summary.json` and the `<stem>.exr` it wrote there.
pub fn run_with_summary(
    mut command: Command,
    out: &std::path::Path,
    stem: &str,
) -> (serde_json::Value, scene_core::Image) {
    let o = command.arg("--out").arg(out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let image = scene_core::Image::read(&out.join(format!("{stem}.exr"))).unwrap();
    (summary, image)
}
