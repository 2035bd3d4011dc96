//! The ideal actuator: the drive's speed law alone, on the sampled mechanics — the
//! campaign's diagnostic shadow ([`IdealLoop`]) and the prediction `design tune` chooses a
//! speed law by ([`super::Campaign::predict`]).

use controller_core::drive::DriveSpec;
use controller_core::encoder::SPEED_WINDOW_READS;
use controller_core::envelope::EnvelopeConfig;
use controller_core::ifoc::TorqueCommand;
use controller_core::motor::MotorParams;
use controller_core::speed::{SpeedControllerConfig, SpeedLaw, SpeedState};

/// The drive's speed law on an ideal torque actuator: the law's own discrete code
/// (`SpeedControllerConfig`; the speed measured ideally, or as the board measures it,
/// [`IdealLoop::measured`]) driving `J dω/dt = τ − Bω − T_L` of
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
    /// The speed at the last [`SPEED_WINDOW_READS`] + 1 slow steps, the newest at `head`:
    /// what the drive's speed estimate averages over.
    window: [f64; SPEED_WINDOW_READS + 1],
    head: usize,
    /// The law reads the window's mean (the encoder's estimate), not the speed itself.
    measured: bool,
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
            window: [0.0; SPEED_WINDOW_READS + 1],
            head: 0,
            measured: false,
            omega_m_rad_s: 0.0,
        })
    }

    /// This loop with its law reading the speed as the drive's estimate gives it: the mean
    /// over the encoder's window of [`SPEED_WINDOW_READS`] slow periods (the M-method,
    /// `controller_core::encoder`: a delay of half the window), the rotor at rest before the
    /// start. The sensorless observer's bandwidth is chosen to lag as much
    /// (`controller_core::drive::observer_speed_bandwidth_rad_s`). A prediction that reads
    /// the speed ideally answers a load step and a speed step sooner than any drive on the
    /// board can, and so chose laws whose drives overshot and dipped beyond it in software in
    /// the loop.
    pub fn measured(self) -> Self {
        Self { measured: true, ..self }
    }

    /// The speed the law reads: the window's mean (trapezoidal over its slow periods), or the
    /// speed itself.
    fn speed_read(&self) -> f64 {
        if !self.measured {
            return self.omega_m_rad_s;
        }
        let n = SPEED_WINDOW_READS;
        let oldest = self.window[(self.head + 1) % (n + 1)];
        let inner: f64 = (1..n).map(|i| self.window[(self.head + n + 1 - i) % (n + 1)]).sum();
        (0.5 * (oldest + self.omega_m_rad_s) + inner) / n as f64
    }

    /// This loop at its start (at rest, the law's state cleared) with speed law `law`
    /// stepped every `t_s`: the same mechanics and envelope.
    pub fn with_law(&self, law: &SpeedLaw, t_s: f64) -> Result<Self, String> {
        let law = SpeedControllerConfig::new(law, t_s).map_err(|e| format!("speed law: {e:?}"))?;
        Ok(Self {
            law,
            state: SpeedState::default(),
            age: 0,
            window: [0.0; SPEED_WINDOW_READS + 1],
            head: 0,
            omega_m_rad_s: 0.0,
            ..*self
        })
    }

    /// The envelope's torque magnitude in the direction `sign` (of the torque) at speed
    /// `omega_m_rad_s`, N·m: what this plant gives there on the drive's voltage and current
    /// limits (τ_max aside).
    pub fn torque_limit_nm(&self, sign: f64, omega_m_rad_s: f64) -> f64 {
        envelope_torque_nm(&self.envelope, self.limits, sign, omega_m_rad_s)
    }

    /// One slow period with reference `omega_ref` and load `load_nm`; `true` when the law's
    /// torque is at its limit — its own, or the envelope's where that is smaller (as the
    /// drive's `speed_saturated`: at 0.999 of it).
    pub fn step(&mut self, omega_ref: f64, load_nm: f64) -> bool {
        if self.age == 0 {
            let w = self.omega_m_rad_s;
            self.torque_max_nm = (self.torque_limit_nm(1.0, w), self.torque_limit_nm(-1.0, w));
            self.age = u32::from(controller_core::envelope::ENVELOPE_REFRESH_SLOW_STEPS);
        }
        self.age -= 1;
        self.head = (self.head + 1) % (SPEED_WINDOW_READS + 1);
        self.window[self.head] = self.omega_m_rad_s;
        let read = self.speed_read();
        let law_limit = f64::from(self.law.output_limit());
        let (tau, law_limit) = match self.law.update(&mut self.state, omega_ref as f32, read as f32) {
            TorqueCommand::TorqueNm(t) => (f64::from(t), law_limit),
            TorqueCommand::IqA(i) => (self.kt * f64::from(i), self.kt * law_limit),
        };
        let envelope = if tau >= 0.0 { self.torque_max_nm.0 } else { self.torque_max_nm.1 };
        let at_limit = tau.abs() >= 0.999 * law_limit.min(envelope);
        let tau = tau.clamp(-self.torque_max_nm.1, self.torque_max_nm.0);
        self.omega_m_rad_s = self.a * self.omega_m_rad_s + self.g * (tau - load_nm);
        at_limit
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Read through the encoder's window, a speed rising at a constant rate lags by half the
    /// window (the M-method's delay, `controller_core::encoder`; the trapezoid is exact on a
    /// ramp); read ideally, it is the speed itself.
    #[test]
    fn the_measured_speed_lags_half_the_window() {
        let f = drive_file::DriveFile::shipped().unwrap();
        let (t_s, rate) = (5e-4, 200.0);
        let ideal = IdealLoop::new(&f.spec, &f.spec.motor, 310.0, t_s).unwrap();
        for (mut l, lag) in [(ideal.measured(), rate * SPEED_WINDOW_READS as f64 * t_s / 2.0), (ideal, 0.0)] {
            for k in 0..=3 * SPEED_WINDOW_READS {
                l.head = (l.head + 1) % (SPEED_WINDOW_READS + 1);
                l.omega_m_rad_s = rate * k as f64 * t_s;
                l.window[l.head] = l.omega_m_rad_s;
            }
            assert!((l.omega_m_rad_s - l.speed_read() - lag).abs() < 1e-9, "{} {}", l.speed_read(), lag);
        }
    }
}
