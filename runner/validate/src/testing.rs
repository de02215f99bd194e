//! A fake FMU behind the probes' [`Binary`] and [`Instance`] traits, for the framework's unit
//! tests: x' = -k x from x(0) = 1, an output `x`, a fixed parameter `k` = 1, an event
//! indicator x - 0.5, a tunable String parameter. It keeps the state machine of the version's
//! own table (a call the table does not allow returns Error), so that it passes every probe,
//! and each [`Fault`] breaks one thing a probe must find. Its calls go through [`Core`], so
//! the call records and believed states are the real ones.

use std::collections::HashSet;
use std::ffi::{c_char, CStr};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Duration;

use runner_sandbox::SharedMemory;

use crate::fmi::{Code, Fmi, Interface, Op, Outcome, State, Type, Version};
use crate::instance::{Binary, Core, EventUpdate, Exports, FmuState, Instance, Log, StepResult, Tracer};
use crate::isolation::{Message, Out, Progress, PROGRESS_SIZE};
use crate::model::{Capabilities, Causality, Experiment, Grid, Initial, Model, Start, Var, Variability};
use crate::probe::Ctx;
use crate::report::Finding;
use crate::table::{Rule, Table};

/// One thing the fake FMU gets wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Fault {
    /// Accepts this call wherever it is made.
    Accepts(Op),
    /// Reset leaves x where the run left it.
    Reset,
    /// A value reference nobody has is read as 0.
    UnknownVr,
    /// The event iteration never settles.
    EventLoop,
}

/// A fake binary of version `fmi`.
pub(crate) struct Fake {
    fmi: Fmi,
    model: &'static Model,
    tracer: Tracer,
    faults: HashSet<Fault>,
}

/// Leaks `value`: the fakes live as long as a probe process's binaries do.
fn leak<T>(value: T) -> &'static T {
    Box::leak(Box::new(value))
}

/// The fake's description.
fn model() -> Model {
    let var = |name: &str, vr: u32, ty, causality, variability, initial, start| Var {
        name: name.into(),
        vr,
        ty,
        causality,
        variability,
        initial,
        is_state: vr == 0,
        start,
        min: None,
        max: None,
    };
    use Causality as C;
    use Variability as V;
    let capabilities = Capabilities {
        model_identifier: "fake".into(),
        can_get_and_set_fmu_state: true,
        can_serialize_fmu_state: true,
        can_handle_variable_communication_step_size: true,
        needs_completed_integrator_step: true,
        ..Capabilities::default()
    };
    Model {
        token: "{fake}".into(),
        vars: vec![
            var("x", 0, Type::Real, C::Output, V::Continuous, Some(Initial::Exact), Some(Start::Number(1.0))),
            var("k", 1, Type::Real, C::Parameter, V::Fixed, Some(Initial::Exact), Some(Start::Number(1.0))),
            var("label", 2, Type::String, C::Parameter, V::Tunable, Some(Initial::Exact), Some(Start::Text("fake".into()))),
        ],
        value_references: vec![0, 1, 2],
        initial_unknowns: HashSet::new(),
        nx: Some(1),
        nz: Some(1),
        experiment: Experiment { start: None, stop: Some(1.0), step: Some(0.01), tolerance: None },
        co_simulation: Some(capabilities.clone()),
        model_exchange: Some(capabilities),
    }
}

impl Fake {
    /// A fake FMU of version `fmi` with `faults`.
    pub(crate) fn new(fmi: Fmi, faults: &[Fault]) -> &'static Fake {
        let progress = Progress::over(leak(SharedMemory::new(PROGRESS_SIZE).expect("the memory of the call records")));
        let tracer = Tracer { progress, slot: 0, timeout: Duration::from_secs(5) };
        leak(Fake { fmi, model: leak(model()), tracer, faults: faults.iter().copied().collect() })
    }
}

impl Binary for Fake {
    fn fmi(&self) -> Fmi {
        self.fmi
    }

    fn model(&self) -> &'static Model {
        self.model
    }

    fn table(&self) -> &'static Table {
        match self.fmi {
            // FMI 1.0 gets no probes: the fakes never speak it.
            Fmi::Fmi2 | Fmi::Fmi1 => &crate::fmi2::table::TABLE,
            Fmi::Fmi3 => &crate::fmi3::table::TABLE,
        }
    }

    fn tracer(&self) -> Tracer {
        self.tracer
    }

    fn instantiate(
        &'static self,
        _name: &str,
        interface: Interface,
        token: &str,
        slot: usize,
    ) -> Result<Box<dyn Instance>, (Code, Option<String>)> {
        if token != self.model.token || self.model.interface(interface).is_none() {
            return Err((Code::error_of(self.fmi), Some("not this FMU's".into())));
        }
        let core = Core::new(self, interface, std::ptr::null_mut(), Box::<Log>::default(), self.tracer.in_slot(slot));
        Ok(Box::new(FakeInstance { core, sim: Sim::default(), state: State::Instantiated, faults: &self.faults }))
    }

    fn exports(&self, _name: &str) -> bool {
        true
    }

    fn required_exports(&self, _interfaces: &[Interface]) -> Exports {
        Exports { required: Vec::new(), passed: "all of them".into() }
    }

    fn query(&self, op: Op) -> Option<Option<String>> {
        self.fmi.identity().iter().find(|(o, _)| *o == op).map(|(_, text)| Some((*text).to_owned()))
    }
}

/// What the fake computes.
#[derive(Debug, Clone, PartialEq)]
struct Sim {
    t: f64,
    x: f64,
    k: f64,
    label: String,
    crossings: u32,
}

impl Default for Sim {
    fn default() -> Sim {
        Sim { t: 0.0, x: 1.0, k: 1.0, label: "fake".into(), crossings: 0 }
    }
}

/// One fake instance: its own state machine, kept apart from the validator's belief.
struct FakeInstance {
    core: Core,
    sim: Sim,
    state: State,
    faults: &'static HashSet<Fault>,
}

const OK: i32 = 0;
const ERROR: i32 = 3;

impl FakeInstance {
    /// Whether the table lets `op` be called now (sets by the table's conditions on `var`).
    fn allowed(&self, op: Op, var: Option<u32>) -> bool {
        if self.faults.contains(&Fault::Accepts(op)) {
            return true;
        }
        let table = self.core.binary.table();
        let (interface, model) = (self.core.interface, self.core.model());
        match table.rule(op, interface, self.state) {
            Rule::Allowed | Rule::GetIf => true,
            Rule::SetTimeIf => model.nx() == 0,
            Rule::EventModeUsed => model.capabilities(interface).event_mode,
            // Nothing to set (a zero-length set) is fine wherever a set is.
            Rule::SetIf => var
                .and_then(|vr| model.vars.iter().find(|v| v.vr == vr))
                .is_none_or(|v| (table.may_set)(op, interface, self.state, v) != Some(false)),
            // What the table does not probe the fake allows.
            Rule::Unprobed => true,
            Rule::Illegal => false,
        }
    }

    /// One call: refused with Error where the table does not allow it (the fake then enters
    /// the version's state after an error), else `body` with the simulation.
    fn call<T: Default>(&mut self, op: Op, var: Option<u32>, body: impl FnOnce(&mut Sim, &mut State) -> (i32, T)) -> Outcome<T> {
        let (allowed, null) = (self.allowed(op, var), self.core.null_instance);
        let (sim, state) = (&mut self.sim, &mut self.state);
        let fmi = self.core.fmi();
        self.core.call(
            op,
            None,
            None,
            |_| {
                Some(if null || !allowed {
                    if !null {
                        *state = fmi.state_after_error();
                    }
                    (ERROR, T::default())
                } else {
                    body(sim, state)
                })
            },
            T::default(),
        )
    }

    fn status(&mut self, op: Op, body: impl FnOnce(&mut Sim, &mut State)) -> Outcome<()> {
        self.call(op, None, |sim, state| {
            body(sim, state);
            (OK, ())
        })
    }
}

impl Instance for FakeInstance {
    fn core(&self) -> &Core {
        &self.core
    }

    fn core_mut(&mut self) -> &mut Core {
        &mut self.core
    }

    fn setup_experiment(&mut self, grid: &Grid) -> Option<Outcome<()>> {
        let start = grid.start;
        (self.core.fmi() == Fmi::Fmi2).then(|| self.status(Op::SetupExperiment, |sim, _| sim.t = start))
    }

    fn enter_initialization_mode(&mut self, grid: &Grid) -> Outcome<()> {
        let start = grid.start;
        self.status(Op::EnterInitializationMode, |sim, state| {
            sim.t = start;
            *state = State::InitializationMode;
        })
    }

    fn simple(&mut self, op: Op) -> Outcome<()> {
        let (interface, between) = (self.core.interface, self.core.binary.table().between_steps);
        let reset_fault = self.faults.contains(&Fault::Reset);
        self.status(op, |sim, state| match op {
            Op::ExitInitializationMode => {
                *state = if interface == Interface::ModelExchange { State::EventMode } else { between };
            }
            Op::Terminate => *state = State::Terminated,
            Op::Reset => {
                let kept = sim.x;
                *sim = Sim::default();
                if reset_fault {
                    sim.x = kept;
                }
                *state = State::Instantiated;
            }
            Op::EnterEventMode => *state = State::EventMode,
            Op::EnterContinuousTimeMode => *state = State::ContinuousTimeMode,
            Op::EnterStepMode => *state = State::StepMode,
            _ => {}
        })
    }

    fn set_debug_logging(&mut self, _on: bool) -> Outcome<()> {
        self.status(Op::SetDebugLogging, |_, _| {})
    }

    fn free(&mut self) {
        self.core.free(None);
    }

    fn get_numbers(&mut self, ty: Type, vrs: &[u32], _names: &str) -> Outcome<Vec<f64>> {
        let unknown_ok = self.faults.contains(&Fault::UnknownVr);
        let vrs = vrs.to_vec();
        self.call(Op::Get(ty), None, |sim, _| {
            let values: Option<Vec<f64>> = vrs
                .iter()
                .map(|vr| match (ty, vr) {
                    (Type::Real, 0) => Some(sim.x),
                    (Type::Real, 1) => Some(sim.k),
                    _ if unknown_ok => Some(0.0),
                    _ => None,
                })
                .collect();
            values.map_or((ERROR, Vec::new()), |v| (OK, v))
        })
    }

    fn get_strings(&mut self, vrs: &[u32], _names: &str) -> Outcome<Vec<Option<String>>> {
        let vrs = vrs.to_vec();
        self.call(Op::Get(Type::String), None, |sim, _| {
            if vrs.iter().all(|vr| *vr == 2) {
                (OK, vrs.iter().map(|_| Some(sim.label.clone())).collect())
            } else {
                (ERROR, Vec::new())
            }
        })
    }

    fn set_numbers(&mut self, ty: Type, vrs: &[u32], values: &[f64], _names: &str) -> Outcome<()> {
        let (vrs, values) = (vrs.to_vec(), values.to_vec());
        self.call(Op::Set(ty), vrs.first().copied(), |sim, _| {
            for (vr, v) in vrs.iter().zip(&values) {
                match (ty, vr) {
                    (Type::Real, 0) => sim.x = *v,
                    (Type::Real, 1) => sim.k = *v,
                    _ => return (ERROR, ()),
                }
            }
            (OK, ())
        })
    }

    fn set_strings(&mut self, vrs: &[u32], values: &[String], _names: &str) -> Outcome<()> {
        let (vrs, values) = (vrs.to_vec(), values.to_vec());
        self.call(Op::Set(Type::String), vrs.first().copied(), |sim, _| match (vrs.as_slice(), values.as_slice()) {
            ([2], [text]) => {
                sim.label = text.clone();
                (OK, ())
            }
            ([], []) => (OK, ()),
            _ => (ERROR, ()),
        })
    }

    fn raw_access(
        &mut self,
        op: Op,
        null_vrs: bool,
        null_values: bool,
        n: usize,
        vr: u32,
        _variable: Option<&str>,
        _value: Option<String>,
    ) -> Outcome<()> {
        let known = [0u32, 1, 2].contains(&vr) || self.faults.contains(&Fault::UnknownVr);
        self.call(op, (n > 0 && !null_vrs).then_some(vr), |_, _| match (n, null_vrs || null_values) {
            (0, _) => (OK, ()),
            (_, true) => (ERROR, ()),
            _ if known => (OK, ()),
            _ => (ERROR, ()),
        })
    }

    fn set_string_pointer(&mut self, vr: u32, text: *const c_char, _variable: &str, _value: String) -> Outcome<()> {
        // SAFETY: the caller's NUL-terminated text, or NULL.
        let text = (!text.is_null()).then(|| unsafe { CStr::from_ptr(text) }.to_string_lossy().into_owned());
        self.call(Op::Set(Type::String), Some(vr), |sim, _| match (vr, text) {
            (2, Some(text)) => {
                sim.label = text;
                (OK, ())
            }
            _ => (ERROR, ()),
        })
    }

    fn get_string_pointer(&mut self, vr: u32, _variable: &str) -> Outcome<(*const c_char, Option<String>)> {
        let got = self.get_strings(&[vr], "");
        Outcome { code: got.code, value: (std::ptr::null(), got.value.into_iter().next().flatten()), log: got.log }
    }

    fn get_fmu_state(&mut self) -> Outcome<FmuState> {
        let got = self.call(Op::GetFmuState, None, |sim, state| (OK, Some((sim.clone(), *state))));
        Outcome {
            code: got.code,
            value: got.value.map_or(std::ptr::null_mut(), |saved| Box::into_raw(Box::new(saved)) as FmuState),
            log: got.log,
        }
    }

    fn get_fmu_state_into_null(&mut self) -> Outcome<()> {
        self.call(Op::GetFmuState, None, |_, _| (ERROR, ()))
    }

    fn set_fmu_state(&mut self, saved: FmuState) -> Outcome<()> {
        self.call(Op::SetFmuState, None, |sim, state| {
            // SAFETY: a state get_fmu_state made.
            let (s, st) = unsafe { &*(saved as *const (Sim, State)) }.clone();
            (*sim, *state) = (s, st);
            (OK, ())
        })
    }

    fn free_fmu_state(&mut self, saved: &mut FmuState) -> Outcome<()> {
        let pointer = *saved;
        let got = self.call(Op::FreeFmuState, None, |_, _| {
            if !pointer.is_null() {
                // SAFETY: a state get_fmu_state made, freed once.
                drop(unsafe { Box::from_raw(pointer as *mut (Sim, State)) });
            }
            (OK, ())
        });
        if got.code.ok() {
            *saved = std::ptr::null_mut();
        }
        got
    }

    fn serialized_fmu_state_size(&mut self, _saved: FmuState) -> Outcome<usize> {
        self.call(Op::SerializedFmuStateSize, None, |_, _| (OK, 24))
    }

    fn serialize_fmu_state(&mut self, saved: FmuState, bytes: &mut [u8]) -> Outcome<()> {
        // SAFETY: a state get_fmu_state made.
        let (s, _) = unsafe { &*(saved as *const (Sim, State)) }.clone();
        let out: Vec<u8> = [s.t, s.x, s.k].iter().flat_map(|v| v.to_le_bytes()).collect();
        let fits = bytes.len() == out.len();
        if fits {
            bytes.copy_from_slice(&out);
        }
        self.call(Op::SerializeFmuState, None, |_, _| (if fits { OK } else { ERROR }, ()))
    }

    fn deserialize_fmu_state(&mut self, bytes: &[u8]) -> Outcome<FmuState> {
        let between = self.core.binary.table().between_steps;
        let interface = self.core.interface;
        let words: Vec<f64> = bytes.chunks(8).map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8]))).collect();
        let got = self.call(Op::DeserializeFmuState, None, |_, _| match words.as_slice() {
            [t, x, k] => {
                let state = if interface == Interface::ModelExchange { State::ContinuousTimeMode } else { between };
                (OK, Some((Sim { t: *t, x: *x, k: *k, ..Sim::default() }, state)))
            }
            _ => (ERROR, None),
        });
        Outcome {
            code: got.code,
            value: got.value.map_or(std::ptr::null_mut(), |saved| Box::into_raw(Box::new(saved)) as FmuState),
            log: got.log,
        }
    }

    fn do_step(&mut self, t: f64, h: f64) -> Outcome<StepResult> {
        self.call(Op::DoStep, None, |sim, _| {
            sim.x *= (-sim.k * h).exp();
            sim.t = t + h;
            (OK, StepResult::default())
        })
    }

    fn terminated(&mut self) -> Outcome<bool> {
        Outcome { code: Code::missing(self.core.fmi()), value: false, log: None }
    }

    fn set_time(&mut self, t: f64) -> Outcome<()> {
        self.status(Op::SetTime, |sim, _| sim.t = t)
    }

    fn set_continuous_states(&mut self, x: &[f64]) -> Outcome<()> {
        let x = x.to_vec();
        self.call(Op::SetContinuousStates, None, |sim, _| match x.as_slice() {
            [x] => {
                sim.x = *x;
                (OK, ())
            }
            _ => (ERROR, ()),
        })
    }

    fn get_vector(&mut self, op: Op, n: usize) -> Outcome<Vec<f64>> {
        self.call(op, None, |sim, _| {
            let value = match op {
                Op::GetDerivatives => -sim.k * sim.x,
                Op::GetEventIndicators => sim.x - 0.5,
                Op::GetContinuousStates => sim.x,
                _ => 1.0,
            };
            if n == 1 {
                (OK, vec![value])
            } else {
                (ERROR, Vec::new())
            }
        })
    }

    fn null_vector(&mut self, op: Op, _n: usize) -> Outcome<()> {
        self.call(op, None, |_, _| (ERROR, ()))
    }

    fn update_discrete_states(&mut self) -> Outcome<EventUpdate> {
        let endless = self.faults.contains(&Fault::EventLoop);
        self.call(Op::UpdateDiscreteStates, None, |sim, _| {
            if sim.x <= 0.5 && sim.crossings == 0 {
                sim.crossings = 1;
            }
            (OK, EventUpdate { again: endless, ..EventUpdate::default() })
        })
    }

    fn completed_integrator_step(&mut self) -> Outcome<(bool, bool)> {
        self.call(Op::CompletedIntegratorStep, None, |_, _| (OK, (false, false)))
    }

    fn number_of(&mut self, op: Op, null: bool) -> Outcome<usize> {
        self.call(op, None, |_, _| if null { (ERROR, 0) } else { (OK, 1) })
    }

    fn other(&mut self, op: Op) -> Outcome<()> {
        self.status(op, |_, _| {})
    }
}

/// A probe's context on the fake, and where its messages go.
pub(crate) struct Probed {
    pub out: &'static Out<'static>,
    messages: &'static Mutex<Vec<Message>>,
    pub runs: PathBuf,
}

impl Probed {
    /// A place for one probe's messages and runs.
    pub(crate) fn new() -> Probed {
        let dir = leak(tempfile::tempdir().expect("a temporary directory"));
        let messages: &'static Mutex<Vec<Message>> = leak(Mutex::new(Vec::new()));
        let out = leak(Out::new(move |message| messages.lock().expect("the messages").push(message.clone())));
        Probed { out, messages, runs: dir.path().to_path_buf() }
    }

    /// A context for probing `binary`'s `interface`.
    pub(crate) fn ctx(&self, binary: &'static Fake, interface: Interface) -> Ctx<'static> {
        Ctx::new(binary, interface, self.out, &self.runs, 0)
    }

    /// The findings sent so far.
    pub(crate) fn findings(&self) -> Vec<Finding> {
        self.messages
            .lock()
            .expect("the messages")
            .iter()
            .filter_map(|message| match message {
                Message::Finding(json) => Some(serde_json::from_str(json).expect("a finding")),
                Message::Cell { .. } => None,
            })
            .collect()
    }

    /// The errors and warnings, as (check, call, state).
    pub(crate) fn troubles(&self) -> Vec<(String, String, String)> {
        self.findings()
            .into_iter()
            .filter(|f| f.severity <= crate::report::Severity::Warning)
            .map(|f| (f.check, f.call.unwrap_or_default(), f.state.unwrap_or_default()))
            .collect()
    }
}
