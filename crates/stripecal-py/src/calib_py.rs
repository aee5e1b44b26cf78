//! `stripecal.solve_axzb`, `stripecal.solve_axzb_full`, `stripecal.fit_laser_plane`:
//! the two-stage calibration pieces (hand-eye / robot-world, laser plane).
//!
//! Transforms are `(N, 4, 4)` homogeneous float arrays (rigid to 1e-6); the GIL is
//! released while the core computes.

use crate::pool::Detach;
use nalgebra::Matrix4;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PySequence, PyTuple};

use crate::args::{bind_as, Params};

use stripecal::calib::axzb::{solve_axzb_with, AxzbOptions, AxzbSolution};
use stripecal::calib::laser_plane::fit_laser_plane as core_fit_laser_plane;
use stripecal::model::geometry::{iso_from_matrix, Iso3};

use std::path::PathBuf;

use stripecal::calib::camera::{calibrate_camera as core_calibrate_camera, CameraOptions};
use stripecal::calib::conic::CentreModel;
use stripecal::calib::joint::{FreeBlocks, RobotMode};
use stripecal::calib::{CircleObs, ViewObs};
use stripecal::model::camera::{DistortionModel, PARAM_NAMES};
use stripecal::pipeline::{
    calibrate_dataset, calibrate_dataset_loaded, CalibrateOptions, CalibrationReport, Method,
};

use crate::board::PyBoard;
use crate::camera::PyCamera;
use crate::convert::{f64_array, fmt_shape, iso_to_py, nd, positive_u32, RIGID_TOL};
use crate::errors::{invalid_input, map_err, map_err_at, quality_error, ResultExt};
use crate::profile_py::{PyProfileDataset, PyProfilerCalibration};
use crate::results::PyCalibration;
use crate::rig::PyDataset;
use stripecal::io::is_profile_dataset;
use stripecal::model::{Calibration, ProfileDataset};
use stripecal::pipeline::profile::{calibrate_profile_dataset_loaded, ProfileCalibrateOptions};

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
    py.detach_pool(|| solve_axzb_with(&a, &b, &opts)).py_err(py)
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
        .detach_pool(|| core_fit_laser_plane(&views, &cam))
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

fn parse_distortion(py: Python<'_>, s: Option<&str>) -> PyResult<Option<DistortionModel>> {
    s.map(|s| DistortionModel::from_name(s).py_err(py))
        .transpose()
}
/// `calibrate`'s parameters (see [`bind_as`]).
const CALIBRATE: Params = Params {
    name: "calibrate",
    positional: &["dataset"],
    required: 1,
    keyword: &[
        "distortion",
        "method",
        "robust",
        "centre_model",
        "from_calibration",
        "fix",
        "laser_only",
        "estimate_board_scale",
        "board_scale_tolerance",
        "leave_one_out",
        "accept_poor",
        "robot_pose_noise",
        "robot",
        "board_stripe_bias",
    ],
};

/// `calibrate`'s arguments, with their defaults.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct CalibrateArgs<'py> {
    dataset: Bound<'py, PyAny>,
    #[pyo3(default)]
    distortion: Option<String>,
    #[pyo3(default = "one-stage".into())]
    method: String,
    #[pyo3(default)]
    robust: bool,
    #[pyo3(default = "conic-exact".into())]
    centre_model: String,
    #[pyo3(default)]
    from_calibration: Option<Bound<'py, PyAny>>,
    #[pyo3(default)]
    fix: Vec<String>,
    #[pyo3(default)]
    laser_only: bool,
    #[pyo3(default)]
    estimate_board_scale: bool,
    #[pyo3(default = 0.01)]
    board_scale_tolerance: f64,
    #[pyo3(default = true)]
    leave_one_out: bool,
    #[pyo3(default)]
    accept_poor: bool,
    #[pyo3(default = true)]
    robot_pose_noise: bool,
    #[pyo3(default = "fixed".into())]
    robot: String,
    #[pyo3(default = true)]
    board_stripe_bias: bool,
}

/// Calibrates a dataset folder (or a loaded `Dataset`): circles and stripes detected in
/// every view, then the camera, the laser plane, `X = T_hand_cam` and `Z = T_base_board`.
///
/// `distortion`: `"radial1"`, `"radial2"` or `"opencv5"` (default: the rig's model);
/// `method`: `"one-stage"` (default: everything refined together, the board poses
/// following from the robot) or `"paper"` (camera, then plane, then linear AX = ZB);
/// `robust`: Huber loss in the one-stage adjustment; `centre_model`: `"conic-exact"`
/// (default), `"conic"` or `"naive"`.
///
/// Starting from an earlier calibration (`from_calibration`: a `Calibration` or a
/// calibration.json path): `fix` names the blocks held at its values (`"camera"`,
/// `"laser_plane"`, `"hand_cam"`, `"base_board"`); `laser_only=True` holds all but the
/// laser plane. `estimate_board_scale=True` frees the board's printed scale (the robot
/// fixes it); otherwise it is checked (the result's `board_scale`, a warning when rig.json
/// disagrees by more than 3 sigma and `board_scale_tolerance`). `leave_one_out=True`
/// (default) computes the leave-one-view-out figure (the result's `leave_one_out`).
///
/// Quality gates: a calibration that fails one (views that disagree and cannot be left
/// out, undetermined parameters, no convergence) raises `CalibrationQualityError`
/// carrying the failed `checks` and the `calibration` for inspection;
/// `accept_poor=True` returns it instead, with `quality["accepted_poor"]` True. Every
/// gate's verdict is in `quality["checks"]`. `robot_pose_noise=True` (default) corrects
/// every view's robot pose by its own small transform and reports the robot-pose noise
/// (`robot_pose_noise`); `False`: the poses are exact (the paper's rigid model, for
/// comparison). `robot` calibrates the
/// robot's DH rows from the same images: `"fixed"` (default; the same as
/// `fix=["robot"]`), `"offsets"` (encoder offsets), `"full"` (every identifiable
/// correction) or `"auto"` (the corrections the data show); the refined rows are the
/// result's `robot`, what was estimated or fixed and why `robot_calibration`. Needs
/// rig.json's robot and joint readings. `board_stripe_bias=True` (default, one-stage
/// method) corrects the laser stripe's sub-pixel bias on the board before the final
/// adjustment (the sheet's thickness from the stripe widths, the model of
/// `measure_sphere`'s correction on a plane) and adds what the correction leaves to the
/// covariance (calibration.json's `board_stripe_bias`).
///
/// Returns a `Calibration` with quality, one-sigma `uncertainty`, per-view figures
/// (`views`) and the run's residuals. Views whose board is not found, and views whose
/// robot pose disagrees with their board pose, are left out with a warning naming them
/// (the result's `warnings`). Raises `InvalidInputError` for fewer than 3 usable views
/// or no usable laser image, `DegenerateError` for pose sets or stripes that do not
/// determine the result, `FormatError`/`OSError` for unreadable files. The GIL is
/// released while it runs; a Ctrl-C (SIGINT) during the run stops it at the core's next
/// step (each view's detection, each stage and adjustment: within about a second) and
/// raises `KeyboardInterrupt`; nothing is returned.
#[pyfunction]
#[pyo3(signature = (*args, **kwargs), text_signature = "(dataset, *, distortion=None, method=\"one-stage\", robust=False, centre_model=\"conic-exact\", from_calibration=None, fix=..., laser_only=False, estimate_board_scale=False, board_scale_tolerance=0.01, leave_one_out=True, accept_poor=False, robot_pose_noise=True, robot=\"fixed\", board_stripe_bias=True)")]
pub fn calibrate(
    py: Python<'_>,
    args: &Bound<'_, PyTuple>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    let CalibrateArgs {
        dataset,
        distortion,
        method,
        robust,
        centre_model,
        from_calibration,
        fix,
        laser_only,
        estimate_board_scale,
        board_scale_tolerance,
        leave_one_out,
        accept_poor,
        robot_pose_noise,
        robot,
        board_stripe_bias,
    } = bind_as(&CALIBRATE, args, kwargs)?;
    let (dataset, distortion, method, centre_model, from_calibration, robot) = (
        &dataset,
        distortion.as_deref(),
        method.as_str(),
        centre_model.as_str(),
        from_calibration.as_ref(),
        robot.as_str(),
    );
    if let Some(ds) = profile_dataset(py, dataset)? {
        // A line profiler's dataset (rig.json sensor.kind = "profiler"): the camera's
        // options do not apply to it.
        let camera_only = [
            ("distortion", distortion.is_some()),
            ("method", method != "one-stage"),
            ("robust", robust),
            ("centre_model", centre_model != "conic-exact"),
            ("from_calibration", from_calibration.is_some()),
            ("fix", !fix.is_empty()),
            ("laser_only", laser_only),
            ("estimate_board_scale", estimate_board_scale),
            ("robot_pose_noise", !robot_pose_noise),
            ("board_stripe_bias", !board_stripe_bias),
        ];
        let opts = ProfileCalibrateOptions {
            robot: RobotMode::from_name(robot).py_err(py)?,
            leave_one_out,
            accept_poor,
        };
        return calibrate_profiler(py, &ds, &camera_only, &opts);
    }
    let from = from_calibration
        .map(|c| calibration_of(py, c))
        .transpose()?;
    let mut free = if laser_only {
        FreeBlocks::laser_only()
    } else {
        FreeBlocks::default()
    };
    for name in &fix {
        free.hold(name).py_err(py)?;
    }
    let robot = RobotMode::from_name(robot).py_err(py)?;
    if robot != RobotMode::Fixed && fix.iter().any(|n| n == "robot") {
        return Err(crate::errors::invalid_input(
            py,
            format!(
                "fix=['robot'] holds the robot but robot={:?} calibrates it",
                robot.name()
            ),
        ));
    }
    free.board_scale = estimate_board_scale;
    let opts = CalibrateOptions {
        distortion: parse_distortion(py, distortion)?,
        method: Method::from_name(method).py_err(py)?,
        robust,
        centre_model: parse_centre_model(py, centre_model)?,
        from,
        free,
        leave_one_out,
        board_scale_tolerance,
        accept_poor,
        robot_pose_noise,
        robot,
        board_stripe_bias,
        ..Default::default()
    };
    let cancel = opts.cancel.clone();
    let result = if let Ok(ds) = dataset.cast::<PyDataset>() {
        let ds = &ds.get().inner;
        py.detach_cancellable(&cancel, || calibrate_dataset_loaded(ds, &opts))?
    } else {
        let path: PathBuf = dataset.extract().map_err(|_| {
            pyo3::exceptions::PyTypeError::new_err(format!(
                "dataset must be a path (str or os.PathLike) or a stripecal.Dataset, got {}",
                crate::convert::type_name(dataset)
            ))
        })?;
        py.detach_cancellable(&cancel, || calibrate_dataset(&path, &opts))?
    };
    // A Ctrl-C after the last poll, as the core returned: the result is dropped and
    // KeyboardInterrupt raised, so no caller goes on to write it.
    py.check_signals()?;
    match result {
        Ok(rep) => Ok(Py::new(py, report_to_py(rep))?.into_any()),
        Err(stripecal::Error::Quality(f)) => {
            let cal = match f.report() {
                Some(rep) => Some(Py::new(py, report_to_py(rep.clone()))?.into_any()),
                None => None,
            };
            Err(quality_error(py, &f, cal))
        }
        Err(e) => Err(map_err(py, e)),
    }
}

/// [`calibrate`] of a line profiler's dataset: refuses the camera's options set
/// (`camera_only`: name, whether set), calibrates with `opts`.
fn calibrate_profiler(
    py: Python<'_>,
    ds: &ProfileDataset,
    camera_only: &[(&str, bool)],
    opts: &ProfileCalibrateOptions,
) -> PyResult<Py<PyAny>> {
    if let Some((name, _)) = camera_only.iter().find(|(_, set)| *set) {
        return Err(crate::errors::invalid_input(
            py,
            format!(
                "{name} is an option of a camera's calibration; this dataset is a line profiler's (rig.json sensor.kind = \"profiler\")"
            ),
        ));
    }
    let result = py.detach_pool(|| calibrate_profile_dataset_loaded(ds, opts));
    py.check_signals()?;
    match result {
        Ok(rep) => Ok(Py::new(
            py,
            PyProfilerCalibration {
                inner: rep.calibration,
            },
        )?
        .into_any()),
        Err(stripecal::Error::Quality(f)) => Err(quality_error(py, &f, None)),
        Err(e) => Err(map_err(py, e)),
    }
}

/// `from_calibration`: a `Calibration`, or a calibration.json path read.
fn calibration_of(py: Python<'_>, c: &Bound<'_, PyAny>) -> PyResult<Calibration> {
    if let Ok(pc) = c.cast::<PyCalibration>() {
        return Ok(pc.get().inner.clone());
    }
    let path: PathBuf = c.extract().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(format!(
            "from_calibration must be a Calibration or a path, got {}",
            crate::convert::type_name(c)
        ))
    })?;
    py.detach_pool(|| stripecal::io::read_calibration(&path))
        .py_err(py)
}

/// The profile dataset `dataset` names (a `ProfileDataset`, or a folder whose rig.json
/// says `sensor.kind = "profiler"`), loaded; `None` for a camera's dataset.
fn profile_dataset(py: Python<'_>, dataset: &Bound<'_, PyAny>) -> PyResult<Option<ProfileDataset>> {
    if let Ok(ds) = dataset.cast::<PyProfileDataset>() {
        return Ok(Some(ds.get().inner.clone()));
    }
    if dataset.cast::<PyDataset>().is_ok() {
        return Ok(None);
    }
    let Ok(path) = dataset.extract::<PathBuf>() else {
        return Ok(None);
    };
    // (without a rig.json the camera's loader says what is missing)
    if !path.join("rig.json").is_file()
        || !py.detach_pool(|| is_profile_dataset(&path)).py_err(py)?
    {
        return Ok(None);
    }
    py.detach_pool(|| ProfileDataset::load(&path))
        .py_err(py)
        .map(Some)
}

fn parse_centre_model(py: Python<'_>, s: &str) -> PyResult<CentreModel> {
    match s {
        "conic-exact" => Ok(CentreModel::ConicExact),
        "conic" => Ok(CentreModel::Conic),
        "naive" => Ok(CentreModel::Naive),
        o => Err(invalid_input(
            py,
            format!("unknown centre_model {o:?}: expected \"conic-exact\", \"conic\" or \"naive\""),
        )),
    }
}

fn report_to_py(rep: CalibrationReport) -> PyCalibration {
    let adj = &rep.adjustment;
    PyCalibration {
        inner: rep.calibration,
        circle_residuals: adj
            .circle_residuals
            .iter()
            .map(|&(v, r, c, u, vv, du, dv)| [v as f64, r as f64, c as f64, u, vv, du, dv])
            .collect(),
        stripe_residuals: adj
            .stripe_residuals
            .iter()
            .map(|&(v, u, vv, d)| [v as f64, u, vv, d])
            .collect(),
    }
}

/// Calibrates the camera alone from circle observations: `views` is a sequence of
/// `(indices (N, 2) int (row, col), centres (N, 2) float (u, v))` pairs, as returned by
/// `detect_circles`; `board` the board; `image_size` `(width, height)`.
///
/// Returns a dict: `camera` (Camera), `cam_board` `(K, 4, 4)` board poses `T_cam_board`
/// of the `K` views used, `views_used` (their indices in `views`), `rms_px`,
/// `per_view_rms_px`, `camera_sigma` (dict of one-sigmas by parameter name),
/// `initial_intrinsics` (Zhang's `[fu, fv, u0, v0]`), `warnings`.
#[pyfunction]
#[pyo3(signature = (views, board, image_size, *, distortion = "radial1", centre_model = "conic-exact"))]
pub fn calibrate_camera<'py>(
    py: Python<'py>,
    views: &Bound<'py, PyAny>,
    board: PyRef<'py, PyBoard>,
    image_size: (i64, i64),
    distortion: &str,
    centre_model: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let model = DistortionModel::from_name(distortion).py_err(py)?;
    let cm = parse_centre_model(py, centre_model)?;
    let width = positive_u32(py, image_size.0, "image_size[0]")?;
    let height = positive_u32(py, image_size.1, "image_size[1]")?;
    let seq = views.cast::<PySequence>().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "views must be a sequence of (indices, centres) pairs",
        )
    })?;
    let mut obs = Vec::new();
    for i in 0..seq.len()? {
        let item = seq.get_item(i)?;
        let (idx, ctr): (Bound<'_, PyAny>, Bound<'_, PyAny>) = item.extract().map_err(|_| {
            pyo3::exceptions::PyTypeError::new_err(format!(
                "views[{i}] must be an (indices, centres) pair"
            ))
        })?;
        let ia = f64_array(&idx, &format!("views[{i}] indices"))?;
        let ca = f64_array(&ctr, &format!("views[{i}] centres"))?;
        let n = match (ia.shape(), ca.shape()) {
            ([n, 2], [m, 2]) if n == m => *n,
            ([0], [0]) => 0,
            (a, b) => {
                return Err(invalid_input(
                    py,
                    format!(
                        "views[{i}]: indices {} and centres {} must both be (N, 2)",
                        fmt_shape(a),
                        fmt_shape(b)
                    ),
                ))
            }
        };
        let mut circles = Vec::with_capacity(n);
        for k in 0..n {
            let (r, c) = (ia[[k, 0].as_slice()], ia[[k, 1].as_slice()]);
            if !(r >= 0.0 && c >= 0.0 && r.fract() == 0.0 && c.fract() == 0.0) {
                return Err(invalid_input(
                    py,
                    format!("views[{i}] indices[{k}] = ({r}, {c}) is not a grid index"),
                ));
            }
            circles.push(CircleObs {
                row: r as usize,
                col: c as usize,
                u: ca[[k, 0].as_slice()],
                v: ca[[k, 1].as_slice()],
            });
        }
        obs.push(ViewObs {
            view: i,
            circles,
            stripe: Vec::new(),
            reading: None,
            base_hand: None,
            alternatives: Vec::new(),
            stripe_shape: None,
        });
    }
    let b = board.inner.clone();
    let opts = CameraOptions {
        centre_model: cm,
        ..Default::default()
    };
    let r = py
        .detach_pool(|| core_calibrate_camera(&obs, &b, width, height, model, &opts))
        .py_err(py)?;
    let d = PyDict::new(py);
    d.set_item("camera", PyCamera::new_py(r.camera.clone()))?;
    let poses: Vec<Iso3> = r.poses.iter().map(|p| p.1).collect();
    d.set_item("cam_board", crate::convert::isos_to_py(py, &poses)?)?;
    d.set_item(
        "views_used",
        r.poses.iter().map(|p| p.0).collect::<Vec<usize>>(),
    )?;
    d.set_item("rms_px", r.rms_px)?;
    d.set_item("per_view_rms_px", r.per_view_rms_px.clone())?;
    let cs = PyDict::new(py);
    for (i, name) in PARAM_NAMES.iter().enumerate() {
        cs.set_item(*name, r.camera_sigma[i])?;
    }
    d.set_item("camera_sigma", cs)?;
    d.set_item("initial_intrinsics", r.initial_intrinsics.to_vec())?;
    d.set_item("unobservable", r.unobservable.clone())?;
    d.set_item("warnings", r.warnings.clone())?;
    Ok(d)
}
