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

use crate::icad::{analyse, closed_loop_abscissa};
use crate::kharitonov::IntervalPoly;
use controller_core::drive::DriveSpec;
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
        assert_eq!(checks.len(), 8 * 4 + 1);
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
}
