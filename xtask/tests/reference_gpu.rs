//! `xtask reference --gpu` against `xtask reference`: the same scene, camera, size and
//! bounce limit traced by the GPU path tracer and the CPU one give the same image mean
//! within the standard error their variance images state.

mod common;
use common::xtask;

fn mean_and_variance(dir: &std::path::Path) -> (f64, f64, usize) {
    let image = scene_core::Image::read(&dir.join("cornell.exr")).unwrap();
    let var = scene_core::Image::read(&dir.join("cornell.variance.exr")).unwrap();
    let n = image.pixels.len();
    let mean = image
        .pixels
        .iter()
        .map(|p| f64::from(p.element_sum()))
        .sum::<f64>()
        / n as f64;
    // Channels summed per pixel: at most fully correlated, so 3 x the sum of variances.
    let v = var
        .pixels
        .iter()
        .map(|p| 3.0 * f64::from(p.element_sum()))
        .sum::<f64>();
    (mean, v, n)
}

#[test]
fn reference_on_the_gpu_agrees_with_the_cpu() {
    if scene_core::testing::gpu_test_context().is_none() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("xtask-reference-gpu-{}", std::process::id()));
    let spp = 512;
    for (sub, extra) in [("cpu", None), ("gpu", Some("--gpu"))] {
        let o = xtask()
            .args([
                "reference",
                "--scene",
                "cornell",
                "--width",
                "32",
                "--height",
                "24",
            ])
            .args(["--spp", &spp.to_string(), "--bounces", "1", "--out"])
            .arg(dir.join(sub))
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (mc, vc, n) = mean_and_variance(&dir.join("cpu"));
    let (mg, vg, _) = mean_and_variance(&dir.join("gpu"));
    let se = ((vc + vg) / f64::from(spp)).sqrt() / n as f64;
    eprintln!("image mean CPU {mc:.5}, GPU {mg:.5}, standard error {se:.5}");
    assert!(se < 0.015 * mc, "too noisy to test: {se} for {mc}");
    assert!((mg - mc).abs() < 4.0 * se, "CPU {mc}, GPU {mg}, se {se}");
    std::fs::remove_dir_all(&dir).ok();
}
