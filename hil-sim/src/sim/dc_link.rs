//! The DC link: the bus capacitor between the source (a supply or a diode rectifier) and
//! the inverter, with an optional brake chopper, solved once per PWM period.

/// The DC link: a capacitor between the source and the inverter, with an optional brake
/// chopper. Without one ([`Scenario::dc_link`](super::Scenario::dc_link) = `None`) the bus is stiff.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DcLink {
    /// Link capacitance, F.
    pub capacitance_f: f64,
    /// What feeds it (its open-circuit voltage is the scenario's `vdc_v`).
    pub source: DcSource,
    /// Internal resistance of the source, Ω.
    pub resistance_ohm: f64,
    /// Brake chopper, if any.
    pub chopper: Option<Chopper>,
}

/// The DC link's source.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DcSource {
    /// A supply that sinks current as well as it sources it (a regenerative front end).
    Supply,
    /// A diode rectifier: current flows only into the link; regenerated energy stays there.
    Rectifier,
}

/// A brake chopper: a resistor switched across the link by the drive's brake output
/// ([`controller_core::drive::FastOutput::brake`], its thresholds in the drive's
/// `[protection] brake_chopper`), from the period after the drive decides it, like the duties.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chopper {
    /// Resistance, Ω.
    pub resistance_ohm: f64,
}

/// The DC link's state and its energy bookkeeping, updated once per PWM period with the
/// phase currents at the period's start: the inverter draws `i_dc = Σ d_x·i_x` (the upper
/// switches connect their phases to the positive rail; with the bridge off, the phases whose
/// current flows into the bridge conduct through their upper diodes), the source delivers
/// `(V_s − V_dc)/R` (a rectifier only when positive), the chopper `V_dc/R_ch` while the
/// drive has it on;
/// `C·dV_dc/dt` is the balance (explicit Euler: the link's time constants are far longer than
/// a period).
#[derive(Clone, Copy, Debug)]
pub(super) struct LinkState {
    pub(super) vdc_v: f64,
}

impl LinkState {
    /// One period of `ts` s with the chopper switched `brake`; returns the source's and the
    /// chopper's mean currents over it, A. The bus capacitor's equation with the inverter's
    /// current held, `C·dv/dt = (V_s − v)/R·[source conducts] − i_dc − v/R_ch·[brake]`, is
    /// linear: solved exactly over the period (an exponential towards its end value), and for
    /// a rectifier piecewise, at the instant the bus crosses the source's voltage. Explicit
    /// Euler, before, went unstable wherever R·C < T/2 — a realistic stiff supply (0.05 Ω,
    /// 470 µF) "diverged" at 13 ms and blamed the machine, and a 1 pF link read 9.6·10¹³ V
    /// (found by trying).
    pub(super) fn step(
        &mut self,
        link: &DcLink,
        source_v: f64,
        i_dc_a: f64,
        brake: bool,
        ts: f64,
    ) -> (f64, f64) {
        let g_ch = match link.chopper {
            Some(c) if brake => 1.0 / c.resistance_ohm,
            _ => 0.0,
        };
        let g_src = 1.0 / link.resistance_ohm;
        let c = link.capacitance_f;
        // `C·dv/dt = u − g·v` with the source conducting or not: (g, u).
        let coefficients = |conducting: bool| {
            if conducting { (g_src + g_ch, g_src * source_v - i_dc_a) } else { (g_ch, -i_dc_a) }
        };
        // `t` s from `v`, the source conducting or not: the voltage then.
        let relax = |v: f64, conducting: bool, t: f64| {
            let (g, u) = coefficients(conducting);
            if g > 0.0 { u / g + (v - u / g) * (-g * t / c).exp() } else { v + t * u / c }
        };
        // When, from `v` over `t` s in that state, the bus reaches the source's voltage.
        let crossing = |v: f64, conducting: bool, t: f64| {
            let (g, u) = coefficients(conducting);
            let tc = if g > 0.0 {
                let end = u / g;
                -(c / g) * ((source_v - end) / (v - end)).ln()
            } else {
                c * (source_v - v) / u
            };
            (tc.is_finite() && tc > 0.0 && tc < t).then_some(tc)
        };
        let v0 = self.vdc_v;
        let v1 = match link.source {
            DcSource::Supply => relax(v0, true, ts),
            DcSource::Rectifier => {
                let conducting = v0 < source_v;
                let v = relax(v0, conducting, ts);
                // Crossed the source's voltage within the period: the diodes switched there.
                if (v < source_v) != conducting
                    && let Some(tc) = crossing(v0, conducting, ts)
                {
                    relax(source_v, !conducting, ts - tc)
                } else {
                    v
                }
            }
        };
        self.vdc_v = v1;
        // Mean currents from the charge balance (the chopper's on the mean voltage).
        let i_ch = g_ch * 0.5 * (v0 + v1);
        let i_src = c * (v1 - v0) / ts + i_dc_a + i_ch;
        let i_src = match link.source {
            DcSource::Supply => i_src,
            DcSource::Rectifier => i_src.max(0.0), // the balance's rounding, not a reverse current
        };
        (i_src, i_ch)
    }
}
