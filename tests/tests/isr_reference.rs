//! ISR against the reference path tracer at bounce limit 1 (direct light + one bounce, ISR's
//! scope; the thesis' POV-Ray `recursion_limit 2`) on every default camera of
//! `cornell-point`, `primitives` and `corridor`, with a claim for every configuration
//! (mean error, eq. 19, from imalyzer; gain = (e_DL - e_ISR) / e_DL):
//!
//! - every configuration whose senders are lit (radiance units) with the thesis' radius beats
//!   DL on every view, and
//!   so does the thesis' eq. 25 with albedo senders, whose term is tiny but positive;
//! - `patch/albedo` (an irradiance estimator fed albedo, not radiance) adds light where
//!   there is none: it loses to DL somewhere in the closed rooms and its mean gain is below
//!   `patch/lit`'s, while it still beats DL in the open, sunlit `primitives` views where the
//!   true indirect light is large;
//! - more samples give more gain (24 < 48 < 80, the default), on the mean over views;
//! - the physically consistent `k_isr = 1` without AO gains more than the thesis' `0.5`
//!   without AO, on every view (the screen-space term is an underestimate, so doubling it
//!   moves towards the reference);
//! - the measured screen-space setting (`IsrSettings::screen_space`: `k_isr` 4, radius 0.5,
//!   no AO, from `cargo xtask sweep-isr` on
//!   held-out random views) is a sane setting: on the mean it is closer than DL and than the
//!   unscaled estimator. It is not asserted to win here, nor to beat DL on every view: these
//!   are not the views it was tuned on.
//!
//! The gains of every combination are printed (`--nocapture`).
//!
//! The defaults (64x48, 256 spp) keep the test quick in the dev profile. The figures of
//! `docs/isr.md` come from the same test at a larger size in release:
//! `ISR_REF_WIDTH=128 ISR_REF_HEIGHT=96 ISR_REF_SPP=2048 cargo test --release -p golden-tests
//! --test isr_reference -- --nocapture` (`ISR_REF_BOUNCES=inf` for the unlimited reference).

use isr::{
    Blur, DownsampleMode, Estimator, IsrInputs, IsrSettings, LightSet, Sender, ShadowSettings,
    downsample, render_image,
};
use scene_core::gbuffer::RayCastRenderer;
use scene_core::reference::{Bounces, ReferenceSettings, render};
use scene_core::{GBufferRenderer, View, builtin};

fn env<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Every mode combination with the thesis' constants, then variations of them, then the
/// measured screen-space setting.
fn configurations() -> Vec<(&'static str, IsrSettings)> {
    let base = IsrSettings::thesis_constants();
    let mut v = Vec::new();
    for (name, estimator, sender) in [
        ("thesis/albedo", Estimator::Thesis, Sender::Albedo),
        ("thesis/lit", Estimator::Thesis, Sender::Lit),
        ("patch/albedo", Estimator::Patch, Sender::Albedo),
        ("patch/lit", Estimator::Patch, Sender::Lit),
    ] {
        v.push((
            name,
            IsrSettings {
                estimator,
                sender,
                ..base
            },
        ));
    }
    v.extend([
        (
            "+AO on indirect",
            IsrSettings {
                ao_indirect_only: true,
                ..base
            },
        ),
        (
            "+edge-aware blur",
            IsrSettings {
                blur: Blur::EdgeAware,
                ..base
            },
        ),
        (
            "+24 samples",
            IsrSettings {
                samples: 24,
                ..base
            },
        ),
        (
            "+48 samples",
            IsrSettings {
                samples: 48,
                ..base
            },
        ),
        (
            "+no AO",
            IsrSettings {
                ssao: false,
                ..base
            },
        ),
        (
            "+k_isr 1, no AO",
            IsrSettings {
                ssao: false,
                k_isr: 1.0,
                ..base
            },
        ),
        ("measured screen space", IsrSettings::screen_space()),
        (
            "+surface-avg down",
            IsrSettings {
                downsample: DownsampleMode::SurfaceAverage,
                ..base
            },
        ),
        (
            "+thesis avg down",
            IsrSettings {
                downsample: DownsampleMode::Average,
                ..base
            },
        ),
    ]);
    v
}

#[test]
fn isr_is_closer_to_the_reference_than_dl_on_every_default_camera() {
    let (w, h) = (env("ISR_REF_WIDTH", 64u32), env("ISR_REF_HEIGHT", 48u32));
    let spp = env("ISR_REF_SPP", 256u32);
    let bounces: Bounces = env("ISR_REF_BOUNCES", Bounces::Limited(1));
    let configs = configurations();
    eprintln!(
        "ISR vs DL against the reference ({w}x{h}, {spp} spp, bounce limit {bounces}); \
         gain = (e_DL - e_ISR) / e_DL of eq. 19, share of pixels closer in brackets"
    );
    let mut header = format!("{:<17} {:>9}", "view", "e_DL");
    for (name, _) in &configs {
        header += &format!(" {name:>16}");
    }
    eprintln!("{header}");
    let mut gains = vec![Vec::new(); configs.len()];
    let mut failures = Vec::new();
    let mut views: Vec<String> = Vec::new();
    for name in ["cornell-point", "primitives", "corridor"] {
        let scene = builtin::scene(name).unwrap();
        let prepared = LightSet::new(&scene, &ShadowSettings::default()).unwrap();
        for camera in &scene.cameras {
            let view = View::from_camera(&camera.with_aspect(w as f32 / h as f32));
            let settings = ReferenceSettings {
                width: w,
                height: h,
                spp,
                bounces,
                seed: 19,
            };
            let reference = render(&scene, &view, &settings, None).image;
            let full = RayCastRenderer::new().render(&scene, &view, w, h).unwrap();
            let coarse = downsample(&full, IsrSettings::screen_space().downsample);
            let inputs = IsrInputs {
                full: &full,
                coarse: &coarse,
                view: &view,
            };
            let dl = render_image(&prepared, &inputs, &IsrSettings::dl()).unwrap();
            let e_dl = imalyzer::mean_error(&reference, &dl).unwrap();
            let label = format!("{name} {}", camera.name);
            views.push(label.clone());
            let mut line = format!("{label:<17} {e_dl:>9.5}");
            for (k, (_, s)) in configs.iter().enumerate() {
                // Each configuration's own coarse buffer (its downsampling mode).
                let own = downsample(&full, s.downsample);
                let inputs = IsrInputs {
                    coarse: &own,
                    ..inputs
                };
                let img = render_image(&prepared, &inputs, s).unwrap();
                let q = imalyzer::quality(&reference, &dl, &img).unwrap();
                let gain = q.linear.gain.unwrap_or(0.0);
                gains[k].push(gain);
                line += &format!(
                    " {:>+7.2}% ({:>3.0}%)",
                    100.0 * gain,
                    100.0 * q.linear.share_closer()
                );
            }
            eprintln!("{line}");
        }
    }
    let mut summary = format!("{:<17} {:>9}", "mean gain", "");
    for g in &gains {
        summary += &format!(
            " {:>+7.2}%       ",
            100.0 * g.iter().sum::<f64>() / g.len() as f64
        );
    }
    eprintln!("{summary}");
    let mut wins = format!("{:<17} {:>9}", "views ISR < DL", "");
    for g in &gains {
        wins += &format!(
            " {:>7}/{:<8}",
            g.iter().filter(|&&x| x > 0.0).count(),
            g.len()
        );
    }
    eprintln!("{wins}");
    if bounces != Bounces::Limited(1) {
        return;
    }
    let by_name = |n: &str| {
        let k = configs.iter().position(|(c, _)| *c == n).unwrap();
        &gains[k]
    };
    let mean = |g: &[f64]| g.iter().sum::<f64>() / g.len() as f64;
    for (k, (name, _)) in configs.iter().enumerate() {
        if *name == "patch/albedo" || *name == "measured screen space" {
            continue;
        }
        for (label, g) in views.iter().zip(&gains[k]) {
            if *g <= 0.0 {
                failures.push(format!(
                    "{name}: not closer than DL on {label} (gain {g:+.5})"
                ));
            }
        }
    }
    let pa = by_name("patch/albedo");
    if pa.iter().all(|&g| g > 0.0) {
        failures.push(
            "patch/albedo beat DL on every view (it should add light where there is none)".into(),
        );
    }
    if mean(pa) >= mean(by_name("patch/lit")) {
        failures.push("patch/albedo's mean gain is not below patch/lit's".into());
    }
    for (label, g) in views.iter().zip(pa) {
        if label.starts_with("primitives") && *g <= 0.0 {
            failures.push(format!(
                "patch/albedo: not closer than DL on {label} ({g:+.5})"
            ));
        }
    }
    let (g24, g48, g80) = (
        mean(by_name("+24 samples")),
        mean(by_name("+48 samples")),
        mean(by_name("patch/lit")),
    );
    if !(g24 < g48 && g48 < g80) {
        failures.push(format!(
            "mean gain does not grow with samples: 24 {g24:+.5}, 48 {g48:+.5}, 80 {g80:+.5}"
        ));
    }
    for (label, (k1, k05)) in views
        .iter()
        .zip(by_name("+k_isr 1, no AO").iter().zip(by_name("+no AO")))
    {
        if k1 <= k05 {
            failures.push(format!(
                "{label}: k_isr 1 ({k1:+.5}) does not gain more than 0.5 ({k05:+.5})"
            ));
        }
    }
    // The measured screen-space setting is checked for sanity only: which setting wins is the held-out
    // sweep's question, and these views are not the ones it was tuned on. Sane: closer than
    // DL on the mean and on the mean closer than the unscaled estimator (`k_isr` 1). (At
    // 64x48 it is not closer on every view: on primitives' top view, a sunlit open scene,
    // its `k_isr` 4 overshoots the one-bounce light, measured -5.1 %.)
    let default = mean(by_name("measured screen space"));
    let unscaled = mean(by_name("+k_isr 1, no AO"));
    if !(default > 0.0 && default > unscaled) {
        failures.push(format!(
            "measured screen space: mean gain {default:+.5}, unscaled estimator {unscaled:+.5}"
        ));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
