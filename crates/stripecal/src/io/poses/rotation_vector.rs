//! `rx_rad,ry_rad,rz_rad` and `rx_deg,ry_deg,rz_deg`: the rotation of `T_base_hand` as a
//! rotation vector `r = theta * k` (the unit axis `k` times the angle `theta`), what
//! Universal Robots' controllers report (in radians). Rodrigues' formula:
//!
//! ```text
//! R = I + sin(theta) [k]x + (1 - cos(theta)) [k]x²,   theta = |r|, k = r / theta
//! ```
//!
//! where `[k]x` is the cross-product matrix of `k`. Every finite vector of angle up to
//! 1e6 rad is a rotation (`r = 0` is the identity); a longer one is an error (its axis
//! and angle are rounding noise, and beyond ~1e154 they overflow). Written back, the angle is in `[0, pi]` (`[0, 180]` deg):
//! near a half turn `r` and `-r` are the same rotation, and the writer picks either.

use nalgebra::{UnitQuaternion, Vector3};

use super::short;
use super::RotationConvention;
use crate::model::geometry::{quaternion_to_rotvec, MAX_ROTVEC_ANGLE_RAD};

/// A rotation vector whose components are in radians times `per_radian`.
pub(super) struct RotationVector {
    columns: &'static [&'static str],
    /// Units of the columns per radian.
    per_radian: f64,
    describe: &'static str,
}

/// `rx_rad,ry_rad,rz_rad`.
pub(super) static RADIANS: RotationVector = RotationVector {
    columns: &["rx_rad", "ry_rad", "rz_rad"],
    per_radian: 1.0,
    describe: "a rotation vector in radians",
};

/// `rx_deg,ry_deg,rz_deg`.
pub(super) static DEGREES: RotationVector = RotationVector {
    columns: &["rx_deg", "ry_deg", "rz_deg"],
    per_radian: 180.0 / std::f64::consts::PI,
    describe: "a rotation vector in degrees",
};

impl RotationConvention for RotationVector {
    fn columns(&self) -> &'static [&'static str] {
        self.columns
    }

    fn describe(&self) -> &'static str {
        self.describe
    }

    fn to_rotation(&self, v: &[f64]) -> Result<UnitQuaternion<f64>, String> {
        let r = Vector3::new(v[0], v[1], v[2]) / self.per_radian;
        let angle = r.norm();
        if !angle.is_finite() || angle > MAX_ROTVEC_ANGLE_RAD {
            return Err(format!(
                "rotation vector ({}, {}, {}) has an angle of {angle:e} rad: expected at most \
                 {MAX_ROTVEC_ANGLE_RAD:e} rad (a controller reports at most a turn)",
                short(v[0]),
                short(v[1]),
                short(v[2])
            ));
        }
        Ok(UnitQuaternion::from_scaled_axis(r))
    }

    fn values(&self, r: &UnitQuaternion<f64>) -> Vec<f64> {
        let v = quaternion_to_rotvec(r) * self.per_radian;
        vec![v.x, v.y, v.z]
    }
}
