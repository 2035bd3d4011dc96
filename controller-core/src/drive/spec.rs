//! The drive specification in design units ([`DriveSpec`]), why one is refused
//! ([`DriveError`]), and the drive's own design constants (the voltage regulator, the
//! modulator's limits, the regeneration limit, the delay advance).

use crate::current::{CurrentError, CurrentLaw};
use crate::discretize::Discretization;
#[cfg(doc)]
use crate::ifoc::IfocConfig;
use crate::ifoc::IfocError;
use crate::motor::MotorParams;
use crate::observer::ObserverError;
use crate::speed::{SpeedError, SpeedLaw};
use crate::supervisor::Protection;
use crate::vhz::VhzError;
#[cfg(doc)]
use crate::{drive::DriveConfig, svpwm};

/// The highest bandwidth of the field-weakening voltage regulator, rad/s: an integrator on
/// the difference between the voltage target and the voltage the current loops ask for,
/// which lowers the voltage budget of the current references ([`crate::envelope`]) when the
/// machine needs more voltage than its model says. Slow against the current loops (≈ 1 000
/// rad/s), so that it corrects the model's steady-state error, not the loops' transients;
/// with the current trim it settles without sustained oscillation in the field-weakening
/// acceptance run (`hil-sim/tests/envelope.rs`). A slow rotor has it slower still: its own
/// is [`DriveSpec::voltage_regulator_bandwidth_rad_s`]. It measures the quadratic mean over
/// a slow period of the magnitude of the loops' request (peak phase volts, before the
/// hexagon), only ever lowers the budget, and by at most [`VOLTAGE_REGULATOR_RANGE`].
pub const VOLTAGE_REGULATOR_BANDWIDTH_RAD_S: f64 = 10.0;

/// The longest the rotor flux takes to fall to a lower reference while Running, s: the
/// fastest field-weakening voltage regulator's time constant
/// (1/[`VOLTAGE_REGULATOR_BANDWIDTH_RAD_S`]), so that the flux follows the budget the
/// regulator sets — and shorter while the speed
/// rises through field weakening ([`FLUX_LAG_FRACTION`]). A rotor slower than that has its
/// d-axis current lowered below the envelope's — to zero at most below base speed, reversed
/// if need be above the no-load base speed (`EnvelopeConfig::no_load_base_speed_rad_s`) — while
/// its flux is above the envelope's ([`IfocConfig::falling_flux_current`]); below the no-load
/// base speed the shipped (T_r 65 ms) and 24 V (14 ms) motors never are. The 500 hp machine (T_r 0.78 s),
/// accelerating at its 2 000 N·m (≈ 180 rad/s²), enters field weakening faster than its
/// flux falls by itself: the voltage left for torque fell to a quarter near 175 rad/s and it
/// was not within 1 % of its 319 rad/s 5 s after the step; with the flux forced down, 2.33 s
/// (`hil-sim` test `a_slow_rotor_weakens_its_field_in_time`).
/// The rotor-resistance law keeps listening while the flux is forced down, although its
/// model holds the flux (`MrasConfig::update`): kept from it then, the tuned 500 hp drive's
/// envelope above base speed fell from −11.5 … −18.5 % to −13.6 … −19.2 % of the analytic
/// one, and its matrix still missed one row on two seeds of twelve (others than without).
pub const FLUX_FALL_TIME_S: f64 = 1.0 / VOLTAGE_REGULATOR_BANDWIDTH_RAD_S;

/// In field weakening the flux the bus allows falls as 1/ω: a speed rising at α asks
/// `dψ*/dt = −ψ*·α/ω`, and a flux falling with time constant τ_f lags it by `τ_f·α/ω` of
/// itself — the lag's back-EMF takes the voltage the torque needs, and the drive holds the
/// torque to what the rest drives. The fall time is therefore at most this fraction of the
/// time the speed takes to rise by itself at the envelope's torque, `τ_f = f·|ω|·J/τ_max(ω)`
/// in field weakening (nominal J: the box's lightest), within [`FLUX_FALL_SLOW_PERIODS`]
/// slow periods and [`FLUX_FALL_TIME_S`]. The fall rate and the reversed current's floor
/// blend in over the first `f·ω_b` above the no-load base speed ω_b, where the target has
/// fallen by less than the lag allowed — switched at ω_b, a reversal to ±ω_b (the 895 W
/// member's ±153 rad/s) flipped them each slow step and two of its 64 runs tripped
/// `SwitchOpen` — or, motoring, as the target itself falls by `f` below the rated flux
/// (the part of its fall the speed makes: weighed by |ω|/ω_b, the share of the bus the
/// rated flux's back-EMF takes), whichever is further in: under load the voltage binds
/// below ω_b. Blended on ω_b alone, the 1.3 kW member 001 (its target 20 % down at ω_b)
/// left its flux behind, forced it there with the full gain, swung i_d* by 1.5 A per
/// encoder count and tripped `SwitchOpen` in 7 of 64 runs (population test
/// `a_loaded_motor_weakens_its_field_where_its_target_falls`). Braking, the speed falls,
/// and the braking point's flux is its own choice: ω_b's blend.
/// With τ_f held at 0.1 s the population's 895 W member (T_r 0.13 s,
/// ≈ 1 900 rad/s² at its τ_max) lagged 25 % at 168 rad/s and gave a fifth of its envelope's
/// torque there; its rise to 305 rad/s took 2.25× the physical least (`population` run,
/// docs/population.md).
pub const FLUX_LAG_FRACTION: f64 = 0.1;

/// The shortest flux fall time, in slow periods: the flux model and the d-axis reference
/// move once per slow period, and a first-order fall sampled at T_slow is well damped for
/// τ_f ≥ 2·T_slow.
pub const FLUX_FALL_SLOW_PERIODS: f64 = 2.0;

/// The dead-time compensation ramps from −t_d/T to +t_d/T across ± this fraction of the
/// current-reference limit around zero current (0.1 %: 4 mA on the shipped drive). It acts on
/// the *reference* currents, which carry no sensor noise, so the ramp can be narrow; a wider
/// one under-compensates around each zero crossing, where the inverter's error flips at once
/// (`hil-sim` test `dead_time_compensation_reduces_the_current_distortion`).
pub const DEAD_TIME_BAND_FRACTION: f64 = 0.001;

/// Six-step's fundamental phase voltage over the linear limit `V_dc/√3`, `2√3/π`: the most
/// any modulator gives, the largest `voltage_margin` an overmodulating drive may ask
/// ([`DriveSpec::overmodulation`]).
pub const SIX_STEP_FUNDAMENTAL: f64 = 2.0 * 1.732_050_807_568_877_2 / core::f64::consts::PI;

/// The lowest duty limit a sampling window may leave ([`DriveSpec::sample_window_s`], less
/// the dead-time compensation): beyond 20 % of the voltage lost the board's window, not the
/// modulator, is what needs fixing (a window of up to 5 µs at 20 kHz).
pub const DUTY_MAX_MIN: f64 = 0.8;

/// Regeneration limit: generating torque is reduced linearly from full at this fraction of
/// `vdc_max_v` (370 V of the shipped 400 V trip) …
pub const REGEN_LIMIT_START: f64 = 0.925;
/// … to zero at this one (390 V): without a brake chopper the energy a braking motor returns
/// charges the DC link, and the drive brakes only as hard as the bus can take, instead of
/// tripping on over-voltage. A chopper set below the start never lets it act.
pub const REGEN_LIMIT_END: f64 = 0.975;

/// The largest current trim on each axis, as a fraction of the current limit: the trim
/// corrects the loops' steady tracking error of a few per cent, not a missing current.
pub const CURRENT_TRIM_RANGE: f32 = 0.25;

/// While the modulator limits the loops' request and the torque asked is at its limit (an
/// acceleration into the voltage limit, on a hot motor's R_s, a saturated inductance), the
/// voltage regulator cuts this many times faster than [`VOLTAGE_REGULATOR_BANDWIDTH_RAD_S`],
/// however slow the rotor's own bandwidth: at 10 rad/s it took ≈ 100 ms to
/// lower the budget by the excess, while the loops lost their current in the 20 ms of the
/// loss-of-control check (issue 21's campaign: R_s × 1.5, R_r × 1.2 tripped at 111 rad/s).
pub const VOLTAGE_REGULATOR_LIMITED_GAIN: f32 = 10.0;

/// The largest excess of the loops' request over the voltage target the regulator takes in
/// one slow period, as a fraction of the target: a model error asks for tens of per cent
/// more (R_s ×1.5 at full current, a saturated inductance), a current step several times
/// the target for a period or two (the proportional path's k_p·Δi: σL_s·ω_c·Δi ≈ 11 kV for
/// the 500 hp machine's 197 A at its 8 763 rad/s crossover). Taken whole, at the limited
/// gain, that step cut the budget by half in four slow periods, the flux then left no
/// voltage for any torque, and the drive oscillated between full and none
/// (`hil-sim envelope krause-tuned.toml --generating`: a false `SwitchOpen` at its base
/// speed). Capped at 0.25, 0.5 or 1 the drive brakes there alike (−10.1 %); a frozen encoder
/// at top speed with the jump check off saturates the loops long enough for `LossOfControl`
/// with any of them (hil-sim test `a_frozen_encoder_at_speed_stays_the_encoders_fault`):
/// the largest, the nearest to what the regulator did before.
pub const VOLTAGE_REGULATOR_EXCESS_MAX: f32 = 1.0;

/// The deepest the voltage regulator may cut the budget, as a fraction of V_dc/√3.
pub const VOLTAGE_REGULATOR_RANGE: f32 = 0.5;

/// Delay from sampling the currents to the middle of the period in which the voltage
/// computed from them is applied, in PWM periods: one period of computation (duties
/// computed in period k act in period k + 1, as the simulator and the firmware's preload
/// do) plus half a period for the average of that period. The field angle of the output
/// voltage is advanced by ω_e times this delay.
pub const VOLTAGE_DELAY_PERIODS: f64 = 1.5;

/// The control core's clock, Hz: the STM32G474's 170 MHz (the firmware's `clocks()`; its
/// TIM1 runs on the same clock, the drive file's `board.tim_clock_hz`).
pub const CORE_CLOCK_HZ: f64 = 170e6;

/// Cycles per instruction the schedule assumes on the Cortex-M4F until the board measures it
/// (docs/firmware.md's bring-up): the instruction counts are QEMU's, and flash wait states,
/// pipeline refills at branches and the FPU's divide and square root take more than one
/// cycle each.
pub const CYCLES_PER_INSTRUCTION: f64 = 1.5;

/// The fast interrupt's longest period the schedule allows, instructions: issue 54's bound,
/// which `cost fast_interrupt_worst` measures on the shipped build.
pub const FAST_INTERRUPT_INSTRUCTIONS_MAX: f64 = 800.0;

/// The slow context's longest run the schedule allows, instructions: issue 54's bound, which
/// `cost slow_context_worst` measures on the shipped build.
pub const SLOW_CONTEXT_INSTRUCTIONS_MAX: f64 = 8000.0;

/// The highest PWM rate whose period holds the fast interrupt's longest,
/// [`FAST_INTERRUPT_INSTRUCTIONS_MAX`] at [`CYCLES_PER_INSTRUCTION`] on the [`CORE_CLOCK_HZ`]
/// core, Hz (141.7 kHz): above it no plan's delay exists ([`plan_delay_periods`]). The one
/// source of the limit the drive file's error names.
pub const PWM_FREQUENCY_MAX_HZ: f64 =
    CORE_CLOCK_HZ / (FAST_INTERRUPT_INSTRUCTIONS_MAX * CYCLES_PER_INSTRUCTION);

/// The plan's delay, PWM periods: the slow step's plan, made from what the fast step latched
/// at the slow tick, is adopted this many periods after the tick — a fixed period index, so
/// that the simulator, QEMU and the board run the same schedule whichever context computes
/// the plan and however long it takes (`Drive::step`). The slow context must finish its
/// longest run, [`SLOW_CONTEXT_INSTRUCTIONS_MAX`], within these periods while the fast
/// interrupt preempts it for up to [`FAST_INTERRUPT_INSTRUCTIONS_MAX`] in each:
///
/// `D = ⌈W_slow·c / (T − W_fast·c)⌉`, `c` = [`CYCLES_PER_INSTRUCTION`]/[`CORE_CLOCK_HZ`],
///
/// at least 1: 2 at 20 kHz (70.6 µs of slow context against 42.9 µs left of each 50 µs
/// period), 1 at 10 kHz and below. `None` when the period does not even hold the fast
/// interrupt's longest (from [`PWM_FREQUENCY_MAX_HZ`] up) or the rate is not finite and
/// positive.
pub fn plan_delay_periods(pwm_frequency_hz: f64) -> Option<u16> {
    let cycle_s = CYCLES_PER_INSTRUCTION / CORE_CLOCK_HZ;
    let left_s = 1.0 / pwm_frequency_hz - FAST_INTERRUPT_INSTRUCTIONS_MAX * cycle_s;
    if !(pwm_frequency_hz.is_finite() && pwm_frequency_hz > 0.0 && left_s > 0.0) {
        return None;
    }
    let periods = libm::ceil(SLOW_CONTEXT_INSTRUCTIONS_MAX * cycle_s / left_s).max(1.0);
    // Below u16::MAX for any rate that leaves time: at 1 Hz it is 1.
    (periods <= f64::from(u16::MAX)).then_some(periods as u16)
}

/// Position loop parameters (P law with speed saturation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionLaw {
    /// Speed reference per rad of position error, 1/s.
    pub k_per_s: f64,
    /// Speed-reference limit, mechanical rad/s.
    pub omega_max_rad_s: f64,
}

/// Reference frame of the current loops.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CurrentFrame {
    /// α/β loops on sinusoidal references (seed 002; ICAD eq. (20)).
    #[default]
    Stationary,
    /// d/q loops on the field-oriented frame (seed 000 PI1/PI3): Park of the measured
    /// currents at θ_e, the controllers on d and q errors, inverse Park of the voltage.
    Synchronous,
}

/// The q-axis current the field's slip is turned on (seed 000 eq. (7), `ω_sl =
/// (L_m·R_r/L_r)·i_q/ψ̂_r`, `IfocConfig::close_period`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SlipCurrent {
    /// The reference i_q*, as seed 000 prints eq. (7).
    #[default]
    Reference,
    /// The measured q current while Running (its mean over each slow period; the plan
    /// predicts with the reference in between): the slip the rotor sees, also where the
    /// loops do not follow their reference — at the voltage limit, or a stationary-frame PI
    /// at the field's frequency (docs/envelope.md).
    Measured,
}

/// Where the drive's speed and field angle come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpeedFeedback {
    /// The encoder's reading (the field anchored on the rotor's angle, seed 002's IFOC).
    #[default]
    Encoder,
    /// No encoder: the flux and speed observer ([`crate::observer`], Hinkkanen et al. 2010)
    /// gives the speed, and the field is anchored on its rotor-flux angle. Its speed
    /// estimate's bandwidth is derived, not chosen ([`DriveConfig::new`]): the low-frequency
    /// lag of the encoder's speed window the speed loop was designed and certified with.
    Sensorless,
    /// The encoder, with the observer running beside it on the measured voltage and
    /// currents alone: on the encoder's fault ([`crate::fault::Fault::EncoderLoss`],
    /// [`crate::fault::Fault::EncoderImplausible`]) while Running under a speed or torque reference, the
    /// drive carries on on the observer — as [`SpeedFeedback::Sensorless`] — instead of
    /// tripping, and reports the fault ([`crate::drive::Drive::ridden_through`]) until the
    /// next enable. Under a position reference (which needs the shaft's angle) or while
    /// magnetizing, the fault trips as with [`SpeedFeedback::Encoder`].
    EncoderRideThrough,
}

/// The control law: field-oriented vector control, or V/Hz.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Control {
    /// Field-oriented vector control (seed 002's IFOC, the current and speed loops).
    #[default]
    Vector,
    /// V/Hz control with stator-current feedback ([`crate::vhz`], Hinkkanen et al. 2022): a
    /// speed reference only, followed by the stator frequency at `ramp_rad_s2` (mechanical
    /// rad/s²); the magnetizing, the flying start and the supervisor as in vector control.
    VHz {
        /// The frequency reference's ramp, mechanical rad/s².
        ramp_rad_s2: f64,
        /// The current feedback's gain `k_u` ([`crate::vhz::K_U`]: the paper's; 0: none).
        k_u: f64,
        /// The frequency feedback's gain `k_w` ([`crate::vhz::K_W`]: the paper's; 0: none).
        k_w: f64,
    },
}

/// Everything a drive needs, in design units (f64). [`DriveConfig::new`] validates it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveSpec {
    /// Motor.
    pub motor: MotorParams,
    /// Fast-loop (PWM) frequency, Hz.
    pub pwm_frequency_hz: f64,
    /// The slow loop runs every `slow_divider`-th fast step (≥ 1).
    pub slow_divider: u16,
    /// Current law (ICAD or PI).
    pub current_law: CurrentLaw,
    /// Discretisation of the current law.
    pub discretization: Discretization,
    /// Frame of the current loops.
    pub current_frame: CurrentFrame,
    /// The field-frame loops' decoupling, `jω_e·σL_s·i*` fed forward
    /// (`DriveConfig::decoupling_v`; synchronous frame only): the partner of a law designed on
    /// the decoupled stator `R + s·σL_s`, as `design tune`'s (`k_p = ω_c·σL_s`, `k_i = ω_c·R`).
    /// Off for a law designed on the coupled axes as they are — seed 000's PI1/PI3, whose
    /// reproduction (`hil-sim run seed000-fig12`) runs the paper's controller. On by default
    /// in a drive file (`[controller] current_decoupling`; docs/envelope.md).
    pub current_decoupling: bool,
    /// The q current the slip is turned on.
    pub slip_current: SlipCurrent,
    /// Speed law.
    pub speed_law: SpeedLaw,
    /// Position loop.
    pub position: PositionLaw,
    /// Rotor-flux reference ψ_r*, Wb.
    pub flux_ref_wb: f64,
    /// Flux floor of the IFOC guard, Wb.
    pub flux_floor_wb: f64,
    /// Magnitude limit of the current reference vector, A.
    pub i_ref_max_a: f64,
    /// Magnetizing → Running when ψ̂_r ≥ this fraction of ψ_r* (in (0, 1)).
    pub magnetized_fraction: f64,
    /// Field weakening: the voltage the current references may ask for in steady state, as
    /// a fraction of the linear limit `V_dc/√3` (in (0, 1]); the rest is the current loops'
    /// headroom for transients ([`crate::envelope`]). Overmodulating, of the full hexagon's
    /// circle and up to [`SIX_STEP_FUNDAMENTAL`]: beyond 1 the steady voltage itself reaches
    /// into the hexagon's corners (docs/envelope.md, "Overmodulation").
    pub voltage_margin: f64,
    /// Bandwidth of the current trim, rad/s (0: off): a slow integral of the field-frame
    /// current error, added to the references the current loops track. The stationary-frame
    /// loops (seed 002) have integral action at DC only, so at an electrical frequency ω_e
    /// their sinusoidal references are followed with a small amplitude and phase error; in the
    /// field frame that is a constant error, which the trim removes — so that the flux and the
    /// torque are what the references say (field weakening relies on it).
    pub current_trim_bandwidth_rad_s: f64,
    /// Dead time the modulator compensates, s (0: none): the board's, when its inverter has
    /// one ([`svpwm::compensate_dead_time`]).
    pub dead_time_compensation_s: f64,
    /// The low-side conduction each phase's current sample needs on either side of the top
    /// of the count, s (0: current sensors that need none, e.g. in-line). The modulator keeps
    /// every duty at most `1 − 2·window/T` (less the dead time's compensation), so all three
    /// phases are measured in every period, and the drive treats that fraction of the bus as
    /// what it has ([`svpwm::modulate_sampled`]). The board's (`[board] sample_window_s`).
    pub sample_window_s: f64,
    /// Overmodulation (issue 52): beyond the hexagon the sampling window leaves, one phase at
    /// a time gives up its window up to the full hexagon (less the dead time's compensation),
    /// its current rebuilt from the other two in the periods that lost it
    /// ([`svpwm::overmodulate`]); the drive then counts on the full hexagon's circle
    /// ([`DriveSpec::duty_max`]). Off: every phase keeps its window and the drive counts on
    /// the sampled hexagon's. The drive file's `[controller] overmodulation`.
    pub overmodulation: bool,
    /// The range of the rotor resistance, × the motor's `R_r` (`[1, 1]`: the motor's, fixed):
    /// the rotor-resistance adaptation ([`crate::mras`]) keeps its estimate within it and
    /// starts from its geometric middle.
    pub rotor_resistance_range: [f64; 2],
    /// The range of the inductances, × the motor's `L_s`, `L_r`, `L_m` alike (`[1, 1]`: the
    /// motor's, fixed): the magnetizing fit ([`crate::mras`]) measures them at every enable
    /// of a demagnetized rotor at rest within it; the drive starts from the motor's, limited
    /// to it.
    pub inductance_range: [f64; 2],
    /// Trip thresholds.
    pub protection: Protection,
    /// The speed's and the field angle's source.
    pub speed_feedback: SpeedFeedback,
    /// The encoder speed reading's resolution, mechanical rad/s: one count over the speed
    /// window ([`crate::encoder::speed_resolution_rad_s`]; a drive file derives it from its
    /// board's `encoder_lines` and the slow period), 0 for a reading without quantisation.
    /// A speed held between two counts reads one or the other: the drive judges the present
    /// flux's torque limit, which is steep in the speed at the voltage limit, at a speed held
    /// within half of it of the reading ([`DriveConfig::new`]; unused on the observer's
    /// speed).
    pub speed_resolution_rad_s: f64,
    /// The control law.
    pub control: Control,
    /// The magnetizing curve the drive runs on (issue 50), `None` for a linear motor: the
    /// rotor flux at no load against the magnetizing current per unit of the rated point
    /// (`flux_ref_wb` at `flux_ref_wb/motor.lm_h()` — the motor's `L_m` is the curve's chord
    /// there). The field orientation's and the machine model's inductances follow the chord
    /// at the flux model's magnetizing current.
    pub magnetizing: Option<crate::magnetics::MagnetizingTable>,
}

impl DriveSpec {
    /// The open-phase window ([`Protection::open_phase_time_s`]) in fast steps, rounded up
    /// (at least one).
    pub fn open_phase_steps(&self) -> u32 {
        libm::ceil(self.protection.open_phase_time_s * self.pwm_frequency_hz).clamp(1.0, 4e9) as u32
    }

    /// … and in the slow steps that sample it — the open-phase, windowed current-sum and
    /// stuck-switch checks take one sample per slow period: its fast steps, rounded up to
    /// whole slow periods (five on the shipped drive). A host that judges those checks (the
    /// fault matrix's sensor rows, `hil_sim::faults`) counts with the drive.
    pub fn open_phase_slow_steps(&self) -> u32 {
        self.open_phase_steps().div_ceil(u32::from(self.slow_divider.max(1)))
    }

    /// The voltage regulator's bandwidth, rad/s: [`VOLTAGE_REGULATOR_BANDWIDTH_RAD_S`], or
    /// `1/T_r` of the slowest rotor the drive may run on where that is lower — the box's
    /// least rotor resistance, its largest inductances and, on a saturating curve, the
    /// chord at no current (the field-weakened flux's). The regulator lowers the budget, the
    /// envelope's flux with it, and the machine's voltage follows that flux with the rotor's
    /// lag: an integrator `K/s` on a first-order lag `1/(1 + s·T_r)` (the leakage's immediate
    /// share, σ·L_s/L_m ≈ 4 %, aside) has a phase margin of `90° − atan(ω_c·T_r)` at its
    /// crossover ω_c, `ω_c·√(1 + (ω_c·T_r)²) = K` — 52° at `K = 1/T_r`, 15° at 10 rad/s on
    /// the population's 153 kW member 010 (T_r 1.41 s). There, loaded at its top speed in
    /// field weakening, the budget swung 0 ↔ −46 V in a 0.55–0.7 s cycle, the envelope's flux
    /// 0.34 ↔ 0.47 Wb around the 0.39 Wb the machine held, and 6 of its 200 campaign runs
    /// at 20 kHz missed the 5 % steady flux accuracy (population test
    /// `a_slow_rotors_voltage_regulator_holds_its_flux_at_top_speed`). An acceleration into
    /// the voltage limit is the other regime, as fast whatever the rotor (`voltage_budget`).
    pub fn voltage_regulator_bandwidth_rad_s(&self) -> f64 {
        let chord_max = self.magnetizing.as_ref().map_or(1.0, |t| f64::max(t.chord_ratio(0.0), 1.0));
        let t_r_max_s =
            self.motor.tr_s() * self.inductance_range[1] * chord_max / self.rotor_resistance_range[0];
        f64::min(VOLTAGE_REGULATOR_BANDWIDTH_RAD_S, 1.0 / t_r_max_s)
    }

    /// The highest duty the modulator gives a phase — also the fraction of the bus voltage
    /// the drive counts on (its current loops, envelope and checks; the envelope a host
    /// computes for this drive: `hil_sim::envelope`): with [`DriveSpec::overmodulation`],
    /// 1 less the dead-time compensation, never below [`DriveSpec::duty_sampled`] (without a
    /// sampling window that is 1: nothing to overmodulate); without, `duty_sampled`.
    pub fn duty_max(&self) -> f64 {
        let sampled = self.duty_sampled();
        if self.overmodulation {
            f64::max(1.0 - self.dead_time_compensation_s * self.pwm_frequency_hz, sampled)
        } else {
            sampled
        }
    }

    /// The highest duty that leaves a phase its current sample: `1 − 2·sample_window_s·f_pwm`
    /// less the dead-time compensation, 1 without a sampling window. Validated by
    /// [`DriveConfig::new`] (at least [`DUTY_MAX_MIN`]).
    pub fn duty_sampled(&self) -> f64 {
        if self.sample_window_s > 0.0 {
            let f = self.pwm_frequency_hz;
            1.0 - 2.0 * self.sample_window_s * f - self.dead_time_compensation_s * f
        } else {
            1.0
        }
    }
}

/// Why a drive specification was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriveError {
    /// PWM frequency not finite and positive, or so high that a period does not hold the
    /// fast interrupt's longest ([`plan_delay_periods`]).
    PwmFrequency,
    /// `slow_divider` below `min`: the slow step's plan must be adopted before the next
    /// slow tick, [`plan_delay_periods`] after its own (`min` = that delay + 1).
    SlowDivider {
        /// The least divider at this PWM rate.
        min: u16,
    },
    /// Current law rejected.
    Current(CurrentError),
    /// Speed law rejected.
    Speed(SpeedError),
    /// Position law rejected.
    Position(SpeedError),
    /// IFOC parameters rejected.
    Ifoc(IfocError),
    /// `rotor_resistance_range` not `0 < min ≤ max ≤ 10·min`, finite
    /// ([`crate::mras::RANGE_RATIO_MAX`]).
    RotorResistanceRange,
    /// `inductance_range` not `0 < min ≤ max ≤ 10·min`, finite.
    InductanceRange,
    /// Flux reference not finite and positive, `flux_floor_wb` not below it, or its
    /// magnetizing current ψ*/L_m not below `i_ref_max_a`.
    FluxReference,
    /// `magnetized_fraction` not in (0, 1).
    MagnetizedFraction,
    /// `voltage_margin` not in (0, 1].
    VoltageMargin,
    /// `dead_time_compensation_s` negative, not finite, or not below a tenth of the PWM
    /// period.
    DeadTime,
    /// `sample_window_s` negative or not finite, or so long (with the dead time's
    /// compensation) that the highest duty is below [`DUTY_MAX_MIN`].
    SampleWindow,
    /// `speed_resolution_rad_s` negative or not finite.
    SpeedResolution,
    /// A raw configuration ([`DriveConfig::from_raw`]) with a non-finite number, an unknown
    /// variant or a zero count.
    Raw,
    /// `current_trim_bandwidth_rad_s` negative, not finite, or not below a tenth of the slow
    /// loop's rate (in rad/s).
    CurrentTrim,
    /// A protection threshold (or the current limit it is judged against) out of its range:
    /// `field`, the [`DriveSpec`] field's path (`protection.stall_time_s`, `i_ref_max_a`; the
    /// drive file's keys under `[protection]` are the same), and what it needs.
    Protection {
        /// The field, as `DriveSpec`'s path.
        field: &'static str,
        /// What it needs.
        need: &'static str,
    },
    /// Brake-chopper thresholds not 0 < off < on < [`REGEN_LIMIT_START`]·vdc_max.
    BrakeChopper,
    /// The sensorless observer cannot run at this PWM rate up to the overspeed level.
    Observer(ObserverError),
    /// The V/Hz law's configuration was rejected.
    Vhz(VhzError),
    /// The magnetizing table was rejected.
    Magnetizing(crate::magnetics::TableError),
    /// A motor with a magnetizing curve in a build without controller-core's `curve` feature
    /// (the firmware's `saturation`).
    CurveNotBuilt,
    /// Overmodulation asked of a build without controller-core's `overmodulation` feature.
    OvermodulationNotBuilt,
}

impl core::fmt::Display for DriveError {
    /// The field refused, as the [`DriveSpec`] path, and what it needs.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::PwmFrequency => write!(
                f,
                "pwm_frequency_hz: must be finite, > 0 and leave each period room for the fast \
                 interrupt's longest (below {:.1} kHz on the {:.0} MHz core)",
                PWM_FREQUENCY_MAX_HZ / 1e3,
                CORE_CLOCK_HZ / 1e6
            ),
            Self::SlowDivider { min } => write!(
                f,
                "slow_divider: must be ≥ {min} at this PWM rate (the slow step's plan is adopted {} \
                 period(s) after its tick, before the next one)",
                min.saturating_sub(1)
            ),
            Self::Current(e) => write!(f, "current_law: {e}"),
            Self::Speed(e) => write!(f, "speed_law: {e}"),
            Self::Position(e) => write!(f, "position: {e}"),
            Self::Ifoc(e) => write!(f, "motor, flux_floor_wb or i_ref_max_a (the field orientation): {e}"),
            Self::RotorResistanceRange => {
                f.write_str("rotor_resistance_range: needs 0 < min ≤ max ≤ 10·min, finite")
            }
            Self::InductanceRange => f.write_str("inductance_range: needs 0 < min ≤ max ≤ 10·min, finite"),
            Self::FluxReference => f.write_str(
                "flux_ref_wb: must be finite and > 0, above flux_floor_wb, with its magnetizing current \
                 ψ*/L_m below i_ref_max_a",
            ),
            Self::MagnetizedFraction => f.write_str("magnetized_fraction: must lie in (0, 1)"),
            Self::VoltageMargin => write!(
                f,
                "voltage_margin: must lie in (0, 1], or with overmodulation in (0, {SIX_STEP_FUNDAMENTAL:.4}] \
                 (six-step's fundamental)"
            ),
            Self::DeadTime => f.write_str(
                "dead_time_compensation_s: must be finite, ≥ 0 and below a tenth of the PWM period",
            ),
            Self::SampleWindow => write!(
                f,
                "sample_window_s: must be finite and ≥ 0, and leave a highest duty of at least {DUTY_MAX_MIN} \
                 with the dead time's compensation"
            ),
            Self::SpeedResolution => f.write_str("speed_resolution_rad_s: must be finite and ≥ 0"),
            Self::Raw => f.write_str(
                "the raw configuration: a number not finite, an unknown variant, a zero count, a bus range \
                 not +0 ≤ min < max, or a controlled stop for a fault that is not stoppable",
            ),
            Self::CurrentTrim => f.write_str(
                "current_trim_bandwidth_rad_s: must be finite, ≥ 0 and below a tenth of the slow loop's rate",
            ),
            Self::Protection { field, need } => write!(f, "{field}: {need}"),
            Self::Observer(e) => write!(f, "speed_feedback (sensorless): {e}"),
            Self::Vhz(e) => write!(f, "control (V/Hz): {e}"),
            Self::OvermodulationNotBuilt => f.write_str(
                "overmodulation: needs controller-core's `overmodulation` feature (the firmware's: \
                 `cargo xtask build-fw --features overmodulation`)",
            ),
            Self::CurveNotBuilt => f.write_str(
                "magnetizing: a saturating motor needs controller-core's `curve` feature (the firmware's \
                 `saturation`: `cargo xtask build-fw --features saturation`)",
            ),
            Self::Magnetizing(crate::magnetics::TableError(k)) => write!(
                f,
                "magnetizing: point {k} is not finite, not above the one before, or more than twice as steep \
                 as the chord to it — or the rated point's flux is not 1 (point {})",
                crate::magnetics::TABLE_POINTS
            ),
            Self::BrakeChopper => write!(
                f,
                "protection.brake_chopper: needs 0 < off_v < on_v < {REGEN_LIMIT_START} × protection.vdc_max_v"
            ),
        }
    }
}
