//! `imalyzer`: compare images from the command line.
//!
//! ```text
//! imalyzer compare REF TEST [--metrics all|mean,pearson,ssim,flip,...] [--diff OUT.png]
//!                  [--map flip|ssim|abs OUT.png]... [--json] [--exclude-non-finite]
//! imalyzer quality MODEL IMG1 IMG2 [--json] [--exclude-non-finite]
//! imalyzer ztest REF TEST --variance VAR.exr --spp N [--ref-variance VAR.exr --ref-spp N]
//! ```
//!
//! Exit status: 0 on success, 1 on an error (the message names the file at fault), 2 on a
//! usage error, 3 when `ztest` runs but the render fails the test.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use imalyzer::scene_core::Image;
use imalyzer::scene_core::glam::Vec3;
use imalyzer::stats::{Estimate, ZTestOptions};
use imalyzer::{
    CompareError, EXCLUDED_COLOUR, FlipOptions, Measure, NonFinite, Pair, Settings, SsimOptions,
    linear_from_srgb8,
};
use serde_json::{Value, json};

#[derive(Parser)]
#[command(
    name = "imalyzer",
    version,
    about = "Compare rendered images: the thesis' Imalyzer measures, RMSE, PSNR, SSIM, FLIP and a statistical test"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Compare a test image with a reference (PNG or EXR).
    Compare(CompareArgs),
    /// Which of two images is closer to a model image (thesis eq. 21) and the share of
    /// pixels that are closer.
    Quality(QualityArgs),
    /// Statistical test of a noisy render against a reference with known per-pixel variance.
    Ztest(ZtestArgs),
}

#[derive(clap::Args)]
struct CompareArgs {
    /// Reference image (.png or .exr).
    reference: PathBuf,
    /// Test image (.png or .exr), the same size.
    test: PathBuf,
    /// Comma-separated measures, or `all`: mean (mean-error), mean8 (mean-error-8bit),
    /// pearson, rmse, psnr, relmse, smape, ssim, flip, hdr-flip.
    #[arg(long, default_value = "all")]
    metrics: String,
    /// Write the difference image: the thesis' negative rendering for .png, |REF - TEST|
    /// for .exr.
    #[arg(long, value_name = "OUT")]
    diff: Option<PathBuf>,
    /// Write an error map: KIND is flip, ssim or abs; OUT is .png (white = most different)
    /// or .exr (raw values). May be repeated.
    #[arg(long, num_args = 2, value_names = ["KIND", "OUT"], action = clap::ArgAction::Append)]
    map: Vec<String>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Leave pixels with NaN or infinite values out (they are refused otherwise).
    #[arg(long)]
    exclude_non_finite: bool,
    /// Which FLIP `flip` means: auto is HDR-FLIP when either input is EXR, LDR otherwise.
    #[arg(long, value_enum, default_value_t = FlipMode::Auto)]
    flip: FlipMode,
    /// FLIP viewing condition, pixels per degree.
    #[arg(long, default_value_t = imalyzer::flip::DEFAULT_PPD)]
    ppd: f32,
    /// HDR-FLIP first exposure (stops); computed from the reference when absent.
    #[arg(long, allow_negative_numbers = true)]
    start_exposure: Option<f32>,
    /// HDR-FLIP last exposure (stops); computed from the reference when absent.
    #[arg(long, allow_negative_numbers = true)]
    stop_exposure: Option<f32>,
    /// HDR-FLIP number of exposures.
    #[arg(long)]
    exposures: Option<usize>,
    /// SSIM data range of the luminance.
    #[arg(long, default_value_t = 1.0)]
    ssim_range: f64,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum FlipMode {
    Auto,
    Ldr,
    Hdr,
}

#[derive(clap::Args)]
struct QualityArgs {
    /// The model image I0 (the ground truth).
    model: PathBuf,
    /// Image I1.
    image1: PathBuf,
    /// Image I2.
    image2: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Leave pixels with NaN or infinite values out (they are refused otherwise).
    #[arg(long)]
    exclude_non_finite: bool,
}

#[derive(clap::Args)]
struct ZtestArgs {
    /// Reference image.
    reference: PathBuf,
    /// Test render (the mean of its samples).
    test: PathBuf,
    /// Per-sample variance of the test render (e.g. scene-core's `.variance.exr`).
    #[arg(long)]
    variance: PathBuf,
    /// Samples per pixel of the test render.
    #[arg(long)]
    spp: u32,
    /// Per-sample variance of the reference, when it is itself a noisy render.
    #[arg(long, requires = "ref_spp")]
    ref_variance: Option<PathBuf>,
    /// Samples per pixel of the reference.
    #[arg(long, requires = "ref_variance")]
    ref_spp: Option<u32>,
    /// Significance level of the whole image (before Šidák's correction).
    #[arg(long, default_value_t = 0.01)]
    significance: f64,
    /// Share of pixel-channels that must pass.
    #[arg(long, default_value_t = 0.9975)]
    pass_fraction: f64,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Leave pixels with NaN or infinite values out (they are refused otherwise).
    #[arg(long)]
    exclude_non_finite: bool,
}

/// A failure: the message to print and the exit code.
struct Failure(String, u8);

impl From<String> for Failure {
    fn from(s: String) -> Self {
        Failure(s, 1)
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Compare(a) => compare(a),
        Command::Quality(a) => quality(a),
        Command::Ztest(a) => ztest(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure(message, code)) => {
            eprintln!("imalyzer: {message}");
            ExitCode::from(code)
        }
    }
}

/// Reads an image under the default budget, or the one `DIFFUSE_GI_BUDGET` sets: a
/// corrupted header asking for gigabytes is refused before anything is allocated.
fn read(path: &Path) -> Result<Image, String> {
    let budget = imalyzer::scene_core::Budget::from_env()?;
    Image::read_with(path, &budget).map_err(|e| e.to_string())
}

fn policy(exclude: bool) -> NonFinite {
    if exclude {
        NonFinite::Exclude
    } else {
        NonFinite::Reject
    }
}

/// Replaces the library's image labels with file names.
fn named(e: CompareError, names: &[(&str, &Path)]) -> String {
    e.relabel(|label| {
        names
            .iter()
            .find(|(l, _)| *l == label)
            .map(|(_, p)| p.display().to_string())
            .unwrap_or_else(|| label.to_string())
    })
    .to_string()
}

fn is_exr(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

fn is_png(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
}

fn check_output(p: &Path) -> Result<(), String> {
    if is_png(p) || is_exr(p) {
        Ok(())
    } else {
        Err(format!(
            "{}: unknown output extension (expected .png or .exr)",
            p.display()
        ))
    }
}

/// JSON number, or null where it is not finite (PSNR of identical images is +inf).
fn number(v: f64) -> Value {
    if v.is_finite() { json!(v) } else { Value::Null }
}

fn compare(a: CompareArgs) -> Result<(), Failure> {
    // Validate the request before reading anything.
    let mut measures: Vec<Measure> = Vec::new();
    let hdr = match a.flip {
        FlipMode::Auto => is_exr(&a.reference) || is_exr(&a.test),
        FlipMode::Ldr => false,
        FlipMode::Hdr => true,
    };
    let auto_flip = if hdr { Measure::HdrFlip } else { Measure::Flip };
    for name in a.metrics.split(',') {
        let list: Vec<Measure> = match name.trim() {
            "all" => Measure::ALL
                .into_iter()
                .filter(|m| *m != Measure::Flip && *m != Measure::HdrFlip)
                .chain([auto_flip])
                .collect(),
            "flip" => vec![auto_flip],
            other => vec![Measure::parse(other).ok_or_else(|| {
                format!(
                    "unknown measure '{other}' (known: mean, mean8, pearson, rmse, psnr, \
                     relmse, smape, ssim, flip, ldr-flip, hdr-flip, all)"
                )
            })?],
        };
        for m in list {
            if !measures.contains(&m) {
                measures.push(m);
            }
        }
    }
    let mut maps: Vec<(Measure, PathBuf)> = Vec::new();
    for kv in a.map.chunks(2) {
        let kind = match kv[0].as_str() {
            "flip" => auto_flip,
            "ssim" => Measure::Ssim,
            "abs" => Measure::MeanError,
            other => {
                return Err(format!("unknown map '{other}' (known: flip, ssim, abs)").into());
            }
        };
        let out = PathBuf::from(&kv[1]);
        check_output(&out)?;
        maps.push((kind, out));
    }
    if let Some(d) = &a.diff {
        check_output(d)?;
    }
    let settings = Settings {
        non_finite: policy(a.exclude_non_finite),
        ssim: SsimOptions {
            data_range: a.ssim_range,
        },
        flip: FlipOptions {
            ppd: a.ppd,
            start_exposure: a.start_exposure,
            stop_exposure: a.stop_exposure,
            exposures: a.exposures,
        },
    };

    let reference = read(&a.reference)?;
    let test = read(&a.test)?;
    let names = [
        ("reference", a.reference.as_path()),
        ("test", a.test.as_path()),
    ];
    let pair =
        Pair::with_policy(&reference, &test, settings.non_finite).map_err(|e| named(e, &names))?;

    let mut results = Vec::new();
    let mut needed = measures.clone();
    for (m, _) in &maps {
        if !needed.contains(m) {
            needed.push(*m);
        }
    }
    for m in needed {
        results.push(pair.evaluate(m, &settings).map_err(|e| named(e, &names))?);
    }

    for (kind, out) in &maps {
        let e = results
            .iter()
            .find(|e| e.measure == *kind)
            .expect("evaluated above");
        let map = e.map.as_ref().expect("map measures have maps");
        write_map(map, *kind, pair.width(), pair.height(), out)?;
    }
    if let Some(out) = &a.diff {
        let img = if is_exr(out) {
            pair.difference()
        } else {
            imalyzer::negative_difference_image(&reference, &test).map_err(|e| named(e, &names))?
        };
        write(&img, out)?;
    }

    let shown: Vec<_> = results
        .iter()
        .filter(|e| measures.contains(&e.measure))
        .collect();
    let [nf_ref, nf_test] = pair.non_finite_pixels();
    if a.json {
        let metrics: BTreeMap<&str, Value> = shown
            .iter()
            .map(|e| (e.measure.name(), number(e.value)))
            .collect();
        let mut doc = json!({
            "reference": a.reference.display().to_string(),
            "test": a.test.display().to_string(),
            "width": pair.width(),
            "height": pair.height(),
            "pixels_compared": pair.used_pixels(),
            "pixels_excluded": pair.excluded_pixels(),
            "non_finite_pixels": { "reference": nf_ref, "test": nf_test },
            "metrics": metrics,
        });
        if let Some(e) = shown.iter().find(|e| e.measure == Measure::HdrFlip) {
            doc["hdr_flip_exposures"] = json!(e.exposures);
        }
        println!(
            "{}",
            serde_json::to_string_pretty(&doc).expect("valid JSON")
        );
    } else {
        println!(
            "reference  {}  ({}x{})",
            a.reference.display(),
            pair.width(),
            pair.height()
        );
        println!("test       {}", a.test.display());
        println!(
            "pixels     {} compared, {} excluded (non-finite: {} in reference, {} in test)",
            pair.used_pixels(),
            pair.excluded_pixels(),
            nf_ref,
            nf_test
        );
        println!();
        println!("{:<17} {:>14}", "measure", "value");
        for e in &shown {
            let note = match e.measure {
                Measure::MeanError => "  eq. 19, linear".to_string(),
                Measure::MeanError8bit => "  eq. 19, 8-bit sRGB (0..255)".to_string(),
                Measure::Pearson => "  eq. 20".to_string(),
                Measure::Psnr => "  dB, peak 1".to_string(),
                Measure::HdrFlip => format!(
                    "  {} exposures, {:.3} to {:.3} stops",
                    e.exposures.len(),
                    e.exposures.first().copied().unwrap_or(0.0),
                    e.exposures.last().copied().unwrap_or(0.0)
                ),
                _ => String::new(),
            };
            let better = if e.measure.lower_is_better() {
                "lower is better"
            } else {
                "higher is better"
            };
            println!(
                "{:<17} {:>14.6}  ({better}){note}",
                e.measure.name(),
                e.value
            );
        }
    }
    Ok(())
}

fn write(img: &Image, out: &Path) -> Result<(), String> {
    if is_exr(out) {
        img.write_exr(out)
    } else {
        img.write_png(out, 0.0)
    }
    .map_err(|e| e.to_string())
}

/// PNG: grey levels `255 v` of the error direction (FLIP and abs as they are, SSIM as
/// `1 - S`), clamped to [0, 1], excluded pixels magenta. EXR: the raw values.
fn write_map(map: &[f32], kind: Measure, w: u32, h: u32, out: &Path) -> Result<(), String> {
    let pixels = if is_exr(out) {
        map.iter().map(|&v| Vec3::splat(v)).collect()
    } else {
        map.iter()
            .map(|&v| {
                if v.is_nan() {
                    return Vec3::from_array(EXCLUDED_COLOUR.map(linear_from_srgb8));
                }
                let e = if kind == Measure::Ssim { 1.0 - v } else { v };
                let code = (e.clamp(0.0, 1.0) * 255.0).round() as u8;
                Vec3::splat(linear_from_srgb8(code))
            })
            .collect()
    };
    write(
        &Image {
            width: w,
            height: h,
            pixels,
        },
        out,
    )
}

fn quality(a: QualityArgs) -> Result<(), Failure> {
    let model = read(&a.model)?;
    let i1 = read(&a.image1)?;
    let i2 = read(&a.image2)?;
    let names = [
        ("model", a.model.as_path()),
        ("image 1", a.image1.as_path()),
        ("image 2", a.image2.as_path()),
    ];
    let q = imalyzer::quality_with(&model, &i1, &i2, policy(a.exclude_non_finite))
        .map_err(|e| named(e, &names))?;
    if a.json {
        let scale = |s: &imalyzer::QualityOnScale| {
            json!({
                "mean_error_1": s.mean_error_1,
                "mean_error_2": s.mean_error_2,
                "f_q": s.f_q,
                "gain": s.gain.map(number),
                "pixels_closer": s.closer,
                "pixels_farther": s.farther,
                "pixels_equal": s.equal,
                "share_closer": s.share_closer(),
            })
        };
        let doc = json!({
            "model": a.model.display().to_string(),
            "image1": a.image1.display().to_string(),
            "image2": a.image2.display().to_string(),
            "pixels_compared": q.pixels,
            "pixels_excluded": q.excluded,
            "linear": scale(&q.linear),
            "srgb8": scale(&q.srgb8),
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&doc).expect("valid JSON")
        );
        return Ok(());
    }
    println!("model      {}", a.model.display());
    println!("image 1    {}", a.image1.display());
    println!("image 2    {}", a.image2.display());
    println!("pixels     {} compared, {} excluded", q.pixels, q.excluded);
    println!();
    println!("{:<26} {:>16} {:>16}", "", "linear", "8-bit sRGB");
    let row = |label: &str, f: &dyn Fn(&imalyzer::QualityOnScale) -> String| {
        println!("{label:<26} {:>16} {:>16}", f(&q.linear), f(&q.srgb8));
    };
    row("mean error, image 1", &|s| format!("{:.6}", s.mean_error_1));
    row("mean error, image 2", &|s| format!("{:.6}", s.mean_error_2));
    row("f_q (eq. 21)", &|s| {
        match s.f_q {
            1 => "1 (image 1)",
            -1 => "-1 (image 2)",
            _ => "0 (equal)",
        }
        .to_string()
    });
    row("gain of image 2", &|s| match s.gain {
        Some(g) => format!("{:.2}%", 100.0 * g),
        None => "n/a".to_string(),
    });
    row("pixels of 2 closer", &|s| {
        format!("{} ({:.2}%)", s.closer, 100.0 * s.share_closer())
    });
    row("pixels of 2 farther", &|s| s.farther.to_string());
    row("pixels equal", &|s| s.equal.to_string());
    Ok(())
}

fn ztest(a: ZtestArgs) -> Result<(), Failure> {
    let reference = read(&a.reference)?;
    let test = read(&a.test)?;
    let variance = read(&a.variance)?;
    let ref_variance = a.ref_variance.as_deref().map(read).transpose()?;
    let names = [
        ("reference", a.reference.as_path()),
        ("test", a.test.as_path()),
        ("test variance", a.variance.as_path()),
        (
            "reference variance",
            a.ref_variance.as_deref().unwrap_or(Path::new("-")),
        ),
    ];
    let options = ZTestOptions {
        significance: a.significance,
        pass_fraction: a.pass_fraction,
        non_finite: policy(a.exclude_non_finite),
        ..ZTestOptions::default()
    };
    let test_estimate = Estimate {
        image: &test,
        variance: &variance,
        spp: a.spp,
    };
    let r = match (&ref_variance, a.ref_spp) {
        (Some(v), Some(spp)) => imalyzer::z_test_noisy_reference(
            &Estimate {
                image: &reference,
                variance: v,
                spp,
            },
            &test_estimate,
            &options,
        ),
        _ => imalyzer::z_test(&reference, &test_estimate, &options),
    }
    .map_err(|e| named(e, &names))?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r).expect("valid JSON"));
    } else {
        println!(
            "{}: {} of {} pixel-channels failed ({:.4}% passed, {:.2}% required)",
            if r.passed { "PASS" } else { "FAIL" },
            r.failed,
            r.channels,
            100.0 * r.passed_fraction,
            100.0 * a.pass_fraction
        );
        println!(
            "z critical {:.3} (channel level {:.3e}); largest z {:.3} at x={}, y={}, channel {}",
            r.z_critical, r.channel_level, r.max_z, r.worst.0, r.worst.1, r.worst.2
        );
        println!("relative bias {:+.4}%", 100.0 * r.relative_bias);
    }
    if r.passed {
        Ok(())
    } else {
        Err(Failure(
            format!(
                "{} fails the statistical test against {}",
                a.test.display(),
                a.reference.display()
            ),
            3,
        ))
    }
}
