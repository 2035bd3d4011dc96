//! Built-in scenarios: the papers' experiments, each starting from the shipped drive file
//! (`drive.toml`, [`drive_file::SHIPPED`]) and changing what the experiment changes.

use crate::inverter::InverterModel;
use crate::sensors::SensorModel;
use crate::sim::{self, Event, LoadModel, PassiveLoad, Row, Scenario};
use controller_core::current::CurrentLaw;
use controller_core::drive::{
    Control, CurrentFrame, Drive, DriveConfig, DriveSpec, Mode, PositionLaw, Reference, SlipCurrent,
    SpeedFeedback,
};
use controller_core::fault::Fault;
use controller_core::magnetics::Saturation;
use controller_core::motor::{MotorError, MotorParams};
use controller_core::speed::SpeedLaw;
use drive_file::{DriveFile, FileError};
use plant::Machine;

/// Why a built-in scenario could not be assembled (a bug in the shipped data, reported
/// rather than hidden).
#[derive(Debug, Clone, PartialEq)]
pub enum ScenarioError {
    /// Motor parameters rejected.
    Motor(MotorError),
    /// A shipped drive or motor file failed to parse or validate.
    File(FileError),
}

impl std::fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ScenarioError::Motor(e) => write!(f, "motor parameters rejected: {e:?}"),
            ScenarioError::File(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for ScenarioError {}

impl From<MotorError> for ScenarioError {
    fn from(e: MotorError) -> Self {
        ScenarioError::Motor(e)
    }
}

impl From<FileError> for ScenarioError {
    fn from(e: FileError) -> Self {
        ScenarioError::File(e)
    }
}

/// A named, runnable scenario with its drive.
#[derive(Clone, Debug)]
pub struct Builtin {
    /// Name used on the command line.
    pub name: String,
    /// One-line description.
    pub about: String,
    /// Drive specification (what the controller believes about the motor).
    pub spec: DriveSpec,
    /// The simulated machine (differs from `spec.motor` in perturbed-plant scenarios).
    pub plant: MotorParams,
    /// Its magnetizing branch's saturation (`plant` is then its form's T model).
    pub plant_saturation: Option<Saturation>,
    /// The fault the run is meant to end in (a scenario that tests a protection): then the
    /// run passes only if the drive latches it, and fails without it or with another.
    pub expect_fault: Option<Fault>,
    /// Events and timing.
    pub scenario: Scenario,
}

impl Builtin {
    /// Run the scenario: returns the trace and the drive's final mode.
    pub fn run(&self, progress: impl FnMut(f64)) -> Result<(Vec<Row>, Mode), String> {
        let mut rows = Vec::new();
        let mode = self.run_into(progress, |r| {
            rows.push(*r);
            Ok(())
        })?;
        Ok((rows, mode))
    }

    /// Run the scenario, each trace row to `sink` as it is made ([`sim::run`]); returns the
    /// drive's final mode.
    pub fn run_into(
        &self,
        progress: impl FnMut(f64),
        sink: impl FnMut(&Row) -> Result<(), String>,
    ) -> Result<Mode, String> {
        let cfg = DriveConfig::new(&self.spec).map_err(|e| format!("invalid drive specification: {e:?}"))?;
        let mut drive = Drive::new(cfg);
        self.simulate(&mut drive, progress, sink)?;
        Ok(drive.mode())
    }

    /// Run the scenario with the drive on the emulated MCU. Returns the trace and the link.
    pub fn run_pil(
        &self,
        opts: &crate::pil::PilOptions,
        progress: impl FnMut(f64),
    ) -> Result<(Vec<Row>, crate::pil::Pil), String> {
        let mut rows = Vec::new();
        let pil = self.run_pil_into(opts, progress, |r| {
            rows.push(*r);
            Ok(())
        })?;
        Ok((rows, pil))
    }

    /// [`Builtin::run_into`] with the drive on the emulated MCU; returns the link.
    pub fn run_pil_into(
        &self,
        opts: &crate::pil::PilOptions,
        progress: impl FnMut(f64),
        sink: impl FnMut(&Row) -> Result<(), String>,
    ) -> Result<crate::pil::Pil, String> {
        let mut pil = crate::pil::Pil::start(opts, &self.spec)?;
        self.simulate(&mut pil, progress, sink)?;
        Ok(pil)
    }

    /// Run the scenario against `dut` (a drive, a `Pil` prepared by the caller — e.g. with a
    /// capture armed); returns the periods run.
    pub fn simulate(
        &self,
        dut: &mut impl sim::DriveUnderTest,
        progress: impl FnMut(f64),
        sink: impl FnMut(&Row) -> Result<(), String>,
    ) -> Result<u64, String> {
        // The sensors sample in the board's window unless the scenario says otherwise.
        let mut sc = self.scenario.clone();
        sc.sensors.low_side_window_s.get_or_insert(self.spec.sample_window_s);
        let machine = plant_machine(&self.plant, self.plant_saturation.as_ref(), &sc.extras)?;
        sim::run(dut, &machine, self.spec.pwm_frequency_hz, &sc, progress, sink)
    }
}

/// A simulated machine other than the drive's own linear motor (`--plant`, a saturating
/// drive file's motor): its T model, its magnetizing branch's curve, and what the plant
/// has beyond them (iron loss, a deep bar; [`plant::Extras`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimulatedMotor {
    /// The T model (a saturating one's at its unsaturated inductance).
    pub motor: MotorParams,
    /// The magnetizing branch's curve.
    pub saturation: Option<Saturation>,
    /// Iron loss, a deep bar.
    pub extras: plant::Extras,
}

/// A motor file's plant extras as the plant takes them.
pub fn extras_of(e: &drive_file::motor::PlantExtras) -> plant::Extras {
    plant::Extras {
        iron_loss_ohm: e.iron_loss_ohm,
        deep_bar: e.deep_bar.map(|d| plant::DeepBar {
            high_slip_resistance_factor: d.high_slip_resistance_factor,
            corner_slip_hz: d.corner_slip_hz,
        }),
    }
}

/// The simulated machine: the motor `plant`, saturating when `saturation` is given, with
/// `extras` (iron loss, a deep bar: [`plant::saturated`] — a saturating machine must be in
/// the inverse-Γ form for them, a linear one takes them in its inverse-Γ equivalent).
pub(crate) fn plant_machine(
    plant: &MotorParams,
    saturation: Option<&Saturation>,
    extras: &plant::Extras,
) -> Result<Machine, String> {
    let why = |e: plant::saturated::SaturationError| format!("the simulated machine: {e}");
    let machine = match saturation {
        Some(s) => Machine::saturated(plant, s).map_err(why)?,
        None => Machine::new(plant),
    };
    machine.with_extras(extras).map_err(why)
}

/// IFOC speed step to 150 rad/s with the shipped drive (DeLorenzo motor, ICAD current loop
/// seed 002 eq. (20), saturated-P speed loop eq. (21)); 1 N·m load from 1.5 s to 2.5 s
/// (after seed 002 Fig. 13).
pub fn speed_step() -> Result<Builtin, ScenarioError> {
    let spec = DriveFile::shipped()?.spec;
    Ok(Builtin {
        name: "speed-step".into(),
        about: "IFOC + ICAD, speed step to 150 rad/s, 1 N·m load applied at 1.5 s and removed at 2.5 s"
            .into(),
        plant: spec.motor,
        plant_saturation: None,
        expect_fault: None,
        spec,
        scenario: Scenario {
            events: vec![
                (0.0, Event::Enable),
                (0.3, Event::Reference(Reference::Speed(150.0))),
                (1.5, Event::LoadNm(1.0)),
                (2.5, Event::LoadNm(0.0)),
            ],
            duration_s: 3.5,
            vdc_v: 310.0,
            // One RK4 step per PWM period is converged (tests/substeps.rs).
            substeps: 1,
            trace_every: 20,
            sensors: SensorModel::default(),
            load: LoadModel::Torque,
            inverter: InverterModel::Average,
            dc_link: None,
            comparator: None,
            heating: None,
            extras: plant::Extras::default(),
        },
    })
}

/// [`speed_step`] with realistic sensors ([`SensorModel::realistic`]: 12-bit current ADC
/// with offset, gain error and noise; 1024-line encoder) and an eddy-current brake of
/// 0.002 N·m·s/rad instead of the load steps.
pub fn speed_step_sensors() -> Result<Builtin, ScenarioError> {
    let mut b = speed_step()?;
    b.name = "speed-step-sensors".into();
    b.about = "speed-step with 12-bit ADC (offset, gain error, noise), 1024-line encoder, eddy-current brake"
        .into();
    b.scenario.events.retain(|(_, e)| !matches!(e, Event::LoadNm(_)));
    b.scenario.sensors = SensorModel::realistic(7);
    b.scenario.load = LoadModel::EddyBrake { k_nm_s_rad: 0.002 };
    Ok(b)
}

/// [`speed_step_sensors`] without an encoder: the drive's speed and field angle from the flux
/// and speed observer ([`SpeedFeedback::Sensorless`], docs/sensorless.md), the 1 N·m load
/// steps kept.
pub fn speed_step_sensorless() -> Result<Builtin, ScenarioError> {
    let mut b = speed_step()?;
    b.name = "speed-step-sensorless".into();
    b.about = "speed-step without an encoder (the flux and speed observer), 12-bit ADC with offset, gain error and noise"
        .into();
    b.spec.speed_feedback = SpeedFeedback::Sensorless;
    b.scenario.sensors = SensorModel::realistic(7);
    Ok(b)
}

/// drive.toml's base speed on its 310 V bus, rad/s (its `[requirements]` comment, printed by
/// `design certify drive.toml`): where [`vhz_fan`]'s fan takes its rated torque.
pub const SHIPPED_BASE_RAD_S: f64 = 196.0;

/// drive.toml as a V/Hz drive without an encoder (`control = { kind = "vhz" }`, the default
/// ramp and gains; docs/sensorless.md, "V/Hz") running a fan that takes 1 N·m at
/// [`SHIPPED_BASE_RAD_S`]: enabled at 0.12 s (after the idle stretch in which it reads its
/// current sensors' residual offsets), to base speed at 0.4 s, back to rest at 4 s; realistic
/// sensors, the switching inverter with the board's dead time.
pub fn vhz_fan() -> Result<Builtin, ScenarioError> {
    let mut b = speed_step()?;
    b.name = "vhz-fan".into();
    b.about = "V/Hz without an encoder: a fan (1 N·m at 196 rad/s) to base speed and back, realistic sensors"
        .into();
    let s = &mut b.spec;
    s.speed_feedback = SpeedFeedback::Sensorless;
    s.control = Control::VHz {
        ramp_rad_s2: controller_core::vhz::default_ramp_rad_s2(&s.motor, s.flux_ref_wb, s.i_ref_max_a),
        k_u: controller_core::vhz::K_U,
        k_w: controller_core::vhz::K_W,
    };
    let k_nm_s2 = 1.0 / (SHIPPED_BASE_RAD_S * SHIPPED_BASE_RAD_S);
    b.scenario.events = vec![
        (0.0, Event::Coupling(PassiveLoad::Fan { k_nm_s2 })),
        (0.12, Event::Enable),
        (0.4, Event::Reference(Reference::Speed(SHIPPED_BASE_RAD_S as f32))),
        (4.0, Event::Reference(Reference::Speed(0.0))),
    ];
    b.scenario.duration_s = 8.0;
    b.scenario.sensors = SensorModel::realistic(7);
    b.scenario.inverter = InverterModel::Switching { dead_time_s: b.spec.dead_time_compensation_s };
    Ok(b)
}

/// [`speed_step`] with the switching inverter model: centre-aligned carrier comparison at
/// 20 kHz and 1 µs dead time (the plant sees the switched voltage, not its average).
pub fn speed_step_switching() -> Result<Builtin, ScenarioError> {
    let mut b = speed_step()?;
    b.name = "speed-step-switching".into();
    b.about = "speed-step with a switching inverter (carrier comparison, 1 µs dead time)".into();
    b.scenario.inverter = InverterModel::Switching { dead_time_s: 1e-6 };
    Ok(b)
}

/// Seed 002 Fig. 11: locked rotor, α/β current references of 1 A at 300 rad/s, ICAD
/// controller eq. (20) at 20 kHz (after the flux build-up, from 0.3 s).
pub fn fig11_locked_rotor() -> Result<Builtin, ScenarioError> {
    let mut b = speed_step()?;
    b.name = "fig11-locked-rotor".into();
    b.about = "seed 002 Fig. 11: locked rotor, 1 A α/β current references at 300 rad/s, ICAD eq. (20)".into();
    b.scenario.events = vec![
        (0.0, Event::Enable),
        (0.3, Event::Reference(Reference::RotatingCurrent { amplitude_a: 1.0, omega_rad_s: 300.0 })),
    ];
    b.scenario.duration_s = 1.3;
    b.scenario.trace_every = 1;
    b.scenario.load = LoadModel::LockedRotor;
    Ok(b)
}

/// Seed 002 Fig. 23: Fig. 11's test on the perturbed plant of Sec. VIII (controller and its
/// IFOC configured for the nominal motor).
pub fn fig23_perturbed() -> Result<Builtin, ScenarioError> {
    let mut b = fig11_locked_rotor()?;
    b.name = "fig23-perturbed".into();
    b.about =
        "seed 002 Fig. 23: perturbed plant (Rs, Rr ×2; Ls, Lr ×0.6; Lm ×0.59), 1 A at 300 rad/s, ICAD".into();
    b.plant = drive_file::motor::load("delorenzo-perturbed")?;
    Ok(b)
}

/// Seed 002 Fig. 14: position step of 6.28 rad at 0.3 s, active load of 0.5 N·m from 2.5 s.
/// Position P loop (4 1/s, speed limit 50 rad/s) around a speed PI producing torque
/// (k_p = 0.1 N·m·s/rad, k_i = 0.5 N·m/rad, ±2 N·m): the speed loop's integral rejects the
/// load, so the position error returns to zero (the paper's gains are in its ref. \[25\];
/// these are ours, crossover ≈ k_p/J = 20 rad/s above the 4 1/s position loop).
// The paper's step is 6.28 rad as printed, not 2π.
#[allow(clippy::approx_constant)]
pub fn fig14_position() -> Result<Builtin, ScenarioError> {
    let mut b = speed_step()?;
    b.name = "fig14-position".into();
    b.about =
        "seed 002 Fig. 14: position step 6.28 rad, 0.5 N·m load from 2.5 s, ICAD + speed PI + position P"
            .into();
    b.spec.speed_law = SpeedLaw::PiTorque { kp: 0.1, ki: 0.5, limit: 2.0, setpoint_weight: 1.0 };
    b.spec.position = PositionLaw { k_per_s: 4.0, omega_max_rad_s: 50.0 };
    b.scenario.events = vec![
        (0.0, Event::Enable),
        (0.3, Event::Reference(Reference::Position(6.28))),
        (2.5, Event::LoadNm(0.5)),
    ];
    b.scenario.duration_s = 4.5;
    Ok(b)
}

/// Seed 002 Fig. 16: saturated-P speed loop eq. (21) (k_p = 0.05 N·m·s/rad,
/// τ_max = 0.4 N·m) to 376 rad/s with the current law `law`.
///
/// Voltage headroom decides the operating point: at 310 V the linear limit is
/// V_dc/√3 = 179 V, and with this machine's short T_r = 65 ms the slip ω_sl = i_q/(T_r·i_d)
/// is large, so ω_e = p·ω_m + ω_sl exceeds 376 rad/s. Steady-state dq voltages
/// v_d = R_s i_d − ω_e σL_s i_q, v_q = R_s i_q + ω_e L_s i_d at the top of the ramp give
/// |v| ≈ 167 V for ψ* = 0.35 Wb and τ_max = 0.4 N·m (i_d = 0.246 A, i_q = 0.805 A,
/// ω_sl = 50 rad/s). With ψ* = 0.4 Wb and τ_max = 1 N·m the voltage limit is reached near
/// 230 rad/s and the stationary ICAD loop loses control (docs/verification.md).
pub fn fig16(law: CurrentLaw, name: &str, about: &str) -> Result<Builtin, ScenarioError> {
    let mut b = speed_step()?;
    b.name = name.into();
    b.about = about.into();
    b.spec.current_law = law;
    b.spec.flux_ref_wb = 0.35;
    // The overspeed level, the stop time and the encoder jump level follow the flux reference
    // (drive_file's default rules).
    let vdc_max = b.spec.protection.vdc_max_v;
    b.spec.protection.overspeed_rad_s =
        drive_file::drive::default_overspeed_rad_s(&b.spec.motor, 0.35, vdc_max);
    b.spec.protection.stop_time_s = drive_file::drive::default_stop_time_s(&b.spec.motor, 0.35, vdc_max);
    b.spec.protection.encoder_jump_rad = drive_file::drive::default_encoder_jump_rad(
        &b.spec.motor,
        0.35,
        b.spec.i_ref_max_a,
        drive_file::drive::DEFAULT_ENCODER_LINES,
        f64::from(b.spec.slow_divider) / b.spec.pwm_frequency_hz,
    );
    // The paper's motor data alone: no I²t limits (the scenario file that embeds this drive,
    // hil-sim/scenarios/fig16-icad.toml, has no thermal data; a 6.5 s run is far below any).
    b.spec.protection.motor_thermal = None;
    b.spec.protection.inverter_thermal = None;
    b.spec.speed_law = SpeedLaw::SaturatedP { kp: 0.05, tau_max_nm: 0.4 };
    // The following window and the stall time follow the torque limit (and the stall time
    // the overspeed level: drive_file's default rules).
    let slow_period_s = f64::from(b.spec.slow_divider) / b.spec.pwm_frequency_hz;
    b.spec.protection.following_time_s = drive_file::drive::default_following_time_s(
        &b.spec.motor,
        0.4,
        drive_file::drive::DEFAULT_ENCODER_LINES,
        slow_period_s,
    );
    b.spec.protection.stall_time_s = drive_file::drive::default_stall_time_s(
        &b.spec.motor,
        0.4,
        b.spec.protection.overspeed_rad_s,
        slow_period_s,
    );
    // The paper's loops alone: the current trim would correct the stationary loops' tracking
    // error at ω_e — the very error this figure compares (the PI's reaches 366 rad/s with it).
    b.spec.current_trim_bandwidth_rad_s = 0.0;
    // The paper's current measurement: no low-side sampling window (the scenario file has no
    // [board]); the shipped board's is in the scenarios on drive.toml.
    b.spec.sample_window_s = 0.0;
    // The paper's field orientation: the motor's rotor resistance and inductances, fixed (no
    // adaptation), the slip on the reference.
    b.spec.rotor_resistance_range = [1.0, 1.0];
    b.spec.inductance_range = [1.0, 1.0];
    b.spec.slip_current = SlipCurrent::Reference;
    b.scenario.events = vec![(0.0, Event::Enable), (0.3, Event::Reference(Reference::Speed(376.0)))];
    b.scenario.duration_s = 6.5;
    Ok(b)
}

/// Fig. 16 with the ICAD controller eq. (20).
pub fn fig16_icad() -> Result<Builtin, ScenarioError> {
    fig16(
        CurrentLaw::ICAD_EQ20,
        "fig16-icad",
        "seed 002 Fig. 16: eq. (21) speed loop to 376 rad/s, ICAD current loops",
    )
}

/// Fig. 16 with the stationary PI of Sec. VI-D (Kp = 360, Ki = 9000).
pub fn fig16_pi() -> Result<Builtin, ScenarioError> {
    fig16(
        CurrentLaw::PI_SEED002,
        "fig16-pi",
        "seed 002 Fig. 16: eq. (21) speed loop to 376 rad/s, PI 360/9000 current loops",
    )
}

/// Seed 000 Fig. 11: the 2300 V machine of Table 2 (as read in
/// `motors/krause-2300v-500hp.toml`) on a 3300 V bus at 20 kHz; synchronous-frame current
/// loops PI1 = PI3 = (30s + 50)/s (eq. (34)); speed loop PI2 = (50s + 250)/s → i_qs*
/// (eq. (35)), limited to 250 A; ψ_r* = 4.5 Wb (i_ds* = 31.5 A). The speed reference of
/// 100 rad/s is applied once the rotor is magnetized (T_r = 0.78 s, ≈ 2.3 s).
pub fn seed000_fig11() -> Result<Builtin, ScenarioError> {
    let motor = drive_file::motor::load("krause-2300v-500hp")?;
    let mut b = speed_step()?;
    b.name = "seed000-fig11".into();
    b.about = "seed 000 Fig. 11: 2300 V machine, speed step to 100 rad/s, dq PI1/PI3 (30s+50)/s, speed PI2 (50s+250)/s".into();
    b.spec.motor = motor;
    b.plant = motor;
    b.spec.current_law = CurrentLaw::PI1_SEED000;
    b.spec.current_frame = CurrentFrame::Synchronous;
    // The paper's PI1/PI3, designed on the coupled axes: no decoupling of ours.
    b.spec.current_decoupling = false;
    b.spec.speed_law = SpeedLaw::pi2_seed000(250.0);
    b.spec.flux_ref_wb = 4.5;
    b.spec.flux_floor_wb = 0.2;
    // The paper's field orientation: the motor's rotor resistance and inductances, fixed
    // (Fig. 12 detunes it), and eq. (7)'s slip on the reference i_q*.
    b.spec.rotor_resistance_range = [1.0, 1.0];
    b.spec.inductance_range = [1.0, 1.0];
    b.spec.slip_current = SlipCurrent::Reference;
    b.spec.i_ref_max_a = 260.0;
    let basis = drive_file::drive::DefaultsBasis {
        flux_ref_wb: 4.5,
        i_ref_max_a: 260.0,
        speed_limit_nm: match b.spec.speed_law {
            SpeedLaw::SaturatedP { tau_max_nm, .. } => tau_max_nm,
            SpeedLaw::PiTorque { limit, .. } => limit,
            SpeedLaw::PiIq { limit, .. } => motor.torque_factor() * 4.5 * limit,
        },
        encoder_lines: drive_file::drive::DEFAULT_ENCODER_LINES,
        slow_period_s: f64::from(b.spec.slow_divider) / b.spec.pwm_frequency_hz,
        // The 500 hp machine's thermal data are not in the paper.
        motor_thermal: None,
        inverter_thermal: None,
        // The paper states no board: the fraction of the trip level alone.
        current_lsb_a: None,
    };
    b.spec.protection = drive_file::drive::protection_with_defaults(&motor, &basis, 400.0, 2500.0, 3800.0);
    b.scenario.vdc_v = 3300.0;
    b.scenario.events = vec![(0.0, Event::Enable), (0.0, Event::Reference(Reference::Speed(100.0)))];
    b.scenario.duration_s = 5.0;
    Ok(b)
}

/// Seed 000 Fig. 12: [`seed000_fig11`] with the plant's R_r +100 % and R_s +50 % (the
/// controller and its IFOC slip gain keep the nominal values).
pub fn seed000_fig12() -> Result<Builtin, ScenarioError> {
    let mut b = seed000_fig11()?;
    b.name = "seed000-fig12".into();
    b.about = "seed 000 Fig. 12: as seed000-fig11 with the plant's Rr +100 % and Rs +50 %".into();
    let n = b.plant;
    b.plant = MotorParams::new(
        1.5 * n.rs_ohm(),
        2.0 * n.rr_ohm(),
        n.ls_h(),
        n.lr_h(),
        n.lm_h(),
        n.pole_pairs(),
        n.j_kgm2(),
        n.b_nms(),
    )?;
    Ok(b)
}

/// All built-in scenarios.
pub fn all() -> Result<Vec<Builtin>, ScenarioError> {
    Ok(vec![
        speed_step()?,
        speed_step_sensors()?,
        speed_step_switching()?,
        speed_step_sensorless()?,
        vhz_fan()?,
        fig11_locked_rotor()?,
        fig14_position()?,
        fig16_icad()?,
        fig16_pi()?,
        fig23_perturbed()?,
        seed000_fig11()?,
        seed000_fig12()?,
    ])
}
