//! Finding the FMU a command names, with the experiment defaults kept as data next to a model
//! (`models/<id>/experiment.toml`, read by runner-workspace), so the runner has no special
//! cases for any model.

use std::path::PathBuf;

use crate::commands::build;
pub use runner_workspace::experiment::{read, AnimateDefaults, Experiment, RunDefaults, SweepDefaults};
use runner_workspace::Located;

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
