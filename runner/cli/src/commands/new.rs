//! `runner new NAME [--path DIR]`: a model crate of one's own, anywhere. It holds a first-order
//! decay `x' = -x / tau` (one parameter, one state, one output), its test against the closed form
//! `x = exp(-t / tau)` and its derivation; it depends on this checkout's export toolkit by path
//! and pins the dependency versions this checkout is tested with (its Cargo.lock). `runner build
//! --manifest-path DIR/Cargo.toml` turns it into FMI 2.0 and 3.0 FMUs.

use std::path::{Path, PathBuf};

/// Words a crate or FMI model identifier cannot be: Rust's keywords (the crate name becomes a
/// Rust identifier) and the names the toolkit's generated code uses.
const RESERVED: &[&str] = &[
    "as",
    "async",
    "await",
    "break",
    "const",
    "continue",
    "crate",
    "dyn",
    "else",
    "enum",
    "extern",
    "false",
    "fn",
    "for",
    "if",
    "impl",
    "in",
    "let",
    "loop",
    "match",
    "mod",
    "move",
    "mut",
    "pub",
    "ref",
    "return",
    "self",
    "static",
    "struct",
    "super",
    "trait",
    "true",
    "type",
    "unsafe",
    "use",
    "where",
    "while",
    "abstract",
    "become",
    "box",
    "do",
    "final",
    "gen",
    "macro",
    "override",
    "priv",
    "try",
    "typeof",
    "unsized",
    "virtual",
    "yield",
    "test",
    "core",
    "std",
    "alloc",
    "proc_macro",
    "fmu_export",
    "serde",
];

/// Checks that `name` can be the crate's name, its library's name and the FMU's
/// modelIdentifier at once: lowercase ASCII letters, digits and underscores, starting with a
/// letter (a C identifier, as FMI requires, and a Rust crate name without renaming).
pub fn check_name(name: &str) -> Result<(), String> {
    let first_ok = name.chars().next().is_some_and(|c| c.is_ascii_lowercase());
    let rest_ok = name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
    if !first_ok || !rest_ok {
        return Err(format!(
            "model name '{name}' must start with a lowercase letter and hold only lowercase letters, digits and underscores \
             (it is the crate's name and the FMU's modelIdentifier, a C identifier)"
        ));
    }
    if RESERVED.contains(&name) {
        return Err(format!("model name '{name}' is a Rust keyword or a name the toolkit uses; choose another"));
    }
    Ok(())
}

/// `my_model` to `MyModel`, the struct's name.
fn type_name(name: &str) -> String {
    name.split('_')
        .filter(|w| !w.is_empty())
        .map(|w| {
            let mut c = w.chars();
            c.next().map(|f| f.to_ascii_uppercase().to_string() + c.as_str()).unwrap_or_default()
        })
        .collect()
}

/// The files of a new model crate named `name` over the toolkit at `toolkit` (this checkout's
/// root): path within the crate and contents.
pub fn files(name: &str, toolkit: &Path) -> Vec<(&'static str, String)> {
    let ty = type_name(name);
    let export = toolkit.join("fmu").join("export");
    // A TOML basic string: backslashes and quotes escaped.
    let export = export.display().to_string().replace('\\', "\\\\").replace('"', "\\\"");
    let fill = |text: &str| text.replace("{{name}}", name).replace("{{Type}}", &ty).replace("{{export}}", &export);
    vec![
        ("Cargo.toml", fill(CARGO_TOML)),
        ("src/lib.rs", fill(LIB_RS)),
        ("derivation.md", fill(DERIVATION_MD)),
        (".gitignore", "/target\n".to_owned()),
    ]
}

/// Creates the crate at `dir` (default `./NAME`); returns its directory. Refuses a directory
/// that exists and is not empty, so nothing of the user's is overwritten.
pub fn new(name: &str, dir: Option<&Path>) -> Result<PathBuf, String> {
    check_name(name)?;
    let dir = dir.map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from(name));
    if dir.exists() {
        let empty = dir.is_dir() && std::fs::read_dir(&dir).map_err(|e| format!("cannot list {}: {e}", dir.display()))?.next().is_none();
        if !empty {
            return Err(format!("{} already exists and is not an empty directory; runner new writes only into a new one", dir.display()));
        }
    }
    let root = crate::workspace::root();
    let toolkit = root.canonicalize().map_err(|e| format!("cannot find the toolkit's checkout {}: {e}", root.display()))?;
    if !toolkit.join("fmu").join("export").join("Cargo.toml").is_file() {
        return Err(format!("{} holds no export toolkit (fmu/export/Cargo.toml)", toolkit.display()));
    }
    for (path, text) in files(name, &toolkit) {
        let path = dir.join(path);
        let parent = path.parent().expect("a file within the crate");
        std::fs::create_dir_all(parent).map_err(|e| format!("cannot create {}: {e}", parent.display()))?;
        std::fs::write(&path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    // The versions of every dependency this checkout is tested with; cargo drops the entries
    // the new crate does not use when it first builds.
    let lock = toolkit.join("Cargo.lock");
    if lock.is_file() {
        std::fs::copy(&lock, dir.join("Cargo.lock")).map_err(|e| format!("cannot copy {}: {e}", lock.display()))?;
    }
    Ok(dir)
}

const CARGO_TOML: &str = r#"[package]
name = "{{name}}"
description = "{{name}}: a model exported as FMI 2.0 and FMI 3.0 FMUs (Co-Simulation and Model Exchange)"
edition = "2021"
version = "0.1.0"
publish = false

[lib]
# cdylib: the FMU's binary; rlib: the tests link the model as a Rust library.
crate-type = ["cdylib", "rlib"]

[dependencies]
# The export toolkit, by path to the checkout `runner new` came from.
fmu-export = { path = "{{export}}" }
serde = { version = "1", features = ["derive"] }

# A crate of its own, not a member of any workspace it happens to sit in.
[workspace]

[profile.release]
# The toolkit's settings: no debug info in the FMU's binary, unwinding (the FMU catches panics
# at the C boundary), one code generation unit (the right-hand side inlined into the solver).
strip = "debuginfo"
panic = "unwind"
codegen-units = 1
"#;

const LIB_RS: &str = r#"#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::{Equations, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use serde::{Deserialize, Serialize};

/// First-order decay `x' = -x / tau`, x(0) = 1. Generic over its number type `T` so that the
/// toolkit can differentiate the equations exactly (FMI directional derivatives).
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[variables(states = State)]
pub struct {{Type}}<T = f64> {
    /// Time constant
    #[parameter(unit = "s", positive)]
    pub tau: T,
    /// Rate of decay -x' = x / tau
    #[output(unit = "1/s")]
    pub rate: T,
}

/// The state vector.
#[derive(StateVector)]
pub struct State<T = f64> {
    /// The decaying quantity, 1 at t = 0
    pub x: T,
}

impl Default for {{Type}} {
    fn default() -> Self {
        {{Type}} { tau: 1.0, rate: 1.0 }
    }
}

impl<T: Scalar> Equations<T> for {{Type}}<T> {
    /// x(0) = 1. The toolkit has checked `tau > 0` (its declared range) before this runs.
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        State { x: T::one() }.store(x);
        Ok(())
    }

    /// x' = -x / tau.
    fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
        let State { x } = State::load(x);
        State { x: -x / self.tau }.store(dx);
    }

    fn outputs(&mut self, _t: T, x: &[T]) {
        self.rate = State::load(x).x / self.tau;
    }
}

impl Model for {{Type}} {
    const N_STATES: usize = State::LEN;

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "{{name}}",
            description: "First-order decay x' = -x / tau, x(0) = 1",
            stop_time: 5.0,
            tolerance: 1e-6,
            output_interval: 0.01,
            documentation: include_str!("../derivation.md"),
        }
    }
}

fmu_export::export_fmu!({{Type}});

#[cfg(test)]
mod tests {
    use super::*;
    use fmu_export::harness::Harness;

    /// The closed form (derivation.md): x(t) = exp(-t / tau).
    fn exact(t: f64, tau: f64) -> f64 {
        (-t / tau).exp()
    }

    /// DOPRI5 at rtol 1e-10 against the closed form over 5 time constants: the global error
    /// stays within a small multiple of the tolerance (x <= 1), so 1e-8 holds with margin and a
    /// wrong sign or factor in `derivatives` (errors of order 1) fails.
    #[test]
    fn matches_the_closed_form() {
        let tau = 0.5;
        let mut h = Harness::<{{Type}}>::new();
        h.set("tau", tau).unwrap();
        h.set("abs_tol", 1e-12).unwrap();
        h.initialize(Some(1e-10)).unwrap();
        let run = h.run(5.0 * tau, 0.01, &["x", "rate"]).unwrap();
        for (k, t) in run.time.iter().enumerate() {
            let x = exact(*t, tau);
            assert!((run.get("x")[k] - x).abs() < 1e-8, "t = {t}: x = {} against {x}", run.get("x")[k]);
            assert!((run.get("rate")[k] - x / tau).abs() < 2e-8, "t = {t}: rate = {}", run.get("rate")[k]);
        }
    }

    /// A time constant that is not positive is refused at initialization, naming it.
    #[test]
    fn a_time_constant_of_zero_is_refused_by_name() {
        let mut h = Harness::<{{Type}}>::new();
        h.set("tau", 0.0).unwrap();
        let err = h.initialize(None).unwrap_err();
        assert!(err.contains("tau"), "{err}");
    }
}
"#;

const DERIVATION_MD: &str = r#"# {{name}}: first-order decay

The model is

```text
x' = -x / tau,   x(0) = 1,   rate = -x' = x / tau
```

with the time constant `tau > 0` (default 1 s) its one parameter, `x` its one state and `rate`
its one output.

## Closed form (the reference of the tests)

Separating variables, dx / x = -dt / tau, so ln x = -t / tau + C, and x(0) = 1 gives C = 0:

```text
x(t) = exp(-t / tau),   rate(t) = exp(-t / tau) / tau
```

`cargo test` compares the FMU's own solver (DOPRI5, rtol 1e-10) against it.
"#;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_that_are_no_c_identifier_or_a_keyword_are_refused() {
        for bad in ["", "My_model", "1st", "has-dash", "has space", "é", "fn", "test", "serde"] {
            assert!(check_name(bad).is_err(), "{bad:?} accepted");
        }
        for good in ["decay", "my_model2", "a_b_c"] {
            check_name(good).unwrap();
        }
    }

    #[test]
    fn the_struct_is_named_in_camel_case() {
        assert_eq!(type_name("damped_oscillator"), "DampedOscillator");
        assert_eq!(type_name("x2"), "X2");
    }

    /// The template's placeholders are all filled, and the toolkit's path is the one given.
    #[test]
    fn the_files_name_the_model_and_the_toolkit() {
        let files = files("decay", Path::new("/opt/toolkit"));
        for (path, text) in &files {
            assert!(!text.contains("{{"), "{path} keeps a placeholder");
        }
        let cargo = &files.iter().find(|(p, _)| *p == "Cargo.toml").unwrap().1;
        assert!(cargo.contains("name = \"decay\"") && cargo.contains("path = \"/opt/toolkit/fmu/export\""), "{cargo}");
        let lib = &files.iter().find(|(p, _)| *p == "src/lib.rs").unwrap().1;
        assert!(lib.contains("pub struct Decay<T = f64>") && lib.contains("identifier: \"decay\""));
    }
}
