//! controller-core on an emulated Cortex-M, with no board.
//!
//! On-target tests and two programs, all run by QEMU with semihosting (`cargo xtask qemu`
//! builds and runs them; `hil-sim pil` starts the first program):
//! - `tests/selftest.rs` — the control laws exercised on the target as `defmt-test` tests:
//!   `cargo test --target thumbv7em-none-eabihf --release` runs them on `mps2-an386`
//!   (Cortex-M4F, f32 on the FPU), `--target thumbv7m-none-eabi` on `lm3s6965evb`
//!   (Cortex-M3, no FPU: f32 in software, plus the `Q32` fixed-point current controller
//!   compared with the f32 one); the runner (`run-qemu.sh`) is in `.cargo/config.toml`.
//! - `pil` — processor in the loop: reads link frames ([`controller_core::link`]) from the
//!   host file `to_mcu`, runs the drive exactly as the firmware's control interrupt does
//!   (`Drive::step` per `Step` frame) and writes replies to `from_mcu`. Both files are FIFOs
//!   made by `hil-sim pil`; QEMU opens them through semihosting `SYS_OPEN` relative to its
//!   working directory.
//! - `cost` — executed instructions per fast and slow step, measured with SysTick under
//!   `-icount shift=0` (1 instruction = 1 ns of virtual time, SysTick at 25 MHz on mps2).
//!
//! This library holds what they share: semihosting file I/O, console output, exit
//! status, the panic handler. It is empty on the host.
#![no_std]

/// The firmware's drive (`drive.toml`), generated at build time: what the self-tests and
/// `cost` run.
pub mod drive {
    include!(concat!(env!("OUT_DIR"), "/drive.rs"));
}

pub mod machine {
    //! A machine behind `cost`'s samples: the induction machine of seed 002 eq. (1) in the
    //! stationary frame (the simulator's `plant` is std and f64; this is its linear form in
    //! f32), the shaft held at a set speed (a dynamometer), answering the voltage the drive
    //! applied over each PWM period. Ideal currents (each period's the reference of the
    //! period before) let the loops wind their integrators against currents that ignore the
    //! voltage, and the drive's checks that compare the applied voltage with its machine
    //! model found the voltage of no machine.
    use controller_core::frames::AlphaBeta;
    use controller_core::motor::MotorParams;

    /// Heun (RK2) steps per PWM period: the stator's fastest pole, −(L_r²R_s + L_m²R_r)/(σL_sL_r²),
    /// times a sub-step stays far below Heun's stability limit of 2 for any motor whose
    /// current loops the drive can close at that rate.
    const SUBSTEPS: u32 = 4;

    /// The machine: its coefficients and state.
    #[derive(Clone, Copy, Debug)]
    pub struct Machine {
        /// `a` of eq. (1), 1/s.
        a: f32,
        /// `b` of eq. (1), 1/H.
        b: f32,
        /// R_r/L_r, 1/s.
        rr_per_lr: f32,
        /// L_m·R_r/L_r, Ω.
        lm_rr_per_lr: f32,
        /// 1/(σL_s), 1/H.
        per_sigma_ls: f32,
        /// Pole pairs.
        pole_pairs: f32,
        /// A sub-step, s.
        h_s: f32,
        /// The shaft's speed, mechanical rad/s.
        omega_m_rad_s: f32,
        /// Stator current, A.
        i_a: AlphaBeta,
        /// Rotor flux, Wb.
        psi_wb: AlphaBeta,
    }

    impl Machine {
        /// A machine with `motor`'s circuit at rest and unmagnetized, stepped over PWM
        /// periods of `ts_s`, its shaft held at `omega_m_rad_s`.
        pub fn new(motor: &MotorParams, ts_s: f32, omega_m_rad_s: f32) -> Self {
            let (rs, rr) = (motor.rs_ohm() as f32, motor.rr_ohm() as f32);
            let (ls, lr, lm) = (motor.ls_h() as f32, motor.lr_h() as f32, motor.lm_h() as f32);
            let sigma_ls = motor.sigma() as f32 * ls;
            Self {
                a: -(lr * lr * rs + lm * lm * rr) / (sigma_ls * lr * lr),
                b: lm / (sigma_ls * lr),
                rr_per_lr: rr / lr,
                lm_rr_per_lr: lm * rr / lr,
                per_sigma_ls: 1.0 / sigma_ls,
                pole_pairs: f32::from(motor.pole_pairs()),
                h_s: ts_s / SUBSTEPS as f32,
                omega_m_rad_s,
                i_a: AlphaBeta::default(),
                psi_wb: AlphaBeta::default(),
            }
        }

        /// Hold the shaft at `omega_m_rad_s` from now on.
        pub fn set_speed(&mut self, omega_m_rad_s: f32) {
            self.omega_m_rad_s = omega_m_rad_s;
        }

        /// Eq. (1)'s derivatives of the current and the flux at `(i, psi)` under `v`.
        fn derivative(&self, i: AlphaBeta, psi: AlphaBeta, v: AlphaBeta) -> (AlphaBeta, AlphaBeta) {
            let w = self.pole_pairs * self.omega_m_rad_s;
            let di = AlphaBeta {
                alpha: self.a * i.alpha
                    + self.b * (self.rr_per_lr * psi.alpha + w * psi.beta)
                    + self.per_sigma_ls * v.alpha,
                beta: self.a * i.beta
                    + self.b * (self.rr_per_lr * psi.beta - w * psi.alpha)
                    + self.per_sigma_ls * v.beta,
            };
            let dpsi = AlphaBeta {
                alpha: self.lm_rr_per_lr * i.alpha - self.rr_per_lr * psi.alpha - w * psi.beta,
                beta: self.lm_rr_per_lr * i.beta - self.rr_per_lr * psi.beta + w * psi.alpha,
            };
            (di, dpsi)
        }

        /// One PWM period: under the stator voltage `v_ab_v` (V, held over it) while the
        /// bridge switches (`switching`), open-circuited otherwise (no current; the rotor's
        /// flux decays and turns with the shaft). Returns the stator current at its end, A.
        pub fn period(&mut self, switching: bool, v_ab_v: AlphaBeta) -> AlphaBeta {
            let h = self.h_s;
            let ahead = |x: AlphaBeta, dx: AlphaBeta, t: f32| AlphaBeta {
                alpha: x.alpha + t * dx.alpha,
                beta: x.beta + t * dx.beta,
            };
            // Open: the current held at zero (its derivative dropped), the flux on its own.
            let machine = *self;
            let derivative = |i: AlphaBeta, psi: AlphaBeta| {
                let (di, dpsi) = machine.derivative(i, psi, v_ab_v);
                (if switching { di } else { AlphaBeta::default() }, dpsi)
            };
            let (mut i, mut psi) = (if switching { self.i_a } else { AlphaBeta::default() }, self.psi_wb);
            for _ in 0..SUBSTEPS {
                let (di1, dpsi1) = derivative(i, psi);
                let (di2, dpsi2) = derivative(ahead(i, di1, h), ahead(psi, dpsi1, h));
                i = ahead(i, ahead(di1, di2, 1.0), 0.5 * h);
                psi = ahead(psi, ahead(dpsi1, dpsi2, 1.0), 0.5 * h);
            }
            (self.i_a, self.psi_wb) = (i, psi);
            i
        }
    }
}

#[cfg(target_os = "none")]
pub mod sh {
    //! Semihosting: host files, console, exit.
    use core::ffi::CStr;
    use cortex_m_semihosting::{debug, nr, syscall};

    /// An open host file.
    #[derive(Clone, Copy, Debug)]
    pub struct HostFile(usize);

    /// Open `path` (relative to QEMU's working directory) for binary reading or writing.
    pub fn open(path: &CStr, write: bool) -> Option<HostFile> {
        let mode = if write { nr::open::W_TRUNC_BINARY } else { nr::open::R_BINARY };
        let len = path.to_bytes().len();
        // SAFETY: SYS_OPEN takes a pointer to a NUL-terminated string (a `CStr`), the mode
        // and the length without the NUL; the host only reads the string.
        let h = unsafe { syscall!(OPEN, path.as_ptr(), mode, len) };
        if h == usize::MAX { None } else { Some(HostFile(h)) }
    }

    impl HostFile {
        /// Read up to `buf.len()` bytes (at least one: the host's `read` blocks on a FIFO).
        /// Returns the count; 0 means end of file.
        pub fn read(&self, buf: &mut [u8]) -> usize {
            // SAFETY: SYS_READ writes at most `len` bytes to `buf`, which we own mutably;
            // it returns the number of bytes *not* read.
            let not_read = unsafe { syscall!(READ, self.0, buf.as_mut_ptr(), buf.len()) };
            buf.len().saturating_sub(not_read)
        }

        /// Write all of `buf`. Returns false if the host reports an error.
        pub fn write_all(&self, buf: &[u8]) -> bool {
            // SAFETY: SYS_WRITE only reads `len` bytes from `buf`; returns bytes not written.
            let not_written = unsafe { syscall!(WRITE, self.0, buf.as_ptr(), buf.len()) };
            not_written == 0
        }
    }

    /// End the QEMU session with status 0 (`ok`) or 1.
    pub fn exit(ok: bool) -> ! {
        debug::exit(if ok { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
        loop {
            cortex_m::asm::bkpt();
        }
    }

    /// `println!` to the host's standard output.
    #[macro_export]
    macro_rules! println {
        ($($arg:tt)*) => { cortex_m_semihosting::hprintln!($($arg)*) };
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
        cortex_m_semihosting::hprintln!("panic: {}", info);
        exit(false)
    }
}

#[cfg(target_os = "none")]
pub mod clock {
    //! Virtual-time measurement with SysTick. Under `-icount shift=0` QEMU advances its
    //! clock by 1 ns per executed instruction and SysTick (processor clock 25 MHz on
    //! mps2-an386) counts deterministically: 1 tick = 40 instructions. DWT CYCCNT does not
    //! count under QEMU.
    use cortex_m::peripheral::{SYST, syst::SystClkSource};

    /// Instructions per SysTick tick on mps2-an386 with `-icount shift=0`.
    pub const INSTRUCTIONS_PER_TICK: u32 = 40;

    /// Free-running 24-bit down-counter (owns SysTick).
    #[allow(missing_debug_implementations)]
    pub struct Ticks(SYST);

    impl Ticks {
        /// Start SysTick from its reload value 0xFF_FFFF on the core clock.
        pub fn start(mut syst: SYST) -> Self {
            syst.set_clock_source(SystClkSource::Core);
            syst.set_reload(0x00FF_FFFF);
            syst.clear_current();
            syst.enable_counter();
            Self(syst)
        }

        /// Current count (down-counting, 24 bits).
        pub fn now(&self) -> u32 {
            SYST::get_current()
        }

        /// Ticks from `earlier` to `later` (two `now()` readings), modulo 2^24.
        pub fn elapsed(earlier: u32, later: u32) -> u32 {
            earlier.wrapping_sub(later) & 0x00FF_FFFF
        }
    }
}

#[cfg(target_os = "none")]
pub mod stack {
    //! Stack depth of a call: paint the free stack below the caller's frame with a pattern,
    //! make the call, find the deepest word it changed. The exception frame the hardware
    //! pushes on an interrupt's entry ([`EXCEPTION_FRAME_FP_BYTES`]) is not part of it.

    const PATTERN: u32 = 0xA5C3_5A3C;
    /// Bytes painted below the painter's frame.
    pub const PAINTED: usize = 16 * 1024;
    /// What the Cortex-M4F pushes on entering an interrupt whose handler uses the FPU: the
    /// basic frame (8 words) and the FP context (S0–S15, FPSCR, a reserved word): 26 words.
    pub const EXCEPTION_FRAME_FP_BYTES: usize = 26 * 4;

    /// The main stack pointer now.
    #[inline(always)]
    pub fn pointer() -> usize {
        cortex_m::register::msp::read() as usize
    }

    /// Paint [`PAINTED`] bytes below this function's frame (64 bytes of it left alone);
    /// returns the painted region's top.
    #[inline(never)]
    pub fn paint() -> usize {
        let top = (pointer() - 64) & !3;
        for a in (top - PAINTED..top).step_by(4) {
            // SAFETY: the words lie below the stack pointer, in the stack's free space (the
            // 4 MiB data SRAM of mps2-an386 holds nothing else there): no live frame or
            // static is written. Volatile, so the writes are not elided.
            unsafe { core::ptr::write_volatile(a as *mut u32, PATTERN) };
        }
        top
    }

    /// Bytes of stack below `sp` (the caller's stack pointer, read before the call) that the
    /// calls since [`paint`] (which returned `top`) reached: `sp` less the deepest word no
    /// longer the pattern. [`PAINTED`] or more: the calls went past the painted region.
    pub fn depth_below(sp: usize, top: usize) -> usize {
        for a in (top - PAINTED..top).step_by(4) {
            // SAFETY: aligned reads of the painted region, below the stack pointer.
            if unsafe { core::ptr::read_volatile(a as *const u32) } != PATTERN {
                return sp - a;
            }
        }
        0
    }
}
