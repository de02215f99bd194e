//! `runner handbook --out DIR`: the lab handbook's figures and numbers (the handbook crate's
//! content), with the FMUs it needs built first when missing, every file put in place whole,
//! a progress bar, and Ctrl-C honoured between exercises and GIF frames.

use std::path::Path;

pub use handbook::Options;
use handbook::{Built, Host};

use crate::commands::build;
use crate::interrupt;
use crate::report::output;
use crate::report::progress::Progress;

/// What the handbook writes through: atomic result files, the user's Ctrl-C, a progress bar.
struct Cli {
    progress: Progress,
}

impl Host for Cli {
    fn write(&self, path: &Path, bytes: &[u8]) -> Result<(), String> {
        output::write_file(path, bytes)
    }

    fn interrupted(&self) -> bool {
        interrupt::requested()
    }

    fn exercise_done(&self) {
        self.progress.inc(1);
    }
}

/// Runs `runner handbook`.
pub fn run(options: &Options) -> Result<Built, String> {
    let missing = handbook::missing_fmus();
    if !missing.is_empty() {
        eprintln!("building the FMUs the handbook needs: {}", missing.join(", "));
        build::build(&missing)?;
    }
    let cli = Cli { progress: Progress::start(handbook::EXERCISES as u64, "exercises") };
    let built = handbook::write(options, &cli)?;
    drop(cli);
    println!("wrote {} figures, index.html and summary.json to {} in {:.1} s", built.files.len() - 2, options.out.display(), built.seconds);
    Ok(built)
}
