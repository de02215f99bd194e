//! What the commands write and show: result files, CSV, progress bars, and the figures the plots
//! crate draws, written where `--plot` says in the format its extension names.

pub mod output;
pub mod partial;
pub mod progress;

use std::path::Path;

use plots::{Drawing, Format};

/// Checks a plot destination before any run: its extension names a format, and its directory
/// exists.
pub fn check_plot(path: &Path) -> Result<Format, String> {
    let format = Format::of(path)?;
    output::check_destination(path)?;
    Ok(format)
}

/// Writes `drawing` to `path` (atomically) in the format its extension names.
pub fn write_plot(path: &Path, drawing: &dyn Drawing) -> Result<(), String> {
    output::write_file(path, &plots::file_bytes(path, drawing)?)
}
