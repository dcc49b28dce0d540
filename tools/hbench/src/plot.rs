//! Stacked time-trace panels written as SVG with plotters: one panel per quantity, one
//! line per run, shared time axis. Display units are chosen by the caller.

use std::path::Path;

use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// One line of a panel.
pub struct Line {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

/// One panel: a y-axis title and its lines.
pub struct Panel {
    pub title: String,
    pub lines: Vec<Line>,
}

const WIDTH: u32 = 1000;
const PANEL_HEIGHT: u32 = 260;
const LOG_PANEL_HEIGHT: u32 = 340;

fn failure(path: &Path, e: &dyn std::fmt::Display) -> String {
    format!("plot {}: {e}", path.display())
}

/// A white SVG page of the common width with `title` on top; what is left to draw on.
fn canvas<'a>(
    path: &'a Path,
    title: &str,
    height: u32,
) -> Result<DrawingArea<SVGBackend<'a>, plotters::coord::Shift>, String> {
    let root = SVGBackend::new(path, (WIDTH, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| failure(path, &e))?;
    root.titled(title, ("sans-serif", 18))
        .map_err(|e| failure(path, &e))
}

fn bounds(panels: &[Panel]) -> (f64, f64) {
    let ts = panels
        .iter()
        .flat_map(|p| p.lines.iter().flat_map(|l| l.points.iter().map(|q| q.0)));
    ts.fold((f64::MAX, f64::MIN), |(a, b), t| (a.min(t), b.max(t)))
}

fn range(lines: &[Line]) -> (f64, f64) {
    let (lo, hi) = lines
        .iter()
        .flat_map(|l| l.points.iter().map(|q| q.1))
        .filter(|v| v.is_finite())
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        return (-1.0, 1.0);
    }
    let pad = 0.05 * (hi - lo).max(1e-12 * hi.abs().max(1.0));
    (lo - pad, hi + pad)
}

/// Write the panels stacked into an SVG file titled `title`, against time.
pub fn time_traces(path: &Path, title: &str, panels: &[Panel]) -> Result<(), String> {
    stacked(path, title, "time (s)", panels)
}

/// Write the panels stacked into an SVG file, against a shared x quantity.
pub fn stacked(path: &Path, title: &str, x_desc: &str, panels: &[Panel]) -> Result<(), String> {
    let fail = |e: &dyn std::fmt::Display| failure(path, e);
    let root = canvas(path, title, PANEL_HEIGHT * panels.len() as u32 + 40)?;
    let (t0, t1) = bounds(panels);
    for (area, panel) in root.split_evenly((panels.len(), 1)).iter().zip(panels) {
        let (lo, hi) = range(&panel.lines);
        let chart = ChartBuilder::on(area)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, lo..hi)
            .map_err(|e| fail(&e))?;
        let style = Style {
            x_desc,
            grid: WHITE.mix(0.0),
            legend: SeriesLabelPosition::MiddleRight,
        };
        draw_panel(chart, panel, style, |_| true).map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))
}

/// How a panel of `stacked` or `stacked_log_x` is dressed.
struct Style<'a> {
    x_desc: &'a str,
    grid: RGBAColor,
    legend: SeriesLabelPosition,
}

/// Draw a panel's mesh, its lines (the points `keep` accepts) and, for several lines,
/// their legend, on a chart whose x axis is linear or logarithmic.
fn draw_panel<'a, DB, X>(
    mut chart: ChartContext<'a, DB, Cartesian2d<X, RangedCoordf64>>,
    panel: &Panel,
    style: Style,
    keep: impl Fn(f64) -> bool,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .x_desc(style.x_desc)
        .y_desc(panel.title.as_str())
        .light_line_style(style.grid)
        .draw()?;
    for (k, line) in panel.lines.iter().enumerate() {
        let color = Palette99::pick(k).to_rgba();
        let points = line.points.iter().copied().filter(|q| keep(q.0));
        chart
            .draw_series(LineSeries::new(points, &color))?
            .label(line.label.as_str())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], color));
    }
    if panel.lines.len() > 1 {
        chart
            .configure_series_labels()
            .position(style.legend)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}

/// Write the panels stacked into an SVG file against a shared, logarithmic x quantity (a
/// frequency response read as a Bode diagram: the decades of a log sweep evenly spread).
/// Only positive x values are drawn.
pub fn stacked_log_x(
    path: &Path,
    title: &str,
    x_desc: &str,
    panels: &[Panel],
) -> Result<(), String> {
    let fail = |e: &dyn std::fmt::Display| failure(path, e);
    let root = canvas(path, title, LOG_PANEL_HEIGHT * panels.len() as u32 + 40)?;
    // from the decade below the data (labelled) to the data's top: a sweep to 300 Hz would
    // leave half a decade empty
    let (x0, x1) = panels
        .iter()
        .flat_map(|p| p.lines.iter().flat_map(|l| l.points.iter().map(|q| q.0)))
        .filter(|x| x.is_finite() && *x > 0.0)
        .fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
    let (x0, x1) = if x0 < x1 {
        (10f64.powf(x0.log10().floor()), x1)
    } else {
        (0.1, 10.0)
    };
    for (area, panel) in root.split_evenly((panels.len(), 1)).iter().zip(panels) {
        let (lo, hi) = range(&panel.lines);
        let chart = ChartBuilder::on(area)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), lo..hi)
            .map_err(|e| fail(&e))?;
        let style = Style {
            x_desc,
            grid: BLACK.mix(0.08),
            legend: SeriesLabelPosition::LowerLeft,
        };
        draw_panel(chart, panel, style, |x| x > 0.0).map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))
}

/// One line of a log-log panel: its colour (palette index) and whether it is dashed.
pub struct LogLine {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub color: usize,
    pub dashed: bool,
}

/// One log-log panel: a title above it, a y-axis title and its lines.
pub struct LogPanel {
    pub title: String,
    pub y_desc: String,
    pub lines: Vec<LogLine>,
}

/// Smallest and largest positive values, widened to whole decades (a log axis shows no
/// zero or negative value).
fn decades(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        return (0.1, 10.0);
    }
    let (lo, hi) = (
        10f64.powf(lo.log10().floor()),
        10f64.powf(hi.log10().ceil()),
    );
    (lo, if hi > lo { hi } else { 10.0 * lo })
}

/// Write log-log panels in a grid of `columns` into an SVG file titled `title`; every line
/// is drawn with a marker at each point, so that a line of one point still shows.
pub fn log_log(
    path: &Path,
    title: &str,
    x_desc: &str,
    panels: &[LogPanel],
    columns: usize,
) -> Result<(), String> {
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns);
    let fail = |e: &dyn std::fmt::Display| failure(path, e);
    let root = canvas(path, title, LOG_PANEL_HEIGHT * rows as u32 + 40)?;
    // the x values are few and chosen (the steps of a study): a margin, not decades
    let (x0, x1) = panels
        .iter()
        .flat_map(|p| p.lines.iter().flat_map(|l| l.points.iter().map(|q| q.0)))
        .filter(|x| *x > 0.0)
        .fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
    let (x0, x1) = if x0 <= x1 {
        (x0 / 1.5, x1 * 1.5)
    } else {
        (0.1, 10.0)
    };
    for (area, panel) in root.split_evenly((rows, columns)).iter().zip(panels) {
        let (y0, y1) = decades(
            panel
                .lines
                .iter()
                .flat_map(|l| l.points.iter().map(|q| q.1)),
        );
        let mut chart = ChartBuilder::on(area)
            .caption(panel.title.as_str(), ("sans-serif", 14))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(|e| fail(&e))?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(panel.y_desc.as_str())
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(|e| fail(&e))?;
        for line in &panel.lines {
            let color = Palette99::pick(line.color).to_rgba();
            let points: Vec<(f64, f64)> =
                line.points.iter().copied().filter(|q| q.1 > 0.0).collect();
            let style = ShapeStyle::from(&color).stroke_width(2);
            let series = if line.dashed {
                chart.draw_series(DashedLineSeries::new(points.clone(), 8, 5, style))
            } else {
                chart.draw_series(LineSeries::new(points.clone(), style))
            };
            series
                .map_err(|e| fail(&e))?
                .label(line.label.as_str())
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], color));
            chart
                .draw_series(points.iter().map(|&q| Circle::new(q, 3, color.filled())))
                .map_err(|e| fail(&e))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 11))
            .draw()
            .map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))
}
