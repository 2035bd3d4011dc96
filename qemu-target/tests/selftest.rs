//! `controller_core::selftest` on the emulated target, as `defmt-test` tests: `cargo test
//! --target thumbv7em-none-eabihf --release` runs them on QEMU mps2-an386 (Cortex-M4F, f32 on
//! the FPU), `--target thumbv7m-none-eabi` on lm3s6965evb (Cortex-M3, no FPU: f32 in software,
//! plus the `Q32` fixed-point controller). The runner is in `qemu-target/.cargo/config.toml`;
//! the exit status is cargo's test result. Each test asserts one check's measured quantity
//! against its limit (the limits are justified in `controller_core::selftest`).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod on_target {
    use controller_core::selftest::{self, Check};
    use core::sync::atomic::{AtomicBool, Ordering};
    use cortex_m_rt as _;
    use defmt_semihosting as _;
    use qemu_target as _;

    /// The Cortex-M3 has no FPU: every f32 operation is a library call, so its long time-domain
    /// check runs shortened (same limit).
    const QUICK: bool = cfg!(not(target_abi = "eabihf"));

    fn check(c: Check) {
        defmt::println!("{=str}: measured {=f64}, limit {=f64}", c.name, c.measured, c.limit);
        defmt::assert!(c.passed(), "{=str}: {=f64} is above its limit {=f64}", c.name, c.measured, c.limit);
    }

    /// The firmware's drive (generated from `drive.toml`).
    fn spec() -> controller_core::drive::DriveSpec {
        match qemu_target::drive::drive_spec() {
            Ok(s) => s,
            Err(_) => defmt::panic!("the generated drive specification is invalid"),
        }
    }

    #[defmt::panic_handler]
    fn defmt_panic() -> ! {
        qemu_target::sh::exit(false)
    }

    /// Set by the handlers of the two exceptions the critical-section test pends.
    static PENDSV_RAN: AtomicBool = AtomicBool::new(false);
    static SYSTICK_RAN: AtomicBool = AtomicBool::new(false);

    #[cortex_m_rt::exception]
    fn PendSV() {
        PENDSV_RAN.store(true, Ordering::SeqCst);
    }

    #[cortex_m_rt::exception]
    fn SysTick() {
        SYSTICK_RAN.store(true, Ordering::SeqCst);
    }

    /// The exception `pend` pends has run (or not) once the pend has taken effect.
    fn ran_after(pend: fn(), flag: &AtomicBool) -> bool {
        pend();
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
        flag.load(Ordering::SeqCst)
    }

    #[defmt_test::tests]
    mod tests {
        use super::*;

        #[test]
        fn icad_time_domain_response() {
            check(selftest::icad_time_domain_response(QUICK));
        }

        #[test]
        fn icad_lag_dc_gain() {
            check(selftest::icad_lag_dc_gain());
        }

        #[test]
        fn pi_windup_recovery() {
            check(selftest::pi_windup_recovery());
        }

        #[test]
        fn svpwm_stays_in_hexagon() {
            check(selftest::svpwm_stays_in_hexagon());
        }

        #[test]
        fn sincos_accuracy() {
            check(selftest::sincos_accuracy());
        }

        #[test]
        fn drive_magnetizing_time() {
            check(selftest::drive_magnetizing_time(&spec()));
        }

        #[test]
        fn supervisor_trips_in_one_step() {
            check(selftest::supervisor_trips_in_one_step(&spec()));
        }

        #[test]
        fn link_rejects_corruption() {
            check(selftest::link_rejects_corruption(&spec()));
        }

        /// Built without controller-core's `vhz`, `observer` and `curve` (as the default
        /// firmware is), a drive that asks for V/Hz, for the speed observer or for a
        /// magnetizing curve is refused, naming what the build leaves out — not run as the encoder drive it would silently become.
        #[test]
        fn a_mode_left_out_of_the_build_is_refused() {
            use controller_core::drive::{Control, DriveConfig, DriveError, DriveSpec, SpeedFeedback};
            use controller_core::{observer::ObserverError, vhz::VhzError};
            let vhz =
                DriveSpec { control: Control::VHz { ramp_rad_s2: 100.0, k_u: 0.0, k_w: 0.0 }, ..spec() };
            defmt::assert!(matches!(DriveConfig::new(&vhz), Err(DriveError::Vhz(VhzError::NotBuilt))));
            for feedback in [SpeedFeedback::Sensorless, SpeedFeedback::EncoderRideThrough] {
                let s = DriveSpec { speed_feedback: feedback, ..spec() };
                defmt::assert!(matches!(
                    DriveConfig::new(&s),
                    Err(DriveError::Observer(ObserverError::NotBuilt))
                ));
            }
            // A saturating motor's curve (the shipped motor's chord on a table of its own).
            use controller_core::magnetics::{MagnetizingCurve, MagnetizingTable};
            let table = MagnetizingCurve::law(2.0, 0.956813, 7.0)
                .ok()
                .and_then(|c| MagnetizingTable::of_curve(&c, 0.9))
                .map(|(t, _)| t);
            defmt::assert!(table.is_some());
            let curve = DriveSpec { magnetizing: table, ..spec() };
            defmt::assert!(matches!(DriveConfig::new(&curve), Err(DriveError::CurveNotBuilt)));
            defmt::assert!(DriveConfig::new(&spec()).is_ok());
        }

        #[test]
        fn q32_icad_vs_f64() {
            check(selftest::q32_icad_vs_f64());
        }

        #[test]
        fn f32_icad_vs_f64() {
            check(selftest::f32_icad_vs_f64());
        }

        /// The board's critical section (`firmware::masking`: BASEPRI at the least priority
        /// step) lets an exception of the highest priority — the control interrupt's, here
        /// PendSV's — run inside it, and holds one of a lower priority — SysTick's, as the
        /// time driver's and the link's — until it ends. On this core's own priority bits.
        #[test]
        fn a_section_masks_all_but_the_highest_priority() {
            use cortex_m::peripheral::SCB;
            use cortex_m::peripheral::scb::SystemHandler;
            use firmware::masking::{cortex, least_step};
            // SAFETY: the test owns the core; it sets only these two handlers' priorities.
            let mut p = unsafe { cortex_m::Peripherals::steal() };
            // SAFETY: priorities of handlers that only set a flag.
            unsafe {
                p.SCB.set_priority(SystemHandler::SysTick, 0xFF);
                p.SCB.set_priority(SystemHandler::PendSV, 0);
            }
            // The lowest priority this NVIC implements reads back as its implemented bits;
            // BASEPRI masks group priorities (SCB_AIRCR.PRIGROUP).
            let prigroup = ((p.SCB.aircr.read() >> 8) & 0x7) as u8;
            let Some(level) = least_step(SCB::get_priority(SystemHandler::SysTick), prigroup) else {
                defmt::panic!("no implemented group-priority bits")
            };
            let before = cortex::enter(level);
            let highest_inside = ran_after(SCB::set_pendsv, &PENDSV_RAN);
            let lower_inside = ran_after(SCB::set_pendst, &SYSTICK_RAN);
            // SAFETY: `before` is this section's `enter`'s.
            unsafe { cortex::leave(before) };
            cortex_m::asm::isb();
            let lower_after = SYSTICK_RAN.load(Ordering::SeqCst);
            defmt::println!(
                "section at BASEPRI {=u8:#x}: highest ran inside {=bool}, lower inside {=bool}, after {=bool}",
                level,
                highest_inside,
                lower_inside,
                lower_after
            );
            defmt::assert!(highest_inside && !lower_inside && lower_after);
        }
    }
}

/// On the host there is nothing to run: these tests need the emulated target.
#[cfg(not(target_os = "none"))]
fn main() {}
