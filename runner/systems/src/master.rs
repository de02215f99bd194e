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

use fmi_importer::{Causality, Instance, Kind, Reader, Step, Value, Variable};
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

/// A connection ready to pass values: from `values[from]` to component `to`'s `variable`.
#[derive(Clone, Copy)]
struct Transfer<'a> {
    from: usize,
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
    /// An algebraic loop Jacobi breaks by its one-step delay (a warning for the user).
    pub warning: Option<String>,
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
            transfers.push(Transfer { from: index_of(*fc, from), to: *tc, variable: to, factor, offset, kind: to.kind });
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
        let mut bound =
            Bound { system, columns, reads, transfers, parameters, order: (0..components.len()).collect(), master, warning: None };
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
        }
        Ok(bound)
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
        for tr in &self.transfers {
            let to = &mut inputs[tr.to];
            let from = slot_of[tr.from];
            if tr.kind == Kind::Real {
                to.vrs.push(tr.variable.value_reference);
                to.names.push(tr.variable.name.as_str());
                to.reals.push((from, tr.factor, tr.offset));
            } else {
                to.others.push(Transfer { from, ..*tr });
            }
        }
        let recorded = recorded.map(|r| r.iter().map(|&c| slot_of[c]).collect());
        Plan { reads, slots, inputs, recorded }
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
        // The Real inputs' values, per component, filled before each set.
        let mut buffers: Vec<Vec<f64>> = plan.inputs.iter().map(|i| vec![0.0; i.vrs.len()]).collect();
        let mut row = vec![0.0; plan.recorded.as_ref().map_or(0, Vec::len)];
        let mut instances = Vec::with_capacity(components.len());
        for (c, component) in components.iter().enumerate() {
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
            }
        }
        for (c, instance) in instances.iter_mut().enumerate() {
            instance.exit_initialization_mode().map_err(fail(c, grid.start))?;
        }
        for c in 0..n_components {
            read(plan, components, c, &mut instances[c], &mut readers[c], &mut values, grid.start)?;
        }
        emit(plan, &mut sample, grid.start, &values, &mut row)?;
        let n = grid.steps();
        let jacobi = self.master == Master::Jacobi;
        for i in 0..n {
            let (t, t_next) = (grid.time_of(i, n), grid.time_of(i + 1, n));
            if jacobi {
                for c in 0..n_components {
                    transfer(plan, components, c, &mut instances[c], &mut buffers[c], &values, t)?;
                }
            }
            for &c in &self.order {
                if !jacobi {
                    transfer(plan, components, c, &mut instances[c], &mut buffers[c], &values, t)?;
                }
                if let Some(ended) = step(&mut instances[c], t, t_next).map_err(fail(c, t))? {
                    // The others may have stepped on: the last row is the one at t.
                    return Ok(Outcome::Ended(Failure { component: Some(components[c].name.clone()), time: t, message: ended }));
                }
                if !jacobi {
                    read(plan, components, c, &mut instances[c], &mut readers[c], &mut values, t_next)?;
                }
            }
            if jacobi {
                for c in 0..n_components {
                    read(plan, components, c, &mut instances[c], &mut readers[c], &mut values, t_next)?;
                }
            }
            emit(plan, &mut sample, t_next, &values, &mut row)?;
        }
        Ok(Outcome::Finished)
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
    /// The slots of the recorded columns, in the caller's order (`None`: the values are the
    /// columns).
    recorded: Option<Vec<usize>>,
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

/// One component's step from `t` to `t_next`, going on from any event it stops at (FMI 3.0):
/// `Some(reason)` when the FMU ended the simulation.
#[inline(always)]
fn step(instance: &mut Instance, t: f64, t_next: f64) -> Result<Option<String>, String> {
    let mut now = t;
    loop {
        match instance.do_step(now, t_next - now)? {
            Step::Done => return Ok(None),
            Step::Ended { reason, .. } => return Ok(Some(reason)),
            Step::Event { time } => {
                if let Some(reason) = instance.handle_event(time)? {
                    return Ok(Some(reason));
                }
                if time >= t_next {
                    return Ok(None);
                }
                now = time;
            }
        }
    }
}
