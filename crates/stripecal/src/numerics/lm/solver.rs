//! The Levenberg-Marquardt iteration (module docs of [`super`]): options, result and the
//! damped-step loop.

use faer::linalg::solvers::Solve;
use nalgebra::{DMatrix, DVector};

use super::covariance::{covariance_by_blocks, sigmas};
use super::normal::{cost_of, Normal, Work, WEIGHT_TOL};
use super::problem::LeastSquares;
use super::schur::{self, Blocks};
use crate::error::{Error, Result};

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
    /// Whether the result carries the covariance (a dense inverse over every
    /// parameter): `false` for a solve whose result only starts another, which then
    /// has empty `covariance` and `sigma` and no `unobservable`.
    pub covariance: bool,
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
            covariance: true,
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
    check_inputs(problem, p0, opts)?;
    let mut s = Solver::start(problem, p0, opts)?;
    let initial_cost = s.cost;
    let mut iterations = 0;
    let mut reason = StopReason::MaxIterations;
    while iterations < opts.max_iterations {
        iterations += 1;
        if let Some(stop) = s.iterate()? {
            reason = stop;
            break;
        }
    }
    Ok(s.finish(initial_cost, iterations, reason))
}

/// The sizes, the start and the options are consistent and finite.
fn check_inputs<P: LeastSquares + ?Sized>(problem: &P, p0: &[f64], opts: &LmOptions) -> Result<()> {
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
    Ok(())
}

/// What a trial step came to.
enum Trial {
    /// The step lowered the cost and was taken.
    Accepted,
    /// Rejected (or the damped system was not positive definite): more damping, retry.
    Retry,
    /// The solver stops.
    Stop(StopReason),
}

/// The iteration's state: the point, its residuals and normal equations, the damping.
struct Solver<'a, P: LeastSquares + ?Sized> {
    problem: &'a P,
    opts: &'a LmOptions,
    n: usize,
    m: usize,
    work: Work,
    p: Vec<f64>,
    r: Vec<f64>,
    p_try: Vec<f64>,
    r_try: Vec<f64>,
    /// The normal equations at `p`.
    ne: Normal,
    cost: f64,
    /// `D^2` of the damping (module docs).
    diag: Vec<f64>,
    lambda: f64,
    /// Growth factor of lambda after a rejected step.
    nu: f64,
    /// The per-view column blocks ([`LeastSquares::view_blocks`]).
    blocks: Option<Blocks>,
    /// Whether the weights moved at the last re-weighting (no convergence stop then).
    weights_moving: bool,
}

impl<'a, P: LeastSquares + ?Sized> Solver<'a, P> {
    /// Evaluates at `p0` (re-weighted) and sets the initial damping.
    fn start(problem: &'a P, p0: &[f64], opts: &'a LmOptions) -> Result<Self> {
        let n = problem.num_params();
        let m = problem.num_residuals();
        let p = p0.to_vec();
        let mut r = vec![0.0; m];
        let blocks = problem.view_blocks().and_then(|b| Blocks::of(n, b));
        let mut work = if problem.has_normal_equations() && opts.huber.is_none() {
            Work::fused(m, n)
        } else {
            Work::new(m, n, problem.jacobian_row_width()).with_blocks(blocks)
        };
        work.evaluate(problem, &p, &mut r)?;
        if let Some(f) = problem.reweight(&r, &mut |rows| work.leverages(&r, opts.huber, rows)) {
            work.rescale(&f, &mut r);
        }
        let mut ne = Normal::default();
        work.normal_equations(&r, opts.huber, &mut ne)?;
        let jtj = &ne.jtj;
        let cost = cost_of(&r, opts.huber);
        let diag: Vec<f64> = match &opts.scaling {
            Some(s) => s.iter().map(|x| 1.0 / (x * x)).collect(),
            None => (0..n).map(|i| jtj[(i, i)].max(1e-300)).collect(),
        };
        let maxdiag = (0..n).map(|i| jtj[(i, i)]).fold(0.0f64, f64::max);
        let lambda = opts.initial_lambda * maxdiag.max(1e-300)
            / diag.iter().cloned().fold(0.0f64, f64::max).max(1e-300);
        Ok(Solver {
            problem,
            opts,
            n,
            m,
            work,
            p,
            r,
            p_try: vec![0.0; n],
            r_try: vec![0.0; m],
            ne,
            cost,
            diag,
            lambda,
            nu: 4.0,
            blocks,
            weights_moving: false,
        })
    }

    /// One iteration: the zero-cost and gradient tests, then trial steps until one is
    /// accepted or the solver stops.
    fn iterate(&mut self) -> Result<Option<StopReason>> {
        let n = self.n;
        if self.cost == 0.0 {
            return Ok(Some(StopReason::ZeroCost));
        }
        // gradient test
        let gmax = (0..n)
            .map(|i| {
                let d = self.ne.jtj[(i, i)];
                if d > 0.0 {
                    self.ne.g[i].abs() / d.sqrt()
                } else {
                    0.0
                }
            })
            .fold(0.0f64, f64::max);
        if gmax <= self.opts.gtol * (2.0 * self.cost).sqrt() && !self.weights_moving {
            return Ok(Some(StopReason::GradientConverged));
        }
        if self.opts.scaling.is_none() {
            for (i, d) in self.diag.iter_mut().enumerate() {
                *d = d.max(self.ne.jtj[(i, i)]);
            }
        }
        loop {
            match self.trial()? {
                Trial::Accepted => return Ok(None),
                Trial::Retry => continue,
                Trial::Stop(reason) => return Ok(Some(reason)),
            }
        }
    }

    /// Solves the damped system and tries the step.
    fn trial(&mut self) -> Result<Trial> {
        let (n, m, opts) = (self.n, self.m, self.opts);
        let dp = match self.damped_step() {
            Some(dp) => dp,
            None => {
                self.lambda *= 10.0;
                if self.lambda > 1e30 {
                    return Ok(Trial::Stop(StopReason::NoDecrease));
                }
                return Ok(Trial::Retry);
            }
        };
        // Decrease predicted by the quadratic model: -g.dp - dp^T JtJ dp / 2.
        let pred = -self.ne.g.dot(&dp) - 0.5 * dp.dot(&(&self.ne.jtj * &dp));
        // Stop before evaluating a step that cannot gain anything worth having: a
        // predicted relative decrease below `ftol` (MINPACK's test), or below the
        // round-off of the cost itself (`m` terms summed).
        let noise = 10.0 * m as f64 * f64::EPSILON;
        if pred.is_nan() || pred <= opts.ftol.max(noise) * self.cost {
            return Ok(Trial::Stop(if pred > noise * self.cost {
                StopReason::CostConverged
            } else {
                StopReason::NoDecrease
            }));
        }
        let dnorm = (0..n)
            .map(|i| self.diag[i] * dp[i] * dp[i])
            .sum::<f64>()
            .sqrt();
        self.problem
            .retract(&self.p, dp.as_slice(), &mut self.p_try);
        let ok = self.p_try.iter().all(|x| x.is_finite())
            && self.problem.residuals(&self.p_try, &mut self.r_try).is_ok()
            && self.r_try.iter().all(|x| x.is_finite());
        let new_cost = if ok {
            cost_of(&self.r_try, opts.huber)
        } else {
            f64::INFINITY
        };
        if new_cost < self.cost {
            return self.accept(new_cost, pred, dnorm);
        }
        self.lambda *= self.nu;
        self.nu *= 2.0;
        if self.lambda > 1e30 {
            return Ok(Trial::Stop(StopReason::NoDecrease));
        }
        Ok(Trial::Retry)
    }

    /// The step of the damped system `(J^T W J + lambda D^2) dp = -g`: by blocks
    /// ([`schur`]) or one dense Cholesky; `None` when the damped matrix is not positive
    /// definite.
    fn damped_step(&self) -> Option<DVector<f64>> {
        let n = self.n;
        let damp: Vec<f64> = self.diag.iter().map(|d| self.lambda * d).collect();
        if let Some(b) = &self.blocks {
            let rhs: Vec<f64> = self.ne.g.iter().map(|x| -x).collect();
            return schur::solve(&self.ne.jtj, &damp, &rhs, b);
        }
        let a = faer::Mat::<f64>::from_fn(n, n, |i, j| {
            self.ne.jtj[(i, j)] + if i == j { damp[i] } else { 0.0 }
        });
        let ch = a.llt(faer::Side::Lower).ok()?;
        let x = ch.solve(faer::Mat::<f64>::from_fn(n, 1, |i, _| -self.ne.g[i]));
        Some(DVector::from_fn(n, |i, _| x[(i, 0)]))
    }

    /// Takes the trial point (cost `new_cost`, predicted decrease `pred`, scaled step
    /// length `dnorm`): re-evaluates and re-weights there, updates the damping from the
    /// gain ratio and applies the cost and step tests.
    fn accept(&mut self, new_cost: f64, pred: f64, dnorm: f64) -> Result<Trial> {
        let (n, opts) = (self.n, self.opts);
        let cost = self.cost;
        let pnorm = (0..n)
            .map(|i| self.diag[i] * self.p[i] * self.p[i])
            .sum::<f64>()
            .sqrt();
        let rel = (cost - new_cost) / cost;
        let rho = (cost - new_cost) / pred;
        std::mem::swap(&mut self.p, &mut self.p_try);
        self.work.evaluate(self.problem, &self.p, &mut self.r)?;
        self.weights_moving = false;
        let (work, r) = (&mut self.work, &self.r);
        if let Some(f) = self
            .problem
            .reweight(r, &mut |rows| work.leverages(r, opts.huber, rows))
        {
            self.weights_moving = f.iter().any(|x| (x - 1.0).abs() > WEIGHT_TOL);
            self.work.rescale(&f, &mut self.r);
        }
        self.work
            .normal_equations(&self.r, opts.huber, &mut self.ne)?;
        self.cost = cost_of(&self.r, opts.huber);
        // The quadratic model predicted the decrease well: close to Gauss-Newton (near
        // the solution of a mildly non-linear problem the damping only slows the
        // convergence in the weakly determined directions).
        self.lambda = if rho > 0.9 {
            self.lambda / 100.0
        } else if rho > 0.75 {
            self.lambda / 10.0
        } else if rho > 0.25 {
            self.lambda / 3.0
        } else {
            self.lambda * 2.0
        }
        .max(1e-300);
        self.nu = 2.0;
        if !self.weights_moving && rel < opts.ftol {
            return Ok(Trial::Stop(StopReason::CostConverged));
        }
        if !self.weights_moving && dnorm <= opts.xtol * (pnorm + opts.xtol) {
            return Ok(Trial::Stop(StopReason::StepConverged));
        }
        Ok(Trial::Accepted)
    }

    /// The result at the last accepted point, with its covariance.
    fn finish(self, initial_cost: f64, iterations: usize, reason: StopReason) -> LmResult {
        let (n, m) = (self.n, self.m);
        let r = self.r;
        let ssr: f64 = r.iter().map(|x| x * x).sum();
        let sigma2 = if m > n { ssr / (m - n) as f64 } else { 0.0 };
        let (covariance, unobservable) = if self.opts.covariance {
            covariance_by_blocks(
                &self.ne.jtj,
                sigma2,
                self.opts.rank_tol,
                self.blocks.as_ref(),
            )
        } else {
            (DMatrix::zeros(0, 0), Vec::new())
        };
        let sigma = sigmas(&covariance);
        LmResult {
            params: self.p,
            residuals: r,
            ssr,
            cost: self.cost,
            initial_cost,
            iterations,
            reason,
            jtj: self.ne.jtj,
            sigma2,
            covariance,
            sigma,
            unobservable,
        }
    }
}
