//! Pixels from SVG: a figure's PNG and an animation's frames are rendered by resvg from the very
//! SVG the figure writes, so lines are anti-aliased, text is shaped and kerned with the embedded
//! font (fonts.rs), and an SVG and a PNG of one figure show the same drawing.

use resvg::tiny_skia::{Pixmap, Transform};
use resvg::usvg;

use crate::fonts;

/// The SVG `svg`, `width` x `height` px, rendered onto white: 3 bytes (RGB) per pixel, row by row.
pub fn rgb(svg: &str, (width, height): (u32, u32)) -> Result<Vec<u8>, String> {
    let options = usvg::Options { fontdb: fonts::database(), font_family: "DejaVu Sans".into(), ..usvg::Options::default() };
    let svg = keep_spaces(svg);
    let tree = usvg::Tree::from_str(&svg, &options).map_err(|e| format!("the figure's SVG does not parse: {e}"))?;
    let mut pixmap = Pixmap::new(width, height).ok_or_else(|| format!("cannot draw a picture of {width}x{height} px"))?;
    pixmap.fill(resvg::tiny_skia::Color::WHITE);
    let size = tree.size();
    let scale = Transform::from_scale(width as f32 / size.width(), height as f32 / size.height());
    resvg::render(&tree, scale, &mut pixmap.as_mut());
    // Opaque (drawn onto white), so the premultiplied RGBA is plain RGBA: drop the alpha.
    Ok(pixmap.data().chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect())
}

/// `svg` with every run of spaces kept as laid out: plotters measures and places a text such as
/// an animation's stamp `t = 1.500 s   regime = 4` with its spaces, which SVG's rules would
/// collapse into one (`xml:space="preserve"` would also keep the line breaks plotters puts
/// around each text, shifting it). A space after a space becomes a no-break space, which looks
/// the same and is not collapsed.
fn keep_spaces(svg: &str) -> std::borrow::Cow<'_, str> {
    if !svg.contains("  ") {
        return svg.into();
    }
    let mut out = String::with_capacity(svg.len());
    let mut previous = '\0';
    for c in svg.chars() {
        out.push(if c == ' ' && previous == ' ' { '\u{a0}' } else { c });
        previous = c;
    }
    out.into()
}

/// An RGB buffer as a PNG file.
pub fn png(rgb: &[u8], (width, height): (u32, u32)) -> Result<Vec<u8>, String> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| format!("PNG: {e}"))?;
    writer.write_image_data(rgb).map_err(|e| format!("PNG: {e}"))?;
    writer.finish().map_err(|e| format!("PNG: {e}"))?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_of_spaces_are_kept_and_single_ones_left_alone() {
        assert_eq!(keep_spaces("<text>t = 1 s   regime = 4</text>"), "<text>t = 1 s \u{a0}\u{a0}regime = 4</text>");
        assert!(matches!(keep_spaces("<svg width=\"2\"> a b </svg>"), std::borrow::Cow::Borrowed(_)));
    }
}
