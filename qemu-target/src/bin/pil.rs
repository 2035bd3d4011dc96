//! Processor-in-the-loop server: the drive — or the commissioning sequence — on the emulated
//! Cortex-M4F, one link frame per PWM period with `hil-sim pil` / `hil-sim identify --pil`
//! (see the crate docs). Exits with status 0 when the host closes
//! `to_mcu`, 1 if the FIFOs cannot be opened or a reply cannot be written.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use controller_core::commission::{CommissionConfig, Commissioning, RECORD_BYTES};
    use controller_core::drive::{Drive, DriveConfig};
    use controller_core::link::{
        self, Command, FrameDecoder, LinkStats, MAX_FRAME, NackReason, RECORD_CHUNK_BYTES, Reply,
    };
    use cortex_m_rt::entry;
    use qemu_target::sh;

    /// What the server runs: nothing yet, a drive (`Configure`), or a commissioning
    /// sequence (`Commission`).
    enum Endpoint {
        None,
        Drive(Drive),
        Commission(Commissioning),
    }

    /// Part `chunk` of a finished sequence's record.
    fn record_chunk(c: &Commissioning, chunk: u8) -> Reply {
        let mut all = [0u8; RECORD_BYTES];
        let Some(_) = c.record().and_then(|r| r.write_bytes(&mut all)) else {
            return Reply::Nack(NackReason::NoRecord);
        };
        let start = usize::from(chunk) * RECORD_CHUNK_BYTES;
        let Some(part) = all.get(start..) else {
            return Reply::Nack(NackReason::NoRecord);
        };
        if part.is_empty() {
            return Reply::Nack(NackReason::NoRecord);
        }
        let mut bytes = [0u8; RECORD_CHUNK_BYTES];
        for (b, x) in bytes.iter_mut().zip(part) {
            *b = *x;
        }
        Reply::CommissionRecord { chunk, bytes }
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
                            endpoint = Endpoint::Commission(Commissioning::new(cfg));
                            Reply::Ack
                        }
                        Err(_) => Reply::Nack(NackReason::Configuration),
                    },
                    (Endpoint::Commission(c), Command::Step(m)) => Reply::Commission(c.step(m)),
                    (Endpoint::Commission(c), Command::Stop | Command::Disable) => {
                        c.abort();
                        Reply::Ack
                    }
                    (Endpoint::Commission(c), Command::GetCommissionRecord { chunk }) => record_chunk(c, *chunk),
                    (Endpoint::Drive(d), c) => link::execute(d, c, &stats),
                    (_, Command::Configure(spec)) => match DriveConfig::new(spec) {
                        Ok(cfg) => {
                            endpoint = Endpoint::Drive(Drive::new(cfg));
                            Reply::Ack
                        }
                        Err(_) => Reply::Nack(NackReason::Configuration),
                    },
                    (Endpoint::Commission(_), _) => Reply::Nack(NackReason::Unsupported),
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
