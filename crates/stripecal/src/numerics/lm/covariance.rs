//! The parameters' covariance at the solution, with rank-deficiency (unobservable
//! parameter) detection.

use nalgebra::DMatrix;

use super::schur::{self, Blocks};

/// Covariance `sigma2 * jtj^-1` with rank-deficiency detection (module docs): returns
/// the covariance (NaN rows / columns for unobservable parameters) and their indices.
pub fn covariance(jtj: &DMatrix<f64>, sigma2: f64, rank_tol: f64) -> (DMatrix<f64>, Vec<usize>) {
    covariance_by_blocks(jtj, sigma2, rank_tol, None)
}

/// [`covariance`] of a normal matrix laid out as `blocks` (no entries between two
/// views' per-view columns): the full-rank inverse by the Schur complement
/// ([`schur::inverse`]: linear in the views but for the output's size; the same numbers
/// to rounding), the rank-deficient case as [`covariance`].
pub(super) fn covariance_by_blocks(
    jtj: &DMatrix<f64>,
    sigma2: f64,
    rank_tol: f64,
    blocks: Option<&Blocks>,
) -> (DMatrix<f64>, Vec<usize>) {
    let n = jtj.nrows();
    let d: Vec<f64> = (0..n).map(|i| jtj[(i, i)].max(0.0).sqrt()).collect();
    let mut bad = vec![false; n];
    for i in 0..n {
        if d[i].is_nan() || d[i] <= 0.0 || !d[i].is_finite() {
            bad[i] = true;
        }
    }
    let good: Vec<usize> = (0..n).filter(|&i| !bad[i]).collect();
    let scaled_at = |a: usize, b: usize| jtj[(good[a], good[b])] / (d[good[a]] * d[good[b]]);
    // Cheap certificate of full rank: for the unit-diagonal `S`, `lambda_max <= trace =
    // k` and `lambda_min >= 1 / trace(S^-1)`; when `k trace(S^-1) rank_tol <= 1` no
    // eigenvalue is below `rank_tol lambda_max` and the eigen-decomposition is skipped.
    // (`S` is read in place by the blocks' inverse: a whole matrix fewer of the views'
    // squared size.)
    let certified: Option<DMatrix<f64>> = if good.len() == n {
        match blocks {
            Some(b) => schur::inverse(scaled_at, b),
            None => spd_inverse(&DMatrix::from_fn(n, n, scaled_at)),
        }
        .filter(|inv| {
            let tr: f64 = (0..n).map(|i| inv[(i, i)]).sum();
            tr.is_finite() && n as f64 * tr * rank_tol <= 1.0
        })
    } else {
        None
    };
    if let Some(mut cov) = certified {
        for b in 0..n {
            for a in 0..n {
                cov[(a, b)] = sigma2 * cov[(a, b)] / (d[a] * d[b]);
            }
        }
        return (cov, Vec::new());
    }
    let scaled = DMatrix::from_fn(good.len(), good.len(), scaled_at);
    if !good.is_empty() {
        let eig = scaled.symmetric_eigen();
        let emax = eig.eigenvalues.iter().cloned().fold(0.0f64, f64::max);
        for (k, &ev) in eig.eigenvalues.iter().enumerate() {
            if ev <= rank_tol * emax {
                for a in 0..good.len() {
                    if eig.eigenvectors[(a, k)].abs() > 0.1 {
                        bad[good[a]] = true;
                    }
                }
            }
        }
    }
    let good: Vec<usize> = (0..n).filter(|&i| !bad[i]).collect();
    let mut cov = DMatrix::from_element(n, n, f64::NAN);
    if !good.is_empty() {
        let sub = DMatrix::from_fn(good.len(), good.len(), |a, b| {
            jtj[(good[a], good[b])] / (d[good[a]] * d[good[b]])
        });
        if let Some(inv) = spd_inverse(&sub) {
            for a in 0..good.len() {
                for b in 0..good.len() {
                    cov[(good[a], good[b])] = sigma2 * inv[(a, b)] / (d[good[a]] * d[good[b]]);
                }
            }
        } else {
            // numerically not positive definite: everything is suspect
            return (cov, (0..n).collect());
        }
    }
    let unobs = (0..n).filter(|&i| bad[i]).collect();
    (cov, unobs)
}

/// The inverse of a symmetric positive definite matrix (Cholesky, faer); `None` when it
/// is not positive definite.
fn spd_inverse(a: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    use faer::linalg::solvers::DenseSolveCore;
    let n = a.nrows();
    let m = faer::Mat::<f64>::from_fn(n, n, |i, j| a[(i, j)]);
    let inv = m.llt(faer::Side::Lower).ok()?.inverse();
    Some(DMatrix::from_fn(n, n, |i, j| inv[(i, j)]))
}

/// The standard deviations on `cov`'s diagonal (NaN where a variance is not finite).
pub fn sigmas(cov: &DMatrix<f64>) -> Vec<f64> {
    (0..cov.nrows())
        .map(|i| {
            let v = cov[(i, i)];
            if v.is_finite() {
                v.max(0.0).sqrt()
            } else {
                f64::NAN
            }
        })
        .collect()
}
