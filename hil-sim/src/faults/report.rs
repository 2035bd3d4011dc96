//! The matrix's rows as results: each row's [`Outcome`] (its measurements, its verdict in
//! words) and the whole matrix as a markdown table, JSON and an SVG picture.

use super::{Case, Expect, Matrix, OperatingPoint};
use crate::sim::Injection;
use controller_core::drive::{Fault, FaultSet, Mode};

/// One row's measurements and verdict.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// The fault injected.
    pub case: Case,
    /// Where.
    pub at: OperatingPoint,
    /// What was asked.
    pub expect: Expect,
    /// The speed at the injection, rad/s.
    pub speed_at_injection_rad_s: f64,
    /// The fault latched first after the injection, and its delay, s.
    pub detected: Option<(Fault, f64)>,
    /// The encoder's faults first reported as ridden through on the observer after the
    /// injection (`speed_feedback = "encoder_ride_through"`), and the delay, s.
    pub reported: Option<(FaultSet, f64)>,
    /// The speed at the end of the observation, rad/s.
    pub final_speed_rad_s: f64,
    /// Where the detection bound runs from, after the injection, s: a switch stuck open's
    /// first use (`None`: never within the observation), a short's first period above the
    /// trip level (the injection if never), a current sensor's first period whose reading's
    /// error reaches the current-sum check's windowed level (`None`: never — a gain error on
    /// a phase near its zero crossing); other faults 0.
    pub acting_after_s: Option<f64>,
    /// A fault latched before the injection (a failed row): its time, s from the start.
    pub tripped_before_s: Option<f64>,
    /// PWM periods from the detection to the bridge off (0: off from the next period).
    pub off_after_periods: Option<u64>,
    /// Peak true phase current after the injection, A.
    pub peak_current_a: f64,
    /// Peak true phase current after the injection while the drive drove its bridge and in
    /// the period its last duties set up, A: what the criterion judges against the trip
    /// level ([`super::PEAK_CURRENT_FRACTION`]). With every switch open the inverter is a
    /// diode bridge, and a back-EMF above the bus drives the machine's own current through
    /// it, which no drive acts on.
    pub peak_driven_a: f64,
    /// Peak |leg current| after the injection (the motor's plus a short's), A; 0 when the
    /// legs are not modelled (no comparator, no short).
    pub peak_leg_a: f64,
    /// Energy the motor returned to the bus after the injection, J.
    pub energy_into_bus_j: f64,
    /// Mode at the end.
    pub final_mode: Mode,
    /// Criteria not met (empty: the row passes; for a gap, "gap closed" when it holds).
    pub failures: Vec<String>,
}

impl Outcome {
    /// The row meets its criterion (a gap: it still does not hold).
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }

    /// "pass", "gap" or "FAIL".
    pub fn verdict(&self) -> &'static str {
        match (self.passed(), self.expect) {
            (false, _) => "FAIL",
            (true, Expect::Gap { .. }) => "gap",
            (true, _) => "pass",
        }
    }

    /// What was asked, in words.
    pub fn asked(&self) -> String {
        match self.expect {
            Expect::Fault { fault, bound_s } => format!("{fault:?} ≤ {}", ms(bound_s)),
            Expect::Either { faults, bound_s } => {
                let names: Vec<String> = faults.iter().map(|f| format!("{f:?}")).collect();
                format!("{} ≤ {}", names.join("/"), ms(bound_s))
            }
            Expect::RideThrough => "no trip".into(),
            Expect::Reported { faults, bound_s } => {
                let names: Vec<String> = faults.iter().map(|f| format!("{f:?}")).collect();
                format!("no trip, {} reported ≤ {}", names.join("/"), ms(bound_s))
            }
            Expect::Gap { fault, bound_s, .. } => format!("({fault:?} ≤ {})", ms(bound_s)),
        }
    }

    /// Table cells shared by the markdown and the terminal table: the periods to the bridge
    /// off, the peak leg current ("—" when not measured) and the failures (": …", or empty).
    pub fn cells(&self) -> (String, String, String) {
        (
            self.off_after_periods.map_or("—".into(), |n| n.to_string()),
            if self.peak_leg_a > 0.0 { format!("{:.2}", self.peak_leg_a) } else { "—".into() },
            if self.failures.is_empty() { String::new() } else { format!(": {}", self.failures.join("; ")) },
        )
    }

    /// What was seen, in words.
    pub fn seen(&self) -> String {
        let seen = match (self.detected, self.reported) {
            (Some((f, t)), _) => format!("{f:?} after {}", ms(t)),
            (None, Some((set, t))) => format!("{} reported after {}", names(set), ms(t)),
            (None, None) => format!("none ({:?})", self.final_mode),
        };
        match (self.case.injection, self.acting_after_s) {
            (Injection::SwitchOpen { .. }, Some(t)) => format!("{seen} (needed from {})", ms(t)),
            (Injection::SwitchOpen { .. }, None) => format!("{seen} (never needed)"),
            (Injection::PhaseShort(_) | Injection::SwitchShort(_), Some(t)) if t > 0.0 => {
                format!("{seen} (over the trip level from {})", ms(t))
            }
            (Injection::CurrentSensor { .. }, Some(t)) if t > 0.0 => {
                format!("{seen} (its error clear of the check's level from {})", ms(t))
            }
            (Injection::CurrentSensor { .. }, None) => {
                format!("{seen} (its error never clear of the check's level)")
            }
            _ => seen,
        }
    }
}

/// The faults of `set`, by name ("A/B").
pub(super) fn names(set: FaultSet) -> String {
    let names: Vec<String> = set.faults().map(|f| format!("{f:?}")).collect();
    names.join("/")
}

/// A time in milliseconds, as the tables write it.
pub(super) fn ms(t_s: f64) -> String {
    format!("{:.2} ms", 1e3 * t_s)
}

/// The table as markdown.
pub fn markdown(m: &Matrix, rows: &[Outcome]) -> String {
    let mut s = format!(
        "# Fault-injection matrix\n\n`hil-sim faults`: {} rows, {} V bus, trip level {} A, top speed {:.1} rad/s, \
         references at {:.4} s, faults injected at {:.4} s, noise seed {} (hil_sim::faults). Gaps are stated with their reason below the \
         table.\n\n\
         | fault injected | operating point | ω at injection (rad/s) | asked | detected as | bridge off after (periods) \
         | peak \\|i\\| (A) | peak / trip | peak leg \\|i\\| (A) | energy into bus (J) | final state | verdict |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
        rows.len(),
        m.vdc_v,
        m.spec.protection.i_trip_a,
        m.top_speed_rad_s,
        m.reference_s(),
        m.inject_s(),
        m.seed
    );
    for o in rows {
        let (off, leg, failures) = o.cells();
        s.push_str(&format!(
            "| {} | {} | {:.1} | {} | {} | {off} | {:.2} | {:.0} % | {leg} | {:.3} | {:?} | {}{failures} |\n",
            o.case.title(),
            o.at.name(),
            o.speed_at_injection_rad_s,
            o.asked(),
            o.seen(),
            o.peak_current_a,
            100.0 * o.peak_current_a / m.spec.protection.i_trip_a,
            o.energy_into_bus_j,
            o.final_mode,
            o.verdict(),
        ));
    }
    // Each gap once, with the operating points it holds at.
    let mut gaps: Vec<(String, &str, Vec<String>)> = Vec::new();
    for o in rows {
        if let Expect::Gap { why, .. } = o.expect {
            match gaps.iter_mut().find(|(n, w, _)| *n == o.case.title() && *w == why) {
                Some((_, _, points)) => points.push(o.at.name()),
                None => gaps.push((o.case.title(), why, vec![o.at.name()])),
            }
        }
    }
    if !gaps.is_empty() {
        s.push_str("\n## Gaps\n\n");
        for (name, why, points) in gaps {
            s.push_str(&format!("- **{name}** ({}): {why}.\n", points.join(", ")));
        }
    }
    s
}

/// The rows as JSON.
pub fn json(m: &Matrix, rows: &[Outcome]) -> serde_json::Value {
    let row = |o: &Outcome| {
        serde_json::json!({
            "fault": o.case.title(),
            "point": o.at.name(),
            "speed_at_injection_rad_s": o.speed_at_injection_rad_s,
            "asked": o.asked(),
            "detected": o.detected.map(|(f, _)| format!("{f:?}")),
            "detection_time_s": o.detected.map(|(_, t)| t),
            "reported": o.reported.map(|(set, _)| names(set)),
            "report_time_s": o.reported.map(|(_, t)| t),
            "final_speed_rad_s": o.final_speed_rad_s,
            "settles_at_rad_s": m.approach(&o.at).ok().map(|a| a.final_rad_s),
            "bound_from_s": o.acting_after_s,
            "tripped_before_injection_at_s": o.tripped_before_s,
            "bridge_off_after_periods": o.off_after_periods,
            "peak_current_a": o.peak_current_a,
            "peak_driven_current_a": o.peak_driven_a,
            "peak_leg_current_a": o.peak_leg_a,
            "trip_level_a": m.spec.protection.i_trip_a,
            "energy_into_bus_j": o.energy_into_bus_j,
            "final_mode": format!("{:?}", o.final_mode),
            "verdict": o.verdict(),
            "failures": o.failures,
        })
    };
    serde_json::json!({
        "vdc_v": m.vdc_v,
        "top_speed_rad_s": m.top_speed_rad_s,
        "reference_s": m.reference_s(),
        "inject_s": m.inject_s(),
        "noise_seed": m.seed,
        "rows": rows.iter().map(row).collect::<Vec<_>>(),
        "passed": rows.iter().filter(|o| o.verdict() == "pass").count(),
        "gaps": rows.iter().filter(|o| o.verdict() == "gap").count(),
        "failed": rows.iter().filter(|o| !o.passed()).count(),
    })
}

/// An overview: one cell per row (fault × operating point), coloured by verdict, with the
/// fault detected and its delay.
pub fn svg(m: &Matrix, rows: &[Outcome]) -> String {
    let points = m.points();
    let mut cases: Vec<String> = rows.iter().map(|o| o.case.title()).collect();
    cases.dedup();
    let (label_w, cell_w, cell_h, head_h) = (230.0, 150.0, 34.0, 60.0);
    let width = label_w + cell_w * points.len() as f64 + 10.0;
    let height = head_h + cell_h * cases.len() as f64 + 40.0;
    let esc = |t: &str| t.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;");
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" \
         font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"8\" y=\"18\" font-size=\"14\">Fault-injection matrix: detected fault and delay \
         (green pass, amber stated gap, red fail)</text>\n"
    );
    for (j, p) in points.iter().enumerate() {
        let x = label_w + cell_w * (j as f64 + 0.5);
        s.push_str(&format!(
            "<text x=\"{x}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n<text x=\"{x}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
            head_h - 22.0,
            p.point.name(),
            head_h - 8.0,
            if p.motoring { "motoring" } else { "generating" }
        ));
    }
    for (i, c) in cases.iter().enumerate() {
        let y = head_h + cell_h * i as f64;
        s.push_str(&format!("<text x=\"8\" y=\"{}\">{}</text>\n", y + cell_h / 2.0 + 4.0, esc(c)));
        for (j, p) in points.iter().enumerate() {
            let Some(o) = rows.iter().find(|o| o.case.title() == *c && o.at == *p) else { continue };
            let fill = match o.verdict() {
                "pass" => "#b7e4b0",
                "gap" => "#f5d98b",
                _ => "#f2a3a3",
            };
            let x = label_w + cell_w * j as f64;
            let (line1, line2) = match (o.detected, o.reported) {
                (Some((f, t)), _) => (format!("{f:?}"), ms(t)),
                (None, Some((set, t))) => (format!("{} reported", names(set)), ms(t)),
                (None, None) => ("no trip".into(), format!("{:?}", o.final_mode)),
            };
            s.push_str(&format!(
                "<rect x=\"{x}\" y=\"{y}\" width=\"{}\" height=\"{}\" fill=\"{fill}\" stroke=\"white\"/>\n\
                 <text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
                cell_w,
                cell_h,
                x + cell_w / 2.0,
                y + 14.0,
                esc(&line1),
                x + cell_w / 2.0,
                y + 28.0,
                esc(&line2)
            ));
        }
    }
    s.push_str("</svg>\n");
    s
}
