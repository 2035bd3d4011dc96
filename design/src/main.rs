//! `design` command line. Exit status everywhere: 0 the checked property holds, 1 it does
//! not, 2 usage or input error (named in the message).
//!
//! ```text
//! design kharitonov --plant <plant.toml> --pi KP,KI [--gpm A,PHI_DEG] [--bandwidth RAD_S]
//!                   [--json] [--plot FILE.svg] [--plot-dir DIR] [--kp-range LO,HI] [--ki-range LO,HI]
//! design icad --motor <motor.toml | builtin> --omega-r <rad/s> --controller <icad20 | pi:KP,KI> [--json]
//! design certify <drive.toml> [--json]
//! design recycle [--json] [--decay RATE] [--plot-dir DIR]
//! design startup-fit [--motor M] [--segments N] [--json] [--plot-dir DIR] [--plant-out FILE.toml]
//! design bench
//! ```
//!
//! `startup-fit` (seed 000 Sec. 6, `design::startup_fit`) fits linear models to segments of
//! a direct-on-line start of the nonlinear machine (default seed 000's 2300 V motor, 13
//! segments) and writes their coefficient ranges as a plant file `kharitonov` reads; exit 0
//! when every fitted model replays its segment's i_sα within 5 % RMS.
//!
//! `bench` times the ICAD ω_r sweep and a 200×200 k_p–k_i grid (JSON; `tools/control_bench.py`
//! runs python-control on the same work and prints the ratio).
//!
//! `kharitonov` checks a PI `(KP·s + KI)/s` on the 16 Kharitonov plants of an interval plant
//! file (`[numerator]`/`[denominator]` tables with `lo`/`hi` arrays of descending
//! coefficients): robust stability, and with `--gpm` the gain–phase-margin tester `A·e^{−jφ}`
//! and with `--bandwidth` the closed-loop `|T(jω_B)| ≥ 1/√2` condition (seed 000 Sec. 4,
//! derived in `design::pi_region`). `--plot` draws the stability plane (Figs. 4/8);
//! `--plot-dir` writes `stability.svg`, and `gpm.svg` / `bandwidth.svg` (Figs. 5–6, 9–10)
//! when asked for. Default ranges: −0.5…3 times the PI gains.
//!
//! `icad` runs seed 002's individual channel analysis of the stator-current loops at one
//! electrical rotor speed (motors: `delorenzo-eq13`, `delorenzo-appendix`,
//! `delorenzo-perturbed`, `krause-2300v-500hp` or a motor file) and sweeps ω_r (0…5000 rad/s,
//! 5 rad/s steps) for the range where the full 2×2 loop stays stable.
//!
//! `certify` checks every controller constant of a drive file against its declared
//! parameter intervals (see `design::certify`).
//!
//! `recycle` runs seed 001's study of the recycle process (`design::recycle`): ITAE
//! nominal PI, where it loses stability, Table I checked every way, and the NLP (18)
//! solved under the printed constraints, lemma 2.2, Kharitonov and the exact family
//! (the last two with roots left of −RATE, default 0.01 1/s). `--plot-dir` writes the
//! step responses of Figs. 2–5 and the k₁–k₂ region plot. Exit 0 when every optimum but
//! the printed one is verified robust.

mod cli {
    pub mod bench;
    pub mod kharitonov;
    pub mod recycle;
    pub mod startup_fit;

    /// Write `text` to `path` through a `.partial` file and a rename: a reader never sees a
    /// half-written plot or plant file.
    pub fn write_atomic(path: &std::path::Path, text: &str) -> Result<(), String> {
        use std::io::Write;
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".partial");
        let written = std::fs::File::create(&tmp)
            .and_then(|mut f| {
                f.write_all(text.as_bytes())?;
                f.sync_all() // on disk before it takes the final name
            })
            .and_then(|()| std::fs::rename(&tmp, path));
        if written.is_err() {
            let _ = std::fs::remove_file(&tmp); // nothing half-written left behind
        }
        written.map_err(|e| format!("{}: {e}", path.display()))
    }
}

use std::process::ExitCode;

fn icad(args: &[String]) -> Result<bool, String> {
    use controller_core::current::CurrentLaw;
    let (mut motor, mut omega_r, mut law, mut json) = (None, None, None, false);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--motor" => motor = Some(it.next().ok_or("--motor needs a file or builtin name")?.clone()),
            "--omega-r" => {
                let v = it.next().ok_or("--omega-r needs a value")?;
                omega_r = Some(
                    v.parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or(format!("--omega-r: `{v}` is not a number"))?,
                );
            }
            "--controller" => {
                let c = it.next().ok_or("--controller needs icad20 or pi:KP,KI")?;
                law = Some(match c.as_str() {
                    "icad20" => CurrentLaw::ICAD_EQ20,
                    other => match other.strip_prefix("pi:") {
                        Some(g) => {
                            let (kp, ki) = cli::kharitonov::parse_pi(g)?;
                            CurrentLaw { kp_v_per_a: kp, ki_v_per_as: ki, lag: None }
                        }
                        None => {
                            return Err(format!("--controller: `{other}` is neither icad20 nor pi:KP,KI"));
                        }
                    },
                });
            }
            "--json" => json = true,
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    let m = drive_file::motor::load(&motor.ok_or("--motor is required")?).map_err(|e| e.to_string())?;
    let omega_r = omega_r.ok_or("--omega-r is required")?;
    let law = law.ok_or("--controller is required")?;
    let r = design::icad::analyse(&m, &law, omega_r);
    let stable_here = design::icad::closed_loop_abscissa(&m, &law, omega_r) < 0.0;
    let range = design::icad::stable_omega_r_max(&m, &law, 5.0, 5000.0);
    let v = serde_json::json!({
        "omega_r_rad_s": omega_r,
        "crossover_rad_s": r.channel.crossover_rad_s,
        "phase_margin_deg": r.channel.phase_margin_deg,
        "gain_margin_increase_db": r.channel.gain_margin_increase_db,
        "gain_margin_reduction_db": r.channel.gain_margin_reduction_db,
        "bandwidth_rad_s": r.channel.bandwidth_rad_s,
        "diagonal_phase_margin_deg": r.diagonal.phase_margin_deg,
        "diagonal_gain_margin_reduction_db": r.diagonal.gain_margin_reduction_db,
        "kg_at_omega_r_db": r.kg_at_omega_r_db,
        "coupling_peak_db": r.coupling_peak_db,
        "gamma_margin_db": r.gamma_margin_db,
        "gamma_h_margin_db": r.gamma_h_margin_db,
        "gm_min": r.gm_min,
        "gm_min_db": 20.0 * r.gm_min.log10(),
        "stable_at_omega_r": stable_here,
        "stable_omega_r_max_rad_s": range,
        "stable_omega_r_search_limit_rad_s": 5000.0,
    });
    if json {
        println!("{}", serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?);
    } else if let Some(obj) = v.as_object() {
        for (k, val) in obj {
            println!("{k:<36} {val}");
        }
    }
    Ok(stable_here)
}

fn certify(args: &[String]) -> Result<bool, String> {
    let (mut path, mut json) = (None, false);
    for a in args {
        match a.as_str() {
            "--json" => json = true,
            p if path.is_none() && !p.starts_with("--") => path = Some(p.to_string()),
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    let path = path.ok_or("certify needs a drive file")?;
    let (spec, c) = design::certify::load(std::path::Path::new(&path))?;
    let checks = design::certify::certify(&spec, &c)?;
    let ok = checks.iter().all(|c| c.pass);
    if json {
        let v: Vec<_> = checks
            .iter()
            .map(|c| serde_json::json!({"check": c.name, "corner": c.corner, "value": c.value, "limit": c.limit, "pass": c.pass}))
            .collect();
        let out = serde_json::json!({"file": path, "certified": ok, "checks": v});
        println!("{}", serde_json::to_string_pretty(&out).map_err(|e| e.to_string())?);
    } else {
        for ch in &checks {
            let value = ch.value.map_or_else(|| "none".to_string(), |v| format!("{v:.3}"));
            println!(
                "{:<5} {:<56} {:<22} {:>10}  limit {}",
                if ch.pass { "ok" } else { "FAIL" },
                ch.name,
                ch.corner,
                value,
                ch.limit
            );
        }
        println!("{path}: {}", if ok { "certified" } else { "NOT certified" });
    }
    if !ok {
        for ch in checks.iter().filter(|c| !c.pass) {
            eprintln!(
                "design certify: {path}: {} at {} is {:?}, limit {}",
                ch.name, ch.corner, ch.value, ch.limit
            );
        }
    }
    Ok(ok)
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("kharitonov") => cli::kharitonov::run(args.get(1..).unwrap_or(&[])),
        Some("icad") => icad(args.get(1..).unwrap_or(&[])),
        Some("certify") => certify(args.get(1..).unwrap_or(&[])),
        Some("recycle") => cli::recycle::run(args.get(1..).unwrap_or(&[])),
        Some("bench") => cli::bench::run(args.get(1..).unwrap_or(&[])),
        Some("startup-fit") => cli::startup_fit::run(args.get(1..).unwrap_or(&[])),
        _ => Err("usage: design kharitonov --plant <plant.toml> --pi KP,KI [--json] [--plot FILE] [--plot-dir DIR]\n       \
                  \x20                 [--kp-range LO,HI] [--ki-range LO,HI] [--gpm A,PHI_DEG] [--bandwidth RAD_S]\n       \
                  design icad --motor <toml|builtin> --omega-r <rad/s> --controller <icad20|pi:KP,KI> [--json]\n       \
                  design certify <drive.toml> [--json]\n       \
                  design recycle [--json] [--decay 1/s] [--plot-dir DIR]\n       \
                  design startup-fit [--motor M] [--segments N] [--json] [--plot-dir DIR] [--plant-out FILE]\n       \
                  design bench"
            .into()),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(1),
        Err(e) => {
            eprintln!("design: {e}");
            ExitCode::from(2)
        }
    }
}
