//! The engine examples of the three methods (`crates/<crate>/examples/*_engine.rs`), run as
//! a user runs them: each goes through its method's `GpuFrame` on scene-core's
//! `ExampleHost`, follows a light change and prints the GPU objects its steady-state frames
//! created, which must be none.
//!
//! `cargo test --workspace` builds the examples beside the test binaries
//! (`target/<profile>/examples/`) before any test runs; a run that filters to this test
//! alone does not, and the test then fails naming the command that builds them.

use std::path::PathBuf;
use std::process::Command;

/// The line `ObjectCounts::steady_state_line` prints when a frame created nothing.
const NOTHING_CREATED: &str =
    "steady-state frame: 0 buffers, 0 textures, 0 bind groups, 0 pipelines created";

/// The example binary `name`, as cargo places it for this test's profile.
fn example(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the test binary's path");
    // target/<profile>/deps/<test> -> target/<profile>/examples/<name>
    let profile_dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("the test binary lies in target/<profile>/deps");
    profile_dir
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX))
}

fn runs_with_nothing_created_per_frame(package: &str, name: &str) {
    if scene_core::testing::gpu_test_context().is_none() {
        return;
    }
    let path = example(name);
    assert!(
        path.exists(),
        "{} is not built: `cargo test --workspace` (or `cargo build -p {package} --examples`) builds it",
        path.display()
    );
    let out = Command::new(&path).output().expect("the example starts");
    let stdout = String::from_utf8_lossy(&out.stdout);
    eprintln!("{stdout}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{name} failed: {}", out.status);
    // The host's light cycle checked that the frame followed the light change (it fails
    // the example otherwise) and printed one mean per frame through the method's name.
    assert_eq!(stdout.matches("mean radiance").count(), 4, "{name}");
    assert!(
        stdout.lines().any(|l| l == NOTHING_CREATED),
        "{name} created GPU objects in a steady-state frame"
    );
}

#[test]
fn the_isr_engine_example_creates_nothing_per_frame() {
    runs_with_nothing_created_per_frame("isr", "isr_engine");
}

#[test]
fn the_relighting_engine_example_creates_nothing_per_frame() {
    runs_with_nothing_created_per_frame("relight-pr", "relight_engine");
}

#[test]
fn the_ibrr_engine_example_creates_nothing_per_frame() {
    runs_with_nothing_created_per_frame("ibrr-ldc", "ibrr_engine");
}
