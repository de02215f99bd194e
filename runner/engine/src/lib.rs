//! The runner's engine: requests ([`request`]: a run, a sweep, as data) and where they run
//! ([`exec`]: in this process, or in worker processes through the sandbox, [`isolated`]); one
//! simulation run ([`run`]), with inputs from a table ([`input`]); parameter sweeps ([`sweep`]);
//! linearization of Model Exchange FMUs, their modes and frequency responses ([`linear`]);
//! per-run metrics ([`metrics`], whose grammar is the formulas crate's); a sweep's CSV on file
//! and its resume, as the command line and the Python package share them ([`partial`]); and the lookup of
//! variables by name with values parsed to their types ([`variables`]). It drives FMUs through the
//! importer and knows nothing of our models.

pub mod exec;
pub mod input;
pub mod isolated;
pub mod linear;
pub mod metrics;
pub mod partial;
pub mod request;
pub mod run;
pub mod stepping;
pub mod sweep;
pub mod variables;

/// Prints a note for the user (a point that ended early) where FMU log lines go.
pub(crate) fn note(line: &str) {
    fmi_importer::print_line(line);
}
