//! Outputs of the host tools (`hil-sim`, `design`): [`plot`] draws SVG line plots,
//! [`write`](mod@write) writes files that appear complete or not at all, [`stdout`] prints
//! without panicking when the reader has gone.
#![forbid(unsafe_code)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing))]

pub mod plot;
pub mod stdout;
pub mod write;
