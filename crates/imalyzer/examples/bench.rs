//! Timing of every measure at 1024x768 (median of repeats after warm-up).
//!
//! ```text
//! cargo run --release -p imalyzer --example bench -- [--threads 2] [--width 1024] [--height 768]
//! ```

use std::hint::black_box;
use std::time::Instant;

use imalyzer::scene_core::Image;
use imalyzer::scene_core::glam::Vec3;
use imalyzer::{Estimate, Pair, ZTestOptions, z_test};

/// Median wall time in milliseconds of `repeats` runs of `f` after `warm` untimed runs.
fn time<T>(warm: usize, repeats: usize, mut f: impl FnMut() -> T) -> f64 {
    for _ in 0..warm {
        black_box(f());
    }
    let mut t: Vec<f64> = (0..repeats)
        .map(|_| {
            let start = Instant::now();
            black_box(f());
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// A render-like test pair: smooth shading, edges, texture, and a noisy copy with a few
/// fireflies; HDR values up to about 20.
fn images(w: u32, h: u32) -> (Image, Image) {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut rand = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut a = Vec::with_capacity((w * h) as usize);
    let mut b = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
            let mut c = Vec3::new(0.2 + 0.6 * u, 0.3 + 0.4 * v, 0.5 - 0.3 * u);
            if (x / 64 + y / 64) % 2 == 0 {
                c *= 0.5;
            }
            let d = (u - 0.3).powi(2) + (v - 0.2).powi(2);
            c += Vec3::new(20.0, 15.0, 10.0) * (-d * 400.0).exp();
            a.push(c);
            let noise = Vec3::new(rand(), rand(), rand()) * 0.2 + Vec3::splat(0.9);
            let firefly = if rand() < 1e-4 { 30.0 } else { 0.0 };
            b.push(c * noise + Vec3::splat(firefly));
        }
    }
    (
        Image::from_pixels(w, h, a).unwrap(),
        Image::from_pixels(w, h, b).unwrap(),
    )
}

fn main() {
    let mut threads = 2usize;
    let (mut w, mut h) = (1024u32, 768u32);
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        let value = pair.get(1).map(String::as_str).unwrap_or("");
        match pair[0].as_str() {
            "--threads" => threads = value.parse().expect("--threads N"),
            "--width" => w = value.parse().expect("--width W"),
            "--height" => h = value.parse().expect("--height H"),
            other => panic!("unknown argument {other}"),
        }
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    let (a, b) = images(w, h);
    let variance = Image::filled(w, h, Vec3::splat(0.05));
    println!("imalyzer bench: {w}x{h}, {threads} threads, median of repeats after warm-up");
    pool.install(|| {
        let pair = Pair::new(&a, &b).unwrap();
        let rows: Vec<(&str, f64)> = vec![
            (
                "check (Pair::new)",
                time(3, 21, || Pair::new(&a, &b).unwrap()),
            ),
            (
                "mean error + Pearson + difference image",
                time(3, 21, || {
                    (pair.mean_error(), pair.pearson(), pair.difference())
                }),
            ),
            (
                "  mean error (eq. 19, linear)",
                time(3, 21, || pair.mean_error()),
            ),
            ("  Pearson (eq. 20)", time(3, 21, || pair.pearson())),
            (
                "  difference image (eq. 18)",
                time(3, 21, || pair.difference()),
            ),
            (
                "mean error, 8-bit sRGB",
                time(3, 21, || pair.mean_error_8bit()),
            ),
            (
                "RMSE + PSNR + relMSE + SMAPE",
                time(3, 21, || {
                    (pair.rmse(), pair.psnr(), pair.relmse(), pair.smape())
                }),
            ),
            ("SSIM (mean + map)", time(2, 9, || pair.ssim())),
            ("LDR-FLIP (mean + map)", time(2, 9, || pair.flip())),
            ("HDR-FLIP (mean + map)", time(1, 5, || pair.hdr_flip())),
            (
                "z-test",
                time(3, 21, || {
                    let est = Estimate {
                        image: &b,
                        variance: &variance,
                        spp: 64,
                    };
                    z_test(&a, &est, &ZTestOptions::default()).unwrap()
                }),
            ),
        ];
        let exposures = pair.hdr_flip().exposures.len();
        for (name, ms) in rows {
            println!("{name:<42} {ms:>9.2} ms");
        }
        println!("(HDR-FLIP evaluated {exposures} exposures)");
    });
}
