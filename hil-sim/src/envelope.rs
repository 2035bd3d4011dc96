//! The torque–speed envelope measured in software in the loop, against the analytic one.
//!
//! At each speed a dynamometer holds the rotor ([`LoadModel::Dynamometer`]); the drive is
//! enabled, magnetizes, and is asked for far more torque than it can give
//! ([`Reference::Torque`]): it delivers what its operating point allows
//! (`controller_core::envelope`). The measured value is the machine model's electromagnetic
//! torque averaged over the last [`AVERAGE_S`] of the run. The analytic envelope is the same
//! machine's steady state under the same limits — the current-reference limit, the rated
//! flux, and the linear voltage limit V_dc/√3 of the bus — on a dense grid of slip ratios
//! (`controller_core::envelope::envelope_by_grid`, f64), independent of the drive's solver.
//! The drive aims at `voltage_margin·V_dc/√3`, so where the voltage limits it delivers about
//! `voltage_margin²` of the analytic torque (the torque at the voltage limit scales with the
//! square of the voltage).

use crate::inverter::InverterModel;
use crate::scenario::Builtin;
use crate::sensors::SensorModel;
use crate::sim::{Event, LoadModel, Scenario};
use controller_core::drive::{DriveSpec, Mode, Reference};
use controller_core::envelope::envelope_by_grid;
use controller_core::magnetics::Saturation;
use controller_core::motor::MotorParams;

/// Simulated time per speed after the drive's magnetizing time
/// ([`crate::sim::magnetizing_time_s`]), s: the slow regulators (voltage margin 10 rad/s,
/// current trim 20 rad/s) settle well within it …
pub const SETTLE_S: f64 = 1.8;
/// … and this many rotor time constants, the rotor flux's own settling in field weakening
/// (0.25 s on the shipped machine, 3.1 s on the 500 hp Krause machine) …
pub const SETTLE_ROTOR_TIME_CONSTANTS: f64 = 4.0;
/// … and at least this long, s.
pub const RUN_S: f64 = 2.0;

/// Simulated time per speed of drive `spec`, s (2 s on the shipped drive).
pub fn run_s(spec: &DriveSpec) -> f64 {
    let settle = SETTLE_S.max(SETTLE_ROTOR_TIME_CONSTANTS * spec.motor.tr_s());
    RUN_S.max(crate::sim::magnetizing_time_s(spec) + settle)
}
/// The torque is averaged over the last this long of each run, s.
pub const AVERAGE_S: f64 = 0.3;

/// The runs' rows: every this many PWM periods.
const TRACE_EVERY: u32 = 10;
/// The torque asked for at a point, as a multiple of its analytic envelope: beyond it (the
/// drive limits it). A fixed 1 kN·m was below the 500 hp Krause machine's 2.8 kN·m, which
/// then measured 65 % short of its envelope.
pub const TORQUE_ASKED_FACTOR: f64 = 2.0;

/// The no-load base speed, mechanical rad/s: the speed at which the rated flux with no load
/// needs the whole linear voltage V_dc/√3 — `|v| = i_d·√(R_s² + (p·ω·L_s)²)` with
/// `i_d = ψ_r*/L_m` (the dq model at zero slip). Above it the drive weakens the field.
pub fn base_speed_rad_s(motor: &MotorParams, flux_ref_wb: f64, vdc_v: f64) -> f64 {
    let i_d = flux_ref_wb / motor.lm_h();
    let v = vdc_v / 3f64.sqrt();
    let x2 = (v / i_d).powi(2) - motor.rs_ohm().powi(2);
    if x2 <= 0.0 { 0.0 } else { x2.sqrt() / (motor.ls_h() * f64::from(motor.pole_pairs())) }
}

/// [`base_speed_rad_s`] of drive `spec` on a bus of `vdc_v`: on the part of the bus its
/// modulator uses ([`DriveSpec::duty_max`]: the low-side sampling window's cost).
pub fn drive_base_speed_rad_s(spec: &DriveSpec, vdc_v: f64) -> f64 {
    base_speed_rad_s(&spec.motor, spec.flux_ref_wb, spec.duty_max() * vdc_v)
}

/// The d-axis current of the rated flux on `plant`, within the current limit, A.
pub(crate) fn rated_d_current_a(spec: &DriveSpec, plant: &MotorParams) -> f64 {
    (spec.flux_ref_wb / plant.lm_h()).min(spec.i_ref_max_a)
}

/// One point of the envelope.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Speed held by the dynamometer, mechanical rad/s.
    pub omega_m_rad_s: f64,
    /// Mean electromagnetic torque of the machine model at the end of the run, N·m.
    pub measured_nm: f64,
    /// Peak-to-peak torque over the averaging window, N·m.
    pub ripple_nm: f64,
    /// The share of the averaging window's periods whose current sample lacked one phase
    /// (`[0]`: rebuilt from the other two, overmodulating) and two or more (`[1]`)
    /// ([`crate::sim::Row::unsampled_periods`]).
    pub unsampled_share: [f64; 2],
    /// The analytic envelope at this speed, N·m.
    pub analytic_nm: f64,
    /// The motor's physical limit at this speed ([`physical_limit_nm`]), N·m.
    pub physical_nm: f64,
    /// Mean rotor flux magnitude of the machine model over the window, Wb.
    pub flux_wb: f64,
    /// The torque asked for, N·m (magnitude).
    pub asked_nm: f64,
    /// Mean of the drive's rotor-flux reference over the window, Wb.
    pub flux_ref_wb: f64,
    /// The drive's mode at the end (Running unless something tripped).
    pub mode: Mode,
}

impl Point {
    /// Measured against analytic, relative (negative: below the envelope).
    pub fn relative_error(&self) -> f64 {
        (self.measured_nm - self.analytic_nm) / self.analytic_nm
    }

    /// Measured against the torque asked for, relative (the torque accuracy).
    pub fn torque_error(&self) -> f64 {
        (self.measured_nm - self.asked_nm) / self.asked_nm
    }

    /// The machine's rotor flux against the drive's reference, relative (the flux accuracy).
    pub fn flux_error(&self) -> f64 {
        (self.flux_wb - self.flux_ref_wb) / self.flux_ref_wb
    }
}

/// What a point asks of the drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Ask {
    /// More than it can give ([`TORQUE_ASKED_FACTOR`] × the analytic envelope): the envelope.
    Beyond,
    /// This fraction of the analytic envelope on the drive's own voltage target
    /// (`voltage_margin` of the linear limit at `duty_max`, what the drive can deliver): the
    /// torque and flux accuracy.
    Fraction(f64),
}

/// Measure the envelope of drive `spec` on plant `plant` at bus `vdc_v` at each of `speeds`
/// (mechanical rad/s), motoring (`sign` = 1) or generating (−1), in parallel on the
/// machine's cores.
pub fn measure(
    spec: &DriveSpec,
    plant: &MotorParams,
    vdc_v: f64,
    speeds: &[f64],
    sign: f32,
) -> Result<Vec<Point>, String> {
    measure_on(spec, plant, None, vdc_v, speeds, sign)
}

/// [`measure`] on a plant whose magnetizing branch may saturate (`saturation`; `plant` its
/// form's T model): the runs simulate the curve, the physical limit follows it
/// ([`physical_limit_saturated_nm`]), and the analytic envelope — a linear model's — is the
/// drive's own motor's.
pub fn measure_on(
    spec: &DriveSpec,
    plant: &MotorParams,
    saturation: Option<&Saturation>,
    vdc_v: f64,
    speeds: &[f64],
    sign: f32,
) -> Result<Vec<Point>, String> {
    measure_asking(spec, plant, saturation, vdc_v, speeds, sign, Ask::Beyond)
}

/// [`measure_on`], each point asking `ask` of the drive.
pub fn measure_asking(
    spec: &DriveSpec,
    plant: &MotorParams,
    saturation: Option<&Saturation>,
    vdc_v: f64,
    speeds: &[f64],
    sign: f32,
    ask: Ask,
) -> Result<Vec<Point>, String> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(speeds.len().max(1));
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut results: Vec<Option<Result<Point, String>>> = vec![None; speeds.len()];
    std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(&w) = speeds.get(i) else { break };
                        done.push((i, point(spec, plant, saturation, vdc_v, w, sign, ask)));
                    }
                    done
                })
            })
            .collect();
        for worker in workers {
            for (i, r) in worker.join().unwrap_or_default() {
                if let Some(slot) = results.get_mut(i) {
                    *slot = Some(r);
                }
            }
        }
    });
    results.into_iter().map(|r| r.unwrap_or_else(|| Err("a worker thread panicked".into()))).collect()
}

fn point(
    spec: &DriveSpec,
    plant: &MotorParams,
    saturation: Option<&Saturation>,
    vdc_v: f64,
    w: f64,
    sign: f32,
    ask: Ask,
) -> Result<Point, String> {
    let run_s = run_s(spec);
    let model = if saturation.is_some() { &spec.motor } else { plant };
    let (analytic, _, _) = envelope_by_grid(
        model,
        f64::from(sign) * w,
        rated_d_current_a(spec, model),
        spec.duty_max() * vdc_v / 3f64.sqrt(),
        spec.i_ref_max_a,
        20_000,
    );
    let asked = match ask {
        Ask::Beyond => TORQUE_ASKED_FACTOR * analytic,
        Ask::Fraction(f) => {
            let v_target = spec.voltage_margin * spec.duty_max() * vdc_v / 3f64.sqrt();
            let (within, _, _) = envelope_by_grid(
                model,
                f64::from(sign) * w,
                rated_d_current_a(spec, model),
                v_target,
                spec.i_ref_max_a,
                20_000,
            );
            f * within
        }
    };
    let asked_nm = asked as f32;
    let b = Builtin {
        name: format!("envelope-{w}"),
        about: String::new(),
        spec: *spec,
        plant: *plant,
        plant_saturation: saturation.copied(),
        expect_fault: None,
        scenario: Scenario {
            events: vec![(0.0, Event::Enable), (0.0, Event::Reference(Reference::Torque(sign * asked_nm)))],
            duration_s: run_s,
            vdc_v,
            substeps: 1,
            trace_every: TRACE_EVERY,
            sensors: SensorModel::default(),
            load: LoadModel::Dynamometer { omega_m_rad_s: w },
            inverter: InverterModel::Average,
            dc_link: None,
            comparator: None,
            heating: None,
            extras: plant::Extras::default(),
        },
    };
    let (rows, mode) = b.run(|_| {})?;
    let window: Vec<_> = rows.iter().filter(|r| r.t_s >= run_s - AVERAGE_S).collect();
    let n = window.len().max(1) as f64;
    let mean = window.iter().map(|r| r.torque_nm).sum::<f64>() / n;
    let (lo, hi) = window
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| (lo.min(r.torque_nm), hi.max(r.torque_nm)));
    let flux = window.iter().map(|r| r.x.psi_alpha_wb.hypot(r.x.psi_beta_wb)).sum::<f64>() / n;
    let flux_ref = window.iter().map(|r| r.psi_ref_wb).sum::<f64>() / n;
    let periods = n * f64::from(TRACE_EVERY);
    let unsampled =
        |k: usize| window.iter().map(|r| f64::from(r.unsampled_periods[k])).sum::<f64>() / periods;
    Ok(Point {
        unsampled_share: [unsampled(0), unsampled(1)],
        asked_nm: asked,
        flux_ref_wb: flux_ref,
        omega_m_rad_s: w,
        measured_nm: mean.abs(),
        ripple_nm: hi - lo,
        analytic_nm: analytic,
        physical_nm: physical_limit_of(plant, saturation, w, f64::from(sign), spec, vdc_v),
        flux_wb: flux,
        mode,
    })
}

/// The limits a motor's physical envelope is taken under ([`physical_limit_nm`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// The rotor flux's magnitude at most, Wb (the drive's `flux_ref_wb`).
    pub flux_max_wb: f64,
    /// The phase voltage's peak at most, V (V_dc/√3: the whole linear circle).
    pub v_max_v: f64,
    /// The stator current's peak at most, A (the drive's `i_ref_max_a`).
    pub i_max_a: f64,
}

impl Limits {
    /// Drive `spec`'s flux and current limits on the whole linear voltage of a `vdc_v` bus.
    pub fn of(spec: &DriveSpec, vdc_v: f64) -> Self {
        Self { flux_max_wb: spec.flux_ref_wb, v_max_v: vdc_v / 3f64.sqrt(), i_max_a: spec.i_ref_max_a }
    }
}

/// Slip frequencies [`physical_limit_nm`] tries, geometric over [`PHYSICAL_SLIP_RANGE`] of
/// the rotor's R_r/L_r: 8.4 % apart, before the golden sections refine the best. Torque
/// against slip is smooth but for the kinks where one limit takes over from another, and
/// its peaks span decades: 200 points find what 8 000 find to 1e-9 (test
/// `a_coarser_slip_grid_finds_the_same_limit`; 12 do not). The campaign computes the limit
/// at every step plan's torque nodes, 44 times a run: at 4 000 points it took ≈ 40 % of a
/// drive.toml campaign's time (`perf record` of `hil-sim campaign drive.toml --runs 1000
/// --duration 1`).
pub const PHYSICAL_SLIP_POINTS: u32 = 200;
/// The slip frequencies searched, in units of R_r/L_r (1 is a current-fed machine's
/// breakdown; a voltage-limited one's lies below it at speed, a leakage-limited one's
/// above).
pub const PHYSICAL_SLIP_RANGE: [f64; 2] = [1e-4, 1e3];

/// The most torque the motor can give at mechanical speed `omega_m_rad_s` in the direction
/// `sign` (+1 motoring at a positive speed, −1 braking), N·m — its **physical limit**, from
/// the motor alone: the T-equivalent circuit at steady state (no drive, no model of one),
/// within [`Limits`]. In the synchronous frame at slip frequency ω_sl, per ampere of
/// stator current along the real axis: the rotor's `0 = R_r·I_r + jω_sl·ψ_r` with `ψ_r = L_m·I + L_r·I_r` gives
/// `ψ_r = L_m·R_r/(R_r + jω_sl·L_r)`, `I_r = −jω_sl·L_m/(R_r + jω_sl·L_r)`; the stator's
/// `ψ_s = L_s + L_m·I_r`, `V = R_s + jω_e·ψ_s` (ω_e = p·ω_m + ω_sl) and
/// `T = −(3/2)·p·Im ψ_s` per A². Each limit bounds the current at that slip — `i =
/// min(I, V/|V₁|, Ψ/|ψ_r₁|)`, everything scaling with it — and the limit is the largest
/// `T₁·i²` over [`PHYSICAL_SLIP_POINTS`] slips, refined by golden sections around the best
/// (`best_over_slips`). Unlike the drive's own envelope it caps no flux (the drive's, motoring at its
/// no-load value, generating at what a reversal holds): what the drive leaves unused shows against
/// it (issue 52).
pub fn physical_limit_nm(m: &MotorParams, omega_m_rad_s: f64, sign: f64, lim: &Limits) -> f64 {
    physical_limit_on_grid(m, omega_m_rad_s, sign, lim, PHYSICAL_SLIP_POINTS)
}

/// [`physical_limit_nm`] on a grid of `points` slips.
fn physical_limit_on_grid(m: &MotorParams, omega_m_rad_s: f64, sign: f64, lim: &Limits, points: u32) -> f64 {
    use num_complex::Complex64 as C;
    let Limits { flux_max_wb, v_max_v, i_max_a } = *lim;
    let (rs, rr, ls, lr, lm) = (m.rs_ohm(), m.rr_ohm(), m.ls_h(), m.lr_h(), m.lm_h());
    let p = f64::from(m.pole_pairs());
    let torque_at = |w_sl: f64| {
        let den = C::new(rr, w_sl * lr);
        let psi_r = C::new(lm * rr, 0.0) / den;
        let i_r = C::new(0.0, -w_sl * lm) / den;
        let psi_s = C::new(ls, 0.0) + i_r * lm;
        let v = C::new(rs, 0.0) + C::new(0.0, p * omega_m_rad_s + w_sl) * psi_s;
        let t1 = -1.5 * p * psi_s.im;
        let i = i_max_a.min(v_max_v / v.norm()).min(flux_max_wb / psi_r.norm());
        t1 * i * i
    };
    best_over_slips(rr / lr, sign, points, torque_at)
}

/// The largest `sign·torque_at(ω_sl)` over slip frequencies of the sign `sign`: a geometric
/// grid of `points` ([`PHYSICAL_SLIP_POINTS`]) over [`PHYSICAL_SLIP_RANGE`] × `unit` (the
/// rotor's R_r/L_r), then 40 golden sections between the best point's neighbours; never
/// below 0.
fn best_over_slips(unit: f64, sign: f64, points: u32, torque_at: impl Fn(f64) -> f64) -> f64 {
    let [lo, hi] = PHYSICAL_SLIP_RANGE;
    let at = |k: f64| sign * unit * lo * (hi / lo).powf(k / f64::from(points));
    let (mut best_k, mut best) = (0.0, f64::NEG_INFINITY);
    for k in 0..=points {
        let t = sign * torque_at(at(f64::from(k)));
        if t > best {
            (best_k, best) = (f64::from(k), t);
        }
    }
    let (mut a, mut b) = (best_k - 1.0, best_k + 1.0);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..40 {
        let (c, d) = (b - g * (b - a), a + g * (b - a));
        if sign * torque_at(at(c)) > sign * torque_at(at(d)) {
            b = d;
        } else {
            a = c;
        }
    }
    best.max(sign * torque_at(at(0.5 * (a + b)))).max(0.0)
}

/// [`physical_limit_nm`] of a machine whose magnetizing branch saturates (`m` its form's T
/// model, `sat` the branch: `plant::saturated`'s equations at steady state). Nothing scales
/// with the current any more, so each slip's operating point is parametrised by the
/// branch's flux r (real in the synchronous frame), from which everything is explicit —
/// Γ: `ψ_r = r/(1 + jω_sl·L_ℓ/R_r)`, `i_r = (ψ_r − r)/L_ℓ`, `i_s = f(r) − i_r`,
/// `v = R_s·i_s + jω_e·r`, `T = (3/2)·p·r·Im i_s`; inverse-Γ: `i_R = −jω_sl·r/R_R`,
/// `i_s = f(r) − i_R`, `ψ_s = r + L_σ·i_s`, `v = R_s·i_s + jω_e·ψ_s`,
/// `T = (3/2)·p·Im(conj ψ_s·i_s)`, ψ_r = r. The current, voltage and rotor flux rise
/// with r: the largest r within the limits is found by bisection (60 halvings), its torque
/// taken, the best over the same slips refined as in [`physical_limit_nm`].
pub fn physical_limit_saturated_nm(
    m: &MotorParams,
    sat: &Saturation,
    omega_m_rad_s: f64,
    sign: f64,
    lim: &Limits,
) -> f64 {
    use controller_core::magnetics::Form;
    use num_complex::Complex64 as C;
    let Limits { flux_max_wb, v_max_v, i_max_a } = *lim;
    let p = f64::from(m.pole_pairs());
    let (rs, rr) = (m.rs_ohm(), m.rr_ohm());
    let curve = sat.curve;
    // (|i_s|, |v|, |ψ_r|, T) at branch flux r and slip w_sl.
    let point = |r: f64, w_sl: f64| {
        let w_e = p * omega_m_rad_s + w_sl;
        let i_m = C::new(curve.current_a(r), 0.0);
        match sat.form {
            Form::Gamma => {
                let l = m.lr_h() - m.lm_h();
                let psi_r = C::new(r, 0.0) / C::new(1.0, w_sl * l / rr);
                let i_r = (psi_r - r) / l;
                let i_s = i_m - i_r;
                let v = i_s * rs + C::new(0.0, w_e * r);
                (i_s.norm(), v.norm(), psi_r.norm(), 1.5 * p * r * i_s.im)
            }
            Form::InverseGamma => {
                let l = m.ls_h() - m.lm_h();
                let i_r = C::new(0.0, -w_sl * r / rr);
                let i_s = i_m - i_r;
                let psi_s = i_s * l + r;
                let v = i_s * rs + C::new(0.0, w_e) * psi_s;
                (i_s.norm(), v.norm(), r, 1.5 * p * (psi_s.conj() * i_s).im)
            }
        }
    };
    let torque_at = |w_sl: f64| {
        let fits = |r: f64| {
            let (i, v, psi_r, _) = point(r, w_sl);
            i <= i_max_a && v <= v_max_v && psi_r <= flux_max_wb
        };
        // The flux where the current alone reaches the limit bounds the search from above.
        let (mut lo, mut hi) = (0.0, curve.flux_at_total_current(i_max_a, 0.0) * 1.01);
        if fits(hi) {
            lo = hi;
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if fits(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        point(lo, w_sl).3
    };
    best_over_slips(rr / m.lr_h(), sign, PHYSICAL_SLIP_POINTS, torque_at)
}

/// The physical limit of the plant (linear or saturating) at speed `w` under drive `spec`'s
/// flux and current limits and the whole linear voltage of the bus.
fn physical_limit_of(
    plant: &MotorParams,
    saturation: Option<&Saturation>,
    w: f64,
    sign: f64,
    spec: &DriveSpec,
    vdc_v: f64,
) -> f64 {
    let lim = Limits::of(spec, vdc_v);
    match saturation {
        Some(s) => physical_limit_saturated_nm(plant, s, w, sign, &lim),
        None => physical_limit_nm(plant, w, sign, &lim),
    }
}

/// The envelope plot: the analytic curve on a fine grid of speeds and the measured points.
pub fn plot(
    spec: &DriveSpec,
    plant: &MotorParams,
    saturation: Option<&Saturation>,
    vdc_v: f64,
    points: &[Point],
    sign: f32,
) -> String {
    use report::plot::{Series, line_plot};
    let top = points.iter().map(|p| p.omega_m_rad_s).fold(0.0, f64::max);
    let model = if saturation.is_some() { &spec.motor } else { plant };
    let i_d_rated = rated_d_current_a(spec, model);
    let curve: Vec<(f64, f64)> = (0..=200)
        .map(|k| {
            let w = top * f64::from(k) / 200.0;
            let v = spec.duty_max() * vdc_v / 3f64.sqrt();
            let (t, _, _) =
                envelope_by_grid(model, f64::from(sign) * w, i_d_rated, v, spec.i_ref_max_a, 4000);
            (w, t)
        })
        .collect();
    let physical: Vec<(f64, f64)> = (0..=200)
        .map(|k| {
            let w = top * f64::from(k) / 200.0;
            (w, physical_limit_of(plant, saturation, w, f64::from(sign), spec, vdc_v))
        })
        .collect();
    let measured: Vec<(f64, f64)> = points.iter().map(|p| (p.omega_m_rad_s, p.measured_nm)).collect();
    let title = format!(
        "Torque–speed envelope ({}, {vdc_v} V bus)",
        if sign < 0.0 { "generating" } else { "motoring" }
    );
    line_plot(
        &title,
        "ω_m (rad/s)",
        &[
            Series::line("analytic: current- and voltage-limited steady state (N·m)", curve),
            Series::line(
                "physical limit: the motor alone, |v| ≤ V_dc/√3, ψ_r ≤ ψ_r*, |i| ≤ I_max (N·m)",
                physical,
            ),
            Series::markers("measured in SIL (N·m)", measured),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lim(flux_max_wb: f64, v_max_v: f64, i_max_a: f64) -> Limits {
        Limits { flux_max_wb, v_max_v, i_max_a }
    }

    /// [`PHYSICAL_SLIP_POINTS`]' grid finds the limit a grid 40× as fine finds, to 1e-9, on
    /// every shipped drive file's motor (drive.toml's and `drives/`: 24 V to 3 300 V buses)
    /// at corners of drive.toml's box (R_s ×1.5, R_r ×2, L ×0.6: the breakdown slip moves
    /// with R_r/L_r and the leakage), on the file's flux, current limit and rated bus, from
    /// standstill to twice its base speed, motoring and braking.
    #[test]
    fn a_coarser_slip_grid_finds_the_same_limit() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut files = vec![root.join("drive.toml")];
        for entry in std::fs::read_dir(root.join("drives")).unwrap() {
            files.push(entry.unwrap().path());
        }
        let (mut checked, mut worst) = (0, 0f64);
        for path in &files {
            let file = drive_file::DriveFile::load(path).unwrap();
            let spec = file.spec;
            let vdc = crate::commands::default_bus_v(&file);
            let l = Limits::of(&spec, vdc);
            for (rs, rr, ls) in [(1.0, 1.0, 1.0), (1.5, 2.0, 0.6), (1.0, 2.0, 1.0), (1.5, 1.0, 0.6)] {
                let m = spec.motor.scaled(rs, rr, ls, 1.0).unwrap();
                let base = base_speed_rad_s(&m, spec.flux_ref_wb, vdc);
                for k in 0..=20 {
                    let w = 0.1 * f64::from(k) * base;
                    for sign in [1.0, -1.0] {
                        let coarse = physical_limit_nm(&m, w, sign, &l);
                        let fine = physical_limit_on_grid(&m, w, sign, &l, 40 * PHYSICAL_SLIP_POINTS);
                        let e = (coarse / fine - 1.0).abs();
                        assert!(e < 1e-9, "{}: {w} rad/s, sign {sign}: {coarse} vs {fine}", path.display());
                        (worst, checked) = (worst.max(e), checked + 1);
                    }
                }
            }
        }
        eprintln!("{checked} limits, worst relative difference {worst:.2e}");
        assert!(checked >= 4 * 4 * 21 * 2, "{checked}");
    }

    /// The physical limit against two references it shares no code with. At standstill,
    /// current- and flux-limited (the bus far away): in the rotor-flux frame ψ_r = L_m·i_d,
    /// so T = (3/2)·p·(L_m/L_r)·Ψ·√(I² − (Ψ/L_m)²) — 5.0474 N·m for the shipped drive, to
    /// 1e-6. Motoring at 1.5 and 2× base speed, where the drive's no-load flux cap does not
    /// bind (motoring never needs more flux than no load: controller-core's envelope docs):
    /// the dq model's dense-grid envelope (`envelope_by_grid`) on the same full circle, to
    /// 1e-3 (its grid's resolution). Generating there too, since the braking flux is the
    /// most a reversal holds within the current limit — the rated flux on this motor (the
    /// no-load cap it replaced left the physical limit 1.2× above the envelope: issue 52).
    #[test]
    fn the_physical_limit_meets_its_closed_form_and_the_dq_envelope() {
        let spec = drive_file::DriveFile::shipped().unwrap().spec;
        let m = spec.motor;
        let (psi, i) = (spec.flux_ref_wb, spec.i_ref_max_a);
        let id = psi / m.lm_h();
        let closed = 1.5 * f64::from(m.pole_pairs()) * m.lm_h() / m.lr_h() * psi * (i * i - id * id).sqrt();
        for sign in [1.0, -1.0] {
            let t = physical_limit_nm(&m, 0.0, sign, &lim(psi, 1e6, i));
            assert!((t / closed - 1.0).abs() < 1e-6, "{t} vs {closed}");
        }
        let v = 310.0 / 3f64.sqrt();
        let base = base_speed_rad_s(&m, psi, 310.0);
        for k in [1.5, 2.0] {
            let w = k * base;
            let (dq, _, _) = envelope_by_grid(&m, w, id, v, i, 200_000);
            let t = physical_limit_nm(&m, w, 1.0, &lim(psi, v, i));
            assert!((t / dq - 1.0).abs() < 1e-3, "{k}× base: {t} vs {dq}");
            let (dq_gen, _, _) = envelope_by_grid(&m, -w, id, v, i, 200_000);
            let t_gen = physical_limit_nm(&m, w, -1.0, &lim(psi, v, i));
            eprintln!("{k}× base generating: physical {t_gen:.4} N·m, dq envelope {dq_gen:.4} N·m");
            assert!((dq_gen / t_gen - 1.0).abs() < 1e-3, "{k}× base generating: {t_gen} vs {dq_gen}");
        }
    }

    /// The saturated physical limit with a straight-line curve is the linear one (in both
    /// forms, the T model's L_m on the line), to 1e-6; on the shipped saturating motor
    /// (`delorenzo-saturating`, its rated point where the appendix motor's is) it departs
    /// from the appendix motor's as the curve says: at standstill 2.8 % below (4.905 against
    /// 5.047 N·m: under full current the Γ branch's flux, the stator's, exceeds the rotor's
    /// 0.9 Wb by L_ℓ·i_r and saturates further, so less of the current is left for torque),
    /// above it at 2× base speed, where the branch, below its knee, magnetizes with less
    /// current.
    #[test]
    fn the_saturated_physical_limit_reduces_to_the_linear_one() {
        use controller_core::magnetics::{Form, MagnetizingCurve, Saturation};
        let inv = MotorParams::new(3.7, 2.1, 0.245, 0.224, 0.224, 2, 0.015, 0.0).unwrap();
        let gamma = MotorParams::new(3.7, 2.5, 0.34, 0.363, 0.34, 2, 0.015, 0.0).unwrap();
        for (m, form) in [(gamma, Form::Gamma), (inv, Form::InverseGamma)] {
            let line: [f64; 2] = [1.0, 5.0];
            let curve = MagnetizingCurve::points(&line, &line.map(|x| x / m.lm_h())).unwrap();
            let sat = Saturation { form, curve };
            for (w, sign) in [(0.0, 1.0), (100.0, 1.0), (200.0, -1.0), (300.0, 1.0)] {
                let lin = physical_limit_nm(&m, w, sign, &lim(1.0, 326.6, 7.0));
                let s = physical_limit_saturated_nm(&m, &sat, w, sign, &lim(1.0, 326.6, 7.0));
                assert!((s / lin - 1.0).abs() < 1e-6, "{form:?} {w} {sign}: {s} vs {lin}");
            }
        }
        let spec = drive_file::DriveFile::shipped().unwrap().spec;
        let (m_sat, sat) = drive_file::motor::load_model("delorenzo-saturating").unwrap();
        let sat = sat.unwrap();
        let (psi, i, v) = (spec.flux_ref_wb, spec.i_ref_max_a, 310.0 / 3f64.sqrt());
        let at_rest = physical_limit_saturated_nm(&m_sat, &sat, 0.0, 1.0, &lim(psi, v, i));
        let ratio = at_rest / physical_limit_nm(&spec.motor, 0.0, 1.0, &lim(psi, v, i));
        assert!((0.96..0.99).contains(&ratio), "{at_rest}: {ratio}");
        let top = physical_limit_saturated_nm(&m_sat, &sat, 368.0, 1.0, &lim(psi, v, i));
        assert!(top > physical_limit_nm(&spec.motor, 368.0, 1.0, &lim(psi, v, i)), "{top}");
    }
}
