//! The solver controls every FMU of this toolkit exposes (`solver`, `fixed_step`, `abs_tol`,
//! `max_step`, and the counters `n_steps`, `n_rhs`): their names, types, defaults, validation,
//! descriptions and messages, in one place. The export toolkit appends them to every variable table and applies them; the
//! runner's `compare` sets them through FMI by these names and codes.

use serde::{Deserialize, Serialize};

use crate::{Method, Settings};

/// One of the toolkit's own variables, appended after the model's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Control {
    Solver,
    FixedStep,
    AbsTol,
    NSteps,
    NRhs,
    MaxStep,
}

/// Every control, in the order they are appended to each model's variable table (`max_step`,
/// the latest, last: the others keep their value references).
pub const CONTROLS: [Control; 6] = [Control::Solver, Control::FixedStep, Control::AbsTol, Control::NSteps, Control::NRhs, Control::MaxStep];

/// The settable solver controls of one instance (parameters: fixed once initialization ends).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Controls {
    pub solver: i32,
    pub fixed_step: f64,
    pub abs_tol: f64,
    /// Largest adaptive step (s); 0 = unlimited.
    pub max_step: f64,
}

impl Default for Controls {
    fn default() -> Self {
        let s = Settings::default();
        Controls { solver: s.method.code(), fixed_step: s.fixed_step, abs_tol: s.atol, max_step: s.max_step }
    }
}

/// The methods as `solver` codes, for messages: "0 (forward Euler), 1 (classical RK4) or ...".
pub fn solver_choices() -> String {
    let items: Vec<String> = Method::ALL.iter().map(|m| format!("{} ({})", m.code(), m.title())).collect();
    match items.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => items.join(""),
    }
}

impl Controls {
    /// Solver settings for relative tolerance `rtol`, or a message naming the bad control.
    pub fn settings(&self, rtol: f64) -> Result<Settings, String> {
        let method = Method::from_code(self.solver)
            .ok_or_else(|| format!("parameter solver = {} is not a solver: use {}", self.solver, solver_choices()))?;
        let settings = Settings { method, fixed_step: self.fixed_step, rtol, atol: self.abs_tol, max_step: self.max_step };
        settings.validate().map_err(|e| e.to_string())?;
        Ok(settings)
    }

    /// The value of a settable control, as a number.
    pub fn get(&self, control: Control) -> Option<f64> {
        match control {
            Control::Solver => Some(self.solver as f64),
            Control::FixedStep => Some(self.fixed_step),
            Control::AbsTol => Some(self.abs_tol),
            Control::MaxStep => Some(self.max_step),
            Control::NSteps | Control::NRhs => None,
        }
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
            Control::MaxStep => "max_step",
        }
    }

    /// The control called `name`.
    pub fn named(name: &str) -> Option<Control> {
        CONTROLS.into_iter().find(|c| c.name() == name)
    }

    /// Variable description.
    pub fn description(self) -> &'static str {
        match self {
            Control::Solver => {
                "Integration method: 0 = forward Euler, 1 = classical RK4 (both with fixed_step), 2 = adaptive Dormand-Prince 5(4) \
                 (ode45), 3 = Bogacki-Shampine 3(2) (ode23), 4 = Dormand-Prince 8(5,3) (DOP853), and for stiff systems the implicit \
                 5 = BDF of orders 1 to 5 (CVODE's class) and 6 = ESDIRK 3(2), L-stable. The adaptive methods step across \
                 communication points, take the values there from the step's dense output and go on from the step's end; a new \
                 input, parameter or state value, or a restored FMU state, restarts them from the communication point, and no \
                 step crosses an event"
            }
            Control::FixedStep => {
                "Step size of forward Euler and RK4; a communication interval that is not a multiple of it ends with a shorter step"
            }
            Control::AbsTol => "Absolute tolerance of the adaptive methods (relative: fmi2SetupExperiment's tolerance)",
            Control::NSteps => "Accepted internal solver steps since initialization",
            Control::NRhs => "Right-hand-side evaluations since initialization",
            Control::MaxStep => "Largest step of the adaptive methods, as ode45's MaxStep; 0 = unlimited (the default)",
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
            Control::FixedStep | Control::MaxStep => Some("s"),
            _ => None,
        }
    }

    /// The start value of a settable control; `None` for the counters.
    pub fn default_value(self) -> Option<f64> {
        Controls::default().get(self)
    }

    /// Checks a value for this control as it is set, naming the control and the rule it breaks.
    pub fn check(self, value: f64) -> Result<(), String> {
        let name = self.name();
        match self {
            Control::Solver => match Method::from_code(value as i32).filter(|_| value.fract() == 0.0) {
                Some(_) => Ok(()),
                None => Err(format!("{name} = {value} refused: use {}", solver_choices())),
            },
            Control::FixedStep if value <= 0.0 || value.is_nan() => {
                Err(format!("{name} = {value} refused: the step must be greater than zero"))
            }
            Control::AbsTol if value < 0.0 => Err(format!("{name} = {value} refused: the tolerance must not be negative")),
            Control::MaxStep if value < 0.0 => {
                Err(format!("{name} = {value} refused: the largest step must not be negative (0 means unlimited)"))
            }
            Control::NSteps | Control::NRhs => Err(format!("'{name}' is an output and cannot be set")),
            _ => Ok(()),
        }
    }

    /// Stores a checked value (see [`Control::check`]) in `controls`.
    pub fn store(self, controls: &mut Controls, value: f64) {
        match self {
            Control::Solver => controls.solver = value as i32,
            Control::FixedStep => controls.fixed_step = value,
            Control::AbsTol => controls.abs_tol = value,
            Control::MaxStep => controls.max_step = value,
            Control::NSteps | Control::NRhs => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The messages list every method, so a new method cannot be left out of them.
    #[test]
    fn messages_name_the_control_and_every_method() {
        let e = Control::Solver.check(9.0).unwrap_err();
        assert!(e.starts_with("solver = 9 refused: use 0 (forward Euler), 1 (classical RK4)"), "{e}");
        assert!(e.contains(&format!("{} (", Method::ALL.len() - 1)), "{e}");
        assert!(Control::FixedStep.check(0.0).unwrap_err().contains("greater than zero"));
        assert!(Control::AbsTol.check(-1.0).unwrap_err().contains("must not be negative"));
        assert!(Control::AbsTol.check(0.0).is_ok());
        assert!(Control::MaxStep.check(-1e-3).unwrap_err().contains("max_step = -0.001 refused"));
        assert!(Control::MaxStep.check(0.0).is_ok());
        assert_eq!(Control::MaxStep.default_value(), Some(0.0));
        assert_eq!(Control::Solver.check(4.0), Ok(()));
        assert!(e.ends_with("4 (Dormand-Prince 8(5,3)), 5 (implicit BDF, orders 1-5) or 6 (implicit ESDIRK 3(2))"), "{e}");
        assert_eq!(Control::named("abs_tol"), Some(Control::AbsTol));
        assert_eq!(Control::FixedStep.default_value(), Some(1e-3));
        let mut c = Controls::default();
        Control::Solver.store(&mut c, 0.0);
        assert_eq!(c.settings(1e-6).unwrap().method, Method::Euler);
        assert!(Controls { solver: 7, ..c }.settings(1e-6).unwrap_err().contains("is not a solver: use 0 (forward Euler)"));
    }
}
