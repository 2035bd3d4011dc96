//! Host cost of one plant step (criterion), the other half of a simulated PWM period next
//! to `Drive::step` (`cargo bench -p hil-sim --bench fast_step`). The figure quoted
//! in docs/performance.md comes from `cargo bench -p plant --bench plant_step`.
//!
//! * `rk4_step_chained`: one RK4 step ([`plant::Rk4::step`], as the simulator
//!   takes it) of the DeLorenzo machine at 50 µs, each step starting
//!   from the previous one's result (as in a run: the step's latency).
//! * `rk4_step_independent`: the same step from a fixed state (its throughput).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use controller_core::motor::MotorParams;
use criterion::{Criterion, criterion_group, criterion_main};
use plant::{Machine, MachineState};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let m = Machine::new(&MotorParams::delorenzo_dl10115a1().unwrap()).rk4_stepper(5e-5);
    let start = MachineState { psi_alpha_wb: 0.9, omega_m_rad_s: 100.0, ..Default::default() };
    let v = [120.0, 40.0];
    let mut x = start;
    c.bench_function("rk4_step_chained", |b| {
        b.iter(|| {
            x = m.step(&x, black_box(v), 0.5);
        })
    });
    black_box(x);
    c.bench_function("rk4_step_independent", |b| b.iter(|| m.step(black_box(&start), black_box(v), 0.5)));
}

criterion_group!(benches, bench);
criterion_main!(benches);
