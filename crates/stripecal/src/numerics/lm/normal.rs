//! The solver's Jacobian storage (dense, or by rows) and its (Huber-weighted) normal
//! equations `J^T W J`, `J^T W r`.

use faer::{Accum, Mat, Par};
use nalgebra::{DMatrix, DVector};

use super::problem::{JacobianRows, LeastSquares};
use crate::error::{Error, Result};

pub(super) fn huber_weight(r: f64, huber: Option<f64>) -> f64 {
    match huber {
        Some(d) if r.abs() > d => d / r.abs(),
        _ => 1.0,
    }
}

pub(super) fn cost_of(r: &[f64], huber: Option<f64>) -> f64 {
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
pub(super) const WEIGHT_TOL: f64 = 1e-3;

/// The solver's Jacobian storage (dense, or by rows) and its normal equations.
pub(super) struct Work {
    m: usize,
    n: usize,
    rows: Option<JacobianRows>,
    jac: Mat<f64>,
    jtj_f: Mat<f64>,
    scratch: Vec<f64>,
}

impl Work {
    pub(super) fn new(m: usize, n: usize, row_width: Option<usize>) -> Self {
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
    pub(super) fn evaluate<P: LeastSquares + ?Sized>(
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
    pub(super) fn rescale(&mut self, f: &[f64], r: &mut [f64]) {
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
    pub(super) fn normal_equations(
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

    /// The leverage of every residual at `r` (see [`LeastSquares::reweight`]): `h_i =
    /// w_i j_i^T N^-1 j_i`, `N = J^T W J` inverted after Jacobi scaling; `None` when `N`
    /// is not positive definite. Dense rows and the dense matrix: `N^-1 J^T` by one
    /// matrix product; sparse rows: each run of rows with the same columns gathers its
    /// block of `N^-1` once.
    pub(super) fn leverages(&mut self, r: &[f64], huber: Option<f64>) -> Option<Vec<f64>> {
        let (jtj, _) = self.normal_equations(r, huber).ok()?;
        let n = self.n;
        let d: Vec<f64> = (0..n)
            .map(|i| 1.0 / jtj[(i, i)].max(1e-300).sqrt())
            .collect();
        let scaled = DMatrix::from_fn(n, n, |a, b| jtj[(a, b)] * d[a] * d[b]);
        let si = scaled.cholesky()?.inverse();
        let inv = DMatrix::from_fn(n, n, |a, b| si[(a, b)] * d[a] * d[b]);
        let wt: Vec<f64> = r.iter().map(|&x| huber_weight(x, huber)).collect();
        let mut h = vec![0.0; self.m];
        let inv_f = Mat::<f64>::from_fn(n, n, |a, b| inv[(a, b)]);
        // `J^T` (n x m) of the dense storages, then `h_i = w_i (J^T)_i . (N^-1 J^T)_i`.
        let dense_t: Option<faer::MatRef<'_, f64>> = match &self.rows {
            Some(rows) if rows.dense => {
                Some(faer::MatRef::from_column_major_slice(&rows.vals, n, self.m))
            }
            Some(_) => None,
            None => Some(self.jac.as_ref().transpose()),
        };
        if let Some(jt) = dense_t {
            let mut x = Mat::<f64>::zeros(n, self.m);
            faer::linalg::matmul::matmul(
                x.as_mut(),
                Accum::Replace,
                inv_f.as_ref(),
                jt,
                1.0,
                Par::Seq,
            );
            for (i, hi) in h.iter_mut().enumerate() {
                *hi = wt[i] * (0..n).map(|k| jt[(k, i)] * x[(k, i)]).sum::<f64>();
            }
        } else if let Some(rows) = &self.rows {
            let w = rows.width;
            let mut block = vec![0.0; w * w];
            let mut cur: Option<&[usize]> = None;
            for (i, hi) in h.iter_mut().enumerate() {
                let (c, v) = rows.row(i);
                if cur != Some(c) {
                    for (a, &ca) in c.iter().enumerate() {
                        for (b, &cb) in c.iter().enumerate() {
                            block[a * w + b] = inv[(ca, cb)];
                        }
                    }
                    cur = Some(c);
                }
                let mut acc = 0.0;
                for (a, &va) in v.iter().enumerate() {
                    if va != 0.0 {
                        let brow = &block[a * w..(a + 1) * w];
                        acc += va * brow.iter().zip(v).map(|(x, y)| x * y).sum::<f64>();
                    }
                }
                *hi = wt[i] * acc;
            }
        }
        h.iter().all(|x| x.is_finite()).then_some(h)
    }
}
