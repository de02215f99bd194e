//! SVG plots (plotters): outputs against time, and sweep metrics against a parameter.

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::report::output;

/// One named line of a plot.
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Points in x order.
    pub points: Vec<(f64, f64)>,
}

/// A point to mark and label on a plot.
pub struct Mark {
    /// Where.
    pub at: (f64, f64),
    /// Text next to it.
    pub text: String,
}

/// A range that contains every finite value of `values`, padded by 5 % (or ±1 when flat).
fn padded_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !lo.is_finite() {
        return 0.0..1.0;
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { lo.abs().max(1.0) * 0.05 };
    (lo - pad)..(hi + pad)
}

/// Draws `series` as lines into an SVG at `path`, with axis labels, a legend and the marks.
/// The file is written whole, once drawn (see `output`).
pub fn lines(path: &Path, title: &str, x_label: &str, y_label: &str, series: &[Series], marks: &[Mark]) -> Result<(), String> {
    crate::report::fonts::register();
    let mut svg = String::new();
    draw(&mut svg, title, x_label, y_label, series, marks).map_err(|e| format!("cannot draw {}: {e}", path.display()))?;
    output::write_file(path, svg.as_bytes())
}

fn draw(svg: &mut String, title: &str, x_label: &str, y_label: &str, series: &[Series], marks: &[Mark]) -> Result<(), String> {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    // x spans the data exactly (time from start to stop); only a single point gets padding.
    let x_range = padded_range(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let x_range = x_range.start + (x_range.end - x_range.start) / 22.0..x_range.end - (x_range.end - x_range.start) / 22.0;
    let y_range = padded_range(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)).chain(marks.iter().map(|m| m.at.1)));
    let root = SVGBackend::with_string(svg, (960, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d(x_range, y_range)
        .map_err(|e| err(&e))?;
    chart.configure_mesh().x_desc(x_label).y_desc(y_label).label_style(("sans-serif", 14)).draw().map_err(|e| err(&e))?;
    for (i, s) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let style = ShapeStyle::from(&color).stroke_width(2);
        chart
            .draw_series(LineSeries::new(s.points.iter().copied().filter(|p| p.1.is_finite()), style))
            .map_err(|e| err(&e))?
            .label(s.label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        if s.points.len() <= 50 {
            chart
                .draw_series(s.points.iter().filter(|p| p.1.is_finite()).map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(|e| err(&e))?;
        }
    }
    for m in marks {
        chart.draw_series(std::iter::once(Circle::new(m.at, 6, RED.stroke_width(2)))).map_err(|e| err(&e))?;
        chart
            .draw_series(std::iter::once(Text::new(
                m.text.clone(),
                m.at,
                ("sans-serif", 15).into_font().color(&RED).pos(Pos::new(HPos::Left, VPos::Bottom)),
            )))
            .map_err(|e| err(&e))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}
