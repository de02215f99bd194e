//! A sweep's CSV while it is being written: `<out>.partial`, a visible file that holds the header
//! and every finished row in point order, flushed every [`FLUSH_EVERY`] and fsynced every
//! [`SYNC_EVERY`] by a thread of its own, so a killed process loses at most the rows of the last
//! [`FLUSH_EVERY`] and a crashed machine those of the last [`SYNC_EVERY`]. A finished sweep starts
//! the write-back of its last rows and renames the file without waiting for the disk (an fsync
//! takes 20 to 50 ms on the development machine, a quarter of the handbook's sweep); an
//! interrupted or failed one waits, as the rows kept are what the user will resume from. Beside it `<out>.sweep` records what the sweep is (the FMU's hash, parameters,
//! metrics, settings), so that `--resume` can tell whether the partial file is its own. When the
//! last row is written the partial file is renamed to `<out>`; the record stays as the CSV's
//! provenance.

use std::fs::{File, OpenOptions};
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Rows wait at most this long in memory before they are written to the partial file.
pub const FLUSH_EVERY: Duration = Duration::from_millis(100);
/// Written rows reach the disk (fsync) at most this long after they were written.
pub const SYNC_EVERY: Duration = Duration::from_secs(2);
/// Rows are written at once when this many bytes are waiting.
const BATCH_BYTES: usize = 64 << 10;

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
    /// process holds it.
    pub fn acquire(out: &Path) -> Result<SweepLock, String> {
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
                    "another sweep is writing {} (it holds {} locked): wait for it to end, or stop it and continue with --resume",
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

/// What a sweep is, as `key = value` lines: everything that decides its CSV's content.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// In order; a key may repeat (one `param` per parameter).
    pub entries: Vec<(String, String)>,
}

/// Keys that describe but do not identify (the FMU or system may be moved or named another way;
/// its hash decides).
const INFORMATIONAL: &[&str] = &["fmu", "system"];

impl Record {
    /// The record's text.
    pub fn text(&self) -> String {
        let mut text = String::from("# runner sweep: what produced the CSV beside this file; `runner sweep --resume` checks it\n");
        for (key, value) in &self.entries {
            text.push_str(&format!("{key} = {value}\n"));
        }
        text
    }

    /// Reads a record written by [`Record::text`].
    pub fn parse(text: &str) -> Result<Record, String> {
        if text.starts_with("# fmurunner sweep") {
            return Err(
                "this is the record of a sweep of the Python package, fmurunner: continue it there, with sweep(..., out=..., resume=True)"
                    .to_owned(),
            );
        }
        let mut entries = Vec::new();
        for line in text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()) {
            let (key, value) = line.split_once(" = ").ok_or_else(|| format!("the line {line:?} is not KEY = VALUE"))?;
            entries.push((key.to_owned(), value.to_owned()));
        }
        Ok(Record { entries })
    }

    /// What differs between `self` (the partial file's) and `current` (this sweep's), one line
    /// per key; `None` if they describe the same sweep.
    pub fn difference(&self, current: &Record) -> Option<String> {
        let mut keys: Vec<&str> = Vec::new();
        for (k, _) in self.entries.iter().chain(&current.entries) {
            if !keys.contains(&k.as_str()) && !INFORMATIONAL.contains(&k.as_str()) {
                keys.push(k);
            }
        }
        let values =
            |r: &Record, key: &str| -> Vec<String> { r.entries.iter().filter(|(k, _)| k == key).map(|(_, v)| v.clone()).collect() };
        let shown = |v: Vec<String>| if v.is_empty() { "nothing".to_owned() } else { v.join("; ") };
        let lines: Vec<String> = keys
            .into_iter()
            .filter(|k| values(self, k) != values(current, k))
            .map(|k| format!("  {k}: the partial file's sweep has {}, this one {}", shown(values(self, k)), shown(values(current, k))))
            .collect();
        (!lines.is_empty()).then(|| lines.join("\n"))
    }
}

/// The state shared with the thread that flushes and syncs.
struct Shared {
    /// `None` after [`PartialCsv::finish`] or a failure.
    file: Option<File>,
    /// Complete rows not yet written, and how many.
    pending: Vec<u8>,
    pending_rows: usize,
    /// Bytes on file, all of them complete rows: after a failed write the file is cut back here.
    written: u64,
    /// Rows on file, the header included.
    rows_written: usize,
    /// Written since the last fsync.
    unsynced: bool,
    /// The first write or sync failure.
    error: Option<String>,
    closing: bool,
}

/// `<out>.partial` being appended to.
pub struct PartialCsv {
    path: PathBuf,
    dest: PathBuf,
    shared: Arc<(Mutex<Shared>, Condvar)>,
    flusher: Option<JoinHandle<()>>,
}

fn io_error(path: &Path, e: &std::io::Error) -> String {
    format!("cannot write {}: {e}", path.display())
}

/// One CSV row's bytes, exactly as a CSV writer spells them in a whole file.
fn csv_line(row: &csv::StringRecord) -> Result<Vec<u8>, String> {
    let mut writer = csv::WriterBuilder::new().from_writer(Vec::new());
    writer.write_record(row).map_err(|e| format!("cannot format a CSV row: {e}"))?;
    writer.into_inner().map_err(|e| format!("cannot format a CSV row: {}", e.error()))
}

impl PartialCsv {
    /// Starts `<dest>.partial` afresh with `header` (replacing any file of that name).
    pub fn create(dest: &Path, header: &[String]) -> Result<PartialCsv, String> {
        let path = partial_path(dest);
        let file = File::create(&path).map_err(|e| format!("cannot create {}: {e}", path.display()))?;
        let mut partial = PartialCsv::start(dest, path, file, 0, 0);
        partial.append(header)?;
        // The header goes to the file at once: a file killed before its first flush is empty.
        let (lock, _) = &*partial.shared;
        if let Ok(mut shared) = lock.lock() {
            write_pending(&mut shared, &partial.path);
            if let Some(e) = &shared.error {
                return Err(e.clone());
            }
        }
        Ok(partial)
    }

    /// Continues `<dest>.partial`, whose first `valid` bytes are the header and `rows` complete
    /// rows (a torn row after them is cut off).
    pub fn resume(dest: &Path, valid: u64, rows: usize) -> Result<PartialCsv, String> {
        let path = partial_path(dest);
        let mut file = OpenOptions::new().write(true).open(&path).map_err(|e| format!("cannot open {}: {e}", path.display()))?;
        file.set_len(valid).and_then(|_| file.seek(SeekFrom::Start(valid))).map_err(|e| io_error(&path, &e))?;
        Ok(PartialCsv::start(dest, path, file, valid, rows + 1))
    }

    fn start(dest: &Path, path: PathBuf, file: File, written: u64, rows_written: usize) -> PartialCsv {
        let shared = Arc::new((
            Mutex::new(Shared {
                file: Some(file),
                pending: Vec::new(),
                pending_rows: 0,
                written,
                rows_written,
                unsynced: false,
                error: None,
                closing: false,
            }),
            Condvar::new(),
        ));
        let flusher = {
            let shared = Arc::clone(&shared);
            let path = path.clone();
            std::thread::spawn(move || flush_loop(&shared, &path))
        };
        PartialCsv { path, dest: dest.to_path_buf(), shared, flusher: Some(flusher) }
    }

    /// The partial file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Point rows on file (those a failed write did not reach are not counted).
    pub fn rows_on_file(&self) -> usize {
        self.shared.0.lock().map_or(0, |s| s.rows_written.saturating_sub(1))
    }

    /// Appends one row; fails with the first write error (the rows before it stay intact).
    pub fn append(&mut self, row: &[String]) -> Result<(), String> {
        let mut line = csv_line(&csv::StringRecord::from(row))?;
        let (lock, wake) = &*self.shared;
        let mut shared = lock.lock().map_err(|_| "the partial file's writer panicked".to_owned())?;
        if let Some(e) = &shared.error {
            return Err(e.clone());
        }
        shared.pending.append(&mut line);
        shared.pending_rows += 1;
        if shared.pending.len() >= BATCH_BYTES {
            write_pending(&mut shared, &self.path);
            if let Some(e) = &shared.error {
                return Err(e.clone());
            }
        }
        wake.notify_one();
        Ok(())
    }

    /// Writes and syncs every row given so far and stops the flushing thread; the partial file
    /// stays (an interrupted or failed sweep). Returns the point rows on file, or the first write
    /// error.
    pub fn close(mut self) -> Result<usize, String> {
        self.stop()?;
        Ok(self.rows_on_file())
    }

    /// Stops the flushing thread and writes the pending rows; `wait` makes them durable (fsync),
    /// else their write-back is only started.
    fn stop_with(&mut self, wait: bool) -> Result<(), String> {
        let (lock, wake) = &*self.shared;
        if let Ok(mut shared) = lock.lock() {
            shared.closing = true;
        }
        wake.notify_one();
        if let Some(t) = self.flusher.take() {
            let _ = t.join();
        }
        let mut shared = lock.lock().map_err(|_| "the partial file's writer panicked".to_owned())?;
        write_pending(&mut shared, &self.path);
        if shared.error.is_none() {
            if let Some(file) = &shared.file {
                if wait {
                    if let Err(e) = file.sync_data() {
                        shared.error = Some(io_error(&self.path, &e));
                    }
                } else {
                    use std::os::fd::AsRawFd;
                    // SAFETY: a hint to the kernel on our open descriptor, over the whole file.
                    unsafe { libc::sync_file_range(file.as_raw_fd(), 0, 0, libc::SYNC_FILE_RANGE_WRITE) };
                }
            }
        }
        shared.file = None;
        shared.error.clone().map_or(Ok(()), Err)
    }

    fn stop(&mut self) -> Result<(), String> {
        self.stop_with(true)
    }

    /// Writes the rest, starts its write-back and renames the partial file to the destination.
    pub fn finish(mut self) -> Result<(), String> {
        self.stop_with(false)?;
        std::fs::rename(&self.path, &self.dest)
            .map_err(|e| format!("cannot rename the finished {} to {}: {e}", self.path.display(), self.dest.display()))
    }
}

impl Drop for PartialCsv {
    fn drop(&mut self) {
        if self.flusher.is_some() {
            let _ = self.stop();
        }
    }
}

/// Writes the pending rows; on failure cuts the file back to its complete rows and keeps the
/// error for the next [`PartialCsv::append`].
fn write_pending(shared: &mut Shared, path: &Path) {
    if shared.pending.is_empty() || shared.error.is_some() {
        return;
    }
    let Some(file) = shared.file.as_mut() else { return };
    match file.write_all(&shared.pending) {
        Ok(()) => {
            shared.written += shared.pending.len() as u64;
            shared.rows_written += shared.pending_rows;
            shared.pending.clear();
            shared.pending_rows = 0;
            shared.unsynced = true;
        }
        Err(e) => {
            // A row written in part must not look like a finished one.
            let _ = file.set_len(shared.written);
            shared.error = Some(io_error(path, &e));
        }
    }
}

fn flush_loop(shared: &(Mutex<Shared>, Condvar), path: &Path) {
    let (lock, wake) = shared;
    let mut last_sync = Instant::now();
    let Ok(mut state) = lock.lock() else { return };
    loop {
        if state.closing || state.file.is_none() {
            return;
        }
        // Sleep until rows arrive (or a sync is due), then give them a moment to gather.
        let timeout = if state.pending.is_empty() && !state.unsynced { SYNC_EVERY } else { FLUSH_EVERY };
        state = match wake.wait_timeout(state, timeout) {
            Ok((s, _)) => s,
            Err(_) => return,
        };
        write_pending(&mut state, path);
        if state.unsynced && last_sync.elapsed() >= SYNC_EVERY {
            // fsync on a second handle, without holding the lock for its milliseconds.
            let handle = state.file.as_ref().and_then(|f| f.try_clone().ok());
            state.unsynced = false;
            drop(state);
            if let Some(handle) = handle {
                let _ = handle.sync_data();
            }
            last_sync = Instant::now();
            state = match lock.lock() {
                Ok(s) => s,
                Err(_) => return,
            };
        }
    }
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
    let mut finished = Finished { rows: 0, valid: 0, metrics: Vec::new(), failed: 0 };
    let mut start = 0usize;
    let params = header.len() - metrics - 1;
    // The header is the file's first write: a file that holds only part of it was killed before
    // any row was there, and starting it again loses nothing.
    let header_line = csv_line(&csv::StringRecord::from(header.to_vec()))?;
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
            finished.failed += usize::from(failed(fields[params + metrics]));
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
    fn rows_are_read_back_and_a_torn_last_row_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("s.csv");
        let mut partial = PartialCsv::create(&dest, &header()).unwrap();
        partial.append(&["0.0".into(), "1.5".into(), "ok".into()]).unwrap();
        partial.append(&["1.0".into(), "".into(), "crashed: SIGSEGV, \"quoted\"\nin fmi2DoStep".into()]).unwrap();
        partial.close().unwrap();
        let path = partial_path(&dest);
        let whole = std::fs::read(&path).unwrap();
        let read = read_finished(&path, &header(), 1, &mut points).unwrap();
        assert_eq!((read.rows, read.failed, read.valid), (2, 1, whole.len() as u64));
        assert_eq!(read.metrics[0], 1.5);
        assert!(read.metrics[1].is_nan());
        // Cut inside the quoted status, and cut inside the first row: each torn row is dropped.
        for cut in [whole.len() - 5, whole.len() - 20, 12] {
            std::fs::write(&path, &whole[..cut]).unwrap();
            let read = read_finished(&path, &header(), 1, &mut points).unwrap();
            assert!(read.rows < 2 && (read.valid as usize) < cut, "cut at {cut}: {} rows", read.rows);
            let mut again = PartialCsv::resume(&dest, read.valid, read.rows).unwrap();
            again.append(&["1.0".into(), "".into(), "crashed: SIGSEGV, \"quoted\"\nin fmi2DoStep".into()]).unwrap();
            if read.rows == 0 {
                continue;
            }
            again.finish().unwrap();
            assert_eq!(std::fs::read(&dest).unwrap(), whole, "resumed from {cut} bytes, the file is whole again");
        }
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

    /// The Python package's record (JSON after its own first line) is named as such, not
    /// refused for its first line that is not KEY = VALUE.
    #[test]
    fn a_record_of_the_python_package_is_named() {
        let text =
            "# fmurunner sweep: what produced the CSV beside this file; sweep(..., resume=True) checks it\n{\n \"fmu\": \"a.fmu\"\n}\n";
        let err = Record::parse(text).unwrap_err();
        assert!(err.contains("fmurunner") && err.contains("resume=True"), "{err}");
    }

    #[test]
    fn records_name_what_differs() {
        let record = |fmu: &str, hash: &str, params: &[&str]| Record {
            entries: [("fmu", fmu), ("fmu_sha256", hash)]
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .chain(params.iter().map(|p| ("param".to_owned(), p.to_string())))
                .collect(),
        };
        let a = record("a.fmu", "00", &["k: 3 values"]);
        assert_eq!(Record::parse(&a.text()).unwrap(), a);
        assert_eq!(a.difference(&record("moved/a.fmu", "00", &["k: 3 values"])), None, "the path alone is not the FMU");
        let diff = a.difference(&record("a.fmu", "11", &["k: 3 values", "x: 2 values"])).unwrap();
        assert!(diff.contains("fmu_sha256: the partial file's sweep has 00, this one 11"), "{diff}");
        assert!(diff.contains("param: the partial file's sweep has k: 3 values, this one k: 3 values; x: 2 values"), "{diff}");
    }
}
