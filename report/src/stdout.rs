//! Standard output for the command-line tools: [`outln!`](crate::outln) and
//! [`out!`](crate::out) instead of `println!`/`print!`, which panic when the reader has gone
//! (`design certify --json | head`, `hil-sim faults | true`: a panic with a backtrace, and
//! `design tune`'s and `hil-sim identify`'s files were never written — found by trying). A
//! reader that left is no error of the tool's: the text is dropped and the work goes on;
//! any other error on standard output is said once on standard error.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};

/// Write `args` to standard output (a line when `newline`); see the module docs.
pub fn write(args: std::fmt::Arguments<'_>, newline: bool) {
    static SAID: AtomicBool = AtomicBool::new(false);
    let mut out = std::io::stdout().lock();
    let r = if newline { writeln!(out, "{args}") } else { write!(out, "{args}") };
    if let Err(e) = r
        && e.kind() != std::io::ErrorKind::BrokenPipe
        && !SAID.swap(true, Ordering::Relaxed)
    {
        eprintln!("cannot write to standard output: {e}");
    }
}

/// `println!` that does not panic when the reader has gone ([`write()`](crate::stdout::write)).
#[macro_export]
macro_rules! outln {
    () => { $crate::stdout::write(format_args!(""), true) };
    ($($arg:tt)*) => { $crate::stdout::write(format_args!($($arg)*), true) };
}

/// `print!` that does not panic when the reader has gone ([`write()`](crate::stdout::write)).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => { $crate::stdout::write(format_args!($($arg)*), false) };
}
