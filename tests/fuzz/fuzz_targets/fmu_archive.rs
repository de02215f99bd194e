//! Fuzzes the `.fmu` loader up to (never including) dlopen: safe unzip into a temporary
//! directory, modelDescription.xml, and the lookup of binaries/linux64/<id>.so.
//!
//! Besides "no panic", it checks the extractor's promise that nothing lands outside its
//! temporary directory: TMPDIR points a few levels deep into a private scratch tree, so an
//! escaping `../` entry lands somewhere in that tree, and after every input the tree must hold
//! exactly what it held before (the runner-fmu-* directory is gone once the result is dropped).

#![no_main]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use fmi_importer::Unpacked;
use libfuzzer_sys::fuzz_target;

/// This process's scratch tree: `root/input.fmu` and TMPDIR = `root/a/b/c/tmp`.
struct Scratch {
    root: PathBuf,
    tmp: PathBuf,
    input: PathBuf,
    /// Every path in the tree before any input ran, sorted.
    baseline: Vec<PathBuf>,
}

fn scratch() -> &'static Scratch {
    static SCRATCH: OnceLock<Scratch> = OnceLock::new();
    SCRATCH.get_or_init(|| {
        // The run script gives each run a fresh TMPDIR; the pid keeps parallel runs apart.
        let root = std::env::temp_dir().join(format!("fmu-archive-fuzz-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let tmp = root.join("a/b/c/tmp");
        std::fs::create_dir_all(&tmp).expect("create the scratch tree");
        let input = root.join("input.fmu");
        std::fs::write(&input, b"").expect("create the input file");
        // Set before any tempfile call, from the single fuzzing thread.
        std::env::set_var("TMPDIR", &tmp);
        let baseline = tree(&root);
        Scratch { root, tmp, input, baseline }
    })
}

/// All paths under `dir` (symbolic links listed, not followed), sorted.
fn tree(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else { continue };
        for entry in entries.flatten() {
            let path = entry.path();
            if entry.file_type().is_ok_and(|t| t.is_dir()) {
                stack.push(path.clone());
            }
            out.push(path);
        }
    }
    out.sort();
    out
}

fuzz_target!(|data: &[u8]| {
    let s = scratch();
    std::fs::write(&s.input, data).expect("write the input file");
    match Unpacked::open(&s.input) {
        Ok(unpacked) => {
            let dir = unpacked.dir.path();
            assert_eq!(dir.parent(), Some(s.tmp.as_path()), "unpacked outside TMPDIR: {}", dir.display());
            let name = dir.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            assert!(name.starts_with("runner-fmu-"), "unexpected temporary directory name {name}");
            // Canonical, so that neither `..` in the modelIdentifier nor a link can point elsewhere.
            let binary = unpacked.binary.canonicalize().expect("the binary exists");
            let canonical_dir = dir.canonicalize().expect("the directory exists");
            assert!(
                binary.starts_with(&canonical_dir) && binary.is_file(),
                "binary {} is not a file inside {}",
                binary.display(),
                canonical_dir.display()
            );
            if let Some(raw) = &unpacked.fmi2 {
                let _ = raw.check();
            }
        }
        Err(message) => assert!(!message.is_empty(), "an empty error message"),
    }
    // The result is dropped: the tree must be back to exactly what it was.
    let after = tree(&s.root);
    if after != s.baseline {
        let extra: Vec<_> = after.iter().filter(|p| !s.baseline.contains(p)).collect();
        let missing: Vec<_> = s.baseline.iter().filter(|p| !after.contains(p)).collect();
        // Clean up so the crash report is about this input only, then fail.
        for p in &extra {
            let _ = std::fs::remove_dir_all(p).or_else(|_| std::fs::remove_file(p));
        }
        panic!("the scratch tree changed: left behind {extra:?}, removed {missing:?}");
    }
});
