//! Hostile or broken `.fmu` archives, built byte by byte (a normal zip writer refuses to write
//! `../` names, duplicate names or sizes that lie). Shared by the runner's regression test, which
//! builds them at test time instead of keeping binary files, and by the fuzz seeds
//! (fuzz/src/seeds.rs includes this file).

use std::io::Write;

/// A small valid Co-Simulation description, the base of the hand-made inputs.
pub const MINIMAL: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="m" guid="{00000000-0000-0000-0000-000000000000}">
  <CoSimulation modelIdentifier="m" canHandleVariableCommunicationStepSize="true"/>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.1"/>
  <ModelVariables>
    <ScalarVariable name="x" valueReference="0" causality="output"><Real/></ScalarVariable>
    <ScalarVariable name="k" valueReference="1" causality="parameter" variability="fixed"><Real start="1"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="1"/></Outputs>
  </ModelStructure>
</fmiModelDescription>
"#;

/// One raw zip entry; every header field is ours to set, including lies.
struct Raw {
    name: Vec<u8>,
    /// Bytes as stored in the archive (already deflated when `method` is 8).
    data: Vec<u8>,
    method: u16,
    crc: u32,
    /// Declared uncompressed size.
    size: u32,
    /// Unix mode in the high 16 bits, as zip's "external attributes".
    mode: u32,
}

impl Raw {
    fn stored(name: &str, data: &[u8]) -> Raw {
        Raw {
            name: name.as_bytes().to_vec(),
            data: data.to_vec(),
            method: 0,
            crc: crc32fast::hash(data),
            size: data.len() as u32,
            mode: 0o100644,
        }
    }

    fn deflated(name: &str, data: &[u8]) -> Raw {
        let mut encoder = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
        encoder.write_all(data).expect("deflate into memory");
        let compressed = encoder.finish().expect("deflate into memory");
        Raw {
            name: name.as_bytes().to_vec(),
            data: compressed,
            method: 8,
            crc: crc32fast::hash(data),
            size: data.len() as u32,
            mode: 0o100644,
        }
    }
}

/// A local (`central` false) or central directory header of `e`, whose local header is at `offset`.
fn header(e: &Raw, central: bool, offset: u32) -> Vec<u8> {
    let mut h = Vec::new();
    h.extend_from_slice(&if central { 0x0201_4b50u32 } else { 0x0403_4b50 }.to_le_bytes());
    if central {
        h.extend_from_slice(&(3u16 << 8 | 20).to_le_bytes()); // made by: Unix, so the mode counts
    }
    h.extend_from_slice(&20u16.to_le_bytes()); // version needed
    h.extend_from_slice(&0u16.to_le_bytes()); // flags
    h.extend_from_slice(&e.method.to_le_bytes());
    h.extend_from_slice(&0u16.to_le_bytes()); // time
    h.extend_from_slice(&0x21u16.to_le_bytes()); // date: 1980-01-01
    h.extend_from_slice(&e.crc.to_le_bytes());
    h.extend_from_slice(&(e.data.len() as u32).to_le_bytes());
    h.extend_from_slice(&e.size.to_le_bytes());
    h.extend_from_slice(&(e.name.len() as u16).to_le_bytes());
    h.extend_from_slice(&0u16.to_le_bytes()); // extra field length
    if central {
        h.extend_from_slice(&0u16.to_le_bytes()); // comment length
        h.extend_from_slice(&0u16.to_le_bytes()); // disk
        h.extend_from_slice(&0u16.to_le_bytes()); // internal attributes
        h.extend_from_slice(&(e.mode << 16).to_le_bytes());
        h.extend_from_slice(&offset.to_le_bytes());
    }
    h.extend_from_slice(&e.name);
    h
}

/// Lays out local headers, data, central directory and end record like any zip writer would.
fn raw_zip(entries: &[Raw]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    for e in entries {
        let offset = out.len() as u32;
        out.extend_from_slice(&header(e, false, offset));
        out.extend_from_slice(&e.data);
        central.extend_from_slice(&header(e, true, offset));
    }
    let central_offset = out.len() as u32;
    out.extend_from_slice(&central);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    out.extend_from_slice(&[0; 4]); // disk numbers
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    out.extend_from_slice(&(central.len() as u32).to_le_bytes());
    out.extend_from_slice(&central_offset.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes()); // comment length
    out
}

/// Hostile or broken archives: (file name, bytes, text the loader's error must contain).
pub fn hostile_archives() -> Vec<(String, Vec<u8>, &'static str)> {
    let xml = || Raw::stored("modelDescription.xml", MINIMAL.as_bytes());
    let so = || Raw::stored("binaries/linux64/m.so", b"\x7fELF");
    let symlink = |name: &str, target: &str| Raw { mode: 0o120777, ..Raw::stored(name, target.as_bytes()) };
    let lying = {
        // 1 MiB of zeros that claims to be 100 bytes: only the actual copy can tell.
        let mut e = Raw::deflated("binaries/linux64/m.so", &vec![0; 1 << 20]);
        e.size = 100;
        e
    };
    let huge = {
        let mut e = Raw::deflated("resources/huge.bin", &[0; 1000]);
        e.size = u32::MAX;
        e
    };
    let traversing_identifier = MINIMAL.replace("modelIdentifier=\"m\"", "modelIdentifier=\"../../m\"");
    let cases: Vec<(&str, Vec<Raw>, &'static str)> = vec![
        ("dotdot.fmu", vec![xml(), so(), Raw::stored("../escaped.txt", b"x")], "'..' component"),
        ("dotdot-nested.fmu", vec![xml(), so(), Raw::stored("resources/../../../escaped.txt", b"x")], "'..' component"),
        ("backslash-dotdot.fmu", vec![xml(), so(), Raw::stored("..\\escaped.txt", b"x")], "'..' component"),
        ("absolute.fmu", vec![xml(), so(), Raw::stored("/tmp/escaped.txt", b"x")], "absolute path"),
        ("symlink.fmu", vec![xml(), symlink("binaries/linux64/m.so", "/lib/x86_64-linux-gnu/libc.so.6")], "symbolic link"),
        ("symlink-dir.fmu", vec![xml(), symlink("resources", "/tmp"), Raw::stored("resources/escaped.txt", b"x")], "symbolic link"),
        ("duplicate.fmu", vec![xml(), so(), Raw::stored("modelDescription.xml", b"<x/>")], "different contents"),
        ("huge-declared-size.fmu", vec![xml(), so(), huge], "limit"),
        ("lying-size.fmu", vec![xml(), lying], "declared"),
        (
            "identifier-traversal.fmu",
            vec![Raw::stored("modelDescription.xml", traversing_identifier.as_bytes()), Raw::stored("m.so", b"\x7fELF")],
            "modelIdentifier",
        ),
        ("no-description.fmu", vec![so()], "modelDescription.xml"),
        ("no-binary.fmu", vec![xml()], "no binary for this platform"),
    ];
    let mut out: Vec<(String, Vec<u8>, &'static str)> =
        cases.into_iter().map(|(name, entries, expect)| (name.to_owned(), raw_zip(&entries), expect)).collect();
    out.push(("not-a-zip.fmu".into(), b"PK\x03\x04 this is not really a zip".to_vec(), "not a zip archive"));
    out.push(("empty.fmu".into(), Vec::new(), "not a zip archive"));
    out
}
