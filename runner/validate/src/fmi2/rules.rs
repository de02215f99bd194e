//! The static checks of an FMI 2.0 modelDescription.xml: the schema's `check()` (fmpy's
//! rules and neighbours), grouped by rule, plus what it does not cover: ModelStructure lists
//! and dependencies that match the causalities, and the GUID's format.

use std::collections::HashSet;

use fmi_schema::fmi2::{self as s, Causality, Initial, Rule, Variability};

use crate::report::Finding;

/// The check each of the schema's rules reports under.
fn check_of(rule: Rule) -> &'static str {
    match rule {
        Rule::Initial => "description.initial",
        Rule::Ranges => "description.start-range",
        Rule::Units => "description.units",
        Rule::ModelStructure | Rule::Derivative => "description.model-structure",
        Rule::Header | Rule::Names | Rule::Start | Rule::DeclaredType | Rule::Definitions | Rule::DefaultExperiment => "description.rules",
    }
}

/// What each check covers, for its passed entry.
const PASSED: [(&str, &str); 6] = [
    (
        "description.rules",
        "fmpy's rules: header, unique names and value references, start values, declared types, definitions, DefaultExperiment",
    ),
    (
        "description.model-structure",
        "Outputs, Derivatives and InitialUnknowns match the causalities, and their dependencies name only knowns",
    ),
    ("description.units", "every unit and display unit used is defined"),
    ("description.start-range", "every start value lies within its min and max"),
    ("description.initial", "every initial suits its causality and variability"),
    ("description.guid", "the GUID has the usual {8-4-4-4-12} hexadecimal form"),
];

/// All static checks of `md`.
pub(crate) fn check(md: &s::ModelDescription, findings: &mut Vec<Finding>) {
    let mut found: Vec<Finding> = md
        .check_by_rule()
        .into_iter()
        .map(|p| {
            let f = Finding::error(check_of(p.rule), p.message);
            match p.variable {
                Some(v) => f.variable(v),
                None => f,
            }
        })
        .collect();
    model_structure(md, &mut found);
    guid(&md.guid, &mut found);
    let troubled: HashSet<String> = found.iter().map(|f| f.check.clone()).collect();
    findings.extend(found);
    for (check, what) in PASSED {
        if !troubled.contains(check) {
            findings.push(Finding::passed(check, what));
        }
    }
}

/// The GUID: a non-empty string without surrounding blanks or control characters (an error:
/// fmi2Instantiate compares it as given), and, as a warning, the brace-wrapped GUID form that
/// every major exporter writes.
fn guid(guid: &str, findings: &mut Vec<Finding>) {
    let shown = fmi_schema::escaped_and_cut(guid, 100, "...");
    if guid.is_empty() {
        // check() reports the empty GUID.
        return;
    }
    if guid.trim() != guid || guid.chars().any(char::is_control) {
        findings.push(
            Finding::error(
                "description.guid",
                "the GUID has surrounding blanks or control characters, which importers may strip before fmi2Instantiate compares it",
            )
            .value(shown),
        );
        return;
    }
    let inner = guid.strip_prefix('{').and_then(|g| g.strip_suffix('}')).unwrap_or(guid);
    let groups: Vec<&str> = inner.split('-').collect();
    let well_formed =
        groups.len() == 5 && groups.iter().zip([8, 4, 4, 4, 12]).all(|(g, n)| g.len() == n && g.chars().all(|c| c.is_ascii_hexdigit()));
    if !well_formed {
        findings.push(
            Finding::warning(
                "description.guid",
                "the GUID is not of the form {xxxxxxxx-xxxx-xxxx-xxxx-xxxxxxxxxxxx}: the standard allows any string, but tools expect a GUID",
            )
            .value(shown),
        );
    }
}

/// What the schema's check leaves out of ModelStructure.
fn model_structure(md: &s::ModelDescription, findings: &mut Vec<Finding>) {
    const CHECK: &str = "description.model-structure";
    let count = md.model_variables.len() as u32;
    let var = |index: u32| md.variable_by_index(index);
    let listed: HashSet<u32> = md.model_structure.derivatives.iter().map(|u| u.index).collect();
    // Model Exchange must expose every state derivative (2.2.8): a Real with `derivative` that
    // is not listed would be a state the importer never integrates.
    if md.model_exchange.is_some() {
        for (i, v) in md.model_variables.iter().enumerate() {
            let index = i as u32 + 1;
            if v.derivative().is_some() && !listed.contains(&index) {
                findings.push(
                    Finding::error(
                        CHECK,
                        format!(
                            "'{}' (index {index}) is a state derivative (it has a derivative attribute) but ModelStructure/Derivatives does not list it; a Model Exchange FMU must list all",
                            v.name
                        ),
                    )
                    .variable(v.name.clone()),
                );
            }
        }
    }
    let states: HashSet<u32> = md.model_structure.derivatives.iter().filter_map(|u| var(u.index)?.derivative()).collect();
    // Dependencies of Outputs and Derivatives: the knowns at a communication point or in
    // Event and Continuous-Time Mode (inputs, continuous states, the independent variable,
    // tunable parameters; section 2.2.8); fixed ones "are not shown".
    for (list, unknowns) in [("Outputs", &md.model_structure.outputs), ("Derivatives", &md.model_structure.derivatives)] {
        for unknown in unknowns {
            let Some(dependencies) = &unknown.dependencies else { continue };
            let Some(of) = var(unknown.index) else { continue };
            for &d in dependencies {
                let Some(known) = var(d).filter(|_| d >= 1 && d <= count) else { continue };
                let is_known = known.causality() == Causality::Input
                    || known.causality() == Causality::Independent
                    || states.contains(&d)
                    || (known.causality() == Causality::Parameter && known.variability() == Variability::Tunable);
                let fixed = matches!(known.variability(), Variability::Fixed | Variability::Constant)
                    && matches!(known.causality(), Causality::Parameter | Causality::CalculatedParameter | Causality::Local);
                let text = format!(
                    "ModelStructure/{list}: '{}' lists '{}' (index {d}, causality {}, variability {}) as a dependency",
                    of.name,
                    known.name,
                    known.causality(),
                    known.variability()
                );
                if fixed {
                    findings.push(
                        Finding::warning(
                            CHECK,
                            format!("{text}; dependencies on values fixed after initialization are not shown (section 2.2.8)"),
                        )
                        .variable(of.name.clone()),
                    );
                } else if !is_known {
                    findings.push(
                        Finding::error(CHECK, format!("{text}, but these dependencies may name only inputs, continuous states, the independent variable and tunable parameters"))
                            .variable(of.name.clone()),
                    );
                }
            }
        }
    }
    // InitialUnknowns depend on inputs, the start time and variables with initial="exact".
    for unknown in &md.model_structure.initial_unknowns {
        let (Some(dependencies), Some(of)) = (&unknown.dependencies, var(unknown.index)) else { continue };
        for &d in dependencies {
            let Some(known) = var(d).filter(|_| d >= 1 && d <= count) else { continue };
            let is_known =
                matches!(known.causality(), Causality::Input | Causality::Independent) || known.initial() == Some(Initial::Exact);
            if !is_known {
                findings.push(
                    Finding::error(
                        CHECK,
                        format!(
                            "ModelStructure/InitialUnknowns: '{}' lists '{}' (index {d}, causality {}, initial {}) as a dependency, but it may name only inputs, the independent variable and variables with initial=\"exact\"",
                            of.name,
                            known.name,
                            known.causality(),
                            known.initial().map_or("none".to_owned(), |i| i.to_string())
                        ),
                    )
                    .variable(of.name.clone()),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checks(xml_variables: &str, structure: &str) -> Vec<Finding> {
        let xml = format!(
            r#"<fmiModelDescription fmiVersion="2.0" modelName="m" guid="{{8c4e810f-3df3-4a00-8276-176fa3c9f000}}">
  <ModelExchange modelIdentifier="m"/>
  <ModelVariables>{xml_variables}</ModelVariables>
  <ModelStructure>{structure}</ModelStructure>
</fmiModelDescription>"#
        );
        let md = s::ModelDescription::from_xml(&xml).unwrap();
        let mut findings = Vec::new();
        check(&md, &mut findings);
        findings
    }

    const VARIABLES: &str = r#"
    <ScalarVariable name="x" valueReference="0" causality="output" initial="exact"><Real start="1"/></ScalarVariable>
    <ScalarVariable name="der(x)" valueReference="1"><Real derivative="1"/></ScalarVariable>
    <ScalarVariable name="k" valueReference="2" causality="parameter" variability="fixed"><Real start="1"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="3" causality="output"><Real/></ScalarVariable>
    <ScalarVariable name="p" valueReference="4" causality="parameter" variability="tunable"><Real start="1"/></ScalarVariable>"#;

    fn troubles(findings: &[Finding]) -> Vec<(crate::report::Severity, String)> {
        findings.iter().filter(|f| f.severity < crate::report::Severity::Passed).map(|f| (f.severity, f.message.clone())).collect()
    }

    #[test]
    fn a_clean_description_passes_every_rule() {
        let structure = r#"<Outputs><Unknown index="1" dependencies=""/><Unknown index="4" dependencies="1 5"/></Outputs>
          <Derivatives><Unknown index="2" dependencies="1"/></Derivatives>
          <InitialUnknowns><Unknown index="2" dependencies="1 3"/><Unknown index="4"/></InitialUnknowns>"#;
        let findings = checks(VARIABLES, structure);
        assert_eq!(troubles(&findings), vec![]);
        assert_eq!(findings.len(), PASSED.len());
    }

    #[test]
    fn model_structure_dependencies_must_name_knowns() {
        use crate::report::Severity::*;
        let structure = r#"<Outputs><Unknown index="1"/><Unknown index="4" dependencies="3 2"/></Outputs>
          <InitialUnknowns><Unknown index="2" dependencies="4"/><Unknown index="4"/></InitialUnknowns>"#;
        let found = troubles(&checks(VARIABLES, structure));
        assert!(found.iter().any(|(s, m)| *s == Error && m.contains("'der(x)' (index 2) is a state derivative")), "{found:#?}");
        assert!(found.iter().any(|(s, m)| *s == Warning && m.contains("'y' lists 'k' (index 3")), "a fixed parameter: {found:#?}");
        assert!(found.iter().any(|(s, m)| *s == Error && m.contains("'y' lists 'der(x)' (index 2")), "a local: {found:#?}");
        assert!(found.iter().any(|(s, m)| *s == Error && m.contains("InitialUnknowns: 'der(x)' lists 'y'")), "{found:#?}");
    }

    #[test]
    fn guids_are_checked_for_form() {
        let mut f = Vec::new();
        guid("{1AE5E10D-9521-4DE3-80B9-D0EAAA7D5AF1}", &mut f);
        guid("8c4e810f-3df3-4a00-8276-176fa3c9f000", &mut f);
        assert!(f.is_empty(), "{f:#?}");
        guid("my-model-v1", &mut f);
        assert_eq!(f.pop().map(|f| f.severity), Some(crate::report::Severity::Warning));
        guid(" {8c4e810f-3df3-4a00-8276-176fa3c9f000}", &mut f);
        assert_eq!(f.pop().map(|f| f.severity), Some(crate::report::Severity::Error));
    }
}
