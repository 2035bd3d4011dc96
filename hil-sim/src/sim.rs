//! Software-in-the-loop: a `controller-core` [`Drive`] against the [`Machine`] plant.
//!
//! Timing, as on the board: at the start of PWM period k the currents are sampled, the
//! drive computes duties, and those duties are applied during period k+1 (one period of
//! computation delay). Inverter: [`InverterModel`] — average-value (default) or switching
//! with dead time; the plant integrates the resulting piecewise-constant voltage exactly.
//! Sensors: [`SensorModel`] (ideal by default). Loads: a piecewise-constant torque set by
//! events, plus the [`LoadModel`] (eddy-current brake or locked rotor).

use crate::bridge_fault::{Comparator, Legs, PhaseShort, SwitchShort};
use crate::inverter::{InverterModel, Segments};
use crate::sensors::{SensorModel, Sensors};
use controller_core::drive::{Drive, FastOutput, Measurements, Mode, PhaseCommand, Reference, Telemetry};
use controller_core::frames::{Abc, AlphaBeta};
use controller_core::motor::MotorParams;
use plant::{Machine, MachineState, Rk4Midway};

/// The controller a run drives: the in-process [`Drive`] (software in the loop) or a drive
/// on an emulated MCU ([`crate::pil::Pil`], processor in the loop). Errors are broken links;
/// a drive refusing a command is not an error (the trace shows it).
///
/// [`DriveUnderTest::step`] returns the output itself, not a `Result`: wrapping it cost the
/// simulator ≈ 5 ns per period when this was changed (`hil-sim bench`: ≈ 58 against ≈ 53
/// ns), the output being copied through memory on its way to the plant. A step that fails
/// (a broken PIL link) returns phases off and leaves its error for
/// [`DriveUnderTest::take_failure`], which the simulator asks after every step.
pub trait DriveUnderTest {
    /// The slow loop runs every `slow_divider()`-th step.
    fn slow_divider(&self) -> u16;
    /// [`Drive::enable`].
    fn enable(&mut self) -> Result<(), String>;
    /// [`Drive::set_reference`].
    fn set_reference(&mut self, r: Reference) -> Result<(), String>;
    /// [`Drive::controlled_stop`].
    fn controlled_stop(&mut self) -> Result<(), String>;
    /// [`Drive::step`]; phases off if the step failed (see [`DriveUnderTest::take_failure`]).
    fn step(&mut self, m: &Measurements) -> FastOutput;
    /// [`Drive::telemetry`]: the signals of the last step (asked only for the trace's rows).
    fn telemetry(&self) -> Telemetry;
    /// Why the last [`DriveUnderTest::step`] failed, if it did (taken: asked again, `None`).
    /// The in-process drive cannot fail.
    fn take_failure(&mut self) -> Option<String> {
        None
    }
    /// The board's comparator broke the bridge ([`Drive::trip`] with `HardwareBreak`, what
    /// the firmware does when it finds the break flag).
    fn hardware_break(&mut self) -> Result<(), String> {
        Err("the hardware comparator's break is modelled for the in-process drive only".into())
    }
    /// The controller has nothing more to do: the run may end early (asked every 2 000
    /// periods). A drive never finishes.
    fn finished(&self) -> bool {
        false
    }
}

impl DriveUnderTest for Drive {
    fn slow_divider(&self) -> u16 {
        self.config().slow_divider()
    }

    fn enable(&mut self) -> Result<(), String> {
        let _refused = Drive::enable(self);
        Ok(())
    }

    fn set_reference(&mut self, r: Reference) -> Result<(), String> {
        let _refused = Drive::set_reference(self, r);
        Ok(())
    }

    fn controlled_stop(&mut self) -> Result<(), String> {
        Drive::controlled_stop(self);
        Ok(())
    }

    fn step(&mut self, m: &Measurements) -> FastOutput {
        Drive::step(self, m)
    }

    fn telemetry(&self) -> Telemetry {
        Drive::telemetry(self)
    }

    fn hardware_break(&mut self) -> Result<(), String> {
        self.trip(controller_core::drive::Fault::HardwareBreak);
        Ok(())
    }
}

/// A time-stamped event of a scenario.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// Enable the drive.
    Enable,
    /// New outer-loop reference.
    Reference(Reference),
    /// New load torque, N·m.
    LoadNm(f64),
    /// A controlled stop ([`Drive::controlled_stop`]).
    Stop,
    /// A fault of the plant, inverter or sensors from this time on.
    Fault(Injection),
}

/// A fault injected into the simulated hardware (issue 18's campaign): what the drive must
/// detect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Injection {
    /// Current sensor of `phase` (0 = a, 1 = b, 2 = c) reads `gain·i + offset_a` from now on:
    /// dead (0, 0), stuck at x (0, x), a gain error (g, 0), an offset drift (1, x).
    CurrentSensor {
        /// Phase index 0…2.
        phase: usize,
        /// New gain.
        gain: f64,
        /// New offset, A.
        offset_a: f64,
    },
    /// The current channels of phases `first` and `second` read each other's phase from
    /// now on (swapped wiring; a commissioning check must refuse it).
    CurrentChannelsSwapped {
        /// Phase index 0…2.
        first: usize,
        /// Phase index 0…2.
        second: usize,
    },
    /// The encoder counter stops counting (a lost or stuck encoder).
    EncoderStuck,
    /// The encoder counts backwards from now on (its A and B channels swapped: an
    /// installation error commissioning must refuse).
    EncoderReversed,
    /// The encoder counter jumps by `counts` spurious counts at the next read (noise on its
    /// lines); the count stays off by that much. Needs the encoder model.
    EncoderGlitch {
        /// Spurious counts (either sign).
        counts: i64,
    },
    /// The encoder counts `lines` per revolution from now on while the estimator decodes
    /// with the configured number (a wrong line count). Needs the encoder model.
    EncoderLines {
        /// The encoder's actual lines per revolution.
        lines: u32,
    },
    /// The DC bus becomes `vdc_v` (a sag or a surge).
    BusVoltage {
        /// New bus voltage, V.
        vdc_v: f64,
    },
    /// The machine's electrical parameters become those of `motor` (the rotor heating, the
    /// magnetizing inductance saturating); the mechanics and the state carry over.
    Plant {
        /// The new electrical parameters (its J and B are not used).
        motor: MotorParams,
    },
    /// The load seizes: a friction torque of `torque_nm` brakes the rotor to rest and holds
    /// it there (a jammed gearbox or bearing; the deceleration is finite, as in a real
    /// seizure).
    LoadSeizure {
        /// The seized load's friction torque, N·m.
        torque_nm: f64,
    },
    /// The load's torque steps to `torque_nm` (as [`Event::LoadNm`]: positive against
    /// positive speed) — an overload beyond what the drive can give, which does not lock the
    /// rotor but drags it away from its reference.
    LoadStep {
        /// The new load torque, N·m.
        torque_nm: f64,
    },
    /// Two motor terminals short ([`crate::bridge_fault`]): a current through the short's
    /// resistance and inductance from leg to leg, which the current sensors and the
    /// comparator see.
    PhaseShort(PhaseShort),
    /// A switch conducts for good ([`crate::bridge_fault`]): the bus shoots through its leg
    /// whenever the leg's other switch turns on.
    SwitchShort(SwitchShort),
    /// A switch of `phase`'s leg never conducts again (a dead gate driver, a bond wire off):
    /// its leg cannot drive the current in that switch's direction, which then flows
    /// through the opposite diode — with the upper switch open, a positive phase current
    /// puts the leg at −V_dc/2 for the whole period (decided on the current at the period's
    /// start).
    SwitchOpen {
        /// Phase index 0…2.
        phase: usize,
        /// The upper switch (else the lower one).
        upper: bool,
    },
    /// The lead of `phase` (0 = a, 1 = b, 2 = c) opens: no current flows in it from now on
    /// (a broken wire or connector; the motor runs single-phase on the other two).
    OpenPhase {
        /// Phase index 0…2.
        phase: usize,
    },
}

/// `m` with its resistances scaled by `rs_factor` and `rr_factor` (heating) and its
/// magnetizing inductance by `lm_factor` (saturation: L_s and L_r change by the same
/// amount, the leakage inductances stay) — a [`Injection::Plant`] change. `None` if the
/// result is not a valid motor.
/// The drive's flux model's time to `magnetized_fraction` of its target on its reference
/// current, `T_r·ln(1/(1 − f))`: when it leaves Magnetizing for Running (0.19 s for the
/// DeLorenzo machine, 2.3 s for the 500 hp Krause machine). Runs ask for torque after it.
pub fn magnetizing_time_s(spec: &controller_core::drive::DriveSpec) -> f64 {
    spec.motor.tr_s() * (1.0 / (1.0 - spec.magnetized_fraction)).ln()
}

pub fn scaled_plant(m: &MotorParams, rs_factor: f64, rr_factor: f64, lm_factor: f64) -> Option<MotorParams> {
    let lm = lm_factor * m.lm_h();
    MotorParams::new(
        rs_factor * m.rs_ohm(),
        rr_factor * m.rr_ohm(),
        m.ls_h() - m.lm_h() + lm,
        m.lr_h() - m.lm_h() + lm,
        lm,
        m.pole_pairs(),
        m.j_kgm2(),
        m.b_nms(),
    )
    .ok()
}

/// Load beyond the event-driven constant torque.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum LoadModel {
    /// Only the constant torque set by [`Event::LoadNm`].
    #[default]
    Torque,
    /// Eddy-current brake: T_L = k·ω_m (plus the event torque).
    EddyBrake {
        /// N·m per rad/s.
        k_nm_s_rad: f64,
    },
    /// Rotor held at standstill.
    LockedRotor,
    /// Coulomb (dry) friction of magnitude `friction_nm` (plus the event torque).
    CoulombFriction {
        /// N·m.
        friction_nm: f64,
    },
    /// A dynamometer: the rotor turns at `omega_m_rad_s` from the start, whatever the torque
    /// (for torque–speed measurements).
    Dynamometer {
        /// Mechanical speed, rad/s.
        omega_m_rad_s: f64,
    },
}

/// The DC link: a capacitor between the source and the inverter, with an optional brake
/// chopper. Without one ([`Scenario::dc_link`] = `None`) the bus is stiff.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DcLink {
    /// Link capacitance, F.
    pub capacitance_f: f64,
    /// What feeds it (its open-circuit voltage is the scenario's `vdc_v`).
    pub source: DcSource,
    /// Internal resistance of the source, Ω.
    pub resistance_ohm: f64,
    /// Brake chopper, if any.
    pub chopper: Option<Chopper>,
}

/// The DC link's source.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DcSource {
    /// A supply that sinks current as well as it sources it (a regenerative front end).
    Supply,
    /// A diode rectifier: current flows only into the link; regenerated energy stays there.
    Rectifier,
}

/// A brake chopper: a resistor switched across the link by the drive's brake output
/// ([`controller_core::drive::FastOutput::brake`], its thresholds in the drive's
/// `[protection] brake_chopper`), from the period after the drive decides it, like the duties.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chopper {
    /// Resistance, Ω.
    pub resistance_ohm: f64,
}

/// The DC link's state and its energy bookkeeping, updated once per PWM period with the
/// phase currents at the period's start: the inverter draws `i_dc = Σ d_x·i_x` (the upper
/// switches connect their phases to the positive rail; with the bridge off, the phases whose
/// current flows into the bridge conduct through their upper diodes), the source delivers
/// `(V_s − V_dc)/R` (a rectifier only when positive), the chopper `V_dc/R_ch` while the
/// drive has it on;
/// `C·dV_dc/dt` is the balance (explicit Euler: the link's time constants are far longer than
/// a period).
#[derive(Clone, Copy, Debug)]
struct LinkState {
    vdc_v: f64,
}

impl LinkState {
    /// One period of `ts` s with the chopper switched `brake`; returns the source's and the
    /// chopper's mean currents over it, A. The bus capacitor's equation with the inverter's
    /// current held, `C·dv/dt = (V_s − v)/R·[source conducts] − i_dc − v/R_ch·[brake]`, is
    /// linear: solved exactly over the period (an exponential towards its end value), and for
    /// a rectifier piecewise, at the instant the bus crosses the source's voltage. Explicit
    /// Euler, before, went unstable wherever R·C < T/2 — a realistic stiff supply (0.05 Ω,
    /// 470 µF) "diverged" at 13 ms and blamed the machine, and a 1 pF link read 9.6·10¹³ V
    /// (found by trying).
    fn step(&mut self, link: &DcLink, source_v: f64, i_dc_a: f64, brake: bool, ts: f64) -> (f64, f64) {
        let g_ch = match link.chopper {
            Some(c) if brake => 1.0 / c.resistance_ohm,
            _ => 0.0,
        };
        let g_src = 1.0 / link.resistance_ohm;
        let c = link.capacitance_f;
        // `C·dv/dt = u − g·v` with the source conducting or not: (g, u).
        let coefficients = |conducting: bool| {
            if conducting { (g_src + g_ch, g_src * source_v - i_dc_a) } else { (g_ch, -i_dc_a) }
        };
        // `t` s from `v`, the source conducting or not: the voltage then.
        let relax = |v: f64, conducting: bool, t: f64| {
            let (g, u) = coefficients(conducting);
            if g > 0.0 { u / g + (v - u / g) * (-g * t / c).exp() } else { v + t * u / c }
        };
        // When, from `v` over `t` s in that state, the bus reaches the source's voltage.
        let crossing = |v: f64, conducting: bool, t: f64| {
            let (g, u) = coefficients(conducting);
            let tc = if g > 0.0 {
                let end = u / g;
                -(c / g) * ((source_v - end) / (v - end)).ln()
            } else {
                c * (source_v - v) / u
            };
            (tc.is_finite() && tc > 0.0 && tc < t).then_some(tc)
        };
        let v0 = self.vdc_v;
        let v1 = match link.source {
            DcSource::Supply => relax(v0, true, ts),
            DcSource::Rectifier => {
                let conducting = v0 < source_v;
                let v = relax(v0, conducting, ts);
                // Crossed the source's voltage within the period: the diodes switched there.
                if (v < source_v) != conducting
                    && let Some(tc) = crossing(v0, conducting, ts)
                {
                    relax(source_v, !conducting, ts - tc)
                } else {
                    v
                }
            }
        };
        self.vdc_v = v1;
        // Mean currents from the charge balance (the chopper's on the mean voltage).
        let i_ch = g_ch * 0.5 * (v0 + v1);
        let i_src = c * (v1 - v0) / ts + i_dc_a + i_ch;
        let i_src = match link.source {
            DcSource::Supply => i_src,
            DcSource::Rectifier => i_src.max(0.0), // the balance's rounding, not a reverse current
        };
        (i_src, i_ch)
    }
}

/// A closed-loop run.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Events `(t_s, event)`, in time order.
    pub events: Vec<(f64, Event)>,
    /// Simulated time, s.
    pub duration_s: f64,
    /// DC-bus voltage, V.
    pub vdc_v: f64,
    /// RK4 sub-steps per PWM period.
    pub substeps: u32,
    /// Trace decimation: one row every `trace_every` PWM periods.
    pub trace_every: u32,
    /// Sensor non-idealities.
    pub sensors: SensorModel,
    /// Load model.
    pub load: LoadModel,
    /// Inverter model.
    pub inverter: InverterModel,
    /// DC link (`None`: a stiff bus at `vdc_v`).
    pub dc_link: Option<DcLink>,
    /// The power board's hardware overcurrent comparator (`None`: not modelled).
    pub comparator: Option<Comparator>,
}

/// A validated open-loop scenario.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpenLoop {
    /// Simulated time, s.
    pub duration_s: f64,
    /// Trace sample period, s.
    pub sample_period_s: f64,
    /// Motor.
    pub motor: MotorParams,
    /// Phase peak voltage, V.
    pub amplitude_v: f64,
    /// Source frequency, Hz.
    pub frequency_hz: f64,
    /// Load torque, N·m.
    pub load_nm: f64,
}

/// One trace row.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Row {
    /// Time, s.
    pub t_s: f64,
    /// Plant state.
    pub x: MachineState,
    /// Electromagnetic torque, N·m.
    pub torque_nm: f64,
    /// Applied stator voltage, V.
    pub v_ab_v: [f64; 2],
    /// Current references, A.
    pub i_ref_ab_a: [f64; 2],
    /// Speed reference, rad/s.
    pub omega_ref_rad_s: f64,
    /// Load torque, N·m.
    pub load_nm: f64,
    /// The drive's mode after this period's step (`None` in open-loop runs).
    pub mode: Option<Mode>,
    /// Duties the drive decided for the next period (`None`: bridge off).
    pub duty: Option<[f64; 3]>,
    /// DC-bus voltage, V.
    pub vdc_v: f64,
    /// The drive's rotor-flux estimate, Wb.
    pub psi_est_wb: f64,
    /// The drive's rotor-flux reference, Wb.
    pub psi_ref_wb: f64,
    /// The rotor resistance the drive's field orientation runs on, × the motor file's.
    pub rr_scale: f64,
    /// The inductances the drive's field orientation runs on, × the motor file's.
    pub l_scale: f64,
    /// Current the inverter draws from the DC link during this period, A (negative:
    /// regeneration into the link).
    pub i_dc_a: f64,
    /// Current from the source into the link, A.
    pub i_source_a: f64,
    /// Current through the brake chopper's resistor, A.
    pub i_chopper_a: f64,
    /// The drive's brake output after this period's step (it switches the chopper in the
    /// next period).
    pub brake: bool,
    /// Largest |leg current| in this period, A (0 unless the comparator or a short is
    /// modelled: then the legs are resolved within the period, [`crate::bridge_fault`]).
    pub i_leg_peak_a: f64,
    /// The hardware comparator has broken the bridge (MOE cleared, latched).
    pub hw_break: bool,
    /// Largest stator current magnitude |i_s| (αβ) at the periods' (the open loop: the RK4
    /// steps') boundaries since the previous row, this row's included, A: a trace thinned
    /// to every n-th period keeps its peak (the summary's peak was the thinned rows': 0.955
    /// against 0.984 A at 1 ms sampling — found by trying).
    pub i_peak_a: f64,
    /// A switch stuck open mattered in this period: its direction of current was needed
    /// and the duty it would have switched (at least [`SWITCH_ACTING_DUTY`]) went through
    /// the opposite diode instead.
    pub switch_acting: bool,
}

/// The least part of a period a stuck-open switch must have been asked to conduct for the
/// period to count as one where it mattered ([`Row::switch_acting`]).
pub const SWITCH_ACTING_DUTY: f64 = 0.02;

/// The plant's side of one period in [`run`].
enum Period {
    /// Average inverter: the held stator voltage and the step begun with it.
    Average([f64; 2], Rk4Midway),
    /// Switching inverter: the duties whose segments the plant integrates.
    Switching([f64; 3]),
    /// All six switches off: the freewheeling diodes ([`integrate_bridge_off`]).
    Off,
}

/// RK4 steps per PWM period while the bridge is off (10 µs at 20 kHz): the diodes stop
/// conducting at a current zero, which the step locates to within one step.
pub const BRIDGE_OFF_SUBSTEPS: u32 = 5;

/// The phase axes a, b, c in the αβ plane, scaled so that the projection of the current
/// vector on an axis is that phase's current (amplitude-invariant Clarke).
const PHASE_AXES: [(f64, f64); 3] =
    [(1.0, 0.0), (-0.5, 0.866_025_403_784_438_6), (-0.5, -0.866_025_403_784_438_6)];

/// A phase current below this is zero: its diodes block, A.
const DIODE_ZERO_A: f64 = 1e-9;

/// The bridge with all six switches off, over one period: the freewheeling diodes, in
/// [`BRIDGE_OFF_SUBSTEPS`] RK4 steps. A phase whose current flows out of the bridge
/// (`i_x > 0`) conducts through its lower diode and sits at `−V_dc/2`; one flowing in,
/// through its upper diode, at `+V_dc/2`. Driven by the bus, the currents die out — within
/// about a millisecond on the DeLorenzo motor — and a phase whose current reaches zero opens
/// (its diodes block): its current is held at zero by projecting the current vector off that
/// phase's axis after each step (all three, when two are open: the currents sum to zero).
///
/// An open phase's terminal follows the machine: with `e` the open-circuit back-EMF of the
/// rotor flux per phase ([`Machine::open_circuit_voltage`]), all three open sit at `e`; with
/// two conducting at ±V_dc/2, the open one at `1.5·e_x` (its current and its derivative zero,
/// the star point between). When that exceeds the bus, diodes conduct again — the motor
/// *regenerates* into the bus while its line back-EMF is above V_dc: from all open, the pair
/// of phases with the largest line EMF, once it exceeds V_dc; with two conducting, the third
/// once `|1.5·e_x|` exceeds V_dc/2 (test `a_trip_above_the_bus_regenerates_until_the_emf_is_down`).
/// Returns the state and the period-average αβ voltage.
fn integrate_bridge_off(
    machine: &Machine,
    rk4: &plant::Rk4,
    x: &MachineState,
    vdc_v: f64,
    load_nm: f64,
) -> (MachineState, [f64; 2]) {
    let phase = |x: &MachineState, (ux, uy): (f64, f64)| x.i_alpha_a * ux + x.i_beta_a * uy;
    let half = 0.5 * vdc_v;
    let mut x = *x;
    let mut v_sum = [0.0; 2];
    for _ in 0..BRIDGE_OFF_SUBSTEPS {
        let before = PHASE_AXES.map(|u| phase(&x, u));
        // Each phase's diode: +1 upper (at +V_dc/2, current into the bridge), −1 lower, 0 open.
        let mut diode = before.map(|i| if i.abs() < DIODE_ZERO_A { 0.0 } else { -i.signum() });
        let e = {
            let [a, b] = machine.open_circuit_voltage(&x);
            let e = AlphaBeta { alpha: a, beta: b }.inverse_clarke();
            [e.a, e.b, e.c]
        };
        let conducting = |d: &[f64; 3]| d.iter().filter(|d| **d != 0.0).count();
        match conducting(&diode) {
            0 => {
                let hi = (0..3).fold(0, |m, p| if e[p] > e[m] { p } else { m });
                let lo = (0..3).fold(0, |m, p| if e[p] < e[m] { p } else { m });
                if e[hi] - e[lo] > vdc_v {
                    (diode[hi], diode[lo]) = (1.0, -1.0);
                }
            }
            2 => {
                let open = diode.iter().position(|d| *d == 0.0).unwrap_or(0);
                if (1.5 * e[open]).abs() > half {
                    diode[open] = e[open].signum();
                }
            }
            _ => {}
        }
        let two = conducting(&diode) == 2;
        let v_abc: [f64; 3] = std::array::from_fn(|p| match diode[p] {
            0.0 if two => 1.5 * e[p],
            0.0 => e[p],
            d => d * half,
        });
        let [a, b, c] = v_abc;
        let v = Abc { a, b, c }.clarke();
        let v = [v.alpha, v.beta];
        x = rk4.step(&x, v, load_nm);
        v_sum[0] += v[0];
        v_sum[1] += v[1];
        // Open: its diodes block (no diode chosen), or its current ended the step at or past
        // zero, against its diode's direction.
        let open = [0, 1, 2].map(|p| diode[p] == 0.0 || phase(&x, PHASE_AXES[p]) * diode[p] >= 0.0);
        match open.iter().filter(|o| **o).count() {
            0 => {}
            1 => {
                let p = open.iter().position(|o| *o).unwrap_or(0);
                let (ux, uy) = PHASE_AXES[p];
                let along = phase(&x, PHASE_AXES[p]);
                x.i_alpha_a -= along * ux;
                x.i_beta_a -= along * uy;
            }
            _ => {
                x.i_alpha_a = 0.0;
                x.i_beta_a = 0.0;
            }
        }
    }
    let n = f64::from(BRIDGE_OFF_SUBSTEPS);
    (x, [v_sum[0] / n, v_sum[1] / n])
}

/// The plant over the voltage segments of one switching period, each in equal RK4 steps of
/// at most `h_max_s`. Kept out of [`run`]: inlined there, it slowed the average-inverter
/// loop by ≈ 3 ns per period (`hil-sim bench`).
#[inline(never)]
fn integrate_segments(
    machine: &Machine,
    x: &MachineState,
    segments: &Segments,
    h_max_s: f64,
    load_nm: f64,
) -> MachineState {
    let mut x = *x;
    for &(dt, v) in segments.as_slice() {
        let n_sub = (dt / h_max_s).ceil().max(1.0);
        let rk4 = machine.rk4_stepper(dt / n_sub);
        for _ in 0..n_sub as u32 {
            x = rk4.step(&x, v, load_nm);
        }
    }
    x
}

/// Run `scenario` with `drive` (already configured) on `machine`; `pwm_hz` is the drive's
/// fast rate. Each trace row goes to `sink` as it is made (a long run streams to disk; an
/// error from the sink — a full disk, an interrupt — stops the run with that error). Calls
/// `progress(fraction)` now and then. A plant state that is no longer finite (a diverging
/// run) stops the run with an error at the first trace row that shows it. Returns the
/// number of rows.
///
/// Never inlined: on its own, the loop keeps more of its state in registers than inlined
/// into the CLI's `main` (measured with `hil-sim bench`).
#[inline(never)]
pub fn run(
    drive: &mut impl DriveUnderTest,
    machine: &Machine,
    pwm_hz: f64,
    sc: &Scenario,
    mut progress: impl FnMut(f64),
    mut sink: impl FnMut(&Row) -> Result<(), String>,
) -> Result<u64, String> {
    let ts = 1.0 / pwm_hz;
    let divider = u64::from(drive.slow_divider());
    let mut sensors =
        Sensors::new(sc.sensors, ts * divider as f64).map_err(|e| format!("encoder model: {e:?}"))?;
    let loaded = match sc.load {
        LoadModel::Torque => *machine,
        LoadModel::EddyBrake { k_nm_s_rad } => machine.with_eddy_brake(k_nm_s_rad),
        LoadModel::LockedRotor | LoadModel::Dynamometer { .. } => machine.speed_locked(),
        LoadModel::CoulombFriction { friction_nm } => machine.with_coulomb_friction(friction_nm),
    };
    // The machine as it is now (a load seizure or a parameter change rebuilds it).
    let mut machine = loaded;
    let substeps = sc.substeps.max(1);
    let h = ts / f64::from(substeps);
    check_rk4_step(&machine, sc, h)?;
    let mut rk4 = machine.rk4_stepper(h);
    let mut rk4_off = machine.rk4_stepper(ts / f64::from(BRIDGE_OFF_SUBSTEPS));
    let n = (sc.duration_s / ts).round() as u64;
    let trace_every = sc.trace_every.max(1);
    let mut x = MachineState::default();
    if let LoadModel::Dynamometer { omega_m_rad_s } = sc.load {
        x.omega_m_rad_s = omega_m_rad_s;
    }
    let mut load = 0.0;
    // Duties applied during the present period (computed in the previous one). A bridge
    // that is off applies ≈ 0 V in the average model: the same as duties of ½.
    let (mut duty_applied, mut bridge_on, mut brake_applied) = ([0.5; 3], false, false);
    // The legs within the period (a short, the comparator): resolved only when modelled.
    let mut legs = Legs::default();
    let mut legs_modelled = sc.comparator.is_some();
    // A switch stuck open: (phase, upper).
    let mut switch_open: Option<(usize, bool)> = None;
    // Low-side shunts: the highest duty that leaves a phase its sampling window (above 1:
    // none needed), and the duties of the period before the present one (bridge off: none).
    let sensed_duty_max = 1.0 - 2.0 * sc.sensors.low_side_window_s.unwrap_or(0.0) * pwm_hz;
    // The drive's limit is the same number in f32: its rounding is no lost window.
    const DUTY_TOLERANCE: f64 = 1e-6;
    let mut duty_before: Option<[f64; 3]> = None;
    let mut events = sc.events.iter().peekable();
    let first_period_of = |e: Option<&&(f64, Event)>| e.map_or(u64::MAX, |(te, _)| first_period_at(*te, ts));
    let mut next_event_k = first_period_of(events.peek());
    let mut rows = 0u64;
    // The largest |i_s|² since the last row ([`Row::i_peak_a`]).
    let mut peak2_since_row = 0.0f64;
    // Countdowns instead of `k % m`: the loop body is a few tens of nanoseconds.
    let (mut to_slow, mut to_trace, mut to_progress) = (0, 0, 0);
    // A stiff bus (no DC link model) is measured once, until a bus fault; with a link model
    // the bus follows the link every period, and a bus fault changes the source.
    let mut vdc_v = sc.vdc_v;
    let mut vdc_measured_v = sensors.vdc(vdc_v);
    let mut source_v = sc.vdc_v;
    let mut link_state = LinkState { vdc_v: sc.vdc_v };
    // An open lead's axis: its current is held at zero after every plant step.
    let mut open_phase: Option<(f64, f64)> = None;
    for k in 0..n {
        if k >= next_event_k {
            let t = k as f64 * ts;
            while let Some((_, e)) = events.next_if(|(te, _)| *te <= t) {
                match *e {
                    Event::Enable => drive.enable()?,
                    Event::Reference(r) => drive.set_reference(r)?,
                    Event::Stop => drive.controlled_stop()?,
                    Event::LoadNm(l) => load = l,
                    Event::Fault(Injection::CurrentSensor { phase, gain, offset_a }) => {
                        sensors.fail_current_channel(phase, gain, offset_a);
                    }
                    Event::Fault(Injection::CurrentChannelsSwapped { first, second }) => {
                        sensors.swap_current_channels(first, second)
                    }
                    Event::Fault(Injection::EncoderStuck) => sensors.freeze_encoder(),
                    Event::Fault(Injection::EncoderReversed) => sensors.reverse_encoder(x.theta_m_rad),
                    Event::Fault(Injection::EncoderGlitch { counts }) => sensors.glitch_encoder(counts),
                    Event::Fault(Injection::EncoderLines { lines }) => {
                        sensors.change_encoder_lines(lines, x.theta_m_rad)
                    }
                    Event::Fault(Injection::BusVoltage { vdc_v: v }) => {
                        if sc.dc_link.is_some() {
                            source_v = v;
                        } else {
                            vdc_v = v;
                            vdc_measured_v = sensors.vdc(v);
                        }
                    }
                    Event::Fault(Injection::SwitchOpen { phase, upper }) => {
                        switch_open = Some((phase.min(2), upper));
                    }
                    Event::Fault(Injection::PhaseShort(short)) => {
                        legs.short = Some((short, 0.0));
                        legs_modelled = true;
                    }
                    Event::Fault(Injection::SwitchShort(s)) => {
                        legs.shoot = Some((SwitchShort { phase: s.phase.min(2), ..s }, 0.0));
                        legs_modelled = true;
                    }
                    Event::Fault(Injection::OpenPhase { phase }) => {
                        open_phase = PHASE_AXES.get(phase).copied()
                    }
                    Event::Fault(Injection::LoadStep { torque_nm }) => load = torque_nm,
                    Event::Fault(Injection::LoadSeizure { torque_nm }) => {
                        machine = machine.with_coulomb_friction(torque_nm);
                        rk4 = machine.rk4_stepper(h);
                        rk4_off = machine.rk4_stepper(ts / f64::from(BRIDGE_OFF_SUBSTEPS));
                    }
                    Event::Fault(Injection::Plant { motor }) => {
                        machine = machine.with_electrical(&motor);
                        rk4 = machine.rk4_stepper(h);
                        rk4_off = machine.rk4_stepper(ts / f64::from(BRIDGE_OFF_SUBSTEPS));
                    }
                }
            }
            next_event_k = first_period_of(events.peek());
        }
        // True phase currents (controller-core's inverse Clarke, in f64).
        let i = AlphaBeta { alpha: x.i_alpha_a, beta: x.i_beta_a }.inverse_clarke();
        let i_true = [i.a, i.b, i.c];
        // A phase without a window in the period before the sample or the one after it reads
        // no current.
        let mask = |d: &[f64; 3]| {
            d.iter()
                .enumerate()
                .fold(0u8, |m, (k, &x)| m | (u8::from(x > sensed_duty_max + DUTY_TOLERANCE) << k))
        };
        let unsampled = if sensed_duty_max < 1.0 {
            duty_before.as_ref().map_or(0, mask) | if bridge_on { mask(&duty_applied) } else { 0 }
        } else {
            0
        };
        let i_abc =
            sensors.currents_sampled(if legs_modelled { legs.currents(i_true) } else { i_true }, unsampled);
        if legs.broken {
            // The firmware finds the break flag in its next interrupt; the bridge is off.
            drive.hardware_break()?;
            bridge_on = false;
        }
        let enc = if to_slow == 0 {
            to_slow = divider.saturating_sub(1);
            sensors.encoder_read(x.theta_m_rad, x.omega_m_rad_s)
        } else {
            to_slow -= 1;
            sensors.encoder_held()
        };
        let m = Measurements {
            i_abc_a: i_abc,
            vdc_v: vdc_measured_v,
            omega_m_rad_s: enc.omega_m_rad_s,
            theta_m_rad: enc.theta_m_rad,
        };
        // The plant's period k sees the duties decided one period ago (bridge off: all ½,
        // ≈ 0 V); the drive's step k acts in period k + 1. The two do not wait on each other,
        // so with the average inverter the plant's first RK4 stages are issued before the
        // drive's step: the processor then runs both dependent chains side by side.
        let x_at_start = x;
        peak2_since_row = peak2_since_row.max(x.i_alpha_a * x.i_alpha_a + x.i_beta_a * x.i_beta_a);
        let mut switch_acting = false;
        if let Some((p, upper)) = switch_open
            && bridge_on
        {
            // The dead switch's direction of current flows through the opposite diode.
            let before = duty_applied[p];
            match (upper, i_true[p] > 0.0) {
                (true, true) => duty_applied[p] = 0.0,
                (false, false) => duty_applied[p] = 1.0,
                _ => {}
            }
            switch_acting = (duty_applied[p] - before).abs() >= SWITCH_ACTING_DUTY;
        }
        let period = match sc.inverter {
            _ if !bridge_on => Period::Off,
            InverterModel::Switching { .. } => Period::Switching(duty_applied),
            InverterModel::Average => {
                let v = InverterModel::average_voltage(duty_applied, vdc_v);
                Period::Average(v, rk4.begin_step(&x, v, load))
            }
        };
        let out = drive.step(&m);
        if let Some(e) = drive.take_failure() {
            return Err(e);
        }
        let v_avg = match period {
            Period::Average(v, midway) => {
                x = midway.finish(&rk4);
                for _ in 1..substeps {
                    x = rk4.step(&x, v, load);
                }
                v
            }
            Period::Off => {
                let (next, v) = integrate_bridge_off(&machine, &rk4_off, &x, vdc_v, load);
                x = next;
                v
            }
            Period::Switching(d) => {
                let segments = sc.inverter.segments(d, i_true, vdc_v, ts);
                x = integrate_segments(&machine, &x, &segments, h, load);
                segments.average()
            }
        };
        if let Some((ux, uy)) = open_phase {
            let along = x.i_alpha_a * ux + x.i_beta_a * uy;
            x.i_alpha_a -= along * ux;
            x.i_beta_a -= along * uy;
        }
        let mut leg_period = crate::bridge_fault::LegPeriod::default();
        if legs_modelled {
            let end = AlphaBeta { alpha: x.i_alpha_a, beta: x.i_beta_a }.inverse_clarke();
            let pole = bridge_on.then(|| duty_applied.map(|d| (d - 0.5) * vdc_v));
            leg_period = legs.period(sc.comparator.as_ref(), i_true, [end.a, end.b, end.c], pole, vdc_v, ts);
        }
        let vdc_period_v = vdc_v;
        let (mut i_dc, mut i_src, mut i_ch) = (0.0, 0.0, 0.0);
        if let Some(link) = &sc.dc_link {
            i_dc = if bridge_on {
                duty_applied.iter().zip(i_true).map(|(d, i)| d * i).sum()
            } else {
                i_true.iter().map(|i| i.min(0.0)).sum()
            };
            (i_src, i_ch) = link_state.step(link, source_v, i_dc, brake_applied, ts);
            vdc_v = link_state.vdc_v;
            vdc_measured_v = sensors.vdc(vdc_v);
        }
        if to_trace == 0 {
            to_trace = trace_every - 1;
            if !x_at_start.is_finite() {
                return Err(non_finite(k as f64 * ts));
            }
            rows += 1;
            let telemetry = drive.telemetry();
            sink(&Row {
                t_s: k as f64 * ts,
                x: x_at_start,
                torque_nm: machine.torque_nm(&x_at_start),
                v_ab_v: v_avg,
                i_ref_ab_a: [f64::from(telemetry.i_ref_ab_a.alpha), f64::from(telemetry.i_ref_ab_a.beta)],
                omega_ref_rad_s: f64::from(telemetry.omega_ref_rad_s),
                load_nm: load,
                mode: Some(out.mode),
                duty: match out.phases {
                    PhaseCommand::Off => None,
                    PhaseCommand::Duty(d) => Some([f64::from(d.a), f64::from(d.b), f64::from(d.c)]),
                },
                vdc_v: vdc_period_v,
                i_dc_a: i_dc,
                i_source_a: i_src,
                i_chopper_a: i_ch,
                brake: out.brake,
                i_leg_peak_a: leg_period.peak_a,
                hw_break: legs.broken,
                i_peak_a: core::mem::take(&mut peak2_since_row).sqrt(),
                switch_acting,
                psi_est_wb: f64::from(telemetry.psi_r_wb),
                psi_ref_wb: f64::from(telemetry.psi_ref_wb),
                rr_scale: f64::from(telemetry.rr_scale),
                l_scale: f64::from(telemetry.l_scale),
            })?;
        } else {
            to_trace -= 1;
        }
        // Duties (and the brake) computed now act during the next period.
        duty_before = bridge_on.then_some(duty_applied);
        brake_applied = out.brake;
        (duty_applied, bridge_on) = match out.phases {
            PhaseCommand::Off => ([0.5; 3], false),
            PhaseCommand::Duty(d) => ([f64::from(d.a), f64::from(d.b), f64::from(d.c)], true),
        };
        if to_progress == 0 {
            to_progress = 1999;
            progress(k as f64 / n as f64);
            if drive.finished() {
                break;
            }
        } else {
            to_progress -= 1;
        }
    }
    progress(1.0);
    Ok(rows)
}

fn non_finite(t_s: f64) -> String {
    format!("the simulated machine's state is no longer finite at t = {t_s} s (the run diverged)")
}

/// [`run`] keeping every row in memory (tests, short runs).
pub fn run_collect(
    drive: &mut impl DriveUnderTest,
    machine: &Machine,
    pwm_hz: f64,
    sc: &Scenario,
    progress: impl FnMut(f64),
) -> Result<Vec<Row>, String> {
    let mut rows = Vec::new();
    run(drive, machine, pwm_hz, sc, progress, |r| {
        rows.push(*r);
        Ok(())
    })?;
    Ok(rows)
}

/// The first period k whose start `k·ts_s` is at or after `t_s` (the same floating-point
/// comparison the event loop makes); `u64::MAX` when there is none in range. Lets [`run`]
/// compare period indices instead of converting every k to a time.
fn first_period_at(t_s: f64, ts_s: f64) -> u64 {
    let at = |k: u64| k as f64 * ts_s;
    let periods = t_s / ts_s;
    if periods.is_nan() || periods >= 1e15 {
        return u64::MAX;
    }
    // The quotient is within a few units of the answer; settle it with the comparison itself.
    let mut k = periods.floor().max(0.0) as u64;
    while k > 0 && at(k - 1) >= t_s {
        k -= 1;
    }
    while at(k) < t_s {
        k += 1;
    }
    k
}

/// Largest RK4 step used for open-loop runs, s. The step-size study
/// (`open_loop_step_convergence` in the tests) shows the trace error at this step.
pub const OPEN_LOOP_MAX_STEP_S: f64 = 1e-5;

/// The largest `rate·h` a run's RK4 step may take ([`plant::Machine::fastest_rate_per_s`]):
/// below RK4's 2.785 on the negative real axis, with a margin.
pub const RK4_RATE_STEP_MAX: f64 = 2.5;

/// The RK4 step `h` is stable on the scenario's machine, and on every machine a parameter
/// step injects. A stiffer machine diverged — or, worse, oscillated into a fault the motor
/// never had: R_s = 10 kΩ (which the motor file accepts) ran on 50 µs steps into
/// `Overcurrent` at 813 A with exit 0 (found by trying).
fn check_rk4_step(machine: &Machine, sc: &Scenario, h: f64) -> Result<(), String> {
    let injected = sc.events.iter().filter_map(|(_, e)| match e {
        Event::Fault(Injection::Plant { motor }) => Some(Machine::new(motor).fastest_rate_per_s()),
        _ => None,
    });
    let rate = injected.fold(machine.fastest_rate_per_s(), f64::max);
    if rate.is_finite() && rate * h <= RK4_RATE_STEP_MAX {
        return Ok(());
    }
    let needed = (rate * h * f64::from(sc.substeps.max(1)) / RK4_RATE_STEP_MAX).ceil();
    Err(format!(
        "the simulated machine is too stiff for the integration step: its fastest electrical mode decays at \
         {rate:.4e} 1/s, and the RK4 step of {h:.3e} s makes rate·step = {:.2} (stable below {RK4_RATE_STEP_MAX}); \
         set rk4_substeps = {needed} or more in the scenario, or check the motor's R_s, R_r and inductances",
        rate * h
    ))
}

/// The most RK4 steps an open-loop run takes per trace sample: a machine stiffer than that
/// (a 0.2 ns stator time constant wanted millions) is refused rather than integrated for
/// minutes.
pub const OPEN_LOOP_SUBSTEPS_MAX: f64 = 10_000.0;

/// Open-loop run: the machine fed by an ideal balanced sine source, for validating the
/// plant alone. One row per `sample_period_s` to `sink` (as in [`run`]); the RK4 step
/// divides the sample period into equal steps of at most `max_step_s`, and small enough for
/// the machine's fastest mode ([`RK4_RATE_STEP_MAX`]). Returns the number of rows.
pub fn run_open_loop(
    sc: &OpenLoop,
    max_step_s: f64,
    mut progress: impl FnMut(f64),
    mut sink: impl FnMut(&Row) -> Result<(), String>,
) -> Result<u64, String> {
    let machine = Machine::new(&sc.motor);
    let w = 2.0 * std::f64::consts::PI * sc.frequency_hz;
    let amp = sc.amplitude_v;
    let source = move |t: f64| [amp * (w * t).cos(), amp * (w * t).sin()];
    // At most `max_step_s`, and stable on this machine's fastest mode (`RK4_RATE_STEP_MAX`).
    let stable_step_s = RK4_RATE_STEP_MAX / machine.fastest_rate_per_s();
    let substeps = (sc.sample_period_s / max_step_s.min(stable_step_s)).ceil().max(1.0);
    if substeps.is_nan() || substeps > OPEN_LOOP_SUBSTEPS_MAX {
        return Err(format!(
            "the simulated machine is too stiff to integrate: its fastest electrical mode decays at {:.4e} 1/s, \
             which needs {substeps:.3e} RK4 steps per sample (at most {OPEN_LOOP_SUBSTEPS_MAX}); check the motor's \
             R_s, R_r and inductances",
            machine.fastest_rate_per_s()
        ));
    }
    let h = sc.sample_period_s / substeps;
    let n = (sc.duration_s / sc.sample_period_s).round() as u64;
    let mut x = MachineState::default();
    let row = |t: f64, x: MachineState, peak2: f64| Row {
        t_s: t,
        x,
        torque_nm: machine.torque_nm(&x),
        v_ab_v: source(t),
        load_nm: sc.load_nm,
        i_peak_a: peak2.sqrt(),
        ..Row::default()
    };
    let magnitude2 = |x: &MachineState| x.i_alpha_a * x.i_alpha_a + x.i_beta_a * x.i_beta_a;
    let mut peak2 = 0.0f64;
    for k in 0..=n {
        let t0 = k as f64 * sc.sample_period_s;
        if !x.is_finite() {
            return Err(non_finite(t0));
        }
        sink(&row(t0, x, peak2.max(magnitude2(&x))))?;
        if k == n {
            break;
        }
        peak2 = 0.0;
        for j in 0..substeps as u64 {
            x = machine.rk4_source(&x, t0 + j as f64 * h, h, source, sc.load_nm);
            peak2 = peak2.max(magnitude2(&x));
        }
        if k % 1000 == 0 {
            progress(k as f64 / n as f64);
        }
    }
    progress(1.0);
    Ok(n + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use OpenLoop;
    use controller_core::motor::MotorParams;

    /// `first_period_at` is the smallest k with `k·ts ≥ t` in floating point — checked against
    /// that definition by search, at event times on, just beside and between period starts.
    #[test]
    fn first_period_at_matches_the_event_comparison() {
        let ts = 1.0 / 20_000.0;
        let brute = |t: f64| (0u64..).find(|&k| k as f64 * ts >= t).unwrap();
        let mut times = vec![0.0, -1.0, 0.3, 1.5, 2.5, 3.5, 1e-9, ts, 2.0 * ts];
        for k in [1u64, 7, 6000, 29_999, 30_000, 70_000] {
            let t = k as f64 * ts;
            times.extend([t, t.next_up(), t.next_down(), t + 0.5 * ts]);
        }
        for t in times {
            assert_eq!(first_period_at(t, ts), brute(t), "t = {t:e}");
        }
        assert_eq!(first_period_at(f64::INFINITY, ts), u64::MAX);
        assert_eq!(first_period_at(f64::NAN, ts), u64::MAX);
    }

    fn dol(max_step: f64) -> Vec<Row> {
        let sc = OpenLoop {
            duration_s: 0.5,
            sample_period_s: 1e-3,
            motor: MotorParams::delorenzo_dl10115a1().unwrap(),
            amplitude_v: 180.0,
            frequency_hz: 50.0,
            load_nm: 0.2,
        };
        let mut rows = Vec::new();
        run_open_loop(
            &sc,
            max_step,
            |_| {},
            |r| {
                rows.push(*r);
                Ok(())
            },
        )
        .unwrap();
        rows
    }

    /// Step-size study of the chosen open-loop step (10 µs) against a 16× finer step
    /// (0.625 µs) over a 0.5 s direct-on-line start: RK4 is 4th order, so the error of
    /// the 10 µs trace is ≈ 16/15 of the difference. Printed and asserted.
    #[test]
    fn open_loop_step_convergence() {
        let (coarse, fine) = (dol(OPEN_LOOP_MAX_STEP_S), dol(OPEN_LOOP_MAX_STEP_S / 16.0));
        let mut max_di: f64 = 0.0;
        let mut max_dw: f64 = 0.0;
        for (a, b) in coarse.iter().zip(&fine) {
            max_di =
                max_di.max((a.x.i_alpha_a - b.x.i_alpha_a).abs().max((a.x.i_beta_a - b.x.i_beta_a).abs()));
            max_dw = max_dw.max((a.x.omega_m_rad_s - b.x.omega_m_rad_s).abs());
        }
        let peak_i = fine.iter().map(|r| r.x.i_alpha_a.abs()).fold(0.0, f64::max);
        eprintln!(
            "RK4 10 µs vs 0.625 µs: max |Δi| {max_di:.2e} A (peak {peak_i:.2} A), max |Δω| {max_dw:.2e} rad/s"
        );
        assert!(max_di < 1e-8 * peak_i.max(1.0));
        assert!(max_dw < 1e-8);
    }

    /// The in-process drive, whose link breaks at its `fail_at`-th step (a PIL target dying).
    struct Breaks {
        drive: Drive,
        steps: u64,
        fail_at: u64,
        failure: Option<String>,
    }

    impl DriveUnderTest for Breaks {
        fn slow_divider(&self) -> u16 {
            self.drive.slow_divider()
        }
        fn enable(&mut self) -> Result<(), String> {
            DriveUnderTest::enable(&mut self.drive)
        }
        fn set_reference(&mut self, r: Reference) -> Result<(), String> {
            DriveUnderTest::set_reference(&mut self.drive, r)
        }
        fn controlled_stop(&mut self) -> Result<(), String> {
            DriveUnderTest::controlled_stop(&mut self.drive)
        }
        fn step(&mut self, m: &Measurements) -> FastOutput {
            self.steps += 1;
            let out = DriveUnderTest::step(&mut self.drive, m);
            if self.steps == self.fail_at {
                self.failure = Some(format!("link broken at step {}", self.steps));
            }
            out
        }
        fn telemetry(&self) -> Telemetry {
            self.drive.telemetry()
        }
        fn take_failure(&mut self) -> Option<String> {
            self.failure.take()
        }
    }

    /// A failed step ends the run with its error at that step: no further step, no trace.
    #[test]
    fn failed_step_stops_the_run() {
        let b = crate::scenario::speed_step().unwrap();
        let drive = Drive::new(controller_core::drive::DriveConfig::new(&b.spec).unwrap());
        let mut dut = Breaks { drive, steps: 0, fail_at: 1000, failure: None };
        let r = run_collect(&mut dut, &Machine::new(&b.plant), b.spec.pwm_frequency_hz, &b.scenario, |_| {});
        assert_eq!(r, Err("link broken at step 1000".to_string()));
        assert_eq!(dut.steps, 1000);
    }
}
