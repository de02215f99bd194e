//! Where things are: the workspace root, its model crates, and `target/fmu/<id>.fmu` (shared
//! with the Python package in the runner-workspace crate).

pub use runner_workspace::{fmu_path, models, root, target_dir};
