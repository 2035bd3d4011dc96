//! `controller_core::selftest` on the emulated target: one line per check, a closing
//! `N passed, M failed` line, exit status 0 only if all pass.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use controller_core::selftest;
    use cortex_m_rt::entry;
    use qemu_target::{println, sh};

    #[entry]
    fn main() -> ! {
        // The Cortex-M3 has no FPU: every f32 operation is a library call, so its long
        // time-domain checks run shortened (same limits).
        let quick = cfg!(not(target_abi = "eabihf"));
        let core = if quick { "Cortex-M3, soft-float" } else { "Cortex-M4F, FPU" };
        println!("controller-core self-tests on {}", core);
        let (mut passed, mut failed) = (0u32, 0u32);
        let Ok(spec) = qemu_target::drive::drive_spec() else {
            println!("the generated drive specification is invalid");
            sh::exit(false)
        };
        for c in selftest::all(&spec, quick) {
            let verdict = if c.passed() { "ok" } else { "FAILED" };
            println!("test {} ... {} (measured {:e}, limit {:e})", c.name, verdict, c.measured, c.limit);
            if c.passed() {
                passed += 1;
            } else {
                failed += 1;
            }
        }
        println!("{} passed, {} failed", passed, failed);
        sh::exit(failed == 0)
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("target-tests: a Cortex-M program; `cargo xtask qemu` runs it under QEMU");
}
