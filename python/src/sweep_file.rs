//! A sweep to a file (`fmurunner.sweep(out=...)`, `_files.py`) through the engine's
//! `partial` module, the code `runner sweep --out` uses: the lock on the record, the spelling of
//! a row, and the rows read back on `resume=True`. Each tool writes its own record and spells its
//! numbers its own way; the rules of the file are written once.

use std::borrow::Cow;
use std::path::Path;

use pyo3::prelude::*;
use runner_engine::partial;

use crate::err;

/// `<out>.sweep` held under an exclusive `flock` until [`SweepLock::release`] (or the process
/// ends), as `runner sweep` holds it, so that the two refuse each other.
#[pyclass(module = "fmurunner._engine")]
pub struct SweepLock {
    lock: Option<partial::SweepLock>,
}

#[pymethods]
impl SweepLock {
    /// Locks `out + ".sweep"` (created empty if there is none); `RunnerError` naming the file
    /// if another sweep holds it.
    #[new]
    fn new(out: &str) -> PyResult<SweepLock> {
        partial::SweepLock::acquire(Path::new(out), "resume=True").map(|lock| SweepLock { lock: Some(lock) }).map_err(err)
    }

    /// Whether the record had content when it was locked (an earlier sweep's).
    #[getter]
    fn had_record(&self) -> bool {
        self.lock.as_ref().is_some_and(|lock| lock.had_record)
    }

    /// Replaces the record's text, in the locked file itself.
    fn write_record(&mut self, text: &str) -> PyResult<()> {
        match &mut self.lock {
            Some(lock) => lock.write_record(text).map_err(err),
            None => Err(err("the sweep's record is no longer locked: it was released".to_owned())),
        }
    }

    /// Ends the lock.
    fn release(&mut self) {
        self.lock = None;
    }
}

/// One row's bytes, exactly as the sweep writes it and [`read_finished`] reads it back.
#[pyfunction]
pub fn csv_line(fields: Vec<String>) -> PyResult<Cow<'static, [u8]>> {
    partial::csv_line(&fields).map(Cow::Owned).map_err(err)
}

/// Rows read back as Python receives them: (the bytes they take with the header, the number of
/// rows, their metrics row by row, the (row, status) of those whose status is not `ok`).
type Finished = (u64, usize, Vec<f64>, Vec<(usize, String)>);

/// The finished rows of the sweep file `path` (`runner sweep --resume`'s check: the header, then
/// each row exactly as written for its point, `points[i]` its parameter values as spelled; a last
/// row cut short by a kill dropped).
#[pyfunction]
pub fn read_finished(path: &str, header: Vec<String>, metrics: usize, points: Vec<Vec<String>>) -> PyResult<Finished> {
    if metrics + 1 > header.len() {
        return Err(err(format!("a header of {} columns cannot hold {metrics} metrics and the status", header.len())));
    }
    let mut point = |i: usize| points.get(i).cloned();
    let finished = partial::read_finished(Path::new(path), &header, metrics, &mut point).map_err(err)?;
    Ok((finished.valid, finished.rows, finished.metrics, finished.statuses))
}
