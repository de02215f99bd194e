//! Line plots of one panel: sweep metrics against a parameter with their peaks marked, and
//! `runner compare`'s work-precision curves with the cost at which each method reaches the
//! target error marked.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::{figure, fonts, Drawing};

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

/// A plot of named lines with marked points, titled, 960 x 600 px.
pub struct LinePlot<'a> {
    /// Title above the plot.
    pub title: &'a str,
    /// Label of the x axis.
    pub x_label: &'a str,
    /// Label of the y axis.
    pub y_label: &'a str,
    /// The lines, in legend order.
    pub series: &'a [Series],
    /// Points marked with a circle and their text.
    pub marks: &'a [Mark],
}

impl Drawing for LinePlot<'_> {
    fn size(&self) -> (u32, u32) {
        SIZE
    }

    fn svg(&self) -> Result<String, String> {
        fonts::register();
        let mut svg = String::new();
        draw(&mut svg, self.title, self.x_label, self.y_label, self.series, self.marks)?;
        Ok(svg)
    }
}

/// The pixel size of a line plot.
const SIZE: (u32, u32) = (960, 600);

/// A box in pixels: left, top, right, bottom.
type Rect = (i32, i32, i32, i32);

/// The first of `obstacles` that overlaps `rect`.
fn in_the_way(obstacles: &[Rect], (x0, y0, x1, y1): Rect) -> Option<Rect> {
    obstacles.iter().copied().find(|&(l, t, r, b)| x0 < r && l < x1 && y0 < b && t < y1)
}

fn draw(svg: &mut String, title: &str, x_label: &str, y_label: &str, series: &[Series], marks: &[Mark]) -> Result<(), String> {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    // x spans the data exactly (time from start to stop); only a single point gets padding.
    let x_range = padded_range(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let x_range = x_range.start + (x_range.end - x_range.start) / 22.0..x_range.end - (x_range.end - x_range.start) / 22.0;
    let y_range = padded_range(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)).chain(marks.iter().map(|m| m.at.1)));
    let root = SVGBackend::with_string(svg, SIZE).into_drawing_area();
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
        let color = figure::color(i).to_rgba();
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
    // Each mark's label goes beside its point, on the first side (above or below, right or
    // left) where it overlaps no other label or marked point and stays inside the plot: marks
    // of nearby points (two methods reaching a target error at similar cost) would otherwise
    // print over each other. When no side is free it goes below the labels in the way, with a
    // thin line back to its point.
    let style = ("sans-serif", 15).into_font().color(&RED).pos(Pos::new(HPos::Left, VPos::Top));
    let (area_x, area_y) = chart.plotting_area().get_pixel_range();
    let points: Vec<(i32, i32)> = marks.iter().map(|m| chart.backend_coord(&m.at)).collect();
    let mut obstacles: Vec<Rect> = points.iter().map(|&(x, y)| (x - 8, y - 8, x + 8, y + 8)).collect();
    for (m, &(px, py)) in marks.iter().zip(&points) {
        chart.draw_series(std::iter::once(Circle::new(m.at, 6, RED.stroke_width(2)))).map_err(|e| err(&e))?;
        let (w, h) = root.estimate_text_size(&m.text, &style).map_err(|e| err(&e))?;
        let (w, h) = (w as i32, h as i32);
        let sides = [(px + 9, py - 9 - h), (px + 9, py + 9), (px - 9 - w, py - 9 - h), (px - 9 - w, py + 9)];
        let inside =
            |(x, y): (i32, i32)| area_x.contains(&x) && area_x.contains(&(x + w)) && area_y.contains(&y) && area_y.contains(&(y + h));
        let (x0, y0) = match sides.iter().copied().find(|&(x, y)| inside((x, y)) && in_the_way(&obstacles, (x, y, x + w, y + h)).is_none())
        {
            Some(side) => side,
            None => {
                let (x0, mut y0) = sides[1];
                while let Some((_, _, _, bottom)) = in_the_way(&obstacles, (x0, y0, x0 + w, y0 + h)) {
                    y0 = bottom + 2;
                }
                root.draw(&PathElement::new(vec![(px, py + 7), (x0, y0 + h / 2)], RED.mix(0.6).stroke_width(1))).map_err(|e| err(&e))?;
                (x0, y0)
            }
        };
        obstacles.push((x0, y0, x0 + w, y0 + h));
        root.draw(&Text::new(m.text.clone(), (x0, y0), style.clone())).map_err(|e| err(&e))?;
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

#[cfg(test)]
mod tests {
    use super::{draw, Mark, Series};

    /// The (x, y) of each `<text>` element whose content is `text`.
    fn positions(svg: &str, text: &str) -> Vec<(f64, f64)> {
        let attr = |tag: &str, name: &str| -> f64 {
            let at = tag.find(&format!(" {name}=\"")).expect("the attribute") + name.len() + 3;
            tag[at..tag[at..].find('"').unwrap() + at].parse().unwrap()
        };
        svg.split("<text")
            .skip(1)
            .filter(|t| t.split_once(">").is_some_and(|(_, body)| body.trim_start().starts_with(text)))
            .map(|t| (attr(t, "x"), attr(t, "y")))
            .collect()
    }

    /// Two marks a few pixels apart (two methods reaching a target error at about the same
    /// cost) get labels that do not overlap: drawn where the first one is, the second would
    /// cover it (both 15 px high, over 100 px wide).
    #[test]
    fn labels_of_nearby_marks_do_not_overlap() {
        crate::fonts::register();
        let series = vec![Series { label: "a".into(), points: vec![(0.0, 0.0), (10.0, 10.0)] }];
        let marks =
            vec![Mark { at: (5.0, 5.0), text: "first reaches 1e-6".into() }, Mark { at: (5.1, 5.05), text: "second reaches 1e-6".into() }];
        let mut svg = String::new();
        draw(&mut svg, "t", "x", "y", &series, &marks).unwrap();
        let (a, b) = (positions(&svg, "first reaches 1e-6"), positions(&svg, "second reaches 1e-6"));
        assert_eq!((a.len(), b.len()), (1, 1), "each label drawn once");
        let ((ax, ay), (bx, by)) = (a[0], b[0]);
        // Apart by a line's height vertically, or by a label's width horizontally.
        assert!((ay - by).abs() >= 15.0 || (ax - bx).abs() >= 100.0, "labels at ({ax}, {ay}) and ({bx}, {by}) overlap");
    }
}
