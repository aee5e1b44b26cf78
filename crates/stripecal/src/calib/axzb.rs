//! Hand-eye and robot-world calibration: `A_i X = Z B_i` (the paper's eq. 23, solved
//! in two linear steps and refined).
//!
//! ## Conventions
//!
//! `A_i = T_base_hand(q_i)`, `X = T_hand_cam`, `Z = T_base_board`,
//! `B_i = T_board_cam(i) = inverse(T_cam_board(i))` (spec/DATASET.md, ERRATA.md).
//! Translations in mm (any unit works: the result is in the unit of the input).
//!
//! ## Method
//!
//! 1. Rotations. `R_A R_X = R_Z R_B` is linear in `(vec R_X, vec R_Z)` (column-stacked
//!    `vec`): `(I3 kron R_A_i) vec(R_X) - (R_B_i^T kron I3) vec(R_Z) = 0`. Stacked over
//!    the views this is a homogeneous `9N x 18` system; its solution is the right
//!    singular vector of the smallest singular value (faer SVD). The common scale and
//!    sign are fixed by `det(R_X) = 1` (divide by `cbrt(det)`), then both matrices are
//!    projected on the nearest rotation.
//! 2. Translations, rotations fixed: `R_A_i t_X - t_Z = R_Z t_B_i - t_A_i`, a `3N x 6`
//!    linear least-squares problem (faer QR).
//!
//!    Unlike the paper's single system (23), the two steps keep radians and millimetres
//!    out of one least-squares problem (OpenCV's `CALIB_ROBOT_WORLD_HAND_EYE_LI` solves
//!    the joint system; the two-step split is its `SHAH` method).
//! 3. Refinement (on by default): least squares ([`crate::numerics::lm`], the one
//!    Levenberg-Marquardt solver) on the per-view rotation residual
//!    `log(R_Z R_B_i (R_A_i R_X)^T)` (rad) and translation residual
//!    `R_A_i t_X + t_A_i - R_Z t_B_i - t_Z` (mm), each kind weighted by the inverse of
//!    its RMS after step 2, so neither unit dominates. Measured under OpenCV's own test
//!    noise (tests/test_axzb.py, 10 poses, 100 trials, unit-scale scene), median errors
//!    X rot / X trans / Z rot / Z trans: linear steps alone 0.166 deg / 0.01266 /
//!    0.158 deg / 0.01356 (identical to OpenCV SHAH), refined 0.129 deg / 0.01259 /
//!    0.133 deg / 0.01237 (measured with the Gauss-Newton loop the solver replaced; both
//!    converge to the same minimum); OpenCV LI 0.170 deg / 0.01293 / 0.169 deg / 0.01410.
//!
//! ## Degenerate pose sets
//!
//! X and Z are unique only when the relative robot motions `A_i^-1 A_j` rotate about at
//! least two distinct axes. [`solve_axzb`] measures this ([`Conditioning`]) and refuses
//! with [`Error::Degenerate`] and the figure: fewer than 3 poses, largest rotation
//! between two poses below [`MIN_ROTATION_DEG`], relative rotation axes spanning less
//! than [`MIN_AXIS_SPREAD_DEG`]. Weak (but solvable) sets give warnings.

use faer::linalg::solvers::SolveLstsq;
use faer::{Mat, MatMut};
use nalgebra::{Matrix3, SMatrix, Vector3};

use crate::error::{Error, Result};
use crate::model::geometry::{
    iso_from_parts, matrix_to_rotvec, nearest_rotation, rotvec_to_matrix, Iso3,
};
use crate::numerics::lm::{levenberg_marquardt, LeastSquares, LmOptions};

/// Refuse when the largest rotation between any two poses is below this (degrees).
pub const MIN_ROTATION_DEG: f64 = 1.0;
/// Refuse when the relative rotation axes span less than this (degrees).
pub const MIN_AXIS_SPREAD_DEG: f64 = 1.0;
/// Warn when the largest rotation between poses is below this (degrees).
pub const WEAK_ROTATION_DEG: f64 = 10.0;
/// Warn when the relative rotation axes span less than this (degrees).
pub const WEAK_AXIS_SPREAD_DEG: f64 = 10.0;
/// At most this many poses (evenly subsampled) enter the all-pairs conditioning figures.
const CONDITIONING_MAX_POSES: usize = 200;
/// Solver iterations of the refinement.
const REFINE_MAX_ITER: usize = 20;

/// How well a pose set determines X and Z (figures from the robot poses `A_i`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditioning {
    /// The angle (degrees, 0..90) the rotation axes of the relative motions
    /// `A_i^-1 A_j` span: `2 atan(sqrt(l2 / l1))` of the angle^2-weighted axis scatter
    /// (exactly the angle between the axes when there are two equally weighted ones).
    /// Near 0: all motions rotate about one axis, X and Z are not unique.
    pub axis_spread_deg: f64,
    /// The largest rotation between two poses (degrees).
    pub max_rotation_deg: f64,
    /// The smallest rotation between two poses (degrees); near 0: duplicate poses.
    pub min_rotation_deg: f64,
    /// `s_1 / s_17` of the `9N x 18` rotation system (its largest singular value over
    /// the second smallest one, the smallest belonging to the solution): large when the
    /// solution is not isolated.
    pub rotation_condition: f64,
}

/// Options of [`solve_axzb_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxzbOptions {
    /// Run the Gauss-Newton refinement after the linear steps (default true).
    pub refine: bool,
}

impl Default for AxzbOptions {
    fn default() -> Self {
        AxzbOptions { refine: true }
    }
}

/// The result of [`solve_axzb`].
#[derive(Debug, Clone, PartialEq)]
pub struct AxzbSolution {
    /// `X = T_hand_cam`.
    pub x: Iso3,
    /// `Z = T_base_board`.
    pub z: Iso3,
    /// RMS over the views of the angle of `R_Z R_B_i (R_A_i R_X)^T`, radians.
    pub rotation_residual_rad: f64,
    /// RMS over the views of `|R_A_i t_X + t_A_i - R_Z t_B_i - t_Z|`, mm.
    pub translation_residual_mm: f64,
    /// Conditioning figures of the pose set.
    pub conditioning: Conditioning,
    /// Whether the refinement ran (and lowered the weighted cost).
    pub refined: bool,
    /// Human-readable warnings (weak pose set, large residuals).
    pub warnings: Vec<String>,
}

/// Solves `A_i X = Z B_i` with the default options (refinement on).
pub fn solve_axzb(a: &[Iso3], b: &[Iso3]) -> Result<AxzbSolution> {
    solve_axzb_with(a, b, &AxzbOptions::default())
}

/// Solves `A_i X = Z B_i` for `X = T_hand_cam`, `Z = T_base_board` from
/// `A_i = T_base_hand(q_i)` and `B_i = T_board_cam(i)` (see the module docs).
///
/// Errors: [`Error::InvalidInput`] for different lengths or non-finite transforms,
/// [`Error::Degenerate`] (with the figure) for pose sets that do not determine X and Z.
pub fn solve_axzb_with(a: &[Iso3], b: &[Iso3], opts: &AxzbOptions) -> Result<AxzbSolution> {
    check_inputs(a, b)?;
    let ra: Vec<Matrix3<f64>> = a
        .iter()
        .map(|t| *t.rotation.to_rotation_matrix().matrix())
        .collect();
    let rb: Vec<Matrix3<f64>> = b
        .iter()
        .map(|t| *t.rotation.to_rotation_matrix().matrix())
        .collect();
    let ta: Vec<Vector3<f64>> = a.iter().map(|t| t.translation.vector).collect();
    let tb: Vec<Vector3<f64>> = b.iter().map(|t| t.translation.vector).collect();
    let (axis_spread_deg, max_rotation_deg, min_rotation_deg) = checked_motion_figures(&ra)?;
    let (rx, rz, rotation_condition) = solve_rotations(&ra, &rb)?;
    let (tx, tz) = solve_translations(&ra, &ta, &tb, &rz)?;
    let data = Data {
        ra: &ra,
        rb: &rb,
        ta: &ta,
        tb: &tb,
    };
    let mut est = Est { rx, tx, rz, tz };
    let mut refined = false;
    if opts.refine {
        (est, refined) = data.refine(est);
    }
    let (rotation_residual_rad, translation_residual_mm) = data.rms(&est);
    let conditioning = Conditioning {
        axis_spread_deg,
        max_rotation_deg,
        min_rotation_deg,
        rotation_condition,
    };
    Ok(AxzbSolution {
        x: iso_from_parts(&est.rx, &est.tx),
        z: iso_from_parts(&est.rz, &est.tz),
        rotation_residual_rad,
        translation_residual_mm,
        warnings: pose_set_warnings(&conditioning, rotation_residual_rad),
        conditioning,
        refined,
    })
}

/// As many `A` as `B`, finite rigid transforms, at least 3 of them.
fn check_inputs(a: &[Iso3], b: &[Iso3]) -> Result<()> {
    if a.len() != b.len() {
        return Err(Error::InvalidInput(format!(
            "AX = ZB needs as many A (robot poses) as B (board poses): got {} and {}",
            a.len(),
            b.len()
        )));
    }
    for (name, set) in [("A", a), ("B", b)] {
        for (i, t) in set.iter().enumerate() {
            let q = &t.rotation;
            let finite = t.translation.vector.iter().all(|v| v.is_finite())
                && q.coords.iter().all(|v| v.is_finite());
            if !finite || (q.coords.norm() - 1.0).abs() > 1e-6 {
                return Err(Error::InvalidInput(format!(
                    "AX = ZB: {name}[{i}] is not a finite rigid transform"
                )));
            }
        }
    }
    let n = a.len();
    if n < 3 {
        return Err(Error::Degenerate(format!(
            "AX = ZB needs at least 3 poses (relative motions about two distinct axes), got {n}"
        )));
    }
    Ok(())
}

/// [`motion_figures`], refusing pose sets that do not determine X and Z.
fn checked_motion_figures(ra: &[Matrix3<f64>]) -> Result<(f64, f64, f64)> {
    let (axis_spread_deg, max_rotation_deg, min_rotation_deg) = motion_figures(ra);
    if max_rotation_deg < MIN_ROTATION_DEG {
        return Err(Error::Degenerate(format!(
            "AX = ZB: largest rotation between poses {max_rotation_deg:.3} deg (need at least \
             {MIN_ROTATION_DEG} deg, better 30 deg or more about different axes)"
        )));
    }
    if axis_spread_deg < MIN_AXIS_SPREAD_DEG {
        return Err(Error::Degenerate(format!(
            "AX = ZB: relative rotation axes span only {axis_spread_deg:.3} deg (need at \
             least {MIN_AXIS_SPREAD_DEG} deg; rotate the hand about two or more different axes)"
        )));
    }
    Ok((axis_spread_deg, max_rotation_deg, min_rotation_deg))
}

/// Step 1 (module docs): `R_X`, `R_Z` from the `9N x 18` homogeneous system, and its
/// condition figure `s_1 / s_17`.
fn solve_rotations(
    ra: &[Matrix3<f64>],
    rb: &[Matrix3<f64>],
) -> Result<(Matrix3<f64>, Matrix3<f64>, f64)> {
    let n = ra.len();
    let mut m = Mat::<f64>::zeros(9 * n, 18);
    for i in 0..n {
        let r0 = 9 * i;
        // (I3 kron R_A): block-diagonal with R_A.
        for blk in 0..3 {
            for r in 0..3 {
                for c in 0..3 {
                    m[(r0 + 3 * blk + r, 3 * blk + c)] = ra[i][(r, c)];
                }
            }
        }
        // -(R_B^T kron I3): block (p, q) = -R_B[(q, p)] * I3.
        for p in 0..3 {
            for q in 0..3 {
                let v = -rb[i][(q, p)];
                for k in 0..3 {
                    m[(r0 + 3 * p + k, 9 + 3 * q + k)] = v;
                }
            }
        }
    }
    let svd = m.thin_svd().map_err(|e| {
        Error::Degenerate(format!("AX = ZB: SVD of the rotation system failed: {e:?}"))
    })?;
    let s = svd.S().column_vector();
    let v = svd.V();
    let s_max = s[0];
    let s_17 = s[16];
    let rotation_condition = if s_17 > 0.0 {
        s_max / s_17
    } else {
        f64::INFINITY
    };
    let mut rx = Matrix3::zeros();
    let mut rz = Matrix3::zeros();
    for c in 0..3 {
        for r in 0..3 {
            rx[(r, c)] = v[(3 * c + r, 17)];
            rz[(r, c)] = v[(9 + 3 * c + r, 17)];
        }
    }
    let det = rx.determinant();
    if !det.is_finite() || det.abs() < 1e-12 {
        return Err(Error::Degenerate(format!(
            "AX = ZB: the rotation system's solution is singular (det {det:.3e}; condition \
             {rotation_condition:.3e})"
        )));
    }
    let scale = 1.0 / det.cbrt();
    let rx = nearest_rotation(&(rx * scale));
    let rz = nearest_rotation(&(rz * scale));
    Ok((rx, rz, rotation_condition))
}

/// Step 2 (module docs): `t_X`, `t_Z` from the `3N x 6` least squares, rotations fixed.
fn solve_translations(
    ra: &[Matrix3<f64>],
    ta: &[Vector3<f64>],
    tb: &[Vector3<f64>],
    rz: &Matrix3<f64>,
) -> Result<(Vector3<f64>, Vector3<f64>)> {
    let n = ra.len();
    let mut mt = Mat::<f64>::zeros(3 * n, 6);
    let mut rhs = Mat::<f64>::zeros(3 * n, 1);
    for i in 0..n {
        let rzb = rz * tb[i] - ta[i];
        for r in 0..3 {
            for c in 0..3 {
                mt[(3 * i + r, c)] = ra[i][(r, c)];
            }
            mt[(3 * i + r, 3 + r)] = -1.0;
            rhs[(3 * i + r, 0)] = rzb[r];
        }
    }
    let sol = mt.qr().solve_lstsq(&rhs);
    let tx = Vector3::new(sol[(0, 0)], sol[(1, 0)], sol[(2, 0)]);
    let tz = Vector3::new(sol[(3, 0)], sol[(4, 0)], sol[(5, 0)]);
    if !(tx.iter().chain(tz.iter()).all(|v| v.is_finite())) {
        return Err(Error::Degenerate(
            "AX = ZB: the translation system has no finite solution".into(),
        ));
    }
    Ok((tx, tz))
}

/// Warnings for a weak (but solvable) pose set and a large rotation residual.
fn pose_set_warnings(c: &Conditioning, rotation_residual_rad: f64) -> Vec<String> {
    let (max_rotation_deg, axis_spread_deg) = (c.max_rotation_deg, c.axis_spread_deg);
    let mut warnings = Vec::new();
    if max_rotation_deg < WEAK_ROTATION_DEG {
        warnings.push(format!(
            "weak pose set: largest rotation between poses {max_rotation_deg:.2} deg (below \
             {WEAK_ROTATION_DEG} deg): X and Z are poorly determined"
        ));
    }
    if axis_spread_deg < WEAK_AXIS_SPREAD_DEG {
        warnings.push(format!(
            "weak pose set: relative rotation axes span only {axis_spread_deg:.2} deg (below \
             {WEAK_AXIS_SPREAD_DEG} deg): X and Z are poorly determined"
        ));
    }
    if rotation_residual_rad.to_degrees() > 1.0 {
        warnings.push(format!(
            "large rotation residual {:.2} deg RMS: poses and board views may not match",
            rotation_residual_rad.to_degrees()
        ));
    }
    warnings
}

/// Axis spread, largest and smallest relative rotation (degrees) of all pose pairs
/// (at most [`CONDITIONING_MAX_POSES`] evenly subsampled poses).
fn motion_figures(ra: &[Matrix3<f64>]) -> (f64, f64, f64) {
    let n = ra.len();
    let step = n.div_ceil(CONDITIONING_MAX_POSES).max(1);
    let idx: Vec<usize> = (0..n).step_by(step).collect();
    let mut scatter = Matrix3::<f64>::zeros();
    let (mut max_a, mut min_a) = (0.0_f64, f64::INFINITY);
    for (k, &i) in idx.iter().enumerate() {
        for &j in &idx[k + 1..] {
            let rel = ra[i].transpose() * ra[j];
            let r = matrix_to_rotvec(&rel);
            let ang = r.norm();
            max_a = max_a.max(ang);
            min_a = min_a.min(ang);
            // angle^2-weighted axis outer product = r r^T.
            scatter += r * r.transpose();
        }
    }
    let eig = scatter.symmetric_eigen();
    let mut ev: Vec<f64> = eig.eigenvalues.iter().map(|v| v.max(0.0)).collect();
    ev.sort_by(|x, y| y.total_cmp(x));
    let spread = if ev[0] > 0.0 {
        2.0 * (ev[1] / ev[0]).sqrt().atan()
    } else {
        0.0
    };
    if !min_a.is_finite() {
        min_a = 0.0;
    }
    (spread.to_degrees(), max_a.to_degrees(), min_a.to_degrees())
}

#[derive(Debug, Clone, Copy)]
struct Est {
    rx: Matrix3<f64>,
    tx: Vector3<f64>,
    rz: Matrix3<f64>,
    tz: Vector3<f64>,
}

struct Data<'a> {
    ra: &'a [Matrix3<f64>],
    rb: &'a [Matrix3<f64>],
    ta: &'a [Vector3<f64>],
    tb: &'a [Vector3<f64>],
}

/// The inverse left Jacobian of SO(3) at `phi`: `d log(exp(d) R) = J_l^-1 d`.
fn inv_left_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let th = phi.norm();
    let k = phi.cross_matrix();
    let c = if th < 1e-4 {
        1.0 / 12.0 + th * th / 720.0
    } else {
        1.0 / (th * th) - (1.0 + th.cos()) / (2.0 * th * th.sin())
    };
    Matrix3::identity() - k * 0.5 + k * k * c
}

impl Data<'_> {
    /// Per-view residuals: rotation (rad, base frame) and translation.
    fn residual(&self, e: &Est, i: usize) -> (Vector3<f64>, Vector3<f64>) {
        let m = e.rz * self.rb[i] * (self.ra[i] * e.rx).transpose();
        let rr = matrix_to_rotvec(&m);
        let rt = self.ra[i] * e.tx + self.ta[i] - e.rz * self.tb[i] - e.tz;
        (rr, rt)
    }

    fn rms(&self, e: &Est) -> (f64, f64) {
        let n = self.ra.len() as f64;
        let (mut sr, mut st) = (0.0, 0.0);
        for i in 0..self.ra.len() {
            let (rr, rt) = self.residual(e, i);
            sr += rr.norm_squared();
            st += rt.norm_squared();
        }
        ((sr / n).sqrt(), (st / n).sqrt())
    }

    fn cost(&self, e: &Est, wr: f64, wt: f64) -> f64 {
        (0..self.ra.len())
            .map(|i| {
                let (rr, rt) = self.residual(e, i);
                wr * wr * rr.norm_squared() + wt * wt * rt.norm_squared()
            })
            .sum()
    }

    /// Step 3 (module docs): the least-squares refinement ([`Refinement`], solved by
    /// [`levenberg_marquardt`]) from `est` on the residuals weighted by the inverse RMS
    /// of each kind at `est`; the refined estimate if it lowered the cost.
    fn refine(&self, est: Est) -> (Est, bool) {
        let (rot_rms, tr_rms) = self.rms(&est);
        let scale_t = self
            .ta
            .iter()
            .chain(self.tb.iter())
            .map(|t| t.norm())
            .fold(0.0_f64, f64::max)
            .max(1e-300);
        // Weights: inverse RMS of each residual kind (floored so exact data stays finite).
        let wr = 1.0 / rot_rms.max(1e-14);
        let wt = 1.0 / tr_rms.max(1e-14 * scale_t);
        let before = self.cost(&est, wr, wt);
        let problem = Refinement { data: self, wr, wt };
        let opts = LmOptions {
            max_iterations: REFINE_MAX_ITER,
            ..LmOptions::default()
        };
        let Ok(res) = levenberg_marquardt(&problem, &Refinement::params(&est), &opts) else {
            return (est, false);
        };
        let refined = Refinement::est(&res.params);
        if self.cost(&refined, wr, wt) < before {
            (refined, true)
        } else {
            (est, false)
        }
    }

    /// The weighted residual rows of view `i` differentiated w.r.t. the increment
    /// `[w_x, dt_x, w_z, dt_z]` (`R_X <- R_X exp(w_x)`, `R_Z <- exp(w_z) R_Z`).
    fn jacobian_rows(&self, e: &Est, i: usize, wr: f64, wt: f64) -> SMatrix<f64, 6, 12> {
        let (rr, _) = self.residual(e, i);
        let jl = inv_left_jacobian(&rr);
        let jr = inv_left_jacobian(&(-rr));
        let mut j = SMatrix::<f64, 6, 12>::zeros();
        // rotation rows
        let d_wx = -(jr * self.ra[i] * e.rx) * wr;
        j.fixed_view_mut::<3, 3>(0, 0).copy_from(&d_wx);
        j.fixed_view_mut::<3, 3>(0, 6).copy_from(&(jl * wr));
        // translation rows
        j.fixed_view_mut::<3, 3>(3, 3).copy_from(&(self.ra[i] * wt));
        let rzt = e.rz * self.tb[i];
        j.fixed_view_mut::<3, 3>(3, 6)
            .copy_from(&(rzt.cross_matrix() * wt));
        j.fixed_view_mut::<3, 3>(3, 9)
            .copy_from(&(-Matrix3::identity() * wt));
        j
    }
}

/// The refinement as a least-squares problem over `[rotvec(R_X), t_X, rotvec(R_Z), t_Z]`:
/// per view the rotation residual `log(R_Z R_B_i (R_A_i R_X)^T)` weighted by `wr` and
/// the translation residual weighted by `wt`; the solver's increment is applied as
/// `R_X exp(w_x)`, `t_X + dt_x`, `exp(w_z) R_Z`, `t_Z + dt_z`.
struct Refinement<'a> {
    data: &'a Data<'a>,
    wr: f64,
    wt: f64,
}

impl Refinement<'_> {
    fn est(p: &[f64]) -> Est {
        Est {
            rx: rotvec_to_matrix(&Vector3::new(p[0], p[1], p[2])),
            tx: Vector3::new(p[3], p[4], p[5]),
            rz: rotvec_to_matrix(&Vector3::new(p[6], p[7], p[8])),
            tz: Vector3::new(p[9], p[10], p[11]),
        }
    }

    fn params(e: &Est) -> Vec<f64> {
        let (wx, wz) = (matrix_to_rotvec(&e.rx), matrix_to_rotvec(&e.rz));
        [wx, e.tx, wz, e.tz]
            .iter()
            .flat_map(|v| [v.x, v.y, v.z])
            .collect()
    }
}

impl LeastSquares for Refinement<'_> {
    fn num_params(&self) -> usize {
        12
    }
    fn num_residuals(&self) -> usize {
        6 * self.data.ra.len()
    }
    fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        let e = Self::est(p);
        for (i, ri) in r.chunks_exact_mut(6).enumerate() {
            let (rr, rt) = self.data.residual(&e, i);
            for k in 0..3 {
                ri[k] = rr[k] * self.wr;
                ri[3 + k] = rt[k] * self.wt;
            }
        }
        Ok(())
    }
    fn residuals_and_jacobian(
        &self,
        p: &[f64],
        r: &mut [f64],
        mut jac: MatMut<'_, f64>,
    ) -> Result<()> {
        self.residuals(p, r)?;
        let e = Self::est(p);
        for i in 0..self.data.ra.len() {
            let j = self.data.jacobian_rows(&e, i, self.wr, self.wt);
            for a in 0..6 {
                for b in 0..12 {
                    jac[(6 * i + a, b)] = j[(a, b)];
                }
            }
        }
        Ok(())
    }
    fn retract(&self, p: &[f64], dp: &[f64], out: &mut [f64]) {
        let e = Self::est(p);
        let rx = e.rx * rotvec_to_matrix(&Vector3::new(dp[0], dp[1], dp[2]));
        let rz = rotvec_to_matrix(&Vector3::new(dp[6], dp[7], dp[8])) * e.rz;
        let (wx, wz) = (matrix_to_rotvec(&rx), matrix_to_rotvec(&rz));
        for k in 0..3 {
            out[k] = wx[k];
            out[3 + k] = p[3 + k] + dp[3 + k];
            out[6 + k] = wz[k];
            out[9 + k] = p[9 + k] + dp[9 + k];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::iso_from_rotvec;

    fn rv(x: f64, y: f64, z: f64) -> Vector3<f64> {
        Vector3::new(x, y, z)
    }

    fn sample() -> (Iso3, Iso3, Vec<Iso3>, Vec<Iso3>) {
        let x = iso_from_rotvec(&rv(0.3, -0.2, 2.9), &rv(30.0, 5.0, 60.0));
        let z = iso_from_rotvec(&rv(0.1, 0.05, -0.4), &rv(450.0, -20.0, 10.0));
        let a: Vec<Iso3> = (0..6)
            .map(|k| {
                let f = k as f64;
                iso_from_rotvec(
                    &rv(2.9 + 0.1 * f, 0.2 * (f - 2.0), 0.15 * f.sin()),
                    &rv(400.0 + 10.0 * f, -30.0 + 7.0 * f, 300.0 - 5.0 * f),
                )
            })
            .collect();
        let b = a.iter().map(|ai| z.inverse() * ai * x).collect();
        (x, z, a, b)
    }

    #[test]
    fn exact_data_is_recovered() {
        let (x, z, a, b) = sample();
        for refine in [false, true] {
            let s = solve_axzb_with(&a, &b, &AxzbOptions { refine }).unwrap();
            assert!((s.x.to_homogeneous() - x.to_homogeneous()).abs().max() < 1e-9);
            assert!((s.z.to_homogeneous() - z.to_homogeneous()).abs().max() < 1e-9);
            assert!(s.rotation_residual_rad < 1e-12);
        }
    }

    #[test]
    fn refinement_jacobian_matches_central_differences() {
        let (x, z, a, b) = sample();
        // Perturbed board poses: non-zero residuals.
        let b: Vec<Iso3> = b
            .iter()
            .enumerate()
            .map(|(k, bi)| {
                let f = k as f64;
                bi * iso_from_rotvec(&rv(0.01 * f, -0.005, 0.002), &rv(0.3, -0.1 * f, 0.2))
            })
            .collect();
        let rot = |t: &Iso3| *t.rotation.to_rotation_matrix().matrix();
        let ra: Vec<Matrix3<f64>> = a.iter().map(rot).collect();
        let rb: Vec<Matrix3<f64>> = b.iter().map(rot).collect();
        let ta: Vec<Vector3<f64>> = a.iter().map(|t| t.translation.vector).collect();
        let tb: Vec<Vector3<f64>> = b.iter().map(|t| t.translation.vector).collect();
        let data = Data {
            ra: &ra,
            rb: &rb,
            ta: &ta,
            tb: &tb,
        };
        let est = Est {
            rx: rot(&x),
            tx: x.translation.vector,
            rz: rot(&z),
            tz: z.translation.vector,
        };
        let pr = Refinement {
            data: &data,
            wr: 50.0,
            wt: 0.5,
        };
        let p = Refinement::params(&est);
        crate::numerics::lm::assert_jacobian_matches_fd(&pr, &p, |_| 1e-6, 1e-12, 1e-5, "axzb");
    }

    #[test]
    fn mismatched_lengths_and_two_poses_are_errors() {
        let (_, _, a, b) = sample();
        assert!(matches!(
            solve_axzb(&a[..3], &b[..2]),
            Err(Error::InvalidInput(_))
        ));
        let e = solve_axzb(&a[..2], &b[..2]).unwrap_err().to_string();
        assert!(
            e.contains("at least 3 poses") && e.ends_with("got 2"),
            "{e}"
        );
    }
}
