//! The per-view columns eliminated block by block (the Schur complement): for problems
//! whose columns are `ng` global ones followed by one block of `pv` columns per view,
//! each row touching the global columns and at most one view's block
//! ([`LeastSquares::view_blocks`](super::LeastSquares::view_blocks)), the normal matrix
//! has no entries between two views' blocks. A damped step and the blocks of the inverse
//! that the leverages need then cost a small solve per view and one `ng x ng` one,
//! linear in the number of views, where the dense factorisation of all `ng + nv pv`
//! columns is cubic in it. The same numbers as the dense solves to rounding.

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::{DenseSolveCore, Solve};
use faer::{Accum, Mat, Par, Side};
use nalgebra::{DMatrix, DVector};

/// The column layout: `ng` global columns, then `nv` blocks of `pv`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Blocks {
    ng: usize,
    pv: usize,
    nv: usize,
}

impl Blocks {
    /// The layout of `n` columns, `ng` global and blocks of `pv`; `None` when they do not
    /// divide so or there are no per-view columns.
    pub(super) fn of(n: usize, (ng, pv): (usize, usize)) -> Option<Blocks> {
        (pv > 0 && n > ng && (n - ng) % pv == 0).then_some(Blocks {
            ng,
            pv,
            nv: (n - ng) / pv,
        })
    }

    /// The view whose block holds column `c` (`None`: a global column).
    fn view_of(&self, c: usize) -> Option<usize> {
        (c >= self.ng).then(|| (c - self.ng) / self.pv)
    }
}

/// One view's block eliminated: `D_v`'s Cholesky factor and `X_v = D_v^-1 A_vg`.
struct Eliminated {
    llt: faer::linalg::solvers::Llt<f64>,
    x: Mat<f64>,
}

/// Every view's block of `a` (plus `damp` on the diagonal) eliminated, and the Schur
/// complement `S = A_gg - sum_v A_gv D_v^-1 A_vg`; `None` when a block is not positive
/// definite.
fn eliminate(
    a: impl Fn(usize, usize) -> f64,
    damp: impl Fn(usize) -> f64,
    b: &Blocks,
) -> Option<(Mat<f64>, Vec<Eliminated>)> {
    let ng = b.ng;
    let mut s = Mat::<f64>::from_fn(ng, ng, |i, j| a(i, j) + if i == j { damp(i) } else { 0.0 });
    let mut out = Vec::with_capacity(b.nv);
    for v in 0..b.nv {
        let o = ng + v * b.pv;
        let d = Mat::<f64>::from_fn(b.pv, b.pv, |i, j| {
            a(o + i, o + j) + if i == j { damp(o + i) } else { 0.0 }
        });
        let llt = d.llt(Side::Lower).ok()?;
        let avg = Mat::<f64>::from_fn(b.pv, ng, |i, j| a(o + i, j));
        let mut x = avg.clone();
        llt.solve_in_place(x.as_mut());
        matmul(
            s.as_mut(),
            Accum::Add,
            avg.transpose(),
            x.as_ref(),
            -1.0,
            Par::Seq,
        );
        out.push(Eliminated { llt, x });
    }
    Some((s, out))
}

/// The solution `x` of `(A + diag(damp)) x = rhs` (`A` the normal matrix, `b` its
/// layout; module docs); `None` when the damped matrix is not positive definite.
pub(super) fn solve(
    a: &DMatrix<f64>,
    damp: &[f64],
    rhs: &[f64],
    b: &Blocks,
) -> Option<DVector<f64>> {
    let ng = b.ng;
    let (s, views) = eliminate(|i, j| a[(i, j)], |i| damp[i], b)?;
    // The reduced right-hand side `b_g - sum_v A_gv D_v^-1 b_v` (`X_v^T b_v`, `A_vv`
    // symmetric).
    let mut bg = Mat::<f64>::from_fn(ng, 1, |i, _| rhs[i]);
    for (v, e) in views.iter().enumerate() {
        let o = ng + v * b.pv;
        let bv = Mat::<f64>::from_fn(b.pv, 1, |i, _| rhs[o + i]);
        matmul(
            bg.as_mut(),
            Accum::Add,
            e.x.transpose(),
            bv.as_ref(),
            -1.0,
            Par::Seq,
        );
    }
    let xg = s.llt(Side::Lower).ok()?.solve(bg);
    let mut out = DVector::<f64>::zeros(ng + b.nv * b.pv);
    for i in 0..ng {
        out[i] = xg[(i, 0)];
    }
    // Back-substitution: `x_v = D_v^-1 b_v - X_v x_g`.
    for (v, e) in views.iter().enumerate() {
        let o = ng + v * b.pv;
        let mut xv = Mat::<f64>::from_fn(b.pv, 1, |i, _| rhs[o + i]);
        e.llt.solve_in_place(xv.as_mut());
        matmul(
            xv.as_mut(),
            Accum::Add,
            e.x.as_ref(),
            xg.as_ref(),
            -1.0,
            Par::Seq,
        );
        for i in 0..b.pv {
            out[o + i] = xv[(i, 0)];
        }
    }
    Some(out)
}

/// The blocks of `A^-1` within the global columns and one view's (module docs): `G =
/// S^-1`, per view `-X_v G` and `D_v^-1 + X_v G X_v^T`; entries between two views'
/// blocks are not held.
pub(super) struct InverseBlocks {
    layout: Blocks,
    gg: Mat<f64>,
    /// Per view: the rows of its columns against the global ones (`pv x ng`) and
    /// against its own (`pv x pv`).
    views: Vec<(Mat<f64>, Mat<f64>)>,
}

impl InverseBlocks {
    /// The blocks of `a`'s inverse (`a` symmetric, laid out as `b`); `None` when it is
    /// not positive definite.
    pub(super) fn new(a: impl Fn(usize, usize) -> f64, b: &Blocks) -> Option<Self> {
        let (s, views) = eliminate(a, |_| 0.0, b)?;
        let gg = s.llt(Side::Lower).ok()?.inverse();
        let views = views
            .into_iter()
            .map(|e| {
                let mut vg = Mat::<f64>::zeros(b.pv, b.ng);
                matmul(
                    vg.as_mut(),
                    Accum::Replace,
                    e.x.as_ref(),
                    gg.as_ref(),
                    -1.0,
                    Par::Seq,
                );
                let mut vv = e.llt.inverse();
                matmul(
                    vv.as_mut(),
                    Accum::Add,
                    vg.as_ref(),
                    e.x.transpose(),
                    -1.0,
                    Par::Seq,
                );
                (vg, vv)
            })
            .collect();
        Some(InverseBlocks {
            layout: *b,
            gg,
            views,
        })
    }

    /// Entry `(i, j)` of the inverse; `None` between two views' blocks.
    pub(super) fn at(&self, i: usize, j: usize) -> Option<f64> {
        let b = &self.layout;
        Some(match (b.view_of(i), b.view_of(j)) {
            (None, None) => self.gg[(i, j)],
            (Some(v), None) => self.views[v].0[(i - b.ng - v * b.pv, j)],
            (None, Some(v)) => self.views[v].0[(j - b.ng - v * b.pv, i)],
            (Some(v), Some(w)) if v == w => {
                let o = b.ng + v * b.pv;
                self.views[v].1[(i - o, j - o)]
            }
            _ => return None,
        })
    }
}

/// The whole inverse of `a` (symmetric, laid out as `b`) by the blocks: [`InverseBlocks`]'s
/// blocks and, between views `v` and `w`, `X_v G X_w^T` (one `n_d x ng` by `ng x n_d`
/// product for all pairs), where the dense inverse factors all `ng + nv pv` columns;
/// `None` when `a` is not positive definite.
pub(super) fn inverse(a: impl Fn(usize, usize) -> f64, b: &Blocks) -> Option<DMatrix<f64>> {
    let (s, views) = eliminate(a, |_| 0.0, b)?;
    let (ng, pv) = (b.ng, b.pv);
    let n = ng + b.nv * pv;
    let gg = s.llt(Side::Lower).ok()?.inverse();
    // X (n_d x ng) stacked over the views, and -X G (the blocks against the global
    // columns).
    let x = Mat::<f64>::from_fn(n - ng, ng, |i, j| views[i / pv].x[(i % pv, j)]);
    let mut xg = Mat::<f64>::zeros(n - ng, ng);
    matmul(
        xg.as_mut(),
        Accum::Replace,
        x.as_ref(),
        gg.as_ref(),
        -1.0,
        Par::Seq,
    );
    // X G X^T, then each view's D_v^-1 on its diagonal block.
    let mut dd = Mat::<f64>::zeros(n - ng, n - ng);
    matmul(
        dd.as_mut(),
        Accum::Replace,
        xg.as_ref(),
        x.transpose(),
        -1.0,
        Par::Seq,
    );
    for (v, e) in views.iter().enumerate() {
        let inv = e.llt.inverse();
        for i in 0..pv {
            for j in 0..pv {
                dd[(v * pv + i, v * pv + j)] += inv[(i, j)];
            }
        }
    }
    Some(DMatrix::from_fn(n, n, |i, j| match (i < ng, j < ng) {
        (true, true) => gg[(i, j)],
        (false, true) => xg[(i - ng, j)],
        (true, false) => xg[(j - ng, i)],
        // symmetric to rounding: the lower triangle's entry on both sides
        (false, false) => dd[(i.max(j) - ng, i.min(j) - ng)],
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::linalg::solvers::DenseSolveCore;

    /// A symmetric positive definite normal matrix with 5 global columns and 4 views
    /// of 3 (no entries between two views' blocks): `J^T J` of block-sparse rows.
    fn normal_matrix() -> (DMatrix<f64>, Blocks) {
        let b = Blocks::of(17, (5, 3)).unwrap();
        let mut a = DMatrix::<f64>::zeros(17, 17);
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for v in 0..4 {
            for _ in 0..12 {
                let cols: Vec<usize> = (0..5).chain(5 + 3 * v..8 + 3 * v).collect();
                let vals: Vec<f64> = cols.iter().map(|_| next()).collect();
                for (x, &cx) in cols.iter().enumerate() {
                    for (y, &cy) in cols.iter().enumerate() {
                        a[(cx, cy)] += vals[x] * vals[y];
                    }
                }
            }
        }
        (a, b)
    }

    #[test]
    fn block_solve_and_inverse_blocks_match_the_dense_ones() {
        let (a, b) = normal_matrix();
        let damp: Vec<f64> = (0..17).map(|i| 0.1 * a[(i, i)]).collect();
        let rhs: Vec<f64> = (0..17).map(|i| (i as f64 * 0.7).sin()).collect();
        let x = solve(&a, &damp, &rhs, &b).unwrap();
        let mut ad = a.clone();
        for (i, d) in damp.iter().enumerate() {
            ad[(i, i)] += d;
        }
        let xd = ad
            .cholesky()
            .unwrap()
            .solve(&DVector::from_column_slice(&rhs));
        assert!((&x - &xd).amax() <= 1e-12 * xd.amax(), "{x} {xd}");
        let inv = InverseBlocks::new(|i, j| a[(i, j)], &b).unwrap();
        let dense = dense_inverse(&a);
        let scale = (0..17).map(|i| dense[(i, i)]).fold(0.0f64, f64::max);
        for i in 0..17 {
            for j in 0..17 {
                match inv.at(i, j) {
                    Some(v) => assert!((v - dense[(i, j)]).abs() <= 1e-12 * scale, "{i} {j}"),
                    None => assert!(b.view_of(i).is_some() && b.view_of(i) != b.view_of(j)),
                }
            }
        }
    }

    /// The test matrix's inverse by a dense Cholesky factorisation (the reference).
    fn dense_inverse(a: &DMatrix<f64>) -> Mat<f64> {
        Mat::<f64>::from_fn(17, 17, |i, j| a[(i, j)])
            .llt(Side::Lower)
            .unwrap()
            .inverse()
    }

    #[test]
    fn the_whole_inverse_by_blocks_matches_the_dense_one() {
        let (a, b) = normal_matrix();
        let inv = inverse(|i, j| a[(i, j)], &b).unwrap();
        let dense = dense_inverse(&a);
        let scale = (0..17).map(|i| dense[(i, i)]).fold(0.0f64, f64::max);
        for i in 0..17 {
            for j in 0..17 {
                assert!(
                    (inv[(i, j)] - dense[(i, j)]).abs() <= 1e-12 * scale,
                    "{i} {j}"
                );
                assert_eq!(inv[(i, j)], inv[(j, i)]);
            }
        }
        // the views' blocks are coupled through the global columns
        assert!(inv[(5, 8)].abs() > 1e-6 * scale);
    }

    #[test]
    fn a_singular_view_block_is_no_solution() {
        let (mut a, b) = normal_matrix();
        for i in 8..11 {
            for j in 0..17 {
                a[(i, j)] = 0.0;
                a[(j, i)] = 0.0;
            }
        }
        assert!(solve(&a, &[0.0; 17], &[1.0; 17], &b).is_none());
        assert!(InverseBlocks::new(|i, j| a[(i, j)], &b).is_none());
        assert!(inverse(|i, j| a[(i, j)], &b).is_none());
    }
}
