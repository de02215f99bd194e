//! The static checks of an FMI 3.0 modelDescription.xml: the schema's `check()` (its rules in
//! one group) and the instantiationToken.

use fmi_schema::fmi3 as s;

use crate::report::Finding;

/// The description's static checks: the schema's rules and the instantiationToken.
pub(crate) fn check(md: &s::ModelDescription, findings: &mut Vec<Finding>) {
    let problems = md.check();
    for p in &problems {
        findings.push(Finding::error("description.rules", p.clone()));
    }
    if problems.is_empty() {
        findings.push(Finding::passed(
            "description.rules",
            "the schema's rules: header, unique names and value references, causality, variability and initial, start values, units, types, array dimensions, ModelStructure",
        ));
    }
    let token = &md.instantiation_token;
    if token.trim().is_empty() {
        findings.push(Finding::error(
            "description.token",
            "instantiationToken is empty: it is a mandatory attribute the FMU may check at instantiation",
        ));
    } else if token.trim() != token || token.chars().any(char::is_control) {
        findings.push(
            Finding::error(
                "description.token",
                "instantiationToken has surrounding blanks or control characters, which importers may strip before passing it",
            )
            .value(fmi_schema::escaped_and_cut(token, 100, "...")),
        );
    } else {
        findings.push(Finding::passed("description.token", "instantiationToken is a non-empty string without surrounding blanks"));
    }
    if !(md.fmi_version == "3.0" || md.fmi_version.starts_with("3.0.")) {
        findings.push(Finding::error("description.rules", format!("fmiVersion is {:?}; FMI 3.0 descriptions say \"3.0\"", md.fmi_version)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn findings(token: &str, version: &str) -> Vec<Finding> {
        let xml = format!(
            r#"<fmiModelDescription fmiVersion="{version}" modelName="m" instantiationToken="{token}"><CoSimulation modelIdentifier="m"/><ModelVariables/><ModelStructure/></fmiModelDescription>"#
        );
        let mut found = Vec::new();
        check(&s::ModelDescription::from_xml(&xml).unwrap(), &mut found);
        found
    }

    #[test]
    fn the_token_must_be_usable_as_given() {
        let severity = |found: &[Finding]| found.iter().find(|f| f.check == "description.token").map(|f| f.severity);
        assert_eq!(severity(&findings("{abc}", "3.0")), Some(crate::report::Severity::Passed));
        assert_eq!(severity(&findings("", "3.0")), Some(crate::report::Severity::Error));
        assert!(findings("{a\u{1}b}", "3.0").iter().any(|f| f.check == "description.token" && f.value.as_deref() == Some("{a\\u{1}b}")));
    }
}
