//! Linearization: a Model Exchange FMU initialized (and optionally simulated to a time T),
//! then linearized where it stands by the importer ([`fmi_importer::exchange::Jacobians`]) into
//! x' = A x + B u, y = C x + D u over its states, its continuous Real inputs and outputs; and
//! what a linear system gives: its eigenvalues, modes (natural frequency and damping ratio),
//! and frequency responses H(i w) = C (i w I - A)^-1 B + D.

use fmi_importer::exchange::{JacobianSource, Ports};
use fmi_importer::{Causality, Fmu, Interface, Kind, Reader, Step, Value, Variability, Variable};
pub use nalgebra::Complex;
use nalgebra::{DMatrix, DVector};

use crate::run::Grid;

/// A linearization to compute: where, after what, how.
pub struct Request<'r, 'a> {
    /// The instance name.
    pub name: &'r str,
    /// Start and stop time, tolerance and the runner's integrator (for `at`).
    pub grid: &'r Grid,
    /// Set before initialization, in order.
    pub assignments: &'r [(&'a Variable, Value)],
    /// Simulate to this time first (`None`: linearize at the initial state).
    pub at: Option<f64>,
    /// Directional derivatives when the FMU provides them, or central differences always.
    pub prefer: JacobianSource,
}

/// A linear model x' = A x + B u, y = C x + D u of an FMU at a time.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Linear {
    /// The time it was taken at.
    pub time: f64,
    /// The states' names, in the FMU's state order.
    pub states: Vec<String>,
    /// The states' values there.
    pub x: Vec<f64>,
    /// The continuous Real inputs' names.
    pub inputs: Vec<String>,
    /// The continuous Real outputs' names.
    pub outputs: Vec<String>,
    /// Row-major: `a[i][j]` = d(der x_i)/d(x_j).
    pub a: Vec<Vec<f64>>,
    pub b: Vec<Vec<f64>>,
    pub c: Vec<Vec<f64>>,
    pub d: Vec<Vec<f64>>,
    /// How the Jacobians were computed.
    pub source: JacobianSource,
}

/// Checks that `at` (`--at`) is a time within the start and stop time of `grid`.
fn check_time(grid: &Grid, at: Option<f64>) -> Result<(), String> {
    match at {
        Some(t) if !t.is_finite() => Err(format!("--at {t}: not a time")),
        Some(t) if t < grid.start => Err(format!("--at {t}: before the start time {}", grid.start)),
        Some(t) if t > grid.stop => {
            Err(format!("--at {t}: beyond the stop time {} (raise it with --stop-time, or linearize at an earlier time)", grid.stop))
        }
        _ => Ok(()),
    }
}

/// The continuous Real scalars of `causality`: the inputs and outputs a linearization is over.
fn continuous_reals(fmu: &Fmu, causality: Causality) -> Vec<&Variable> {
    fmu.description
        .variables
        .iter()
        .filter(|v| v.causality == causality && v.variability == Variability::Continuous && v.kind == Kind::Real && !v.is_array())
        .collect()
}

/// Instantiates, sets, initializes, simulates to `at` when asked, and linearizes. `fmu` must
/// have been loaded for Model Exchange.
pub fn linearize(fmu: &Fmu, request: &Request) -> Result<Linear, String> {
    if fmu.interface != Interface::ModelExchange {
        return Err(format!("{}: linearization needs the FMU loaded for Model Exchange", fmu.identifier));
    }
    let grid = request.grid;
    check_time(grid, request.at)?;
    let inputs = continuous_reals(fmu, Causality::Input);
    let outputs = continuous_reals(fmu, Causality::Output);
    let mut instance = fmu.instantiate(request.name, false)?;
    instance.set_solver(grid.solver);
    instance.setup_experiment(grid.tolerance, grid.start, grid.stop)?;
    for (variable, value) in request.assignments {
        instance.set(variable, value)?;
    }
    instance.enter_initialization_mode()?;
    instance.exit_initialization_mode()?;
    if let Some(at) = request.at.filter(|&t| t > grid.start) {
        advance(&mut instance, grid, at)?;
    }
    let mut input_reader = Reader::new(fmu.description.fmi_version, &inputs)?;
    let mut input_values = vec![0.0; inputs.len()];
    instance.read(&mut input_reader, &mut input_values)?;
    let mut reader = Reader::new(fmu.description.fmi_version, &outputs)?;
    let input_vrs: Vec<u32> = inputs.iter().map(|v| v.value_reference).collect();
    let output_vrs: Vec<u32> = outputs.iter().map(|v| v.value_reference).collect();
    let ports = Ports { inputs: &input_vrs, input_values: &input_values, outputs: &output_vrs, reader: &mut reader };
    let j = instance.linearize(ports, request.prefer)?;
    let states = j.states.iter().map(|&vr| state_name(fmu, vr)).collect();
    Ok(Linear {
        time: j.time,
        states,
        x: j.x,
        inputs: inputs.iter().map(|v| v.name.clone()).collect(),
        outputs: outputs.iter().map(|v| v.name.clone()).collect(),
        a: j.a.to_rows(),
        b: j.b.to_rows(),
        c: j.c.to_rows(),
        d: j.d.to_rows(),
        source: j.source,
    })
}

/// The name of the state with value reference `vr` (a Real; the first of FMI 2.0 aliases).
fn state_name(fmu: &Fmu, vr: u32) -> String {
    fmu.description
        .variables
        .iter()
        .find(|v| v.value_reference == vr && v.kind == Kind::Real)
        .map_or_else(|| format!("value reference {vr}"), |v| v.name.clone())
}

/// Steps the instance on the grid's communication interval from the start to `at` (the last
/// step shortened to end there).
fn advance(instance: &mut fmi_importer::Instance, grid: &Grid, at: f64) -> Result<(), String> {
    let mut t = grid.start;
    let mut i = 0usize;
    while t < at {
        i += 1;
        let next = (grid.start + i as f64 * grid.interval).min(at);
        match instance.do_step(t, next - t)? {
            Step::Done => {}
            Step::Event { time } => {
                if let Some(reason) = instance.handle_event(time)? {
                    return Err(format!("the model ended the simulation at t = {time}, before --at {at}: {reason}"));
                }
            }
            Step::Ended { reason, .. } => return Err(format!("the simulation ended before --at {at}: {reason}")),
        }
        t = next;
    }
    Ok(())
}

/// The eigenvalues of the square matrix `a` (row-major), ordered by modulus, then imaginary
/// part; an error when the QR iteration does not converge.
pub fn eigenvalues(a: &[Vec<f64>]) -> Result<Vec<Complex<f64>>, String> {
    let n = a.len();
    if n == 0 {
        return Ok(Vec::new());
    }
    if a.iter().flatten().any(|v| !v.is_finite()) {
        return Err("the state matrix A has a value that is not finite".to_owned());
    }
    let m = DMatrix::from_fn(n, n, |i, j| a[i][j]);
    let norm = m.norm();
    // At most 10000 sweeps of the QR iteration: a bounded time even for an adversarial matrix.
    let schur = nalgebra::Schur::try_new(m, f64::EPSILON, 10_000)
        .ok_or_else(|| "the eigenvalues of A did not converge in 10000 QR iterations".to_owned())?;
    // The QR iteration is backward stable: each eigenvalue is exact for a matrix within about
    // n eps |A| of A, so parts below that are rounding (a pure integrator's 0 comes out as
    // 1e-15, and would be a mode with a damping ratio of -1): they are set to zero.
    let noise = 16.0 * n as f64 * f64::EPSILON * norm;
    let snap = |v: f64| if v.abs() <= noise { 0.0 } else { v };
    let mut values: Vec<Complex<f64>> = schur.complex_eigenvalues().iter().map(|l| Complex::new(snap(l.re), snap(l.im))).collect();
    values.sort_by(|p, q| p.norm().total_cmp(&q.norm()).then(p.im.total_cmp(&q.im)));
    Ok(values)
}

/// A mode: a real eigenvalue, or a complex pair (given by its member with im >= 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// The eigenvalue (for a pair, the one with the positive imaginary part).
    pub eigenvalue: Complex<f64>,
    /// Its modulus |lambda| (rad/s).
    pub natural_frequency: f64,
    /// -re(lambda) / |lambda|; `None` for lambda = 0 (an integrator has no damping ratio).
    pub damping_ratio: Option<f64>,
}

/// The modes of `eigenvalues` (as [`eigenvalues`] orders them), by rising natural frequency:
/// each real eigenvalue one mode, each complex-conjugate pair one.
pub fn modes(eigenvalues: &[Complex<f64>]) -> Vec<Mode> {
    let mut modes: Vec<Mode> = eigenvalues
        .iter()
        .filter(|l| l.im >= 0.0)
        .map(|&l| {
            let wn = l.norm();
            // + 0.0: an undamped mode's ratio is 0, not -0.
            Mode { eigenvalue: l, natural_frequency: wn, damping_ratio: (wn > 0.0).then(|| -l.re / wn + 0.0) }
        })
        .collect();
    modes.sort_by(|p, q| p.natural_frequency.total_cmp(&q.natural_frequency).then(p.eigenvalue.re.total_cmp(&q.eigenvalue.re)));
    modes
}

impl Linear {
    /// The index of input `name`, or an error listing the inputs.
    pub fn input(&self, name: &str) -> Result<usize, String> {
        self.inputs
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| format!("'{name}' is not a continuous Real input of the FMU; its inputs are: {}", list(&self.inputs)))
    }

    /// The index of output `name`, or an error listing the outputs.
    pub fn output(&self, name: &str) -> Result<usize, String> {
        self.outputs
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| format!("'{name}' is not a continuous Real output of the FMU; its outputs are: {}", list(&self.outputs)))
    }

    /// H(i w) = C (i w I - A)^-1 B + D from input `input` to output `output` at each angular
    /// frequency of `omegas` (rad/s); an error at a frequency where i w is an eigenvalue of A.
    pub fn frequency_response(&self, input: usize, output: usize, omegas: &[f64]) -> Result<Vec<Complex<f64>>, String> {
        let n = self.a.len();
        let b = DVector::from_fn(n, |i, _| Complex::new(self.b[i][input], 0.0));
        let c = DVector::from_fn(n, |j, _| Complex::new(self.c[output][j], 0.0));
        let d = self.d[output][input];
        omegas
            .iter()
            .map(|&w| {
                let m = DMatrix::from_fn(n, n, |i, j| Complex::new(-self.a[i][j], if i == j { w } else { 0.0 }));
                let x = m.lu().solve(&b).ok_or_else(|| {
                    format!("the frequency response is infinite at w = {w} rad/s: i w is an eigenvalue of A (an undamped mode)")
                })?;
                Ok(c.dot(&x) + d)
            })
            .collect()
    }
}

fn list(names: &[String]) -> String {
    if names.is_empty() {
        "none".to_owned()
    } else {
        names.join(", ")
    }
}

/// `count` angular frequencies (rad/s) spaced evenly in log from `from` to `to` (both > 0).
pub fn log_spaced(from: f64, to: f64, count: usize) -> Vec<f64> {
    if count < 2 {
        return vec![from];
    }
    let (l0, l1) = (from.ln(), to.ln());
    (0..count).map(|k| (l0 + (l1 - l0) * k as f64 / (count - 1) as f64).exp()).collect()
}

/// The default frequency range of a frequency response (rad/s): from a decade below the
/// slowest mode to a decade above the fastest (the decades rounded out), or 0.01 to 1000 rad/s
/// when no mode has a frequency.
pub fn default_range(modes: &[Mode]) -> (f64, f64) {
    let finite: Vec<f64> = modes.iter().map(|m| m.natural_frequency).filter(|w| *w > 0.0 && w.is_finite()).collect();
    if finite.is_empty() {
        return (1e-2, 1e3);
    }
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(0.0, f64::max);
    (10f64.powf(lo.log10().floor() - 1.0), 10f64.powf(hi.log10().ceil() + 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn system(a: Vec<Vec<f64>>, b: Vec<Vec<f64>>, c: Vec<Vec<f64>>, d: Vec<Vec<f64>>) -> Linear {
        let n = a.len();
        Linear {
            time: 0.0,
            states: (0..n).map(|i| format!("x{i}")).collect(),
            x: vec![0.0; n],
            inputs: vec!["u".into()],
            outputs: vec!["y".into()],
            a,
            b,
            c,
            d,
            source: JacobianSource::FiniteDifferences,
        }
    }

    /// x'' + 2 zeta wn x' + wn^2 x = u: eigenvalues -zeta wn +- i wn sqrt(1 - zeta^2), one mode
    /// with that natural frequency and damping ratio, and H(i w) = 1 / (wn^2 - w^2 + 2 i zeta
    /// wn w), written by hand (rounding only: 1e-14).
    #[test]
    fn a_damped_oscillator_has_its_textbook_mode_and_response() {
        let (wn, zeta): (f64, f64) = (3.0, 0.2);
        let s = system(
            vec![vec![0.0, 1.0], vec![-wn * wn, -2.0 * zeta * wn]],
            vec![vec![0.0], vec![1.0]],
            vec![vec![1.0, 0.0]],
            vec![vec![0.0]],
        );
        let eig = eigenvalues(&s.a).unwrap();
        let wd = wn * (1.0 - zeta * zeta).sqrt();
        assert_eq!(eig.len(), 2);
        assert!((eig[0] - Complex::new(-zeta * wn, -wd)).norm() < 1e-14, "{eig:?}");
        assert!((eig[1] - Complex::new(-zeta * wn, wd)).norm() < 1e-14, "{eig:?}");
        let m = modes(&eig);
        assert_eq!(m.len(), 1);
        assert!((m[0].natural_frequency - wn).abs() < 1e-14 && (m[0].damping_ratio.unwrap() - zeta).abs() < 1e-14);
        let omegas = [0.5, 3.0, 10.0];
        for (w, h) in omegas.iter().zip(s.frequency_response(0, 0, &omegas).unwrap()) {
            let exact = Complex::new(1.0, 0.0) / Complex::new(wn * wn - w * w, 2.0 * zeta * wn * w);
            assert!((h - exact).norm() < 1e-14 * exact.norm(), "w = {w}: {h} against {exact}");
        }
    }

    /// An integrator (lambda = 0) has no damping ratio, and the response of an undamped mode at
    /// its own frequency is refused, saying why.
    #[test]
    fn an_integrator_and_a_resonance_are_reported_as_such() {
        let m = modes(&eigenvalues(&[vec![0.0]]).unwrap());
        assert_eq!(m[0].damping_ratio, None);
        let s = system(vec![vec![0.0, 1.0], vec![-4.0, 0.0]], vec![vec![0.0], vec![1.0]], vec![vec![1.0, 0.0]], vec![vec![0.0]]);
        let err = s.frequency_response(0, 0, &[2.0]).unwrap_err();
        assert!(err.contains("infinite at w = 2 rad/s"), "{err}");
        assert!(s.input("v").unwrap_err().contains("its inputs are: u"));
    }

    /// The quarter car's road height is a pure integrator: its eigenvalue is 0 exactly, not
    /// the QR iteration's 1e-15, so it is a mode without a damping ratio and the frequency range
    /// ignores it.
    #[test]
    fn rounding_does_not_make_an_integrator_a_mode() {
        let a = vec![
            vec![0.0, 0.0, 0.0, 1.0, 0.0],
            vec![0.0, 0.0, 0.0, 0.0, 1.0],
            vec![0.0, 0.0, 0.0, 0.0, 0.0],
            vec![-90.0, 90.0, 0.0, -6.5, 6.5],
            vec![600.0, -4766.666666666667, 4166.666666666667, 43.333333333333336, -43.666666666666664],
        ];
        let eig = eigenvalues(&a).unwrap();
        assert_eq!(eig[0], Complex::new(0.0, 0.0), "{eig:?}");
        let m = modes(&eig);
        assert_eq!(m[0].damping_ratio, None);
        assert_eq!(default_range(&m), (0.1, 1000.0));
    }

    #[test]
    fn default_ranges_round_out_to_decades_around_the_modes() {
        let m = modes(&[Complex::new(-1.0, 0.0), Complex::new(-0.5, 50.0), Complex::new(-0.5, -50.0)]);
        assert_eq!(default_range(&m), (0.1, 1000.0));
        let w = log_spaced(0.1, 1000.0, 5);
        assert!((w[2] - 10.0).abs() < 1e-12 && (w[4] - 1000.0).abs() < 1e-9);
    }
}
