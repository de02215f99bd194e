//! How the commands run FMUs in worker processes: the runner's own binary with the hidden
//! `worker` command, and the limits each worker gets; the FMU as a command opens it.

use std::path::Path;
use std::time::Duration;

use fmi_importer::call_log::CallLogTarget;
use fmi_importer::{Description, Interface};
use runner_engine::exec::Held;
use runner_engine::input::InputTable;
use runner_engine::isolated;
use runner_engine::request::FmuSource;
use runner_sandbox::{Config, WorkerCommand};

use crate::integration::Integration;

/// The hidden command a worker runs (`runner worker`).
pub const WORKER_COMMAND: &str = "worker";

/// The sandbox of runs in worker processes of this binary: each run or point stopped after
/// `timeout`, each worker limited to `memory_mib` MiB.
pub fn isolation(timeout: Option<Duration>, memory_mib: u64) -> Result<Config, String> {
    isolated::config(WorkerCommand::this_program(&[WORKER_COMMAND])?, timeout, memory_mib)
}

/// Opens the FMU at `path` through `integration`'s interface: loaded here when `in_process`,
/// else only described; returns it with the source its workers load (this copy).
pub fn open(path: &Path, integration: &Integration, in_process: bool) -> Result<(Held, FmuSource), String> {
    let (held, source) = Held::open(&FmuSource::new(path, integration.interface), in_process)?;
    integration.check(held.description(), held.identifier(), held.interface())?;
    Ok((held, source))
}

/// Creates (empties) the `--log-fmi-calls` file, so one that cannot be written is refused before
/// any run; the runs, here or in workers, then append to it.
pub fn create_call_log(target: Option<&CallLogTarget>) -> Result<(), String> {
    match target {
        Some(CallLogTarget::File(path)) => fmi_importer::call_log::create(path),
        _ => Ok(()),
    }
}

/// Reads `--input-file FILE.csv` and checks it against the FMU `description` run through
/// `interface`, so a bad file is refused before any run.
pub fn input_file(path: Option<&Path>, description: &Description, interface: Interface) -> Result<Option<InputTable>, String> {
    let Some(path) = path else { return Ok(None) };
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read the input file {}: {e}", path.display()))?;
    let table = InputTable::from_csv(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    table.bind(description, interface).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(Some(table))
}

/// A shell-quoted command line (for "continue with: ..." messages).
pub fn shell_line(args: &[String]) -> String {
    args.iter()
        .map(|a| {
            if !a.is_empty() && a.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c)) {
                a.clone()
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_lines_are_quoted_for_the_shell() {
        let args: Vec<String> = ["runner", "sweep", "m=max(x)/2", "a b", "it's"].map(String::from).to_vec();
        assert_eq!(shell_line(&args), r"runner sweep 'm=max(x)/2' 'a b' 'it'\''s'");
    }
}
