//! Project automation: `cargo xtask <task>`.
//!
//! * `ci` — everything CI checks, in order, reporting every failure (not only the first):
//!   fmt check, clippy `-D warnings` (host, all targets), rustdoc with warnings as errors,
//!   host tests, `design certify gains.toml`, a thumbv7em build of
//!   `controller-core` on its own (proof that it is no_std without the host's `std` feature),
//!   and the firmware release build with its flash/RAM use.
//! * `lint`, `test-host`, `build-core-m4`, `build-fw` — the single steps.

use std::process::{Command, ExitCode};

const THUMB: &str = "thumbv7em-none-eabihf";

struct Step {
    name: &'static str,
    args: &'static [&'static str],
    /// Extra environment variables.
    env: &'static [(&'static str, &'static str)],
}

const FMT: Step = Step { name: "fmt", args: &["fmt", "--all", "--", "--check"], env: &[] };
const CLIPPY: Step = Step {
    name: "clippy",
    args: &["clippy", "--workspace", "--all-targets", "--", "-D", "warnings"],
    env: &[],
};
const DOC: Step =
    Step { name: "doc", args: &["doc", "--workspace", "--no-deps"], env: &[("RUSTDOCFLAGS", "-D warnings")] };
const CERTIFY: Step = Step {
    name: "certify",
    args: &["run", "--quiet", "--release", "--package", "design", "--", "certify", "gains.toml"],
    env: &[],
};
const TEST: Step = Step { name: "test-host", args: &["test", "--workspace"], env: &[] };
const CORE_M4: Step = Step {
    name: "build-core-m4",
    args: &["build", "--package", "controller-core", "--target", THUMB, "--release"],
    env: &[],
};
const FW: Step = Step {
    name: "build-fw",
    args: &["build", "--package", "firmware", "--target", THUMB, "--release"],
    env: &[],
};

/// Test totals summed over every `test result:` line cargo printed.
#[derive(Default)]
struct Totals {
    passed: u64,
    failed: u64,
}

impl Totals {
    /// Parse `test result: ok. 58 passed; 0 failed; …`.
    fn add_line(&mut self, line: &str) {
        let Some(rest) = line.strip_prefix("test result: ") else { return };
        let count = |word: &str| {
            rest.split(';')
                .find_map(|part| {
                    part.trim().trim_start_matches("ok. ").trim_start_matches("FAILED. ").strip_suffix(word)
                })
                .and_then(|n| n.trim().parse::<u64>().ok())
                .unwrap_or(0)
        };
        self.passed += count(" passed");
        self.failed += count(" failed");
    }
}

/// Run a step, echoing its stdout line by line and counting any test results in it.
fn run_counting(step: &Step, totals: &mut Totals) -> bool {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    eprintln!("\n=== xtask: {} (cargo {}) ===", step.name, step.args.join(" "));
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut child = match Command::new(cargo)
        .args(step.args)
        .envs(step.env.iter().copied())
        .stdout(Stdio::piped())
        .spawn()
    {
        Ok(c) => c,
        Err(e) => {
            eprintln!("xtask: cannot start cargo for `{}`: {e}", step.name);
            return false;
        }
    };
    if let Some(out) = child.stdout.take() {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            println!("{line}");
            totals.add_line(&line);
        }
    }
    match child.wait() {
        Ok(s) if s.success() => true,
        Ok(s) => {
            eprintln!("xtask: step `{}` failed with {s}", step.name);
            false
        }
        Err(e) => {
            eprintln!("xtask: waiting for `{}`: {e}", step.name);
            false
        }
    }
}

/// Flash and static-RAM use of an ELF32 little-endian image, like `size`: flash = every
/// allocated section with file contents (vector table, text, rodata, data's load image),
/// RAM = every allocated writable section (data, bss, uninit). The stack is not included.
fn elf_size(path: &std::path::Path) -> Result<(u64, u64), String> {
    let b = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let u16_at =
        |o: usize| b.get(o..o + 2).and_then(|s| s.try_into().ok()).map(|a| u16::from_le_bytes(a) as usize);
    let u32_at =
        |o: usize| b.get(o..o + 4).and_then(|s| s.try_into().ok()).map(|a| u64::from(u32::from_le_bytes(a)));
    if b.get(0..5) != Some(b"\x7fELF\x01".as_slice()) {
        return Err(format!("{} is not an ELF32 file", path.display()));
    }
    let bad = || format!("{}: truncated ELF header", path.display());
    let shoff = u32_at(0x20).ok_or_else(bad)? as usize;
    let (shentsize, shnum) = (u16_at(0x2E).ok_or_else(bad)?, u16_at(0x30).ok_or_else(bad)?);
    let (mut flash, mut ram) = (0u64, 0u64);
    for i in 0..shnum {
        let h = shoff + i * shentsize;
        let (ty, flags, size) =
            (u32_at(h + 4).ok_or_else(bad)?, u32_at(h + 8).ok_or_else(bad)?, u32_at(h + 20).ok_or_else(bad)?);
        const ALLOC: u64 = 0x2;
        const WRITE: u64 = 0x1;
        const NOBITS: u64 = 8;
        if flags & ALLOC != 0 {
            if ty != NOBITS {
                flash += size;
            }
            if flags & WRITE != 0 {
                ram += size;
            }
        }
    }
    Ok((flash, ram))
}

fn report_firmware_size() -> bool {
    let elf = std::path::Path::new("target").join(THUMB).join("release").join("firmware");
    match elf_size(&elf) {
        Ok((flash, ram)) => {
            println!(
                "firmware size: flash {flash} B ({:.1} KiB), static RAM {ram} B ({:.1} KiB)",
                flash as f64 / 1024.0,
                ram as f64 / 1024.0
            );
            true
        }
        Err(e) => {
            eprintln!("xtask: firmware size: {e}");
            false
        }
    }
}

fn main() -> ExitCode {
    let task = std::env::args().nth(1).unwrap_or_else(|| "help".into());
    let steps: Vec<&Step> = match task.as_str() {
        "ci" => vec![&FMT, &CLIPPY, &DOC, &TEST, &CERTIFY, &CORE_M4, &FW],
        "lint" => vec![&FMT, &CLIPPY, &DOC],
        "test-host" => vec![&TEST],
        "build-core-m4" => vec![&CORE_M4],
        "build-fw" => vec![&FW],
        "certify" => vec![&CERTIFY],
        _ => {
            eprintln!("usage: cargo xtask <ci | lint | test-host | certify | build-core-m4 | build-fw>");
            return ExitCode::from(2);
        }
    };
    let mut totals = Totals::default();
    let mut failed: Vec<&str> =
        steps.iter().filter(|s| !run_counting(s, &mut totals)).map(|s| s.name).collect();
    if steps.iter().any(|s| s.name == FW.name) && !failed.contains(&FW.name) && !report_firmware_size() {
        failed.push("firmware-size");
    }
    let code = if failed.is_empty() {
        eprintln!("\nxtask {task}: all {} steps passed", steps.len());
        ExitCode::SUCCESS
    } else {
        eprintln!("\nxtask {task}: FAILED steps: {}", failed.join(", "));
        ExitCode::FAILURE
    };
    if steps.iter().any(|s| s.name == TEST.name) {
        use std::io::Write;
        let _ = std::io::stderr().flush();
        println!("tests: {} passed, {} failed", totals.passed, totals.failed);
    }
    code
}
