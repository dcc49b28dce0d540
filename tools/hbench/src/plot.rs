//! Stacked time-trace panels written as SVG with plotters: one panel per quantity, one
//! line per run, shared time axis. Display units are chosen by the caller.

use std::path::Path;

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

/// Write the panels stacked into an SVG file titled `title`.
pub fn time_traces(path: &Path, title: &str, panels: &[Panel]) -> Result<(), String> {
    let height = PANEL_HEIGHT * panels.len() as u32 + 40;
    let root = SVGBackend::new(path, (WIDTH, height)).into_drawing_area();
    let fail = |e: &dyn std::fmt::Display| format!("plot {}: {e}", path.display());
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let root = root
        .titled(title, ("sans-serif", 18))
        .map_err(|e| fail(&e))?;
    let (t0, t1) = bounds(panels);
    for (area, panel) in root.split_evenly((panels.len(), 1)).iter().zip(panels) {
        let (lo, hi) = range(&panel.lines);
        let mut chart = ChartBuilder::on(area)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, lo..hi)
            .map_err(|e| fail(&e))?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc(panel.title.as_str())
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(|e| fail(&e))?;
        for (k, line) in panel.lines.iter().enumerate() {
            let color = Palette99::pick(k).to_rgba();
            chart
                .draw_series(LineSeries::new(line.points.iter().copied(), &color))
                .map_err(|e| fail(&e))?
                .label(line.label.as_str())
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], color));
        }
        if panel.lines.len() > 1 {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| fail(&e))?;
        }
    }
    root.present().map_err(|e| fail(&e))
}
