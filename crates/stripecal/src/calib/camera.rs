//! Camera calibration from circle-grid views: homographies -> Zhang -> Levenberg-
//! Marquardt over intrinsics, the model's free distortion coefficients and the per-view
//! board poses, predicting imaged centres with the bias-free conic model
//! ([`crate::calib::conic`]).
//!
//! ## Parameters of the adjustment
//!
//! `[fu, fv, u0, v0, <free distortion coefficients of the model>]`, then per view
//! `(w, v)`: the pose increment of [`crate::calib::conic`] (`R = R0 Exp(w)`,
//! `t = t0 + v`); the state keeps each pose as a rotation vector and a translation.
//! Pose one-sigmas are therefore: rotation about the BOARD axes (rad), translation in
//! the camera frame (mm).

use faer::MatMut;
use nalgebra::{Vector2, Vector3};
use rayon::prelude::*;

use crate::calib::clustered::ViewShare;
use crate::calib::conic::{
    centre_any_model, centre_any_model_with_jacobians, centre_generic_n, quadrature_nodes,
    CentreModel, CentreScalar,
};
use crate::calib::homography::fit_homography;
use crate::calib::zhang::{pose_from_homography, zhang_intrinsics};
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::camera::{Camera, DistortionModel, Intrinsics, Projection};
use crate::model::geometry::{
    iso_from_rotvec, iso_to_rotvec, matrix_to_rotvec, rotvec_to_matrix, Iso3,
};
use crate::numerics::dual::Dual;
use crate::numerics::lm::{
    dense_jacobian_from_rows, levenberg_marquardt, JacobianRows, LeastSquares, LmOptions, LmResult,
    StopReason,
};
use crate::numerics::mat3::rot_times_exp_first_order;

/// Options of [`calibrate_camera`].
#[derive(Debug, Clone, PartialEq)]
pub struct CameraOptions {
    /// Centre model of the adjustment (default: exact conic centroid).
    pub centre_model: CentreModel,
    /// Solver options.
    pub lm: LmOptions,
    /// Minimum circles for a view to be used (>= 4).
    pub min_circles: usize,
    /// Widen the camera's sigmas to the views' own scatter where that is larger
    /// ([`crate::calib::clustered`]; default true).
    pub clustered_covariance: bool,
}

impl Default for CameraOptions {
    fn default() -> Self {
        CameraOptions {
            centre_model: CentreModel::ConicExact,
            lm: LmOptions {
                max_iterations: 200,
                ..Default::default()
            },
            min_circles: 4,
            clustered_covariance: true,
        }
    }
}

/// One-sigma of a view's pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSigma {
    /// Rotation about the board axes, rad.
    pub rotation_rad: Vector3<f64>,
    /// Translation, mm.
    pub translation_mm: Vector3<f64>,
}

/// The result of [`calibrate_camera`].
#[derive(Debug, Clone)]
pub struct CameraCalibration {
    pub camera: Camera,
    /// `(view index (ViewObs::view), T_cam_board)` of every used view.
    pub poses: Vec<(usize, Iso3)>,
    /// RMS of the circle-centre residuals (per coordinate... as a 2D distance), px.
    pub rms_px: f64,
    /// Per used view (same order as `poses`): RMS 2D residual, px.
    pub per_view_rms_px: Vec<f64>,
    /// One-sigma per camera parameter in the model's
    /// [`crate::model::camera::CameraModel::param_names`] order (`brown5`:
    /// [`crate::model::camera::PARAM_NAMES`]; a model with fewer parameters leaves the
    /// last slots 0), 0 for fixed ones, NaN for unobservable ones.
    pub camera_sigma: [f64; 9],
    /// One-sigma of each pose (same order as `poses`).
    pub pose_sigma: Vec<PoseSigma>,
    /// LM iterations.
    pub iterations: usize,
    pub stop_reason: StopReason,
    /// The closed-form (Zhang) intrinsics before refinement `[fu, fv, u0, v0]`.
    pub initial_intrinsics: [f64; 4],
    /// Names of parameters found unobservable.
    pub unobservable: Vec<String>,
    /// Views dropped, with the reason (naming the view index).
    pub warnings: Vec<String>,
}

struct Obs {
    view: usize, // index into used views
    centre: (f64, f64),
    radius: f64,
    u: f64,
    v: f64,
}

struct CamProblem<'a> {
    base: &'a Camera,
    free: Vec<usize>, // indices into the model's camera parameters
    nviews: usize,
    obs: Vec<Obs>,
    model: CentreModel,
}

impl CamProblem<'_> {
    fn ncam(&self) -> usize {
        self.free.len()
    }
    /// The camera of the parameters `p` (any model).
    fn camera(&self, p: &[f64]) -> Camera {
        if self.base.projection.is_brown5() {
            return self.base.with_params(&self.cam_params(p));
        }
        let mut c = self.base.model_params();
        for (k, &i) in self.free.iter().enumerate() {
            c[i] = p[k];
        }
        self.base.with_model_params(&c)
    }
    /// `brown5`'s parameter vector of `p`.
    fn cam_params(&self, p: &[f64]) -> [f64; 9] {
        let mut c = self.base.params();
        for (k, &i) in self.free.iter().enumerate() {
            c[i] = p[k];
        }
        c
    }
    /// Predicted imaged centre of observation `o`'s circle (camera and pose generic).
    fn predict<T: CentreScalar>(
        &self,
        cam: &[T; 9],
        pose: &([[T; 3]; 3], [T; 3]),
        o: &Obs,
    ) -> Result<[T; 2]> {
        let (rot, t) = pose;
        centre_generic_n(
            cam,
            rot,
            t,
            o.centre,
            o.radius,
            self.model,
            quadrature_nodes(self.base.model),
        )
    }
    fn pose(&self, p: &[f64], v: usize) -> ([[f64; 3]; 3], [f64; 3]) {
        let o = self.ncam() + 6 * v;
        let r = rotvec_to_matrix(&Vector3::new(p[o], p[o + 1], p[o + 2]));
        (
            std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)])),
            [p[o + 3], p[o + 4], p[o + 5]],
        )
    }
    /// [`LeastSquares::residuals_and_jacobian_rows`] for a model other than `brown5`:
    /// the analytic Jacobians of [`centre_any_model_with_jacobians`].
    fn rows_any_model(&self, p: &[f64], r: &mut [f64], rows: &mut JacobianRows) -> Result<()> {
        let cam = self.camera(p);
        let nc = self.ncam();
        let width = nc + 6;
        let r0: Vec<_> = (0..self.nviews)
            .map(|v| {
                let o = nc + 6 * v;
                rotvec_to_matrix(&Vector3::new(p[o], p[o + 1], p[o + 2]))
            })
            .collect();
        let (cols, vals) = rows.parts_mut();
        r.par_chunks_mut(2)
            .zip(cols.par_chunks_mut(2 * width))
            .zip(vals.par_chunks_mut(2 * width))
            .zip(self.obs.par_iter())
            .try_for_each(|(((r, cols), vals), o)| -> Result<()> {
                let q = nc + 6 * o.view;
                let t0 = [p[q + 3], p[q + 4], p[q + 5]];
                let (uv, jc, jp) = centre_any_model_with_jacobians(
                    &cam,
                    &r0[o.view],
                    &t0,
                    o.centre,
                    o.radius,
                    self.model,
                )?;
                for a in 0..2 {
                    r[a] = uv[a] - if a == 0 { o.u } else { o.v };
                    let (c, v) = (
                        &mut cols[a * width..(a + 1) * width],
                        &mut vals[a * width..(a + 1) * width],
                    );
                    for (k, &i) in self.free.iter().enumerate() {
                        c[k] = k;
                        v[k] = jc[(a, i)];
                    }
                    for k in 0..6 {
                        c[nc + k] = q + k;
                        v[nc + k] = jp[(a, k)];
                    }
                }
                Ok(())
            })
    }
}

impl LeastSquares for CamProblem<'_> {
    fn num_params(&self) -> usize {
        self.ncam() + 6 * self.nviews
    }
    fn num_residuals(&self) -> usize {
        2 * self.obs.len()
    }
    fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        let c = self.cam_params(p);
        let poses: Vec<_> = (0..self.nviews).map(|v| self.pose(p, v)).collect();
        let preds: Vec<[f64; 2]> = if self.base.projection.is_brown5() {
            self.obs
                .par_iter()
                .map(|o| self.predict(&c, &poses[o.view], o))
                .collect::<Result<_>>()?
        } else {
            let cam = self.camera(p);
            self.obs
                .par_iter()
                .map(|o| {
                    let (rot, t) = &poses[o.view];
                    centre_any_model(&cam, rot, t, o.centre, o.radius, self.model)
                })
                .collect::<Result<_>>()?
        };
        for (k, (o, uv)) in self.obs.iter().zip(&preds).enumerate() {
            r[2 * k] = uv[0] - o.u;
            r[2 * k + 1] = uv[1] - o.v;
        }
        Ok(())
    }
    fn residuals_and_jacobian(&self, p: &[f64], r: &mut [f64], jac: MatMut<'_, f64>) -> Result<()> {
        dense_jacobian_from_rows(self, p, r, jac)
    }
    fn jacobian_row_width(&self) -> Option<usize> {
        // The free camera parameters and the view's pose.
        Some(self.ncam() + 6)
    }
    fn residuals_and_jacobian_rows(
        &self,
        p: &[f64],
        r: &mut [f64],
        rows: &mut JacobianRows,
    ) -> Result<()> {
        if !self.base.projection.is_brown5() {
            return self.rows_any_model(p, r, rows);
        }
        type D = Dual<15>;
        let c = self.cam_params(p);
        let mut cd: [D; 9] = std::array::from_fn(|i| D::cst(c[i]));
        for (k, &i) in self.free.iter().enumerate() {
            cd[i] = D::var(c[i], k);
        }
        let nc = self.ncam();
        let w: [D; 3] = std::array::from_fn(|i| D::var(0.0, 9 + i));
        let poses: Vec<_> = (0..self.nviews)
            .map(|v| {
                let o = nc + 6 * v;
                let r0 = rotvec_to_matrix(&Vector3::new(p[o], p[o + 1], p[o + 2]));
                let rot = rot_times_exp_first_order(&r0, &w);
                let t: [D; 3] = std::array::from_fn(|i| D::var(p[o + 3 + i], 12 + i));
                (rot, t)
            })
            .collect();
        let width = nc + 6;
        let (cols, vals) = rows.parts_mut();
        r.par_chunks_mut(2)
            .zip(cols.par_chunks_mut(2 * width))
            .zip(vals.par_chunks_mut(2 * width))
            .zip(self.obs.par_iter())
            .try_for_each(|(((r, cols), vals), o)| -> Result<()> {
                let uv = self.predict(&cd, &poses[o.view], o)?;
                for a in 0..2 {
                    r[a] = uv[a].v - if a == 0 { o.u } else { o.v };
                    let (c, v) = (
                        &mut cols[a * width..(a + 1) * width],
                        &mut vals[a * width..(a + 1) * width],
                    );
                    for q in 0..nc {
                        c[q] = q;
                        v[q] = uv[a].d[q];
                    }
                    for q in 0..6 {
                        c[nc + q] = nc + 6 * o.view + q;
                        v[nc + q] = uv[a].d[9 + q];
                    }
                }
                Ok(())
            })
    }
    fn retract(&self, p: &[f64], dp: &[f64], out: &mut [f64]) {
        let nc = self.ncam();
        for i in 0..nc {
            out[i] = p[i] + dp[i];
        }
        for v in 0..self.nviews {
            let o = nc + 6 * v;
            let r0 = rotvec_to_matrix(&Vector3::new(p[o], p[o + 1], p[o + 2]));
            let r = r0 * rotvec_to_matrix(&Vector3::new(dp[o], dp[o + 1], dp[o + 2]));
            let rv = matrix_to_rotvec(&r);
            for i in 0..3 {
                out[o + i] = rv[i];
                out[o + 3 + i] = p[o + 3 + i] + dp[o + 3 + i];
            }
        }
    }
}

/// Calibrates the camera from circle observations (see the module docs).
///
/// Views with fewer than `opts.min_circles` circles or whose homography fails are
/// dropped (listed in `warnings`). Errors: [`Error::InvalidInput`] for a bad board or
/// image size, non-finite or out-of-grid observations, or fewer than 3 usable views;
/// errors of Zhang's method ([`Error::Degenerate`]) and of the adjustment are passed on.
pub fn calibrate_camera(
    views: &[ViewObs],
    board: &Board,
    width: u32,
    height: u32,
    model: DistortionModel,
    opts: &CameraOptions,
) -> Result<CameraCalibration> {
    calibrate_camera_model(views, board, width, height, Projection::Brown5, model, opts)
}

/// [`calibrate_camera`] for a camera of the projection model `projection` (its
/// coefficients start at 0; `model` says which `brown5` estimates, others estimate all
/// theirs: [`crate::model::camera::CameraModel::free_coefficients`]). A model other
/// than `brown5` predicts with [`centre_any_model`]: the conic or naive centre models,
/// or any with a target of points ([`CentreModel::ConicExact`] on circles is an error).
pub fn calibrate_camera_model(
    views: &[ViewObs],
    board: &Board,
    width: u32,
    height: u32,
    projection: Projection,
    model: DistortionModel,
    opts: &CameraOptions,
) -> Result<CameraCalibration> {
    check_inputs(views, board, width, height)?;
    let mut warnings = Vec::new();
    let used = view_homographies(views, board, opts.min_circles, &mut warnings)?;
    let hs: Vec<_> = used.iter().map(|(_, h)| *h).collect();
    let scale = 0.5 * (width as f64 + height as f64);
    let k0 = zhang_intrinsics(&hs, None, scale)?;
    let initial_intrinsics = [k0.fu, k0.fv, k0.u0, k0.v0];
    let base = Camera::new(
        width,
        height,
        Intrinsics {
            fu: k0.fu,
            fv: k0.fv,
            u0: k0.u0,
            v0: k0.v0,
        },
        model,
        [0.0; 5],
    )?;
    let base = if projection.is_brown5() {
        base
    } else {
        base.with_projection(
            projection,
            &vec![0.0; projection.model().distortion_count()],
        )?
    };
    let mut free = vec![0, 1, 2, 3];
    for (i, f) in projection
        .model()
        .free_coefficients(model)
        .iter()
        .enumerate()
    {
        if *f {
            free.push(4 + i);
        }
    }
    let (mut problem, p0) = start_problem(&base, free, &used, board, &k0.k(), opts)?;
    // The exact centroid model is solved from the first-order conic model's solution
    // (the two differ by the distortion curvature only: a few exact iterations).
    let p0 = if opts.centre_model == CentreModel::ConicExact {
        problem.model = CentreModel::Conic;
        let first = levenberg_marquardt(&problem, &p0, &opts.lm)?.params;
        problem.model = CentreModel::ConicExact;
        first
    } else {
        p0
    };
    let res = levenberg_marquardt(&problem, &p0, &opts.lm)?;
    let camera = problem.camera(&res.params);
    camera.validate()?;
    Ok(collect_result(
        &problem,
        &res,
        opts.clustered_covariance,
        &used,
        camera,
        initial_intrinsics,
        warnings,
    ))
}

/// A valid board and image size, finite observations on the board's grid.
fn check_inputs(views: &[ViewObs], board: &Board, width: u32, height: u32) -> Result<()> {
    board.validate()?;
    if width == 0 || height == 0 {
        return Err(Error::InvalidInput(format!(
            "image size {width}x{height} must be positive"
        )));
    }
    for v in views {
        for c in &v.circles {
            if !(c.u.is_finite() && c.v.is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "view {}: circle ({}, {}) has a non-finite centre",
                    v.view, c.row, c.col
                )));
            }
            if c.row >= board.rows || c.col >= board.cols {
                return Err(Error::InvalidInput(format!(
                    "view {}: circle ({}, {}) is outside the {} x {} board",
                    v.view, c.row, c.col, board.rows, board.cols
                )));
            }
        }
    }
    Ok(())
}

/// The views with enough circles and a homography (board -> image), the others
/// dropped with a warning; an error below 3 views.
fn view_homographies<'v>(
    views: &'v [ViewObs],
    board: &Board,
    min_circles: usize,
    warnings: &mut Vec<String>,
) -> Result<Vec<(&'v ViewObs, nalgebra::Matrix3<f64>)>> {
    let mut used: Vec<(&ViewObs, nalgebra::Matrix3<f64>)> = Vec::new();
    for v in views {
        if v.circles.len() < min_circles.max(4) {
            warnings.push(format!(
                "view {}: dropped, only {} circles (need {})",
                v.view,
                v.circles.len(),
                min_circles.max(4)
            ));
            continue;
        }
        let plane: Vec<Vector2<f64>> = v
            .circles
            .iter()
            .map(|c| {
                let p = board.center(c.row, c.col);
                Vector2::new(p.x, p.y)
            })
            .collect();
        let image: Vec<Vector2<f64>> = v.circles.iter().map(|c| Vector2::new(c.u, c.v)).collect();
        match fit_homography(&plane, &image) {
            Ok((h, _)) => used.push((v, h)),
            Err(e) => warnings.push(format!("view {}: dropped, homography failed: {e}", v.view)),
        }
    }
    if used.len() < 3 {
        return Err(Error::InvalidInput(format!(
            "camera calibration needs at least 3 usable views, got {}{}",
            used.len(),
            if warnings.is_empty() {
                String::new()
            } else {
                format!(" ({})", warnings.join("; "))
            }
        )));
    }
    Ok(used)
}

/// The adjustment problem over the used views and its start: the `base` camera's free
/// parameters, then each view's pose from its homography and the intrinsics `kmat`.
fn start_problem<'a>(
    base: &'a Camera,
    free: Vec<usize>,
    used: &[(&ViewObs, nalgebra::Matrix3<f64>)],
    board: &Board,
    kmat: &nalgebra::Matrix3<f64>,
    opts: &CameraOptions,
) -> Result<(CamProblem<'a>, Vec<f64>)> {
    let mut obs = Vec::new();
    let start = base.model_params();
    let mut p0: Vec<f64> = free.iter().map(|&i| start[i]).collect();
    for (vi, (v, h)) in used.iter().enumerate() {
        let pose = pose_from_homography(h, kmat)?;
        let (rv, t) = iso_to_rotvec(&pose);
        p0.extend_from_slice(&[rv.x, rv.y, rv.z, t.x, t.y, t.z]);
        for c in &v.circles {
            let ctr = board.center(c.row, c.col);
            obs.push(Obs {
                view: vi,
                centre: (ctr.x, ctr.y),
                radius: 0.5 * board.diameter(c.row, c.col),
                u: c.u,
                v: c.v,
            });
        }
    }
    let problem = CamProblem {
        base,
        free,
        nviews: used.len(),
        obs,
        model: opts.centre_model,
    };
    Ok((problem, p0))
}

/// The camera's sigmas from the model's covariance widened to the views' own scatter
/// ([`crate::calib::clustered`]); `None` when it cannot be formed (four views or fewer,
/// unobservable parameters).
fn widened_camera_sigma(problem: &CamProblem<'_>, res: &LmResult) -> Option<Vec<f64>> {
    if !res.unobservable.is_empty() {
        return None;
    }
    let (n, m, nc) = (
        problem.num_params(),
        problem.num_residuals(),
        problem.ncam(),
    );
    let mut r = vec![0.0; m];
    let mut rows = JacobianRows::new(m, problem.jacobian_row_width()?, n);
    problem
        .residuals_and_jacobian_rows(&res.params, &mut r, &mut rows)
        .ok()?;
    let mut shares: Vec<ViewShare> = (0..problem.nviews)
        .map(|v| ViewShare::new(nc, nc + 6 * v..nc + 6 * v + 6))
        .collect();
    for (k, o) in problem.obs.iter().enumerate() {
        for i in [2 * k, 2 * k + 1] {
            let (cols, vals) = rows.row(i);
            shares[o.view].add_row(cols, vals, r[i]);
        }
    }
    let shares: Vec<_> = shares
        .into_iter()
        .map(ViewShare::reduced)
        .collect::<Option<_>>()?;
    let model = res.covariance.view((0, 0), (nc, nc)).into_owned();
    let (wide, _) = crate::calib::clustered::widened(&model, &shares)?;
    Some((0..nc).map(|k| wide[(k, k)].max(0.0).sqrt()).collect())
}

/// The calibration of the solution `res` (giving `camera`): poses, sigmas, RMS values
/// and unobservable names.
fn collect_result(
    problem: &CamProblem<'_>,
    res: &LmResult,
    clustered: bool,
    used: &[(&ViewObs, nalgebra::Matrix3<f64>)],
    camera: Camera,
    initial_intrinsics: [f64; 4],
    warnings: Vec<String>,
) -> CameraCalibration {
    let free = &problem.free;
    let nc = free.len();
    let mut camera_sigma = [0.0; 9];
    let widened = clustered
        .then(|| widened_camera_sigma(problem, res))
        .flatten();
    for (k, &i) in free.iter().enumerate() {
        camera_sigma[i] = widened.as_ref().map_or(res.sigma[k], |w| w[k]);
    }
    let mut poses = Vec::new();
    let mut pose_sigma = Vec::new();
    let mut per_view_ss = vec![(0.0, 0usize); used.len()];
    for (k, o) in problem.obs.iter().enumerate() {
        let e = &mut per_view_ss[o.view];
        e.0 += res.residuals[2 * k].powi(2) + res.residuals[2 * k + 1].powi(2);
        e.1 += 1;
    }
    for (vi, (v, _)) in used.iter().enumerate() {
        let o = nc + 6 * vi;
        let p = &res.params;
        poses.push((
            v.view,
            iso_from_rotvec(
                &Vector3::new(p[o], p[o + 1], p[o + 2]),
                &Vector3::new(p[o + 3], p[o + 4], p[o + 5]),
            ),
        ));
        let s = &res.sigma;
        pose_sigma.push(PoseSigma {
            rotation_rad: Vector3::new(s[o], s[o + 1], s[o + 2]),
            translation_mm: Vector3::new(s[o + 3], s[o + 4], s[o + 5]),
        });
    }
    let per_view_rms_px = per_view_ss
        .iter()
        .map(|(s, n)| (s / (*n).max(1) as f64).sqrt())
        .collect();
    let rms_px = (res.ssr / problem.obs.len() as f64).sqrt();
    let unobservable = res
        .unobservable
        .iter()
        .map(|&i| {
            if i < nc {
                problem.base.projection.model().param_names()[free[i]].to_string()
            } else {
                let v = (i - nc) / 6;
                let q = (i - nc) % 6;
                format!(
                    "view {} pose {}",
                    used[v].0.view,
                    ["wx", "wy", "wz", "tx", "ty", "tz"][q]
                )
            }
        })
        .collect();
    CameraCalibration {
        camera,
        poses,
        rms_px,
        per_view_rms_px,
        camera_sigma,
        pose_sigma,
        iterations: res.iterations,
        stop_reason: res.reason,
        initial_intrinsics,
        unobservable,
        warnings,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::conic::predict_centre;

    fn synthetic(model: CentreModel) -> (Camera, Vec<Iso3>, CamProblem<'static>, Vec<f64>) {
        let cam = Camera::new(
            1024,
            768,
            Intrinsics {
                fu: 900.0,
                fv: 900.5,
                u0: 515.3,
                v0: 380.8,
            },
            DistortionModel::OpenCv5,
            [-0.25, 0.12, 1e-3, -2e-3, 0.01],
        )
        .unwrap();
        let poses = vec![
            iso_from_rotvec(
                &Vector3::new(0.3, 0.1, 0.2),
                &Vector3::new(-20.0, -15.0, 100.0),
            ),
            iso_from_rotvec(
                &Vector3::new(-0.2, 0.35, -0.1),
                &Vector3::new(-25.0, -10.0, 110.0),
            ),
        ];
        let board = Board::hp3_paper();
        let mut obs = Vec::new();
        for (v, t) in poses.iter().enumerate() {
            for (r, c) in board.indices().step_by(7) {
                let ctr = board.center(r, c);
                let rad = 0.5 * board.diameter(r, c);
                let uv = predict_centre(&cam, t, &ctr, rad, model).unwrap();
                obs.push(Obs {
                    view: v,
                    centre: (ctr.x, ctr.y),
                    radius: rad,
                    u: uv.x + 0.1,
                    v: uv.y - 0.05,
                });
            }
        }
        let base: &'static Camera = Box::leak(Box::new(cam.clone()));
        let pr = CamProblem {
            base,
            free: (0..9).collect(),
            nviews: poses.len(),
            obs,
            model,
        };
        let mut p: Vec<f64> = cam.params().to_vec();
        for t in &poses {
            let (rv, tr) = iso_to_rotvec(t);
            p.extend_from_slice(&[rv.x, rv.y, rv.z, tr.x, tr.y, tr.z]);
        }
        (cam, poses, pr, p)
    }

    #[test]
    fn adjustment_jacobian_matches_central_differences_through_retract() {
        for model in [
            CentreModel::Naive,
            CentreModel::Conic,
            CentreModel::ConicExact,
        ] {
            let (_, _, pr, p) = synthetic(model);
            let step = |j: usize| {
                if j < 9 {
                    1e-4 * p[j].abs().max(1.0)
                } else if (j - 9) % 6 < 3 {
                    1e-6
                } else {
                    1e-5
                }
            };
            let what = format!("{model:?}");
            crate::numerics::lm::assert_jacobian_matches_fd(&pr, &p, step, 1e-12, 1e-6, &what);
        }
    }
}
