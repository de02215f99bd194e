//! The call-sequence driver: turns bytes into a sequence of FMI calls on our FMUs and checks
//! every answer.
//!
//! A sequence holds up to four instances at once, each of any model, FMI 2.0 or 3.0, Model
//! Exchange or Co-Simulation, and a pool of FMU states and serialized states that any instance
//! may be handed (a state from another model, another version, or bytes mutated). Each step is
//! either one FMI call with arguments drawn from the bytes (every state of the state machine is
//! reached because nothing stops a call from coming at the wrong time; NULL pointers, NaN and
//! infinities, wrong value references, wrong lengths, huge steps), or a short legal run
//! (initialize, step, integrate, event iteration) that takes an instance deeper.
//!
//! What is checked on every call (a failed check panics, which the fuzzer reports with the
//! input):
//! - the status is OK, Warning, Discard or Error (never Fatal, nor a code outside the enum);
//! - a status other than OK comes with at least one logged message, when the instance has a
//!   logger and that status's category is on (an importer may switch categories off);
//! - FMI 2.0 messages are safe printf formats (every `%` doubled: the logger is variadic);
//! - a call on a NULL instance returns Error.
//!
//! The sanitizers check the rest: no read or write outside the buffers the caller gave (each
//! array is allocated with exactly the length the call is told), no use after free, no leak
//! once the sequence frees what it made, no data race (the threads runner).

use std::cell::{Cell, RefCell};
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::sync::atomic::{AtomicU64, Ordering};

use arbitrary::{Result, Unstructured};

use crate::fmus::{CallbackFunctions, EventInfo, Fmu, States};

/// Sequences run, FMI calls made, instances created (all threads, all sequences).
pub static SEQUENCES: AtomicU64 = AtomicU64::new(0);
/// See [`SEQUENCES`].
pub static CALLS: AtomicU64 = AtomicU64::new(0);
/// See [`SEQUENCES`].
pub static INSTANCES: AtomicU64 = AtomicU64::new(0);

/// The most instances alive at once in one sequence.
const MAX_INSTANCES: usize = 4;
/// The most steps of one sequence.
const MAX_STEPS: usize = 96;

const OK: c_int = 0;
const ERROR: c_int = 3;
const FATAL: c_int = 4;

/// The status categories the FMUs log refusals in, by status code 1..=4.
const STATUS_CATEGORIES: [&str; 4] = ["logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal"];
/// Every category the FMUs declare, and one they do not.
const CATEGORIES: [&str; 7] =
    ["logEvents", "logCalls", "logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal", "logNoSuchCategory"];

/// What `glue::report_panic` logs when it catches a panic of the model or toolkit code.
const PANIC_MARK: &[u8] = b"internal error in the model code";

/// What the logger callbacks record for one instance (their environment pointer).
#[derive(Default)]
pub struct Env {
    messages: Cell<u64>,
    bad_format: RefCell<Option<String>>,
    panicked: RefCell<Option<String>>,
}

impl Env {
    fn take_bad_format(&self) -> Option<String> {
        self.bad_format.borrow_mut().take()
    }

    fn take_panic(&self) -> Option<String> {
        self.panicked.borrow_mut().take()
    }
}

/// The message is a printf format for FMI 2.0's logger: a `%` must be doubled, else an
/// importer that formats it reads arguments that were never passed.
fn printf_safe(message: &[u8]) -> bool {
    let mut i = 0;
    while i < message.len() {
        if message[i] == b'%' {
            if message.get(i + 1) != Some(&b'%') {
                return false;
            }
            i += 2;
        } else {
            i += 1;
        }
    }
    true
}

unsafe fn record(env: *mut c_void, status: c_int, message: *const c_char, fmi2: bool) {
    let env = &*(env as *const Env);
    assert!(!message.is_null(), "the FMU logged a NULL message");
    let text = CStr::from_ptr(message).to_bytes();
    assert!((0..=4).contains(&status), "the FMU logged status {status}, not an fmiStatus");
    if fmi2 && !printf_safe(text) {
        *env.bad_format.borrow_mut() = Some(String::from_utf8_lossy(text).into_owned());
    }
    // The front ends turn a panic of the model code into fmiError with this message: a refusal
    // that comes from a panic (an index out of range, an overflow) is a bug all the same.
    if text.windows(PANIC_MARK.len()).any(|w| w == PANIC_MARK) {
        *env.panicked.borrow_mut() = Some(String::from_utf8_lossy(text).into_owned());
    }
    env.messages.set(env.messages.get() + 1);
}

/// The FMI 2.0 logger (variadic: the message is a format; ours take no arguments).
unsafe extern "C" fn log2(
    env: *mut c_void,
    name: *const c_char,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
    _args: ...
) {
    assert!(!name.is_null() && !category.is_null(), "the FMU logged with a NULL instance name or category");
    record(env, status, message, true);
}

/// The FMI 3.0 logger.
unsafe extern "C" fn log3(env: *mut c_void, status: c_int, category: *const c_char, message: *const c_char) {
    assert!(!category.is_null(), "the FMU logged with a NULL category");
    record(env, status, message, false);
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Version {
    Fmi2,
    Fmi3,
}

/// One live instance.
struct Slot {
    fmu: usize,
    version: Version,
    model_exchange: bool,
    c: *mut c_void,
    env: Box<Env>,
    /// FMI 2.0 keeps a pointer to its callbacks' struct for the instance's lifetime.
    _callbacks: Box<CallbackFunctions>,
    can_log: bool,
    /// Whether each status category (Warning, Discard, Error, Fatal) is on, as the fuzzer
    /// set it with fmiXSetDebugLogging.
    enabled: [bool; 4],
    /// The time the legal runs step from.
    time: f64,
}

/// One FMU state handed out by fmiXGetFMUState or fmiXDeSerializeFMUState.
struct SavedState {
    fmu: usize,
    version: Version,
    ptr: *mut c_void,
}

/// One sequence's world.
pub struct Sequence<'a> {
    fmus: &'a [Fmu],
    slots: Vec<Slot>,
    states: Vec<SavedState>,
    serialized: Vec<Vec<u8>>,
}

fn count_call() {
    CALLS.fetch_add(1, Ordering::Relaxed);
}

/// A float argument: mostly ordinary values, often the ones that break arithmetic.
fn float(u: &mut Unstructured) -> Result<f64> {
    Ok(match u.int_in_range(0..=15u8)? {
        0 => f64::NAN,
        1 => f64::INFINITY,
        2 => f64::NEG_INFINITY,
        3 => f64::MAX,
        4 => -f64::MAX,
        5 => f64::MIN_POSITIVE / 4.0,
        6 => 0.0,
        7 => -0.0,
        8 => 1e300,
        9 => f64::from_bits(u.arbitrary()?),
        10 => 1.0,
        11 => -1.0,
        _ => u.int_in_range(-1000..=1000i32)? as f64 / 64.0,
    })
}

/// A communication step: mostly ordinary, sometimes zero, negative, huge or not a number. A
/// huge one (1e9 s, f64::MAX) on an oscillating model, like an extreme parameter (`float` sets
/// any Real to 1e300 or 5e-309, `fixed_step` and `max_step` included), is the FMU's solver's to
/// refuse: one call takes at most `solvers::MAX_STEPS_PER_CALL` step attempts (issue 37), so
/// none of them is tamed here.
fn step_size(u: &mut Unstructured) -> Result<f64> {
    Ok(match u.int_in_range(0..=9u8)? {
        0 => float(u)?,
        1 => 1e9,
        2 => 0.0,
        3 => -0.01,
        _ => [1e-6, 1e-3, 0.01, 0.1, 0.5, 2.0][u.int_in_range(0..=5usize)?],
    })
}

/// Value references: mostly the model's own, sometimes one past the end or anything.
fn value_references(u: &mut Unstructured, n_variables: u32) -> Result<Vec<u32>> {
    let n = u.int_in_range(0..=5usize)?;
    (0..n)
        .map(|_| {
            Ok(match u.int_in_range(0..=9u8)? {
                0 => u.arbitrary()?,
                1 => n_variables,
                2 => u32::MAX,
                _ => u.int_in_range(0..=n_variables.saturating_sub(1))?,
            })
        })
        .collect()
}

/// The orders of `n` input or output derivatives: mostly 1 or 2, sometimes anything.
fn derivative_orders(u: &mut Unstructured, n: usize) -> Result<Vec<c_int>> {
    (0..n).map(|_| Ok(if u.ratio(1, 4)? { u.arbitrary()? } else { u.int_in_range(1..=2)? })).collect()
}

/// A buffer length: usually `n`, sometimes another (the FMU must refuse, and never reach past
/// the length it is told: the buffer is allocated with exactly that length).
fn length(u: &mut Unstructured, n: usize) -> Result<usize> {
    Ok(if u.ratio(1, 6)? { u.int_in_range(0..=n + 3)? } else { n })
}

/// A pointer to `v`, or NULL now and then.
fn ptr<T>(u: &mut Unstructured, v: &[T]) -> Result<*const T> {
    Ok(if u.ratio(1, 24)? { std::ptr::null() } else { v.as_ptr() })
}

fn ptr_mut<T>(u: &mut Unstructured, v: &mut [T]) -> Result<*mut T> {
    Ok(if u.ratio(1, 24)? { std::ptr::null_mut() } else { v.as_mut_ptr() })
}

/// A text argument: ordinary, empty, with `%` (the logger's format), long, or not UTF-8.
fn text(u: &mut Unstructured) -> Result<CString> {
    let bytes: Vec<u8> = match u.int_in_range(0..=6u8)? {
        0 => Vec::new(),
        1 => b"100% %s %n %d".to_vec(),
        2 => vec![0xff, 0xfe, b'a'],
        3 => vec![b'x'; 5000],
        4 => u.arbitrary::<Vec<u8>>()?,
        _ => b"text".to_vec(),
    };
    Ok(CString::new(bytes.into_iter().filter(|b| *b != 0).collect::<Vec<u8>>()).expect("NULs removed"))
}

impl<'a> Sequence<'a> {
    /// An empty world over `fmus` (from [`crate::fmus::all`]).
    pub fn new(fmus: &'a [Fmu]) -> Self {
        Sequence { fmus, slots: Vec::new(), states: Vec::new(), serialized: Vec::new() }
    }

    /// Runs the sequence the bytes describe, then frees everything it made.
    pub fn run(mut self, u: &mut Unstructured) {
        SEQUENCES.fetch_add(1, Ordering::Relaxed);
        let mut steps = 0;
        while steps < MAX_STEPS && !u.is_empty() {
            if self.step(u).is_err() {
                break;
            }
            steps += 1;
        }
        self.teardown();
    }

    /// The call's status checked against the rules above.
    fn check(&self, slot: Option<usize>, before: u64, name: &str, status: c_int) {
        count_call();
        assert!((0..=4).contains(&status), "{name} returned {status}, not an fmiStatus");
        let Some(i) = slot else {
            assert_eq!(status, ERROR, "{name} on a NULL instance must return fmiError");
            return;
        };
        let s = &self.slots[i];
        let model = self.fmus[s.fmu].name;
        assert_ne!(status, FATAL, "{model} {:?}: {name} returned fmiFatal", s.version);
        if let Some(message) = s.env.take_bad_format() {
            panic!("{model} {:?}: {name} logged a message that is not a safe printf format: {message:?}", s.version);
        }
        if let Some(message) = s.env.take_panic() {
            panic!("{model} {:?}: {name} panicked inside the FMU: {message}", s.version);
        }
        if status != OK && s.can_log && s.enabled[status as usize - 1] {
            assert!(s.env.messages.get() > before, "{model} {:?}: {name} returned status {status} without logging a message", s.version);
        }
    }

    /// Picks an instance (`None`: the call gets a NULL instance, now and then).
    fn pick(&self, u: &mut Unstructured) -> Result<Option<usize>> {
        if self.slots.is_empty() || u.ratio(1, 40)? {
            return Ok(None);
        }
        Ok(Some(u.choose_index(self.slots.len())?))
    }

    fn messages(&self, slot: Option<usize>) -> u64 {
        slot.map_or(0, |i| self.slots[i].env.messages.get())
    }

    fn c(&self, slot: Option<usize>) -> *mut c_void {
        slot.map_or(std::ptr::null_mut(), |i| self.slots[i].c)
    }

    /// The model a call goes to: the instance's, or any for a NULL instance.
    fn fmu(&self, u: &mut Unstructured, slot: Option<usize>) -> Result<&'a Fmu> {
        Ok(match slot {
            Some(i) => &self.fmus[self.slots[i].fmu],
            None => &self.fmus[u.choose_index(self.fmus.len())?],
        })
    }

    fn step(&mut self, u: &mut Unstructured) -> Result<()> {
        if self.slots.is_empty() || (self.slots.len() < MAX_INSTANCES && u.ratio(1, 12)?) {
            return self.instantiate(u);
        }
        let slot = self.pick(u)?;
        let version = slot.map_or(if u.arbitrary()? { Version::Fmi2 } else { Version::Fmi3 }, |i| self.slots[i].version);
        // A quarter of the steps are legal runs, the rest single calls.
        if slot.is_some() && u.ratio(1, 4)? {
            return self.legal_run(u, slot.expect("checked"));
        }
        match version {
            Version::Fmi2 => self.call2(u, slot),
            Version::Fmi3 => self.call3(u, slot),
        }
    }

    fn instantiate(&mut self, u: &mut Unstructured) -> Result<()> {
        let fmu_index = u.choose_index(self.fmus.len())?;
        let fmu = &self.fmus[fmu_index];
        let version = if u.arbitrary()? { Version::Fmi2 } else { Version::Fmi3 };
        let model_exchange: bool = u.arbitrary()?;
        let env = Box::<Env>::default();
        let env_ptr = &*env as *const Env as *mut c_void;
        let name = match u.int_in_range(0..=15u8)? {
            0 => None,
            1 => Some(text(u)?),
            _ => Some(CString::new("instance").expect("no NUL")),
        };
        let guid = match u.int_in_range(0..=15u8)? {
            0 => None,
            1 => Some(CString::new(self.fmus[u.choose_index(self.fmus.len())?].guid).expect("no NUL")),
            2 => Some(text(u)?),
            _ => Some(CString::new(fmu.guid).expect("no NUL")),
        };
        let resources = match u.int_in_range(0..=7u8)? {
            0 => Some(text(u)?),
            1 => Some(
                CString::new(if version == Version::Fmi2 { "file:///nonexistent%20dir/" } else { "/nonexistent dir/" }).expect("no NUL"),
            ),
            _ => None,
        };
        let logging_on: bool = u.arbitrary()?;
        let with_logger = !u.ratio(1, 20)?;
        let as_ptr = |s: &Option<CString>| s.as_ref().map_or(std::ptr::null(), |s| s.as_ptr());
        let callbacks = Box::new(CallbackFunctions {
            logger: with_logger.then_some(log2 as fmu_export::fmi2::ffi::LoggerFn),
            allocate_memory: None,
            free_memory: None,
            step_finished: None,
            component_environment: env_ptr,
        });
        let (mut functions_null, mut fmu_type_legal) = (false, true);
        let c = unsafe {
            match version {
                Version::Fmi2 => {
                    functions_null = u.ratio(1, 40)?;
                    let functions: *const CallbackFunctions = if functions_null { std::ptr::null() } else { &*callbacks };
                    let fmu_type = match u.int_in_range(0..=20u8)? {
                        0 => 2,
                        _ => model_exchange as c_int ^ 1,
                    };
                    fmu_type_legal = fmu_type != 2;
                    (fmu.fmi2.instantiate)(as_ptr(&name), fmu_type, as_ptr(&guid), as_ptr(&resources), functions, 0, logging_on as c_int)
                }
                Version::Fmi3 => {
                    let log = with_logger.then_some(log3 as crate::fmus::LogMessageCallback);
                    if model_exchange {
                        (fmu.fmi3.instantiate_model_exchange)(as_ptr(&name), as_ptr(&guid), as_ptr(&resources), logging_on, env_ptr, log)
                    } else {
                        let (event_mode_used, early_return_allowed) = (u.arbitrary()?, u.arbitrary()?);
                        (fmu.fmi3.instantiate_co_simulation)(
                            as_ptr(&name),
                            as_ptr(&guid),
                            as_ptr(&resources),
                            logging_on,
                            event_mode_used,
                            early_return_allowed,
                            env_ptr,
                            log,
                        )
                    }
                }
            }
        };
        count_call();
        if c.is_null() {
            // A refusal names its reason, when there is a logger to name it through; a legal
            // request is never refused.
            let could_log = with_logger && !functions_null;
            assert!(!could_log || env.messages.get() > 0, "{} {version:?}: instantiation refused without a logged reason", fmu.name);
            let legal = name.as_ref().is_some_and(|n| !n.as_bytes().is_empty() && n.to_str().is_ok())
                && guid.as_ref().is_some_and(|g| g.as_bytes() == fmu.guid.as_bytes())
                && resources.is_none()
                && !functions_null
                && fmu_type_legal;
            assert!(!legal, "{} {version:?}: a legal instantiation was refused", fmu.name);
            return Ok(());
        }
        INSTANCES.fetch_add(1, Ordering::Relaxed);
        self.slots.push(Slot {
            fmu: fmu_index,
            version,
            model_exchange,
            c,
            env,
            _callbacks: callbacks,
            can_log: with_logger,
            enabled: [true; 4],
            time: 0.0,
        });
        Ok(())
    }

    fn free_slot(&mut self, i: usize) {
        let s = self.slots.remove(i);
        let fmu = &self.fmus[s.fmu];
        unsafe {
            match s.version {
                Version::Fmi2 => (fmu.fmi2.free_instance)(s.c),
                Version::Fmi3 => (fmu.fmi3.free_instance)(s.c),
            }
        }
        count_call();
    }

    /// Records the categories a successful fmiXSetDebugLogging switched.
    fn logging_switched(&mut self, slot: Option<usize>, on: bool, names: &[&str]) {
        let Some(i) = slot else { return };
        let enabled = &mut self.slots[i].enabled;
        if names.is_empty() {
            *enabled = [true; 4];
        }
        for name in names {
            if let Some(k) = STATUS_CATEGORIES.iter().position(|c| c == name) {
                enabled[k] = on;
            }
        }
    }

    fn categories(u: &mut Unstructured) -> Result<Vec<&'static str>> {
        let n = u.int_in_range(0..=3usize)?;
        (0..n).map(|_| Ok(*u.choose(&CATEGORIES)?)).collect()
    }

    /// A state from the pool for an instance of `fmu`/`version`: usually its own kind,
    /// sometimes another model's or version's (which must be refused), or NULL.
    fn pick_state(&self, u: &mut Unstructured) -> Result<Option<usize>> {
        if self.states.is_empty() || u.ratio(1, 16)? {
            return Ok(None);
        }
        Ok(Some(u.choose_index(self.states.len())?))
    }

    /// Serialized bytes: one of the pool's (from any model or version), perhaps mutated.
    fn serialized_bytes(&self, u: &mut Unstructured) -> Result<Vec<u8>> {
        let mut bytes = if self.serialized.is_empty() || u.ratio(1, 8)? {
            u.arbitrary::<Vec<u8>>()?
        } else {
            self.serialized[u.choose_index(self.serialized.len())?].clone()
        };
        match u.int_in_range(0..=5u8)? {
            0 if !bytes.is_empty() => {
                let k = u.choose_index(bytes.len())?;
                bytes[k] ^= u.int_in_range(1..=255u8)?;
            }
            1 => {
                let n = u.int_in_range(0..=bytes.len())?;
                bytes.truncate(n);
            }
            2 => bytes.extend_from_slice(&[0u8; 9]),
            _ => {}
        }
        Ok(bytes)
    }

    /// A state after a call that may have made one: pooled when it is new.
    fn keep_state(&mut self, slot: Option<usize>, before: *mut c_void, after: *mut c_void) {
        if after.is_null() || after == before {
            return;
        }
        let s = &self.slots[slot.expect("a state comes from an instance")];
        self.states.push(SavedState { fmu: s.fmu, version: s.version, ptr: after });
    }

    /// One call of an FMU-state function (either version), a state from the pool (this model's,
    /// another model's or version's, or NULL), arguments from the bytes.
    fn state_call(&mut self, u: &mut Unstructured, slot: Option<usize>, f: &States, version: Version) -> Result<()> {
        let model = self.fmu(u, slot)?.name;
        let c = self.c(slot);
        let before = self.messages(slot);
        let [get, set, free, size_name, serialize, deserialize] = f.names;
        unsafe {
            match u.int_in_range(0..=7u8)? {
                0 | 1 => {
                    // A new state, or one of the pool's overwritten (this model's or not).
                    let mut state = match self.pick_state(u)? {
                        Some(k) if u.arbitrary()? => self.states[k].ptr,
                        _ => std::ptr::null_mut(),
                    };
                    let before_state = state;
                    let target: *mut *mut c_void = if u.ratio(1, 24)? { std::ptr::null_mut() } else { &mut state };
                    let status = (f.get)(c, target);
                    self.check(slot, before, get, status);
                    if status == OK {
                        self.keep_state(slot, before_state, state);
                    } else {
                        assert_eq!(state, before_state, "{model}: a refused {get} changed the state pointer");
                    }
                }
                2 | 3 => {
                    let state = self.pick_state(u)?.map_or(std::ptr::null_mut(), |k| self.states[k].ptr);
                    let status = (f.set)(c, state);
                    self.check(slot, before, set, status);
                }
                4 => {
                    let status = match self.pick_state(u)? {
                        Some(k) => {
                            let mut state = self.states[k].ptr;
                            let status = (f.free)(c, &mut state);
                            if status == OK {
                                let own =
                                    slot.is_some_and(|i| self.slots[i].fmu == self.states[k].fmu && self.states[k].version == version);
                                assert!(own, "{model}: {free} freed a state that is not this model's");
                                assert!(state.is_null(), "{model}: {free} did not set the state to NULL");
                                self.states.remove(k);
                            }
                            status
                        }
                        None => {
                            let mut state = std::ptr::null_mut();
                            (f.free)(c, if u.arbitrary()? { &mut state } else { std::ptr::null_mut() })
                        }
                    };
                    self.check(slot, before, free, status);
                }
                5 | 6 => {
                    let state = self.pick_state(u)?.map_or(std::ptr::null_mut(), |k| self.states[k].ptr);
                    let mut size = 0usize;
                    let size_ptr: *mut usize = if u.ratio(1, 24)? { std::ptr::null_mut() } else { &mut size };
                    let status = (f.size)(c, state, size_ptr);
                    self.check(slot, before, size_name, status);
                    if status == OK {
                        let before = self.messages(slot);
                        let n = length(u, size)?;
                        let mut buffer = vec![0u8; n];
                        let status = (f.serialize)(c, state, ptr_mut(u, &mut buffer)?, n);
                        self.check(slot, before, serialize, status);
                        if status == OK && self.serialized.len() < 8 {
                            self.serialized.push(buffer);
                        }
                    }
                }
                _ => {
                    let bytes = self.serialized_bytes(u)?;
                    let mut state = match self.pick_state(u)? {
                        Some(k) if u.arbitrary()? => self.states[k].ptr,
                        _ => std::ptr::null_mut(),
                    };
                    let before_state = state;
                    let status = (f.deserialize)(c, ptr(u, &bytes)?, bytes.len(), &mut state);
                    self.check(slot, before, deserialize, status);
                    if status == OK {
                        self.keep_state(slot, before_state, state);
                    }
                }
            }
        }
        Ok(())
    }

    /// One FMI 2.0 call, any function, arguments from the bytes.
    fn call2(&mut self, u: &mut Unstructured, slot: Option<usize>) -> Result<()> {
        let fmu = self.fmu(u, slot)?;
        let f = &fmu.fmi2;
        let c = self.c(slot);
        let before = self.messages(slot);
        let n_states = fmu.n_states;
        let status: c_int;
        let name: &str;
        unsafe {
            match u.int_in_range(0..=40u8)? {
                0 => {
                    let names = Self::categories(u)?;
                    let cs: Vec<CString> = names.iter().map(|n| CString::new(*n).expect("no NUL")).collect();
                    let ps: Vec<*const c_char> = cs.iter().map(|s| s.as_ptr()).collect();
                    let on: bool = u.arbitrary()?;
                    let n = length(u, ps.len())?.min(ps.len());
                    name = "fmi2SetDebugLogging";
                    status = (f.set_debug_logging)(c, on as c_int, n, ptr(u, &ps)?);
                    if status == OK {
                        self.logging_switched(slot, on, &names[..n]);
                    }
                }
                1 => {
                    name = "fmi2SetupExperiment";
                    status = (f.setup_experiment)(
                        c,
                        u.arbitrary::<bool>()? as c_int,
                        float(u)?,
                        float(u)?,
                        u.arbitrary::<bool>()? as c_int,
                        float(u)?,
                    );
                }
                2 => (name, status) = ("fmi2EnterInitializationMode", (f.enter_initialization_mode)(c)),
                3 => (name, status) = ("fmi2ExitInitializationMode", (f.exit_initialization_mode)(c)),
                4 => (name, status) = ("fmi2Terminate", (f.terminate)(c)),
                5 => (name, status) = ("fmi2Reset", (f.reset)(c)),
                6 | 7 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let mut v = vec![0.0f64; vrs.len()];
                    name = "fmi2GetReal";
                    status = (f.get_real)(c, ptr(u, &vrs)?, vrs.len(), ptr_mut(u, &mut v)?);
                }
                8 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let mut v = vec![0 as c_int; vrs.len()];
                    name = "fmi2GetInteger";
                    status = (f.get_integer)(c, ptr(u, &vrs)?, vrs.len(), ptr_mut(u, &mut v)?);
                }
                9 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let mut v = vec![0 as c_int; vrs.len()];
                    name = "fmi2GetBoolean";
                    status = (f.get_boolean)(c, ptr(u, &vrs)?, vrs.len(), ptr_mut(u, &mut v)?);
                }
                10 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let mut v = vec![std::ptr::null::<c_char>(); vrs.len()];
                    name = "fmi2GetString";
                    status = (f.get_string)(c, ptr(u, &vrs)?, vrs.len(), ptr_mut(u, &mut v)?);
                    if status == OK {
                        for p in &v {
                            assert!(!p.is_null(), "{}: fmi2GetString returned OK with a NULL string", fmu.name);
                            let _ = CStr::from_ptr(*p).to_bytes().len();
                        }
                    }
                }
                11..=13 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let v: Vec<f64> = (0..vrs.len()).map(|_| float(u)).collect::<Result<_>>()?;
                    name = "fmi2SetReal";
                    status = (f.set_real)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &v)?);
                }
                14 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let v: Vec<c_int> = (0..vrs.len()).map(|_| u.arbitrary()).collect::<Result<_>>()?;
                    name = "fmi2SetInteger";
                    status = (f.set_integer)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &v)?);
                }
                15 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let v: Vec<c_int> = (0..vrs.len()).map(|_| u.arbitrary()).collect::<Result<_>>()?;
                    name = "fmi2SetBoolean";
                    status = (f.set_boolean)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &v)?);
                }
                16 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let texts: Vec<CString> = (0..vrs.len()).map(|_| text(u)).collect::<Result<_>>()?;
                    let mut ps: Vec<*const c_char> = texts.iter().map(|t| t.as_ptr()).collect();
                    if !ps.is_empty() && u.ratio(1, 8)? {
                        let k = u.choose_index(ps.len())?;
                        ps[k] = std::ptr::null();
                    }
                    name = "fmi2SetString";
                    status = (f.set_string)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &ps)?);
                }
                17..=24 => return self.state_call(u, slot, &f.states, Version::Fmi2),
                25 => {
                    // FMI 2.0 has no lengths for the seed and the sensitivity: one value per
                    // known and one per unknown, allocated with exactly those lengths.
                    let unknowns = value_references(u, fmu.n_variables)?;
                    let knowns = value_references(u, fmu.n_variables)?;
                    let seed: Vec<f64> = (0..knowns.len()).map(|_| float(u)).collect::<Result<_>>()?;
                    let mut sensitivity = vec![0.0f64; unknowns.len()];
                    name = "fmi2GetDirectionalDerivative";
                    status = (f.get_directional_derivative)(
                        c,
                        ptr(u, &unknowns)?,
                        unknowns.len(),
                        ptr(u, &knowns)?,
                        knowns.len(),
                        ptr(u, &seed)?,
                        ptr_mut(u, &mut sensitivity)?,
                    );
                }
                26 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let orders = derivative_orders(u, vrs.len())?;
                    let v: Vec<f64> = (0..vrs.len()).map(|_| float(u)).collect::<Result<_>>()?;
                    name = "fmi2SetRealInputDerivatives";
                    status = (f.set_real_input_derivatives)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &orders)?, ptr(u, &v)?);
                }
                27 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let orders = derivative_orders(u, vrs.len())?;
                    let mut v = vec![0.0f64; vrs.len()];
                    name = "fmi2GetRealOutputDerivatives";
                    status = (f.get_real_output_derivatives)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &orders)?, ptr_mut(u, &mut v)?);
                }
                28 | 29 => {
                    let t = if u.arbitrary()? { slot.map_or(0.0, |i| self.slots[i].time) } else { float(u)? };
                    let h = step_size(u)?;
                    name = "fmi2DoStep";
                    status = (f.do_step)(c, t, h, u.arbitrary::<bool>()? as c_int);
                    if status == OK {
                        if let Some(i) = slot {
                            self.slots[i].time = t + h;
                        }
                    }
                }
                30 => (name, status) = ("fmi2CancelStep", (f.cancel_step)(c)),
                31 => {
                    let kind = u.int_in_range(-1..=4)?;
                    let mut v: c_int = 0;
                    let (mut r, mut s) = (0.0f64, std::ptr::null::<c_char>());
                    match u.int_in_range(0..=4u8)? {
                        0 => {
                            (name, status) =
                                ("fmi2GetStatus", (f.get_status)(c, kind, if u.ratio(1, 8)? { std::ptr::null_mut() } else { &mut v }))
                        }
                        1 => {
                            (name, status) = (
                                "fmi2GetRealStatus",
                                (f.get_real_status)(c, kind, if u.ratio(1, 8)? { std::ptr::null_mut() } else { &mut r }),
                            )
                        }
                        2 => (name, status) = ("fmi2GetIntegerStatus", (f.get_integer_status)(c, kind, &mut v)),
                        3 => {
                            (name, status) = (
                                "fmi2GetBooleanStatus",
                                (f.get_boolean_status)(c, kind, if u.ratio(1, 8)? { std::ptr::null_mut() } else { &mut v }),
                            )
                        }
                        _ => (name, status) = ("fmi2GetStringStatus", (f.get_string_status)(c, kind, &mut s)),
                    }
                }
                32 => (name, status) = ("fmi2EnterEventMode", (f.enter_event_mode)(c)),
                33 => {
                    let mut info = EventInfo::default();
                    name = "fmi2NewDiscreteStates";
                    status = (f.new_discrete_states)(c, if u.ratio(1, 16)? { std::ptr::null_mut() } else { &mut info });
                }
                34 => (name, status) = ("fmi2EnterContinuousTimeMode", (f.enter_continuous_time_mode)(c)),
                35 => {
                    let (mut a, mut b) = (0 as c_int, 0 as c_int);
                    name = "fmi2CompletedIntegratorStep";
                    status = (f.completed_integrator_step)(c, 1, if u.ratio(1, 16)? { std::ptr::null_mut() } else { &mut a }, &mut b);
                }
                36 => (name, status) = ("fmi2SetTime", (f.set_time)(c, float(u)?)),
                37 => {
                    let n = length(u, n_states)?;
                    let x: Vec<f64> = (0..n).map(|_| float(u)).collect::<Result<_>>()?;
                    name = "fmi2SetContinuousStates";
                    status = (f.set_continuous_states)(c, ptr(u, &x)?, n);
                }
                38 => {
                    let n = length(u, n_states)?;
                    let mut dx = vec![0.0; n];
                    name = "fmi2GetDerivatives";
                    status = (f.get_derivatives)(c, ptr_mut(u, &mut dx)?, n);
                }
                39 => {
                    let n = u.int_in_range(0..=4usize)?;
                    let mut z = vec![0.0; n];
                    name = "fmi2GetEventIndicators";
                    status = (f.get_event_indicators)(c, ptr_mut(u, &mut z)?, n);
                }
                _ => {
                    let n = length(u, n_states)?;
                    let mut x = vec![0.0; n];
                    if u.arbitrary()? {
                        name = "fmi2GetContinuousStates";
                        status = (f.get_continuous_states)(c, ptr_mut(u, &mut x)?, n);
                    } else {
                        name = "fmi2GetNominalsOfContinuousStates";
                        status = (f.get_nominals_of_continuous_states)(c, ptr_mut(u, &mut x)?, n);
                    }
                }
            }
        }
        self.check(slot, before, name, status);
        Ok(())
    }

    /// One FMI 3.0 call, any function, arguments from the bytes.
    fn call3(&mut self, u: &mut Unstructured, slot: Option<usize>) -> Result<()> {
        let fmu = self.fmu(u, slot)?;
        let f = &fmu.fmi3;
        let c = self.c(slot);
        let before = self.messages(slot);
        let n_states = fmu.n_states;
        let status: c_int;
        let name: &str;
        unsafe {
            match u.int_in_range(0..=45u8)? {
                0 => {
                    let names = Self::categories(u)?;
                    let cs: Vec<CString> = names.iter().map(|n| CString::new(*n).expect("no NUL")).collect();
                    let ps: Vec<*const c_char> = cs.iter().map(|s| s.as_ptr()).collect();
                    let on: bool = u.arbitrary()?;
                    let n = length(u, ps.len())?.min(ps.len());
                    name = "fmi3SetDebugLogging";
                    status = (f.set_debug_logging)(c, on, n, ptr(u, &ps)?);
                    if status == OK {
                        self.logging_switched(slot, on, &names[..n]);
                    }
                }
                1 | 2 => {
                    name = "fmi3EnterInitializationMode";
                    status = (f.enter_initialization_mode)(c, u.arbitrary()?, float(u)?, float(u)?, u.arbitrary()?, float(u)?);
                }
                3 => (name, status) = ("fmi3ExitInitializationMode", (f.exit_initialization_mode)(c)),
                4 => (name, status) = ("fmi3EnterEventMode", (f.enter_event_mode)(c)),
                5 => (name, status) = ("fmi3Terminate", (f.terminate)(c)),
                6 => (name, status) = ("fmi3Reset", (f.reset)(c)),
                7 | 8 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let n = length(u, vrs.len())?;
                    let mut v = vec![0.0f64; n];
                    name = "fmi3GetFloat64";
                    status = (f.get_float64)(c, ptr(u, &vrs)?, vrs.len(), ptr_mut(u, &mut v)?, n);
                }
                9 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let n = length(u, vrs.len())?;
                    let mut v = vec![0i32; n];
                    name = "fmi3GetInt32";
                    status = (f.get_int32)(c, ptr(u, &vrs)?, vrs.len(), ptr_mut(u, &mut v)?, n);
                }
                10 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let n = length(u, vrs.len())?;
                    let mut v = vec![false; n];
                    name = "fmi3GetBoolean";
                    status = (f.get_boolean)(c, ptr(u, &vrs)?, vrs.len(), ptr_mut(u, &mut v)?, n);
                }
                11 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let n = length(u, vrs.len())?;
                    let mut v = vec![std::ptr::null::<c_char>(); n];
                    name = "fmi3GetString";
                    status = (f.get_string)(c, ptr(u, &vrs)?, vrs.len(), ptr_mut(u, &mut v)?, n);
                    if status == OK {
                        for p in &v {
                            assert!(!p.is_null(), "{}: fmi3GetString returned OK with a NULL string", fmu.name);
                            let _ = CStr::from_ptr(*p).to_bytes().len();
                        }
                    }
                }
                12..=14 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let n = length(u, vrs.len())?;
                    let v: Vec<f64> = (0..n).map(|_| float(u)).collect::<Result<_>>()?;
                    name = "fmi3SetFloat64";
                    status = (f.set_float64)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &v)?, n);
                }
                15 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let n = length(u, vrs.len())?;
                    let v: Vec<i32> = (0..n).map(|_| u.arbitrary()).collect::<Result<_>>()?;
                    name = "fmi3SetInt32";
                    status = (f.set_int32)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &v)?, n);
                }
                16 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let n = length(u, vrs.len())?;
                    // Any byte, not only 0 and 1: a C caller's bool may hold anything.
                    let v: Vec<u8> = (0..n).map(|_| u.arbitrary()).collect::<Result<_>>()?;
                    name = "fmi3SetBoolean";
                    status = (f.set_boolean)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &v)?, n);
                }
                17 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let n = length(u, vrs.len())?;
                    let texts: Vec<CString> = (0..n).map(|_| text(u)).collect::<Result<_>>()?;
                    let mut ps: Vec<*const c_char> = texts.iter().map(|t| t.as_ptr()).collect();
                    if !ps.is_empty() && u.ratio(1, 8)? {
                        let k = u.choose_index(ps.len())?;
                        ps[k] = std::ptr::null();
                    }
                    name = "fmi3SetString";
                    status = (f.set_string)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &ps)?, n);
                }
                18..=25 => return self.state_call(u, slot, &f.states, Version::Fmi3),
                26 => {
                    let mut out = [false; 5];
                    let mut next = 0.0;
                    let null_one = u.ratio(1, 16)?;
                    let [a, b, cc, d, e] = &mut out;
                    name = "fmi3UpdateDiscreteStates";
                    status = (f.update_discrete_states)(c, a, b, if null_one { std::ptr::null_mut() } else { cc }, d, e, &mut next);
                }
                27 => (name, status) = ("fmi3EnterContinuousTimeMode", (f.enter_continuous_time_mode)(c)),
                28 => {
                    let (mut a, mut b) = (false, false);
                    name = "fmi3CompletedIntegratorStep";
                    status = (f.completed_integrator_step)(c, true, if u.ratio(1, 16)? { std::ptr::null_mut() } else { &mut a }, &mut b);
                }
                29 => (name, status) = ("fmi3SetTime", (f.set_time)(c, float(u)?)),
                30 => {
                    let n = length(u, n_states)?;
                    let x: Vec<f64> = (0..n).map(|_| float(u)).collect::<Result<_>>()?;
                    name = "fmi3SetContinuousStates";
                    status = (f.set_continuous_states)(c, ptr(u, &x)?, n);
                }
                31 => {
                    let n = length(u, n_states)?;
                    let mut dx = vec![0.0; n];
                    name = "fmi3GetContinuousStateDerivatives";
                    status = (f.get_continuous_state_derivatives)(c, ptr_mut(u, &mut dx)?, n);
                }
                32 => {
                    let n = u.int_in_range(0..=4usize)?;
                    let mut z = vec![0.0; n];
                    name = "fmi3GetEventIndicators";
                    status = (f.get_event_indicators)(c, ptr_mut(u, &mut z)?, n);
                }
                33 => {
                    let n = length(u, n_states)?;
                    let mut x = vec![0.0; n];
                    name = "fmi3GetContinuousStates";
                    status = (f.get_continuous_states)(c, ptr_mut(u, &mut x)?, n);
                }
                34 => {
                    let n = length(u, n_states)?;
                    let mut x = vec![0.0; n];
                    name = "fmi3GetNominalsOfContinuousStates";
                    status = (f.get_nominals_of_continuous_states)(c, ptr_mut(u, &mut x)?, n);
                }
                35 => {
                    let mut n = 0usize;
                    let p: *mut usize = if u.ratio(1, 8)? { std::ptr::null_mut() } else { &mut n };
                    if u.arbitrary()? {
                        name = "fmi3GetNumberOfEventIndicators";
                        status = (f.get_number_of_event_indicators)(c, p);
                    } else {
                        name = "fmi3GetNumberOfContinuousStates";
                        status = (f.get_number_of_continuous_states)(c, p);
                        if status == OK {
                            assert_eq!(n, n_states, "{}: fmi3GetNumberOfContinuousStates", fmu.name);
                        }
                    }
                }
                36 => (name, status) = ("fmi3EnterStepMode", (f.enter_step_mode)(c)),
                37..=39 => {
                    let t = if u.arbitrary()? { slot.map_or(0.0, |i| self.slots[i].time) } else { float(u)? };
                    let h = step_size(u)?;
                    let mut out = [false; 3];
                    let mut last = f64::NAN;
                    let null_one = u.ratio(1, 16)?;
                    let [a, b, cc] = &mut out;
                    name = "fmi3DoStep";
                    status = (f.do_step)(c, t, h, u.arbitrary()?, a, if null_one { std::ptr::null_mut() } else { b }, cc, &mut last);
                    if status == OK {
                        if let Some(i) = slot {
                            self.slots[i].time = last;
                        }
                    }
                }
                40 | 41 => {
                    // The seed has one value per known (directional) or per unknown (adjoint),
                    // the sensitivity one per unknown or per known; each length is sometimes
                    // another, and each buffer has exactly the length it is told.
                    let adjoint = u.arbitrary::<bool>()?;
                    let unknowns = value_references(u, fmu.n_variables)?;
                    let knowns = value_references(u, fmu.n_variables)?;
                    let (seeds, results) = if adjoint { (unknowns.len(), knowns.len()) } else { (knowns.len(), unknowns.len()) };
                    let n_seed = length(u, seeds)?;
                    let n_sensitivity = length(u, results)?;
                    let seed: Vec<f64> = (0..n_seed).map(|_| float(u)).collect::<Result<_>>()?;
                    let mut sensitivity = vec![0.0f64; n_sensitivity];
                    let call = if adjoint { f.get_adjoint_derivative } else { f.get_directional_derivative };
                    name = if adjoint { "fmi3GetAdjointDerivative" } else { "fmi3GetDirectionalDerivative" };
                    status = call(
                        c,
                        ptr(u, &unknowns)?,
                        unknowns.len(),
                        ptr(u, &knowns)?,
                        knowns.len(),
                        ptr(u, &seed)?,
                        n_seed,
                        ptr_mut(u, &mut sensitivity)?,
                        n_sensitivity,
                    );
                }
                42 => {
                    let vrs = value_references(u, fmu.n_variables)?;
                    let orders = derivative_orders(u, vrs.len())?;
                    let n = length(u, vrs.len())?;
                    let mut v = vec![0.0f64; n];
                    name = "fmi3GetOutputDerivatives";
                    status = (f.get_output_derivatives)(c, ptr(u, &vrs)?, vrs.len(), ptr(u, &orders)?, ptr_mut(u, &mut v)?, n);
                }
                _ => {
                    let refused = u.choose(&f.refused)?;
                    name = refused.name;
                    status = (refused.call)(c);
                    assert_ne!(status, OK, "{}: {} cannot succeed on these FMUs", fmu.name, refused.name);
                }
            }
        }
        self.check(slot, before, name, status);
        Ok(())
    }

    /// A short legal run on instance `i`: initialize, step (Co-Simulation) or integrate with
    /// explicit Euler and handle events (Model Exchange), or free it. Every call is checked as
    /// above; a refusal ends the run (the instance may be in any state when it starts).
    fn legal_run(&mut self, u: &mut Unstructured, i: usize) -> Result<()> {
        match u.int_in_range(0..=9u8)? {
            0 => {
                self.free_slot(i);
                Ok(())
            }
            1..=3 => {
                self.initialize(u, i)?;
                Ok(())
            }
            _ if self.slots[i].model_exchange => self.integrate(u, i),
            _ => self.co_simulate(u, i),
        }
    }

    /// Checks one call of a legal run; true when it succeeded.
    fn ran(&self, i: usize, before: u64, name: &str, status: c_int) -> bool {
        self.check(Some(i), before, name, status);
        status == OK
    }

    fn initialize(&mut self, u: &mut Unstructured, i: usize) -> Result<bool> {
        let fmu = &self.fmus[self.slots[i].fmu];
        let c = self.slots[i].c;
        let tolerance: Option<f64> = if u.arbitrary()? { Some([1e-4, 1e-6, 1e-10][u.int_in_range(0..=2usize)?]) } else { None };
        let stop: Option<f64> = if u.arbitrary()? { Some(u.int_in_range(1..=20u8)? as f64) } else { None };
        let ok = unsafe {
            match self.slots[i].version {
                Version::Fmi2 => {
                    let f = &fmu.fmi2;
                    let b = self.messages(Some(i));
                    self.ran(
                        i,
                        b,
                        "fmi2SetupExperiment",
                        (f.setup_experiment)(
                            c,
                            tolerance.is_some() as c_int,
                            tolerance.unwrap_or(0.0),
                            0.0,
                            stop.is_some() as c_int,
                            stop.unwrap_or(0.0),
                        ),
                    ) && {
                        let b = self.messages(Some(i));
                        self.ran(i, b, "fmi2EnterInitializationMode", (f.enter_initialization_mode)(c))
                    } && {
                        let b = self.messages(Some(i));
                        self.ran(i, b, "fmi2ExitInitializationMode", (f.exit_initialization_mode)(c))
                    }
                }
                Version::Fmi3 => {
                    let f = &fmu.fmi3;
                    let b = self.messages(Some(i));
                    self.ran(
                        i,
                        b,
                        "fmi3EnterInitializationMode",
                        (f.enter_initialization_mode)(
                            c,
                            tolerance.is_some(),
                            tolerance.unwrap_or(0.0),
                            0.0,
                            stop.is_some(),
                            stop.unwrap_or(0.0),
                        ),
                    ) && {
                        let b = self.messages(Some(i));
                        self.ran(i, b, "fmi3ExitInitializationMode", (f.exit_initialization_mode)(c))
                    }
                }
            }
        };
        if ok {
            self.slots[i].time = 0.0;
            if self.slots[i].model_exchange {
                self.event_iteration(i);
            }
        }
        Ok(ok)
    }

    /// Up to 20 communication steps of an ordinary size.
    fn co_simulate(&mut self, u: &mut Unstructured, i: usize) -> Result<()> {
        let fmu = &self.fmus[self.slots[i].fmu];
        let c = self.slots[i].c;
        let h = [1e-3, 0.01, 0.1, 0.5][u.int_in_range(0..=3usize)?];
        for _ in 0..u.int_in_range(1..=20u8)? {
            let t = self.slots[i].time;
            let b = self.messages(Some(i));
            unsafe {
                match self.slots[i].version {
                    Version::Fmi2 => {
                        if !self.ran(i, b, "fmi2DoStep", (fmu.fmi2.do_step)(c, t, h, 1)) {
                            return Ok(());
                        }
                        self.slots[i].time = t + h;
                    }
                    Version::Fmi3 => {
                        let (mut event, mut terminate, mut early, mut last) = (false, false, false, 0.0);
                        let status = (fmu.fmi3.do_step)(c, t, h, true, &mut event, &mut terminate, &mut early, &mut last);
                        if !self.ran(i, b, "fmi3DoStep", status) {
                            return Ok(());
                        }
                        self.slots[i].time = last;
                        if event {
                            // Event mode, the discrete update, back to step mode.
                            let b = self.messages(Some(i));
                            if !self.ran(i, b, "fmi3EnterEventMode", (fmu.fmi3.enter_event_mode)(c)) {
                                return Ok(());
                            }
                            self.event_iteration(i);
                            let b = self.messages(Some(i));
                            if !self.ran(i, b, "fmi3EnterStepMode", (fmu.fmi3.enter_step_mode)(c)) {
                                return Ok(());
                            }
                        }
                        if terminate {
                            return Ok(());
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// The discrete update in event mode (up to 5 iterations; Model Exchange then back to
    /// continuous-time mode).
    fn event_iteration(&mut self, i: usize) {
        let fmu = &self.fmus[self.slots[i].fmu];
        let c = self.slots[i].c;
        unsafe {
            for _ in 0..5 {
                let b = self.messages(Some(i));
                let again = match self.slots[i].version {
                    Version::Fmi2 => {
                        let mut info = EventInfo::default();
                        if !self.ran(i, b, "fmi2NewDiscreteStates", (fmu.fmi2.new_discrete_states)(c, &mut info)) {
                            return;
                        }
                        info.new_discrete_states_needed != 0 && info.terminate_simulation == 0
                    }
                    Version::Fmi3 => {
                        let mut out = [false; 5];
                        let mut next = 0.0;
                        let [a, b2, cc, d, e] = &mut out;
                        if !self.ran(i, b, "fmi3UpdateDiscreteStates", (fmu.fmi3.update_discrete_states)(c, a, b2, cc, d, e, &mut next)) {
                            return;
                        }
                        out[0] && !out[1]
                    }
                };
                if !again {
                    break;
                }
            }
            if self.slots[i].model_exchange {
                let b = self.messages(Some(i));
                let status = match self.slots[i].version {
                    Version::Fmi2 => (fmu.fmi2.enter_continuous_time_mode)(c),
                    Version::Fmi3 => (fmu.fmi3.enter_continuous_time_mode)(c),
                };
                self.ran(i, b, "fmiXEnterContinuousTimeMode", status);
            }
        }
    }

    /// Up to 20 explicit Euler steps through the Model Exchange calls, with event handling.
    fn integrate(&mut self, u: &mut Unstructured, i: usize) -> Result<()> {
        let fmu = &self.fmus[self.slots[i].fmu];
        let c = self.slots[i].c;
        let n = fmu.n_states;
        let h = [1e-4, 1e-3, 0.01][u.int_in_range(0..=2usize)?];
        let (mut x, mut dx) = (vec![0.0; n], vec![0.0; n]);
        let mut z = vec![0.0; u.int_in_range(0..=2usize)?];
        for _ in 0..u.int_in_range(1..=20u8)? {
            let t = self.slots[i].time + h;
            let version = self.slots[i].version;
            unsafe {
                macro_rules! call {
                    ($name:literal, $e:expr) => {{
                        let b = self.messages(Some(i));
                        if !self.ran(i, b, $name, $e) {
                            return Ok(());
                        }
                    }};
                }
                let (mut enter, mut terminate) = (false, false);
                match version {
                    Version::Fmi2 => {
                        let f = &fmu.fmi2;
                        call!("fmi2GetContinuousStates", (f.get_continuous_states)(c, x.as_mut_ptr(), n));
                        call!("fmi2GetDerivatives", (f.get_derivatives)(c, dx.as_mut_ptr(), n));
                        for (x, dx) in x.iter_mut().zip(&dx) {
                            *x += h * dx;
                        }
                        call!("fmi2SetTime", (f.set_time)(c, t));
                        call!("fmi2SetContinuousStates", (f.set_continuous_states)(c, x.as_ptr(), n));
                        let b = self.messages(Some(i));
                        // The number of event indicators is the description's; a wrong one
                        // is refused with a message, which is checked all the same.
                        let _ = self.ran(i, b, "fmi2GetEventIndicators", (f.get_event_indicators)(c, z.as_mut_ptr(), z.len()));
                        let (mut e, mut s) = (0, 0);
                        call!("fmi2CompletedIntegratorStep", (f.completed_integrator_step)(c, 1, &mut e, &mut s));
                        (enter, terminate) = (e != 0, s != 0);
                        if enter {
                            call!("fmi2EnterEventMode", (f.enter_event_mode)(c));
                        }
                    }
                    Version::Fmi3 => {
                        let f = &fmu.fmi3;
                        call!("fmi3GetContinuousStates", (f.get_continuous_states)(c, x.as_mut_ptr(), n));
                        call!("fmi3GetContinuousStateDerivatives", (f.get_continuous_state_derivatives)(c, dx.as_mut_ptr(), n));
                        for (x, dx) in x.iter_mut().zip(&dx) {
                            *x += h * dx;
                        }
                        call!("fmi3SetTime", (f.set_time)(c, t));
                        call!("fmi3SetContinuousStates", (f.set_continuous_states)(c, x.as_ptr(), n));
                        let b = self.messages(Some(i));
                        let _ = self.ran(i, b, "fmi3GetEventIndicators", (f.get_event_indicators)(c, z.as_mut_ptr(), z.len()));
                        call!("fmi3CompletedIntegratorStep", (f.completed_integrator_step)(c, true, &mut enter, &mut terminate));
                        if enter {
                            call!("fmi3EnterEventMode", (f.enter_event_mode)(c));
                        }
                    }
                }
                self.slots[i].time = t;
                if enter {
                    self.event_iteration(i);
                }
                if terminate {
                    return Ok(());
                }
            }
        }
        Ok(())
    }

    /// Frees every state (through an instance of its model and version, a fresh one if none
    /// is left), then every instance: what an importer owes the FMU, so that anything left
    /// allocated after this is the FMU's leak.
    fn teardown(&mut self) {
        let states = std::mem::take(&mut self.states);
        for state in states {
            let owner = self.slots.iter().position(|s| s.fmu == state.fmu && s.version == state.version);
            if let Some(i) = owner {
                if self.free_state(i, state.ptr) {
                    continue;
                }
            }
            // The owner refused (its state machine may not allow it now), or none is left.
            let fresh = self.fresh_instance(state.fmu, state.version);
            let freed = self.free_state(fresh, state.ptr);
            assert!(freed, "{} {:?}: a fresh instance refused to free an FMU state", self.fmus[state.fmu].name, state.version);
            self.free_slot(fresh);
        }
        while !self.slots.is_empty() {
            self.free_slot(self.slots.len() - 1);
        }
    }

    fn free_state(&mut self, i: usize, mut state: *mut c_void) -> bool {
        let fmu = &self.fmus[self.slots[i].fmu];
        let c = self.slots[i].c;
        let b = self.messages(Some(i));
        let status = unsafe {
            match self.slots[i].version {
                Version::Fmi2 => (fmu.fmi2.states.free)(c, &mut state),
                Version::Fmi3 => (fmu.fmi3.states.free)(c, &mut state),
            }
        };
        self.check(Some(i), b, "fmiXFreeFMUState", status);
        status == OK && state.is_null()
    }

    /// A new Co-Simulation instance of `fmu` (for the teardown); its index.
    fn fresh_instance(&mut self, fmu_index: usize, version: Version) -> usize {
        let fmu = &self.fmus[fmu_index];
        let env = Box::<Env>::default();
        let env_ptr = &*env as *const Env as *mut c_void;
        let callbacks = Box::new(CallbackFunctions {
            logger: Some(log2),
            allocate_memory: None,
            free_memory: None,
            step_finished: None,
            component_environment: env_ptr,
        });
        let guid = CString::new(fmu.guid).expect("no NUL");
        let c = unsafe {
            match version {
                Version::Fmi2 => (fmu.fmi2.instantiate)(c"teardown".as_ptr(), 1, guid.as_ptr(), std::ptr::null(), &*callbacks, 0, 0),
                Version::Fmi3 => (fmu.fmi3.instantiate_co_simulation)(
                    c"teardown".as_ptr(),
                    guid.as_ptr(),
                    std::ptr::null(),
                    false,
                    false,
                    false,
                    env_ptr,
                    Some(log3),
                ),
            }
        };
        count_call();
        assert!(!c.is_null(), "{} {version:?}: a legal instantiation was refused", fmu.name);
        self.slots.push(Slot {
            fmu: fmu_index,
            version,
            model_exchange: false,
            c,
            env,
            _callbacks: callbacks,
            can_log: true,
            enabled: [true; 4],
            time: 0.0,
        });
        self.slots.len() - 1
    }
}

/// Runs one sequence from `data` (the fuzz target's and the threads runner's entry point).
pub fn run(fmus: &[Fmu], data: &[u8]) {
    let mut u = Unstructured::new(data);
    Sequence::new(fmus).run(&mut u);
}

/// The counters as one line.
pub fn summary() -> String {
    format!(
        "{} sequences, {} FMI calls, {} instances",
        SEQUENCES.load(Ordering::Relaxed),
        CALLS.load(Ordering::Relaxed),
        INSTANCES.load(Ordering::Relaxed)
    )
}
