//! Writes the seed corpora of both fuzz targets, and the hand-made hostile inputs that are kept
//! as regression tests.
//!
//! ```text
//! seeds corpus <workspace root> <fuzz dir> [real.fmu]
//! seeds regressions <fmu/tests/fuzz_regressions>
//! ```
//!
//! Seeds are generated rather than committed: model descriptions come from a real FMU (when
//! given), the workspace's hand-written fixtures and a few variants; archives wrap them in
//! well-formed zips, plus hostile zips built byte by byte (a normal zip writer refuses to write
//! `../` names, duplicate names or sizes that lie).

use std::path::Path;

use fmi_importer::archive::{write_zip, Entry};

#[path = "../../../runner/importer/tests/hostile/archives.rs"]
mod hostile;

use hostile::{hostile_archives, MINIMAL};

/// Every type kind, units, type definitions and dependencies: reaches most of the reader.
const RICH: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="rich" guid="g" variableNamingConvention="structured" numberOfEventIndicators="2">
  <ModelExchange modelIdentifier="rich" completedIntegratorStepNotNeeded="true"><SourceFiles><File name="a.c"/></SourceFiles></ModelExchange>
  <CoSimulation modelIdentifier="rich" canGetAndSetFMUstate="true" maxOutputDerivativeOrder="1"/>
  <UnitDefinitions>
    <Unit name="rad/s"><BaseUnit s="-1" rad="1" factor="1" offset="0"/><DisplayUnit name="rpm" factor="9.549296585513721" offset="0"/></Unit>
  </UnitDefinitions>
  <TypeDefinitions>
    <SimpleType name="Speed"><Real quantity="AngularVelocity" unit="rad/s" displayUnit="rpm" min="-INF" max="INF" nominal="1" unbounded="false" relativeQuantity="false"/></SimpleType>
    <SimpleType name="Count"><Integer min="0" max="10"/></SimpleType>
    <SimpleType name="Mode"><Enumeration><Item name="off" value="0" description="Off"/><Item name="on" value="1"/></Enumeration></SimpleType>
  </TypeDefinitions>
  <LogCategories><Category name="logAll"/></LogCategories>
  <DefaultExperiment startTime="0" stopTime="10" tolerance="1e-6" stepSize="0.01"/>
  <ModelVariables>
    <ScalarVariable name="w" valueReference="0" causality="local" variability="continuous" initial="exact"><Real declaredType="Speed" start="-0"/></ScalarVariable>
    <ScalarVariable name="der(w)" valueReference="1"><Real derivative="1" reinit="true"/></ScalarVariable>
    <ScalarVariable name="n" valueReference="0" causality="input" variability="discrete"><Integer declaredType="Count" start="3"/></ScalarVariable>
    <ScalarVariable name="on" valueReference="0" causality="parameter" variability="tunable"><Boolean start="true"/></ScalarVariable>
    <ScalarVariable name="label" valueReference="0" causality="parameter" variability="fixed"><String start="a &amp; b"/></ScalarVariable>
    <ScalarVariable name="mode" valueReference="2" causality="output" variability="discrete"><Enumeration declaredType="Mode"/></ScalarVariable>
    <ScalarVariable name="k" valueReference="3" causality="calculatedParameter" variability="fixed" initial="calculated"><Real start="NaN"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="6" dependencies="3 4" dependenciesKind="dependent dependent"/></Outputs>
    <Derivatives><Unknown index="2" dependencies="1" dependenciesKind="fixed"/></Derivatives>
    <InitialUnknowns><Unknown index="2"/><Unknown index="6"/><Unknown index="7"/></InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"#;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.iter().map(String::as_str).collect::<Vec<_>>().as_slice() {
        ["corpus", root, fuzz] => corpus(Path::new(root), Path::new(fuzz), None),
        ["corpus", root, fuzz, fmu] => corpus(Path::new(root), Path::new(fuzz), Some(Path::new(fmu))),
        ["regressions", xml_dir] => regressions(Path::new(xml_dir)),
        _ => Err("usage: seeds corpus <workspace root> <fuzz dir> [real.fmu] | seeds regressions <xml dir>".to_owned()),
    };
    if let Err(e) = result {
        eprintln!("seeds: {e}");
        std::process::exit(1);
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let path = dir.join(name);
    std::fs::write(&path, bytes).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// The `r#"..."#` literals holding a whole model description in a Rust test source.
fn fixtures_in(source: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = source;
    while let Some(start) = rest.find("r#\"<?xml") {
        let body = &rest[start + 3..];
        let Some(end) = body.find("\"#") else { break };
        if body[..end].contains("<fmiModelDescription") {
            out.push(body[..end].to_owned());
        }
        rest = &body[end..];
    }
    out
}

/// The modelDescription.xml of the FMU at `path`, read through the loader under test.
fn description_of(path: &Path) -> Result<String, String> {
    let unpacked = fmi_importer::Unpacked::open(path)?;
    let xml = unpacked.dir.path().join("modelDescription.xml");
    std::fs::read_to_string(&xml).map_err(|e| format!("cannot read {}: {e}", xml.display()))
}

/// The model identifier a description declares for Co-Simulation ("m" when unreadable).
fn identifier_of(xml: &str) -> String {
    fmi_schema::fmi2::ModelDescription::from_xml(xml)
        .ok()
        .and_then(|d| d.co_simulation().ok().map(|c| c.common.model_identifier.clone()))
        .unwrap_or_else(|| "m".to_owned())
}

fn corpus(root: &Path, fuzz: &Path, fmu: Option<&Path>) -> Result<(), String> {
    let mut descriptions: Vec<(String, String)> = vec![("minimal".into(), MINIMAL.into()), ("rich".into(), RICH.into())];
    if let Some(fmu) = fmu {
        descriptions.push(("real".into(), description_of(fmu)?));
    }
    for (source, tag) in [("tests/c_fmu/modelDescription.xml", "c_fmu")] {
        if let Ok(text) = std::fs::read_to_string(root.join(source)) {
            descriptions.push((tag.into(), text));
        }
    }
    if let Ok(text) = std::fs::read_to_string(root.join("fmu/schema/src/fmi2/tests.rs")) {
        for (i, xml) in fixtures_in(&text).into_iter().enumerate() {
            descriptions.push((format!("fixture{i}"), xml));
        }
    }

    let xml_dir = fuzz.join("corpus/model_description");
    for (name, xml) in &descriptions {
        write(&xml_dir, &format!("seed-{name}.xml"), xml.as_bytes())?;
    }
    for (name, _, bytes) in hostile_descriptions() {
        write(&xml_dir, &format!("seed-{name}"), &bytes)?;
    }

    let zip_dir = fuzz.join("corpus/fmu_archive");
    std::fs::create_dir_all(&zip_dir).map_err(|e| format!("cannot create {}: {e}", zip_dir.display()))?;
    for (name, xml) in &descriptions {
        let id = identifier_of(xml);
        let binary = format!("binaries/linux64/{id}.so");
        // A few bytes stand in for the library: the loader checks it exists, never opens it.
        let entries = [Entry { path: "modelDescription.xml", bytes: xml.as_bytes() }, Entry { path: &binary, bytes: b"\x7fELF" }];
        let path = zip_dir.join(format!("seed-{name}.fmu"));
        let file = std::fs::File::create(&path).map_err(|e| format!("cannot create {}: {e}", path.display()))?;
        write_zip(file, &entries)?;
    }
    for (name, bytes, _) in hostile_archives() {
        write(&zip_dir, &format!("seed-{name}"), &bytes)?;
    }
    println!("seeds: {} descriptions, {} archives", descriptions.len(), descriptions.len() + hostile_archives().len());
    Ok(())
}

/// Writes the hand-made hostile descriptions with a `.expect` file each: the text their error
/// must contain. (The hostile archives are built by the runner's regression test itself.)
fn regressions(xml_dir: &Path) -> Result<(), String> {
    for (name, expect, bytes) in hostile_descriptions() {
        write(xml_dir, &name, &bytes)?;
        if let Some(expect) = expect {
            write(xml_dir, &format!("{name}.expect"), format!("{expect}\n").as_bytes())?;
        }
    }
    Ok(())
}

/// Hostile or broken model descriptions, each small: (file name, text the reader's error must
/// contain or `None` when the reader may accept it, bytes).
fn hostile_descriptions() -> Vec<(String, Option<&'static str>, Vec<u8>)> {
    let minimal = |from: &str, to: &str| MINIMAL.replacen(from, to, 1).into_bytes();
    let mut deep = String::from(r#"<fmiModelDescription fmiVersion="2.0" modelName="m" guid="g">"#);
    deep.push_str(&"<a>".repeat(10_000));
    deep.push_str(&"</a>".repeat(10_000));
    deep.push_str("</fmiModelDescription>");
    vec![
        (
            "billion-laughs.xml".into(),
            Some("unrecognized entity"),
            br#"<?xml version="1.0"?>
<!DOCTYPE fmiModelDescription [
 <!ENTITY a "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa">
 <!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">
 <!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">
]>
<fmiModelDescription fmiVersion="2.0" modelName="&c;" guid="g"/>
"#
            .to_vec(),
        ),
        ("deep-nesting.xml".into(), Some("missing element ModelVariables"), deep.into_bytes()),
        ("unclosed.xml".into(), Some("is closed"), minimal("</fmiModelDescription>", "")),
        ("wrong-root.xml".into(), Some("root element is <fmuDescription>"), b"<fmuDescription fmiVersion=\"2.0\"/>".to_vec()),
        ("fmi3.xml".into(), Some("only FMI 2.0 is supported"), minimal("fmiVersion=\"2.0\"", "fmiVersion=\"3.0\"")),
        ("duplicate-attribute.xml".into(), Some("duplicated attribute"), minimal("modelName=\"m\"", "modelName=\"m\" modelName=\"n\"")),
        (
            "value-reference-overflow.xml".into(),
            Some("is not an unsigned integer"),
            minimal("valueReference=\"0\"", "valueReference=\"4294967296\""),
        ),
        ("unknown-index-zero.xml".into(), None, minimal("<Unknown index=\"1\"/>", "<Unknown index=\"0\" dependencies=\"4294967295\"/>")),
        ("two-types.xml".into(), Some("more than one type element"), minimal("<Real/>", "<Real/><Integer/>")),
        ("no-type.xml".into(), Some("has no type element"), minimal("<Real/>", "")),
        ("empty.xml".into(), Some("no <fmiModelDescription> element found"), Vec::new()),
    ]
}
