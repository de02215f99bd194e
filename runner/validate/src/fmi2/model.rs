//! The validator's view of an FMI 2.0 description: each variable with its base type, causality,
//! variability and effective `initial`, the continuous states in `Derivatives` order, and the
//! experiment the dynamic checks run.

use std::collections::HashSet;

use fmi_schema::fmi2 as s;

pub(crate) use s::{Causality, Initial, Variability};

/// The four value-reference spaces of FMI 2.0 (Enumeration is exchanged as Integer).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Base {
    Real,
    Integer,
    Boolean,
    String,
}

impl Base {
    pub(crate) const ALL: [Base; 4] = [Base::Real, Base::Integer, Base::Boolean, Base::String];

    pub(crate) fn name(self) -> &'static str {
        match self {
            Base::Real => "Real",
            Base::Integer => "Integer",
            Base::Boolean => "Boolean",
            Base::String => "String",
        }
    }
}

/// One variable as the checks see it.
#[derive(Debug, Clone)]
pub(crate) struct Var {
    pub name: String,
    pub vr: u32,
    pub base: Base,
    pub causality: Causality,
    pub variability: Variability,
    /// Effective initial (`None` for inputs and the independent variable).
    pub initial: Option<Initial>,
    /// A continuous-time state (the target of a listed derivative).
    pub is_state: bool,
    pub start: Option<s::StartValue>,
    pub min: Option<f64>,
    pub max: Option<f64>,
}

impl Var {
    /// A short description of what kind of variable this is, for messages.
    pub(crate) fn kind(&self) -> String {
        let what = match self.causality {
            Causality::Parameter => format!("{} parameter", self.variability),
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
        self.base != Base::String
    }
}

/// An FMI 2.0 description ready for the checks.
pub(crate) struct Model {
    pub md: s::ModelDescription,
    pub vars: Vec<Var>,
    /// Indices into `vars` of the continuous states, in `Derivatives` order.
    pub states: Vec<usize>,
    /// Indices into `vars` listed under InitialUnknowns.
    pub initial_unknowns: HashSet<usize>,
    pub event_indicators: usize,
}

impl Model {
    /// The checks' view of `md`.
    pub(crate) fn new(md: s::ModelDescription) -> Model {
        let position = |index: u32| (index as usize).checked_sub(1).filter(|&p| p < md.model_variables.len());
        let mut states = Vec::new();
        for unknown in &md.model_structure.derivatives {
            let Some(d) = position(unknown.index) else { continue };
            let Some(state) = md.model_variables[d].derivative().and_then(position) else { continue };
            states.push(state);
        }
        let state_set: HashSet<usize> = states.iter().copied().collect();
        let vars = md
            .model_variables
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let (min, max) = match &v.var_type {
                    s::VariableType::Real(r) => {
                        let declared = r.declared_type.as_deref().and_then(|t| md.simple_type(t)).and_then(|t| match &t.kind {
                            s::SimpleTypeKind::Real(rt) => Some(rt),
                            _ => None,
                        });
                        (r.attributes.min.or(declared.and_then(|t| t.min)), r.attributes.max.or(declared.and_then(|t| t.max)))
                    }
                    s::VariableType::Integer(n) => (n.attributes.min.map(f64::from), n.attributes.max.map(f64::from)),
                    s::VariableType::Enumeration(e) => (e.attributes.min.map(f64::from), e.attributes.max.map(f64::from)),
                    _ => (None, None),
                };
                Var {
                    name: v.name.clone(),
                    vr: v.value_reference,
                    base: match v.type_kind().base_type() {
                        s::TypeKind::Real => Base::Real,
                        s::TypeKind::Boolean => Base::Boolean,
                        s::TypeKind::String => Base::String,
                        _ => Base::Integer,
                    },
                    causality: v.causality(),
                    variability: v.variability(),
                    initial: v.initial(),
                    is_state: state_set.contains(&i),
                    start: v.start(),
                    min,
                    max,
                }
            })
            .collect();
        let initial_unknowns = md.model_structure.initial_unknowns.iter().filter_map(|u| position(u.index)).collect();
        let event_indicators = md.number_of_event_indicators.unwrap_or(0) as usize;
        Model { md, vars, states, initial_unknowns, event_indicators }
    }

    /// Number of continuous states.
    pub(crate) fn nx(&self) -> usize {
        self.states.len()
    }

    /// The variables of one base type.
    pub(crate) fn of(&self, base: Base) -> impl Iterator<Item = &Var> + '_ {
        self.vars.iter().filter(move |v| v.base == base)
    }

    /// A value reference no variable of any type uses: the standard requires fmi2Error for it.
    pub(crate) fn unknown_vr(&self) -> u32 {
        let used: HashSet<u32> = self.vars.iter().map(|v| v.vr).collect();
        let top = self.vars.iter().map(|v| v.vr).max().unwrap_or(0);
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
    /// The grid of `md`'s DefaultExperiment. With `variable_steps` false the run ends at the
    /// last whole step at or before the stop time.
    pub(crate) fn new(md: &s::ModelDescription, variable_steps: bool) -> Grid {
        let experiment = md.default_experiment.clone().unwrap_or_default();
        let finite = |v: Option<f64>| v.filter(|x| x.is_finite());
        let start = finite(experiment.start_time).unwrap_or(0.0);
        let stop = finite(experiment.stop_time).filter(|&s| s > start).unwrap_or(start + 1.0);
        let h = finite(experiment.step_size).filter(|&h| h > 0.0 && h <= stop - start).unwrap_or((stop - start) / 500.0);
        let exact = (stop - start) / h;
        let whole = (exact + 1e-9).floor();
        let mut steps = if variable_steps && exact - whole > 1e-9 { whole as usize + 1 } else { (whole as usize).max(1) };
        let shortened = steps > MAX_STEPS;
        steps = steps.min(MAX_STEPS);
        Grid { start, stop, h, steps, tolerance: finite(experiment.tolerance).filter(|t| *t > 0.0), shortened }
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
mod tests {
    use super::*;

    fn md(experiment: &str) -> s::ModelDescription {
        let xml = format!(
            r#"<fmiModelDescription fmiVersion="2.0" modelName="m" guid="g"><CoSimulation modelIdentifier="m"/>{experiment}<ModelVariables/><ModelStructure/></fmiModelDescription>"#
        );
        s::ModelDescription::from_xml(&xml).unwrap()
    }

    #[test]
    fn a_run_records_at_most_max_recorded_outputs() {
        let variables: String = (0..100)
            .map(|i| format!(r#"<ScalarVariable name="y{i}" valueReference="{i}" causality="output"><Real/></ScalarVariable>"#))
            .collect();
        let xml = format!(
            r#"<fmiModelDescription fmiVersion="2.0" modelName="m" guid="g"><CoSimulation modelIdentifier="m"/><ModelVariables>{variables}</ModelVariables><ModelStructure/></fmiModelDescription>"#
        );
        let model = Model::new(s::ModelDescription::from_xml(&xml).unwrap());
        assert_eq!((model.recorded().len(), model.recordable_count()), (MAX_RECORDED, 100));
        assert_eq!(model.recorded()[0], 0, "the first ones, in ModelVariables order");
    }

    #[test]
    fn the_grid_follows_the_default_experiment() {
        let g = Grid::new(&md(r#"<DefaultExperiment startTime="0" stopTime="3" stepSize="0.01"/>"#), true);
        assert_eq!((g.steps, g.point(300), g.shortened), (300, 3.0, false));
        assert_eq!(g.point(150), 1.5);
        // 1 / 0.3 is not whole: a last, shorter step where variable steps are allowed.
        let g = Grid::new(&md(r#"<DefaultExperiment stopTime="1" stepSize="0.3"/>"#), true);
        assert_eq!((g.steps, g.end()), (4, 1.0));
        let g = Grid::new(&md(r#"<DefaultExperiment stopTime="1" stepSize="0.3"/>"#), false);
        assert_eq!(g.steps, 3);
        assert!((g.end() - 0.9).abs() < 1e-15);
        // fmpy's defaults without a DefaultExperiment.
        let g = Grid::new(&md(""), true);
        assert_eq!((g.start, g.stop, g.steps), (0.0, 1.0, 500));
        let g = Grid::new(&md(r#"<DefaultExperiment stopTime="1e6" stepSize="1e-3"/>"#), true);
        assert_eq!((g.steps, g.shortened), (MAX_STEPS, true));
        assert_eq!(g.end(), 100.0);
    }
}
