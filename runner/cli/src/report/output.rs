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

/// A CSV table written row by row as the csv crate writes it (`,` between fields, `\n` after a
/// row, a field quoted only when it holds `,`, `"`, `\r` or `\n`, its quotes doubled), for the
/// long tables of `simulate`: numbers, which never need quotes, are appended as they are, with
/// neither a String each nor csv's scan of every field. Rows reach the output in chunks, as
/// csv's own buffer gave them.
pub struct CsvRows {
    /// `None` once finished.
    output: Option<Output>,
    pending: Vec<u8>,
    /// No field of the current row written yet.
    row_start: bool,
}

impl CsvRows {
    const CHUNK: usize = 8 * 1024;

    /// Starts the table on [`Output::open`]`(path)` with the row `header`.
    pub fn open(path: Option<&Path>, header: &[String]) -> Result<CsvRows, String> {
        let mut rows = CsvRows { output: Some(Output::open(path)?), pending: Vec::with_capacity(2 * Self::CHUNK), row_start: true };
        for name in header {
            rows.text(name);
        }
        rows.end_row()?;
        Ok(rows)
    }

    /// The buffer to append the next field's bytes to, which need no quotes (a number's text).
    pub fn field(&mut self) -> &mut Vec<u8> {
        if !std::mem::take(&mut self.row_start) {
            self.pending.push(b',');
        }
        &mut self.pending
    }

    /// The next field, any text: quoted when it needs to be.
    pub fn text(&mut self, text: &str) {
        let out = self.field();
        if text.bytes().any(|b| matches!(b, b',' | b'"' | b'\r' | b'\n')) {
            out.push(b'"');
            for b in text.bytes() {
                if b == b'"' {
                    out.push(b'"');
                }
                out.push(b);
            }
            out.push(b'"');
        } else {
            out.extend_from_slice(text.as_bytes());
        }
    }

    /// Ends the current row.
    pub fn end_row(&mut self) -> Result<(), String> {
        self.pending.push(b'\n');
        self.row_start = true;
        if self.pending.len() >= Self::CHUNK {
            self.write_pending()?;
        }
        Ok(())
    }

    fn write_pending(&mut self) -> Result<(), String> {
        if let Some(output) = &mut self.output {
            output.write_all(&self.pending).map_err(|e| format!("cannot write CSV: {e}"))?;
        }
        self.pending.clear();
        Ok(())
    }

    /// Writes the rows still pending and commits the output ([`Output::commit`]).
    pub fn finish(mut self) -> Result<(), String> {
        self.write_pending()?;
        self.output.take().map_or(Ok(()), Output::commit)
    }
}

impl Drop for CsvRows {
    /// A command that fails still has every row written so far on standard output, as csv's
    /// writer gave it; a result file not committed is deleted whatever it holds.
    fn drop(&mut self) {
        if let Some(output) = &mut self.output {
            let _ = output.write_all(&self.pending);
            let _ = output.flush();
        }
    }
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

    /// `simulate`'s tables must keep their bytes: CsvRows against the csv crate's writer (which
    /// wrote them before) on a header and rows of numbers and of texts that need quotes or not.
    #[test]
    fn csv_rows_are_the_csv_crates_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("rows.csv");
        let header: Vec<String> = ["time", "a,b", "say \"hi\"", "x"].map(String::from).to_vec();
        let rows = [["0.0", "plain", "", "1e-5"], ["0.5", "two\nlines", "cr\rhere", "-0.0"], ["1.0", "\"quoted\"", " spaced ", "NaN"]];
        let mut ours = CsvRows::open(Some(&dest), &header).unwrap();
        for row in rows {
            ours.field().extend_from_slice(row[0].as_bytes());
            ours.text(row[1]);
            ours.text(row[2]);
            ours.field().extend_from_slice(row[3].as_bytes());
            ours.end_row().unwrap();
        }
        ours.finish().unwrap();
        let mut theirs = csv::Writer::from_writer(Vec::new());
        theirs.write_record(&header).unwrap();
        for row in rows {
            theirs.write_record(row).unwrap();
        }
        assert_eq!(std::fs::read_to_string(&dest).unwrap(), String::from_utf8(theirs.into_inner().unwrap()).unwrap());
    }

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
