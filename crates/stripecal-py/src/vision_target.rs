//! `stripecal.detect_target` and `stripecal.TargetDetection`: any target kind (circle
//! grid with any number of markers, asymmetric circle grid, chessboard) in a gray or
//! colour image, as typed arrays.

use crate::pool::Detach;
use pyo3::prelude::*;

use stripecal::model::board::Symmetry;
use stripecal::vision::circles::CentreMethod;
use stripecal::vision::target::{self as core, PointFlags, TargetOptions};

use crate::convert::nd;
use crate::errors::ResultExt;
use crate::imageview::gray_or_colour_from_py;
use crate::PyBoard;

/// What `detect_target` found: the indexed points sorted by `(row, col)`, their flags,
/// the indexed points it left out with the reason, and the board symmetries the image
/// cannot decide (`alternatives`: the calibration chooses among them from the robot
/// poses; never guessed here).
#[pyclass(name = "TargetDetection", module = "stripecal", frozen)]
pub struct PyTargetDetection {
    inner: core::TargetDetection,
    board: stripecal::Board,
}

/// Bit of `flags`: the point is a marker circle.
const FLAG_MARKER: u8 = PointFlags::MARKER;
/// Bit of `flags`: a bright stripe crosses the point's window (kept and flagged).
const FLAG_STRIPE_CROSSED: u8 = PointFlags::STRIPE_CROSSED;
/// Bit of `flags`: the point's window is near the image border.
const FLAG_NEAR_BORDER: u8 = PointFlags::NEAR_BORDER;

#[pymethods]
impl PyTargetDetection {
    #[classattr]
    const FLAG_MARKER: u8 = FLAG_MARKER;
    #[classattr]
    const FLAG_STRIPE_CROSSED: u8 = FLAG_STRIPE_CROSSED;
    #[classattr]
    const FLAG_NEAR_BORDER: u8 = FLAG_NEAR_BORDER;

    /// The board kind: "circles", "asymmetric_circles" or "chessboard".
    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.kind.name()
    }

    /// `(row, col)` of every point, shape (N, 2), int64, sorted.
    #[getter]
    fn indices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = &self.inner.points;
        nd(
            py,
            &[p.len(), 2],
            p.iter()
                .flat_map(|q| [q.row as i64, q.col as i64])
                .collect(),
        )
    }

    /// Sub-pixel image positions `(u, v)`, px, shape (N, 2): circle centroids or
    /// chessboard corners (the top-left pixel's centre is (0, 0)).
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = &self.inner.points;
        nd(
            py,
            &[p.len(), 2],
            p.iter().flat_map(|q| [q.u, q.v]).collect(),
        )
    }

    /// Per-point flag bits, shape (N,), uint8: `FLAG_MARKER`, `FLAG_STRIPE_CROSSED`,
    /// `FLAG_NEAR_BORDER`.
    #[getter]
    fn flags<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = &self.inner.points;
        nd(py, &[p.len()], p.iter().map(|q| q.flags.0).collect())
    }

    /// Per-point quality figure, px, shape (N,): a circle's ellipse-fit RMS, a corner's
    /// refinement residual (NaN where not available).
    #[getter]
    fn quality_px<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = &self.inner.points;
        nd(py, &[p.len()], p.iter().map(|q| q.quality_px).collect())
    }

    /// `(row, col)` of the indexed points left out, shape (M, 2), int64.
    #[getter]
    fn dropped_indices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let d = &self.inner.dropped;
        nd(
            py,
            &[d.len(), 2],
            d.iter()
                .flat_map(|q| [q.row as i64, q.col as i64])
                .collect(),
        )
    }

    /// Rough positions of the points left out, px, shape (M, 2).
    #[getter]
    fn dropped_points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let d = &self.inner.dropped;
        nd(
            py,
            &[d.len(), 2],
            d.iter().flat_map(|q| [q.u, q.v]).collect(),
        )
    }

    /// Why each point in `dropped_indices` was left out.
    #[getter]
    fn dropped_reasons(&self) -> Vec<&'static str> {
        self.inner.dropped.iter().map(|d| d.reason).collect()
    }

    /// The board symmetries this view cannot decide, as `(quarter_turns, (di, dj))`
    /// lattice rotations; empty when the labelling is unique. `relabel(k)` gives the
    /// indices under alternative `k`.
    #[getter]
    fn alternatives(&self) -> Vec<(u8, (i64, i64))> {
        self.inner
            .alternatives
            .iter()
            .map(|s| (s.quarter_turns, s.shift))
            .collect()
    }

    /// `indices` under alternative `k` (shape (N, 2), int64): the same image points
    /// labelled as the board would be after that rotation.
    fn relabel<'py>(&self, py: Python<'py>, k: usize) -> PyResult<Bound<'py, PyAny>> {
        let s: &Symmetry = self.inner.alternatives.get(k).ok_or_else(|| {
            pyo3::exceptions::PyIndexError::new_err(format!(
                "alternative {k} does not exist ({} alternatives)",
                self.inner.alternatives.len()
            ))
        })?;
        let mut out = Vec::with_capacity(2 * self.inner.points.len());
        for p in &self.inner.points {
            let (r, c) = s.apply(&self.board, p.row, p.col).ok_or_else(|| {
                pyo3::exceptions::PyRuntimeError::new_err("a symmetry left the board (internal)")
            })?;
            out.extend([r as i64, c as i64]);
        }
        nd(py, &[self.inner.points.len(), 2], out)
    }

    /// RMS residual of a board-to-image homography through the points, px (lens
    /// distortion shows here too; NaN below 5 points).
    #[getter]
    fn homography_rms_px(&self) -> f64 {
        self.inner.homography_rms_px
    }

    /// Largest residual of that homography, px.
    #[getter]
    fn homography_max_px(&self) -> f64 {
        self.inner.homography_max_px
    }

    fn __len__(&self) -> usize {
        self.inner.points.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "TargetDetection(kind='{}', points={}, dropped={}, alternatives={})",
            self.inner.kind.name(),
            self.inner.points.len(),
            self.inner.dropped.len(),
            self.inner.alternatives.len()
        )
    }
}

/// Detects `board` in `image`, whatever its kind (`board.kind`): a circle grid with
/// any number of markers (none included), an asymmetric circle grid or a chessboard.
///
/// `image` is a 2D uint8/uint16 array, or a 3D (rows, columns, 3 or 4) RGB(A) array
/// converted to gray by BT.601 luma. `method` chooses the circle-centre method
/// ("gravity" or "ellipse", circle kinds only); with `drop_stripe_crossed=False`
/// circles crossed by a laser stripe are kept and flagged.
///
/// Raises `DetectionError` when the board is not found, cannot be indexed without
/// guessing or does not match the board's size (the message says what was found),
/// `InvalidInputError` for a bad image shape, board or option, `TypeError` for an image
/// that is not a uint8/uint16 numpy array. The GIL is released while it runs.
#[pyfunction]
#[pyo3(signature = (image, board, *, method = "gravity", drop_stripe_crossed = true))]
pub fn detect_target(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    board: PyRef<'_, PyBoard>,
    method: &str,
    drop_stripe_crossed: bool,
) -> PyResult<PyTargetDetection> {
    let img = gray_or_colour_from_py(image, "image")?;
    let mut opts = TargetOptions::default();
    opts.circles.method = CentreMethod::from_name(method).py_err(py)?;
    opts.circles.drop_stripe_crossed = drop_stripe_crossed;
    let board = board.inner.clone();
    let inner = py
        .detach_pool(|| core::detect_target(img.view()?, &board, &opts))
        .py_err(py)?;
    Ok(PyTargetDetection { inner, board })
}
