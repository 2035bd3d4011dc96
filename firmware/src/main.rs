//! STM32G474RE drive firmware — bring-up stage.
//!
//! What exists: the binary builds and links for `thumbv7em-none-eabihf` with the workspace's
//! `memory.x`, validates the drive configuration at start-up (so configuration errors are
//! caught before any peripheral is touched) and then sleeps. The peripheral layer
//! (TIM1 PWM, ADC, encoder, control interrupt, command link) is issue 6.
//!
//! On the host this crate builds to a small program that says so, which keeps
//! `cargo test --workspace` working without a target.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use controller_core::drive::{Drive, DriveConfig, example_spec};
    use cortex_m_rt::entry;
    use panic_halt as _;

    #[entry]
    fn main() -> ! {
        // Validate at construction; with an invalid configuration the bridge is never enabled.
        let drive = example_spec().ok().and_then(|s| DriveConfig::new(&s).ok()).map(Drive::new);
        let _ = core::hint::black_box(drive);
        loop {
            cortex_m::asm::wfi();
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("firmware: build for the board with `cargo build-fw` (thumbv7em-none-eabihf)");
}
