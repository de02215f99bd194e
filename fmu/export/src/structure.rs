//! The dependencies a modelDescription's ModelStructure declares (FMI 2.0 section 2.2.8), found
//! by probing the compiled equations, so that they are the ones the model really has and not a
//! second description that could disagree with the code.
//!
//! Continuous time (Outputs, Derivatives): the knowns are time, the states and the inputs.
//! The model runs its default experiment, for the default parameters and for a few parameter
//! sets drawn around them (a dependency hidden by a default of zero, such as a friction
//! coefficient, shows for the others); at sample points along each run, through every mode the
//! run visits, each known is moved by two sizes of step and every derivative and continuous
//! output that changes in any bit depends on it. Initialization (InitialUnknowns): the knowns
//! are the start time, the parameters and the inputs, each moved the same way (integers by one
//! and to their negative, booleans flipped) before `Model::initial_state`.
//!
//! Probing can only miss a dependency, never invent one, and misses one only where it is
//! invisible at every sample (a mode no default run reaches, a parameter that changes nothing
//! near every parameter set tried). The models' tests compare the result with the dependencies
//! their derivations give. Discrete outputs change only at events, where they may depend on
//! anything: no dependencies are claimed for them.

use std::collections::BTreeSet;

use crate::core::{Core, Names, Phase, State, StepEnd};
use crate::logging::Logger;
use crate::model::{Access, BaseType, Causality, Model, Variability};
use crate::table::{Row, Slot, Table};

/// Parameter sets drawn around the defaults, besides the defaults themselves.
const DRAWS: usize = 3;
/// Draws tried to find them (a draw the model refuses, e.g. a linkage that cannot be
/// assembled, is skipped).
const ATTEMPTS: usize = 40;
/// Relative spread of the draws around a nonzero default.
const SPREAD: f64 = 0.05;
/// Sample points per run of the default experiment.
const SAMPLES: usize = 200;

/// For each row of the table, the rows it depends on; `None` where no claim is made (which
/// FMI reads as "depends on every known").
#[derive(Debug, Clone, PartialEq)]
pub struct Dependencies {
    /// In continuous time, for the derivatives and the continuous Real outputs.
    pub continuous: Vec<Option<Vec<usize>>>,
    /// At initialization, for the outputs, calculated parameters and derivatives.
    pub initial: Vec<Option<Vec<usize>>>,
}

const PROBE_NAMES: Names =
    Names { setup: "the experiment setup", exit_initialization: "the end of initialization", real: "Real", integer: "Integer" };

/// A deterministic generator (the description must be the same at every build).
struct Lcg(u64);

impl Lcg {
    /// A number in [-1, 1).
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// A Real parameter or input the draws may move: its row and setter.
fn drawable<M>(row: &Row<M>) -> Option<fn(&mut M, f64)> {
    match (&row.slot, row.causality) {
        (Slot::Model(Access::Real { set: Some(set), .. }), Causality::Parameter | Causality::Input) => Some(*set),
        _ => None,
    }
}

/// The default parameters and up to [`DRAWS`] sets around them that the model accepts.
fn parameter_sets<M: Model>(table: &Table<M>) -> Vec<M> {
    let mut defaults = M::default();
    crate::model::refresh(&mut defaults);
    let mut sets = vec![defaults.clone()];
    let mut rng = Lcg(0x005e_ed0f_d3e9);
    for _ in 0..ATTEMPTS {
        if sets.len() > DRAWS {
            break;
        }
        let mut model = defaults.clone();
        for row in &table.rows {
            if let (Some(set), Slot::Model(Access::Real { get, .. })) = (drawable(row), &row.slot) {
                let v = get(&defaults);
                let u = rng.next();
                // A zero default (no friction, at rest) becomes a small positive value.
                set(&mut model, if v != 0.0 { v * (1.0 + SPREAD * u) } else { 0.006 + 0.005 * u });
            }
        }
        let mut x = vec![0.0; M::N_STATES];
        crate::model::refresh(&mut model);
        if model.clone().initial_state(&mut x).is_ok() {
            sets.push(model);
        }
    }
    sets
}

/// The states of a run of the default experiment from `model`'s parameters, at up to
/// [`SAMPLES`] communication points and where the run ends.
pub(crate) fn trajectory<M: Model>(model: &M) -> Vec<State<M>> {
    let mut core = Core::<M>::new("probe", Logger::new(None, false), PROBE_NAMES);
    let table = Table::<M>::new();
    // The parameters go in through the table, as an importer would set them.
    for (vr, row) in table.rows.iter().enumerate() {
        if let (Some(_), Slot::Model(Access::Real { get, .. })) = (drawable(row), &row.slot) {
            if core.set_real(&[vr as u32], &[get(model)], Phase::Initializing, "probe").is_err() {
                return Vec::new();
            }
        }
    }
    let info = M::info();
    if core.setup(None, 0.0, Some(info.stop_time)).is_err() || core.start().is_err() {
        return Vec::new();
    }
    let n = ((info.stop_time / info.output_interval).round() as usize).max(1);
    let stride = (n / SAMPLES).max(1);
    let mut samples = vec![core.capture()];
    for k in 1..=n {
        let t = core.time();
        let target = if k == n { info.stop_time } else { k as f64 * info.output_interval };
        match core.do_step(t, target - t) {
            Ok(StepEnd::Completed) if k % stride == 0 || k == n => samples.push(core.capture()),
            Ok(StepEnd::Completed) => {}
            Ok(StepEnd::EndedEarly) => {
                samples.push(core.capture());
                break;
            }
            Err(_) => break,
        }
    }
    samples
}

/// The bits of every row's value at (t, x) for `model` (0 for rows not computed from them).
fn values<M: Model>(table: &Table<M>, model: &M, t: f64, x: &[f64]) -> Vec<u64> {
    let mut model = model.clone();
    model.outputs(t, x);
    let mut dx = vec![0.0; M::N_STATES];
    model.derivatives(t, x, &mut dx);
    table
        .rows
        .iter()
        .map(|row| match &row.slot {
            Slot::Model(Access::State(k)) => x[*k].to_bits(),
            Slot::Model(Access::Real { get, .. }) => get(&model).to_bits(),
            Slot::Model(Access::Integer { get, .. }) => get(&model) as u64,
            Slot::Model(Access::Boolean { get, .. }) => get(&model) as u64,
            // String variables are parameters: never computed from (t, x) or the inputs.
            Slot::Model(Access::String { .. }) => 0,
            Slot::Derivative(k) => dx[*k].to_bits(),
            Slot::Time | Slot::Control(_) => 0,
        })
        .collect()
}

/// Records in `found[i]` the known `j` for every row whose value differs between `base` and
/// `moved`.
fn record(found: &mut [BTreeSet<usize>], base: &[u64], moved: &[u64], j: usize) {
    for (i, (a, b)) in base.iter().zip(moved).enumerate() {
        if a != b {
            found[i].insert(j);
        }
    }
}

/// Two steps for a known of value `v`: small (a change of the last digits) and large.
fn steps(v: f64) -> [f64; 2] {
    let scale = v.abs().max(1.0);
    [1e-7 * scale, 1e-3 * scale]
}

/// The rows that are unknowns in continuous time: derivatives and continuous Real outputs.
fn is_continuous_unknown<M>(row: &Row<M>) -> bool {
    matches!(row.slot, Slot::Derivative(_))
        || (row.causality == Causality::Output && row.variability == Variability::Continuous && row.base_type == BaseType::Real)
}

/// The rows that are unknowns at initialization: outputs, calculated parameters, derivatives.
fn is_initial_unknown<M>(row: &Row<M>) -> bool {
    matches!(row.slot, Slot::Derivative(_)) || matches!(row.causality, Causality::Output | Causality::CalculatedParameter)
}

fn continuous<M: Model>(table: &Table<M>, sets: &[M]) -> Option<Vec<BTreeSet<usize>>> {
    let mut found = vec![BTreeSet::new(); table.rows.len()];
    let mut sampled = false;
    for set in sets {
        for s in trajectory(set) {
            sampled = true;
            let base = values(table, &s.model, s.t, &s.x);
            for (j, row) in table.rows.iter().enumerate() {
                match &row.slot {
                    Slot::Time => {
                        for h in steps(s.t) {
                            record(&mut found, &base, &values(table, &s.model, s.t + h, &s.x), j);
                        }
                    }
                    Slot::Model(Access::State(k)) => {
                        for h in steps(s.x[*k]) {
                            let mut x = s.x.clone();
                            x[*k] += h;
                            record(&mut found, &base, &values(table, &s.model, s.t, &x), j);
                        }
                    }
                    Slot::Model(Access::Real { get, set: Some(set) }) if row.causality == Causality::Input => {
                        let v = get(&s.model);
                        for h in steps(v) {
                            let mut model = s.model.clone();
                            set(&mut model, v + h);
                            crate::model::refresh(&mut model);
                            record(&mut found, &base, &values(table, &model, s.t, &s.x), j);
                        }
                    }
                    _ => {}
                }
            }
        }
    }
    sampled.then_some(found)
}

/// A change of one parameter or input of a model.
type Move<M> = Box<dyn Fn(&mut M)>;

/// The values a parameter or input may be moved to from its value in `model`.
fn moves<M: Model>(row: &Row<M>, model: &M) -> Vec<Move<M>> {
    match &row.slot {
        Slot::Model(Access::Real { get, set: Some(set) }) => {
            let (v, set) = (get(model), *set);
            steps(v).into_iter().map(|h| Box::new(move |m: &mut M| set(m, v + h)) as Move<M>).collect()
        }
        Slot::Model(Access::Integer { get, set: Some(set) }) => {
            let (v, set) = (get(model), *set);
            [v.saturating_add(1), v.saturating_sub(1), v.saturating_neg()]
                .into_iter()
                .filter(|&w| w != v)
                .map(|w| Box::new(move |m: &mut M| set(m, w)) as Move<M>)
                .collect()
        }
        Slot::Model(Access::Boolean { get, set: Some(set) }) => {
            let (v, set) = (get(model), *set);
            vec![Box::new(move |m: &mut M| set(m, !v))]
        }
        _ => Vec::new(),
    }
}

/// The values at initialization (start time `t`) for the parameters of `model`, or `None` if
/// the model refuses them.
fn initial_values<M: Model>(table: &Table<M>, model: &M, t: f64) -> Option<Vec<u64>> {
    let mut model = model.clone();
    // What the model derives from its parameters, as the FMU derives it before the initial
    // state.
    crate::model::refresh(&mut model);
    let mut x = vec![0.0; M::N_STATES];
    model.initial_state(&mut x).ok()?;
    Some(values(table, &model, t, &x))
}

fn initial<M: Model>(table: &Table<M>, sets: &[M]) -> Vec<BTreeSet<usize>> {
    let mut found = vec![BTreeSet::new(); table.rows.len()];
    for set in sets {
        let Some(base) = initial_values(table, set, 0.0) else { continue };
        for (j, row) in table.rows.iter().enumerate() {
            if matches!(row.slot, Slot::Time) {
                for h in steps(0.0) {
                    if let Some(moved) = initial_values(table, set, h) {
                        record(&mut found, &base, &moved, j);
                    }
                }
                continue;
            }
            if !matches!(row.causality, Causality::Parameter | Causality::Input) {
                continue;
            }
            let moves = moves(row, set);
            let mut accepted = false;
            for apply in &moves {
                let mut model = set.clone();
                apply(&mut model);
                if let Some(moved) = initial_values(table, &model, 0.0) {
                    accepted = true;
                    record(&mut found, &base, &moved, j);
                }
            }
            // A model parameter whose every move is refused cannot be probed: assume that
            // everything depends on it.
            if !accepted && !moves.is_empty() {
                for f in found.iter_mut() {
                    f.insert(j);
                }
            }
        }
    }
    found
}

/// The dependencies of model `M`'s unknowns (see the module documentation).
pub fn dependencies<M: Model>() -> Dependencies {
    let table = Table::<M>::new();
    let sets = parameter_sets(&table);
    let continuous_found = continuous(&table, &sets);
    let initial_found = initial(&table, &sets);
    let continuous = table
        .rows
        .iter()
        .enumerate()
        .map(|(i, row)| match &continuous_found {
            Some(found) if is_continuous_unknown(row) => Some(found[i].iter().copied().collect()),
            _ => None,
        })
        .collect();
    let initial =
        table.rows.iter().enumerate().map(|(i, row)| is_initial_unknown(row).then(|| initial_found[i].iter().copied().collect())).collect();
    Dependencies { continuous, initial }
}
