//! `report.md` and `report.html` from [`Results`]. Every number in the reports is formatted
//! by the functions here from the values in `results.json`.

use std::fmt::Write as _;
use std::path::Path;

use base64::Engine as _;

use crate::experiment::{slug, view_dir};
use crate::results::{Results, SceneSpeedError, gain};

/// A time in seconds, 3 decimals.
pub fn fmt_s(x: f64) -> String {
    format!("{x:.3}")
}

/// A time in milliseconds, 3 decimals.
pub fn fmt_ms(x: f64) -> String {
    format!("{x:.3}")
}

/// A rate or plain number, 2 decimals.
pub fn fmt_2(x: f64) -> String {
    format!("{x:.2}")
}

/// A share as a percentage with 2 decimals (`0.9905` -> `99.05%`).
pub fn fmt_pct(x: f64) -> String {
    format!("{:.2}%", x * 100.0)
}

/// An error or correlation value, 6 significant decimals.
pub fn fmt_err(x: f64) -> String {
    format!("{x:.6}")
}

fn opt(x: Option<f64>) -> String {
    x.map(fmt_err).unwrap_or_else(|| "-".into())
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
    let _ = write!(o, "| technique |");
    for c in &rows {
        let _ = write!(o, " {} |", c.label);
    }
    let _ = write!(o, "\n|---|");
    for _ in &rows {
        let _ = write!(o, "---|");
    }
    let _ = writeln!(o);
    for a in &rows {
        let _ = write!(o, "| {} |", a.label);
        for b in &rows {
            let cell = if a.label == b.label {
                "".to_string()
            } else {
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
            };
            let _ = write!(o, " {cell} |");
        }
        let _ = writeln!(o);
    }
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
         its seconds per sample give the time. Speedup: path-tracer seconds over the \
         technique's frame time (precomputation not counted; above 1 the technique is \
         faster at equal error). Extrapolated: views whose error lies outside the ladder.\n",
        ladder.join(", ")
    );
    let _ = writeln!(
        o,
        "| technique | bounces | views | mean error | path tracer spp (median) | path tracer (s) | frame (ms) | speedup | extrapolated |\n|---|---|---|---|---|---|---|---|---|"
    );
    for e in &r.summary.equal_error {
        let _ = writeln!(
            o,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            e.technique,
            e.bounces,
            e.views,
            fmt_err(e.mean_error),
            fmt_2(e.median_spp),
            fmt_s(e.mean_path_tracer_s),
            fmt_ms(e.mean_frame_s * 1e3),
            fmt_2(e.speedup),
            e.extrapolated
        );
    }
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
         per view; error metric `{}`, baseline `{}`.\n",
        r.views.len(),
        s.width,
        s.height,
        s.spp,
        s.bounces.join(", "),
        s.warmup,
        s.repeats,
        s.error_metric,
        s.baseline
    );
    let _ = writeln!(o, "## Techniques\n");
    let _ = writeln!(o, "| label | family | parameters |\n|---|---|---|");
    for t in &r.techniques {
        let _ = writeln!(o, "| {} | {} | {} |", t.label, t.family, t.description);
    }
    let _ = writeln!(
        o,
        "\n## Time (the thesis' Table 2)\n\nTotal = sum of the per-view median frame times.\n"
    );
    let _ = writeln!(
        o,
        "| technique | views | total time (s) | average frame time (ms) | average FPS | precomputation (s) |\n|---|---|---|---|---|---|"
    );
    for t in &r.summary.times {
        let _ = writeln!(
            o,
            "| {} | {} | {} | {} | {} | {} |",
            t.label,
            t.views,
            fmt_s(t.total_s),
            fmt_ms(t.avg_frame_ms),
            fmt_2(t.avg_fps),
            fmt_s(t.prepare_s)
        );
    }
    break_even_table(&mut o, r);
    equal_error_table(&mut o, r);
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

const W: f64 = 520.0;
const H: f64 = 300.0;
const PAD: f64 = 50.0;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Axis range with a margin; never empty.
fn range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in v.filter(|x| x.is_finite()) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let m = ((hi - lo) * 0.08).max(hi.abs().max(1e-9) * 0.02);
    (lo - m, hi + m)
}

fn svg_open(o: &mut String, title: &str, xlabel: &str, ylabel: &str) {
    let _ = write!(
        o,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" \
         font-family=\"sans-serif\" font-size=\"11\">\
         <rect width=\"{W}\" height=\"{H}\" fill=\"white\"/>\
         <text x=\"{}\" y=\"16\" text-anchor=\"middle\" font-size=\"13\">{}</text>\
         <line x1=\"{PAD}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/>\
         <line x1=\"{PAD}\" y1=\"{PAD}\" x2=\"{PAD}\" y2=\"{}\" stroke=\"black\"/>\
         <text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\
         <text x=\"12\" y=\"{}\" transform=\"rotate(-90 12 {})\" text-anchor=\"middle\">{}</text>",
        W / 2.0,
        esc(title),
        H - PAD,
        W - 10.0,
        H - PAD,
        H - PAD,
        W / 2.0,
        H - 12.0,
        esc(xlabel),
        H / 2.0,
        H / 2.0,
        esc(ylabel)
    );
}

fn ticks_y(o: &mut String, lo: f64, hi: f64) {
    for i in 0..=4 {
        let v = lo + (hi - lo) * i as f64 / 4.0;
        let y = (H - PAD) - (H - 2.0 * PAD) * i as f64 / 4.0;
        let _ = write!(
            o,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"end\">{:.4}</text>\
             <line x1=\"{PAD}\" y1=\"{y}\" x2=\"{}\" y2=\"{y}\" stroke=\"#ddd\"/>",
            PAD - 3.0,
            y + 4.0,
            v,
            W - 10.0
        );
    }
}

/// The speed-against-error plot of one scene: x = log10 of the frame time, y = mean error,
/// the Pareto front as a line.
pub fn speed_error_svg(se: &SceneSpeedError) -> String {
    let mut o = String::new();
    let (xl, xh) = range(se.points.iter().map(|p| p.frame_ms.max(1e-6).log10()));
    let (yl, yh) = range(se.points.iter().map(|p| p.error));
    let sx = |x: f64| PAD + (x - xl) / (xh - xl) * (W - PAD - 20.0);
    let sy = |y: f64| (H - PAD) - (y - yl) / (yh - yl) * (H - 2.0 * PAD);
    svg_open(
        &mut o,
        &format!("{}: speed against error", se.scene),
        "log10 frame time (ms)",
        &format!("mean error (bounces {})", se.bounces),
    );
    ticks_y(&mut o, yl, yh);
    for i in 0..=4 {
        let v = xl + (xh - xl) * i as f64 / 4.0;
        let _ = write!(
            o,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{:.2}</text>",
            sx(v),
            H - PAD + 14.0,
            v
        );
    }
    let mut front: Vec<_> = se.points.iter().filter(|p| p.pareto).collect();
    front.sort_by(|a, b| a.frame_ms.total_cmp(&b.frame_ms));
    let pts: Vec<String> = front
        .iter()
        .map(|p| format!("{:.1},{:.1}", sx(p.frame_ms.max(1e-6).log10()), sy(p.error)))
        .collect();
    let _ = write!(
        o,
        "<polyline points=\"{}\" fill=\"none\" stroke=\"#c33\" stroke-dasharray=\"4 3\"/>",
        pts.join(" ")
    );
    for p in &se.points {
        let (x, y) = (sx(p.frame_ms.max(1e-6).log10()), sy(p.error));
        let colour = if p.pareto { "#c33" } else { "#36c" };
        let _ = write!(
            o,
            "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"4\" fill=\"{colour}\"><title>{}: {} ms, {}</title></circle>\
             <text x=\"{:.1}\" y=\"{:.1}\">{}</text>",
            esc(&p.label),
            fmt_ms(p.frame_ms),
            fmt_err(p.error),
            x + 6.0,
            y - 4.0,
            esc(&p.label)
        );
    }
    o.push_str("</svg>");
    o
}

/// Per-view series plot: one polyline per series over the view index.
fn series_svg(title: &str, ylabel: &str, series: &[(&str, &str, Vec<f64>)], zero: bool) -> String {
    let mut o = String::new();
    let n = series.iter().map(|s| s.2.len()).max().unwrap_or(0);
    let (mut yl, yh) = range(series.iter().flat_map(|s| s.2.iter().copied()));
    if zero {
        yl = yl.min(0.0);
    }
    let sx = |i: usize| PAD + (i as f64 + 0.5) / n.max(1) as f64 * (W - PAD - 20.0);
    let sy = |y: f64| (H - PAD) - (y - yl) / (yh - yl) * (H - 2.0 * PAD);
    svg_open(&mut o, title, "view", ylabel);
    ticks_y(&mut o, yl, yh);
    if zero {
        let _ = write!(
            o,
            "<line x1=\"{PAD}\" y1=\"{0:.1}\" x2=\"{1}\" y2=\"{0:.1}\" stroke=\"black\" stroke-dasharray=\"2 2\"/>",
            sy(0.0),
            W - 10.0
        );
    }
    for (k, (name, colour, v)) in series.iter().enumerate() {
        let pts: Vec<String> = v
            .iter()
            .enumerate()
            .map(|(i, y)| format!("{:.1},{:.1}", sx(i), sy(*y)))
            .collect();
        let _ = write!(
            o,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\"/>",
            pts.join(" ")
        );
        for (i, y) in v.iter().enumerate() {
            let _ = write!(
                o,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2.5\" fill=\"{colour}\"><title>view {i}: {}</title></circle>",
                sx(i),
                sy(*y),
                fmt_err(*y)
            );
        }
        let _ = write!(
            o,
            "<text x=\"{}\" y=\"{}\" fill=\"{colour}\">{}</text>",
            W - 120.0,
            PAD + 14.0 * k as f64,
            esc(name)
        );
    }
    o.push_str("</svg>");
    o
}

/// The subset of Markdown the report uses (headings, pipe tables, paragraphs, `code`) as HTML.
fn markdown_to_html(md: &str) -> String {
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

fn embed_png(out: &Path, rel: &Path) -> String {
    match std::fs::read(out.join(rel)) {
        Ok(bytes) => format!(
            "<img src=\"data:image/png;base64,{}\" alt=\"{}\">",
            base64::engine::general_purpose::STANDARD.encode(bytes),
            esc(&rel.display().to_string())
        ),
        Err(_) => format!("<span>missing {}</span>", esc(&rel.display().to_string())),
    }
}

/// The report in HTML: the Markdown report's tables, the speed-against-error plot of each
/// scene, the per-view errors and gains (thesis figures 5.8 and 5.9) and a gallery of the
/// first view of every scene (reference, baseline, headline, difference images), with the
/// PNGs under `out` embedded.
pub fn html(r: &Results, headline: Option<&str>, out: &Path) -> String {
    let s = &r.settings;
    let mut o = String::from(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>Experiment report</title>\
         <style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse}\
         td,th{border:1px solid #ccc;padding:2px 6px}figure{display:inline-block;margin:4px}\
         img{image-rendering:pixelated;width:240px}</style></head><body>",
    );
    // The Markdown report's text and tables, as HTML.
    o.push_str(&markdown_to_html(&markdown(r, headline)));
    o.push_str("<h2>Speed against error (plots)</h2>");
    for se in &r.summary.speed_error {
        o.push_str(&speed_error_svg(se));
    }
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
        let _ = write!(o, "<h2>Per view ({h} against {})</h2>", s.baseline);
        o.push_str(&series_svg(
            "mean error per view (figure 5.8)",
            "mean error",
            &[
                (&s.baseline, "#36c", pairs.iter().map(|p| p.0).collect()),
                (h, "#c33", pairs.iter().map(|p| p.1).collect()),
            ],
            false,
        ));
        o.push_str(&series_svg(
            "quality gain per view (figure 5.9)",
            "gain",
            &[(
                "gain",
                "#393",
                pairs.iter().map(|p| gain(p.0, p.1)).collect(),
            )],
            true,
        ));
        o.push_str("<h2>Gallery</h2>");
        let mut seen: Vec<&str> = Vec::new();
        for v in &r.views {
            if seen.contains(&v.scene.as_str()) {
                continue;
            }
            seen.push(&v.scene);
            let dir = view_dir(&v.scene, v.camera_index, &v.camera_name());
            let _ = write!(o, "<h3>{} / {}</h3>", esc(&v.scene), esc(&v.camera_name()));
            let items = [
                (
                    format!("reference (bounces {b})"),
                    format!("reference-b{b}.png"),
                ),
                (s.baseline.clone(), format!("{}.png", slug(&s.baseline))),
                (h.to_string(), format!("{}.png", slug(h))),
                (
                    format!("|reference - {}| x8", s.baseline),
                    format!("diff-{}-b{b}.png", slug(&s.baseline)),
                ),
                (
                    format!("|reference - {h}| x8"),
                    format!("diff-{}-b{b}.png", slug(h)),
                ),
            ];
            for (caption, file) in items {
                let _ = write!(
                    o,
                    "<figure>{}<figcaption>{}</figcaption></figure>",
                    embed_png(out, &dir.join(file)),
                    esc(&caption)
                );
            }
        }
    }
    o.push_str("</body></html>\n");
    o
}
