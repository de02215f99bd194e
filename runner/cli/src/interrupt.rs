//! Ctrl-C (SIGINT), and SIGTERM and SIGHUP as a job scheduler or a closed terminal sends them:
//! the first one asks long commands to stop (a sweep keeps its finished points in its
//! `.partial` file, a run its rows so far in `--out`); a second one quits at once, deleting
//! unfinished temporary result files (not a sweep's `.partial`).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, Once};

static REQUESTED: AtomicBool = AtomicBool::new(false);
static SIGNALS: AtomicUsize = AtomicUsize::new(0);
/// Temporary files of result files being written, for the second Ctrl-C to delete.
static PARTIAL: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Exit code of a command stopped by Ctrl-C (128 + SIGINT, as shells report it), or by SIGTERM
/// or SIGHUP (the handler is not told which signal came).
pub const EXIT_CODE: i32 = 130;

/// Installs the handler of Ctrl-C, SIGTERM and SIGHUP (once per process; later calls do
/// nothing).
pub fn install() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let installed = ctrlc::set_handler(|| {
            if SIGNALS.fetch_add(1, Ordering::SeqCst) == 0 {
                REQUESTED.store(true, Ordering::SeqCst);
                eprintln!("\ninterrupted: stopping, keeping what has finished (Ctrl-C again to quit at once)");
            } else {
                for path in PARTIAL.lock().map(|p| p.clone()).unwrap_or_default() {
                    let _ = std::fs::remove_file(path);
                }
                std::process::exit(EXIT_CODE);
            }
        });
        if let Err(e) = installed {
            eprintln!("warning: cannot handle Ctrl-C ({e}); an interrupted command may leave a temporary .partial file");
        }
    });
}

/// True once Ctrl-C was pressed.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}

/// Records a temporary file to delete if the process is killed by a second Ctrl-C.
pub fn register_partial(path: &Path) {
    if let Ok(mut p) = PARTIAL.lock() {
        p.push(path.to_path_buf());
    }
}

/// Forgets a temporary file (committed or deleted).
pub fn unregister_partial(path: &Path) {
    if let Ok(mut p) = PARTIAL.lock() {
        p.retain(|q| q != path);
    }
}
