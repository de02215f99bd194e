//! Inputs that change over a run, from a table: fmpy's and the Reference FMUs' convention. The
//! first column is `time`, then one column per input; a time given twice marks a discontinuity
//! (the first row is the value just before it, the second the value from it on). Continuous
//! Reals are interpolated linearly between rows, Integers, Booleans and discrete Reals are held
//! from their row until the next; before the first row and after the last the end values hold.
//! An FMI 3.0 array input is given by its elements, as the runner writes arrays (`u[1]`, `u[2]`,
//! ..., or `u[1,1]`, ... one index per dimension) or as fmusim writes them (one column `u`
//! whose cells list the elements separated by spaces, row-major).
//!
//! An [`InputTable`] is plain data (from CSV text or from columns); [`InputTable::bind`] checks
//! it against an FMU's description and gives the [`Inputs`] a run applies before each step
//! ([`crate::run::Run`]), with the times a step must land on.

use fmi_importer::{Causality, Description, FmiVersion, Instance, Interface, Kind, Value, Variability, Variable};
use serde::{Deserialize, Serialize};

use crate::variables;

/// A table of input values: a time column and one column per input, as read, not yet checked
/// against an FMU.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputTable {
    /// The input names, in column order (without `time`).
    pub names: Vec<String>,
    /// The time of each row, non-decreasing.
    pub time: Vec<f64>,
    /// One column of values per name, each as long as `time`.
    pub values: Vec<Vec<f64>>,
}

/// Two times closer than this, relative, are the same time (Python's `math.isclose`, as fmpy
/// compares them): a discontinuity written as 0.5 and 0.5000000000001 is one instant.
const SAME_TIME: f64 = 1e-9;

/// True when `a` and `b` are the same instant (relative tolerance `SAME_TIME`).
pub fn same_time(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= SAME_TIME * a.abs().max(b.abs())
}

impl InputTable {
    /// A table from columns: `names[k]`'s values are `values[k]`, one per entry of `time`.
    pub fn from_columns(names: Vec<String>, time: Vec<f64>, values: Vec<Vec<f64>>) -> Result<InputTable, String> {
        if names.len() != values.len() {
            return Err(format!("the input table has {} names but {} columns of values", names.len(), values.len()));
        }
        if time.is_empty() {
            return Err("the input table has no rows: give at least one time".to_owned());
        }
        for (name, column) in names.iter().zip(&values) {
            if column.len() != time.len() {
                return Err(format!("input '{name}' has {} values for {} times", column.len(), time.len()));
            }
            if let Some(row) = column.iter().position(|x| !x.is_finite()) {
                return Err(format!("input '{name}' at time {}: {} is not a finite number", time[row], column[row]));
            }
        }
        for (k, name) in names.iter().enumerate() {
            if name == "time" || names[..k].contains(name) {
                return Err(format!("input '{name}' is given twice (time is the first column, each input one column)"));
            }
        }
        if let Some(row) = time.iter().position(|t| !t.is_finite()) {
            return Err(format!("row {}: time {} is not a finite number", row + 1, time[row]));
        }
        if let Some(row) = (1..time.len()).find(|&r| time[r] < time[r - 1]) {
            return Err(format!(
                "time must not decrease: row {} has time {} after {} (a repeated time marks a discontinuity)",
                row + 1,
                time[row],
                time[row - 1]
            ));
        }
        Ok(InputTable { names, time, values })
    }

    /// A table from CSV text (a header `time,NAME,...`, then rows of numbers; `true`/`false`
    /// are read as 1/0). Errors name the line and the column.
    pub fn from_csv(text: &str) -> Result<InputTable, String> {
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .flexible(true)
            .trim(csv::Trim::All)
            .comment(Some(b'#'))
            .from_reader(text.as_bytes());
        let header = reader.headers().map_err(|e| format!("the input file's header cannot be read: {e}"))?.clone();
        let names: Vec<String> = header.iter().map(str::to_owned).collect();
        match names.first() {
            Some(first) if first == "time" => {}
            Some(first) => return Err(format!("the input file's first column must be 'time', not '{first}'")),
            None => return Err("the input file is empty: its first line must be 'time,NAME,...'".to_owned()),
        }
        let names = names[1..].to_vec();
        let mut rows = Vec::new();
        for record in reader.records() {
            let record = record.map_err(|e| format!("the input file cannot be read: {e}"))?;
            let line = record.position().map_or(0, |p| p.line());
            if record.len() != names.len() + 1 {
                return Err(format!(
                    "line {line} of the input file has {} values; the header has {} columns",
                    record.len(),
                    names.len() + 1
                ));
            }
            rows.push((line, record));
        }
        if rows.is_empty() {
            return Err("the input file has a header but no rows".to_owned());
        }
        let number = |cell: &str, column: &str, line: u64| -> Result<f64, String> {
            match cell {
                "true" => Ok(1.0),
                "false" => Ok(0.0),
                _ => cell
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| format!("line {line} of the input file, column '{column}': '{cell}' is not a finite number")),
            }
        };
        let time: Vec<f64> = rows.iter().map(|(line, r)| number(&r[0], "time", *line)).collect::<Result<_, _>>()?;
        // An array as fmusim writes it: one column, its elements in each cell separated by
        // spaces (row-major), read as the columns NAME[1], NAME[2], ... (flat, 1-based).
        let mut columns = Vec::new();
        let mut values = Vec::new();
        for (k, name) in names.iter().enumerate() {
            let width = rows.iter().map(|(_, r)| r[k + 1].split_whitespace().count()).max().unwrap_or(1);
            if width <= 1 {
                columns.push(name.clone());
                values.push(rows.iter().map(|(line, r)| number(&r[k + 1], name, *line)).collect::<Result<Vec<f64>, _>>()?);
                continue;
            }
            let mut elements = vec![Vec::with_capacity(rows.len()); width];
            for (line, r) in &rows {
                let cell: Vec<&str> = r[k + 1].split_whitespace().collect();
                if cell.len() != width {
                    return Err(format!(
                        "line {line} of the input file, column '{name}': {} values where other rows have {width} (an array's elements, separated by spaces)",
                        cell.len()
                    ));
                }
                for (e, x) in cell.iter().enumerate() {
                    elements[e].push(number(x, name, *line)?);
                }
            }
            columns.extend((1..=width).map(|e| format!("{name}[{e}]")));
            values.extend(elements);
        }
        InputTable::from_columns(columns, time, values)
    }

    /// Checks the table against the FMU `description` run through `interface`: every column
    /// must be a scalar input of the FMU or an element of an array input (all of its elements
    /// given, in order), and every value one of its type. An FMI 2.0
    /// Co-Simulation FMU that can interpolate inputs also gets their derivatives.
    pub fn bind<'a>(&self, description: &'a Description, interface: Interface) -> Result<Inputs<'a>, String> {
        let mut signals: Vec<Signal> = Vec::with_capacity(self.names.len());
        for (column, name) in self.names.iter().enumerate() {
            let (variable, index) = match description.variable(name) {
                Some(v) => (v, None),
                None => match element_name(name) {
                    Some((base, index)) if description.variable(base).is_some_and(|v| v.is_array()) => {
                        (description.variable(base).expect("looked up"), Some(index))
                    }
                    _ => (variables::find(description, name).map_err(|e| format!("input file column '{name}': {e}"))?, None),
                },
            };
            if variable.causality != Causality::Input {
                return Err(format!(
                    "input file column '{name}': '{}' is {} ({}), not an input; set parameters with --set",
                    variable.name, variable.causality, variable.variability
                ));
            }
            if !variable.kind.is_numeric() {
                return Err(format!(
                    "input file column '{name}': '{}' is a {}; input files drive numeric inputs",
                    variable.name, variable.kind
                ));
            }
            let element = Variable { dimensions: vec![], ..variable.clone() };
            for (row, &x) in self.values[column].iter().enumerate() {
                variables::number_value(&element, x).map_err(|e| format!("input file column '{name}', time {}: {e}", self.time[row]))?;
            }
            let continuous = matches!(variable.kind, Kind::Real | Kind::Float32) && variable.variability == Variability::Continuous;
            match (variable.is_array(), index) {
                (false, _) => signals.push(Signal { variable, element, columns: vec![column], continuous }),
                (true, None) => {
                    return Err(format!(
                        "input file column '{name}': '{name}' is an array: give its elements as columns {name}[1], {name}[2], ... or as one column of values separated by spaces"
                    ))
                }
                (true, Some(index)) => {
                    let flat = flat_index(description, variable, &index).map_err(|e| format!("input file column '{name}': {e}"))?;
                    match (signals.iter_mut().find(|s| s.variable.name == variable.name), flat) {
                        (Some(signal), flat) if signal.columns.len() == flat => signal.columns.push(column),
                        (None, 0) => signals.push(Signal { variable, element, columns: vec![column], continuous }),
                        _ => {
                            return Err(format!(
                                "input file column '{name}': the elements of '{}' must be columns in order from the first, each once",
                                variable.name
                            ))
                        }
                    }
                }
            }
        }
        for signal in signals.iter().filter(|s| s.variable.is_array()) {
            let shape = description.shape(signal.variable, &|_| None)?;
            let size: u64 = shape.iter().product();
            if signal.columns.len() as u64 != size {
                return Err(format!(
                    "the input file gives {} element(s) of '{}', which has {size} (by its dimensions' start values)",
                    signal.columns.len(),
                    signal.variable.name
                ));
            }
        }
        let derivatives = interface == Interface::CoSimulation
            && matches!(description.fmi_version, FmiVersion::Fmi1 | FmiVersion::Fmi2)
            && description.co_simulation.as_ref().is_some_and(|c| c.can_interpolate_inputs);
        let variable_steps = match interface {
            Interface::CoSimulation => description.co_simulation.as_ref().is_some_and(|c| c.can_handle_variable_communication_step_size),
            Interface::ModelExchange => true,
        };
        let events = self.events(&signals);
        Ok(Inputs { table: self.clone(), signals, events, derivatives, variable_steps })
    }

    /// The times a step must land on: repeated times, and the rows where a held value changes.
    fn events(&self, signals: &[Signal]) -> Vec<f64> {
        let t = &self.time;
        let mut events: Vec<f64> = (1..t.len()).filter(|&r| same_time(t[r], t[r - 1])).map(|r| t[r]).collect();
        for s in signals.iter().filter(|s| !s.continuous) {
            for &column in &s.columns {
                let y = &self.values[column];
                events.extend((1..t.len()).filter(|&r| y[r] != y[r - 1]).map(|r| t[r]));
            }
        }
        events.sort_by(f64::total_cmp);
        events.dedup_by(|a, b| same_time(*a, *b));
        events
    }
}

/// One column bound to its variable.
#[derive(Debug, Clone)]
struct Signal<'a> {
    variable: &'a Variable,
    /// The variable as a scalar, for the type of each element.
    element: Variable,
    /// Its column, or an array's element columns in row-major order.
    columns: Vec<usize>,
    /// Interpolated linearly (a continuous Real), else held.
    continuous: bool,
}

/// An [`InputTable`] checked against an FMU: what a run sets before each step.
#[derive(Debug, Clone)]
pub struct Inputs<'a> {
    table: InputTable,
    signals: Vec<Signal<'a>>,
    /// Discontinuities, ascending: a step that would cross one is shortened to end on it.
    events: Vec<f64>,
    /// Pass the derivatives of continuous inputs (the FMU interpolates inputs over a step).
    derivatives: bool,
    /// The FMU takes steps of any size (canHandleVariableCommunicationStepSize), so steps can be
    /// shortened onto discontinuities; else a discontinuity takes effect at the next point.
    variable_steps: bool,
}

impl Inputs<'_> {
    /// The value of column `column` at `time` from that instant on (at a discontinuity, the
    /// value after it), and its time derivative over the step that starts there.
    pub fn value_at(&self, column: usize, continuous: bool, time: f64) -> (f64, f64) {
        let (t, y) = (&self.table.time, &self.table.values[column]);
        let n = t.len();
        // The last row at or before `time`, the same instant counting as before it.
        let after = t.partition_point(|&ti| ti < time || same_time(ti, time));
        if after == 0 {
            return (y[0], 0.0);
        }
        let i = after - 1;
        if !continuous || i + 1 == n {
            return (y[i], 0.0);
        }
        let (t0, t1, v0, v1) = (t[i], t[i + 1], y[i], y[i + 1]);
        let slope = (v1 - v0) / (t1 - t0);
        if time <= t0 {
            return (v0, slope);
        }
        // fmpy's weights, so the values agree with its to the bit.
        let w0 = (t1 - time) / (t1 - t0);
        (w0 * v0 + (1.0 - w0) * v1, slope)
    }

    /// Sets every input on `instance` to its value at `time` (after any discontinuity there),
    /// and the derivatives of the continuous ones where the FMU interpolates inputs.
    pub fn apply(&self, instance: &mut Instance, time: f64) -> Result<(), String> {
        for s in &self.signals {
            if s.variable.is_array() {
                let elements = s.columns.iter().map(|&c| variables::number_value(&s.element, self.value_at(c, s.continuous, time).0));
                instance.set(s.variable, &Value::List(elements.collect::<Result<_, _>>()?))?;
                continue;
            }
            let (x, slope) = self.value_at(s.columns[0], s.continuous, time);
            let value = variables::number_value(s.variable, x)?;
            instance.set(s.variable, &value)?;
            if s.continuous && self.derivatives {
                instance.set_input_derivative(s.variable, slope)?;
            }
        }
        Ok(())
    }

    /// Where a step from `now` towards `end` must stop: the first discontinuity after `now`
    /// and before `end` when the FMU takes steps of any size, else `end`.
    pub fn step_end(&self, now: f64, end: f64) -> f64 {
        if !self.variable_steps {
            return end;
        }
        let k = self.events.partition_point(|&e| e < now || same_time(e, now));
        match self.events.get(k) {
            Some(&e) if e < end && !same_time(e, end) => e,
            _ => end,
        }
    }

    /// The discontinuities, ascending.
    pub fn events(&self) -> &[f64] {
        &self.events
    }

    /// The input variables the table drives, in column order.
    pub fn variables(&self) -> impl Iterator<Item = &Variable> + '_ {
        self.signals.iter().map(|s| s.variable)
    }
}

/// `NAME[I]` or `NAME[I,J,...]`: the array's name and the 1-based indices.
fn element_name(name: &str) -> Option<(&str, Vec<u64>)> {
    let (base, rest) = name.strip_suffix(']')?.split_once('[')?;
    let index: Option<Vec<u64>> = rest.split(',').map(|i| i.trim().parse::<u64>().ok().filter(|&i| i >= 1)).collect();
    Some((base, index?))
}

/// The 0-based row-major position of the element at the 1-based `index` of `array`: one index
/// is the flat position (as fmusim's cells list the elements), else one index per dimension.
fn flat_index(description: &Description, array: &Variable, index: &[u64]) -> Result<usize, String> {
    let shape = description.shape(array, &|_| None)?;
    let size: u64 = shape.iter().product();
    let flat = match index {
        [k] => k - 1,
        _ if index.len() == shape.len() => {
            if let Some((i, n)) = index.iter().zip(&shape).find(|(i, n)| *i > *n) {
                return Err(format!("index {i} is past the dimension of {n} elements of '{}'", array.name));
            }
            index.iter().zip(&shape).fold(0, |flat, (i, n)| flat * n + (i - 1))
        }
        _ => return Err(format!("'{}' has {} dimensions, not {}", array.name, shape.len(), index.len())),
    };
    if flat >= size {
        return Err(format!("element {} is past the {size} elements of '{}'", flat + 1, array.name));
    }
    Ok(flat as usize)
}

#[cfg(test)]
mod tests {
    use super::*;
    use fmi_importer::model::{Capabilities, Start};

    fn variable(name: &str, vr: u32, kind: Kind, causality: Causality, variability: Variability) -> Variable {
        Variable {
            name: name.into(),
            value_reference: vr,
            description: None,
            kind,
            causality,
            variability,
            unit: None,
            display_unit: None,
            start: Some(Start::Real(0.0)),
            dimensions: vec![],
        }
    }

    fn description(variable_steps: bool, interpolates: bool) -> Description {
        Description {
            fmi_version: FmiVersion::Fmi2,
            fmi_version_text: "2.0".into(),
            model_name: "m".into(),
            description: None,
            instantiation_token: "g".into(),
            generation_tool: None,
            co_simulation: Some(Capabilities {
                model_identifier: "m".into(),
                can_handle_variable_communication_step_size: variable_steps,
                can_interpolate_inputs: interpolates,
                ..Default::default()
            }),
            model_exchange: None,
            default_experiment: None,
            units: vec![],
            variables: vec![
                variable("u", 1, Kind::Real, Causality::Input, Variability::Continuous),
                variable("d", 2, Kind::Real, Causality::Input, Variability::Discrete),
                variable("n", 3, Kind::Integer, Causality::Input, Variability::Discrete),
                variable("b", 4, Kind::Boolean, Causality::Input, Variability::Discrete),
                variable("k", 5, Kind::Real, Causality::Parameter, Variability::Fixed),
                variable("y", 6, Kind::Real, Causality::Output, Variability::Continuous),
            ],
            number_of_continuous_states: 0,
            number_of_event_indicators: 0,
        }
    }

    const CSV: &str = "time,u,d,n,b\n0,0,0,0,0\n1,2,1,3,1\n1,5,1,3,1\n2,7,4,3,false\n";

    /// The values of fmpy's `Input.interpolate(after_event=True)` for this table, worked by
    /// hand: linear between rows, the second row of a repeated time from that time on, held
    /// values from their row, the end values before and after the table.
    #[test]
    fn values_follow_fmpys_convention() {
        let d = description(true, false);
        let inputs = InputTable::from_csv(CSV).unwrap().bind(&d, Interface::CoSimulation).unwrap();
        let u = |t: f64| inputs.value_at(0, true, t);
        let held = |c: usize, t: f64| inputs.value_at(c, false, t).0;
        assert_eq!(u(-1.0), (0.0, 0.0), "before the table: the first value, held");
        assert_eq!(u(0.0), (0.0, 2.0));
        assert_eq!(u(0.25), (0.5, 2.0));
        assert_eq!(u(1.0), (5.0, 2.0), "at the discontinuity: the value after it and the slope after it");
        assert_eq!(u(1.0 - 1e-12), (5.0, 2.0), "a time within 1e-9 relative is the same instant");
        assert_eq!(u(1.5), (6.0, 2.0));
        assert_eq!(u(3.0), (7.0, 0.0), "after the table: the last value, held");
        assert_eq!((held(1, 0.5), held(1, 1.0), held(1, 1.99), held(1, 2.0)), (0.0, 1.0, 1.0, 4.0));
        assert_eq!((held(3, 1.5), held(3, 2.0)), (1.0, 0.0), "booleans: true and false read as 1 and 0");
        assert_eq!(inputs.events(), [1.0, 2.0], "the repeated time and the held changes");
    }

    /// Steps stop on discontinuities only for an FMU that takes steps of any size.
    #[test]
    fn steps_are_shortened_onto_discontinuities() {
        let table = InputTable::from_csv(CSV).unwrap();
        let d = description(true, false);
        let inputs = table.bind(&d, Interface::CoSimulation).unwrap();
        assert_eq!(inputs.step_end(0.9, 1.1), 1.0);
        assert_eq!(inputs.step_end(1.0, 1.1), 1.1, "a step from the discontinuity goes on");
        assert_eq!(inputs.step_end(0.5, 1.0 + 1e-12), 1.0 + 1e-12, "an end on the discontinuity is not shortened");
        assert_eq!(inputs.step_end(1.5, 3.0), 2.0);
        assert_eq!(inputs.step_end(2.5, 3.0), 3.0);
        let fixed = description(false, false);
        assert_eq!(table.bind(&fixed, Interface::CoSimulation).unwrap().step_end(0.9, 1.1), 1.1);
    }

    #[test]
    fn bad_tables_are_explained() {
        let d = description(true, false);
        let bind = |csv: &str| InputTable::from_csv(csv).and_then(|t| t.bind(&d, Interface::CoSimulation).map(|_| ()));
        let err = |csv: &str| bind(csv).unwrap_err();
        assert!(err("t,u\n0,1\n").contains("first column must be 'time', not 't'"));
        assert!(
            err("time,uu\n0,1\n").contains("column 'uu': the model m has no variable 'uu'; did you mean 'u'?"),
            "{}",
            err("time,uu\n0,1\n")
        );
        assert!(err("time,k\n0,1\n").contains("'k' is parameter (fixed), not an input"));
        assert!(err("time,y\n0,1\n").contains("'y' is output (continuous), not an input"));
        assert!(err("time,u\n0,1\n2,1\n1,1\n").contains("time must not decrease: row 3 has time 1 after 2"));
        assert!(err("time,u\n0,1\n1,abc\n").contains("line 3 of the input file, column 'u': 'abc' is not a finite number"));
        assert!(err("time,u\n0,nan\n").contains("'nan' is not a finite number"));
        assert!(err("time,u\n0,1,2\n").contains("line 2 of the input file has 3 values; the header has 2 columns"));
        assert!(err("time,n\n0,1.5\n").contains("column 'n', time 0: 'n' is Integer; 1.5 is not a value of that type"));
        assert!(err("time,b\n0,2\n").contains("'b' is Boolean; 2 is not a value"));
        assert!(err("time,u,u\n0,1,1\n").contains("'u' is given twice"));
        assert!(err("time,u\n").contains("no rows"));
        assert!(err("").contains("empty"));
        assert!(bind("time,u\n0,1\n").is_ok());
    }

    #[test]
    fn columns_are_checked_like_csv() {
        let names = vec!["u".to_owned()];
        assert!(InputTable::from_columns(names.clone(), vec![0.0, 1.0], vec![vec![1.0]]).unwrap_err().contains("1 values for 2 times"));
        assert!(InputTable::from_columns(names.clone(), vec![1.0, 0.0], vec![vec![1.0, 2.0]]).unwrap_err().contains("must not decrease"));
        assert!(InputTable::from_columns(names.clone(), vec![], vec![vec![]]).unwrap_err().contains("no rows"));
        let table = InputTable::from_columns(names, vec![0.0, 1.0], vec![vec![1.0, 3.0]]).unwrap();
        assert_eq!(table, InputTable::from_csv("time,u\n0,1\n1,3\n").unwrap());
    }

    /// Derivatives go to FMI 2.0 Co-Simulation FMUs that declare canInterpolateInputs only.
    #[test]
    fn derivatives_only_where_the_fmu_interpolates() {
        let table = InputTable::from_csv("time,u\n0,0\n1,1\n").unwrap();
        let yes = description(true, true);
        let no = description(true, false);
        assert!(table.bind(&yes, Interface::CoSimulation).unwrap().derivatives);
        assert!(!table.bind(&no, Interface::CoSimulation).unwrap().derivatives);
        assert!(!table.bind(&yes, Interface::ModelExchange).unwrap().derivatives);
    }
}

/// Runs of the Reference FMUs' Feedthrough (outputs equal inputs), when `../shared` holds it.
#[cfg(test)]
mod runs {
    use std::path::Path;

    use fmi_importer::Fmu;

    use super::*;
    use crate::run::{Grid, Recording, Run, Texts};

    fn feedthrough() -> Option<Fmu> {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference-fmus/fmi2/Feedthrough.fmu");
        path.is_file().then(|| Fmu::load(&path).expect("Feedthrough loads"))
    }

    /// Feedthrough copies the inputs set before a step to its outputs, so the outputs at each
    /// point are the table's values (fmpy's convention, worked out by hand in
    /// [`tests::values_follow_fmpys_convention`]) at the start of the step that ended there. The
    /// discontinuity at 0.25 shortens the step from 0.2, so point 0.3 shows the values from 0.25
    /// on, not those of 0.2: the loop landed on it and set the inputs again.
    #[test]
    fn the_run_loop_sets_inputs_before_each_step_and_lands_on_discontinuities() {
        let Some(fmu) = feedthrough() else { return };
        let d = &fmu.description;
        let csv = "time,Float64_continuous_input,Int32_input,Boolean_input\n0,0,0,0\n0.25,0.5,0,0\n0.25,2,3,1\n1,5,3,1\n";
        let inputs = InputTable::from_csv(csv).unwrap().bind(d, fmu.interface).unwrap();
        assert_eq!(inputs.events(), [0.25]);
        let grid = Grid::checked(0.0, 1.0, 0.1, None).unwrap();
        let recorded: Vec<&Variable> =
            ["Float64_continuous_output", "Int32_output", "Boolean_output"].iter().map(|n| d.variable(n).unwrap()).collect();
        let recording = Recording::scalars(&recorded).unwrap();
        let run = Run {
            name: "feedthrough",
            grid: &grid,
            assignments: &[],
            inputs: Some(&inputs),
            recording: &recording,
            debug_logging: false,
            initial_state: None,
            final_state: false,
        };
        let mut rows = Vec::new();
        run.execute(&fmu, |t: f64, v: &[f64], _: &dyn Texts| {
            rows.push((t, v.to_vec()));
            Ok(())
        })
        .unwrap();
        assert_eq!(rows.len(), 11);
        // Feedthrough's outputs follow its inputs at once: at each point they show the inputs
        // set at that point's step start, which for point 0.3 is the discontinuity's 0.25.
        let expect = |i: usize| -> Vec<f64> {
            let from = if i == 3 { 0.25 } else { grid.time(i - 1) };
            vec![inputs.value_at(0, true, from).0, inputs.value_at(1, false, from).0, inputs.value_at(2, false, from).0]
        };
        for (i, (t, v)) in rows.iter().enumerate().skip(1) {
            assert_eq!(v, &expect(i), "at t = {t}");
        }
    }
}
