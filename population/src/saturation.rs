//! The population's saturation (issue 50): a drawn member's magnetizing branch as a Γ
//! machine on motulator's law `L(ψ) = L_u/(1 + (β·ψ)^S)` (Qu, Ranta, Hinkkanen, Luomi, IEEE
//! TIA 2012), placed on the member's own linear model.
//!
//! The member's T model is its machine at the rated point; the Γ form of the same terminals
//! (Slemon, IEEE TIA 1989) puts the branch at them: `L_s` across the terminals, the leakage
//! `L_σ = L_s·(L_s·L_r − L_m²)/L_m²` and `R_R = (L_s/L_m)²·R_r` on the rotor side. The curve
//! is placed so that its chord at the rated stator flux ψ_N (the nameplate's
//! `√2·V_LL/(√3·2π·f)`) is that `L_s`: with the saturation factor `k = L_u/L(ψ_N)`,
//! `L_u = k·L_s` and `β·ψ_N = (k − 1)^{1/S}`. Machines are designed with the rated point at
//! the knee of their curve; `k` is drawn in [`SATURATION_FACTOR`] and S in
//! [`SATURATION_EXPONENT`] — a stated assumption of the population, with motulator's measured
//! 2.2 kW machine (k = 1 + 0.873⁷ = 1.39, S = 7) inside it.

use crate::member::Member;
use controller_core::magnetics::{Form, MagnetizingCurve, Saturation};
use controller_core::motor::MotorParams;
use hil_sim::rng::{Rng, mix};

/// Saturation factor L_u/L(ψ_N) at the rated stator flux: drawn uniformly in this range.
pub const SATURATION_FACTOR: [f64; 2] = [1.1, 1.6];
/// The law's exponent S: drawn uniformly in this range.
pub const SATURATION_EXPONENT: [f64; 2] = [5.0, 9.0];
/// Mixed into the member's seed for its curve's draws (the member's own draws unchanged).
const STREAM: u64 = 0x5a70_c0de;

/// Member `index` of the population of `seed` (`member`, drawn) as a saturating Γ machine:
/// its model (the T form of the Γ machine at the unsaturated `L_u`, as a motor file with
/// `form = "gamma"` and the law gives it) and its branch's saturation; `None` for a shipped
/// member (no nameplate) or a model the Γ form refuses.
pub fn saturating(seed: u64, index: u64, member: &Member) -> Option<(MotorParams, Saturation)> {
    let (gamma, beta, s) = saturating_law(seed, index, member)?;
    let curve = MagnetizingCurve::law(gamma.lm_h(), beta, s).ok()?;
    Some((gamma, Saturation { form: Form::Gamma, curve }))
}

/// [`saturating`]'s machine and its law's `(β, S)`, 1/Wb and 1.
fn saturating_law(seed: u64, index: u64, member: &Member) -> Option<(MotorParams, f64, f64)> {
    let plate = member.nameplate?;
    let m = &member.motor;
    let mut rng = Rng(mix(seed ^ mix(index) ^ STREAM));
    let draw = |rng: &mut Rng, [lo, hi]: [f64; 2]| lo + (hi - lo) * rng.uniform();
    let k = draw(&mut rng, SATURATION_FACTOR);
    let s = draw(&mut rng, SATURATION_EXPONENT);
    let psi_n = hil_sim::identify::rated_flux_wb(plate.line_voltage_v, plate.frequency_hz);
    let (ls, lr, lm) = (m.ls_h(), m.lr_h(), m.lm_h());
    let l_sigma = ls * (ls * lr - lm * lm) / (lm * lm);
    let r_r = (ls / lm).powi(2) * m.rr_ohm();
    let l_u = k * ls;
    let beta = (k - 1.0).powf(1.0 / s) / psi_n;
    // A law the curve refuses is no machine (its file would be refused too).
    MagnetizingCurve::law(l_u, beta, s).ok()?;
    let gamma =
        MotorParams::new(m.rs_ohm(), r_r, l_u, l_u + l_sigma, l_u, m.pole_pairs(), m.j_kgm2(), m.b_nms())
            .ok()?;
    Some((gamma, beta, s))
}

/// Member `index` of the population of `seed` as a saturating motor file (the Γ form with
/// `[motor.saturation]`, [`saturating`]'s machine), its first lines the nameplate and the
/// `hil-sim identify` command that commissions it on its own board with the curve; `None`
/// where [`saturating`] is.
pub fn saturating_motor_file(seed: u64, index: u64, member: &Member) -> Option<String> {
    let (gamma, beta, s) = saturating_law(seed, index, member)?;
    let (plate, board) = (member.nameplate?, member.board?);
    let law = drive_file::motor::SaturationTable {
        beta_per_wb: Some(beta),
        exponent: Some(s),
        ..Default::default()
    };
    let table = member.motor_table(&gamma, Some(law))?;
    Some(format!(
        "# Population member {} (seed {seed}) as a saturating machine: the Γ form of its model with\n\
         # motulator's law L(ψ) = lm_h/(1 + (β·ψ)^S), the chord at the rated stator flux {:.4} Wb its\n\
         # linear L_s (population/src/saturation.rs). Commissioned on its own board with the curve:\n\
         #   hil-sim identify FILE --out identified.toml --test-current {:.4} --vdc {:.1} --pwm-hz {:.1} \\\n\
         #     --level-time {:.1} --rotate --curve --rated-voltage {:.1} --rated-frequency {:.1}\n\n{}\n",
        member.name,
        hil_sim::identify::rated_flux_wb(plate.line_voltage_v, plate.frequency_hz),
        board.i_ref_max_a,
        board.vdc_v,
        board.pwm_hz,
        (5.0 * (gamma.lr_h() / gamma.rr_ohm()).max(0.1)).clamp(3.0, 60.0),
        plate.line_voltage_v,
        plate.frequency_hz,
        table
    ))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]
mod tests {
    use super::*;
    use controller_core::commission::{CommissionConfig, CommissionSpec};
    use hil_sim::identify::{self, Setup};

    /// The curve's chord at the rated stator flux is the member's linear L_s, and the Γ
    /// machine's terminals are the member's while linear (the inverse-Γ values agree).
    #[test]
    fn a_saturating_member_is_its_member_at_the_rated_point() {
        let member = crate::member::draw(1, 0, None).unwrap();
        let (g, sat) = saturating(1, 0, &member).unwrap();
        let plate = member.nameplate.unwrap();
        let psi_n = identify::rated_flux_wb(plate.line_voltage_v, plate.frequency_hz);
        let chord = psi_n / sat.curve.current_a(psi_n);
        assert!((chord / member.motor.ls_h() - 1.0).abs() < 1e-12, "{chord}");
        let at_rated = MotorParams::new(
            g.rs_ohm(),
            g.rr_ohm(),
            chord,
            chord + g.lr_h() - g.lm_h(),
            chord,
            g.pole_pairs(),
            g.j_kgm2(),
            g.b_nms(),
        )
        .unwrap();
        let (a, b) = (identify::inverse_gamma(&at_rated), identify::inverse_gamma(&member.motor));
        for (x, y) in [(a.0, b.0), (a.1, b.1), (a.2, b.2), (a.3, b.3)] {
            assert!((x / y - 1.0).abs() < 1e-12, "{a:?} against {b:?}");
        }
    }

    /// `population write --saturating`'s file is the member's saturating machine: read back by
    /// drive-file, the same Γ machine and the same curve (flux at five currents to 1e-12).
    #[test]
    fn a_saturating_members_file_reads_back_to_its_machine() {
        for index in 0..3 {
            let member = crate::member::draw(1, index, None).unwrap();
            let (m, sat) = saturating(1, index, &member).unwrap();
            let text = saturating_motor_file(1, index, &member).unwrap();
            let (back, back_sat) =
                drive_file::motor::parse_model(std::path::Path::new("member.toml"), &text).unwrap();
            let back_sat = back_sat.unwrap();
            assert_eq!(back_sat.form, Form::Gamma, "{text}");
            for (x, y) in [(back.rs_ohm(), m.rs_ohm()), (back.rr_ohm(), m.rr_ohm()), (back.lm_h(), m.lm_h())]
                .into_iter()
                .chain([(back.lr_h(), m.lr_h()), (back.ls_h(), m.ls_h()), (back.j_kgm2(), m.j_kgm2())])
            {
                assert!((x / y - 1.0).abs() < 1e-12, "{text}");
            }
            for i in [0.1, 1.0, 3.0, 10.0, 30.0] {
                let (a, b) =
                    (back_sat.curve.flux_at_total_current(i, 0.0), sat.curve.flux_at_total_current(i, 0.0));
                assert!((a / b - 1.0).abs() < 1e-12, "{text}");
            }
            assert!(text.contains("hil-sim identify FILE --out identified.toml --test-current"), "{text}");
        }
    }

    /// Issue 50's acceptance on saturating population members: the commissioning with its
    /// curve (`--curve`) on the member's board (its bus, PWM, dead time and current limit as
    /// the test current; realistic sensors), the nameplate's rated flux: the curve within 5 % of the
    /// machine's flux at its current over 0.3…1.1 of the rated flux, R_s within 3 %, L_σ, R_R
    /// and T_r at rated flux within 5 %, each interval holding the truth.
    #[test]
    fn saturating_members_are_identified_on_their_curve() {
        let mut done = 0;
        for index in 0..3 {
            let member = crate::member::draw(1, index, None).unwrap();
            let (m, sat) = saturating(1, index, &member).unwrap();
            let (plate, board) = (member.nameplate.unwrap(), member.board.unwrap());
            let tr = (m.lr_h() / m.rr_ohm()).max(0.1);
            let spec = CommissionSpec {
                pwm_hz: board.pwm_hz as f32,
                test_current_a: board.i_ref_max_a as f32,
                current_limit_a: 2.0 * board.i_ref_max_a as f32,
                vdc_min_v: (0.8 * board.vdc_v) as f32,
                vdc_max_v: (1.2 * board.vdc_v) as f32,
                level_time_s: (5.0 * tr).clamp(3.0, 60.0) as f32,
                rotate: true,
                rated_flux_wb: identify::rated_flux_wb(plate.line_voltage_v, plate.frequency_hz) as f32,
                no_load_hz: (plate.frequency_hz / 4.0) as f32,
                curve: true,
            };
            let config = CommissionConfig::new(spec).unwrap();
            let mut s = Setup::realistic(m, config, board.vdc_v, 7);
            s.saturation = Some(sat);
            s.inverter = hil_sim::inverter::InverterModel::Switching { dead_time_s: board.dead_time_s };
            let (rec, t) = identify::simulate(&s, |_, _| {}, || false).unwrap();
            let id = identify::estimate(&s.config, &rec, m.pole_pairs())
                .unwrap_or_else(|e| panic!("{}: {e}", member.name));
            let nl = id.no_load.as_ref().unwrap();
            let mut line = format!("{}: curve", member.name);
            // Every point within 5 % and inside its interval, the points spanning 0.3…1.1 of
            // the rated flux (the levels settle within 5 % of their targets).
            let (mut worst, mut outside, mut span) = (0.0f64, false, [f64::INFINITY, 0.0f64]);
            for p in &nl.curve {
                let truth = sat.curve.flux_at_total_current(p.current_a.value, 0.0);
                let (e, x) = (p.flux_wb.value / truth - 1.0, p.flux_wb.value / f64::from(spec.rated_flux_wb));
                line += &format!(" {x:.3}:{:+.2} %", 100.0 * e);
                worst = worst.max(e.abs());
                outside |= !p.flux_wb.contains(truth);
                span = [span[0].min(x), span[1].max(x)];
            }
            assert!(worst <= 0.05 && !outside, "{line}");
            assert!(span[0] <= 0.3 * 1.05 && span[1] >= 1.1, "{line}: the curve spans {span:?}");
            let (g, truth) = (id.gamma.unwrap(), identify::gamma_truth(&m, &sat.curve, nl.flux_wb));
            let rel = |a: f64, b: f64| a / b - 1.0;
            for (what, e, bound, inside) in [
                ("R_s", rel(id.rs_ohm.value, m.rs_ohm()), 0.03, id.rs_ohm.contains(m.rs_ohm())),
                ("L_σ", rel(g.l_sigma_h.value, truth.l_sigma_h), 0.05, g.l_sigma_h.contains(truth.l_sigma_h)),
                ("R_R", rel(g.r_r_ohm.value, truth.r_r_ohm), 0.05, g.r_r_ohm.contains(truth.r_r_ohm)),
                ("T_r", rel(g.tr_s.value, truth.tr_s), 0.05, g.tr_s.contains(truth.tr_s)),
            ] {
                line += &format!(" {what} {:+.2} %", 100.0 * e);
                assert!(e.abs() <= bound && inside, "{line}");
            }
            println!("{line}, {} points, {t:.1} s", nl.curve.len());
            done += 1;
        }
        assert_eq!(done, 3);
    }
}
