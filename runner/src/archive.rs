//! The zip rules of `.fmu` archives: how we write them (atomically, fixed layout) and how we
//! unpack other people's (refusing anything that could land outside the target directory).

use std::io::Write;
use std::path::{Component, Path, PathBuf};

/// One file of an archive.
pub struct Entry<'a> {
    pub path: &'a str,
    pub bytes: &'a [u8],
}

/// Writes `entries` as a zip at `dest`, via a temporary file renamed into place so a reader
/// never sees half an archive.
pub fn write_zip(dest: &Path, entries: &[Entry]) -> Result<(), String> {
    let dir = dest.parent().ok_or_else(|| format!("{} has no parent directory", dest.display()))?;
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let tmp = dest.with_extension("fmu.partial");
    let result = (|| -> Result<(), String> {
        let file = std::fs::File::create(&tmp).map_err(|e| format!("cannot create {}: {e}", tmp.display()))?;
        let mut zip = zip::ZipWriter::new(file);
        let options = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated).unix_permissions(0o644);
        for entry in entries {
            zip.start_file(entry.path, options).map_err(|e| format!("zip {}: {e}", entry.path))?;
            zip.write_all(entry.bytes).map_err(|e| format!("zip {}: {e}", entry.path))?;
        }
        zip.finish().map_err(|e| format!("cannot finish {}: {e}", tmp.display()))?;
        std::fs::rename(&tmp, dest).map_err(|e| format!("cannot move {} into place: {e}", dest.display()))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Why an entry name is unsafe to extract, or `None` when it stays inside the target directory.
fn unsafe_entry_name(name: &str) -> Option<&'static str> {
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

/// Extracts the zip at `archive` into the existing directory `dest`, refusing (before writing
/// anything) entries with absolute paths, `..` components or symbolic links.
pub fn extract_zip(archive: &Path, dest: &Path) -> Result<(), String> {
    let file = std::fs::File::open(archive).map_err(|e| format!("cannot open {}: {e}", archive.display()))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| format!("{} is not a zip archive (an .fmu is one): {e}", archive.display()))?;
    // First pass checks every name, so a bad archive leaves nothing behind.
    let mut plan: Vec<(usize, PathBuf, bool)> = Vec::with_capacity(zip.len());
    for i in 0..zip.len() {
        let entry = zip.by_index_raw(i).map_err(|e| format!("{}: entry {i}: {e}", archive.display()))?;
        let name = String::from_utf8_lossy(entry.name_raw()).into_owned();
        if let Some(why) = unsafe_entry_name(&name) {
            return Err(format!("{}: refusing entry '{name}': it has {why} and would be written outside the extraction directory", archive.display()));
        }
        if entry.is_symlink() {
            return Err(format!("{}: refusing entry '{name}': it is a symbolic link", archive.display()));
        }
        let relative: PathBuf = name.replace('\\', "/").split('/').filter(|c| !c.is_empty() && *c != ".").collect();
        plan.push((i, relative, entry.is_dir()));
    }
    for (i, relative, is_dir) in plan {
        let target = dest.join(&relative);
        if is_dir || relative.as_os_str().is_empty() {
            std::fs::create_dir_all(&target).map_err(|e| format!("cannot create {}: {e}", target.display()))?;
            continue;
        }
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent).map_err(|e| format!("cannot create {}: {e}", parent.display()))?;
        }
        let mut entry = zip.by_index(i).map_err(|e| format!("{}: entry {}: {e}", archive.display(), relative.display()))?;
        // create_new: a duplicate name must not overwrite (or follow) what an earlier entry made.
        let mut out = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&target)
            .map_err(|e| format!("cannot create {}: {e}", target.display()))?;
        std::io::copy(&mut entry, &mut out).map_err(|e| format!("{}: cannot extract {}: {e}", archive.display(), relative.display()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::unsafe_entry_name;

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
