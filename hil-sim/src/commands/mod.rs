//! The bodies of `hil-sim`'s commands, callable without the command line: each takes a
//! plain options struct (what its flags say, defaults already filled in by the caller),
//! prints what the command prints (tables and JSON on stdout, progress on stderr), writes
//! its files and returns `Err` with the message when the command fails (the binary exits 1
//! with it). The binary (`src/main.rs`) only parses the arguments and calls these.
//!
//! * [`run`]: `list`, `run` and `pil` (the trace itself: [`crate::trace`]);
//! * [`bench`](mod@bench): the simulation loop's speed;
//! * [`envelope`], [`campaign`], [`faults`]: the drive file's torque–speed envelope, its
//!   nonlinear campaign and its fault-injection matrix;
//! * [`identify`]: self-commissioning in simulation, and the options every commissioning
//!   run takes;
//! * [`link`]: the board's command/telemetry link (`link DEVICE …`).
//!
//! The few things they share live here: the Ctrl-C flag, the progress bar, the bus voltage a
//! drive file's command runs on and the processor-in-the-loop options.

pub mod bench;
pub mod campaign;
pub mod envelope;
pub mod faults;
pub mod identify;
pub mod link;
pub mod run;

use crate::pil::PilOptions;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

/// Set by Ctrl-C (SIGINT, SIGTERM, SIGHUP; [`stop_on_ctrl_c`]): a run in progress stops at
/// its next trace row and cleans up.
pub static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Ctrl-C sets [`INTERRUPTED`]: the run stops at its next check and writes nothing (a
/// second Ctrl-C while it winds down is ignored).
pub fn stop_on_ctrl_c() {
    let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::Relaxed));
}

/// `Err("interrupted")` once Ctrl-C was pressed.
fn interrupted() -> Result<(), String> {
    if INTERRUPTED.load(Ordering::Relaxed) { Err("interrupted".into()) } else { Ok(()) }
}

/// A progress bar for a fraction done, redrawn in place on stderr — only when stderr is a
/// terminal (a log gets nothing).
pub fn progress_bar(fraction: f64) {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return;
    }
    let width = 40;
    let filled = ((fraction.clamp(0.0, 1.0)) * width as f64) as usize;
    eprint!("\r[{}{}] {:3.0}%", "#".repeat(filled), " ".repeat(width - filled), fraction * 100.0);
    if fraction >= 1.0 {
        eprintln!();
    }
}

/// The processor-in-the-loop options of `--elf` and `--no-pin`: the `pil` target program
/// (made absolute: QEMU runs in a temporary directory, where a relative path would be taken
/// relative to it) or the default one, and the simulator pinned to a CPU unless `no_pin`.
pub fn pil_options(elf: Option<&Path>, no_pin: bool) -> Result<PilOptions, String> {
    let mut opts = PilOptions::default();
    if let Some(e) = elf {
        opts.elf = std::path::absolute(e).map_err(|er| format!("--elf {}: {er}", e.display()))?;
    }
    if no_pin {
        opts.pin_cpu = None;
    }
    Ok(opts)
}

/// The bus `faults`, `campaign` and `envelope` run on without `--vdc`, when the drive's
/// range holds it, V.
pub const DEFAULT_VDC_V: f64 = 310.0;

/// The bus a command runs `what` on: `asked` (`--vdc`), refused outside the drive's bus range
/// (`[protection]`: every run would trip on it), else [`DEFAULT_VDC_V`], or the middle of the
/// range when that lies outside it (said on stderr).
pub fn bus_voltage(
    asked: Option<f64>,
    p: &controller_core::drive::Protection,
    what: &str,
) -> Result<f64, String> {
    let inside = |v: f64| v > p.vdc_min_v && v < p.vdc_max_v;
    match asked {
        Some(v) if !inside(v) => Err(format!(
            "--vdc {v} V must lie strictly between the drive's bus trip levels, {} and {} V of [protection]: \
             on or beyond one every run trips (the sensors' noise crosses it)",
            p.vdc_min_v, p.vdc_max_v
        )),
        Some(v) => Ok(v),
        None if inside(DEFAULT_VDC_V) => Ok(DEFAULT_VDC_V),
        None => {
            let v = 0.5 * (p.vdc_min_v + p.vdc_max_v);
            eprintln!(
                "hil-sim: {DEFAULT_VDC_V} V lies outside the drive's bus range ({} … {} V): {what} runs on {v} V (--vdc to choose)",
                p.vdc_min_v, p.vdc_max_v
            );
            Ok(v)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped drive's range holds 310 V; a range that does not gets its middle; a
    /// `--vdc` on a trip level is refused, one inside taken.
    #[test]
    fn the_bus_is_the_default_the_middle_or_the_one_asked() {
        let mut p = drive_file::DriveFile::shipped().unwrap().spec.protection;
        assert_eq!(bus_voltage(None, &p, "test"), Ok(DEFAULT_VDC_V));
        assert_eq!(bus_voltage(Some(300.0), &p, "test"), Ok(300.0));
        let e = bus_voltage(Some(p.vdc_max_v), &p, "test").unwrap_err();
        assert!(e.contains("strictly between"), "{e}");
        (p.vdc_min_v, p.vdc_max_v) = (20.0, 40.0);
        assert_eq!(bus_voltage(None, &p, "test"), Ok(30.0));
    }

    #[test]
    fn a_relative_elf_is_made_absolute() {
        let opts = pil_options(Some(Path::new("some/pil.elf")), true).unwrap();
        assert!(opts.elf.is_absolute() && opts.elf.ends_with("some/pil.elf"));
        assert_eq!(opts.pin_cpu, None);
    }
}
