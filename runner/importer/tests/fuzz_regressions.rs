//! The hand-made hostile archives the `fmu_archive` fuzz target is seeded with
//! (tests/hostile/archives.rs, built here at test time), plus any archive the fuzzer found
//! crashing, kept in `tests/fuzz_regressions/` (none so far), replayed through `Unpacked::open`.
//!
//! Every input must load or fail without a panic, and leave nothing behind. A hostile archive
//! must be refused with a message containing its expected text; a kept file with a
//! `NAME.expect` beside it likewise.

#[path = "hostile/archives.rs"]
mod hostile;

use std::path::{Path, PathBuf};

use fmi_importer::Unpacked;

/// Every path under `dir`, sorted.
fn tree(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap().flatten() {
            if entry.file_type().unwrap().is_dir() {
                stack.push(entry.path());
            }
            out.push(entry.path());
        }
    }
    out.sort();
    out
}

#[test]
fn fuzz_regressions_load_or_fail_cleanly() {
    // (archive, text its error must contain)
    let built = tempfile::tempdir().unwrap();
    let mut inputs: Vec<(PathBuf, Option<String>)> = hostile::hostile_archives()
        .into_iter()
        .map(|(name, bytes, expect)| {
            let path = built.path().join(name);
            std::fs::write(&path, bytes).unwrap();
            (path, Some(expect.to_owned()))
        })
        .collect();
    let kept = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    if let Ok(dir) = std::fs::read_dir(&kept) {
        let mut files: Vec<PathBuf> = dir.map(|e| e.unwrap().path()).filter(|p| p.extension().is_none_or(|x| x != "expect")).collect();
        files.sort();
        for file in files {
            let name = file.file_name().unwrap().to_string_lossy().into_owned();
            let expect = std::fs::read_to_string(file.with_file_name(format!("{name}.expect"))).ok();
            inputs.push((file, expect));
        }
    }

    // Extraction goes into a temporary directory a few levels into a scratch tree of our own,
    // so an entry that escaped it would show up in the tree. This is the only test in this
    // binary, so setting TMPDIR races with no other thread.
    let scratch = tempfile::tempdir().unwrap();
    let tmp = scratch.path().join("a/b/c/tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    std::env::set_var("TMPDIR", &tmp);
    let before = tree(scratch.path());

    let mut failures = Vec::new();
    for (file, expect) in &inputs {
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        let expect = expect.clone();
        let outcome = std::panic::catch_unwind(|| Unpacked::open(file).map(|u| u.identifier));
        match (outcome, expect) {
            (Err(_), _) => failures.push(format!("{name}: panicked")),
            (Ok(Ok(id)), Some(expect)) => {
                failures.push(format!("{name}: loaded (identifier {id}) but should fail with '{}'", expect.trim()))
            }
            (Ok(Err(message)), Some(expect)) if !message.contains(expect.trim()) => {
                failures.push(format!("{name}: error does not mention '{}': {message}", expect.trim()))
            }
            (Ok(Err(message)), _) if !message.contains(&file.display().to_string()) => {
                failures.push(format!("{name}: error does not name the file: {message}"))
            }
            _ => {}
        }
        let after = tree(scratch.path());
        if after != before {
            failures.push(format!("{name}: the scratch tree changed: {after:?}"));
            for p in after.iter().filter(|p| !before.contains(p)) {
                let _ = std::fs::remove_dir_all(p).or_else(|_| std::fs::remove_file(p));
            }
        }
    }
    assert!(failures.is_empty(), "{} of {} inputs failed:\n  {}", failures.len(), inputs.len(), failures.join("\n  "));
}
