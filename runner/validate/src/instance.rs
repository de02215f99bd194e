//! An FMU binary and its instances as the probes call them, whatever the version: the
//! [`Binary`] and [`Instance`] traits are the calls that differ between FMI 2.0 and 3.0 (each
//! version's module implements them over its C functions), and [`Core`] is what every call has
//! in common: recorded in the memory shared with the validator before it is made (so that a
//! crash or a hang names it), the FMU's log taken after it, the believed state moved on after Error or Fatal.
//!
//! This is the probe process's side; nothing here is safe to run in the validator's own
//! process.

use std::ffi::{c_char, c_int, c_void};
use std::sync::Mutex;
use std::time::Duration;

use crate::failure::Failure;
use crate::fmi::{numbers, Code, Fmi, Interface, Op, Outcome, State, Type, Version};
use crate::isolation::{CallRecord, Progress};
use crate::model::{Grid, Model};
use crate::table::Table;

/// A captured FMU state (`fmi2FMUstate`, `fmi3FMUState`).
pub(crate) type FmuState = *mut c_void;

/// What a Co-Simulation step returned besides its status.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct StepResult {
    /// FMI 3.0 eventHandlingNeeded.
    pub event: bool,
    /// FMI 3.0 terminateSimulation.
    pub terminate: bool,
    /// FMI 3.0 earlyReturn, and the lastSuccessfulTime it reached.
    pub early: bool,
    pub last: f64,
}

/// What one discrete update (fmi2NewDiscreteStates, fmi3UpdateDiscreteStates) returned.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct EventUpdate {
    /// Another update is needed at the same time.
    pub again: bool,
    pub terminate: bool,
    pub values_changed: bool,
    pub next_event_time: Option<f64>,
}

/// The messages an instance logged since they were last taken.
#[derive(Default)]
pub(crate) struct Log {
    messages: Mutex<Vec<String>>,
}

impl Log {
    /// One message: `line` (the whole of it) goes to the probe process's stderr, whose tail a
    /// crash report quotes; `text` (the message alone) is kept for the call's findings.
    pub(crate) fn receive(&self, line: &str, text: &str) {
        eprintln!("{line}");
        if let Ok(mut messages) = self.messages.lock() {
            if messages.len() >= 20 {
                messages.remove(0);
            }
            messages.push(fmi_schema::escaped_and_cut(text, 300, "..."));
        }
    }

    /// The last few messages logged since the last take, joined; `None` if there were none.
    pub(crate) fn take(&self) -> Option<String> {
        let mut messages = self.messages.lock().ok()?;
        if messages.is_empty() {
            return None;
        }
        let joined = messages[messages.len().saturating_sub(3)..].join(" | ");
        messages.clear();
        Some(joined)
    }
}

/// Where the probe process records its calls: the progress record in the memory it shares
/// with the validator, the slot of the calling thread, and the timeout each call gets.
#[derive(Clone, Copy)]
pub(crate) struct Tracer {
    pub progress: Progress<'static>,
    pub slot: usize,
    pub timeout: Duration,
}

impl Tracer {
    /// Runs `body` (one FMI call) with `record` in the progress record: the parent can then name
    /// it if it crashes or overruns the timeout.
    pub(crate) fn traced<R>(&self, record: &CallRecord, body: impl FnOnce() -> R) -> R {
        self.progress.begin(self.slot, record, self.timeout);
        let result = body();
        self.progress.end(self.slot);
        result
    }

    /// The same tracer for the thread of another slot.
    pub(crate) fn in_slot(self, slot: usize) -> Tracer {
        Tracer { slot, ..self }
    }
}

/// The value a record shows for a call made with a NULL instance.
pub(crate) fn null_instance(fmi: Fmi) -> String {
    format!("a NULL {}", fmi.instance_type())
}

/// `value` of a call as its record shows it: short, and printable.
fn shown(text: String) -> String {
    fmi_schema::escaped_and_cut(&text, 200, "...")
}

/// What every instance has, whatever its version.
pub(crate) struct Core {
    pub binary: &'static dyn Binary,
    pub interface: Interface,
    /// Where the validator believes the instance is (the state the standard's state machine
    /// puts it in after the calls made).
    pub state: State,
    /// While set, every call passes a NULL instance (the NULL-instance probes): the instance
    /// itself is not addressed, so its believed state does not move.
    pub null_instance: bool,
    /// The C handle (`fmi2Component`, `fmi3Instance`).
    handle: *mut c_void,
    tracer: Tracer,
    log: Box<Log>,
    fatal: bool,
}

// An instance is used by one thread at a time (the threads probe moves each to its own).
unsafe impl Send for Core {}

impl Core {
    /// The core of the instance `handle` that `binary` made for `interface`, logging into
    /// `log` (whose address the FMU holds).
    pub(crate) fn new(binary: &'static dyn Binary, interface: Interface, handle: *mut c_void, log: Box<Log>, tracer: Tracer) -> Core {
        Core { binary, interface, state: State::Instantiated, null_instance: false, handle, tracer, log, fatal: false }
    }

    pub(crate) fn fmi(&self) -> Fmi {
        self.binary.fmi()
    }

    pub(crate) fn model(&self) -> &'static Model {
        self.binary.model()
    }

    /// The C name of `op` in this version.
    pub(crate) fn name(&self, op: Op) -> &'static str {
        self.binary.table().name(op, self.interface)
    }

    /// The value of `outcome` (of `op`, made in `state`) if it succeeded, else the failure
    /// that names the call.
    pub(crate) fn expect<T>(&self, outcome: Outcome<T>, op: Op, state: State) -> Result<T, Failure> {
        if outcome.code.ok() {
            Ok(outcome.value)
        } else {
            Err(Failure::refused(self.name(op), state, &outcome, ""))
        }
    }

    /// What the FMU logged since the last take.
    pub(crate) fn take_log(&self) -> Option<String> {
        self.log.take()
    }

    /// After Fatal the standard allows no call at all, not even FreeInstance.
    pub(crate) fn is_fatal(&self) -> bool {
        self.fatal
    }

    /// Makes one call of `op`: records it (function, state, variable, value), runs `body`
    /// with the handle (NULL in NULL-instance mode), takes the log, and moves the believed
    /// state on after an Error or Fatal status. `body` gives `None` for a function the binary
    /// does not export, which is then not called.
    pub(crate) fn call<T>(
        &mut self,
        op: Op,
        variable: Option<&str>,
        value: Option<String>,
        body: impl FnOnce(*mut c_void) -> Option<(c_int, T)>,
        missing: T,
    ) -> Outcome<T> {
        let fmi = self.fmi();
        let value = match (self.null_instance, value) {
            (false, value) => value,
            (true, None) => Some(null_instance(fmi)),
            (true, Some(v)) => Some(format!("{}; {v}", null_instance(fmi))),
        };
        let record = CallRecord {
            call: self.name(op).to_owned(),
            state: self.state.name().to_owned(),
            variable: variable.map(|v| shown(v.to_owned())),
            value: value.map(shown),
        };
        let handle = if self.null_instance { std::ptr::null_mut() } else { self.handle };
        let result = self.tracer.traced(&record, || body(handle));
        let log = self.take_log();
        let (code, value) = match result {
            Some((status, value)) => (Code::new(fmi, status), value),
            None => (Code::missing(fmi), missing),
        };
        if self.null_instance {
            return Outcome { code, value, log };
        }
        if code.is_error() && self.state != State::Gone {
            self.state = fmi.state_after_error();
        }
        if code.is_fatal() {
            self.fatal = true;
            self.state = State::Gone;
        }
        Outcome { code, value, log }
    }

    /// A call that returns only a status.
    pub(crate) fn status(
        &mut self,
        op: Op,
        variable: Option<&str>,
        value: Option<String>,
        body: impl FnOnce(*mut c_void) -> Option<c_int>,
    ) -> Outcome<()> {
        self.call(op, variable, value, |h| body(h).map(|code| (code, ())), ())
    }

    /// FreeInstance through `free` (the version's function, `None` when not exported),
    /// once; the instance is gone afterwards.
    pub(crate) fn free(&mut self, free: Option<unsafe extern "C" fn(*mut c_void)>) {
        if self.state == State::Gone {
            return;
        }
        self.null_instance = false;
        let ok = Code::ok_of(self.fmi()).status;
        let _ = self.status(Op::FreeInstance, None, None, |h| {
            // SAFETY: the live instance, freed once.
            free.map(|f| unsafe { f(h) }).map(|()| ok)
        });
        self.state = State::Gone;
    }
}

/// The functions a binary must export for the interfaces it declares: each with the rule
/// that requires it (the end of the message that reports it missing), and the message that
/// reports them all there.
pub(crate) struct Exports {
    pub required: Vec<(&'static str, String)>,
    pub passed: String,
}

/// `(instance) -> status`: the calls on the instance alone.
pub(crate) type Plain = unsafe extern "C" fn(*mut c_void) -> c_int;
/// `(instance, double*, size_t) -> status`: the Model Exchange vector getters.
pub(crate) type GetVector = unsafe extern "C" fn(*mut c_void, *mut f64, usize) -> c_int;
/// `(instance, const double*, size_t) -> status`: SetContinuousStates.
pub(crate) type SetVector = unsafe extern "C" fn(*mut c_void, *const f64, usize) -> c_int;
/// `(instance, FMUstate*) -> status`: GetFMUState and FreeFMUState.
pub(crate) type StatePointer = unsafe extern "C" fn(*mut c_void, *mut FmuState) -> c_int;

/// The calls whose C signatures both versions share (the types of `fmi_c::fmi2` and
/// `fmi_c::fmi3` are the same function pointers there), made once for both.
impl Core {
    /// A call on the instance alone.
    pub(crate) fn plain(&mut self, op: Op, f: Option<Plain>) -> Outcome<()> {
        // SAFETY: these functions take the instance only.
        self.status(op, None, None, |h| f.map(|f| unsafe { f(h) }))
    }

    /// GetFMUState into a new state.
    pub(crate) fn get_fmu_state(&mut self, f: Option<StatePointer>) -> Outcome<FmuState> {
        self.call(
            Op::GetFmuState,
            None,
            None,
            |h| {
                let mut state: FmuState = std::ptr::null_mut();
                // SAFETY: a valid out pointer, to NULL: a new state.
                f.map(|f| (unsafe { f(h, &mut state) }, state))
            },
            std::ptr::null_mut(),
        )
    }

    /// GetFMUState with a NULL pointer to write the state to.
    pub(crate) fn get_fmu_state_into_null(&mut self, f: Option<StatePointer>) -> Outcome<()> {
        let what = format!("a NULL {} pointer", self.fmi().fmu_state_word());
        // SAFETY: deliberately NULL: the FMU must not write through it.
        self.status(Op::GetFmuState, None, Some(what), |h| f.map(|f| unsafe { f(h, std::ptr::null_mut()) }))
    }

    /// SetFMUState.
    pub(crate) fn set_fmu_state(
        &mut self,
        f: Option<unsafe extern "C" fn(*mut c_void, FmuState) -> c_int>,
        state: FmuState,
    ) -> Outcome<()> {
        // SAFETY: a state this instance's FMU returned.
        self.status(Op::SetFmuState, None, None, |h| f.map(|f| unsafe { f(h, state) }))
    }

    /// FreeFMUState.
    pub(crate) fn free_fmu_state(&mut self, f: Option<StatePointer>, state: &mut FmuState) -> Outcome<()> {
        // SAFETY: a state this instance's FMU returned, and a valid pointer to it.
        self.status(Op::FreeFmuState, None, None, |h| f.map(|f| unsafe { f(h, state) }))
    }

    /// SerializedFMUStateSize.
    pub(crate) fn serialized_fmu_state_size(
        &mut self,
        f: Option<unsafe extern "C" fn(*mut c_void, FmuState, *mut usize) -> c_int>,
        state: FmuState,
    ) -> Outcome<usize> {
        let mut n = 0usize;
        // SAFETY: a valid out pointer.
        self.call(Op::SerializedFmuStateSize, None, None, |h| f.map(|f| (unsafe { f(h, state, &mut n) }, n)), 0)
    }

    /// SetTime.
    pub(crate) fn set_time(&mut self, f: Option<unsafe extern "C" fn(*mut c_void, f64) -> c_int>, t: f64) -> Outcome<()> {
        // SAFETY: a scalar argument.
        self.status(Op::SetTime, None, Some(format!("time {t}")), |h| f.map(|f| unsafe { f(h, t) }))
    }

    /// SetContinuousStates.
    pub(crate) fn set_continuous_states(&mut self, f: Option<SetVector>, x: &[f64]) -> Outcome<()> {
        // SAFETY: an array of x.len() elements.
        self.status(Op::SetContinuousStates, None, Some(numbers(x)), |h| f.map(|f| unsafe { f(h, x.as_ptr(), x.len()) }))
    }

    /// A vector getter `op` (through `f`) into `n` values.
    pub(crate) fn get_vector(&mut self, op: Op, f: Option<GetVector>, n: usize) -> Outcome<Vec<f64>> {
        let mut out = vec![0.0f64; n];
        // SAFETY: an array of n elements (a dangling but aligned pointer for none).
        let got = self.call(op, None, Some(format!("{n} values")), |h| f.map(|f| (unsafe { f(h, out.as_mut_ptr(), n) }, ())), ());
        Outcome { code: got.code, value: if got.code.is_missing() { Vec::new() } else { out }, log: got.log }
    }

    /// A vector getter `op` (through `get`), or SetContinuousStates (through `set`), with a
    /// NULL array of `n` values.
    pub(crate) fn null_vector(&mut self, op: Op, get: Option<GetVector>, set: Option<SetVector>, n: usize) -> Outcome<()> {
        self.status(op, None, Some(format!("a NULL array of {n} values")), |h| {
            // SAFETY: deliberately a NULL array: the FMU must not touch it.
            unsafe {
                match op {
                    Op::SetContinuousStates => set.map(|f| f(h, std::ptr::null(), n)),
                    _ => get.map(|f| f(h, std::ptr::null_mut(), n)),
                }
            }
        })
    }
}

/// One loaded FMU binary of either version, with its description.
pub(crate) trait Binary: Sync {
    fn fmi(&self) -> Fmi;
    /// The description as the probes see it.
    fn model(&self) -> &'static Model;
    /// The version's state table (and the names of its functions).
    fn table(&self) -> &'static Table;
    /// Where this thread's calls are recorded.
    fn tracer(&self) -> Tracer;
    /// Instantiate for `interface` as `name` with `token`, the calls recorded in progress
    /// slot `slot`; `Err` with what the FMU logged when it returns NULL (or the function is
    /// missing).
    fn instantiate(
        &'static self,
        name: &str,
        interface: Interface,
        token: &str,
        slot: usize,
    ) -> Result<Box<dyn Instance>, (Code, Option<String>)>;
    /// Whether the binary exports the function called `name`.
    fn exports(&self, name: &str) -> bool;
    /// What the version requires a binary offering `interfaces` to export.
    fn required_exports(&self, interfaces: &[Interface]) -> Exports;
    /// A text-returning query without an instance (GetVersion, GetTypesPlatform): `None` when
    /// not exported, `Some(None)` for a NULL.
    fn query(&self, op: Op) -> Option<Option<String>>;
}

/// One live instance: the calls that differ between the versions. Each makes the call with
/// the arguments given, whatever the state (the probes decide what is legal), through
/// [`Core::call`].
pub(crate) trait Instance: Send {
    fn core(&self) -> &Core;
    fn core_mut(&mut self) -> &mut Core;

    /// fmi2SetupExperiment over the grid's times; `None` for FMI 3.0, whose
    /// fmi3EnterInitializationMode takes them.
    fn setup_experiment(&mut self, grid: &Grid) -> Option<Outcome<()>>;
    /// EnterInitializationMode (FMI 3.0 with the grid's times and tolerance).
    fn enter_initialization_mode(&mut self, grid: &Grid) -> Outcome<()>;
    /// A call on the instance alone: ExitInitializationMode, Terminate, Reset,
    /// EnterEventMode, EnterContinuousTimeMode, EnterStepMode, CancelStep.
    fn simple(&mut self, op: Op) -> Outcome<()>;
    /// SetDebugLogging for all categories.
    fn set_debug_logging(&mut self, on: bool) -> Outcome<()>;
    /// FreeInstance; the instance is gone afterwards.
    fn free(&mut self);

    /// Get of `vrs` (Real, Integer or Boolean) as f64 (Booleans 0/1); `names` for the record.
    fn get_numbers(&mut self, ty: Type, vrs: &[u32], names: &str) -> Outcome<Vec<f64>>;
    /// GetString of `vrs`, copied at once (the FMU may reuse its buffers).
    fn get_strings(&mut self, vrs: &[u32], names: &str) -> Outcome<Vec<Option<String>>>;
    /// Set of `vrs` (Real, Integer or Boolean) to `values`.
    fn set_numbers(&mut self, ty: Type, vrs: &[u32], values: &[f64], names: &str) -> Outcome<()>;
    /// SetString of `vrs` to `values`.
    fn set_strings(&mut self, vrs: &[u32], values: &[String], names: &str) -> Outcome<()>;
    /// Get or Set of `op`'s type with raw arrays: NULL where asked, else the one value
    /// reference `vr` and a valid buffer of one value; `n` values claimed.
    #[allow(clippy::too_many_arguments)]
    fn raw_access(
        &mut self,
        op: Op,
        null_vrs: bool,
        null_values: bool,
        n: usize,
        vr: u32,
        variable: Option<&str>,
        value: Option<String>,
    ) -> Outcome<()>;
    /// SetString of the one variable `vr` to the caller's buffer `text` (which may be NULL).
    fn set_string_pointer(&mut self, vr: u32, text: *const c_char, variable: &str, value: String) -> Outcome<()>;
    /// GetString of the one variable `vr`: the pointer the FMU gave and its text.
    fn get_string_pointer(&mut self, vr: u32, variable: &str) -> Outcome<(*const c_char, Option<String>)>;

    /// GetFMUState into a new state.
    fn get_fmu_state(&mut self) -> Outcome<FmuState>;
    /// GetFMUState with a NULL pointer to write the state to.
    fn get_fmu_state_into_null(&mut self) -> Outcome<()>;
    fn set_fmu_state(&mut self, state: FmuState) -> Outcome<()>;
    /// FreeFMUState, which the standard has set `*state` to NULL.
    fn free_fmu_state(&mut self, state: &mut FmuState) -> Outcome<()>;
    fn serialized_fmu_state_size(&mut self, state: FmuState) -> Outcome<usize>;
    /// SerializeFMUState into `bytes` (of the size the FMU asked for).
    fn serialize_fmu_state(&mut self, state: FmuState, bytes: &mut [u8]) -> Outcome<()>;
    /// DeserializeFMUState of `bytes` into a new state.
    fn deserialize_fmu_state(&mut self, bytes: &[u8]) -> Outcome<FmuState>;

    /// DoStep from `t` over `h`.
    fn do_step(&mut self, t: f64, h: f64) -> Outcome<StepResult>;
    /// After a step returned Discard: whether the model ended the run
    /// (fmi2GetBooleanStatus(fmi2Terminated); FMI 3.0 says so in fmi3DoStep's arguments, so
    /// its answer is the missing function's).
    fn terminated(&mut self) -> Outcome<bool>;

    fn set_time(&mut self, t: f64) -> Outcome<()>;
    fn set_continuous_states(&mut self, x: &[f64]) -> Outcome<()>;
    /// GetDerivatives, GetEventIndicators, GetContinuousStates or
    /// GetNominalsOfContinuousStates into `n` values.
    fn get_vector(&mut self, op: Op, n: usize) -> Outcome<Vec<f64>>;
    /// A vector call (a getter or SetContinuousStates) with a NULL array of `n` values.
    fn null_vector(&mut self, op: Op, n: usize) -> Outcome<()>;
    fn update_discrete_states(&mut self) -> Outcome<EventUpdate>;
    /// CompletedIntegratorStep: (enterEventMode, terminateSimulation).
    fn completed_integrator_step(&mut self) -> Outcome<(bool, bool)>;
    /// GetNumberOfContinuousStates or GetNumberOfEventIndicators (FMI 3.0): the number, or
    /// with `null` a NULL pointer to write it to.
    fn number_of(&mut self, op: Op, null: bool) -> Outcome<usize>;

    /// The version's other calls, with valid arguments (no variables for the derivative
    /// functions, the status queries with a status kind of their type).
    fn other(&mut self, op: Op) -> Outcome<()>;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_keeps_the_last_messages_until_taken() {
        let log = Log::default();
        assert_eq!(log.take(), None);
        for i in 0..25 {
            log.receive(&format!("[x] fmi2OK (logAll): message {i}"), &format!("message {i}"));
        }
        assert_eq!(log.take().as_deref(), Some("message 22 | message 23 | message 24"));
        assert_eq!(log.take(), None, "taken once");
        log.receive("line", "a\u{7}b");
        assert_eq!(log.take().as_deref(), Some("a\\u{7}b"), "made printable");
    }
}
