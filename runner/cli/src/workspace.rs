//! Where things are: the workspace root, its model crates, and `target/fmu/<id>.fmu` (shared
//! with the Python package in the runner-workspace crate).

pub use runner_workspace::{fmu_path, models, root, target_dir};
use std::path::{Path, PathBuf};

/// Where `runner build` writes model `id`'s FMI 3.0 FMU.
pub fn fmu3_path(root: &Path, id: &str) -> PathBuf {
    target_dir(root).join("fmu3").join(format!("{id}.fmu"))
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
