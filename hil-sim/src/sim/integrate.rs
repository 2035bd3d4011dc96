//! The plant over one PWM period where the average inverter's RK4 step does not do: a
//! switching inverter's voltage segments, and the bridge with all six switches off (the
//! freewheeling diodes); and the RK4 step's stability on the machines a run meets.

use super::{Event, Injection, Scenario};
use crate::inverter::Segments;
use controller_core::frames::{Abc, AlphaBeta};
use plant::{Machine, MachineState};

/// RK4 steps per PWM period while the bridge is off (10 µs at 20 kHz): the diodes stop
/// conducting at a current zero, which the step locates to within one step.
pub const BRIDGE_OFF_SUBSTEPS: u32 = 5;

/// The phase axes a, b, c in the αβ plane, scaled so that the projection of the current
/// vector on an axis is that phase's current (amplitude-invariant Clarke).
pub(super) const PHASE_AXES: [(f64, f64); 3] =
    [(1.0, 0.0), (-0.5, 0.866_025_403_784_438_6), (-0.5, -0.866_025_403_784_438_6)];

/// A phase current below this is zero: its diodes block, A.
const DIODE_ZERO_A: f64 = 1e-9;

/// The bridge with all six switches off, over one period: the freewheeling diodes, in
/// [`BRIDGE_OFF_SUBSTEPS`] RK4 steps. A phase whose current flows out of the bridge
/// (`i_x > 0`) conducts through its lower diode and sits at `−V_dc/2`; one flowing in,
/// through its upper diode, at `+V_dc/2`. Driven by the bus, the currents die out — within
/// about a millisecond on the DeLorenzo motor — and a phase whose current reaches zero opens
/// (its diodes block): its current is held at zero by projecting the current vector off that
/// phase's axis after each step (all three, when two are open: the currents sum to zero).
///
/// An open phase's terminal follows the machine: with `e` the open-circuit back-EMF of the
/// rotor flux per phase ([`Machine::open_circuit_voltage`]), all three open sit at `e`; with
/// two conducting at ±V_dc/2, the open one at `1.5·e_x` (its current and its derivative zero,
/// the star point between). When that exceeds the bus, diodes conduct again — the motor
/// *regenerates* into the bus while its line back-EMF is above V_dc: from all open, the pair
/// of phases with the largest line EMF, once it exceeds V_dc; with two conducting, the third
/// once `|1.5·e_x|` exceeds V_dc/2 (test `a_trip_above_the_bus_regenerates_until_the_emf_is_down`).
/// Returns the state and the period-average αβ voltage.
pub(super) fn integrate_bridge_off(
    machine: &Machine,
    rk4: &plant::Rk4,
    x: &MachineState,
    vdc_v: f64,
    load_nm: f64,
) -> (MachineState, [f64; 2]) {
    let phase = |x: &MachineState, (ux, uy): (f64, f64)| x.i_alpha_a * ux + x.i_beta_a * uy;
    let half = 0.5 * vdc_v;
    let mut x = *x;
    let mut v_sum = [0.0; 2];
    for _ in 0..BRIDGE_OFF_SUBSTEPS {
        let before = PHASE_AXES.map(|u| phase(&x, u));
        // Each phase's diode: +1 upper (at +V_dc/2, current into the bridge), −1 lower, 0 open.
        let mut diode = before.map(|i| if i.abs() < DIODE_ZERO_A { 0.0 } else { -i.signum() });
        let e = {
            let [a, b] = machine.open_circuit_voltage(&x);
            let e = AlphaBeta { alpha: a, beta: b }.inverse_clarke();
            [e.a, e.b, e.c]
        };
        let conducting = |d: &[f64; 3]| d.iter().filter(|d| **d != 0.0).count();
        match conducting(&diode) {
            0 => {
                let hi = (0..3).fold(0, |m, p| if e[p] > e[m] { p } else { m });
                let lo = (0..3).fold(0, |m, p| if e[p] < e[m] { p } else { m });
                if e[hi] - e[lo] > vdc_v {
                    (diode[hi], diode[lo]) = (1.0, -1.0);
                }
            }
            2 => {
                let open = diode.iter().position(|d| *d == 0.0).unwrap_or(0);
                if (1.5 * e[open]).abs() > half {
                    diode[open] = e[open].signum();
                }
            }
            _ => {}
        }
        let two = conducting(&diode) == 2;
        let v_abc: [f64; 3] = std::array::from_fn(|p| match diode[p] {
            0.0 if two => 1.5 * e[p],
            0.0 => e[p],
            d => d * half,
        });
        let [a, b, c] = v_abc;
        let v = Abc { a, b, c }.clarke();
        let v = [v.alpha, v.beta];
        x = rk4.step(&x, v, load_nm);
        v_sum[0] += v[0];
        v_sum[1] += v[1];
        // Open: its diodes block (no diode chosen), or its current ended the step at or past
        // zero, against its diode's direction.
        let open = [0, 1, 2].map(|p| diode[p] == 0.0 || phase(&x, PHASE_AXES[p]) * diode[p] >= 0.0);
        match open.iter().filter(|o| **o).count() {
            0 => {}
            1 => {
                let p = open.iter().position(|o| *o).unwrap_or(0);
                let (ux, uy) = PHASE_AXES[p];
                let along = phase(&x, PHASE_AXES[p]);
                x.i_alpha_a -= along * ux;
                x.i_beta_a -= along * uy;
            }
            _ => {
                x.i_alpha_a = 0.0;
                x.i_beta_a = 0.0;
            }
        }
    }
    let n = f64::from(BRIDGE_OFF_SUBSTEPS);
    (x, [v_sum[0] / n, v_sum[1] / n])
}

/// The plant over the voltage segments of one switching period, each in equal RK4 steps of
/// at most `h_max_s`. Kept out of [`run`]: inlined there, it slowed the average-inverter
/// loop by ≈ 3 ns per period (`hil-sim bench`).
#[inline(never)]
pub(super) fn integrate_segments(
    machine: &Machine,
    x: &MachineState,
    segments: &Segments,
    h_max_s: f64,
    load_nm: f64,
) -> MachineState {
    let mut x = *x;
    for &(dt, v) in segments.as_slice() {
        let n_sub = (dt / h_max_s).ceil().max(1.0);
        let rk4 = machine.rk4_stepper(dt / n_sub);
        for _ in 0..n_sub as u32 {
            x = rk4.step(&x, v, load_nm);
        }
    }
    x
}

/// The largest `rate·h` a run's RK4 step may take ([`plant::Machine::fastest_rate_per_s`]):
/// below RK4's 2.785 on the negative real axis, with a margin.
pub const RK4_RATE_STEP_MAX: f64 = 2.5;

/// The RK4 step `h` is stable on the scenario's machine, and on every machine a parameter
/// step injects. A stiffer machine diverged — or, worse, oscillated into a fault the motor
/// never had: R_s = 10 kΩ (which the motor file accepts) ran on 50 µs steps into
/// `Overcurrent` at 813 A with exit 0 (found by trying).
pub(super) fn check_rk4_step(machine: &Machine, sc: &Scenario, h: f64) -> Result<(), String> {
    let mut rate = machine.fastest_rate_per_s();
    for (_, e) in &sc.events {
        if let Event::Fault(Injection::Plant { motor }) = e {
            let injected = machine.with_electrical(motor).map_err(|e| format!("a plant step: {e}"))?;
            rate = rate.max(injected.fastest_rate_per_s());
        }
    }
    if rate.is_finite() && rate * h <= RK4_RATE_STEP_MAX {
        return Ok(());
    }
    let needed = (rate * h * f64::from(sc.substeps.max(1)) / RK4_RATE_STEP_MAX).ceil();
    Err(format!(
        "the simulated machine is too stiff for the integration step: its fastest electrical mode decays at \
         {rate:.4e} 1/s, and the RK4 step of {h:.3e} s makes rate·step = {:.2} (stable below {RK4_RATE_STEP_MAX}); \
         set rk4_substeps = {needed} or more in the scenario, or check {}",
        rate * h,
        super::stiffness_culprits(machine)
    ))
}
