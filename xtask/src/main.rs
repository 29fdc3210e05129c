//! Project automation: `cargo xtask <command>`.
//!
//! - `ci`: formatting, clippy (warnings denied), the dependency rule, shader validation and
//!   the workspace tests.
//! - `shaders`: parse and validate every `shaders/*/*.wgsl` with naga and translate it to
//!   SPIR-V, MSL and HLSL.
//! - `reference`: render a scene with the reference path tracer to EXR + PNG.
//! - `export-gltf`: write a built-in scene as glTF.
//! - `bench reference`: rays per second of the reference path tracer.
//! - `bench isr`: ISR ms per frame by pass at 1024x768, 24/48/80 samples, CPU and GPU.
//! - `experiment`: the main job: scenes x cameras x `dl`/`isr` against the reference path
//!   tracer, with `report.md`, `report.html` and `results.json`.
//! - `fuzz`: mutation fuzzing of the loaders (glTF, GLB, EXR, PNG, camera lists); failing
//!   inputs are kept under `tests/fuzz-regressions/` and replayed by the tests.
//! - `bench gbuffer`: G-buffer ms per frame (CPU and GPU), downsampling passes and quality,
//!   position reconstruction micro-benchmark.
//! - `bench relight`: the radiosity relighting paper's Tables 1 and 2 and the solve time
//!   for 10^4 elements.

mod bench;
mod bench_frames;
mod bench_ibrr;
mod bench_relight;
mod bench_scaling;
mod checks;
mod experiment;
mod fuzz;
mod gpu_frames;
mod ibrr;
mod relight;
mod results_doc;
mod shaders;
mod sweep;
mod techniques;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use scene_core::reference::{Accumulator, Bounces, PathTracer};
use std::sync::Arc;

use scene_core::{Scene, View, gltf_io};

#[derive(Parser)]
#[command(name = "xtask", about = "Automation for the diffuse-GI toolkit")]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Add a sun to every scene opened: DX,DY,DZ=R,G,B, the direction it travels
    /// (0,-1,0 shines straight down) and its irradiance (one number: grey). Repeatable.
    #[arg(long = "sun", global = true, value_name = "DIR=RGB")]
    suns: Vec<String>,
    /// Add a point light to every scene opened: X,Y,Z=R,G,B, its position in the file's
    /// coordinates and its intensity in W/sr (one number: grey). Repeatable.
    #[arg(long = "point", global = true, value_name = "POS=RGB")]
    points: Vec<String>,
    /// Add a sky to every scene opened: R,G,B (one number: grey), a uniform radiance over
    /// the upper hemisphere, or FILE.exr, an equirectangular environment map (+Y up, its
    /// centre column along -Z). It lights surfaces through openings; it is not drawn as a
    /// background.
    #[arg(long = "sky", global = true, value_name = "RGB|FILE.exr")]
    sky: Option<String>,
    /// How many directional lights the sky becomes for the methods that do not integrate
    /// it (DL, ISR, relighting, the IBRR): 1 to 1024, default 64 (docs/scene-core.md has
    /// the error and cost of 16, 64 and 256).
    #[arg(long = "sky-directions", global = true, value_name = "N")]
    sky_directions: Option<u32>,
}

/// The lights `--sun`, `--point` and `--sky` add to every scene a command opens (set before
/// the command runs: once by `main`, per input by the `commands` fuzz target).
static ADDED_LIGHTS: std::sync::RwLock<Option<scene_core::AddedLights>> =
    std::sync::RwLock::new(None);

/// Sets [`ADDED_LIGHTS`].
fn set_added_lights(added: Option<scene_core::AddedLights>) {
    *ADDED_LIGHTS
        .write()
        .unwrap_or_else(std::sync::PoisonError::into_inner) = added;
}

/// The lights the global flags of `cli` add, parsed (errors name the flag's fault).
fn added_lights(cli: &Cli) -> Result<scene_core::AddedLights, String> {
    let mut added = scene_core::AddedLights::default();
    cli.suns.iter().try_for_each(|s| added.parse_sun(s))?;
    cli.points.iter().try_for_each(|p| added.parse_point(p))?;
    cli.sky.iter().try_for_each(|s| added.parse_sky(s))?;
    cli.sky_directions
        .iter()
        .try_for_each(|&n| added.set_sky_directions(n))?;
    Ok(added)
}

/// The options of `cargo xtask experiment`.
#[derive(clap::Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
struct ExperimentArgs {
    /// `merge`: combine shard folders.
    #[command(subcommand)]
    then: Option<ExperimentCommand>,
    /// The sizes of the run: default (minutes on 2 cores: every method at one setting,
    /// 128x96, 512 spp), full (every setting, 256x192, 512 spp) or hd (every method at
    /// 1280x720, 1920x1080 with --gpu, 256 spp; minutes on a GPU, hours on 2 cores).
    /// Options given override the preset's.
    #[arg(long, default_value = "default")]
    preset: String,
    /// Run only share K of N (views and the sequence dealt round the shards), e.g. 2/4;
    /// combine the shards' folders with `experiment merge`.
    #[arg(long)]
    shard: Option<String>,
    /// Also write a generated results document (e.g. docs/results.md) from the run.
    #[arg(long)]
    write_docs: Option<PathBuf>,
    /// Timed still-camera frames per view (the same view again; default: the preset's).
    #[arg(long)]
    still_repeats: Option<u32>,
    /// Built-in scene name or .gltf/.glb path (repeatable; default: cornell,
    /// cornell-point, primitives, corridor).
    #[arg(long = "scene")]
    scenes: Vec<String>,
    /// Techniques: dl, isr (the default and the thesis' modes at 24/48/80 samples),
    /// isr-default, isr-thesis, isr-scaled, isr-N (screen-space and light-space senders, one
    /// bounce), isr-thesis-N, isr-scaled-N (screen-space senders, measured k_isr), isr-ls-N,
    /// isr-lsv-N (exact shadow rays, CPU only), isr-mb, isr-mb-N (every bounce), isr-mbv-N (every bounce, shadow rays), relight (256
    /// and 1024 elements), relight-N, ibrr (LDC 128 with 64 IRPLs and LDC 256 with 184),
    /// ibrr-RES-N, ibrr-RES-N-cam (camera importance); comma-separated. Default: the
    /// preset's.
    #[arg(long)]
    techniques: Option<String>,
    /// Views per scene: the scene's cameras first, then seeded random ones.
    #[arg(long)]
    views: Option<usize>,
    /// Reference samples per pixel (default: the preset's).
    #[arg(long)]
    spp: Option<u32>,
    /// Reference bounce limits, comma-separated (0, 1, N, inf).
    #[arg(long, default_value = "1,inf")]
    bounces: String,
    /// Image size WxH (default: the preset's).
    #[arg(long)]
    size: Option<String>,
    /// Output directory.
    #[arg(long, default_value = "out/experiment")]
    out: PathBuf,
    /// Run every method on the GPU (wgpu) as an engine hosts it: the G-buffer drawn on the
    /// GPU, each method's frame on the frame contract timed on the device (GPU timestamps
    /// where the adapter has them) apart from the harness, whose wall time is reported
    /// beside; references and the equal-error ladder from the GPU path tracer.
    #[arg(long, conflicts_with = "cpu")]
    gpu: bool,
    /// Run every method on the CPU (the default).
    #[arg(long)]
    cpu: bool,
    /// A camera list for a scene: SCENE=FILE.json (repeatable).
    #[arg(long)]
    cameras: Vec<String>,
    /// Timed moving-camera frames per view after one warm-up (default: the preset's).
    #[arg(long)]
    repeats: Option<u32>,
    /// Seed of the reference and the random cameras.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also write a POV-Ray scene file per view (thesis' radiosity block); renders it as an
    /// extra column when povray is on PATH.
    #[arg(long)]
    povray: bool,
    /// The measure that decides which image is closer and the gain: mean-error (eq. 19 on
    /// linear values), mean-error-8bit (on 8-bit sRGB codes, as the thesis), rmse, flip.
    #[arg(long, default_value = "mean-error")]
    error_metric: String,
    /// Reference cache folder (default DIR/reference-cache).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Skip the equal-error ladder (the path tracer at 1, 2, 4 ... spp/8 spp per view).
    #[arg(long)]
    no_ladder: bool,
    /// The relighting sequence's scene and camera, SCENE or SCENE:CAMERA (default: corridor
    /// when in the run, else the first scene; camera 0).
    #[arg(long)]
    sequence: Option<String>,
    /// Frames of the relighting sequence (0: none; default: the preset's).
    #[arg(long)]
    sequence_frames: Option<usize>,
    /// Samples per pixel of each sequence frame's reference (default: spp / 2).
    #[arg(long)]
    sequence_spp: Option<u32>,
}

impl ExperimentArgs {
    /// The run's options: the preset's values where the command line gives none.
    fn options(&self) -> Result<experiment::Options, String> {
        let p = experiment::Preset::named(&self.preset)?;
        Ok(experiment::Options {
            scenes: self.scenes.clone(),
            techniques: self
                .techniques
                .clone()
                .unwrap_or_else(|| p.techniques.into()),
            views: self.views,
            spp: self.spp.unwrap_or(p.spp),
            bounces: self.bounces.clone(),
            size: self
                .size
                .clone()
                .unwrap_or_else(|| match p.gpu_size.filter(|_| self.gpu) {
                    Some(s) => s.into(),
                    None => p.size.into(),
                }),
            out: self.out.clone(),
            gpu: self.gpu,
            cameras: self.cameras.clone(),
            repeats: self.repeats.unwrap_or(p.repeats),
            seed: self.seed,
            povray: self.povray,
            error_metric: self.error_metric.clone(),
            cache: self.cache.clone(),
            ladder: !self.no_ladder,
            sequence: self.sequence.clone(),
            sequence_frames: self.sequence_frames.unwrap_or(p.sequence_frames),
            sequence_spp: self.sequence_spp,
            still_repeats: self.still_repeats.unwrap_or(p.still_repeats),
            preset: p.name.into(),
            shard: self
                .shard
                .as_deref()
                .map(bench_harness::Shard::parse)
                .transpose()?,
            write_docs: self.write_docs.clone(),
        })
    }

    /// Checks every number and name of the options before anything is loaded.
    fn check_numbers(&self) -> Result<(), String> {
        if self.then.is_some() {
            return Ok(());
        }
        let o = self.options()?;
        experiment::parse_size(&o.size)?;
        experiment::parse_bounces(&o.bounces)?;
        techniques::parse_techniques(&o.techniques)?;
        experiment::check_numbers(&o)
    }
}

/// What `cargo xtask experiment` does besides a run.
#[derive(Subcommand, Debug)]
enum ExperimentCommand {
    /// Combine the output folders of a sharded run (`--shard K/N`) into one report,
    /// identical in its errors and ranking to a single run's.
    Merge {
        /// The shard folders (every share exactly once).
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Output folder of the merged report.
        #[arg(long, default_value = "out/experiment")]
        out: PathBuf,
        /// Also write a generated results document (e.g. docs/results.md).
        #[arg(long)]
        write_docs: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
enum Command {
    /// Everything CI checks: fmt, clippy -D warnings, dependency rule, shaders, tests.
    Ci {
        /// Skip `cargo test --workspace` (the README's test command runs it separately).
        #[arg(long)]
        no_test: bool,
    },
    /// Validate every shaders/*/*.wgsl with naga and translate to SPIR-V, MSL and HLSL.
    Shaders {
        /// Also write the translations to this directory.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Check only the dependency rule (spokes depend on scene-core, never on a sibling).
    DepRule,
    /// Render a scene with the reference path tracer: writes DIR/SCENE.exr, a PNG preview
    /// and DIR/SCENE.variance.exr.
    Reference {
        /// Built-in scene name (cornell, cornell-point, primitives, corridor, "many-boxes N")
        /// or a .gltf/.glb path.
        #[arg(long, default_value = "cornell")]
        scene: String,
        /// Index of the scene camera to render.
        #[arg(long, default_value_t = 0)]
        camera: usize,
        /// Image width.
        #[arg(long, default_value_t = 256)]
        width: u32,
        /// Image height.
        #[arg(long, default_value_t = 256)]
        height: u32,
        /// Samples per pixel.
        #[arg(long, default_value_t = 256)]
        spp: u32,
        /// Indirect bounces: 0 (direct only), 1 (ISR's scope), N, or inf.
        #[arg(long, default_value = "1")]
        bounces: Bounces,
        /// Seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// PNG exposure in stops.
        #[arg(long, default_value_t = 0.0)]
        exposure: f32,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Also write the scene, camera and settings as a Mitsuba 3 scene in this directory
        /// (`bench_harness::mitsuba`; `python3 xtask/scripts/mitsuba_render.py DIR` renders
        /// and times it).
        #[arg(long)]
        mitsuba: Option<PathBuf>,
        /// Trace on the GPU (`scene_core::reference::GpuPathTracer`: the same estimator in
        /// a wgpu compute shader, agreeing with the CPU tracer in distribution; the adapter
        /// as `WGPU_BACKEND` and `WGPU_ADAPTER_NAME` choose).
        #[arg(long)]
        gpu: bool,
    },
    /// Radiosity relighting: mesh and solve a scene with light-tagged progressive
    /// refinement, relight it with the given light settings and write the view from a
    /// scene camera (EXR, PNG) and summary.json.
    Relight(relight::Options),
    /// Image-based radiosity: build a layered depth cube from instant-radiosity point lights
    /// and write the view from a scene camera (EXR, PNG) and summary.json.
    Ibrr(ibrr::Options),
    /// Export a scene (built-in name or glTF path) as .gltf or .glb.
    ExportGltf {
        /// Built-in scene name or a .gltf/.glb path.
        #[arg(long)]
        scene: String,
        /// Output file (.gltf or .glb).
        #[arg(long)]
        out: PathBuf,
    },
    /// ISR's settings (k_isr, AO on/off, radius) swept at 24/48/80 samples on held-out
    /// views (seeded random cameras of the built-in scenes, none of which the main job
    /// scores) against the reference; prints the most accurate setting per sample count.
    SweepIsr(sweep::Options),
    /// Regenerate a generated results document (docs/results.md) from the results.json it
    /// names, check that it is unchanged, or generate it from a run's results.json.
    ResultsDoc {
        /// The document.
        #[arg(long, default_value = "docs/results.md")]
        doc: PathBuf,
        /// Fail when the document differs from what its results generate.
        #[arg(long, conflicts_with = "from")]
        check: bool,
        /// Generate the document from this run's results.json (copied beside it).
        #[arg(long)]
        from: Option<PathBuf>,
    },
    /// The main job: render the scenes with DL, ISR, radiosity relighting, the IBRR and the
    /// reference path tracer and write results.json, report.md and report.html (speed
    /// against error, equal-error path tracing, a relighting sequence).
    /// `experiment merge DIR... --out DIR` combines the folders of a sharded run.
    Experiment(Box<ExperimentArgs>),
    /// Fuzz the loaders with mutated seed files: each input under catch_unwind, the worker
    /// under an address-space cap and a per-input time limit; failing inputs are saved under
    /// tests/fuzz-regressions/TARGET/ (replayed by `cargo test`).
    Fuzz {
        /// A target to run: gltf, glb, exr, png, cameras, scenes, cli, commands (repeatable; default all).
        #[arg(long = "target")]
        targets: Vec<String>,
        /// Seconds per target.
        #[arg(long, default_value_t = 60)]
        seconds: u64,
        /// Seed of the mutations.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Targets fuzzed at once.
        #[arg(long, default_value_t = 1)]
        jobs: usize,
        /// Working directory.
        #[arg(long, default_value = "out/fuzz")]
        dir: PathBuf,
    },
    /// One fuzz worker (started by `fuzz`).
    #[command(hide = true)]
    FuzzWorker {
        #[arg(long)]
        target: String,
        #[arg(long)]
        seconds: u64,
        #[arg(long)]
        seed: u64,
        #[arg(long)]
        dir: PathBuf,
    },
    /// Benchmarks (figures printed, nothing asserted).
    Bench {
        /// What to benchmark: `frames`, `reference`, `gbuffer`, `isr`, `relight`, `relight-frames`,
        /// `relight-dynamic`, `relight-direct`, `ibrr` or `scaling`.
        what: String,
        /// Worker threads.
        #[arg(long, default_value_t = 2)]
        threads: usize,
        /// Timed repeats after one warm-up.
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// `scaling` only: the largest box field, in triangles (10^5, 10^6 and 10^7 up to
        /// it).
        #[arg(long, default_value_t = 1_000_000)]
        max_triangles: u64,
        /// `frames` only: the frame sizes, `WIDTHxHEIGHT` separated by commas.
        #[arg(long, default_value = "256x192,1280x720")]
        sizes: String,
        /// `frames` only: the built-in scene.
        #[arg(long, default_value = "cornell")]
        scene: String,
        /// `frames` only: before each timed frame, write 256 MiB through the device's
        /// memory so that the frame finds its caches cold, as after an engine's other work
        /// (the default times frames back to back).
        #[arg(long)]
        cold_cache: bool,
    },
}

/// Loads a built-in scene by name, or a glTF file when the name ends in .gltf/.glb, printing
/// what the import ignored.
pub fn load_scene(spec: &str) -> Result<Scene, String> {
    Ok(open_scene_noted(spec)?.scene)
}

/// [`scene_core::open_scene`], printing its notes; the translation it applied (a scene far
/// from the origin is moved to it) comes with the scene.
pub fn open_scene_noted(spec: &str) -> Result<scene_core::OpenedScene, String> {
    let added = ADDED_LIGHTS
        .read()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .clone()
        .unwrap_or_default();
    let opened = scene_core::open_scene_with(spec, &added).map_err(|e| e.to_string())?;
    for note in &opened.notes {
        eprintln!("{note}");
    }
    Ok(opened)
}

/// The options every command that renders one view of a scene takes.
#[derive(Debug, clap::Args)]
pub struct ViewArgs {
    /// Built-in scene name or a .gltf/.glb path.
    #[arg(long, default_value = "cornell")]
    pub scene: String,
    /// A light's emission in the scene's units: ID=R,G,B with ID point:N, directional:N
    /// or emissive:N (a mesh index). Repeatable.
    #[arg(long = "light")]
    pub lights: Vec<String>,
    /// Index of the scene camera to render (a scene without cameras: its default view).
    #[arg(long, default_value_t = 0)]
    pub camera: usize,
    /// Image width.
    #[arg(long, default_value_t = 256)]
    pub width: u32,
    /// Image height.
    #[arg(long, default_value_t = 192)]
    pub height: u32,
    /// PNG exposure in stops.
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f32,
}

/// This process's peak resident set so far (`VmHWM` of `/proc/self/status`), in KiB; 0
/// where the system does not say.
pub fn peak_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1).and_then(|v| v.parse().ok()))
        })
        .unwrap_or(0)
}

/// [`scene_core::range::check`] with the error as the commands print it.
pub fn ranged<T: PartialOrd + std::fmt::Debug + Copy>(
    what: &str,
    value: T,
    range: std::ops::RangeInclusive<T>,
) -> Result<T, String> {
    scene_core::range::check(what, value, range).map_err(|e| e.to_string())
}

/// Fails at once unless `dir` can be created (or exists as a folder) and a file can be
/// written in it: an output path is checked before the long work that fills it.
pub fn check_out_dir(dir: &Path) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("output folder {}: {e}", dir.display()))?;
    let probe = dir.join(format!(".write-check-{}", std::process::id()));
    std::fs::write(&probe, b"")
        .map_err(|e| format!("output folder {}: cannot write in it: {e}", dir.display()))?;
    std::fs::remove_file(&probe).ok();
    Ok(())
}

impl ViewArgs {
    /// Checks the numbers (size, exposure: [`scene_core::range`]), loads the scene, parses
    /// the lights and picks the camera.
    pub fn check(&self) -> Result<(), String> {
        ranged("--width", self.width, scene_core::range::IMAGE_SIDE)?;
        ranged("--height", self.height, scene_core::range::IMAGE_SIDE)?;
        ranged("--exposure", self.exposure, scene_core::range::EXPOSURE)?;
        Ok(())
    }

    /// Loads the scene, parses the lights and picks the camera (the numbers were checked
    /// first, [`ViewArgs::check`] through `Command::check_numbers`).
    pub fn open(&self) -> Result<(Arc<Scene>, scene_core::LightState, scene_core::Camera), String> {
        let scene = Arc::new(load_scene(&self.scene)?);
        let state = relight::light_state(&scene, &self.lights)?;
        let camera = scene_camera(&scene, self.camera)?;
        Ok((scene, state, camera))
    }
}

/// Camera `index` of `scene`; a scene without cameras gets
/// [`scene_core::rays::framing::framing_camera`] as camera 0 (said on stderr).
pub fn scene_camera(scene: &Scene, index: usize) -> Result<scene_core::Camera, String> {
    if scene.cameras.is_empty() && index == 0 {
        let camera = scene_core::rays::framing::framing_camera(scene);
        eprintln!(
            "note: scene '{}' has no camera; using the default view '{}' (the candidate view \
             that sees the most lit surface, docs/scene-core.md)",
            scene.name, camera.name
        );
        return Ok(camera);
    }
    scene.cameras.get(index).cloned().ok_or_else(|| {
        format!(
            "scene '{}' has {} camera(s); --camera {index} does not exist",
            scene.name,
            scene.cameras.len()
        )
    })
}

/// Writes a command's view of `scene` as `DIR/<scene>.exr` and `.png` (creating `DIR`);
/// returns both paths.
pub fn write_view(
    out: &Path,
    scene: &Scene,
    image: &scene_core::Image,
    exposure: f32,
) -> Result<(PathBuf, PathBuf), String> {
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let stem = Path::new(&scene.name)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let exr = out.join(format!("{stem}.exr"));
    let png = out.join(format!("{stem}.png"));
    image.write_exr(&exr).map_err(|e| e.to_string())?;
    image.write_png(&png, exposure).map_err(|e| e.to_string())?;
    Ok((exr, png))
}

/// Writes `DIR/summary.json` (through a temporary file, so a reader never sees half of it).
pub fn write_summary(out: &Path, summary: &serde_json::Value) -> Result<PathBuf, String> {
    let json = out.join("summary.json");
    let text = serde_json::to_string_pretty(summary).map_err(|e| e.to_string())?;
    scene_core::image::write_via_temp(
        &json,
        |path| std::fs::write(path, &text).map_err(|e| format!("{}: {e}", path.display())),
        |e| format!("{}: {e}", json.display()),
    )?;
    Ok(json)
}

fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let bar = if std::env::var_os("CI").is_some() {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(len)
    };
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len}, eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

#[allow(clippy::too_many_arguments)]
fn reference(
    scene_spec: &str,
    camera: usize,
    (width, height, spp, bounces, seed): (u32, u32, u32, Bounces, u64),
    exposure: f32,
    out: &Path,
    mitsuba: Option<&Path>,
    gpu: bool,
) -> Result<(), String> {
    // The numbers were checked by `Command::check_numbers`.
    check_out_dir(out)?;
    let scene = load_scene(scene_spec)?;
    let cam = scene_camera(&scene, camera)?;
    let cam = cam.with_aspect(width as f32 / height as f32);
    let view = View::from_camera(&cam);
    if let Some(dir) = mitsuba {
        check_out_dir(dir)?;
        let limit = match bounces {
            Bounces::Limited(n) => Some(n),
            Bounces::Unlimited => None,
        };
        let xml = bench_harness::mitsuba::export(&scene, &cam, width, height, spp, limit, dir)
            .map_err(|e| e.to_string())?;
        eprintln!("Mitsuba scene: {}", xml.display());
    }
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let stem = Path::new(&scene.name)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    eprintln!(
        "{}: {} triangles, camera '{}', {width}x{height}, {spp} spp, bounces {bounces}",
        scene.name,
        scene.triangle_count(),
        cam.name
    );
    let exr = out.join(format!("{stem}.exr"));
    let png = out.join(format!("{stem}.png"));
    let var = out.join(format!("{stem}.variance.exr"));
    let (image, variance) = if gpu {
        let ctx = scene_core::gpu::GpuContext::new().map_err(|e| e.to_string())?;
        let t0 = Instant::now();
        let tracer = scene_core::reference::GpuPathTracer::new(
            &ctx,
            &scene,
            &scene_core::LightState::default(),
        )
        .map_err(|e| e.to_string())?;
        let mut acc = tracer
            .accumulator(width, height)
            .map_err(|e| e.to_string())?;
        eprintln!(
            "GPU tracer on {} ready in {:.1} ms",
            ctx.adapter_summary(),
            t0.elapsed().as_secs_f64() * 1e3
        );
        let bar = progress_bar(u64::from(spp), "rendering (samples per pixel)");
        let report = |done: u32, _: u32| bar.set_position(u64::from(done));
        tracer
            .add_pass(&mut acc, &view, bounces, seed, spp, Some(&report))
            .map_err(|e| e.to_string())?;
        bar.finish_and_clear();
        let paths = f64::from(width) * f64::from(height) * f64::from(spp);
        eprintln!(
            "{:.2} s, {:.3e} paths/s",
            acc.seconds(),
            paths / acc.seconds().max(1e-9)
        );
        (
            acc.image().map_err(|e| e.to_string())?,
            acc.variance().map_err(|e| e.to_string())?,
        )
    } else {
        let t0 = Instant::now();
        let tracer = PathTracer::new(&scene);
        eprintln!("BVH built in {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
        let mut acc = Accumulator::new(width, height);
        // Progressive passes of up to 64 spp so the bar moves on long renders.
        let passes = spp.div_ceil(64);
        let bar = progress_bar(height as u64 * passes as u64, "rendering (rows)");
        let mut done = 0u32;
        for pass in 0..passes {
            let n = (spp - done).min(64);
            let base = pass as u64 * height as u64;
            let report = |rows: u64, _total: u64| bar.set_position(base + rows);
            acc.add_pass(&tracer, &view, bounces, seed, n, Some(&report));
            done += n;
        }
        bar.finish_and_clear();
        let stats = acc.stats();
        eprintln!(
            "{:.2} s, {:.2} Mrays/s ({} primary, {} shadow, {} bounce)",
            stats.seconds,
            stats.rays_per_second() / 1e6,
            stats.primary,
            stats.shadow,
            stats.bounce
        );
        (acc.image(), acc.variance())
    };
    image.write_exr(&exr).map_err(|e| e.to_string())?;
    image.write_png(&png, exposure).map_err(|e| e.to_string())?;
    variance.write_exr(&var).map_err(|e| e.to_string())?;
    println!("{}", exr.display());
    println!("{}", png.display());
    println!("{}", var.display());
    Ok(())
}

impl Command {
    /// Every number of the command against its stated range ([`scene_core::range`],
    /// docs/hostile-files.md), touching no file: what `run` checks before any work, and what
    /// the `cli` fuzz target runs on mutated command lines.
    fn check_numbers(&self) -> Result<(), String> {
        use scene_core::range::{EXPOSURE, IMAGE_SIDE, SPP};
        let bounces = |b: &Bounces| match b {
            Bounces::Limited(n) => ranged("--bounces", *n, 0..=1000).map(|_| ()),
            Bounces::Unlimited => Ok(()),
        };
        match self {
            Command::Reference {
                width,
                height,
                spp,
                bounces: b,
                exposure,
                ..
            } => {
                ranged("--width", *width, IMAGE_SIDE)?;
                ranged("--height", *height, IMAGE_SIDE)?;
                ranged("--spp", *spp, SPP)?;
                ranged("--exposure", *exposure, EXPOSURE)?;
                bounces(b)
            }
            Command::Relight(o) => o.check_numbers(),
            Command::Ibrr(o) => ibrr::check_numbers(o),
            Command::SweepIsr(o) => {
                experiment::parse_size(&o.size)?;
                ranged("--views", o.views, 1..=100)?;
                ranged("--spp", o.spp, SPP).map(|_| ())
            }
            Command::Experiment(args) => args.check_numbers(),
            Command::Fuzz { seconds, jobs, .. } => {
                ranged("--seconds", *seconds, 1..=86_400)?;
                ranged("--jobs", *jobs, 1..=16).map(|_| ())
            }
            Command::Bench {
                threads,
                repeats,
                max_triangles,
                sizes,
                ..
            } => {
                for s in sizes.split(',') {
                    bench_frames::parse_size(s)?;
                }
                ranged("--threads", *threads, 1..=1024)?;
                ranged("--max-triangles", *max_triangles, 100_000..=10_000_000)?;
                ranged("--repeats", *repeats, 1..=1000).map(|_| ())
            }
            _ => Ok(()),
        }
    }
}

/// The `cli` fuzz target: a JSON array of arguments (after `xtask`) parsed as a command
/// line and checked ([`Command::check_numbers`]); a parse error or a refusal is an outcome,
/// a panic a finding. Nothing runs and no file is touched.
pub fn fuzz_command_line(bytes: &[u8]) -> Result<(), String> {
    let args: Vec<String> = serde_json::from_slice(bytes).map_err(|e| e.to_string())?;
    let cli = Cli::try_parse_from(std::iter::once("xtask".to_string()).chain(args))
        .map_err(|e| e.to_string().lines().next().unwrap_or_default().to_string())?;
    cli.command.check_numbers()
}

/// The `commands` fuzz target: a command line parsed and checked as [`fuzz_command_line`]
/// does, then **run** at a tiny size with its outputs in `scratch`: `reference`, `relight`,
/// `ibrr` and `export-gltf` on the built-in scenes (the `building` is too slow for the
/// fuzzer's time limit), with the global light flags (`--point` at 1e38, `--sky`...). A
/// command line asking for more (a larger image, more samples, elements or IRPLs, a file
/// scene, another command) is refused as an outcome. The command's own error is an
/// outcome too; a panic, or an image it wrote holding a NaN, an infinity or a negative
/// value, is a finding.
pub fn fuzz_run_command(bytes: &[u8], scratch: &Path) -> Result<(), String> {
    let args: Vec<String> = serde_json::from_slice(bytes).map_err(|e| e.to_string())?;
    let mut cli = Cli::try_parse_from(std::iter::once("xtask".to_string()).chain(args))
        .map_err(|e| e.to_string().lines().next().unwrap_or_default().to_string())?;
    cli.command.check_numbers()?;
    let added = added_lights(&cli)?;
    let out = scratch.join("command-out");
    std::fs::remove_dir_all(&out).ok();
    let tiny = |what: &str, v: u64, max: u64| {
        if v <= max {
            Ok(())
        } else {
            Err(format!("{what} {v}: above the commands target's {max}"))
        }
    };
    let builtin = |scene: &str| {
        if scene_core::builtin::NAMES.contains(&scene) && scene != "building" {
            Ok(())
        } else {
            Err(format!(
                "scene '{scene}': the commands target runs the small built-in scenes"
            ))
        }
    };
    let view = |v: &ViewArgs| {
        builtin(&v.scene)?;
        tiny("pixels", u64::from(v.width) * u64::from(v.height), 16 * 12)
    };
    match &mut cli.command {
        Command::Reference {
            scene,
            width,
            height,
            spp,
            out: dir,
            mitsuba,
            gpu,
            ..
        } => {
            if *gpu {
                return Err("--gpu: not run by the commands target (a device per input)".into());
            }
            builtin(scene)?;
            tiny("pixels", u64::from(*width) * u64::from(*height), 16 * 12)?;
            tiny("spp", u64::from(*spp), 4)?;
            *dir = out.clone();
            *mitsuba = None;
        }
        Command::Relight(o) => {
            view(&o.view)?;
            tiny("elements", o.elements as u64, 256)?;
            if o.form_factors == "hemicube" {
                tiny("hemicube resolution", u64::from(o.hemicube_resolution), 32)?;
            }
            tiny("subpixels", u64::from(o.subpixels), 8)?;
            o.out = out.clone();
        }
        Command::Ibrr(o) => {
            view(&o.view)?;
            tiny("LDC resolution", u64::from(o.ldc), 32)?;
            tiny("IRPLs", u64::from(o.irpls), 16)?;
            tiny("direct render", u64::from(o.direct_render), 32)?;
            tiny("indirect render", u64::from(o.indirect_render), 32)?;
            o.out = out.clone();
        }
        Command::ExportGltf { scene, out: file } => {
            builtin(scene)?;
            let glb = file.extension().is_some_and(|e| e == "glb");
            *file = out.join(if glb { "export.glb" } else { "export.gltf" });
            std::fs::create_dir_all(&out).map_err(|e| e.to_string())?;
        }
        _ => return Err("not a command the commands target runs".into()),
    }
    set_added_lights(Some(added));
    let result = run(cli);
    set_added_lights(None);
    result?;
    // What the command wrote: every EXR finite and non-negative.
    for e in std::fs::read_dir(&out).into_iter().flatten().flatten() {
        let path = e.path();
        if path.extension().is_some_and(|x| x == "exr") {
            let image = scene_core::Image::read_exr(&path).map_err(|e| e.to_string())?;
            if let Some(p) = image
                .pixels
                .iter()
                .find(|p| !p.is_finite() || p.min_element() < 0.0)
            {
                panic!("{} holds the pixel {p}", path.display());
            }
        }
    }
    Ok(())
}

fn run(cli: Cli) -> Result<(), String> {
    cli.command.check_numbers()?;
    match cli.command {
        Command::Ci { no_test } => checks::ci(!no_test),
        Command::Shaders { out } => shaders::validate_all(out.as_deref()).map(|n| {
            println!("{n} shader pass(es) composed, valid and translated to SPIR-V, MSL and HLSL");
        }),
        Command::DepRule => checks::dependency_rule(),
        Command::Reference {
            scene,
            camera,
            width,
            height,
            spp,
            bounces,
            seed,
            exposure,
            out,
            mitsuba,
            gpu,
        } => reference(
            &scene,
            camera,
            (width, height, spp, bounces, seed),
            exposure,
            &out,
            mitsuba.as_deref(),
            gpu,
        ),
        Command::Relight(options) => relight::run(&options),
        Command::Ibrr(options) => ibrr::run(&options),
        Command::ExportGltf { scene, out } => {
            let s = load_scene(&scene)?;
            gltf_io::export(&s, &out).map_err(|e| e.to_string())?;
            println!("{}", out.display());
            Ok(())
        }
        Command::SweepIsr(o) => sweep::run(o),
        Command::ResultsDoc {
            doc,
            from: Some(from),
            ..
        } => {
            let r = bench_harness::merge::read_results_file(&from).map_err(|e| e.to_string())?;
            results_doc::check_input(&r, &from)?;
            results_doc::write(&r, &doc)?;
            println!("{}", doc.display());
            Ok(())
        }
        Command::ResultsDoc { doc, check, .. } => {
            let (text, now) = results_doc::regenerate(&doc)?;
            if check {
                if text != now {
                    return Err(format!(
                        "{} differs from what its results generate; run `cargo xtask results-doc`",
                        doc.display()
                    ));
                }
                println!("{}: as generated", doc.display());
            } else {
                std::fs::write(&doc, now).map_err(|e| format!("{}: {e}", doc.display()))?;
                println!("{}", doc.display());
            }
            Ok(())
        }
        Command::Experiment(args) => match &args.then {
            Some(ExperimentCommand::Merge {
                dirs,
                out,
                write_docs,
            }) => experiment::merge(dirs, out, write_docs.as_deref()),
            None => experiment::run(&args.options()?),
        },
        Command::Fuzz {
            targets,
            seconds,
            seed,
            jobs,
            dir,
        } => fuzz::run(&fuzz::Options {
            targets,
            seconds,
            seed,
            dir,
            jobs,
        }),
        Command::FuzzWorker {
            target,
            seconds,
            seed,
            dir,
        } => fuzz::worker(&target, seconds, seed, &dir),
        Command::Bench {
            what,
            threads,
            repeats,
            max_triangles,
            sizes,
            scene,
            cold_cache,
        } => match what.as_str() {
            "frames" => sizes
                .split(',')
                .map(bench_frames::parse_size)
                .collect::<Result<Vec<_>, _>>()
                .and_then(|sizes| bench_frames::run(&scene, threads, repeats, &sizes, cold_cache)),
            "reference" => bench::reference(threads, repeats),
            "isr" => bench::isr(threads, repeats),
            "gbuffer" => bench::gbuffer(threads, repeats),
            "relight" => bench_relight::run(threads, repeats),
            "relight-frames" => bench_relight::frames(threads, repeats),
            "relight-dynamic" => bench_relight::dynamic_only(threads, repeats),
            "relight-direct" => bench_relight::direct(threads, repeats),
            "ibrr" => bench_ibrr::run(threads, repeats),
            "scaling" => bench_scaling::run(threads, repeats, max_triangles),
            other => Err(format!(
                "unknown benchmark '{other}' (known: frames, reference, gbuffer, isr, relight, relight-frames, relight-dynamic, relight-direct, ibrr, scaling)"
            )),
        },
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match added_lights(&cli) {
        Ok(added) => set_added_lights(Some(added)),
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
