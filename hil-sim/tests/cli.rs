//! CLI contracts: outputs and their header; a bad file names file, key and reason and
//! writes nothing.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::path::PathBuf;
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hil-sim"))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hil-sim-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

const SCENARIO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/dol-delorenzo.toml");

#[test]
fn open_loop_file_writes_trace_and_summary() {
    let out = tmp("ok");
    let st = bin().args(["run", SCENARIO, "--out"]).arg(&out).output().unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    let trace = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    assert_eq!(
        trace.lines().next().unwrap(),
        "t_s,i_alpha_a,i_beta_a,psi_alpha_wb,psi_beta_wb,omega_m_rad_s,theta_m_rad,torque_nm,v_alpha_v,v_beta_v"
    );
    // 1 s at 0.1 ms: 10 001 samples (both ends) plus the header.
    assert_eq!(trace.lines().count(), 10_002);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["kind"], "open_loop");
    assert!(summary["final_omega_m_rad_s"].as_f64().unwrap() > 100.0);
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn bad_file_is_reported_and_nothing_is_written() {
    let dir = tmp("bad");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("bad.toml");
    let text = std::fs::read_to_string(SCENARIO).unwrap().replace("lr_h = 1.5", "lr_h = -1.5");
    std::fs::write(&file, text).unwrap();
    let out = dir.join("out");
    let st = bin().args(["run"]).arg(&file).arg("--out").arg(&out).output().unwrap();
    assert_eq!(st.status.code(), Some(1));
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(err.contains("bad.toml:") && err.contains("motor.lr_h: is -1.5; must lie in"), "{err}");
    assert!(!out.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn unknown_scenario_and_usage_errors() {
    let st = bin().args(["run", "no-such-thing"]).output().unwrap();
    assert_eq!(st.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&st.stderr).contains("hil-sim list"));
    assert_eq!(bin().output().unwrap().status.code(), Some(2));
    let list = bin().arg("list").output().unwrap();
    assert!(String::from_utf8_lossy(&list.stdout).contains("speed-step"));
}

/// `bench` prints its figures as JSON, consistent with each other (factor = duration /
/// wall time; ns per period = wall time / periods), and rejects bad arguments.
#[test]
fn bench_reports_consistent_figures_and_rejects_bad_arguments() {
    let out = bin().args(["bench", "speed-step", "--runs", "1"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let f = |k: &str| v[k].as_f64().expect(k);
    let wall = f("median_wall_time_s");
    assert!(wall > 0.0);
    assert!((f("median_real_time_factor") - 3.5 / wall).abs() < 1e-9 * f("median_real_time_factor"));
    assert!((f("median_ns_per_pwm_period") - wall * 1e9 / 70_000.0).abs() < 1e-6);
    assert!(f("best_real_time_factor") >= f("median_real_time_factor"));
    for bad in
        [&["bench", "--runs", "0"][..], &["bench", "--runs"], &["bench", "no-such"], &["bench", "--fast"]]
    {
        let st = bin().args(bad).output().unwrap();
        assert_eq!(st.status.code(), Some(1), "{bad:?}");
        assert!(!String::from_utf8_lossy(&st.stderr).is_empty());
    }
}
