//! ISR against the reference path tracer at bounce limit 1 (direct light + one bounce, ISR's
//! scope; the thesis' POV-Ray `recursion_limit 2`): on every default camera of
//! `cornell-point`, `primitives` and `corridor`, ISR's mean error (eq. 19, imalyzer) must be
//! below the DL baseline's. The gains of every mode combination are printed
//! (`--nocapture`).
//!
//! The defaults (64x48, 256 spp) keep the test quick in the dev profile. The figures of
//! `docs/isr.md` come from the same test at a larger size in release:
//! `ISR_REF_WIDTH=128 ISR_REF_HEIGHT=96 ISR_REF_SPP=2048 cargo test --release -p golden-tests
//! --test isr_reference -- --nocapture` (`ISR_REF_BOUNCES=inf` for the unlimited reference).

use isr::{
    Blur, Estimator, IsrInputs, IsrScene, IsrSettings, Sender, ShadowSettings, downsample,
    render_image,
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

/// Every mode combination with the thesis' constants, then variations of the default.
fn configurations() -> Vec<(&'static str, IsrSettings)> {
    let base = IsrSettings::default();
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
    for name in ["cornell-point", "primitives", "corridor"] {
        let scene = builtin::scene(name).unwrap();
        let prepared = IsrScene::new(&scene, &ShadowSettings::default()).unwrap();
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
            let full = RayCastRenderer.render(&scene, &view, w, h).unwrap();
            let coarse = downsample(&full);
            let inputs = IsrInputs {
                full: &full,
                coarse: &coarse,
                view: &view,
            };
            let dl = render_image(&prepared, &inputs, &IsrSettings::dl()).unwrap();
            let e_dl = imalyzer::mean_error(&reference, &dl).unwrap();
            let label = format!("{name} {}", camera.name);
            let mut line = format!("{label:<17} {e_dl:>9.5}");
            for (k, (_, s)) in configs.iter().enumerate() {
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
            // The default configuration must beat DL.
            let isr = render_image(&prepared, &inputs, &IsrSettings::default()).unwrap();
            let e_isr = imalyzer::mean_error(&reference, &isr).unwrap();
            if e_isr >= e_dl {
                failures.push(format!("{label}: ISR {e_isr:.5} >= DL {e_dl:.5}"));
            }
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
    if bounces == Bounces::Limited(1) {
        assert!(failures.is_empty(), "{}", failures.join("\n"));
    }
}
