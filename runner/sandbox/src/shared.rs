//! The memory a worker shares with its supervisor: a few pages the worker writes as it goes (the
//! FMI call it is in and the model time, recorded by the importer; a validator's probe records
//! more) and the supervisor reads after the worker died or was killed. Writing it costs no
//! system call, so a run of a million steps records every call.
//!
//! What is in it is the client's: the sandbox creates it zeroed, maps it on both sides and hands
//! out views of a type the client lays over it ([`SharedMemory::view`]).

use std::os::fd::RawFd;

/// A memory region shared between a supervisor and one worker (a `memfd`, mapped in both).
pub struct SharedMemory {
    fd: RawFd,
    base: *mut libc::c_void,
    len: usize,
}

// Only touched through views of atomics (see `view`), so it may be shared between threads.
unsafe impl Send for SharedMemory {}
unsafe impl Sync for SharedMemory {}

impl std::fmt::Debug for SharedMemory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SharedMemory({} bytes)", self.len)
    }
}

/// The page size the region is a multiple of.
const PAGE: usize = 4096;

impl SharedMemory {
    /// A zeroed region of at least `len` bytes (whole pages), to hand to a worker.
    pub fn new(len: usize) -> Result<SharedMemory, String> {
        let len = len.max(1).div_ceil(PAGE) * PAGE;
        let error = |what: &str| format!("cannot create the memory shared with a worker ({what}): {}", std::io::Error::last_os_error());
        // SAFETY: plain system calls; the mapping is checked before use and unmapped on drop.
        unsafe {
            let fd = libc::memfd_create(c"runner-sandbox".as_ptr(), libc::MFD_CLOEXEC);
            if fd < 0 {
                return Err(error("memfd_create"));
            }
            if libc::ftruncate(fd, len as libc::off_t) != 0 {
                libc::close(fd);
                return Err(error("ftruncate"));
            }
            match map(fd, len) {
                Ok(base) => Ok(SharedMemory { fd, base, len }),
                Err(e) => {
                    libc::close(fd);
                    Err(e)
                }
            }
        }
    }

    /// Maps the region a supervisor passed as descriptor `fd` (in a worker). The descriptor is
    /// closed: the mapping outlives it.
    pub(crate) fn inherit(fd: RawFd) -> Result<SharedMemory, String> {
        // SAFETY: fstat fills a zeroed struct; mapping a descriptor of at least that size.
        unsafe {
            let mut stat: libc::stat = std::mem::zeroed();
            if libc::fstat(fd, &mut stat) != 0 {
                return Err(format!(
                    "no shared memory at descriptor {fd} (only a supervisor starts a worker): {}",
                    std::io::Error::last_os_error()
                ));
            }
            let len = stat.st_size as usize;
            let base = map(fd, len)?;
            libc::close(fd);
            Ok(SharedMemory { fd: -1, base, len })
        }
    }

    /// The descriptor a worker inherits.
    pub(crate) fn fd(&self) -> RawFd {
        self.fd
    }

    /// Its size in bytes.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True for a region of no bytes (never: a region has a page at least).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The region seen as a `T` laid over its first bytes.
    ///
    /// # Safety
    /// `T` must fit in the region, need no more than page alignment, be valid for any bytes
    /// (all zero at first) and be shared between processes safely: atomics only, or bytes one
    /// side writes only while the other does not read them.
    pub unsafe fn view<T: Sync>(&self) -> &T {
        assert!(std::mem::size_of::<T>() <= self.len && std::mem::align_of::<T>() <= PAGE, "a view larger than the shared memory");
        &*(self.base as *const T)
    }

    /// The region's first address, for views of several records.
    pub fn as_ptr(&self) -> *mut u8 {
        self.base as *mut u8
    }
}

/// Maps `len` bytes of `fd`, shared and writable.
unsafe fn map(fd: RawFd, len: usize) -> Result<*mut libc::c_void, String> {
    let base = libc::mmap(std::ptr::null_mut(), len, libc::PROT_READ | libc::PROT_WRITE, libc::MAP_SHARED, fd, 0);
    if base == libc::MAP_FAILED {
        return Err(format!("cannot map the memory shared with a worker: {}", std::io::Error::last_os_error()));
    }
    Ok(base)
}

impl Drop for SharedMemory {
    fn drop(&mut self) {
        // SAFETY: the mapping and the descriptor are ours.
        unsafe {
            libc::munmap(self.base, self.len);
            if self.fd >= 0 {
                libc::close(self.fd);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU64, Ordering};

    /// What one mapping writes, another of the same descriptor reads: as a worker's writes
    /// reach its supervisor.
    #[test]
    fn a_view_written_through_one_mapping_is_read_through_another() {
        let region = SharedMemory::new(10).unwrap();
        assert_eq!(region.len(), PAGE, "whole pages");
        // SAFETY: dup of our own descriptor, then a second mapping of it.
        let other = SharedMemory::inherit(unsafe { libc::dup(region.fd()) }).unwrap();
        let (a, b) = unsafe { (region.view::<[AtomicU64; 2]>(), other.view::<[AtomicU64; 2]>()) };
        assert_eq!(b[1].load(Ordering::Relaxed), 0, "zeroed");
        a[1].store(0x0123_4567_89ab_cdef, Ordering::Relaxed);
        assert_eq!(b[1].load(Ordering::Relaxed), 0x0123_4567_89ab_cdef);
        assert!(SharedMemory::inherit(-1).unwrap_err().contains("only a supervisor starts a worker"));
    }
}
