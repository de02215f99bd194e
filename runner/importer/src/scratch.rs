//! Where an FMU is unpacked. On a disk file system writing the binary, and deleting it again,
//! costs journal work and (mounted with `discard`) a discard per freed extent: most of the time a
//! short sweep or `runner info` spends outside the FMU. With no TMPDIR chosen and a temporary
//! directory on disk, an FMU is unpacked into memory (`/dev/shm`) instead, when that is a tmpfs
//! the runner may write to and run code from, with room to spare.

use std::ffi::CString;
use std::path::{Path, PathBuf};

/// The prefix of every unpacked FMU's directory.
pub const PREFIX: &str = "runner-fmu-";

/// The in-memory file system tried when the temporary directory is on disk.
const MEMORY: &str = "/dev/shm";

/// Room left over on the in-memory file system after unpacking, besides as much again as the
/// FMU needs: the machine's memory is shared with what runs there.
const SPARE: u64 = 256 << 20;

/// True if `dir` is on a tmpfs.
fn on_tmpfs(dir: &Path) -> bool {
    const TMPFS_MAGIC: i64 = 0x0102_1994;
    let Ok(c) = CString::new(dir.as_os_str().as_encoded_bytes()) else { return false };
    // SAFETY: statfs fills the zeroed struct it is given for a NUL-terminated path.
    unsafe {
        let mut fs: libc::statfs = std::mem::zeroed();
        libc::statfs(c.as_ptr(), &mut fs) == 0 && fs.f_type as i64 == TMPFS_MAGIC
    }
}

/// True if `dir` is a tmpfs mounted writable and executable, that this process may write to,
/// with room for `bytes` twice over and [`SPARE`].
fn usable_memory_dir(dir: &Path, bytes: u64) -> bool {
    let Ok(c) = CString::new(dir.as_os_str().as_encoded_bytes()) else { return false };
    if !on_tmpfs(dir) {
        return false;
    }
    // SAFETY: statvfs fills the zeroed struct it is given; access only reads the path.
    unsafe {
        let mut vfs: libc::statvfs = std::mem::zeroed();
        if libc::statvfs(c.as_ptr(), &mut vfs) != 0 || libc::access(c.as_ptr(), libc::W_OK | libc::X_OK) != 0 {
            return false;
        }
        // A binary on a noexec mount cannot be loaded.
        if vfs.f_flag & (libc::ST_NOEXEC | libc::ST_RDONLY) != 0 {
            return false;
        }
        let free = (vfs.f_bavail as u64).saturating_mul(vfs.f_frsize as u64);
        free >= bytes.saturating_mul(2).saturating_add(SPARE)
    }
}

/// The directory to unpack an FMU of `bytes` (all its files together) in: the temporary
/// directory when TMPDIR names one or it is in memory already, else `MEMORY` when usable.
pub fn parent_for(bytes: u64) -> PathBuf {
    let temp = std::env::temp_dir();
    let chosen = std::env::var_os("TMPDIR").is_some_and(|t| !t.is_empty());
    if chosen || on_tmpfs(&temp) || !usable_memory_dir(Path::new(MEMORY), bytes) {
        temp
    } else {
        PathBuf::from(MEMORY)
    }
}

/// The prefix of this process's directories: `runner-fmu-<pid namespace>-<pid>-`, so that a
/// later runner can tell a directory whose process is gone (see [`remove_stale`]).
fn own_prefix() -> String {
    format!("{PREFIX}{}-{}-", pid_namespace(), std::process::id())
}

/// The inode of this process's pid namespace (0 if unknown): pids mean something only within
/// one namespace, and containers may share a /dev/shm.
fn pid_namespace() -> u64 {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata("/proc/self/ns/pid").map_or(0, |m| m.ino())
}

/// True unless no process `pid` exists (in this pid namespace).
fn alive(pid: i32) -> bool {
    // SAFETY: signal 0 only checks that the process exists and may be signalled.
    unsafe { libc::kill(pid, 0) == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH) }
}

/// Removes from `parent` the unpacked FMUs that runners of this user and pid namespace left
/// when they were killed before they could remove them (SIGKILL, a crash): in the in-memory
/// file system they would hold memory until the next reboot. A directory is only removed when
/// its process no longer exists; a pid reused since keeps it (harmless, and rare).
fn remove_stale(parent: &Path) {
    use std::os::unix::fs::MetadataExt;
    let Ok(entries) = std::fs::read_dir(parent) else { return };
    let ours = format!("{PREFIX}{}-", pid_namespace());
    // SAFETY: getuid cannot fail.
    let uid = unsafe { libc::getuid() };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(|n| n.strip_prefix(&ours)).and_then(|rest| rest.split_once('-')) else { continue };
        let Ok(pid) = pid.0.parse::<i32>() else { continue };
        let owned_dir = entry.path().symlink_metadata().is_ok_and(|m| m.is_dir() && m.uid() == uid);
        if pid > 0 && owned_dir && !alive(pid) {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// A new, empty directory to unpack an FMU of `bytes` in (deleted on drop). In the in-memory
/// file system the copies that killed runners left there are removed first.
pub fn unpack_dir(bytes: u64) -> Result<tempfile::TempDir, String> {
    let parent = parent_for(bytes);
    if parent == Path::new(MEMORY) {
        remove_stale(&parent);
    }
    let made = tempfile::Builder::new().prefix(&own_prefix()).tempdir_in(&parent);
    // Should the memory file system refuse after all, the temporary directory still serves.
    let made = match made {
        Err(_) if parent != std::env::temp_dir() => tempfile::Builder::new().prefix(&own_prefix()).tempdir(),
        other => other,
    };
    made.map_err(|e| format!("cannot create a temporary directory: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Directories named for a process that has exited are removed; those of a live process
    /// (this one), of another pid namespace, or not named by a runner are kept. In a directory
    /// of the test's own, so that no other runner's copies are touched.
    #[test]
    fn only_copies_of_processes_that_are_gone_are_removed() {
        let parent = tempfile::tempdir().unwrap();
        let exited = {
            let mut child = std::process::Command::new("true").spawn().unwrap();
            let pid = child.id();
            child.wait().unwrap();
            pid
        };
        let ns = pid_namespace();
        let names = [
            format!("{PREFIX}{ns}-{exited}-abc"),
            format!("{PREFIX}{ns}-{}-abc", std::process::id()),
            format!("{PREFIX}{}-{exited}-abc", ns + 1),
            format!("{PREFIX}{exited}-abc"),
            format!("other-{ns}-{exited}-abc"),
        ];
        for name in &names {
            std::fs::create_dir(parent.path().join(name)).unwrap();
            std::fs::write(parent.path().join(name).join("modelDescription.xml"), "x").unwrap();
        }
        remove_stale(parent.path());
        let left: Vec<bool> = names.iter().map(|n| parent.path().join(n).exists()).collect();
        assert_eq!(left, [false, true, true, true, true], "{names:?}");
        assert!(own_prefix().starts_with(&format!("{PREFIX}{ns}-{}-", std::process::id())));
    }

    #[test]
    fn a_chosen_tmpdir_is_kept_and_a_disk_directory_is_never_taken_for_memory() {
        // This test binary's processes never set TMPDIR themselves, so the rule reads the
        // environment the tests were started with: either way the answer is one of the two.
        let parent = parent_for(1 << 20);
        assert!(parent == std::env::temp_dir() || parent == Path::new(MEMORY), "{}", parent.display());
        if parent == Path::new(MEMORY) {
            assert!(on_tmpfs(&parent) && !on_tmpfs(&std::env::temp_dir()));
        }
        // An FMU larger than any memory file system is unpacked in the temporary directory.
        assert_eq!(parent_for(u64::MAX / 4), std::env::temp_dir());
        // A directory on disk (the crate's own) is no memory file system.
        assert!(!usable_memory_dir(Path::new(env!("CARGO_MANIFEST_DIR")), 0) || on_tmpfs(Path::new(env!("CARGO_MANIFEST_DIR"))));
    }
}
