//! `stripecal.Board`.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::args::{bind_as, Params};
use stripecal::model::board::{Board, BoardKind};

use crate::convert::{nd, non_negative};
use crate::errors::{invalid_input, ResultExt};

/// The calibration target (spec/DATASET.md, "Target kinds"): `kind` "circles" (a
/// `rows x cols` grid of circles, circle (row, col) centred at board coordinates
/// `(col * pitch_mm, row * pitch_mm, 0)`; `markers`, default the L `(0, 0), (0, 1),
/// (1, 0)`, any number or none, have `marker_diameter_mm`), "asymmetric_circles"
/// (OpenCV's asymmetric grid, odd rows shifted by half a pitch; see
/// `Board.asymmetric_circles`) or "chessboard" (inner corners; see
/// `Board.chessboard`). Board z points into the plate.
#[pyclass(name = "Board", module = "stripecal", frozen, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyBoard {
    pub inner: Board,
}

impl PyBoard {
    pub fn new_py(inner: Board) -> Self {
        PyBoard { inner }
    }
}

fn kind_name(k: BoardKind) -> &'static str {
    k.name()
}

/// `Board`'s parameters (see [`bind_as`]).
const BOARD: Params = Params {
    name: "Board",
    positional: &[
        "rows",
        "cols",
        "pitch_mm",
        "circle_diameter_mm",
        "marker_diameter_mm",
        "markers",
        "dark_circles",
        "kind",
        "square_mm",
    ],
    required: 4,
    keyword: &[],
};

/// `Board`'s arguments, with their defaults.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct BoardArgs {
    rows: i64,
    cols: i64,
    pitch_mm: f64,
    circle_diameter_mm: f64,
    #[pyo3(default)]
    marker_diameter_mm: Option<f64>,
    #[pyo3(default)]
    markers: Option<Vec<(i64, i64)>>,
    #[pyo3(default = true)]
    dark_circles: bool,
    #[pyo3(default = "circles".into())]
    kind: String,
    #[pyo3(default)]
    square_mm: Option<f64>,
}

#[pymethods]
impl PyBoard {
    #[new]
    #[pyo3(signature = (*args, **kwargs), text_signature = "(rows, cols, pitch_mm, circle_diameter_mm, marker_diameter_mm=None, markers=None, dark_circles=True, kind=\"circles\", square_mm=None)")]
    fn new(
        py: Python<'_>,
        args: &Bound<'_, PyTuple>,
        kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let BoardArgs {
            rows,
            cols,
            pitch_mm,
            circle_diameter_mm,
            marker_diameter_mm,
            markers,
            dark_circles,
            kind,
            square_mm,
        } = bind_as(&BOARD, args, kwargs)?;
        let kind = kind.as_str();
        let kind = BoardKind::from_name(kind).map_err(|e| invalid_input(py, e.to_string()))?;
        let markers = match markers {
            None if kind == BoardKind::Circles => Board::default_markers(),
            None => Vec::new(),
            Some(ms) => ms
                .into_iter()
                .map(|(r, c)| {
                    Ok([
                        non_negative(py, r, "marker row")?,
                        non_negative(py, c, "marker column")?,
                    ])
                })
                .collect::<PyResult<Vec<_>>>()?,
        };
        let marker_diameter_mm = match marker_diameter_mm {
            Some(d) => d,
            None if markers.is_empty() => circle_diameter_mm,
            None => {
                return Err(invalid_input(
                    py,
                    "marker_diameter_mm is needed when the board has markers (pass markers=[] \
                     for a grid without)",
                ))
            }
        };
        let b = Board {
            kind,
            rows: non_negative(py, rows, "rows")?,
            cols: non_negative(py, cols, "cols")?,
            pitch_mm,
            circle_diameter_mm,
            marker_diameter_mm,
            markers,
            dark_circles,
            square_mm,
        };
        b.validate().py_err(py)?;
        Ok(PyBoard::new_py(b))
    }

    /// The 8 x 11 board of the `hp3-paper` preset (pitch 5, circles 2.5, markers 3.5 mm).
    #[staticmethod]
    fn hp3_paper() -> Self {
        PyBoard::new_py(Board::hp3_paper())
    }

    /// A chessboard of `rows x cols` INNER corners (a board of `(rows + 1) x (cols + 1)`
    /// squares), corner (r, c) at `(c * square_mm, r * square_mm, 0)`; the square
    /// outside corner (0, 0) is dark.
    #[staticmethod]
    fn chessboard(py: Python<'_>, rows: i64, cols: i64, square_mm: f64) -> PyResult<Self> {
        let b = Board::chessboard(
            non_negative(py, rows, "rows")?,
            non_negative(py, cols, "cols")?,
            square_mm,
        )
        .py_err(py)?;
        Ok(PyBoard::new_py(b))
    }

    /// OpenCV's asymmetric circle grid: `rows x cols` circles, circle (r, c) at
    /// `((2 c + r mod 2) * pitch_mm / 2, r * pitch_mm / 2, 0)` (`pitch_mm` is the distance
    /// between neighbours in one row).
    #[staticmethod]
    #[pyo3(signature = (rows, cols, pitch_mm, circle_diameter_mm, dark_circles = true))]
    fn asymmetric_circles(
        py: Python<'_>,
        rows: i64,
        cols: i64,
        pitch_mm: f64,
        circle_diameter_mm: f64,
        dark_circles: bool,
    ) -> PyResult<Self> {
        let mut b = Board::asymmetric_circles(
            non_negative(py, rows, "rows")?,
            non_negative(py, cols, "cols")?,
            pitch_mm,
            circle_diameter_mm,
        )
        .py_err(py)?;
        b.dark_circles = dark_circles;
        Ok(PyBoard::new_py(b))
    }

    /// The rotations that map the board onto itself, points and appearance alike, as
    /// `(quarter_turns, (di, dj))` lattice maps; empty when the board fixes its own
    /// orientation (markers, colours, an odd number of rows...).
    fn symmetries(&self) -> Vec<(u8, (i64, i64))> {
        self.inner
            .symmetries()
            .iter()
            .map(|s| (s.quarter_turns, s.shift))
            .collect()
    }

    /// `"circles"`, `"asymmetric_circles"` or `"chessboard"`.
    #[getter]
    fn kind(&self) -> &'static str {
        kind_name(self.inner.kind)
    }

    /// Grid rows (circles along board y).
    #[getter]
    fn rows(&self) -> usize {
        self.inner.rows
    }

    /// Grid columns (circles along board x).
    #[getter]
    fn cols(&self) -> usize {
        self.inner.cols
    }

    /// Centre-to-centre distance, mm.
    #[getter]
    fn pitch_mm(&self) -> f64 {
        self.inner.pitch_mm
    }

    /// Diameter of ordinary circles, mm.
    #[getter]
    fn circle_diameter_mm(&self) -> f64 {
        self.inner.circle_diameter_mm
    }

    /// Diameter of marker circles, mm.
    #[getter]
    fn marker_diameter_mm(&self) -> f64 {
        self.inner.marker_diameter_mm
    }

    /// Marker circles as `(row, col)`.
    #[getter]
    fn markers(&self) -> Vec<(usize, usize)> {
        self.inner.markers.iter().map(|m| (m[0], m[1])).collect()
    }

    /// Dark circles on a light plate (True) or light on dark.
    #[getter]
    fn dark_circles(&self) -> bool {
        self.inner.dark_circles
    }

    /// Chessboard square size in mm (chessboards only).
    #[getter]
    fn square_mm(&self) -> Option<f64> {
        self.inner.square_mm
    }

    /// Point positions (circle centres or inner corners) in board coordinates (mm),
    /// shape (rows * cols, 3), row-major.
    fn centers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let b = &self.inner;
        let data = b
            .indices()
            .flat_map(|(r, c)| {
                let p = b.center(r, c);
                [p.x, p.y, p.z]
            })
            .collect();
        nd(py, &[b.len(), 3], data)
    }

    /// `(row, col)` of every circle, shape (rows * cols, 2), int64, same order as
    /// `centers()`.
    fn indices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let b = &self.inner;
        let data: Vec<i64> = b
            .indices()
            .flat_map(|(r, c)| [r as i64, c as i64])
            .collect();
        nd(py, &[b.len(), 2], data)
    }

    /// Circle diameters (mm), shape (rows * cols,), same order as `centers()`.
    fn diameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let b = &self.inner;
        let data = b.indices().map(|(r, c)| b.diameter(r, c)).collect();
        nd(py, &[b.len()], data)
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        let b = &self.inner;
        format!(
            "Board(rows={}, cols={}, pitch_mm={:?}, circle_diameter_mm={:?}, marker_diameter_mm={:?}, markers={:?}, dark_circles={}, kind='{}')",
            b.rows,
            b.cols,
            b.pitch_mm,
            b.circle_diameter_mm,
            b.marker_diameter_mm,
            self.markers(),
            if b.dark_circles { "True" } else { "False" },
            kind_name(b.kind)
        )
    }
}
