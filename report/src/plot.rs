//! Minimal SVG line plots (no dependencies): one panel, shared x axis, several series,
//! "nice" ticks, legend. Enough to look at a trace without a notebook.

use std::fmt::Write;

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// Polyline through the points.
    Line,
    /// One small dot per point (e.g. a region sampled on a grid).
    Dots,
    /// A large outlined marker per point (a design point on a region plot).
    Markers,
}

/// One named curve.
#[derive(Debug, Clone)]
pub struct Series<'a> {
    /// Legend label (with unit).
    pub label: &'a str,
    /// Points `(x, y)`.
    pub points: Vec<(f64, f64)>,
    /// Drawing style.
    pub style: Style,
    /// Colour (CSS); `None` cycles through a palette.
    pub color: Option<&'static str>,
}

impl<'a> Series<'a> {
    /// A polyline.
    pub fn line(label: &'a str, points: Vec<(f64, f64)>) -> Self {
        Self { label, points, style: Style::Line, color: None }
    }
    /// Dots.
    pub fn dots(label: &'a str, points: Vec<(f64, f64)>) -> Self {
        Self { label, points, style: Style::Dots, color: None }
    }
    /// Large markers.
    pub fn markers(label: &'a str, points: Vec<(f64, f64)>) -> Self {
        Self { label, points, style: Style::Markers, color: None }
    }
}

impl Series<'_> {
    /// The same series in a fixed colour.
    pub fn colored(mut self, color: &'static str) -> Self {
        self.color = Some(color);
        self
    }
}

/// Fixed axis ranges `((x0, x1), (y0, y1))`; points outside are clipped (lines break).
pub type Window = ((f64, f64), (f64, f64));

const W: f64 = 800.0;
const H: f64 = 360.0;
const LEFT: f64 = 70.0;
const RIGHT: f64 = 20.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 50.0;
const COLORS: [&str; 6] = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"];

/// Round step of about `span/5`: 1, 2 or 5 times a power of ten.
fn nice_step(span: f64) -> f64 {
    let raw = (span / 5.0).max(f64::MIN_POSITIVE);
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    mag * if f < 1.5 {
        1.0
    } else if f < 3.5 {
        2.0
    } else if f < 7.5 {
        5.0
    } else {
        10.0
    }
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        (0.0, 1.0)
    } else if hi - lo < 1e-12 {
        (lo - 1.0, hi + 1.0)
    } else {
        (lo, hi)
    }
}

/// Render an SVG document with axes fitted to the data.
pub fn line_plot(title: &str, x_label: &str, series: &[Series<'_>]) -> String {
    let (x0, x1) = range(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let (y0, y1) = range(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let pad = 0.05 * (y1 - y0);
    plot_in(title, x_label, series, ((x0, x1), (y0 - pad, y1 + pad)))
}

/// Render an SVG document in a fixed window.
pub fn plot_in(title: &str, x_label: &str, series: &[Series<'_>], window: Window) -> String {
    let ((x0, x1), (y0, y1)) = window;
    let inside = |x: f64, y: f64| x.is_finite() && y.is_finite() && x >= x0 && x <= x1 && y >= y0 && y <= y1;
    let px = |x: f64| LEFT + (x - x0) / (x1 - x0) * (W - LEFT - RIGHT);
    let py = |y: f64| H - BOTTOM - (y - y0) / (y1 - y0) * (H - TOP - BOTTOM);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="22" text-anchor="middle" font-size="15">{}</text>"#,
        W / 2.0,
        escape(title)
    );
    // grid and ticks
    for (lo, hi, vertical) in [(x0, x1, true), (y0, y1, false)] {
        let step = nice_step(hi - lo);
        let mut v = (lo / step).ceil() * step;
        while v <= hi + 1e-9 * step {
            // As many decimals as the step needs; `+ 0.0` turns −0 into 0.
            let decimals = usize::try_from(-(step.log10().floor() as i64)).unwrap_or(0);
            let label = format!("{:.*}", decimals, (v / step).round() * step + 0.0);
            if vertical {
                let x = px(v);
                let _ = writeln!(
                    s,
                    r##"<line x1="{x:.1}" y1="{TOP}" x2="{x:.1}" y2="{:.1}" stroke="#ddd"/>"##,
                    H - BOTTOM
                );
                let _ = writeln!(
                    s,
                    r#"<text x="{x:.1}" y="{:.1}" text-anchor="middle">{label}</text>"#,
                    H - BOTTOM + 16.0
                );
            } else {
                let y = py(v);
                let _ = writeln!(
                    s,
                    r##"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#ddd"/>"##,
                    W - RIGHT
                );
                let _ = writeln!(
                    s,
                    r#"<text x="{:.1}" y="{:.1}" text-anchor="end">{label}</text>"#,
                    LEFT - 6.0,
                    y + 4.0
                );
            }
            v += step;
        }
    }
    let _ = writeln!(
        s,
        r##"<rect x="{LEFT}" y="{TOP}" width="{:.1}" height="{:.1}" fill="none" stroke="#444"/>"##,
        W - LEFT - RIGHT,
        H - TOP - BOTTOM
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
        W / 2.0,
        H - 12.0,
        escape(x_label)
    );
    let mut legend_row = 0usize;
    for (k, ser) in series.iter().enumerate() {
        let color = ser.color.unwrap_or_else(|| COLORS.get(k % COLORS.len()).copied().unwrap_or("black"));
        match ser.style {
            Style::Line => {
                let mut d = String::new();
                let mut pen_down = false;
                for &(x, y) in &ser.points {
                    if inside(x, y) {
                        let _ = write!(d, "{}{:.1},{:.1} ", if pen_down { "L" } else { "M" }, px(x), py(y));
                        pen_down = true;
                    } else {
                        pen_down = false;
                    }
                }
                let _ = writeln!(s, r#"<path d="{d}" fill="none" stroke="{color}" stroke-width="1.2"/>"#);
            }
            Style::Dots | Style::Markers => {
                let marker = if ser.style == Style::Dots { r#"r="1.6""# } else { r##"r="5" stroke="#222""## };
                for &(x, y) in ser.points.iter().filter(|p| inside(p.0, p.1)) {
                    let _ = writeln!(
                        s,
                        r#"<circle cx="{:.1}" cy="{:.1}" {marker} fill="{color}"/>"#,
                        px(x),
                        py(y)
                    );
                }
            }
        }
        if ser.label.is_empty() {
            continue; // unlabeled series get no legend entry
        }
        let ly = TOP + 14.0 + 16.0 * legend_row as f64;
        legend_row += 1;
        // A translucent backing keeps the legend readable over dense data.
        let _ = writeln!(
            s,
            r#"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="16" fill="white" fill-opacity="0.8"/>"#,
            LEFT + 6.0,
            ly - 8.0,
            32.0 + 7.0 * ser.label.chars().count() as f64
        );
        let _ = writeln!(
            s,
            r#"<line x1="{:.1}" y1="{ly:.1}" x2="{:.1}" y2="{ly:.1}" stroke="{color}" stroke-width="2"/>"#,
            LEFT + 10.0,
            LEFT + 30.0
        );
        let _ =
            writeln!(s, r#"<text x="{:.1}" y="{:.1}">{}</text>"#, LEFT + 36.0, ly + 4.0, escape(ser.label));
    }
    s.push_str("</svg>\n");
    s
}

/// Panels made by [`line_plot`] / [`plot_in`], one above the other in one SVG document
/// (each keeps its own axes: signals of different units on a shared time axis).
pub fn stack(panels: &[String]) -> String {
    let height = H * panels.len() as f64;
    let mut s = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{height}\">\n");
    for (k, p) in panels.iter().enumerate() {
        // A nested <svg> placed at its row.
        s.push_str(&p.replacen("<svg ", &format!("<svg y=\"{}\" ", H * k as f64), 1));
    }
    s.push_str("</svg>\n");
    s
}

fn escape(t: &str) -> String {
    t.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_rounded_to_the_step() {
        let svg = plot_in("t", "x", &[], ((0.0, 3.5), (0.0, 1.2)));
        assert!(svg.contains(">0.2</text>") && svg.contains(">0.6</text>"), "{svg}");
        assert!(!svg.contains("0000"), "{svg}");
        assert!(svg.contains(">0.5</text>") && svg.contains(">3.5</text>"));
    }

    #[test]
    fn nice_steps() {
        assert_eq!(nice_step(10.0), 2.0);
        assert_eq!(nice_step(3.5), 0.5);
        assert_eq!(nice_step(150.0), 20.0);
    }

    #[test]
    fn renders_every_series_and_survives_degenerate_data() {
        let svg = line_plot(
            "t<1>",
            "t (s)",
            &[
                Series::line("a", vec![(0.0, 1.0), (1.0, 2.0)]),
                Series::line("flat", vec![(0.0, 3.0), (1.0, 3.0), (2.0, f64::NAN)]),
                Series::line("empty", vec![]),
            ],
        );
        assert_eq!(svg.matches("<path").count(), 3);
        assert!(svg.contains("t&lt;1&gt;") && svg.ends_with("</svg>\n"));
    }
}

#[cfg(test)]
mod stack_tests {
    use super::*;

    #[test]
    fn panels_are_nested_one_per_row() {
        let p = |t: &str| line_plot(t, "t (s)", &[Series::line("y", vec![(0.0, 1.0), (1.0, 0.0)])]);
        let svg = stack(&[p("a"), p("b"), p("c")]);
        assert_eq!(svg.matches("<svg ").count(), 4);
        assert!(svg.contains(&format!("height=\"{}\"", 3.0 * H)));
        assert!(svg.contains(&format!("<svg y=\"{}\" ", 2.0 * H)));
        assert!(svg.ends_with("</svg>\n</svg>\n"));
    }
}

#[cfg(test)]
mod window_tests {
    use super::*;

    #[test]
    fn dots_and_clipping() {
        let svg = plot_in(
            "w",
            "x",
            &[
                Series::dots("d", vec![(0.5, 0.5), (5.0, 0.5)]),
                Series::line("l", vec![(0.0, 0.0), (9.0, 9.0), (1.0, 1.0)]),
            ],
            ((0.0, 1.0), (0.0, 1.0)),
        );
        assert_eq!(svg.matches("<circle").count(), 1);
        // The line leaves the window and re-enters: its path has two sub-paths ("M" moves).
        let path = svg.split("<path d=\"").nth(1).and_then(|p| p.split('"').next()).unwrap_or("");
        assert_eq!(path.matches('M').count(), 2, "{path}");
    }
}
