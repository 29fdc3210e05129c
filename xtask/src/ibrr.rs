//! `cargo xtask ibrr`: build the image-based radiosity representation of a scene (IRPLs
//! from particle walks warped into a layered depth cube) and write the view from a scene
//! camera and a summary.

use std::time::Instant;

use ibrr_ldc::ldc::SourcePrecision;
use ibrr_ldc::{IbrrSettings, IbrrTechnique, Lookup, Splat};
use scene_core::{FrameRequest, LightSetting, LightState, Technique};

/// The options of `xtask ibrr`.
#[derive(Debug, clap::Args)]
pub struct Options {
    /// Scene, lights, camera, size and exposure.
    #[command(flatten)]
    pub view: crate::ViewArgs,
    /// Output directory.
    #[arg(long, default_value = "out/ibrr")]
    pub out: std::path::PathBuf,
    /// LDI resolution along each side of the scene's bounding cube.
    #[arg(long, default_value_t = 256)]
    pub ldc: u32,
    /// About this many instant-radiosity point lights in the first round (with
    /// `--target-error 0`, in all: the paper's fixed count).
    #[arg(long, default_value_t = 184)]
    pub irpls: u32,
    /// Add rounds of paths until the build's own estimate of its lit-surface error (the
    /// half-width of a 95 % interval, largest channel) is below this, or a budget ends
    /// it (0: the fixed count of --irpls).
    #[arg(long, default_value_t = IbrrSettings::default().target_error)]
    pub target_error: f32,
    /// Most IRPLs a build aiming at --target-error makes (0: twice --irpls).
    #[arg(long, default_value_t = 0)]
    pub irpl_budget: u32,
    /// Seconds after which a build aiming at --target-error starts no further round (0:
    /// no limit; the result then depends on the machine's speed).
    #[arg(long, default_value_t = 0.0)]
    pub time_budget: f32,
    /// How renders become LDC values: nearest (the paper), gaussian (the paper's planned
    /// kernel) or exact (geometry term at every LDI pixel, renders as shadow maps).
    #[arg(long, default_value = "exact")]
    pub splat: String,
    /// Reconstruction kernel: nearest, average (3x3, the paper's) or bilinear.
    #[arg(long, default_value = "bilinear")]
    pub lookup: String,
    /// Clamp of path IRPLs' geometry term as a fraction of the scene's extent, with the
    /// clamped energy restored (0: unclamped, the paper's accurate option).
    #[arg(long, default_value_t = 0.1)]
    pub clamp: f32,
    /// How the clamped energy is restored: local (short rays from every layer recover it
    /// where it was lost) or rescale (each IRPL's values scaled to its unclamped power).
    #[arg(long, default_value = "local")]
    pub compensation: String,
    /// Pixels that find no layer take the light of the pixels around them that did, up to
    /// this many camera pixels away (the hole fill; 0: they stay black).
    #[arg(long, default_value_t = IbrrSettings::default().fill_radius)]
    pub fill_radius: u32,
    /// Seed of the particle walks.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Store each layer's light per source in f16 (half the memory of f32).
    #[arg(long)]
    pub f16: bool,
    /// Most bounces of a particle: 0 keeps only the lights' own exact sources (direct
    /// light), 1 adds one bounce, and so on.
    #[arg(long, default_value_t = 32)]
    pub bounces: u32,
    /// Render resolution of the lights' own exact sources (0: the LDC resolution).
    #[arg(long, default_value_t = 0)]
    pub direct_render: u32,
    /// Render resolution of the path IRPLs' hemicubes (0: half the direct one).
    #[arg(long, default_value_t = 0)]
    pub indirect_render: u32,
    /// Spend the IRPL budget on the light the scene's cameras see: IRPLs that no camera's
    /// surface point sees are kept one in eight, eight times as strong (unbiased).
    #[arg(long)]
    pub camera_importance: bool,
    /// Start suns' and sky regions' particles where their light enters what the scene's
    /// cameras see (a window, found by pilot rays); the rest fewer and stronger
    /// (unbiased).
    #[arg(long)]
    pub entry_importance: bool,
}

/// Every number against its stated range (no file touched), run by `Command::check_numbers`
/// before the LDC is built.
pub fn check_numbers(o: &Options) -> Result<(), String> {
    o.view.check()?;
    crate::ranged("--ldc", o.ldc, 8..=2048)?;
    crate::ranged("--irpls", o.irpls, 1..=100_000)?;
    crate::ranged("--clamp", o.clamp, 0.0..=1.0)?;
    crate::ranged("--target-error", o.target_error, 0.0..=1.0)?;
    crate::ranged("--irpl-budget", o.irpl_budget, 0..=1_000_000)?;
    crate::ranged("--time-budget", o.time_budget, 0.0..=1e6)?;
    if o.irpl_budget != 0 && o.irpl_budget < o.irpls {
        return Err(format!(
            "--irpl-budget ({}) must be at least --irpls ({})",
            o.irpl_budget, o.irpls
        ));
    }
    crate::ranged("--bounces", o.bounces, 0..=1024)?;
    crate::ranged(
        "--fill-radius",
        o.fill_radius,
        0..=ibrr_ldc::settings::MAX_FILL_RADIUS,
    )?;
    crate::ranged("--direct-render", o.direct_render, 0..=8192)?;
    crate::ranged("--indirect-render", o.indirect_render, 0..=8192)?;
    Ok(())
}

/// Runs the command.
pub fn run(o: &Options) -> Result<(), String> {
    let splat: Splat = o.splat.parse().map_err(|e| format!("--splat: {e}"))?;
    let lookup: Lookup = o.lookup.parse().map_err(|e| format!("--lookup: {e}"))?;
    let compensation: ibrr_ldc::Compensation = o
        .compensation
        .parse()
        .map_err(|e| format!("--compensation: {e}"))?;
    // The numbers were checked by `Command::check_numbers`.
    crate::check_out_dir(&o.out)?;
    let (scene, state, camera) = o.view.open()?;
    let camera = &camera;
    let settings = IbrrSettings {
        resolution: o.ldc,
        irpls: o.irpls,
        target_error: o.target_error,
        irpl_budget: o.irpl_budget,
        time_budget: o.time_budget,
        splat,
        lookup,
        clamp: o.clamp,
        compensation,
        fill_radius: o.fill_radius,
        seed: o.seed,
        max_depth: o.bounces,
        direct_hemicube: o.direct_render,
        indirect_hemicube: o.indirect_render,
        camera_importance: o.camera_importance,
        entry_importance: o.entry_importance,
        source_precision: if o.f16 {
            SourcePrecision::F16
        } else {
            SourcePrecision::F32
        },
        ..Default::default()
    };
    settings.check().map_err(|e| e.to_string())?;
    let mut technique = IbrrTechnique::new(settings, Box::new(gbuffer::CpuRasterizer::new()));
    let bar = crate::progress_bar(1, "building the LDC (IRPLs)");
    let t0 = Instant::now();
    // Built with every light on as the scene describes it; `--light` is applied by
    // relighting the layers, as any later light change would be.
    technique
        .prepare_lit(scene.clone(), &LightState::default(), &mut |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })
        .map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    let build_s = t0.elapsed().as_secs_f64();
    let built = LightState::default();
    let at = |lights| FrameRequest::from_camera(camera, o.view.width, o.view.height, lights);
    // One frame to warm up, one timed with the lights as built (a steady frame), one after
    // a light change (the asked state, or every light dimmed to half when that is the state
    // built), then the asked state's frame, written.
    technique.render(&at(&built)).map_err(|e| e.to_string())?;
    technique.render(&at(&built)).map_err(|e| e.to_string())?;
    let steady = technique.last_timings();
    let changed = if state.fingerprint() != built.fingerprint() {
        state.clone()
    } else {
        let mut dim = LightState::default();
        for id in scene_core::lights::light_ids(&scene) {
            dim.set(
                id,
                LightSetting {
                    color: glam::Vec3::splat(0.5),
                    ..Default::default()
                },
            );
        }
        dim
    };
    technique.render(&at(&changed)).map_err(|e| e.to_string())?;
    let after_change = technique.last_timings();
    let image = technique.render(&at(&state)).map_err(|e| e.to_string())?;
    let timings = technique.last_timings();
    let ms = |t: ibrr_ldc::FrameTimings| {
        (t.rebuild + t.relight + t.gbuffer + t.lookup).as_secs_f64() * 1e3
    };
    let c = technique.construction().expect("built above");
    let stats = c.stats();
    let ldc = technique.ldc().expect("built above");
    let (exr, png) = crate::write_view(&o.out, &scene, &image, o.view.exposure)?;
    let served = write_served(&o.out, technique.last_served(), o.view.width, o.view.height)?;
    let frame_ms = ms(steady);
    let sources = ldc.sources.sources();
    let estimate = c.error_estimate();
    let stop = c.stopped().map(|s| s.name());
    let mut summary = serde_json::json!({
        "scene": scene.name,
        "triangles": scene.triangle_count(),
        "ldc_resolution": o.ldc,
        "splat": o.splat,
        "lookup": o.lookup,
        "seed": o.seed,
        "bounces": o.bounces,
        "camera_importance": o.camera_importance,
        "entry_importance": o.entry_importance,
        "clamp": o.clamp,
        "compensation": o.compensation,
        "compensation_seconds": stats.compensation_time.as_secs_f64(),
        "irpls": c.irpls.irpls.len(),

        "exact_sources": c.irpls.exact,
        "paths": c.irpls.paths,
        "layers": ldc.layer_count(),
        "memory_bytes": ldc.bytes(),
        "light_sources": sources,
        "source_precision": if o.f16 { "f16" } else { "f32" },
        "memory_bytes_per_source": ldc.sources.bytes() / sources.max(1) as u64,
        "frame_after_light_change_ms": ms(after_change),
        "relight_ms": after_change.relight.as_secs_f64() * 1e3,
        "rebuild_ms": after_change.rebuild.as_secs_f64() * 1e3,
        "construction_seconds": build_s,
        "walk_seconds": stats.walk_time.as_secs_f64(),
        "render_seconds": stats.render_time.as_secs_f64(),
        "warp_seconds": stats.warp_time.as_secs_f64(),
        "samples_warped": stats.samples,
        "frame_ms": frame_ms,
        "gbuffer_ms": steady.gbuffer.as_secs_f64() * 1e3,
        "lookup_ms": steady.lookup.as_secs_f64() * 1e3,
        "pixels_without_layer": timings.missing,
        "pixels_from_fallback": timings.fallback,
        "pixels_filled": timings.filled,
        "camera": camera.name,
        "width": o.view.width,
        "height": o.view.height,
    });
    // The build's error target and its own estimate (ibrr_ldc::estimate).
    let target = serde_json::json!({
        "target_error": o.target_error,
        "irpl_budget": c.settings.budget(),
        "time_budget_seconds": o.time_budget,
        "rounds": c.round() + 1,
        "stopped_by": stop,
        "error_estimate": estimate.map(|e| e.worst()),
        "error_estimate_rgb": estimate.map(|e| e.relative),
        "error_estimate_batches": estimate.map(|e| e.batches),
        "error_estimate_probes": estimate.map(|e| e.probes),
    });
    if let (Some(all), Some(more)) = (summary.as_object_mut(), target.as_object()) {
        all.extend(more.clone());
    }
    let json = crate::write_summary(&o.out, &summary)?;
    eprintln!(
        "{}: {}, {} layers, {:.1} MB ({sources} light sources), built in {build_s:.2} s; frame {frame_ms:.2} ms, {:.2} ms after a light change (relight {:.2} ms), {} pixels without a layer",
        scene.name,
        c.describe(),
        ldc.layer_count(),
        ldc.bytes() as f64 / 1e6,
        ms(after_change),
        after_change.relight.as_secs_f64() * 1e3,
        timings.missing
    );
    println!(
        "{}\n{}\n{}\n{}",
        exr.display(),
        png.display(),
        served.display(),
        json.display()
    );
    Ok(())
}

/// Writes `DIR/served.exr`: how each pixel of the written view found its light (red: the
/// layers of its plane, green: the fallback, yellow: the hole fill, blue: nothing, black:
/// background).
fn write_served(
    out: &std::path::Path,
    served: &[ibrr_ldc::Served],
    width: u32,
    height: u32,
) -> Result<std::path::PathBuf, String> {
    let pixels = served
        .iter()
        .map(|s| match s {
            ibrr_ldc::Served::Background => glam::Vec3::ZERO,
            ibrr_ldc::Served::Layer => glam::Vec3::X,
            ibrr_ldc::Served::Fallback => glam::Vec3::Y,
            ibrr_ldc::Served::Missing => glam::Vec3::Z,
            ibrr_ldc::Served::Filled => glam::Vec3::new(1.0, 1.0, 0.0),
        })
        .collect();
    let image = scene_core::Image {
        width,
        height,
        pixels,
    };
    let path = out.join("served.exr");
    image.write_exr(&path).map_err(|e| e.to_string())?;
    Ok(path)
}
