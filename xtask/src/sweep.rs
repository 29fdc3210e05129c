//! `cargo xtask sweep-isr`: ISR's settings swept over the built-in scenes against the
//! reference, to choose the default mode from measurement. Every combination of the indirect
//! power `k_isr`, ambient occlusion (on at `k_ssao` 0.5, or off) and the sampling radius runs
//! at each of the thesis' sample counts through the same experiment harness as the main job,
//! and the most accurate setting per sample count is printed, each setting with its mean
//! gain over DL and its share of views closer to the reference than DL (the thesis' check).
//! Beside the grid, `isr-ls-N`: light-space senders at `k_isr` 1, which has nothing to tune.
//!
//! The sweep is held out from what the main job scores: it runs on seeded random cameras
//! of the built-in scenes ([`HELD_OUT_SEED`]), never on their own cameras, which are the
//! views the main job measures, so a default chosen here is not chosen on the data it is
//! reported on.

use std::path::PathBuf;
use std::sync::Arc;

use bench_harness::{
    Experiment, ExperimentSettings, RandomCameraSettings, SceneSetup, TechniqueSetup, cameras_for,
};
use gbuffer::CpuRasterizer;
use imalyzer::{Measure, MeasureMetric};
use isr::{IsrSettings, IsrTechnique, Radius};
use scene_core::Metric;
use scene_core::reference::Bounces;

/// Where ISR's defaults were tuned, as the main job's results record it.
pub const TUNING_NOTE: &str = "ISR (`isr-N`): screen-space and light-space senders at \
    k_isr 1, nothing tuned (4 096 senders, a round number); `isr-scaled-N`'s k_isr per sample \
    count was chosen by `cargo xtask sweep-isr` on held-out views (seeded random cameras, seed \
    7001, of the built-in scenes; none of them is a view the main job scores)";

/// The seed of the sweep's random cameras (the main job scores the scenes' own cameras).
pub const HELD_OUT_SEED: u64 = 7001;

/// The swept values.
pub const K_ISR: [f32; 8] = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0];
/// Ambient occlusion: `Some(k_ssao)` or off.
pub const AO: [Option<f32>; 2] = [Some(0.5), None];
/// Radii as a share of the scene's extent.
pub const RADII: [f32; 3] = [0.1, 0.25, 0.5];

/// One swept setting.
#[derive(Clone, Debug)]
pub struct Setting {
    /// Label (`isr-80-k1-ao-r0.25`).
    pub label: String,
    /// The settings.
    pub settings: IsrSettings,
}

/// The grid at `samples`.
pub fn grid(samples: u32) -> Vec<Setting> {
    let mut out = Vec::new();
    for k in K_ISR {
        for ao in AO {
            for r in RADII {
                let settings = IsrSettings {
                    samples,
                    k_isr: k,
                    ssao: ao.is_some(),
                    k_ssao: ao.unwrap_or(0.0),
                    radius: Radius::Relative(r),
                    ..IsrSettings::screen_space()
                };
                let label = format!(
                    "isr-{samples}-k{k}-{}-r{r}",
                    if ao.is_some() { "ao" } else { "noao" }
                );
                out.push(Setting { label, settings });
            }
        }
    }
    out
}

/// What `cargo xtask sweep-isr` runs (its command-line options).
#[derive(Clone, Debug, clap::Args)]
pub struct Options {
    /// Output directory.
    #[arg(long, default_value = "out/sweep-isr")]
    pub out: PathBuf,
    /// Reference cache folder.
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// Image size WxH.
    #[arg(long, default_value = "128x96")]
    pub size: String,
    /// Reference samples per pixel.
    #[arg(long, default_value_t = 512)]
    pub spp: u32,
    /// Random views per scene.
    #[arg(long, default_value_t = 4)]
    pub views: usize,
    /// Scenes to sweep (built-in names or .gltf/.glb paths; repeatable). Default: the
    /// four built-in scenes of the main job.
    #[arg(long = "scene")]
    pub scenes: Vec<String>,
    /// Leave out the screen-space grid: DL and the default ISR (light-space senders,
    /// `k_isr` 1, nothing tuned) at each sample count only, the held-out check on a
    /// large file in minutes.
    #[arg(long)]
    pub no_grid: bool,
}

/// Runs the sweep.
pub fn run(o: Options) -> Result<(), String> {
    let Options {
        out,
        cache,
        size,
        spp,
        views,
        scenes: names,
        no_grid,
    } = o;
    let with_grid = !no_grid;
    let (width, height) = crate::experiment::parse_size(&size)?;
    // The numbers were checked by `Command::check_numbers`.
    crate::check_out_dir(&out)?;
    let names: Vec<String> = if names.is_empty() {
        crate::experiment::DEFAULT_SCENES
            .iter()
            .map(|s| s.to_string())
            .collect()
    } else {
        names
    };
    let mut scenes = Vec::new();
    for name in &names {
        let scene = crate::load_scene(name)?;
        // Random cameras only: none of the scene's own (scored) cameras.
        let cameras = cameras_for(
            &scene,
            &[],
            views,
            &RandomCameraSettings {
                seed: HELD_OUT_SEED,
                ..Default::default()
            },
        )
        .map_err(|e| e.to_string())?;
        scenes.push(SceneSetup {
            id: crate::experiment::scene_id(name),
            scene: Arc::new(scene),
            cameras,
        });
    }
    let mut techniques = vec![TechniqueSetup {
        label: "dl".into(),
        family: "dl".into(),
        description: "direct light".into(),
        technique: Box::new(
            IsrTechnique::new(IsrSettings::dl(), Box::new(CpuRasterizer::new())).named("dl"),
        ),
        single_frame: false,
    }];
    let mut labels = Vec::new();
    for n in crate::techniques::SAMPLES {
        // Beside the grid, the setting with light-space senders (k_isr 1, nothing to tune):
        // what the grid's scale factor stands in for.
        let ls = Setting {
            label: format!("isr-ls-{n}"),
            settings: IsrSettings::with_light_senders(n, crate::techniques::LIGHT_SENDERS),
        };
        let swept = if with_grid { grid(n) } else { Vec::new() };
        for s in swept.into_iter().chain([ls]) {
            labels.push((n, s.label.clone(), s.settings));
            techniques.push(TechniqueSetup {
                label: s.label.clone(),
                family: "isr".into(),
                description: format!("{:?}", s.settings),
                technique: Box::new(
                    IsrTechnique::new(s.settings, Box::new(CpuRasterizer::new())).named(&s.label),
                ),
                single_frame: false,
            });
        }
    }
    let metrics: Vec<Box<dyn Metric>> = vec![Box::new(MeasureMetric::new(Measure::MeanError))];
    let mut x = Experiment {
        settings: ExperimentSettings {
            width,
            height,
            spp,
            bounces: vec![Bounces::Limited(1), Bounces::Unlimited],
            repeats: 1,
            ladder_extend: false,
            out_dir: out.clone(),
            cache_dir: cache,
            error_metric: Measure::MeanError.name().into(),
            correlation_metric: Measure::MeanError.name().into(),
            write_images: false,
            ..Default::default()
        },
        scenes,
        techniques,
        metrics,
    };
    let outcome = x.run().map_err(|e| e.to_string())?;
    let r = &outcome.results;
    let comparison = |label: &str, b: &str| {
        r.summary
            .comparisons
            .iter()
            .find(|c| c.technique == label && c.bounces == b)
    };
    let gain = |label: &str, b: &str| {
        comparison(label, b)
            .map(|c| c.mean_gain)
            .unwrap_or(f64::NEG_INFINITY)
    };
    let better = |label: &str| {
        comparison(label, "1")
            .map(|c| c.share_views_better)
            .unwrap_or(0.0)
    };
    println!(
        "{:<28} {:>12} {:>12} {:>18}",
        "setting", "gain b=1", "gain b=inf", "better than DL b=1"
    );
    for n in crate::techniques::SAMPLES {
        let mut rows: Vec<&(u32, String, IsrSettings)> =
            labels.iter().filter(|l| l.0 == n).collect();
        rows.sort_by(|a, b| gain(&b.1, "1").total_cmp(&gain(&a.1, "1")));
        for (i, (_, label, _)) in rows.iter().enumerate() {
            println!(
                "{:<28} {:>11.2}% {:>11.2}% {:>17.2}%{}",
                label,
                gain(label, "1") * 100.0,
                gain(label, "inf") * 100.0,
                better(label) * 100.0,
                if i == 0 {
                    "  <- most accurate at bounce 1"
                } else {
                    ""
                }
            );
        }
        println!();
    }
    println!("report: {}", outcome.report_md.display());
    Ok(())
}
