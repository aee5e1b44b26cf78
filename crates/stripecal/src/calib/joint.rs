//! The one-stage adjustment: intrinsics, distortion, laser plane, hand-eye `X` and
//! robot-world `Z` refined together in ONE Levenberg-Marquardt, the board pose of each
//! view following from the robot.
//!
//! ## Model
//!
//! Per view i with `A_i = T_base_hand(q_i)` (known from the robot):
//!
//! ```text
//! T_cam_board(i) = (A_i X)^-1 Z,   R_cb = R_X^T R_A^T R_Z,   t_cb = R_X^T (R_A^T (t_Z - t_A) - t_X)
//! ```
//!
//! Residuals, in pixels:
//! - circles: detected imaged centre minus the predicted imaged centre of the circle
//!   (the bias-free conic model of [`crate::calib::conic`], default the exact area
//!   centroid);
//! - stripe points: signed image distance from the detected point to the image of the
//!   line where the laser plane meets view i's board plane. The distance is measured to
//!   the foot point `P(s*)` of the (distorted) image curve of the 3D line, found by
//!   Gauss-Newton along the line; its derivative w.r.t. the parameters is, by the
//!   envelope theorem, `n^T d pi(P(s*)) / d theta` at fixed `s*`, `n` the unit normal of
//!   the image curve at the foot point.
//!
//! ## Parameters (state vector)
//!
//! `[free camera parameters (PARAM_NAMES order)] [plane a, b, d] [X: w, v] [Z: w, v]`.
//! The laser plane's unit normal is `normalize(n0 + a e1 + b e2)` around the starting
//! normal `n0` (`e1`, `e2` orthonormal, perpendicular to it), its offset `d` mm. The
//! transforms are stored as rotation vector and translation; the solver's increment is
//! `R Exp(w)` (rotation about the transform's own axes) and `t + v` (mm).
//!
//! ## Weighting and uncertainty
//!
//! Circle and stripe residuals have different noise. The adjustment estimates one
//! standard deviation per residual type (variance components): after every accepted
//! step it re-estimates `sigma_type^2 = SSR_type / (m_type - n m_type / m)` from the
//! residuals and re-weights (`1 / sigma_type`); the solver does not stop while the
//! weights still move (see [`LeastSquares::reweight`]). The covariance of the
//! parameters is then `s^2 (J^T W J)^-1` with `s^2` the a-posteriori variance factor of
//! the weighted residuals (about 1). Optional Huber loss on the weighted residuals
//! (threshold 1.345 sigma). Jacobians by forward-mode automatic differentiation
//! ([`Dual`]), checked against central differences in the tests.

use faer::MatMut;
use nalgebra::{DMatrix, Matrix3, Vector3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

use crate::calib::conic::{centre_generic_n, quadrature_nodes, CentreModel};
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::camera::{distort_generic, project_generic};
use crate::model::camera::{Camera, PARAM_NAMES};
use crate::model::geometry::{
    iso_from_rotvec, iso_to_rotvec, matrix_to_rotvec, rotvec_to_matrix, Iso3, Plane,
};
use crate::numerics::dual::{Dual, Scalar};
use crate::numerics::lm::{
    dense_jacobian_from_rows, levenberg_marquardt, JacobianRows, LeastSquares, LmOptions, LmResult,
    StopReason,
};
use crate::numerics::mat3::{cross, dot, m3, matmul, matvec, rot_times_exp_first_order, transpose};

/// Dual numbers over every parameter slot: camera 0..9, plane 9..12, X 12..18, Z 18..24.
type D24 = Dual<24>;
const SLOT_PLANE: usize = 9;
const SLOT_X: usize = 12;
const SLOT_Z: usize = 18;

/// Variance-component re-estimations per solve: they settle in 2-3 on noisy data; a
/// residual type fitted exactly (noise-free data, or a model that fits one type
/// perfectly) would otherwise chase its sigma towards zero step after step.
const MAX_REWEIGHTS: usize = 5;

/// Huber threshold on the weighted residuals (in units of the residual's sigma).
pub const HUBER_SIGMAS: f64 = 1.345;

/// Options of [`joint_adjustment`].
#[derive(Debug, Clone, PartialEq)]
pub struct JointOptions {
    /// Circle-centre model.
    pub centre_model: CentreModel,
    /// Solver options of each round.
    pub lm: LmOptions,
    /// Huber loss on the weighted residuals.
    pub robust: bool,
    /// Estimate one standard deviation per residual type (variance components) during
    /// the solve (default true); otherwise the weights stay `1 / initial_sigma_px`.
    pub variance_components: bool,
    /// A view whose RMS of weighted residuals exceeds this (in sigmas) is reported as an
    /// outlier (default 3).
    pub outlier_sigmas: f64,
    /// Starting standard deviations (circle, stripe), px.
    pub initial_sigma_px: (f64, f64),
}

impl Default for JointOptions {
    fn default() -> Self {
        JointOptions {
            centre_model: CentreModel::ConicExact,
            // The weighted residuals have unit variance (variance components), so the
            // cost is about (m - n) / 2 and a step that lowers it by `ftol * cost`
            // moves the parameters by sqrt(2 ftol cost) sigmas: 1e-8 stops within
            // 0.01 sigma for m = 10^4 (and to round-off on exact data, where each step
            // gains orders of magnitude).
            lm: LmOptions {
                max_iterations: 100,
                ftol: 1e-8,
                xtol: 1e-10,
                ..Default::default()
            },
            robust: false,
            variance_components: true,
            outlier_sigmas: 3.0,
            initial_sigma_px: (0.02, 0.05),
        }
    }
}

/// Where the adjustment starts (the two-stage results).
#[derive(Debug, Clone, PartialEq)]
pub struct JointStart {
    pub camera: Camera,
    /// Laser plane, camera frame.
    pub plane: Plane,
    /// `X = T_hand_cam`.
    pub hand_cam: Iso3,
    /// `Z = T_base_board`.
    pub base_board: Iso3,
}

/// One-sigma of an estimated transform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransformSigma {
    /// Of the rotation-vector components, rad.
    pub rotation_vector: Vector3<f64>,
    /// Of the translation, mm.
    pub translation_mm: Vector3<f64>,
}

/// One-sigma of every estimated number.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSigma {
    /// Camera parameters in [`PARAM_NAMES`] order (0 for fixed ones, NaN unobservable).
    pub camera: [f64; 9],
    /// Components of the plane's unit normal.
    pub plane_normal: Vector3<f64>,
    /// Plane offset, mm.
    pub plane_d_mm: f64,
    pub hand_cam: TransformSigma,
    pub base_board: TransformSigma,
}

/// Per-view figures of the adjustment.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewReport {
    /// `ViewObs::view` (dataset row).
    pub view: usize,
    pub circles: usize,
    pub stripe_points: usize,
    /// RMS of the 2D circle residuals, px (NaN without circles).
    pub circle_rms_px: f64,
    /// RMS of the stripe distances, px (NaN without stripe points).
    pub stripe_rms_px: f64,
    /// RMS of the stripe points' distances from the laser plane's line on the board,
    /// mm (each point's image residual converted with its local scale).
    pub stripe_rms_mm: f64,
    /// Residuals far beyond the others' (see [`JointOptions::outlier_sigmas`]).
    pub outlier: bool,
}

/// The result of [`joint_adjustment`].
#[derive(Debug, Clone)]
pub struct JointResult {
    pub camera: Camera,
    pub plane: Plane,
    pub hand_cam: Iso3,
    pub base_board: Iso3,
    pub sigma: JointSigma,
    /// RMS of the 2D circle residuals over all views, px.
    pub circle_rms_px: f64,
    /// RMS of the stripe distances, px.
    pub stripe_rms_px: f64,
    /// RMS of the stripe residuals in mm on the board.
    pub stripe_rms_mm: f64,
    /// Estimated standard deviations of one residual coordinate (circle, stripe), px.
    pub sigma_px: (f64, f64),
    pub views: Vec<ViewReport>,
    /// Parameter names of the state vector, and its covariance (weighted, scaled by the
    /// variance factor).
    pub param_names: Vec<String>,
    pub covariance: DMatrix<f64>,
    pub iterations: usize,
    pub stop_reason: StopReason,
    pub unobservable: Vec<String>,
    /// Per-circle values: `(view, row, col, u, v, du, dv)`, the detected centre `(u, v)`
    /// and the residual predicted minus detected, px.
    pub circle_residuals: Vec<(usize, usize, usize, f64, f64, f64, f64)>,
    /// Stripe `(view, u, v, distance px)`.
    pub stripe_residuals: Vec<(usize, f64, f64, f64)>,
    pub warnings: Vec<String>,
}

#[derive(Debug, Clone, Copy)]
struct CircleTerm {
    view: usize,
    row: usize,
    col: usize,
    centre: (f64, f64),
    radius: f64,
    u: f64,
    v: f64,
}

#[derive(Debug, Clone, Copy)]
struct StripeTerm {
    view: usize,
    u: f64,
    v: f64,
}

struct JointProblem<'a> {
    base: &'a Camera,
    free: Vec<usize>,
    /// Centre model of the residuals.
    model: CentreModel,
    /// Centre model whose derivatives the Jacobian takes (`model` for the exact
    /// Jacobian; the first-order `Conic` while the exact model's solve is under way:
    /// an inexact Jacobian only changes the path, the last solve's is exact).
    jacobian_model: CentreModel,
    n0: Vector3<f64>,
    e1: Vector3<f64>,
    e2: Vector3<f64>,
    /// `T_base_hand` of each used view.
    a: Vec<Iso3>,
    circles: Vec<CircleTerm>,
    stripes: Vec<StripeTerm>,
    /// Weights `1 / sigma` of the circle and stripe residuals (f64 bits; re-estimated
    /// during the solve when `variance_components` is set).
    w_circle: AtomicU64,
    w_stripe: AtomicU64,
    /// Re-estimate the weights (variance components) in [`LeastSquares::reweight`].
    variance_components: bool,
    /// MAD instead of RMS for the sigmas (robust).
    robust_sigma: bool,
    /// Re-estimations left in the current solve (see [`MAX_REWEIGHTS`]).
    reweights_left: AtomicUsize,
    /// The last foot-point parameter of each stripe point (f64 bits; NaN: none): the
    /// next evaluation starts there (a warm start; the result does not depend on it
    /// beyond the 1e-11 px convergence tolerance).
    foot_cache: Vec<AtomicU64>,
}

/// The values of the state decoded.
struct State {
    cam: [f64; 9],
    plane_n: Vector3<f64>,
    plane_d: f64,
    x_rot: Matrix3<f64>,
    x_t: Vector3<f64>,
    z_rot: Matrix3<f64>,
    z_t: Vector3<f64>,
}

impl State {
    /// `T_cam_board` of each view, `(R, t)`, from the robot poses `a`.
    fn view_poses(&self, a: &[Iso3]) -> Vec<([[f64; 3]; 3], [f64; 3])> {
        let xr: [[f64; 3]; 3] = m3(&self.x_rot);
        let zr: [[f64; 3]; 3] = m3(&self.z_rot);
        let xt = [self.x_t.x, self.x_t.y, self.x_t.z];
        let zt = [self.z_t.x, self.z_t.y, self.z_t.z];
        a.iter().map(|a| cam_board(a, &xr, &xt, &zr, &zt)).collect()
    }
}

/// `T_cam_board = (A X)^-1 Z` from the parts.
fn cam_board<T: Scalar>(
    a: &Iso3,
    xr: &[[T; 3]; 3],
    xt: &[T; 3],
    zr: &[[T; 3]; 3],
    zt: &[T; 3],
) -> ([[T; 3]; 3], [T; 3]) {
    let ra = a.rotation.to_rotation_matrix().into_inner();
    let rat: [[T; 3]; 3] = m3(&ra.transpose());
    let ta = a.translation.vector;
    let xrt = transpose(xr);
    let rot = matmul(&xrt, &matmul(&rat, zr));
    let dz: [T; 3] = std::array::from_fn(|i| zt[i] - T::from_f64(ta[i]));
    let inner = matvec(&rat, &dz);
    let inner2: [T; 3] = std::array::from_fn(|i| inner[i] - xt[i]);
    (rot, matvec(&xrt, &inner2))
}

/// The line where the laser plane `(n1, d1)` meets the board plane (third column of
/// `rot`, through `t`): a point and a unit direction, camera frame.
fn stripe_line<T: Scalar>(
    n1: &[T; 3],
    d1: T,
    rot: &[[T; 3]; 3],
    t: &[T; 3],
) -> Result<([T; 3], [T; 3])> {
    let n2 = [rot[0][2], rot[1][2], rot[2][2]];
    let d2 = dot(&n2, t);
    let dir = cross(n1, &n2);
    let s2 = dot(&dir, &dir);
    if s2.value().is_nan() || s2.value() <= 1e-18 {
        return Err(Error::Degenerate(
            "the laser plane is parallel to a view's board plane".into(),
        ));
    }
    let a = cross(&n2, &dir);
    let b = cross(&dir, n1);
    let p: [T; 3] = std::array::from_fn(|i| (a[i] * d1 + b[i] * d2) / s2);
    let s = s2.sqrt();
    let u: [T; 3] = std::array::from_fn(|i| dir[i] / s);
    Ok((p, u))
}

/// Foot point of `target` on the image of the 3D line `p0 + s dir`: `s*`, and the unit
/// normal of the image curve there. Gauss-Newton along the line from the distortion-free
/// closest point.
fn foot_point(
    cam: &[f64; 9],
    p0: &[f64; 3],
    dir: &[f64; 3],
    target: [f64; 2],
    start: f64,
) -> Result<(f64, [f64; 2])> {
    // Start: closest point of the 3D line to the distortion-free viewing ray.
    let r = Vector3::new(
        (target[0] - cam[2]) / cam[0],
        (target[1] - cam[3]) / cam[1],
        1.0,
    )
    .normalize();
    let (pv, dv) = (Vector3::from(*p0), Vector3::from(*dir));
    let b = dv.dot(&r);
    let den = 1.0 - b * b;
    let mut s = if start.is_finite() {
        start
    } else if den > 1e-12 {
        (b * r.dot(&pv) - dv.dot(&pv)) / den
    } else {
        0.0
    };
    let cd: [Dual<1>; 9] = std::array::from_fn(|i| Dual::cst(cam[i]));
    let mut normal = [0.0, 0.0];
    for it in 0..30 {
        let sd = Dual::<1>::var(s, 0);
        let p: [Dual<1>; 3] = std::array::from_fn(|i| Dual::cst(p0[i]) + sd.scale(dir[i]));
        if p[2].v <= 0.0 {
            return Err(Error::Degenerate(
                "a view's stripe line passes behind the camera".into(),
            ));
        }
        let uv = project_generic(&cd, &p);
        let res = [uv[0].v - target[0], uv[1].v - target[1]];
        let j = [uv[0].d[0], uv[1].d[0]];
        let jj = j[0] * j[0] + j[1] * j[1];
        if jj.is_nan() || jj <= 1e-300 || !jj.is_finite() {
            return Err(Error::Degenerate(
                "a view's stripe line images as a point".into(),
            ));
        }
        let jn = jj.sqrt();
        normal = [-j[1] / jn, j[0] / jn];
        let step = -(j[0] * res[0] + j[1] * res[1]) / jj;
        s += step;
        if (step * jn).abs() < 1e-11 || it == 29 {
            break;
        }
    }
    Ok((s, normal))
}

impl JointProblem<'_> {
    fn ncam(&self) -> usize {
        self.free.len()
    }

    fn wc(&self) -> f64 {
        f64::from_bits(self.w_circle.load(Ordering::Relaxed))
    }

    fn ws(&self) -> f64 {
        f64::from_bits(self.w_stripe.load(Ordering::Relaxed))
    }

    /// Standard deviations (circle, stripe) of the raw residuals behind the weighted
    /// `r`: `sqrt(SSR_type / (m_type - n m_type / m))`, or 1.4826 MAD when robust;
    /// floored at 1e-9 px (round-off of exact data).
    fn sigmas(&self, r: &[f64]) -> (Option<f64>, f64) {
        let n = self.num_params() as f64;
        let m = r.len() as f64;
        let mc = 2 * self.circles.len();
        let (rc, rs) = r.split_at(mc);
        let est = |rr: &[f64], w: f64| -> f64 {
            let mt = rr.len() as f64;
            let dof = (mt - n * mt / m).max(1.0);
            let s = if self.robust_sigma {
                let mut a: Vec<f64> = rr.iter().map(|x| (x / w).abs()).collect();
                a.sort_by(f64::total_cmp);
                1.4826 * a.get(a.len() / 2).copied().unwrap_or(0.0)
            } else {
                (rr.iter().map(|x| (x / w).powi(2)).sum::<f64>() / dof).sqrt()
            };
            s.max(1e-9)
        };
        let sc = (mc > 0).then(|| est(rc, self.wc()));
        (sc, est(rs, self.ws()))
    }

    fn decode(&self, p: &[f64]) -> State {
        let mut cam = self.base.params();
        for (k, &i) in self.free.iter().enumerate() {
            cam[i] = p[k];
        }
        let o = self.ncam();
        let n = self.n0 + self.e1 * p[o] + self.e2 * p[o + 1];
        let x = o + 3;
        let z = o + 9;
        State {
            cam,
            plane_n: n / n.norm(),
            plane_d: p[o + 2],
            x_rot: rotvec_to_matrix(&Vector3::new(p[x], p[x + 1], p[x + 2])),
            x_t: Vector3::new(p[x + 3], p[x + 4], p[x + 5]),
            z_rot: rotvec_to_matrix(&Vector3::new(p[z], p[z + 1], p[z + 2])),
            z_t: Vector3::new(p[z + 3], p[z + 4], p[z + 5]),
        }
    }

    /// Column of the state for a dual slot (`None`: a fixed camera parameter).
    fn column(&self, slot: usize) -> Option<usize> {
        if slot < 9 {
            self.free.iter().position(|&i| i == slot)
        } else {
            Some(self.ncam() + slot - 9)
        }
    }

    fn nviews(&self) -> usize {
        self.a.len()
    }

    /// f64 residuals (unweighted): circles (2 each) then stripe points.
    fn raw_residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        let s = self.decode(p);
        let poses = s.view_poses(&self.a);
        let n1 = [s.plane_n.x, s.plane_n.y, s.plane_n.z];
        let lines: Vec<Option<_>> = poses
            .iter()
            .map(|(rot, t)| stripe_line(&n1, s.plane_d, rot, t).ok())
            .collect();
        let nc = self.circles.len();
        let (rc, rs) = r.split_at_mut(2 * nc);
        rc.par_chunks_mut(2)
            .zip(self.circles.par_iter())
            .try_for_each(|(out, c)| -> Result<()> {
                let (rot, t) = &poses[c.view];
                let uv = centre_generic_n(
                    &s.cam,
                    rot,
                    t,
                    c.centre,
                    c.radius,
                    self.model,
                    quadrature_nodes(self.base.model),
                )?;
                out[0] = uv[0] - c.u;
                out[1] = uv[1] - c.v;
                Ok(())
            })?;
        rs.par_iter_mut()
            .zip(self.stripes.par_iter().zip(self.foot_cache.par_iter()))
            .try_for_each(|(out, (st, cache))| -> Result<()> {
                let Some((p0, dir)) = lines[st.view] else {
                    return Err(parallel_error(st.view));
                };
                let start = f64::from_bits(cache.load(Ordering::Relaxed));
                let (sf, normal) = foot_point(&s.cam, &p0, &dir, [st.u, st.v], start)?;
                cache.store(sf.to_bits(), Ordering::Relaxed);
                let pt: [f64; 3] = std::array::from_fn(|i| p0[i] + sf * dir[i]);
                let uv = project_generic(&s.cam, &pt);
                *out = normal[0] * (uv[0] - st.u) + normal[1] * (uv[1] - st.v);
                Ok(())
            })?;
        Ok(())
    }
}

impl LeastSquares for JointProblem<'_> {
    fn num_params(&self) -> usize {
        self.ncam() + 15
    }
    fn num_residuals(&self) -> usize {
        2 * self.circles.len() + self.stripes.len()
    }
    fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        self.raw_residuals(p, r)?;
        let nc = 2 * self.circles.len();
        for (i, x) in r.iter_mut().enumerate() {
            *x *= if i < nc { self.wc() } else { self.ws() };
        }
        Ok(())
    }
    fn residuals_and_jacobian(&self, p: &[f64], r: &mut [f64], jac: MatMut<'_, f64>) -> Result<()> {
        dense_jacobian_from_rows(self, p, r, jac)
    }
    fn jacobian_row_width(&self) -> Option<usize> {
        // Every residual depends on (nearly) every parameter: dense rows.
        Some(self.num_params())
    }
    fn residuals_and_jacobian_rows(
        &self,
        p: &[f64],
        r: &mut [f64],
        rows: &mut JacobianRows,
    ) -> Result<()> {
        let s = self.decode(p);
        let n = self.num_params();
        // Column of each dual slot (fixed camera parameters: none).
        let col_of: [Option<usize>; 24] = std::array::from_fn(|slot| self.column(slot));
        let o = self.ncam();
        // Duals over every slot.
        let a = D24::var(p[o], SLOT_PLANE);
        let b = D24::var(p[o + 1], SLOT_PLANE + 1);
        let nn: [D24; 3] = std::array::from_fn(|i| {
            D24::cst(self.n0[i]) + a.scale(self.e1[i]) + b.scale(self.e2[i])
        });
        let len = dot(&nn, &nn).sqrt();
        let n1: [D24; 3] = std::array::from_fn(|i| nn[i] / len);
        let d1 = D24::var(p[o + 2], SLOT_PLANE + 2);
        let wx: [D24; 3] = std::array::from_fn(|i| D24::var(0.0, SLOT_X + i));
        let wz: [D24; 3] = std::array::from_fn(|i| D24::var(0.0, SLOT_Z + i));
        let xr = rot_times_exp_first_order(&s.x_rot, &wx);
        let zr = rot_times_exp_first_order(&s.z_rot, &wz);
        let xt: [D24; 3] = std::array::from_fn(|i| D24::var(s.x_t[i], SLOT_X + 3 + i));
        let zt: [D24; 3] = std::array::from_fn(|i| D24::var(s.z_t[i], SLOT_Z + 3 + i));
        let poses: Vec<_> = self
            .a
            .iter()
            .map(|a| cam_board(a, &xr, &xt, &zr, &zt))
            .collect();
        // Chain of each view's pose increment (w, v) of T_cam_board w.r.t. the X and Z
        // slots: dw = vee(R0^T dR), dv = dt.
        let chains: Vec<[[f64; 12]; 6]> = poses
            .iter()
            .map(|(rot, t)| {
                let r0 = Matrix3::from_fn(|i, j| rot[i][j].v);
                let mut m = [[0.0; 12]; 6];
                #[allow(clippy::needless_range_loop)]
                for k in 0..12 {
                    let slot = SLOT_X + k;
                    let dr = Matrix3::from_fn(|i, j| rot[i][j].d[slot]);
                    let sk = r0.transpose() * dr;
                    m[0][k] = 0.5 * (sk[(2, 1)] - sk[(1, 2)]);
                    m[1][k] = 0.5 * (sk[(0, 2)] - sk[(2, 0)]);
                    m[2][k] = 0.5 * (sk[(1, 0)] - sk[(0, 1)]);
                    for i in 0..3 {
                        m[3 + i][k] = t[i].d[slot];
                    }
                }
                m
            })
            .collect();
        let poses_f: Vec<([[f64; 3]; 3], [f64; 3])> = poses
            .iter()
            .map(|(rot, t)| {
                (
                    std::array::from_fn(|i| std::array::from_fn(|j| rot[i][j].v)),
                    std::array::from_fn(|i| t[i].v),
                )
            })
            .collect();
        let lines: Vec<Option<([D24; 3], [D24; 3])>> = poses
            .iter()
            .map(|(rot, t)| stripe_line(&n1, d1, rot, t).ok())
            .collect();

        // Circles: duals over (camera 9, pose increment 6), chained to X and Z.
        type D15 = Dual<15>;
        // Fixed camera parameters are constants (zero coefficients then cost nothing).
        let c15: [D15; 9] = std::array::from_fn(|i| {
            if col_of[i].is_some() {
                D15::var(s.cam[i], i)
            } else {
                D15::cst(s.cam[i])
            }
        });
        let w15: [D15; 3] = std::array::from_fn(|i| D15::var(0.0, 9 + i));
        let nc = self.circles.len();
        let (rc, rs) = r.split_at_mut(2 * nc);
        // Dense rows: values of columns 0..n.
        let (_, vals) = rows.parts_mut();
        let (vc, vs) = vals.split_at_mut(2 * nc * n);
        let wc = self.wc();
        rc.par_chunks_mut(2)
            .zip(vc.par_chunks_mut(2 * n))
            .zip(self.circles.par_iter())
            .try_for_each(|((out, jrow), c)| -> Result<()> {
                let (rot, t) = &poses_f[c.view];
                let r0 = Matrix3::from_fn(|i, j| rot[i][j]);
                let rd = rot_times_exp_first_order(&r0, &w15);
                let td: [D15; 3] = std::array::from_fn(|i| D15::var(t[i], 12 + i));
                let nodes = quadrature_nodes(self.base.model);
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
                let ch = &chains[c.view];
                for (a, ua) in uv.iter().enumerate() {
                    let row = &mut jrow[a * n..(a + 1) * n];
                    for (slot, col) in col_of.iter().enumerate().take(9) {
                        if let Some(col) = col {
                            row[*col] = wc * ua.d[slot];
                        }
                    }
                    for kk in 0..12 {
                        let acc: f64 = (0..6).map(|q| ua.d[9 + q] * ch[q][kk]).sum();
                        row[o + 3 + kk] = wc * acc;
                    }
                }
                Ok(())
            })?;
        // Stripe points.
        let ws = self.ws();
        // Chain rule: d res = n^T (d pi/d P (d p0 + s d dir) + d pi/d camera), the line's
        // derivatives (plane, X, Z slots) from the per-view duals, the projection's by a
        // small dual over (x, y, k1..k3) at the point.
        rs.par_iter_mut()
            .zip(vs.par_chunks_mut(n))
            .zip(self.stripes.par_iter().zip(self.foot_cache.par_iter()))
            .try_for_each(|((out, row), (st, cache))| -> Result<()> {
                let Some((p0, dir)) = lines[st.view] else {
                    return Err(parallel_error(st.view));
                };
                let p0f = [p0[0].v, p0[1].v, p0[2].v];
                let dirf = [dir[0].v, dir[1].v, dir[2].v];
                let start = f64::from_bits(cache.load(Ordering::Relaxed));
                let (sf, normal) = foot_point(&s.cam, &p0f, &dirf, [st.u, st.v], start)?;
                cache.store(sf.to_bits(), Ordering::Relaxed);
                let pf: [f64; 3] = std::array::from_fn(|i| p0f[i] + sf * dirf[i]);
                let (x, y) = (pf[0] / pf[2], pf[1] / pf[2]);
                type D7 = Dual<7>;
                let kd: [D7; 5] = std::array::from_fn(|i| {
                    if col_of[4 + i].is_some() {
                        D7::var(s.cam[4 + i], 2 + i)
                    } else {
                        D7::cst(s.cam[4 + i])
                    }
                });
                let (d, _) = distort_generic(&kd, D7::var(x, 0), D7::var(y, 1));
                let (fu, fv) = (s.cam[0], s.cam[1]);
                let res = normal[0] * (fu * d[0].v + s.cam[2] - st.u)
                    + normal[1] * (fv * d[1].v + s.cam[3] - st.v);
                let (g0, g1) = (normal[0] * fu, normal[1] * fv);
                let drx = g0 * d[0].d[0] + g1 * d[1].d[0];
                let dry = g0 * d[0].d[1] + g1 * d[1].d[1];
                let dp = [drx / pf[2], dry / pf[2], -(drx * x + dry * y) / pf[2]];
                let mut full = [0.0; 24];
                full[0] = normal[0] * d[0].v;
                full[1] = normal[1] * d[1].v;
                full[2] = normal[0];
                full[3] = normal[1];
                for i in 0..5 {
                    full[4 + i] = g0 * d[0].d[2 + i] + g1 * d[1].d[2 + i];
                }
                for (slot, o) in full.iter_mut().enumerate().skip(SLOT_PLANE) {
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
                Ok(())
            })?;
        Ok(())
    }
    fn reweight(&self, r: &[f64]) -> Option<Vec<f64>> {
        if !self.variance_components
            || self
                .reweights_left
                .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |k| k.checked_sub(1))
                .is_err()
        {
            return None;
        }
        let (sc, ss) = self.sigmas(r);
        let (wc0, ws0) = (self.wc(), self.ws());
        let wc1 = sc.map_or(wc0, |s| 1.0 / s);
        let ws1 = 1.0 / ss;
        self.w_circle.store(wc1.to_bits(), Ordering::Relaxed);
        self.w_stripe.store(ws1.to_bits(), Ordering::Relaxed);
        let nc = 2 * self.circles.len();
        let (fc, fs) = (wc1 / wc0, ws1 / ws0);
        Some((0..r.len()).map(|i| if i < nc { fc } else { fs }).collect())
    }
    fn retract(&self, p: &[f64], dp: &[f64], out: &mut [f64]) {
        let o = self.ncam();
        for i in 0..o + 3 {
            out[i] = p[i] + dp[i];
        }
        for b in [o + 3, o + 9] {
            let r0 = rotvec_to_matrix(&Vector3::new(p[b], p[b + 1], p[b + 2]));
            let r = r0 * rotvec_to_matrix(&Vector3::new(dp[b], dp[b + 1], dp[b + 2]));
            let rv = matrix_to_rotvec(&r);
            for i in 0..3 {
                out[b + i] = rv[i];
                out[b + 3 + i] = p[b + 3 + i] + dp[b + 3 + i];
            }
        }
    }
}

fn parallel_error(view: usize) -> Error {
    Error::Degenerate(format!(
        "the laser plane is parallel to the board plane of view {view} (of the views used)"
    ))
}

/// Two unit vectors completing `n` to an orthonormal basis.
fn tangent_basis(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if n.x.abs() < 0.6 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = n.cross(&helper).normalize();
    let e2 = n.cross(&e1);
    (e1, e2)
}

/// `d rotvec / d w` for `rotvec(R Exp(w))` at `w = 0`: the inverse right Jacobian of SO(3)
/// at `r`.
fn inverse_right_jacobian(r: &Vector3<f64>) -> Matrix3<f64> {
    let th = r.norm();
    let k = r.cross_matrix();
    let c = if th < 1e-6 {
        1.0 / 12.0 + th * th / 720.0
    } else {
        (1.0 / (th * th)) - (1.0 + th.cos()) / (2.0 * th * th.sin())
    };
    Matrix3::identity() + k * 0.5 + k * k * c
}

/// The one-stage adjustment (module docs) over the views' circles and stripe points.
///
/// Every view used must carry `base_hand` (`T_base_hand`). Views without circles or
/// without `base_hand` are skipped with a warning. Errors: [`Error::InvalidInput`] for
/// fewer than 3 usable views, no stripe point at all, or non-finite observations;
/// [`Error::Degenerate`] when a view's stripe line cannot be formed; solver errors are
/// passed on.
pub fn joint_adjustment(
    views: &[ViewObs],
    board: &Board,
    start: &JointStart,
    opts: &JointOptions,
) -> Result<JointResult> {
    board.validate()?;
    start.camera.validate()?;
    let mut warnings = Vec::new();
    let mut a = Vec::new();
    let mut used = Vec::new();
    let mut circles = Vec::new();
    let mut stripes = Vec::new();
    for v in views {
        let Some(bh) = v.base_hand else {
            warnings.push(format!("view {}: left out, no robot pose", v.view));
            continue;
        };
        if v.circles.is_empty() && v.stripe.is_empty() {
            warnings.push(format!("view {}: left out, no observation", v.view));
            continue;
        }
        let vi = a.len();
        a.push(bh);
        used.push(v.view);
        for c in &v.circles {
            if !(c.u.is_finite() && c.v.is_finite()) || c.row >= board.rows || c.col >= board.cols {
                return Err(Error::InvalidInput(format!(
                    "view {}: circle ({}, {}) at ({}, {}) is not a valid observation",
                    v.view, c.row, c.col, c.u, c.v
                )));
            }
            let ctr = board.center(c.row, c.col);
            circles.push(CircleTerm {
                view: vi,
                row: c.row,
                col: c.col,
                centre: (ctr.x, ctr.y),
                radius: 0.5 * board.diameter(c.row, c.col),
                u: c.u,
                v: c.v,
            });
        }
        for s in &v.stripe {
            if !(s[0].is_finite() && s[1].is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "view {}: stripe point ({}, {}) is not finite",
                    v.view, s[0], s[1]
                )));
            }
            stripes.push(StripeTerm {
                view: vi,
                u: s[0],
                v: s[1],
            });
        }
    }
    if a.len() < 3 {
        return Err(Error::InvalidInput(format!(
            "the one-stage adjustment needs at least 3 views with a robot pose, got {}",
            a.len()
        )));
    }
    if stripes.is_empty() {
        return Err(Error::InvalidInput(
            "the one-stage adjustment needs stripe points (no view has any)".into(),
        ));
    }
    let model = start.camera.model;
    let mut free = vec![0, 1, 2, 3];
    for (i, f) in model.free_coefficients().iter().enumerate() {
        if *f {
            free.push(4 + i);
        }
    }
    let n0 = start.plane.normal;
    let (e1, e2) = tangent_basis(&n0);
    let mut problem = JointProblem {
        base: &start.camera,
        free: free.clone(),
        model: opts.centre_model,
        jacobian_model: opts.centre_model,
        n0,
        e1,
        e2,
        a,
        circles,
        stripes,
        w_circle: AtomicU64::new((1.0 / opts.initial_sigma_px.0).to_bits()),
        w_stripe: AtomicU64::new((1.0 / opts.initial_sigma_px.1).to_bits()),
        variance_components: opts.variance_components,
        robust_sigma: opts.robust,
        reweights_left: AtomicUsize::new(MAX_REWEIGHTS),
        foot_cache: Vec::new(),
    };
    problem.foot_cache = (0..problem.stripes.len())
        .map(|_| AtomicU64::new(f64::NAN.to_bits()))
        .collect();
    let cp = start.camera.params();
    let mut p: Vec<f64> = free.iter().map(|&i| cp[i]).collect();
    p.extend_from_slice(&[0.0, 0.0, start.plane.d]);
    for t in [&start.hand_cam, &start.base_board] {
        let (rv, tr) = iso_to_rotvec(t);
        p.extend_from_slice(&[rv.x, rv.y, rv.z, tr.x, tr.y, tr.z]);
    }
    let m_c = 2 * problem.circles.len();
    let m_s = problem.stripes.len();
    // Solves (residual model, Jacobian model, Huber). With the exact centroid model the
    // steps are taken with the first-order conic model's Jacobian (the residuals are
    // exact; an inexact Jacobian only changes the path, at a sixth of the cost), and a
    // last solve with the exact Jacobian checks convergence (usually it stops at its
    // first evaluation) and gives the covariance. The variance components are
    // re-estimated after every accepted step. Huber, when robust, from the second solve
    // on (the first, least squares, gives it a start and scale).
    let model = opts.centre_model;
    let step_model = if model == CentreModel::ConicExact {
        CentreModel::Conic
    } else {
        model
    };
    let mut solves = vec![(model, step_model, false)];
    if opts.robust {
        solves.push((model, step_model, true));
    }
    if step_model != model {
        solves.push((model, model, opts.robust));
    }
    let mut res: Option<LmResult> = None;
    let mut iterations = 0;
    for (model, jacobian_model, huber) in solves {
        let mut lm = opts.lm.clone();
        if huber {
            lm.huber = Some(HUBER_SIGMAS);
        }
        problem.model = model;
        problem.jacobian_model = jacobian_model;
        problem
            .reweights_left
            .store(MAX_REWEIGHTS, Ordering::Relaxed);
        let r = levenberg_marquardt(&problem, &p, &lm)?;
        iterations += r.iterations;
        p.clone_from(&r.params);
        res = Some(r);
    }
    let Some(res) = res else {
        return Err(Error::InvalidInput(
            "the one-stage adjustment did not run".into(),
        ));
    };
    let s = problem.decode(&res.params);
    let camera = start.camera.with_params(&s.cam);
    camera.validate()?;
    let plane = Plane::new(s.plane_n, s.plane_d)?;
    let o = problem.ncam();
    let pr = &res.params;
    let hand_cam = iso_from_rotvec(
        &Vector3::new(pr[o + 3], pr[o + 4], pr[o + 5]),
        &Vector3::new(pr[o + 6], pr[o + 7], pr[o + 8]),
    );
    let base_board = iso_from_rotvec(
        &Vector3::new(pr[o + 9], pr[o + 10], pr[o + 11]),
        &Vector3::new(pr[o + 12], pr[o + 13], pr[o + 14]),
    );

    // Uncertainty.
    let cov = &res.covariance;
    let mut cam_sigma = [0.0; 9];
    for (k, &i) in free.iter().enumerate() {
        cam_sigma[i] = cov[(k, k)].sqrt();
    }
    // Plane normal: n = normalize(n0 + a e1 + b e2); dn/d(a, b) at the solution.
    let nraw = n0 + e1 * pr[o] + e2 * pr[o + 1];
    let l = nraw.norm();
    let proj = (Matrix3::identity() - s.plane_n * s.plane_n.transpose()) / l;
    let jn = nalgebra::Matrix3x2::from_columns(&[proj * e1, proj * e2]);
    let cab = nalgebra::Matrix2::new(
        cov[(o, o)],
        cov[(o, o + 1)],
        cov[(o + 1, o)],
        cov[(o + 1, o + 1)],
    );
    let cn = jn * cab * jn.transpose();
    // A normal flipped by Plane::new (d < 0) has the same sigmas.
    let plane_normal = Vector3::new(cn[(0, 0)].sqrt(), cn[(1, 1)].sqrt(), cn[(2, 2)].sqrt());
    let tsig = |b: usize| -> TransformSigma {
        let rv = Vector3::new(pr[b], pr[b + 1], pr[b + 2]);
        let jr = inverse_right_jacobian(&rv);
        let cw = Matrix3::from_fn(|i, j| cov[(b + i, b + j)]);
        let crv = jr * cw * jr.transpose();
        TransformSigma {
            rotation_vector: Vector3::new(
                crv[(0, 0)].sqrt(),
                crv[(1, 1)].sqrt(),
                crv[(2, 2)].sqrt(),
            ),
            translation_mm: Vector3::new(
                cov[(b + 3, b + 3)].sqrt(),
                cov[(b + 4, b + 4)].sqrt(),
                cov[(b + 5, b + 5)].sqrt(),
            ),
        }
    };
    let sigma = JointSigma {
        camera: cam_sigma,
        plane_normal,
        plane_d_mm: cov[(o + 2, o + 2)].sqrt(),
        hand_cam: tsig(o + 3),
        base_board: tsig(o + 9),
    };

    // Unweighted residuals and reports.
    // The solver's final residuals carry the last round's weights.
    let (sc_final, ss_final) = (1.0 / problem.wc(), 1.0 / problem.ws());
    let raw: Vec<f64> = res
        .residuals
        .iter()
        .enumerate()
        .map(|(i, r)| r * if i < m_c { sc_final } else { ss_final })
        .collect();
    let mut circle_residuals = Vec::with_capacity(problem.circles.len());
    let mut vc = vec![(0.0, 0usize); problem.nviews()];
    for (k, c) in problem.circles.iter().enumerate() {
        let (du, dv) = (raw[2 * k], raw[2 * k + 1]);
        circle_residuals.push((used[c.view], c.row, c.col, c.u, c.v, du, dv));
        vc[c.view].0 += du * du + dv * dv;
        vc[c.view].1 += 1;
    }
    // mm per px on the board for each view's stripe: the image length of 1 mm of the
    // stripe line's normal offset, estimated from the view's pose.
    let mut vs = vec![(0.0, 0usize, 0.0); problem.nviews()];
    let mut stripe_residuals = Vec::with_capacity(m_s);
    let mm_per_px: Vec<f64> = s
        .view_poses(&problem.a)
        .into_iter()
        .map(|(rot, t)| {
            let depth = Vector3::from(t).norm();
            let tilt = rot[2][2].abs().max(0.1);
            // Image scale of the board at the stand-off, corrected for its tilt.
            depth / (0.5 * (s.cam[0] + s.cam[1])) / tilt
        })
        .collect();
    for (k, st) in problem.stripes.iter().enumerate() {
        let d = raw[m_c + k];
        stripe_residuals.push((used[st.view], st.u, st.v, d));
        let e = &mut vs[st.view];
        e.0 += d * d;
        e.1 += 1;
        e.2 += (d * mm_per_px[st.view]).powi(2);
    }
    let mut views_out = Vec::new();
    let mut ss_mm = 0.0;
    for (vi, &view) in used.iter().enumerate() {
        let crms = if vc[vi].1 > 0 {
            (vc[vi].0 / vc[vi].1 as f64).sqrt()
        } else {
            f64::NAN
        };
        let srms = if vs[vi].1 > 0 {
            (vs[vi].0 / vs[vi].1 as f64).sqrt()
        } else {
            f64::NAN
        };
        let smm = if vs[vi].1 > 0 {
            (vs[vi].2 / vs[vi].1 as f64).sqrt()
        } else {
            f64::NAN
        };
        ss_mm += vs[vi].2;
        // RMS per coordinate in sigmas.
        let zc = crms / std::f64::consts::SQRT_2 / sc_final;
        let zs = srms / ss_final;
        let outlier = zc > opts.outlier_sigmas || zs > opts.outlier_sigmas;
        if outlier {
            warnings.push(format!(
                "view {view}: outlier (circle RMS {crms:.4} px, stripe RMS {srms:.4} px vs \
                 sigmas {sc_final:.4} / {ss_final:.4} px per coordinate)"
            ));
        }
        views_out.push(ViewReport {
            view,
            circles: vc[vi].1,
            stripe_points: vs[vi].1,
            circle_rms_px: crms,
            stripe_rms_px: srms,
            stripe_rms_mm: smm,
            outlier,
        });
    }
    let circle_ss: f64 = raw[..m_c].iter().map(|x| x * x).sum();
    let stripe_ss: f64 = raw[m_c..].iter().map(|x| x * x).sum();
    let mut param_names: Vec<String> = free.iter().map(|&i| PARAM_NAMES[i].to_string()).collect();
    for nm in [
        "plane_a",
        "plane_b",
        "plane_d_mm",
        "hand_cam_wx",
        "hand_cam_wy",
        "hand_cam_wz",
        "hand_cam_tx_mm",
        "hand_cam_ty_mm",
        "hand_cam_tz_mm",
        "base_board_wx",
        "base_board_wy",
        "base_board_wz",
        "base_board_tx_mm",
        "base_board_ty_mm",
        "base_board_tz_mm",
    ] {
        param_names.push(nm.to_string());
    }
    let unobservable = res
        .unobservable
        .iter()
        .map(|&i| param_names[i].clone())
        .collect::<Vec<_>>();
    if !unobservable.is_empty() {
        warnings.push(format!(
            "unobservable parameters (their sigma is NaN): {}",
            unobservable.join(", ")
        ));
    }
    Ok(JointResult {
        camera,
        plane,
        hand_cam,
        base_board,
        sigma,
        circle_rms_px: if m_c > 0 {
            (circle_ss / (m_c / 2) as f64).sqrt()
        } else {
            f64::NAN
        },
        stripe_rms_px: (stripe_ss / m_s as f64).sqrt(),
        stripe_rms_mm: (ss_mm / m_s as f64).sqrt(),
        sigma_px: (sc_final, ss_final),
        views: views_out,
        param_names,
        covariance: res.covariance.clone(),
        iterations,
        stop_reason: res.reason,
        unobservable,
        circle_residuals,
        stripe_residuals,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::conic::predict_centre;
    use crate::calib::laser_plane::stripe_line_in_view;
    use crate::calib::CircleObs;
    use crate::model::camera::DistortionModel;

    struct Synth {
        cam: Camera,
        plane: Plane,
        x: Iso3,
        z: Iso3,
        views: Vec<ViewObs>,
    }

    fn synth(model: DistortionModel, k: [f64; 5]) -> Synth {
        let cam = Camera::new(768, 576, 1270.0, 1320.0, 380.0, 290.0, model, k).unwrap();
        let plane = Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap();
        let x = iso_from_rotvec(
            &Vector3::new(-0.3087, 0.2362, 3.0369),
            &Vector3::new(29.19, 5.37, 62.64),
        );
        let board = Board::hp3_paper();
        // Board 110 mm in front of the camera at view 0; other views rotate the hand.
        let cb0 = iso_from_rotvec(
            &Vector3::new(3.1, 0.05, 0.0),
            &Vector3::new(-18.0, -12.0, 112.0),
        );
        let a0 = iso_from_rotvec(
            &Vector3::new(0.0, 3.1, 0.0),
            &Vector3::new(480.0, 0.0, 300.0),
        );
        let z = a0 * x * cb0;
        let mut views = Vec::new();
        for (i, d) in [
            [0.0, 0.0, 0.0],
            [0.15, 0.0, 0.05],
            [0.0, 0.18, -0.1],
            [-0.12, 0.1, 0.2],
            [0.1, -0.15, -0.2],
        ]
        .iter()
        .enumerate()
        {
            // Rotate the camera about a point on the board in front of it.
            let bc0 = cb0.inverse();
            let rot = iso_from_rotvec(&Vector3::new(d[0], d[1], d[2]), &Vector3::zeros());
            let centre = iso_from_rotvec(&Vector3::zeros(), &Vector3::new(20.0, 15.0, 0.0));
            let bc = centre * rot * centre.inverse() * bc0;
            let cb = bc.inverse();
            let a = z * cb.inverse() * x.inverse();
            let mut circles = Vec::new();
            for (r, c) in board.indices() {
                let uv = predict_centre(
                    &cam,
                    &cb,
                    &board.center(r, c),
                    0.5 * board.diameter(r, c),
                    CentreModel::ConicExact,
                )
                .unwrap();
                circles.push(CircleObs {
                    row: r,
                    col: c,
                    u: uv.x,
                    v: uv.y,
                });
            }
            let l = stripe_line_in_view(&plane, &cb, &cam).unwrap();
            let stripe = (-20..20)
                .map(|s| {
                    let uv = cam
                        .project(&(l.point_cam + l.direction_cam * (s as f64)))
                        .unwrap();
                    [uv.x, uv.y]
                })
                .collect();
            views.push(ViewObs {
                view: i,
                circles,
                stripe,
                reading: None,
                base_hand: Some(a),
                alternatives: Vec::new(),
            });
        }
        Synth {
            cam,
            plane,
            x,
            z,
            views,
        }
    }

    fn iso_err(a: &Iso3, b: &Iso3) -> (f64, f64) {
        (
            a.rotation.angle_to(&b.rotation),
            (a.translation.vector - b.translation.vector).norm(),
        )
    }

    fn perturbed_start(s: &Synth) -> JointStart {
        let mut p = s.cam.params();
        p[0] += 3.0;
        p[1] -= 2.0;
        p[2] += 1.5;
        p[3] -= 1.0;
        let d = iso_from_rotvec(
            &Vector3::new(0.002, -0.001, 0.003),
            &Vector3::new(0.3, -0.2, 0.4),
        );
        JointStart {
            camera: s.cam.with_params(&p),
            plane: Plane::new(
                s.plane.normal + Vector3::new(0.01, -0.01, 0.005),
                s.plane.d + 0.5,
            )
            .unwrap(),
            hand_cam: s.x * d,
            base_board: d * s.z,
        }
    }

    #[test]
    fn exact_observations_recover_every_parameter() {
        for (model, k) in [
            (DistortionModel::Radial1, [0.05, 0.0, 0.0, 0.0, 0.0]),
            (DistortionModel::OpenCv5, [-0.2, 0.1, 1e-3, -1e-3, 0.02]),
        ] {
            let s = synth(model, k);
            let start = perturbed_start(&s);
            let r = joint_adjustment(
                &s.views,
                &Board::hp3_paper(),
                &start,
                &JointOptions::default(),
            )
            .unwrap();
            let (p, t) = (r.camera.params(), s.cam.params());
            for i in 0..9 {
                assert!(
                    (p[i] - t[i]).abs() <= 1e-6 * t[i].abs().max(1e-3),
                    "{model:?} {i}: {} vs {}",
                    p[i],
                    t[i]
                );
            }
            assert!((r.plane.normal - s.plane.normal).norm() < 1e-9);
            assert!((r.plane.d - s.plane.d).abs() < 1e-7);
            let (xr, xt) = iso_err(&r.hand_cam, &s.x);
            let (zr, zt) = iso_err(&r.base_board, &s.z);
            assert!(
                xr < 1e-9 && xt < 1e-7 && zr < 1e-9 && zt < 1e-7,
                "{xr} {xt} {zr} {zt}"
            );
            assert!(r.circle_rms_px < 1e-7 && r.stripe_rms_px < 1e-7);
        }
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let s = synth(DistortionModel::OpenCv5, [-0.2, 0.1, 1e-3, -1e-3, 0.02]);
        let start = perturbed_start(&s);
        let mut circles = Vec::new();
        let mut stripes = Vec::new();
        let board = Board::hp3_paper();
        let mut a = Vec::new();
        for (vi, v) in s.views.iter().enumerate() {
            a.push(v.base_hand.unwrap());
            for c in v.circles.iter().step_by(9) {
                let ctr = board.center(c.row, c.col);
                circles.push(CircleTerm {
                    view: vi,
                    row: c.row,
                    col: c.col,
                    centre: (ctr.x, ctr.y),
                    radius: 0.5 * board.diameter(c.row, c.col),
                    u: c.u + 0.3,
                    v: c.v - 0.2,
                });
            }
            for p in v.stripe.iter().step_by(7) {
                stripes.push(StripeTerm {
                    view: vi,
                    u: p[0] + 0.4,
                    v: p[1] - 0.3,
                });
            }
        }
        let (e1, e2) = tangent_basis(&start.plane.normal);
        let pr = JointProblem {
            base: &start.camera,
            free: (0..9).collect(),
            model: CentreModel::ConicExact,
            jacobian_model: CentreModel::ConicExact,
            n0: start.plane.normal,
            e1,
            e2,
            a,
            circles,
            stripes,
            w_circle: AtomicU64::new(2.0f64.to_bits()),
            w_stripe: AtomicU64::new(0.5f64.to_bits()),
            variance_components: false,
            robust_sigma: false,
            reweights_left: AtomicUsize::new(0),
            foot_cache: Vec::new(),
        };
        let mut pr = pr;
        pr.foot_cache = (0..pr.stripes.len())
            .map(|_| AtomicU64::new(f64::NAN.to_bits()))
            .collect();
        let mut p: Vec<f64> = start.camera.params().to_vec();
        p.extend_from_slice(&[0.01, -0.02, start.plane.d]);
        for t in [&start.hand_cam, &start.base_board] {
            let (rv, tr) = iso_to_rotvec(t);
            p.extend_from_slice(&[rv.x, rv.y, rv.z, tr.x, tr.y, tr.z]);
        }
        let step = |j: usize| {
            if j < 9 {
                1e-5 * p[j].abs().max(1e-2)
            } else {
                1e-6
            }
        };
        crate::numerics::lm::assert_jacobian_matches_fd(&pr, &p, step, 1e-9, 1e-5, "joint");
    }

    #[test]
    fn too_few_views_and_no_stripe_are_typed_errors() {
        let s = synth(DistortionModel::Radial1, [0.05, 0.0, 0.0, 0.0, 0.0]);
        let start = perturbed_start(&s);
        let b = Board::hp3_paper();
        let e = joint_adjustment(&s.views[..2], &b, &start, &JointOptions::default()).unwrap_err();
        assert!(matches!(e, Error::InvalidInput(_)), "{e}");
        let mut v = s.views.clone();
        for x in &mut v {
            x.stripe.clear();
        }
        let e = joint_adjustment(&v, &b, &start, &JointOptions::default()).unwrap_err();
        assert!(e.to_string().contains("stripe"), "{e}");
    }
}
