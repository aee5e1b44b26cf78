//! The covariance widened to the views' own scatter (a covariance clustered by view).
//!
//! The model's covariance `C_m = s^2 N^-1` is honest when the residuals are what the
//! noise model says: white image noise of the estimated sigmas, and the robot-pose noise.
//! Real images are not quite: a view's detections share errors (a board that is not
//! flat, a detector bias that depends on the viewing angle, a lens the model does not
//! quite fit; on rosi_10x10 a quadratic per view takes up half the residual variance of a
//! camera calibrated with free board poses), and then even that camera states sigmas
//! several times too small (rosi_10x10: the two halves of its views disagree on `u0` by
//! 7.6 of their sigmas, on `fu` by 4.4). The views are the independent units, and the
//! scatter of what they say measures the estimate's uncertainty whatever the model
//! misses (the sandwich, or cluster-robust, covariance).
//!
//! For each view `v`, its share of the normal equations reduced to the global columns
//! (its own per-view columns eliminated: its robot-pose correction, its board pose),
//! `M_v` and `s_v` (`N = sum M_v`; `s_v = J_v^T r_v` sums to zero at the solution). With
//! `N = L L^T` and the view's leverage `A_v = L^-1 M_v L^-T`, its contribution is `d_v =
//! L^-T (I - A_v)^-1/2 L^-1 s_v`, and `V = sum d_v d_v^T` (the bias-reduced sandwich of
//! Bell and McCaffrey, "CR2": `(I - A_v)^-1` instead would be the delete-one-view
//! jackknife, which overstates: split halves of rosi_10x10 came out at RMS z 0.85 with
//! it, 1.06 with this). In a direction one view determines nearly alone (its leverage
//! there above 0.9: a laser plane seen in two views) there is no scatter to measure and
//! that view's contribution is left out. The covariance is `C_m` widened to `V` where
//! that is larger: with `C_m = L' L'^T` and `L'^-1 V L'^-T = U diag(l) U^T`, `C = L' U
//! diag(max(l, 1)) U^T L'^T`, so that `C >= C_m` and `C >= V` (no combination of the
//! numbers has a sigma below either's). With four views or fewer the model's covariance
//! stays.
//!
//! Used by the camera stage ([`super::camera`], free board poses) and the one-stage
//! adjustment ([`super::joint`]), so that a camera-only calibration and a one-stage one
//! state their sigmas the same way.

use std::ops::Range;

use nalgebra::{DMatrix, DVector};

/// One view's share of the normal equations, accumulated row by row: the global
/// columns `0..ng` and the view's own columns `own` (eliminated at the end).
#[derive(Debug, Clone)]
pub struct ViewShare {
    ng: usize,
    own: Range<usize>,
    a: DMatrix<f64>,
    g: DVector<f64>,
    /// Scratch: a row's columns as local indices ([`Self::add_row`]).
    local: Vec<Option<usize>>,
}

impl ViewShare {
    /// An empty share over `ng` global columns and the view's columns `own`.
    pub fn new(ng: usize, own: Range<usize>) -> Self {
        let n = ng + own.len();
        ViewShare {
            ng,
            own,
            a: DMatrix::zeros(n, n),
            g: DVector::zeros(n),
            local: Vec::new(),
        }
    }

    /// Adds one (weighted) row: its columns, values and residual; other views' columns
    /// are ignored (they have none).
    pub fn add_row(&mut self, cols: &[usize], vals: &[f64], r: f64) {
        let mut local = std::mem::take(&mut self.local);
        local.clear();
        local.extend(cols.iter().map(|&c| self.local_column(c)));
        for (x, (lx, vx)) in local.iter().zip(vals).enumerate() {
            let (Some(lx), true) = (lx, *vx != 0.0) else {
                continue;
            };
            self.g[*lx] += vx * r;
            for (ly, vy) in local.iter().zip(vals).skip(x) {
                let Some(ly) = ly else { continue };
                let v = vx * vy;
                self.a[(*lx, *ly)] += v;
                if lx != ly {
                    self.a[(*ly, *lx)] += v;
                }
            }
        }
        self.local = local;
    }

    /// Adds rows that share their columns `cols` (`w` of them) at once: their values
    /// `jt` (the rows' `J^T`, `w x len`, each row a column) and residuals `r` (length
    /// `len`). The same sums as [`Self::add_row`] row by row (in another order: equal to
    /// rounding), as one `w x w` matrix product instead of a scalar loop per row; the
    /// lower triangle of the product is mirrored, so the share stays exactly symmetric.
    pub fn add_rows(&mut self, cols: &[usize], jt: faer::MatRef<'_, f64>, r: &[f64]) {
        let w = cols.len();
        let mut local = std::mem::take(&mut self.local);
        local.clear();
        local.extend(cols.iter().map(|&c| self.local_column(c)));
        let mut block = faer::Mat::<f64>::zeros(w, w);
        let mut gb = faer::Mat::<f64>::zeros(w, 1);
        let rv = faer::MatRef::from_column_major_slice(r, r.len(), 1);
        let seq = faer::Par::Seq;
        faer::linalg::matmul::matmul(
            block.as_mut(),
            faer::Accum::Replace,
            jt,
            jt.transpose(),
            1.0,
            seq,
        );
        faer::linalg::matmul::matmul(gb.as_mut(), faer::Accum::Replace, jt, rv, 1.0, seq);
        for (x, lx) in local.iter().enumerate() {
            let Some(lx) = *lx else { continue };
            self.g[lx] += gb[(x, 0)];
            for (y, ly) in local.iter().enumerate().take(x + 1) {
                let Some(ly) = *ly else { continue };
                let v = block[(x, y)];
                self.a[(lx, ly)] += v;
                if x != y {
                    self.a[(ly, lx)] += v;
                }
            }
        }
        self.local = local;
    }

    /// Column `c`'s index in the share (`None`: another view's).
    fn local_column(&self, c: usize) -> Option<usize> {
        if c < self.ng {
            Some(c)
        } else if self.own.contains(&c) {
            Some(self.ng + c - self.own.start)
        } else {
            None
        }
    }

    /// `(M_v, s_v)`: `A_gg - A_gd A_dd^-1 A_dg` and `g_g - A_gd A_dd^-1 g_d`; `None` when
    /// the view's own block is singular.
    pub fn reduced(self) -> Option<(DMatrix<f64>, DVector<f64>)> {
        let (ng, pv) = (self.ng, self.own.len());
        let agg = self.a.view((0, 0), (ng, ng)).into_owned();
        let gg = self.g.rows(0, ng).into_owned();
        if pv == 0 {
            return Some((agg, gg));
        }
        let agd = self.a.view((0, ng), (ng, pv)).into_owned();
        let add = self.a.view((ng, ng), (pv, pv)).into_owned();
        let gd = self.g.rows(ng, pv).into_owned();
        let ch = add.cholesky()?;
        let x = ch.solve(&agd.transpose());
        let y = ch.solve(&gd);
        Some((&agg - &agd * x, &gg - &agd * y))
    }

    /// The view's own columns' Gauss-Newton step given the global columns' step `dg`:
    /// `-A_dd^-1 (g_d + A_dg dg)` (empty without own columns); `None` when the view's
    /// own block is singular.
    pub fn own_step(&self, dg: &DVector<f64>) -> Option<DVector<f64>> {
        let (ng, pv) = (self.ng, self.own.len());
        if pv == 0 {
            return Some(DVector::zeros(0));
        }
        let adg = self.a.view((ng, 0), (pv, ng));
        let add = self.a.view((ng, ng), (pv, pv)).into_owned();
        let rhs = self.g.rows(ng, pv) + adg * dg;
        Some(-add.cholesky()?.solve(&rhs))
    }
}

/// A view whose share of some direction's information exceeds this determines that
/// direction nearly alone: its score there is no sample of the views' scatter (module
/// docs).
const MAX_VIEW_LEVERAGE: f64 = 0.9;

/// The views' scatter `V` of the global parameters from their reduced shares `(M_v,
/// s_v)` (module docs); `None` with fewer than 5 views or when the total is not positive
/// definite. In a direction that one view determines nearly alone (its leverage there
/// above [`MAX_VIEW_LEVERAGE`]) that view's contribution is left out.
pub fn view_scatter(shares: &[(DMatrix<f64>, DVector<f64>)]) -> Option<DMatrix<f64>> {
    let nv = shares.len();
    if nv < 5 {
        return None;
    }
    let ng = shares[0].0.nrows();
    let total = shares
        .iter()
        .fold(DMatrix::zeros(ng, ng), |acc, (m, _)| acc + m);
    // Whitened by the total: N = L L^T, each view's leverage matrix L^-1 M_v L^-T.
    let dsc = DVector::from_fn(ng, |i, _| total[(i, i)].max(1e-300).sqrt());
    let scaled = |m: &DMatrix<f64>| DMatrix::from_fn(ng, ng, |a, b| m[(a, b)] / (dsc[a] * dsc[b]));
    let l = (0.5 * (scaled(&total) + scaled(&total).transpose()))
        .cholesky()?
        .l();
    let li = l.clone().try_inverse()?;
    let mut d = Vec::with_capacity(nv);
    for (m, s) in shares {
        let a = &li * scaled(m) * li.transpose();
        let eig = (0.5 * (&a + a.transpose())).symmetric_eigen();
        // (I - A)^-1/2 L^-1 s over the directions the others determine too.
        let z = &li * DVector::from_fn(ng, |i, _| s[i] / dsc[i]);
        let mut y = DVector::zeros(ng);
        for (lev, u) in eig.eigenvalues.iter().zip(eig.eigenvectors.column_iter()) {
            if *lev < MAX_VIEW_LEVERAGE {
                y += u * (u.dot(&z) / (1.0 - lev.max(0.0)).sqrt());
            }
        }
        let x = li.transpose() * y;
        d.push(DVector::from_fn(ng, |i, _| x[i] / dsc[i]));
    }
    let mut v = DMatrix::zeros(ng, ng);
    for x in &d {
        v += x * x.transpose();
    }
    v.iter().all(|x| x.is_finite()).then_some(v)
}

/// `model` widened to `jack` where that is larger (module docs), and the largest ratio
/// of their variances over every linear combination (1 when the model's is nowhere
/// smaller); `None` when `model` is not positive definite.
pub fn widen(model: &DMatrix<f64>, jack: &DMatrix<f64>) -> Option<(DMatrix<f64>, f64)> {
    let n = model.nrows();
    // Scaled to a unit diagonal first (the numbers mix px, mm and rad).
    let d = DVector::from_fn(n, |i, _| model[(i, i)].max(1e-300).sqrt());
    let scale = |m: &DMatrix<f64>| DMatrix::from_fn(n, n, |a, b| m[(a, b)] / (d[a] * d[b]));
    let cm = scale(model);
    let l = (0.5 * (&cm + cm.transpose())).cholesky()?.l();
    let li = l.clone().try_inverse()?;
    let w = &li * scale(jack) * li.transpose();
    let eig = (0.5 * (&w + w.transpose())).symmetric_eigen();
    let largest = eig.eigenvalues.iter().cloned().fold(1.0, f64::max);
    let lam = DMatrix::from_diagonal(&eig.eigenvalues.map(|x| x.max(1.0)));
    let c = &l * &eig.eigenvectors * lam * eig.eigenvectors.transpose() * l.transpose();
    let out = DMatrix::from_fn(n, n, |a, b| c[(a, b)] * d[a] * d[b]);
    let out = 0.5 * (&out + out.transpose());
    out.iter().all(|x| x.is_finite()).then_some((out, largest))
}

/// `model` (the global parameters' covariance) widened to the scatter of the views'
/// `shares`, and the largest ratio of sigmas; `None` when either cannot be formed.
pub fn widened(
    model: &DMatrix<f64>,
    shares: &[(DMatrix<f64>, DVector<f64>)],
) -> Option<(DMatrix<f64>, f64)> {
    let jack = view_scatter(shares)?;
    let (c, ratio) = widen(model, &jack)?;
    Some((c, ratio.sqrt()))
}
