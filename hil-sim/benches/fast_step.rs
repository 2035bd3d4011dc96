//! Host cost of one drive step (criterion). The figure quoted in docs/performance.md comes from
//! `cargo bench -p hil-sim --bench fast_step`.
//!
//! * `drive_step_running`: `Drive::step` in Running (supervisor, Clarke, IFOC with
//!   sincos, two ICAD channels, SVPWM; the slow step every 10th call).
//! * `icad_axis`: one ICAD channel (lag biquad + PI) alone.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use controller_core::current::{CurrentAxisState, CurrentControllerConfig, CurrentLaw};
use controller_core::discretize::Discretization;
use controller_core::drive::{Drive, DriveConfig, Measurements, Mode, PhaseCommand, Reference};
use controller_core::frames::Abc;
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn running_drive() -> Drive {
    let mut d = Drive::new(DriveConfig::new(&drive_file::DriveFile::shipped().unwrap().spec).unwrap());
    d.set_reference(Reference::Speed(100.0)).unwrap();
    d.enable().unwrap();
    // R-L load until the flux model says magnetized.
    let (r, l, ts, vdc) = (16.2f32, 0.1f32, 5e-5f32, 310.0f32);
    let mut i = Abc::default();
    let a = (-r / l * ts).exp();
    for _ in 0..100_000 {
        if d.mode() == Mode::Running {
            return d;
        }
        if let PhaseCommand::Duty(duty) =
            d.step(&Measurements { i_abc_a: i, vdc_v: vdc, ..Default::default() }).phases
        {
            let v = Abc { a: (duty.a - 0.5) * vdc, b: (duty.b - 0.5) * vdc, c: (duty.c - 0.5) * vdc };
            let v0 = (v.a + v.b + v.c) / 3.0;
            let f = |i: f32, v: f32| a * i + (1.0 - a) * (v - v0) / r;
            i = Abc { a: f(i.a, v.a), b: f(i.b, v.b), c: f(i.c, v.c) };
        }
    }
    panic!("drive did not reach Running");
}

fn bench(c: &mut Criterion) {
    let mut d = running_drive();
    let mut k = 0u32;
    c.bench_function("drive_step_running", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let x = (k % 1000) as f32 * 1e-3;
            let m = Measurements {
                i_abc_a: Abc { a: 0.6 * x, b: -0.3 * x, c: -0.3 * x },
                vdc_v: 310.0,
                omega_m_rad_s: 100.0,
                theta_m_rad: x,
            };
            black_box(d.step(black_box(&m)))
        })
    });
    let cfg =
        CurrentControllerConfig::<f32>::new(&CurrentLaw::ICAD_EQ20, 5e-5, Discretization::Tustin, 200.0)
            .unwrap();
    let mut s = CurrentAxisState::default();
    c.bench_function("icad_axis", |b| b.iter(|| black_box(cfg.update_axis(&mut s, black_box(0.01), 179.0))));
}

criterion_group!(benches, bench);
criterion_main!(benches);
