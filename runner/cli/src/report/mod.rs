//! What the commands write and show: result files, CSV, plots and figures (SVG, PNG),
//! animations (GIF), progress bars.

pub mod figure;
pub mod fonts;
pub mod gif;
pub mod output;
pub mod partial;
pub mod plot;
pub mod progress;
pub mod scene;
