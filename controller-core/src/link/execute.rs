//! Command execution: what a drive does with a [`Command`] — the policy shared by the
//! processor-in-the-loop server and the firmware.

use super::receive::LinkStats;
use super::schema::{BoardCommand, Command, NackReason, Reply};
use crate::capture::{CHUNK_BYTES, Capture, CaptureSpec, CaptureState};
use crate::drive::{CommandError, Drive, DriveConfig, DriveMut};

/// Carry out `cmd` on `drive` and say how it went — the command handling shared by the
/// processor-in-the-loop server and the firmware (which refuses `Step` itself: on the board
/// the measurements come from the ADC, and handles the speed-gain commands, which need the
/// specification and the certified ranges it keeps). `Configure` swaps the configuration only while the drive
/// is Idle or faulted, for one validated by [`DriveConfig::new`]: for the same motor keeping
/// the machine's state ([`Drive::reconfigure`]: its temperature, position and estimates; a
/// fault stays latched), for another a new drive (Idle).
pub fn execute(drive: &mut Drive, cmd: &Command, stats: &LinkStats) -> Reply {
    match cmd {
        Command::Configure(spec) => {
            if drive.mode().is_active() {
                return Reply::Nack(NackReason::NotIdle);
            }
            match DriveConfig::new(spec) {
                // The same motor (its field orientation and machine model): its state carries
                // over. Another: another drive, which only knows how long the rotor was left.
                Ok(cfg) if cfg.same_motor(drive.config()) => command_result(drive.reconfigure(cfg)),
                Ok(cfg) => {
                    drive.replace(cfg);
                    Reply::Ack
                }
                Err(_) => Reply::Nack(NackReason::Configuration),
            }
        }
        Command::Step(m) => Reply::Output(drive.step(m), drive.telemetry()),
        other => execute_board(drive.as_mut(), &BoardCommand::of(other), stats),
    }
}

/// [`execute`] for every command but `Configure` and `Step` ([`BoardCommand`], as the board
/// decodes them; `Refused` is `Nack(Unsupported)`): the firmware's commands, without the
/// ≈ 500 B [`Command`] built on the control interrupt's stack for them. `#[inline]`:
/// compiled in the caller's crate, the firmware's opt-level "z" for its commands (rare,
/// beside the control step in the interrupt; −56 B of flash).
#[inline]
pub fn execute_board(mut drive: DriveMut<'_>, cmd: &BoardCommand, stats: &LinkStats) -> Reply {
    match cmd {
        BoardCommand::Enable => command_result(drive.enable()),
        BoardCommand::Disable => {
            drive.disable();
            Reply::Ack
        }
        BoardCommand::ClearFault => {
            drive.clear_fault();
            Reply::Ack
        }
        BoardCommand::Stop => {
            drive.controlled_stop();
            Reply::Ack
        }
        BoardCommand::SetReference(r) => command_result(drive.set_reference(*r)),
        BoardCommand::GetStatus => {
            // The timing and readings are the board's to fill in (firmware `server`).
            Reply::Status {
                mode: drive.mode(),
                ridden_through: drive.ridden_through(),
                frames_ok: stats.frames_ok,
                frame_errors: stats.errors(),
                timing: super::schema::LoopTiming::default(),
                readings: super::schema::BoardReadings::default(),
            }
        }
        // Gains live in the specification, which the board keeps (firmware `server`).
        BoardCommand::WriteSpeedGains { .. } | BoardCommand::ReadSpeedGains => {
            Reply::Nack(NackReason::Unsupported)
        }
        // A drive does not commission; the endpoint that can (the PIL server) handles these.
        BoardCommand::Commission(_)
        | BoardCommand::GetCommissionRecord { .. }
        | BoardCommand::GetCommissionStage => Reply::Nack(NackReason::Unsupported),
        // The capture is the endpoint's, beside the drive ([`arm_capture`], [`read_capture`]).
        BoardCommand::ArmCapture(_) | BoardCommand::ReadCapture { .. } => {
            Reply::Nack(NackReason::Unsupported)
        }
        BoardCommand::Refused => Reply::Nack(NackReason::Unsupported),
    }
}

/// `ArmCapture`: `Ack`, or `Nack(Configuration)` for a spec the capture refuses.
pub fn arm_capture<const DEPTH: usize>(capture: &mut Capture<DEPTH>, spec: CaptureSpec) -> Reply {
    match capture.arm(spec) {
        Ok(()) => Reply::Ack,
        Err(_) => Reply::Nack(NackReason::Configuration),
    }
}

/// `ReadCapture { chunk }`: the state, and the chunk once the record is done (zeros
/// before); `Nack(NoRecord)` past the record's end.
pub fn read_capture<const DEPTH: usize>(capture: &Capture<DEPTH>, chunk: u8) -> Reply {
    capture_reply::<DEPTH>(capture.state(), chunk, capture.chunk(usize::from(chunk)))
}

/// `ReadCapture { chunk }`'s reply for a capture of `DEPTH` samples in `state`, with the
/// chunk's `bytes` (zeros without: the record not done) — also what an endpoint answers
/// while another context records into the capture; `Nack(NoRecord)` past the record's end.
pub fn capture_reply<const DEPTH: usize>(
    state: CaptureState,
    chunk: u8,
    bytes: Option<[u8; CHUNK_BYTES]>,
) -> Reply {
    if usize::from(chunk) >= Capture::<DEPTH>::CHUNKS {
        return Reply::Nack(NackReason::NoRecord);
    }
    Reply::Capture {
        state,
        // At most 2 048 (`Capture::new`'s bound).
        samples: DEPTH as u16,
        chunk,
        bytes: bytes.unwrap_or([0; CHUNK_BYTES]),
    }
}

fn command_result(r: Result<(), CommandError>) -> Reply {
    match r {
        Ok(()) => Reply::Ack,
        Err(CommandError::Faulted) => Reply::Nack(NackReason::Faulted),
        Err(CommandError::NonFinite) => Reply::Nack(NackReason::NonFinite),
        Err(CommandError::Active) => Reply::Nack(NackReason::NotIdle),
        Err(CommandError::NoEncoder) => Reply::Nack(NackReason::NoEncoder),
        Err(CommandError::SpeedOnly) => Reply::Nack(NackReason::SpeedOnly),
    }
}
