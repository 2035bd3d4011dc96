//! `hil-sim` command line (`hil-sim --help`, `hil-sim <command> --help`; the help text is
//! the doc comments below). Exit status: 0 done, 1 the run or the link failed, 2 usage error.
//!
//! `run` and `pil` write `DIR/trace.csv` (streamed to disk as the run goes), `summary.json`
//! and the plots `speed.svg`, `currents.svg`, `torque.svg`. Every output appears complete or
//! not at all (written under a `.partial` name, then renamed); a failed or interrupted
//! (Ctrl-C) run leaves none behind.

use clap::{Args, Parser, Subcommand};
use controller_core::drive::Mode;
use controller_core::frames::{Abc, AlphaBeta};
use controller_core::link::{Command, Reply};
use hil_sim::pil::PilOptions;
use hil_sim::scenario::{self, Builtin};
use hil_sim::sim::{self, Row};
use report::write::{write_atomic, write_text};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Induction-motor drive simulator: `controller-core` against a nonlinear machine model
/// (software in the loop), on an emulated Cortex-M4F (processor in the loop), or talking to
/// the board.
#[derive(Parser, Debug)]
#[command(name = "hil-sim", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// List the built-in scenarios (the papers' experiments).
    List,
    /// Run a scenario with the drive in this process (software in the loop).
    Run(RunArgs),
    /// Run a closed-loop scenario with the drive on an emulated Cortex-M4F (QEMU mps2-an386,
    /// processor in the loop); writes the same outputs as `run`, plus link figures.
    Pil {
        #[command(flatten)]
        run: RunArgs,
        /// The `pil` target program [default: qemu-target's release build, or
        /// $HIL_SIM_PIL_ELF]. Build it with `cargo xtask qemu`.
        #[arg(long)]
        elf: Option<PathBuf>,
        /// Leave QEMU and the simulator unpinned (slower).
        #[arg(long)]
        no_pin: bool,
    },
    /// Time the closed-loop simulation alone (no trace files); prints JSON with the median
    /// and best real-time factor and nanoseconds per PWM period.
    Bench {
        /// A built-in scenario.
        #[arg(default_value = "speed-step")]
        scenario: String,
        /// Timed runs (after one warm-up run).
        #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=10_000))]
        runs: u32,
    },
    /// Measure the torque–speed envelope in software in the loop (a dynamometer holds each
    /// speed, the drive is asked for more torque than it has) against the analytic one;
    /// writes envelope.csv, envelope.svg and summary.json, and exits 1 if a point is more
    /// than 5 % off or the drive faulted.
    Envelope(EnvelopeArgs),
    /// The nonlinear campaign: the drive file in software in the loop over the corners and
    /// seeded random samples of its [certify] parameter box, through speed steps, load steps
    /// to 0.8·τ_max both ways and reversals, with realistic sensors, in parallel on all cores;
    /// each run judged (no fault, tracking against an ideal torque actuator, flux, torque
    /// ripple: `hil_sim::campaign`). Writes campaign.csv, campaign.svg and summary.json, and
    /// exits 1 if any run fails.
    Campaign(CampaignArgs),
    /// The fault-injection matrix: every fault the simulator injects (open phase, encoder
    /// stuck/glitch/wrong line count, current sensor dead/stuck/gain/offset, bus sag and
    /// surge, parameter steps, an overload, load seizure) at standstill, mid-speed and top speed, motoring
    /// and generating, in parallel on all cores; each row judged against issue 18's detection
    /// bounds (`hil_sim::faults`). Prints the table, writes faults.md, faults.json and
    /// faults.svg, and exits 1 if a row fails.
    Faults(FaultsArgs),
    /// Self-commissioning in software in the loop: controller-core's standstill sequence
    /// (offsets and bus, voltage pulses for current direction and phase order, three DC
    /// levels, two sinusoidal injections; with --rotate a slow rotating field for the encoder
    /// and J, B) on the simulated motor, with realistic sensors and
    /// a switching inverter with 1 µs of dead time; prints what it identified against the
    /// simulated motor and writes a motor file with intervals (nothing when it fails).
    Identify(IdentifyArgs),
    /// Talk to the board's command/telemetry link on a serial port (115200 baud).
    Link(LinkArgs),
}

/// What every commissioning run takes (`identify` and `link … identify`).
#[derive(Args, Debug, Clone)]
struct CommissionArgs {
    /// The motor file to write.
    #[arg(long, value_parser = non_empty_path)]
    out: PathBuf,
    /// Test current, A: the higher DC level (the motor's rated peak current is a good
    /// choice).
    #[arg(long, value_parser = positive_amperes)]
    test_current: f64,
    /// Phase-current limit during the tests, A [default: 2 × the test current].
    #[arg(long, value_parser = positive_amperes)]
    current_limit: Option<f64>,
    /// Time each DC level is held, s (at least 4 rotor time constants).
    #[arg(long, default_value_t = 3.0)]
    level_time: f64,
    /// Assumed leakage split L_lr/L_ls (the terminals cannot tell it; 1 is the usual equal
    /// split, 1.5 IEEE 112's for NEMA design B).
    #[arg(long, default_value_t = 1.0, value_parser = leakage_ratio)]
    leakage_ratio: f64,
    /// The motor may turn: end with a slow rotating field that checks the encoder's
    /// direction and line count and identifies the inertia and friction, then the no-load
    /// test that measures the magnetizing inductance at rated flux (needs the nameplate's
    /// --rated-voltage and --rated-frequency).
    #[arg(long, requires_all = ["rated_voltage", "rated_frequency"])]
    rotate: bool,
    /// Nameplate: rated line voltage, V RMS (with --rated-frequency, the rated flux of the
    /// no-load test).
    #[arg(long, requires = "rotate", value_parser = positive_volts)]
    rated_voltage: Option<f64>,
    /// Nameplate: rated frequency, Hz.
    #[arg(long, requires = "rotate", value_parser = positive_hertz)]
    rated_frequency: Option<f64>,
    /// The no-load test's field frequency, Hz [default: a quarter of the rated frequency,
    /// at least 2 Hz; lowered if the bus cannot give rated flux there].
    #[arg(long, requires = "rotate", value_parser = positive_hertz)]
    no_load_frequency: Option<f64>,
}

impl CommissionArgs {
    /// The sequence's spec for a PWM rate and a bus range; refused with the flag to change.
    fn config(
        &self,
        pwm_hz: f64,
        vdc_v: (f64, f64),
    ) -> Result<controller_core::commission::CommissionConfig, String> {
        use controller_core::commission::{
            CommissionConfig, CommissionSpec, CommissionSpecError as E, ROTATION_HZ,
        };
        let spec = CommissionSpec {
            pwm_hz: pwm_hz as f32,
            test_current_a: self.test_current as f32,
            current_limit_a: self.current_limit.unwrap_or(2.0 * self.test_current) as f32,
            vdc_min_v: vdc_v.0 as f32,
            vdc_max_v: vdc_v.1 as f32,
            level_time_s: self.level_time as f32,
            rotate: self.rotate,
            rated_flux_wb: match (self.rated_voltage, self.rated_frequency) {
                (Some(v), Some(f)) => hil_sim::identify::rated_flux_wb(v, f) as f32,
                _ => 0.0,
            },
            no_load_hz: self
                .no_load_frequency
                .or(self.rated_frequency.map(|f| (0.25 * f).max(f64::from(ROTATION_HZ))))
                .unwrap_or(0.0) as f32,
        };
        CommissionConfig::new(spec).map_err(|e| {
            match e {
                E::PwmFrequency => "the PWM frequency must lie in 1 … 100 kHz",
                E::TestCurrent => "--test-current must be positive",
                E::CurrentLimit => "--current-limit must be at least 1.5 × the test current",
                E::BusRange => "the bus range is empty",
                E::LevelTime => "--level-time must lie between 192 PWM periods and 60 s",
                E::NoLoad => "--no-load-frequency must lie in 2 … 400 Hz (and the rated flux be positive)",
            }
            .to_string()
        })
    }

    /// Write the motor file for `id` (checked to load as a motor first; atomically).
    fn write(
        &self,
        id: &hil_sim::identify::Identified,
        pole_pairs: u8,
        j_b: (f64, f64),
        about: &str,
    ) -> Result<(), String> {
        let text = hil_sim::identify::motor_file(id, self.leakage_ratio, pole_pairs, j_b.0, j_b.1, about);
        drive_file::motor::parse(&self.out, &text)
            .map_err(|e| format!("the identified motor is not valid: {e}"))?;
        write_text(&self.out, &text)?;
        eprintln!("hil-sim: wrote {}", self.out.display());
        Ok(())
    }
}

#[derive(Args, Debug)]
struct IdentifyArgs {
    /// The motor to simulate: a shipped motor's name, a motor file, a drive file or a
    /// scenario file.
    motor: String,
    #[command(flatten)]
    run: CommissionArgs,
    /// DC-bus voltage, V (the accepted range is ±20 % of it).
    #[arg(long, default_value_t = 310.0, value_parser = positive_volts)]
    vdc: f64,
    /// PWM frequency, Hz.
    #[arg(long, default_value_t = 20_000.0)]
    pwm_hz: f64,
    /// Seed of the sensors' noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The motor's pole pairs (nameplate) [default: the simulated motor's].
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=64))]
    pole_pairs: Option<u8>,
    /// Swap the current channels of phases b and c (a wiring error the sequence refuses).
    #[arg(long)]
    swap_current_channels: bool,
    /// Make the encoder count backwards (a wiring error the rotating field finds).
    #[arg(long, requires = "rotate")]
    reverse_encoder: bool,
    /// Also write the pictures (decays.svg; rotation.svg with --rotate) into this directory.
    #[arg(long, value_parser = non_empty_path)]
    plot_dir: Option<PathBuf>,
    /// Run the sequence on the emulated Cortex-M4F (QEMU, processor in the loop) instead of
    /// in this process: the same record, so the same file, bit for bit.
    #[arg(long)]
    pil: bool,
    /// With --pil: the `pil` target program [default: qemu-target's release build, or
    /// $HIL_SIM_PIL_ELF]. Build it with `cargo xtask qemu`.
    #[arg(long, requires = "pil")]
    elf: Option<PathBuf>,
}

fn positive_amperes(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 && x <= 1e5 => Ok(x),
        _ => Err(format!("`{s}` is not a current in (0, 100000] A")),
    }
}

fn positive_hertz(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 && x <= 1000.0 => Ok(x),
        _ => Err(format!("`{s}` is not a frequency in (0, 1000] Hz")),
    }
}

fn leakage_ratio(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if (0.1..=10.0).contains(&x) => Ok(x),
        _ => Err(format!("`{s}` is not a leakage ratio L_lr/L_ls in [0.1, 10]")),
    }
}

fn link_identify<R: std::io::Read, W: std::io::Write>(
    link: &mut hil_sim::link_client::LinkClient<R, W>,
    a: &LinkIdentifyArgs,
) -> Result<(), String> {
    use controller_core::commission::Stage;
    use hil_sim::identify;
    let file = drive_file::DriveFile::load(&a.drive).map_err(|e| e.to_string())?;
    let p = &file.spec.protection;
    // The board validates the same way; refused here first, with a reason.
    let config = a.run.config(file.spec.pwm_frequency_hz, (p.vdc_min_v, p.vdc_max_v))?;
    stop_on_ctrl_c();
    let mut shown = None;
    let record = identify::over_link(
        link,
        *config.spec(),
        Duration::from_millis(200),
        |stage: Stage| {
            if shown != Some(stage) && stage.index() < Stage::COUNT {
                eprintln!(
                    "hil-sim: [{}/{}] {}",
                    stage.index() + 1,
                    Stage::COUNT,
                    identify::stage_name(stage)
                );
                shown = Some(stage);
            }
        },
        || INTERRUPTED.load(Ordering::Relaxed),
    )
    .map_err(|e| e.to_string())?;
    let m = &file.spec.motor;
    let id = identify::estimate(&config, &record, m.pole_pairs())?;
    if let Some(n) = &id.no_load {
        report::outln!("{}", identify::describe_no_load(n));
    }
    let about = format!(
        "Commissioned on the board over its link (hil-sim link … identify: test current {} A, drive file {}).",
        a.run.test_current,
        a.drive.display()
    );
    a.run.write(&id, m.pole_pairs(), (m.j_kgm2(), m.b_nms()), &about)
}

/// The capture's spec from the command line, checked before any port is opened.
fn capture_spec(a: &LinkCaptureArgs) -> Result<(controller_core::capture::CaptureSpec, usize), String> {
    use hil_sim::capture::{parse_signals, parse_then, parse_trigger};
    if let Some(t) = &a.then {
        parse_then(t).map_err(|e| format!("--then: {e}"))?;
    }
    let (signals, shown) = parse_signals(&a.signals).map_err(|e| format!("--signals: {e}"))?;
    let trigger = parse_trigger(&a.trigger).map_err(|e| format!("--trigger: {e}"))?;
    let depth = controller_core::capture::RECORD_SAMPLES;
    if usize::from(a.pre) >= depth {
        return Err(format!("--pre {}: must be below the record's {depth} samples", a.pre));
    }
    Ok((
        controller_core::capture::CaptureSpec { signals, trigger, pre_samples: a.pre, decimation: a.every },
        shown,
    ))
}

/// `hil-sim link DEVICE capture`: arm, wait (progress on stderr, Ctrl-C stops), read, write.
fn link_capture<R: std::io::Read, W: std::io::Write>(
    link: &mut hil_sim::link_client::LinkClient<R, W>,
    a: &LinkCaptureArgs,
    spec: controller_core::capture::CaptureSpec,
    shown: usize,
    period_s: f64,
) -> Result<(), String> {
    use controller_core::capture::CaptureState;
    stop_on_ctrl_c();
    let mut transact = |c: &controller_core::link::Command| link.transact(c);
    let record = hil_sim::capture::take(
        &mut transact,
        &hil_sim::capture::Request {
            spec,
            period_s,
            shown,
            then: a.then.as_deref().map(hil_sim::capture::parse_then).transpose()?,
        },
        Duration::from_secs_f64(a.wait_s),
        Duration::from_millis(100),
        &|| INTERRUPTED.load(Ordering::Relaxed),
        &mut |s| {
            eprintln!(
                "hil-sim: capture {}",
                match s {
                    CaptureState::Idle => "idle",
                    CaptureState::Armed => "armed, waiting for the trigger",
                    CaptureState::Triggered => "triggered",
                    CaptureState::Done => "done, reading it out",
                }
            );
        },
    )?;
    if INTERRUPTED.load(Ordering::Relaxed) {
        return Err("interrupted: nothing written".into());
    }
    let csv = a.out.join("capture.csv");
    let svg = a.out.join("capture.svg");
    write_text(&csv, &record.csv())?;
    write_text(&svg, &record.svg(&format!("capture ({})", a.trigger)))?;
    report::outln!("{} samples: {} and {}", record.samples.len(), csv.display(), svg.display());
    Ok(())
}

/// Ctrl-C sets [`INTERRUPTED`]: the run stops at its next check and writes nothing (a
/// second Ctrl-C while it winds down is ignored).
fn stop_on_ctrl_c() {
    let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::Relaxed));
}

fn identify(a: &IdentifyArgs) -> Result<(), String> {
    use controller_core::commission::Stage;
    use hil_sim::identify::{self, Setup};
    // Before anything runs: a plot directory that is a file, and --out onto the motor file
    // simulated (it replaced the motor silently; `design tune` refuses its own template: both
    // found by trying).
    a.plot_dir.as_deref().map(report::write::check_dir).transpose()?;
    let same = |p: &Path| std::fs::canonicalize(p).ok();
    if same(&a.run.out).is_some() && same(&a.run.out) == same(Path::new(&a.motor)) {
        return Err(format!(
            "--out {} is the motor simulated: identification writes a new motor file; choose another --out",
            a.run.out.display()
        ));
    }
    let motor = drive_file::motor::load(&a.motor).map_err(|e| e.to_string())?;
    let config = a.run.config(a.pwm_hz, (0.8 * a.vdc, 1.2 * a.vdc))?;
    let mut setup = Setup::realistic(motor, config, a.vdc, a.seed);
    if a.swap_current_channels {
        setup.injections.push(hil_sim::sim::Injection::CurrentChannelsSwapped { first: 1, second: 2 });
    }
    if a.reverse_encoder {
        setup.injections.push(hil_sim::sim::Injection::EncoderReversed);
    }
    let pole_pairs = a.pole_pairs.unwrap_or(motor.pole_pairs());
    let target = if a.pil {
        let mut opts = PilOptions::default();
        if let Some(e) = &a.elf {
            opts.elf = std::path::absolute(e).map_err(|er| format!("--elf {}: {er}", e.display()))?;
        }
        identify::Target::Pil(opts)
    } else {
        identify::Target::InProcess
    };
    let mut shown = (None, -1.0);
    let (record, t) = identify::simulate_on(
        &setup,
        &target,
        |stage: Stage, t_s| {
            // Done or refused: the final call reports the simulation's allowance, not the time.
            let running = stage.index() < Stage::COUNT;
            if running && (shown.0 != Some(stage) || t_s - shown.1 >= 1.0) {
                eprint!(
                    "\rhil-sim: [{}/{}] {:<44} t = {t_s:5.1} s",
                    stage.index() + 1,
                    Stage::COUNT,
                    identify::stage_name(stage)
                );
                shown = (Some(stage), t_s);
            }
        },
        || INTERRUPTED.load(Ordering::Relaxed),
    )
    .map_err(|e| {
        eprintln!();
        e.to_string()
    })?;
    eprintln!();
    let id = identify::estimate(&config, &record, pole_pairs)?;
    let (l_sigma, l_mm, r_rr, tr) = identify::inverse_gamma(&motor);
    let tm = id.t_model(a.run.leakage_ratio);
    let truth = identify::t_model(motor.rs_ohm(), l_sigma, l_mm, r_rr, a.run.leakage_ratio);
    report::outln!(
        "motor time {t:.1} s; against the simulated motor (T-model under L_lr/L_ls = {}):",
        a.run.leakage_ratio
    );
    report::outln!(
        "{:<12} {:>12} {:>26} {:>12} {:>8}",
        "parameter",
        "identified",
        "interval",
        "simulated",
        "error"
    );
    let rows: [(&str, &identify::Estimate, f64); 5] = [
        ("R_s Ω", &id.rs_ohm, motor.rs_ohm()),
        ("σL_s H", &id.l_sigma_h, l_sigma),
        ("T_r s", &id.tr_s, tr),
        ("L_M H", &id.l_mm_h, l_mm),
        ("R_R Ω", &id.r_rr_ohm, r_rr),
    ];
    let g = |x: f64| format!("{x:.5}");
    for (name, e, x) in rows {
        let iv = format!("[{}, {}]", g(e.interval[0]), g(e.interval[1]));
        report::outln!(
            "{name:<12} {:>12} {iv:>26} {:>12} {:>+7.2}%",
            g(e.value),
            g(x),
            100.0 * (e.value / x - 1.0)
        );
    }
    let t_rows = [
        ("R_r Ω", tm.rr_ohm, truth.rr_ohm),
        ("L_s H", tm.ls_h, truth.ls_h),
        ("L_r H", tm.lr_h, truth.lr_h),
        ("L_m H", tm.lm_h, truth.lm_h),
    ];
    for (name, v, x) in t_rows {
        report::outln!("{name:<12} {:>12} {:>26} {:>12} {:>+7.2}%", g(v), "", g(x), 100.0 * (v / x - 1.0));
    }
    let ve = a.vdc * 1e-6 * a.pwm_hz;
    report::outln!(
        "inverter voltage error {} V per phase (the simulated 1 µs dead time: {} V); offsets {:?} A",
        g(id.inverter_error_v.value),
        g(ve),
        id.offsets_a.map(|o| (o * 1e5).round() / 1e5)
    );
    if let Some(r) = &id.rotation {
        report::outln!(
            "rotating field: the rotor turned {:.4}× the field ({:.2} rad/s); J {} kg·m² [{}, {}] (simulated {}), \
             B {} N·m·s/rad [{}, {}] (simulated {})",
            r.ratio,
            r.omega_hold_rad_s,
            g(r.j_kgm2.value),
            g(r.j_kgm2.interval[0]),
            g(r.j_kgm2.interval[1]),
            g(motor.j_kgm2()),
            g(r.b_nms.value),
            g(r.b_nms.interval[0]),
            g(r.b_nms.interval[1]),
            g(motor.b_nms()),
        );
    }
    if let Some(n) = &id.no_load {
        report::outln!("{}", hil_sim::identify::describe_no_load(n));
    }
    let about = format!(
        "Simulated commissioning of `{}` (hil-sim identify: {} V bus, {} Hz PWM, test current {} A, seed {}).",
        a.motor, a.vdc, a.pwm_hz, a.run.test_current, a.seed
    );
    // Nothing in the text says where the sequence ran: SIL and PIL write the same file.
    a.run.write(&id, pole_pairs, (motor.j_kgm2(), motor.b_nms()), &about)?;
    if let Some(dir) = &a.plot_dir {
        std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        for (name, svg) in identify::plots(&config, &record, &id, pole_pairs) {
            write_text(&dir.join(name), &svg)?;
        }
        eprintln!("hil-sim: wrote the pictures in {}", dir.display());
    }
    Ok(())
}

#[derive(Args, Debug)]
struct CampaignArgs {
    /// A drive file with a [certify] table.
    #[arg(default_value = "drive.toml")]
    drive: PathBuf,
    /// Runs in the whole campaign (the 16 corners × 4 manoeuvres come first), at most
    /// 1 000 000 (every verdict is kept for the table; shard a larger campaign).
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    runs: u64,
    /// Length of each run, s (long runs reach into field weakening).
    #[arg(long, default_value_t = 1.0, value_parser = campaign_seconds)]
    duration: f64,
    /// Seed of the random samples (and of the sensors' noise).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Run only the shard i of N (runs with k mod N = i); shards' CSV rows concatenate into
    /// the whole campaign's.
    #[arg(long, default_value = "0/1", value_parser = shard)]
    shard: (u64, u64),
    /// DC-bus voltage, V [default: 310, or the middle of the drive's bus range
    /// (`[protection]` vdc_min_v … vdc_max_v) when 310 V lies outside it].
    #[arg(long, value_parser = positive_volts)]
    vdc: Option<f64>,
    /// Output directory [default: out/campaign].
    #[arg(long, value_parser = non_empty_path)]
    out: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct FaultsArgs {
    /// A drive file (its [certify] omega_r_max_rad_s sets the top speed, if it has one).
    #[arg(default_value = "drive.toml")]
    drive: PathBuf,
    /// DC-bus voltage, V [default: 310, or the middle of the drive's bus range
    /// (`[protection]` vdc_min_v … vdc_max_v) when 310 V lies outside it].
    #[arg(long, value_parser = positive_volts)]
    vdc: Option<f64>,
    /// Output directory [default: out/faults].
    #[arg(long, value_parser = non_empty_path)]
    out: Option<PathBuf>,
    /// Inject every fault this long after its time in the matrix (2.5 s, later for a drive
    /// slower to magnetize or to settle), ms: off the fast steps' grid and the supervisor's
    /// windows (0 … 1000).
    #[arg(long, default_value_t = 0.0, value_parser = inject_delay_ms)]
    inject_delay_ms: f64,
    /// Another draw of the sensors' noise and offsets (0: the matrix's own).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Only the rows whose "fault at operating point" contains this text (any case), e.g.
    /// "open phase" or "switch a upper stuck open at mid-speed motoring".
    #[arg(long)]
    only: Option<String>,
    /// Also write each row's trace into OUT/rows/<row>/: every PWM period from 50 ms before
    /// the injection, or before a fault latched earlier (trace.csv), and plots of the phase
    /// currents against their references, the speed and the torque. At most 12 rows: select
    /// them with --only.
    #[arg(long)]
    trace: bool,
}

/// The bus `faults`, `campaign` and `envelope` run on without `--vdc`, when the drive's
/// range holds it, V.
const DEFAULT_VDC_V: f64 = 310.0;

/// The bus a command runs `what` on: `asked` (`--vdc`), refused outside the drive's bus range
/// (`[protection]`: every run would trip on it), else [`DEFAULT_VDC_V`], or the middle of the
/// range when that lies outside it (said on stderr).
fn bus_voltage(
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
/// The most rows `hil-sim faults --trace` writes (each trace ≈ 3 MB of CSV).
const MAX_TRACED_ROWS: usize = 12;
/// `--trace` starts this long before the injection (or an earlier fault), s.
const TRACE_LEAD_S: f64 = 0.05;

fn inject_delay_ms(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if (0.0..=1000.0).contains(&x) => Ok(x),
        _ => Err(format!("`{s}` is not a delay in [0, 1000] ms")),
    }
}

/// A row's name as a directory name: lower case, every run of other characters one `-`.
fn slug(name: &str) -> String {
    let mut s = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            s.push(c.to_ascii_lowercase());
        } else if !s.ends_with('-') {
            s.push('-');
        }
    }
    s.trim_matches('-').to_string()
}

/// One fault row's run again, traced from [`TRACE_LEAD_S`] before its injection — or before
/// the fault its first run latched earlier (`tripped_before_s`: a failed row) — into
/// `out/trace.csv` (atomic, as `run`'s), with `phases.svg` (the three phase currents and
/// their references), `speed.svg` and `torque.svg`.
fn trace_fault_row(
    m: &hil_sim::faults::Matrix,
    row: &hil_sim::faults::RowSpec,
    tripped_before_s: Option<f64>,
    out: &Path,
) -> Result<(), String> {
    use report::plot::{Series, line_plot};
    let (k, case, at) = row;
    let b = m.scenario(*k, case, at);
    let from_s = tripped_before_s.unwrap_or(f64::INFINITY).min(m.inject_s()) - TRACE_LEAD_S;
    let expected = (b.scenario.duration_s - from_s) * b.spec.pwm_frequency_hz;
    let (_, trace) = stream_trace(out, true, expected, |sink| {
        b.run_into(|_| {}, |r| if r.t_s >= from_s { sink(r) } else { Ok(()) })
    })?;
    let rows = &trace.plot;
    let pts = |f: &dyn Fn(&Row) -> f64| rows.iter().map(|r| (r.t_s, f(r))).collect::<Vec<_>>();
    let abc = |r: &Row| AlphaBeta { alpha: r.x.i_alpha_a, beta: r.x.i_beta_a }.inverse_clarke();
    let abc_ref = |r: &Row| AlphaBeta { alpha: r.i_ref_ab_a[0], beta: r.i_ref_ab_a[1] }.inverse_clarke();
    let colors = ["#1f77b4", "#d62728", "#2ca02c"];
    let names = [("i_a (A)", "i_a ref (A)"), ("i_b (A)", "i_b ref (A)"), ("i_c (A)", "i_c ref (A)")];
    let mut phases = Vec::new();
    for (p, ((name, ref_name), color)) in names.iter().zip(colors).enumerate() {
        let pick = move |v: Abc<f64>| [v.a, v.b, v.c].get(p).copied().unwrap_or(f64::NAN);
        phases.push(Series::line(name, pts(&|r| pick(abc(r)))).colored(color));
        phases.push(Series::dots(ref_name, pts(&|r| pick(abc_ref(r)))).colored(color));
    }
    let title = format!("{}: phase currents (dots: references)", hil_sim::faults::row_name(case, at));
    write_text(&out.join("phases.svg"), &line_plot(&title, "t (s)", &phases))?;
    let speed = [
        Series::line("ω_m (rad/s)", pts(&|r| r.x.omega_m_rad_s)),
        Series::line("ω_ref (rad/s)", pts(&|r| r.omega_ref_rad_s)),
    ];
    write_text(&out.join("speed.svg"), &line_plot("Rotor speed", "t (s)", &speed))?;
    let torque =
        [Series::line("T_e (N·m)", pts(&|r| r.torque_nm)), Series::line("T_L (N·m)", pts(&|r| r.load_nm))];
    write_text(&out.join("torque.svg"), &line_plot("Torque", "t (s)", &torque))?;
    Ok(())
}

fn faults(a: &FaultsArgs) -> Result<(), String> {
    use hil_sim::faults::Matrix;
    let file = drive_file::DriveFile::load(&a.drive).map_err(|e| e.to_string())?;
    let vdc = bus_voltage(a.vdc, &file.spec.protection, "the matrix")?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out/faults"));
    // Without [certify], the top speed is twice the base speed (the field-weakening range).
    let omega_r_max = file.certify.map_or(f64::INFINITY, |c| c.omega_r_max_rad_s);
    let mut m = Matrix::new(file.spec, omega_r_max, vdc);
    m.encoder_lines = file.encoder_lines();
    m.comparator = file
        .board
        .and_then(|b| b.table.comparator)
        .map(|c| hil_sim::bridge_fault::Comparator { trip_a: c.trip_a, filter_s: c.filter_s });
    m.inject_delay_s = 1e-3 * a.inject_delay_ms;
    m.seed = a.seed;
    let all = m.rows()?;
    let selected: Vec<_> = match &a.only {
        Some(text) => {
            let text = text.to_lowercase();
            let rows: Vec<_> = all
                .iter()
                .filter(|(_, c, p)| hil_sim::faults::row_name(c, p).to_lowercase().contains(&text))
                .cloned()
                .collect();
            if rows.is_empty() {
                let mut names: Vec<String> = all.iter().map(|(_, c, _)| c.title()).collect();
                names.dedup();
                let points: Vec<String> = m.points().iter().map(|p| p.name()).collect();
                return Err(format!(
                    "--only {text:?} names no row (\"<fault> at <point>\"; faults: {}; points: {})",
                    names.join(", "),
                    points.join(", ")
                ));
            }
            rows
        }
        None => all,
    };
    if a.trace && selected.len() > MAX_TRACED_ROWS {
        return Err(format!(
            "--trace writes at most {MAX_TRACED_ROWS} rows' traces (≈ 3 MB of CSV each), and {} rows are selected: \
             narrow them with --only",
            selected.len()
        ));
    }
    // Made once the arguments are known to be good (a bad --only or --trace left an empty
    // directory: found by trying), and removed if the matrix is interrupted.
    let made = make_out_dir(&out)?;
    let total = selected.len();
    eprintln!(
        "hil-sim: fault matrix of {} on {} V: {total} rows (top speed {:.1} rad/s{}{})",
        a.drive.display(),
        vdc,
        m.top_speed_rad_s,
        if a.inject_delay_ms > 0.0 {
            format!(", injected {} ms late", a.inject_delay_ms)
        } else {
            String::new()
        },
        if a.seed != 0 { format!(", noise seed {}", a.seed) } else { String::new() },
    );
    let start = std::time::Instant::now();
    let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let rows = m.run_rows(
        &selected,
        |done| {
            if tty {
                eprint!("\rhil-sim: {done}/{total} rows");
            } else if done % 10 == 0 || done == total {
                eprintln!("hil-sim: {done}/{total} rows");
            }
        },
        &INTERRUPTED,
    );
    if tty {
        eprintln!();
    }
    let rows = rows.inspect_err(|_| unmake_out_dir(&out, made))?;
    let elapsed = start.elapsed().as_secs_f64();
    let md = hil_sim::faults::markdown(&m, &rows);
    write_text(&out.join("faults.md"), &md)?;
    let json = serde_json::to_string_pretty(&hil_sim::faults::json(&m, &rows)).map_err(|e| e.to_string())?;
    write_text(&out.join("faults.json"), &format!("{json}\n"))?;
    write_text(&out.join("faults.svg"), &hil_sim::faults::svg(&m, &rows))?;
    report::outln!(
        "{:<30} {:<22} {:>8} {:<40} {:<30} {:>4} {:>7} {:>7} {:>9} {:<22} verdict",
        "fault injected",
        "operating point",
        "ω rad/s",
        "asked",
        "detected as",
        "off",
        "peak A",
        "leg A",
        "E_bus J",
        "final"
    );
    for o in &rows {
        let (off, leg, failures) = o.cells();
        report::outln!(
            "{:<30} {:<22} {:>8.1} {:<40} {:<30} {off:>4} {:>7.2} {leg:>7} {:>9.3} {:<22} {}{failures}",
            o.case.title(),
            o.at.name(),
            o.speed_at_injection_rad_s,
            o.asked(),
            o.seen(),
            o.peak_current_a,
            o.energy_into_bus_j,
            format!("{:?}", o.final_mode),
            o.verdict(),
        );
    }
    let (failed, gaps) =
        (rows.iter().filter(|o| !o.passed()).count(), rows.iter().filter(|o| o.verdict() == "gap").count());
    report::outln!(
        "{} rows in {elapsed:.2} s: {} pass, {gaps} stated gaps, {failed} fail",
        rows.len(),
        rows.len() - failed - gaps
    );
    eprintln!("hil-sim: wrote faults.md, faults.json, faults.svg in {}", out.display());
    if a.trace {
        for (row, o) in selected.iter().zip(&rows) {
            let dir = out.join("rows").join(slug(&hil_sim::faults::row_name(&row.1, &row.2)));
            trace_fault_row(&m, row, o.tripped_before_s, &dir)?;
            eprintln!("hil-sim: wrote trace.csv, phases.svg, speed.svg, torque.svg in {}", dir.display());
        }
    }
    if failed == 0 { Ok(()) } else { Err(format!("{failed} of {} rows failed their criterion", rows.len())) }
}

fn campaign_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if (0.5..=60.0).contains(&x) => Ok(x),
        _ => Err(format!("`{s}` is not a run length in [0.5, 60] s (the speed step comes at 0.25 s)")),
    }
}

fn shard(s: &str) -> Result<(u64, u64), String> {
    let bad = || format!("`{s}` is not a shard i/N with 0 ≤ i < N");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n) = (i.trim().parse::<u64>().map_err(|_| bad())?, n.trim().parse::<u64>().map_err(|_| bad())?);
    if n == 0 || i >= n { Err(bad()) } else { Ok((i, n)) }
}

fn campaign(a: &CampaignArgs) -> Result<(), String> {
    use hil_sim::campaign::{Campaign, Verdict};
    let file = drive_file::DriveFile::load(&a.drive).map_err(|e| e.to_string())?;
    let certify = file.certify.ok_or_else(|| {
        format!("{}: no [certify] table: the campaign samples its parameter box", a.drive.display())
    })?;
    let vdc = bus_voltage(a.vdc, &file.spec.protection, "the campaign")?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out/campaign"));
    let c = Campaign {
        spec: file.spec,
        certify,
        vdc_v: vdc,
        duration_s: a.duration,
        runs: a.runs,
        seed: a.seed,
        shard: a.shard,
        encoder_lines: file.encoder_lines(),
    };
    c.check()?;
    let total = c.indices().count() as u64;
    if total == 0 {
        return Err(format!(
            "shard {}/{} of a {}-run campaign has no runs (its runs are those with k mod {} = {}): take fewer shards",
            a.shard.0, a.shard.1, a.runs, a.shard.1, a.shard.0
        ));
    }
    if a.runs < hil_sim::campaign::CORNER_RUNS {
        eprintln!(
            "hil-sim: {} runs leave corners of the box without every manoeuvre: `design certify --campaign` asks for {} or more",
            a.runs,
            hil_sim::campaign::CORNER_RUNS
        );
    }
    let made = make_out_dir(&out)?;
    eprintln!(
        "hil-sim: campaign of {} on {} V: {total} run(s) of {} s (shard {}/{} of {}), speed steps to ±{:.1} rad/s",
        a.drive.display(),
        vdc,
        a.duration,
        a.shard.0,
        a.shard.1,
        a.runs,
        c.omega_s_rad_s()
    );
    let start = std::time::Instant::now();
    // Progress: one line rewritten on a terminal, a line per 10 % otherwise (a CI log).
    let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let step = (total / if tty { 100 } else { 10 }).max(1);
    let verdicts = c.run(
        |done| {
            if done % step == 0 || done == total {
                if tty {
                    eprint!("\rhil-sim: {done}/{total} runs");
                } else {
                    eprintln!("hil-sim: {done}/{total} runs");
                }
            }
        },
        &INTERRUPTED,
    );
    if tty {
        eprintln!();
    }
    // Interrupted (Ctrl-C): nothing written, nor the directory this made.
    let verdicts = verdicts.inspect_err(|_| unmake_out_dir(&out, made))?;
    let elapsed = start.elapsed().as_secs_f64();
    let mut csv = String::from(Verdict::CSV_HEADER);
    csv.push('\n');
    for v in &verdicts {
        csv.push_str(&v.csv());
        csv.push('\n');
    }
    write_text(&out.join("campaign.csv"), &csv)?;
    write_text(&out.join("campaign.svg"), &hil_sim::campaign::plot(&c, &verdicts))?;
    let mut summary = hil_sim::campaign::summary(&c, &verdicts, elapsed);
    // Which file exactly: `design certify --campaign` refuses a summary of another one.
    let drive_text = drive_file::source::read(&a.drive).map_err(|e| e.to_string())?;
    if let Some(o) = summary.as_object_mut() {
        o.insert(
            "drive".into(),
            serde_json::json!({
                "file": a.drive.display().to_string(),
                "fingerprint": drive_file::source::fingerprint(&drive_text),
            }),
        );
    }
    let text = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    write_text(&out.join("summary.json"), &format!("{text}\n"))?;
    report::outln!(
        "{:<12} {:>6} {:>7} {:>17} {:>13} {:>16}",
        "manoeuvre",
        "runs",
        "passed",
        "worst tracking",
        "worst ripple",
        "flux / model"
    );
    for m in hil_sim::campaign::per_manoeuvre(&verdicts) {
        match (m.worst_tracking_error_rad_s, m.worst_ripple_nm, m.flux_ratio) {
            (Some(tracking), Some(ripple), Some([lo, hi])) => report::outln!(
                "{:<12} {:>6} {:>7} {tracking:>11.3} rad/s {ripple:>10.4} Nm {lo:>8.3} … {hi:.3}",
                m.manoeuvre.name(),
                m.runs,
                m.passed,
            ),
            _ => report::outln!(
                "{:<12} {:>6} {:>7} {:>17} {:>13} {:>16}",
                m.manoeuvre.name(),
                m.runs,
                m.passed,
                "—",
                "—",
                "—"
            ),
        }
    }
    let failed: Vec<&Verdict> = verdicts.iter().filter(|v| !v.passed()).collect();
    for v in failed.iter().take(20) {
        report::outln!("FAIL run {}: {} ({})", v.k, v.failures.join(", "), v.csv());
    }
    report::outln!(
        "{} runs in {elapsed:.2} s ({:.1} ns per simulated PWM period, {:.0} runs/s)",
        verdicts.len(),
        hil_sim::campaign::ns_per_period(&c, verdicts.len(), elapsed),
        verdicts.len() as f64 / elapsed
    );
    eprintln!("hil-sim: wrote campaign.csv, campaign.svg, summary.json in {}", out.display());
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("{} of {} runs failed their criteria", failed.len(), verdicts.len()))
    }
}

#[derive(Args, Debug)]
struct EnvelopeArgs {
    /// A drive file.
    #[arg(default_value = "drive.toml")]
    drive: PathBuf,
    /// DC-bus voltage, V [default: 310, or the middle of the drive's bus range
    /// (`[protection]` vdc_min_v … vdc_max_v) when 310 V lies outside it].
    #[arg(long, value_parser = positive_volts)]
    vdc: Option<f64>,
    /// Speeds measured, evenly from 0.2× to 2× the no-load base speed.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(2..=200))]
    points: u32,
    /// Braking (generating) torque instead of motoring.
    #[arg(long)]
    generating: bool,
    /// Output directory [default: out/envelope].
    #[arg(long, value_parser = non_empty_path)]
    out: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct RunArgs {
    /// A built-in scenario (`hil-sim list`) or a scenario file (`.toml`).
    scenario: String,
    /// Output directory [default: out/<scenario name>].
    #[arg(long, value_parser = non_empty_path)]
    out: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct LinkArgs {
    /// Serial device (e.g. /dev/ttyACM0, the NUCLEO's virtual COM port); `list` shows the
    /// ports found.
    device: String,
    #[command(subcommand)]
    command: Option<LinkCmd>,
    /// Give up on a reply after this many seconds (noise counts as silence).
    #[arg(long, default_value_t = 2.0, value_parser = positive_seconds)]
    timeout_s: f64,
}

#[derive(Subcommand, Debug, Clone)]
enum LinkCmd {
    /// Enable the bridge (Idle → Magnetizing → Running).
    Enable,
    /// Disable the bridge.
    Disable,
    /// A controlled stop: brake to rest on the speed loop, then the bridge off.
    Stop,
    /// Clear a latched fault.
    ClearFault,
    /// Mode, link counters, the control step's longest time and the board's raw readings,
    /// scaled with the drive file the firmware was built from.
    Status {
        /// The firmware's drive file (its `[board]` scalings).
        #[arg(long, default_value = "drive.toml")]
        drive: PathBuf,
    },
    /// Speed reference, rad/s.
    Speed { value: f32 },
    /// Position reference, rad.
    Position { value: f32 },
    /// Torque reference, N·m.
    Torque { value: f32 },
    /// Read the speed-loop gains.
    Gains,
    /// Write the saturated-P speed gains (only while Idle, only inside the certified ranges).
    SetGains { kp: f32, tau_max_nm: f32 },
    /// Print N telemetry frames.
    Telemetry {
        #[arg(default_value_t = 10)]
        n: u32,
    },
    /// Self-commissioning on the board (firmware built with `--features commissioning`):
    /// the standstill sequence (and the rotating field with --rotate), progress shown,
    /// the motor estimated and written to --out; nothing written if it fails.
    Identify(LinkIdentifyArgs),
    /// The drive's scope: arm a capture of up to four signals, wait for its trigger, read
    /// the record out and write `capture.csv` and `capture.svg` to --out (nothing if it
    /// fails or is interrupted).
    Capture(LinkCaptureArgs),
}

#[derive(Args, Debug, Clone)]
struct LinkCaptureArgs {
    /// One to four signals, comma-separated: i_a, i_b, i_c, vdc, omega_m, theta_m, i_alpha,
    /// i_beta, i_ref_alpha, i_ref_beta, v_alpha, v_beta, theta_e, omega_sl, psi_r, psi_ref,
    /// i_q_ref, omega_ref, rr_scale, l_scale, duty_a, duty_b, duty_c, mode.
    #[arg(long, default_value = "i_alpha,i_ref_alpha,omega_m,omega_ref")]
    signals: String,
    /// `immediate`, or SIGNAL:rising|falling|either:LEVEL (e.g. omega_ref:rising:100).
    #[arg(long, default_value = "immediate")]
    trigger: String,
    /// Samples kept before the trigger's (below the record's 256).
    #[arg(long, default_value_t = 64)]
    pre: u16,
    /// One sample every N control periods.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..))]
    every: u16,
    /// A command to send once the capture is armed — what the capture is to see: enable,
    /// disable, stop, or speed|torque|position VALUE (e.g. "speed 100").
    #[arg(long)]
    then: Option<String>,
    /// Give up when no record is complete after this many seconds.
    #[arg(long, default_value_t = 60.0, value_parser = positive_seconds)]
    wait_s: f64,
    /// The drive file the firmware was built from (its PWM period gives the time axis).
    #[arg(long, default_value = "drive.toml")]
    drive: PathBuf,
    /// Output directory.
    #[arg(long, default_value = "capture", value_parser = non_empty_path)]
    out: PathBuf,
}

#[derive(Args, Debug, Clone)]
struct LinkIdentifyArgs {
    #[command(flatten)]
    run: CommissionArgs,
    /// The drive file the firmware was built from: its PWM frequency, bus range, pole pairs,
    /// and J and B for a standstill-only run.
    #[arg(long, default_value = "drive.toml")]
    drive: PathBuf,
}

fn non_empty_path(s: &str) -> Result<PathBuf, String> {
    if s.trim().is_empty() { Err("must not be empty".into()) } else { Ok(PathBuf::from(s)) }
}

fn positive_volts(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 && x <= 10_000.0 => Ok(x),
        _ => Err(format!("`{s}` is not a voltage in (0, 10000] V")),
    }
}

/// The envelope's acceptance: measured within this fraction of the analytic envelope.
const ENVELOPE_TOLERANCE: f64 = 0.05;

fn envelope(a: &EnvelopeArgs) -> Result<(), String> {
    let file = drive_file::DriveFile::load(&a.drive).map_err(|e| e.to_string())?;
    let spec = file.spec;
    let vdc = bus_voltage(a.vdc, &spec.protection, "the envelope")?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out/envelope"));
    let base = hil_sim::envelope::drive_base_speed_rad_s(&spec, vdc);
    if base <= 0.0 {
        return Err(format!("the rated flux needs more than the {} V bus has even at standstill", vdc));
    }
    std::fs::create_dir_all(&out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let n = f64::from(a.points - 1);
    let speeds: Vec<f64> = (0..a.points).map(|k| base * (0.2 + 1.8 * f64::from(k) / n)).collect();
    let sign = if a.generating { -1.0 } else { 1.0 };
    eprintln!(
        "hil-sim: envelope of {} on {} V, {} speeds from {:.1} to {:.1} rad/s (no-load base speed {base:.1} rad/s)",
        a.drive.display(),
        vdc,
        speeds.len(),
        speeds.first().copied().unwrap_or(0.0),
        speeds.last().copied().unwrap_or(0.0)
    );
    let points = hil_sim::envelope::measure(&spec, &spec.motor, vdc, &speeds, sign)?;
    let mut csv =
        String::from("omega_m_rad_s,measured_nm,analytic_nm,relative_error,ripple_nm,flux_wb,mode\n");
    report::outln!(
        "{:>10} {:>12} {:>12} {:>8} {:>10} {:>8}  mode",
        "ω (rad/s)",
        "measured",
        "analytic",
        "error",
        "ripple",
        "ψ_r"
    );
    let mut failed = Vec::new();
    for p in &points {
        let e = p.relative_error();
        report::outln!(
            "{:>10.1} {:>10.4} Nm {:>9.4} Nm {:>+7.2}% {:>7.4} Nm {:>7.3}  {:?}",
            p.omega_m_rad_s,
            p.measured_nm,
            p.analytic_nm,
            100.0 * e,
            p.ripple_nm,
            p.flux_wb,
            p.mode
        );
        csv.push_str(&format!(
            "{:.4},{:.6},{:.6},{:.6},{:.6},{:.5},{:?}\n",
            p.omega_m_rad_s, p.measured_nm, p.analytic_nm, e, p.ripple_nm, p.flux_wb, p.mode
        ));
        if e.abs() > ENVELOPE_TOLERANCE || p.mode != Mode::Running {
            failed.push(p.omega_m_rad_s);
        }
    }
    write_text(&out.join("envelope.csv"), &csv)?;
    write_text(&out.join("envelope.svg"), &hil_sim::envelope::plot(&spec, &spec.motor, vdc, &points, sign))?;
    let summary = serde_json::json!({
        "drive": a.drive.display().to_string(),
        "vdc_v": vdc,
        "base_speed_rad_s": base,
        "direction": if a.generating { "generating" } else { "motoring" },
        "tolerance": ENVELOPE_TOLERANCE,
        "worst_relative_error": points.iter().map(|p| p.relative_error().abs()).fold(0.0, f64::max),
        "points_outside": failed.len(),
    });
    let text = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    write_text(&out.join("summary.json"), &format!("{text}\n"))?;
    eprintln!("hil-sim: wrote envelope.csv, envelope.svg, summary.json in {}", out.display());
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{} point(s) more than {:.0} % off the envelope or faulted, at {failed:.1?} rad/s",
            failed.len(),
            100.0 * ENVELOPE_TOLERANCE
        ))
    }
}

fn positive_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 && x <= 3600.0 => Ok(x),
        _ => Err(format!("`{s}` is not a number of seconds in (0, 3600]")),
    }
}

/// Set by Ctrl-C: a run in progress stops at its next trace row and cleans up.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

fn interrupted() -> Result<(), String> {
    if INTERRUPTED.load(Ordering::Relaxed) { Err("interrupted".into()) } else { Ok(()) }
}

const BASE_HEADER: &str =
    "t_s,i_alpha_a,i_beta_a,psi_alpha_wb,psi_beta_wb,omega_m_rad_s,theta_m_rad,torque_nm,v_alpha_v,v_beta_v";
const CLOSED_LOOP_HEADER: &str = ",i_alpha_ref_a,i_beta_ref_a,omega_ref_rad_s,load_nm,drive_mode,fault,duty_a,duty_b,duty_c,vdc_v,psi_est_wb,psi_ref_wb,rr_scale,l_scale,brake,i_chopper_a,i_leg_peak_a,comparator";

/// Most points per plotted curve.
const PLOT_POINTS: f64 = 4000.0;

/// What a streamed trace leaves for the summary and the plots: the peak current, the last
/// row and a thinned copy of the rows.
struct TraceStats {
    closed_loop: bool,
    plot_every: u64,
    count: u64,
    peak_a: f64,
    last: Option<Row>,
    plot: Vec<Row>,
}

impl TraceStats {
    fn new(closed_loop: bool, expected_rows: f64) -> Self {
        Self {
            closed_loop,
            plot_every: (expected_rows / PLOT_POINTS).ceil().max(1.0) as u64,
            count: 0,
            peak_a: 0.0,
            last: None,
            plot: Vec::new(),
        }
    }

    fn add(&mut self, r: &Row) {
        // Every period's, not only the trace's rows ([`Row::i_peak_a`]).
        self.peak_a = self.peak_a.max(r.i_peak_a).max(r.x.i_alpha_a.hypot(r.x.i_beta_a));
        if self.count.is_multiple_of(self.plot_every) {
            self.plot.push(*r);
        }
        self.count += 1;
        self.last = Some(*r);
    }
}

/// One CSV row of the trace.
fn write_row(f: &mut dyn Write, r: &Row, closed_loop: bool) -> std::io::Result<()> {
    let x = &r.x;
    write!(
        f,
        "{:.7},{:.6},{:.6},{:.6},{:.6},{:.5},{:.5},{:.5},{:.4},{:.4}",
        r.t_s,
        x.i_alpha_a,
        x.i_beta_a,
        x.psi_alpha_wb,
        x.psi_beta_wb,
        x.omega_m_rad_s,
        x.theta_m_rad,
        r.torque_nm,
        r.v_ab_v[0],
        r.v_ab_v[1]
    )?;
    if closed_loop {
        write!(
            f,
            ",{:.6},{:.6},{:.4},{:.4}",
            r.i_ref_ab_a[0], r.i_ref_ab_a[1], r.omega_ref_rad_s, r.load_nm
        )?;
        // Mode and fault as words; duties empty while the bridge is off.
        let (mode, fault) = match r.mode {
            Some(Mode::Fault(which)) => ("Fault".to_string(), format!("{which:?}")),
            Some(m) => (format!("{m:?}"), String::new()),
            None => (String::new(), String::new()),
        };
        write!(f, ",{mode},{fault}")?;
        match r.duty {
            Some([a, b, c]) => write!(f, ",{a:.6},{b:.6},{c:.6}")?,
            None => write!(f, ",,,")?,
        }
        write!(
            f,
            ",{:.2},{:.5},{:.5},{:.4},{:.4}",
            r.vdc_v, r.psi_est_wb, r.psi_ref_wb, r.rr_scale, r.l_scale
        )?;
        write!(f, ",{},{:.4}", u8::from(r.brake), r.i_chopper_a)?;
        write!(f, ",{:.4},{}", r.i_leg_peak_a, u8::from(r.hw_break))?;
    }
    writeln!(f)
}

/// Make the output directory `out` (and its parents); `true` when this call made `out`.
fn make_out_dir(out: &Path) -> Result<bool, String> {
    report::write::check_dir(out)?;
    let made = !out.exists();
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    Ok(made)
}

/// After a failed or interrupted command: `out` removed when the command made it
/// ([`make_out_dir`]) and it is still empty — `remove_dir` takes only an empty directory, so
/// nothing anyone put there is lost (failures left empty directories: found by trying).
fn unmake_out_dir(out: &Path, made: bool) {
    if made {
        let _ = std::fs::remove_dir(out);
    }
}

/// Stream the rows `run` makes into `out/trace.csv` through the one atomic writer
/// (`report::write`): the file is created before the run (an unusable directory fails at
/// once) and takes its name only complete; a failed or interrupted run leaves nothing — nor
/// the directory, when this call made it (an empty one was left: found by trying).
fn stream_trace<T>(
    out: &Path,
    closed_loop: bool,
    expected_rows: f64,
    run: impl FnOnce(&mut dyn FnMut(&Row) -> Result<(), String>) -> Result<T, String>,
) -> Result<(T, TraceStats), String> {
    let made_dir = make_out_dir(out)?;
    let mut stats = TraceStats::new(closed_loop, expected_rows);
    let mut outcome = None;
    let written = write_atomic(&out.join("trace.csv"), |w| {
        writeln!(w, "{BASE_HEADER}{}", if closed_loop { CLOSED_LOOP_HEADER } else { "" })?;
        let mut io_error = None;
        let result = run(&mut |row| {
            interrupted()?;
            if let Err(e) = write_row(w, row, closed_loop) {
                let reason = e.to_string();
                io_error = Some(e);
                return Err(reason);
            }
            stats.add(row);
            Ok(())
        });
        if let Some(e) = io_error {
            return Err(e);
        }
        let failed = result.is_err();
        outcome = Some(result);
        if failed { Err(std::io::Error::other("the run failed")) } else { Ok(()) }
    });
    let result = match (outcome, written) {
        (Some(Err(e)), _) => Err(e),
        (_, Err(e)) => Err(e),
        (Some(Ok(value)), Ok(())) => Ok((value, stats)),
        (None, Ok(())) => Err("the run did not start".into()),
    };
    if result.is_err() {
        unmake_out_dir(out, made_dir);
    }
    result
}

fn progress_bar(fraction: f64) {
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

/// The main signals as SVG plots: speed, stator currents (with references in closed loop),
/// torque.
fn write_plots(out: &Path, rows: &[Row], closed_loop: bool) -> Result<(), String> {
    use report::plot::{Series, line_plot};
    let pts = |f: &dyn Fn(&Row) -> f64| rows.iter().map(|r| (r.t_s, f(r))).collect::<Vec<_>>();
    let mut speed = vec![Series::line("ω_m (rad/s)", pts(&|r| r.x.omega_m_rad_s))];
    let mut currents = vec![
        Series::line("i_α (A)", pts(&|r| r.x.i_alpha_a)),
        Series::line("i_β (A)", pts(&|r| r.x.i_beta_a)),
    ];
    let mut torque = vec![Series::line("T_e (N·m)", pts(&|r| r.torque_nm))];
    if closed_loop {
        speed.push(Series::line("ω_ref (rad/s)", pts(&|r| r.omega_ref_rad_s)));
        currents.push(Series::line("i_α ref (A)", pts(&|r| r.i_ref_ab_a[0])));
        currents.push(Series::line("i_β ref (A)", pts(&|r| r.i_ref_ab_a[1])));
        torque.push(Series::line("T_L (N·m)", pts(&|r| r.load_nm)));
    }
    for (name, title, series) in [
        ("speed.svg", "Rotor speed", speed),
        ("currents.svg", "Stator currents", currents),
        ("torque.svg", "Torque", torque),
    ] {
        write_text(&out.join(name), &line_plot(title, "t (s)", &series))?;
    }
    Ok(())
}

/// Write the plots and the summary (given the trace's figures).
fn finish(
    out: &Path,
    trace: TraceStats,
    summary: impl FnOnce(&Row, f64) -> serde_json::Value,
) -> Result<(), String> {
    let last = trace.last.ok_or("empty run")?;
    let summary = summary(&last, trace.peak_a);
    write_plots(out, &trace.plot, trace.closed_loop)?;
    let text = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    write_text(&out.join("summary.json"), &format!("{text}\n"))?;
    report::outln!("{text}");
    eprintln!(
        "hil-sim: wrote trace.csv, summary.json, speed.svg, currents.svg, torque.svg in {}",
        out.display()
    );
    Ok(())
}

fn run_builtin(b: &Builtin, out: &Path, pil: Option<&PilOptions>) -> Result<(), String> {
    let rows = b.scenario.duration_s * b.spec.pwm_frequency_hz / f64::from(b.scenario.trace_every.max(1));
    let wall = std::time::Instant::now();
    let ((mode, link), trace) = stream_trace(out, true, rows, |sink| {
        eprintln!("hil-sim: {} — {}", b.name, b.about);
        // Not refused (a scenario may mean to trip), but said: found by trying a 310 V
        // scenario on the 3 300 V template, which tripped at once and exited 0.
        let (vdc_v, p) = (b.scenario.vdc_v, &b.spec.protection);
        if !(vdc_v >= p.vdc_min_v && vdc_v <= p.vdc_max_v) {
            eprintln!(
                "hil-sim: note: the scenario's bus, {vdc_v} V, lies outside the drive's range ({} … {} V): \
                 its supervisor trips on it (DcBusUndervoltage below, DcBusOvervoltage above)",
                p.vdc_min_v, p.vdc_max_v
            );
        }
        match pil {
            None => Ok((format!("{:?}", b.run_into(progress_bar, sink)?), None)),
            Some(opts) => {
                let mut link = b.run_pil_into(opts, progress_bar, sink)?;
                match link.transact(&Command::GetStatus)? {
                    Reply::Status { mode, .. } => Ok((format!("{mode:?}"), Some(link))),
                    other => Err(format!("unexpected reply to GetStatus: {other:?}")),
                }
            }
        }
    })?;
    let secs = wall.elapsed().as_secs_f64();
    finish(out, trace, |last, peak| {
        let mut summary = serde_json::json!({
            "scenario": b.name,
            "kind": "closed_loop",
            "duration_s": b.scenario.duration_s,
            "final_omega_m_rad_s": last.x.omega_m_rad_s,
            "final_omega_ref_rad_s": last.omega_ref_rad_s,
            "peak_stator_current_a": peak,
            "drive_mode": mode,
            "rk4_substeps_per_pwm_period": b.scenario.substeps,
            "wall_time_s": secs,
            "real_time_factor": b.scenario.duration_s / secs,
        });
        if let (Some(link), Some(obj)) = (&link, summary.as_object_mut()) {
            obj.insert("controller".into(), "pil: QEMU mps2-an386 (Cortex-M4F)".into());
            obj.insert("link_round_trips".into(), link.round_trips().into());
            obj.insert("link_round_trips_per_s".into(), (link.round_trips() as f64 / secs).into());
            obj.insert("link_host_rx_errors".into(), link.stats().errors().into());
            obj.insert("pinned_to_one_cpu".into(), link.pinned().into());
        }
        summary
    })
}

fn run_file(path: &Path, out: &Path, pil: Option<&PilOptions>) -> Result<(), String> {
    use hil_sim::scenario_file::{self, ScenarioFileKind};
    let sc = match scenario_file::load(path).map_err(|e| e.to_string())? {
        ScenarioFileKind::ClosedLoop(b) => return run_builtin(&b, out, pil),
        ScenarioFileKind::OpenLoop(_) if pil.is_some() => {
            return Err(format!(
                "{}: an open-loop scenario has no controller to put in the loop",
                path.display()
            ));
        }
        ScenarioFileKind::OpenLoop(sc) => sc,
    };
    let wall = std::time::Instant::now();
    let (_, trace) = stream_trace(out, false, sc.duration_s / sc.sample_period_s, |sink| {
        eprintln!("hil-sim: open-loop run of {}", path.display());
        sim::run_open_loop(&sc, sim::OPEN_LOOP_MAX_STEP_S, progress_bar, sink)
    })?;
    let secs = wall.elapsed().as_secs_f64();
    finish(out, trace, |last, peak| {
        serde_json::json!({
            "scenario": path.display().to_string(),
            "kind": "open_loop",
            "duration_s": sc.duration_s,
            "final_omega_m_rad_s": last.x.omega_m_rad_s,
            "final_torque_nm": last.torque_nm,
            "peak_stator_current_a": peak,
            "rk4_max_step_s": sim::OPEN_LOOP_MAX_STEP_S,
            "wall_time_s": secs,
        })
    })
}

fn run_or_pil(builtins: &[Builtin], args: &RunArgs, pil: Option<PilOptions>) -> Result<(), String> {
    let name = &args.scenario;
    let stem = Path::new(name).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&stem));
    if let Some(b) = builtins.iter().find(|b| &b.name == name) {
        run_builtin(b, &out, pil.as_ref())
    } else if name.ends_with(".toml") || Path::new(name).exists() {
        run_file(Path::new(name), &out, pil.as_ref())
    } else {
        Err(format!("`{name}` is neither a scenario file nor a built-in scenario (`hil-sim list`)"))
    }
}

/// `hil-sim bench`: wall time of the simulation loop alone.
fn bench(builtins: &[Builtin], name: &str, runs: u32) -> Result<(), String> {
    let b = builtins
        .iter()
        .find(|b| b.name == name)
        .ok_or(format!("`{name}` is not a built-in scenario (`hil-sim list`)"))?;
    let periods = (b.scenario.duration_s * b.spec.pwm_frequency_hz).round();
    let mut secs = Vec::with_capacity(runs as usize);
    for k in 0..=runs {
        let wall = std::time::Instant::now();
        let (rows, _) = b.run(|_| {})?;
        let s = wall.elapsed().as_secs_f64();
        std::hint::black_box(rows);
        interrupted()?;
        if k > 0 {
            secs.push(s);
        }
        progress_bar(f64::from(k) / f64::from(runs));
    }
    secs.sort_by(f64::total_cmp);
    let median = secs.get(secs.len() / 2).copied().ok_or("no runs")?;
    let best = secs.first().copied().ok_or("no runs")?;
    let summary = serde_json::json!({
        "scenario": b.name,
        "runs": runs,
        "duration_s": b.scenario.duration_s,
        "pwm_frequency_hz": b.spec.pwm_frequency_hz,
        "rk4_substeps_per_pwm_period": b.scenario.substeps,
        "median_wall_time_s": median,
        "median_real_time_factor": b.scenario.duration_s / median,
        "best_real_time_factor": b.scenario.duration_s / best,
        "median_ns_per_pwm_period": median * 1e9 / periods,
        "best_ns_per_pwm_period": best * 1e9 / periods,
    });
    report::outln!("{}", serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?);
    Ok(())
}

/// `hil-sim link DEVICE …`: one command to the board, or N telemetry frames from it.
fn board_link(a: &LinkArgs) -> Result<(), String> {
    use controller_core::drive::Reference;
    if a.device == "list" {
        let ports = serialport::available_ports().map_err(|e| format!("cannot list serial ports: {e}"))?;
        if ports.is_empty() {
            eprintln!("hil-sim: no serial ports found");
        }
        for p in ports {
            report::outln!("{}", p.port_name);
        }
        return Ok(());
    }
    let Some(command) = a.command.clone() else {
        return Err("which command? (`hil-sim link --help`)".into());
    };
    let cmd = match command {
        LinkCmd::Enable => Some(Command::Enable),
        LinkCmd::Disable => Some(Command::Disable),
        LinkCmd::Stop => Some(Command::Stop),
        LinkCmd::ClearFault => Some(Command::ClearFault),
        LinkCmd::Status { .. } => Some(Command::GetStatus),
        LinkCmd::Speed { value } => Some(Command::SetReference(Reference::Speed(value))),
        LinkCmd::Position { value } => Some(Command::SetReference(Reference::Position(value))),
        LinkCmd::Torque { value } => Some(Command::SetReference(Reference::Torque(value))),
        LinkCmd::Gains => Some(Command::ReadSpeedGains),
        LinkCmd::SetGains { kp, tau_max_nm } => Some(Command::WriteSpeedGains { kp, tau_max_nm }),
        LinkCmd::Telemetry { .. } | LinkCmd::Identify(_) | LinkCmd::Capture(_) => None,
    };
    // The drive file the status is scaled with (or the capture timed with): read before the
    // port is opened, so that a bad file or argument is reported as such, board or no board.
    let status_file = match &command {
        LinkCmd::Status { drive } | LinkCmd::Capture(LinkCaptureArgs { drive, .. }) => {
            Some(drive_file::DriveFile::load(drive).map_err(|e| e.to_string())?)
        }
        _ => None,
    };
    let capture = match &command {
        LinkCmd::Capture(c) => {
            let spec = capture_spec(c)?;
            std::fs::create_dir_all(&c.out).map_err(|e| format!("cannot create {}: {e}", c.out.display()))?;
            Some(spec)
        }
        _ => None,
    };
    let timeout = Duration::from_secs_f64(a.timeout_s);
    // Raw 8N1 at 115200 baud; reads return after 100 ms without data (the client's own
    // deadline decides when to give up).
    let port = serialport::new(&a.device, 115_200)
        .timeout(Duration::from_millis(100))
        .open()
        .map_err(|e| format!("{}: {e}", a.device))?;
    let rx = port.try_clone().map_err(|e| format!("{}: {e}", a.device))?;
    let mut link = hil_sim::link_client::LinkClient::new(rx, port).with_reply_timeout(timeout);
    match (cmd, command) {
        (None, LinkCmd::Identify(args)) => link_identify(&mut link, &args)?,
        (None, LinkCmd::Capture(args)) if let (Some((spec, shown)), Some(file)) = (capture, &status_file) => {
            link_capture(&mut link, &args, spec, shown, 1.0 / file.spec.pwm_frequency_hz)?
        }
        (Some(c), LinkCmd::Status { .. }) if let Some(file) = &status_file => {
            let r = link.transact(&c)?;
            match hil_sim::link_client::format_status(&r, file) {
                Some(text) => report::out!("{text}"),
                None => report::outln!("{r:?}"),
            }
        }
        (Some(c), _) => report::outln!("{:?}", link.transact(&c)?),
        (None, LinkCmd::Telemetry { n }) => {
            // Each status request keeps the board's link watchdog (`[board] link_timeout_s`)
            // from stopping the drive while we watch; the board streams an output after 10 ms
            // of quiet.
            for _ in 0..n {
                report::outln!("{:?}", link.transact(&Command::GetStatus)?);
                report::outln!("{:?}", link.next_reply()?);
            }
        }
        (None, _) => {}
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let builtins = || scenario::all().map_err(|e| format!("built-in scenarios: {e}"));
    let result = match &cli.command {
        Cmd::List => builtins().map(|bs| {
            for b in &bs {
                report::outln!("{:<20} {}", b.name, b.about);
            }
        }),
        Cmd::Run(args) => builtins().and_then(|bs| {
            stop_on_ctrl_c();
            run_or_pil(&bs, args, None)
        }),
        Cmd::Pil { run, elf, no_pin } => builtins().and_then(|bs| {
            let mut opts = PilOptions::default();
            if let Some(e) = elf {
                // QEMU runs in a temporary directory: a relative path must not be taken
                // relative to it.
                opts.elf = std::path::absolute(e).map_err(|er| format!("--elf {}: {er}", e.display()))?;
            }
            if *no_pin {
                opts.pin_cpu = None;
            }
            stop_on_ctrl_c();
            run_or_pil(&bs, run, Some(opts))
        }),
        Cmd::Bench { scenario, runs } => builtins().and_then(|bs| {
            stop_on_ctrl_c();
            bench(&bs, scenario, *runs)
        }),
        Cmd::Envelope(a) => envelope(a),
        Cmd::Campaign(a) => {
            stop_on_ctrl_c();
            campaign(a)
        }
        Cmd::Faults(a) => {
            stop_on_ctrl_c();
            faults(a)
        }
        Cmd::Identify(a) => {
            stop_on_ctrl_c();
            identify(a)
        }
        Cmd::Link(a) => board_link(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hil-sim: {e}");
            ExitCode::FAILURE
        }
    }
}
