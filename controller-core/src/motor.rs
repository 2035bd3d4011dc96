//! Induction-motor parameters, validated at construction.
//!
//! Per-phase equivalent-circuit values referred to the stator, as in seed 000 Table 1 and
//! seed 002 eq. (1): `L_s = L_ls + L_m`, `L_r = L_lr + L_m` are *self* inductances.
//! Derived: leakage coefficient `σ = 1 − L_m²/(L_s L_r)` and rotor time constant
//! `T_r = L_r/R_r`.
//!
//! Speed convention: `pole_pairs` = p; electrical speed `ω_e = p·ω_m`. (Seed 002 writes `P`
//! for the number of *poles*, so its `P/2` is our `p`.)

/// A parameter that failed validation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotorField {
    /// Stator resistance.
    RsOhm,
    /// Rotor resistance.
    RrOhm,
    /// Stator self-inductance.
    LsH,
    /// Rotor self-inductance.
    LrH,
    /// Magnetising inductance.
    LmH,
    /// Pole pairs.
    PolePairs,
    /// Inertia.
    JKgm2,
    /// Viscous friction.
    BNms,
}

/// Why a parameter set was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotorError {
    /// The field must be finite and > 0 (≥ 0 for `B`, ≥ 1 for pole pairs).
    NotPositive(MotorField),
    /// `σ = 1 − Lm²/(Ls·Lr)` must lie in (0, 1): `Lm² < Ls·Lr`.
    Leakage,
}

/// Validated motor parameters (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorParams {
    rs_ohm: f64,
    rr_ohm: f64,
    ls_h: f64,
    lr_h: f64,
    lm_h: f64,
    pole_pairs: u8,
    j_kgm2: f64,
    b_nms: f64,
}

impl MotorParams {
    /// Validate and build. Every field must be finite and positive (`b_nms` may be 0,
    /// `pole_pairs ≥ 1`) and `0 < σ < 1`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        rs_ohm: f64,
        rr_ohm: f64,
        ls_h: f64,
        lr_h: f64,
        lm_h: f64,
        pole_pairs: u8,
        j_kgm2: f64,
        b_nms: f64,
    ) -> Result<Self, MotorError> {
        let pos = |x: f64, f: MotorField| {
            if x.is_finite() && x > 0.0 { Ok(()) } else { Err(MotorError::NotPositive(f)) }
        };
        pos(rs_ohm, MotorField::RsOhm)?;
        pos(rr_ohm, MotorField::RrOhm)?;
        pos(ls_h, MotorField::LsH)?;
        pos(lr_h, MotorField::LrH)?;
        pos(lm_h, MotorField::LmH)?;
        if pole_pairs == 0 {
            return Err(MotorError::NotPositive(MotorField::PolePairs));
        }
        pos(j_kgm2, MotorField::JKgm2)?;
        if !(b_nms.is_finite() && b_nms >= 0.0) {
            return Err(MotorError::NotPositive(MotorField::BNms));
        }
        let sigma = 1.0 - lm_h * lm_h / (ls_h * lr_h);
        if !(sigma > 0.0 && sigma < 1.0) {
            return Err(MotorError::Leakage);
        }
        Ok(Self { rs_ohm, rr_ohm, ls_h, lr_h, lm_h, pole_pairs, j_kgm2, b_nms })
    }

    /// The same machine with its resistances `rs`× and `rr`×, its inductances `l`× (L_s, L_r
    /// and L_m alike: σ and L_m/L_r stay) and its inertia `j`× — a corner or sample of a
    /// certified parameter box (seed 000 Fig. 12, the design toolkit's `[certify]`).
    pub fn scaled(&self, rs: f64, rr: f64, l: f64, j: f64) -> Result<Self, MotorError> {
        Self::new(
            rs * self.rs_ohm,
            rr * self.rr_ohm,
            l * self.ls_h,
            l * self.lr_h,
            l * self.lm_h,
            self.pole_pairs,
            j * self.j_kgm2,
            self.b_nms,
        )
    }

    /// DeLorenzo DL10115A1, seed 002 appendix: Rs = 16.2 Ω, Rr = 23.2 Ω, Ls = 1.44 H,
    /// Lr = 1.5 H, Lm = 1.42 H, P = 2 poles (p = 1). J and B are not given in the paper;
    /// the values here (J = 0.005 kg·m², B = 0.0005 N·m·s) are placeholders of the right
    /// order for a 0.3 kW machine, to be replaced by hil-sim's motor files.
    pub fn delorenzo_dl10115a1() -> Result<Self, MotorError> {
        Self::new(16.2, 23.2, 1.44, 1.5, 1.42, 1, 0.005, 0.0005)
    }

    /// Stator resistance, Ω.
    pub fn rs_ohm(&self) -> f64 {
        self.rs_ohm
    }
    /// Rotor resistance, Ω.
    pub fn rr_ohm(&self) -> f64 {
        self.rr_ohm
    }
    /// Stator self-inductance, H.
    pub fn ls_h(&self) -> f64 {
        self.ls_h
    }
    /// Rotor self-inductance, H.
    pub fn lr_h(&self) -> f64 {
        self.lr_h
    }
    /// Magnetising inductance, H.
    pub fn lm_h(&self) -> f64 {
        self.lm_h
    }
    /// Pole pairs p.
    pub fn pole_pairs(&self) -> u8 {
        self.pole_pairs
    }
    /// Rotor + load inertia, kg·m².
    pub fn j_kgm2(&self) -> f64 {
        self.j_kgm2
    }
    /// Viscous friction, N·m·s/rad.
    pub fn b_nms(&self) -> f64 {
        self.b_nms
    }
    /// Leakage coefficient σ = 1 − Lm²/(Ls·Lr).
    pub fn sigma(&self) -> f64 {
        1.0 - self.lm_h * self.lm_h / (self.ls_h * self.lr_h)
    }
    /// Rotor time constant Tr = Lr/Rr, s.
    pub fn tr_s(&self) -> f64 {
        self.lr_h / self.rr_ohm
    }
    /// Torque constant at rotor flux ψr: T = (3/2)·p·(Lm/Lr)·ψr·i_qs → returns (3/2)·p·Lm/Lr.
    pub fn torque_factor(&self) -> f64 {
        1.5 * f64::from(self.pole_pairs) * self.lm_h / self.lr_h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box corner: resistances and inertia scaled as given, the inductances together (σ and
    /// L_m/L_r unchanged, T_r = L_r/R_r × l/rr); ×1 is the motor itself; a corner that is no
    /// motor is refused.
    #[test]
    fn scaled_is_a_box_corner() {
        let m = MotorParams::delorenzo_dl10115a1().unwrap();
        assert_eq!(m.scaled(1.0, 1.0, 1.0, 1.0), Ok(m));
        let c = m.scaled(1.5, 2.0, 0.6, 2.0).unwrap();
        assert_eq!((c.rs_ohm(), c.rr_ohm(), c.j_kgm2(), c.b_nms()), (1.5 * 16.2, 46.4, 0.01, m.b_nms()));
        assert!((c.sigma() - m.sigma()).abs() < 1e-12 && (c.tr_s() / m.tr_s() - 0.3).abs() < 1e-12);
        assert!(m.scaled(1.0, 1.0, -1.0, 1.0).is_err());
    }

    #[test]
    fn derived_quantities_of_the_delorenzo_motor() {
        let m = MotorParams::delorenzo_dl10115a1().unwrap();
        // σ = 1 − 1.42²/(1.44·1.5) = 1 − 2.0164/2.16
        assert!((m.sigma() - (1.0 - 2.0164 / 2.16)).abs() < 1e-12);
        assert!((m.tr_s() - 1.5 / 23.2).abs() < 1e-12);
    }

    #[test]
    fn bad_sets_name_the_field() {
        type Raw = (f64, f64, f64, f64, f64, u8, f64, f64);
        let ok: Raw = (16.2, 23.2, 1.44, 1.5, 1.42, 1, 0.005, 0.0);
        let build = |f: &dyn Fn(&mut Raw)| {
            let mut p = ok;
            f(&mut p);
            MotorParams::new(p.0, p.1, p.2, p.3, p.4, p.5, p.6, p.7)
        };
        assert!(build(&|_| ()).is_ok());
        assert_eq!(build(&|p| p.0 = -1.0), Err(MotorError::NotPositive(MotorField::RsOhm)));
        assert_eq!(build(&|p| p.1 = f64::NAN), Err(MotorError::NotPositive(MotorField::RrOhm)));
        assert_eq!(build(&|p| p.2 = 0.0), Err(MotorError::NotPositive(MotorField::LsH)));
        assert_eq!(build(&|p| p.3 = f64::INFINITY), Err(MotorError::NotPositive(MotorField::LrH)));
        assert_eq!(build(&|p| p.4 = -0.1), Err(MotorError::NotPositive(MotorField::LmH)));
        assert_eq!(build(&|p| p.5 = 0), Err(MotorError::NotPositive(MotorField::PolePairs)));
        assert_eq!(build(&|p| p.6 = 0.0), Err(MotorError::NotPositive(MotorField::JKgm2)));
        assert_eq!(build(&|p| p.7 = -1e-3), Err(MotorError::NotPositive(MotorField::BNms)));
        // Lm larger than √(Ls·Lr): σ ≤ 0 — physically impossible.
        assert_eq!(build(&|p| p.4 = 1.5), Err(MotorError::Leakage));
    }
}
