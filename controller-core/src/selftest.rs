//! Control-law checks that run anywhere: on the host (unit test below), on an emulated
//! Cortex-M4F and Cortex-M3 (`qemu-target/tests/selftest.rs`, defmt-test), and on a board as a
//! commissioning self-test. Each check measures one quantity and compares it with a limit
//! justified in its doc comment; none allocates.
//!
//! They are deliberately the same checks as some of the host unit tests of the modules,
//! restated without `std`, so that the *target's* arithmetic (FPU or soft-float f32,
//! soft-float f64, `libm`) is what gets measured.

use crate::current::{CurrentAxisState, CurrentControllerConfig, CurrentLaw};
use crate::discretize::{Complex, Discretization};
use crate::drive::{Drive, DriveConfig, DriveSpec, Fault, Measurements, Mode, PhaseCommand};
use crate::frames::{Abc, AlphaBeta, SinCos};
use crate::link::{self, Command, FrameDecoder, LinkStats, MAX_FRAME, Reply};
use crate::num::{Q32, Scalar};
use crate::pi::{PiConfig, PiState};
use crate::svpwm;

/// Result of one check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Check {
    /// Name.
    pub name: &'static str,
    /// Measured value (the check's worst case).
    pub measured: f64,
    /// Pass when `measured <= limit`.
    pub limit: f64,
}

impl Check {
    /// Within the limit (NaN fails).
    pub fn passed(&self) -> bool {
        self.measured <= self.limit
    }
}

/// Every check, in order; the drive checks run `spec` (the caller's configuration — on a
/// target, the one generated from its drive file). `quick` shortens the long time-domain
/// runs (for the soft-float Cortex-M3, ≈ 20× slower per f32 operation), keeping their limits.
pub fn all(spec: &DriveSpec, quick: bool) -> [Check; 10] {
    [
        icad_time_domain_response(quick),
        icad_lag_dc_gain(),
        pi_windup_recovery(),
        svpwm_stays_in_hexagon(),
        sincos_accuracy(),
        drive_magnetizing_time(spec),
        supervisor_trips_in_one_step(spec),
        link_rejects_corruption(spec),
        q32_icad_vs_f64(),
        f32_icad_vs_f64(),
    ]
}

/// Least-squares fit of `y ≈ a·sin ωt + b·cos ωt + c` over the samples pushed.
#[derive(Clone, Copy, Debug, Default)]
struct SineFit {
    m: [[f64; 3]; 3],
    v: [f64; 3],
}

impl SineFit {
    fn push(&mut self, basis: [f64; 3], y: f64) {
        for (mi, (vi, bi)) in self.m.iter_mut().zip(self.v.iter_mut().zip(basis)) {
            *vi += bi * y;
            for (mij, bj) in mi.iter_mut().zip(basis) {
                *mij += bi * bj;
            }
        }
    }

    /// `a + j·b` by Cramer's rule.
    fn phasor(&self) -> Complex {
        let det3 = |m: &[[f64; 3]; 3]| {
            let [[a, b, c], [d, e, f], [g, h, i]] = *m;
            a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
        };
        let with_col = |col: usize| {
            let mut mc = self.m;
            for (row, vi) in mc.iter_mut().zip(self.v) {
                if let Some(x) = row.get_mut(col) {
                    *x = vi;
                }
            }
            det3(&mc) / det3(&self.m)
        };
        Complex::new(with_col(0), with_col(1))
    }
}

/// ICAD eq. (20) as implemented (f32, Tustin, 20 kHz) driven by unit sines at 300, 1000 and
/// 3000 rad/s: worst relative error of the fitted response against the continuous k(jω).
/// Limit 0.3 %: the Tustin frequency warping alone gives 0.10 % over 1–3000 rad/s at
/// 20 kHz (`current` tests), and the fit over whole periods adds < 0.1 %.
pub fn icad_time_domain_response(quick: bool) -> Check {
    let ts = 1.0 / 20_000.0;
    let mut worst = f64::NAN;
    if let Ok(c) =
        CurrentControllerConfig::<f32>::new(&CurrentLaw::ICAD_EQ20, ts, Discretization::Tustin, 1e9)
    {
        worst = 0.0;
        // The lag poles decay with 20 ms: 2 s (quick: 0.3 s, e^-15) settles them.
        let (n_settle, n_fit) = if quick { (6_000usize, 4_000usize) } else { (40_000, 20_000) };
        for w in [300.0f64, 1000.0, 3000.0] {
            let mut s = CurrentAxisState::default();
            let mut fit = SineFit::default();
            for k in 0..(n_settle + n_fit) {
                let (sin, cos) = libm::sincos(w * k as f64 * ts);
                let y = f64::from(c.update_axis(&mut s, sin as f32, 1e9));
                if k >= n_settle {
                    fit.push([sin, cos, 1.0], y);
                }
            }
            let expected = CurrentLaw::ICAD_EQ20.response(w);
            worst = worst.max((fit.phasor() - expected).norm() / expected.norm());
        }
    }
    Check { name: "ICAD eq. (20) sine response vs k(jw), rel. error", measured: worst, limit: 3e-3 }
}

/// The ICAD lag section (s+400)²/(s²+100s+42500) in δ-form: relative error of the step
/// response's final value against the DC gain 160000/42500. Limit 1e-5: the δ-form keeps
/// the DC gain to 8e-9 in f32 (`filter` tests); 1e-5 leaves room for the 1 s of f32
/// accumulation (20 000 steps of ~6e-8 relative rounding that the loop attenuates).
pub fn icad_lag_dc_gain() -> Check {
    let ts = 1.0 / 20_000.0;
    let mut measured = f64::NAN;
    if let Ok(c) =
        CurrentControllerConfig::<f32>::new(&CurrentLaw::ICAD_EQ20, ts, Discretization::Tustin, 1e9)
        && let Some(lag) = c.lag()
    {
        let mut s = Default::default();
        let mut y = 0.0f32;
        // Settles with 20 ms: 1 s is e^-50.
        for _ in 0..20_000 {
            y = lag.update(&mut s, 1.0f32);
        }
        let dc = 160_000.0 / 42_500.0;
        measured = (f64::from(y) - dc).abs() / dc;
    }
    Check { name: "ICAD lag DC gain, rel. error", measured, limit: 1e-5 }
}

/// PI with conditional integration on the loop 10/s (20(s+10)/s², ζ = 0.71): overshoot
/// after a step of 10 that saturates the output for ≈ 1 s, as a fraction of the bound
/// OS_lin·r (the overshoot of the same step without saturation). Limit 1: never worse than
/// the linear loop (host measurement ≈ 0.05; an unprotected integrator gives > 3).
pub fn pi_windup_recovery() -> Check {
    let ts = 1.0 / 20_000.0;
    let peak = |c: &PiConfig<f32>, r: f32| {
        let (mut y, mut peak, mut s) = (0.0f32, 0.0f32, PiState::default());
        for _ in 0..30_000 {
            let u = c.update(&mut s, r - y);
            y += 10.0 * u * ts as f32;
            peak = peak.max(y);
        }
        peak
    };
    let measured = match PiConfig::<f32>::new(2.0, 20.0, ts, Discretization::Tustin, -1.0, 1.0) {
        Ok(c) => {
            let os_lin = f64::from(peak(&c, 0.01)) / 0.01 - 1.0;
            let os = f64::from(peak(&c, 10.0)) - 10.0;
            os / (os_lin * 10.0)
        }
        Err(_) => f64::NAN,
    };
    Check { name: "PI anti-windup overshoot / linear bound", measured, limit: 1.0 }
}

/// SVPWM over a polar grid of requests up to twice the hexagon: worst violation of
/// duty ∈ [0, 1], of |v_applied| ≤ hexagon radius along the request, and of the angle of
/// the applied vector (rad). Limit 1e-5 (f32 rounding of quantities of order 1).
pub fn svpwm_stays_in_hexagon() -> Check {
    let vdc = 310.0f32;
    let mut worst = 0.0f64;
    for i in 0..360 {
        let th = i as f32 * (core::f32::consts::TAU / 360.0);
        let sc = SinCos::new(th);
        for r in 1..=40 {
            let mag = r as f32 * (vdc / 30.0);
            let v = AlphaBeta { alpha: mag * sc.cos, beta: mag * sc.sin };
            let m = svpwm::modulate(v, vdc);
            for d in [m.duty.a, m.duty.b, m.duty.c] {
                worst = worst.max(f64::from((-d).max(d - 1.0)));
            }
            // Applied = request scaled by k ∈ (0, 1]: cross product ~ 0, dot product ≥ 0.
            let cross = v.alpha * m.v_applied.beta - v.beta * m.v_applied.alpha;
            let angle =
                f64::from(cross) / (f64::from(v.magnitude()) * f64::from(m.v_applied.magnitude()).max(1e-9));
            worst = worst.max(angle.abs());
            let line = m.v_applied.inverse_clarke();
            // Phase-to-phase voltage can't exceed Vdc.
            for d in [line.a - line.b, line.b - line.c, line.c - line.a] {
                worst = worst.max(f64::from((d.abs() - vdc) / vdc));
            }
        }
    }
    Check { name: "SVPWM duty/hexagon/angle violation", measured: worst, limit: 1e-5 }
}

/// `SinCos` (f32 libm) on 100 001 angles in [−π, π] against f64: worst absolute error.
/// Limit 2e-7: sinf/cosf are faithfully rounded (≤ 1 ulp ≤ 6e-8 near 1) plus the f32
/// rounding of the angle itself (≤ 1.2e-7 at π).
pub fn sincos_accuracy() -> Check {
    let mut worst = 0.0f64;
    for i in 0..=100_000 {
        let th = -core::f32::consts::PI + i as f32 * (core::f32::consts::TAU / 100_000.0);
        let sc = SinCos::new(th);
        let (s, c) = libm::sincos(f64::from(th));
        worst = worst.max((f64::from(sc.sin) - s).abs()).max((f64::from(sc.cos) - c).abs());
    }
    Check { name: "SinCos abs. error vs f64", measured: worst, limit: 2e-7 }
}

/// The drive `spec` with ideal current tracking (measured = reference of the previous
/// step): the time from `enable` to Running against the IFOC flux model's
/// `T_r·ln(1/(1 − fraction))`, relative error — T_r of the rotor resistance the drive runs on
/// (its range's middle: ideal tracking leaves the magnetizing fit no decaying voltage to
/// read, `controller_core::mras`). The discrete flux model's time constant is exact to
/// ≪ 1e-4, but it runs at the slow step, which also decides the transition: the time has
/// the resolution of one slow period, and the references of the fast steps before the first
/// slow step — up to `slow_divider − 1` of them: the slow cadence runs on through an enable,
/// in step with the encoder's reads — are zero (the drive plans them there). Limit:
/// `2·slow_divider + 1` samples over the expected count (7.7e-3 of the ≈ 2 740 samples of
/// the shipped drive, where it measures 4.3e-3; 4.6e-3 of the ≈ 4 600 at R_r as the motor
/// file states it).
pub fn drive_magnetizing_time(spec: &DriveSpec) -> Check {
    let Ok(cfg) = DriveConfig::new(spec) else {
        return Check { name: "magnetizing", measured: f64::NAN, limit: 0.0 };
    };
    let mut drive = Drive::new(cfg);
    let _ = drive.enable();
    let mut i_ab = AlphaBeta::default();
    let mut steps = 0u32;
    while drive.mode() == Mode::Magnetizing && steps < 200_000 {
        let m = Measurements { i_abc_a: i_ab.inverse_clarke(), vdc_v: 310.0, ..Default::default() };
        drive.step(&m);
        i_ab = drive.telemetry().i_ref_ab_a;
        steps += 1;
    }
    let t = f64::from(steps) / spec.pwm_frequency_hz;
    let tr_s = spec.motor.tr_s() / f64::from(drive.ifoc_state().rotor_resistance_scale());
    let expected = tr_s * libm::log(1.0 / (1.0 - spec.magnetized_fraction));
    let measured =
        if drive.mode() == Mode::Running { (t - expected).abs() / expected } else { f64::INFINITY };
    let limit = (2.0 * f64::from(spec.slow_divider) + 1.0) / (expected * spec.pwm_frequency_hz);
    Check { name: "time to Running vs Tr*ln(1/(1-f)), rel. error", measured, limit }
}

/// A NaN measurement, then (after clearing) a current beyond `i_trip_a`: each must latch its
/// fault and turn the phases off in the same step. Measured: number of failures (limit 0).
pub fn supervisor_trips_in_one_step(spec: &DriveSpec) -> Check {
    let mut failures = 0.0;
    let Ok(cfg) = DriveConfig::new(spec) else {
        return Check { name: "supervisor", measured: f64::NAN, limit: 0.0 };
    };
    let mut drive = Drive::new(cfg);
    let ok = Measurements { vdc_v: 310.0, ..Default::default() };
    let cases = [
        (Measurements { vdc_v: f32::NAN, ..ok }, Fault::NonFiniteInput),
        (Measurements { i_abc_a: Abc { a: 1e3, b: -5e2, c: -5e2 }, ..ok }, Fault::Overcurrent),
        (Measurements { vdc_v: 1e4, ..ok }, Fault::DcBusOvervoltage),
    ];
    for (bad, fault) in cases {
        drive.clear_fault();
        let _ = drive.enable();
        let _ = drive.step(&ok);
        let out = drive.step(&bad);
        if out.mode != Mode::Fault(fault) || out.phases != PhaseCommand::Off {
            failures += 1.0;
        }
    }
    Check { name: "supervisor trip failures", measured: failures, limit: 0.0 }
}

/// Link frames through the target's decoder: a configure frame and a corrupted copy of it
/// (each single-bit flip of the body). Measured: mis-handled frames — a good frame lost or
/// a corrupted one accepted (limit 0).
pub fn link_rejects_corruption(spec: &DriveSpec) -> Check {
    let mut bad = 0.0;
    let mut frame = [0u8; MAX_FRAME];
    let n = link::command_frame(&Command::Configure(*spec), &mut frame).unwrap_or(0);
    let body = frame.get(..n).unwrap_or(&[]);
    let mut decoder = FrameDecoder::new();
    let mut stats = LinkStats::default();
    let mut feed = |bytes: &mut dyn Iterator<Item = u8>, stats: &mut LinkStats| -> u32 {
        let mut accepted = 0;
        for b in bytes {
            match decoder.push(b) {
                Some(Ok(p)) => match Command::decode(p) {
                    Ok(_) => accepted += 1,
                    Err(e) => stats.count_decode(e),
                },
                Some(Err(e)) => stats.count_frame(e),
                None => {}
            }
        }
        accepted
    };
    if feed(&mut body.iter().copied(), &mut stats) != 1 {
        bad += 1.0;
    }
    for i in 0..n.saturating_sub(1) {
        for bit in 0..8u8 {
            let mut it = body.iter().enumerate().map(|(j, &b)| if j == i { b ^ (1 << bit) } else { b });
            // A flip may create a delimiter, splitting the frame: nothing may be accepted.
            if feed(&mut it, &mut stats) != 0 {
                bad += 1.0;
            }
            // Resynchronise for the next case (an unfinished frame is dropped).
            feed(&mut core::iter::once(0), &mut stats);
        }
    }
    // Round trip of a reply.
    let r = Reply::Status {
        mode: Mode::Running,
        ridden_through: crate::fault::FaultSet::EMPTY,
        frames_ok: 3,
        frame_errors: 4,
        timing: link::LoopTiming::default(),
        readings: link::BoardReadings {
            i_abc_counts: [2048, 2047, 2049],
            vdc_counts: 3100,
            encoder_counts: 9,
        },
    };
    let mut p = [0u8; MAX_FRAME];
    if !matches!(r.encode(&mut p).map(|k| Reply::decode(p.get(..k).unwrap_or(&[]))), Ok(Ok(x)) if x == r) {
        bad += 1.0;
    }
    Check { name: "link frames mis-handled", measured: bad, limit: 0.0 }
}

/// The ICAD axis in `T` against f64 on 0.5 s of a decaying 2 A error at 300 rad/s plus a
/// 1 mA step (output up to ≈ 150 V): worst |T − f64| in volts.
fn icad_vs_f64<T: Scalar + Default>() -> f64 {
    let ts = 1.0 / 20_000.0;
    let law = CurrentLaw::ICAD_EQ20;
    let (Ok(ct), Ok(cd)) = (
        CurrentControllerConfig::<T>::new(&law, ts, Discretization::Tustin, 200.0),
        CurrentControllerConfig::<f64>::new(&law, ts, Discretization::Tustin, 200.0),
    ) else {
        return f64::NAN;
    };
    let (mut st, mut sd) = (CurrentAxisState::default(), CurrentAxisState::default());
    let mut worst = 0.0f64;
    for k in 0..10_000 {
        let t = k as f64 * ts;
        let e = 2.0 * libm::sin(300.0 * t) * libm::exp(-20.0 * t) + if k > 5_000 { 0.001 } else { 0.0 };
        let yt = ct.update_axis(&mut st, T::from_f64(e), T::from_f64(200.0)).to_f64();
        let yd = cd.update_axis(&mut sd, e, 200.0);
        worst = worst.max((yt - yd).abs());
    }
    worst
}

/// The fixed-point (`Q32`) ICAD controller's trajectory against f64 (0.5 s of a decaying
/// 2 A error at 300 rad/s plus a 1 mA step; worst difference in volts). Limit 5e-3 V (3e-5 of full scale; host measurement 1.7e-3 V).
pub fn q32_icad_vs_f64() -> Check {
    Check { name: "Q32 ICAD trajectory vs f64, V", measured: icad_vs_f64::<Q32>(), limit: 5e-3 }
}

/// The f32 ICAD controller's trajectory against f64 on the same input, for comparison with
/// [`q32_icad_vs_f64`]: the 1 mA step ramps the integrator by ≈ 0.016 V per sample up to
/// ≈ 80 V, where one f32 ulp is 7.6e-6 V, so 5000 roundings of the increment drift by up to
/// ≈ 0.04 V (host measurement 4.1e-2 V — Q32, with 32 fractional bits, is 24× closer).
/// Limit 0.1 V.
pub fn f32_icad_vs_f64() -> Check {
    Check { name: "f32 ICAD trajectory vs f64, V", measured: icad_vs_f64::<f32>(), limit: 0.1 }
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_check_passes_on_the_host() {
        let spec = crate::drive::test_spec();
        for c in super::all(&spec, false).iter().chain(super::all(&spec, true).iter().take(1)) {
            std::eprintln!("{:<50} {:.3e} (limit {:.1e})", c.name, c.measured, c.limit);
            assert!(c.passed(), "{c:?}");
        }
    }
}
