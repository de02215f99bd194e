//! Animated GIFs from RGB frames (the `gif` crate of image-rs encodes): one fixed 256-colour
//! palette that holds the figure colours exactly, with their blends into white for the
//! anti-aliased edges of text; each frame stores only the rectangle that changed since the one
//! before, and frame delays add up to the animation's real duration.

use std::borrow::Cow;
use std::io::Write;

use gif::{DisposalMethod, Encoder, Frame, Repeat};

use crate::figure::PALETTE;

/// Shortest frame delay (centiseconds) that browsers honour: below 2 they show 10.
pub const MIN_DELAY_CS: u16 = 2;

/// The palette: the figure colours, black and the link colour, each blended into white in 12
/// steps; 24 greys; and a 4x4x4 colour cube for anything else.
fn palette() -> Vec<[u8; 3]> {
    let mut colors: Vec<[u8; 3]> = Vec::with_capacity(256);
    let mut bases: Vec<[u8; 3]> = PALETTE.iter().map(|c| [c.0, c.1, c.2]).collect();
    bases.push([0, 0, 0]);
    bases.push([52, 62, 88]);
    for base in &bases {
        for k in 0..12 {
            let t = k as f64 / 12.0;
            let mix = |c: u8| (c as f64 + (255.0 - c as f64) * t).round() as u8;
            colors.push([mix(base[0]), mix(base[1]), mix(base[2])]);
        }
    }
    for k in 0..24 {
        let g = (k * 255 / 23) as u8;
        colors.push([g, g, g]);
    }
    for r in 0..4 {
        for g in 0..4 {
            for b in 0..4 {
                colors.push([r * 85, g * 85, b * 85]);
            }
        }
    }
    colors.truncate(256);
    colors
}

/// Maps RGB colours to palette indices, nearest colour first computed on demand per 6-bit
/// colour cell (a frame has few distinct colours).
struct Quantizer {
    colors: Vec<[u8; 3]>,
    cells: Vec<u16>,
}

impl Quantizer {
    const UNSET: u16 = u16::MAX;

    fn new() -> Quantizer {
        Quantizer { colors: palette(), cells: vec![Self::UNSET; 1 << 18] }
    }

    fn index(&mut self, r: u8, g: u8, b: u8) -> u8 {
        let cell = ((r as usize >> 2) << 12) | ((g as usize >> 2) << 6) | (b as usize >> 2);
        if self.cells[cell] == Self::UNSET {
            let distance = |c: &[u8; 3]| {
                let d = |a: u8, b: u8| (a as i32 - b as i32).pow(2);
                d(c[0], r) + d(c[1], g) + d(c[2], b)
            };
            let best = self.colors.iter().enumerate().min_by_key(|(_, c)| distance(c)).map_or(0, |(i, _)| i);
            self.cells[cell] = best as u16;
        }
        self.cells[cell] as u8
    }
}

/// An animated GIF being written into `W` (a file the caller puts in place when finished, or
/// memory).
pub struct GifWriter<W: Write> {
    encoder: Encoder<W>,
    size: (u16, u16),
    quantizer: Quantizer,
    previous: Option<Vec<u8>>,
    /// Centiseconds of delay written so far, and the duration they should add up to.
    written_cs: u64,
    wanted_seconds: f64,
    frames: usize,
}

impl<W: Write> GifWriter<W> {
    /// Starts a looping GIF of `size` pixels in `out`.
    pub fn new(out: W, (w, h): (u32, u32)) -> Result<GifWriter<W>, String> {
        let size = (
            u16::try_from(w).map_err(|_| format!("a GIF is at most 65535 px wide, not {w}"))?,
            u16::try_from(h).map_err(|_| format!("a GIF is at most 65535 px high, not {h}"))?,
        );
        let quantizer = Quantizer::new();
        let flat: Vec<u8> = quantizer.colors.iter().flatten().copied().collect();
        let gif_err = |e: gif::EncodingError| format!("cannot write a GIF: {e}");
        let mut encoder = Encoder::new(out, size.0, size.1, &flat).map_err(gif_err)?;
        encoder.set_repeat(Repeat::Infinite).map_err(gif_err)?;
        Ok(GifWriter { encoder, size, quantizer, previous: None, written_cs: 0, wanted_seconds: 0.0, frames: 0 })
    }

    /// Adds a frame (RGB, the GIF's size) shown for `seconds`.
    pub fn frame(&mut self, rgb: &[u8], seconds: f64) -> Result<(), String> {
        let (w, h) = (self.size.0 as usize, self.size.1 as usize);
        if rgb.len() != w * h * 3 {
            return Err(format!("a frame of {} bytes for a {w}x{h} GIF", rgb.len()));
        }
        let indexed: Vec<u8> = rgb.chunks_exact(3).map(|p| self.quantizer.index(p[0], p[1], p[2])).collect();
        // The rectangle that changed; an unchanged frame still takes its place in time as one pixel.
        let (left, top, right, bottom) = match &self.previous {
            None => (0, 0, w - 1, h - 1),
            Some(before) => changed_box(before, &indexed, w).unwrap_or((0, 0, 0, 0)),
        };
        let (fw, fh) = (right - left + 1, bottom - top + 1);
        let mut buffer = Vec::with_capacity(fw * fh);
        for row in top..=bottom {
            buffer.extend_from_slice(&indexed[row * w + left..=row * w + right]);
        }
        self.wanted_seconds += seconds.max(0.0);
        let wanted_cs = (self.wanted_seconds * 100.0).round() as u64;
        let delay = wanted_cs.saturating_sub(self.written_cs).clamp(MIN_DELAY_CS as u64, u16::MAX as u64) as u16;
        self.written_cs += delay as u64;
        let frame = Frame {
            delay,
            dispose: DisposalMethod::Keep,
            left: left as u16,
            top: top as u16,
            width: fw as u16,
            height: fh as u16,
            buffer: Cow::Owned(buffer),
            ..Frame::default()
        };
        self.encoder.write_frame(&frame).map_err(|e| format!("cannot write a GIF frame: {e}"))?;
        self.previous = Some(indexed);
        self.frames += 1;
        Ok(())
    }

    /// Finishes the GIF; returns where it was written and the number of frames.
    pub fn finish(self) -> Result<(W, usize), String> {
        let out = self.encoder.into_inner().map_err(|e| format!("cannot finish the GIF: {e}"))?;
        Ok((out, self.frames))
    }
}

/// The smallest box `(left, top, right, bottom)` holding every pixel that differs.
fn changed_box(a: &[u8], b: &[u8], w: usize) -> Option<(usize, usize, usize, usize)> {
    let rows: Vec<usize> = (0..a.len() / w).filter(|&r| a[r * w..(r + 1) * w] != b[r * w..(r + 1) * w]).collect();
    let (top, bottom) = (*rows.first()?, *rows.last()?);
    let mut left = w;
    let mut right = 0;
    for r in top..=bottom {
        let (ra, rb) = (&a[r * w..(r + 1) * w], &b[r * w..(r + 1) * w]);
        if let Some(first) = (0..w).find(|&x| ra[x] != rb[x]) {
            left = left.min(first);
            right = right.max((first..w).rev().find(|&x| ra[x] != rb[x]).unwrap_or(first));
        }
    }
    Some((left, top, right, bottom))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figure_colours_are_in_the_palette_exactly() {
        let mut q = Quantizer::new();
        for c in PALETTE.iter().chain([&plotters::style::RGBColor(255, 255, 255), &plotters::style::RGBColor(0, 0, 0)]) {
            let i = q.index(c.0, c.1, c.2) as usize;
            assert_eq!(q.colors[i], [c.0, c.1, c.2]);
        }
        assert!(q.colors.len() <= 256);
    }

    #[test]
    fn the_changed_box_is_tight() {
        let w = 5;
        let a = vec![0u8; 20];
        let mut b = a.clone();
        b[w + 1] = 1;
        b[2 * w + 3] = 1;
        assert_eq!(changed_box(&a, &b, w), Some((1, 1, 3, 2)));
        assert_eq!(changed_box(&a, &a, w), None);
    }

    /// Frames, their count and their delays as a GIF decoder reads them back: the delays add up
    /// to the duration asked for, to the centisecond, though 1/30 s is not a whole number of them.
    #[test]
    fn a_written_gif_decodes_to_its_frames_and_duration() {
        let (w, h) = (8u32, 6u32);
        let mut gif = GifWriter::new(Vec::new(), (w, h)).unwrap();
        for k in 0..30 {
            let mut rgb = vec![255u8; (w * h * 3) as usize];
            rgb[(k % 8) * 3] = 0;
            gif.frame(&rgb, 1.0 / 30.0).unwrap();
        }
        let (bytes, frames) = gif.finish().unwrap();
        assert_eq!(frames, 30);
        let mut options = gif::DecodeOptions::new();
        options.set_color_output(gif::ColorOutput::Indexed);
        let mut decoder = options.read_info(std::io::Cursor::new(bytes)).unwrap();
        let (mut frames, mut cs) = (0, 0u32);
        while let Some(frame) = decoder.read_next_frame().unwrap() {
            frames += 1;
            cs += frame.delay as u32;
        }
        assert_eq!((frames, cs), (30, 100));
    }
}
