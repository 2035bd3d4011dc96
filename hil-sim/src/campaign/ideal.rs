//! The ideal actuator: the drive's speed law alone, on the sampled mechanics — the
//! campaign's diagnostic shadow ([`IdealLoop`]) and the prediction `design tune` chooses a
//! speed law by ([`super::Campaign::predict`]).

use controller_core::drive::DriveSpec;
use controller_core::envelope::EnvelopeConfig;
use controller_core::ifoc::TorqueCommand;
use controller_core::motor::MotorParams;
use controller_core::speed::{SpeedControllerConfig, SpeedLaw, SpeedState};

/// The drive's speed law on an ideal torque actuator: the law's own discrete code
/// (`SpeedControllerConfig`, ideal speed measurement) driving `J dω/dt = τ − Bω − T_L` of
/// the sampled plant's mechanics, one step per slow period (zero-order hold). The torque is
/// limited to the steady-state envelope of the *sampled* machine at the present speed
/// (`controller_core::envelope` with the plant's parameters, the drive's voltage target on
/// the bus, remade every [`controller_core::envelope::ENVELOPE_REFRESH_SLOW_STEPS`]), so that
/// above base speed the criterion compares the drive with what the machine it drives allows
/// — a hot motor's larger R_s leaves less torque at speed for any drive — not with τ_max.
#[derive(Clone, Copy, Debug)]
pub struct IdealLoop {
    law: SpeedControllerConfig,
    state: SpeedState,
    kt: f64,
    a: f64,
    g: f64,
    envelope: EnvelopeConfig,
    /// Rated d-axis current, voltage target and current limit of the envelope.
    limits: (f32, f32, f32),
    /// The envelope's torque magnitude (motoring, generating) at the last refresh, N·m.
    torque_max_nm: (f64, f64),
    age: u32,
    /// The ideal loop's speed, mechanical rad/s.
    pub omega_m_rad_s: f64,
}

impl IdealLoop {
    /// For drive `spec` on the mechanics of `plant` and bus `vdc_v`, stepped every `t_s`.
    pub fn new(spec: &DriveSpec, plant: &MotorParams, vdc_v: f64, t_s: f64) -> Result<Self, String> {
        let law =
            SpeedControllerConfig::new(&spec.speed_law, t_s).map_err(|e| format!("speed law: {e:?}"))?;
        let (j, b) = (plant.j_kgm2(), plant.b_nms());
        let (a, g) = if b > 0.0 {
            let a = (-b * t_s / j).exp();
            (a, (1.0 - a) / b)
        } else {
            (1.0, t_s / j)
        };
        Ok(Self {
            law,
            state: SpeedState::default(),
            kt: plant.torque_factor() * spec.flux_ref_wb,
            a,
            g,
            envelope: EnvelopeConfig::new(plant),
            limits: drive_limits(spec, plant, vdc_v),
            torque_max_nm: (f64::INFINITY, f64::INFINITY),
            age: 0,
            omega_m_rad_s: 0.0,
        })
    }

    /// This loop at its start (at rest, the law's state cleared) with speed law `law`
    /// stepped every `t_s`: the same mechanics and envelope.
    pub fn with_law(&self, law: &SpeedLaw, t_s: f64) -> Result<Self, String> {
        let law = SpeedControllerConfig::new(law, t_s).map_err(|e| format!("speed law: {e:?}"))?;
        Ok(Self { law, state: SpeedState::default(), age: 0, omega_m_rad_s: 0.0, ..*self })
    }

    /// The envelope's torque magnitude in the direction `sign` (of the torque) at speed
    /// `omega_m_rad_s`, N·m: what this plant gives there on the drive's voltage and current
    /// limits (τ_max aside).
    pub fn torque_limit_nm(&self, sign: f64, omega_m_rad_s: f64) -> f64 {
        envelope_torque_nm(&self.envelope, self.limits, sign, omega_m_rad_s)
    }

    /// One slow period with reference `omega_ref` and load `load_nm`.
    pub fn step(&mut self, omega_ref: f64, load_nm: f64) {
        if self.age == 0 {
            let w = self.omega_m_rad_s;
            self.torque_max_nm = (self.torque_limit_nm(1.0, w), self.torque_limit_nm(-1.0, w));
            self.age = u32::from(controller_core::envelope::ENVELOPE_REFRESH_SLOW_STEPS);
        }
        self.age -= 1;
        let tau = match self.law.update(&mut self.state, omega_ref as f32, self.omega_m_rad_s as f32) {
            TorqueCommand::TorqueNm(t) => f64::from(t),
            TorqueCommand::IqA(i) => self.kt * f64::from(i),
        };
        let tau = tau.clamp(-self.torque_max_nm.1, self.torque_max_nm.0);
        self.omega_m_rad_s = self.a * self.omega_m_rad_s + self.g * (tau - load_nm);
    }
}

/// The drive's envelope limits on `plant` and bus `vdc_v`: the rated flux's d-axis current,
/// the voltage target on the part of the bus the modulator uses (the sampling window) and
/// the current limit.
pub(super) fn drive_limits(spec: &DriveSpec, plant: &MotorParams, vdc_v: f64) -> (f32, f32, f32) {
    let i_d_rated = crate::envelope::rated_d_current_a(spec, plant);
    let v_target = spec.voltage_margin * spec.duty_max() * vdc_v / 3f64.sqrt();
    (i_d_rated as f32, v_target as f32, spec.i_ref_max_a as f32)
}

/// The torque magnitude of `envelope` in the direction `sign` at speed `omega_m_rad_s`
/// within `limits` ([`drive_limits`]), N·m.
pub(super) fn envelope_torque_nm(
    envelope: &EnvelopeConfig,
    (i_d, v, i_max): (f32, f32, f32),
    sign: f64,
    omega_m_rad_s: f64,
) -> f64 {
    let s = if sign < 0.0 { -1.0 } else { 1.0 };
    f64::from(envelope.envelope(s, omega_m_rad_s as f32, i_d, v, i_max).torque_max_nm)
}
