//! The zip rules of `.fmu` archives: how we write them (atomically, fixed layout) and how we
//! unpack other people's (refusing anything that could land outside the target directory, and
//! archives that would unpack to more files or bytes than any FMU needs).

use std::io::{Read, Seek, Write};
use std::path::{Component, Path, PathBuf};

/// One file of an archive.
pub struct Entry<'a> {
    pub path: &'a str,
    pub bytes: &'a [u8],
}

/// Writes `entries` as a zip into `out` and hands `out` back (`runner build` gives it a result
/// file that is renamed into place once complete, so a reader never sees half an archive).
pub fn write_zip<W: Write + Seek>(out: W, entries: &[Entry]) -> Result<W, String> {
    let mut zip = zip::ZipWriter::new(out);
    let options = zip::write::SimpleFileOptions::default().unix_permissions(0o644);
    for entry in entries {
        // Shared libraries are stored as they are: every sweep unpacks the FMU, and inflating
        // a 1.2 MB library took 8 ms of it; deflate would only halve the file.
        let method = if entry.path.starts_with("binaries/") { zip::CompressionMethod::Stored } else { zip::CompressionMethod::Deflated };
        zip.start_file(entry.path, options.compression_method(method)).map_err(|e| format!("zip {}: {e}", entry.path))?;
        zip.write_all(entry.bytes).map_err(|e| format!("zip {}: {e}", entry.path))?;
    }
    zip.finish().map_err(|e| format!("cannot finish the archive: {e}"))
}

/// Why an entry name is unsafe to extract, or `None` when it stays inside the target directory
/// (the rule `extract_zip` applies; `runner validate` reports each such entry).
pub fn unsafe_entry_name(name: &str) -> Option<&'static str> {
    // Zips written on Windows may use backslashes; treat them as separators so `..\\x` is caught.
    let normalized = name.replace('\\', "/");
    if normalized.starts_with('/') {
        return Some("an absolute path");
    }
    if normalized.as_bytes().get(1) == Some(&b':') {
        return Some("a drive-letter path");
    }
    if normalized.contains('\0') {
        return Some("a NUL byte");
    }
    for component in Path::new(&normalized).components() {
        match component {
            Component::Normal(_) | Component::CurDir => {}
            Component::ParentDir => return Some("a '..' component"),
            Component::RootDir | Component::Prefix(_) => return Some("an absolute path"),
        }
    }
    None
}

/// How much an archive may unpack to. A zip declares each entry's size, so a few kilobytes can
/// claim (and, compressed, really hold) gigabytes or millions of files; these bounds refuse such
/// an archive before it fills the disk.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Most entries (files and directories) an archive may have.
    pub max_entries: usize,
    /// Most bytes all files together may unpack to.
    pub max_total_bytes: u64,
}

impl Limits {
    /// The bounds for `.fmu` archives: far above any real FMU (binaries for a few platforms,
    /// sources, documentation), far below what would hurt the machine.
    pub const FMU: Limits = Limits { max_entries: 10_000, max_total_bytes: 1 << 30 };
}

/// `bytes` as a short human-readable size for error messages.
fn size_text(bytes: u64) -> String {
    match bytes {
        b if b >= 1 << 30 && b % (1 << 30) == 0 => format!("{} GiB", b >> 30),
        b if b >= 1 << 20 && b % (1 << 20) == 0 => format!("{} MiB", b >> 20),
        b => format!("{b} bytes"),
    }
}

/// Extracts the zip at `archive` into the existing directory `dest` within [`Limits::FMU`].
pub fn extract_zip(archive: &Path, dest: &Path) -> Result<(), String> {
    extract_zip_with(archive, dest, Limits::FMU)
}

/// An entry name as it may appear in a message: the archive chose it, so control characters
/// (terminal escapes, NUL) are escaped and a very long name is cut short.
fn shown(name: &str) -> String {
    fmi_schema::escaped_and_cut(name, 200, "...")
}

/// Extracts the zip at `archive` into the existing directory `dest`, refusing (before writing
/// anything) entries with absolute paths, `..` components or symbolic links, names that occur
/// twice, and archives over `limits`.
pub fn extract_zip_with(archive: &Path, dest: &Path, limits: Limits) -> Result<(), String> {
    check_zip(archive, limits)?.extract(dest)
}

/// An archive whose entry names and sizes passed the checks of [`extract_zip_with`], ready to be
/// extracted: what it will unpack to is known before a directory is chosen for it.
pub struct Checked {
    zip: zip::ZipArchive<std::fs::File>,
    /// (index, path inside the target, is a directory, declared size) per entry.
    plan: Vec<(usize, PathBuf, bool, u64)>,
    total: u64,
    at: String,
}

impl Checked {
    /// The bytes all files together declare: what extracting needs on disk.
    pub fn total_bytes(&self) -> u64 {
        self.total
    }

    /// Extracts the checked archive into the existing directory `dest`.
    pub fn extract(self, dest: &Path) -> Result<(), String> {
        let Checked { mut zip, plan, at, .. } = self;
        for (i, relative, is_dir, declared) in plan {
            let target = dest.join(&relative);
            let what = shown(&relative.to_string_lossy());
            // The temporary path means nothing to the user; the entry's path inside the archive does.
            let fail = |e: &dyn std::fmt::Display| format!("{at}: cannot extract '{what}': {e}");
            if is_dir || relative.as_os_str().is_empty() {
                std::fs::create_dir_all(&target).map_err(|e| fail(&e))?;
                continue;
            }
            if let Some(parent) = target.parent() {
                std::fs::create_dir_all(parent).map_err(|e| fail(&e))?;
            }
            let mut entry = zip.by_index(i).map_err(|e| fail(&e))?;
            // create_new: never overwrite (or follow a link at) a path an earlier entry made.
            let file = std::fs::OpenOptions::new().write(true).create_new(true).open(&target).map_err(|e| fail(&e))?;
            // A large buffer: a shared library in 8 KiB writes is 150 system calls.
            let mut out = std::io::BufWriter::with_capacity(1 << 18, file);
            // Declared sizes can lie: copy at most one byte more than declared, enough to tell.
            // Each file then stays within its declared size, so the total stays within the limit.
            let copied = std::io::copy(&mut (&mut entry).take(declared.saturating_add(1)), &mut out).map_err(|e| fail(&e))?;
            if copied > declared {
                return Err(fail(&format!("it unpacks to more than its declared size of {declared} bytes")));
            }
            out.flush().map_err(|e| fail(&e))?;
        }
        Ok(())
    }
}

/// Opens the zip at `archive` and checks every entry's name and declared size against the rules
/// of [`extract_zip_with`] and `limits`, writing nothing.
pub fn check_zip(archive: &Path, limits: Limits) -> Result<Checked, String> {
    let file = std::fs::File::open(archive).map_err(|e| format!("cannot open {}: {e}", archive.display()))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| format!("{} is not a zip archive (an .fmu is one): {e}", archive.display()))?;
    let at = archive.display();
    // The zip crate keeps one entry per name, so a repeated name must be caught here: which copy
    // counts would otherwise depend on the unzip tool, and a checker could see another file.
    if zip.has_duplicate_names() {
        return Err(format!("{at}: refusing the archive: it lists an entry name more than once"));
    }
    if zip.len() > limits.max_entries {
        return Err(format!("{at}: refusing the archive: it has {} entries, more than the limit of {}", zip.len(), limits.max_entries));
    }
    // First pass checks every name and size, so a bad archive leaves nothing behind.
    let mut plan: Vec<(usize, PathBuf, bool, u64)> = Vec::with_capacity(zip.len());
    let mut seen = std::collections::HashSet::new();
    let mut total: u64 = 0;
    for i in 0..zip.len() {
        let entry = zip.by_index_raw(i).map_err(|e| format!("{at}: entry {i}: {e}"))?;
        let name = String::from_utf8_lossy(entry.name_raw()).into_owned();
        if let Some(why) = unsafe_entry_name(&name) {
            return Err(format!(
                "{at}: refusing entry '{}': it has {why} and would be written outside the extraction directory",
                shown(&name)
            ));
        }
        if entry.is_symlink() {
            return Err(format!("{at}: refusing entry '{}': it is a symbolic link", shown(&name)));
        }
        let relative: PathBuf = name.replace('\\', "/").split('/').filter(|c| !c.is_empty() && *c != ".").collect();
        // Distinct names can still land on one path ("a/b", "a//b", "./a/b", a lossy non-UTF-8 name).
        if !relative.as_os_str().is_empty() && !seen.insert(relative.clone()) {
            return Err(format!(
                "{at}: refusing entry '{}': an earlier entry has the same path ({}), so it would be extracted more than once",
                shown(&name),
                shown(&relative.to_string_lossy())
            ));
        }
        let size = if entry.is_dir() { 0 } else { entry.size() };
        total = total.saturating_add(size);
        if total > limits.max_total_bytes {
            return Err(format!(
                "{at}: refusing the archive: its files would unpack to more than the limit of {} ('{}' alone declares {})",
                size_text(limits.max_total_bytes),
                shown(&name),
                size_text(size)
            ));
        }
        plan.push((i, relative, entry.is_dir(), size));
    }
    Ok(Checked { zip, plan, total, at: at.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_file(path: &Path, entries: &[Entry]) {
        write_zip(std::fs::File::create(path).unwrap(), entries).unwrap();
    }

    /// Writes `entries` as `name` in `dir` and extracts it into a fresh `dir/out` within `limits`.
    fn extract(dir: &Path, name: &str, entries: &[Entry], limits: Limits) -> Result<(), String> {
        let archive = dir.join(name);
        write_file(&archive, entries);
        let result = extract_into(dir, &archive, limits);
        if result.is_err() {
            // Names, sizes and counts are checked before anything is written.
            assert_eq!(std::fs::read_dir(dir.join("out")).unwrap().count(), 0, "a refused archive left files behind");
        }
        result
    }

    /// Extracts `archive` into a fresh `dir/out`.
    fn extract_into(dir: &Path, archive: &Path, limits: Limits) -> Result<(), String> {
        let out = dir.join("out");
        let _ = std::fs::remove_dir_all(&out);
        std::fs::create_dir(&out).unwrap();
        extract_zip_with(archive, &out, limits)
    }

    #[test]
    fn binaries_are_stored_and_the_rest_deflated_and_both_unpack_unchanged() {
        let dir = tempfile::tempdir().unwrap();
        let library: Vec<u8> = (0..200_000u32).map(|i| (i % 251) as u8).collect();
        let xml = b"<fmiModelDescription/>".repeat(100);
        let entries = [Entry { path: "modelDescription.xml", bytes: &xml }, Entry { path: "binaries/linux64/m.so", bytes: &library }];
        let archive = dir.path().join("m.fmu");
        write_file(&archive, &entries);
        let mut zip = zip::ZipArchive::new(std::fs::File::open(&archive).unwrap()).unwrap();
        assert_eq!(zip.by_name("binaries/linux64/m.so").unwrap().compression(), zip::CompressionMethod::Stored);
        assert_eq!(zip.by_name("modelDescription.xml").unwrap().compression(), zip::CompressionMethod::Deflated);
        let out = dir.path().join("out");
        extract_zip_with(&archive, &out, Limits::FMU).unwrap();
        assert_eq!(std::fs::read(out.join("binaries/linux64/m.so")).unwrap(), library);
        assert_eq!(std::fs::read(out.join("modelDescription.xml")).unwrap(), xml);
    }

    #[test]
    fn declared_sizes_over_the_limit_are_refused_before_writing() {
        let dir = tempfile::tempdir().unwrap();
        let zeros = vec![0u8; 3 << 20];
        let limits = Limits { max_total_bytes: 4 << 20, ..Limits::FMU };
        let one = [Entry { path: "a.bin", bytes: &zeros }];
        extract(dir.path(), "one.zip", &one, limits).unwrap();
        let two = [Entry { path: "a.bin", bytes: &zeros }, Entry { path: "b.bin", bytes: &zeros }];
        let error = extract(dir.path(), "two.zip", &two, limits).unwrap_err();
        assert!(error.contains("more than the limit of 4 MiB") && error.contains("'b.bin' alone declares 3 MiB"), "{error}");
        assert!(error.contains("two.zip"), "{error}");
    }

    #[test]
    fn more_entries_than_the_limit_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let names: Vec<String> = (0..=Limits::FMU.max_entries).map(|i| format!("d/{i}")).collect();
        let entries: Vec<Entry> = names.iter().map(|n| Entry { path: n, bytes: b"" }).collect();
        let error = extract(dir.path(), "many.zip", &entries, Limits::FMU).unwrap_err();
        assert!(error.contains("10001 entries, more than the limit of 10000"), "{error}");
        // Exactly at the limit is fine (a small limit, to keep the test quick).
        let limits = Limits { max_entries: 3, ..Limits::FMU };
        extract(dir.path(), "three.zip", &entries[..3], limits).unwrap();
        let error = extract(dir.path(), "four.zip", &entries[..4], limits).unwrap_err();
        assert!(error.contains("4 entries, more than the limit of 3"), "{error}");
    }

    #[test]
    fn an_entry_larger_than_it_declares_is_cut_off() {
        let dir = tempfile::tempdir().unwrap();
        let archive = dir.path().join("lying.zip");
        write_file(&archive, &[Entry { path: "bomb.bin", bytes: &vec![0u8; 1 << 20] }]);
        // Rewrite the declared uncompressed size, in the local header and the central directory,
        // to 100 bytes: the declared total is then harmless and only the copy can tell.
        let mut bytes = std::fs::read(&archive).unwrap();
        bytes[22..26].copy_from_slice(&100u32.to_le_bytes());
        let central = bytes.windows(4).position(|w| w == [0x50, 0x4b, 0x01, 0x02]).unwrap();
        bytes[central + 24..central + 28].copy_from_slice(&100u32.to_le_bytes());
        std::fs::write(&archive, &bytes).unwrap();
        let error = extract_into(dir.path(), &archive, Limits::FMU).unwrap_err();
        assert!(error.contains("bomb.bin") && error.contains("declared"), "{error}");
        // The copy stopped right after the declared size.
        let written = std::fs::metadata(dir.path().join("out/bomb.bin")).map(|m| m.len()).unwrap_or(0);
        assert!(written <= 101, "{written} bytes were written");
    }

    #[test]
    fn names_in_messages_are_escaped_and_cut_short() {
        assert_eq!(shown("a\u{1b}[31mb\0"), "a\\u{1b}[31mb\\u{0}");
        let long = "x".repeat(1000);
        assert_eq!(shown(&long), format!("{}...", &long[..200]));
        let dir = tempfile::tempdir().unwrap();
        let name = format!("{}/evil\u{1b}]0;title\u{7}", "d/".repeat(3000));
        let error = extract(dir.path(), "deep.zip", &[Entry { path: &name, bytes: b"x" }], Limits::FMU).unwrap_err();
        assert!(error.starts_with(&format!("{}: cannot extract 'd/d/d/", dir.path().join("deep.zip").display())), "{error}");
        assert!(error.len() < 400 && !error.contains('\u{1b}'), "{error}");
    }

    #[test]
    fn names_that_land_on_one_path_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let entries = [Entry { path: "a/b.txt", bytes: b"1" }, Entry { path: "a//./b.txt", bytes: b"2" }];
        let error = extract(dir.path(), "twice.zip", &entries, Limits::FMU).unwrap_err();
        assert!(error.contains("'a//./b.txt'") && error.contains("extracted more than once"), "{error}");
    }

    #[test]
    fn entry_names_that_escape_are_refused() {
        for bad in ["/etc/passwd", "../x.so", "binaries/../../x", "a\\..\\..\\b", "C:/x", "\\abs"] {
            assert!(unsafe_entry_name(bad).is_some(), "{bad} should be refused");
        }
        for good in ["modelDescription.xml", "binaries/linux64/m.so", "./resources/a.txt", "documentation/"] {
            assert_eq!(unsafe_entry_name(good), None, "{good} should be accepted");
        }
    }
}
