//! The runner's engine: one simulation run ([`run`]), parameter sweeps on a thread pool
//! ([`sweep`]), per-run metrics and closed-form formulas ([`metrics`]), and the lookup of
//! variables by name with values parsed to their types ([`variables`]). It drives FMUs through
//! the importer and knows nothing of our models.

pub mod metrics;
pub mod run;
pub mod sweep;
pub mod variables;

/// Prints a note for the user (a point that ended early) where FMU log lines go.
pub(crate) fn note(line: &str) {
    fmi_importer::print_line(line);
}
