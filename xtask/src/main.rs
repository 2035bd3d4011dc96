//! Project automation: `cargo xtask <task>`.
//!
//! * `ci` — everything CI checks, in order, reporting every failure (not only the first):
//!   fmt check, clippy `-D warnings` (host, all targets), host tests, a thumbv7em build of
//!   `controller-core` on its own (proof that it is no_std without the host's `std` feature),
//!   and the firmware release build with its flash/RAM use.
//! * `lint`, `test-host`, `build-core-m4`, `build-fw` — the single steps.

use std::process::{Command, ExitCode};

const THUMB: &str = "thumbv7em-none-eabihf";

struct Step {
    name: &'static str,
    args: &'static [&'static str],
}

const FMT: Step = Step { name: "fmt", args: &["fmt", "--all", "--", "--check"] };
const CLIPPY: Step =
    Step { name: "clippy", args: &["clippy", "--workspace", "--all-targets", "--", "-D", "warnings"] };
const TEST: Step = Step { name: "test-host", args: &["test", "--workspace"] };
const CORE_M4: Step = Step {
    name: "build-core-m4",
    args: &["build", "--package", "controller-core", "--target", THUMB, "--release"],
};
const FW: Step =
    Step { name: "build-fw", args: &["build", "--package", "firmware", "--target", THUMB, "--release"] };

fn run(step: &Step) -> bool {
    eprintln!("\n=== xtask: {} (cargo {}) ===", step.name, step.args.join(" "));
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    match Command::new(cargo).args(step.args).status() {
        Ok(s) if s.success() => true,
        Ok(s) => {
            eprintln!("xtask: step `{}` failed with {s}", step.name);
            false
        }
        Err(e) => {
            eprintln!("xtask: cannot start cargo for `{}`: {e}", step.name);
            false
        }
    }
}

fn main() -> ExitCode {
    let task = std::env::args().nth(1).unwrap_or_else(|| "help".into());
    let steps: Vec<&Step> = match task.as_str() {
        "ci" => vec![&FMT, &CLIPPY, &TEST, &CORE_M4, &FW],
        "lint" => vec![&FMT, &CLIPPY],
        "test-host" => vec![&TEST],
        "build-core-m4" => vec![&CORE_M4],
        "build-fw" => vec![&FW],
        _ => {
            eprintln!("usage: cargo xtask <ci | lint | test-host | build-core-m4 | build-fw>");
            return ExitCode::from(2);
        }
    };
    let failed: Vec<&str> = steps.iter().filter(|s| !run(s)).map(|s| s.name).collect();
    if failed.is_empty() {
        eprintln!("\nxtask {task}: all {} steps passed", steps.len());
        ExitCode::SUCCESS
    } else {
        eprintln!("\nxtask {task}: FAILED steps: {}", failed.join(", "));
        ExitCode::FAILURE
    }
}
