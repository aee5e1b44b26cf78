//! Rotation helpers.

use nalgebra::{Matrix3, Vector3};
use pyo3::prelude::*;
use stripecal::model::geometry::{
    matrix_to_rotvec as core_m2r, nearest_rotation as core_nearest, rotvec_to_matrix as core_r2m,
};

use crate::convert::{fixed, mat3_to_py, nd, py_to_mat3};
use crate::errors::invalid_input;

/// Tolerance on `R^T R - I` for `matrix_to_rotvec`.
const ROTATION_TOL: f64 = 1e-6;

/// The rotation matrix (3, 3) of a rotation vector (3,) (axis times angle, radians).
#[pyfunction]
pub fn rotvec_to_matrix<'py>(
    py: Python<'py>,
    rotvec: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let r = fixed::<3>(rotvec, "rotvec")?;
    mat3_to_py(py, &core_r2m(&Vector3::from(r)))
}

/// The rotation vector (3,) (angle in [0, pi], radians) of a rotation matrix (3, 3).
/// Raises InvalidInputError when the matrix is not a rotation (use `nearest_rotation`).
#[pyfunction]
pub fn matrix_to_rotvec<'py>(
    py: Python<'py>,
    matrix: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let m = py_to_mat3(matrix, "matrix")?;
    let err = (m.transpose() * m - Matrix3::identity()).abs().max();
    if err.is_nan() || err > ROTATION_TOL || m.determinant() < 0.0 {
        return Err(invalid_input(
            py,
            format!(
                "matrix is not a rotation (|R^T R - I| = {err:.2e}, det = {:.6}); use nearest_rotation first",
                m.determinant()
            ),
        ));
    }
    let r = core_m2r(&m);
    nd(py, &[3], vec![r.x, r.y, r.z])
}

/// The rotation (3, 3) closest to a matrix (3, 3) in the Frobenius norm (determinant +1).
#[pyfunction]
pub fn nearest_rotation<'py>(
    py: Python<'py>,
    matrix: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let m = py_to_mat3(matrix, "matrix")?;
    if m.iter().any(|x| !x.is_finite()) {
        return Err(invalid_input(py, "matrix has non-finite entries"));
    }
    mat3_to_py(py, &core_nearest(&m))
}
