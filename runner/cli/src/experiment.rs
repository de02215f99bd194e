//! Finding the FMU a command names, and the experiment defaults kept as data next to a model
//! (`models/<id>/experiment.toml`), so the runner has no special cases for any model.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::commands::build;
use crate::workspace;
use runner_engine::run::GridSettings;

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
        GridSettings { stop_time: self.stop_time, output_interval: self.output_interval, tolerance: self.tolerance }
    }
}

impl SweepDefaults {
    /// The settings of each run (serde cannot flatten them and still refuse unknown keys).
    pub fn run(&self) -> RunDefaults {
        RunDefaults { stop_time: self.stop_time, output_interval: self.output_interval, tolerance: self.tolerance, set: self.set.clone() }
    }
}

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
}

/// Reads `path` (a missing file means no defaults).
pub fn read(path: &Path) -> Result<Experiment, String> {
    match std::fs::read_to_string(path) {
        Ok(text) => toml::from_str(&text).map_err(|e| format!("{}: {e}", path.display())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Experiment::default()),
        Err(e) => Err(format!("cannot read {}: {e}", path.display())),
    }
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
    let as_path = Path::new(arg);
    let looks_like_path = arg.ends_with(".fmu") || arg.contains(std::path::MAIN_SEPARATOR) || as_path.exists();
    if looks_like_path {
        if !as_path.is_file() {
            return Err(format!("FMU file {arg} does not exist"));
        }
        return Ok(Target { path: as_path.to_path_buf(), experiment: Experiment::default() });
    }
    let root = workspace::root();
    let models = workspace::models(&root)?;
    if !models.iter().any(|m| m == arg) {
        return Err(format!("{arg} is neither an existing .fmu file nor a model of this workspace ({})", models.join(", ")));
    }
    let path = workspace::fmu_path(&root, arg);
    if !path.is_file() {
        eprintln!("{} is missing: building it", path.display());
        build::build(&[arg.to_owned()])?;
    }
    let experiment = read(&root.join("models").join(arg).join("experiment.toml"))?;
    Ok(Target { path, experiment })
}
