//! The uncertainty of reconstructed points: a 3x3 covariance per point in the base
//! frame, from the calibration's covariance, the stripe's sub-pixel noise and the
//! robot's repeatability, and the sensitivities the fits' budgets are built from
//! ([`super::fit::budget`]).
//!
//! ## Conventions
//!
//! The calibration's numbers are those of calibration.json's `covariance` (contract
//! names: `camera.fu`, `camera.distortion[0]`, `laser_plane.normal[1]`,
//! `laser_plane.d_mm`, `hand_cam.rotation_vector[2]`, `hand_cam.translation_mm[0]`,
//! `robot.joints[i].theta0_deg`, ...; the robot's in degrees and mm). Numbers that do
//! not move a base-frame point (`base_board.*`, `board.scale`) are left out; numbers
//! not in the covariance (held) have no uncertainty.
//!
//! ## The chain, linearised (one frame at `T_base_cam = T_base_hand(q) T_hand_cam`)
//!
//! A stripe point at pixel `(u, v)`: `xd = (u - u0) / fu`, `yd = (v - v0) / fv`; the
//! undistorted `(xn, yn)` solves `D(xn, yn; k) = (xd, yd)`, so
//! `d(xn, yn) = Jd^-1 (d(xd, yd) - Dk dk)` with `Jd = dD/d(xn, yn)` and
//! `Dk = dD/dk`. The ray `r = (xn, yn, 1)` meets the plane `n . p = d` at
//! `p_c = s r`, `s = d / (n . r)`:
//! `dp_c = s (I - r n^T / (n . r)) dr - s r r^T / (n . r) dn + r / (n . r) dd`.
//! The frame's pose enters as a right perturbation of `T_base_cam` in the camera frame,
//! `T_base_cam Exp((w, v))`: `dp_b = R_base_cam (w x p_c + v)`. So with the local
//! vector `eta = (dcamera[9], dn[3], dd, w[3], v[3])` (19 numbers, camera in
//! [`crate::model::camera::PARAM_NAMES`] order) every point of the frame has
//! `dp_b = R_base_cam J_c eta`, `J_c = [dp_c/dcamera, dp_c/dn, dp_c/dd, -[p_c]x, I]`.
//!
//! The calibration's numbers map to `eta` linearly, `eta = M_f theta`:
//! - camera numbers and the plane's offset one to one; the normal through its
//!   normalisation (`n` is read as `n / |n|`): `dn = (I - n n^T) dn_file`;
//! - `hand_cam.rotation_vector` `r`: `R(r + dr) = R(r) Exp(J_r(r) dr)` (the right
//!   Jacobian of SO(3)), so `w = J_r(r) dr`; `hand_cam.translation_mm`: `v = R_X^T dt`;
//! - a DH number: its flange twist `(w_h, v_h)` ([`crate::calib::joint::flange_twists`],
//!   flange frame) carried to the camera: `w = R_X^T w_h`, `v = R_X^T (w_h x t_X + v_h)`.
//!
//! Only the DH columns change from frame to frame. The frame's covariance of `eta` is
//! `Sigma_f = M_f C M_f^T + Sigma_robot,f`, where the robot's figures add, on the twist
//! block: encoder readings of one-sigma `sigma_q` turn joint i about its axis like
//! `-dtheta0_i` (`theta_i = q_i - theta0_i`), `sigma_q^2 sum_i g_i g_i^T`; a pose
//! repeatability `sigma_t` (mm, read as a one-sigma per axis: the conservative reading
//! of a maker's figure, as [`crate::Robot::pose_noise_floor`]) adds `sigma_t^2 I` to
//! `v` (isotropic, so the same in every frame). The stripe's noise is along the scan
//! line the extractor searches (`u` for [`crate::StripeDirection::Cols`], `v` for
//! `Rows`), one-sigma `sigma_s`: `dp_c = s (I - r n^T/(n . r)) Jd^-1 (1/fu, 0, 0)^T du`.
//!
//! A point's covariance is
//! `R_base_cam (J_c Sigma_f J_c^T + sigma_s^2 a a^T) R_base_cam^T`: one 3x19 by 19x19
//! product per point after one 19xP map per frame ([`FrameUncertainty`]). It is exact
//! to first order; the Monte Carlo over calibration draws agrees within a few percent
//! (tests).
//!
//! ## Profilers
//!
//! A line profiler ([`UncertaintyModel::profiler`]) delivers its points in its own
//! frame, `p_s = (x, 0, z)` mm; its camera and laser plane are the maker's, so their
//! numbers are not in the budget (the maker's residual error shows as the points'
//! scatter). The same `eta` serves with the camera and plane entries unused:
//! `J_s = [0 (camera 9), 0 (plane 4), -[p_s]x, I]`, and `dp_b = R_base_sensor J_s eta`
//! with `T_base_sensor = T_base_hand(q) T_hand_sensor`. The numbers that move a point
//! are `hand_cam.rotation_vector[k]`, `hand_cam.translation_mm[k]` (`T_hand_sensor`,
//! written as `hand_cam`) and the DH numbers, mapped exactly as the camera's hand-eye
//! and DH numbers above; `sphere.center_mm[k]` and `sphere.diameter_mm` (the
//! calibration's reference sphere) move no point and are left out as `base_board.*`
//! are. The point's own noise is along the sensor's z (the measuring direction),
//! one-sigma `sigma_z` mm (`UncertaintyOptions::profile_sigma_mm`, default the
//! calibration's `quality.profile_rms_mm`): `sigma_z^2 R e_z e_z^T R^T`. Robot figures
//! add as for the camera. A profiler's point is addressed by its profile coordinates
//! `(x_mm, z_mm)` wherever a camera's is addressed by its pixel `(u_px, v_px)`
//! ([`ScanPoints::u_px`] / [`ScanPoints::v_px`] hold x and z for a profile scan).
//!
//! ## Which parts are correlated
//!
//! The calibration part is shared by every point of every scan made with the
//! calibration: it does not average out in a fit. The robot part is shared by the
//! points of one frame, independent between frames. The stripe part is independent
//! per point. [`super::fit::budget`] keeps them apart.

mod frame;
mod model;
mod perturb;

pub use frame::{FrameUncertainty, LocalJacobian, SensorChain, ETA};
pub use model::{UncertaintyModel, UncertaintyOptions};
pub use perturb::{perturbed_calibration, perturbed_profiler_calibration};

use crate::error::Result;
use crate::model::Calibration;
use crate::model::RobotReading;

use super::ScanPoints;

/// Per-point covariances (base frame, mm^2, upper triangle `xx, xy, xz, yy, yz, zz`) of
/// reconstructed points, the frames' readings indexed by [`ScanPoints::frame`] (a
/// profiler's: [`UncertaintyModel::profiler`] and [`UncertaintyModel::scan_covariances`]).
pub fn point_covariances(
    calibration: &Calibration,
    readings: &[RobotReading],
    points: &ScanPoints,
    opts: &UncertaintyOptions,
) -> Result<Vec<[f64; 6]>> {
    UncertaintyModel::new(calibration, opts)?.scan_covariances(readings, points)
}

impl UncertaintyModel {
    /// [`point_covariances`] with this model: one frame map per run of points of the
    /// same frame, the runs in parallel.
    pub fn scan_covariances(
        &self,
        readings: &[RobotReading],
        points: &ScanPoints,
    ) -> Result<Vec<[f64; 6]>> {
        use rayon::prelude::*;
        let n = points.len();
        let mut runs = Vec::new();
        let mut start = 0;
        while start < n {
            let f = points.frame[start];
            let mut end = start;
            while end < n && points.frame[end] == f {
                end += 1;
            }
            runs.push((start, end, f));
            start = end;
        }
        let mut out = vec![[0.0; 6]; n];
        let mut slices = Vec::with_capacity(runs.len());
        let mut rest: &mut [[f64; 6]] = &mut out;
        for &(s, e, _) in &runs {
            let (a, b) = rest.split_at_mut(e - s);
            slices.push(a);
            rest = b;
        }
        runs.par_iter().zip(slices.into_par_iter()).try_for_each(
            |(&(s, e, f), dst)| -> Result<()> {
                let reading = readings.get(f as usize).ok_or_else(|| {
                    crate::Error::InvalidInput(format!(
                        "point {s} is of frame {f}, but only {} frame readings were given",
                        readings.len()
                    ))
                })?;
                let fu = self.frame(reading)?;
                let uv = (s..e).map(|i| (points.u_px[i], points.v_px[i]));
                fu.point_covariances(uv, dst);
                Ok(())
            },
        )?;
        Ok(out)
    }
}

#[cfg(test)]
mod profiler_tests;
#[cfg(test)]
pub(crate) mod tests;
