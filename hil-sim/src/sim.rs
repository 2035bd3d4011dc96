//! Software-in-the-loop: a `controller-core` [`Drive`] against the [`Machine`] plant.
//!
//! Timing, as on the board: at the start of PWM period k the currents are sampled, the
//! drive computes duties, and those duties are applied during period k+1 (one period of
//! computation delay). Inverter: average-value model — phase-to-midpoint voltage
//! `(d − 1/2)·V_dc`, common mode removed by the Clarke transform (floating star point).
//! Sensors are ideal in this first version (no quantisation, exact speed and angle).

use crate::plant::{Machine, MachineState};
use controller_core::drive::{Drive, Measurements, PhaseCommand, Reference};
use controller_core::frames::Abc;

/// A time-stamped event of a scenario.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// Enable the drive.
    Enable,
    /// New outer-loop reference.
    Reference(Reference),
    /// New load torque, N·m.
    LoadNm(f64),
}

/// A closed-loop run.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Events `(t_s, event)`, in time order.
    pub events: Vec<(f64, Event)>,
    /// Simulated time, s.
    pub duration_s: f64,
    /// DC-bus voltage, V.
    pub vdc_v: f64,
    /// RK4 sub-steps per PWM period.
    pub substeps: u32,
    /// Trace decimation: one row every `trace_every` PWM periods.
    pub trace_every: u32,
}

/// One trace row.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Row {
    /// Time, s.
    pub t_s: f64,
    /// Plant state.
    pub x: MachineState,
    /// Electromagnetic torque, N·m.
    pub torque_nm: f64,
    /// Applied stator voltage, V.
    pub v_ab_v: [f64; 2],
    /// Current references, A.
    pub i_ref_ab_a: [f64; 2],
    /// Speed reference, rad/s.
    pub omega_ref_rad_s: f64,
    /// Load torque, N·m.
    pub load_nm: f64,
}

/// Run `scenario` with `drive` (already configured) on `machine`; `pwm_hz` is the drive's
/// fast rate. Calls `progress(fraction)` now and then.
pub fn run(
    drive: &mut Drive,
    machine: &Machine,
    pwm_hz: f64,
    sc: &Scenario,
    mut progress: impl FnMut(f64),
) -> Vec<Row> {
    let ts = 1.0 / pwm_hz;
    let h = ts / f64::from(sc.substeps.max(1));
    let n = (sc.duration_s / ts).round() as u64;
    let mut x = MachineState::default();
    let mut load = 0.0;
    let mut applied = [0.0f64; 2]; // voltage applied during the present period
    let mut events = sc.events.iter().peekable();
    let mut rows = Vec::with_capacity((n / u64::from(sc.trace_every.max(1)) + 1) as usize);
    for k in 0..n {
        let t = k as f64 * ts;
        while let Some((_, e)) = events.next_if(|(te, _)| *te <= t) {
            match *e {
                Event::Enable => {
                    let _ = drive.enable();
                }
                Event::Reference(r) => {
                    let _ = drive.set_reference(r);
                }
                Event::LoadNm(l) => load = l,
            }
        }
        let i_abc = controller_core::frames::AlphaBeta { alpha: x.i_alpha_a as f32, beta: x.i_beta_a as f32 }
            .inverse_clarke();
        let m = Measurements {
            i_abc_a: i_abc,
            vdc_v: sc.vdc_v as f32,
            omega_m_rad_s: x.omega_m_rad_s as f32,
            theta_m_rad: x.theta_m_rad as f32,
        };
        let out = drive.step(&m);
        if k % u64::from(sc.trace_every.max(1)) == 0 {
            rows.push(Row {
                t_s: t,
                x,
                torque_nm: machine.torque_nm(&x),
                v_ab_v: applied,
                i_ref_ab_a: [
                    f64::from(out.telemetry.i_ref_ab_a.alpha),
                    f64::from(out.telemetry.i_ref_ab_a.beta),
                ],
                omega_ref_rad_s: f64::from(out.telemetry.omega_ref_rad_s),
                load_nm: load,
            });
        }
        for _ in 0..sc.substeps.max(1) {
            x = machine.rk4(&x, applied, load, h);
        }
        // Duties computed now act during the next period.
        applied = match out.phases {
            PhaseCommand::Off => [0.0, 0.0], // simplification: bridge off ≈ zero voltage
            PhaseCommand::Duty(d) => {
                let v = Abc {
                    a: (d.a - 0.5) * sc.vdc_v as f32,
                    b: (d.b - 0.5) * sc.vdc_v as f32,
                    c: (d.c - 0.5) * sc.vdc_v as f32,
                }
                .clarke();
                [f64::from(v.alpha), f64::from(v.beta)]
            }
        };
        if k % 2000 == 0 {
            progress(k as f64 / n as f64);
        }
    }
    progress(1.0);
    rows
}
