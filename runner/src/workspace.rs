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
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("runner/ has a parent").to_path_buf()
}

/// The model identifiers: one crate per directory under `models/`.
pub fn models(root: &Path) -> Result<Vec<String>, String> {
    let dir = root.join("models");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .map_err(|e| format!("cannot list {}: {e}", dir.display()))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().join("Cargo.toml").is_file())
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
