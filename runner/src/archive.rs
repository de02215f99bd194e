//! The zip rules of `.fmu` archives: how we write them (atomically, fixed layout).

use std::io::Write;
use std::path::Path;

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
