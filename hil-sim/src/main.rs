//! `hil-sim` command line (`hil-sim --help`, `hil-sim <command> --help`; the help text is
//! the doc comments below). Exit status: 0 done, 1 the run or the link failed, 2 usage error.
//!
//! This file is the command line only: the arguments, their value parsers, and a match that
//! hands each command's options to its body in `hil_sim::commands`.
//!
//! `run` and `pil` write `DIR/trace.csv` (streamed to disk as the run goes; its columns:
//! `hil_sim::trace`), `summary.json` and the plots `speed.svg`, `currents.svg`,
//! `torque.svg`. Every output appears complete or not at all (written under a `.partial`
//! name, then renamed); a failed or interrupted (Ctrl-C) run leaves none behind.

use clap::{Args, Parser, Subcommand};
use controller_core::drive::Reference;
use controller_core::link::Command;
use hil_sim::commands::campaign::CampaignOptions;
use hil_sim::commands::envelope::EnvelopeOptions;
use hil_sim::commands::faults::FaultsOptions;
use hil_sim::commands::identify::{CommissionOptions, IdentifyOptions};
use hil_sim::commands::link::{CaptureOptions, LinkAction, LinkIdentifyOptions, LinkOptions};
use hil_sim::commands::run::RunOptions;
use hil_sim::commands::{self, pil_options, stop_on_ctrl_c};
use hil_sim::scenario;
use std::path::PathBuf;
use std::process::ExitCode;

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
    /// With --rotate: after the rated flux, the no-load test measures the magnetizing curve
    /// at 0.3…1.2 of it (a motor that saturates; ≈ 2 s of settling per level more), and the
    /// motor file carries it when the motor saturates beyond the L_M interval.
    #[arg(long, requires = "rotate")]
    curve: bool,
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

#[derive(Args, Debug)]
struct RunArgs {
    /// A built-in scenario (`hil-sim list`) or a scenario file (`.toml`).
    scenario: String,
    /// Output directory [default: out/<scenario name>].
    #[arg(long, value_parser = non_empty_path)]
    out: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct EnvelopeArgs {
    /// A drive file.
    #[arg(default_value = "drive.toml")]
    drive: PathBuf,
    #[arg(long, value_parser = positive_volts, help = VDC_HELP)]
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
    /// Simulate this motor instead of the drive's own (a shipped motor's name or a file with a
    /// [motor] table); the physical limit is then that motor's, its saturation included.
    #[arg(long)]
    plant: Option<String>,
    /// Ask this fraction (0.01 ≤ F ≤ 1) of the envelope on the drive's voltage target instead
    /// of more than it has, and judge the torque against the torque asked and the machine's
    /// rotor flux against the drive's reference (each within 5 %): the torque and flux
    /// accuracy. Below a hundredth of the envelope the error relative to the torque asked
    /// measures the current sensors' counts more than the drive.
    #[arg(long, value_parser = torque_fraction)]
    torque_fraction: Option<f64>,
}

/// `--torque-fraction`: a fraction of the envelope (1e-300 asked a torque that rounded to 0
/// and printed an error of 10^300 %: found by trying).
fn torque_fraction(s: &str) -> Result<f64, String> {
    number(s, |x| (0.01..=1.0).contains(&x), "a fraction of the envelope in [0.01, 1]")
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
    /// Length of each run, s [default: 1 s, or longer where the largest inertia of the box
    /// needs longer to step to the box's top speed — field weakening included]
    #[arg(long, value_parser = campaign_seconds)]
    duration: Option<f64>,
    /// Seed of the random samples (and of the sensors' noise).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Run only the shard i of N (runs with k mod N = i); shards' CSV rows concatenate into
    /// the whole campaign's.
    #[arg(long, default_value = "0/1", value_parser = shard)]
    shard: (u64, u64),
    #[arg(long, value_parser = positive_volts, help = VDC_HELP)]
    vdc: Option<f64>,
    /// Output directory [default: out/campaign].
    #[arg(long, value_parser = non_empty_path)]
    out: Option<PathBuf>,
    /// Simulate this motor at the box's points instead of the drive's own: a shipped motor's
    /// name or any file with a [motor] table — a saturating one (form = "gamma",
    /// [motor.saturation]) puts the drive on a plant richer than its model.
    #[arg(long)]
    plant: Option<String>,
    /// Run only run K of the campaign (the same parameters, manoeuvre and noise) and write
    /// its trace (trace.csv, one row per slow period), plots and verdict (summary.json) in
    /// --out [default: out/campaign/run-K]: why that run failed.
    #[arg(long, value_name = "K")]
    trace: Option<u64>,
}

#[derive(Args, Debug)]
struct FaultsArgs {
    /// A drive file (its [certify] omega_r_max_rad_s sets the top speed, if it has one).
    #[arg(default_value = "drive.toml")]
    drive: PathBuf,
    #[arg(long, value_parser = positive_volts, help = VDC_HELP)]
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
    /// Simulate this motor instead of the drive's own: a shipped motor's name or any file
    /// with a [motor] table — a saturating one (form = "gamma", [motor.saturation]) puts the
    /// drive on a plant richer than its model.
    #[arg(long)]
    plant: Option<String>,
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

/// A command's options from its arguments: the fields of the same names, each converted
/// with `From` (most are the same type; the commissioning arguments convert in turn).
/// Destructured and built in full, so a flag without its option does not compile.
macro_rules! options_from_args {
    ($($args:ident => $options:ident { $($field:ident),* $(,)? })*) => {$(
        impl From<$args> for $options {
            fn from(a: $args) -> Self {
                let $args { $($field),* } = a;
                Self { $($field: $field.into()),* }
            }
        }
    )*};
}

options_from_args! {
    RunArgs => RunOptions { scenario, out }
    EnvelopeArgs => EnvelopeOptions { drive, vdc, points, generating, out, plant, torque_fraction }
    CampaignArgs => CampaignOptions { drive, runs, duration, seed, shard, vdc, out, plant, trace }
    FaultsArgs => FaultsOptions { drive, vdc, out, inject_delay_ms, seed, only, trace, plant }
    CommissionArgs => CommissionOptions {
        out, test_current, current_limit, level_time, leakage_ratio, rotate, curve, rated_voltage,
        rated_frequency, no_load_frequency,
    }
    IdentifyArgs => IdentifyOptions {
        motor, run, vdc, pwm_hz, seed, pole_pairs, swap_current_channels, reverse_encoder, plot_dir, pil, elf,
    }
    LinkIdentifyArgs => LinkIdentifyOptions { run, drive }
    LinkCaptureArgs => CaptureOptions { signals, trigger, pre, every, then, wait_s, drive, out }
}

impl From<LinkArgs> for LinkOptions {
    fn from(a: LinkArgs) -> Self {
        let LinkArgs { device, command, timeout_s } = a;
        let reference = |r| LinkAction::Send(Command::SetReference(r));
        let action = command.map(|c| match c {
            LinkCmd::Enable => LinkAction::Send(Command::Enable),
            LinkCmd::Disable => LinkAction::Send(Command::Disable),
            LinkCmd::Stop => LinkAction::Send(Command::Stop),
            LinkCmd::ClearFault => LinkAction::Send(Command::ClearFault),
            LinkCmd::Status { drive } => LinkAction::Status { drive },
            LinkCmd::Speed { value } => reference(Reference::Speed(value)),
            LinkCmd::Position { value } => reference(Reference::Position(value)),
            LinkCmd::Torque { value } => reference(Reference::Torque(value)),
            LinkCmd::Gains => LinkAction::Send(Command::ReadSpeedGains),
            LinkCmd::SetGains { kp, tau_max_nm } => {
                LinkAction::Send(Command::WriteSpeedGains { kp, tau_max_nm })
            }
            LinkCmd::Telemetry { n } => LinkAction::Telemetry { n },
            LinkCmd::Identify(a) => LinkAction::Identify(a.into()),
            LinkCmd::Capture(a) => LinkAction::Capture(a.into()),
        });
        LinkOptions { device, action, timeout_s }
    }
}

/// `s` as a number that `ok` takes, or "`s` is not WHAT".
fn number(s: &str, ok: impl Fn(f64) -> bool, what: &str) -> Result<f64, String> {
    s.parse::<f64>().ok().filter(|&x| ok(x)).ok_or_else(|| format!("`{s}` is not {what}"))
}

fn non_empty_path(s: &str) -> Result<PathBuf, String> {
    if s.trim().is_empty() { Err("must not be empty".into()) } else { Ok(PathBuf::from(s)) }
}

/// `--vdc` of the commands that run a drive file (`hil_sim::commands::bus_voltage`).
const VDC_HELP: &str = "DC-bus voltage, V [default: the file's rated bus, `[board] vdc_rated_v`; without one \
    310, or the middle of the drive's bus range (`[protection]` vdc_min_v … vdc_max_v) when 310 V lies outside it]";

fn positive_volts(s: &str) -> Result<f64, String> {
    number(s, |x| x.is_finite() && x > 0.0 && x <= 10_000.0, "a voltage in (0, 10000] V")
}

fn positive_amperes(s: &str) -> Result<f64, String> {
    number(s, |x| x.is_finite() && x > 0.0 && x <= 1e5, "a current in (0, 100000] A")
}

fn positive_hertz(s: &str) -> Result<f64, String> {
    number(s, |x| x.is_finite() && x > 0.0 && x <= 1000.0, "a frequency in (0, 1000] Hz")
}

fn leakage_ratio(s: &str) -> Result<f64, String> {
    number(s, |x| (0.1..=10.0).contains(&x), "a leakage ratio L_lr/L_ls in [0.1, 10]")
}

fn positive_seconds(s: &str) -> Result<f64, String> {
    number(s, |x| x.is_finite() && x > 0.0 && x <= 3600.0, "a number of seconds in (0, 3600]")
}

fn inject_delay_ms(s: &str) -> Result<f64, String> {
    number(s, |x| (0.0..=1000.0).contains(&x), "a delay in [0, 1000] ms")
}

fn campaign_seconds(s: &str) -> Result<f64, String> {
    number(s, |x| (0.5..=60.0).contains(&x), "a run length in [0.5, 60] s (the speed step comes at 0.25 s)")
}

fn shard(s: &str) -> Result<(u64, u64), String> {
    let bad = || format!("`{s}` is not a shard i/N with 0 ≤ i < N");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n) = (i.trim().parse::<u64>().map_err(|_| bad())?, n.trim().parse::<u64>().map_err(|_| bad())?);
    if n == 0 || i >= n { Err(bad()) } else { Ok((i, n)) }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let builtins = || scenario::all().map_err(|e| format!("built-in scenarios: {e}"));
    let result = match cli.command {
        Cmd::List => builtins().map(|bs| commands::run::list(&bs)),
        Cmd::Run(args) => builtins().and_then(|bs| {
            stop_on_ctrl_c();
            commands::run::run_or_pil(&bs, &args.into(), None)
        }),
        Cmd::Pil { run, elf, no_pin } => builtins().and_then(|bs| {
            let opts = pil_options(elf.as_deref(), no_pin)?;
            stop_on_ctrl_c();
            commands::run::run_or_pil(&bs, &run.into(), Some(opts))
        }),
        Cmd::Bench { scenario, runs } => builtins().and_then(|bs| {
            stop_on_ctrl_c();
            commands::bench::bench(&bs, &scenario, runs)
        }),
        Cmd::Envelope(a) => commands::envelope::envelope(&a.into()),
        Cmd::Campaign(a) => {
            stop_on_ctrl_c();
            commands::campaign::campaign(&a.into())
        }
        Cmd::Faults(a) => {
            stop_on_ctrl_c();
            commands::faults::faults(&a.into())
        }
        Cmd::Identify(a) => {
            stop_on_ctrl_c();
            commands::identify::identify(&a.into())
        }
        Cmd::Link(a) => commands::link::board_link(&a.into()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hil-sim: {e}");
            ExitCode::FAILURE
        }
    }
}
