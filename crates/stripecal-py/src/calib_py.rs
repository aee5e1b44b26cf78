//! `stripecal.solve_axzb`, `stripecal.solve_axzb_full`, `stripecal.fit_laser_plane`:
//! the two-stage calibration pieces (hand-eye / robot-world, laser plane).
//!
//! Transforms are `(N, 4, 4)` homogeneous float arrays (rigid to 1e-6); the GIL is
//! released while the core computes.

use nalgebra::Matrix4;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PySequence};

use stripecal::calib::axzb::{solve_axzb_with, AxzbOptions, AxzbSolution};
use stripecal::calib::laser_plane::fit_laser_plane as core_fit_laser_plane;
use stripecal::geometry::{iso_from_matrix, Iso3};

use crate::camera::PyCamera;
use crate::convert::{f64_array, fmt_shape, iso_to_py, nd, RIGID_TOL};
use crate::errors::{invalid_input, map_err_at, ResultExt};

/// `(N, 4, 4)` rigid transforms.
fn isos_from_py(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<Iso3>> {
    let py = obj.py();
    let a = f64_array(obj, name)?;
    let n = match a.shape() {
        [n, 4, 4] => *n,
        s => {
            return Err(invalid_input(
                py,
                format!("{name} must have shape (N, 4, 4), got {}", fmt_shape(s)),
            ))
        }
    };
    (0..n)
        .map(|i| {
            let m = Matrix4::from_fn(|r, c| a[[i, r, c].as_slice()]);
            iso_from_matrix(&m, RIGID_TOL).map_err(|e| map_err_at(py, e, &format!("{name}[{i}]")))
        })
        .collect()
}

fn solve(
    py: Python<'_>,
    a: &Bound<'_, PyAny>,
    b: &Bound<'_, PyAny>,
    refine: bool,
) -> PyResult<AxzbSolution> {
    let a = isos_from_py(a, "A")?;
    let b = isos_from_py(b, "B")?;
    let opts = AxzbOptions { refine };
    py.detach(|| solve_axzb_with(&a, &b, &opts)).py_err(py)
}

/// Solves `A_i X = Z B_i` for `X = T_hand_cam` and `Z = T_base_board` from
/// `A` = `T_base_hand(q_i)` `(N, 4, 4)` and `B` = `T_board_cam(i)` (the inverse of the
/// board pose in the camera) `(N, 4, 4)`. Returns `(X, Z)`, two `(4, 4)` arrays.
///
/// Kronecker rotation system (SVD), translation least squares, then (if `refine`) a
/// Gauss-Newton refinement. Raises `DegenerateError` (naming the figure) for pose sets
/// that do not determine X and Z: fewer than 3 poses, too little rotation, rotations
/// about one axis only.
#[pyfunction]
#[pyo3(signature = (A, B, refine = true))]
#[allow(non_snake_case)]
pub fn solve_axzb<'py>(
    py: Python<'py>,
    A: &Bound<'py, PyAny>,
    B: &Bound<'py, PyAny>,
    refine: bool,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let s = solve(py, A, B, refine)?;
    Ok((iso_to_py(py, &s.x)?, iso_to_py(py, &s.z)?))
}

/// Like `solve_axzb`, with the diagnostics: a dict with `X`, `Z` `(4, 4)`,
/// `rotation_residual_rad`, `translation_residual` (RMS, unit of the input),
/// `axis_spread_deg`, `max_rotation_deg`, `min_rotation_deg`, `rotation_condition`,
/// `refined` (bool) and `warnings` (list of str).
#[pyfunction]
#[pyo3(signature = (A, B, refine = true))]
#[allow(non_snake_case)]
pub fn solve_axzb_full<'py>(
    py: Python<'py>,
    A: &Bound<'py, PyAny>,
    B: &Bound<'py, PyAny>,
    refine: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let s = solve(py, A, B, refine)?;
    let d = PyDict::new(py);
    d.set_item("X", iso_to_py(py, &s.x)?)?;
    d.set_item("Z", iso_to_py(py, &s.z)?)?;
    d.set_item("rotation_residual_rad", s.rotation_residual_rad)?;
    d.set_item("translation_residual", s.translation_residual_mm)?;
    let c = s.conditioning;
    d.set_item("axis_spread_deg", c.axis_spread_deg)?;
    d.set_item("max_rotation_deg", c.max_rotation_deg)?;
    d.set_item("min_rotation_deg", c.min_rotation_deg)?;
    d.set_item("rotation_condition", c.rotation_condition)?;
    d.set_item("refined", s.refined)?;
    d.set_item("warnings", PyList::new(py, &s.warnings)?)?;
    Ok(d)
}

/// Fits the laser plane (camera frame, `n . p = d`, `|n| = 1`, `d > 0`) to stripe points
/// on the board. `cam_board`: `(N, 4, 4)` board poses `T_cam_board`; `stripes`: a
/// sequence of N arrays `(M_i, 2)` of stripe pixels `(u, v)` on the board (may be empty);
/// `camera`: the calibrated camera.
///
/// Returns a dict: `normal` `(3,)`, `d_mm`, `rms_mm`, `per_view_rms_mm` (list, `None`
/// for views without points), `n_points`, `n_outliers`, `normal_sigma` `(3,)`,
/// `d_sigma_mm`, `max_line_angle_deg`, `span_across_mm`, `warnings`. Raises
/// `DegenerateError` (with the figure) when the points do not determine a plane.
#[pyfunction]
pub fn fit_laser_plane<'py>(
    py: Python<'py>,
    cam_board: &Bound<'py, PyAny>,
    stripes: &Bound<'py, PyAny>,
    camera: PyRef<'py, PyCamera>,
) -> PyResult<Bound<'py, PyDict>> {
    let poses = isos_from_py(cam_board, "cam_board")?;
    let seq = stripes.cast::<PySequence>().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err("stripes must be a sequence of (M, 2) arrays")
    })?;
    let n = seq.len()?;
    if n != poses.len() {
        return Err(invalid_input(
            py,
            format!(
                "stripes has {n} entries but cam_board has {} poses",
                poses.len()
            ),
        ));
    }
    let mut views = Vec::with_capacity(n);
    for (i, pose) in poses.into_iter().enumerate() {
        let name = format!("stripes[{i}]");
        let a = f64_array(&seq.get_item(i)?, &name)?;
        let pts: Vec<[f64; 2]> = match a.shape() {
            [0] => Vec::new(),
            [_, 2] => a.rows().into_iter().map(|r| [r[0], r[1]]).collect(),
            s => {
                return Err(invalid_input(
                    py,
                    format!("{name} must have shape (M, 2), got {}", fmt_shape(s)),
                ))
            }
        };
        views.push((pose, pts));
    }
    let cam = camera.inner.clone();
    let fit = py
        .detach(|| core_fit_laser_plane(&views, &cam))
        .py_err(py)?;
    let d = PyDict::new(py);
    let nrm = fit.plane.normal;
    d.set_item("normal", nd(py, &[3], vec![nrm.x, nrm.y, nrm.z])?)?;
    d.set_item("d_mm", fit.plane.d)?;
    d.set_item("rms_mm", fit.rms_mm)?;
    d.set_item("per_view_rms_mm", PyList::new(py, &fit.per_view_rms_mm)?)?;
    d.set_item("n_points", fit.n_points)?;
    d.set_item("n_outliers", fit.n_outliers)?;
    let s = fit.sigma.normal;
    d.set_item("normal_sigma", nd(py, &[3], vec![s.x, s.y, s.z])?)?;
    d.set_item("d_sigma_mm", fit.sigma.d_mm)?;
    d.set_item("max_line_angle_deg", fit.max_line_angle_deg)?;
    d.set_item("span_across_mm", fit.span_across_mm)?;
    d.set_item("warnings", PyList::new(py, &fit.warnings)?)?;
    Ok(d)
}
