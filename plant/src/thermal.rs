//! Winding temperatures (issue 50): the stator winding and the rotor cage as two first-order
//! thermal nodes, each heated by its own copper loss and cooled to the ambient through its
//! thermal resistance, their electrical resistances following their temperatures.
//!
//! ```text
//! C·dT/dt = P − (T − T_a)/R_th                 (each node; τ = R_th·C)
//! P_s = (3/2)·R_s(T_s)·|i_s|²,   P_r = (3/2)·R_r(T_r)·|i_r|²,   i_r = (ψ_r − L_m·i_s)/L_r
//! R(T) = R_ref·(1 + α·(T − T_ref))             (α_Cu = 3.93e-3/K, α_Al = 4.03e-3/K)
//! ```
//! (peak-valued space vectors: `(3/2)·|i|²` is three phases' RMS current squared). The
//! motor's resistances are stated at `T_ref`. Each node's thermal resistance comes from the
//! nameplate, not from a fitted number: at the rated RMS current I_N in steady state both
//! windings sit at the rated rise ΔT_N above the ambient (the insulation class's design
//! figure: IEC 60034-1 allows 80 K for class B, 105 K for class F) —
//! `R_th,s = ΔT_N/(3·R_s(T_a + ΔT_N)·I_N²)` and, the rotor carrying the rated current's torque
//! share `I_q² = I_N² − I_0²` (I_0 the no-load magnetizing current) referred through `L_m/L_r`,
//! `R_th,r = ΔT_N/(3·R_r(T_a + ΔT_N)·(L_m/L_r)²·I_q²)`. Both nodes share the motor's thermal
//! time constant. The temperatures move over minutes, so the simulator steps them with the
//! period's mean loss ([`Heating::advance`], exact for a loss held over the step) and
//! rebuilds the machine on the new resistances; the electrical model within a step keeps
//! them fixed.

use crate::MachineState;
use controller_core::motor::MotorParams;

/// The resistance-temperature coefficient of annealed copper at 20 °C, 1/K (IEC 60028).
pub const COPPER_ALPHA_PER_K: f64 = 3.93e-3;
/// The resistance-temperature coefficient of cast aluminium (a cage rotor) at 20 °C, 1/K.
pub const ALUMINIUM_ALPHA_PER_K: f64 = 4.03e-3;

/// Copper's melting point, °C: no winding is hotter, and the linear R(T) means nothing near it.
pub const COPPER_MELTING_C: f64 = 1085.0;

/// A heating machine's thermal data, as a nameplate and a data sheet give them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThermalSpec {
    /// The rated (continuous) RMS phase current, A.
    pub rated_current_a: f64,
    /// The no-load (magnetizing) RMS phase current at the rated flux, A (< the rated one).
    pub no_load_current_a: f64,
    /// The windings' steady rise above the ambient at the rated current, K.
    pub rated_rise_k: f64,
    /// The windings' thermal time constant, s.
    pub time_constant_s: f64,
    /// The ambient (coolant) temperature, °C.
    pub ambient_c: f64,
    /// The temperature the motor's resistances are stated at, °C.
    pub reference_c: f64,
}

/// Why a thermal spec was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ThermalError {
    /// A current, the rise or the time constant not finite and positive, or the no-load
    /// current not below the rated one.
    Nameplate,
    /// A temperature not finite, a resistance that would not be positive at the ambient or
    /// at the rated rise, or the rated rise reaching [`COPPER_MELTING_C`].
    Temperature,
}

impl core::fmt::Display for ThermalError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Nameplate => {
                "heating: the rated and no-load currents, the rated rise and the time constant must be \
                 finite and positive, the no-load current below the rated one"
            }
            Self::Temperature => {
                "heating: the ambient and reference temperatures must be finite and leave the resistances \
                 positive, and the ambient plus the rated rise below copper's melting point"
            }
        })
    }
}

/// The two windings' temperatures, °C.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Windings {
    /// The stator winding's.
    pub stator_c: f64,
    /// The rotor cage's.
    pub rotor_c: f64,
}

/// A machine that heats: its motor at the reference temperature and the two nodes' thermal
/// resistances ([`ThermalSpec::heating`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Heating {
    spec: ThermalSpec,
    motor: MotorParams,
    /// Thermal resistances to the ambient, K/W: stator, rotor.
    rth_k_per_w: [f64; 2],
}

impl ThermalSpec {
    /// The heating model of `motor` (its resistances stated at [`Self::reference_c`]).
    pub fn heating(&self, motor: &MotorParams) -> Result<Heating, ThermalError> {
        let s = self;
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !([s.rated_current_a, s.rated_rise_k, s.time_constant_s].into_iter().all(positive)
            && s.no_load_current_a.is_finite()
            && s.no_load_current_a >= 0.0
            && s.no_load_current_a < s.rated_current_a)
        {
            return Err(ThermalError::Nameplate);
        }
        if !(s.ambient_c.is_finite() && s.reference_c.is_finite()) {
            return Err(ThermalError::Temperature);
        }
        let hot = s.ambient_c + s.rated_rise_k;
        if hot >= COPPER_MELTING_C {
            return Err(ThermalError::Temperature);
        }
        let factor = |alpha: f64, t: f64| 1.0 + alpha * (t - s.reference_c);
        let (fs, fr) = (factor(COPPER_ALPHA_PER_K, hot), factor(ALUMINIUM_ALPHA_PER_K, hot));
        if !(positive(fs)
            && positive(fr)
            && positive(factor(COPPER_ALPHA_PER_K, s.ambient_c))
            && positive(factor(ALUMINIUM_ALPHA_PER_K, s.ambient_c)))
        {
            return Err(ThermalError::Temperature);
        }
        let i_n2 = s.rated_current_a * s.rated_current_a;
        let i_q2 = i_n2 - s.no_load_current_a * s.no_load_current_a;
        let k = motor.lm_h() / motor.lr_h();
        let p_s = 3.0 * motor.rs_ohm() * fs * i_n2;
        let p_r = 3.0 * motor.rr_ohm() * fr * k * k * i_q2;
        Ok(Heating { spec: *s, motor: *motor, rth_k_per_w: [s.rated_rise_k / p_s, s.rated_rise_k / p_r] })
    }
}

impl Heating {
    /// Both windings at the ambient (a motor started cold).
    pub fn cold(&self) -> Windings {
        Windings { stator_c: self.spec.ambient_c, rotor_c: self.spec.ambient_c }
    }

    /// Both windings at the rated rise (a motor stopped after running at its rated current).
    pub fn rated_hot(&self) -> Windings {
        let t = self.spec.ambient_c + self.spec.rated_rise_k;
        Windings { stator_c: t, rotor_c: t }
    }

    /// The same windings on another motor's resistances at the reference temperature (a
    /// parameter step mid-run): the thermal resistances are the machine's and stay.
    pub fn with_motor(&self, motor: &MotorParams) -> Self {
        Self { motor: *motor, ..*self }
    }

    /// The nodes' thermal resistances to the ambient, K/W: stator, rotor.
    pub fn thermal_resistances_k_per_w(&self) -> [f64; 2] {
        self.rth_k_per_w
    }

    /// The motor at the windings' temperatures `w`: its resistances scaled, all else as stated.
    pub fn motor_at(&self, w: &Windings) -> MotorParams {
        let t_ref = self.spec.reference_c;
        let rs = 1.0 + COPPER_ALPHA_PER_K * (w.stator_c - t_ref);
        let rr = 1.0 + ALUMINIUM_ALPHA_PER_K * (w.rotor_c - t_ref);
        // The factors are positive from the ambient up (checked at construction); a winding
        // cannot cool below its ambient in `advance`.
        self.motor.scaled(rs, rr, 1.0, 1.0).unwrap_or(self.motor)
    }

    /// The copper losses of the machine `m` (the motor at the windings' present temperatures,
    /// [`Self::motor_at`]) in the state `x`, W: stator, rotor (module docs).
    pub fn losses_w(m: &MotorParams, x: &MachineState) -> [f64; 2] {
        let (lm, lr) = (m.lm_h(), m.lr_h());
        let i2 = x.i_alpha_a * x.i_alpha_a + x.i_beta_a * x.i_beta_a;
        let (ira, irb) = ((x.psi_alpha_wb - lm * x.i_alpha_a) / lr, (x.psi_beta_wb - lm * x.i_beta_a) / lr);
        [1.5 * m.rs_ohm() * i2, 1.5 * m.rr_ohm() * (ira * ira + irb * irb)]
    }

    /// The windings `w` after `dt_s` with the losses `losses_w` (W: stator, rotor) held: each
    /// node's exact first-order step, `T ← T_∞ + (T − T_∞)·e^{−dt/τ}`, `T_∞ = T_a + P·R_th`.
    pub fn advance(&self, w: &Windings, losses_w: [f64; 2], dt_s: f64) -> Windings {
        let decay = (-dt_s / self.spec.time_constant_s).exp();
        let step = |t: f64, p: f64, rth: f64| {
            let t_inf = self.spec.ambient_c + p.max(0.0) * rth;
            t_inf + (t - t_inf) * decay
        };
        let [rs, rr] = self.rth_k_per_w;
        Windings { stator_c: step(w.stator_c, losses_w[0], rs), rotor_c: step(w.rotor_c, losses_w[1], rr) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor() -> MotorParams {
        MotorParams::delorenzo_dl10115a1().unwrap()
    }

    fn spec() -> ThermalSpec {
        ThermalSpec {
            rated_current_a: 0.88,
            no_load_current_a: 0.45,
            rated_rise_k: 80.0,
            time_constant_s: 900.0,
            ambient_c: 40.0,
            reference_c: 20.0,
        }
    }

    /// A DC current at standstill (the flux settled: no rotor current) heats the stator alone
    /// to the fixed point of `T − T_a = R_th·3·R_s(T)·I²`, in closed form
    /// `T = (T_a + R_th·3R_ref·I²·(1 − α·T_ref))/(1 − α·R_th·3R_ref·I²)`: stepped over forty
    /// time constants it ends within 1e-9 of it; at the rated current that is the rated rise
    /// (the thermal resistance's definition), and the rotor stays at the ambient.
    #[test]
    fn a_dc_current_heats_the_stator_to_its_analytic_steady_state() {
        let (m, s) = (motor(), spec());
        let h = s.heating(&m).unwrap();
        let [rth, _] = h.thermal_resistances_k_per_w();
        for i_rms in [0.5, s.rated_current_a, 1.2] {
            let i_peak = i_rms * 2f64.sqrt();
            let mut w = h.cold();
            let dt = s.time_constant_s / 200.0;
            for _ in 0..8_000 {
                let at = h.motor_at(&w);
                let x = MachineState {
                    i_alpha_a: i_peak,
                    psi_alpha_wb: at.lm_h() * i_peak,
                    ..Default::default()
                };
                w = h.advance(&w, Heating::losses_w(&at, &x), dt);
            }
            let k = rth * 3.0 * m.rs_ohm() * i_rms * i_rms;
            let t = (s.ambient_c + k * (1.0 - COPPER_ALPHA_PER_K * s.reference_c))
                / (1.0 - COPPER_ALPHA_PER_K * k);
            assert!((w.stator_c - t).abs() < 1e-9 * t, "{i_rms} A: {} °C against {t}", w.stator_c);
            assert_eq!(w.rotor_c, s.ambient_c);
            if i_rms == s.rated_current_a {
                assert!((t - s.ambient_c - s.rated_rise_k).abs() < 1e-9, "{t}");
            }
        }
    }

    /// The rotor node at the rated current's torque share: with `|i_r| = (L_m/L_r)·I_q·√2`
    /// held, the rotor settles at the rated rise; a step of the loss from cold follows
    /// `1 − e^{−t/τ}` (63.2 % of the rise after one time constant).
    #[test]
    fn the_rotor_heats_at_its_rated_loss_to_the_rated_rise() {
        let (m, s) = (motor(), spec());
        let h = s.heating(&m).unwrap();
        let i_q = (s.rated_current_a.powi(2) - s.no_load_current_a.powi(2)).sqrt() * 2f64.sqrt();
        // A rotor current i_r = −(L_m/L_r)·i_q on the β axis: ψ_r = L_m·i_s + L_r·i_r = 0 there.
        let x = |_: &MotorParams| MachineState { i_beta_a: i_q, psi_beta_wb: 0.0, ..Default::default() };
        let mut w = h.cold();
        let dt = s.time_constant_s / 1_000.0;
        for _ in 0..1_000 {
            let at = h.motor_at(&w);
            w = h.advance(&w, Heating::losses_w(&at, &x(&at)), dt);
        }
        // After one time constant, the loss rising with R_r(T): at least 63.2 % of the rise
        // the cold loss would settle at, and below the rated rise.
        let f = |t: f64| 1.0 + ALUMINIUM_ALPHA_PER_K * (t - s.reference_c);
        let cold_rise = s.rated_rise_k * f(s.ambient_c) / f(s.ambient_c + s.rated_rise_k);
        let rise = w.rotor_c - s.ambient_c;
        assert!(rise > (1.0 - (-1f64).exp()) * cold_rise && rise < s.rated_rise_k, "{rise} K");
        for _ in 0..40_000 {
            let at = h.motor_at(&w);
            w = h.advance(&w, Heating::losses_w(&at, &x(&at)), dt);
        }
        // Settled: the β current also heats the stator (it is the stator's current too).
        assert!((w.rotor_c - s.ambient_c - s.rated_rise_k).abs() < 1e-6, "{}", w.rotor_c);
        let at = h.motor_at(&w);
        let expected =
            m.rr_ohm() * (1.0 + ALUMINIUM_ALPHA_PER_K * (s.ambient_c + s.rated_rise_k - s.reference_c));
        assert!((at.rr_ohm() / expected - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_nameplate_that_is_not_one_is_refused() {
        let m = motor();
        let bad = [
            ThermalSpec { rated_current_a: 0.0, ..spec() },
            ThermalSpec { no_load_current_a: 0.88, ..spec() },
            ThermalSpec { rated_rise_k: f64::NAN, ..spec() },
            ThermalSpec { time_constant_s: -1.0, ..spec() },
        ];
        for s in bad {
            assert_eq!(s.heating(&m), Err(ThermalError::Nameplate), "{s:?}");
        }
        let cold = ThermalSpec { ambient_c: -300.0, ..spec() };
        assert_eq!(cold.heating(&m), Err(ThermalError::Temperature));
        assert_eq!(
            ThermalSpec { reference_c: f64::INFINITY, ..spec() }.heating(&m),
            Err(ThermalError::Temperature)
        );
        // Found by trying: a rise of 1e300 K was taken, and the run failed on the machine's
        // stiffness, naming the RK4 step instead of the rise. A winding hotter than copper
        // melts is not one.
        for rise in [1e300, COPPER_MELTING_C] {
            let s = ThermalSpec { rated_rise_k: rise, ..spec() };
            assert_eq!(s.heating(&m), Err(ThermalError::Temperature), "{rise}");
        }
        assert!(ThermalSpec { rated_rise_k: COPPER_MELTING_C - 41.0, ..spec() }.heating(&m).is_ok());
    }
}
