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
//! over runs of rows with the same columns (sparse rows); the damped `n x n` system is
//! solved by Cholesky.
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

use faer::{Accum, Mat, MatMut, Par};
use nalgebra::{DMatrix, DVector};

use crate::error::{Error, Result};

/// A least-squares problem `min sum_i rho(r_i(p))`.
pub trait LeastSquares {
    /// Number of parameters n.
    fn num_params(&self) -> usize;
    /// Number of residuals m.
    fn num_residuals(&self) -> usize;
    /// Residuals at `p` into `r` (length m).
    fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()>;
    /// Residuals into `r` and the Jacobian `dr/dp` into `jac` (m x n, zero-filled on
    /// entry) at `p`. Columns are derivatives w.r.t. the increment `dp` of
    /// [`LeastSquares::retract`].
    fn residuals_and_jacobian(&self, p: &[f64], r: &mut [f64], jac: MatMut<'_, f64>) -> Result<()>;
    /// `p (+) dp` into `out`; default: addition. Override for manifold parameters
    /// (rotations: `R Exp(dw)`), the Jacobian being w.r.t. `dp` at 0.
    fn retract(&self, p: &[f64], dp: &[f64], out: &mut [f64]) {
        for ((o, a), b) in out.iter_mut().zip(p).zip(dp) {
            *o = a + b;
        }
    }
    /// Re-weighting (variance components): called with the residuals at the start and
    /// after every accepted step; a problem that changes its residual weights returns
    /// the factor by which each residual's weight changed (the solver rescales the
    /// residuals and Jacobian it holds). While a factor differs from 1 by more than
    /// 1e-3 the solver does not stop on its cost or step tests. Default: `None`.
    fn reweight(&self, _r: &[f64]) -> Option<Vec<f64>> {
        None
    }
    /// `Some(w)` when every Jacobian row has at most `w` non-zeros and the problem
    /// provides them by [`LeastSquares::residuals_and_jacobian_rows`] (the solver then
    /// never forms the `m x n` Jacobian matrix; `w = n`: dense rows, see
    /// [`JacobianRows`]); `None` (default): the dense matrix.
    fn jacobian_row_width(&self) -> Option<usize> {
        None
    }
    /// Residuals into `r` and the Jacobian by rows into `rows` (zero-filled on entry;
    /// see [`JacobianRows`]). Only called when [`LeastSquares::jacobian_row_width`] is
    /// `Some`.
    fn residuals_and_jacobian_rows(
        &self,
        _p: &[f64],
        _r: &mut [f64],
        _rows: &mut JacobianRows,
    ) -> Result<()> {
        Err(Error::InvalidInput(
            "this least-squares problem has no row Jacobian".into(),
        ))
    }
}

/// A Jacobian stored by rows of `width` (column, value) pairs: for problems in which
/// each residual depends on a few parameters (a camera and one view's pose). Unused
/// pairs are (0, 0.0); a column may appear more than once in a row (the values add).
///
/// When the width equals the number of parameters the rows are DENSE: row `i` holds
/// the values of columns `0..n` in order, no columns are stored ([`Self::parts_mut`]
/// returns an empty column slice) and the solver forms `J^T J` by a matrix product.
#[derive(Debug, Clone)]
pub struct JacobianRows {
    width: usize,
    dense: bool,
    /// Sparse: the columns of every row; dense: `0..width` once.
    cols: Vec<usize>,
    vals: Vec<f64>,
}

impl JacobianRows {
    /// `m` zero rows of `width` pairs; dense when `width == n`.
    pub fn new(m: usize, width: usize, n: usize) -> Self {
        let dense = width == n;
        JacobianRows {
            width,
            dense,
            cols: if dense {
                (0..width).collect()
            } else {
                vec![0; m * width]
            },
            vals: vec![0.0; m * width],
        }
    }
    /// Pairs per row.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Whether the rows are dense (see the type's docs).
    pub fn is_dense(&self) -> bool {
        self.dense
    }
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.vals.len() / self.width.max(1)
    }
    /// True without rows.
    pub fn is_empty(&self) -> bool {
        self.vals.is_empty()
    }
    /// Zero-fills every row.
    pub fn clear(&mut self) {
        if !self.dense {
            self.cols.fill(0);
        }
        self.vals.fill(0.0);
    }
    /// Columns (empty when dense) and values of every row, row after row (`width`
    /// each): split them with `chunks_mut(width)` (or rayon's `par_chunks_mut`).
    pub fn parts_mut(&mut self) -> (&mut [usize], &mut [f64]) {
        if self.dense {
            (&mut [], &mut self.vals)
        } else {
            (&mut self.cols, &mut self.vals)
        }
    }
    /// Columns and values of row `i`.
    pub fn row(&self, i: usize) -> (&[usize], &[f64]) {
        let w = self.width;
        let c = if self.dense {
            &self.cols[..]
        } else {
            &self.cols[i * w..(i + 1) * w]
        };
        (c, &self.vals[i * w..(i + 1) * w])
    }
}

/// [`LeastSquares::residuals_and_jacobian`] of a problem that provides its Jacobian by
/// rows: the rows scattered into the dense matrix (for tests and callers that want it).
pub fn dense_jacobian_from_rows<P: LeastSquares + ?Sized>(
    problem: &P,
    p: &[f64],
    r: &mut [f64],
    mut jac: MatMut<'_, f64>,
) -> Result<()> {
    let w = problem.jacobian_row_width().ok_or_else(|| {
        Error::InvalidInput("this least-squares problem has no row Jacobian".into())
    })?;
    let mut rows = JacobianRows::new(r.len(), w, problem.num_params());
    problem.residuals_and_jacobian_rows(p, r, &mut rows)?;
    for i in 0..rows.len() {
        let (c, v) = rows.row(i);
        for (&c, &v) in c.iter().zip(v) {
            jac[(i, c)] += v;
        }
    }
    Ok(())
}

/// Options of [`levenberg_marquardt`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmOptions {
    /// Maximum iterations (Jacobian evaluations).
    pub max_iterations: usize,
    /// Relative cost decrease after an accepted step below which the solver stops.
    pub ftol: f64,
    /// Relative (scaled) step size below which the solver stops.
    pub xtol: f64,
    /// Scaled gradient `max_i |g_i| / sqrt((J^T J)_ii) / sqrt(2 cost)` below which the
    /// solver stops (cosine between residual and Jacobian columns).
    pub gtol: f64,
    /// Initial damping relative to the largest diagonal entry of `J^T J`.
    pub initial_lambda: f64,
    /// Huber threshold (residual units); `None` for plain least squares.
    pub huber: Option<f64>,
    /// Per-parameter typical size (length n): the damping uses `1 / scaling^2`.
    pub scaling: Option<Vec<f64>>,
    /// Relative eigenvalue of the Jacobi-scaled `J^T J` below which a direction is
    /// unobservable.
    pub rank_tol: f64,
}

impl Default for LmOptions {
    fn default() -> Self {
        LmOptions {
            max_iterations: 100,
            ftol: 1e-15,
            xtol: 1e-15,
            gtol: 1e-14,
            initial_lambda: 1e-4,
            huber: None,
            scaling: None,
            rank_tol: 1e-13,
        }
    }
}

/// Why the solver stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    CostConverged,
    StepConverged,
    GradientConverged,
    /// Cost is zero (exact fit).
    ZeroCost,
    /// No step lowers the cost any more (round-off floor).
    NoDecrease,
    MaxIterations,
}

/// The solution and its statistics.
#[derive(Debug, Clone)]
pub struct LmResult {
    pub params: Vec<f64>,
    /// Final residuals (unweighted).
    pub residuals: Vec<f64>,
    /// Sum of squared residuals (unweighted).
    pub ssr: f64,
    /// The minimised cost: `0.5 * sum rho(r)` (`0.5 SSR` without Huber).
    pub cost: f64,
    /// Initial cost.
    pub initial_cost: f64,
    pub iterations: usize,
    pub reason: StopReason,
    /// `J^T W J` at the solution (n x n), for covariance and chaining.
    pub jtj: DMatrix<f64>,
    /// `sigma^2 = SSR / (m - n)` (0 when m <= n).
    pub sigma2: f64,
    /// Covariance `sigma^2 (J^T W J)^-1` (rows / columns of unobservable parameters NaN).
    pub covariance: DMatrix<f64>,
    /// One-sigma per parameter (NaN where unobservable).
    pub sigma: Vec<f64>,
    /// Indices of unobservable parameters.
    pub unobservable: Vec<usize>,
}

fn huber_weight(r: f64, huber: Option<f64>) -> f64 {
    match huber {
        Some(d) if r.abs() > d => d / r.abs(),
        _ => 1.0,
    }
}

fn cost_of(r: &[f64], huber: Option<f64>) -> f64 {
    match huber {
        None => 0.5 * r.iter().map(|x| x * x).sum::<f64>(),
        Some(d) => r
            .iter()
            .map(|&x| {
                let a = x.abs();
                if a <= d {
                    0.5 * x * x
                } else {
                    d * (a - 0.5 * d)
                }
            })
            .sum(),
    }
}

/// Relative weight change below which re-weighted weights count as settled.
const WEIGHT_TOL: f64 = 1e-3;

/// The solver's Jacobian storage (dense, or by rows) and its normal equations.
struct Work {
    m: usize,
    n: usize,
    rows: Option<JacobianRows>,
    jac: Mat<f64>,
    jtj_f: Mat<f64>,
    scratch: Vec<f64>,
}

impl Work {
    fn new(m: usize, n: usize, row_width: Option<usize>) -> Self {
        Work {
            m,
            n,
            rows: row_width.map(|w| JacobianRows::new(m, w, n)),
            jac: if row_width.is_some() {
                Mat::zeros(0, 0)
            } else {
                Mat::zeros(m, n)
            },
            jtj_f: Mat::zeros(n, n),
            scratch: Vec::new(),
        }
    }

    /// Residuals and Jacobian at `p`.
    fn evaluate<P: LeastSquares + ?Sized>(
        &mut self,
        problem: &P,
        p: &[f64],
        r: &mut [f64],
    ) -> Result<()> {
        match &mut self.rows {
            Some(rows) => {
                rows.clear();
                problem.residuals_and_jacobian_rows(p, r, rows)?;
            }
            None => {
                self.jac.fill(0.0);
                problem.residuals_and_jacobian(p, r, self.jac.as_mut())?;
            }
        }
        if r.iter().any(|x| !x.is_finite()) {
            return Err(Error::Degenerate("residuals are not finite".into()));
        }
        Ok(())
    }

    /// Multiplies residual `i` and Jacobian row `i` by `f[i]` (a re-weighting).
    fn rescale(&mut self, f: &[f64], r: &mut [f64]) {
        for (ri, fi) in r.iter_mut().zip(f) {
            *ri *= fi;
        }
        match &mut self.rows {
            Some(rows) => {
                let w = rows.width;
                for (v, fi) in rows.vals.chunks_exact_mut(w.max(1)).zip(f) {
                    v.iter_mut().for_each(|x| *x *= fi);
                }
            }
            None => {
                for j in 0..self.n {
                    for (i, fi) in f.iter().enumerate() {
                        self.jac[(i, j)] *= fi;
                    }
                }
            }
        }
    }

    /// `(J^T W J, J^T W r)`, `W` the Huber IRLS weights at `r` (identity without Huber).
    fn normal_equations(
        &mut self,
        r: &[f64],
        huber: Option<f64>,
    ) -> Result<(DMatrix<f64>, DVector<f64>)> {
        let (m, n) = (self.m, self.n);
        let mut g = DVector::<f64>::zeros(n);
        let mut jtj = DMatrix::<f64>::zeros(n, n);
        // sqrt(W) r
        let sw: Vec<f64> = r.iter().map(|&x| huber_weight(x, huber).sqrt()).collect();
        let rw: Vec<f64> = r.iter().zip(&sw).map(|(x, s)| x * s).collect();
        // sqrt(W) J as a column-major n x m matrix (J^T) or a column-major m x n one.
        let dense_t: Option<faer::MatRef<'_, f64>>;
        match &self.rows {
            Some(rows) => {
                let w = rows.width;
                if rows.dense {
                    // Every row holds columns 0..n in order: the values are J^T stored
                    // column-major (n x m).
                    let vals: &[f64] = if huber.is_some() {
                        self.scratch.clear();
                        self.scratch.extend_from_slice(&rows.vals);
                        for (v, s) in self.scratch.chunks_exact_mut(w.max(1)).zip(&sw) {
                            v.iter_mut().for_each(|x| *x *= s);
                        }
                        &self.scratch
                    } else {
                        &rows.vals
                    };
                    dense_t = Some(faer::MatRef::from_column_major_slice(vals, n, m));
                } else {
                    // Rows with the same columns as the previous (same view) are summed
                    // into a small w x w block; the block is scattered into the n x n
                    // matrix when the columns change.
                    let acc = jtj.as_mut_slice();
                    let mut block = vec![0.0; w * w];
                    let mut cur: Option<usize> = None;
                    let flush = |acc: &mut [f64], block: &mut [f64], cols: &[usize]| {
                        for (a, &ca) in cols.iter().enumerate() {
                            let col = &mut acc[ca * n..(ca + 1) * n];
                            for (b, &cb) in cols.iter().enumerate() {
                                col[cb] += block[a * w + b];
                            }
                        }
                        block.fill(0.0);
                    };
                    for (i, (&ri, &si)) in r.iter().zip(&sw).enumerate() {
                        let wt = si * si;
                        let (c, v) = rows.row(i);
                        if let Some(k) = cur {
                            if rows.row(k).0 != c {
                                flush(acc, &mut block, rows.row(k).0);
                                cur = Some(i);
                            }
                        } else {
                            cur = Some(i);
                        }
                        for (a, (&ca, &va)) in c.iter().zip(v).enumerate() {
                            let wva = wt * va;
                            g[ca] += wva * ri;
                            let brow = &mut block[a * w..(a + 1) * w];
                            for (bb, &vb) in brow.iter_mut().zip(v) {
                                *bb += wva * vb;
                            }
                        }
                    }
                    if let Some(k) = cur {
                        flush(acc, &mut block, rows.row(k).0);
                    }
                    dense_t = None;
                }
            }
            None => {
                if huber.is_some() {
                    self.scratch.clear();
                    self.scratch.resize(m * n, 0.0);
                    for j in 0..n {
                        let col = self.jac.col(j);
                        for (i, si) in sw.iter().enumerate() {
                            self.scratch[j * m + i] = col[i] * si;
                        }
                    }
                    dense_t = Some(
                        faer::MatRef::from_column_major_slice(&self.scratch, m, n).transpose(),
                    );
                } else {
                    dense_t = Some(self.jac.as_ref().transpose());
                }
            }
        }
        if let Some(jt) = dense_t {
            faer::linalg::matmul::matmul(
                self.jtj_f.as_mut(),
                Accum::Replace,
                jt,
                jt.transpose(),
                1.0,
                Par::Seq,
            );
            let rv = faer::MatRef::from_column_major_slice(&rw, m, 1);
            let mut gf = Mat::<f64>::zeros(n, 1);
            faer::linalg::matmul::matmul(gf.as_mut(), Accum::Replace, jt, rv, 1.0, Par::Seq);
            for a in 0..n {
                g[a] = gf[(a, 0)];
                for b in 0..n {
                    jtj[(a, b)] = self.jtj_f[(a, b)];
                }
            }
        }
        if jtj.iter().any(|x| !x.is_finite()) || g.iter().any(|x| !x.is_finite()) {
            return Err(Error::Degenerate("Jacobian is not finite".into()));
        }
        Ok((jtj, g))
    }
}

/// Minimises the problem from `p0`.
///
/// Errors: [`Error::InvalidInput`] for inconsistent sizes, non-finite `p0` or options;
/// [`Error::Degenerate`] if the initial residuals or Jacobian are not finite; errors of
/// the problem's own evaluation at `p0` are passed on (later failed evaluations count
/// as rejected steps).
pub fn levenberg_marquardt<P: LeastSquares + ?Sized>(
    problem: &P,
    p0: &[f64],
    opts: &LmOptions,
) -> Result<LmResult> {
    let n = problem.num_params();
    let m = problem.num_residuals();
    if p0.len() != n {
        return Err(Error::InvalidInput(format!(
            "initial parameters have length {}, the problem has {n}",
            p0.len()
        )));
    }
    if n == 0 || m == 0 {
        return Err(Error::InvalidInput(format!(
            "least squares needs parameters and residuals (n = {n}, m = {m})"
        )));
    }
    if p0.iter().any(|x| !x.is_finite()) {
        return Err(Error::InvalidInput(
            "initial parameters are not finite".into(),
        ));
    }
    if let Some(s) = &opts.scaling {
        if s.len() != n || s.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(Error::InvalidInput(format!(
                "scaling must hold {n} positive finite values"
            )));
        }
    }
    if let Some(h) = opts.huber {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidInput(format!(
                "Huber threshold {h} must be positive"
            )));
        }
    }

    let mut p = p0.to_vec();
    let mut r = vec![0.0; m];
    let mut work = Work::new(m, n, problem.jacobian_row_width());
    let mut r_try = vec![0.0; m];
    let mut p_try = vec![0.0; n];

    work.evaluate(problem, &p, &mut r)?;
    if let Some(f) = problem.reweight(&r) {
        work.rescale(&f, &mut r);
    }
    let (mut jtj, mut g) = work.normal_equations(&r, opts.huber)?;
    let mut cost = cost_of(&r, opts.huber);
    let initial_cost = cost;
    let mut diag: Vec<f64> = match &opts.scaling {
        Some(s) => s.iter().map(|x| 1.0 / (x * x)).collect(),
        None => (0..n).map(|i| jtj[(i, i)].max(1e-300)).collect(),
    };
    let maxdiag = (0..n).map(|i| jtj[(i, i)]).fold(0.0f64, f64::max);
    let mut lambda = opts.initial_lambda * maxdiag.max(1e-300)
        / diag.iter().cloned().fold(0.0f64, f64::max).max(1e-300);
    let mut nu = 4.0;
    let mut iterations = 0;
    let mut reason = StopReason::MaxIterations;
    // Whether the weights moved at the last re-weighting (no convergence stop then).
    let mut weights_moving = false;

    'outer: while iterations < opts.max_iterations {
        iterations += 1;
        if cost == 0.0 {
            reason = StopReason::ZeroCost;
            break;
        }
        // gradient test
        let gmax = (0..n)
            .map(|i| {
                let d = jtj[(i, i)];
                if d > 0.0 {
                    g[i].abs() / d.sqrt()
                } else {
                    0.0
                }
            })
            .fold(0.0f64, f64::max);
        if gmax <= opts.gtol * (2.0 * cost).sqrt() && !weights_moving {
            reason = StopReason::GradientConverged;
            break;
        }
        if opts.scaling.is_none() {
            for (i, d) in diag.iter_mut().enumerate() {
                *d = d.max(jtj[(i, i)]);
            }
        }
        loop {
            let mut a = jtj.clone();
            for i in 0..n {
                a[(i, i)] += lambda * diag[i];
            }
            let dp = match a.cholesky() {
                Some(ch) => ch.solve(&(-&g)),
                None => {
                    lambda *= 10.0;
                    if lambda > 1e30 {
                        reason = StopReason::NoDecrease;
                        break 'outer;
                    }
                    continue;
                }
            };
            // Decrease predicted by the quadratic model: -g.dp - dp^T JtJ dp / 2.
            let pred = -g.dot(&dp) - 0.5 * dp.dot(&(&jtj * &dp));
            // Stop before evaluating a step that cannot gain anything worth having: a
            // predicted relative decrease below `ftol` (MINPACK's test), or below the
            // round-off of the cost itself (`m` terms summed).
            let noise = 10.0 * m as f64 * f64::EPSILON;
            if pred.is_nan() || pred <= opts.ftol.max(noise) * cost {
                reason = if pred > noise * cost {
                    StopReason::CostConverged
                } else {
                    StopReason::NoDecrease
                };
                break 'outer;
            }
            let dnorm = (0..n).map(|i| diag[i] * dp[i] * dp[i]).sum::<f64>().sqrt();
            problem.retract(&p, dp.as_slice(), &mut p_try);
            let ok = p_try.iter().all(|x| x.is_finite())
                && problem.residuals(&p_try, &mut r_try).is_ok()
                && r_try.iter().all(|x| x.is_finite());
            let new_cost = if ok {
                cost_of(&r_try, opts.huber)
            } else {
                f64::INFINITY
            };
            if new_cost < cost {
                let pnorm = (0..n).map(|i| diag[i] * p[i] * p[i]).sum::<f64>().sqrt();
                let rel = (cost - new_cost) / cost;
                let rho = (cost - new_cost) / pred;
                std::mem::swap(&mut p, &mut p_try);
                work.evaluate(problem, &p, &mut r)?;
                weights_moving = false;
                if let Some(f) = problem.reweight(&r) {
                    weights_moving = f.iter().any(|x| (x - 1.0).abs() > WEIGHT_TOL);
                    work.rescale(&f, &mut r);
                }
                (jtj, g) = work.normal_equations(&r, opts.huber)?;
                cost = cost_of(&r, opts.huber);
                // The quadratic model predicted the decrease well: close to Gauss-Newton
                // (near the solution of a mildly non-linear problem the damping only
                // slows the convergence in the weakly determined directions).
                lambda = if rho > 0.9 {
                    lambda / 100.0
                } else if rho > 0.75 {
                    lambda / 10.0
                } else if rho > 0.25 {
                    lambda / 3.0
                } else {
                    lambda * 2.0
                }
                .max(1e-300);
                nu = 2.0;
                if !weights_moving && rel < opts.ftol {
                    reason = StopReason::CostConverged;
                    break 'outer;
                }
                if !weights_moving && dnorm <= opts.xtol * (pnorm + opts.xtol) {
                    reason = StopReason::StepConverged;
                    break 'outer;
                }
                break;
            }
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e30 {
                reason = StopReason::NoDecrease;
                break 'outer;
            }
        }
    }

    let ssr: f64 = r.iter().map(|x| x * x).sum();
    let sigma2 = if m > n { ssr / (m - n) as f64 } else { 0.0 };
    let (covariance, unobservable) = covariance(&jtj, sigma2, opts.rank_tol);
    let sigma = (0..n)
        .map(|i| {
            let v = covariance[(i, i)];
            if v.is_finite() {
                v.max(0.0).sqrt()
            } else {
                f64::NAN
            }
        })
        .collect();
    Ok(LmResult {
        params: p,
        residuals: r,
        ssr,
        cost,
        initial_cost,
        iterations,
        reason,
        jtj,
        sigma2,
        covariance,
        sigma,
        unobservable,
    })
}

/// Covariance `sigma2 * jtj^-1` with rank-deficiency detection (module docs): returns
/// the covariance (NaN rows / columns for unobservable parameters) and their indices.
pub fn covariance(jtj: &DMatrix<f64>, sigma2: f64, rank_tol: f64) -> (DMatrix<f64>, Vec<usize>) {
    let n = jtj.nrows();
    let d: Vec<f64> = (0..n).map(|i| jtj[(i, i)].max(0.0).sqrt()).collect();
    let mut bad = vec![false; n];
    for i in 0..n {
        if d[i].is_nan() || d[i] <= 0.0 || !d[i].is_finite() {
            bad[i] = true;
        }
    }
    let good: Vec<usize> = (0..n).filter(|&i| !bad[i]).collect();
    let scaled = DMatrix::from_fn(good.len(), good.len(), |a, b| {
        jtj[(good[a], good[b])] / (d[good[a]] * d[good[b]])
    });
    // Cheap certificate of full rank: for the unit-diagonal `S`, `lambda_max <= trace =
    // k` and `lambda_min >= 1 / trace(S^-1)`; when `k trace(S^-1) rank_tol <= 1` no
    // eigenvalue is below `rank_tol lambda_max` and the eigen-decomposition is skipped.
    let certified: Option<DMatrix<f64>> = if good.len() == n {
        scaled
            .clone()
            .cholesky()
            .map(|ch| ch.inverse())
            .filter(|inv| {
                let tr: f64 = (0..n).map(|i| inv[(i, i)]).sum();
                tr.is_finite() && n as f64 * tr * rank_tol <= 1.0
            })
    } else {
        None
    };
    if let Some(inv) = certified {
        let cov = DMatrix::from_fn(n, n, |a, b| sigma2 * inv[(a, b)] / (d[a] * d[b]));
        return (cov, Vec::new());
    }
    if !good.is_empty() {
        let eig = scaled.clone().symmetric_eigen();
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
        if let Some(ch) = sub.cholesky() {
            let inv = ch.inverse();
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

/// Test support: asserts that `residuals_and_jacobian` at `p` returns the residuals of
/// `residuals` (to `rtol` absolute) and a Jacobian equal to central differences taken
/// through [`LeastSquares::retract`] with step `step(j)` per column: the largest
/// difference in a column at most `tol * max(largest |entry|, 1)`.
#[cfg(test)]
pub(crate) fn assert_jacobian_matches_fd<P: LeastSquares>(
    pr: &P,
    p: &[f64],
    step: impl Fn(usize) -> f64,
    rtol: f64,
    tol: f64,
    what: &str,
) {
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
        fn reweight(&self, r: &[f64]) -> Option<Vec<f64>> {
            if !self.reweighting {
                return None;
            }
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
