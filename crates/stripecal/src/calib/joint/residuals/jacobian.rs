//! The image residuals' Jacobian rows: each view linearised once (its board pose and
//! stripe line as duals over every slot, chained to `X`, `Z`, the board scale and the
//! view's correction), then the circle rows and the stripe rows from it.

use nalgebra::{Matrix3, Matrix6};
use rayon::prelude::*;

use super::line::{parallel_error, stripe_line};
use super::{DSlots, JointProblem};
use crate::calib::conic::{
    centre_any_model, centre_any_model_with_jacobians, centre_generic_n, quadrature_nodes,
};
use crate::calib::joint::chain::cam_board;
use crate::calib::joint::layout::{Block, JointParams, SLOTS};
use crate::calib::joint::robot_noise;
use crate::error::Result;
use crate::model::camera::distort_generic;
use crate::model::geometry::Iso3;
use crate::numerics::dual::{Dual, Scalar};
use crate::numerics::mat3::{dot, rot_times_exp_first_order};

/// The slots after `X`'s first that a view's board pose depends on: `X`, `Z`, the board
/// scale.
const CHAIN: usize = 13;

/// Per-view quantities of a Jacobian evaluation: the pose each view's board points are
/// imaged with (`T_cam_board` with its translation divided by the board scale, values),
/// the chain of its increment to the `X`, `Z` and scale slots, and its stripe line with
/// derivatives over every slot.
pub(super) struct ViewLinearisation {
    board_poses: Vec<([[f64; 3]; 3], [f64; 3])>,
    /// `d(w, v) / d(X, Z, scale slots)`: rows `(w, v)` of the board pose's increment.
    chains: Vec<[[f64; CHAIN]; 6]>,
    lines: Vec<Option<([DSlots; 3], [DSlots; 3])>>,
    /// With the robot-pose noise: each view's map from its correction to `X`'s
    /// increment ([`robot_noise::correction_map`]).
    maps: Vec<Matrix6<f64>>,
    /// With the robot block: the map from the flange's own perturbation to `X`'s
    /// increment, and each view's flange perturbation per DH correction.
    robot: Option<RobotLinearisation>,
    /// The bench: the derivatives along `Z`'s slots are the view's board-pose columns.
    bench: bool,
}

/// The map from the flange's own perturbation to `X`'s increment, and each view's
/// flange perturbation per DH correction.
type RobotLinearisation = (Matrix6<f64>, Vec<Vec<[f64; 6]>>);

/// The robot block's columns of a row from its derivatives `gx` over `X`'s six slots.
#[inline]
fn robot_columns(
    robot: &Option<RobotLinearisation>,
    view: usize,
    gx: &[f64; 6],
    weight: f64,
    out: &mut [f64],
) {
    if let Some((m, jac)) = robot {
        let gf = robot_noise::correction_columns(gx, m);
        for (o, col) in out.iter_mut().zip(&jac[view]) {
            *o = weight * (0..6).map(|k| gf[k] * col[k]).sum::<f64>();
        }
    }
}

impl JointProblem<'_> {
    /// The views' poses and stripe lines as duals over every slot, and the chains.
    pub(super) fn linearise_views(&self, p: &[f64], s: &JointParams) -> ViewLinearisation {
        let layout = self.layout;
        let (sp, sx, sz, ss) = (
            layout.slots(Block::Plane).start,
            layout.slots(Block::HandCam).start,
            layout.slots(Block::BaseBoard).start,
            layout.slots(Block::BoardScale).start,
        );
        debug_assert_eq!(ss, sx + CHAIN - 1);
        let v = layout.full(p);
        let chart = &layout.chart;
        let a = DSlots::var(v[sp], sp);
        let b = DSlots::var(v[sp + 1], sp + 1);
        let nn: [DSlots; 3] = std::array::from_fn(|i| {
            DSlots::cst(chart.n0[i]) + a.scale(chart.e1[i]) + b.scale(chart.e2[i])
        });
        let len = dot(&nn, &nn).sqrt();
        let n1: [DSlots; 3] = std::array::from_fn(|i| nn[i] / len);
        let d1 = DSlots::var(v[sp + 2], sp + 2);
        let wx: [DSlots; 3] = std::array::from_fn(|i| DSlots::var(0.0, sx + i));
        let wz: [DSlots; 3] = std::array::from_fn(|i| DSlots::var(0.0, sz + i));
        let xr = rot_times_exp_first_order(&s.x_rot, &wx);
        let zr = rot_times_exp_first_order(&s.z_rot, &wz);
        let xt: [DSlots; 3] = std::array::from_fn(|i| DSlots::var(s.x_t[i], sx + 3 + i));
        let zt: [DSlots; 3] = std::array::from_fn(|i| DSlots::var(s.z_t[i], sz + 3 + i));
        let poses: Vec<_> = if s.board_poses.is_empty() {
            s.flange_poses(&self.flanges(s))
                .iter()
                .map(|a| cam_board(a, &xr, &xt, &zr, &zt))
                .collect()
        } else {
            // The bench: `A_i` and `X` the identity, each view's board pose in `Z`'s
            // slots (their derivatives are the view's board-pose columns).
            s.board_poses
                .iter()
                .map(|(r, t)| {
                    let zr = rot_times_exp_first_order(r, &wz);
                    let zt: [DSlots; 3] = std::array::from_fn(|i| DSlots::var(t[i], sz + 3 + i));
                    cam_board(&Iso3::identity(), &xr, &xt, &zr, &zt)
                })
                .collect()
        };
        let maps = s
            .corrections
            .iter()
            .map(|(rd, _)| robot_noise::correction_map(&s.x_rot, &s.x_t, rd))
            .collect();
        // Chain of each view's board-pose increment (w, v) w.r.t. the X, Z and scale
        // slots: dw = vee(R0^T dR), dv = d(t / s) = dt / s - t ds / s^2.
        let inv_s = 1.0 / s.scale;
        let chains = poses
            .iter()
            .map(|(rot, t)| {
                let r0 = Matrix3::from_fn(|i, j| rot[i][j].v);
                let mut m = [[0.0; CHAIN]; 6];
                #[allow(clippy::needless_range_loop)]
                for k in 0..CHAIN - 1 {
                    let slot = sx + k;
                    let dr = Matrix3::from_fn(|i, j| rot[i][j].d[slot]);
                    let sk = r0.transpose() * dr;
                    m[0][k] = 0.5 * (sk[(2, 1)] - sk[(1, 2)]);
                    m[1][k] = 0.5 * (sk[(0, 2)] - sk[(2, 0)]);
                    m[2][k] = 0.5 * (sk[(1, 0)] - sk[(0, 1)]);
                    for i in 0..3 {
                        m[3 + i][k] = t[i].d[slot] * inv_s;
                    }
                }
                for i in 0..3 {
                    m[3 + i][CHAIN - 1] = -t[i].v * inv_s * inv_s;
                }
                m
            })
            .collect();
        let board_poses = poses
            .iter()
            .map(|(rot, t)| {
                (
                    std::array::from_fn(|i| std::array::from_fn(|j| rot[i][j].v)),
                    std::array::from_fn(|i| t[i].v * inv_s),
                )
            })
            .collect();
        let lines = poses
            .iter()
            .map(|(rot, t)| stripe_line(&n1, d1, rot, t).ok())
            .collect();
        let robot = self.layout.robot.as_ref().map(|rb| {
            (
                robot_noise::correction_map(&s.x_rot, &s.x_t, &Matrix3::identity()),
                rb.flange_jacobians(&s.robot, &s.corrections),
            )
        });
        ViewLinearisation {
            board_poses,
            chains,
            lines,
            maps,
            robot,
            bench: self.bench,
        }
    }

    /// Weighted circle residuals `rc` and their Jacobian rows `vc` (2 rows of
    /// [`Self::row_width`] values per circle): duals over (camera 9, pose increment 6),
    /// chained to `X`, `Z` and the board scale, and through `X`'s to the view's
    /// correction. A camera of another model than brown5: its centre and analytic
    /// Jacobians through the model's trait ([`Self::circle_rows_any_model`]).
    pub(super) fn circle_rows(
        &self,
        s: &JointParams,
        views: &ViewLinearisation,
        rc: &mut [f64],
        vc: &mut [f64],
    ) -> Result<()> {
        type D15 = Dual<15>;
        if !self.base.projection.is_brown5() {
            return self.circle_rows_any_model(s, views, rc, vc);
        }
        let w = self.row_width();
        let col_of = self.layout.columns();
        // Fixed camera parameters are constants (zero coefficients then cost nothing).
        let c15: [D15; 9] = std::array::from_fn(|i| {
            if col_of[i].is_some() {
                D15::var(s.cam[i], i)
            } else {
                D15::cst(s.cam[i])
            }
        });
        let w15: [D15; 3] = std::array::from_fn(|i| D15::var(0.0, 9 + i));
        let wc = self.wc();
        let nodes = quadrature_nodes(self.base.model);
        rc.par_chunks_mut(2)
            .zip(vc.par_chunks_mut(2 * w))
            .zip(self.terms.circles.par_iter())
            .try_for_each(|((out, jrow), c)| -> Result<()> {
                let (rot, t) = &views.board_poses[c.view];
                let r0 = Matrix3::from_fn(|i, j| rot[i][j]);
                let rd = rot_times_exp_first_order(&r0, &w15);
                let td: [D15; 3] = std::array::from_fn(|i| D15::var(t[i], 12 + i));
                let uv = centre_generic_n(
                    &c15,
                    &rd,
                    &td,
                    c.centre,
                    c.radius,
                    self.jacobian_model,
                    nodes,
                )?;
                let value = if self.jacobian_model == self.model {
                    [uv[0].v, uv[1].v]
                } else {
                    centre_generic_n(&s.cam, rot, t, c.centre, c.radius, self.model, nodes)?
                };
                out[0] = wc * (value[0] - c.u);
                out[1] = wc * (value[1] - c.v);
                for (a, ua) in uv.iter().enumerate() {
                    let row = &mut jrow[a * w..(a + 1) * w];
                    for (slot, col) in col_of.iter().enumerate().take(9) {
                        if let Some(col) = col {
                            row[*col] = wc * ua.d[slot];
                        }
                    }
                    let pose: [f64; 6] = std::array::from_fn(|q| ua.d[9 + q]);
                    self.pose_columns(views, c.view, &pose, wc, row);
                }
                Ok(())
            })
    }

    /// [`Self::circle_rows`] for a camera of another model than brown5: the centre and
    /// its derivatives over the model's parameters and the pose increment from
    /// [`centre_any_model_with_jacobians`] (the `naive` and `conic` centre models, and
    /// any for point targets).
    fn circle_rows_any_model(
        &self,
        s: &JointParams,
        views: &ViewLinearisation,
        rc: &mut [f64],
        vc: &mut [f64],
    ) -> Result<()> {
        let w = self.row_width();
        let col_of = self.layout.columns();
        let cam = self.base.with_params(&s.cam);
        let wc = self.wc();
        rc.par_chunks_mut(2)
            .zip(vc.par_chunks_mut(2 * w))
            .zip(self.terms.circles.par_iter())
            .try_for_each(|((out, jrow), c)| -> Result<()> {
                let (rot, t) = &views.board_poses[c.view];
                let r0 = Matrix3::from_fn(|i, j| rot[i][j]);
                let (uv, jc, jp) = centre_any_model_with_jacobians(
                    &cam,
                    &r0,
                    t,
                    c.centre,
                    c.radius,
                    self.jacobian_model,
                )?;
                let value = if self.jacobian_model == self.model {
                    [uv.x, uv.y]
                } else {
                    centre_any_model(&cam, rot, t, c.centre, c.radius, self.model)?
                };
                out[0] = wc * (value[0] - c.u);
                out[1] = wc * (value[1] - c.v);
                for a in 0..2 {
                    let row = &mut jrow[a * w..(a + 1) * w];
                    for (slot, col) in col_of.iter().enumerate().take(jc.ncols()) {
                        if let Some(col) = col {
                            row[*col] = wc * jc[(a, slot)];
                        }
                    }
                    let pose: [f64; 6] = std::array::from_fn(|q| jp[(a, q)]);
                    self.pose_columns(views, c.view, &pose, wc, row);
                }
                Ok(())
            })
    }

    /// A circle row's columns from its derivatives over the view's board-pose increment
    /// `(w, v)`: chained to `X`, `Z` and the board scale, through `X`'s to the view's
    /// correction and the robot block, and on the bench to the view's board pose.
    fn pose_columns(
        &self,
        views: &ViewLinearisation,
        view: usize,
        pose: &[f64; 6],
        wc: f64,
        row: &mut [f64],
    ) {
        let ng = self.layout.num_global();
        let col_of = self.layout.columns();
        let sx = self.layout.slots(Block::HandCam).start;
        let ch = &views.chains[view];
        let (mut gx, mut gz) = ([0.0; 6], [0.0; 6]);
        for kk in 0..CHAIN {
            let acc: f64 = (0..6).map(|q| pose[q] * ch[q][kk]).sum();
            if kk < 6 {
                gx[kk] = acc;
            } else if kk < 12 {
                gz[kk - 6] = acc;
            }
            if let Some(col) = col_of[sx + kk] {
                row[col] = wc * acc;
            }
        }
        if let Some(m) = views.maps.get(view) {
            let d = robot_noise::correction_columns(&gx, m);
            for (o, v) in row[ng..ng + 6].iter_mut().zip(d) {
                *o = wc * v;
            }
        }
        let rcols = self.layout.robot_columns();
        robot_columns(&views.robot, view, &gx, wc, &mut row[rcols]);
        if views.bench {
            for (o, v) in row[ng..ng + 6].iter_mut().zip(gz) {
                *o = wc * v;
            }
        }
    }

    /// Weighted stripe residuals `rs` and their Jacobian rows `vs` ([`Self::row_width`]
    /// values each).
    ///
    /// Chain rule: `d res = n^T (d pi/d P (d p0 + s d dir) + d pi/d camera)`, the line's
    /// derivatives (plane, `X`, `Z` slots) from the per-view duals, the projection's by
    /// a small dual over `(x, y, k1..k3)` at the point (another model than brown5: its
    /// trait's analytic derivatives).
    pub(super) fn stripe_rows(
        &self,
        s: &JointParams,
        views: &ViewLinearisation,
        rs: &mut [f64],
        vs: &mut [f64],
    ) -> Result<()> {
        type D7 = Dual<7>;
        let w = self.row_width();
        let ng = self.layout.num_global();
        let col_of = self.layout.columns();
        let sp = self.layout.slots(Block::Plane).start;
        let sx = self.layout.slots(Block::HandCam).start;
        let sz = self.layout.slots(Block::BaseBoard).start;
        let rcols = self.layout.robot_columns();
        let ws = self.ws();
        let cam = self.base.with_params(&s.cam);
        let other = (!cam.projection.is_brown5()).then(|| cam.projection.model());
        rs.par_iter_mut()
            .zip(vs.par_chunks_mut(w))
            .enumerate()
            .try_for_each(|(k, (out, row))| -> Result<()> {
                let st = &self.terms.stripes[k];
                let Some((p0, dir)) = views.lines[st.view] else {
                    return Err(parallel_error(st.view));
                };
                let p0f = [p0[0].v, p0[1].v, p0[2].v];
                let dirf = [dir[0].v, dir[1].v, dir[2].v];
                let (sf, normal) = self.cached_foot_point(k, &cam, &p0f, &dirf)?;
                let pf: [f64; 3] = std::array::from_fn(|i| p0f[i] + sf * dirf[i]);
                let (x, y) = (pf[0] / pf[2], pf[1] / pf[2]);
                // the distorted point, its derivatives over (x, y) and the coefficients
                let (dv, dxy, dk) = if let Some(m) = other {
                    let coef = cam.coefficients();
                    let ((xd, yd), j) = m.distort(coef, x, y);
                    let jk = m.distortion_jacobian(coef, x, y);
                    let dk: [[f64; 2]; 5] = std::array::from_fn(|i| {
                        if i < jk.ncols() {
                            [jk[(0, i)], jk[(1, i)]]
                        } else {
                            [0.0; 2]
                        }
                    });
                    (
                        [xd, yd],
                        [[j[(0, 0)], j[(0, 1)]], [j[(1, 0)], j[(1, 1)]]],
                        dk,
                    )
                } else {
                    let kd: [D7; 5] = std::array::from_fn(|i| {
                        if col_of[4 + i].is_some() {
                            D7::var(s.cam[4 + i], 2 + i)
                        } else {
                            D7::cst(s.cam[4 + i])
                        }
                    });
                    let (d, _) = distort_generic(&kd, D7::var(x, 0), D7::var(y, 1));
                    (
                        [d[0].v, d[1].v],
                        [[d[0].d[0], d[0].d[1]], [d[1].d[0], d[1].d[1]]],
                        std::array::from_fn(|i| [d[0].d[2 + i], d[1].d[2 + i]]),
                    )
                };
                let (fu, fv) = (s.cam[0], s.cam[1]);
                let res = normal[0] * (fu * dv[0] + s.cam[2] - st.u)
                    + normal[1] * (fv * dv[1] + s.cam[3] - st.v);
                let (g0, g1) = (normal[0] * fu, normal[1] * fv);
                let drx = g0 * dxy[0][0] + g1 * dxy[1][0];
                let dry = g0 * dxy[0][1] + g1 * dxy[1][1];
                let dp = [drx / pf[2], dry / pf[2], -(drx * x + dry * y) / pf[2]];
                let mut full = [0.0; SLOTS];
                full[0] = normal[0] * dv[0];
                full[1] = normal[1] * dv[1];
                full[2] = normal[0];
                full[3] = normal[1];
                for i in 0..5 {
                    full[4 + i] = g0 * dk[i][0] + g1 * dk[i][1];
                }
                for (slot, o) in full.iter_mut().enumerate().skip(sp) {
                    *o = (0..3)
                        .map(|i| dp[i] * (p0[i].d[slot] + sf * dir[i].d[slot]))
                        .sum();
                }
                *out = ws * res;
                for (slot, v) in full.iter().enumerate() {
                    if let Some(col) = col_of[slot] {
                        row[col] = ws * v;
                    }
                }
                let gx: [f64; 6] = std::array::from_fn(|k| full[sx + k]);
                robot_columns(&views.robot, st.view, &gx, ws, &mut row[rcols.clone()]);
                if let Some(m) = views.maps.get(st.view) {
                    let d = robot_noise::correction_columns(&gx, m);
                    for (o, v) in row[ng..ng + 6].iter_mut().zip(d) {
                        *o = ws * v;
                    }
                }
                if views.bench {
                    for (o, v) in row[ng..ng + 6].iter_mut().zip(&full[sz..sz + 6]) {
                        *o = ws * v;
                    }
                }
                Ok(())
            })
    }
}
