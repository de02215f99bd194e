//! This workspace's models by name: the workspace root, its model crates, where `runner build`
//! writes each model's FMU, and the run defaults kept as data next to each model
//! (`models/<id>/experiment.toml`). The runner's commands and the Python package both resolve a
//! command's FMU argument here, so a model name means the same FMU and the same defaults in both.

use std::path::{Path, PathBuf};

pub mod experiment;

pub use experiment::Experiment;

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
}
