//! The main job's technique list (`--techniques`): the names a user gives (`dl`, `isr-80`,
//! `isr-ls-80`, `relight-1024`, `ibrr-256-184`, ...) and the settings each stands for;
//! `experiment` and `sweep-isr` build their techniques from them.

use isr::IsrSettings;

/// The ISR sample counts of the thesis.
pub const SAMPLES: [u32; 3] = [24, 48, 80];

/// What a technique the command line named is, with its settings.
#[derive(Clone, Debug, PartialEq)]
pub enum ChoiceKind {
    /// DL or ISR with these frame settings.
    Isr(IsrSettings),
    /// Radiosity relighting at this target element count.
    Relight {
        /// Target element count.
        elements: usize,
        /// The direct light of every frame from shadow maps (`DirectLight::ShadowMaps`)
        /// instead of the per-pixel ray gather (the GPU frame uses the maps either way).
        shadow_maps: bool,
    },
    /// The image-based radiosity representation.
    Ibrr {
        /// LDC resolution.
        ldc: u32,
        /// IRPLs.
        irpls: u32,
        /// The IRPL budget spent where the scene's cameras look
        /// (`IbrrSettings::camera_importance`).
        camera_importance: bool,
    },
}

/// One technique the command line named.
#[derive(Clone, Debug, PartialEq)]
pub struct TechniqueChoice {
    /// Label.
    pub label: String,
    /// `dl`, `isr`, `relight` or `ibrr`.
    pub family: String,
    /// What to build.
    pub kind: ChoiceKind,
    /// Parameters in words.
    pub description: String,
}

/// The element counts of `relight` in a technique list (a coarse and a fine mesh; 4096
/// elements solve for minutes per scene and gain little over 1024 on the built-in scenes).
pub const RELIGHT_ELEMENTS: [usize; 2] = [256, 1024];

/// The (LDC resolution, IRPLs) pairs of `ibrr` in a technique list.
pub const IBRR_SETTINGS: [(u32, u32); 2] = [(128, 64), (256, 184)];

fn relight_choice(elements: usize) -> TechniqueChoice {
    relight_choice_with(elements, false)
}

/// `relight-N`, or with `shadow_maps` `relight-N-sm`.
fn relight_choice_with(elements: usize, shadow_maps: bool) -> TechniqueChoice {
    let (suffix, direct) = if shadow_maps {
        ("-sm", "direct light from shadow maps every frame")
    } else {
        ("", "per-pixel direct light")
    };
    TechniqueChoice {
        label: format!("relight-{elements}{suffix}"),
        family: "relight".into(),
        kind: ChoiceKind::Relight {
            elements,
            shadow_maps,
        },
        description: format!(
            "radiosity relighting, {elements} elements, ray-cast form factors, {direct}, progressive solve (hierarchical above 8 192 elements, e.g. a file of 10^5 triangles) (precomputed per scene)"
        ),
    }
}

fn ibrr_choice(ldc: u32, irpls: u32, camera_importance: bool) -> TechniqueChoice {
    let (suffix, importance) = if camera_importance {
        (
            "-cam",
            ", camera importance (IRPLs the scene's cameras do not see kept 1 in 8)",
        )
    } else {
        ("", "")
    };
    TechniqueChoice {
        label: format!("ibrr-{ldc}-{irpls}{suffix}"),
        family: "ibrr".into(),
        kind: ChoiceKind::Ibrr {
            ldc,
            irpls,
            camera_importance,
        },
        description: format!(
            "image-based radiosity, LDC {ldc}, {irpls} IRPLs, exact splats, bilinear lookup{importance} (precomputed per scene)"
        ),
    }
}

/// The screen-space-only mode of ISR: `isr-scaled-N` (`k_isr` measured on the sweep's
/// views) or `isr-thesis-N` (the thesis' constants).
fn isr_choice(thesis: bool, samples: u32) -> TechniqueChoice {
    let base = if thesis {
        IsrSettings::thesis()
    } else {
        IsrSettings::for_samples(samples)
    };
    let (label, mode) = if thesis {
        (
            format!("isr-thesis-{samples}"),
            "thesis mode (eq. 25 as published, albedo senders)",
        )
    } else {
        (
            format!("isr-scaled-{samples}"),
            "screen-space senders only (patch estimator, lit senders, no AO, k_isr measured for the sample count on sweep-isr's views)",
        )
    };
    TechniqueChoice {
        label,
        family: "isr".into(),
        kind: ChoiceKind::Isr(IsrSettings { samples, ..base }),
        description: format!("{samples} samples, {mode}, CPU rasteriser G-buffer"),
    }
}

/// The light-space senders of the `isr-N`, `isr-ls-N` and `isr-mb-N` techniques (about this
/// many; issue 50): the library's default.
pub const LIGHT_SENDERS: u32 = isr::DEFAULT_LIGHT_SENDERS;

/// ISR with light-space senders carrying every bounce: `isr-mb-N` (light paths continued
/// from the first senders until Russian roulette ends them), or
/// `isr-mbv-N` with exact shadow rays (a measurement, CPU only).
fn isr_mb_choice(samples: u32, shadowed: bool) -> TechniqueChoice {
    let (suffix, how) = if shadowed {
        (
            "mbv",
            ", their light shadowed by a ray per receiver and sender",
        )
    } else {
        ("mb", "")
    };
    TechniqueChoice {
        label: format!("isr-{suffix}-{samples}"),
        family: "isr".into(),
        kind: ChoiceKind::Isr(IsrSettings {
            light_sender_bounces: scene_core::reference::Bounces::Unlimited,
            light_sender_shadows: shadowed,
            ..IsrSettings::with_light_senders(samples, LIGHT_SENDERS)
        }),
        description: format!(
            "{samples} samples and about {LIGHT_SENDERS} light-space senders with every bounce \
             (as isr-{samples}, and as many light paths continued from them, Russian roulette \
             on the albedo){how}, CPU rasteriser G-buffer"
        ),
    }
}

/// ISR with light-space senders: the default `isr-N` (`named` false), or under the name
/// `isr-ls-N`, or `isr-lsv-N` with exact shadow rays.
fn isr_ls_choice(samples: u32, shadowed: bool, named: bool) -> TechniqueChoice {
    let (suffix, how) = if shadowed {
        (
            "-lsv",
            ", their light shadowed by a ray per receiver and sender",
        )
    } else if named {
        ("-ls", "")
    } else {
        ("", "")
    };
    TechniqueChoice {
        label: format!("isr{suffix}-{samples}"),
        family: "isr".into(),
        kind: ChoiceKind::Isr(IsrSettings {
            light_sender_shadows: shadowed,
            ..IsrSettings::with_light_senders(samples, LIGHT_SENDERS)
        }),
        description: format!(
            "{samples} samples and about {LIGHT_SENDERS} light-space senders (reflective shadow \
             maps with visibility maps, interleaved 4x4, each surface counted once, k_isr 1){how}, \
             CPU rasteriser G-buffer"
        ),
    }
}

/// Parses a technique list: `dl`, `isr` (the default and the thesis' modes at 24, 48 and 80
/// samples), `isr-default`, `isr-thesis`, `isr-scaled`, `isr-N` (the default: screen-space
/// and light-space senders, `k_isr` 1), `isr-thesis-N`, `isr-scaled-N` (screen-space senders
/// scaled by a measured `k_isr`), `isr-ls` and `isr-ls-N` (the default under another name),
/// `isr-lsv-N` (with shadow rays), `isr-mb` and `isr-mb-N` (every bounce), `isr-mbv-N`
/// (every bounce, shadow rays), `relight` (256 and 1024 elements), `relight-N`,
/// `relight-N-sm` (the direct light from shadow maps every frame),
/// `ibrr` (LDC 128 with 64 IRPLs, LDC 256 with 184), `ibrr-RES-N`, `ibrr-RES-N-cam` (with
/// camera importance). `dl` (the baseline) is
/// added first when missing.
pub fn parse_techniques(list: &str) -> Result<Vec<TechniqueChoice>, String> {
    let known = "dl, isr, isr-default, isr-thesis, isr-scaled, isr-N, isr-thesis-N, \
                 isr-scaled-N, isr-ls, isr-ls-N, isr-lsv-N, isr-mb, isr-mb-N, isr-mbv-N (N in 1..=256), \
                 relight, relight-N (N elements, 16..=1000000), relight-N-sm (shadow-mapped \
                 direct light), ibrr, ibrr-RES-N (LDC RES in \
                 8..=2048, N IRPLs in 1..=100000), ibrr-RES-N-cam (camera importance)";
    let mut out: Vec<TechniqueChoice> = Vec::new();
    for token in list.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        let t = token.to_ascii_lowercase();
        let mut add: Vec<TechniqueChoice> = Vec::new();
        match t.as_str() {
            "dl" => add.push(TechniqueChoice {
                label: "dl".into(),
                family: "dl".into(),
                kind: ChoiceKind::Isr(IsrSettings::dl()),
                description: "direct light with ESM shadows (the thesis' I_DL)".into(),
            }),
            "isr" => {
                add.extend(SAMPLES.map(|n| isr_ls_choice(n, false, false)));
                add.extend(SAMPLES.map(|n| isr_choice(true, n)));
            }
            "isr-default" => add.extend(SAMPLES.map(|n| isr_ls_choice(n, false, false))),
            "isr-thesis" => add.extend(SAMPLES.map(|n| isr_choice(true, n))),
            "isr-scaled" => add.extend(SAMPLES.map(|n| isr_choice(false, n))),
            "isr-ls" => add.extend(SAMPLES.map(|n| isr_ls_choice(n, false, true))),
            "isr-mb" => add.extend(SAMPLES.map(|n| isr_mb_choice(n, false))),
            "relight" => add.extend(RELIGHT_ELEMENTS.map(relight_choice)),
            "ibrr" => add.extend(IBRR_SETTINGS.map(|(r, n)| ibrr_choice(r, n, false))),
            _ if t.starts_with("relight-") => {
                let rest = &t["relight-".len()..];
                let (rest, maps) = match rest.strip_suffix("-sm") {
                    Some(r) => (r, true),
                    None => (rest, false),
                };
                let n: usize = rest
                    .parse()
                    .ok()
                    .filter(|n| (16..=1_000_000).contains(n))
                    .ok_or_else(|| format!("unknown technique '{token}' (known: {known})"))?;
                add.push(relight_choice_with(n, maps));
            }
            _ if t.starts_with("ibrr-") => {
                let rest = &t["ibrr-".len()..];
                let (rest, cam) = match rest.strip_suffix("-cam") {
                    Some(r) => (r, true),
                    None => (rest, false),
                };
                let parsed = rest.split_once('-').and_then(|(r, n)| {
                    let r: u32 = r.parse().ok().filter(|r| (8..=2048).contains(r))?;
                    let n: u32 = n.parse().ok().filter(|n| (1..=100_000).contains(n))?;
                    Some((r, n))
                });
                let (r, n) = parsed
                    .ok_or_else(|| format!("unknown technique '{token}' (known: {known})"))?;
                add.push(ibrr_choice(r, n, cam));
            }
            _ => {
                let (mode, n) = if let Some(n) = t.strip_prefix("isr-thesis-") {
                    ("thesis", n)
                } else if let Some(n) = t.strip_prefix("isr-scaled-") {
                    ("scaled", n)
                } else if let Some(n) = t.strip_prefix("isr-ls-") {
                    ("ls", n)
                } else if let Some(n) = t.strip_prefix("isr-lsv-") {
                    ("lsv", n)
                } else if let Some(n) = t.strip_prefix("isr-mbv-") {
                    ("mbv", n)
                } else if let Some(n) = t.strip_prefix("isr-mb-") {
                    ("mb", n)
                } else if let Some(n) = t.strip_prefix("isr-") {
                    ("default", n)
                } else {
                    return Err(format!("unknown technique '{token}' (known: {known})"));
                };
                let n: u32 = n
                    .parse()
                    .ok()
                    .filter(|n| (1..=256).contains(n))
                    .ok_or_else(|| format!("unknown technique '{token}' (known: {known})"))?;
                add.push(match mode {
                    "ls" => isr_ls_choice(n, false, true),
                    "lsv" => isr_ls_choice(n, true, true),
                    "mb" => isr_mb_choice(n, false),
                    "mbv" => isr_mb_choice(n, true),
                    "scaled" => isr_choice(false, n),
                    "thesis" => isr_choice(true, n),
                    _ => isr_ls_choice(n, false, false),
                });
            }
        }
        for c in add {
            if !out.iter().any(|o| o.label == c.label) {
                out.push(c);
            }
        }
    }
    if out.is_empty() {
        return Err(format!("no technique given (known: {known})"));
    }
    if !out.iter().any(|c| c.label == "dl") {
        out.insert(0, parse_techniques("dl")?.remove(0));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn technique_lists_expand_and_unknown_names_are_refused() {
        let all = parse_techniques("isr").unwrap();
        let labels: Vec<&str> = all.iter().map(|c| c.label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "dl",
                "isr-24",
                "isr-48",
                "isr-80",
                "isr-thesis-24",
                "isr-thesis-48",
                "isr-thesis-80"
            ]
        );
        assert_eq!(parse_techniques("dl, isr-thesis-48").unwrap().len(), 2);
        let e = parse_techniques("dl,magic").unwrap_err();
        assert!(
            e.contains("unknown technique 'magic'") && e.contains("known"),
            "{e}"
        );
        assert!(parse_techniques("isr-0").is_err());
        let methods =
            parse_techniques("relight,ibrr,relight-100,ibrr-64-32,ibrr-64-32-cam,relight-100-sm")
                .unwrap();
        let labels: Vec<&str> = methods.iter().map(|c| c.label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "dl",
                "relight-256",
                "relight-1024",
                "ibrr-128-64",
                "ibrr-256-184",
                "relight-100",
                "ibrr-64-32",
                "ibrr-64-32-cam",
                "relight-100-sm"
            ]
        );
        assert!(matches!(
            methods[8].kind,
            ChoiceKind::Relight {
                elements: 100,
                shadow_maps: true
            }
        ));
        assert!(matches!(
            methods[5].kind,
            ChoiceKind::Relight {
                shadow_maps: false,
                ..
            }
        ));
        assert!(parse_techniques("relight-8-sm").is_err());
        assert!(matches!(
            methods[7].kind,
            ChoiceKind::Ibrr {
                camera_importance: true,
                ..
            }
        ));
        assert!(matches!(
            methods[6].kind,
            ChoiceKind::Ibrr {
                camera_importance: false,
                ..
            }
        ));
        for bad in [
            "relight-3",
            "ibrr-4-10",
            "ibrr-64",
            "ibrr-64-0",
            "ibrr-64-32-cat",
            "ibrr-cam",
            "relight-x",
        ] {
            assert!(
                parse_techniques(bad)
                    .unwrap_err()
                    .contains("unknown technique"),
                "{bad}"
            );
        }
        assert!(parse_techniques("isr-999").is_err());
        // Light-space senders: k_isr 1, the sender budget, shadowed senders only with -lsv.
        let ls = parse_techniques("isr-ls,isr-lsv-24").unwrap();
        let labels: Vec<&str> = ls.iter().map(|c| c.label.as_str()).collect();
        assert_eq!(
            labels,
            ["dl", "isr-ls-24", "isr-ls-48", "isr-ls-80", "isr-lsv-24"]
        );
        for c in &ls[1..] {
            let ChoiceKind::Isr(s) = &c.kind else {
                panic!("{} is not ISR", c.label)
            };
            assert_eq!(
                (s.k_isr, s.light_senders),
                (1.0, LIGHT_SENDERS),
                "{}",
                c.label
            );
            assert_eq!(
                s.light_sender_shadows,
                c.label.starts_with("isr-lsv"),
                "{}",
                c.label
            );
        }
        assert!(parse_techniques("isr-ls-0").is_err());
        // The default `isr-N` is the light-space form; the screen-space scale is
        // `isr-scaled-N`, with the measured k_isr.
        let isr = parse_techniques("isr-48,isr-scaled-48,isr-scaled").unwrap();
        let labels: Vec<&str> = isr.iter().map(|c| c.label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "dl",
                "isr-48",
                "isr-scaled-48",
                "isr-scaled-24",
                "isr-scaled-80"
            ]
        );
        let settings = |i: usize| match &isr[i].kind {
            ChoiceKind::Isr(s) => *s,
            _ => panic!("{} is not ISR", isr[i].label),
        };
        assert_eq!(
            (settings(1).k_isr, settings(1).light_senders),
            (1.0, LIGHT_SENDERS)
        );
        assert_eq!(
            (settings(2).k_isr, settings(2).light_senders),
            (IsrSettings::k_isr_for_samples(48), 0)
        );
        assert!(parse_techniques("isr-scaled-0").is_err());
    }
}
