//! A system's FMUs: one unpacked FMU per component (two components of one FMU file are two
//! instances of two loads, so each keeps its own resources). [`System::open`] reads and checks
//! them without running any of their code; their binaries are loaded where the system runs:
//! [`System::load_binaries`] in this process, [`System::load_copy`] in a worker process, so a
//! binary that crashes as it loads costs only the worker.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use fmi_importer::{Causality, Description, Fmu, Instance, Interface, Kind, Unpacked};
use serde::{Deserialize, Serialize};

use crate::ssd::{ComponentSpec, Structure};

/// A component: its FMU and which of its outputs depend directly on which inputs.
pub struct Component {
    /// The flattened name (`car`, `sub.car`).
    pub name: String,
    pub fmu: ComponentFmu,
    /// Output name -> the inputs it depends on directly (ModelStructure; all inputs where the
    /// FMU does not say).
    pub feedthrough: HashMap<String, Vec<String>>,
    /// Where its FMU is unpacked, and through which interface it runs.
    dir: PathBuf,
    pub interface: Interface,
    // After `fmu`: the binary closes before its files go (`None`: another process's copy).
    _dir: Option<tempfile::TempDir>,
}

/// A component's FMU: what its description says, read before any of its code runs, and its
/// binary once loaded.
pub struct ComponentFmu {
    pub description: Description,
    pub interface: Interface,
    /// `None` until [`System::load_binaries`] (a worker's copy is loaded at once).
    binary: Option<Fmu>,
}

impl ComponentFmu {
    /// The loaded FMU.
    pub fn loaded(&self) -> Result<&Fmu, String> {
        self.binary.as_ref().ok_or_else(|| format!("{}'s binary is not loaded in this process", self.description.model_name))
    }

    /// A new instance ([`Fmu::instantiate`]).
    pub fn instantiate(&self, name: &str, debug_logging: bool) -> Result<Instance<'_>, String> {
        self.loaded()?.instantiate(name, debug_logging)
    }
}

/// A system, opened.
pub struct System {
    /// Where it was read from.
    pub path: PathBuf,
    /// Its SystemStructure.ssd, and the extracted archive it is in (an `.ssp`'s).
    ssd: PathBuf,
    archive_root: Option<PathBuf>,
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
        let (ssd, archive): (PathBuf, Option<tempfile::TempDir>) = match path.extension().and_then(|e| e.to_str()) {
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
        // What an archive names must be inside it; a folder's SSD may name files anywhere.
        let structure = match &archive {
            Some(dir) => Structure::read_in_archive(&ssd, dir.path()).map_err(|e| format!("{}: {e}", path.display()))?,
            None => Structure::read(&ssd)?,
        };
        let mut components = Vec::with_capacity(structure.components.len());
        for (index, spec) in structure.components.iter().enumerate() {
            let at = |e: String| format!("component '{}': {e}", spec.name);
            let source = spec.source.strip_prefix(ssd.parent().unwrap_or(Path::new(""))).unwrap_or(&spec.source);
            if !spec.source.is_file() {
                return Err(at(format!("its FMU {} is not in the system", source.display())));
            }
            let unpacked = Unpacked::open_as(&spec.source, spec.implementation).map_err(at)?;
            let linked = structure.links.iter().flat_map(|l| [&l.from, &l.to]).filter(|(c, _)| *c == index);
            check_connectors(&unpacked.description, unpacked.fmi3.as_ref(), spec, linked.map(|(_, v)| v.as_str())).map_err(at)?;
            let feedthrough = feedthrough(&unpacked);
            let (dir, interface) = (unpacked.dir.path().to_path_buf(), unpacked.interface);
            let fmu = ComponentFmu { description: unpacked.description, interface, binary: None };
            components.push(Component { name: spec.name.clone(), fmu, feedthrough, dir, interface, _dir: Some(unpacked.dir) });
        }
        let archive_root = archive.as_ref().map(|d| d.path().to_path_buf());
        Ok(System { path: path.to_path_buf(), ssd, archive_root, structure, components, _archive: archive })
    }

    /// The folder an `.ssp` archive was extracted to (a fresh temporary folder for every
    /// [`System::open`]); `None` for a system read from a folder or an `.ssd`.
    pub fn archive_root(&self) -> Option<&Path> {
        self.archive_root.as_deref()
    }

    /// Loads every component's binary into this process, to run the system here.
    pub fn load_binaries(&mut self) -> Result<(), String> {
        for (c, (component, spec)) in self.components.iter_mut().zip(&self.structure.components).enumerate() {
            if component.fmu.binary.is_none() {
                component.fmu.binary = Some(load_binary(c, &component.name, &spec.source, &component.dir, component.interface)?);
            }
        }
        Ok(())
    }

    /// Where this system's files are, for a worker process to load this copy
    /// ([`System::load_copy`]) while this process keeps it.
    pub fn files(&self) -> SystemFiles {
        SystemFiles {
            path: self.path.clone(),
            ssd: self.ssd.clone(),
            archive_root: self.archive_root.clone(),
            components: self
                .components
                .iter()
                .map(|c| ComponentFiles {
                    name: c.name.clone(),
                    dir: c.dir.clone(),
                    interface: c.interface,
                    feedthrough: c.feedthrough.clone(),
                })
                .collect(),
        }
    }

    /// Loads the system another process opened, from its copy `files` (a worker: it extracts
    /// and unpacks nothing, so if it dies it leaves nothing behind; the other process deletes
    /// the files).
    pub fn load_copy(files: &SystemFiles) -> Result<System, String> {
        let structure = match &files.archive_root {
            Some(root) => Structure::read_in_archive(&files.ssd, root).map_err(|e| format!("{}: {e}", files.path.display()))?,
            None => Structure::read(&files.ssd)?,
        };
        if structure.components.len() != files.components.len() {
            return Err(format!("{}: the system changed while it was being run", files.path.display()));
        }
        let mut components = Vec::with_capacity(files.components.len());
        for (c, (spec, copy)) in structure.components.iter().zip(&files.components).enumerate() {
            let binary = load_binary(c, &spec.name, &spec.source, &copy.dir, copy.interface)?;
            let fmu = ComponentFmu { description: binary.description.clone(), interface: binary.interface, binary: Some(binary) };
            components.push(Component {
                name: spec.name.clone(),
                fmu,
                feedthrough: copy.feedthrough.clone(),
                dir: copy.dir.clone(),
                interface: copy.interface,
                _dir: None,
            });
        }
        Ok(System {
            path: files.path.clone(),
            ssd: files.ssd.clone(),
            archive_root: files.archive_root.clone(),
            structure,
            components,
            _archive: None,
        })
    }
}

/// Loads the binary of component `c`, `name`, unpacked in `dir` from `source`; the importer's
/// call slot names the component meanwhile (a worker that dies loading it says which).
fn load_binary(c: usize, name: &str, source: &Path, dir: &Path, interface: Interface) -> Result<Fmu, String> {
    fmi_importer::trace::set_context(c as u32 + 1);
    let loaded = Fmu::load_unpacked(source, dir, Some(interface)).map_err(|e| format!("component '{name}': {e}"));
    fmi_importer::trace::set_context(0);
    loaded
}

/// Where a system opened by one process is on disk ([`System::files`]), for another to load.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SystemFiles {
    /// The system as given (for messages).
    pub path: PathBuf,
    pub ssd: PathBuf,
    pub archive_root: Option<PathBuf>,
    /// Per component, in the structure's order.
    pub components: Vec<ComponentFiles>,
}

/// Where a component's FMU is unpacked, its interface and its direct feedthrough (read from
/// the raw description when it was unpacked).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ComponentFiles {
    /// Its flattened name, for a worker's reports before the structure is read.
    pub name: String,
    pub dir: PathBuf,
    pub interface: Interface,
    pub feedthrough: HashMap<String, Vec<String>>,
}

/// The SSD's connectors against the FMU: a connector's declared type must be its variable's
/// (SSP calls a difference an error), and a connected variable must be a scalar value that no
/// clock governs (FMI 3.0 arrays, Clocks and clocked variables are refused by name; the master
/// passes scalar values once per step). `d` is the FMU's description, `fmi3` its FMI 3.0 one as
/// written (clocks are there); `linked`: the component's connected variables.
fn check_connectors<'n>(
    d: &Description,
    fmi3: Option<&fmi_schema::fmi3::ModelDescription>,
    spec: &ComponentSpec,
    linked: impl Iterator<Item = &'n str>,
) -> Result<(), String> {
    for c in &spec.connectors {
        let (Some(declared), Some(v)) = (c.data_type, d.variable(&c.name)) else { continue };
        if !declared.accepts(v.kind) {
            return Err(format!(
                "connector '{}' (line {}) is declared {}, but the FMU's variable '{}' is {}",
                c.name,
                c.line,
                declared.as_str(),
                v.name,
                v.kind.name_in(d.fmi_version)
            ));
        }
    }
    for name in linked {
        let Some(v) = d.variable(name) else { continue };
        if v.kind == Kind::Clock {
            return Err(format!("'{name}' is a Clock: clocked connections are not supported"));
        }
        if v.is_array() {
            return Err(format!("'{name}' is an array variable: array connections are not supported, only scalars"));
        }
        let clocks = fmi3.and_then(|raw| raw.variable(name)).and_then(|raw| raw.clocks.as_ref());
        if let Some(clocks) = clocks.filter(|c| !c.is_empty()) {
            let names: Vec<String> =
                clocks.iter().map(|&vr| d.variable_by_reference(vr).map_or(format!("valueReference {vr}"), |c| c.name.clone())).collect();
            return Err(format!("'{name}' is clocked by {}: clocked connections are not supported", names.join(", ")));
        }
    }
    Ok(())
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

/// An SSD's connectors against an FMI 3.0 FMU's variables: declared types must match, and
/// connected Clocks, clocked variables and arrays are refused by name.
#[cfg(test)]
mod connectors {
    use super::*;
    use crate::ssd::{Connector, ConnectorType};

    const XML: &str = r#"<fmiModelDescription fmiVersion="3.0" modelName="m" instantiationToken="t"><CoSimulation modelIdentifier="m"/><ModelVariables>
<Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
<Float64 name="y" valueReference="1" causality="output" variability="continuous"/>
<Int32 name="n" valueReference="2" causality="input" start="0"/>
<Clock name="tick" valueReference="3" causality="input" intervalVariability="constant" intervalDecimal="1"/>
<Int32 name="count" valueReference="4" causality="output" variability="discrete" clocks="3"/>
<Float64 name="v" valueReference="5" causality="output" variability="continuous"><Dimension start="2"/></Float64>
</ModelVariables><ModelStructure><Output valueReference="1"/><Output valueReference="4"/><Output valueReference="5"/></ModelStructure></fmiModelDescription>"#;

    fn check(declared: &[(&str, ConnectorType)], linked: &[&str]) -> Result<(), String> {
        let raw = fmi_schema::fmi3::ModelDescription::from_xml(XML).unwrap();
        let d = fmi_importer::fmi3::describe(&raw);
        let spec = ComponentSpec {
            name: "a".into(),
            source: PathBuf::from("a.fmu"),
            implementation: None,
            connector_units: HashMap::new(),
            connectors: declared.iter().map(|(n, t)| Connector { name: (*n).into(), data_type: Some(*t), line: 9 }).collect(),
            parameters: Vec::new(),
        };
        check_connectors(&d, Some(&raw), &spec, linked.iter().copied())
    }

    #[test]
    fn declared_types_must_be_the_variables() {
        assert_eq!(check(&[("y", ConnectorType::Exact(Kind::Real)), ("n", ConnectorType::Exact(Kind::Integer))], &["y", "n"]), Ok(()));
        assert_eq!(check(&[("y", ConnectorType::Real), ("n", ConnectorType::Integer)], &[]), Ok(()), "SSP 1.0's types fit any width");
        assert_eq!(
            check(&[("n", ConnectorType::Exact(Kind::Int8))], &[]).unwrap_err(),
            "connector 'n' (line 9) is declared Int8, but the FMU's variable 'n' is Int32"
        );
        assert_eq!(
            check(&[("y", ConnectorType::Exact(Kind::Float32))], &[]).unwrap_err(),
            "connector 'y' (line 9) is declared Float32, but the FMU's variable 'y' is Float64"
        );
    }

    #[test]
    fn connected_clocks_clocked_variables_and_arrays_are_refused() {
        assert_eq!(check(&[], &["tick"]).unwrap_err(), "'tick' is a Clock: clocked connections are not supported");
        assert_eq!(check(&[], &["count"]).unwrap_err(), "'count' is clocked by tick: clocked connections are not supported");
        assert_eq!(check(&[], &["v"]).unwrap_err(), "'v' is an array variable: array connections are not supported, only scalars");
        // Unconnected, they are no concern of the master's.
        assert_eq!(check(&[], &["y"]), Ok(()));
    }
}

/// Hostile archives: a system someone sends may only use the files it holds. Each archive
/// below would make the runner load or read a file from elsewhere on the machine; each must
/// be refused before anything is loaded, with a message that names the component or file.
#[cfg(test)]
mod hostile_archives {
    use std::io::Write;

    use super::*;

    const HEAD: &str = r#"<?xml version="1.0"?><ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping" version="1.0" name="hostile">"#;

    /// An SSD with one component `a` whose source is `source` and whose element holds `inner`.
    fn ssd(source: &str, inner: &str) -> String {
        format!(
            r#"{HEAD}<ssd:System name="s"><ssd:Elements><ssd:Component name="a" source="{source}">{inner}</ssd:Component></ssd:Elements></ssd:System></ssd:SystemStructureDescription>"#
        )
    }

    fn binding(source: &str) -> String {
        format!(r#"<ssd:ParameterBindings><ssd:ParameterBinding source="{source}"/></ssd:ParameterBindings>"#)
    }

    /// Writes an .ssp holding `files` (name, bytes) and `links` (name, target) into `dir`.
    fn archive(dir: &Path, files: &[(&str, &[u8])], links: &[(&str, &str)]) -> PathBuf {
        let path = dir.join("hostile.ssp");
        let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
        let options = zip::write::SimpleFileOptions::default();
        for (name, bytes) in files {
            zip.start_file(*name, options).unwrap();
            zip.write_all(bytes).unwrap();
        }
        for (name, target) in links {
            zip.add_symlink(*name, *target, options).unwrap();
        }
        zip.finish().unwrap();
        path
    }

    /// A file outside the archive that a hostile SSD points at (it must never be opened).
    fn outside(dir: &Path, name: &str) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, b"not to be read").unwrap();
        path
    }

    fn refusal(files: &[(&str, &[u8])], links: &[(&str, &str)]) -> String {
        let dir = tempfile::tempdir().unwrap();
        match System::open(&archive(dir.path(), files, links)) {
            Ok(_) => panic!("a hostile archive was opened"),
            Err(e) => e,
        }
    }

    fn assert_names(e: &str, parts: &[&str]) {
        for part in parts {
            assert!(e.contains(part), "the refusal should say {part:?}: {e}");
        }
    }

    #[test]
    fn an_absolute_source_is_refused_by_component() {
        let dir = tempfile::tempdir().unwrap();
        let evil = outside(dir.path(), "evil.fmu");
        let e = refusal(&[("SystemStructure.ssd", ssd(&evil.display().to_string(), "").as_bytes())], &[]);
        assert_names(&e, &["component 'a'", "absolute path", "hostile.ssp"]);
    }

    #[test]
    fn a_file_uri_or_any_scheme_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let evil = outside(dir.path(), "evil.fmu");
        for source in [
            format!("file://{}", evil.display()),
            format!("file:{}", evil.display()),
            "file:resources/a.fmu".into(),
            "https://example.org/a.fmu".into(),
        ] {
            let e = refusal(&[("SystemStructure.ssd", ssd(&source, "").as_bytes())], &[]);
            assert_names(&e, &["component 'a'", "is a URI"]);
        }
    }

    #[test]
    fn dot_dot_out_of_the_archive_is_refused_in_sources_parameter_files_and_mappings() {
        let e = refusal(&[("SystemStructure.ssd", ssd("resources/../../a.fmu", "").as_bytes())], &[]);
        assert_names(&e, &["component 'a'", "leaves the archive"]);
        let e = refusal(&[("SystemStructure.ssd", ssd("a.fmu", &binding("../../../etc/passwd")).as_bytes()), ("a.fmu", b"x")], &[]);
        assert_names(&e, &["the parameter file", "leaves the archive"]);
        let mapping = r#"<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" name="p"><ssv:Parameters/></ssv:ParameterSet></ssd:ParameterValues><ssd:ParameterMapping source="/etc/passwd"/></ssd:ParameterBinding></ssd:ParameterBindings>"#;
        let e = refusal(&[("SystemStructure.ssd", ssd("a.fmu", mapping).as_bytes()), ("a.fmu", b"x")], &[]);
        assert_names(&e, &["the parameter mapping", "absolute path"]);
    }

    #[test]
    fn an_absolute_parameter_file_is_refused_even_when_it_exists() {
        let dir = tempfile::tempdir().unwrap();
        let ssv = outside(dir.path(), "p.ssv");
        let e = refusal(&[("SystemStructure.ssd", ssd("a.fmu", &binding(&ssv.display().to_string())).as_bytes()), ("a.fmu", b"x")], &[]);
        assert_names(&e, &["the parameter file", "absolute path"]);
    }

    /// Parameter files and mappings follow the components' rule: a `file:` URI or any other
    /// scheme is refused naming the binding, even when the file it names exists.
    #[test]
    fn a_uri_for_a_parameter_file_or_mapping_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let ssv = outside(dir.path(), "p.ssv");
        for source in [format!("file://{}", ssv.display()), format!("file:{}", ssv.display()), "https://example.org/p.ssv".into()] {
            let e = refusal(&[("SystemStructure.ssd", ssd("a.fmu", &binding(&source)).as_bytes()), ("a.fmu", b"x")], &[]);
            assert_names(&e, &["the parameter file", "is a URI"]);
            let mapping = format!(
                r#"<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" name="p"><ssv:Parameters/></ssv:ParameterSet></ssd:ParameterValues><ssd:ParameterMapping source="{source}"/></ssd:ParameterBinding></ssd:ParameterBindings>"#
            );
            let e = refusal(&[("SystemStructure.ssd", ssd("a.fmu", &mapping).as_bytes()), ("a.fmu", b"x")], &[]);
            assert_names(&e, &["the parameter mapping", "is a URI"]);
        }
    }

    /// A parameter file that is a symbolic link to a file outside is refused like a linked FMU.
    #[test]
    fn a_symbolic_link_as_a_parameter_file_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let ssv = outside(dir.path(), "p.ssv");
        let e = refusal(
            &[("SystemStructure.ssd", ssd("a.fmu", &binding("resources/p.ssv")).as_bytes()), ("a.fmu", b"x")],
            &[("resources/p.ssv", &ssv.display().to_string())],
        );
        assert_names(&e, &["symbolic link"]);
    }

    #[test]
    fn a_symbolic_link_in_the_archive_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let evil = outside(dir.path(), "evil.fmu");
        let e =
            refusal(&[("SystemStructure.ssd", ssd("resources/a.fmu", "").as_bytes())], &[("resources/a.fmu", &evil.display().to_string())]);
        assert_names(&e, &["symbolic link"]);
    }

    #[test]
    fn an_ssd_that_names_itself_is_refused() {
        let e = refusal(&[("SystemStructure.ssd", ssd("SystemStructure.ssd", "").as_bytes())], &[]);
        assert_names(&e, &["component 'a'", "is the system structure itself"]);
        let e = refusal(&[("SystemStructure.ssd", ssd("./resources/../SystemStructure.ssd", "").as_bytes())], &[]);
        assert_names(&e, &["component 'a'", "is the system structure itself"]);
        // As its own parameter file: read, and refused for what it is.
        let e = refusal(&[("SystemStructure.ssd", ssd("a.fmu", &binding("SystemStructure.ssd")).as_bytes()), ("a.fmu", b"x")], &[]);
        assert_names(&e, &["SystemStructure.ssd", "not <ssv:ParameterSet>"]);
    }

    /// The rule's other side: what the archive holds resolves inside it, `..` that stays
    /// inside included; a folder's SSD still names files beside it (or anywhere: the user's own).
    #[test]
    fn files_inside_the_archive_and_beside_a_folder_ssd_resolve() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        std::fs::create_dir(root.join("resources")).unwrap();
        std::fs::write(root.join("resources/p.ssv"), r#"<ssv:ParameterSet xmlns:ssv="v" version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="k"><ssv:Real value="2"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>"#).unwrap();
        let path = root.join("SystemStructure.ssd");
        std::fs::write(&path, ssd("resources/../resources/a.fmu", &binding("./resources/p.ssv"))).unwrap();
        let s = Structure::read_in_archive(&path, root).unwrap();
        assert_eq!(s.components[0].source, root.join("resources/a.fmu"));
        assert_eq!(s.components[0].parameters[0].variable, "k");
        let elsewhere = tempfile::tempdir().unwrap();
        let fmu = outside(elsewhere.path(), "b.fmu");
        std::fs::write(&path, ssd(&fmu.display().to_string(), "")).unwrap();
        assert_eq!(Structure::read(&path).unwrap().components[0].source, fmu);
    }
}
