//! A campaign's verdicts summed up: per manoeuvre and per requirement, the JSON summary, the
//! step-response band and the plots.

use super::*;

/// One manoeuvre's runs: counts and worst values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ManoeuvreStats {
    /// The manoeuvre.
    pub manoeuvre: Manoeuvre,
    /// Runs.
    pub runs: usize,
    /// Runs that passed.
    pub passed: usize,
    /// Largest tracking error, rad/s (`None`: no runs).
    pub worst_tracking_error_rad_s: Option<f64>,
    /// Largest torque ripple, N·m (`None`: no runs).
    pub worst_ripple_nm: Option<f64>,
    /// Smallest and largest flux ratio (`None`: no runs — the table showed "inf … 0.000" for
    /// a shard without the manoeuvre: found by trying).
    pub flux_ratio: Option<[f64; 2]>,
}

/// [`ManoeuvreStats`] of each manoeuvre.
pub fn per_manoeuvre(verdicts: &[Verdict]) -> Vec<ManoeuvreStats> {
    Manoeuvre::ALL
        .iter()
        .map(|&m| {
            let of: Vec<&Verdict> = verdicts.iter().filter(|v| v.manoeuvre == m).collect();
            let some = |x: f64| (!of.is_empty()).then_some(x);
            ManoeuvreStats {
                manoeuvre: m,
                runs: of.len(),
                passed: of.iter().filter(|v| v.passed()).count(),
                worst_tracking_error_rad_s: some(
                    of.iter().map(|v| v.tracking_error_rad_s).fold(0.0, f64::max),
                ),
                worst_ripple_nm: some(of.iter().map(|v| v.ripple_nm).fold(0.0, f64::max)),
                flux_ratio: (!of.is_empty()).then(|| {
                    [
                        of.iter().map(|v| v.flux_ratio[0]).fold(f64::INFINITY, f64::min),
                        of.iter().map(|v| v.flux_ratio[1]).fold(0.0, f64::max),
                    ]
                }),
            }
        })
        .collect()
}

/// One requirement over a campaign's runs: how many measured it, how many met it, and its
/// worst run (least margin).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RequirementStats {
    /// The requirement.
    pub requirement: Requirement,
    /// Runs that measured it.
    pub runs: usize,
    /// Runs that met it.
    pub met: usize,
    /// The worst run's index and measure.
    pub worst: Option<(u64, Measure)>,
}

/// [`RequirementStats`] of each requirement the campaign measures
/// ([`CAMPAIGN_REQUIREMENTS`]).
pub fn per_requirement(verdicts: &[Verdict]) -> Vec<RequirementStats> {
    CAMPAIGN_REQUIREMENTS
        .iter()
        .map(|&r| {
            let of: Vec<(u64, Measure)> = verdicts
                .iter()
                .filter_map(|v| v.measures.iter().find(|m| m.requirement == r).map(|m| (v.k, *m)))
                .collect();
            let worst = judge::worst_each_tagged(of.iter().copied()).into_iter().next();
            RequirementStats {
                requirement: r,
                runs: of.len(),
                met: of.iter().filter(|(_, m)| m.met()).count(),
                worst,
            }
        })
        .collect()
}

/// Nanoseconds of computation per simulated PWM period (all cores' work in `elapsed_s`;
/// each run as long as it lasted: the requirements lengthen some, [`WINDOW_MARGIN`]).
pub fn ns_per_period(c: &Campaign, verdicts: &[Verdict], elapsed_s: f64) -> f64 {
    let simulated_s: f64 = verdicts.iter().map(|v| v.duration_s).sum();
    1e9 * elapsed_s / (simulated_s * c.spec.pwm_frequency_hz).max(1.0)
}

/// The runs whose rotor flux left [`FLUX_MODEL_BAND`] of the drive's model (a diagnostic).
pub fn flux_outside_model(verdicts: &[Verdict]) -> Vec<u64> {
    verdicts
        .iter()
        .filter(|v| !(v.flux_ratio[0] >= FLUX_MODEL_BAND[0] && v.flux_ratio[1] <= FLUX_MODEL_BAND[1]))
        .map(|v| v.k)
        .collect()
}

/// The campaign's summary as JSON: what was run, the criteria, the counts and worst values
/// per manoeuvre, the failed runs, and the time it took.
pub fn summary(c: &Campaign, verdicts: &[Verdict], elapsed_s: f64) -> serde_json::Value {
    let per: Vec<_> = per_manoeuvre(verdicts)
        .iter()
        .map(|m| {
            serde_json::json!({
                "manoeuvre": m.manoeuvre.name(),
                "runs": m.runs,
                "passed": m.passed,
                "worst_tracking_error_rad_s": m.worst_tracking_error_rad_s,
                "worst_ripple_nm": m.worst_ripple_nm,
                "flux_ratio_min": m.flux_ratio.map(|r| r[0]),
                "flux_ratio_max": m.flux_ratio.map(|r| r[1]),
            })
        })
        .collect();
    let requirements: Vec<_> = per_requirement(verdicts)
        .iter()
        .map(|r| {
            serde_json::json!({
                "requirement": r.requirement.to_string(),
                "runs": r.runs,
                "met": r.met,
                "worst_run": r.worst.map(|(k, _)| k),
                "worst_value": r.worst.map(|(_, m)| m.value).filter(|x| x.is_finite()),
                "allowed": r.worst.map(|(_, m)| m.allowed).filter(|x| x.is_finite()),
                "margin": r.worst.map(|(_, m)| m.margin()).filter(|x| x.is_finite()),
                "worst_corner": r.worst.map(|(k, _)| {
                    let s = c.sample(k);
                    serde_json::json!({"rs_factor": s.rs, "rr_factor": s.rr, "inductance_factor": s.l, "j_factor": s.j})
                }),
            })
        })
        .collect();
    let missed: Vec<String> = per_requirement(verdicts)
        .iter()
        .filter(|r| r.met < r.runs)
        .map(|r| r.requirement.to_string())
        .collect();
    serde_json::json!({
        "requirements": requirements,
        "requirements_missed": missed,
        "runs": verdicts.len(),
        "passed": verdicts.iter().filter(|v| v.passed()).count(),
        "failed": verdicts.iter().filter(|v| !v.passed()).map(|v| v.k).collect::<Vec<_>>(),
        "campaign_runs": c.runs,
        "corner_runs": CORNER_RUNS,
        "shard": format!("{}/{}", c.shard.0, c.shard.1),
        "seed": c.seed,
        "duration_s": c.duration_s,
        "vdc_v": c.vdc_v,
        "omega_s_rad_s": c.omega_s_rad_s(),
        "box": {
            "rs_factor": c.certify.rs_factor,
            "rr_factor": c.certify.rr_factor,
            "inductance_factor": c.certify.inductance_factor,
            "j_factor": c.certify.j_factor,
        },
        "criteria": {
            "ripple_nm": RIPPLE_FRACTION * torque_limit_nm(&c.spec),
        },
        // The drive against its own shadow: recorded, never a verdict.
        "diagnostics": {
            "tracking_rad_s": TRACKING_FRACTION * c.omega_s_rad_s() + TRACKING_FLOOR_RAD_S,
            "flux_model_band": FLUX_MODEL_BAND,
            "flux_outside_model": flux_outside_model(verdicts),
        },
        "per_manoeuvre": per,
        "step_band": StepBand::of(c, verdicts),
        "elapsed_s": elapsed_s,
        "ns_per_period": ns_per_period(c, verdicts, elapsed_s),
    })
}

/// Points a run keeps of its first step's response ([`Verdict::step_response`]).
pub const STEP_RESPONSE_POINTS: usize = 200;

/// The band of every run's first speed step over the box — the least and the most of the
/// step covered at each time after it — and what the requirements allow: the overshoot
/// ceiling, the settling band about the target, the least rise and settling times any run
/// was allowed. Kept in the campaign's summary (`step_band`), from which `design certify`
/// draws the certificate's page.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StepBand {
    /// The campaign's speed step, rad/s.
    pub step_rad_s: f64,
    /// Runs in the band.
    pub runs: usize,
    /// Times after the step, s.
    pub t_s: Vec<f64>,
    /// The least of the step covered at each time, over the runs (fraction of the step).
    pub least: Vec<f64>,
    /// The most.
    pub most: Vec<f64>,
    /// `1 + speed_overshoot_fraction`.
    pub overshoot_ceiling: f64,
    /// The settling band's half-width (fraction of the step).
    pub band_fraction: f64,
    /// The least rise time any run was allowed, s.
    pub rise_allowed_least_s: Option<f64>,
    /// The least settling time any run was allowed, s.
    pub settling_allowed_least_s: Option<f64>,
}

impl StepBand {
    /// The band of `verdicts`' first steps ([`Verdict::step_response`]) on
    /// [`STEP_RESPONSE_POINTS`] times.
    pub fn of(c: &Campaign, verdicts: &[Verdict]) -> Self {
        let req = &c.requirements;
        let end = verdicts.iter().filter_map(|v| v.step_response.last().map(|p| p.0)).fold(0.0, f64::max);
        let n = STEP_RESPONSE_POINTS;
        let at = |v: &Verdict, t: f64| {
            let r = &v.step_response;
            let k = r.iter().position(|p| p.0 >= t)?;
            let (b, a) = (r.get(k)?, if k == 0 { r.get(k)? } else { r.get(k - 1)? });
            let f = if b.0 > a.0 { (t - a.0) / (b.0 - a.0) } else { 0.0 };
            Some(a.1 + f * (b.1 - a.1))
        };
        let (mut t_s, mut least, mut most) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..=n {
            let t = end * i as f64 / n as f64;
            let ys: Vec<f64> = verdicts.iter().filter_map(|v| at(v, t)).filter(|y| y.is_finite()).collect();
            if let (Some(a), Some(b)) =
                (ys.iter().copied().reduce(f64::min), ys.iter().copied().reduce(f64::max))
            {
                t_s.push(t);
                least.push(a);
                most.push(b);
            }
        }
        let least_allowed = |r: Requirement| {
            verdicts
                .iter()
                .filter_map(|v| v.measures.iter().find(|m| m.requirement == r).map(|m| m.allowed))
                .filter(|t| t.is_finite())
                .reduce(f64::min)
        };
        Self {
            step_rad_s: c.omega_s_rad_s(),
            runs: verdicts.len(),
            t_s,
            least,
            most,
            overshoot_ceiling: 1.0 + req.speed_overshoot_fraction,
            band_fraction: c.scales().settling_band_fraction(req, c.omega_s_rad_s()),
            rise_allowed_least_s: least_allowed(Requirement::SpeedRiseTime),
            settling_allowed_least_s: least_allowed(Requirement::SpeedSettlingTime),
        }
    }

    /// The band against what the requirements allow (vertical lines: the least rise and
    /// settling times allowed).
    pub fn plot(&self) -> String {
        use report::plot::{Series, line_plot};
        let end = self.t_s.last().copied().unwrap_or(0.0);
        let pairs = |y: &[f64]| self.t_s.iter().copied().zip(y.iter().copied()).collect::<Vec<_>>();
        let flat = |y: f64| vec![(0.0, y), (end, y)];
        let vertical =
            |t: Option<f64>| t.filter(|&t| t <= end).map_or_else(Vec::new, |t| vec![(t, 0.0), (t, 1.0)]);
        line_plot(
            &format!(
                "The first speed step of {} runs (±{:.1} rad/s) over the box against [requirements]",
                self.runs, self.step_rad_s
            ),
            "s after the step (y: fraction of the step)",
            &[
                Series::line("least over the box", pairs(&self.least)),
                Series::line("most over the box", pairs(&self.most)),
                Series::line("overshoot allowed", flat(self.overshoot_ceiling)),
                Series::line("settling band", flat(1.0 - self.band_fraction)),
                Series::line("settling band (upper)", flat(1.0 + self.band_fraction)),
                Series::line("rise time allowed (least)", vertical(self.rise_allowed_least_s)),
                Series::line("settling time allowed (least)", vertical(self.settling_allowed_least_s)),
            ],
        )
    }
}

/// The requirements' picture (`requirements.svg`): [`StepBand::plot`].
pub fn requirements_plot(c: &Campaign, verdicts: &[Verdict]) -> String {
    StepBand::of(c, verdicts).plot()
}

/// The overview plot: each run's tracking error against its limit (relative), by run index,
/// passed and failed apart.
pub fn plot(c: &Campaign, verdicts: &[Verdict]) -> String {
    use report::plot::{Series, line_plot};
    let limit = TRACKING_FRACTION * c.omega_s_rad_s() + TRACKING_FLOOR_RAD_S;
    let pts = |pass: bool| -> Vec<(f64, f64)> {
        verdicts
            .iter()
            .filter(|v| v.passed() == pass)
            .map(|v| (v.k as f64, v.tracking_error_rad_s / limit))
            .collect()
    };
    line_plot(
        &format!("Campaign: {} runs of {} s, tracking error over its limit", verdicts.len(), c.duration_s),
        "run k",
        &[Series::markers("passed", pts(true)), Series::markers("failed", pts(false))],
    )
}
