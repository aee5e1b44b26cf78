//! `stripecal.measure_sphere`, `stripecal.measure_ball_bar`, `stripecal.measure_plane`,
//! `stripecal.verify`: measurements of a scan with their GUM budgets and the VDI/VDE
//! 2634-2 acceptance test. Conversions only (the core's JSON records as dicts); the GIL
//! is released while Rust works.

use crate::pool::Detach;
use std::ops::ControlFlow;
use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::args::{bind_as, Params};

use serde_json::Value;
use stripecal::model::{Calibration, ProfilerCalibration, RobotReading};
use stripecal::pipeline::measure::{
    measure_scan_ball_bar, measure_scan_plane, measure_scan_sphere, profiler_uncertainty_model,
    scan_readings, scan_uncertainty_model, MeasureOptions,
};
use stripecal::pipeline::verify::{verify as core_verify, verify_profiler, VerifyOptions};
use stripecal::reconstruct::{
    load_profile_frames, profile_scan_points, ProfileReconstructOptions, ScanPoints,
};
use stripecal::reconstruct::{load_scan, reconstruct_scan, ReconstructOptions, UncertaintyOptions};
use stripecal::{Error, Result};

use crate::convert::{json_to_py, progress_step};
use crate::errors::{invalid_input, ResultExt};
use crate::profile_py::PyProfilerCalibration;
use crate::reconstruct_py::PyCloud;
use crate::results::PyCalibration;

/// Which shape to measure.
#[derive(Clone, Copy)]
enum Shape {
    Sphere,
    BallBar,
    Plane,
}

/// The arguments of `measure_sphere`, `measure_ball_bar` and `measure_plane` (the
/// keywords a function lacks keep their defaults).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct MeasureArgs<'py> {
    calibration: Bound<'py, PyAny>,
    scan_dir: PathBuf,
    #[pyo3(default)]
    cloud: Option<Bound<'py, PyCloud>>,
    #[pyo3(default)]
    diameter_range_mm: Option<(f64, f64)>,
    #[pyo3(default = true)]
    correct_bias: bool,
    #[pyo3(default = true)]
    calibration_part: bool,
    #[pyo3(default)]
    stripe_sigma_px: Option<f64>,
    #[pyo3(default)]
    repeatability_mm: Option<f64>,
    #[pyo3(default)]
    encoder_sigma_deg: Option<f64>,
    #[pyo3(default = 3.0)]
    trim_sigma: f64,
}

/// The fit and budget options of a measurement or of `verify`.
struct Budget {
    diameter_range_mm: Option<(f64, f64)>,
    correct_bias: bool,
    calibration_part: bool,
    stripe_sigma_px: Option<f64>,
    repeatability_mm: Option<f64>,
    encoder_sigma_deg: Option<f64>,
    trim_sigma: f64,
}

/// The parameters of `measure_sphere` and `measure_ball_bar`.
const fn measure_params(name: &'static str) -> Params {
    Params {
        name,
        positional: &["calibration", "scan_dir"],
        required: 2,
        keyword: &[
            "cloud",
            "diameter_range_mm",
            "correct_bias",
            "calibration_part",
            "stripe_sigma_px",
            "repeatability_mm",
            "encoder_sigma_deg",
            "trim_sigma",
        ],
    }
}

const MEASURE_SPHERE: Params = measure_params("measure_sphere");
const MEASURE_BALL_BAR: Params = measure_params("measure_ball_bar");
const MEASURE_PLANE: Params = Params {
    name: "measure_plane",
    positional: &["calibration", "scan_dir"],
    required: 2,
    keyword: &[
        "cloud",
        "calibration_part",
        "stripe_sigma_px",
        "repeatability_mm",
        "encoder_sigma_deg",
        "trim_sigma",
    ],
};
const VERIFY: Params = Params {
    name: "verify",
    positional: &["calibration", "folder"],
    required: 2,
    keyword: &[
        "artefacts",
        "correct_bias",
        "stripe_sigma_px",
        "repeatability_mm",
        "encoder_sigma_deg",
        "progress",
    ],
};

fn options(py: Python<'_>, b: &Budget) -> PyResult<MeasureOptions> {
    if !b.trim_sigma.is_finite() {
        return Err(invalid_input(py, "trim_sigma must be finite"));
    }
    let mut o = MeasureOptions {
        uncertainty: UncertaintyOptions {
            calibration: b.calibration_part,
            stripe_sigma_px: b.stripe_sigma_px,
            repeatability_mm: b.repeatability_mm,
            encoder_sigma_deg: b.encoder_sigma_deg,
            ..Default::default()
        },
        correct_bias: b.correct_bias,
        ..Default::default()
    };
    o.fit.trim_sigma = b.trim_sigma;
    o.fit.diameter_range_mm = b.diameter_range_mm.map(|(a, b)| [a, b]);
    Ok(o)
}

/// [`measure`] of `shape` with the arguments of `p`'s function.
fn measure_bound(
    py: Python<'_>,
    shape: Shape,
    p: &Params,
    args: &Bound<'_, PyTuple>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    let a: MeasureArgs = bind_as(p, args, kwargs)?;
    let b = Budget {
        diameter_range_mm: a.diameter_range_mm,
        // no curved-surface bias on a plane
        correct_bias: a.correct_bias && !matches!(shape, Shape::Plane),
        calibration_part: a.calibration_part,
        stripe_sigma_px: a.stripe_sigma_px,
        repeatability_mm: a.repeatability_mm,
        encoder_sigma_deg: a.encoder_sigma_deg,
        trim_sigma: a.trim_sigma,
    };
    let o = options(py, &b)?;
    measure(py, shape, &a.calibration, a.scan_dir, a.cloud.as_ref(), o)
}

/// The measurement of `shape` in a scan's points, as JSON.
fn measure_shape(
    shape: Shape,
    model: &stripecal::reconstruct::UncertaintyModel,
    readings: &[RobotReading],
    points: &ScanPoints,
    opts: &MeasureOptions,
) -> Result<Value> {
    Ok(match shape {
        Shape::Sphere => measure_scan_sphere(model, readings, points, opts)?.to_json(),
        Shape::BallBar => measure_scan_ball_bar(model, readings, points, opts)?.to_json(),
        Shape::Plane => measure_scan_plane(model, readings, points, opts)?.to_json(),
    })
}

fn measure(
    py: Python<'_>,
    shape: Shape,
    calibration: &Bound<'_, PyAny>,
    scan_dir: PathBuf,
    cloud: Option<&Bound<'_, PyCloud>>,
    opts: MeasureOptions,
) -> PyResult<Py<PyAny>> {
    if let Ok(pc) = calibration.cast::<PyProfilerCalibration>() {
        return measure_profile_scan(py, shape, &pc.get().inner, scan_dir, cloud, opts);
    }
    let calibration = calibration
        .cast::<PyCalibration>()
        .map_err(|_| crate::convert::not_a_calibration(calibration))?;
    let cal = &calibration.get().inner;
    let given = cloud.map(|c| c.get().inner.clone());
    let v: Value = py
        .detach_pool(|| -> Result<Value> {
            let scan = load_scan(&scan_dir, cal)?;
            let points = match given {
                Some(p) => p,
                None => reconstruct_scan(
                    cal,
                    &scan,
                    &ReconstructOptions::default(),
                    &mut |_, _, _| ControlFlow::Continue(()),
                )?,
            };
            check_cloud_frames(&points, scan.frames.len())?;
            let model = scan_uncertainty_model(cal, &scan, &opts.uncertainty)?;
            let readings = scan_readings(&scan);
            measure_shape(shape, &model, &readings, &points, &opts)
        })
        .py_err(py)?;
    Ok(json_to_py(py, &v)?.unbind())
}

/// An error if `points` has a point of a frame the scan (of `frames` frames) lacks: it is
/// another scan's cloud.
fn check_cloud_frames(points: &ScanPoints, frames: usize) -> Result<()> {
    if let Some(&f) = points.frame.iter().find(|&&f| f as usize >= frames) {
        return Err(Error::InvalidInput(format!(
            "the cloud has points of frame {f}, but the scan has {frames} frames: it is not this \
             scan's cloud"
        )));
    }
    Ok(())
}

/// Measures the sphere in a scan (reconstructed here, or `cloud`, the scan's
/// reconstruction) with GUM budgets: the fit (robust start, `trim_sigma` trimming,
/// `diameter_range_mm`), corrected for the curved-surface stripe bias
/// (`correct_bias`), and for the diameter, each centre coordinate and the probing form
/// the standard uncertainties `random_mm`, `calibration_mm` (the calibration's
/// covariance through every point; `calibration_part=False` leaves it out),
/// `robot_mm` (`repeatability_mm`, `encoder_sigma_deg`, default the calibration's
/// robot figures), `systematic_mm`, combined, and `expanded_mm` (k = 2): the
/// headline.
/// [`measure`] of a line profiler's scan (a profile scan folder): its points from the
/// profiles (or `cloud`), the budgets from the profiler's calibration.
fn measure_profile_scan(
    py: Python<'_>,
    shape: Shape,
    cal: &ProfilerCalibration,
    scan_dir: PathBuf,
    cloud: Option<&Bound<'_, PyCloud>>,
    opts: MeasureOptions,
) -> PyResult<Py<PyAny>> {
    let given = cloud.map(|c| c.get().inner.clone());
    let v: Value = py
        .detach_pool(|| -> Result<Value> {
            let (frames, _) = load_profile_frames(
                &scan_dir,
                cal.robot.as_ref(),
                &ProfileReconstructOptions::default(),
            )?;
            let points = match given {
                Some(p) => p,
                None => profile_scan_points(&frames, cal)?,
            };
            check_cloud_frames(&points, frames.len())?;
            let model = profiler_uncertainty_model(cal, &opts.uncertainty)?;
            let readings: Vec<RobotReading> = frames.iter().map(|f| f.0.clone()).collect();
            measure_shape(shape, &model, &readings, &points, &opts)
        })
        .py_err(py)?;
    Ok(json_to_py(py, &v)?.unbind())
}

#[pyfunction]
#[pyo3(signature = (*args, **kwargs), text_signature = "(calibration, scan_dir, *, cloud=None, diameter_range_mm=None, correct_bias=True, calibration_part=True, stripe_sigma_px=None, repeatability_mm=None, encoder_sigma_deg=None, trim_sigma=3.0)")]
pub fn measure_sphere(
    py: Python<'_>,
    args: &Bound<'_, PyTuple>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    measure_bound(py, Shape::Sphere, &MEASURE_SPHERE, args, kwargs)
}

/// Measures a ball bar's two spheres in a scan and their centres' distance, each with
/// its budget (as `measure_sphere`; the distance's calibration and robot parts are
/// correlated between the spheres as the chain says).
#[pyfunction]
#[pyo3(signature = (*args, **kwargs), text_signature = "(calibration, scan_dir, *, cloud=None, diameter_range_mm=None, correct_bias=True, calibration_part=True, stripe_sigma_px=None, repeatability_mm=None, encoder_sigma_deg=None, trim_sigma=3.0)")]
pub fn measure_ball_bar(
    py: Python<'_>,
    args: &Bound<'_, PyTuple>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    measure_bound(py, Shape::BallBar, &MEASURE_BALL_BAR, args, kwargs)
}

/// Measures the plane in a scan: flatness, offset and tilts with their budgets.
#[pyfunction]
#[pyo3(signature = (*args, **kwargs), text_signature = "(calibration, scan_dir, *, cloud=None, calibration_part=True, stripe_sigma_px=None, repeatability_mm=None, encoder_sigma_deg=None, trim_sigma=3.0)")]
pub fn measure_plane(
    py: Python<'_>,
    args: &Bound<'_, PyTuple>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    measure_bound(py, Shape::Plane, &MEASURE_PLANE, args, kwargs)
}

/// `verify`'s folder and callback (its budget keywords are a [`BudgetArgs`]).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct VerifyArgs<'py> {
    calibration: Bound<'py, PyAny>,
    folder: PathBuf,
    #[pyo3(default)]
    artefacts: Option<PathBuf>,
    #[pyo3(default)]
    progress: Option<Py<PyAny>>,
    #[pyo3(default = true)]
    correct_bias: bool,
    #[pyo3(default)]
    stripe_sigma_px: Option<f64>,
    #[pyo3(default)]
    repeatability_mm: Option<f64>,
    #[pyo3(default)]
    encoder_sigma_deg: Option<f64>,
}

/// The VDI/VDE 2634-2 style acceptance test on a folder holding `artefacts.json` (or
/// `artefacts`), the manifest `verify.csv` (`scan,artefact`) and the scans: probing
/// error form and size, sphere-spacing error and flatness measurement error per
/// measurement with expanded uncertainties, against the MPEs; returns the report
/// (`format` "stripecal/verify@1", `passed`, `summary`, `rows`).
/// `progress(stage, done, total)` is called per chunk of frames; an exception raised
/// by it (or Ctrl-C) stops the run.
#[pyfunction]
#[pyo3(signature = (*args, **kwargs), text_signature = "(calibration, folder, *, artefacts=None, correct_bias=True, stripe_sigma_px=None, repeatability_mm=None, encoder_sigma_deg=None, progress=None)")]
pub fn verify(
    py: Python<'_>,
    args: &Bound<'_, PyTuple>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    let VerifyArgs {
        calibration,
        folder,
        artefacts,
        progress,
        correct_bias,
        stripe_sigma_px,
        repeatability_mm,
        encoder_sigma_deg,
    } = bind_as(&VERIFY, args, kwargs)?;
    let budget = Budget {
        diameter_range_mm: None,
        correct_bias,
        calibration_part: true,
        stripe_sigma_px,
        repeatability_mm,
        encoder_sigma_deg,
        trim_sigma: 3.0,
    };
    let calibration = &calibration;
    let which: std::result::Result<Calibration, ProfilerCalibration> =
        match calibration.cast::<PyProfilerCalibration>() {
            Ok(p) => Err(p.get().inner.clone()),
            Err(_) => Ok(calibration
                .cast::<PyCalibration>()
                .map_err(|_| crate::convert::not_a_calibration(calibration))?
                .get()
                .inner
                .clone()),
        };
    let opts = VerifyOptions {
        measure: options(py, &budget)?,
        reconstruct: ReconstructOptions::default(),
        artefacts,
    };
    let mut cb_err: Option<PyErr> = None;
    // on this thread (not the pool's): the callback checks for signals, which Python
    // delivers to its main thread only
    let result = py.detach(|| {
        let mut cb = |stage: &str, done: usize, total: usize| {
            progress_step(&progress, &mut cb_err, (stage, done, total))
        };
        match &which {
            Ok(cal) => core_verify(cal, &folder, &opts, &mut cb),
            Err(profiler) => verify_profiler(profiler, &folder, &opts, &mut cb),
        }
        .map(|r| r.to_json())
    });
    if let Some(e) = cb_err {
        return Err(e);
    }
    let v = result.py_err(py)?;
    py.check_signals()?;
    Ok(json_to_py(py, &v)?.unbind())
}
