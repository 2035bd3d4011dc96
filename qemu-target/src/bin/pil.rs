//! Processor-in-the-loop server: the drive — or the commissioning sequence — on the emulated
//! Cortex-M4F, one link frame per PWM period with `hil-sim pil` / `hil-sim identify --pil`
//! (see the crate docs). The capture ([`controller_core::capture`], the firmware's depth)
//! records every drive `Step`, as the firmware's control interrupt does. Exits with status 0 when the host closes
//! `to_mcu`, 1 if the FIFOs cannot be opened or a reply cannot be written.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use controller_core::capture::{Capture, RECORD_SAMPLES};
    use controller_core::commission::{CommissionConfig, CommissionOutput, Commissioning};
    use controller_core::drive::{Drive, DriveConfig};
    use controller_core::link::{self, Command, FrameDecoder, LinkStats, MAX_FRAME, NackReason, Reply};
    use cortex_m_rt::entry;
    use qemu_target::sh;

    /// What the server runs: nothing yet, a drive (`Configure`), or a commissioning
    /// sequence (`Commission`).
    // One value for the program's life, on main's stack (which has room): no heap to box
    // the sequence's record in.
    #[allow(clippy::large_enum_variant)]
    enum Endpoint {
        None,
        Drive(Drive),
        Commission(Commissioning, Option<CommissionOutput>),
    }

    #[entry]
    fn main() -> ! {
        let (Some(rx), Some(tx)) = (sh::open(c"to_mcu", false), sh::open(c"from_mcu", true)) else {
            qemu_target::println!("pil: cannot open the FIFOs to_mcu/from_mcu");
            sh::exit(false)
        };
        // Until the host sends `Configure` or `Commission`, only those and `GetStatus`-like
        // queries are answered (`Nack(NotConfigured)`).
        let mut endpoint = Endpoint::None;
        let mut capture = Capture::<RECORD_SAMPLES>::new();
        let mut stats = LinkStats::default();
        let mut decoder = FrameDecoder::new();
        let mut input = [0u8; 256];
        let mut frame = [0u8; MAX_FRAME];
        loop {
            let n = rx.read(&mut input);
            if n == 0 {
                sh::exit(true);
            }
            for &byte in input.iter().take(n) {
                let Some(cmd) = decoder.push_command(byte, &mut stats) else { continue };
                let reply = match (&mut endpoint, &cmd) {
                    (_, Command::Commission(spec)) => match CommissionConfig::new(*spec) {
                        Ok(cfg) => {
                            endpoint = Endpoint::Commission(Commissioning::new(cfg), None);
                            Reply::Ack
                        }
                        Err(_) => Reply::Nack(NackReason::Configuration),
                    },
                    (Endpoint::Commission(c, last), Command::Step(m)) => {
                        let out = c.step(m);
                        *last = Some(out);
                        Reply::Commission(out)
                    }
                    (Endpoint::Commission(c, _), Command::Stop | Command::Disable) => {
                        c.abort();
                        Reply::Ack
                    }
                    (Endpoint::Commission(c, _), Command::GetCommissionRecord { chunk }) => {
                        link::record_chunk(c.record(), *chunk)
                    }
                    (Endpoint::Commission(_, last), Command::GetCommissionStage) => {
                        last.map_or(Reply::Nack(NackReason::NoRecord), Reply::Commission)
                    }
                    (_, Command::ArmCapture(spec)) => link::arm_capture(&mut capture, *spec),
                    (_, Command::ReadCapture { chunk }) => link::read_capture(&capture, *chunk),
                    (Endpoint::Drive(d), Command::Step(m)) => {
                        let out = d.step(m);
                        let telemetry = d.telemetry();
                        capture.record(m, &out, || telemetry);
                        Reply::Output(out, telemetry)
                    }
                    (Endpoint::Drive(d), c) => link::execute(d, c, &stats),
                    (_, Command::Configure(spec)) => match DriveConfig::new(spec) {
                        Ok(cfg) => {
                            endpoint = Endpoint::Drive(Drive::new(cfg));
                            Reply::Ack
                        }
                        Err(_) => Reply::Nack(NackReason::Configuration),
                    },
                    (Endpoint::Commission(..), _) => Reply::Nack(NackReason::Unsupported),
                    (Endpoint::None, _) => Reply::Nack(NackReason::NotConfigured),
                };
                match link::reply_frame(&reply, &mut frame) {
                    Ok(len) if tx.write_all(frame.get(..len).unwrap_or(&[])) => {}
                    _ => sh::exit(false),
                }
            }
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("pil: a Cortex-M program; `hil-sim pil` runs it under QEMU");
}
