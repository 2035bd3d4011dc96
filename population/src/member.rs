//! Members of the population: a motor drawn from the scaling laws ([`crate::laws`]) with its
//! nameplate, on a board drawn for its voltage class, written as the template a new user
//! writes from the nameplate — or a shipped motor on its shipped template.
//!
//! **The board** ([`Board`]), drawn per member:
//! - voltage class from the rated power ([`VOLTAGE_CLASSES`]): 24/48 V battery drives
//!   below 1 kW, 230/400/480 V mains from 0.1 to 200 kW, 690 V from 10 kW; the bus is
//!   `√2·V_LL × bus ratio`, the ratio uniform in [`BUS_RATIO`] (a rectified mains at its
//!   tolerance, a battery partly discharged: below 1 the bus cannot give the rated flux at
//!   rated speed);
//! - dead time by switch technology ([`dead_time_range_s`]): MOSFETs on a 24–48 V bus
//!   0.3–0.6 µs, IGBTs on 230–480 V 0.8–2 µs, on 690 V 1.5–3 µs (log-uniform);
//! - PWM from 4 to 20 kHz (log-uniform), unless the run sets it;
//! - the current limit 1.4 × the rated peak (the tester's rule of issue 49), the trip
//!   level [`TRIP_OVER_LIMIT`] above it, the current sensors' full scale 1.1–2 × the trip
//!   level on a 12-bit ADC, the bus channel's 1.05–1.5 × the overvoltage trip, the
//!   hardware comparator 1.15–1.4 × the trip level, the inverter rated 1–2 × the motor's
//!   current (150 % for 60 s), an encoder of 500–4 096 lines;
//! - the bus trips at 0.7 and 1.25 × the nominal bus, the chopper on at 0.9 × the
//!   overvoltage trip (below the drive's regeneration cut at 0.925).
//!
//! **The template** ([`Member::template`]) holds what the nameplate and the board give:
//! the motor as its model, flux reference = the rated rotor flux, the certificate's box
//! of the walk-through's template (R_s × [1, 1.5], R_r × [1, 1.2], L × [0.95, 1.05],
//! J × [1, 2]) and its top speed twice the rated frequency; `design tune` replaces the gains.

use crate::laws::{self, Circuit, Nameplate, Unphysical};
use controller_core::motor::MotorParams;
use hil_sim::rng::{Rng, mix};
use std::f64::consts::{PI, SQRT_2};
use std::fmt::Write as _;

/// Voltage classes: (rated line voltage V, frequency Hz, least and largest rated power W,
/// weight). A 24 V or 48 V class is a battery drive: its motor's rated line voltage is what
/// its bus gives.
pub const VOLTAGE_CLASSES: [(f64, f64, f64, f64, f64); 6] = [
    (17.0, 50.0, 100.0, 1_000.0, 1.0),
    (34.0, 50.0, 100.0, 2_000.0, 1.0),
    (230.0, 50.0, 100.0, 20_000.0, 2.0),
    (400.0, 50.0, 180.0, 200_000.0, 4.0),
    (480.0, 60.0, 180.0, 200_000.0, 2.0),
    (690.0, 50.0, 10_000.0, 200_000.0, 2.0),
];

/// The population's rated powers, W (log-uniform between).
pub const POWER_RANGE_W: [f64; 2] = [100.0, 200_000.0];
/// Bus voltage over the peak rated line voltage.
pub const BUS_RATIO: [f64; 2] = [0.95, 1.15];
/// Current limit over the rated peak phase current.
pub const LIMIT_OVER_RATED_PEAK: f64 = 1.4;
/// Trip level over the current limit.
pub const TRIP_OVER_LIMIT: f64 = 1.5;
/// PWM rates a board has, Hz.
pub const PWM_RANGE_HZ: [f64; 2] = [4_000.0, 20_000.0];
/// Pole pairs and their weights (4-pole machines are the most common).
pub const POLE_PAIRS: [(u8, f64); 4] = [(1, 2.0), (2, 5.0), (3, 2.0), (4, 1.0)];
/// Encoder line counts.
pub const ENCODER_LINES: [u32; 5] = [500, 1024, 2048, 2500, 4096];
/// The slow (speed) loop's rate the templates aim at, Hz: the divider is the PWM rate over
/// it, rounded, at least 1.
pub const SLOW_RATE_HZ: f64 = 2_000.0;

/// The dead time's range for a bus of `vdc_v`, s: the switches such a bus uses.
pub fn dead_time_range_s(vdc_v: f64) -> [f64; 2] {
    if vdc_v < 100.0 {
        [0.3e-6, 0.6e-6]
    } else if vdc_v < 800.0 {
        [0.8e-6, 2.0e-6]
    } else {
        [1.5e-6, 3.0e-6]
    }
}

/// An inverter board.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Board {
    /// Nominal bus voltage, V.
    pub vdc_v: f64,
    /// PWM rate, Hz.
    pub pwm_hz: f64,
    /// Dead time, s.
    pub dead_time_s: f64,
    /// Current sensors' full scale (± peak), A.
    pub current_full_scale_a: f64,
    /// Bus channel's full scale, V.
    pub vdc_full_scale_v: f64,
    /// Hardware comparator's trip level, A.
    pub comparator_a: f64,
    /// Inverter's rated RMS current, A.
    pub inverter_rated_a: f64,
    /// Encoder lines.
    pub encoder_lines: u32,
    /// Current limit, A.
    pub i_ref_max_a: f64,
    /// Trip level, A.
    pub i_trip_a: f64,
}

impl Board {
    /// This board at the PWM rate nearest `hz` its timer makes ([`timer_rate_hz`]).
    /// Its dead time is cut to [`DEAD_TIME_MAX_SHARE`] of the half-period: a board built for
    /// that rate has switches fast enough.
    pub fn at_pwm(self, hz: f64) -> Self {
        let pwm_hz = timer_rate_hz(hz);
        Self { pwm_hz, dead_time_s: self.dead_time_s.min(DEAD_TIME_MAX_SHARE * 0.5 / pwm_hz), ..self }
    }
    /// Undervoltage trip, V.
    pub fn vdc_min_v(&self) -> f64 {
        0.7 * self.vdc_v
    }
    /// Overvoltage trip, V.
    pub fn vdc_max_v(&self) -> f64 {
        1.25 * self.vdc_v
    }
}

/// The largest dead time a board has as a share of the PWM half-period: a designer does not
/// run 3 µs IGBTs at 20 kHz (the drive file refuses more than 5 %).
pub const DEAD_TIME_MAX_SHARE: f64 = 0.04;

/// The boards' PWM timer clock, Hz: the core's, on which the firmware runs TIM1 (the drive file
/// refuses another).
pub const TIM_CLOCK_HZ: f64 = controller_core::drive::CORE_CLOCK_HZ;

/// The centre-aligned PWM rate nearest `hz` that a whole number of timer ticks makes.
pub fn timer_rate_hz(hz: f64) -> f64 {
    TIM_CLOCK_HZ / (2.0 * (TIM_CLOCK_HZ / (2.0 * hz)).round())
}

/// Where a member comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Origin {
    /// Drawn: the population's seed and the member's index.
    Drawn {
        /// Seed.
        seed: u64,
        /// Index.
        index: u64,
        /// Circuits drawn again because the screens refused them.
        redraws: u32,
    },
    /// A shipped template and motor file (paths from the repository's root).
    Shipped {
        /// The template drive file.
        template: &'static str,
        /// The motor file.
        motor: &'static str,
    },
}

/// One member: a motor with its nameplate on a board.
#[derive(Clone, Debug, PartialEq)]
pub struct Member {
    /// A short name (power, voltage, poles, index).
    pub name: String,
    /// Where it comes from.
    pub origin: Origin,
    /// The nameplate (drawn members; `None` for shipped motors, whose files state theirs in
    /// their comments).
    pub nameplate: Option<Nameplate>,
    /// The motor's model (with any coupled load's inertia in `j_kgm2`).
    pub motor: MotorParams,
    /// The winding's thermal time constant, s.
    pub thermal_time_constant_s: f64,
    /// The board (drawn members).
    pub board: Option<Board>,
}

/// The shipped drives: each template with the motor file it was written for.
pub const SHIPPED: [(&str, &str); 5] = [
    ("drive.toml", "motors/delorenzo-appendix.toml"),
    ("drive.toml", "motors/delorenzo-eq13.toml"),
    ("drive.toml", "motors/delorenzo-perturbed.toml"),
    ("drives/em-synergy-24v.toml", "motors/em-synergy-m800006.toml"),
    ("drives/krause-3300v.toml", "motors/krause-2300v-500hp.toml"),
];

fn pick<T: Copy>(rng: &mut Rng, items: &[(T, f64)]) -> Option<T> {
    let total: f64 = items.iter().map(|(_, w)| w).sum();
    let mut u = rng.uniform() * total;
    for (x, w) in items {
        if u <= *w {
            return Some(*x);
        }
        u -= w;
    }
    items.last().map(|(x, _)| *x)
}

fn log_uniform(rng: &mut Rng, [lo, hi]: [f64; 2]) -> f64 {
    lo * (hi / lo).powf(rng.uniform())
}

fn uniform(rng: &mut Rng, [lo, hi]: [f64; 2]) -> f64 {
    lo + (hi - lo) * rng.uniform()
}

/// Draws a circuit for the given rating until the screens keep one (at most `MAX_REDRAWS`).
const MAX_REDRAWS: u32 = 200;

/// Member `index` of the population of `seed` (the same pair gives the same member on any
/// machine); `pwm_hz` fixes the board's PWM rate (`None`: drawn).
pub fn draw(seed: u64, index: u64, pwm_hz: Option<f64>) -> Result<Member, String> {
    let mut rng = Rng(mix(seed ^ mix(index)));
    let power_w = log_uniform(&mut rng, POWER_RANGE_W);
    let classes: Vec<_> = VOLTAGE_CLASSES
        .iter()
        .filter(|c| (c.2..=c.3).contains(&power_w))
        .map(|&(v, f, _, _, w)| ((v, f), w))
        .collect();
    let (line_voltage_v, frequency_hz) =
        pick(&mut rng, &classes).ok_or_else(|| format!("no voltage class holds {power_w:.0} W"))?;
    let pole_pairs = pick(&mut rng, &POLE_PAIRS).unwrap_or(2);
    let p_kw = power_w / 1e3;
    let z_b = line_voltage_v * line_voltage_v / power_w;
    let omega_e = 2.0 * PI * frequency_hz;
    let mut redraws = 0;
    let (circuit, plate) = loop {
        let c = Circuit {
            rs_ohm: laws::RS_PU.draw(p_kw, rng.normal()) * z_b,
            rr_ohm: laws::RR_PU.draw(p_kw, rng.normal()) * z_b,
            xls_ohm: laws::XL_PU.draw(p_kw, rng.normal()) * z_b,
            xlr_ohm: 0.0,
            xm_ohm: laws::xm_pu(p_kw, pole_pairs, rng.normal()) * z_b,
        };
        let c = Circuit { xlr_ohm: c.xls_ohm, ..c };
        match laws::nameplate(&c, power_w, line_voltage_v, frequency_hz, pole_pairs) {
            Ok(n) => break (c, n),
            Err(why) if redraws < MAX_REDRAWS => {
                let _: Unphysical = why;
                redraws += 1;
            }
            Err(why) => {
                return Err(format!("member {index}: no physical circuit in {MAX_REDRAWS} draws ({why:?})"));
            }
        }
    };
    let omega_m = 2.0 * PI * plate.speed_rpm / 60.0;
    let h_s = laws::H_S.draw(p_kw, rng.normal());
    let j_motor = 2.0 * h_s * power_w / (omega_m * omega_m);
    let load_share = if rng.uniform() < laws::LOAD_FREE_PROBABILITY {
        0.0
    } else {
        log_uniform(&mut rng, laws::LOAD_INERTIA_SHARE)
    };
    let lm_h = circuit.xm_ohm / omega_e;
    let ll_h = circuit.xls_ohm / omega_e;
    let motor = MotorParams::new(
        circuit.rs_ohm,
        circuit.rr_ohm,
        lm_h + ll_h,
        lm_h + ll_h,
        lm_h,
        pole_pairs,
        j_motor * (1.0 + load_share),
        laws::FRICTION_SHARE * plate.torque_nm / omega_m,
    )
    .map_err(|e| format!("member {index}: {e:?}"))?;
    let thermal =
        laws::THERMAL_S.draw(p_kw, rng.normal()).clamp(laws::THERMAL_RANGE_S[0], laws::THERMAL_RANGE_S[1]);
    let vdc_v = SQRT_2 * line_voltage_v * uniform(&mut rng, BUS_RATIO);
    let i_ref_max_a = LIMIT_OVER_RATED_PEAK * SQRT_2 * plate.current_a;
    let i_trip_a = TRIP_OVER_LIMIT * i_ref_max_a;
    let board = Board {
        vdc_v,
        pwm_hz: timer_rate_hz(pwm_hz.unwrap_or_else(|| log_uniform(&mut rng, PWM_RANGE_HZ))),
        dead_time_s: log_uniform(&mut rng, dead_time_range_s(vdc_v)),
        current_full_scale_a: i_trip_a * uniform(&mut rng, [1.1, 2.0]),
        vdc_full_scale_v: 1.25 * vdc_v * uniform(&mut rng, [1.05, 1.5]),
        comparator_a: i_trip_a * uniform(&mut rng, [1.15, 1.4]),
        inverter_rated_a: plate.current_a * uniform(&mut rng, [1.0, 2.0]),
        encoder_lines: ENCODER_LINES
            .get((rng.next_u64() % ENCODER_LINES.len() as u64) as usize)
            .copied()
            .unwrap_or(1024),
        i_ref_max_a,
        i_trip_a,
    };
    let board = board.at_pwm(board.pwm_hz);
    let name = format!(
        "{index:03}-{}-{:.0}V-{}p{}",
        power_name(power_w),
        line_voltage_v,
        2 * pole_pairs,
        if load_share > 0.0 { "-load" } else { "" }
    );
    Ok(Member {
        name,
        origin: Origin::Drawn { seed, index, redraws },
        nameplate: Some(plate),
        motor,
        thermal_time_constant_s: thermal,
        board: Some(board),
    })
}

/// "2.2kW", "370W".
pub fn power_name(w: f64) -> String {
    if w >= 1e3 {
        let kw = w / 1e3;
        if kw >= 10.0 { format!("{kw:.0}kW") } else { format!("{kw:.1}kW") }
    } else {
        format!("{w:.0}W")
    }
}

impl Member {
    /// The `[motor]` table of model `m` as drive-file writes motor files
    /// (`drive_file::motor::MotorTable`), with this member's rated current and thermal time
    /// constant and `saturation`'s curve, if any; `None` for a drawn member without a
    /// nameplate.
    pub(crate) fn motor_table(
        &self,
        m: &MotorParams,
        saturation: Option<drive_file::motor::SaturationTable>,
    ) -> Option<String> {
        #[derive(serde::Serialize)]
        struct MotorFile {
            motor: drive_file::motor::MotorTable,
        }
        let motor = drive_file::motor::MotorTable {
            rated_current_a: Some(self.nameplate?.current_a),
            thermal_time_constant_s: Some(self.thermal_time_constant_s),
            saturation,
            ..drive_file::motor::MotorTable::from_params(m)
        };
        Some(toml::to_string(&MotorFile { motor }).ok()?.trim_end().to_owned())
    }

    /// The template drive file a user writes from the nameplate and the board (drawn
    /// members), `None` for a shipped member (its template is a file).
    pub fn template(&self) -> Option<String> {
        let (plate, b) = (self.nameplate?, self.board?);
        let m = &self.motor;
        let divider = (b.pwm_hz / SLOW_RATE_HZ).round().max(1.0);
        let sigma_ls = m.ls_h() - m.lm_h() * m.lm_h() / m.lr_h();
        let omega_c = 2.0 * PI * b.pwm_hz / 20.0;
        let omega_m_rated = 2.0 * PI * plate.speed_rpm / 60.0;
        let tau_max = 1.5 * plate.torque_nm;
        let omega_e = 2.0 * PI * plate.frequency_hz;
        let mut t = String::new();
        let _ = writeln!(
            t,
            "# Population member {}: {} {:.0} V {:.0} Hz {}-pole, {:.3} A, {:.0} r/min, {:.4} N·m, cos φ {:.3},\n\
             # η {:.3}, breakdown {:.2} × rated, no-load current {:.2} of rated (drawn from the scaling laws of\n\
             # population/src/laws.rs); a {:.0} V bus, {:.1} kHz PWM, {:.2} µs dead time.",
            self.name,
            power_name(plate.power_w),
            plate.line_voltage_v,
            plate.frequency_hz,
            2 * plate.pole_pairs,
            plate.current_a,
            plate.speed_rpm,
            plate.torque_nm,
            plate.power_factor,
            plate.efficiency,
            plate.breakdown,
            plate.magnetizing_share,
            b.vdc_v,
            b.pwm_hz / 1e3,
            b.dead_time_s * 1e6
        );
        let _ = writeln!(t, "\n[pwm]\nfrequency_hz = {:?}\nslow_divider = {divider}", b.pwm_hz);
        let _ = writeln!(t, "\n{}", self.motor_table(m, None)?);
        let _ = writeln!(
            t,
            "\n[controller]\ncurrent = {{ kind = \"pi\", kp = {:?}, ki = {:?} }}\ncurrent_frame = \"stationary\"\n\
             speed = {{ kind = \"saturated_p\", kp = {:?}, tau_max_nm = {:?} }}\n\
             position = {{ k_per_s = 10.0, omega_max_rad_s = {:?} }}\nflux_ref_wb = {:?}\ni_ref_max_a = {:?}",
            omega_c * sigma_ls,
            omega_c * (m.rs_ohm() + m.rr_ohm()),
            m.j_kgm2() * 10.0,
            tau_max,
            omega_m_rated,
            plate.rotor_flux_wb,
            b.i_ref_max_a
        );
        let chopper_on = 0.9 * b.vdc_max_v();
        let _ = writeln!(
            t,
            "\n[protection]\ni_trip_a = {:?}\nvdc_min_v = {:?}\nvdc_max_v = {:?}\n\
             brake_chopper = {{ on_v = {:?}, off_v = {:?} }}",
            b.i_trip_a,
            b.vdc_min_v(),
            b.vdc_max_v(),
            chopper_on,
            0.97 * chopper_on
        );
        let _ = writeln!(
            t,
            "\n[certify]\nomega_r_max_rad_s = {:?}\nrs_factor = [1.0, 1.5]\nrr_factor = [1.0, 1.2]\n\
             inductance_factor = [0.95, 1.05]\nj_factor = [1.0, 2.0]\nspeed_kp_writable = [{:?}, {:?}]\n\
             speed_tau_max_nm_writable = [{:?}, {:?}]\nphase_margin_deg_min = 45.0\ngain_margin_db_min = 6.0\n\
             gamma_h_margin_db_min = 1.0",
            2.0 * omega_e,
            m.j_kgm2() * 5.0,
            m.j_kgm2() * 20.0,
            tau_max / 20.0,
            tau_max
        );
        let _ = writeln!(
            t,
            "\n[board]\ntim_clock_hz = {:.0}\ndead_time_s = {:?}\nadc_full_scale = 4095\n\
             current_a_per_count = {:?}\ncurrent_offset_counts = 2048\nvdc_v_per_count = {:?}\nvdc_rated_v = {:?}\n\
             encoder_lines = {}\nlink_timeout_s = 1.0\ninverter_rated_current_a = {:?}\n\
             inverter_overload = {{ factor = 1.5, time_s = 60.0 }}\ncomparator = {{ trip_a = {:?}, filter_s = 1e-6 }}",
            TIM_CLOCK_HZ,
            b.dead_time_s,
            b.current_full_scale_a / 2048.0,
            b.vdc_full_scale_v / 4095.0,
            b.vdc_v,
            b.encoder_lines,
            b.inverter_rated_a,
            b.comparator_a
        );
        Some(t)
    }
}

/// The shipped members ([`SHIPPED`]): each motor file on its template, read under `root`
/// (the repository).
pub fn shipped(root: &std::path::Path) -> Result<Vec<Member>, String> {
    SHIPPED
        .iter()
        .map(|&(template, motor_file)| {
            // Read from the repository (the templates are files, not built in): run elsewhere,
            // say where they are looked for and what to do, not just that a path is missing.
            for file in [template, motor_file] {
                if !root.join(file).is_file() {
                    return Err(format!(
                        "{}: no such file — the shipped drives and motors are read from the repository: run \
                         from its root (where drive.toml is)",
                        root.join(file).display()
                    ));
                }
            }
            let path = root.join(motor_file);
            let motor = drive_file::motor::load(&path.display().to_string()).map_err(|e| e.to_string())?;
            let stem = |p: &str| {
                std::path::Path::new(p)
                    .file_stem()
                    .map_or(String::new(), |s| s.to_string_lossy().into_owned())
            };
            Ok(Member {
                name: format!("shipped-{}-on-{}", stem(motor_file), stem(template)),
                origin: Origin::Shipped { template, motor: motor_file },
                nameplate: None,
                motor,
                thermal_time_constant_s: f64::NAN,
                board: None,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped members are read from the repository's files: asked elsewhere, the error
    /// says where they were looked for and to run from the repository's root (it said
    /// "./motors/delorenzo-appendix.toml: neither a file nor a shipped motor").
    #[test]
    fn the_shipped_members_asked_outside_the_repository_say_where_to_run() {
        let e = shipped(std::path::Path::new("/nonexistent")).unwrap_err();
        assert!(
            e.starts_with("/nonexistent/drive.toml: no such file") && e.contains("run from its root"),
            "{e}"
        );
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        assert_eq!(shipped(&root).unwrap().len(), SHIPPED.len());
    }

    /// A seed names the population: the same member on every call, another seed another one.
    #[test]
    fn a_seed_and_an_index_name_one_member() {
        assert_eq!(draw(7, 3, None).unwrap(), draw(7, 3, None).unwrap());
        assert_ne!(draw(7, 3, None).unwrap().motor, draw(8, 3, None).unwrap().motor);
    }

    /// Every drawn member's template is a valid drive file (the drive-file crate's own
    /// checks), its nameplate is its circuit's rated point, and its PWM rate is one the
    /// timer makes.
    #[test]
    fn drawn_templates_are_drive_files_of_their_nameplate() {
        for i in 0..40 {
            let m = draw(1, i, None).unwrap();
            let text = m.template().unwrap();
            let path = std::path::Path::new("member.toml");
            let file = drive_file::DriveFile::parse(path, &text)
                .unwrap_or_else(|e| panic!("{}: {e}\n{text}", m.name));
            assert_eq!(file.spec.motor, m.motor);
            let (n, b) = (m.nameplate.unwrap(), m.board.unwrap());
            // The bus it was drawn with is the file's rated bus: every command runs on it.
            assert_eq!(file.rated_bus_v(), Some(b.vdc_v));
            assert!((POWER_RANGE_W[0]..=POWER_RANGE_W[1]).contains(&n.power_w));
            // The rated point again, from the model the template holds.
            let omega_e = 2.0 * PI * n.frequency_hz;
            let mo = &file.spec.motor;
            let c = Circuit {
                rs_ohm: mo.rs_ohm(),
                rr_ohm: mo.rr_ohm(),
                xls_ohm: omega_e * (mo.ls_h() - mo.lm_h()),
                xlr_ohm: omega_e * (mo.lr_h() - mo.lm_h()),
                xm_ohm: omega_e * mo.lm_h(),
            };
            let o = c.at(n.slip, n.line_voltage_v / 3f64.sqrt());
            assert!((o.mechanical_w / n.power_w - 1.0).abs() < 1e-6, "{}: {o:?}", m.name);
            let ticks = TIM_CLOCK_HZ / (2.0 * b.pwm_hz);
            assert!((ticks - ticks.round()).abs() < 1e-6, "{}: {} Hz", m.name, b.pwm_hz);
        }
    }

    /// The population spans what issue 49 asks: 100 W … ≥ 100 kW, 24 … 690 V classes,
    /// 1 … 4 pole pairs, with and without a coupled load, dead times 0.3 … 3 µs.
    #[test]
    fn the_population_spans_the_classes() {
        let all: Vec<Member> = (0..300).map(|i| draw(1, i, None).unwrap()).collect();
        let plates: Vec<Nameplate> = all.iter().filter_map(|m| m.nameplate).collect();
        let boards: Vec<Board> = all.iter().filter_map(|m| m.board).collect();
        assert!(plates.iter().any(|n| n.power_w < 200.0) && plates.iter().any(|n| n.power_w > 100e3));
        for v in [17.0, 34.0, 230.0, 400.0, 480.0, 690.0] {
            assert!(plates.iter().any(|n| n.line_voltage_v == v), "{v} V");
        }
        for p in 1..=4 {
            assert!(plates.iter().any(|n| n.pole_pairs == p), "{p} pole pairs");
        }
        assert!(
            all.iter().any(|m| m.name.ends_with("-load")) && all.iter().any(|m| !m.name.ends_with("-load"))
        );
        assert!(
            boards.iter().any(|b| b.dead_time_s < 0.4e-6) && boards.iter().any(|b| b.dead_time_s > 2.5e-6)
        );
        assert!(boards.iter().any(|b| b.pwm_hz < 5e3) && boards.iter().any(|b| b.pwm_hz > 16e3));
    }
}
