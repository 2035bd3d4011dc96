//! The drive's capture (`controller_core::capture`) from the host: arm it over a link, wait
//! for its record, read it out, and write it as CSV and SVG — `hil-sim link DEVICE capture`
//! on a board, and the processor-in-the-loop test that compares a PIL run's capture with
//! the simulation's trace.

use controller_core::capture::{CHANNELS, CaptureSpec, CaptureState, Edge, Signal, Trigger};
use controller_core::link::{Command, NackReason, Reply};
use std::time::{Duration, Instant};

/// One command, one reply (a board's `LinkClient`, a `Pil`).
pub type Transact<'a> = dyn FnMut(&Command) -> Result<Reply, String> + 'a;

/// What to capture and how to report it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// What to arm.
    pub spec: CaptureSpec,
    /// The drive's control (PWM) period, s.
    pub period_s: f64,
    /// Channels to report: the first `shown` of the spec's.
    pub shown: usize,
    /// A command sent once the capture is armed (e.g. the speed step it is to see).
    pub then: Option<Command>,
}

/// A finished record: the spec it was armed with, its samples (oldest first; sample
/// `pre_samples` is the trigger's) and the control period.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    /// What was armed.
    pub spec: CaptureSpec,
    /// The samples, each the four channels.
    pub samples: Vec<[f32; CHANNELS]>,
    /// The drive's control (PWM) period, s.
    pub period_s: f64,
    /// Channels to report: the first `shown` of the spec's (the rest repeat the first).
    pub shown: usize,
}

impl Record {
    /// Time of sample `k` from the trigger's sample, s.
    pub fn t_s(&self, k: usize) -> f64 {
        (k as f64 - f64::from(self.spec.pre_samples)) * f64::from(self.spec.decimation) * self.period_s
    }

    fn signals(&self) -> impl Iterator<Item = (usize, Signal)> + '_ {
        self.spec.signals.iter().copied().enumerate().take(self.shown)
    }

    /// CSV: `t_s` (from the trigger), then one column per shown signal, named with its unit.
    pub fn csv(&self) -> String {
        let mut s = String::from("t_s");
        for (_, sig) in self.signals() {
            s.push_str(&format!(",{}_{}", sig.name(), unit_suffix(sig)));
        }
        s.push('\n');
        for (k, sample) in self.samples.iter().enumerate() {
            s.push_str(&format!("{:.9}", self.t_s(k)));
            for (c, _) in self.signals() {
                s.push_str(&format!(",{}", sample.get(c).copied().unwrap_or(f32::NAN)));
            }
            s.push('\n');
        }
        s
    }

    /// SVG: one panel per shown signal on the shared time axis, the trigger at t = 0.
    pub fn svg(&self, title: &str) -> String {
        use report::plot::{Series, line_plot, stack};
        let panels: Vec<String> = self
            .signals()
            .map(|(c, sig)| {
                let points = self
                    .samples
                    .iter()
                    .enumerate()
                    .map(|(k, s)| (self.t_s(k) * 1e3, f64::from(s.get(c).copied().unwrap_or(f32::NAN))))
                    .collect();
                let label = format!("{} ({})", sig.name(), sig.unit());
                line_plot(
                    &format!("{title}: {label}"),
                    "t from the trigger (ms)",
                    &[Series::line(&label, points)],
                )
            })
            .collect();
        stack(&panels)
    }
}

fn unit_suffix(s: Signal) -> &'static str {
    match s.unit() {
        "rad/s" => "rad_s",
        "1" => "1",
        u => u,
    }
}

/// Arm `spec`; the drive's refusal as a sentence.
pub fn arm(transact: &mut Transact<'_>, spec: CaptureSpec) -> Result<(), String> {
    match transact(&Command::ArmCapture(spec))? {
        Reply::Ack => Ok(()),
        Reply::Nack(NackReason::Configuration) => Err(format!(
            "the drive refused the capture: pre-trigger samples ({}) must be below its record's depth, \
             decimation at least 1, the trigger level finite",
            spec.pre_samples
        )),
        Reply::Nack(NackReason::Unsupported) => Err("the drive has no capture (older firmware?)".into()),
        r => Err(format!("unexpected reply to ArmCapture: {r:?}")),
    }
}

/// The capture's state, and its record once it is done (`None` before).
pub fn read(transact: &mut Transact<'_>, req: &Request) -> Result<(CaptureState, Option<Record>), String> {
    let (state, depth) = match transact(&Command::ReadCapture { chunk: 0 })? {
        Reply::Capture { state, samples, .. } => (state, usize::from(samples)),
        r => return Err(format!("unexpected reply to ReadCapture: {r:?}")),
    };
    use controller_core::capture::{CHUNK_SAMPLES, MAX_DEPTH};
    if depth == 0 || depth % CHUNK_SAMPLES != 0 || depth > MAX_DEPTH {
        return Err(format!("the drive reports a record of {depth} samples: not a whole number of chunks"));
    }
    if state != CaptureState::Done {
        return Ok((state, None));
    }
    let chunks = depth / CHUNK_SAMPLES;
    let mut samples = Vec::with_capacity(depth);
    for k in 0..chunks {
        let chunk =
            u8::try_from(k).map_err(|_| format!("a record of {depth} samples has too many chunks"))?;
        match transact(&Command::ReadCapture { chunk })? {
            Reply::Capture { state: CaptureState::Done, chunk: c, bytes, .. } if c == chunk => {
                for s in bytes.chunks_exact(4 * CHANNELS) {
                    let mut sample = [0.0f32; CHANNELS];
                    for (v, b) in sample.iter_mut().zip(s.chunks_exact(4)) {
                        *v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                    }
                    samples.push(sample);
                }
            }
            Reply::Capture { state: CaptureState::Done, chunk: c, .. } => {
                return Err(format!("asked for chunk {chunk}, got chunk {c}: the link is out of step"));
            }
            Reply::Capture { state, .. } => {
                return Err(format!(
                    "the record changed while it was read (now {state:?}): re-armed by another client?"
                ));
            }
            r => return Err(format!("unexpected reply to ReadCapture {{ chunk: {chunk} }}: {r:?}")),
        }
    }
    Ok((state, Some(Record { spec: req.spec, samples, period_s: req.period_s, shown: req.shown })))
}

/// Arm, then poll every `poll` until the record is done (`progress` sees each new state),
/// at most `wait`, or until `stop` says so; then read it out.
pub fn take(
    transact: &mut Transact<'_>,
    req: &Request,
    wait: Duration,
    poll: Duration,
    stop: &dyn Fn() -> bool,
    progress: &mut dyn FnMut(CaptureState),
) -> Result<Record, String> {
    arm(transact, req.spec)?;
    if let Some(c) = &req.then {
        match transact(c)? {
            Reply::Ack => {}
            r => return Err(format!("the capture is armed, but the drive answered {c:?} with {r:?}")),
        }
    }
    let start = Instant::now();
    let mut last = None;
    loop {
        let (state, record) = read(transact, req)?;
        if last != Some(state) {
            progress(state);
            last = Some(state);
        }
        if let Some(r) = record {
            return Ok(r);
        }
        if state == CaptureState::Idle {
            return Err("the drive reports no capture armed (was it reset?): nothing written".into());
        }
        if stop() {
            return Err("interrupted: nothing written".into());
        }
        if start.elapsed() >= wait {
            return Err(format!(
                "no record after {:.0} s (the capture is {}): nothing written",
                wait.as_secs_f64(),
                match state {
                    CaptureState::Armed => "armed and waiting for its trigger",
                    CaptureState::Triggered => "triggered, completing its record",
                    CaptureState::Idle => "idle: the arm did not take",
                    CaptureState::Done => "done",
                }
            ));
        }
        std::thread::sleep(poll);
    }
}

/// The command `--then` sends: `enable`, `disable`, `stop`, or `speed|torque|position V`.
pub fn parse_then(text: &str) -> Result<Command, String> {
    use controller_core::drive::Reference;
    let words: Vec<&str> = text.split_whitespace().collect();
    let value = |v: &str| -> Result<f32, String> {
        v.parse::<f32>().ok().filter(|x| x.is_finite()).ok_or_else(|| format!("`{v}` is not a finite number"))
    };
    Ok(match words.as_slice() {
        ["enable"] => Command::Enable,
        ["disable"] => Command::Disable,
        ["stop"] => Command::Stop,
        ["speed", v] => Command::SetReference(Reference::Speed(value(v)?)),
        ["torque", v] => Command::SetReference(Reference::Torque(value(v)?)),
        ["position", v] => Command::SetReference(Reference::Position(value(v)?)),
        _ => return Err(format!("`{text}`: enable, disable, stop, or speed|torque|position VALUE")),
    })
}

/// `"omega_ref"` → the signal, or a sentence listing the names.
pub fn parse_signal(name: &str) -> Result<Signal, String> {
    Signal::ALL.iter().copied().find(|s| s.name() == name.trim()).ok_or_else(|| {
        let names: Vec<&str> = Signal::ALL.iter().map(|s| s.name()).collect();
        format!("unknown signal `{name}` (one of: {})", names.join(", "))
    })
}

/// 1 to 4 comma-separated signal names → the four channels (unused ones repeat the first)
/// and how many were asked for.
pub fn parse_signals(list: &str) -> Result<([Signal; CHANNELS], usize), String> {
    let asked: Vec<Signal> = list.split(',').map(parse_signal).collect::<Result<_, _>>()?;
    if asked.is_empty() || asked.len() > CHANNELS {
        return Err(format!("1 to {CHANNELS} signals, comma-separated (got {})", asked.len()));
    }
    let mut signals = [asked[0]; CHANNELS];
    for (s, a) in signals.iter_mut().zip(&asked) {
        *s = *a;
    }
    Ok((signals, asked.len()))
}

/// `immediate`, or `SIGNAL:rising|falling|either:LEVEL` (e.g. `omega_ref:rising:100`).
pub fn parse_trigger(text: &str) -> Result<Trigger, String> {
    if text.trim() == "immediate" {
        return Ok(Trigger::Immediate);
    }
    let parts: Vec<&str> = text.split(':').collect();
    let [signal, edge, level] = parts.as_slice() else {
        return Err(format!("trigger `{text}`: `immediate` or SIGNAL:rising|falling|either:LEVEL"));
    };
    let edge = match edge.trim() {
        "rising" => Edge::Rising,
        "falling" => Edge::Falling,
        "either" => Edge::Either,
        e => return Err(format!("trigger edge `{e}`: rising, falling or either")),
    };
    let level: f32 = level.trim().parse().map_err(|_| format!("trigger level `{level}` is not a number"))?;
    if !level.is_finite() {
        return Err(format!("trigger level `{level}` is not finite"));
    }
    Ok(Trigger::Level { signal: parse_signal(signal)?, edge, level })
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::capture::Capture;
    use controller_core::drive::{FastOutput, Measurements, Mode, PhaseCommand, Telemetry};
    use controller_core::link;

    #[test]
    fn parsing_signals_and_triggers() {
        let (s, n) = parse_signals("i_a, omega_ref").unwrap();
        assert_eq!((s, n), ([Signal::IA, Signal::OmegaRef, Signal::IA, Signal::IA], 2));
        assert!(parse_signals("i_a,i_b,i_c,vdc,mode").unwrap_err().contains("1 to 4"));
        assert!(parse_signals("i_x").unwrap_err().contains("omega_ref"));
        assert_eq!(parse_trigger("immediate"), Ok(Trigger::Immediate));
        assert_eq!(
            parse_trigger("omega_ref:rising:100"),
            Ok(Trigger::Level { signal: Signal::OmegaRef, edge: Edge::Rising, level: 100.0 })
        );
        use controller_core::drive::Reference;
        assert_eq!(parse_then(" speed  50 "), Ok(Command::SetReference(Reference::Speed(50.0))));
        assert_eq!(parse_then("stop"), Ok(Command::Stop));
        for bad in ["speed", "speed fast", "speed inf", "jump 3", ""] {
            assert!(parse_then(bad).is_err(), "{bad}");
        }
        for bad in [
            "omega_ref:up:1",
            "omega_ref:rising",
            "omega_ref:rising:x",
            "omega_ref:rising:inf",
            "nope:rising:1",
        ] {
            assert!(parse_trigger(bad).is_err(), "{bad}");
        }
    }

    /// Against an endpoint that serves a capture the way the firmware does: the record read
    /// back is what was recorded, with its times from the trigger; CSV and SVG carry the
    /// shown channels only.
    #[test]
    fn take_reads_back_what_the_endpoint_recorded() {
        let mut capture = Capture::<16>::new();
        let mut period = 0u32;
        let mut transact = |c: &Command| -> Result<Reply, String> {
            Ok(match c {
                Command::ArmCapture(s) => link::arm_capture(&mut capture, *s),
                Command::ReadCapture { chunk } => {
                    // Each poll: ten control periods pass, i_a = the period's number.
                    for _ in 0..10 {
                        let mut m = Measurements::default();
                        m.i_abc_a.a = period as f32;
                        let out = FastOutput { phases: PhaseCommand::Off, mode: Mode::Idle, brake: false };
                        capture.record(&m, &out, Telemetry::default);
                        period += 1;
                    }
                    link::read_capture(&capture, *chunk)
                }
                _ => Reply::Nack(NackReason::Unsupported),
            })
        };
        let trigger = Trigger::Level { signal: Signal::IA, edge: Edge::Rising, level: 50.0 };
        let spec = CaptureSpec {
            signals: [Signal::IA, Signal::Mode, Signal::IA, Signal::IA],
            trigger,
            pre_samples: 3,
            decimation: 2,
        };
        let mut states = Vec::new();
        let req = Request { spec, period_s: 5e-5, shown: 2, then: None };
        let r = take(&mut transact, &req, Duration::from_secs(5), Duration::ZERO, &|| false, &mut |s| {
            states.push(s)
        })
        .unwrap();
        assert_eq!(states.first(), Some(&CaptureState::Armed));
        assert_eq!(states.last(), Some(&CaptureState::Done));
        assert_eq!(r.samples.len(), 16);
        // Sample 3 is the trigger's: the first even period at or above 50.
        assert_eq!(r.samples[3][0], 50.0);
        assert_eq!(r.samples[0][0], 44.0);
        assert!((r.t_s(3)).abs() < 1e-15 && (r.t_s(4) - 1e-4).abs() < 1e-12);
        let csv = r.csv();
        assert!(csv.starts_with("t_s,i_a_A,mode_1\n"), "{csv}");
        assert_eq!(csv.lines().count(), 17);
        assert_eq!(r.svg("t").matches("<svg ").count(), 3);
        // A refused arm, as a sentence.
        let bad = CaptureSpec { pre_samples: 16, ..spec };
        assert!(arm(&mut transact, bad).unwrap_err().contains("pre-trigger samples (16)"));
    }

    /// `--then`'s command goes out once the capture is armed, and its refusal is named; a
    /// drive that forgot its capture (reset) fails at once.
    #[test]
    fn then_is_sent_after_the_arm_and_a_reset_drive_fails_at_once() {
        let mut capture = Capture::<8>::new();
        let mut sent = Vec::new();
        let mut transact = |c: &Command| -> Result<Reply, String> {
            sent.push(*c);
            Ok(match c {
                Command::ArmCapture(s) => link::arm_capture(&mut capture, *s),
                Command::ReadCapture { chunk } => {
                    // The board reset after the arm.
                    capture = Capture::new();
                    link::read_capture(&capture, *chunk)
                }
                Command::Enable => Reply::Ack,
                _ => Reply::Nack(NackReason::NotIdle),
            })
        };
        let spec = CaptureSpec {
            signals: [Signal::IA; 4],
            trigger: Trigger::Immediate,
            pre_samples: 0,
            decimation: 1,
        };
        let req = Request { spec, period_s: 5e-5, shown: 1, then: Some(Command::Enable) };
        let e = take(&mut transact, &req, Duration::from_secs(9), Duration::ZERO, &|| false, &mut |_| {})
            .unwrap_err();
        assert!(e.contains("no capture armed"), "{e}");
        let stop = Request { then: Some(Command::Stop), ..req };
        let e = take(&mut transact, &stop, Duration::from_secs(9), Duration::ZERO, &|| false, &mut |_| {})
            .unwrap_err();
        assert!(e.contains("Stop") && e.contains("NotIdle"), "{e}");
        assert!(matches!(
            sent[..],
            [Command::ArmCapture(_), Command::Enable, Command::ReadCapture { chunk: 0 }, ..]
        ));
    }

    #[test]
    fn a_capture_that_never_triggers_gives_up_and_says_why() {
        let mut capture = Capture::<8>::new();
        let mut transact = |c: &Command| -> Result<Reply, String> {
            Ok(match c {
                Command::ArmCapture(s) => link::arm_capture(&mut capture, *s),
                Command::ReadCapture { chunk } => link::read_capture(&capture, *chunk),
                _ => Reply::Nack(NackReason::Unsupported),
            })
        };
        let spec = CaptureSpec {
            signals: [Signal::IA; 4],
            trigger: Trigger::Level { signal: Signal::IA, edge: Edge::Rising, level: 1.0 },
            pre_samples: 0,
            decimation: 1,
        };
        let req = Request { spec, period_s: 5e-5, shown: 1, then: None };
        let e =
            take(&mut transact, &req, Duration::ZERO, Duration::ZERO, &|| false, &mut |_| {}).unwrap_err();
        assert!(e.contains("waiting for its trigger") && e.contains("nothing written"), "{e}");
        let e = take(&mut transact, &req, Duration::from_secs(9), Duration::ZERO, &|| true, &mut |_| {})
            .unwrap_err();
        assert!(e.contains("interrupted"), "{e}");
    }
}
