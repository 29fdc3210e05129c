//! Helpers shared by relight-pr's integration tests.

use glam::Vec3;

/// The largest difference between `a` and `b` over the largest value of `b`.
pub fn max_relative(a: &[Vec3], b: &[Vec3]) -> f32 {
    let peak = b.iter().map(|v| v.max_element()).fold(0.0f32, f32::max);
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).abs().max_element())
        .fold(0.0f32, f32::max)
        / peak
}
