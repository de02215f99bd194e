//! `runner build`: compiles model crates in release mode and packs each into
//! `target/fmu/<id>.fmu` (FMI 2.0) and `target/fmu3/<id>.fmu` (FMI 3.0) with the XML and HTML
//! the compiled library generates from its table. One binary exports both versions' functions
//! (their names do not collide), so both archives hold the same library and the same page.
//! The FMI 3.0 archive also carries the reference result of its default experiment under
//! FMI-LS-REF (`extra/org.fmi-standard.fmi-ls-ref/`), so any importer can check itself against
//! the model. The one place that runs cargo: the import path only ever loads built FMUs.

use std::collections::BTreeMap;
use std::ffi::c_char;
use std::path::{Path, PathBuf};
use std::process::Command;

use fmi_importer::archive::{write_zip, Entry};
use fmi_importer::fmi2::PLATFORM;
use fmi_importer::{Interface, Kind, Variable};
use libloading::{Library, Symbol};
use runner_engine::exec::Runs;
use runner_engine::request::RunRequest;
use runner_engine::run::{Grid, Recording};
use solvers::controls::Control;

use crate::commands::compare;
use crate::experiment;
use crate::integration::Integration;
use crate::interrupt;
use crate::reference::{self, LS_REF_DIR};
use crate::report::output::ResultFile;
use crate::workers;
use crate::workspace;

type TextExport = unsafe extern "C" fn(*mut c_char, usize) -> usize;

/// Calls one of the toolkit's text exports (`fmu_model_description`, `fmu_documentation`).
fn text_export(lib: &Library, name: &str) -> Result<String, String> {
    // SAFETY: the export toolkit defines these symbols with exactly this signature.
    let f: Symbol<TextExport> = unsafe { lib.get(name.as_bytes()) }.map_err(|_| format!("the model library does not export {name}"))?;
    // SAFETY: f follows the snprintf contract of fmu_export::frontend::ffi::copy_out.
    let needed = unsafe { f(std::ptr::null_mut(), 0) };
    if needed == 0 {
        return Err(format!("{name} failed inside the model library"));
    }
    let mut buf = vec![0u8; needed];
    unsafe { f(buf.as_mut_ptr() as *mut c_char, buf.len()) };
    buf.pop();
    String::from_utf8(buf).map_err(|_| format!("{name} returned text that is not UTF-8"))
}

/// Runs `cargo build --release` for the given model crates.
pub fn cargo_build(root: &Path, ids: &[String]) -> Result<(), String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let mut cmd = Command::new(cargo);
    cmd.current_dir(root).args(["build", "--release", "--quiet"]);
    for id in ids {
        cmd.args(["-p", id]);
    }
    let status = cmd.status().map_err(|e| format!("cannot run cargo: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("cargo build --release failed for {}", ids.join(", ")))
    }
}

/// Packs the already-built library of model `id` into its FMI 2.0 and FMI 3.0 `.fmu`s;
/// returns their paths.
pub fn pack(root: &Path, id: &str) -> Result<[PathBuf; 2], String> {
    let so = workspace::target_dir(root).join("release").join(format!("lib{id}.so"));
    let dir = root.join("models").join(id);
    pack_library(&so, id, &dir, &workspace::fmu_path(root, id), &workspace::fmu3_path(root, id))
}

/// Packs the model library `so` (modelIdentifier `id`) and the files of `dir/resources` (if
/// that folder exists) into the FMI 2.0 FMU `fmu2` and the FMI 3.0 FMU `fmu3`, the latter with
/// its LS-REF result (see [`ls_ref_result`]; closed forms from `dir/experiment.toml`); returns
/// their paths.
pub fn pack_library(so: &Path, id: &str, dir: &Path, fmu2: &Path, fmu3: &Path) -> Result<[PathBuf; 2], String> {
    // SAFETY: a model library just built from source by cargo: loading it runs no code but Rust's.
    let lib = unsafe { Library::new(so) }.map_err(|e| format!("cannot load {}: {e}", so.display()))?;
    let xml = text_export(&lib, "fmu_model_description")?;
    let xml3 = text_export(&lib, "fmu3_model_description")?;
    let html = text_export(&lib, "fmu_documentation")?;
    let description = fmi_schema::fmi2::ModelDescription::from_xml(&xml)
        .map_err(|e| format!("{id}: generated modelDescription.xml does not parse: {e}"))?;
    let identifiers = [
        description.co_simulation.as_ref().map(|c| &c.common.model_identifier),
        description.model_exchange.as_ref().map(|m| &m.common.model_identifier),
    ];
    if let Some(other) = identifiers.into_iter().flatten().find(|i| *i != id) {
        return Err(format!(
            "{}: the model's identifier (ModelInfo::identifier) is '{other}' but its library is named '{id}'; they must agree, since the FMU's binary is named after its modelIdentifier",
            so.display()
        ));
    }
    let problems = description.check();
    if !problems.is_empty() {
        return Err(format!("{id}: generated modelDescription.xml has problems:\n  {}", problems.join("\n  ")));
    }
    let description3 = fmi_schema::fmi3::ModelDescription::from_xml(&xml3)
        .map_err(|e| format!("{id}: generated FMI 3.0 modelDescription.xml does not parse: {e}"))?;
    let problems = description3.check();
    if !problems.is_empty() {
        return Err(format!("{id}: generated FMI 3.0 modelDescription.xml has problems:\n  {}", problems.join("\n  ")));
    }
    let binary = std::fs::read(so).map_err(|e| format!("cannot read {}: {e}", so.display()))?;
    let mut resources = model_resources(&dir.join("resources"))?;
    write_fmu(fmu2, &xml, &format!("binaries/{PLATFORM}/{id}.so"), &binary, &html, &resources)?;
    // The FMI 3.0 FMU is packed, run for its reference result, then packed again with it.
    let binary3 = format!("binaries/{}/{id}.so", fmi_importer::fmi3::PLATFORM);
    write_fmu(fmu3, &xml3, &binary3, &binary, &html, &resources)?;
    let experiment = experiment::read(&dir.join("experiment.toml"))?;
    let result = ls_ref_result(fmu3, &experiment.compare.reference, &experiment.reference.omit)
        .map_err(|e| format!("{id}: its LS-REF reference result: {e}"))?;
    if let Some((csv, description)) = result {
        let source = format!("{id}_out.csv");
        resources.push((format!("{LS_REF_DIR}/{}", reference::MANIFEST), reference::manifest(&source, &description).into_bytes()));
        resources.push((format!("{LS_REF_DIR}/{source}"), csv.into_bytes()));
        write_fmu(fmu3, &xml3, &binary3, &binary, &html, &resources)?;
    }
    Ok([fmu2.to_path_buf(), fmu3.to_path_buf()])
}

/// The relative tolerance of the DOP853 run an LS-REF result comes from where no closed form
/// gives a column: far below any tube an importer would be checked with (1e-3 by default).
pub const LS_REF_RTOL: f64 = 1e-12;

/// The reference result of the FMU at `fmu` for LS-REF, as CSV in fmpy's layout (`time`, then
/// every output but the solver's counters and those `omit` names, as `runner simulate` writes
/// them), and its description: the run of its
/// DefaultExperiment (on that grid, without experiment.toml's settings, which other importers
/// do not read) at DOP853 and rtol [`LS_REF_RTOL`], each output of `closed_forms` (the model's
/// `[compare.reference]`, which holds for the default parameters) replaced by its closed form at
/// the run's times. `None` for a model without outputs: a result of times alone checks nothing.
pub fn ls_ref_result(fmu: &Path, closed_forms: &BTreeMap<String, String>, omit: &[String]) -> Result<Option<(String, String)>, String> {
    // A model built from source here: run in this process, with no worker to start.
    let (held, source) = workers::open(fmu, &Integration::default(), true)?;
    let md = held.description();
    let config = workers::isolation(None, runner_sandbox::default_memory_mib(1))?;
    let mut runs = Runs::new(&held, &config, &source);
    let controls = match held.interface() {
        Interface::ModelExchange => None,
        _ => Some((compare::control(md, Control::Solver)?, compare::control(md, Control::AbsTol)?)),
    };
    let (grid, settings) = compare::reference_accuracy(Grid::choose(md, &[])?, controls, LS_REF_RTOL);
    // Not the solver's counters (n_steps, n_rhs): they count the reference run's own work.
    let counter = |v: &Variable| Control::named(&v.name).is_some_and(Control::is_output);
    for name in omit {
        if !md.outputs().any(|v| v.name == *name) {
            return Err(format!("experiment.toml's [reference] omit names '{name}', which is not an output of {}", md.model_name));
        }
    }
    let kept = |v: &Variable| v.kind != Kind::Clock && !counter(v) && !omit.contains(&v.name);
    let outputs: Vec<&Variable> = md.outputs().filter(|v| kept(v)).collect();
    if outputs.is_empty() {
        return Ok(None);
    }
    let recording = Recording::new(md, &outputs, &settings)?;
    let columns = recording.names.len();
    let request = RunRequest::new(held.identifier(), grid, &settings, &recording, false);
    let mut rows: Vec<(f64, Vec<String>)> = Vec::new();
    // The FMU's own messages are not the build's: a linkage's limit position or the trebuchet's
    // landing ends the default experiment with a logged discard every build would print. A
    // failure still says why (the importer keeps an instance's last problem for its error).
    let printer = fmi_importer::set_log_printer(|_| {});
    let ran = runs.run(&request, &interrupt::requested, |t, values, texts| {
        rows.push((t, (0..columns).map(|c| texts.text(c, values)).collect()));
        Ok(())
    });
    fmi_importer::set_log_printer(printer);
    ran?;
    let times: Vec<f64> = rows.iter().map(|r| r.0).collect();
    let (exact, values) = compare::closed_form(md, closed_forms, &[], &times)?;
    for (k, variable) in exact.iter().enumerate() {
        let c = recording.names.iter().position(|n| *n == variable.name).ok_or_else(|| format!("{} is not recorded", variable.name))?;
        for (row, value) in rows.iter_mut().zip(&values) {
            row.1[c] = format!("{:?}", value[k]);
        }
    }
    let mut writer = csv::Writer::from_writer(Vec::new());
    let header = std::iter::once("time").chain(recording.names.iter().map(String::as_str));
    writer.write_record(header).map_err(|e| e.to_string())?;
    for (t, cells) in &rows {
        writer.write_record(std::iter::once(format!("{t:?}")).chain(cells.iter().cloned())).map_err(|e| e.to_string())?;
    }
    let csv = String::from_utf8(writer.into_inner().map_err(|e| e.to_string())?).map_err(|e| e.to_string())?;
    let solver = format!("DOP853 at rtol {LS_REF_RTOL:e}");
    let description = match exact.len() {
        0 => format!("Output of the default experiment, from {solver}"),
        n if n == outputs.len() => "Output of the default experiment, from its closed-form solution".to_owned(),
        _ => {
            let names: Vec<&str> = exact.iter().map(|v| v.name.as_str()).collect();
            format!("Output of the default experiment: {} from the closed-form solution, the other columns from {solver}", names.join(", "))
        }
    };
    Ok(Some((csv, description)))
}

/// Writes one `.fmu` archive at `dest`.
fn write_fmu(dest: &Path, xml: &str, bin_path: &str, binary: &[u8], html: &str, resources: &[(String, Vec<u8>)]) -> Result<(), String> {
    let dir = dest.parent().ok_or_else(|| format!("{} has no parent directory", dest.display()))?;
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let mut entries = vec![
        Entry { path: "modelDescription.xml", bytes: xml.as_bytes() },
        Entry { path: bin_path, bytes: binary },
        Entry { path: "documentation/index.html", bytes: html.as_bytes() },
    ];
    entries.extend(resources.iter().map(|(path, bytes)| Entry { path, bytes }));
    write_zip(ResultFile::create(dest)?, &entries)?.commit()?;
    Ok(())
}

/// The files of a model's `resources/` folder (the FMU's `resources/`, which the model reads
/// at instantiation), as archive paths and bytes; none when the folder is absent.
fn model_resources(dir: &Path) -> Result<Vec<(String, Vec<u8>)>, String> {
    let mut files = Vec::new();
    if !dir.is_dir() {
        return Ok(files);
    }
    let mut entries: Vec<_> =
        std::fs::read_dir(dir).map_err(|e| format!("cannot list {}: {e}", dir.display()))?.filter_map(|e| e.ok()).collect();
    entries.sort_by_key(|e| e.file_name());
    for e in entries {
        let path = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if !path.is_file() {
            return Err(format!("{}: resources are plain files; {name} is not", dir.display()));
        }
        files.push((format!("resources/{name}"), std::fs::read(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))?));
    }
    Ok(files)
}

/// The model crate of a `Cargo.toml` anywhere, as cargo describes it.
struct Crate {
    /// Its library's name: the FMU's modelIdentifier.
    lib: String,
    /// Its folder (for `resources/`).
    dir: PathBuf,
    /// Cargo's target directory for it.
    target: PathBuf,
}

/// Reads `cargo metadata` for `manifest`: the package it names must build a `cdylib`.
fn describe(manifest: &Path) -> Result<Crate, String> {
    if !manifest.is_file() {
        return Err(format!("{} does not exist", manifest.display()));
    }
    let manifest = manifest.canonicalize().map_err(|e| format!("cannot resolve {}: {e}", manifest.display()))?;
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let out = Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--no-deps", "--manifest-path"])
        .arg(&manifest)
        .output()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !out.status.success() {
        return Err(format!("cargo metadata failed for {}:\n{}", manifest.display(), String::from_utf8_lossy(&out.stderr).trim_end()));
    }
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).map_err(|e| format!("cargo metadata gave no JSON: {e}"))?;
    let target = meta["target_directory"].as_str().ok_or("cargo metadata names no target directory")?;
    let package = meta["packages"]
        .as_array()
        .into_iter()
        .flatten()
        .find(|p| p["manifest_path"].as_str().is_some_and(|m| Path::new(m) == manifest))
        .ok_or_else(|| format!("{} names no package (a workspace's manifest? give the model crate's own)", manifest.display()))?;
    let lib = package["targets"]
        .as_array()
        .into_iter()
        .flatten()
        .find(|t| t["kind"].as_array().is_some_and(|k| k.iter().any(|k| k == "cdylib")))
        .and_then(|t| t["name"].as_str())
        .ok_or_else(|| {
            format!(
                "{}: the package builds no cdylib, so no FMU binary; its [lib] needs crate-type = [\"cdylib\", \"rlib\"]",
                manifest.display()
            )
        })?;
    let dir = manifest.parent().expect("a file has a folder").to_path_buf();
    Ok(Crate { lib: lib.to_owned(), dir, target: PathBuf::from(target) })
}

/// `runner build --manifest-path DIR/Cargo.toml [--out-dir OUT]`: builds the model crate there
/// (anywhere, such as one `runner new` made) in release mode and packs `OUT/fmu/<id>.fmu`
/// (FMI 2.0) and `OUT/fmu3/<id>.fmu` (FMI 3.0); OUT defaults to the crate's target directory.
pub fn build_manifest(manifest: &Path, out_dir: Option<&Path>) -> Result<Vec<PathBuf>, String> {
    let krate = describe(manifest)?;
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let status = Command::new(cargo)
        .args(["build", "--release", "--quiet", "--lib", "--manifest-path"])
        .arg(krate.dir.join("Cargo.toml"))
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !status.success() {
        return Err(format!("cargo build --release failed for {}", manifest.display()));
    }
    let so = krate.target.join("release").join(format!("lib{}.so", krate.lib));
    let out = out_dir.map(Path::to_path_buf).unwrap_or(krate.target);
    let id = &krate.lib;
    let fmus = pack_library(&so, id, &krate.dir, &out.join("fmu").join(format!("{id}.fmu")), &out.join("fmu3").join(format!("{id}.fmu")))?;
    Ok(fmus.to_vec())
}

/// `runner build [NAME...]`: every model and every system under `systems/` when none is named;
/// a named system builds the models it uses, then is packed into `target/ssp/<name>.ssp`. The
/// FMI 2.0 paths come first, then the FMI 3.0 ones, then the systems.
pub fn build(requested: &[String]) -> Result<Vec<PathBuf>, String> {
    let root = workspace::root();
    let known = workspace::models(&root)?;
    let systems = workspace::systems(&root)?;
    let (mut ids, wanted_systems): (Vec<String>, Vec<String>) = if requested.is_empty() {
        (known.clone(), systems.clone())
    } else {
        let (s, m): (Vec<String>, Vec<String>) = requested.iter().cloned().partition(|n| systems.contains(n) && !known.contains(n));
        (m, s)
    };
    for id in &ids {
        if !known.contains(id) {
            return Err(format!("unknown model '{id}'; the models are: {}; the systems: {}", known.join(", "), systems.join(", ")));
        }
    }
    let mut uses = Vec::new();
    for name in &wanted_systems {
        let models = system_models(&root, name, &known)?;
        for m in &models {
            if !ids.contains(&m.model) {
                ids.push(m.model.clone());
            }
        }
        uses.push((name, models));
    }
    cargo_build(&root, &ids)?;
    let packed = ids.iter().map(|id| pack(&root, id)).collect::<Result<Vec<_>, String>>()?;
    let (fmi2, fmi3): (Vec<PathBuf>, Vec<PathBuf>) = packed.into_iter().map(|[a, b]| (a, b)).unzip();
    let mut built: Vec<PathBuf> = fmi2.into_iter().chain(fmi3).collect();
    for (name, models) in uses {
        built.push(pack_system(&root, name, &models)?);
    }
    Ok(built)
}

/// A model of this workspace that a system uses, as the FMU its source names:
/// `resources/<model>.fmu` is the FMI 2.0 FMU (`target/fmu/`), `resources/fmu3/<model>.fmu` the
/// FMI 3.0 one (`target/fmu3/`).
#[derive(Debug, Clone, PartialEq)]
pub struct SystemModel {
    pub model: String,
    pub fmi3: bool,
}

impl SystemModel {
    /// Its path in the archive, as the SSD names it.
    fn entry(&self) -> String {
        if self.fmi3 {
            format!("resources/fmu3/{}.fmu", self.model)
        } else {
            format!("resources/{}.fmu", self.model)
        }
    }
}

/// The models system `name` takes from this workspace: its components' sources
/// `resources/<model>.fmu` (FMI 2.0) and `resources/fmu3/<model>.fmu` (FMI 3.0).
fn system_models(root: &Path, name: &str, known: &[String]) -> Result<Vec<SystemModel>, String> {
    let ssd = root.join("systems").join(name).join("SystemStructure.ssd");
    let structure = fmi_systems::ssd::Structure::read(&ssd)?;
    let dir = root.join("systems").join(name);
    let mut models = Vec::new();
    for c in &structure.components {
        let relative = c.source.strip_prefix(&dir).unwrap_or(&c.source);
        let in_resources = relative.strip_prefix("resources").ok();
        let (fmi3, file) = match in_resources.and_then(|p| p.strip_prefix("fmu3").ok()) {
            Some(file) => (true, Some(file)),
            None => (false, in_resources),
        };
        let model = file.and_then(|p| p.to_str()).and_then(|p| p.strip_suffix(".fmu"));
        match model {
            Some(m) if known.iter().any(|k| k == m) => {
                let wanted = SystemModel { model: m.to_owned(), fmi3 };
                if !models.contains(&wanted) {
                    models.push(wanted);
                }
            }
            _ if c.source.is_file() => {}
            _ => {
                return Err(format!(
                    "system {name}: component '{}' has source {}, neither resources/<model>.fmu (FMI 2.0) nor resources/fmu3/<model>.fmu (FMI 3.0) of a model here ({}) nor a file in systems/{name}",
                    c.name,
                    relative.display(),
                    known.join(", ")
                ))
            }
        }
    }
    Ok(models)
}

/// Packs `systems/<name>/` (the SSD, parameter files, any other files) and the FMUs of `models`
/// (as their sources name them) into `target/ssp/<name>.ssp`.
pub fn pack_system(root: &Path, name: &str, models: &[SystemModel]) -> Result<PathBuf, String> {
    let dir = root.join("systems").join(name);
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    let mut pending = vec![dir.clone()];
    while let Some(d) = pending.pop() {
        let mut entries: Vec<_> =
            std::fs::read_dir(&d).map_err(|e| format!("cannot list {}: {e}", d.display()))?.filter_map(|e| e.ok()).collect();
        entries.sort_by_key(|e| e.file_name());
        for e in entries {
            let path = e.path();
            if path.is_dir() {
                pending.push(path);
                continue;
            }
            let relative = path.strip_prefix(&dir).expect("under the system").to_string_lossy().into_owned();
            files.push((relative, std::fs::read(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))?));
        }
    }
    for m in models {
        let fmu = if m.fmi3 { workspace::fmu3_path(root, &m.model) } else { workspace::fmu_path(root, &m.model) };
        files.push((m.entry(), std::fs::read(&fmu).map_err(|e| format!("cannot read {}: {e}", fmu.display()))?));
    }
    files.sort_by(|a, b| (a.0 != "SystemStructure.ssd", &a.0).cmp(&(b.0 != "SystemStructure.ssd", &b.0)));
    let dest = workspace::target_dir(root).join("ssp").join(format!("{name}.ssp"));
    let parent = dest.parent().expect("target/ssp");
    std::fs::create_dir_all(parent).map_err(|e| format!("cannot create {}: {e}", parent.display()))?;
    let entries: Vec<Entry> = files.iter().map(|(path, bytes)| Entry { path, bytes }).collect();
    write_zip(ResultFile::create(&dest)?, &entries)?.commit()?;
    Ok(dest)
}
