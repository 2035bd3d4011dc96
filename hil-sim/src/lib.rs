//! Host-side plant simulator for `controller-core` (software in the loop).
//!
//! First version: the stationary-frame induction machine ([`plant`]) and a closed-loop
//! runner ([`sim`]) with an average-value inverter and ideal sensors. Scenario files,
//! sensor/inverter options and the papers' experiments come with issue 3.
#![forbid(unsafe_code)]
// Host simulator, not the control path: fixed-size state arrays are indexed inside
// `array::from_fn` with indices bounded by the array length.
#![allow(clippy::indexing_slicing)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod closed_loop_file;
pub mod config;
pub mod inverter;
pub mod motors;
pub mod plant;
pub mod plot;
pub mod scenario;
pub mod sensors;
pub mod sim;
