//! The requirements a speed law is predicted to miss: a short campaign over the box before a file is written, and the writable gain range it bounds.

use super::*;

/// The bus the requirements are predicted on: the file's rated bus, or the campaign's
/// default within the drive's bus range ([`hil_sim::commands::default_bus_v`]).
pub(super) fn prediction_bus_v(file: &drive_file::DriveFile) -> f64 {
    hil_sim::commands::default_bus_v(file)
}

/// The requirements `spec`'s speed law misses over the box `cert`, predicted on the ideal
/// actuator (`hil_sim::campaign::Campaign::predict`) over the campaign's corner runs (every
/// corner through every manoeuvre): each missed requirement once, with its worst run.
pub fn predicted_misses(
    spec: &DriveSpec,
    cert: &CertifySpec,
    file: &drive_file::DriveFile,
    vdc_v: f64,
) -> Result<Misses, String> {
    let c = prediction_campaign(spec, cert, file, vdc_v);
    let predictor = c.predictor(0..hil_sim::campaign::CORNER_RUNS)?;
    Ok(missed(predictor.measures(&spec.speed_law)?))
}

/// The campaign `design tune` predicts on: the corner runs (every corner through every
/// manoeuvre) of a campaign as `population` runs it — long enough for a slow rotor to
/// magnetize first and for the largest inertia to step to the box's top speed
/// ([`hil_sim::campaign::Campaign::full_range_duration_s`]), field weakening included.
pub(super) fn prediction_campaign(
    spec: &DriveSpec,
    cert: &CertifySpec,
    file: &drive_file::DriveFile,
    vdc_v: f64,
) -> hil_sim::campaign::Campaign {
    use hil_sim::campaign::{CORNER_RUNS, Campaign};
    let mut c = Campaign {
        spec: *spec,
        certify: *cert,
        vdc_v,
        duration_s: 1.0,
        runs: CORNER_RUNS,
        seed: 1,
        shard: (0, 1),
        encoder_lines: file.encoder_lines(),
        plant: None,
        requirements: file.requirements,
    };
    c.duration_s = c.duration_s.max(c.full_range_duration_s());
    c
}

/// The requirements missed among runs' measures, each once with its worst run.
pub(super) fn missed(measures: Vec<(u64, Vec<hil_sim::requirements::Measure>)>) -> Misses {
    let each =
        measures.into_iter().flat_map(|(k, ms)| ms.into_iter().filter(|m| !m.met()).map(move |m| (k, m)));
    hil_sim::requirements::worst_each_tagged(each)
}

/// Runs the screen of `design tune`'s PI search keeps as the hardest: tried first on every law.
pub const SCREEN_RUNS: usize = 8;

/// Many speed laws predicted over the corner runs ([`hil_sim::campaign::Predictor`]), the
/// runs that an earlier law missed tried first: a law that misses one of them is rejected
/// after those few runs (its misses then are those runs' only), one that meets them is
/// predicted on the rest. An empty answer is therefore always the whole prediction.
pub(super) struct Screen<'a> {
    pub(super) predictor: hil_sim::campaign::Predictor<'a>,
    pub(super) hard: Vec<u64>,
}

impl Screen<'_> {
    pub(super) fn misses(&mut self, law: &SpeedLaw) -> Result<Misses, String> {
        let hard = &mut self.hard;
        if !hard.is_empty() {
            let first = missed(self.predictor.measures_where(law, |k| hard.contains(&k))?);
            if !first.is_empty() {
                return Ok(first);
            }
        }
        let rest = missed(self.predictor.measures_where(law, |k| !hard.contains(&k))?);
        for (k, _) in &rest {
            if hard.len() < SCREEN_RUNS && !hard.contains(k) {
                hard.push(*k);
            }
        }
        Ok(rest)
    }
}

/// The setpoint weights `design tune` tries for a speed PI, the one-degree PI first: the
/// largest that meets the requirements is taken (the least filtering of the reference).
pub const SETPOINT_WEIGHTS: [f64; 11] = [1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1, 0.0];

/// The PI law `law` with the largest of [`SETPOINT_WEIGHTS`] whose prediction (`predict`) meets the
/// requirements, and its misses (none) — or, when none does, the last weight tried and its
/// misses. The weight shapes the reference's response only (`controller_core::speed`): it
/// lowers the overshoot, and the settling time with it, and lengthens the rise; the search
/// stops at the first weight that misses anything else (a lower one cannot help).
pub fn weigh_setpoint(
    law: &SpeedLaw,
    mut predict: impl FnMut(&SpeedLaw) -> Result<Misses, String>,
) -> Result<(SpeedLaw, Misses), String> {
    use drive_file::requirements::Requirement;
    let mut last = None;
    for b in SETPOINT_WEIGHTS {
        let law = match *law {
            SpeedLaw::PiTorque { kp, ki, limit, .. } => {
                SpeedLaw::PiTorque { kp, ki, limit, setpoint_weight: b }
            }
            SpeedLaw::PiIq { kp, ki, limit, .. } => SpeedLaw::PiIq { kp, ki, limit, setpoint_weight: b },
            SpeedLaw::SaturatedP { .. } => return Err("internal: a setpoint weight for a P law".into()),
        };
        let misses = predict(&law)?;
        let shaped =
            |r: Requirement| matches!(r, Requirement::SpeedOvershoot | Requirement::SpeedSettlingTime);
        let done = misses.is_empty() || !misses.iter().all(|(_, m)| shaped(m.requirement));
        last = Some((law, misses));
        if done {
            break;
        }
    }
    last.ok_or_else(|| "internal: no setpoint weight".into())
}

/// The setpoint weight of a PI law (1 for the P law: it has none).
pub(super) fn setpoint_weight(law: &SpeedLaw) -> f64 {
    match *law {
        SpeedLaw::PiTorque { setpoint_weight, .. } | SpeedLaw::PiIq { setpoint_weight, .. } => {
            setpoint_weight
        }
        SpeedLaw::SaturatedP { .. } => 1.0,
    }
}

/// `requirements.x (worst run k: value against allowed), …`.
pub(super) fn describe(misses: &[(u64, hil_sim::requirements::Measure)]) -> String {
    misses
        .iter()
        .map(|(k, m)| format!("{} (worst run {k}: {:.4} against {:.4})", m.requirement, m.value, m.allowed))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Halvings of the bisection for the least writable saturated-P k_p: within 2^-8 of
/// [k_p/2, k_p].
pub const WRITABLE_KP_BISECTIONS: u32 = 8;

/// The least saturated-P k_p in `[k_p/2, k_p]` whose predicted response still meets the
/// requirements (`spec`'s k_p meets them): k_p/2 if it does, else a bisection (the droop
/// falls as k_p rises).
pub(super) fn least_writable_kp(
    spec: &DriveSpec,
    cert: &CertifySpec,
    file: &drive_file::DriveFile,
    vdc_v: f64,
) -> Result<f64, String> {
    let SpeedLaw::SaturatedP { kp, tau_max_nm } = spec.speed_law else {
        return Ok(cert.speed_kp_writable[0]);
    };
    let meets = |k: f64| -> Result<bool, String> {
        let at = DriveSpec { speed_law: SpeedLaw::SaturatedP { kp: k, tau_max_nm }, ..*spec };
        Ok(predicted_misses(&at, cert, file, vdc_v)?.is_empty())
    };
    let (mut lo, mut hi) = (0.5 * kp, kp);
    if meets(lo)? {
        return Ok(lo);
    }
    for _ in 0..WRITABLE_KP_BISECTIONS {
        let mid = 0.5 * (lo + hi);
        if meets(mid)? { hi = mid } else { lo = mid }
    }
    Ok(hi)
}

/// Requirements missed, each with its worst run ([`predicted_misses`]).
pub type Misses = Vec<(u64, hil_sim::requirements::Measure)>;

/// The corners of the link's writable speed gains (`certify.speed_kp_writable` ×
/// `certify.speed_tau_max_nm_writable`, a saturated-P law's: the link rewrites no other) at
/// which the law's predicted response misses the file's requirements over the box
/// ([`predicted_misses`], on the bus the tune predicts on): each corner's `(k_p, τ_max)` with
/// what it misses. Empty: any gains the link accepts still meet them (predicted; the droop
/// τ_L/k_p grows as k_p falls, and is largest at the largest τ_max, whose load is 0.8 × it).
pub fn writable_gain_misses(
    spec: &DriveSpec,
    cert: &CertifySpec,
    file: &drive_file::DriveFile,
) -> Result<Vec<([f64; 2], Misses)>, String> {
    if !matches!(spec.speed_law, SpeedLaw::SaturatedP { .. }) {
        return Ok(Vec::new());
    }
    let vdc = prediction_bus_v(file);
    let mut missed = Vec::new();
    for kp in cert.speed_kp_writable {
        for tau_max_nm in cert.speed_tau_max_nm_writable {
            let at = DriveSpec { speed_law: SpeedLaw::SaturatedP { kp, tau_max_nm }, ..*spec };
            let misses = predicted_misses(&at, cert, file, vdc)?;
            if !misses.is_empty() {
                missed.push(([kp, tau_max_nm], misses));
            }
        }
    }
    Ok(missed)
}
