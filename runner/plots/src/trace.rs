//! A run kept in memory: the time and the values of chosen variables at every communication
//! point, looked up by name, and the events found in it (changes of discrete outputs such as
//! the bumper's `in_contact` or the trebuchet's `regime`). Plots and animations are drawn from it.

use fmi_importer::{Causality, Description, Fmu, Kind, Value, Variability, Variable};
use runner_engine::run::{Grid, Recording, Run, Texts};
use runner_engine::variables;
use solvers::controls::CONTROLS;

/// Time and values of a run.
#[derive(Debug, Clone, Default)]
pub struct Trace {
    /// Variable names, one per column.
    pub names: Vec<String>,
    /// Communication points (s).
    pub time: Vec<f64>,
    /// `columns[j][i]`: variable `names[j]` at `time[i]` (Booleans as 0/1).
    pub columns: Vec<Vec<f64>>,
    /// Why the model stopped before the stop time, if it did.
    pub ended_early: Option<String>,
}

impl Trace {
    /// Runs `fmu` on `grid` with `assignments` and keeps `variables` at every point.
    pub fn record(
        fmu: &Fmu,
        instance_name: &str,
        grid: &Grid,
        assignments: &[(&Variable, Value)],
        variables: &[&Variable],
    ) -> Result<Trace, String> {
        let recording = Trace::recording(&fmu.description, variables, assignments, false)?;
        Trace::record_with(fmu, instance_name, grid, assignments, &recording, false, |_, _, _| Ok(()))
    }

    /// The columns that recording `variables` gives (an array's elements each, sized with
    /// `assignments`), with a row at each event too when `events`.
    pub fn recording<'a>(
        description: &Description,
        variables: &[&'a Variable],
        assignments: &[(&Variable, Value)],
        events: bool,
    ) -> Result<Recording<'a>, String> {
        let mut recording = Recording::new(description, variables, assignments)?;
        recording.events = events;
        Ok(recording)
    }

    /// [`Trace::record`] of a [`Recording`]'s columns, also handing every sample to `sample`
    /// as it arrives (a CSV row), with the reader that gives each column exactly.
    pub fn record_with(
        fmu: &Fmu,
        instance_name: &str,
        grid: &Grid,
        assignments: &[(&Variable, Value)],
        recording: &Recording,
        debug_logging: bool,
        mut sample: impl FnMut(f64, &[f64], &dyn Texts) -> Result<(), String>,
    ) -> Result<Trace, String> {
        let mut trace = Trace::empty(recording, grid);
        let run =
            Run { name: instance_name, grid, assignments, inputs: None, recording, debug_logging, initial_state: None, final_state: false };
        let outcome = run.execute(fmu, |t: f64, values: &[f64], texts: &dyn Texts| {
            trace.push(t, values);
            sample(t, values, texts)
        })?;
        trace.ended_early = outcome.ended_early;
        Ok(trace)
    }

    /// A trace of `recording`'s columns with no samples yet, sized for `grid`.
    pub fn empty(recording: &Recording, grid: &Grid) -> Trace {
        let rows = grid.steps().saturating_add(1).min(1 << 16);
        Trace { names: recording.names.clone(), columns: vec![Vec::with_capacity(rows); recording.names.len()], ..Trace::default() }
    }

    /// Appends the sample at `t`.
    pub fn push(&mut self, t: f64, values: &[f64]) {
        self.time.push(t);
        for (column, &v) in self.columns.iter_mut().zip(values) {
            column.push(v);
        }
    }

    /// The column of `name`, if recorded.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.names.iter().position(|n| n == name).map(|j| self.columns[j].as_slice())
    }

    /// The column of `name`, or an error naming it.
    pub fn get(&self, name: &str) -> Result<&[f64], String> {
        self.column(name).ok_or_else(|| format!("the run recorded no variable '{name}'"))
    }

    /// `(time, value)` pairs of `name`.
    pub fn series(&self, name: &str) -> Result<Vec<(f64, f64)>, String> {
        Ok(self.time.iter().copied().zip(self.get(name)?.iter().copied()).collect())
    }

    /// `(x, y)` pairs of two variables.
    pub fn pairs(&self, x: &str, y: &str) -> Result<Vec<(f64, f64)>, String> {
        Ok(self.get(x)?.iter().copied().zip(self.get(y)?.iter().copied()).collect())
    }

    /// The value of `name` at the last sample.
    pub fn last(&self, name: &str) -> Result<f64, String> {
        self.get(name)?.last().copied().ok_or_else(|| format!("the run of '{name}' has no samples"))
    }
}

/// The variable called `name` if its values are numbers (any numeric type, Booleans as 0/1).
pub fn numeric_variable<'a>(description: &'a Description, name: &str) -> Result<&'a Variable, String> {
    let v = variables::find(description, name)?;
    if v.kind.is_numeric() {
        Ok(v)
    } else {
        Err(format!("'{name}' is a {}; only numbers can be plotted or shown", v.kind))
    }
}

/// An event seen in a run: discrete outputs changed between two communication points.
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    /// The first communication point showing the new values (the event lies in the interval
    /// before it).
    pub time: f64,
    /// Index of that sample.
    pub index: usize,
    /// What changed, e.g. `in_contact → false` or `regime → 4`.
    pub text: String,
}

/// Most changes a discrete output may show and still be read as marking events: a counter that
/// changes at every step is no event signal.
const MAX_EVENT_CHANGES: usize = 20;

/// The discrete outputs of `description` that can mark events: Boolean, Integer and discrete
/// Real outputs, without the toolkit's solver counters.
pub fn event_variables(description: &Description) -> Vec<&Variable> {
    description
        .outputs()
        .filter(|v| v.kind.is_numeric() && v.variability != Variability::Continuous)
        .filter(|v| !CONTROLS.iter().any(|c| c.name() == v.name))
        .collect()
}

/// The events of `trace` found in the columns of `variables` (from [`event_variables`]):
/// each time one or more of them changed. Changes of Booleans and Integers name the event; a
/// discrete Real (a recorded time, a range) names it only when nothing else changed then.
pub fn events(trace: &Trace, variables: &[&Variable]) -> Vec<Event> {
    let watched: Vec<(&Variable, &[f64])> = variables
        .iter()
        .filter_map(|v| trace.column(&v.name).map(|c| (*v, c)))
        .filter(|(_, c)| c.windows(2).filter(|w| w[0] != w[1] && !(w[0].is_nan() && w[1].is_nan())).count() <= MAX_EVENT_CHANGES)
        .collect();
    let mut found = Vec::new();
    for i in 1..trace.time.len() {
        let changed: Vec<&(&Variable, &[f64])> =
            watched.iter().filter(|(_, c)| c[i] != c[i - 1] && !(c[i].is_nan() && c[i - 1].is_nan())).collect();
        if changed.is_empty() {
            continue;
        }
        let naming: Vec<String> = changed.iter().filter(|(v, _)| v.kind != Kind::Real).map(|(v, c)| change_text(v, c[i])).collect();
        let text = if naming.is_empty() {
            changed.iter().map(|(v, c)| change_text(v, c[i])).collect::<Vec<_>>().join(", ")
        } else {
            naming.join(", ")
        };
        found.push(Event { time: trace.time[i], index: i, text });
    }
    found
}

fn change_text(v: &Variable, value: f64) -> String {
    match v.kind {
        Kind::Boolean => format!("{} → {}", v.name, value != 0.0),
        Kind::Integer | Kind::Enumeration => format!("{} → {}", v.name, value),
        _ => format!("{} = {}", v.name, short(value)),
    }
}

/// A number in at most 4 significant digits.
pub fn short(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (x.fract() == 0.0 && x.abs() < 1e6) {
        return format!("{x}");
    }
    // A whole number up to rounding (60 deg read back from radians) is shown as one.
    if x.round() != 0.0 && (x - x.round()).abs() < 1e-9 * x.abs() && x.abs() < 1e6 {
        return format!("{}", x.round());
    }
    let digits = (3 - x.abs().log10().floor() as i32).max(0) as usize;
    if x.abs() >= 1e6 || x.abs() < 1e-4 {
        format!("{x:.3e}")
    } else {
        format!("{x:.digits$}")
    }
}

/// The outputs a plot shows by default: Real outputs of continuous variability, the model's
/// continuous results (not the solver counters or the event flags).
pub fn continuous_outputs(description: &Description) -> Vec<&Variable> {
    description
        .outputs()
        .filter(|v| v.kind == Kind::Real && v.variability == Variability::Continuous && v.causality == Causality::Output)
        .filter(|v| !CONTROLS.iter().any(|c| c.name() == v.name))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn var(name: &str, kind: Kind, variability: Variability) -> Variable {
        Variable {
            name: name.into(),
            value_reference: 0,
            description: None,
            kind,
            causality: Causality::Output,
            variability,
            unit: None,
            display_unit: None,
            start: None,
            dimensions: Vec::new(),
        }
    }

    /// The bumper's release as its FMU reports it: in_contact drops and t_release is set at
    /// the same sample; the solver counter, which changes at every sample, marks nothing.
    #[test]
    fn a_release_is_one_event_named_by_the_flag() {
        let flag = var("in_contact", Kind::Boolean, Variability::Discrete);
        let t_release = var("t_release", Kind::Real, Variability::Discrete);
        let counter = var("steps_taken", Kind::Integer, Variability::Discrete);
        let n = 40;
        let trace = Trace {
            names: vec!["in_contact".into(), "t_release".into(), "steps_taken".into()],
            time: (0..n).map(|i| i as f64 * 0.01).collect(),
            columns: vec![
                (0..n).map(|i| if i < 17 { 1.0 } else { 0.0 }).collect(),
                (0..n).map(|i| if i < 17 { -1.0 } else { 0.1634 }).collect(),
                (0..n).map(|i| i as f64 * 3.0).collect(),
            ],
            ended_early: None,
        };
        let found = events(&trace, &[&flag, &t_release, &counter]);
        assert_eq!(found, vec![Event { time: 0.17, index: 17, text: "in_contact → false".into() }]);
    }

    #[test]
    fn a_discrete_real_alone_names_its_event() {
        let range = var("range", Kind::Real, Variability::Discrete);
        let trace =
            Trace { names: vec!["range".into()], time: vec![0.0, 1.0, 2.0], columns: vec![vec![0.0, 0.0, 23.21269]], ended_early: None };
        assert_eq!(events(&trace, &[&range])[0].text, "range = 23.21");
    }

    #[test]
    fn short_numbers_keep_four_digits() {
        assert_eq!(short(0.173_259_6), "0.1733");
        assert_eq!(short(23.212_69), "23.21");
        assert_eq!(short(1234.6), "1235");
        assert_eq!(short(-2.5e-7), "-2.500e-7");
        assert_eq!(short(3.0), "3", "a whole number (an Integer output) has no decimals");
        assert_eq!(short(1.0471975511965976 / (std::f64::consts::PI / 180.0)), "60");
        assert_eq!(short(1.2e-15), "1.200e-15", "a tiny number is not rounded to 0");
    }
}
