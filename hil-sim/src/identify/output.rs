//! What an identification writes: the motor file with its intervals, the pictures of a run
//! and the no-load test's line.

use super::estimation::skip_periods;
use super::{CurvePoint, Estimate, Identified, NoLoad};
use controller_core::commission::{BLOCKS, CommissionConfig, Record};

/// One line on the no-load test's result.
pub fn describe_no_load(n: &NoLoad) -> String {
    format!(
        "no-load test: stator flux {:.4} Wb ({:.1} % of rated {:.4} Wb) at {:.2} Hz with {:.4} A, slip {:.3} rad/s; \
         L_M {:.5} H [{:.5}, {:.5}] (DC levels: {:.5} H)",
        n.flux_wb,
        100.0 * n.flux_wb / n.rated_flux_wb,
        n.rated_flux_wb,
        n.omega_e_rad_s / (2.0 * std::f64::consts::PI),
        n.amplitude_a,
        n.slip_rad_s,
        n.l_mm_h.value,
        n.l_mm_h.interval[0],
        n.l_mm_h.interval[1],
        n.standstill_l_mm_h.value,
    )
}

/// The measured magnetizing curve, if the motor saturates beyond the rated chord's interval
/// and the Γ model was fitted on it: some point's chord ψ_s/i_m lies outside the interval of
/// L_s at rated flux (a linear motor's chords all lie within it, and its file stays in the
/// T form with one L_m). At least two points.
pub fn saturating_curve(id: &Identified) -> Option<&[CurvePoint]> {
    let nl = id.no_load.as_ref()?;
    let curve = &nl.curve;
    let outside = curve.iter().any(|p| !nl.l_s_h.contains(p.flux_wb.value / p.current_a.value));
    (id.gamma.is_some() && curve.len() >= 2 && outside).then_some(curve.as_slice())
}

/// One line per point of the measured curve.
pub fn describe_curve(id: &Identified) -> Vec<String> {
    let Some(nl) = &id.no_load else { return Vec::new() };
    nl.curve
        .iter()
        .map(|p| {
            format!(
                "  curve at {}: ψ_s {:.4} Wb [{:.4}, {:.4}] at i_m {:.4} A (chord L_s {:.5} H)",
                p.target_fraction.map_or("the test current".into(), |f| format!("{f:.2} of the rated flux")),
                p.flux_wb.value,
                p.flux_wb.interval[0],
                p.flux_wb.interval[1],
                p.current_a.value,
                p.flux_wb.value / p.current_a.value,
            )
        })
        .collect()
}

/// The pictures of a run: `decays.svg` — each DC level's recorded voltage above its settled
/// value, over its fitted amplitude, against time over its fitted T_r: all three on
/// `e^{−t/T_r}` when the model holds; and, with the rotating field, `rotation.svg` — the
/// encoder's speed against the field's mechanical speed. (name, SVG) pairs.
pub fn plots(
    cfg: &CommissionConfig,
    rec: &Record,
    id: &Identified,
    pole_pairs: u8,
) -> Vec<(&'static str, String)> {
    use report::plot::{Series, line_plot};
    let ts = f64::from(cfg.ts_s());
    let ends = cfg.block_end();
    let mut series = Vec::new();
    let labels = ["0 → I/2", "I/2 → I", "I → I/2"];
    for ((level, fit), label) in rec.levels.iter().zip(&id.decays).zip(labels) {
        let pts = (0..BLOCKS)
            .filter_map(|b| {
                let start = if b == 0 { 0.0 } else { f64::from(ends[b - 1]) };
                let mid = 0.5 * (start + f64::from(ends[b])) * ts;
                let x = mid / fit.tau_s;
                let y = (f64::from(level.v_alpha_v[b]) - fit.c_v) / fit.a_v;
                (x <= 5.0 && start >= skip_periods()).then_some((x, y))
            })
            .collect();
        series.push(Series::dots(label, pts));
    }
    let model = (0..=200).map(|k| k as f64 * 5.0 / 200.0).map(|x| (x, (-x).exp())).collect();
    series.push(Series::line("e^(−t/T_r)", model));
    let mut out = vec![(
        "decays.svg",
        line_plot("DC levels: (v − v_settled)/A against t/T_r", "t / T_r (each step's fitted T_r)", &series),
    )];
    if let Some(rot) = &id.rotation {
        let r = &rec.rotation;
        let dt = f64::from(r.periods_per_block) * ts;
        let mut prev = 0.0;
        let speed: Vec<(f64, f64)> = r
            .theta_m_rad
            .iter()
            .enumerate()
            .map(|(b, th)| {
                let w = (f64::from(*th) - prev) / dt;
                prev = f64::from(*th);
                ((b as f64 + 0.5) * dt, w)
            })
            .collect();
        let ramp = f64::from(controller_core::commission::ROTATION_RAMP_S);
        let w_max = 2.0 * std::f64::consts::PI * f64::from(controller_core::commission::ROTATION_HZ)
            / f64::from(pole_pairs);
        let t_end = speed.last().map_or(0.0, |p| p.0 + 0.5 * dt);
        let field = vec![(0.0, 0.0), (ramp, w_max), (t_end, w_max)];
        let title = format!(
            "Rotating field: J = {:.4} kg·m², B = {:.4} N·m·s/rad, rotor/field {:.4}",
            rot.j_kgm2.value, rot.b_nms.value, rot.ratio
        );
        out.push((
            "rotation.svg",
            line_plot(
                &title,
                "t, s (from the field's start)",
                &[Series::line("field / p, rad/s", field), Series::dots("encoder, rad/s", speed)],
            ),
        ));
    }
    out
}

/// The motor file: `[motor]` at the nominal values under `ratio`, with `pole_pairs` as given,
/// J and B identified by the rotating field if it ran (else `j_kgm2`, `b_nms` as given), and
/// `[identification]` with the intervals and the inverter's error. A motor that saturates
/// ([`saturating_curve`]) is written in the Γ form it was identified in (`ratio` set aside:
/// the curve saturates the branch at the terminals, which the T form cannot say), with
/// `[motor.saturation]` the curve's points and `[identification]` their intervals.
pub fn motor_file(
    id: &Identified,
    ratio: f64,
    pole_pairs: u8,
    j_kgm2: f64,
    b_nms: f64,
    about: &str,
) -> String {
    let curve = saturating_curve(id).zip(id.gamma);
    let t = id.t_model(ratio);
    let (j_kgm2, b_nms, mechanics) = match &id.rotation {
        Some(r) => (r.j_kgm2.value, r.b_nms.value, "j_kgm2 and b_nms by the slow rotating field"),
        None => (j_kgm2, b_nms, "j_kgm2 and b_nms are as given (the motor was not allowed to turn)"),
    };
    let n = drive_file::source::num;
    let iv = |e: &Estimate| format!("[{}, {}]", n(e.interval[0]), n(e.interval[1]));
    let magnetizing = match &id.no_load {
        Some(nl) => format!(
            "L_M (so L_m, L_s, L_r) by the no-load test at {:.4} Wb stator flux ({:.1} % of the rated\n\
             # {:.4} Wb), {:.2} Hz, {:.4} A; the DC levels gave L_M = {:.5} H",
            nl.flux_wb,
            100.0 * nl.flux_wb / nl.rated_flux_wb,
            nl.rated_flux_wb,
            nl.omega_e_rad_s / (2.0 * std::f64::consts::PI),
            nl.amplitude_a,
            nl.standstill_l_mm_h.value
        ),
        None => "L_M (so L_m, L_s, L_r) by the DC levels (the motor was not allowed to turn)".into(),
    };
    let mut s = String::new();
    for line in about.lines() {
        s.push_str(&format!("# {line}\n"));
    }
    let head = "# Identified by controller-core's commissioning sequence (hil_sim::identify).\n";
    match curve {
        None => s.push_str(&format!(
            "{head}\
             # The leakage split L_lr/L_ls = {} is assumed (the terminals cannot tell it; control does not\n\
             # depend on it). pole_pairs is as given; {mechanics}.\n\
             # {magnetizing}.\n\
             [motor]\n\
             rs_ohm = {}\nrr_ohm = {}\nls_h = {}\nlr_h = {}\nlm_h = {}\npole_pairs = {pole_pairs}\nj_kgm2 = {}\nb_nms = {}\n\n",
            n(ratio),
            n(t.rs_ohm),
            n(t.rr_ohm),
            n(t.ls_h),
            n(t.lr_h),
            n(t.lm_h),
            n(j_kgm2),
            n(b_nms),
        )),
        Some((points, g)) => {
            s.push_str(&format!(
                "{head}\
                 # The magnetizing branch saturates: written in the Γ form it was identified in (the branch at\n\
                 # the terminals, the leakage on the rotor side; lm_h is L_s at rated flux, rr_ohm the Γ R_R).\n\
                 # pole_pairs is as given; {mechanics}.\n\
                 # {magnetizing}.\n\
                 [motor]\n\
                 form = \"gamma\"\nrs_ohm = {}\nrr_ohm = {}\nlm_h = {}\nl_sigma_h = {}\npole_pairs = {pole_pairs}\n\
                 j_kgm2 = {}\nb_nms = {}\n\n\
                 # The curve by the no-load test at {} levels: the stator flux ψ_s and the branch's current i_m (peak).\n\
                 [motor.saturation]\ncurrent_a = [{}]\nflux_wb = [{}]\n\n",
                n(id.rs_ohm.value),
                n(g.r_r_ohm.value),
                n(g.l_s_h.value),
                n(g.l_sigma_h.value),
                n(j_kgm2),
                n(b_nms),
                points.len(),
                points.iter().map(|p| n(p.current_a.value)).collect::<Vec<_>>().join(", "),
                points.iter().map(|p| n(p.flux_wb.value)).collect::<Vec<_>>().join(", "),
            ));
        }
    }
    s.push_str(
        "# Intervals: the repeats' span widened by the stated margins (hil_sim::identify::MARGIN).\n\
         [identification]\n",
    );
    match curve {
        None => {
            s.push_str(&format!("leakage_ratio = {}\n", n(ratio)));
            for (key, e) in id.t_intervals(ratio) {
                s.push_str(&format!("{key} = {}\n", iv(&e)));
            }
        }
        // The Γ file's T model: L_s = L_m = lm_h, L_r = L_s + L_σ, R_r = R_R.
        Some((_, g)) => {
            let [(ll, lh), (sl, sh)] = [g.l_s_h.interval, g.l_sigma_h.interval].map(|[a, b]| (a, b));
            s.push_str(&format!(
                "rs_ohm = {}\nrr_ohm = {}\nls_h = {}\nlr_h = [{}, {}]\nlm_h = {}\n",
                iv(&id.rs_ohm),
                iv(&g.r_r_ohm),
                iv(&g.l_s_h),
                n(ll + sl),
                n(lh + sh),
                iv(&g.l_s_h)
            ));
        }
    }
    s.push_str(&format!(
        "sigma_ls_h = {}\ntr_s = {}\nl_mm_h = {}\nr_rr_ohm = {}\n",
        iv(&id.l_sigma_h),
        iv(&id.tr_s),
        iv(&id.l_mm_h),
        iv(&id.r_rr_ohm)
    ));
    if let Some((points, _)) = curve {
        let list =
            |f: fn(&CurvePoint) -> &Estimate| points.iter().map(|p| iv(f(p))).collect::<Vec<_>>().join(", ");
        s.push_str(&format!(
            "curve_current_a = [{}]\ncurve_flux_wb = [{}]\n",
            list(|p| &p.current_a),
            list(|p| &p.flux_wb)
        ));
    }
    if let Some(r) = &id.rotation {
        s.push_str(&format!(
            "j_kgm2 = {}\nb_nms = {}\n# The rotor turned {}× the field's mechanical speed (1 − slip) at {} rad/s.\n",
            iv(&r.j_kgm2),
            iv(&r.b_nms),
            n(r.ratio),
            n(r.omega_hold_rad_s)
        ));
    }
    s.push_str(&format!(
        "# Inverter voltage error per phase (dead time and switch drops) at {} V, and its share of the bus:\n\
         inverter_error_v = {}\ndead_time_duty = {}\ncurrent_offsets_a = [{}, {}, {}]\n",
        n(id.vdc_v),
        n(id.inverter_error_v.value),
        n(id.inverter_error_v.value / id.vdc_v),
        n(id.offsets_a[0]),
        n(id.offsets_a[1]),
        n(id.offsets_a[2]),
    ));
    s
}
