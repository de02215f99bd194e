//! `runner animate`: an animated GIF of any FMU whose outputs include point coordinates
//! (`<P>_x`, `<P>_y`), drawn to scale with the links, trails and frame of the model's
//! `[animate]` section (or of `--experiment FILE` for an FMU given by path).

use std::path::PathBuf;

use fmi_importer::Fmu;
use plots::animation::{self, Animation, Written, DEFAULT_SIZE, MAX_FRAMES, MAX_SIZE, MIN_SIZE};
use plots::trace::short;

use crate::experiment::{self, Experiment, RunDefaults};
use crate::interrupt;
use crate::report::output::{self, ResultFile};
use crate::report::progress::Progress;

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

/// Resolves the FMU, its `[animate]` settings (or those of `--experiment FILE`) and the
/// command line into a scene and a grid.
pub fn prepare(options: &Options) -> Result<Animation, String> {
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
    Animation::new(Fmu::load(&target.path)?, &experiment, &options.run, options.speed, options.fps)
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
            short(prepared.timing.frame_step)
        ));
    }
    let trace = prepared.record()?;
    if let Some(reason) = &trace.ended_early {
        // The importer's reason says when.
        eprintln!("{}: the run ended early: {reason}", prepared.fmu.identifier);
    }
    let motion = prepared.scene.motion(&trace)?;
    let frames = prepared.timing.frames(&trace.time);
    let progress = Progress::start(frames.len() as u64, "frames");
    let file = ResultFile::create(&options.out)?;
    let title = &prepared.fmu.description.model_name;
    let (file, written) = animation::write_gif(file, &motion, &frames, title, width, prepared.timing.fps, &mut |done| {
        if interrupt::requested() {
            return Err(format!("interrupted after {done} frames; no file written"));
        }
        progress.inc(1);
        Ok(())
    })?;
    file.commit()?;
    drop(progress);
    println!(
        "wrote {}: {} frames, {}x{} px, {} fps ({} simulated s per frame)",
        options.out.display(),
        written.frames,
        written.size.0,
        written.size.1,
        short(written.fps),
        short(prepared.timing.frame_step)
    );
    Ok(written)
}
