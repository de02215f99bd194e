//! Result files are never half-written: each is written under a temporary name beside its
//! destination and renamed into place only once complete, so an interrupted or failed command
//! leaves the previous file (or none), never a truncated one that looks finished. A destination
//! that is a stream (`/dev/null`, `/dev/stdout`, a FIFO) is written directly: a rename would
//! replace the device with a regular file.

use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::interrupt;

/// The directory a result file goes into (`.` for a bare file name).
fn directory_of(dest: &Path) -> &Path {
    match dest.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Refuses a destination whose directory does not exist, so that a file written only after the
/// runs (a plot, a comparison's table) is refused before them, not after minutes of work.
pub fn check_destination(dest: &Path) -> Result<(), String> {
    let dir = directory_of(dest);
    if dir.is_dir() {
        Ok(())
    } else {
        Err(format!("cannot write {}: the directory {} does not exist", dest.display(), dir.display()))
    }
}

/// Whether `dest` exists and is neither a regular file nor a directory (after symbolic links): a
/// device, a FIFO or a socket, written as a stream.
pub fn is_stream(dest: &Path) -> bool {
    std::fs::metadata(dest).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Where a result file's bytes go until it is committed.
enum Sink {
    /// A temporary file in the destination's directory (deleted if dropped before
    /// [`ResultFile::commit`]).
    Temp(BufWriter<tempfile::NamedTempFile>),
    /// The destination itself, a stream ([`is_stream`]).
    Stream(BufWriter<std::fs::File>),
}

/// A result file being written.
pub struct ResultFile {
    /// `None` only inside `commit`.
    sink: Option<Sink>,
    /// The temporary file's path, registered for the second Ctrl-C (empty for a stream).
    partial: PathBuf,
    dest: PathBuf,
}

impl ResultFile {
    /// Starts writing `dest`; its directory must exist.
    pub fn create(dest: &Path) -> Result<ResultFile, String> {
        if is_stream(dest) {
            let file = std::fs::OpenOptions::new().write(true).open(dest).map_err(|e| format!("cannot write {}: {e}", dest.display()))?;
            return Ok(ResultFile { sink: Some(Sink::Stream(BufWriter::new(file))), partial: PathBuf::new(), dest: dest.to_path_buf() });
        }
        let dir = directory_of(dest);
        let name = dest.file_name().ok_or_else(|| format!("{} is not a file name", dest.display()))?.to_string_lossy();
        let prefix = format!(".{name}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".partial");
        // Like File::create, the user's umask decides (usually rw-r--r--), not tempfile's
        // private default (rw-------): the file is a result to share, not a secret.
        #[cfg(unix)]
        builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
        let temp =
            builder.tempfile_in(dir).map_err(|e| format!("cannot create a file in {} for {}: {e}", dir.display(), dest.display()))?;
        let partial = temp.path().to_path_buf();
        interrupt::register_partial(&partial);
        Ok(ResultFile { sink: Some(Sink::Temp(BufWriter::new(temp))), partial, dest: dest.to_path_buf() })
    }

    /// The destination.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Flushes and renames the file into place (a stream: flushes).
    pub fn commit(mut self) -> Result<(), String> {
        let dest = &self.dest;
        match self.sink.take().expect("a ResultFile is committed once") {
            Sink::Temp(buffered) => {
                let temp = buffered.into_inner().map_err(|e| format!("cannot write {}: {}", dest.display(), e.error()))?;
                temp.persist(dest).map(|_| ()).map_err(|e| format!("cannot move the finished {} into place: {}", dest.display(), e.error))
            }
            Sink::Stream(mut stream) => stream.flush().map_err(|e| format!("cannot write {}: {e}", dest.display())),
        }
    }

    fn sink(&mut self) -> &mut Sink {
        self.sink.as_mut().expect("a ResultFile is not written after commit")
    }
}

impl Drop for ResultFile {
    fn drop(&mut self) {
        // Committed or not, the temporary name is gone now: an abandoned file is deleted by
        // NamedTempFile's own drop.
        interrupt::unregister_partial(&self.partial);
    }
}

impl Write for ResultFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self.sink() {
            Sink::Temp(f) => f.write(buf),
            Sink::Stream(f) => f.write(buf),
        }
    }
    fn flush(&mut self) -> std::io::Result<()> {
        match self.sink() {
            Sink::Temp(f) => f.flush(),
            Sink::Stream(f) => f.flush(),
        }
    }
}

// A zip writer seeks back to patch its local headers (the FMUs `runner build` packs); a stream
// refuses, as the device does.
impl Seek for ResultFile {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        match self.sink() {
            Sink::Temp(f) => f.seek(pos),
            Sink::Stream(f) => f.seek(pos),
        }
    }
}

/// Where a command's table goes: a result file, or stdout when no file was named.
pub enum Output {
    /// A file written atomically.
    File(ResultFile),
    /// Standard output, streamed as rows arrive.
    Stdout(std::io::Stdout),
}

impl Output {
    /// A result file at `path`, or stdout for `None`.
    pub fn open(path: Option<&Path>) -> Result<Output, String> {
        Ok(match path {
            Some(p) => Output::File(ResultFile::create(p)?),
            None => Output::Stdout(std::io::stdout()),
        })
    }

    /// Where it goes, for messages.
    pub fn describe(&self) -> String {
        match self {
            Output::File(f) => f.dest().display().to_string(),
            Output::Stdout(_) => "standard output".to_owned(),
        }
    }

    /// Finishes the output: renames a file into place, flushes stdout.
    pub fn commit(self) -> Result<(), String> {
        match self {
            Output::File(f) => f.commit(),
            Output::Stdout(mut s) => s.flush().map_err(|e| format!("cannot write to standard output: {e}")),
        }
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self {
            Output::File(f) => f.write(buf),
            Output::Stdout(s) => s.write(buf),
        }
    }
    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Output::File(f) => f.flush(),
            Output::Stdout(s) => s.flush(),
        }
    }
}

/// A CSV writer on [`Output::open`]`(path)`.
pub fn csv_writer(path: Option<&Path>) -> Result<csv::Writer<Output>, String> {
    Ok(csv::WriterBuilder::new().from_writer(Output::open(path)?))
}

/// Flushes a CSV writer and commits its output.
pub fn finish_csv(writer: csv::Writer<Output>) -> Result<(), String> {
    let output = writer.into_inner().map_err(|e| format!("cannot write CSV: {}", e.error()))?;
    output.commit()
}

/// Writes `bytes` to `dest` atomically.
pub fn write_file(dest: &Path, bytes: &[u8]) -> Result<(), String> {
    let mut file = ResultFile::create(dest)?;
    file.write_all(bytes).map_err(|e| format!("cannot write {}: {e}", dest.display()))?;
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_appears_only_when_committed_and_an_abandoned_one_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("table.csv");
        std::fs::write(&dest, "old complete file\n").unwrap();
        let mut file = ResultFile::create(&dest).unwrap();
        file.write_all(b"new, half").unwrap();
        file.flush().unwrap();
        assert_eq!(std::fs::read_to_string(&dest).unwrap(), "old complete file\n", "the destination is untouched while writing");
        drop(file);
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, vec![std::ffi::OsString::from("table.csv")], "the abandoned temporary file is gone");

        let mut file = ResultFile::create(&dest).unwrap();
        file.write_all(b"new complete file\n").unwrap();
        file.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&dest).unwrap(), "new complete file\n");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    /// A result is a file to share: it gets the permissions File::create gives (the umask's
    /// say), not the owner-only ones of a temporary file. Both are made under the same umask.
    #[cfg(unix)]
    #[test]
    fn a_result_file_gets_the_permissions_of_a_plain_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain.csv");
        std::fs::File::create(&plain).unwrap();
        let dest = dir.path().join("table.csv");
        let mut file = ResultFile::create(&dest).unwrap();
        file.write_all(b"x\n").unwrap();
        file.commit().unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&dest), mode(&plain), "result {:o}, plain file {:o}", mode(&dest), mode(&plain));
    }

    #[test]
    fn a_missing_directory_is_named() {
        let err = ResultFile::create(Path::new("/nonexistent-dir/x.csv")).err().unwrap();
        assert!(err.contains("/nonexistent-dir") && err.contains("x.csv"), "{err}");
    }
}
