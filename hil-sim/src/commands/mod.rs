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

/// `--plant NAME|FILE`: the machine a command simulates instead of the drive's own motor (a
/// shipped motor's name or a file with a `[motor]` table, its saturation, iron loss and deep
/// bar included); one the drive could not run (other pole pairs) or the plant could not
/// build (a deep bar on a Γ-form curve) is refused, naming it.
pub fn plant_model(
    plant: &str,
    drive: &controller_core::drive::DriveSpec,
) -> Result<crate::scenario::SimulatedMotor, String> {
    let (motor, saturation) = drive_file::motor::load_model(plant).map_err(|e| e.to_string())?;
    if motor.pole_pairs() != drive.motor.pole_pairs() {
        return Err(format!(
            "--plant {plant}: {} pole pairs, the drive's motor {}: the drive could not run it",
            motor.pole_pairs(),
            drive.motor.pole_pairs()
        ));
    }
    let extras = drive_file::motor::load_plant_extras(plant).map_err(|e| e.to_string())?;
    simulated(plant, motor, saturation, extras)
}

/// The machine, checked by building it once.
fn simulated(
    name: &str,
    motor: controller_core::motor::MotorParams,
    saturation: Option<controller_core::magnetics::Saturation>,
    extras: drive_file::motor::PlantExtras,
) -> Result<crate::scenario::SimulatedMotor, String> {
    let extras = crate::scenario::extras_of(&extras);
    crate::scenario::plant_machine(&motor, saturation.as_ref(), &extras)
        .map_err(|e| format!("{name}: {e}"))?;
    Ok(crate::scenario::SimulatedMotor { motor, saturation, extras })
}

/// The machine a command simulates for drive `file` read from `path`: `asked` (`--plant`,
/// [`plant_model`]), else the file's own motor when the plant differs from the drive's linear
/// model — its curve ([`drive_file::DriveFile::saturating_motor`]: a drive on its curve runs
/// against the curve) or its `[motor.iron_loss]`, `[motor.deep_bar]` — else `None`: the
/// drive's own linear motor.
pub fn simulated_motor(
    asked: Option<&str>,
    file: &drive_file::DriveFile,
    path: &std::path::Path,
) -> Result<Option<crate::scenario::SimulatedMotor>, String> {
    if let Some(p) = asked {
        return plant_model(p, &file.spec).map(Some);
    }
    let name = path.to_string_lossy();
    let extras = drive_file::motor::load_plant_extras(&name).map_err(|e| e.to_string())?;
    match file.saturating_motor {
        Some((m, s)) => simulated(&name, m, Some(s), extras).map(Some),
        None if extras != drive_file::motor::PlantExtras::default() => {
            simulated(&name, file.spec.motor, None, extras).map(Some)
        }
        None => Ok(None),
    }
}

/// The bus a command runs on when none is asked ([`bus_voltage`], silently): the file's rated
/// bus, or [`DEFAULT_VDC_V`] within the drive's bus range, or that range's middle.
pub fn default_bus_v(file: &drive_file::DriveFile) -> f64 {
    let p = &file.spec.protection;
    match file.rated_bus_v() {
        Some(v) => v,
        None if DEFAULT_VDC_V > p.vdc_min_v && DEFAULT_VDC_V < p.vdc_max_v => DEFAULT_VDC_V,
        None => 0.5 * (p.vdc_min_v + p.vdc_max_v),
    }
}

/// A bus voltage for a message: to 0.1 V, a whole one without its ".0" ("runs on 24 V",
/// "runs on 772.4 V" — not the rated bus's 772.3735400613667, found by trying a population
/// member's file).
pub fn volts(v: f64) -> String {
    let s = format!("{v:.1}");
    s.strip_suffix(".0").map(str::to_owned).unwrap_or(s)
}

/// The bus a command runs `what` on: `asked` (`--vdc`), refused outside the drive's bus range
/// (`[protection]`: every run would trip on it), else the file's rated bus (`[board]
/// vdc_rated_v`, checked inside the range when the file was read), else [`DEFAULT_VDC_V`], or
/// the middle of the range when that lies outside it (said on stderr).
pub fn bus_voltage(asked: Option<f64>, file: &drive_file::DriveFile, what: &str) -> Result<f64, String> {
    let p = &file.spec.protection;
    let inside = |v: f64| v > p.vdc_min_v && v < p.vdc_max_v;
    match asked.map(|v| (v, true)).or(file.rated_bus_v().map(|v| (v, false))) {
        Some((v, true)) if !inside(v) => Err(format!(
            "--vdc {v} V must lie strictly between the drive's bus trip levels, {} and {} V of [protection]: \
             on or beyond one every run trips (the sensors' noise crosses it)",
            p.vdc_min_v, p.vdc_max_v
        )),
        Some((v, true)) => Ok(v),
        Some((v, false)) => {
            eprintln!(
                "hil-sim: {what} runs on {} V, the file's rated bus ([board] vdc_rated_v; --vdc to choose)",
                volts(v)
            );
            Ok(v)
        }
        None if inside(DEFAULT_VDC_V) => Ok(DEFAULT_VDC_V),
        None => {
            let v = 0.5 * (p.vdc_min_v + p.vdc_max_v);
            eprintln!(
                "hil-sim: {DEFAULT_VDC_V} V lies outside the drive's bus range ({} … {} V) and the file states no \
                 [board] vdc_rated_v: {what} runs on {} V (--vdc to choose)",
                p.vdc_min_v,
                p.vdc_max_v,
                volts(v)
            );
            Ok(v)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The file's rated bus when it states one; else 310 V inside the range, or the range's
    /// middle; a `--vdc` on a trip level is refused, one inside taken.
    #[test]
    fn the_bus_is_the_rated_the_default_the_middle_or_the_one_asked() {
        let parse = |t: &str| drive_file::DriveFile::parse(Path::new("d.toml"), t).unwrap();
        let rated = drive_file::SHIPPED;
        assert!(rated.contains("vdc_rated_v = 310.0"));
        let f = parse(&rated.replace("vdc_rated_v = 310.0", "vdc_rated_v = 330.0"));
        assert_eq!(bus_voltage(None, &f, "test"), Ok(330.0));
        assert_eq!(bus_voltage(Some(300.0), &f, "test"), Ok(300.0));
        let e = bus_voltage(Some(f.spec.protection.vdc_max_v), &f, "test").unwrap_err();
        assert!(e.contains("strictly between"), "{e}");
        let unrated = rated.replace("vdc_rated_v = 310.0", "");
        assert_eq!(bus_voltage(None, &parse(&unrated), "test"), Ok(DEFAULT_VDC_V));
        let low = unrated.replace("vdc_min_v = 200.0", "vdc_min_v = 320.0");
        assert_ne!(low, unrated);
        assert_eq!(bus_voltage(None, &parse(&low), "test"), Ok(360.0));
    }

    #[test]
    fn a_relative_elf_is_made_absolute() {
        let opts = pil_options(Some(Path::new("some/pil.elf")), true).unwrap();
        assert!(opts.elf.is_absolute() && opts.elf.ends_with("some/pil.elf"));
        assert_eq!(opts.pin_cpu, None);
    }
}
