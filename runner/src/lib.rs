//! The `runner` library: the FMU importer (safe unzip, dlopen, FMI calls) and the commands
//! built on it. `main.rs` is only the command-line parser.

pub mod archive;
pub mod compare;
pub mod experiment;
pub mod fmi;
pub mod info;
pub mod interrupt;
pub mod library;
pub mod metrics;
pub mod output;
pub mod package;
pub mod plot;
pub mod progress;
pub mod sim;
pub mod simulate;
pub mod sweep;
pub mod variables;
pub mod workspace;
