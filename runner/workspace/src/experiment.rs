//! `experiment.toml`, the run defaults kept as data next to each model (`models/<id>/experiment.toml`,
//! or a file given with `--experiment`): `[simulate]`, `[sweep]`, `[compare]` (a closed-form
//! reference) and `[animate]` (how a mechanism is drawn). This module is the file's one reader:
//! the runner's commands, `runner handbook` and the Python package all parse it here, and a key
//! that is not one of these is refused naming the file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use runner_engine::run::GridSettings;
use serde::Deserialize;

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

/// `[reference]`: the reference result `runner build` ships in the FMI 3.0 FMU (FMI-LS-REF).
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceDefaults {
    /// Outputs left out of it: diagnostics whose values are rounding noise (a loop closure's
    /// residual, ~1e-17 m), which no run reproduces within any relative tube.
    #[serde(default)]
    pub omit: Vec<String>,
}

/// A coordinate of a point defined in `[animate.points]`: a number (m) or an expression of
/// the FMU's variables (parameters and outputs, and `t`).
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum Coordinate {
    /// A fixed value (m).
    Number(f64),
    /// An expression of the FMU's variables and `t`.
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
    /// The chain of points, drawn as one bar.
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
    /// The point whose path is drawn.
    pub point: String,
    /// A comparison `EXPR OP EXPR`, as in [`PointsWhen::when`].
    pub when: String,
}

/// `follow`: the frame keeps `point` in view while `when` holds (the projectile in flight).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FollowSpec {
    /// The point kept in view.
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
    /// What the shipped reference result leaves out.
    #[serde(default)]
    pub reference: ReferenceDefaults,
}

/// Settings shared by `simulate` and `sweep`; each is overridden by its command-line option.
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunDefaults {
    /// Stop time (s).
    pub stop_time: Option<f64>,
    /// Communication (output) interval (s).
    pub output_interval: Option<f64>,
    /// Relative tolerance passed to fmi2SetupExperiment.
    pub tolerance: Option<f64>,
    /// `NAME=VALUE` assignments applied before initialization.
    #[serde(default)]
    pub set: Vec<String>,
}

/// `[sweep]`: the sweep a model is known for.
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepDefaults {
    /// Stop time (s) of each run.
    pub stop_time: Option<f64>,
    /// Communication (output) interval (s).
    pub output_interval: Option<f64>,
    /// Relative tolerance.
    pub tolerance: Option<f64>,
    /// `NAME=VALUE` assignments common to every point.
    #[serde(default)]
    pub set: Vec<String>,
    /// `NAME=START:STOP:STEP` or `NAME=V1,V2,...` ranges (their cartesian product).
    #[serde(default)]
    pub param: Vec<String>,
    /// `NAME=EXPR` metrics.
    #[serde(default)]
    pub metric: Vec<String>,
    /// CSV file written when `--out` is not given.
    pub out: Option<PathBuf>,
    /// SVG plot written when `--plot` is not given.
    pub plot: Option<PathBuf>,
}

impl RunDefaults {
    /// The grid part of these settings.
    pub fn grid(&self) -> GridSettings {
        GridSettings { start_time: None, stop_time: self.stop_time, output_interval: self.output_interval, tolerance: self.tolerance }
    }
}

impl SweepDefaults {
    /// The settings of each run (serde cannot flatten them and still refuse unknown keys).
    pub fn run(&self) -> RunDefaults {
        RunDefaults { stop_time: self.stop_time, output_interval: self.output_interval, tolerance: self.tolerance, set: self.set.clone() }
    }
}

/// Reads the text of the experiment file `path`: `None` when there is none.
fn read_text(path: &Path) -> Result<Option<String>, String> {
    match std::fs::read_to_string(path) {
        Ok(text) => Ok(Some(text)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(format!("cannot read {}: {e}", path.display())),
    }
}

/// Reads the experiment file `path` (a missing file means no defaults).
pub fn read(path: &Path) -> Result<Experiment, String> {
    match read_text(path)? {
        Some(text) => toml::from_str(&text).map_err(|e| format!("{}: {e}", path.display())),
        None => Ok(Experiment::default()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The run sections are read from a file that also has the commands' own sections, and a
    /// typo inside them is refused with the file's name.
    #[test]
    fn run_sections_are_read_and_checked() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("experiment.toml");
        std::fs::write(&path, "[simulate]\nstop_time = 2.5\n[sweep]\nparam = [\"k=1,2\"]\ntolerance = 1e-9\n[animate]\nspeed = 0.5\n")
            .unwrap();
        let sections = read(&path).unwrap();
        assert_eq!(sections.simulate.stop_time, Some(2.5));
        assert_eq!(sections.sweep.param, ["k=1,2"]);
        assert_eq!(sections.sweep.run().grid().tolerance, Some(1e-9));
        std::fs::write(&path, "[simulate]\nstop_tim = 2.5\n").unwrap();
        let err = read(&path).unwrap_err();
        assert!(err.contains("experiment.toml") && err.contains("stop_tim"), "{err}");
        let none = read(&dir.path().join("absent.toml")).unwrap();
        assert!(none.simulate.stop_time.is_none());
    }
}
