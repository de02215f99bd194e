//! Formulas as text, evaluated the same way wherever they are read: sweep metrics
//! (`transmissibility=max(z_s)/max(z_r)`, [`metrics::Metrics`]), closed-form expressions of
//! time and parameters (`2*exp(-3*t)`, [`metrics::Formula`]), and the models' tables of closed
//! forms (`references.toml`, [`references::References`]). The models' tests, the runner's
//! engine and `runner handbook` share it; tests/fmpy/closed_form.py follows the same rules in
//! Python. It knows nothing of FMI.

pub mod metrics;
pub mod references;

pub use metrics::{Formula, Metrics};
pub use references::References;
