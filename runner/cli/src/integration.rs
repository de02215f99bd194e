//! `--interface`, `--solver`, `--fixed-step` and `--abs-tolerance`: which interface of an FMU a
//! command drives, and for Model Exchange the runner's own integrator (a Co-Simulation FMU
//! integrates itself). The relative tolerance is `--tolerance`, for either interface.

use std::path::Path;

use fmi_importer::exchange::Counters;
use fmi_importer::{Description, Fmu, Interface, Method, Solver};
use runner_engine::run::{refuse_solver_under_co_simulation, solver_of, SolverOptionNames};

/// The interface and integrator options of `simulate`, `sweep` and `compare`.
#[derive(Debug, Clone, Default)]
pub struct Integration {
    /// The interface to drive (`None`: Co-Simulation when the FMU offers it, else Model Exchange).
    pub interface: Option<Interface>,
    /// The runner's integration method for Model Exchange: euler, rk4, dopri5, bs23, dop853,
    /// bdf or esdirk.
    pub solver: Option<String>,
    /// The step of Euler and RK4 (s).
    pub fixed_step: Option<f64>,
    /// DOPRI5's absolute tolerance.
    pub abs_tolerance: Option<f64>,
}

/// The integrator's options as the command line spells them.
const OPTION_NAMES: SolverOptionNames = SolverOptionNames {
    fixed_step: "--fixed-step ",
    abs_tolerance: "--abs-tolerance ",
    all: "--solver, --fixed-step and --abs-tolerance",
    to_model_exchange: "add --interface model-exchange, or for this toolkit's FMUs set their own solver with --set solver=N",
};

/// The interface for its command-line spelling, or a message listing both.
pub fn parse_interface(text: &str) -> Result<Interface, String> {
    Interface::from_name(text).ok_or_else(|| format!("'{text}' is not an interface: use model-exchange or co-simulation"))
}

impl Integration {
    /// True when an option of the runner's integrator was given.
    fn sets_solver(&self) -> bool {
        self.solver.is_some() || self.fixed_step.is_some() || self.abs_tolerance.is_some()
    }

    /// Loads the FMU at `path` for the chosen interface. The integrator's options are refused
    /// for a Co-Simulation run, where they would silently do nothing.
    pub fn load(&self, path: &Path) -> Result<Fmu, String> {
        let fmu = Fmu::load_as(path, self.interface)?;
        self.check(&fmu.description, &fmu.identifier, fmu.interface)?;
        Ok(fmu)
    }

    /// Refuses the integrator's options for an FMU that runs as Co-Simulation (`interface`),
    /// where they would silently do nothing.
    pub fn check(&self, description: &Description, identifier: &str, interface: Interface) -> Result<(), String> {
        refuse_solver_under_co_simulation(self.sets_solver(), description, identifier, interface, OPTION_NAMES)
    }

    /// The runner's integrator from the options, checked (defaults: the toolkit's FMUs' own
    /// solver controls, DOPRI5 with a 1 ms fixed step and abs_tol 1e-9).
    pub fn solver(&self) -> Result<Solver, String> {
        solver_of(self.solver.as_deref(), self.fixed_step, self.abs_tolerance, OPTION_NAMES)
    }
}

/// What the runner's integrator did in a Model Exchange run, for a line on stderr: steps,
/// derivative evaluations and, for the implicit methods, Jacobians and Newton failures.
pub fn work(c: &Counters, method: Method) -> String {
    let mut text = format!("the runner's {} integration took {} steps and {} derivative evaluations", method.name(), c.n_steps, c.n_rhs);
    if method.is_implicit() {
        let how = if c.n_directional > 0 {
            format!("{} directional-derivative calls", c.n_directional)
        } else {
            format!("{} of the evaluations", c.n_jacobian_columns)
        };
        text.push_str(&format!(", {} Jacobians ({how}), {} Newton failures", c.n_jacobians, c.n_newton_failures));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_are_checked_with_their_names() {
        assert_eq!(parse_interface("model-exchange").unwrap(), Interface::ModelExchange);
        assert!(parse_interface("me").unwrap_err().contains("use model-exchange or co-simulation"));
        let bad = Integration { solver: Some("ode45".into()), ..Default::default() };
        assert!(bad.solver().unwrap_err().contains("unknown solver 'ode45': use euler, rk4, dopri5, bs23, dop853"));
        let bad = Integration { fixed_step: Some(0.0), ..Default::default() };
        assert!(bad.solver().unwrap_err().contains("--fixed-step 0 must be a positive number"));
        let bad = Integration { abs_tolerance: Some(-1.0), ..Default::default() };
        assert!(bad.solver().unwrap_err().contains("--abs-tolerance -1"));
        let good = Integration { solver: Some("RK4".into()), fixed_step: Some(1e-4), ..Default::default() };
        assert_eq!(good.solver().unwrap(), Solver { method: Method::Rk4, fixed_step: 1e-4, abs_tol: 1e-9 });
    }
}
