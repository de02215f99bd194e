//! Helpers shared by the runner's integration tests: running the binary, building the C test
//! FMU, writing zips, reading CSV.

#![allow(dead_code)]

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the runner binary with `args` in `dir`.
pub fn runner(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_runner")).current_dir(dir).args(args).output().expect("runner starts")
}

/// stderr as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Asserts success and returns stdout.
pub fn ok(o: Output) -> String {
    assert!(o.status.success(), "runner failed: {}", stderr(&o));
    String::from_utf8(o.stdout).expect("UTF-8 output")
}

/// Asserts failure and returns stderr.
pub fn fails(o: Output) -> String {
    assert!(!o.status.success(), "runner should have failed; stdout: {}", String::from_utf8_lossy(&o.stdout));
    stderr(&o)
}

/// The workspace's tests/c_fmu directory.
pub fn c_fmu_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/c_fmu")
}

/// Compiles tests/c_fmu/dahlquist.c with the system C compiler into `out` (extra flags appended).
pub fn compile_c_fmu(out: &Path, extra: &[&str]) {
    let source = c_fmu_dir().join("dahlquist.c");
    let status = Command::new("cc")
        .args(["-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-o"])
        .arg(out)
        .arg(&source)
        .args(extra)
        .arg("-lm")
        .status()
        .expect("the C compiler `cc` runs");
    assert!(status.success(), "cc failed to compile {}", source.display());
}

/// A zip entry to write: a file with bytes, or a symbolic link to a target.
pub enum ZipItem<'a> {
    /// A regular file.
    File(&'a str, &'a [u8]),
    /// A symbolic link.
    Link(&'a str, &'a str),
}

/// Writes a zip at `dest` with exactly `items` (names taken as given, even unsafe ones).
pub fn write_zip(dest: &Path, items: &[ZipItem]) {
    let mut zip = zip::ZipWriter::new(std::fs::File::create(dest).unwrap());
    let options = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    for item in items {
        match item {
            ZipItem::File(name, bytes) => {
                zip.start_file(*name, options).unwrap();
                zip.write_all(bytes).unwrap();
            }
            ZipItem::Link(name, target) => zip.add_symlink(*name, *target, options).unwrap(),
        }
    }
    zip.finish().unwrap();
}

/// The element that makes an FMI 1.0 description a Co-Simulation FMU's.
pub const FMI1_IMPLEMENTATION: &str = "  <Implementation>
    <CoSimulation_StandAlone>
      <Capabilities canHandleVariableCommunicationStepSize=\"true\" canHandleEvents=\"true\"/>
    </CoSimulation_StandAlone>
  </Implementation>
</fmiModelDescription>";

/// Builds the FMI 1.0 test FMU tests/c_fmu/fmi1_<model>.c as `<dir>/<file>`, Co-Simulation
/// (-DFMI1_CO_SIMULATION, the description with [`FMI1_IMPLEMENTATION`]) or Model Exchange, its
/// modelDescription.xml passed through `edit`; returns its path.
pub fn fmi1_fmu(dir: &Path, file: &str, model: &str, co_simulation: bool, edit: impl Fn(&str) -> String) -> PathBuf {
    let so = dir.join(format!("{file}.so"));
    let source = c_fmu_dir().join(format!("fmi1_{model}.c"));
    let flags: &[&str] = if co_simulation { &["-DFMI1_CO_SIMULATION"] } else { &[] };
    let status = Command::new("cc")
        .args(["-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-o"])
        .arg(&so)
        .arg(&source)
        .args(flags)
        .arg("-lm")
        .status()
        .expect("the C compiler `cc` runs");
    assert!(status.success(), "cc failed to compile {}", source.display());
    let binary = std::fs::read(&so).unwrap();
    let mut xml = std::fs::read_to_string(c_fmu_dir().join(format!("fmi1_{model}.xml"))).unwrap();
    if co_simulation {
        xml = xml.replace("</fmiModelDescription>", FMI1_IMPLEMENTATION);
    }
    let xml = edit(&xml);
    let path = dir.join(file);
    let entry = format!("binaries/linux64/fmi1_{model}.so");
    write_zip(&path, &[ZipItem::File("modelDescription.xml", xml.as_bytes()), ZipItem::File(&entry, &binary)]);
    path
}

/// Builds the C test FMU (binary for `platform`) as `<dir>/<file>`; returns its path.
pub fn c_fmu(dir: &Path, file: &str, platform: &str, extra_flags: &[&str]) -> PathBuf {
    let so = dir.join(format!("{file}.so"));
    compile_c_fmu(&so, extra_flags);
    let binary = std::fs::read(&so).unwrap();
    let xml = std::fs::read(c_fmu_dir().join("modelDescription.xml")).unwrap();
    let entry = format!("binaries/{platform}/dahlquist.so");
    let path = dir.join(file);
    write_zip(&path, &[ZipItem::File("modelDescription.xml", &xml), ZipItem::File(&entry, &binary)]);
    path
}

/// A CSV file as its header and rows of strings.
pub fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut reader = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let header = reader.headers().unwrap().iter().map(str::to_owned).collect();
    let rows = reader.records().map(|r| r.unwrap().iter().map(str::to_owned).collect()).collect();
    (header, rows)
}

/// Column `name` of a CSV as numbers.
pub fn column(header: &[String], rows: &[Vec<String>], name: &str) -> Vec<f64> {
    let i = header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name} in {header:?}"));
    rows.iter().map(|r| r[i].parse().unwrap_or_else(|_| panic!("{name} = {:?} is not a number", r[i]))).collect()
}

/// Builds the Model Exchange test FMU tests/c_fmu/me_faults.c as `<dir>/<file>`, its
/// modelDescription.xml passed through `edit` first; returns its path.
pub fn me_faults_fmu(dir: &Path, file: &str, edit: impl Fn(&str) -> String) -> PathBuf {
    let so = dir.join(format!("{file}.so"));
    let source = c_fmu_dir().join("me_faults.c");
    let status = Command::new("cc")
        .args(["-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-o"])
        .arg(&so)
        .arg(&source)
        .arg("-lm")
        .status()
        .expect("the C compiler `cc` runs");
    assert!(status.success(), "cc failed to compile {}", source.display());
    let binary = std::fs::read(&so).unwrap();
    let xml = edit(&std::fs::read_to_string(c_fmu_dir().join("me_faults.xml")).unwrap());
    let path = dir.join(file);
    write_zip(&path, &[ZipItem::File("modelDescription.xml", xml.as_bytes()), ZipItem::File("binaries/linux64/me_faults.so", &binary)]);
    path
}

/// Builds tests/c_fmu/faulty.c, the FMU that crashes, aborts, hangs, exits or leaks on request,
/// as `<dir>/<file>`; `once_per_process` is what its modelDescription declares as
/// canBeInstantiatedOnlyOncePerProcess, `extra_flags` go to the compiler (-DONCE_PER_PROCESS).
pub fn faulty_fmu(dir: &Path, file: &str, once_per_process: bool, extra_flags: &[&str]) -> PathBuf {
    let source = c_fmu_dir().join("faulty.c");
    let so = dir.join(format!("{file}.so"));
    let status = Command::new("cc")
        .args(["-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-o"])
        .arg(&so)
        .arg(&source)
        .args(extra_flags)
        .arg("-lm")
        .status()
        .expect("the C compiler `cc` runs");
    assert!(status.success(), "cc failed to compile {}", source.display());
    let xml = std::fs::read_to_string(c_fmu_dir().join("faulty.xml")).unwrap();
    let xml = xml
        .replace(r#"canBeInstantiatedOnlyOncePerProcess="false""#, &format!(r#"canBeInstantiatedOnlyOncePerProcess="{once_per_process}""#));
    let path = dir.join(file);
    let binary = std::fs::read(&so).unwrap();
    write_zip(&path, &[ZipItem::File("modelDescription.xml", xml.as_bytes()), ZipItem::File("binaries/linux64/faulty.so", &binary)]);
    path
}

/// Runs the runner with `args` in `dir` as a child process, for tests that signal it.
pub fn spawn_runner(dir: &Path, args: &[&str]) -> std::process::Child {
    // A runner the test kills cannot remove its unpacked FMU: with TMPDIR inside the test's own
    // directory the copy goes when the test's directory does (else /tmp or /dev/shm keeps it).
    let scratch = dir.join("scratch");
    std::fs::create_dir_all(&scratch).expect("scratch directory");
    Command::new(env!("CARGO_BIN_EXE_runner"))
        .current_dir(dir)
        .env("TMPDIR", scratch)
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("runner starts")
}

/// The start of a system structure, namespaces declared, up to its `<ssd:System>`.
pub const SSD_HEAD: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping" version="1.0" name="test">"#;

/// A system folder `dir/name` holding `ssd` (between [`SSD_HEAD`] and the closing tag), the FMU
/// files `fmus` as resources/<file>, and `extra` files.
pub fn system(dir: &Path, name: &str, ssd: &str, fmus: &[(&str, &Path)], extra: &[(&str, &str)]) -> PathBuf {
    let root = dir.join(name);
    std::fs::create_dir_all(root.join("resources")).unwrap();
    std::fs::write(root.join("SystemStructure.ssd"), format!("{SSD_HEAD}\n{ssd}\n</ssd:SystemStructureDescription>\n")).unwrap();
    for (file, path) in fmus {
        std::fs::copy(path, root.join("resources").join(file)).unwrap();
    }
    for (file, text) in extra {
        std::fs::write(root.join(file), text).unwrap();
    }
    root
}
