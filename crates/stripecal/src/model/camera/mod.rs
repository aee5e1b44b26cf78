//! The camera of spec/DATASET.md: pinhole, no skew, a distortion of the normalised
//! coordinates given by the camera's model ([`CameraModel`], one file per model:
//! [`models`] for the seam and its registry, [`brown5`] for the contract's model).
//!
//! ## Camera
//!
//! For a point `p = (xc, yc, zc)` in the camera frame:
//!
//! ```text
//! xn = xc / zc,  yn = yc / zc
//! (xd, yd) = distort(k; xn, yn)        (the model's)
//! u = fu xd + u0,  v = fv yd + v0
//! ```
//!
//! The default model, `brown5`, is OpenCV's five-coefficient distortion
//! `[k1, k2, p1, p2, k3]`; its [`DistortionModel`] says which of them a calibration may
//! estimate (the others stay as given, normally 0). A camera stores its model's
//! coefficients in `distortion` (at most [`MAX_DISTORTION`], the rest 0).
//!
//! Camera parameters, where a vector of them is used (Jacobians, adjustment), are in the
//! order of the model's [`CameraModel::param_names`]: `fu, fv, u0, v0`, then the
//! coefficients; for `brown5` that is [`PARAM_NAMES`]:
//! `fu, fv, u0, v0, k1, k2, p1, p2, k3`.
//!
//! Pixel coordinates: the centre of the top-left pixel is `(0, 0)`.

pub mod brown5;
pub mod models;

pub use brown5::{
    distort_generic, distortion_coefficient_jacobian, distortion_of, project_generic,
    to_pixel_generic,
};
pub use models::{model_names, projection, register, CameraModel, Projection, MAX_DISTORTION};

use nalgebra::{Matrix2, Matrix2x3, Matrix2xX, Vector2, Vector3};

use crate::error::{Error, Result};

/// Names of the `brown5` camera's parameters, in the order of its parameter vector.
pub const PARAM_NAMES: [&str; 9] = ["fu", "fv", "u0", "v0", "k1", "k2", "p1", "p2", "k3"];

/// Which distortion coefficients a model estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum DistortionModel {
    /// `k1` only: the paper's model.
    #[default]
    Radial1,
    /// `k1, k2`.
    Radial2,
    /// `k1, k2, p1, p2, k3` (OpenCV's five-coefficient model).
    OpenCv5,
}

impl DistortionModel {
    /// The name used in files: `radial1`, `radial2` or `opencv5`.
    pub fn name(self) -> &'static str {
        match self {
            DistortionModel::Radial1 => "radial1",
            DistortionModel::Radial2 => "radial2",
            DistortionModel::OpenCv5 => "opencv5",
        }
    }

    /// Parses a model name (`radial1`, `radial2`, `opencv5`).
    pub fn from_name(s: &str) -> Result<Self> {
        match s {
            "radial1" => Ok(DistortionModel::Radial1),
            "radial2" => Ok(DistortionModel::Radial2),
            "opencv5" => Ok(DistortionModel::OpenCv5),
            other => Err(Error::InvalidInput(format!(
                "unknown distortion model {other:?}: expected \"radial1\", \"radial2\" or \"opencv5\""
            ))),
        }
    }

    /// Which of `[k1, k2, p1, p2, k3]` the model estimates.
    pub fn free_coefficients(self) -> [bool; 5] {
        match self {
            DistortionModel::Radial1 => [true, false, false, false, false],
            DistortionModel::Radial2 => [true, true, false, false, false],
            DistortionModel::OpenCv5 => [true; 5],
        }
    }
}

impl std::fmt::Display for DistortionModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A calibrated camera: image size, intrinsics and distortion.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Image width in pixels (columns).
    pub width: u32,
    /// Image height in pixels (rows).
    pub height: u32,
    /// Focal length along u, in pixels.
    pub fu: f64,
    /// Focal length along v, in pixels.
    pub fv: f64,
    /// Principal point, u (pixels).
    pub u0: f64,
    /// Principal point, v (pixels).
    pub v0: f64,
    /// The distortion model (which coefficients are estimated).
    pub model: DistortionModel,
    /// The model's distortion coefficients (`brown5`: `[k1, k2, p1, p2, k3]`), the
    /// slots past the model's count 0.
    pub distortion: [f64; MAX_DISTORTION],
    /// The projection model (default `brown5`).
    pub projection: Projection,
}

/// The pinhole numbers of a camera ([`Camera::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Focal length along u, in pixels.
    pub fu: f64,
    /// Focal length along v, in pixels.
    pub fv: f64,
    /// Principal point, u (pixels).
    pub u0: f64,
    /// Principal point, v (pixels).
    pub v0: f64,
}

/// Maximum Newton iterations of [`Camera::undistort`].
const UNDISTORT_MAX_ITER: usize = 30;
/// Convergence tolerance of [`Camera::undistort`] in normalised coordinates
/// (1e-14 is ~1e-11 px for a 1000 px focal length).
const UNDISTORT_TOL: f64 = 1e-14;

impl Camera {
    /// A `brown5` camera with checked values (positive size and focal lengths, finite
    /// numbers); [`Camera::with_projection`] gives it another model.
    pub fn new(
        width: u32,
        height: u32,
        k: Intrinsics,
        model: DistortionModel,
        distortion: [f64; MAX_DISTORTION],
    ) -> Result<Camera> {
        let cam = Camera {
            width,
            height,
            fu: k.fu,
            fv: k.fv,
            u0: k.u0,
            v0: k.v0,
            model,
            distortion,
            projection: Projection::Brown5,
        };
        cam.validate()?;
        Ok(cam)
    }

    /// The pinhole part.
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            fu: self.fu,
            fv: self.fv,
            u0: self.u0,
            v0: self.v0,
        }
    }

    /// This camera with another model and its coefficients (checked: as many as the
    /// model has, finite).
    pub fn with_projection(&self, projection: Projection, coefficients: &[f64]) -> Result<Camera> {
        let n = projection.model().distortion_count();
        if coefficients.len() != n || n > MAX_DISTORTION {
            return Err(Error::InvalidInput(format!(
                "camera model {} takes {n} distortion coefficients, not {}",
                projection.name(),
                coefficients.len()
            )));
        }
        let mut distortion = [0.0; MAX_DISTORTION];
        distortion[..n].copy_from_slice(coefficients);
        let cam = Camera {
            distortion,
            projection,
            ..self.clone()
        };
        cam.validate()?;
        Ok(cam)
    }

    /// Checks the invariants [`Camera::new`] enforces.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::InvalidInput(format!(
                "camera size {}x{} must be positive",
                self.width, self.height
            )));
        }
        if !(self.fu.is_finite() && self.fu > 0.0 && self.fv.is_finite() && self.fv > 0.0) {
            return Err(Error::InvalidInput(format!(
                "focal lengths fu = {}, fv = {} must be positive and finite",
                self.fu, self.fv
            )));
        }
        if !(self.u0.is_finite() && self.v0.is_finite())
            || self.distortion.iter().any(|k| !k.is_finite())
        {
            return Err(Error::InvalidInput(
                "principal point and distortion must be finite".into(),
            ));
        }
        let n = self.projection.model().distortion_count();
        if self.distortion[n.min(MAX_DISTORTION)..]
            .iter()
            .any(|&k| k != 0.0)
        {
            return Err(Error::InvalidInput(format!(
                "camera model {} has {n} distortion coefficients: the others must be 0",
                self.projection.name()
            )));
        }
        Ok(())
    }

    /// The model's distortion coefficients.
    #[inline]
    pub fn coefficients(&self) -> &[f64] {
        let n = self.projection.model().distortion_count();
        &self.distortion[..n]
    }

    /// The model's parameter vector (`fu, fv, u0, v0`, then its coefficients;
    /// [`CameraModel::param_names`] order).
    pub fn model_params(&self) -> Vec<f64> {
        let mut v = vec![self.fu, self.fv, self.u0, self.v0];
        v.extend_from_slice(self.coefficients());
        v
    }

    /// A copy of this camera with parameters from a vector in the model's order
    /// ([`Self::model_params`]).
    pub fn with_model_params(&self, p: &[f64]) -> Camera {
        let mut distortion = [0.0; MAX_DISTORTION];
        distortion[..p.len() - 4].copy_from_slice(&p[4..]);
        Camera {
            fu: p[0],
            fv: p[1],
            u0: p[2],
            v0: p[3],
            distortion,
            ..self.clone()
        }
    }

    /// The parameter vector `[fu, fv, u0, v0, k1, k2, p1, p2, k3]` (the stored
    /// coefficients: `brown5`'s layout).
    pub fn params(&self) -> [f64; 9] {
        let k = self.distortion;
        [
            self.fu, self.fv, self.u0, self.v0, k[0], k[1], k[2], k[3], k[4],
        ]
    }

    /// A copy of this camera with parameters from a vector in [`PARAM_NAMES`] order.
    pub fn with_params(&self, p: &[f64; 9]) -> Camera {
        Camera {
            fu: p[0],
            fv: p[1],
            u0: p[2],
            v0: p[3],
            distortion: [p[4], p[5], p[6], p[7], p[8]],
            ..self.clone()
        }
    }

    /// Applies the distortion to normalised coordinates ([`distort_generic`]).
    #[inline]
    pub fn distort(&self, xn: f64, yn: f64) -> (f64, f64) {
        match self.projection {
            Projection::Brown5 => {
                let (d, _) = distort_generic(&self.distortion, xn, yn);
                (d[0], d[1])
            }
            Projection::Other(m) => m.distort(self.coefficients(), xn, yn).0,
        }
    }

    /// The distortion and its 2x2 Jacobian with respect to `(xn, yn)`
    /// ([`distort_generic`]).
    #[inline]
    pub fn distort_with_jacobian(&self, xn: f64, yn: f64) -> ((f64, f64), Matrix2<f64>) {
        match self.projection {
            Projection::Brown5 => {
                let (d, j) = distort_generic(&self.distortion, xn, yn);
                (
                    (d[0], d[1]),
                    Matrix2::new(j[0][0], j[0][1], j[1][0], j[1][1]),
                )
            }
            Projection::Other(m) => m.distort(self.coefficients(), xn, yn),
        }
    }

    /// Normalised coordinates of a point in the camera frame; error if `zc <= 0` or
    /// they are not finite (a point at infinity, or nearly in the focal plane).
    #[inline]
    pub fn normalize(p: &Vector3<f64>) -> Result<(f64, f64)> {
        if p.z.is_nan() || p.z <= 0.0 {
            return Err(Error::Degenerate(format!(
                "point ({:.4}, {:.4}, {:.4}) is not in front of the camera",
                p.x, p.y, p.z
            )));
        }
        let (x, y) = (p.x / p.z, p.y / p.z);
        if !(x.is_finite() && y.is_finite()) {
            return Err(Error::Degenerate(format!(
                "point ({:.4e}, {:.4e}, {:.4e}) has no finite image (at infinity or in the \
                 focal plane)",
                p.x, p.y, p.z
            )));
        }
        Ok((x, y))
    }

    /// Pixel of distorted normalised coordinates.
    #[inline]
    pub fn to_pixel(&self, xd: f64, yd: f64) -> Vector2<f64> {
        Vector2::new(self.fu * xd + self.u0, self.fv * yd + self.v0)
    }

    /// Distorted normalised coordinates of a pixel.
    #[inline]
    pub fn from_pixel(&self, uv: &Vector2<f64>) -> (f64, f64) {
        ((uv.x - self.u0) / self.fu, (uv.y - self.v0) / self.fv)
    }

    /// Projects a point in the camera frame to pixels; error if it is not in front or
    /// its pixel is not finite (a point at infinity, a distortion that overflows).
    #[inline]
    pub fn project(&self, p: &Vector3<f64>) -> Result<Vector2<f64>> {
        let (xn, yn) = Self::normalize(p)?;
        let (xd, yd) = self.distort(xn, yn);
        let uv = self.to_pixel(xd, yd);
        if !(uv.x.is_finite() && uv.y.is_finite()) {
            return Err(Error::Degenerate(format!(
                "point ({:.4e}, {:.4e}, {:.4e}) projects to a non-finite pixel",
                p.x, p.y, p.z
            )));
        }
        Ok(uv)
    }

    /// Inverts the distortion by Newton's method.
    ///
    /// Errors with [`Error::NotConverged`] when the iteration does not reach 1e-14 in
    /// 30 steps, and with [`Error::Degenerate`] where the distortion folds (its
    /// Jacobian is singular or orientation-reversing: outside the model's valid zone).
    pub fn undistort(&self, xd: f64, yd: f64) -> Result<(f64, f64)> {
        self.undistort_from(xd, yd, xd, yd)
    }

    /// [`Camera::undistort`] starting from the guess `(x0, y0)` (a neighbouring
    /// solution makes it converge in one or two steps).
    pub fn undistort_from(&self, xd: f64, yd: f64, x0: f64, y0: f64) -> Result<(f64, f64)> {
        if !(xd.is_finite() && yd.is_finite()) {
            return Err(Error::InvalidInput(
                "cannot undistort a non-finite point".into(),
            ));
        }
        let (mut x, mut y) = (x0, y0);
        let mut res = f64::INFINITY;
        for _ in 0..UNDISTORT_MAX_ITER {
            let ((fx, fy), j) = self.distort_with_jacobian(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            res = ex.abs().max(ey.abs());
            if res < UNDISTORT_TOL {
                return if j.determinant() > 0.0 {
                    Ok((x, y))
                } else {
                    Err(Error::Degenerate(format!(
                        "distorted point ({xd:.6}, {yd:.6}) lies where the distortion model folds"
                    )))
                };
            }
            let det = j.determinant();
            if !(det.is_finite() && det > 1e-12) {
                return Err(Error::Degenerate(format!(
                    "distorted point ({xd:.6}, {yd:.6}) lies where the distortion model folds \
                     (Jacobian determinant {det:.3e})"
                )));
            }
            // Solve J * delta = e.
            let dx = (j[(1, 1)] * ex - j[(0, 1)] * ey) / det;
            let dy = (-j[(1, 0)] * ex + j[(0, 0)] * ey) / det;
            x -= dx;
            y -= dy;
            if !(x.is_finite() && y.is_finite()) {
                break;
            }
        }
        Err(Error::NotConverged {
            what: "undistortion",
            iterations: UNDISTORT_MAX_ITER,
            residual: res,
        })
    }

    /// The viewing ray of a pixel: `(xn, yn, 1)` in the camera frame (not unit length).
    pub fn unproject(&self, uv: &Vector2<f64>) -> Result<Vector3<f64>> {
        let (xd, yd) = self.from_pixel(uv);
        let (xn, yn) = self.undistort(xd, yd)?;
        Ok(Vector3::new(xn, yn, 1.0))
    }

    /// Projection with its Jacobians: the pixel, d(u,v)/d(point) (2x3) and
    /// d(u,v)/d(params) (2 x the model's parameter count, columns in
    /// [`CameraModel::param_names`] order: [`PARAM_NAMES`] for `brown5`); errors as
    /// [`Self::project`] (also when a Jacobian is not finite).
    pub fn project_with_jacobians(
        &self,
        p: &Vector3<f64>,
    ) -> Result<(Vector2<f64>, Matrix2x3<f64>, Matrix2xX<f64>)> {
        let (xn, yn) = Self::normalize(p)?;
        let ((xd, yd), jd) = self.distort_with_jacobian(xn, yn);
        let uv = self.to_pixel(xd, yd);
        let iz = 1.0 / p.z;
        // d(xn, yn)/d(p)
        let jn = Matrix2x3::new(iz, 0.0, -xn * iz, 0.0, iz, -yn * iz);
        let f = Matrix2::new(self.fu, 0.0, 0.0, self.fv);
        let jp = f * jd * jn;
        let model = self.projection.model();
        let mut jc = Matrix2xX::<f64>::zeros(model.param_count());
        jc[(0, 0)] = xd;
        jc[(1, 1)] = yd;
        jc[(0, 2)] = 1.0;
        jc[(1, 3)] = 1.0;
        let dk = model.distortion_jacobian(self.coefficients(), xn, yn);
        for i in 0..model.distortion_count() {
            jc[(0, 4 + i)] = self.fu * dk[(0, i)];
            jc[(1, 4 + i)] = self.fv * dk[(1, i)];
        }
        if !(uv.iter().chain(jp.iter()).chain(jc.iter())).all(|x| x.is_finite()) {
            return Err(Error::Degenerate(format!(
                "point ({:.4e}, {:.4e}, {:.4e}) projects to a non-finite pixel or Jacobian",
                p.x, p.y, p.z
            )));
        }
        Ok((uv, jp, jc))
    }

    /// Whether a pixel position lies inside the image (pixel centres from 0 to size-1,
    /// the image area from -0.5 to size-0.5).
    pub fn contains(&self, uv: &Vector2<f64>, margin: f64) -> bool {
        uv.x >= -0.5 + margin
            && uv.y >= -0.5 + margin
            && uv.x <= self.width as f64 - 0.5 - margin
            && uv.y <= self.height as f64 - 0.5 - margin
    }

    // ------------------------------------------------------------------------------
    // Undistortion of a sequence of neighbouring points (stripe points, contours).

    /// [`Camera::undistort`] for one point of a sequence of neighbouring points, each
    /// Newton iteration started at the previous point's solution held in `track` (made by
    /// [`UndistortTrack::new`] for this camera): neighbouring points converge in 1-2
    /// steps. Without distortion the point is returned as it is; for radial-only `brown5`
    /// cameras (`p1 = p2 = 0`) a 1D Newton iteration on the scale `r_n / r_d`
    /// ([`Camera::undistort_radial_scale`]) with the 2D one as fallback, otherwise the 2D
    /// one ([`Camera::undistort_from`], from the previous solution when it is near).
    /// Both stop at ~1e-15 relative. `None` where the model folds (as
    /// [`Camera::undistort`] refuses) and for a non-finite point. Allocates nothing
    /// (except in the failing 2D case).
    #[inline]
    pub fn undistort_tracked(
        &self,
        xd: f64,
        yd: f64,
        track: &mut UndistortTrack,
    ) -> Option<(f64, f64)> {
        if !(xd.is_finite() && yd.is_finite()) {
            return None;
        }
        if track.no_distortion {
            Some((xd, yd))
        } else if track.radial_only {
            match self.undistort_radial_scale(xd, yd, track.scale) {
                Some(s) => {
                    track.scale = s;
                    Some((xd * s, yd * s))
                }
                None => {
                    track.scale = 1.0;
                    self.undistort_near(xd, yd, track)
                }
            }
        } else {
            self.undistort_near(xd, yd, track)
        }
    }

    /// Radial-only distortion (`p1 = p2 = 0`): the undistorted point is the distorted one
    /// scaled by `s = r_n / r_d`, the root of the 1D equation
    /// `f(s) = s (1 + k1 rho s^2 + k2 rho^2 s^4 + k3 rho^3 s^6) - 1 = 0` with
    /// `rho = r_d^2`, solved by Newton's method from `s0` (the previous point's scale: a
    /// neighbouring stripe point converges in one or two steps) to `|ds| <= 1e-15 s`.
    /// `None` where it does not converge in 20 steps or the model folds there
    /// (`f'(s) <= 0`, the radial factor `<= 0`): the general 2D solver then decides.
    /// Meaningless for a `brown5` camera with tangential terms and for other models
    /// ([`UndistortTrack::new`] tells).
    #[inline]
    pub fn undistort_radial_scale(&self, xd: f64, yd: f64, s0: f64) -> Option<f64> {
        let [k1, k2, _, _, k3] = self.distortion;
        let rho = xd * xd + yd * yd;
        let (a1, a2, a3) = (k1 * rho, k2 * rho * rho, k3 * rho * rho * rho);
        let mut s = if s0 > 0.0 && s0.is_finite() { s0 } else { 1.0 };
        for _ in 0..20 {
            let s2 = s * s;
            let poly = 1.0 + s2 * (a1 + s2 * (a2 + s2 * a3));
            // f'(s) and f''(s) / s.
            let dpoly = 1.0 + s2 * (3.0 * a1 + s2 * (5.0 * a2 + s2 * 7.0 * a3));
            let ddpoly = 6.0 * a1 + s2 * (20.0 * a2 + s2 * 42.0 * a3);
            if !(dpoly > 1e-12 && poly > 0.0) {
                return None;
            }
            let ds = (s * poly - 1.0) / dpoly;
            s -= ds;
            // Newton's error after the step is about |f'' / (2 f')| ds^2: stop when that
            // is below 1e-16 (s is about 1), without the extra step a |ds| test needs.
            if (ddpoly * s).abs() * ds * ds <= 2e-16 * dpoly {
                return (s > 0.0).then_some(s);
            }
        }
        None
    }

    /// The 2D Newton ([`Camera::undistort_from`]) from the track's previous solution when
    /// it is near, else from the distorted point; records the solution in `track`.
    #[inline]
    fn undistort_near(&self, xd: f64, yd: f64, track: &mut UndistortTrack) -> Option<(f64, f64)> {
        let (x0, y0) = match track.xy {
            Some((gx, gy)) if (gx - xd).abs() + (gy - yd).abs() < 0.05 => (gx, gy),
            _ => (xd, yd),
        };
        let p = self.undistort_from(xd, yd, x0, y0).ok();
        track.xy = p;
        p
    }
}

/// Newton starts carried from one point of a sequence to the next
/// ([`Camera::undistort_tracked`]), and which solver the camera's coefficients allow.
#[derive(Debug, Clone, Copy)]
pub struct UndistortTrack {
    /// All distortion coefficients are zero (no iteration).
    no_distortion: bool,
    /// The tangential coefficients are zero (the 1D iteration).
    radial_only: bool,
    /// Radial-only models: the previous point's `r_n / r_d`.
    scale: f64,
    /// General models: the previous point's undistorted coordinates.
    xy: Option<(f64, f64)>,
}

impl UndistortTrack {
    /// A fresh track (no previous point) for `camera`.
    pub fn new(camera: &Camera) -> UndistortTrack {
        UndistortTrack {
            no_distortion: camera.distortion.iter().all(|&k| k == 0.0),
            radial_only: camera.projection.is_brown5()
                && camera.distortion[2] == 0.0
                && camera.distortion[3] == 0.0,
            scale: 1.0,
            xy: None,
        }
    }

    /// Whether the camera is a radial-only `brown5` (`p1 = p2 = 0`): the 1D iteration.
    pub fn is_radial_only(&self) -> bool {
        self.radial_only
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cameras() -> Vec<Camera> {
        let base = Camera::new(
            768,
            576,
            Intrinsics {
                fu: 1271.65,
                fv: 1322.52,
                u0: 346.14,
                v0: 262.60,
            },
            DistortionModel::Radial1,
            [0.0002, 0.0, 0.0, 0.0, 0.0],
        )
        .unwrap();
        vec![
            base.clone(),
            Camera {
                distortion: [-0.3, 0.0, 0.0, 0.0, 0.0],
                ..base.clone()
            },
            Camera {
                model: DistortionModel::Radial2,
                distortion: [-0.3, 0.1, 0.0, 0.0, 0.0],
                ..base.clone()
            },
            Camera {
                model: DistortionModel::OpenCv5,
                distortion: [-0.3, 0.1, 1e-3, 1e-3, 0.02],
                ..base.clone()
            },
            // wide-angle short focal length: strong distortion reaches far into the corners
            Camera {
                fu: 500.0,
                fv: 500.0,
                model: DistortionModel::OpenCv5,
                distortion: [-0.3, 0.1, 1e-3, 1e-3, -0.01],
                ..base
            },
        ]
    }

    #[test]
    fn project_unproject_round_trip_over_the_whole_image() {
        for cam in cameras() {
            let mut worst: f64 = 0.0;
            for iv in 0..=48 {
                for iu in 0..=64 {
                    let uv = Vector2::new(
                        -0.5 + iu as f64 * cam.width as f64 / 64.0,
                        -0.5 + iv as f64 * cam.height as f64 / 48.0,
                    );
                    let ray = cam.unproject(&uv).unwrap();
                    let back = cam.project(&(ray * 137.0)).unwrap();
                    worst = worst.max((back - uv).norm());
                }
            }
            assert!(
                worst < 1e-6,
                "{:?}: round trip {worst:e} px",
                cam.distortion
            );
        }
    }

    #[test]
    fn jacobians_match_central_differences() {
        for cam in cameras() {
            for p in [
                Vector3::new(12.0, -7.0, 100.0),
                Vector3::new(-40.0, 30.0, 95.0),
                Vector3::new(1.0, 2.0, 300.0),
            ] {
                let (_, jp, jc) = cam.project_with_jacobians(&p).unwrap();
                for k in 0..3 {
                    let h = 1e-4 * p.norm();
                    let (mut a, mut b) = (p, p);
                    a[k] += h;
                    b[k] -= h;
                    let fd = (cam.project(&a).unwrap() - cam.project(&b).unwrap()) / (2.0 * h);
                    for r in 0..2 {
                        let rel = (fd[r] - jp[(r, k)]).abs() / jp.column(k).norm().max(1e-12);
                        assert!(rel < 1e-6, "d/dp{k} row {r}: {} vs {}", jp[(r, k)], fd[r]);
                    }
                }
                let params = cam.params();
                for k in 0..9 {
                    // u, v are linear in each distortion coefficient: a finite step is exact there.
                    let h = if k < 4 { 1e-6 * params[k].abs() } else { 1e-4 };
                    let (mut a, mut b) = (params, params);
                    a[k] += h;
                    b[k] -= h;
                    let fd = (cam.with_params(&a).project(&p).unwrap()
                        - cam.with_params(&b).project(&p).unwrap())
                        / (2.0 * h);
                    for r in 0..2 {
                        // Relative to the column (floored at 1e-3 px per unit: below that, round-off of
                        // u ~ 1e3 px dominates any finite difference).
                        let scale = jc.column(k).norm().max(1e-3);
                        let rel = (fd[r] - jc[(r, k)]).abs() / scale;
                        assert!(
                            rel < 1e-6,
                            "d/d{} row {r}: {} vs {}",
                            PARAM_NAMES[k],
                            jc[(r, k)],
                            fd[r]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn undistort_refuses_where_the_model_folds() {
        let cam = Camera::new(
            100,
            100,
            Intrinsics {
                fu: 100.0,
                fv: 100.0,
                u0: 50.0,
                v0: 50.0,
            },
            DistortionModel::Radial1,
            [-0.5, 0.0, 0.0, 0.0, 0.0],
        )
        .unwrap();
        // max of r (1 - 0.5 r^2) is at r = sqrt(2/3) giving 0.544: beyond it no solution
        assert!(cam.undistort(0.7, 0.0).is_err());
        assert!(cam.project(&Vector3::new(0.0, 0.0, -1.0)).is_err());
    }

    #[test]
    fn invalid_cameras_are_rejected() {
        assert!(Camera::new(
            0,
            10,
            Intrinsics {
                fu: 1.0,
                fv: 1.0,
                u0: 0.0,
                v0: 0.0
            },
            DistortionModel::Radial1,
            [0.0; 5]
        )
        .is_err());
        assert!(Camera::new(
            10,
            10,
            Intrinsics {
                fu: -1.0,
                fv: 1.0,
                u0: 0.0,
                v0: 0.0
            },
            DistortionModel::Radial1,
            [0.0; 5]
        )
        .is_err());
        assert!(Camera::new(
            10,
            10,
            Intrinsics {
                fu: 1.0,
                fv: 1.0,
                u0: f64::NAN,
                v0: 0.0
            },
            DistortionModel::Radial1,
            [0.0; 5]
        )
        .is_err());
        assert!(DistortionModel::from_name("fisheye").is_err());
    }
}
