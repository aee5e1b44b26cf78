//! `qw,qx,qy,qz`: the rotation of `T_base_hand` as a unit quaternion
//! `q = w + x i + y j + z k` (Hamilton's convention, the one of ROS, Eigen and nalgebra):
//!
//! ```text
//!     | 1 - 2(y² + z²)   2(xy - wz)       2(xz + wy)     |
//! R = | 2(xy + wz)       1 - 2(x² + z²)   2(yz - wx)     |
//!     | 2(xz - wy)       2(yz + wx)       1 - 2(x² + y²) |
//! ```
//!
//! The column names say which number is which, so any order is read: ROS writes
//! `x, y, z, w` (geometry_msgs/Quaternion), most others `w, x, y, z`. `q` and `-q` are
//! the same rotation. A quaternion whose norm is within [`QUATERNION_TOL`] of 1 is
//! normalised (a controller prints a few digits); any other norm is an error, never
//! normalised away.

use nalgebra::{Quaternion, UnitQuaternion};

use super::short;
use super::RotationConvention;

/// How far from 1 the norm of a quaternion may be; it is then normalised.
pub const QUATERNION_TOL: f64 = 1e-3;

pub(super) struct UnitQuaternionColumns;

impl RotationConvention for UnitQuaternionColumns {
    fn columns(&self) -> &'static [&'static str] {
        &["qw", "qx", "qy", "qz"]
    }

    fn describe(&self) -> &'static str {
        "a unit quaternion"
    }

    fn to_rotation(&self, v: &[f64]) -> Result<UnitQuaternion<f64>, String> {
        let q = Quaternion::new(v[0], v[1], v[2], v[3]);
        let norm = q.norm();
        if (norm - 1.0).abs() > QUATERNION_TOL {
            return Err(format!(
                "quaternion (qw, qx, qy, qz) = ({}, {}, {}, {}) has norm {}, expected 1 (within {QUATERNION_TOL})",
                short(v[0]), short(v[1]), short(v[2]), short(v[3]), short(norm)
            ));
        }
        Ok(UnitQuaternion::from_quaternion(q))
    }

    fn values(&self, r: &UnitQuaternion<f64>) -> Vec<f64> {
        vec![r.w, r.i, r.j, r.k]
    }
}
