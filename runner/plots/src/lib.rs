//! Figures a person reads, drawn from runs: panels of curves with events marked ([`figure`]),
//! a run's outputs over time in their display units ([`outputs`]), metrics against a parameter
//! with their peaks marked ([`lines`]), mechanisms drawn to scale ([`scene`]) and animated
//! ([`animation`], [`gif`]), from runs kept in memory ([`trace`]). Every drawing is SVG first;
//! a PNG (and a GIF frame) is that SVG rendered by resvg ([`raster`]), so both look alike.
//! The runner's commands, the handbook and the page use it; it writes no files itself (the
//! caller decides how a file is put in place) and knows no lab model.

pub mod animation;
pub mod figure;
pub mod fonts;
pub mod gif;
pub mod lines;
pub mod outputs;
pub mod raster;
pub mod scene;
pub mod trace;

use std::path::Path;

/// A picture that is SVG first, and a PNG rendered from that SVG.
pub trait Drawing {
    /// Its size in pixels.
    fn size(&self) -> (u32, u32);
    /// Its SVG text.
    fn svg(&self) -> Result<String, String>;
}

/// How a picture is written, from the file's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Scalable Vector Graphics (`.svg`).
    Svg,
    /// A PNG rendered from the SVG (`.png`).
    Png,
}

impl Format {
    /// Every format with its extension, in the order messages list them.
    pub const ALL: [Format; 2] = [Format::Svg, Format::Png];

    /// The format `path`'s extension names (`.svg` or `.png`, any case), or an error naming the
    /// extension and the ones there are: the one rule of every `--plot FILE`.
    pub fn of(path: &Path) -> Result<Format, String> {
        let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if let Some(format) = Format::ALL.into_iter().find(|f| extension.as_deref() == Some(f.extension())) {
            return Ok(format);
        }
        let accepted: Vec<String> = Format::ALL.iter().map(|f| format!(".{}", f.extension())).collect();
        let given = match path.extension() {
            Some(e) => format!("its extension .{} is not one of them", e.to_string_lossy()),
            None => "it has no extension".to_owned(),
        };
        Err(format!("cannot plot into {}: the file name must end in {}, and {given}", path.display(), accepted.join(" or ")))
    }

    /// The format called `name` (`svg` or `png`), for options such as `--format`.
    pub fn named(name: &str) -> Result<Format, String> {
        Format::ALL.into_iter().find(|f| f.extension().eq_ignore_ascii_case(name)).ok_or_else(|| {
            let names: Vec<&str> = Format::ALL.iter().map(|f| f.extension()).collect();
            format!("the format {name} is not one of {}", names.join(", "))
        })
    }

    /// The extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Svg => "svg",
            Format::Png => "png",
        }
    }
}

/// The bytes of a file holding `drawing` as `format`.
pub fn encode(drawing: &dyn Drawing, format: Format) -> Result<Vec<u8>, String> {
    fonts::register();
    let svg = drawing.svg()?;
    match format {
        Format::Svg => Ok(svg.into_bytes()),
        Format::Png => raster::png(&raster::rgb(&svg, drawing.size())?, drawing.size()),
    }
}

/// The bytes of the file `path` holding `drawing`, in the format its extension names: what every
/// command that takes `--plot FILE` writes.
pub fn file_bytes(path: &Path, drawing: &dyn Drawing) -> Result<Vec<u8>, String> {
    let format = Format::of(path)?;
    encode(drawing, format).map_err(|e| format!("cannot draw {}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::figure::{color, Curve, Figure, Panel};
    use crate::lines::{LinePlot, Mark, Series};

    /// A PNG's width, height and pixels (RGB), as a PNG reader sees the file.
    fn decode(bytes: &[u8]) -> (u32, u32, Vec<[u8; 3]>) {
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
        let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buffer).unwrap();
        assert_eq!((info.color_type, info.bit_depth), (png::ColorType::Rgb, png::BitDepth::Eight));
        (info.width, info.height, buffer[..info.buffer_size()].chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect())
    }

    /// The distinct levels (steps of 1/32, strictly between none and full) at which `line` is
    /// blended into the white background somewhere in `pixels`: a pixel a line covers by a
    /// fraction a is a line + (1 - a) white in every channel (within 4 of 255 per channel, for
    /// the rasterizer's 8-bit arithmetic). A line drawn without anti-aliasing is either there or
    /// not, and stair-steps; an anti-aliased one shades its edges through many levels.
    fn blend_levels(pixels: &[[u8; 3]], line: plotters::style::RGBColor) -> usize {
        let line = [255.0 - line.0 as f64, 255.0 - line.1 as f64, 255.0 - line.2 as f64];
        let norm = line.iter().map(|l| l * l).sum::<f64>();
        let mut levels = std::collections::BTreeSet::new();
        for p in pixels {
            let ink: Vec<f64> = p.iter().map(|&c| 255.0 - c as f64).collect();
            let a = ink.iter().zip(line).map(|(i, l)| i * l).sum::<f64>() / norm;
            let off = ink.iter().zip(line).map(|(i, l)| (i - a * l).powi(2)).sum::<f64>().sqrt();
            if off <= 4.0 && a > 0.05 && a < 0.95 {
                levels.insert((a * 32.0).round() as u32);
            }
        }
        levels.len()
    }

    /// Checks a PNG as an image: the size its drawing says, ink on it (not blank), and the
    /// curve in `line` drawn anti-aliased (at 10 or more of the 31 partial coverage levels).
    fn check_png(drawing: &dyn Drawing, line: plotters::style::RGBColor) {
        let (w, h, pixels) = decode(&encode(drawing, Format::Png).unwrap());
        assert_eq!((w, h), drawing.size());
        let inked = pixels.iter().filter(|p| **p != [255, 255, 255]).count();
        assert!(inked * 100 > pixels.len(), "{inked} of {} pixels drawn: blank", pixels.len());
        assert!(pixels.iter().any(|p| p.iter().all(|&c| c < 60)), "black text and axes are drawn");
        let levels = blend_levels(&pixels, line);
        assert!(levels >= 10, "the curve's colour appears at {levels} coverage levels: not anti-aliased");
    }

    /// A figure of two panels with a sloping line each, as PNG.
    #[test]
    fn a_png_figure_is_an_anti_aliased_image_of_its_size() {
        let panel = Panel { curves: vec![Curve::line("y", vec![(0.0, 0.0), (1.0, 1.0)], color(0))], ..Panel::default() };
        let figure = Figure::column(Some("test".into()), vec![panel.clone(), panel], (400, 200));
        assert_eq!(figure.size(), (400, 2 * 200 + 40), "a title's 40 px above the panels");
        check_png(&figure, color(0));
    }

    /// A sweep's line plot with its peak marked, as PNG.
    #[test]
    fn a_png_line_plot_is_an_anti_aliased_image_of_its_size() {
        let points: Vec<(f64, f64)> = (0..200).map(|i| (i as f64 * 0.25, (i as f64 * 0.05).sin())).collect();
        let series = [Series { label: "metric".into(), points }];
        let marks = [Mark { at: (7.75, 1.0), text: "peak 1.0000 at speed = 7.75".into() }];
        let plot = LinePlot { title: "t", x_label: "speed (m/s)", y_label: "metric", series: &series, marks: &marks };
        assert_eq!(plot.size(), (960, 600));
        check_png(&plot, color(0));
    }

    /// The checks can fail: a line drawn without anti-aliasing (one colour on white, as
    /// plotters' bitmap backend drew it) shows no partial coverage.
    #[test]
    fn a_stair_stepped_line_has_no_partial_coverage() {
        let c = color(0);
        let mut pixels = vec![[255u8; 3]; 100 * 100];
        for i in 0..100 {
            pixels[i * 100 + i / 2] = [c.0, c.1, c.2];
        }
        assert_eq!(blend_levels(&pixels, c), 0);
    }

    #[test]
    fn formats_are_chosen_by_extension_and_others_refused_by_name() {
        assert_eq!(Format::of(Path::new("a/b.SVG")).unwrap(), Format::Svg);
        assert_eq!(Format::of(Path::new("b.png")).unwrap(), Format::Png);
        let e = Format::of(Path::new("out/b.pdf")).unwrap_err();
        assert_eq!(e, "cannot plot into out/b.pdf: the file name must end in .svg or .png, and its extension .pdf is not one of them");
        assert!(Format::of(Path::new("plot")).unwrap_err().contains("it has no extension"));
        assert_eq!(Format::named("PNG").unwrap(), Format::Png);
        assert_eq!(Format::named("pdf").unwrap_err(), "the format pdf is not one of svg, png");
    }
}
