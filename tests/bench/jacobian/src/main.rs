//! Issue 34's cost target: one Jacobian d(der x)/dx by directional derivatives costs at most as
//! much as n + 1 right-hand-side evaluations (what an importer's one-sided finite differences
//! pay). Both are measured through the FMI layer the runner uses, on the same instance at its
//! initial state: the Jacobian as `runner linearize` takes it from directional derivatives
//! (set the time and states, then n fmiGetDirectionalDerivative calls), and an evaluation as
//! the runner's central differences make 2 n of them (set the states, get the derivatives),
//! whose mean is the cost of one. Timings are the best of several rounds, the two interleaved
//! (the machine is shared). Exit code 1 if an FMU misses the target.
//!
//! Every Jacobian here is taken at the same point (the time and states set are the same
//! values each time): the FMU computes its Jacobian block (a dual-number pass over the
//! equations) at the first call of the run and answers every later column from it, in place.
//! So this measures repeated linearization at one point, not a Jacobian at a new point as an
//! implicit solver needs it. At a new point (an input set before each Jacobian, both ways)
//! quarter_car measured 1.8 (FMI 2.0 and 3.0): in the FMU a Jacobian is then 4470
//! instructions (the first call 3220, of which the dual pass 2620, then 4 columns of 277),
//! an evaluation 167 (set the states 43, get the derivatives 124).
//!
//! The Jacobian's time includes what the importer does once per linearization whatever the
//! source (check the model structure, allocate A, B, C and D, set the time and states): for
//! our FMUs an evaluation is about 0.05 us, so those fixed costs weigh. The FMU's own share,
//! in instructions through its C functions (callgrind, quarter_car): 5 columns at the cached
//! point 1385 (FMI 2.0; 1410 in FMI 3.0) against 1000 for n + 1 evaluations.
//!
//! Usage: `cargo run --release -p jacobian_bench [-- FMU...]` (default: the FMI 2.0 and 3.0
//! FMUs of second_order, mass_spring_damper, quarter_car and pendulum in target/, built by
//! `runner build`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use fmi_importer::exchange::{JacobianSource, Ports};
use fmi_importer::{Fmu, Interface, Reader};

const MODELS: [&str; 4] = ["second_order", "mass_spring_damper", "quarter_car", "pendulum"];
/// Jacobians per timed batch, and batches (rounds) per FMU.
const BATCH: u32 = 2000;
const ROUNDS: usize = 7;

/// Seconds per Jacobian of `batch` Jacobians by `source`, and the states' count.
fn time(instance: &mut fmi_importer::Instance, fmu: &Fmu, source: JacobianSource) -> Result<(f64, usize), String> {
    let mut reader = Reader::new(fmu.description.fmi_version, &[])?;
    let mut n = 0;
    let start = Instant::now();
    for _ in 0..BATCH {
        let ports = Ports { inputs: &[], input_values: &[], outputs: &[], reader: &mut reader };
        let j = instance.linearize(ports, source)?;
        if j.source != source {
            return Err(format!("{}: asked for {}, got {}", fmu.identifier, source.text(), j.source.text()));
        }
        n = j.states.len();
        std::hint::black_box(&j);
    }
    Ok((start.elapsed().as_secs_f64() / f64::from(BATCH), n))
}

fn measure(path: &Path) -> Result<(usize, f64, f64), String> {
    let fmu = Fmu::load_as(path, Some(Interface::ModelExchange))?;
    let mut instance = fmu.instantiate("bench", false)?;
    instance.setup_experiment(None, 0.0, 1.0)?;
    instance.enter_initialization_mode()?;
    instance.exit_initialization_mode()?;
    let (mut exact, mut differences, mut n) = (f64::INFINITY, f64::INFINITY, 0);
    for _ in 0..ROUNDS {
        let (t, states) = time(&mut instance, &fmu, JacobianSource::DirectionalDerivatives)?;
        exact = exact.min(t);
        n = states;
        differences = differences.min(time(&mut instance, &fmu, JacobianSource::FiniteDifferences)?.0);
    }
    // Central differences: 2 n evaluations per Jacobian.
    Ok((n, exact, differences / (2 * n) as f64))
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../..");
    let args: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    let fmus = if args.is_empty() {
        MODELS.iter().flat_map(|m| ["target/fmu", "target/fmu3"].map(|d| root.join(d).join(format!("{m}.fmu")))).collect()
    } else {
        args
    };
    println!("best of {ROUNDS} rounds of {BATCH} Jacobians, release build\n");
    println!("| FMU | n | Jacobian by directional derivatives (us) | one evaluation (us) | Jacobian / (n + 1) evaluations | at most 1 |");
    println!("|---|---|---|---|---|---|");
    let mut missed = false;
    for path in &fmus {
        let name = format!(
            "{}/{}",
            path.parent().and_then(|p| p.file_name()).unwrap_or_default().to_string_lossy(),
            path.file_stem().unwrap_or_default().to_string_lossy()
        );
        match measure(path) {
            Ok((n, exact, evaluation)) => {
                let ratio = exact / ((n + 1) as f64 * evaluation);
                missed |= ratio > 1.0;
                println!(
                    "| {name} | {n} | {:.3} | {:.3} | {ratio:.2} | {} |",
                    exact * 1e6,
                    evaluation * 1e6,
                    if ratio <= 1.0 { "met" } else { "MISSED" }
                );
            }
            Err(e) => {
                missed = true;
                println!("| {name} | - | - | - | - | {e} |");
            }
        }
    }
    std::process::exit(i32::from(missed));
}
