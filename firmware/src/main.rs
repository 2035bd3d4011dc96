//! STM32G474RE drive firmware (NUCLEO-G474RE + three-phase inverter board).
//!
//! Start-up: clocks (170 MHz from HSI16 via the PLL, boost mode) → drive configuration
//! validated ([`firmware::control::ControlLoop::init`]; an invalid one never enables the
//! bridge) → TIM1 centre-aligned complementary PWM at 20 kHz with dead time and the break
//! input → ADC1 injected conversions (three phase currents, bus voltage) triggered by TIM1
//! TRGO2 = OC4REF just before the counter's top (the centre of the low-side conduction
//! interval, where low-side shunts carry the phase currents) → TIM4
//! quadrature encoder → control interrupt → link task (which also feeds the watchdog).
//!
//! Priorities: the control interrupt `ADC1_2` (end of the injected sequence) is the only
//! one at P0; the time driver (TIM3), the UART and its DMA run at P4 and below; the tasks run
//! in thread mode.
//!
//! On the host this crate builds to a program that re-runs cargo for the board target, so
//! `cargo run -p firmware --release` flashes through probe-rs (runner in `.cargo/config.toml`).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use controller_core::calibration::CalibrationError;
    use controller_core::link::{self, BoardCommand, FrameDecoder, LinkStats, LoopTiming, MAX_FRAME, Reply};
    use core::mem::ManuallyDrop;
    use core::sync::atomic::{AtomicPtr, AtomicU32, Ordering};
    use defmt_rtt as _;
    use embassy_executor::Spawner;
    use embassy_stm32::adc::{Adc, AdcChannel as _, Exten, SampleTime};
    use embassy_stm32::gpio::{AfType, AnyPin, Flex, Level, Output, OutputType, Pull, Speed};
    use embassy_stm32::interrupt;
    use embassy_stm32::interrupt::{InterruptExt, Priority};
    use embassy_stm32::mode::Async;
    use embassy_stm32::pac;
    use embassy_stm32::pac::timer::vals::{Bkp, Ckd, Mms2, Ossi, Ossr};
    use embassy_stm32::pac::timer::vals::{Dir, Ocm, Urs};
    use embassy_stm32::peripherals::{
        IWDG, PA0, PA1, PA2, PA3, PA6, PA8, PA9, PA10, PB6, PB7, PB13, PB14, PB15, PC0, PC1, TIM1,
    };
    use embassy_stm32::timer::low_level::{CountingMode, FilterValue, OutputCompareMode, Timer as LlTimer};
    use embassy_stm32::timer::qei::{Config as QeiConfig, Qei};
    use embassy_stm32::timer::{
        BkIn1, BreakInputPin, Ch1, Ch2, Ch3, Channel, TimerComplementaryPin, TimerPin,
    };
    use embassy_stm32::usart::{self, RingBufferedUartRx, Uart, UartTx};
    use embassy_stm32::wdg::IndependentWatchdog;
    use embassy_stm32::{Config, Peri, bind_interrupts, dma, peripherals};
    use embassy_time::{Duration, Timer, with_timeout};
    use firmware::config::{
        BOARD, DEAD_TIME_TICKS, DRIVE_CONFIG, ENCODER_FILTER, LINK_TIMEOUT_MS, TIM_CLOCK_HZ,
    };
    use firmware::interrupt::Shared;

    /// The drive file's dead time as TIM1's DTG code (CKD = 00), at compile time: a dead
    /// time the generator cannot give stops the build.
    const DEAD_TIME_DTG: u8 = match controller_core::scaling::dead_time_dtg(DEAD_TIME_TICKS) {
        Some(code) => code,
        None => panic!("the drive file's dead time exceeds TIM1's 1 008 ticks"),
    };

    /// A TIM1 output pin handed to the timer (alternate function `af`, push-pull, very high
    /// speed — what embassy's `PwmPin::new` does; its output register low, as embassy's).
    fn pwm_pin(af: u8, pin: Peri<'static, AnyPin>) -> Flex<'static> {
        let mut f = Flex::new(pin);
        f.set_low();
        f.set_as_af_unchecked(af, AfType::output(OutputType::PushPull, Speed::VeryHigh));
        f
    }
    use firmware::control::{
        Calibration, Cells, ControlError, ControlLoop, Samples, SlowCell, UPDATE_REPETITION,
        check_update_timing,
    };
    use firmware::output::{OutputStage, Outputs, stop_for_good};
    use firmware::scope::Scope;
    use firmware::server;

    bind_interrupts!(struct Irqs {
        LPUART1 => usart::InterruptHandler<peripherals::LPUART1>;
        DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
        DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
    });

    /// The control loop, handed over once: stored at start-up, taken by the control
    /// interrupt at its first run ([`take_control`]), then the interrupt's alone (the link
    /// task reaches it through `SHARED`). No critical section on either side.
    static CONTROL: AtomicPtr<ControlLoop<'static>> = AtomicPtr::new(core::ptr::null_mut());
    /// Where the control loop lives: zero-initialised (`.bss`), so its ≈ 5.2 KiB take no flash
    /// for an initial image, as an `Option<ControlLoop>` static did.
    static CONTROL_CELL: static_cell::StaticCell<ControlLoop<'static>> = static_cell::StaticCell::new();
    /// What the control loop shares (`firmware::control::Cells`): the drive's slow side (issue
    /// 54's two contexts), lent by the control interrupt to the slow interrupt ([`CORDIC`])
    /// from the slow step's tick until its job is done (`firmware::boundary::Handoff`), and the
    /// capture, the link task's while the control interrupt does not record
    /// (`firmware::scope`); zero-initialised as the loop's.
    static CELLS: static_cell::StaticCell<Cells> = static_cell::StaticCell::new();
    /// The slow cell for the slow interrupt, stored once at start-up (null before: the
    /// interrupt then does nothing).
    static SLOW: AtomicPtr<SlowCell> = AtomicPtr::new(core::ptr::null_mut());

    /// The slow step's job handed over ([`SlowCell`]): pend the slow context — a vector no
    /// peripheral of the board uses, CORDIC's, at the priority below the control interrupt's
    /// (its handler, [`CORDIC`], runs once the control interrupt returns, and is preempted by
    /// the next).
    fn pend_slow(_: &SlowCell) {
        interrupt::CORDIC.pend();
    }
    /// Control interrupts served; the link task feeds the watchdog only while this advances.
    static ISR_COUNT: AtomicU32 = AtomicU32::new(0);
    /// The control interrupt's longest step and overruns (`Status`).
    static LOOP_TIMER: firmware::control::LoopTimer = firmware::control::LoopTimer::new();
    /// What the control interrupt and the link task share, lock-free: the snapshot of the
    /// control loop (published by the interrupt), commands in, the link watchdog's stop.
    static SHARED: Shared = Shared::new();

    /// TIM1 and the brake pin as the control interrupt's output stage (`firmware::output`,
    /// host-tested against a model of this logic).
    struct Tim1;

    /// The brake chopper's gate: PB5 (see [`Pins::brake`]), written through BSRR (one atomic
    /// store: no read-modify-write of the port).
    const BRAKE_PIN: usize = 5;

    /// TIM1_SR's `rc_w0` flags (RM0440 §28.6.5): UIF, CC1IF–CC4IF, COMIF, TIF (bits 0–6),
    /// B2IF, CC1OF–CC4OF, SBIF (8–13), CC5IF, CC6IF (16, 17), IDXF, DIRF, IERRF, TERRF
    /// (20–23). Writing 1 leaves a flag alone, 0 clears it.
    const SR_RC_W0_FLAGS: u32 = 0x00F3_3F7F | (1 << 7);
    /// BIF, bit 7.
    const SR_BIF: u32 = 1 << 7;
    /// UIF, bit 0.
    const SR_UIF: u32 = 1;
    /// Status-register reads to wait for TIM1's first update event at start.
    const UPDATE_WAIT_POLLS: u32 = 100_000;

    impl OutputStage for Tim1 {
        fn break_flag(&mut self) -> bool {
            pac::TIM1.sr().read().bif(0)
        }
        fn clear_break_flag(&mut self) {
            // A mask, not read-modify-write: flags set meanwhile are kept.
            pac::TIM1.sr().write_value(pac::timer::regs::SrAdv(SR_RC_W0_FLAGS & !SR_BIF));
        }
        fn outputs_enabled(&mut self) -> bool {
            pac::TIM1.bdtr().read().moe()
        }
        fn set_compare(&mut self, [a, b, c]: [u16; 3]) {
            let tim = pac::TIM1;
            tim.ccr(0).write(|w| w.set_ccr(a));
            tim.ccr(1).write(|w| w.set_ccr(b));
            tim.ccr(2).write(|w| w.set_ccr(c));
        }
        fn enable_outputs(&mut self) {
            pac::TIM1.bdtr().modify(|w| w.set_moe(true));
        }
        fn disable_outputs(&mut self) {
            pac::TIM1.bdtr().modify(|w| w.set_moe(false));
        }
        fn set_brake(&mut self, on: bool) {
            pac::GPIOB.bsrr().write(|w| {
                w.set_bs(BRAKE_PIN, on);
                w.set_br(BRAKE_PIN, !on);
            });
        }
    }

    fn clocks() -> Config {
        use embassy_stm32::rcc::{
            AHBPrescaler, APBPrescaler, Pll, PllMul, PllPreDiv, PllRDiv, PllSource, Sysclk, mux,
        };
        let mut config = Config::default();
        config.rcc.hsi = true;
        // 16 MHz / 4 · 85 / 2 = 170 MHz.
        config.rcc.pll = Some(Pll {
            source: PllSource::HSI,
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL85,
            divp: None,
            divq: None,
            divr: Some(PllRDiv::DIV2),
        });
        config.rcc.sys = Sysclk::PLL1_R;
        config.rcc.boost = true;
        config.rcc.ahb_pre = AHBPrescaler::DIV1;
        config.rcc.apb1_pre = APBPrescaler::DIV1;
        config.rcc.apb2_pre = APBPrescaler::DIV1;
        config.rcc.mux.adc12sel = mux::Adcsel::SYS;
        config.bdma_interrupt_priority = Priority::P5; // G4 DMA is the "bdma" kind
        config
    }

    /// The board's pin map — the one place that names pins (another board changes this
    /// struct, its constructor, and `firmware::board`).
    struct Pins {
        /// TIM1 CH1..CH3 (high sides) and CH1N..CH3N (low sides).
        pwm_high: (Peri<'static, PA8>, Peri<'static, PA9>, Peri<'static, PA10>),
        pwm_low: (Peri<'static, PB13>, Peri<'static, PB14>, Peri<'static, PB15>),
        /// TIM1 BKIN: the power board's overcurrent comparator, active low.
        bkin: Peri<'static, PA6>,
        /// ADC1 IN1, IN2, IN6: phase-current amplifiers a, b, c; IN7: bus-voltage divider.
        i_abc: (Peri<'static, PA0>, Peri<'static, PA1>, Peri<'static, PC0>),
        vdc: Peri<'static, PC1>,
        /// TIM4 CH1/CH2: encoder A/B.
        encoder: (Peri<'static, PB6>, Peri<'static, PB7>),
        /// LPUART1 TX/RX: the NUCLEO's ST-LINK virtual COM port.
        link_tx: Peri<'static, PA2>,
        link_rx: Peri<'static, PA3>,
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let p = embassy_stm32::init(clocks());
        // The brake gate first: a push-pull output, low (resistor out) until the drive asks.
        // From reset until here the pin floats (an input): the power board's pull-down holds
        // the chopper off (docs/firmware.md's bring-up).
        let brake = Output::new(p.PB5, Level::Low, Speed::Low);
        // Flash prefetch (off from reset; the ART caches are on): instruction fetches from
        // flash at 4 wait states stall less on straight code (its effect is a board
        // measurement: docs/firmware.md's bring-up).
        pac::FLASH.acr().modify(|w| w.set_prften(true));
        // A breakpoint stops TIM1 (outputs frozen in their idle state by the break logic's
        // OSSI) and the independent watchdog with the core, instead of leaving the PWM running.
        pac::DBGMCU.apb2fzr().modify(|w| w.set_tim1(true));
        pac::DBGMCU.apb1lfzr().modify(|w| w.set_iwdg(true));
        // The microcontroller's own failures are TIM1 break inputs (`firmware::safety`): a
        // core lockup (a fault inside the HardFault handler), an SRAM parity error, the
        // supply below the PVD's level, a flash ECC double error. The PVD first (its level
        // and enable are locked by PVDL), then the links, read back.
        pac::RCC.apb1enr1().modify(|w| w.set_pwren(true));
        pac::PWR.cr2().modify(|w| {
            w.set_pls(firmware::safety::PVD_LEVEL_CODE);
            w.set_pvde(true);
        });
        pac::SYSCFG.cfgr2().write_value(pac::syscfg::regs::Cfgr2(firmware::safety::BREAK_LINKS));
        if let Err(e) = firmware::safety::check_break_links(pac::SYSCFG.cfgr2().read().0) {
            defmt::error!("SYSCFG_CFGR2 reads {=u32:#x}, not every break link: bridge stays off", e.read);
            halt_safe();
        }
        // The cycle counter the control interrupt times itself with (`Status`). Taken once
        // here; nothing else uses the core peripherals (the time driver is TIM3).
        if let Some(mut cp) = cortex_m::Peripherals::take() {
            cp.DCB.enable_trace();
            cp.DWT.enable_cycle_counter();
        }
        let pins = Pins {
            pwm_high: (p.PA8, p.PA9, p.PA10),
            pwm_low: (p.PB13, p.PB14, p.PB15),
            bkin: p.PA6,
            i_abc: (p.PA0, p.PA1, p.PC0),
            vdc: p.PC1,
            encoder: (p.PB6, p.PB7),
            link_tx: p.PA2,
            link_rx: p.PA3,
        };
        defmt::info!("drive firmware: 170 MHz, validating the drive configuration");

        // Validate at construction: with an invalid configuration nothing is enabled.
        let control = match ControlLoop::init(
            CONTROL_CELL.uninit(),
            CELLS.uninit(),
            pend_slow,
            &DRIVE_CONFIG,
            &BOARD,
        ) {
            Ok(c) => c,
            Err(e) => {
                // One interned message per reason (a table of strings took flash).
                match e {
                    // `BridgeActive` is a reconfiguration's, never the start's.
                    ControlError::Drive(_) | ControlError::BridgeActive | ControlError::SlowBusy => {
                        defmt::error!("configuration rejected (drive specification)")
                    }
                    ControlError::Scaling(_) => defmt::error!("configuration rejected (ADC/PWM scaling)"),
                    ControlError::Encoder(_) => defmt::error!("configuration rejected (encoder)"),
                    ControlError::Calibration(_) => {
                        defmt::error!("configuration rejected (offset-calibration limits)")
                    }
                    ControlError::PwmPeriod { .. } => defmt::error!("configuration rejected (PWM period)"),
                    ControlError::UpdateTiming { .. } => {
                        defmt::error!("configuration rejected (PWM update timing)")
                    }
                }
                defmt::error!("bridge stays off");
                halt_safe();
            }
        };
        // The link's requests: the drive's commands, the watchdog's stop and the snapshots
        // served by the slow interrupt, the rest by the control interrupt (`SHARED` both).
        // (Nothing has run yet: the slow side is the start-up's.)
        if !control.connect(&SHARED) {
            halt_safe();
        }
        // The capture for the link task, the slow cell for the slow interrupt, and the loop
        // for the control interrupt, which takes it at its first run (Release: their
        // initialisation is seen there).
        let scope = control.scope();
        SLOW.store(core::ptr::from_ref(control.slow_cell()).cast_mut(), Ordering::Release);
        CONTROL.store(control, Ordering::Release);

        // TIM1: centre-aligned complementary PWM, outputs off until the drive asks (MOE is
        // 0 from reset and set only by the output stage's explicit enable). Through embassy's
        // low-level timer — the register steps of its `ComplementaryPwm::new`, without its
        // frequency arithmetic (64-bit divisions, ≈ 1.2 KB of flash) and without its setting
        // MOE: the period and the dead time are the drive file's, in timer ticks. Never
        // dropped (`ManuallyDrop`): the timer's drop stops its clock, freezing the outputs.
        let pwm = ManuallyDrop::new(LlTimer::new(p.TIM1));
        // The period and dead time in ticks assume the drive file's timer clock: checked.
        if pwm.get_clock_frequency().0 != TIM_CLOCK_HZ {
            defmt::error!("TIM1 clock is not the drive file's {=u32} Hz: bridge stays off", TIM_CLOCK_HZ);
            halt_safe();
        }
        pwm.set_counting_mode(CountingMode::CenterAlignedBothInterrupts);
        for ch in [Channel::Ch1, Channel::Ch2, Channel::Ch3, Channel::Ch4] {
            pwm.set_output_compare_mode(ch, OutputCompareMode::PwmMode1);
            pwm.set_output_compare_preload(ch, true);
        }
        pwm.set_autoreload_preload(true);
        // The period the drive's constants were discretised for: centre-aligned, 2·ARR ticks
        // of the undivided timer clock. Written, read back, checked.
        pac::TIM1.psc().write_value(0);
        pac::TIM1.arr().write(|w| w.set_arr(BOARD.pwm_period_counts));
        pwm.generate_update_event();
        pwm.start();
        let arr_read = pac::TIM1.arr().read().arr();
        if let Err(ControlError::PwmPeriod { read, expected }) =
            firmware::control::check_pwm_period(arr_read, &BOARD)
        {
            defmt::error!(
                "TIM1 ARR reads {=u16}, the board's period is {=u16}: bridge stays off",
                read,
                expected
            );
            halt_safe();
        }
        pwm.set_dead_time_clock_division(Ckd::DIV1);
        pwm.set_dead_time_value(DEAD_TIME_DTG);
        pwm.set_ossr(Ossr::IDLE_LEVEL);
        pwm.set_ossi(Ossi::IDLE_LEVEL);
        // Break input: the overcurrent comparator pulls BKIN low → MOE cleared by hardware,
        // latched (no automatic output enable); the control interrupt sees the flag.
        let bkin_pin = pins.bkin;
        let af = BreakInputPin::<TIM1, BkIn1>::af_num(&*bkin_pin);
        let mut bkin = Flex::new(bkin_pin);
        bkin.set_as_af_unchecked(af, AfType::input(Pull::Up));
        pwm.set_break_input_pin_enable(true);
        pwm.set_break_polarity(Bkp::ACTIVE_LOW);
        pwm.set_break_filter(FilterValue::FCK_INT_N8);
        pwm.set_automatic_output_enable(false);
        pwm.set_break_enable(true);
        for ch in [Channel::Ch1, Channel::Ch2, Channel::Ch3] {
            pwm.set_compare_value(ch, BOARD.pwm_period_counts / 2);
            pwm.enable_channel(ch, true);
            pwm.enable_complementary_channel(ch, true);
        }
        // Only now the pins go to the timer: with MOE 0, OSSI set and the channels enabled,
        // it drives them to their idle level (low) from the first instant. Before, from
        // reset until here, they float: the gate driver's pull-downs hold the switches off
        // (a hardware requirement: docs/firmware.md's bring-up). Never dropped either (a
        // dropped pin is disconnected).
        let pwm_pins = ManuallyDrop::new([
            pwm_pin(TimerPin::<TIM1, Ch1>::af_num(&*pins.pwm_high.0), pins.pwm_high.0.into()),
            pwm_pin(TimerComplementaryPin::<TIM1, Ch1>::af_num(&*pins.pwm_low.0), pins.pwm_low.0.into()),
            pwm_pin(TimerPin::<TIM1, Ch2>::af_num(&*pins.pwm_high.1), pins.pwm_high.1.into()),
            pwm_pin(TimerComplementaryPin::<TIM1, Ch2>::af_num(&*pins.pwm_low.1), pins.pwm_low.1.into()),
            pwm_pin(TimerPin::<TIM1, Ch3>::af_num(&*pins.pwm_high.2), pins.pwm_high.2.into()),
            pwm_pin(TimerComplementaryPin::<TIM1, Ch3>::af_num(&*pins.pwm_low.2), pins.pwm_low.2.into()),
        ]);
        // Lock level 1: dead time, idle states and the break configuration (BKE, BKP, AOE)
        // can no longer be written until reset. MOE stays writable.
        pac::TIM1.bdtr().modify(|w| w.set_lock(pac::timer::vals::Lock::LEVEL1));
        // Sampling instant: the phases run PWM mode 1 (high side on while CNT < CCR), so the
        // low sides conduct around the top of the count, CNT = ARR. Channel 4 (no pin) in
        // PWM mode 2 with CCR4 = ARR − 1 raises OC4REF once per period just before the top;
        // TRGO2 = OC4REF starts the injected conversions on that edge.
        let arr = BOARD.pwm_period_counts;
        pac::TIM1.ccmr_output(1).modify(|w| w.set_ocm(1, Ocm::PWM_MODE2));
        pac::TIM1.ccr(3).modify(|w| w.set_ccr(arr - 1));
        pwm.set_mms2_selection(Mms2::COMPARE_OC4);
        // Update delay: one period (`control::UPDATE_REPETITION`). The counter stopped, RCR
        // written, an update generated (the repetition counter and the preloads reloaded,
        // the counter back to 0), then started: the update event now falls on every
        // overflow, the sampling instant. Read back — RCR, and the counter running down just
        // after the first event — or the bridge stays off.
        let update = critical_section::with(|_| {
            let tim = pac::TIM1;
            tim.cr1().modify(|w| w.set_cen(false));
            tim.rcr().write(|w| w.set_rep(UPDATE_REPETITION));
            tim.cr1().modify(|w| w.set_urs(Urs::COUNTER_ONLY));
            tim.egr().write(|w| w.set_ug(true));
            tim.cr1().modify(|w| w.set_urs(Urs::ANY_EVENT));
            tim.sr().write_value(pac::timer::regs::SrAdv(SR_RC_W0_FLAGS & !SR_UIF));
            tim.cr1().modify(|w| w.set_cen(true));
            // The first event comes after ARR ticks (half a period); a poll takes cycles,
            // so this bound is several periods.
            let down = (0..UPDATE_WAIT_POLLS)
                .find(|_| tim.sr().read().uif())
                .map(|_| tim.cr1().read().dir() == Dir::DOWN);
            check_update_timing(tim.rcr().read().rep(), down)
        });
        if let Err(ControlError::UpdateTiming { rcr, down_after_update }) = update {
            defmt::error!(
                "TIM1 update event not once per period at the top (RCR {=u16}, down after it: {}): bridge stays off",
                rcr,
                down_after_update
            );
            halt_safe();
        }

        // ADC1: four injected conversions per trigger, end-of-sequence interrupt.
        let adc = Adc::new(p.ADC1, Default::default());
        let _injected = adc.setup_injected_conversions(
            [
                (pins.i_abc.0.degrade_adc(), SampleTime::CYCLES6_5),
                (pins.i_abc.1.degrade_adc(), SampleTime::CYCLES6_5),
                (pins.i_abc.2.degrade_adc(), SampleTime::CYCLES6_5),
                (pins.vdc.degrade_adc(), SampleTime::CYCLES24_5),
            ],
            embassy_stm32::triggers::TIM1_TRGO2,
            Exten::RISING_EDGE,
            true,
        );

        // TIM4 quadrature encoder (x4).
        let qc = QeiConfig { ch1_pull: Pull::Up, ch2_pull: Pull::Up, ..Default::default() };
        let _encoder = Qei::new(p.TIM4, pins.encoder.0, pins.encoder.1, qc);
        // Its input filter on A and B (`ENCODER_FILTER`, from the board's line count
        // and the overspeed level: glitches shorter than ≈ 0.38 µs rejected with drive.toml).
        let filter = pac::timer::vals::FilterValue::from_bits(ENCODER_FILTER);
        pac::TIM4.ccmr_input(0).modify(|w| {
            w.set_icf(0, filter);
            w.set_icf(1, filter);
        });

        // Link on the ST-LINK virtual COM port.
        let mut uart_cfg = usart::Config::default();
        uart_cfg.baudrate = 115_200;
        let Ok(uart) =
            Uart::new(p.LPUART1, pins.link_rx, pins.link_tx, p.DMA1_CH1, p.DMA1_CH2, Irqs, uart_cfg)
        else {
            defmt::error!("LPUART1 configuration rejected");
            halt_safe();
        };
        let (tx, rx) = uart.split();
        static RX_BUF: static_cell::StaticCell<[u8; 256]> = static_cell::StaticCell::new();
        let rx = rx.into_ring_buffered(RX_BUF.init([0; 256]));

        // Priorities: only the control interrupt at P0, the drive's slow context at P1.
        interrupt::TIM3.set_priority(Priority::P4);
        interrupt::LPUART1.set_priority(Priority::P5);
        interrupt::CORDIC.set_priority(Priority::P1);
        interrupt::CORDIC.unpend();
        // SAFETY: the handler only touches the slow cell, through its hand-off (the control
        // interrupt lends it), and nothing else shares its priority.
        unsafe { interrupt::CORDIC.enable() };
        interrupt::ADC1_2.set_priority(Priority::P0);
        interrupt::ADC1_2.unpend();
        // SAFETY: the handler only touches the control loop (handed over once through
        // CONTROL), its own `static mut` state, the lock-free boundary statics and the TIM1/ADC1/TIM4 registers that nothing else
        // writes after this point.
        unsafe { interrupt::ADC1_2.enable() };

        match link_task(tx, rx, p.IWDG, scope) {
            Ok(l) => spawner.spawn(l),
            Err(_) => halt_safe(),
        }
        // The peripherals' drivers must stay alive.
        loop {
            Timer::after_secs(3600).await;
            let _ = (&pwm, &pwm_pins, &bkin, &brake, &_injected, &_encoder);
        }
    }

    /// The control interrupt: end of the injected ADC sequence, once per PWM period.
    ///
    /// Time budget: one period is 50 µs = 8 500 cycles at 170 MHz. The control step's
    /// instructions per fast and slow step are counted under QEMU (`cargo xtask qemu`,
    /// `qemu-target/src/bin/cost.rs`; the figures in docs/performance.md): about a tenth of
    /// the period at one cycle per instruction. The real cycle count (FPU divide latency, flash wait states)
    /// the board measures itself, from the period's update event (TIM1's counter at entry)
    /// to the end of this handler (DWT CYCCNT): the longest and the periods of a period or
    /// more in the link's `Status` (`control::LoopTimer`); two of those running latch
    /// `Fault::Overrun` with the bridge off (`Outputs::overrun`). The compare values
    /// written here take effect at the next update event (preload), which is at the next
    /// sample's instant (`control::UPDATE_REPETITION`): one period after sampling — the
    /// delay the simulator and the certificate model.
    #[interrupt]
    fn ADC1_2() {
        // The interrupt's own state, which nothing else reaches: cortex-m-rt makes these
        // `&mut` to this handler (no critical section around the body, issue 54).
        static mut CONTROL_LOOP: Option<&'static mut ControlLoop<'static>> = None;
        static mut OUTPUTS: Outputs = Outputs::new();
        let t0 = cortex_m::peripheral::DWT::cycle_count();
        // Where the period was when the handler began: its work is timed from the update
        // event (the sample), not from here (`control::ticks_since_update`).
        let (cnt, cr1) = (pac::TIM1.cnt().read().cnt(), pac::TIM1.cr1().read());
        let since_update =
            firmware::control::ticks_since_update(cnt, cr1.dir() == Dir::DOWN, BOARD.pwm_period_counts);
        let adc = pac::ADC1;
        if !adc.isr().read().jeos() {
            return;
        }
        // Samples in: currents, bus, encoder (the break flag is the output stage's).
        let samples = Samples {
            i_abc: [adc.jdr(0).read().jdata(), adc.jdr(1).read().jdata(), adc.jdr(2).read().jdata()],
            vdc: adc.jdr(3).read().jdata(),
            encoder: pac::TIM4.cnt().read().cnt(),
            hardware_break: false,
        };
        adc.isr().write(|w| w.set_jeos(true));
        // Break detection → control step → compare values (preloaded: they take effect at
        // the next update) and MOE, set only on an explicit enable, a period after them.
        if CONTROL_LOOP.is_none() {
            *CONTROL_LOOP = take_control();
        }
        match CONTROL_LOOP.as_deref_mut() {
            Some(ctl) => {
                SHARED.control_period(OUTPUTS, &mut Tim1, ctl, samples);
            }
            None => Tim1.disable_outputs(),
        }
        ISR_COUNT.fetch_add(1, Ordering::Relaxed);
        let cycles = cortex_m::peripheral::DWT::cycle_count().wrapping_sub(t0).saturating_add(since_update);
        if LOOP_TIMER.record(cycles, firmware::control::period_cycles(&BOARD)) {
            match CONTROL_LOOP.as_deref_mut() {
                Some(ctl) => OUTPUTS.overrun(&mut Tim1, ctl),
                None => Tim1.disable_outputs(),
            }
        }
    }

    /// The drive's slow context (issue 54's two contexts): the slow step's job the control
    /// interrupt handed over at its tick ([`CELLS`]), run here — preempted by the control
    /// interrupt (P0 over P1) — and the slow side handed back. Its plan is adopted a plan's
    /// delay after the tick (2 periods at 20 kHz); a job not back by then latches
    /// `Fault::Overrun` with the bridge off in that period (`FastSide::step`).
    #[interrupt]
    fn CORDIC() {
        // SAFETY: a non-null pointer in `SLOW` is the `&'static` cell start-up stored, never
        // freed; a shared reference is all the hand-off needs (it is `Sync`).
        if let Some(cell) = unsafe { SLOW.load(Ordering::Acquire).as_ref() } {
            firmware::control::run_slow(cell);
        }
    }

    /// The control loop [`CONTROL`] holds, taken out (`None` if none was stored, or it was
    /// taken before).
    fn take_control() -> Option<&'static mut ControlLoop<'static>> {
        let p = CONTROL.swap(core::ptr::null_mut(), Ordering::Acquire);
        // SAFETY: a non-null pointer in `CONTROL` is the `&'static mut` start-up stored, once
        // (from the static cell's single initialisation); the swap leaves null behind, so it
        // is taken once, here, by the control interrupt — which nothing re-enters (the only
        // interrupt at its priority) — and no other reference to the loop exists.
        unsafe { p.as_mut() }
    }

    /// The main stack's high-water mark since reset, bytes (`firmware::stack`): the region
    /// cortex-m-rt painted, `_stack_end` (its bottom) up to `_stack_start` (its top).
    fn stack_used_bytes() -> u32 {
        unsafe extern "C" {
            static _stack_end: u32;
            static _stack_start: u32;
        }
        // The paint `firmware::stack` looks for is cortex-m-rt's: without its `paint-stack`
        // feature this constant does not exist and the build stops.
        const { assert!(cortex_m_rt::STACK_PAINT_VALUE == firmware::stack::PAINT) };
        let bottom = core::ptr::addr_of!(_stack_end) as usize;
        let top = core::ptr::addr_of!(_stack_start) as usize;
        let words = top.saturating_sub(bottom) / 4;
        let used = firmware::stack::used_bytes(words, |i| {
            let word = core::ptr::with_exposed_provenance::<u32>(bottom + 4 * i);
            // SAFETY: `bottom + 4·i` for i < words lies inside the stack region the linker
            // script defines (RAM, below `_stack_start`), word-aligned; a volatile read of a
            // word the stack may be writing at the same time reads either value — only the
            // paint's presence matters — and nothing is written.
            unsafe { core::ptr::read_volatile(word) }
        });
        u32::try_from(used).unwrap_or(u32::MAX)
    }

    /// Microseconds since boot, wrapping (the link watchdog's clock): embassy's ticks are
    /// microseconds, so no 64-bit division (a library call on the M4F) makes it.
    fn now_us() -> u32 {
        const { assert!(embassy_time::TICK_HZ == 1_000_000) };
        embassy_time::Instant::now().as_ticks() as u32
    }

    /// The link watchdog's timeout in its clock's unit (3 600 s at most: below 2^32 µs).
    const LINK_TIMEOUT_US: u32 = LINK_TIMEOUT_MS * 1000;

    /// `cmd` executed — by the drive's slow context or the control interrupt, posted to them
    /// (`SHARED.commands`), or here if it is the capture's (`Scope::serve`: an `ArmCapture`
    /// while the control interrupt records waits for the capture to come back): its reply
    /// within [`COMMAND_TIMEOUT_MS`], else none (no control loop, or the interrupts not
    /// running; a late reply is dropped before the next command).
    async fn execute(
        cmd: BoardCommand,
        prepared: server::Prepared,
        stats: LinkStats,
        scope: &Scope,
    ) -> Option<Reply> {
        let here = server::link_task_serves(&cmd);
        let _ = SHARED.commands.take();
        if !here && !SHARED.commands.post((cmd, prepared, stats)) {
            return None;
        }
        let t0 = embassy_time::Instant::now();
        loop {
            let reply = if here { scope.serve(&cmd) } else { SHARED.commands.take() };
            if reply.is_some() {
                return reply;
            }
            if t0.elapsed() > Duration::from_millis(COMMAND_TIMEOUT_MS) {
                return None;
            }
            Timer::after_micros(50).await;
        }
    }

    /// How long the link task waits for the control interrupt to execute a command, ms (the
    /// interrupt serves one within two 50 µs periods: not in the drive's slow step's).
    const COMMAND_TIMEOUT_MS: u64 = 10;

    /// Commands in, replies and telemetry (every 10 ms) out; the link watchdog
    /// (`server::LinkWatchdog`): a link silent for `LINK_TIMEOUT_MS` while the bridge is on
    /// stops the drive (a controlled stop).
    #[embassy_executor::task]
    async fn link_task(
        mut tx: UartTx<'static, Async>,
        mut rx: RingBufferedUartRx<'static>,
        iwdg: Peri<'static, IWDG>,
        scope: &'static Scope,
    ) {
        // The independent watchdog (100 ms), fed from this loop — which turns at least every
        // 10 ms (the read's timeout) — and only while the control interrupt runs: a reset
        // if either stops (before, a task of its own fed it, which saw the interrupt only).
        let mut wdg = IndependentWatchdog::new(iwdg, 100_000);
        wdg.unleash();
        let mut isr_count = ISR_COUNT.load(Ordering::Relaxed);
        let mut decoder = FrameDecoder::new();
        let mut stats = LinkStats::default();
        let mut input = [0u8; 64];
        let mut frame = [0u8; MAX_FRAME];
        let mut watchdog = server::LinkWatchdog::new(LINK_TIMEOUT_US, now_us());
        let mut calibration_logged = false;
        loop {
            let now = ISR_COUNT.load(Ordering::Relaxed);
            if now != isr_count {
                wdg.pet();
            }
            isr_count = now;
            // The control loop's state, and requests to it, lock-free (`firmware::boundary`):
            // the snapshot the interrupt published after the last turn's request (an older
            // one if no period without the drive's slow step has passed since), and a fresh
            // one asked for the stream below and the next turn. Its fields read from the `Option` (a default `Snapshot`
            // copied in took flash).
            let snapshot = SHARED.snapshot.read();
            SHARED.request_snapshot();
            let stopped = watchdog.due(now_us(), snapshot.is_some_and(|s| s.bridge_on));
            if stopped {
                SHARED.watchdog_stop.store(true, Ordering::Relaxed);
            }
            let calibration = snapshot.and_then(|s| s.calibration);
            if stopped {
                defmt::warn!("link silent for {=u32} ms: controlled stop", LINK_TIMEOUT_MS);
            }
            // The offset calibration's result, once (from this task: never from the interrupt).
            match calibration {
                Some(Calibration::Done(o)) if !calibration_logged => {
                    calibration_logged = true;
                    defmt::info!(
                        "current offsets {=u16} {=u16} {=u16} counts, noise {=f32} {=f32} {=f32} counts RMS",
                        o.counts[0],
                        o.counts[1],
                        o.counts[2],
                        o.rms_counts[0],
                        o.rms_counts[1],
                        o.rms_counts[2]
                    );
                }
                Some(Calibration::Failed(e)) if !calibration_logged => {
                    calibration_logged = true;
                    match e {
                        CalibrationError::Offset { channel, mean_counts } => defmt::error!(
                            "current channel {=u8}: zero at {=f32} counts, out of range: bridge stays off",
                            channel,
                            mean_counts
                        ),
                        CalibrationError::Noise { channel, rms_counts } => defmt::error!(
                            "current channel {=u8}: {=f32} counts RMS of noise: bridge stays off",
                            channel,
                            rms_counts
                        ),
                    }
                }
                _ => {}
            }
            let n = match with_timeout(Duration::from_millis(10), rx.read(&mut input)).await {
                Ok(Ok(n)) => n,
                Ok(Err(_)) => 0, // overrun/framing error: the frames it hit fail their CRC
                Err(_) => {
                    // Quiet for 10 ms: stream telemetry. The frame is encoded in a statement
                    // of its own: no message lives across the `await` (the task's state
                    // would hold it, and moving it there linked a `memmove`).
                    let len = SHARED
                        .snapshot
                        .read()
                        .and_then(|s| s.output)
                        .and_then(|(o, t)| link::reply_frame(&Reply::Output(o, t), &mut frame).ok());
                    if let Some(len) = len {
                        let _ = tx.write(frame.get(..len).unwrap_or(&[])).await;
                    }
                    continue;
                }
            };
            for &b in input.iter().take(n) {
                let Some(cmd) = decoder.push_board_command(b, &mut stats) else { continue };
                watchdog.frame(now_us());
                // Heavy work (a commissioning configuration) here, not in the interrupt.
                let prepared = server::prepare(&cmd);
                let reply = execute(cmd, prepared, stats, scope).await;
                // The status carries the interrupt's timing (the link module cannot see it).
                let reply = reply.map(|r| match r {
                    Reply::Status { mode, ridden_through, frames_ok, frame_errors, readings, .. } => {
                        let timing = LoopTiming { stack_bytes: stack_used_bytes(), ..LOOP_TIMER.read() };
                        Reply::Status { mode, ridden_through, frames_ok, frame_errors, timing, readings }
                    }
                    other => other,
                });
                let len = reply.and_then(|r| link::reply_frame(&r, &mut frame).ok());
                if let Some(len) = len {
                    let _ = tx.write(frame.get(..len).unwrap_or(&[])).await;
                }
            }
        }
    }

    /// Interrupts masked, bridge off (MOE = 0) for good, then wait for the watchdog or the
    /// debugger.
    fn halt_safe() -> ! {
        stop_for_good(cortex_m::interrupt::disable, &mut Tim1);
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// A panic masks every interrupt (no control interrupt can set MOE again), turns the
    /// bridge off, logs, and waits for the watchdog reset. `cargo xtask build-fw` checks in
    /// the disassembly that `cpsid` comes before the handler's first store.
    ///
    /// The `PanicInfo` is not read, not even its location: reading it kept every panic
    /// site's message arguments alive — core::fmt's integer and string formatting and the
    /// sources' paths, 5 672 B of flash (docs/firmware.md). The probe locates a panic
    /// better than a file and line: the core stays in this handler's loop, and stopping
    /// `probe-rs run` (Ctrl-C) prints the backtrace from the debug information on the host.
    #[panic_handler]
    fn panic(_info: &core::panic::PanicInfo<'_>) -> ! {
        stop_for_good(cortex_m::interrupt::disable, &mut Tim1);
        // defmt-rtt never waits for the probe (`disable-blocking-mode`).
        defmt::error!("panic: bridge off for good; the probe's backtrace (Ctrl-C) locates it");
        loop {
            cortex_m::asm::nop();
        }
    }

    /// A HardFault (flip-link turns a stack overflow into one) masks every interrupt and
    /// turns the bridge off for good, instead of the default `b .` that left the PWM running
    /// with frozen duties; the watchdog then resets the MCU.
    #[cortex_m_rt::exception]
    // SAFETY: (of the attribute's contract) the handler never returns and touches only TIM1's
    // BDTR through the PAC, after masking interrupts.
    unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
        stop_for_good(cortex_m::interrupt::disable, &mut Tim1);
        loop {
            cortex_m::asm::nop();
        }
    }

    /// Every exception and interrupt without a handler of its own — the NMI among them (the
    /// clock security system's, a flash ECC double error's), and any interrupt enabled by
    /// mistake — stops the same way: interrupts masked, the bridge off for good. cortex-m-rt's
    /// default (`b .`) left MOE set and the PWM switching its frozen duties until the
    /// watchdog reset (issue 54). `cargo xtask build-fw` checks that `cpsid` comes first.
    #[cortex_m_rt::exception]
    // SAFETY: (of the attribute's contract, which for the NMI asks that the handler touch no
    // data a critical section protects) the handler never returns and touches only TIM1's
    // BDTR and the brake pin's output register through the PAC, after masking interrupts:
    // the same as the HardFault handler.
    unsafe fn DefaultHandler(_irqn: i16) -> ! {
        stop_for_good(cortex_m::interrupt::disable, &mut Tim1);
        loop {
            cortex_m::asm::nop();
        }
    }
}

/// On the host: build and flash for the board (`cargo run -p firmware --release`).
#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let args = ["run", "--package", "firmware", "--profile", "firmware", "--target", "thumbv7em-none-eabihf"];
    eprintln!("firmware: a board program; running `cargo {}` (probe-rs flashes it)", args.join(" "));
    match std::process::Command::new(cargo).args(args).status() {
        Ok(s) if s.success() => std::process::ExitCode::SUCCESS,
        Ok(_) | Err(_) => std::process::ExitCode::FAILURE,
    }
}
