//! The baseline of `tests/bench/systems`: the two FMUs of systems/quarter_car_road stepped by
//! the least a master can do, the FMI calls the system needs and nothing else. Per
//! communication step: road fmi2DoStep, road fmi2GetReal(z_r_dot), car fmi2SetReal(z_r_dot_ext),
//! car fmi2DoStep, car fmi2GetReal(z_s) and a running maximum, through the runner's importer
//! (its calls are thin: a status check and the trace word), with value references looked up
//! once, no connection plan, no unit conversion, no recording. Its time per step is the two
//! FMUs' own step time; what `runner sweep SYSTEM` costs beyond it is the master's overhead.
//!
//! It sets the parameters of the system's .ssv files and initializes as the Jacobi master does,
//! so it does the same numerical work: it prints max(car.z_s) per speed, which must equal the
//! runner's sweep of the system to the bit (tests/bench/systems.py checks).
//!
//! With `polynomial` after the arguments, the calls of the polynomial coupling too: after the
//! car's fmi2SetReal, fmi2SetRealInputDerivatives of orders 1 to 3, and after the road's
//! fmi2GetReal, fmi2GetRealOutputDerivatives of orders 1 to 3 (the runner's
//! `--coupling polynomial` under Jacobi).
//!
//! Usage: bare_master CAR.fmu ROAD.fmu SPEEDS(comma list) STOP INTERVAL \[polynomial\]

use std::path::Path;

use fmi_importer::{Fmu, Instance, Reader, Step, Value, Variable};
use runner_engine::run::Grid;

fn variable<'a>(fmu: &'a Fmu, name: &str) -> &'a Variable {
    fmu.description.variables.iter().find(|v| v.name == name).unwrap_or_else(|| panic!("no variable {name}"))
}

fn done(step: Result<Step, String>) {
    match step {
        Ok(Step::Done) => {}
        Ok(_) => panic!("the step did not reach its end"),
        Err(e) => panic!("{e}"),
    }
}

/// max(car.z_s) over the communication points of one run of the system at `speed`.
fn run(car: &Fmu, road: &Fmu, speed: f64, grid: &Grid, polynomial: bool) -> Result<f64, String> {
    let (z_r_dot, z_r_dot_ext, z_s) = (variable(road, "z_r_dot"), variable(car, "z_r_dot_ext"), variable(car, "z_s"));
    let mut road_out = Reader::new(road.description.fmi_version, &[z_r_dot])?;
    let mut car_out = Reader::new(car.description.fmi_version, &[z_s])?;
    let (mut rate, mut sprung) = ([0.0], [0.0]);
    let vr = [z_r_dot_ext.value_reference];
    let (orders, mut rates) = ([1, 2, 3], [0.0; 3]);
    let (rate_vrs, input_vrs) = ([z_r_dot.value_reference; 3], [z_r_dot_ext.value_reference; 3]);
    let mut road_i = road.instantiate("road", false)?;
    let mut car_i = car.instantiate("car", false)?;
    // road.ssv, then the swept speed; car.ssv.
    for (i, fmu, params) in [
        (&mut road_i, road, vec![("profile", Value::Integer(0)), ("speed", Value::Real(30.0)), ("speed", Value::Real(speed))]),
        (&mut car_i, car, vec![("speed", Value::Real(0.0))]),
    ] {
        i.setup_experiment(grid.tolerance, grid.start, grid.stop)?;
        for (name, value) in &params {
            i.set(variable(fmu, name), value)?;
        }
        i.enter_initialization_mode()?;
    }
    // As the master: the road's rate passed to the car once per component, then the outputs.
    for _ in 0..2 {
        road_i.read(&mut road_out, &mut rate)?;
        car_i.set_reals(&vr, &rate)?;
    }
    road_i.exit_initialization_mode()?;
    car_i.exit_initialization_mode()?;
    road_i.read(&mut road_out, &mut rate)?;
    if polynomial {
        road_i.get_output_derivatives(&rate_vrs, &orders, &mut rates)?;
    }
    car_i.read(&mut car_out, &mut sprung)?;
    let mut max = sprung[0];
    let n = grid.steps();
    for i in 0..n {
        let (t, t_next) = (grid.time(i), grid.time(i + 1));
        car_i.set_reals(&vr, &rate)?;
        if polynomial {
            car_i.set_input_derivatives(&input_vrs, &orders, &rates)?;
        }
        done(road_i.do_step(t, t_next - t));
        done(car_i.do_step(t, t_next - t));
        road_i.read(&mut road_out, &mut rate)?;
        if polynomial {
            road_i.get_output_derivatives(&rate_vrs, &orders, &mut rates)?;
        }
        car_i.read(&mut car_out, &mut sprung)?;
        max = max.max(sprung[0]);
    }
    drop::<[Instance; 2]>([road_i, car_i]);
    Ok(max)
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let (car, road, speeds, stop, interval, polynomial) = match &args[..] {
        [_, car, road, speeds, stop, interval] => (car, road, speeds, stop, interval, false),
        [_, car, road, speeds, stop, interval, mode] if mode == "polynomial" => (car, road, speeds, stop, interval, true),
        _ => return Err("usage: bare_master CAR.fmu ROAD.fmu SPEEDS STOP INTERVAL [polynomial]".to_owned()),
    };
    let number = |s: &str| s.parse::<f64>().map_err(|e| format!("{s}: {e}"));
    let (car, road) = (Fmu::load(Path::new(car))?, Fmu::load(Path::new(road))?);
    let grid = Grid::checked(0.0, number(stop)?, number(interval)?, None)?;
    for speed in speeds.split(',') {
        let speed = number(speed)?;
        println!("{speed:?},{:?}", run(&car, &road, speed, &grid, polynomial)?);
    }
    Ok(())
}
