//! `r11,r12,r13,r21,r22,r23,r31,r32,r33`: the rotation matrix of `T_base_hand` row by
//! row (`rij` is row i, column j; the columns of R are the hand's axes in the base
//! frame).
//!
//! A matrix is a rotation when `R^T R = I` and `det R = +1`. One that is within
//! [`MATRIX_TOL`] of that (every entry of `R^T R - I`, and `det R - 1`) is replaced by
//! the nearest rotation (SVD, Frobenius norm): a controller prints a few digits. Any
//! other is an error naming its entries, never orthonormalised away; a reflection
//! (det -1) is never a rotation.

use nalgebra::{Matrix3, UnitQuaternion};

use super::short;
use super::RotationConvention;
use crate::model::geometry::{nearest_rotation, quaternion_from_matrix};

/// How far from a rotation a matrix may be; it is then replaced by the nearest rotation.
pub const MATRIX_TOL: f64 = 1e-3;

pub(super) struct RotationMatrix;

impl RotationConvention for RotationMatrix {
    fn columns(&self) -> &'static [&'static str] {
        &[
            "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33",
        ]
    }

    fn describe(&self) -> &'static str {
        "a rotation matrix"
    }

    fn to_rotation(&self, v: &[f64]) -> Result<UnitQuaternion<f64>, String> {
        let m = Matrix3::from_row_slice(v);
        let err = (m.transpose() * m - Matrix3::identity()).abs().max();
        let det = m.determinant();
        // a NaN (inf - inf in R^T R of huge entries) is refused too
        if err.is_nan() || det.is_nan() || err > MATRIX_TOL || (det - 1.0).abs() > MATRIX_TOL {
            return Err(format!(
                "matrix (r11..r33) = [[{}, {}, {}], [{}, {}, {}], [{}, {}, {}]] is not a rotation: \
                 max |R^T R - I| = {err:.3e} and det = {} (a rotation has R^T R = I and det = +1, within {MATRIX_TOL})",
                short(v[0]), short(v[1]), short(v[2]), short(v[3]), short(v[4]), short(v[5]),
                short(v[6]), short(v[7]), short(v[8]), short(det)
            ));
        }
        Ok(quaternion_from_matrix(&nearest_rotation(&m)))
    }

    fn values(&self, r: &UnitQuaternion<f64>) -> Vec<f64> {
        let m = r.to_rotation_matrix().into_inner();
        (0..9).map(|i| m[(i / 3, i % 3)]).collect()
    }
}
