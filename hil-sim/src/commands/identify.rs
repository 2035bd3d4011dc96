//! `hil-sim identify`: self-commissioning in software in the loop (or on QEMU) against a
//! simulated motor ([`crate::identify`]), what it found against the motor, and the motor
//! file; and [`CommissionOptions`], what every commissioning run takes (`identify` and
//! `link … identify`).

use super::{INTERRUPTED, pil_options};
use report::write::write_text;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

/// What every commissioning run takes (`identify` and `link … identify`).
#[derive(Debug, Clone, PartialEq)]
pub struct CommissionOptions {
    /// The motor file to write.
    pub out: PathBuf,
    /// Test current, A: the higher DC level.
    pub test_current: f64,
    /// Phase-current limit during the tests, A (`None`: 2 × the test current).
    pub current_limit: Option<f64>,
    /// Time each DC level is held, s.
    pub level_time: f64,
    /// Assumed leakage split L_lr/L_ls.
    pub leakage_ratio: f64,
    /// The motor may turn: the rotating field and the no-load test after the standstill
    /// sequence.
    pub rotate: bool,
    /// With `rotate`: the no-load test measures the magnetizing curve too.
    pub curve: bool,
    /// Nameplate: rated line voltage, V RMS.
    pub rated_voltage: Option<f64>,
    /// Nameplate: rated frequency, Hz.
    pub rated_frequency: Option<f64>,
    /// The no-load test's field frequency, Hz (`None`: a quarter of the rated frequency, at
    /// least the rotating field's).
    pub no_load_frequency: Option<f64>,
}

impl CommissionOptions {
    /// The sequence's spec for a PWM rate and a bus range; refused with the flag to change.
    pub fn config(
        &self,
        pwm_hz: f64,
        vdc_v: (f64, f64),
    ) -> Result<controller_core::commission::CommissionConfig, String> {
        use controller_core::commission::{
            CommissionConfig, CommissionSpec, CommissionSpecError as E, ROTATION_HZ,
        };
        let spec = CommissionSpec {
            pwm_hz: pwm_hz as f32,
            test_current_a: self.test_current as f32,
            current_limit_a: self.current_limit.unwrap_or(2.0 * self.test_current) as f32,
            vdc_min_v: vdc_v.0 as f32,
            vdc_max_v: vdc_v.1 as f32,
            level_time_s: self.level_time as f32,
            rotate: self.rotate,
            rated_flux_wb: match (self.rated_voltage, self.rated_frequency) {
                (Some(v), Some(f)) => crate::identify::rated_flux_wb(v, f) as f32,
                _ => 0.0,
            },
            no_load_hz: self
                .no_load_frequency
                .or(self.rated_frequency.map(|f| (0.25 * f).max(f64::from(ROTATION_HZ))))
                .unwrap_or(0.0) as f32,
            curve: self.curve,
        };
        CommissionConfig::new(spec).map_err(|e| {
            match e {
                E::PwmFrequency => "the PWM frequency must lie in 1 … 100 kHz",
                E::TestCurrent => "--test-current must be positive",
                E::CurrentLimit => "--current-limit must be at least 1.5 × the test current",
                E::BusRange => "the bus range is empty",
                E::LevelTime => "--level-time must lie between 192 PWM periods and 60 s",
                E::NoLoad => "--no-load-frequency must lie in 2 … 400 Hz (and the rated flux be positive)",
                E::CurveWithoutRotation => {
                    "--curve needs --rotate: the curve is measured on the turning rotor"
                }
            }
            .to_string()
        })
    }

    /// Write the motor file for `id` (checked to load as a motor first; atomically).
    pub fn write(
        &self,
        id: &crate::identify::Identified,
        pole_pairs: u8,
        j_b: (f64, f64),
        about: &str,
    ) -> Result<(), String> {
        let text = crate::identify::motor_file(id, self.leakage_ratio, pole_pairs, j_b.0, j_b.1, about);
        drive_file::motor::parse(&self.out, &text)
            .map_err(|e| format!("the identified motor is not valid: {e}"))?;
        write_text(&self.out, &text)?;
        eprintln!("hil-sim: wrote {}", self.out.display());
        Ok(())
    }
}

/// What `identify` is asked.
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifyOptions {
    /// The motor to simulate: a shipped motor's name, a motor file, a drive file or a
    /// scenario file.
    pub motor: String,
    /// The commissioning run.
    pub run: CommissionOptions,
    /// DC-bus voltage, V (the accepted range is ±20 % of it).
    pub vdc: f64,
    /// PWM frequency, Hz.
    pub pwm_hz: f64,
    /// Seed of the sensors' noise.
    pub seed: u64,
    /// The motor's pole pairs (`None`: the simulated motor's).
    pub pole_pairs: Option<u8>,
    /// Swap the current channels of phases b and c (a wiring error the sequence refuses).
    pub swap_current_channels: bool,
    /// Make the encoder count backwards (a wiring error the rotating field finds).
    pub reverse_encoder: bool,
    /// Also write the pictures into this directory.
    pub plot_dir: Option<PathBuf>,
    /// Run the sequence on the emulated Cortex-M4F (QEMU) instead of in this process.
    pub pil: bool,
    /// With `pil`: the `pil` target program (`None`: the default).
    pub elf: Option<PathBuf>,
}

/// `hil-sim identify`: the sequence on the simulated motor (progress on stderr, Ctrl-C
/// stops it), the estimates printed against the motor simulated, the motor file written
/// (nothing when it fails), and the pictures if asked.
pub fn identify(a: &IdentifyOptions) -> Result<(), String> {
    use crate::identify::{self, Setup};
    use controller_core::commission::Stage;
    // Before anything runs: a plot directory that is a file, and --out onto the motor file
    // simulated (it replaced the motor silently; `design tune` refuses its own template: both
    // found by trying).
    a.plot_dir.as_deref().map(report::write::check_dir).transpose()?;
    let same = |p: &Path| std::fs::canonicalize(p).ok();
    if same(&a.run.out).is_some() && same(&a.run.out) == same(Path::new(&a.motor)) {
        return Err(format!(
            "--out {} is the motor simulated: identification writes a new motor file; choose another --out",
            a.run.out.display()
        ));
    }
    let (motor, saturation) = drive_file::motor::load_model(&a.motor).map_err(|e| e.to_string())?;
    let config = a.run.config(a.pwm_hz, (0.8 * a.vdc, 1.2 * a.vdc))?;
    let extras = drive_file::motor::load_plant_extras(&a.motor).map_err(|e| e.to_string())?;
    let mut setup = Setup::realistic(motor, config, a.vdc, a.seed);
    setup.saturation = saturation;
    setup.extras = crate::scenario::extras_of(&extras);
    if a.swap_current_channels {
        setup.injections.push(crate::sim::Injection::CurrentChannelsSwapped { first: 1, second: 2 });
    }
    if a.reverse_encoder {
        setup.injections.push(crate::sim::Injection::EncoderReversed);
    }
    let pole_pairs = a.pole_pairs.unwrap_or(motor.pole_pairs());
    let target = if a.pil {
        identify::Target::Pil(pil_options(a.elf.as_deref(), false)?)
    } else {
        identify::Target::InProcess
    };
    let mut shown = (None, -1.0);
    let (record, t) = identify::simulate_on(
        &setup,
        &target,
        |stage: Stage, t_s| {
            // Done or refused: the final call reports the simulation's allowance, not the time.
            let running = stage.index() < Stage::COUNT;
            if running && (shown.0 != Some(stage) || t_s - shown.1 >= 1.0) {
                eprint!(
                    "\rhil-sim: [{}/{}] {:<44} t = {t_s:5.1} s",
                    stage.index() + 1,
                    Stage::COUNT,
                    identify::stage_name(stage)
                );
                shown = (Some(stage), t_s);
            }
        },
        || INTERRUPTED.load(Ordering::Relaxed),
    )
    .map_err(|e| {
        eprintln!();
        e.to_string()
    })?;
    eprintln!();
    let id = identify::estimate(&config, &record, pole_pairs)?;
    let g = |x: f64| format!("{x:.5}");
    let row = |name: &str, e: &identify::Estimate, x: f64| {
        let iv = format!("[{}, {}]", g(e.interval[0]), g(e.interval[1]));
        report::outln!(
            "{name:<12} {:>12} {iv:>26} {:>12} {:>+7.2}%",
            g(e.value),
            g(x),
            100.0 * (e.value / x - 1.0)
        );
    };
    let header = || {
        report::outln!(
            "{:<12} {:>12} {:>26} {:>12} {:>8}",
            "parameter",
            "identified",
            "interval",
            "simulated",
            "error"
        )
    };
    // A plant richer than the circuit identified: what "simulated" leaves out, said first.
    let mut beyond = Vec::new();
    if let Some(r) = setup.extras.iron_loss_ohm {
        beyond.push(format!("iron loss (R_fe {r} Ω)"));
    }
    if let Some(d) = setup.extras.deep_bar {
        beyond.push(format!(
            "a deep bar (R_r ×{} above {} Hz of slip)",
            d.high_slip_resistance_factor, d.corner_slip_hz
        ));
    }
    if !beyond.is_empty() {
        report::outln!(
            "the simulated motor also has {}, which the sequence does not model: \"simulated\" below is its \
             circuit without them (the rotor's at zero slip)",
            beyond.join(" and ")
        );
    }
    let gamma_plant = saturation.filter(|s| s.form == controller_core::magnetics::Form::Gamma);
    if let (Some(fit), Some(sat), Some(nl)) = (id.gamma, gamma_plant, id.no_load.as_ref()) {
        // A saturating Γ machine identified on its curve: its own values at the flux the
        // no-load test reached (L_s the chord there).
        let truth = identify::gamma_truth(&motor, &sat.curve, nl.flux_wb);
        report::outln!(
            "motor time {t:.1} s; against the simulated Γ machine at the no-load test's {:.4} Wb:",
            nl.flux_wb
        );
        header();
        row("R_s Ω", &id.rs_ohm, motor.rs_ohm());
        row("L_s H", &fit.l_s_h, truth.l_s_h);
        row("L_σ H", &fit.l_sigma_h, truth.l_sigma_h);
        row("R_R Ω", &fit.r_r_ohm, truth.r_r_ohm);
        row("T_r s", &fit.tr_s, truth.tr_s);
    } else {
        let (l_sigma, l_mm, r_rr, tr) = identify::inverse_gamma(&motor);
        let tm = id.t_model(a.run.leakage_ratio);
        let truth = identify::t_model(motor.rs_ohm(), l_sigma, l_mm, r_rr, a.run.leakage_ratio);
        report::outln!(
            "motor time {t:.1} s; against the simulated motor (T-model under L_lr/L_ls = {}):",
            a.run.leakage_ratio
        );
        header();
        let rows: [(&str, &identify::Estimate, f64); 5] = [
            ("R_s Ω", &id.rs_ohm, motor.rs_ohm()),
            ("σL_s H", &id.l_sigma_h, l_sigma),
            ("T_r s", &id.tr_s, tr),
            ("L_M H", &id.l_mm_h, l_mm),
            ("R_R Ω", &id.r_rr_ohm, r_rr),
        ];
        for (name, e, x) in rows {
            row(name, e, x);
        }
        let t_rows = [
            ("R_r Ω", tm.rr_ohm, truth.rr_ohm),
            ("L_s H", tm.ls_h, truth.ls_h),
            ("L_r H", tm.lr_h, truth.lr_h),
            ("L_m H", tm.lm_h, truth.lm_h),
        ];
        for (name, v, x) in t_rows {
            report::outln!(
                "{name:<12} {:>12} {:>26} {:>12} {:>+7.2}%",
                g(v),
                "",
                g(x),
                100.0 * (v / x - 1.0)
            );
        }
    }
    let ve = a.vdc * 1e-6 * a.pwm_hz;
    report::outln!(
        "inverter voltage error {} V per phase (the simulated 1 µs dead time: {} V); offsets {:?} A",
        g(id.inverter_error_v.value),
        g(ve),
        id.offsets_a.map(|o| (o * 1e5).round() / 1e5)
    );
    if let Some(r) = &id.rotation {
        report::outln!(
            "rotating field: the rotor turned {:.4}× the field ({:.2} rad/s); J {} kg·m² [{}, {}] (simulated {}), \
             B {} N·m·s/rad [{}, {}] (simulated {})",
            r.ratio,
            r.omega_hold_rad_s,
            g(r.j_kgm2.value),
            g(r.j_kgm2.interval[0]),
            g(r.j_kgm2.interval[1]),
            g(motor.j_kgm2()),
            g(r.b_nms.value),
            g(r.b_nms.interval[0]),
            g(r.b_nms.interval[1]),
            g(motor.b_nms()),
        );
    }
    if let Some(n) = &id.no_load {
        report::outln!("{}", crate::identify::describe_no_load(n));
    }
    for line in crate::identify::describe_curve(&id) {
        report::outln!("{line}");
    }
    let about = format!(
        "Simulated commissioning of `{}` (hil-sim identify: {} V bus, {} Hz PWM, test current {} A, seed {}).",
        a.motor, a.vdc, a.pwm_hz, a.run.test_current, a.seed
    );
    // Nothing in the text says where the sequence ran: SIL and PIL write the same file.
    a.run.write(&id, pole_pairs, (motor.j_kgm2(), motor.b_nms()), &about)?;
    if let Some(dir) = &a.plot_dir {
        std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        for (name, svg) in identify::plots(&config, &record, &id, pole_pairs) {
            write_text(&dir.join(name), &svg)?;
        }
        eprintln!("hil-sim: wrote the pictures in {}", dir.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("hil-sim-identify-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    fn options(motor: &str, out: PathBuf) -> IdentifyOptions {
        IdentifyOptions {
            motor: motor.into(),
            run: CommissionOptions {
                out,
                test_current: 1.24,
                current_limit: None,
                level_time: 3.0,
                leakage_ratio: 1.0,
                rotate: false,
                curve: false,
                rated_voltage: None,
                rated_frequency: None,
                no_load_frequency: None,
            },
            vdc: 310.0,
            pwm_hz: 20_000.0,
            seed: 1,
            pole_pairs: None,
            swap_current_channels: false,
            reverse_encoder: false,
            plot_dir: None,
            pil: false,
            elf: None,
        }
    }

    /// The sequence's spec refused names the flag to change.
    #[test]
    fn a_bad_spec_names_its_flag() {
        let mut o = options("delorenzo-appendix", tmp("spec").join("motor.toml")).run;
        o.current_limit = Some(1.0);
        assert!(o.config(20_000.0, (250.0, 370.0)).unwrap_err().contains("--current-limit"));
        o.current_limit = None;
        o.level_time = 1e-4;
        assert!(o.config(20_000.0, (250.0, 370.0)).unwrap_err().contains("--level-time"));
        o.level_time = 3.0;
        assert!(o.config(200_000.0, (250.0, 370.0)).unwrap_err().contains("PWM frequency"));
        assert!(o.config(20_000.0, (250.0, 370.0)).is_ok());
    }

    /// Refused before anything runs: `--out` onto the motor file simulated, a plot directory
    /// that is a file, a motor that is not there — and the motor file is left as it was.
    #[test]
    fn outputs_that_cannot_be_are_refused_before_the_run() {
        let dir = tmp("refused");
        std::fs::create_dir_all(&dir).unwrap();
        let motor = dir.join("motor.toml");
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../drive.toml")).unwrap();
        std::fs::write(&motor, &text).unwrap();
        let e = identify(&options(motor.to_str().unwrap(), motor.clone())).unwrap_err();
        assert!(e.contains("is the motor simulated"), "{e}");
        let mut o = options(motor.to_str().unwrap(), dir.join("new.toml"));
        o.plot_dir = Some(motor.clone());
        let e = identify(&o).unwrap_err();
        assert!(e.contains("exists and is not a directory"), "{e}");
        let e = identify(&options("no-such-motor", dir.join("new.toml"))).unwrap_err();
        assert!(e.contains("no-such-motor"), "{e}");
        assert_eq!(std::fs::read_to_string(&motor).unwrap(), text);
        assert!(!dir.join("new.toml").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
