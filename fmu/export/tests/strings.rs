//! String variables through the whole toolkit: declared with `#[derive(Variables)]`, written
//! into both modelDescription.xml versions, and served by the C functions of FMI 2.0 and 3.0
//! (NULL and non-UTF-8 arguments refused with a message, the returned pointers kept alive,
//! the fixed/tunable rules, and FMU states that carry the text).

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::sync::Mutex;

use fmu_export::fmi2::ffi::{self, CallbackFunctions, LoggerFn};
use fmu_export::model::{Causality, Initial, Variability};
use fmu_export::table::{Start, Table};
use fmu_export::{Model, ModelError, ModelInfo, StateVector, Variables};
use serde::{Deserialize, Serialize};

/// The state of `Labelled`.
#[derive(StateVector)]
pub struct Decay {
    /// The decaying value
    pub y: f64,
}

/// A decaying value with a fixed and a tunable String parameter.
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[variables(states = Decay)]
pub struct Labelled {
    /// Decay rate
    #[parameter(positive)]
    pub rate: f64,
    /// A label fixed at initialization
    #[parameter]
    pub label: String,
    /// A note the importer may change at any time
    #[parameter(tunable)]
    pub note: String,
}

impl Default for Labelled {
    fn default() -> Self {
        Labelled { rate: 1.0, label: "start <&\"label\">".to_owned(), note: String::new() }
    }
}

impl fmu_export::Equations<f64> for Labelled {
    fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
        x[0] = 1.0;
        Ok(())
    }

    fn derivatives(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = -self.rate * x[0];
    }
}

impl Model for Labelled {
    const N_STATES: usize = 1;
    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "labelled",
            description: "strings",
            stop_time: 1.0,
            tolerance: 1e-6,
            output_interval: 0.1,
            documentation: "",
        }
    }
}

const RATE: u32 = 0;
const LABEL: u32 = 1;
const NOTE: u32 = 2;

#[test]
fn the_derive_makes_string_parameters_fixed_or_tunable() {
    let table = Table::<Labelled>::new();
    assert!(table.problems().is_empty(), "{:?}", table.problems());
    let label = table.row(LABEL).unwrap();
    assert_eq!((label.name, label.causality, label.variability), ("label", Causality::Parameter, Variability::Fixed));
    assert_eq!((label.base_type, label.initial), (fmu_export::model::BaseType::String, Some(Initial::Exact)));
    assert_eq!(label.description, "A label fixed at initialization");
    assert_eq!(label.start(&Labelled::default()), Some(Start::String("start <&\"label\">".to_owned())));
    let note = table.row(NOTE).unwrap();
    assert_eq!(note.variability, Variability::Tunable);
    assert_eq!(note.start(&Labelled::default()), Some(Start::String(String::new())));
}

#[test]
fn both_model_descriptions_carry_the_string_start_values() {
    let xml2 = fmu_export::fmi2::describe::model_description_xml::<Labelled>().unwrap();
    assert!(xml2.contains(r#"<String start="start &lt;&amp;&quot;label&quot;&gt;"/>"#), "{xml2}");
    // An empty start is written, not left out: an empty text is a value.
    assert!(xml2.contains(r#"<String start=""/>"#), "{xml2}");
    let back = fmi_schema::fmi2::ModelDescription::from_xml(&xml2).unwrap();
    let sv = back.model_variables.iter().find(|v| v.name == "label").unwrap();
    assert!(matches!(&sv.var_type, fmi_schema::fmi2::VariableType::String(s) if s.start.as_deref() == Some("start <&\"label\">")));

    let xml3 = fmu_export::fmi3::describe::model_description_xml::<Labelled>();
    let back = fmi_schema::fmi3::ModelDescription::from_xml(&xml3).unwrap();
    let v = back.model_variables.iter().find(|v| v.name == "label").unwrap();
    assert!(matches!(&v.kind, fmi_schema::fmi3::VariableKind::String { start: Some(s) } if s == &vec!["start <&\"label\">".to_owned()]));
    assert_eq!(v.variability, Some(fmi_schema::fmi3::Variability::Fixed));
    // The 3.0 form: the start value is a child element.
    let at = xml3.find(r#"name="label""#).unwrap();
    let element = &xml3[at..at + xml3[at..].find("</String>").unwrap()];
    assert!(element.contains(r#"<Start value="start &lt;&amp;&quot;label&quot;&gt;"/>"#), "{element}");
}

// The C functions as a model crate exports them: the tests call them as an importer would.
fmu_export::export_fmu!(Labelled);

static MESSAGES: Mutex<Vec<String>> = Mutex::new(Vec::new());

extern "C" fn record(_env: *mut c_void, _name: *const c_char, status: c_int, _cat: *const c_char, msg: *const c_char) {
    let msg = unsafe { CStr::from_ptr(msg) }.to_string_lossy().into_owned();
    MESSAGES.lock().unwrap().push(format!("{status}: {msg}"));
}

/// The messages logged since the last call (the tests of this file share the logger).
fn logged() -> String {
    std::mem::take(&mut *MESSAGES.lock().unwrap()).join("\n")
}

static TEST_LOCK: Mutex<()> = Mutex::new(());

/// A Co-Simulation FMI 2.0 instance of `Labelled` logging into `MESSAGES`.
unsafe fn instance2() -> *mut c_void {
    // SAFETY: on x86-64 System V a variadic call with only the fixed arguments matches this
    // non-variadic callee (as in panic_boundary.rs).
    let logger: LoggerFn = std::mem::transmute(record as extern "C" fn(_, _, _, _, _));
    let callbacks = CallbackFunctions {
        logger: Some(logger),
        allocate_memory: None,
        free_memory: None,
        step_finished: None,
        component_environment: std::ptr::null_mut(),
    };
    let guid = CString::new(fmu_export::table::guid::<Labelled>()).unwrap();
    let c = fmi2_exports::fmi2Instantiate(c"s".as_ptr(), ffi::FMI2_COSIMULATION, guid.as_ptr(), std::ptr::null(), &callbacks, 0, 0);
    assert!(!c.is_null());
    c
}

unsafe fn text(p: *const c_char) -> String {
    CStr::from_ptr(p).to_str().unwrap().to_owned()
}

#[test]
fn fmi2_strings_are_set_read_and_refused_clearly() {
    let _serial = TEST_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    unsafe {
        let c = instance2();
        logged();
        // Set before initialization, read from Initialization Mode on (as FMI 2.0 allows).
        let mut out = [std::ptr::null::<c_char>(); 2];
        assert_eq!(fmi2_exports::fmi2GetString(c, [LABEL].as_ptr(), 1, out.as_mut_ptr()), 3);
        assert!(logged().contains("fmi2GetString is not allowed in state"));
        assert_eq!(fmi2_exports::fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), 0);
        assert_eq!(fmi2_exports::fmi2EnterInitializationMode(c), 0);
        assert_eq!(fmi2_exports::fmi2GetString(c, [LABEL, NOTE].as_ptr(), 2, out.as_mut_ptr()), 0);
        assert_eq!((text(out[0]), text(out[1])), ("start <&\"label\">".to_owned(), String::new()));

        // The importer's text is copied: its buffer may go away right after the call.
        let value = CString::new("ünïcode ✓").unwrap();
        assert_eq!(fmi2_exports::fmi2SetString(c, [LABEL].as_ptr(), 1, [value.as_ptr()].as_ptr()), 0);
        drop(value);
        assert_eq!(fmi2_exports::fmi2GetString(c, [LABEL].as_ptr(), 1, out.as_mut_ptr()), 0);
        let first = out[0];
        // The pointers stay valid across other calls into the instance (FMI 2.0 asks until
        // the next call; they last until the next fmi2GetString).
        let mut y = [0.0];
        assert_eq!(fmi2_exports::fmi2GetReal(c, [RATE].as_ptr(), 1, y.as_mut_ptr()), 0);
        assert_eq!(fmi2_exports::fmi2SetReal(c, [RATE].as_ptr(), 1, [2.0].as_ptr()), 0);
        assert_eq!(text(first), "ünïcode ✓");

        // NULL: the array, and an element of it. Nothing is set by a refused call.
        assert_eq!(fmi2_exports::fmi2SetString(c, [LABEL].as_ptr(), 1, std::ptr::null()), 3);
        assert!(logged().contains("fmi2SetString: value[] is NULL but its length is 1"));
        let other = CString::new("other").unwrap();
        assert_eq!(fmi2_exports::fmi2SetString(c, [NOTE, LABEL].as_ptr(), 2, [other.as_ptr(), std::ptr::null()].as_ptr()), 3);
        let msg = logged();
        assert!(msg.contains("fmi2SetString: value[1] (for 'label') is a NULL pointer, not a string"), "{msg}");
        // Not UTF-8: a lone continuation byte.
        let bad: [u8; 3] = [b'a', 0x80, 0];
        assert_eq!(fmi2_exports::fmi2SetString(c, [NOTE].as_ptr(), 1, [bad.as_ptr() as *const c_char].as_ptr()), 3);
        let msg = logged();
        assert!(msg.contains("value[0] (for 'note') is not valid UTF-8 text"), "{msg}");
        assert_eq!(fmi2_exports::fmi2GetString(c, [NOTE].as_ptr(), 1, out.as_mut_ptr()), 0);
        assert_eq!(text(out[0]), "", "refused calls change nothing");

        // Wrong types both ways, named.
        assert_eq!(fmi2_exports::fmi2GetString(c, [RATE].as_ptr(), 1, out.as_mut_ptr()), 3);
        assert!(logged().contains("value reference 0 is 'rate' of type Real, not a String variable"));
        assert_eq!(fmi2_exports::fmi2SetReal(c, [LABEL].as_ptr(), 1, [1.0].as_ptr()), 3);
        assert!(logged().contains("'label' of type String, not a settable Real variable"));

        // After initialization: the fixed label is refused, the tunable note is not.
        assert_eq!(fmi2_exports::fmi2SetString(c, [LABEL].as_ptr(), 1, [c"in init".as_ptr()].as_ptr()), 0);
        assert_eq!(fmi2_exports::fmi2ExitInitializationMode(c), 0);
        assert_eq!(fmi2_exports::fmi2SetString(c, [LABEL].as_ptr(), 1, [c"late".as_ptr()].as_ptr()), 3);
        let msg = logged();
        assert!(msg.contains("parameter 'label' is fixed and can be set only before fmi2ExitInitializationMode"), "{msg}");
        assert_eq!(fmi2_exports::fmi2SetString(c, [NOTE].as_ptr(), 1, [c"tuned".as_ptr()].as_ptr()), 0);
        assert_eq!(fmi2_exports::fmi2DoStep(c, 0.0, 0.1, 1), 0);
        assert_eq!(fmi2_exports::fmi2GetString(c, [LABEL, NOTE].as_ptr(), 2, out.as_mut_ptr()), 0);
        assert_eq!((text(out[0]), text(out[1])), ("in init".to_owned(), "tuned".to_owned()));
        fmi2_exports::fmi2FreeInstance(c);
    }
}

#[test]
fn fmi2_fmu_states_carry_the_strings_and_old_formats_are_refused() {
    let _serial = TEST_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    unsafe {
        let c = instance2();
        assert_eq!(fmi2_exports::fmi2SetString(c, [LABEL].as_ptr(), 1, [c"saved label".as_ptr()].as_ptr()), 0);
        assert_eq!(fmi2_exports::fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), 0);
        assert_eq!(fmi2_exports::fmi2EnterInitializationMode(c), 0);
        assert_eq!(fmi2_exports::fmi2ExitInitializationMode(c), 0);
        assert_eq!(fmi2_exports::fmi2SetString(c, [NOTE].as_ptr(), 1, [c"saved note".as_ptr()].as_ptr()), 0);
        let mut state = std::ptr::null_mut();
        assert_eq!(fmi2_exports::fmi2GetFMUstate(c, &mut state), 0);
        let mut size = 0;
        assert_eq!(fmi2_exports::fmi2SerializedFMUstateSize(c, state, &mut size), 0);
        let mut bytes = vec![0u8; size];
        assert_eq!(fmi2_exports::fmi2SerializeFMUstate(c, state, bytes.as_mut_ptr() as *mut c_char, size), 0);
        assert_eq!(fmi2_exports::fmi2FreeFMUstate(c, &mut state), 0);

        // Change the note and step on; then restore the serialized state in a second instance.
        assert_eq!(fmi2_exports::fmi2SetString(c, [NOTE].as_ptr(), 1, [c"changed".as_ptr()].as_ptr()), 0);
        assert_eq!(fmi2_exports::fmi2DoStep(c, 0.0, 0.1, 1), 0);
        let d = instance2();
        let mut restored = std::ptr::null_mut();
        assert_eq!(fmi2_exports::fmi2DeSerializeFMUstate(d, bytes.as_ptr() as *const c_char, size, &mut restored), 0);
        assert_eq!(fmi2_exports::fmi2SetFMUstate(d, restored), 0);
        let mut out = [std::ptr::null::<c_char>(); 2];
        assert_eq!(fmi2_exports::fmi2GetString(d, [LABEL, NOTE].as_ptr(), 2, out.as_mut_ptr()), 0);
        assert_eq!((text(out[0]), text(out[1])), ("saved label".to_owned(), "saved note".to_owned()));
        // The restored instance is after initialization: its label is fixed there too.
        assert_eq!(fmi2_exports::fmi2SetString(d, [LABEL].as_ptr(), 1, [c"x".as_ptr()].as_ptr()), 3);
        assert_eq!(fmi2_exports::fmi2FreeFMUstate(d, &mut restored), 0);

        // A buffer of the format version before Strings (4) is refused, saying so.
        logged();
        let mut old = bytes.clone();
        old[4..6].copy_from_slice(&4u16.to_le_bytes());
        assert_eq!(fmi2_exports::fmi2DeSerializeFMUstate(d, old.as_ptr() as *const c_char, size, &mut restored), 3);
        let msg = logged();
        assert!(msg.contains("format version 4; this FMU reads version 6"), "{msg}");
        fmi2_exports::fmi2FreeInstance(c);
        fmi2_exports::fmi2FreeInstance(d);
    }
}

unsafe extern "C" fn record3(_env: *mut c_void, status: c_int, _cat: *const c_char, msg: *const c_char) {
    let msg = unsafe { CStr::from_ptr(msg) }.to_string_lossy().into_owned();
    MESSAGES.lock().unwrap().push(format!("{status}: {msg}"));
}

#[test]
fn fmi3_strings_are_arrays_of_values_checked_like_fmi2() {
    let _serial = TEST_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    unsafe {
        let token = CString::new(fmu_export::table::guid::<Labelled>()).unwrap();
        // name, token, resources, visible, loggingOn, eventModeUsed, earlyReturnAllowed,
        // required intermediate variables, environment, logger, intermediate-update callback.
        let c = fmi3_exports::fmi3InstantiateCoSimulation(
            c"s3".as_ptr(),
            token.as_ptr(),
            std::ptr::null(),
            false,
            false,
            false,
            false,
            std::ptr::null(),
            0,
            std::ptr::null_mut(),
            Some(record3),
            std::ptr::null(),
        );
        assert!(!c.is_null());
        logged();
        assert_eq!(fmi3_exports::fmi3EnterInitializationMode(c, false, 0.0, 0.0, false, 0.0), 0);
        let mut out = [std::ptr::null::<c_char>(); 2];
        assert_eq!(fmi3_exports::fmi3GetString(c, [LABEL, NOTE].as_ptr(), 2, out.as_mut_ptr(), 2), 0);
        assert_eq!((text(out[0]), text(out[1])), ("start <&\"label\">".to_owned(), String::new()));
        let values = [c"three".as_ptr(), c"3.0 note".as_ptr()];
        assert_eq!(fmi3_exports::fmi3SetString(c, [LABEL, NOTE].as_ptr(), 2, values.as_ptr(), 2), 0);
        assert_eq!(fmi3_exports::fmi3GetString(c, [NOTE, LABEL].as_ptr(), 2, out.as_mut_ptr(), 2), 0);
        assert_eq!((text(out[0]), text(out[1])), ("3.0 note".to_owned(), "three".to_owned()));
        // nValues must match (the variables are scalars), NULL elements are refused.
        assert_eq!(fmi3_exports::fmi3GetString(c, [LABEL].as_ptr(), 1, out.as_mut_ptr(), 2), 3);
        assert!(logged().contains("fmi3GetString: nValues = 2 but the 1 value references are scalars"));
        assert_eq!(fmi3_exports::fmi3SetString(c, [LABEL].as_ptr(), 1, [std::ptr::null()].as_ptr(), 1), 3);
        assert!(logged().contains("fmi3SetString: values[0] (for 'label') is a NULL pointer"));
        assert_eq!(fmi3_exports::fmi3ExitInitializationMode(c), 0);
        assert_eq!(fmi3_exports::fmi3SetString(c, [LABEL].as_ptr(), 1, [c"late".as_ptr()].as_ptr(), 1), 3);
        assert!(logged().contains("parameter 'label' is fixed and can be set only before fmi3ExitInitializationMode"));
        assert_eq!(fmi3_exports::fmi3SetString(c, [NOTE].as_ptr(), 1, [c"tuned".as_ptr()].as_ptr(), 1), 0);
        fmi3_exports::fmi3FreeInstance(c);
    }
}
