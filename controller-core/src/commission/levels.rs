//! Stages 3 and 4 of the sequence (the `commission` module's docs): the three DC levels on
//! the α axis, recorded in blocks, and the two sinusoidal injections' lock-in sums — both
//! on the current loops.

use super::{
    Commissioning, INJECTION_CYCLES, INJECTION_FRACTION, INJECTION_PERIODS, INJECTION_SETTLE_CYCLES,
    LAG_PERIODS, LEVELS, Stage,
};
use crate::frames::{AlphaBeta, SinCos};

impl Commissioning {
    pub(super) fn start_level(&mut self, l: u8) {
        self.next(Stage::Level(l));
        self.block = 0;
        self.block_v = 0.0;
        self.block_i = 0.0;
        self.block_n = 0;
        let i_ref = LEVELS.get(usize::from(l)).copied().unwrap_or(0.0) * self.cfg.spec.test_current_a;
        if let Some(rec) = self.record.levels.get_mut(usize::from(l)) {
            rec.i_ref_a = i_ref;
        }
    }

    pub(super) fn level(&mut self, l: u8, i: AlphaBeta, vdc_v: f32) -> Option<(AlphaBeta, f32)> {
        let idx = usize::from(l);
        let i_ref = self.record.levels.get(idx).map_or(0.0, |r| r.i_ref_a);
        let v = self.regulate(i_ref, i, vdc_v)?;
        let ends = self.cfg.block_end;
        let k = self.k;
        let rec = self.record.levels.get_mut(idx)?;
        if k < LAG_PERIODS {
            rec.lag_a_periods += i_ref - i.alpha;
        }
        self.block_v += v.alpha;
        self.block_i += i.alpha;
        self.block_n += 1;
        self.k += 1;
        if ends.get(self.block).is_some_and(|&e| self.k >= e) {
            let n = self.block_n.max(1) as f32;
            if let (Some(bv), Some(bi)) =
                (rec.v_alpha_v.get_mut(self.block), rec.i_alpha_a.get_mut(self.block))
            {
                *bv = self.block_v / n;
                *bi = self.block_i / n;
            }
            self.block += 1;
            (self.block_v, self.block_i, self.block_n) = (0.0, 0.0, 0);
        }
        if self.k >= self.cfg.level_periods {
            self.i_ref_prev_a = i_ref;
            if l + 1 < LEVELS.len() as u8 {
                self.start_level(l + 1);
            } else {
                self.next(Stage::Injection(0));
                if let Some(rec) = self.record.injections.get_mut(0) {
                    rec.periods_per_cycle = INJECTION_PERIODS[0];
                }
            }
        }
        Some((v, i_ref))
    }

    pub(super) fn injection(&mut self, j: u8, i: AlphaBeta, vdc_v: f32) -> Option<(AlphaBeta, f32)> {
        let idx = usize::from(j);
        let n = INJECTION_PERIODS.get(idx).copied().unwrap_or(1);
        let bias = self.i_ref_prev_a;
        // The level's settled voltage: the last block of the last level.
        let v_bias = self.record.levels.last().and_then(|r| r.v_alpha_v.last()).copied().unwrap_or(0.0);
        let phase = (self.k % n) as f32 * (2.0 * core::f32::consts::PI / n as f32);
        let sc = SinCos::new(phase);
        let i_ref = bias + INJECTION_FRACTION * self.cfg.spec.test_current_a * sc.sin;
        let v = self.regulate(i_ref, i, vdc_v)?;
        let settle = INJECTION_SETTLE_CYCLES * n;
        if self.k >= settle {
            let rec = self.record.injections.get_mut(idx)?;
            rec.periods_per_cycle = n;
            let (dv, di) = (v.alpha - v_bias, i.alpha - bias);
            rec.v_sin_cos[0] += dv * sc.sin;
            rec.v_sin_cos[1] += dv * sc.cos;
            rec.i_sin_cos[0] += di * sc.sin;
            rec.i_sin_cos[1] += di * sc.cos;
        }
        self.k += 1;
        if self.k >= settle + INJECTION_CYCLES * n {
            if j + 1 < INJECTION_PERIODS.len() as u8 {
                self.next(Stage::Injection(j + 1));
            } else if self.cfg.spec.rotate {
                self.next(Stage::Rotate);
                self.theta_e_rad = 0.0;
                self.block = 0;
                (self.block_v, self.block_n) = (0.0, 0);
            } else {
                self.stage = Stage::Done;
            }
        }
        Some((v, i_ref))
    }
}
