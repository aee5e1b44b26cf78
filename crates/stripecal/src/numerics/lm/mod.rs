//! A dense Levenberg-Marquardt solver for small parameter vectors (n up to a few
//! hundred) and many residuals (m up to ~1e5).
//!
//! ## Use
//!
//! Implement [`LeastSquares`] (residuals; residuals + Jacobian written into a reused
//! `m x n` faer matrix, or by rows when each residual depends on a few parameters
//! ([`LeastSquares::jacobian_row_width`], [`JacobianRows`]); optionally a manifold update
//! [`LeastSquares::retract`] and a re-weighting [`LeastSquares::reweight`]) and call
//! [`levenberg_marquardt`]. The Jacobian storage is allocated once; `J^T J` is formed by
//! faer's matrix product (dense matrix or dense rows) or by per-row outer products summed
//! over runs of rows with the same columns (sparse rows), or by the problem itself
//! ([`LeastSquares::has_normal_equations`]: no Jacobian stored, for many residuals over
//! few parameters, without Huber weights or re-weighting); the damped `n x n` system is
//! solved by Cholesky, or, when the problem's columns are global ones and one block per
//! view ([`LeastSquares::view_blocks`]), by eliminating the views' blocks one by one (the
//! Schur complement: a small Cholesky per view and one over the global columns, linear
//! in the number of views; the leverages take the inverse's blocks the same way).
//!
//! ## Algorithm
//!
//! Step: `(J^T W J + lambda D^2) dp = -J^T W r`, with `D^2` the running maximum of
//! `diag(J^T W J)` (More's scaling) or, if given, the user's `scaling^-2`. `W` are the
//! Huber IRLS weights (`1` inside the threshold, `delta / |r|` outside) when
//! [`LmOptions::huber`] is set; the cost is then the Huber cost. A step is accepted if
//! it lowers the cost. Lambda follows the gain ratio `rho` (actual over predicted
//! decrease): divided by 100 when `rho > 0.9`, by 10 above 0.75, by 3 above 0.25,
//! doubled below; after a rejected step it grows by 4, 8, 16, ... (Nielsen). Near the
//! solution of a mildly non-linear problem the steps are then Gauss-Newton steps and
//! the convergence is quadratic rather than held back by the damping in the weakly
//! determined directions.
//!
//! Stopping ([`StopReason`]): before a trial, the decrease predicted by the quadratic
//! model below `ftol * cost` (MINPACK's test; `CostConverged`) or below the cost's own
//! round-off `10 m eps cost` (`NoDecrease`); after an accepted step, relative decrease
//! below `ftol` or step `|D dp| <= xtol (|D p| + xtol)`; gradient `max |g_i| /
//! sqrt(diag_i)` below `gtol * sqrt(2 cost)`; zero cost; lambda overflow; iteration
//! limit. While a re-weighting still moves the weights the cost, step and gradient
//! tests wait.
//!
//! ## Covariance
//!
//! At the solution `cov = sigma^2 (J^T W J)^-1`, `sigma^2 = SSR / (m - n)`. Parameters
//! are first Jacobi-scaled (`J^T J` to unit diagonal); eigenvalues of the scaled matrix
//! below `rank_tol * max` span the unobservable directions, and every parameter with a
//! component above 0.1 in one of them is reported in [`LmResult::unobservable`] with a
//! NaN sigma; the others' covariance is the inverse of their sub-matrix (the
//! unobservable ones held fixed). The eigen-decomposition is skipped when the bound
//! `lambda_min >= 1 / trace(S^-1)` already certifies full rank (`n trace(S^-1)
//! rank_tol <= 1` for the unit-diagonal `S`).

mod covariance;
mod normal;
mod problem;
mod schur;
mod solver;

pub use covariance::{covariance, sigmas};
pub use problem::{dense_jacobian_from_rows, JacobianRows, LeastSquares, Leverages};
pub use solver::{levenberg_marquardt, LmOptions, LmResult, StopReason};

#[cfg(test)]
use faer::Mat;

/// Test support: asserts that `residuals_and_jacobian` at `p` returns the residuals of
/// `residuals` (to `rtol` absolute) and a Jacobian equal to central differences taken
/// through [`LeastSquares::retract`] with step `step(j)` per column: the largest
/// difference in a column at most `tol * max(largest |entry|, 1)`. Returns the largest
/// of those relative differences over the columns.
#[cfg(test)]
pub(crate) fn assert_jacobian_matches_fd<P: LeastSquares>(
    pr: &P,
    p: &[f64],
    step: impl Fn(usize) -> f64,
    rtol: f64,
    tol: f64,
    what: &str,
) -> f64 {
    let (m, n) = (pr.num_residuals(), pr.num_params());
    let mut r = vec![0.0; m];
    let mut jac = Mat::<f64>::zeros(m, n);
    pr.residuals_and_jacobian(p, &mut r, jac.as_mut()).unwrap();
    let mut r2 = vec![0.0; m];
    pr.residuals(p, &mut r2).unwrap();
    assert!(
        r.iter().zip(&r2).all(|(a, b)| (a - b).abs() < rtol),
        "{what}: residuals differ"
    );
    let mut worst = 0.0f64;
    for j in 0..n {
        let h = step(j);
        let mut dp = vec![0.0; n];
        let (mut pa, mut pb) = (vec![0.0; n], vec![0.0; n]);
        dp[j] = h;
        pr.retract(p, &dp, &mut pa);
        dp[j] = -h;
        pr.retract(p, &dp, &mut pb);
        let (mut ra, mut rb) = (vec![0.0; m], vec![0.0; m]);
        pr.residuals(&pa, &mut ra).unwrap();
        pr.residuals(&pb, &mut rb).unwrap();
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for i in 0..m {
            let fd = (ra[i] - rb[i]) / (2.0 * h);
            num = num.max((fd - jac[(i, j)]).abs());
            den = den.max(jac[(i, j)].abs());
        }
        assert!(
            num <= tol * den.max(1.0),
            "{what} column {j}: {num:e} of {den:e}"
        );
        worst = worst.max(num / den.max(1.0));
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Result;
    use faer::MatMut;
    use std::sync::atomic::{AtomicU64, Ordering};

    /// Fit y = a exp(b x) + c.
    struct Expo {
        x: Vec<f64>,
        y: Vec<f64>,
        /// add a duplicated parameter (unobservable combination) when true
        dup: bool,
    }

    impl LeastSquares for Expo {
        fn num_params(&self) -> usize {
            if self.dup {
                4
            } else {
                3
            }
        }
        fn num_residuals(&self) -> usize {
            self.x.len()
        }
        fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
            let c = if self.dup { p[2] + p[3] } else { p[2] };
            for ((ri, x), y) in r.iter_mut().zip(&self.x).zip(&self.y) {
                *ri = p[0] * (p[1] * x).exp() + c - y;
            }
            Ok(())
        }
        fn residuals_and_jacobian(
            &self,
            p: &[f64],
            r: &mut [f64],
            mut jac: MatMut<'_, f64>,
        ) -> Result<()> {
            self.residuals(p, r)?;
            for i in 0..self.x.len() {
                let e = (p[1] * self.x[i]).exp();
                jac[(i, 0)] = e;
                jac[(i, 1)] = p[0] * self.x[i] * e;
                jac[(i, 2)] = 1.0;
                if self.dup {
                    jac[(i, 3)] = 1.0;
                }
            }
            Ok(())
        }
    }

    fn data(noise: bool) -> (Vec<f64>, Vec<f64>) {
        let x: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let y = x
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                2.0 * (-0.7 * x).exp()
                    + 0.5
                    + if noise {
                        0.01 * ((i * 7919) % 13) as f64 / 13.0 - 0.005
                    } else {
                        0.0
                    }
            })
            .collect();
        (x, y)
    }

    #[test]
    fn exact_fit_and_covariance() {
        let (x, y) = data(false);
        let pr = Expo { x, y, dup: false };
        let res = levenberg_marquardt(&pr, &[1.0, -0.1, 0.0], &LmOptions::default()).unwrap();
        assert!((res.params[0] - 2.0).abs() < 1e-10, "{:?}", res);
        assert!((res.params[1] + 0.7).abs() < 1e-10);
        assert!((res.params[2] - 0.5).abs() < 1e-10);
        assert!(res.unobservable.is_empty());

        let (x, y) = data(true);
        let pr = Expo { x, y, dup: false };
        let res = levenberg_marquardt(&pr, &[1.0, -0.1, 0.0], &LmOptions::default()).unwrap();
        assert!(res.sigma.iter().all(|s| s.is_finite() && *s > 0.0));
        assert!((res.params[0] - 2.0).abs() < 5.0 * res.sigma[0] + 1e-3);
    }

    #[test]
    fn rank_deficiency_is_reported() {
        let (x, y) = data(true);
        let pr = Expo { x, y, dup: true };
        let res = levenberg_marquardt(&pr, &[1.0, -0.1, 0.0, 0.0], &LmOptions::default()).unwrap();
        assert_eq!(res.unobservable, vec![2, 3]);
        assert!(res.sigma[2].is_nan() && res.sigma[3].is_nan());
        assert!(res.sigma[0].is_finite());
        assert!((res.params[2] + res.params[3] - 0.5).abs() < 0.01);
    }

    #[test]
    fn huber_resists_an_outlier() {
        let (x, mut y) = data(false);
        y[10] += 5.0;
        let pr = Expo { x, y, dup: false };
        let opts = LmOptions {
            huber: Some(0.01),
            max_iterations: 300,
            ..Default::default()
        };
        let res = levenberg_marquardt(&pr, &[1.0, -0.1, 0.0], &opts).unwrap();
        assert!((res.params[0] - 2.0).abs() < 1e-3, "{:?}", res.params);
        let plain = levenberg_marquardt(&pr, &[1.0, -0.1, 0.0], &LmOptions::default()).unwrap();
        assert!((plain.params[0] - 2.0).abs() > (res.params[0] - 2.0).abs());
    }

    #[test]
    fn bad_input() {
        let (x, y) = data(false);
        let pr = Expo { x, y, dup: false };
        assert!(levenberg_marquardt(&pr, &[1.0, 0.0], &LmOptions::default()).is_err());
        assert!(levenberg_marquardt(&pr, &[f64::NAN, 0.0, 0.0], &LmOptions::default()).is_err());
    }

    /// [`Expo`] with its Jacobian by rows: `width` 3 (dense rows) or 5 (sparse rows,
    /// columns shuffled, one column split into two entries, one unused pair).
    struct ExpoRows {
        inner: Expo,
        width: usize,
        /// Variance components on two halves of the residuals.
        reweighting: bool,
        weights: [AtomicU64; 2],
    }

    impl LeastSquares for ExpoRows {
        fn num_params(&self) -> usize {
            3
        }
        fn num_residuals(&self) -> usize {
            self.inner.x.len()
        }
        fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
            self.inner.residuals(p, r)?;
            let h = r.len() / 2;
            for (i, x) in r.iter_mut().enumerate() {
                *x *= f64::from_bits(self.weights[usize::from(i >= h)].load(Ordering::Relaxed));
            }
            Ok(())
        }
        fn residuals_and_jacobian(
            &self,
            p: &[f64],
            r: &mut [f64],
            jac: MatMut<'_, f64>,
        ) -> Result<()> {
            dense_jacobian_from_rows(self, p, r, jac)
        }
        fn jacobian_row_width(&self) -> Option<usize> {
            Some(self.width)
        }
        fn residuals_and_jacobian_rows(
            &self,
            p: &[f64],
            r: &mut [f64],
            rows: &mut JacobianRows,
        ) -> Result<()> {
            self.residuals(p, r)?;
            let h = r.len() / 2;
            let w = rows.width();
            let (cols, vals) = rows.parts_mut();
            for (i, x) in self.inner.x.iter().enumerate() {
                let s = f64::from_bits(self.weights[usize::from(i >= h)].load(Ordering::Relaxed));
                let e = (p[1] * x).exp();
                let d = [s * e, s * p[0] * x * e, s];
                let v = &mut vals[i * w..(i + 1) * w];
                if w == 3 {
                    v.copy_from_slice(&d);
                } else {
                    let c = &mut cols[i * w..(i + 1) * w];
                    c.copy_from_slice(&[2, 0, 1, 0, 1]);
                    v.copy_from_slice(&[d[2], 0.25 * d[0], d[1], 0.75 * d[0], 0.0]);
                }
            }
            Ok(())
        }
        fn reweight(&self, r: &[f64], leverages: &mut Leverages<'_>) -> Option<Vec<f64>> {
            if !self.reweighting {
                return None;
            }
            // The leverages add up to n (3) in every storage.
            let h = leverages(std::slice::from_ref(&(0..r.len()))).expect("leverages");
            assert!(
                (h.iter().sum::<f64>() - 3.0).abs() < 1e-9,
                "{}",
                h.iter().sum::<f64>()
            );
            assert!(h.iter().all(|x| (0.0..=1.0 + 1e-12).contains(x)));
            let h = r.len() / 2;
            let mut f = vec![1.0; r.len()];
            for (g, part) in [&r[..h], &r[h..]].into_iter().enumerate() {
                let w0 = f64::from_bits(self.weights[g].load(Ordering::Relaxed));
                let rms =
                    (part.iter().map(|x| (x / w0).powi(2)).sum::<f64>() / part.len() as f64).sqrt();
                let w1 = 1.0 / rms.max(1e-12);
                self.weights[g].store(w1.to_bits(), Ordering::Relaxed);
                let off = g * h;
                f[off..off + part.len()]
                    .iter_mut()
                    .for_each(|x| *x = w1 / w0);
            }
            Some(f)
        }
    }

    #[test]
    fn jacobian_by_rows_dense_or_sparse_solves_like_the_dense_matrix() {
        let (x, y) = data(true);
        let one = || {
            [
                AtomicU64::new(1f64.to_bits()),
                AtomicU64::new(1f64.to_bits()),
            ]
        };
        for huber in [None, Some(0.003)] {
            let opts = LmOptions {
                huber,
                ..Default::default()
            };
            let dense = Expo {
                x: x.clone(),
                y: y.clone(),
                dup: false,
            };
            let a = levenberg_marquardt(&dense, &[1.0, -0.1, 0.0], &opts).unwrap();
            for width in [3, 5] {
                let pr = ExpoRows {
                    inner: Expo {
                        x: x.clone(),
                        y: y.clone(),
                        dup: false,
                    },
                    width,
                    reweighting: false,
                    weights: one(),
                };
                crate::numerics::lm::assert_jacobian_matches_fd(
                    &pr,
                    &a.params,
                    |_| 1e-6,
                    1e-14,
                    1e-6,
                    "rows",
                );
                let b = levenberg_marquardt(&pr, &[1.0, -0.1, 0.0], &opts).unwrap();
                for k in 0..3 {
                    assert!(
                        (a.params[k] - b.params[k]).abs() < 1e-9,
                        "{width} {huber:?}: {:?} {:?}",
                        a.params,
                        b.params
                    );
                    assert!((a.sigma[k] - b.sigma[k]).abs() < 1e-9 * a.sigma[k].max(1e-9) + 1e-12);
                }
            }
        }
    }

    /// [`Expo`] forming its own normal equations (and no Jacobian rows).
    struct ExpoNormals(Expo);

    impl LeastSquares for ExpoNormals {
        fn num_params(&self) -> usize {
            self.0.num_params()
        }
        fn num_residuals(&self) -> usize {
            self.0.num_residuals()
        }
        fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
            self.0.residuals(p, r)
        }
        fn residuals_and_jacobian(
            &self,
            p: &[f64],
            r: &mut [f64],
            jac: MatMut<'_, f64>,
        ) -> Result<()> {
            self.0.residuals_and_jacobian(p, r, jac)
        }
        fn has_normal_equations(&self) -> bool {
            true
        }
        fn residuals_and_normal_equations(
            &self,
            p: &[f64],
            r: &mut [f64],
        ) -> Result<(nalgebra::DMatrix<f64>, nalgebra::DVector<f64>)> {
            let (m, n) = (self.num_residuals(), self.num_params());
            let mut jac = faer::Mat::<f64>::zeros(m, n);
            self.0.residuals_and_jacobian(p, r, jac.as_mut())?;
            let j = nalgebra::DMatrix::from_fn(m, n, |i, k| jac[(i, k)]);
            let rv = nalgebra::DVector::from_column_slice(r);
            Ok((j.transpose() * &j, j.transpose() * rv))
        }
    }

    /// A problem that forms its own normal equations solves as the Jacobian does (the
    /// same parameters and sigmas); with a Huber threshold the solver uses its Jacobian.
    #[test]
    fn own_normal_equations_solve_like_the_jacobian() {
        let (x, y) = data(true);
        for huber in [None, Some(0.003)] {
            let opts = LmOptions {
                huber,
                ..Default::default()
            };
            let expo = || Expo {
                x: x.clone(),
                y: y.clone(),
                dup: false,
            };
            let a = levenberg_marquardt(&expo(), &[1.0, -0.1, 0.0], &opts).unwrap();
            let b = levenberg_marquardt(&ExpoNormals(expo()), &[1.0, -0.1, 0.0], &opts).unwrap();
            assert_eq!(a.iterations, b.iterations, "{huber:?}");
            for k in 0..3 {
                assert!((a.params[k] - b.params[k]).abs() < 1e-10, "{huber:?}");
                assert!((a.sigma[k] - b.sigma[k]).abs() < 1e-9 * a.sigma[k]);
            }
        }
    }

    /// The leverages of every Jacobian storage (dense matrix, dense rows, sparse rows
    /// with a split column) equal the hat matrix's diagonal `w_i j_i^T (J^T W J)^-1 j_i`
    /// written out, with and without Huber weights.
    #[test]
    fn leverages_are_the_hat_matrix_diagonal() {
        let (x, y) = data(true);
        let p = [1.9, -0.68, 0.51];
        let expo = || Expo {
            x: x.clone(),
            y: y.clone(),
            dup: false,
        };
        let m = x.len();
        for huber in [None, Some(0.02)] {
            let plain = expo();
            let mut r = vec![0.0; m];
            let mut jac = Mat::<f64>::zeros(m, 3);
            plain
                .residuals_and_jacobian(&p, &mut r, jac.as_mut())
                .unwrap();
            let w: Vec<f64> = r.iter().map(|&x| normal::huber_weight(x, huber)).collect();
            let jm = nalgebra::DMatrix::from_fn(m, 3, |i, j| jac[(i, j)]);
            let wm = nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_vec(w.clone()));
            let inv = (jm.transpose() * &wm * &jm).try_inverse().unwrap();
            let expect: Vec<f64> = (0..m)
                .map(|i| w[i] * (jm.row(i) * &inv * jm.row(i).transpose())[(0, 0)])
                .collect();
            let check = |h: Vec<f64>, what: &str| {
                for (a, b) in h.iter().zip(&expect) {
                    assert!((a - b).abs() < 1e-10, "{what} {huber:?}: {a} vs {b}");
                }
            };
            let mut work = normal::Work::new(m, 3, None);
            work.evaluate(&plain, &p, &mut r).unwrap();
            check(
                work.leverages(&r, huber, std::slice::from_ref(&(0..m)))
                    .unwrap(),
                "dense matrix",
            );
            // Some rows only: the others 0.
            let part = work.leverages(&r, huber, &[3..9, 20..m + 5]).unwrap();
            for (i, (a, b)) in part.iter().zip(&expect).enumerate() {
                let inside = (3..9).contains(&i) || i >= 20;
                assert!((a - if inside { *b } else { 0.0 }).abs() < 1e-10, "{i}");
            }
            for width in [3, 5] {
                let pr = ExpoRows {
                    inner: expo(),
                    width,
                    reweighting: false,
                    weights: [
                        AtomicU64::new(1f64.to_bits()),
                        AtomicU64::new(1f64.to_bits()),
                    ],
                };
                let mut work = normal::Work::new(m, 3, Some(width));
                work.evaluate(&pr, &p, &mut r).unwrap();
                check(
                    work.leverages(&r, huber, std::slice::from_ref(&(0..m)))
                        .unwrap(),
                    "rows",
                );
                let part = work
                    .leverages(&r, huber, std::slice::from_ref(&(5..30)))
                    .unwrap();
                for (i, (a, b)) in part.iter().zip(&expect).enumerate() {
                    let inside = (5..30).contains(&i);
                    assert!((a - if inside { *b } else { 0.0 }).abs() < 1e-10, "{i}");
                }
            }
        }
    }

    #[test]
    fn reweighting_settles_and_normalises_the_cost() {
        // Noise on the second half ten times larger: the weights settle at the halves'
        // RMS, the cost at about m / 2 (unit-variance weighted residuals).
        let (x, mut y) = data(true);
        let h = y.len() / 2;
        for (i, v) in y.iter_mut().enumerate().skip(h) {
            *v += 0.05 * (((i * 7919) % 13) as f64 / 13.0 - 0.5);
        }
        let pr = ExpoRows {
            inner: Expo { x, y, dup: false },
            width: 3,
            reweighting: true,
            weights: [
                AtomicU64::new(1f64.to_bits()),
                AtomicU64::new(1f64.to_bits()),
            ],
        };
        let res = levenberg_marquardt(&pr, &[1.0, -0.1, 0.0], &LmOptions::default()).unwrap();
        let m = res.residuals.len() as f64;
        assert!(
            (res.cost - 0.5 * m).abs() < 0.5 * m * 1e-3,
            "cost {} for m = {m}",
            res.cost
        );
        let (w0, w1) = (
            f64::from_bits(pr.weights[0].load(Ordering::Relaxed)),
            f64::from_bits(pr.weights[1].load(Ordering::Relaxed)),
        );
        assert!(
            w0 > 5.0 * w1,
            "the noisier half must weigh less: {w0} vs {w1}"
        );
        assert!((res.params[0] - 2.0).abs() < 5.0 * res.sigma[0] + 1e-3);
    }
}
