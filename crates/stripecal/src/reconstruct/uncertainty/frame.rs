//! One frame's uncertainty: its pose, `M_f`, `Sigma_f`, and per point the local
//! Jacobian `J_c` and the 3x3 covariance ([`super`] docs). What is the sensor's own
//! (a camera's pixel-to-point chain, or a profiler's points given in its frame) sits in
//! [`SensorChain`]; the rest is shared.

use nalgebra::{DMatrix, Matrix3, Matrix6, SMatrix, Vector2, Vector3};

use crate::error::{Error, Result};
use crate::model::camera::{distortion_coefficient_jacobian, Camera, UndistortTrack};
use crate::model::geometry::Iso3;
use crate::vision::stripe::StripeDirection;

use super::model::{Sensor, UncertaintyModel};

/// Length of the local vector `eta` (camera 9, plane normal 3, plane offset 1, twist 6).
pub const ETA: usize = 19;

type Sigma = SMatrix<f64, ETA, ETA>;
type Jac = SMatrix<f64, 3, ETA>;

/// The first-order chain of one stripe point ([`super`] docs), camera (or profiler)
/// frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalJacobian {
    /// The point, camera frame (a profiler's: sensor frame, `(x, 0, z)`), mm.
    pub p_cam: Vector3<f64>,
    /// The point, base frame, mm.
    pub p_base: Vector3<f64>,
    /// `dp_cam / deta` (3 x 19; a profiler's: the twist columns only).
    pub j_eta: Jac,
    /// `dp_cam / d(measured coordinate)`: mm per px along the scan line for a camera
    /// (the stripe noise's direction); `(0, 0, 1)` (mm per mm along the sensor's z) for
    /// a profiler.
    pub j_px: Vector3<f64>,
}

/// What of a frame's chain is the sensor's own.
#[derive(Debug, Clone)]
pub enum SensorChain {
    /// A camera and its laser plane: a point from a pixel `(u, v)` through the
    /// undistortion and the ray-plane intersection; the stripe's noise along `u`
    /// (`along_u`) or `v`.
    Camera {
        camera: Camera,
        n: Vector3<f64>,
        d: f64,
        along_u: bool,
    },
    /// A calibrated line profiler: a point is given as `(x, z)` mm in the sensor frame,
    /// `p_s = (x, 0, z)`; its noise is along z. The maker's calibration of its camera
    /// and laser plane is not in the budget (not ours to know): only the pose chain.
    Profiler,
}

/// One frame of a scan: `R_base_cam`, `M_f` and `Sigma_f`.
#[derive(Debug, Clone)]
pub struct FrameUncertainty {
    chain: SensorChain,
    base_cam: Iso3,
    r_bc: Matrix3<f64>,
    /// `eta` from the calibration's numbers (19 x P).
    map: DMatrix<f64>,
    sigma: Sigma,
    /// The robot's part of the twist block (6 x 6).
    robot_sigma: Matrix6<f64>,
    /// The point's own noise's variance (px^2 camera, mm^2 profiler).
    stripe_var: f64,
}

impl FrameUncertainty {
    pub(super) fn new(
        model: &UncertaintyModel,
        base_hand: &Iso3,
        map: DMatrix<f64>,
        sigma: DMatrix<f64>,
        robot_sigma: Matrix6<f64>,
    ) -> Result<Self> {
        let chain = match &model.sensor {
            Sensor::Camera {
                calibration,
                direction,
            } => {
                let plane = crate::reconstruct::triangulate::laser_plane_of(calibration)?;
                SensorChain::Camera {
                    camera: calibration.camera.clone(),
                    n: plane.normal,
                    d: plane.d,
                    along_u: *direction != StripeDirection::Rows,
                }
            }
            Sensor::Profiler { .. } => SensorChain::Profiler,
        };
        let base_cam = base_hand * model.hand_sensor();
        let s = model.noise_sigma;
        Ok(FrameUncertainty {
            chain,
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
        })
    }

    /// The sensor's own part of the chain.
    pub fn chain(&self) -> &SensorChain {
        &self.chain
    }

    /// `T_base_cam` of the frame (a profiler's: `T_base_sensor`).
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

    /// One-sigma of the stripe centre along the scan line, px; for a profiler the
    /// point's one-sigma along the sensor's z, mm.
    pub fn stripe_sigma_px(&self) -> f64 {
        self.stripe_var.sqrt()
    }

    /// `R_base_cam`.
    pub fn rotation(&self) -> &Matrix3<f64> {
        &self.r_bc
    }

    /// The chain of pixel `(u, v)` (a profiler's: profile point `(x_mm, z_mm)`); an
    /// error where the point is not triangulated (the undistortion fails, the ray misses
    /// the plane; a profile point not finite).
    pub fn local(&self, u: f64, v: f64) -> Result<LocalJacobian> {
        match &self.chain {
            SensorChain::Camera { camera, .. } => {
                self.local_tracked(u, v, &mut UndistortTrack::new(camera))
            }
            SensorChain::Profiler => self.local_profile(u, v),
        }
        .ok_or_else(|| {
            Error::Degenerate(match self.chain {
                SensorChain::Camera { .. } => format!(
                    "pixel ({u:.3}, {v:.3}) gives no point (undistortion failed or the ray \
                     misses the laser plane)"
                ),
                SensorChain::Profiler => {
                    format!("profile point ({u}, {v}) mm is not finite")
                }
            })
        })
    }

    /// A profiler's chain of the profile point `(x, z)`: `J = [0, -[p_s]x, I]`.
    fn local_profile(&self, x: f64, z: f64) -> Option<LocalJacobian> {
        if !(x.is_finite() && z.is_finite()) {
            return None;
        }
        let p_cam = Vector3::new(x, 0.0, z);
        let mut j = Jac::zeros();
        j.fixed_view_mut::<3, 3>(0, 13)
            .copy_from(&(-p_cam.cross_matrix()));
        j.fixed_view_mut::<3, 3>(0, 16)
            .copy_from(&Matrix3::identity());
        let p_base = self.r_bc * p_cam + self.base_cam.translation.vector;
        Some(LocalJacobian {
            p_cam,
            p_base,
            j_eta: j,
            j_px: Vector3::z(),
        })
    }

    /// A camera's chain of pixel `(u, v)` (`None` for a profiler).
    fn local_tracked(&self, u: f64, v: f64, track: &mut UndistortTrack) -> Option<LocalJacobian> {
        let SensorChain::Camera {
            camera: c,
            n,
            d,
            along_u,
        } = &self.chain
        else {
            return None;
        };
        let xd = (u - c.u0) / c.fu;
        let yd = (v - c.v0) / c.fv;
        let (xn, yn) = c.undistort_tracked(xd, yd, track)?;
        let (_, jd) = c.distort_with_jacobian(xn, yn);
        let jdi = jd.try_inverse()?;
        let dk = distortion_coefficient_jacobian(xn, yn);
        let r = Vector3::new(xn, yn, 1.0);
        let den = n.dot(&r);
        if den.abs() < 1e-12 {
            return None;
        }
        let s = d / den;
        let p_cam = r * s;
        // dp/d(xn, yn): the first two columns of s (I - r n^T / den).
        let pr = (Matrix3::identity() - r * n.transpose() / den) * s;
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
        let dpx = if *along_u {
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

    /// The covariance of the point of pixel `(u, v)` (a profiler's: profile point
    /// `(x_mm, z_mm)`), base frame, mm^2, upper triangle `xx, xy, xz, yy, yz, zz` (NaN
    /// where the pixel gives no point).
    pub fn point_covariance(&self, u: f64, v: f64) -> [f64; 6] {
        match &self.chain {
            SensorChain::Camera { camera, .. } => {
                self.point_covariance_tracked(u, v, &mut UndistortTrack::new(camera))
            }
            SensorChain::Profiler => self.covariance_of(self.local_profile(u, v)),
        }
    }

    /// [`Self::point_covariance`] of many pixels of the frame, written to `out` (one
    /// undistortion track: neighbours converge in a step or two).
    pub fn point_covariances(&self, uv: impl Iterator<Item = (f64, f64)>, out: &mut [[f64; 6]]) {
        match &self.chain {
            SensorChain::Camera { camera, .. } => {
                let mut track = UndistortTrack::new(camera);
                for ((u, v), o) in uv.zip(out.iter_mut()) {
                    *o = self.point_covariance_tracked(u, v, &mut track);
                }
            }
            SensorChain::Profiler => {
                for ((x, z), o) in uv.zip(out.iter_mut()) {
                    *o = self.covariance_of(self.local_profile(x, z));
                }
            }
        }
    }

    #[inline]
    fn point_covariance_tracked(&self, u: f64, v: f64, track: &mut UndistortTrack) -> [f64; 6] {
        self.covariance_of(self.local_tracked(u, v, track))
    }

    /// `R (J Sigma_f J^T + var j j^T) R^T` of a point's chain (NaN without one).
    #[inline]
    fn covariance_of(&self, l: Option<LocalJacobian>) -> [f64; 6] {
        let Some(l) = l else {
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
