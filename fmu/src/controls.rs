//! The solver controls every model gets (`solver`, `fixed_step`, `abs_tol`, `n_steps`,
//! `n_rhs`): their table rows, defaults, validation and the solver settings built from them.

use serde::{Deserialize, Serialize};

use crate::solver::{Method, Settings};

/// One of the toolkit's own variables, appended after the model's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Control {
    Solver,
    FixedStep,
    AbsTol,
    NSteps,
    NRhs,
}

/// Every control, in the order they are appended to each model's variable table.
pub const CONTROLS: [Control; 5] = [Control::Solver, Control::FixedStep, Control::AbsTol, Control::NSteps, Control::NRhs];

/// The settable solver controls of one instance (parameters: fixed once initialization ends).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Controls {
    pub solver: i32,
    pub fixed_step: f64,
    pub abs_tol: f64,
}

impl Default for Controls {
    fn default() -> Self {
        Controls { solver: Method::Dopri5.code(), fixed_step: 1e-3, abs_tol: 1e-9 }
    }
}

impl Controls {
    /// Solver settings for relative tolerance `rtol`, or a message naming the bad control.
    pub fn settings(&self, rtol: f64) -> Result<Settings, String> {
        let method = Method::from_code(self.solver).ok_or_else(|| {
            format!("parameter solver = {} is not a solver: use 0 (forward Euler), 1 (classical RK4) or 2 (Dormand-Prince 5(4))", self.solver)
        })?;
        let settings = Settings { method, fixed_step: self.fixed_step, rtol, atol: self.abs_tol };
        settings.validate().map_err(|e| e.to_string())?;
        Ok(settings)
    }
}

impl Control {
    /// Variable name.
    pub fn name(self) -> &'static str {
        match self {
            Control::Solver => "solver",
            Control::FixedStep => "fixed_step",
            Control::AbsTol => "abs_tol",
            Control::NSteps => "n_steps",
            Control::NRhs => "n_rhs",
        }
    }

    /// Variable description.
    pub fn description(self) -> &'static str {
        match self {
            Control::Solver => "Integration method: 0 = forward Euler, 1 = classical RK4, 2 = adaptive Dormand-Prince 5(4) (ode45)",
            Control::FixedStep => "Step size of forward Euler and RK4",
            Control::AbsTol => "Absolute tolerance of Dormand-Prince 5(4) (relative: fmi2SetupExperiment's tolerance)",
            Control::NSteps => "Accepted internal solver steps since initialization",
            Control::NRhs => "Right-hand-side evaluations since initialization",
        }
    }

    /// True for the two counters (integer outputs), false for the parameters.
    pub fn is_output(self) -> bool {
        matches!(self, Control::NSteps | Control::NRhs)
    }

    /// True for the integer-typed controls.
    pub fn is_integer(self) -> bool {
        matches!(self, Control::Solver | Control::NSteps | Control::NRhs)
    }

    /// SI unit, where it has one.
    pub fn unit(self) -> Option<&'static str> {
        match self {
            Control::FixedStep => Some("s"),
            _ => None,
        }
    }
}
