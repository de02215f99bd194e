//! The fixed-step co-simulation master. A [`Bound`] is a system checked once for a run's
//! settings: its columns, its connections as value indices with their unit conversions, its
//! parameter values and its stepping order. [`Bound::run`] runs one instance of the system.
//!
//! Jacobi (the default, libcosim's fixed-step algorithm and fmpy's SSP runner): at each
//! communication point every input is set from the outputs at that point, then every component
//! steps from t to t + h. Gauss-Seidel: the components step one after another in data-flow
//! order, each with the outputs its predecessors reached at t + h.
//!
//! Initialization: every component is set up, gets its parameters and enters initialization
//! mode; then the outputs are passed to the inputs as many times as there are components, so
//! values settle along any chain; then every component leaves initialization mode.

use fmi_importer::{Causality, FmiVersion, Instance, Interface, Kind, Reader, Step, Value, Variability, Variable};
use runner_engine::input::{self, InputTable};
use runner_engine::run::Grid;
use runner_engine::variables;

use crate::ssd::{self, ParameterValue};
use crate::system::{Component, System};

/// The master algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Master {
    /// Every component steps from t with the outputs at t.
    #[default]
    Jacobi,
    /// Components step in data-flow order, each with its predecessors' new outputs.
    GaussSeidel,
}

impl Master {
    /// The command-line spelling.
    pub fn from_name(name: &str) -> Option<Master> {
        match name {
            "jacobi" => Some(Master::Jacobi),
            "gauss-seidel" => Some(Master::GaussSeidel),
            _ => None,
        }
    }
}

/// How a connection passes a Real value over a communication step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coupling {
    /// The input holds the value at the step's start (libcosim's and fmpy's coupling).
    Hold,
    /// The input follows a polynomial over the step, from the source's value and output
    /// derivatives (`fmi2GetRealOutputDerivatives`, `fmi3GetOutputDerivatives`) given to an FMU
    /// that interpolates inputs (`canInterpolateInputs`, `fmi2SetRealInputDerivatives`): under
    /// Jacobi the Taylor polynomial at the step's start (extrapolated), under Gauss-Seidel, from
    /// a source that has already stepped, the cubic through its values and first derivatives at
    /// both ends (interpolated).
    Polynomial,
}

impl Coupling {
    /// The command-line spelling.
    pub fn from_name(name: &str) -> Option<Coupling> {
        match name {
            "hold" => Some(Coupling::Hold),
            "polynomial" => Some(Coupling::Polynomial),
            _ => None,
        }
    }
}

/// The highest order of output derivatives the master passes on (a Taylor polynomial of this
/// degree; Gauss-Seidel's interpolating cubic needs orders 1 to 3 at the input too).
pub const MAX_COUPLING_ORDER: usize = 3;

/// A connection ready to pass values: from `values[from]` to component `to`'s `variable`.
#[derive(Clone, Copy)]
struct Transfer<'a> {
    from: usize,
    /// The source's component and variable.
    source: usize,
    source_variable: &'a Variable,
    to: usize,
    variable: &'a Variable,
    factor: f64,
    offset: f64,
    kind: Kind,
}

/// How a run ended early.
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    /// The component that failed or ended the run (`None`: the master itself, e.g. writing
    /// a row failed).
    pub component: Option<String>,
    /// The communication point the step started from.
    pub time: f64,
    /// The FMI call's message (call and status), or the FMU's reason for ending.
    pub message: String,
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.component {
            Some(c) => write!(f, "component '{c}' at t = {}: {}", self.time, self.message),
            None => write!(f, "at t = {}: {}", self.time, self.message),
        }
    }
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// It reached the stop time.
    Finished,
    /// A component ended the simulation (terminated, fmi2Discard): the rows up to it are kept.
    Ended(Failure),
}

/// A system bound to its variables for runs.
pub struct Bound<'a> {
    pub system: &'a System,
    /// One name per column (after time): `COMPONENT.VARIABLE`.
    pub columns: Vec<String>,
    /// Per component: the variables read each step, and where its values start in a row.
    reads: Vec<(Vec<&'a Variable>, usize)>,
    transfers: Vec<Transfer<'a>>,
    /// Per component: the parameter values of the SSD's bindings.
    parameters: Vec<Vec<(&'a Variable, Value)>>,
    /// Component indices in stepping order (Gauss-Seidel: data-flow order).
    order: Vec<usize>,
    master: Master,
    /// `None`: polynomial wherever both ends of a connection allow it, else hold.
    coupling: Option<Coupling>,
    /// An algebraic loop Jacobi breaks by its one-step delay (a warning for the user).
    pub warning: Option<String>,
    /// Per component: the unconnected inputs an input table drives (`--input-file`).
    tables: Vec<Option<input::Inputs<'a>>>,
}

/// A `COMPONENT.VARIABLE=VALUE` assignment resolved: component index, variable, value.
pub type Assignment<'a> = (usize, &'a Variable, Value);

impl<'a> Bound<'a> {
    /// Checks `system` for runs under `master`: every connection between existing variables
    /// of matching types and convertible units, every parameter a settable variable, and under
    /// Gauss-Seidel no algebraic loop.
    pub fn new(system: &'a System, master: Master) -> Result<Bound<'a>, String> {
        let structure = &system.structure;
        let components = &system.components;
        let mut reads: Vec<(Vec<&Variable>, usize)> = Vec::new();
        let mut columns = Vec::new();
        let mut sources = vec![Vec::<&Variable>::new(); components.len()];
        for link in &structure.links {
            let (c, name) = &link.from;
            let d = &components[*c].fmu.description;
            let v = variables::find(d, name).map_err(|e| format!("connection from {}.{name}: {e}", components[*c].name))?;
            if !sources[*c].iter().any(|s| s.value_reference == v.value_reference && s.kind == v.kind) {
                sources[*c].push(v);
            }
        }
        for (c, component) in components.iter().enumerate() {
            let d = &component.fmu.description;
            let mut vars: Vec<&Variable> = d.outputs().filter(|v| !v.is_array() && v.kind.is_numeric()).collect();
            for s in &sources[c] {
                if !vars.iter().any(|v| v.value_reference == s.value_reference && v.kind == s.kind) {
                    vars.push(s);
                }
            }
            columns.extend(vars.iter().map(|v| format!("{}.{}", component.name, v.name)));
            let offset = reads.last().map_or(0, |(v, o): &(Vec<&Variable>, usize)| o + v.len());
            reads.push((vars, offset));
        }
        let index_of = |c: usize, v: &Variable| {
            let (vars, offset) = &reads[c];
            offset + vars.iter().position(|r| r.value_reference == v.value_reference && r.kind == v.kind).expect("sources are read")
        };
        let mut transfers = Vec::new();
        for link in &structure.links {
            let ((fc, fname), (tc, tname)) = (&link.from, &link.to);
            let (from_d, to_d) = (&components[*fc].fmu.description, &components[*tc].fmu.description);
            let at = format!("connection {}.{fname} -> {}.{tname} (line {})", components[*fc].name, components[*tc].name, link.line);
            let from = variables::find(from_d, fname).map_err(|e| format!("{at}: {e}"))?;
            let to = variables::find(to_d, tname).map_err(|e| format!("{at}: {e}"))?;
            if to.causality != Causality::Input && to.causality != Causality::Parameter {
                return Err(format!("{at}: '{tname}' is {}, not an input", to.causality));
            }
            let class = |k: Kind| match k {
                Kind::Real | Kind::Float32 => 0,
                Kind::Boolean => 2,
                k if k.is_numeric() => 1,
                _ => 3,
            };
            if class(from.kind) != class(to.kind) || class(from.kind) == 3 || from.is_array() || to.is_array() {
                return Err(format!(
                    "{at}: a {} cannot drive a {} (connections join Real, Integer or Boolean scalars of one type)",
                    from.kind, to.kind
                ));
            }
            let (mut factor, mut offset) = (1.0, 0.0);
            if let Some((f, o)) = link.transformation {
                (factor, offset) = (f, o);
            } else if class(from.kind) == 0 && !link.suppress_unit_conversion {
                let unit = |c: usize, name: &str, v: &Variable| {
                    structure.components[c].connector_units.get(name).cloned().or_else(|| v.unit.clone())
                };
                if let (Some(a), Some(b)) = (unit(*fc, fname, from), unit(*tc, tname, to)) {
                    if let Some((f, o)) = ssd::convert(&structure.units, &a, &b).map_err(|e| format!("{at}: {e}"))? {
                        (factor, offset) = (f, o);
                    }
                }
            }
            transfers.push(Transfer {
                from: index_of(*fc, from),
                source: *fc,
                source_variable: from,
                to: *tc,
                variable: to,
                factor,
                offset,
                kind: to.kind,
            });
        }
        let mut parameters = Vec::with_capacity(components.len());
        for (c, spec) in structure.components.iter().enumerate() {
            let d = &components[c].fmu.description;
            let mut values = Vec::new();
            for a in &spec.parameters {
                let at = |e: String| format!("{}: parameter {}.{}: {e}", a.origin, spec.name, a.variable);
                let v = variables::find(d, &a.variable).map_err(at)?;
                variables::check_settable(v).map_err(at)?;
                let value = match &a.value {
                    ParameterValue::Real(x, unit) => {
                        let x = match (unit, &v.unit) {
                            (Some(from), Some(to)) => match ssd::convert(&structure.units, from, to).map_err(at)? {
                                Some((f, o)) => f * x + o,
                                None => *x,
                            },
                            _ => *x,
                        };
                        variables::number_value(v, x).map_err(at)?
                    }
                    ParameterValue::Integer(i) => variables::number_value(v, *i as f64).map_err(at)?,
                    ParameterValue::Boolean(b) => variables::number_value(v, f64::from(u8::from(*b))).map_err(at)?,
                    ParameterValue::String(s) => variables::parse_value(v, s).map_err(at)?,
                };
                values.push((v, value));
            }
            parameters.push(values);
        }
        let mut bound = Bound {
            system,
            columns,
            reads,
            transfers,
            parameters,
            order: (0..components.len()).collect(),
            master,
            coupling: None,
            warning: None,
            tables: (0..components.len()).map(|_| None).collect(),
        };
        let algebraic = bound.algebraic_loop();
        match (master, algebraic) {
            (Master::GaussSeidel, Some(cycle)) => {
                return Err(format!("algebraic loop of direct feedthrough: {cycle}; no stepping order resolves it (run it under --master jacobi, whose one-step delay breaks it)"))
            }
            (Master::Jacobi, Some(cycle)) => {
                bound.warning = Some(format!("algebraic loop of direct feedthrough: {cycle}; the Jacobi master breaks it with a delay of one communication step"))
            }
            _ => {}
        }
        if master == Master::GaussSeidel {
            bound.order = bound.data_flow_order();
        } else {
            // The components that stop at their events step first, so that the others, not yet
            // stepped, step only to such an event (the order is otherwise free under Jacobi).
            bound.order.sort_by_key(|&c| !returns_early(&components[c]));
        }
        Ok(bound)
    }

    /// Chooses how connections pass Real values: `Some(Hold)` everywhere, or polynomials where
    /// both ends allow them (the default, `None`, and `Some(Polynomial)`, which falls back to the
    /// hold where a component cannot).
    pub fn set_coupling(&mut self, coupling: Option<Coupling>) {
        self.coupling = coupling;
    }

    /// The order of the polynomial the connection `tr` passes (0: held): the source is a
    /// Co-Simulation FMU with output derivatives, the input's an FMI 2.0 Co-Simulation FMU that
    /// interpolates inputs, and both variables are continuous Reals.
    fn polynomial_order(&self, tr: &Transfer) -> usize {
        if self.coupling == Some(Coupling::Hold) || tr.kind != Kind::Real || tr.source_variable.kind != Kind::Real {
            return 0;
        }
        let (source, target) = (&self.system.components[tr.source].fmu, &self.system.components[tr.to].fmu);
        let continuous = tr.source_variable.variability == Variability::Continuous
            && tr.variable.variability == Variability::Continuous
            && tr.variable.causality == Causality::Input;
        let interpolates = target.interface == Interface::CoSimulation
            && matches!(target.description.fmi_version, FmiVersion::Fmi1 | FmiVersion::Fmi2)
            && target.description.co_simulation.as_ref().is_some_and(|c| c.can_interpolate_inputs);
        let derivatives = match (&source.interface, &source.description.co_simulation) {
            (Interface::CoSimulation, Some(c)) => c.max_output_derivative_order as usize,
            _ => 0,
        };
        if continuous && interpolates {
            derivatives.min(MAX_COUPLING_ORDER)
        } else {
            0
        }
    }

    /// The connections that pass polynomials (`from -> to (order k)`), for the user.
    pub fn polynomial_connections(&self) -> Vec<String> {
        let components = &self.system.components;
        self.transfers
            .iter()
            .filter_map(|tr| {
                let order = self.polynomial_order(tr);
                (order > 0).then(|| {
                    format!(
                        "{}.{} -> {}.{} (order {order})",
                        components[tr.source].name, tr.source_variable.name, components[tr.to].name, tr.variable.name
                    )
                })
            })
            .collect()
    }

    /// A cycle of connections and direct feedthrough, as `a.y -> b.u -> b.y -> a.u`, if any.
    fn algebraic_loop(&self) -> Option<String> {
        let components = &self.system.components;
        // Nodes: (component, variable name); edges: connections and feedthrough.
        let links = &self.system.structure.links;
        let next = |(c, v): &(usize, String)| -> Vec<(usize, String)> {
            let mut out: Vec<(usize, String)> = links.iter().filter(|l| l.from == (*c, v.clone())).map(|l| l.to.clone()).collect();
            for (output, inputs) in &components[*c].feedthrough {
                if inputs.contains(v) {
                    out.push((*c, output.clone()));
                }
            }
            out
        };
        let name = |(c, v): &(usize, String)| format!("{}.{v}", components[*c].name);
        for start in links.iter().map(|l| l.to.clone()) {
            // Depth-first from an input, looking for a way back to it.
            let mut stack = vec![(start.clone(), vec![start.clone()])];
            let mut seen = std::collections::HashSet::new();
            while let Some((node, path)) = stack.pop() {
                for n in next(&node) {
                    if n == start {
                        let mut names: Vec<String> = path.iter().map(name).collect();
                        names.push(name(&start));
                        return Some(names.join(" -> "));
                    }
                    if seen.insert(n.clone()) {
                        let mut p = path.clone();
                        p.push(n.clone());
                        stack.push((n, p));
                    }
                }
            }
        }
        None
    }

    /// Components in data-flow order: each after the components it takes inputs from, a cycle
    /// (without feedthrough all around) entered at its first component in the SSD.
    fn data_flow_order(&self) -> Vec<usize> {
        let n = self.system.components.len();
        let edges: Vec<(usize, usize)> = self.system.structure.links.iter().map(|l| (l.from.0, l.to.0)).filter(|(a, b)| a != b).collect();
        let mut placed = vec![false; n];
        let mut order = Vec::with_capacity(n);
        while order.len() < n {
            let ready = (0..n).find(|&c| !placed[c] && edges.iter().all(|&(a, b)| b != c || placed[a]));
            let c = ready.unwrap_or_else(|| (0..n).find(|&c| !placed[c]).expect("some component is left"));
            placed[c] = true;
            order.push(c);
        }
        order
    }

    /// Resolves `COMPONENT.VARIABLE=VALUE` texts (a value with a unit the FMU declares).
    pub fn parse_sets(&self, sets: &[String]) -> Result<Vec<Assignment<'a>>, String> {
        sets.iter().map(|text| self.parse_set(text)).collect()
    }

    fn parse_set(&self, text: &str) -> Result<Assignment<'a>, String> {
        let (name, value) = variables::split_assignment(text, "--set")?;
        let (c, variable) = self.resolve(name)?;
        let d = &self.system.components[c].fmu.description;
        variables::check_settable(variable).map_err(|e| format!("{name}: {e}"))?;
        let value = variables::parse_quantity(d, variable, value).map_err(|e| format!("{name}: {e}"))?;
        Ok((c, variable, value))
    }

    /// The component and variable of `COMPONENT.VARIABLE`.
    pub fn resolve(&self, name: &str) -> Result<(usize, &'a Variable), String> {
        let system: &'a System = self.system;
        let (c, variable) = system.structure.split(name).ok_or_else(|| {
            let names: Vec<&str> = system.components.iter().map(|c| c.name.as_str()).collect();
            format!("'{name}' names no component of the system: write COMPONENT.VARIABLE with COMPONENT one of {}", names.join(", "))
        })?;
        let d = &system.components[c].fmu.description;
        let v = variables::find(d, variable).map_err(|e| format!("{name}: component '{}': {e}", system.components[c].name))?;
        Ok((c, v))
    }

    /// Drives unconnected inputs from `table` (`--input-file`, fmpy's CSV convention), whose
    /// columns name them `COMPONENT.INPUT`. Each component's are set at every communication
    /// point and sub-step, before it steps (a continuous Real with its slope where the FMU
    /// interpolates inputs, as for a single FMU): a discontinuity between points takes effect
    /// at the next one, as every value the master passes does.
    pub fn set_inputs(&mut self, table: &InputTable) -> Result<(), String> {
        let components = &self.system.components;
        let mut columns: Vec<(Vec<String>, Vec<Vec<f64>>)> = vec![(Vec::new(), Vec::new()); components.len()];
        for (k, name) in table.names.iter().enumerate() {
            let (c, variable) = self.resolve(name).map_err(|e| format!("input file column '{name}': {e}"))?;
            let connected = self.transfers.iter().find(|tr| tr.to == c && tr.variable.value_reference == variable.value_reference);
            if let Some(tr) = connected {
                return Err(format!(
                    "input file column '{name}': the system connects that input to {}: an input file drives unconnected inputs",
                    self.columns[tr.from]
                ));
            }
            columns[c].0.push(variable.name.clone());
            columns[c].1.push(table.values[k].clone());
        }
        for (c, (names, values)) in columns.into_iter().enumerate() {
            if names.is_empty() {
                continue;
            }
            let component = &components[c];
            let own = InputTable::from_columns(names, table.time.clone(), values)?;
            let bound =
                own.bind(&component.fmu.description, component.interface).map_err(|e| format!("component '{}': {e}", component.name))?;
            self.tables[c] = Some(bound);
        }
        Ok(())
    }

    /// Sets component `c`'s inputs from the input table at `time`, if it has any.
    fn apply_table(&self, c: usize, instance: &mut Instance, time: f64) -> Result<(), Failure> {
        match &self.tables[c] {
            Some(table) => table.apply(instance, time).map_err(|e| failure(&self.system.components, c, time, e)),
            None => Ok(()),
        }
    }

    /// The column of `COMPONENT.VARIABLE`, if recorded.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == name)
    }

    /// Runs one instance of the system on `grid` with `sets` applied after the SSD's
    /// parameters; `sample(t, row)` gets every communication point's values in column order.
    /// A component's failure is an `Err` naming it, the time and the call; the rows sampled
    /// before it stay sampled.
    pub fn run(
        &self,
        instance_name: &str,
        grid: &Grid,
        sets: &[Assignment],
        sample: impl FnMut(f64, &[f64]) -> Result<(), String>,
    ) -> Result<Outcome, Failure> {
        self.run_plan(&self.plan(None), instance_name, grid, sets, sample)
    }

    /// [`Bound::run`] recording only the columns `recorded` (indices into
    /// [`Bound::columns`], e.g. a sweep's metric variables): `sample(t, values)` gets their
    /// values in that order, and the master reads from the FMUs only these and the outputs
    /// that feed connections.
    pub fn run_recorded(
        &self,
        instance_name: &str,
        grid: &Grid,
        sets: &[Assignment],
        recorded: &[usize],
        sample: impl FnMut(f64, &[f64]) -> Result<(), String>,
    ) -> Result<Outcome, Failure> {
        self.run_plan(&self.plan(Some(recorded)), instance_name, grid, sets, sample)
    }

    /// What a run reads and sets, made once so that a step does no lookups: the values read
    /// at each point (all columns, or `recorded` ones and connection sources), and per
    /// component its Real inputs as value references with their sources and conversions.
    fn plan(&self, recorded: Option<&[usize]>) -> Plan<'a> {
        let components = &self.system.components;
        let sources: Vec<usize> = self.transfers.iter().map(|tr| tr.from).collect();
        // Column -> its slot in the values read at each point.
        let mut slot_of = vec![usize::MAX; self.columns.len()];
        let mut reads = Vec::with_capacity(components.len());
        let mut slots = 0;
        for (vars, offset) in &self.reads {
            let mut read = Vec::new();
            for (k, v) in vars.iter().enumerate() {
                let column = offset + k;
                if recorded.is_none_or(|r| r.contains(&column)) || sources.contains(&column) {
                    slot_of[column] = slots + read.len();
                    read.push(*v);
                }
            }
            reads.push((read, slots));
            slots += reads.last().map_or(0, |(r, _): &(Vec<&Variable>, usize)| r.len());
        }
        let mut inputs: Vec<Inputs<'a>> = (0..components.len()).map(|_| Inputs::default()).collect();
        let mut rates: Vec<RateReads> = (0..components.len()).map(|_| RateReads::default()).collect();
        let position = |c: usize| self.order.iter().position(|&o| o == c).expect("every component is in the order");
        for tr in &self.transfers {
            let to = &mut inputs[tr.to];
            let from = slot_of[tr.from];
            if tr.kind == Kind::Real {
                let order = self.polynomial_order(tr);
                if order > 0 {
                    // Gauss-Seidel interpolates from a source that steps first; otherwise the
                    // polynomial extrapolates from the step's start.
                    let interpolate = self.master == Master::GaussSeidel && position(tr.source) < position(tr.to);
                    let passed = if interpolate { MAX_COUPLING_ORDER } else { order };
                    to.rates.push(Rate {
                        vr: tr.variable.value_reference,
                        from,
                        source: tr.source,
                        factor: tr.factor,
                        offset: tr.offset,
                        order: passed,
                        interpolate,
                    });
                    if interpolate {
                        // Set with its derivatives (its value is its source's at the step's start).
                        to.interpolated.push((tr.variable.value_reference, from, tr.factor, tr.offset));
                    }
                    for k in 1..=passed {
                        to.rate_vrs.push(tr.variable.value_reference);
                        to.rate_orders.push(k as i32);
                    }
                    let source = &mut rates[tr.source];
                    let read = if interpolate { 1 } else { order };
                    match source.slots.iter().position(|&s| s == from) {
                        Some(i) => source.orders[i] = source.orders[i].max(read),
                        None => {
                            source.slots.push(from);
                            source.vrs.push(tr.source_variable.value_reference);
                            source.orders.push(read);
                        }
                    }
                    to.rate_names.push(tr.variable.name.as_str());
                    if interpolate {
                        continue;
                    }
                }
                to.vrs.push(tr.variable.value_reference);
                to.names.push(tr.variable.name.as_str());
                to.reals.push((from, tr.factor, tr.offset));
            } else {
                to.others.push(Transfer { from, ..*tr });
            }
        }
        for r in &mut rates {
            for (i, &order) in r.orders.iter().enumerate() {
                for k in 1..=order {
                    r.call_vrs.push(r.vrs[i]);
                    r.call_orders.push(k as i32);
                    r.call_slots.push((r.slots[i], k - 1));
                }
            }
            if let [slot] = r.slots[..] {
                r.direct = Some(slot);
            }
        }
        for i in &mut inputs {
            if let [Rate { from, factor, interpolate: false, .. }] = i.rates[..] {
                i.direct = (factor == 1.0).then_some(from);
            }
        }
        let mut interpolates: Vec<usize> = inputs.iter().flat_map(|i| i.rates.iter().filter(|r| r.interpolate).map(|r| r.from)).collect();
        interpolates.sort_unstable();
        interpolates.dedup();
        let coupled = inputs.iter().any(|i| !i.rates.is_empty());
        let recorded = recorded.map(|r| r.iter().map(|&c| slot_of[c]).collect());
        let returns_early = components.iter().map(returns_early).collect();
        Plan { reads, slots, inputs, rates, coupled, interpolates, recorded, returns_early }
    }

    fn run_plan(
        &self,
        plan: &Plan,
        instance_name: &str,
        grid: &Grid,
        sets: &[Assignment],
        mut sample: impl FnMut(f64, &[f64]) -> Result<(), String>,
    ) -> Result<Outcome, Failure> {
        let components = &self.system.components;
        let fail = |c: usize, time: f64| move |message: String| failure(components, c, time, message);
        let mut readers = Vec::with_capacity(components.len());
        for (c, (vars, _)) in plan.reads.iter().enumerate() {
            readers.push(Reader::new(components[c].fmu.description.fmi_version, vars).map_err(fail(c, grid.start))?);
        }
        let mut values = vec![0.0; plan.slots];
        // Polynomial coupling: the sources' output derivatives, the values and derivatives at
        // the step's start (for Gauss-Seidel's interpolation), and scratch for the calls.
        let mut rates = vec![[0.0; MAX_COUPLING_ORDER]; plan.slots];
        let (mut start_values, mut start_rates) = (values.clone(), rates.clone());
        let mut scratch: Vec<Vec<f64>> = plan.rates.iter().map(|r| vec![0.0; r.call_vrs.len()]).collect();
        let mut passed: Vec<Vec<f64>> = plan.inputs.iter().map(|i| vec![0.0; i.rate_vrs.len() + i.interpolated.len()]).collect();
        // The Real inputs' values, per component, filled before each set.
        let mut buffers: Vec<Vec<f64>> = plan.inputs.iter().map(|i| vec![0.0; i.vrs.len()]).collect();
        let mut row = vec![0.0; plan.recorded.as_ref().map_or(0, Vec::len)];
        let mut instances = Vec::with_capacity(components.len());
        for (c, component) in components.iter().enumerate() {
            driving(c);
            let mut instance =
                component.fmu.instantiate(&format!("{instance_name}.{}", component.name), false).map_err(fail(c, grid.start))?;
            instance.set_solver(grid.solver);
            instance.setup_experiment(grid.tolerance, grid.start, grid.stop).map_err(fail(c, grid.start))?;
            for (variable, value) in &self.parameters[c] {
                instance.set(variable, value).map_err(fail(c, grid.start))?;
            }
            for (_, variable, value) in sets.iter().filter(|(sc, ..)| *sc == c) {
                instance.set(variable, value).map_err(fail(c, grid.start))?;
            }
            instance.enter_initialization_mode().map_err(fail(c, grid.start))?;
            self.apply_table(c, &mut instance, grid.start)?;
            instances.push(instance);
        }
        let n_components = components.len();
        // Pass values along chains during initialization.
        for _ in 0..n_components {
            for c in 0..n_components {
                read(plan, components, c, &mut instances[c], &mut readers[c], &mut values, grid.start)?;
            }
            for c in 0..n_components {
                transfer(plan, components, c, &mut instances[c], &mut buffers[c], &values, grid.start)?;
                for &(vr, from, factor, offset) in &plan.inputs[c].interpolated {
                    let x = factor * values[from] + offset;
                    instances[c].set_reals(&[vr], &[x]).map_err(|e| failure(components, c, grid.start, e))?;
                }
            }
        }
        for (c, instance) in instances.iter_mut().enumerate() {
            driving(c);
            instance.exit_initialization_mode().map_err(fail(c, grid.start))?;
        }
        for c in 0..n_components {
            read(plan, components, c, &mut instances[c], &mut readers[c], &mut values, grid.start)?;
            if plan.coupled {
                read_rates(plan, components, c, &mut instances[c], &mut scratch[c], &mut rates, grid.start)?;
            }
        }
        emit(plan, &mut sample, grid.start, &values, &mut row)?;
        let n = grid.steps();
        let jacobi = self.master == Master::Jacobi;
        for i in 0..n {
            let (t, t_next) = (grid.time_of(i, n), grid.time_of(i + 1, n));
            // Only the interpolated sources' values at the start are read (here and when
            // synchronizing): copying all of them called memcpy twice a step.
            for &slot in &plan.interpolates {
                start_values[slot] = values[slot];
                start_rates[slot] = rates[slot];
            }
            let start = Start { values: &start_values, rates: &start_rates, h: t_next - t };
            let mut early = None;
            if jacobi {
                for c in 0..n_components {
                    transfer(plan, components, c, &mut instances[c], &mut buffers[c], &values, t)?;
                    if plan.coupled {
                        pass_rates(plan, components, c, &mut instances[c], &mut passed[c], &values, &rates, &start, t)?;
                    }
                }
            }
            for &c in &self.order {
                if !jacobi {
                    transfer(plan, components, c, &mut instances[c], &mut buffers[c], &values, t)?;
                    if plan.coupled {
                        pass_rates(plan, components, c, &mut instances[c], &mut passed[c], &values, &rates, &start, t)?;
                    }
                }
                driving(c);
                self.apply_table(c, &mut instances[c], t)?;
                match step(&mut instances[c], t, t_next, plan.returns_early[c]).map_err(fail(c, t))? {
                    Stepped::Reached => {}
                    Stepped::Ended(ended) => {
                        // The others may have stepped on: the last row is the one at t.
                        return Ok(Outcome::Ended(Failure { component: Some(components[c].name.clone()), time: t, message: ended }));
                    }
                    Stepped::Early(event) => {
                        early = Some((c, event));
                        break;
                    }
                }
                if !jacobi {
                    read(plan, components, c, &mut instances[c], &mut readers[c], &mut values, t_next)?;
                    if plan.coupled {
                        read_rates(plan, components, c, &mut instances[c], &mut scratch[c], &mut rates, t_next)?;
                    }
                }
            }
            if let Some((c, event)) = early {
                let mut run = Running {
                    instances: &mut instances,
                    readers: &mut readers,
                    values: &mut values,
                    rates: &mut rates,
                    scratch: &mut scratch,
                    buffers: &mut buffers,
                };
                if let Some(ended) = self.synchronize(plan, &mut run, (&start_values, &start_rates), (t, t_next), c, event)? {
                    return Ok(Outcome::Ended(ended));
                }
            } else if jacobi {
                for c in 0..n_components {
                    read(plan, components, c, &mut instances[c], &mut readers[c], &mut values, t_next)?;
                    if plan.coupled {
                        read_rates(plan, components, c, &mut instances[c], &mut scratch[c], &mut rates, t_next)?;
                    }
                }
            }
            emit(plan, &mut sample, t_next, &values, &mut row)?;
        }
        for (c, instance) in instances.into_iter().enumerate() {
            driving(c);
            drop(instance);
        }
        Ok(Outcome::Finished)
    }
}

impl Bound<'_> {
    /// The rest of the communication step from `t` to `t_next` after component `first` stopped
    /// at an event at `event` (FMI 3.0 early return): every component is brought to that time
    /// with a shorter step, the values are passed there, and the step goes on from there to
    /// `t_next` (stopping again at any further event). Components that had stepped before
    /// `first` in this step (Jacobi: only other early returners, which step first;
    /// Gauss-Seidel: the ones before it in data-flow order) are at `t_next` already and wait
    /// there; a component that cannot shorten its step (FMI 2.0 without
    /// `canHandleVariableCommunicationStepSize`) takes the whole remaining step. A component's
    /// values are read when the sub-steps reach the time it is at. A polynomial input follows
    /// its source's Taylor polynomial from its last read, moved to the sub-step's start; under
    /// Gauss-Seidel, from a source already past that start, the cubic between its last two
    /// reads. `start` holds the values and derivatives at `t` (kept when Gauss-Seidel
    /// interpolates). `Some`: a component ended the run.
    #[cold]
    #[inline(never)]
    fn synchronize(
        &self,
        plan: &Plan,
        run: &mut Running,
        start: (&[f64], &[Rates]),
        (t, t_next): (f64, f64),
        first: usize,
        event: f64,
    ) -> Result<Option<Failure>, Failure> {
        let components = &self.system.components;
        let n = components.len();
        let jacobi = self.master == Master::Jacobi;
        let position = self.order.iter().position(|&c| c == first).expect("every component is in the order");
        // Where each component is; the time its values (and derivatives) were read at, and the
        // values it had at the read before (Gauss-Seidel's components before `first` were read
        // at t_next, after their values at t).
        let (mut at, mut reads) = (vec![t; n], Reads::new(n, t, start));
        for &c in &self.order[..position] {
            at[c] = t_next;
            if !jacobi {
                reads.at[c] = t_next;
            }
        }
        at[first] = event;
        loop {
            let now = at.iter().copied().fold(f64::INFINITY, f64::min);
            if now >= t_next {
                break;
            }
            // Components that arrived here earlier (at an event) are read now.
            for (c, &arrived) in at.iter().enumerate() {
                if arrived == now && reads.at[c] != now {
                    reads.read(run, plan, components, c, now)?;
                }
            }
            let mut end = at.iter().copied().filter(|&a| a > now).fold(t_next, f64::min);
            let stepping: Vec<usize> = self.order.iter().copied().filter(|&c| at[c] == now).collect();
            if jacobi {
                for &c in &stepping {
                    run.set_inputs_at(plan, components, c, now, &reads)?;
                }
            }
            for &c in &stepping {
                if !jacobi {
                    run.set_inputs_at(plan, components, c, now, &reads)?;
                }
                let to = if takes_any_step(&components[c]) { end } else { t_next };
                driving(c);
                self.apply_table(c, &mut run.instances[c], now)?;
                match step(&mut run.instances[c], now, to, plan.returns_early[c]).map_err(|e| failure(components, c, now, e))? {
                    Stepped::Reached => at[c] = to,
                    Stepped::Ended(message) => {
                        return Ok(Some(Failure { component: Some(components[c].name.clone()), time: now, message }));
                    }
                    Stepped::Early(time) => {
                        at[c] = time;
                        end = end.min(time);
                    }
                }
                if !jacobi {
                    reads.read(run, plan, components, c, at[c])?;
                }
            }
        }
        for c in 0..n {
            if reads.at[c] != t_next {
                reads.read(run, plan, components, c, t_next)?;
            }
        }
        Ok(None)
    }
}

/// When each component's values were read during [`Bound::synchronize`], and the values and
/// derivatives of the read before, to interpolate between.
struct Reads {
    at: Vec<f64>,
    before_at: Vec<f64>,
    before_values: Vec<f64>,
    before_rates: Vec<Rates>,
}

impl Reads {
    /// Every component read at `t`, with `start`'s values (no read before).
    fn new(n: usize, t: f64, (values, rates): (&[f64], &[Rates])) -> Reads {
        Reads { at: vec![t; n], before_at: vec![t; n], before_values: values.to_vec(), before_rates: rates.to_vec() }
    }

    /// Reads component `c` at `time`, keeping what it had.
    fn read(&mut self, run: &mut Running, plan: &Plan, components: &[Component], c: usize, time: f64) -> Result<(), Failure> {
        let (vars, offset) = &plan.reads[c];
        let slots = *offset..offset + vars.len();
        self.before_values[slots.clone()].copy_from_slice(&run.values[slots.clone()]);
        self.before_rates[slots.clone()].copy_from_slice(&run.rates[slots]);
        self.before_at[c] = self.at[c];
        self.at[c] = time;
        run.read(plan, components, c, time)
    }
}

/// A run's instances and the values passed between them, for [`Bound::synchronize`].
struct Running<'r, 'i> {
    instances: &'r mut [Instance<'i>],
    readers: &'r mut [Reader],
    values: &'r mut [f64],
    rates: &'r mut [Rates],
    scratch: &'r mut [Vec<f64>],
    buffers: &'r mut [Vec<f64>],
}

impl Running<'_, '_> {
    /// Reads component `c`'s values, and its output derivatives when polynomials are passed.
    fn read(&mut self, plan: &Plan, components: &[Component], c: usize, t: f64) -> Result<(), Failure> {
        read(plan, components, c, &mut self.instances[c], &mut self.readers[c], self.values, t)?;
        if plan.coupled {
            read_rates(plan, components, c, &mut self.instances[c], &mut self.scratch[c], self.rates, t)?;
        }
        Ok(())
    }

    /// Sets component `c`'s inputs for a sub-step from `now`: held ones as last read,
    /// polynomial ones from their source's Taylor polynomial at its last read moved to `now`,
    /// or, for Gauss-Seidel's interpolated ones from a source read past `now`, from the cubic
    /// through its last two reads.
    fn set_inputs_at(&mut self, plan: &Plan, components: &[Component], c: usize, now: f64, reads: &Reads) -> Result<(), Failure> {
        let instance = &mut self.instances[c];
        transfer(plan, components, c, instance, &mut self.buffers[c], self.values, now)?;
        let inputs = &plan.inputs[c];
        if inputs.rates.is_empty() {
            return Ok(());
        }
        let (mut vrs, mut xs, mut derivatives) = (Vec::new(), Vec::new(), Vec::new());
        for r in &inputs.rates {
            let (read_at, before_at) = (reads.at[r.source], reads.before_at[r.source]);
            let (value, d) = if r.interpolate && read_at > now && before_at <= now && before_at < read_at {
                let u0 = reads.before_values[r.from];
                let d = hermite(u0, reads.before_rates[r.from][0], self.values[r.from], self.rates[r.from][0], read_at - before_at);
                shifted(u0, &d, now - before_at)
            } else {
                shifted(self.values[r.from], &self.rates[r.from], now - read_at)
            };
            vrs.push(r.vr);
            xs.push(r.factor * value + r.offset);
            derivatives.extend(d[..r.order].iter().map(|x| r.factor * x));
        }
        let fail =
            |e: String| failure(components, c, now, format!("{e} (setting {} with their derivatives)", inputs.rate_names.join(", ")));
        instance.set_reals(&vrs, &xs).map_err(fail)?;
        instance.set_input_derivatives(&inputs.rate_vrs, &inputs.rate_orders, &derivatives).map_err(fail)
    }
}

/// What a run reads and sets, from [`Bound::plan`].
struct Plan<'a> {
    /// Per component: the variables read at each point, and where their values start.
    reads: Vec<(Vec<&'a Variable>, usize)>,
    /// The number of values read at each point.
    slots: usize,
    /// Per component: the inputs it gets from connections.
    inputs: Vec<Inputs<'a>>,
    /// Per component: the output derivatives read at each point (polynomial coupling).
    rates: Vec<RateReads>,
    /// Some connection passes a polynomial (else the hold's code alone runs).
    coupled: bool,
    /// The slots of the sources some input interpolates from, between their values at both ends
    /// of a step (Gauss-Seidel): their values and derivatives at the step's start are kept.
    interpolates: Vec<usize>,
    /// The slots of the recorded columns, in the caller's order (`None`: the values are the
    /// columns).
    recorded: Option<Vec<usize>>,
    /// Per component: it stops its step at an event (FMI 3.0 early return), and the master
    /// then brings the others to that time.
    returns_early: Vec<bool>,
}

/// A component's inputs from connections: its Real ones set in one call, the others one by one.
#[derive(Default)]
struct Inputs<'a> {
    /// The Real inputs' value references.
    vrs: Vec<u32>,
    /// Their names, for errors.
    names: Vec<&'a str>,
    /// Per Real input: the slot of its source, and the conversion `factor * x + offset`.
    reals: Vec<(usize, f64, f64)>,
    /// Integer, Boolean and Float32 inputs (`from` is a slot).
    others: Vec<Transfer<'a>>,
    /// The Real inputs that follow polynomials, and their derivatives' value references and
    /// orders in one `fmi2SetRealInputDerivatives` call.
    rates: Vec<Rate>,
    rate_vrs: Vec<u32>,
    rate_orders: Vec<i32>,
    /// Their names, for errors.
    rate_names: Vec<&'a str>,
    /// One polynomial input, extrapolated, without unit conversion (factor 1, which leaves
    /// every number as it is): the slot of its source, whose rates the call then passes as they
    /// are.
    direct: Option<usize>,
    /// The interpolating inputs (set here rather than with the others): value reference, the
    /// slot of the source, and the conversion.
    interpolated: Vec<(u32, usize, f64, f64)>,
}

/// A Real input that follows a polynomial over each step.
struct Rate {
    /// The input's value reference.
    vr: u32,
    /// The slot of its source's value (and derivatives), and the source component.
    from: usize,
    source: usize,
    /// The unit conversion `factor * x + offset` (derivatives scale by the factor alone).
    factor: f64,
    offset: f64,
    /// The derivatives passed: orders 1 to `order`.
    order: usize,
    /// Gauss-Seidel from a source already at the step's end: the cubic through both ends.
    interpolate: bool,
}

/// The output derivatives a component gives at each point: per source output (its slot, value
/// reference, highest order), and the one call that reads them all.
#[derive(Default)]
struct RateReads {
    slots: Vec<usize>,
    vrs: Vec<u32>,
    orders: Vec<usize>,
    call_vrs: Vec<u32>,
    call_orders: Vec<i32>,
    /// Per value of the call: the slot and the order's index where it goes.
    call_slots: Vec<(usize, usize)>,
    /// The call reads orders 1 to n of one output, in that order (a source of one polynomial
    /// connection): its slot, whose rates the call then fills in place.
    direct: Option<usize>,
}

/// Time derivatives of orders 1 to [`MAX_COUPLING_ORDER`] of a slot's value.
type Rates = [f64; MAX_COUPLING_ORDER];

/// Notes that the FMI calls from now on drive component `c`: a worker process that dies in one
/// is reported with the component (see `fmi_importer::trace::set_context`).
#[inline(always)]
fn driving(c: usize) {
    fmi_importer::trace::set_context(c as u32 + 1);
}

/// The failure of component `c` at `time`.
#[cold]
fn failure(components: &[Component], c: usize, time: f64, message: String) -> Failure {
    Failure { component: Some(components[c].name.clone()), time, message }
}

/// Reads component `c`'s planned outputs into its slots of `values`.
#[inline(always)]
fn read(
    plan: &Plan,
    components: &[Component],
    c: usize,
    instance: &mut Instance,
    reader: &mut Reader,
    values: &mut [f64],
    t: f64,
) -> Result<(), Failure> {
    driving(c);
    let (vars, offset) = &plan.reads[c];
    if vars.is_empty() {
        return Ok(());
    }
    instance.read(reader, &mut values[*offset..offset + vars.len()]).map_err(|e| failure(components, c, t, e))
}

/// Sets component `c`'s inputs from `values`: its Reals in one call, any others one by one.
#[inline(always)]
fn transfer(
    plan: &Plan,
    components: &[Component],
    c: usize,
    instance: &mut Instance,
    buffer: &mut [f64],
    values: &[f64],
    t: f64,
) -> Result<(), Failure> {
    driving(c);
    let inputs = &plan.inputs[c];
    if !inputs.vrs.is_empty() {
        for (x, &(from, factor, offset)) in buffer.iter_mut().zip(&inputs.reals) {
            *x = factor * values[from] + offset;
        }
        if let Err(e) = instance.set_reals(&inputs.vrs, buffer) {
            return Err(failure(components, c, t, format!("{e} (setting {})", inputs.names.join(", "))));
        }
    }
    for tr in &inputs.others {
        let x = tr.factor * values[tr.from] + tr.offset;
        let value = match tr.kind {
            Kind::Real | Kind::Float32 => Value::Real(x),
            Kind::Boolean => Value::Boolean(x != 0.0),
            _ => variables::number_value(tr.variable, x.round()).map_err(|e| failure(components, c, t, e))?,
        };
        instance.set(tr.variable, &value).map_err(|e| failure(components, c, t, e))?;
    }
    Ok(())
}

/// The values and output derivatives at the step's start, and the step.
struct Start<'s> {
    values: &'s [f64],
    rates: &'s [Rates],
    h: f64,
}

/// Reads component `c`'s output derivatives that polynomial connections pass (none: nothing).
/// Inlined into the loops with the importer's call: out of line, the frames cost about 100
/// instructions a communication step on quarter_car_road (tests/bench/systems), a fifth of the
/// master's share of the polynomial coupling, and the hold's loops did not gain from them.
#[inline(always)]
fn read_rates(
    plan: &Plan,
    components: &[Component],
    c: usize,
    instance: &mut Instance,
    scratch: &mut [f64],
    rates: &mut [Rates],
    t: f64,
) -> Result<(), Failure> {
    let r = &plan.rates[c];
    if r.call_vrs.is_empty() {
        return Ok(());
    }
    driving(c);
    if let Some(slot) = r.direct {
        // The usual source, one output: no copying through scratch (a few dozen instructions
        // a step).
        let into = &mut rates[slot][..r.call_vrs.len()];
        return instance.get_output_derivatives(&r.call_vrs, &r.call_orders, into).map_err(|e| failure(components, c, t, e));
    }
    instance.get_output_derivatives(&r.call_vrs, &r.call_orders, scratch).map_err(|e| failure(components, c, t, e))?;
    for (&x, &(slot, k)) in scratch.iter().zip(&r.call_slots) {
        rates[slot][k] = x;
    }
    Ok(())
}

/// Sets component `c`'s polynomial inputs' derivatives for the step from `t` (none: nothing).
/// Their values were set by [`transfer`]; an interpolating input's value is its source's at the
/// step's start instead (Gauss-Seidel: the source is at the step's end already). Inlined into
/// the loops, as [`read_rates`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn pass_rates(
    plan: &Plan,
    components: &[Component],
    c: usize,
    instance: &mut Instance,
    passed: &mut [f64],
    values: &[f64],
    rates: &[Rates],
    start: &Start,
    t: f64,
) -> Result<(), Failure> {
    let inputs = &plan.inputs[c];
    if inputs.rates.is_empty() {
        return Ok(());
    }
    driving(c);
    // The failure made only when there is one (a closure passed to map_err had its captures
    // stored at every call).
    let fail = |e: String| failure(components, c, t, format!("{e} (setting {} with their derivatives)", inputs.rate_names.join(", ")));
    if let Some(from) = inputs.direct {
        // One extrapolated input without conversion: its source's rates as they are.
        return match instance.set_input_derivatives(&inputs.rate_vrs, &inputs.rate_orders, &rates[from][..inputs.rate_vrs.len()]) {
            Ok(()) => Ok(()),
            Err(e) => Err(fail(e)),
        };
    }
    if let [r @ Rate { interpolate: true, .. }] = &inputs.rates[..] {
        // One interpolated input (Gauss-Seidel's usual one), as below without the buffers: its
        // source's value at the step's start and the cubic's derivatives.
        instance.set_reals(&[r.vr], &[r.factor * start.values[r.from] + r.offset]).map_err(fail)?;
        let d = hermite(start.values[r.from], start.rates[r.from][0], values[r.from], rates[r.from][0], start.h).map(|x| r.factor * x);
        return match instance.set_input_derivatives(&inputs.rate_vrs, &inputs.rate_orders, &d[..r.order]) {
            Ok(()) => Ok(()),
            Err(e) => Err(fail(e)),
        };
    }
    let (derivatives, interpolated) = passed.split_at_mut(inputs.rate_vrs.len());
    if !inputs.interpolated.is_empty() {
        // The interpolating inputs start from their sources' values at the step's start.
        let mut vrs = [0u32; 8];
        for (chunk_at, chunk) in inputs.interpolated.chunks(vrs.len()).enumerate() {
            let out = &mut interpolated[chunk_at * 8..][..chunk.len()];
            for (k, &(vr, from, factor, offset)) in chunk.iter().enumerate() {
                vrs[k] = vr;
                out[k] = factor * start.values[from] + offset;
            }
            instance.set_reals(&vrs[..chunk.len()], out).map_err(fail)?;
        }
    }
    let mut at = 0;
    for r in &inputs.rates {
        let d = if r.interpolate {
            hermite(start.values[r.from], start.rates[r.from][0], values[r.from], rates[r.from][0], start.h)
        } else {
            rates[r.from]
        };
        for x in &d[..r.order] {
            derivatives[at] = r.factor * x;
            at += 1;
        }
    }
    match instance.set_input_derivatives(&inputs.rate_vrs, &inputs.rate_orders, derivatives) {
        Ok(()) => Ok(()),
        Err(e) => Err(fail(e)),
    }
}

/// The Taylor coefficients at the step's start (first, second and third derivatives) of the
/// cubic p on [0, h] with p(0) = u0, p'(0) = d0, p(h) = u1, p'(h) = d1 (cubic Hermite
/// interpolation: its error is h^4 max|u''''| / 384).
#[inline]
fn hermite(u0: f64, d0: f64, u1: f64, d1: f64, h: f64) -> Rates {
    let slope = (u1 - u0) / h;
    let a2 = (3.0 * slope - 2.0 * d0 - d1) / h;
    let a3 = (d0 + d1 - 2.0 * slope) / (h * h);
    [d0, 2.0 * a2, 6.0 * a3]
}

/// Gives `sample` the point's values: all columns, or the recorded ones in the caller's order.
#[inline(always)]
fn emit(
    plan: &Plan,
    sample: &mut impl FnMut(f64, &[f64]) -> Result<(), String>,
    t: f64,
    values: &[f64],
    row: &mut [f64],
) -> Result<(), Failure> {
    let result = match &plan.recorded {
        None => sample(t, values),
        Some(slots) => {
            for (x, &s) in row.iter_mut().zip(slots) {
                *x = values[s];
            }
            sample(t, row)
        }
    };
    result.map_err(|message| Failure { component: None, time: t, message })
}

/// How a component's step ended.
enum Stepped {
    /// At the step's end.
    Reached,
    /// The FMU ended the simulation, for this reason.
    Ended(String),
    /// At an event before the step's end, handled (Event Mode left): the component is at
    /// this time.
    Early(f64),
}

/// One component's step from `t` to `t_next`. An FMI 3.0 FMU that stops at an event gets it
/// handled in Event Mode (`fmi3EnterEventMode`, `fmi3UpdateDiscreteStates` until settled,
/// `fmi3EnterStepMode`); then, when `stop_early`, the step ends there ([`Stepped::Early`]),
/// else it goes on to `t_next`.
#[inline(always)]
fn step(instance: &mut Instance, t: f64, t_next: f64, stop_early: bool) -> Result<Stepped, String> {
    let mut now = t;
    let mut stalled = 0;
    loop {
        match instance.do_step(now, t_next - now)? {
            Step::Done => return Ok(Stepped::Reached),
            Step::Ended { reason, .. } => return Ok(Stepped::Ended(reason)),
            Step::Event { time } => {
                if let Some(reason) = instance.handle_event(time)? {
                    return Ok(Stepped::Ended(reason));
                }
                if time >= t_next {
                    return Ok(Stepped::Reached);
                }
                if time < now || time.is_nan() {
                    return Err(format!("fmi3DoStep from t = {now} stopped at an event at t = {time}, before its start"));
                }
                if time > now {
                    if stop_early {
                        return Ok(Stepped::Early(time));
                    }
                } else {
                    // An event at the step's start (handled: step on), but not for ever.
                    stalled += 1;
                    if stalled > MAX_EVENTS_WITHOUT_PROGRESS {
                        return Err(format!(
                            "fmi3DoStep stopped at an event at t = {time} more than {MAX_EVENTS_WITHOUT_PROGRESS} times without advancing"
                        ));
                    }
                }
                now = time;
            }
        }
    }
}

/// How many events in a row a step may stop at without advancing before the FMU is taken to
/// be stuck.
const MAX_EVENTS_WITHOUT_PROGRESS: usize = 100;

/// Whether `component` stops its steps at its events: an FMI 3.0 Co-Simulation FMU that may
/// return early (`mightReturnEarlyFromDoStep`; the importer instantiates it with
/// `earlyReturnAllowed` then).
fn returns_early(component: &Component) -> bool {
    let fmu = &component.fmu;
    fmu.interface == Interface::CoSimulation
        && fmu.description.fmi_version == FmiVersion::Fmi3
        && fmu.description.co_simulation.as_ref().is_some_and(|c| c.might_return_early_from_do_step)
}

/// Whether `component` takes a step shorter than the communication step (FMI 2.0's
/// `canHandleVariableCommunicationStepSize`; FMI 3.0 Co-Simulation and Model Exchange always
/// do).
fn takes_any_step(component: &Component) -> bool {
    let d = &component.fmu.description;
    component.fmu.interface == Interface::ModelExchange
        || d.fmi_version == FmiVersion::Fmi3
        || d.co_simulation.as_ref().is_some_and(|c| c.can_handle_variable_communication_step_size)
}

/// The Taylor coefficients (value, then derivatives of orders 1 to 3) of a cubic moved from
/// its point to `delta` later (earlier when negative).
#[inline]
fn shifted(value: f64, d: &Rates, delta: f64) -> (f64, Rates) {
    let [d1, d2, d3] = *d;
    let value = value + delta * (d1 + delta * (d2 / 2.0 + delta * d3 / 6.0));
    (value, [d1 + delta * (d2 + delta * d3 / 2.0), d2 + delta * d3, d3])
}

#[cfg(test)]
mod tests {
    use super::{hermite, shifted};

    /// Moving a cubic's Taylor coefficients from 0 to `delta` gives its value and derivatives
    /// at `delta` (p = 1 + 2 s + 3 s^2 + 4 s^3, whose derivatives at 0 are 2, 6, 24), forward
    /// and back, to rounding (a few ulps of values of order 10).
    #[test]
    fn shifted_moves_a_cubic_along_itself() {
        let p = |s: f64| 1.0 + 2.0 * s + 3.0 * s * s + 4.0 * s * s * s;
        let dp = |s: f64| [2.0 + 6.0 * s + 12.0 * s * s, 6.0 + 24.0 * s, 24.0];
        for delta in [0.3, -0.7] {
            let (value, d) = shifted(p(0.0), &[2.0, 6.0, 24.0], delta);
            assert!((value - p(delta)).abs() < 1e-12, "{delta}: {value}");
            for (got, want) in d.iter().zip(dp(delta)) {
                assert!((got - want).abs() < 1e-12, "{delta}: {d:?}");
            }
        }
    }

    /// The interpolating cubic of a cubic is the cubic itself: from its values and slopes at 0
    /// and h, `hermite` gives its Taylor coefficients at 0 (p' = 2, p'' = 6, p''' = 24 for
    /// p = 1 + 2 s + 3 s^2 + 4 s^3), to rounding (h = 0.5 keeps the arithmetic within a few
    /// ulps: 1e-12 leaves room).
    #[test]
    fn hermite_reproduces_a_cubic() {
        let p = |s: f64| 1.0 + 2.0 * s + 3.0 * s * s + 4.0 * s * s * s;
        let dp = |s: f64| 2.0 + 6.0 * s + 12.0 * s * s;
        let h = 0.5;
        let d = hermite(p(0.0), dp(0.0), p(h), dp(h), h);
        for (got, want) in d.iter().zip([2.0, 6.0, 24.0]) {
            assert!((got - want).abs() < 1e-12, "{d:?}");
        }
    }
}
