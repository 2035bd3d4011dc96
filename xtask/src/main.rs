//! Project automation: `cargo xtask <task>`.
//!
//! * `ci --setup` — the README's test command, what `.ci/run` calls: first installs what the
//!   checks need and a fresh machine lacks ([`setup`]: the thumbv7em/thumbv7m targets,
//!   rustfmt, clippy and llvm-tools, QEMU, `cargo-fuzz`, `flip-link`, `defmt-print`, the
//!   Python cross-checks' packages in a venv, `target/ci-venv`), then runs `ci`.
//! * `ci` — everything CI checks, in order, reporting every failure (not only the first):
//!   fmt check, clippy `-D warnings` (host, all targets), rustdoc with warnings as errors,
//!   host tests, `design certify drive.toml`, the fault matrix, the population's CI sample
//!   ([`POPULATION`]), a thumbv7em build of
//!   `controller-core` on its own (proof that it is no_std without the host's `std` feature),
//!   and the firmware release build with its flash/RAM use.
//!   Then the emulated-target steps (`qemu`): fmt and clippy of `qemu-target` (a workspace
//!   of its own), its build for the Cortex-M4F, the control-law self-tests as `defmt-test`
//!   tests on QEMU `mps2-an386` and `lm3s6965evb` (`cargo test --target …` in `qemu-target`,
//!   runner in `qemu-target/.cargo/config.toml`), the instruction-count benchmark
//!   (`-icount shift=0`) at opt-level 3 and as the firmware ships (its profile), and the
//!   processor-in-the-loop tests (`hil-sim/tests/pil.rs`; the server built with every
//!   control mode, `qemu-target`'s `all-modes`).
//!   Last, `fuzz`: the link decoder under `cargo fuzz` for 60 s (needs `cargo-fuzz`).
//! * `bench` — the simulation speed against gym-electric-motor (`tools/gem_speed.py`, in the
//!   venv of `ci --setup`, made or completed first: [`setup_python`]): a figure, not a check,
//!   so not a step of `ci`.
//! * `population` — issue 49's CI sample of the population ([`POPULATION`]), also a step of
//!   `ci`.
//! * `build-tools` — the release build of `design` and `hil-sim` in one feature resolution
//!   ([`RELEASE_TOOLS`]): `certify`'s and `faults`' first step, which run its binaries; the
//!   Python scripts call it before theirs. `ci`'s first step builds `population` with them
//!   ([`RELEASE_POPULATION`]).
//! * `lint`, `test-host`, `certify`, `build-core-m4`, `build-fw [--features F]` (the
//!   firmware's features, a drive file's control modes: docs/firmware.md), `qemu`, `fuzz` —
//!   single steps; `modules` — no import cycle between the top-level modules of any crate and no
//!   module of controller-core, hil-sim or design over 1 000 lines of non-test code (part of
//!   `ci` and `lint`; see [`module_cycles`], [`module_sizes`]).
//!
//! The closing line `tests: N passed, M failed` sums cargo's `test result:` lines and the
//! defmt-test runs' (`(k/N) running …`, `all tests passed!`, decoded by `defmt-print`).

use std::process::{Command, ExitCode};

const THUMB: &str = "thumbv7em-none-eabihf";

struct Step {
    name: &'static str,
    /// `cargo` (the running one) or another program.
    program: &'static str,
    /// Arguments before `args` (the common QEMU options).
    pre_args: &'static [&'static str],
    /// Working directory (the workspace root when empty).
    dir: &'static str,
    args: &'static [&'static str],
    /// Extra environment variables.
    env: &'static [(&'static str, &'static str)],
}

impl Step {
    const fn cargo(name: &'static str, args: &'static [&'static str]) -> Self {
        Step { name, program: "cargo", pre_args: &[], dir: "", args, env: &[] }
    }
    const fn in_qemu_target(name: &'static str, args: &'static [&'static str]) -> Self {
        Step { name, program: "cargo", pre_args: &[], dir: "qemu-target", args, env: &[] }
    }
    /// A binary of [`RELEASE_TOOLS`] or [`RELEASE_POPULATION`], by its path from the workspace root.
    const fn tool(name: &'static str, path: &'static str, args: &'static [&'static str]) -> Self {
        Step { name, program: path, pre_args: &[], dir: "", args, env: &[] }
    }
    /// A Python script (the set-up's venv's interpreter when there is one: `run_counting`).
    const fn python(name: &'static str, args: &'static [&'static str]) -> Self {
        Step { name, program: "python3", pre_args: &[], dir: "", args, env: &[] }
    }
    /// A `qemu-target` program under QEMU with semihosting; exit status = the program's.
    const fn qemu(name: &'static str, args: &'static [&'static str]) -> Self {
        const COMMON: &[&str] = &["-nographic", "-semihosting-config", "enable=on,target=native"];
        Step { name, program: "qemu-system-arm", pre_args: COMMON, dir: "", args, env: &[] }
    }
}

const FMT: Step = Step::cargo("fmt", &["fmt", "--all", "--", "--check"]);
const CLIPPY: Step =
    Step::cargo("clippy", &["clippy", "--workspace", "--all-targets", "--", "-D", "warnings"]);
const DOC: Step = Step {
    name: "doc",
    program: "cargo",
    pre_args: &[],
    dir: "",
    args: &["doc", "--workspace", "--no-deps"],
    env: &[("RUSTDOCFLAGS", "-D warnings")],
};
/// The release build of the host tools, `design` and `hil-sim` in one cargo invocation: one
/// feature resolution (design's — nalgebra and toml_edit turn on features of crates
/// `hil-sim` shares, so a `cargo run -p hil-sim` of its own rebuilt controller-core, plant,
/// drive-file and hil-sim, a minute of CI). The steps below and the Python cross-checks
/// (`cargo xtask build-tools`) run the binaries it makes.
const RELEASE_TOOLS: Step = Step::cargo(
    "build-tools (release: design, hil-sim)",
    &["build", "--quiet", "--release", "--package", "design", "--package", "hil-sim"],
);
/// The release build of `population` with the host tools (one feature resolution, as
/// [`RELEASE_TOOLS`]): the first step of `ci` and of `cargo xtask population`.
const RELEASE_POPULATION: Step = Step::cargo(
    "build-tools (release: design, hil-sim, population)",
    &[
        "build",
        "--quiet",
        "--release",
        "--package",
        "design",
        "--package",
        "hil-sim",
        "--package",
        "population",
    ],
);
const CERTIFY: Step = Step::tool(
    "certify",
    "target/release/design",
    &["certify", "drive.toml", "--plot-dir", "target/certificate"],
);
const FAULTS: Step = Step::tool(
    "fault-injection matrix (hil-sim faults)",
    "target/release/hil-sim",
    &["faults", "drive.toml", "--out", "target/faults"],
);
/// Issue 49's CI sample of the population (docs/population.md): 24 members of seed 1, at 4,
/// 10 and 20 kHz in turn (eight drives at each rate), each tuned by `design tune`, then its
/// file's 200-run campaign and fault matrix; fails on a drive that passes tune and then
/// fails, or on more than 10 % refused.
/// Its last line is the sample's wall time on this machine's cores (issue 49 asks ≤ 5
/// minutes on 2 cores: docs/population.md).
const POPULATION: Step = Step::tool(
    "population sample (24 members at 4, 10, 20 kHz in turn: tune, 200-run campaign, fault matrix)",
    "target/release/population",
    &["run", "--members", "24", "--pwm", "4000,10000,20000", "--pwm-in-turn", "--out", "target/population"],
);
const TEST: Step = Step::cargo("test-host", &["test", "--workspace"]);
/// The Python cross-checks (docs/verification.md; their packages: [`PYTHON_PACKAGES`]).
const PY_GEM_DOL: Step =
    Step::python("independent plant cross-check (gym-electric-motor + scipy)", &["tools/gem_dol.py"]);
const PY_GEM_SPEED: Step =
    Step::python("simulation speed: hil-sim vs gym-electric-motor, same run", &["tools/gem_speed.py"]);
const PY_CONTROL: Step =
    Step::python("design toolkit vs python-control, same work, same run", &["tools/control_bench.py"]);
/// The versions the docs quote (docs/verification.md).
const PYTHON_PACKAGES: [&str; 3] = ["gym-electric-motor==3.0.3", "scipy==1.17.1", "control==0.10.2"];
const CORE_M4: Step =
    Step::cargo("build-core-m4", &["build", "--package", "controller-core", "--target", THUMB, "--release"]);
const FW: Step =
    Step::cargo("build-fw", &["build", "--package", "firmware", "--target", THUMB, "--profile", "firmware"]);
/// The firmware build with the firmware's `features` (a drive file's control modes beyond the
/// default image's, docs/firmware.md: `vhz`, `sensorless`, `saturation`): the one step of a run, made once.
fn firmware_with(features: &str) -> &'static Step {
    let features: &'static str = Box::leak(features.to_owned().into_boxed_str());
    let args: Vec<&'static str> = FW.args.iter().copied().chain(["--features", features]).collect();
    Box::leak(Box::new(Step::cargo(FW.name, Box::leak(args.into_boxed_slice()))))
}
const CLIPPY_FW: Step = Step::cargo(
    "clippy (firmware for the board)",
    &["clippy", "--package", "firmware", "--target", THUMB, "--profile", "firmware", "--", "-D", "warnings"],
);
/// The firmware with the commissioning sequence (feature `commissioning`, not in the default
/// image: its flash): checked for the board and tested on the host.
const CLIPPY_FW_COMMISSIONING: Step = Step::cargo(
    "clippy (firmware for the board, commissioning)",
    &[
        "clippy",
        "--package",
        "firmware",
        "--target",
        THUMB,
        "--profile",
        "firmware",
        "--features",
        "commissioning",
        "--",
        "-D",
        "warnings",
    ],
);
const TEST_FW_COMMISSIONING: Step = Step::cargo(
    "test-host (firmware, commissioning)",
    &["test", "--package", "firmware", "--features", "commissioning"],
);

const M3: &str = "thumbv7m-none-eabi";
const Q_FMT: Step = Step::in_qemu_target("qemu-target fmt", &["fmt", "--", "--check"]);
const Q_CLIPPY: Step = Step::in_qemu_target(
    "qemu-target clippy",
    &["clippy", "--target", THUMB, "--release", "--bins", "--test", "selftest", "--", "-D", "warnings"],
);
const Q_BUILD_M4: Step =
    Step::in_qemu_target("qemu-target build (M4F)", &["build", "--target", THUMB, "--release", "--bins"]);
const Q_TESTS_M4: Step = Step::in_qemu_target(
    "target tests on QEMU mps2-an386 (Cortex-M4F; defmt-test, qemu-target/tests/selftest.rs)",
    &["test", "--target", THUMB, "--release", "--test", "selftest"],
);
const Q_TESTS_M3: Step = Step::in_qemu_target(
    "target tests on QEMU lm3s6965evb (Cortex-M3, soft-float, Q32; defmt-test)",
    &["test", "--target", M3, "--release", "--test", "selftest"],
);
const Q_COST: Step = Step::qemu(
    "instructions per step on the Cortex-M4F (QEMU -icount shift=0)",
    &[
        "-cpu",
        "cortex-m4",
        "-machine",
        "mps2-an386",
        "-icount",
        "shift=0",
        "-kernel",
        "qemu-target/target/thumbv7em-none-eabihf/release/cost",
    ],
);
const Q_BUILD_M4_FW: Step = Step::in_qemu_target(
    "qemu-target build (M4F, the firmware's profile)",
    &["build", "--target", THUMB, "--profile", "firmware", "--bin", "cost"],
);
const Q_COST_FW: Step = Step::qemu(
    "instructions per step as the firmware ships (profile firmware: opt-level z, fat LTO, controller-core at 2)",
    &[
        "-cpu",
        "cortex-m4",
        "-machine",
        "mps2-an386",
        "-icount",
        "shift=0",
        "-kernel",
        "qemu-target/target/thumbv7em-none-eabihf/firmware/cost",
    ],
);
/// The processor-in-the-loop server runs every builtin scenario, V/Hz and sensorless ones
/// too: built with every control mode (the firmware's default image and `cost` leave them out).
const Q_BUILD_PIL: Step = Step::in_qemu_target(
    "qemu-target build (M4F, the PIL server with every control mode)",
    &["build", "--target", THUMB, "--release", "--bin", "pil", "--features", "all-modes"],
);
const PIL: Step = Step::cargo(
    "processor in the loop (hil-sim/tests/pil.rs)",
    // The workspace's test build (test-host's, reused): hil-sim's own `--release` test build
    // resolved other features (criterion's) and rebuilt the drive's crates, a minute of CI.
    &["test", "--workspace", "--test", "pil", "--", "--ignored", "--nocapture"],
);
const FUZZ: Step = Step {
    name: "fuzz the link decoder (60 s)",
    program: "cargo",
    pre_args: &[],
    dir: "fuzz",
    args: &["fuzz", "run", "frame_decoder", "--", "-max_total_time=60", "-print_final_stats=1"],
    // cargo fuzz passes nightly-only flags (sanitizer, coverage) to the stable compiler.
    env: &[("RUSTC_BOOTSTRAP", "1")],
};
const QEMU_STEPS: [&Step; 10] = [
    &Q_FMT,
    &Q_CLIPPY,
    &Q_BUILD_M4,
    &Q_TESTS_M4,
    &Q_TESTS_M3,
    &Q_COST,
    &Q_BUILD_M4_FW,
    &Q_COST_FW,
    &Q_BUILD_PIL,
    &PIL,
];

/// Test totals summed over every `test result:` line cargo printed.
#[derive(Default)]
struct Totals {
    passed: u64,
    failed: u64,
    /// The last `(k/N) running` line of a defmt-test run in the current step.
    target_run: Option<(u64, u64)>,
    /// Each step's wall time, in the order run (printed at the end: where CI's minutes go).
    seconds: Vec<(&'static str, f64)>,
}

impl Totals {
    /// Parse `test result: ok. 58 passed; 0 failed; …` (cargo) and `9 passed, 0 failed`
    /// (the target harness).
    fn add_line(&mut self, line: &str) {
        // defmt-test on QEMU (decoded by defmt-print): `(3/10) running `name`...`, then
        // `all tests passed!`.
        if let Some((_, rest)) = line.split_once('(')
            && let Some((kn, tail)) = rest.split_once(')')
            && tail.trim_start().starts_with("running")
            && let Some((k, n)) = kn.split_once('/')
            && let (Ok(k), Ok(n)) = (k.parse::<u64>(), n.parse::<u64>())
        {
            self.target_run = Some((k, n));
            return;
        }
        if line.contains("all tests passed!")
            && let Some((_, n)) = self.target_run.take()
        {
            self.passed += n;
            return;
        }
        if let Some((p, f)) = line.split_once(" passed, ")
            && let (Ok(p), Some(Ok(f))) =
                (p.trim().parse::<u64>(), f.strip_suffix(" failed").map(|f| f.trim().parse::<u64>()))
        {
            self.passed += p;
            self.failed += f;
            return;
        }
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

    /// End of a step: a defmt-test run that stopped at test k of N passed k − 1 and failed one.
    fn finish_step(&mut self) {
        if let Some((k, _)) = self.target_run.take() {
            self.passed += k.saturating_sub(1);
            self.failed += 1;
        }
    }
}

/// Run a step, echoing its stdout line by line and counting any test results in it.
fn run_counting(step: &Step, totals: &mut Totals) -> bool {
    let started = std::time::Instant::now();
    let passed = run_step(step, totals);
    let s = started.elapsed().as_secs_f64();
    eprintln!("=== xtask: {} {} in {s:.0} s ===", step.name, if passed { "passed" } else { "FAILED" });
    totals.seconds.push((step.name, s));
    passed
}

/// Run one step, its standard output echoed line by line and counted into `totals`.
fn run_step(step: &Step, totals: &mut Totals) -> bool {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let all_args: Vec<&str> = step.pre_args.iter().chain(step.args).copied().collect();
    eprintln!("\n=== xtask: {} ({} {}) ===", step.name, step.program, all_args.join(" "));
    let program = match step.program {
        "cargo" => std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()),
        // The set-up's venv when there is one (its packages), else the PATH's python3.
        "python3" if std::path::Path::new(VENV_PYTHON).exists() => VENV_PYTHON.into(),
        other => other.into(),
    };
    let mut cmd = Command::new(program);
    if !step.dir.is_empty() {
        cmd.current_dir(step.dir);
    }
    let mut child = match cmd
        .args(&all_args)
        .stdin(Stdio::null())
        .envs(step.env.iter().copied())
        .stdout(Stdio::piped())
        .spawn()
    {
        Ok(c) => c,
        Err(e) => {
            eprintln!("xtask: cannot start {} for `{}`: {e}", step.program, step.name);
            return false;
        }
    };
    if let Some(out) = child.stdout.take() {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            println!("{line}");
            totals.add_line(&line);
        }
    }
    let status = child.wait();
    totals.finish_step();
    match status {
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

/// Budget of issue 6: flash and static RAM of the release firmware.
const FLASH_BUDGET: u64 = 48 * 1024;
const RAM_BUDGET: u64 = 12 * 1024;

fn report_firmware_size() -> bool {
    let elf = std::path::Path::new("target").join(THUMB).join("firmware").join("firmware");
    match elf_size(&elf) {
        Ok((flash, ram)) => {
            println!(
                "firmware size: flash {flash} B ({:.1} KiB of {} KiB), static RAM {ram} B ({:.1} KiB of {} KiB; stack not included)",
                flash as f64 / 1024.0,
                FLASH_BUDGET / 1024,
                ram as f64 / 1024.0,
                RAM_BUDGET / 1024
            );
            let ok = flash <= FLASH_BUDGET && ram <= RAM_BUDGET;
            if !ok {
                eprintln!("xtask: firmware over budget");
            }
            ok
        }
        Err(e) => {
            eprintln!("xtask: firmware size: {e}");
            false
        }
    }
}

/// `llvm-objdump` of the `llvm-tools` rustup component (`.ci/run` installs it).
fn llvm_objdump() -> Result<std::path::PathBuf, String> {
    let out = |args: &[&str]| -> Result<String, String> {
        let o = Command::new("rustc").args(args).output().map_err(|e| format!("rustc: {e}"))?;
        Ok(String::from_utf8_lossy(&o.stdout).into_owned())
    };
    let sysroot = out(&["--print", "sysroot"])?;
    let host = out(&["-vV"])?
        .lines()
        .find_map(|l| l.strip_prefix("host: ").map(str::to_string))
        .ok_or("rustc -vV names no host")?;
    let p =
        std::path::Path::new(sysroot.trim()).join("lib/rustlib").join(host.trim()).join("bin/llvm-objdump");
    if p.is_file() {
        Ok(p)
    } else {
        Err(format!("{} missing: `rustup component add llvm-tools`", p.display()))
    }
}

/// In the disassembly `dis`, the first of {`cpsid`, a store that is not a push, a call} in
/// the function whose label ends with `name_suffix`; `None` if the function is not found.
fn first_effect(dis: &str, name_suffix: &str) -> Option<String> {
    let mut lines = dis.lines().skip_while(|l| !(l.ends_with(">:") && l.contains(name_suffix)));
    lines.next()?;
    for l in lines {
        if l.trim().is_empty() {
            break;
        }
        let Some(mnemonic) = l.split('\t').nth(1).map(str::trim) else { continue };
        if mnemonic.starts_with("cpsid")
            || mnemonic.starts_with("str")
            || mnemonic.starts_with("stm")
            || mnemonic == "bl"
            || mnemonic == "blx"
        {
            return Some(l.trim().to_string());
        }
    }
    Some(String::from("(none)"))
}

/// Issue 19: the panic and HardFault handlers of the shipped firmware mask interrupts
/// (`cpsid i`) before their first store or call — before they touch TIM1 — so that no
/// control interrupt can run again and set MOE.
fn check_fault_handlers() -> bool {
    let elf = std::path::Path::new("target").join(THUMB).join("firmware").join("firmware");
    let objdump = |args: &[&str]| {
        llvm_objdump().and_then(|od| {
            let o =
                Command::new(od).args(args).arg(&elf).output().map_err(|e| format!("llvm-objdump: {e}"))?;
            Ok(String::from_utf8_lossy(&o.stdout).into_owned())
        })
    };
    let (dis, syms) = match (objdump(&["-d", "--no-show-raw-insn"]), objdump(&["-t"])) {
        (Ok(d), Ok(s)) => (d, s),
        (Err(e), _) | (_, Err(e)) => {
            eprintln!("xtask: fault handlers: {e}");
            return false;
        }
    };
    // The default handler's trampoline shares its address with the vectors it serves, and
    // the disassembly labels it with one of their names: found by the symbol's address.
    let default_label = syms
        .lines()
        .find(|l| l.split_whitespace().last() == Some("DefaultHandler"))
        .and_then(|l| l.split_whitespace().next())
        .map(|addr| format!("{addr} <"));
    let mut ok = true;
    for (what, label) in [
        ("panic handler", Some("rust_begin_unwind>:".to_string())),
        ("HardFault handler", Some("__cortex_m_rt_HardFault".to_string())),
        // Every other exception and interrupt without a handler, the NMI among them: its
        // trampoline reads the IRQ number and calls the handler's body (the linker may fold
        // it with the HardFault handler's, which is the same code).
        ("default handler (NMI, unused vectors)", default_label),
    ] {
        let first = label.as_deref().and_then(|l| first_effect(&dis, l));
        let first = match first {
            Some(f) if f.contains("\tbl\t") => {
                let target = f.split('<').nth(1).and_then(|t| t.split('>').next()).map(|t| format!("<{t}>:"));
                target.and_then(|t| first_effect(&dis, &t)).map(|g| format!("{f} → {g}"))
            }
            other => other,
        };
        match first {
            Some(first) if first.split(" → ").last().is_some_and(|l| l.contains("cpsid")) => {
                println!("fault handlers: {what} masks interrupts first ({first})")
            }
            Some(first) => {
                eprintln!("xtask: {what}: first store or call is not `cpsid`: {first}");
                ok = false;
            }
            None => {
                eprintln!("xtask: {what} not found in {}", elf.display());
                ok = false;
            }
        }
    }
    ok
}

/// The crates whose module graphs are checked.
const CRATES: [&str; 9] = [
    "controller-core",
    "drive-file",
    "plant",
    "report",
    "hil-sim",
    "design",
    "firmware",
    "qemu-target",
    "xtask",
];

/// Top-level module of a source file (`src/a.rs`, `src/a/b.rs`, `src/a/mod.rs` → `a`; the
/// crate roots and `src/bin/*` → `None`).
fn top_module(rel: &std::path::Path) -> Option<String> {
    let mut parts = rel.iter().map(|p| p.to_string_lossy().into_owned());
    let first = parts.next()?;
    let name = first.strip_suffix(".rs").unwrap_or(&first).to_string();
    (!matches!(name.as_str(), "lib" | "main" | "bin")).then_some(name)
}

/// `crate::NAME` references in the non-test code of `text` (comments and `#[cfg(test)]`
/// modules do not count: a doc link or a test helper is not a dependency of the module).
fn crate_references(text: &str) -> std::collections::BTreeSet<String> {
    let mut out = std::collections::BTreeSet::new();
    for line in text.lines() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        let code = line.split("//").next().unwrap_or("");
        for (i, _) in code.match_indices("crate::") {
            let rest = code.get(i + 7..).unwrap_or("");
            let name: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            let before = code.get(..i).and_then(|b| b.chars().last());
            if !name.is_empty() && !before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$') {
                out.insert(name);
            }
        }
    }
    out
}

/// A cycle in the graph `edges` (module → modules it uses), if any, as the modules on it.
fn find_cycle(
    edges: &std::collections::BTreeMap<String, std::collections::BTreeSet<String>>,
) -> Option<Vec<String>> {
    fn visit(
        n: &str,
        edges: &std::collections::BTreeMap<String, std::collections::BTreeSet<String>>,
        state: &mut std::collections::BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(n.to_string(), 1);
        stack.push(n.to_string());
        for m in edges.get(n).into_iter().flatten() {
            match state.get(m.as_str()) {
                Some(1) => {
                    let at = stack.iter().position(|s| s == m).unwrap_or(0);
                    let mut cycle = stack.get(at..).unwrap_or_default().to_vec();
                    cycle.push(m.clone());
                    return Some(cycle);
                }
                Some(_) => {}
                None => {
                    if let Some(c) = visit(m, edges, state, stack) {
                        return Some(c);
                    }
                }
            }
        }
        stack.pop();
        state.insert(n.to_string(), 2);
        None
    }
    let mut state = std::collections::BTreeMap::new();
    for n in edges.keys() {
        if !state.contains_key(n.as_str())
            && let Some(c) = visit(n, edges, &mut state, &mut Vec::new())
        {
            return Some(c);
        }
    }
    None
}

/// The Rust source files under `dir`, sorted.
fn rust_files(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(p) = todo.pop() {
        if p.is_dir() {
            if let Ok(rd) = std::fs::read_dir(&p) {
                todo.extend(rd.filter_map(Result::ok).map(|e| e.path()));
            }
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
    out.sort();
    out
}

/// The crates whose modules are held to [`MODULE_LINES_MAX`] (issue 48).
const SIZED_CRATES: [&str; 3] = ["controller-core", "hil-sim", "design"];

/// The most lines of non-test code one module file of [`SIZED_CRATES`] may hold.
const MODULE_LINES_MAX: usize = 1000;

/// Lines of a module's non-test code: those before its first `#[cfg(test)]`.
fn non_test_lines(text: &str) -> usize {
    text.lines().take_while(|l| !l.trim_start().starts_with("#[cfg(test)]")).count()
}

/// The files of the `#[cfg(test)] mod name;` declarations in the module file `path` (its
/// text `text`): `name.rs` and `name/mod.rs` beside a `mod.rs`, `lib.rs` or `main.rs`,
/// under `stem/` beside any other file.
fn test_module_files(path: &std::path::Path, text: &str) -> Vec<std::path::PathBuf> {
    let parent = path.parent().unwrap_or(std::path::Path::new(""));
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let dir = if matches!(stem.as_str(), "mod" | "lib" | "main") {
        parent.to_path_buf()
    } else {
        parent.join(stem)
    };
    let mut out = Vec::new();
    let mut under_cfg_test = false;
    for line in text.lines().map(str::trim) {
        if line.starts_with("#[cfg(test)]") {
            under_cfg_test = true;
        } else if !line.starts_with("#[") {
            if under_cfg_test && let Some(name) = line.strip_prefix("mod ").and_then(|r| r.strip_suffix(';'))
            {
                out.push(dir.join(format!("{name}.rs")));
                out.push(dir.join(name).join("mod.rs"));
            }
            under_cfg_test = false;
        }
    }
    out
}

/// No module file of [`SIZED_CRATES`] holds more than [`MODULE_LINES_MAX`] lines of
/// non-test code ([`non_test_lines`]; a file that is a test module is not counted): each
/// crate's largest is printed, each one over the limit named.
fn module_sizes() -> bool {
    let mut ok = true;
    for krate in SIZED_CRATES {
        let files: Vec<(std::path::PathBuf, String)> = rust_files(&std::path::Path::new(krate).join("src"))
            .into_iter()
            .map(|p| {
                let text = std::fs::read_to_string(&p).unwrap_or_default();
                (p, text)
            })
            .collect();
        let tests: Vec<std::path::PathBuf> =
            files.iter().flat_map(|(p, t)| test_module_files(p, t)).collect();
        let mut largest = (0, std::path::PathBuf::new());
        for (p, text) in files.iter().filter(|(p, _)| !tests.contains(p)) {
            let n = non_test_lines(text);
            if n > MODULE_LINES_MAX {
                eprintln!(
                    "xtask: {} holds {n} lines of non-test code, more than {MODULE_LINES_MAX}",
                    p.display()
                );
                ok = false;
            }
            if n > largest.0 {
                largest = (n, p.clone());
            }
        }
        println!(
            "modules: {krate}: largest module {} ({} non-test lines, at most {MODULE_LINES_MAX})",
            largest.1.display(),
            largest.0
        );
    }
    ok
}

/// No import cycle between the top-level modules of any crate: every `crate::x` reference
/// in a module's non-test code is an edge to `x`; a cycle fails the check, printed.
fn module_cycles() -> bool {
    let mut ok = true;
    for krate in CRATES {
        let src = std::path::Path::new(krate).join("src");
        let mut edges: std::collections::BTreeMap<String, std::collections::BTreeSet<String>> =
            std::collections::BTreeMap::new();
        for p in rust_files(&src) {
            let Some(module) = p.strip_prefix(&src).ok().and_then(top_module) else { continue };
            let text = std::fs::read_to_string(&p).unwrap_or_default();
            let refs: Vec<String> = crate_references(&text).into_iter().filter(|m| *m != module).collect();
            edges.entry(module).or_default().extend(refs);
        }
        match find_cycle(&edges) {
            Some(c) => {
                eprintln!("xtask: module cycle in {krate}: {}", c.join(" → "));
                ok = false;
            }
            None => println!("modules: {krate}: {} top-level modules, no cycle", edges.len()),
        }
    }
    ok
}

/// Run `program args` for the set-up, its output passed through; `Err` says what failed.
fn run_setup(program: &str, args: &[&str]) -> Result<(), String> {
    eprintln!("\n=== xtask setup: {program} {} ===", args.join(" "));
    match Command::new(program).args(args).status() {
        Ok(s) if s.success() => Ok(()),
        Ok(s) => Err(format!("`{program} {}` failed with {s}", args.join(" "))),
        Err(e) => Err(format!("cannot start `{program}`: {e}")),
    }
}

/// `program` answers `--version` (it is on the PATH).
fn on_path(program: &str) -> bool {
    Command::new(program).arg("--version").output().is_ok_and(|o| o.status.success())
}

/// Install what `ci` needs and a fresh machine lacks (`ci --setup`; what `.ci/run` did
/// itself until the README's command did it): the targets and components through rustup,
/// QEMU through apt-get (as root; otherwise it says what to install), the cargo tools with
/// `--locked`, the Python packages at the versions the docs quote. What is there already is
/// left alone, so a second run costs seconds.
fn setup() -> Result<(), String> {
    run_setup("rustup", &["target", "add", THUMB, M3])?;
    run_setup("rustup", &["component", "add", "rustfmt", "clippy", "llvm-tools"])?;
    if !on_path("qemu-system-arm") {
        let root = Command::new("id").arg("-u").output().is_ok_and(|o| o.stdout.starts_with(b"0\n"));
        if !(root && on_path("apt-get")) {
            return Err("QEMU is missing: install qemu-system-arm (Debian/Ubuntu: \
                        `sudo apt-get install qemu-system-arm`), then run this again"
                .into());
        }
        run_setup("apt-get", &["update", "-qq"])?;
        run_setup("apt-get", &["install", "-y", "-qq", "qemu-system-arm"])?;
    }
    for (tool, krate) in
        [("cargo-fuzz", "cargo-fuzz"), ("flip-link", "flip-link"), ("defmt-print", "defmt-print")]
    {
        // cargo-fuzz answers `cargo fuzz --version`, not `cargo-fuzz --version`.
        let there = if tool == "cargo-fuzz" {
            Command::new("cargo").args(["fuzz", "--version"]).output().is_ok_and(|o| o.status.success())
        } else {
            on_path(tool)
        };
        if !there {
            run_setup("cargo", &["install", krate, "--locked", "--quiet"])?;
        }
    }
    setup_python()
}

/// The Python packages at the versions the docs quote, in a venv of the workspace's own
/// (`target/ci-venv`): a distribution's python3 is "externally managed" (PEP 668) and
/// refuses pip installs into it. Part of `ci --setup`, and what `bench` does first (its
/// script needs gym-electric-motor: without the venv it stopped on a `ModuleNotFoundError`).
fn setup_python() -> Result<(), String> {
    if !std::path::Path::new(VENV_PYTHON).exists() {
        run_setup("python3", &["-m", "venv", VENV_DIR]).map_err(|e| {
            format!("{e} (Debian/Ubuntu: `sudo apt-get install python3-venv`, then run this again)")
        })?;
    }
    let mut pip = vec!["-m", "pip", "install", "--quiet", "--disable-pip-version-check"];
    pip.extend(PYTHON_PACKAGES);
    run_setup(VENV_PYTHON, &pip)
}

/// The set-up's Python environment (the cross-checks' packages), in the workspace's target
/// directory.
const VENV_DIR: &str = "target/ci-venv";
/// … its interpreter: what the Python steps run when it exists.
const VENV_PYTHON: &str = "target/ci-venv/bin/python3";

fn main() -> ExitCode {
    let task = std::env::args().nth(1).unwrap_or_else(|| "help".into());
    let options: Vec<String> = std::env::args().skip(2).collect();
    let mut fw = &FW;
    match (task.as_str(), options.as_slice()) {
        ("ci", [o]) if o == "--setup" => {
            if let Err(e) = setup() {
                eprintln!("xtask: set-up failed: {e}");
                return ExitCode::FAILURE;
            }
        }
        ("build-fw", [o, features]) if o == "--features" => fw = firmware_with(features),
        ("bench", []) => {
            if let Err(e) = setup_python() {
                eprintln!("xtask: set-up of the Python packages failed: {e}");
                return ExitCode::FAILURE;
            }
        }
        (_, []) => {}
        _ => {
            eprintln!(
                "xtask: unknown options {options:?} (only `ci --setup` and `build-fw --features F` take them)"
            );
            return ExitCode::from(2);
        }
    }
    let steps: Vec<&Step> = match task.as_str() {
        "ci" => [
            &RELEASE_POPULATION,
            &PY_GEM_DOL,
            &PY_CONTROL,
            &FMT,
            &CLIPPY,
            &CLIPPY_FW,
            &CLIPPY_FW_COMMISSIONING,
            &DOC,
            &TEST,
            &TEST_FW_COMMISSIONING,
            &CERTIFY,
            &FAULTS,
            &POPULATION,
            &CORE_M4,
            &FW,
        ]
        .into_iter()
        .chain(QEMU_STEPS)
        .chain([&FUZZ])
        .collect(),
        "fuzz" => vec![&FUZZ],
        // The script builds the tools itself (`cargo xtask build-tools`).
        "bench" => vec![&PY_GEM_SPEED],
        "build-tools" => vec![&RELEASE_TOOLS],
        "qemu" => QEMU_STEPS.to_vec(),
        "lint" => vec![&FMT, &CLIPPY, &CLIPPY_FW, &CLIPPY_FW_COMMISSIONING, &DOC],
        "modules" => vec![],
        "test-host" => vec![&TEST, &TEST_FW_COMMISSIONING],
        "build-core-m4" => vec![&CORE_M4],
        "build-fw" => vec![fw],
        "certify" => vec![&RELEASE_TOOLS, &CERTIFY],
        "faults" => vec![&RELEASE_TOOLS, &FAULTS],
        "population" => vec![&RELEASE_POPULATION, &POPULATION],
        _ => {
            eprintln!(
                "usage: cargo xtask <ci [--setup] | lint | modules | test-host | build-tools | certify | faults | population | build-core-m4 | build-fw [--features F] | qemu | fuzz | bench>"
            );
            return ExitCode::from(2);
        }
    };
    let mut totals = Totals::default();
    let mut failed: Vec<&str> =
        steps.iter().filter(|s| !run_counting(s, &mut totals)).map(|s| s.name).collect();
    if steps.iter().any(|s| s.name == FW.name) && !failed.contains(&FW.name) {
        if !report_firmware_size() {
            failed.push("firmware-size");
        }
        if !check_fault_handlers() {
            failed.push("fault-handlers");
        }
    }
    if matches!(task.as_str(), "ci" | "lint" | "modules") {
        if !module_cycles() {
            failed.push("modules");
        }
        if !module_sizes() {
            failed.push("module-sizes");
        }
    }
    if totals.seconds.len() > 1 {
        let total: f64 = totals.seconds.iter().map(|(_, s)| s).sum();
        eprintln!("\nxtask {task}: wall time per step ({total:.0} s in all)");
        for (name, s) in &totals.seconds {
            eprintln!("{s:>8.0} s  {name}");
        }
    }
    let code = if failed.is_empty() {
        eprintln!("\nxtask {task}: all steps passed");
        ExitCode::SUCCESS
    } else {
        eprintln!("\nxtask {task}: FAILED steps: {}", failed.join(", "));
        ExitCode::FAILURE
    };
    if steps.iter().any(|s| s.name == TEST.name || s.name == PIL.name) {
        use std::io::Write;
        let _ = std::io::stderr().flush();
        println!("tests: {} passed, {} failed", totals.passed, totals.failed);
    }
    code
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn module_sizes_count_non_test_code_and_skip_test_files() {
        assert_eq!(non_test_lines("a\nb\n#[cfg(test)]\nmod tests {\n}\n"), 2);
        assert_eq!(non_test_lines("a\n    #[cfg(test)]\n    fn t() {}\n"), 1);
        let text = "mod fast;\n#[cfg(test)]\n#[allow(clippy::unwrap_used)]\nmod tests;\n#[cfg(test)]\nmod inline {}\n";
        let beside = |p: &str| test_module_files(std::path::Path::new(p), text);
        assert_eq!(
            beside("src/drive/mod.rs"),
            [std::path::PathBuf::from("src/drive/tests.rs"), "src/drive/tests/mod.rs".into()]
        );
        assert_eq!(
            beside("src/drive.rs"),
            [std::path::PathBuf::from("src/drive/tests.rs"), "src/drive/tests/mod.rs".into()]
        );
        assert!(test_module_files(std::path::Path::new("src/lib.rs"), "mod tests;\n").is_empty());
    }

    #[test]
    fn references_and_cycles() {
        let refs = crate_references(
            "use crate::a::X;\n// crate::b\nfn f() { crate::c::g(); my_crate::d(); }\n#[cfg(test)]\nmod tests { use crate::e; }",
        );
        assert_eq!(refs.into_iter().collect::<Vec<_>>(), ["a", "c"]);
        let graph = |pairs: &[(&str, &str)]| {
            let mut g: std::collections::BTreeMap<String, std::collections::BTreeSet<String>> =
                Default::default();
            for (a, b) in pairs {
                g.entry((*a).into()).or_default().insert((*b).into());
                g.entry((*b).into()).or_default();
            }
            g
        };
        assert_eq!(find_cycle(&graph(&[("a", "b"), ("b", "c"), ("a", "c")])), None);
        assert_eq!(find_cycle(&graph(&[("a", "b"), ("b", "c"), ("c", "a")])).unwrap(), ["a", "b", "c", "a"]);
        assert_eq!(top_module(std::path::Path::new("x/mod.rs")).as_deref(), Some("x"));
        assert_eq!(top_module(std::path::Path::new("bin/pil.rs")), None);
        assert_eq!(top_module(std::path::Path::new("sim.rs")).as_deref(), Some("sim"));
    }

    #[test]
    fn fault_handler_disassembly_check() {
        let good = "08000c58 <x_rust_begin_unwind>:\n 8000c58:\tpush\t{r7, lr}\n 8000c5c:\tldr\tr1, [pc, #0x28]\n 8000c5e:\tcpsid i\n 8000c66:\tstr\tr2, [r1]\n\n";
        let bad = good.replace("\tcpsid i\n", "\tnop\n");
        assert!(first_effect(good, "rust_begin_unwind>:").unwrap().contains("cpsid"));
        assert!(first_effect(&bad, "rust_begin_unwind>:").unwrap().contains("str"));
        assert_eq!(first_effect(good, "HardFault"), None);
    }
}
