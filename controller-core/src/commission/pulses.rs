//! Stages 1 and 2 of the sequence (the `commission` module's docs): the offsets and the bus
//! with the bridge off, then the voltage pulses along each phase — the wiring's checks, L̂σ,
//! and the current loops designed from it.

use super::{
    BUS_RIPPLE_MAX, Commissioning, DIRECTION_COS_MIN, LOOP_BANDWIDTH_DIVIDER, OFFSET_PERIODS,
    OFFSET_SHARE_MAX, PULSE_MAX_FRACTION, PULSE_MAX_PERIODS, PULSE_START_FRACTION, PulsePhase, PulseRecord,
    REST_CURRENT_FRACTION, REST_MAX_PERIODS, Refusal, Stage, VOLTAGE_LIMIT_FRACTION,
};
use crate::drive::Measurements;
use crate::frames::{AlphaBeta, SinCos};
use crate::pi::{PiConfig, PiState};
use crate::svpwm;

impl Commissioning {
    pub(super) fn offsets(&mut self, m: &Measurements) {
        let i = [m.i_abc_a.a, m.i_abc_a.b, m.i_abc_a.c];
        for ((s, s2), x) in self.sum_a.iter_mut().zip(self.sum2_a.iter_mut()).zip(i) {
            *s += x;
            *s2 += x * x;
        }
        self.vdc_sum_v += m.vdc_v;
        self.vdc_min_v = self.vdc_min_v.min(m.vdc_v);
        self.vdc_max_v = self.vdc_max_v.max(m.vdc_v);
        self.k += 1;
        if self.k < OFFSET_PERIODS {
            return;
        }
        let n = OFFSET_PERIODS as f32;
        let r = &mut self.record;
        for (ch, (((off, noise), s), s2)) in
            r.offsets_a.iter_mut().zip(r.noise_a.iter_mut()).zip(self.sum_a).zip(self.sum2_a).enumerate()
        {
            *off = s / n;
            *noise = crate::num::sqrt_f32((s2 / n - *off * *off).max(0.0));
            if off.abs() > OFFSET_SHARE_MAX * self.cfg.spec.test_current_a {
                let offset_a = *off;
                self.refuse(Refusal::OffsetTooLarge { channel: ch as u8, offset_a });
                return;
            }
        }
        let mean = self.vdc_sum_v / n;
        self.record.vdc_v = mean;
        let spec = &self.cfg.spec;
        if !(spec.vdc_min_v..=spec.vdc_max_v).contains(&mean) {
            self.refuse(Refusal::BusOutOfRange(mean));
        } else if self.vdc_max_v - self.vdc_min_v > BUS_RIPPLE_MAX * mean {
            self.refuse(Refusal::BusUnsteady(self.vdc_max_v - self.vdc_min_v));
        } else {
            self.next(Stage::Pulse(0));
            self.v_pulse_v = PULSE_START_FRACTION * svpwm::linear_limit_v(mean);
        }
    }

    /// Unit vector of phase `p`'s axis.
    fn axis(p: u8) -> AlphaBeta {
        let sc = SinCos::new(f32::from(p) * (2.0 * core::f32::consts::PI / 3.0));
        AlphaBeta { alpha: sc.cos, beta: sc.sin }
    }

    pub(super) fn pulse(&mut self, p: u8, i: AlphaBeta, vdc_v: f32) -> Option<(AlphaBeta, f32)> {
        let u = Self::axis(p);
        let test = self.cfg.spec.test_current_a;
        match self.pulse_phase {
            PulsePhase::Rise => {
                let n = self.pulse_periods;
                if self.k == 0 {
                    self.i_start = i;
                }
                // The voltage commanded at step k acts in period k + 1: the sample at step
                // n + 1 ends the last period of the pulse, at n/2 + 1 its middle.
                if self.k == n / 2 + 1 {
                    self.i_half = i;
                }
                if self.k == n + 1 {
                    let di = i - self.i_start;
                    if di.magnitude() < 0.25 * test {
                        let limit = PULSE_MAX_FRACTION * svpwm::linear_limit_v(vdc_v);
                        if 2.0 * self.v_pulse_v <= limit {
                            self.v_pulse_v *= 2.0;
                        } else if 2 * n <= PULSE_MAX_PERIODS {
                            self.pulse_periods = 2 * n;
                        } else {
                            self.refuse(Refusal::NoCurrent);
                            return None;
                        }
                        // Let the small current decay, then a larger pulse.
                        self.pulse_phase = PulsePhase::Rest;
                        self.k = 0;
                        return Some((AlphaBeta::default(), 0.0));
                    }
                    if let Some(rec) = self.record.pulses.get_mut(usize::from(p)) {
                        *rec = PulseRecord {
                            v_pulse_v: self.v_pulse_v,
                            periods: n,
                            delta_i_half_a: self.i_half - self.i_start,
                            delta_i_a: di,
                        };
                    }
                    self.pulse_phase = PulsePhase::Reverse;
                    self.k = 1;
                    return Some((u.scale(-self.v_pulse_v), 0.0));
                }
                self.k += 1;
                let on = self.k <= n;
                Some((if on { u.scale(self.v_pulse_v) } else { AlphaBeta::default() }, 0.0))
            }
            PulsePhase::Reverse => {
                self.k += 1;
                if self.k > self.pulse_periods {
                    self.pulse_phase = PulsePhase::Rest;
                    self.k = 0;
                    return Some((AlphaBeta::default(), 0.0));
                }
                Some((u.scale(-self.v_pulse_v), 0.0))
            }
            PulsePhase::Rest => {
                self.k += 1;
                if i.magnitude() > REST_CURRENT_FRACTION * test {
                    if self.k > REST_MAX_PERIODS {
                        self.refuse(Refusal::NoDecay);
                        return None;
                    }
                    return Some((AlphaBeta::default(), 0.0));
                }
                let recorded = self.record.pulses.get(usize::from(p)).is_some_and(|r| r.v_pulse_v > 0.0);
                if !recorded {
                    // The pulse was too small: again, larger.
                    self.pulse_phase = PulsePhase::Rise;
                    self.k = 0;
                } else if p < 2 {
                    self.next(Stage::Pulse(p + 1));
                } else {
                    self.check_directions();
                }
                Some((AlphaBeta::default(), 0.0))
            }
        }
    }

    /// After the three pulses: the currents' directions, L̂σ and the current loops.
    fn check_directions(&mut self) {
        let pulses = self.record.pulses;
        let cos_to = |d: AlphaBeta, u: AlphaBeta| {
            let m = d.magnitude();
            if m > 0.0 { (d.alpha * u.alpha + d.beta * u.beta) / m } else { 0.0 }
        };
        let mut aligned = true;
        let mut mirrored = true;
        let mut reversed = true;
        let mut first_wrong = None;
        for (p, rec) in (0u8..).zip(pulses.iter()) {
            let u = Self::axis(p);
            let c = cos_to(rec.delta_i_a, u);
            let mirror = AlphaBeta { alpha: u.alpha, beta: -u.beta };
            if c < DIRECTION_COS_MIN {
                aligned = false;
                first_wrong.get_or_insert(p);
            }
            mirrored &= cos_to(rec.delta_i_a, mirror) >= DIRECTION_COS_MIN;
            reversed &= c <= -DIRECTION_COS_MIN;
        }
        if !aligned {
            let r = if reversed {
                Refusal::CurrentSign
            } else if mirrored {
                Refusal::PhaseOrder
            } else {
                Refusal::CurrentDirection { phase: first_wrong.unwrap_or(0) }
            };
            self.refuse(r);
            return;
        }
        // L̂σ = V/(di/dt) at the pulse's start, averaged over the three pulses.
        let l: f32 = pulses
            .iter()
            .map(|r| {
                let t = r.periods as f32 * self.cfg.ts_s;
                let (half, full) = (r.delta_i_half_a.magnitude(), r.delta_i_a.magnitude());
                let slope = (4.0 * half - full) / t;
                // A rise that bends more than a quadratic: the chord's slope (L̂σ too high).
                let slope = if slope > full / t { slope } else { full / t };
                r.v_pulse_v / slope
            })
            .sum::<f32>()
            / 3.0;
        let wc = 2.0 * core::f32::consts::PI * self.cfg.spec.pwm_hz / LOOP_BANDWIDTH_DIVIDER;
        let kp = wc * l;
        let limit = VOLTAGE_LIMIT_FRACTION * svpwm::linear_limit_v(self.record.vdc_v);
        let Some(loops) = PiConfig::tustin_f32(kp, kp * wc / 10.0, self.cfg.ts_s, limit) else {
            self.refuse(Refusal::NonFinite);
            return;
        };
        self.record.l_sigma_pulse_h = l;
        self.record.kp_v_per_a = kp;
        self.loops = Some(loops);
        self.pi_alpha = PiState::default();
        self.pi_beta = PiState::default();
        self.start_level(0);
    }
}
