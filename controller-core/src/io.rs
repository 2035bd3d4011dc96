//! What crosses the drive's boundary: the measurements of a period ([`Measurements`]), the
//! user's reference ([`Reference`]), the bridge command and the step's output
//! ([`PhaseCommand`], [`FastOutput`]), the signals for logs ([`Telemetry`]).

use crate::fault::Mode;
use crate::frames::{Abc, AlphaBeta};

/// Outer-loop reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reference {
    /// Mechanical speed, rad/s.
    Speed(f32),
    /// Mechanical position, rad (not wrapped).
    Position(f32),
    /// Electromagnetic torque, N·m (speed loop bypassed).
    Torque(f32),
    /// Current-loop test (commissioning; seed 002 Fig. 11/23): IFOC and the outer loops are
    /// bypassed and the stator current reference is the rotating vector
    /// `A·(cos θ, sin θ)`, `θ += ω·T` — a sinusoid of `omega_rad_s` on each axis, β lagging
    /// α by 90°. The amplitude is limited to `i_ref_max_a`.
    RotatingCurrent {
        /// Amplitude A, A.
        amplitude_a: f32,
        /// Electrical frequency ω, rad/s.
        omega_rad_s: f32,
    },
}

/// Commands that are refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandError {
    /// A fault is latched: clear it first.
    Faulted,
    /// The reference value is NaN or infinite.
    NonFinite,
    /// Not while the bridge is active (Magnetizing or Running): disable first.
    Active,
    /// A position reference needs an encoder: a sensorless drive's position is its estimated
    /// speed's integral, which drifts ([`crate::drive::SpeedFeedback::Sensorless`]).
    NoEncoder,
    /// V/Hz control takes a speed reference only ([`crate::drive::Control::VHz`]).
    SpeedOnly,
}

/// Sampled inputs of one PWM period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Measurements {
    /// Phase currents, A.
    pub i_abc_a: Abc,
    /// DC-bus voltage, V.
    pub vdc_v: f32,
    /// Mechanical speed, rad/s.
    pub omega_m_rad_s: f32,
    /// Mechanical angle, rad, within a revolution: `[-π, π)` as the encoder reports it
    /// (`crate::encoder`; any finite value is accepted — the drive works on the wrapped
    /// difference of successive readings and counts the turns itself, so the angle keeps its
    /// precision however far the motor has turned). Read by the slow step.
    pub theta_m_rad: f32,
}

impl Measurements {
    pub(crate) fn is_finite(&self) -> bool {
        self.i_abc_a.is_finite()
            && self.vdc_v.is_finite()
            && self.omega_m_rad_s.is_finite()
            && self.theta_m_rad.is_finite()
    }
}

/// What the bridge should do for the next PWM period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PhaseCommand {
    /// All six switches off.
    Off,
    /// Upper-switch duty cycles in [0, 1].
    Duty(Abc),
}

/// Signals of one fast step, for logs and traces.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Telemetry {
    /// Measured stator current, A.
    pub i_ab_a: AlphaBeta,
    /// Stator current reference, A.
    pub i_ref_ab_a: AlphaBeta,
    /// Applied stator voltage (after the hexagon limit), V.
    pub v_ab_v: AlphaBeta,
    /// Field angle, rad.
    pub theta_e_rad: f32,
    /// Slip speed, electrical rad/s.
    pub omega_sl_rad_s: f32,
    /// Rotor-flux model estimate, Wb.
    pub psi_r_wb: f32,
    /// Rotor-flux reference of the operating point, L_m·i_d*, Wb (field weakening lowers
    /// it above base speed).
    pub psi_ref_wb: f32,
    /// q-axis current reference, A.
    pub i_q_ref_a: f32,
    /// Speed reference of the speed loop, mechanical rad/s.
    pub omega_ref_rad_s: f32,
    /// The rotor resistance the field orientation runs on, × the motor's
    /// ([`crate::mras`]).
    pub rr_scale: f32,
    /// The inductances the field orientation runs on, × the motor's ([`crate::mras`]).
    pub l_scale: f32,
}

/// One field of [`Telemetry`], named: what reads one signal of a step without making them
/// all (the firmware's capture: `crate::drive::FastSide::signal`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TelemetryField {
    /// [`Telemetry::i_ab_a`]'s α.
    IAlpha,
    /// [`Telemetry::i_ab_a`]'s β.
    IBeta,
    /// [`Telemetry::i_ref_ab_a`]'s α.
    IRefAlpha,
    /// [`Telemetry::i_ref_ab_a`]'s β.
    IRefBeta,
    /// [`Telemetry::v_ab_v`]'s α.
    VAlpha,
    /// [`Telemetry::v_ab_v`]'s β.
    VBeta,
    /// [`Telemetry::theta_e_rad`].
    ThetaE,
    /// [`Telemetry::omega_sl_rad_s`].
    OmegaSl,
    /// [`Telemetry::psi_r_wb`].
    PsiR,
    /// [`Telemetry::psi_ref_wb`].
    PsiRef,
    /// [`Telemetry::i_q_ref_a`].
    IqRef,
    /// [`Telemetry::omega_ref_rad_s`].
    OmegaRef,
    /// [`Telemetry::rr_scale`].
    RrScale,
    /// [`Telemetry::l_scale`].
    LScale,
}

impl TelemetryField {
    /// Every field.
    pub const ALL: [TelemetryField; 14] = [
        TelemetryField::IAlpha,
        TelemetryField::IBeta,
        TelemetryField::IRefAlpha,
        TelemetryField::IRefBeta,
        TelemetryField::VAlpha,
        TelemetryField::VBeta,
        TelemetryField::ThetaE,
        TelemetryField::OmegaSl,
        TelemetryField::PsiR,
        TelemetryField::PsiRef,
        TelemetryField::IqRef,
        TelemetryField::OmegaRef,
        TelemetryField::RrScale,
        TelemetryField::LScale,
    ];
}

impl Telemetry {
    /// The field `k`.
    #[inline]
    pub fn get(&self, k: TelemetryField) -> f32 {
        use TelemetryField as F;
        match k {
            F::IAlpha => self.i_ab_a.alpha,
            F::IBeta => self.i_ab_a.beta,
            F::IRefAlpha => self.i_ref_ab_a.alpha,
            F::IRefBeta => self.i_ref_ab_a.beta,
            F::VAlpha => self.v_ab_v.alpha,
            F::VBeta => self.v_ab_v.beta,
            F::ThetaE => self.theta_e_rad,
            F::OmegaSl => self.omega_sl_rad_s,
            F::PsiR => self.psi_r_wb,
            F::PsiRef => self.psi_ref_wb,
            F::IqRef => self.i_q_ref_a,
            F::OmegaRef => self.omega_ref_rad_s,
            F::RrScale => self.rr_scale,
            F::LScale => self.l_scale,
        }
    }
}

/// Output of one fast step (its signals: `Drive::telemetry`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FastOutput {
    /// Bridge command.
    pub phases: PhaseCommand,
    /// Mode after this step.
    pub mode: Mode,
    /// Brake chopper on (the bus above the chopper's on level, and not yet below its off
    /// level); always `false` without a chopper.
    pub brake: bool,
}
