//! Host side of the `controller_core::link` protocol over any byte stream: the FIFOs of the
//! processor-in-the-loop run ([`crate::pil`]) and the board's serial port (`hil-sim link`).
//!
//! One command, one reply. The board also streams `Output` telemetry on its own; a reply to
//! anything but `Step` therefore skips `Output` frames ([`LinkClient::transact`]).

use controller_core::drive::FaultSet;
use controller_core::link::{self, Command, FrameDecoder, LinkStats, MAX_FRAME, Reply};
use std::io::{Read, Write};
use std::time::{Duration, Instant};

/// A link endpoint on a reader and a writer.
#[derive(Debug)]
pub struct LinkClient<R, W> {
    rx: R,
    tx: W,
    decoder: FrameDecoder,
    input: Vec<u8>,
    input_pos: usize,
    stats: LinkStats,
    round_trips: u64,
    reply_timeout: Option<Duration>,
}

impl<R: Read, W: Write> LinkClient<R, W> {
    /// A client reading replies from `rx` and writing commands to `tx`.
    pub fn new(rx: R, tx: W) -> Self {
        Self {
            rx,
            tx,
            decoder: FrameDecoder::new(),
            input: Vec::new(),
            input_pos: 0,
            stats: LinkStats::default(),
            round_trips: 0,
            reply_timeout: None,
        }
    }

    /// Give up on a reply after `timeout`, whatever arrives meanwhile: a line that streams
    /// noise fails like a silent one. (The lockstep PIL link has no timeout: a slow emulator
    /// is not an error.) Reads that time out on their own (a serial port's) keep waiting
    /// until then.
    pub fn with_reply_timeout(mut self, timeout: Duration) -> Self {
        self.reply_timeout = Some(timeout);
        self
    }

    /// Commands sent so far.
    pub fn round_trips(&self) -> u64 {
        self.round_trips
    }

    /// Counters of the receiver (frames accepted and rejected by kind).
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Write raw bytes (link tests: corrupt frames, noise).
    pub fn send_raw(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.tx.write_all(bytes)?;
        self.tx.flush()
    }

    /// Send `cmd` and return its reply (for anything but `Step`, streamed `Output` frames
    /// are skipped).
    pub fn transact(&mut self, cmd: &Command) -> Result<Reply, String> {
        let mut frame = [0u8; MAX_FRAME];
        let n = link::command_frame(cmd, &mut frame).map_err(|_| "command does not fit a frame")?;
        self.send_raw(frame.get(..n).unwrap_or_default()).map_err(|e| format!("link broken (write): {e}"))?;
        self.round_trips += 1;
        loop {
            let r = self.next_reply()?;
            if matches!(cmd, Command::Step(_)) || !matches!(r, Reply::Output(..)) {
                return Ok(r);
            }
        }
    }

    /// The next well-formed frame from the other side (rejected frames are counted).
    pub fn next_reply(&mut self) -> Result<Reply, String> {
        let deadline = self.reply_timeout.map(|t| (t, Instant::now() + t));
        loop {
            while let Some(&b) = self.input.get(self.input_pos) {
                self.input_pos += 1;
                if let Some(r) = self.decoder.push_reply(b, &mut self.stats) {
                    return Ok(r);
                }
            }
            if let Some((t, at)) = deadline
                && Instant::now() >= at
            {
                return Err(format!(
                    "no well-formed reply within {t:?} ({} malformed frames meanwhile)",
                    self.stats.errors()
                ));
            }
            self.input.resize(4096, 0);
            let n = match self.rx.read(&mut self.input) {
                Ok(n) => n,
                Err(e) if deadline.is_some() && e.kind() == std::io::ErrorKind::TimedOut => {
                    self.input.clear();
                    self.input_pos = 0;
                    continue;
                }
                Err(e) => return Err(format!("link broken (read): {e}")),
            };
            if n == 0 {
                return Err("the other side closed the link".into());
            }
            self.input.truncate(n);
            self.input_pos = 0;
        }
    }
}

/// A board's `Status` for a person at the bench: mode, link counters, the control step's
/// longest time against the PWM period, and the raw readings scaled with the drive file's
/// `[board]` (the firmware's own scalings, before its offset calibration).
pub fn format_status(r: &Reply, file: &drive_file::DriveFile) -> Option<String> {
    let Reply::Status { mode, ridden_through, frames_ok, frame_errors, timing, readings } = r else {
        return None;
    };
    let mut s = format!("mode          {mode:?}\n");
    if *ridden_through != FaultSet::EMPTY {
        let names: Vec<String> = ridden_through.faults().map(|f| format!("{f:?}")).collect();
        s += &format!(
            "ridden through {} — running on the observer, the encoder is not read\n",
            names.join(", ")
        );
    }
    s += &format!("frames        {frames_ok} accepted, {frame_errors} rejected\n");
    let f_pwm = file.spec.pwm_frequency_hz;
    match &file.board {
        Some(b) => {
            let t = &b.table;
            let f_cpu = f64::from(t.tim_clock_hz);
            s += &format!(
                "control step  longest {} cycles = {:.1} µs of the {:.1} µs period, {} overruns\n",
                timing.cycles_max,
                f64::from(timing.cycles_max) / f_cpu * 1e6,
                1e6 / f_pwm,
                timing.overruns
            );
            s += &format!("stack         {} B at most since reset\n", timing.stack_bytes);
            let amps = |c: u16| (f64::from(c) - f64::from(t.current_offset_counts)) * t.current_a_per_count;
            let [a, bb, c] = readings.i_abc_counts;
            s += &format!(
                "currents      {a} {bb} {c} counts (zero {}): {:+.3} {:+.3} {:+.3} A\n",
                t.current_offset_counts,
                amps(a),
                amps(bb),
                amps(c)
            );
            s += &format!(
                "bus           {} counts: {:.1} V\n",
                readings.vdc_counts,
                f64::from(readings.vdc_counts) * t.vdc_v_per_count
            );
            s += &format!(
                "encoder       {} counts ({} per revolution)\n",
                readings.encoder_counts,
                4 * u64::from(t.encoder_lines)
            );
        }
        None => {
            s += &format!(
                "control step  longest {} cycles, {} overruns\nstack         {} B at most since reset\nreadings      {readings:?} (no [board] to scale them)\n",
                timing.cycles_max, timing.overruns, timing.stack_bytes
            );
        }
    }
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::drive::Fault;

    /// The shipped board's scalings: the calibration's zero reads 0 A, 3 100 counts 310 V, a
    /// 3 400-cycle step 20.0 µs of the 50 µs period.
    #[test]
    fn status_reads_in_units() {
        let file = drive_file::DriveFile::shipped().unwrap();
        let r = Reply::Status {
            mode: controller_core::drive::Mode::Idle,
            ridden_through: FaultSet::EMPTY,
            frames_ok: 3,
            frame_errors: 1,
            timing: controller_core::link::LoopTiming { cycles_max: 3400, overruns: 0, stack_bytes: 1480 },
            readings: controller_core::link::BoardReadings {
                i_abc_counts: [2048, 2048 + 124, 2048 - 124],
                vdc_counts: 3100,
                encoder_counts: 4096,
            },
        };
        let s = format_status(&r, &file).unwrap();
        assert!(s.contains("20.0 µs of the 50.0 µs period"), "{s}");
        assert!(s.contains("+0.000 +0.999 -0.999 A"), "{s}");
        assert!(s.contains("310.0 V") && s.contains("4096 per revolution"), "{s}");
        assert!(s.contains("stack         1480 B"), "{s}");
        assert!(!s.contains("ridden through"), "{s}");
        assert_eq!(format_status(&Reply::Ack, &file), None);
        // A drive riding through its encoder's fault says so, by name.
        let Reply::Status { mode, frames_ok, frame_errors, timing, readings, .. } = r else { unreachable!() };
        let ridden = FaultSet::EMPTY.with(Fault::EncoderLoss).with(Fault::EncoderImplausible);
        let r = Reply::Status { mode, ridden_through: ridden, frames_ok, frame_errors, timing, readings };
        let s = format_status(&r, &file).unwrap();
        assert!(
            s.contains("ridden through EncoderLoss, EncoderImplausible — running on the observer"),
            "{s}"
        );
    }
    use controller_core::drive::{FastOutput, Mode, PhaseCommand, Telemetry};

    fn frames(replies: &[Reply]) -> Vec<u8> {
        let mut out = Vec::new();
        for r in replies {
            let mut f = [0u8; MAX_FRAME];
            let n = link::reply_frame(r, &mut f).unwrap();
            out.extend_from_slice(&f[..n]);
        }
        out
    }

    #[test]
    fn a_command_reply_skips_streamed_telemetry_and_noise() {
        let telemetry = Reply::Output(
            FastOutput { phases: PhaseCommand::Off, mode: Mode::Idle, brake: false },
            Telemetry::default(),
        );
        let mut wire = frames(&[telemetry, telemetry]);
        wire.extend([0x13, 0x37, 0x00]); // noise: a bad frame
        wire.extend(frames(&[Reply::Ack, telemetry]));
        let mut sent = Vec::new();
        let mut c = LinkClient::new(wire.as_slice(), &mut sent);
        assert_eq!(c.transact(&Command::Enable).unwrap(), Reply::Ack);
        assert_eq!(c.stats().frames_ok, 3);
        assert_eq!(c.stats().errors(), 1);
        // A Step takes the next Output.
        assert_eq!(c.transact(&Command::Step(Default::default())).unwrap(), telemetry);
        // Then the stream ends.
        assert!(c.transact(&Command::GetStatus).unwrap_err().contains("closed"));
        drop(c);
        // What went out decodes to the three commands.
        let mut d = FrameDecoder::new();
        let got: Vec<Command> =
            sent.iter().filter_map(|&b| d.push(b).map(|p| Command::decode(p.unwrap()).unwrap())).collect();
        assert_eq!(got, [Command::Enable, Command::Step(Default::default()), Command::GetStatus]);
    }

    /// Issue 16: `hil-sim link` on a line that streams noise never returned.
    #[test]
    fn noise_times_out_like_silence() {
        struct Noise(u8);
        impl Read for Noise {
            fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
                for b in buf.iter_mut() {
                    self.0 = self.0.wrapping_mul(73).wrapping_add(41);
                    *b = self.0;
                }
                Ok(buf.len())
            }
        }
        struct Silence;
        impl Read for Silence {
            fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
                std::thread::sleep(Duration::from_millis(5));
                Err(std::io::ErrorKind::TimedOut.into())
            }
        }
        let t = Duration::from_millis(50);
        let started = Instant::now();
        let mut c = LinkClient::new(Noise(1), std::io::sink()).with_reply_timeout(t);
        let e = c.transact(&Command::GetStatus).unwrap_err();
        assert!(e.contains("no well-formed reply") && e.contains("malformed"), "{e}");
        let mut c = LinkClient::new(Silence, std::io::sink()).with_reply_timeout(t);
        assert!(c.transact(&Command::GetStatus).unwrap_err().contains("no well-formed reply"));
        assert!(started.elapsed() < Duration::from_secs(2));
    }
}
