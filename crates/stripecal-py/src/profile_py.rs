//! A calibrated line profiler's files: `stripecal.Profile` (`read_profile`),
//! `stripecal.ProfileDataset` (`load_profile_dataset`), `stripecal.ProfilerCalibration`
//! (`read_profiler_calibration`, `write_profiler_calibration`).

use crate::pool::Detach;
use std::path::{Path, PathBuf};

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

use crate::args::{bind_as, Params};
use stripecal::io::{
    diameter_check_to_json, mirror_to_json, profiler_adjustment_to_json,
    profiler_calibration_extra_keys, profiler_calibration_from_json, profiler_calibration_to_json,
    profiler_loo_to_json, profiler_records_split, profiler_view_to_json, read_profile,
    read_profiler_calibration as core_read_profiler_calibration, robot_calibration_to_json,
    write_profiler_calibration as core_write_profiler_calibration,
};
use stripecal::model::{
    Profile, ProfileDataset, ProfilerCalibration, ProfilerQuality, RobotReading,
};

use crate::convert::{fixed, iso_to_py, json_to_py, map_to_py, nd, opt_dict_to_map, py_to_iso};
use crate::errors::{invalid_input, ResultExt};
use crate::results::{checks_to_py, covariance_to_py};
use crate::rig::{joints_array, poses_array};
use crate::robot::PyRobot;

/// One profile as read: points `(x, z)` in mm in the profiler frame, gaps skipped.
#[pyclass(name = "Profile", module = "stripecal", frozen)]
#[derive(Debug, Clone)]
pub struct PyProfile {
    pub inner: Profile,
}

#[pymethods]
impl PyProfile {
    /// The points, shape (N, 2): `x_mm, z_mm` in the profiler frame (y = 0).
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = &self.inner.points;
        nd(py, &[p.len(), 2], p.iter().flatten().copied().collect())
    }

    /// Points reported as gaps (empty or non-finite z, or the rig's `invalid_z`).
    #[getter]
    fn gaps(&self) -> usize {
        self.inner.gaps
    }

    fn __len__(&self) -> usize {
        self.inner.points.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Profile(points={}, gaps={})",
            self.inner.points.len(),
            self.inner.gaps
        )
    }
}

/// Reads a profile file (header naming `x_mm` and `z_mm`, one point per line); gaps
/// (empty, `nan`, `inf` z, or `invalid_z`) are skipped and counted. Errors name the
/// file, line and column.
#[pyfunction(name = "read_profile")]
#[pyo3(signature = (path, invalid_z = None))]
pub fn read_profile_py(
    py: Python<'_>,
    path: PathBuf,
    invalid_z: Option<f64>,
) -> PyResult<PyProfile> {
    let inner = py
        .detach_pool(|| read_profile(&path, invalid_z))
        .py_err(py)?;
    Ok(PyProfile { inner })
}

/// A profile dataset folder (rig.json of a profiler + views.csv with a `profile`
/// column), from `load_profile_dataset`. Profile paths are joined with the folder.
#[pyclass(name = "ProfileDataset", module = "stripecal", frozen)]
#[derive(Debug, Clone)]
pub struct PyProfileDataset {
    pub inner: ProfileDataset,
}

impl PyProfileDataset {
    fn readings(&self) -> Vec<&RobotReading> {
        self.inner.views.iter().map(|v| &v.reading).collect()
    }
}

#[pymethods]
impl PyProfileDataset {
    /// The dataset folder as given.
    #[getter]
    fn root(&self) -> String {
        self.inner.root.display().to_string()
    }

    /// Profile file paths, one per view.
    #[getter]
    fn profiles(&self) -> Vec<String> {
        let d = &self.inner;
        d.views
            .iter()
            .map(|v| d.profile_path(&v.profile).display().to_string())
            .collect()
    }

    /// Line numbers of the views in views.csv (the header is line 1).
    #[getter]
    fn lines(&self) -> Vec<usize> {
        self.inner.views.iter().map(|v| v.line).collect()
    }

    /// Joint readings `(N, J)` in degrees, or None when the views carry flange poses.
    #[getter]
    fn joints<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        joints_array(py, &self.readings())
    }

    /// Reported flange poses `T_base_hand`, `(N, 4, 4)` mm, or None for joint readings.
    #[getter]
    fn flange_poses<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        poses_array(py, &self.readings())
    }

    /// The nominal DH table (rig.json `robot`), or None.
    #[getter]
    fn robot(&self) -> Option<PyRobot> {
        self.inner.rig.robot.clone().map(PyRobot::new_py)
    }

    /// The vendor's "no point" sentinel (rig.json `sensor.invalid_z`), or None.
    #[getter]
    fn invalid_z(&self) -> Option<f64> {
        self.inner.rig.invalid_z
    }

    /// The reference sphere's declared diameter, mm; None: the calibration estimates it.
    #[getter]
    fn sphere_diameter_mm(&self) -> Option<f64> {
        self.inner.rig.diameter_mm
    }

    /// Reads view `i`'s profile (with the rig's `invalid_z`).
    fn profile(&self, py: Python<'_>, i: usize) -> PyResult<PyProfile> {
        let d = &self.inner;
        let Some(v) = d.views.get(i) else {
            return Err(invalid_input(
                py,
                format!(
                    "view {i} out of range: the dataset has {} views",
                    d.views.len()
                ),
            ));
        };
        let path = d.profile_path(&v.profile);
        let inner = py
            .detach_pool(|| read_profile(&path, d.rig.invalid_z))
            .py_err(py)?;
        Ok(PyProfile { inner })
    }

    fn __len__(&self) -> usize {
        self.inner.views.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "ProfileDataset(root={}, views={})",
            crate::convert::quote(&self.inner.root.display().to_string()),
            self.inner.views.len()
        )
    }
}

/// Loads a profile dataset folder (a profiler's rig.json + views.csv with a `profile`
/// column, checking that every profile file exists). Never reads truth.json.
#[pyfunction]
pub fn load_profile_dataset(py: Python<'_>, path: PathBuf) -> PyResult<PyProfileDataset> {
    let inner = py.detach_pool(|| ProfileDataset::load(&path)).py_err(py)?;
    Ok(PyProfileDataset { inner })
}

/// A profiler's calibration (calibration.json with `"sensor": {"kind": "profiler"}`):
/// `T_hand_sensor`, the reference sphere in the base frame, the robot used, quality
/// figures and uncertainties.
#[pyclass(name = "ProfilerCalibration", module = "stripecal", frozen, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyProfilerCalibration {
    pub inner: ProfilerCalibration,
}

/// `ProfilerCalibration`'s parameters (see [`bind_as`]).
const PROFILERCALIBRATION: Params = Params {
    name: "ProfilerCalibration",
    positional: &[
        "hand_sensor",
        "sphere_center_mm",
        "sphere_diameter_mm",
        "robot",
        "profile_rms_mm",
        "views_used",
        "uncertainty",
        "extra",
    ],
    required: 3,
    keyword: &[],
};

/// `ProfilerCalibration`'s arguments, with their defaults.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct ProfilerCalibrationArgs<'py> {
    hand_sensor: Bound<'py, PyAny>,
    sphere_center_mm: Bound<'py, PyAny>,
    sphere_diameter_mm: f64,
    #[pyo3(default)]
    robot: Option<Bound<'py, PyRobot>>,
    #[pyo3(default)]
    profile_rms_mm: f64,
    #[pyo3(default)]
    views_used: usize,
    #[pyo3(default)]
    uncertainty: Option<Bound<'py, PyDict>>,
    #[pyo3(default)]
    extra: Option<Bound<'py, PyDict>>,
}

#[pymethods]
impl PyProfilerCalibration {
    #[new]
    #[pyo3(signature = (*args, **kwargs), text_signature = "(hand_sensor, sphere_center_mm, sphere_diameter_mm, robot=None, profile_rms_mm=0.0, views_used=0, uncertainty=None, extra=None)")]
    fn new(
        py: Python<'_>,
        args: &Bound<'_, PyTuple>,
        kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let ProfilerCalibrationArgs {
            hand_sensor,
            sphere_center_mm,
            sphere_diameter_mm,
            robot,
            profile_rms_mm,
            views_used,
            uncertainty,
            extra,
        } = bind_as(&PROFILERCALIBRATION, args, kwargs)?;
        let (hand_sensor, sphere_center_mm) = (&hand_sensor, &sphere_center_mm);
        let (robot, uncertainty, extra) = (robot.as_ref(), uncertainty.as_ref(), extra.as_ref());
        if !(sphere_diameter_mm.is_finite() && sphere_diameter_mm > 0.0) {
            return Err(invalid_input(
                py,
                format!("sphere_diameter_mm must be finite and positive, got {sphere_diameter_mm}"),
            ));
        }
        let robot = robot.map(|r| r.get().inner.clone());
        // the records `extra` holds (views, mirror, ...) become the calibration's records
        let (records, extra) =
            profiler_records_split(&opt_dict_to_map(extra, "extra")?, robot.as_ref());
        Ok(PyProfilerCalibration {
            inner: ProfilerCalibration {
                hand_sensor: py_to_iso(hand_sensor, "hand_sensor")?,
                robot,
                sphere_center_mm: fixed::<3>(sphere_center_mm, "sphere_center_mm")?.into(),
                sphere_diameter_mm,
                quality: ProfilerQuality {
                    profile_rms_mm,
                    views_used,
                    ..Default::default()
                },
                uncertainty: opt_dict_to_map(uncertainty, "uncertainty")?,
                covariance: None,
                records,
                extra,
            },
        })
    }

    /// `T_hand_sensor`, shape (4, 4), mm (calibration.json `hand_cam`).
    #[getter]
    fn hand_sensor<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        iso_to_py(py, &self.inner.hand_sensor)
    }

    /// The reference sphere's centre in the base frame, shape (3,), mm.
    #[getter]
    fn sphere_center_mm<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(
            py,
            &[3],
            self.inner.sphere_center_mm.iter().copied().collect(),
        )
    }

    /// The reference sphere's diameter, mm (declared, or estimated).
    #[getter]
    fn sphere_diameter_mm(&self) -> f64 {
        self.inner.sphere_diameter_mm
    }

    /// The DH table used (refined if the robot was calibrated), or None (flange poses).
    #[getter]
    fn robot(&self) -> Option<PyRobot> {
        self.inner.robot.clone().map(PyRobot::new_py)
    }

    /// `{"profile_rms_mm": float, "views_used": int, "accepted_poor": bool, "checks":
    /// [...]}`.
    #[getter]
    fn quality<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let q = &self.inner.quality;
        let d = PyDict::new(py);
        d.set_item("profile_rms_mm", q.profile_rms_mm)?;
        d.set_item("views_used", q.views_used)?;
        d.set_item("accepted_poor", q.accepted_poor)?;
        d.set_item("checks", checks_to_py(py, &q.checks)?)?;
        Ok(d)
    }

    /// One-sigma values, mirroring the estimated values' keys (`hand_cam`, `sphere`,
    /// `robot`; JSON-like dict).
    #[getter]
    fn uncertainty<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        map_to_py(py, &self.inner.uncertainty)
    }

    /// `(names, matrix)`: the covariance of the estimated numbers, or None.
    #[getter]
    fn covariance<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<(Vec<String>, Bound<'py, PyAny>)>> {
        covariance_to_py(py, self.inner.covariance.as_ref())
    }

    /// calibration.json's top-level keys after the fixed ones (JSON-like dict): the
    /// records (`views`, `adjustment`, `mirror`, ...; read them through their getters)
    /// and any key this version does not know.
    #[getter]
    fn extra<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        map_to_py(py, &profiler_calibration_extra_keys(&self.inner))
    }

    /// rig.json's sphere diameter was null, so the adjustment estimated it
    /// (calibration.json's `sphere_diameter_estimated`); None when the file has none.
    #[getter]
    fn sphere_diameter_estimated(&self) -> Option<bool> {
        self.inner.records.sphere_diameter_estimated
    }

    /// The adjustment's figures (calibration.json's `adjustment`): `sigma_mm`,
    /// `points_used`, `iterations`, `view_variance_factor`; None when the file has none.
    #[getter]
    fn adjustment<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let r = &self.inner.records;
        r.adjustment
            .as_ref()
            .map(|a| json_to_py(py, &profiler_adjustment_to_json(a)))
            .transpose()
    }

    /// Every view, used or not (calibration.json's `views`): `view`, `line`, `profile`,
    /// `used`, `points`, `gaps`, `arc_points`, `sphere_points`, `rejected`, `rms_mm`,
    /// `side`, `centre_in_sensor_mm`, `note` (empty when the file has none).
    #[getter]
    fn views<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let list = PyList::empty(py);
        for v in self.inner.records.views.as_deref().unwrap_or_default() {
            list.append(json_to_py(py, &profiler_view_to_json(v))?)?;
        }
        Ok(list.into_any())
    }

    /// The mirror test (calibration.json's `mirror`): `ssr_chosen_mm2`,
    /// `ssr_mirror_mm2`, `delta_chi2`, `passed`, `centre_spread_mm` (`x`, `y`, `z`,
    /// `across_plane`); None when the file has none.
    #[getter]
    fn mirror<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let r = &self.inner.records;
        r.mirror
            .as_ref()
            .map(|m| json_to_py(py, &mirror_to_json(m)))
            .transpose()
    }

    /// The declared diameter against the profiles' (calibration.json's
    /// `diameter_check`): `declared_mm`, `estimate_mm`, `sigma_mm`, `disagrees`; None
    /// when not run.
    #[getter]
    fn diameter_check<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let r = &self.inner.records;
        r.diameter_check
            .as_ref()
            .map(|d| json_to_py(py, &diameter_check_to_json(d)))
            .transpose()
    }

    /// The leave-one-view-out figures (calibration.json's `leave_one_out`):
    /// `median_rms_mm` and `views` (per view `view`, `points`, `rms_mm`, `disagrees`);
    /// None when not computed.
    #[getter]
    fn leave_one_out<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let r = &self.inner.records;
        r.leave_one_out
            .as_ref()
            .map(|l| json_to_py(py, &profiler_loo_to_json(l)))
            .transpose()
    }

    /// What the robot calibration did (calibration.json's `robot_calibration`): `mode`,
    /// `estimated` (`name`, `correction`, `sigma`), `fixed` (`name`, `reason`); None
    /// without one.
    #[getter]
    fn robot_calibration<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let r = &self.inner.records;
        r.robot_calibration
            .as_ref()
            .map(|rc| json_to_py(py, &robot_calibration_to_json(rc)))
            .transpose()
    }

    /// What the user should know about the calibration (calibration.json `warnings`).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.records.warnings.clone()
    }

    /// Writes calibration.json (atomically).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let c = &self.inner;
        py.detach_pool(|| core_write_profiler_calibration(&path, c))
            .py_err(py)
    }

    /// The calibration.json text.
    fn to_json(&self) -> String {
        profiler_calibration_to_json(&self.inner)
    }

    /// A profiler calibration from calibration.json text (errors name `<string>` as the
    /// file).
    #[staticmethod]
    fn from_json(py: Python<'_>, text: &str) -> PyResult<Self> {
        profiler_calibration_from_json(Path::new("<string>"), text)
            .py_err(py)
            .map(|inner| PyProfilerCalibration { inner })
    }

    fn __repr__(&self) -> String {
        let c = &self.inner;
        let s = &c.sphere_center_mm;
        format!(
            "ProfilerCalibration(sphere_center_mm=[{:.3}, {:.3}, {:.3}], sphere_diameter_mm={:.4}, profile_rms_mm={:.4}, views_used={})",
            s.x, s.y, s.z, c.sphere_diameter_mm, c.quality.profile_rms_mm, c.quality.views_used
        )
    }
}

/// Reads a profiler's calibration.json (a camera's is refused, saying so).
#[pyfunction]
pub fn read_profiler_calibration(py: Python<'_>, path: PathBuf) -> PyResult<PyProfilerCalibration> {
    let inner = py
        .detach_pool(|| core_read_profiler_calibration(&path))
        .py_err(py)?;
    Ok(PyProfilerCalibration { inner })
}

/// Writes a profiler's calibration.json (atomically).
#[pyfunction]
pub fn write_profiler_calibration(
    py: Python<'_>,
    path: PathBuf,
    calibration: &Bound<'_, PyProfilerCalibration>,
) -> PyResult<()> {
    let c = &calibration.get().inner;
    py.detach_pool(|| core_write_profiler_calibration(&path, c))
        .py_err(py)
}
