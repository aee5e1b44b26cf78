//! What the adjustment's normal equations say per view: each view's share reduced to
//! the global columns, and the image rows' response to flange motions.

use nalgebra::DMatrix;

use super::{JointProblem, ReducedShare};
use crate::calib::clustered::ViewShare;
use crate::error::Result;
use crate::numerics::lm::{JacobianRows, LeastSquares};

impl JointProblem<'_> {
    /// Each view's share of the normal equations at `p`, reduced to the global columns
    /// by eliminating its own per-view columns: `(M_v, s_v)` with `M_v = A_gg - A_gd
    /// A_dd^-1 A_dg` and `s_v = g_g - A_gd A_dd^-1 g_d` over its rows (its image rows
    /// and prior rows, weighted; `A = J^T J`, `g = J^T r`). Their sums are the reduced
    /// normal equations; `None` when a view's own block is singular.
    pub fn view_shares(&self, p: &[f64]) -> Result<Option<Vec<ReducedShare>>> {
        let acc = self.view_normals_by_view(p)?;
        Ok(acc.into_iter().map(ViewShare::reduced).collect())
    }

    /// Each view's share of the normal equations at `p` over the global columns and its
    /// own per-view columns (its image rows and prior rows, weighted), not reduced.
    pub fn view_normals_by_view(&self, p: &[f64]) -> Result<Vec<ViewShare>> {
        let (mut r, mut rows) = self.empty_rows();
        self.residuals_and_jacobian_rows(p, &mut r, &mut rows)?;
        Ok(self.view_normals_of_rows(&r, &rows, &self.share_runs(&rows)))
    }

    /// Zeroed residuals and Jacobian rows of the problem's size, for
    /// [`LeastSquares::residuals_and_jacobian_rows`] and [`Self::view_normals_of_rows`].
    pub fn empty_rows(&self) -> (Vec<f64>, JacobianRows) {
        let (n, m) = (self.num_params(), self.num_residuals());
        (vec![0.0; m], JacobianRows::new(m, self.row_width(), n))
    }

    /// The stretches `(view, first, end)` of rows of one view with the same columns in
    /// `rows` (an evaluation's: the columns are the layout's, the same at every
    /// evaluation).
    pub fn share_runs(&self, rows: &JacobianRows) -> Vec<(usize, usize, usize)> {
        self.view_runs
            .iter()
            .flat_map(|&(view, i0, i1)| {
                rows.runs(i0..i1)
                    .into_iter()
                    .map(move |(a, b)| (view, a, b))
            })
            .collect()
    }

    /// Each view's share of the normal equations ([`Self::view_normals_by_view`]) from
    /// residuals `r` and Jacobian rows `rows` evaluated already, `runs` their
    /// [`Self::share_runs`].
    pub fn view_normals_of_rows(
        &self,
        r: &[f64],
        rows: &JacobianRows,
        runs: &[(usize, usize, usize)],
    ) -> Vec<ViewShare> {
        let ng = self.layout.num_global();
        let pv = self.layout.per_view_len();
        let w = self.row_width();
        let nv = self.terms.a.len();
        let mut acc: Vec<ViewShare> = (0..nv)
            .map(|v| ViewShare::new(ng, ng + v * pv..ng + (v + 1) * pv))
            .collect();
        // A run's rows share their columns (the global ones and the view's): one
        // product per stretch of rows with the same columns.
        for &(view, a, b) in runs {
            let jt = faer::MatRef::from_column_major_slice(rows.values(a, b), w, b - a);
            acc[view].add_rows(rows.row(a).0, jt, &r[a..b]);
        }
        acc
    }

    /// `J^T J_k` (n x p) at `p`: the gradient of the weighted image rows' sum of squares'
    /// linear term along each of `p` flange motions, `twists[view][k]` the view's flange
    /// perturbation `(w, v)` per unit of motion `k` in its correction's frame (the image
    /// rows reach them through the view's correction columns). `None` without the
    /// robot-pose corrections.
    pub fn flange_response(
        &self,
        p: &[f64],
        twists: &[Vec<[f64; 6]>],
    ) -> Result<Option<DMatrix<f64>>> {
        if !self.robot {
            return Ok(None);
        }
        let (n, m) = (self.num_params(), self.num_residuals());
        let ng = self.layout.num_global();
        let pv = self.layout.per_view_len();
        let w = self.row_width();
        let k = twists.first().map_or(0, |t| t.len());
        let mut r = vec![0.0; m];
        let mut rows = JacobianRows::new(m, w, n);
        self.residuals_and_jacobian_rows(p, &mut r, &mut rows)?;
        let mut g = DMatrix::zeros(n, k);
        let po = self.prior_offset();
        // per row: its correction columns' (index, value) in the row's order, and the
        // row's value along each motion
        let (mut corr, mut along): (Vec<(usize, f64)>, Vec<f64>) = (Vec::new(), Vec::new());
        for &(view, i0, i1) in self.view_runs.iter().filter(|r| r.1 < po) {
            let Some(tw) = twists.get(view) else { continue };
            let own = ng + view * pv;
            for i in i0..i1 {
                let (cols, vals) = rows.row(i);
                // The row's value along each motion: its correction columns times the
                // motion's twist.
                corr.clear();
                corr.extend(
                    cols.iter()
                        .zip(vals)
                        .filter(|(c, _)| (own..own + 6).contains(*c))
                        .map(|(c, v)| (c - own, *v)),
                );
                along.clear();
                along.extend((0..k).map(|j| corr.iter().map(|&(q, v)| v * tw[j][q]).sum::<f64>()));
                for (c, v) in cols.iter().zip(vals) {
                    if *v == 0.0 {
                        continue;
                    }
                    for (j, a) in along.iter().enumerate() {
                        g[(*c, j)] += v * a;
                    }
                }
            }
        }
        Ok(Some(g))
    }
}
