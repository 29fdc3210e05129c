//! The command-line tools on hostile files: `xtask reference`, `xtask experiment --scene
//! FILE` (and `--cameras`) and `imalyzer` exit non-zero with a message naming the file and
//! the fault, never a panic (exit 101) or an abort, each run under a 1 GiB address-space
//! cap so that an allocation made from a file's word fails the test.

use std::path::{Path, PathBuf};
use std::process::Command;

use golden_tests::hostile;

const CAP_BYTES: u64 = 1 << 30;

/// Runs `exe args` under the cap; returns (exit code, stderr + stdout).
fn run_capped(exe: &Path, args: &[&str]) -> (Option<i32>, String) {
    let out = golden_tests::child::capped_command(exe, CAP_BYTES)
        .args(args)
        .env("CI", "1")
        .output()
        .expect("run under sh");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    (out.status.code(), text)
}

/// Expects a clean failure (exit 1) whose message holds every one of `needles`.
fn fails_cleanly(exe: &Path, args: &[&str], needles: &[&str]) {
    let (code, text) = run_capped(exe, args);
    assert_eq!(code, Some(1), "{args:?} exited {code:?}:\n{text}");
    assert!(!text.contains("panicked"), "{args:?} panicked:\n{text}");
    for n in needles {
        assert!(text.contains(n), "{args:?}: message lacks '{n}':\n{text}");
    }
}

struct Files {
    dir: PathBuf,
    cases: Vec<(PathBuf, &'static str)>,
}

/// Each hostile scene file (in `DIR/scene/`, with `DIR/outside.bin` beside that folder)
/// with a phrase its error must contain.
fn hostile_scenes() -> Files {
    let root = hostile::scratch_dir("cli");
    hostile::write(&root, "outside.bin", &hostile::triangle_buffer());
    let dir = root.join("scene");
    std::fs::create_dir_all(&dir).unwrap();
    let w = |name: &str, bytes: Vec<u8>| hostile::write(&dir, name, &bytes);
    let cases = vec![
        (
            w("camera.gltf", hostile::camera_type_mismatch()),
            "camera 0",
        ),
        (
            w("sparse.gltf", hostile::sparse_instanced(1 << 26, 4)),
            "vertices",
        ),
        (
            w(
                "texture.gltf",
                hostile::triangle_with_texture(&hostile::png_bomb(16384)),
            ),
            "image-bytes",
        ),
        (
            w(
                "passwd.gltf",
                hostile::triangle_with_buffer_uri("file:///etc/passwd"),
            ),
            "refused URI 'file:///etc/passwd'",
        ),
        (
            w(
                "zero.gltf",
                hostile::triangle_with_buffer_uri("file:///dev/zero"),
            ),
            "refused URI 'file:///dev/zero'",
        ),
        (
            w(
                "up.gltf",
                hostile::triangle_with_buffer_uri("../outside.bin"),
            ),
            "outside the scene's folder",
        ),
        (w("empty.gltf", hostile::camera_only()), "has no geometry"),
        (
            w("far.gltf", hostile::triangle_far_away(1e7)),
            "move the scene to the origin",
        ),
    ];
    std::fs::write(
        dir.parent().unwrap().join("outside.bin"),
        hostile::triangle_buffer(),
    )
    .ok();
    Files { dir, cases }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn xtask_reference_and_experiment_refuse_hostile_scenes() {
    let xtask = Path::new(env!("CARGO_BIN_EXE_xtask"));
    let files = hostile_scenes();
    let out = files.dir.join("out");
    for (file, phrase) in &files.cases {
        let name = file.file_name().unwrap().to_str().unwrap();
        fails_cleanly(
            xtask,
            &[
                "reference",
                "--scene",
                s(file),
                "--width",
                "8",
                "--height",
                "8",
                "--spp",
                "1",
                "--out",
                s(&out),
            ],
            &[name, phrase],
        );
        fails_cleanly(
            xtask,
            &[
                "experiment",
                "--scene",
                s(file),
                "--spp",
                "1",
                "--size",
                "8x8",
                "--out",
                s(&out),
            ],
            &[name, phrase],
        );
    }
    // Nothing half-written.
    assert!(!out.exists() || std::fs::read_dir(&out).unwrap().next().is_none());
    std::fs::remove_dir_all(&files.dir).ok();
}

#[test]
fn xtask_experiment_refuses_bad_camera_lists() {
    let xtask = Path::new(env!("CARGO_BIN_EXE_xtask"));
    let dir = hostile::scratch_dir("cli-cams");
    for (i, (what, text)) in hostile::bad_camera_lists().into_iter().enumerate() {
        let file = hostile::write(&dir, &format!("cams{i}.json"), text.as_bytes());
        let arg = format!("cornell={}", file.display());
        let name = format!("cams{i}.json");
        let (code, out) = run_capped(
            xtask,
            &[
                "experiment",
                "--scene",
                "cornell",
                "--cameras",
                &arg,
                "--spp",
                "1",
                "--size",
                "8x8",
                "--out",
                s(&dir.join("out")),
            ],
        );
        assert_eq!(code, Some(1), "{what}: {out}");
        assert!(
            out.contains(&name) && out.contains("degenerate camera"),
            "{what}: {out}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `imalyzer`, built beside this crate's binary by `cargo test --workspace`.
fn imalyzer() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_BIN_EXE_xtask"))
        .with_file_name(format!("imalyzer{}", std::env::consts::EXE_SUFFIX));
    p.exists().then_some(p)
}

#[test]
fn imalyzer_refuses_image_bombs() {
    let Some(imalyzer) = imalyzer() else {
        eprintln!("imalyzer is not built (cargo test --workspace builds it); not tested here");
        return;
    };
    let dir = hostile::scratch_dir("cli-imalyzer");
    let good = hostile::write(&dir, "good.exr", &hostile::small_exr(4, 4));
    let exr_bomb = hostile::write(&dir, "bomb.exr", &hostile::exr_bomb(100_000, 100_000));
    let png_bomb = hostile::write(&dir, "bomb.png", &hostile::png_bomb(16384));
    let good_png = dir.join("good.png");
    scene_core::Image::read(&good)
        .unwrap()
        .write_png(&good_png, 0.0)
        .unwrap();
    fails_cleanly(
        &imalyzer,
        &["compare", s(&good), s(&exr_bomb)],
        &["bomb.exr", "image-bytes"],
    );
    fails_cleanly(
        &imalyzer,
        &["compare", s(&png_bomb), s(&good_png)],
        &["bomb.png", "image-bytes"],
    );
    // A decoder panic inside the exr crate (an abort before) is a message and exit 1; the
    // image is 32 x 32 so compare it with one of its size.
    let b44 = hostile::write(&dir, "b44.exr", &hostile::exr_b44_overflow());
    let good32 = hostile::write(&dir, "good32.exr", &hostile::small_exr(32, 32));
    fails_cleanly(
        &imalyzer,
        &["compare", s(&good32), s(&b44)],
        &["b44.exr", "decoder"],
    );
    // ztest with a corrupted variance image.
    let (code, text) = run_capped(
        &imalyzer,
        &[
            "ztest",
            s(&good),
            s(&good),
            "--variance",
            s(&exr_bomb),
            "--spp",
            "4",
        ],
    );
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("bomb.exr") && text.contains("image-bytes"),
        "{text}"
    );
    // The budget is the caller's: DIFFUSE_GI_BUDGET can lower it.
    let out = Command::new(&imalyzer)
        .args(["compare", s(&good), s(&good)])
        .env("DIFFUSE_GI_BUDGET", "image-bytes=100")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("image-bytes budget of 100 bytes"));
    std::fs::remove_dir_all(&dir).ok();
}

/// Every number a user sets has a stated range, checked before any work: a huge, zero or
/// NaN value exits 1 at once naming the argument and its range (before, several aborted on
/// a huge allocation, hung, or wrote a black image with exit 0).
#[test]
fn numbers_out_of_range_are_refused_before_any_work() {
    let xtask = Path::new(env!("CARGO_BIN_EXE_xtask"));
    let dir = hostile::scratch_dir("cli-ranges");
    let out = dir.join("out");
    let o = s(&out);
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["relight", "--subpixels", "4000000000", "--out", o],
            "--subpixels = 4000000000 is outside its range [1, 256]",
        ),
        (
            vec!["relight", "--emitter-rays", "4000000000", "--out", o],
            "--emitter-rays",
        ),
        (
            vec![
                "relight",
                "--form-factors",
                "hemicube",
                "--hemicube-resolution",
                "1",
                "--out",
                o,
            ],
            "--hemicube-resolution = 1",
        ),
        (
            vec!["relight", "--exposure", "NaN", "--out", o],
            "--exposure = NaN",
        ),
        (
            vec!["relight", "--cluster-radius", "NaN", "--out", o],
            "--cluster-radius = NaN",
        ),
        (
            vec!["relight", "--cluster-radius", "17", "--out", o],
            "--cluster-radius = 17",
        ),
        (
            vec!["relight", "--solve-groups-above", "NaN", "--out", o],
            "--solve-groups-above = NaN",
        ),
        (
            vec!["relight", "--solve-groups-above=-1", "--out", o],
            "--solve-groups-above = -1",
        ),
        (vec!["ibrr", "--irpls", "0", "--out", o], "--irpls = 0"),
        (
            vec!["reference", "--exposure", "NaN", "--out", o],
            "--exposure = NaN",
        ),
        (
            vec!["reference", "--width", "100000", "--out", o],
            "--width = 100000",
        ),
        (
            vec!["experiment", "--views", "0", "--out", o],
            "--views = 0 is outside its range [1, 1000]",
        ),
        (
            vec!["experiment", "--views", "1000000000", "--out", o],
            "--views = 1000000000",
        ),
        (
            vec!["experiment", "--sequence-frames", "1000000000", "--out", o],
            "--sequence-frames",
        ),
        (
            vec!["experiment", "--repeats", "0", "--out", o],
            "--repeats = 0",
        ),
        (
            vec!["experiment", "--still-repeats", "101", "--out", o],
            "--still-repeats = 101",
        ),
        (
            vec!["experiment", "--shard", "3/2", "--out", o],
            "--shard takes K/N with 1 <= K <= N <= 4096, got '3/2'",
        ),
        (
            vec!["experiment", "--shard", "0/2", "--out", o],
            "--shard takes K/N",
        ),
        (
            vec!["experiment", "--preset", "huge", "--out", o],
            "unknown preset 'huge' (known: default, full, hd)",
        ),
        (vec!["experiment", "merge", o, "--out", o], "results.json"),
        (
            vec!["bench", "reference", "--threads", "0"],
            "--threads = 0",
        ),
        (vec!["fuzz", "--seconds", "0"], "--seconds = 0"),
    ];
    for (args, says) in &cases {
        let start = std::time::Instant::now();
        fails_cleanly(xtask, args, &[says]);
        assert!(
            start.elapsed() < std::time::Duration::from_secs(20),
            "{args:?} took {:?}",
            start.elapsed()
        );
    }
    if let Some(imalyzer) = imalyzer() {
        let good = hostile::write(&dir, "good.exr", &hostile::small_exr(4, 4));
        fails_cleanly(
            &imalyzer,
            &["compare", s(&good), s(&good), "--exposures", "100000000"],
            &["HDR-FLIP exposures = 100000000 is outside its range [1, 64]"],
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// An output folder that cannot be made fails before the long work, naming the folder.
#[test]
fn an_output_folder_that_cannot_be_made_fails_first() {
    let xtask = Path::new(env!("CARGO_BIN_EXE_xtask"));
    let dir = hostile::scratch_dir("cli-out");
    let file = hostile::write(&dir, "a-file", b"x");
    let inside = file.join("out");
    for cmd in ["reference", "relight", "ibrr", "experiment"] {
        fails_cleanly(
            xtask,
            &[cmd, "--out", s(&inside)],
            &["output folder", "a-file"],
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
