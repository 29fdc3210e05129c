//! Sampling: a seeded RNG, hashing for per-pixel seeds, scrambled Halton, R2, the
//! cosine-weighted hemisphere and uniform points on triangles.
//!
//! Everything is a pure function of explicit seeds, so results do not depend on the thread
//! that draws them.

use glam::{Vec2, Vec3};

use crate::view::orthonormal_basis;

/// Mixes a 64-bit value (SplitMix64 finaliser). Good avalanche; used to derive seeds.
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Combines a seed with two stream indices into a new well-mixed seed.
pub fn hash_seed(seed: u64, a: u64, b: u64) -> u64 {
    mix64(mix64(mix64(seed ^ 0x9e37_79b9_7f4a_7c15).wrapping_add(a)).wrapping_add(b))
}

/// A small, fast, seeded generator (PCG-XSH-RR 64/32).
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

impl Rng {
    /// A generator for `seed` on stream `stream`.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Rng {
            state: 0,
            inc: (mix64(stream) << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(mix64(seed));
        rng.next_u32();
        rng
    }

    /// The next 32 random bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// A uniform float in [0, 1).
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// A uniform double in [0, 1) with 53 random bits.
    pub fn next_f64(&mut self) -> f64 {
        let bits = ((self.next_u32() as u64) << 21) ^ (self.next_u32() as u64 >> 11);
        bits as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Two uniform floats in [0, 1).
    pub fn next_vec2(&mut self) -> Vec2 {
        Vec2::new(self.next_f32(), self.next_f32())
    }

    /// A uniform integer in `0..n` (n > 0), by Lemire's multiply-shift.
    pub fn below(&mut self, n: u32) -> u32 {
        ((self.next_u32() as u64 * n as u64) >> 32) as u32
    }
}

/// The first primes, bases of the Halton dimensions.
const PRIMES: [u32; 16] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53];

/// Scrambled Halton sequence: dimension `dim` (< 16) uses the radical inverse in the
/// `dim`-th prime base with random digit scrambling (each digit position gets its own
/// seeded shift modulo the base, applied to all digit positions down to f32 precision so the
/// implied trailing zeros are scrambled too). The unscrambled sequence is `seed = None`.
/// Digits below 1e-9 are not computed, so dimension `d` repeats with period
/// `base^k` where `base^-k < 1e-9` (2^30 points in base 2, far beyond f32 resolution).
pub fn halton(index: u64, dim: usize, seed: Option<u64>) -> f32 {
    let base = PRIMES[dim % PRIMES.len()] as u64;
    let inv_base = 1.0 / base as f64;
    let mut n = index;
    let mut inv = inv_base;
    let mut value = 0.0f64;
    let mut level = 0u64;
    // Digits until the contribution falls below f32 resolution.
    while inv > 1e-9 {
        let digit = n % base;
        let d = match seed {
            Some(s) => (digit + hash_seed(s, dim as u64, level) % base) % base,
            None => digit,
        };
        value += d as f64 * inv;
        n /= base;
        inv *= inv_base;
        level += 1;
        if seed.is_none() && n == 0 {
            break;
        }
    }
    (value as f32).min(1.0 - f32::EPSILON / 2.0)
}

/// Nested uniform scrambling of the 32 bits of `x` (an approximation of Owen's scrambling
/// by Laine and Karras' hash, applied to the bit-reversed value as Burley's "Practical
/// hash-based Owen scrambling", 2020, proposes): a bijection of the 32-bit values for each
/// `seed` that keeps every dyadic stratum's points in one dyadic stratum, so a scrambled
/// (0, m, 2)-net stays a net; for a uniform seed each output is uniform.
pub fn owen_scramble(x: u32, seed: u32) -> u32 {
    let mut v = x.reverse_bits();
    v = v.wrapping_add(seed);
    v ^= v.wrapping_mul(0x6c50_b47c);
    v ^= v.wrapping_mul(0xb82f_1e52);
    v ^= v.wrapping_mul(0xc7af_e638);
    v ^= v.wrapping_mul(0x8d22_f6e6);
    v.reverse_bits()
}

/// The first two dimensions of Sobol's sequence (a (0, 2)-sequence in base 2: the first
/// `2^m` points put one point in every dyadic box of area `2^-m`), point `index`, each
/// dimension Owen-scrambled and the index itself shuffled by a scrambling of its own
/// (Burley 2020), all from `seed`. Separate seeds give independent sequences, so a walk
/// can draw each bounce's 2D sample from its own seed ("padding", Kollig and Keller 2002)
/// and keep every bounce stratified over its paths; prefixes of `2^k` indices keep the
/// stratification whatever the seed. For a uniform seed each point is uniform in the
/// square, so an estimate from it is unbiased. [`Sobol2d`] is the same sequence with its
/// scrambles hashed once, for many points of one seed.
pub fn sobol_2d(index: u32, seed: u64) -> Vec2 {
    Sobol2d::new(seed).point(index)
}

/// Dimension 1 of Sobol's sequence, whose direction numbers are those of the polynomial
/// `x + 1` (`v_0 = 2^31`, `v_k = v_(k-1) ^ (v_(k-1) >> 1)`), as four tables of 256 entries:
/// entry `b` of table `j` is the XOR of the direction numbers of the bits set in byte `b`
/// of the index shifted by `8 j`.
const SOBOL_Y: [[u32; 256]; 4] = {
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 32 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    let mut t = [[0u32; 256]; 4];
    let mut j = 0;
    while j < 4 {
        let mut b = 0;
        while b < 256 {
            let mut y = 0u32;
            let mut bit = 0;
            while bit < 8 {
                if b & (1 << bit) != 0 {
                    y ^= v[8 * j + bit];
                }
                bit += 1;
            }
            t[j][b] = y;
            b += 1;
        }
        j += 1;
    }
    t
};

/// Dimension 1 of Sobol's sequence at `i`, unscrambled, from [`SOBOL_Y`].
#[inline]
fn sobol_y(i: u32) -> u32 {
    (0..4).fold(0u32, |y, j| y ^ SOBOL_Y[j][(i >> (8 * j)) as usize & 0xff])
}

/// One seed's scrambled and shuffled two-dimensional Sobol sequence ([`sobol_2d`]), its
/// three scrambles hashed once: a path tracer keeps one per pixel and bounce and draws a
/// point per sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sobol2d {
    /// Scrambles of the index, of dimension 0 and of dimension 1.
    scramble: [u32; 3],
}

impl Sobol2d {
    /// The sequence of `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            scramble: [0, 1, 2].map(|k| hash_seed(seed, 0x50b0, k) as u32),
        }
    }

    /// Point `index` of the sequence, in [0, 1)^2.
    #[inline]
    pub fn point(&self, index: u32) -> Vec2 {
        let i = owen_scramble(index, self.scramble[0]);
        // Dimension 0 is the radical inverse in base 2, dimension 1 the tables' XOR.
        let x = i.reverse_bits();
        let y = sobol_y(i);
        let x = owen_scramble(x, self.scramble[1]);
        let y = owen_scramble(y, self.scramble[2]);
        Vec2::new(unit_from_bits(x), unit_from_bits(y))
    }
}

/// The scrambled radical inverse in base 2 of a shuffled `index` (the 1D counterpart of
/// [`sobol_2d`], with its own shuffle): a stratified uniform number in [0, 1) per index.
pub fn sobol_1d(index: u32, seed: u64) -> f32 {
    let i = owen_scramble(index, hash_seed(seed, 0x50b1, 0) as u32);
    unit_from_bits(owen_scramble(
        i.reverse_bits(),
        hash_seed(seed, 0x50b1, 1) as u32,
    ))
}

/// The top 24 bits of `x` as a float in [0, 1).
fn unit_from_bits(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// The R2 sequence (Roberts' additive recurrence from the plastic number): point `index`
/// in [0, 1)², offset by `offset`.
pub fn r2(index: u64, offset: Vec2) -> Vec2 {
    const G: f64 = 1.324_717_957_244_746;
    const A1: f64 = 1.0 / G;
    const A2: f64 = 1.0 / (G * G);
    let i = index as f64;
    let x = (offset.x as f64 + 0.5 + A1 * i).rem_euclid(1.0);
    let y = (offset.y as f64 + 0.5 + A2 * i).rem_euclid(1.0);
    // The f64 to f32 rounding may reach 1.0: keep the result in [0, 1).
    let top = 1.0 - f32::EPSILON / 2.0;
    Vec2::new((x as f32).min(top), (y as f32).min(top))
}

/// Maps a point of the unit square to the unit disk (Shirley-Chiu concentric map, which
/// keeps strata compact).
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = u * 2.0 - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, std::f32::consts::FRAC_PI_4 * (o.y / o.x))
    } else {
        (
            o.y,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (o.x / o.y),
        )
    };
    Vec2::new(r * theta.cos(), r * theta.sin())
}

/// A cosine-weighted direction on the hemisphere around unit `normal`
/// (pdf = cos(theta) / pi), by projecting the concentric disk up (Malley's method).
pub fn cosine_hemisphere(normal: Vec3, u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    let (t, b) = orthonormal_basis(normal);
    (t * d.x + b * d.y + normal * z).normalize()
}

/// A uniform direction on the unit sphere.
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Barycentric coordinates `(b1, b2)` of a point uniform on a triangle (`b0 = 1 - b1 - b2`),
/// by the square-root warp.
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    let su = u.x.sqrt();
    Vec2::new(su * (1.0 - u.y), su * u.y)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first `2^m` points of [`sobol_2d`] (any seed) form a (0, m, 2)-net: every
    /// dyadic box of area `2^-m`, of every shape, holds exactly one point; the first
    /// `2^m` of [`sobol_1d`] hold one per interval of `2^-m`. A wrong direction number or
    /// a scramble that does not keep strata breaks it (the plain `Rng` fails it). Over
    /// many seeds one index's point is uniform (its mean within 4 standard errors of the
    /// square's centre), so estimates from it are unbiased.
    #[test]
    fn scrambled_sobol_points_are_nets_and_uniform_over_seeds() {
        for seed in [1u64, 2, 77] {
            for m in [3u32, 6, 9] {
                let n = 1u32 << m;
                let points: Vec<Vec2> = (0..n).map(|i| sobol_2d(i, seed)).collect();
                for a in 0..=m {
                    let (nx, ny) = (1u32 << a, 1u32 << (m - a));
                    let mut boxes = vec![0u32; n as usize];
                    for p in &points {
                        assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
                        let (bx, by) = ((p.x * nx as f32) as u32, (p.y * ny as f32) as u32);
                        boxes[(by * nx + bx) as usize] += 1;
                    }
                    assert!(
                        boxes.iter().all(|&c| c == 1),
                        "seed {seed}, m {m}, boxes {nx} x {ny}: {boxes:?}"
                    );
                }
                let mut cells = vec![0u32; n as usize];
                for i in 0..n {
                    cells[(sobol_1d(i, seed) * n as f32) as usize] += 1;
                }
                assert!(cells.iter().all(|&c| c == 1), "1D, seed {seed}, m {m}");
            }
        }
        assert_ne!(sobol_2d(5, 1), sobol_2d(5, 2));
        let mut rng = Rng::new(3, 0);
        let random: Vec<Vec2> = (0..64).map(|_| rng.next_vec2()).collect();
        let mut boxes = [0u32; 64];
        for p in &random {
            boxes[((p.y * 8.0) as usize) * 8 + (p.x * 8.0) as usize] += 1;
        }
        assert!(boxes.iter().any(|&c| c != 1), "the control is stratified");
        const SEEDS: u64 = 20_000;
        for index in [0u32, 1, 37] {
            let mut sum = glam::DVec2::ZERO;
            let mut sum1 = 0.0f64;
            for seed in 0..SEEDS {
                sum += sobol_2d(index, seed).as_dvec2();
                sum1 += f64::from(sobol_1d(index, seed));
            }
            let se = (1.0 / 12.0 / SEEDS as f64).sqrt();
            let mean = sum / SEEDS as f64;
            assert!(
                (mean - glam::DVec2::splat(0.5)).abs().max_element() < 4.0 * se,
                "{mean}"
            );
            assert!((sum1 / SEEDS as f64 - 0.5).abs() < 4.0 * se);
        }
    }

    /// The tables give dimension 1 as the bit-by-bit XOR of its direction numbers.
    #[test]
    fn the_sobol_tables_equal_the_direction_number_recurrence() {
        let slow = |i: u32| {
            let (mut y, mut v, mut bits) = (0u32, 1u32 << 31, i);
            while bits != 0 {
                if bits & 1 == 1 {
                    y ^= v;
                }
                bits >>= 1;
                v ^= v >> 1;
            }
            y
        };
        let mut rng = Rng::new(8, 0);
        let indices = (0..4096)
            .chain((0..4096).map(|_| rng.next_u32()))
            .chain([u32::MAX]);
        for i in indices {
            assert_eq!(sobol_y(i), slow(i), "index {i}");
        }
        // The first points of dimension 1 unscrambled, in index order (Sobol's second
        // coordinate: 0, 1/2, 3/4, 1/4, 5/8, 1/8).
        let firsts: Vec<f64> = (0..6)
            .map(|i| f64::from(slow(i)) / 4_294_967_296.0)
            .collect();
        assert_eq!(firsts, [0.0, 0.5, 0.75, 0.25, 0.625, 0.125]);
    }

    #[test]
    fn rng_is_uniform_and_deterministic() {
        let mut a = Rng::new(42, 3);
        let mut b = Rng::new(42, 3);
        let mut c = Rng::new(42, 4);
        let xs: Vec<f32> = (0..100_000).map(|_| a.next_f32()).collect();
        assert!(xs.iter().all(|&x| (0.0..1.0).contains(&x)));
        let ys: Vec<f32> = (0..100_000).map(|_| b.next_f32()).collect();
        assert_eq!(xs, ys);
        let zs: Vec<f32> = (0..100).map(|_| c.next_f32()).collect();
        assert_ne!(&xs[..100], &zs[..]);
        let mean = xs.iter().map(|&x| x as f64).sum::<f64>() / xs.len() as f64;
        // Standard error of the mean of U(0,1) over 1e5 draws is 0.0009.
        assert!((mean - 0.5).abs() < 0.004, "mean {mean}");
        // Ten equal bins each within 5 sigma of 10000.
        let mut bins = [0u32; 10];
        for &x in &xs {
            bins[(x * 10.0) as usize] += 1;
        }
        for b in bins {
            assert!((b as f64 - 10_000.0).abs() < 5.0 * 94.9, "{bins:?}");
        }
    }

    #[test]
    fn halton_unscrambled_matches_radical_inverse() {
        // Base 2: 1/2, 1/4, 3/4, 1/8; base 3: 1/3, 2/3, 1/9.
        let b2: Vec<f32> = (1..5).map(|i| halton(i, 0, None)).collect();
        assert_eq!(b2, vec![0.5, 0.25, 0.75, 0.125]);
        assert!((halton(1, 1, None) - 1.0 / 3.0).abs() < 1e-7);
        assert!((halton(2, 1, None) - 2.0 / 3.0).abs() < 1e-7);
        assert!((halton(3, 1, None) - 1.0 / 9.0).abs() < 1e-7);
    }

    #[test]
    fn scrambled_halton_stays_stratified() {
        // Any 2^k consecutive-from-zero points of the base-2 dimension put exactly one point
        // in each interval of width 2^-k, with or without digit scrambling.
        for seed in [1u64, 99, 12345] {
            let mut hits = [0u32; 64];
            for i in 0..64 {
                let x = halton(i, 0, Some(seed));
                assert!((0.0..1.0).contains(&x));
                hits[(x * 64.0) as usize] += 1;
            }
            assert!(hits.iter().all(|&h| h == 1), "seed {seed}: {hits:?}");
            // Base 3 likewise over 27 points.
            let mut hits3 = [0u32; 27];
            for i in 0..27 {
                hits3[(halton(i, 1, Some(seed)) * 27.0) as usize] += 1;
            }
            assert!(hits3.iter().all(|&h| h == 1));
        }
        assert_ne!(halton(5, 0, Some(1)), halton(5, 0, Some(2)));
    }

    #[test]
    fn r2_is_low_discrepancy() {
        // 4096 R2 points over a 16x16 grid: every cell gets 16 +- 3 (random points would
        // deviate by ~4 sigma = 16 somewhere).
        let mut cells = [0u32; 256];
        for i in 0..4096 {
            let p = r2(i, Vec2::ZERO);
            cells[(p.y * 16.0) as usize * 16 + (p.x * 16.0) as usize] += 1;
        }
        assert!(cells.iter().all(|&c| (13..=19).contains(&c)), "{cells:?}");
    }

    #[test]
    fn cosine_hemisphere_has_cosine_density() {
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let mut rng = Rng::new(7, 0);
        let count = 200_000;
        let mut mean_cos = 0.0f64;
        let mut mean_cos2 = 0.0f64;
        for _ in 0..count {
            let d = cosine_hemisphere(n, rng.next_vec2());
            assert!((d.length() - 1.0).abs() < 1e-5);
            let c = d.dot(n) as f64;
            assert!(c >= -1e-6);
            mean_cos += c;
            mean_cos2 += c * c;
        }
        mean_cos /= count as f64;
        mean_cos2 /= count as f64;
        // For pdf cos/pi: E[cos] = 2/3, E[cos^2] = 1/2.
        assert!((mean_cos - 2.0 / 3.0).abs() < 3e-3, "{mean_cos}");
        assert!((mean_cos2 - 0.5).abs() < 3e-3, "{mean_cos2}");
    }

    #[test]
    fn uniform_triangle_is_uniform() {
        let mut rng = Rng::new(11, 0);
        let count = 100_000;
        let mut mean = Vec2::ZERO;
        let mut in_sub = 0;
        for _ in 0..count {
            let b = uniform_triangle(rng.next_vec2());
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
            mean += b;
            // The sub-triangle b1 + b2 < 1/2 has a quarter of the area.
            if b.x + b.y < 0.5 {
                in_sub += 1;
            }
        }
        mean /= count as f32;
        // The centroid has barycentrics (1/3, 1/3).
        assert!((mean - Vec2::splat(1.0 / 3.0)).abs().max_element() < 4e-3);
        let frac = in_sub as f64 / count as f64;
        assert!((frac - 0.25).abs() < 6e-3, "{frac}");
    }
}
