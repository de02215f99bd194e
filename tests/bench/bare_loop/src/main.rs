//! The limit for `tests/bench/run`: the Ex. 4 sweep done by calling the toolkit's solver on
//! quarter_car's right-hand side directly, with no FMI layer, no instance, no value references
//! and no output handling beyond the two running maxima the metric needs.
//!
//! It asks the integrator for the same 1 ms communication points as an FMU run, computed the
//! way the runner computes them, with the stop time set as the FMU sets it: the same steps
//! across those points, the same dense output at them, so it does exactly the numerical work
//! of one `runner sweep` point and its transmissibility is the same number. Prints one JSON
//! object: per-run cost, the transmissibility and the right-hand-side evaluations per speed.
//!
//! Usage: bare_loop SPEEDS (comma list or START:STOP:STEP) \[RTOL\]

use std::time::Instant;

use fmu_export::core::System;
use fmu_export::solvers::{Integrator, Method, Settings};
use fmu_export::{Equations, Lift, Model};
use quarter_car::QuarterCar;

const STOP: f64 = 10.0;
const INTERVAL: f64 = 1e-3;
/// The FMU's default `abs_tol`.
const ATOL: f64 = 1e-9;

/// max(z_s)/max(z_r) over the communication points of one 10 s run, and the run's
/// right-hand-side evaluations.
fn transmissibility(speed: f64, rtol: f64) -> (f64, u64) {
    // The model is the integrator's ODE system (the same code path as in the FMU). Its
    // parameters are data, as in an FMU run: without black_box the compiler would fold the
    // default masses and stiffnesses into the stages as constants (68 fewer instructions per
    // step), an advantage no run of real parameters has.
    let mut system = QuarterCar::default();
    system.speed = speed;
    let mut system = std::hint::black_box(system);
    // As the FMU at the end of initialization: derives what the right-hand side needs of the
    // parameters, checks them, and gives the initial state.
    system.refresh();
    let mut x = [0.0; QuarterCar::N_STATES];
    system.initial_state(&mut x).expect("the handbook's parameters are valid");
    let settings = Settings { method: Method::Dopri5, fixed_step: INTERVAL, rtol, atol: ATOL, max_step: 0.0 };
    let mut integrator = Integrator::new(settings, QuarterCar::N_STATES, 0);
    // As the FMU after fmi2SetupExperiment: no step ends after the stop time.
    integrator.set_stop_time(Some(STOP));
    let (mut max_zs, mut max_zr) = (0.0f64, 0.0f64);
    let steps = (STOP / INTERVAL).round() as usize;
    let mut t = 0.0;
    for i in 0..steps {
        // The runner's grid: t_i = i h, and the FMU ends its step at t_i + (t_{i+1} - t_i).
        let (t_i, t_next) = (i as f64 * INTERVAL, if i + 1 == steps { STOP } else { (i + 1) as f64 * INTERVAL });
        let t_end = t_i + (t_next - t_i);
        integrator.advance(System::of(&system), &mut t, &mut x, t_end).expect("quarter_car integrates at these settings");
        t = t_end;
        // Compares, as the runner's accumulators do (f64::max's NaN rule costs more, and the
        // integrator hands out finite values only).
        if x[0] > max_zs {
            max_zs = x[0];
        }
        if x[2] > max_zr {
            max_zr = x[2];
        }
    }
    (max_zs / max_zr, integrator.n_rhs())
}

fn parse_speeds(text: &str) -> Vec<f64> {
    let number = |s: &str| s.trim().parse::<f64>().unwrap_or_else(|_| panic!("'{s}' is not a number"));
    if let [start, stop, step] = text.split(':').collect::<Vec<_>>()[..] {
        let (start, stop, step) = (number(start), number(stop), number(step));
        let count = ((stop - start) / step * (1.0 + 1e-12) + 1e-9).floor() as usize + 1;
        (0..count).map(|i| start + i as f64 * step).collect()
    } else {
        text.split(',').map(number).collect()
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 2 {
        eprintln!("usage: bare_loop SPEEDS (V1,V2,... or START:STOP:STEP) [RTOL]");
        std::process::exit(2);
    }
    let speeds = parse_speeds(&args[1]);
    let rtol = args.get(2).map_or(1e-9, |r| r.parse().expect("RTOL is a number"));
    let clock = Instant::now();
    let results: Vec<(f64, (f64, u64))> = speeds.iter().map(|&s| (s, transmissibility(s, rtol))).collect();
    let wall = clock.elapsed().as_secs_f64();
    let table: Vec<String> = results.iter().map(|(s, (r, _))| format!("\"{s:?}\": {r:?}")).collect();
    let rhs: Vec<String> = results.iter().map(|(s, (_, n))| format!("\"{s:?}\": {n}")).collect();
    println!(
        "{{\"tool\": \"bare_dopri5\", \"processes\": 1, \"runs\": {}, \"wall_seconds\": {wall}, \"per_run_seconds\": {}, \"transmissibility\": {{{}}}, \"rhs\": {{{}}}}}",
        speeds.len(),
        wall / speeds.len() as f64,
        table.join(", "),
        rhs.join(", ")
    );
}
