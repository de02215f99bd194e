//! What the commands write and show: result files, CSV, plots and figures (SVG, PNG),
//! progress bars.

pub mod figure;
pub mod fonts;
pub mod output;
pub mod plot;
pub mod progress;
