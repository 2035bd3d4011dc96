//! The magnetizing branch of an induction machine that saturates: its curve, and where the
//! branch sits in the equivalent circuit.
//!
//! A saturating branch is described by its magnetizing current as a function of the flux
//! linking it, `i_m = f(|ψ_m|)·ψ_m/|ψ_m|`: a radial map, the gradient of the magnetic
//! energy `W(ψ_m) = ∫₀^|ψ_m| f(r) dr` (per phase-peak unit, times 3/2 for the three
//! phases), so a model built on it neither creates nor loses energy through the
//! nonlinearity ([`MagnetizingCurve::energy`]). Two descriptions, as users have them:
//! - motulator's law (Qu, Ranta, Hinkkanen, Luomi, "Loss-minimizing flux level control of
//!   induction motor drives", IEEE TIA 2012): `L(ψ) = L_u/(1 + (β·ψ)^S)`, so
//!   `f(ψ) = ψ·(1 + (β·ψ)^S)/L_u`;
//! - the curve as points `(ψ_k, i_k)` from a no-load test or a data sheet, joined from the
//!   origin by a monotone cubic (piecewise cubic Hermite: Fritsch and Carlson, "Monotone
//!   piecewise cubic interpolation", SIAM J. Numer. Anal. 1980, with the knots' slopes the
//!   weighted harmonic mean of Fritsch and Butland, SIAM J. Sci. Stat. Comput. 1984), the
//!   last segment's chord extended beyond the last point. Straight lines between a no-load
//!   test's few points cut the knee, where the drive runs at rated flux, and gave the
//!   identification's DC steps into saturation a wrong rotor resistance
//!   (docs/commissioning.md, the saturating population members).
//!
//! Where the branch sits ([`Form`]) decides which flux saturates it: the Γ model puts it at
//! the stator terminals (ψ_m = ψ_s, the rotor-side leakage outside), the inverse-Γ model
//! at the rotor (ψ_m = ψ_R). A T model with both leakages is the same machine only while
//! it is linear (Slemon, "Modelling of induction machines for electric drives", IEEE TIA
//! 1989); saturated, a motor is written in the form its curve was measured in.

/// The most points a measured curve may hold (no allocation: the curve is `Copy`).
pub const CURVE_POINTS_MAX: usize = 16;

/// A knot of a measured curve's cubic: `(ψ, i, di/dψ)`, Wb, A, 1/H.
type Knot = (f64, f64, f64);

/// Where the magnetizing branch sits in the equivalent circuit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// Γ model: the branch across the stator terminals (after R_s), the leakage on the
    /// rotor side; its flux is the stator flux.
    Gamma,
    /// Inverse-Γ model: the branch at the rotor, the leakage on the stator side; its flux
    /// is the rotor flux.
    InverseGamma,
}

/// A saturating magnetizing branch: its curve and where it sits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Saturation {
    /// Where the branch sits.
    pub form: Form,
    /// Its curve.
    pub curve: MagnetizingCurve,
}

/// Why a curve was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CurveError {
    /// β, S or L_u not finite and positive (S ≥ 1: the curve must bend toward saturation).
    Law,
    /// Fewer than 2 or more than [`CURVE_POINTS_MAX`] points, or flux and current of
    /// different lengths.
    Count,
    /// A point not finite, or the flux or the current not strictly rising from the origin
    /// (at this index).
    NotRising(usize),
}

/// A saturating branch's magnetizing current against its flux ([module](self)), made by
/// [`MagnetizingCurve::law`] or [`MagnetizingCurve::points`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MagnetizingCurve(Repr);

// No allocation (no_std): the measured curve's points are held in place, so the law's
// variant is as large; a curve is made once per run, never copied in a loop.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
enum Repr {
    /// `L(ψ) = L_u/(1 + (β·ψ)^S)`.
    Law {
        /// 1/L_u, the unsaturated inductance's inverse, 1/H.
        inv_l_unsat_per_h: f64,
        /// β, 1/Wb.
        beta_per_wb: f64,
        /// S.
        exponent: f64,
        /// S when whole and at most 32 (then (β·ψ)^S by squaring), else 0.
        whole_exponent: u32,
    },
    /// Points `(ψ_k, i_k)`, k < n, both strictly rising, joined from the origin by the
    /// cubic Hermite through them with slopes `di/dψ` at the origin and at each point.
    Points {
        /// Number of points used.
        n: usize,
        /// ψ_k, Wb (peak of the space vector).
        psi_wb: [f64; CURVE_POINTS_MAX],
        /// i_k, A (peak of the space vector).
        current_a: [f64; CURVE_POINTS_MAX],
        /// di/dψ at the origin (index 0) and at each point (index k + 1), 1/H.
        slope_per_h: [f64; CURVE_POINTS_MAX + 1],
    },
}

impl MagnetizingCurve {
    /// motulator's law, validated.
    pub fn law(l_unsat_h: f64, beta_per_wb: f64, exponent: f64) -> Result<Self, CurveError> {
        let ok = |x: f64| x.is_finite() && x > 0.0;
        if ok(l_unsat_h) && ok(beta_per_wb) && exponent.is_finite() && exponent >= 1.0 {
            let whole = exponent == libm::floor(exponent) && exponent <= 32.0;
            Ok(Self(Repr::Law {
                inv_l_unsat_per_h: 1.0 / l_unsat_h,
                beta_per_wb,
                exponent,
                whole_exponent: if whole { exponent as u32 } else { 0 },
            }))
        } else {
            Err(CurveError::Law)
        }
    }

    /// A measured curve, validated: 2…[`CURVE_POINTS_MAX`] points, flux and current both
    /// strictly rising from the origin (the origin itself not listed).
    pub fn points(psi_wb: &[f64], current_a: &[f64]) -> Result<Self, CurveError> {
        let n = psi_wb.len();
        if n != current_a.len() || !(2..=CURVE_POINTS_MAX).contains(&n) {
            return Err(CurveError::Count);
        }
        let (mut psi, mut cur) = ([0.0; CURVE_POINTS_MAX], [0.0; CURVE_POINTS_MAX]);
        let (mut last_psi, mut last_i) = (0.0, 0.0);
        for (k, ((p, i), (dp, di))) in
            psi_wb.iter().zip(current_a).zip(psi.iter_mut().zip(cur.iter_mut())).enumerate()
        {
            if !(p.is_finite() && i.is_finite() && *p > last_psi && *i > last_i) {
                return Err(CurveError::NotRising(k));
            }
            (*dp, *di, last_psi, last_i) = (*p, *i, *p, *i);
        }
        Ok(Self(Repr::Points {
            n,
            psi_wb: psi,
            current_a: cur,
            slope_per_h: Self::knot_slopes(n, &psi, &cur),
        }))
    }

    /// The knots' slopes of the monotone cubic through the origin and the `n` points:
    /// at the origin and at the last point the adjacent chord (the curve starts linear, and
    /// the last chord extends it), between two chords `d₀`, `d₁` over `h₀`, `h₁` their
    /// weighted harmonic mean `3(h₀ + h₁)/((2h₁ + h₀)/d₀ + (h₁ + 2h₀)/d₁)` (Fritsch and
    /// Butland), which keeps each segment monotone (the chords are all positive here).
    fn knot_slopes(
        n: usize,
        psi_wb: &[f64; CURVE_POINTS_MAX],
        current_a: &[f64; CURVE_POINTS_MAX],
    ) -> [f64; CURVE_POINTS_MAX + 1] {
        let knot = |k: usize| -> (f64, f64) {
            match k.checked_sub(1) {
                None => (0.0, 0.0),
                Some(j) => (psi_wb.get(j).copied().unwrap_or(0.0), current_a.get(j).copied().unwrap_or(0.0)),
            }
        };
        // Chord k joins knot k to knot k + 1, k < n.
        let chord = |k: usize| {
            let ((p0, i0), (p1, i1)) = (knot(k), knot(k + 1));
            (p1 - p0, (i1 - i0) / (p1 - p0))
        };
        let mut m = [0.0; CURVE_POINTS_MAX + 1];
        for (k, slot) in m.iter_mut().enumerate().take(n + 1) {
            *slot = match (k.checked_sub(1).map(chord), (k < n).then(|| chord(k))) {
                (Some((h0, d0)), Some((h1, d1))) => {
                    3.0 * (h0 + h1) / ((2.0 * h1 + h0) / d0 + (h1 + 2.0 * h0) / d1)
                }
                (Some((_, d)), None) | (None, Some((_, d))) => d,
                (None, None) => 0.0,
            };
        }
        m
    }

    /// A measured curve's current, its slope di/dψ and its energy ∫₀^ψ i dψ at `psi` ≥ 0:
    /// the cubic Hermite on the segment holding it (`t` its position in the segment, `h`
    /// its length; the energy the full segments' `h·(i₀ + i₁)/2 + h²·(m₀ − m₁)/12` and the
    /// basis functions' integrals over `[0, t]`), beyond the last point the last knot's line
    /// `(ψ₀, i₀)` with slope `m₀`. One walk over the knots finds the segment and sums the
    /// full segments before it.
    fn points_at(
        n: usize,
        psi_wb: &[f64; CURVE_POINTS_MAX],
        current_a: &[f64; CURVE_POINTS_MAX],
        slope_per_h: &[f64; CURVE_POINTS_MAX + 1],
        psi: f64,
    ) -> (f64, f64, f64) {
        let mut w = 0.0;
        let (mut start, mut end): (Knot, Option<Knot>) =
            ((0.0, 0.0, slope_per_h.first().copied().unwrap_or(0.0)), None);
        for ((p1, i1), m1) in psi_wb.iter().zip(current_a).zip(slope_per_h.iter().skip(1)).take(n) {
            if psi <= *p1 {
                end = Some((*p1, *i1, *m1));
                break;
            }
            let (q0, j0, k0) = start;
            let h = p1 - q0;
            w += h * (0.5 * (j0 + i1) + h * (k0 - m1) / 12.0);
            start = (*p1, *i1, *m1);
        }
        let (p0, i0, m0) = start;
        match end {
            None => {
                let x = psi - p0;
                (i0 + m0 * x, m0, w + x * (i0 + 0.5 * m0 * x))
            }
            Some((p1, i1, m1)) => {
                let h = p1 - p0;
                let t = (psi - p0) / h;
                let (t2, t3) = (t * t, t * t * t);
                let t4 = t2 * t2;
                let i = (2.0 * t3 - 3.0 * t2 + 1.0) * i0
                    + (t3 - 2.0 * t2 + t) * h * m0
                    + (3.0 * t2 - 2.0 * t3) * i1
                    + (t3 - t2) * h * m1;
                let slope = (6.0 * t2 - 6.0 * t) / h * (i0 - i1)
                    + (3.0 * t2 - 4.0 * t + 1.0) * m0
                    + (3.0 * t2 - 2.0 * t) * m1;
                let energy = h
                    * ((t - t3 + 0.5 * t4) * i0
                        + (0.5 * t2 - 2.0 / 3.0 * t3 + 0.25 * t4) * h * m0
                        + (t3 - 0.5 * t4) * i1
                        + (0.25 * t4 - t3 / 3.0) * h * m1);
                (i, slope, w + energy)
            }
        }
    }

    /// (β·ψ)^S: by squaring for a whole S up to 32 (the laws in use: motulator's S = 7; a
    /// simulated step evaluates it a dozen times), else `pow`.
    #[inline]
    fn saturation_term(beta_per_wb: f64, exponent: f64, whole_exponent: u32, psi: f64) -> f64 {
        let x = beta_per_wb * psi;
        if whole_exponent > 0 {
            let (mut n, mut base, mut acc) = (whole_exponent, x, 1.0);
            while n > 0 {
                if n & 1 == 1 {
                    acc *= base;
                }
                base *= base;
                n >>= 1;
            }
            acc
        } else {
            libm::pow(x, exponent)
        }
    }

    /// The magnetizing current's magnitude at flux magnitude `psi_wb` ≥ 0, A.
    pub fn current_a(&self, psi_wb: f64) -> f64 {
        match self.0 {
            Repr::Law { .. } => psi_wb * self.inverse_inductance_per_h(psi_wb),
            Repr::Points { n, psi_wb: ref p, current_a: ref i, slope_per_h: ref m } => {
                Self::points_at(n, p, i, m, psi_wb).0
            }
        }
    }

    /// The same curve with every inductance scaled by `k` > 0 (the currents divided by it):
    /// a change of the magnetizing inductance injected into a saturating plant.
    pub fn with_inductance_scaled(&self, k: f64) -> Self {
        match self.0 {
            Repr::Law { inv_l_unsat_per_h, beta_per_wb, exponent, whole_exponent } => Self(Repr::Law {
                inv_l_unsat_per_h: inv_l_unsat_per_h / k,
                beta_per_wb,
                exponent,
                whole_exponent,
            }),
            Repr::Points { n, psi_wb, current_a, slope_per_h } => Self(Repr::Points {
                n,
                psi_wb,
                current_a: current_a.map(|i| i / k),
                slope_per_h: slope_per_h.map(|m| m / k),
            }),
        }
    }

    /// A flux far into saturation, Wb: where the law's inductance has fallen to a tenth of
    /// its unsaturated value (`(β·ψ)^S = 9`: 1.63 Wb, 1.37× the knee 1/β, on motulator's
    /// 2.2-kW curve, whose rated flux is 1.04 Wb), a tenth past the last point of a measured
    /// curve. A plant's fastest mode is judged there (its incremental inductance is larger
    /// at any flux below); beyond it the integration step is not proven stable.
    pub fn deep_flux_wb(&self) -> f64 {
        match self.0 {
            Repr::Law { beta_per_wb, exponent, .. } => libm::pow(9.0, 1.0 / exponent) / beta_per_wb,
            Repr::Points { n, psi_wb, .. } => psi_wb.get(n.saturating_sub(1)).copied().unwrap_or(0.0) * 1.1,
        }
    }

    /// `current_a(ψ)/ψ`, the secant inverse inductance 1/L(ψ), 1/H; its limit at ψ = 0.
    pub fn inverse_inductance_per_h(&self, psi_wb: f64) -> f64 {
        match self.0 {
            Repr::Law { inv_l_unsat_per_h, beta_per_wb, exponent, whole_exponent } => {
                (1.0 + Self::saturation_term(beta_per_wb, exponent, whole_exponent, psi_wb))
                    * inv_l_unsat_per_h
            }
            Repr::Points { slope_per_h: ref m, .. } => {
                if psi_wb > 0.0 {
                    self.current_a(psi_wb) / psi_wb
                } else {
                    m.first().copied().unwrap_or(0.0)
                }
            }
        }
    }

    /// The incremental inverse inductance di/dψ at `psi_wb`, 1/H.
    pub fn slope_per_h(&self, psi_wb: f64) -> f64 {
        match self.0 {
            Repr::Law { inv_l_unsat_per_h, beta_per_wb, exponent, whole_exponent } => {
                (1.0 + (exponent + 1.0)
                    * Self::saturation_term(beta_per_wb, exponent, whole_exponent, psi_wb))
                    * inv_l_unsat_per_h
            }
            Repr::Points { n, psi_wb: ref p, current_a: ref i, slope_per_h: ref m } => {
                Self::points_at(n, p, i, m, psi_wb).1
            }
        }
    }

    /// The magnetic energy stored at flux magnitude `psi_wb`, ∫₀^ψ f(r) dr, J per unit of
    /// the space vector's peak scaling (times 3/2 for the machine's three phases).
    pub fn energy(&self, psi_wb: f64) -> f64 {
        match self.0 {
            Repr::Law { inv_l_unsat_per_h, beta_per_wb, exponent, whole_exponent } => {
                let s = Self::saturation_term(beta_per_wb, exponent, whole_exponent, psi_wb);
                psi_wb * psi_wb * (0.5 + s / (exponent + 2.0)) * inv_l_unsat_per_h
            }
            Repr::Points { n, psi_wb: ref p, current_a: ref i, slope_per_h: ref m } => {
                Self::points_at(n, p, i, m, psi_wb).2
            }
        }
    }

    /// The flux magnitude r ≥ 0 at which `current_a(r) + r·k_per_h = a` (a ≥ 0, k ≥ 0): the
    /// branch in parallel with a linear inductance 1/k fed the total current `a` — what
    /// turns the currents of a saturated machine back into its fluxes. The left side rises
    /// with r, so the root is unique. Newton from the linear bound `a/(1/L(0) + k)` (above
    /// the root: the curve bends up), at most 60 iterations; a step below 1e-9·r is the
    /// last (Newton squares the error: the next is below rounding), which on motulator's
    /// curve at rated flux ends after three.
    pub fn flux_at_total_current(&self, a: f64, k_per_h: f64) -> f64 {
        if a.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            return 0.0;
        }
        let mut r = a / (self.inverse_inductance_per_h(0.0) + k_per_h);
        for _ in 0..60 {
            let (i, slope) = self.current_and_slope(r);
            let step = (i + r * k_per_h - a) / (slope + k_per_h);
            let next = (r - step).max(0.5 * r);
            if !next.is_finite() {
                return r;
            }
            r = next;
            if step.abs() <= 1e-9 * r {
                break;
            }
        }
        r
    }

    /// `(current_a(ψ), slope_per_h(ψ))` from one evaluation of the law.
    #[inline]
    fn current_and_slope(&self, psi_wb: f64) -> (f64, f64) {
        match self.0 {
            Repr::Law { inv_l_unsat_per_h, beta_per_wb, exponent, whole_exponent } => {
                let t = Self::saturation_term(beta_per_wb, exponent, whole_exponent, psi_wb);
                (psi_wb * (1.0 + t) * inv_l_unsat_per_h, (1.0 + (exponent + 1.0) * t) * inv_l_unsat_per_h)
            }
            Repr::Points { n, psi_wb: ref p, current_a: ref i, slope_per_h: ref m } => {
                let (i, slope, _) = Self::points_at(n, p, i, m, psi_wb);
                (i, slope)
            }
        }
    }
}

/// Points of the drive's magnetizing table ([`MagnetizingTable`]) beyond the origin.
pub const TABLE_POINTS: usize = 16;
/// The table's step in magnetizing current, × the rated flux's: it spans 0 … 2× that
/// current (the flux rises past the rated one by the curve's last segment beyond).
pub const TABLE_STEP: f64 = 0.125;
/// The point of the table at the rated current (its flux is the rated flux).
const TABLE_RATED: usize = 7;

/// The drive's view of a saturating branch (issue 50): the rotor flux at no load against
/// the magnetizing current, both per unit of the rated point — `flux_ratio[k]` is
/// `ψ(x)/ψ_N` at `x = (k + 1)·`[`TABLE_STEP`] `× i_N`, with `i_N` the current of the rated
/// rotor flux `ψ_N` (so `flux_ratio[7]` is 1), joined by straight lines from the origin
/// and the last segment extended. At no load the rotor current is zero, so in either form
/// the branch's flux is the rotor's: the table is the no-load test's curve
/// ([`Self::of_curve`]). The drive runs on its chord `ψ(x)/(x·ψ_N)`, the inductance scale
/// at that current ([`MagnetizingChord`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MagnetizingTable {
    /// ψ/ψ_N at each step of the current.
    pub flux_ratio: [f64; TABLE_POINTS],
}

/// Why a [`MagnetizingTable`] was refused: the point at this index (`TABLE_POINTS`: the
/// rated point's flux is not 1) is not finite, not rising, or rises more than twice as steeply
/// as the chord to it — the drive's chord model then does not settle (its magnetizing
/// current is `ψ*/chord` on the present current, which converges while
/// `0 < L_diff < 2·L_chord`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TableError(pub usize);

impl MagnetizingTable {
    /// The table of `curve` (a branch's) with its rated point at the rotor flux
    /// `flux_rated_wb` at no load, and that point's magnetizing current, A (`None`: the flux
    /// is not finite and positive).
    pub fn of_curve(curve: &MagnetizingCurve, flux_rated_wb: f64) -> Option<(Self, f64)> {
        if !(flux_rated_wb.is_finite() && flux_rated_wb > 0.0) {
            return None;
        }
        let i_rated_a = curve.current_a(flux_rated_wb);
        let mut flux_ratio = [0.0; TABLE_POINTS];
        for (k, y) in flux_ratio.iter_mut().enumerate() {
            let i = (k + 1) as f64 * TABLE_STEP * i_rated_a;
            *y = curve.flux_at_total_current(i, 0.0) / flux_rated_wb;
        }
        // The rated point exactly (Newton leaves it within 1e-9).
        if let Some(y) = flux_ratio.get_mut(TABLE_RATED) {
            *y = 1.0;
        }
        Some((Self { flux_ratio }, i_rated_a))
    }

    /// Refuses what the drive cannot run on ([`TableError`]).
    pub fn validate(&self) -> Result<(), TableError> {
        let mut y0 = 0.0;
        for (k, &y) in self.flux_ratio.iter().enumerate() {
            let x = (k + 1) as f64 * TABLE_STEP;
            let slope = (y - y0) / TABLE_STEP;
            if !(y.is_finite() && y > y0 && slope < 2.0 * y / x) {
                return Err(TableError(k));
            }
            y0 = y;
        }
        match self.flux_ratio.get(TABLE_RATED) {
            Some(&y) if (y - 1.0).abs() <= 1e-6 => Ok(()),
            _ => Err(TableError(TABLE_POINTS)),
        }
    }

    /// The chord `ψ(x)/(x·ψ_N)` at current ratio `x` ≥ 0 (the inductance at that current
    /// over the rated one; its limit at 0): [`MagnetizingChord::ratio`] in f64.
    pub fn chord_ratio(&self, x: f64) -> f64 {
        let u = x / TABLE_STEP;
        let at = |m: usize| self.flux_ratio.get(m.wrapping_sub(1)).copied().unwrap_or(0.0);
        if u.partial_cmp(&1.0) != Some(core::cmp::Ordering::Greater) {
            return at(1) / TABLE_STEP;
        }
        // The segment [m, m + 1] in steps (the last one extended beyond it).
        let m = (u as usize).clamp(1, TABLE_POINTS - 1);
        (at(m) + (u - m as f64) * (at(m + 1) - at(m))) / x
    }
}

crate::raw::raw_struct! {
    /// The drive's magnetizing table in f32 ([`MagnetizingTable`] on the target): the
    /// inductance scale the field orientation and the machine model run on at a magnetizing
    /// current (`Drive`'s slow step follows it, issue 50). `on` false: a linear motor, nothing
    /// is evaluated.
    #[derive(Clone, Copy, Debug, Default, PartialEq)]
    pub struct MagnetizingChord {
        /// The motor saturates: the table is in use.
        pub(crate) on: bool,
        /// `1/(Δx·i_N)`: the magnetizing current in table steps, 1/A.
        pub(crate) steps_per_a: f32,
        /// `1/ψ_N`: the flux in units of the rated one, 1/Wb.
        pub(crate) per_wb: f32,
        /// [`MagnetizingTable::flux_ratio`].
        pub(crate) flux_ratio: [f32; TABLE_POINTS],
    }
}

impl MagnetizingChord {
    /// The drive's table of `t` with the rated flux `flux_rated_wb` at the magnetizing
    /// current `i_rated_a` (both > 0), or a linear motor's (`None`).
    pub fn new(t: Option<&MagnetizingTable>, i_rated_a: f64, flux_rated_wb: f64) -> Self {
        match t {
            Some(t) => Self {
                on: true,
                steps_per_a: (1.0 / (TABLE_STEP * i_rated_a)) as f32,
                per_wb: (1.0 / flux_rated_wb) as f32,
                flux_ratio: t.flux_ratio.map(|y| y as f32),
            },
            None => Self::default(),
        }
    }

    /// The motor saturates (and the build carries the curve: controller-core's `curve`
    /// feature, a constant otherwise — none of the curve's code is linked).
    #[inline]
    pub fn on(&self) -> bool {
        cfg!(feature = "curve") && self.on
    }

    /// The chord ratio at the flux `psi_wb` (Wb; 0 or less: the unsaturated end's): the
    /// table read the other way — the current of that flux (at a refresh of the machine
    /// model, not every slow step).
    #[inline(never)]
    pub fn ratio_at_flux(&self, psi_wb: f32) -> f32 {
        let y = psi_wb * self.per_wb;
        let table = &self.flux_ratio;
        let at = |m: usize| table.get(m.wrapping_sub(1)).copied().unwrap_or(0.0);
        // The segment [m, m + 1] in steps holding y (a binary search of the rising table),
        // the last one extended beyond it.
        let m = table.partition_point(|&y1| y1 < y).min(TABLE_POINTS - 1);
        let u = m as f32 + (y - at(m)) / (at(m + 1) - at(m));
        if u > 0.0 { y / (u * TABLE_STEP as f32) } else { at(1) / TABLE_STEP as f32 }
    }

    /// The magnetizing current of the flux `psi_wb` on the table, A (the file's machine; 0 at
    /// a flux of 0 or less): `i_N·(ψ/ψ_N)/c(ψ)`, the table read the other way.
    pub fn current_at_flux(&self, psi_wb: f32) -> f32 {
        if psi_wb <= 0.0 {
            return 0.0;
        }
        psi_wb * self.per_wb / (self.ratio_at_flux(psi_wb) * self.steps_per_a * TABLE_STEP as f32)
    }

    /// Off, or on in a build that carries the curve (controller-core's `curve` feature).
    pub(crate) fn is_built(&self) -> bool {
        !self.on || cfg!(feature = "curve")
    }

    /// Off, or on a positive step and a rising table (what [`crate::drive::DriveConfig::from_raw`]
    /// checks of a raw table: the rest is [`MagnetizingTable::validate`]'s, on the host).
    pub(crate) fn is_valid(&self) -> bool {
        let mut last = 0.0;
        !self.on
            || (self.steps_per_a > 0.0
                && self.per_wb > 0.0
                && self.flux_ratio.iter().all(|&y| {
                    let up = y > last;
                    last = y;
                    up
                }))
    }

    /// The chord ratio ([`MagnetizingTable::chord_ratio`]) at magnetizing current
    /// `i_m_a` (A; 0 or less: the unsaturated end's). Out of line: the flux model's and the
    /// machine model's call share it (inlined into both, the firmware took 80 B more flash).
    #[inline(never)]
    pub fn ratio(&self, i_m_a: f32) -> f32 {
        let u = i_m_a * self.steps_per_a;
        let y = &self.flux_ratio;
        let at = |m: usize| y.get(m.wrapping_sub(1)).copied().unwrap_or(0.0);
        let step = TABLE_STEP as f32;
        if u.partial_cmp(&1.0) != Some(core::cmp::Ordering::Greater) {
            return at(1) / step;
        }
        let m = (u as usize).clamp(1, TABLE_POINTS - 1);
        (at(m) + (u - m as f32) * (at(m + 1) - at(m))) / (u * step)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motulator() -> MagnetizingCurve {
        MagnetizingCurve::law(0.34, 0.84, 7.0).unwrap()
    }

    /// The numbers for motulator's 2.2 kW curve: L(ψ)/L(0) and the energy as the
    /// integral of the current (trapezoids on a fine grid), for the law and for the same
    /// curve given as points.
    #[test]
    fn the_law_and_its_points_agree_with_their_definitions() {
        let c = motulator();
        for psi in [0.0, 0.3, 0.9, 1.2, 1.6] {
            let l = 0.34 / (1.0 + libm::pow(0.84 * psi, 7.0));
            assert!((c.inverse_inductance_per_h(psi) - 1.0 / l).abs() < 1e-12 / l);
            assert!((c.current_a(psi) - psi / l).abs() < 1e-12);
            let h = 1e-6;
            let numeric =
                (c.current_a(psi + h) - c.current_a((psi - h).max(0.0))) / (psi + h - (psi - h).max(0.0));
            assert!((c.slope_per_h(psi) - numeric).abs() < 1e-5 * c.slope_per_h(psi), "{psi}");
            let n = 20_000;
            let trapezoid: f64 = (0..n)
                .map(|k| {
                    let (a, b) = (psi * k as f64 / n as f64, psi * (k + 1) as f64 / n as f64);
                    0.5 * (c.current_a(a) + c.current_a(b)) * (b - a)
                })
                .sum();
            assert!((c.energy(psi) - trapezoid).abs() < 1e-8 * (1.0 + trapezoid), "{psi}");
        }
        let psi: [f64; 12] = core::array::from_fn(|k| 0.15 * (k + 1) as f64);
        let cur = psi.map(|p| c.current_a(p));
        let p = MagnetizingCurve::points(&psi, &cur).unwrap();
        for k in 0..12 {
            assert!((p.current_a(psi[k]) - cur[k]).abs() < 1e-12);
        }
        // Between the points the monotone cubic follows the law far closer than straight
        // lines (the chord over 0.15 Wb of a knee): within 0.6 % up to 1.65 Wb, where the
        // chords miss by up to 5 %; it rises, its slope is its current's derivative and
        // continuous at the points, and its energy is its current's integral.
        let (mut cubic, mut chords) = (0.0f64, 0.0f64);
        let mut last_i = 0.0;
        for k in 1..=1650 {
            let x = 1e-3 * f64::from(k);
            let (j, truth) = (p.current_a(x), c.current_a(x));
            cubic = cubic.max((j / truth - 1.0).abs());
            let seg = ((x / 0.15).ceil() as usize).clamp(1, 12) - 1;
            let (q0, j0) = if seg == 0 { (0.0, 0.0) } else { (psi[seg - 1], cur[seg - 1]) };
            let line = j0 + (cur[seg] - j0) / (psi[seg] - q0) * (x - q0);
            chords = chords.max((line / truth - 1.0).abs());
            assert!(j > last_i, "{x}");
            last_i = j;
            let h = 1e-7;
            let numeric = (p.current_a(x + h) - p.current_a(x - h)) / (2.0 * h);
            assert!((p.slope_per_h(x) - numeric).abs() < 1e-5 * p.slope_per_h(x), "{x}");
        }
        assert!(cubic < 0.006 && chords > 0.04, "cubic {cubic}, chords {chords}");
        for knot in psi {
            let (below, above) = (p.slope_per_h(knot - 1e-12), p.slope_per_h(knot + 1e-12));
            assert!((below / above - 1.0).abs() < 1e-6, "{knot}: {below} {above}");
        }
        // Simpson's rule on each 1 mWb: exact for the cubics, their knots on its nodes.
        let simpson: f64 = (0..1700)
            .map(|k| {
                let (a, b) = (1e-3 * f64::from(k), 1e-3 * f64::from(k + 1));
                (b - a) / 6.0 * (p.current_a(a) + 4.0 * p.current_a(0.5 * (a + b)) + p.current_a(b))
            })
            .sum();
        assert!((p.energy(1.7) - simpson).abs() < 1e-12 * simpson, "{} {simpson}", p.energy(1.7));
        // Beyond the last point, the last segment's chord extended.
        let last = (cur[11] - cur[10]) / (psi[11] - psi[10]);
        assert!((p.current_a(2.0) - (cur[11] + last * 0.2)).abs() < 1e-9);
        assert!(
            (p.energy(2.0) - p.energy(1.8) - 0.5 * (p.current_a(1.8) + p.current_a(2.0)) * 0.2).abs() < 1e-9
        );
    }

    #[test]
    fn flux_at_total_current_solves_its_equation() {
        let c = motulator();
        let pts = MagnetizingCurve::points(&[0.5, 1.0, 1.2], &[1.6, 3.8, 7.0]).unwrap();
        for curve in [c, pts] {
            for k in [0.0, 1.0 / 0.023, 1e3] {
                for a in [1e-9, 0.5, 5.0, 50.0, 500.0] {
                    let r = curve.flux_at_total_current(a, k);
                    let g = curve.current_a(r) + r * k;
                    assert!((g - a).abs() <= 1e-12 * a, "{curve:?} k {k} a {a}: r {r} gives {g}");
                }
            }
            assert_eq!(curve.flux_at_total_current(0.0, 1.0), 0.0);
            assert_eq!(curve.flux_at_total_current(f64::NAN, 1.0), 0.0);
        }
    }

    #[test]
    fn bad_curves_are_refused() {
        assert_eq!(MagnetizingCurve::law(0.0, 0.84, 7.0), Err(CurveError::Law));
        assert_eq!(MagnetizingCurve::law(0.34, f64::NAN, 7.0), Err(CurveError::Law));
        assert_eq!(MagnetizingCurve::law(0.34, 0.84, 0.5), Err(CurveError::Law));
        assert_eq!(MagnetizingCurve::points(&[1.0], &[1.0]), Err(CurveError::Count));
        assert_eq!(MagnetizingCurve::points(&[1.0, 2.0], &[1.0]), Err(CurveError::Count));
        assert_eq!(MagnetizingCurve::points(&[1.0, 1.0], &[1.0, 2.0]), Err(CurveError::NotRising(1)));
        assert_eq!(MagnetizingCurve::points(&[1.0, 2.0], &[1.0, 0.5]), Err(CurveError::NotRising(1)));
        assert_eq!(MagnetizingCurve::points(&[-1.0, 2.0], &[1.0, 2.0]), Err(CurveError::NotRising(0)));
        assert_eq!(MagnetizingCurve::points(&[0.5; 17], &[1.0; 17]), Err(CurveError::Count));
    }

    /// The drive's table of motulator's 2.2-kW curve at its rated rotor flux: the chord it
    /// gives is the curve's own to a fraction of a percent from a third of the rated current
    /// to twice it (linear interpolation of a bending curve), 1 at the rated point, the
    /// unsaturated inductance below the first step; the f32 copy the drive runs agrees with
    /// it; a straight curve gives 1 everywhere.
    #[test]
    fn the_drive_table_follows_the_curve() {
        let curve = MagnetizingCurve::law(0.34, 0.84, 7.0).unwrap();
        let psi_n = 0.95;
        let (t, i_n) = MagnetizingTable::of_curve(&curve, psi_n).unwrap();
        t.validate().unwrap();
        assert!((curve.current_a(psi_n) - i_n).abs() < 1e-12);
        let chord = MagnetizingChord::new(Some(&t), i_n, psi_n);
        let mut worst: f64 = 0.0;
        for k in 0..=170 {
            let x = 0.3 + 0.01 * f64::from(k);
            let truth = curve.flux_at_total_current(x * i_n, 0.0) / (x * psi_n);
            worst = worst.max((t.chord_ratio(x) / truth - 1.0).abs());
            let f32_ratio = f64::from(chord.ratio((x * i_n) as f32));
            assert!((f32_ratio / t.chord_ratio(x) - 1.0).abs() < 1e-5, "x {x}: {f32_ratio}");
            // Read by flux: the same chord at the flux the table gives that current.
            let psi = t.chord_ratio(x) * x * psi_n;
            let by_flux = f64::from(chord.ratio_at_flux(psi as f32));
            assert!((by_flux / t.chord_ratio(x) - 1.0).abs() < 1e-4, "x {x}: {by_flux}");
            // … and the current of that flux, the table read the other way.
            let i = f64::from(chord.current_at_flux(psi as f32));
            assert!((i / (x * i_n) - 1.0).abs() < 1e-4, "x {x}: {i}");
        }
        assert_eq!(chord.current_at_flux(0.0), 0.0);
        assert_eq!(chord.current_at_flux(-0.1), 0.0);
        assert!(worst < 0.01, "worst chord error {worst}");
        assert_eq!(t.chord_ratio(1.0), 1.0);
        let unsat = curve.flux_at_total_current(0.1 * i_n, 0.0) / (0.1 * psi_n);
        assert!((t.chord_ratio(0.0) / unsat - 1.0).abs() < 0.01, "{} vs {unsat}", t.chord_ratio(0.0));
        assert!(!MagnetizingChord::new(None, i_n, psi_n).on());
        assert_eq!(chord.ratio_at_flux(0.0), chord.ratio(0.0));

        let straight = MagnetizingCurve::points(&[0.5, 1.0], &[1.0, 2.0]).unwrap();
        let (t, _) = MagnetizingTable::of_curve(&straight, 0.8).unwrap();
        for x in [0.0, 0.2, 0.9, 1.0, 1.7, 2.5] {
            assert!((t.chord_ratio(x) - 1.0).abs() < 1e-9, "{x}: {}", t.chord_ratio(x));
        }
        assert!(MagnetizingTable::of_curve(&straight, 0.0).is_none());
    }

    /// A table the drive cannot settle on is refused at the point that breaks it.
    #[test]
    fn a_table_the_drive_cannot_run_on_is_refused() {
        let good =
            MagnetizingTable::of_curve(&MagnetizingCurve::law(0.34, 0.84, 7.0).unwrap(), 0.95).unwrap().0;
        let with = |k: usize, y: f64| {
            let mut t = good;
            t.flux_ratio[k] = y;
            t.validate()
        };
        assert_eq!(with(3, f64::NAN), Err(TableError(3)));
        assert_eq!(with(10, good.flux_ratio[9]), Err(TableError(10)));
        // A step more than twice as steep as the chord to it.
        assert_eq!(with(5, 2.0), Err(TableError(5)));
        assert_eq!(with(7, 1.01), Err(TableError(TABLE_POINTS)));
    }
}
