//! The inverter's legs within a PWM period, where a fault needs finer time than the plant's
//! step: a short between two motor terminals, and the power board's hardware overcurrent
//! comparator (what the timer's break input BKIN sees).
//!
//! **Leg currents.** The current sensors (low-side shunts) and the comparator measure the
//! currents in the inverter's legs. Healthy, they are the motor's phase currents. A short
//! between terminals p and q (resistance R, inductance L: the cable, the connector) adds a
//! current i_s out of leg p into leg q: `L di_s/dt = v_p − v_q − R i_s` while the bridge
//! drives them; the motor, fed by the stiff legs, is not affected. Once the bridge is off the
//! short's current freewheels through the diodes against the bus and dies (`L di_s/dt =
//! −V_dc·sign(i_s) − R i_s`); what the short then does to a spinning motor (a braking current
//! from its back-EMF through the two shorted phases) is not modelled.
//!
//! **A switch shorted** (failed conducting: a punched-through transistor) shoots the bus
//! through its leg whenever the leg's healthy switch turns on — with the upper switch
//! shorted, while the low side conducts (around the top of the count, where the period
//! starts and ends), with the lower one shorted, while the high side does (its middle):
//! `L di/dt = V_dc − R i` through the leg's loop (the DC-link capacitor, the two switches,
//! the low-side shunt), and when the healthy switch turns off — or the bridge does — the
//! loop's current dies through the diodes against the bus. The low-side shunt carries it
//! downwards (a negative phase-current reading), the comparator its magnitude; the motor's
//! terminals are not affected. What the shorted switch does to a spinning motor once the
//! bridge is off (a braking current through it and the other legs' diodes) is not
//! modelled, like the short's.
//!
//! **Comparator.** Each leg current's magnitude through a first-order filter of time
//! constant `filter_s` (the board's RC and the comparator's delay); above `trip_a` the
//! timer's break clears MOE at once — the bridge is off from that instant, within the
//! period — and latches until the drive is reset (the drive is told: `Fault::HardwareBreak`).
//!
//! Both are resolved in [`SUBSTEPS`] steps per PWM period (1 µs at 20 kHz); the motor's
//! currents are interpolated linearly across the period. A trip within a period leaves the
//! motor its whole period's voltage (the plant has already taken its step): an error of
//! less than one period in the motor's currents, none in the leg's.

/// Sub-steps per PWM period.
pub const SUBSTEPS: u32 = 50;

/// The power board's hardware overcurrent comparator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Comparator {
    /// Trip level of the filtered |leg current|, A.
    pub trip_a: f64,
    /// Filter time constant, s.
    pub filter_s: f64,
}

/// A short between two motor terminals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseShort {
    /// The two phases (0 = a), different.
    pub phases: [usize; 2],
    /// Resistance of the short, Ω.
    pub resistance_ohm: f64,
    /// Inductance of the short's loop, H (> 0).
    pub inductance_h: f64,
}

/// A switch shorted for good: the shoot-through loop through its leg.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwitchShort {
    /// Phase index 0…2.
    pub phase: usize,
    /// The upper switch (else the lower one).
    pub upper: bool,
    /// Resistance of the leg's loop, Ω.
    pub resistance_ohm: f64,
    /// Inductance of the leg's loop (DC-link capacitor, switches, shunt), H (> 0).
    pub inductance_h: f64,
}

/// The legs' state across periods.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Legs {
    /// The short, if one is injected, and its current (out of the first phase's leg).
    pub short: Option<(PhaseShort, f64)>,
    /// The shorted switch, if one is injected, and its leg's shoot-through current (≥ 0,
    /// from the positive rail to the negative one).
    pub shoot: Option<(SwitchShort, f64)>,
    /// The comparator's filtered |leg current| per phase, A.
    pub filtered_a: [f64; 3],
    /// The comparator has tripped: MOE cleared, the bridge off until reset.
    pub broken: bool,
}

/// What one period did to the legs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LegPeriod {
    /// Largest |leg current| in the period, A.
    pub peak_a: f64,
    /// The comparator tripped in this period.
    pub tripped: bool,
}

impl Legs {
    /// The leg currents for motor phase currents `motor` (at the sampling instant).
    pub fn currents(&self, motor: [f64; 3]) -> [f64; 3] {
        let mut leg = motor;
        if let Some((s, i)) = self.short {
            let [p, q] = s.phases;
            leg[p] += i;
            leg[q] -= i;
        }
        if let Some((s, i)) = self.shoot
            && let Some(x) = leg.get_mut(s.phase)
        {
            // Downwards through the low-side shunt: a negative phase-current reading.
            *x -= i;
        }
        leg
    }

    /// One PWM period of `ts_s`: the motor's currents go from `start` to `end`; the legs'
    /// pole voltages (`None`: bridge off) on a bus of `vdc_v`.
    pub fn period(
        &mut self,
        comparator: Option<&Comparator>,
        start: [f64; 3],
        end: [f64; 3],
        pole_v: Option<[f64; 3]>,
        vdc_v: f64,
        ts_s: f64,
    ) -> LegPeriod {
        let mut out = LegPeriod::default();
        if self.short.is_none() && self.shoot.is_none() {
            // The legs carry the motor's currents, smooth across the period: their largest
            // magnitude is at an end, and the filter (a time constant of microseconds) has
            // followed it there.
            if let Some(c) = comparator {
                for (f, (a, b)) in self.filtered_a.iter_mut().zip(start.iter().zip(end)) {
                    out.peak_a = out.peak_a.max(a.abs()).max(b.abs());
                    *f = b.abs();
                }
                if out.peak_a > c.trip_a && !self.broken {
                    self.broken = true;
                    out.tripped = true;
                }
            }
            return out;
        }
        let dt = ts_s / f64::from(SUBSTEPS);
        let keep = comparator.map_or(0.0, |c| (-dt / c.filter_s).exp());
        let mut driven = pole_v.filter(|_| !self.broken);
        for j in 1..=SUBSTEPS {
            if let Some((s, i)) = &mut self.short {
                let [p, q] = s.phases;
                let (r, l) = (s.resistance_ohm, s.inductance_h);
                match driven {
                    Some(v) => {
                        // Exact for the constant pole voltages of the average inverter.
                        let u = v[p] - v[q];
                        if r > 0.0 {
                            let i_ss = u / r;
                            *i = i_ss + (*i - i_ss) * (-dt * r / l).exp();
                        } else {
                            *i += u / l * dt;
                        }
                    }
                    None => {
                        // Freewheeling through the diodes against the bus, to zero.
                        let di = (vdc_v + r * i.abs()) / l * dt;
                        *i = if i.abs() <= di { 0.0 } else { *i - di * i.signum() };
                    }
                }
            }
            let w = f64::from(j) / f64::from(SUBSTEPS);
            if let Some((s, i)) = &mut self.shoot {
                let (r, l) = (s.resistance_ohm, s.inductance_h);
                // The healthy switch conducts in this sub-step (its middle): the low side
                // for the first and last (1 − d)/2 of the period (it starts at the top of
                // the count), the high side for the d between.
                let mid = w - 0.5 / f64::from(SUBSTEPS);
                let healthy_on = driven.and_then(|v| v.get(s.phase).copied()).is_some_and(|v| {
                    let d = (v / vdc_v + 0.5).clamp(0.0, 1.0);
                    let low_on = mid < 0.5 * (1.0 - d) || mid > 0.5 * (1.0 + d);
                    if s.upper { low_on } else { !low_on }
                });
                if healthy_on {
                    let i_ss = if r > 0.0 { vdc_v / r } else { f64::INFINITY };
                    *i = if r > 0.0 { i_ss + (*i - i_ss) * (-dt * r / l).exp() } else { *i + vdc_v / l * dt };
                } else {
                    // Through the diodes against the bus, to zero.
                    let di = (vdc_v + r * *i) / l * dt;
                    *i = if *i <= di { 0.0 } else { *i - di };
                }
            }
            let motor: [f64; 3] = std::array::from_fn(|k| start[k] + (end[k] - start[k]) * w);
            let leg = self.currents(motor);
            for (k, x) in leg.iter().enumerate() {
                out.peak_a = out.peak_a.max(x.abs());
                if let Some(c) = comparator {
                    let f = &mut self.filtered_a[k];
                    *f = x.abs() + (*f - x.abs()) * keep;
                    if *f > c.trip_a && !self.broken {
                        self.broken = true;
                        out.tripped = true;
                        driven = None;
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A short on a 310 V difference through 20 µH rises at 15.5 A/µs; a comparator at 12 A
    /// with a 1 µs filter trips ≈ 0.8 µs after the crossing plus the filter's delay, within
    /// the period, and the short's current then dies through the diodes.
    #[test]
    fn a_short_trips_the_comparator_within_its_filter_time() {
        let c = Comparator { trip_a: 12.0, filter_s: 1e-6 };
        let s = PhaseShort { phases: [0, 1], resistance_ohm: 0.05, inductance_h: 20e-6 };
        let mut legs = Legs { short: Some((s, 0.0)), ..Legs::default() };
        let p = legs.period(Some(&c), [0.0; 3], [0.0; 3], Some([155.0, -155.0, 0.0]), 310.0, 50e-6);
        assert!(p.tripped && legs.broken);
        // The leg current crosses 12 A at 0.77 µs and the filter follows a ramp one time
        // constant late: the trip near 1.8 µs, the peak ≈ 28 A (1 µs steps).
        assert!(p.peak_a > 12.0 && p.peak_a < 40.0, "{}", p.peak_a);
        assert_eq!(legs.short.map(|(_, i)| i), Some(0.0), "freewheeled to zero within the period");
        // Latched: the next period is not driven.
        let p = legs.period(Some(&c), [0.0; 3], [0.0; 3], Some([155.0, -155.0, 0.0]), 310.0, 50e-6);
        assert!(!p.tripped && p.peak_a == 0.0);
    }

    /// An upper switch shorted: the low side's conduction from the period's start shoots
    /// the 310 V bus through 20 µH at 15.5 A/µs, and the comparator trips within its filter
    /// time; a lower switch shorted waits for the high side's turn (at duty 0.5, a quarter
    /// of the period in). Both then die through the diodes, and the motor is untouched.
    #[test]
    fn a_shorted_switch_shoots_through_when_its_partner_turns_on() {
        let c = Comparator { trip_a: 12.0, filter_s: 1e-6 };
        for upper in [true, false] {
            let s = SwitchShort { phase: 1, upper, resistance_ohm: 0.05, inductance_h: 20e-6 };
            let mut legs = Legs { shoot: Some((s, 0.0)), ..Legs::default() };
            let motor = [1.0, -0.5, -0.5];
            let p = legs.period(Some(&c), motor, motor, Some([0.0; 3]), 310.0, 50e-6);
            assert!(p.tripped && legs.broken, "upper {upper}");
            assert!(p.peak_a > 12.0 && p.peak_a < 40.0, "{}", p.peak_a);
            assert_eq!(legs.shoot.map(|(_, i)| i), Some(0.0));
            assert_eq!(legs.currents(motor), motor, "the motor's currents");
        }
        // Without a comparator the loop's current grows while the partner conducts, and the
        // low-side shunt reads it (negative) at the next sample: the software's overcurrent.
        let s = SwitchShort { phase: 0, upper: true, resistance_ohm: 0.05, inductance_h: 20e-6 };
        let mut legs = Legs { shoot: Some((s, 0.0)), ..Legs::default() };
        let _ = legs.period(None, [0.0; 3], [0.0; 3], Some([0.0; 3]), 310.0, 50e-6);
        assert!(legs.currents([0.0; 3])[0] < -100.0, "{:?}", legs.currents([0.0; 3]));
    }

    /// Without a fault the legs carry the motor's currents, and a comparator above them does
    /// not trip.
    #[test]
    fn healthy_legs_are_the_motor_currents() {
        let c = Comparator { trip_a: 12.0, filter_s: 1e-6 };
        let mut legs = Legs::default();
        let p = legs.period(Some(&c), [1.0, -0.5, -0.5], [2.0, -1.0, -1.0], Some([0.0; 3]), 310.0, 50e-6);
        assert!(!p.tripped);
        assert!((p.peak_a - 2.0).abs() < 1e-12);
        assert_eq!(legs.currents([1.0, 2.0, -3.0]), [1.0, 2.0, -3.0]);
    }
}
