//! Executed instructions per fast and slow step on the Cortex-M4F, measured under QEMU with
//! `-icount shift=0` (deterministic: 1 instruction = 1 ns of virtual time; SysTick at 25 MHz
//! → 40 instructions per tick). Each figure is the average over 4096 calls with inputs
//! varying along a rotating current vector, minus the same loop without the call (its
//! counter and timer reads), so the resolution is 40/4096 ≈ 0.01 instruction. The firmware's
//! interrupt body (`interrupt_*`) is also less the benchmark's fetch of each period's samples
//! from its table; the drive's `period` and `fast_step` still include fetching each period's
//! ADC codes from theirs (the parts measured alone subtract what they say).
//!
//! `interrupt_period` is the firmware's control work per period once its samples are read:
//! the control interrupt (`firmware::interrupt::Shared::control_period`: the break check, ADC
//! codes → amperes and volts (`AdcScaling`) → the drive's fast side (`FastSide::step`: the
//! fast step — supervisor, Clarke, the IFOC's fast part, two ICAD channels, SVPWM — and at
//! the tick the slow step's job latched and handed over) → compare values (`PwmScaling`) and
//! MOE, the link's requests) and the slow context's job after it (`firmware::control::run_slow`,
//! every N-th period); `interrupt_fast_step` is a period less the drive's slow step's share —
//! the control interrupt's average. `interrupt_worst_period` and
//! `interrupt_worst_command_period` are the control interrupt's longest single periods (each
//! timed alone, to SysTick's 40 instructions): the 50 µs period's margin, where the averages
//! are the processor's load. `worst:<point>` lines are the control interrupt's longest period
//! and the slow context's longest job at each operating point of a sweep from standstill to
//! top speed — motoring, generating, braking, a capture armed — and `fast_interrupt_worst`
//! and `slow_context_worst` the longest of them (the first with the commands'; issue 54's
//! worst-case accounting).
//! `period` and `fast_step` are the drive's own. The components are also measured alone to show what
//! dominates. Output: `cost <name> <instructions>` lines, then the stack depths
//! (`qemu_target::stack`: painted, then scanned) of `Drive::step` and of the interrupt's
//! body serving each command the link can post.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use controller_core::capture::{CaptureSpec, Edge, FastPeriod, Signal, Trigger};
    use controller_core::current::{CurrentControllerConfig, CurrentLaw, CurrentState};
    use controller_core::discretize::Discretization;
    use controller_core::drive::{
        Drive, DriveConfig, FastOutput, Measurements, Mode, PhaseCommand, Reference,
    };
    use controller_core::envelope::EnvelopeConfig;
    use controller_core::frames::{Abc, AlphaBeta, Dq, SinCos};
    use controller_core::ifoc::{IfocConfig, TorqueCommand};
    use controller_core::link::{BoardCommand, LinkStats, Reply};
    use controller_core::magnetics::{MagnetizingChord, MagnetizingCurve, MagnetizingTable};
    use controller_core::motor::MotorParams;
    use controller_core::mras::{Evidence, FitPeriod, MrasConfig, RotorFit};
    use controller_core::observer::{FluxObserver, ObserverConfig};
    use controller_core::scaling::{AdcCode, AdcScaling, PwmScaling};
    use controller_core::svpwm;
    use core::hint::black_box;
    use cortex_m_rt::entry;
    use firmware::scope::Scope;
    use firmware::server::Prepared;
    use qemu_target::clock::{INSTRUCTIONS_PER_TICK, Ticks};
    use qemu_target::machine::Machine;
    use qemu_target::{println, sh};

    const N: u32 = 4096;

    /// The shaft's speed in [`interrupt_period`] once Running (the encoder's counts), mechanical
    /// rad/s.
    const ENCODER_RAD_S: f32 = 10.0;

    /// Instructions per call of `f` (baseline loop subtracted).
    fn per_call(ticks: &Ticks, mut f: impl FnMut(u32)) -> f32 {
        let run = |ticks: &Ticks, g: &mut dyn FnMut(u32)| {
            let t0 = ticks.now();
            for k in 0..N {
                g(k);
            }
            Ticks::elapsed(t0, ticks.now())
        };
        let base = run(ticks, &mut |k| {
            black_box(k);
        });
        let with = run(ticks, &mut f);
        (with.saturating_sub(base) * INSTRUCTIONS_PER_TICK) as f32 / N as f32
    }

    /// TIM1's registers and the brake pin as plain memory: each access one volatile load or
    /// store, as the firmware's are (their addresses aside); no break ever.
    #[derive(Default)]
    struct Registers {
        sr: u32,
        bdtr: u32,
        ccr: [u32; 3],
        bsrr: u32,
    }

    impl firmware::output::OutputStage for Registers {
        fn break_flag(&mut self) -> bool {
            // SAFETY: a field of `self`, aligned and initialised.
            let sr = unsafe { core::ptr::read_volatile(&self.sr) };
            sr & (1 << 7) != 0
        }
        fn clear_break_flag(&mut self) {
            // SAFETY: as above.
            unsafe { core::ptr::write_volatile(&mut self.sr, !(1 << 7)) }
        }
        fn outputs_enabled(&mut self) -> bool {
            // SAFETY: as above.
            let bdtr = unsafe { core::ptr::read_volatile(&self.bdtr) };
            bdtr & (1 << 15) != 0
        }
        fn set_compare(&mut self, [a, b, c]: [u16; 3]) {
            let [ra, rb, rc] = &mut self.ccr;
            // SAFETY: as above.
            unsafe {
                core::ptr::write_volatile(ra, u32::from(a));
                core::ptr::write_volatile(rb, u32::from(b));
                core::ptr::write_volatile(rc, u32::from(c));
            }
        }
        fn enable_outputs(&mut self) {
            // SAFETY: as above (a read-modify-write, as the firmware's `modify`).
            unsafe {
                core::ptr::write_volatile(&mut self.bdtr, core::ptr::read_volatile(&self.bdtr) | (1 << 15))
            }
        }
        fn disable_outputs(&mut self) {
            // SAFETY: as above.
            unsafe {
                core::ptr::write_volatile(&mut self.bdtr, core::ptr::read_volatile(&self.bdtr) & !(1 << 15))
            }
        }
        fn set_brake(&mut self, on: bool) {
            // SAFETY: as above.
            unsafe { core::ptr::write_volatile(&mut self.bsrr, if on { 1 << 5 } else { 1 << 21 }) }
        }
    }

    /// [`interrupt_period`]'s figures.
    struct Interrupt {
        /// Instructions per period (NaN: the drive did not run).
        period: f32,
        /// Calls of the body before the measured ones.
        calls_before: u32,
        /// The deepest stack of the control interrupt's body in a period with a command posted
        /// or served, bytes (0: a command was not served).
        stack_bytes: usize,
        /// The slow context's then.
        slow_stack_bytes: usize,
        /// The longest of the [`N`] measured periods, run again from a copy of the loop and
        /// each timed alone, in instructions (to `WORST_RESOLUTION`; NaN: the drive did not
        /// run): no command posted, the capture idle.
        worst_period: f32,
        /// The control interrupt's longest period while a command is posted or served (each
        /// the link can post, in turn, a snapshot asked for with each), and its command.
        worst_command_period: f32,
        worst_command: &'static str,
        /// The slow context's longest turn then (the job and the command it serves), and its
        /// command.
        worst_slow_command: f32,
        worst_slow_name: &'static str,
        /// The worst-case sweep at each [`Point`] (`None`: the drive faulted there).
        sweep: [Option<Worst>; POINTS],
    }

    impl Interrupt {
        const FAILED: Self = Self {
            period: f32::NAN,
            calls_before: 0,
            stack_bytes: 0,
            slow_stack_bytes: 0,
            worst_period: f32::NAN,
            worst_command_period: f32::NAN,
            worst_command: "",
            worst_slow_command: f32::NAN,
            worst_slow_name: "",
            sweep: [None; POINTS],
        };
    }

    /// The slow step's job was handed over at a tick and waits for the slow context
    /// ([`pend_slow`]; the board pends its slow interrupt).
    static PENDING: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

    /// The benchmark's [`firmware::control::Pend`]: the job is left for [`slow_context`].
    fn pend_slow(_: &firmware::control::SlowCell) {
        PENDING.store(true, core::sync::atomic::Ordering::Relaxed);
    }

    /// The slow context's body after a period, as the board's slow interrupt runs it once the
    /// control interrupt returns: the job handed over, if any (`firmware::control::run_slow`).
    /// True if there was one.
    fn slow_context(cell: &firmware::control::SlowCell) -> bool {
        let pending = PENDING.swap(false, core::sync::atomic::Ordering::Relaxed);
        if pending {
            firmware::control::run_slow(cell);
        }
        pending
    }

    /// A single call timed alone: SysTick's resolution, 40 instructions.
    const WORST_RESOLUTION: u32 = INSTRUCTIONS_PER_TICK;

    /// Instructions of one call of `f`, timed alone (less the timing's own, also measured
    /// alone), to [`WORST_RESOLUTION`].
    fn timed(ticks: &Ticks, f: impl FnOnce()) -> u32 {
        use core::sync::atomic::{Ordering::SeqCst, compiler_fence};
        let t0 = ticks.now();
        compiler_fence(SeqCst);
        f();
        compiler_fence(SeqCst);
        Ticks::elapsed(t0, ticks.now()) * INSTRUCTIONS_PER_TICK
    }

    /// The current `machine` answers the period `c` just ran with: the voltage it applied,
    /// while its bridge switches.
    fn answer(machine: &mut Machine, c: &firmware::control::ControlLoop) -> AlphaBeta {
        machine.period(c.fast().mode().is_active(), c.telemetry().v_ab_v)
    }

    /// Instructions per period of the firmware's control-interrupt body once its samples
    /// are read (`firmware::interrupt::Shared::control_period`: the output stage's break
    /// check, `ControlLoop::step`, the compare values and MOE, the link's requests, the
    /// snapshot for the link task) on `raw` (the board's scalings, `firmware::config::BOARD`),
    /// TIM1 as plain memory ([`Registers`]): calibrated at rest, enabled, pre-charged and
    /// magnetized, then Running under a 150 rad/s speed reference (the samples a [`Machine`]'s
    /// with `motor`'s circuit, its shaft at the encoder's 10 rad/s), less the benchmark's own
    /// fetch of the samples from its table; NaN if it never runs. Also the calls before the
    /// measured ones (calibration, pre-charge, magnetizing and the rehearsal's:
    /// `tools/qemu_profile.py --skip`), and the body's deepest stack, a command served in
    /// the period (each the link can post, in turn) and a snapshot published.
    fn interrupt_period(
        ticks: &Ticks,
        raw: &controller_core::drive::RawDriveConfig,
        ts_s: f32,
        motor: &MotorParams,
        points: &[Point; POINTS],
    ) -> Interrupt {
        use firmware::config::BOARD;
        use firmware::control::{CALIBRATION_SAMPLES, ControlLoop, Samples};
        use firmware::interrupt::Shared;
        use firmware::output::Outputs;
        let mut cell = core::mem::MaybeUninit::uninit();
        let Ok(mut c) = ControlLoop::new(raw, &BOARD, &mut cell, pend_slow) else { return Interrupt::FAILED };
        // The link's: the slow context serves the drive's commands and the snapshots.
        static SHARED: Shared = Shared::new();
        let shared = &SHARED;
        if !c.connect(shared) {
            return Interrupt::FAILED;
        }
        let mut outputs = Outputs::new();
        let mut tim1 = Registers::default();
        let zero = BOARD.current_offset_counts;
        let code = |i: f32| {
            let x = f32::from(zero) + i / BOARD.current_a_per_count;
            x.clamp(0.0, f32::from(BOARD.adc_full_scale)) as u16
        };
        // The encoder at 10 rad/s once Running: counts per PWM period.
        let counts = 4.0 * BOARD.encoder_lines as f32 / core::f32::consts::TAU * ENCODER_RAD_S * ts_s;
        // A period's conversions and counter, as the interrupt reads them: five half-words.
        let codes = |i: AlphaBeta, k: u32| {
            let i = i.inverse_clarke();
            [code(i.a), code(i.b), code(i.c), 3100, (k as f32 * counts) as u32 as u16]
        };
        let samples = |[a, b, cc, vdc, encoder]: [u16; 5]| Samples {
            i_abc: [a, b, cc],
            vdc,
            encoder,
            hardware_break: false,
        };
        // The control interrupt's body; the slow context's after it (`slow_context`).
        let mut step = |c: &mut ControlLoop, s: Samples| {
            shared.control_period(&mut outputs, &mut tim1, c, s);
        };

        for _ in 0..=CALIBRATION_SAMPLES {
            step(&mut c, samples(codes(AlphaBeta::default(), 0)));
            slow_context(c.slow_cell());
        }
        // The commands in a period without the slow step in flight, as the link's are served.
        let mut waited = 0;
        while c.slow_busy() {
            step(&mut c, samples(codes(AlphaBeta::default(), 0)));
            slow_context(c.slow_cell());
            waited += 1;
        }
        if c.drive_mut(|mut d| d.enable()) != Some(Ok(())) {
            return Interrupt::FAILED;
        }
        // The machine behind the samples, its shaft at the encoder's speed once Running
        // (held at rest until then, as the encoder is).
        let mut machine = Machine::new(motor, ts_s, 0.0);
        let mut i_ab = AlphaBeta::default();
        let mut k = 0u32;
        // At rest until Running (the pre-charge and the magnetizing).
        while (c.fast().mode() != Mode::Running || c.slow_busy()) && k < 100_000 {
            step(&mut c, samples(codes(i_ab, 0)));
            slow_context(c.slow_cell());
            i_ab = answer(&mut machine, &c);
            k += 1;
        }
        machine.set_speed(ENCODER_RAD_S);
        if c.drive_mut(|mut d| d.set_reference(Reference::Speed(150.0))) != Some(Ok(())) {
            return Interrupt::FAILED;
        }
        let mut table = [[0u16; 5]; N as usize];
        let mut rehearsal_cell = core::mem::MaybeUninit::uninit();
        let Some(mut rehearsal) = c.fork(&mut rehearsal_cell) else { return Interrupt::FAILED };
        for (j, t) in (0u32..).zip(table.iter_mut()) {
            *t = codes(i_ab, j);
            rehearsal.step(&samples(*t));
            slow_context(rehearsal.slow_cell());
            i_ab = answer(&mut machine, &rehearsal);
        }
        // The table's currents over and over, the encoder turning on past its end (a
        // counter that fell back to the table's first count tripped `EncoderLoss`, and the
        // commands below, meant to be served while Running, were served in a fault).
        let fetch = |j: u32| Samples {
            encoder: (j as f32 * counts) as u32 as u16,
            ..samples(table.get((j % N) as usize).copied().unwrap_or_default())
        };
        // The same periods again below, each timed alone, from here.
        let mut again_cell = core::mem::MaybeUninit::uninit();
        let Some(mut again) = c.fork(&mut again_cell) else { return Interrupt::FAILED };
        // Both contexts' work per period: the processor's load.
        let period = per_call(ticks, |j| {
            step(&mut c, black_box(fetch(j)));
            slow_context(c.slow_cell());
        });
        // The benchmark's own fetch of each period's samples from its table (the firmware
        // reads them from the ADC's and the timer's registers, outside this body).
        let fetch_cost = per_call(ticks, |j| {
            black_box(fetch(j));
        });
        // The longest period: the same N periods again, from a copy of the loop as it was
        // before them, each timed alone. The average above is the processor's load; this is
        // the 50 µs period's margin (a board's DWT reads it in cycles: `Status`'s timing).
        let empty = (0..8).map(|_| timed(ticks, || ())).min().unwrap_or(0);
        let mut worst = 0;
        for j in 0..N {
            let s = black_box(fetch(j));
            worst = worst.max(timed(ticks, || step(&mut again, s)));
            slow_context(again.slow_cell());
        }
        let worst = worst.saturating_sub(empty);
        let running_again = again.fast().mode() == Mode::Running;
        let before = CALIBRATION_SAMPLES + 1 + waited + k + N;
        let running = c.fast().mode() == Mode::Running;
        // The interrupt's deepest stack: a period serving each command the link can post,
        // with a snapshot asked for (the stop and the disable last), from a painted stack.
        let gains = c.config().speed().saturated_p().unwrap_or((0.0, 0.0));
        let spec = CaptureSpec {
            signals: [Signal::IA, Signal::IAlpha, Signal::OmegaRef, Signal::DutyA],
            trigger: Trigger::Immediate,
            pre_samples: 0,
            decimation: 1,
        };
        // Running, then (after the disable) Idle: a gain write that rebuilds the drive, and
        // an enable that starts it.
        let write_gains = BoardCommand::WriteSpeedGains { kp: gains.0, tau_max_nm: gains.1 };
        let commands = [
            ("GetStatus", BoardCommand::GetStatus),
            ("ReadSpeedGains", BoardCommand::ReadSpeedGains),
            ("WriteSpeedGains (refused: Running)", write_gains),
            ("SetReference", BoardCommand::SetReference(Reference::Speed(150.0))),
            ("ClearFault", BoardCommand::ClearFault),
            ("Refused", BoardCommand::Refused),
            ("Stop", BoardCommand::Stop),
            ("Enable (Running)", BoardCommand::Enable),
            ("Disable", BoardCommand::Disable),
            ("WriteSpeedGains (Idle)", write_gains),
            ("Enable (Idle)", BoardCommand::Enable),
            // The link task's own (no interrupt's work but the recording: the points' capture).
            ("ArmCapture", BoardCommand::ArmCapture(spec)),
            ("ReadCapture", BoardCommand::ReadCapture { chunk: 0 }),
        ];
        // Each context's deepest stack: painted before each turn, scanned after it.
        let sp = qemu_target::stack::pointer();
        let (mut fast_stack, mut slow_stack) = (0, 0);
        let mut served = true;
        let (mut worst_command, mut worst_name) = (0, "");
        let (mut worst_slow_command, mut worst_slow_name) = (0, "");
        let mut j = N;
        let mut i_now = i_ab;
        for (name, cmd) in commands {
            if matches!(cmd, BoardCommand::Stop) {
                // The commands before it were served while Running.
                served &= c.fast().mode() == Mode::Running;
            }
            if firmware::server::link_task_serves(&cmd) {
                // The capture's: the link task's own, in thread mode (`firmware::scope`).
                served &= c.scope().serve(&cmd).is_some();
                continue;
            }
            served &= shared.commands.post((cmd, Prepared::Nothing, LinkStats::default()));
            shared.request_snapshot();
            // Served by the slow context after the next tick's job (the drive's commands), or
            // by the control interrupt in a period without the slow step in flight (the
            // capture's): within a slow period and a plan's delay. Every period it waits
            // timed, and the slow context's turn after it.
            // Then the periods up to its adoption. The measured current is the reference
            // (the table's no longer: the commands change the references).
            let mut reply = None;
            let mut adopted = false;
            for _ in 0..=2 * (c.config().slow_divider() + c.config().plan_delay()) {
                if reply.is_some() && !c.slow_busy() {
                    adopted = true;
                    break;
                }
                let s = black_box(samples(codes(i_now, j)));
                j += 1;
                let top = qemu_target::stack::paint();
                let t = timed(ticks, || step(&mut c, s));
                fast_stack = fast_stack.max(qemu_target::stack::depth_below(sp, top));
                if t > worst_command {
                    (worst_command, worst_name) = (t, name);
                }
                let cell = c.slow_cell();
                let top = qemu_target::stack::paint();
                let u = timed(ticks, || {
                    slow_context(cell);
                });
                slow_stack = slow_stack.max(qemu_target::stack::depth_below(sp, top));
                if u > worst_slow_command {
                    (worst_slow_command, worst_slow_name) = (u, name);
                }
                if reply.is_none() {
                    reply = shared.commands.take();
                }
                i_now = answer(&mut machine, &c);
            }
            served &= reply.is_some() && adopted;
        }
        served &= c.fast().mode() == Mode::Magnetizing;
        let worst_command = worst_command.saturating_sub(empty);
        let worst_slow_command = worst_slow_command.saturating_sub(empty);
        // The worst-case sweep, through the same body (one `step` for all: a second call
        // site of `control_period` changed the firmware profile's inlining, +2 instructions
        // per period in the figures above).
        let mut sweep = [None; POINTS];
        for (w, p) in sweep.iter_mut().zip(points) {
            *w = worst_at(ticks, raw, ts_s, motor, &mut step, p);
        }
        Interrupt {
            period: if running { period - fetch_cost } else { f32::NAN },
            calls_before: before,
            stack_bytes: if served { fast_stack } else { 0 },
            slow_stack_bytes: if served { slow_stack } else { 0 },
            worst_period: if running && running_again { worst as f32 } else { f32::NAN },
            worst_command_period: if running && served { worst_command as f32 } else { f32::NAN },
            worst_command: worst_name,
            worst_slow_command: if running && served { worst_slow_command as f32 } else { f32::NAN },
            worst_slow_name,
            sweep,
        }
    }

    /// An operating point of the worst-case sweep (issue 54): the shaft turning at
    /// `omega_m_rad_s` (the encoder ramped up to it with the bridge off), a speed reference,
    /// the bus, and whether a capture is armed (recording every period).
    struct Point {
        name: &'static str,
        omega_m_rad_s: f32,
        reference_rad_s: f32,
        vdc_v: f32,
        capture: bool,
    }

    /// The longest runs at a [`Point`], instructions (to [`WORST_RESOLUTION`]): of the
    /// control interrupt's body, and of the slow context's job.
    #[derive(Clone, Copy)]
    struct Worst {
        fast: u32,
        slow: u32,
    }

    /// Operating points of the sweep.
    const POINTS: usize = 6;

    /// Periods of the sweep at each point: settled, then timed.
    const SETTLE_PERIODS: u32 = 4000;
    const TIMED_PERIODS: u32 = 2000;

    /// The firmware's control-interrupt body (`Shared::control_period`, as
    /// [`interrupt_period`]) at operating point `p`: calibrated at rest, the encoder ramped
    /// up to the point's speed over half a second with the bridge off, enabled, pre-charged
    /// and magnetized, Running under the point's speed reference for [`SETTLE_PERIODS`]
    /// (the flux settles to the point's, weakened at speed), then [`TIMED_PERIODS`] periods
    /// each timed alone. The samples are a [`Machine`]'s with `motor`'s circuit, its shaft
    /// held at the point's speed whatever the torque (through the ADC's quantisation): the
    /// loops close on a machine, at the voltage limit where the point asks for it. `None` if
    /// the drive is not Running at the end (a fault).
    fn worst_at(
        ticks: &Ticks,
        raw: &controller_core::drive::RawDriveConfig,
        ts_s: f32,
        motor: &MotorParams,
        step: &mut impl FnMut(&mut firmware::control::ControlLoop, firmware::control::Samples),
        p: &Point,
    ) -> Option<Worst> {
        use firmware::config::BOARD;
        use firmware::control::{CALIBRATION_SAMPLES, ControlLoop, Samples};
        let mut cell = core::mem::MaybeUninit::uninit();
        let mut c = ControlLoop::new(raw, &BOARD, &mut cell, pend_slow).ok()?;
        let zero = BOARD.current_offset_counts;
        let code = |i: f32| {
            let x = f32::from(zero) + i / BOARD.current_a_per_count;
            x.clamp(0.0, f32::from(BOARD.adc_full_scale)) as u16
        };
        let vdc = (p.vdc_v / BOARD.vdc_v_per_count) as u16;
        let counts_per_rad = 4.0 * BOARD.encoder_lines as f32 / core::f32::consts::TAU;
        // The encoder's counter, kept within one wrap of the 16-bit register (f32 keeps the
        // fraction there).
        let mut counter = 0.0f32;
        let mut advance = |omega_m_rad_s: f32| -> u16 {
            counter += omega_m_rad_s * ts_s * counts_per_rad;
            if counter >= 65536.0 {
                counter -= 65536.0;
            }
            counter as u16
        };
        let samples = |i_ab: AlphaBeta, encoder: u16| {
            let i = i_ab.inverse_clarke();
            Samples { i_abc: [code(i.a), code(i.b), code(i.c)], vdc, encoder, hardware_break: false }
        };
        for _ in 0..=CALIBRATION_SAMPLES {
            step(&mut c, samples(AlphaBeta::default(), 0));
            slow_context(c.slow_cell());
        }
        let ramp = (0.5 / ts_s) as u32;
        for k in 0..ramp {
            let w = p.omega_m_rad_s * (k + 1) as f32 / ramp as f32;
            step(&mut c, samples(AlphaBeta::default(), advance(w)));
            slow_context(c.slow_cell());
        }
        // The commands in a period without the slow step in flight, as the link's are served.
        while c.slow_busy() {
            step(&mut c, samples(AlphaBeta::default(), advance(p.omega_m_rad_s)));
            slow_context(c.slow_cell());
        }
        c.drive_mut(|mut d| d.enable())?.ok()?;
        // The machine behind the samples, its shaft held at the point's speed.
        let mut machine = Machine::new(motor, ts_s, p.omega_m_rad_s);
        let mut i_ab = AlphaBeta::default();
        let mut guard = 0;
        while (c.fast().mode() != Mode::Running || c.slow_busy()) && guard < 100_000 {
            step(&mut c, samples(i_ab, advance(p.omega_m_rad_s)));
            slow_context(c.slow_cell());
            i_ab = answer(&mut machine, &c);
            guard += 1;
        }
        c.drive_mut(|mut d| d.set_reference(Reference::Speed(p.reference_rad_s)))?.ok()?;
        if p.capture {
            // As the link task arms it (`firmware::scope`).
            (c.scope().serve(&BoardCommand::ArmCapture(recording_on())) == Some(Reply::Ack)).then_some(())?;
        }
        for _ in 0..SETTLE_PERIODS {
            step(&mut c, samples(i_ab, advance(p.omega_m_rad_s)));
            slow_context(c.slow_cell());
            i_ab = answer(&mut machine, &c);
        }
        let empty = (0..8).map(|_| timed(ticks, || ())).min().unwrap_or(0);
        let mut worst = Worst { fast: 0, slow: 0 };
        for _ in 0..TIMED_PERIODS {
            let s = black_box(samples(i_ab, advance(p.omega_m_rad_s)));
            let t = timed(ticks, || step(&mut c, s)).saturating_sub(empty);
            worst.fast = worst.fast.max(t);
            let cell = c.slow_cell();
            let mut ran = false;
            let t = timed(ticks, || ran = slow_context(cell)).saturating_sub(empty);
            if ran {
                worst.slow = worst.slow.max(t);
            }
            i_ab = answer(&mut machine, &c);
        }
        let mode = c.fast().mode();
        if mode != Mode::Running {
            println!("cost worst:{} ended in {:?}", p.name, mode);
        }
        (mode == Mode::Running).then_some(worst)
    }

    /// A capture of four signals armed on a trigger that never fires: it records every
    /// period, as a capture waiting for its event does.
    fn recording_on() -> CaptureSpec {
        CaptureSpec {
            signals: [Signal::IA, Signal::IAlpha, Signal::OmegaRef, Signal::DutyA],
            trigger: Trigger::Level { signal: Signal::Vdc, edge: Edge::Rising, level: 1e9 },
            pre_samples: 0,
            decimation: 1,
        }
    }

    /// A 12-bit ADC code of a phase current (±16.5 A full scale, offset 2048).
    fn code(i_a: f32) -> AdcCode {
        AdcCode((2048.0 + i_a * (2048.0 / 16.5)) as u16)
    }

    #[entry]
    fn main() -> ! {
        let Some(cp) = cortex_m::Peripherals::take() else { sh::exit(false) };
        let ticks = Ticks::start(cp.SYST);
        let (Ok(spec), Ok(adc_i), Ok(adc_v), Ok(pwm)) = (
            qemu_target::drive::drive_spec(),
            AdcScaling::new(16.5 / 2048.0, 2048, 4095),
            AdcScaling::new(0.1, 0, 4095),
            PwmScaling::new(4250),
        ) else {
            sh::exit(false)
        };
        // The firmware's loop below runs on a machine ([`Machine`]) whose shaft a dynamometer
        // holds at a set speed: the speed does not follow its reference, so the stall and
        // following-error windows never close.
        let mut spec = spec;
        spec.protection.following_time_s = 1e6;
        spec.protection.stall_time_s = 1e6;
        // The same configuration for the firmware's loop below, as the firmware embeds it.
        let Ok(raw) = DriveConfig::new(&spec).map(|c| c.to_raw()) else { sh::exit(false) };
        // The drive's own periods below have no machine behind them (each period's current the
        // reference of the period before): the encoder's plausibility against the machine
        // model would find the voltage of no machine (it runs every slow period; it never
        // fires), and the loops' request, against currents that ignore it, winds beyond the
        // hexagon, which would trip `LossOfControl`.
        spec.protection.encoder_check_time_s = 1e6;
        spec.protection.saturation_time_s = 1e6;
        let Ok(cfg) = DriveConfig::new(&spec) else { sh::exit(false) };
        let ts = 1.0 / spec.pwm_frequency_hz;
        // Inputs: a 1.5 A current vector rotating at 0.01 rad per sample.
        let current = |k: u32| {
            let sc = SinCos::new(k as f32 * 0.01);
            AlphaBeta { alpha: 1.5 * sc.cos, beta: 1.5 * sc.sin }.inverse_clarke()
        };
        // The encoder: a speed of 100 rad/s, an angle advancing at 10 rad/s (5e-3 rad per slow
        // period: the slow steps measured alone below start out of step with the periods'
        // cadence by up to a slow period, which at 100 rad/s would be a jump).
        let measure = |c: [AdcCode; 4], k: u32| {
            let [a, b, cc, v] = c;
            Measurements {
                i_abc_a: Abc { a: adc_i.to_f32(a), b: adc_i.to_f32(b), c: adc_i.to_f32(cc) },
                vdc_v: adc_v.to_f32(v),
                omega_m_rad_s: 100.0,
                theta_m_rad: k as f32 * 5e-4,
            }
        };

        // The drive, magnetized (ideal current tracking) and Running with a speed reference.
        let mut drive = Drive::new(cfg);
        let _ = drive.enable();
        let mut i_ab = AlphaBeta::default();
        let mut guard = 0u32;
        while drive.mode() != Mode::Running && guard < 100_000 {
            let m = Measurements {
                i_abc_a: i_ab.inverse_clarke(),
                vdc_v: 310.0,
                ..measure([AdcCode::default(); 4], guard)
            };
            drive.step(&m);
            i_ab = drive.telemetry().i_ref_ab_a;
            guard += 1;
        }
        // The periods below go on from here (the encoder's angle too).
        let k0 = guard;
        let _ = drive.set_reference(Reference::Speed(150.0));
        // The measured periods' inputs: what ideal current loops measure — each period's
        // current the reference of the period before, through the ADC's quantisation —
        // rehearsed on a copy of the drive, which is deterministic: the measured run sees
        // exactly these currents, and its loops run in their linear range, as a drive's do
        // (a current that ignores the references, as this benchmark used before, held them
        // saturated: every period then took the modulator's limiting path and the loops'
        // tracking, ≈ 50 instructions that a drive in its linear range does not run).
        let mut codes = [[AdcCode::default(); 4]; N as usize];
        let mut rehearsal = drive;
        for (k, c) in (0u32..).zip(codes.iter_mut()) {
            let i = i_ab.inverse_clarke();
            *c = [code(i.a), code(i.b), code(i.c), AdcCode(3100)];
            rehearsal.step(&measure(*c, k0 + k));
            i_ab = rehearsal.telemetry().i_ref_ab_a;
        }
        let input = |k: u32| codes.get((k % N) as usize).copied().unwrap_or_default();

        // Whole PWM periods as the interrupt runs them (`Drive::step`: the slow step every
        // `slow_divider`-th, and the fast step right after it carrying the once-per-slow-
        // period work — encoder and stuck-switch checks, the rotor-resistance law); the fast
        // step's average is a period less its share of the slow step. (Calling `fast_step`
        // alone froze the cadence: the after-slow work ran on every call or on none, by the
        // phase the magnetizing left it in.)
        let period = per_call(&ticks, |k| {
            let m = measure(black_box(input(k)), k0 + k);
            let out = drive.step(&m);
            if let controller_core::drive::PhaseCommand::Duty(d) = out.phases {
                black_box(pwm.compare3(d));
            }
        });
        // The drive as the measured periods left it: the stack's depth is measured on it
        // (below), not on the drive the slow steps alone then ran.
        let after_periods = drive;
        // The slow steps alone, the encoder going on where the periods left it, at the same
        // increment per read (a jump back would be `EncoderLoss`).
        // Its currents are the plan's references, rehearsed on a copy as above (the
        // open-phase and stuck-switch checks compare the two there).
        let divider = u32::from(drive.config().slow_divider());
        let mut slow_codes = [[AdcCode::default(); 4]; N as usize];
        let mut rehearsal = drive;
        for (k, c) in (0u32..).zip(slow_codes.iter_mut()) {
            let i = rehearsal.ifoc_state().i_ref_ab().inverse_clarke();
            *c = [code(i.a), code(i.b), code(i.c), AdcCode(3100)];
            rehearsal.slow_step(&measure(*c, k0 + N + divider * k));
        }
        let slow_input = |k: u32| slow_codes.get((k % N) as usize).copied().unwrap_or_default();
        let slow =
            per_call(&ticks, |k| drive.slow_step(&measure(black_box(slow_input(k)), k0 + N + divider * k)));
        let running = drive.mode() == Mode::Running;
        if !running {
            println!("cost: the drive left Running in its slow steps: {:?}", drive.mode());
        }
        let fast = period - slow / divider as f32;

        // The firmware's own control-interrupt body, `firmware::interrupt::Shared::
        // control_period`: raw samples in (ADC codes, the encoder's counter), the bridge's
        // compare values out, with what the firmware does around the drive — the break
        // check, the pre-charge and calibration checks, the encoder read at the slow step,
        // the capture's call, the link's requests. TIM1's registers are plain memory here
        // ([`Registers`]). The same drive as above, its protection whole but for the speed's
        // windows; the currents a machine's (rehearsed on a copy), its shaft and the encoder
        // turning at 10 rad/s.
        // The worst case (issue 54): the interrupt's longest period at each operating point,
        // from standstill to top speed (0.9 × the overspeed level) motoring and generating
        // in field weakening, braking with the chopper on, a capture armed; the commands
        // above. Derived from the drive file's limits, not from one speed.
        let top = 0.9 * spec.protection.overspeed_rad_s as f32;
        let vdc_rated = 310.0;
        let chopper_on = spec.protection.brake_chopper.map_or(vdc_rated, |b| b.on_v as f32 + 5.0);
        let points: [Point; POINTS] = [
            Point {
                name: "standstill",
                omega_m_rad_s: 0.0,
                reference_rad_s: 0.0,
                vdc_v: vdc_rated,
                capture: false,
            },
            Point {
                name: "low_speed",
                omega_m_rad_s: 0.03 * top,
                reference_rad_s: 0.03 * top,
                vdc_v: vdc_rated,
                capture: false,
            },
            Point {
                name: "top_speed_motoring",
                omega_m_rad_s: top,
                reference_rad_s: 1.1 * top,
                vdc_v: vdc_rated,
                capture: false,
            },
            Point {
                name: "top_speed_generating",
                omega_m_rad_s: top,
                reference_rad_s: 0.5 * top,
                vdc_v: vdc_rated,
                capture: false,
            },
            Point {
                name: "braking_chopper_on",
                omega_m_rad_s: top,
                reference_rad_s: 0.5 * top,
                vdc_v: chopper_on,
                capture: false,
            },
            Point {
                name: "capture_armed_top_speed",
                omega_m_rad_s: top,
                reference_rad_s: 1.1 * top,
                vdc_v: vdc_rated,
                capture: true,
            },
        ];

        let isr = interrupt_period(&ticks, &raw, ts as f32, &spec.motor, &points);
        let sweep = isr.sweep;

        // Components alone.
        let adc = per_call(&ticks, |k| {
            black_box(measure(black_box(input(k)), k));
        });
        let clarke = per_call(&ticks, |k| {
            black_box(black_box(current(k % 64)).clarke());
        });
        let sincos = per_call(&ticks, |k| {
            black_box(SinCos::new(black_box(k as f32 * 0.01 - 3.0)));
        });
        // The sensorless observer's step (`[controller] speed_feedback = "sensorless"`, run
        // every period before the drive's steps): the drive file's motor and rate, a 100 V
        // voltage and the 1.5 A current turning at 0.01 rad per sample — magnetized past the
        // flux floor first, so that the speed adaptation runs in every timed step.
        let observer = match ObserverConfig::new(
            &spec.motor,
            ts,
            controller_core::drive::observer_speed_bandwidth_rad_s(ts, ts * f64::from(spec.slow_divider)),
            spec.flux_floor_wb,
            f64::from(spec.motor.pole_pairs()) * spec.protection.overspeed_rad_s,
        ) {
            Ok(o) => {
                let u = |k: u32| {
                    let sc = SinCos::new((k % 600) as f32 * 0.01 - 3.0);
                    AlphaBeta { alpha: 100.0 * sc.cos, beta: 100.0 * sc.sin }
                };
                let mut obs = FluxObserver::new(AlphaBeta::default());
                for k in 0..N {
                    obs.step(&o, u(k), current(k).clarke());
                }
                per_call(&ticks, |k| {
                    black_box(obs.step(&o, black_box(u(k)), black_box(current(k).clarke())));
                })
            }
            Err(_) => f32::NAN,
        };
        let icad = match CurrentControllerConfig::<f32>::new(
            &CurrentLaw::ICAD_EQ20,
            ts,
            Discretization::Tustin,
            180.0,
        ) {
            Ok(c) => {
                let mut s = CurrentState::default();
                per_call(&ticks, |k| {
                    let e = black_box(current(k % 64)).clarke();
                    black_box(c.request(&mut s, e.alpha, e.beta, 207.0));
                }) - per_call(&ticks, |k| {
                    black_box(black_box(current(k % 64)).clarke());
                })
            }
            Err(_) => f32::NAN,
        };
        // The IFOC's two rates: its fast step (references, field turn, the flux model's
        // sum), and the slow step's plan with its two `SinCos::new` and its division.
        let (ifoc, ifoc_plan) = match IfocConfig::new(&spec.motor, ts, spec.flux_floor_wb, spec.i_ref_max_a) {
            Ok(c) => {
                let mut s = c.state(0.9, 1.0);
                let flux = c.flux_command(0.9);
                let plan = per_call(&ticks, |k| {
                    c.plan(
                        &mut s,
                        &flux,
                        TorqueCommand::TorqueNm(black_box(0.3)),
                        k as f32 * 1e-3,
                        Dq::default(),
                    );
                    // The plan is state for the fast steps: kept, or it is optimised away.
                    black_box(&mut s);
                });
                let step = per_call(&ticks, |k| {
                    black_box(c.step(&mut s, black_box(current(k % 64)).clarke()));
                }) - per_call(&ticks, |k| {
                    black_box(black_box(current(k % 64)).clarke());
                });
                (step, plan)
            }
            Err(_) => (f32::NAN, f32::NAN),
        };
        // The slow step's operating point (issue 17): the envelope's solver, at speeds from
        // standstill to beyond the base speed and torques across the envelope.
        let envelope = controller_core::envelope::EnvelopeConfig::new(&spec.motor);
        let operating_point = per_call(&ticks, |k| {
            let w = black_box((k % 64) as f32 * 6.5);
            let t = black_box(((k / 64) % 8) as f32 * 0.3 - 1.0);
            black_box(envelope.operating_point(t, w, 0.634, 175.0, 4.0));
        });
        let i_q_at_flux = per_call(&ticks, |k| {
            let w = black_box((k % 64) as f32 * 6.5);
            black_box(envelope.i_q_max_at_flux(black_box(0.6), 0.4, w, 175.0, 3.9, 1.0));
        });
        // The rotor-resistance law once per slow period, with evidence it listens to (a
        // loaded machine at speed; in the periods above the synthetic current keeps the loops
        // saturated, so it mostly does not), and one step of the magnetizing fit.
        let model = EnvelopeConfig::new(&spec.motor);
        let (law, inductance_law, fit, on_curve) =
            match MrasConfig::new(&spec.motor, ts, spec.slow_divider, [1.0, 2.0], [0.6, 1.0]) {
                Ok(c) => {
                    let mut r = 1.4f32;
                    let law = per_call(&ticks, |k| {
                        let e = Evidence {
                            i: Dq { d: 0.63, q: 1.2 + k as f32 * 1e-4 },
                            v: Dq { d: -40.0, q: 120.0 },
                            w_e_rad_s: 150.0,
                            psi_r_wb: 0.9,
                            v_limit_v: 168.0,
                            i_ref_step_a: 0.0,
                        };
                        r = c.update(black_box(r), &model, black_box(&e));
                    });
                    // The inductance law on the same machine at no load, listening (its flux
                    // model settled at L̂_m·i_d).
                    let mut l = 0.9f32;
                    let psi = model.lm2_over_lr_h() / model.lm_over_lr() * 0.63;
                    let inductance = per_call(&ticks, |k| {
                        let e = Evidence {
                            i: Dq { d: 0.63, q: k as f32 * 1e-5 },
                            v: Dq { d: 3.0, q: 130.0 },
                            w_e_rad_s: 150.0,
                            psi_r_wb: psi,
                            v_limit_v: 168.0,
                            i_ref_step_a: 0.0,
                        };
                        l = c.update_inductance(black_box(l), &model, black_box(&e));
                    });
                    let mut f = RotorFit::new(true);
                    let n = spec.slow_divider;
                    // A slow period at rest: its d-axis voltage sum at 0.634 A.
                    let at_rest = |v_d_sum: f32, saturating: bool| FitPeriod {
                        v_sum: Dq { d: v_d_sum, q: 0.0 },
                        steps: n,
                        i_d_a: 0.634,
                        i_d_mean_a: 0.634,
                        field_step_rad: 0.0,
                        built_inductance_scale: 1.0,
                        saturating,
                        delay_steps: 0,
                    };
                    let fit = per_call(&ticks, |k| {
                        if k % 512 == 0 {
                            f = RotorFit::new(true);
                        }
                        let v = black_box(10.0 + 1e3 / (k % 512 + 100) as f32) * f32::from(n);
                        black_box(c.fit(&mut f, &at_rest(v, false), 1.0));
                    });
                    // A saturating motor's fit to its end — a first-order build at the rotor's
                    // time constant, 10 V of constant part — then its rotor resistance read
                    // on the curve (once per enable): the saturating twin's law
                    // (drives/delorenzo-saturating.toml: β 0.956813/Wb, S = 7; its
                    // unsaturated inductance, 2.0 H, sets only where the flux sits).
                    let on_curve = match MagnetizingCurve::law(2.0, 0.956813, 7.0)
                        .ok()
                        .and_then(|curve| MagnetizingTable::of_curve(&curve, 0.9))
                    {
                        Some((table, i_rated_a)) => {
                            let chord = MagnetizingChord::new(Some(&table), i_rated_a, 0.9);
                            let mut f = RotorFit::new(true);
                            let tr_s = spec.motor.tr_s() as f32;
                            let mut t_s = 0.0f32;
                            for _ in 0..100_000 {
                                let mut v = 0.0;
                                for _ in 0..n {
                                    v += 10.0 + 60.0 * libm::expf(-t_s / tr_s);
                                    t_s += ts as f32;
                                }
                                if c.fit(&mut f, &at_rest(v, true), 1.0).is_some() {
                                    break;
                                }
                            }
                            per_call(&ticks, |_| {
                                black_box(c.rotor_resistance_on_curve(black_box(&f), 1.0, |psi| {
                                    chord.current_at_flux(psi)
                                }));
                            })
                        }
                        None => f32::NAN,
                    };
                    (law, inductance, fit, on_curve)
                }
                Err(_) => (f32::NAN, f32::NAN, f32::NAN, f32::NAN),
            };
        let dead_time = per_call(&ticks, |k| {
            let i = black_box(current(k % 64));
            black_box(svpwm::compensate_dead_time(Abc { a: 0.4, b: 0.5, c: 0.6 }, i, 0.01, 0.004));
        }) - per_call(&ticks, |k| {
            black_box(black_box(current(k % 64)));
        });
        let svm = per_call(&ticks, |k| {
            let v = black_box(current(k % 64)).clarke().scale(60.0);
            black_box(svpwm::modulate(v, 310.0));
        }) - clarke;
        let compare = per_call(&ticks, |k| {
            let d = black_box(k as f32 * (1.0 / 4096.0));
            black_box(pwm.compare3(Abc { a: d, b: d * 0.5, c: 1.0 - d }));
        });
        // The capture (issue 19), as the firmware's control interrupt takes it after every
        // step (`firmware::scope::Scope`, the drive's signals each made alone by
        // `FastPeriod`): the call while nothing is armed, and a recorded sample of four
        // signals (armed by the link's command on a trigger that never fires, so it records
        // on).
        let out = FastOutput {
            phases: PhaseCommand::Duty(Abc { a: 0.4, b: 0.5, c: 0.6 }),
            mode: Mode::Running,
            brake: false,
        };
        static SCOPE: Scope = Scope::new();
        let (fast_side, _) = drive.into_parts();
        let mut take = |k: u32| {
            let m = measure(input(k), k);
            if SCOPE.recording() {
                SCOPE.record(&FastPeriod { m: black_box(&m), out: black_box(&out), fast: &fast_side });
            }
        };
        let capture_idle = per_call(&ticks, &mut take) - adc;
        let capture_sample = match SCOPE.serve(&BoardCommand::ArmCapture(recording_on())) {
            Some(Reply::Ack) => per_call(&ticks, &mut take) - adc,
            _ => f32::NAN,
        };

        // Stack depth of the firmware's interrupt body, `Drive::step` (the fast step, and
        // every slow_divider-th period the slow step): 20 periods from a painted stack.
        // On the drive the measured periods left, going on from there (its encoder too), its
        // currents rehearsed from there as above. (On the drive the slow steps alone had run
        // — slow steps whose references no fast step turned, so the stuck-switch check's
        // samples compared the currents with stale ones — the first after-slow check of these
        // periods named `SwitchOpen` once the rotor-resistance law took another path.)
        const STACK_PERIODS: u32 = 20;
        let at = |k: u32| k0 + N + k;
        let mut stacked = after_periods;
        let mut stack_codes = [[AdcCode::default(); 4]; STACK_PERIODS as usize];
        let mut rehearsal = stacked;
        let mut i_ab = rehearsal.telemetry().i_ref_ab_a;
        for (k, c) in (0u32..).zip(stack_codes.iter_mut()) {
            let i = i_ab.inverse_clarke();
            *c = [code(i.a), code(i.b), code(i.c), AdcCode(3100)];
            rehearsal.step(&measure(*c, at(k)));
            i_ab = rehearsal.telemetry().i_ref_ab_a;
        }
        let sp = qemu_target::stack::pointer();
        let top = qemu_target::stack::paint();
        for (k, c) in (0u32..).zip(stack_codes) {
            black_box(stacked.step(&measure(black_box(c), at(k))));
        }
        let stack = qemu_target::stack::depth_below(sp, top);
        let running = running && stacked.mode() == Mode::Running;
        if !running {
            println!("cost: the drive left Running: {:?}", stacked.mode());
        }

        println!("cost magnetizing_periods {k0}");
        println!("cost period {:.1}", period);
        println!("cost fast_step {:.1}", fast);
        println!("cost slow_step {:.1}", slow);
        println!("cost interrupt_calls_before {}", isr.calls_before);
        println!("cost interrupt_period {:.1}", isr.period);
        println!("cost interrupt_fast_step {:.1}", isr.period - slow / divider as f32);
        println!(
            "cost interrupt_worst_period {:.0} (the longest of {N} periods, each timed alone, ±{WORST_RESOLUTION})",
            isr.worst_period
        );
        println!(
            "cost interrupt_worst_command_period {:.0} (the control interrupt's longest period with a command the link posts and a snapshot asked for: {}, ±{WORST_RESOLUTION})",
            isr.worst_command_period, isr.worst_command
        );
        println!(
            "cost slow_context_worst_command {:.0} (the slow context's longest turn serving them, its job included: {}, ±{WORST_RESOLUTION})",
            isr.worst_slow_command, isr.worst_slow_name
        );
        let nan = |w: Option<u32>| w.map_or(f32::NAN, |w| w as f32);
        let (mut fast_worst, mut slow_worst) = (0u32, 0u32);
        for (p, w) in points.iter().zip(sweep) {
            println!(
                "cost worst:{} fast {:.0} slow {:.0} (ω {:.0} rad/s, reference {:.0} rad/s, bus {:.0} V)",
                p.name,
                nan(w.map(|w| w.fast)),
                nan(w.map(|w| w.slow)),
                p.omega_m_rad_s,
                p.reference_rad_s,
                p.vdc_v
            );
            if let Some(w) = w {
                (fast_worst, slow_worst) = (fast_worst.max(w.fast), slow_worst.max(w.slow));
            }
        }
        let swept = sweep.iter().all(Option::is_some);
        let command = if isr.worst_command_period.is_finite() { isr.worst_command_period as u32 } else { 0 };
        let slow_command = if isr.worst_slow_command.is_finite() { isr.worst_slow_command as u32 } else { 0 };
        println!(
            "cost fast_interrupt_worst {:.0} (the control interrupt's longest period over the points and the commands, ±{WORST_RESOLUTION})",
            nan(swept.then_some(fast_worst.max(command)))
        );
        println!(
            "cost slow_context_worst {:.0} (the slow context's longest turn over the points and the commands, ±{WORST_RESOLUTION})",
            nan(swept.then_some(slow_worst.max(slow_command)))
        );
        println!("cost part:adc_scaling_4ch {:.1}", adc);
        println!("cost part:clarke {:.1}", clarke);
        println!("cost part:icad_two_axes {:.1}", icad);
        println!("cost part:ifoc_fast {:.1}", ifoc);
        println!("cost part:ifoc_plan_incl_sincos {:.1}", ifoc_plan);
        println!("cost part:sincos {:.1}", sincos);
        println!("cost part:observer_step {:.1}", observer);
        println!("cost part:svpwm {:.1}", svm);
        println!("cost part:compare_3ch {:.1}", compare);
        println!("cost part:capture_idle {:.1}", capture_idle);
        println!("cost part:capture_sample {:.1}", capture_sample);
        println!("cost part:envelope_operating_point {:.1}", operating_point);
        println!("cost part:envelope_i_q_max_at_flux {:.1}", i_q_at_flux);
        println!("cost part:dead_time_compensation {:.1}", dead_time);
        println!("cost part:rotor_resistance_law {:.1}", law);
        println!("cost part:inductance_law {:.1}", inductance_law);
        println!("cost part:rotor_resistance_fit {:.1}", fit);
        println!("cost part:rotor_resistance_on_curve {:.1}", on_curve);
        println!("stack drive_step_bytes {stack}");
        let frame = qemu_target::stack::EXCEPTION_FRAME_FP_BYTES;
        println!(
            "stack interrupt_bytes {} (the control interrupt's body with a command posted, with the {frame} B exception frame)",
            isr.stack_bytes + frame,
        );
        println!(
            "stack slow_context_bytes {} (the slow context's turn serving the commands, with its {frame} B exception frame)",
            isr.slow_stack_bytes + frame,
        );
        println!(
            "stack nested_bytes {} (the two: the control interrupt preempts the slow context on the board)",
            isr.stack_bytes + isr.slow_stack_bytes + 2 * frame,
        );
        sh::exit(
            running
                && isr.stack_bytes > 0
                && isr.worst_period.is_finite()
                && isr.worst_command_period.is_finite()
                && swept,
        )
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("cost: a Cortex-M program; `cargo xtask qemu` runs it under QEMU with -icount shift=0");
}
