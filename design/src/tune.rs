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
//! 8-pole motor at 4 kHz: 54 rad/s against 1 753); the file records the frame taken.
//!
//! **Speed loop**: saturated P (seed 002 eq. (21)), `k_p = J·ω_s`: the speed loop's
//! crossover ω_s on the nominal inertia, at most ω_c/[`SPEED_BELOW_CURRENT`], and at most
//! what keeps the encoder's speed resolution from shaking the torque: `k_p·Δω_q ≤`
//! [`ENCODER_NOISE_FRACTION`]`·τ_max`, with `Δω_q = 2π/(4·lines)/(window·T_slow)` one count
//! over the speed estimate's window (the linear certificate cannot see quantisation; the
//! nonlinear campaign's torque-ripple criterion can). Then the largest of the same kind of
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
//! **Box**: the template's factors, widened to hold the motor file's `[identification]`
//! intervals (relative to its nominal values; L_s, L_r and L_m's widest together) and the
//! rotor-resistance range the drive's estimate may take (`rotor_resistance_range`); that R_r
//! hull is written back as the file's `rotor_resistance_range` (unless the estimate is off:
//! a range of one value). The inductances' box and `inductance_range` likewise, and a
//! template that does not state `inductance_range` gets the box's: a spread the drive does
//! not estimate is a flux error of that size.

use crate::certify::{CertifySpec, Check, certify, certify_current, certify_speed};
use crate::pi_region::SpeedRegions;
use controller_core::current::CurrentLaw;
use controller_core::discretize::ContinuousSection;
use controller_core::drive::{CurrentFrame, DriveSpec};
use controller_core::motor::MotorParams;
use controller_core::speed::SpeedLaw;
use std::path::Path;

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

/// The saturated-P speed loop's bandwidth (crossover `omega_s_rad_s` on the nominal
/// inertia) on the heaviest inertia, `ω_s/j_factor_max`: what the speed PI must reach on
/// every inertia (as fast as the proportional loop, with integral action besides), and
/// what places the position loop ([`POSITION_BELOW_SPEED`]).
pub fn heaviest_speed_bandwidth(omega_s_rad_s: f64, cert: &CertifySpec) -> f64 {
    omega_s_rad_s / cert.j_factor[1]
}

/// The position loop's gain is the speed loop's bandwidth on the heaviest inertia over
/// this: the cascade `k·ω_B/(s(s + ω_B))` is then critically damped there
/// (ζ = ½·√(ω_B/k) = 1), better damped on lighter inertias.
pub const POSITION_BELOW_SPEED: f64 = 4.0;

/// Points per axis of the speed PI's k_p–k_i grid ([`speed_pi`]).
pub const SPEED_PI_GRID: usize = 81;

/// A speed PI chosen by seed 000's method on [`SpeedRegions`]: the first of
/// [`speed_pi_region`]`(regions, omega_b_rad_s, kp_max)`, the admissible point **farthest
/// from the region's boundary**. Returns `(k_p, k_i)`.
pub fn speed_pi(regions: &SpeedRegions, omega_b_rad_s: f64, kp_max: f64) -> Result<(f64, f64), String> {
    let points = speed_pi_region(regions, omega_b_rad_s, kp_max, 1);
    points.first().map(|p| (p.kp, p.ki)).ok_or_else(|| {
        format!(
            "no speed PI meets the margins ({}°, {} dB) and a bandwidth of {omega_b_rad_s:.2} rad/s on every inertia of \
             J [{:.4e}, {:.4e}] kg·m² with k_p ≤ {kp_max:.4e} (dead time {:.2} ms)",
            regions.minima[0],
            regions.minima[1],
            regions.j_kgm2[0],
            regions.j_kgm2[1],
            regions.tau_s * 1e3
        )
    })
}

/// A point of seed 000's admissible region for the speed PI ([`speed_pi_region`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionPoint {
    /// N·m per rad/s.
    pub kp: f64,
    /// N·m per rad.
    pub ki: f64,
    /// Its distance from the region's boundary, in grid steps (each axis scaled by the
    /// grid's extent): seed 000's measure of how far inside the margins a design sits.
    pub depth: f64,
}

/// Seed 000's admissible region for the speed PI on [`SpeedRegions`], deepest first: on
/// an [`SPEED_PI_GRID`]² grid of the k_p–k_i plane a point is admissible when it has the
/// margins, a closed-loop bandwidth of at least `omega_b_rad_s` on every inertia (0: no
/// floor), and `k_p ≤ kp_max` (the encoder-noise rule); its depth is the distance to the
/// nearest inadmissible grid point, in coordinates scaled by the grid's extent, which is
/// the admissible region's with a quarter to spare. Every `stride`-th point of each axis
/// is returned (the depth is the full grid's). Empty when no point is admissible.
pub fn speed_pi_region(
    regions: &SpeedRegions,
    omega_b_rad_s: f64,
    kp_max: f64,
    stride: usize,
) -> Vec<RegionPoint> {
    let tau = regions.tau_s;
    let jl = regions.j_kgm2[0];
    let stable = |kp: f64, ki: f64| regions.stable(kp, ki);
    let admissible = |kp: f64, ki: f64| {
        kp <= kp_max
            && regions.margins(kp, ki)
            && (omega_b_rad_s <= 0.0 || regions.bandwidth(kp, ki, omega_b_rad_s))
    };
    // The grid's extent: the admissible region's, found on coarse grids — k_p up to the
    // robust stability limit (about J_min·π/(2τ), grown while the region reaches the edge)
    // and `kp_max`; k_i from the same scale, shrunk (the margins keep k_i/k_p well below
    // 1/τ) or grown until the region sits inside with a quarter of its size to spare.
    let mut kp_hi = 2.0 * jl / tau;
    for _ in 0..20 {
        if !(1..=8).any(|i| stable(kp_hi, kp_hi / tau * f64::from(i) / 64.0)) {
            break;
        }
        kp_hi *= 2.0;
    }
    kp_hi = kp_hi.min(kp_max);
    let coarse = 33;
    let extent = |kp_hi: f64, ki_hi: f64| {
        let mut top: Option<(f64, f64)> = None;
        for a in 1..=coarse {
            for b in 1..=coarse {
                let (kp, ki) = (kp_hi * a as f64 / coarse as f64, ki_hi * b as f64 / coarse as f64);
                if admissible(kp, ki) {
                    let t = top.get_or_insert((kp, ki));
                    *t = (t.0.max(kp), t.1.max(ki));
                }
            }
        }
        top
    };
    let mut ki_hi = 2.0 * kp_hi / tau;
    let mut found = None;
    for _ in 0..40 {
        match extent(kp_hi, ki_hi) {
            Some((_, ki)) if ki >= ki_hi * (1.0 - 1.0 / coarse as f64) => ki_hi *= 2.0,
            Some(top) => {
                found = Some(top);
                break;
            }
            None => ki_hi *= 0.5,
        }
    }
    if let Some((kp_top, ki_top)) = found {
        (kp_hi, ki_hi) = ((1.25 * kp_top).min(kp_hi), 1.25 * ki_top);
    }
    let n = SPEED_PI_GRID;
    let at = |i: usize, hi: f64| hi * i as f64 / (n - 1) as f64;
    let member: Vec<bool> = (0..n * n).map(|k| admissible(at(k / n, kp_hi), at(k % n, ki_hi))).collect();
    // Beyond the grid is outside: the k_i = 0 and k_p = 0 axes (a root at the origin; no
    // P action), k_p past `kp_max` or the stability limit, k_i past the region's extent.
    let outside: Vec<(f64, f64)> = (0..n * n)
        .filter(|&k| !member.get(k).copied().unwrap_or(false))
        .map(|k| ((k / n) as f64, (k % n) as f64))
        .chain((0..n).flat_map(|i| {
            let (i, e) = (i as f64, n as f64);
            [(i, -1.0), (-1.0, i), (i, e), (e, i)]
        }))
        .collect();
    let stride = stride.max(1);
    let mut points: Vec<RegionPoint> = (0..n * n)
        .filter(|&k| member.get(k).copied().unwrap_or(false))
        .filter(|&k| stride == 1 || ((k / n).is_multiple_of(stride) && (k % n).is_multiple_of(stride)))
        .map(|k| {
            let (a, b) = ((k / n) as f64, (k % n) as f64);
            let d =
                outside.iter().map(|(x, y)| (x - a).powi(2) + (y - b).powi(2)).fold(f64::INFINITY, f64::min);
            RegionPoint { kp: at(k / n, kp_hi), ki: at(k % n, ki_hi), depth: d.sqrt() }
        })
        .collect();
    // Deepest first; among equals the last in the grid's order (k_p, then k_i, ascending),
    // as seed 000's choice always took it.
    points.reverse();
    points.sort_by(|x, y| y.depth.total_cmp(&x.depth));
    points
}

/// Stride of `design tune`'s PI search over seed 000's region: every this-many-th point of the
/// [`SPEED_PI_GRID`]² grid on each axis (441 points at most; the region's depth is the full
/// grid's).
pub const SPEED_PI_SEARCH_STRIDE: usize = 4;

/// The points of the region `design tune`'s PI search runs in software in the loop before it refuses
/// (each costs the campaign's 64 corner runs).
pub const SIL_CONFIRMATIONS: usize = 2;

/// The speed PI `design tune` chooses for the requirements (issue 51): seed 000's own choice
/// ([`speed_pi`]: the region with the saturated P's bandwidth on the heaviest inertia, its
/// deepest point) at its best setpoint weight ([`weigh_setpoint`]) when it meets them, and
/// its drive does in software in the loop on the corner runs; else
/// the deepest point of the region *without* that bandwidth floor — the margins on every
/// inertia and the encoder's k_p cap only: the requirements say how fast the loop must be —
/// whose best weight meets them, whose drive passes the certificate, and whose drive meets
/// them in software in the loop on the campaign's corner runs (every corner of the box
/// through every manoeuvre: the prediction has no current loops, field orientation or
/// sensors, and a point chosen at the edge of what it allows failed the whole drive's
/// campaign on 9 of the population's 87 drives). At most [`SIL_CONFIRMATIONS`] points are
/// run so; else a refusal.
struct SpeedPiSearch<'a> {
    regions: &'a SpeedRegions,
    /// The saturated P's bandwidth on the heaviest inertia, rad/s (seed 000's floor).
    omega_b_rad_s: f64,
    /// The encoder-noise cap on k_p ([`encoder_kp_limit`]).
    kp_max: f64,
    tau_max_nm: f64,
}

/// What [`SpeedPiSearch::choose`] found: the law (at its setpoint weight), its predicted
/// misses, and how many points of the region it tried.
struct SpeedPiChoice {
    law: SpeedLaw,
    misses: Misses,
    tried: usize,
    region: Vec<RegionPoint>,
    /// The last point predicted to meet the requirements whose drive then missed them in
    /// software in the loop (before the one taken, if one was): its law and what the corner
    /// runs missed.
    sil_missed: Option<(SpeedLaw, String)>,
    /// Found by the search (not seed 000's own point).
    searched: bool,
}

impl SpeedPiSearch<'_> {
    fn law(&self, kp: f64, ki: f64) -> SpeedLaw {
        SpeedLaw::PiTorque { kp, ki, limit: self.tau_max_nm, setpoint_weight: 1.0 }
    }

    fn choose(
        &self,
        spec: &DriveSpec,
        cert: &CertifySpec,
        file: &drive_file::DriveFile,
        vdc_v: f64,
    ) -> Result<SpeedPiChoice, String> {
        // `spec`'s law has the same torque limit, which the prepared runs are sized by.
        let campaign = prediction_campaign(spec, cert, file, vdc_v);
        let mut screen =
            Screen { predictor: campaign.predictor(0..hil_sim::campaign::CORNER_RUNS)?, hard: Vec::new() };
        let certified = |law: &SpeedLaw| -> Result<bool, String> {
            Ok(certify(&DriveSpec { speed_law: *law, ..*spec }, cert)?.iter().all(|c| c.pass))
        };
        let region = speed_pi_region(self.regions, 0.0, self.kp_max, SPEED_PI_SEARCH_STRIDE);
        // Seed 000's choice, or — where no point has the saturated P's bandwidth — the
        // region's deepest, which is then a searched point like the others (run in SIL).
        let (seed, seed000) = match speed_pi(self.regions, self.omega_b_rad_s, self.kp_max) {
            Ok(p) => (p, true),
            Err(e) => (region.first().map(|p| (p.kp, p.ki)).ok_or(e)?, false),
        };
        let (law, misses) =
            weigh_setpoint(&self.law(seed.0, seed.1), |l| Ok(missed(screen.predictor.measures(l)?)))?;
        let seed_certified = certified(&law)?;
        let sil = |l: &SpeedLaw| {
            sil_misses(&hil_sim::campaign::Campaign {
                spec: DriveSpec { speed_law: *l, ..*spec },
                ..campaign
            })
        };
        let mut sil_missed = None;
        if seed000 && misses.is_empty() && seed_certified {
            // Seed 000's own point, predicted to meet them: confirmed like any other.
            match sil(&law)? {
                None => {
                    return Ok(SpeedPiChoice {
                        law,
                        misses,
                        tried: 1,
                        region,
                        sil_missed: None,
                        searched: false,
                    });
                }
                Some(why) => sil_missed = Some((law, why)),
            }
        }
        let (mut tried, mut confirmations) = (1, 0);
        for p in &region {
            if confirmations == SIL_CONFIRMATIONS {
                break;
            }
            if seed000 && (p.kp, p.ki) == seed {
                // Seed 000's own point: weighed (and run) above.
                continue;
            }
            tried += 1;
            let (l, m) = weigh_setpoint(&self.law(p.kp, p.ki), |l| screen.misses(l))?;
            if m.is_empty() && certified(&l)? {
                confirmations += 1;
                match sil(&l)? {
                    None => {
                        return Ok(SpeedPiChoice {
                            law: l,
                            misses: m,
                            tried,
                            region,
                            sil_missed: sil_missed.take(),
                            searched: true,
                        });
                    }
                    Some(why) => sil_missed = Some((l, why)),
                }
            }
        }
        if misses.is_empty() && seed_certified {
            // Predicted to meet the requirements and certified, but its drive missed them.
            let (l, why) = sil_missed.as_ref().map_or((&law, "not run"), |(l, why)| (l, why.as_str()));
            return Err(format!(
                "the speed PI ({}) is predicted to meet the requirements over the box, but the drive misses them in \
                 software in the loop on the campaign's corner runs: {why} — relax [requirements], or take a \
                 smaller box",
                gains_words(l)
            ));
        }
        if misses.is_empty() {
            return Err(format!(
                "the speed PI of seed 000's regions (k_p {:.4e}, k_i {:.4e}) meets the requirements but fails the \
                 certificate, and no other point of the regions meets both: the Padé model of the dead time is too \
                 coarse here — use `--speed p`",
                seed.0, seed.1
            ));
        }
        Ok(SpeedPiChoice { law, misses, tried, region, sil_missed, searched: false })
    }

    /// Why no PI meets the requirements: seed 000's choice and what it misses, and what
    /// bounds the region searched — the encoder's resolution (`lines` over the speed window at
    /// the slow period `t_slow_s`) or the margins with the speed loop's dead time.
    fn refusal(&self, c: &SpeedPiChoice, lines: u32, t_slow_s: f64) -> String {
        let kp_top = c.region.iter().map(|p| p.kp).fold(0.0, f64::max);
        let bound = if kp_top >= 0.9 * self.kp_max {
            format!(
                "k_p ≤ {:.4e}, the encoder's: one count of its {lines} lines over the {}-read speed window at \
                 {:.3} ms moves the torque {} × τ_max",
                self.kp_max,
                controller_core::encoder::SPEED_WINDOW_READS,
                t_slow_s * 1e3,
                ENCODER_NOISE_FRACTION
            )
        } else {
            format!(
                "k_p ≤ {kp_top:.4e}, where the margins ({}°, {} dB) end on the heaviest inertia with the speed \
                 loop's {:.2} ms dead time",
                self.regions.minima[0],
                self.regions.minima[1],
                self.regions.tau_s * 1e3
            )
        };
        let sil = match &c.sil_missed {
            Some((law, why)) => format!(
                "; the last predicted to meet them ({}) missed them in software in the loop: {why}",
                gains_words(law)
            ),
            None => String::new(),
        };
        format!(
            "PI (seed 000's, {}) misses {}, and none of the {} points of seed 000's region tried meets them (the \
             region: {bound}){sil}",
            gains_words(&c.law),
            describe(&c.misses),
            c.tried - 1
        )
    }
}

/// `k_p …, k_i …, setpoint weight …` of a speed law, as tune's messages name a point.
fn gains_words(law: &SpeedLaw) -> String {
    let (kp, ki) = law_gains(law);
    format!("k_p {kp:.4e}, k_i {ki:.4e}, setpoint weight {}", setpoint_weight(law))
}

/// `, met on the campaign's 64 corner runs in SIL`: what a law's origin adds once its drive
/// was run.
fn met_in_sil_words() -> String {
    format!(", met on the campaign's {} corner runs in SIL", hil_sim::campaign::CORNER_RUNS)
}

/// A speed law's (k_p, k_i) (k_i 0 for the P law).
fn law_gains(law: &SpeedLaw) -> (f64, f64) {
    match *law {
        SpeedLaw::PiTorque { kp, ki, .. } | SpeedLaw::PiIq { kp, ki, .. } => (kp, ki),
        SpeedLaw::SaturatedP { kp, .. } => (kp, 0.0),
    }
}

/// What the campaign `c`'s corner runs (every corner through every manoeuvre) miss in
/// software in the loop — each missed requirement or failed criterion with its runs
/// count — or `None` when every run passes.
fn sil_misses(c: &hil_sim::campaign::Campaign) -> Result<Option<String>, String> {
    let c = hil_sim::campaign::Campaign { runs: hil_sim::campaign::CORNER_RUNS, shard: (0, 1), ..*c };
    let verdicts = c.run(|_| {}, &std::sync::atomic::AtomicBool::new(false))?;
    let mut counts: Vec<(String, usize)> = Vec::new();
    for v in verdicts.iter().filter(|v| !v.passed()) {
        for f in &v.failures {
            match counts.iter_mut().find(|(name, _)| name == f) {
                Some((_, n)) => *n += 1,
                None => counts.push(((*f).to_string(), 1)),
            }
        }
    }
    Ok((!counts.is_empty()).then(|| {
        let each: Vec<String> =
            counts.iter().map(|(f, n)| format!("{f} in {n} of {} runs", verdicts.len())).collect();
        each.join(", ")
    }))
}

/// ICAD lag: double zero at `−ω_h` (seed 002 eq. (20): −400 rad/s at ω_h = 400 rad/s).
pub const ICAD_LAG_ZERO: f64 = 1.0;
/// ICAD lag: poles at `ω_h·(−1/8 ± j/2)` (eq. (20): −50 ± j200 rad/s).
pub const ICAD_LAG_POLE: [f64; 2] = [-0.125, 0.5];
/// ICAD PI zero, the phase lead: `−2.5·ω_h` (eq. (20): −1 000 rad/s).
pub const ICAD_LEAD_ZERO: f64 = 2.5;
/// The ICAD gain search's coarse grid: each candidate k_p is this fraction of the last.
pub const ICAD_GRID_RATIO: f64 = 0.8;
/// Golden-section steps refining the best grid point (the bracket shrinks to 0.618^n).
pub const ICAD_REFINE_STEPS: usize = 12;

/// Seed 002 eq. (20)'s structure placed for a top electrical rotor speed `omega_h_rad_s`:
/// `(k_p + k_i/s)·(s + z·ω_h)²/(s² − 2a·ω_h s + (a² + b²)ω_h²)` with `z` =
/// [`ICAD_LAG_ZERO`], `(a, b)` = [`ICAD_LAG_POLE`], `k_i = `[`ICAD_LEAD_ZERO`]`·ω_h·k_p`.
///
/// The reasoning generalised from Sec. VI-D (Amézquita-Brooks et al.): h_i's resonance —
/// the rotor-speed dip that makes γh approach (1, 0) — sits at the rotor speed, worst at the
/// top speed; the lag pair raises the open-loop gain there (its resonance just below ω_h,
/// 8.2 dB at ω_h, 11.5 dB at DC) without a drastic loss of phase at crossover, and the PI
/// zero adds the lead that keeps the loop stable, all slower than the closed-loop bandwidth.
/// Scaled by ω_h every placement is the paper's at ω_h = 400 rad/s (the shipped drive's
/// `[certify] omega_r_max_rad_s`): `icad_law(326.5, 400.0)` is eq. (20) exactly.
pub fn icad_law(kp_v_per_a: f64, omega_h_rad_s: f64) -> CurrentLaw {
    let w = omega_h_rad_s;
    let [a, b] = ICAD_LAG_POLE;
    let z = ICAD_LAG_ZERO * w;
    CurrentLaw {
        kp_v_per_a,
        ki_v_per_as: ICAD_LEAD_ZERO * w * kp_v_per_a,
        lag: Some(ContinuousSection::biquad(
            [1.0, 2.0 * z, z * z],
            [1.0, -2.0 * a * w, (a * a + b * b) * w * w],
        )),
    }
}

/// The smallest ratio of a margin to its minimum over every margin check (phase, gain, γh;
/// continuous and sampled; every corner) — the distance to the certificate's boundary, in
/// units of the minima — and the check that sets it; −∞ when a stability check fails. A
/// margin that does not exist (no phase crossover for a gain margin) does not bind.
pub fn robustness(checks: &[Check]) -> (f64, Option<&Check>) {
    let mut worst = (f64::INFINITY, None);
    for c in checks {
        let r = if c.name.contains("margin") {
            match c.value {
                Some(v) if c.limit > 0.0 => v / c.limit,
                Some(v) => v - c.limit + 1.0,
                None if c.pass => continue,
                None => f64::NEG_INFINITY,
            }
        } else if c.pass {
            continue;
        } else {
            f64::NEG_INFINITY
        };
        if r < worst.0 {
            worst = (r, Some(c));
        }
    }
    worst
}

/// Each candidate crossover is this fraction of the last.
pub const SEARCH_RATIO: f64 = 0.9;
/// The searches first try every this many candidates (`search_down`).
pub const SEARCH_STRIDE: usize = 4;

/// The candidates of a geometric search: `top`, then each [`SEARCH_RATIO`] of the last
/// (by repeated multiplication: the values the written gains come from), while at least
/// `bottom`.
fn candidates(top: f64, bottom: f64) -> impl Iterator<Item = f64> {
    std::iter::successors(Some(top), |w| Some(w * SEARCH_RATIO)).take_while(move |&w| w >= bottom)
}

/// The first of `grid` (largest first) that `pass`es: every [`SEARCH_STRIDE`]-th candidate
/// first, then those between the last that failed and the first that passed, largest
/// first. Where passing is monotone in the gain (the sampled delay and the dead time bound
/// the loops from above), that is the candidate-by-candidate search's answer in about a
/// quarter of its certificates — `design tune` spent 10 s on a 116 W motor whose
/// stationary-frame PI passes 43 candidates down.
fn search_down(
    grid: impl Iterator<Item = f64>,
    mut pass: impl FnMut(f64) -> Result<bool, String>,
) -> Result<Option<f64>, String> {
    let grid: Vec<f64> = grid.collect();
    let mut failed_below = 0; // candidates before this index failed (or were skipped)
    let mut hit = None;
    for (i, &w) in grid.iter().enumerate().step_by(SEARCH_STRIDE) {
        if pass(w)? {
            hit = Some((i, w));
            break;
        }
        failed_below = i + 1;
    }
    let end = hit.map_or(grid.len(), |(i, _)| i);
    for &w in grid.get(failed_below..end).unwrap_or_default() {
        if pass(w)? {
            return Ok(Some(w));
        }
    }
    Ok(hit.map(|(_, w)| w))
}

/// `spec` with the current law `law`.
fn with_law(spec: &DriveSpec, law: CurrentLaw) -> DriveSpec {
    DriveSpec { current_law: law, ..*spec }
}
/// The speed loop's crossover is at least this many times below the current loops'.
pub const SPEED_BELOW_CURRENT: f64 = 20.0;
/// One count of speed resolution may move the torque by at most this fraction of τ_max:
/// a quarter of the ripple the campaign allows (`hil_sim::campaign::RIPPLE_FRACTION`, peak to
/// peak). The estimate toggles between neighbouring counts, so the speed law's torque
/// toggles by `k_p·Δω_q` — a square wave the loop carries round and the current loops add
/// their own noise to; the quarter leaves the rest of the allowance to them. Measured over
/// the population (`population run --members 24 --shipped --pwm 4000,10000,20000`): at a
/// quarter, one drive of 87 oscillates in 2 of its 200 runs; at half, 12 drives in 60 runs,
/// the shipped DeLorenzo and EM_Synergy drives among them. (First fitted on the DeLorenzo
/// motor alone, narrow box: k_p = 0.1 passed 64 of 64 runs, 0.2 63, 0.4 49 — the same
/// value.)
pub const ENCODER_NOISE_FRACTION: f64 = hil_sim::campaign::RIPPLE_FRACTION / 4.0;

/// The largest speed k_p the encoder's resolution allows (N·m per rad/s): one count over
/// the speed estimate's window, `Δω_q = 2π/(4·lines)/(window·T_slow)`, may move the torque
/// by at most [`ENCODER_NOISE_FRACTION`]`·τ_max`.
pub fn encoder_kp_limit(tau_max_nm: f64, encoder_lines: u32, t_slow_s: f64) -> f64 {
    let window = controller_core::encoder::SPEED_WINDOW_READS as f64;
    let speed_quantum = std::f64::consts::TAU / (4.0 * f64::from(encoder_lines)) / (window * t_slow_s);
    ENCODER_NOISE_FRACTION * tau_max_nm / speed_quantum
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
    pub predicted_misses: Vec<(u64, hil_sim::requirements::Measure)>,
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
    /// The speed law's drive met the requirements on the campaign's corner runs in software
    /// in the loop before the file was written (`--speed auto`; a forced law is not run).
    pub met_in_sil: bool,
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

/// Tune `motor` on the template drive file (`template_text`, read from `template_path`).
pub fn tune(
    template_path: &Path,
    template_text: &str,
    motor: &MotorParams,
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
    if spec.current_frame == CurrentFrame::Synchronous && structure.current == CurrentDesign::Icad {
        return Err(
            "the template's current frame is synchronous: ICAD's lag pair is placed at the stationary \
                    frame's top speed ω_h, where the field frame's currents are constant — take the PI \
                    (--current pi), or a stationary-frame template"
                .into(),
        );
    }
    spec.motor = *motor;
    if let Some(iv) = intervals {
        cert.rs_factor = hull(cert.rs_factor, motor.rs_ohm(), iv.rs_ohm);
        cert.rr_factor = hull(cert.rr_factor, motor.rr_ohm(), iv.rr_ohm);
        for (nominal, i) in [motor.ls_h(), motor.lr_h(), motor.lm_h()].into_iter().zip(iv.inductances_h) {
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
                let pass = |w: f64| {
                    Ok::<_, String>(certify_current(&with_law(&spec, law(w)), &cert)?.iter().all(|c| c.pass))
                };
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
    let lines = file.encoder_lines();
    let t_slow = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
    let kp_noise = encoder_kp_limit(tau_max, lines, t_slow);
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
    // The requirements over the box, predicted from the speed law alone (the campaign then
    // judges the whole drive): on the drive's rated bus, or 310 V within its range.
    let vdc = prediction_bus_v(&file);
    let p_misses = predicted_misses(&spec, &cert, &file, vdc)?;
    // The link may lower k_p only as far as the requirements still hold (a P law's droop
    // grows as 1/k_p): the least writable k_p is the lowest of [k_p/2, k_p] that meets them.
    if p_misses.is_empty() {
        cert.speed_kp_writable[0] = least_writable_kp(&spec, &cert, &file, vdc)?;
    }
    // A P law predicted to meet them is run like a searched PI: its drive on the campaign's
    // corner runs in software in the loop (the prediction has no current loops, field
    // orientation or sensors: on 8 of the population's 87 drives a law predicted to meet the
    // requirements missed them in the campaign).
    let p_sil = match structure.speed {
        SpeedDesign::Auto if p_misses.is_empty() => {
            let c = prediction_campaign(&spec, &cert, &file, vdc);
            sil_misses(&c)?
        }
        _ => None,
    };
    let p_origin = format!("crossover {omega_s:.1} rad/s on the nominal inertia");
    let (speed_design, predicted, speed_origin) = match structure.speed {
        SpeedDesign::SaturatedP => (SpeedDesign::SaturatedP, p_misses, p_origin),
        SpeedDesign::Auto if p_misses.is_empty() && p_sil.is_none() => {
            (SpeedDesign::SaturatedP, p_misses, format!("{p_origin}{}", met_in_sil_words()))
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
            let choice = pi.choose(&spec, &cert, &file, vdc)?;
            if structure.speed == SpeedDesign::Auto && !choice.misses.is_empty() {
                let p_kp = law_gains(&spec.speed_law).0;
                let p_why = match &p_sil {
                    Some(why) => format!(
                        "saturated P (k_p {p_kp:.4e}) is predicted to meet them, but its drive misses them in \
                         software in the loop on the campaign's corner runs: {why}"
                    ),
                    None => format!("saturated P (k_p {p_kp:.4e}) misses {}", describe(&p_misses)),
                };
                return Err(format!(
                    "no speed law meets the requirements over the box (predicted on the ideal actuator, {vdc:.0} V): \
                     {p_why}; {} — relax [requirements], or take a smaller box",
                    pi.refusal(&choice, lines, t_slow),
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
                    choice.tried,
                    met_in_sil_words()
                )
            } else {
                let sil = if choice.misses.is_empty() { met_in_sil_words() } else { String::new() };
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
    let (text, changes) = write(template_text, template_path, &spec, &cert, omega_c, &speed_origin)?;
    // The file as written, read back and certified whole.
    let back =
        drive_file::DriveFile::parse(Path::new("<tuned>"), &text).map_err(|e| format!("tuned file: {e}"))?;
    let back_cert = back.certify.ok_or("tuned file lost its [certify]")?;
    let checks = certify(&back.spec, &back_cert)?;
    if let Some(c) = checks.iter().find(|c| !c.pass) {
        return Err(format!("the tuned file fails `{}` at {} (as written)", c.name, c.corner));
    }
    Ok(Tuned {
        structure,
        predicted_misses: predicted,
        current_robustness: robustness(&certify_current(&back.spec, &back_cert)?).0,
        text,
        spec: back.spec,
        certify: back_cert,
        omega_c_rad_s: omega_c,
        omega_s_rad_s: omega_s,
        checks,
        speed_origin,
        met_in_sil,
        changes,
    })
}

/// The bus the requirements are predicted on: the file's rated bus, or the campaign's
/// default within the drive's bus range ([`hil_sim::commands::default_bus_v`]).
fn prediction_bus_v(file: &drive_file::DriveFile) -> f64 {
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
/// magnetize first.
fn prediction_campaign(
    spec: &DriveSpec,
    cert: &CertifySpec,
    file: &drive_file::DriveFile,
    vdc_v: f64,
) -> hil_sim::campaign::Campaign {
    use hil_sim::campaign::{CORNER_RUNS, Campaign, MIN_AFTER_STEP_S};
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
    c.duration_s = c.duration_s.max(c.step_s() + 2.0 * MIN_AFTER_STEP_S);
    c
}

/// The requirements missed among runs' measures, each once with its worst run.
fn missed(measures: Vec<(u64, Vec<hil_sim::requirements::Measure>)>) -> Misses {
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
struct Screen<'a> {
    predictor: hil_sim::campaign::Predictor<'a>,
    hard: Vec<u64>,
}

impl Screen<'_> {
    fn misses(&mut self, law: &SpeedLaw) -> Result<Misses, String> {
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
fn setpoint_weight(law: &SpeedLaw) -> f64 {
    match *law {
        SpeedLaw::PiTorque { setpoint_weight, .. } | SpeedLaw::PiIq { setpoint_weight, .. } => {
            setpoint_weight
        }
        SpeedLaw::SaturatedP { .. } => 1.0,
    }
}

/// `requirements.x (worst run k: value against allowed), …`.
fn describe(misses: &[(u64, hil_sim::requirements::Measure)]) -> String {
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
fn least_writable_kp(
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

/// The ICAD gain (V/A) of [`icad_law`] at `omega_h` with the largest [`robustness`] of the
/// current checks over the box: a geometric grid from `kp_range[1]` down (ratio
/// [`ICAD_GRID_RATIO`]), then a golden-section search between the best point's neighbours.
/// Refused when even the best does not pass every current check.
fn icad_gain(
    spec: &mut DriveSpec,
    cert: &CertifySpec,
    omega_h: f64,
    kp_range: [f64; 2],
) -> Result<f64, String> {
    let mut score = |kp: f64| -> Result<f64, String> {
        spec.current_law = icad_law(kp, omega_h);
        Ok(robustness(&certify_current(spec, cert)?).0)
    };
    let mut grid = Vec::new();
    let mut kp = kp_range[1];
    while kp >= kp_range[0] {
        grid.push((kp, score(kp)?));
        kp *= ICAD_GRID_RATIO;
    }
    let best = (0..grid.len())
        .max_by(|&a, &b| grid[a].1.total_cmp(&grid[b].1))
        .ok_or("internal: an empty ICAD gain grid")?;
    let (kp_best, s_best) = grid[best];
    // Golden section on ln k_p between the neighbours (or the grid's end).
    let (mut lo, mut hi) = ((kp_best * ICAD_GRID_RATIO).ln(), (kp_best / ICAD_GRID_RATIO).ln());
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut f1, mut f2) = (score(x1.exp())?, score(x2.exp())?);
    for _ in 0..ICAD_REFINE_STEPS {
        if f1 >= f2 {
            hi = x2;
            (x2, f2) = (x1, f1);
            x1 = hi - g * (hi - lo);
            f1 = score(x1.exp())?;
        } else {
            lo = x1;
            (x1, f1) = (x2, f2);
            x2 = lo + g * (hi - lo);
            f2 = score(x2.exp())?;
        }
    }
    let (kp, s) = [(kp_best, s_best), (x1.exp(), f1), (x2.exp(), f2)]
        .into_iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((kp_best, s_best));
    if s < 1.0 {
        spec.current_law = icad_law(kp, omega_h);
        let checks = certify_current(spec, cert)?;
        let why = robustness(&checks).1.map_or(String::new(), |c| match c.value {
            Some(v) => format!(": `{}` at {} is {v:.3} of {}", c.name, c.corner, c.limit),
            None => format!(": `{}` at {} fails", c.name, c.corner),
        });
        return Err(format!(
            "no ICAD gain from {:.4} to {:.4} V/A passes every current check on every corner at ω_h = {omega_h} rad/s \
             — the most robust, k_p = {kp:.4} V/A, falls short{why} (the box, the top speed or the PWM rate asks \
             too much)",
            kp_range[0], kp_range[1]
        ));
    }
    Ok(kp)
}

/// The current loops' other frame.
fn other_frame(f: CurrentFrame) -> CurrentFrame {
    match f {
        CurrentFrame::Stationary => CurrentFrame::Synchronous,
        CurrentFrame::Synchronous => CurrentFrame::Stationary,
    }
}

/// The template's tables with `[motor]`, the gains and `[certify]`'s box and writable
/// ranges replaced (comments are not kept: the header says where the file came from).
/// The template `template_text` with the tuned values written into it, and what changed.
///
/// Edited in place (`toml_edit`): the template's comments, order and layout stay; a value
/// tune sets keeps the comment after it, unless it is a law table whose `kind` changed (the
/// comment described the template's law). Each value that differs from the template's —
/// compared as numbers, not as text — is listed as `key: old → new` (`(absent)` where the
/// template did not state it), and each key a new law drops as `key: old → (removed)`.
fn write(
    template_text: &str,
    template_path: &Path,
    spec: &DriveSpec,
    cert: &CertifySpec,
    omega_c: f64,
    speed_origin: &str,
) -> Result<(String, Vec<String>), String> {
    use toml_edit::{Array, DocumentMut, Value};
    // A tuned file used as the template: its header described the last tune, not this one.
    let body = match template_text.strip_prefix(HEADER_START) {
        Some(rest) => {
            rest.split_once(HEADER_END).map_or(template_text, |(_, after)| after.trim_start_matches('\n'))
        }
        None => template_text,
    };
    let mut doc: DocumentMut = body.parse().map_err(|e| format!("{}: {e}", template_path.display()))?;
    let mut changes = Vec::new();
    let float = |x: f64| Value::from(x);
    let pair = |p: [f64; 2]| Value::Array(p.into_iter().map(float).collect::<Array>());
    let m = &spec.motor;
    // The tuned motor is linear (`MotorParams`), written in the T form unless it has no
    // rotor leakage (the inverse-Γ form: L_r = L_m) or no stator leakage (the Γ form:
    // L_s = L_m), which the T form refuses; the keys of the other forms, and the saturation
    // the linear model does not take, go.
    let (form, leakage_h, gone) = if m.lr_h() == m.lm_h() {
        (Some("inverse_gamma"), m.ls_h() - m.lm_h(), ["ls_h", "lr_h", "saturation"])
    } else if m.ls_h() == m.lm_h() {
        (Some("gamma"), m.lr_h() - m.lm_h(), ["ls_h", "lr_h", "saturation"])
    } else {
        (None, 0.0, ["form", "l_sigma_h", "saturation"])
    };
    let mut motor = vec![("rs_ohm", float(m.rs_ohm())), ("rr_ohm", float(m.rr_ohm()))];
    match form {
        Some(f) => motor.extend([("form", Value::from(f)), ("l_sigma_h", float(leakage_h))]),
        None => motor.extend([("ls_h", float(m.ls_h())), ("lr_h", float(m.lr_h()))]),
    }
    motor.extend([("lm_h", float(m.lm_h())), ("j_kgm2", float(m.j_kgm2())), ("b_nms", float(m.b_nms()))]);
    motor.push(("pole_pairs", Value::from(i64::from(m.pole_pairs()))));
    if let Some(t) = doc.get_mut("motor").and_then(|t| t.as_table_like_mut()) {
        for key in gone {
            if let Some(old) = t.remove(key) {
                let old = old.as_value().map_or_else(|| "a table".to_string(), bare);
                changes.push(format!("motor.{key}: {old} → (removed)"));
            }
        }
    }
    set_keys(&mut doc, "motor", &motor, &mut changes)?;
    let law = &spec.current_law;
    let mut current = vec![
        ("kind", Value::from(if law.lag.is_some() { "icad" } else { "pi" })),
        ("kp", float(law.kp_v_per_a)),
        ("ki", float(law.ki_v_per_as)),
    ];
    let triple = |p: [f64; 3]| Value::Array(p.into_iter().map(float).collect::<Array>());
    if let Some(lag) = &law.lag {
        current.push(("lag_num", triple(lag.num)));
        current.push(("lag_den", triple(lag.den)));
    }
    let speed = match spec.speed_law {
        SpeedLaw::SaturatedP { kp, tau_max_nm } => {
            vec![("kind", Value::from("saturated_p")), ("kp", float(kp)), ("tau_max_nm", float(tau_max_nm))]
        }
        SpeedLaw::PiTorque { kp, ki, limit, setpoint_weight } => vec![
            ("kind", Value::from("pi_torque")),
            ("kp", float(kp)),
            ("ki", float(ki)),
            ("limit", float(limit)),
            ("setpoint_weight", float(setpoint_weight)),
        ],
        SpeedLaw::PiIq { .. } => return Err("internal: tune does not write an i_q speed law".into()),
    };
    let position = [
        ("k_per_s", float(spec.position.k_per_s)),
        ("omega_max_rad_s", float(spec.position.omega_max_rad_s)),
    ];
    let controller =
        doc.get_mut("controller").and_then(|c| c.as_table_like_mut()).ok_or("no [controller] table")?;
    let frame = match spec.current_frame {
        CurrentFrame::Stationary => "stationary",
        CurrentFrame::Synchronous => "synchronous",
    };
    set_law(controller, "controller.current", &current, &mut changes)?;
    set_value(controller, "controller", "current_frame", Value::from(frame), &mut changes);
    set_law(controller, "controller.speed", &speed, &mut changes)?;
    set_value(
        controller,
        "controller",
        "rotor_resistance_range",
        pair(spec.rotor_resistance_range),
        &mut changes,
    );
    set_value(controller, "controller", "inductance_range", pair(spec.inductance_range), &mut changes);
    set_law(controller, "controller.position", &position, &mut changes)?;
    let certify = [
        ("rs_factor", pair(cert.rs_factor)),
        ("rr_factor", pair(cert.rr_factor)),
        ("inductance_factor", pair(cert.inductance_factor)),
        ("j_factor", pair(cert.j_factor)),
        ("speed_kp_writable", pair(cert.speed_kp_writable)),
        ("speed_tau_max_nm_writable", pair(cert.speed_tau_max_nm_writable)),
    ];
    set_keys(&mut doc, "certify", &certify, &mut changes)?;
    let speed_loop = match spec.speed_law {
        SpeedLaw::SaturatedP { .. } => format!("saturated-P speed loop,\n# {speed_origin}"),
        _ => format!("PI speed loop,\n# {speed_origin}"),
    };
    let current = if law.lag.is_some() {
        "ICAD current loops (seed 002\n# eq. (20)'s placement scaled to the top rotor speed, the gain the most robust over the box)"
    } else {
        "PI current loops with their zero\n# on the stator's pole (the fastest the certificate passes on every corner)"
    };
    Ok((
        format!(
            "{HEADER_START} from the template {} (design::tune): {frame}-frame {current},\n\
             # crossover {omega_c:.0} rad/s on the nominal motor; {speed_loop}{HEADER_END}{doc}",
            template_path.display()
        ),
        changes,
    ))
}

/// The first words of the header `design tune` writes …
const HEADER_START: &str = "# Tuned by `design tune`";
/// … and its last.
const HEADER_END: &str = ". `design certify` this file.\n";

/// The value's text without its decoration (the comment and spaces around it).
fn bare(v: &toml_edit::Value) -> String {
    let mut v = v.clone();
    v.decor_mut().clear();
    if let Some(t) = v.as_inline_table_mut() {
        t.fmt();
    }
    v.to_string()
}

/// The same value: numbers compared as numbers (a template's `2` is the tuned `2.0`),
/// arrays element by element, anything else by its text.
fn same(a: &toml_edit::Value, b: &toml_edit::Value) -> bool {
    let number = |v: &toml_edit::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
    match (a, b) {
        (toml_edit::Value::Array(x), toml_edit::Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y.iter()).all(|(p, q)| same(p, q))
        }
        _ => match (number(a), number(b)) {
            (Some(x), Some(y)) => x == y,
            _ => bare(a) == bare(b),
        },
    }
}

/// `table.key = new`, the old value's comment kept; a change listed as `path.key: old → new`.
fn set_value(
    table: &mut dyn toml_edit::TableLike,
    path: &str,
    key: &str,
    new: toml_edit::Value,
    changes: &mut Vec<String>,
) {
    match table.get_mut(key).and_then(|i| i.as_value_mut()) {
        Some(old) if same(old, &new) => {}
        Some(old) => {
            changes.push(format!("{path}.{key}: {} → {}", bare(old), bare(&new)));
            let decor = old.decor().clone();
            *old = new;
            *old.decor_mut() = decor;
        }
        None => {
            changes.push(format!("{path}.{key}: (absent) → {}", bare(&new)));
            table.insert(key, toml_edit::Item::Value(new));
        }
    }
}

/// The keys `values` of the top-level table `name` (made if the template has none).
fn set_keys(
    doc: &mut toml_edit::DocumentMut,
    name: &str,
    values: &[(&str, toml_edit::Value)],
    changes: &mut Vec<String>,
) -> Result<(), String> {
    let table = doc
        .entry(name)
        .or_insert_with(toml_edit::table)
        .as_table_like_mut()
        .ok_or_else(|| format!("[{name}] is not a table"))?;
    for (key, v) in values {
        set_value(table, name, key, v.clone(), changes);
    }
    Ok(())
}

/// A law's table `path` (`controller.speed`: its last part the key in `parent`) with
/// exactly the keys `values`: an inline table stays inline, a table stays a table; the
/// keys another law had are removed; the comment after an inline table is kept unless the
/// law's `kind` changed.
fn set_law(
    parent: &mut dyn toml_edit::TableLike,
    path: &str,
    values: &[(&str, toml_edit::Value)],
    changes: &mut Vec<String>,
) -> Result<(), String> {
    let key = path.rsplit('.').next().unwrap_or(path);
    let item = parent.entry(key).or_insert(toml_edit::Item::None);
    if item.is_none() {
        *item = toml_edit::Item::Value(toml_edit::Value::InlineTable(toml_edit::InlineTable::new()));
    }
    let kind_changed =
        match (item.get("kind").and_then(|k| k.as_str()), values.iter().find(|(k, _)| *k == "kind")) {
            (Some(old), Some((_, new))) => new.as_str() != Some(old),
            _ => false,
        };
    if kind_changed && let Some(v) = item.as_value_mut() {
        v.decor_mut().clear();
    }
    let table = item.as_table_like_mut().ok_or_else(|| format!("`{path}` is not a table"))?;
    let stale: Vec<String> =
        table.iter().map(|(k, _)| k.to_string()).filter(|k| !values.iter().any(|(v, _)| v == k)).collect();
    for k in stale {
        if let Some(old) = table.remove(&k) {
            let old = old.as_value().map_or_else(|| "a table".to_string(), bare);
            changes.push(format!("{path}.{k}: {old} → (removed)"));
        }
    }
    for (k, v) in values {
        set_value(table, path, k, v.clone(), changes);
    }
    if let Some(t) = item.as_inline_table_mut() {
        t.fmt();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEMPLATE: &str = include_str!("../../drive.toml");

    /// Every shipped DeLorenzo motor on the shipped board: a drive file that the certificate
    /// passes whole, with faster or equal current loops than the search's floor.
    #[test]
    fn shipped_motors_on_the_shipped_board_are_certified() {
        for name in ["delorenzo-appendix", "delorenzo-eq13", "delorenzo-perturbed"] {
            let m = drive_file::motor::load(name).unwrap();
            let t = tune(Path::new("drive.toml"), TEMPLATE, &m, None, Structure::default()).unwrap();
            assert!(t.checks.iter().all(|c| c.pass), "{name}");
            // The position loop: critically damped on the heaviest inertia, the sampled
            // cascade among the checks.
            let omega_b = t.omega_s_rad_s / t.certify.j_factor[1];
            assert!((t.spec.position.k_per_s - omega_b / POSITION_BELOW_SPEED).abs() < 1e-12);
            assert!(t.checks.iter().any(|c| c.name.starts_with("sampled position") && c.pass));
            assert!(
                t.omega_c_rad_s > 1000.0 && t.omega_s_rad_s > 1.0,
                "{name}: {} {}",
                t.omega_c_rad_s,
                t.omega_s_rad_s
            );
            println!(
                "{name}: ω_c {:.0} rad/s, ω_s {:.1} rad/s, {} checks",
                t.omega_c_rad_s,
                t.omega_s_rad_s,
                t.checks.len()
            );
        }
    }

    /// The ICAD placement at ω_h = 400 rad/s (the shipped drive's top speed) with eq. (20)'s
    /// gain is eq. (20), coefficient for coefficient.
    #[test]
    fn icad_placement_at_the_shipped_top_speed_is_eq20() {
        assert_eq!(icad_law(326.5, 400.0), CurrentLaw::ICAD_EQ20);
    }

    /// Issue 21: on the DeLorenzo motor the tuned ICAD controller has margins at least as good
    /// as eq. (20)'s at ω_r = 375 rad/s — every margin of the paper's continuous analysis, the
    /// coupling and the stable speed range, and the sampled phase, gain-reduction and γh
    /// margins. The sampled gain-*increase* margin is the one figure below eq. (20)'s (the
    /// price of a faster crossover; docs/design-toolkit.md), asserted at twice the minimum.
    /// The criterion itself: over the box, the tuned gain's smallest margin-to-minimum ratio
    /// is at least eq. (20)'s.
    #[test]
    fn tuned_icad_is_at_least_as_robust_as_eq20() {
        let m = drive_file::motor::load("delorenzo-appendix").unwrap();
        let t = tune(
            Path::new("drive.toml"),
            TEMPLATE,
            &m,
            None,
            Structure { current: CurrentDesign::Icad, ..Default::default() },
        )
        .unwrap();
        assert!(t.checks.iter().all(|c| c.pass));
        let law = t.spec.current_law;
        assert_eq!(law.lag, CurrentLaw::ICAD_EQ20.lag);
        assert_eq!(law.ki_v_per_as / law.kp_v_per_a, 1000.0);
        // The criterion lands near the paper's hand design (Bode shaping, k_p = 326.5 V/A).
        assert!((law.kp_v_per_a / 326.5 - 1.0).abs() < 0.05, "{}", law.kp_v_per_a);
        let eq20 = CurrentLaw::ICAD_EQ20;
        let ts = 1.0 / t.spec.pwm_frequency_hz;
        let report = |l: &CurrentLaw| {
            let ctrl = controller_core::current::CurrentControllerConfig::<f32>::new(
                l,
                ts,
                t.spec.discretization,
                1.0,
            )
            .unwrap();
            (
                crate::icad::analyse(&m, l, 375.0),
                crate::sampled::analyse(&m, &ctrl, ts, 375.0),
                crate::icad::stable_omega_r_max(&m, l, 5.0, 5000.0).unwrap(),
                crate::sampled::stable_omega_r_max(&m, &ctrl, ts, 5.0, 5000.0).unwrap(),
            )
        };
        let (c, s, range, s_range) = report(&law);
        let (c0, s0, range0, s_range0) = report(&eq20);
        let f = |x: Option<f64>| x.unwrap();
        println!("at 375 rad/s        tuned ICAD   eq. (20)");
        for (what, a, b) in [
            ("crossover", f(c.channel.crossover_rad_s), f(c0.channel.crossover_rad_s)),
            ("phase margin", f(c.channel.phase_margin_deg), f(c0.channel.phase_margin_deg)),
            ("gain reduction", f(c.channel.gain_margin_reduction_db), f(c0.channel.gain_margin_reduction_db)),
            ("γh margin", f(c.gamma_h_margin_db), f(c0.gamma_h_margin_db)),
            ("sampled phase", f(s.channel.phase_margin_deg), f(s0.channel.phase_margin_deg)),
            (
                "sampled reduction",
                f(s.channel.gain_margin_reduction_db),
                f(s0.channel.gain_margin_reduction_db),
            ),
            ("sampled γh", f(s.gamma_h_margin_db), f(s0.gamma_h_margin_db)),
            ("stable range", range, range0),
            ("sampled range", s_range, s_range0),
        ] {
            println!("{what:<20}{a:>10.2}{b:>10.2}");
            assert!(a >= b, "{what}: {a} < eq. (20)'s {b}");
        }
        assert!(c.coupling_peak_db <= c0.coupling_peak_db, "{} {}", c.coupling_peak_db, c0.coupling_peak_db);
        // No gain-increase margin exists continuously (the phase never crosses −180°).
        assert!(c.channel.gain_margin_increase_db.is_none() && c0.channel.gain_margin_increase_db.is_none());
        let (gi, gi0) = (f(s.channel.gain_margin_increase_db), f(s0.channel.gain_margin_increase_db));
        println!("sampled increase    {gi:>10.2}{gi0:>10.2}  (minimum 6)");
        assert!(gi >= 12.0, "{gi}");
        let (_, cert) = crate::certify::parse(Path::new("drive.toml"), TEMPLATE).unwrap();
        let mut shipped = t.spec;
        shipped.current_law = eq20;
        let r0 = robustness(&certify_current(&shipped, &cert).unwrap()).0;
        println!("robustness over the box: tuned {:.4}, eq. (20) {r0:.4}", t.current_robustness);
        assert!(t.current_robustness >= r0);
    }

    /// `--speed pi` on the DeLorenzo motor: a PI with integral action inside every region
    /// of seed 000's design (margins and bandwidth on all 16 Kharitonov plants of the
    /// inertia interval, k_p under the encoder-noise limit), away from their boundary (±5 %
    /// in either gain stays inside), and certified — the exact sampled loop included.
    #[test]
    fn speed_pi_lies_inside_seed000s_regions() {
        let m = drive_file::motor::load("delorenzo-appendix").unwrap();
        let structure = Structure { speed: SpeedDesign::Pi, ..Default::default() };
        let t = tune(Path::new("drive.toml"), TEMPLATE, &m, None, structure).unwrap();
        assert!(t.checks.iter().all(|c| c.pass));
        let SpeedLaw::PiTorque { kp, ki, limit, .. } = t.spec.speed_law else {
            panic!("{:?}", t.spec.speed_law)
        };
        assert_eq!(limit, 2.0);
        let c = &t.certify;
        let t_slow = f64::from(t.spec.slow_divider) / t.spec.pwm_frequency_hz;
        let r = SpeedRegions::new(
            [m.j_kgm2() * c.j_factor[0], m.j_kgm2() * c.j_factor[1]],
            m.b_nms(),
            t_slow,
            [c.phase_margin_deg_min, c.gain_margin_db_min],
        )
        .unwrap();
        let omega_b = heaviest_speed_bandwidth(t.omega_s_rad_s, c);
        let kp_noise = encoder_kp_limit(2.0, 1024, t_slow);
        println!("speed PI: kp {kp:.5}, ki {ki:.5}, ω_B {omega_b:.2} rad/s, kp limit {kp_noise:.5}");
        assert!(ki > 0.0 && kp <= kp_noise);
        for (a, b) in [(1.0, 1.0), (0.95, 1.0), (1.05, 1.0), (1.0, 0.95), (1.0, 1.05)] {
            let (x, y) = (a * kp, b * ki);
            assert!(r.margins(x, y) && r.bandwidth(x, y, omega_b), "({x}, {y}) outside");
        }
    }

    /// The speed PI's drive in the nonlinear campaign, on the narrow box (what
    /// self-commissioning's intervals give): every run passes the campaign's criteria (the
    /// requirements drive.toml states for its P law are printed: the PI overshoots its
    /// torque-limited reversals by ≈ 13 % against 10 %).
    #[test]
    fn speed_pi_passes_the_campaign() {
        use hil_sim::campaign::Campaign;
        use std::sync::atomic::AtomicBool;
        let template = TEMPLATE
            .replace("rr_factor = [1.0, 2.0]", "rr_factor = [1.0, 1.2]")
            .replace("inductance_factor = [0.6, 1.0]", "inductance_factor = [0.95, 1.05]");
        let m = drive_file::motor::load("delorenzo-appendix").unwrap();
        let structure = Structure { speed: SpeedDesign::Pi, ..Default::default() };
        let t = tune(Path::new("narrow.toml"), &template, &m, None, structure).unwrap();
        let c = Campaign {
            spec: t.spec,
            certify: t.certify,
            vdc_v: 310.0,
            duration_s: 1.0,
            runs: 64,
            seed: 1,
            shard: (0, 1),
            encoder_lines: drive_file::drive::DEFAULT_ENCODER_LINES,
            plant: None,
            requirements: drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap().requirements,
        };
        let v = c.run(|_| {}, &AtomicBool::new(false)).unwrap();
        let bad: Vec<String> =
            v.iter().filter(|v| !v.criteria_failed().is_empty()).map(|v| v.csv()).collect();
        println!("speed PI on drive.toml's requirements: missed {}", missed_counts(&v));
        assert!(bad.is_empty(), "{} of {} fail:\n{}", bad.len(), v.len(), bad.join("\n"));
    }

    /// `requirement ×runs` for each requirement `verdicts` missed.
    fn missed_counts(verdicts: &[hil_sim::campaign::Verdict]) -> String {
        let mut n = std::collections::BTreeMap::new();
        for r in verdicts.iter().flat_map(|v| v.requirements_missed()) {
            *n.entry(r.key()).or_insert(0) += 1;
        }
        n.iter().map(|(k, c)| format!("{k} ×{c}")).collect::<Vec<_>>().join(", ")
    }

    /// A PWM rate too slow for the ICAD loops at the top speed: refused, naming the check
    /// that binds (at 5 kHz the sampled phase margin stays under 18° of 45°).
    /// The tuned file is the template edited in place: every comment of `drive.toml` is
    /// still there, and each value tune changed is named with its old and new value (the
    /// speed gain, the writable range it certifies, the current law ICAD → PI); the values it
    /// kept are not listed. (Until this, tune wrote the file anew from its parsed values:
    /// every comment gone, the writable ranges rewritten silently.)
    #[test]
    fn the_tuned_file_keeps_the_templates_comments_and_names_each_change() {
        let path = Path::new("drive.toml");
        let m = drive_file::motor::load("delorenzo-appendix").unwrap();
        let t = tune(path, TEMPLATE, &m, None, Structure::default()).unwrap();
        // The ICAD law's comment goes with it (the law is now a PI); every other stays.
        for line in TEMPLATE.lines().filter(|l| l.contains('#') && !l.starts_with("current = ")) {
            let comment = &line[line.find('#').unwrap()..];
            assert!(t.text.contains(comment), "lost: {comment}");
        }
        assert!(!t.text.contains("# seed 002 eq. (20)"), "an ICAD comment on a PI law");
        let named = |prefix: &str| t.changes.iter().any(|c| c.starts_with(prefix));
        assert!(named("controller.speed.kp: 0.05 → "), "{:#?}", t.changes);
        assert!(named("certify.speed_kp_writable: [0.04, 0.1] → "), "{:#?}", t.changes);
        assert!(named("controller.current.kind: \"icad\" → \"pi\""), "{:#?}", t.changes);
        assert!(!named("motor."), "the template's motor is the one tuned: {:#?}", t.changes);
        // What it names is what differs.
        let back = drive_file::DriveFile::parse(path, &t.text).unwrap();
        assert_eq!(back.spec.speed_law, t.spec.speed_law);
        // Tuned again from its own output: one header (this tune's), nothing changed.
        let again = tune(path, &t.text, &m, None, Structure::default()).unwrap();
        assert_eq!(again.text.matches(HEADER_START).count(), 1, "{}", again.text);
        assert!(again.changes.is_empty(), "{:#?}", again.changes);
    }

    /// A template whose motor is written in another form (Γ, with its saturation) is tuned
    /// in the T form the tuned motor has: the other form's keys go, named. Found by trying:
    /// tune wrote the T keys beside `form = "gamma"` and refused its own file ("tuned file:
    /// motor.ls_h: belongs to the T form").
    #[test]
    fn a_template_in_another_motor_form_is_tuned_in_the_t_form() {
        let a = TEMPLATE.find("[motor]").unwrap();
        let b = a + TEMPLATE[a + 1..].find("\n[").unwrap() + 1;
        let gamma = "[motor]\nform = \"gamma\"\nrs_ohm = 16.2\nrr_ohm = 23.86\nlm_h = 1.998\nl_sigma_h = 0.1026\n\
                     pole_pairs = 1\nj_kgm2 = 0.005\nb_nms = 0.0005\nrated_current_a = 0.88\n\
                     thermal_time_constant_s = 900.0\n\n[motor.saturation]\nbeta_per_wb = 0.9\nexponent = 7.0\n";
        let template = format!("{}{gamma}{}", &TEMPLATE[..a], &TEMPLATE[b..]);
        drive_file::DriveFile::parse(Path::new("gamma.toml"), &template).unwrap();
        let m = drive_file::motor::load("delorenzo-appendix").unwrap();
        let t = tune(Path::new("gamma.toml"), &template, &m, None, Structure::default()).unwrap();
        for key in ["form", "l_sigma_h", "saturation"] {
            assert!(
                t.changes
                    .iter()
                    .any(|c| c.starts_with(&format!("motor.{key}: ")) && c.ends_with("(removed)")),
                "{key}: {:#?}",
                t.changes
            );
        }
        assert_eq!(t.spec.motor, m);
    }

    #[test]
    fn an_icad_the_pwm_cannot_run_is_refused() {
        let template = TEMPLATE
            .replace("frequency_hz = 20000.0", "frequency_hz = 5000.0")
            .replace("slow_divider = 10", "slow_divider = 2");
        let m = drive_file::motor::load("delorenzo-appendix").unwrap();
        let e = tune(
            Path::new("slow.toml"),
            &template,
            &m,
            None,
            Structure { current: CurrentDesign::Icad, ..Default::default() },
        )
        .unwrap_err();
        assert!(e.contains("no ICAD gain") && e.contains("sampled current: phase margin"), "{e}");
    }

    /// The 500 hp Krause machine on its 3 300 V template: certified (linear), its box holding
    /// the rotor resistances the drive's estimate may take — the template's R_r ×[1, 1.2]
    /// widened to the default estimate range ×[1, 1.5] (the tuned file's flying starts ran on
    /// the range's middle, ×1.22, outside what it certified: found by trying) and written so.
    #[test]
    fn the_krause_motor_tunes_on_its_template() {
        let template = include_str!("../../drives/krause-3300v.toml");
        assert!(template.contains("rr_factor = [1.0, 1.2]") && !template.contains("rotor_resistance_range"));
        let m = drive_file::motor::load("krause-2300v-500hp").unwrap();
        let t =
            tune(Path::new("drives/krause-3300v.toml"), template, &m, None, Structure::default()).unwrap();
        assert!(t.checks.iter().all(|c| c.pass));
        assert_eq!(t.spec.rotor_resistance_range, controller_core::mras::DEFAULT_RANGE);
        assert_eq!(t.certify.rr_factor, controller_core::mras::DEFAULT_RANGE);
        let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap();
        assert_eq!(written.certify.unwrap().rr_factor, controller_core::mras::DEFAULT_RANGE);
        // A range of one value is the estimate switched off: it stays so (the box holds it).
        let off = template.replace("[controller]\n", "[controller]\nrotor_resistance_range = [1.0, 1.0]\n");
        assert_ne!(off, template);
        let t = tune(Path::new("off.toml"), &off, &m, None, Structure::default()).unwrap();
        assert_eq!(t.spec.rotor_resistance_range, [1.0, 1.0]);
        assert_eq!(t.certify.rr_factor, [1.0, 1.2]);
        let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap();
        assert_eq!(written.spec.rotor_resistance_range, [1.0, 1.0]);
    }

    /// A template sized for motor `m` on a 310 V bus: rated flux 0.9·(V_dc/√3)/(2π·50 Hz),
    /// current limit three times the magnetizing current, τ_max half of what it gives,
    /// trip at twice the limit; the narrow box self-commissioning supports.
    fn template_for(m: &MotorParams) -> String {
        let psi = 0.9 * 310.0 / 3f64.sqrt() / (2.0 * std::f64::consts::PI * 50.0);
        let i_d = psi / m.lm_h();
        let i_max = 3.0 * i_d;
        let tau = 0.5 * m.torque_factor() * psi * (i_max * i_max - i_d * i_d).sqrt();
        format!(
            "[pwm]\nfrequency_hz = 20000.0\nslow_divider = 10\n\
             [motor]\nrs_ohm = {}\nrr_ohm = {}\nls_h = {}\nlr_h = {}\nlm_h = {}\npole_pairs = {}\nj_kgm2 = {}\nb_nms = {}\n\
             [controller]\ncurrent = {{ kind = \"pi\", kp = 1.0, ki = 1.0 }}\n\
             speed = {{ kind = \"saturated_p\", kp = 0.001, tau_max_nm = {tau} }}\n\
             flux_ref_wb = {psi}\ni_ref_max_a = {i_max}\n\
             [protection]\ni_trip_a = {}\nvdc_min_v = 250.0\nvdc_max_v = 370.0\n\
             [certify]\nomega_r_max_rad_s = 628.0\nrs_factor = [1.0, 1.5]\nrr_factor = [1.0, 1.2]\n\
             inductance_factor = [0.95, 1.05]\nj_factor = [1.0, 2.0]\nspeed_kp_writable = [0.0005, 0.002]\n\
             speed_tau_max_nm_writable = [{}, {tau}]\nphase_margin_deg_min = 45.0\ngain_margin_db_min = 6.0\n\
             gamma_h_margin_db_min = 1.0\n",
            m.rs_ohm(),
            m.rr_ohm(),
            m.ls_h(),
            m.lr_h(),
            m.lm_h(),
            m.pole_pairs(),
            m.j_kgm2(),
            m.b_nms(),
            2.0 * i_max,
            tau / 20.0,
        )
    }

    /// Six seeded random motors in the ranges of `hil-sim/tests/identify.rs`.
    fn seeded_random_motors() -> Vec<MotorParams> {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = |lo: f64, hi: f64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            lo + (hi - lo) * (state >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..6)
            .map(|_| {
                let lm = (uniform(0.05f64.ln(), 2f64.ln())).exp();
                let (ls, lr) = (lm * (1.0 + uniform(0.02, 0.1)), lm * (1.0 + uniform(0.02, 0.1)));
                let rr = lr / uniform(0.02, 0.6);
                let rs = ls / uniform(0.01, 0.2);
                let j = uniform(1e-4, 1e-1);
                MotorParams::new(rs, rr, ls, lr, lm, 2, j, j * 0.01).unwrap()
            })
            .collect()
    }

    /// Motors the toolkit has never seen (the ranges of `hil-sim/tests/identify.rs`: 2–10 %
    /// leakage each side, L_m 0.05…2 H, T_r 20…600 ms, L_s/R_s 10…200 ms, p = 2), each on a
    /// template sized for it: the tuned file passes every linear check.
    #[test]
    fn seeded_random_motors_tune_and_certify() {
        for (k, m) in seeded_random_motors().into_iter().enumerate() {
            let template = template_for(&m);
            let t = tune(Path::new("template.toml"), &template, &m, None, Structure::default())
                .unwrap_or_else(|e| panic!("random {k} ({m:?}): {e}"));
            assert!(t.checks.iter().all(|c| c.pass), "random {k}");
            println!("random {k}: ω_c {:.0} rad/s, ω_s {:.1} rad/s", t.omega_c_rad_s, t.omega_s_rad_s);
        }
    }

    /// Issue 51's acceptance on the same random motors, each on its template's default
    /// requirements: `--speed auto` writes a file predicted to meet them, or refuses naming
    /// each requirement its laws miss. Today all six are refused — the P droops, and seed
    /// 000's PI at its best setpoint weight overshoots or rises too slowly (the population's
    /// refusals, docs/population.md) — each naming what it misses.
    #[test]
    fn seeded_random_motors_meet_the_requirements_or_are_refused_naming_them() {
        let auto = Structure { speed: SpeedDesign::Auto, ..Default::default() };
        let mut verdicts = Vec::new();
        for (k, m) in seeded_random_motors().into_iter().enumerate() {
            match tune(Path::new("template.toml"), &template_for(&m), &m, None, auto) {
                Ok(t) => {
                    assert!(t.predicted_misses.is_empty(), "random {k}: {:?}", t.predicted_misses);
                    verdicts.push(format!("random {k}: {:?}", t.spec.speed_law));
                }
                Err(e) => {
                    assert!(
                        e.starts_with("no speed law meets the requirements")
                            && e.contains("misses requirements.")
                            && e.contains("PI (seed 000's"),
                        "random {k}: {e}"
                    );
                    verdicts.push(format!("random {k}: {e}"));
                }
            }
        }
        println!("{}", verdicts.join("\n"));
    }

    /// The same random motors' tuned files in the nonlinear campaign (issue 21: "passes both
    /// certificates"): 200 runs each over the tuned file's box (`hil_sim::campaign`: speed
    /// steps, load steps to the torque limit and reversals, realistic sensors scaled to the
    /// drive's trip level), long enough for each motor to magnetize first. Every run passes
    /// (a stated gap — reversals at the R_r ×1.2 corners missing tracking by a little, the
    /// fixed-T_r orientation detuned — closed with the drive's rotor-resistance estimate,
    /// docs/rotor-resistance.md). The runs are judged on the campaign's own criteria (no
    /// fault, no flux collapse, no oscillation); the default `[requirements]` — ±1 % speed
    /// regulation, which the saturated P's droop τ_L/k_p misses by design — are printed, not
    /// asserted: choosing a speed law that meets them is the tuner's next step (issue 51).
    #[test]
    fn seeded_random_motors_pass_the_campaign() {
        use hil_sim::campaign::{Campaign, STEP_S};
        use std::sync::atomic::AtomicBool;
        let mut failed = Vec::new();
        for (k, m) in seeded_random_motors().into_iter().enumerate() {
            let t =
                tune(Path::new("template.toml"), &template_for(&m), &m, None, Structure::default()).unwrap();
            let mut c = Campaign {
                spec: t.spec,
                certify: t.certify,
                vdc_v: 310.0,
                duration_s: 1.0,
                runs: 200,
                seed: 1,
                shard: (0, 1),
                encoder_lines: drive_file::drive::DEFAULT_ENCODER_LINES,
                plant: None,
                requirements: drive_file::DriveFile::parse(Path::new("t.toml"), &t.text)
                    .unwrap()
                    .requirements,
            };
            // A long rotor time constant magnetizes later: 0.75 s after the step as at 1 s.
            c.duration_s = c.duration_s.max(c.step_s() + (1.0 - STEP_S));
            let v = c.run(|_| {}, &AtomicBool::new(false)).unwrap();
            let bad: Vec<String> =
                v.iter().filter(|v| !v.criteria_failed().is_empty()).map(|v| v.csv()).collect();
            println!(
                "random {k} (L_m {:.3} H, T_r {:.3} s, J {:.2e} kg·m², i_trip {:.2} A, runs of {:.2} s): {} of {} pass the criteria, {} meet the default requirements; missed: {}",
                m.lm_h(),
                m.lr_h() / m.rr_ohm(),
                m.j_kgm2(),
                t.spec.protection.i_trip_a,
                c.duration_s,
                v.len() - bad.len(),
                v.len(),
                v.iter().filter(|v| v.passed()).count(),
                missed_counts(&v),
            );
            for b in bad.iter().take(5) {
                println!("  {b}");
            }
            if !bad.is_empty() {
                failed.push(k);
            }
        }
        assert!(failed.is_empty(), "random motors {failed:?} fail the campaign");
    }

    /// Issue 51: the template's `[requirements]` choose the speed law. The 24 V template asks
    /// the defaults (±1 % regulation, 10 % overshoot): the saturated P's droop misses the
    /// first, so `auto` takes the PI — with the largest setpoint weight that keeps the
    /// overshoot within the second — predicted to meet them all; `--speed p` keeps the P and
    /// reports the miss. Asked for 5 % overshoot, neither law meets the requirements and the
    /// tune is refused, naming each law's misses. drive.toml's own requirements (its
    /// P law's) keep the P; the 3 300 V template is refused on the defaults.
    #[test]
    fn the_requirements_choose_the_speed_law_or_refuse_naming_them() {
        let template = include_str!("../../drives/em-synergy-24v.toml");
        let m = drive_file::motor::load("em-synergy-m800006").unwrap();
        let auto = Structure { speed: SpeedDesign::Auto, ..Default::default() };
        let t = tune(Path::new("24v.toml"), template, &m, None, auto).unwrap();
        assert!(
            matches!(t.spec.speed_law, SpeedLaw::PiTorque { .. }) && t.structure.speed == SpeedDesign::Pi
        );
        assert!(t.predicted_misses.is_empty(), "{:?}", t.predicted_misses);
        let p = tune(Path::new("24v.toml"), template, &m, None, Structure::default()).unwrap();
        let missed: Vec<_> = p.predicted_misses.iter().map(|(_, m)| m.requirement.key()).collect();
        assert!(missed.contains(&"speed_error_fraction"), "{missed:?}");
        // The defaults' 10 % overshoot: the one-degree PI overshoots a reversal by 10.3 %, the
        // setpoint weight takes it within them (b = 0.9, predicted).
        let SpeedLaw::PiTorque { setpoint_weight, .. } = t.spec.speed_law else { unreachable!() };
        assert_eq!(setpoint_weight, 0.9);
        assert!(t.text.contains("setpoint_weight = 0.9"), "written");
        // 5 %: seed 000's own point at no weight gets there without missing the rise time;
        // the search of its region finds one that does (predicted, and in SIL on the corner
        // runs).
        let strict =
            template.replace("[requirements]\n", "[requirements]\nspeed_overshoot_fraction = 0.05\n");
        let t = tune(Path::new("strict.toml"), &strict, &m, None, auto).unwrap();
        assert!(t.predicted_misses.is_empty() && matches!(t.spec.speed_law, SpeedLaw::PiTorque { .. }));
        // 1 %: refused, named, with what bounds the region.
        let strict =
            template.replace("[requirements]\n", "[requirements]\nspeed_overshoot_fraction = 0.01\n");
        let e = tune(Path::new("strict.toml"), &strict, &m, None, auto).unwrap_err();
        assert!(
            e.contains("saturated P")
                && e.contains("misses requirements.speed_error_fraction")
                && e.contains("PI (seed 000's")
                && e.contains("requirements.speed_overshoot_fraction")
                && e.contains("the region: k_p ≤"),
            "{e}"
        );
        let d = drive_file::motor::load("delorenzo-appendix").unwrap();
        let t = tune(Path::new("drive.toml"), TEMPLATE, &d, None, auto).unwrap();
        assert!(matches!(t.spec.speed_law, SpeedLaw::SaturatedP { .. }) && t.predicted_misses.is_empty());
        // The 500 hp machine on its 3 300 V template (the default requirements): neither the
        // P (its droop) nor the PI (its slow, overshooting steps) meets them — refused, named.
        let k = drive_file::motor::load("krause-2300v-500hp").unwrap();
        let e =
            tune(Path::new("krause.toml"), include_str!("../../drives/krause-3300v.toml"), &k, None, auto)
                .unwrap_err();
        assert!(e.contains("setpoint weight 1) misses requirements.speed_error_fraction"), "{e}");
    }

    /// Issue 51, deliverable 3: the link's writable gains are the ranges over which the
    /// requirements hold. drive.toml's, k_p × [0.04, 0.1], meet them at every corner
    /// (predicted); widened down to 0.02, the corners there miss the load step's dip (0.38 of
    /// base speed against the 0.25 asked) — `design certify` refuses it, naming them.
    #[test]
    fn the_writable_speed_gains_keep_the_requirements() {
        use drive_file::requirements::Requirement;
        let shipped = drive_file::DriveFile::shipped().unwrap();
        let cert = shipped.certify.unwrap();
        assert_eq!(cert.speed_kp_writable, [0.04, 0.1]);
        assert!(writable_gain_misses(&shipped.spec, &cert, &shipped).unwrap().is_empty());
        let wide = CertifySpec { speed_kp_writable: [0.02, 0.1], ..cert };
        let missed = writable_gain_misses(&shipped.spec, &wide, &shipped).unwrap();
        assert!(!missed.is_empty() && missed.iter().all(|([kp, _], _)| *kp == 0.02), "{missed:?}");
        let dip = missed
            .iter()
            .flat_map(|(_, m)| m)
            .find(|(_, m)| m.requirement == Requirement::LoadDip)
            .map(|(_, m)| (m.value, m.allowed));
        let (value, allowed) = dip.expect("the load dip is missed at k_p 0.02");
        assert!((value - 0.384).abs() < 0.01 && (allowed - 0.252).abs() < 0.001, "{value} against {allowed}");
    }

    /// The walk-through's motor on its 24 V template (docs/walkthrough.md).
    #[test]
    fn the_walkthrough_motor_tunes_on_its_template() {
        let template = include_str!("../../drives/em-synergy-24v.toml");
        let m = drive_file::motor::load("em-synergy-m800006").unwrap();
        let t =
            tune(Path::new("drives/em-synergy-24v.toml"), template, &m, None, Structure::default()).unwrap();
        assert!(t.checks.iter().all(|c| c.pass));
        let SpeedLaw::SaturatedP { kp, tau_max_nm } = t.spec.speed_law else { panic!() };
        assert_eq!(tau_max_nm, 0.12);
        // The encoder rule binds: k_p·Δω_q = 2.5 % of τ_max (Δω_q = 0.383 rad/s).
        assert!((kp * 0.3835 / (0.025 * 0.12) - 1.0).abs() < 0.01, "{kp}");
    }

    /// The inductance estimate follows the box: a template that does not state
    /// `inductance_range` gets its box's inductance interval as the range (the 24 V
    /// template's ±5 %: estimated, so that the flux is not off by the box's spread); one that
    /// states a single value keeps the estimate off; one that states a range gets the hull of
    /// the two as both box and range, written into the file.
    #[test]
    fn the_inductance_estimate_covers_the_box() {
        let template = include_str!("../../drives/em-synergy-24v.toml");
        assert!(
            template.contains("inductance_factor = [0.95, 1.05]") && !template.contains("inductance_range")
        );
        let m = drive_file::motor::load("em-synergy-m800006").unwrap();
        let tuned = |text: &str| {
            let t = tune(Path::new("t.toml"), text, &m, None, Structure::default()).unwrap();
            let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap();
            assert_eq!(written.spec.inductance_range, t.spec.inductance_range, "written as tuned");
            assert_eq!(written.certify.unwrap().inductance_factor, t.certify.inductance_factor);
            (t.spec.inductance_range, t.certify.inductance_factor)
        };
        assert_eq!(tuned(template), ([0.95, 1.05], [0.95, 1.05]));
        let state = |range: &str| {
            template.replace("[controller]\n", &format!("[controller]\ninductance_range = {range}\n"))
        };
        assert_eq!(tuned(&state("[1.0, 1.0]")), ([1.0, 1.0], [0.95, 1.05]), "stated off: kept off");
        assert_eq!(tuned(&state("[0.6, 1.0]")), ([0.6, 1.05], [0.6, 1.05]), "the hull");
    }

    /// A synchronous-frame template: the same PI rule (its zero on the stator's pole below the
    /// rotor corner holds in the field frame too), searched against the certificate in that
    /// frame, passes every check and keeps the frame; ICAD in it is refused by name.
    #[test]
    fn a_synchronous_template_tunes_a_pi() {
        let sync = TEMPLATE.replace("current_frame = \"stationary\"", "current_frame = \"synchronous\"");
        assert_ne!(sync, TEMPLATE);
        let m = drive_file::motor::load("delorenzo-appendix").unwrap();
        let t = tune(Path::new("sync.toml"), &sync, &m, None, Structure::default()).unwrap();
        assert_eq!(t.spec.current_frame, CurrentFrame::Synchronous);
        assert!(t.checks.iter().all(|c| c.pass));
        assert!(t.checks.iter().any(|c| c.name.starts_with("sampled current: worst")));
        let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap();
        assert_eq!(written.spec.current_frame, CurrentFrame::Synchronous);
        // The header names the frame (it said "stationary-frame" whatever the template's).
        assert!(t.text.starts_with("# Tuned by") && t.text.contains("synchronous-frame PI"), "{}", t.text);
        assert!(!t.text.contains("stationary"), "{}", t.text);
        println!("synchronous PI: ω_c {:.0} rad/s, {} checks", t.omega_c_rad_s, t.checks.len());
        let icad = Structure { current: CurrentDesign::Icad, ..Default::default() };
        let e = tune(Path::new("sync.toml"), &sync, &m, None, icad).unwrap_err();
        assert!(e.contains("synchronous") && e.contains("--current pi"), "{e}");
    }

    /// The strided search answers what the candidate-by-candidate one did wherever passing
    /// is monotone (every threshold over a 44-candidate grid, and none passing), with at
    /// most ⌈n/4⌉ + 3 certificates.
    #[test]
    fn the_strided_search_finds_the_first_passing_candidate() {
        let grid: Vec<f64> = candidates(5026.5, 50.0).collect();
        assert_eq!(grid.len(), 44);
        for threshold in grid.iter().copied().chain([0.0, 1e9]) {
            let mut calls = 0;
            let found = search_down(grid.iter().copied(), |w| {
                calls += 1;
                Ok(w <= threshold)
            })
            .unwrap();
            let linear = grid.iter().copied().find(|&w| w <= threshold);
            assert_eq!(found, linear, "threshold {threshold}");
            assert!(calls < grid.len().div_ceil(SEARCH_STRIDE) + SEARCH_STRIDE, "{calls} calls");
        }
        // An error stops it.
        assert!(search_down(grid.iter().copied(), |_| Err("no".into())).is_err());
    }

    /// The frame is tune's choice (issue 49: it never tried the other one): the shipped
    /// board at 10 kHz passes no stationary-frame crossover of the search on the DeLorenzo
    /// motor — the stationary PI's phase error at the top electrical speed — and the
    /// field-frame PI passes; the file records the frame taken.
    #[test]
    fn tune_takes_the_field_frame_when_the_stationary_frame_fails() {
        let at_10k = TEMPLATE
            .replace("frequency_hz = 20000.0", "frequency_hz = 10000.0")
            .replace("slow_divider = 10", "slow_divider = 5");
        assert_ne!(at_10k, TEMPLATE);
        let m = drive_file::motor::load("delorenzo-appendix").unwrap();
        let t = tune(Path::new("10k.toml"), &at_10k, &m, None, Structure::default()).unwrap();
        assert_eq!(t.spec.current_frame, CurrentFrame::Synchronous);
        assert!(t.checks.iter().all(|c| c.pass));
        let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap();
        assert_eq!(written.spec.current_frame, CurrentFrame::Synchronous);
        // The same gains in the stationary frame fail the template's own box.
        let mut spec = drive_file::DriveFile::parse(Path::new("10k.toml"), &at_10k).unwrap().spec;
        spec.motor = m;
        let cert = drive_file::DriveFile::parse(Path::new("10k.toml"), &at_10k).unwrap().certify.unwrap();
        spec.current_law = t.spec.current_law;
        assert_eq!(spec.current_frame, CurrentFrame::Stationary);
        assert!(!certify_current(&spec, &cert).unwrap().iter().all(|c| c.pass));
    }

    /// A motor without rotor leakage (inverse-Γ, L_r = L_m) or without stator leakage (Γ,
    /// L_s = L_m) is written back in its own form: in the T form the tuned file refused
    /// itself ("L_m = 0.224 H must be below lr_h = 0.224 H") and tune wrote nothing — found
    /// tuning motulator's 2.2-kW machine from motors/motulator-2kw.toml.
    #[test]
    fn a_motor_without_one_leakage_is_written_in_its_own_form() {
        let inverse_gamma = "[motor]\nform = \"inverse_gamma\"\nrs_ohm = 16.2\nrr_ohm = 22.0\nlm_h = 1.34\n\
                             l_sigma_h = 0.1\npole_pairs = 1\nj_kgm2 = 0.005\nb_nms = 0.0005\n";
        let gamma = "[motor]\nform = \"gamma\"\nrs_ohm = 16.2\nrr_ohm = 24.0\nlm_h = 1.44\nl_sigma_h = 0.1\n\
                     pole_pairs = 1\nj_kgm2 = 0.005\nb_nms = 0.0005\n";
        for (text, form) in [(inverse_gamma, "inverse_gamma"), (gamma, "gamma")] {
            let m = drive_file::motor::parse(Path::new("m.toml"), text).unwrap();
            let t = tune(Path::new("drive.toml"), TEMPLATE, &m, None, Structure::default()).unwrap();
            assert!(t.text.contains(&format!("form = \"{form}\"")), "{}", t.text);
            let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap().spec.motor;
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
            for (a, b) in [
                (written.ls_h(), m.ls_h()),
                (written.lr_h(), m.lr_h()),
                (written.lm_h(), m.lm_h()),
                (written.rr_ohm(), m.rr_ohm()),
                (written.rs_ohm(), m.rs_ohm()),
            ] {
                assert!(close(a, b), "{form}: {a} against {b}");
            }
        }
    }

    #[test]
    fn identification_intervals_widen_the_box() {
        let text = "[motor]\nrs_ohm = 16.2\nrr_ohm = 23.2\nls_h = 1.44\nlr_h = 1.5\nlm_h = 1.42\npole_pairs = 1\n\
                    j_kgm2 = 0.005\nb_nms = 0.0005\n[identification]\nrs_ohm = [15.0, 17.0]\nj_kgm2 = [0.004, 0.011]\n";
        let iv = Intervals::parse(text).unwrap().unwrap();
        assert_eq!(iv.rs_ohm, Some([15.0, 17.0]));
        let m = drive_file::motor::parse(Path::new("m.toml"), text).unwrap();
        let t = tune(Path::new("drive.toml"), TEMPLATE, &m, Some(&iv), Structure::default()).unwrap();
        assert!((t.certify.rs_factor[0] - 15.0 / 16.2).abs() < 1e-12, "{:?}", t.certify.rs_factor);
        assert_eq!(t.certify.j_factor[1], 0.011 / 0.005);
        assert!(Intervals::parse("[identification]\nrs_ohm = [2.0, 1.0]\n").is_err());
        assert_eq!(Intervals::parse("[motor]\n").unwrap(), None);
    }
}
