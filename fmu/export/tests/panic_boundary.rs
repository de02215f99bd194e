//! A panic in model code must not cross the C boundary: it becomes fmi2Error with a logged
//! message, the instance moves to the Error state, and the importer can still read and free it.

use std::ffi::{c_char, c_int, c_void, CStr};
use std::sync::Mutex;

use fmu_export::fmi2::ffi::{self, CallbackFunctions, LoggerFn};
use fmu_export::{Model, ModelError, ModelInfo, Variable, Variables};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
struct Exploding {
    fuse: f64,
}

// Written by hand (no derive): a table is any `Variables` implementation.
impl Variables for Exploding {
    fn variables() -> Vec<Variable<Self>> {
        vec![Variable::<Exploding>::parameter("fuse", "time of the panic", |m| m.fuse, |m, v| m.fuse = v), Variable::state("x", "x", 0)]
    }
}

impl fmu_export::Equations<f64> for Exploding {
    fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
        x[0] = 1.0;
        Ok(())
    }

    fn derivatives(&self, t: f64, x: &[f64], dx: &mut [f64]) {
        if t > self.fuse {
            panic!("model bug at t = {t}");
        }
        dx[0] = -x[0];
    }
}

impl Model for Exploding {
    const N_STATES: usize = 1;
    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "exploding",
            description: "panics once t passes fuse",
            stop_time: 1.0,
            tolerance: 1e-6,
            output_interval: 0.1,
            documentation: "",
        }
    }
}

// The C functions as a model crate exports them: the tests call them as an importer would.
fmu_export::export_fmu!(Exploding);

static MESSAGES: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// Reads only the fixed arguments: our FMUs pass preformatted messages (with `%` escaped).
extern "C" fn record(_env: *mut c_void, _name: *const c_char, status: c_int, _cat: *const c_char, msg: *const c_char) {
    let msg = unsafe { CStr::from_ptr(msg) }.to_string_lossy().into_owned();
    MESSAGES.lock().unwrap().push(format!("{status}: {msg}"));
}

#[test]
fn a_panic_becomes_fmi2_error_with_a_message() {
    // SAFETY: on x86-64 System V a variadic call with only the fixed arguments matches this
    // non-variadic callee; the test runs only there.
    let logger: LoggerFn = unsafe { std::mem::transmute(record as extern "C" fn(_, _, _, _, _)) };
    let callbacks = CallbackFunctions {
        logger: Some(logger),
        allocate_memory: None,
        free_memory: None,
        step_finished: None,
        component_environment: std::ptr::null_mut(),
    };
    let guid = std::ffi::CString::new(fmu_export::table::guid::<Exploding>()).unwrap();
    unsafe {
        let c = fmi2_exports::fmi2Instantiate(c"boom".as_ptr(), ffi::FMI2_COSIMULATION, guid.as_ptr(), std::ptr::null(), &callbacks, 0, 0);
        assert!(!c.is_null());
        let vr = [0u32];
        assert_eq!(fmi2_exports::fmi2SetReal(c, vr.as_ptr(), 1, [0.25].as_ptr()), 0);
        // Steps of at most 0.05 s: the adaptive solver steps across communication points, and
        // the first step, to 0.1, must not reach the fuse at 0.25.
        let max_step = [fmu_export::table::Table::<Exploding>::new().value_reference("max_step").unwrap()];
        assert_eq!(fmi2_exports::fmi2SetReal(c, max_step.as_ptr(), 1, [0.05].as_ptr()), 0);
        assert_eq!(fmi2_exports::fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), 0);
        assert_eq!(fmi2_exports::fmi2EnterInitializationMode(c), 0);
        assert_eq!(fmi2_exports::fmi2ExitInitializationMode(c), 0);
        assert_eq!(fmi2_exports::fmi2DoStep(c, 0.0, 0.1, 1), 0);
        // The step across t = 0.25 panics inside derivatives.
        assert_eq!(fmi2_exports::fmi2DoStep(c, 0.1, 0.5, 1), 3);
        let logged = MESSAGES.lock().unwrap().join("\n");
        assert!(logged.contains("fmi2DoStep") && logged.contains("model bug"), "{logged}");
        // Error state: no more steps, but values can be read and the instance freed or reset.
        assert_eq!(fmi2_exports::fmi2DoStep(c, 0.1, 0.1, 1), 3);
        let mut x = [f64::NAN];
        let state_vr = [1u32];
        assert_eq!(fmi2_exports::fmi2GetReal(c, state_vr.as_ptr(), 1, x.as_mut_ptr()), 0);
        assert!(x[0].is_finite());
        assert_eq!(fmi2_exports::fmi2Reset(c), 0);
        fmi2_exports::fmi2FreeInstance(c);
        // NULL components are refused, not dereferenced.
        assert_eq!(fmi2_exports::fmi2DoStep(std::ptr::null_mut(), 0.0, 0.1, 1), 3);
    }
}

/// The same through Model Exchange's hot path: fmi2GetDerivatives answers fmi2OK for t before
/// the fuse, fmi2Error with the panic's message after it (the instance in the Error state, where
/// fmi2SetTime is refused by the state machine and the states can still be read).
#[test]
fn a_panic_in_model_exchange_derivatives_becomes_fmi2_error() {
    // SAFETY: as in the test above.
    let logger: LoggerFn = unsafe { std::mem::transmute(record as extern "C" fn(_, _, _, _, _)) };
    let callbacks = CallbackFunctions {
        logger: Some(logger),
        allocate_memory: None,
        free_memory: None,
        step_finished: None,
        component_environment: std::ptr::null_mut(),
    };
    let guid = std::ffi::CString::new(fmu_export::table::guid::<Exploding>()).unwrap();
    unsafe {
        let c = fmi2_exports::fmi2Instantiate(c"me".as_ptr(), 0, guid.as_ptr(), std::ptr::null(), &callbacks, 0, 0);
        assert!(!c.is_null());
        assert_eq!(fmi2_exports::fmi2SetReal(c, [0u32].as_ptr(), 1, [0.25].as_ptr()), 0);
        assert_eq!(fmi2_exports::fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), 0);
        assert_eq!(fmi2_exports::fmi2EnterInitializationMode(c), 0);
        assert_eq!(fmi2_exports::fmi2ExitInitializationMode(c), 0);
        let mut info = ffi::EventInfo::default();
        assert_eq!(fmi2_exports::fmi2NewDiscreteStates(c, &mut info), 0);
        assert_eq!(fmi2_exports::fmi2EnterContinuousTimeMode(c), 0);
        let mut dx = [f64::NAN];
        assert_eq!(fmi2_exports::fmi2SetTime(c, 0.1), 0);
        assert_eq!(fmi2_exports::fmi2SetContinuousStates(c, [2.0].as_ptr(), 1), 0);
        assert_eq!(fmi2_exports::fmi2GetDerivatives(c, dx.as_mut_ptr(), 1), 0);
        assert_eq!(dx[0], -2.0);
        // A NaN state is refused (fmi2Discard), the wrong length too (fmi2Error).
        assert_eq!(fmi2_exports::fmi2SetContinuousStates(c, [f64::NAN].as_ptr(), 1), 2);
        assert_eq!(fmi2_exports::fmi2GetDerivatives(c, dx.as_mut_ptr(), 2), 3);
        assert_eq!(fmi2_exports::fmi2SetTime(c, 0.5), 0);
        assert_eq!(fmi2_exports::fmi2GetDerivatives(c, dx.as_mut_ptr(), 1), 3);
        let logged = MESSAGES.lock().unwrap().join("\n");
        assert!(logged.contains("fmi2GetDerivatives") && logged.contains("model bug at t = 0.5"), "{logged}");
        assert!(logged.contains("nx = 2, but this FMU has 1"), "{logged}");
        assert_eq!(fmi2_exports::fmi2SetTime(c, 0.6), 3, "the Error state allows no fmi2SetTime");
        let mut x = [f64::NAN];
        assert_eq!(fmi2_exports::fmi2GetContinuousStates(c, x.as_mut_ptr(), 1), 0);
        assert_eq!(x[0], 2.0);
        fmi2_exports::fmi2FreeInstance(c);
        assert_eq!(fmi2_exports::fmi2SetTime(std::ptr::null_mut(), 0.0), 3);
        assert_eq!(fmi2_exports::fmi2GetDerivatives(std::ptr::null_mut(), dx.as_mut_ptr(), 1), 3);
    }
}

unsafe extern "C" fn record3(_env: *mut c_void, status: c_int, _cat: *const c_char, msg: *const c_char) {
    let msg = unsafe { CStr::from_ptr(msg) }.to_string_lossy().into_owned();
    MESSAGES.lock().unwrap().push(format!("{status}: {msg}"));
}

/// FMI 3.0's Model Exchange goes through the same hot paths as FMI 2.0's (one front end): the
/// usual fmi3SetTime, fmi3SetContinuousStates and fmi3GetContinuousStateDerivatives answer
/// fmi3OK; a NaN state is fmi3Discard, a wrong length fmi3Error naming FMI 3.0's argument; a
/// panic in the derivatives is fmi3Error with the panic's message, and the Error state
/// refuses fmi3SetTime while the states stay readable.
#[test]
fn a_panic_in_fmi3_model_exchange_derivatives_becomes_fmi3_error() {
    let token = std::ffi::CString::new(fmu_export::table::guid::<Exploding>()).unwrap();
    unsafe {
        let c = fmi3_exports::fmi3InstantiateModelExchange(
            c"me3".as_ptr(),
            token.as_ptr(),
            std::ptr::null(),
            false,
            false,
            std::ptr::null_mut(),
            Some(record3),
        );
        assert!(!c.is_null());
        assert_eq!(fmi3_exports::fmi3SetFloat64(c, [0u32].as_ptr(), 1, [0.25].as_ptr(), 1), 0);
        assert_eq!(fmi3_exports::fmi3EnterInitializationMode(c, false, 0.0, 0.0, false, 0.0), 0);
        assert_eq!(fmi3_exports::fmi3ExitInitializationMode(c), 0);
        let mut flags = [true; 5];
        let mut next = 0.0;
        let [a, b, d, e, f] = &mut flags;
        assert_eq!(fmi3_exports::fmi3UpdateDiscreteStates(c, a, b, d, e, f, &mut next), 0);
        assert_eq!(fmi3_exports::fmi3EnterContinuousTimeMode(c), 0);
        let mut dx = [f64::NAN];
        assert_eq!(fmi3_exports::fmi3SetTime(c, 0.1), 0);
        assert_eq!(fmi3_exports::fmi3SetContinuousStates(c, [2.0].as_ptr(), 1), 0);
        assert_eq!(fmi3_exports::fmi3GetContinuousStateDerivatives(c, dx.as_mut_ptr(), 1), 0);
        assert_eq!(dx[0], -2.0);
        assert_eq!(fmi3_exports::fmi3SetContinuousStates(c, [f64::NAN].as_ptr(), 1), 2);
        assert_eq!(fmi3_exports::fmi3GetContinuousStateDerivatives(c, dx.as_mut_ptr(), 2), 3);
        assert_eq!(fmi3_exports::fmi3SetTime(c, 0.5), 0);
        assert_eq!(fmi3_exports::fmi3GetContinuousStateDerivatives(c, dx.as_mut_ptr(), 1), 3);
        let logged = MESSAGES.lock().unwrap().join("\n");
        assert!(logged.contains("fmi3GetContinuousStateDerivatives") && logged.contains("model bug at t = 0.5"), "{logged}");
        assert!(logged.contains("nContinuousStates = 2, but this FMU has 1"), "{logged}");
        assert_eq!(fmi3_exports::fmi3SetTime(c, 0.6), 3, "the Error state allows no fmi3SetTime");
        let mut x = [f64::NAN];
        assert_eq!(fmi3_exports::fmi3GetContinuousStates(c, x.as_mut_ptr(), 1), 0);
        assert_eq!(x[0], 2.0);
        fmi3_exports::fmi3FreeInstance(c);
        // An FMI 2.0 component is not an FMI 3.0 instance (nor the reverse), and NULL is refused.
        let callbacks = CallbackFunctions {
            logger: None,
            allocate_memory: None,
            free_memory: None,
            step_finished: None,
            component_environment: std::ptr::null_mut(),
        };
        let c2 = fmi2_exports::fmi2Instantiate(c"me2".as_ptr(), 0, token.as_ptr(), std::ptr::null(), &callbacks, 0, 0);
        assert!(!c2.is_null());
        assert_eq!(fmi3_exports::fmi3GetContinuousStates(c2, x.as_mut_ptr(), 1), 3);
        let c3 = fmi3_exports::fmi3InstantiateModelExchange(
            c"me3".as_ptr(),
            token.as_ptr(),
            std::ptr::null(),
            false,
            false,
            std::ptr::null_mut(),
            None,
        );
        assert_eq!(fmi2_exports::fmi2GetContinuousStates(c3, x.as_mut_ptr(), 1), 3);
        fmi2_exports::fmi2FreeInstance(c2);
        fmi3_exports::fmi3FreeInstance(c3);
        assert_eq!(fmi3_exports::fmi3SetTime(std::ptr::null_mut(), 0.0), 3);
    }
}
