//! The reference path tracer: the project's ground truth.
//!
//! Lambertian surfaces only (two-sided reflection; emission one-sided, from the side the
//! triangle's winding faces). Next-event estimation for point lights (inverse-square or the
//! windowed falloff of thesis eq. 16), directional lights and emissive triangles; emissive
//! triangles are sampled by area (triangle chosen in proportion to its power) and combined
//! with emitter hits of cosine-sampled bounce rays by multiple importance sampling (power
//! heuristic). Russian roulette only from [`RR_START_DEPTH`] surface vertices on.
//!
//! Bounce limit `Limited(0)` is direct light only, `Limited(1)` is direct light plus one
//! indirect bounce (ISR's scope, the thesis' POV-Ray `recursion_limit 2`), `Unlimited`
//! converges to the full solution.
//!
//! Every sample of every pixel draws from its own generator seeded by
//! `(seed, pixel, sample index)`, and its pixel position and first vertices' emitter points
//! and bounces from the pixel's scrambled Sobol sequences at the sample index (stratified
//! over the pixel's samples; docs/reference.md has what that gains),
//! so an image is the same bit for bit whatever the thread count and however the samples
//! are split into progressive passes. A [`crate::sky::Sky::is_uniform`] sky is sampled by
//! the cosine-weighted bounce alone; any other sky also by next-event estimation from its
//! map, with MIS.

use crate::image::Image;

#[cfg(feature = "reference")]
mod tracer;
#[cfg(feature = "reference")]
pub use tracer::{Accumulator, PathTracer, ReferenceTechnique, render, render_lit};

#[cfg(all(feature = "reference", feature = "gpu"))]
mod gpu;
#[cfg(all(feature = "reference", feature = "gpu"))]
pub use gpu::{
    GpuAccumulator, GpuPathTracer, GpuRayAnswer, GpuReferenceOutput, PATH_TRACER, PathTracerFrame,
    PathTracerFrameSettings, render_gpu,
};

/// Surface vertices before Russian roulette may end a path.
pub const RR_START_DEPTH: u32 = 4;

/// How many indirect bounces to follow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bounces {
    /// At most this many indirect bounces (0 = direct light only).
    Limited(u32),
    /// Follow paths until Russian roulette ends them.
    Unlimited,
}

impl std::str::FromStr for Bounces {
    type Err = String;
    /// Parses `0`, `1`, any `N`, or `inf`/`unlimited`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "inf" | "unlimited" | "infinite" => Ok(Bounces::Unlimited),
            n => n
                .parse::<u32>()
                .map(Bounces::Limited)
                .map_err(|_| format!("bounces must be a number or 'inf', got '{s}'")),
        }
    }
}

impl std::fmt::Display for Bounces {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Bounces::Limited(n) => write!(f, "{n}"),
            Bounces::Unlimited => write!(f, "inf"),
        }
    }
}

/// Settings of a reference render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Bounce limit.
    pub bounces: Bounces,
    /// Seed of all random decisions.
    pub seed: u64,
}

impl Default for ReferenceSettings {
    fn default() -> Self {
        Self {
            width: 256,
            height: 256,
            spp: 256,
            bounces: Bounces::Limited(1),
            seed: 1,
        }
    }
}

/// Ray counts and time of a render pass.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayStats {
    /// Camera rays.
    pub primary: u64,
    /// Shadow (occlusion) rays of next-event estimation.
    pub shadow: u64,
    /// Bounce rays (closest-hit queries after the first vertex).
    pub bounce: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl RayStats {
    /// All rays.
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.bounce
    }

    /// Rays per second.
    pub fn rays_per_second(&self) -> f64 {
        if self.seconds > 0.0 {
            self.total() as f64 / self.seconds
        } else {
            0.0
        }
    }

    #[cfg(feature = "reference")]
    fn add(&mut self, o: &RayStats) {
        self.primary += o.primary;
        self.shadow += o.shadow;
        self.bounce += o.bounce;
        self.seconds += o.seconds;
    }
}

/// What a pixel's centre sees ([`PathTracer::pixel_classes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelClass {
    /// Nothing: the ray leaves the scene.
    Background,
    /// A surface whose material emits.
    Emitter,
    /// A reflecting surface that does not emit.
    Surface,
}

/// The result of [`render`].
#[derive(Clone, Debug)]
pub struct ReferenceOutput {
    /// The mean radiance per pixel.
    pub image: Image,
    /// Per-pixel, per-channel sample variance (of one sample, unbiased). Divided by `spp` it
    /// is the variance of the mean for independent samples; the reference's stratified
    /// samples make the mean's true variance lower (9-23x on the Cornell box at 256 spp), so
    /// tests built on it are conservative.
    pub variance: Image,
    /// Samples per pixel accumulated.
    pub spp: u32,
    /// Ray counts and time.
    pub stats: RayStats,
}

/// One block's test of [`block_z_tests`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockTest {
    /// The block's column and row (in blocks).
    pub block: (u32, u32),
    /// The channel: 0 red, 1 green, 2 blue.
    pub channel: usize,
    /// The block's mean in the first render.
    pub a: f64,
    /// The block's mean in the second.
    pub b: f64,
    /// The standard error of their difference, from the variance images.
    pub se: f64,
}

impl BlockTest {
    /// `(b - a) / se`.
    pub fn z(&self) -> f64 {
        (self.b - self.a) / self.se.max(f64::MIN_POSITIVE)
    }
}

/// Two renders of one view at `spp` samples per pixel each ([`ReferenceOutput`]'s image and
/// per-sample variance image), compared per `block x block` pixels and per channel: each
/// block's two means and the standard error of their difference, for a z-test. Blocks
/// black in both are left out; pixels beyond the last whole block are not used. The
/// variance images of a stratified render overstate its noise, so such tests are
/// conservative. How the CPU and GPU path tracers are checked against each other.
pub fn block_z_tests(
    a: (&Image, &Image),
    b: (&Image, &Image),
    spp: u32,
    block: u32,
) -> Vec<BlockTest> {
    let (w, h) = (a.0.width, a.0.height);
    let block = block.max(1);
    let n = f64::from(block * block);
    let mut out = Vec::new();
    for by in 0..h / block {
        for bx in 0..w / block {
            for channel in 0..3 {
                let (mut ma, mut mb, mut var) = (0.0f64, 0.0f64, 0.0f64);
                for y in by * block..(by + 1) * block {
                    for x in bx * block..(bx + 1) * block {
                        let i = (y * w + x) as usize;
                        ma += f64::from(a.0.pixels[i][channel]);
                        mb += f64::from(b.0.pixels[i][channel]);
                        var += f64::from(a.1.pixels[i][channel] + b.1.pixels[i][channel]);
                    }
                }
                let (ma, mb) = (ma / n, mb / n);
                if ma.max(mb) <= 0.0 {
                    continue;
                }
                out.push(BlockTest {
                    block: (bx, by),
                    channel,
                    a: ma,
                    b: mb,
                    se: (var / f64::from(spp.max(1))).sqrt() / n,
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// Block means and the standard error of their difference from the variance images;
    /// a partial block is left out, and so is a block black in both renders.
    #[test]
    fn block_z_tests_give_block_means_and_their_standard_error() {
        let image = |w: u32, f: &dyn Fn(u32) -> Vec3| Image {
            width: w,
            height: 8,
            pixels: (0..w * 8).map(|i| f(i % w)).collect(),
        };
        let a = image(20, &|x| if x < 8 { Vec3::ONE } else { Vec3::ZERO });
        let b = image(20, &|x| if x < 8 { Vec3::splat(1.5) } else { Vec3::ZERO });
        let var = image(20, &|_| Vec3::splat(2.0));
        let tests = block_z_tests((&a, &var), (&b, &var), 16, 8);
        assert_eq!(
            tests.len(),
            3,
            "one lit block of two whole ones, three channels"
        );
        for t in &tests {
            assert_eq!(t.block, (0, 0));
            assert_eq!((t.a, t.b), (1.0, 1.5));
            // Sum of the variances over 64 pixels, over spp, square root, over 64.
            assert!((t.se - (64.0f64 * 4.0 / 16.0).sqrt() / 64.0).abs() < 1e-12);
            assert!((t.z() - 0.5 / t.se).abs() < 1e-9);
        }
    }
}
