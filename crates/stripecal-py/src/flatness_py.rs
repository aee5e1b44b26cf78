//! Binding of the board flatness figure (`stripecal::calib::flatness`): converts and
//! calls, nothing more.

use crate::pool::Detach;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use stripecal::calib::flatness::{view_flatness, FlatnessOptions};
use stripecal::calib::CircleObs;

use crate::board::PyBoard;
use crate::camera::PyCamera;
use crate::convert::{f64_array, fmt_shape, iso_to_py, py_to_iso};
use crate::errors::{invalid_input, map_err};

/// The flatness figure of one board view: `indices` `(N, 2)` (row, col) and `points`
/// `(N, 2)` (detected image positions, px) of `board`, `cam_board` `(4, 4)` the view's
/// pose, `sigma_px` the detections' one-sigma (None: from the residuals). Returns a
/// dict: `sag_mm`, `sigma_mm`, `axis_deg`, `width_mm`, `sag2_mm`, `sigma2_mm`,
/// `rms_px`, `rms_flat_px`, `points`, `cam_board` `(4, 4)`.
#[pyfunction]
#[pyo3(signature = (camera, board, indices, points, cam_board, sigma_px=None))]
pub fn board_flatness<'py>(
    py: Python<'py>,
    camera: PyRef<'py, PyCamera>,
    board: PyRef<'py, PyBoard>,
    indices: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
    cam_board: &Bound<'py, PyAny>,
    sigma_px: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let idx = f64_array(indices, "indices")?;
    let pts = f64_array(points, "points")?;
    let n = match (idx.shape(), pts.shape()) {
        ([a, 2], [b, 2]) if a == b => *a,
        (si, sp) => {
            return Err(invalid_input(
                py,
                format!(
                    "indices and points must both have shape (N, 2), got {} and {}",
                    fmt_shape(si),
                    fmt_shape(sp)
                ),
            ))
        }
    };
    let b = &board.inner;
    let mut circles = Vec::with_capacity(n);
    for i in 0..n {
        let (r, c) = (idx[[i, 0]], idx[[i, 1]]);
        if !(r >= 0.0 && c >= 0.0 && r.fract() == 0.0 && c.fract() == 0.0)
            || r as usize >= b.rows
            || c as usize >= b.cols
        {
            return Err(invalid_input(
                py,
                format!(
                    "indices[{i}] = ({r}, {c}) is not a point of the {}x{} board",
                    b.rows, b.cols
                ),
            ));
        }
        circles.push(CircleObs {
            row: r as usize,
            col: c as usize,
            u: pts[[i, 0]],
            v: pts[[i, 1]],
        });
    }
    let pose = py_to_iso(cam_board, "cam_board")?;
    let cam = camera.inner.clone();
    let board = b.clone();
    let f = py
        .detach_pool(|| view_flatness(&cam, &board, &circles, &pose, &FlatnessOptions { sigma_px }))
        .map_err(|e| map_err(py, e))?;
    let d = PyDict::new(py);
    d.set_item("sag_mm", f.sag_mm)?;
    d.set_item("sigma_mm", f.sigma_mm)?;
    d.set_item("axis_deg", f.axis_deg)?;
    d.set_item("width_mm", f.width_mm)?;
    d.set_item("sag2_mm", f.sag2_mm)?;
    d.set_item("sigma2_mm", f.sigma2_mm)?;
    d.set_item("rms_px", f.rms_px)?;
    d.set_item("rms_flat_px", f.rms_flat_px)?;
    d.set_item("points", f.points)?;
    d.set_item("cam_board", iso_to_py(py, &f.cam_board)?)?;
    Ok(d)
}
