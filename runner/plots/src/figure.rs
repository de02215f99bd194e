//! Figures a person reads: one or more panels (subplots) in a grid, each with curves, legend,
//! event lines, marked points and, for mechanisms, links and joints drawn to scale. Drawn as SVG
//! (a [`Drawing`], so also as PNG), and into RGB frames for animations.

use std::ops::Range;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::{fonts, raster, Drawing};

/// Colours of successive curves (Tableau 10): distinct, and readable on white.
pub const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// The colour of curve number `i`.
pub fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Marker shapes for curves drawn as symbols.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Marker {
    /// An open circle.
    Circle,
    /// An open square.
    Square,
    /// A filled triangle.
    Triangle,
    /// A diagonal cross.
    Cross,
}

/// How a curve is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Style {
    /// A solid line this many pixels wide.
    Line(u32),
    /// A dashed line.
    Dashed(u32),
    /// A symbol at every point, no line.
    Markers(Marker),
}

/// One curve of a panel.
#[derive(Debug, Clone)]
pub struct Curve {
    /// Legend text (`None`: not in the legend).
    pub label: Option<String>,
    /// Points in drawing order; a non-finite value breaks the line.
    pub points: Vec<(f64, f64)>,
    /// Its colour.
    pub color: RGBColor,
    /// Line, dashes or symbols.
    pub style: Style,
}

impl Curve {
    /// A solid 2 px line.
    pub fn line(label: impl Into<String>, points: Vec<(f64, f64)>, color: RGBColor) -> Curve {
        Curve { label: Some(label.into()), points, color, style: Style::Line(2) }
    }
}

/// A vertical line across a panel at `x` (an event), with an optional label near the top.
#[derive(Debug, Clone)]
pub struct VLine {
    /// Where it crosses the x axis.
    pub x: f64,
    /// Text near its top (`None`: none).
    pub label: Option<String>,
    /// Its colour and its label's.
    pub color: RGBColor,
}

/// A marked point with text next to it.
#[derive(Debug, Clone)]
pub struct Note {
    /// The point, circled.
    pub at: (f64, f64),
    /// Text above and to the right of it.
    pub text: String,
    /// The circle's and the text's colour.
    pub color: RGBColor,
}

/// Drawing elements of mechanisms and other scenes, in data coordinates.
#[derive(Debug, Clone)]
pub enum Shape {
    /// Connected segments (a link, a trail), `width` px wide.
    Polyline {
        /// The corners, in order; a non-finite one breaks the line.
        points: Vec<(f64, f64)>,
        /// Line colour.
        color: RGBColor,
        /// Line width (px).
        width: u32,
    },
    /// A filled circle with an outline (a joint, a mass), `radius` px.
    Dot {
        /// Its centre.
        at: (f64, f64),
        /// Radius (px).
        radius: u32,
        /// Inside colour.
        fill: RGBColor,
        /// Outline colour.
        outline: RGBColor,
    },
    /// A filled square (a fixed pivot), `size` px from its centre to each side.
    Pivot {
        /// Its centre.
        at: (f64, f64),
        /// Half its side (px).
        size: u32,
    },
    /// Text beside a point, offset in pixels.
    Label {
        /// The point.
        at: (f64, f64),
        /// The text (a point's name).
        text: String,
        /// From the point to the text's centre (px, y down).
        offset: (i32, i32),
    },
    /// A horizontal line across the panel (the ground, a slider's guide).
    Level {
        /// Its height.
        y: f64,
    },
}

/// One subplot.
#[derive(Debug, Clone, Default)]
pub struct Panel {
    /// Title above the panel.
    pub title: Option<String>,
    /// Label of the x axis (empty: none).
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// Curves, drawn in order.
    pub curves: Vec<Curve>,
    /// Vertical lines (events).
    pub vlines: Vec<VLine>,
    /// Marked points with text.
    pub notes: Vec<Note>,
    /// Mechanism shapes, in data coordinates.
    pub shapes: Vec<Shape>,
    /// Bars `(x, height, label)` from y = `bar_base`, `bar_width` wide in x units.
    pub bars: Vec<(f64, f64, String, RGBColor)>,
    /// Width of each bar (x units).
    pub bar_width: f64,
    /// Where the bars start (y units).
    pub bar_base: f64,
    /// Tick labels for these x positions instead of numbers (a bar chart's categories).
    pub x_categories: Vec<(f64, String)>,
    /// Fixed ranges; `None` fits the data with a margin.
    pub x_range: Option<Range<f64>>,
    /// As `x_range`, for y.
    pub y_range: Option<Range<f64>>,
    /// One metre (or unit) is as long across as up: mechanisms to scale.
    pub equal_scales: bool,
    /// The y values are log10 of the quantity: ticks are labelled 10^k.
    pub log_y: bool,
    /// The x values are log10 of the quantity (a frequency response): ticks labelled 10^k.
    pub log_x: bool,
    /// Text in the upper-left corner of the plot (a time stamp).
    pub corner_text: Option<String>,
    /// Where the legend goes (default upper right).
    pub legend_lower: bool,
}

/// A figure: panels in a grid, filled row by row.
#[derive(Debug, Clone)]
pub struct Figure {
    /// Title above the panels.
    pub title: Option<String>,
    /// The panels, row by row.
    pub panels: Vec<Panel>,
    /// Panels per row.
    pub columns: usize,
    /// Pixel size of one panel.
    pub panel_size: (u32, u32),
}

impl Figure {
    /// Panels stacked in one column.
    pub fn column(title: Option<String>, panels: Vec<Panel>, panel_size: (u32, u32)) -> Figure {
        Figure { title, panels, columns: 1, panel_size }
    }

    /// The whole figure's size in pixels.
    pub fn size(&self) -> (u32, u32) {
        let columns = self.columns.max(1);
        let rows = self.panels.len().div_ceil(columns).max(1);
        let title = if self.title.is_some() { TITLE_HEIGHT } else { 0 };
        (self.panel_size.0 * columns as u32, self.panel_size.1 * rows as u32 + title)
    }
}

/// Height taken by a figure's title.
const TITLE_HEIGHT: u32 = 40;
const MARGIN: u32 = 12;
const X_LABEL_AREA: u32 = 44;
const Y_LABEL_AREA: u32 = 78;
const PANEL_TITLE_HEIGHT: u32 = 26;

impl Drawing for Figure {
    fn size(&self) -> (u32, u32) {
        Figure::size(self)
    }

    fn svg(&self) -> Result<String, String> {
        fonts::register();
        let mut svg = String::new();
        draw_figure(SVGBackend::with_string(&mut svg, self.size()).into_drawing_area(), self)?;
        Ok(svg)
    }
}

/// The figure rendered into an RGB buffer of `figure.size()` (an animation's frame).
pub fn rasterize(figure: &Figure) -> Result<Vec<u8>, String> {
    raster::rgb(&figure.svg()?, figure.size())
}

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

fn draw_figure<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, figure: &Figure) -> Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    let body = match &figure.title {
        Some(title) => {
            let (top, rest) = root.split_vertically(TITLE_HEIGHT);
            let (w, _) = top.dim_in_pixel();
            top.draw(&Text::new(
                title.clone(),
                (w as i32 / 2, 10),
                ("sans-serif", 20).into_font().style(FontStyle::Bold).color(&BLACK).pos(Pos::new(HPos::Center, VPos::Top)),
            ))
            .map_err(err)?;
            rest
        }
        None => root.clone(),
    };
    let columns = figure.columns.max(1);
    let rows = figure.panels.len().div_ceil(columns).max(1);
    let areas = body.split_evenly((rows, columns));
    for (panel, area) in figure.panels.iter().zip(areas) {
        draw_panel(&area, panel)?;
    }
    root.present().map_err(err)
}

/// A range holding every finite value, padded by 5 % each side (±5 % of the value when flat).
pub fn padded_range(values: impl Iterator<Item = f64>) -> Range<f64> {
    let (lo, hi) = values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !lo.is_finite() {
        return 0.0..1.0;
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { lo.abs().max(1e-9) * 0.05 };
    (lo - pad)..(hi + pad)
}

/// The data x range of a panel: curves, bars and event lines, exactly (no padding).
fn data_x_range(panel: &Panel) -> Range<f64> {
    let xs = panel
        .curves
        .iter()
        .flat_map(|c| c.points.iter().map(|p| p.0))
        .chain(panel.vlines.iter().map(|v| v.x))
        .chain(panel.notes.iter().map(|n| n.at.0))
        .chain(shape_points(&panel.shapes).map(|p| p.0))
        .chain(panel.bars.iter().flat_map(|b| [b.0 - panel.bar_width, b.0 + panel.bar_width]));
    if panel.equal_scales || !panel.bars.is_empty() {
        return padded_range(xs);
    }
    // Curves against time span the data exactly.
    exact_range(xs)
}

/// The smallest range holding every finite value (0..1 for none).
pub fn exact_range(values: impl Iterator<Item = f64>) -> Range<f64> {
    let (lo, hi) = values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo.is_finite() {
        lo..hi
    } else {
        0.0..1.0
    }
}

fn shape_points(shapes: &[Shape]) -> impl Iterator<Item = (f64, f64)> + '_ {
    shapes.iter().flat_map(|s| match s {
        Shape::Polyline { points, .. } => points.clone(),
        Shape::Dot { at, .. } | Shape::Pivot { at, .. } | Shape::Label { at, .. } => vec![*at],
        Shape::Level { .. } => vec![],
    })
}

fn data_y_range(panel: &Panel) -> Range<f64> {
    let ys = panel
        .curves
        .iter()
        .flat_map(|c| c.points.iter().map(|p| p.1))
        .chain(panel.notes.iter().map(|n| n.at.1))
        .chain(shape_points(&panel.shapes).map(|p| p.1))
        .chain(panel.bars.iter().flat_map(|b| [b.1, panel.bar_base]));
    let mut r = padded_range(ys);
    if !panel.bars.is_empty() {
        // Room above the bars for their value labels.
        r.end += 0.08 * (r.end - r.start);
    }
    r
}

/// Widens `x` or `y` so that one unit spans as many pixels across as up in a `w` x `h` area.
pub fn equalize(x: Range<f64>, y: Range<f64>, (w, h): (u32, u32)) -> (Range<f64>, Range<f64>) {
    let (w, h) = (w.max(1) as f64, h.max(1) as f64);
    let scale = ((x.end - x.start) / w).max((y.end - y.start) / h);
    let (cx, cy) = ((x.start + x.end) / 2.0, (y.start + y.end) / 2.0);
    ((cx - scale * w / 2.0)..(cx + scale * w / 2.0), (cy - scale * h / 2.0)..(cy + scale * h / 2.0))
}

/// The pixel size of a panel's plotting area inside an area of `size`.
pub fn plot_area_size(panel: &Panel, (w, h): (u32, u32)) -> (u32, u32) {
    let title = if panel.title.is_some() { PANEL_TITLE_HEIGHT } else { 0 };
    (w.saturating_sub(2 * MARGIN + Y_LABEL_AREA), h.saturating_sub(2 * MARGIN + X_LABEL_AREA + title))
}

/// Clips a polyline to the box `x` by `y` (plotters would squash what lies outside onto the
/// border): the visible pieces, each a run of connected points.
fn clip(points: &[(f64, f64)], x: &Range<f64>, y: &Range<f64>) -> Vec<Vec<(f64, f64)>> {
    let inside = |p: (f64, f64)| x.start <= p.0 && p.0 <= x.end && y.start <= p.1 && p.1 <= y.end;
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut current: Vec<(f64, f64)> = Vec::new();
    let finite = |p: &(f64, f64)| p.0.is_finite() && p.1.is_finite();
    if points.len() == 1 && finite(&points[0]) && inside(points[0]) {
        return vec![points.to_vec()];
    }
    for w in points.windows(2) {
        let (a, b) = (w[0], w[1]);
        if !(finite(&a) && finite(&b)) {
            if !current.is_empty() {
                runs.push(std::mem::take(&mut current));
            }
            continue;
        }
        // Liang-Barsky: the part t0..t1 of a -> b inside the box.
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        let mut visible = true;
        for (p, q) in [(-dx, a.0 - x.start), (dx, x.end - a.0), (-dy, a.1 - y.start), (dy, y.end - a.1)] {
            if p == 0.0 {
                if q < 0.0 {
                    visible = false;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
            }
        }
        if !visible || t0 > t1 {
            if !current.is_empty() {
                runs.push(std::mem::take(&mut current));
            }
            continue;
        }
        let start = (a.0 + t0 * dx, a.1 + t0 * dy);
        let end = (a.0 + t1 * dx, a.1 + t1 * dy);
        if current.is_empty() {
            current.push(start);
        } else if current.last() != Some(&start) {
            runs.push(std::mem::take(&mut current));
            current.push(start);
        }
        current.push(end);
        if t1 < 1.0 {
            runs.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        runs.push(current);
    }
    runs
}

/// Splits a curve's points at non-finite values into drawable runs, thinning very long runs
/// whose x only grows to the first and last, lowest and highest point of each pixel-wide bucket.
fn segments(points: &[(f64, f64)], buckets: usize) -> Vec<Vec<(f64, f64)>> {
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut current = Vec::new();
    for &p in points {
        if p.0.is_finite() && p.1.is_finite() {
            current.push(p);
        } else if !current.is_empty() {
            runs.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        runs.push(current);
    }
    runs.into_iter().map(|run| thin(run, buckets)).collect()
}

fn thin(run: Vec<(f64, f64)>, buckets: usize) -> Vec<(f64, f64)> {
    let monotonic = run.windows(2).all(|w| w[1].0 >= w[0].0);
    if run.len() <= 4 * buckets || !monotonic || buckets == 0 {
        return run;
    }
    let per = run.len().div_ceil(buckets);
    let mut kept = Vec::with_capacity(4 * buckets);
    for chunk in run.chunks(per) {
        let lo = chunk.iter().enumerate().min_by(|a, b| a.1 .1.total_cmp(&b.1 .1)).map(|(i, _)| i).unwrap_or(0);
        let hi = chunk.iter().enumerate().max_by(|a, b| a.1 .1.total_cmp(&b.1 .1)).map(|(i, _)| i).unwrap_or(0);
        let mut picks = [0, lo, hi, chunk.len() - 1];
        picks.sort_unstable();
        let mut last = usize::MAX;
        for i in picks {
            if i != last {
                kept.push(chunk[i]);
                last = i;
            }
        }
    }
    kept
}

/// Formats tick values on an axis spanning `span`: as many decimals as the tick spacing (about
/// a sixth of the span) needs, and scientific notation for very large or small values.
fn tick(v: f64, span: f64) -> String {
    let step = (span / 6.0).abs();
    if v == 0.0 || !step.is_finite() || step == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-4..1e6).contains(&a) && a > step * 1e-6 {
        return format!("{v:.2e}");
    }
    if a < step * 1e-6 {
        return "0".into();
    }
    let decimals = (1 - step.log10().floor() as i32).clamp(0, 12) as usize;
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { &s };
    if s == "-0" {
        "0".into()
    } else {
        s.to_owned()
    }
}

/// Draws one panel into `area`.
pub fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, panel: &Panel) -> Result<(), String> {
    let area = match &panel.title {
        Some(t) => {
            let (top, rest) = area.split_vertically(PANEL_TITLE_HEIGHT);
            let (w, _) = top.dim_in_pixel();
            top.draw(&Text::new(
                t.clone(),
                (w as i32 / 2, 6),
                ("sans-serif", 15).into_font().color(&BLACK).pos(Pos::new(HPos::Center, VPos::Top)),
            ))
            .map_err(err)?;
            rest
        }
        None => area.clone(),
    };
    let mut x_range = panel.x_range.clone().unwrap_or_else(|| data_x_range(panel));
    let mut y_range = panel.y_range.clone().unwrap_or_else(|| data_y_range(panel));
    if x_range.end <= x_range.start {
        x_range = (x_range.start - 0.5)..(x_range.start + 0.5);
    }
    if y_range.end <= y_range.start {
        y_range = (y_range.start - 0.5)..(y_range.start + 0.5);
    }
    let (pw, ph) = {
        let (w, h) = area.dim_in_pixel();
        (w.saturating_sub(2 * MARGIN + Y_LABEL_AREA), h.saturating_sub(2 * MARGIN + X_LABEL_AREA))
    };
    if panel.equal_scales {
        (x_range, y_range) = equalize(x_range, y_range, (pw, ph));
    }
    let mut chart = ChartBuilder::on(&area)
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(x_range.clone(), y_range.clone())
        .map_err(err)?;
    let log_label = |y: &f64| {
        let k = y.round();
        if (y - k).abs() < 1e-6 {
            format!("1e{}", k as i64)
        } else {
            String::new()
        }
    };
    let categories = &panel.x_categories;
    let category_label = |_: &f64| String::new();
    let (x_span, y_span) = (x_range.end - x_range.start, y_range.end - y_range.start);
    let x_number = |v: &f64| tick(*v, x_span);
    let y_number = |v: &f64| tick(*v, y_span);
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(RGBColor(238, 238, 238))
        .bold_line_style(RGBColor(215, 215, 215))
        .max_light_lines(1)
        .x_labels(8)
        .y_labels(6);
    if panel.log_y {
        mesh.y_label_formatter(&log_label);
    } else {
        mesh.y_label_formatter(&y_number);
    }
    if panel.log_x {
        mesh.x_label_formatter(&log_label);
    } else if categories.is_empty() {
        mesh.x_label_formatter(&x_number);
    } else {
        mesh.x_label_formatter(&category_label).disable_x_mesh();
    }
    mesh.draw().map_err(err)?;
    if !categories.is_empty() {
        // Category names under each bar group (the mesh's own ticks fall between them).
        for (x, name) in categories {
            chart
                .draw_series(std::iter::once(Text::new(
                    name.clone(),
                    (*x, y_range.start),
                    ("sans-serif", 13).into_font().color(&BLACK).pos(Pos::new(HPos::Center, VPos::Top)),
                )))
                .map_err(err)?;
        }
    }

    for shape in &panel.shapes {
        match shape {
            Shape::Level { y } => {
                let style = ShapeStyle::from(&RGBColor(120, 120, 120)).stroke_width(1);
                chart.draw_series(DashedLineSeries::new([(x_range.start, *y), (x_range.end, *y)], 8, 5, style)).map_err(err)?;
            }
            Shape::Polyline { points, color, width } => {
                for run in clip(points, &x_range, &y_range) {
                    chart.draw_series(LineSeries::new(run, color.stroke_width(*width))).map_err(err)?;
                }
            }
            _ => {}
        }
    }
    let inside = |p: &(f64, f64)| x_range.start <= p.0 && p.0 <= x_range.end && y_range.start <= p.1 && p.1 <= y_range.end;
    for shape in &panel.shapes {
        match shape {
            Shape::Dot { at, radius, fill, outline } if inside(at) => {
                chart.draw_series(std::iter::once(Circle::new(*at, *radius, fill.filled()))).map_err(err)?;
                chart.draw_series(std::iter::once(Circle::new(*at, *radius, outline.stroke_width(2)))).map_err(err)?;
            }
            Shape::Pivot { at, size } if inside(at) => {
                let s = *size as i32;
                chart
                    .draw_series(std::iter::once(EmptyElement::at(*at) + Rectangle::new([(-s, -s), (s, s)], BLACK.filled())))
                    .map_err(err)?;
            }
            Shape::Label { at, text, offset } if inside(at) => {
                chart
                    .draw_series(std::iter::once(
                        EmptyElement::at(*at)
                            + Text::new(
                                text.clone(),
                                *offset,
                                ("sans-serif", 15)
                                    .into_font()
                                    .style(FontStyle::Bold)
                                    .color(&BLACK)
                                    .pos(Pos::new(HPos::Center, VPos::Center)),
                            ),
                    ))
                    .map_err(err)?;
            }
            _ => {}
        }
    }

    for (x, height, label, color) in &panel.bars {
        let half = panel.bar_width / 2.0;
        chart
            .draw_series(std::iter::once(Rectangle::new([(x - half, panel.bar_base), (x + half, *height)], color.filled())))
            .map_err(err)?;
        chart
            .draw_series(std::iter::once(Text::new(
                label.clone(),
                (*x, *height),
                ("sans-serif", 12).into_font().color(&BLACK).pos(Pos::new(HPos::Center, VPos::Bottom)),
            )))
            .map_err(err)?;
    }

    let buckets = pw as usize;
    let mut legend = false;
    for curve in &panel.curves {
        let color = curve.color;
        let text = curve.label.as_deref();
        legend |= text.is_some();
        match curve.style {
            Style::Line(width) | Style::Dashed(width) => {
                let style = color.stroke_width(width);
                let runs = segments(&curve.points, buckets).iter().flat_map(|r| clip(r, &x_range, &y_range)).collect::<Vec<_>>();
                for (k, run) in runs.into_iter().enumerate() {
                    let series = if matches!(curve.style, Style::Dashed(_)) {
                        chart.draw_series(DashedLineSeries::new(run, 10, 6, style)).map_err(err)?
                    } else {
                        chart.draw_series(LineSeries::new(run, style)).map_err(err)?
                    };
                    if let (Some(text), 0) = (text, k) {
                        series.label(text).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
                    }
                }
            }
            Style::Markers(marker) => {
                let points = curve.points.iter().copied().filter(|p| inside(p));
                let stroke = color.stroke_width(2);
                let series = match marker {
                    Marker::Circle => chart.draw_series(points.map(|p| Circle::new(p, 4, stroke))).map_err(err)?,
                    Marker::Square => {
                        chart.draw_series(points.map(|p| EmptyElement::at(p) + Rectangle::new([(-4, -4), (4, 4)], stroke))).map_err(err)?
                    }
                    Marker::Triangle => chart.draw_series(points.map(|p| TriangleMarker::new(p, 5, color.filled()))).map_err(err)?,
                    Marker::Cross => chart.draw_series(points.map(|p| Cross::new(p, 4, stroke))).map_err(err)?,
                };
                if let Some(text) = text {
                    let anno = series.label(text);
                    match marker {
                        Marker::Circle => anno.legend(move |(x, y)| Circle::new((x + 10, y), 4, stroke)),
                        Marker::Square => anno.legend(move |(x, y)| Rectangle::new([(x + 6, y - 4), (x + 14, y + 4)], stroke)),
                        Marker::Triangle => anno.legend(move |(x, y)| TriangleMarker::new((x + 10, y), 5, color.filled())),
                        Marker::Cross => anno.legend(move |(x, y)| Cross::new((x + 10, y), 4, stroke)),
                    };
                }
            }
        }
    }

    for (i, v) in panel.vlines.iter().enumerate() {
        let style = v.color.stroke_width(1);
        chart.draw_series(DashedLineSeries::new([(v.x, y_range.start), (v.x, y_range.end)], 6, 4, style)).map_err(err)?;
        if let Some(label) = &v.label {
            // Staggered rows so the labels of events close in time do not overprint.
            let row = (i % 3) as i32;
            // Labels of lines in the right quarter go to their left, so they are not cut off.
            let right = v.x > x_range.start + 0.75 * (x_range.end - x_range.start);
            let (dx, anchor) = if right { (-4, HPos::Right) } else { (4, HPos::Left) };
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((v.x, y_range.end))
                        + Text::new(
                            label.clone(),
                            (dx, 4 + 15 * row),
                            ("sans-serif", 12).into_font().color(&v.color).pos(Pos::new(anchor, VPos::Top)),
                        ),
                ))
                .map_err(err)?;
        }
    }
    for n in panel.notes.iter().filter(|n| inside(&n.at)) {
        chart.draw_series(std::iter::once(Circle::new(n.at, 6, n.color.stroke_width(2)))).map_err(err)?;
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(n.at)
                    + Text::new(
                        n.text.clone(),
                        (9, -6),
                        ("sans-serif", 14).into_font().color(&n.color).pos(Pos::new(HPos::Left, VPos::Bottom)),
                    ),
            ))
            .map_err(err)?;
    }
    if let Some(text) = &panel.corner_text {
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((x_range.start, y_range.end))
                    + Text::new(text.clone(), (8, 6), ("sans-serif", 16).into_font().color(&BLACK).pos(Pos::new(HPos::Left, VPos::Top))),
            ))
            .map_err(err)?;
    }
    if legend {
        chart
            .configure_series_labels()
            .label_font(("sans-serif", 13))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .position(if panel.legend_lower { SeriesLabelPosition::LowerRight } else { SeriesLabelPosition::UpperRight })
            .draw()
            .map_err(err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_scales_give_one_unit_the_same_pixels_both_ways() {
        let (x, y) = equalize(0.0..2.0, 0.0..0.5, (400, 300));
        let (sx, sy) = ((x.end - x.start) / 400.0, (y.end - y.start) / 300.0);
        assert!((sx - sy).abs() < 1e-12, "{sx} vs {sy}");
        assert!(x.start <= 0.0 && x.end >= 2.0 && y.start <= 0.0 && y.end >= 0.5, "the data still fits");
    }

    #[test]
    fn thinning_keeps_the_extremes_of_each_bucket() {
        let run: Vec<(f64, f64)> = (0..10_000).map(|i| (i as f64, ((i as f64) * 0.01).sin())).collect();
        let thinned = thin(run.clone(), 100);
        assert!(thinned.len() <= 400, "{}", thinned.len());
        let peak = |p: &[(f64, f64)]| p.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(peak(&thinned), peak(&run), "the maximum survives");
        assert_eq!(thinned.first(), run.first());
        assert_eq!(thinned.last(), run.last());
    }

    #[test]
    fn lines_are_clipped_to_the_box() {
        let (x, y) = (0.0..1.0, 0.0..1.0);
        assert_eq!(clip(&[(0.5, 0.5), (1.5, 0.5)], &x, &y), vec![vec![(0.5, 0.5), (1.0, 0.5)]]);
        assert_eq!(clip(&[(-1.0, 0.5), (2.0, 0.5)], &x, &y), vec![vec![(0.0, 0.5), (1.0, 0.5)]]);
        assert!(clip(&[(2.0, 2.0), (3.0, 3.0)], &x, &y).is_empty(), "wholly outside");
        let out_and_back = clip(&[(0.5, 0.5), (1.5, 0.5), (0.5, 0.6)], &x, &y);
        assert_eq!(out_and_back.len(), 2, "{out_and_back:?}");
    }

    #[test]
    fn non_finite_values_break_a_line() {
        let s = segments(&[(0.0, 1.0), (1.0, f64::NAN), (2.0, 1.0), (3.0, 2.0)], 100);
        assert_eq!(s, vec![vec![(0.0, 1.0)], vec![(2.0, 1.0), (3.0, 2.0)]]);
    }

    #[test]
    fn ticks_have_the_decimals_their_spacing_needs() {
        assert_eq!(tick(0.5, 3.0), "0.5");
        assert_eq!(tick(2.0, 10.0), "2");
        assert_eq!(tick(0.125_349_87, 1e-8), "0.12534987");
        assert_eq!(tick(-2.8e-17, 3.0), "0", "float noise at zero");
        assert_eq!(tick(1.5e7, 1e8), "1.50e7");
        assert_eq!(tick(12000.0, 20000.0), "12000");
    }
}
