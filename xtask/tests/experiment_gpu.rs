//! `xtask experiment --gpu`: each method is hosted on the frame contract over a G-buffer
//! drawn on the GPU, its frame timed on the device apart from the harness, and the
//! references and the equal-error ladder come from the GPU path tracer.

mod common;
use common::xtask;

#[test]
fn gpu_main_job_times_the_method_apart_from_the_harness() {
    if scene_core::testing::gpu_test_context().is_none() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("xtask-experiment-gpu-{}", std::process::id()));
    let o = xtask()
        .args([
            "experiment",
            "--gpu",
            "--scene",
            "cornell",
            "--size",
            "24x18",
        ])
        .args(["--spp", "32", "--views", "1", "--techniques", "dl,isr-24"])
        .args([
            "--repeats",
            "3",
            "--still-repeats",
            "1",
            "--sequence-frames",
            "0",
        ])
        .args(["--bounces", "1", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(dir.join("results.json")).unwrap();
    let r: serde_json::Value = serde_json::from_str(&text).unwrap();
    let renderer = r["settings"]["reference_renderer"].as_str().unwrap();
    assert!(renderer.contains("GPU path tracer"), "{renderer}");
    let view = &r["views"][0];
    let ladder = view["references"][0]["ladder"].as_array().unwrap();
    assert!(!ladder.is_empty(), "no ladder rungs");
    for rung in ladder {
        assert!(rung["seconds"].as_f64().unwrap() > 0.0, "{rung}");
    }
    for t in view["techniques"].as_array().unwrap() {
        let label = t["label"].as_str().unwrap();
        let clock = t["clock"].as_str().unwrap_or("");
        assert!(
            clock == "GPU timestamps" || clock.starts_with("wall clock"),
            "{label}: clock '{clock}'"
        );
        // The harness's wall time of the same frames holds the method's: G-buffer, method,
        // readback; per frame at least as long, so the medians are ordered too.
        let method = t["frame"]["median_s"].as_f64().unwrap();
        let harness = t["harness"]["median_s"].as_f64().unwrap();
        assert!(
            method > 0.0 && method <= harness,
            "{label}: method {method} s, harness {harness} s"
        );
        assert_eq!(t["harness"]["repeats"].as_u64(), Some(3), "{label}");
    }
    let report = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(
        report.contains("harness wall (ms)"),
        "the report names the harness time"
    );
    std::fs::remove_dir_all(&dir).ok();
}
