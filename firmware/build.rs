//! Puts the workspace's single `memory.x` on the linker search path; for the board target
//! also links defmt's section script. Writes `certified.rs`: the speed-gain ranges of
//! `gains.toml`'s `[certify]` table (checked by `design certify`), the limits the firmware
//! enforces on gains written over its link.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join("memory.x");
    if let Err(e) = fs::copy(&src, out.join("memory.x")) {
        println!("cargo::warning=cannot copy {}: {e}", src.display());
    }
    println!("cargo::rustc-link-search={}", out.display());
    println!("cargo::rerun-if-changed={}", src.display());
    let gains = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join("gains.toml");
    println!("cargo::rerun-if-changed={}", gains.display());
    match certified_ranges(&gains) {
        Ok(code) => {
            if let Err(e) = fs::write(out.join("certified.rs"), code) {
                println!("cargo::error=cannot write certified.rs: {e}");
            }
        }
        Err(e) => println!("cargo::error={}: {e}", gains.display()),
    }
    if env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none") {
        println!("cargo::rustc-link-arg-bins=-Tdefmt.x");
    }
}

/// `[certify] speed_kp_writable` and `speed_tau_max_nm_writable` as Rust constants.
fn certified_ranges(path: &std::path::Path) -> Result<String, String> {
    let text = fs::read_to_string(path).map_err(|e| e.to_string())?;
    let table: toml::Table = text.parse().map_err(|e: toml::de::Error| e.to_string())?;
    let certify = table.get("certify").and_then(|c| c.as_table()).ok_or("no [certify] table")?;
    let range = |key: &str| -> Result<(f64, f64), String> {
        let a = certify.get(key).and_then(|v| v.as_array()).ok_or(format!("certify.{key}: missing"))?;
        let num = |i: usize| a.get(i).and_then(|v| v.as_float()).ok_or(format!("certify.{key}: two floats"));
        let (lo, hi) = (num(0)?, num(1)?);
        if a.len() == 2 && lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi {
            Ok((lo, hi))
        } else {
            Err(format!("certify.{key}: needs [lo, hi] with 0 < lo ≤ hi"))
        }
    };
    let (kp_lo, kp_hi) = range("speed_kp_writable")?;
    let (tau_lo, tau_hi) = range("speed_tau_max_nm_writable")?;
    Ok(format!(
        "/// Saturated-P speed gain accepted over the link, N·m per rad/s (gains.toml).\n\
         pub const SPEED_KP: (f32, f32) = ({kp_lo:?}, {kp_hi:?});\n\
         /// τ_max accepted over the link, N·m (gains.toml).\n\
         pub const SPEED_TAU_MAX_NM: (f32, f32) = ({tau_lo:?}, {tau_hi:?});\n"
    ))
}
