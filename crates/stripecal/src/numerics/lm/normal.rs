//! The solver's Jacobian storage (dense, or by rows) and its (Huber-weighted) normal
//! equations `J^T W J`, `J^T W r`.

use std::ops::Range;

use faer::linalg::solvers::DenseSolveCore;
use faer::{Accum, Mat, Par};
use nalgebra::{DMatrix, DVector};

use super::problem::{JacobianRows, LeastSquares};
use super::schur::{Blocks, InverseBlocks};
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

/// Normal equations `J^T W J`, `J^T W r` kept from one evaluation to the next: sparse
/// rows write only the blocks of their runs' columns, and only those are zeroed before the
/// next accumulation (the matrix has `(ng + nv pv)^2` entries, the blocks about
/// `ng^2 + nv (2 ng + pv) pv`: zeroing and checking all of it grew as the views squared).
#[derive(Debug, Clone, Default)]
pub(super) struct Normal {
    pub jtj: DMatrix<f64>,
    pub g: DVector<f64>,
    /// The column sets whose blocks were written since the matrix was last zero
    /// everywhere; `None`: any entry may be nonzero.
    written: Option<Vec<Vec<usize>>>,
}

impl Normal {
    /// Zero normal equations of `n` parameters, when they are not that size.
    fn sized(&mut self, n: usize) {
        if self.jtj.nrows() != n || self.jtj.ncols() != n || self.g.len() != n {
            *self = Normal {
                jtj: DMatrix::zeros(n, n),
                g: DVector::zeros(n),
                written: Some(Vec::new()),
            };
        }
    }

    /// Zero everywhere, by the blocks written since it last was.
    fn zeroed(&mut self) {
        match self.written.take() {
            None => self.jtj.fill(0.0),
            Some(sets) => {
                for c in &sets {
                    for &a in c {
                        for &b in c {
                            self.jtj[(a, b)] = 0.0;
                        }
                    }
                }
            }
        }
        self.g.fill(0.0);
        self.written = Some(Vec::new());
    }

    /// Whether every entry is finite (the written blocks, when known).
    fn finite(&self) -> bool {
        let blocks = match &self.written {
            None => self.jtj.iter().all(|x| x.is_finite()),
            Some(sets) => sets.iter().all(|c| {
                c.iter()
                    .all(|&a| c.iter().all(|&b| self.jtj[(a, b)].is_finite()))
            }),
        };
        blocks && self.g.iter().all(|x| x.is_finite())
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
    /// Sparse rows: the runs of rows with the same columns at the last evaluation.
    runs: Vec<(usize, usize)>,
    /// The leverages' product buffer.
    lev_buf: Mat<f64>,
    /// The leverages' normal equations.
    lev_normal: Normal,
    /// The problem's own normal equations at the last evaluation (no Jacobian stored;
    /// [`LeastSquares::has_normal_equations`]).
    fused: Option<(DMatrix<f64>, DVector<f64>)>,
    fused_mode: bool,
    /// The per-view column blocks of sparse rows ([`Blocks`]).
    blocks: Option<Blocks>,
}

impl Work {
    pub(super) fn new(m: usize, n: usize, row_width: Option<usize>) -> Self {
        Work {
            m,
            n,
            rows: row_width.map(|w| JacobianRows::new(m, w, n)),
            fused: None,
            fused_mode: false,
            jac: if row_width.is_some() {
                Mat::zeros(0, 0)
            } else {
                Mat::zeros(m, n)
            },
            // Allocated by the first product of dense storage.
            jtj_f: Mat::zeros(0, 0),
            scratch: Vec::new(),
            runs: Vec::new(),
            lev_buf: Mat::zeros(0, 0),
            lev_normal: Normal::default(),
            blocks: None,
        }
    }

    /// With the per-view column blocks `blocks` (the leverages of sparse rows then take
    /// the inverse's blocks, [`InverseBlocks`], instead of the dense inverse).
    pub(super) fn with_blocks(self, blocks: Option<Blocks>) -> Self {
        Work { blocks, ..self }
    }

    /// The storage of a problem that forms its own normal equations (nothing of size
    /// `m x n`).
    pub(super) fn fused(m: usize, n: usize) -> Self {
        Work {
            rows: None,
            jac: Mat::zeros(0, 0),
            fused_mode: true,
            ..Work::new(m, n, Some(n))
        }
    }

    /// Residuals and Jacobian (or the problem's normal equations) at `p`.
    pub(super) fn evaluate<P: LeastSquares + ?Sized>(
        &mut self,
        problem: &P,
        p: &[f64],
        r: &mut [f64],
    ) -> Result<()> {
        if self.fused_mode {
            self.fused = Some(problem.residuals_and_normal_equations(p, r)?);
            if r.iter().any(|x| !x.is_finite()) {
                return Err(Error::Degenerate("residuals are not finite".into()));
            }
            return Ok(());
        }
        match &mut self.rows {
            Some(rows) => {
                rows.clear();
                problem.residuals_and_jacobian_rows(p, r, rows)?;
                if !rows.dense {
                    self.runs = rows.runs(0..rows.len());
                }
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
        // The problem's own normal equations cannot be re-weighted here: none then,
        // and `normal_equations` says why.
        self.fused = None;
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

    /// `(J^T W J, J^T W r)` into `out`, `W` the Huber IRLS weights at `r` (identity
    /// without Huber).
    pub(super) fn normal_equations(
        &mut self,
        r: &[f64],
        huber: Option<f64>,
        out: &mut Normal,
    ) -> Result<()> {
        let (m, n) = (self.m, self.n);
        let not_finite = || Error::Degenerate("Jacobian is not finite".into());
        if self.fused_mode {
            let (jtj, g) = self.fused.clone().ok_or_else(|| {
                Error::InvalidInput(
                    "a problem that forms its own normal equations cannot re-weight its \
                     residuals"
                        .into(),
                )
            })?;
            *out = Normal {
                jtj,
                g,
                written: None,
            };
            return if out.finite() {
                Ok(())
            } else {
                Err(not_finite())
            };
        }
        out.sized(n);
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
                    out.zeroed();
                    let (sw, rw) = (&sw[..], &rw[..]);
                    accumulate_runs(rows, &self.runs, (sw, rw), huber, &mut self.scratch, out);
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
            if self.jtj_f.nrows() != n {
                self.jtj_f = Mat::zeros(n, n);
            }
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
            // Every entry written.
            out.written = None;
            for a in 0..n {
                out.g[a] = gf[(a, 0)];
                for b in 0..n {
                    out.jtj[(a, b)] = self.jtj_f[(a, b)];
                }
            }
        }
        if out.finite() {
            Ok(())
        } else {
            Err(not_finite())
        }
    }

    /// The leverages of the residuals in `wanted` (row ranges; the others 0) at `r` (see
    /// [`LeastSquares::reweight`]): `h_i = w_i j_i^T N^-1 j_i`, `N = J^T W J` inverted
    /// after Jacobi scaling (faer's Cholesky); `None` when `N` is not positive definite.
    /// Dense rows and the dense matrix: `N^-1 J^T` by one matrix product per range;
    /// sparse rows: one product per run of rows with the same columns, with its block of
    /// `N^-1`.
    pub(super) fn leverages(
        &mut self,
        r: &[f64],
        huber: Option<f64>,
        wanted: &[Range<usize>],
    ) -> Option<Vec<f64>> {
        if self.fused_mode {
            return None;
        }
        let mut normal = std::mem::take(&mut self.lev_normal);
        let done = self.normal_equations(r, huber, &mut normal);
        self.lev_normal = normal;
        done.ok()?;
        let jtj = &self.lev_normal.jtj;
        let n = self.n;
        let d: Vec<f64> = (0..n)
            .map(|i| 1.0 / jtj[(i, i)].max(1e-300).sqrt())
            .collect();
        let inv = match (&self.rows, &self.blocks) {
            (Some(rows), Some(b)) if !rows.dense => {
                let si = InverseBlocks::new(|a, b| jtj[(a, b)] * d[a] * d[b], b)?;
                Inverse::Blocks(si, d)
            }
            _ => {
                let scaled = Mat::<f64>::from_fn(n, n, |a, b| jtj[(a, b)] * d[a] * d[b]);
                let si = scaled.llt(faer::Side::Lower).ok()?.inverse();
                Inverse::Dense(Mat::<f64>::from_fn(n, n, |a, b| si[(a, b)] * d[a] * d[b]))
            }
        };
        let mut h = vec![0.0; self.m];
        let wanted: Vec<Range<usize>> = wanted
            .iter()
            .map(|g| g.start.min(self.m)..g.end.min(self.m))
            .filter(|g| !g.is_empty())
            .collect();
        // `J^T` (n x m) of the dense storages, then `h_i = w_i (J^T)_i . (N^-1 J^T)_i`.
        let dense_t: Option<faer::MatRef<'_, f64>> = match &self.rows {
            Some(rows) if rows.dense => {
                Some(faer::MatRef::from_column_major_slice(&rows.vals, n, self.m))
            }
            Some(_) => None,
            None => Some(self.jac.as_ref().transpose()),
        };
        // The rows i0..i1 with their J^T (w x len) and `N^-1` restricted to their
        // columns.
        // One buffer for `N^-1 J^T` of every range and run, kept between calls.
        let mut buf = std::mem::replace(&mut self.lev_buf, Mat::zeros(0, 0));
        let mut fill = |i0: usize, jt: faer::MatRef<'_, f64>, block: faer::MatRef<'_, f64>| {
            if buf.nrows() < jt.nrows() || buf.ncols() < jt.ncols() {
                buf = Mat::zeros(jt.nrows().max(buf.nrows()), jt.ncols().max(buf.ncols()));
            }
            faer::linalg::matmul::matmul(
                buf.as_mut().submatrix_mut(0, 0, jt.nrows(), jt.ncols()),
                Accum::Replace,
                block,
                jt,
                1.0,
                Par::Seq,
            );
            let x = buf.as_ref().submatrix(0, 0, jt.nrows(), jt.ncols());
            for (k, hi) in h[i0..i0 + jt.ncols()].iter_mut().enumerate() {
                *hi = huber_weight(r[i0 + k], huber) * dot(jt.col(k), x.col(k));
            }
        };
        if let (Some(jt), Inverse::Dense(inv)) = (dense_t, &inv) {
            for g in &wanted {
                fill(g.start, jt.subcols(g.start, g.len()), inv.as_ref());
            }
        } else if let Some(rows) = &self.rows {
            let w = rows.width;
            for &(i0, i1) in &self.runs {
                let c = rows.row(i0).0;
                let mut block: Option<Mat<f64>> = None;
                for g in &wanted {
                    let (a, b) = (i0.max(g.start), i1.min(g.end));
                    if a >= b {
                        continue;
                    }
                    if block.is_none() {
                        block = Some(inv.block(c)?);
                    }
                    let block = block.as_ref()?;
                    let jt =
                        faer::MatRef::from_column_major_slice(&rows.vals[a * w..b * w], w, b - a);
                    fill(a, jt, block.as_ref());
                }
            }
        }
        self.lev_buf = buf;
        h.iter().all(|x| x.is_finite()).then_some(h)
    }
}

/// `N^-1`, dense or by the blocks of the per-view columns (Jacobi-scaled, with the
/// scaling `d`).
enum Inverse {
    Dense(Mat<f64>),
    Blocks(InverseBlocks, Vec<f64>),
}

impl Inverse {
    /// The inverse restricted to columns `c` (a row's); `None` when they span two views'
    /// blocks.
    fn block(&self, c: &[usize]) -> Option<Mat<f64>> {
        let w = c.len();
        match self {
            Inverse::Dense(inv) => Some(Mat::<f64>::from_fn(w, w, |p, q| inv[(c[p], c[q])])),
            Inverse::Blocks(si, d) => {
                let mut out = Mat::<f64>::zeros(w, w);
                for p in 0..w {
                    for q in 0..w {
                        out[(p, q)] = si.at(c[p], c[q])? * d[c[p]] * d[c[q]];
                    }
                }
                Some(out)
            }
        }
    }
}

/// `a . b` of two columns.
fn dot(a: faer::ColRef<'_, f64>, b: faer::ColRef<'_, f64>) -> f64 {
    match (a.try_as_col_major(), b.try_as_col_major()) {
        (Some(a), Some(b)) => a
            .as_slice()
            .iter()
            .zip(b.as_slice())
            .map(|(x, y)| x * y)
            .sum(),
        _ => a.iter().zip(b.iter()).map(|(x, y)| x * y).sum(),
    }
}

/// Sparse rows' share of the normal equations added to `(jtj, g)`: runs of rows with
/// the same columns (a view's) are one small product each, `sqrt(W) J` from the
/// weights' square roots `sw` (applied when `huber`), `sqrt(W) r` given as `rw`.
fn accumulate_runs(
    rows: &JacobianRows,
    runs: &[(usize, usize)],
    (sw, rw): (&[f64], &[f64]),
    huber: Option<f64>,
    scratch: &mut Vec<f64>,
    out: &mut Normal,
) {
    let w = rows.width;
    // Runs of rows with the same columns (a view's) are one small product each: their
    // values are the run's J^T stored column-major (w x len); the w x w block is
    // scattered into the n x n matrix.
    let n = out.g.len();
    let written = out.written.get_or_insert_with(Vec::new);
    let (jtj, g) = (&mut out.jtj, &mut out.g);
    let acc = jtj.as_mut_slice();
    let mut block = Mat::<f64>::zeros(w, w);
    let mut gb = Mat::<f64>::zeros(w, 1);
    for &(i0, i1) in runs {
        let len = i1 - i0;
        let raw = &rows.vals[i0 * w..i1 * w];
        let vals: &[f64] = if huber.is_some() {
            scratch.clear();
            scratch.extend_from_slice(raw);
            for (v, s) in scratch.chunks_exact_mut(w).zip(&sw[i0..i1]) {
                v.iter_mut().for_each(|x| *x *= s);
            }
            scratch
        } else {
            raw
        };
        let jt = faer::MatRef::from_column_major_slice(vals, w, len);
        let rv = faer::MatRef::from_column_major_slice(&rw[i0..i1], len, 1);
        faer::linalg::matmul::matmul(
            block.as_mut(),
            Accum::Replace,
            jt,
            jt.transpose(),
            1.0,
            Par::Seq,
        );
        faer::linalg::matmul::matmul(gb.as_mut(), Accum::Replace, jt, rv, 1.0, Par::Seq);
        let cols = rows.row(i0).0;
        if written.last().is_none_or(|c| c[..] != *cols) {
            written.push(cols.to_vec());
        }
        for (a, &ca) in cols.iter().enumerate() {
            g[ca] += gb[(a, 0)];
            let col = &mut acc[ca * n..(ca + 1) * n];
            for (b, &cb) in cols.iter().enumerate() {
                col[cb] += block[(a, b)];
            }
        }
    }
}
