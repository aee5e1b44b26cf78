//! One frame's uncertainty: its pose, `M_f`, `Sigma_f`, and per point the local
//! Jacobian `J_c` and the 3x3 covariance ([`super`] docs).

use nalgebra::{DMatrix, Matrix3, Matrix6, SMatrix, Vector2, Vector3};

use crate::error::{Error, Result};
use crate::model::camera::{distortion_coefficient_jacobian, Camera, UndistortTrack};
use crate::model::geometry::Iso3;
use crate::vision::stripe::StripeDirection;

use super::model::UncertaintyModel;

/// Length of the local vector `eta` (camera 9, plane normal 3, plane offset 1, twist 6).
pub const ETA: usize = 19;

type Sigma = SMatrix<f64, ETA, ETA>;
type Jac = SMatrix<f64, 3, ETA>;

/// The first-order chain of one stripe point ([`super`] docs), camera frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalJacobian {
    /// The point, camera frame, mm.
    pub p_cam: Vector3<f64>,
    /// The point, base frame, mm.
    pub p_base: Vector3<f64>,
    /// `dp_cam / deta` (3 x 19).
    pub j_eta: Jac,
    /// `dp_cam / d(scan-line coordinate)`, mm per px (the stripe noise's direction).
    pub j_px: Vector3<f64>,
}

/// One frame of a scan: `R_base_cam`, `M_f` and `Sigma_f`.
#[derive(Debug, Clone)]
pub struct FrameUncertainty {
    camera: Camera,
    n: Vector3<f64>,
    d: f64,
    base_cam: Iso3,
    r_bc: Matrix3<f64>,
    /// `eta` from the calibration's numbers (19 x P).
    map: DMatrix<f64>,
    sigma: Sigma,
    /// The robot's part of the twist block (6 x 6).
    robot_sigma: Matrix6<f64>,
    stripe_var: f64,
    along_u: bool,
}

impl FrameUncertainty {
    pub(super) fn new(
        model: &UncertaintyModel,
        base_hand: &Iso3,
        map: DMatrix<f64>,
        sigma: DMatrix<f64>,
        robot_sigma: Matrix6<f64>,
    ) -> Result<Self> {
        let cal = &model.calibration;
        let plane = crate::reconstruct::triangulate::laser_plane_of(cal)?;
        let base_cam = base_hand * cal.hand_cam;
        let s = model.stripe_sigma_px;
        Ok(FrameUncertainty {
            camera: cal.camera.clone(),
            n: plane.normal,
            d: plane.d,
            r_bc: base_cam.rotation.to_rotation_matrix().into_inner(),
            base_cam,
            map,
            sigma: Sigma::from_fn(|r, c| {
                let rob = if r >= 13 && c >= 13 {
                    robot_sigma[(r - 13, c - 13)]
                } else {
                    0.0
                };
                sigma[(r, c)] + rob
            }),
            robot_sigma,
            stripe_var: s * s,
            along_u: model.direction != StripeDirection::Rows,
        })
    }

    /// `T_base_cam` of the frame.
    pub fn base_cam(&self) -> &Iso3 {
        &self.base_cam
    }

    /// `M_f`: `eta` from the calibration's numbers (19 x P, columns as
    /// [`UncertaintyModel::names`]).
    pub fn map(&self) -> &DMatrix<f64> {
        &self.map
    }

    /// `Sigma_f`: the covariance of `eta` (calibration and robot parts; 19 x 19).
    pub fn sigma(&self) -> &SMatrix<f64, ETA, ETA> {
        &self.sigma
    }

    /// The robot figures' covariance of the frame's twist `(w, v)` (6 x 6; in
    /// [`Self::sigma`] too).
    pub fn robot_sigma(&self) -> &Matrix6<f64> {
        &self.robot_sigma
    }

    /// One-sigma of the stripe centre along the scan line, px.
    pub fn stripe_sigma_px(&self) -> f64 {
        self.stripe_var.sqrt()
    }

    /// `R_base_cam`.
    pub fn rotation(&self) -> &Matrix3<f64> {
        &self.r_bc
    }

    /// The chain of pixel `(u, v)`; an error where the point is not triangulated (the
    /// undistortion fails, the ray misses the plane).
    pub fn local(&self, u: f64, v: f64) -> Result<LocalJacobian> {
        self.local_tracked(u, v, &mut UndistortTrack::new(&self.camera))
            .ok_or_else(|| {
                Error::Degenerate(format!(
                    "pixel ({u:.3}, {v:.3}) gives no point (undistortion failed or the ray \
                     misses the laser plane)"
                ))
            })
    }

    fn local_tracked(&self, u: f64, v: f64, track: &mut UndistortTrack) -> Option<LocalJacobian> {
        let c = &self.camera;
        let xd = (u - c.u0) / c.fu;
        let yd = (v - c.v0) / c.fv;
        let (xn, yn) = c.undistort_tracked(xd, yd, track)?;
        let (_, jd) = c.distort_with_jacobian(xn, yn);
        let jdi = jd.try_inverse()?;
        let dk = distortion_coefficient_jacobian(xn, yn);
        let r = Vector3::new(xn, yn, 1.0);
        let den = self.n.dot(&r);
        if den.abs() < 1e-12 {
            return None;
        }
        let s = self.d / den;
        let p_cam = r * s;
        // dp/d(xn, yn): the first two columns of s (I - r n^T / den).
        let pr = (Matrix3::identity() - r * self.n.transpose() / den) * s;
        let q = pr.fixed_columns::<2>(0).into_owned();
        let mut j = Jac::zeros();
        // d(xn, yn) per camera number: Jd^-1 (d(xd, yd) - Dk dk).
        let dn_cols: [Vector2<f64>; 4] = [
            jdi * Vector2::new(-xd / c.fu, 0.0),
            jdi * Vector2::new(0.0, -yd / c.fv),
            jdi * Vector2::new(-1.0 / c.fu, 0.0),
            jdi * Vector2::new(0.0, -1.0 / c.fv),
        ];
        for (k, col) in dn_cols.iter().enumerate() {
            j.set_column(k, &(q * col));
        }
        let jk = -(jdi * dk);
        for k in 0..5 {
            j.set_column(4 + k, &(q * jk.column(k)));
        }
        let rr = r * r.transpose() * (-s / den);
        j.fixed_view_mut::<3, 3>(0, 9).copy_from(&rr);
        j.set_column(12, &(r / den));
        j.fixed_view_mut::<3, 3>(0, 13)
            .copy_from(&(-p_cam.cross_matrix()));
        j.fixed_view_mut::<3, 3>(0, 16)
            .copy_from(&Matrix3::identity());
        let dpx = if self.along_u {
            Vector2::new(1.0 / c.fu, 0.0)
        } else {
            Vector2::new(0.0, 1.0 / c.fv)
        };
        let j_px = q * (jdi * dpx);
        let p_base = self.r_bc * p_cam + self.base_cam.translation.vector;
        Some(LocalJacobian {
            p_cam,
            p_base,
            j_eta: j,
            j_px,
        })
    }

    /// The covariance of the point of pixel `(u, v)`, base frame, mm^2, upper triangle
    /// `xx, xy, xz, yy, yz, zz` (NaN where the pixel gives no point).
    pub fn point_covariance(&self, u: f64, v: f64) -> [f64; 6] {
        self.point_covariance_tracked(u, v, &mut UndistortTrack::new(&self.camera))
    }

    /// [`Self::point_covariance`] of many pixels of the frame, written to `out` (one
    /// undistortion track: neighbours converge in a step or two).
    pub fn point_covariances(&self, uv: impl Iterator<Item = (f64, f64)>, out: &mut [[f64; 6]]) {
        let mut track = UndistortTrack::new(&self.camera);
        for ((u, v), o) in uv.zip(out.iter_mut()) {
            *o = self.point_covariance_tracked(u, v, &mut track);
        }
    }

    #[inline]
    fn point_covariance_tracked(&self, u: f64, v: f64, track: &mut UndistortTrack) -> [f64; 6] {
        let Some(l) = self.local_tracked(u, v, track) else {
            return [f64::NAN; 6];
        };
        let js = l.j_eta * self.sigma;
        let mut c = js * l.j_eta.transpose();
        c += l.j_px * l.j_px.transpose() * self.stripe_var;
        let b = self.r_bc * c * self.r_bc.transpose();
        [
            b[(0, 0)],
            b[(0, 1)],
            b[(0, 2)],
            b[(1, 1)],
            b[(1, 2)],
            b[(2, 2)],
        ]
    }
}
