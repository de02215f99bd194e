//! Compiles `src/logger.c`, the variadic FMI logger callback that stable Rust cannot define.

fn main() {
    println!("cargo:rerun-if-changed=src/logger.c");
    cc::Build::new().file("src/logger.c").warnings(true).compile("runner_logger");
}
