//! This workspace's models by name: the workspace root, its model crates, where `runner build`
//! writes each model's FMU, and the run defaults kept as data next to each model
//! (`models/<id>/experiment.toml`). The runner's commands and the Python package both resolve a
//! command's FMU argument here, so a model name means the same FMU and the same defaults in both.

use std::path::{Path, PathBuf};

use runner_engine::run::GridSettings;
use serde::Deserialize;

/// The workspace root: the nearest ancestor of the current directory holding `models/` and a
/// workspace `Cargo.toml`, else the one this crate was built from.
pub fn root() -> PathBuf {
    let is_root = |p: &Path| p.join("models").is_dir() && p.join("Cargo.toml").is_file() && p.join("fmu").is_dir();
    if let Ok(cwd) = std::env::current_dir() {
        if let Some(found) = cwd.ancestors().find(|p| is_root(p)) {
            return found.to_path_buf();
        }
    }
    Path::new(env!("CARGO_MANIFEST_DIR")).ancestors().nth(2).expect("runner/workspace/ is two levels down").to_path_buf()
}

/// True when the crate at `dir` builds an FMU (a `cdylib`), not a library the models share.
fn is_model_crate(dir: &Path) -> bool {
    std::fs::read_to_string(dir.join("Cargo.toml")).is_ok_and(|text| text.contains("\"cdylib\""))
}

/// The model identifiers: one crate per directory under `models/` that builds an FMU.
pub fn models(root: &Path) -> Result<Vec<String>, String> {
    let dir = root.join("models");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .map_err(|e| format!("cannot list {}: {e}", dir.display()))?
        .filter_map(|e| e.ok())
        .filter(|e| is_model_crate(&e.path()))
        .filter_map(|e| e.file_name().to_str().map(str::to_owned))
        .collect();
    names.sort();
    Ok(names)
}

/// Cargo's target directory for this workspace.
pub fn target_dir(root: &Path) -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|| root.join("target"))
}

/// Where `runner build` writes the FMU of model `id`.
pub fn fmu_path(root: &Path, id: &str) -> PathBuf {
    target_dir(root).join("fmu").join(format!("{id}.fmu"))
}

/// What a command's FMU argument names.
#[derive(Debug, Clone, PartialEq)]
pub enum Located {
    /// An `.fmu` file given by its path (it exists).
    File(PathBuf),
    /// A model of this workspace.
    Model {
        /// The model identifier, e.g. `quarter_car`.
        id: String,
        /// Its FMU, `target/fmu/<id>.fmu`, which may not be built yet.
        fmu: PathBuf,
        /// Its experiment defaults, `models/<id>/experiment.toml` (a missing file means none).
        experiment: PathBuf,
    },
}

/// Resolves `arg`: an existing file or anything that looks like a path is a file; otherwise a
/// model identifier of this workspace.
pub fn locate(arg: &str) -> Result<Located, String> {
    let as_path = Path::new(arg);
    let looks_like_path = arg.ends_with(".fmu") || arg.contains(std::path::MAIN_SEPARATOR) || as_path.exists();
    if looks_like_path {
        if !as_path.is_file() {
            return Err(format!("FMU file {arg} does not exist"));
        }
        return Ok(Located::File(as_path.to_path_buf()));
    }
    let root = root();
    let models = models(&root)?;
    if !models.iter().any(|m| m == arg) {
        return Err(format!("{arg} is neither an existing .fmu file nor a model of this workspace ({})", models.join(", ")));
    }
    Ok(Located::Model { id: arg.to_owned(), fmu: fmu_path(&root, arg), experiment: root.join("models").join(arg).join("experiment.toml") })
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
        GridSettings { stop_time: self.stop_time, output_interval: self.output_interval, tolerance: self.tolerance }
    }
}

impl SweepDefaults {
    /// The settings of each run (serde cannot flatten them and still refuse unknown keys).
    pub fn run(&self) -> RunDefaults {
        RunDefaults { stop_time: self.stop_time, output_interval: self.output_interval, tolerance: self.tolerance, set: self.set.clone() }
    }
}

/// The `[simulate]` and `[sweep]` sections of an experiment file; its other sections belong to
/// the runner's own commands (compare, animate), which read the whole file.
#[derive(Debug, Default, Clone, Deserialize)]
pub struct RunSections {
    /// Defaults of a single run.
    #[serde(default)]
    pub simulate: RunDefaults,
    /// Defaults of a sweep.
    #[serde(default)]
    pub sweep: SweepDefaults,
}

/// Reads the text of the experiment file `path`: `None` when there is none.
pub fn read_text(path: &Path) -> Result<Option<String>, String> {
    match std::fs::read_to_string(path) {
        Ok(text) => Ok(Some(text)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(format!("cannot read {}: {e}", path.display())),
    }
}

/// Parses the experiment file `path` into `T` (a missing file gives `T`'s defaults).
pub fn read<T: Default + serde::de::DeserializeOwned>(path: &Path) -> Result<T, String> {
    match read_text(path)? {
        Some(text) => toml::from_str(&text).map_err(|e| format!("{}: {e}", path.display())),
        None => Ok(T::default()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every model of the workspace resolves to its FMU under target/fmu and its experiment
    /// file; a path resolves to itself; anything else is refused with the model names.
    #[test]
    fn names_resolve_to_models_and_paths_to_files() {
        let root = root();
        match locate("quarter_car").unwrap() {
            Located::Model { id, fmu, experiment } => {
                assert_eq!(id, "quarter_car");
                assert_eq!(fmu, fmu_path(&root, "quarter_car"));
                assert!(experiment.is_file(), "{}", experiment.display());
            }
            other => panic!("{other:?}"),
        }
        let err = locate("quater_car").unwrap_err();
        assert!(err.contains("neither an existing .fmu file nor a model") && err.contains("quarter_car"), "{err}");
        assert!(locate("missing/thing.fmu").unwrap_err().contains("FMU file missing/thing.fmu does not exist"));
        let file = tempfile::Builder::new().suffix(".fmu").tempfile().unwrap();
        let path = file.path().to_str().unwrap();
        assert_eq!(locate(path).unwrap(), Located::File(file.path().to_path_buf()));
        assert!(!models(&root).unwrap().contains(&"linkages".to_owned()), "a shared library crate is no model");
    }

    /// The run sections are read from a file that also has the commands' own sections, and a
    /// typo inside them is refused with the file's name.
    #[test]
    fn run_sections_are_read_and_checked() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("experiment.toml");
        std::fs::write(&path, "[simulate]\nstop_time = 2.5\n[sweep]\nparam = [\"k=1,2\"]\ntolerance = 1e-9\n[animate]\nspeed = 0.5\n")
            .unwrap();
        let sections: RunSections = read(&path).unwrap();
        assert_eq!(sections.simulate.stop_time, Some(2.5));
        assert_eq!(sections.sweep.param, ["k=1,2"]);
        assert_eq!(sections.sweep.run().grid().tolerance, Some(1e-9));
        std::fs::write(&path, "[simulate]\nstop_tim = 2.5\n").unwrap();
        let err = read::<RunSections>(&path).unwrap_err();
        assert!(err.contains("experiment.toml") && err.contains("stop_tim"), "{err}");
        let none: RunSections = read(&dir.path().join("absent.toml")).unwrap();
        assert!(none.simulate.stop_time.is_none());
    }
}
