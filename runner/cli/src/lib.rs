//! The `runner` command line: the commands (build, info, simulate, sweep, compare, validate) over the
//! engine, and the reporting they share (CSV, plots, progress, result files that appear only
//! when complete). `main.rs` is only the argument parser.

pub mod commands;
pub mod experiment;
pub mod integration;
pub mod interrupt;
pub mod reference;
pub mod report;
pub mod workers;
pub mod workspace;
