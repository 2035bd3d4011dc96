//! The magnetizing fit: the rotor resistance, the inductances and the stator resistance
//! read from the flux build at the enable, before the first torque ([`MrasConfig::fit`]).
//!
//! **Why at the enable.** The rotor's
//! temperature at power-up is unknown, and a first full-torque acceleration on a guess is
//! where the detuning costs most. At rest, with the d-axis current held by the loops, the
//! d-axis voltage is `v_d(t) = R_s·i_d + R_R·i_d·e^{−t/T_r}` (`R_R = (L_m/L_r)²·R_r`; the
//! second term is `(L_m/L_r)·dψ_r/dt` of the building flux), so the sums `S₀, S₁, S₂` of
//! three consecutive windows of length W fall geometrically and
//! `(S₀ − S₁)/(S₁ − S₂) = e^{W/T_r}`: the rotor time constant **without the stator
//! resistance**, any constant offset of the voltage (dead time, current-sensor offset) or
//! the flux left from an earlier run. `r̂ = (T_r,motor/T̂_r)·ℓ̂` (ℓ̂ the inductance scale,
//! below; 1 when it is not estimated), limited to the range. The
//! windows start [`FIT_SKIP_S`] after the enable (the current's own step), each
//! [`FIT_WINDOW_FRACTION`] of T_r at the range's middle; the drive stays magnetizing until
//! the fit is done. It holds on a spinning rotor too (with i_q = 0 the cross term
//! `−ω_e·σL_s·i_q` is zero and the flux builds on the d axis); a d-axis reference that moves
//! (field weakening while spinning), or sums that do not fall, leave the estimate where it
//! was.
//!
//! **On a turning rotor, the q axis** ([`FitAxis`]). The same flux appears in the q-axis
//! voltage as the back-EMF, `v_q = R_s·i_q + σL_s·(di_q/dt + ω_e·i_d) + ω_e·(L_m/L_r)·ψ_r`,
//! so `−v_q/ω_e` (i_q = 0) is a constant plus `−(L_m/L_r)·ψ_r`: the same decay, with an
//! amplitude `|ω_e|·T_r` times the d axis's. A field angle that drifts by δ while the flux
//! builds moves `v_d` by δ·v_q — at the 300 W motor's 373 rad/s (ω_e·T_r ≈ 24) a drift of a
//! milliradian is a quarter of the d axis's decay over a window, and the d-axis fit read
//! ×2.4 its rotor resistance (the top of its range; hil-sim test
//! `a_flying_start_at_top_speed_reads_its_rotor_resistance`); the q axis moves by δ·v_d. So
//! the fit reads `−v_q/ω_e` when `|ω_e|·T_r ≥ 1` as its windows begin (the q axis's share of
//! the decay at least the d axis's; ω_e the field's mean speed since the enable, not one
//! slow period's encoder count), scaled by that speed, and gives up when the mean over the
//! windows falls below the bound. Its constant part is not the stator's drop: no stator
//! resistance is read there.
//!
//! Before the first fit the estimate is the range's geometric middle
//! ([`MrasConfig::initial_scale`]); it is kept across disable/enable.
//!
//! **The stator resistance, from the same transient**: `c/i_d` ([`Fitted::stator_resistance_ohm`]).
//! An encoder drive does not need it (the law above cancels R_s); a sensorless drive's
//! observer runs its voltage model on it ([`crate::observer`]), and holds the rotor
//! resistance at the fit's (without a speed measurement the reactive power carries no
//! information on R_r: docs/sensorless.md).
//!
//! **The inductances, from the same transient.** `T_r = L_r/R_r` shortens with saturation
//! (the inductances ×ℓ, L_s, L_r, L_m alike), so the ratio alone reads L ×0.6 as R_r ×1.67.
//! The flux linkage the enable builds settles it: `∫(v_d − c) dt = L_s·i_d` from a rotor
//! without flux — the fast steps before the windows as summed, the decay from the first
//! window on from the fit (`B/(1 − q)`, `q = e^{−W/T_r}`), the constant `c` (stator drop,
//! offsets) from the windows. `ℓ̂ = ∫(v_d − c) dt/(L_s·i_d)`, limited to its range, and
//! `r̂ = (T_r,motor/T̂_r)·ℓ̂` ([`Fitted`]). Only on a rotor idle for
//! [`DEMAGNETIZED_TIME_CONSTANTS`] (a flux left from the last run reads as a smaller
//! inductance) and at rest ([`RotorFit::turning`]); otherwise ℓ̂ is kept. The online laws
//! ([`super`]) run on the model at ℓ̂
//! ([`with_inductance_scale`](crate::envelope::EnvelopeConfig::with_inductance_scale)).
//!
//! **On a saturating motor the windows slide** ([`FitPeriod::saturating`]). There the flux
//! does not build as one exponential: the voltage's decay runs at the incremental
//! inductance of the flux reached, `(L_d(ψ) + L_lr)/R_r`, long while the flux is below the
//! knee and short above it, and three windows across the knee read the constant part `c` —
//! which multiplies the whole time since the enable — wrong: on the 300 W motor's
//! saturating twin at its rated current, ×2.9 its flux linkage (test
//! `a_saturating_machines_fit_slides_until_its_flux_settles`). In the drive the range
//! clamped that to its top, and ℓ solved from it on the curve's flat part read 0.846 where the
//! machine was ×1 and ×0.8 alike (hil-sim test
//! `a_saturating_machine_is_identified_on_its_curve_at_any_inductance_scale`). So the windows
//! slide on — the first joins the sum before them, a new one opens — until the last two
//! differ by at most [`FIT_SETTLED_SHARE`] of the least inductance's flux linkage (the flux
//! has settled, `c` is the voltage the loops then ask), at most [`FIT_SLIDE_WINDOWS_MAX`]
//! windows more; a slid decay slower than the slowest rotor the ranges allow is the noise's
//! and counts as none beyond its first window.
//! What [`MrasConfig::fit`] returns as the rotor resistance is the first windows' (their
//! decay and the flux linkage they read are of the same building flux, where the later
//! ones' decay is within the noise) — but across the knee no window ratio is the rotor's
//! rate, and the drive reads it on the curve instead, from the rotor's own equation over
//! the sampled build ([`MrasConfig::rotor_resistance_on_curve`]).

use super::MrasConfig;
use crate::frames::Dq;
use crate::motor::MotorParams;
use crate::num::{Scalar, finite_positive};

/// The fit's windows start this long after the enable, when the d-axis current's own step is
/// over (the current loops settle within ≈ 1 ms; the ICAD lag's slow modes, −50 ± j200 rad/s
/// in eq. (20), have decayed to e^{−0.5}: 5 ms gave 3.5 % more bias at R_s ×1.5).
pub const FIT_SKIP_S: f64 = 10e-3;

/// Each window of the fit is this fraction of the rotor time constant at the middle of the
/// range: the three windows take 2.4 of its 3 time constants of magnetizing (to 95 %). Longer
/// windows average more of the voltage's noise (the current sensors' through the loops'
/// gain): with half a time constant, one of twelve seeded runs with realistic sensors was
/// 22 % off; the error with 0.8 is what `magnetizing_measures_the_rotor_resistance_and_the_inductance` prints.
pub const FIT_WINDOW_FRACTION: f64 = 0.8;

/// A saturating motor's fit slides its windows on while the last two differ by more than
/// this fraction of the least inductance's flux linkage ([`MrasConfig::fit`]): what the
/// flux still builds is then of the order of this share, a tenth of a flux requirement of
/// 10 %, and ℓ solved on the curve's flat part (× `L_chord/L_d`, ≈ 3) stays within a few %.
pub const FIT_SETTLED_SHARE: f32 = 0.01;

/// The most windows a saturating motor's fit slides past: with its three, nine windows of
/// [`FIT_WINDOW_FRACTION`] of the rotor time constant at the range's middle — 7.2 of them,
/// the flux settled to e^{−7} on the chord, sooner on the steeper incremental decay above
/// the knee.
pub const FIT_SLIDE_WINDOWS_MAX: u32 = 6;

/// Samples of the flux linkage a saturating motor's fit keeps over its skip and first three
/// windows ([`MrasConfig::rotor_resistance_on_curve`]): one every 0.08 of the rotor time
/// constant at the range's middle, where the trapezoids' bias on the convex magnetizing
/// current is −0.2 … −0.6 % (a Γ-model check of motulator's 2.2 kW curve at 5 and 10 ms).
pub const FIT_FLUX_SAMPLES: usize = 32;

/// A saturating motor's rotor resistance is read over the build up to where the stator
/// flux first reaches this fraction of its value as the third window closes. An error δc of
/// the voltage's constant part puts `δc·t` into the flux, and the flux's current grows
/// steeply above the knee: read to the settled flux, 0.5 % of δc moved R̂_r by 4–8 %; to 0.7
/// of it, 1 % moved it by 2.3–3.4 % (the same check, ℓ 0.9 … 1.1, R_r ×1 … ×1.5).
pub const FIT_CURVE_FLUX_FRACTION: f32 = 0.7;

/// The fit gives up when the d-axis current reference moves by more than this fraction.
pub const FIT_I_D_TOLERANCE: f32 = 0.01;

/// The inductance is measured only on a rotor idle this many of its longest rotor time
/// constants since the bridge last drove it (the rotor flux left is then below e^{−5} = 0.7 %
/// of what it was): the fit reads the whole flux linkage the enable builds, and a flux left
/// from the last run would read as a smaller inductance.
pub const DEMAGNETIZED_TIME_CONSTANTS: f64 = 5.0;

/// What the magnetizing fit measured ([`MrasConfig::fit`]), each limited to its range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fitted {
    /// The rotor resistance, × the motor's R_r.
    pub rr_scale: f32,
    /// The inductances, × the motor's (the scale in use when not measured). A saturating
    /// motor's is the flux linkage over the motor's `L_s·i_d`, not limited here: ℓ times the
    /// chord's ratio at the current asked, which may lie beyond the range where ℓ does not —
    /// the drive solves ℓ on its curve and limits that (`SlowState::set_inductance_on_curve`).
    pub inductance_scale: f32,
    /// `inductance_scale` was measured (at rest, on a demagnetized rotor, a range to read
    /// within): the flux linkage of the settled build at the fit's current.
    pub inductance_measured: bool,
    /// The d-axis voltage's constant part over the current, Ω: the stator resistance as the
    /// voltage the loops ask for sees it (any constant offset of that voltage — the dead
    /// time's residual at this current — included). `None` when not finite and positive.
    /// A sensorless drive's observer runs on it ([`crate::observer`]).
    pub stator_resistance_ohm: Option<f32>,
}

/// Which voltage the magnetizing fit reads the building flux in (module docs): chosen by
/// the field's speed as its windows begin.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FitAxis {
    /// The d-axis voltage, `(L_m/L_r)·dψ_r/dt` (a rotor at rest or turning slowly).
    #[default]
    Direct,
    /// `−v_q/ω_e`, `−(L_m/L_r)·ψ_r` (`|ω_e|·T_r ≥ 1`).
    Quadrature,
}

/// One slow period of magnetizing, as the drive hands it to [`MrasConfig::fit`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FitPeriod {
    /// The sum of the voltage the loops asked for (the modulator's limit of it while it
    /// limits) over the period's fast steps, field frame, V.
    pub v_sum: Dq,
    /// The period's fast steps.
    pub steps: u16,
    /// The d-axis current reference, A.
    pub i_d_a: f32,
    /// The period's mean measured d-axis current, field frame, A: a saturating motor's
    /// build integrates it ([`MrasConfig::rotor_resistance_on_curve`]; the reference's step
    /// overshoots at top speed, where the reference's integral read R_r 1.9 % high).
    pub i_d_mean_a: f32,
    /// The field's angle over the period at the shaft's speed, `p·ω_m·T_slow`, electrical
    /// rad (0 without a speed measurement).
    pub field_step_rad: f32,
    /// The inductance scale, × the motor's, at the flux the reference builds: the rotor
    /// time constant the decay approaches (a saturating motor's chord there, the scale in
    /// use for a linear one).
    pub built_inductance_scale: f32,
    /// The motor saturates: the windows slide on until the flux linkage they read settles
    /// ([`MrasConfig::fit`]).
    pub saturating: bool,
    /// The fast steps of each slow period that still run the plan before the last (the
    /// plan's delay, `DriveConfig::plan_delay`): in the period after the first slow step
    /// they carry no current yet ([`MrasConfig::fit`]).
    pub delay_steps: u16,
}

/// The magnetizing fit's progress ([`MrasConfig::fit`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RotorFit {
    /// Slow steps since the enable.
    steps: u32,
    /// The windows' sums of the slow periods' mean v_d, V.
    sums: [f32; 3],
    /// The sum of v_d over the fast steps before the windows, V, and their number.
    pre_sum: f32,
    pre_steps: u32,
    /// The d-axis current reference the fit started with, A.
    i_d_a: f32,
    /// The voltage it reads, chosen with the reference.
    axis: FitAxis,
    /// The field's angle at the shaft's speed before the windows and over them, rad.
    field_rad: f32,
    window_field_rad: f32,
    /// The rotor was demagnetized at the enable: the inductance is measured too (not on a
    /// turning rotor).
    demagnetized: bool,
    /// The rotor was demagnetized at the enable, turning or not: a saturating motor's rotor
    /// resistance may be read on its curve ([`MrasConfig::rotor_resistance_on_curve`]).
    flux_free: bool,
    /// Finished (estimated, or given up).
    done: bool,
    /// A saturating motor's fit: windows slid past so far, and the rotor resistance its first
    /// three windows read.
    slid: u32,
    first_rr_scale: f32,
    /// A saturating motor's fit: the sum of the voltage over the fast steps since the first
    /// slow step, V, and of the slow periods' mean measured d-axis current, A (a flying
    /// start in field weakening moves the reference before the windows and within
    /// [`FIT_I_D_TOLERANCE`] over them; its step overshoots at speed); both sums at each [`FIT_FLUX_SAMPLES`] sample and
    /// how many were taken; the d-axis voltage's constant part the settled fit found, V (0
    /// on the q axis; NaN when the fit cannot be read on the curve — a rotor with flux at the
    /// enable, or at rest one whose flux linkage was not measured).
    volts: f32,
    amps: f32,
    flux_samples: [FluxSample; FIT_FLUX_SAMPLES],
    taken: u32,
    constant_v: f32,
}

/// One sample of a saturating motor's build ([`RotorFit`]): the sums of the voltage, V, and
/// of the mean measured d-axis current, A, from the first slow step to it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct FluxSample {
    volts: f32,
    amps: f32,
}

impl RotorFit {
    /// A fit starting at an enable; `demagnetized` as [`MrasConfig::demagnetized_after`]
    /// says (otherwise only the rotor time constant is read).
    pub fn new(demagnetized: bool) -> Self {
        Self { demagnetized, flux_free: demagnetized, ..Self::default() }
    }

    /// The rotor turns during the fit: the inductance is not read (the rotor time constant
    /// still is). On a turning rotor the stationary loops lag their references at the
    /// field's frequency — the trim that corrects it is held while the fit runs — so the
    /// flux linkage built is not `L_s·i_d*`: a flying start at 147 rad/s ran 2 % below its
    /// flux and lost 0.55 points of the envelope's torque (docs/rotor-resistance.md).
    pub fn turning(&mut self) {
        self.demagnetized = false;
    }
}

/// The magnetizing fit's window for `motor` and the rotor-resistance range `[min, max]`, s:
/// [`FIT_WINDOW_FRACTION`] of the rotor time constant at the range's middle `√(min·max)`.
pub fn fit_window_s(motor: &MotorParams, [min, max]: [f64; 2]) -> f64 {
    FIT_WINDOW_FRACTION * motor.tr_s() / libm::sqrt(min * max)
}

/// The longest the magnetizing fit keeps the drive magnetizing, s: [`FIT_SKIP_S`] and its
/// three windows ([`fit_window_s`]), and the slid ones of a saturating motor whose inductance
/// it measures (`inductance_range` not one value; [`FIT_SLIDE_WINDOWS_MAX`]).
pub fn fit_time_max_s(
    motor: &MotorParams,
    range: [f64; 2],
    inductance_range: [f64; 2],
    saturating: bool,
) -> f64 {
    let slides = saturating && inductance_range[0] < inductance_range[1];
    let windows = 3 + if slides { FIT_SLIDE_WINDOWS_MAX } else { 0 };
    FIT_SKIP_S + f64::from(windows) * fit_window_s(motor, range)
}

impl MrasConfig {
    /// The slow steps the magnetizing fit may keep the drive magnetizing at most: its skip,
    /// the first step's and its three windows, and the slid ones of a saturating motor whose
    /// inductance it measures ([`FIT_SLIDE_WINDOWS_MAX`]); 0 when it does not run.
    pub fn fit_slow_steps_max(&self, saturating: bool) -> u32 {
        if !self.fit_active() {
            return 0;
        }
        let slides = saturating && self.l_max > self.l_min;
        let windows = 3 + if slides { FIT_SLIDE_WINDOWS_MAX } else { 0 };
        self.fit_skip_steps.saturating_add(1).saturating_add(windows.saturating_mul(self.fit_window_steps))
    }

    /// A rotor left idle `idle_slow_steps` slow steps counts as demagnetized
    /// ([`DEMAGNETIZED_TIME_CONSTANTS`]).
    pub fn demagnetized_after(&self, idle_slow_steps: u32) -> bool {
        idle_slow_steps >= self.demagnetized_steps
    }

    /// `|ω_e|·T_r,motor` over one slow period's field angle `field_step_rad`.
    fn field_speed_tr(&self, field_step_rad: f32) -> f32 {
        field_step_rad.abs() * self.tr_over_window * self.fit_window_steps as f32
    }

    /// One slow step of magnetizing ([`FitPeriod`]) on the inductance scale in use `l_now`
    /// (what [`Fitted::inductance_scale`] keeps when it is not measured). The rotor
    /// resistance is the decay's rate × the inductance it approaches: the flux linkage
    /// measured, or [`FitPeriod::built_inductance_scale`] — on a saturating motor the chord
    /// at the flux the reference builds, not where the flux is as the windows close (the
    /// 300 W motor's saturating twin at 100 rad/s read ×1.15 there, and a tenth of its
    /// envelope ran 13 % over its torque). Returns what it measured once, when the third
    /// window closes (a saturating motor's: when its slid windows settle; module docs),
    /// `None` before, after and when the fit is given up: the reference moved by more than
    /// [`FIT_I_D_TOLERANCE`] from the first window on (field weakening on a spinning rotor),
    /// the voltage is not finite, or a q-axis fit's field slowed below `|ω_e|·T_r = 1` over
    /// the windows. [`RotorFit::new`] starts it (at the
    /// enable).
    pub fn fit(&self, f: &mut RotorFit, period: &FitPeriod, l_now: f32) -> Option<Fitted> {
        if f.done || !self.fit_active() {
            return None;
        }
        let FitPeriod {
            v_sum,
            steps,
            i_d_a,
            i_d_mean_a,
            field_step_rad,
            built_inductance_scale,
            saturating,
            delay_steps,
        } = *period;
        let (first, second) = (f.steps == 0, f.steps == 1);
        // The reference and the axis are taken up to the first window: a move before it (a
        // saturating machine's model settling on its curve in field weakening) leaves one
        // decay at the rotor's rate after it, which the windows read, and the flux linkage
        // of the final current. The axis by the field's mean speed since the enable: one
        // slow period's angle is the encoder's count at rest (one count of 1 024 lines over
        // 0.5 ms reads 3 rad/s, ω_e·T_r ≈ 6 on a 153 kW motor).
        if f.steps <= self.fit_skip_steps {
            f.i_d_a = i_d_a;
            f.field_rad += field_step_rad;
            let mean = f.field_rad / (f.steps + 1) as f32;
            f.axis = if self.field_speed_tr(mean) >= 1.0 { FitAxis::Quadrature } else { FitAxis::Direct };
        } else {
            f.window_field_rad += field_step_rad;
        }
        let v = match f.axis {
            FitAxis::Direct => v_sum.d,
            // −v_q/ω_e up to the mean speed's magnitude (a constant factor of the sums).
            FitAxis::Quadrature if f.field_rad < 0.0 => v_sum.q,
            FitAxis::Quadrature => -v_sum.q,
        };
        if !(v.is_finite() && (i_d_a - f.i_d_a).abs() <= FIT_I_D_TOLERANCE * f.i_d_a.abs()) {
            f.done = true;
            return None;
        }
        f.steps = f.steps.saturating_add(1);
        if saturating && !first {
            self.sample_flux(f, v, i_d_mean_a);
        }
        let Some(k) = f.steps.checked_sub(self.fit_skip_steps.saturating_add(1)) else {
            // The first slow step's sum is of the fast steps between the enable and it, which
            // ran before it set the d-axis reference: no current, nothing built — and the
            // constant part `c` must not be taken off them (an enable between slow steps read
            // ℓ̂ low by up to (N − 1)·T·R_s/(ℓ·L_s)). Nor off the next period's first
            // `delay_steps`, which still ran the plan before it — none: the first reference
            // is adopted a plan's delay after the slow step that made it (`drive.toml`'s
            // perturbed motor at R_s × 1.5, 4 kHz, one step: ℓ̂ 0.860 for 0.874).
            if !first {
                let idle = if second { delay_steps.min(steps) } else { 0 };
                f.pre_sum += v;
                f.pre_steps = f.pre_steps.saturating_add(u32::from(steps - idle));
            }
            return None;
        };
        let window = (k / self.fit_window_steps).wrapping_sub(f.slid) as usize;
        if let Some(sum) = f.sums.get_mut(window) {
            *sum += v / f32::from(steps.max(1));
        }
        if k + 1 < (3 + f.slid).saturating_mul(self.fit_window_steps) {
            return None;
        }
        f.done = true;
        // A q-axis fit whose field slowed below the bound over the windows: the back-EMF
        // no longer carries the decay.
        let windows_steps = (3 * self.fit_window_steps) as f32;
        if f.axis == FitAxis::Quadrature && self.field_speed_tr(f.window_field_rad / windows_steps) < 1.0 {
            return None;
        }
        let [s0, s1, s2] = f.sums;
        let (d0, d1) = (s0 - s1, s1 - s2);
        let rate = if f.slid == 0 {
            if !(d0 > 0.0 && d1 > 0.0) {
                return None;
            }
            // r̂/ℓ̂ = T_r,motor/T̂_r; a ratio at or below 1 (the middle window's step the
            // smaller) is noise, not a fit.
            let rate = self.tr_over_window * crate::num::ln_f32(d0 / d1);
            if !finite_positive(rate) {
                return None;
            }
            rate
        } else {
            0.0
        };
        // A saturating motor's windows have settled when the last two differ by at most
        // FIT_SETTLED_SHARE of the least inductance's flux linkage (their volt-seconds).
        let settled =
            self.t_fast_over_ls * self.slow_divider * d1.abs() / f.i_d_a <= FIT_SETTLED_SHARE * self.l_min;
        // Slid windows: a decay slower than the slowest rotor the ranges allow (`T̂_r` above
        // `T_r·ℓ_max/r_min`) is the noise's — its ratio near 1 would blow the tail
        // `B/(1 − q)` up — and leaves nothing beyond the first of them.
        let physical = |d0: f32, d1: f32| {
            d0 > 0.0
                && d1 > 0.0
                && d1 < d0
                && self.tr_over_window * crate::num::ln_f32(d0 / d1) >= self.min / self.l_max
        };
        let d1 = if f.slid == 0 || physical(d0, d1) { d1 } else { 0.0 };
        let direct = f.axis == FitAxis::Direct;
        let measured = if direct && f.demagnetized && self.l_max > self.l_min && f.i_d_a > 0.0 {
            self.flux_linkage_scale(f, d0, d1, saturating)
        } else {
            None
        };
        // A saturating motor's rotor resistance is its first windows': their decay and the
        // flux linkage they read are of the same building flux (a decay, not yet the noise);
        // on the inductance scale that linkage reads within the range.
        let rr = if f.slid == 0 {
            rate * measured.map_or(built_inductance_scale, |l| l.limit(self.l_min, self.l_max))
        } else {
            f.first_rr_scale
        };
        if saturating && measured.is_some() && !settled && f.slid < FIT_SLIDE_WINDOWS_MAX {
            // The first window joins the sum before the windows; a new one opens.
            f.first_rr_scale = rr;
            f.pre_sum += self.slow_divider * s0;
            f.pre_steps =
                f.pre_steps.saturating_add(self.fit_window_steps.saturating_mul(self.slow_divider as u32));
            f.sums = [s1, s2, 0.0];
            f.slid += 1;
            f.done = false;
            return None;
        }
        if !finite_positive(rr) {
            return None;
        }
        let c = if direct { self.constant_v(f, d0, d1) } else { f32::NAN };
        // The curve's reading needs a rotor without flux at the enable and, at rest, the
        // settled constant part ([`Self::rotor_resistance_on_curve`]).
        f.constant_v = match (saturating && f.flux_free, direct) {
            (true, true) if measured.is_some() => c,
            (true, false) => 0.0,
            _ => f32::NAN,
        };
        let r_s = c / f.i_d_a;
        Some(Fitted {
            rr_scale: rr.limit(self.min, self.max),
            inductance_scale: measured.unwrap_or(l_now),
            inductance_measured: measured.is_some(),
            stator_resistance_ohm: finite_positive(r_s).then_some(r_s),
        })
    }

    /// The d-axis voltage's constant part `c = (S₀ − B)/W`, V: the first window's mean less
    /// its share of the geometric decay, `B = d₀/(1 − q)`, `q = d₁/d₀` ([`Self::fit`]'s sums).
    fn constant_v(&self, f: &RotorFit, d0: f32, d1: f32) -> f32 {
        let b = d0 / (1.0 - d1 / d0);
        (f.sums[0] - b) / self.fit_window_steps as f32
    }

    /// The stator's flux linkage the enable built, over the motor's `L_s·i_d`: the
    /// volt-seconds of the d-axis voltage less its constant part (the stator's drop, any
    /// offset), from the enable on — the fast steps before the windows as summed, the
    /// geometric decay from the first window on to its end, `B/(1 − q)` with
    /// `q = e^{−W/T_r} = d₁/d₀` and `B = d₀/(1 − q)` the first window's share; the constant
    /// part `c = (S₀ − B)/W`. Limited to the range on a linear motor, where it is the
    /// inductance scale; a saturating motor's is ℓ times the chord's ratio at the current
    /// asked (the twin's at ℓ = 1: ×1.027), which a limit to ℓ's range read as ℓ = 0.96
    /// ([`Fitted::inductance_scale`]). `None` if not finite and positive.
    fn flux_linkage_scale(&self, f: &RotorFit, d0: f32, d1: f32, saturating: bool) -> Option<f32> {
        let q = d1 / d0;
        let b = d0 / (1.0 - q);
        let c = self.constant_v(f, d0, d1);
        let volt_steps = f.pre_sum - c * f.pre_steps as f32 + self.slow_divider * b / (1.0 - q);
        let l = self.t_fast_over_ls * volt_steps / f.i_d_a;
        if !finite_positive(l) {
            None
        } else if saturating {
            Some(l)
        } else {
            Some(l.limit(self.l_min, self.l_max))
        }
    }

    /// A saturating motor's fit: one slow period's voltage sum `v` (V over its fast steps)
    /// and its mean measured d-axis current `i_d_a` added to the build's, both kept every
    /// `fit_sample_steps` periods while samples are left.
    fn sample_flux(&self, f: &mut RotorFit, v: f32, i_d_a: f32) {
        f.volts += v;
        f.amps += i_d_a;
        // Periods since the first slow step, this one included (≥ 1 here).
        let n = f.steps.saturating_sub(1);
        if n.is_multiple_of(self.fit_sample_steps)
            && let Some(sample) = f.flux_samples.get_mut(f.taken as usize)
        {
            *sample = FluxSample { volts: f.volts, amps: f.amps };
            f.taken += 1;
        }
    }

    /// A saturating motor's rotor resistance, × the motor file's, from its magnetizing fit on
    /// the machine whose inductances are `l` × the file's and whose magnetizing current of a
    /// flux ψ is `current_at_flux(ψ)/l` (the file's curve,
    /// [`crate::magnetics::MagnetizingChord::current_at_flux`]); `None` where it cannot be
    /// read (a rotor with flux at the enable, at rest a fit that did not measure the flux
    /// linkage, too few samples, a flux that never reaches [`FIT_CURVE_FLUX_FRACTION`]).
    ///
    /// The building flux is not one exponential on a curve, and no window ratio reads its
    /// rate (module docs); but the rotor's own equation does, whatever the curve. With the
    /// field on the d axis, i_q = 0 and the rotor without flux before the first slow step,
    /// `dψ_r/dt = −R_r·i_r = R_r·(i_d − i_m)` (T model; the Γ and inverse-Γ forms are its
    /// `L_ls = 0` and `L_lr = 0` cases), so
    ///
    /// `R_r = ψ_r(T) / ∫₀ᵀ (i_d − i_m(ψ_m(t))) dt`,
    ///
    /// with the branch's flux `ψ_m = ψ_s − L_ls·i_d` and `ψ_r = ψ_m + L_lr·(i_m − i_d)`: a
    /// quotient of the measured flux and the integral of the current that has not yet gone
    /// into magnetizing. The stator flux: at rest (d axis) `ψ_s(t) = ∫₀ᵗ (v_d − c) dt`, c the
    /// constant part the settled fit found; on a turning rotor (q axis, [`FitAxis`])
    /// `ψ_s = −v_q/ω_e`, each sample's mean at its middle, ω_e the field's mean speed. `∫i_d`
    /// is the measured current's (the reference moves in field weakening, and its step
    /// overshoots at speed), `∫i_m` trapezoids over the [`FIT_FLUX_SAMPLES`] samples, read up to where
    /// the stator flux first reaches [`FIT_CURVE_FLUX_FRACTION`] of the last sample's. On an
    /// exact build of the 300 W motor's saturating twin at rest (Γ form, R_r ×1 and ×1.5,
    /// ℓ 0.8 … 1.2) it reads within 0.5 % (unit test
    /// `a_saturating_motors_rotor_resistance_is_read_on_its_curve`). The current's step is
    /// in the samples: it leaves the rotor's flux at zero and puts the leakage's volt-seconds
    /// into the stator's (a build started at ψ_s = 0 read 9 % low).
    pub fn rotor_resistance_on_curve(
        &self,
        f: &RotorFit,
        l: f32,
        current_at_flux: impl Fn(f32) -> f32,
    ) -> Option<f32> {
        let (c, i_d) = (f.constant_v, f.i_d_a);
        let taken = (f.taken as usize).min(FIT_FLUX_SAMPLES);
        let samples = f.flux_samples.get(..taken)?;
        let t_slow_s = self.slow_divider * self.t_fast_s;
        let dt_s = self.fit_sample_steps as f32 * t_slow_s;
        // The field's mean speed over the fit (a q-axis fit's), electrical rad/s.
        let w_e = (f.field_rad + f.window_field_rad).abs() / (f.steps as f32 * t_slow_s);
        let direct = f.axis == FitAxis::Direct;
        if !(c.is_finite()
            && i_d > 0.0
            && taken >= 4
            && finite_positive(l)
            && (direct || finite_positive(w_e)))
        {
            return None;
        }
        // Each sample's time: at its end (d axis), at its middle (q axis), s.
        let time_s = |k: usize| ((k + 1) as f32 - if direct { 0.0 } else { 0.5 }) * dt_s;
        // The stator flux: at each sample's end from the volt-seconds less the constant
        // part (d axis), or over each sample as the back-EMF's mean over the field's speed,
        // `−v_q/ω_e`, at its middle (q axis).
        let volts = |k: usize| samples.get(k).map_or(0.0, |s| s.volts);
        let stator_flux = |k: usize| {
            if direct {
                self.t_fast_s * (volts(k) - c * time_s(k) / self.t_fast_s)
            } else {
                let before = k.checked_sub(1).map_or(0.0, volts);
                (before - volts(k)) / (dt_s / self.t_fast_s * w_e)
            }
        };
        let target = FIT_CURVE_FLUX_FRACTION * stator_flux(taken - 1);
        // `∫i_d dt` to a sample's end (d axis) or middle (q axis): the measured current's.
        let amps = |k: usize| samples.get(k).map_or(0.0, |s| s.amps);
        let charge = |k: usize| {
            let at_end = t_slow_s * amps(k);
            if direct { at_end } else { 0.5 * (at_end + t_slow_s * k.checked_sub(1).map_or(0.0, amps)) }
        };
        // `∫i_m dt` by trapezoids, from no magnetizing current at the start.
        let (mut before, mut t_before_s, mut magnetizing) = (0.0, 0.0, 0.0);
        for k in 0..taken {
            let psi_s = stator_flux(k);
            let psi_m = psi_s - l * self.l_ls_h * i_d;
            let i_m = current_at_flux(psi_m) / l;
            magnetizing += 0.5 * (before + i_m) * (time_s(k) - t_before_s);
            (before, t_before_s) = (i_m, time_s(k));
            if psi_s >= target {
                let psi_r = psi_m + l * self.l_lr_h * (i_m - i_d);
                let rr = psi_r / ((charge(k) - magnetizing) * self.rr_ohm);
                return finite_positive(rr).then(|| rr.limit(self.min, self.max));
            }
        }
        None
    }

    /// Estimating anything at all (either range is not a single value).
    pub fn fit_active(&self) -> bool {
        self.max > self.min || self.l_max > self.l_min
    }

    /// The magnetizing fit is still to come (the drive keeps magnetizing until it is done).
    pub fn fit_pending(&self, f: &RotorFit) -> bool {
        self.fit_active() && !f.done
    }
}
