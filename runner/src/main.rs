//! `runner`: builds, inspects, simulates, sweeps and compares FMI 2.0 Co-Simulation FMUs.

mod archive;
mod library;
mod package;
mod workspace;

use clap::{Parser, Subcommand};

/// Build and run FMI 2.0 Co-Simulation FMUs.
#[derive(Parser)]
#[command(name = "runner", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Build model crates in release mode and pack target/fmu/<MODEL>.fmu.
    ///
    /// Example: `runner build quarter_car pendulum` (no MODEL: every crate under models/).
    Build {
        /// Model identifiers (crate names under models/).
        models: Vec<String>,
    },
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Cmd::Build { models } => package::build(&models).map(|paths| {
            for p in paths {
                println!("{}", p.display());
            }
        }),
    };
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
