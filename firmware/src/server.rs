//! Command handling of the board's link (LPUART1, `controller_core::link` frames — the same
//! as the processor-in-the-loop link).
//!
//! Accepted: `Enable`, `Disable`, `Stop` (a controlled stop), `ClearFault`, `SetReference`, `GetStatus`,
//! `ReadSpeedGains`, and `WriteSpeedGains` while Idle with both values inside the ranges
//! certified in `drive.toml` ([`crate::config`]; `Nack(OutOfCertifiedRange)` otherwise).
//! Refused with `Nack(Unsupported)`: `Step` (on the board the ADC provides the
//! measurements) and `Configure` (the rest of the constants are the certified ones the
//! firmware was built with).
//!
//! **Who serves what** (issue 54's two contexts): the drive's commands are the drive's slow
//! context's ([`slow_context_serves`], [`drive_command`]: after the slow step's job, on the
//! slow side alone; a command's effect on the bridge comes with the plan's adoption, a
//! plan's delay after its tick), so that their work — a gain write rebuilds the drive's
//! configuration, an enable a run — never lengthens a control period; the capture's are the
//! link task's own, in thread mode ([`link_task_serves`], `crate::scope`); the
//! commissioning's the control interrupt's ([`handle_board`]), which owns the sequence.
//!
//! Commissioning (feature `commissioning`; without it these commands are answered
//! `Nack(Unsupported)`): `Commission` while Idle and calibrated
//! starts the sequence in the drive's place — its configuration built by [`prepare`]
//! in the link task, swapped in by [`handle_board`];
//! `GetCommissionStage` and `GetCommissionRecord` report it; `Stop` or `Disable` abort it,
//! and nothing else reaches the drive while it runs (`Nack(NotIdle)`).

use crate::config as certified;
#[cfg(feature = "commissioning")]
use crate::control::CommissionRefused;
use crate::control::ControlLoop;
use controller_core::commission::{CommissionConfig, CommissionSpecError};
use controller_core::drive::{DriveMut, Mode};
use controller_core::link::{self, BoardCommand, BoardReadings, LinkStats, LoopTiming, NackReason, Reply};

/// The link's watchdog: no valid frame for `timeout_us` while the bridge is on (Magnetizing
/// or Running) → one controlled stop ([`controller_core::drive::Drive::controlled_stop`]);
/// a frame re-arms it. `timeout_us` = 0: off. Times are a free-running microsecond counter,
/// wrapping every 71.6 min (the firmware's: embassy's 1 MHz ticks, no division on the
/// target), so a timeout must stay below 2^32 µs (the drive file's at most 3 600 s).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkWatchdog {
    timeout_us: u32,
    last_us: u32,
    fired: bool,
}

impl LinkWatchdog {
    /// Armed from `now_us`.
    pub const fn new(timeout_us: u32, now_us: u32) -> Self {
        Self { timeout_us, last_us: now_us, fired: false }
    }

    /// A valid frame arrived.
    pub fn frame(&mut self, now_us: u32) {
        self.last_us = now_us;
        self.fired = false;
    }

    /// Check at `now_us`; stops the drive (once) when the link has been silent too long.
    /// Returns whether it did.
    pub fn poll(&mut self, now_us: u32, ctl: &mut ControlLoop) -> bool {
        let due = self.due(now_us, ctl.snapshot().bridge_on);
        if due {
            Self::stop(ctl);
        }
        due
    }

    /// Whether to stop now, with the bridge on or not (`control::Snapshot::bridge_on`): once
    /// per silence, then [`LinkWatchdog::stop`] does it. The firmware's link task asks this
    /// without touching the control loop and takes it only to stop.
    pub fn due(&mut self, now_us: u32, bridge_on: bool) -> bool {
        if self.timeout_us == 0
            || self.fired
            || !bridge_on
            || now_us.wrapping_sub(self.last_us) < self.timeout_us
        {
            return false;
        }
        self.fired = true;
        true
    }

    /// The watchdog's reaction: a controlled stop, and any commissioning sequence aborted.
    /// False when the stop must wait for a period with the drive's slow side back (the
    /// sequence is aborted at once).
    pub fn stop(ctl: &mut ControlLoop) -> bool {
        ctl.abort_commissioning();
        ctl.drive_mut(|mut d| d.controlled_stop()).is_some()
    }
}

/// The work a command needs before it reaches the control loop, done outside the critical
/// section: a commissioning sequence's configuration.
// Lives only between `prepare` and `handle_board`, on the link task's stack; no heap to box
// the configuration (≈ 220 B) in.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Prepared {
    /// Nothing to prepare.
    Nothing,
    /// `Commission`'s configuration, or why its spec was rejected.
    Commission(Result<CommissionConfig, CommissionSpecError>),
}

/// Prepare `cmd` in the link task (then [`handle_board`] in the control interrupt).
pub fn prepare(cmd: &BoardCommand) -> Prepared {
    match cmd {
        #[cfg(feature = "commissioning")]
        BoardCommand::Commission(spec) => Prepared::Commission(CommissionConfig::new(*spec)),
        _ => Prepared::Nothing,
    }
}

/// Answer one command in the control interrupt, as the board decodes it
/// ([`Command::decode_board`](controller_core::link::Command::decode_board): `Configure` and
/// `Step` arrive unparsed, as [`BoardCommand::Refused`]), with what [`prepare`] built: the
/// capture's and the commissioning's — and the drive's while a commissioning sequence runs
/// (`Stop` or `Disable` aborts it, `GetStatus` reports, the rest is refused). `None` for the
/// drive's commands otherwise: they are the slow context's ([`slow_context_serves`],
/// [`drive_command`]), and stay posted for it.
pub fn handle_board(
    ctl: &mut ControlLoop,
    cmd: &BoardCommand,
    prepared: Prepared,
    stats: &LinkStats,
) -> Option<Reply> {
    Some(match (cmd, prepared) {
        #[cfg(feature = "commissioning")]
        (BoardCommand::Commission(_), Prepared::Commission(cfg)) => {
            match cfg.map(|c| ctl.start_commissioning(c)) {
                Ok(Ok(())) => Reply::Ack,
                Ok(Err(CommissionRefused::NotIdle)) => Reply::Nack(NackReason::NotIdle),
                Ok(Err(CommissionRefused::NotCalibrated)) => Reply::Nack(NackReason::NotConfigured),
                Ok(Err(CommissionRefused::RotorTurning)) => Reply::Nack(NackReason::NotAtRest),
                Err(_) => Reply::Nack(NackReason::Configuration),
            }
        }
        // Not prepared: refused rather than built inside the interrupt.
        #[cfg(feature = "commissioning")]
        (BoardCommand::Commission(_), _) => Reply::Nack(NackReason::Configuration),
        #[cfg(feature = "commissioning")]
        (BoardCommand::GetCommissionStage, _) => {
            ctl.commission_output().map_or(Reply::Nack(NackReason::NoRecord), Reply::Commission)
        }
        #[cfg(feature = "commissioning")]
        (BoardCommand::GetCommissionRecord { chunk }, _) => {
            link::record_chunk(ctl.commission_record(), *chunk)
        }
        #[cfg(not(feature = "commissioning"))]
        (
            BoardCommand::Commission(_)
            | BoardCommand::GetCommissionStage
            | BoardCommand::GetCommissionRecord { .. },
            _,
        ) => Reply::Nack(NackReason::Unsupported),
        // The link task's, never posted ([`link_task_serves`]).
        (BoardCommand::ArmCapture(_) | BoardCommand::ReadCapture { .. }, _) => {
            Reply::Nack(NackReason::Unsupported)
        }
        _ if !ctl.commissioning() => return None,
        (BoardCommand::Stop | BoardCommand::Disable, _) => {
            ctl.abort_commissioning();
            Reply::Ack
        }
        (BoardCommand::GetStatus, _) => Reply::Status {
            mode: ctl.fast().mode(),
            ridden_through: ctl.drive(|d| d.ridden_through())?,
            frames_ok: stats.frames_ok,
            frame_errors: stats.errors(),
            timing: LoopTiming::default(),
            readings: ctl.readings(),
        },
        _ => Reply::Nack(NackReason::NotIdle),
    })
}

/// A command answered at once in the fast context (the host tests' link): the capture's by
/// the scope ([`crate::scope::Scope::serve`], as the link task does), the drive's with both
/// halves ([`drive_command`] on [`ControlLoop::drive_mut`]: `None` while the slow step is
/// in flight), the rest as the control interrupt does ([`handle_board`]).
#[cfg(test)]
pub(crate) fn serve_at_once(
    ctl: &mut ControlLoop,
    cmd: &BoardCommand,
    prepared: Prepared,
    stats: &LinkStats,
) -> Option<Reply> {
    if link_task_serves(cmd) {
        ctl.scope().serve(cmd)
    } else if slow_context_serves(cmd) && !ctl.commissioning() {
        let readings = ctl.readings();
        ctl.drive_mut(|d| drive_command(d, cmd, stats, readings))
    } else {
        handle_board(ctl, cmd, prepared, stats)
    }
}

/// Whether the link task serves `cmd` itself, never posting it: the capture's
/// ([`crate::scope::Scope::serve`]: arming and reading out in thread mode).
pub fn link_task_serves(cmd: &BoardCommand) -> bool {
    matches!(cmd, BoardCommand::ArmCapture(_) | BoardCommand::ReadCapture { .. })
}

/// Whether the drive's slow context serves `cmd` ([`crate::control::SlowLink::serve`],
/// after the slow step's job, on the slow side alone): the drive's commands and reads — they
/// act on the slow side, and their work (a gain write rebuilds the configuration, an enable
/// a run) stays out of the control interrupt. The commissioning's are the control
/// interrupt's ([`handle_board`]): they act on what it owns; the capture's the link task's
/// ([`link_task_serves`]).
pub fn slow_context_serves(cmd: &BoardCommand) -> bool {
    match cmd {
        BoardCommand::Enable
        | BoardCommand::Disable
        | BoardCommand::ClearFault
        | BoardCommand::Stop
        | BoardCommand::SetReference(_)
        | BoardCommand::GetStatus
        | BoardCommand::WriteSpeedGains { .. }
        | BoardCommand::ReadSpeedGains
        | BoardCommand::Refused => true,
        BoardCommand::Commission(_)
        | BoardCommand::GetCommissionRecord { .. }
        | BoardCommand::GetCommissionStage
        | BoardCommand::ArmCapture(_)
        | BoardCommand::ReadCapture { .. } => false,
    }
}

/// Answer one of the drive's commands on `d` ([`slow_context_serves`]): the slow context's
/// (on the slow side alone, [`DriveMut::slow_only`]: the command's fast part at the plan's
/// adoption) or the fast context's (at once). `Status` carries the board's raw `readings`
/// (its timing is filled in by the link task). The gain write keeps the slow divider
/// ([`DriveMut::write_speed_gains`] changes the speed law and the stall check's limit
/// alone): the board's encoder estimator, which reads at that period, needs no change.
pub fn drive_command(
    d: DriveMut<'_>,
    cmd: &BoardCommand,
    stats: &LinkStats,
    readings: BoardReadings,
) -> Reply {
    match cmd {
        BoardCommand::ReadSpeedGains => match d.config().speed().saturated_p() {
            Some((kp, tau_max_nm)) => Reply::SpeedGains { kp, tau_max_nm },
            None => Reply::Nack(NackReason::Unsupported),
        },
        BoardCommand::WriteSpeedGains { kp, tau_max_nm } => write_speed_gains(d, *kp, *tau_max_nm),
        other => match link::execute_board(d, other, stats) {
            Reply::Status { mode, ridden_through, frames_ok, frame_errors, timing, .. } => {
                Reply::Status { mode, ridden_through, frames_ok, frame_errors, timing, readings }
            }
            r => r,
        },
    }
}

fn write_speed_gains(mut d: DriveMut<'_>, kp: f32, tau_max_nm: f32) -> Reply {
    if !(kp.is_finite() && tau_max_nm.is_finite()) {
        return Reply::Nack(NackReason::NonFinite);
    }
    let inside = |x: f32, (lo, hi): (f32, f32)| lo <= x && x <= hi;
    if !inside(kp, certified::SPEED_KP) || !inside(tau_max_nm, certified::SPEED_TAU_MAX_NM) {
        return Reply::Nack(NackReason::OutOfCertifiedRange);
    }
    if d.mode() != Mode::Idle {
        return Reply::Nack(NackReason::NotIdle);
    }
    // In f32, on the configuration in use: no design arithmetic on the target.
    match d.write_speed_gains(kp, tau_max_nm) {
        None => Reply::Nack(NackReason::Unsupported),
        Some(Ok(())) => Reply::Ack,
        Some(Err(_)) => Reply::Nack(NackReason::Configuration),
    }
}

#[cfg(test)]
mod tests {
    /// The command's reply, served in a period with the slow side back (the tests' loops
    /// run the slow step's job at its tick).
    fn handle(c: &mut ControlLoop, cmd: &BoardCommand, s: &LinkStats) -> Reply {
        serve_at_once(c, cmd, Prepared::Nothing, s).expect("served")
    }

    fn handle_board(c: &mut ControlLoop, cmd: &BoardCommand, p: Prepared, s: &LinkStats) -> Reply {
        serve_at_once(c, cmd, p, s).expect("served")
    }

    use super::*;
    use crate::config::{BOARD, DRIVE_CONFIG, drive_spec};
    use crate::control::run_slow;
    use crate::control::tests::cell;
    use controller_core::drive::{Measurements, Reference};
    use controller_core::link::Command;

    #[test]
    fn commands_reach_the_drive_and_step_or_configure_are_refused() {
        let spec = drive_spec().unwrap();
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        let stats = LinkStats { frames_ok: 5, crc: 2, ..Default::default() };
        assert_eq!(handle(&mut c, &BoardCommand::Enable, &stats), Reply::Ack);
        assert_eq!(c.fast().mode(), Mode::Magnetizing);
        assert_eq!(
            handle(&mut c, &BoardCommand::SetReference(Reference::Speed(f32::NAN)), &stats),
            Reply::Nack(NackReason::NonFinite)
        );
        assert_eq!(handle(&mut c, &BoardCommand::SetReference(Reference::Speed(100.0)), &stats), Reply::Ack);
        assert_eq!(
            handle(&mut c, &BoardCommand::of(&Command::Step(Measurements::default())), &stats),
            Reply::Nack(NackReason::Unsupported)
        );
        assert_eq!(
            handle(&mut c, &BoardCommand::of(&Command::Configure(spec)), &stats),
            Reply::Nack(NackReason::Unsupported)
        );
        // The interrupt notes the raw samples of the period that serves a command.
        c.note_readings(&crate::control::Samples {
            i_abc: [2048; 3],
            vdc: 3100,
            encoder: 7,
            hardware_break: false,
        });
        assert_eq!(
            handle(&mut c, &BoardCommand::GetStatus, &stats),
            Reply::Status {
                mode: Mode::Magnetizing,
                ridden_through: controller_core::drive::FaultSet::EMPTY,
                frames_ok: 5,
                frame_errors: 2,
                timing: Default::default(),
                readings: link::BoardReadings {
                    i_abc_counts: [2048; 3],
                    vdc_counts: 3100,
                    encoder_counts: 7
                },
            }
        );
        assert_eq!(handle(&mut c, &BoardCommand::Disable, &stats), Reply::Ack);
        assert_eq!(c.fast().mode(), Mode::Idle);
    }

    /// On the wire: `Configure` and `Step` frames are refused unparsed (the board decodes no
    /// motor in f64), every other command as the host encoded it.
    #[test]
    fn the_board_refuses_configure_and_step_frames_unparsed() {
        let spec = drive_spec().unwrap();
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        let mut stats = LinkStats::default();
        let mut decoder = link::FrameDecoder::new();
        let mut reply = |cmd: &Command, c: &mut ControlLoop, stats: &mut LinkStats| {
            let mut f = [0u8; link::MAX_FRAME];
            let n = link::command_frame(cmd, &mut f).unwrap();
            let mut got = None;
            for &b in &f[..n] {
                if let Some(bc) = decoder.push_board_command(b, stats) {
                    got = Some(handle_board(c, &bc, prepare(&bc), stats));
                }
            }
            got
        };
        let unsupported = Some(Reply::Nack(NackReason::Unsupported));
        assert_eq!(reply(&Command::Configure(spec), &mut c, &mut stats), unsupported);
        assert_eq!(reply(&Command::Step(Measurements::default()), &mut c, &mut stats), unsupported);
        // No sequence ran: no record (without the feature: not supported).
        let no_record = Some(Reply::Nack(if cfg!(feature = "commissioning") {
            NackReason::NoRecord
        } else {
            NackReason::Unsupported
        }));
        assert_eq!(reply(&Command::GetCommissionRecord { chunk: 0 }, &mut c, &mut stats), no_record);
        assert_eq!(reply(&Command::Enable, &mut c, &mut stats), Some(Reply::Ack));
        assert_eq!(c.fast().mode(), Mode::Magnetizing);
        assert_eq!(stats.frames_ok, 4);
        assert_eq!(link::Command::decode_board(&[0x7E]), Err(link::DecodeError::UnknownType(0x7E)));
    }

    /// The scope on the board, over the wire: armed on the measured current a rising through
    /// 1 A with 4 pre-trigger samples, every 2nd period; the record holds the control loop's
    /// own readings of the board's ADC codes, the trigger's sample at index 4; a gain write
    /// meanwhile keeps it (and the measured offsets); a bad spec and a chunk past the end are
    /// refused.
    #[test]
    fn the_capture_records_the_control_loops_periods_and_reads_out_over_the_link() {
        use crate::control::{CAPTURE_DEPTH, Samples};
        use controller_core::capture::{CaptureSpec, CaptureState, Edge, Signal, Trigger};
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        let mut stats = LinkStats::default();
        let mut decoder = link::FrameDecoder::new();
        let mut reply = |cmd: &Command, c: &mut ControlLoop| {
            let mut f = [0u8; link::MAX_FRAME];
            let n = link::command_frame(cmd, &mut f).unwrap();
            let mut got = None;
            for &b in &f[..n] {
                if let Some(bc) = decoder.push_board_command(b, &mut stats) {
                    got = handle_board(c, &bc, prepare(&bc), &stats).into();
                }
            }
            got.unwrap()
        };
        let trigger = Trigger::Level { signal: Signal::IA, edge: Edge::Rising, level: 1.0 };
        let spec = CaptureSpec {
            signals: [Signal::IA, Signal::IB, Signal::Vdc, Signal::Mode],
            trigger,
            pre_samples: 4,
            decimation: 2,
        };
        let bad = CaptureSpec { pre_samples: CAPTURE_DEPTH as u16, ..spec };
        assert_eq!(reply(&Command::ArmCapture(bad), &mut c), Reply::Nack(NackReason::Configuration));
        assert_eq!(reply(&Command::ArmCapture(spec), &mut c), Reply::Ack);
        // Phase a's code climbs one count per period from the offset: i_a = k·16.5/2048 A,
        // above 1 A from k = 125 (the 125th period is odd: the first sample above is k = 126).
        let a_per_count = BOARD.current_a_per_count;
        let offset = BOARD.current_offset_counts;
        let samples = |k: u16| Samples {
            i_abc: [offset + k, offset - k, offset],
            vdc: 3100,
            encoder: 0,
            hardware_break: false,
        };
        for k in 0..1000u16 {
            let _ = c.step(&samples(k));
            if k == 300 {
                // A gain write while it records: the capture and the offsets carry over.
                let (kp, tau) = (crate::config::SPEED_KP.0, crate::config::SPEED_TAU_MAX_NM.0);
                let w = Command::WriteSpeedGains { kp, tau_max_nm: tau };
                assert_eq!(reply(&w, &mut c), Reply::Ack);
                assert!(matches!(c.snapshot().calibration, Some(crate::control::Calibration::Done(_))));
            }
        }
        let chunks = CAPTURE_DEPTH / controller_core::capture::CHUNK_SAMPLES;
        let mut record = [0.0f32; 4 * CAPTURE_DEPTH];
        for (k, part) in record.chunks_exact_mut(32).enumerate() {
            match reply(&Command::ReadCapture { chunk: k as u8 }, &mut c) {
                Reply::Capture { state: CaptureState::Done, samples, chunk, bytes } => {
                    assert_eq!((usize::from(samples), usize::from(chunk)), (CAPTURE_DEPTH, k));
                    for (x, b) in part.iter_mut().zip(bytes.chunks_exact(4)) {
                        *x = f32::from_le_bytes(b.try_into().unwrap());
                    }
                }
                r => panic!("chunk {k}: {r:?}"),
            }
        }
        assert_eq!(
            reply(&Command::ReadCapture { chunk: chunks as u8 }, &mut c),
            Reply::Nack(NackReason::NoRecord)
        );
        // Sample j is period 118 + 2j: the trigger's (j = 4) is period 126.
        for (j, s) in record.chunks_exact(4).enumerate() {
            let k = 118 + 2 * j as u16;
            let i_a = f32::from(k) * a_per_count;
            assert!((s[0] - i_a).abs() < 1e-4, "sample {j}: {} A, period {k}: {i_a} A", s[0]);
            assert!((s[1] + i_a).abs() < 1e-4);
            assert_eq!(s[2], 310.0);
            assert_eq!(s[3], 0.0, "Idle");
        }
        assert!(record[4 * 3] < 1.0 && record[4 * 4] >= 1.0);
    }

    /// The watchdog stops a running drive once after `timeout` µs of silence (the drive then
    /// brakes: it is stopping, still Running), not before, not while Idle, and a frame
    /// re-arms it; the counter may wrap.
    #[test]
    fn a_silent_link_stops_a_running_drive() {
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        let start = u32::MAX - 100; // wraps during the test
        let mut w = LinkWatchdog::new(1000, start);
        assert!(!w.poll(start.wrapping_add(5000), &mut c), "Idle: nothing to stop");
        c.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        // Magnetizing: a controlled stop turns the bridge off at once.
        w.frame(start);
        assert!(!w.poll(start.wrapping_add(999), &mut c));
        assert!(w.poll(start.wrapping_add(1000), &mut c));
        assert_eq!(c.fast().mode(), Mode::Idle);
        assert!(!w.poll(start.wrapping_add(2000), &mut c), "once");
        // Re-armed by a frame: a second silence stops the drive again.
        c.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        w.frame(start.wrapping_add(3000));
        assert!(!w.poll(start.wrapping_add(3999), &mut c));
        assert!(w.poll(start.wrapping_add(4000), &mut c));
        let off = LinkWatchdog::new(0, start);
        assert_eq!(off, LinkWatchdog { timeout_us: 0, last_us: start, fired: false });
        assert!(!{ off }.poll(start.wrapping_add(1_000_000), &mut c));
        assert_eq!(certified::LINK_TIMEOUT_MS, 1000, "drive.toml link_timeout_s");
    }

    #[test]
    fn speed_gains_are_written_only_inside_the_certified_ranges_and_while_idle() {
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        let s = LinkStats::default();
        let read = |c: &mut ControlLoop| handle(c, &BoardCommand::ReadSpeedGains, &s);
        assert_eq!(read(&mut c), Reply::SpeedGains { kp: 0.05, tau_max_nm: 2.0 });
        let (kp_lo, kp_hi) = certified::SPEED_KP;
        let (tau_lo, tau_hi) = certified::SPEED_TAU_MAX_NM;
        assert!((kp_lo, kp_hi, tau_lo, tau_hi) == (0.04, 0.1, 0.1, 2.0), "drive.toml ranges");
        let write = |c: &mut ControlLoop, kp: f32, tau: f32| {
            handle(c, &BoardCommand::WriteSpeedGains { kp, tau_max_nm: tau }, &s)
        };
        let out = Reply::Nack(NackReason::OutOfCertifiedRange);
        assert_eq!(write(&mut c, kp_hi * 1.01, 1.0), out);
        assert_eq!(write(&mut c, kp_lo * 0.99, 1.0), out);
        assert_eq!(write(&mut c, 0.05, tau_hi + 0.1), out);
        assert_eq!(write(&mut c, f32::NAN, 1.0), Reply::Nack(NackReason::NonFinite));
        assert_eq!(read(&mut c), Reply::SpeedGains { kp: 0.05, tau_max_nm: 2.0 }, "unchanged");
        assert_eq!(write(&mut c, kp_hi, 1.5), Reply::Ack);
        assert_eq!(read(&mut c), Reply::SpeedGains { kp: kp_hi, tau_max_nm: 1.5 });
        // Not while the bridge is active.
        assert_eq!(handle(&mut c, &BoardCommand::Enable, &s), Reply::Ack);
        assert_eq!(write(&mut c, 0.05, 1.0), Reply::Nack(NackReason::NotIdle));
    }

    /// A gain write is a new configuration for the same motor on the same board: the motor's
    /// and the inverter's I²t state (their temperature) and the encoder's turn count carry
    /// over. Found by reading (issue 48): the write rebuilt the drive, and a user could cool
    /// a hot motor's protection by writing gains.
    #[test]
    fn a_gain_write_keeps_the_thermal_state_and_the_position() {
        use crate::control::Samples;
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        let s = LinkStats::default();
        // 2 A in phase a and back through b, with the bridge off (the models integrate the
        // measured current in every mode): 1.9 × the motor's rated RMS current for ten thermal
        // updates (5 s of its 900 s time constant: θ ≈ 0.019), and the shaft turned by a
        // revolution and a bit.
        let zero = BOARD.current_offset_counts;
        let counts = (2.0 / BOARD.current_a_per_count) as u16;
        let lines = 4 * BOARD.encoder_lines;
        let periods = 10 * 1000 * u32::from(c.config().slow_divider());
        for k in 0..periods {
            let encoder = (k * (lines + 17) / periods) as u16;
            let hot = Samples {
                i_abc: [zero + counts, zero - counts, zero],
                vdc: 3100,
                encoder,
                hardware_break: false,
            };
            let _ = c.step(&hot);
        }
        assert_eq!(c.fast().mode(), Mode::Idle);
        let (motor, inverter) = c.drive(|d| d.thermal_state()).unwrap();
        assert!(motor > 0.015 && inverter > 0.005, "heated: {motor} {inverter}");
        let position = c.drive(|d| d.position_rad()).unwrap();
        assert!(position > core::f32::consts::TAU, "one turn and more: {position}");
        assert_eq!(
            handle(&mut c, &BoardCommand::WriteSpeedGains { kp: 0.08, tau_max_nm: 1.5 }, &s),
            Reply::Ack
        );
        assert_eq!(c.config().speed().saturated_p(), Some((0.08, 1.5)), "the gains written");
        assert_eq!(
            c.drive(|d| d.thermal_state()).unwrap(),
            (motor, inverter),
            "the motor is as hot as before"
        );
        assert_eq!(c.drive(|d| d.position_rad()).unwrap(), position, "the shaft is where it was");
    }

    /// A standstill commissioning of the shipped motor on its board (the tests' request).
    #[cfg(feature = "commissioning")]
    fn commission_spec() -> controller_core::commission::CommissionSpec {
        controller_core::commission::CommissionSpec {
            pwm_hz: 20_000.0,
            test_current_a: 1.0,
            current_limit_a: 2.0,
            vdc_min_v: 250.0,
            vdc_max_v: 370.0,
            level_time_s: 1.0,
            rotate: false,
            rated_flux_wb: 0.823,
            no_load_hz: 15.0,
            curve: false,
        }
    }

    /// The rotor-at-rest check before commissioning (`controller_core::supervisor::rest`):
    /// a coasting rotor — the encoder turning at twice the rest speed `0.05/(p·T_r)` — is
    /// refused `NotAtRest`; once it has stood still for the check's windows, the same command
    /// starts the sequence. The rotor turning slower than the rest speed is at rest.
    #[cfg(feature = "commissioning")]
    #[test]
    fn commissioning_is_refused_while_the_rotor_turns() {
        use crate::control::Samples;
        use controller_core::supervisor::rest::REST_SPEED_TR;
        let spec = commission_spec();
        let cmd = BoardCommand::Commission(spec);
        let stats = LinkStats::default();
        let motor = drive_spec().unwrap().motor;
        let rest_rad_s = REST_SPEED_TR / (f64::from(motor.pole_pairs()) * motor.tr_s());
        let counts_per_rad = 4.0 * f64::from(BOARD.encoder_lines) / core::f64::consts::TAU;
        let zero = BOARD.current_offset_counts;
        // `periods` PWM periods of the encoder turning at `w_rad_s` from `counts0`.
        let turn = |c: &mut ControlLoop, counts0: f64, w_rad_s: f64, periods: u32| {
            let mut counts = counts0;
            for _ in 0..periods {
                counts += w_rad_s * counts_per_rad / spec.pwm_hz as f64;
                let encoder = (counts.rem_euclid(65_536.0)) as u16;
                let _ = c.step(&Samples { i_abc: [zero; 3], vdc: 3100, encoder, hardware_break: false });
            }
            counts
        };
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        let counts = turn(&mut c, 0.0, 2.0 * rest_rad_s, 20_000);
        assert!(!c.drive(|d| d.rotor_at_rest()).unwrap());
        assert_eq!(handle_board(&mut c, &cmd, prepare(&cmd), &stats), Reply::Nack(NackReason::NotAtRest));
        assert!(!c.commissioning());
        turn(&mut c, counts, 0.5 * rest_rad_s, 20_000);
        assert!(c.drive(|d| d.rotor_at_rest()).unwrap(), "creeping at half the rest speed");
        assert_eq!(handle_board(&mut c, &cmd, prepare(&cmd), &stats), Reply::Ack);
        assert!(c.commissioning());
    }

    /// Commissioning on the board (feature `commissioning`): refused until the offsets are
    /// calibrated, then the sequence takes the bridge (off during its own offsets, switching
    /// from its first pulse), reports its stage, refuses other commands, and a hardware
    /// break or a `Stop` ends it with the bridge off for good.
    #[cfg(feature = "commissioning")]
    #[test]
    fn commissioning_takes_the_bridge_and_a_break_or_stop_ends_it() {
        use crate::control::{Bridge, Samples};
        use controller_core::commission::{CommissionSpec, Refusal, Stage};
        let spec = commission_spec();
        let cmd = BoardCommand::Commission(spec);
        let stats = LinkStats::default();
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        assert_eq!(handle_board(&mut c, &cmd, prepare(&cmd), &stats), Reply::Nack(NackReason::NotConfigured));
        c.calibrate_at_rest();
        assert_eq!(
            handle_board(&mut c, &cmd, Prepared::Nothing, &stats),
            Reply::Nack(NackReason::Configuration)
        );
        let bad = BoardCommand::Commission(CommissionSpec { test_current_a: -1.0, ..spec });
        assert_eq!(handle_board(&mut c, &bad, prepare(&bad), &stats), Reply::Nack(NackReason::Configuration));
        assert_eq!(handle_board(&mut c, &cmd, prepare(&cmd), &stats), Reply::Ack);
        assert!(c.commissioning());
        assert_eq!(
            handle_board(&mut c, &BoardCommand::Enable, Prepared::Nothing, &stats),
            Reply::Nack(NackReason::NotIdle)
        );
        let zero = BOARD.current_offset_counts;
        let at_rest = Samples { i_abc: [zero; 3], vdc: 3100, encoder: 0, hardware_break: false };
        let first = (0..4000).find(|_| matches!(c.step(&at_rest), Bridge::Compare(_)));
        // The sequence's own offsets (2 048 periods) with the bridge off, then the first pulse.
        assert_eq!(first, Some(controller_core::commission::OFFSET_PERIODS as usize));
        let stage = handle_board(&mut c, &BoardCommand::GetCommissionStage, Prepared::Nothing, &stats);
        assert!(matches!(stage, Reply::Commission(o) if o.stage == Stage::Pulse(0)), "{stage:?}");
        // A hardware break: the drive latches it, the sequence ends, the bridge stays off.
        assert_eq!(c.step(&Samples { hardware_break: true, ..at_rest }), Bridge::Off);
        assert!(!c.commissioning());
        for _ in 0..100 {
            assert_eq!(c.step(&at_rest), Bridge::Off);
        }
        let stage = handle_board(&mut c, &BoardCommand::GetCommissionStage, Prepared::Nothing, &stats);
        assert!(
            matches!(stage, Reply::Commission(o) if o.stage == Stage::Refused(Refusal::Aborted)),
            "{stage:?}"
        );
        // A new one on a healthy drive, stopped from the link.
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        assert_eq!(handle_board(&mut c, &cmd, prepare(&cmd), &stats), Reply::Ack);
        assert_eq!(handle_board(&mut c, &BoardCommand::Stop, Prepared::Nothing, &stats), Reply::Ack);
        assert!(!c.commissioning());
        assert_eq!(c.step(&at_rest), Bridge::Off);
        let record =
            handle_board(&mut c, &BoardCommand::GetCommissionRecord { chunk: 0 }, Prepared::Nothing, &stats);
        assert_eq!(record, Reply::Nack(NackReason::NoRecord));
    }
}
