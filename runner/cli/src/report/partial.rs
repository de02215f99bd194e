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

// What the Python package's sweep to a file shares with this one: the lock, the row check
// `--resume` reads back with, and how a row is spelled.
pub use runner_engine::partial::{csv_line, failed, partial_path, read_finished, record_path, SweepLock, ENDED_EARLY};

/// Rows wait at most this long in memory before they are written to the partial file.
pub const FLUSH_EVERY: Duration = Duration::from_millis(100);
/// Written rows reach the disk (fsync) at most this long after they were written.
pub const SYNC_EVERY: Duration = Duration::from_secs(2);
/// Rows are written at once when this many bytes are waiting.
const BATCH_BYTES: usize = 64 << 10;

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
        // A metric is compared by what it computes, not by how it was typed (`final(x)` and
        // `final( x )` are one metric); the record keeps the text as typed.
        let meant = |r: &Record, key: &str| -> Vec<String> {
            let spelled = |v: String| if key == "metric" { formulas::metrics::canonical_definition(&v).unwrap_or(v) } else { v };
            values(r, key).into_iter().map(spelled).collect()
        };
        let shown = |v: Vec<String>| if v.is_empty() { "nothing".to_owned() } else { v.join("; ") };
        let lines: Vec<String> = keys
            .into_iter()
            .filter(|k| meant(self, k) != meant(current, k))
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
        let mut line = csv_line(row)?;
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

#[cfg(test)]
mod tests {
    use super::*;

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
        assert_eq!(read.statuses, [(1, "crashed: SIGSEGV, \"quoted\"\nin fmi2DoStep".to_owned())], "the failed row's status, as written");
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

    /// A metric typed another way (spaces, `5` for `5.0`) is the same metric; another metric,
    /// or one more, is a difference named with the texts as typed.
    #[test]
    fn records_compare_metrics_by_what_they_compute() {
        let record = |metrics: &[&str]| Record { entries: metrics.iter().map(|m| ("metric".to_owned(), m.to_string())).collect() };
        let typed = record(&["peak=max(z_s, 5)/max(z_r)", "last=final(x)"]);
        assert_eq!(typed.difference(&record(&["peak = max( z_s, 5.0 ) / max(z_r)", "last=final( x )"])), None);
        let diff = typed.difference(&record(&["peak=max(z_s, 6)/max(z_r)", "last=final(x)"])).unwrap();
        assert!(
            diff.contains(
                "metric: the partial file's sweep has peak=max(z_s, 5)/max(z_r); last=final(x), this one peak=max(z_s, 6)/max(z_r)"
            ),
            "{diff}"
        );
        assert!(typed.difference(&record(&["peak=max(z_s, 5)/max(z_r)"])).is_some(), "a metric fewer");
    }
}
