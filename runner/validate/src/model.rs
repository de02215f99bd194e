//! The probes' view of a description, the same for both versions (each version's
//! `description.rs` builds it): the variables the probes exchange, each with its type,
//! causality, variability and effective `initial`; the continuous states; the capability flags
//! of each interface; and the communication grid the runs use.

use std::collections::HashSet;
use std::fmt;

use crate::fmi::{Interface, Type};
use crate::report::Finding;

macro_rules! attribute {
    ($(#[$meta:meta])* $name:ident { $($variant:ident = $text:literal),+ $(,)? }) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub(crate) enum $name {
            $($variant),+
        }

        impl $name {
            /// The attribute value as written in modelDescription.xml.
            pub(crate) fn as_str(self) -> &'static str {
                match self {
                    $($name::$variant => $text),+
                }
            }

            /// The value written `text`, if any of them.
            pub(crate) fn parse(text: &str) -> Option<$name> {
                match text {
                    $($text => Some($name::$variant),)+
                    _ => None,
                }
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.as_str())
            }
        }
    };
}

attribute! {
    /// `causality`, of either version (FMI 3.0 adds structuralParameter).
    Causality {
        Parameter = "parameter",
        CalculatedParameter = "calculatedParameter",
        StructuralParameter = "structuralParameter",
        Input = "input",
        Output = "output",
        Local = "local",
        Independent = "independent",
    }
}

attribute! {
    /// `variability`.
    Variability { Constant = "constant", Fixed = "fixed", Tunable = "tunable", Discrete = "discrete", Continuous = "continuous" }
}

attribute! {
    /// `initial`.
    Initial { Exact = "exact", Approx = "approx", Calculated = "calculated" }
}

/// A start value as the probes use it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Start {
    /// A number (Booleans as 0 and 1).
    Number(f64),
    Text(String),
}

/// One variable as the checks see it.
#[derive(Debug, Clone)]
pub(crate) struct Var {
    pub name: String,
    pub vr: u32,
    pub ty: Type,
    pub causality: Causality,
    pub variability: Variability,
    /// Effective initial (`None` for inputs and the independent variable in FMI 2.0).
    pub initial: Option<Initial>,
    /// A continuous-time state (the target of a listed derivative).
    pub is_state: bool,
    pub start: Option<Start>,
    pub min: Option<f64>,
    pub max: Option<f64>,
}

impl Var {
    /// A short description of what kind of variable this is, for messages.
    pub(crate) fn kind(&self) -> String {
        let what = match self.causality {
            Causality::Parameter => format!("{} parameter", self.variability),
            Causality::StructuralParameter => format!("{} structural parameter", self.variability),
            Causality::CalculatedParameter => "calculated parameter".to_owned(),
            Causality::Input => format!("{} input", self.variability),
            Causality::Output if self.is_state => "output (a continuous state)".to_owned(),
            Causality::Output => format!("{} output", self.variability),
            Causality::Local if self.variability == Variability::Constant => "constant".to_owned(),
            Causality::Local if self.is_state => "continuous state".to_owned(),
            Causality::Local => format!("{} local", self.variability),
            Causality::Independent => "independent variable".to_owned(),
        };
        match self.initial {
            Some(i) if self.variability != Variability::Constant => format!("{what}, initial={i}"),
            _ => what,
        }
    }

    /// True for the types whose values the runs record (Booleans as 0/1).
    pub(crate) fn is_numeric(&self) -> bool {
        self.ty != Type::String
    }
}

/// What the description says an interface can do.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Capabilities {
    /// The binary's name.
    pub model_identifier: String,
    pub can_get_and_set_fmu_state: bool,
    pub can_serialize_fmu_state: bool,
    pub can_be_instantiated_only_once_per_process: bool,
    /// Co-Simulation: steps of any size.
    pub can_handle_variable_communication_step_size: bool,
    /// FMI 3.0 Co-Simulation: Event Mode (hasEventMode), so the instances are made with
    /// eventModeUsed.
    pub event_mode: bool,
    /// FMI 3.0 Co-Simulation: early return (mightReturnEarlyFromDoStep), so the instances
    /// are made with earlyReturnAllowed.
    pub early_return: bool,
    /// Model Exchange: CompletedIntegratorStep after every step (always in FMI 2.0).
    pub needs_completed_integrator_step: bool,
}

/// The DefaultExperiment as written.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Experiment {
    pub start: Option<f64>,
    pub stop: Option<f64>,
    pub step: Option<f64>,
    pub tolerance: Option<f64>,
}

/// What the validator reads of a description for its static checks.
pub(crate) struct Declared {
    pub fmi_version: String,
    pub model_name: String,
    /// The interfaces it declares, each with its model identifier.
    pub interfaces: Vec<(Interface, String)>,
    /// FMI 3.0 Co-Simulation with Event Mode (hasEventMode): its instances have that state.
    pub event_mode: bool,
    /// The static checks' findings (the description's rules).
    pub findings: Vec<Finding>,
}

/// A description ready for the checks.
#[derive(Debug, Clone, Default)]
pub(crate) struct Model {
    /// The GUID or instantiationToken.
    pub token: String,
    /// The variables the probes exchange, in ModelVariables order.
    pub vars: Vec<Var>,
    /// The value references of every variable, those the probes do not exchange too.
    pub value_references: Vec<u32>,
    /// Indices into `vars` listed under InitialUnknowns.
    pub initial_unknowns: HashSet<usize>,
    /// The numbers of continuous states and event indicators the description declares; `None`
    /// where it cannot be known (an FMI 3.0 array sized by a structural parameter).
    pub nx: Option<usize>,
    pub nz: Option<usize>,
    pub experiment: Experiment,
    pub co_simulation: Option<Capabilities>,
    pub model_exchange: Option<Capabilities>,
}

impl Model {
    /// Number of continuous states (as declared; 0 where unknown).
    pub(crate) fn nx(&self) -> usize {
        self.nx.unwrap_or(0)
    }

    /// Number of event indicators (as declared; 0 where unknown).
    pub(crate) fn nz(&self) -> usize {
        self.nz.unwrap_or(0)
    }

    /// The variables of one type.
    pub(crate) fn of(&self, ty: Type) -> impl Iterator<Item = &Var> + '_ {
        self.vars.iter().filter(move |v| v.ty == ty)
    }

    /// The capabilities of `interface`, if the FMU declares it.
    pub(crate) fn interface(&self, interface: Interface) -> Option<&Capabilities> {
        match interface {
            Interface::CoSimulation => self.co_simulation.as_ref(),
            Interface::ModelExchange => self.model_exchange.as_ref(),
        }
    }

    /// The capabilities of `interface`, all false (and only once per process) where it is
    /// not declared.
    pub(crate) fn capabilities(&self, interface: Interface) -> Capabilities {
        self.interface(interface)
            .cloned()
            .unwrap_or(Capabilities { can_be_instantiated_only_once_per_process: true, ..Capabilities::default() })
    }

    /// A value reference no variable of any type uses: the standard requires Error for it.
    pub(crate) fn unknown_vr(&self) -> u32 {
        let used: HashSet<u32> = self.value_references.iter().copied().collect();
        let top = self.value_references.iter().copied().max().unwrap_or(0);
        match top.checked_add(1) {
            Some(vr) => vr,
            None => (0..u32::MAX).find(|vr| !used.contains(vr)).unwrap_or(u32::MAX),
        }
    }

    /// The variables a run records: the numeric outputs, else every numeric variable that is
    /// not a parameter (an FMU without outputs still has a trajectory to compare); at most
    /// [`MAX_RECORDED`] of them, so that a run's record stays small.
    pub(crate) fn recorded(&self) -> Vec<usize> {
        self.recordable().into_iter().take(MAX_RECORDED).collect()
    }

    /// How many variables a run would record without the [`MAX_RECORDED`] bound.
    pub(crate) fn recordable_count(&self) -> usize {
        self.recordable().len()
    }

    fn recordable(&self) -> Vec<usize> {
        let outputs: Vec<usize> =
            (0..self.vars.len()).filter(|&i| self.vars[i].causality == Causality::Output && self.vars[i].is_numeric()).collect();
        if !outputs.is_empty() {
            return outputs;
        }
        (0..self.vars.len())
            .filter(|&i| {
                let v = &self.vars[i];
                v.is_numeric() && matches!(v.causality, Causality::Local | Causality::Independent) && v.variability != Variability::Constant
            })
            .collect()
    }
}

/// The communication grid the dynamic checks use: the DefaultExperiment, with the defaults
/// fmpy uses where it is silent (stop 1 s, 500 intervals), and at most [`MAX_STEPS`] steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Grid {
    pub start: f64,
    pub stop: f64,
    pub h: f64,
    pub steps: usize,
    pub tolerance: Option<f64>,
    /// The DefaultExperiment asks for more than MAX_STEPS steps; the runs stop after them.
    pub shortened: bool,
}

/// The most communication steps one run takes (a run of our FMUs takes 10,000).
pub(crate) const MAX_STEPS: usize = 100_000;

/// The most variables a run records: 64 values at 100,000 points are 51 MB, and a run's record
/// is kept a few times over (the reference, the threads' runs).
pub(crate) const MAX_RECORDED: usize = 64;

impl Grid {
    /// The grid of `experiment`. With `variable_steps` false the run ends at the last whole
    /// step at or before the stop time.
    pub(crate) fn new(experiment: &Experiment, variable_steps: bool) -> Grid {
        let finite = |v: Option<f64>| v.filter(|x| x.is_finite());
        let start = finite(experiment.start).unwrap_or(0.0);
        let stop = finite(experiment.stop).filter(|&s| s > start).unwrap_or(start + 1.0);
        let h = finite(experiment.step).filter(|&h| h > 0.0 && h <= stop - start).unwrap_or((stop - start) / 500.0);
        let exact = (stop - start) / h;
        let whole = (exact + 1e-9).floor();
        let mut steps = if variable_steps && exact - whole > 1e-9 { whole as usize + 1 } else { (whole as usize).max(1) };
        let shortened = steps > MAX_STEPS;
        steps = steps.min(MAX_STEPS);
        Grid { start, stop, h, steps, tolerance: finite(experiment.tolerance).filter(|t| *t > 0.0), shortened }
    }

    /// The grid the runs of `interface` use: with a last, shorter step where the interface
    /// can take one (Model Exchange, and Co-Simulation with
    /// canHandleVariableCommunicationStepSize).
    pub(crate) fn of(model: &Model, interface: Interface) -> Grid {
        let variable = interface == Interface::ModelExchange
            || model.co_simulation.as_ref().is_some_and(|c| c.can_handle_variable_communication_step_size);
        Grid::new(&model.experiment, variable)
    }

    /// Communication point `k` (0..=steps): start + k h, the last one exactly the stop time.
    pub(crate) fn point(&self, k: usize) -> f64 {
        let t = self.start + k as f64 * self.h;
        if k == self.steps && !self.shortened && (t - self.stop).abs() <= 1e-9 * self.stop.abs().max(self.h) {
            self.stop
        } else {
            t.min(self.stop)
        }
    }

    /// Where the runs end.
    pub(crate) fn end(&self) -> f64 {
        self.point(self.steps)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A variable of type `ty` named `name`, value reference `vr`.
    pub(crate) fn var(name: &str, vr: u32, ty: Type, causality: Causality, variability: Variability, initial: Option<Initial>) -> Var {
        Var { name: name.into(), vr, ty, causality, variability, initial, is_state: false, start: None, min: None, max: None }
    }

    fn experiment(start: Option<f64>, stop: Option<f64>, step: Option<f64>) -> Experiment {
        Experiment { start, stop, step, tolerance: None }
    }

    #[test]
    fn a_run_records_at_most_max_recorded_outputs() {
        let vars: Vec<Var> =
            (0..100).map(|i| var(&format!("y{i}"), i, Type::Real, Causality::Output, Variability::Continuous, None)).collect();
        let model = Model { value_references: (0..100).collect(), vars, ..Model::default() };
        assert_eq!((model.recorded().len(), model.recordable_count()), (MAX_RECORDED, 100));
        assert_eq!(model.recorded()[0], 0, "the first ones, in ModelVariables order");
        assert_eq!(model.unknown_vr(), 100);
    }

    /// Without outputs a run records the locals and the independent variable that vary, not
    /// the parameters, constants or Strings.
    #[test]
    fn without_outputs_a_run_records_what_varies() {
        use Causality as C;
        use Variability as V;
        let vars = vec![
            var("time", 0, Type::Real, C::Independent, V::Continuous, None),
            var("k", 1, Type::Real, C::Parameter, V::Fixed, Some(Initial::Exact)),
            var("pi", 2, Type::Real, C::Local, V::Constant, Some(Initial::Exact)),
            var("n", 3, Type::Integer, C::Local, V::Discrete, Some(Initial::Calculated)),
            var("label", 4, Type::String, C::Local, V::Discrete, Some(Initial::Calculated)),
        ];
        let model = Model { vars, ..Model::default() };
        assert_eq!(model.recorded(), vec![0, 3]);
    }

    #[test]
    fn an_unknown_value_reference_is_found_past_the_largest() {
        let model = Model { value_references: vec![u32::MAX, 0, 1], ..Model::default() };
        assert_eq!(model.unknown_vr(), 2);
    }

    #[test]
    fn the_kind_of_a_variable_is_named() {
        let mut v = var("x", 0, Type::Real, Causality::Local, Variability::Continuous, Some(Initial::Exact));
        v.is_state = true;
        assert_eq!(v.kind(), "continuous state, initial=exact");
        let k = var("k", 1, Type::Real, Causality::Parameter, Variability::Fixed, Some(Initial::Exact));
        assert_eq!(k.kind(), "fixed parameter, initial=exact");
        assert_eq!(Causality::parse("structuralParameter"), Some(Causality::StructuralParameter));
    }

    #[test]
    fn the_grid_follows_the_default_experiment() {
        let g = Grid::new(&experiment(Some(0.0), Some(3.0), Some(0.01)), true);
        assert_eq!((g.steps, g.point(300), g.shortened), (300, 3.0, false));
        assert_eq!(g.point(150), 1.5);
        // 1 / 0.3 is not whole: a last, shorter step where variable steps are allowed.
        let g = Grid::new(&experiment(None, Some(1.0), Some(0.3)), true);
        assert_eq!((g.steps, g.end()), (4, 1.0));
        let g = Grid::new(&experiment(None, Some(1.0), Some(0.3)), false);
        assert_eq!(g.steps, 3);
        assert!((g.end() - 0.9).abs() < 1e-15);
        // fmpy's defaults without a DefaultExperiment.
        let g = Grid::new(&Experiment::default(), true);
        assert_eq!((g.start, g.stop, g.steps), (0.0, 1.0, 500));
        let g = Grid::new(&experiment(None, Some(1e6), Some(1e-3)), true);
        assert_eq!((g.steps, g.shortened), (MAX_STEPS, true));
        assert_eq!(g.end(), 100.0);
        // A step larger than the run, or not positive: the default 500 intervals.
        let g = Grid::new(&experiment(None, Some(2.0), Some(-1.0)), true);
        assert_eq!((g.steps, g.h), (500, 2.0 / 500.0));
    }
}
