//! The runner's engine: one simulation run ([`run`]), with inputs from a table ([`input`]), parameter sweeps on a thread pool
//! ([`sweep`]) or in worker processes ([`isolation`], with the worker's side in [`worker`] and
//! their messages in [`protocol`]), per-run metrics and closed-form formulas ([`metrics`]; named tables of them, the models'
//! references.toml, in [`references`]), and
//! the lookup of variables by name with values parsed to their types ([`variables`]). It drives
//! FMUs through the importer and knows nothing of our models.

pub mod input;
pub mod isolation;
pub mod metrics;
pub mod protocol;
pub mod references;
pub mod run;
pub mod sweep;
pub mod variables;
pub mod worker;

/// Prints a note for the user (a point that ended early) where FMU log lines go.
pub(crate) fn note(line: &str) {
    fmi_importer::print_line(line);
}
