#![no_std]
#![forbid(unsafe_code)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic))]
#![doc = include_str!("../README.md")]

#[cfg(test)]
#[macro_use]
extern crate std;

pub mod current;
pub mod discretize;
pub mod drive;
pub mod encoder;
pub mod filter;
pub mod frames;
pub mod ifoc;
pub mod link;
pub mod motor;
pub mod num;
pub mod pi;
pub mod scaling;
pub mod selftest;
pub mod speed;
pub mod svpwm;
