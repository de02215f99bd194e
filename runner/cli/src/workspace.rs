//! Where things are: the workspace root, its model crates, and `target/fmu/<id>.fmu` (shared
//! with the Python package in the runner-workspace crate).

pub use runner_workspace::{fmu_path, models, root, target_dir};
use std::path::{Path, PathBuf};

/// Where `runner build` writes model `id`'s FMI 3.0 FMU.
pub fn fmu3_path(root: &Path, id: &str) -> PathBuf {
    target_dir(root).join("fmu3").join(format!("{id}.fmu"))
}
