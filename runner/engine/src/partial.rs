//! A sweep's CSV on file, as `runner sweep --out` and the Python package's `sweep(out=...)` both
//! keep it: the finished rows in `<out>.partial` until the last, beside the sweep's record
//! `<out>.sweep`, held locked for the sweep's life ([`SweepLock`]). `--resume` and
//! `resume=True` read the rows back with [`read_finished`]: each must be exactly the row the
//! sweep writes for its point ([`csv_line`] spells rows for both tools). Each tool writes its own
//! record and rows; what they share is here, so the two cannot drift apart.

use std::fs::{File, OpenOptions};
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// `<out>.partial`.
pub fn partial_path(out: &Path) -> PathBuf {
    with_suffix(out, ".partial")
}

/// `<out>.sweep`, the sweep's record.
pub fn record_path(out: &Path) -> PathBuf {
    with_suffix(out, ".sweep")
}

fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(suffix);
    PathBuf::from(name)
}

/// `<out>.sweep` held under an exclusive advisory lock (`flock`) for the sweep's life, so that a
/// second sweep to the same `--out` (this command or the Python package, which locks the same
/// file) is refused instead of interleaving its rows with this one's. The kernel drops the lock
/// when the process ends, however it ends: a killed sweep never blocks its `--resume`.
pub struct SweepLock {
    file: File,
    path: PathBuf,
    /// The record had content when it was locked: an earlier sweep's (an empty one is what
    /// locking created, or a sweep killed before writing it left).
    pub had_record: bool,
}

impl SweepLock {
    /// Locks `<out>.sweep`, creating it empty if there is none; refused at once if another
    /// process holds it, the message ending with how to continue in the caller's terms
    /// (`--resume`, `resume=True`).
    pub fn acquire(out: &Path, resume: &str) -> Result<SweepLock, String> {
        use std::os::fd::AsRawFd;
        let path = record_path(out);
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| format!("cannot open {}, the record of the sweep to {}: {e}", path.display(), out.display()))?;
        // SAFETY: flock on a descriptor this function owns.
        if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
            let e = std::io::Error::last_os_error();
            return Err(if e.kind() == std::io::ErrorKind::WouldBlock {
                format!(
                    "another sweep is writing {} (it holds {} locked): wait for it to end, or stop it and continue with {resume}",
                    out.display(),
                    path.display()
                )
            } else {
                format!("cannot lock {}, the record of the sweep to {}: {e}", path.display(), out.display())
            });
        }
        let had_record = file.metadata().map_err(|e| format!("cannot read {}: {e}", path.display()))?.len() > 0;
        Ok(SweepLock { file, path, had_record })
    }

    /// Replaces the record's text in the locked file itself (a new file renamed over it would
    /// be a file another sweep could lock).
    pub fn write_record(&mut self, text: &str) -> Result<(), String> {
        let cannot = |e: std::io::Error| format!("cannot write {}: {e}", self.path.display());
        self.file.set_len(0).map_err(cannot)?;
        self.file.seek(SeekFrom::Start(0)).map_err(cannot)?;
        self.file.write_all(text.as_bytes()).map_err(cannot)?;
        self.file.sync_data().map_err(cannot)
    }
}

/// One CSV row's bytes, exactly as a CSV writer spells them in a whole file.
pub fn csv_line<I: IntoIterator<Item = T>, T: AsRef<[u8]>>(row: I) -> Result<Vec<u8>, String> {
    let mut writer = csv::WriterBuilder::new().from_writer(Vec::new());
    writer.write_record(row).map_err(|e| format!("cannot format a CSV row: {e}"))?;
    writer.into_inner().map_err(|e| format!("cannot format a CSV row: {}", e.error()))
}

/// How the status of a system's sweep point that a component ended early starts: its metrics
/// are over the samples up to there, and the point did not fail.
pub const ENDED_EARLY: &str = "ended early: ";

/// True when a sweep row's `status` counts as a failed point.
pub fn failed(status: &str) -> bool {
    status != "ok" && !status.starts_with(ENDED_EARLY)
}

/// The finished rows of a partial (or complete) CSV, read back for `--resume`.
pub struct Finished {
    /// Number of point rows.
    pub rows: usize,
    /// Bytes of the header and those rows (a torn row after them is dropped).
    pub valid: u64,
    /// Each row's metric values (NaN where the point failed), `rows x metrics`.
    pub metrics: Vec<f64>,
    /// Rows of failed points ([`failed`]).
    pub failed: usize,
    /// The rows whose status is not `ok` (failed or ended early), each with its status: what a
    /// table of the kept rows needs besides their metrics.
    pub statuses: Vec<(usize, String)>,
}

/// Reads `path`, whose rows must be `header` and then points `0, 1, ...` with the parameter
/// values `point(i)` spells, `metrics` metric columns and a status. A last row cut short by a
/// kill is not counted; anything else that does not match is refused.
pub fn read_finished(
    path: &Path,
    header: &[String],
    metrics: usize,
    point: &mut dyn FnMut(usize) -> Option<Vec<String>>,
) -> Result<Finished, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let mut reader = csv::ReaderBuilder::new().has_headers(false).flexible(true).from_reader(&bytes[..]);
    let mut record = csv::StringRecord::new();
    let mut finished = Finished { rows: 0, valid: 0, metrics: Vec::new(), failed: 0, statuses: Vec::new() };
    let mut start = 0usize;
    let params = header.len() - metrics - 1;
    // The header is the file's first write: a file that holds only part of it was killed before
    // any row was there, and starting it again loses nothing.
    let header_line = csv_line(header)?;
    let header_torn = bytes.len() < header_line.len() && header_line.starts_with(&bytes);
    let torn_or_refused = |finished, start, end| torn_or_refused(path, finished, start, end, bytes.len(), header_torn);
    loop {
        let more = match reader.read_record(&mut record) {
            Ok(more) => more,
            // Invalid UTF-8 or a quote cut by a kill: only acceptable as the torn end.
            Err(_) => return torn_or_refused(finished, start, bytes.len()),
        };
        if !more {
            return Ok(finished);
        }
        let end = reader.position().byte() as usize;
        let exact = csv_line(&record)?[..] == bytes[start..end.min(bytes.len())];
        let row = finished.rows;
        let expected: Option<Vec<String>> = if start == 0 { Some(header.to_vec()) } else { point(row) };
        let fields: Vec<&str> = record.iter().collect();
        let matches = match &expected {
            _ if !exact || fields.len() != header.len() => false,
            Some(e) if start == 0 => fields == e.iter().map(String::as_str).collect::<Vec<_>>(),
            Some(e) => fields[..params] == e.iter().map(String::as_str).collect::<Vec<_>>()[..],
            None => false,
        };
        if !matches {
            return torn_or_refused(finished, start, end);
        }
        if start != 0 {
            for text in &fields[params..params + metrics] {
                let value = if text.is_empty() {
                    f64::NAN
                } else {
                    text.parse()
                        .map_err(|_| format!("{}: row {} has the metric {text:?}, which is not a number", path.display(), row + 1))?
                };
                finished.metrics.push(value);
            }
            let status = fields[params + metrics];
            finished.failed += usize::from(failed(status));
            if status != "ok" {
                finished.statuses.push((row, status.to_owned()));
            }
            finished.rows += 1;
        }
        start = end;
        finished.valid = end as u64;
    }
}

/// A row that does not read back exactly: if it runs to the end of the file it is the row a
/// kill cut short, and the rows before it stand (a header cut short, `header_torn`, leaves no
/// row); anywhere else the file is not this sweep's.
fn torn_or_refused(
    path: &Path,
    finished: Finished,
    start: usize,
    end: usize,
    length: usize,
    header_torn: bool,
) -> Result<Finished, String> {
    if end >= length && (start > 0 || header_torn) {
        Ok(finished)
    } else if start == 0 {
        Err(format!("{} does not start with this sweep's header: it is not this sweep's CSV, or was changed", path.display()))
    } else {
        Err(format!(
            "{}: row {} is not the row this sweep writes for point {} (the file was changed, or is another sweep's)",
            path.display(),
            finished.rows + 1,
            finished.rows + 1
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point counts as failed unless it is `ok` or a system's point a component ended early
    /// (its metrics are there), so a resumed sweep counts its rows as the first run did.
    #[test]
    fn ended_early_points_are_not_failures() {
        assert!(!failed("ok"));
        assert!(!failed("ended early: component 'car' at t = 1: the model terminated"));
        assert!(failed("crashed: SIGSEGV in fmi2DoStep of component 'bad' at t = 0.31"));
        assert!(failed("failed: component 'bad' at t = 0.5: fmi2DoStep returned fmi2Error"));
        assert!(failed("metric m is NaN"));
    }

    fn header() -> Vec<String> {
        ["k", "m", "status"].map(String::from).to_vec()
    }

    fn points(i: usize) -> Option<Vec<String>> {
        (i < 5).then(|| vec![format!("{:?}", i as f64)])
    }

    #[test]
    fn a_row_of_another_sweep_is_refused_not_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.csv.partial");
        std::fs::write(&path, "k,m,status\n0.0,1.0,ok\n7.0,1.0,ok\n1.0,2.0,ok\n").unwrap();
        let err = read_finished(&path, &header(), 1, &mut points).err().unwrap();
        assert!(err.contains("row 2 is not the row this sweep writes for point 2"), "{err}");
        std::fs::write(&path, "speed,m,status\n").unwrap();
        assert!(read_finished(&path, &header(), 1, &mut points).err().unwrap().contains("header"));
    }

    /// A header cut short (the file's first write, so no row was there) is started again, as
    /// the Python package does; a first line that is not part of this sweep's header is refused,
    /// cut short or not. Before, the torn header was refused and `--resume` could not go on.
    #[test]
    fn a_torn_header_is_started_again_and_another_first_line_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.csv.partial");
        for torn in ["k", "k,m,sta", "k,m,status"] {
            std::fs::write(&path, torn).unwrap();
            let read = read_finished(&path, &header(), 1, &mut points).unwrap_or_else(|e| panic!("{torn:?}: {e}"));
            assert_eq!((read.rows, read.valid), (0, 0), "{torn:?}: nothing kept, the file starts again");
        }
        for other in ["speed", "k,m,statu\n", "k,x"] {
            std::fs::write(&path, other).unwrap();
            let err = read_finished(&path, &header(), 1, &mut points).err().unwrap_or_else(|| panic!("{other:?} accepted"));
            assert!(err.contains("s.csv.partial does not start with this sweep's header"), "{err}");
        }
    }
}
