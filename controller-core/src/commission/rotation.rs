//! Stage 5 of the sequence (the `commission` module's docs): the slow rotating field, which
//! hands over to the no-load test at its hold's end.

use super::{
    Commissioning, LEVELS, ROTATION_BLOCKS, ROTATION_HOLD_S, ROTATION_HZ, ROTATION_RAMP_S, ROTATION_STOP_S,
    Stage,
};
use crate::drive::Measurements;
use crate::frames::{AlphaBeta, SinCos};

impl Commissioning {
    /// Stage 5: the slow rotating field (see the module docs).
    pub(super) fn rotate(&mut self, i: AlphaBeta, m: &Measurements) -> Option<(AlphaBeta, f32)> {
        let pwm = self.cfg.spec.pwm_hz;
        let (ramp, hold, stop) =
            ((ROTATION_RAMP_S * pwm) as u32, (ROTATION_HOLD_S * pwm) as u32, (ROTATION_STOP_S * pwm) as u32);
        let w_max = 2.0 * core::f32::consts::PI * ROTATION_HZ;
        let k = self.k;
        let w = if k < ramp {
            w_max * k as f32 / ramp as f32
        } else if k < ramp + hold {
            w_max
        } else {
            (w_max * (1.0 - (k - ramp - hold) as f32 / stop as f32)).max(0.0)
        };
        let amplitude = LEVELS[0] * self.cfg.spec.test_current_a;
        let sc = SinCos::new(self.theta_e_rad);
        let i_ref = AlphaBeta { alpha: amplitude * sc.cos, beta: amplitude * sc.sin };
        let v = self.regulate_ab(i_ref, i, m.vdc_v)?;
        let step_rad = w * self.cfg.ts_s;
        self.theta_e_rad = crate::frames::wrap_angle(self.theta_e_rad + step_rad);
        if k == 0 {
            self.theta_m_prev_rad = m.theta_m_rad;
        }
        let d_theta_m = crate::frames::wrap_angle(m.theta_m_rad - self.theta_m_prev_rad);
        self.theta_m_prev_rad = m.theta_m_rad;
        let per_block = (ramp + hold) / ROTATION_BLOCKS as u32;
        let r = &mut self.record.rotation;
        r.amplitude_a = amplitude;
        r.periods_per_block = per_block;
        // The turning so far (exact in f32 to a count for tens of revolutions).
        self.block_v += d_theta_m;
        if self.block < ROTATION_BLOCKS {
            self.block_n += 1;
            if self.block_n >= per_block {
                if let Some(b) = r.theta_m_rad.get_mut(self.block) {
                    *b = self.block_v;
                }
                self.block += 1;
                self.block_n = 0;
            }
        }
        self.k += 1;
        // At the hold's end, the no-load test takes over the turning field (if it can).
        if self.k == ramp + hold && self.start_no_load(m.vdc_v) {
            self.next(Stage::NoLoad);
        } else if self.k >= ramp + hold + stop {
            self.stage = Stage::Done;
        }
        Some((v, i_ref.alpha))
    }
}
