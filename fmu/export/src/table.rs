//! The complete variable table of an FMU: the model's rows, the solver controls, the
//! independent variable `time` and the derivative `der(x)` of each state `x` (the last two for
//! Model Exchange, appended so the earlier value references stay as they were). A variable's
//! value reference is its index here, so the C glue, the XML and the documentation all number
//! variables the same way.

use std::any::TypeId;
use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

use crate::model::{Access, BaseType, Causality, Initial, Model, Range, Variability, Variable};
use solvers::controls::{Control, CONTROLS};

/// Where a row's value lives.
pub enum Slot<M> {
    Model(Access<M>),
    Control(Control),
    /// The independent variable, the instance's time.
    Time,
    /// The time derivative of state `k`, from `Model::derivatives`.
    Derivative(usize),
}

/// One variable of the FMU, whoever owns its value.
pub struct Row<M> {
    pub name: &'static str,
    pub description: &'static str,
    pub causality: Causality,
    pub variability: Variability,
    pub initial: Option<Initial>,
    pub unit: Option<&'static str>,
    pub display_unit: Option<&'static str>,
    pub base_type: BaseType,
    pub slot: Slot<M>,
    /// The model struct's real field holding the value ([`crate::Lift::field`]), for a
    /// model variable of type Real.
    pub field: Option<usize>,
}

impl<M> Row<M> {
    fn from_variable(v: Variable<M>) -> Row<M> {
        Row {
            name: v.name,
            description: v.description,
            causality: v.causality,
            variability: v.variability,
            initial: v.initial,
            unit: v.unit,
            display_unit: v.display_unit,
            base_type: v.base_type(),
            slot: Slot::Model(v.access),
            field: v.field,
        }
    }

    pub(crate) fn from_control(c: Control) -> Row<M> {
        let (causality, variability, initial) = if c.is_output() {
            (Causality::Output, Variability::Discrete, Some(Initial::Calculated))
        } else {
            (Causality::Parameter, Variability::Fixed, Some(Initial::Exact))
        };
        Row {
            name: c.name(),
            description: c.description(),
            causality,
            variability,
            initial,
            unit: c.unit(),
            display_unit: None,
            base_type: if c.is_integer() { BaseType::Integer } else { BaseType::Real },
            slot: Slot::Control(c),
            field: None,
        }
    }

    pub(crate) fn time() -> Row<M> {
        Row {
            name: "time",
            description: "Simulation time",
            causality: Causality::Independent,
            variability: Variability::Continuous,
            initial: None,
            unit: Some("s"),
            display_unit: None,
            base_type: BaseType::Real,
            slot: Slot::Time,
            field: None,
        }
    }

    /// The row `der(x)` of state `k`, whose own row is `state`; `names` holds the derivative's
    /// name and description.
    pub(crate) fn derivative(k: usize, state: &Row<M>, names: &'static (String, String)) -> Row<M> {
        Row {
            name: &names.0,
            description: &names.1,
            causality: Causality::Local,
            variability: Variability::Continuous,
            initial: Some(Initial::Calculated),
            unit: state.unit.and_then(crate::units::rate_of),
            display_unit: None,
            base_type: BaseType::Real,
            slot: Slot::Derivative(k),
            field: None,
        }
    }

    /// True when the importer may set this variable at all.
    pub fn is_settable(&self) -> bool {
        matches!(self.causality, Causality::Parameter | Causality::Input)
    }
}

/// The name and description of the derivative of state `state`: `der(state)`.
pub(crate) fn derivative_label(state: &str) -> (String, String) {
    (format!("der({state})"), format!("Time derivative of {state}"))
}

/// The name and description of `der(x)` for each state, in state order.
type DerivativeNames = &'static [(String, String)];

/// [`DerivativeNames`] made once per model type and process (a row's strings are `&'static`,
/// and a sweep builds a table per point).
fn derivative_names<M: Model>(rows: &[Row<M>]) -> DerivativeNames {
    static NAMES: OnceLock<Mutex<HashMap<TypeId, DerivativeNames>>> = OnceLock::new();
    let mut names = NAMES.get_or_init(Default::default).lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    names.entry(TypeId::of::<M>()).or_insert_with(|| {
        let made: Vec<(String, String)> = (0..M::N_STATES)
            .map(|k| {
                let state = rows.iter().find(|r| matches!(r.slot, Slot::Model(Access::State(j)) if j == k)).map_or("?", |r| r.name);
                derivative_label(state)
            })
            .collect();
        Box::leak(made.into_boxed_slice())
    })
}

/// The FMU's variables in value-reference order.
pub struct Table<M> {
    pub rows: Vec<Row<M>>,
    /// Per row: its value is computed by `Model::outputs` (a model variable that is neither a
    /// parameter, an input nor a state). Kept apart because every read asks.
    pub computed: Vec<bool>,
    /// Per row: the index of the state it is, [`DIRECT_TIME`] for the time, else
    /// [`DIRECT_NONE`]. The hot read ([`crate::core::Core::read_states`]) decodes this one word
    /// instead of the row's slot, half the instructions per value.
    pub direct: Vec<u32>,
}

/// [`Table::direct`] of the time row.
pub const DIRECT_TIME: u32 = u32::MAX - 1;
/// [`Table::direct`] of a row that is neither a state nor the time.
pub const DIRECT_NONE: u32 = u32::MAX;

impl<M: Model> Table<M> {
    /// Builds the table of model `M`, checking the invariants the rest of the toolkit relies on.
    pub fn new() -> Table<M> {
        let mut rows: Vec<Row<M>> = M::variables().into_iter().map(Row::from_variable).collect();
        rows.extend(CONTROLS.iter().map(|&c| Row::from_control(c)));
        rows.push(Row::time());
        let names = derivative_names::<M>(&rows);
        for (k, names) in names.iter().enumerate() {
            let state = rows.iter().find(|r| matches!(r.slot, Slot::Model(Access::State(j)) if j == k));
            let derivative = match state {
                Some(state) => Row::derivative(k, state, names),
                None => Row::derivative(k, &Row::time(), names),
            };
            rows.push(derivative);
        }
        let computed = rows
            .iter()
            .map(|r| {
                matches!(r.slot, Slot::Model(Access::Real { .. } | Access::Integer { .. } | Access::Boolean { .. } | Access::String { .. }))
                    && !matches!(r.causality, Causality::Parameter | Causality::Input)
            })
            .collect();
        let direct = rows
            .iter()
            .map(|r| match r.slot {
                Slot::Model(Access::State(j)) => u32::try_from(j).ok().filter(|&j| j < DIRECT_TIME).expect("fewer than 2^32 - 2 states"),
                Slot::Time => DIRECT_TIME,
                _ => DIRECT_NONE,
            })
            .collect();
        Table { rows, computed, direct }
    }

    /// Problems with the model's table (duplicate names, bad state indices, unknown units):
    /// authoring mistakes, caught by each model's tests and by `runner build`.
    pub fn problems(&self) -> Vec<String> {
        let mut problems = Vec::new();
        let defaults = M::default();
        for (i, (row, range)) in self.rows.iter().zip(ranges::<M>()).enumerate() {
            if let Slot::Model(Access::String { get, .. }) = row.slot {
                // C strings end at the first NUL: such a start value could not be handed out.
                if get(&defaults).contains('\0') {
                    problems.push(format!("String variable '{}' has a start value with a NUL character", row.name));
                }
            }
            if self.rows[..i].iter().any(|r| r.name == row.name) {
                problems.push(format!("variable name '{}' is used twice", row.name));
            }
            if let Slot::Model(Access::State(k)) = row.slot {
                if k >= M::N_STATES {
                    problems.push(format!("variable '{}' is state {k} but the model has {} states", row.name, M::N_STATES));
                }
            }
            if let Some(unit) = row.unit {
                match crate::units::unit(unit) {
                    None => problems.push(format!("variable '{}' has unit '{unit}', which fmu::units does not define", row.name)),
                    Some(_) => {
                        if let Some(du) = row.display_unit {
                            if crate::units::display_unit(unit, du).is_none() {
                                problems.push(format!("variable '{}': '{du}' is not a display unit of '{unit}'", row.name));
                            }
                        }
                    }
                }
            } else if row.display_unit.is_some() {
                problems.push(format!("variable '{}' has a display unit but no unit", row.name));
            }
            if row.base_type != BaseType::Real && (row.unit.is_some() || row.display_unit.is_some()) {
                problems.push(format!("variable '{}' is not Real but declares a unit", row.name));
            }
            if range != Range::Any && !row.is_settable() {
                problems.push(format!("variable '{}' declares a range but the importer cannot set it", row.name));
            }
            let real_range = matches!(range, Range::Finite | Range::Positive | Range::NonNegative);
            if (real_range && row.base_type != BaseType::Real)
                || (matches!(range, Range::OneOf(_)) && row.base_type != BaseType::Integer)
                || (range != Range::Any && matches!(row.base_type, BaseType::Boolean | BaseType::String))
            {
                problems.push(format!("variable '{}' declares a range its type {:?} cannot have", row.name, row.base_type));
            }
        }
        for k in 0..M::N_STATES {
            if !self.rows.iter().any(|r| matches!(r.slot, Slot::Model(Access::State(j)) if j == k)) {
                problems.push(format!("state {k} is not exposed by any variable"));
            }
        }
        problems
    }
}

/// The declared range of each row of `Table<M>` (the solver controls check their values when
/// set, and `time` and the `der(x)` rows are computed, so theirs is `Any`). Not kept in the
/// table, whose layout the stepping path reads: only initialization, the XML and the
/// documentation need them.
pub fn ranges<M: Model>() -> Vec<Range> {
    let mut ranges: Vec<Range> = M::variables().iter().map(|v| v.range).collect();
    ranges.resize(ranges.len() + CONTROLS.len() + 1 + M::N_STATES, Range::Any);
    ranges
}

impl<M: Model> Default for Table<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M> Table<M> {
    /// The row of value reference `vr`.
    pub fn row(&self, vr: u32) -> Option<&Row<M>> {
        self.rows.get(vr as usize)
    }

    /// The value reference of the variable called `name`.
    pub fn value_reference(&self, name: &str) -> Option<u32> {
        self.rows.iter().position(|r| r.name == name).map(|i| i as u32)
    }
}

impl<M: Model> Table<M> {
    /// The value of every Real and Integer parameter of `model` by name (Integers as f64; the
    /// Boolean and String ones and the solver controls left out): what the closed forms of a model's references.toml read.
    pub fn parameter_values(&self, model: &M) -> Vec<(&'static str, f64)> {
        let parameters = self.rows.iter().filter(|r| r.causality == Causality::Parameter && matches!(r.slot, Slot::Model(_)));
        parameters
            .filter_map(|r| match r.start(model)? {
                Start::Real(v) => Some((r.name, v)),
                Start::Integer(v) => Some((r.name, v as f64)),
                Start::Boolean(_) | Start::String(_) => None,
            })
            .collect()
    }
}

/// FNV-1a over `bytes`, from `seed`: a stable hash (std's hashers may change between releases).
fn fnv1a(seed: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(seed, |h, b| (h ^ *b as u64).wrapping_mul(0x0000_0100_0000_01b3))
}

/// Everything that makes two builds of a model interface-compatible, as text.
fn fingerprint<M: Model>() -> String {
    let info = M::info();
    let mut s = format!("{}|{}|{}|{}|", info.identifier, env!("CARGO_PKG_VERSION"), M::N_STATES, M::N_EVENT_INDICATORS);
    for (vr, row) in Table::<M>::new().rows.iter().enumerate() {
        s.push_str(&format!("{vr}:{}:{:?}:{:?}:{:?}:{:?};", row.name, row.base_type, row.causality, row.variability, row.unit));
    }
    s
}

/// The model's GUID and its FMU-state tag, computed once per model and process: the fingerprint
/// formats the whole table (about 30 us), and a sweep instantiates, checking the GUID, once
/// per point.
fn identity<M: Model>() -> &'static (String, u64) {
    // One entry per model type: a cdylib holds one model, a test binary several.
    static IDENTITIES: OnceLock<Mutex<HashMap<TypeId, &'static (String, u64)>>> = OnceLock::new();
    let mut identities = IDENTITIES.get_or_init(Default::default).lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    identities.entry(TypeId::of::<M>()).or_insert_with(|| {
        let text = fingerprint::<M>();
        let a = fnv1a(0xcbf2_9ce4_8422_2325, text.as_bytes());
        let b = fnv1a(0x6c62_272e_07bb_0142, text.as_bytes());
        let guid =
            format!("{{{:08x}-{:04x}-{:04x}-{:04x}-{:012x}}}", a >> 32, (a >> 16) & 0xffff, a & 0xffff, b >> 48, b & 0xffff_ffff_ffff);
        // FMU states hold the model struct itself, so their tag also covers its fields: a
        // state saved by a build whose struct differs (a field added or moved) is refused
        // rather than misread. The GUID, which importers see, depends on the interface alone.
        let tag = fnv1a(a, M::LAYOUT.as_bytes());
        Box::leak(Box::new((guid, tag)))
    })
}

/// A 64-bit hash of the model's interface and of its struct's fields ([`Variables::LAYOUT`]),
/// used to tag FMU states.
///
/// [`Variables::LAYOUT`]: crate::model::Variables::LAYOUT
pub fn guid_hash<M: Model>() -> u64 {
    identity::<M>().1
}

/// The FMU's GUID: derived from the model's interface, so the XML and the binary built from
/// the same table always agree, and a changed table gets a new GUID.
pub fn guid<M: Model>() -> &'static str {
    &identity::<M>().0
}

/// A start value as the XML and the documentation show it.
#[derive(Debug, Clone, PartialEq)]
pub enum Start {
    Real(f64),
    Integer(i32),
    Boolean(bool),
    String(String),
}

impl std::fmt::Display for Start {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Start::Real(v) => write!(f, "{v:?}"),
            Start::Integer(v) => write!(f, "{v}"),
            Start::Boolean(v) => write!(f, "{v}"),
            Start::String(v) => write!(f, "{v:?}"),
        }
    }
}

impl<M: Model> Row<M> {
    /// The start value FMI requires for this row (parameters, inputs, exact/approx initials),
    /// read from the model's `Default` and the default controls; `None` where FMI forbids one.
    pub fn start(&self, model: &M) -> Option<Start> {
        let needs_start = matches!(self.causality, Causality::Parameter | Causality::Input)
            || matches!(self.initial, Some(Initial::Exact) | Some(Initial::Approx));
        if !needs_start {
            return None;
        }
        Some(match &self.slot {
            Slot::Model(Access::State(_)) => return None,
            Slot::Model(Access::Real { get, .. }) => Start::Real(get(model)),
            Slot::Model(Access::Integer { get, .. }) => Start::Integer(get(model)),
            Slot::Model(Access::Boolean { get, .. }) => Start::Boolean(get(model)),
            Slot::Model(Access::String { get, .. }) => Start::String(get(model).to_owned()),
            Slot::Time | Slot::Derivative(_) => return None,
            Slot::Control(c) => {
                let value = c.default_value()?;
                if c.is_integer() {
                    Start::Integer(value as i32)
                } else {
                    Start::Real(value)
                }
            }
        })
    }
}
