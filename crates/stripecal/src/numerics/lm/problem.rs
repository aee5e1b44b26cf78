//! What the solver minimises: the [`LeastSquares`] problem trait and the row storage of
//! its Jacobian ([`JacobianRows`]).

use faer::MatMut;

use crate::error::{Error, Result};

/// What [`LeastSquares::reweight`] is given to compute leverages: the row ranges wanted
/// in, every residual's leverage out (0 outside the ranges; `None` when the normal
/// matrix is not positive definite).
pub type Leverages<'a> = dyn FnMut(&[std::ops::Range<usize>]) -> Option<Vec<f64>> + 'a;

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
    ///
    /// `leverages(rows)` computes, when called, the leverages of the residuals in the
    /// row ranges `rows` (the others are returned as 0) at the current point and
    /// weights: `h_i = w_i j_i^T N^-1 j_i` with `N = J^T W J` (`W` the Huber weights
    /// `w_i`, 1 without Huber), the diagonal of the hat matrix. The redundancy of a group
    /// g of residuals is then `r_g = m_g - sum_g h_i = m_g - tr(N^-1 N_g)` (Förstner);
    /// the leverages of all residuals add up to `n`, so one group's may be left out and
    /// taken as the rest. It costs about one normal-equation product and one inverse,
    /// plus a product per requested row; `None` when `N` is not positive definite.
    fn reweight(&self, _r: &[f64], _leverages: &mut Leverages<'_>) -> Option<Vec<f64>> {
        None
    }
    /// `Some(w)` when every Jacobian row has at most `w` non-zeros and the problem
    /// provides them by [`LeastSquares::residuals_and_jacobian_rows`] (the solver then
    /// never forms the `m x n` Jacobian matrix; `w = n`: dense rows, see
    /// [`JacobianRows`]); `None` (default): the dense matrix.
    fn jacobian_row_width(&self) -> Option<usize> {
        None
    }
    /// `Some((ng, pv))` when the columns are `ng` global ones followed by one block of
    /// `pv` per view and every residual depends on the global columns and at most one
    /// view's block: the solver then eliminates the blocks view by view (the Schur
    /// complement; the same steps and leverages to rounding, in time linear in the
    /// number of views). Default: `None` (dense factorisations).
    fn view_blocks(&self) -> Option<(usize, usize)> {
        None
    }
    /// `true` when the problem accumulates its normal equations itself
    /// ([`LeastSquares::residuals_and_normal_equations`]): for many residuals over few
    /// parameters the solver then never stores the Jacobian. Such a problem must not
    /// re-weight ([`LeastSquares::reweight`] gets no leverages), and with a Huber
    /// threshold the solver uses the Jacobian instead. Default: `false`.
    fn has_normal_equations(&self) -> bool {
        false
    }
    /// Residuals into `r` and `(J^T J, J^T r)` at `p` (unweighted). Only called when
    /// [`LeastSquares::has_normal_equations`] is `true`.
    fn residuals_and_normal_equations(
        &self,
        _p: &[f64],
        _r: &mut [f64],
    ) -> Result<(nalgebra::DMatrix<f64>, nalgebra::DVector<f64>)> {
        Err(Error::InvalidInput(
            "this least-squares problem has no normal equations of its own".into(),
        ))
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
    pub(super) width: usize,
    pub(super) dense: bool,
    /// Sparse: the columns of every row; dense: `0..width` once.
    pub(super) cols: Vec<usize>,
    pub(super) vals: Vec<f64>,
    /// Whether the columns were written since the rows were made or cleared
    /// ([`Self::columns_written`]).
    cols_written: bool,
}

impl JacobianRows {
    /// `m` zero rows of `width` pairs; dense when `width == n`.
    ///
    /// # Panics
    ///
    /// When `m * width` overflows a `usize` (in every build profile).
    pub fn new(m: usize, width: usize, n: usize) -> Self {
        let dense = width == n;
        let len = m
            .checked_mul(width)
            .unwrap_or_else(|| panic!("{m} Jacobian rows of width {width} overflow usize"));
        JacobianRows {
            width,
            dense,
            cols: if dense {
                (0..width).collect()
            } else {
                vec![0; len]
            },
            vals: vec![0.0; len],
            cols_written: false,
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
    /// Whether an evaluation wrote the columns since the rows were made or cleared
    /// ([`Self::set_columns_written`]): a problem whose rows' columns are the same at
    /// every evaluation (a fixed layout) need not write them again into rows it
    /// evaluated before.
    pub fn columns_written(&self) -> bool {
        self.cols_written
    }
    /// Records that the columns were written ([`Self::columns_written`]).
    pub fn set_columns_written(&mut self) {
        self.cols_written = true;
    }
    /// Zero-fills every row.
    pub fn clear(&mut self) {
        self.cols_written = false;
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
    /// The values of rows `i0..i1`, row after row (`width` each): the rows' `J^T`
    /// stored column-major (`width x (i1 - i0)`).
    pub fn values(&self, i0: usize, i1: usize) -> &[f64] {
        let w = self.width;
        &self.vals[i0 * w..i1 * w]
    }
    /// The runs `(first, end)` of consecutive rows within `rows` that have the same
    /// columns.
    pub fn runs(&self, rows: std::ops::Range<usize>) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        let mut i0 = rows.start;
        while i0 < rows.end {
            let c = self.row(i0).0;
            let mut i1 = i0 + 1;
            while i1 < rows.end && self.row(i1).0 == c {
                i1 += 1;
            }
            out.push((i0, i1));
            i0 = i1;
        }
        out
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
