//! `runner`: builds, inspects, simulates, sweeps, compares, validates and animates FMUs (FMI 2.0
//! and 3.0, Co-Simulation, and Model Exchange integrated with the runner's own solvers) and SSP
//! systems of them, and reproduces the lab handbook's figures.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};
use fmi_importer::call_log::CallLogTarget;

use plots::Format;
use runner::commands::{animate, build, compare, handbook, info, linearize, new, serve, simulate, sweep, validate};
use runner::experiment::{self, RunDefaults};
use runner::integration::{self, Integration};
use runner::interrupt;
use runner::report::progress;

/// Build and run FMUs (FMI 1.0, 2.0 and 3.0; Co-Simulation, and Model Exchange with the runner's
/// solvers) and SSP systems of them.
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
    /// Set a parameter or input before initialization, in SI or in a unit the FMU declares for
    /// it (`--set theta0=120deg`, `--set k=10lbf/in`); repeatable.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
}

/// Inputs that change over the run, and the master of a system.
#[derive(Args)]
struct InputArgs {
    /// Drive inputs from a CSV file in fmpy's convention: `time` first, then input names; Reals
    /// interpolated linearly, Integers, Booleans and discrete values held, a repeated time a
    /// discontinuity (steps are shortened to land on it). For a system, the columns name
    /// unconnected inputs as COMPONENT.INPUT, set at every communication point.
    #[arg(long, value_name = "FILE.csv")]
    input_file: Option<PathBuf>,
    /// For a system (.ssp, .ssd or a folder holding SystemStructure.ssd): the co-simulation
    /// master, jacobi (default: every component steps from t with the outputs at t) or
    /// gauss-seidel (components step in data-flow order).
    #[arg(long, value_name = "ALGORITHM")]
    master: Option<String>,
    /// For a system: how connections pass Real values over a step, hold (the value at the
    /// step's start, as libcosim and fmpy) or polynomial (the source's output derivatives given
    /// to an input that interpolates; Gauss-Seidel interpolates between both ends of the step).
    /// Default: polynomial where both ends of a connection allow it, hold elsewhere.
    #[arg(long, value_name = "hold|polynomial")]
    coupling: Option<String>,
}

/// `runner simulate`'s options named as fmusim names them (fmpy's spelling accepted too).
#[derive(Args)]
struct SimulateParity {
    /// Start time in seconds (default: the FMU's DefaultExperiment, else 0).
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    start_time: Option<f64>,
    /// Record exactly this variable, of any causality (parameters and locals too); repeatable,
    /// in the CSV's column order. Default: the outputs. fmpy's `--output-variables A B` works
    /// too.
    #[arg(long = "output-variable", visible_alias = "output-variables", value_name = "NAME", num_args = 1..)]
    output_variables: Vec<String>,
    /// Communication points on a logarithmic time scale, as fmusim's: point i at
    /// start * F^i, F the --output-interval (a factor above 1; default: 500 points from
    /// start to stop), the start time above 0.
    #[arg(long)]
    log_time_scale: bool,
    /// Check the run against reference results, a CSV in fmusim's and fmpy's layout (arrays as
    /// NAME[k] columns or as fmusim's space-separated cells); without FILE, the results the FMU
    /// ships under FMI-LS-REF. Every shared column is compared at every reference time within
    /// |y - ref| <= rtol*|ref| + atol; the first violation fails the command, named by column,
    /// time, value and bound.
    #[arg(long, value_name = "REF.csv", num_args = 0..=1, default_missing_value = "")]
    reference_file: Option<String>,
    /// Go on from the FMU state saved in FILE by --final-fmu-state-file (of the same FMU,
    /// through the same interface): the FMU is initialized as usual, then set to that state, and
    /// the run starts at the state's time.
    #[arg(long, value_name = "FILE")]
    initial_fmu_state_file: Option<PathBuf>,
    /// Save the FMU's serialized state at the stop time into FILE, with the FMU's identity (its
    /// instantiation token or GUID, model name and interface), for --initial-fmu-state-file.
    #[arg(long, value_name = "FILE")]
    final_fmu_state_file: Option<PathBuf>,
    /// The reference check's relative tolerance (default 1e-3).
    #[arg(long, value_name = "R", allow_negative_numbers = true)]
    rtol: Option<f64>,
    /// The reference check's absolute tolerance (default: rtol times each column's largest
    /// |ref|).
    #[arg(long, value_name = "A", allow_negative_numbers = true)]
    atol: Option<f64>,
}

impl RunArgs {
    fn defaults(self) -> RunDefaults {
        RunDefaults { stop_time: self.stop_time, output_interval: self.output_interval, tolerance: self.tolerance, set: self.set }
    }
}

/// Which interface of the FMU to drive.
#[derive(Args)]
struct InterfaceArgs {
    /// model-exchange (the runner integrates, with --solver) or co-simulation (the FMU
    /// integrates itself); default: Co-Simulation when the FMU offers it.
    #[arg(long, value_name = "INTERFACE", value_parser = integration::parse_interface)]
    interface: Option<fmi_importer::Interface>,
}

/// The runner's integrator for a Model Exchange run.
#[derive(Args)]
struct SolverArgs {
    /// Model Exchange: the runner's integration method, euler, rk4, dopri5, bs23, dop853, or
    /// for stiff models the implicit bdf and esdirk (default dopri5, with --tolerance as its
    /// relative tolerance).
    #[arg(long, value_name = "METHOD")]
    solver: Option<String>,
    /// Model Exchange: the step of euler and rk4 in seconds (default 1e-3).
    #[arg(long, value_name = "H", allow_negative_numbers = true)]
    fixed_step: Option<f64>,
    /// Model Exchange: the absolute tolerance of the adaptive methods (default 1e-9).
    #[arg(long, value_name = "A", allow_negative_numbers = true)]
    abs_tolerance: Option<f64>,
}

fn integration(interface: InterfaceArgs, solver: Option<SolverArgs>) -> Integration {
    let solver = solver.unwrap_or(SolverArgs { solver: None, fixed_step: None, abs_tolerance: None });
    Integration {
        interface: interface.interface,
        solver: solver.solver,
        fixed_step: solver.fixed_step,
        abs_tolerance: solver.abs_tolerance,
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// Build model crates in release mode and pack target/fmu/<MODEL>.fmu (FMI 2.0) and
    /// target/fmu3/<MODEL>.fmu (FMI 3.0, with the reference result of its default experiment
    /// under FMI-LS-REF); pack the systems under systems/ into target/ssp/<SYSTEM>.ssp with the
    /// FMUs they use.
    ///
    /// Example: `runner build quarter_car pendulum` (no name: every crate under models/ and
    /// every system under systems/).
    ///
    /// Example: `runner build --manifest-path my_model/Cargo.toml` (a model crate anywhere, such
    /// as one `runner new` made: my_model/target/fmu/my_model.fmu and fmu3/my_model.fmu).
    Build {
        /// Model identifiers (crate names under models/).
        #[arg(conflicts_with = "manifest_path")]
        models: Vec<String>,
        /// Build the model crate of this Cargo.toml instead, wherever it is.
        #[arg(long, value_name = "DIR/Cargo.toml")]
        manifest_path: Option<PathBuf>,
        /// With --manifest-path: write OUT/fmu/<id>.fmu and OUT/fmu3/<id>.fmu (default: the
        /// crate's target directory).
        #[arg(long, value_name = "OUT", requires = "manifest_path")]
        out_dir: Option<PathBuf>,
    },
    /// Create a model crate of your own: one parameter, one state, one output, its test against
    /// the closed form and derivation.md, depending on this checkout's export toolkit by path.
    ///
    /// Example: `runner new my_model --path ~/models/my_model`, then `cargo test` in it and
    /// `runner build --manifest-path ~/models/my_model/Cargo.toml`.
    New {
        /// The model's name: its crate, struct (in CamelCase) and FMU modelIdentifier.
        name: String,
        /// The directory to create (default: ./NAME); it must not exist or be empty.
        #[arg(long, value_name = "DIR")]
        path: Option<PathBuf>,
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
        #[command(flatten)]
        interface: InterfaceArgs,
        #[command(flatten)]
        solver: SolverArgs,
        /// Write the CSV here instead of stdout.
        #[arg(long, value_name = "FILE.csv")]
        out: Option<PathBuf>,
        /// Plot into this file (.svg or .png): one panel per continuous output on a shared time
        /// axis, in the FMU's display units (deg, rpm), with events (discrete outputs changing,
        /// such as a release) marked.
        #[arg(long, value_name = "FILE.svg|FILE.png")]
        plot: Option<PathBuf>,
        /// Turn on the FMU's debug logging (messages go to stderr with the instance name).
        #[arg(long)]
        log: bool,
        /// The variables to plot, comma-separated (default: the continuous outputs).
        #[arg(long, value_name = "A,B,...", value_delimiter = ',')]
        plot_vars: Vec<String>,
        /// Plot against this variable instead of time, e.g. `--plot-x theta` (a phase portrait).
        #[arg(long, value_name = "VAR")]
        plot_x: Option<String>,
        /// Run once per value of a parameter and overlay the runs, e.g.
        /// `--overlay theta0=15deg,120deg`; the CSV gets the parameter (SI) as a first column.
        #[arg(long, value_name = "NAME=V1,V2,...")]
        overlay: Option<String>,
        /// Also write a row at each event an FMI 3.0 FMU stops a step at (the values just
        /// before the event is handled), besides the rows at the communication points.
        #[arg(long)]
        record_events: bool,
        #[command(flatten)]
        isolation: SimulateIsolation,
        #[command(flatten)]
        inputs: InputArgs,
        #[command(flatten)]
        parity: SimulateParity,
        #[command(flatten)]
        call_log: CallLogArgs,
    },
    /// Run a parameter sweep: one FMU instance per point, in parallel; metrics per point as CSV.
    ///
    /// Every --param adds a dimension; the points are the cartesian product (the last --param
    /// varies fastest). A metric is NAME=EXPR over per-run summaries (max, min, final, mean,
    /// peak_to_peak, rms) of any variable, optionally from a time on as in max(x, 5), and
    /// amplitude(x, 5, W), the amplitude at angular frequency W (rad/s, an expression of
    /// parameters such as 2*pi*speed/road_wavelength) fitted to the samples from t = 5 on, combined
    /// with the operators `+ - * / ^`, parentheses, the constant pi and the functions exp, log,
    /// sqrt, sin, cos, tan, asin, acos, atan, atan2(y, x), hypot(x, y), abs and ellipk(m) (the
    /// complete elliptic integral of the first kind, m = k^2); natural_frequency(N) and
    /// damping(N) read mode N of the point linearized at its initial state (through Model
    /// Exchange). The CSV has one row per point: parameters,
    /// metrics, status (`ok` or the error). Failed points are recorded and the others still
    /// run; the exit code is 1 if any failed. With a model name and no options, the model's
    /// experiment.toml gives the sweep. Points run in worker processes, so a crash or hang of the
    /// FMU costs only its point; to a file the rows go to <out>.partial as points finish, and a
    /// killed or interrupted sweep continues with --resume.
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
        /// Worker processes, or threads with --in-process (default: one per core); results do
        /// not depend on it.
        #[arg(long, value_name = "N", allow_negative_numbers = true)]
        threads: Option<usize>,
        #[command(flatten)]
        run: RunArgs,
        #[command(flatten)]
        interface: InterfaceArgs,
        #[command(flatten)]
        solver: SolverArgs,
        /// Write the CSV here (default: experiment.toml's, else stdout).
        #[arg(long, value_name = "FILE.csv")]
        out: Option<PathBuf>,
        /// Plot each metric against the first parameter into this file, peaks marked: SVG, or
        /// PNG for a name ending in .png (default: experiment.toml's, unless --out names the CSV).
        #[arg(long, value_name = "FILE.svg|FILE.png")]
        plot: Option<PathBuf>,
        #[command(flatten)]
        isolation: SweepIsolation,
        #[command(flatten)]
        inputs: InputArgs,
    },
    /// Compare solvers: steps, rhs evaluations and time each needs to reach a target error.
    ///
    /// Runs the FMU with forward Euler and RK4 over fixed steps from the output interval down,
    /// and the adaptive DOPRI5, BS23 and DOP853 over tolerances from 1e-2 down (they step
    /// across communication points: their natural work), measures each run's error against a
    /// reference (max over the compared outputs of |y - y_ref| / max|y_ref|): the closed-form
    /// solution of the model's experiment.toml `[compare.reference]` when it has one and no
    /// --set changes its parameters, else DOP853 at rtol 1e-13 over the continuous outputs.
    /// Prints the cheapest setting that reaches --target-error per solver, and writes the
    /// work-precision table (CSV) and plot (SVG) of each model. With several models it also
    /// prints their step counts side by side: Ex. 4's discussion question 1. Under
    /// --interface model-exchange the runner's own integrator runs the methods, on any Model
    /// Exchange FMU, and n_rhs counts its derivative evaluations plus the implicit methods'
    /// directional-derivative calls.
    ///
    /// Example: `runner compare quarter_car second_order --target-error 1e-6`
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
        /// Also check a run of each FMU (as `runner simulate` makes it) against these reference
        /// results, as `runner simulate --reference-file` does: a violation is an error. Without
        /// it, an FMU that ships an FMI-LS-REF result is checked against that, and a violation
        /// is a warning.
        #[arg(long, value_name = "REF.csv")]
        reference_file: Option<PathBuf>,
        /// The reference check's relative tolerance (default 1e-3).
        #[arg(long, value_name = "R", allow_negative_numbers = true)]
        rtol: Option<f64>,
        /// The reference check's absolute tolerance (default: rtol times each column's largest
        /// |ref|).
        #[arg(long, value_name = "A", allow_negative_numbers = true)]
        atol: Option<f64>,
    },
    /// Linearize a Model Exchange FMU at its initial state or at a time of a simulation.
    ///
    /// x' = A x + B u, y = C x + D u over its states, continuous Real inputs and outputs, from
    /// the FMU's directional derivatives when it provides them, else central finite
    /// differences (the first line says which). Prints the eigenvalues with each mode's
    /// natural frequency and damping ratio, and the matrices; --out writes them as JSON;
    /// --bode INPUT:OUTPUT writes the frequency response's magnitude and phase as CSV. The FMU
    /// runs in a worker process, so a crash is reported with its signal and FMI call.
    ///
    /// Example: `runner linearize quarter_car --bode z_r_dot_ext:z_s --plot qc_bode.svg`
    ///
    /// Example: `runner linearize pendulum --set theta0=30deg --out pendulum.json`
    Linearize(LinearizeArgs),
    /// Animate an FMU whose outputs include point coordinates (<P>_x, <P>_y) into a GIF.
    ///
    /// Drawn to scale (equal axis scales) with a time stamp. The links, trails, ground lines and
    /// the frame come from the `[animate]` section of the model's experiment.toml; for an FMU
    /// given by path, from `--experiment FILE.toml`; without one, every point is drawn with its
    /// path. One frame per output interval (at most 50 per second) unless --fps says otherwise.
    ///
    /// Example: `runner animate trebuchet --out trebuchet.gif`
    ///
    /// Example: `runner animate my.fmu --experiment my_animate.toml --out my.gif --fps 25`
    Animate(AnimateArgs),
    /// Reproduce every figure the lab handbook's "Discussion and Deliverables" sections ask for.
    ///
    /// Ex. 1 to 6 and App. E from this workspace's FMUs (built if missing): the figures (SVG, or
    /// PNG with --format png), the Ex. 5B and Ex. 6 GIFs, DIR/index.html with every figure, its
    /// caption and the numbers a report quotes, and DIR/summary.json with those numbers.
    ///
    /// Example: `runner handbook --out handbook`
    Handbook {
        /// The directory to write into (created if missing).
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
        /// Figure format: svg or png.
        #[arg(long, value_name = "FORMAT", default_value = "svg")]
        format: String,
        /// Worker threads (default: one per core).
        #[arg(long, value_name = "N")]
        threads: Option<usize>,
    },
    /// Serve the lab in the browser: a page per model with sliders for its parameters, plots of
    /// its outputs updated as a value changes, a phase plot, the animation of a mechanism, a
    /// sweep panel and downloads, over a JSON API of the same engine (runs in worker processes).
    ///
    /// Listens on 127.0.0.1 only unless --host is given; serves only the FMUs named here (no
    /// name: every model of the workspace, built if missing); refuses requests from other web
    /// pages.
    ///
    /// Example: `runner serve` (then open the URL it prints)
    ///
    /// Example: `runner serve quarter_car trebuchet --port 0` (any free port)
    Serve {
        /// Model names or paths to .fmu files (default: every model of the workspace).
        fmus: Vec<String>,
        /// The port to listen on; 0 picks a free one (the URL printed names it).
        #[arg(long, default_value_t = 8000)]
        port: u16,
        /// Listen on this address instead of 127.0.0.1 (e.g. 0.0.0.0: every interface), which
        /// lets other machines run the served FMUs here; a warning says so.
        #[arg(long, value_name = "ADDRESS")]
        host: Option<String>,
        /// A run or sweep point that takes longer fails and its worker is replaced (default 60).
        #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
        point_timeout: Option<f64>,
        /// Most points a sweep from the page may have.
        #[arg(long, value_name = "N", default_value_t = 2000)]
        max_points: usize,
        /// Worker processes of a sweep (default: one per core).
        #[arg(long, value_name = "N")]
        threads: Option<usize>,
    },
    /// A worker process of sweep, simulate, compare and linearize (started by the runner itself).
    #[command(hide = true)]
    Worker,
    /// A worker process that runs SSP systems for sweep and simulate (started by the runner
    /// itself).
    #[command(hide = true, name = "system-worker")]
    SystemWorker,
}

/// How `runner sweep` isolates its points, and resumes.
#[derive(Args)]
struct SweepIsolation {
    /// Run the points on threads of this process instead of worker processes (for trusted FMUs:
    /// a crash then ends the sweep).
    #[arg(long)]
    in_process: bool,
    /// Record a point that runs longer than this as timed out and replace its worker.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    point_timeout: Option<f64>,
    /// Memory limit of each worker process in MiB (default: three quarters of the machine's,
    /// shared among the workers); a worker that grows past half of it is replaced.
    #[arg(long, value_name = "MIB")]
    worker_memory: Option<u64>,
    /// Continue the interrupted or killed sweep whose finished rows are in <out>.partial.
    #[arg(long)]
    resume: bool,
}

/// How `runner simulate` and `runner linearize` isolate their run.
#[derive(Args)]
struct SimulateIsolation {
    /// Stop the run (and fail) if it takes longer than this.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    timeout: Option<f64>,
    /// Run the FMU in this process instead of a worker process (for trusted FMUs).
    #[arg(long)]
    in_process: bool,
}

/// The log of every FMI call (`--log-fmi-calls`), for `runner simulate` and `runner linearize`.
#[derive(Args)]
struct CallLogArgs {
    /// Write every FMI call the runner makes into FILE (without FILE: to stderr), one line per
    /// call with its arguments, the status it returned and its duration, e.g.
    /// `fmi2DoStep(currentCommunicationPoint=0.1, communicationStepSize=0.1, ...) -> fmi2OK [3 us]`.
    /// Each call is written before the FMU runs it, so the last line of an FMU that crashed
    /// names the call it crashed in. In FILE, the FMU's log messages are copied among the
    /// calls.
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "")]
    log_fmi_calls: Option<String>,
}

impl CallLogArgs {
    /// Where the log goes: a file, stderr (the flag without FILE), or nowhere.
    fn target(self) -> Option<CallLogTarget> {
        self.log_fmi_calls.map(|path| match path.is_empty() {
            true => CallLogTarget::Stderr,
            false => CallLogTarget::File(PathBuf::from(path)),
        })
    }
}

/// Arguments of `runner animate`.
#[derive(clap::Args)]
struct AnimateArgs {
    /// Model name or path to a .fmu file.
    fmu: String,
    /// The GIF file to write.
    #[arg(long, value_name = "FILE.gif")]
    out: PathBuf,
    #[command(flatten)]
    run: RunArgs,
    /// Frames per second of the GIF (default: one frame per output interval, at most 50).
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// Simulated seconds per second of playback: 1 is real time, 0.25 four times slower.
    #[arg(long, value_name = "X", allow_negative_numbers = true)]
    speed: Option<f64>,
    /// Width of the GIF in pixels (default 640; the height follows the scene, at least 480).
    #[arg(long, value_name = "PX")]
    size: Option<u32>,
    /// An experiment.toml with an [animate] section to use instead of the model's (for an FMU
    /// given by path, the way to give it one).
    #[arg(long, value_name = "FILE.toml")]
    experiment: Option<PathBuf>,
}

/// Arguments of `runner linearize`.
#[derive(clap::Args)]
struct LinearizeArgs {
    /// Model name or path to a .fmu file that offers Model Exchange.
    fmu: String,
    #[command(flatten)]
    run: RunArgs,
    #[command(flatten)]
    solver: SolverArgs,
    /// Simulate to this time (s) and linearize there (default: at the initial state, after
    /// initialization).
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    at: Option<f64>,
    /// Use central finite differences even when the FMU provides directional derivatives.
    #[arg(long)]
    finite_differences: bool,
    /// Write states, inputs, outputs, A, B, C, D, eigenvalues ({re, im}), modes and source as
    /// JSON here.
    #[arg(long, value_name = "FILE.json")]
    out: Option<PathBuf>,
    /// A frequency response to write, from a continuous Real input to a continuous Real
    /// output; repeatable.
    #[arg(long, value_name = "INPUT:OUTPUT")]
    bode: Vec<String>,
    /// The frequencies of --bode in Hz: F1,F2,... or FROM:TO:COUNT spaced evenly in log
    /// (default: from a decade below the slowest mode to a decade above the fastest, 50 per
    /// decade).
    #[arg(long, value_name = "HZ")]
    frequencies: Option<String>,
    /// The CSV of --bode (default <MODEL>_bode.csv): frequency_hz, omega_rad_s, then
    /// magnitude(OUTPUT/INPUT) and phase_deg(OUTPUT/INPUT) per pair.
    #[arg(long, value_name = "FILE.csv")]
    bode_out: Option<PathBuf>,
    /// Plot the --bode responses (magnitude and phase against frequency) into this file, SVG or
    /// PNG by its extension.
    #[arg(long, value_name = "FILE.svg|FILE.png")]
    plot: Option<PathBuf>,
    #[command(flatten)]
    isolation: SimulateIsolation,
    #[command(flatten)]
    call_log: CallLogArgs,
}

/// Arguments of `runner compare`.
#[derive(clap::Args)]
struct CompareArgs {
    /// Model names or paths to .fmu files (of this toolkit, which have the solver controls, or
    /// any Model Exchange FMU with --interface model-exchange).
    #[arg(required = true, value_name = "MODEL")]
    models: Vec<String>,
    /// Solvers to compare, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "euler,rk4,dopri5,bs23,dop853,bdf,esdirk")]
    solvers: Vec<String>,
    /// Error to reach: max over outputs of |y - y_ref| / max|y_ref|.
    #[arg(long, value_name = "E", default_value_t = 1e-6, allow_negative_numbers = true)]
    target_error: f64,
    #[command(flatten)]
    run: RunArgs,
    #[command(flatten)]
    interface: InterfaceArgs,
    /// Work-precision table of a single model (default <MODEL>_compare.csv for each).
    #[arg(long, value_name = "FILE.csv")]
    out: Option<PathBuf>,
    /// Work-precision plot of a single model, SVG or PNG by its extension (default
    /// <MODEL>_compare.svg for each).
    #[arg(long, value_name = "FILE.svg|FILE.png")]
    plot: Option<PathBuf>,
    /// Run in this process instead of a worker process (for trusted FMUs).
    #[arg(long)]
    in_process: bool,
    /// Record a run that takes longer than this as timed out and replace its worker.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    point_timeout: Option<f64>,
}

fn main() {
    // A probe process of `runner validate`: no argument parsing, no handlers, just the probes.
    if std::env::args_os().nth(1).is_some_and(|a| a == validate::PROBE_COMMAND) {
        std::process::exit(fmi_validate::probe_worker());
    }
    // The runner ends after its runs: an FMU's code stays loaded for what runs at exit.
    fmi_importer::keep_binaries_loaded();
    let cli = Cli::parse();
    if let Cmd::Worker = cli.command {
        if let Err(e) = runner_engine::isolated::serve() {
            eprintln!("runner worker: {e}");
            std::process::exit(1);
        }
        return;
    }
    if let Cmd::SystemWorker = cli.command {
        if let Err(e) = runner::commands::system::serve() {
            eprintln!("runner system-worker: {e}");
            std::process::exit(1);
        }
        return;
    }
    interrupt::install();
    // FMU log lines go above the progress bar, when one is drawn.
    fmi_importer::set_log_printer(progress::eprint_line);
    let result = match cli.command {
        Cmd::Build { manifest_path: Some(manifest), out_dir, .. } => build::build_manifest(&manifest, out_dir.as_deref()).map(|paths| {
            for p in paths {
                println!("{}", p.display());
            }
        }),
        Cmd::New { name, path } => new::new(&name, path.as_deref()).map(|dir| {
            println!("created model crate {name} in {}", dir.display());
        }),
        Cmd::Build { models, .. } => build::build(&models).map(|paths| {
            for p in paths {
                println!("{}", p.display());
            }
        }),
        Cmd::Info { fmu } => {
            experiment::resolve(&fmu).and_then(|t| fmi_importer::Fmu::load(&t.path)).map(|f| print!("{}", info::report(&f.description)))
        }
        Cmd::Simulate {
            fmu,
            run,
            interface,
            solver,
            out,
            plot,
            log,
            plot_vars,
            plot_x,
            overlay,
            record_events,
            isolation,
            inputs,
            parity,
            call_log,
        } => simulate::run(&simulate::Options {
            fmu,
            run: run.defaults(),
            out,
            plot,
            log,
            plot_vars,
            plot_x,
            overlay,
            record_events,
            integration: integration(interface, Some(solver)),
            timeout: isolation.timeout,
            in_process: isolation.in_process,
            input_file: inputs.input_file,
            master: inputs.master,
            coupling: inputs.coupling,
            start_time: parity.start_time,
            output_variables: parity.output_variables,
            log_time_scale: parity.log_time_scale,
            reference_file: parity.reference_file.map(|f| Some(PathBuf::from(f)).filter(|f| !f.as_os_str().is_empty())),
            rtol: parity.rtol,
            atol: parity.atol,
            initial_fmu_state_file: parity.initial_fmu_state_file,
            final_fmu_state_file: parity.final_fmu_state_file,
            log_fmi_calls: call_log.target(),
        }),
        Cmd::Sweep { fmu, params, metrics, threads, run, interface, solver, out, plot, isolation, inputs } => {
            match sweep::run(&sweep::Options {
                fmu,
                params,
                metrics,
                threads,
                run: run.defaults(),
                out,
                plot,
                integration: integration(interface, Some(solver)),
                in_process: isolation.in_process,
                point_timeout: isolation.point_timeout,
                worker_memory: isolation.worker_memory,
                resume: isolation.resume,
                command_line: std::env::args().collect(),
                input_file: inputs.input_file,
                master: inputs.master,
                coupling: inputs.coupling,
            }) {
                Ok(s) if s.failed == 0 => Ok(()),
                Ok(s) => Err(format!("{} of {} sweep point(s) failed; see the status column", s.failed, s.points)),
                Err(e) => Err(e),
            }
        }
        Cmd::Validate { fmus, timeout, report, junit, strict, reference_file, rtol, atol } => {
            std::process::exit(validate::run(&validate::Options { fmus, timeout, report, junit, strict, reference_file, rtol, atol }))
        }
        Cmd::Compare(a) => compare::run(&compare::Options {
            models: a.models,
            solvers: a.solvers,
            target_error: a.target_error,
            run: a.run.defaults(),
            out: a.out,
            plot: a.plot,
            integration: integration(a.interface, None),
            in_process: a.in_process,
            point_timeout: a.point_timeout,
        })
        .map(|_| ()),
        Cmd::Linearize(a) => linearize::run(&linearize::Options {
            fmu: a.fmu,
            run: a.run.defaults(),
            integration: integration(InterfaceArgs { interface: Some(fmi_importer::Interface::ModelExchange) }, Some(a.solver)),
            at: a.at,
            finite_differences: a.finite_differences,
            out: a.out,
            bode: a.bode,
            frequencies: a.frequencies,
            bode_out: a.bode_out,
            plot: a.plot,
            timeout: a.isolation.timeout,
            in_process: a.isolation.in_process,
            log_fmi_calls: a.call_log.target(),
        })
        .map(|_| ()),
        Cmd::Animate(a) => animate::run(&animate::Options {
            fmu: a.fmu,
            run: a.run.defaults(),
            out: a.out,
            fps: a.fps,
            speed: a.speed,
            size: a.size,
            experiment: a.experiment,
        })
        .map(|_| ()),
        Cmd::Handbook { out, format, threads } => Format::named(&format)
            .map_err(|e| format!("--format: {e}"))
            .and_then(|format| handbook::run(&handbook::Options { out, format, threads }).map(|_| ())),
        Cmd::Serve { fmus, port, host, point_timeout, max_points, threads } => {
            serve::run(&serve::Options { fmus, host, port, point_timeout, max_points, threads })
        }
        Cmd::Worker | Cmd::SystemWorker => unreachable!("served above"),
    };
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(if interrupt::requested() { interrupt::EXIT_CODE } else { 1 });
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    /// `runner sweep --help` names every function and constant a metric may use (the formulas
    /// crate's tables), so the help cannot fall behind the grammar.
    #[test]
    fn the_sweep_help_names_every_metric_function() {
        let mut cli = super::Cli::command();
        let help = cli.find_subcommand_mut("sweep").expect("a sweep command").render_long_help().to_string();
        for (name, _) in formulas::metrics::FUNCTIONS {
            assert!(help.contains(&format!(" {name}")), "sweep --help does not name {name}");
        }
        for (name, _) in formulas::metrics::CONSTANTS {
            assert!(help.contains(&format!("constant {name}")), "sweep --help does not name {name}");
        }
    }
}
