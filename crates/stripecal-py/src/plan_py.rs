//! `stripecal.plan_poses`: the calibration's predicted uncertainty for a list of robot
//! poses, before any image is taken (conversion only; the core's
//! `stripecal::pipeline::plan_poses`).

use crate::pool::Detach;
use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::args::{bind_as, Params};

use stripecal::calib::joint::FreeBlocks;
use stripecal::model::{Calibration, Rig};
use stripecal::pipeline::{
    nominal_from_truth, plan_poses as core_plan_poses, read_nominal, read_plan_rig, PlanOptions,
};

use crate::convert::{f64_array, fmt_shape, json_to_py, type_name};
use crate::errors::{invalid_input, ResultExt};
use crate::results::PyCalibration;
use crate::rig::{PyDataset, PyRig};
use crate::truth::PyTruth;

fn rig_of(py: Python<'_>, obj: &Bound<'_, PyAny>) -> PyResult<Rig> {
    if let Ok(r) = obj.cast::<PyRig>() {
        return Ok(r.get().inner.clone());
    }
    if let Ok(d) = obj.cast::<PyDataset>() {
        return Ok(d.get().inner.rig.clone());
    }
    let path: PathBuf = obj.extract().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(format!(
            "rig must be a Rig, a Dataset or a path (rig.json or a dataset folder), got {}",
            type_name(obj)
        ))
    })?;
    py.detach_pool(|| read_plan_rig(&path)).py_err(py)
}

fn nominal_of(py: Python<'_>, obj: &Bound<'_, PyAny>) -> PyResult<Calibration> {
    if let Ok(c) = obj.cast::<PyCalibration>() {
        return Ok(c.get().inner.clone());
    }
    if let Ok(t) = obj.cast::<PyTruth>() {
        return Ok(nominal_from_truth(t.get().inner.clone()));
    }
    let path: PathBuf = obj.extract().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(format!(
            "nominal must be a Calibration, a Truth or a path (calibration.json or \
             truth.json), got {}",
            type_name(obj)
        ))
    })?;
    py.detach_pool(|| read_nominal(&path)).py_err(py)
}

/// `plan_poses`' parameters (see [`bind_as`]).
const PLAN_POSES: Params = Params {
    name: "plan_poses",
    positional: &["rig", "nominal", "joints"],
    required: 3,
    keyword: &[
        "sigma_px",
        "standoff_mm",
        "margin_px",
        "fix",
        "robot",
        "pose_noise",
    ],
};

/// `plan_poses`' arguments, with their defaults.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct PlanArgs<'py> {
    rig: Bound<'py, PyAny>,
    nominal: Bound<'py, PyAny>,
    joints: Bound<'py, PyAny>,
    #[pyo3(default = (0.05, 0.1))]
    sigma_px: (f64, f64),
    #[pyo3(default)]
    standoff_mm: Option<f64>,
    #[pyo3(default = 10.0)]
    margin_px: f64,
    #[pyo3(default)]
    fix: Vec<String>,
    #[pyo3(default = "fixed".into())]
    robot: String,
    #[pyo3(default)]
    pose_noise: Option<(f64, f64)>,
}

/// The predicted one-sigma of every calibration parameter, and of a point on the laser
/// plane at the stand-off, for the robot poses `joints` `(M, dof)` (degrees) of the
/// rig's robot around the nominal calibration (calibration.json or truth.json). Returns
/// a `PosePlan` dict (stripecal.types). The calibration's noise model: the robot-pose
/// noise `pose_noise=(mm, deg)` (default: the nominal calibration's estimate, else
/// rig.json's robot figures, else an exact robot; `pose_noise_mm_deg` in the plan).
/// Raises `InvalidInputError` for fewer than 3
/// usable poses (naming why each other one is not) or a wrong joint count,
/// `DegenerateError` naming the parameters the poses do not determine.
#[pyfunction]
#[pyo3(signature = (*args, **kwargs), text_signature = "(rig, nominal, joints, *, sigma_px=(0.05, 0.1), standoff_mm=None, margin_px=10.0, fix=..., robot=\"fixed\", pose_noise=None)")]
pub fn plan_poses<'py>(
    py: Python<'py>,
    args: &Bound<'py, PyTuple>,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let PlanArgs {
        rig,
        nominal,
        joints,
        sigma_px,
        standoff_mm,
        margin_px,
        fix,
        robot,
        pose_noise,
    } = bind_as(&PLAN_POSES, args, kwargs)?;
    let (rig, nominal, joints, robot) = (&rig, &nominal, &joints, robot.as_str());
    if let Some((t, r)) = pose_noise {
        if !(t.is_finite() && r.is_finite() && t > 0.0 && r > 0.0) {
            return Err(invalid_input(
                py,
                format!("pose_noise must be two positive numbers (mm, deg), got ({t}, {r})"),
            ));
        }
    }
    let robot = stripecal::calib::joint::RobotMode::from_name(robot).py_err(py)?;
    let rig = rig_of(py, rig)?;
    let nominal = nominal_of(py, nominal)?;
    let a = f64_array(joints, "joints")?;
    let (m, n) = match a.shape() {
        [m, n] => (*m, *n),
        s => {
            return Err(invalid_input(
                py,
                format!("joints must have shape (M, dof), got {}", fmt_shape(s)),
            ))
        }
    };
    let q: Vec<Vec<f64>> = (0..m)
        .map(|i| (0..n).map(|j| a[[i, j].as_slice()]).collect())
        .collect();
    let mut free = FreeBlocks::default();
    for name in &fix {
        free.hold(name).py_err(py)?;
    }
    let opts = PlanOptions {
        sigma_px,
        standoff_mm,
        margin_px,
        free,
        robot,
        pose_noise,
        ..PlanOptions::default()
    };
    let plan = py
        .detach_pool(|| core_plan_poses(&rig, &nominal, &q, &opts))
        .py_err(py)?;
    let v = serde_json::to_value(&plan)
        .map_err(|e| invalid_input(py, format!("the plan cannot be converted: {e}")))?;
    json_to_py(py, &v)
}
