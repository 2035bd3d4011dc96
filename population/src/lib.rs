//! A seeded, physical population of induction motors and inverter boards, and the judge
//! every release of the drive stack passes on it (issue 49).
//!
//! - [`laws`]: the scaling laws of real machines (per-unit circuit, inertia, thermal time
//!   constant against rated power), their anchors, and the steady state that makes a
//!   nameplate of a circuit;
//! - [`member`]: a member — a motor drawn from the laws on a board drawn for its voltage
//!   class, written as the template a user writes from its nameplate; or a shipped motor on
//!   its shipped template;
//! - [`run`]: a member through `design tune`, the tuned file's campaign and its fault
//!   matrix, judged pass / refuse / fail.
//!
//! `population --help` (the CLI) lists the members, writes their files, and runs a sample.

#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod laws;
pub mod member;
pub mod run;
pub mod saturation;
