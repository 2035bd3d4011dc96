//! `hil-sim bench`: the wall time of the closed-loop simulation alone (no trace files).

use super::{interrupted, progress_bar};
use crate::scenario::Builtin;

/// `hil-sim bench`: the built-in `name` of `builtins` run `runs` times after one warm-up
/// run; prints JSON with the median and best real-time factor and nanoseconds per PWM
/// period.
pub fn bench(builtins: &[Builtin], name: &str, runs: u32) -> Result<(), String> {
    let b = builtins
        .iter()
        .find(|b| b.name == name)
        .ok_or(format!("`{name}` is not a built-in scenario (`hil-sim list`)"))?;
    let periods = (b.scenario.duration_s * b.spec.pwm_frequency_hz).round();
    let mut secs = Vec::with_capacity(runs as usize);
    for k in 0..=runs {
        let wall = std::time::Instant::now();
        let (rows, _) = b.run(|_| {})?;
        let s = wall.elapsed().as_secs_f64();
        std::hint::black_box(rows);
        interrupted()?;
        if k > 0 {
            secs.push(s);
        }
        progress_bar(f64::from(k) / f64::from(runs));
    }
    secs.sort_by(f64::total_cmp);
    let median = secs.get(secs.len() / 2).copied().ok_or("no runs")?;
    let best = secs.first().copied().ok_or("no runs")?;
    let summary = serde_json::json!({
        "scenario": b.name,
        "runs": runs,
        "duration_s": b.scenario.duration_s,
        "pwm_frequency_hz": b.spec.pwm_frequency_hz,
        "rk4_substeps_per_pwm_period": b.scenario.substeps,
        "median_wall_time_s": median,
        "median_real_time_factor": b.scenario.duration_s / median,
        "best_real_time_factor": b.scenario.duration_s / best,
        "median_ns_per_pwm_period": median * 1e9 / periods,
        "best_ns_per_pwm_period": best * 1e9 / periods,
    });
    report::outln!("{}", serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_builtin_is_timed() {
        let mut b = crate::scenario::speed_step().unwrap();
        b.scenario.duration_s = 0.005;
        let e = bench(std::slice::from_ref(&b), "no-such-scenario", 1).unwrap_err();
        assert!(e.contains("not a built-in scenario"), "{e}");
        bench(&[b], "speed-step", 1).unwrap();
    }
}
