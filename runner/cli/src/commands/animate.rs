//! `runner animate`: an animated GIF of any FMU whose outputs include point coordinates
//! (`<P>_x`, `<P>_y`), drawn to scale with the links, trails and frame of the model's
//! `[animate]` section (or of `--experiment FILE` for an FMU given by path).

use std::path::{Path, PathBuf};

use fmi_importer::{Fmu, Variable};
use runner_engine::run::Grid;
use runner_engine::variables;

use crate::experiment::{self, AnimateDefaults, Experiment, RunDefaults};
use crate::interrupt;
use crate::report::figure::{self, Figure, Panel};
use crate::report::gif::GifWriter;
use crate::report::output;
use crate::report::progress::Progress;
use crate::report::scene::{Motion, Scene, View};
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

/// Options of `runner animate`.
#[derive(Default)]
pub struct Options {
    /// Model name or `.fmu` path.
    pub fmu: String,
    /// Grid and assignments from the command line.
    pub run: RunDefaults,
    /// The GIF to write.
    pub out: PathBuf,
    /// Frames per second.
    pub fps: Option<f64>,
    /// Simulated seconds per second of playback.
    pub speed: Option<f64>,
    /// Width in pixels.
    pub size: Option<u32>,
    /// An experiment.toml whose `[animate]` (and `[simulate]`) apply instead of the model's.
    pub experiment: Option<PathBuf>,
}

/// What was written.
#[derive(Debug)]
pub struct Written {
    pub frames: usize,
    pub size: (u32, u32),
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

/// Draws `frames` of `motion` into the GIF at `path`; `progress` counts them.
pub fn write_gif(
    path: &Path,
    motion: &Motion<'_>,
    frames: &[usize],
    title: &str,
    width: u32,
    fps: f64,
    progress: Option<&Progress>,
) -> Result<Written, String> {
    let views = motion.views(frames);
    let size = gif_size(&views[0], width);
    let mut gif = GifWriter::create(path, size)?;
    for (k, (&i, view)) in frames.iter().zip(&views).enumerate() {
        if interrupt::requested() {
            return Err(format!("interrupted after {k} frames; no file written"));
        }
        let figure = Figure { title: None, panels: vec![motion.panel(i, view, Some(title.to_owned()))], columns: 1, panel_size: size };
        let rgb = figure::rasterize(&figure)?;
        gif.frame(&rgb, 1.0 / fps)?;
        if let Some(p) = progress {
            p.inc(1);
        }
    }
    let frames = gif.finish()?;
    Ok(Written { frames, size, fps })
}

/// Everything an animation needs before drawing: the FMU, the scene, the timing and the run.
pub struct Prepared {
    pub fmu: Fmu,
    pub scene: Scene,
    pub timing: Timing,
    pub grid: Grid,
    pub set: Vec<String>,
    pub config: AnimateDefaults,
}

/// Resolves the FMU, its `[animate]` settings and the command line into a scene and a grid.
pub fn prepare(options: &Options) -> Result<Prepared, String> {
    let target = experiment::resolve(&options.fmu)?;
    let experiment: Experiment = match &options.experiment {
        Some(path) => {
            if !path.is_file() {
                return Err(format!("the experiment file {} does not exist", path.display()));
            }
            experiment::read(path)?
        }
        None => target.experiment,
    };
    let fmu = Fmu::load(&target.path)?;
    let config = experiment.animate.clone();
    let scene = Scene::new(&fmu.description, &config)?;
    let grid = Grid::choose(&fmu.description, &[options.run.grid(), config.run().grid(), experiment.simulate.grid()])?;
    let timing = Timing::choose(grid.interval, options.speed.or(config.speed), options.fps.or(config.fps))?;
    let grid = Grid { interval: timing.interval, ..grid };
    let mut set = experiment.simulate.set.clone();
    set.extend(config.set.iter().cloned());
    set.extend(options.run.set.iter().cloned());
    Ok(Prepared { fmu, scene, timing, grid, set, config })
}

impl Prepared {
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

/// Runs `runner animate`.
pub fn run(options: &Options) -> Result<Written, String> {
    match options.out.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("gif") => {}
        _ => return Err(format!("cannot animate into {}: the file name must end in .gif", options.out.display())),
    }
    output::check_destination(&options.out)?;
    let prepared = prepare(options)?;
    let width = options.size.or(prepared.config.size).unwrap_or(DEFAULT_SIZE);
    if !(MIN_SIZE..=MAX_SIZE).contains(&width) {
        return Err(format!("a GIF width of {width} px: the width (--size, or [animate] size) must be {MIN_SIZE} to {MAX_SIZE} px"));
    }
    let expected = ((prepared.grid.stop - prepared.grid.start) / prepared.timing.frame_step).ceil();
    if expected > MAX_FRAMES as f64 {
        return Err(format!(
            "{} s of motion at {} s per frame is {expected:.0} frames, more than the {MAX_FRAMES} an animation may have: raise --speed or the output interval, or lower --fps",
            prepared.grid.stop - prepared.grid.start,
            crate::trace::short(prepared.timing.frame_step)
        ));
    }
    let trace = prepared.record()?;
    if let Some(reason) = &trace.ended_early {
        eprintln!("{}: the run ended at t = {} s: {reason}", prepared.fmu.identifier, trace.time.last().copied().unwrap_or(0.0));
    }
    let motion = prepared.scene.motion(&trace)?;
    let frames = prepared.timing.frames(&trace.time);
    let progress = Progress::start(frames.len() as u64, "frames");
    let written =
        write_gif(&options.out, &motion, &frames, &prepared.fmu.description.model_name, width, prepared.timing.fps, Some(&progress))?;
    drop(progress);
    println!(
        "wrote {}: {} frames, {}x{} px, {} fps ({} simulated s per frame)",
        options.out.display(),
        written.frames,
        written.size.0,
        written.size.1,
        crate::trace::short(written.fps),
        crate::trace::short(prepared.timing.frame_step)
    );
    Ok(written)
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
