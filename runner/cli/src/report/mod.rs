//! What the commands write and show: result files, CSV, SVG plots, progress bars.

pub mod output;
pub mod partial;
pub mod plot;
pub mod progress;
