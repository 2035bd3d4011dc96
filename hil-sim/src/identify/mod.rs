//! Self-commissioning, host side (issue 20): run `controller_core::commission` against a
//! simulated motor (software in the loop), estimate the motor from its [`Record`], and write
//! a motor file with nominal values and intervals.
//!
//! # The model identified, and the leakage split
//! Seen from its terminals, an induction machine at standstill is the *inverse-Γ* circuit:
//! R_s, then L_σ = σL_s in series, then L_M = L_m²/L_r in parallel with R_R = R_r·(L_m/L_r)².
//! Its rotor time constant is T_r = L_M/R_R = L_r/R_r and L_s = L_σ + L_M. These four values
//! are all the terminals can tell; the T-model's five (R_s, R_r, L_s, L_r, L_m) need one
//! more: how the leakage divides between stator and rotor, `k = L_lr/L_ls` (default 1, the
//! usual equal split; IEEE Std 112 suggests 1.5 for NEMA design B, 1 for A and D). Control
//! does not depend on it: the current loops see R_s, σL_s and the rotor branch; IFOC's slip
//! gain needs T_r; the torque constant is 1.5·p·L_m²/L_r = 1.5·p·L_M; the rotor flux
//! referred to the stator, (L_m/L_r)·ψ_r, and every transfer function from stator voltage
//! to stator current are the same for every k (`split_leaves_the_terminals_unchanged`).
//!
//! # Estimation
//! - **R_s and the inverter's voltage error**: the DC levels' settled voltages `c` against
//!   their currents: `c = R_s·I + e` (two levels: the error e, constant while the phase
//!   currents keep their sign, cancels). Along phase a, each phase's dead-time error
//!   `−sign(i_x)·V_e` adds up to `−(4/3)·V_e` on the α axis, which the loop makes up:
//!   e = (4/3)·V_e, so V_e = ¾·e; its dead-time equivalent is `V_e/V_dc` of the period.
//! - **T_r and R_R** from each level step (the DC-decay test): with the current held by the
//!   loop at the new level, the rotor flux settles with T_r, and the voltage carries
//!   `dψ/dt = R_R·ΔI·e^{−t/T_r}` above its settled value. Each block mean is fitted by
//!   `c + A·(mean of e^{−(t − t₀)/τ} over the block)`, weighted by the block's length, with
//!   c and A by least squares for each τ and τ by a search on a logarithmic grid refined by
//!   golden section (variable projection). t₀ is the current's mean lag behind its step
//!   (from the record) less the 1.5 periods by which a commanded voltage precedes its
//!   effect. R_R = A/ΔI, L_M = R_R·T_r.
//! - **σL_s** from the injections: `Z(jω) = V̂·e^{−j1.5ωT}·sinc(ωT/2)/Î` (the voltage acts
//!   one period late and is held for a period), and
//!   `L_σ = (Im Z − Im Z_R)/ω` with the rotor branch `Z_R = jωL_M·R_R/(jωL_M + R_R)`.
//!
//! Every estimate is made once per repeat (two level pairs for R_s, three steps for T_r and
//! R_R, two frequencies for L_σ); the nominal value is their mean, the interval spans them,
//! widened by the stated margins ([`MARGIN`]).
//!
//! # Where it lives
//! - this module: what an identification finds ([`Identified`], [`Estimate`]) and the
//!   margins its intervals are widened by ([`MARGIN`]);
//! - `estimation`: the estimates from a [`Record`] ([`estimate`]; the equations above) and
//!   the thresholds that refuse a record;
//! - `model`: the inverse-Γ and T-models ([`TModel`], [`inverse_gamma`]), a saturating Γ
//!   machine's own values ([`gamma_truth`]) and the rated flux;
//! - `curve`: with the magnetizing curve measured (`--curve`), the estimates redone on it in
//!   the Γ model ([`GammaFit`], [`measured_curve`]);
//! - `run`: running the sequence — in SIL or PIL ([`simulate`], [`simulate_on`]) or on a
//!   board over its link ([`over_link`]) — and its refusals and stages in words;
//! - `output`: the motor file ([`motor_file`]; a saturating motor's in the Γ form with its
//!   curve, [`saturating_curve`]), the pictures ([`plots`]) and the no-load test's lines
//!   ([`describe_no_load`], [`describe_curve`]).
//!
//! [`Record`]: controller_core::commission::Record

mod curve;
mod estimation;
mod model;
mod output;
mod run;

pub use curve::measured_curve;
pub use estimation::{MECHANICS_MARGIN, NO_LOAD_FLUX_MIN, ROTATION_RATIO_RANGE, SLIP_RESOLUTION, estimate};
pub use model::{GammaTruth, TModel, gamma_truth, inverse_gamma, rated_flux_wb, t_model};
pub use output::{describe_curve, describe_no_load, motor_file, plots, saturating_curve};
pub use run::{RunError, Setup, Target, describe, over_link, simulate, simulate_on, stage_name};

/// Relative margin added on each side of the repeats' span, per parameter: the accuracy the
/// identification is tested to on every shipped motor and on seeded random motors
/// (`tests/identify.rs`) — what the repeats cannot show (a current sensor's gain error
/// scales every impedance alike; the model's approximations).
pub const MARGIN: Margins = Margins { rs: 0.03, l_sigma: 0.05, tr: 0.05, rr: 0.05, lm: 0.03 };

/// Relative margins ([`MARGIN`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Margins {
    /// R_s.
    pub rs: f64,
    /// σL_s.
    pub l_sigma: f64,
    /// T_r.
    pub tr: f64,
    /// R_r (and R_R).
    pub rr: f64,
    /// L_m, L_s, L_r (and L_M).
    pub lm: f64,
}

/// A value and its interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Mean of the repeats.
    pub value: f64,
    /// Smallest and largest repeat, widened by the margin.
    pub interval: [f64; 2],
    /// Largest repeat over the smallest, minus one (the repeatability).
    pub spread: f64,
}

impl Estimate {
    fn of(repeats: &[f64], margin: f64) -> Self {
        let n = repeats.len().max(1) as f64;
        let value = repeats.iter().sum::<f64>() / n;
        let lo = repeats.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = repeats.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Self { value, interval: [lo * (1.0 - margin), hi * (1.0 + margin)], spread: hi / lo - 1.0 }
    }

    /// A derived value: `f` of the nominal values, its interval from `f` at the ends
    /// (`f` monotonic in each argument: the caller passes the ends that bound it).
    fn derived(value: f64, lo: f64, hi: f64) -> Self {
        Self { value, interval: [lo.min(hi), hi.max(lo)], spread: f64::NAN }
    }

    /// `x` lies in the interval.
    pub fn contains(&self, x: f64) -> bool {
        self.interval[0] <= x && x <= self.interval[1]
    }
}

/// One exponential fit of a level step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DecayFit {
    /// Settled voltage, V.
    pub c_v: f64,
    /// Amplitude at the current's step, V.
    pub a_v: f64,
    /// Time constant, s.
    pub tau_s: f64,
    /// RMS of the weighted residual, V.
    pub rms_v: f64,
    /// Settled current of the level, A.
    pub i_a: f64,
}

/// What the standstill sequence identified.
#[derive(Clone, Debug, PartialEq)]
pub struct Identified {
    /// Stator resistance, Ω.
    pub rs_ohm: Estimate,
    /// Transient inductance σL_s = L_σ, H.
    pub l_sigma_h: Estimate,
    /// Rotor time constant, s.
    pub tr_s: Estimate,
    /// Referred rotor resistance R_R = R_r·(L_m/L_r)², Ω.
    pub r_rr_ohm: Estimate,
    /// L_M = L_m²/L_r, H: at rated flux by the no-load test if it ran, else from the DC
    /// levels.
    pub l_mm_h: Estimate,
    /// The inverter's voltage error per phase V_e, V.
    pub inverter_error_v: Estimate,
    /// Current-channel offsets, A.
    pub offsets_a: [f64; 3],
    /// Mean bus voltage, V.
    pub vdc_v: f64,
    /// The decay fits of the three level steps.
    pub decays: [DecayFit; 3],
    /// Impedance measured at each injection: (ω rad/s, Re Z, Im Z).
    pub impedance: [(f64, f64, f64); 2],
    /// The rotating field's results (if the motor was allowed to turn).
    pub rotation: Option<Rotation>,
    /// The no-load test's results (if the motor was allowed to turn).
    pub no_load: Option<NoLoad>,
    /// The Γ model on the measured curve (with `--curve`; module `curve`): then R_R, σL_s,
    /// L_M and T_r above are its inverse-Γ equivalent at rated flux.
    pub gamma: Option<GammaFit>,
}

/// The Γ model identified on the measured curve, at rated flux (`curve` module).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GammaFit {
    /// The branch's chord L_s = ψ_s/i_m at rated flux, H.
    pub l_s_h: Estimate,
    /// The rotor-side leakage L_σ, H.
    pub l_sigma_h: Estimate,
    /// The rotor resistance R_R, Ω.
    pub r_r_ohm: Estimate,
    /// The rotor time constant (L_s + L_σ)/R_R at rated flux, s.
    pub tr_s: Estimate,
}

/// One point of the magnetizing curve, the Γ branch's (at the terminals): the stator flux
/// against the branch's current, each an estimate over the level's windows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurvePoint {
    /// The fraction of the rated stator flux the level aimed at; `None` for the test
    /// current's level.
    pub target_fraction: Option<f64>,
    /// The stator flux ψ_s = |V − R_s·I|/ω, Wb (peak).
    pub flux_wb: Estimate,
    /// The branch's current i_m, the stator current's component along ψ_s, A (peak): the
    /// rotor's, ψ_s·ω_slip/R_R, lies at right angles to the flux to first order in the slip.
    pub current_a: Estimate,
}

/// What the no-load test at rated flux found.
#[derive(Clone, Debug, PartialEq)]
pub struct NoLoad {
    /// L_M at the test's flux, H (one repeat per window).
    pub l_mm_h: Estimate,
    /// L_M from the DC levels (the standstill test's flux), H.
    pub standstill_l_mm_h: Estimate,
    /// Stator flux reached, Wb (peak), against the rated flux asked for.
    pub flux_wb: f64,
    /// The rated stator flux asked for, Wb.
    pub rated_flux_wb: f64,
    /// Field frequency, rad/s (electrical).
    pub omega_e_rad_s: f64,
    /// Current amplitude, A.
    pub amplitude_a: f64,
    /// Mean slip, rad/s (electrical; from the encoder and the pole pairs).
    pub slip_rad_s: f64,
    /// The Γ branch's chord L_s = ψ_s/i_m at the test's flux, H (one repeat per window).
    pub l_s_h: Estimate,
    /// The magnetizing curve: a point per level reached (`controller_core::commission::
    /// no_load`, step 5) and the rated flux's, by rising current (a level the test current
    /// capped at its predecessor's current is left out).
    pub curve: Vec<CurvePoint>,
}

/// What the slow rotating field found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotation {
    /// The rotor's turning over the field's mechanical turning during the hold (1 − slip):
    /// the encoder's direction and line count, with the pole pairs given.
    pub ratio: f64,
    /// Mean speed during the hold, rad/s.
    pub omega_hold_rad_s: f64,
    /// Inertia, kg·m².
    pub j_kgm2: Estimate,
    /// Viscous friction, N·m·s/rad.
    pub b_nms: Estimate,
}
