//! Gain certification: the drive's constants (`gains.toml`) checked against declared
//! parameter intervals before they reach the firmware.
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

use crate::icad::{analyse, closed_loop_abscissa};
use crate::kharitonov::IntervalPoly;
use controller_core::drive::DriveSpec;
use controller_core::motor::MotorParams;
use controller_core::speed::SpeedLaw;
use serde::Deserialize;
use std::path::Path;

/// `[certify]` table.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CertifySpec {
    /// Electrical rotor speed range to certify, 0 … this, rad/s.
    pub omega_r_max_rad_s: f64,
    /// Multiplicative interval of R_s.
    pub rs_factor: [f64; 2],
    /// Multiplicative interval of R_r.
    pub rr_factor: [f64; 2],
    /// Multiplicative interval of L_s, L_r, L_m (together).
    pub inductance_factor: [f64; 2],
    /// Multiplicative interval of J.
    pub j_factor: [f64; 2],
    /// Saturated-P speed gain range the firmware accepts over its link, N·m per rad/s.
    pub speed_kp_writable: [f64; 2],
    /// τ_max range the firmware accepts over its link, N·m.
    pub speed_tau_max_nm_writable: [f64; 2],
    /// Minimum phase margin of the individual channel, degrees.
    pub phase_margin_deg_min: f64,
    /// Minimum gain margin (increase and reduction), dB.
    pub gain_margin_db_min: f64,
    /// Minimum structural margin of γh to (1, 0), dB.
    pub gamma_h_margin_db_min: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GainsFile {
    #[serde(default = "hil_sim::closed_loop_file::default_pwm")]
    pwm_frequency_hz: f64,
    #[serde(default = "hil_sim::closed_loop_file::default_divider")]
    slow_divider: u16,
    motor: hil_sim::config::MotorFile,
    controller: hil_sim::closed_loop_file::ControllerFile,
    protection: hil_sim::closed_loop_file::ProtectionFile,
    certify: CertifySpec,
}

/// Load a gains file: the drive specification and the certification intervals.
pub fn load(path: &Path) -> Result<(DriveSpec, CertifySpec), String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    parse(path, &text)
}

/// Parse gains-file text read from `path`.
pub fn parse(path: &Path, text: &str) -> Result<(DriveSpec, CertifySpec), String> {
    let f: GainsFile = hil_sim::config::from_toml(path, text).map_err(|e| e.to_string())?;
    let spec = hil_sim::closed_loop_file::drive_spec(
        path,
        f.pwm_frequency_hz,
        f.slow_divider,
        &f.motor,
        &f.controller,
        &f.protection,
    )
    .map_err(|e| e.to_string())?;
    let c = f.certify;
    let bad = |key: &str, why: &str| Err(format!("{}: key `certify.{key}`: {why}", path.display()));
    for (key, [lo, hi]) in [
        ("rs_factor", c.rs_factor),
        ("rr_factor", c.rr_factor),
        ("inductance_factor", c.inductance_factor),
        ("j_factor", c.j_factor),
    ] {
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
            return bad(key, "needs finite 0 < lo ≤ hi");
        }
    }
    if !(c.omega_r_max_rad_s.is_finite() && c.omega_r_max_rad_s >= 0.0) {
        return bad("omega_r_max_rad_s", "must be finite and ≥ 0");
    }
    for (key, [lo, hi]) in [
        ("speed_kp_writable", c.speed_kp_writable),
        ("speed_tau_max_nm_writable", c.speed_tau_max_nm_writable),
    ] {
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
            return bad(key, "needs finite 0 < lo ≤ hi");
        }
    }
    if let SpeedLaw::SaturatedP { kp, tau_max_nm } = spec.speed_law {
        let inside = |x: f64, [lo, hi]: [f64; 2]| lo <= x && x <= hi;
        if !inside(kp, c.speed_kp_writable) || !inside(tau_max_nm, c.speed_tau_max_nm_writable) {
            return bad(
                "speed_kp_writable",
                "the configured speed gains must lie inside the writable ranges",
            );
        }
    }
    Ok((spec, c))
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
    MotorParams::new(
        rs * m.rs_ohm(),
        rr * m.rr_ohm(),
        l * m.ls_h(),
        l * m.lr_h(),
        l * m.lm_h(),
        m.pole_pairs(),
        m.j_kgm2(),
        m.b_nms(),
    )
    .map_err(|e| format!("corner motor rejected: {e:?}"))
}

/// Run every check.
pub fn certify(spec: &DriveSpec, c: &CertifySpec) -> Result<Vec<Check>, String> {
    let mut checks = Vec::new();
    let m = &spec.motor;
    for rs in c.rs_factor {
        for rr in c.rr_factor {
            for l in c.inductance_factor {
                let corner = format!("Rs×{rs} Rr×{rr} L×{l}");
                let cm = corner_motor(m, rs, rr, l)?;
                let a = analyse(&cm, &spec.current_law, c.omega_r_max_rad_s);
                let pm = a.channel.phase_margin_deg;
                checks.push(Check {
                    name: "current: phase margin (deg)".into(),
                    corner: corner.clone(),
                    value: pm,
                    limit: c.phase_margin_deg_min,
                    pass: pm.is_some_and(|p| p >= c.phase_margin_deg_min),
                });
                let gm = match (a.channel.gain_margin_increase_db, a.channel.gain_margin_reduction_db) {
                    (Some(x), Some(y)) => Some(x.min(y)),
                    (x, y) => x.or(y),
                };
                checks.push(Check {
                    name: "current: gain margin (dB)".into(),
                    corner: corner.clone(),
                    value: gm,
                    limit: c.gain_margin_db_min,
                    pass: gm.is_none_or(|g| g >= c.gain_margin_db_min),
                });
                checks.push(Check {
                    name: "current: γh margin to (1,0) (dB)".into(),
                    corner: corner.clone(),
                    value: a.gamma_h_margin_db,
                    limit: c.gamma_h_margin_db_min,
                    pass: a.gamma_h_margin_db.is_none_or(|g| g >= c.gamma_h_margin_db_min),
                });
                let mut w = 0.0;
                let mut worst: f64 = f64::NEG_INFINITY;
                while w <= c.omega_r_max_rad_s {
                    worst = worst.max(closed_loop_abscissa(&cm, &spec.current_law, w));
                    w += 5.0;
                }
                checks.push(Check {
                    name: "current: worst closed-loop pole Re over 0…ω_r,max (1/s)".into(),
                    corner,
                    value: Some(worst),
                    limit: 0.0,
                    pass: worst < 0.0,
                });
            }
        }
    }
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
    Ok(checks)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GAINS: &str = include_str!("../../gains.toml");

    #[test]
    fn gains_file_is_what_the_firmware_builds() {
        let (spec, _) = parse(Path::new("gains.toml"), GAINS).unwrap();
        assert_eq!(spec, controller_core::drive::example_spec().unwrap());
    }

    #[test]
    fn shipped_gains_certify() {
        let (spec, c) = parse(Path::new("gains.toml"), GAINS).unwrap();
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
        assert_eq!(checks.len(), 8 * 4 + 1);
    }

    /// A speed range beyond the ICAD limit (645 rad/s on the nominal motor) must fail, and a
    /// phase-margin demand above what (20) offers must fail: the certification can say no.
    #[test]
    fn certification_rejects_what_it_should() {
        let (spec, c) = parse(Path::new("gains.toml"), GAINS).unwrap();
        let fast = CertifySpec { omega_r_max_rad_s: 800.0, ..c };
        assert!(
            certify(&spec, &fast).unwrap().iter().any(|ch| !ch.pass && ch.name.contains("closed-loop pole"))
        );
        let strict = CertifySpec { phase_margin_deg_min: 85.0, ..c };
        assert!(
            certify(&spec, &strict).unwrap().iter().any(|ch| !ch.pass && ch.name.contains("phase margin"))
        );
        let bad = GAINS.replace("rs_factor = [1.0, 1.5]", "rs_factor = [1.5, 1.0]");
        assert!(parse(Path::new("g.toml"), &bad).unwrap_err().contains("certify.rs_factor"));
        // The configured speed gain must lie in the range the firmware may be given.
        let bad = GAINS.replace("speed_kp_writable = [0.02, 0.1]", "speed_kp_writable = [0.06, 0.1]");
        assert!(parse(Path::new("g.toml"), &bad).unwrap_err().contains("writable"));
        // A writable range reaching kp ≤ −B makes the speed loop not robustly stable.
        let c_neg = CertifySpec { speed_kp_writable: [-0.01, 0.1], ..c };
        assert!(certify(&spec, &c_neg).unwrap().iter().any(|ch| !ch.pass && ch.name.starts_with("speed")));
    }
}
