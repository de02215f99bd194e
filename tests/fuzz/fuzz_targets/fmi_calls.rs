//! Fuzzes every model's FMI 2.0 and 3.0 C API with call sequences (see `src/driver.rs` for what
//! a sequence does and what is checked). Built with AddressSanitizer and LeakSanitizer: any
//! read or write outside the caller's buffers, use after free or leak is a crash.

#![no_main]
// FMI 2.0's logger is a variadic C function; only nightly Rust defines one (this crate is
// built with nightly for the sanitizers anyway).
#![feature(c_variadic)]

#[path = "../src/driver.rs"]
mod driver;
#[path = "../src/fmus.rs"]
mod fmus;

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;

static FMUS: OnceLock<Vec<fmus::Fmu>> = OnceLock::new();

extern "C" fn print_counts() {
    eprintln!("fmi_calls: {}", driver::summary());
}

fuzz_target!(
    init: {
        FMUS.get_or_init(fmus::all);
        // libFuzzer ends with exit(): the counters are printed then.
        unsafe { libc::atexit(print_counts) };
    },
    |data: &[u8]| {
        driver::run(FMUS.get().expect("initialized"), data);
    }
);
