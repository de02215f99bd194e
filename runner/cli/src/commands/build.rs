//! `runner build`: compiles model crates in release mode and packs each into
//! `target/fmu/<id>.fmu` (FMI 2.0) and `target/fmu3/<id>.fmu` (FMI 3.0) with the XML and HTML
//! the compiled library generates from its table. One binary exports both versions' functions
//! (their names do not collide), so both archives hold the same library and the same page.
//! The one place that runs cargo: the import path only ever loads built FMUs.

use std::ffi::c_char;
use std::path::{Path, PathBuf};
use std::process::Command;

use fmi_importer::archive::{write_zip, Entry};
use fmi_importer::fmi2::PLATFORM;
use libloading::{Library, Symbol};

use crate::report::output::ResultFile;
use crate::workspace;

type TextExport = unsafe extern "C" fn(*mut c_char, usize) -> usize;

/// Calls one of the toolkit's text exports (`fmu_model_description`, `fmu_documentation`).
fn text_export(lib: &Library, name: &str) -> Result<String, String> {
    // SAFETY: the export toolkit defines these symbols with exactly this signature.
    let f: Symbol<TextExport> = unsafe { lib.get(name.as_bytes()) }.map_err(|_| format!("the model library does not export {name}"))?;
    // SAFETY: f follows the snprintf contract of fmu_export::fmi2::ffi::copy_out.
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
    // SAFETY: our own model library, just built: loading it runs no code but Rust's.
    let lib = unsafe { Library::new(&so) }.map_err(|e| format!("cannot load {}: {e}", so.display()))?;
    let xml = text_export(&lib, "fmu_model_description")?;
    let xml3 = text_export(&lib, "fmu3_model_description")?;
    let html = text_export(&lib, "fmu_documentation")?;
    let description = fmi_schema::fmi2::ModelDescription::from_xml(&xml)
        .map_err(|e| format!("{id}: generated modelDescription.xml does not parse: {e}"))?;
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
    let binary = std::fs::read(&so).map_err(|e| format!("cannot read {}: {e}", so.display()))?;
    let fmu2 = workspace::fmu_path(root, id);
    write_fmu(&fmu2, &xml, &format!("binaries/{PLATFORM}/{id}.so"), &binary, &html)?;
    let fmu3 = workspace::fmu3_path(root, id);
    write_fmu(&fmu3, &xml3, &format!("binaries/{}/{id}.so", fmi_importer::fmi3::PLATFORM), &binary, &html)?;
    Ok([fmu2, fmu3])
}

/// Writes one `.fmu` archive at `dest`.
fn write_fmu(dest: &Path, xml: &str, bin_path: &str, binary: &[u8], html: &str) -> Result<(), String> {
    let dir = dest.parent().ok_or_else(|| format!("{} has no parent directory", dest.display()))?;
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    write_zip(
        ResultFile::create(dest)?,
        &[
            Entry { path: "modelDescription.xml", bytes: xml.as_bytes() },
            Entry { path: bin_path, bytes: binary },
            Entry { path: "documentation/index.html", bytes: html.as_bytes() },
        ],
    )?
    .commit()?;
    Ok(())
}

/// `runner build [MODEL...]`: all models when none is named; the FMI 2.0 paths, then the FMI
/// 3.0 ones.
pub fn build(requested: &[String]) -> Result<Vec<PathBuf>, String> {
    let root = workspace::root();
    let known = workspace::models(&root)?;
    let ids: Vec<String> = if requested.is_empty() { known.clone() } else { requested.to_vec() };
    for id in &ids {
        if !known.contains(id) {
            return Err(format!("unknown model '{id}'; the models are: {}", known.join(", ")));
        }
    }
    cargo_build(&root, &ids)?;
    let packed = ids.iter().map(|id| pack(&root, id)).collect::<Result<Vec<_>, String>>()?;
    // The FMI 2.0 FMUs first, as before, then the FMI 3.0 ones.
    let (fmi2, fmi3): (Vec<PathBuf>, Vec<PathBuf>) = packed.into_iter().map(|[a, b]| (a, b)).unzip();
    Ok(fmi2.into_iter().chain(fmi3).collect())
}
