//! Where things are: the workspace root, its model crates, and `target/fmu/<id>.fmu`.

use std::path::{Path, PathBuf};

/// The workspace root: the nearest ancestor of the current directory holding `models/` and a
/// workspace `Cargo.toml`, else the one this runner was built from.
pub fn root() -> PathBuf {
    let is_root = |p: &Path| p.join("models").is_dir() && p.join("Cargo.toml").is_file() && p.join("fmu").is_dir();
    if let Ok(cwd) = std::env::current_dir() {
        if let Some(found) = cwd.ancestors().find(|p| is_root(p)) {
            return found.to_path_buf();
        }
    }
    Path::new(env!("CARGO_MANIFEST_DIR")).ancestors().nth(2).expect("runner/cli/ is two levels down").to_path_buf()
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

/// The systems under `systems/`: one folder holding a `SystemStructure.ssd` each.
pub fn systems(root: &Path) -> Result<Vec<String>, String> {
    let dir = root.join("systems");
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .map_err(|e| format!("cannot list {}: {e}", dir.display()))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().join("SystemStructure.ssd").is_file())
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
