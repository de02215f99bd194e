//! fmi2/fmi3 GetString and SetString through `Instance`, on the Reference FMU Feedthrough
//! (third-party FMUs, FMI 2.0 and 3.0), which copies `String_input` to `String_output`: the
//! text set comes back as it was, also outside ASCII, and a variable of another type is
//! refused. (tests/fmpy/test_strings.py reads the same FMUs with fmpy, independently.)

use std::path::{Path, PathBuf};

use fmi_importer::{Fmu, Value};

fn reference(version: &str) -> Option<PathBuf> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../../shared/reference-fmus/{version}/Feedthrough.fmu"));
    path.is_file().then_some(path)
}

fn round_trip(path: &Path) {
    let fmu = Fmu::load(path).expect("Feedthrough loads");
    let d = &fmu.description;
    let (input, output) = (d.variable("String_input").unwrap(), d.variable("String_output").unwrap());
    let mut inst = fmu.instantiate("strings", false).unwrap();
    inst.setup_experiment(None, 0.0, 1.0).unwrap();
    inst.enter_initialization_mode().unwrap();
    // The start value, as the description gives it.
    assert_eq!(inst.get_string(input).unwrap(), ["Set me!"]);
    inst.set(input, &Value::String("héllo, wörld ✓".to_owned())).unwrap();
    inst.exit_initialization_mode().unwrap();
    assert!(matches!(inst.do_step(0.0, 0.1).unwrap(), fmi_importer::Step::Done));
    assert_eq!(inst.get_string(output).unwrap(), ["héllo, wörld ✓"]);
    let real = d.variable("Float64_continuous_input").unwrap();
    let err = inst.get_string(real).unwrap_err();
    assert!(err.contains("Float64_continuous_input") && err.contains("not a String"), "{err}");
}

#[test]
fn fmi2_get_string_reads_what_set_string_wrote() {
    let Some(path) = reference("fmi2") else { return };
    round_trip(&path);
}

#[test]
fn fmi3_get_string_reads_what_set_string_wrote() {
    let Some(path) = reference("fmi3") else { return };
    round_trip(&path);
}
