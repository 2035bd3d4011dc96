//! Loop margins from a frequency response evaluated on a dense log grid, crossings refined by
//! linear interpolation in log ω.
//!
//! * Gain crossover: |L| = 1 (every crossing; the phase margin is the smallest over them).
//! * Phase crossovers: unwrapped ∠L = −180° + k·360°. At each, `|L| < 1` gives a gain
//!   **increase** margin `−20 log|L|`, `|L| > 1` a gain **reduction** margin `20 log|L|`
//!   (conditionally stable loops, like ICAD's lag-compensated channels, have both).
//! * Bandwidth: the first ω where the closed loop `|L/(1 + L)|` falls below `1/√2` of its
//!   low-frequency value.

use num_complex::Complex64;

/// Margins of one loop.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Margins {
    /// Highest gain-crossover frequency, rad/s.
    pub crossover_rad_s: Option<f64>,
    /// Smallest phase margin over all gain crossovers, degrees.
    pub phase_margin_deg: Option<f64>,
    /// Smallest gain-increase margin, dB.
    pub gain_margin_increase_db: Option<f64>,
    /// Smallest gain-reduction margin, dB.
    pub gain_margin_reduction_db: Option<f64>,
    /// Closed-loop −3 dB bandwidth, rad/s.
    pub bandwidth_rad_s: Option<f64>,
}

fn lerp_log(w0: f64, w1: f64, f0: f64, f1: f64, target: f64) -> f64 {
    let t = if f1 != f0 { (target - f0) / (f1 - f0) } else { 0.5 };
    (w0.ln() + t * (w1.ln() - w0.ln())).exp()
}

/// Unwrapped phase (degrees) of `l` over `omegas`.
pub fn unwrapped_phase_deg(l: &[Complex64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(l.len());
    let mut prev: Option<f64> = None;
    for z in l {
        let mut p = z.arg().to_degrees();
        if let Some(q) = prev {
            while p - q > 180.0 {
                p -= 360.0;
            }
            while p - q < -180.0 {
                p += 360.0;
            }
        }
        out.push(p);
        prev = Some(p);
    }
    out
}

/// Margins of the loop `l` sampled on the increasing grid `omegas`.
pub fn margins(omegas: &[f64], l: &[Complex64]) -> Margins {
    let mag_db: Vec<f64> = l.iter().map(|z| 20.0 * z.norm().log10()).collect();
    let phase = unwrapped_phase_deg(l);
    let mut m = Margins::default();
    for k in 1..omegas.len().min(l.len()) {
        let (w0, w1) = (omegas[k - 1], omegas[k]);
        // gain crossover
        if (mag_db[k - 1] >= 0.0) != (mag_db[k] >= 0.0) {
            let wc = lerp_log(w0, w1, mag_db[k - 1], mag_db[k], 0.0);
            let t = (wc.ln() - w0.ln()) / (w1.ln() - w0.ln());
            let ph = phase[k - 1] + t * (phase[k] - phase[k - 1]);
            let pm = (ph + 180.0).rem_euclid(360.0);
            let pm = if pm > 180.0 { pm - 360.0 } else { pm };
            m.crossover_rad_s = Some(m.crossover_rad_s.map_or(wc, |c: f64| c.max(wc)));
            m.phase_margin_deg = Some(m.phase_margin_deg.map_or(pm, |p: f64| p.min(pm)));
        }
        // phase crossovers at −180 + k·360
        let (p0, p1) = (phase[k - 1], phase[k]);
        let lo = p0.min(p1);
        let hi = p0.max(p1);
        let mut target = ((lo + 180.0) / 360.0).ceil() * 360.0 - 180.0;
        while target <= hi {
            if target > lo || (target == lo && p0 != p1) {
                let wp = lerp_log(w0, w1, p0, p1, target);
                let t = (wp.ln() - w0.ln()) / (w1.ln() - w0.ln());
                let g = mag_db[k - 1] + t * (mag_db[k] - mag_db[k - 1]);
                if g < 0.0 {
                    m.gain_margin_increase_db =
                        Some(m.gain_margin_increase_db.map_or(-g, |x: f64| x.min(-g)));
                } else {
                    m.gain_margin_reduction_db =
                        Some(m.gain_margin_reduction_db.map_or(g, |x: f64| x.min(g)));
                }
            }
            target += 360.0;
        }
    }
    // closed-loop bandwidth
    let t: Vec<f64> = l.iter().map(|z| (z / (Complex64::new(1.0, 0.0) + z)).norm()).collect();
    if let Some(&t0) = t.first() {
        let level = t0 / std::f64::consts::SQRT_2;
        m.bandwidth_rad_s = (1..t.len())
            .find(|&k| t[k - 1] >= level && t[k] < level)
            .map(|k| lerp_log(omegas[k - 1], omegas[k], t[k - 1], t[k], level));
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tf::{Tf, logspace};

    #[test]
    fn margins_of_a_textbook_loop() {
        // L = K/(s+1)³: phase −180° at ω = √3 where |L| = K/8.
        let k = 4.0;
        let g = Tf::new(&[k], &[1.0, 3.0, 3.0, 1.0]);
        let w = logspace(1e-3, 1e3, 20_000);
        let l: Vec<_> = w.iter().map(|&x| g.response(x)).collect();
        let m = margins(&w, &l);
        // GM = 8/K → 6.02 dB
        assert!((m.gain_margin_increase_db.unwrap() - 20.0 * 2f64.log10()).abs() < 1e-3);
        // crossover: |L| = 1 ⇔ (1 + ω²)^{3/2} = 4 ⇔ ω = √(4^{2/3} − 1)
        let wc = (4f64.powf(2.0 / 3.0) - 1.0).sqrt();
        assert!((m.crossover_rad_s.unwrap() - wc).abs() < 1e-3 * wc);
        let pm = 180.0 - 3.0 * wc.atan().to_degrees();
        assert!((m.phase_margin_deg.unwrap() - pm).abs() < 0.01);
        assert!(m.gain_margin_reduction_db.is_none());
    }

    #[test]
    fn conditionally_stable_loop_has_a_reduction_margin() {
        // L = 100(s+1)²/(s³(0.01s + 1)): the phase starts at −270° and rises above −180°
        // through the double zero, so reducing the gain destabilises: a reduction margin.
        let g = Tf::new(&[100.0, 200.0, 100.0], &[0.01, 1.0, 0.0, 0.0, 0.0]);
        let w = logspace(1e-3, 1e4, 40_000);
        let l: Vec<_> = w.iter().map(|&x| g.response(x)).collect();
        let m = margins(&w, &l);
        assert!(m.gain_margin_reduction_db.is_some(), "{m:?}");
    }

    #[test]
    fn first_order_closed_loop_bandwidth() {
        // L = a/s → T = a/(s + a): bandwidth a.
        let w = logspace(1e-2, 1e5, 20_000);
        let l: Vec<_> = w.iter().map(|&x| Complex64::new(0.0, -300.0 / x)).collect();
        assert!((margins(&w, &l).bandwidth_rad_s.unwrap() - 300.0).abs() < 0.5);
    }
}
