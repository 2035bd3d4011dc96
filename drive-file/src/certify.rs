//! `[certify]`: the parameter intervals the drive must be robust to and what it must meet on
//! all of them (`design certify` checks it; the firmware enforces the writable ranges).

use crate::source::{FileError, Source, num};
use crate::values::Interval;
use controller_core::drive::DriveSpec;
use controller_core::speed::SpeedLaw;
use serde::Deserialize;

/// Largest electrical rotor speed a certificate may cover, rad/s (≈ 190 000 r/min for one
/// pole pair): beyond any induction motor, and it bounds the sweep's length.
pub const OMEGA_R_MAX_RAD_S: f64 = 20_000.0;

/// The range a `[certify]` parameter factor may take: a decade either way of the motor
/// file's value (beyond it the file describes another motor; identify it again).
pub const PARAMETER_FACTOR_RANGE: [f64; 2] = [0.1, 10.0];

/// `[certify]` as written.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CertifyTable {
    /// Electrical rotor speeds 0 … this, rad/s.
    pub omega_r_max_rad_s: f64,
    /// Multiplicative interval of R_s.
    pub rs_factor: Interval,
    /// Multiplicative interval of R_r.
    pub rr_factor: Interval,
    /// Multiplicative interval of L_s, L_r, L_m (together).
    pub inductance_factor: Interval,
    /// Multiplicative interval of J.
    pub j_factor: Interval,
    /// Saturated-P speed gain range accepted over the link, N·m per rad/s.
    pub speed_kp_writable: Interval,
    /// τ_max range accepted over the link, N·m.
    pub speed_tau_max_nm_writable: Interval,
    /// Minimum phase margin of the individual channel, degrees.
    pub phase_margin_deg_min: f64,
    /// Minimum gain margin (increase and reduction), dB.
    pub gain_margin_db_min: f64,
    /// Minimum structural margin of γh to (1, 0), dB.
    pub gamma_h_margin_db_min: f64,
}

/// Validated `[certify]` (intervals as `[lo, hi]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Certify {
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
    /// Saturated-P speed gain range the firmware accepts over its link.
    pub speed_kp_writable: [f64; 2],
    /// τ_max range the firmware accepts over its link, N·m.
    pub speed_tau_max_nm_writable: [f64; 2],
    /// Minimum phase margin, degrees.
    pub phase_margin_deg_min: f64,
    /// Minimum gain margin, dB.
    pub gain_margin_db_min: f64,
    /// Minimum γh margin, dB.
    pub gamma_h_margin_db_min: f64,
}

impl CertifyTable {
    /// Validate against the drive it certifies; errors point at the value.
    pub fn validate(&self, src: &Source<'_>, spec: &DriveSpec) -> Result<Certify, FileError> {
        let w = self.omega_r_max_rad_s;
        src.check(
            w.is_finite() && (0.0..=OMEGA_R_MAX_RAD_S).contains(&w),
            "certify.omega_r_max_rad_s",
            &format!("is {}; must lie in [0, {OMEGA_R_MAX_RAD_S}] rad/s", num(w)),
        )?;
        // A certificate short of base speed leaves the current loops unchecked where the
        // drive runs at full flux (and the fault matrix's and the campaign's top speed, which
        // it caps, at a standstill for 0: found by trying).
        let base = crate::motor::no_load_base_speed_el_rad_s(
            &spec.motor,
            spec.flux_ref_wb,
            spec.protection.vdc_min_v,
        );
        src.check(
            w >= base,
            "certify.omega_r_max_rad_s",
            &format!(
                "is {} rad/s, below the drive's no-load base speed on its lowest bus \
                 (protection.vdc_min_v = {} V): {} rad/s electrical; the certificate must cover \
                 the speeds the drive runs at",
                num(w),
                num(spec.protection.vdc_min_v),
                num((base * 10.0).ceil() / 10.0),
            ),
        )?;
        // The parameter factors (`factor`) lie within a decade each way of the motor file's
        // value: wider, the box is no longer one motor (`rs_factor = [1.0, 1e300]` was
        // accepted: found by trying).
        for (key, i, factor) in [
            ("rs_factor", self.rs_factor, true),
            ("rr_factor", self.rr_factor, true),
            ("inductance_factor", self.inductance_factor, true),
            ("j_factor", self.j_factor, true),
            ("speed_kp_writable", self.speed_kp_writable, false),
            ("speed_tau_max_nm_writable", self.speed_tau_max_nm_writable, false),
        ] {
            let key = format!("certify.{key}");
            let (lo, hi) = (num(i.lo), num(i.hi));
            src.check(
                i.is_ordered() && i.lo > 0.0,
                &key,
                &format!("is [{lo}, {hi}]; needs finite 0 < lo ≤ hi"),
            )?;
            let [min, max] = PARAMETER_FACTOR_RANGE;
            src.check(
                !factor || (i.lo >= min && i.hi <= max),
                &key,
                &format!("is [{lo}, {hi}]; a factor of the motor file's value must lie in [{min}, {max}]"),
            )?;
        }
        for (key, x) in [
            ("phase_margin_deg_min", self.phase_margin_deg_min),
            ("gain_margin_db_min", self.gain_margin_db_min),
            ("gamma_h_margin_db_min", self.gamma_h_margin_db_min),
        ] {
            src.check(x.is_finite(), &format!("certify.{key}"), &format!("is {x}; must be a finite number"))?;
        }
        if let SpeedLaw::SaturatedP { kp, tau_max_nm } = spec.speed_law {
            src.check(
                self.speed_kp_writable.contains(kp),
                "certify.speed_kp_writable",
                &format!("must contain the configured controller.speed.kp = {kp}"),
            )?;
            src.check(
                self.speed_tau_max_nm_writable.contains(tau_max_nm),
                "certify.speed_tau_max_nm_writable",
                &format!("must contain the configured controller.speed.tau_max_nm = {tau_max_nm}"),
            )?;
        }
        Ok(Certify {
            omega_r_max_rad_s: w,
            rs_factor: self.rs_factor.ends(),
            rr_factor: self.rr_factor.ends(),
            inductance_factor: self.inductance_factor.ends(),
            j_factor: self.j_factor.ends(),
            speed_kp_writable: self.speed_kp_writable.ends(),
            speed_tau_max_nm_writable: self.speed_tau_max_nm_writable.ends(),
            phase_margin_deg_min: self.phase_margin_deg_min,
            gain_margin_db_min: self.gain_margin_db_min,
            gamma_h_margin_db_min: self.gamma_h_margin_db_min,
        })
    }
}
