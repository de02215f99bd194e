//! Animations of mechanisms: a run recorded at the frame times of `[animate]` (or the command
//! line's), each frame the scene at one sample drawn to scale, written as a looping GIF whose
//! frame delays add up to the motion's duration at the chosen playback speed.

use std::io::Write;

use fmi_importer::{Fmu, Variable};
use runner_engine::run::Grid;
use runner_engine::variables;
use runner_workspace::experiment::{AnimateDefaults, Experiment, RunDefaults};

use crate::figure::{self, Figure, Panel};
use crate::gif::GifWriter;
use crate::scene::{Motion, Scene, View};
use crate::trace::Trace;

/// Highest frame rate: a GIF frame lasts a whole number of centiseconds, at least 2.
pub const MAX_FPS: f64 = 50.0;
/// Default width of the GIF (px).
pub const DEFAULT_SIZE: u32 = 640;
/// Smallest width and height of a GIF (px).
pub const MIN_SIZE: u32 = 480;
/// Largest width of a GIF (px): a frame is drawn in memory, width x height x 3 bytes.
pub const MAX_SIZE: u32 = 4096;
/// Most frames an animation may have: 20,000 frames are minutes of GIF at 50 per second.
pub const MAX_FRAMES: usize = 20_000;

/// What was written.
#[derive(Debug)]
pub struct Written {
    /// Number of frames.
    pub frames: usize,
    /// Width and height (px).
    pub size: (u32, u32),
    /// Frames per second.
    pub fps: f64,
}

/// The animation's timing: the run's output interval, and every frame's sample and duration.
#[derive(Debug, Clone, PartialEq)]
pub struct Timing {
    /// Frames per second of playback.
    pub fps: f64,
    /// Simulated seconds between frames.
    pub frame_step: f64,
    /// The output interval the run uses (the frame step or finer).
    pub interval: f64,
}

impl Timing {
    /// From the output interval `interval` of the settings, `speed` (default 1) and `fps`
    /// (default one frame per output interval, at most [`MAX_FPS`]).
    pub fn choose(interval: f64, speed: Option<f64>, fps: Option<f64>) -> Result<Timing, String> {
        let speed = speed.unwrap_or(1.0);
        if !(speed.is_finite() && speed > 0.0) {
            return Err(format!("the playback speed {speed} must be a positive number (1 is real time)"));
        }
        let fps = match fps {
            Some(f) if !(f.is_finite() && f > 0.0 && f <= MAX_FPS) => {
                return Err(format!("--fps {f} must be a number above 0 and at most {MAX_FPS} (a GIF frame lasts at least 20 ms)"));
            }
            Some(f) => f,
            None => (speed / interval).min(MAX_FPS),
        };
        let frame_step = speed / fps;
        Ok(Timing { fps, frame_step, interval: interval.min(frame_step) })
    }

    /// The samples shown as frames: the one nearest each multiple of the frame step, and the
    /// last sample (where a model that ends early, such as a landing, stopped).
    pub fn frames(&self, time: &[f64]) -> Vec<usize> {
        let Some(&end) = time.last() else { return Vec::new() };
        let start = time[0];
        let count = ((end - start) / self.frame_step + 1e-9).floor() as usize + 1;
        let mut picks: Vec<usize> = Vec::with_capacity(count + 1);
        let mut j = 0;
        for k in 0..count {
            let t = start + k as f64 * self.frame_step;
            while j + 1 < time.len() && (time[j + 1] - t).abs() <= (time[j] - t).abs() {
                j += 1;
            }
            if picks.last() != Some(&j) {
                picks.push(j);
            }
        }
        let last = time.len() - 1;
        if picks.last() != Some(&last) && time[last] - time[*picks.last().unwrap_or(&0)] > 1e-9 * end.abs().max(1.0) {
            picks.push(last);
        }
        picks
    }
}

/// The GIF's pixel size for views of `view`'s shape: `width` wide, high enough to keep the
/// scene's proportions, and at least [`MIN_SIZE`] both ways.
pub fn gif_size(view: &View, width: u32) -> (u32, u32) {
    let width = width.max(MIN_SIZE);
    let (w, h) = (view.0.end - view.0.start, view.1.end - view.1.start);
    let probe = Panel { title: Some(String::new()), ..Panel::default() };
    let (pw, ph) = figure::plot_area_size(&probe, (width, width));
    let extra = width - ph;
    let plot_h = (pw as f64 * h / w.max(1e-12)).round() as u32;
    let height = (plot_h + extra).clamp(MIN_SIZE, 2 * width);
    (width, height)
}

/// Draws `frames` of `motion` into a GIF written to `out`, `width` px wide; `after_frame` is told
/// how many frames are drawn after each one (a progress bar), and an error it returns (the user
/// interrupted) stops the drawing. Returns `out` with the GIF in it.
pub fn write_gif<W: Write>(
    out: W,
    motion: &Motion<'_>,
    frames: &[usize],
    title: &str,
    width: u32,
    fps: f64,
    after_frame: &mut dyn FnMut(usize) -> Result<(), String>,
) -> Result<(W, Written), String> {
    let views = motion.views(frames);
    let size = gif_size(&views[0], width);
    let mut gif = GifWriter::new(out, size)?;
    for (k, (&i, view)) in frames.iter().zip(&views).enumerate() {
        let figure = Figure { title: None, panels: vec![motion.panel(i, view, Some(title.to_owned()))], columns: 1, panel_size: size };
        let rgb = figure::rasterize(&figure)?;
        gif.frame(&rgb, 1.0 / fps)?;
        after_frame(k + 1)?;
    }
    let (out, frames) = gif.finish()?;
    Ok((out, Written { frames, size, fps }))
}

/// Everything an animation needs before drawing: the FMU, the scene, the timing and the run.
pub struct Animation {
    /// The FMU, loaded.
    pub fmu: Fmu,
    /// Its `[animate]` scene, resolved against its variables.
    pub scene: Scene,
    /// Frames per second and the frame step.
    pub timing: Timing,
    /// The run's grid, sampled at the frame step or finer.
    pub grid: Grid,
    /// `NAME=VALUE` assignments of the run: `[simulate]`'s, `[animate]`'s, then the command line's.
    pub set: Vec<String>,
    /// The `[animate]` section.
    pub config: AnimateDefaults,
}

impl Animation {
    /// Resolves `experiment`'s `[animate]` section and `run`, `speed` and `fps` (the command
    /// line's, which take precedence) against `fmu` into a scene, a timing and a grid.
    pub fn new(fmu: Fmu, experiment: &Experiment, run: &RunDefaults, speed: Option<f64>, fps: Option<f64>) -> Result<Animation, String> {
        let config = experiment.animate.clone();
        let scene = Scene::new(&fmu.description, &config)?;
        let grid = Grid::choose(&fmu.description, &[run.grid(), config.run().grid(), experiment.simulate.grid()])?;
        let timing = Timing::choose(grid.interval, speed.or(config.speed), fps.or(config.fps))?;
        let grid = Grid { interval: timing.interval, ..grid };
        let mut set = experiment.simulate.set.clone();
        set.extend(config.set.iter().cloned());
        set.extend(run.set.iter().cloned());
        Ok(Animation { fmu, scene, timing, grid, set, config })
    }

    /// Runs the FMU, keeping what the scene reads and every numeric output.
    pub fn record(&self) -> Result<Trace, String> {
        let md = &self.fmu.description;
        let assignments = variables::parse_sets(md, &self.set)?;
        let mut recorded: Vec<&Variable> = self.scene.variables(md);
        for v in md.outputs().filter(|v| v.kind.is_numeric()) {
            if !recorded.iter().any(|r| r.name == v.name) {
                recorded.push(v);
            }
        }
        let trace = Trace::record(&self.fmu, &self.fmu.identifier, &self.grid, &assignments, &recorded)?;
        if trace.time.is_empty() {
            return Err(format!("{} produced no samples to animate", md.model_name));
        }
        Ok(trace)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_rate_follows_the_output_interval_up_to_fifty() {
        let t = Timing::choose(0.05, None, None).unwrap();
        assert_eq!((t.fps, t.frame_step, t.interval), (20.0, 0.05, 0.05));
        let t = Timing::choose(0.001, None, None).unwrap();
        assert_eq!((t.fps, t.interval), (50.0, 0.001), "1000 samples a second are shown at 50 fps");
        let t = Timing::choose(0.01, Some(0.25), None).unwrap();
        assert!((t.fps - 25.0).abs() < 1e-12 && (t.frame_step - 0.01).abs() < 1e-15, "{t:?}");
        let t = Timing::choose(0.1, None, Some(25.0)).unwrap();
        assert_eq!(t.interval, 0.04, "--fps finer than the samples refines the run");
        assert!(Timing::choose(0.1, None, Some(60.0)).unwrap_err().contains("at most 50"));
        assert!(Timing::choose(0.1, Some(0.0), None).unwrap_err().contains("speed"));
    }

    /// 12 s sampled every 10 ms shown every 50 ms: 241 frames, one per 5 samples; a run that
    /// stopped between frames (a landing) keeps its last sample as the last frame.
    #[test]
    fn frames_pick_the_samples_at_the_frame_times() {
        let timing = Timing { fps: 20.0, frame_step: 0.05, interval: 0.01 };
        let time: Vec<f64> = (0..=1200).map(|i| i as f64 * 0.01).collect();
        let frames = timing.frames(&time);
        assert_eq!(frames.len(), 241);
        assert_eq!(frames[1], 5);
        assert_eq!(*frames.last().unwrap(), 1200);
        let mut ended = time[..=503].to_vec();
        ended.push(5.0372);
        let frames = timing.frames(&ended);
        assert_eq!(frames.len(), 102, "0, 0.05, ..., 5.0 and the end at 5.0372");
        assert_eq!(*frames.last().unwrap(), ended.len() - 1);
    }

    #[test]
    fn a_gif_is_at_least_480_px_both_ways_and_keeps_the_proportions() {
        assert_eq!(gif_size(&(0.0..10.0, 0.0..1.0), 640), (640, 480));
        let (w, h) = gif_size(&(0.0..1.0, 0.0..2.0), 640);
        assert_eq!(w, 640);
        assert!(h > 900, "{h}");
        assert_eq!(gif_size(&(0.0..1.0, 0.0..1.0), 100).0, 480);
    }
}
