//! When the drive itself has arrived at its operating points.
//!
//! The matrix's injection time is worked out from the speed law on an ideal torque actuator
//! ([`Matrix::approach`]) and [`SETTLE_EXTRA_S`](super::SETTLE_EXTRA_S) for the drive's current and flux loops. A
//! drive whose torque lags the ideal one's by more — a large rotor in field weakening,
//! whose flux falls towards its reference with T_r ≈ 0.7–0.8 s and holds the torque under
//! the envelope's while it does (at the ideal wait the population's 65 kW member 161 was at
//! 663 of its 679 rad/s top speed, the 114 kW member 199 at 248 of 283) — would take its
//! faults before it is at the point the row names. So the matrix also runs the drive healthy at
//! each point it moves to and waits for it: the row then judges the fault at the point,
//! while a drive that does not arrive (or trips on its way) keeps the ideal wait and its
//! rows fail with the reason ("the operating point was not reached").

use super::{Matrix, OBSERVE_S, OperatingPoint, Point, REACHED_TOLERANCE_RAD_S, Row};
use controller_core::drive::Mode;
use rayon::prelude::*;

/// The drive has arrived once it stays within this fraction of [`REACHED_TOLERANCE_RAD_S`]
/// of the point's [`super::Approach`] speed: the rest of the tolerance is left to the rows'
/// own sensor draws, which move their runs from the healthy one.
pub const ARRIVAL_BAND_FRACTION: f64 = 0.5;

/// The healthy runs last this multiple of the ideal wait (from the reference to the ideal
/// injection), plus [`OBSERVE_S`]: a drive twice as slow as the speed law on an ideal
/// actuator (with its [`SETTLE_EXTRA_S`](super::SETTLE_EXTRA_S)) is one whose rows fail as not reached, and an
/// arrival counts only if it holds for an observation's length before the run ends.
pub const ARRIVAL_HORIZON: f64 = 2.0;

impl Matrix {
    /// When the drive, run healthy, has arrived at every point it reaches within the
    /// horizon ([`ARRIVAL_HORIZON`]), s (0 with no such point): measured once.
    pub(super) fn arrival_s(&self) -> f64 {
        *self.arrival_s.get_or_init(|| {
            let (reference_s, ideal_s) = self.times_s;
            let horizon_s = reference_s + ARRIVAL_HORIZON * (ideal_s - reference_s) + OBSERVE_S;
            self.approaches
                .par_iter()
                .filter(|(at, _)| at.point != Point::Standstill)
                .filter_map(|(at, a)| {
                    self.healthy_arrival_s(at, a.as_ref().ok()?.final_rad_s, ideal_s, horizon_s)
                })
                .reduce(|| 0.0, f64::max)
        })
    }

    /// The last time the drive, run healthy at `at`, was farther than the arrival band from
    /// `final_rad_s` or not running, s — the run stopped once it has stayed within the band
    /// for [`OBSERVE_S`] and the ideal wait `ideal_s` has passed (nothing later moves the
    /// injection), at `horizon_s` at the latest; `None` if it had not stayed so by then (it
    /// has not arrived), or the run failed.
    fn healthy_arrival_s(
        &self,
        at: &OperatingPoint,
        final_rad_s: f64,
        ideal_s: f64,
        horizon_s: f64,
    ) -> Option<f64> {
        const ARRIVED: &str = "arrived";
        let run = self.point_run(0, format!("healthy at {}", at.name()), at, None, horizon_s);
        let band = ARRIVAL_BAND_FRACTION * REACHED_TOLERANCE_RAD_S;
        let mut away_s = 0.0;
        let end = run.run_into(
            |_| {},
            |r: &Row| {
                let running = r.mode.is_none_or(|m| m == Mode::Running);
                if !running || (r.x.omega_m_rad_s - final_rad_s).abs() > band {
                    away_s = r.t_s;
                } else if r.t_s >= ideal_s && r.t_s - away_s >= OBSERVE_S {
                    return Err(ARRIVED.into());
                }
                Ok(())
            },
        );
        match end {
            Err(e) if e == ARRIVED => Some(away_s),
            Ok(_) => (away_s + OBSERVE_S <= horizon_s).then_some(away_s),
            Err(_) => None,
        }
    }
}
