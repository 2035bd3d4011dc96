//! Puts the workspace's single `memory.x` on the linker search path; for the board target
//! also links defmt's section script.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join("memory.x");
    if let Err(e) = fs::copy(&src, out.join("memory.x")) {
        println!("cargo::warning=cannot copy {}: {e}", src.display());
    }
    println!("cargo::rustc-link-search={}", out.display());
    println!("cargo::rerun-if-changed={}", src.display());
    if env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none") {
        println!("cargo::rustc-link-arg-bins=-Tdefmt.x");
    }
}
