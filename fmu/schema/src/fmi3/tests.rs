//! FMI 3.0 descriptions: the Reference FMUs (third-party files) read, check clean and survive a
//! write/read round trip; hand-made breakages are each found by check() with a message that
//! names the variable; hostile input is refused with a position.

use std::io::Read;

use super::*;

/// The modelDescription.xml of every FMI 3.0 Reference FMU (../shared/reference-fmus/fmi3).
fn reference_descriptions() -> Vec<(String, String)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference-fmus/fmi3");
    let mut out = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.unwrap().path();
        let mut zip = zip::ZipArchive::new(std::fs::File::open(&path).unwrap()).unwrap();
        let mut xml = String::new();
        zip.by_name("modelDescription.xml").unwrap().read_to_string(&mut xml).unwrap();
        out.push((path.file_stem().unwrap().to_string_lossy().into_owned(), xml));
    }
    out.sort();
    assert!(out.len() >= 9, "expected the nine FMI 3.0 Reference FMUs, found {}", out.len());
    out
}

#[test]
fn reference_fmus_read_check_clean_and_round_trip() {
    for (name, xml) in reference_descriptions() {
        let md = ModelDescription::from_xml(&xml).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(md.check(), Vec::<String>::new(), "{name}");
        let again = ModelDescription::from_xml(&md.to_xml()).unwrap_or_else(|e| panic!("{name} written: {e}"));
        assert_eq!(again, md, "{name}: the round trip changed the description");
    }
}

#[test]
fn reference_fmus_are_read_into_the_right_types() {
    let all = reference_descriptions();
    let get = |n: &str| ModelDescription::from_xml(&all.iter().find(|(name, _)| name == n).unwrap().1).unwrap();
    let feed = get("Feedthrough");
    let kinds: Vec<BaseType> = feed.model_variables.iter().map(Variable::base_type).collect();
    for t in
        [BaseType::Float(FloatType::Float32), BaseType::Int(IntType::UInt64), BaseType::Binary, BaseType::Enumeration, BaseType::String]
    {
        assert!(kinds.contains(&t), "Feedthrough has a {t} variable");
    }
    match &feed.variable("Binary_input").unwrap().kind {
        VariableKind::Binary { start: Some(s), .. } => assert_eq!(s, &vec![b"foo".to_vec()]),
        other => panic!("{other:?}"),
    }
    match &feed.variable("String_input").unwrap().kind {
        VariableKind::String { start: Some(s) } => assert_eq!(s, &vec!["Set me!".to_owned()]),
        other => panic!("{other:?}"),
    }
    let space = get("StateSpace");
    let a = space.variable("A").unwrap();
    assert_eq!(a.dimensions, vec![Dimension::Variable(2), Dimension::Variable(2)]);
    assert_eq!(space.start_shape(a), Some(vec![3, 3]));
    assert_eq!(a.start_len(), 9);
    let ball = get("BouncingBall");
    let h = ball.variable("h").unwrap();
    assert_eq!(ball.unit_of(h), Some("m"), "the unit comes from the declared type Position");
    assert_eq!(h.aliases[0].display_unit.as_deref(), Some("ft"));
    assert_eq!(ball.model_structure.event_indicators.len(), 1);
    assert!(ball.co_simulation.as_ref().unwrap().might_return_early_from_do_step);
    let clocks = get("Clocks");
    assert!(clocks.scheduled_execution.is_some() && clocks.co_simulation.is_none());
}

/// A small clean description to break in the tests below.
fn sample() -> ModelDescription {
    let mut md = ModelDescription::new("m", "{token}");
    md.co_simulation =
        Some(CoSimulation { common: InterfaceCommon { model_identifier: "m".into(), ..Default::default() }, ..Default::default() });
    md.unit_definitions.push(Unit { name: "m".into(), base_unit: Some(BaseUnit { m: 1, ..Default::default() }), display_units: vec![] });
    let float = |start: Option<Vec<f64>>| VariableKind::Float {
        precision: FloatType::Float64,
        attributes: Float::default(),
        start,
        derivative: None,
        reinit: false,
    };
    let mut time = Variable::new("time", 0, float(None));
    time.causality = Some(Causality::Independent);
    let mut k = Variable::new("k", 1, float(Some(vec![2.0])));
    k.causality = Some(Causality::Parameter);
    k.variability = Some(Variability::Fixed);
    if let VariableKind::Float { attributes, .. } = &mut k.kind {
        attributes.min = Some(0.0);
        attributes.unit = Some("m".into());
    }
    let mut x = Variable::new("x", 2, float(Some(vec![1.0])));
    x.causality = Some(Causality::Output);
    x.initial = Some(Initial::Exact);
    let mut dx = Variable::new("der(x)", 3, float(None));
    if let VariableKind::Float { derivative, .. } = &mut dx.kind {
        *derivative = Some(2);
    }
    md.model_variables = vec![time, k, x, dx];
    md.model_structure.outputs.push(Unknown::new(2));
    md.model_structure.continuous_state_derivatives.push(Unknown::new(3));
    md.model_structure.initial_unknowns.push(Unknown::new(3));
    md
}

fn assert_problem(breakage: impl FnOnce(&mut ModelDescription), expected: &str) {
    let mut md = sample();
    breakage(&mut md);
    let problems = md.check();
    assert!(problems.iter().any(|p| p.contains(expected)), "expected a problem containing {expected:?}, got {problems:?}");
}

#[test]
fn the_sample_is_clean_and_round_trips() {
    let md = sample();
    assert_eq!(md.check(), Vec::<String>::new());
    assert_eq!(ModelDescription::from_xml(&md.to_xml()).unwrap(), md);
}

#[test]
fn check_finds_each_broken_rule() {
    assert_problem(|m| m.model_variables[2].value_reference = 1, "has the same value reference as variable 'k'");
    assert_problem(|m| m.model_variables[2].name = "k".into(), "the variable name 'k' is not unique");
    assert_problem(|m| m.model_variables[0].causality = None, "exactly one independent variable must be defined, found 0");
    assert_problem(|m| m.model_variables[1].initial = Some(Initial::Calculated), "initial=\"calculated\" is not allowed");
    assert_problem(
        |m| {
            m.model_variables[2].kind = VariableKind::Float {
                precision: FloatType::Float64,
                attributes: Float::default(),
                start: None,
                derivative: None,
                reinit: false,
            }
        },
        "'x' (valueReference 2) has no start value",
    );
    assert_problem(
        |m| {
            if let VariableKind::Float { start, .. } = &mut m.model_variables[1].kind {
                *start = Some(vec![-1.0]);
            }
        },
        "start -1 is outside [0, inf]",
    );
    assert_problem(
        |m| {
            if let VariableKind::Float { attributes, .. } = &mut m.model_variables[1].kind {
                attributes.unit = Some("kg".into());
            }
        },
        "the unit 'kg' is not defined",
    );
    assert_problem(|m| m.model_structure.outputs.clear(), "Output must list exactly the variables with causality=\"output\"");
    assert_problem(|m| m.model_structure.initial_unknowns.clear(), "InitialUnknown lists {}, expected {der(x)}");
    assert_problem(|m| m.model_variables[2].dimensions = vec![Dimension::Variable(1)], "not a scalar integer structural parameter");
    assert_problem(
        |m| m.co_simulation.as_mut().unwrap().common.model_identifier = "a b".into(),
        "modelIdentifier 'a b' is not a C identifier",
    );
    assert_problem(|m| m.model_variables[1].declared_type = Some("Nope".into()), "declaredType 'Nope' is not defined");
    assert_problem(
        |m| m.default_experiment = Some(DefaultExperiment { start_time: Some(1.0), stop_time: Some(0.0), ..Default::default() }),
        "stopTime 0 must be after startTime 1",
    );
}

#[test]
fn an_array_with_one_start_for_all_elements_is_accepted() {
    let mut md = sample();
    md.model_variables[2].dimensions = vec![Dimension::Fixed(3)];
    assert!(!md.check().iter().any(|p| p.contains("start value(s)")), "{:?}", md.check());
    if let VariableKind::Float { start, .. } = &mut md.model_variables[2].kind {
        *start = Some(vec![1.0, 2.0]);
    }
    assert!(md.check().iter().any(|p| p.contains("has 2 start value(s) but 3 element(s)")));
}

fn read_error(text: &str) -> String {
    ModelDescription::from_xml(text).unwrap_err().message().to_owned()
}

#[test]
fn bad_input_is_refused_with_the_element_and_attribute() {
    let wrap = |vars: &str| {
        format!("<fmiModelDescription fmiVersion=\"3.0\" modelName=\"m\" instantiationToken=\"t\"><ModelVariables>{vars}</ModelVariables></fmiModelDescription>")
    };
    assert!(read_error(&wrap("<Float64 name=\"x\" valueReference=\"a\"/>"))
        .contains("attribute valueReference=\"a\" on <Float64 name=\"x\"> (line 1)"));
    assert!(read_error(&wrap("<UInt8 name=\"n\" valueReference=\"1\" start=\"300\"/>")).contains("outside the range of UInt8 (0 to 255)"));
    assert!(read_error(&wrap("<Int8 name=\"n\" valueReference=\"1\" start=\"1.5\"/>")).contains("not an integer of type Int8"));
    assert!(read_error(&wrap("<Float32 name=\"f\" valueReference=\"1\" start=\"1e300\"/>")).contains("outside the range of Float32"));
    assert!(
        read_error(&wrap("<Binary name=\"b\" valueReference=\"1\"><Start value=\"xyz\"/></Binary>")).contains("is not hexadecimal bytes")
    );
    assert!(
        read_error(&wrap("<Binary name=\"b\" valueReference=\"1\"><Start value=\"é1\"/></Binary>")).contains("is not hexadecimal bytes")
    );
    assert!(read_error(&wrap("<Boolean name=\"b\" valueReference=\"1\" start=\"yes\"/>")).contains("not a boolean"));
    assert!(read_error(&wrap("<Float64 name=\"x\"/>")).contains("missing attribute valueReference on <Float64 name=\"x\">"));
    assert!(read_error(&wrap("<Float64 name=\"x\" valueReference=\"1\"><Dimension/></Float64>"))
        .contains("needs exactly one of start and valueReference"));
    assert!(read_error("<fmiModelDescription fmiVersion=\"2.0\" modelName=\"m\" guid=\"g\"/>").contains("fmiVersion is 2.0, expected 3.0"));
    assert!(read_error("<fmiModelDescription fmiVersion=\"3.0\" modelName=\"m\" instantiationToken=\"t\"/>")
        .contains("missing element ModelVariables"));
    assert!(read_error("<other/>").contains("root element is <other>"));
    assert!(read_error("<fmiModelDescription").contains("malformed XML"));
}

#[test]
fn float32_values_keep_single_precision_and_short_text() {
    let xml = "<fmiModelDescription fmiVersion=\"3.0\" modelName=\"m\" instantiationToken=\"t\"><ModelVariables><Float32 name=\"f\" valueReference=\"1\" causality=\"parameter\" variability=\"fixed\" start=\"0.1\"/></ModelVariables></fmiModelDescription>";
    let md = ModelDescription::from_xml(xml).unwrap();
    match &md.model_variables[0].kind {
        VariableKind::Float { start: Some(s), .. } => assert_eq!(s[0], 0.1f32 as f64),
        other => panic!("{other:?}"),
    }
    assert!(md.to_xml().contains("start=\"0.1\""), "{}", md.to_xml());
}

#[test]
fn hex_round_trips() {
    assert_eq!(hex(&[0, 15, 255]), "000fff");
    assert_eq!(unhex("000FfF").unwrap(), vec![0, 15, 255]);
    assert!(unhex("abc").unwrap_err().contains("odd number"));
}
