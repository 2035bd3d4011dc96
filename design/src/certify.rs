//! Gain certification: the drive's constants (a drive file's `[certify]` table, e.g. the
//! firmware's `drive.toml`) checked against declared parameter intervals before they reach
//! the firmware.
//!
//! * **Current loops** (seed 002): on every corner of the box `R_s × rs_factor`,
//!   `R_r × rr_factor`, `(L_s, L_r, L_m) × inductance_factor`, at `omega_r_max_rad_s`:
//!   phase margin, the smaller of the gain-increase/-reduction margins, and the structural
//!   margin of γh₂ to (1, 0) against their minima; and full 2×2 closed-loop stability
//!   (eigenvalues) for every ω_r in 0…omega_r_max in 5 rad/s steps.
//! * **Speed loop** (seed 000, Kharitonov): with ideal current loops the torque → speed
//!   plant is `n/(J s + B)` (n = 1 for torque laws, n = K_t = (3/2)p(L_m/L_r)ψ* for i_q
//!   laws). The closed-loop polynomial `J s² + (B + k_p n) s + k_i n` (PI) or
//!   `J s + B + k_p n` (P) has each coefficient depending on one uncertain parameter, so
//!   its interval form is exact and Kharitonov's four polynomials decide robust stability
//!   over `J × j_factor`.
//! * **The sampled loops** ([`crate::sampled`]): the same checks on the loops as the drive
//!   runs them — zero-order hold, one PWM period of computational delay and the drive's
//!   1.5·T·ω_e advance, the controllers' f32 coefficients — on every corner: the closed
//!   loop's spectral radius over 0…omega_r_max, and the phase, gain and γh margins at
//!   omega_r_max against the same minima; the speed loop at the slow period with the
//!   encoder's speed window and one slow period of torque delay, over a grid of J (and of
//!   k_p over the writable range); and the position loop closed around it
//!   ([`crate::sampled::SpeedLoop::position_matrix`]) over the same grid. A PWM rate too slow for the current law, or a speed gain
//!   the sampled loop cannot take, fails here although the continuous checks pass.

use crate::icad::{IcadReport, analyse_in, closed_loop_abscissa_in};
use crate::kharitonov::IntervalPoly;
use controller_core::current::CurrentControllerConfig;
use controller_core::drive::{CurrentFrame, DriveSpec};
use controller_core::motor::MotorParams;
use controller_core::speed::SpeedLaw;
use std::path::Path;

pub use drive_file::certify::Certify as CertifySpec;

/// Load a drive file with a `[certify]` table: the drive and its certification intervals.
pub fn load(path: &Path) -> Result<(DriveSpec, CertifySpec), String> {
    let text = drive_file::source::read(path).map_err(|e| e.to_string())?;
    parse(path, &text)
}

/// Parse drive-file text read from `path`; it must have a `[certify]` table.
pub fn parse(path: &Path, text: &str) -> Result<(DriveSpec, CertifySpec), String> {
    let d = drive_file::DriveFile::parse(path, text).map_err(|e| e.to_string())?;
    let c = d.certify.ok_or_else(|| format!("{}: no [certify] table to check against", path.display()))?;
    Ok((d.spec, c))
}

/// One check of the certification.
#[derive(Clone, Debug, PartialEq)]
pub struct Check {
    /// What is checked.
    pub name: String,
    /// Parameter corner (or "all" for the speed loop).
    pub corner: String,
    /// Measured value (None: the quantity does not exist, e.g. no phase crossover).
    pub value: Option<f64>,
    /// Required bound.
    pub limit: f64,
    /// Passed?
    pub pass: bool,
}

fn corner_motor(m: &MotorParams, rs: f64, rr: f64, l: f64) -> Result<MotorParams, String> {
    m.scaled(rs, rr, l, 1.0).map_err(|e| format!("corner motor rejected: {e:?}"))
}

/// Run every check.
pub fn certify(spec: &DriveSpec, c: &CertifySpec) -> Result<Vec<Check>, String> {
    let mut checks = certify_current(spec, c)?;
    checks.extend(certify_speed(spec, c)?);
    Ok(checks)
}

/// The speed and position loops' checks alone (Kharitonov, sampled speed, sampled
/// position): what `design tune` searches the speed gain on, the current loops fixed.
pub fn certify_speed(spec: &DriveSpec, c: &CertifySpec) -> Result<Vec<Check>, String> {
    let mut checks = Vec::new();
    let m = &spec.motor;
    let (j, b) = (m.j_kgm2(), m.b_nms());
    let (jl, jh) = (j * c.j_factor[0], j * c.j_factor[1]);
    let kt = m.torque_factor() * spec.flux_ref_wb;
    // Saturated P: every kp the firmware accepts over its link (the writable range, which
    // contains the configured one) — kp enters one coefficient, so the interval is exact.
    let [kp_lo, kp_hi] = c.speed_kp_writable;
    let poly = match spec.speed_law {
        SpeedLaw::SaturatedP { .. } => IntervalPoly::new(&[jl, b + kp_lo], &[jh, b + kp_hi]),
        SpeedLaw::PiTorque { kp, ki, .. } => IntervalPoly::new(&[jl, b + kp, ki], &[jh, b + kp, ki]),
        SpeedLaw::PiIq { kp, ki, .. } => {
            IntervalPoly::new(&[jl, b + kp * kt, ki * kt], &[jh, b + kp * kt, ki * kt])
        }
    }
    .map_err(|e| format!("speed-loop interval polynomial: {e:?}"))?;
    let worst =
        poly.kharitonov().iter().map(crate::poly::Poly::max_real_root).fold(f64::NEG_INFINITY, f64::max);
    let robust = poly.kharitonov().iter().all(crate::poly::Poly::is_hurwitz_routh);
    checks.push(Check {
        name: "speed: Kharitonov worst closed-loop pole Re (1/s)".into(),
        corner: match spec.speed_law {
            SpeedLaw::SaturatedP { .. } => {
                format!("J×[{}, {}], kp∈[{kp_lo}, {kp_hi}]", c.j_factor[0], c.j_factor[1])
            }
            _ => format!("J×[{}, {}]", c.j_factor[0], c.j_factor[1]),
        },
        value: Some(worst),
        limit: 0.0,
        pass: robust,
    });
    checks.push(sampled_speed_check(spec, c, None)?);
    checks.push(sampled_speed_check(spec, c, Some(spec.position.k_per_s))?);
    Ok(checks)
}

/// The current loops' checks alone (continuous and sampled, every corner): what `design
/// tune` searches the current gains on.
pub fn certify_current(spec: &DriveSpec, c: &CertifySpec) -> Result<Vec<Check>, String> {
    let mut checks = Vec::new();
    for corner in current_corners(c) {
        checks.extend(current_corner_checks(spec, c, corner, Stop::Never)?);
    }
    Ok(checks)
}

/// Whether every current check of the certificate passes ([`certify_current`]'s verdict,
/// the same checks): corner by corner, and within a corner the margins at ω_r,max (one
/// frequency sweep each) before the stability sweeps over 0…ω_r,max (an eigenvalue problem
/// every 5 rad/s), stopping at the first that fails: `design tune`'s crossover search tries
/// most of its candidates above the one it takes, and a failing one costs what it takes to
/// fail, not the whole certificate.
pub fn current_passes(spec: &DriveSpec, c: &CertifySpec) -> Result<bool, String> {
    for corner in current_corners(c) {
        if current_corner_checks(spec, c, corner, Stop::AtFirstFailure)?.iter().any(|k| !k.pass) {
            return Ok(false);
        }
    }
    Ok(true)
}

/// The corners of the current loops' box, `(R_s, R_r, L)` factors, in the certificate's
/// order.
fn current_corners(c: &CertifySpec) -> impl Iterator<Item = [f64; 3]> + '_ {
    c.rs_factor.into_iter().flat_map(move |rs| {
        c.rr_factor.into_iter().flat_map(move |rr| c.inductance_factor.into_iter().map(move |l| [rs, rr, l]))
    })
}

/// Whether a corner's checks run to the end ([`certify_current`]) or stop at the first
/// group that fails ([`current_passes`]).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Stop {
    Never,
    AtFirstFailure,
}

/// The current checks of one corner, by the work they take.
#[derive(Clone, Copy)]
enum CurrentGroup {
    /// Phase, gain and γh margins of the continuous loop at ω_r,max (one frequency sweep).
    ContinuousMargins,
    /// The continuous loop's closed-loop poles over 0…ω_r,max (an eigenvalue problem every 5
    /// rad/s).
    ContinuousPoles,
    /// The sampled loop's spectral radius over 0…ω_r,max (likewise).
    SampledPoles,
    /// The sampled loop's margins at ω_r,max.
    SampledMargins,
}

impl CurrentGroup {
    /// The certificate's order (`design certify` prints them so).
    const CERTIFICATE: [Self; 4] =
        [Self::ContinuousMargins, Self::ContinuousPoles, Self::SampledPoles, Self::SampledMargins];
    /// Cheapest and likeliest to fail first ([`current_passes`]): at a crossover too fast for
    /// the PWM rate the sampled loop's phase margin goes first.
    const CHEAPEST_FIRST: [Self; 4] =
        [Self::SampledMargins, Self::ContinuousMargins, Self::SampledPoles, Self::ContinuousPoles];
}

/// The current checks of one corner, in the certificate's order ([`CurrentGroup`]); with
/// [`Stop::AtFirstFailure`] cheapest first, ending with the first group that fails.
fn current_corner_checks(
    spec: &DriveSpec,
    c: &CertifySpec,
    [rs, rr, l]: [f64; 3],
    stop: Stop,
) -> Result<Vec<Check>, String> {
    let corner = format!("Rs×{rs} Rr×{rr} L×{l}");
    let cm = corner_motor(&spec.motor, rs, rr, l)?;
    let frame = spec.current_frame;
    let ts = 1.0 / spec.pwm_frequency_hz;
    let ctrl = CurrentControllerConfig::<f32>::new(&spec.current_law, ts, spec.discretization, 1.0)
        .map_err(|e| format!("current law rejected at {} Hz: {e:?}", spec.pwm_frequency_hz))?;
    let w_max = c.omega_r_max_rad_s;
    let group_checks = |group: CurrentGroup| -> Vec<Check> {
        let mut checks = Vec::new();
        match group {
            CurrentGroup::ContinuousMargins => {
                let a = analyse_in(&cm, &spec.current_law, w_max, frame);
                margin_checks(&mut checks, "current", &a, c, &corner);
            }
            CurrentGroup::ContinuousPoles => {
                let mut w = 0.0;
                let mut worst: f64 = f64::NEG_INFINITY;
                while w <= w_max {
                    worst = worst.max(closed_loop_abscissa_in(&cm, &spec.current_law, w, frame));
                    w += 5.0;
                }
                checks.push(Check {
                    name: "current: worst closed-loop pole Re over 0…ω_r,max (1/s)".into(),
                    corner: corner.clone(),
                    value: Some(worst),
                    limit: 0.0,
                    pass: worst < 0.0,
                });
            }
            CurrentGroup::SampledPoles => {
                // As a continuous decay rate, comparable with the continuous pole's real part.
                let (radius, at) =
                    crate::sampled::current_loop_worst_radius_in(&cm, &ctrl, ts, w_max, 5.0, frame);
                let sigma = radius.ln() / ts;
                checks.push(Check {
                    name: format!(
                        "sampled current: worst closed-loop ln|z|/T over 0…ω_r,max (1/s) (worst at ω_r = {at} rad/s)"
                    ),
                    corner: corner.clone(),
                    value: Some(sigma),
                    limit: 0.0,
                    pass: sigma < 0.0,
                });
            }
            CurrentGroup::SampledMargins => {
                let a = crate::sampled::analyse_in(&cm, &ctrl, ts, w_max, frame);
                margin_checks(&mut checks, "sampled current", &a, c, &corner);
            }
        }
        checks
    };
    let order = match stop {
        Stop::Never => CurrentGroup::CERTIFICATE,
        Stop::AtFirstFailure => CurrentGroup::CHEAPEST_FIRST,
    };
    let mut checks = Vec::new();
    for group in order {
        let got = group_checks(group);
        let failed = got.iter().any(|k| !k.pass);
        checks.extend(got);
        if failed && stop == Stop::AtFirstFailure {
            break;
        }
    }
    Ok(checks)
}

/// The current loops' bandwidth over the box: the least gain crossover of the sampled
/// individual channel at ω_r,max over the corners of (R_s, R_r, L), rad/s, and its corner —
/// what `[requirements] current_bandwidth_hz` asks of every corner (`design certify`).
pub fn current_bandwidth_rad_s(spec: &DriveSpec, c: &CertifySpec) -> Result<(f64, String), String> {
    let ts = 1.0 / spec.pwm_frequency_hz;
    let ctrl = CurrentControllerConfig::<f32>::new(&spec.current_law, ts, spec.discretization, 1.0)
        .map_err(|e| format!("current law rejected at {} Hz: {e:?}", spec.pwm_frequency_hz))?;
    let mut least = (f64::INFINITY, String::new());
    for rs in c.rs_factor {
        for rr in c.rr_factor {
            for l in c.inductance_factor {
                let cm = corner_motor(&spec.motor, rs, rr, l)?;
                let a = crate::sampled::analyse_in(&cm, &ctrl, ts, c.omega_r_max_rad_s, spec.current_frame);
                // No crossover: the loop gain never reaches 1 — no bandwidth at all.
                let w = a.channel.crossover_rad_s.unwrap_or(0.0);
                if w < least.0 {
                    least = (w, format!("Rs×{rs} Rr×{rr} L×{l}"));
                }
            }
        }
    }
    Ok(least)
}

/// Phase, gain and γh margins of an ICAD report against the certificate's minima.
fn margin_checks(checks: &mut Vec<Check>, what: &str, a: &IcadReport, c: &CertifySpec, corner: &str) {
    let pm = a.channel.phase_margin_deg;
    checks.push(Check {
        name: format!("{what}: phase margin (deg)"),
        corner: corner.into(),
        value: pm,
        limit: c.phase_margin_deg_min,
        pass: pm.is_some_and(|p| p >= c.phase_margin_deg_min),
    });
    let gm = match (a.channel.gain_margin_increase_db, a.channel.gain_margin_reduction_db) {
        (Some(x), Some(y)) => Some(x.min(y)),
        (x, y) => x.or(y),
    };
    checks.push(Check {
        name: format!("{what}: gain margin (dB)"),
        corner: corner.into(),
        value: gm,
        limit: c.gain_margin_db_min,
        pass: gm.is_none_or(|g| g >= c.gain_margin_db_min),
    });
    checks.push(Check {
        name: format!("{what}: γh margin to (1,0) (dB)"),
        corner: corner.into(),
        value: a.gamma_h_margin_db,
        limit: c.gamma_h_margin_db_min,
        pass: a.gamma_h_margin_db.is_none_or(|g| g >= c.gamma_h_margin_db_min),
    });
}

/// Points of the sampled speed check's grid on each interval (J, and k_p over the writable
/// range), log-spaced, ends included.
pub const SPEED_GRID_POINTS: usize = 9;

/// The sampled speed loop over the grid J × k_p ([`crate::sampled::SpeedLoop`]), or with
/// `position` (its gain, 1/s) the position loop closed around it.
fn sampled_speed_check(spec: &DriveSpec, c: &CertifySpec, position: Option<f64>) -> Result<Check, String> {
    let m = &spec.motor;
    let t_slow = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
    let grid = |lo: f64, hi: f64| -> Vec<f64> {
        (0..SPEED_GRID_POINTS)
            .map(|k| {
                let f = k as f64 / (SPEED_GRID_POINTS - 1) as f64;
                if lo > 0.0 && hi > 0.0 { lo * (hi / lo).powf(f) } else { lo + f * (hi - lo) }
            })
            .collect()
    };
    let js = grid(m.j_kgm2() * c.j_factor[0], m.j_kgm2() * c.j_factor[1]);
    let kt = m.torque_factor() * spec.flux_ref_wb;
    let mut worst = (f64::NEG_INFINITY, String::new());
    for &j in &js {
        let loops: Vec<(crate::sampled::SpeedLoop, String)> = match spec.speed_law {
            SpeedLaw::SaturatedP { .. } => grid(c.speed_kp_writable[0], c.speed_kp_writable[1])
                .into_iter()
                .map(|kp| {
                    let l = crate::sampled::SpeedLoop {
                        j_kgm2: j,
                        b_nms: m.b_nms(),
                        ts_s: t_slow,
                        kp,
                        ki_over_k: 0.0,
                    };
                    (l, format!("J = {j:.4e}, kp = {kp:.4}"))
                })
                .collect(),
            SpeedLaw::PiTorque { kp, ki, .. } => {
                vec![(
                    crate::sampled::SpeedLoop::pi(j, m.b_nms(), t_slow, kp, ki, 1.0)?,
                    format!("J = {j:.4e}"),
                )]
            }
            SpeedLaw::PiIq { kp, ki, .. } => {
                vec![(
                    crate::sampled::SpeedLoop::pi(j, m.b_nms(), t_slow, kp, ki, kt)?,
                    format!("J = {j:.4e}"),
                )]
            }
        };
        for (l, at) in loops {
            let r = position.map_or_else(|| l.radius(), |k| l.position_radius(k));
            if r > worst.0 || r.is_nan() {
                worst = (r, at);
            }
        }
    }
    let sigma = worst.0.ln() / t_slow;
    let what = match position {
        None => "speed".to_string(),
        Some(k) => format!("position (k = {k} 1/s)"),
    };
    Ok(Check {
        name: format!("sampled {what}: worst closed-loop ln|z|/T_slow (1/s) (at {})", worst.1),
        corner: match spec.speed_law {
            SpeedLaw::SaturatedP { .. } => format!(
                "J×[{}, {}], kp∈[{}, {}]",
                c.j_factor[0], c.j_factor[1], c.speed_kp_writable[0], c.speed_kp_writable[1]
            ),
            _ => format!("J×[{}, {}]", c.j_factor[0], c.j_factor[1]),
        },
        value: Some(sigma),
        limit: 0.0,
        pass: sigma < 0.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const GAINS: &str = drive_file::SHIPPED;

    #[test]
    fn shipped_gains_certify() {
        let (spec, c) = parse(Path::new("drive.toml"), GAINS).unwrap();
        let checks = certify(&spec, &c).unwrap();
        for ch in &checks {
            eprintln!(
                "{:>4} {:<58} {:<22} {:>10.3?} (limit {})",
                if ch.pass { "ok" } else { "FAIL" },
                ch.name,
                ch.corner,
                ch.value,
                ch.limit
            );
        }
        assert!(checks.iter().all(|c| c.pass));
        assert_eq!(checks.len(), 8 * 8 + 3);
    }

    /// A speed range beyond the ICAD limit (645 rad/s on the nominal motor) must fail, and a
    /// phase-margin demand above what (20) offers must fail: the certification can say no.
    #[test]
    fn certification_rejects_what_it_should() {
        let (spec, c) = parse(Path::new("drive.toml"), GAINS).unwrap();
        let fast = CertifySpec { omega_r_max_rad_s: 800.0, ..c };
        assert!(
            certify(&spec, &fast).unwrap().iter().any(|ch| !ch.pass && ch.name.contains("closed-loop pole"))
        );
        let strict = CertifySpec { phase_margin_deg_min: 85.0, ..c };
        assert!(
            certify(&spec, &strict).unwrap().iter().any(|ch| !ch.pass && ch.name.contains("phase margin"))
        );
        // A writable range reaching kp ≤ −B makes the speed loop not robustly stable.
        let c_neg = CertifySpec { speed_kp_writable: [-0.01, 0.1], ..c };
        assert!(certify(&spec, &c_neg).unwrap().iter().any(|ch| !ch.pass && ch.name.starts_with("speed")));
    }

    /// `current_passes` is `certify_current`'s verdict: on the shipped gains, a speed range
    /// beyond the ICAD limit (its poles fail), a phase-margin demand above what (20) offers,
    /// the shipped law at 2 kHz, and stationary-frame PIs from 1 000 to 25 000 rad/s at 20 kHz.
    #[test]
    fn the_early_verdict_is_the_certificates() {
        let (spec, c) = parse(Path::new("drive.toml"), GAINS).unwrap();
        let fast = CertifySpec { omega_r_max_rad_s: 800.0, ..c };
        let strict = CertifySpec { phase_margin_deg_min: 85.0, ..c };
        let slow = DriveSpec { pwm_frequency_hz: 2_000.0, ..spec };
        let (k, sigma_ls) = (spec.motor.lm_h() / spec.motor.lr_h(), spec.motor.sigma() * spec.motor.ls_h());
        let r = spec.motor.rs_ohm() + spec.motor.rr_ohm() * k * k;
        let pi = |omega_c: f64| DriveSpec {
            current_law: controller_core::current::CurrentLaw {
                kp_v_per_a: omega_c * sigma_ls,
                ki_v_per_as: omega_c * r,
                lag: None,
            },
            ..spec
        };
        let mut verdicts = Vec::new();
        for (spec, c) in [(spec, c), (spec, fast), (spec, strict), (slow, c)]
            .into_iter()
            .chain([1_000.0, 4_000.0, 12_000.0, 25_000.0].map(|w| (pi(w), c)))
        {
            let whole = certify_current(&spec, &c).unwrap().iter().all(|ch| ch.pass);
            assert_eq!(current_passes(&spec, &c).unwrap(), whole);
            verdicts.push(whole);
        }
        // Both verdicts occur: the comparison is not between two constants.
        assert!(verdicts.contains(&true) && verdicts.contains(&false), "{verdicts:?}");
    }

    fn failed(text: &str) -> Vec<Check> {
        let (spec, c) = parse(Path::new("drive.toml"), text).unwrap();
        certify(&spec, &c).unwrap().into_iter().filter(|ch| !ch.pass).collect()
    }

    /// Issue 21: a 100 Hz loop passed the continuous certificate (the continuous analysis
    /// does not know the sampling rate). The sampled one refuses it, and only it.
    #[test]
    fn a_100_hz_loop_is_refused_by_the_sampled_certificate_alone() {
        // The drive file itself refuses parts of it: the current trim's 20 rad/s default at a
        // 10 Hz slow rate, the board's 16-bit PWM timer (so: no [board] table here), and a
        // current bandwidth of 500 Hz above the 50 Hz Nyquist rate (so: the default's).
        let slow = GAINS
            .replace("frequency_hz = 20000.0", "frequency_hz = 100.0")
            .replace("current_bandwidth_hz = 500.0\n", "")
            .replace("[controller]\n", "[controller]\ncurrent_trim_bandwidth_rad_s = 0.0\n");
        let slow = slow.get(..slow.find("[board]").unwrap()).unwrap();
        let bad = failed(slow);
        assert!(!bad.is_empty());
        for ch in &bad {
            assert!(ch.name.starts_with("sampled"), "{} failed too", ch.name);
        }
        assert!(bad.iter().any(|ch| ch.name.starts_with("sampled current: worst closed-loop")));
    }

    /// Issue 21: a writable speed gain up to 1e9 passed Kharitonov (the continuous speed
    /// loop is stable for any k_p > −B); the sampled loop refuses it, and the writable range
    /// is refused from k_p ≈ 3.6 on (the limit `sampled::tests::speed_gain_limits` prints for
    /// the nominal J; here the grid's smallest J is the nominal one).
    #[test]
    fn a_huge_speed_gain_is_refused_by_the_sampled_certificate_alone() {
        for (hi, refused) in [("1e9", true), ("50.0", true), ("4.0", true), ("3.0", false)] {
            let text = GAINS
                .replace("speed_kp_writable = [0.04, 0.1]", &format!("speed_kp_writable = [0.04, {hi}]"));
            let bad = failed(&text);
            assert_eq!(!bad.is_empty(), refused, "kp up to {hi}: {bad:?}");
            // The speed check, and the position cascade closed around that speed loop.
            for ch in &bad {
                assert!(
                    ch.name.starts_with("sampled speed") || ch.name.starts_with("sampled position"),
                    "{} failed too",
                    ch.name
                );
            }
            assert_eq!(bad.iter().any(|ch| ch.name.starts_with("sampled speed")), refused);
        }
    }

    /// Synchronous-frame loops are analysed in the field's coordinates (`ImModel::in_frame`,
    /// `sampled::current_loop_matrix_in`), not as stationary ones: seed 002's PI (360, 9 000)
    /// in the synchronous frame has a different sampled stability figure from the same PI in
    /// the stationary frame, and a gain beyond the Nyquist rate is refused in either frame.
    #[test]
    fn synchronous_frame_loops_are_analysed_in_their_frame() {
        let pi = GAINS
            .replace("current = { kind = \"icad\" }", "current = { kind = \"pi\", kp = 360.0, ki = 9000.0 }");
        assert_ne!(pi, GAINS, "the template's current law");
        let sampled = |text: &str| -> f64 {
            let (spec, c) = parse(Path::new("t.toml"), text).unwrap();
            let checks = certify(&spec, &c).unwrap();
            checks
                .iter()
                .filter(|ch| ch.name.starts_with("sampled current: worst"))
                .filter_map(|ch| ch.value)
                .fold(f64::NEG_INFINITY, f64::max)
        };
        let sync = pi.replace("current_frame = \"stationary\"", "current_frame = \"synchronous\"");
        let (st, sy) = (sampled(&pi), sampled(&sync));
        eprintln!("seed 002's PI: worst sampled ln|z|/T {st:.2} 1/s stationary, {sy:.2} 1/s synchronous");
        assert!(st < 0.0 && sy < 0.0 && (st - sy).abs() > 1.0, "{st} vs {sy}");
        let fast = sync.replace("kp = 360.0", "kp = 5000.0");
        assert!(failed(&fast).iter().any(|ch| ch.name.starts_with("sampled current: worst")));
    }
}

/// Points of the certificate page's torque–speed panel, each direction.
pub const PAGE_ENVELOPE_POINTS: usize = 10;

/// The certificate's one-page summary (`design certify --out F` writes it beside F, as
/// `.svg`): the campaign's first speed step over the box against the requirements
/// (`band`, from the campaign's summary: [`hil_sim::campaign::StepBand`]) above the
/// torque–speed envelope the drive reaches in SIL on bus `vdc_v`, motoring and generating,
/// from 0.2 to 2 × the no-load base speed ([`hil_sim::envelope::measure`]), against the
/// motor's physical limit there (computed from the motor alone, the bus and the current
/// limit: `hil_sim::envelope::physical_limit_nm`) and τ_max.
pub fn summary_page(
    spec: &DriveSpec,
    band: Option<&hil_sim::campaign::StepBand>,
    vdc_v: f64,
) -> Result<String, String> {
    use report::plot::{Series, line_plot, stack};
    let base = hil_sim::envelope::drive_base_speed_rad_s(spec, vdc_v);
    if base.is_nan() || base <= 0.0 {
        return Err(format!("the rated flux needs more than the {vdc_v} V bus has: no envelope to draw"));
    }
    let n = (PAGE_ENVELOPE_POINTS - 1) as f64;
    let speeds: Vec<f64> = (0..PAGE_ENVELOPE_POINTS).map(|k| base * (0.2 + 1.8 * k as f64 / n)).collect();
    let motoring = hil_sim::envelope::measure(spec, &spec.motor, vdc_v, &speeds, 1.0)?;
    let generating = hil_sim::envelope::measure(spec, &spec.motor, vdc_v, &speeds, -1.0)?;
    let of = |p: &[hil_sim::envelope::Point], f: fn(&hil_sim::envelope::Point) -> f64| {
        p.iter().map(|x| (x.omega_m_rad_s, f(x).abs())).collect::<Vec<_>>()
    };
    let tau_max = hil_sim::campaign::torque_limit_nm(spec);
    let top = speeds.last().copied().unwrap_or(base);
    let envelope = line_plot(
        &format!(
            "Torque–speed envelope on {vdc_v:.0} V: the drive in SIL against the motor's physical limit"
        ),
        "mechanical rad/s (y: |torque|, N·m)",
        &[
            Series::markers("motoring, SIL", of(&motoring, |p| p.measured_nm)),
            Series::markers("generating, SIL", of(&generating, |p| p.measured_nm)),
            Series::line("physical limit, motoring", of(&motoring, |p| p.physical_nm)),
            Series::line("physical limit, generating", of(&generating, |p| p.physical_nm)),
            Series::line("τ_max", vec![(speeds.first().copied().unwrap_or(0.0), tau_max), (top, tau_max)]),
        ],
    );
    Ok(match band {
        Some(b) => stack(&[b.plot(), envelope]),
        None => envelope,
    })
}

/// The pictures an engineer checks before flashing (issue 21), as `(file name, SVG)`: on
/// every current-loop corner of the box, at ω_r,max — the Nyquist plots of γ and γ·h₂ around
/// (1, 0) (seed 002's structural-robustness conditions and its Fig. 9), the individual
/// channel c₁ and k·g₁₁ in magnitude and phase (nominal motor), and the stable-speed sweep:
/// the full 2×2 loop's worst closed-loop pole over 0…ω_r,max. Continuous-time, like the
/// paper's figures; the sampled certificate's numbers are in the checks.
pub fn pictures(spec: &DriveSpec, c: &CertifySpec) -> Result<Vec<(&'static str, String)>, String> {
    use report::plot::{Series, line_plot, plot_in};
    let m = &spec.motor;
    let law = &spec.current_law;
    let w = crate::tf::logspace(1.0, 1e5, 800);
    let wr = c.omega_r_max_rad_s;
    let mut corners = Vec::new();
    for rs in c.rs_factor {
        for rr in c.rr_factor {
            for l in c.inductance_factor {
                corners.push((format!("Rs×{rs} Rr×{rr} L×{l}"), corner_motor(m, rs, rr, l)?));
            }
        }
    }
    let frame = spec.current_frame;
    let curves: Vec<_> =
        corners.iter().map(|(_, cm)| crate::icad::curves_in(cm, law, wr, &w, frame)).collect();
    let point = || Series::markers("(1, 0)", vec![(1.0, 0.0)]).colored("#d62728");
    let nyquist = |title: &str, f: fn(&crate::icad::IcadPoint) -> num_complex::Complex64| {
        let mut series: Vec<Series<'_>> = corners
            .iter()
            .zip(&curves)
            .map(|((name, _), cv)| Series::line(name, cv.iter().map(|p| (f(p).re, f(p).im)).collect()))
            .collect();
        series.push(point());
        plot_in(title, "Re", &series, ((-1.0, 3.0), (-2.0, 2.0)))
    };
    let gamma = nyquist(
        &format!(
            "γ(jω) at ω_r = {wr} rad/s, every corner: its phase-0 crossings stay left of (1, 0) (seed 002 (b.2))"
        ),
        |p| p.gamma,
    );
    let gamma_h = nyquist(
        &format!(
            "γ·h₂(jω) at ω_r = {wr} rad/s, every corner: no encirclement of (1, 0) (seed 002 (a.2), Fig. 9)"
        ),
        |p| p.gamma_h2,
    );
    let nominal = curves.first().ok_or("no corner")?;
    let db = |z: num_complex::Complex64| 20.0 * z.norm().log10();
    let phase = crate::margins::unwrapped_phase_deg(&nominal.iter().map(|p| p.c1).collect::<Vec<_>>());
    let phase_kg = crate::margins::unwrapped_phase_deg(&nominal.iter().map(|p| p.kg11).collect::<Vec<_>>());
    let lw: Vec<f64> = w.iter().map(|x| x.log10()).collect();
    let magnitude = line_plot(
        &format!(
            "|c₁| and |k·g₁₁| at ω_r = {wr} rad/s, {} (dB against log₁₀ ω)",
            corners.first().map_or("", |c| &c.0)
        ),
        "log₁₀ ω (rad/s)",
        &[
            Series::line("|c₁| dB", lw.iter().zip(nominal).map(|(x, p)| (*x, db(p.c1))).collect()),
            Series::line("|k·g₁₁| dB", lw.iter().zip(nominal).map(|(x, p)| (*x, db(p.kg11))).collect()),
            Series::line("0 dB", vec![(0.0, 0.0), (5.0, 0.0)]).colored("#7f7f7f"),
        ],
    );
    let phase_plot = line_plot(
        &format!("phase of c₁ and k·g₁₁ at ω_r = {wr} rad/s (degrees against log₁₀ ω)"),
        "log₁₀ ω (rad/s)",
        &[
            Series::line("∠c₁", lw.iter().copied().zip(phase).collect()),
            Series::line("∠k·g₁₁", lw.iter().copied().zip(phase_kg).collect()),
            Series::line("−180°", vec![(0.0, -180.0), (5.0, -180.0)]).colored("#7f7f7f"),
        ],
    );
    let speeds: Vec<f64> = (0..=80).map(|k| wr * f64::from(k) / 80.0).collect();
    let sweep: Vec<Series<'_>> = corners
        .iter()
        .map(|(name, cm)| {
            Series::line(
                name,
                speeds.iter().map(|&x| (x, closed_loop_abscissa_in(cm, law, x, frame))).collect(),
            )
        })
        .collect();
    let stable = line_plot(
        &format!(
            "worst closed-loop pole Re (1/s) of the 2×2 current loop against ω_r, 0…{wr} rad/s: below 0 is stable"
        ),
        "ω_r (rad/s)",
        &sweep,
    );
    let (region, speed_step) = speed_pictures(spec, c)?;
    let current_step = current_step_picture(spec, c, &corners)?;
    Ok(vec![
        ("nyquist_gamma.svg", gamma),
        ("nyquist_gamma_h.svg", gamma_h),
        ("bode_magnitude.svg", magnitude),
        ("bode_phase.svg", phase_plot),
        ("stable_speed.svg", stable),
        ("speed_region.svg", region),
        ("speed_step.svg", speed_step),
        ("current_step.svg", current_step),
    ])
}

/// The sampled speed loop with a torque law's gain `kp` (a saturated P's, or a PI's at the
/// drive's values) on inertia `j`.
fn speed_loop(spec: &DriveSpec, j: f64, kp: f64) -> Result<crate::sampled::SpeedLoop, String> {
    let m = &spec.motor;
    let t_slow = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
    let kt = m.torque_factor() * spec.flux_ref_wb;
    match spec.speed_law {
        SpeedLaw::SaturatedP { .. } => {
            Ok(crate::sampled::SpeedLoop { j_kgm2: j, b_nms: m.b_nms(), ts_s: t_slow, kp, ki_over_k: 0.0 })
        }
        SpeedLaw::PiTorque { ki, .. } => crate::sampled::SpeedLoop::pi(j, m.b_nms(), t_slow, kp, ki, 1.0),
        SpeedLaw::PiIq { ki, .. } => crate::sampled::SpeedLoop::pi(j, m.b_nms(), t_slow, kp, ki, kt),
    }
}

/// The speed loop's region — the sampled closed loop's slowest pole, `ln|z|/T_slow`,
/// against k_p at the box's smallest and largest inertia, with the writable range and the
/// configured gain marked (below zero is stable) — and its step response: the speed after a
/// unit reference step on both inertias (the linear loop, below the torque limit), from the
/// sampled model: x(k+1) = M·x(k) from the state of a step of 1 at rest.
fn speed_pictures(spec: &DriveSpec, c: &CertifySpec) -> Result<(String, String), String> {
    use report::plot::{Series, line_plot};
    let m = &spec.motor;
    let t_slow = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
    let kp_now = match spec.speed_law {
        SpeedLaw::SaturatedP { kp, .. } | SpeedLaw::PiTorque { kp, .. } | SpeedLaw::PiIq { kp, .. } => kp,
    };
    let js = [m.j_kgm2() * c.j_factor[0], m.j_kgm2() * c.j_factor[1]];
    let k_hi = 4.0 * c.speed_kp_writable[1].max(kp_now);
    let kps: Vec<f64> = (1..=200).map(|k| k_hi * f64::from(k) / 200.0).collect();
    let mut series = Vec::new();
    let labels: Vec<String> = js.iter().map(|j| format!("J = {j:.4e} kg·m²")).collect();
    for (j, label) in js.iter().zip(&labels) {
        let pts: Result<Vec<(f64, f64)>, String> =
            kps.iter().map(|&kp| Ok((kp, speed_loop(spec, *j, kp)?.radius().ln() / t_slow))).collect();
        series.push(Series::line(label, pts?));
    }
    let [w0, w1] = c.speed_kp_writable;
    series.push(Series::markers("writable k_p", vec![(w0, 0.0), (w1, 0.0)]).colored("#2ca02c"));
    series.push(Series::markers("configured k_p", vec![(kp_now, 0.0)]).colored("#d62728"));
    series.push(Series::line("0 (stability)", vec![(0.0, 0.0), (k_hi, 0.0)]).colored("#7f7f7f"));
    let region = match spec.speed_law {
        SpeedLaw::PiTorque { kp, ki, .. } => pi_region_picture(spec, c, kp, ki)?,
        _ => line_plot(
            "sampled speed loop: slowest pole ln|z|/T_slow (1/s) against k_p, at J_min and J_max (below 0 is stable)",
            "k_p (N·m per rad/s)",
            &series,
        ),
    };
    let mut steps = Vec::new();
    for (j, label) in js.iter().zip(&labels) {
        let y = speed_step(&speed_loop(spec, *j, kp_now)?, 400);
        steps.push(Series::line(
            label,
            y.iter().enumerate().map(|(k, v)| (k as f64 * t_slow * 1e3, *v)).collect(),
        ));
    }
    let step = line_plot(
        &format!(
            "sampled speed loop: speed after a unit reference step, k_p = {kp_now} (linear, below τ_max)"
        ),
        "t (ms)",
        &steps,
    );
    Ok((region, step))
}

/// Seed 000's k_p–k_i regions of a speed PI → torque over the inertia interval
/// ([`crate::pi_region::SpeedRegions`]) on a grid around the configured point: robustly
/// stable, and stable with the certificate's gain–phase margins too; the configured point.
fn pi_region_picture(spec: &DriveSpec, c: &CertifySpec, kp: f64, ki: f64) -> Result<String, String> {
    use report::plot::{Series, plot_in};
    let m = &spec.motor;
    let t_slow = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
    let r = crate::pi_region::SpeedRegions::new(
        [m.j_kgm2() * c.j_factor[0], m.j_kgm2() * c.j_factor[1]],
        m.b_nms(),
        t_slow,
        [c.phase_margin_deg_min, c.gain_margin_db_min],
    )?;
    let (kp_hi, ki_hi) = (2.5 * kp.abs().max(1e-9), 2.5 * ki.abs().max(1e-9));
    let n = 48;
    let (mut stable, mut margins) = (Vec::new(), Vec::new());
    for a in 1..=n {
        for b in 1..=n {
            let (x, y) = (kp_hi * f64::from(a) / f64::from(n), ki_hi * f64::from(b) / f64::from(n));
            if r.margins(x, y) {
                margins.push((x, y));
            } else if r.stable(x, y) {
                stable.push((x, y));
            }
        }
    }
    Ok(plot_in(
        &format!(
            "speed PI regions over J × [{}, {}] (seed 000; dead time {:.2} ms as a Padé): stable, and with {}° / {} dB",
            c.j_factor[0],
            c.j_factor[1],
            r.tau_s * 1e3,
            c.phase_margin_deg_min,
            c.gain_margin_db_min
        ),
        "k_p (N·m per rad/s); vertical: k_i (N·m/rad)",
        &[
            Series::markers("robustly stable", stable).colored("#c7c7c7"),
            Series::markers("with the margins", margins).colored("#2ca02c"),
            Series::markers("configured (k_p, k_i)", vec![(kp, ki)]).colored("#d62728"),
        ],
        ((0.0, kp_hi), (0.0, ki_hi)),
    ))
}

/// The speed of `l` after a unit reference step at rest, `n` slow periods: in the error
/// coordinates (ω − 1 = −1, every recorded angle increment −T: what the window measures less
/// the reference), x(k+1) = M·x(k).
pub fn speed_step(l: &crate::sampled::SpeedLoop, n: usize) -> Vec<f64> {
    let mm = l.matrix();
    let mut x = nalgebra::DVector::<f64>::zeros(mm.nrows());
    for (i, v) in x.iter_mut().enumerate().take(controller_core::encoder::SPEED_WINDOW_READS + 1) {
        *v = if i == 0 { -1.0 } else { -l.ts_s };
    }
    (0..n)
        .map(|_| {
            let y = 1.0 + x[0];
            x = &mm * &x;
            y
        })
        .collect()
}

/// i_α of the sampled current loop (`m`, `ctrl`, at `omega_r`, loops in `frame`: i_d after
/// a unit i_d step in the synchronous frame) after a unit reference step, `n` PWM periods:
/// x(k+1) = M·x(k) + b, b the reference's input — where −i_α enters the controller, with
/// the opposite sign.
pub fn current_step(
    m: &MotorParams,
    ctrl: &CurrentControllerConfig<f32>,
    ts: f64,
    omega_r: f64,
    n: usize,
    frame: CurrentFrame,
) -> Vec<f64> {
    let mm = crate::sampled::current_loop_matrix_in(m, ctrl, ts, omega_r, frame);
    let b = nalgebra::DVector::<f64>::from_iterator(
        mm.nrows(),
        (0..mm.nrows()).map(|r| if r < 4 { 0.0 } else { -mm[(r, 0)] }),
    );
    let mut x = nalgebra::DVector::<f64>::zeros(mm.nrows());
    (0..n)
        .map(|_| {
            let y = x[0];
            x = &mm * &x + &b;
            y
        })
        .collect()
}

/// The sampled current loop's α current after a unit α reference step, on every corner at
/// ω_r = 0 and at ω_r,max (x(k+1) = M·x(k) + b·r, b the controller's reference input).
fn current_step_picture(
    spec: &DriveSpec,
    c: &CertifySpec,
    corners: &[(String, MotorParams)],
) -> Result<String, String> {
    use report::plot::{Series, line_plot};
    let ts = 1.0 / spec.pwm_frequency_hz;
    let ctrl = CurrentControllerConfig::<f32>::new(&spec.current_law, ts, spec.discretization, 1.0)
        .map_err(|e| format!("current law rejected at {} Hz: {e:?}", spec.pwm_frequency_hz))?;
    let mut series = Vec::new();
    let labels: Vec<String> = corners
        .iter()
        .flat_map(|(name, _)| [format!("{name}, ω_r = 0"), format!("{name}, ω_r = {}", c.omega_r_max_rad_s)])
        .collect();
    let mut label = labels.iter();
    for (_, cm) in corners {
        for wr in [0.0, c.omega_r_max_rad_s] {
            let y = current_step(cm, &ctrl, ts, wr, 200, spec.current_frame);
            if let Some(l) = label.next() {
                series.push(Series::line(
                    l,
                    y.iter().enumerate().map(|(k, v)| (k as f64 * ts * 1e3, *v)).collect(),
                ));
            }
        }
    }
    Ok(line_plot(
        "sampled current loop: i_α (i_d in the synchronous frame) after a unit reference step, every corner, at rest and at ω_r,max",
        "t (ms)",
        &series,
    ))
}

#[cfg(test)]
mod picture_tests {
    use super::*;

    /// The shipped drive's pictures: five SVG documents; the Nyquist plots draw one curve per
    /// corner (8) and the point (1, 0); the data they draw keeps γ·h₂ clear of (1, 0) by the
    /// certified margin (its phase-0 crossings at |γh₂| ≤ 10^(−γh margin/20)).
    #[test]
    fn the_certificate_draws_every_corner() {
        let d = drive_file::DriveFile::shipped().unwrap();
        let (spec, c) = (d.spec, d.certify.unwrap());
        let pics = pictures(&spec, &c).unwrap();
        let names: Vec<&str> = pics.iter().map(|p| p.0).collect();
        assert_eq!(
            names,
            [
                "nyquist_gamma.svg",
                "nyquist_gamma_h.svg",
                "bode_magnitude.svg",
                "bode_phase.svg",
                "stable_speed.svg",
                "speed_region.svg",
                "speed_step.svg",
                "current_step.svg"
            ]
        );
        for (name, svg) in &pics {
            assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"), "{name}");
            assert!(svg.trim_end().ends_with("</svg>"), "{name}");
        }
        // The step responses drawn: the current loop's integral action takes i_α to the
        // reference within 10 ms at rest (nominal motor); the saturated P speed loop to
        // k_p/(k_p + B) within 2 s (J_max).
        let ctrl =
            CurrentControllerConfig::<f32>::new(&spec.current_law, 5e-5, spec.discretization, 1.0).unwrap();
        let i = current_step(&spec.motor, &ctrl, 5e-5, 0.0, 200, CurrentFrame::Stationary);
        assert!((i[199] - 1.0).abs() < 0.01 && i[1].abs() < 1e-12, "{} {}", i[1], i[199]);
        let SpeedLaw::SaturatedP { kp, .. } = spec.speed_law else { panic!() };
        let l = speed_loop(&spec, spec.motor.j_kgm2() * c.j_factor[1], kp).unwrap();
        let w = speed_step(&l, 4000);
        let target = kp / (kp + spec.motor.b_nms());
        assert!((w[3999] - target).abs() < 0.01 * target, "{} vs {target}", w[3999]);
        let gh = &pics[1].1;
        assert_eq!(gh.matches("<path").count(), 8, "one curve per corner");
        assert!(gh.contains("Rs×1.5 Rr×2 L×0.6") && gh.contains("(1, 0)"));
        let a = crate::icad::analyse(&spec.motor, &spec.current_law, c.omega_r_max_rad_s);
        let margin = a.gamma_h_margin_db.unwrap();
        let w = crate::tf::logspace(1.0, 1e5, 800);
        let cv = crate::icad::curves(&spec.motor, &spec.current_law, c.omega_r_max_rad_s, &w);
        let near_one = cv
            .iter()
            .filter(|p| p.gamma_h2.im.abs() < 1e-3 * p.gamma_h2.norm().max(1e-9) && p.gamma_h2.re > 0.0)
            .map(|p| p.gamma_h2.norm())
            .fold(0.0f64, f64::max);
        assert!(near_one <= 10f64.powf(-margin / 20.0) * 1.02, "{near_one} vs margin {margin} dB");
    }
}
