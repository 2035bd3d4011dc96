//! Host cost of one plant step (criterion), the other half of a simulated PWM period next
//! to `Drive::step` (`cargo bench -p hil-sim --bench fast_step`). The figure quoted
//! in docs/performance.md comes from `cargo bench -p plant --bench plant_step`.
//!
//! * `rk4_step_chained`: one RK4 step ([`plant::Rk4::step`], as the simulator
//!   takes it) of the DeLorenzo machine at 50 µs, each step starting
//!   from the previous one's result (as in a run: the step's latency).
//! * `rk4_step_independent`: the same step from a fixed state (its throughput).
//! * `rk4_step_saturated_2kw_chained`: one step of motulator's 2.2-kW machine with main-flux
//!   saturation (Γ form, `L = 0.34/(1 + (0.84·ψ)^7)`, `plant::saturated`) at 50 µs, at
//!   rated flux and speed, chained; `rk4_step_linear_2kw_chained` the same machine linear
//!   (its T model at the unsaturated inductance), for the ratio.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use controller_core::magnetics::{Form, MagnetizingCurve, Saturation};
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

    let t = MotorParams::new(3.7, 2.5, 0.34, 0.363, 0.34, 2, 0.015, 0.0).unwrap();
    let curve = MagnetizingCurve::law(0.34, 0.84, 7.0).unwrap();
    let saturated =
        Machine::saturated(&t, &Saturation { form: Form::Gamma, curve }).unwrap().rk4_stepper(5e-5);
    let linear = Machine::new(&t).rk4_stepper(5e-5);
    // 400 V 50 Hz, one voltage per 50 µs step (a period of 400 steps); each machine first
    // runs 1 s on it against 14.6 N·m, to its rated operating point (the saturated one at
    // ≈ 1 Wb, past the knee's bend), and is timed there.
    let amp = 2f64.sqrt() * 400.0 / 3f64.sqrt();
    let v: Vec<[f64; 2]> = (0..400)
        .map(|k| {
            let th = 2.0 * std::f64::consts::PI * k as f64 / 400.0;
            [amp * th.cos(), amp * th.sin()]
        })
        .collect();
    for (name, m) in [("rk4_step_saturated_2kw_chained", saturated), ("rk4_step_linear_2kw_chained", linear)]
    {
        let mut x = MachineState::default();
        let mut source = v.iter().copied().cycle();
        for v in source.by_ref().take(20_000) {
            x = m.step(&x, v, 14.6);
        }
        c.bench_function(name, |b| {
            b.iter(|| {
                x = m.step(&x, black_box(source.next().unwrap_or_default()), 14.6);
            })
        });
        black_box(x);
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
