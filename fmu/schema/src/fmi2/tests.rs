//! Tests of reading, writing and checking model descriptions.

use super::*;

// ---------------------------------------------------------------------------------------------
// Builders for descriptions written the way our exporter writes them.
// ---------------------------------------------------------------------------------------------

fn real(name: &str, vr: u32, causality: Causality, variability: Variability, attributes: RealVariable) -> ScalarVariable {
    let mut v = ScalarVariable::new(name, vr, VariableType::Real(attributes));
    v.causality = Some(causality);
    v.variability = Some(variability);
    v
}

fn unit(name: &str, base: BaseUnit, display_units: Vec<DisplayUnit>) -> Unit {
    Unit { name: name.to_string(), base_unit: Some(base), display_units }
}

/// A clean Co-Simulation + Model Exchange description using every variable type, units,
/// display units, a declared type and a model structure with dependencies.
fn spring() -> ModelDescription {
    let mut md = ModelDescription::new("Spring", "{8c4e810f-3df3-4a00-8276-176fa3c9f000}");
    md.description = Some("Mass on a spring & friends <test>".to_string());
    md.author = Some("fmu toolkit".to_string());
    md.version = Some("1.2.3".to_string());
    md.generation_tool = Some("fmu 0.1.0".to_string());
    md.generation_date_and_time = Some("2024-01-02T03:04:05Z".to_string());
    md.variable_naming_convention = Some(VariableNamingConvention::Structured);
    md.number_of_event_indicators = Some(0);
    md.model_exchange = Some(ModelExchange {
        common: InterfaceCommon { model_identifier: "Spring".to_string(), ..InterfaceCommon::default() },
        completed_integrator_step_not_needed: true,
    });
    md.co_simulation = Some(CoSimulation {
        common: InterfaceCommon {
            model_identifier: "Spring".to_string(),
            can_get_and_set_fmu_state: true,
            source_files: vec!["spring.c".to_string()],
            ..InterfaceCommon::default()
        },
        can_handle_variable_communication_step_size: true,
        max_output_derivative_order: 1,
        ..CoSimulation::default()
    });
    md.unit_definitions = vec![
        unit("s", BaseUnit { s: 1, ..BaseUnit::default() }, vec![]),
        unit("m", BaseUnit { m: 1, ..BaseUnit::default() }, vec![DisplayUnit::new("mm", 1000.0, 0.0)]),
        unit("m/s", BaseUnit { m: 1, s: -1, ..BaseUnit::default() }, vec![DisplayUnit::new("km/h", 3.6, 0.0)]),
        unit("m/s2", BaseUnit { m: 1, s: -2, ..BaseUnit::default() }, vec![]),
        unit("N", BaseUnit { kg: 1, m: 1, s: -2, ..BaseUnit::default() }, vec![]),
        unit("N/m", BaseUnit { kg: 1, s: -2, ..BaseUnit::default() }, vec![]),
        unit("J", BaseUnit { kg: 1, m: 2, s: -2, ..BaseUnit::default() }, vec![]),
        unit("degC", BaseUnit { k: 1, offset: 273.15, ..BaseUnit::default() }, vec![DisplayUnit::new("degF", 1.8, 32.0)]),
    ];
    md.type_definitions = vec![
        SimpleType {
            name: "Position".to_string(),
            description: Some("a length".to_string()),
            kind: SimpleTypeKind::Real(RealAttributes {
                quantity: Some("Length".to_string()),
                unit: Some("m".to_string()),
                display_unit: Some("mm".to_string()),
                ..RealAttributes::default()
            }),
        },
        SimpleType {
            name: "Mode".to_string(),
            description: None,
            kind: SimpleTypeKind::Enumeration(EnumerationType {
                quantity: None,
                items: vec![
                    EnumerationItem { name: "off".to_string(), value: 1, description: Some("idle".to_string()) },
                    EnumerationItem { name: "on".to_string(), value: 2, description: None },
                ],
            }),
        },
        SimpleType {
            name: "Count".to_string(),
            description: None,
            kind: SimpleTypeKind::Integer(IntegerAttributes { quantity: None, min: Some(0), max: None }),
        },
        SimpleType { name: "Flag".to_string(), description: None, kind: SimpleTypeKind::Boolean },
        SimpleType { name: "Text".to_string(), description: None, kind: SimpleTypeKind::String },
    ];
    md.log_categories = vec![Category::new("logEvents", Some("Events")), Category::new("logStatusError", None)];
    md.default_experiment =
        Some(DefaultExperiment { start_time: Some(0.0), stop_time: Some(10.0), tolerance: Some(1e-6), step_size: Some(1e-3) });

    let mut time = real(
        "time",
        0,
        Causality::Independent,
        Variability::Continuous,
        RealVariable { attributes: RealAttributes { unit: Some("s".to_string()), ..RealAttributes::default() }, ..RealVariable::default() },
    );
    time.description = Some("Simulation time".to_string());
    let mut x = real(
        "x",
        1,
        Causality::Output,
        Variability::Continuous,
        RealVariable {
            declared_type: Some("Position".to_string()),
            start: Some(1.0),
            attributes: RealAttributes { min: Some(-10.0), max: Some(10.0), nominal: Some(0.5), ..RealAttributes::default() },
            ..RealVariable::default()
        },
    );
    x.initial = Some(Initial::Exact);
    let der_x = real(
        "der(x)",
        2,
        Causality::Local,
        Variability::Continuous,
        RealVariable {
            attributes: RealAttributes { unit: Some("m/s".to_string()), ..RealAttributes::default() },
            derivative: Some(2),
            ..RealVariable::default()
        },
    );
    let mut v = real(
        "v",
        3,
        Causality::Output,
        Variability::Continuous,
        RealVariable {
            attributes: RealAttributes {
                unit: Some("m/s".to_string()),
                display_unit: Some("km/h".to_string()),
                ..RealAttributes::default()
            },
            start: Some(0.0),
            reinit: true,
            ..RealVariable::default()
        },
    );
    v.initial = Some(Initial::Exact);
    let der_v = real(
        "der(v)",
        4,
        Causality::Local,
        Variability::Continuous,
        RealVariable {
            attributes: RealAttributes { unit: Some("m/s2".to_string()), ..RealAttributes::default() },
            derivative: Some(4),
            ..RealVariable::default()
        },
    );
    let k = real(
        "k",
        5,
        Causality::Parameter,
        Variability::Fixed,
        RealVariable {
            attributes: RealAttributes { unit: Some("N/m".to_string()), ..RealAttributes::default() },
            start: Some(1e-9),
            ..RealVariable::default()
        },
    );
    let force = real(
        "F",
        6,
        Causality::Input,
        Variability::Continuous,
        RealVariable {
            attributes: RealAttributes { unit: Some("N".to_string()), ..RealAttributes::default() },
            start: Some(0.1),
            ..RealVariable::default()
        },
    );
    let energy = real(
        "energy",
        7,
        Causality::CalculatedParameter,
        Variability::Fixed,
        RealVariable {
            attributes: RealAttributes {
                unit: Some("J".to_string()),
                relative_quantity: true,
                unbounded: true,
                ..RealAttributes::default()
            },
            ..RealVariable::default()
        },
    );
    let mut steps = ScalarVariable::new(
        "steps",
        0,
        VariableType::Integer(IntegerVariable { declared_type: Some("Count".to_string()), ..IntegerVariable::default() }),
    );
    steps.causality = Some(Causality::Output);
    steps.variability = Some(Variability::Discrete);
    steps.description = Some("number of steps taken".to_string());
    let mut active = ScalarVariable::new(
        "active",
        0,
        VariableType::Boolean(BooleanVariable { declared_type: Some("Flag".to_string()), start: Some(true) }),
    );
    active.causality = Some(Causality::Parameter);
    active.variability = Some(Variability::Fixed);
    let mut mode = ScalarVariable::new(
        "mode",
        1,
        VariableType::Enumeration(EnumerationVariable {
            declared_type: Some("Mode".to_string()),
            attributes: IntegerAttributes { min: Some(1), max: Some(2), ..IntegerAttributes::default() },
            start: Some(2),
        }),
    );
    mode.causality = Some(Causality::Parameter);
    mode.variability = Some(Variability::Tunable);
    let mut label = ScalarVariable::new(
        "label",
        0,
        VariableType::String(StringVariable { declared_type: Some("Text".to_string()), start: Some(String::new()) }),
    );
    label.causality = Some(Causality::Parameter);
    label.variability = Some(Variability::Fixed);
    let mut temperature = real(
        "T",
        8,
        Causality::Local,
        Variability::Discrete,
        RealVariable {
            attributes: RealAttributes {
                unit: Some("degC".to_string()),
                display_unit: Some("degF".to_string()),
                ..RealAttributes::default()
            },
            start: Some(-0.0),
            ..RealVariable::default()
        },
    );
    temperature.initial = Some(Initial::Approx);
    temperature.can_handle_multiple_set_per_time_instant = Some(false);
    md.model_variables = vec![time, x, der_x, v, der_v, k, force, energy, steps, active, mode, label, temperature];
    // Indices: time 1, x 2, der(x) 3, v 4, der(v) 5, k 6, F 7, energy 8, steps 9, active 10,
    // mode 11, label 12, T 13.
    md.model_structure = ModelStructure {
        outputs: vec![Unknown::with_dependencies(2, vec![]), Unknown::with_dependencies(4, vec![]), Unknown::new(9)],
        derivatives: vec![
            Unknown { index: 3, dependencies: Some(vec![4]), dependencies_kind: Some(vec![DependencyKind::Constant]) },
            Unknown {
                index: 5,
                dependencies: Some(vec![2, 7]),
                dependencies_kind: Some(vec![DependencyKind::Fixed, DependencyKind::Dependent]),
            },
        ],
        initial_unknowns: vec![
            Unknown::with_dependencies(3, vec![4]),
            Unknown::with_dependencies(5, vec![2, 6, 7]),
            Unknown::with_dependencies(8, vec![6]),
            Unknown::new(9),
        ],
    };
    md
}

// ---------------------------------------------------------------------------------------------
// Writing and round trips.
// ---------------------------------------------------------------------------------------------

#[test]
fn good_description_is_clean() {
    assert_eq!(spring().check(), Vec::<String>::new());
}

#[test]
fn round_trip_preserves_everything() {
    let md = spring();
    let xml = md.to_xml().unwrap();
    let back = ModelDescription::from_xml(&xml).unwrap();
    assert_eq!(back, md, "written XML:\n{xml}");
    // Writing again gives byte-identical text, so exports are reproducible.
    assert_eq!(back.to_xml().unwrap(), xml);
}

#[test]
fn reals_round_trip_bit_exactly() {
    let values = [
        1e-9,
        0.1,
        -0.0,
        0.0,
        1.7976931348623157e308,
        -1.7976931348623157e308,
        f64::MIN_POSITIVE,
        5e-324,
        1.0 / 3.0,
        2.0f64.sqrt(),
        123456789.0,
        1e16,
        1e15 + 0.3,
        -9.81,
        6.02214076e23,
    ];
    let mut md = ModelDescription::new("Reals", "guid");
    md.co_simulation = Some(CoSimulation {
        common: InterfaceCommon { model_identifier: "Reals".to_string(), ..InterfaceCommon::default() },
        ..CoSimulation::default()
    });
    for (i, &value) in values.iter().enumerate() {
        md.model_variables.push(real(
            &format!("p{i}"),
            i as u32,
            Causality::Parameter,
            Variability::Fixed,
            RealVariable {
                start: Some(value),
                attributes: RealAttributes { nominal: Some(value), ..RealAttributes::default() },
                ..RealVariable::default()
            },
        ));
    }
    md.model_variables.push(real(
        "inf",
        99,
        Causality::Parameter,
        Variability::Fixed,
        RealVariable {
            start: Some(0.0),
            attributes: RealAttributes { min: Some(f64::NEG_INFINITY), max: Some(f64::INFINITY), ..RealAttributes::default() },
            ..RealVariable::default()
        },
    ));
    let xml = md.to_xml().unwrap();
    assert!(xml.contains(r#"start="1e-9""#), "{xml}");
    assert!(xml.contains(r#"start="0.1""#), "{xml}");
    assert!(xml.contains(r#"start="-0""#), "{xml}");
    assert!(xml.contains(r#"start="1.7976931348623157e308""#), "{xml}");
    assert!(xml.contains(r#"min="-INF" max="INF""#), "{xml}");
    let back = ModelDescription::from_xml(&xml).unwrap();
    for (i, &value) in values.iter().enumerate() {
        let read = back.model_variables[i].real_start().unwrap();
        assert_eq!(read.to_bits(), value.to_bits(), "{value:?} came back as {read:?}");
        let nominal = back.model_variables[i].as_real().unwrap().attributes.nominal.unwrap();
        assert_eq!(nominal.to_bits(), value.to_bits());
    }
    let inf = back.variable("inf").unwrap().as_real().unwrap();
    assert_eq!((inf.attributes.min, inf.attributes.max), (Some(f64::NEG_INFINITY), Some(f64::INFINITY)));
}

#[test]
fn format_real_is_short_and_exact() {
    for (value, text) in [(1.0, "1"), (-2.0, "-2"), (0.5, "0.5"), (1e-9, "1e-9"), (1e300, "1e300"), (-0.0, "-0"), (f64::NAN, "NaN")] {
        assert_eq!(xml::format_real(value), text);
    }
    assert!(xml::parse_real("NaN").unwrap().is_nan());
    assert_eq!(xml::parse_real("-INF"), Some(f64::NEG_INFINITY));
    assert_eq!(xml::parse_real("INF"), Some(f64::INFINITY));
    assert_eq!(xml::parse_real("+INF"), Some(f64::INFINITY));
    assert_eq!(xml::parse_real(".5"), Some(0.5));
    assert_eq!(xml::parse_real("1,5"), None);
    assert_eq!(xml::parse_real("1E3"), Some(1000.0));
}

#[test]
fn written_xml_has_declaration_indentation_and_fmi_names() {
    let xml = spring().to_xml().unwrap();
    assert!(
        xml.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<fmiModelDescription fmiVersion=\"2.0\" modelName=\"Spring\""),
        "{xml}"
    );
    assert!(xml.ends_with("</fmiModelDescription>\n"));
    // Two-space indentation per level.
    assert!(xml.contains("\n  <CoSimulation modelIdentifier=\"Spring\" canHandleVariableCommunicationStepSize=\"true\" maxOutputDerivativeOrder=\"1\" canGetAndSetFMUstate=\"true\">"), "{xml}");
    assert!(xml.contains("\n    <ScalarVariable name=\"time\" valueReference=\"0\" description=\"Simulation time\" causality=\"independent\" variability=\"continuous\">\n      <Real unit=\"s\"/>\n    </ScalarVariable>"), "{xml}");
    assert!(xml.contains("<BaseUnit kg=\"1\" m=\"1\" s=\"-2\"/>"), "{xml}");
    assert!(xml.contains("<DisplayUnit name=\"degF\" factor=\"1.8\" offset=\"32\"/>"), "{xml}");
    assert!(xml.contains("<Unknown index=\"2\" dependencies=\"\"/>"), "{xml}");
    assert!(xml.contains("<Unknown index=\"5\" dependencies=\"2 7\" dependenciesKind=\"fixed dependent\"/>"), "{xml}");
    assert!(xml.contains("<Unknown index=\"9\"/>"), "{xml}");
    assert!(xml.contains("<Boolean declaredType=\"Flag\" start=\"true\"/>"), "{xml}");
    assert!(xml.contains("<SimpleType name=\"Flag\">\n      <Boolean/>\n    </SimpleType>"), "{xml}");
    assert!(xml.contains("description=\"Mass on a spring &amp; friends &lt;test&gt;\""), "{xml}");
    // Absent optional attributes and false/zero defaults are not written.
    assert!(!xml.contains("needsExecutionTool"), "{xml}");
    assert!(!xml.contains("copyright"), "{xml}");
    assert!(!xml.contains("canInterpolateInputs"), "{xml}");
    assert!(!xml.contains("<ScalarVariable name=\"der(x)\" valueReference=\"2\" description"), "{xml}");
    // Elements come in the schema's order.
    let order = [
        "<ModelExchange",
        "<CoSimulation",
        "<UnitDefinitions",
        "<TypeDefinitions",
        "<LogCategories",
        "<DefaultExperiment",
        "<ModelVariables",
        "<ModelStructure",
        "<Outputs",
        "<Derivatives",
        "<InitialUnknowns",
    ];
    let positions: Vec<usize> = order.iter().map(|tag| xml.find(tag).unwrap_or_else(|| panic!("{tag} missing"))).collect();
    assert!(positions.windows(2).all(|w| w[0] < w[1]), "{positions:?}");
}

#[test]
fn minimal_description_writes_required_elements_only() {
    let mut md = ModelDescription::new("Empty", "g");
    md.co_simulation = Some(CoSimulation {
        common: InterfaceCommon { model_identifier: "Empty".to_string(), ..InterfaceCommon::default() },
        ..CoSimulation::default()
    });
    let xml = md.to_xml().unwrap();
    assert_eq!(
        xml,
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <fmiModelDescription fmiVersion=\"2.0\" modelName=\"Empty\" guid=\"g\">\n  \
         <CoSimulation modelIdentifier=\"Empty\"/>\n  \
         <ModelVariables/>\n  \
         <ModelStructure/>\n\
         </fmiModelDescription>\n"
    );
    assert_eq!(ModelDescription::from_xml(&xml).unwrap(), md);
}

#[test]
fn awkward_strings_round_trip() {
    let mut md = spring();
    let text = "tab\there, newline\nthere, cr\r, quotes \" ' and <&> , unicode µ°C ✓";
    md.description = Some(text.to_string());
    md.model_variables[0].description = Some(text.to_string());
    if let VariableType::String(s) = &mut md.model_variables[11].var_type {
        s.start = Some(text.to_string());
    }
    let xml = md.to_xml().unwrap();
    let back = ModelDescription::from_xml(&xml).unwrap();
    assert_eq!(back.description.as_deref(), Some(text));
    assert_eq!(back.model_variables[0].description.as_deref(), Some(text));
    assert_eq!(back.variable("label").unwrap().string_start(), Some(text));
}

#[test]
fn empty_and_absent_dependencies_differ() {
    let xml = spring().to_xml().unwrap();
    let back = ModelDescription::from_xml(&xml).unwrap();
    assert_eq!(back.model_structure.outputs[0].dependencies, Some(vec![]));
    assert_eq!(back.model_structure.outputs[2].dependencies, None);
    // An empty start string is a value, not a missing one.
    assert_eq!(back.variable("label").unwrap().string_start(), Some(""));
}

#[test]
fn serde_impls_match_to_xml_and_from_xml() {
    let md = spring();
    let via_serde = quick_xml::se::to_string_with_root("fmiModelDescription", &md).unwrap();
    let back: ModelDescription = quick_xml::de::from_str(&via_serde).unwrap();
    assert_eq!(back, md);
}

// ---------------------------------------------------------------------------------------------
// Reading descriptions written by other tools.
// ---------------------------------------------------------------------------------------------

/// In the style of the Reference FMUs' BouncingBall (FMI 2.0), plus the clutter real exports
/// carry: comments, a namespace declaration, vendor annotations, unknown attributes and
/// elements, per-variable annotations.
const BOUNCING_BALL: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<!-- Written by hand in the style of a third-party export. -->
<fmiModelDescription
  xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
  fmiVersion="2.0"
  modelName="BouncingBall"
  description="This model calculates the trajectory, over time, of a ball dropped from a height of 1 m."
  generationTool="Reference FMUs (hand-written fixture)"
  generationDateAndTime="2023-05-04T10:11:12Z"
  guid="{1AE5E10D-9521-4DE3-80B9-D0EAAA7D5AF1}"
  numberOfEventIndicators="1"
  vendorSpecificFlag="yes">

  <ModelExchange
    modelIdentifier="BouncingBall"
    canNotUseMemoryManagementFunctions="true"
    canGetAndSetFMUstate="true"
    canSerializeFMUstate="true">
    <SourceFiles>
      <File name="all.c"/>
    </SourceFiles>
  </ModelExchange>

  <CoSimulation
    modelIdentifier="BouncingBall"
    canHandleVariableCommunicationStepSize="true"
    canNotUseMemoryManagementFunctions="true"
    canGetAndSetFMUstate="true"
    canSerializeFMUstate="1"
    maxOutputDerivativeOrder="0"
    someFutureCapability="true">
    <SourceFiles>
      <File name="all.c"/>
    </SourceFiles>
  </CoSimulation>

  <UnitDefinitions>
    <Unit name="m">
      <BaseUnit m="1"/>
    </Unit>
    <Unit name="m/s">
      <BaseUnit m="1" s="-1"/>
      <DisplayUnit name="km/h" factor="3.6"/>
    </Unit>
    <Unit name="m/s2">
      <BaseUnit m="1" s="-2"/>
    </Unit>
    <Unit name="s">
      <BaseUnit s="1"/>
    </Unit>
  </UnitDefinitions>

  <TypeDefinitions>
    <SimpleType name="Position">
      <Real quantity="Position" unit="m"/>
    </SimpleType>
    <SimpleType name="Velocity">
      <Real quantity="Velocity" unit="m/s" displayUnit="km/h"/>
    </SimpleType>
    <SimpleType name="Acceleration">
      <Real quantity="Acceleration" unit="m/s2"/>
    </SimpleType>
  </TypeDefinitions>

  <LogCategories>
    <Category name="logEvents" description="Log events"/>
    <Category name="logStatusError" description="Log error messages"/>
  </LogCategories>

  <DefaultExperiment startTime="0" stopTime="3" stepSize="1e-2"/>

  <VendorAnnotations>
    <Tool name="SomeTool">
      <Settings solver="dassl"><Nested deep="true"/></Settings>
    </Tool>
  </VendorAnnotations>

  <ModelVariables>
    <!-- Index 1 -->
    <ScalarVariable name="time" valueReference="0" causality="independent" variability="continuous"
                    description="Simulation time">
      <Real unit="s"/>
    </ScalarVariable>
    <!-- Index 2 -->
    <ScalarVariable name="h" valueReference="1" causality="output" variability="continuous"
                    initial="exact" description="Position of the ball">
      <Real declaredType="Position" start="1"/>
      <Annotations>
        <Tool name="SomeTool"><Dialog group="States"/></Tool>
      </Annotations>
    </ScalarVariable>
    <!-- Index 3 -->
    <ScalarVariable name="der(h)" valueReference="2" causality="local" variability="continuous"
                    description="Derivative of h">
      <Real declaredType="Velocity" derivative="2"/>
    </ScalarVariable>
    <!-- Index 4 -->
    <ScalarVariable name="v" valueReference="3" causality="output" variability="continuous"
                    initial="exact" description="Velocity of the ball" futureAttribute="42">
      <Real declaredType="Velocity" start="0" reinit="true"/>
    </ScalarVariable>
    <!-- Index 5 -->
    <ScalarVariable name="der(v)" valueReference="4" causality="local" variability="continuous"
                    description="Derivative of v">
      <Real declaredType="Acceleration" derivative="4"/>
    </ScalarVariable>
    <!-- Index 6 -->
    <ScalarVariable name="g" valueReference="5" causality="parameter" variability="fixed"
                    initial="exact" description="Gravity acting on the ball">
      <Real declaredType="Acceleration" start="-9.81"/>
    </ScalarVariable>
    <!-- Index 7 -->
    <ScalarVariable name="e" valueReference="6" causality="parameter" variability="tunable"
                    description="Coefficient of restitution">
      <Real min="0.5" max="1" start="0.7"/>
    </ScalarVariable>
    <!-- Index 8 -->
    <ScalarVariable name="v_min" valueReference="7" variability="constant"
                    description="Velocity below which the ball stops bouncing">
      <Real declaredType="Velocity" start="0.1"/>
    </ScalarVariable>
  </ModelVariables>

  <ModelStructure>
    <Outputs>
      <Unknown index="2"/>
      <Unknown index="4"/>
    </Outputs>
    <Derivatives>
      <Unknown index="3" dependencies="4" dependenciesKind="constant"/>
      <Unknown index="5" dependencies=""/>
    </Derivatives>
    <InitialUnknowns>
      <Unknown index="3" dependencies="4"/>
      <Unknown index="5" dependencies="6"/>
    </InitialUnknowns>
  </ModelStructure>

</fmiModelDescription>
"#;

#[test]
fn reads_reference_style_bouncing_ball() {
    let md = ModelDescription::from_xml(BOUNCING_BALL).unwrap();
    assert_eq!(md.fmi_version, "2.0");
    assert_eq!(md.model_name, "BouncingBall");
    assert_eq!(md.guid, "{1AE5E10D-9521-4DE3-80B9-D0EAAA7D5AF1}");
    assert_eq!(md.number_of_event_indicators, Some(1));
    assert_eq!(md.generation_date_and_time.as_deref(), Some("2023-05-04T10:11:12Z"));
    assert_eq!(md.variable_naming_convention, None);

    let me = md.model_exchange.as_ref().unwrap();
    assert_eq!(me.common.model_identifier, "BouncingBall");
    assert!(me.common.can_get_and_set_fmu_state && !me.completed_integrator_step_not_needed);
    assert_eq!(me.common.source_files, vec!["all.c".to_string()]);

    let cs = md.co_simulation().unwrap();
    assert_eq!(cs.common.model_identifier, "BouncingBall");
    assert!(cs.can_handle_variable_communication_step_size);
    assert!(cs.common.can_serialize_fmu_state, "xs:boolean \"1\" is true");
    assert!(!cs.can_interpolate_inputs && !cs.common.needs_execution_tool && !cs.can_run_asynchronuously);
    assert_eq!(cs.max_output_derivative_order, 0);

    assert_eq!(md.unit_definitions.len(), 4);
    let mps = md.unit("m/s").unwrap();
    assert_eq!(mps.base_unit, Some(BaseUnit { m: 1, s: -1, ..BaseUnit::default() }));
    assert_eq!(mps.display_units, vec![DisplayUnit::new("km/h", 3.6, 0.0)]);
    assert_eq!(md.type_definitions.len(), 3);
    assert_eq!(md.simple_type("Velocity").unwrap().type_kind(), TypeKind::Real);
    assert_eq!(md.log_categories[1], Category::new("logStatusError", Some("Log error messages")));
    let experiment = md.default_experiment.as_ref().unwrap();
    assert_eq!((experiment.start_time, experiment.stop_time, experiment.step_size), (Some(0.0), Some(3.0), Some(0.01)));
    assert_eq!(experiment.tolerance, None);

    assert_eq!(md.model_variables.len(), 8);
    let h = md.variable("h").unwrap();
    assert_eq!(h.value_reference, 1);
    assert_eq!(h.type_kind(), TypeKind::Real);
    assert_eq!(h.real_start(), Some(1.0));
    assert_eq!(h.start(), Some(StartValue::Real(1.0)));
    assert_eq!(h.declared_type(), Some("Position"));
    assert_eq!(h.unit(), None);
    assert_eq!(md.unit_of(h), Some("m"), "unit comes from the declared type");
    let v = md.variable("v").unwrap();
    assert_eq!(md.display_unit_of(v), Some("km/h"));
    assert!(v.as_real().unwrap().reinit);
    assert_eq!(md.variable("der(v)").unwrap().derivative(), Some(4));
    assert_eq!(md.index_of("der(v)"), Some(5));
    assert_eq!(md.variable_by_index(5).unwrap().name, "der(v)");
    assert_eq!(md.variable_by_index(0), None);
    assert_eq!(md.variable("g").unwrap().real_start(), Some(-9.81));
    let e = md.variable("e").unwrap();
    assert_eq!((e.as_real().unwrap().attributes.min, e.as_real().unwrap().attributes.max), (Some(0.5), Some(1.0)));
    assert_eq!(e.variability(), Variability::Tunable);
    assert_eq!(e.initial, None);
    assert_eq!(e.initial(), Some(Initial::Exact), "parameters default to exact");

    // Defaults for absent attributes.
    let v_min = md.variable("v_min").unwrap();
    assert_eq!(v_min.causality, None);
    assert_eq!(v_min.causality(), Causality::Local);
    assert_eq!(v_min.variability(), Variability::Constant);
    assert_eq!(v_min.initial(), Some(Initial::Exact));
    let der_h = md.variable("der(h)").unwrap();
    assert_eq!(der_h.initial(), Some(Initial::Calculated));
    assert_eq!(md.variable("time").unwrap().initial(), None);

    let outputs: Vec<&str> = md.outputs().map(|v| v.name.as_str()).collect();
    assert_eq!(outputs, ["h", "v"]);
    let parameters: Vec<&str> = md.parameters().map(|v| v.name.as_str()).collect();
    assert_eq!(parameters, ["g", "e"]);
    assert_eq!(md.inputs().count(), 0);

    let ms = &md.model_structure;
    assert_eq!(ms.outputs, vec![Unknown::new(2), Unknown::new(4)]);
    assert_eq!(ms.derivatives[0].dependencies, Some(vec![4]));
    assert_eq!(ms.derivatives[0].dependencies_kind, Some(vec![DependencyKind::Constant]));
    assert_eq!(ms.derivatives[1].dependencies, Some(vec![]));
    assert_eq!(ms.initial_unknowns[1], Unknown::with_dependencies(5, vec![6]));

    assert_eq!(md.check(), Vec::<String>::new());
}

#[test]
fn reads_with_bom_and_crlf_line_endings() {
    let text = format!("\u{feff}{}", BOUNCING_BALL.replace('\n', "\r\n"));
    let md = ModelDescription::from_xml(&text).unwrap();
    assert_eq!(md.model_variables.len(), 8);
    assert_eq!(md, ModelDescription::from_xml(BOUNCING_BALL).unwrap());
}

#[test]
fn vendor_elements_between_list_items_are_skipped() {
    // Non-standard, but seen in the wild; serde alone would call the second run of
    // ScalarVariables a "duplicate field".
    let vendor = r#"<Vendor:Extra xmlns:Vendor="urn:x" flag="1"><Inner>text</Inner></Vendor:Extra>"#;
    let text = BOUNCING_BALL
        .replace("<!-- Index 4 -->", vendor)
        .replace("<Unit name=\"m/s\">", &format!("{vendor}<Unit name=\"m/s\">"))
        .replace("<DisplayUnit name=\"km/h\"", &format!("{vendor}<DisplayUnit name=\"km/h\""))
        .replace("<SimpleType name=\"Velocity\">", &format!("{vendor}<SimpleType name=\"Velocity\">"))
        .replace("<Category name=\"logStatusError\"", &format!("{vendor}<Category name=\"logStatusError\""))
        .replace("<Unknown index=\"4\"/>", &format!("{vendor}<Unknown index=\"4\"/>"))
        .replace("<File name=\"all.c\"/>", &format!("{vendor}<File name=\"all.c\"/>{vendor}"));
    assert_eq!(text.matches("Vendor:Extra xmlns").count(), 10, "every insertion point exists");
    assert_eq!(ModelDescription::from_xml(&text).unwrap(), ModelDescription::from_xml(BOUNCING_BALL).unwrap());
}

/// In the style of the Reference FMUs' Feedthrough: one variable of every type, an
/// Enumeration type, a Co-Simulation-only FMU, a Tool-specific child element at the root.
const FEEDTHROUGH: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Feedthrough" guid="{37B954F1-CC86-4D8F-B97F-C7C36F6670D2}"
  variableNamingConvention="structured" description="A model to test different variable types">
  <CoSimulation modelIdentifier="Feedthrough" canHandleVariableCommunicationStepSize="true"/>
  <TypeDefinitions>
    <SimpleType name="Option" description="An enumeration">
      <Enumeration>
        <Item name="Option 1" value="1" description="First option"/>
        <Item name="Option 2" value="2" description="Second option"/>
      </Enumeration>
    </SimpleType>
    <SimpleType name="Ints"><Integer min="-5" max="5"/></SimpleType>
    <SimpleType name="Bools"><Boolean/></SimpleType>
    <SimpleType name="Strings"><String/></SimpleType>
  </TypeDefinitions>
  <LogCategories>
    <Category name="logEvents"/>
  </LogCategories>
  <DefaultExperiment stopTime="2" tolerance="1E-4"/>
  <ModelVariables>
    <ScalarVariable name="time" valueReference="0" causality="independent"><Real/></ScalarVariable>
    <ScalarVariable name="real_fixed_parameter" valueReference="1" causality="parameter" variability="fixed">
      <Real start=" 2.5 "/>
    </ScalarVariable>
    <ScalarVariable name="real_continuous_input" valueReference="3" causality="input"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="real_continuous_output" valueReference="4" causality="output"><Real/></ScalarVariable>
    <ScalarVariable name="int_input" valueReference="5" causality="input" variability="discrete">
      <Integer declaredType="Ints" start="-3"/>
    </ScalarVariable>
    <ScalarVariable name="int_output" valueReference="6" causality="output" variability="discrete">
      <Integer/>
    </ScalarVariable>
    <ScalarVariable name="bool_input" valueReference="7" causality="input" variability="discrete">
      <Boolean start="false"/>
    </ScalarVariable>
    <ScalarVariable name="bool_output" valueReference="8" causality="output" variability="discrete">
      <Boolean/>
    </ScalarVariable>
    <ScalarVariable name="string_param" valueReference="9" causality="parameter" variability="fixed">
      <String start="Set me &amp; &quot;quote&quot; me&#x21;"/>
    </ScalarVariable>
    <ScalarVariable name="enum_input" valueReference="10" causality="input" variability="discrete">
      <Enumeration declaredType="Option" start="2"/>
    </ScalarVariable>
    <ScalarVariable name="enum_output" valueReference="11" causality="output" variability="discrete">
      <Enumeration declaredType="Option"/>
    </ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs>
      <Unknown index="4" dependencies="3" dependenciesKind="dependent"/>
      <Unknown index="6" dependencies="5"/>
      <Unknown index="8" dependencies="7"/>
      <Unknown index="11" dependencies="10"/>
    </Outputs>
    <InitialUnknowns>
      <Unknown index="4" dependencies="3"/>
      <Unknown index="6" dependencies="5"/>
      <Unknown index="8" dependencies="7"/>
      <Unknown index="11" dependencies="10"/>
    </InitialUnknowns>
  </ModelStructure>
  <Annotations><Tool name="future"/></Annotations>
</fmiModelDescription>"#;

#[test]
fn reads_every_variable_type() {
    let md = ModelDescription::from_xml(FEEDTHROUGH).unwrap();
    assert_eq!(md.variable_naming_convention, Some(VariableNamingConvention::Structured));
    assert!(md.model_exchange.is_none());
    assert_eq!(md.default_experiment.as_ref().unwrap().tolerance, Some(1e-4));
    assert_eq!(md.variable("real_fixed_parameter").unwrap().real_start(), Some(2.5));
    let int_input = md.variable("int_input").unwrap();
    assert_eq!(int_input.type_kind(), TypeKind::Integer);
    assert_eq!(int_input.integer_start(), Some(-3));
    assert_eq!(int_input.start(), Some(StartValue::Integer(-3)));
    assert_eq!(md.variable("bool_input").unwrap().boolean_start(), Some(false));
    assert_eq!(md.variable("bool_output").unwrap().boolean_start(), None);
    assert_eq!(
        md.variable("string_param").unwrap().string_start(),
        Some("Set me & \"quote\" me!"),
        "entities and character references are unescaped"
    );
    let enum_input = md.variable("enum_input").unwrap();
    assert_eq!(enum_input.type_kind(), TypeKind::Enumeration);
    assert_eq!(enum_input.type_kind().base_type(), TypeKind::Integer);
    assert_eq!(enum_input.integer_start(), Some(2));
    assert_eq!(enum_input.start(), Some(StartValue::Enumeration(2)));
    match &md.simple_type("Option").unwrap().kind {
        SimpleTypeKind::Enumeration(e) => {
            assert_eq!(e.items.len(), 2);
            assert_eq!(e.items[1].name, "Option 2");
            assert_eq!(e.items[1].value, 2);
            assert_eq!(e.items[0].description.as_deref(), Some("First option"));
        }
        other => panic!("expected an Enumeration, got {other:?}"),
    }
    assert_eq!(md.simple_type("Bools").unwrap().kind, SimpleTypeKind::Boolean);
    assert_eq!(md.simple_type("Strings").unwrap().kind, SimpleTypeKind::String);
    assert_eq!(
        md.simple_type("Ints").unwrap().kind,
        SimpleTypeKind::Integer(IntegerAttributes { quantity: None, min: Some(-5), max: Some(5) })
    );
    let outputs: Vec<&str> = md.outputs().map(|v| v.name.as_str()).collect();
    assert_eq!(outputs, ["real_continuous_output", "int_output", "bool_output", "enum_output"]);
    assert_eq!(md.check(), Vec::<String>::new());
    // And what we read, we can write and read back unchanged.
    assert_eq!(ModelDescription::from_xml(&md.to_xml().unwrap()).unwrap(), md);
}

#[test]
fn co_simulation_missing_is_a_clear_error() {
    let text = BOUNCING_BALL.replace("<CoSimulation", "<NotCoSimulation").replace("</CoSimulation>", "</NotCoSimulation>");
    let md = ModelDescription::from_xml(&text).unwrap();
    assert_eq!(md.co_simulation().unwrap_err().message(), "this FMU does not support Co-Simulation");
}

// ---------------------------------------------------------------------------------------------
// Reading errors.
// ---------------------------------------------------------------------------------------------

fn read_error(text: &str) -> String {
    match ModelDescription::from_xml(text) {
        Ok(md) => panic!("expected an error, read {md:?}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn missing_value_reference_names_the_variable() {
    let text = BOUNCING_BALL.replace(r#"name="g" valueReference="5""#, r#"name="g""#);
    assert_eq!(read_error(&text), "missing attribute valueReference on ScalarVariable 'g'");
}

#[test]
fn variable_without_type_element_names_the_variable() {
    let text = BOUNCING_BALL.replace(r#"<Real min="0.5" max="1" start="0.7"/>"#, "");
    assert_eq!(read_error(&text), "ScalarVariable 'e' has no type element (Real, Integer, Boolean, String or Enumeration)");
    let text = BOUNCING_BALL.replace(r#"<Real min="0.5" max="1" start="0.7"/>"#, r#"<Real start="1"/><Integer start="1"/>"#);
    assert!(read_error(&text).starts_with("ScalarVariable 'e' has more than one type element"));
}

#[test]
fn variable_without_name_is_located_by_position() {
    let text = BOUNCING_BALL.replace(r#"name="e" "#, "");
    assert_eq!(read_error(&text), "missing attribute name on ScalarVariable #7");
}

#[test]
fn wrong_fmi_version_is_rejected() {
    let text = BOUNCING_BALL.replace(r#"fmiVersion="2.0""#, r#"fmiVersion="3.0""#);
    assert_eq!(read_error(&text), "fmiVersion is 3.0, only FMI 2.0 is supported");
    let text = BOUNCING_BALL.replace(r#"fmiVersion="2.0""#, r#"fmiVersion="1.0""#);
    assert_eq!(read_error(&text), "fmiVersion is 1.0, only FMI 2.0 is supported");
    let text = BOUNCING_BALL.replace(r#"fmiVersion="2.0""#, "");
    assert_eq!(read_error(&text), "missing attribute fmiVersion on fmiModelDescription");
    // An FMI 3.0 file is rejected for its version, not for its different layout.
    let fmi3 = r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="BouncingBall" instantiationToken="{1AE5E10D}">
  <CoSimulation modelIdentifier="BouncingBall" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="h" valueReference="1" causality="output" start="1"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="1"/>
    <Output valueReference="1"/>
  </ModelStructure>
</fmiModelDescription>"#;
    assert_eq!(read_error(fmi3), "fmiVersion is 3.0, only FMI 2.0 is supported");
    // Maintenance releases keep the 2.0 schema.
    let text = BOUNCING_BALL.replace(r#"fmiVersion="2.0""#, r#"fmiVersion="2.0.4""#);
    assert!(ModelDescription::from_xml(&text).is_ok());
}

#[test]
fn malformed_xml_is_reported_with_a_position() {
    let text = BOUNCING_BALL.replace("</ModelStructure>", "</ModelStructur>");
    let message = read_error(&text);
    assert!(message.starts_with("malformed XML at line 137, column 3: "), "{message}");
    assert!(message.contains("ModelStructure"), "{message}");

    assert_eq!(
        read_error("<fmiModelDescription fmiVersion=\"2.0\">\n  <ModelVariables>"),
        "malformed XML: the document ends before <ModelVariables> (opened at line 2, column 3) is closed"
    );
    let message = read_error(&BOUNCING_BALL.replace("<CoSimulation", "<CoSimulation x=\"1\" x=\"2\""));
    assert!(message.starts_with("malformed XML at line 24, column 3: in the attributes of <CoSimulation>"), "{message}");
    assert!(message.contains("duplicated attribute"), "{message}");
    let message = read_error(&BOUNCING_BALL.replace("height of 1 m.", "height of 1 m & more"));
    assert!(message.starts_with("malformed XML at line 3, column 1: in the attributes of <fmiModelDescription>"), "{message}");

    let message = read_error("<fmiModelDescription fmiVersion=\"2.0 modelName=\"x\"/>");
    assert!(message.starts_with("malformed XML at line 1"), "{message}");

    assert_eq!(read_error("not xml at all"), "malformed XML at line 1, column 1: text outside the root element");
    assert!(read_error("").starts_with("malformed XML"));
    assert_eq!(
        read_error("<?xml version=\"1.0\"?>\n<html><body/></html>"),
        "root element is <html>, expected <fmiModelDescription> (not a modelDescription.xml)"
    );
}

#[test]
fn hostile_text_in_messages_is_escaped_and_cut() {
    // An escape sequence and a newline (character references are legal in attributes) would
    // reach the terminal as they are; a megabyte-long value would fill it.
    let text = BOUNCING_BALL.replace(r#"name="g" valueReference="5""#, r#"name="g" valueReference="&#27;[2J&#10;5""#);
    assert_eq!(read_error(&text), "attribute valueReference=\"\\u{1b}[2J\\n5\" on ScalarVariable 'g' is not an unsigned integer");
    let long = "9".repeat(1 << 20);
    let text = BOUNCING_BALL.replace(r#"name="g" valueReference="5""#, &format!(r#"name="g" valueReference="x{long}""#));
    let message = read_error(&text);
    assert!(message.starts_with("attribute valueReference=\"x999") && message.ends_with("... (cut)"), "{}", &message[..80]);
    assert_eq!(message.chars().count(), 1000 + "... (cut)".len());
    // Clean messages pass unchanged.
    assert_eq!(printable("plain".to_owned()), "plain");
}

#[test]
fn bad_attribute_values_name_element_and_attribute() {
    let text = BOUNCING_BALL.replace(r#"start="-9.81""#, r#"start="-9.81 m/s2""#);
    assert_eq!(read_error(&text), "attribute start=\"-9.81 m/s2\" on ScalarVariable 'g' (Real) is not a number");
    let text = BOUNCING_BALL.replace(r#"causality="parameter" variability="tunable""#, r#"causality="knob" variability="tunable""#);
    let message = read_error(&text);
    assert!(message.starts_with("attribute causality on ScalarVariable 'e': 'knob' is not a valid causality"), "{message}");
    let text = BOUNCING_BALL.replace(r#"name="g" valueReference="5""#, r#"name="g" valueReference="-5""#);
    assert_eq!(read_error(&text), "attribute valueReference=\"-5\" on ScalarVariable 'g' is not an unsigned integer");
    let text = BOUNCING_BALL.replace(r#"reinit="true""#, r#"reinit="yes""#);
    assert_eq!(read_error(&text), "attribute reinit=\"yes\" on ScalarVariable 'v' (Real) is not a boolean (true or false)");
    let text = BOUNCING_BALL.replace(r#"dependencies="4" dependenciesKind="constant""#, r#"dependencies="4 x""#);
    assert_eq!(read_error(&text), "attribute dependencies on ModelStructure/Derivatives/Unknown #1: 'x' is not a variable index");
    let text = BOUNCING_BALL.replace(r#"<BaseUnit m="1" s="-2"/>"#, r#"<BaseUnit m="one"/>"#);
    assert_eq!(read_error(&text), "attribute m=\"one\" on BaseUnit of Unit 'm/s2' is not an integer");
    let text = BOUNCING_BALL.replace(
        r#"<CoSimulation
    modelIdentifier="BouncingBall""#,
        "<CoSimulation",
    );
    assert_eq!(read_error(&text), "missing attribute modelIdentifier on CoSimulation");
    let text = BOUNCING_BALL.replace("<ModelVariables>", "<Variables>").replace("</ModelVariables>", "</Variables>");
    assert_eq!(read_error(&text), "missing element ModelVariables in fmiModelDescription");
}

// ---------------------------------------------------------------------------------------------
// Defaults from the standard's tables.
// ---------------------------------------------------------------------------------------------

#[test]
fn initial_defaults_follow_the_standard_table() {
    use Causality as C;
    use Variability as V;
    let cases = [
        (C::Parameter, V::Fixed, Some(Initial::Exact)),
        (C::Parameter, V::Tunable, Some(Initial::Exact)),
        (C::CalculatedParameter, V::Fixed, Some(Initial::Calculated)),
        (C::Input, V::Continuous, None),
        (C::Input, V::Discrete, None),
        (C::Output, V::Constant, Some(Initial::Exact)),
        (C::Output, V::Continuous, Some(Initial::Calculated)),
        (C::Local, V::Constant, Some(Initial::Exact)),
        (C::Local, V::Tunable, Some(Initial::Calculated)),
        (C::Local, V::Discrete, Some(Initial::Calculated)),
        (C::Independent, V::Continuous, None),
    ];
    for (c, v, initial) in cases {
        assert!(c.allows(v), "{c} {v}");
        assert_eq!(Initial::default_for(c, v), initial, "{c} {v}");
    }
    for (c, v) in [
        (C::Parameter, V::Constant),
        (C::Parameter, V::Continuous),
        (C::CalculatedParameter, V::Discrete),
        (C::Input, V::Fixed),
        (C::Output, V::Tunable),
        (C::Independent, V::Discrete),
    ] {
        assert!(!c.allows(v), "{c} {v}");
        assert_eq!(Initial::default_for(c, v), None);
    }
    assert_eq!(Initial::allowed_for(C::CalculatedParameter, V::Tunable), &[Initial::Approx, Initial::Calculated]);
    assert_eq!(Initial::allowed_for(C::Local, V::Continuous).len(), 3);
    assert_eq!(Causality::default(), C::Local);
    assert_eq!(Variability::default(), V::Continuous);
    let bare = ScalarVariable::new("x", 0, VariableType::Real(RealVariable::default()));
    assert_eq!((bare.causality(), bare.variability(), bare.initial()), (C::Local, V::Continuous, Some(Initial::Calculated)));
}

// ---------------------------------------------------------------------------------------------
// check(): each kind of problem on a crafted bad description.
// ---------------------------------------------------------------------------------------------

fn var<'a>(md: &'a mut ModelDescription, name: &str) -> &'a mut ScalarVariable {
    md.model_variables.iter_mut().find(|v| v.name == name).unwrap()
}

fn real_of<'a>(md: &'a mut ModelDescription, name: &str) -> &'a mut RealVariable {
    match &mut var(md, name).var_type {
        VariableType::Real(r) => r,
        _ => panic!("{name} is not Real"),
    }
}

/// Applies `breakage` to the clean description and expects a problem containing `expected`.
fn assert_problem(breakage: impl FnOnce(&mut ModelDescription), expected: &str) {
    let mut md = spring();
    breakage(&mut md);
    let problems = md.check();
    assert!(problems.iter().any(|p| p.contains(expected)), "expected a problem containing {expected:?}, got {problems:#?}");
}

#[test]
fn check_finds_duplicate_names_and_value_references() {
    assert_problem(|md| var(md, "v").name = "x".to_string(), "variable name 'x' is not unique (indices 2 and 4)");
    assert_problem(|md| var(md, "v").name = "v\nw".to_string(), "variable name \"v\\nw\" (index 4) contains a line feed");
    assert_problem(|md| var(md, "F").value_reference = 1, "Real value reference 1 is used by both 'x' (index 2) and 'F' (index 7)");
    // Integer and Enumeration share fmi2GetInteger's reference space.
    assert_problem(|md| var(md, "mode").value_reference = 0, "Integer value reference 0 is used by both 'steps'");
    // Different base types may share a number.
    let md = spring();
    assert_eq!(md.variable("time").unwrap().value_reference, md.variable("steps").unwrap().value_reference);
    assert!(md.check().is_empty());
}

#[test]
fn check_finds_bad_model_structure_indices() {
    assert_problem(
        |md| md.model_structure.outputs.push(Unknown::new(99)),
        "ModelStructure/Outputs/Unknown #4 (index 99) does not point at a variable (indices are 1-based, 1..=13)",
    );
    assert_problem(|md| md.model_structure.derivatives[0].index = 0, "Derivatives/Unknown #1 (index 0) does not point");
    assert_problem(
        |md| md.model_structure.initial_unknowns[0].dependencies = Some(vec![14]),
        "has dependency 14, which is not a variable index",
    );
    assert_problem(
        |md| md.model_structure.derivatives[1].dependencies_kind = Some(vec![DependencyKind::Fixed]),
        "has 2 dependencies but 1 dependenciesKind entries",
    );
    assert_problem(|md| md.model_structure.outputs[2].dependencies_kind = Some(vec![]), "has dependenciesKind without dependencies");
    assert_problem(|md| md.model_structure.outputs.push(Unknown::new(2)), "(index 2) is listed more than once");
}

#[test]
fn check_finds_wrong_outputs_list() {
    assert_problem(
        |md| {
            md.model_structure.outputs.remove(1);
        },
        "ModelStructure/Outputs is missing v",
    );
    assert_problem(|md| md.model_structure.outputs.push(Unknown::new(6)), "ModelStructure/Outputs must not list k");
}

#[test]
fn check_finds_wrong_initial_unknowns() {
    assert_problem(
        |md| {
            md.model_structure.initial_unknowns.remove(2);
        },
        "InitialUnknowns is missing energy",
    );
    // An output with initial approx must be listed too.
    assert_problem(|md| var(md, "x").initial = Some(Initial::Approx), "InitialUnknowns is missing x");
    assert_problem(|md| md.model_structure.initial_unknowns.insert(0, Unknown::new(2)), "InitialUnknowns must not list x");
    assert_problem(|md| md.model_structure.initial_unknowns.swap(0, 1), "InitialUnknowns is not sorted");
    assert_problem(
        |md| md.model_structure.derivatives.push(Unknown::new(2)),
        "Derivatives lists 'x' (index 2), which has no derivative attribute",
    );
}

#[test]
fn check_finds_missing_and_forbidden_start_values() {
    assert_problem(
        |md| real_of(md, "k").start = None,
        "variable 'k' (index 6) has initial=\"exact\" (the default for its causality and variability) but no start value",
    );
    assert_problem(|md| real_of(md, "F").start = None, "variable 'F' (index 7) has causality=\"input\" but no start value");
    assert_problem(|md| real_of(md, "T").start = None, "has initial=\"approx\" but no start value");
    assert_problem(
        |md| real_of(md, "energy").start = Some(1.0),
        "variable 'energy' (index 8) has initial=\"calculated\" (the default for its causality and variability) but provides a start value",
    );
    assert_problem(|md| real_of(md, "time").start = Some(0.0), "has causality=\"independent\" but provides a start value");
}

#[test]
fn check_finds_illegal_causality_variability_initial() {
    assert_problem(
        |md| var(md, "k").variability = Some(Variability::Continuous),
        "variable 'k' (index 6): the combination causality=\"parameter\" and variability=\"continuous\" is not allowed",
    );
    assert_problem(
        |md| var(md, "F").variability = Some(Variability::Fixed),
        "causality=\"input\" and variability=\"fixed\" is not allowed",
    );
    assert_problem(
        |md| var(md, "F").initial = Some(Initial::Exact),
        "variable 'F' (index 7) has causality=\"input\" and must not define initial",
    );
    assert_problem(
        |md| var(md, "k").initial = Some(Initial::Calculated),
        "initial=\"calculated\" is not allowed with causality=\"parameter\" and variability=\"fixed\" (allowed: exact)",
    );
    assert_problem(
        |md| var(md, "steps").variability = None,
        "variable 'steps' (index 9) is of type Integer and must not have variability=\"continuous\" (the default",
    );
    assert_problem(
        |md| {
            let time = md.model_variables[0].clone();
            md.model_variables[0].name = "t".to_string();
            md.model_variables.push(ScalarVariable { value_reference: 100, ..time });
        },
        "more than one variable has causality=\"independent\": t, time",
    );
}

#[test]
fn check_finds_unit_problems() {
    assert_problem(
        |md| real_of(md, "k").attributes.unit = Some("furlong".to_string()),
        "variable 'k' (index 6) has unit \"furlong\", which is not defined in UnitDefinitions",
    );
    assert_problem(
        |md| real_of(md, "v").attributes.display_unit = Some("mph".to_string()),
        "variable 'v' (index 4) has displayUnit \"mph\", which is not a DisplayUnit of unit \"m/s\"",
    );
    assert_problem(
        |md| real_of(md, "der(x)").attributes.display_unit = Some("mm".to_string()),
        "has displayUnit \"mm\", which is not a DisplayUnit of unit \"m/s\"",
    );
    assert_problem(
        |md| {
            let energy = real_of(md, "energy");
            energy.attributes.unit = None;
            energy.attributes.display_unit = Some("kWh".to_string());
        },
        "variable 'energy' (index 8) has displayUnit \"kWh\" but no unit",
    );
    // Units reached through a declared type count too.
    assert_problem(
        |md| md.unit_definitions.retain(|u| u.name != "m"),
        "variable 'x' (index 2) has unit \"m\", which is not defined in UnitDefinitions",
    );
    assert_problem(
        |md| md.unit_definitions.retain(|u| u.name != "m"),
        "SimpleType 'Position' has unit \"m\", which is not defined in UnitDefinitions",
    );
    assert_problem(
        |md| md.unit_definitions[2].display_units.push(DisplayUnit::new("km/h", 1.0, 0.0)),
        "DisplayUnit name in unit \"m/s\" \"km/h\" is not unique",
    );
}

#[test]
fn check_finds_declared_type_and_derivative_problems() {
    assert_problem(
        |md| real_of(md, "x").declared_type = Some("Nope".to_string()),
        "variable 'x' (index 2) has declaredType \"Nope\", which is not in TypeDefinitions",
    );
    assert_problem(
        |md| real_of(md, "x").declared_type = Some("Mode".to_string()),
        "variable 'x' (index 2) is Real but its declaredType \"Mode\" is of type Enumeration",
    );
    assert_problem(
        |md| {
            if let VariableType::Enumeration(e) = &mut var(md, "mode").var_type {
                e.declared_type = None;
            }
        },
        "variable 'mode' (index 11) is an Enumeration without the required declaredType",
    );
    assert_problem(
        |md| real_of(md, "der(x)").derivative = Some(99),
        "variable 'der(x)' (index 3) has derivative=\"99\", which is not a variable index (1..=13)",
    );
    assert_problem(|md| real_of(md, "der(x)").derivative = Some(9), "pointing at non-Real variable 'steps'");
}

#[test]
fn check_finds_range_problems() {
    assert_problem(|md| real_of(md, "x").attributes.min = Some(20.0), "variable 'x' (index 2) has min=20 greater than max=10");
    assert_problem(|md| real_of(md, "x").start = Some(11.0), "variable 'x' (index 2) has start=11 outside [min, max] = [-10, 10]");
    assert_problem(|md| real_of(md, "x").attributes.nominal = Some(0.0), "has nominal=0, must be > 0");
    // Bounds inherited from the declared type count too (Count has min=0).
    assert_problem(
        |md| {
            if let VariableType::Integer(i) = &mut var(md, "steps").var_type {
                i.start = Some(-1);
            }
        },
        "variable 'steps' (index 9) has start=-1 outside [min, max] = [0, -]",
    );
    assert_problem(
        |md| {
            if let VariableType::Enumeration(e) = &mut var(md, "mode").var_type {
                e.start = Some(3);
            }
        },
        "variable 'mode' (index 11) has start=3 outside [min, max] = [1, 2]",
    );
}

#[test]
fn check_finds_header_and_experiment_problems() {
    assert_problem(
        |md| {
            md.model_exchange = None;
            md.co_simulation = None;
        },
        "neither ModelExchange nor CoSimulation is present",
    );
    assert_problem(
        |md| md.co_simulation.as_mut().unwrap().common.model_identifier = "my model".to_string(),
        "CoSimulation modelIdentifier \"my model\" is not a valid C identifier",
    );
    assert_problem(|md| md.fmi_version = "3.0".to_string(), "fmiVersion is \"3.0\", must be \"2.0\"");
    assert_problem(
        |md| md.default_experiment.as_mut().unwrap().stop_time = Some(0.0),
        "DefaultExperiment stopTime=0 is not greater than startTime=0",
    );
    assert_problem(|md| md.default_experiment.as_mut().unwrap().step_size = Some(-1.0), "DefaultExperiment stepSize=-1 must be > 0");
    assert_problem(|md| md.log_categories.push(Category::new("logEvents", None)), "log category name \"logEvents\" is not unique");
}

#[test]
fn check_reports_every_problem_at_once() {
    let mut md = spring();
    real_of(&mut md, "k").start = None;
    real_of(&mut md, "k").attributes.unit = Some("furlong".to_string());
    md.model_structure.outputs.clear();
    let problems = md.check();
    assert_eq!(problems.len(), 3, "{problems:#?}");
}

/// `check_by_rule` tags each problem with the rule and variable it concerns, and its messages
/// are exactly `check`'s.
#[test]
fn check_by_rule_tags_each_problem() {
    let mut md = spring();
    real_of(&mut md, "k").start = None;
    real_of(&mut md, "k").attributes.unit = Some("furlong".to_string());
    real_of(&mut md, "x").start = Some(11.0);
    md.unit_definitions.retain(|u| u.name != "m");
    md.model_structure.outputs.clear();
    let tagged = md.check_by_rule();
    assert_eq!(tagged.iter().map(|p| p.message.clone()).collect::<Vec<_>>(), md.check());
    let rule_of = |text: &str| {
        let p = tagged.iter().find(|p| p.message.contains(text)).unwrap_or_else(|| panic!("no problem with {text:?}: {tagged:#?}"));
        (p.rule, p.variable.clone())
    };
    assert_eq!(rule_of("'k' (index 6) has initial=\"exact\""), (Rule::Start, Some("k".to_string())));
    assert_eq!(rule_of("unit \"furlong\""), (Rule::Units, Some("k".to_string())));
    assert_eq!(rule_of("start=11 outside"), (Rule::Ranges, Some("x".to_string())));
    assert_eq!(rule_of("SimpleType 'Position' has unit \"m\""), (Rule::Units, None));
    assert_eq!(rule_of("ModelStructure/Outputs is missing"), (Rule::ModelStructure, None));
}
