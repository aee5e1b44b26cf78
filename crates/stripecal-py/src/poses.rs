//! Flange poses in controller conventions (`stripecal::io::poses`): a row of pose
//! values <-> a 4x4 `T_base_hand` (mm).

use nalgebra::Matrix4;
use numpy::ndarray::ArrayD;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyString;
use stripecal::io::PoseColumns;
use stripecal::model::geometry::iso_from_matrix;
use stripecal::Iso3;

use crate::convert::{f64_array, fmt_shape, iso_to_py, isos_to_py, nd, RIGID_TOL};
use crate::errors::{invalid_input, map_err_at};

/// The pose columns of `convention`: a shorthand name (`"ros"`), a comma-separated
/// header (`"x_m,y_m,z_m,qx,qy,qz,qw"`) or a sequence of column names.
fn columns(convention: &Bound<'_, PyAny>) -> PyResult<PoseColumns> {
    let py = convention.py();
    let names: Vec<String> = if let Ok(s) = convention.cast::<PyString>() {
        vec![s.extract::<String>()?]
    } else {
        convention.extract::<Vec<String>>().map_err(|_| {
            PyTypeError::new_err(format!(
                "convention must be a str or a sequence of str, got {}",
                crate::convert::type_name(convention)
            ))
        })?
    };
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    PoseColumns::from_spec(&refs).map_err(|e| invalid_input(py, format!("convention: {e}")))
}

/// `T_base_hand` (4, 4) of a controller's pose values (N,), or (M, 4, 4) of rows (M, N).
///
/// `convention` names the values' columns (spec/DATASET.md, views.csv): a shorthand
/// (`"quaternion"`: x_mm,y_mm,z_mm,qw,qx,qy,qz; `"ros"`: x_m,y_m,z_m,qx,qy,qz,qw;
/// `"rotvec"`: x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad; `"rotvec_deg"`; `"ur"`:
/// x_m,y_m,z_m,rx_rad,ry_rad,rz_rad; `"kuka"`: x_mm,y_mm,z_mm,a_deg,b_deg,c_deg with
/// R = Rz(A) Ry(B) Rx(C); `"fanuc"`: x_mm,y_mm,z_mm,w_deg,p_deg,r_deg with
/// R = Rz(R) Ry(P) Rx(W); `"matrix"`: x_mm,y_mm,z_mm,r11,...,r33 row by row), a
/// comma-separated header such as `"qx,qy,qz,qw,x_m,y_m,z_m"` (any order), or a sequence
/// of column names. The translation of the result is in mm whatever the columns' unit.
/// A quaternion whose norm, or a matrix whose `R^T R` and determinant, are off by more
/// than 1e-3 raise InvalidInputError (within it they are normalised).
#[pyfunction]
pub fn pose_to_matrix<'py>(
    py: Python<'py>,
    values: &Bound<'py, PyAny>,
    convention: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let cols = columns(convention)?;
    let a = f64_array(values, "values")?;
    let n = cols.len();
    let (rows, single) = match a.shape() {
        [k] if *k == n => (1, true),
        [m, k] if *k == n => (*m, false),
        s => {
            return Err(invalid_input(
                py,
                format!(
                    "values must have shape ({n},) or (M, {n}) for the columns {}, got {}",
                    cols.names().join(","),
                    fmt_shape(s)
                ),
            ))
        }
    };
    let flat: Vec<f64> = a.iter().copied().collect();
    let isos = (0..rows)
        .map(|i| {
            cols.to_iso(&flat[i * n..(i + 1) * n]).map_err(|e| {
                let at = if single {
                    "values".to_string()
                } else {
                    format!("values[{i}]")
                };
                invalid_input(py, format!("{at}: {e}"))
            })
        })
        .collect::<PyResult<Vec<Iso3>>>()?;
    if single {
        iso_to_py(py, &isos[0])
    } else {
        isos_to_py(py, &isos)
    }
}

/// One rigid transform of a (4, 4) block of `a` starting at `offset`.
fn iso_at(py: Python<'_>, a: &ArrayD<f64>, offset: usize, name: &str) -> PyResult<Iso3> {
    let flat: Vec<f64> = a.iter().copied().skip(offset).take(16).collect();
    let m = Matrix4::from_row_slice(&flat);
    iso_from_matrix(&m, RIGID_TOL).map_err(|e| map_err_at(py, e, name))
}

/// A controller's pose values (N,) of `T_base_hand` (4, 4) (mm), or (M, N) of (M, 4, 4):
/// the inverse of `pose_to_matrix` with the same `convention`. Rotation vectors come back
/// with angles in [0, pi]; Euler angles with the middle one (KUKA's B, Fanuc's P) in
/// [-90, 90] deg; quaternions with either sign. The rotation part of `transform` must be
/// a rotation within 1e-6.
#[pyfunction]
pub fn matrix_to_pose<'py>(
    py: Python<'py>,
    transform: &Bound<'py, PyAny>,
    convention: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let cols = columns(convention)?;
    let a = f64_array(transform, "transform")?;
    let n = cols.len();
    match a.shape() {
        [4, 4] => nd(py, &[n], cols.to_values(&iso_at(py, &a, 0, "transform")?)),
        [m, 4, 4] => {
            let mut data = Vec::with_capacity(m * n);
            for i in 0..*m {
                let t = iso_at(py, &a, 16 * i, &format!("transform[{i}]"))?;
                data.extend(cols.to_values(&t));
            }
            nd(py, &[*m, n], data)
        }
        s => Err(invalid_input(
            py,
            format!(
                "transform must have shape (4, 4) or (M, 4, 4), got {}",
                fmt_shape(s)
            ),
        )),
    }
}
