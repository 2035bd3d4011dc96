//! Eigenvalues that always return: every stability check of the toolkit asks them.
//!
//! nalgebra's `complex_eigenvalues` runs the shifted QR iterations of the real Schur form
//! without a limit; on a badly scaled closed-loop matrix (a 7.3 kW motor's current loops:
//! inductances of 10⁻³ H beside integral gains of 10⁵ V/(A·s)) it never converged and
//! `design tune` hung (found by the motor population, issue 49). Here the matrix is first
//! balanced (Parlett–Reinsch: a diagonal similarity, the eigenvalues unchanged, the rows' and
//! columns' norms made comparable) and the iterations are capped; a matrix that still does
//! not converge has no answer (`None`), which each check reads as "not proven stable".

use nalgebra::DMatrix;
use nalgebra::linalg::Schur;
use nalgebra::linalg::balancing::balance_parlett_reinsch;
use num_complex::Complex64;

/// QR iterations allowed per eigenvalue (LAPACK's `dhseqr` allows 30; the unbalanced first
/// attempt gets as many before the balanced one).
pub const ITERATIONS_PER_EIGENVALUE: usize = 30;

/// The eigenvalues of the square matrix `m`, or `None` if a non-finite entry or the QR
/// iterations' failure to converge (balanced and unbalanced) leaves them unknown.
pub fn eigenvalues(m: &DMatrix<f64>) -> Option<Vec<Complex64>> {
    if !m.is_square() || !m.iter().all(|x| x.is_finite()) {
        return None;
    }
    let cap = ITERATIONS_PER_EIGENVALUE * m.nrows().max(1);
    let schur = Schur::try_new(m.clone(), f64::EPSILON, cap).or_else(|| {
        let mut b = m.clone();
        balance_parlett_reinsch(&mut b);
        Schur::try_new(b, f64::EPSILON, cap)
    })?;
    Some(schur.complex_eigenvalues().iter().copied().collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    /// The closed loop `design tune` hung on (member 002 of the population of seed 1, a 7.3 kW
    /// 400 V 4-pole motor, stationary-frame PI current loops at ω_r = 30 rad/s; column-major):
    /// the unbalanced QR iterations do not converge within their cap (unbounded, they never
    /// did), the balanced ones do, and every eigenvalue found makes `A − λI` singular.
    #[test]
    fn a_matrix_the_unbounded_iterations_hung_on_has_its_eigenvalues() {
        #[rustfmt::skip]
        let m = DMatrix::from_column_slice(6, 6, &[
            -421.8021357730961, 0.0, 1.0258103111093388, 0.0, -1.0, 0.0,
            0.0, -421.8021357730961, 0.0, 1.0258103111093388, 0.0, -1.0,
            628.0518288631185, -3411.1774295127643, -5.523475472979073, 30.0, 0.0, 0.0,
            3411.1774295127643, 628.0518288631185, -30.0, -5.523475472979073, 0.0, 0.0,
            38267.45248042547, 0.0, 0.0, 0.0, -0.0, 0.0,
            0.0, 38267.45248042547, 0.0, 0.0, 0.0, -0.0,
        ]);
        let cap = ITERATIONS_PER_EIGENVALUE * 6;
        assert!(
            Schur::try_new(m.clone(), f64::EPSILON, cap).is_none(),
            "the unbalanced iterations converge now"
        );
        let e = eigenvalues(&m).expect("balanced, they converge");
        assert_eq!(e.len(), 6);
        let scale = m.norm();
        for l in e {
            let shifted = m.map(|x| num_complex::Complex64::new(x, 0.0))
                - DMatrix::<num_complex::Complex64>::identity(6, 6) * l;
            let smallest = shifted.singular_values().iter().copied().fold(f64::INFINITY, f64::min);
            assert!(smallest < 1e-9 * scale, "λ = {l}: σ_min(A − λI) = {smallest:e} of ‖A‖ = {scale:e}");
        }
    }

    /// Unknown, not a guess: a non-finite matrix has no eigenvalues.
    #[test]
    fn a_non_finite_matrix_has_none() {
        let m = DMatrix::from_element(2, 2, f64::NAN);
        assert!(eigenvalues(&m).is_none());
    }
}
