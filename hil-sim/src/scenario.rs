//! Built-in scenarios (the TOML scenario files of issue 3 will extend this list).

use crate::sensors::SensorModel;
use crate::sim::{Event, LoadModel, Scenario};
use controller_core::drive::{DriveSpec, Reference, example_spec};
use controller_core::motor::MotorError;

/// A named, runnable scenario with its drive.
#[derive(Clone, Debug)]
pub struct Builtin {
    /// Name used on the command line.
    pub name: &'static str,
    /// One-line description.
    pub about: &'static str,
    /// Drive specification.
    pub spec: DriveSpec,
    /// Events and timing.
    pub scenario: Scenario,
}

/// IFOC speed step to 150 rad/s with the ICAD current loop (seed 002 eq. (20)) and the
/// saturated-P speed loop (eq. (21)) on the DeLorenzo motor; 1 N·m load from 1.5 s to
/// 2.5 s (after seed 002 Fig. 13).
pub fn speed_step() -> Result<Builtin, MotorError> {
    Ok(Builtin {
        name: "speed-step",
        about: "IFOC + ICAD, speed step to 150 rad/s, 1 N·m load applied at 1.5 s and removed at 2.5 s",
        spec: example_spec()?,
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

/// All built-in scenarios.
pub fn all() -> Result<Vec<Builtin>, MotorError> {
    Ok(vec![speed_step()?, speed_step_sensors()?, fig11_locked_rotor()?])
}
