//! Seed 001: robust PI control of a recycle process with an uncertain process gain.
//!
//! Unit 1 `G(s) = G_L(s) = k/(τs + 1)²` under a PI `C(s) = k₁ + k₂/s`; the recycle unit
//! `G_R(s) = k_R/(τ_R s + 1)` feeds the output back positively. The load response (14) is
//!
//! ```text
//! Y/L = G_L / (1 + C·G − G_L·G_R) = k·s·(τ_R s + 1) / Δ(s),
//! Δ(s) = s(τs + 1)²(τ_R s + 1) + k(k₁s + k₂)(τ_R s + 1) − k·k_R·s      (16), (17)
//! ```
//!
//! built here from the loop's polynomials, not typed in. Δ is affine in `k`, so the
//! family over `k ∈ [k_lo, k_hi]` is a segment of polynomials: its exact robust stability
//! is Bialas' test ([`segment_is_hurwitz`]); its interval hull (the paper's (16)) is what
//! Kharitonov's theorem and lemmas 2.1/2.2 see — conservative, because the hull's
//! coefficients vary independently while the family's move together with `k`.
//!
//! Findings against the paper (numbers from `design recycle --json`, asserted in tests):
//! - The printed interval (16) writes the s¹ coefficient as `[k₁ + k₂ − 0.6, 3k₁ + 3k₂ − 3.8]`;
//!   that is its lower end only when `k₁ + k₂ ≥ 1.6`. Below, the ends swap, the seventh
//!   printed constraint (`3k₁ + 3k₂ ≥ 3.8`, i.e. `y₁ ≥ 0` instead of `y₁ ≥ x₁`) lets the
//!   true lower end reach zero, and the printed NLP's optimum (k₁, k₂) = (1.1244, 0.1422)
//!   is **not** robustly stable: the closed loop is unstable at k = 3.
//! - Table I's ε is not defined in the text, and its sets are not optima of the printed NLP
//!   (whose optimum is the point above); all five sets are nonetheless robustly stable.

use crate::kharitonov::{IntervalError, IntervalPoly, NIE_SUFFICIENT};
use crate::poly::{Poly, segment_is_hurwitz};
use crate::tf::Tf;

/// PI gains `C(s) = k₁ + k₂/s`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Pi {
    /// Proportional gain k₁.
    pub k1: f64,
    /// Integral gain k₂ (1/s).
    pub k2: f64,
}

impl Pi {
    /// The NLP objective (18): squared distance to `nominal`.
    pub fn cost(&self, nominal: &Pi) -> f64 {
        (self.k1 - nominal.k1).powi(2) + (self.k2 - nominal.k2).powi(2)
    }
}

/// The recycle process; construct with [`RecycleProcess::new`] (validated).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RecycleProcess {
    k_lo: f64,
    k_hi: f64,
    k_nominal: f64,
    tau_s: f64,
    k_r: f64,
    tau_r_s: f64,
}

/// Table I of seed 001: (set, ε, k₁, k₂).
#[allow(clippy::approx_constant)] // set 5's k₂ = 0.6931 is the paper's number, not ln 2
pub const TABLE_I: [(u32, f64, f64, f64); 5] = [
    (1, 0.5, 1.2992, 0.1667),
    (2, 1.0, 1.8133, 0.3333),
    (3, 1.5, 2.2337, 0.5),
    (4, 1.8, 2.4561, 0.6),
    (5, 2.5, 2.4242, 0.6931),
];

/// The seven NLP constraints exactly as printed under eq. (18), `g_i(k₁, k₂) ≤ 0`.
/// Kept verbatim to reproduce the paper; the tests show each is a lemma 2.1/2.2 condition
/// on the printed interval (16), and where that interval is wrong.
pub fn printed_constraints(pi: &Pi) -> [f64; 7] {
    let (k1, k2) = (pi.k1, pi.k2);
    [
        -k1 * k1 - 2.4 * k1 + 6.0 * k2 - k1 * k2 + 1.8,
        3.0 * k2 - 12.8,
        -k1 * k1 - 2.4 * k1 + 16.3340 * k2 - k1 * k2 + 1.8,
        1.6035 * k1 + 3.0 * k2 - 7.9895,
        -k1 - k2 + 0.6,
        -k1 - 3.0,
        -3.0 * k1 - 3.0 * k2 + 3.8,
    ]
}

/// The interval polynomial (16) as printed (descending), valid only where its printed
/// lower ends are below the upper ones.
pub fn printed_interval(pi: &Pi) -> Result<IntervalPoly, IntervalError> {
    let (k1, k2) = (pi.k1, pi.k2);
    IntervalPoly::new(
        &[1.0, 3.0, k1 + 3.0, k1 + k2 - 0.6, k2],
        &[1.0, 3.0, 3.0 * k1 + 3.0, 3.0 * k1 + 3.0 * k2 - 3.8, 3.0 * k2],
    )
}

impl RecycleProcess {
    /// Seed 001 Sec. IV: k ∈ [1, 3] (nominal 2), τ = 1, k_R = 1.6, τ_R = 1.
    pub fn seed001() -> Self {
        Self { k_lo: 1.0, k_hi: 3.0, k_nominal: 2.0, tau_s: 1.0, k_r: 1.6, tau_r_s: 1.0 }
    }

    /// Validated: finite, `0 < k_lo ≤ k_nominal ≤ k_hi`, `τ, τ_R > 0`.
    pub fn new(k: (f64, f64), k_nominal: f64, tau_s: f64, k_r: f64, tau_r_s: f64) -> Result<Self, String> {
        let all_finite = [k.0, k.1, k_nominal, tau_s, k_r, tau_r_s].iter().all(|x| x.is_finite());
        if !all_finite {
            return Err("recycle process parameters must be finite".into());
        }
        if !(0.0 < k.0 && k.0 <= k_nominal && k_nominal <= k.1) {
            return Err(format!("need 0 < k_lo ≤ k_nominal ≤ k_hi, got [{}, {}] ∋ {k_nominal}", k.0, k.1));
        }
        if tau_s <= 0.0 || tau_r_s <= 0.0 {
            return Err(format!("time constants must be positive, got τ = {tau_s}, τ_R = {tau_r_s}"));
        }
        Ok(Self { k_lo: k.0, k_hi: k.1, k_nominal, tau_s, k_r, tau_r_s })
    }

    /// Gain range `(k_lo, k_hi)`.
    pub fn k_range(&self) -> (f64, f64) {
        (self.k_lo, self.k_hi)
    }

    /// Nominal process gain.
    pub fn k_nominal(&self) -> f64 {
        self.k_nominal
    }

    fn lag2(&self) -> Poly {
        Poly::new(&[self.tau_s, 1.0]).mul(&Poly::new(&[self.tau_s, 1.0]))
    }

    fn pi_num(pi: &Pi) -> Poly {
        Poly::new(&[pi.k1, pi.k2])
    }

    /// Unit 1 alone (eq. (12)): `s(τs + 1)² + k(k₁s + k₂)`.
    pub fn unit1_characteristic(&self, k: f64, pi: &Pi) -> Poly {
        Poly::new(&[1.0, 0.0]).mul(&self.lag2()).add(&Self::pi_num(pi).scale(k))
    }

    /// With the recycle (eqs. (16)–(17)): `s(τs + 1)²(τ_R s + 1) + k(k₁s + k₂)(τ_R s + 1) − k·k_R·s`.
    pub fn characteristic(&self, k: f64, pi: &Pi) -> Poly {
        let recycle_lag = Poly::new(&[self.tau_r_s, 1.0]);
        Poly::new(&[1.0, 0.0])
            .mul(&self.lag2())
            .mul(&recycle_lag)
            .add(&Self::pi_num(pi).mul(&recycle_lag).scale(k))
            .add(&Poly::new(&[-k * self.k_r, 0.0]))
    }

    /// Load-to-output transfer function (14): with the recycle `k·s(τ_R s + 1)/Δ`, without
    /// it `k·s/(s(τs + 1)² + k(k₁s + k₂))`.
    pub fn load_response(&self, k: f64, pi: &Pi, recycle: bool) -> Tf {
        if recycle {
            Tf { num: Poly::new(&[k * self.tau_r_s, k, 0.0]), den: self.characteristic(k, pi) }
        } else {
            Tf { num: Poly::new(&[k, 0.0]), den: self.unit1_characteristic(k, pi) }
        }
    }

    /// The closed loop's interval polynomial over `k ∈ [k_lo, k_hi]` with every root
    /// shifted right by `decay` (`decay = 0`: eq. (16) as it should read). Δ is affine in
    /// k, so the hull of the two end members is exact.
    pub fn interval(&self, pi: &Pi, decay: f64) -> IntervalPoly {
        IntervalPoly::hull(&self.end_members(pi, decay))
    }

    /// Exact: every member `k ∈ [k_lo, k_hi]` has all roots left of `−decay` (Bialas).
    pub fn family_is_stable(&self, pi: &Pi, decay: f64) -> bool {
        let [a, b] = self.end_members(pi, decay);
        segment_is_hurwitz(&a, &b)
    }

    /// Δ at `k_lo` and `k_hi`, roots shifted right by `decay`: the ends of the segment the
    /// family is.
    fn end_members(&self, pi: &Pi, decay: f64) -> [Poly; 2] {
        [self.k_lo, self.k_hi].map(|k| self.characteristic(k, pi).shifted(decay))
    }

    /// Exact for unit 1 without the recycle.
    pub fn unit1_family_is_stable(&self, pi: &Pi) -> bool {
        segment_is_hurwitz(
            &self.unit1_characteristic(self.k_lo, pi),
            &self.unit1_characteristic(self.k_hi, pi),
        )
    }

    /// The family's worst closed-loop pole: `(max Re, k where it occurs)` — a 201-point
    /// sweep of k refined by golden-section search around the worst sample.
    pub fn family_abscissa(&self, pi: &Pi) -> (f64, f64) {
        let f = |k: f64| self.characteristic(k, pi).max_real_root();
        let n = 200;
        let step = (self.k_hi - self.k_lo) / n as f64;
        let (mut best_k, mut best) = (self.k_lo, f(self.k_lo));
        for i in 1..=n {
            let k = self.k_lo + step * i as f64;
            let v = f(k);
            if v > best {
                (best_k, best) = (k, v);
            }
        }
        let (mut a, mut b) = ((best_k - step).max(self.k_lo), (best_k + step).min(self.k_hi));
        // Golden section: each iteration keeps one interior point (and its value) and
        // evaluates one new one.
        let g = (5.0_f64.sqrt() - 1.0) / 2.0;
        let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
        let (mut fc, mut fd) = (f(c), f(d));
        for _ in 0..60 {
            if fc >= fd {
                (b, d, fd) = (d, c, fc);
                c = b - g * (b - a);
                fc = f(c);
            } else {
                (a, c, fc) = (c, d, fd);
                d = a + g * (b - a);
                fd = f(d);
            }
        }
        let k = 0.5 * (a + b);
        let v = f(k);
        if v > best { (v, k) } else { (best, best_k) }
    }

    /// The ITAE-optimal nominal PI (eq. (13)): unit 1's characteristic at the nominal gain,
    /// made monic, matched to `s³ + 1.75ω s² + 2.15ω² s + ω³` (the s² coefficient fixes
    /// ω = 2/(1.75τ)).
    pub fn itae(&self) -> Pi {
        let (k, tau) = (self.k_nominal, self.tau_s);
        let w = 2.0 / (1.75 * tau);
        Pi { k1: (2.15 * w * w * tau * tau - 1.0) / k, k2: w.powi(3) * tau * tau / k }
    }

    /// Smallest `k` in the range where the recycle loop with `pi` stops being stable
    /// (`None`: stable over the whole range): a 401-point sweep, then bisection on the sign
    /// of the largest pole real part.
    pub fn loss_of_stability_k(&self, pi: &Pi) -> Option<f64> {
        let unstable = |k: f64| self.characteristic(k, pi).max_real_root() >= 0.0;
        let n = 400;
        let step = (self.k_hi - self.k_lo) / n as f64;
        let first = (0..=n).map(|i| self.k_lo + step * i as f64).find(|&k| unstable(k))?;
        if first <= self.k_lo {
            return Some(self.k_lo);
        }
        let (mut a, mut b) = (first - step, first);
        for _ in 0..80 {
            let m = 0.5 * (a + b);
            if unstable(m) { b = m } else { a = m }
        }
        Some(0.5 * (a + b))
    }
}

/// Which robust-stability condition the NLP (18) is solved under.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Constraints {
    /// The seven inequalities as printed in the paper.
    PaperPrinted,
    /// Lemma 2.2 (sufficient, with lemma 2.1 and positivity) on the interval polynomial
    /// built from the loop (correct orientation).
    Lemmas,
    /// Kharitonov's exact test on the interval hull, roots left of `−decay`.
    Kharitonov,
    /// The family itself over `k`, roots left of `−decay` (least conservative).
    Family,
}

impl Constraints {
    /// All four, most conservative first.
    pub const ALL: [Constraints; 4] =
        [Constraints::PaperPrinted, Constraints::Lemmas, Constraints::Kharitonov, Constraints::Family];
}

/// Verdicts on one PI for the recycle family.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Verdict {
    /// Objective (18) against the ITAE nominal PI.
    pub cost: f64,
    /// All seven printed constraints `g_i ≤ 0`.
    pub printed_constraints_hold: bool,
    /// The printed interval (16) is an interval (lower ≤ upper at every coefficient).
    pub printed_interval_valid: bool,
    /// Lemma 2.1 on the printed interval (if valid).
    pub printed_lemma_21: Option<bool>,
    /// Lemma 2.2 on the printed interval (if valid).
    pub printed_lemma_22: Option<bool>,
    /// Lemma 2.1 (necessary) on the interval built from the loop.
    pub lemma_21: bool,
    /// Lemma 2.2 (sufficient) on the interval built from the loop.
    pub lemma_22: bool,
    /// Kharitonov's four polynomials Hurwitz (exact for the interval hull).
    pub kharitonov: bool,
    /// The family over k is Hurwitz (exact, Bialas).
    pub family_stable: bool,
    /// Worst closed-loop pole real part over the family (1/s).
    pub worst_pole_re: f64,
    /// The process gain where it occurs.
    pub worst_at_k: f64,
}

/// Check `pi` every way.
pub fn verdict(p: &RecycleProcess, pi: &Pi) -> Verdict {
    let printed = printed_interval(pi).ok();
    let built = p.interval(pi, 0.0);
    let (worst_pole_re, worst_at_k) = p.family_abscissa(pi);
    Verdict {
        cost: pi.cost(&p.itae()),
        printed_constraints_hold: printed_constraints(pi).iter().all(|&g| g <= 0.0),
        printed_interval_valid: printed.is_some(),
        printed_lemma_21: printed.as_ref().map(|i| i.nie_conditions(1.0).holds),
        printed_lemma_22: printed.as_ref().map(|i| i.nie_conditions(NIE_SUFFICIENT).holds),
        lemma_21: built.nie_conditions(1.0).holds,
        lemma_22: built.nie_conditions(NIE_SUFFICIENT).holds,
        kharitonov: built.is_robustly_hurwitz(),
        family_stable: p.family_is_stable(pi, 0.0),
        worst_pole_re,
        worst_at_k,
    }
}

/// A solution of the NLP (18).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct NlpSolution {
    /// Constraint set used.
    pub constraints: Constraints,
    /// Optimal gains.
    pub pi: Pi,
    /// Objective value.
    pub cost: f64,
    /// COBYLA's objective evaluations.
    pub evaluations: usize,
    /// The optimum checked every way (exact tests at decay 0).
    pub verdict: Verdict,
}

/// Constraint values `c_i(pi) ≥ 0` of a set (what the optimiser sees).
pub fn constraint_values(p: &RecycleProcess, which: Constraints, decay: f64, pi: &Pi) -> Vec<f64> {
    match which {
        Constraints::PaperPrinted => printed_constraints(pi).iter().map(|g| -g).collect(),
        Constraints::Lemmas => {
            let i = p.interval(pi, 0.0);
            let r = i.nie_conditions(NIE_SUFFICIENT);
            let mut v = vec![r.min_coefficient];
            v.extend(r.margins);
            v
        }
        Constraints::Kharitonov => vec![-p.interval(pi, decay).kharitonov_abscissa()],
        Constraints::Family => vec![-decay - p.family_abscissa(pi).0],
    }
}

/// Solve the NLP (18): the PI nearest to the ITAE nominal one that satisfies `which`, with
/// COBYLA (Powell's derivative-free constrained optimiser, `cobyla` crate) from the
/// nominal PI, gains boxed to ±20. Feasibility of the result is re-checked.
pub fn nearest_robust_pi(p: &RecycleProcess, which: Constraints, decay: f64) -> Result<NlpSolution, String> {
    let nominal = p.itae();
    let n_cons = constraint_values(p, which, decay, &nominal).len();
    let evaluations = std::cell::Cell::new(0usize);
    let at = |x: &[f64]| Pi { k1: x.first().copied().unwrap_or(0.0), k2: x.get(1).copied().unwrap_or(0.0) };
    let objective = |x: &[f64], _: &mut ()| {
        evaluations.set(evaluations.get() + 1);
        at(x).cost(&nominal)
    };
    // COBYLA asks for the constraints one by one at the same point: compute them once per point.
    let last: std::cell::RefCell<(Vec<f64>, Vec<f64>)> = std::cell::RefCell::default();
    let value = |x: &[f64], i: usize| {
        let mut cache = last.borrow_mut();
        if cache.0 != x {
            *cache = (x.to_vec(), constraint_values(p, which, decay, &at(x)));
        }
        cache.1.get(i).copied().unwrap_or(f64::NEG_INFINITY)
    };
    let cons: Vec<_> = (0..n_cons).map(|i| move |x: &[f64], _: &mut ()| value(x, i)).collect();
    let cons_dyn: Vec<&dyn cobyla::Func<()>> = cons.iter().map(|c| c as &dyn cobyla::Func<()>).collect();
    let stop = cobyla::StopTols { xtol_abs: vec![1e-10; 2], ftol_abs: 1e-14, ..cobyla::StopTols::default() };
    let (_, x, _) = cobyla::minimize(
        objective,
        &[nominal.k1, nominal.k2],
        &[(-20.0, 20.0), (-20.0, 20.0)],
        &cons_dyn,
        (),
        20_000,
        cobyla::RhoBeg::All(0.2),
        Some(stop),
    )
    .map_err(|(e, _, _)| format!("COBYLA failed ({which:?}): {e:?}"))?;
    let pi = at(&x);
    let worst = constraint_values(p, which, decay, &pi).iter().copied().fold(f64::INFINITY, f64::min);
    if worst < -1e-6 {
        return Err(format!("COBYLA ended infeasible ({which:?}): constraint value {worst:e} at {pi:?}"));
    }
    Ok(NlpSolution {
        constraints: which,
        pi,
        cost: pi.cost(&nominal),
        evaluations: evaluations.get(),
        verdict: verdict(p, &pi),
    })
}

/// One Table I row checked every way.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TableRow {
    /// Set number.
    pub set: u32,
    /// The paper's ε (undefined in its text).
    pub epsilon: f64,
    /// Gains.
    pub pi: Pi,
    /// Verdicts.
    pub verdict: Verdict,
}

/// Everything `design recycle` reports.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Report {
    /// The process.
    pub process: RecycleProcess,
    /// Decay margin imposed on the Kharitonov and family optima (1/s).
    pub decay_1_per_s: f64,
    /// ITAE nominal PI.
    pub itae: Pi,
    /// Unit 1 closed-loop poles at the nominal gain, `[re, im]`.
    pub itae_unit1_poles: Vec<[f64; 2]>,
    /// Unit 1 without the recycle stays stable over the gain range with the ITAE PI (exact).
    pub itae_unit1_robust: bool,
    /// With the recycle, the smallest process gain where the ITAE PI loses stability.
    pub itae_recycle_loss_of_stability_k: Option<f64>,
    /// Table I, each set checked every way.
    pub table_i: Vec<TableRow>,
    /// NLP (18) optima under each constraint set.
    pub optima: Vec<NlpSolution>,
}

/// Run the whole seed-001 study.
pub fn report(p: &RecycleProcess, decay: f64) -> Result<Report, String> {
    if !(decay.is_finite() && decay >= 0.0) {
        return Err(format!("decay must be a finite non-negative rate, got {decay}"));
    }
    let itae = p.itae();
    let mut poles: Vec<[f64; 2]> = p
        .unit1_characteristic(p.k_nominal, &itae)
        .roots()
        .ok_or("the ITAE loop's closed-loop poles did not converge")?
        .iter()
        .map(|z| [z.re, z.im])
        .collect();
    poles.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    let table_i = TABLE_I
        .iter()
        .map(|&(set, epsilon, k1, k2)| TableRow {
            set,
            epsilon,
            pi: Pi { k1, k2 },
            verdict: verdict(p, &Pi { k1, k2 }),
        })
        .collect();
    let optima =
        Constraints::ALL.iter().map(|&c| nearest_robust_pi(p, c, decay)).collect::<Result<_, _>>()?;
    Ok(Report {
        process: *p,
        decay_1_per_s: decay,
        itae,
        itae_unit1_poles: poles,
        itae_unit1_robust: p.unit1_family_is_stable(&itae),
        itae_recycle_loss_of_stability_k: p.loss_of_stability_k(&itae),
        table_i,
        optima,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> RecycleProcess {
        RecycleProcess::seed001()
    }

    #[test]
    fn validation() {
        assert!(RecycleProcess::new((1.0, 3.0), 2.0, 1.0, 1.6, 1.0).is_ok());
        assert!(RecycleProcess::new((3.0, 1.0), 2.0, 1.0, 1.6, 1.0).is_err());
        assert!(RecycleProcess::new((1.0, 3.0), 4.0, 1.0, 1.6, 1.0).is_err());
        assert!(RecycleProcess::new((1.0, 3.0), 2.0, 0.0, 1.6, 1.0).is_err());
        assert!(RecycleProcess::new((1.0, f64::NAN), 2.0, 1.0, 1.6, 1.0).is_err());
    }

    /// ITAE nominal gains and poles as printed: k₁⁰ = 0.9041, k₂⁰ = 0.7464, poles −0.8093 and
    /// −0.5954 ± 1.2207j, damping 0.438 (paper rounds to 4 digits).
    #[test]
    fn itae_nominal_design() {
        let pi = p().itae();
        assert!((pi.k1 - 0.9041).abs() < 5e-5 && (pi.k2 - 0.7464).abs() < 5e-5, "{pi:?}");
        let r = p().unit1_characteristic(2.0, &pi).roots().unwrap();
        let real = r.iter().find(|z| z.im.abs() < 1e-9).unwrap();
        let cplx = r.iter().find(|z| z.im > 0.0).unwrap();
        assert!((real.re + 0.8093).abs() < 5e-5, "{real}");
        assert!((cplx.re + 0.5954).abs() < 5e-5 && (cplx.im - 1.2207).abs() < 5e-5, "{cplx}");
        let zeta = -cplx.re / cplx.norm();
        assert!((zeta - 0.438).abs() < 5e-4, "{zeta}");
        // Unit 1 without the recycle stays stable over k ∈ [1, 3] (paper, Fig. 2).
        assert!(p().unit1_family_is_stable(&pi));
    }

    /// Δ built from the loop equals eq. (17) at k = 2 and the printed (16) at its ends.
    #[test]
    fn characteristic_matches_eqs_16_17() {
        let pi = Pi { k1: 2.2337, k2: 0.5 };
        let c = p().characteristic(2.0, &pi);
        let want = [1.0, 3.0, 3.0 + 2.0 * pi.k1, 2.0 * pi.k1 + 2.0 * pi.k2 - 2.2, 2.0 * pi.k2];
        for (a, b) in c.coeffs().iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{:?}", c.coeffs());
        }
        let built = p().interval(&pi, 0.0);
        let printed = printed_interval(&pi).unwrap();
        for (a, b) in built.lo().iter().chain(built.hi()).zip(printed.lo().iter().chain(printed.hi())) {
            assert!((a - b).abs() < 1e-12);
        }
        // Affine in k: the midpoint member is the average of the ends (so the hull is exact).
        let (a, b, m) =
            (p().characteristic(1.0, &pi), p().characteristic(3.0, &pi), p().characteristic(2.0, &pi));
        let avg = a.add(&b).scale(0.5);
        assert!(avg.coeffs().iter().zip(m.coeffs()).all(|(x, y)| (x - y).abs() < 1e-12));
    }

    /// The printed constraints are lemma conditions on the printed interval (16):
    /// g₁ = −(x₁x₂ − y₀y₃), g₂ = −(x₂x₃ − y₁y₄), g₃ ≈ −(0.4655x₁x₂ − y₀y₃)/0.4655,
    /// g₄ = −(0.4655x₂x₃ − y₁y₄), g₅ = −x₁, g₆ = −x₂, g₇ = −y₁ (where y₁ ≥ x₁ was meant).
    #[test]
    fn printed_constraints_are_the_lemmas_on_interval_16() {
        for (k1, k2) in [(2.2337, 0.5), (1.0, 0.9), (3.0, 0.2), (0.8, 1.4)] {
            let pi = Pi { k1, k2 };
            let g = printed_constraints(&pi);
            let (x1, x2, x3) = (k1 + k2 - 0.6, k1 + 3.0, 3.0);
            let (y0, y1, y3, y4) = (3.0 * k2, 3.0 * k1 + 3.0 * k2 - 3.8, 3.0, 1.0);
            assert!((g[0] + (x1 * x2 - y0 * y3)).abs() < 1e-12);
            assert!((g[1] + (x2 * x3 - y1 * y4)).abs() < 1e-12);
            assert!((g[2] + (0.4655 * x1 * x2 - y0 * y3) / 0.4655).abs() < 1e-4 * (1.0 + g[2].abs()));
            assert!((g[3] + (0.4655 * x2 * x3 - y1 * y4)).abs() < 1e-12);
            assert!((g[4] + x1).abs() < 1e-12 && (g[5] + x2).abs() < 1e-12 && (g[6] + y1).abs() < 1e-12);
        }
    }

    /// The family's worst pole by sweep + golden section equals the maximum over a
    /// 20 001-point grid of k (to the grid's resolution) and is never below it, for the
    /// ITAE design and two others.
    #[test]
    fn family_abscissa_is_the_dense_grid_maximum() {
        for pi in [p().itae(), Pi { k1: 2.2337, k2: 0.5 }, Pi { k1: 0.8, k2: 1.4 }] {
            let (worst, at_k) = p().family_abscissa(&pi);
            let (lo, hi) = (p().k_lo, p().k_hi);
            let grid = (0..=20_000)
                .map(|i| p().characteristic(lo + (hi - lo) * f64::from(i) / 20_000.0, &pi).max_real_root())
                .fold(f64::NEG_INFINITY, f64::max);
            assert!(worst >= grid - 1e-12 && worst - grid < 1e-6, "{pi:?}: {worst} vs grid {grid}");
            assert!((p().characteristic(at_k, &pi).max_real_root() - worst).abs() < 1e-12);
        }
    }

    /// The nominal ITAE PI loses stability inside k ∈ [1, 3] (paper: stable at 1, unstable
    /// at 3): at k ≈ 2.4029, where a pole pair crosses the imaginary axis.
    #[test]
    fn nominal_pi_loses_stability_at_k_2_403() {
        let pi = p().itae();
        let k = p().loss_of_stability_k(&pi).unwrap();
        assert!((k - 2.4029).abs() < 1e-3, "{k}");
        assert!(p().characteristic(k, &pi).max_real_root().abs() < 1e-6);
        assert!(p().characteristic(1.0, &pi).is_hurwitz_routh());
        assert!(!p().characteristic(3.0, &pi).is_hurwitz_routh());
        // The exact segment test agrees on either side.
        let below = RecycleProcess::new((1.0, k - 1e-3), 2.0, 1.0, 1.6, 1.0).unwrap();
        let above = RecycleProcess::new((1.0, k + 1e-3), 2.0, 1.0, 1.6, 1.0).unwrap();
        assert!(below.family_is_stable(&pi, 0.0) && !above.family_is_stable(&pi, 0.0));
    }

    /// Table I checked both ways: all five sets are robustly stable (Kharitonov and the
    /// exact family test). Set 1 has k₁ + k₂ < 1.6, where the printed interval (16) turns
    /// inside out — the printed lemma conditions cannot even be evaluated there.
    #[test]
    fn table_i_sets() {
        for (set, _eps, k1, k2) in TABLE_I {
            let v = verdict(&p(), &Pi { k1, k2 });
            assert!(v.kharitonov && v.family_stable && v.worst_pole_re < 0.0, "set {set}: {v:?}");
            assert!(v.lemma_21, "set {set}");
            assert_eq!(v.printed_interval_valid, set != 1, "set {set}");
        }
    }

    /// The printed NLP's optimum violates robust stability; the exact constraint sets give
    /// verified-robust optima, each less conservative (closer to nominal) than the last.
    #[test]
    fn nlp_optima() {
        let decay = 0.01;
        let sols: Vec<NlpSolution> =
            Constraints::ALL.iter().map(|&c| nearest_robust_pi(&p(), c, decay).unwrap()).collect();
        let printed = &sols[0];
        assert!(
            (printed.pi.k1 - 1.1244).abs() < 1e-3 && (printed.pi.k2 - 0.1422).abs() < 1e-3,
            "{printed:?}"
        );
        assert!(!printed.verdict.family_stable && printed.verdict.worst_pole_re > 0.0);
        for s in &sols[1..] {
            assert!(s.verdict.kharitonov || s.constraints == Constraints::Family, "{s:?}");
            assert!(s.verdict.family_stable && s.verdict.worst_pole_re < 0.0, "{s:?}");
        }
        assert!(sols[1].cost > sols[2].cost && sols[2].cost > sols[3].cost, "{sols:?}");
        // The decay margin is met to the optimiser's tolerance and is active at the optimum.
        assert!((sols[3].verdict.worst_pole_re + decay).abs() < 1e-5, "{:?}", sols[3]);
    }

    /// Brute force: on a 201×201 grid no feasible point beats COBYLA's optimum by more than
    /// the grid's resolution allows, for the exact family constraint.
    #[test]
    fn family_optimum_against_a_grid() {
        let decay = 0.01;
        let sol = nearest_robust_pi(&p(), Constraints::Family, decay).unwrap();
        let nominal = p().itae();
        let mut best = f64::INFINITY;
        // Window around the nominal gains; the optimum lies within 0.2 of it.
        for i in 0..=200 {
            for j in 0..=200 {
                let pi = Pi {
                    k1: nominal.k1 - 0.2 + 0.4 * f64::from(i) / 200.0,
                    k2: nominal.k2 - 0.2 + 0.4 * f64::from(j) / 200.0,
                };
                if pi.cost(&nominal) < best && p().family_is_stable(&pi, decay) {
                    best = pi.cost(&nominal);
                }
            }
        }
        // Grid step 0.002: distance error ≤ 0.0015, cost error ≤ 2·√cost·0.0015 + 0.0015².
        let tol = 2.0 * sol.cost.sqrt() * 0.0015 + 0.0015 * 0.0015;
        assert!(sol.cost <= best + 1e-9 && best <= sol.cost + tol, "cobyla {} grid {best}", sol.cost);
    }
}
