//! Issue 34's cost target: one Jacobian d(der x)/dx by directional derivatives costs at most as
//! much as n + 1 right-hand-side evaluations (what an importer's one-sided finite differences
//! pay). Both are measured through the FMI layer the runner uses, on the same instance near its
//! initial state: the Jacobian as `runner linearize` takes it from directional derivatives
//! (set the time and states, then n fmiGetDirectionalDerivative calls), and an evaluation as
//! the runner's central differences make 2 n of them (set the states, get the derivatives),
//! whose mean is the cost of one. Timings are the best of several rounds, the two interleaved
//! (the machine is shared). Exit code 1 if an FMU misses the target.
//!
//! The target is for a Jacobian at a new point, as an implicit solver takes one: before each
//! Jacobian, both ways, every state is moved by 1e-9 relative, back and forth, so the FMU
//! cannot answer from the Jacobian it computed for the last point. The same Jacobian at one
//! fixed point (repeated linearization: the FMU computes its block once and answers every later
//! column from it) is the last column.
//!
//! The Jacobian's time includes what the importer does once per linearization whatever the
//! source (check the model structure, allocate A, B, C and D, set the time and states): for
//! our FMUs an evaluation is about 0.05 us, so those fixed costs weigh.
//!
//! Measured 2026-12-06 (this machine, shared, load average about 3, so +-0.1; five runs): at a
//! new point 0.71-1.10, the target missed: mass_spring_damper 0.99-1.10 (FMI 2.0 and 3.0, above 1
//! in 4 of 5 runs), and single runs of second_order (1.10), quarter_car (1.02, 1.03) and
//! pendulum (1.02) above 1; otherwise second_order 0.92-1.00, quarter_car 0.86-1.00, pendulum
//! 0.71-0.98. At the fixed point 0.50-0.69. The same day before the importer's changes below:
//! 1.15-1.51 (1.04-1.26 measured earlier; before the export toolkit kept the lifted model
//! between Jacobians 1.29-1.91).
//!
//! In instructions per Jacobian at a new point, importer and FMU together (callgrind on
//! `--one`, FMI 2.0): quarter_car 4893 (5652 before the importer kept its sensitivity buffer,
//! allocated the matrices without calloc, inlined the call's wrapper and filled the matrices
//! row by row; FMI 3.0 4924) against 4157 for n + 1 evaluations as counted here (six tenths of
//! its central-difference Jacobian, 6928): 1.18; second_order 2751 against 2851 (0.96),
//! mass_spring_damper 2773 against 2746 (1.01), pendulum 2878 against 3001 (0.96). Of those,
//! about 1200 per Jacobian are the importer's fixed costs whatever the source (set the time and
//! states, allocate and free the result, the loop here), which finite differences spread over
//! 2 n evaluations. Inside the FMU's C functions (unchanged) quarter_car's Jacobian at a new
//! point is 2795 (FMI 3.0 2810; 2770 and 2815 measured before with the same code) plus setting
//! the time and states (68), against 1002 for n + 1 evaluations (set the states 43, get the
//! derivatives 124): the 5 column calls' own checks and reads 1343 (about 270 each, more than
//! the n + 1 evaluations alone), making the block current 1416 (the dual-number pass 1122, of
//! which the model's own arithmetic about 470 in 6-lane dual numbers, the rest seeding,
//! dispatch and reading out; checking and recording the point 293).
//!
//! Usage: `cargo run --release -p jacobian_bench [-- FMU...]` (default: the FMI 2.0 and 3.0
//! FMUs of second_order, mass_spring_damper, quarter_car and pendulum in target/, built by
//! `runner build`). For a profiler: `jacobian_bench --one directional|differences FMU` takes one
//! batch of Jacobians at new points by that source and prints nothing (under callgrind, the
//! inclusive cost of `jacobian_bench::time` divided by the batch is the cost of one).

use std::path::{Path, PathBuf};
use std::time::Instant;

use fmi_importer::exchange::{JacobianSource, Ports};
use fmi_importer::{Fmu, Interface, Reader};

const MODELS: [&str; 4] = ["second_order", "mass_spring_damper", "quarter_car", "pendulum"];
/// Jacobians per timed batch, and batches (rounds) per FMU.
const BATCH: u32 = 2000;
const ROUNDS: usize = 7;

/// Where each Jacobian of a batch is taken.
#[derive(Clone, Copy, PartialEq)]
enum Point {
    /// Always at the initial state: the FMU may answer from the Jacobian it computed once.
    Fixed,
    /// Every state moved by a tiny relative amount before each Jacobian, back and forth: each
    /// is at a new point, as an implicit solver asks for them.
    New,
}

/// Seconds per Jacobian of `batch` Jacobians by `source` at `point`s around `x0`.
fn time(instance: &mut fmi_importer::Instance, fmu: &Fmu, source: JacobianSource, point: Point, x0: &[f64]) -> Result<f64, String> {
    let mut reader = Reader::new(fmu.description.fmi_version, &[])?;
    let mut x = x0.to_vec();
    let start = Instant::now();
    for i in 0..BATCH {
        if point == Point::New {
            // 1e-9 relative (absolute for values below 1): far above rounding, so every
            // Jacobian is at a point other than the last one's.
            let step = if i % 2 == 0 { 1e-9 } else { -1e-9 };
            for (x, &x0) in x.iter_mut().zip(x0) {
                *x = x0 + step * x0.abs().max(1.0);
            }
            instance.move_states(&x)?;
        }
        let ports = Ports { inputs: &[], input_values: &[], outputs: &[], reader: &mut reader };
        let j = instance.linearize(ports, source)?;
        if j.source != source {
            return Err(format!("{}: asked for {}, got {}", fmu.identifier, source.text(), j.source.text()));
        }
        std::hint::black_box(&j);
    }
    Ok(start.elapsed().as_secs_f64() / f64::from(BATCH))
}

/// An instance of `fmu` after initialization, and its states there.
fn started(fmu: &Fmu) -> Result<(fmi_importer::Instance<'_>, Vec<f64>), String> {
    let mut instance = fmu.instantiate("bench", false)?;
    instance.setup_experiment(None, 0.0, 1.0)?;
    instance.enter_initialization_mode()?;
    instance.exit_initialization_mode()?;
    let mut reader = Reader::new(fmu.description.fmi_version, &[])?;
    let ports = Ports { inputs: &[], input_values: &[], outputs: &[], reader: &mut reader };
    let x0 = instance.linearize(ports, JacobianSource::FiniteDifferences)?.x;
    Ok((instance, x0))
}

/// The states' count and, per point (new, fixed), the Jacobian by directional derivatives and
/// one evaluation, in seconds.
fn measure(path: &Path) -> Result<(usize, [(f64, f64); 2]), String> {
    let fmu = Fmu::load_as(path, Some(Interface::ModelExchange))?;
    let (mut instance, x0) = started(&fmu)?;
    let n = x0.len();
    let mut best = [(f64::INFINITY, f64::INFINITY); 2];
    for _ in 0..ROUNDS {
        for (point, (exact, evaluation)) in [Point::New, Point::Fixed].into_iter().zip(&mut best) {
            *exact = exact.min(time(&mut instance, &fmu, JacobianSource::DirectionalDerivatives, point, &x0)?);
            // Central differences: 2 n evaluations per Jacobian.
            let differences = time(&mut instance, &fmu, JacobianSource::FiniteDifferences, point, &x0)?;
            *evaluation = evaluation.min(differences / (2 * n) as f64);
        }
    }
    Ok((n, best))
}

/// `--one SOURCE FMU`: one batch at new points by `source`, for a profiler.
fn one(source: &str, path: &Path) -> Result<(), String> {
    let source = match source {
        "directional" => JacobianSource::DirectionalDerivatives,
        "differences" => JacobianSource::FiniteDifferences,
        other => return Err(format!("--one {other}: give directional or differences")),
    };
    let fmu = Fmu::load_as(path, Some(Interface::ModelExchange))?;
    let (mut instance, x0) = started(&fmu)?;
    time(&mut instance, &fmu, source, Point::New, &x0).map(drop)
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../..");
    let args: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    if let [flag, source, path] = args.as_slice() {
        if flag.as_os_str() == "--one" {
            if let Err(e) = one(&source.to_string_lossy(), path) {
                eprintln!("{e}");
                std::process::exit(2);
            }
            return;
        }
    }
    let fmus = if args.is_empty() {
        MODELS.iter().flat_map(|m| ["target/fmu", "target/fmu3"].map(|d| root.join(d).join(format!("{m}.fmu")))).collect()
    } else {
        args
    };
    println!("best of {ROUNDS} rounds of {BATCH} Jacobians, release build; the target is judged at a new point\n");
    println!("| FMU | n | new point: Jacobian (us) | one evaluation (us) | Jacobian / (n + 1) evaluations | at most 1 | fixed point (repeated call): Jacobian / (n + 1) evaluations |");
    println!("|---|---|---|---|---|---|---|");
    let mut missed = false;
    for path in &fmus {
        let name = format!(
            "{}/{}",
            path.parent().and_then(|p| p.file_name()).unwrap_or_default().to_string_lossy(),
            path.file_stem().unwrap_or_default().to_string_lossy()
        );
        match measure(path) {
            Ok((n, [(exact, evaluation), (fixed_exact, fixed_evaluation)])) => {
                let ratio = exact / ((n + 1) as f64 * evaluation);
                let fixed = fixed_exact / ((n + 1) as f64 * fixed_evaluation);
                missed |= ratio > 1.0;
                println!(
                    "| {name} | {n} | {:.3} | {:.3} | {ratio:.2} | {} | {fixed:.2} |",
                    exact * 1e6,
                    evaluation * 1e6,
                    if ratio <= 1.0 { "met" } else { "MISSED" }
                );
            }
            Err(e) => {
                missed = true;
                println!("| {name} | - | - | - | - | {e} | - |");
            }
        }
    }
    std::process::exit(i32::from(missed));
}
