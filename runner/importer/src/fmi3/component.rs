//! An instantiated FMI 3.0 instance of either interface (fmi3Instantiate.. .. fmi3FreeInstance)
//! and the calls both share: initialization, the discrete update, setting (structural
//! parameters in Configuration Mode) and reading variables of every type, and the checks that
//! turn a status into an error message with the FMU's logged reason.

use std::ffi::{c_int, CStr, CString};

use fmi_c::fmi3 as c;

use super::{Binary, Environment};
use crate::call_log::{self, boolean, list};
use crate::exchange::EventUpdate;
use crate::model::{Causality, Kind, Variable};
use crate::reader::Buffer;
use crate::trace::{self, Call};
use crate::{Reader, Value};

pub(crate) const OK: c_int = c::Status::Ok as c_int;
pub(crate) const WARNING: c_int = c::Status::Warning as c_int;
pub(crate) const ERROR: c_int = c::Status::Error as c_int;
pub(crate) const FATAL: c_int = c::Status::Fatal as c_int;

/// One instance of an FMI 3.0 FMU, of either interface.
pub(crate) struct Component<'a> {
    pub(crate) binary: &'a Binary,
    pub(crate) name: String,
    pub(crate) instance: c::Instance,
    // Must stay at a fixed address while the instance lives: the FMU keeps the pointer.
    pub(crate) env: Box<Environment>,
    /// Setup values, passed on by fmi3EnterInitializationMode.
    experiment: (Option<f64>, f64, f64),
    /// fmi3Terminate is allowed (initialized, and no fmi3Error since).
    terminate_allowed: bool,
    fatal: bool,
    /// Instantiated and not yet initializing: structural parameters are set in Configuration Mode.
    instantiated: bool,
}

impl<'a> Component<'a> {
    /// The instance `instance` (NULL: the instantiation `call` failed, with the FMU's reason).
    pub(crate) fn new(
        binary: &'a Binary,
        name: &str,
        instance: c::Instance,
        env: Box<Environment>,
        call: &str,
    ) -> Result<Component<'a>, String> {
        let component = Component {
            binary,
            name: name.to_owned(),
            instance,
            env,
            experiment: (None, 0.0, 0.0),
            terminate_allowed: false,
            fatal: false,
            instantiated: true,
        };
        if component.instance.is_null() {
            return Err(component.failure(call, "returned NULL"));
        }
        Ok(component)
    }

    fn failure(&self, call: &str, what: &str) -> String {
        match self.env.log.take_reason() {
            Some(message) => format!("{}: {call} {what}: {message}", self.name),
            None => format!("{}: {call} {what} ({})", self.name, crate::logging::NO_REASON),
        }
    }

    #[inline]
    pub(crate) fn check(&mut self, call: &str, status: c_int) -> Result<(), String> {
        match status {
            OK | WARNING => Ok(()),
            _ => Err(self.refused(call, status)),
        }
    }

    /// Records what a status other than OK or Warning means for the calls still allowed.
    #[cold]
    pub(crate) fn note_status(&mut self, status: c_int) {
        if status == FATAL {
            self.fatal = true;
            trace::note_fatal();
        }
        if status == ERROR || status == FATAL {
            self.terminate_allowed = false;
        }
    }

    /// The failure of `call` at model time `t` (a step from it), with the FMU's reason.
    #[cold]
    #[inline(never)]
    pub(crate) fn refused_at(&mut self, call: &str, t: f64, status: c_int) -> String {
        self.refused(&format!("{call} at t = {t}"), status)
    }

    #[cold]
    fn refused(&mut self, call: &str, status: c_int) -> String {
        self.note_status(status);
        self.failure(call, &format!("returned {}", c::status_name(status)))
    }

    /// Keeps tolerance, start and stop time for fmi3EnterInitializationMode.
    pub(crate) fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        self.experiment = (tolerance, start, stop);
        Ok(())
    }

    /// The start time of the experiment.
    pub(crate) fn start_time(&self) -> f64 {
        self.experiment.1
    }

    /// fmi3EnterInitializationMode with the experiment's tolerance, start and stop time.
    pub(crate) fn enter_initialization_mode(&mut self) -> Result<(), String> {
        let (tolerance, start, stop) = self.experiment;
        trace::enter(Call::Fmi3EnterInitializationMode, start);
        let entered = call_log::enter("fmi3EnterInitializationMode", || {
            format!(
                "toleranceDefined={}, tolerance={:?}, startTime={start:?}, stopTimeDefined={}, stopTime={:?}",
                boolean(3, tolerance.is_some()),
                tolerance.unwrap_or(0.0),
                boolean(3, stop.is_finite()),
                if stop.is_finite() { stop } else { 0.0 }
            )
        });
        let status = unsafe {
            // An infinite stop time is none: stepping from outside runs as long as it is asked to.
            (self.binary.api.enter_initialization_mode)(
                self.instance,
                tolerance.is_some(),
                tolerance.unwrap_or(0.0),
                start,
                stop.is_finite(),
                if stop.is_finite() { stop } else { 0.0 },
            )
        };
        call_log::returned(entered, || c::status_name(status));
        self.instantiated = false;
        self.check("fmi3EnterInitializationMode", status)
    }

    /// fmi3ExitInitializationMode.
    pub(crate) fn exit_initialization_mode(&mut self) -> Result<(), String> {
        trace::enter(Call::Fmi3ExitInitializationMode, self.experiment.1);
        let entered = call_log::enter("fmi3ExitInitializationMode", String::new);
        let status = unsafe { (self.binary.api.exit_initialization_mode)(self.instance) };
        call_log::returned(entered, || c::status_name(status));
        self.check("fmi3ExitInitializationMode", status)?;
        self.terminate_allowed = true;
        Ok(())
    }

    /// fmi3Reset: back to the state right after instantiation (set up and initialize again).
    pub(crate) fn reset(&mut self) -> Result<(), String> {
        let Some(reset) = self.binary.api.functions.reset else {
            return Err(format!("{}: the FMU does not export fmi3Reset", self.name));
        };
        trace::enter(Call::Fmi3Reset, f64::NAN);
        // SAFETY: the instance is live.
        let entered = call_log::enter("fmi3Reset", String::new);
        let status = unsafe { reset(self.instance) };
        call_log::returned(entered, || c::status_name(status));
        self.check("fmi3Reset", status)?;
        self.terminate_allowed = false;
        self.instantiated = true;
        Ok(())
    }

    /// The FMU's state, serialized (fmi3GetFMUState, fmi3SerializedFMUStateSize,
    /// fmi3SerializeFMUState; the state freed again).
    pub(crate) fn get_state(&mut self) -> Result<Vec<u8>, String> {
        let f = &self.binary.api.functions;
        let (Some(get), Some(size), Some(serialize), Some(free)) =
            (f.get_fmu_state, f.serialized_fmu_state_size, f.serialize_fmu_state, f.free_fmu_state)
        else {
            return Err(format!("{}: the FMU does not export fmi3GetFMUState and fmi3SerializeFMUState", self.name));
        };
        let mut state: c::FmuState = std::ptr::null_mut();
        trace::enter(Call::Fmi3GetFmuState, f64::NAN);
        // SAFETY: the instance is live; `state` receives the FMU's handle.
        let entered = call_log::enter("fmi3GetFMUState", String::new);
        let status = unsafe { get(self.instance, &mut state) };
        call_log::returned(entered, || c::status_name(status));
        self.check("fmi3GetFMUState", status)?;
        let mut n = 0usize;
        // SAFETY: a state this instance returned, and an out pointer.
        let entered = call_log::enter("fmi3SerializedFMUStateSize", String::new);
        let status = unsafe { size(self.instance, state, &mut n) };
        call_log::returned_with(entered, || c::status_name(status), || format!("size={n}"));
        let bytes = self.check("fmi3SerializedFMUStateSize", status).and_then(|()| {
            if n > crate::state::MAX_STATE_BYTES {
                return Err(format!("{}: fmi3SerializedFMUStateSize gave {n} bytes", self.name));
            }
            let mut bytes = vec![0u8; n];
            // SAFETY: `n` writable bytes, as the FMU asked for.
            let entered = call_log::enter("fmi3SerializeFMUState", || format!("size={n}"));
            let status = unsafe { serialize(self.instance, state, bytes.as_mut_ptr(), n) };
            call_log::returned(entered, || c::status_name(status));
            self.check("fmi3SerializeFMUState", status).map(|()| bytes)
        });
        let entered = call_log::enter("fmi3FreeFMUState", String::new);
        // SAFETY: the state is this instance's, freed once.
        let status = unsafe { free(self.instance, &mut state) };
        call_log::returned(entered, || c::status_name(status));
        bytes
    }

    /// Sets the FMU's state from `bytes` of [`Component::get_state`] (fmi3DeserializeFMUState,
    /// fmi3SetFMUState; the state freed again).
    pub(crate) fn set_state(&mut self, bytes: &[u8]) -> Result<(), String> {
        let f = &self.binary.api.functions;
        let (Some(deserialize), Some(set), Some(free)) = (f.deserialize_fmu_state, f.set_fmu_state, f.free_fmu_state) else {
            return Err(format!("{}: the FMU does not export fmi3DeserializeFMUState and fmi3SetFMUState", self.name));
        };
        let mut state: c::FmuState = std::ptr::null_mut();
        trace::enter(Call::Fmi3SetFmuState, f64::NAN);
        // SAFETY: `bytes.len()` readable bytes; `state` receives the FMU's handle.
        let entered = call_log::enter("fmi3DeserializeFMUState", || format!("size={}", bytes.len()));
        let status = unsafe { deserialize(self.instance, bytes.as_ptr(), bytes.len(), &mut state) };
        call_log::returned(entered, || c::status_name(status));
        self.check("fmi3DeserializeFMUState", status)?;
        // SAFETY: a state this instance made.
        let entered = call_log::enter("fmi3SetFMUState", String::new);
        let status = unsafe { set(self.instance, state) };
        call_log::returned(entered, || c::status_name(status));
        let result = self.check("fmi3SetFMUState", status);
        let entered = call_log::enter("fmi3FreeFMUState", String::new);
        // SAFETY: freed once.
        let status = unsafe { free(self.instance, &mut state) };
        call_log::returned(entered, || c::status_name(status));
        result?;
        self.terminate_allowed = true;
        self.instantiated = false;
        Ok(())
    }

    /// One fmi3UpdateDiscreteStates: its status and what it returned.
    pub(crate) fn update_discrete_states(&self) -> (c_int, EventUpdate) {
        let (mut again, mut terminate, mut nominals, mut values, mut next_defined, mut next) = (false, false, false, false, false, 0.0);
        let entered = call_log::enter("fmi3UpdateDiscreteStates", String::new);
        // SAFETY: valid out pointers.
        let status = unsafe {
            (self.binary.api.update_discrete_states)(
                self.instance,
                &mut again,
                &mut terminate,
                &mut nominals,
                &mut values,
                &mut next_defined,
                &mut next,
            )
        };
        call_log::returned_with(
            entered,
            || c::status_name(status),
            || {
                format!(
                "discreteStatesNeedUpdate={}, terminateSimulation={}, nominalsOfContinuousStatesChanged={}, valuesOfContinuousStatesChanged={}, nextEventTimeDefined={}, nextEventTime={next:?}",
                boolean(3, again),
                boolean(3, terminate),
                boolean(3, nominals),
                boolean(3, values),
                boolean(3, next_defined)
            )
            },
        );
        (status, EventUpdate { again, terminate, next_event_time: next_defined.then_some(next) })
    }

    /// Sets one variable (a scalar, or an array whole); structural parameters are set in
    /// Configuration Mode, which this enters and leaves around the call.
    pub(crate) fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        let configure = self.instantiated && variable.causality == Causality::StructuralParameter;
        if configure {
            trace::enter(Call::Fmi3EnterConfigurationMode, f64::NAN);
            let entered = call_log::enter("fmi3EnterConfigurationMode", String::new);
            let status = unsafe { (self.binary.api.enter_configuration_mode)(self.instance) };
            call_log::returned(entered, || c::status_name(status));
            self.check("fmi3EnterConfigurationMode", status)?;
        }
        // A refused value is the error to report: after it the FMU may refuse leaving too.
        self.set_values(variable, value)?;
        if configure {
            trace::enter(Call::Fmi3ExitConfigurationMode, f64::NAN);
            let entered = call_log::enter("fmi3ExitConfigurationMode", String::new);
            let status = unsafe { (self.binary.api.exit_configuration_mode)(self.instance) };
            call_log::returned(entered, || c::status_name(status));
            self.check("fmi3ExitConfigurationMode", status)?;
        }
        Ok(())
    }

    fn set_values(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        let items: Vec<&Value> = match value {
            Value::List(items) => items.iter().collect(),
            single => vec![single],
        };
        let vr = [variable.value_reference];
        trace::enter(Call::Fmi3Set, f64::NAN);
        let (inst, api, n) = (self.instance, &self.binary.api, items.len());
        let wrong = || format!("{}: {value:?} is not a value of its type {}", variable.name, variable.kind);
        let arguments = |values: String| format!("valueReferences={}, nValueReferences=1, values={values}, nValues={n}", list(&vr));
        macro_rules! set {
            ($f:ident, $conv:expr) => {{
                let values = items.iter().map(|v| $conv(*v)).collect::<Option<Vec<_>>>().ok_or_else(wrong)?;
                let entered = call_log::enter(setter_name(variable.kind), || arguments(list(&values)));
                // SAFETY: one value reference and `n` values of its type.
                let status = unsafe { (api.$f)(inst, vr.as_ptr(), 1, values.as_ptr(), n) };
                call_log::returned(entered, || c::status_name(status));
                status
            }};
        }
        let int = |v: &Value| match v {
            Value::Integer(i) => Some(i128::from(*i)),
            Value::Int(i) => Some(*i),
            _ => None,
        };
        let status = match variable.kind {
            Kind::Real => set!(set_float64, |v: &Value| if let Value::Real(x) = v { Some(*x) } else { None }),
            Kind::Float32 => set!(set_float32, |v: &Value| if let Value::Real(x) = v { Some(*x as f32) } else { None }),
            Kind::Int8 => set!(set_int8, |v| int(v).and_then(|i| i8::try_from(i).ok())),
            Kind::UInt8 => set!(set_uint8, |v| int(v).and_then(|i| u8::try_from(i).ok())),
            Kind::Int16 => set!(set_int16, |v| int(v).and_then(|i| i16::try_from(i).ok())),
            Kind::UInt16 => set!(set_uint16, |v| int(v).and_then(|i| u16::try_from(i).ok())),
            Kind::Integer => set!(set_int32, |v| int(v).and_then(|i| i32::try_from(i).ok())),
            Kind::UInt32 => set!(set_uint32, |v| int(v).and_then(|i| u32::try_from(i).ok())),
            Kind::Int64 | Kind::Enumeration => set!(set_int64, |v| int(v).and_then(|i| i64::try_from(i).ok())),
            Kind::UInt64 => set!(set_uint64, |v| int(v).and_then(|i| u64::try_from(i).ok())),
            Kind::Boolean => set!(set_boolean, |v: &Value| if let Value::Boolean(b) = v { Some(*b) } else { None }),
            Kind::String => {
                let texts = items
                    .iter()
                    .map(|v| match v {
                        Value::String(s) => {
                            CString::new(s.as_str()).map_err(|_| format!("the value of {} contains a NUL byte", variable.name))
                        }
                        _ => Err(wrong()),
                    })
                    .collect::<Result<Vec<CString>, String>>()?;
                let pointers: Vec<*const std::ffi::c_char> = texts.iter().map(|t| t.as_ptr()).collect();
                let entered = call_log::enter("fmi3SetString", || arguments(list(&texts)));
                let status = unsafe { (api.set_string)(inst, vr.as_ptr(), 1, pointers.as_ptr(), n) };
                call_log::returned(entered, || c::status_name(status));
                status
            }
            Kind::Binary => {
                let bytes = items
                    .iter()
                    .map(|v| if let Value::Binary(b) = v { Some(b) } else { None })
                    .collect::<Option<Vec<&Vec<u8>>>>()
                    .ok_or_else(wrong)?;
                let sizes: Vec<usize> = bytes.iter().map(|b| b.len()).collect();
                let pointers: Vec<*const u8> = bytes.iter().map(|b| b.as_ptr()).collect();
                let entered = call_log::enter("fmi3SetBinary", || arguments(format!("(sizes {})", list(&sizes))));
                let status = unsafe { (api.set_binary)(inst, vr.as_ptr(), 1, sizes.as_ptr(), pointers.as_ptr(), n) };
                call_log::returned(entered, || c::status_name(status));
                status
            }
            Kind::Clock => return Err(format!("{} is a Clock: clocks are not supported", variable.name)),
        };
        self.check(&format!("fmi3Set{} of {}", variable.kind, variable.name), status)
    }

    /// Reads a String variable, every element of an array (fmi3GetString with one value
    /// reference): the FMU's texts copied at once, as it may reuse their memory.
    pub(crate) fn get_string(&mut self, variable: &Variable) -> Result<Vec<String>, String> {
        if variable.kind != Kind::String {
            return Err(format!("{} is a {}, not a String", variable.name, variable.kind));
        }
        // Fixed dimensions only: a structural parameter's value is the FMU's to tell.
        let n = variable
            .dimensions
            .iter()
            .map(|d| match d {
                crate::model::Dimension::Fixed(n) => usize::try_from(*n).ok(),
                crate::model::Dimension::Variable(_) => None,
            })
            .product::<Option<usize>>()
            .ok_or_else(|| format!("{}: a String array sized by a structural parameter is not read", variable.name))?;
        let vr = [variable.value_reference];
        let mut values: Vec<c::FmiString> = vec![std::ptr::null(); n];
        trace::enter(Call::Fmi3Get, f64::NAN);
        // SAFETY: one value reference and room for its `n` elements.
        let entered = call_log::enter("fmi3GetString", || format!("valueReferences={}, nValueReferences=1, nValues={n}", list(&vr)));
        let status = unsafe { (self.binary.api.get_string)(self.instance, vr.as_ptr(), 1, values.as_mut_ptr(), n) };
        call_log::returned(entered, || c::status_name(status));
        self.check(&format!("fmi3GetString of {}", variable.name), status)?;
        // SAFETY: non-NULL pointers from the FMU are NUL-terminated strings until its next call.
        values.iter().map(|p| unsafe { crate::text_of(*p, &variable.name, "fmi3GetString") }).collect()
    }

    /// Reads the variables of `reader` into `out` (one f64 per element, Booleans as 0/1).
    /// Always inlined, as FMI 2.0's: a sweep reads at every sample.
    #[inline(always)]
    pub(crate) fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        if reader.direct {
            if let Some(group) = reader.groups.first() {
                trace::enter(Call::Fmi3Get, f64::NAN);
                let (get_float64, instance, vrs, values, n) =
                    (self.binary.api.get_float64, self.instance, &group.vrs, out.as_mut_ptr(), out.len());
                let status = call_log::call(
                    "fmi3GetFloat64",
                    || format!("valueReferences={}, nValueReferences={}, nValues={n}", list(vrs), vrs.len()),
                    || unsafe { get_float64(instance, vrs.as_ptr(), vrs.len(), values, n) },
                    c::status_name,
                    // SAFETY: the `n` values the call just wrote.
                    |_| format!("values={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
                );
                self.check("fmi3GetFloat64", status)?;
            }
            return Ok(());
        }
        self.read_groups(reader)?;
        reader.gather(out);
        Ok(())
    }

    /// Sets Float64 scalars, `values[k]` to `vrs[k]`, in one fmi3SetFloat64 call (a master's
    /// inputs at every step: no allocation).
    #[inline]
    pub(crate) fn set_reals(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        debug_assert_eq!(vrs.len(), values.len());
        let n = vrs.len().min(values.len());
        trace::enter(Call::Fmi3Set, f64::NAN);
        let (set_float64, instance) = (self.binary.api.set_float64, self.instance);
        let status = call_log::call(
            "fmi3SetFloat64",
            || format!("valueReferences={}, nValueReferences={n}, values={}, nValues={n}", list(&vrs[..n]), list(&values[..n])),
            // SAFETY: `n` value references of scalars and `n` values, valid for the call.
            || unsafe { set_float64(instance, vrs.as_ptr(), n, values.as_ptr(), n) },
            c::status_name,
            |_| String::new(),
        );
        self.check("fmi3SetFloat64", status)
    }

    fn read_groups(&mut self, reader: &mut Reader) -> Result<(), String> {
        let inst = self.instance;
        trace::enter(Call::Fmi3Get, f64::NAN);
        for group in &mut reader.groups {
            let (vrs, nvr) = (group.vrs.as_ptr(), group.vrs.len());
            let api = &self.binary.api;
            let group_vrs = &group.vrs;
            let arguments = |n: usize| format!("valueReferences={}, nValueReferences={nvr}, nValues={n}", list(group_vrs));
            macro_rules! get {
                ($f:ident, $name:literal, $b:expr) => {{
                    let entered = call_log::enter($name, || arguments($b.len()));
                    // SAFETY: the buffer holds every element of the group's variables.
                    let status = unsafe { (api.$f)(inst, vrs, nvr, $b.as_mut_ptr(), $b.len()) };
                    call_log::returned_with(entered, || c::status_name(status), || format!("values={}", list($b)));
                    status
                }};
            }
            let status = match &mut group.buffer {
                Buffer::F64(b) => get!(get_float64, "fmi3GetFloat64", b),
                Buffer::F32(b) => get!(get_float32, "fmi3GetFloat32", b),
                Buffer::I8(b) => get!(get_int8, "fmi3GetInt8", b),
                Buffer::U8(b) => get!(get_uint8, "fmi3GetUInt8", b),
                Buffer::I16(b) => get!(get_int16, "fmi3GetInt16", b),
                Buffer::U16(b) => get!(get_uint16, "fmi3GetUInt16", b),
                Buffer::I32(b) => get!(get_int32, "fmi3GetInt32", b),
                Buffer::U32(b) => get!(get_uint32, "fmi3GetUInt32", b),
                Buffer::I64(b) => get!(get_int64, "fmi3GetInt64", b),
                Buffer::U64(b) => get!(get_uint64, "fmi3GetUInt64", b),
                Buffer::Bool(b) => get!(get_boolean, "fmi3GetBoolean", b),
                Buffer::Text(texts) => {
                    let mut pointers = vec![std::ptr::null::<std::ffi::c_char>(); texts.len()];
                    let entered = call_log::enter("fmi3GetString", || arguments(texts.len()));
                    let status = unsafe { (api.get_string)(inst, vrs, nvr, pointers.as_mut_ptr(), pointers.len()) };
                    if status == OK || status == WARNING {
                        for (t, p) in texts.iter_mut().zip(&pointers) {
                            // SAFETY: the FMU returned NUL-terminated strings valid until its next call.
                            *t = if p.is_null() { String::new() } else { unsafe { CStr::from_ptr(*p) }.to_string_lossy().into_owned() };
                        }
                    }
                    call_log::returned_with(entered, || c::status_name(status), || format!("values={}", list(texts)));
                    status
                }
                Buffer::Bytes(bytes) => {
                    let mut sizes = vec![0usize; bytes.len()];
                    let mut pointers = vec![std::ptr::null::<u8>(); bytes.len()];
                    let entered = call_log::enter("fmi3GetBinary", || arguments(bytes.len()));
                    let status = unsafe { (api.get_binary)(inst, vrs, nvr, sizes.as_mut_ptr(), pointers.as_mut_ptr(), pointers.len()) };
                    call_log::returned_with(entered, || c::status_name(status), || format!("valueSizes={}", list(&sizes)));
                    if status == OK || status == WARNING {
                        for ((b, p), n) in bytes.iter_mut().zip(&pointers).zip(&sizes) {
                            // SAFETY: the FMU returned `n` bytes at `p`, valid until its next call.
                            *b = if p.is_null() { Vec::new() } else { unsafe { std::slice::from_raw_parts(*p, *n) }.to_vec() };
                        }
                    }
                    status
                }
                Buffer::IntBool(_) | Buffer::CharBool(_) => {
                    return Err(format!("{}: an FMI 1.0 or 2.0 Boolean buffer in an FMI 3.0 reader", self.name))
                }
            };
            if !(status == OK || status == WARNING) {
                return Err(self.refused(&format!("fmi3Get{}", group.kind), status));
            }
        }
        Ok(())
    }
}

impl Drop for Component<'_> {
    fn drop(&mut self) {
        if self.fatal {
            return;
        }
        // SAFETY: the instance is live; fmi3Terminate only where allowed; fmi3FreeInstance last.
        unsafe {
            if self.terminate_allowed {
                trace::enter(Call::Fmi3Terminate, f64::NAN);
                let entered = call_log::enter("fmi3Terminate", String::new);
                let status = (self.binary.api.terminate)(self.instance);
                call_log::returned(entered, || c::status_name(status));
            }
            trace::enter(Call::Fmi3FreeInstance, f64::NAN);
            let entered = call_log::enter("fmi3FreeInstance", String::new);
            (self.binary.api.free_instance)(self.instance);
            call_log::returned(entered, || "(void)");
        }
    }
}

/// The FMI 3.0 setter of variables of `kind`, by name.
fn setter_name(kind: Kind) -> &'static str {
    match kind {
        Kind::Real => "fmi3SetFloat64",
        Kind::Float32 => "fmi3SetFloat32",
        Kind::Int8 => "fmi3SetInt8",
        Kind::UInt8 => "fmi3SetUInt8",
        Kind::Int16 => "fmi3SetInt16",
        Kind::UInt16 => "fmi3SetUInt16",
        Kind::Integer => "fmi3SetInt32",
        Kind::UInt32 => "fmi3SetUInt32",
        Kind::Int64 | Kind::Enumeration => "fmi3SetInt64",
        Kind::UInt64 => "fmi3SetUInt64",
        Kind::Boolean => "fmi3SetBoolean",
        Kind::String => "fmi3SetString",
        Kind::Binary => "fmi3SetBinary",
        Kind::Clock => "fmi3SetClock",
    }
}
