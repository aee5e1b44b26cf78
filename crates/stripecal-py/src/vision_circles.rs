//! `stripecal.detect_circles` and `stripecal.detect_circles_full`: the circle grid of a
//! board image, indexed by `(row, col)` with sub-pixel centres.
//!
//! Images are 2D uint8/uint16 numpy arrays of any strides (copied, then the GIL is
//! released); other dtypes are a `TypeError`, other shapes or empty arrays an
//! `InvalidInputError`. A grid that cannot be found or indexed without guessing is a
//! `DetectionError` saying what was found.

use crate::pool::Detach;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use stripecal::vision::circles::{self as core, CentreMethod, CircleGrid, CircleOptions};

use crate::convert::nd;
use crate::errors::ResultExt;
use crate::imageview::gray_from_py;
use crate::PyBoard;

fn run(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    board: &PyBoard,
    method: &str,
    drop_stripe_crossed: bool,
) -> PyResult<CircleGrid> {
    let img = gray_from_py(image, "image")?;
    let method = CentreMethod::from_name(method).py_err(py)?;
    let opts = CircleOptions {
        method,
        drop_stripe_crossed,
        ..Default::default()
    };
    let board = board.inner.clone();
    py.detach_pool(|| core::detect_circles(img.view()?, &board, &opts))
        .py_err(py)
}

fn indices_centres<'py>(
    py: Python<'py>,
    g: &CircleGrid,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let n = g.circles.len();
    let idx: Vec<i64> = g
        .circles
        .iter()
        .flat_map(|c| [c.row as i64, c.col as i64])
        .collect();
    let ctr: Vec<f64> = g.circles.iter().flat_map(|c| [c.u, c.v]).collect();
    Ok((nd(py, &[n, 2], idx)?, nd(py, &[n, 2], ctr)?))
}

/// Detects the circles of `board` in `image` (2D uint8/uint16).
///
/// Returns `(indices, centres)`: `indices` (N, 2) int64 as `(row, col)`, `centres`
/// (N, 2) float64 as `(u, v)` px (the top-left pixel's centre is (0, 0)), sorted by
/// `(row, col)`. Partial boards give the visible circles as long as every marker is
/// seen. `method` is `"gravity"` (background-corrected intensity centroid, default)
/// or `"ellipse"` (centre of an ellipse fitted to sub-pixel edge points). Circles
/// crossed by a bright laser stripe (single-image views) are left out.
///
/// Raises `DetectionError` when no grid is found or it cannot be indexed without
/// guessing, `InvalidInputError` for a bad image shape, board or method, `TypeError`
/// for an image that is not a uint8/uint16 numpy array.
#[pyfunction]
#[pyo3(signature = (image, board, method = "gravity"))]
pub fn detect_circles<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    board: PyRef<'py, PyBoard>,
    method: &str,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let g = run(py, image, &board, method, true)?;
    indices_centres(py, &g)
}

/// Like `detect_circles`, with everything the detector knows, as a dict:
/// `indices` (N, 2) int64, `centres` (N, 2) float64, `quality_px` (N,) (RMS residual
/// of an ellipse fitted to the circle's edge points, NaN if none could be fitted),
/// `area_px` (N,), `axes_px` (N, 2) (ellipse semi-axes, major first), `angle_rad` (N,)
/// (major axis from +u towards +v), `stripe_crossed` (N,) bool, `dropped` (a list of
/// `{row, col, u, v, reason}` for indexed circles left out), `blobs`, `nodes_grown`,
/// `nodes_inconsistent`, `homography_rms_px`, `homography_max_px`, `method`.
/// With `drop_stripe_crossed=False` circles crossed by a stripe are kept and flagged.
#[pyfunction]
#[pyo3(signature = (image, board, method = "gravity", drop_stripe_crossed = true))]
pub fn detect_circles_full<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    board: PyRef<'py, PyBoard>,
    method: &str,
    drop_stripe_crossed: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let g = run(py, image, &board, method, drop_stripe_crossed)?;
    let n = g.circles.len();
    let d = PyDict::new(py);
    let (idx, ctr) = indices_centres(py, &g)?;
    d.set_item("indices", idx)?;
    d.set_item("centres", ctr)?;
    let col = |f: &dyn Fn(&core::DetectedCircle) -> f64| -> Vec<f64> {
        g.circles.iter().map(f).collect()
    };
    d.set_item("quality_px", nd(py, &[n], col(&|c| c.quality_px))?)?;
    d.set_item("area_px", nd(py, &[n], col(&|c| c.area_px))?)?;
    d.set_item(
        "axes_px",
        nd(
            py,
            &[n, 2],
            g.circles.iter().flat_map(|c| c.axes_px).collect(),
        )?,
    )?;
    d.set_item("angle_rad", nd(py, &[n], col(&|c| c.angle_rad))?)?;
    d.set_item(
        "stripe_crossed",
        nd(
            py,
            &[n],
            g.circles.iter().map(|c| c.stripe_crossed).collect(),
        )?,
    )?;
    let dropped = PyList::empty(py);
    for c in &g.dropped {
        let e = PyDict::new(py);
        e.set_item("row", c.row)?;
        e.set_item("col", c.col)?;
        e.set_item("u", c.u)?;
        e.set_item("v", c.v)?;
        e.set_item("reason", c.reason)?;
        dropped.append(e)?;
    }
    d.set_item("dropped", dropped)?;
    d.set_item("blobs", g.blobs)?;
    d.set_item("nodes_grown", g.nodes_grown)?;
    d.set_item("nodes_inconsistent", g.nodes_inconsistent)?;
    d.set_item("homography_rms_px", g.homography_rms_px)?;
    d.set_item("homography_max_px", g.homography_max_px)?;
    d.set_item("method", g.method.name())?;
    Ok(d)
}
