//! `design bench`: the work `tools/control_bench.py` also gives python-control, timed here.
//!
//! 1. ICAD ω_r sweep: closed-loop eigenvalues of the full 2×2 current loop (DeLorenzo eq. (13)
//!    motor, controller (20) on both axes) at ω_r = 0, 5, …, 5000 rad/s (1001 speeds).
//! 2. A 200×200 k_p–k_i grid on seed 000's interval current plant: a point is robustly
//!    stable when the PI closes all 16 Kharitonov loops stably — decided from closed-loop
//!    poles (companion eigenvalues, the work python-control does) and, separately, by Routh.
//!
//! Prints JSON with the timings and the results (abscissae, the verdict grid as rows of
//! 0/1) so that the script can check both tools computed the same thing.

use controller_core::current::CurrentLaw;
use design::kharitonov::pi_characteristic;
use design::pi_region::{linspace, robust_grid};
use std::time::Instant;

/// The grid's window (k_p, k_i): both verdicts occur (see `design kharitonov --plot-dir`).
pub const KP_RANGE: (f64, f64) = (-0.05, 0.1);
/// k_i range of the grid.
pub const KI_RANGE: (f64, f64) = (-1.0, 10.0);

/// Run the benchmark; always `Ok(true)` unless an input is missing.
pub fn run() -> Result<bool, String> {
    let motor = drive_file::motor::load("delorenzo-eq13").map_err(|e| e.to_string())?;
    let plant = design::kharitonov::seed000_current_plant().map_err(|e| format!("{e:?}"))?;
    let speeds: Vec<f64> = (0..=1000).map(|i| 5.0 * f64::from(i)).collect();
    // Best of three runs for each figure (the first also warms caches).
    let best = |f: &mut dyn FnMut()| {
        (0..3)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let mut abscissae = Vec::new();
    let sweep_s = best(&mut || {
        abscissae = speeds
            .iter()
            .map(|&w| design::icad::closed_loop_abscissa(&motor, &CurrentLaw::ICAD_EQ20, w))
            .collect();
    });
    let (kps, kis) = (linspace(KP_RANGE.0, KP_RANGE.1, 200), linspace(KI_RANGE.0, KI_RANGE.1, 200));
    let plants = plant.kharitonov_plants();
    // Routh is the shipped decision (`pi_region::robust_grid`); by poles is python-control's way.
    let by_poles_grid = || -> Vec<Vec<bool>> {
        kps.iter()
            .map(|&kp| {
                kis.iter()
                    .map(|&ki| {
                        plants
                            .iter()
                            .all(|(_, _, n, d)| pi_characteristic(n, d, kp, ki).max_real_root() < 0.0)
                    })
                    .collect()
            })
            .collect()
    };
    let rows = |g: &[Vec<bool>]| -> Vec<String> {
        g.iter().map(|r| r.iter().map(|&ok| if ok { '1' } else { '0' }).collect()).collect()
    };
    let mut poles_grid = Vec::new();
    let poles_s = best(&mut || poles_grid = by_poles_grid());
    let mut routh_grid = Vec::new();
    let routh_s = best(&mut || routh_grid = robust_grid(&plant, &kps, &kis));
    let (by_poles, by_routh) = (rows(&poles_grid), rows(&routh_grid));
    let differ = by_poles
        .iter()
        .zip(&by_routh)
        .flat_map(|(a, b)| a.chars().zip(b.chars()))
        .filter(|(x, y)| x != y)
        .count();
    let v = serde_json::json!({
        "icad_sweep": {"speeds": speeds.len(), "seconds": sweep_s, "abscissae": abscissae},
        "grid": {
            "kp_range": [KP_RANGE.0, KP_RANGE.1], "ki_range": [KI_RANGE.0, KI_RANGE.1], "n": 200,
            "seconds_poles": poles_s, "seconds_routh": routh_s,
            "poles_vs_routh_differences": differ,
            "rows_kp_major": by_poles,
        },
    });
    report::outln!("{}", serde_json::to_string(&v).map_err(|e| e.to_string())?);
    Ok(true)
}
