//! Robust design toolkit (host): polynomials and transfer functions, Kharitonov
//! robust-stability analysis of PI loops (seed 000), interval-polynomial conditions
//! (seed 001) and ICAD analysis (seed 002), and the certification of a drive file. It
//! shares the machine model (`plant`), the drive file (`drive-file`) and the output writers
//! (`report`) with the simulator, not the simulator itself: it needs linear algebra and
//! optimisation the simulator does not.
#![forbid(unsafe_code)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]
// Host analysis code: dense matrices are indexed within their dimensions.
#![allow(clippy::indexing_slicing)]

pub mod certify;
pub mod eig;
pub mod icad;
pub mod im;
pub mod kharitonov;
pub mod margins;
pub mod nyquist;
pub mod observer;
pub mod pi_region;
pub mod poly;
pub mod recycle;
pub mod sampled;
pub mod startup_fit;
#[cfg(test)]
mod testutil;
pub mod tf;
pub mod tune;
