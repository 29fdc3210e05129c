//! `report.md` and `report.html` from [`Results`]. Every number in the reports is formatted
//! by the functions here from the values in `results.json`.

use std::fmt::Write as _;
use std::path::Path;

pub use crate::format::{fmt_2, fmt_bias, fmt_err, fmt_ms, fmt_pct, fmt_s};
use crate::results::{Results, gain};
use crate::run::{slug, view_dir};

fn opt_ms(x: Option<f64>) -> String {
    x.map(fmt_ms).unwrap_or_else(|| "-".into())
}

fn opt(x: Option<f64>) -> String {
    x.map(fmt_err).unwrap_or_else(|| "-".into())
}

/// A Markdown table: the header row, its rule, then one row per `rows` item.
fn table<S: AsRef<str>>(
    o: &mut String,
    headers: &[S],
    rows: impl IntoIterator<Item = Vec<String>>,
) {
    let headers: Vec<&str> = headers.iter().map(AsRef::as_ref).collect();
    let _ = writeln!(o, "| {} |", headers.join(" | "));
    let _ = writeln!(o, "|{}", "---|".repeat(headers.len()));
    for row in rows {
        let _ = writeln!(o, "| {} |", row.join(" | "));
    }
}

/// The break-even table: per scene, after how many frames each technique that
/// precomputes costs less in total (precomputation + frames) than each other technique.
/// Written only when some technique precomputes.
fn break_even_table(o: &mut String, r: &Results) {
    use crate::results::{BreakEven, break_even};
    let mut scenes: Vec<&str> = r.views.iter().map(|v| v.scene.as_str()).collect();
    scenes.sort_unstable();
    scenes.dedup();
    let n = scenes.len().max(1) as f64;
    let rows: Vec<_> = r
        .summary
        .times
        .iter()
        .filter(|t| r.techniques.iter().any(|x| x.label == t.label))
        .collect();
    if !rows.iter().any(|t| t.prepare_s > 0.0) {
        return;
    }
    let _ = writeln!(
        o,
        "\n## Break-even\n\nPer scene: precomputation (the mean over scenes) plus frames at the \
         average frame time. \"after N\": the row's technique costs less than the column's \
         from N frames on; \"first N\": for the first N frames only; \"always\" and \"never\" \
         for any number of frames.\n"
    );
    let mut headers = vec!["technique"];
    headers.extend(rows.iter().map(|t| t.label.as_str()));
    let cells = rows.iter().map(|a| {
        let mut row = vec![a.label.clone()];
        row.extend(rows.iter().map(|b| {
            if a.label == b.label {
                return String::new();
            }
            match break_even(
                a.prepare_s / n,
                a.avg_frame_ms * 1e-3,
                b.prepare_s / n,
                b.avg_frame_ms * 1e-3,
            ) {
                BreakEven::Always => "always".into(),
                BreakEven::Never => "never".into(),
                BreakEven::After(f) => format!("after {}", f.ceil()),
                BreakEven::Until(f) => format!("first {}", f.floor()),
            }
        }));
        row
    });
    table(o, &headers, cells);
}

/// The ranking: techniques by mean error at the last bounce limit, closest first.
pub fn ranking_section(r: &Results) -> String {
    let mut o = String::new();
    let Some(first) = r.summary.ranking.first() else {
        return o;
    };
    let _ = writeln!(
        o,
        "## Ranking\n\nBy mean error over every view against the reference at bounce limit \
         {}. Frame: a moving camera (every timed frame a view the technique had not rendered, \
         so per-view work is inside); still: the same view again (reusing per-view work), a \
         second figure that nothing below is computed from. Surface error and bias: over lit \
         surfaces only (emitters, background and the reference's brightest 1% left out), \
         bias per channel R / G / B. Pareto: scenes where no other technique is both faster \
         and closer; speedup: over the path tracer at equal error (\"> N\": closer than the \
         ladder's finest rung, a lower bound).\n",
        first.bounces
    );
    table(
        &mut o,
        &[
            "rank",
            "technique",
            "mean error",
            "surface error",
            "surface bias",
            "frame (ms)",
            "still camera (ms)",
            "precomputation (s)",
            "Pareto scenes",
            "speedup at equal error",
        ],
        r.summary.ranking.iter().map(|k| {
            vec![
                k.rank.to_string(),
                k.technique.clone(),
                fmt_err(k.mean_error),
                opt(k.surface_error),
                k.surface_bias.map(fmt_bias).unwrap_or_else(|| "-".into()),
                fmt_ms(k.frame_ms),
                opt_ms(k.still_frame_ms),
                fmt_s(k.prepare_s),
                k.pareto_scenes.to_string(),
                k.speedup.clone().unwrap_or_else(|| "-".into()),
            ]
        }),
    );
    o
}

/// The relighting sequence as a table: per frame the caption, each technique's error and
/// frame time.
pub fn sequence_section(r: &Results) -> String {
    let mut o = String::new();
    let Some(q) = &r.sequence else {
        return o;
    };
    let _ = writeln!(
        o,
        "## Relighting sequence\n\n{} / {}, {} frames, references at {} spp (bounces {}), \
         error `{}`. The camera stays still while the lights change, so these are \
         still-camera frame times. Each cell: error / error over lit surfaces / frame time \
         (ms). Precomputation (s): {}.\n",
        q.scene,
        q.camera,
        q.frames.len(),
        q.spp,
        q.bounces,
        q.metric,
        q.prepare_s
            .iter()
            .map(|(l, t)| format!("{l} {}", fmt_s(*t)))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let mut headers = vec!["frame", "lights"];
    headers.extend(q.prepare_s.iter().map(|(l, _)| l.as_str()));
    let rows = q.frames.iter().enumerate().map(|(i, f)| {
        let mut row = vec![i.to_string(), f.caption.clone()];
        row.extend(f.techniques.iter().map(|t| {
            format!(
                "{} / {} / {}",
                fmt_err(t.error),
                opt(t.surface.map(|x| x.mean_error)),
                fmt_ms(t.frame_s * 1e3)
            )
        }));
        row
    });
    table(&mut o, &headers, rows);
    o
}

/// Error over lit surfaces per technique and scene, beside the whole-image error.
pub fn surface_section(o: &mut String, r: &Results) {
    if r.summary.surface.is_empty() {
        return;
    }
    let _ = writeln!(
        o,
        "\n## Error over lit surfaces\n\nPer scene and bounce limit, the mean error over \
         the pixels that see a reflecting surface (emitters, background and the reference's \
         brightest 1% left out) beside the whole-image error, and the bias per channel R / G \
         / B over those pixels ((sum test - sum reference) / sum reference: -10% is 10% \
         dark).\n"
    );
    let stated = r.summary.surface.iter().any(|x| x.stated_error.is_some());
    if stated {
        let _ = writeln!(
            o,
            "Stated error: the method's own estimate of its lit-surface error on the scene, \
             made from its precomputation alone (the half-width of a 95% interval of the \
             lit-surface mean, largest channel; the IBRR's batches of particle paths), to \
             hold against the bias beside it at the run's last bounce limit (the methods \
             that state one carry every bounce).\n"
        );
    }
    let last = r.settings.bounces.last();
    let mut headers = vec![
        "technique",
        "scene",
        "bounces",
        "views",
        "surface error",
        "image error",
        "surface bias",
    ];
    if stated {
        headers.push("stated error");
    }
    table(
        o,
        &headers,
        r.summary.surface.iter().map(|x| {
            let mut row = vec![
                x.technique.clone(),
                x.scene.clone(),
                x.bounces.clone(),
                x.views.to_string(),
                fmt_err(x.mean_error),
                fmt_err(x.image_error),
                fmt_bias(x.bias),
            ];
            if stated {
                row.push(
                    x.stated_error
                        .filter(|_| last == Some(&x.bounces))
                        .map(|e| format!("{:.1}%", 100.0 * e))
                        .unwrap_or_else(|| "-".into()),
                );
            }
            row
        }),
    );
}

/// The equal-error table: the path tracer's spp and time at each technique's error.
fn equal_error_table(o: &mut String, r: &Results) {
    if r.summary.equal_error.is_empty() {
        return;
    }
    let ladder: Vec<String> = r
        .views
        .first()
        .and_then(|v| v.references.first())
        .map(|rf| rf.ladder.iter().map(|p| p.spp.to_string()).collect())
        .unwrap_or_default();
    let _ = writeln!(
        o,
        "\n## Equal error (why not just path trace)\n\nThe path tracer renders every view \
         again at {} spp with another seed; its error against the reference, read in log-log \
         between those rungs, gives the spp at which it is as close as each technique, and \
         its seconds per sample give the time. Speedup: the median over views of the \
         path tracer's seconds over the technique's moving-camera frame time (precomputation \
         not counted; above 1 the technique is faster at equal error), over the views the \
         ladder brackets. Nothing is extrapolated: the ladder is extended (rungs at twice the \
         finest, up to half the reference's spp, where the reference's own noise sets the \
         floor) until it brackets each technique's error; a view still closer than the finest \
         rung counts under \"above ladder\" and is left out of the median (when every view is \
         above, the speedup is shown as \"> N\", the median of their lower bounds); \"below \
         ladder\": farther than 1 spp. Surface error: over lit surfaces.\n",
        ladder.join(", ")
    );
    table(
        o,
        &[
            "technique",
            "bounces",
            "views",
            "mean error",
            "path tracer spp (median)",
            "path tracer (s)",
            "frame (ms)",
            "speedup",
            "above ladder",
            "below ladder",
            "surface error",
        ],
        r.summary.equal_error.iter().map(|e| {
            vec![
                e.technique.clone(),
                e.bounces.clone(),
                e.views.to_string(),
                fmt_err(e.mean_error),
                fmt_2(e.median_spp),
                fmt_s(e.mean_path_tracer_s),
                fmt_ms(e.mean_frame_s * 1e3),
                e.shown(),
                e.above_ladder.to_string(),
                e.below_ladder.to_string(),
                opt(e.surface_error),
            ]
        }),
    );
}

/// The report in Markdown: settings, Table 2 (time), the break-even frame counts, the summary statistics, speed against
/// error per scene and the per-view errors of `headline` against the baseline.
pub fn markdown(r: &Results, headline: Option<&str>) -> String {
    let s = &r.settings;
    let mut o = String::new();
    let _ = writeln!(o, "# Experiment report\n");
    let _ = writeln!(
        o,
        "{} views, {}x{}, reference {} spp at bounce limits {}, {} warm-up + {} timed frames \
         per view from views new to the technique (moving camera) + {} still-camera frames; \
         error metric `{}`, baseline `{}`.\n",
        r.views.len(),
        s.width,
        s.height,
        s.spp,
        s.bounces.join(", "),
        s.warmup,
        s.repeats,
        s.still_repeats,
        s.error_metric,
        s.baseline
    );
    if !s.reference_renderer.is_empty() {
        let _ = writeln!(
            o,
            "References and the equal-error ladder: {}.\n",
            s.reference_renderer
        );
    }
    o.push_str(&ranking_section(r));
    let _ = writeln!(o, "\n## Techniques\n");
    let _ = writeln!(o, "| label | family | parameters |\n|---|---|---|");
    for t in &r.techniques {
        let _ = writeln!(o, "| {} | {} | {} |", t.label, t.family, t.description);
    }
    let _ = writeln!(
        o,
        "\n## Time (the thesis' Table 2)\n\nTotal = sum of the per-view median frame times.\n"
    );
    let device = r.summary.times.iter().any(|t| t.clock.is_some());
    if device {
        let _ = writeln!(
            o,
            "Frame times of a technique with a clock are the method's own time on its device, \
             its G-buffer drawn and its image read back outside it; the harness wall time is \
             the whole render the harness timed around it (G-buffer, method, readback), a \
             second, labelled figure that nothing else is computed from.\n"
        );
    }
    let mut headers = vec![
        "technique",
        "views",
        "total time (s)",
        "average frame time (ms)",
        "average FPS",
        "still camera (ms)",
        "precomputation (s)",
    ];
    if device {
        headers.extend(["clock", "harness wall (ms)"]);
    }
    table(
        &mut o,
        &headers,
        r.summary.times.iter().map(|t| {
            let mut row = vec![
                t.label.clone(),
                t.views.to_string(),
                fmt_s(t.total_s),
                fmt_ms(t.avg_frame_ms),
                fmt_2(t.avg_fps),
                opt_ms(t.still_frame_ms),
                fmt_s(t.prepare_s),
            ];
            if device {
                row.push(t.clock.clone().unwrap_or_else(|| "harness wall".into()));
                row.push(opt_ms(t.harness_frame_ms));
            }
            row
        }),
    );
    surface_section(&mut o, r);
    break_even_table(&mut o, r);
    equal_error_table(&mut o, r);
    if r.sequence.is_some() {
        let _ = writeln!(o);
        o.push_str(&sequence_section(r));
    }
    let _ = writeln!(
        o,
        "\n## Against the baseline (the thesis' summary statistics)\n\nGain = mean over views \
         of (e_baseline - e) / e_baseline with e the eq. 19 mean error; pixels closer: share \
         of all pixels whose distance to the reference (sum over channels of |D|) is below \
         the baseline's; changed pixels closer: the same share among the pixels whose distance \
         differs from the baseline's (ties left out).\n"
    );
    let _ = writeln!(
        o,
        "| technique | bounces | views | views better | mean gain | mean error | baseline mean error | mean Pearson | baseline mean Pearson | pixels closer | changed pixels closer |\n|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for c in &r.summary.comparisons {
        let _ = writeln!(
            o,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            c.technique,
            c.bounces,
            c.views,
            fmt_pct(c.share_views_better),
            fmt_pct(c.mean_gain),
            fmt_err(c.mean_error),
            fmt_err(c.baseline_mean_error),
            opt(c.mean_pearson),
            opt(c.baseline_mean_pearson),
            fmt_pct(c.share_pixels_closer),
            fmt_pct(c.share_changed_pixels_closer)
        );
    }
    let _ = writeln!(o, "\n## Speed against error per scene\n");
    for se in &r.summary.speed_error {
        let _ = writeln!(
            o,
            "### {} (error at bounce limit {})\n\n| technique | frame (ms) | mean error | Pareto |\n|---|---|---|---|",
            se.scene, se.bounces
        );
        for p in &se.points {
            let _ = writeln!(
                o,
                "| {} | {} | {} | {} |",
                p.label,
                fmt_ms(p.frame_ms),
                fmt_err(p.error),
                if p.pareto { "yes" } else { "" }
            );
        }
        let _ = writeln!(o);
    }
    if let Some(h) = headline {
        let _ = writeln!(
            o,
            "## Per view: `{}` against `{}` (mean error, bounce limit {})\n",
            h,
            s.baseline,
            s.bounces.first().map(String::as_str).unwrap_or("-")
        );
        let _ = writeln!(
            o,
            "| scene | camera | {} | {} | gain |\n|---|---|---|---|---|",
            s.baseline, h
        );
        for v in &r.views {
            let b = s.bounces.first().map(String::as_str).unwrap_or("1");
            if let (Some(eb), Some(eh)) = (
                v.error(&s.baseline, b, &s.error_metric),
                v.error(h, b, &s.error_metric),
            ) {
                let _ = writeln!(
                    o,
                    "| {} | {} | {} | {} | {} |",
                    v.scene,
                    v.camera_name(),
                    fmt_err(eb),
                    fmt_err(eh),
                    fmt_pct(gain(eb, eh))
                );
            }
        }
    }
    o
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The subset of Markdown the report uses (headings, pipe tables, paragraphs, `code`) as HTML.
pub fn markdown_to_html(md: &str) -> String {
    let inline = |t: &str| {
        let mut out = String::new();
        for (i, part) in esc(t).split('`').enumerate() {
            if i % 2 == 1 {
                let _ = write!(out, "<code>{part}</code>");
            } else {
                out.push_str(part);
            }
        }
        out
    };
    let mut o = String::new();
    let mut in_table = false;
    for line in md.lines() {
        let t = line.trim();
        if t.starts_with('|') {
            let cells: Vec<&str> = t.trim_matches('|').split('|').map(str::trim).collect();
            if cells
                .iter()
                .all(|c| !c.is_empty() && c.chars().all(|ch| ch == '-'))
            {
                continue;
            }
            let tag = if in_table { "td" } else { "th" };
            if !in_table {
                o.push_str("<table>");
                in_table = true;
            }
            o.push_str("<tr>");
            for c in cells {
                let _ = write!(o, "<{tag}>{}</{tag}>", inline(c));
            }
            o.push_str("</tr>");
            continue;
        }
        if in_table {
            o.push_str("</table>");
            in_table = false;
        }
        let level = t.chars().take_while(|&c| c == '#').count();
        if level > 0 {
            let _ = write!(o, "<h{level}>{}</h{level}>", inline(t[level..].trim()));
        } else if !t.is_empty() {
            let _ = write!(o, "<p>{}</p>", inline(t));
        }
    }
    if in_table {
        o.push_str("</table>");
    }
    o
}

/// A plot, or the reason it could not be drawn, as HTML.
fn plot_html(p: Result<String, String>) -> String {
    match p {
        Ok(svg) => format!("<div class=\"plot\">{svg}</div>"),
        Err(e) => format!("<p class=\"error\">{}</p>", esc(&e)),
    }
}

/// The images the HTML gallery links for one view, relative to the run's folder.
#[derive(Clone, Debug)]
pub struct GalleryImages {
    /// The reference at the run's last bounce limit.
    pub reference: std::path::PathBuf,
    /// Each technique's image, in the view's order.
    pub techniques: Vec<std::path::PathBuf>,
    /// Each technique's error map at the same bounce limit.
    pub error_maps: Vec<std::path::PathBuf>,
}

impl GalleryImages {
    /// Every image, the reference first.
    pub fn all(&self) -> impl Iterator<Item = &std::path::PathBuf> {
        std::iter::once(&self.reference)
            .chain(&self.techniques)
            .chain(&self.error_maps)
    }
}

/// The images the HTML gallery links for view `v` of `r` ([`crate::merge()`] checks that
/// they exist before a merged report links them).
pub fn gallery_images(r: &Results, v: &crate::results::ViewResult) -> GalleryImages {
    let gb = gallery_bounces(r);
    let dir = view_dir(&v.scene, v.camera_index, &v.camera_name());
    let each = |name: &dyn Fn(&str) -> String| {
        v.techniques
            .iter()
            .map(|t| dir.join(name(&slug(&t.label))))
            .collect()
    };
    GalleryImages {
        reference: dir.join(format!("reference-b{gb}.png")),
        techniques: each(&|l| format!("{l}.png")),
        error_maps: each(&|l| format!("errmap-{l}-b{gb}.png")),
    }
}

/// The bounce limit the gallery shows: the run's last.
fn gallery_bounces(r: &Results) -> String {
    r.settings
        .bounces
        .last()
        .cloned()
        .unwrap_or_else(|| "1".into())
}

fn img(src: &Path, alt: &str) -> String {
    let src = src.display().to_string().replace('\\', "/");
    format!(
        "<img src=\"{}\" alt=\"{}\" loading=\"eager\">",
        esc(&src),
        esc(alt)
    )
}

/// The page checks itself once loaded: every image decoded and every plot drawn, written to
/// `#check` and `<body data-check>` (read by the headless-browser test).
const SELF_CHECK: &str = "<script>window.addEventListener('load',function(){\
var imgs=Array.prototype.slice.call(document.images);\
var bad=imgs.filter(function(i){return !(i.complete&&i.naturalWidth>0);});\
var plots=document.querySelectorAll('div.plot svg').length;\
var s=(bad.length===0?'ok':'broken')+' images='+imgs.length+' broken='+bad.length+' plots='+plots;\
document.body.setAttribute('data-check',s);\
var p=document.getElementById('check');if(p){p.textContent='Page check: '+s;}});</script>";

/// The report in HTML: a ranking of the techniques, the speed-against-error plot of each
/// scene and bounce limit with the Pareto front, the relighting sequence's error and time
/// along its frames, a gallery per view (reference, every technique, their error maps in a
/// perceptual colour map, side by side), the per-view errors and gains against the baseline
/// (thesis figures 5.8 and 5.9), and every table of the Markdown report. Plots are SVG
/// drawn with plotters; images are linked relative to `out` (the page lives there).
pub fn html(r: &Results, headline: Option<&str>, out: &Path) -> String {
    let _ = out;
    let s = &r.settings;
    let colour_of = |label: &str| {
        r.techniques
            .iter()
            .position(|t| t.label == label)
            .unwrap_or(r.techniques.len())
    };
    let mut o = String::from(
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>Experiment report</title><link rel=\"icon\" href=\"data:,\">\
         <style>body{font-family:sans-serif;max-width:1400px;margin:auto;padding:0 12px}\
         table{border-collapse:collapse;margin:6px 0}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}\
         td:first-child,th:first-child{text-align:left}.plot{display:inline-block;margin:4px}\
         .gallery{display:grid;gap:4px;margin-bottom:16px}.gallery figure{margin:0}\
         .gallery img{width:100%;image-rendering:pixelated;display:block}\
         figcaption{font-size:12px}.error{color:#b00}</style></head><body>",
    );
    let _ = write!(
        o,
        "<h1>Experiment report</h1><p id=\"check\">Page check: not run</p><p>{} views, \
         {}x{}, reference {} spp at bounce limits {}, error metric <code>{}</code>, baseline \
         <code>{}</code>.</p>",
        r.views.len(),
        s.width,
        s.height,
        s.spp,
        esc(&s.bounces.join(", ")),
        esc(&s.error_metric),
        esc(&s.baseline)
    );
    // Ranking.
    o.push_str(&markdown_to_html(&ranking_section(r)));
    // Speed against error.
    o.push_str("<h2>Speed against error</h2>");
    for se in &r.summary.speed_error {
        o.push_str(&plot_html(crate::plots::speed_error(se, &colour_of)));
    }
    // The relighting sequence.
    if let Some(q) = &r.sequence {
        let _ = write!(
            o,
            "<h2>Relighting sequence: {} / {}</h2><p>After one precomputation the lights \
             change every frame; each frame's reference is rendered under that frame's \
             lights ({} spp, bounces {}).</p>",
            esc(&q.scene),
            esc(&q.camera),
            q.spp,
            esc(&q.bounces)
        );
        let frames: Vec<String> = (0..q.frames.len()).map(|i| i.to_string()).collect();
        let labels: Vec<&String> = q.prepare_s.iter().map(|p| &p.0).collect();
        let lines = |pick: fn(&(f64, f64)) -> f64| -> Vec<(String, usize, Vec<f64>)> {
            labels
                .iter()
                .map(|l| {
                    (
                        l.to_string(),
                        colour_of(l),
                        q.series(l).iter().map(pick).collect(),
                    )
                })
                .collect()
        };
        o.push_str(&plot_html(crate::plots::series(
            "error along the sequence",
            "frame",
            &q.metric,
            &frames,
            &lines(|p| p.1),
            false,
        )));
        o.push_str(&plot_html(crate::plots::series(
            "frame time along the sequence",
            "frame",
            "seconds (log scale)",
            &frames,
            &lines(|p| p.0),
            true,
        )));
        o.push_str(&markdown_to_html(&sequence_section(r)));
    }
    // Gallery.
    let gb = gallery_bounces(r);
    let _ = write!(
        o,
        "<h2>Gallery</h2><p>Every view at bounce limit {gb}: the reference and every \
         technique, and below each technique its error map (per pixel |reference - image| \
         summed over channels, over the reference's mean; viridis):</p>{}",
        plot_html(crate::plots::colour_bar(&format!(
            ">= {:.0}% of the mean",
            crate::experiment::ERROR_MAP_TOP * 100.0
        )))
    );
    let cols = r.techniques.len() + 1;
    for v in &r.views {
        let g = gallery_images(r, v);
        let (reference, shots, maps) = (&g.reference, &g.techniques, &g.error_maps);
        let _ = write!(
            o,
            "<h3>{} / {}</h3><div class=\"gallery\" style=\"grid-template-columns:repeat({cols},1fr)\">",
            esc(&v.scene),
            esc(&v.camera_name())
        );
        let _ = write!(
            o,
            "<figure>{}<figcaption>reference ({} spp)</figcaption></figure>",
            img(reference, "reference"),
            s.spp
        );
        for (t, shot) in v.techniques.iter().zip(shots) {
            let e = v.error(&t.label, &gb, &s.error_metric);
            let _ = write!(
                o,
                "<figure>{}<figcaption>{} ({} ms, error {})</figcaption></figure>",
                img(shot, &t.label),
                esc(&t.label),
                fmt_ms(t.frame.median_s * 1e3),
                e.map(fmt_err).unwrap_or_else(|| "-".into())
            );
        }
        o.push_str("<figure></figure>");
        for (t, map) in v.techniques.iter().zip(maps) {
            let _ = write!(
                o,
                "<figure>{}<figcaption>error map: {}</figcaption></figure>",
                img(map, &format!("error map of {}", t.label)),
                esc(&t.label)
            );
        }
        o.push_str("</div>");
    }
    // Per view against the baseline.
    let b = s.bounces.first().cloned().unwrap_or_else(|| "1".into());
    if let Some(h) = headline {
        let pairs: Vec<(f64, f64)> = r
            .views
            .iter()
            .filter_map(|v| {
                Some((
                    v.error(&s.baseline, &b, &s.error_metric)?,
                    v.error(h, &b, &s.error_metric)?,
                ))
            })
            .collect();
        let names: Vec<String> = r
            .views
            .iter()
            .map(|v| format!("{}/{}", v.scene, v.camera_index))
            .collect();
        let _ = write!(
            o,
            "<h2>Per view ({} against {})</h2>",
            esc(h),
            esc(&s.baseline)
        );
        o.push_str(&plot_html(crate::plots::series(
            &format!("mean error per view, bounces {b} (figure 5.8)"),
            "view",
            "mean error",
            &names,
            &[
                (
                    s.baseline.clone(),
                    colour_of(&s.baseline),
                    pairs.iter().map(|p| p.0).collect(),
                ),
                (
                    h.to_string(),
                    colour_of(h),
                    pairs.iter().map(|p| p.1).collect(),
                ),
            ],
            false,
        )));
        o.push_str(&plot_html(crate::plots::series(
            &format!("quality gain per view, bounces {b} (figure 5.9)"),
            "view",
            "gain",
            &names,
            &[(
                "gain".into(),
                colour_of(h),
                pairs.iter().map(|p| gain(p.0, p.1)).collect(),
            )],
            false,
        )));
    }
    o.push_str("<h2>Tables</h2>");
    o.push_str(&markdown_to_html(&markdown(r, headline)));
    o.push_str(SELF_CHECK);
    o.push_str("</body></html>\n");
    o
}
