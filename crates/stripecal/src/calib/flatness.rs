//! The flatness figure of a board view: the sag of the best-fitting cylinder.
//!
//! A paper board held by hand is not flat, and a calibration that assumes it is absorbs
//! the bend into the lens distortion or the focal length. This module measures the bend
//! of ONE view from its own detections, so a quality gate can name the view with its
//! figure and leave it out (docs/flatness.md).
//!
//! ## The model
//!
//! The printed point at board coordinates `(X, Y)` lies at `(X, Y, z(X, Y))` in the
//! board frame (`z` points into the board, away from the camera; the board frame is the
//! contract's), with the height field the general quadric
//!
//! ```text
//! z(X, Y) = 1/2 [dX dY] H [dX dY]^T,   dX = X - cX,  dY = Y - cY,   H = [[hxx, hxy], [hxy, hyy]]
//! ```
//!
//! (`(cX, cY)` the centroid of the view's board points; any affine part of the height
//! is a change of the board pose, so it is left to the pose). `H` is the height's
//! Hessian: its eigenvector `u` with the eigenvalue of largest magnitude `k1` is the
//! direction ACROSS the bend, the other eigenvector the cylinder's AXIS. Over the
//! width `W` of the view's board points along `u` (max minus min of `P . u`), the
//! best-fitting cylinder (parabolic section) is
//!
//! ```text
//! z(x') = -s (1 - (2 x' / W)^2),   x' = (P - c) . u,     so   s = k1 W^2 / 8
//! ```
//!
//! `s` is the SAG in mm: positive when the middle of the board bulges TOWARDS the
//! camera, negative when it sinks away. `sag2_mm` is the same figure along the axis
//! (`k2 W2^2 / 8`, `W2` the width along the axis): near 0 for a cylinder.
//!
//! ## The adjustment
//!
//! Parameters: the board pose (`R = Exp(w) R0`, `t = t0 + v`) and `(hxx, hxy, hyy)`,
//! started at the given pose and a flat board; Gauss-Newton on the pixel residuals of
//! every detected point, with the analytic Jacobian (checked against finite
//! differences in the tests). Circle centres are detected as centroids of the imaged
//! outline, which are not the projections of the centres: the offset (the conic
//! model's centroid minus the projected centre, [`crate::calib::conic`]) is computed at
//! the starting pose and removed from the observations first (it would otherwise mimic
//! a small bend); after a first fit it is computed again for each circle lying in the
//! tangent plane of the fitted sheet (the bend tilts the circles by up to `4 s / W`
//! rad, which changes their offsets by a part that grows linearly across the board and
//! reads as 0.5 % of the sag), and the fit repeated. The covariance is
//! `s0^2 (J^T J)^-1` with `s0^2` the residuals' variance (`SSR / (2n - 9)`), or the
//! given pixel sigma; `sigma_mm` is the sag's one-sigma from it (`ds = W^2/8 u^T dH u`).

use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, SMatrix, UnitQuaternion, Vector2, Vector3};

use crate::calib::conic::{predict_centre, CentreModel};
use crate::calib::CircleObs;
use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::{Board, Camera};

/// Parameters of the adjustment: rotation increment (3), translation (3), `hxx, hxy, hyy`.
const NPAR: usize = 9;
/// Gauss-Newton iterations at most.
const MAX_ITER: usize = 30;

/// One detected board point: board coordinates (mm, `z = 0` on a flat board), the
/// radius of its circle (0 for a chessboard corner) and its detected image position (px).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlatPoint {
    pub board_xy: [f64; 2],
    pub radius_mm: f64,
    pub uv: [f64; 2],
}

/// Options of [`fit_flatness`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FlatnessOptions {
    /// The detections' one-sigma in px; `None`: estimated from the residuals.
    pub sigma_px: Option<f64>,
}

/// The flatness figure of one view (module docs for the definitions).
#[derive(Debug, Clone, PartialEq)]
pub struct Flatness {
    /// Sag of the best-fitting cylinder across the bend, mm (positive: the middle
    /// bulges towards the camera).
    pub sag_mm: f64,
    /// One-sigma of `sag_mm`, mm.
    pub sigma_mm: f64,
    /// Direction of the cylinder's axis in the board plane, degrees from board x, in
    /// `(-90, 90]`.
    pub axis_deg: f64,
    /// The width `W` the sag is measured over (across the bend), mm.
    pub width_mm: f64,
    /// The sag along the axis (the other principal direction), mm: near 0 for a cylinder.
    pub sag2_mm: f64,
    /// Its one-sigma, mm.
    pub sigma2_mm: f64,
    /// RMS pixel residual of the bent fit and of the flat board (the starting pose
    /// refined with `H = 0`), px.
    pub rms_px: f64,
    pub rms_flat_px: f64,
    /// Points used.
    pub points: usize,
    /// The refined `T_cam_board` of the bent fit.
    pub cam_board: Iso3,
    /// `[hxx, hxy, hyy]`, 1/mm.
    pub hessian: [f64; 3],
}

impl Flatness {
    /// The sag in units of its sigma (0 when the sigma is 0).
    pub fn significance(&self) -> f64 {
        if self.sigma_mm > 0.0 {
            self.sag_mm.abs() / self.sigma_mm
        } else {
            0.0
        }
    }
}

/// The flatness of a circle-grid or chessboard view from its detections: `circles` of
/// `board` (grid indices and imaged centres), `cam_board` a good estimate of the view's
/// pose (e.g. the calibration's), `camera` the calibrated camera.
pub fn view_flatness(
    camera: &Camera,
    board: &Board,
    circles: &[CircleObs],
    cam_board: &Iso3,
    opts: &FlatnessOptions,
) -> Result<Flatness> {
    let pts: Vec<FlatPoint> = circles
        .iter()
        .map(|c| {
            let p = board.center(c.row, c.col);
            FlatPoint {
                board_xy: [p.x, p.y],
                radius_mm: 0.5 * board.diameter(c.row, c.col),
                uv: [c.u, c.v],
            }
        })
        .collect();
    fit_flatness(camera, &pts, cam_board, opts)
}

/// The state of the adjustment.
#[derive(Debug, Clone, Copy)]
struct State {
    rot: UnitQuaternion<f64>,
    t: Vector3<f64>,
    h: [f64; 3],
    center: [f64; 2],
}

impl State {
    /// The board-frame point of board coordinates (x, y) on the bent sheet.
    fn board_point(&self, xy: [f64; 2]) -> (Vector3<f64>, [f64; 3]) {
        let dx = xy[0] - self.center[0];
        let dy = xy[1] - self.center[1];
        // dz / d(hxx, hxy, hyy)
        let dz = [0.5 * dx * dx, dx * dy, 0.5 * dy * dy];
        let z = self.h[0] * dz[0] + self.h[1] * dz[1] + self.h[2] * dz[2];
        (Vector3::new(xy[0], xy[1], z), dz)
    }

    /// Predicted pixel of a point and its Jacobian w.r.t. the 9 parameters.
    fn predict(
        &self,
        camera: &Camera,
        xy: [f64; 2],
    ) -> Result<(Vector2<f64>, SMatrix<f64, 2, NPAR>)> {
        let (pb, dz) = self.board_point(xy);
        let rp = self.rot * pb;
        let pc = rp + self.t;
        let (uv, jp, _) = camera.project_with_jacobians(&pc)?;
        let mut j = SMatrix::<f64, 2, NPAR>::zeros();
        // R = Exp(w) R: dp/dw = -[R P]x
        let skew = -Matrix3::new(0.0, -rp.z, rp.y, rp.z, 0.0, -rp.x, -rp.y, rp.x, 0.0);
        j.fixed_view_mut::<2, 3>(0, 0).copy_from(&(jp * skew));
        j.fixed_view_mut::<2, 3>(0, 3).copy_from(&jp);
        let nz = self.rot * Vector3::z();
        let jz = jp * nz;
        for k in 0..3 {
            j[(0, 6 + k)] = jz.x * dz[k];
            j[(1, 6 + k)] = jz.y * dz[k];
        }
        Ok((uv, j))
    }

    fn apply(&mut self, d: &DVector<f64>, bend: bool) {
        let w = Vector3::new(d[0], d[1], d[2]);
        self.rot = UnitQuaternion::from_scaled_axis(w) * self.rot;
        self.t += Vector3::new(d[3], d[4], d[5]);
        if bend {
            for k in 0..3 {
                self.h[k] += d[6 + k];
            }
        }
    }
}

/// Result of one Gauss-Newton run: final state, normal matrix, sum of squares.
type GnRun = (State, DMatrix<f64>, f64);

/// Gauss-Newton from `s0`; `bend` false holds `H` at its value (a flat board).
fn gauss_newton(
    camera: &Camera,
    pts: &[FlatPoint],
    obs: &[Vector2<f64>],
    s0: State,
    bend: bool,
) -> Result<GnRun> {
    let np = if bend { NPAR } else { 6 };
    let mut s = s0;
    let mut last = (DMatrix::zeros(np, np), f64::INFINITY);
    for _ in 0..MAX_ITER {
        let mut n = DMatrix::<f64>::zeros(np, np);
        let mut b = DVector::<f64>::zeros(np);
        let mut ssr = 0.0;
        for (p, o) in pts.iter().zip(obs) {
            let (uv, j) = s.predict(camera, p.board_xy)?;
            let r = o - uv;
            ssr += r.norm_squared();
            let j = j.columns(0, np).into_owned();
            let jt = j.transpose();
            n += &jt * &j;
            b += &jt * r;
        }
        last = (n.clone(), ssr);
        let d = n.clone().cholesky().map(|c| c.solve(&b)).ok_or_else(|| {
            Error::Degenerate("flatness: the board pose and bend are not determined".into())
        })?;
        let mut full = DVector::<f64>::zeros(NPAR);
        full.rows_mut(0, np).copy_from(&d);
        s.apply(&full, bend);
        if d.amax() < 1e-12 {
            break;
        }
    }
    // the normal matrix and SSR at the final state
    let mut n = DMatrix::<f64>::zeros(np, np);
    let mut ssr = 0.0;
    for (p, o) in pts.iter().zip(obs) {
        let (uv, j) = s.predict(camera, p.board_xy)?;
        ssr += (o - uv).norm_squared();
        let j = j.columns(0, np).into_owned();
        n += j.transpose() * &j;
    }
    if !ssr.is_finite() {
        return Err(Error::Degenerate(format!(
            "flatness: the adjustment diverged (last SSR {:.3e})",
            last.1
        )));
    }
    Ok((s, n, ssr))
}

/// The detections with each circle's centroid offset removed: the conic model's imaged
/// centroid minus the projected centre, for the circle lying in the tangent plane of the
/// sheet of `s` at its centre (chessboard corners, radius 0, are left as they are).
fn centre_corrected(camera: &Camera, pts: &[FlatPoint], s: &State) -> Result<Vec<Vector2<f64>>> {
    let cam_board = Iso3::from_parts(s.t.into(), s.rot);
    pts.iter()
        .map(|p| {
            let o = Vector2::new(p.uv[0], p.uv[1]);
            if p.radius_mm <= 0.0 {
                return Ok(o);
            }
            let (pb, _) = s.board_point(p.board_xy);
            let dx = p.board_xy[0] - s.center[0];
            let dy = p.board_xy[1] - s.center[1];
            // the sheet's gradient and the tangent frame (z along the normal)
            let gx = s.h[0] * dx + s.h[1] * dy;
            let gy = s.h[1] * dx + s.h[2] * dy;
            let nz = Vector3::new(-gx, -gy, 1.0).normalize();
            let tilt = UnitQuaternion::rotation_between(&Vector3::z(), &nz)
                .unwrap_or_else(UnitQuaternion::identity);
            let local = cam_board * Iso3::from_parts(pb.into(), tilt);
            let exact = predict_centre(
                camera,
                &local,
                &Vector3::zeros(),
                p.radius_mm,
                CentreModel::ConicExact,
            )?;
            let naive = camera.project(&(cam_board * nalgebra::Point3::from(pb)).coords)?;
            Ok(o - (exact - naive))
        })
        .collect()
}

/// The flatness figure from detected points (module docs). At least 12 points, not on
/// one line, are needed; fewer is an error.
pub fn fit_flatness(
    camera: &Camera,
    pts: &[FlatPoint],
    cam_board: &Iso3,
    opts: &FlatnessOptions,
) -> Result<Flatness> {
    if pts.len() < 12 {
        return Err(Error::InvalidInput(format!(
            "flatness: {} board points (at least 12 are needed)",
            pts.len()
        )));
    }
    if let Some(sp) = opts.sigma_px {
        if !(sp.is_finite() && sp > 0.0) {
            return Err(Error::InvalidInput(format!(
                "flatness: sigma_px {sp} must be finite and > 0"
            )));
        }
    }
    let n = pts.len() as f64;
    let center = [
        pts.iter().fold(0.0, |a, p| a + p.board_xy[0]) / n,
        pts.iter().fold(0.0, |a, p| a + p.board_xy[1]) / n,
    ];
    let s0 = State {
        rot: cam_board.rotation,
        t: cam_board.translation.vector,
        h: [0.0; 3],
        center,
    };
    // observations with the circle-centre offset of the starting pose (a flat board)
    // removed; then again with the offsets of each circle's tangent plane on the bent
    // sheet of the first fit (a bend tilts the circles, and their offsets with them)
    let obs = centre_corrected(camera, pts, &s0)?;
    let (_, _, ssr_flat) = gauss_newton(camera, pts, &obs, s0, false)?;
    let (s1, _, _) = gauss_newton(camera, pts, &obs, s0, true)?;
    let obs = centre_corrected(camera, pts, &s1)?;
    let (s, nmat, ssr) = gauss_newton(camera, pts, &obs, s1, true)?;
    let dof = 2.0 * n - NPAR as f64;
    let var = match opts.sigma_px {
        Some(sp) => sp * sp,
        None => ssr / dof,
    };
    let cov = nmat
        .try_inverse()
        .ok_or_else(|| Error::Degenerate("flatness: singular normal matrix".into()))?
        * var;
    let ch = cov.view((6, 6), (3, 3)).into_owned();
    let hm = Matrix2::new(s.h[0], s.h[1], s.h[1], s.h[2]);
    let eig = hm.symmetric_eigen();
    let (i1, i2) = if eig.eigenvalues[0].abs() >= eig.eigenvalues[1].abs() {
        (0, 1)
    } else {
        (1, 0)
    };
    let figure = |i: usize| -> (f64, f64, f64, Vector2<f64>) {
        let u: Vector2<f64> = eig.eigenvectors.column(i).into_owned();
        let (lo, hi) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                let x = u.x * p.board_xy[0] + u.y * p.board_xy[1];
                (lo.min(x), hi.max(x))
            });
        let w = hi - lo;
        let k = w * w / 8.0;
        let g = nalgebra::Vector3::new(k * u.x * u.x, 2.0 * k * u.x * u.y, k * u.y * u.y);
        let sag = eig.eigenvalues[i] * k;
        let sig = (g.transpose() * &ch * g)[(0, 0)].max(0.0).sqrt();
        (sag, sig, w, u)
    };
    let (sag, sig, w, u) = figure(i1);
    let (sag2, sig2, _, _) = figure(i2);
    // the axis is perpendicular to u
    let mut axis_deg = u.x.atan2(-u.y).to_degrees();
    if axis_deg <= -90.0 {
        axis_deg += 180.0;
    } else if axis_deg > 90.0 {
        axis_deg -= 180.0;
    }
    Ok(Flatness {
        sag_mm: sag,
        sigma_mm: sig,
        axis_deg,
        width_mm: w,
        sag2_mm: sag2,
        sigma2_mm: sig2,
        rms_px: (ssr / n).sqrt(),
        rms_flat_px: (ssr_flat / n).sqrt(),
        points: pts.len(),
        cam_board: Iso3::from_parts(s.t.into(), s.rot),
        hessian: s.h,
    })
}

#[cfg(test)]
mod tests;
