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
    /// Entries listed again with the same contents (skipped), by name.
    duplicates: Vec<String>,
}

/// Most bytes a repeated entry may have for its copies to be compared (they are read whole).
const MOST_COMPARED: u64 = 1 << 28;

impl Checked {
    /// The files the archive lists more than once, each time with the same bytes: accepted
    /// (the copies are one file), but a warning for `runner validate`.
    pub fn duplicates(&self) -> &[String] {
        &self.duplicates
    }

    /// The bytes all files together declare: what extracting needs on disk.
    pub fn total_bytes(&self) -> u64 {
        self.total
    }

    /// Extracts the checked archive into the existing directory `dest`.
    pub fn extract(self, dest: &Path) -> Result<(), String> {
        let Checked { mut zip, plan, at, .. } = self;
        for entry in plan {
            extract_entry(&mut zip, entry, dest, &at)?;
        }
        Ok(())
    }

    /// Extracts the file `name` (a path inside the archive) into `dest` first, if the archive
    /// has it; [`Checked::extract`] then extracts the others.
    pub fn extract_first(&mut self, name: &str, dest: &Path) -> Result<(), String> {
        match self.plan.iter().position(|(_, relative, is_dir, _)| !is_dir && relative == Path::new(name)) {
            Some(k) => {
                let entry = self.plan.remove(k);
                extract_entry(&mut self.zip, entry, dest, &self.at)
            }
            None => Ok(()),
        }
    }
}

/// Extracts one planned entry (index, path inside the target, is a directory, declared size)
/// of the archive `at` into `dest`.
fn extract_entry(
    zip: &mut zip::ZipArchive<std::fs::File>,
    (i, relative, is_dir, declared): (usize, PathBuf, bool, u64),
    dest: &Path,
    at: &str,
) -> Result<(), String> {
    let target = dest.join(&relative);
    let what = shown(&relative.to_string_lossy());
    // The temporary path means nothing to the user; the entry's path inside the archive does.
    let fail = |e: &dyn std::fmt::Display| format!("{at}: cannot extract '{what}': {e}");
    if is_dir || relative.as_os_str().is_empty() {
        return std::fs::create_dir_all(&target).map_err(|e| fail(&e));
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
    Ok(())
}

/// Opens the zip at `archive` and checks every entry's name and declared size against the rules
/// of [`extract_zip_with`] and `limits`, writing nothing.
pub fn check_zip(archive: &Path, limits: Limits) -> Result<Checked, String> {
    let file = std::fs::File::open(archive).map_err(|e| format!("cannot open {}: {e}", archive.display()))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| format!("{} is not a zip archive (an .fmu is one): {e}", archive.display()))?;
    let at = archive.display();
    // The zip crate keeps one entry per name, so copies listed under one name are found in
    // the central directory itself and compared there.
    let mut duplicates = if zip.has_duplicate_names() {
        let mut file = std::fs::File::open(archive).map_err(|e| format!("cannot open {}: {e}", archive.display()))?;
        same_name_copies(&mut file).map_err(|why| format!("{at}: refusing the archive: {why}"))?
    } else {
        Vec::new()
    };
    if zip.len() > limits.max_entries {
        return Err(format!("{at}: refusing the archive: it has {} entries, more than the limit of {}", zip.len(), limits.max_entries));
    }
    // First pass checks every name and size, so a bad archive leaves nothing behind.
    let mut plan: Vec<(usize, PathBuf, bool, u64)> = Vec::with_capacity(zip.len());
    // Each path and the entry first listed there: a path listed again (the same name twice,
    // or names such as "a/b" and "a//b") is one file only if the copies are the same bytes;
    // else which copy counts would depend on the unzip tool, and a checker could see another.
    let mut seen: std::collections::HashMap<PathBuf, usize> = std::collections::HashMap::new();
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
        let is_dir = entry.is_dir();
        drop(entry);
        if let Some(&first) = seen.get(&relative) {
            if !relative.as_os_str().is_empty() {
                same_contents(&mut zip, first, i).map_err(|why| {
                    format!(
                        "{at}: refusing entry '{}': an earlier entry has the same path ({}) {why}, so a tool that takes the first copy and one that takes the last would unpack different FMUs",
                        shown(&name),
                        shown(&relative.to_string_lossy())
                    )
                })?;
                if !is_dir {
                    duplicates.push(shown(&relative.to_string_lossy()));
                }
            }
            continue;
        }
        seen.insert(relative.clone(), i);
        let entry = zip.by_index_raw(i).map_err(|e| format!("{at}: entry {i}: {e}"))?;
        let size = if is_dir { 0 } else { entry.size() };
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
    Ok(Checked { zip, plan, total, at: at.to_string(), duplicates })
}

/// The names the central directory lists more than once, each with copies of the same stored
/// bytes (compression method and data, read from each copy's local header on); an error names
/// one whose copies differ. Copies compressed differently count as different: an archive
/// writer that repeats an entry repeats its bytes.
fn same_name_copies(file: &mut std::fs::File) -> Result<Vec<String>, String> {
    let records = central_directory(file)?;
    let mut by_name: std::collections::BTreeMap<&[u8], Vec<(u64, u64)>> = std::collections::BTreeMap::new();
    for (name, offset, compressed) in &records {
        by_name.entry(name.as_slice()).or_default().push((*offset, *compressed));
    }
    let mut repeated = Vec::new();
    for (name, copies) in by_name.into_iter().filter(|(_, c)| c.len() > 1) {
        let shown_name = shown(&String::from_utf8_lossy(name));
        let unreadable = |e: &dyn std::fmt::Display| format!("a copy of entry '{shown_name}' cannot be read: {e}");
        let mut first: Option<(u16, Vec<u8>)> = None;
        for (offset, compressed) in copies {
            if compressed > MOST_COMPARED {
                return Err(format!("entry '{shown_name}' is listed more than once and too large to compare the copies"));
            }
            // The local header: signature, ..., method at 8, name and extra lengths at 26 and 28.
            let mut header = [0u8; 30];
            file.seek(std::io::SeekFrom::Start(offset)).map_err(|e| unreadable(&e))?;
            file.read_exact(&mut header).map_err(|e| unreadable(&e))?;
            if header[..4] != [0x50, 0x4b, 0x03, 0x04] {
                return Err(unreadable(&"no local header at its offset"));
            }
            let method = u16::from_le_bytes([header[8], header[9]]);
            let skip = i64::from(u16::from_le_bytes([header[26], header[27]])) + i64::from(u16::from_le_bytes([header[28], header[29]]));
            file.seek(std::io::SeekFrom::Current(skip)).map_err(|e| unreadable(&e))?;
            let mut data = vec![0u8; compressed as usize];
            file.read_exact(&mut data).map_err(|e| unreadable(&e))?;
            match &first {
                None => first = Some((method, data)),
                Some(kept) if *kept == (method, data) => {}
                Some(_) => {
                    return Err(format!(
                        "it lists entry '{shown_name}' more than once with different contents, so a tool that takes the first copy and one that takes the last would unpack different FMUs"
                    ))
                }
            }
        }
        // Directories repeated are harmless: the files are named.
        if !name.ends_with(b"/") {
            repeated.push(shown_name);
        }
    }
    Ok(repeated)
}

/// Every record of the zip's central directory: the raw name, the local header's offset and the
/// compressed size. Zip64 archives (whose fields say 0xFFFFFFFF) are not read here.
fn central_directory(file: &mut std::fs::File) -> Result<Vec<(Vec<u8>, u64, u64)>, String> {
    let fail = |e: std::io::Error| format!("the central directory cannot be read: {e}");
    let length = file.seek(std::io::SeekFrom::End(0)).map_err(fail)?;
    // The end record: 22 bytes and a comment of at most 65,535, at the end.
    let tail_length = length.min(22 + 65_535);
    file.seek(std::io::SeekFrom::Start(length - tail_length)).map_err(fail)?;
    let mut tail = vec![0u8; tail_length as usize];
    file.read_exact(&mut tail).map_err(fail)?;
    let end = (0..tail.len().saturating_sub(21))
        .rev()
        .find(|&i| tail[i..i + 4] == [0x50, 0x4b, 0x05, 0x06])
        .ok_or("it has no end of central directory record")?;
    let u16_at = |b: &[u8], i: usize| u16::from_le_bytes([b[i], b[i + 1]]) as usize;
    let u32_at = |b: &[u8], i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    let (count, size, start) = (u16_at(&tail, end + 10), u32_at(&tail, end + 12), u32_at(&tail, end + 16));
    if size == u32::MAX || start == u32::MAX || count == 0xFFFF {
        return Err("it lists an entry name more than once in a zip64 directory, whose copies the runner does not compare".to_owned());
    }
    if u64::from(start) + u64::from(size) > length {
        return Err("its central directory lies past the end of the file".to_owned());
    }
    file.seek(std::io::SeekFrom::Start(u64::from(start))).map_err(fail)?;
    let mut directory = vec![0u8; size as usize];
    file.read_exact(&mut directory).map_err(fail)?;
    let mut records = Vec::with_capacity(count);
    let mut at = 0;
    for _ in 0..count {
        if at + 46 > directory.len() || directory[at..at + 4] != [0x50, 0x4b, 0x01, 0x02] {
            return Err("its central directory is truncated".to_owned());
        }
        let (name_length, extra, comment) = (u16_at(&directory, at + 28), u16_at(&directory, at + 30), u16_at(&directory, at + 32));
        let (compressed, offset) = (u32_at(&directory, at + 20), u32_at(&directory, at + 42));
        if compressed == u32::MAX || offset == u32::MAX {
            return Err("it lists an entry name more than once in a zip64 directory, whose copies the runner does not compare".to_owned());
        }
        let name = directory.get(at + 46..at + 46 + name_length).ok_or("its central directory is truncated")?;
        records.push((name.to_vec(), u64::from(offset), u64::from(compressed)));
        at += 46 + name_length + extra + comment;
    }
    Ok(records)
}

/// Whether entries `a` and `b` are the same: both directories, or files of the same bytes
/// (read and compared, up to [`MOST_COMPARED`] bytes each); else why not.
fn same_contents(zip: &mut zip::ZipArchive<std::fs::File>, a: usize, b: usize) -> Result<(), String> {
    let mut read = |i: usize| -> Result<Option<Vec<u8>>, String> {
        let mut entry = zip.by_index(i).map_err(|e| format!("and entry {i} cannot be read ({e})"))?;
        if entry.is_dir() {
            return Ok(None);
        }
        if entry.size() > MOST_COMPARED {
            return Err(format!("and {} bytes, too many to compare", entry.size()));
        }
        let mut bytes = Vec::with_capacity(entry.size() as usize);
        (&mut entry).take(MOST_COMPARED + 1).read_to_end(&mut bytes).map_err(|e| format!("and cannot be read ({e})"))?;
        Ok(Some(bytes))
    };
    match (read(a)?, read(b)?) {
        (None, None) => Ok(()),
        (Some(x), Some(y)) if x == y => Ok(()),
        (Some(_), Some(_)) => Err("with different contents".to_owned()),
        _ => Err("but one is a directory and the other a file".to_owned()),
    }
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
    fn names_that_land_on_one_path_with_other_bytes_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let entries = [Entry { path: "a/b.txt", bytes: b"1" }, Entry { path: "a//./b.txt", bytes: b"2" }];
        let error = extract(dir.path(), "twice.zip", &entries, Limits::FMU).unwrap_err();
        assert!(error.contains("'a//./b.txt'") && error.contains("different contents"), "{error}");
        let entries = [Entry { path: "a/b", bytes: b"1" }, Entry { path: "a/b/", bytes: b"" }];
        let error = extract(dir.path(), "kinds.zip", &entries, Limits::FMU).unwrap_err();
        assert!(error.contains("one is a directory and the other a file"), "{error}");
    }

    /// A zip listing one name twice: written with the names "x/a.txt" and "x/b.txt", then the
    /// second renamed in its local header and its central directory record (the zip writer
    /// refuses a repeated name).
    fn same_name_twice(dir: &Path, first: &[u8], second: &[u8]) -> PathBuf {
        let archive = dir.join("twice.zip");
        write_file(&archive, &[Entry { path: "x/a.txt", bytes: first }, Entry { path: "x/b.txt", bytes: second }]);
        let mut bytes = std::fs::read(&archive).unwrap();
        for at in (0..bytes.len() - 7).filter(|&i| &bytes[i..i + 7] == b"x/b.txt").collect::<Vec<_>>() {
            bytes[at..at + 7].copy_from_slice(b"x/a.txt");
        }
        std::fs::write(&archive, &bytes).unwrap();
        archive
    }

    /// The same name listed twice: the copies' bytes decide (the zip crate itself keeps one).
    #[test]
    fn a_name_listed_twice_is_one_file_only_with_the_same_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let archive = same_name_twice(dir.path(), b"same bytes", b"same bytes");
        let checked = check_zip(&archive, Limits::FMU).unwrap();
        assert_eq!(checked.duplicates(), ["x/a.txt"]);
        let archive = same_name_twice(dir.path(), b"first copy", b"other copy");
        let error = check_zip(&archive, Limits::FMU).err().unwrap();
        assert!(error.contains("lists entry 'x/a.txt' more than once with different contents"), "{error}");
    }

    /// Issue 33: the Reference FMUs' Roberts.fmu lists its `extra/` entries twice, the same
    /// bytes each time. Such copies are one file: extracted once, and named for a warning.
    #[test]
    fn an_entry_listed_twice_with_the_same_bytes_is_extracted_once_and_reported() {
        let dir = tempfile::tempdir().unwrap();
        let entries = [
            Entry { path: "extra/", bytes: b"" },
            Entry { path: "extra/a.csv", bytes: b"t,x\n0,1\n" },
            Entry { path: "extra//", bytes: b"" },
            Entry { path: "extra/./a.csv", bytes: b"t,x\n0,1\n" },
        ];
        let archive = dir.path().join("same.zip");
        write_file(&archive, &entries);
        let checked = check_zip(&archive, Limits::FMU).unwrap();
        assert_eq!(checked.duplicates(), ["extra/a.csv"]);
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        checked.extract(&out).unwrap();
        assert_eq!(std::fs::read(out.join("extra/a.csv")).unwrap(), b"t,x\n0,1\n");
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
