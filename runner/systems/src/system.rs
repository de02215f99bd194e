//! A system's FMUs, loaded: one unpacked FMU per component (two components of one FMU file are
//! two instances of two loads, so each keeps its own resources).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use fmi_importer::{Causality, Fmu, Unpacked};

use crate::ssd::Structure;

/// A component: its FMU and which of its outputs depend directly on which inputs.
pub struct Component {
    /// The flattened name (`car`, `sub.car`).
    pub name: String,
    pub fmu: Fmu,
    /// Output name -> the inputs it depends on directly (ModelStructure; all inputs where the
    /// FMU does not say).
    pub feedthrough: HashMap<String, Vec<String>>,
    // After `fmu`: the binary closes before its files go.
    _dir: tempfile::TempDir,
}

/// A loaded system.
pub struct System {
    /// Where it was read from.
    pub path: PathBuf,
    pub structure: Structure,
    pub components: Vec<Component>,
    // Last: the FMUs close before the extracted archive goes.
    _archive: Option<tempfile::TempDir>,
}

/// True when `path` names a system rather than an FMU: a `.ssp` or `.ssd` file, or a folder
/// holding `SystemStructure.ssd`.
pub fn is_system(path: &Path) -> bool {
    match path.extension().and_then(|e| e.to_str()) {
        Some("ssp" | "ssd") => true,
        _ => path.is_dir() && path.join("SystemStructure.ssd").is_file(),
    }
}

impl System {
    /// Reads the system at `path` (`.ssp`, `.ssd` or a folder) and loads its FMUs.
    pub fn open(path: &Path) -> Result<System, String> {
        let (ssd, archive) = match path.extension().and_then(|e| e.to_str()) {
            Some("ssp") => {
                if !path.is_file() {
                    return Err(format!("system file {} does not exist", path.display()));
                }
                let dir = tempfile::Builder::new()
                    .prefix("runner-ssp-")
                    .tempdir()
                    .map_err(|e| format!("cannot create a temporary directory: {e}"))?;
                fmi_importer::archive::extract_zip(path, dir.path()).map_err(|e| format!("{}: {e}", path.display()))?;
                let ssd = dir.path().join("SystemStructure.ssd");
                if !ssd.is_file() {
                    return Err(format!("{}: the archive holds no SystemStructure.ssd at its root", path.display()));
                }
                (ssd, Some(dir))
            }
            Some("ssd") => (path.to_path_buf(), None),
            _ if path.is_dir() => {
                let ssd = path.join("SystemStructure.ssd");
                if !ssd.is_file() {
                    return Err(format!("{}: the folder holds no SystemStructure.ssd", path.display()));
                }
                (ssd, None)
            }
            _ => {
                return Err(format!(
                    "{} is not a system: give a .ssp archive, a .ssd file or a folder holding SystemStructure.ssd",
                    path.display()
                ))
            }
        };
        let structure = Structure::read(&ssd)?;
        let mut components = Vec::with_capacity(structure.components.len());
        for spec in &structure.components {
            let at = |e: String| format!("component '{}': {e}", spec.name);
            let source = spec.source.strip_prefix(ssd.parent().unwrap_or(Path::new(""))).unwrap_or(&spec.source);
            if !spec.source.is_file() {
                return Err(at(format!("its FMU {} is not in the system", source.display())));
            }
            let unpacked = Unpacked::open_as(&spec.source, spec.implementation).map_err(at)?;
            let feedthrough = feedthrough(&unpacked);
            let fmu = Fmu::load_unpacked(&spec.source, unpacked.dir.path(), Some(unpacked.interface)).map_err(at)?;
            components.push(Component { name: spec.name.clone(), fmu, feedthrough, _dir: unpacked.dir });
        }
        Ok(System { path: path.to_path_buf(), structure, components, _archive: archive })
    }
}

/// Output name -> inputs it depends on, from the raw ModelStructure of either FMI version.
fn feedthrough(unpacked: &Unpacked) -> HashMap<String, Vec<String>> {
    let d = &unpacked.description;
    let inputs: Vec<String> = d.variables.iter().filter(|v| v.causality == Causality::Input).map(|v| v.name.clone()).collect();
    let mut out = HashMap::new();
    if let Some(raw) = &unpacked.fmi2 {
        for unknown in &raw.model_structure.outputs {
            let Some(output) = raw.variable_by_index(unknown.index) else { continue };
            let depends = match &unknown.dependencies {
                None => inputs.clone(),
                Some(list) => list
                    .iter()
                    .filter_map(|&i| raw.variable_by_index(i))
                    .filter(|v| inputs.contains(&v.name))
                    .map(|v| v.name.clone())
                    .collect(),
            };
            out.insert(output.name.clone(), depends);
        }
    } else if let Some(raw) = &unpacked.fmi3 {
        for unknown in &raw.model_structure.outputs {
            let Some(output) = d.variable_by_reference(unknown.value_reference) else { continue };
            let depends = match &unknown.dependencies {
                None => inputs.clone(),
                Some(list) => list
                    .iter()
                    .filter_map(|&vr| d.variable_by_reference(vr))
                    .filter(|v| v.causality == Causality::Input)
                    .map(|v| v.name.clone())
                    .collect(),
            };
            out.insert(output.name.clone(), depends);
        }
    }
    // Outputs the structure does not list depend on every input, as FMI 2.0 reads an absent list.
    for v in d.outputs() {
        out.entry(v.name.clone()).or_insert_with(|| inputs.clone());
    }
    out
}
