//! Inverter models. Both return the stator voltage over one PWM period as piecewise-constant
//! αβ segments, so the plant integrates exactly the waveform the model describes.
//!
//! * [`InverterModel::Average`] (default): one segment, the period-average voltage
//!   `v_x = (d_x − 1/2)·V_dc` per phase.
//! * [`InverterModel::Switching`]: centre-aligned carrier comparison. Phase x's upper switch
//!   is commanded on during `[(1 − d_x)·T/2, (1 + d_x)·T/2]`; every turn-on is delayed by the
//!   dead time `t_d`, during which the freewheeling diode chosen by the current sign sets the
//!   phase: `i_x > 0` → lower diode → the high interval shrinks to `[t_on + t_d, t_off]`;
//!   `i_x ≤ 0` → upper diode → it grows to `[t_on, t_off + t_d]`. The current sign is taken at
//!   the start of the period. Average voltage error per phase: `−sign(i_x)·(t_d/T)·V_dc`.
//!   Duties of exactly 0 or 1 do not switch, so they have no dead time.
//!
//! Phase voltages are `±V_dc/2` against the DC midpoint; the floating star point removes the
//! common mode, which the amplitude-invariant Clarke transform discards.

use controller_core::frames::Abc;

/// Inverter model of a scenario.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum InverterModel {
    /// Period-average voltages.
    #[default]
    Average,
    /// Carrier comparison with dead time.
    Switching {
        /// Dead time, s.
        dead_time_s: f64,
    },
}

/// Up to 7 segments `(duration_s, [v_alpha, v_beta])` covering one period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Segments {
    items: [(f64, [f64; 2]); 7],
    len: usize,
}

impl Segments {
    fn push(&mut self, dt: f64, v: [f64; 2]) {
        if let Some(slot) = self.items.get_mut(self.len) {
            *slot = (dt, v);
            self.len += 1;
        }
    }

    /// The segments in time order.
    pub fn as_slice(&self) -> &[(f64, [f64; 2])] {
        self.items.get(..self.len).unwrap_or(&[])
    }

    /// Period-average αβ voltage.
    pub fn average(&self) -> [f64; 2] {
        let total: f64 = self.as_slice().iter().map(|s| s.0).sum();
        let mut v = [0.0; 2];
        for (dt, s) in self.as_slice() {
            v[0] += dt * s[0];
            v[1] += dt * s[1];
        }
        if total > 0.0 { [v[0] / total, v[1] / total] } else { v }
    }
}

/// Amplitude-invariant Clarke of phase voltages (common mode dropped): controller-core's
/// transform, in f64.
#[inline]
fn clarke([a, b, c]: [f64; 3]) -> [f64; 2] {
    let v = Abc { a, b, c }.clarke();
    [v.alpha, v.beta]
}

impl InverterModel {
    /// The period-average αβ voltage of duties `duty` on a bus of `vdc_v` volts (the
    /// [`InverterModel::Average`] model's one segment).
    #[inline]
    pub fn average_voltage(duty: [f64; 3], vdc_v: f64) -> [f64; 2] {
        // Clarke of (d − ½)·V_dc per phase: the common −½·V_dc drops out, and V_dc joins the
        // transform's constants instead of multiplying its result — one operation fewer on
        // the simulator's critical path, which runs through the duties (`clarke` then × V_dc:
        // ≈ 0.3 ns per period slower in `hil-sim bench`).
        let [a, b, c] = duty.map(|d| d.clamp(0.0, 1.0));
        let v = Abc { a, b, c }.clarke_scaled(vdc_v);
        [v.alpha, v.beta]
    }

    /// Voltage segments of one period of length `ts_s` for duties `duty` (each in [0, 1]),
    /// phase currents `i_abc_a` at the start of the period and bus voltage `vdc_v`.
    pub fn segments(&self, duty: [f64; 3], i_abc_a: [f64; 3], vdc_v: f64, ts_s: f64) -> Segments {
        let mut out = Segments::default();
        match *self {
            InverterModel::Average => {
                out.push(ts_s, Self::average_voltage(duty, vdc_v));
            }
            InverterModel::Switching { dead_time_s } => {
                // High interval of each phase.
                let high: [(f64, f64); 3] = std::array::from_fn(|x| {
                    let d = duty[x].clamp(0.0, 1.0);
                    if d <= 0.0 {
                        return (0.0, 0.0);
                    }
                    if d >= 1.0 {
                        return (0.0, ts_s);
                    }
                    let (on, off) = ((1.0 - d) * ts_s / 2.0, (1.0 + d) * ts_s / 2.0);
                    let (on, off) =
                        if i_abc_a[x] > 0.0 { (on + dead_time_s, off) } else { (on, off + dead_time_s) };
                    (on.clamp(0.0, ts_s), off.clamp(0.0, ts_s))
                });
                let mut edges = [0.0; 8];
                for (x, (on, off)) in high.iter().enumerate() {
                    edges[2 * x] = *on;
                    edges[2 * x + 1] = *off;
                }
                edges[6] = 0.0;
                edges[7] = ts_s;
                edges.sort_by(f64::total_cmp);
                for w in edges.windows(2) {
                    let (t0, t1) = (w[0], w[1]);
                    if t1 - t0 <= 0.0 {
                        continue;
                    }
                    let mid = 0.5 * (t0 + t1);
                    let v =
                        high.map(|(on, off)| if mid > on && mid < off { 0.5 * vdc_v } else { -0.5 * vdc_v });
                    out.push(t1 - t0, clarke(v));
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: f64 = 5e-5;

    fn close(a: [f64; 2], b: [f64; 2], tol: f64) -> bool {
        (a[0] - b[0]).abs() < tol && (a[1] - b[1]).abs() < tol
    }

    #[test]
    fn switching_without_dead_time_averages_to_the_average_model() {
        for duty in [[0.5, 0.5, 0.5], [0.9, 0.2, 0.4], [1.0, 0.0, 0.3], [0.01, 0.99, 0.5]] {
            let avg = InverterModel::Average.segments(duty, [0.0; 3], 310.0, T);
            let sw = InverterModel::Switching { dead_time_s: 0.0 }.segments(duty, [1.0, -1.0, 0.5], 310.0, T);
            assert!(close(sw.average(), avg.average(), 1e-9), "{duty:?}");
            let total: f64 = sw.as_slice().iter().map(|s| s.0).sum();
            assert!((total - T).abs() < 1e-15);
            // Every segment is one of the 8 switching states: |v| ∈ {0, 2V_dc/3}.
            for (_, v) in sw.as_slice() {
                let m = v[0].hypot(v[1]);
                assert!(m < 1e-9 || (m - 2.0 * 310.0 / 3.0).abs() < 1e-9, "{m}");
            }
        }
    }

    #[test]
    fn dead_time_error_is_sign_of_current_times_td_over_t() {
        let td = 1e-6;
        let duty = [0.7, 0.4, 0.55];
        let i = [2.0, -1.5, -0.5];
        let sw = InverterModel::Switching { dead_time_s: td }.segments(duty, i, 310.0, T);
        let expected =
            clarke(std::array::from_fn(|x| (duty[x] - 0.5) * 310.0 - i[x].signum() * td / T * 310.0));
        assert!(close(sw.average(), expected, 1e-9), "{:?} vs {expected:?}", sw.average());
    }
}
