//! What each row of the matrix asks ([`Matrix::expect`]): the fault's name and bound from
//! the detection bounds, or the stated gap and why — the encoder's rows from what
//! its readings can tell ([`Matrix::encoder_reach`]).

use super::*;

impl Matrix {
    /// What the drive's jump check can make of an encoder fault at `at`
    /// (`controller_core::drive` `EncoderTrack::read`; `None` for a case that is not one).
    /// A counter that stops changes each read's increment by `c = |ω|·T`, one that loses
    /// lines by `c·(1 − lines/set)`. With the fault falling `g` of the way through a read
    /// interval from its end (the matrix's injection against the simulator's reads, every
    /// slow divider's period from the first), the second difference of the readings at a
    /// spacing of `n` reads reaches `max(n − 1 + g, n − g)·c` — `n·c` when the fault falls on
    /// a read — against the level's quantisation share plus `n²` times the mechanics'
    /// allowance ([`controller_core::drive::ENCODER_ACCEL_FACTOR`] × the drive's peak
    /// acceleration, over a read squared); the readings' own quantisation moves it by less
    /// than two counts (half the quantisation share, `drive_file::drive::ENCODER_JUMP_COUNTS`)
    /// either way.
    pub fn encoder_reach(&self, case: &Case, at: &OperatingPoint) -> Option<EncoderReach> {
        let spec = &self.spec;
        let pwm_s = 1.0 / spec.pwm_frequency_hz;
        let divider = u64::from(spec.slow_divider.max(1));
        let t_s = divider as f64 * pwm_s;
        let per_read = at.speed_rad_s.abs() * t_s;
        let c = match case.injection {
            Injection::EncoderStuck => per_read,
            Injection::EncoderLines { lines } => {
                per_read * (1.0 - f64::from(lines) / f64::from(self.encoder_lines.max(1))).abs()
            }
            _ => return None,
        };
        let [counts, accel] = controller_core::drive::encoder_jump_shares(spec);
        let quantisation = 0.5 * counts;
        // The periods of the read interval the injection leaves faulty: all of the next one
        // when it falls on a read.
        let r = crate::sim::first_period_at(self.inject_s(), pwm_s) % divider;
        let g = if r == 0 { 1.0 } else { (divider - r) as f64 / divider as f64 };
        let reach = |sign: f64| {
            (1..=controller_core::drive::JUMP_SPACING_MAX).find(|&n| {
                let n_f = n as f64;
                (n_f - 1.0 + g).max(n_f - g) * c + sign * quantisation > counts + n_f * n_f * accel
            })
        };
        Some(match (reach(-1.0), reach(1.0)) {
            (Some(n), _) => EncoderReach::Seen(n),
            (None, Some(n)) => EncoderReach::Unsure(n),
            (None, None) => EncoderReach::Unseen,
        })
    }

    /// An overload of `load_nm` at `at`: its detection bound, s.
    ///
    /// The following-error check counts once the speed law is at its limit: the issue's
    /// bound, or — a law slower than that to reach its limit under the overload
    /// ([`Matrix::overload_reach_s`]) — from there the time the check needs: with the
    /// load k·τ_max against the limit τ_max the speed is dragged at a = (k − 1)·τ_max/J
    /// while it owes f·τ_max/J (f = `FOLLOWING_PROGRESS_FRACTION`), and the drag beyond
    /// what it owes so far plus a whole window's owing, f·τ_max·T_f/J, trips at once:
    /// f·T_f/(k − 1 − f) after the limit (a quarter of the window at k = 1.5), or the
    /// window T_f if sooner. A rotor the drag brings through rest on the way pauses the
    /// check within the stall check's "not moving" band, ±s: 2s/a more (member 178's
    /// at mid-speed, motoring, crossed zero as the check would have spoken). Plus the
    /// speed estimate's window (the drag shows in it that much later) and a slow
    /// period.
    pub fn overload_bound_s(&self, at: &OperatingPoint, load_nm: f64) -> f64 {
        let slow_s = f64::from(self.spec.slow_divider) / self.spec.pwm_frequency_hz;
        let tau_nm = crate::campaign::torque_limit_nm(&self.spec);
        let f = controller_core::supervisor::motion::FOLLOWING_PROGRESS_FRACTION;
        let k = load_nm.abs() / tau_nm;
        let window_s = self.spec.protection.following_time_s;
        let check_s = if k - 1.0 - f > 0.0 { (f * window_s / (k - 1.0 - f)).min(window_s) } else { window_s };
        let drag = (k - 1.0).max(0.0) * tau_nm / self.spec.motor.j_kgm2();
        let band =
            controller_core::supervisor::motion::STALL_SPEED_FRACTION * self.spec.protection.overspeed_rad_s;
        let estimate_s = controller_core::encoder::SPEED_WINDOW_READS as f64 * slow_s;
        match self.overload_reach_s(at, load_nm) {
            Some((reach_s, omega)) => {
                // The speed's distance from rest, counted along the drag (the load
                // pulls it towards its own sign's opposite: positive, down).
                let towards = omega * load_nm.signum();
                let through_rest = omega.abs() <= band || (towards > 0.0 && towards - drag * check_s <= band);
                let pause_s = if through_rest && drag > 0.0 { 2.0 * band / drag } else { 0.0 };
                STALL_BOUND_S.max(reach_s + check_s + pause_s + estimate_s + slow_s)
            }
            None => STALL_BOUND_S,
        }
    }

    /// What the issue asks of `case` at `at`, or the stated gap.
    pub fn expect(&self, case: &Case, at: &OperatingPoint) -> Expect {
        let slow_s = f64::from(self.spec.slow_divider) / self.spec.pwm_frequency_hz;
        // A wider spacing sees a smaller change, the reads it spans later (one more for a
        // fault that falls between two reads).
        let reach = self.encoder_reach(case, at);
        let spacing = match reach {
            Some(EncoderReach::Seen(n) | EncoderReach::Unsure(n)) => n as f64 + 1.0,
            _ => 0.0,
        };
        let encoder_s = ENCODER_BOUND_SLOW_PERIODS.max(spacing) * slow_s;
        let pwm_s = 1.0 / self.spec.pwm_frequency_hz;
        let rest = at.point == Point::Standstill;
        match case.injection {
            // At rest the current vector stands still, wherever the position hold left it:
            // along the open phase's axis it asks the other two phases equal currents, which
            // the open lead holds at zero between them — the motor carries no current at all,
            // which `NoMotorCurrent` names (a 270 W 34 V member: the vector within a few degrees
            // of phase a; further off, b and c carry a current clear of the noise: `OpenPhase`).
            // Telling it from three open leads would take a probe current the plan does not
            // ask for; the bridge goes off either way.
            Injection::OpenPhase { .. } if rest => Expect::Either {
                faults: &[Fault::OpenPhase, Fault::NoMotorCurrent],
                bound_s: OPEN_PHASE_BOUND_S,
            },
            Injection::OpenPhase { .. } => {
                Expect::Fault { fault: Fault::OpenPhase, bound_s: OPEN_PHASE_BOUND_S }
            }
            // The comparator breaks the bridge within its filter time, inside the period
            // (the drive learns it at its next interrupt), or — a short whose current stays
            // below the comparator's level within the period — the software's overcurrent
            // check at the next sample: one period either way.
            Injection::PhaseShort(_) | Injection::SwitchShort(_) if self.comparator.is_some() => {
                Expect::Either { faults: &[Fault::HardwareBreak, Fault::Overcurrent], bound_s: pwm_s }
            }
            Injection::PhaseShort(_) => Expect::Fault { fault: Fault::Overcurrent, bound_s: pwm_s },
            // Without the comparator the loop's current flows only while the partner
            // conducts; the low-side shunt carries it at the sample (around the top of the
            // count) only when the upper switch is the shorted one: the software's
            // overcurrent at the next sample, one period — a shorted lower switch's current
            // has died through the diodes by then and nothing but the comparator sees it.
            Injection::SwitchShort(s) if s.upper => {
                Expect::Fault { fault: Fault::Overcurrent, bound_s: pwm_s }
            }
            Injection::SwitchShort(_) => Expect::Gap {
                fault: Fault::Overcurrent,
                bound_s: pwm_s,
                why: "without the board's comparator a shorted lower switch's shoot-through flows only while \
                      the high side conducts, between the samples: only the comparator can see it",
                may_close: false,
            },
            // A switch stuck open does nothing until its direction of current is needed: the
            // bound runs from the first peak of its dead direction after the injection
            // ([`dead_peak_after_s`]: the run measures the field's angle and turn,
            // `Matrix::run_one`), or from the first period it mattered
            // ([`Outcome::acting_after_s`]) if later, at most the observation later.
            // The phase then cannot follow one way: `SwitchOpen` once the other way has carried
            // since (`drive::SWITCH_MISSING_SHARE`); before that (or when the reference hardly
            // reverses) the phase carries none of its current, which is `OpenPhase`; a dead
            // lower switch leaves its low-side shunt without current exactly then, which the
            // current-sum check sees first. At rest, as for an open lead: with the vector at
            // the dead direction's peak the other two phases are asked for (r_b − r_c)/2
            // between them, which the dead phase holds at zero — one direction lost at angle θ
            // from its peak leaves them √3·|i|·|sin θ| against Σ|i_ref| ≈ 2|i|, under
            // `OPEN_PHASE_ABSENT_FRACTION` of it within 6.6°, which a field turning at the slip
            // frequency holds for the two windows `NoMotorCurrent` needs (the population's
            // 7.4 kW member 184 at 7.9 kHz, phase a's reference at its positive peak:
            // 20 A asked, ≈ 1 A carried by b and c, `NoMotorCurrent` after 9.0 ms).
            Injection::SwitchOpen { .. } if rest => Expect::Either {
                faults: &[Fault::SwitchOpen, Fault::OpenPhase, Fault::CurrentSensor, Fault::NoMotorCurrent],
                bound_s: OPEN_PHASE_BOUND_S,
            },
            Injection::SwitchOpen { .. } => Expect::Either {
                faults: &[Fault::SwitchOpen, Fault::OpenPhase, Fault::CurrentSensor],
                bound_s: OPEN_PHASE_BOUND_S,
            },
            // A wiring error made at installation, not a failure in service: commissioning
            // refuses it (`hil_sim::identify`); not among the matrix's cases.
            Injection::CurrentChannelsSwapped { .. } => Expect::Gap {
                fault: Fault::CurrentSensor,
                bound_s: SENSOR_BOUND_S,
                why: "swapped current channels are an installation error, refused by commissioning",
                may_close: false,
            },
            Injection::EncoderReversed => Expect::Gap {
                fault: Fault::EncoderImplausible,
                bound_s: encoder_s,
                why: "a reversed encoder is an installation error, refused by commissioning",
                may_close: false,
            },
            Injection::EncoderStuck if rest => Expect::Gap {
                fault: Fault::EncoderLoss,
                bound_s: encoder_s,
                why: "at rest a stuck counter reads what a healthy one reads; the load then turns the rotor \
                      unseen (needs a speed observer from the electrical quantities)",
                may_close: false,
            },
            Injection::EncoderLines { .. } if rest => Expect::Gap {
                fault: Fault::EncoderLoss,
                bound_s: encoder_s,
                why: "at rest a wrong line count changes no reading",
                may_close: false,
            },
            // Slower, the change is one the mechanics allow: a seizure slowing the rotor that
            // hard reads the same — only the electrical quantities could tell them apart.
            Injection::EncoderStuck | Injection::EncoderLines { .. }
                if matches!(reach, Some(EncoderReach::Unseen | EncoderReach::Unsure(_))) =>
            {
                Expect::Gap {
                    fault: Fault::EncoderLoss,
                    bound_s: encoder_s,
                    why: "at this speed a counter that stops or loses lines changes the readings no more than \
                          a seizure of ten times the drive's torque slowing the rotor would (the jump check's \
                          allowance, Matrix::encoder_reach) — or only by the readings' quantisation: telling \
                          them apart needs a speed observer from the electrical quantities",
                    may_close: matches!(reach, Some(EncoderReach::Unsure(_))),
                }
            }
            // The observer beside the encoder carries the drive on (issue 53: ride-through) —
            // at speed: standstill is a position hold, which needs the shaft's angle, and the
            // fault trips there as without the observer.
            Injection::EncoderStuck | Injection::EncoderGlitch { .. } | Injection::EncoderLines { .. }
                if self.spec.speed_feedback == SpeedFeedback::EncoderRideThrough && !rest =>
            {
                Expect::Reported {
                    faults: &[Fault::EncoderLoss, Fault::EncoderImplausible],
                    bound_s: encoder_s,
                }
            }
            Injection::EncoderStuck | Injection::EncoderGlitch { .. } | Injection::EncoderLines { .. } => {
                Expect::Fault { fault: Fault::EncoderLoss, bound_s: encoder_s }
            }
            Injection::CurrentSensor { .. } => {
                Expect::Fault { fault: Fault::CurrentSensor, bound_s: SENSOR_BOUND_S }
            }
            Injection::BusVoltage { vdc_v } => Expect::Fault {
                fault: if vdc_v < self.spec.protection.vdc_min_v {
                    Fault::DcBusUndervoltage
                } else {
                    Fault::DcBusOvervoltage
                },
                bound_s: pwm_s,
            },
            Injection::Plant { .. } => Expect::RideThrough,
            // At rest under a position hold, a seized load changes nothing the drive commands.
            // A load the drive cannot hold drags the rotor away from its reference: named by
            // the following-error check, or by overspeed if the rotor crosses that first.
            // The following-error check counts once the speed law is at its limit
            // ([`Matrix::overload_bound_s`]).
            Injection::LoadStep { torque_nm } => Expect::Either {
                faults: &[Fault::FollowingError, Fault::Overspeed],
                bound_s: self.overload_bound_s(at, self.overload_nm(torque_nm, at)),
            },
            Injection::LoadSeizure { .. } if rest => Expect::RideThrough,
            // At speed, a seizure first decelerates the rotor against the drive's full torque:
            // until it stops, that is a load beyond the drive dragging the speed against the
            // torque — the following-error check's — and once stopped, a stall. The following
            // window derived from the mechanics (issue 49) names the first on a light rotor.
            Injection::LoadSeizure { .. } => {
                Expect::Either { faults: &[Fault::Stall, Fault::FollowingError], bound_s: STALL_BOUND_S }
            }
        }
    }
}
