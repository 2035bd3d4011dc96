//! Memory map of the *emulated* boards (not the STM32: that one is the root `memory.x`,
//! used by the firmware). QEMU's mps2-an386 (Cortex-M4F) has 4 MiB of code SRAM at 0 and
//! 4 MiB of data SRAM at 0x2000_0000; lm3s6965evb (Cortex-M3) has 256 KiB flash and 64 KiB
//! SRAM. Written to OUT_DIR for cortex-m-rt's `link.x`. Also generates `drive.rs` from the
//! workspace's `drive.toml` (the firmware's drive, `drive_file::codegen`): the drive the
//! self-tests and the instruction count run.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    let target = env::var("TARGET").unwrap_or_default();
    let memory = if target.starts_with("thumbv7m-") {
        "MEMORY\n{\n  FLASH : ORIGIN = 0x00000000, LENGTH = 256K\n  RAM : ORIGIN = 0x20000000, LENGTH = 64K\n}\n"
    } else {
        "MEMORY\n{\n  FLASH : ORIGIN = 0x00000000, LENGTH = 4M\n  RAM : ORIGIN = 0x20000000, LENGTH = 4M\n}\n"
    };
    if let Err(e) = fs::write(out.join("memory.x"), memory) {
        println!("cargo::error=cannot write memory.x: {e}");
    }
    println!("cargo::rustc-link-search={}", out.display());
    // The on-target tests log through defmt (tests/selftest.rs).
    if target.starts_with("thumb") {
        println!("cargo::rustc-link-arg-tests=-Tdefmt.x");
    }
    let drive = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join("drive.toml");
    println!("cargo::rerun-if-changed={}", drive.display());
    match drive_file::DriveFile::load(&drive) {
        Ok(d) => {
            if let Err(e) =
                fs::write(out.join("drive.rs"), drive_file::codegen::spec_rs(&d.spec, "drive.toml"))
            {
                println!("cargo::error=cannot write drive.rs: {e}");
            }
        }
        Err(e) => println!("cargo::error={e}"),
    }
    println!("cargo::rerun-if-changed=build.rs");
}
