//! The nonlinear campaign (issue 21): a drive file run in software in the loop over the
//! corners and seeded random samples of its `[certify]` parameter box, each sample through
//! manoeuvres across the operating range, each run judged by stated criteria.
//!
//! **Runs.** Run k of a campaign takes its parameters from the box — the 16 corners of
//! (R_s, R_r, L, J) first, each with every manoeuvre, then uniform random samples from
//! a generator seeded by (campaign seed, k) — and manoeuvre `k mod 4` ([`Manoeuvre`]); its
//! sensors are realistic ([`SensorModel::realistic_for_trip`]: scaled to the drive's trip level, seeded by k). Every run is therefore
//! reproducible on its own, and `--shard i/N` (the runs with k mod N = i) splits a campaign
//! over machines whose CSV files concatenate into the whole one.
//!
//! **Manoeuvres** (enable at 0; the speed step once magnetized, at [`Campaign::step_s`]; the second
//! event half-way through the rest of the run): to +ω_s with a load step of 0.8 ×
//! the largest load the motor holds there (motoring), to −ω_s with its mirror, to +ω_s with
//! a load that drives (generating), and a reversal +ω_s/2 → −ω_s/2. The largest load is
//! τ_L − B·ω_s motoring and τ_L + B·ω_s braking: τ_L is τ_max, or less where the run's plant
//! cannot give τ_max at ω_s in that direction on the bus and the current limit (its
//! envelope, the [`IdealLoop`]'s), and the motor's own friction takes or gives B·ω_s. A load
//! beyond what the motor can hold there tests the motor, not the drive — 0.8·τ_max
//! generating at twice base speed drove the rotor away from every 8-pole 1.3 kW member's
//! reference (`FollowingError`, rightly, in 50 of 50 runs).
//! ω_s is the top speed of the box ([`Campaign::top_speed_rad_s`]: the certified
//! ω_r,max/p, at most twice the no-load base speed on the bus — field weakening — and at most
//! where the friction takes [`FRICTION_SHARE_MAX`] of the drive's torque), or what the
//! weakest corner (largest J) can reach at τ_max in [`REACH_FRACTION`] of the first half:
//! runs shorter than [`Campaign::full_range_duration_s`] stay below the top speed — a large
//! motor's far below its base speed.
//!
//! **Verdict** (each run; [`Verdict`]): no fault latched; every requirement of the file's
//! `[requirements]` met ([`crate::requirements`]: the machine's own speed, torque and rotor
//! flux against what the user asked — the flux's steady error against the drive's flux
//! reference among them); and no oscillation: torque peak to peak about its trend line over
//! the last [`RIPPLE_WINDOW_S`] below [`RIPPLE_FRACTION`]·τ_max.
//!
//! **Diagnostics** (recorded in `campaign.csv` and `summary.json`, never a verdict: the drive
//! against its own shadow, issue 51):
//! - tracking: the largest distance from the same speed law driving an *ideal* torque
//!   actuator on the same mechanics with the same load ([`IdealLoop`]), beside
//!   [`TRACKING_FRACTION`]·ω_s + [`TRACKING_FLOOR_RAD_S`] (`campaign.svg`);
//! - flux: the machine's rotor flux over the drive's flux model once magnetized; the runs
//!   that leave [`FLUX_MODEL_BAND`] are listed (a model that does not know the machine — a
//!   corner the estimates do not reach — shows there first; whether the flux the drive then
//!   makes is the one asked is the requirement's verdict).

use crate::inverter::InverterModel;
mod ideal;
mod load;
use load::overhauling_load_nm;
mod stats;

use crate::requirements::{self as judge, Measure};
use crate::rng::mix;
use crate::scenario::Builtin;
use crate::sensors::SensorModel;
use crate::sim::{Event, LoadModel, Row, Scenario};
use controller_core::drive::{DriveSpec, Mode, Reference};
use controller_core::encoder::{EncoderConfig, SPEED_WINDOW_READS};
use controller_core::magnetics::Saturation;
use controller_core::motor::MotorParams;
use controller_core::speed::SpeedLaw;
use drive_file::certify::Certify;
use drive_file::requirements::{Requirement, Requirements};
pub use ideal::IdealLoop;
use rayon::prelude::*;
pub use stats::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// The speed step comes once the drive is magnetized: at this time, s, or later for a
/// motor the drive magnetizes more slowly ([`Campaign::step_s`]).
pub const STEP_S: f64 = 0.25;
/// A run must last at least this long after its speed step, s (the shortest the campaign
/// accepts; a 1 s run leaves 0.75 s).
pub const MIN_AFTER_STEP_S: f64 = 0.25;
/// ω_s is what the largest inertia reaches at τ_max in this fraction of the first half.
pub const REACH_FRACTION: f64 = 0.6;
/// Load step as a fraction of the largest load the motor holds at ω_s: τ_max (or the
/// envelope's torque there, if less) less its own friction.
pub const LOAD_FRACTION: f64 = 0.8;
/// ω_s is at most the speed where the motor's friction `B·ω` takes this share of the torque
/// the drive's envelope gives there ([`Campaign::friction_bound_rad_s`]): beyond it the
/// torque left accelerates the largest inertia ever more slowly, and the step tests the
/// motor's friction, not the drive (the shipped 24 V drive's certified 2 × base speed, 283
/// rad/s, is beyond any: at 261 rad/s its envelope gives 0.047 N·m, `hil-sim envelope
/// drives/em-synergy-24v.toml`, and its friction there is 2.04·10⁻⁴ N·m·s × 261 rad/s =
/// 0.053 N·m).
pub const FRICTION_SHARE_MAX: f64 = 0.5;
/// Bisection steps of [`Campaign::friction_bound_rad_s`] (2⁻³⁰ of the top speed).
const FRICTION_BOUND_STEPS: u32 = 30;
/// Tracking tolerance: this fraction of ω_s …
pub const TRACKING_FRACTION: f64 = 0.05;
/// … plus this, rad/s.
pub const TRACKING_FLOOR_RAD_S: f64 = 2.0;
/// Rotor flux over the drive's flux model ψ̂_r, once magnetized: a run outside this band is
/// listed among the diagnostics (`flux_outside_model` in `summary.json`), not failed.
pub const FLUX_MODEL_BAND: [f64; 2] = [0.5, 1.3];
/// Torque ripple is measured over the last this long of the run, s: the requirements'
/// steady-state window.
pub const RIPPLE_WINDOW_S: f64 = judge::STEADY_WINDOW_S;
/// Torque ripple limit as a fraction of τ_max (the judge's, which bounds a speed loop's gain
/// by it).
pub const RIPPLE_FRACTION: f64 = judge::RIPPLE_FRACTION;
/// The 16 corners of (R_s, R_r, L, J).
pub const CORNERS: u64 = 16;
/// The runs that take every corner through every manoeuvre: a campaign's first runs, the
/// fewest `design certify --campaign` accepts (its summary's `corner_runs`).
pub const CORNER_RUNS: u64 = CORNERS * Manoeuvre::ALL.len() as u64;

/// The requirements a campaign run measures: all but the current loops' bandwidth, the
/// linear certificate's (`design certify`; last in [`Requirement::ALL`]).
pub const CAMPAIGN_REQUIREMENTS: &[Requirement] = Requirement::ALL.split_at(8).0;

/// What run `k` is before it runs ([`Campaign::setup`]).
#[derive(Clone, Copy, Debug)]
struct Setup {
    sample: Sample,
    manoeuvre: Manoeuvre,
    plant: MotorParams,
    plant_saturation: Option<Saturation>,
    /// What the simulated machine has beyond its circuit and curve.
    extras: plant::Extras,
    /// ω_s, mechanical rad/s.
    w: f64,
    step_s: f64,
    t2_s: f64,
    duration_s: f64,
    first_step: StepPlan,
    second: Second,
    second_event: SecondEvent,
    ideal: IdealLoop,
}

/// A campaign's runs prepared once ([`Campaign::predictor`]) to predict many speed laws on,
/// as `design tune` searches for one.
#[derive(Debug)]
pub struct Predictor<'a> {
    campaign: &'a Campaign,
    setups: Vec<(u64, Setup)>,
}

impl Predictor<'_> {
    /// Each run's [`PREDICTED`] requirements under speed law `law` in place of the
    /// campaign's: [`Campaign::predict`] of a campaign whose drive runs `law`, without
    /// preparing the runs again. The law must keep the campaign's torque limit (the runs'
    /// load steps and windows are sized from it).
    pub fn measures(&self, law: &SpeedLaw) -> Result<Vec<(u64, Vec<Measure>)>, String> {
        self.measures_where(law, |_| true)
    }

    /// [`Predictor::measures`] on the prepared runs `k` with `keep(k)`.
    pub fn measures_where(
        &self,
        law: &SpeedLaw,
        keep: impl Fn(u64) -> bool + Sync,
    ) -> Result<Vec<(u64, Vec<Measure>)>, String> {
        let spec = DriveSpec { speed_law: *law, ..self.campaign.spec };
        let (was, is) = (torque_limit_nm(&self.campaign.spec), torque_limit_nm(&spec));
        if was.to_bits() != is.to_bits() {
            return Err(format!(
                "a prediction's speed law keeps the campaign's torque limit ({was} N·m), not {is} N·m"
            ));
        }
        let t_s = self.campaign.slow_period_s();
        // In parallel (rayon), in run order: `design tune` predicts every law it tries on
        // every corner run, and each is thousands of slow periods on the envelope.
        self.setups
            .par_iter()
            .filter(|(k, _)| keep(*k))
            .map(|(k, s)| {
                let ideal = s.ideal.with_law(law, t_s)?;
                Ok((*k, self.campaign.predict_setup(Setup { ideal, ..*s })))
            })
            .collect()
    }
}

/// The second event's value.
#[derive(Clone, Copy, Debug, PartialEq)]
enum SecondEvent {
    /// A load step to this, N·m.
    LoadNm(f64),
    /// A speed step to this, mechanical rad/s.
    SpeedRadS(f64),
}

/// The requirements [`Campaign::predict`] predicts: the speed's, the campaign's first six
/// (the ideal actuator has no torque or flux error to predict).
pub const PREDICTED: &[Requirement] = CAMPAIGN_REQUIREMENTS.split_at(6).0;

/// A speed step of a run, planned before it runs.
#[derive(Clone, Copy, Debug, PartialEq)]
struct StepPlan {
    /// Target, mechanical rad/s.
    to: f64,
    /// Settling band, × the step.
    band_fraction: f64,
    /// Rise time allowed, s.
    rise_allowed_s: f64,
    /// Settling time allowed, s.
    settling_allowed_s: f64,
}

/// What follows a run's first speed step.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Second {
    /// A load step: the deviation allowed after it, rad/s ([`judge::Scales::dip_allowed_rad_s`]),
    /// and the recovery time, s.
    Load {
        /// The largest deviation allowed, rad/s.
        dip_allowed_rad_s: f64,
        /// The recovery time allowed, s.
        recovery_allowed_s: f64,
    },
    /// A speed step.
    Step(StepPlan),
}

/// Each half of a run (after the speed step) lasts at least this many times the longest
/// time a requirement allows in it: long enough to see a response settle *and stay*.
pub const WINDOW_MARGIN: f64 = 1.2;

/// The first speed step's target of `m` at campaign speed `w`, mechanical rad/s.
fn first_target(m: Manoeuvre, w: f64) -> f64 {
    match m {
        Manoeuvre::Motoring | Manoeuvre::Generating => w,
        Manoeuvre::Reverse => -w,
        Manoeuvre::Reversal => 0.5 * w,
    }
}

/// A run's manoeuvre (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Manoeuvre {
    /// +ω_s, then +0.8·τ_max load.
    Motoring,
    /// −ω_s, then −0.8·τ_max load.
    Reverse,
    /// +ω_s, then −0.8·τ_max load (generating).
    Generating,
    /// +ω_s/2, then −ω_s/2.
    Reversal,
}

impl Manoeuvre {
    const ALL: [Manoeuvre; 4] = [Self::Motoring, Self::Reverse, Self::Generating, Self::Reversal];

    fn of(k: u64) -> Self {
        Self::ALL[(k % Self::ALL.len() as u64) as usize]
    }

    /// Name in the CSV.
    pub fn name(self) -> &'static str {
        match self {
            Self::Motoring => "motoring",
            Self::Reverse => "reverse",
            Self::Generating => "generating",
            Self::Reversal => "reversal",
        }
    }
}

/// A campaign.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Campaign {
    /// The drive (its motor is the box's nominal point).
    pub spec: DriveSpec,
    /// The box and the top speed.
    pub certify: Certify,
    /// Bus voltage, V.
    pub vdc_v: f64,
    /// Length of each run, s.
    pub duration_s: f64,
    /// Runs in the whole campaign (corners × manoeuvres first).
    pub runs: u64,
    /// Seed of the random samples.
    pub seed: u64,
    /// This shard: runs with k mod `shard.1` = `shard.0`.
    pub shard: (u64, u64),
    /// The board's encoder lines, which the simulated encoder has
    /// ([`drive_file::drive::DriveFile::encoder_lines`]; it had 1 024 whatever the file
    /// said: a 13 000-line board's campaign tripped `EncoderLoss` at standstill).
    pub encoder_lines: u32,
    /// The simulated machine's nominal point when it is not the drive's motor (`hil-sim
    /// campaign --plant`): its T model, its magnetizing branch's saturation and its extras.
    /// Each run scales it by the run's sample (a saturating curve's inductances by the
    /// sample's L factor; a deep bar's resistances with R_r), as it would the drive's motor.
    pub plant: Option<crate::scenario::SimulatedMotor>,
    /// What the user asks of the drive (the drive file's `[requirements]`): each run is
    /// judged against it ([`crate::requirements`]).
    pub requirements: Requirements,
}

/// The parameter factors of one run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// R_s factor.
    pub rs: f64,
    /// R_r factor.
    pub rr: f64,
    /// L_s, L_r, L_m factor.
    pub l: f64,
    /// J factor.
    pub j: f64,
}

/// What one run did and how it was judged.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    /// Run index.
    pub k: u64,
    /// Parameters.
    pub sample: Sample,
    /// Manoeuvre.
    pub manoeuvre: Manoeuvre,
    /// Speed step target, mechanical rad/s.
    pub omega_s_rad_s: f64,
    /// How long the run lasted, s: the campaign's duration, or longer where the requirements
    /// allow a response more time than half of it ([`WINDOW_MARGIN`]).
    pub duration_s: f64,
    /// Largest |ω − ω_ideal| after the speed step, rad/s: a diagnostic (the drive against
    /// its own speed law on an ideal actuator), not a criterion.
    pub tracking_error_rad_s: f64,
    /// Smallest and largest |ψ_r|/ψ̂_r (the drive's flux model) once magnetized: a
    /// diagnostic ([`FLUX_MODEL_BAND`]), not a criterion.
    pub flux_ratio: [f64; 2],
    /// Torque peak to peak about its trend over the last [`RIPPLE_WINDOW_S`], N·m.
    pub ripple_nm: f64,
    /// Final mode.
    pub mode: Mode,
    /// Each requirement this run measured, its worst ([`crate::requirements::worst_each`]).
    pub measures: Vec<Measure>,
    /// The first speed step's response: (s since the step, the fraction of the step
    /// covered), at most [`STEP_RESPONSE_POINTS`] points (for [`requirements_plot`]).
    pub step_response: Vec<(f64, f64)>,
    /// Why it failed (empty: passed): a criterion's name (`fault`, `oscillation`), or a
    /// requirement's key.
    pub failures: Vec<&'static str>,
}

impl Verdict {
    /// Passed every criterion and met every requirement.
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }

    /// The campaign's own criteria that failed — a fault, an oscillation: what no
    /// requirement excuses.
    pub fn criteria_failed(&self) -> Vec<&'static str> {
        self.failures
            .iter()
            .copied()
            .filter(|f| self.measures.iter().all(|m| m.requirement.key() != *f))
            .collect()
    }

    /// The requirements this run missed.
    pub fn requirements_missed(&self) -> Vec<Requirement> {
        self.measures.iter().filter(|m| !m.met()).map(|m| m.requirement).collect()
    }

    /// The CSV header of [`Verdict::csv`]: the run, its diagnostics, then each requirement's
    /// measured value and what was allowed (empty where the run does not measure it).
    pub fn csv_header() -> String {
        let mut h = String::from(
            "k,rs_factor,rr_factor,l_factor,j_factor,manoeuvre,omega_s_rad_s,tracking_error_rad_s,flux_ratio_min,flux_ratio_max,ripple_nm,mode,passed,failures",
        );
        for &r in CAMPAIGN_REQUIREMENTS {
            h.push_str(&format!(",{0},{0}_allowed", r.key()));
        }
        h
    }

    /// One CSV line.
    pub fn csv(&self) -> String {
        let s = &self.sample;
        let mut measured = String::new();
        for &r in CAMPAIGN_REQUIREMENTS {
            match self.measures.iter().find(|m| m.requirement == r) {
                Some(m) => measured.push_str(&format!(",{:.5},{:.5}", m.value, m.allowed)),
                None => measured.push_str(",,"),
            }
        }
        format!(
            "{},{:.6},{:.6},{:.6},{:.6},{},{:.3},{:.5},{:.4},{:.4},{:.5},{:?},{},{}{measured}",
            self.k,
            s.rs,
            s.rr,
            s.l,
            s.j,
            self.manoeuvre.name(),
            self.omega_s_rad_s,
            self.tracking_error_rad_s,
            self.flux_ratio[0],
            self.flux_ratio[1],
            self.ripple_nm,
            self.mode,
            self.passed(),
            self.failures.join(" ")
        )
    }
}

impl Campaign {
    /// Parameters of run `k`.
    pub fn sample(&self, k: u64) -> Sample {
        let c = &self.certify;
        if k < CORNER_RUNS {
            let corner = k / Manoeuvre::ALL.len() as u64;
            let pick = |iv: [f64; 2], bit: u64| if corner >> bit & 1 == 0 { iv[0] } else { iv[1] };
            return Sample {
                rs: pick(c.rs_factor, 0),
                rr: pick(c.rr_factor, 1),
                l: pick(c.inductance_factor, 2),
                j: pick(c.j_factor, 3),
            };
        }
        let mut state = mix(self.seed ^ mix(k));
        let mut uniform = |iv: [f64; 2]| {
            state = mix(state);
            iv[0] + (iv[1] - iv[0]) * ((state >> 11) as f64 / (1u64 << 53) as f64)
        };
        Sample {
            rs: uniform(c.rs_factor),
            rr: uniform(c.rr_factor),
            l: uniform(c.inductance_factor),
            j: uniform(c.j_factor),
        }
    }

    /// ω_s (module docs), mechanical rad/s.
    pub fn omega_s_rad_s(&self) -> f64 {
        let half = 0.5 * (self.duration_s - self.step_s());
        self.top_speed_rad_s().min(REACH_FRACTION * half / self.seconds_per_rad_s())
    }

    /// The box's top speed, mechanical rad/s: the certified ω_r,max/p, at most
    /// [`FIELD_WEAKENING_RANGE`](drive_file::drive::FIELD_WEAKENING_RANGE) × the drive's base
    /// speed on the campaign's bus, and at most the speed where the motor's friction takes
    /// [`FRICTION_SHARE_MAX`] of the torque the drive's envelope gives there
    /// ([`Campaign::friction_bound_rad_s`]).
    pub fn top_speed_rad_s(&self) -> f64 {
        let p = f64::from(self.spec.motor.pole_pairs());
        let base = crate::envelope::drive_base_speed_rad_s(&self.spec, self.vdc_v);
        let top = (self.certify.omega_r_max_rad_s / p).min(drive_file::drive::FIELD_WEAKENING_RANGE * base);
        self.friction_bound_rad_s(top)
    }

    /// The highest speed up to `top` (mechanical rad/s) at which the friction `B·ω` of the
    /// motor the runs drive (`--plant`'s, else the drive's) is at most [`FRICTION_SHARE_MAX`]
    /// of the torque the drive's envelope (on that motor and the campaign's bus, at most
    /// τ_max) gives motoring there: `top` where it is, else the crossing (bisection; the
    /// envelope falls and the friction grows with speed).
    pub fn friction_bound_rad_s(&self, top: f64) -> f64 {
        let plant = self.plant.as_ref().map_or(&self.spec.motor, |p| &p.motor);
        let envelope = controller_core::envelope::EnvelopeConfig::new(plant);
        let limits = ideal::drive_limits(&self.spec, plant, self.vdc_v);
        let tau_max = torque_limit_nm(&self.spec);
        let spare = |w: f64| {
            FRICTION_SHARE_MAX * tau_max.min(ideal::envelope_torque_nm(&envelope, limits, 1.0, w))
                - plant.b_nms() * w
        };
        if top.is_nan() || top <= 0.0 || spare(top) >= 0.0 {
            return top;
        }
        let (mut lo, mut hi) = (0.0, top);
        for _ in 0..FRICTION_BOUND_STEPS {
            let mid = 0.5 * (lo + hi);
            if spare(mid) >= 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// The time the largest inertia of the box takes per rad/s at τ_max, s·s/rad.
    fn seconds_per_rad_s(&self) -> f64 {
        self.spec.motor.j_kgm2() * self.certify.j_factor[1] / torque_limit_nm(&self.spec)
    }

    /// The shortest run that steps the speed to the box's top speed
    /// ([`Campaign::top_speed_rad_s`], not what a shorter run reaches: module docs) — and
    /// lasts at least [`MIN_AFTER_STEP_S`] after each of its two events, s. A shorter run
    /// steps a large motor far below its base speed and never runs its field weakening:
    /// `hil-sim campaign` (by default), `population` and `design tune` judge a drive on runs
    /// this long.
    pub fn full_range_duration_s(&self) -> f64 {
        let half = self.top_speed_rad_s() * self.seconds_per_rad_s() / REACH_FRACTION;
        // A drive without a speed range gets the least run: `Campaign::check` names why.
        self.step_s() + 2.0 * half.max(MIN_AFTER_STEP_S)
    }

    /// The run indices of this shard.
    pub fn indices(&self) -> impl Iterator<Item = u64> + '_ {
        (0..self.runs).filter(|k| k % self.shard.1 == self.shard.0)
    }

    /// When the speed step comes, s: [`STEP_S`], or 10 % after the drive's flux model — which
    /// decides Magnetizing → Running, on the nominal rotor time constant whatever the
    /// corner's — reaches `magnetized_fraction` of its target, `−T_r·ln(1 − f)` (3 T_r at
    /// 0.95): 0.19 s for the DeLorenzo machine, 2.3 s for the 500 hp Krause machine.
    pub fn step_s(&self) -> f64 {
        STEP_S.max(1.1 * crate::sim::magnetizing_time_s(&self.spec))
    }

    /// The shortest run the campaign accepts for this drive, s: [`MIN_AFTER_STEP_S`] after the
    /// speed step ([`Campaign::step_s`]).
    pub fn least_duration_s(&self) -> f64 {
        self.step_s() + MIN_AFTER_STEP_S
    }

    /// The campaign can judge this drive: the runs are long enough for this motor, at least
    /// [`MIN_AFTER_STEP_S`] after the step (else every run would end magnetizing, or be
    /// judged on a step it had no time for), and it has a speed range on the campaign's bus
    /// (a drive whose rated flux needs more voltage than the bus has even at standstill has
    /// none, and its steps to ±0 rad/s passed every run: found by trying).
    pub fn check(&self) -> Result<(), String> {
        let least = self.least_duration_s();
        if self.duration_s < least {
            let m = &self.spec.motor;
            return Err(format!(
                "runs of {} s are too short for this motor: the drive magnetizes it (T_r = {:.3} s) before the speed \
                 step at {:.2} s, and a run needs {MIN_AFTER_STEP_S} s after it — take a duration of at least {:.2} s",
                self.duration_s,
                m.lr_h() / m.rr_ohm(),
                self.step_s(),
                least
            ));
        }
        let w = self.omega_s_rad_s();
        if w.is_nan() || w <= 0.0 {
            return Err(format!(
                "the drive has no speed range on the {} V bus: its rated flux (controller.flux_ref_wb = {}) needs more \
                 voltage than the bus gives even at standstill (`hil-sim envelope` shows it) — nothing to step the speed to",
                self.vdc_v, self.spec.flux_ref_wb
            ));
        }
        Ok(())
    }

    /// Everything run `k` is, before it runs: its sample, plant, manoeuvre, the events' times
    /// and values, and the requirements' step plans.
    fn setup(&self, k: u64) -> Result<Setup, String> {
        self.check()?;
        let step_s = self.step_s();
        let sample = self.sample(k);
        let manoeuvre = Manoeuvre::of(k);
        let scaled = |m: &MotorParams| {
            m.scaled(sample.rs, sample.rr, sample.l, sample.j)
                .map_err(|e| format!("run {k}: sample motor rejected: {e:?}"))
        };
        let model = scaled(&self.spec.motor)?;
        let (plant, plant_saturation, extras) = match &self.plant {
            Some(p) => (
                scaled(&p.motor)?,
                p.saturation.map(|s| Saturation { curve: s.curve.with_inductance_scaled(sample.l), ..s }),
                p.extras,
            ),
            None => (model, None, plant::Extras::default()),
        };
        // The ideal loop's envelope is the plant's steady state: a linear plant's own; for a
        // saturating one, whose T model holds the unsaturated inductance, the drive's model
        // at the run's sample.
        let envelope_plant = if plant_saturation.is_some() { model } else { plant };
        let w = self.omega_s_rad_s();
        let ideal = IdealLoop::new(&self.spec, &envelope_plant, self.vdc_v, self.slow_period_s())?;
        // The load: LOAD_FRACTION of the largest this plant holds at the speed it loads, in
        // the direction the drive then pushes — τ_max, or the envelope's less in field
        // weakening, with the motor's own friction B·ω (which a motoring drive must also
        // overcome, and a braking one has on its side).
        let sc = self.scales();
        let held = |omega_m: f64, torque_sign: f64| {
            let most = torque_limit_nm(&self.spec).min(ideal.torque_limit_nm(torque_sign, omega_m));
            LOAD_FRACTION * (torque_sign * most - plant.b_nms() * omega_m)
        };
        let load = |omega_m: f64, torque_sign: f64| {
            overhauling_load_nm(omega_m, torque_sign, &held, |l| sc.dip_allowed_rad_s(&self.requirements, l))
        };
        // The requirements' times on this run's motor, and windows long enough to see them:
        // each half of the run lasts at least WINDOW_MARGIN × the longest time allowed in it.
        let physical = |omega_m: f64, motoring: bool| {
            let lim = crate::envelope::Limits::of(&self.spec, self.vdc_v);
            let sign = if motoring { 1.0 } else { -1.0 };
            let most = match &plant_saturation {
                Some(sat) => crate::envelope::physical_limit_saturated_nm(&plant, sat, omega_m, sign, &lim),
                None => crate::envelope::physical_limit_nm(&plant, omega_m, sign, &lim),
            };
            most.min(torque_limit_nm(&self.spec))
        };
        let plan = |from: f64, to: f64| self.step_plan(&sc, &plant, physical, from, to);
        let first_step = plan(0.0, first_target(manoeuvre, w));
        let second_event = match manoeuvre {
            Manoeuvre::Motoring => SecondEvent::LoadNm(load(w, 1.0)),
            Manoeuvre::Reverse => SecondEvent::LoadNm(load(-w, -1.0)),
            Manoeuvre::Generating => SecondEvent::LoadNm(load(w, -1.0)),
            Manoeuvre::Reversal => SecondEvent::SpeedRadS(-0.5 * w),
        };
        let second = match second_event {
            SecondEvent::SpeedRadS(to) => Second::Step(plan(0.5 * w, to)),
            SecondEvent::LoadNm(load_nm) => Second::Load {
                dip_allowed_rad_s: sc.dip_allowed_rad_s(&self.requirements, load_nm),
                recovery_allowed_s: self.requirements.recovery_time_allowed_s(
                    first_step.settling_allowed_s,
                    sc.least_recovery_s(&self.requirements, load_nm, plant.j_kgm2()),
                ),
            },
        };
        let second_allowed_s = match second {
            Second::Step(p) => p.settling_allowed_s.max(p.rise_allowed_s),
            Second::Load { recovery_allowed_s, .. } => recovery_allowed_s,
        };
        let half = [first_step.settling_allowed_s, first_step.rise_allowed_s, second_allowed_s]
            .into_iter()
            .filter(|t| t.is_finite())
            .fold(0.5 * (self.duration_s - step_s), |h, t| h.max(WINDOW_MARGIN * t));
        // A time derived from the least can be long where the motor barely
        // accelerates: a run that would last longer than the longest a file may state is
        // refused, not run for hours.
        let most = WINDOW_MARGIN * drive_file::requirements::MAX_TIME_S;
        if half > most {
            return Err(format!(
                "run {k}: its requirements' windows need {half:.0} s after the step, more than the {most} s the longest \
                 stated time gives: state speed_rise_time_s / speed_settling_time_s / load_recovery_time_s in [requirements]"
            ));
        }
        Ok(Setup {
            sample,
            manoeuvre,
            plant,
            plant_saturation,
            extras,
            w,
            step_s,
            t2_s: step_s + half,
            duration_s: step_s + 2.0 * half,
            first_step,
            second,
            second_event,
            ideal,
        })
    }

    /// The slow loop's period, s (one row of a run).
    fn slow_period_s(&self) -> f64 {
        f64::from(self.spec.slow_divider) / self.spec.pwm_frequency_hz
    }

    /// What the speed law alone gives on run `k` ([`PREDICTED`] requirements): the run's
    /// manoeuvre on its [`IdealLoop`] — the law's discrete code driving the sampled mechanics,
    /// the torque within τ_max and the machine's envelope, the speed read through the
    /// encoder's window ([`IdealLoop::measured`]); no current loops, field orientation or
    /// sensor noise. Cheap (the slow rate only, no electrical model): `design tune` chooses the
    /// speed law by it, before the campaign judges the whole drive.
    pub fn predict(&self, k: u64) -> Result<Vec<Measure>, String> {
        Ok(self.predict_setup(self.setup(k)?))
    }

    /// Run `k`s of this campaign prepared for [`Predictor::measures`] to try many speed laws
    /// on: a run's plant, step plans and windows — the least times, the costly part
    /// of [`Campaign::predict`] — do not depend on the law, only on its torque limit.
    pub fn predictor(&self, runs: impl IntoIterator<Item = u64>) -> Result<Predictor<'_>, String> {
        let runs: Vec<u64> = runs.into_iter().collect();
        let setups = runs.par_iter().map(|&k| Ok((k, self.setup(k)?))).collect::<Result<_, String>>()?;
        Ok(Predictor { campaign: self, setups })
    }

    /// [`Campaign::predict`] on a prepared run.
    fn predict_setup(&self, s: Setup) -> Vec<Measure> {
        let t_row = self.slow_period_s();
        // The law reads the speed as the board measures it.
        let mut ideal = s.ideal.measured();
        let (mut omega_ref, mut load) = (0.0, 0.0);
        let rows = (s.duration_s / t_row).round() as u64;
        let mut samples = Vec::with_capacity(rows as usize + 1);
        for i in 0..=rows {
            let t_s = i as f64 * t_row;
            if t_s >= s.step_s {
                omega_ref = s.first_step.to;
            }
            if t_s >= s.t2_s {
                match s.second_event {
                    SecondEvent::LoadNm(l) => load = l,
                    SecondEvent::SpeedRadS(w) => omega_ref = w,
                }
            }
            let flux = self.spec.flux_ref_wb;
            samples.push(judge::Sample {
                t_s,
                omega_m_rad_s: ideal.omega_m_rad_s,
                omega_ref_rad_s: omega_ref,
                psi_r_wb: flux,
                psi_ref_wb: flux,
                ..judge::Sample::default()
            });
            if t_s >= s.step_s {
                ideal.step(omega_ref, load);
            }
        }
        let measures = self.judge(&samples, s.step_s, s.t2_s, &s.first_step, &s.second);
        measures.into_iter().filter(|m| PREDICTED.contains(&m.requirement)).collect()
    }

    /// Run `k`; stops with an error at the next slow period once `cancel` is set.
    pub fn run_one(&self, k: u64, cancel: &AtomicBool) -> Result<Verdict, String> {
        self.run_one_into(k, cancel, &mut |_| Ok(()))
    }

    /// [`Campaign::run_one`], each trace row (one per slow period) also to `tap` as it is
    /// made (`hil-sim campaign --trace K`: why run K failed); `tap`'s error stops the run.
    pub fn run_one_into(
        &self,
        k: u64,
        cancel: &AtomicBool,
        tap: &mut dyn FnMut(&Row) -> Result<(), String>,
    ) -> Result<Verdict, String> {
        let Setup {
            sample,
            manoeuvre,
            plant,
            plant_saturation,
            extras,
            w,
            step_s,
            t2_s: t2,
            duration_s,
            first_step,
            second,
            second_event,
            mut ideal,
        } = self.setup(k)?;
        let divider = self.spec.slow_divider;
        let speed = |x: f64| Event::Reference(Reference::Speed(x as f32));
        let first = speed(first_step.to);
        let second_event = match second_event {
            SecondEvent::LoadNm(l) => Event::LoadNm(l),
            SecondEvent::SpeedRadS(x) => speed(x),
        };
        let b = Builtin {
            name: format!("campaign-{k}"),
            about: String::new(),
            spec: self.spec,
            plant,
            plant_saturation,
            expect_fault: None,
            scenario: Scenario {
                events: vec![(0.0, Event::Enable), (step_s, first), (t2, second_event)],
                duration_s,
                vdc_v: self.vdc_v,
                substeps: 1,
                // One row per slow period: the ideal loop runs on the rows.
                trace_every: u32::from(divider),
                sensors: SensorModel {
                    encoder_lines: Some(self.encoder_lines),
                    ..SensorModel::realistic_for_trip(mix(self.seed ^ k), self.spec.protection.i_trip_a)
                },
                load: LoadModel::Torque,
                inverter: InverterModel::Average,
                dc_link: None,
                comparator: None,
                heating: None,
                extras,
            },
        };
        let (mut track, mut flux, mut faulted) = (0.0f64, [f64::INFINITY, 0.0f64], false);
        let mut window: Vec<(f64, f64)> = Vec::new();
        let mut samples: Vec<judge::Sample> = Vec::new();
        let kt = self.spec.motor.torque_factor();
        let mode = b.run_into(
            |_| {},
            |r: &Row| {
                if cancel.load(Ordering::Relaxed) {
                    return Err("interrupted".into());
                }
                tap(r)?;
                faulted |= matches!(r.mode, Some(Mode::Fault(_)));
                let psi_r = r.x.psi_alpha_wb.hypot(r.x.psi_beta_wb);
                if r.t_s >= step_s && r.mode == Some(Mode::Running) {
                    track = track.max((r.x.omega_m_rad_s - ideal.omega_m_rad_s).abs());
                    let ratio = psi_r / r.psi_est_wb.max(1e-9);
                    flux = [flux[0].min(ratio), flux[1].max(ratio)];
                }
                if r.t_s >= duration_s - RIPPLE_WINDOW_S {
                    window.push((r.t_s, r.torque_nm));
                }
                samples.push(judge::Sample {
                    t_s: r.t_s,
                    omega_m_rad_s: r.x.omega_m_rad_s,
                    omega_ref_rad_s: r.omega_ref_rad_s,
                    torque_nm: r.torque_nm,
                    torque_ref_nm: kt * r.psi_est_wb * r.i_q_ref_a,
                    psi_r_wb: psi_r,
                    psi_ref_wb: r.psi_ref_wb,
                });
                // The ideal loop follows the same reference and load from the speed step on.
                if r.t_s >= step_s {
                    ideal.step(r.omega_ref_rad_s, r.load_nm);
                } else {
                    ideal.omega_m_rad_s = r.x.omega_m_rad_s;
                }
                Ok(())
            },
        )?;
        let ripple = detrended_peak_to_peak(&window);
        let mut failures = Vec::new();
        if faulted || mode != Mode::Running {
            failures.push("fault");
        }
        if ripple.is_nan() || ripple > RIPPLE_FRACTION * torque_limit_nm(&self.spec) {
            failures.push("oscillation");
        }
        let measures = self.judge(&samples, step_s, t2, &first_step, &second);
        let from = samples.iter().find(|s| s.t_s >= step_s).map_or(0.0, |s| s.omega_m_rad_s);
        let window: Vec<&judge::Sample> = samples.iter().filter(|s| s.t_s >= step_s && s.t_s < t2).collect();
        let stride = window.len().div_ceil(STEP_RESPONSE_POINTS).max(1);
        let step_response = window
            .iter()
            .step_by(stride)
            .map(|s| (s.t_s - step_s, (s.omega_m_rad_s - from) / (first_step.to - from)))
            .collect();
        failures.extend(measures.iter().filter(|m| !m.met()).map(|m| m.requirement.key()));
        Ok(Verdict {
            k,
            sample,
            manoeuvre,
            omega_s_rad_s: w,
            duration_s,
            tracking_error_rad_s: track,
            flux_ratio: flux,
            ripple_nm: ripple,
            mode,
            measures,
            step_response,
            failures,
        })
    }

    /// The scales the requirements are judged in ([`judge::Scales`]): the drive's motor's
    /// base speed on the campaign's bus, the board's encoder's speed resolution at the slow
    /// rate, τ_max and the rated flux.
    pub fn scales(&self) -> judge::Scales {
        let t_slow = f64::from(self.spec.slow_divider) / self.spec.pwm_frequency_hz;
        let quantum = EncoderConfig::<{ SPEED_WINDOW_READS }>::new(self.encoder_lines, t_slow as f32)
            .map_or(0.0, |e| f64::from(e.speed_resolution_rad_s()));
        judge::Scales {
            base_speed_rad_s: crate::envelope::base_speed_rad_s(
                &self.spec.motor,
                self.spec.flux_ref_wb,
                self.vdc_v,
            ),
            speed_quantum_rad_s: quantum,
            tau_max_nm: torque_limit_nm(&self.spec),
            flux_rated_wb: self.spec.flux_ref_wb,
        }
    }

    /// A speed step's plan on `plant` ([`StepPlan`]) in the campaign's scales `sc`: its
    /// settling band, and the times the requirements allow it — stated, or from the least
    /// (motor and board) with `physical(ω, motoring)` the most torque at ω
    /// ([`judge::least_step_times`]).
    fn step_plan(
        &self,
        sc: &judge::Scales,
        plant: &MotorParams,
        physical: impl Fn(f64, bool) -> f64,
        from: f64,
        to: f64,
    ) -> StepPlan {
        let req = &self.requirements;
        let band_fraction = sc.settling_band_fraction(req, to - from);
        let gain = sc.speed_gain_limit_nm_s();
        let (rise, settle) =
            judge::least_step_times(physical, plant.j_kgm2(), plant.b_nms(), gain, from, to, band_fraction);
        StepPlan {
            to,
            band_fraction,
            rise_allowed_s: req.rise_time_allowed_s(rise),
            settling_allowed_s: req.settling_time_allowed_s(settle),
        }
    }

    /// Each requirement measured on one run's `samples` ([`crate::requirements`]): the first
    /// speed step (at `step_s`, `first`) until `t2_s`; then the second — a load step (dip,
    /// recovery) or a speed step — to the end; the steady state (speed, torque, flux).
    fn judge(
        &self,
        samples: &[judge::Sample],
        step_s: f64,
        t2_s: f64,
        first: &StepPlan,
        second: &Second,
    ) -> Vec<Measure> {
        use drive_file::requirements::Requirement as R;
        let (req, sc) = (&self.requirements, self.scales());
        let measure = |requirement, value, allowed| Measure { requirement, value, allowed };
        let speed_at = |t: f64| samples.iter().find(|s| s.t_s >= t).map_or(0.0, |s| s.omega_m_rad_s);
        let mut out = Vec::new();
        let mut step = |t0: f64, t_end: f64, p: &StepPlan| {
            let r = judge::step_response(samples, t0, t_end, speed_at(t0), p.to, p.band_fraction);
            out.push(measure(R::SpeedRiseTime, r.rise_s, p.rise_allowed_s));
            out.push(measure(R::SpeedOvershoot, r.overshoot_fraction, req.speed_overshoot_fraction));
            out.push(measure(R::SpeedSettlingTime, r.settling_s, p.settling_allowed_s));
        };
        step(step_s, t2_s, first);
        let base = sc.base_speed_rad_s;
        match second {
            Second::Step(p) => step(t2_s, f64::INFINITY, p),
            Second::Load { dip_allowed_rad_s, recovery_allowed_s } => {
                let l = judge::load_response(samples, t2_s, sc.speed_error_allowed_rad_s(req));
                out.push(measure(R::LoadDip, l.dip_rad_s / base, dip_allowed_rad_s / base));
                out.push(measure(R::LoadRecoveryTime, l.recovery_s, *recovery_allowed_s));
            }
        }
        let st = judge::steady(samples);
        out.push(measure(
            R::SpeedError,
            st.speed_error_rad_s / base,
            sc.speed_error_allowed_rad_s(req) / base,
        ));
        out.push(measure(
            R::TorqueAccuracy,
            st.torque_error_nm / sc.tau_max_nm,
            req.torque_accuracy_fraction,
        ));
        out.push(measure(R::FluxAccuracy, st.flux_error_wb / sc.flux_rated_wb, req.flux_accuracy_fraction));
        judge::worst_each(out)
    }

    /// Every run of this shard, in parallel on all cores (rayon), in index order;
    /// `progress(done)` after each; the first error (an interrupt: `cancel`) stops them all.
    pub fn run(&self, progress: impl Fn(u64) + Sync, cancel: &AtomicBool) -> Result<Vec<Verdict>, String> {
        self.run_where(|_| true, progress, cancel)
    }

    /// [`Self::run`] on this shard's runs `k` with `keep(k)` only, in their order.
    pub fn run_where(
        &self,
        keep: impl Fn(u64) -> bool,
        progress: impl Fn(u64) + Sync,
        cancel: &AtomicBool,
    ) -> Result<Vec<Verdict>, String> {
        self.check()?;
        let done = AtomicU64::new(0);
        let indices: Vec<u64> = self.indices().filter(|&k| keep(k)).collect();
        indices
            .par_iter()
            .map(|&k| {
                let v = self.run_one(k, cancel);
                progress(done.fetch_add(1, Ordering::Relaxed) + 1);
                v
            })
            .collect()
    }
}

/// Peak to peak of `points` about their least-squares line: an oscillation, not the slow
/// transient a load step leaves (a P speed law settles with J/k_p ≈ 0.1 s), NaN if empty.
pub fn detrended_peak_to_peak(points: &[(f64, f64)]) -> f64 {
    if points.is_empty() {
        return f64::NAN;
    }
    let n = points.len() as f64;
    let (mt, my) = points.iter().fold((0.0, 0.0), |(a, b), (t, y)| (a + t / n, b + y / n));
    let (stt, sty) =
        points.iter().fold((0.0, 0.0), |(a, b), (t, y)| (a + (t - mt).powi(2), b + (t - mt) * (y - my)));
    let slope = if stt > 0.0 { sty / stt } else { 0.0 };
    let (lo, hi) = points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (t, y)| {
        let r = y - my - slope * (t - mt);
        (lo.min(r), hi.max(r))
    });
    hi - lo
}

/// The drive's torque limit (τ_max of a torque law; K_t·i_q,max at the rated flux for an
/// i_q law), N·m.
pub fn torque_limit_nm(spec: &DriveSpec) -> f64 {
    match spec.speed_law {
        SpeedLaw::SaturatedP { tau_max_nm, .. } => tau_max_nm,
        SpeedLaw::PiTorque { limit, .. } => limit,
        SpeedLaw::PiIq { limit, .. } => limit * spec.motor.torque_factor() * spec.flux_ref_wb,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn campaign(runs: u64, duration_s: f64) -> Campaign {
        let f = drive_file::DriveFile::shipped().unwrap();
        Campaign {
            spec: f.spec,
            certify: f.certify.unwrap(),
            vdc_v: 310.0,
            duration_s,
            runs,
            seed: 1,
            shard: (0, 1),
            encoder_lines: f.encoder_lines(),
            plant: None,
            requirements: f.requirements,
        }
    }

    /// A run of `full_range_duration_s` steps to the top speed (drive.toml: 368.0 rad/s, the
    /// 1 s default's 45), a shorter one does not; and a friction the drive's envelope cannot
    /// hold up there brings the top speed down to where it takes half the envelope's torque.
    #[test]
    fn full_range_runs_reach_the_top_speed_within_the_friction() {
        let mut c = campaign(64, 1.0);
        let top = c.top_speed_rad_s();
        assert!(c.omega_s_rad_s() < 0.2 * top, "{} of {top}", c.omega_s_rad_s());
        c.duration_s = c.full_range_duration_s();
        assert!((c.omega_s_rad_s() / top - 1.0).abs() < 1e-9, "{} of {top}", c.omega_s_rad_s());
        assert!((top - 368.0).abs() < 0.1, "{top}");
        let heavy = MotorParams::new(
            c.spec.motor.rs_ohm(),
            c.spec.motor.rr_ohm(),
            c.spec.motor.ls_h(),
            c.spec.motor.lr_h(),
            c.spec.motor.lm_h(),
            c.spec.motor.pole_pairs(),
            c.spec.motor.j_kgm2(),
            0.01,
        )
        .unwrap();
        let c = Campaign { spec: DriveSpec { motor: heavy, ..c.spec }, ..c };
        let w = c.top_speed_rad_s();
        let env = controller_core::envelope::EnvelopeConfig::new(&heavy);
        let limits = ideal::drive_limits(&c.spec, &heavy, c.vdc_v);
        let half = FRICTION_SHARE_MAX
            * torque_limit_nm(&c.spec).min(ideal::envelope_torque_nm(&env, limits, 1.0, w));
        assert!(w < top && (0.01 * w / half - 1.0).abs() < 1e-6, "{w}: {} against {half}", 0.01 * w);
    }

    /// Corners first (every manoeuvre of each), then seeded samples inside the box; a run's
    /// parameters depend only on (seed, k), so shards agree with the whole.
    #[test]
    fn samples_are_corners_then_seeded_and_shard_independent() {
        let c = campaign(200, 1.0);
        let corners: std::collections::BTreeSet<String> =
            (0..64).map(|k| format!("{:?}", c.sample(k))).collect();
        assert_eq!(corners.len(), 16);
        assert_eq!(c.sample(0), c.sample(3));
        for k in 64..200 {
            let s = c.sample(k);
            let inside = |x: f64, iv: [f64; 2]| x >= iv[0] && x <= iv[1];
            assert!(inside(s.rs, c.certify.rs_factor) && inside(s.rr, c.certify.rr_factor));
            assert!(inside(s.l, c.certify.inductance_factor) && inside(s.j, c.certify.j_factor));
        }
        let other = Campaign { shard: (1, 3), ..c };
        assert_eq!(other.sample(100), c.sample(100));
        let idx: Vec<u64> = other.indices().take(3).collect();
        assert_eq!(idx, [1, 4, 7]);
        assert_ne!(Campaign { seed: 2, ..c }.sample(100), c.sample(100));
    }

    /// The campaign judges every requirement but the current bandwidth; the prediction the
    /// speed's alone (the lists are cut from `Requirement::ALL` by position).
    #[test]
    fn the_requirement_lists_are_the_ones_meant() {
        assert_eq!(CAMPAIGN_REQUIREMENTS.len() + 1, Requirement::ALL.len());
        assert!(!CAMPAIGN_REQUIREMENTS.contains(&Requirement::CurrentBandwidth));
        for r in [Requirement::TorqueAccuracy, Requirement::FluxAccuracy] {
            assert!(CAMPAIGN_REQUIREMENTS.contains(&r) && !PREDICTED.contains(&r));
        }
        assert_eq!(PREDICTED.len(), 6);
    }

    /// A ramp has no ripple; a sine on it has its own peak to peak.
    #[test]
    fn detrending() {
        let ramp: Vec<(f64, f64)> =
            (0..100).map(|k| (k as f64 * 1e-3, 3.0 + 20.0 * k as f64 * 1e-3)).collect();
        assert!(detrended_peak_to_peak(&ramp) < 1e-12);
        let wavy: Vec<(f64, f64)> = ramp.iter().map(|&(t, y)| (t, y + 0.1 * (t * 2000.0).sin())).collect();
        assert!((detrended_peak_to_peak(&wavy) - 0.2).abs() < 0.01);
        assert!(detrended_peak_to_peak(&[]).is_nan());
    }

    /// A predictor prepared once predicts any law with the campaign's torque limit as a
    /// campaign running that law predicts it, bit for bit, and refuses another limit.
    #[test]
    fn the_predictor_predicts_what_predict_does() {
        let c = campaign(8, 1.0);
        let SpeedLaw::SaturatedP { tau_max_nm, .. } = c.spec.speed_law else { panic!("shipped law") };
        let pi = SpeedLaw::PiTorque { kp: 0.08, ki: 0.9, limit: tau_max_nm, setpoint_weight: 0.7 };
        let p = c.predictor(0..8).unwrap();
        let with_pi = Campaign { spec: DriveSpec { speed_law: pi, ..c.spec }, ..c };
        let direct: Vec<_> = (0..8).map(|k| (k, with_pi.predict(k).unwrap())).collect();
        assert_eq!(p.measures(&pi).unwrap(), direct);
        assert_eq!(p.measures(&c.spec.speed_law).unwrap().len(), 8);
        let odd: Vec<_> =
            p.measures_where(&pi, |k| k % 2 == 1).unwrap().into_iter().map(|(k, _)| k).collect();
        assert_eq!(odd, [1, 3, 5, 7]);
        let other = SpeedLaw::PiTorque { kp: 0.08, ki: 0.9, limit: 0.5 * tau_max_nm, setpoint_weight: 1.0 };
        assert!(p.measures(&other).unwrap_err().contains("torque limit"));
    }

    /// The ideal loop of the saturated P law settles where eq. (21) puts it:
    /// ω = (k_p·ω_ref − T_L)/(k_p + B).
    #[test]
    fn the_ideal_loop_settles_at_the_p_laws_speed() {
        let c = campaign(1, 1.0);
        let mut l = IdealLoop::new(&c.spec, &c.spec.motor, 310.0, 5e-4).unwrap();
        for _ in 0..40_000 {
            l.step(100.0, 0.5);
        }
        let (kp, b) = (0.05, c.spec.motor.b_nms());
        assert!((l.omega_m_rad_s - (kp * 100.0 - 0.5) / (kp + b)).abs() < 1e-3, "{}", l.omega_m_rad_s);
    }
}
