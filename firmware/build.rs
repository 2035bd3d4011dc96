//! With the `board` feature, puts the workspace's single `memory.x` on the linker search
//! path and, for the board target, links defmt's section script. Generates `config.rs` from the workspace's drive file
//! (`drive.toml`, read by the `drive-file` crate — the one source of every constant): the
//! drive specification, the board constants and the certified ranges of the gains writable
//! over the link. A bad drive file stops the build with its `file:line:column: key: reason`.
//! `FIRMWARE_DRIVE_FILE=<path>` builds from another drive file (e.g. one `design tune` wrote;
//! a relative path is taken from the workspace root).
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    // The board's memory map only for the board's binary: a search path set here reaches
    // every program linked with this crate (`qemu-target`'s, on QEMU's own maps).
    let board = env::var_os("CARGO_FEATURE_BOARD").is_some();
    if board {
        let src = root.join("memory.x");
        if let Err(e) = fs::copy(&src, out.join("memory.x")) {
            println!("cargo::warning=cannot copy {}: {e}", src.display());
        }
        println!("cargo::rustc-link-search={}", out.display());
        println!("cargo::rerun-if-changed={}", src.display());
    }
    println!("cargo::rerun-if-env-changed=FIRMWARE_DRIVE_FILE");
    let name = env::var("FIRMWARE_DRIVE_FILE").unwrap_or_else(|_| "drive.toml".into());
    let drive = root.join(&name);
    println!("cargo::rerun-if-changed={}", drive.display());
    let code = drive_file::DriveFile::load(&drive)
        .map_err(|e| e.to_string())
        .and_then(|d| modes_built(&d, &name).map(|()| d))
        .and_then(|d| drive_file::codegen::firmware_rs(&d, &name));
    match code {
        Ok(code) => {
            if let Err(e) = fs::write(out.join("config.rs"), code) {
                println!("cargo::error=cannot write config.rs: {e}");
            }
        }
        Err(e) => println!("cargo::error={e}"),
    }
    if board && env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none") {
        println!("cargo::rustc-link-arg-bins=-Tdefmt.x");
    }
}

/// The image carries only the control modes its drive runs (controller-core's features,
/// docs/firmware.md): a drive that asks for one the build leaves out stops the build, naming
/// the feature — the firmware would otherwise refuse its own configuration at power-up.
fn modes_built(d: &drive_file::DriveFile, name: &str) -> Result<(), String> {
    use controller_core::drive::{Control, SpeedFeedback};
    let feature = |f: &str| env::var_os(format!("CARGO_FEATURE_{}", f.to_uppercase())).is_some();
    let needs = [
        (matches!(d.spec.control, Control::VHz { .. }), "vhz", "[controller] control = \"vhz\""),
        (d.spec.speed_feedback != SpeedFeedback::Encoder, "sensorless", "[controller] speed_feedback"),
        (d.spec.magnetizing.is_some(), "saturation", "[motor.saturation]"),
        (d.spec.overmodulation, "overmodulation", "[controller] overmodulation"),
    ];
    match needs.iter().find(|(needed, f, _)| *needed && !feature(f)) {
        Some((_, f, key)) => Err(format!(
            "{name}: {key} needs the firmware built with `--features {f}` (`cargo xtask build-fw --features {f}`)"
        )),
        None => Ok(()),
    }
}
