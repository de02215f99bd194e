//! The one table of each FMI version's functions ([`crate::fmi2::Functions`],
//! [`crate::fmi3::Functions`]): every function of the standard, resolved once from a loaded
//! binary, each `None` where the binary does not export it. A validator reads the whole table
//! (which functions are missing is a finding); an importer takes a [`view!`] of it, the
//! functions it calls checked present once, so that each call is a plain call through a
//! function pointer.

#[cfg(feature = "symbols")]
use std::ffi::{c_void, CStr};
#[cfg(feature = "symbols")]
use std::path::Path;

#[cfg(feature = "symbols")]
use libloading::os::unix::{Library as Unix, RTLD_LOCAL, RTLD_NOW};

/// A shared library opened for its FMI functions. Closing it (dropping) unloads the binary:
/// every function taken from its table must be dead by then. A resident one
/// ([`Library::open_resident`]) is never unloaded.
#[cfg(feature = "symbols")]
pub struct Library {
    inner: std::mem::ManuallyDrop<Unix>,
    resident: bool,
}

#[cfg(feature = "symbols")]
impl Drop for Library {
    fn drop(&mut self) {
        if !self.resident {
            // SAFETY: dropped once, here; `inner` is not used after.
            unsafe { std::mem::ManuallyDrop::drop(&mut self.inner) }
        }
    }
}

#[cfg(feature = "symbols")]
impl Library {
    /// Opens the shared library at `path` with every symbol bound at once (`RTLD_NOW`) and kept
    /// to itself (`RTLD_LOCAL`: two FMUs' `fmi2DoStep` never get mixed up).
    ///
    /// # Safety
    /// Opening runs the library's initializers: arbitrary code of whoever built it. That is the
    /// price of running any FMU; run untrusted ones in a worker process.
    pub unsafe fn open(path: &Path) -> Result<Library, String> {
        Self::open_as(path, false)
    }

    /// [`Library::open`], but the library stays loaded until the process ends, dropped or not:
    /// for a process that ends after its runs, so that the FMU's code is still there when the
    /// process exits (exit handlers it registered for the whole process, threads of libraries
    /// it brought, as a PythonFMU's libpython and numpy do).
    ///
    /// # Safety
    /// As [`Library::open`].
    pub unsafe fn open_resident(path: &Path) -> Result<Library, String> {
        Self::open_as(path, true)
    }

    unsafe fn open_as(path: &Path, resident: bool) -> Result<Library, String> {
        Unix::open(Some(path), RTLD_NOW | RTLD_LOCAL)
            .map(|inner| Library { inner: std::mem::ManuallyDrop::new(inner), resident })
            .map_err(|e| format!("cannot load {}: {e}", path.display()))
    }

    /// The function `name` (NUL-terminated) as the C signature `F`, `None` when not exported.
    ///
    /// # Safety
    /// `F` must be the function pointer type the standard gives the function `name`.
    pub unsafe fn function<F: Copy>(&self, name: &str) -> Option<F> {
        self.inner.get::<F>(name.as_bytes()).ok().map(|symbol| *symbol)
    }

    /// Whether the library exports a symbol called `name`, whatever it is (for names outside
    /// the standard's tables).
    pub fn exports(&self, name: &CStr) -> bool {
        // SAFETY: only the address is looked up, never used.
        unsafe { self.inner.get::<*mut c_void>(name.to_bytes_with_nul()).is_ok() }
    }
}

/// Declares a version's function table: per group (as the version's header lists them) a
/// constant array of the names, and one [`Functions`]-style struct of every function.
macro_rules! functions {
    ($(
        $(#[$group_doc:meta])*
        $group:ident {
            $( $field:ident: $ty:ident = $name:literal, )*
        }
    )*) => {
        $(
            $(#[$group_doc])*
            pub const $group: [&str; { let names: &[&str] = &[$($name),*]; names.len() }] = [$($name),*];
        )*

        /// Every function of this version: the pointer the loaded binary exports under the
        /// standard's name, `None` where it exports none. Resolved once per binary
        /// ([`Functions::resolve`]).
        #[cfg(feature = "symbols")]
        #[derive(Clone, Copy)]
        pub struct Functions {
            $($(
                #[doc = concat!("`", $name, "`.")]
                pub $field: Option<$ty>,
            )*)*
        }

        /// The C name of every function of [`Functions`], by the same field.
        #[cfg(feature = "symbols")]
        pub struct Names {
            $($(
                #[doc = concat!("`", $name, "`.")]
                pub $field: &'static str,
            )*)*
        }

        #[cfg(feature = "symbols")]
        impl Functions {
            /// The C name of every function.
            pub const NAMES: Names = Names { $($( $field: $name, )*)* };

            /// The table of a binary that exports none of them (what a check of a view's
            /// functions refuses, in tests).
            pub const MISSING: Functions = Functions { $($( $field: None, )*)* };

            /// Looks every function up in `library`.
            pub fn resolve(library: &$crate::functions::Library) -> Functions {
                // SAFETY: each name is a function of this version whose C signature the
                // standard fixes as the type of its field.
                unsafe { Functions { $($( $field: library.function::<$ty>(concat!($name, "\0")), )*)* } }
            }

            /// Looks every function up in `library` under `<prefix>_<name>`, as FMI 1.0 names
            /// them after the modelIdentifier.
            pub fn resolve_prefixed(library: &$crate::functions::Library, prefix: &str) -> Functions {
                // SAFETY: as for `resolve`, under the prefixed name.
                unsafe { Functions { $($( $field: library.function::<$ty>(&format!("{prefix}_{}\0", $name)), )*)* } }
            }

            /// Whether the binary exports the function of this version called `name` (false
            /// for a name that is not one).
            pub fn exports(&self, name: &str) -> bool {
                match name {
                    $($( $name => self.$field.is_some(), )*)*
                    _ => false,
                }
            }
        }
    };
}

pub(crate) use functions;

/// Declares a view of a function table: the functions one user of the table calls, each taken
/// from it once and checked present, so that a call is a plain call through a function pointer
/// (no test of an `Option` in a simulation's inner loop). The fields are the table's, with its
/// types; `take` names the first one the binary does not export.
///
/// ```
/// # #[cfg(feature = "symbols")] {
/// use fmi_c::fmi2 as c;
/// fmi_c::view! {
///     /// What a minimal Co-Simulation master calls.
///     struct Stepping from c::Functions {
///         do_step: c::DoStep,
///         get_real: c::GetReal,
///     }
/// }
/// assert_eq!(Stepping::take(&c::Functions::MISSING).err(), Some("fmi2DoStep"));
/// # }
/// ```
#[macro_export]
macro_rules! view {
    (
        $(#[$meta:meta])*
        $vis:vis struct $view:ident from $table:ty {
            $( $field:ident: $ty:ty, )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy)]
        $vis struct $view {
            $( pub(crate) $field: $ty, )*
        }

        impl $view {
            /// The view's functions from `functions`; `Err` is the C name of the first one the
            /// binary does not export.
            #[allow(dead_code)]
            $vis fn take(functions: &$table) -> ::core::result::Result<$view, &'static str> {
                ::core::result::Result::Ok($view {
                    $(
                        $field: match functions.$field {
                            ::core::option::Option::Some(function) => function,
                            ::core::option::Option::None => return ::core::result::Result::Err(<$table>::NAMES.$field),
                        },
                    )*
                })
            }
        }
    };
}
