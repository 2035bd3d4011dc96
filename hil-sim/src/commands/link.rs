//! `hil-sim link DEVICE …`: the board's command/telemetry link on a serial port — one
//! command and its reply, telemetry, self-commissioning on the board, the drive's scope.

use super::identify::CommissionOptions;
use super::{INTERRUPTED, stop_on_ctrl_c};
use controller_core::link::Command;
use report::write::write_text;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::Duration;

/// What `link` is asked.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkOptions {
    /// Serial device, or `list` for the ports found.
    pub device: String,
    /// What to do on it (`None`: an error, unless the device is `list`).
    pub action: Option<LinkAction>,
    /// Give up on a reply after this many seconds.
    pub timeout_s: f64,
}

/// One `link` subcommand.
// One per process, made once: a `Command` (its `Configure` variant is large) is not worth a box.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum LinkAction {
    /// Send a command, print its reply.
    Send(Command),
    /// The status, scaled with the drive file the firmware was built from.
    Status {
        /// The firmware's drive file (its `[board]` scalings).
        drive: PathBuf,
    },
    /// Print `n` status replies and `n` telemetry frames.
    Telemetry {
        /// Frames.
        n: u32,
    },
    /// Self-commissioning on the board.
    Identify(LinkIdentifyOptions),
    /// The drive's scope.
    Capture(CaptureOptions),
}

/// What `link … capture` is asked.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureOptions {
    /// One to four signals, comma-separated.
    pub signals: String,
    /// `immediate`, or SIGNAL:rising|falling|either:LEVEL.
    pub trigger: String,
    /// Samples kept before the trigger's (below the record's).
    pub pre: u16,
    /// One sample every N control periods.
    pub every: u16,
    /// A command to send once the capture is armed.
    pub then: Option<String>,
    /// Give up when no record is complete after this many seconds.
    pub wait_s: f64,
    /// The drive file the firmware was built from (its PWM period gives the time axis).
    pub drive: PathBuf,
    /// Output directory.
    pub out: PathBuf,
}

/// What `link … identify` is asked.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkIdentifyOptions {
    /// The commissioning run.
    pub run: CommissionOptions,
    /// The drive file the firmware was built from.
    pub drive: PathBuf,
}

/// `s` seconds as a duration; an error naming `flag` when it cannot be one.
fn seconds(s: f64, flag: &str) -> Result<Duration, String> {
    Duration::try_from_secs_f64(s).map_err(|e| format!("{flag} {s}: {e}"))
}

/// `hil-sim link DEVICE identify`: the sequence on the board (progress on stderr, Ctrl-C
/// stops it), the motor estimated and written (nothing if it fails).
pub fn link_identify<R: std::io::Read, W: std::io::Write>(
    link: &mut crate::link_client::LinkClient<R, W>,
    a: &LinkIdentifyOptions,
) -> Result<(), String> {
    use crate::identify;
    use controller_core::commission::Stage;
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
    for line in identify::describe_curve(&id) {
        report::outln!("{line}");
    }
    let about = format!(
        "Commissioned on the board over its link (hil-sim link … identify: test current {} A, drive file {}).",
        a.run.test_current,
        a.drive.display()
    );
    a.run.write(&id, m.pole_pairs(), (m.j_kgm2(), m.b_nms()), &about)
}

/// The capture's spec from the command line, checked before any port is opened.
pub fn capture_spec(a: &CaptureOptions) -> Result<(controller_core::capture::CaptureSpec, usize), String> {
    use crate::capture::{parse_signals, parse_then, parse_trigger};
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
pub fn link_capture<R: std::io::Read, W: std::io::Write>(
    link: &mut crate::link_client::LinkClient<R, W>,
    a: &CaptureOptions,
    spec: controller_core::capture::CaptureSpec,
    shown: usize,
    period_s: f64,
) -> Result<(), String> {
    use controller_core::capture::CaptureState;
    stop_on_ctrl_c();
    let mut transact = |c: &controller_core::link::Command| link.transact(c);
    let record = crate::capture::take(
        &mut transact,
        &crate::capture::Request {
            spec,
            period_s,
            shown,
            then: a.then.as_deref().map(crate::capture::parse_then).transpose()?,
        },
        seconds(a.wait_s, "--wait-s")?,
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

/// `hil-sim link DEVICE …`: one command to the board, or N telemetry frames from it.
pub fn board_link(a: &LinkOptions) -> Result<(), String> {
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
    let Some(action) = &a.action else {
        return Err("which command? (`hil-sim link --help`)".into());
    };
    // The drive file the status is scaled with (or the capture timed with): read before the
    // port is opened, so that a bad file or argument is reported as such, board or no board.
    let status_file = match action {
        LinkAction::Status { drive } | LinkAction::Capture(CaptureOptions { drive, .. }) => {
            Some(drive_file::DriveFile::load(drive).map_err(|e| e.to_string())?)
        }
        _ => None,
    };
    let capture = match action {
        LinkAction::Capture(c) => {
            let spec = capture_spec(c)?;
            std::fs::create_dir_all(&c.out).map_err(|e| format!("cannot create {}: {e}", c.out.display()))?;
            Some(spec)
        }
        _ => None,
    };
    let timeout = seconds(a.timeout_s, "--timeout-s")?;
    // Raw 8N1 at 115200 baud; reads return after 100 ms without data (the client's own
    // deadline decides when to give up).
    let port = serialport::new(&a.device, 115_200)
        .timeout(Duration::from_millis(100))
        .open()
        .map_err(|e| format!("{}: {e}", a.device))?;
    let rx = port.try_clone().map_err(|e| format!("{}: {e}", a.device))?;
    let mut link = crate::link_client::LinkClient::new(rx, port).with_reply_timeout(timeout);
    match action {
        LinkAction::Identify(args) => link_identify(&mut link, args)?,
        LinkAction::Capture(args) if let (Some((spec, shown)), Some(file)) = (capture, &status_file) => {
            link_capture(&mut link, args, spec, shown, 1.0 / file.spec.pwm_frequency_hz)?
        }
        LinkAction::Status { .. } if let Some(file) = &status_file => {
            let r = link.transact(&Command::GetStatus)?;
            match crate::link_client::format_status(&r, file) {
                Some(text) => report::out!("{text}"),
                None => report::outln!("{r:?}"),
            }
        }
        LinkAction::Send(c) => report::outln!("{:?}", link.transact(c)?),
        LinkAction::Telemetry { n } => {
            // Each status request keeps the board's link watchdog (`[board] link_timeout_s`)
            // from stopping the drive while we watch; the board streams an output after 10 ms
            // of quiet.
            for _ in 0..*n {
                report::outln!("{:?}", link.transact(&Command::GetStatus)?);
                report::outln!("{:?}", link.next_reply()?);
            }
        }
        LinkAction::Status { .. } | LinkAction::Capture(_) => {}
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn capture(pre: u16, signals: &str, then: Option<&str>) -> CaptureOptions {
        CaptureOptions {
            signals: signals.into(),
            trigger: "immediate".into(),
            pre,
            every: 1,
            then: then.map(String::from),
            wait_s: 1.0,
            drive: PathBuf::from("drive.toml"),
            out: PathBuf::from("capture"),
        }
    }

    /// The capture's arguments are checked without a board, each error naming its flag.
    #[test]
    fn capture_arguments_are_checked_alone() {
        let (spec, shown) = capture_spec(&capture(8, "i_a,omega_m", Some("speed 50"))).unwrap();
        assert_eq!((shown, spec.pre_samples, spec.decimation), (2, 8, 1));
        let depth = controller_core::capture::RECORD_SAMPLES as u16;
        assert!(capture_spec(&capture(depth, "i_a", None)).unwrap_err().starts_with("--pre"));
        assert!(capture_spec(&capture(0, "no_such_signal", None)).unwrap_err().starts_with("--signals"));
        assert!(capture_spec(&capture(0, "i_a", Some("jump"))).unwrap_err().starts_with("--then"));
    }

    /// No command, or a status whose drive file is not there: an error, before any port.
    #[test]
    fn link_errors_come_before_the_port() {
        let mut a = LinkOptions { device: "/dev/no-such-port".into(), action: None, timeout_s: 1.0 };
        assert!(board_link(&a).unwrap_err().contains("which command?"));
        a.action = Some(LinkAction::Status { drive: PathBuf::from("no-such-drive.toml") });
        assert!(board_link(&a).unwrap_err().contains("no-such-drive.toml"));
        a.action = Some(LinkAction::Send(Command::GetStatus));
        assert!(board_link(&a).unwrap_err().starts_with("/dev/no-such-port"));
    }
}
