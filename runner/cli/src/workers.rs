//! How the commands start worker processes: the runner's own binary with the hidden `worker`
//! command, and the limits each worker gets; the FMU as a command holds it, and its runs, in
//! this process or in a worker.

use std::path::Path;
use std::time::Duration;

use fmi_importer::{Description, Fmu, Interface, Unpacked, Value, Variable};
use runner_engine::input::InputTable;
use runner_engine::isolation::{Isolation, Runs, WorkerCommand};
use runner_engine::protocol::{FmuSource, RunJob};
use runner_engine::run::{self as sim, Grid, Outcome, Recording, Texts};

use crate::integration::Integration;
use crate::interrupt;

/// The hidden command a worker runs (`runner worker`).
pub const WORKER_COMMAND: &str = "worker";

/// Physical memory in bytes, from /proc/meminfo (`None` if unreadable).
fn physical_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The default memory limit of each of `workers` workers: together three quarters of the
/// machine's memory, so a leaking FMU fails its point before the machine starts to swap.
pub fn default_memory_mib(workers: usize) -> u64 {
    physical_memory().map_or(4096, |bytes| bytes / 4 * 3 / workers.max(1) as u64 / (1 << 20))
}

/// Checks a timeout given in seconds on the command line.
pub fn timeout(option: &str, seconds: Option<f64>) -> Result<Option<Duration>, String> {
    match seconds {
        None => Ok(None),
        Some(s) if s.is_finite() && s > 0.0 && s < 1e9 => Ok(Some(Duration::from_secs_f64(s))),
        Some(s) => Err(format!("{option} {s} must be a positive number of seconds")),
    }
}

/// The isolation of runs in worker processes of this binary.
pub fn isolation(timeout: Option<Duration>, memory_mib: u64) -> Result<Isolation, String> {
    if memory_mib < 64 {
        return Err(format!("--worker-memory {memory_mib} MiB is too little for a worker (at least 64)"));
    }
    let program = std::env::current_exe().map_err(|e| format!("cannot find the runner's own binary to start workers: {e}"))?;
    Ok(Isolation {
        command: WorkerCommand { program, args: vec![WORKER_COMMAND.to_owned()] },
        timeout,
        memory_limit: Some(memory_mib << 20),
    })
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

/// The FMU as a command holds it: loaded for in-process runs, only unpacked and described when
/// workers run it (its binary's initializers then never run in the supervisor).
// One value for the whole command: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
pub enum Held {
    Loaded(Fmu),
    Described(Unpacked),
}

impl Held {
    /// Opens the FMU at `path` through `integration`'s interface: loaded here when `in_process`,
    /// else only described; returns it with the source its workers load (this copy).
    pub fn open(path: &Path, integration: &Integration, in_process: bool) -> Result<(Held, FmuSource), String> {
        let source = FmuSource::new(path, integration.interface);
        let (held, source) = match in_process {
            true => (Held::Loaded(source.load()?), source),
            false => source.open().map(|(unpacked, for_workers)| (Held::Described(unpacked), for_workers))?,
        };
        integration.check(held.description(), held.identifier(), held.interface())?;
        Ok((held, source))
    }

    pub fn description(&self) -> &Description {
        match self {
            Held::Loaded(f) => &f.description,
            Held::Described(u) => &u.description,
        }
    }

    pub fn identifier(&self) -> &str {
        match self {
            Held::Loaded(f) => &f.identifier,
            Held::Described(u) => &u.identifier,
        }
    }

    pub fn interface(&self) -> Interface {
        match self {
            Held::Loaded(f) => f.interface,
            Held::Described(u) => u.interface,
        }
    }
}

/// Where a command's runs happen, one after another: in this process, or in a worker process
/// (replaced after a crash).
pub enum Executor<'a> {
    InProcess(&'a Fmu),
    Workers(Runs<'a>),
}

impl<'a> Executor<'a> {
    /// Runs on `held`: in this process when it is loaded, else in workers started from `source`.
    pub fn new(held: &'a Held, config: &'a Isolation, source: &'a FmuSource) -> Executor<'a> {
        match held {
            Held::Loaded(fmu) => Executor::InProcess(fmu),
            Held::Described(u) => {
                Executor::Workers(Runs::new(config, source, runner_engine::isolation::once_per_process(&u.description, u.interface)))
            }
        }
    }

    /// One run of `recording` as [`sim::run_recording`] makes it, wherever the runs happen.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        &mut self,
        description: &Description,
        name: &str,
        grid: &Grid,
        assignments: &[(&Variable, Value)],
        recording: &Recording,
        debug_logging: bool,
        sample: impl FnMut(f64, &[f64], &dyn Texts) -> Result<(), String>,
    ) -> Result<Outcome, String> {
        self.run_with_inputs(description, name, grid, assignments, None, recording, debug_logging, sample)
    }

    /// [`Executor::run`] with `inputs` set before every step (`--input-file`).
    #[allow(clippy::too_many_arguments)]
    pub fn run_with_inputs(
        &mut self,
        description: &Description,
        name: &str,
        grid: &Grid,
        assignments: &[(&Variable, Value)],
        inputs: Option<&InputTable>,
        recording: &Recording,
        debug_logging: bool,
        sample: impl FnMut(f64, &[f64], &dyn Texts) -> Result<(), String>,
    ) -> Result<Outcome, String> {
        match self {
            Executor::InProcess(fmu) => {
                let bound = inputs.map(|table| table.bind(&fmu.description, fmu.interface)).transpose()?;
                sim::run_with_inputs(fmu, name, grid, assignments, bound.as_ref(), recording, debug_logging, sample)
            }
            Executor::Workers(runs) => {
                let job = RunJob::new(name, *grid, assignments, recording, debug_logging).with_inputs(inputs.cloned());
                runs.run(description, &job, &interrupt::requested, sample)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_lines_are_quoted_for_the_shell() {
        let args: Vec<String> = ["runner", "sweep", "m=max(x)/2", "a b", "it's"].map(String::from).to_vec();
        assert_eq!(shell_line(&args), r"runner sweep 'm=max(x)/2' 'a b' 'it'\''s'");
    }

    #[test]
    fn timeouts_must_be_positive() {
        assert_eq!(timeout("--timeout", Some(0.5)).unwrap(), Some(Duration::from_millis(500)));
        assert!(timeout("--timeout", Some(0.0)).unwrap_err().contains("--timeout 0 must be a positive"));
        assert!(timeout("--timeout", Some(f64::NAN)).is_err());
    }
}
