//! The k x n solution in the layout eq. 1 streams through, on the CPU and the GPU alike.
//!
//! A relight frame reads every stored value once: `B_j = base + sum_m d_m D_jm + i_m I_jm`
//! (eq. 1 with each source's direct and indirect parts scaled apart). The values are
//! stored element-major, and for each element source by source the six scalars
//! `D_jm.rgb, I_jm.rgb`, as 32-bit words: f32 bits ([`Precision::F32`], 24 bytes per element
//! and source) or two IEEE half floats per word ([`Precision::F16`], 12 bytes; relative
//! rounding 2^-11, range up to 65504 in the solution's units). The same words are what
//! [`crate::gpu`] uploads, so the two backends read the same bits.

use glam::Vec3;
use rayon::prelude::*;

/// Storage precision of a [`Packed`] solution.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precision {
    /// 32-bit floats (exact copies of the solution).
    #[default]
    F32,
    /// 16-bit floats: half the memory and the bandwidth of a relight frame. Values beyond
    /// 65504 saturate to the largest half ([`Packed::saturated`] counts them, and
    /// [`crate::gpu::GpuRelight::new`] refuses such a solution); scale the scene's units if
    /// they come near it.
    F16,
}

impl Precision {
    /// 32-bit words per element and source.
    pub fn words(self) -> usize {
        match self {
            Precision::F32 => 6,
            Precision::F16 => 3,
        }
    }
}

/// Per-item (element or vertex), per-source direct and indirect irradiance, packed.
#[derive(Clone, Debug, PartialEq)]
pub struct Packed {
    /// Items (elements or welded vertices).
    pub n: usize,
    /// Sources.
    pub k: usize,
    /// Storage precision.
    pub precision: Precision,
    /// `n * k * precision.words()` words.
    pub words: Vec<u32>,
    /// Values that f16 storage saturated at 65504 (0 at f32).
    pub saturated: usize,
}

fn half_bits(x: f32) -> u32 {
    // Saturate instead of overflowing to infinity (a NaN must not spread from here).
    let x = if x.is_finite() {
        x.clamp(-65504.0, 65504.0)
    } else {
        0.0
    };
    half::f16::from_f32(x).to_bits() as u32
}

fn half_value(bits: u32) -> f32 {
    half::f16::from_bits(bits as u16).to_f32()
}

impl Packed {
    /// Packs `direct` and `indirect` (item-major, `j * k + m`, the layout of
    /// [`crate::Solution`]).
    pub fn new(direct: &[Vec3], indirect: &[Vec3], k: usize, precision: Precision) -> Self {
        let n = direct.len().checked_div(k).unwrap_or(0);
        let w = precision.words();
        let mut words = vec![0u32; n * k * w];
        words
            .par_chunks_mut(w)
            .zip(direct.par_iter().zip(indirect.par_iter()))
            .for_each(|(out, (d, i))| {
                let v = [d.x, d.y, d.z, i.x, i.y, i.z];
                match precision {
                    Precision::F32 => {
                        for (o, x) in out.iter_mut().zip(v) {
                            *o = x.to_bits();
                        }
                    }
                    Precision::F16 => {
                        for (c, o) in out.iter_mut().enumerate() {
                            *o = half_bits(v[2 * c]) | (half_bits(v[2 * c + 1]) << 16);
                        }
                    }
                }
            });
        let saturated = if precision == Precision::F16 {
            direct
                .par_iter()
                .chain(indirect.par_iter())
                .map(|v| {
                    v.to_array()
                        .iter()
                        .filter(|x| x.is_finite() && x.abs() > 65504.0)
                        .count()
                })
                .sum()
        } else {
            0
        };
        Self {
            n,
            k,
            precision,
            words,
            saturated,
        }
    }

    /// Bytes stored.
    pub fn bytes(&self) -> u64 {
        self.words.len() as u64 * 4
    }

    /// The six scalars of item `j`, source `m`, as stored.
    pub fn get(&self, j: usize, m: usize) -> (Vec3, Vec3) {
        let w = self.precision.words();
        let s = &self.words[(j * self.k + m) * w..(j * self.k + m + 1) * w];
        let v: [f32; 6] = match self.precision {
            Precision::F32 => std::array::from_fn(|c| f32::from_bits(s[c])),
            Precision::F16 => std::array::from_fn(|c| half_value(s[c / 2] >> (16 * (c % 2)))),
        };
        (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]))
    }

    /// Eq. 1 for every item: `base + sum_m d_m D_jm + i_m I_jm`, `factors[m] = (d_m, i_m)`
    /// (RGB). Parallel over items; each thread streams its items' words once.
    pub fn relight(&self, factors: &[(Vec3, Vec3)], base: Vec3) -> Vec<Vec3> {
        let mut out = vec![Vec3::ZERO; self.n];
        self.relight_into(factors, base, &mut out);
        out
    }

    /// [`Packed::relight`] into `out` (length `n`), allocating nothing.
    pub fn relight_into(&self, factors: &[(Vec3, Vec3)], base: Vec3, out: &mut [Vec3]) {
        let (k, w) = (self.k, self.precision.words());
        if k == 0 {
            out.fill(base);
            return;
        }
        const CHUNK: usize = 1024;
        out.par_chunks_mut(CHUNK)
            .zip(self.words.par_chunks(CHUNK * k * w))
            .for_each(|(out, words)| match self.precision {
                Precision::F32 => {
                    for (o, item) in out.iter_mut().zip(words.chunks_exact(k * w)) {
                        let mut e = base;
                        for (s, (d, i)) in item.chunks_exact(6).zip(factors) {
                            let v = |c: usize| f32::from_bits(s[c]);
                            e +=
                                Vec3::new(v(0), v(1), v(2)) * *d + Vec3::new(v(3), v(4), v(5)) * *i;
                        }
                        *o = e;
                    }
                }
                Precision::F16 => {
                    // Decode the chunk's halves with the slice conversion (hardware F16C
                    // where the CPU has it, detected at run time), then sum as f32. A word
                    // holds value 2c in its low half: on a little-endian machine that is
                    // the first u16 of the pair.
                    let halves: &[u16] = bytemuck::cast_slice(words);
                    let mut v = vec![0.0f32; halves.len()];
                    half::slice::HalfFloatSliceExt::convert_to_f32_slice(
                        bytemuck::cast_slice::<u16, half::f16>(halves),
                        &mut v,
                    );
                    for (o, item) in out.iter_mut().zip(v.chunks_exact(6 * k)) {
                        let mut e = base;
                        for (s, (d, i)) in item.chunks_exact(6).zip(factors) {
                            e +=
                                Vec3::new(s[0], s[1], s[2]) * *d + Vec3::new(s[3], s[4], s[5]) * *i;
                        }
                        *o = e;
                    }
                }
            });
    }
}
