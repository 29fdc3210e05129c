//! Combining the output folders of a sharded run ([`crate::ExperimentSettings::shard`]) into
//! one report: the views of every shard put back in run order, the summary computed once from
//! all of them, so the merged `results.json` holds the same errors and the same ranking as a
//! single run of the same settings.
//!
//! The shards are independent processes: run them with any job runner (GNU parallel on one
//! host, a Slurm job array, a Kubernetes Indexed Job), give them one reference cache folder
//! if they share a file system, and merge their folders when all are done.

use std::path::{Path, PathBuf};

use crate::HarnessError;
use crate::results::{Results, summarize};

/// What [`merge`] wrote.
#[derive(Clone, Debug)]
pub struct Merged {
    /// The merged results.
    pub results: Results,
    /// `results.json`.
    pub results_json: PathBuf,
    /// `report.md`.
    pub report_md: PathBuf,
    /// `report.html`.
    pub report_html: PathBuf,
}

/// Reads `<dir>/results.json` of a shard (within the default file budget).
pub fn read_results(dir: &Path) -> Result<Results, HarnessError> {
    read_results_file(&dir.join("results.json"))
}

/// Reads a `results.json` (within the default file budget).
pub fn read_results_file(path: &Path) -> Result<Results, HarnessError> {
    let bytes = scene_core::budget::read_file(path, &scene_core::Budget::default())
        .map_err(|e| HarnessError::io(path, e))?;
    serde_json::from_slice(&bytes).map_err(|e| HarnessError::io(path, e))
}

/// Merges the shard folders `dirs` into `out`: checks that they are the shares `1/N` to
/// `N/N` of one run (same settings, techniques, metrics, scenes, scene contents and tool
/// version; every share exactly once; every image the report links present), puts their
/// views back in run order, recomputes the summary, copies every image (`images/`,
/// `sequence/`) and writes `results.json`, `report.md` and `report.html`. `headline` is the
/// technique shown against the baseline in the gallery.
///
/// Nothing is written before every check has passed, and `out` may be neither one of the
/// shard folders nor inside one (merging would overwrite that shard's `results.json`).
pub fn merge(dirs: &[PathBuf], out: &Path, headline: Option<&str>) -> Result<Merged, HarnessError> {
    let invalid = |m: String| HarnessError::Invalid(format!("merge: {m}"));
    let mut shards: Vec<(PathBuf, Results)> = Vec::new();
    for d in dirs {
        shards.push((d.clone(), read_results(d)?));
    }
    let out_abs = absolute(out);
    for d in dirs {
        let d_abs = absolute(d);
        if out_abs.starts_with(&d_abs) {
            return Err(invalid(format!(
                "the output folder {} is {} shard folder {}: merging would overwrite that \
                 shard; give another --out",
                out.display(),
                if out_abs == d_abs {
                    "the"
                } else {
                    "inside the"
                },
                d.display()
            )));
        }
    }
    let Some((first_dir, first)) = shards.first() else {
        return Err(invalid("no shard folder given".into()));
    };
    let count = first
        .run
        .shard
        .map(|s| s.count)
        .ok_or_else(|| invalid(format!("{} is not a shard's output", first_dir.display())))?;
    let mut seen = vec![false; count];
    for (d, r) in &shards {
        let Some(s) = r.run.shard else {
            return Err(invalid(format!("{} is not a shard's output", d.display())));
        };
        if s.count != count {
            return Err(invalid(format!(
                "{} is share {s} but {} is of {count}",
                d.display(),
                first_dir.display()
            )));
        }
        if std::mem::replace(&mut seen[s.index], true) {
            return Err(invalid(format!("share {s} is given twice")));
        }
        if r.settings != first.settings
            || r.techniques != first.techniques
            || r.metrics != first.metrics
            || r.run.scenes != first.run.scenes
        {
            return Err(invalid(format!(
                "{} was run with other settings, techniques, metrics or scenes than {}",
                d.display(),
                first_dir.display()
            )));
        }
        if r.run.tool_version.is_empty() || r.run.scene_hashes.len() != r.run.scenes.len() {
            return Err(invalid(format!(
                "{} records no tool version or scene hashes (made by an older version): run \
                 its share again",
                d.display()
            )));
        }
        if r.run.tool_version != first.run.tool_version {
            return Err(invalid(format!(
                "{} was made by {} but {} by {}",
                d.display(),
                r.run.tool_version,
                first_dir.display(),
                first.run.tool_version
            )));
        }
        if let Some(i) =
            (0..r.run.scenes.len()).find(|&i| r.run.scene_hashes[i] != first.run.scene_hashes[i])
        {
            return Err(invalid(format!(
                "scene '{}' differs between {} (content hash {}) and {} ({}): the scene file \
                 changed between the shares",
                r.run.scenes[i],
                d.display(),
                r.run.scene_hashes[i],
                first_dir.display(),
                first.run.scene_hashes[i]
            )));
        }
    }
    if let Some(missing) = seen.iter().position(|s| !s) {
        return Err(invalid(format!(
            "share {}/{count} is missing ({} of {count} given)",
            missing + 1,
            shards.len()
        )));
    }
    let order = |scene: &str| first.run.scenes.iter().position(|s| s == scene);
    let mut views: Vec<_> = shards
        .iter()
        .flat_map(|(_, r)| r.views.iter().cloned())
        .collect();
    views.sort_by_key(|v| (order(&v.scene), v.camera_index));
    if let Some(w) = views
        .windows(2)
        .find(|w| w[0].scene == w[1].scene && w[0].camera_index == w[1].camera_index)
    {
        return Err(invalid(format!(
            "view {} / {} appears in two shards",
            w[0].scene, w[0].camera_index
        )));
    }
    let sequences: Vec<_> = shards
        .iter()
        .filter_map(|(_, r)| r.sequence.clone())
        .collect();
    if sequences.len() > 1 {
        return Err(invalid(
            "more than one shard holds the relighting sequence".into(),
        ));
    }
    if first.run.sequence_expected && sequences.is_empty() {
        return Err(invalid("the relighting sequence is in no shard".into()));
    }
    // Every image the report will link, in the shard that made the view.
    for (d, r) in &shards {
        for v in &r.views {
            if let Some(missing) = crate::report::gallery_images(r, v)
                .all()
                .find(|p| !d.join(p).is_file())
            {
                return Err(invalid(format!(
                    "{} is missing {} (view {} / {}): the report would link a missing image; \
                     run that share again",
                    d.display(),
                    missing.display(),
                    v.scene,
                    v.camera_index
                )));
            }
        }
    }
    std::fs::create_dir_all(out).map_err(|e| HarnessError::io(out, e))?;
    for (d, _) in &shards {
        for sub in ["images", "sequence"] {
            copy_tree(&d.join(sub), &out.join(sub))?;
        }
    }
    let summary = summarize(&first.settings, &first.techniques, &views);
    let mut run = first.run.clone();
    // The command of every share, then the merge.
    if let Some(s) = run.shard {
        run.command = format!(
            "{}; then `cargo xtask experiment merge` of the {count} shares",
            run.command.replace(
                &format!("--shard {s}"),
                &format!("--shard K/{count} (K = 1 to {count})")
            )
        );
    }
    run.shard = None;
    run.merged_shards = count;
    run.seconds = shards
        .iter()
        .map(|(_, r)| r.run.seconds)
        .fold(0.0, f64::max);
    run.date = shards
        .iter()
        .map(|(_, r)| r.run.date.clone())
        .max()
        .unwrap_or_default();
    let results = Results {
        settings: first.settings.clone(),
        techniques: first.techniques.clone(),
        metrics: first.metrics.clone(),
        views,
        summary,
        sequence: sequences.into_iter().next(),
        run,
    };
    let results_json = out.join("results.json");
    let report_md = out.join("report.md");
    let report_html = out.join("report.html");
    crate::write_json(&results_json, &results)?;
    crate::experiment::write_text(&report_md, &crate::report::markdown(&results, headline))?;
    crate::experiment::write_text(&report_html, &crate::report::html(&results, headline, out))?;
    Ok(Merged {
        results,
        results_json,
        report_md,
        report_html,
    })
}

/// Copies the regular files under `from` to the same places under `to` (a missing `from`
/// copies nothing; links are not followed).
fn copy_tree(from: &Path, to: &Path) -> Result<(), HarnessError> {
    let Ok(entries) = std::fs::read_dir(from) else {
        return Ok(());
    };
    std::fs::create_dir_all(to).map_err(|e| HarnessError::io(to, e))?;
    for e in entries {
        let e = e.map_err(|e| HarnessError::io(from, e))?;
        let kind = e.file_type().map_err(|x| HarnessError::io(&e.path(), x))?;
        let target = to.join(e.file_name());
        if kind.is_dir() {
            copy_tree(&e.path(), &target)?;
        } else if kind.is_file() {
            std::fs::copy(e.path(), &target).map_err(|x| HarnessError::io(&target, x))?;
        }
    }
    Ok(())
}

/// `p` made absolute and free of `.` and `..` (through the existing part of the path, so
/// links resolve), for comparing folders that may not exist yet.
fn absolute(p: &Path) -> PathBuf {
    let abs = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    // The longest existing ancestor, canonicalised, and the rest appended.
    let mut rest = Vec::new();
    let mut cur = abs.as_path();
    loop {
        if let Ok(c) = cur.canonicalize() {
            return rest
                .iter()
                .rev()
                .fold(c, |acc: PathBuf, part| acc.join(part));
        }
        match (cur.parent(), cur.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                cur = parent;
            }
            _ => return abs,
        }
    }
}
