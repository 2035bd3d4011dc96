//! The load a campaign run steps to ([`overhauling_load_nm`]).

/// Bisection steps of [`overhauling_load_nm`]: the load to 2^-30 of its no-dip value.
const OVERHAULING_BISECTION_STEPS: u32 = 30;

/// The load a run applies at speed `omega_m_rad_s` against a drive pushing in direction
/// `torque_sign`, N·m, of `held(ω, sign)` — [`super::LOAD_FRACTION`] of what the plant
/// holds at ω. Motoring (the drive pushes with the speed), the load slows the rotor towards
/// speeds where the plant holds more: `held` at the speed it loads. Braking an overhauling
/// load, the rotor runs ahead by up to the deviation the requirements allow after a load
/// step, `dip_allowed(load)` (the stated one, or the least the board's speed loop makes: no
/// loop on the board holds it closer), and above base speed the plant holds less the faster
/// it turns: the largest load of at most `held` there that the plant still holds
/// [`super::LOAD_FRACTION`] of wherever that deviation may take it (a bisection: the load a
/// speed holds falls, the deviation grows, with the load). Found on the population: the
/// 1.3 kW 8-pole member at 20 kHz braking 0.8 × its top speed's torque ran ahead by the
/// least dip to where its envelope held 0.95 of the load, and on to a `FollowingError` — a
/// load no drive on its board can hold, not a test of the drive.
pub(super) fn overhauling_load_nm(
    omega_m_rad_s: f64,
    torque_sign: f64,
    held: &impl Fn(f64, f64) -> f64,
    dip_allowed_rad_s: impl Fn(f64) -> f64,
) -> f64 {
    let here = held(omega_m_rad_s, torque_sign);
    if torque_sign * omega_m_rad_s >= 0.0 {
        return here;
    }
    let ahead = |l: f64| omega_m_rad_s + omega_m_rad_s.signum() * dip_allowed_rad_s(l);
    // `l` (a fraction of `here`) is held where it may run to.
    let holds = |f: f64| {
        let l = f * here;
        held(ahead(l), torque_sign).abs() >= l.abs()
    };
    if holds(1.0) {
        return here;
    }
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..OVERHAULING_BISECTION_STEPS {
        let mid = 0.5 * (lo + hi);
        if holds(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo * here
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::LOAD_FRACTION;

    /// An overhauling load is the largest the plant still holds [`LOAD_FRACTION`] of
    /// wherever the deviation it is allowed takes the rotor: on a plant holding 10 N·m to
    /// 100 rad/s and 1 000/ω above, with 2 rad/s of deviation allowed per N·m, braking at
    /// 100 rad/s the load `l` solves `l = 0.8·1 000/(100 + 2·l)` (7.016 N·m, not 8);
    /// motoring, or where the deviation stays below base speed, it is 0.8 of the torque there.
    #[test]
    fn an_overhauling_load_is_held_where_its_deviation_takes_the_rotor() {
        let torque = |w: f64| if w.abs() <= 100.0 { 10.0 } else { 1_000.0 / w.abs() };
        let held = |w: f64, sign: f64| LOAD_FRACTION * sign * torque(w);
        let dip = |l: f64| 2.0 * l.abs();
        let exact = (-100.0 + (100.0f64.powi(2) + 8.0 * 800.0).sqrt()) / 4.0;
        let braking = overhauling_load_nm(100.0, -1.0, &held, dip);
        assert!((braking + exact).abs() < 1e-6, "{braking} against {}", -exact);
        let mirrored = overhauling_load_nm(-100.0, 1.0, &held, dip);
        assert!((mirrored - exact).abs() < 1e-6, "{mirrored}");
        assert_eq!(overhauling_load_nm(100.0, 1.0, &held, dip), 8.0);
        assert_eq!(overhauling_load_nm(50.0, -1.0, &held, dip), -8.0);
    }
}
