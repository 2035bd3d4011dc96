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
