//! `stripecal.Calibration` (calibration.json).

use crate::pool::Detach;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use stripecal::io::{
    board_scale_to_json, calibration_extra_keys, calibration_records_from, leave_one_out_to_json,
    robot_calibration_to_json, robot_pose_noise_to_json, summary_to_json, view_record_to_json,
};
use stripecal::io::{
    calibration_from_json, calibration_leave_one_out, calibration_to_json, take_bench_flag,
    write_calibration,
};
use stripecal::model::geometry::Plane;
use stripecal::model::{Calibration, Mount, NamedCovariance, Quality, QualityCheck};

use crate::args::{bind_as, Params};
use crate::camera::PyCamera;
use crate::convert::{
    fixed, iso_to_py, json_to_py, map_to_py, nd, opt_dict_to_map, py_to_iso, rows_of,
};
use crate::errors::{invalid_input, ResultExt};
use crate::robot::PyRobot;
use stripecal::pipeline::held_out_laser_board;

/// `(normal, d_mm)` -> a plane (normalised, `d >= 0`).
pub(crate) fn plane_from_py(py: Python<'_>, obj: &Bound<'_, PyAny>) -> PyResult<Plane> {
    let t = obj
        .cast::<PyTuple>()
        .ok()
        .filter(|t| t.len() == 2)
        .ok_or_else(|| {
            PyTypeError::new_err(
                "laser_plane must be a tuple (normal (3,), d_mm) with n . p = d_mm",
            )
        })?;
    let n = fixed::<3>(&t.get_item(0)?, "laser_plane normal")?;
    let d: f64 = t.get_item(1)?.extract()?;
    Plane::new(Vector3::from(n), d).py_err(py)
}

pub(crate) fn plane_to_py<'py>(py: Python<'py>, p: &Plane) -> PyResult<Bound<'py, PyTuple>> {
    let n = nd(py, &[3], vec![p.normal.x, p.normal.y, p.normal.z])?;
    PyTuple::new(py, [n, p.d.into_pyobject(py)?.into_any()])
}

fn quality_from_py(py: Python<'_>, d: Option<&Bound<'_, PyDict>>) -> PyResult<Quality> {
    let mut q = Quality::default();
    let Some(d) = d else { return Ok(q) };
    for (k, v) in d.iter() {
        let key: String = k.extract()?;
        match key.as_str() {
            "circle_rms_px" | "target_rms_px" => q.circle_rms_px = v.extract()?,
            "stripe_rms_px" => q.stripe_rms_px = v.extract()?,
            "views_used" => q.views_used = v.extract()?,
            "accepted_poor" => q.accepted_poor = v.extract()?,
            "checks" => {
                q.checks = v
                    .try_iter()?
                    .map(|c| check_from_py(py, &c?))
                    .collect::<PyResult<_>>()?
            }
            other => {
                return Err(invalid_input(
                    py,
                    format!(
                        "quality: unknown key {other:?} (expected target_rms_px (or circle_rms_px), stripe_rms_px, views_used, accepted_poor, checks)"
                    ),
                ))
            }
        }
    }
    Ok(q)
}

fn quality_to_py<'py>(py: Python<'py>, q: &Quality) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("circle_rms_px", q.circle_rms_px)?;
    d.set_item("target_rms_px", q.circle_rms_px)?;
    d.set_item("stripe_rms_px", q.stripe_rms_px)?;
    d.set_item("views_used", q.views_used)?;
    d.set_item("accepted_poor", q.accepted_poor)?;
    d.set_item("checks", checks_to_py(py, &q.checks)?)?;
    Ok(d)
}

/// One quality check from a dict `{name, passed, message, views}`.
fn check_from_py(py: Python<'_>, c: &Bound<'_, PyAny>) -> PyResult<QualityCheck> {
    let d = c
        .cast::<PyDict>()
        .map_err(|_| invalid_input(py, "quality.checks: each check must be a dict"))?;
    let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
        d.get_item(k)?
            .ok_or_else(|| invalid_input(py, format!("quality.checks: a check lacks {k:?}")))
    };
    Ok(QualityCheck {
        name: get("name")?.extract()?,
        passed: get("passed")?.extract()?,
        message: get("message")?.extract()?,
        views: match d.get_item("views")? {
            Some(v) => v.extract()?,
            None => Vec::new(),
        },
    })
}

/// Quality checks as a list of dicts `{name, passed, message, views}`.
pub fn checks_to_py<'py>(py: Python<'py>, checks: &[QualityCheck]) -> PyResult<Bound<'py, PyList>> {
    let out = PyList::empty(py);
    for c in checks {
        let d = PyDict::new(py);
        d.set_item("name", &c.name)?;
        d.set_item("passed", c.passed)?;
        d.set_item("message", &c.message)?;
        d.set_item("views", c.views.clone())?;
        out.append(d)?;
    }
    Ok(out)
}

/// `(names, matrix (n, n))` of a covariance, or None.
pub fn covariance_to_py<'py>(
    py: Python<'py>,
    c: Option<&NamedCovariance>,
) -> PyResult<Option<(Vec<String>, Bound<'py, PyAny>)>> {
    let Some(c) = c else {
        return Ok(None);
    };
    let n = c.parameters.len();
    let data: Vec<f64> = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| c.matrix[(i, j)])
        .collect();
    Ok(Some((c.parameters.clone(), nd(py, &[n, n], data)?)))
}

/// A calibration result (calibration.json): camera, laser plane `n . p = d_mm` in the
/// camera frame, `T_hand_cam` (X), `T_base_board` (Z), the robot used, quality figures
/// and one-sigma uncertainties.
#[pyclass(name = "Calibration", module = "stripecal", frozen, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyCalibration {
    pub inner: Calibration,
    /// Per-circle residuals `(view, row, col, u, v, du_px, dv_px)` of the calibration run
    /// (empty for a calibration loaded from a file).
    pub circle_residuals: Vec<[f64; 7]>,
    /// Per-stripe-point residuals `(view, u, v, distance_px)`.
    pub stripe_residuals: Vec<[f64; 4]>,
}

impl PyCalibration {
    /// A calibration without run residuals (loaded or constructed).
    pub fn from_inner(inner: Calibration) -> Self {
        PyCalibration {
            inner,
            circle_residuals: Vec::new(),
            stripe_residuals: Vec::new(),
        }
    }
}

/// `Calibration`'s parameters (see [`bind_as`]).
const CALIBRATION: Params = Params {
    name: "Calibration",
    positional: &[
        "camera",
        "laser_plane",
        "hand_cam",
        "base_board",
        "robot",
        "quality",
        "uncertainty",
        "extra",
    ],
    required: 4,
    keyword: &[],
};

/// `Calibration`'s arguments, with their defaults.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct CalibrationArgs<'py> {
    camera: Bound<'py, PyCamera>,
    laser_plane: Bound<'py, PyAny>,
    hand_cam: Bound<'py, PyAny>,
    base_board: Bound<'py, PyAny>,
    #[pyo3(default)]
    robot: Option<Bound<'py, PyRobot>>,
    #[pyo3(default)]
    quality: Option<Bound<'py, PyDict>>,
    #[pyo3(default)]
    uncertainty: Option<Bound<'py, PyDict>>,
    #[pyo3(default)]
    extra: Option<Bound<'py, PyDict>>,
}

#[pymethods]
impl PyCalibration {
    #[new]
    #[pyo3(signature = (*args, **kwargs), text_signature = "(camera, laser_plane, hand_cam, base_board, robot=None, quality=None, uncertainty=None, extra=None)")]
    fn new(
        py: Python<'_>,
        args: &Bound<'_, PyTuple>,
        kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let CalibrationArgs {
            camera,
            laser_plane,
            hand_cam,
            base_board,
            robot,
            quality,
            uncertainty,
            extra,
        } = bind_as(&CALIBRATION, args, kwargs)?;
        let (camera, laser_plane, hand_cam, base_board) =
            (&camera, &laser_plane, &hand_cam, &base_board);
        let (robot, quality, uncertainty, extra) = (
            robot.as_ref(),
            quality.as_ref(),
            uncertainty.as_ref(),
            extra.as_ref(),
        );
        let robot = robot.map(|r| r.get().inner.clone());
        // the records among `extra`'s keys, as a file's are read
        let (records, mut extra) =
            calibration_records_from(opt_dict_to_map(extra, "extra")?, robot.as_ref())
                .py_err(py)?;
        // `extra={"bench": True}` (the file's flag) is the bench mount
        let bench = take_bench_flag(&mut extra);
        Ok(PyCalibration::from_inner(Calibration {
            camera: camera.get().inner.clone(),
            laser_plane: if laser_plane.is_none() {
                None
            } else {
                Some(plane_from_py(py, laser_plane)?)
            },
            mount: if bench { Mount::Bench } else { Mount::Robot },
            hand_cam: py_to_iso(hand_cam, "hand_cam")?,
            base_board: py_to_iso(base_board, "base_board")?,
            robot,
            quality: quality_from_py(py, quality)?,
            uncertainty: opt_dict_to_map(uncertainty, "uncertainty")?,
            covariance: None,
            records,
            extra,
        }))
    }

    /// The calibrated camera.
    #[getter]
    fn camera(&self) -> PyCamera {
        PyCamera::new_py(self.inner.camera.clone())
    }

    /// `(normal (3,), d_mm)`: the laser plane `normal . p = d_mm` in the camera frame;
    /// None when it was not estimated (views without laser images).
    #[getter]
    fn laser_plane<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyTuple>>> {
        self.inner
            .laser_plane
            .as_ref()
            .map(|p| plane_to_py(py, p))
            .transpose()
    }

    /// `(names, matrix)`: the covariance of the estimated numbers (calibration.json
    /// `covariance`; names like `camera.fu`, `laser_plane.normal[0]`), or None.
    #[getter]
    fn covariance<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<(Vec<String>, Bound<'py, PyAny>)>> {
        covariance_to_py(py, self.inner.covariance.as_ref())
    }

    /// `T_hand_cam` (the paper's X), shape (4, 4), mm (the identity in a bench
    /// calibration, whose file has none).
    #[getter]
    fn hand_cam<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        iso_to_py(py, &self.inner.hand_cam)
    }

    /// A bench calibration (from a dataset without poses): camera and laser plane only;
    /// its file has no `hand_cam`, `base_board` or `robot`.
    #[getter]
    fn is_bench(&self) -> bool {
        self.inner.is_bench()
    }

    /// `T_base_board` (the paper's Z), shape (4, 4), mm.
    #[getter]
    fn base_board<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        iso_to_py(py, &self.inner.base_board)
    }

    /// The DH table used (refined if the robot was calibrated), or None.
    #[getter]
    fn robot(&self) -> Option<PyRobot> {
        self.inner.robot.clone().map(PyRobot::new_py)
    }

    /// `{"target_rms_px": float (circle centres or chessboard corners; also as the
    /// contract's "circle_rms_px"), "stripe_rms_px": float, "views_used": int,
    /// "accepted_poor": bool, "checks": [...]}`.
    #[getter]
    fn quality<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        quality_to_py(py, &self.inner.quality)
    }

    /// One-sigma values, mirroring the estimated values' keys (JSON-like dict).
    #[getter]
    fn uncertainty<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        map_to_py(py, &self.inner.uncertainty)
    }

    /// Other top-level keys of calibration.json (JSON-like dict), as its file holds
    /// them: the records (`method`, `views`, `warnings`, `leave_one_out`, ...), `bench`
    /// and any key this version does not know.
    #[getter]
    fn extra<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        map_to_py(py, &calibration_extra_keys(&self.inner))
    }

    /// How the sensor was held: `"robot"` or `"bench"`.
    #[getter]
    fn mount(&self) -> &'static str {
        match self.inner.mount {
            Mount::Robot => "robot",
            Mount::Bench => "bench",
        }
    }

    /// What the user should know about the calibration (calibration.json `warnings`).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.records.warnings.clone()
    }

    /// How the calibration was made (calibration.json's `method`, `centre_model`,
    /// `base_board_orientation` (when set), `stripe_rms_mm`, `residual_sigma_px`,
    /// `stripe_off_plane`); None when the file has none.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner
            .records
            .summary
            .as_ref()
            .map(|s| json_to_py(py, &serde_json::Value::Object(summary_to_json(s))))
            .transpose()
    }

    /// The signal the stripes were found in (`"gray"`, `"red"`, `"green"` or
    /// `"blue"`; calibration.json's `stripe_channel`); None when rig.json's
    /// `stripe.channel` is gray (or the file has none).
    #[getter]
    fn stripe_channel(&self) -> Option<&'static str> {
        self.inner
            .records
            .stripe_channel
            .as_ref()
            .map(|c| c.channel.name())
    }

    /// With `stripe.channel: auto`, each signal's score (summed stripe peak-to-noise
    /// ratio over the laser images looked at) by name (`stripe_channel_scores`); None
    /// otherwise.
    #[getter]
    fn stripe_channel_scores<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(scores) = self
            .inner
            .records
            .stripe_channel
            .as_ref()
            .and_then(|c| c.scores.as_ref())
        else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        for (c, x) in scores {
            d.set_item(c.name(), *x)?;
        }
        Ok(Some(d))
    }

    /// Per-view figures of the calibration (calibration.json's `views`): a list of dicts with
    /// `view`, `used`, `circles`, `stripe_points`, `circle_rms_px`, `stripe_rms_px`,
    /// `outlier` and `note` (empty when the file has none).
    #[getter]
    fn views<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let views = self.inner.records.views.as_deref().unwrap_or_default();
        let list = PyList::empty(py);
        for v in views {
            list.append(json_to_py(py, &view_record_to_json(v))?)?;
        }
        Ok(list.into_any())
    }

    /// The leave-one-view-out figures (calibration.json's `leave_one_out`): `views` (per view:
    /// `view`, `points`, `board_rms_px`, `board_rms_mm`, `stripe_points`,
    /// `stripe_rms_mm`) and their medians; None when not computed.
    #[getter]
    fn leave_one_out<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner
            .records
            .leave_one_out
            .as_ref()
            .map(|l| json_to_py(py, &leave_one_out_to_json(l)))
            .transpose()
    }

    /// The board's scale against the robot (calibration.json's `board_scale`): `scale`, `sigma`,
    /// `declared_mm`, `implied_mm`, `estimated`, `disagrees`, `tolerance`; None when not
    /// computed.
    #[getter]
    fn board_scale<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner
            .records
            .board_scale
            .as_ref()
            .map(|b| json_to_py(py, &board_scale_to_json(b)))
            .transpose()
    }

    /// The robot-pose noise the adjustment estimated (calibration.json's `robot_pose_noise`):
    /// `translation_mm` and `rotation_deg` (one-sigma per component of the flange pose),
    /// `image_factor` (the part of each view's pose error its own image makes, in units
    /// of the image's own pose uncertainty), `at_floor` (`translation`, `rotation`,
    /// `image`), `floor`, per view `views` (`view`, `translation_mm`, `rotation_deg` of
    /// its correction, `test`: above 4 the view disagrees) and `left_out` (views left out
    /// by their test); None when not estimated (the paper's method,
    /// `robot_pose_noise=False`).
    #[getter]
    fn robot_pose_noise<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner
            .records
            .robot_pose_noise
            .as_ref()
            .map(|n| json_to_py(py, &robot_pose_noise_to_json(n)))
            .transpose()
    }

    /// The robot calibration (calibration.json's `robot_calibration`, `--robot`): `mode`,
    /// `estimated` (`name`, `correction`, `sigma`) and `fixed` (`name`, `reason`); None
    /// when the robot was held. The refined DH rows are `robot`.
    #[getter]
    fn robot_calibration<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner
            .records
            .robot_calibration
            .as_ref()
            .map(|r| json_to_py(py, &robot_calibration_to_json(r)))
            .transpose()
    }

    /// Circle residuals of the run that produced this calibration, `(N, 7)`:
    /// `view, row, col, u, v, du_px, dv_px`: the detected centre `(u, v)` and the
    /// residual, predicted minus detected. Empty `(0, 7)` for a calibration read from a
    /// file.
    #[getter]
    fn circle_residuals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let data: Vec<f64> = self.circle_residuals.iter().flatten().copied().collect();
        nd(py, &[self.circle_residuals.len(), 7], data)
    }

    /// Stripe residuals of the run, `(M, 4)`: `view, u, v, distance_px` (signed image
    /// distance of the point from its predicted stripe line). Empty `(0, 4)` for a
    /// calibration read from a file.
    #[getter]
    fn stripe_residuals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let data: Vec<f64> = self.stripe_residuals.iter().flatten().copied().collect();
        nd(py, &[self.stripe_residuals.len(), 4], data)
    }

    /// The held-out laser->board distance (DECISIONS 8) of any stripe points, scored
    /// with this calibration's leave-one-out folds: `points` maps a view (views.csv row,
    /// 0-based) to its `(N, 2)` pixel points `(u, v)`; each point is triangulated with
    /// the laser plane of the calibration without its view, and its distance from the
    /// board plane that calibration predicts for the view is taken. Returns
    /// `{"median_mm", "p95_mm", "points"}` over all points, None when none could be
    /// scored. For a peer's or a plain extractor's points: a figure that leaving hard
    /// points out cannot improve. `InvalidInputError` without a leave-one-out with folds
    /// (a file written before they were kept, `leave_one_out=False`) or for a view it
    /// does not hold.
    fn held_out_laser_board<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyDict>,
    ) -> PyResult<Option<Bound<'py, PyDict>>> {
        let loo = calibration_leave_one_out(&self.inner)
            .py_err(py)?
            .ok_or_else(|| {
                invalid_input(
                    py,
                    "held_out_laser_board: the calibration holds no leave-one-out (calibrate \
                     with leave_one_out=True)"
                        .to_string(),
                )
            })?;
        let mut pts = Vec::with_capacity(points.len());
        for (k, v) in points.iter() {
            let view: usize = k.extract().map_err(|_| {
                invalid_input(
                    py,
                    format!(
                        "held_out_laser_board: points' keys are view numbers (int >= 0), got \
                         {}",
                        crate::convert::type_name(&k)
                    ),
                )
            })?;
            let (rows, _) = rows_of::<2>(&v, &format!("points[{view}]"))?;
            pts.push((view, rows));
        }
        let fig = py.detach(|| held_out_laser_board(&loo, &pts)).py_err(py)?;
        fig.map(|f| {
            let d = PyDict::new(py);
            d.set_item("median_mm", f.median_mm)?;
            d.set_item("p95_mm", f.p95_mm)?;
            d.set_item("points", f.points)?;
            Ok(d)
        })
        .transpose()
    }

    /// Writes calibration.json (atomically).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let c = &self.inner;
        py.detach_pool(|| write_calibration(&path, c)).py_err(py)
    }

    /// The calibration.json text.
    fn to_json(&self) -> String {
        calibration_to_json(&self.inner)
    }

    /// A calibration from calibration.json text (errors name `<string>` as the file).
    #[staticmethod]
    fn from_json(py: Python<'_>, text: &str) -> PyResult<Self> {
        calibration_from_json(Path::new("<string>"), text)
            .py_err(py)
            .map(PyCalibration::from_inner)
    }

    fn __repr__(&self) -> String {
        let c = &self.inner;
        format!(
            "Calibration(camera={}x{} fu={:.3} fv={:.3}, laser_plane {}, circle_rms_px={:.4}, views_used={})",
            c.camera.width,
            c.camera.height,
            c.camera.fu,
            c.camera.fv,
            c.laser_plane
                .map_or("not estimated".to_string(), |p| format!("d_mm={:.3}", p.d)),
            c.quality.circle_rms_px,
            c.quality.views_used
        )
    }
}
