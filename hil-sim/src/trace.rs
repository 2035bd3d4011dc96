//! The trace contract of a run (`hil-sim run`, `pil`, `faults --trace`): what
//! `DIR/trace.csv` holds, how it is written, and the plots and summary beside it.
//!
//! `trace.csv` has one header line, then one line per trace row ([`Row`]; every
//! `trace_every`-th PWM period in closed loop, every sample period in open loop). Units are in
//! the column names. Every run has the first ten columns ([`COLUMNS`]):
//!
//! | column | what | format |
//! |---|---|---|
//! | `t_s` | time, s | 7 decimals |
//! | `i_alpha_a`, `i_beta_a` | stator current, stationary frame, A | 6 decimals |
//! | `psi_alpha_wb`, `psi_beta_wb` | the plant's rotor flux, stationary frame, Wb | 6 decimals |
//! | `omega_m_rad_s` | mechanical speed, rad/s | 5 decimals |
//! | `theta_m_rad` | mechanical angle, rad (not wrapped) | 5 decimals |
//! | `torque_nm` | electromagnetic torque, N·m | 5 decimals |
//! | `v_alpha_v`, `v_beta_v` | applied stator voltage, V | 4 decimals |
//!
//! A closed-loop run (the drive in the loop) adds twenty ([`CLOSED_LOOP_COLUMNS`]):
//!
//! | column | what | format |
//! |---|---|---|
//! | `i_alpha_ref_a`, `i_beta_ref_a` | current references, A | 6 decimals |
//! | `omega_ref_rad_s` | speed reference, rad/s | 4 decimals |
//! | `load_nm` | load torque, N·m | 4 decimals |
//! | `drive_mode` | the drive's mode after the period's step (`Running`, `Fault`, …) | word |
//! | `fault` | the latched fault (`Overcurrent`, …), empty unless `drive_mode` is `Fault` | word |
//! | `duty_a`, `duty_b`, `duty_c` | duties for the next period, 0 … 1; empty while the bridge is off | 6 decimals |
//! | `vdc_v` | DC-bus voltage, V | 2 decimals |
//! | `psi_est_wb`, `psi_ref_wb` | the drive's rotor-flux estimate and reference, Wb | 5 decimals |
//! | `rr_scale`, `l_scale` | rotor resistance and inductances the field orientation runs on, × the motor file's | 4 decimals |
//! | `brake` | the brake chopper's output, 0 or 1 | integer |
//! | `i_chopper_a` | current through the chopper's resistor, A | 4 decimals |
//! | `i_leg_peak_a` | largest \|leg current\| in the period, A | 4 decimals |
//! | `comparator` | the hardware comparator has broken the bridge (latched), 0 or 1 | integer |
//! | `stator_c`, `rotor_c` | the windings' temperatures, °C; empty unless they heat (a scenario's `[heating]`) | 2 decimals |
//!
//! The file is streamed to disk as the run goes ([`stream_trace`]) under a `.partial` name
//! and renamed when complete (`report::write`): a failed or interrupted run leaves neither it
//! nor the directory it made. After a complete run, [`finish`] writes `summary.json` and the
//! plots `speed.svg`, `currents.svg`, `torque.svg` ([`write_plots`]) from the figures the
//! stream kept ([`TraceStats`]).

use crate::sim::Row;
use controller_core::drive::Mode;
use report::write::{write_atomic, write_text};
use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

/// The columns of every trace (open and closed loop), in order.
pub const COLUMNS: [&str; 10] = [
    "t_s",
    "i_alpha_a",
    "i_beta_a",
    "psi_alpha_wb",
    "psi_beta_wb",
    "omega_m_rad_s",
    "theta_m_rad",
    "torque_nm",
    "v_alpha_v",
    "v_beta_v",
];

/// The columns a closed-loop trace adds after [`COLUMNS`], in order.
pub const CLOSED_LOOP_COLUMNS: [&str; 20] = [
    "i_alpha_ref_a",
    "i_beta_ref_a",
    "omega_ref_rad_s",
    "load_nm",
    "drive_mode",
    "fault",
    "duty_a",
    "duty_b",
    "duty_c",
    "vdc_v",
    "psi_est_wb",
    "psi_ref_wb",
    "rr_scale",
    "l_scale",
    "brake",
    "i_chopper_a",
    "i_leg_peak_a",
    "comparator",
    "stator_c",
    "rotor_c",
];

/// The header line of a trace (without its line end).
pub fn header(closed_loop: bool) -> String {
    let extra: &[&str] = if closed_loop { &CLOSED_LOOP_COLUMNS } else { &[] };
    COLUMNS.iter().chain(extra).copied().collect::<Vec<_>>().join(",")
}

/// Most points per plotted curve.
const PLOT_POINTS: f64 = 4000.0;

/// What a streamed trace leaves for the summary and the plots: the peak current, the last
/// row and a thinned copy of the rows.
#[derive(Debug, Clone)]
pub struct TraceStats {
    /// The trace has the closed-loop columns (and the plots their references).
    pub closed_loop: bool,
    /// Every `plot_every`-th row is kept for the plots (at most about [`PLOT_POINTS`]).
    plot_every: u64,
    /// Rows written.
    pub count: u64,
    /// Largest stator current magnitude |i_s| over every period, A ([`Row::i_peak_a`]).
    pub peak_a: f64,
    /// The last row written.
    pub last: Option<Row>,
    /// The rows kept for the plots.
    pub plot: Vec<Row>,
}

impl TraceStats {
    /// Nothing seen yet, for a trace of about `expected_rows` rows.
    pub fn new(closed_loop: bool, expected_rows: f64) -> Self {
        Self {
            closed_loop,
            plot_every: (expected_rows / PLOT_POINTS).ceil().max(1.0) as u64,
            count: 0,
            peak_a: 0.0,
            last: None,
            plot: Vec::new(),
        }
    }

    /// Take one row's figures.
    pub fn add(&mut self, r: &Row) {
        // Every period's, not only the trace's rows ([`Row::i_peak_a`]).
        self.peak_a = self.peak_a.max(r.i_peak_a).max(r.x.i_alpha_a.hypot(r.x.i_beta_a));
        if self.count.is_multiple_of(self.plot_every) {
            self.plot.push(*r);
        }
        self.count += 1;
        self.last = Some(*r);
    }
}

/// One CSV row of the trace (the columns and formats of the module's table), with its line
/// end.
pub fn write_row(f: &mut dyn Write, r: &Row, closed_loop: bool) -> std::io::Result<()> {
    let x = &r.x;
    write!(
        f,
        "{:.7},{:.6},{:.6},{:.6},{:.6},{:.5},{:.5},{:.5},{:.4},{:.4}",
        r.t_s,
        x.i_alpha_a,
        x.i_beta_a,
        x.psi_alpha_wb,
        x.psi_beta_wb,
        x.omega_m_rad_s,
        x.theta_m_rad,
        r.torque_nm,
        r.v_ab_v[0],
        r.v_ab_v[1]
    )?;
    if closed_loop {
        write!(
            f,
            ",{:.6},{:.6},{:.4},{:.4}",
            r.i_ref_ab_a[0], r.i_ref_ab_a[1], r.omega_ref_rad_s, r.load_nm
        )?;
        // Mode and fault as words; duties empty while the bridge is off.
        let (mode, fault) = match r.mode {
            Some(Mode::Fault(which)) => ("Fault".to_string(), format!("{which:?}")),
            Some(m) => (format!("{m:?}"), String::new()),
            None => (String::new(), String::new()),
        };
        write!(f, ",{mode},{fault}")?;
        match r.duty {
            Some([a, b, c]) => write!(f, ",{a:.6},{b:.6},{c:.6}")?,
            None => write!(f, ",,,")?,
        }
        write!(
            f,
            ",{:.2},{:.5},{:.5},{:.4},{:.4}",
            r.vdc_v, r.psi_est_wb, r.psi_ref_wb, r.rr_scale, r.l_scale
        )?;
        write!(f, ",{},{:.4}", u8::from(r.brake), r.i_chopper_a)?;
        write!(f, ",{:.4},{}", r.i_leg_peak_a, u8::from(r.hw_break))?;
        match r.windings {
            Some(w) => write!(f, ",{:.2},{:.2}", w.stator_c, w.rotor_c)?,
            None => write!(f, ",,")?,
        }
    }
    writeln!(f)
}

/// Make the output directory `out` (and its parents); `true` when this call made `out`.
pub fn make_out_dir(out: &Path) -> Result<bool, String> {
    report::write::check_dir(out)?;
    let made = !out.exists();
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    Ok(made)
}

/// After a failed or interrupted command: `out` removed when the command made it
/// ([`make_out_dir`]) and it is still empty — `remove_dir` takes only an empty directory, so
/// nothing anyone put there is lost (failures left empty directories: found by trying).
pub fn unmake_out_dir(out: &Path, made: bool) {
    if made {
        let _ = std::fs::remove_dir(out);
    }
}

/// Stream the rows `run` makes into `out/trace.csv` through the one atomic writer
/// (`report::write`): the file is created before the run (an unusable directory fails at
/// once) and takes its name only complete; a failed or interrupted run (`stop` set: checked
/// before every row) leaves nothing — nor the directory, when this call made it (an empty
/// one was left: found by trying). `expected_rows` sets how thinly the plots' copy is kept.
pub fn stream_trace<T>(
    out: &Path,
    closed_loop: bool,
    expected_rows: f64,
    stop: &AtomicBool,
    run: impl FnOnce(&mut dyn FnMut(&Row) -> Result<(), String>) -> Result<T, String>,
) -> Result<(T, TraceStats), String> {
    let made_dir = make_out_dir(out)?;
    let mut stats = TraceStats::new(closed_loop, expected_rows);
    let mut outcome = None;
    let written = write_atomic(&out.join("trace.csv"), |w| {
        writeln!(w, "{}", header(closed_loop))?;
        let mut io_error = None;
        let result = run(&mut |row| {
            if stop.load(Ordering::Relaxed) {
                return Err("interrupted".into());
            }
            if let Err(e) = write_row(w, row, closed_loop) {
                let reason = e.to_string();
                io_error = Some(e);
                return Err(reason);
            }
            stats.add(row);
            Ok(())
        });
        if let Some(e) = io_error {
            return Err(e);
        }
        let failed = result.is_err();
        outcome = Some(result);
        if failed { Err(std::io::Error::other("the run failed")) } else { Ok(()) }
    });
    let result = match (outcome, written) {
        (Some(Err(e)), _) => Err(e),
        (_, Err(e)) => Err(e),
        (Some(Ok(value)), Ok(())) => Ok((value, stats)),
        (None, Ok(())) => Err("the run did not start".into()),
    };
    if result.is_err() {
        unmake_out_dir(out, made_dir);
    }
    result
}

/// The main signals as SVG plots in `out`: `speed.svg`, `currents.svg` (stator currents,
/// with their references in closed loop), `torque.svg`.
pub fn write_plots(out: &Path, rows: &[Row], closed_loop: bool) -> Result<(), String> {
    use report::plot::{Series, line_plot};
    let pts = |f: &dyn Fn(&Row) -> f64| rows.iter().map(|r| (r.t_s, f(r))).collect::<Vec<_>>();
    let mut speed = vec![Series::line("ω_m (rad/s)", pts(&|r| r.x.omega_m_rad_s))];
    let mut currents = vec![
        Series::line("i_α (A)", pts(&|r| r.x.i_alpha_a)),
        Series::line("i_β (A)", pts(&|r| r.x.i_beta_a)),
    ];
    let mut torque = vec![Series::line("T_e (N·m)", pts(&|r| r.torque_nm))];
    if closed_loop {
        speed.push(Series::line("ω_ref (rad/s)", pts(&|r| r.omega_ref_rad_s)));
        currents.push(Series::line("i_α ref (A)", pts(&|r| r.i_ref_ab_a[0])));
        currents.push(Series::line("i_β ref (A)", pts(&|r| r.i_ref_ab_a[1])));
        torque.push(Series::line("T_L (N·m)", pts(&|r| r.load_nm)));
    }
    for (name, title, series) in [
        ("speed.svg", "Rotor speed", speed),
        ("currents.svg", "Stator currents", currents),
        ("torque.svg", "Torque", torque),
    ] {
        write_text(&out.join(name), &line_plot(title, "t (s)", &series))?;
    }
    Ok(())
}

/// After a complete trace: the plots and `summary.json` (`summary` made from the last row
/// and the peak current), the summary also on stdout.
pub fn finish(
    out: &Path,
    trace: TraceStats,
    summary: impl FnOnce(&Row, f64) -> serde_json::Value,
) -> Result<(), String> {
    let last = trace.last.ok_or("empty run")?;
    let summary = summary(&last, trace.peak_a);
    write_plots(out, &trace.plot, trace.closed_loop)?;
    let text = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    write_text(&out.join("summary.json"), &format!("{text}\n"))?;
    report::outln!("{text}");
    eprintln!(
        "hil-sim: wrote trace.csv, summary.json, speed.svg, currents.svg, torque.svg in {}",
        out.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::drive::Fault;
    use std::path::PathBuf;

    /// A fresh directory under the system's temporary one, unique to this test.
    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("hil-sim-trace-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    fn row(t_s: f64) -> Row {
        let mut r = Row { t_s, torque_nm: 0.25, vdc_v: 310.0, ..Row::default() };
        r.x.i_alpha_a = 1.5;
        r.x.i_beta_a = -2.0;
        r
    }

    #[test]
    fn the_header_names_every_column_once() {
        assert_eq!(
            header(false),
            "t_s,i_alpha_a,i_beta_a,psi_alpha_wb,psi_beta_wb,omega_m_rad_s,theta_m_rad,torque_nm,v_alpha_v,v_beta_v"
        );
        let closed = header(true);
        assert!(
            closed.starts_with(&header(false))
                && closed.ends_with(",i_leg_peak_a,comparator,stator_c,rotor_c")
        );
        let mut names: Vec<&str> = closed.split(',').collect();
        assert_eq!(names.len(), 30);
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), 30);
    }

    /// A row has as many fields as the header, in either kind of trace, whatever the mode
    /// (a fault names itself, a bridge that is off leaves the duties empty).
    #[test]
    fn a_row_has_a_field_for_every_column() {
        let mut faulted = row(0.5);
        faulted.mode = Some(Mode::Fault(Fault::Overcurrent));
        let mut running = row(0.25);
        running.mode = Some(Mode::Running);
        running.duty = Some([0.5, 0.25, 0.75]);
        running.brake = true;
        let field = |r: &Row, closed_loop: bool, name: &str| {
            let mut line = Vec::new();
            write_row(&mut line, r, closed_loop).unwrap();
            let line = String::from_utf8(line).unwrap();
            let fields: Vec<String> = line.strip_suffix('\n').unwrap().split(',').map(String::from).collect();
            let head = header(closed_loop);
            assert_eq!(fields.len(), head.split(',').count(), "{line}");
            fields[head.split(',').position(|c| c == name).unwrap()].clone()
        };
        assert_eq!(field(&row(0.0), false, "t_s"), "0.0000000");
        assert_eq!(field(&row(0.0), false, "i_beta_a"), "-2.000000");
        assert_eq!(field(&row(0.0), false, "v_beta_v"), "0.0000");
        assert_eq!(field(&faulted, true, "drive_mode"), "Fault");
        assert_eq!(field(&faulted, true, "fault"), "Overcurrent");
        assert_eq!(field(&faulted, true, "duty_b"), "");
        assert_eq!(field(&running, true, "fault"), "");
        assert_eq!(field(&running, true, "duty_c"), "0.750000");
        assert_eq!(field(&running, true, "vdc_v"), "310.00");
        assert_eq!(field(&running, true, "brake"), "1");
        assert_eq!(field(&running, true, "comparator"), "0");
        assert_eq!(field(&running, true, "rotor_c"), "");
        running.windings = Some(plant::thermal::Windings { stator_c: 61.25, rotor_c: 70.5 });
        assert_eq!(field(&running, true, "stator_c"), "61.25");
        assert_eq!(field(&running, true, "rotor_c"), "70.50");
    }

    /// A complete stream: the header and one line per row, the figures kept, the directory
    /// made (parents too).
    #[test]
    fn a_stream_writes_the_header_and_every_row() {
        let dir = tmp("stream");
        let out = dir.join("a").join("b");
        let (value, stats) = stream_trace(&out, true, 3.0, &AtomicBool::new(false), |sink| {
            for k in 0..3 {
                sink(&row(f64::from(k) * 1e-3))?;
            }
            Ok(7)
        })
        .unwrap();
        assert_eq!(value, 7);
        assert_eq!((stats.count, stats.plot.len()), (3, 3));
        assert_eq!(stats.peak_a, 2.5);
        assert_eq!(stats.last.unwrap().t_s, 2e-3);
        let text = std::fs::read_to_string(out.join("trace.csv")).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4);
        assert_eq!(lines[0], header(true));
        assert!(lines[1..].iter().all(|l| l.split(',').count() == 30), "{text}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A run that fails, or is stopped, leaves nothing: no trace, no partial file, not the
    /// directory the stream made — but a directory that was there stays, with its files.
    #[test]
    fn a_failed_or_stopped_stream_leaves_nothing() {
        let dir = tmp("failed");
        let out = dir.join("made");
        let failed = stream_trace(&out, false, 10.0, &AtomicBool::new(false), |sink| {
            sink(&row(0.0))?;
            Err::<(), _>("diverged".to_string())
        });
        assert_eq!(failed.unwrap_err(), "diverged");
        assert!(!out.exists());
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("keep.txt"), "mine").unwrap();
        let stopped = stream_trace(&dir, false, 10.0, &AtomicBool::new(true), |sink| sink(&row(0.0)));
        assert_eq!(stopped.unwrap_err(), "interrupted");
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(left, ["keep.txt"]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// An output directory that is a file is an error before the run starts, not a panic.
    #[test]
    fn an_output_path_that_is_a_file_is_an_error() {
        let dir = tmp("file");
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("not-a-dir");
        std::fs::write(&file, "x").unwrap();
        let mut started = false;
        let e = stream_trace(&file, true, 1.0, &AtomicBool::new(false), |_| {
            started = true;
            Ok(())
        })
        .unwrap_err();
        assert!(e.contains("exists and is not a directory"), "{e}");
        assert!(!started);
        let e =
            stream_trace(&file.join("below"), true, 1.0, &AtomicBool::new(false), |_| Ok(())).unwrap_err();
        assert!(e.contains("cannot create"), "{e}");
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The plots and the summary of a complete trace; an empty one is an error.
    #[test]
    fn finish_writes_the_plots_and_the_summary() {
        let dir = tmp("finish");
        std::fs::create_dir_all(&dir).unwrap();
        assert_eq!(
            finish(&dir, TraceStats::new(true, 1.0), |_, _| serde_json::json!({})).unwrap_err(),
            "empty run"
        );
        let mut stats = TraceStats::new(true, 2.0);
        stats.add(&row(0.0));
        stats.add(&row(1e-3));
        finish(&dir, stats, |last, peak| serde_json::json!({ "t": last.t_s, "peak": peak })).unwrap();
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
        assert_eq!(summary, serde_json::json!({ "t": 1e-3, "peak": 2.5 }));
        for svg in ["speed.svg", "currents.svg", "torque.svg"] {
            assert!(std::fs::read_to_string(dir.join(svg)).unwrap().starts_with("<svg"), "{svg}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
