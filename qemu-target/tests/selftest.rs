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

        #[test]
        fn q32_icad_vs_f64() {
            check(selftest::q32_icad_vs_f64());
        }

        #[test]
        fn f32_icad_vs_f64() {
            check(selftest::f32_icad_vs_f64());
        }
    }
}

/// On the host there is nothing to run: these tests need the emulated target.
#[cfg(not(target_os = "none"))]
fn main() {}
