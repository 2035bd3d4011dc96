//! The requirements a speed law is predicted to miss: a short campaign over the box before a file is written, and the writable gain range it bounds.

use super::*;

/// The bus the requirements are predicted on: the file's rated bus, or the campaign's
/// default within the drive's bus range ([`hil_sim::commands::default_bus_v`]).
pub(super) fn prediction_bus_v(file: &drive_file::DriveFile) -> f64 {
    hil_sim::commands::default_bus_v(file)
}

/// The requirements `spec`'s speed law misses over the box `cert`, predicted on the ideal
/// actuator (`hil_sim::campaign::Campaign::predict`) over the corner runs (every corner
/// through every manoeuvre) of the campaigns tune judges on (`TuneCampaigns`): each missed
/// requirement once, with its worst run.
pub fn predicted_misses(
    spec: &DriveSpec,
    cert: &CertifySpec,
    file: &drive_file::DriveFile,
    vdc_v: f64,
) -> Result<Misses, String> {
    let campaigns = TuneCampaigns::new(spec, cert, file, vdc_v);
    Ok(missed(campaigns.prediction()?.measures_where(&spec.speed_law, |_| true)?))
}

/// The campaign run `design tune` names: its campaign's run length and its index there
/// (`hil-sim campaign FILE --duration D` runs it as run `k`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TuneRun {
    /// The run length of its campaign, s.
    pub duration_s: f64,
    /// Its index in that campaign.
    pub k: u64,
}

impl core::fmt::Display for TuneRun {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "run {} of the {:.2} s campaign", self.k, self.duration_s)
    }
}

/// The campaigns `design tune` predicts and confirms a speed law on, each on its corner runs
/// (every corner through every manoeuvre), as `hil-sim campaign` runs them:
/// - **short**: runs of [`SHORT_RUN_S`], or the least the campaign accepts for a motor the
///   drive magnetizes more slowly ([`hil_sim::campaign::Campaign::least_duration_s`]: 1.08 s
///   for a 1.3 kW member at 10 kHz, 2.83 s for the 500 hp Krause machine), whose steps are
///   small enough for every inertia to follow them linearly — where a one-degree PI
///   overshoots most (a reversal at the torque limit hides it: tuned on the full-range runs
///   alone, a PI met them all and overshot 0.21 against 0.1 in 254 of 1 000 runs of 1 s). The
///   times such small steps are allowed come from the fastest loop the board's encoder allows
///   ([`hil_sim::requirements::least_step_times`]), and each half of a run lasts as long as
///   they need;
/// - **full range**: runs long enough for a slow rotor to magnetize first and for the largest
///   inertia to step to the box's top speed
///   ([`hil_sim::campaign::Campaign::full_range_duration_s`]), field weakening included — as
///   `population` and `hil-sim campaign` without `--duration` run them.
///
/// One campaign when there is no short one, or the full range is no longer.
pub(super) struct TuneCampaigns {
    each: Vec<hil_sim::campaign::Campaign>,
}

impl TuneCampaigns {
    pub(super) fn new(
        spec: &DriveSpec,
        cert: &CertifySpec,
        file: &drive_file::DriveFile,
        vdc_v: f64,
    ) -> Self {
        use hil_sim::campaign::{CORNER_RUNS, Campaign};
        let short = Campaign {
            spec: *spec,
            certify: *cert,
            vdc_v,
            duration_s: SHORT_RUN_S,
            runs: CORNER_RUNS,
            seed: 1,
            shard: (0, 1),
            encoder_lines: file.encoder_lines(),
            plant: None,
            requirements: file.requirements,
        };
        let short = Campaign { duration_s: SHORT_RUN_S.max(short.least_duration_s()), ..short };
        let full = Campaign { duration_s: short.duration_s.max(short.full_range_duration_s()), ..short };
        let each = if full.duration_s > short.duration_s { vec![short, full] } else { vec![full] };
        Self { each }
    }

    /// The same campaigns with speed law `law` in the drive.
    pub(super) fn with_law(&self, law: &SpeedLaw) -> Self {
        let each = self
            .each
            .iter()
            .map(|c| hil_sim::campaign::Campaign { spec: DriveSpec { speed_law: *law, ..c.spec }, ..*c })
            .collect();
        Self { each }
    }

    /// The campaigns themselves.
    pub(super) fn campaigns(&self) -> Vec<hil_sim::campaign::Campaign> {
        self.each.clone()
    }

    /// Their corner runs prepared for predictions under many speed laws.
    pub(super) fn prediction(&self) -> Result<Prediction<'_>, String> {
        let each = self
            .each
            .iter()
            .map(|c| Ok((c.duration_s, c.predictor(0..hil_sim::campaign::CORNER_RUNS)?)))
            .collect::<Result<_, String>>()?;
        Ok(Prediction { each })
    }

    /// What their corner runs miss in software in the loop: each missed requirement or failed
    /// criterion with its runs count, of the first campaign (shortest first) that misses any
    /// — the longer ones are not run then (a refused point costs one campaign, not all) — or
    /// `None` when every run of every campaign passes.
    pub(super) fn sil_misses(&self) -> Result<Option<SilMiss>, String> {
        for c in &self.each {
            if let Some(miss) = super::sil_misses(c)? {
                let words = format!("{} (runs of {:.2} s)", miss.words, c.duration_s);
                return Ok(Some(SilMiss { words, ..miss }));
            }
        }
        Ok(None)
    }

    /// `the 64 corner runs of the 1.00 s and the 6.38 s campaigns` (drive.toml's).
    pub(super) fn words(&self) -> String {
        let lengths: Vec<String> = self.each.iter().map(|c| format!("{:.2} s", c.duration_s)).collect();
        let s = if self.each.len() > 1 { "s" } else { "" };
        format!(
            "the {} corner runs of the {} campaign{s}",
            hil_sim::campaign::CORNER_RUNS,
            lengths.join(" and the ")
        )
    }
}

/// The short campaign's run length, s (`TuneCampaigns`): `hil-sim campaign`'s `--duration`
/// of the docs' campaigns.
pub const SHORT_RUN_S: f64 = 1.0;

/// The corner runs of [`TuneCampaigns`], prepared ([`hil_sim::campaign::Predictor`]).
pub(super) struct Prediction<'a> {
    each: Vec<(f64, hil_sim::campaign::Predictor<'a>)>,
}

impl Prediction<'_> {
    /// Each run's predicted measures under `law`, on the runs with `keep(run)`.
    pub(super) fn measures_where(
        &self,
        law: &SpeedLaw,
        keep: impl Fn(TuneRun) -> bool + Sync,
    ) -> Result<Vec<(TuneRun, Vec<hil_sim::requirements::Measure>)>, String> {
        let mut all = Vec::new();
        for (duration_s, p) in &self.each {
            let run = |k| TuneRun { duration_s: *duration_s, k };
            let measures = p.measures_where(law, |k| keep(run(k)))?;
            all.extend(measures.into_iter().map(|(k, m)| (run(k), m)));
        }
        Ok(all)
    }
}

/// The requirements missed among runs' measures, each once with its worst run.
pub(super) fn missed(measures: Vec<(TuneRun, Vec<hil_sim::requirements::Measure>)>) -> Misses {
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
    pub(super) prediction: Prediction<'a>,
    pub(super) hard: Vec<TuneRun>,
}

impl Screen<'_> {
    pub(super) fn misses(&mut self, law: &SpeedLaw) -> Result<Misses, String> {
        let hard = &mut self.hard;
        if !hard.is_empty() {
            let first = missed(self.prediction.measures_where(law, |k| hard.contains(&k))?);
            if !first.is_empty() {
                return Ok(first);
            }
        }
        let rest = missed(self.prediction.measures_where(law, |k| !hard.contains(&k))?);
        for (k, _) in &rest {
            if hard.len() < SCREEN_RUNS && !hard.contains(k) {
                hard.push(*k);
            }
        }
        Ok(rest)
    }
}

/// What a speed law's drive missed in software in the loop ([`TuneCampaigns::sil_misses`]).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct SilMiss {
    /// Each missed requirement or failed criterion with its runs count: `speed_overshoot_fraction
    /// in 1 of 64 runs (runs of 1.00 s)`.
    pub(super) words: String,
    /// Only requirements the setpoint weight shapes ([`shaped_by_setpoint_weight`]) were missed
    /// — no fault, no other criterion.
    pub(super) shaped_only: bool,
}

/// The setpoint weights `design tune` tries for a speed PI, the one-degree PI first: the
/// largest that meets the requirements is taken (the least filtering of the reference).
pub const SETPOINT_WEIGHTS: [f64; 11] = [1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1, 0.0];

/// A requirement the setpoint weight shapes: the weight filters the reference only
/// (`controller_core::speed`), so it lowers the overshoot, and the settling time with it,
/// and leaves the loop's margins and its answer to a load as they are.
pub(super) fn shaped_by_setpoint_weight(r: drive_file::requirements::Requirement) -> bool {
    use drive_file::requirements::Requirement;
    matches!(r, Requirement::SpeedOvershoot | Requirement::SpeedSettlingTime)
}

/// PI law `law` with setpoint weight `b` (`None` for a P law: it has none).
pub(super) fn with_setpoint_weight(law: &SpeedLaw, b: f64) -> Option<SpeedLaw> {
    match *law {
        SpeedLaw::PiTorque { kp, ki, limit, .. } => {
            Some(SpeedLaw::PiTorque { kp, ki, limit, setpoint_weight: b })
        }
        SpeedLaw::PiIq { kp, ki, limit, .. } => Some(SpeedLaw::PiIq { kp, ki, limit, setpoint_weight: b }),
        SpeedLaw::SaturatedP { .. } => None,
    }
}

/// The PI law `law` at the next of [`SETPOINT_WEIGHTS`] below its own (`None` at 0 and for
/// a P law).
pub(super) fn lower_setpoint_weight(law: &SpeedLaw) -> Option<SpeedLaw> {
    let b = setpoint_weight(law);
    let next = SETPOINT_WEIGHTS.into_iter().find(|w| *w < b - 1e-9)?;
    with_setpoint_weight(law, next)
}

/// The PI law `law` with the largest of [`SETPOINT_WEIGHTS`] whose prediction (`predict`) meets the
/// requirements, and its misses (none) — or, when none does, the last weight tried and its
/// misses. The weight shapes the reference's response only (`controller_core::speed`): it
/// lowers the overshoot, and the settling time with it, and lengthens the rise; the search
/// stops at the first weight that misses anything else (a lower one cannot help).
pub fn weigh_setpoint(
    law: &SpeedLaw,
    mut predict: impl FnMut(&SpeedLaw) -> Result<Misses, String>,
) -> Result<(SpeedLaw, Misses), String> {
    let mut last = None;
    for b in SETPOINT_WEIGHTS {
        let law = with_setpoint_weight(law, b).ok_or("internal: a setpoint weight for a P law")?;
        let misses = predict(&law)?;
        let done = misses.is_empty() || !misses.iter().all(|(_, m)| shaped_by_setpoint_weight(m.requirement));
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

/// `requirements.x (worst run k of the d s campaign: value against allowed), …`.
pub(super) fn describe(misses: &[(TuneRun, hil_sim::requirements::Measure)]) -> String {
    misses
        .iter()
        .map(|(run, m)| format!("{} (worst {run}: {:.4} against {:.4})", m.requirement, m.value, m.allowed))
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
pub type Misses = Vec<(TuneRun, hil_sim::requirements::Measure)>;

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
