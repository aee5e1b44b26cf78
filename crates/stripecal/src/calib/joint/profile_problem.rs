//! The profiler adjustment's least-squares problem ([`super::profile`]): every sphere
//! point's distance from the sphere, its Jacobian row, and the normal equations formed
//! without storing the Jacobian.
//!
//! ## Residuals and rows
//!
//! A profile point `p = (x, 0, z)` of view i is at `P = A_i (R_X p + t_X)`. In the
//! flange frame, `d = R_Ai^T (P - c) = x r_0 + z r_2 + t_f` (`r_k` the columns of `R_X`,
//! `t_f = t_X + R_Ai^T (t_Ai - c)`); `e = |d| - D / 2`, `u_f = d / |d|`, `u = R_Ai u_f`:
//!
//! ```text
//! de/dw_X = p x (R_X^T u_f)      (X's increment R_X Exp(w))
//! de/dt_X = u_f
//! de/dc   = -u,   de/dD = -1/2
//! de/dk   = w_k . (q x u_f) + v_k . u_f   (DH correction k, q = R_X p + t_X)
//! ```
//!
//! Every term is linear in the point's features `f = (u_f, x u_f, z u_f, 1)`
//! (`p x a = x e_0 x a + z e_2 x a`, `q x u_f = x r_0 x u_f + z r_2 x u_f + t_X x u_f`):
//! a row is `B_v f` with one `n x 10` map `B_v` per view ([`feature_map`]).
//!
//! ## Normal equations
//!
//! A profile has thousands of points and the adjustment a handful of numbers: a view's
//! `J_v^T J_v = B_v G_v B_v^T` and `J_v^T r_v = B_v G_v[.., e]`, with `G_v` the Gram
//! matrix of the features and the residual (`11 x 11`, faer's product over blocks of
//! [`BLOCK`] points), so the Jacobian is never stored. The per-view gradients
//! `g_v = J_v^T r_v` are the view-clustered variance factor's. Checked against the rows
//! in the tests, the rows against central differences.

use std::ops::Range;

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rayon::prelude::*;

use super::layout::{Block, ParamLayout};
use super::profile::ProfileViewObs;
use crate::error::Result;
use crate::model::geometry::Iso3;
use crate::numerics::lm::{dense_jacobian_from_rows, JacobianRows, LeastSquares};

/// The residual terms: the points used, stored view after view (`x` and `z` apart).
pub(super) struct Terms {
    pub xs: Vec<f64>,
    pub zs: Vec<f64>,
    /// Per view: its points in `xs` / `zs`.
    pub ranges: Vec<Range<usize>>,
    /// Per view: `T_base_hand` (the readings', or the fit's flanges).
    pub a: Vec<Iso3>,
}

impl Terms {
    /// The points `selected` (per view, indices into its points) of `views`, their
    /// flange poses `a`.
    pub fn of(views: &[ProfileViewObs], selected: &[Vec<usize>], a: &[Iso3]) -> Terms {
        let mut t = Terms {
            xs: Vec::new(),
            zs: Vec::new(),
            ranges: Vec::with_capacity(views.len()),
            a: a.to_vec(),
        };
        t.select(views, selected);
        t
    }

    /// The points `selected` of `views` in place of the present ones (the buffers kept).
    pub fn select(&mut self, views: &[ProfileViewObs], selected: &[Vec<usize>]) {
        self.xs.clear();
        self.zs.clear();
        self.ranges.clear();
        for (o, sel) in views.iter().zip(selected) {
            let k = self.xs.len();
            self.xs.extend(sel.iter().map(|&i| o.points[i][0]));
            self.zs.extend(sel.iter().map(|&i| o.points[i][1]));
            self.ranges.push(k..self.xs.len());
        }
    }

    pub fn len(&self) -> usize {
        self.xs.len()
    }
}

/// `r` cut into the views' ranges.
fn per_view<'a, T>(mut r: &'a mut [T], ranges: &[Range<usize>], width: usize) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(ranges.len());
    for g in ranges {
        let (head, tail) = std::mem::take(&mut r).split_at_mut(g.len() * width);
        out.push(head);
        r = tail;
    }
    out
}

/// What every point of a view shares at a parameter vector (module docs), in the
/// flange frame: `R_A^T (P - c) = x r_0 + z r_2 + t_f` (`r_k` the columns of `R_X`).
struct ViewState {
    /// `t_f = t_X + R_A^T (t_A - c)`.
    tf: Vector3<f64>,
    /// `R_A^T`.
    rat: Matrix3<f64>,
    /// The flange perturbation per DH correction.
    twists: Vec<[f64; 6]>,
}

/// A point's residual `e = |d| - rho` and its features `f = (u_f, x u_f, z u_f, 1)`
/// (module docs), `d = x r_0 + z r_2 + t_f`, `u_f = d / |d|`.
#[inline(always)]
fn point_features(x: f64, z: f64, st: &State, tf: &Vector3<f64>) -> (f64, [f64; F - 1]) {
    let (r0, r2) = (&st.rx0, &st.rx2);
    let d0 = x * r0.x + z * r2.x + tf.x;
    let d1 = x * r0.y + z * r2.y + tf.y;
    let d2 = x * r0.z + z * r2.z + tf.z;
    let nd = (d0 * d0 + d1 * d1 + d2 * d2).sqrt().max(1e-300);
    let inv = 1.0 / nd;
    let (u0, u1, u2) = (d0 * inv, d1 * inv, d2 * inv);
    (
        nd - st.rho,
        [
            u0,
            u1,
            u2,
            x * u0,
            x * u1,
            x * u2,
            z * u0,
            z * u1,
            z * u2,
            1.0,
        ],
    )
}

/// What every point shares at a parameter vector: `X`'s rotation columns 0 and 2 and
/// translation, the sphere's radius, every view's [`ViewState`].
struct State {
    /// `R_X^T`.
    rxt: Matrix3<f64>,
    rx0: Vector3<f64>,
    rx2: Vector3<f64>,
    tx: Vector3<f64>,
    rho: f64,
    views: Vec<ViewState>,
}

impl State {
    /// The residual `|P - c| - rho` of the point `(x, 0, z)` of view `s`.
    #[inline]
    fn distance(&self, x: f64, z: f64, s: &ViewState) -> f64 {
        let d = x * self.rx0 + z * self.rx2 + s.tf;
        (d.x * d.x + d.y * d.y + d.z * d.z).sqrt() - self.rho
    }
}

/// The Jacobian's columns of the blocks.
#[derive(Clone)]
struct Columns {
    /// `X`'s six (rotation, translation), when free.
    x: Option<usize>,
    centre: Range<usize>,
    diameter: Range<usize>,
    robot: Range<usize>,
}

/// One view's normal equations: `J_v^T J_v` and `g_v = J_v^T r_v`.
pub(super) struct ViewNormals {
    pub jtj: DMatrix<f64>,
    pub g: DVector<f64>,
}

/// The parameters of the last normal equations and their per-view gradients.
type LastNormals = (Vec<f64>, Vec<DVector<f64>>);

pub(super) struct ProfileProblem<'a> {
    pub layout: &'a ParamLayout,
    pub terms: &'a Terms,
    /// The parameters of the last normal equations formed and their per-view
    /// gradients `g_v` (the view-clustered variance factor's, at the solver's last
    /// point without another pass).
    pub last: std::sync::Mutex<Option<LastNormals>>,
}

impl<'a> ProfileProblem<'a> {
    pub fn new(layout: &'a ParamLayout, terms: &'a Terms) -> Self {
        ProfileProblem {
            layout,
            terms,
            last: std::sync::Mutex::new(None),
        }
    }

    /// The per-view gradients `g_v` at `p` when the last normal equations were formed
    /// there.
    pub fn view_gradients_at(&self, p: &[f64]) -> Option<Vec<DVector<f64>>> {
        let last = self.last.lock().ok()?.take()?;
        (last.0 == p).then_some(last.1)
    }
}

impl ProfileProblem<'_> {
    fn state(&self, p: &[f64], with_twists: bool) -> State {
        let x = self.layout.transform(p, Block::HandCam);
        let rx = x.rotation.to_rotation_matrix().into_inner();
        let tx = x.translation.vector;
        let c = self.layout.sphere_centre(p);
        let none = || vec![Vec::new(); self.terms.a.len()];
        let (flanges, twists) = match &self.layout.robot {
            Some(rb) => {
                let v = &p[self.layout.robot_columns()];
                let tw = if with_twists {
                    rb.flange_jacobians(v, &[])
                } else {
                    none()
                };
                (rb.flanges(v), tw)
            }
            None => (self.terms.a.clone(), none()),
        };
        let views = flanges
            .iter()
            .zip(twists)
            .map(|(a, twists)| {
                let rat = a.rotation.to_rotation_matrix().into_inner().transpose();
                ViewState {
                    tf: tx + rat * (a.translation.vector - c),
                    rat,
                    twists,
                }
            })
            .collect();
        State {
            rxt: rx.transpose(),
            rx0: rx.column(0).into_owned(),
            rx2: rx.column(2).into_owned(),
            tx,
            rho: 0.5 * self.layout.sphere_diameter(p),
            views,
        }
    }

    fn columns(&self) -> Columns {
        Columns {
            x: self.layout.column(self.layout.slots(Block::HandCam).start),
            centre: self.layout.slotless_columns(Block::SphereCentre),
            diameter: self.layout.slotless_columns(Block::SphereDiameter),
            robot: self.layout.robot_columns(),
        }
    }

    /// `f(xs, zs, view state, state, columns, residuals out)` of every view at `p` (in
    /// parallel), the residuals into `r`.
    fn map_views<T, F>(&self, p: &[f64], r: &mut [f64], f: F) -> Vec<T>
    where
        T: Send,
        F: Fn(&[f64], &[f64], &ViewState, &State, &Columns, &mut [f64]) -> T + Sync,
    {
        let st = self.state(p, true);
        let cols = self.columns();
        let t = self.terms;
        per_view(r, &t.ranges, 1)
            .into_par_iter()
            .zip(t.ranges.par_iter())
            .zip(st.views.par_iter())
            .map(|((out, g), s)| f(&t.xs[g.clone()], &t.zs[g.clone()], s, &st, &cols, out))
            .collect()
    }

    /// Every view's normal equations at `p`, its residuals into `r` (module docs).
    pub fn view_normals(&self, p: &[f64], r: &mut [f64]) -> Vec<ViewNormals> {
        let n = self.layout.num_params();
        self.map_views(p, r, |xs, zs, s, st, cols, out| {
            view_block(xs, zs, s, st, cols, n, out)
        })
    }

    /// Every view's gradient `g_v = J_v^T r_v` and half its sum of squares at `p`, the
    /// residuals into `r`: the normal equations' work without the Gram matrix
    /// (`g_v = B_v sum_i f_i e_i`; the stopping test of [`super::profile_rounds`]).
    pub fn view_gradients(&self, p: &[f64], r: &mut [f64]) -> Vec<(DVector<f64>, f64)> {
        let n = self.layout.num_params();
        self.map_views(p, r, |xs, zs, s, st, cols, out| {
            let fe = features_by_blocks(xs, zs, s, st, out, 1);
            let b = feature_map(s, st, cols, n);
            let grad = b * DVector::from_fn(F - 1, |i, _| fe[(i, 0)]);
            (grad, 0.5 * fe[(F - 1, 0)])
        })
    }

    /// The residuals and Jacobian rows at `p` of single points `(view, x, z)` (`view` an
    /// index into the terms' views): the updates of the normal equations when a few
    /// points join or leave the selection ([`super::profile_rounds`]).
    pub fn point_rows(&self, p: &[f64], points: &[(usize, f64, f64)]) -> Vec<(f64, DVector<f64>)> {
        if points.is_empty() {
            return Vec::new();
        }
        let n = self.layout.num_params();
        let st = self.state(p, true);
        let cols = self.columns();
        let mut maps: Vec<Option<DMatrix<f64>>> = vec![None; st.views.len()];
        points
            .iter()
            .map(|&(v, x, z)| {
                let s = &st.views[v];
                let b = maps[v].get_or_insert_with(|| feature_map(s, &st, &cols, n));
                let (e, f) = point_features(x, z, &st, &s.tf);
                (e, &*b * DVector::from_column_slice(&f))
            })
            .collect()
    }
}

/// Features per point: `u_f`, `x u_f`, `z u_f`, 1, and the residual (module docs).
const F: usize = 11;
/// Points per block of the Gram product.
const BLOCK: usize = 128;

/// `[a]_x`, the cross-product matrix (`[a]_x b = a x b`).
fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// The map `B` (n x 10) of one view: a point's Jacobian row is `B f` (module docs).
fn feature_map(s: &ViewState, st: &State, cols: &Columns, n: usize) -> DMatrix<f64> {
    let mut b = DMatrix::<f64>::zeros(n, F - 1);
    let set = |b: &mut DMatrix<f64>, r0: usize, c0: usize, m: &Matrix3<f64>| {
        let mut v = b.fixed_view_mut::<3, 3>(r0, c0);
        v += m;
    };
    if let Some(c0) = cols.x {
        // p x (R_X^T u_f) = x [e0]_x R_X^T u_f + z [e2]_x R_X^T u_f
        let rxt = st.rxt;
        set(&mut b, c0, 3, &(skew(&Vector3::x()) * rxt));
        set(&mut b, c0, 6, &(skew(&Vector3::z()) * rxt));
        set(&mut b, c0 + 3, 0, &Matrix3::identity());
    }
    for (k, c) in cols.centre.clone().enumerate() {
        // -u = -R_A u_f
        for j in 0..3 {
            b[(c, j)] -= s.rat[(j, k)];
        }
    }
    for c in cols.diameter.clone() {
        b[(c, 9)] -= 0.5;
    }
    if !s.twists.is_empty() {
        // w . (q x u_f) + v . u_f, q = x rx0 + z rx2 + t_X: the row w^T [q]_x + v^T
        let (s0, s2, st_) = (skew(&st.rx0), skew(&st.rx2), skew(&st.tx));
        for (c, tw) in cols.robot.clone().zip(&s.twists) {
            let w = Vector3::new(tw[0], tw[1], tw[2]);
            let v = Vector3::new(tw[3], tw[4], tw[5]);
            let r0 = st_.transpose() * w + v;
            let r1 = s0.transpose() * w;
            let r2 = s2.transpose() * w;
            for j in 0..3 {
                b[(c, j)] += r0[j];
                b[(c, 3 + j)] += r1[j];
                b[(c, 6 + j)] += r2[j];
            }
        }
    }
    b
}

/// One view's residuals into `out` and the products of its points' features with the
/// residual (`F x 1`: `sum f_i e_i`, `sum e_i^2` last; `cols` 1) or with themselves
/// (`F x F`, the Gram matrix; `cols` F), by blocks of [`BLOCK`] points.
fn features_by_blocks(
    xs: &[f64],
    zs: &[f64],
    s: &ViewState,
    st: &State,
    out: &mut [f64],
    cols: usize,
) -> faer::Mat<f64> {
    // the features row after row (F rows of BLOCK), so that the loop vectorises
    let mut buf = vec![0.0; F * BLOCK.min(xs.len().max(1))];
    let stride = buf.len() / F;
    let mut prod = faer::Mat::<f64>::zeros(F, cols);
    for k0 in (0..xs.len()).step_by(BLOCK) {
        let len = BLOCK.min(xs.len() - k0);
        let (xs, zs) = (&xs[k0..k0 + len], &zs[k0..k0 + len]);
        let o = &mut out[k0..k0 + len];
        let mut rows = buf.chunks_exact_mut(stride);
        let mut next = || &mut rows.next().expect("F rows of BLOCK")[..len];
        let (f0, f1, f2, f3, f4) = (next(), next(), next(), next(), next());
        let (f5, f6, f7, f8, f9, f10) = (next(), next(), next(), next(), next(), next());
        for i in 0..len {
            let (e, f) = point_features(xs[i], zs[i], st, &s.tf);
            o[i] = e;
            f0[i] = f[0];
            f1[i] = f[1];
            f2[i] = f[2];
            f3[i] = f[3];
            f4[i] = f[4];
            f5[i] = f[5];
            f6[i] = f[6];
            f7[i] = f[7];
            f8[i] = f[8];
            f9[i] = f[9];
            f10[i] = e;
        }
        // row k of the features: buf[k * stride..][..len]
        let fm = faer::MatRef::from_row_major_slice_with_stride(&buf, F, len, stride);
        let rhs = if cols == F {
            fm.transpose()
        } else {
            fm.subrows(F - 1, 1).transpose()
        };
        faer::linalg::matmul::matmul(
            prod.as_mut(),
            faer::Accum::Add,
            fm,
            rhs,
            1.0,
            faer::Par::Seq,
        );
    }
    prod
}

/// One view's residuals into `out` and its normal equations: the Gram matrix of the
/// points' features (with the residual, [`features_by_blocks`]), then `B G B^T`.
fn view_block(
    xs: &[f64],
    zs: &[f64],
    s: &ViewState,
    st: &State,
    cols: &Columns,
    n: usize,
    out: &mut [f64],
) -> ViewNormals {
    let gram = features_by_blocks(xs, zs, s, st, out, F);
    let b = feature_map(s, st, cols, n);
    let g10 = DMatrix::<f64>::from_fn(F - 1, F - 1, |i, j| gram[(i, j)]);
    let fe = DVector::<f64>::from_fn(F - 1, |i, _| gram[(i, F - 1)]);
    ViewNormals {
        jtj: &b * g10 * b.transpose(),
        g: &b * fe,
    }
}

impl LeastSquares for ProfileProblem<'_> {
    fn num_params(&self) -> usize {
        self.layout.num_params()
    }
    fn num_residuals(&self) -> usize {
        self.terms.len()
    }
    fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        let st = self.state(p, false);
        let t = self.terms;
        per_view(r, &t.ranges, 1)
            .into_par_iter()
            .zip(t.ranges.par_iter())
            .zip(st.views.par_iter())
            .for_each(|((out, g), s)| {
                for ((o, &x), &z) in out.iter_mut().zip(&t.xs[g.clone()]).zip(&t.zs[g.clone()]) {
                    *o = st.distance(x, z, s);
                }
            });
        Ok(())
    }
    fn residuals_and_jacobian(
        &self,
        p: &[f64],
        r: &mut [f64],
        jac: faer::MatMut<'_, f64>,
    ) -> Result<()> {
        dense_jacobian_from_rows(self, p, r, jac)
    }
    fn jacobian_row_width(&self) -> Option<usize> {
        Some(self.layout.num_params())
    }
    fn residuals_and_jacobian_rows(
        &self,
        p: &[f64],
        r: &mut [f64],
        rows: &mut JacobianRows,
    ) -> Result<()> {
        let n = self.layout.num_params();
        let st = self.state(p, true);
        let cols = self.columns();
        let t = self.terms;
        let (_, vals) = rows.parts_mut();
        per_view(r, &t.ranges, 1)
            .into_par_iter()
            .zip(per_view(vals, &t.ranges, n))
            .zip(t.ranges.par_iter())
            .zip(st.views.par_iter())
            .for_each(|(((out, rows), g), s)| {
                // a row is B f (module docs)
                let b = feature_map(s, &st, &cols, n);
                let it = out
                    .iter_mut()
                    .zip(rows.chunks_exact_mut(n))
                    .zip(&t.xs[g.clone()])
                    .zip(&t.zs[g.clone()]);
                for (((o, row), &x), &z) in it {
                    let (e, f) = point_features(x, z, &st, &s.tf);
                    *o = e;
                    let j = &b * DVector::from_column_slice(&f);
                    row.copy_from_slice(j.as_slice());
                }
            });
        Ok(())
    }
    fn has_normal_equations(&self) -> bool {
        true
    }
    fn residuals_and_normal_equations(
        &self,
        p: &[f64],
        r: &mut [f64],
    ) -> Result<(DMatrix<f64>, DVector<f64>)> {
        let n = self.layout.num_params();
        let mut jtj = DMatrix::<f64>::zeros(n, n);
        let mut g = DVector::<f64>::zeros(n);
        let normals = self.view_normals(p, r);
        let mut gv = Vec::with_capacity(normals.len());
        for v in normals {
            jtj += v.jtj;
            g += &v.g;
            gv.push(v.g);
        }
        if let Ok(mut last) = self.last.lock() {
            *last = Some((p.to_vec(), gv));
        }
        // B G B^T is symmetric up to round-off: exactly so
        let jtj = (&jtj + jtj.transpose()) * 0.5;
        Ok((jtj, g))
    }
    fn retract(&self, p: &[f64], dp: &[f64], out: &mut [f64]) {
        self.layout.retract(p, dp, out);
    }
}

/// Every point's distance from the sphere of `p` (per view, all its points; `a` the
/// views' flange poses).
pub(super) fn all_residuals(
    layout: &ParamLayout,
    p: &[f64],
    views: &[ProfileViewObs],
    a: &[Iso3],
) -> Vec<Vec<f64>> {
    // the state needs the flanges only
    let terms = Terms {
        xs: Vec::new(),
        zs: Vec::new(),
        ranges: Vec::new(),
        a: a.to_vec(),
    };
    let st = ProfileProblem::new(layout, &terms).state(p, false);
    views
        .par_iter()
        .zip(st.views.par_iter())
        .map(|(o, s)| {
            o.points
                .iter()
                .map(|q| st.distance(q[0], q[1], s))
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::layout::SphereStart;
    use super::super::profile::tests::scene;
    use super::super::robot::{candidates, RobotBlock, RobotMode};
    use super::*;
    use crate::model::kinematics::Robot;

    /// A problem with X, the centre, the diameter and every DH correction free, over
    /// every 37th point (and the parameters moved off the scene's truth).
    fn problem_parts() -> (ParamLayout, Terms, Vec<f64>) {
        let robot = Robot::hp3();
        let (views, x, c, d) = scene(Some(&robot));
        let ids: Vec<usize> = (0..views.len()).collect();
        let block = RobotBlock {
            reference: robot.clone(),
            params: candidates(&robot, RobotMode::Full),
            readings: views.iter().map(|v| v.q.clone().unwrap()).collect(),
        };
        let sphere = SphereStart {
            centre: c + Vector3::new(0.3, -0.2, 0.1),
            diameter: d + 0.1,
            diameter_free: true,
        };
        let layout = ParamLayout::profiler(&x, true, sphere, &ids, Some(block));
        let selected: Vec<Vec<usize>> = views
            .iter()
            .map(|v| (0..v.points.len()).step_by(37).collect())
            .collect();
        let a: Vec<Iso3> = views.iter().map(|v| v.a).collect();
        let terms = Terms::of(&views, &selected, &a);
        let mut p = layout.encode();
        for (k, v) in p.iter_mut().enumerate() {
            *v += 1e-3 * ((k as f64) * 0.37).sin();
        }
        (layout, terms, p)
    }

    /// The analytic Jacobian rows against central differences, with X, the centre, the
    /// diameter and DH corrections free.
    #[test]
    fn jacobian_matches_central_differences() {
        let (layout, terms, p) = problem_parts();
        let prob = ProfileProblem::new(&layout, &terms);
        let worst = crate::numerics::lm::assert_jacobian_matches_fd(
            &prob,
            &p,
            |_| 1e-6,
            1e-12,
            1e-5,
            "profiler rows",
        );
        assert!(worst < 1e-5, "worst relative difference {worst:e}");
    }

    /// The normal equations formed block by block equal `J^T J` and `J^T r` of the
    /// rows, and the residuals are the same.
    #[test]
    fn normal_equations_match_the_rows() {
        let (layout, terms, p) = problem_parts();
        let prob = ProfileProblem::new(&layout, &terms);
        let (m, n) = (prob.num_residuals(), prob.num_params());
        let mut r = vec![0.0; m];
        let mut rows = JacobianRows::new(m, n, n);
        prob.residuals_and_jacobian_rows(&p, &mut r, &mut rows)
            .unwrap();
        let jac = DMatrix::from_fn(m, n, |i, j| rows.row(i).1[j]);
        let want_n = jac.transpose() * &jac;
        let want_g = jac.transpose() * DVector::from_column_slice(&r);
        let mut r2 = vec![f64::NAN; m];
        let (got_n, got_g) = prob.residuals_and_normal_equations(&p, &mut r2).unwrap();
        let mut r3 = vec![f64::NAN; m];
        prob.residuals(&p, &mut r3).unwrap();
        for i in 0..m {
            assert!((r[i] - r2[i]).abs() < 1e-12 && (r[i] - r3[i]).abs() < 1e-12);
        }
        let scale = want_n.amax();
        assert!((&got_n - &want_n).amax() < 1e-12 * scale);
        assert!((&got_n - got_n.transpose()).amax() == 0.0);
        assert!((got_g - &want_g).amax() < 1e-12 * want_g.amax().max(1.0));
    }
}
