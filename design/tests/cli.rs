//! CLI contract of `design kharitonov`.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use std::process::Command;

const PLANT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/plants/seed000-current.toml");

fn run(args: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_design")).args(args).output().unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stdout).into(), String::from_utf8_lossy(&o.stderr).into())
}

#[test]
fn seed000_pi1_json() {
    let (code, out, _) = run(&["kharitonov", "--plant", PLANT, "--pi", "30,50", "--json"]);
    assert_eq!(code, Some(0));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["robust_stable"], true);
    let worst = v["worst_pole_re"].as_f64().unwrap();
    assert!(worst < 0.0 && worst > -1.0, "{worst}");
    assert_eq!(v["plants"].as_array().unwrap().len(), 16);
}

#[test]
fn destabilising_gain_exits_1_and_bad_input_exits_2() {
    // A negative integral gain puts a closed-loop pole in the right half plane.
    let (code, out, _) = run(&["kharitonov", "--plant", PLANT, "--pi", "30,-50", "--json"]);
    assert_eq!(code, Some(1));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["robust_stable"], false);
    assert!(v["worst_pole_re"].as_f64().unwrap() > 0.0);
    let (code, _, err) = run(&["kharitonov", "--plant", PLANT, "--pi", "30"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("KP,KI"));
    let (code, _, err) = run(&["kharitonov", "--plant", "/nonexistent.toml", "--pi", "1,1"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("/nonexistent.toml"));
}

#[test]
fn plot_writes_the_region() {
    let path = std::env::temp_dir().join(format!("design-region-{}.svg", std::process::id()));
    let p = path.to_str().unwrap();
    let (code, _, err) = run(&[
        "kharitonov",
        "--plant",
        PLANT,
        "--pi",
        "30,50",
        "--plot",
        p,
        "--kp-range",
        "-5,90",
        "--ki-range",
        "-20,150",
    ]);
    assert_eq!(code, Some(0), "{err}");
    let svg = std::fs::read_to_string(&path).unwrap();
    // 16 loci + the k_i = 0 line are paths; the robust grid and the PI point are dots.
    assert!(svg.matches("<path").count() >= 17);
    assert!(svg.matches("<circle").count() > 1000);
    let _ = std::fs::remove_file(&path);
    let (code, _, err) =
        run(&["kharitonov", "--plant", PLANT, "--pi", "30,50", "--plot", p, "--kp-range", "5,1"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("LO < HI"));
}

#[test]
fn icad_json_contract() {
    let (code, out, err) =
        run(&["icad", "--motor", "delorenzo-eq13", "--omega-r", "375", "--controller", "icad20", "--json"]);
    assert_eq!(code, Some(0), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    for key in [
        "crossover_rad_s",
        "phase_margin_deg",
        "gain_margin_reduction_db",
        "bandwidth_rad_s",
        "coupling_peak_db",
        "gamma_margin_db",
        "gamma_h_margin_db",
        "gm_min",
        "stable_omega_r_max_rad_s",
    ] {
        assert!(v[key].is_number(), "{key} missing in {out}");
    }
    assert!((v["crossover_rad_s"].as_f64().unwrap() - 3350.0).abs() < 70.0);
    assert_eq!(v["stable_omega_r_max_rad_s"].as_f64().unwrap(), 645.0);
    // Beyond the limit the loop is unstable: exit 1.
    let (code, out, _) =
        run(&["icad", "--motor", "delorenzo-eq13", "--omega-r", "800", "--controller", "icad20", "--json"]);
    assert_eq!(code, Some(1));
    assert_eq!(serde_json::from_str::<serde_json::Value>(&out).unwrap()["stable_at_omega_r"], false);
    let (code, _, err) =
        run(&["icad", "--motor", "delorenzo-eq13", "--omega-r", "375", "--controller", "lqr"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("lqr"));
    let (code, out, _) = run(&[
        "icad",
        "--motor",
        "delorenzo-eq13",
        "--omega-r",
        "375",
        "--controller",
        "pi:360,9000",
        "--json",
    ]);
    assert_eq!(code, Some(0));
    assert!(
        serde_json::from_str::<serde_json::Value>(&out).unwrap()["phase_margin_deg"].as_f64().unwrap() > 45.0
    );
}

#[test]
fn certify_the_shipped_gains_and_reject_a_bad_range() {
    let gains = concat!(env!("CARGO_MANIFEST_DIR"), "/../gains.toml");
    let (code, out, err) = run(&["certify", gains, "--json"]);
    assert_eq!(code, Some(0), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["certified"], true);
    let bad = std::env::temp_dir().join(format!("gains-bad-{}.toml", std::process::id()));
    let text = std::fs::read_to_string(gains)
        .unwrap()
        .replace("omega_r_max_rad_s = 375.0", "omega_r_max_rad_s = 800.0");
    std::fs::write(&bad, text).unwrap();
    let (code, _, err) = run(&["certify", bad.to_str().unwrap()]);
    assert_eq!(code, Some(1));
    assert!(err.contains("closed-loop pole"), "{err}");
    let _ = std::fs::remove_file(&bad);
}
