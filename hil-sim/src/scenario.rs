//! Built-in scenarios (the TOML scenario files of issue 3 will extend this list).

use crate::plant::Machine;
use crate::sensors::SensorModel;
use crate::sim::{self, Event, LoadModel, Row, Scenario};
use controller_core::drive::{Drive, DriveConfig, DriveSpec, Mode, Reference, example_spec};
use controller_core::motor::{MotorError, MotorParams};

/// A named, runnable scenario with its drive.
#[derive(Clone, Debug)]
pub struct Builtin {
    /// Name used on the command line.
    pub name: &'static str,
    /// One-line description.
    pub about: &'static str,
    /// Drive specification (what the controller believes about the motor).
    pub spec: DriveSpec,
    /// The simulated machine (differs from `spec.motor` in perturbed-plant scenarios).
    pub plant: MotorParams,
    /// Events and timing.
    pub scenario: Scenario,
}

impl Builtin {
    /// Run the scenario: returns the trace and the drive's final mode.
    pub fn run(&self, progress: impl FnMut(f64)) -> Result<(Vec<Row>, Mode), String> {
        let cfg = DriveConfig::new(&self.spec).map_err(|e| format!("invalid drive specification: {e:?}"))?;
        let mut drive = Drive::new(cfg);
        let rows = sim::run(
            &mut drive,
            &Machine::new(&self.plant),
            self.spec.pwm_frequency_hz,
            &self.scenario,
            progress,
        )?;
        Ok((rows, drive.mode()))
    }
}

/// The perturbed DeLorenzo motor of seed 002 Sec. VIII ("≈ 100 % perturbation"):
/// R_s, R_r × 2; L_s, L_r × 0.6; L_m × 0.59.
pub fn delorenzo_perturbed() -> Result<MotorParams, MotorError> {
    let n = MotorParams::delorenzo_dl10115a1()?;
    MotorParams::new(
        2.0 * n.rs_ohm(),
        2.0 * n.rr_ohm(),
        0.6 * n.ls_h(),
        0.6 * n.lr_h(),
        0.59 * n.lm_h(),
        n.pole_pairs(),
        n.j_kgm2(),
        n.b_nms(),
    )
}

/// IFOC speed step to 150 rad/s with the ICAD current loop (seed 002 eq. (20)) and the
/// saturated-P speed loop (eq. (21)) on the DeLorenzo motor; 1 N·m load from 1.5 s to
/// 2.5 s (after seed 002 Fig. 13).
pub fn speed_step() -> Result<Builtin, MotorError> {
    let spec = example_spec()?;
    Ok(Builtin {
        name: "speed-step",
        about: "IFOC + ICAD, speed step to 150 rad/s, 1 N·m load applied at 1.5 s and removed at 2.5 s",
        plant: spec.motor,
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
            substeps: 4,
            trace_every: 20,
            sensors: SensorModel::default(),
            load: LoadModel::Torque,
        },
    })
}

/// [`speed_step`] with realistic sensors ([`SensorModel::realistic`]: 12-bit current ADC
/// with offset, gain error and noise; 1024-line encoder) and an eddy-current brake of
/// 0.002 N·m·s/rad instead of the load steps.
pub fn speed_step_sensors() -> Result<Builtin, MotorError> {
    let mut b = speed_step()?;
    b.name = "speed-step-sensors";
    b.about = "speed-step with 12-bit ADC (offset, gain error, noise), 1024-line encoder, eddy-current brake";
    b.scenario.events.retain(|(_, e)| !matches!(e, Event::LoadNm(_)));
    b.scenario.sensors = SensorModel::realistic(7);
    b.scenario.load = LoadModel::EddyBrake { k_nm_s_rad: 0.002 };
    Ok(b)
}

/// Seed 002 Fig. 11: locked rotor, α/β current references of 1 A at 300 rad/s, ICAD
/// controller eq. (20) at 20 kHz (after the flux build-up, from 0.3 s).
pub fn fig11_locked_rotor() -> Result<Builtin, MotorError> {
    let mut b = speed_step()?;
    b.name = "fig11-locked-rotor";
    b.about = "seed 002 Fig. 11: locked rotor, 1 A α/β current references at 300 rad/s, ICAD eq. (20)";
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
pub fn fig23_perturbed() -> Result<Builtin, MotorError> {
    let mut b = fig11_locked_rotor()?;
    b.name = "fig23-perturbed";
    b.about = "seed 002 Fig. 23: perturbed plant (Rs, Rr ×2; Ls, Lr ×0.6; Lm ×0.59), 1 A at 300 rad/s, ICAD";
    b.plant = delorenzo_perturbed()?;
    Ok(b)
}

/// All built-in scenarios.
pub fn all() -> Result<Vec<Builtin>, MotorError> {
    Ok(vec![speed_step()?, speed_step_sensors()?, fig11_locked_rotor()?, fig23_perturbed()?])
}
