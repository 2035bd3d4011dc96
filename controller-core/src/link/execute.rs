//! Command execution: what a drive does with a [`Command`] — the policy shared by the
//! processor-in-the-loop server and the firmware.

use super::receive::LinkStats;
use super::schema::{Command, NackReason, Reply};
use crate::capture::{Capture, CaptureSpec};
use crate::drive::{CommandError, Drive, DriveConfig, Mode};

/// Carry out `cmd` on `drive` and say how it went — the command handling shared by the
/// processor-in-the-loop server and the firmware (which refuses `Step` itself: on the board
/// the measurements come from the ADC, and handles the speed-gain commands, which need the
/// specification and the certified ranges it keeps). `Configure` replaces the drive only while it is
/// Idle or faulted, with a configuration validated by [`DriveConfig::new`].
pub fn execute(drive: &mut Drive, cmd: &Command, stats: &LinkStats) -> Reply {
    match cmd {
        Command::Configure(spec) => {
            if matches!(drive.mode(), Mode::Magnetizing | Mode::Running) {
                return Reply::Nack(NackReason::NotIdle);
            }
            match DriveConfig::new(spec) {
                Ok(cfg) => {
                    *drive = Drive::new(cfg);
                    Reply::Ack
                }
                Err(_) => Reply::Nack(NackReason::Configuration),
            }
        }
        Command::Enable => command_result(drive.enable()),
        Command::Disable => {
            drive.disable();
            Reply::Ack
        }
        Command::ClearFault => {
            drive.clear_fault();
            Reply::Ack
        }
        Command::Stop => {
            drive.controlled_stop();
            Reply::Ack
        }
        Command::SetReference(r) => command_result(drive.set_reference(*r)),
        Command::Step(m) => Reply::Output(drive.step(m)),
        Command::GetStatus => {
            // The timing and readings are the board's to fill in (firmware `server`).
            Reply::Status {
                mode: drive.mode(),
                frames_ok: stats.frames_ok,
                frame_errors: stats.errors(),
                timing: super::schema::LoopTiming::default(),
                readings: super::schema::BoardReadings::default(),
            }
        }
        // Gains live in the specification, which the board keeps (firmware `server`).
        Command::WriteSpeedGains { .. } | Command::ReadSpeedGains => Reply::Nack(NackReason::Unsupported),
        // A drive does not commission; the endpoint that can (the PIL server) handles these.
        Command::Commission(_) | Command::GetCommissionRecord { .. } | Command::GetCommissionStage => {
            Reply::Nack(NackReason::Unsupported)
        }
        // The capture is the endpoint's, beside the drive ([`arm_capture`], [`read_capture`]).
        Command::ArmCapture(_) | Command::ReadCapture { .. } => Reply::Nack(NackReason::Unsupported),
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
    if usize::from(chunk) >= Capture::<DEPTH>::CHUNKS {
        return Reply::Nack(NackReason::NoRecord);
    }
    Reply::Capture {
        state: capture.state(),
        // At most 2 048 (`Capture::new`'s bound).
        samples: DEPTH as u16,
        chunk,
        bytes: capture.chunk(usize::from(chunk)).unwrap_or([0; crate::capture::CHUNK_BYTES]),
    }
}

fn command_result(r: Result<(), CommandError>) -> Reply {
    match r {
        Ok(()) => Reply::Ack,
        Err(CommandError::Faulted) => Reply::Nack(NackReason::Faulted),
        Err(CommandError::NonFinite) => Reply::Nack(NackReason::NonFinite),
    }
}
