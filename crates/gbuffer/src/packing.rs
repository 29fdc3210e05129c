//! The thesis' 8-bit normal packing (eq. 22), kept as a measured alternative.
//!
//! The thesis stores each normal component in 8 bits, `c_packed = round(255 (c + 1) / 2)`,
//! unpacked as `c = 2 c_packed / 255 - 1` (eq. 22). The G-buffers of this crate keep
//! normals as 32-bit floats instead (scene-core's [`GpuGBuffer::NORMAL_FORMAT`] is
//! `Rgba32Float`): the packing costs up to 0.38 degrees of normal direction and leaves
//! unpacked normals up to 0.63 % off unit length unless renormalised (figures from
//! [`max_packing_error`] over 20 000 directions, tested). That is below what ISR's
//! `cos` terms would show in most pixels, but it is a systematic error at grazing angles
//! (a 0.38 degree tilt changes `cos` by 0.0066 at 89 degrees, 38 % of its value) and the
//! CPU/GPU agreement tests compare normals to 1e-4, which 8-bit normals cannot meet; the
//! 12 bytes per pixel it would save are not this project's bottleneck.
//!
//! [`GpuGBuffer::NORMAL_FORMAT`]: scene_core::gpu::GpuGBuffer::NORMAL_FORMAT

use glam::Vec3;

/// Packs a unit normal into three bytes (eq. 22 inverted, rounded to nearest).
pub fn pack_normal_unorm8(n: Vec3) -> [u8; 3] {
    n.to_array()
        .map(|c| ((c.clamp(-1.0, 1.0) + 1.0) * 0.5 * 255.0).round() as u8)
}

/// Unpacks three bytes into a normal by eq. 22, `2 c / 255 - 1` (not renormalised).
pub fn unpack_normal_unorm8(p: [u8; 3]) -> Vec3 {
    Vec3::from_array(p.map(|c| 2.0 * c as f32 / 255.0 - 1.0))
}

/// The worst angular error (degrees) and the worst deviation from unit length of eq. 22
/// over `samples` normals spread evenly over the sphere (a Fibonacci lattice).
pub fn max_packing_error(samples: u32) -> (f32, f32) {
    let golden = std::f32::consts::PI * (3.0 - 5.0f32.sqrt());
    let mut worst_angle = 0.0f32;
    let mut worst_length = 0.0f32;
    for i in 0..samples {
        let y = 1.0 - 2.0 * (i as f32 + 0.5) / samples as f32;
        let r = (1.0 - y * y).max(0.0).sqrt();
        let phi = golden * i as f32;
        let n = Vec3::new(r * phi.cos(), y, r * phi.sin()).normalize();
        let u = unpack_normal_unorm8(pack_normal_unorm8(n));
        let cos = (u.normalize().dot(n) as f64).clamp(-1.0, 1.0);
        worst_angle = worst_angle.max(cos.acos().to_degrees() as f32);
        worst_length = worst_length.max((u.length() - 1.0).abs());
    }
    (worst_angle, worst_length)
}
