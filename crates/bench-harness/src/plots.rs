//! The report's plots as SVG, drawn with plotters: speed against error with the Pareto front,
//! series along views or along a relighting sequence, and the error maps' colour scale.

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::report::fmt_err;
use crate::results::SceneSpeedError;

const SIZE: (u32, u32) = (620, 380);
const FONT: &str = "sans-serif";

type PlotResult = Result<String, String>;

fn err(e: impl std::fmt::Display) -> String {
    format!("plot: {e}")
}

/// The colour of series `i` (plotters' 99-colour palette, so every technique of a run keeps
/// one colour across plots).
pub fn colour(i: usize) -> RGBColor {
    let c = Palette99::pick(i).to_rgba();
    RGBColor(c.0, c.1, c.2)
}

/// `#rrggbb` of [`colour`].
pub fn colour_hex(i: usize) -> String {
    let c = colour(i);
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// Axis range of positive values on a log axis: a decade-friendly margin; never empty.
fn log_range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for x in v.filter(|x| x.is_finite() && *x > 0.0) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if !lo.is_finite() {
        return (1e-3, 1.0);
    }
    (lo / 1.6, hi * 1.6)
}

/// Linear axis range with a margin; never empty.
fn lin_range(v: impl Iterator<Item = f64>, zero: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in v.filter(|x| x.is_finite()) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if zero {
        lo = lo.min(0.0);
    }
    let m = ((hi - lo) * 0.08).max(hi.abs().max(1e-9) * 0.02);
    (lo - m, hi + m)
}

/// Speed against error of one scene: x = frame time (ms, log), y = error; every technique a
/// labelled point in its colour (`colour_of(label)`), the Pareto front as a dashed line.
pub fn speed_error(se: &SceneSpeedError, colour_of: &dyn Fn(&str) -> usize) -> PlotResult {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let (xl, xh) = log_range(se.points.iter().map(|p| p.frame_ms));
        let (yl, yh) = lin_range(se.points.iter().map(|p| p.error), true);
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{}: speed against error (bounces {})", se.scene, se.bounces),
                (FONT, 16),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((xl..xh).log_scale(), yl..yh)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("frame time (ms, log scale)")
            .y_desc("mean error")
            .y_label_formatter(&|v| format!("{v:.3}"))
            .draw()
            .map_err(err)?;
        let mut front: Vec<(f64, f64)> = se
            .points
            .iter()
            .filter(|p| p.pareto)
            .map(|p| (p.frame_ms, p.error))
            .collect();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(
                front,
                ShapeStyle::from(&RED.mix(0.7)).stroke_width(2),
            ))
            .map_err(err)?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], RED));
        for p in &se.points {
            let c = colour(colour_of(&p.label));
            let size = if p.pareto { 6 } else { 4 };
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((p.frame_ms, p.error))
                        + Circle::new((0, 0), size, c.filled())
                        + Text::new(p.label.clone(), (7, -12), (FONT, 12)),
                ))
                .map_err(err)?;
        }
        legend(&mut chart)?;
        root.present().map_err(err)?;
    }
    Ok(svg)
}

/// One line per series over the points `0..n` of the x axis, labelled `x_labels` (views,
/// or the frames of a sequence). `log_y` draws the y axis in log scale (times). Series are
/// `(label, colour index, values)`.
pub fn series(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    x_labels: &[String],
    lines: &[(String, usize, Vec<f64>)],
    log_y: bool,
) -> PlotResult {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let n = lines.iter().map(|l| l.2.len()).max().unwrap_or(1).max(1);
        let values = || lines.iter().flat_map(|l| l.2.iter().copied());
        let mut chart = ChartBuilder::on(&root);
        chart
            .caption(title, (FONT, 16))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70);
        let x_fmt = |v: &f64| -> String {
            let i = v.round();
            if (v - i).abs() < 1e-6 && i >= 0.0 {
                x_labels
                    .get(i as usize)
                    .cloned()
                    .unwrap_or_else(|| format!("{i}"))
            } else {
                String::new()
            }
        };
        let x_range = -0.5..(n as f64 - 0.5);
        if log_y {
            let (yl, yh) = log_range(values());
            let mut c = chart
                .build_cartesian_2d(x_range, (yl..yh).log_scale())
                .map_err(err)?;
            c.configure_mesh()
                .x_desc(x_desc)
                .y_desc(y_desc)
                .x_labels(n.min(16))
                .x_label_formatter(&x_fmt)
                .y_label_formatter(&|v| format!("{v:.3}"))
                .draw()
                .map_err(err)?;
            draw_lines(&mut c, lines)?;
        } else {
            let (yl, yh) = lin_range(values(), true);
            let mut c = chart.build_cartesian_2d(x_range, yl..yh).map_err(err)?;
            c.configure_mesh()
                .x_desc(x_desc)
                .y_desc(y_desc)
                .x_labels(n.min(16))
                .x_label_formatter(&x_fmt)
                .y_label_formatter(&|v| fmt_err(*v).trim_end_matches('0').to_string())
                .draw()
                .map_err(err)?;
            draw_lines(&mut c, lines)?;
        }
        root.present().map_err(err)?;
    }
    Ok(svg)
}

fn draw_lines<'a, Y: Ranged<ValueType = f64>>(
    chart: &mut ChartContext<'a, SVGBackend<'a>, Cartesian2d<RangedCoordf64, Y>>,
    lines: &[(String, usize, Vec<f64>)],
) -> Result<(), String> {
    for (label, c, v) in lines {
        let c = colour(*c);
        chart
            .draw_series(LineSeries::new(
                v.iter().enumerate().map(|(i, y)| (i as f64, *y)),
                c.stroke_width(2),
            ))
            .map_err(err)?
            .label(label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2)));
        chart
            .draw_series(
                v.iter()
                    .enumerate()
                    .map(|(i, y)| Circle::new((i as f64, *y), 3, c.filled())),
            )
            .map_err(err)?;
    }
    legend(chart)
}

/// The legend of every labelled series, top right.
fn legend<'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, SVGBackend<'a>, CT>,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)
}

/// The colour of an error-map value in [0, 1] (viridis, perceptually uniform), as sRGB bytes.
pub fn viridis(t: f64) -> [u8; 3] {
    let c: RGBColor = ViridisRGB::get_color(t.clamp(0.0, 1.0) as f32);
    [c.0, c.1, c.2]
}

/// The error maps' colour scale: a bar from 0 to `max_label`.
pub fn colour_bar(max_label: &str) -> PlotResult {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (360, 56)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let n = 64;
        for i in 0..n {
            let [r, g, b] = viridis(i as f64 / (n - 1) as f64);
            let x0 = 20 + i * 5;
            root.draw(&Rectangle::new(
                [(x0, 6), (x0 + 5, 30)],
                RGBColor(r, g, b).filled(),
            ))
            .map_err(err)?;
        }
        root.draw(&Text::new("0", (16, 36), (FONT, 12)))
            .map_err(err)?;
        root.draw(&Text::new(max_label.to_string(), (250, 36), (FONT, 12)))
            .map_err(err)?;
        root.present().map_err(err)?;
    }
    Ok(svg)
}
