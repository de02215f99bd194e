//! Model descriptions that crashed the `model_description` fuzz target, and the hand-made
//! hostile ones it was seeded with (see fuzz/src/seeds.rs), replayed through the reader.
//!
//! For every file in `tests/fuzz_regressions/`: reading must not panic; a description that
//! reads must survive `check`, `co_simulation` and a write/read round trip unchanged. Files
//! other than `*.expect` are inputs; `NAME.expect`, when present, holds text that the error
//! for `NAME` must contain (the input must be refused, with a message that says why).

use std::path::{Path, PathBuf};

use fmi_schema::fmi2::ModelDescription;

/// Reads, checks and round-trips one input, as the fuzz target does.
fn exercise(text: &str) -> Result<(), String> {
    let description = ModelDescription::from_xml(text).map_err(|e| e.message().to_owned())?;
    let _ = description.check();
    let _ = description.co_simulation();
    let xml = description.to_xml().expect("a description that was read can be written");
    let again = ModelDescription::from_xml(&xml).expect("our own XML reads back");
    assert_eq!(format!("{again:?}"), format!("{description:?}"), "the round trip changed the description");
    Ok(())
}

/// The FMI 3.0 reader on the same input: read, check, and round trip when it reads.
fn exercise_fmi3(text: &str) {
    if let Ok(description) = fmi_schema::fmi3::ModelDescription::from_xml(text) {
        let _ = description.check();
        let again = fmi_schema::fmi3::ModelDescription::from_xml(&description.to_xml()).expect("our own FMI 3.0 XML reads back");
        assert_eq!(format!("{again:?}"), format!("{description:?}"), "the FMI 3.0 round trip changed the description");
    }
}

#[test]
fn fuzz_regressions_read_or_fail_cleanly() {
    let inputs = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let mut files: Vec<PathBuf> =
        std::fs::read_dir(&inputs).unwrap().map(|e| e.unwrap().path()).filter(|p| p.extension().is_none_or(|x| x != "expect")).collect();
    files.sort();
    assert!(!files.is_empty(), "no inputs in {}", inputs.display());

    let mut failures = Vec::new();
    for file in &files {
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        let bytes = std::fs::read(file).unwrap();
        // The importer reads the file as UTF-8 first; other bytes never reach the parser.
        let Ok(text) = std::str::from_utf8(&bytes) else { continue };
        let expect = std::fs::read_to_string(file.with_file_name(format!("{name}.expect"))).ok();
        // Every input also goes through the FMI 3.0 reader, which must refuse or read it
        // without a panic (the runner picks the reader by fmiVersion, which a file can fake).
        if std::panic::catch_unwind(|| exercise_fmi3(text)).is_err() {
            failures.push(format!("{name}: the FMI 3.0 reader panicked"));
        }
        match (std::panic::catch_unwind(|| exercise(text)), expect) {
            (Err(_), _) => failures.push(format!("{name}: panicked")),
            (Ok(Ok(())), Some(expect)) => failures.push(format!("{name}: read but should fail with '{}'", expect.trim())),
            (Ok(Err(message)), Some(expect)) if !message.contains(expect.trim()) => {
                failures.push(format!("{name}: error does not mention '{}': {message}", expect.trim()))
            }
            _ => {}
        }
    }
    assert!(failures.is_empty(), "{} of {} inputs failed:\n  {}", failures.len(), files.len(), failures.join("\n  "));
}
