//! Reading an SSP 1.0 or 2.0 system structure: the SystemStructure.ssd, its parameter files
//! (.ssv) and parameter mappings (.ssm), into a flat [`Structure`]: FMU components named by their
//! path (`car`, or `sub.car` inside a nested system), the connections between FMU variables with
//! nested systems' connectors resolved, and the parameter values each component gets.
//!
//! SSP 2.0 keeps SSP 1.0's namespaces (`http://ssp-standard.org/SSP1/...`) and says
//! `version="2.0"`; what it adds for FMI 3.0 is read here: the types Float64, Float32 and Int8 to
//! UInt64 on connectors and in parameter files. Its array connectors (`ssc:Dimension`,
//! `startIndices`), clocks (`ssc:Clock` connectors) and clocked connectors (`ssd:Clock`) are
//! refused, naming the connector: the master passes scalar values once per step.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use fmi_importer::{Interface, Kind};

use crate::xml::{self, Element};

/// A value a parameter binding assigns.
#[derive(Debug, Clone, PartialEq)]
pub enum ParameterValue {
    /// A Real, with the unit it is given in (`None`: the variable's own).
    Real(f64, Option<String>),
    Integer(i64),
    Boolean(bool),
    String(String),
}

/// One parameter value for one variable of a component.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// The variable's name in the FMU.
    pub variable: String,
    pub value: ParameterValue,
    /// Where it came from (file and line), for messages.
    pub origin: String,
}

/// The type an SSD gives a connector: SSP 1.0's Real and Integer, which stand for any width, or
/// one of SSP 2.0's FMI 3.0 types.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConnectorType {
    /// `ssc:Real`: a Float64 or Float32 variable (FMI 2.0's Real).
    Real,
    /// `ssc:Integer`: an integer variable of any width.
    Integer,
    /// `ssc:Float64`, `ssc:Int8`, `ssc:Boolean`, ...: a variable of exactly this type
    /// (Float64 is [`Kind::Real`], Int32 is [`Kind::Integer`]).
    Exact(Kind),
}

impl ConnectorType {
    /// The type of the element named `name` (`Real`, `Float64`, `UInt16`, ...); `None` for
    /// `Clock` and what is not a type.
    pub fn from_element(name: &str) -> Option<ConnectorType> {
        Some(match name {
            "Real" => ConnectorType::Real,
            "Integer" => ConnectorType::Integer,
            "Float64" => ConnectorType::Exact(Kind::Real),
            "Float32" => ConnectorType::Exact(Kind::Float32),
            "Int8" => ConnectorType::Exact(Kind::Int8),
            "UInt8" => ConnectorType::Exact(Kind::UInt8),
            "Int16" => ConnectorType::Exact(Kind::Int16),
            "UInt16" => ConnectorType::Exact(Kind::UInt16),
            "Int32" => ConnectorType::Exact(Kind::Integer),
            "UInt32" => ConnectorType::Exact(Kind::UInt32),
            "Int64" => ConnectorType::Exact(Kind::Int64),
            "UInt64" => ConnectorType::Exact(Kind::UInt64),
            "Boolean" => ConnectorType::Exact(Kind::Boolean),
            "String" => ConnectorType::Exact(Kind::String),
            "Enumeration" => ConnectorType::Exact(Kind::Enumeration),
            "Binary" => ConnectorType::Exact(Kind::Binary),
            _ => return None,
        })
    }

    /// The SSP element's name.
    pub fn as_str(self) -> &'static str {
        match self {
            ConnectorType::Real => "Real",
            ConnectorType::Integer => "Integer",
            ConnectorType::Exact(kind) => kind.name_in(fmi_importer::FmiVersion::Fmi3),
        }
    }

    /// True when a variable of type `kind` fits a connector of this type (SSP: a connector's
    /// type that differs from its FMU variable's is an error).
    pub fn accepts(self, kind: Kind) -> bool {
        match self {
            ConnectorType::Real => matches!(kind, Kind::Real | Kind::Float32),
            ConnectorType::Integer => kind.integer_range().is_some(),
            ConnectorType::Exact(k) => k == kind,
        }
    }
}

/// A connector an SSD declares on an FMU component.
#[derive(Debug, Clone, PartialEq)]
pub struct Connector {
    /// The FMU variable's name.
    pub name: String,
    /// Its type, when the SSD gives one.
    pub data_type: Option<ConnectorType>,
    /// The SSD's line, for messages.
    pub line: usize,
}

/// An FMU component of the flattened system.
#[derive(Debug, Clone)]
pub struct ComponentSpec {
    /// Its name, with the names of the systems it is nested in: `sub.car`.
    pub name: String,
    /// The FMU file.
    pub source: PathBuf,
    /// The interface the SSD asks for (`None`: any, Co-Simulation when the FMU offers it).
    pub implementation: Option<Interface>,
    /// The unit of each connector that declares one.
    pub connector_units: HashMap<String, String>,
    /// The connectors the SSD declares, in its order.
    pub connectors: Vec<Connector>,
    /// Parameter values, in the order they apply (a later one wins).
    pub parameters: Vec<Assignment>,
}

/// A connection between two FMU variables after flattening.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    /// Component index and variable of the start (an output).
    pub from: (usize, String),
    /// Component index and variable of the end (an input).
    pub to: (usize, String),
    /// `end = factor * start + offset`, when the SSD gives a LinearTransformation (composed
    /// along nested systems' connectors); then no unit conversion is added.
    pub transformation: Option<(f64, f64)>,
    /// No unit conversion (`suppressUnitConversion="true"` on a connection on the way).
    pub suppress_unit_conversion: bool,
    /// The SSD's line of the first connection on the way, for messages.
    pub line: usize,
}

/// A unit in SI base units: `value_in_si = factor * value + offset`, exponents of kg, m, s,
/// A, K, mol, cd, rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitDefinition {
    pub exponents: [i32; 8],
    pub factor: f64,
    pub offset: f64,
}

/// The experiment the SSD proposes.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Experiment {
    pub start: Option<f64>,
    pub stop: Option<f64>,
    /// The communication step from an annotation (libcosim's `osp:FixedStepAlgorithm
    /// baseStepSize`).
    pub step: Option<f64>,
}

/// A flattened system structure.
#[derive(Debug, Clone)]
pub struct Structure {
    /// The SSD's name.
    pub name: String,
    pub components: Vec<ComponentSpec>,
    pub links: Vec<Link>,
    pub units: HashMap<String, UnitDefinition>,
    pub experiment: Experiment,
}

/// `y = factor * x + offset`.
pub type Transformation = (f64, f64);

/// A connection as written: start node, end node, transformation, suppressUnitConversion, line.
type Edge = (String, String, Option<Transformation>, bool, usize);

/// A parameter mapping: parameter name -> (target name, transformation).
type Mapping = HashMap<String, (String, Option<Transformation>)>;

/// Builds a [`Structure`] while walking the SSD.
struct Reader<'a> {
    /// The SSD's directory: sources are relative to it.
    base: &'a Path,
    /// Where every file the SSD names must lie (an extracted `.ssp` archive), and the SSD
    /// itself; `None` for an SSD the user keeps in a folder, which may name any file.
    confined: Option<(&'a Path, &'a Path)>,
    file: String,
    components: Vec<ComponentSpec>,
    /// Connector node ("path.connector") of each FMU component's connectors.
    fmu_nodes: HashMap<String, (usize, String)>,
    /// Every connection: start node, end node, transformation, suppress, line.
    edges: Vec<Edge>,
    units: HashMap<String, UnitDefinition>,
    /// System-level bindings: (system path prefix, assignment with a dotted name).
    system_bindings: Vec<(String, Assignment)>,
}

impl Structure {
    /// Reads the SSD at `path` and the files it references (relative to its folder; an SSD the
    /// user keeps in a folder may also name files elsewhere on the machine).
    pub fn read(path: &Path) -> Result<Structure, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let base = path.parent().unwrap_or(Path::new("."));
        Structure::parse_with(&text, base, &path.display().to_string(), None)
    }

    /// Reads the SSD at `path` in an extracted archive `root`: every FMU, parameter file and
    /// mapping it names must be a path inside `root`. An archive is what someone sends, and an
    /// FMU is code: an absolute path, a URI (`file:` or any other scheme), a `..` that leaves
    /// the archive or a link that points out of it is refused, naming the component or file.
    pub fn read_in_archive(path: &Path, root: &Path) -> Result<Structure, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let base = path.parent().unwrap_or(Path::new("."));
        let name = path.strip_prefix(root).unwrap_or(path).display().to_string();
        Structure::parse_with(&text, base, &name, Some((root, path)))
    }

    /// Reads SSD `text` (the file `file`, its references relative to `base`).
    pub fn parse(text: &str, base: &Path, file: &str) -> Result<Structure, String> {
        Structure::parse_with(text, base, file, None)
    }

    /// [`Structure::parse`], the references confined to `confined`'s root (see
    /// [`Structure::read_in_archive`]; its second path is the SSD itself).
    fn parse_with(text: &str, base: &Path, file: &str, confined: Option<(&Path, &Path)>) -> Result<Structure, String> {
        let root = xml::parse(text, file)?;
        if root.name != "SystemStructureDescription" {
            return Err(format!("{file}: the root element is <{}>, not <ssd:SystemStructureDescription>", root.name));
        }
        let version = root.attribute("version").unwrap_or("");
        if !(version.starts_with("1.") || version.starts_with("2.")) {
            return Err(format!("{file}: SSP version '{version}' is not supported (1.0 or 2.0)"));
        }
        let mut reader = Reader {
            base,
            confined,
            file: file.to_owned(),
            components: Vec::new(),
            fmu_nodes: HashMap::new(),
            edges: Vec::new(),
            units: HashMap::new(),
            system_bindings: Vec::new(),
        };
        if let Some(units) = root.child("Units") {
            reader.read_units(units, file)?;
        }
        let system = root.child("System").ok_or_else(|| format!("{file}: no <ssd:System>"))?;
        let name = root.attribute("name").unwrap_or("system").to_owned();
        reader.read_system(system, "")?;
        let experiment = match root.child("DefaultExperiment") {
            Some(e) => Experiment { start: e.number("startTime", file)?, stop: e.number("stopTime", file)?, step: fixed_step(e, file)? },
            None => Experiment::default(),
        };
        let links = reader.flatten()?;
        let Reader { mut components, system_bindings, units, .. } = reader;
        // System-level bindings name `component.variable` from the system they are bound at.
        for (prefix, mut assignment) in system_bindings {
            let full = format!("{prefix}{}", assignment.variable);
            let (index, variable) = split_component(&components, &full)
                .ok_or_else(|| format!("{}: parameter '{full}' names no component of the system", assignment.origin))?;
            assignment.variable = variable.to_owned();
            components[index].parameters.push(assignment);
        }
        if components.is_empty() {
            return Err(format!("{file}: the system has no FMU components"));
        }
        Ok(Structure { name, components, links, units, experiment })
    }

    /// The component index and variable name of `COMPONENT.VARIABLE` (the longest component
    /// name that fits, as variable names may hold dots too).
    pub fn split<'n>(&self, name: &'n str) -> Option<(usize, &'n str)> {
        split_component(&self.components, name)
    }
}

/// The component and the rest of a dotted `name`: the longest component name that is a prefix.
pub fn split_component<'n>(components: &[ComponentSpec], name: &'n str) -> Option<(usize, &'n str)> {
    components
        .iter()
        .enumerate()
        .filter(|(_, c)| name.len() > c.name.len() + 1 && name.starts_with(&c.name) && name.as_bytes()[c.name.len()] == b'.')
        .max_by_key(|(_, c)| c.name.len())
        .map(|(i, c)| (i, &name[c.name.len() + 1..]))
}

/// The step of a FixedStepAlgorithm annotation anywhere under the DefaultExperiment.
fn fixed_step(e: &Element, file: &str) -> Result<Option<f64>, String> {
    if e.name == "FixedStepAlgorithm" {
        return e.number("baseStepSize", file);
    }
    for c in &e.children {
        if let Some(step) = fixed_step(c, file)? {
            return Ok(Some(step));
        }
    }
    Ok(None)
}

/// The connector `c` of the element `owner` and its unit (Real, Float64 and Float32 have one),
/// or why it is refused: an array connector (`ssc:Dimension`), a clock (`ssc:Clock`, the type)
/// or a clocked connector (`ssd:Clock name=...`, the association with a clock).
fn connector<'e>(c: &'e Element, owner: &str, file: &str) -> Result<(Connector, Option<&'e str>), String> {
    let name = c.required("name", file)?;
    let at = |what: String| format!("{file}, line {}: connector '{name}' of {owner} {what}", c.line);
    if c.child("Dimension").is_some() {
        let sizes: Vec<&str> =
            c.children("Dimension").map(|d| d.attribute("size").or(d.attribute("sizeConnector")).unwrap_or("?")).collect();
        return Err(at(format!(
            "is an array connector (ssc:Dimension, sizes {}): array connectors are not supported, only scalars",
            sizes.join(" x ")
        )));
    }
    // Both the type Clock and the association with a clock are a `Clock` element; the
    // association alone has a name.
    if let Some(clock) = c.child("Clock") {
        return Err(match clock.attribute("name") {
            Some(by) => at(format!("is clocked by clock '{by}' (ssd:Clock): clocked connectors are not supported")),
            None => at("is a Clock (ssc:Clock): clocks are not supported".to_owned()),
        });
    }
    let typed = c.children.iter().find_map(|t| ConnectorType::from_element(&t.name).map(|ty| (ty, t)));
    let unit = typed.and_then(|(_, t)| t.attribute("unit"));
    let connector = Connector { name: name.to_owned(), data_type: typed.map(|(ty, _)| ty), line: c.line };
    Ok((connector, unit))
}

fn linear_transformation(e: &Element, file: &str) -> Result<Option<(f64, f64)>, String> {
    if let Some(t) = e.child("LinearTransformation") {
        return Ok(Some((t.number("factor", file)?.unwrap_or(1.0), t.number("offset", file)?.unwrap_or(0.0))));
    }
    for other in ["BooleanMappingTransformation", "IntegerMappingTransformation", "EnumerationMappingTransformation"] {
        if let Some(t) = e.child(other) {
            return Err(format!("{file}, line {}: <ssc:{other}> is not supported (only LinearTransformation)", t.line));
        }
    }
    Ok(None)
}

impl Reader<'_> {
    fn read_units(&mut self, units: &Element, file: &str) -> Result<(), String> {
        for unit in units.children("Unit") {
            let name = unit.required("name", file)?.to_owned();
            let base = unit.child("BaseUnit");
            let mut exponents = [0i32; 8];
            for (k, key) in ["kg", "m", "s", "A", "K", "mol", "cd", "rad"].iter().enumerate() {
                if let Some(b) = base {
                    if let Some(x) = b.number(key, file)? {
                        exponents[k] = x as i32;
                    }
                }
            }
            let factor = match base {
                Some(b) => b.number("factor", file)?.unwrap_or(1.0),
                None => 1.0,
            };
            let offset = match base {
                Some(b) => b.number("offset", file)?.unwrap_or(0.0),
                None => 0.0,
            };
            self.units.insert(name, UnitDefinition { exponents, factor, offset });
        }
        Ok(())
    }

    /// Reads the system `system` whose elements are named with `prefix` (`""` at the top,
    /// `"sub."` inside the nested system `sub`).
    fn read_system(&mut self, system: &Element, prefix: &str) -> Result<(), String> {
        let file = self.file.clone();
        // The system's own connectors are the nodes "<path>.<connector>", which is what its
        // parent's connections call "<name>.<connector>".
        let own = prefix.strip_suffix('.').unwrap_or("");
        // A system's own connectors carry no type the run needs, but an array or a clock there
        // is refused as on a component.
        if let Some(connectors) = system.child("Connectors") {
            for c in connectors.children("Connector") {
                let owner = if own.is_empty() { "the top system".to_owned() } else { format!("system '{own}'") };
                connector(c, &owner, &file)?;
            }
        }
        if let Some(bindings) = system.child("ParameterBindings") {
            for assignment in self.read_bindings(bindings, &file)? {
                self.system_bindings.push((prefix.to_owned(), assignment));
            }
        }
        if let Some(elements) = system.child("Elements") {
            for element in &elements.children {
                let name = element.required("name", &file)?;
                if name.contains('.') {
                    return Err(format!(
                        "{file}, line {}: element name '{name}' must not contain a dot (names are joined with dots)",
                        element.line
                    ));
                }
                let path = format!("{prefix}{name}");
                match element.name.as_str() {
                    "Component" => self.read_component(element, path, &file)?,
                    "System" => self.read_system(element, &format!("{path}."))?,
                    "SignalDictionaryReference" => {
                        return Err(format!("{file}, line {}: signal dictionaries are not supported ('{path}')", element.line))
                    }
                    other => return Err(format!("{file}, line {}: unknown element <{other}> '{path}'", element.line)),
                }
            }
        }
        if let Some(connections) = system.child("Connections") {
            for c in connections.children("Connection") {
                let node = |element: Option<&str>, connector: &str| match element {
                    Some(e) => format!("{prefix}{e}.{connector}"),
                    None if own.is_empty() => format!(".{connector}"),
                    None => format!("{own}.{connector}"),
                };
                let start = node(c.attribute("startElement"), c.required("startConnector", &file)?);
                let end = node(c.attribute("endElement"), c.required("endConnector", &file)?);
                for (indices, connector) in [("startIndices", &start), ("endIndices", &end)] {
                    if let Some(list) = c.attribute(indices) {
                        return Err(format!(
                            "{file}, line {}: the connection from '{start}' to '{end}' selects elements {list} of the array connector '{connector}' ({indices}): array connectors are not supported",
                            c.line
                        ));
                    }
                }
                let suppress = c.flag("suppressUnitConversion", &file)?.unwrap_or(false);
                self.edges.push((start, end, linear_transformation(c, &file)?, suppress, c.line));
            }
        }
        Ok(())
    }

    fn read_component(&mut self, element: &Element, path: String, file: &str) -> Result<(), String> {
        let kind = element.attribute("type").unwrap_or("application/x-fmu-sharedlibrary");
        if kind != "application/x-fmu-sharedlibrary" {
            return Err(format!(
                "{file}, line {}: component '{path}' is of type '{kind}': only FMUs (application/x-fmu-sharedlibrary) are supported; nest a referenced system as an <ssd:System> to have it flattened",
                element.line
            ));
        }
        let at = || format!("{file}, line {}: component '{path}'", element.line);
        // SSP 2.0 lets an architecture name components before their implementations exist.
        let source = element.attribute("source").ok_or_else(|| {
            format!(
                "{}: no source: the component has no FMU to run (SSP 2.0 allows that for an architecture, not for a system to simulate)",
                at()
            )
        })?;
        let source = match self.confined {
            Some(_) => self.inside(source, &at)?,
            None => {
                let relative = source.strip_prefix("file:").unwrap_or(source);
                if relative.contains("://") || relative.starts_with('/') && source.starts_with("file:") && relative.starts_with("//") {
                    return Err(format!("{}: source '{source}' must be a path relative to the SSD", at()));
                }
                self.base.join(relative)
            }
        };
        if let Some((_, ssd)) = self.confined {
            if source == ssd {
                return Err(format!(
                    "{}: its source '{}' is the system structure itself, not an FMU",
                    at(),
                    element.required("source", file)?
                ));
            }
        }
        let implementation = match element.attribute("implementation").unwrap_or("any") {
            "any" => None,
            "CoSimulation" => Some(Interface::CoSimulation),
            "ModelExchange" => Some(Interface::ModelExchange),
            other => {
                return Err(format!(
                    "{file}, line {}: component '{path}': implementation '{other}' is not supported (CoSimulation, ModelExchange or any)",
                    element.line
                ))
            }
        };
        let index = self.components.len();
        let mut connector_units = HashMap::new();
        let mut connectors = Vec::new();
        if let Some(list) = element.child("Connectors") {
            for c in list.children("Connector") {
                let (declared, unit) = connector(c, &format!("component '{path}'"), file)?;
                if let Some(unit) = unit {
                    connector_units.insert(declared.name.clone(), unit.to_owned());
                }
                self.fmu_nodes.insert(format!("{path}.{}", declared.name), (index, declared.name.clone()));
                connectors.push(declared);
            }
        }
        let parameters = match element.child("ParameterBindings") {
            Some(b) => self.read_bindings(b, file)?,
            None => Vec::new(),
        };
        self.components.push(ComponentSpec { name: path, source, implementation, connector_units, connectors, parameters });
        Ok(())
    }

    /// The file a parameter binding or mapping names: beside the SSD, and inside the archive
    /// when the SSD is in one.
    fn reference(&self, source: &str, at: &dyn Fn() -> String) -> Result<PathBuf, String> {
        match self.confined {
            Some(_) => self.inside(source, at),
            None => Ok(self.base.join(source)),
        }
    }

    /// `source` resolved inside the archive (`self.confined`), or why it is refused: `at`
    /// names what refers to it (the component, or the file and line of a binding).
    fn inside(&self, source: &str, at: &dyn Fn() -> String) -> Result<PathBuf, String> {
        let (root, _) = self.confined.expect("only for an SSD in an archive");
        let refuse = |why: &str| Err(format!("{}: source '{source}' {why}; a system archive may only use the files it holds", at()));
        // A URI scheme: letters, digits, '+', '-', '.', then ':' (RFC 3986), before any '/'.
        let scheme = source.split_once(':').is_some_and(|(s, _)| {
            s.starts_with(|c: char| c.is_ascii_alphabetic()) && s.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
        });
        if scheme {
            return refuse("is a URI, not a path inside the archive");
        }
        if source.starts_with('/') || source.starts_with('\\') {
            return refuse("is an absolute path, outside the archive");
        }
        // Resolved by its words first, from the SSD's folder: a `..` may step back inside the
        // archive, never out of it.
        let mut inside = self.base.strip_prefix(root).map_or_else(|_| PathBuf::new(), Path::to_path_buf);
        for part in Path::new(source).components() {
            match part {
                std::path::Component::Normal(p) => inside.push(p),
                std::path::Component::CurDir => {}
                std::path::Component::ParentDir => {
                    if !inside.pop() {
                        return refuse("leaves the archive through '..'");
                    }
                }
                std::path::Component::RootDir | std::path::Component::Prefix(_) => {
                    return refuse("is an absolute path, outside the archive")
                }
            }
        }
        let path = root.join(&inside);
        // Then by the file system: the archive reader refuses links, but the check holds even
        // if one got there (a link resolved to somewhere outside the extracted folder).
        if let (Ok(real), Ok(real_root)) = (path.canonicalize(), root.canonicalize()) {
            if !real.starts_with(&real_root) {
                return refuse("leads out of the archive through a symbolic link");
            }
        }
        Ok(path)
    }

    /// The assignments of every ParameterBinding in `bindings`, names relative to the element.
    fn read_bindings(&mut self, bindings: &Element, file: &str) -> Result<Vec<Assignment>, String> {
        let mut out = Vec::new();
        for binding in bindings.children("ParameterBinding") {
            let prefix = binding.attribute("prefix").unwrap_or("");
            let (set, set_file) = match binding.attribute("source") {
                Some(source) => {
                    let path = self.reference(source, &|| format!("{file}, line {}: the parameter file", binding.line))?;
                    let text = std::fs::read_to_string(&path)
                        .map_err(|e| format!("{file}, line {}: cannot read the parameter file {source}: {e}", binding.line))?;
                    (xml::parse(&text, source)?, source.to_owned())
                }
                None => {
                    let values = binding
                        .child("ParameterValues")
                        .ok_or_else(|| format!("{file}, line {}: a ParameterBinding needs a source or ParameterValues", binding.line))?;
                    let set = values
                        .child("ParameterSet")
                        .ok_or_else(|| format!("{file}, line {}: ParameterValues holds no ssv:ParameterSet", values.line))?;
                    (set.clone(), file.to_owned())
                }
            };
            if set.name != "ParameterSet" {
                return Err(format!("{set_file}: the root element is <{}>, not <ssv:ParameterSet>", set.name));
            }
            if let Some(units) = set.child("Units") {
                self.read_units(units, &set_file)?;
            }
            let mapping = match binding.child("ParameterMapping") {
                Some(m) => self.read_mapping(m, file)?,
                None => HashMap::new(),
            };
            let parameters = set.child("Parameters").map(|p| p.children("Parameter").collect::<Vec<_>>()).unwrap_or_default();
            for p in parameters {
                let name = p.required("name", &set_file)?;
                let origin = format!("{set_file}, line {}", p.line);
                let mut value = parameter_value(p, &set_file)?;
                let target = match mapping.get(name) {
                    Some((target, transformation)) => {
                        if let (Some((factor, offset)), ParameterValue::Real(x, _)) = (transformation, &value) {
                            value = ParameterValue::Real(factor * x + offset, None);
                        }
                        target.clone()
                    }
                    None => name.to_owned(),
                };
                out.push(Assignment { variable: format!("{prefix}{target}"), value, origin });
            }
        }
        Ok(out)
    }

    /// A ParameterMapping (inline, or its .ssm source): parameter name -> (target, transformation).
    fn read_mapping(&mut self, m: &Element, file: &str) -> Result<Mapping, String> {
        let (root, mapping_file) = match m.attribute("source") {
            Some(source) => {
                let path = self.reference(source, &|| format!("{file}, line {}: the parameter mapping", m.line))?;
                let text = std::fs::read_to_string(&path)
                    .map_err(|e| format!("{file}, line {}: cannot read the parameter mapping {source}: {e}", m.line))?;
                (xml::parse(&text, source)?, source.to_owned())
            }
            None => (
                m.child("ParameterMapping").cloned().ok_or_else(|| {
                    format!("{file}, line {}: a ParameterMapping needs a source or an inline ssm:ParameterMapping", m.line)
                })?,
                file.to_owned(),
            ),
        };
        let mut out = HashMap::new();
        for entry in root.children("MappingEntry") {
            let source = entry.required("source", &mapping_file)?.to_owned();
            let target = entry.required("target", &mapping_file)?.to_owned();
            out.insert(source, (target, linear_transformation(entry, &mapping_file)?));
        }
        Ok(out)
    }

    /// Follows the connections from every FMU output through nested systems' connectors to the
    /// FMU inputs they reach.
    fn flatten(&self) -> Result<Vec<Link>, String> {
        let mut links = Vec::new();
        for (start, _, _, _, line) in &self.edges {
            let is_fmu = self.fmu_nodes.contains_key(start);
            let component = self.components.iter().any(|c| start.starts_with(&format!("{}.", c.name)));
            if component && !is_fmu {
                return Err(format!("{}, line {line}: connection from '{start}': the component has no such connector", self.file));
            }
        }
        for (_, end, _, _, line) in &self.edges {
            let component = self.components.iter().any(|c| end.starts_with(&format!("{}.", c.name)));
            if component && !self.fmu_nodes.contains_key(end) {
                return Err(format!("{}, line {line}: connection to '{end}': the component has no such connector", self.file));
            }
        }
        for (start, _, _, _, first_line) in self.edges.iter().filter(|(s, ..)| self.fmu_nodes.contains_key(s)) {
            if links.iter().any(|l: &Link| self.fmu_nodes[start] == l.from) {
                continue;
            }
            // Depth-first over non-FMU nodes, composing transformations.
            let mut stack = vec![(start.clone(), None::<(f64, f64)>, false, 0usize)];
            while let Some((node, transformation, suppress, depth)) = stack.pop() {
                if depth > self.edges.len() {
                    return Err(format!("{}: the connections through system connectors form a cycle at '{node}'", self.file));
                }
                for (s, e, t, sup, _) in self.edges.iter().filter(|(s, ..)| *s == node) {
                    debug_assert_eq!(s, &node);
                    let composed = match (transformation, t) {
                        (None, None) => None,
                        (Some(a), None) => Some(a),
                        (None, Some(b)) => Some(*b),
                        (Some((f1, o1)), Some((f2, o2))) => Some((f2 * f1, f2 * o1 + o2)),
                    };
                    if let Some(end) = self.fmu_nodes.get(e) {
                        links.push(Link {
                            from: self.fmu_nodes[start].clone(),
                            to: end.clone(),
                            transformation: composed,
                            suppress_unit_conversion: suppress || *sup,
                            line: *first_line,
                        });
                    } else {
                        stack.push((e.clone(), composed, suppress || *sup, depth + 1));
                    }
                }
            }
        }
        // An input fed twice has no single value.
        for (k, l) in links.iter().enumerate() {
            if let Some(other) = links[..k].iter().find(|o| o.to == l.to) {
                let name = |(c, v): &(usize, String)| format!("{}.{v}", self.components[*c].name);
                return Err(format!(
                    "{}: input '{}' is connected to both '{}' and '{}'",
                    self.file,
                    name(&l.to),
                    name(&other.from),
                    name(&l.from)
                ));
            }
        }
        Ok(links)
    }
}

/// A parameter's value: SSP 1.0's Real, Integer, Boolean and String, and SSP 2.0's Float64,
/// Float32 and Int8 to UInt64 (an integer within its type's range). SSP 2.0's array parameters (a
/// `ssc:Dimension`, a list of values, several `ssv:Value`s) are refused, naming the parameter.
fn parameter_value(p: &Element, file: &str) -> Result<ParameterValue, String> {
    let at = |what: &str| format!("{file}, line {}: parameter '{}': {what}", p.line, p.attribute("name").unwrap_or(""));
    let typed =
        p.children.first().ok_or_else(|| at("no value (ssv:Real, ssv:Float64, ssv:Integer, ssv:Int32, ssv:Boolean, ssv:String, ...)"))?;
    let array = |count: usize| at(&format!("an array parameter ({count} values): array parameters are not supported, only scalars"));
    if p.child("Dimension").is_some() {
        return Err(at("an array parameter (ssc:Dimension): array parameters are not supported, only scalars"));
    }
    // SSP 2.0: a String may give its value as one ssv:Value child instead of the attribute.
    let values: Vec<&Element> = typed.children("Value").collect();
    if values.len() > 1 {
        return Err(array(values.len()));
    }
    let text = values.first().map_or(typed.attribute("value"), |v| v.attribute("value")).ok_or_else(|| at("no value attribute"))?;
    // Numbers, Booleans: an xs:list in SSP 2.0, where more than one item is an array.
    let scalar = || {
        let items = text.split_whitespace().count();
        if items > 1 {
            Err(array(items))
        } else {
            Ok(text.trim())
        }
    };
    let integer = |kind: Kind| -> Result<ParameterValue, String> {
        let text = scalar()?;
        let (low, high) = kind.integer_range().expect("an integer type");
        let name = if typed.name == "Integer" { "Integer" } else { kind.name_in(fmi_importer::FmiVersion::Fmi3) };
        let i: i128 = text.parse().map_err(|_| at(&format!("'{text}' is not an integer")))?;
        if i < low || i > high {
            return Err(at(&format!("{i} is outside {name}'s range {low} to {high}")));
        }
        i64::try_from(i).map(ParameterValue::Integer).map_err(|_| at(&format!("{i} is above {} (not supported)", i64::MAX)))
    };
    match typed.name.as_str() {
        "Real" | "Float64" | "Float32" => {
            scalar()?;
            let x = typed.number("value", file)?.ok_or_else(|| at("no value"))?;
            Ok(ParameterValue::Real(x, typed.attribute("unit").map(str::to_owned)))
        }
        // SSP 1.0's Integer is an xs:int, as Int32.
        "Integer" | "Int32" => integer(Kind::Integer),
        "Int8" => integer(Kind::Int8),
        "UInt8" => integer(Kind::UInt8),
        "Int16" => integer(Kind::Int16),
        "UInt16" => integer(Kind::UInt16),
        "UInt32" => integer(Kind::UInt32),
        "Int64" => integer(Kind::Int64),
        "UInt64" => integer(Kind::UInt64),
        "Boolean" => match scalar()? {
            "true" | "1" => Ok(ParameterValue::Boolean(true)),
            "false" | "0" => Ok(ParameterValue::Boolean(false)),
            _ => Err(at(&format!("'{text}' is not true or false"))),
        },
        "String" => Ok(ParameterValue::String(text.to_owned())),
        other => Err(at(&format!("values of type {other} are not supported"))),
    }
}

/// `x` in `from` as a value in `to`, when both are defined with the same base units.
pub fn convert(units: &HashMap<String, UnitDefinition>, from: &str, to: &str) -> Result<Option<(f64, f64)>, String> {
    if from == to {
        return Ok(None);
    }
    let a = units.get(from).ok_or_else(|| format!("unit '{from}' is not defined in the SSD's or the parameter file's Units"))?;
    let b = units.get(to).ok_or_else(|| format!("unit '{to}' is not defined in the SSD's or the parameter file's Units"))?;
    if a.exponents != b.exponents {
        return Err(format!("units '{from}' and '{to}' measure different quantities"));
    }
    // SI = fa x + oa = fb y + ob, so y = (fa / fb) x + (oa - ob) / fb.
    Ok(Some((a.factor / b.factor, (a.offset - b.offset) / b.factor)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEAD: &str = r#"<ssd:SystemStructureDescription xmlns:ssd="s" xmlns:ssc="c" version="1.0" name="t">"#;

    fn parse(body: &str) -> Result<Structure, String> {
        Structure::parse(&format!("{HEAD}{body}</ssd:SystemStructureDescription>"), Path::new("/sys"), "t.ssd")
    }

    fn fmu(name: &str, connectors: &[&str]) -> String {
        let c: String =
            connectors.iter().map(|c| format!(r#"<ssd:Connector name="{c}" kind="inout"><ssc:Real/></ssd:Connector>"#)).collect();
        format!(r#"<ssd:Component name="{name}" source="r/{name}.fmu"><ssd:Connectors>{c}</ssd:Connectors></ssd:Component>"#)
    }

    /// A source in the top system feeds two sinks, one two systems down, through system
    /// connectors, with a transformation at each level: they compose as functions do.
    #[test]
    fn nested_systems_flatten_and_transformations_compose() {
        let inner = format!(
            r#"<ssd:System name="in2"><ssd:Elements>{}</ssd:Elements><ssd:Connections><ssd:Connection startConnector="u" endElement="deep" endConnector="u"><ssc:LinearTransformation factor="3" offset="1"/></ssd:Connection></ssd:Connections></ssd:System>"#,
            fmu("deep", &["u"])
        );
        let middle = format!(
            r#"<ssd:System name="in1"><ssd:Elements>{inner}</ssd:Elements><ssd:Connections><ssd:Connection startConnector="u" endElement="in2" endConnector="u"><ssc:LinearTransformation factor="2" offset="0.5"/></ssd:Connection></ssd:Connections></ssd:System>"#
        );
        let s = parse(&format!(
            r#"<ssd:System name="top"><ssd:Elements>{}{}{middle}</ssd:Elements><ssd:Connections><ssd:Connection startElement="src" startConnector="y" endElement="in1" endConnector="u"/><ssd:Connection startElement="src" startConnector="y" endElement="near" endConnector="u"/></ssd:Connections></ssd:System>"#,
            fmu("src", &["y"]),
            fmu("near", &["u"])
        ))
        .unwrap();
        let names: Vec<&str> = s.components.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["src", "near", "in1.in2.deep"]);
        assert_eq!(s.components[2].source, Path::new("/sys/r/deep.fmu"));
        let deep = s.links.iter().find(|l| l.to.0 == 2).unwrap();
        // deep.u = 3 (2 y + 0.5) + 1 = 6 y + 2.5.
        assert_eq!(deep.transformation, Some((6.0, 2.5)));
        assert_eq!(s.links.iter().find(|l| l.to.0 == 1).unwrap().transformation, None);
        assert_eq!(s.split("in1.in2.deep.a.b"), Some((2, "a.b")), "the longest component name wins; variables may hold dots");
        assert_eq!(s.split("in1.x"), None);
    }

    #[test]
    fn units_convert_between_scales_and_refuse_other_quantities() {
        let s = parse(
            r#"<ssd:System name="t"><ssd:Elements><ssd:Component name="a" source="a.fmu"/></ssd:Elements></ssd:System><ssd:Units><ssc:Unit name="degC"><ssc:BaseUnit K="1" offset="273.15"/></ssc:Unit><ssc:Unit name="degF"><ssc:BaseUnit K="1" factor="0.5555555555555556" offset="255.3722222222222"/></ssc:Unit><ssc:Unit name="m"><ssc:BaseUnit m="1"/></ssc:Unit></ssd:Units>"#,
        )
        .unwrap();
        let (f, o) = convert(&s.units, "degC", "degF").unwrap().unwrap();
        assert!((f * 100.0 + o - 212.0).abs() < 1e-9 && (o - 32.0).abs() < 1e-9);
        assert_eq!(convert(&s.units, "m", "m").unwrap(), None);
        assert!(convert(&s.units, "m", "degC").unwrap_err().contains("measure different quantities"));
        assert!(convert(&s.units, "m", "ft").unwrap_err().contains("unit 'ft' is not defined"));
    }

    #[test]
    fn bad_structures_are_explained() {
        let err = |body: &str| parse(body).unwrap_err();
        assert!(err("").contains("no <ssd:System>"));
        assert!(err(r#"<ssd:System name="t"/>"#).contains("no FMU components"));
        let two = format!("{}{}", fmu("a", &["y"]), fmu("b", &["y"]));
        let feed_twice = format!(
            r#"<ssd:System name="t"><ssd:Elements>{two}{}</ssd:Elements><ssd:Connections><ssd:Connection startElement="a" startConnector="y" endElement="c" endConnector="u"/><ssd:Connection startElement="b" startConnector="y" endElement="c" endConnector="u"/></ssd:Connections></ssd:System>"#,
            fmu("c", &["u"])
        );
        assert!(err(&feed_twice).contains("input 'c.u' is connected to both 'a.y' and 'b.y'"));
        assert!(err(r#"<ssd:System name="t"><ssd:Elements><ssd:Component name="a.b" source="x.fmu"/></ssd:Elements></ssd:System>"#)
            .contains("must not contain a dot"));
        assert!(err(r#"<ssd:System name="t"><ssd:Elements><ssd:Component name="a" source="x.fmu" implementation="ScheduledExecution"/></ssd:Elements></ssd:System>"#).contains("implementation 'ScheduledExecution' is not supported"));
        assert!(err(r#"<ssd:System name="t"><ssd:Elements><ssd:Component name="a" source="x.fmu"><ssd:ParameterBindings><ssd:ParameterBinding source="missing.ssv"/></ssd:ParameterBindings></ssd:Component></ssd:Elements></ssd:System>"#).contains("cannot read the parameter file missing.ssv"));
        let wrong_version =
            Structure::parse(r#"<ssd:SystemStructureDescription version="0.9" name="t"/>"#, Path::new("/"), "t.ssd").unwrap_err();
        assert!(wrong_version.contains("SSP version '0.9' is not supported"));
    }
}

/// SSP 2.0 files as the standard writes them (its namespaces are SSP 1.0's, its version 2.0):
/// the FMI 3.0 types on connectors and in parameter files, and the refusals of what the master
/// cannot pass (arrays, clocks), each naming the connector or parameter.
#[cfg(test)]
mod ssp2 {
    use super::*;

    const HEAD: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="2.0" name="t">"#;

    /// An SSD whose component `a` has the connectors `connectors` (XML) and whose system holds
    /// `more` after its elements (connectors, connections).
    fn ssd(connectors: &str, more: &str) -> String {
        format!(
            "{HEAD}\n<ssd:System name=\"s\"><ssd:Elements>\n<ssd:Component name=\"a\" source=\"a.fmu\"><ssd:Connectors>\n{connectors}\n</ssd:Connectors></ssd:Component>\n</ssd:Elements>{more}</ssd:System></ssd:SystemStructureDescription>"
        )
    }

    fn parse(text: &str) -> Result<Structure, String> {
        Structure::parse(text, Path::new("/sys"), "t.ssd")
    }

    /// Every type SSP 2.0 puts on a connector is read as that type: the FMI 3.0 widths exactly,
    /// SSP 1.0's Real and Integer as any float or integer width. Units stay with the floats.
    #[test]
    fn every_connector_type_is_read() {
        let types = [
            ("Real", ConnectorType::Real),
            ("Float64", ConnectorType::Exact(Kind::Real)),
            ("Float32", ConnectorType::Exact(Kind::Float32)),
            ("Integer", ConnectorType::Integer),
            ("Int8", ConnectorType::Exact(Kind::Int8)),
            ("UInt8", ConnectorType::Exact(Kind::UInt8)),
            ("Int16", ConnectorType::Exact(Kind::Int16)),
            ("UInt16", ConnectorType::Exact(Kind::UInt16)),
            ("Int32", ConnectorType::Exact(Kind::Integer)),
            ("UInt32", ConnectorType::Exact(Kind::UInt32)),
            ("Int64", ConnectorType::Exact(Kind::Int64)),
            ("UInt64", ConnectorType::Exact(Kind::UInt64)),
            ("Boolean", ConnectorType::Exact(Kind::Boolean)),
            ("String", ConnectorType::Exact(Kind::String)),
            ("Enumeration", ConnectorType::Exact(Kind::Enumeration)),
            ("Binary", ConnectorType::Exact(Kind::Binary)),
        ];
        let connectors: String = types
            .iter()
            .map(|(t, _)| {
                let attribute = match *t {
                    "Real" | "Float64" | "Float32" => r#" unit="m/s""#,
                    "Enumeration" => r#" name="E""#,
                    "Binary" => r#" mime-type="application/octet-stream""#,
                    _ => "",
                };
                format!(r#"<ssd:Connector name="c{t}" kind="input"><ssc:{t}{attribute}/></ssd:Connector>"#)
            })
            .collect();
        let s = parse(&ssd(&connectors, "")).unwrap();
        let read = &s.components[0].connectors;
        assert_eq!(read.len(), types.len());
        for ((name, expected), c) in types.iter().zip(read) {
            assert_eq!((c.name.as_str(), c.data_type), (format!("c{name}").as_str(), Some(*expected)));
            assert_eq!(expected.as_str(), *name, "the type's name is the element's");
            assert_eq!(c.line, 5, "all on the line after <ssd:Connectors>");
        }
        let mut units: Vec<&str> = s.components[0].connector_units.keys().map(String::as_str).collect();
        units.sort();
        assert_eq!(units, ["cFloat32", "cFloat64", "cReal"]);
        // Which FMU variable fits which connector type.
        let fits = |t: ConnectorType, k: Kind| t.accepts(k);
        assert!(fits(ConnectorType::Real, Kind::Real) && fits(ConnectorType::Real, Kind::Float32));
        assert!(fits(ConnectorType::Integer, Kind::Int64) && fits(ConnectorType::Integer, Kind::UInt8));
        assert!(fits(ConnectorType::Exact(Kind::Integer), Kind::Integer), "Int32 is FMI 3.0's Int32 and FMI 2.0's Integer");
        assert!(!fits(ConnectorType::Exact(Kind::Real), Kind::Float32), "a Float64 connector is no Float32 variable");
        assert!(!fits(ConnectorType::Exact(Kind::Integer), Kind::Int64));
        assert!(!fits(ConnectorType::Integer, Kind::Boolean) && !fits(ConnectorType::Integer, Kind::Enumeration));
        assert!(!fits(ConnectorType::Real, Kind::Integer));
    }

    /// An untyped connector (SSP: the FMU's variable decides) is read without a type.
    #[test]
    fn a_connector_without_a_type_takes_the_variables() {
        let s = parse(&ssd(r#"<ssd:Connector name="u" kind="input"/>"#, "")).unwrap();
        assert_eq!(s.components[0].connectors[0].data_type, None);
    }

    #[test]
    fn array_connectors_are_refused_by_name() {
        let array = r#"<ssd:Connector name="u" kind="input"><ssc:Float64/><ssc:Dimension size="3"/><ssc:Dimension sizeConnector="n"/></ssd:Connector>"#;
        assert_eq!(
            parse(&ssd(array, "")).unwrap_err(),
            "t.ssd, line 5: connector 'u' of component 'a' is an array connector (ssc:Dimension, sizes 3 x n): array connectors are not supported, only scalars"
        );
        // On a system's own connector too.
        let system = r#"<ssd:Connectors><ssd:Connector name="bus" kind="output"><ssc:Int8/><ssc:Dimension size="4"/></ssd:Connector></ssd:Connectors>"#;
        let err = parse(&ssd(r#"<ssd:Connector name="y" kind="output"/>"#, system)).unwrap_err();
        assert!(err.contains("connector 'bus' of the top system is an array connector (ssc:Dimension, sizes 4)"), "{err}");
        // A connection to some elements of an array connector.
        let scalars = r#"<ssd:Connector name="y" kind="output"/><ssd:Connector name="u" kind="input"/>"#;
        let indices = r#"<ssd:Connections><ssd:Connection startElement="a" startConnector="y" startIndices="2" endElement="a" endConnector="u"/></ssd:Connections>"#;
        assert_eq!(
            parse(&ssd(scalars, indices)).unwrap_err(),
            "t.ssd, line 7: the connection from 'a.y' to 'a.u' selects elements 2 of the array connector 'a.y' (startIndices): array connectors are not supported"
        );
    }

    /// SSP 2.0 has two `Clock` elements on a connector: the type (ssc:Clock, a clock itself) and
    /// the association (ssd:Clock name=..., a variable that ticks with a clock). Both are refused.
    #[test]
    fn clocks_and_clocked_connectors_are_refused_by_name() {
        let clock = r#"<ssd:Connector name="tick" kind="output"><ssc:Clock intervalVariability="triggered"/></ssd:Connector>"#;
        assert_eq!(
            parse(&ssd(clock, "")).unwrap_err(),
            "t.ssd, line 5: connector 'tick' of component 'a' is a Clock (ssc:Clock): clocks are not supported"
        );
        let clocked = r#"<ssd:Connector name="y" kind="output"><ssc:Int32/><ssd:Clock name="tick"/></ssd:Connector>"#;
        assert_eq!(
            parse(&ssd(clocked, "")).unwrap_err(),
            "t.ssd, line 5: connector 'y' of component 'a' is clocked by clock 'tick' (ssd:Clock): clocked connectors are not supported"
        );
    }

    /// SSP 2.0's parameter types: Float64 and Float32 as Reals, Int8 to UInt64 as integers in
    /// their type's range, a String's value as a Value element; arrays refused by name.
    #[test]
    fn parameter_files_in_ssp2_types() {
        let set = |parameters: &str| {
            let binding = format!(
                r#"<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="2.0" name="p"><ssv:Parameters>{parameters}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"#
            );
            let text = format!(
                r#"{HEAD}<ssd:System name="s"><ssd:Elements><ssd:Component name="a" source="a.fmu">{binding}</ssd:Component></ssd:Elements></ssd:System></ssd:SystemStructureDescription>"#
            );
            parse(&text).map(|s| s.components[0].parameters.iter().map(|a| (a.variable.clone(), a.value.clone())).collect::<Vec<_>>())
        };
        let read = set(r#"<ssv:Parameter name="f"><ssv:Float64 value="2.5" unit="m"/></ssv:Parameter>
<ssv:Parameter name="g"><ssv:Float32 value="-0.5"/></ssv:Parameter>
<ssv:Parameter name="i"><ssv:Int8 value="-128"/></ssv:Parameter>
<ssv:Parameter name="j"><ssv:UInt16 value="65535"/></ssv:Parameter>
<ssv:Parameter name="k"><ssv:Int32 value="7"/></ssv:Parameter>
<ssv:Parameter name="l"><ssv:Int64 value="-9223372036854775808"/></ssv:Parameter>
<ssv:Parameter name="m"><ssv:UInt64 value="9223372036854775807"/></ssv:Parameter>
<ssv:Parameter name="b"><ssv:Boolean value="true"/></ssv:Parameter>
<ssv:Parameter name="s"><ssv:String><ssv:Value value="profile.csv"/></ssv:String></ssv:Parameter>"#)
        .unwrap();
        assert_eq!(
            read,
            [
                ("f".into(), ParameterValue::Real(2.5, Some("m".into()))),
                ("g".into(), ParameterValue::Real(-0.5, None)),
                ("i".into(), ParameterValue::Integer(-128)),
                ("j".into(), ParameterValue::Integer(65535)),
                ("k".into(), ParameterValue::Integer(7)),
                ("l".into(), ParameterValue::Integer(i64::MIN)),
                ("m".into(), ParameterValue::Integer(i64::MAX)),
                ("b".into(), ParameterValue::Boolean(true)),
                ("s".into(), ParameterValue::String("profile.csv".into())),
            ]
        );
        let err = |p: &str| set(p).unwrap_err();
        assert!(err(r#"<ssv:Parameter name="i"><ssv:Int8 value="128"/></ssv:Parameter>"#)
            .ends_with("parameter 'i': 128 is outside Int8's range -128 to 127"));
        assert!(err(r#"<ssv:Parameter name="u"><ssv:UInt32 value="-1"/></ssv:Parameter>"#)
            .ends_with("parameter 'u': -1 is outside UInt32's range 0 to 4294967295"));
        assert!(err(r#"<ssv:Parameter name="m"><ssv:UInt64 value="18446744073709551615"/></ssv:Parameter>"#)
            .ends_with("parameter 'm': 18446744073709551615 is above 9223372036854775807 (not supported)"));
        assert!(err(r#"<ssv:Parameter name="x0"><ssv:Float64 value="0 0 0"/></ssv:Parameter>"#)
            .ends_with("parameter 'x0': an array parameter (3 values): array parameters are not supported, only scalars"));
        assert!(err(r#"<ssv:Parameter name="A"><ssv:Float64 value="1"/><ssc:Dimension size="1"/></ssv:Parameter>"#)
            .ends_with("parameter 'A': an array parameter (ssc:Dimension): array parameters are not supported, only scalars"));
        assert!(err(r#"<ssv:Parameter name="t"><ssv:String><ssv:Value value="a"/><ssv:Value value="b"/></ssv:String></ssv:Parameter>"#)
            .ends_with("parameter 't': an array parameter (2 values): array parameters are not supported, only scalars"));
        assert!(err(r#"<ssv:Parameter name="e"><ssv:Enumeration value="Red"/></ssv:Parameter>"#)
            .ends_with("parameter 'e': values of type Enumeration are not supported"));
    }

    /// Broken SSP 2.0 files get a message with the file, the line and what is wrong.
    #[test]
    fn malformed_ssp2_files_are_explained() {
        let unclosed = ssd(r#"<ssd:Connector name="u" kind="input"><ssc:Float64></ssd:Connector>"#, "");
        let err = parse(&unclosed).unwrap_err();
        assert!(err.starts_with("t.ssd, line 5: not well-formed XML"), "{err}");
        let unnamed = ssd(r#"<ssd:Connector kind="input"><ssc:Float64/></ssd:Connector>"#, "");
        assert_eq!(parse(&unnamed).unwrap_err(), "t.ssd, line 5: <Connector> has no attribute 'name'");
        let bad_number = ssd(r#"<ssd:Connector name="u" kind="input"/>"#, "")
            .replace("</ssd:System>", r#"</ssd:System><ssd:DefaultExperiment startTime="zero"/>"#);
        assert!(parse(&bad_number).unwrap_err().contains("'zero' is not a finite number"));
        // SSP 2.0 allows a component without an implementation (an architecture); it cannot run.
        let sourceless = format!(
            r#"{HEAD}<ssd:System name="s"><ssd:Elements><ssd:Component name="planned"/></ssd:Elements></ssd:System></ssd:SystemStructureDescription>"#
        );
        assert!(parse(&sourceless).unwrap_err().contains("component 'planned': no source: the component has no FMU to run"));
        let future = HEAD.replace(r#"version="2.0""#, r#"version="3.0""#);
        let err = parse(&format!("{future}</ssd:SystemStructureDescription>")).unwrap_err();
        assert_eq!(err, "t.ssd: SSP version '3.0' is not supported (1.0 or 2.0)");
    }
}
