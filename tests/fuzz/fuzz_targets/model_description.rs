//! Fuzzes the modelDescription.xml readers (FMI 2.0 and 3.0), which see whatever FMU a user
//! hands the runner.
//!
//! Reading must never panic, hang or blow up; a description that reads must pass through the
//! checker, and write and read back to the same description (our writer's output must be
//! readable by our reader, and nothing may be lost on the way).

#![no_main]

use fmi_schema::fmi2::ModelDescription;
use libfuzzer_sys::fuzz_target;

/// The FMI 3.0 reader, the same round trip.
fn fmi3(text: &str) {
    let Ok(description) = fmi_schema::fmi3::ModelDescription::from_xml(text) else { return };
    let _ = description.check();
    let xml = description.to_xml();
    let again =
        fmi_schema::fmi3::ModelDescription::from_xml(&xml).unwrap_or_else(|e| panic!("our own FMI 3.0 XML does not read back: {e}\n{xml}"));
    if again != description {
        assert_eq!(format!("{again:#?}"), format!("{description:#?}"), "the FMI 3.0 round trip changed the description\n{xml}");
    }
    assert_eq!(again.to_xml(), xml, "FMI 3.0 writing is not stable across a round trip");
}

fuzz_target!(|data: &[u8]| {
    // The runner reads the file with read_to_string, so only UTF-8 ever reaches from_xml.
    let Ok(text) = std::str::from_utf8(data) else { return };
    if fmi_schema::fmi_version(text).is_ok_and(|v| v.starts_with("3.")) {
        return fmi3(text);
    }
    let Ok(description) = ModelDescription::from_xml(text) else { return };
    let _ = description.check();
    let _ = description.co_simulation();

    let xml = description.to_xml().unwrap_or_else(|e| panic!("a description that was read cannot be written: {e}"));
    let again = ModelDescription::from_xml(&xml).unwrap_or_else(|e| panic!("our own XML does not read back: {e}\n{xml}"));
    // NaN != NaN under PartialEq; Debug prints every NaN alike but keeps -0.0 apart from 0.0,
    // so it is the stricter comparison whenever the derived one disagrees.
    if again != description {
        assert_eq!(format!("{again:#?}"), format!("{description:#?}"), "the round trip changed the description\n{xml}");
    }
    let xml_again = again.to_xml().unwrap_or_else(|e| panic!("the re-read description cannot be written: {e}"));
    assert_eq!(xml_again, xml, "writing is not stable across a round trip");
});
