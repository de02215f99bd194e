//! Reading an SSP 1.0 system structure: the SystemStructure.ssd, its parameter files (.ssv) and
//! parameter mappings (.ssm), into a flat [`Structure`]: FMU components named by their path
//! (`car`, or `sub.car` inside a nested system), the connections between FMU variables with
//! nested systems' connectors resolved, and the parameter values each component gets.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use fmi_importer::Interface;

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
            return Err(format!("{file}: SSP version '{version}' is not supported (1.0, and 2.0 where it is the same)"));
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
        let source = element.required("source", file)?;
        let at = || format!("{file}, line {}: component '{path}'", element.line);
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
        if let Some(connectors) = element.child("Connectors") {
            for c in connectors.children("Connector") {
                let name = c.required("name", file)?.to_owned();
                if let Some(unit) = ["Real", "Integer", "Boolean", "String", "Enumeration", "Binary"]
                    .iter()
                    .find_map(|t| c.child(t))
                    .and_then(|t| t.attribute("unit"))
                {
                    connector_units.insert(name.clone(), unit.to_owned());
                }
                self.fmu_nodes.insert(format!("{path}.{name}"), (index, name));
            }
        }
        let parameters = match element.child("ParameterBindings") {
            Some(b) => self.read_bindings(b, file)?,
            None => Vec::new(),
        };
        self.components.push(ComponentSpec { name: path, source, implementation, connector_units, parameters });
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

fn parameter_value(p: &Element, file: &str) -> Result<ParameterValue, String> {
    let at = |what: &str| format!("{file}, line {}: parameter '{}': {what}", p.line, p.attribute("name").unwrap_or(""));
    let typed = p.children.first().ok_or_else(|| at("no value (ssv:Real, ssv:Integer, ssv:Boolean or ssv:String)"))?;
    let text = typed.attribute("value").ok_or_else(|| at("no value attribute"))?;
    match typed.name.as_str() {
        "Real" => {
            let x = typed.number("value", file)?.ok_or_else(|| at("no value"))?;
            Ok(ParameterValue::Real(x, typed.attribute("unit").map(str::to_owned)))
        }
        "Integer" => text.trim().parse().map(ParameterValue::Integer).map_err(|_| at(&format!("'{text}' is not an integer"))),
        "Boolean" => match text.trim() {
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
