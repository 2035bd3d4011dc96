//! `design tune` (issue 21): a drive file for a motor — its current and speed gains
//! synthesised and the result certified — from a template drive file (the board, the PWM,
//! the protection, the certificate's minima and operating range) and a motor file (a
//! shipped motor, or one `hil-sim identify` wrote, whose `[identification]` intervals widen
//! the certified box).
//!
//! **Current loops**, [`CurrentDesign`]: PI (the default; in the template's frame, stationary or
//! synchronous — the same rule, checked in that frame) or ICAD (stationary frame only).
//!
//! *ICAD* (`--current icad`): seed 002 eq. (20)'s structure — PI × a lag pair — placed from
//! the top electrical rotor speed ω_h = `[certify] omega_r_max_rad_s` by the rules of
//! [`icad_law`] (double lag zero at −ω_h, lag poles ω_h(−1/8 ± j/2), PI zero at −2.5·ω_h:
//! eq. (20) exactly at ω_h = 400 rad/s); its one free gain k_p is the one with the largest
//! [`robustness`] over the box — the smallest ratio of any current margin (phase, gain, γh;
//! continuous and sampled; every corner) to its minimum, i.e. the point farthest inside the
//! certificate's region. On the DeLorenzo motor and the shipped box that is k_p = 339.9 V/A,
//! 4 % above the paper's Bode-shaped 326.5 (test `tuned_icad_is_at_least_as_robust_as_eq20`).
//!
//! *PI*: below the rotor's corner the stator sees `R_s + R_R + s·σL_s` (the rotor branch is
//! resistive for ω ≫ 1/T_r); the PI's zero cancels that pole: `k_p = ω_c·σL_s`,
//! `k_i = ω_c·(R_s + R_R)`, an integrator loop of crossover ω_c on the nominal motor. ω_c
//! is the largest of a geometric search from 2π·f_pwm/5 down (ratio [`SEARCH_RATIO`]) for
//! which every current check of the certificate passes on every corner of the box — the
//! sampled ones (delay, ZOH, the f32 coefficients) bound it from above. The search runs in
//! both frames (`current_frame`) and takes the faster crossover, the template's frame on a
//! tie: the field frame passes where the stationary frame's phase error at the top electrical
//! speed fails (a 3 hp 220 V motor at 10 kHz, issue 49), or passes only far lower (a 116 W
//! 8-pole motor at 4 kHz: 54 rad/s against 1 753); the file records the frame taken. A
//! stationary-frame crossover also has to leave a steady error at the top electrical speed,
//! |S(jω_r,max)| of the loop on the stator with the back-EMF fed forward, within what the
//! drive's current trim makes up ([`controller_core::drive::CURRENT_TRIM_RANGE`] of the
//! current limit): a stationary PI follows the field's rotation only through its gain, and
//! the two frames' certificates tie where it does not (an 895 W motor at 4 kHz: the same
//! gains in both frames, the stationary PI 1.1 A off a 4 A reference at 100 Hz and its
//! drive outrun by the generating load at the top speed, the field frame's passing).
//!
//! **Speed loop**: saturated P (seed 002 eq. (21)), `k_p = J·ω_s`: the speed loop's
//! crossover ω_s on the nominal inertia, at most ω_c/[`SPEED_BELOW_CURRENT`], and at most
//! what keeps the encoder's speed resolution from shaking the torque: `k_p·Δω_q ≤`
//! [`ENCODER_NOISE_FRACTION`]`·τ_max`, with `Δω_q = 2π/(4·lines)/(window·T_slow)` one count
//! over the speed estimate's window (the linear certificate cannot see quantisation; the
//! nonlinear campaign's torque-ripple criterion can). Without an encoder (`[controller]
//! speed_feedback = "sensorless"`) the observer's estimate carries the current sensors' noise
//! instead, and its peak to peak ([`observer_speed_peak_to_peak_rad_s`]) takes the count's
//! place in the same rule ([`SpeedNoise`]). Then the largest of the same kind of
//! search for which the speed checks pass with the writable range `[k_p/2, 2·k_p]` (what
//! the link may set). τ_max: the template's (the torque the application asks), at most what
//! the template's current limit gives at its flux reference,
//! `1.5·p·(L_m/L_r)·ψ*·√(i_max² − (ψ*/L_m)²)`; the writable range `[τ_max/20, τ_max]`.
//! (τ_max at that current limit — 5.05 N·m on the DeLorenzo motor against the template's 2
//! — fails the nonlinear campaign's tracking at every corner: the loops then run at the
//! current limit and the flux sags to 0.9 of its model.)
//!
//! **Position loop**: `k = ω_B/`[`POSITION_BELOW_SPEED`], ω_B the speed loop's bandwidth
//! on the heaviest inertia ([`heaviest_speed_bandwidth`]): critically damped there; the
//! certificate checks the sampled cascade. The speed limit `omega_max_rad_s` is the
//! template's.
//!
//! **Field angle**: the slip on the measured q current (`slip_current = "measured"`)
//! unless the template states its choice — the rotor slips at the current it carries, and
//! the reference's slip turns the field away from the rotor's flux wherever the loops lag
//! their reference (at the voltage limit; a stationary PI at the top field frequency).
//!
//! **Box**: the template's factors, widened to hold the motor file's `[identification]`
//! intervals (relative to its nominal values; L_s, L_r and L_m's widest together) and the
//! rotor-resistance range the drive's estimate may take (`rotor_resistance_range`); that R_r
//! hull is written back as the file's `rotor_resistance_range` (unless the estimate is off:
//! a range of one value). The inductances' box and `inductance_range` likewise, and a
//! template that does not state `inductance_range` gets the box's: a spread the drive does
//! not estimate is a flux error of that size.

use crate::certify::{CertifySpec, Check, certify_current, certify_speed, current_passes};
use crate::pi_region::SpeedRegions;
use controller_core::current::CurrentLaw;
use controller_core::discretize::ContinuousSection;
use controller_core::drive::{CurrentFrame, DriveSpec, SlipCurrent, SpeedFeedback};
use controller_core::motor::MotorParams;
use controller_core::speed::SpeedLaw;
use std::path::Path;

mod current;
mod screen;
mod speed;
mod write;

pub use current::*;
pub use screen::*;
pub use speed::*;
use write::write;

/// The current controller [`tune`] synthesises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CurrentDesign {
    /// Stationary-frame PI, the fastest crossover the certificate passes.
    #[default]
    Pi,
    /// ICAD: PI × lag pair placed from the top rotor speed ([`icad_law`]), its gain the most
    /// robust over the box.
    Icad,
}

impl std::str::FromStr for CurrentDesign {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "pi" => Ok(Self::Pi),
            "icad" => Ok(Self::Icad),
            other => Err(format!("`{other}` is neither pi nor icad")),
        }
    }
}

/// The controllers [`tune`] synthesises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Structure {
    /// The current loops'.
    pub current: CurrentDesign,
    /// The speed loop's.
    pub speed: SpeedDesign,
}

/// The speed controller [`tune`] synthesises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpeedDesign {
    /// Saturated P (seed 002 eq. (21)), the gains the link may rewrite.
    #[default]
    SaturatedP,
    /// PI → torque, seed 000's regions ([`speed_pi`]).
    Pi,
    /// The first of saturated P and PI whose predicted response meets the file's
    /// `[requirements]` over the box ([`predicted_misses`]); refused, naming what each
    /// misses, when neither does.
    Auto,
}

impl std::str::FromStr for SpeedDesign {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "p" => Ok(Self::SaturatedP),
            "pi" => Ok(Self::Pi),
            "auto" => Ok(Self::Auto),
            other => Err(format!("`{other}` is none of p, pi, auto")),
        }
    }
}

/// A motor file's `[identification]` intervals that the box must hold.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Intervals {
    /// R_s, Ω.
    pub rs_ohm: Option<[f64; 2]>,
    /// R_r, Ω.
    pub rr_ohm: Option<[f64; 2]>,
    /// L_s, L_r, L_m, H.
    pub inductances_h: [Option<[f64; 2]>; 3],
    /// J, kg·m².
    pub j_kgm2: Option<[f64; 2]>,
}

impl Intervals {
    /// The `[identification]` table of a motor file's text (`None` without one).
    pub fn parse(text: &str) -> Result<Option<Self>, String> {
        let table: toml::Table = toml::from_str(text).map_err(|e| e.to_string())?;
        let Some(id) = table.get("identification").and_then(|v| v.as_table()) else {
            return Ok(None);
        };
        let pair = |key: &str| -> Result<Option<[f64; 2]>, String> {
            match id.get(key) {
                None => Ok(None),
                Some(v) => {
                    let a = v.as_array().ok_or(format!("identification.{key}: not an interval"))?;
                    let x =
                        |i: usize| a.get(i).and_then(|x| x.as_float().or(x.as_integer().map(|n| n as f64)));
                    match (a.len(), x(0), x(1)) {
                        (2, Some(lo), Some(hi))
                            if lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi =>
                        {
                            Ok(Some([lo, hi]))
                        }
                        _ => Err(format!("identification.{key}: not an interval [lo, hi] with 0 ≤ lo ≤ hi")),
                    }
                }
            }
        };
        Ok(Some(Self {
            rs_ohm: pair("rs_ohm")?,
            rr_ohm: pair("rr_ohm")?,
            inductances_h: [pair("ls_h")?, pair("lr_h")?, pair("lm_h")?],
            j_kgm2: pair("j_kgm2")?,
        }))
    }
}

/// The result of [`tune`].
#[derive(Clone, Debug)]
pub struct Tuned {
    /// The controllers' structure.
    pub structure: Structure,
    /// [`robustness`] of the current checks: 1 is the certificate's boundary.
    pub current_robustness: f64,
    /// The drive file's text.
    pub text: String,
    /// The requirements the chosen speed law is predicted to miss over the box, each with
    /// its worst run (empty: all met; only an explicit `--speed` may leave some).
    pub predicted_misses: Misses,
    /// Its drive.
    pub spec: DriveSpec,
    /// Its certificate.
    pub certify: CertifySpec,
    /// The current loops' crossover on the nominal motor, rad/s.
    pub omega_c_rad_s: f64,
    /// The speed loop's crossover on the nominal inertia, rad/s.
    pub omega_s_rad_s: f64,
    /// Every check of the certificate (all pass).
    pub checks: Vec<Check>,
    /// Where the speed law comes from, in words (the file's header and `design tune`'s
    /// summary): the P's crossover, seed 000's own PI, or a point the search found.
    pub speed_origin: String,
    /// The speed law's drive met the requirements on the corner runs of tune's campaigns
    /// (`TuneCampaigns`) in software in the loop before the file was written (`--speed
    /// auto`; a forced law is not run).
    pub met_in_sil: bool,
    /// Those runs in words: `the 64 corner runs of the 1.00 s and the 6.38 s campaigns`
    /// (drive.toml's).
    pub sil_runs: String,
    /// Those campaigns, with the written speed law, when it met them there
    /// ([`Self::met_in_sil`]; empty otherwise): every one of their corner runs passed. A
    /// campaign equal to one of them but for its number of runs has the same corner runs —
    /// the simulation is deterministic — and a caller that runs it need not run them again
    /// ([`Self::passed_corner_runs_of`]).
    pub sil_campaigns: Vec<hil_sim::campaign::Campaign>,
    /// Every value the tuned file changed from the template's, `key: old → new`.
    pub changes: Vec<String>,
}

fn hull(f: [f64; 2], nominal: f64, interval: Option<[f64; 2]>) -> [f64; 2] {
    match interval {
        Some([lo, hi]) if nominal > 0.0 => [f[0].min(lo / nominal), f[1].max(hi / nominal)],
        _ => f,
    }
}

/// The TOML text states `key` in its `[table]` (a value serde's default would otherwise
/// stand for).
fn template_states(text: &str, table: &str, key: &str) -> bool {
    text.parse::<toml::Table>()
        .ok()
        .and_then(|t| t.get(table).and_then(toml::Value::as_table).map(|c| c.contains_key(key)))
        .unwrap_or(false)
}

/// The speed checks among `checks` passing (the names the certificate gives them).
fn speed_ok(checks: &[Check]) -> bool {
    checks
        .iter()
        .filter(|c| c.name.starts_with("speed") || c.name.starts_with("sampled speed"))
        .all(|c| c.pass)
}

/// A motor file as written (a shipped motor's text under `<builtin name>`), for
/// [`tune_file`].
#[derive(Clone, Copy, Debug)]
pub struct MotorFile<'a> {
    /// Where it was read from.
    pub path: &'a Path,
    /// Its text.
    pub text: &'a str,
}

/// Tune `motor` on the template drive file (`template_text`, read from `template_path`).
pub fn tune(
    template_path: &Path,
    template_text: &str,
    motor: &MotorParams,
    intervals: Option<&Intervals>,
    structure: Structure,
) -> Result<Tuned, String> {
    tune_with(template_path, template_text, motor, None, intervals, structure)
}

/// [`tune`] the motor of a motor file. A motor whose magnetizing branch saturates
/// (`[motor.saturation]`: `hil-sim identify --curve`'s, or a data sheet's) is designed for as
/// the drive runs it — its linear model at the curve's chord at the template's
/// `flux_ref_wb` ([`drive_file::motor::MotorTable::drive_model`]), the curve as the drive's
/// table — and its `[motor]` table goes into the drive file as written, form, values and
/// curve. Found by trying: tuning on an identified saturating motor wrote its linear model
/// at the rated chord and removed the curve, so the drive ran linear on a motor that is not.
pub fn tune_file(
    template_path: &Path,
    template_text: &str,
    motor: MotorFile<'_>,
    intervals: Option<&Intervals>,
    structure: Structure,
) -> Result<Tuned, String> {
    let (params, _) = drive_file::motor::parse_model(motor.path, motor.text).map_err(|e| e.to_string())?;
    tune_with(template_path, template_text, &params, Some(motor), intervals, structure)
}

fn tune_with(
    template_path: &Path,
    template_text: &str,
    motor: &MotorParams,
    written: Option<MotorFile<'_>>,
    intervals: Option<&Intervals>,
    structure: Structure,
) -> Result<Tuned, String> {
    let file = drive_file::DriveFile::parse(template_path, template_text).map_err(|e| e.to_string())?;
    let mut cert = file.certify.ok_or_else(|| {
        format!(
            "{}: the template needs a [certify] table (the certificate's minima and range)",
            template_path.display()
        )
    })?;
    let mut spec = file.spec;
    // The slip on the q current the rotor saw, unless the template states its choice: the
    // rotor's slip follows the current it carries, and where the loops do not follow their
    // reference (at the voltage limit, or a stationary-frame PI at the top field frequency)
    // the reference's slip turns the field away from the rotor's flux (a 7.3 kW motor at
    // 4 kHz braking at its top speed: the rotor's flux swung 0.37–0.57 Wb while the model
    // held 0.45–0.51, and the speed ran away; population test
    // `a_braking_drive_turns_its_field_at_the_slip_its_rotor_sees`).
    if !template_states(template_text, "controller", "slip_current") {
        spec.slip_current = SlipCurrent::Measured;
    }
    if spec.current_frame == CurrentFrame::Synchronous && structure.current == CurrentDesign::Icad {
        return Err(
            "the template's current frame is synchronous: ICAD's lag pair is placed at the stationary \
                    frame's top speed ω_h, where the field frame's currents are constant — take the PI \
                    (--current pi), or a stationary-frame template"
                .into(),
        );
    }
    // A saturating motor file: its table, and its model and curve as the drive runs them.
    let saturating = match written {
        Some(f) => {
            drive_file::motor::drive_model_of(f.path, f.text, spec.flux_ref_wb).map_err(|e| e.to_string())?
        }
        None => None,
    };
    // The identification's intervals are of the values as written (a saturating motor's
    // inductances at the point it was identified at), so the box's factors are taken
    // against those; the drive runs at its own flux reference's chord.
    let as_written = *motor;
    let chord;
    let motor = match &saturating {
        Some((m, magnetizing, _)) => {
            spec.magnetizing = Some(*magnetizing);
            chord = *m;
            &chord
        }
        None => motor,
    };
    spec.motor = *motor;
    if let Some(iv) = intervals {
        cert.rs_factor = hull(cert.rs_factor, motor.rs_ohm(), iv.rs_ohm);
        cert.rr_factor = hull(cert.rr_factor, motor.rr_ohm(), iv.rr_ohm);
        for (nominal, i) in
            [as_written.ls_h(), as_written.lr_h(), as_written.lm_h()].into_iter().zip(iv.inductances_h)
        {
            cert.inductance_factor = hull(cert.inductance_factor, nominal, i);
        }
        cert.j_factor = hull(cert.j_factor, motor.j_kgm2(), iv.j_kgm2);
    }
    // One rotor-resistance interval for the box and the drive's own estimate
    // (`rotor_resistance_range`, × the motor file's R_r; by default the rotor measured cold
    // up to ≈ 120 K hotter): their hull, written into both. Found by trying: the 3 300 V
    // template's box [1, 1.2] left its flying start's guess, the estimate range's middle
    // ×1.22, outside what the certificate covered; and the walkthrough's identified motor
    // widened the box down to ×0.921 where the estimate stopped at ×1, so that corner ran
    // detuned and missed the campaign's tracking bound (5.80 of 5.78 rad/s). A range of one
    // value is the estimate switched off: the box holds that value, the range stays.
    let [lo, hi] = spec.rotor_resistance_range;
    cert.rr_factor = [cert.rr_factor[0].min(lo), cert.rr_factor[1].max(hi)];
    if lo < hi {
        spec.rotor_resistance_range = cert.rr_factor;
    }
    // The inductances likewise, with one difference: their estimate is off by default
    // (`inductance_range` [1, 1]). A box with an inductance spread the drive does not
    // estimate leaves the flux off by that spread (the population's ±5 % box against the
    // default ±5 % flux accuracy: the largest family of its failures), so a template that
    // does not state the range gets the box's; one that states a single value keeps it off.
    let [l_lo, l_hi] = spec.inductance_range;
    let stated = template_states(template_text, "controller", "inductance_range");
    if cert.inductance_factor[0] < cert.inductance_factor[1] && (l_lo < l_hi || !stated) {
        cert.inductance_factor = [cert.inductance_factor[0].min(l_lo), cert.inductance_factor[1].max(l_hi)];
        spec.inductance_range = cert.inductance_factor;
    }
    // The stator seen below the rotor's corner.
    let k = motor.lm_h() / motor.lr_h();
    let sigma_ls = motor.ls_h() - motor.lm_h() * k;
    let r = motor.rs_ohm() + motor.rr_ohm() * k * k;
    let top = 2.0 * std::f64::consts::PI * spec.pwm_frequency_hz / 5.0;
    let bottom = top / 100.0;
    let omega_c = match structure.current {
        CurrentDesign::Pi => {
            // The template's frame first, then the other: a stationary-frame PI tracks the
            // field's rotation only through its gain (its phase error grows with ω_e/ω_c), a
            // field-frame PI sees constant currents but its decoupling error grows with ω_e
            // times the PWM delay — which one passes depends on the motor and the PWM rate.
            let law = |omega_c: f64| CurrentLaw {
                kp_v_per_a: omega_c * sigma_ls,
                ki_v_per_as: omega_c * r,
                lag: None,
            };
            // Both frames searched, the faster crossover taken (the template's frame on a
            // tie): the first frame that passed at all was taken before, and a stationary PI
            // that passes at 54 rad/s where the field frame passes at 1 753 (a 116 W 8-pole
            // motor at 4 kHz: its currents lag their references at every speed, and the
            // open-phase check reads that as a lost phase) is a frame that passes, not one
            // that works.
            let first = spec.current_frame;
            let mut found: Option<(f64, CurrentFrame)> = None;
            for frame in [first, other_frame(first)] {
                spec.current_frame = frame;
                let grid = candidates(top, bottom).filter(|&w| found.is_none_or(|(best, _)| w > best));
                // A stationary-frame PI follows the field's rotation only through its gain: at the
                // top electrical speed its steady error, |S(jω)| of the loop on the stator with the
                // back-EMF fed forward (the delay advanced away at ω_e), must lie within what the
                // current trim makes up (`CURRENT_TRIM_RANGE` of the current limit).
                let steady = |w: f64| {
                    frame == CurrentFrame::Synchronous
                        || stationary_steady_error(law(w), r, sigma_ls, cert.omega_r_max_rad_s)
                            <= f64::from(controller_core::drive::CURRENT_TRIM_RANGE)
                };
                let pass =
                    |w: f64| Ok::<_, String>(steady(w) && current_passes(&with_law(&spec, law(w)), &cert)?);
                if let Some(w) = search_down(grid, pass)? {
                    found = Some((w, frame));
                }
            }
            let found = found.map(|(omega_c, frame)| {
                spec.current_frame = frame;
                omega_c
            });
            let omega_c = found.ok_or_else(|| {
                format!(
                    "no current-loop crossover from {top:.0} down to {bottom:.0} rad/s passes the certificate on \
                     every corner in either frame (the box or the PWM rate asks too much)"
                )
            })?;
            spec.current_law = law(omega_c);
            omega_c
        }
        CurrentDesign::Icad => {
            let omega_h = cert.omega_r_max_rad_s;
            let kp = icad_gain(&mut spec, &cert, omega_h, [bottom * sigma_ls, top * sigma_ls])?;
            spec.current_law = icad_law(kp, omega_h);
            crate::icad::analyse(motor, &spec.current_law, omega_h)
                .channel
                .crossover_rad_s
                .unwrap_or(kp / sigma_ls)
        }
    };
    // Speed: saturated P; τ_max from the current limit at the flux reference.
    let psi = spec.flux_ref_wb;
    let i_d = psi / motor.lm_h();
    let i_q = (spec.i_ref_max_a.powi(2) - i_d * i_d).max(0.0).sqrt();
    let tau_limit = motor.torque_factor() * psi * i_q;
    let template_tau = match file.spec.speed_law {
        SpeedLaw::SaturatedP { tau_max_nm, .. } => tau_max_nm,
        SpeedLaw::PiTorque { limit, .. } => limit,
        SpeedLaw::PiIq { limit, .. } => motor.torque_factor() * psi * limit,
    };
    let tau_max = tau_limit.min(template_tau);
    if !(tau_max.is_finite() && tau_max > 0.0) {
        return Err(format!(
            "the current limit {} A cannot magnetize the motor to ψ* = {psi} Wb (i_d = {i_d:.3} A): no torque left",
            spec.i_ref_max_a
        ));
    }
    let j = motor.j_kgm2();
    let t_slow = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
    // The speed measurement the law closes on, and its noise's cap on k_p.
    let noise = match spec.speed_feedback {
        SpeedFeedback::Sensorless => {
            let noise_rms_a = hil_sim::sensors::SensorModel::realistic_for_trip(0, spec.protection.i_trip_a)
                .current_noise_rms_a;
            SpeedNoise::Observer {
                noise_rms_a,
                peak_to_peak_rad_s: observer_speed_peak_to_peak_rad_s(
                    motor,
                    psi,
                    noise_rms_a,
                    spec.pwm_frequency_hz,
                    spec.slow_divider,
                ),
            }
        }
        SpeedFeedback::Encoder | SpeedFeedback::EncoderRideThrough => {
            SpeedNoise::Encoder { lines: file.encoder_lines(), t_slow_s: t_slow }
        }
    };
    let kp_noise = noise.kp_limit(tau_max);
    let omega_s_top = (omega_c / SPEED_BELOW_CURRENT).min(kp_noise / j);
    let speed_at = |spec: &mut DriveSpec, cert: &mut CertifySpec, omega_s: f64| {
        let kp = j * omega_s;
        spec.speed_law = SpeedLaw::SaturatedP { kp, tau_max_nm: tau_max };
        cert.speed_kp_writable = [0.5 * kp, 2.0 * kp];
        cert.speed_tau_max_nm_writable = [tau_max / 20.0, tau_max];
    };
    // The current loops are fixed and pass: only the speed checks move with k_p (the
    // position check waits for the position gain, set from the result).
    let grid = candidates(omega_s_top, omega_c / (SPEED_BELOW_CURRENT * 1000.0));
    let omega_s = search_down(grid, |w| {
        let (mut spec, mut cert) = (spec, cert);
        speed_at(&mut spec, &mut cert, w);
        Ok(speed_ok(&certify_speed(&spec, &cert)?))
    })?
    .ok_or("no speed-loop gain passes the certificate")?;
    speed_at(&mut spec, &mut cert, omega_s);
    // The position gain: a quarter of the heaviest speed loop's bandwidth, lowered (the same
    // geometric search) until the sampled position loop around every writable speed gain
    // passes — the quarter alone failed the tuned file's own certificate on a small motor
    // behind a 3 300 V template's slow loop (found by trying).
    let position_ok =
        |checks: &[Check]| checks.iter().filter(|c| c.name.starts_with("sampled position")).all(|c| c.pass);
    let k_first = heaviest_speed_bandwidth(omega_s, &cert) / POSITION_BELOW_SPEED;
    spec.position.k_per_s = search_down(candidates(k_first, k_first / 1000.0), |k| {
        let mut spec = spec;
        spec.position.k_per_s = k;
        Ok(position_ok(&certify_speed(&spec, &cert)?))
    })?
    .ok_or("no position-loop gain passes the certificate")?;
    // The protection as the written file derives it: its stall and following times follow
    // the speed loop's torque limit (`drive_file::drive::protection_with_defaults`), which
    // tune may have lowered from the template's — the drive run in software in the loop
    // below is the one written (the population's members 007 and 010 were confirmed with
    // times 0.3–3 % off their files', and `population run` ran their corner runs twice).
    let table = saturating.as_ref().map(|(_, _, t)| t);
    let (provisional, _) = write(template_text, template_path, &spec, table, &cert, omega_c, "")?;
    spec.protection = drive_file::DriveFile::parse(Path::new("<tuned>"), &provisional)
        .map_err(|e| format!("tuned file: {e}"))?
        .spec
        .protection;
    // The requirements over the box, predicted from the speed law alone (the campaign then
    // judges the whole drive): on the drive's rated bus, or 310 V within its range.
    let vdc = prediction_bus_v(&file);
    let p_misses = predicted_misses(&spec, &cert, &file, vdc)?;
    // The link may lower k_p only as far as the requirements still hold (a P law's droop
    // grows as 1/k_p): the least writable k_p is the lowest of [k_p/2, k_p] that meets them.
    if p_misses.is_empty() {
        cert.speed_kp_writable[0] = least_writable_kp(&spec, &cert, &file, vdc)?;
    }
    // A P law predicted to meet them is run like a searched PI: its drive on the corner runs
    // of tune's campaigns in software in the loop (the prediction has no current loops, field
    // orientation or sensors: on 8 of the population's 87 drives a law predicted to meet the
    // requirements missed them in the campaign).
    let campaigns = TuneCampaigns::new(&spec, &cert, &file, vdc);
    let p_sil = match structure.speed {
        SpeedDesign::Auto if p_misses.is_empty() => campaigns.sil_misses()?.map(|m| m.words),
        _ => None,
    };
    let met_in_sil_words = format!(", met on {} in SIL", campaigns.words());
    let p_origin = format!("crossover {omega_s:.1} rad/s on the nominal inertia");
    let (speed_design, predicted, speed_origin) = match structure.speed {
        SpeedDesign::SaturatedP => (SpeedDesign::SaturatedP, p_misses, p_origin),
        SpeedDesign::Auto if p_misses.is_empty() && p_sil.is_none() => {
            (SpeedDesign::SaturatedP, p_misses, format!("{p_origin}{met_in_sil_words}"))
        }
        SpeedDesign::Pi | SpeedDesign::Auto => {
            let js = [j * cert.j_factor[0], j * cert.j_factor[1]];
            let minima = [cert.phase_margin_deg_min, cert.gain_margin_db_min];
            let regions = SpeedRegions::new(js, motor.b_nms(), t_slow, minima)?;
            let pi = SpeedPiSearch {
                regions: &regions,
                omega_b_rad_s: heaviest_speed_bandwidth(omega_s, &cert),
                kp_max: kp_noise,
                tau_max_nm: tau_max,
            };
            let choice = pi.choose(&spec, &cert, &campaigns)?;
            if structure.speed == SpeedDesign::Auto && !choice.misses.is_empty() {
                let p_kp = law_gains(&spec.speed_law).0;
                let p_why = match &p_sil {
                    Some(why) => format!(
                        "saturated P (k_p {p_kp:.4e}) is predicted to meet them, but its drive misses them in \
                         software in the loop on {}: {why}",
                        campaigns.words()
                    ),
                    None => format!("saturated P (k_p {p_kp:.4e}) misses {}", describe(&p_misses)),
                };
                return Err(format!(
                    "no speed law meets the requirements over the box (predicted on the ideal actuator, {vdc:.0} V): \
                     {p_why}; {} — relax [requirements], or take a smaller box",
                    pi.refusal(&choice, &noise),
                ));
            }
            spec.speed_law = choice.law;
            let origin = if choice.searched {
                let before = match &choice.sil_missed {
                    Some((l, why)) => {
                        format!("; before it, {} was predicted to meet them and missed {why}", gains_words(l))
                    }
                    None => String::new(),
                };
                format!(
                    "inside seed 000's regions without the P's bandwidth floor: the deepest point meeting \
                     [requirements] of {} tried{}{before}",
                    choice.tried, met_in_sil_words
                )
            } else {
                let sil = if choice.misses.is_empty() { met_in_sil_words.as_str() } else { "" };
                format!(
                    "seed 000's regions, the deepest point with a bandwidth ≥ {:.1} rad/s on every inertia{sil}",
                    pi.omega_b_rad_s
                )
            };
            (SpeedDesign::Pi, choice.misses, origin)
        }
    };
    // `--speed auto` writes only a law whose drive met them on the corner runs; a forced PI
    // whose prediction meets them was run too (`SpeedPiSearch::choose`).
    let met_in_sil =
        predicted.is_empty() && (structure.speed == SpeedDesign::Auto || speed_design == SpeedDesign::Pi);
    let structure = Structure { speed: speed_design, ..structure };
    let (text, changes) = write(template_text, template_path, &spec, table, &cert, omega_c, &speed_origin)?;
    // The file as written, read back and certified whole.
    let back =
        drive_file::DriveFile::parse(Path::new("<tuned>"), &text).map_err(|e| format!("tuned file: {e}"))?;
    let back_cert = back.certify.ok_or("tuned file lost its [certify]")?;
    // `certify`'s checks, the current loops' first: their robustness without a second run.
    let current_checks = certify_current(&back.spec, &back_cert)?;
    let current_robustness = robustness(&current_checks).0;
    let mut checks = current_checks;
    checks.extend(certify_speed(&back.spec, &back_cert)?);
    if let Some(c) = checks.iter().find(|c| !c.pass) {
        return Err(format!("the tuned file fails `{}` at {} (as written)", c.name, c.corner));
    }
    Ok(Tuned {
        structure,
        predicted_misses: predicted,
        current_robustness,
        text,
        spec: back.spec,
        certify: back_cert,
        omega_c_rad_s: omega_c,
        omega_s_rad_s: omega_s,
        checks,
        speed_origin,
        met_in_sil,
        sil_runs: campaigns.words(),
        sil_campaigns: if met_in_sil { campaigns.with_law(&spec.speed_law).campaigns() } else { Vec::new() },
        changes,
    })
}

impl Tuned {
    /// Whether `c`'s corner runs ([`hil_sim::campaign::CORNER_RUNS`], its first) are runs
    /// this tune ran and passed: `c` is one of [`Self::sil_campaigns`] but for its number of
    /// runs (every other field equal: the drive as written and read back, the box, bus,
    /// run length, seed, sensors and requirements), unsharded, with at least those runs.
    pub fn passed_corner_runs_of(&self, c: &hil_sim::campaign::Campaign) -> bool {
        use hil_sim::campaign::{CORNER_RUNS, Campaign};
        c.runs >= CORNER_RUNS
            && c.shard == (0, 1)
            && self.sil_campaigns.contains(&Campaign { runs: CORNER_RUNS, ..*c })
    }
}

/// |S(jω)| = |1/(1 + C(jω)·G(jω))| of a stationary-frame PI `law` ([`CurrentLaw::response`])
/// on the stator seen with the back-EMF fed forward, G = 1/(r + jω·σL_s): the share of a
/// current reference at electrical speed ω the loop leaves as steady error.
fn stationary_steady_error(law: CurrentLaw, r_ohm: f64, sigma_ls_h: f64, omega_rad_s: f64) -> f64 {
    use controller_core::discretize::Complex;
    let w = omega_rad_s.abs().max(1e-9);
    let loop_gain = law.response(w) / Complex::new(r_ohm, w * sigma_ls_h);
    1.0 / (1.0 + loop_gain).norm()
}

#[cfg(test)]
mod tests;
