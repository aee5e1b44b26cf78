//! `stripecal.Truth` (truth.json, written by simulators).

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use stripecal::io::{truth_from_json, truth_to_json, write_truth};
use stripecal::model::{Sphere, Truth};

use crate::args::{bind_as, Params};
use crate::camera::PyCamera;
use crate::convert::{fixed, iso_to_py, map_to_py, nd, opt_dict_to_map, py_to_iso};
use crate::errors::{invalid_input, ResultExt};
use crate::pool::Detach;
use crate::results::{plane_from_py, plane_to_py};
use crate::robot::PyRobot;

fn sphere_from_py(py: Python<'_>, d: Option<&Bound<'_, PyDict>>) -> PyResult<Option<Sphere>> {
    let Some(d) = d else { return Ok(None) };
    let (Some(c), Some(dia)) = (d.get_item("center_mm")?, d.get_item("diameter_mm")?) else {
        return Err(invalid_input(
            py,
            "sphere must be a dict {\"center_mm\": (3,), \"diameter_mm\": float}",
        ));
    };
    if d.len() != 2 {
        return Err(invalid_input(
            py,
            "sphere must have exactly the keys center_mm and diameter_mm",
        ));
    }
    Ok(Some(Sphere {
        center_mm: Vector3::from(fixed::<3>(&c, "sphere center_mm")?),
        diameter_mm: dia.extract()?,
    }))
}

fn sphere_to_py<'py>(py: Python<'py>, s: &Sphere) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item(
        "center_mm",
        nd(py, &[3], vec![s.center_mm.x, s.center_mm.y, s.center_mm.z])?,
    )?;
    d.set_item("diameter_mm", s.diameter_mm)?;
    Ok(d)
}

/// Ground truth written by simulators (truth.json): the true camera, laser plane,
/// `T_hand_cam`, `T_base_board`, robot, and for scans the sphere.
#[pyclass(name = "Truth", module = "stripecal", frozen, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyTruth {
    pub inner: Truth,
}

/// `Truth`'s parameters (see [`bind_as`]).
const TRUTH: Params = Params {
    name: "Truth",
    positional: &[
        "camera",
        "laser_plane",
        "hand_cam",
        "base_board",
        "robot",
        "sphere",
        "working_range_mm",
        "extra",
    ],
    required: 4,
    keyword: &[],
};

/// `Truth`'s arguments, with their defaults.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct TruthArgs<'py> {
    camera: Bound<'py, PyCamera>,
    laser_plane: Bound<'py, PyAny>,
    hand_cam: Bound<'py, PyAny>,
    base_board: Bound<'py, PyAny>,
    #[pyo3(default)]
    robot: Option<Bound<'py, PyRobot>>,
    #[pyo3(default)]
    sphere: Option<Bound<'py, PyDict>>,
    #[pyo3(default)]
    working_range_mm: Option<(f64, f64)>,
    #[pyo3(default)]
    extra: Option<Bound<'py, PyDict>>,
}

#[pymethods]
impl PyTruth {
    #[new]
    #[pyo3(signature = (*args, **kwargs), text_signature = "(camera, laser_plane, hand_cam, base_board, robot=None, sphere=None, working_range_mm=None, extra=None)")]
    fn new(
        py: Python<'_>,
        args: &Bound<'_, PyTuple>,
        kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let TruthArgs {
            camera,
            laser_plane,
            hand_cam,
            base_board,
            robot,
            sphere,
            working_range_mm,
            extra,
        } = bind_as(&TRUTH, args, kwargs)?;
        let (camera, laser_plane, hand_cam, base_board) =
            (&camera, &laser_plane, &hand_cam, &base_board);
        let (robot, sphere, extra) = (robot.as_ref(), sphere.as_ref(), extra.as_ref());
        Ok(PyTruth {
            inner: Truth {
                camera: camera.get().inner.clone(),
                laser_plane: plane_from_py(py, laser_plane)?,
                hand_cam: py_to_iso(hand_cam, "hand_cam")?,
                base_board: py_to_iso(base_board, "base_board")?,
                robot: robot.map(|r| r.get().inner.clone()),
                sphere: sphere_from_py(py, sphere)?,
                working_range_mm: working_range_mm.map(|(a, b)| [a, b]),
                extra: opt_dict_to_map(extra, "extra")?,
            },
        })
    }

    /// The true camera.
    #[getter]
    fn camera(&self) -> PyCamera {
        PyCamera::new_py(self.inner.camera.clone())
    }

    /// `(normal (3,), d_mm)` in the camera frame.
    #[getter]
    fn laser_plane<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        plane_to_py(py, &self.inner.laser_plane)
    }

    /// True `T_hand_cam`, shape (4, 4).
    #[getter]
    fn hand_cam<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        iso_to_py(py, &self.inner.hand_cam)
    }

    /// True `T_base_board`, shape (4, 4).
    #[getter]
    fn base_board<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        iso_to_py(py, &self.inner.base_board)
    }

    /// The robot's TRUE DH table, or None.
    #[getter]
    fn robot(&self) -> Option<PyRobot> {
        self.inner.robot.clone().map(PyRobot::new_py)
    }

    /// `{"center_mm": (3,), "diameter_mm": float}` for scans, else None.
    #[getter]
    fn sphere<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.inner
            .sphere
            .as_ref()
            .map(|s| sphere_to_py(py, s))
            .transpose()
    }

    /// `(near, far)` stand-offs in mm the rig is meant for, or None.
    #[getter]
    fn working_range_mm(&self) -> Option<(f64, f64)> {
        self.inner.working_range_mm.map(|[a, b]| (a, b))
    }

    /// Simulator-specific keys (JSON-like dict).
    #[getter]
    fn extra<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        map_to_py(py, &self.inner.extra)
    }

    /// Writes truth.json (atomically).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let t = &self.inner;
        py.detach_pool(|| write_truth(&path, t)).py_err(py)
    }

    /// The truth.json text.
    fn to_json(&self) -> String {
        truth_to_json(&self.inner)
    }

    /// Truth from truth.json text (errors name `<string>` as the file).
    #[staticmethod]
    fn from_json(py: Python<'_>, text: &str) -> PyResult<Self> {
        truth_from_json(Path::new("<string>"), text)
            .py_err(py)
            .map(|inner| PyTruth { inner })
    }

    fn __repr__(&self) -> String {
        let t = &self.inner;
        format!(
            "Truth(camera={}x{} fu={:.3} fv={:.3}, laser_plane d_mm={:.3}, sphere={})",
            t.camera.width,
            t.camera.height,
            t.camera.fu,
            t.camera.fv,
            t.laser_plane.d,
            t.sphere
                .map(|s| format!("diameter_mm={:.4}", s.diameter_mm))
                .unwrap_or_else(|| "None".into())
        )
    }
}
