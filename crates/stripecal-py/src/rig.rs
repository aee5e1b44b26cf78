//! `stripecal.Rig`, `stripecal.Dataset`, `stripecal.Scan`.

use crate::pool::Detach;
use std::path::{Path, PathBuf};

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use stripecal::io::{rig_from_json, rig_to_json, write_rig};
use stripecal::model::camera::DistortionModel;
use stripecal::model::{Dataset, Rig, RobotReading, Scan, StripeChannel, StripeDirection};
use stripecal::Iso3;

use crate::board::PyBoard;
use crate::convert::{isos_to_py, nd, positive_u32};
use crate::errors::{map_err_at, ResultExt};
use crate::robot::PyRobot;

/// The rig description (rig.json): camera size, board, robot, hints.
#[pyclass(name = "Rig", module = "stripecal", frozen, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyRig {
    pub inner: Rig,
}

#[pymethods]
impl PyRig {
    #[new]
    #[pyo3(signature = (camera_size, board, robot = None, distortion_model = "radial1", stripe_direction = "auto", stripe_channel = "gray"))]
    fn new(
        py: Python<'_>,
        camera_size: (i64, i64),
        board: &Bound<'_, PyBoard>,
        robot: Option<&Bound<'_, PyRobot>>,
        distortion_model: &str,
        stripe_direction: &str,
        stripe_channel: &str,
    ) -> PyResult<Self> {
        Ok(PyRig {
            inner: Rig {
                width: positive_u32(py, camera_size.0, "camera width")?,
                height: positive_u32(py, camera_size.1, "camera height")?,
                distortion_model: DistortionModel::from_name(distortion_model).py_err(py)?,
                board: board.get().inner.clone(),
                robot: robot.map(|r| r.get().inner.clone()),
                stripe_direction: StripeDirection::from_name(stripe_direction).py_err(py)?,
                stripe_channel: StripeChannel::from_name(stripe_channel).py_err(py)?,
            },
        })
    }

    /// `(width, height)` of the camera images, pixels.
    #[getter]
    fn camera_size(&self) -> (u32, u32) {
        (self.inner.width, self.inner.height)
    }

    /// Image width, pixels.
    #[getter]
    fn width(&self) -> u32 {
        self.inner.width
    }

    /// Image height, pixels.
    #[getter]
    fn height(&self) -> u32 {
        self.inner.height
    }

    /// The calibration target.
    #[getter]
    fn board(&self) -> PyBoard {
        PyBoard::new_py(self.inner.board.clone())
    }

    /// The nominal DH table, or None when the controller reports flange poses.
    #[getter]
    fn robot(&self) -> Option<PyRobot> {
        self.inner.robot.clone().map(PyRobot::new_py)
    }

    /// The distortion model calibration uses unless told otherwise.
    #[getter]
    fn distortion_model(&self) -> &'static str {
        self.inner.distortion_model.name()
    }

    /// `"auto"`, `"rows"` or `"cols"`.
    #[getter]
    fn stripe_direction(&self) -> &'static str {
        self.inner.stripe_direction.name()
    }

    /// The laser's colour in colour laser images (rig.json `stripe.channel`): `"gray"`
    /// (the default: BT.601 gray), `"red"`, `"green"`, `"blue"` (the stripe is found in
    /// that colour's channel) or `"auto"` (decided once per dataset from its laser
    /// images).
    #[getter]
    fn stripe_channel(&self) -> &'static str {
        self.inner.stripe_channel.name()
    }

    /// Writes rig.json (atomically).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let rig = &self.inner;
        py.detach_pool(|| write_rig(&path, rig)).py_err(py)
    }

    /// The rig.json text.
    fn to_json(&self) -> String {
        rig_to_json(&self.inner)
    }

    /// A rig from rig.json text (errors name `<string>` as the file).
    #[staticmethod]
    fn from_json(py: Python<'_>, text: &str) -> PyResult<Self> {
        rig_from_json(Path::new("<string>"), text)
            .py_err(py)
            .map(|inner| PyRig { inner })
    }

    fn __repr__(&self) -> String {
        let r = &self.inner;
        format!(
            "Rig(camera_size=({}, {}), board={}x{}, robot={}, distortion_model='{}', stripe_direction='{}', stripe_channel='{}')",
            r.width,
            r.height,
            r.board.rows,
            r.board.cols,
            r.robot
                .as_ref()
                .map(|r| crate::convert::quote(&r.name))
                .unwrap_or_else(|| "None".into()),
            r.distortion_model.name(),
            r.stripe_direction.name(),
            r.stripe_channel.name()
        )
    }
}

fn path_str(root: &Path, rel: &Path) -> String {
    root.join(rel).display().to_string()
}

/// Joint readings `(N, J)` when every reading is joints, else None.
pub(crate) fn joints_array<'py>(
    py: Python<'py>,
    readings: &[&RobotReading],
) -> PyResult<Option<Bound<'py, PyAny>>> {
    let mut data = Vec::new();
    let mut width = None;
    for r in readings {
        match r {
            RobotReading::Joints(q) => {
                if *width.get_or_insert(q.len()) != q.len() {
                    return Ok(None);
                }
                data.extend_from_slice(q);
            }
            RobotReading::FlangePose(_) | RobotReading::Fixed => return Ok(None),
        }
    }
    match width {
        Some(w) => nd(py, &[readings.len(), w], data).map(Some),
        None => Ok(None),
    }
}

/// Reported flange poses `(N, 4, 4)` when every reading is a pose, else None.
pub(crate) fn poses_array<'py>(
    py: Python<'py>,
    readings: &[&RobotReading],
) -> PyResult<Option<Bound<'py, PyAny>>> {
    let poses: Option<Vec<Iso3>> = readings
        .iter()
        .map(|r| match r {
            RobotReading::FlangePose(t) => Some(*t),
            RobotReading::Joints(_) | RobotReading::Fixed => None,
        })
        .collect();
    match poses {
        Some(p) if !p.is_empty() => isos_to_py(py, &p).map(Some),
        _ => Ok(None),
    }
}

/// `T_base_hand` of every reading, `(N, 4, 4)`.
fn base_hand_array<'py>(
    py: Python<'py>,
    readings: &[&RobotReading],
    lines: &[usize],
    file: &str,
    robot: Option<&stripecal::Robot>,
) -> PyResult<Bound<'py, PyAny>> {
    let ts = readings
        .iter()
        .zip(lines)
        .map(|(r, line)| {
            r.base_hand(robot)
                .map_err(|e| map_err_at(py, e, &format!("{file} line {line}")))
        })
        .collect::<PyResult<Vec<_>>>()?;
    isos_to_py(py, &ts)
}

fn reading_items<'py>(py: Python<'py>, d: &Bound<'py, PyDict>, r: &RobotReading) -> PyResult<()> {
    match r {
        RobotReading::Joints(q) => {
            d.set_item("joints", nd(py, &[q.len()], q.clone())?)?;
            d.set_item("flange_pose", py.None())?;
        }
        RobotReading::FlangePose(t) => {
            d.set_item("joints", py.None())?;
            d.set_item("flange_pose", crate::convert::iso_to_py(py, t)?)?;
        }
        RobotReading::Fixed => {
            d.set_item("joints", py.None())?;
            d.set_item("flange_pose", py.None())?;
        }
    }
    Ok(())
}

/// A calibration dataset folder (rig.json + views.csv + images), from `load_dataset`.
/// Image paths are joined with the folder.
#[pyclass(name = "Dataset", module = "stripecal", frozen)]
#[derive(Debug, Clone)]
pub struct PyDataset {
    pub inner: Dataset,
}

impl PyDataset {
    fn readings(&self) -> Vec<&RobotReading> {
        self.inner.views.iter().map(|v| &v.reading).collect()
    }
}

#[pymethods]
impl PyDataset {
    /// The dataset folder as given.
    #[getter]
    fn root(&self) -> String {
        self.inner.root.display().to_string()
    }

    /// The rig (rig.json).
    #[getter]
    fn rig(&self) -> PyRig {
        PyRig {
            inner: self.inner.rig.clone(),
        }
    }

    /// One dict per view: `line` (int, in views.csv), `board_image` (str),
    /// `laser_image` (str | None), `joints` ((J,) array | None), `flange_pose`
    /// ((4, 4) array | None).
    #[getter]
    fn views<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let root = &self.inner.root;
        let items = self
            .inner
            .views
            .iter()
            .map(|v| {
                let d = PyDict::new(py);
                d.set_item("line", v.line)?;
                d.set_item("board_image", path_str(root, &v.board_image))?;
                d.set_item(
                    "laser_image",
                    v.laser_image.as_ref().map(|l| path_str(root, l)),
                )?;
                reading_items(py, &d, &v.reading)?;
                Ok(d)
            })
            .collect::<PyResult<Vec<_>>>()?;
        PyList::new(py, items)
    }

    /// Board image paths, one per view.
    #[getter]
    fn board_images(&self) -> Vec<String> {
        let root = &self.inner.root;
        self.inner
            .views
            .iter()
            .map(|v| path_str(root, &v.board_image))
            .collect()
    }

    /// Laser image paths (None where the view has none), one per view.
    #[getter]
    fn laser_images(&self) -> Vec<Option<String>> {
        let root = &self.inner.root;
        self.inner
            .views
            .iter()
            .map(|v| v.laser_image.as_ref().map(|l| path_str(root, l)))
            .collect()
    }

    /// Line numbers of the views in views.csv (the header is line 1).
    #[getter]
    fn lines(&self) -> Vec<usize> {
        self.inner.views.iter().map(|v| v.line).collect()
    }

    /// A bench dataset: views.csv has no pose columns (camera and laser plane only;
    /// `joints`, `flange_poses` are None and `base_hand` raises).
    #[getter]
    fn is_bench(&self) -> bool {
        self.inner.is_bench()
    }

    /// Joint readings in degrees, shape (N, J); None when the rig reports flange poses.
    #[getter]
    fn joints<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        joints_array(py, &self.readings())
    }

    /// Reported flange poses `T_base_hand`, shape (N, 4, 4); None for joint readings.
    #[getter]
    fn flange_poses<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        poses_array(py, &self.readings())
    }

    /// `T_base_hand` of every view, shape (N, 4, 4): forward kinematics of the rig's
    /// nominal robot, or the reported flange poses.
    fn base_hand<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let lines: Vec<usize> = self.lines();
        base_hand_array(
            py,
            &self.readings(),
            &lines,
            "views.csv",
            self.inner.rig.robot.as_ref(),
        )
    }

    fn __len__(&self) -> usize {
        self.inner.views.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Dataset(root={}, views={})",
            crate::convert::quote(&self.inner.root.display().to_string()),
            self.inner.views.len()
        )
    }
}

/// A scan folder (scan.csv + images, optional rig.json), from `load_scan`. Image paths
/// are joined with the folder.
#[pyclass(name = "Scan", module = "stripecal", frozen)]
#[derive(Debug, Clone)]
pub struct PyScan {
    pub inner: Scan,
}

impl PyScan {
    fn readings(&self) -> Vec<&RobotReading> {
        self.inner.frames.iter().map(|f| &f.reading).collect()
    }
}

#[pymethods]
impl PyScan {
    /// The scan folder as given.
    #[getter]
    fn root(&self) -> String {
        self.inner.root.display().to_string()
    }

    /// The scan's rig.json, if it has one.
    #[getter]
    fn rig(&self) -> Option<PyRig> {
        self.inner.rig.clone().map(|inner| PyRig { inner })
    }

    /// Stripe image paths, one per frame.
    #[getter]
    fn images(&self) -> Vec<String> {
        let root = &self.inner.root;
        self.inner
            .frames
            .iter()
            .map(|f| path_str(root, &f.image))
            .collect()
    }

    /// Line numbers of the frames in scan.csv.
    #[getter]
    fn lines(&self) -> Vec<usize> {
        self.inner.frames.iter().map(|f| f.line).collect()
    }

    /// Joint readings in degrees, shape (N, J); None when flange poses were reported.
    #[getter]
    fn joints<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        joints_array(py, &self.readings())
    }

    /// Reported flange poses, shape (N, 4, 4); None for joint readings.
    #[getter]
    fn flange_poses<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        poses_array(py, &self.readings())
    }

    /// `T_base_hand` of every frame, shape (N, 4, 4), by forward kinematics of `robot`
    /// (default: the scan's rig.json robot) or from the reported flange poses.
    #[pyo3(signature = (robot = None))]
    fn base_hand<'py>(
        &self,
        py: Python<'py>,
        robot: Option<&Bound<'py, PyRobot>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let robot = match robot {
            Some(r) => Some(r.get().inner.clone()),
            None => self.inner.rig.as_ref().and_then(|r| r.robot.clone()),
        };
        base_hand_array(
            py,
            &self.readings(),
            &self.lines(),
            "scan.csv",
            robot.as_ref(),
        )
    }

    fn __len__(&self) -> usize {
        self.inner.frames.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Scan(root={}, frames={})",
            crate::convert::quote(&self.inner.root.display().to_string()),
            self.inner.frames.len()
        )
    }
}
