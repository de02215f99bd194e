//! `runner`: builds, inspects, simulates, sweeps, compares and validates FMI 2.0 FMUs.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

use runner::commands::{build, compare, info, simulate, sweep, validate};
use runner::experiment::{self, RunDefaults};
use runner::interrupt;
use runner::report::progress;

/// Build and run FMI 2.0 Co-Simulation FMUs.
#[derive(Parser)]
#[command(name = "runner", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

/// Options of every run; unset ones come from the model's experiment.toml, then the FMU's
/// DefaultExperiment.
#[derive(Args)]
struct RunArgs {
    // Numbers may be negative on the command line, so that `--tolerance -1` is refused by the
    // check that explains why, not taken for an unknown option.
    /// Stop time in seconds.
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    stop_time: Option<f64>,
    /// Communication (output) interval in seconds: one CSV row per interval.
    #[arg(long, value_name = "H", allow_negative_numbers = true)]
    output_interval: Option<f64>,
    /// Relative tolerance given to fmi2SetupExperiment.
    #[arg(long, value_name = "R", allow_negative_numbers = true)]
    tolerance: Option<f64>,
    /// Set a parameter or input before initialization (SI units); repeatable.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
}

impl RunArgs {
    fn defaults(self) -> RunDefaults {
        RunDefaults { stop_time: self.stop_time, output_interval: self.output_interval, tolerance: self.tolerance, set: self.set }
    }
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
    /// Show an FMU's variables (causality, type, unit, start value) and capabilities.
    ///
    /// FMU is a path to any .fmu file, or a model name of this workspace (built if missing).
    ///
    /// Example: `runner info quarter_car`
    Info {
        /// Model name or path to a .fmu file.
        fmu: String,
    },
    /// Simulate an FMU and write time and its outputs as CSV (fmpy's layout).
    ///
    /// Without --out the CSV goes to stdout. A model that ends the run early (fmi2Discard and
    /// terminated) keeps the rows up to there and the reason is printed on stderr.
    ///
    /// Example: `runner simulate quarter_car --stop-time 5 --set speed=12 --out qc.csv --plot qc.svg`
    Simulate {
        /// Model name or path to a .fmu file.
        fmu: String,
        #[command(flatten)]
        run: RunArgs,
        /// Write the CSV here instead of stdout.
        #[arg(long, value_name = "FILE.csv")]
        out: Option<PathBuf>,
        /// Plot the outputs against time into this SVG file.
        #[arg(long, value_name = "FILE.svg")]
        plot: Option<PathBuf>,
        /// Turn on the FMU's debug logging (messages go to stderr with the instance name).
        #[arg(long)]
        log: bool,
    },
    /// Run a parameter sweep: one FMU instance per point, in parallel; metrics per point as CSV.
    ///
    /// Every --param adds a dimension; the points are the cartesian product (the last --param
    /// varies fastest). A metric is NAME=EXPR over per-run summaries (max, min, final, mean,
    /// peak_to_peak, rms) of any variable, optionally from a time on as in max(x, 5), combined
    /// with the operators `+ - * / ^`, parentheses and the functions exp, log, sqrt, sin, cos,
    /// tan, atan, abs. The CSV has one row per point: parameters,
    /// metrics, status (`ok` or the error). Failed points are recorded and the others still
    /// run; the exit code is 1 if any failed. With a model name and no options, the model's
    /// experiment.toml gives the sweep.
    ///
    /// Example: `runner sweep quarter_car` (handbook Ex. 4: transmissibility against speed)
    ///
    /// Example: `runner sweep quarter_car --param speed=5:30:5 --param b_s=800,1300 --metric 'transmissibility=max(z_s)/max(z_r)' --threads 2 --out t.csv --plot t.svg`
    Sweep {
        /// Model name or path to a .fmu file.
        fmu: String,
        /// A swept parameter: NAME=START:STOP:STEP (inclusive) or NAME=V1,V2,...; repeatable.
        #[arg(long = "param", value_name = "NAME=RANGE")]
        params: Vec<String>,
        /// A metric NAME=EXPR, e.g. 'transmissibility=max(z_s)/max(z_r)'; repeatable.
        #[arg(long = "metric", value_name = "NAME=EXPR")]
        metrics: Vec<String>,
        /// Worker threads (default: one per core); results do not depend on it.
        #[arg(long, value_name = "N", allow_negative_numbers = true)]
        threads: Option<usize>,
        #[command(flatten)]
        run: RunArgs,
        /// Write the CSV here (default: experiment.toml's, else stdout).
        #[arg(long, value_name = "FILE.csv")]
        out: Option<PathBuf>,
        /// Plot each metric against the first parameter into this SVG file, peaks marked
        /// (default: experiment.toml's, unless --out names the CSV).
        #[arg(long, value_name = "FILE.svg")]
        plot: Option<PathBuf>,
    },
    /// Compare solvers: steps, rhs evaluations and time each needs to reach a target error.
    ///
    /// Runs the FMU with forward Euler and RK4 over fixed steps from the output interval down,
    /// and DOPRI5 over tolerances 1e-3..1e-11, measures each run's error against a reference
    /// (max over the compared outputs of |y - y_ref| / max|y_ref|): the closed-form solution of
    /// the model's experiment.toml `[compare.reference]` when it has one and no --set changes
    /// its parameters, else DOPRI5 at rtol 1e-12 over the continuous outputs. Prints the cheapest
    /// setting that reaches --target-error per solver, and writes the work-precision table
    /// (CSV) and plot (SVG). Answers Ex. 4's question on solver effort, for any of our models.
    ///
    /// Example: `runner compare quarter_car --solvers euler,rk4,dopri5 --target-error 1e-6`
    Compare(CompareArgs),
    /// Check FMUs statically and dynamically: archive, description, exports, then every probe
    /// of the binary in a child process (lifecycle, state machine, NULL and unknown arguments,
    /// FMU state, variable steps, threads, reproducibility, Model Exchange events).
    ///
    /// Prints errors, warnings and passed checks per FMU; a crash or hang of the FMU is a
    /// finding naming the call, the state, the variable and the value. Exit code 0 when clean,
    /// 1 when an FMU has errors (or warnings, with --strict), 2 when one could not be validated.
    ///
    /// Example: `runner validate target/fmu/*.fmu --report validate.json --junit validate.xml`
    Validate {
        /// FMU files (or model names of this workspace).
        fmus: Vec<String>,
        /// Seconds any single FMI call may take before it counts as a hang.
        #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
        timeout: Option<f64>,
        /// Write every finding as JSON here.
        #[arg(long, value_name = "FILE.json")]
        report: Option<PathBuf>,
        /// Write a JUnit XML report here (one test case per check).
        #[arg(long, value_name = "FILE.xml")]
        junit: Option<PathBuf>,
        /// Warnings fail too (exit code 1).
        #[arg(long)]
        strict: bool,
    },
}

/// Arguments of `runner compare`.
#[derive(clap::Args)]
struct CompareArgs {
    /// Model name or path to a .fmu file of this toolkit (it needs the solver controls).
    fmu: String,
    /// Solvers to compare, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "euler,rk4,dopri5")]
    solvers: Vec<String>,
    /// Error to reach: max over outputs of |y - y_ref| / max|y_ref|.
    #[arg(long, value_name = "E", default_value_t = 1e-6, allow_negative_numbers = true)]
    target_error: f64,
    #[command(flatten)]
    run: RunArgs,
    /// Work-precision table (default <MODEL>_compare.csv).
    #[arg(long, value_name = "FILE.csv")]
    out: Option<PathBuf>,
    /// Work-precision plot (default <MODEL>_compare.svg).
    #[arg(long, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
}

fn main() {
    // A probe process of `runner validate`: no argument parsing, no handlers, just the probe.
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    if args.get(1).is_some_and(|a| a == validate::PROBE_COMMAND) {
        std::process::exit(fmi_validate::probe_main(&args[2..]));
    }
    let cli = Cli::parse();
    interrupt::install();
    // FMU log lines go above the progress bar, when one is drawn.
    fmi_importer::set_log_printer(progress::eprint_line);
    let result = match cli.command {
        Cmd::Build { models } => build::build(&models).map(|paths| {
            for p in paths {
                println!("{}", p.display());
            }
        }),
        Cmd::Info { fmu } => {
            experiment::resolve(&fmu).and_then(|t| fmi_importer::Fmu::load(&t.path)).map(|f| print!("{}", info::report(&f.description)))
        }
        Cmd::Simulate { fmu, run, out, plot, log } => simulate::run(&simulate::Options { fmu, run: run.defaults(), out, plot, log }),
        Cmd::Sweep { fmu, params, metrics, threads, run, out, plot } => {
            match sweep::run(&sweep::Options { fmu, params, metrics, threads, run: run.defaults(), out, plot }) {
                Ok(s) if s.failed == 0 => Ok(()),
                Ok(s) => Err(format!("{} of {} sweep point(s) failed; see the status column", s.failed, s.points)),
                Err(e) => Err(e),
            }
        }
        Cmd::Validate { fmus, timeout, report, junit, strict } => {
            std::process::exit(validate::run(&validate::Options { fmus, timeout, report, junit, strict }))
        }
        Cmd::Compare(a) => {
            let stem =
                std::path::Path::new(&a.fmu).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "compare".into());
            let out = a.out.unwrap_or_else(|| PathBuf::from(format!("{stem}_compare.csv")));
            let plot = a.plot.unwrap_or_else(|| PathBuf::from(format!("{stem}_compare.svg")));
            compare::run(&compare::Options {
                fmu: a.fmu,
                solvers: a.solvers,
                target_error: a.target_error,
                run: a.run.defaults(),
                out,
                plot,
            })
            .map(|_| ())
        }
    };
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(if interrupt::requested() { interrupt::EXIT_CODE } else { 1 });
    }
}
