//! The phase checks, once per slow period: the open-phase window ([`Fault::OpenPhase`],
//! [`Fault::NoMotorCurrent`], the windowed current sum's [`Fault::CurrentSensor`]) and the
//! stuck-switch check ([`Fault::SwitchOpen`]).

#[cfg(doc)]
use super::{Protection, encoder::PINNED_FIELD_TURN_RAD};
use crate::fault::Fault;
use crate::frames::{Abc, AlphaBeta, INV_SQRT3};
use crate::num::{max_f32, min_f32, sqrt_f32};

/// Open-phase check: a phase is *commanded* over a window when the mean magnitude of its
/// reference current is at least this fraction of the rated magnetizing current …
pub const OPEN_PHASE_COMMANDED_FRACTION: f32 = 0.2;
/// … and *absent* when its measured current's mean magnitude is below this fraction of its
/// reference's (and every phase absent when their sum is below this fraction of the
/// references' sum); see `OpenPhaseWindow::add`.
pub const OPEN_PHASE_ABSENT_FRACTION: f32 = 0.1;
/// … and below this fraction of the mean magnitude of the other two phases' currents, which
/// must themselves reach this fraction of the commanded level (sensor noise of 0.01 A RMS
/// averages to 0.008 A, a quarter of that level at the shipped motor's 0.63 A).
pub const OPEN_PHASE_OTHERS_FRACTION: f32 = 0.25;
/// Consecutive windows an open phase (or no motor current) must persist for.
pub const OPEN_PHASE_WINDOWS: u8 = 2;
/// Open-phase check: a phase below the commanded level is still judged while its reference's
/// mean magnitude is at least this share of the other two's mean (a phase at its zero
/// crossing is not) and the three references' sum reaches the level.
pub const OPEN_PHASE_REF_SHARE: f32 = 0.5;

/// The stuck-switch check ([`Fault::SwitchOpen`], `PhaseDirections::add`) weighs each
/// direction of a phase's reference over that direction's recent samples (one per slow
/// period), with a time constant of this many open-phase windows
/// ([`Protection::open_phase_time_s`]; 2.5 ms shipped: a sample's weight is 0.18) …
pub const SWITCH_WINDOWS: f64 = 1.0;
/// … counting the samples where the phase's reference reaches this share of the reference
/// vector's magnitude (away from its zero crossings: 30° each side, where a lagging current
/// would miss) …
pub const SWITCH_LEVEL_SHARE: f32 = 0.5;
/// … while that magnitude reaches this share of the open-phase check's commanded level
/// ([`OPEN_PHASE_COMMANDED_FRACTION`] of the rated magnetizing current: at top speed the
/// voltage regulator shrinks the references after a fault) …
pub const SWITCH_FLOOR_SHARE: f32 = 0.5;
/// … a sample whose current falls short of its reference (in the reference's direction) by
/// more than this fraction of it *misses*; one that does not, with the current at the
/// commanded level or more (clear of the sensors' noise and offsets), *carries* …
pub const SWITCH_SHORTFALL_MISSING: f32 = 0.6;
/// … or, short of its reference at all, while the voltage the bridge applied departs from
/// the machine model's (the voltage check's departure, `SwitchWatch::note_departure`) on
/// the phase's axis in the reference's direction by more than this share of the linear
/// limit: the bridge did not apply what the phase asked. A leg held at the other rail for a
/// fraction δ of the period removes δ·V_dc from its own phase only, (2/3)·δ·V_dc on the
/// phase's axis once the common mode drops out — 2δ/√3 of the linear limit V_dc/√3: this is
/// δ = ½, a leg dead for half the period. A dead switch's current, driven through the
/// opposite diode by the back-EMF, may reach 55–80 % of its reference (no miss by the
/// shortfall alone) while its phase departs by 0.75–1.2 of the limit (the population's
/// 19 kW member at 10 kHz, `switch a upper stuck open at mid-speed generating`:
/// `SwitchOpen` after 98.4 ms against a bound of 60.1 ms, 34.1 ms with the departure). A
/// healthy drive departs by the model's error, ≤ 0.05 of the limit there — but the
/// departure is sampled as the loops take a new plan, and a loop catching up a lagging
/// current departs along its error by σL·di/dt: 0.3–0.7 of the limit on one phase for
/// ≈ 10 slow periods in a row on the 1.3 kW 8-pole member at 10 kHz accelerating, which at
/// half this level (1/(2√3)) tripped `SwitchOpen` healthy in 2 of its 200 campaign runs.
pub const SWITCH_DEPARTURE_SHARE: f32 = INV_SQRT3 as f32;
/// The voltage check's verdict names a phase the loops do not drive the bridge's
/// ([`Fault::OpenPhase`]: no current in a phase that is commanded — an open lead or a switch
/// stuck open in the direction needed, the same currents until the reference reverses)
/// when, in the stuck-switch check's last sample, its reference is
/// at least this share of the reference vector's magnitude — clear of its zero crossings,
/// where the sensors' noise and a lagging current miss any reference — and its current
/// misses it ([`SWITCH_SHORTFALL_MISSING`]).
pub const UNDRIVEN_REFERENCE_SHARE: f32 = 0.25;
/// … in this many samples in a row, and only while the field turned less than
/// [`PINNED_FIELD_TURN_RAD`] over the voltage check's window (as for a pinned phase): a
/// healthy current lagging its reference by φ ≈ ω/ω_c falls short near each zero crossing
/// for about 1/(ω_c·T_slow) samples whatever the speed (6 in a row for loops of 340 rad/s,
/// 20° behind at 125 rad/s: `a_phase_that_follows_one_way_only_is_a_stuck_switch`), but a
/// field that hardly turns has no lag to speak of. The 24 V drive's switches stuck open at
/// standstill fall short for 3 or more in a row before the verdict on seeds 0–11 (6 missed
/// seeds 0 and 1).
pub const UNDRIVEN_SAMPLES: u8 = 3;
/// … a direction is judged once its weighted count of samples reaches this (1: a long run;
/// 0.5: 3.5 samples) …
pub const SWITCH_SEEN: f32 = 0.5;
/// … and it is dead when more than this share of them missed (from a direction that
/// followed: 7 misses in a row) …
pub const SWITCH_MISSING_SHARE: f32 = 0.75;
/// … a stuck switch when the other direction follows (less than this share missed) and has
/// carried since the dead one began to miss, and no phase carries nothing either way (one
/// direction missing, the other not carried since: an open lead's — the other two phases
/// then share one current, one of them following one way only).
///
/// Or when the dead direction's current flowed *the other way* in more than
/// [`SWITCH_MISSING_SHARE`] of the samples of its last visit (its reference's counted
/// stretch of a half-wave, `Direction::reversed`) and the other direction has carried
/// since, following or not; such a phase is no open lead either. A lagging current does
/// not do that: a visit's samples lie within 60° of its reference's peak
/// ([`SWITCH_LEVEL_SHARE`]), and a current φ behind flows the other way in (φ − 30°)/120° of
/// them — three quarters only beyond φ = 120°, a third of a turn behind (the 3 300 V
/// drive's loops, 90° behind at mid-speed: half). Judged per whole visit, not over a
/// window: the reversed samples of a lagging current are the first of each visit, which a
/// window ending there reads as all of them (a 100° lag tripped so). A switch stuck open at
/// speed does: its phase sits at the other rail whenever its current flows the dead way
/// (through the opposite diode), and the back-EMF drives it the other way. At the voltage
/// limit the speed loop, asking back the lost torque, grows the references beyond what the
/// bus can drive, and the live direction, short of them both ways like every phase, no longer
/// follows: the population's 153 kW member at 4 kHz, its upper switch stuck open at top
/// speed motoring — references from 80 to 430 A, the live direction carrying 20–60 % of
/// them, the dead one −0.5 to −1.3 of its own — was named after 150–184 ms against a
/// bound of 52.6 ms (sensor seeds 0, 1, 5, 9), and after 10.5–26.5 ms on seeds 0–11 by
/// its reversed current.
pub const SWITCH_FOLLOWING_SHARE: f32 = 0.25;
/// A visit of fewer samples tells no reversal ([`SWITCH_FOLLOWING_SHARE`]): half the six a
/// visit holds (a third of the period) at ≈ 18 slow samples per electrical period, what the
/// slow rate leaves at 700 rad/s (`Drive::check_phases`).
pub const SWITCH_VISIT_SAMPLES: u8 = 3;
/// … "follows" judged over this many open-phase windows: a current lagging its reference
/// misses the first part of every half-wave and carries the rest, which the shorter window
/// reads as a dead direction followed by a live one (the 3 300 V drive's loops, 90° behind
/// at mid-speed: `SwitchOpen` before any fault with one window).
pub const SWITCH_FOLLOWING_WINDOWS: f64 = 4.0;
/// The current-sum check's windowed level (`Protection::current_sum_mean_max_a`), as a
/// fraction of the default `current_sum_max_a` (the drive file's default: its reason there,
/// `drive_file::drive::default_current_sum_mean_a`). The instantaneous check (the full level)
/// catches a large error at once; the mean, a sensor whose error stays below the full level
/// (a gain fault at a light load): healthy sensors leave a mean of a few tens of mA (three
/// channels of 10 mA RMS noise: 14 mA; a 20 mA offset; a 0.5 % gain error: 20 mA at 4 A), a
/// gain of 0.5 on a phase carrying 0.75 A leaves 0.24 A.
pub const CURRENT_SUM_MEAN_FRACTION: f64 = 0.25;

/// The gain error of a healthy current channel, as a fraction of its reading: a shunt and
/// its amplifier with 1 % parts, or a Hall sensor, is specified within ±1–2 % over
/// temperature. Three channels each within ε of their nominal gain read a sum of at most
/// `ε·(|i_a| + |i_b| + |i_c|)` (the true currents sum to zero), so the windowed current-sum
/// check allows that share of the window's mean |i_a| + |i_b| + |i_c| on top of its level
/// (`Protection::current_sum_mean_max_a`): the healthy channels' error grows with the
/// current, while a channel's gain of 0.5 reads ≈ a sixth of that sum.
pub const CURRENT_SENSOR_GAIN_TOLERANCE: f32 = 0.02;

crate::raw::raw_struct! {
    /// The phase checks' levels, as the slow step uses them (the drive configuration's).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub(crate) struct PhaseLimits {
        /// The open-phase check's commanded level, A, for the stuck-switch check
        /// ([`OPEN_PHASE_COMMANDED_FRACTION`] × the rated flux's d-axis current: derived in the
        /// slow step instead, the firmware took 196 B more flash).
        pub(crate) switch_level_a: f32,
        /// The stuck-switch check's weights of a new sample, 1 − exp(−T_slow/τ) with τ
        /// [`SWITCH_WINDOWS`] and [`SWITCH_FOLLOWING_WINDOWS`] open-phase windows.
        pub(crate) switch_gains: [f32; 2],
        /// Slow steps of the open-phase check's window (it samples the currents once per slow
        /// period, with the stuck-switch check).
        pub(crate) open_phase_slow_steps: u32,
        /// The windowed current-sum check's level (`Protection::current_sum_mean_max_a`), A.
        pub(crate) sum_mean_max_a: f32,
    }
}

impl PhaseLimits {
    /// The levels for an open-phase window of `open_phase_steps` fast steps and
    /// `open_phase_slow_steps` slow ones (`DriveSpec::open_phase_steps`,
    /// `DriveSpec::open_phase_slow_steps`), a slow step every `slow_divider` fast ones, the
    /// rated flux's d-axis current `i_d_rated_a` and the windowed current-sum level
    /// `sum_mean_max_a`.
    pub(crate) fn new(
        [open_phase_steps, open_phase_slow_steps]: [u32; 2],
        slow_divider: u16,
        i_d_rated_a: f32,
        sum_mean_max_a: f32,
    ) -> Self {
        let n = f64::from(slow_divider);
        Self {
            switch_level_a: OPEN_PHASE_COMMANDED_FRACTION * i_d_rated_a,
            switch_gains: [SWITCH_WINDOWS, SWITCH_FOLLOWING_WINDOWS]
                .map(|windows| (1.0 - libm::exp(-n / (windows * f64::from(open_phase_steps)))) as f32),
            open_phase_slow_steps,
            sum_mean_max_a,
        }
    }
}

/// The open-phase check's window ([`Protection::open_phase_time_s`]).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct OpenPhaseWindow {
    /// Σ|i_ref| per phase, A.
    reference: Abc,
    /// Σ|i| per phase, A.
    measured: Abc,
    /// Σ|i_a + i_b + i_c|, A.
    sum_error: f32,
    steps: u32,
    /// Consecutive windows in which each phase looked open.
    suspect: [u8; 3],
    /// Consecutive windows without any motor current.
    no_current: u8,
    /// The last window's Σ|i_ref| per phase, A: what a phase is absent against when the
    /// fault itself shrank its reference ([`looks_open`]).
    last_reference: Abc,
}

impl OpenPhaseWindow {
    /// One sample (a slow step's: `Drive::check_phases`) of the reference and measured
    /// phase currents. At the end of a window of `steps` samples, with `level_a` the rated
    /// magnetizing current:
    /// - a phase *looks open* when it was commanded (mean |i_ref| ≥
    ///   [`OPEN_PHASE_COMMANDED_FRACTION`]·`level_a`, or at least [`OPEN_PHASE_REF_SHARE`] of
    ///   the other two's mean while the three references' sum reaches that level) while the other two carry current (their
    ///   mean |i| at least [`OPEN_PHASE_OTHERS_FRACTION`] of that level) but it hardly does:
    ///   its mean |i| below [`OPEN_PHASE_OTHERS_FRACTION`] of theirs and below
    ///   [`OPEN_PHASE_ABSENT_FRACTION`] of its own mean |i_ref| or of the commanded level,
    ///   whichever is larger (an open lead carries none, the other two equal and opposite
    ///   currents; its reading is the sensor's noise);
    /// - the motor *carries no current* when the reference does (the sum of the mean
    ///   |i_ref| at least twice the commanded level) and the measured sum is below
    ///   [`OPEN_PHASE_ABSENT_FRACTION`] of it (no lead connected, or every sensor dead: the
    ///   current-sum check cannot see three sensors reading zero), and no phase looks open:
    ///   an open lead met with the reference along its own phase leaves the other two only
    ///   the reference's small component across them, under that fraction of the sum but
    ///   clear of the sensors' noise, which no current at all is not.
    ///
    /// Either must hold for [`OPEN_PHASE_WINDOWS`] windows in a row — a healthy phase passes
    /// its zero crossing, and slow current loops (seed 000's) catch up, within one — to give
    /// [`Fault::OpenPhase`] or [`Fault::NoMotorCurrent`]. Then a new window.
    ///
    /// Also, in one window: the mean |i_a + i_b + i_c| above `sum_mean_max_a` plus
    /// [`CURRENT_SENSOR_GAIN_TOLERANCE`] of the mean |i_a| + |i_b| + |i_c| is
    /// [`Fault::CurrentSensor`].
    pub(crate) fn add(
        &mut self,
        reference: Abc,
        measured: Abc,
        steps: u32,
        level_a: f32,
        sum_mean_max_a: f32,
    ) -> Option<Fault> {
        let (r, i) = (&mut self.reference, &mut self.measured);
        r.a += reference.a.abs();
        r.b += reference.b.abs();
        r.c += reference.c.abs();
        i.a += measured.a.abs();
        i.b += measured.b.abs();
        i.c += measured.c.abs();
        self.sum_error += (measured.a + measured.b + measured.c).abs();
        self.steps += 1;
        if self.steps < steps {
            return None;
        }
        self.close(level_a, sum_mean_max_a)
    }

    /// The window's verdict, at its end (see [`OpenPhaseWindow::add`]): out of line, once
    /// per window — inlined, it took the fast step's flash.
    #[inline(never)]
    fn close(&mut self, level_a: f32, sum_mean_max_a: f32) -> Option<Fault> {
        let (r, i) = (self.reference, self.measured);
        if self.sum_error
            > sum_mean_max_a * self.steps as f32 + CURRENT_SENSOR_GAIN_TOLERANCE * (i.a + i.b + i.c)
        {
            return Some(Fault::CurrentSensor);
        }
        let commanded = OPEN_PHASE_COMMANDED_FRACTION * level_a * self.steps as f32;
        let (r_sum, i_sum) = (r.a + r.b + r.c, i.a + i.b + i.c);
        let looks_open = |r: f32, last: f32, i: f32| looks_open(commanded, [r_sum, i_sum], [r, last], i);
        let count = |n: u8, now: bool| if now { n.saturating_add(1) } else { 0 };
        let ([sa, sb, sc], last) = (self.suspect, self.last_reference);
        let open = [looks_open(r.a, last.a, i.a), looks_open(r.b, last.b, i.b), looks_open(r.c, last.c, i.c)];
        let suspect = [count(sa, open[0]), count(sb, open[1]), count(sc, open[2])];
        // Two phases carrying current (a phase looks open only then) is no motor without it.
        let absent = r_sum >= 2.0 * commanded && i_sum < OPEN_PHASE_ABSENT_FRACTION * r_sum;
        let no_current = count(self.no_current, absent && open == [false; 3]);
        *self = Self { suspect, no_current, last_reference: r, ..Self::default() };
        if no_current >= OPEN_PHASE_WINDOWS {
            Some(Fault::NoMotorCurrent)
        } else if suspect.iter().any(|&n| n >= OPEN_PHASE_WINDOWS) {
            Some(Fault::OpenPhase)
        } else {
            None
        }
    }
}

/// One phase of the open-phase window's verdict ([`OpenPhaseWindow::add`]): its sums `r`
/// (Σ|i_ref|, this window's and the last's) and `i` (Σ|i|) against the three phases'
/// `[r_sum, i_sum]` and the commanded level's sum `commanded`. Absent against the other two
/// phases' current *and* against its own reference: a phase at its reference's zero crossing
/// (slow rotation: generating near synchronism, standstill) legitimately carries little, and
/// so does its reference; the other two must carry clearly more than the sensors' noise. Out of line: one copy for the three
/// phases (inlined three times: 192 B more flash), once per window.
#[inline(never)]
fn looks_open(commanded: f32, [r_sum, i_sum]: [f32; 2], [r, r_last]: [f32; 2], i: f32) -> bool {
    let others = 0.5 * (i_sum - i);
    let r_others = 0.5 * (r_sum - r);
    // Commanded: this phase at the commanded level, or — the motor commanded at all — as
    // much as half the others' mean (not at its zero crossing): a reference that shrinks
    // below the level with the open lead (at top speed, ≈ 5 ms after it opens) stays judged.
    (r >= commanded || (r_sum >= commanded && r >= OPEN_PHASE_REF_SHARE * r_others))
        && others >= OPEN_PHASE_OTHERS_FRACTION * commanded
        && i < OPEN_PHASE_OTHERS_FRACTION * others
        // Against its reference — this window's or the last's, whichever is larger — or the
        // commanded level when both are below it: the voltage regulator shrinks the references
        // within a window of the fault, at top speed to the commanded level and below, and a
        // tenth of that lies under the sensors' noise and offset, which an open lead's reading
        // is (the shipped drive at 150 rad/s with the back-EMF fed forward: the realistic
        // board's 20 mA offset on phase b kept its open lead unjudged for 36.5 ms, 7 ms
        // against the last window's reference). A healthy phase follows its reference within
        // a window; no sinusoid's window mean falls tenfold in the next.
        && i < OPEN_PHASE_ABSENT_FRACTION * max_f32(max_f32(r, r_last), commanded)
}

/// The stuck-switch check ([`Fault::SwitchOpen`]) of one phase in one direction of its
/// reference: exponentially weighted over that direction's recent samples (one per slow
/// period where the reference reaches the level), how many there were (`seen`, towards 1)
/// and how many of them *missed* (the current short of its reference by more than
/// [`SWITCH_SHORTFALL_MISSING`] of it), over two windows. Counts, not amperes: a reference
/// step the loops take two samples to follow is two samples, however large.
#[derive(Clone, Copy, Debug)]
struct Direction {
    seen: f32,
    missed: f32,
    /// `seen` and `missed` over [`SWITCH_FOLLOWING_WINDOWS`] (a whole half-wave of a
    /// lagging current holds misses).
    seen_long: f32,
    missed_long: f32,
    /// Samples in this direction's present (or last) visit — its reference's counted
    /// stretch of a half-wave, ended by the other direction's next sample — and how many of
    /// them flowed the other way (any amount: the sensors' noise alone reverses half the
    /// samples of a current at zero, never most).
    visit: [u8; 2],
    /// The last whole visit's current flowed the other way in more than
    /// [`SWITCH_MISSING_SHARE`] of its samples, at least [`SWITCH_VISIT_SAMPLES`] of them.
    reversed: bool,
    /// A sample of this direction carried since the other direction last missed in good
    /// standing.
    fresh: bool,
    /// This direction went missing: the other direction's next sample decides.
    dead: bool,
    /// Samples of this direction in a row that carried (from [`SWITCH_VISIT_SAMPLES`] on, a
    /// dead direction is no longer dead).
    carrying: u8,
}

impl Default for Direction {
    fn default() -> Self {
        Self::NONE
    }
}

impl Direction {
    /// No samples yet.
    const NONE: Self = Self {
        seen: 0.0,
        missed: 0.0,
        seen_long: 0.0,
        missed_long: 0.0,
        visit: [0; 2],
        reversed: false,
        fresh: false,
        dead: false,
        carrying: 0,
    };

    /// Judged (at least [`SWITCH_SEEN`] of a window's samples) and missing in more than
    /// [`SWITCH_MISSING_SHARE`] of them.
    fn missing(&self) -> bool {
        self.seen >= SWITCH_SEEN && self.missed > SWITCH_MISSING_SHARE * self.seen
    }

    /// Judged and missing in [`SWITCH_FOLLOWING_SHARE`] of them or more: out of good
    /// standing.
    fn lapsed(&self) -> bool {
        self.seen >= SWITCH_SEEN && self.missed >= SWITCH_FOLLOWING_SHARE * self.seen
    }

    /// Judged over the longer window and missing in less than [`SWITCH_FOLLOWING_SHARE`]
    /// of its samples.
    fn following(&self) -> bool {
        self.seen_long >= SWITCH_SEEN && self.missed_long < SWITCH_FOLLOWING_SHARE * self.seen_long
    }
}

/// [`Direction`]s of one phase.
#[derive(Clone, Copy, Debug, Default)]
struct PhaseDirections {
    positive: Direction,
    negative: Direction,
    /// One direction missing and the other not carried since it began to miss, whichever
    /// way the last counted sample went: the phase carries nothing either way (an open lead,
    /// the open-phase check's). Not "both directions missing": a lead that opens late in a
    /// half-wave leaves that direction a few misses after a half-wave carried, far from
    /// missing when the other is, and the other two phases, sharing one current at the
    /// voltage limit, may follow one way only (population member 022 at 20 kHz, top speed,
    /// motoring: `SwitchOpen` on phase b 8.6 ms after phase a's lead opened). Nor only the
    /// last sample's direction: the first samples the other way, not yet missing, cleared it
    /// while the other two phases, their current lost to the back-EMF, gave a verdict (member
    /// 010 at 20 kHz, the same row, sensor seeds 5 and 8: `SwitchOpen` after 9.0–10.5 ms).
    open: bool,
    /// Consecutive samples whose current fell short of a *tracked* reference (what the
    /// phase's loop pushes for: the intended one plus the current trim) of at least
    /// [`UNDRIVEN_REFERENCE_SHARE`] of the intended reference vector's magnitude, counted or
    /// not; from
    /// [`UNDRIVEN_SAMPLES`] on, the loops do not drive the phase (the voltage check's
    /// verdict reads it: [`SwitchWatch::undriven`]).
    short: u8,
    /// The applied voltage's departure from the machine model's on this phase's axis at the
    /// last voltage check, in linear limits: positive where the bridge applied less than asked
    /// in the positive direction ([`SwitchWatch::note_departure`]).
    departure: f32,
}

impl PhaseDirections {
    /// One sample of the phase's intended reference `r`, its tracked reference `tracked` and
    /// measured current `m`, A, and its leg's side `leg` ([`leg_sides`]: positive, the upper
    /// switch on for most of the period): [`PhaseDirections::short`] counts against `tracked` at
    /// `floor` or more; a reference `r` at `level` or more goes into its direction with
    /// `gains` (the other direction holds). The directions judge the intended reference —
    /// what the plan asks of the machine —, not the tracked one: the current trim makes up a
    /// stationary-frame PI's steady error at speed (≈ E/k_p), so the tracked reference
    /// exceeds what a healthy phase carries (the tuned 3 300 V drive's 27 A of ≈ 60 A at
    /// top speed, read as dead directions before its injection).
    /// `true`: a stuck switch — one direction missing while the other follows and has
    /// carried (the current at the `commanded` level or more: clear of the sensors' noise
    /// and offsets) since the first began to miss, or, the first gone missing, the other's
    /// next sample carries; the other need not follow where the missing one's current
    /// flowed the other way ([`SWITCH_FOLLOWING_SHARE`]). Its current then flows through the
    /// opposite diode and pins the phase to the other rail. An open lead misses both ways,
    /// loops that cannot follow miss both ways in every phase, and a lagging current misses
    /// the start of every half-wave both ways: none of them is a stuck switch.
    ///
    /// Out of line: one copy for the three phases, once per slow period.
    #[inline(never)]
    fn add(
        &mut self,
        [r, tracked]: [f32; 2],
        [m, leg]: [f32; 2],
        [level, floor, allowance]: [f32; 3],
        commanded: f32,
        gains: [f32; 2],
    ) -> bool {
        let Self { positive, negative, open, short, departure } = self;
        let fell_short = allowance <= 0.0 && tracked.abs() >= floor && misses(tracked, m);
        *short = if fell_short { short.saturating_add(1) } else { 0 };
        let (this, other, d) = if r >= 0.0 { (positive, negative, 1.0) } else { (negative, positive, -1.0) };
        let magnitude = d * r;
        // Short of its reference beyond what a step the loops follow explains (`allowance`),
        // or absent (a loop overshooting a fall leaves a current, not none: an open lead's
        // reading is the sensors' noise), or — no such step — short by any amount where the
        // bridge departed from the model.
        let shortfall = d * (r - m);
        let missed = shortfall - allowance > SWITCH_SHORTFALL_MISSING * magnitude
            || (allowance > 0.0 && m.abs() < OPEN_PHASE_ABSENT_FRACTION * magnitude)
            || (allowance <= 0.0 && d * *departure > SWITCH_DEPARTURE_SHARE && shortfall > 0.0);
        // A sample the step may explain — a miss without the allowance, none with it — tells
        // nothing either way.
        if magnitude < level || (!missed && shortfall > SWITCH_SHORTFALL_MISSING * magnitude) {
            return false;
        }
        // This sample ends the other direction's visit; it opens or goes on with this one's.
        if other.visit[0] > 0 {
            let [n, reversed] = core::mem::take(&mut other.visit);
            other.reversed =
                n >= SWITCH_VISIT_SAMPLES && f32::from(reversed) > SWITCH_MISSING_SHARE * f32::from(n);
        }
        // A visit longer than a count holds (a standing field's) is judged on its first
        // samples: both counts stop together, the share stays the samples'.
        let [n, reversed] = &mut this.visit;
        if *n < u8::MAX {
            *n += 1;
            *reversed += u8::from(d * m < -allowance);
        }
        if missed && !this.lapsed() {
            // A miss in good standing: the other way must carry anew (an open lead misses
            // both ways from the same moment). Further misses of a direction already out of
            // standing keep what the other way showed since (a stuck switch's dead direction
            // may carry a little, through the opposite diode, late in its half-wave).
            other.fresh = false;
        }
        let carried = !missed && d * m >= commanded;
        this.fresh |= carried;
        let x = if missed { 1.0 } else { 0.0 };
        let [g, g_long] = gains;
        // What calls the direction dead skips a current that carried while its switch was
        // needed for less than half the period (its leg held at the other rail for most of
        // it): it flows through the opposite diode, dead switch or not, and tells nothing of
        // the switch. It still shows the phase connected, for the other direction's verdict
        // (`fresh`, `following`); a miss counts wherever it falls.
        if missed || d * leg >= 0.0 {
            this.seen += g * (1.0 - this.seen);
            this.missed += g * (x - this.missed);
        }
        this.seen_long += g_long * (1.0 - this.seen_long);
        this.missed_long += g_long * (x - this.missed_long);
        // Missing on a sample that missed: a direction carrying again is not dead, whatever
        // its history (a direction's history is stale until its next sample: a current that
        // trailed a reference step through one half-wave carried in the next, and was judged
        // dead by it, `a_current_catching_up_with_a_reference_step_is_no_stuck_switch`). A
        // stuck switch's dead direction misses every sample. Dead until the other way answers,
        // or until it carries [`SWITCH_VISIT_SAMPLES`] samples in a row (the 34 kW population
        // member at 6.5 kHz, arriving at top speed to generate: a direction of phase b went
        // missing as the loops undershot a falling torque, then carried eight samples in a row;
        // the other way's next sample answered the stale verdict, `SwitchOpen` on a healthy
        // drive). Not on one: a dead switch's phase may carry the last sample of its
        // half-wave (drive.toml at top speed, motoring: phase a's dead direction, 0.2 A against
        // a reference of 0.09 A).
        this.carrying = if carried { this.carrying.saturating_add(1) } else { 0 };
        let missing = missed && this.missing();
        this.dead = missing || (this.dead && this.carrying < SWITCH_VISIT_SAMPLES);
        // The other way, dead, answered by this sample: carried here, the switch is stuck —
        // on this way's following, or on the dead way's current driven the other way.
        let answered = core::mem::take(&mut other.dead) && carried && (this.following() || other.reversed);
        // A phase whose current was driven either way against its reference is connected.
        let reversed = this.reversed || other.reversed;
        *open = ((this.missing() && !other.fresh) || (other.missing() && !this.fresh)) && !reversed;
        answered || (missing && (other.following() || this.reversed) && other.fresh)
    }
}

/// A current `m` short of its reference `r` (in the reference's direction) by more than
/// [`SWITCH_SHORTFALL_MISSING`] of it: the sample *misses*.
#[inline]
fn misses(r: f32, m: f32) -> bool {
    let d = if r >= 0.0 { 1.0 } else { -1.0 };
    d * (r - m) > SWITCH_SHORTFALL_MISSING * d * r
}

/// [`PhaseDirections`] of the three phases.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SwitchWatch {
    phases: [PhaseDirections; 3],
    /// The reference vector's magnitude, its falls followed over [`SWITCH_WINDOWS`] (its
    /// rises at once), A: how far the references fell of late ([`SwitchWatch::add`]).
    recent_peak_a: f32,
}

/// No samples yet: a constant, which the drive's two resets (`Drive::new`,
/// `Drive::enable`) write in one go (the derived `Default` built each phase's directions
/// apart and copied them in: 264 B of flash).
impl Default for SwitchWatch {
    fn default() -> Self {
        const NEW: SwitchWatch = SwitchWatch {
            phases: [PhaseDirections {
                positive: Direction::NONE,
                negative: Direction::NONE,
                open: false,
                short: 0,
                departure: 0.0,
            }; 3],
            recent_peak_a: 0.0,
        };
        NEW
    }
}

impl SwitchWatch {
    /// A phase the loops do not drive, for another check's verdict (the voltage check's):
    /// one missing both ways, a direction that went missing and was not yet answered the
    /// other way, or [`UNDRIVEN_SAMPLES`] samples in a row short of a reference of at least
    /// [`UNDRIVEN_REFERENCE_SHARE`] of the magnitude ([`PhaseDirections::short`]) — a switch
    /// stuck open at standstill pins its phase at a rail while the reference still rises
    /// below [`SWITCH_LEVEL_SHARE`] of it (the 24 V drive's upper switch, named
    /// `EncoderImplausible` 16 ms after it was first needed). That is [`Fault::OpenPhase`],
    /// no current in a commanded phase: until the reference reverses, an open lead and a
    /// switch stuck open in the direction needed give the same currents, so the verdict
    /// claims no switch ([`Fault::SwitchOpen`] is the stuck-switch check's own, once the
    /// other way has carried); a wrong field angle turns the references and the loops still
    /// follow them.
    ///
    /// `turning`: the field turned more than [`PINNED_FIELD_TURN_RAD`] over the voltage
    /// check's window, where a lagging current falls short near its zero crossings — the
    /// short samples do not count.
    ///
    /// A phase missing both ways needs no test of its own: [`PhaseDirections::add`] sets
    /// `open` only with the missing direction's `dead`, which only the phase's next counted
    /// sample (that sets `open` anew) or a reset clears. The flags or'ed, not short-circuited,
    /// and inlined into its one caller, `Drive::check_encoder` (out of line, with `open`
    /// tested and `||`, 178 B: 88 B more flash).
    pub(crate) fn undriven(&self, turning: bool) -> bool {
        let short = |p: &PhaseDirections| p.short >= UNDRIVEN_SAMPLES;
        let dead = |p: &PhaseDirections| p.positive.dead | p.negative.dead;
        self.phases.iter().fold(false, |u, p| u | dead(p) | (short(p) & !turning))
    }

    /// The voltage check's departure of the applied voltage from the machine model's,
    /// `departure` (stationary frame, V), against the linear limit `v_limit_v`: each phase's
    /// share, for the next samples' [`SWITCH_DEPARTURE_SHARE`].
    pub(crate) fn note_departure(&mut self, departure: AlphaBeta, v_limit_v: f32) {
        let per_v = 1.0 / max_f32(v_limit_v, 1e-3);
        let p = departure.inverse_clarke();
        let [a, b, c] = &mut self.phases;
        (a.departure, b.departure, c.departure) = (p.a * per_v, p.b * per_v, p.c * per_v);
    }

    /// One sample (a slow period) of the phase references `reference` (intended) and
    /// `tracked` (with the current trim) and currents `measured`, A, with the side each leg
    /// held its phase at ([`leg_sides`]: a carried sample whose leg sat at the other rail
    /// does not count towards its direction's verdict, [`PhaseDirections::add`]): a phase's
    /// sample counts where its reference reaches
    /// [`SWITCH_LEVEL_SHARE`] of the reference vector's magnitude (away from its zero
    /// crossings), with that magnitude at least [`SWITCH_FLOOR_SHARE`] of the `commanded`
    /// level; `gains` weigh it (`DriveConfig`'s). [`Fault::SwitchOpen`] when a phase's
    /// directions say so and no phase carries nothing either way. Out of line: once per slow period
    /// (inlined, the interrupt took ≈ 850 B more flash).
    ///
    /// `forcing_a`: how far the drive's flux forcing holds the d reference below where the
    /// flux would fall of itself (0 unforced). The loops follow that step at the voltage
    /// limit, for milliseconds — a lag in every phase, which the direction counts would read
    /// as a dead switch (a reversal from braking at 2× base speed tripped `SwitchOpen`).
    /// Likewise a fall of the references (their magnitude against its recent peak, which
    /// follows falls over [`SWITCH_WINDOWS`] open-phase windows — the loops settle within
    /// one, as the open-phase check takes them to): loops that follow a fall overshoot it by
    /// a share of the fall, which a sample of the smaller reference reads as a miss. The
    /// speed loop drops the torque from its limit to nearly nothing on arriving at its speed,
    /// and at the voltage limit the loops undershot the fall for 8 ms, the currents 1.3–3 A
    /// of references of 6–8 A: `SwitchOpen` on healthy drives, the population's 34 kW member
    /// at 6.5 kHz and 73 kW member at 5.7 kHz arriving at top speed to generate.
    ///
    /// A current that never followed such a step falls short by at most the step, and one
    /// that overshot it still flows. So while the larger of the two could make a miss (more
    /// than [`SWITCH_SHORTFALL_MISSING`] of the level, [`SWITCH_LEVEL_SHARE`] of the
    /// magnitude, the least a counted sample's reference is), a sample misses by a shortfall
    /// beyond the step, or with its current absent (below [`OPEN_PHASE_ABSENT_FRACTION`] of
    /// its reference: an open lead's, which the check must see as such to leave it to the
    /// open-phase check — population member 010's recorded samples,
    /// `an_open_lead_whose_other_phases_lose_their_current_is_no_stuck_switch`); it reverses
    /// only by a current the other way beyond the step; a sample the step may explain (a miss
    /// without it, none with it) counts for nothing; and the voltage's departure and the
    /// undriven count judge nothing. Not kept out altogether: a stuck switch at top speed shrinks the references
    /// each time its dead direction is needed — the voltage regulator's answer to a phase held
    /// at the other rail — so the fall comes with every visit of the dead direction, the very
    /// samples that show it. The population's 24 kW member 181 at 7.2 kHz, its upper switch
    /// stuck open at top speed, motoring: the magnitude fell from ≈ 22 to ≈ 10 A at each of
    /// phase a's positive half-waves, its current −18 A against +11 A asked; with every such
    /// sample kept out, `SwitchOpen` came after 86.8 ms against a bound of 52.9 ms (13.0 ms
    /// judged so; drive.toml's own at top speed, motoring, 10.1 ms instead of 20.6). The
    /// flux's forcing, the same: population member 022 (35 kW) at top speed on a scratch
    /// build forced its flux by 0.07–0.14 A of a 21 A magnitude for 166 ms after a switch
    /// stuck open, and kept out of any forcing the check named it after 175–181 ms against
    /// a bound of 53 ms.
    #[inline(never)]
    pub(crate) fn add(
        &mut self,
        [reference, tracked]: [Abc; 2],
        [measured, legs]: [Abc; 2],
        [commanded, forcing_a]: [f32; 2],
        gains: [f32; 2],
    ) -> Option<Fault> {
        // The reference vector's magnitude from its phases (their sum zero): √(⅔ Σ r²).
        let r = reference;
        let amplitude = sqrt_f32((2.0 / 3.0) * (r.a * r.a + r.b * r.b + r.c * r.c));
        let level = SWITCH_LEVEL_SHARE * amplitude;
        let ([g, _], peak) = (gains, &mut self.recent_peak_a);
        *peak = max_f32(amplitude, *peak - g * (*peak - amplitude));
        let step_a = max_f32(forcing_a, *peak - amplitude);
        if amplitude < SWITCH_FLOOR_SHARE * commanded {
            for p in &mut self.phases {
                p.short = 0; // no sample: none stale
            }
            return None;
        }
        let allowance = if step_a > SWITCH_SHORTFALL_MISSING * level { step_a } else { 0.0 };
        let floor = UNDRIVEN_REFERENCE_SHARE * amplitude;
        let [a, b, c] = &mut self.phases;
        let levels = [level, floor, allowance];
        let (m, v) = (measured, legs);
        let stuck = a.add([reference.a, tracked.a], [m.a, v.a], levels, commanded, gains)
            | b.add([reference.b, tracked.b], [m.b, v.b], levels, commanded, gains)
            | c.add([reference.c, tracked.c], [m.c, v.c], levels, commanded, gains);
        // No phase carries nothing either way: a lead open on one phase leaves the other two
        // one current between them, which one of them may follow one way only.
        (stuck && !(a.open || b.open || c.open)).then_some(Fault::SwitchOpen)
    }
}

/// Which rail each leg held its phase at for most of a period in which the bridge was
/// given `v_ab` (stationary frame, V): each phase's voltage less the mid of the highest and
/// the lowest — the min–max modulator's common mode, so positive where the leg's duty is
/// above ½ (`svpwm::duties_within`), its upper switch on for most of the period, and
/// negative where its lower one is. For the stuck-switch check ([`SwitchWatch::add`]).
pub(crate) fn leg_sides(v_ab: AlphaBeta) -> Abc {
    let v = v_ab.inverse_clarke();
    let mid = 0.5 * (max_f32(max_f32(v.a, v.b), v.c) + min_f32(min_f32(v.a, v.b), v.c));
    Abc { a: v.a - mid, b: v.b - mid, c: v.c - mid }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The window's current-sum verdict on `steps` samples of three-phase currents of
    /// amplitude `amplitude_a` at `phase_rad` (a standing vector: a rotor held at rest),
    /// channel b read with gain `gain_b` and channel c with `gain_c`, against the level
    /// `sum_mean_max_a`.
    fn sum_verdict(
        amplitude_a: f32,
        phase_rad: f32,
        [gain_b, gain_c]: [f32; 2],
        sum_mean_max_a: f32,
    ) -> Option<Fault> {
        let third = 2.0 * core::f32::consts::PI / 3.0;
        let i = |k: f32| amplitude_a * libm::cosf(phase_rad - k * third);
        let truth = Abc { a: i(0.0), b: i(1.0), c: i(2.0) };
        let measured = Abc { a: truth.a, b: gain_b * truth.b, c: gain_c * truth.c };
        let mut w = OpenPhaseWindow::default();
        (0..5).find_map(|_| w.add(truth, measured, 5, 1.0, sum_mean_max_a))
    }

    /// A visit longer than its counts hold (a field at rest, then turning) is judged on the
    /// samples it counted, not on a count of reversed samples that went on past the count
    /// of samples: 300 samples, the last 200 of them reversed — 0.78 of 255 read so, 0.61 of
    /// the first 255 — is no reversed visit.
    #[test]
    fn a_long_visit_is_judged_on_the_samples_it_counted() {
        let mut p = PhaseDirections::default();
        let add = |p: &mut PhaseDirections, r: f32, m: f32| {
            p.add([r, r], [m, r], [0.5, 0.25, 0.0], 0.1, [0.18, 0.05]);
        };
        for k in 0..300 {
            add(&mut p, 1.0, if k < 100 { 1.0 } else { -0.1 });
        }
        add(&mut p, -1.0, -1.0);
        assert_eq!(p.positive.visit, [0, 0]);
        assert!(!p.positive.reversed);
    }

    /// A direction that went missing and then carries [`SWITCH_VISIT_SAMPLES`] samples in a
    /// row is no longer dead: the other way's next carried sample names no switch. One
    /// carried sample (a dead switch's phase at the end of its half-wave) leaves it dead.
    #[test]
    fn a_direction_that_carries_again_is_no_longer_dead() {
        let add = |p: &mut PhaseDirections, r: f32, m: f32| {
            p.add([r, r], [m, r], [0.5, 0.25, 0.0], 0.1, [0.18, 0.05])
        };
        for carried_again in [1, SWITCH_VISIT_SAMPLES] {
            let mut p = PhaseDirections::default();
            for _ in 0..40 {
                for r in [1.0, -1.0] {
                    for _ in 0..6 {
                        add(&mut p, r, r);
                    }
                }
            }
            for _ in 0..12 {
                add(&mut p, 1.0, 0.0);
            }
            assert!(p.positive.dead);
            for _ in 0..carried_again {
                add(&mut p, 1.0, 1.0);
            }
            assert_eq!(add(&mut p, -1.0, -1.0), carried_again == 1, "{carried_again} carried");
        }
    }

    /// Loops that undershoot a fall of the references are no stuck switch: a balanced
    /// reference turning 10° per sample at 1 A falls to 0.3 A, and the currents sit at a
    /// fifth of it for the next 90° — every direction counted there misses — then follow
    /// again: no `SwitchOpen` (it tripped before the references' recent fall kept those
    /// samples out). Phase a's upper switch dead on the steady references (its current
    /// clamped at zero, b and c sharing theirs) is named within two turns.
    #[test]
    fn loops_undershooting_a_fall_of_the_references_are_no_stuck_switch() {
        let third = 2.0 * core::f32::consts::PI / 3.0;
        let reference = |deg: i32, amplitude: f32| {
            let t = (deg as f32).to_radians();
            let i = |k: f32| amplitude * libm::cosf(t - k * third);
            Abc { a: i(0.0), b: i(1.0), c: i(2.0) }
        };
        let run = |amplitude: &dyn Fn(i32) -> f32, current: &dyn Fn(i32, Abc) -> Abc| {
            let mut w = SwitchWatch::default();
            (0..360).find_map(|k| {
                let deg = 10 * k;
                let r = reference(deg, amplitude(deg));
                w.add([r, r], [current(deg, r), r], [0.1, 0.0], [0.18, 0.05]).map(|f| (deg, f))
            })
        };
        let falls = |deg: i32| if deg < 1800 { 1.0 } else { 0.3 };
        let undershoot = |deg: i32, r: Abc| {
            let f = if (1800..1890).contains(&deg) { 0.2 } else { 1.0 };
            Abc { a: f * r.a, b: f * r.b, c: f * r.c }
        };
        assert_eq!(run(&falls, &undershoot), None);
        let stuck = |deg: i32, r: Abc| {
            if deg < 1800 || r.a <= 0.0 {
                return r;
            }
            let shared = 0.5 * (r.b - r.c);
            Abc { a: 0.0, b: shared, c: -shared }
        };
        let (deg, fault) = run(&|_| 1.0, &stuck).unwrap();
        assert_eq!(fault, Fault::SwitchOpen);
        assert!(deg < 1800 + 720, "named at {deg}°");
    }

    /// An open lead met with the reference along its own phase (the tuned DeLorenzo
    /// appendix drive's phase a at mid-speed generating: 0.72 A asked of a, 0.36 A of b and
    /// c) leaves b and c only the reference's component across them, which starts at nil:
    /// they carry 0.06 A each, a twelfth of the references' sum — under
    /// [`OPEN_PHASE_ABSENT_FRACTION`] of it, as with no motor connected — yet well above the
    /// sensors' noise, which a motor carrying no current would not. That is
    /// [`Fault::OpenPhase`]; three phases at nothing (or at the sensors' noise) are
    /// [`Fault::NoMotorCurrent`].
    #[test]
    fn two_phases_carrying_current_are_no_missing_motor_current() {
        let reference = Abc { a: 0.72, b: -0.36, c: -0.36 };
        let verdict = |measured: Abc| {
            let mut w = OpenPhaseWindow::default();
            (0..3 * 5).find_map(|_| w.add(reference, measured, 5, 0.7, 0.1))
        };
        assert_eq!(verdict(Abc { a: 0.0, b: 0.06, c: -0.06 }), Some(Fault::OpenPhase));
        assert_eq!(verdict(Abc { a: 0.0, b: 0.0, c: 0.0 }), Some(Fault::NoMotorCurrent));
        assert_eq!(verdict(Abc { a: 0.004, b: -0.003, c: 0.005 }), Some(Fault::NoMotorCurrent));
    }

    /// A healthy channel's gain error of 1.5 % (within `CURRENT_SENSOR_GAIN_TOLERANCE`) on
    /// 14.7 A of a 20 A vector leaves 0.22 A in the sum, more than twice the shipped
    /// drive's level of 0.1 A, and is no fault; a channel 8 % off at the same currents
    /// (1.17 A against the 0.86 A the level and its share allow) is, and so is a gain of 0.5
    /// on a phase carrying 0.3 A of a 0.5 A vector (0.15 A against 0.12 A).
    #[test]
    fn the_windowed_sum_allows_the_healthy_gain_error_at_large_currents() {
        let level_a = 0.25 * 0.4;
        assert_eq!(sum_verdict(20.0, 0.3, [1.0, 1.015], level_a), None);
        assert_eq!(sum_verdict(20.0, 0.3, [1.0, 1.08], level_a), Some(Fault::CurrentSensor));
        let faulty = sum_verdict(0.5, 2.0 * core::f32::consts::PI / 3.0 + 0.93, [0.5, 1.0], level_a);
        assert_eq!(faulty, Some(Fault::CurrentSensor));
    }
}
