//! Finding the FMU a command names, and the experiment defaults kept as data next to a model
//! (`models/<id>/experiment.toml`), so the runner has no special cases for any model.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::commands::build;
use runner_workspace::Located;
pub use runner_workspace::{RunDefaults, SweepDefaults};

/// `[compare]`: the closed-form solution `runner compare` measures errors against.
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompareDefaults {
    /// `NAME=VALUE` assignments the reference holds for, applied to every run of the comparison.
    #[serde(default)]
    pub set: Vec<String>,
    /// Output name to its exact solution: an expression of `t` and the FMU's parameters.
    #[serde(default)]
    pub reference: BTreeMap<String, String>,
}

/// A coordinate of a point defined in `[animate.points]`: a number (m) or an expression of
/// the FMU's variables (parameters and outputs, and `t`).
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum Coordinate {
    Number(f64),
    Expression(String),
}

impl Coordinate {
    /// The expression text (a number as written).
    pub fn text(&self) -> String {
        match self {
            Coordinate::Number(x) => format!("{x:?}"),
            Coordinate::Expression(e) => e.clone(),
        }
    }
}

/// Points drawn together: a chain of point names, optionally only while a condition holds.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum PointsSpec {
    /// `["O", "A", "B"]`.
    Always(Vec<String>),
    /// `{ points = ["D", "E"], when = "regime < 4" }`.
    When(PointsWhen),
}

/// A chain of points drawn while `when` holds.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointsWhen {
    pub points: Vec<String>,
    /// A comparison `EXPR OP EXPR` (OP one of < <= > >= == !=) of variables and `t`.
    pub when: String,
}

/// A point whose path is drawn, optionally only while a condition holds.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum TrailSpec {
    /// `"A"`.
    Always(String),
    /// `{ point = "E", when = "t > 0.5" }`.
    When(TrailWhen),
}

/// A trail drawn while `when` holds.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrailWhen {
    pub point: String,
    pub when: String,
}

/// `follow`: the frame keeps `point` in view while `when` holds (the projectile in flight).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FollowSpec {
    pub point: String,
    /// Condition; absent: always.
    pub when: Option<String>,
}

/// `[animate]`: how `runner animate` (and the handbook's mechanism figures) draw a model whose
/// outputs include point coordinates `<P>_x`, `<P>_y`.
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnimateDefaults {
    /// Stop time (s).
    pub stop_time: Option<f64>,
    /// Output interval (s): the samples trails are drawn through, one frame each at `speed`.
    pub output_interval: Option<f64>,
    /// Relative tolerance.
    pub tolerance: Option<f64>,
    /// `NAME=VALUE` assignments.
    #[serde(default)]
    pub set: Vec<String>,
    /// Frames per second of the GIF (default: `speed` / output interval, at most 50).
    pub fps: Option<f64>,
    /// Simulated seconds per second of playback (default 1, real time; 0.25 is slow motion).
    pub speed: Option<f64>,
    /// Width of the GIF in pixels (default 640; the height follows the scene, at least 480).
    pub size: Option<u32>,
    /// Points defined by expressions, `NAME = [X, Y]` (m): ground pivots, or points the FMU
    /// does not output. Points named in `links`/`trails` and not defined here are the FMU's
    /// `<NAME>_x`, `<NAME>_y` outputs.
    #[serde(default)]
    pub points: BTreeMap<String, [Coordinate; 2]>,
    /// Links, each drawn as a bar through its points.
    #[serde(default)]
    pub links: Vec<PointsSpec>,
    /// Points whose paths are drawn.
    #[serde(default)]
    pub trails: Vec<TrailSpec>,
    /// Heights (m, numbers or expressions of parameters) of horizontal lines: the ground, a
    /// slider's guide.
    #[serde(default)]
    pub levels: Vec<Coordinate>,
    /// The frame follows a point (default: one fixed frame that holds the whole motion).
    pub follow: Option<FollowSpec>,
    /// Variables whose values are shown beside the time stamp, e.g. `["regime"]`.
    #[serde(default)]
    pub show: Vec<String>,
}

impl AnimateDefaults {
    /// The settings of the run.
    pub fn run(&self) -> RunDefaults {
        RunDefaults { stop_time: self.stop_time, output_interval: self.output_interval, tolerance: self.tolerance, set: self.set.clone() }
    }
}

/// The whole `experiment.toml`.
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiment {
    /// Defaults of `runner simulate`.
    #[serde(default)]
    pub simulate: RunDefaults,
    /// Defaults of `runner sweep`.
    #[serde(default)]
    pub sweep: SweepDefaults,
    /// The analytical reference of `runner compare`.
    #[serde(default)]
    pub compare: CompareDefaults,
    /// How `runner animate` draws the model.
    #[serde(default)]
    pub animate: AnimateDefaults,
}

/// Reads `path` (a missing file means no defaults).
pub fn read(path: &Path) -> Result<Experiment, String> {
    runner_workspace::read(path)
}

/// The FMU a command was given: its file and, for a model named by identifier, its defaults.
pub struct Target {
    /// The `.fmu` file.
    pub path: PathBuf,
    /// `experiment.toml` of the model, or empty defaults for an FMU given by path.
    pub experiment: Experiment,
}

/// Resolves `FMU`: an existing file or anything that looks like a path is a file; otherwise a
/// model identifier, whose `target/fmu/<id>.fmu` is built first if it is missing.
pub fn resolve(arg: &str) -> Result<Target, String> {
    match runner_workspace::locate(arg)? {
        Located::File(path) => Ok(Target { path, experiment: Experiment::default() }),
        Located::Model { id, fmu: path, experiment } => {
            if !path.is_file() {
                eprintln!("{} is missing: building it", path.display());
                build::build(&[id])?;
            }
            Ok(Target { path, experiment: read(&experiment)? })
        }
    }
}
