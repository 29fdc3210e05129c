//! `cargo xtask experiment`: the main job. Built-in (or glTF) scenes x cameras x the `dl`,
//! `isr`, `relight` and `ibrr` techniques x imalyzer's measures, against the reference path
//! tracer, through bench-harness (precomputation timed per scene as its own column).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use bench_harness::{
    Experiment, ExperimentSettings, RandomCameraSettings, SceneSetup, TechniqueSetup, cameras_for,
    load_camera_list,
};
use gbuffer::CpuRasterizer;
use imalyzer::{Measure, MeasureMetric};
use isr::{Backend, IsrTechnique};
use scene_core::reference::Bounces;
use scene_core::{FrameRequest, Metric, Technique};

use crate::techniques::{ChoiceKind, parse_techniques};

/// The built-in scenes of the default run.
pub const DEFAULT_SCENES: [&str; 4] = ["cornell", "cornell-point", "primitives", "corridor"];

/// The measures every view is compared with.
pub const MEASURES: [Measure; 6] = [
    Measure::MeanError,
    Measure::MeanError8bit,
    Measure::Pearson,
    Measure::Rmse,
    Measure::Ssim,
    Measure::Flip,
];

/// Everything `cargo xtask experiment` takes.
#[derive(Clone, Debug)]
pub struct Options {
    /// Scene names or glTF paths (empty: the defaults).
    pub scenes: Vec<String>,
    /// Comma-separated technique list.
    pub techniques: String,
    /// Views per scene (default: the scene's own cameras).
    pub views: Option<usize>,
    /// Reference spp.
    pub spp: u32,
    /// Bounce limits, comma-separated.
    pub bounces: String,
    /// `WxH`.
    pub size: String,
    /// Output folder.
    pub out: PathBuf,
    /// Run every method on the GPU through its frame contract, with GPU references.
    pub gpu: bool,
    /// Camera lists, `SCENE=FILE.json`.
    pub cameras: Vec<String>,
    /// Timed repeats.
    pub repeats: u32,
    /// Seed of the reference and the random cameras.
    pub seed: u64,
    /// Write a POV-Ray file per view (and render it when povray is on PATH).
    pub povray: bool,
    /// The measure deciding "closer" and the gain.
    pub error_metric: String,
    /// Reference cache folder.
    pub cache: Option<PathBuf>,
    /// Run the equal-error ladder.
    pub ladder: bool,
    /// The relighting sequence's `SCENE[:CAMERA]` (default: corridor, else the first scene).
    pub sequence: Option<String>,
    /// Frames of the sequence (0: none).
    pub sequence_frames: usize,
    /// Samples per pixel of the sequence's references (default spp / 2).
    pub sequence_spp: Option<u32>,
    /// Timed still-camera frames per view (0: not measured).
    pub still_repeats: u32,
    /// The preset the options came from (recorded in results.json).
    pub preset: String,
    /// Run only this share of the work.
    pub shard: Option<bench_harness::Shard>,
    /// Write a generated results document (docs/results.md) from the run's results.json.
    pub write_docs: Option<PathBuf>,
}

/// A named set of the experiment's sizes: what `--preset` chooses; any option given on
/// the command line overrides its value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preset {
    /// `default`, `full` or `hd`.
    pub name: &'static str,
    /// What it is for, in words.
    pub about: &'static str,
    /// Image size.
    pub size: &'static str,
    /// Image size with `--gpu`, when it differs.
    pub gpu_size: Option<&'static str>,
    /// Reference spp.
    pub spp: u32,
    /// Technique list.
    pub techniques: &'static str,
    /// Moving-camera timed frames per view.
    pub repeats: u32,
    /// Still-camera timed frames per view.
    pub still_repeats: u32,
    /// Frames of the relighting sequence.
    pub sequence_frames: usize,
}

/// The presets: `default` answers in minutes on 2 cores with every method, both bounce
/// limits, the ladder and a sequence; `full` is the thorough run; `hd` runs every method at
/// the sizes users render (its references take hours on 2 cores, minutes on a GPU with
/// `--gpu`).
pub const PRESETS: [Preset; 3] = [
    Preset {
        name: "default",
        about: "every method at one setting each (DL, ISR in both modes at 24/48/80 samples and \
                with every bounce at 80, relighting at 256 elements, the IBRR at LDC 128 with 64 \
                IRPLs), 128x96, 512 spp",
        size: "128x96",
        gpu_size: None,
        spp: 512,
        techniques: "dl,isr,isr-mb-80,relight-256,ibrr-128-64",
        repeats: 3,
        still_repeats: 2,
        sequence_frames: 8,
    },
    Preset {
        name: "full",
        about: "every method at every setting (ISR with one bounce and with every bounce, \
                relighting at 256 and 1024 elements, the IBRR at LDC 128/64 IRPLs and 256/184), \
                256x192, 512 spp",
        size: "256x192",
        gpu_size: None,
        spp: 512,
        techniques: "dl,isr,isr-mb,relight,ibrr",
        repeats: 3,
        still_repeats: 3,
        sequence_frames: 8,
    },
    Preset {
        name: "hd",
        about: "every method (DL, ISR at 24/48/80 samples and with every bounce at 80, \
                relighting at 1024 elements, the IBRR \
                at LDC 256 with 184 IRPLs) at the sizes users render: 1280x720, 1920x1080 with \
                --gpu (whose references and ladder then come from the GPU path tracer), 256 spp",
        size: "1280x720",
        gpu_size: Some("1920x1080"),
        spp: 256,
        techniques: "dl,isr-default,isr-mb-80,relight-1024,ibrr-256-184",
        repeats: 3,
        still_repeats: 2,
        sequence_frames: 4,
    },
];

impl Preset {
    /// The preset called `name`.
    pub fn named(name: &str) -> Result<Self, String> {
        PRESETS
            .iter()
            .find(|p| p.name == name.trim().to_ascii_lowercase())
            .copied()
            .ok_or_else(|| {
                let names: Vec<&str> = PRESETS.iter().map(|p| p.name).collect();
                format!("unknown preset '{name}' (known: {})", names.join(", "))
            })
    }
}

/// The sequence the options ask for, checked against the run's scenes.
fn sequence_spec(
    o: &Options,
    scenes: &[SceneSetup],
    bounces: &[Bounces],
) -> Result<Option<bench_harness::SequenceSpec>, String> {
    if o.sequence_frames == 0 {
        return Ok(None);
    }
    let (scene, camera) = match &o.sequence {
        Some(s) => match s.rsplit_once(':') {
            Some((sc, cam)) if cam.chars().all(|c| c.is_ascii_digit()) && !cam.is_empty() => (
                sc.to_string(),
                cam.parse::<usize>()
                    .map_err(|_| format!("--sequence: bad camera index in '{s}'"))?,
            ),
            _ => (s.clone(), 0),
        },
        None => match scenes
            .iter()
            .find(|s| s.id == "corridor")
            .or(scenes.first())
        {
            Some(s) => (s.id.clone(), 0),
            None => return Ok(None),
        },
    };
    let Some(sc) = scenes.iter().find(|s| s.id == scene) else {
        let ids: Vec<&str> = scenes.iter().map(|s| s.id.as_str()).collect();
        return Err(format!(
            "--sequence names scene '{scene}', which is not in the run ({})",
            ids.join(", ")
        ));
    };
    if camera >= sc.cameras.len() {
        return Err(format!(
            "--sequence: camera {camera} does not exist ({} view(s) of '{scene}')",
            sc.cameras.len()
        ));
    }
    let spp = o.sequence_spp.unwrap_or((o.spp / 2).max(1));
    if spp == 0 {
        return Err("--sequence-spp must be positive".into());
    }
    Ok(Some(bench_harness::SequenceSpec {
        scene,
        camera,
        frames: o.sequence_frames,
        spp,
        bounces: *bounces.last().unwrap_or(&Bounces::Unlimited),
    }))
}

/// POV-Ray as a [`Technique`]: each frame exports the scene and camera with the thesis'
/// radiosity block ([`bench_harness::povray`]), runs `povray` and reads its EXR back. An extra
/// reference column (the thesis' ground truth), compared with the path tracer like any
/// technique.
pub struct PovrayTechnique {
    dir: PathBuf,
    frame: u64,
    scene: Option<Arc<scene_core::Scene>>,
}

impl PovrayTechnique {
    /// Renders through files in `dir`.
    pub fn new(dir: PathBuf) -> Self {
        Self {
            dir,
            frame: 0,
            scene: None,
        }
    }
}

impl Technique for PovrayTechnique {
    fn name(&self) -> &str {
        "povray"
    }

    fn prepare(&mut self, scene: Arc<scene_core::Scene>) -> Result<(), scene_core::Error> {
        self.scene = Some(scene);
        Ok(())
    }

    /// Renders with the scene's own lights: POV-Ray's radiosity has no per-light state, so
    /// a frame whose light state is not the default is refused.
    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<scene_core::Image, scene_core::Error> {
        let fail = |m: String| scene_core::Error::InvalidArgument(format!("povray: {m}"));
        let Some(scene) = self.scene.clone() else {
            return Err(scene_core::Error::NotPrepared("povray".into()));
        };
        if !frame.lights.is_default() {
            return Err(fail("POV-Ray renders the scene's lights as they are; the frame asks for another light state".into()));
        }
        let (width, height) = (frame.width, frame.height);
        let camera = frame
            .view
            .to_camera("view")
            .ok_or_else(|| fail("POV-Ray takes symmetric perspective views only".into()))?;
        let (scene, camera) = (&*scene, &camera);
        std::fs::create_dir_all(&self.dir).map_err(|e| fail(e.to_string()))?;
        self.frame += 1;
        let stem = format!(
            "{}-{}-{}",
            bench_harness::experiment::slug(&scene.name),
            bench_harness::experiment::slug(&camera.name),
            self.frame
        );
        let pov = self.dir.join(format!("{stem}.pov"));
        let exr = self.dir.join(format!("{stem}.exr"));
        bench_harness::povray::write(&pov, scene, camera, width, height)
            .map_err(|e| fail(e.to_string()))?;
        let out = std::process::Command::new("povray")
            .arg(format!("+I{}", pov.display()))
            .arg(format!("+O{}", exr.display()))
            .args(["+FE", "-D", "-V", "+A0.1", "+AM2"])
            .arg(format!("+W{width}"))
            .arg(format!("+H{height}"))
            .output()
            .map_err(|e| fail(format!("cannot run povray: {e}")))?;
        if !out.status.success() {
            let err = String::from_utf8_lossy(&out.stderr);
            let tail: String = err.lines().rev().take(5).collect::<Vec<_>>().join(" / ");
            return Err(fail(format!("{} failed: {tail}", pov.display())));
        }
        Ok(scene_core::Image::read_exr(&exr)?)
    }
}

/// Parses `WxH`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size must be WxH, got '{s}'"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("size must be WxH, got '{s}'"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("size must be WxH, got '{s}'"))?;
    if w == 0 || h == 0 || w > 8192 || h > 8192 {
        return Err(format!("size must be between 1x1 and 8192x8192, got '{s}'"));
    }
    Ok((w, h))
}

/// Parses a comma-separated bounce list (`1,inf`).
pub fn parse_bounces(s: &str) -> Result<Vec<Bounces>, String> {
    let v: Vec<Bounces> = s
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(|t| t.parse::<Bounces>())
        .collect::<Result<_, _>>()?;
    if v.is_empty() {
        return Err("no bounce limit given".into());
    }
    Ok(v)
}

pub(crate) fn scene_id(spec: &str) -> String {
    let lower = spec.to_ascii_lowercase();
    if lower.ends_with(".gltf") || lower.ends_with(".glb") {
        Path::new(spec)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".into())
    } else {
        spec.trim().replace([' ', ':'], "-")
    }
}

/// The experiment's counts against their stated ranges (docs/hostile-files.md), before any
/// scene is loaded or camera drawn: `--spp`, `--views`, `--repeats`, `--still-repeats`,
/// `--sequence-frames`, `--sequence-spp`.
pub fn check_numbers(o: &Options) -> Result<(), String> {
    use scene_core::range::{SPP, check_opt};
    crate::ranged("--spp", o.spp, SPP)?;
    check_opt("--views", o.views, 1..=1000).map_err(|e| e.to_string())?;
    crate::ranged("--repeats", o.repeats, 1..=100)?;
    crate::ranged("--still-repeats", o.still_repeats, 0..=100)?;
    crate::ranged("--sequence-frames", o.sequence_frames, 0..=64)?;
    check_opt("--sequence-spp", o.sequence_spp, SPP).map_err(|e| e.to_string())?;
    Ok(())
}

/// The command line that runs exactly `o` (every size spelled out, so a later reader can
/// repeat the run whatever the presets have become).
pub fn command_line(o: &Options) -> String {
    let mut c = format!(
        "cargo xtask experiment --preset {} --size {} --spp {} --bounces {} --techniques {} \
         --repeats {} --still-repeats {} --sequence-frames {} --seed {}",
        o.preset,
        o.size,
        o.spp,
        o.bounces,
        o.techniques,
        o.repeats,
        o.still_repeats,
        o.sequence_frames,
        o.seed
    );
    for sc in &o.scenes {
        c.push_str(&format!(" --scene {sc}"));
    }
    if let Some(v) = o.views {
        c.push_str(&format!(" --views {v}"));
    }
    if let Some(q) = o.sequence_spp {
        c.push_str(&format!(" --sequence-spp {q}"));
    }
    if let Some(q) = &o.sequence {
        c.push_str(&format!(" --sequence {q}"));
    }
    if !o.ladder {
        c.push_str(" --no-ladder");
    }
    if o.gpu {
        c.push_str(" --gpu");
    }
    if o.error_metric != "mean-error" {
        c.push_str(&format!(" --error-metric {}", o.error_metric));
    }
    if let Some(k) = o.shard {
        c.push_str(&format!(" --shard {k}"));
    }
    c
}

/// Builds the experiment the options describe (scenes loaded, cameras parsed or drawn).
pub fn build(o: &Options) -> Result<Experiment, String> {
    let (width, height) = parse_size(&o.size)?;
    let bounces = parse_bounces(&o.bounces)?;
    let choices = parse_techniques(&o.techniques)?;
    check_numbers(o)?;
    if let (Some(k), Some(doc)) = (o.shard, &o.write_docs) {
        return Err(format!(
            "--write-docs {} with --shard {k}: a shard holds a share of the views, not the \
             run a results document describes; run `cargo xtask experiment merge DIR... --out \
             DIR --write-docs {}` once every shard is done",
            doc.display(),
            doc.display()
        ));
    }
    crate::check_out_dir(&o.out)?;
    let backend = if o.gpu {
        let ctx = scene_core::gpu::GpuContext::new()
            .map_err(|e| format!("--gpu: {e} (run with --cpu to stay on the CPU)"))?;
        Backend::Gpu(ctx)
    } else {
        Backend::Cpu
    };
    let specs: Vec<String> = if o.scenes.is_empty() {
        DEFAULT_SCENES.iter().map(|s| s.to_string()).collect()
    } else {
        o.scenes.clone()
    };
    let mut lists: Vec<(String, PathBuf)> = Vec::new();
    for c in &o.cameras {
        let (scene, file) = c
            .split_once('=')
            .ok_or_else(|| format!("--cameras takes SCENE=FILE.json, got '{c}'"))?;
        lists.push((scene.trim().to_string(), PathBuf::from(file.trim())));
    }
    let mut scenes = Vec::new();
    for spec in &specs {
        let lower = spec.to_ascii_lowercase();
        if (lower.ends_with(".gltf") || lower.ends_with(".glb")) && !Path::new(spec).exists() {
            return Err(format!("scene file '{spec}' does not exist"));
        }
        let opened = crate::open_scene_noted(spec)?;
        let (scene, moved) = (opened.scene, opened.translation);
        let id = scene_id(spec);
        let given = match lists.iter().find(|(s, _)| s == spec || *s == id) {
            // A camera list is in the file's coordinates: read it against the scene as the
            // file has it, then move it with the scene.
            Some((_, file)) => {
                let unmoved;
                let file_scene = if moved == scene_core::glam::Vec3::ZERO {
                    &scene
                } else {
                    unmoved = scene.clone().translated(-moved);
                    &unmoved
                };
                load_camera_list(file, file_scene)
            }
            .map_err(|e| e.to_string())?
            .into_iter()
            .map(|mut c| {
                c.position += moved;
                c.target += moved;
                c
            })
            .collect(),
            None => scene.cameras.clone(),
        };
        let count = o.views.unwrap_or(given.len().max(1));
        let random = RandomCameraSettings {
            seed: o.seed,
            ..Default::default()
        };
        let cameras = cameras_for(&scene, &given, count, &random).map_err(|e| e.to_string())?;
        scenes.push(SceneSetup {
            id,
            scene: Arc::new(scene),
            cameras,
        });
    }
    for (s, _) in &lists {
        if !scenes.iter().any(|sc| &sc.id == s) && !specs.contains(s) {
            return Err(format!(
                "--cameras names scene '{s}', which is not in the run"
            ));
        }
    }
    let mut techniques: Vec<TechniqueSetup> = choices
        .into_iter()
        .map(|c| {
            if let Backend::Gpu(ctx) = &backend {
                let description = format!(
                    "{}; on the GPU frame contract over a GPU G-buffer, the method's frame \
                     timed on the device",
                    c.description.replace(", CPU rasteriser G-buffer", "")
                );
                let make = match &c.kind {
                    ChoiceKind::Isr(settings) => crate::gpu_frames::isr_maker(*settings),
                    ChoiceKind::Relight { elements, .. } => crate::gpu_frames::relight_maker(
                        *elements,
                        relight_pr::packed::Precision::F32,
                    ),
                    ChoiceKind::Ibrr {
                        ldc,
                        irpls,
                        camera_importance,
                    } => crate::gpu_frames::ibrr_maker(ibrr_ldc::IbrrSettings {
                        target_error: 0.0,
                        resolution: *ldc,
                        irpls: *irpls,
                        camera_importance: *camera_importance,
                        ..Default::default()
                    }),
                };
                return Ok(TechniqueSetup {
                    technique: Box::new(crate::gpu_frames::FrameTechnique::new(
                        &c.label, ctx, make,
                    )?),
                    label: c.label,
                    family: c.family,
                    description,
                    single_frame: false,
                });
            }
            let technique: Box<dyn Technique> = match &c.kind {
                ChoiceKind::Isr(settings) => Box::new(
                    IsrTechnique::new(*settings, Box::new(CpuRasterizer::new()))
                        .with_backend(backend.clone())
                        .named(&c.label),
                ),
                ChoiceKind::Relight {
                    elements,
                    shadow_maps,
                } => {
                    let mut t = relight_pr::RelightTechnique::new(
                        relight_pr::MeshSettings::elements(*elements),
                        relight_pr::SolverSettings::default(),
                        Box::new(CpuRasterizer::new()),
                    )
                    .named(&c.label);
                    if *shadow_maps {
                        t.direct = relight_pr::direct::DirectLight::shadow_maps();
                    }
                    match &backend {
                        Backend::Gpu(ctx) => Box::new(t.on_gpu(ctx.clone())),
                        _ => Box::new(t),
                    }
                }
                ChoiceKind::Ibrr {
                    ldc,
                    irpls,
                    camera_importance,
                } => {
                    let settings = ibrr_ldc::IbrrSettings {
                        target_error: 0.0,
                        resolution: *ldc,
                        irpls: *irpls,
                        camera_importance: *camera_importance,
                        ..Default::default()
                    };
                    let t = ibrr_ldc::IbrrTechnique::new(settings, Box::new(CpuRasterizer::new()))
                        .named(&c.label);
                    match &backend {
                        Backend::Gpu(ctx) => Box::new(t.on_gpu(ctx.clone())),
                        _ => Box::new(t),
                    }
                }
            };
            Ok(TechniqueSetup {
                label: c.label,
                family: c.family,
                description: c.description,
                technique,
                single_frame: false,
            })
        })
        .collect::<Result<_, String>>()?;
    let sequence = sequence_spec(o, &scenes, &bounces)?;
    if o.povray {
        if bench_harness::povray::povray_available() {
            techniques.push(TechniqueSetup {
                label: "povray".into(),
                family: "povray".into(),
                description: "POV-Ray 3.7 with the thesis' radiosity block (Table 1), one frame"
                    .into(),
                technique: Box::new(PovrayTechnique::new(o.out.join("povray"))),
                single_frame: true,
            });
        } else {
            eprintln!(
                "note: povray is not on PATH; --povray writes the scene files without rendering them"
            );
        }
    }
    let error_metric = Measure::parse(&o.error_metric)
        .filter(|m| MEASURES.contains(m) && m.lower_is_better())
        .map(|m| m.name().to_string())
        .ok_or_else(|| {
            let known: Vec<&str> = MEASURES
                .iter()
                .filter(|m| m.lower_is_better())
                .map(|m| m.name())
                .collect();
            format!(
                "unknown error metric '{}' (known: {})",
                o.error_metric,
                known.join(", ")
            )
        })?;
    let metrics: Vec<Box<dyn Metric>> = MEASURES
        .into_iter()
        .map(|m| Box::new(MeasureMetric::new(m)) as Box<dyn Metric>)
        .collect();
    Ok(Experiment {
        settings: ExperimentSettings {
            width,
            height,
            spp: o.spp,
            bounces,
            seed: o.seed,
            warmup: 1,
            repeats: o.repeats.max(1),
            still_repeats: o.still_repeats,
            ladder_extend: true,
            shard: o.shard,
            run_info: bench_harness::RunInfo {
                command: command_line(o),
                preset: o.preset.clone(),
                threads: rayon::current_num_threads(),
                tuning: vec![crate::sweep::TUNING_NOTE.to_string()],
                ..Default::default()
            },
            out_dir: o.out.clone(),
            cache_dir: o.cache.clone(),
            reference_renderer: match &backend {
                Backend::Gpu(ctx) => Some(Arc::new(crate::gpu_frames::GpuReference::new(ctx))),
                _ => None,
            },
            baseline: "dl".into(),
            error_metric,
            correlation_metric: Measure::Pearson.name().into(),
            headline: Some("isr-80".into()).filter(|h| {
                parse_techniques(&o.techniques)
                    .map(|c| c.iter().any(|c| &c.label == h))
                    .unwrap_or(false)
            }),
            progress: true,
            stop_after_views: None,
            exposure: 0.0,
            write_images: true,
            ladder_spp: if o.ladder {
                bench_harness::experiment::default_ladder(o.spp)
            } else {
                Vec::new()
            },
            sequence,
        },
        scenes,
        techniques,
        metrics,
    })
}

/// The summary table printed at the end.
pub fn summary_text(r: &bench_harness::Results) -> String {
    use bench_harness::report::{fmt_2, fmt_ms, fmt_pct, fmt_s};
    let mut s = String::new();
    s.push_str(&format!(
        "{:<26} {:>6} {:>12} {:>14} {:>10}\n",
        "technique", "views", "total (s)", "frame (ms)", "FPS"
    ));
    for t in &r.summary.times {
        s.push_str(&format!(
            "{:<26} {:>6} {:>12} {:>14} {:>10}\n",
            t.label,
            t.views,
            fmt_s(t.total_s),
            fmt_ms(t.avg_frame_ms),
            fmt_2(t.avg_fps)
        ));
    }
    s.push_str(&format!(
        "\n{:<18} {:>7} {:>13} {:>11} {:>14} {:>16}\n",
        "against dl", "bounces", "views better", "mean gain", "pixels closer", "changed closer"
    ));
    for c in &r.summary.comparisons {
        s.push_str(&format!(
            "{:<18} {:>7} {:>13} {:>11} {:>14} {:>16}\n",
            c.technique,
            c.bounces,
            fmt_pct(c.share_views_better),
            fmt_pct(c.mean_gain),
            fmt_pct(c.share_pixels_closer),
            fmt_pct(c.share_changed_pixels_closer)
        ));
    }
    if !r.summary.ranking.is_empty() {
        s.push_str(&format!(
            "\nranking by mean error at bounce limit {} (frame: moving camera; still: the same view again)\n{:<5} {:<18} {:>12} {:>12} {:>26} {:>11} {:>11} {:>13} {:>10}\n",
            r.summary.ranking[0].bounces,
            "rank",
            "technique",
            "mean error",
            "surface err",
            "surface bias R/G/B",
            "frame (ms)",
            "still (ms)",
            "precomp (s)",
            "speedup"
        ));
        for k in &r.summary.ranking {
            s.push_str(&format!(
                "{:<5} {:<18} {:>12} {:>12} {:>26} {:>11} {:>11} {:>13} {:>10}\n",
                k.rank,
                k.technique,
                bench_harness::report::fmt_err(k.mean_error),
                k.surface_error
                    .map(bench_harness::report::fmt_err)
                    .unwrap_or_else(|| "-".into()),
                k.surface_bias
                    .map(bench_harness::report::fmt_bias)
                    .unwrap_or_else(|| "-".into()),
                fmt_ms(k.frame_ms),
                k.still_frame_ms.map(fmt_ms).unwrap_or_else(|| "-".into()),
                fmt_s(k.prepare_s),
                k.speedup.clone().unwrap_or_else(|| "-".into())
            ));
        }
    }
    if let Some(q) = &r.sequence {
        s.push_str(&format!(
            "\nrelighting sequence ({} / {}, {} frames): mean frame (ms), worst error / first-frame error\n",
            q.scene,
            q.camera,
            q.frames.len()
        ));
        for (label, _) in &q.prepare_s {
            let v = q.series(label);
            let mean_ms = v.iter().map(|p| p.0).sum::<f64>() / v.len().max(1) as f64 * 1e3;
            let first = v.first().map(|p| p.1).unwrap_or(0.0);
            let worst = v.iter().map(|p| p.1).fold(0.0, f64::max);
            s.push_str(&format!(
                "{:<18} {:>11} {:>9}\n",
                label,
                fmt_ms(mean_ms),
                if first > 0.0 {
                    fmt_2(worst / first)
                } else {
                    "-".into()
                }
            ));
        }
    }
    s
}

/// Runs `cargo xtask experiment`.
pub fn run(o: &Options) -> Result<(), String> {
    let mut experiment = build(o)?;
    let views: usize = experiment.scenes.iter().map(|s| s.cameras.len()).sum();
    eprintln!(
        "experiment: {} scene(s), {views} view(s), {} technique(s), {}x{}, reference {} spp, bounces {}",
        experiment.scenes.len(),
        experiment.techniques.len(),
        experiment.settings.width,
        experiment.settings.height,
        experiment.settings.spp,
        o.bounces
    );
    if o.povray {
        for sc in &experiment.scenes {
            for (i, cam) in sc.cameras.iter().enumerate() {
                let dir = o.out.join("povray");
                std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
                let file = dir.join(format!(
                    "{}--{i:02}-{}.pov",
                    bench_harness::experiment::slug(&sc.id),
                    bench_harness::experiment::slug(&cam.name)
                ));
                bench_harness::povray::write(
                    &file,
                    &sc.scene,
                    cam,
                    experiment.settings.width,
                    experiment.settings.height,
                )
                .map_err(|e| e.to_string())?;
            }
        }
        eprintln!("POV-Ray files in {}", o.out.join("povray").display());
    }
    let outcome = experiment.run().map_err(|e| e.to_string())?;
    eprintln!(
        "{} view(s) computed, {} resumed, {} reference render(s), {:.1} s",
        outcome.views_computed, outcome.views_resumed, outcome.reference_renders, outcome.seconds
    );
    print!("{}", summary_text(&outcome.results));
    if let Some(k) = o.shard {
        println!(
            "\nshard {k}: results in {} (combine every shard with `cargo xtask experiment merge DIR... --out DIR`)",
            outcome.results_json.display()
        );
        return Ok(());
    }
    println!("\nreport: {}", outcome.report_md.display());
    println!("report: {}", outcome.report_html.display());
    println!("results: {}", outcome.results_json.display());
    if let Some(doc) = &o.write_docs {
        crate::results_doc::write(&outcome.results, doc)?;
        println!("document: {}", doc.display());
    }
    Ok(())
}

/// Runs `cargo xtask experiment merge`.
pub fn merge(dirs: &[PathBuf], out: &Path, write_docs: Option<&Path>) -> Result<(), String> {
    crate::check_out_dir(out)?;
    let m = bench_harness::merge(dirs, out, Some("isr-80")).map_err(|e| e.to_string())?;
    eprintln!(
        "merged {} shard(s): {} view(s){}",
        m.results.run.merged_shards,
        m.results.views.len(),
        if m.results.sequence.is_some() {
            " and the relighting sequence"
        } else {
            ""
        }
    );
    print!("{}", summary_text(&m.results));
    println!("\nreport: {}", m.report_md.display());
    println!("report: {}", m.report_html.display());
    println!("results: {}", m.results_json.display());
    if let Some(doc) = write_docs {
        crate::results_doc::write(&m.results, doc)?;
        println!("document: {}", doc.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options() -> Options {
        Options {
            scenes: vec!["cornell".into()],
            techniques: "dl,isr-24".into(),
            views: Some(1),
            spp: 2,
            bounces: "1".into(),
            size: "32x24".into(),
            out: std::env::temp_dir().join(format!("xtask-experiment-{}", std::process::id())),
            gpu: false,
            cameras: Vec::new(),
            repeats: 1,
            seed: 1,
            povray: false,
            error_metric: "mean-error".into(),
            cache: None,
            ladder: false,
            sequence: None,
            sequence_frames: 0,
            sequence_spp: None,
            still_repeats: 0,
            preset: "default".into(),
            shard: None,
            write_docs: None,
        }
    }

    fn err(o: &Options) -> String {
        match build(o) {
            Ok(_) => panic!("expected an error"),
            Err(e) => e,
        }
    }

    #[test]
    fn a_shard_does_not_write_the_results_document() {
        let mut o = options();
        o.out = std::env::temp_dir().join(format!("xtask-shard-docs-{}", std::process::id()));
        o.shard = Some(bench_harness::Shard::parse("1/2").unwrap());
        o.write_docs = Some(o.out.join("results.md"));
        let e = err(&o);
        assert!(
            e.contains("--write-docs") && e.contains("experiment merge"),
            "{e}"
        );
        assert!(!o.out.exists(), "nothing is written for a refused run");
    }

    #[test]
    fn missing_scene_files_unknown_techniques_and_bad_camera_lists_are_clear_errors() {
        let mut o = options();
        o.scenes = vec!["/no/such/scene.gltf".into()];
        let e = err(&o);
        assert!(
            e.contains("/no/such/scene.gltf") && e.contains("does not exist"),
            "{e}"
        );

        let mut o = options();
        o.techniques = "dl,nope".into();
        assert!(err(&o).contains("unknown technique 'nope'"));

        let dir = std::env::temp_dir().join(format!("xtask-cams-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("broken.json");
        std::fs::write(&file, "[{\"position\": [1, 2, 3], \"target\": ").unwrap();
        let mut o = options();
        o.cameras = vec![format!("cornell={}", file.display())];
        let e = err(&o);
        assert!(
            e.contains("camera list") && e.contains("broken.json"),
            "{e}"
        );

        let mut o = options();
        o.size = "64by48".into();
        assert!(err(&o).contains("WxH"));
        let mut o = options();
        o.bounces = "one".into();
        assert!(err(&o).contains("bounces"));
        let mut o = options();
        o.error_metric = "psnr".into();
        assert!(err(&o).contains("unknown error metric 'psnr'"));
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_camera_list_and_random_views_build_the_scene_setup() {
        let dir = std::env::temp_dir().join(format!("xtask-cams-ok-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("cams.json");
        std::fs::write(
            &file,
            "[{\"name\": \"mine\", \"position\": [0.278, 0.273, -0.8], \"target\": [0.278, 0.273, 0.0], \"fov\": 39}]",
        )
        .unwrap();
        let mut o = options();
        o.cameras = vec![format!("cornell={}", file.display())];
        o.views = Some(3);
        let x = build(&o).unwrap();
        let names: Vec<&str> = x.scenes[0]
            .cameras
            .iter()
            .map(|c| c.name.as_str())
            .collect();
        assert_eq!(names, ["mine", "random0", "random1"]);
        assert_eq!(x.techniques.len(), 2);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn povray_renders_the_exported_scene_when_it_is_installed() {
        if !bench_harness::povray::povray_available() {
            eprintln!("povray is not on PATH; skipping the POV-Ray render check");
            return;
        }
        let scene = scene_core::builtin::scene("cornell-point").unwrap();
        let dir = std::env::temp_dir().join(format!("xtask-povray-{}", std::process::id()));
        let mut t = PovrayTechnique::new(dir.clone());
        t.prepare(Arc::new(scene.clone())).unwrap();
        let img = t
            .render(&FrameRequest::from_camera(
                &scene.cameras[0],
                32,
                24,
                &scene_core::LightState::default(),
            ))
            .unwrap();
        assert_eq!((img.width, img.height), (32, 24));
        assert_eq!(img.non_finite_count(), 0);
        assert!(img.mean().element_sum() > 0.0);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn relighting_and_the_ibrr_run_in_the_experiment_with_their_precomputation_timed() {
        let mut o = options();
        o.out = std::env::temp_dir().join(format!("xtask-tiny-methods-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&o.out);
        o.scenes = vec!["cornell-point".into()];
        o.size = "32x24".into();
        o.spp = 64;
        o.bounces = "inf".into();
        o.techniques = "dl,relight-64,ibrr-64-48".into();
        let mut x = build(&o).unwrap();
        assert_eq!(
            x.techniques
                .iter()
                .map(|t| t.family.as_str())
                .collect::<Vec<_>>(),
            ["dl", "relight", "ibrr"]
        );
        x.settings.progress = false;
        let out = x.run().unwrap();
        let r = &out.results;
        let view = &r.views[0];
        for label in ["relight-64", "ibrr-64-48"] {
            let t = view
                .techniques
                .iter()
                .find(|t| t.label == label)
                .unwrap_or_else(|| panic!("{label} missing"));
            // Precomputation is timed apart from the frames.
            assert!(t.prepare_s > 0.0, "{label}: prepare {}", t.prepare_s);
            for e in &t.errors {
                assert!(e.metrics.iter().all(|(_, v)| v.is_finite()), "{label}");
            }
        }
        let err = |label: &str| {
            view.techniques
                .iter()
                .find(|t| t.label == label)
                .unwrap()
                .errors[0]
                .metric(Measure::MeanError.name())
                .unwrap()
        };
        // Against the unlimited reference relighting is closer than direct light alone
        // (which misses every bounce). The IBRR at this tiny setting (48 IRPLs, 32 x 24
        // pixels, a 64-spp reference) is as far as DL by eq. 19 (measured 0.0339 against
        // 0.0346; relighting 0.0217): its instant-radiosity noise is the price of so few
        // IRPLs, so only its figures' presence is asserted.
        let (dl, relight, ibrr) = (err("dl"), err("relight-64"), err("ibrr-64-48"));
        eprintln!("mean error: dl {dl:.4}, relight {relight:.4}, ibrr {ibrr:.4}");
        assert!(relight < 0.8 * dl, "dl {dl}, relight {relight}");
        assert!(ibrr.is_finite() && ibrr > 0.0);
        // The report's break-even table: a row per technique; DL (no precomputation) and
        // the methods that precompute are compared, never a technique with itself.
        let md = std::fs::read_to_string(o.out.join("report.md")).unwrap();
        let table = md
            .split("## Break-even")
            .nth(1)
            .expect("a break-even section");
        for label in ["dl", "relight-64", "ibrr-64-48"] {
            assert!(
                table.contains(&format!("| {label} |")),
                "{label} row missing"
            );
        }
        assert!(
            ["after ", "first ", "always", "never"]
                .iter()
                .any(|w| table.contains(w)),
            "{table}"
        );
        std::fs::remove_dir_all(&o.out).ok();
    }

    #[test]
    fn the_main_job_runs_end_to_end_on_a_tiny_setting_and_resumes() {
        let mut o = options();
        o.out = std::env::temp_dir().join(format!("xtask-tiny-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&o.out);
        o.views = Some(2);
        o.size = "64x48".into();
        o.spp = 4;
        o.bounces = "1,inf".into();
        o.techniques = "dl,isr-24,isr-thesis-24".into();
        let mut x = build(&o).unwrap();
        x.settings.progress = false;
        let first = x.run().unwrap();
        assert_eq!(first.views_computed, 2);
        // 3 techniques x 2 views x (1 warm-up + 1 repeat).
        assert_eq!(first.technique_renders, 12);
        let r = &first.results;
        assert_eq!(r.summary.comparisons.len(), 4);
        assert_eq!(r.metrics.len(), 6);
        for v in &r.views {
            for t in &v.techniques {
                for e in &t.errors {
                    assert_eq!(e.metrics.len(), 6);
                    assert!(e.metrics.iter().all(|(_, x)| x.is_finite()));
                }
            }
        }
        for f in ["results.json", "report.md", "report.html"] {
            assert!(o.out.join(f).is_file(), "{f}");
        }
        assert!(summary_text(&first.results).contains("isr-thesis-24"));
        // A rerun with the same options renders nothing.
        let mut again = build(&o).unwrap();
        again.settings.progress = false;
        let second = again.run().unwrap();
        assert_eq!((second.views_resumed, second.technique_renders), (2, 0));
        assert_eq!(second.reference_renders, 0);
        std::fs::remove_dir_all(&o.out).ok();
    }

    /// Every cell of the row of `table` whose first cell is `first`.
    fn md_row(table: &str, first: &str) -> Vec<String> {
        table
            .lines()
            .map(|l| {
                l.trim()
                    .trim_matches('|')
                    .split('|')
                    .map(|c| c.trim().to_string())
                    .collect::<Vec<_>>()
            })
            .find(|c| c.first().map(String::as_str) == Some(first))
            .unwrap_or_else(|| panic!("no row '{first}'"))
    }

    #[test]
    fn every_technique_runs_with_the_ladder_and_a_relighting_sequence_and_the_reports_agree() {
        let mut o = options();
        o.out = std::env::temp_dir().join(format!("xtask-every-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&o.out);
        o.scenes = vec!["corridor".into()];
        o.views = Some(2);
        o.size = "48x36".into();
        o.spp = 32;
        o.bounces = "1,inf".into();
        o.techniques = "dl,isr-24,isr-thesis-24,relight-256,ibrr-64-48".into();
        o.ladder = true;
        o.sequence_frames = 8;
        o.sequence_spp = Some(32);
        let mut x = build(&o).unwrap();
        x.settings.progress = false;
        let out = x.run().unwrap();
        let r = &out.results;
        let labels = ["dl", "isr-24", "isr-thesis-24", "relight-256", "ibrr-64-48"];
        // Every output: results, both reports, every image and error map of every view.
        for f in ["results.json", "report.md", "report.html"] {
            assert!(o.out.join(f).is_file(), "{f}");
        }
        let json: bench_harness::Results =
            serde_json::from_str(&std::fs::read_to_string(o.out.join("results.json")).unwrap())
                .unwrap();
        assert_eq!(&json, r);
        assert_eq!(r.views.len(), 2);
        for v in &r.views {
            let dir = o.out.join(bench_harness::experiment::view_dir(
                &v.scene,
                v.camera_index,
                &v.camera_name(),
            ));
            for l in labels {
                for f in [format!("{l}.png"), format!("errmap-{l}-binf.png")] {
                    assert!(dir.join(&f).is_file(), "{f}");
                }
            }
            // The ladder (1, 2, 4 spp, extended by doubling up to 16 where a technique is
            // closer than its finest rung) at both bounce limits.
            for rf in &v.references {
                let spps: Vec<u32> = rf.ladder.iter().map(|p| p.spp).collect();
                assert!(
                    spps.starts_with(&[1, 2, 4])
                        && spps.windows(2).all(|w| w[1] == 2 * w[0])
                        && *spps.last().unwrap() <= 16,
                    "{spps:?}"
                );
            }
        }
        let md = std::fs::read_to_string(o.out.join("report.md")).unwrap();
        let html = std::fs::read_to_string(o.out.join("report.html")).unwrap();
        // The ranking in all three.
        let ranking = md.split("## Ranking").nth(1).unwrap();
        assert_eq!(r.summary.ranking.len(), labels.len());
        for k in &r.summary.ranking {
            let c = md_row(ranking, &k.rank.to_string());
            assert_eq!(c[1], k.technique);
            assert_eq!(c[2], bench_harness::report::fmt_err(k.mean_error));
            assert!(html.contains(&format!(
                "<td>{}</td><td>{}</td><td>{}</td>",
                k.rank, k.technique, c[2]
            )));
        }
        // Equal error: a row per technique and bounce limit, in both reports.
        let eq = md.split("## Equal error").nth(1).unwrap();
        for e in &r.summary.equal_error {
            // A median of bracketed views, or every view a bound.
            assert!(
                (e.speedup.is_some() && e.median_spp > 0.0)
                    || e.above_ladder + e.below_ladder == e.views,
                "{e:?}"
            );
            let cells = format!(
                "| {} | {} | {} | {} | {} |",
                e.technique,
                e.bounces,
                e.views,
                bench_harness::report::fmt_err(e.mean_error),
                bench_harness::report::fmt_2(e.median_spp)
            );
            assert!(eq.contains(&cells), "{cells}");
        }
        // The sequence: every technique at every frame, the same numbers in the reports.
        let q = r.sequence.as_ref().expect("a relighting sequence");
        assert_eq!(q.frames.len(), 8);
        let seq = md.split("## Relighting sequence").nth(1).unwrap();
        for (i, f) in q.frames.iter().enumerate() {
            assert_eq!(f.techniques.len(), labels.len());
            let c = md_row(seq, &i.to_string());
            assert_eq!(c[1], f.caption);
            for (k, t) in f.techniques.iter().enumerate() {
                assert!(t.error.is_finite() && t.frame_s > 0.0);
                assert_eq!(
                    c[2 + k],
                    format!(
                        "{} / {} / {}",
                        bench_harness::report::fmt_err(t.error),
                        bench_harness::report::fmt_err(t.surface.unwrap().mean_error),
                        bench_harness::report::fmt_ms(t.frame_s * 1e3)
                    )
                );
            }
        }
        assert!(html.contains("error along the sequence"));
        // Relighting does not drift: every frame's error within 1.5x of the first frame's,
        // and every frame faster than solving again (its precomputation).
        let relight = q.series("relight-256");
        let solve = q.prepare_s.iter().find(|p| p.0 == "relight-256").unwrap().1;
        for (i, (t, e)) in relight.iter().enumerate() {
            eprintln!("frame {i}: relight {:.3} ms, error {e:.5}", t * 1e3);
            assert!(
                *e <= 1.5 * relight[0].1,
                "frame {i}: {e} against {}",
                relight[0].1
            );
            assert!(*t < solve, "frame {i}: {t} s against a {solve} s solve");
        }
        std::fs::remove_dir_all(&o.out).ok();
    }
}
