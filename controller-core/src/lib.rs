#![no_std]
// One `unsafe` block in the crate: the FPU's square root (`num::sqrt_f32`), allowed there.
#![deny(unsafe_code)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic))]
#![doc = include_str!("../README.md")]

#[cfg(test)]
#[macro_use]
extern crate std;

pub mod calibration;
pub mod capture;
pub mod commission;
pub mod current;
pub mod discretize;
pub mod drive;
pub mod encoder;
pub mod envelope;
pub mod fault;
pub mod filter;
pub mod frames;
pub mod ifoc;
pub mod io;
pub mod link;
pub mod magnetics;
pub mod motor;
pub mod mras;
pub mod num;
pub mod observer;
pub mod pi;
pub mod raw;
pub mod scaling;
pub mod selftest;
pub mod speed;
pub mod speed_search;
pub mod supervisor;
pub mod svpwm;
pub mod vhz;
