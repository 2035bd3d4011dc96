//! STM32G474 drive firmware: the hardware-independent part, tested on the host.
//!
//! * [`control`]: the control interrupt's body — ADC codes and encoder counter in, compare
//!   values out — around `controller_core::drive::Drive`;
//! * [`interrupt`]: the control interrupt's body once its samples are read — the output
//!   stage around the control step, the link's requests that are its — and the drive's
//!   slow context's part of the link (the drive's commands, the snapshot): what they share
//!   with the link task;
//! * [`scope`]: the capture between the control interrupt (which records) and the link
//!   task (which arms it and reads it out);
//! * [`output`]: the output stage — MOE, the break flag and the compare registers behind a
//!   trait, host-tested against a model of the timer's break logic;
//! * [`server`]: the command/telemetry link's command handling;
//! * [`boundary`]: the lock-free hand-overs between the control interrupt, the slow context
//!   and the link task;
//! * [`safety`]: the microcontroller's own failures (lockup, SRAM parity, supply, flash
//!   ECC) linked to the bridge's break — the words written at start-up and their check;
//! * [`stack`]: the main stack's high-water mark, read from cortex-m-rt's paint;
//! * [`masking`]: the board's critical section — BASEPRI, which never masks the control
//!   interrupt (PRIMASK's did);
//! * [`config`]: the drive and board constants, generated from `drive.toml` at build time —
//!   the pin map is in `main.rs`'s `pins` module, next to the peripherals it names.
//!
//! The binary (`main.rs`) wires these to embassy-stm32: TIM1 PWM, ADC1 injected
//! conversions triggered by TIM1, TIM4 encoder, LPUART1 link, independent watchdog.
#![no_std]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing))]

pub mod boundary;
pub mod config;
pub mod control;
pub mod interrupt;
pub mod masking;
pub mod output;
pub mod safety;
pub mod scope;
pub mod server;
pub mod stack;
