//! What the sequence measured ([`Record`]), field by field, and its bytes: every field a
//! 4-byte little-endian word, so a record crosses a link bit-exactly.

use super::no_load::NoLoadRecord;
use super::{BLOCKS, ROTATION_BLOCKS};
use crate::frames::AlphaBeta;

/// One voltage pulse's result.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PulseRecord {
    /// Pulse voltage (magnitude, along the phase's axis), V.
    pub v_pulse_v: f32,
    /// Pulse length, periods.
    pub periods: u32,
    /// Current change over the first half of the pulse, A.
    pub delta_i_half_a: AlphaBeta,
    /// Current change over the pulse, A.
    pub delta_i_a: AlphaBeta,
}

/// One DC level's record: the step from the previous level's current to this one's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelRecord {
    /// α-current reference of the level, A.
    pub i_ref_a: f32,
    /// Mean α voltage commanded in each block, V.
    pub v_alpha_v: [f32; BLOCKS],
    /// Mean measured α current in each block, A.
    pub i_alpha_a: [f32; BLOCKS],
    /// Σ (i_ref − i_α) over the first [`LAG_PERIODS`](super::LAG_PERIODS) periods,
    /// A·periods: the current's mean lag behind the step, in periods, is this over the step.
    pub lag_a_periods: f32,
}

impl Default for LevelRecord {
    fn default() -> Self {
        Self { i_ref_a: 0.0, v_alpha_v: [0.0; BLOCKS], i_alpha_a: [0.0; BLOCKS], lag_a_periods: 0.0 }
    }
}

/// One sinusoidal injection's lock-in sums over [`INJECTION_CYCLES`](super::INJECTION_CYCLES)
/// whole cycles: the excitation's phase of period k is 2π·k/`periods_per_cycle`; voltage and
/// current are taken relative to the level they ride on.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InjectionRecord {
    /// Periods per cycle.
    pub periods_per_cycle: u32,
    /// Σ v_α·sin, Σ v_α·cos, V·periods (the voltage commanded at period k).
    pub v_sin_cos: [f32; 2],
    /// Σ i_α·sin, Σ i_α·cos, A·periods (the current sampled at period k).
    pub i_sin_cos: [f32; 2],
}

/// The rotating field's record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotationRecord {
    /// Amplitude of the rotating current, A.
    pub amplitude_a: f32,
    /// Periods per block (the ramp and the hold in [`ROTATION_BLOCKS`] equal blocks).
    pub periods_per_block: u32,
    /// The encoder's turning from the field's start to the end of each block, rad (the sum
    /// of its readings' wrapped differences).
    pub theta_m_rad: [f32; ROTATION_BLOCKS],
}

impl Default for RotationRecord {
    fn default() -> Self {
        Self { amplitude_a: 0.0, periods_per_block: 0, theta_m_rad: [0.0; ROTATION_BLOCKS] }
    }
}

/// Everything measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Record {
    /// Offset of each current channel, A.
    pub offsets_a: [f32; 3],
    /// RMS noise of each current channel with the bridge off, A.
    pub noise_a: [f32; 3],
    /// Mean bus voltage, V.
    pub vdc_v: f32,
    /// The pulses along a, b, c.
    pub pulses: [PulseRecord; 3],
    /// L̂σ from the pulses, H (the current loop's design value).
    pub l_sigma_pulse_h: f32,
    /// Current-loop proportional gain, V/A.
    pub kp_v_per_a: f32,
    /// The DC levels.
    pub levels: [LevelRecord; 3],
    /// The injections.
    pub injections: [InjectionRecord; 2],
    /// The rotating field (all zero unless [`CommissionSpec::rotate`](super::CommissionSpec::rotate)).
    pub rotation: RotationRecord,
    /// The no-load test (all zero unless it ran).
    pub no_load: NoLoadRecord,
}

/// Bytes of a serialised [`Record`] ([`Record::write_bytes`]).
pub const RECORD_BYTES: usize =
    4 * (3 + 3 + 1 + 3 * 6 + 2 + 3 * (2 + 2 * BLOCKS) + 2 * 5 + 2 + ROTATION_BLOCKS + NoLoadRecord::WORDS);

impl Record {
    /// Every field in declaration order, as 4-byte little-endian words (f32 as IEEE-754
    /// bits, so a record crosses a link bit-exactly): [`RECORD_BYTES`] into `out`. `None`
    /// if `out` is shorter.
    pub fn write_bytes(&self, out: &mut [u8]) -> Option<usize> {
        let mut chunks = out.chunks_exact_mut(4);
        let mut put = |w: u32| chunks.next().map(|c| c.copy_from_slice(&w.to_le_bytes()));
        let mut ok = true;
        let mut f = |x: f32| ok &= put(x.to_bits()).is_some();
        self.visit(&mut f);
        ok.then_some(RECORD_BYTES)
    }

    /// The record of [`Record::write_bytes`]'s bytes; `None` unless `bytes` holds exactly
    /// [`RECORD_BYTES`].
    pub fn read_bytes(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != RECORD_BYTES {
            return None;
        }
        let mut words = bytes.chunks_exact(4).map(|c| {
            let mut w = [0u8; 4];
            w.copy_from_slice(c);
            u32::from_le_bytes(w)
        });
        let mut r = Record::default();
        r.visit_mut(&mut |x: &mut f32| *x = f32::from_bits(words.next().unwrap_or(0)));
        Some(r)
    }

    /// Each field as an f32 (integers by their bits), in order.
    fn visit(&self, f: &mut impl FnMut(f32)) {
        let mut copy = *self;
        copy.visit_mut(&mut |x: &mut f32| f(*x));
    }

    pub(super) fn visit_mut(&mut self, f: &mut impl FnMut(&mut f32)) {
        let bits = |f: &mut dyn FnMut(&mut f32), n: &mut u32| {
            let mut x = f32::from_bits(*n);
            f(&mut x);
            *n = x.to_bits();
        };
        self.offsets_a.iter_mut().chain(self.noise_a.iter_mut()).for_each(&mut *f);
        f(&mut self.vdc_v);
        for p in self.pulses.iter_mut() {
            f(&mut p.v_pulse_v);
            bits(f, &mut p.periods);
            for ab in [&mut p.delta_i_half_a, &mut p.delta_i_a] {
                f(&mut ab.alpha);
                f(&mut ab.beta);
            }
        }
        f(&mut self.l_sigma_pulse_h);
        f(&mut self.kp_v_per_a);
        for l in self.levels.iter_mut() {
            f(&mut l.i_ref_a);
            l.v_alpha_v.iter_mut().chain(l.i_alpha_a.iter_mut()).for_each(&mut *f);
            f(&mut l.lag_a_periods);
        }
        for j in self.injections.iter_mut() {
            bits(f, &mut j.periods_per_cycle);
            j.v_sin_cos.iter_mut().chain(j.i_sin_cos.iter_mut()).for_each(&mut *f);
        }
        let r = &mut self.rotation;
        f(&mut r.amplitude_a);
        bits(f, &mut r.periods_per_block);
        r.theta_m_rad.iter_mut().for_each(&mut *f);
        let n = &mut self.no_load;
        for x in
            [&mut n.rs_ohm, &mut n.ls_h, &mut n.tr_s, &mut n.k_e, &mut n.flux_first_wb, &mut n.amplitude_a]
        {
            f(x);
        }
        f(&mut n.omega_e_rad_s);
        bits(f, &mut n.periods_per_window);
        for w in n.windows.iter_mut().chain(n.curve.iter_mut()) {
            w.v_dq_v.iter_mut().chain(w.i_dq_a.iter_mut()).for_each(&mut *f);
            f(&mut w.theta_m_rad);
        }
    }
}
