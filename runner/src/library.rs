//! A shared library opened with `dlopen`, closed when dropped.

use std::ffi::{c_void, CStr, CString};
use std::path::Path;

/// An open shared library.
pub struct Library {
    handle: *mut c_void,
}

// SAFETY: dlopen handles may be used from any thread; dlsym is thread-safe.
unsafe impl Send for Library {}
unsafe impl Sync for Library {}

fn dlerror_message() -> String {
    // SAFETY: dlerror returns NULL or a NUL-terminated string owned by libc.
    unsafe {
        let e = libc::dlerror();
        if e.is_null() {
            "unknown dlopen error".to_owned()
        } else {
            CStr::from_ptr(e).to_string_lossy().into_owned()
        }
    }
}

impl Library {
    /// Opens `path` with all symbols resolved now and kept local to this library.
    pub fn open(path: &Path) -> Result<Library, String> {
        let c_path = CString::new(path.as_os_str().as_encoded_bytes()).map_err(|_| format!("{}: path contains a NUL byte", path.display()))?;
        // SAFETY: c_path is a valid C string; RTLD_LOCAL keeps two FMUs' fmi2* symbols apart.
        let handle = unsafe { libc::dlopen(c_path.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL) };
        if handle.is_null() {
            return Err(format!("cannot load {}: {}", path.display(), dlerror_message()));
        }
        Ok(Library { handle })
    }

    /// The address of symbol `name`, or an error naming it.
    pub fn symbol(&self, name: &str) -> Result<*mut c_void, String> {
        let c_name = CString::new(name).map_err(|_| format!("symbol name {name:?} contains a NUL byte"))?;
        // SAFETY: handle is open; c_name is a valid C string.
        let p = unsafe { libc::dlsym(self.handle, c_name.as_ptr()) };
        if p.is_null() {
            Err(format!("the binary does not export the function {name}"))
        } else {
            Ok(p)
        }
    }
}

impl Drop for Library {
    fn drop(&mut self) {
        // SAFETY: handle came from dlopen and is closed once.
        unsafe {
            libc::dlclose(self.handle);
        }
    }
}
