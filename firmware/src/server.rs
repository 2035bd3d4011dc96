//! Command handling of the board's link (LPUART1, `controller_core::link` frames — the same
//! as the processor-in-the-loop link).
//!
//! Accepted: `Enable`, `Disable`, `ClearFault`, `SetReference`, `GetStatus`. Refused with
//! `Nack(Unsupported)`: `Step` (on the board the ADC provides the measurements) and
//! `Configure` (the firmware runs the certified constants it was built with; writing gains
//! over the link is not implemented).

use crate::control::ControlLoop;
use controller_core::link::{self, Command, LinkStats, NackReason, Reply};

/// Answer one command.
pub fn handle(ctl: &mut ControlLoop, cmd: &Command, stats: &LinkStats) -> Reply {
    match cmd {
        Command::Step(_) | Command::Configure(_) => Reply::Nack(NackReason::Unsupported),
        other => link::execute(ctl.drive_mut(), other, stats),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::BOARD;
    use controller_core::drive::{Measurements, Mode, Reference, example_spec};

    #[test]
    fn commands_reach_the_drive_and_step_or_configure_are_refused() {
        let spec = example_spec().unwrap();
        let mut c = ControlLoop::new(&spec, &BOARD).unwrap();
        let stats = LinkStats { frames_ok: 5, crc: 2, ..Default::default() };
        assert_eq!(handle(&mut c, &Command::Enable, &stats), Reply::Ack);
        assert_eq!(c.drive().mode(), Mode::Magnetizing);
        assert_eq!(
            handle(&mut c, &Command::SetReference(Reference::Speed(f32::NAN)), &stats),
            Reply::Nack(NackReason::NonFinite)
        );
        assert_eq!(handle(&mut c, &Command::SetReference(Reference::Speed(100.0)), &stats), Reply::Ack);
        assert_eq!(
            handle(&mut c, &Command::Step(Measurements::default()), &stats),
            Reply::Nack(NackReason::Unsupported)
        );
        assert_eq!(handle(&mut c, &Command::Configure(spec), &stats), Reply::Nack(NackReason::Unsupported));
        assert_eq!(
            handle(&mut c, &Command::GetStatus, &stats),
            Reply::Status { mode: Mode::Magnetizing, frames_ok: 5, frame_errors: 2 }
        );
        assert_eq!(handle(&mut c, &Command::Disable, &stats), Reply::Ack);
        assert_eq!(c.drive().mode(), Mode::Idle);
    }
}
