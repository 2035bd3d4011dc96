//! Host-side plant simulator for `controller-core` (software in the loop).
//!
//! * the plant: the `plant` crate (the stationary-frame induction machine, seed 002
//!   eqs. (1)–(2), RK4), shared with `design`;
//! * [`sim`]: the closed-loop runner (one PWM period of computation delay) and the
//!   open-loop voltage-source runner; [`inverter`] (average or switching with dead time),
//!   [`sensors`] (ADC, bus, encoder), loads;
//! * [`link_client`]: the host end of the command/telemetry link (PIL FIFOs, board UART);
//! * [`pil`]: the same runs with the drive on an emulated Cortex-M4F (QEMU), lockstep;
//! * [`campaign`]: the nonlinear campaign over a parameter box; [`faults`]: the
//!   fault-injection matrix; [`identify`]: self-commissioning (the core's sequence against
//!   the simulated motor, in process or on QEMU) and the motor's estimation;
//! * [`scenario`]: the papers' experiments as built-ins, on the shipped drive file;
//!   [`scenario_file`]: scenario files (a drive file plus a run); plots and
//!   file writing: the `report` crate;
//! * [`trace`]: the trace of a run (`trace.csv`: its columns and units, the streaming
//!   writer, the output directory, the plots and the summary);
//! * [`commands`]: the bodies of the `hil-sim` commands, each taking plain options (the
//!   binary, `src/main.rs`, only parses the command line and calls them).
#![forbid(unsafe_code)]
// Host simulator, not the control path: fixed-size state arrays are indexed inside
// `array::from_fn` with indices bounded by the array length.
#![allow(clippy::indexing_slicing)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod bridge_fault;
pub mod campaign;
pub mod capture;
pub mod commands;
pub mod envelope;
pub mod faults;
pub mod identify;
pub mod inverter;
pub mod link_client;
pub mod pil;
pub mod requirements;
pub mod rng;
pub mod scenario;
pub mod scenario_file;
pub mod sensors;
pub mod sim;
pub mod trace;
