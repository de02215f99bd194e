//! Compiles `src/logger.c`, the variadic FMI 1.0 and 2.0 logger callbacks that stable Rust cannot define,
//! when the `logger-shim` feature asks for it.

fn main() {
    println!("cargo:rerun-if-changed=src/logger.c");
    if std::env::var_os("CARGO_FEATURE_LOGGER_SHIM").is_some() {
        cc::Build::new().file("src/logger.c").warnings(true).compile("fmi_c_logger");
    }
}
