//! `stripecal.profiler_start`: the first two steps of a profiler's calibration alone
//! (each profile's arc of the sphere, the consensus and its closed-form start;
//! `stripecal::pipeline::profile::prepare`), so that another solver can start from the
//! same start over the same points (scripts/bench_profiler_scipy.py); and
//! `stripecal.profiler_adjust`: step 3 alone (the one-stage adjustment from such a
//! start over its points, `stripecal::calib::joint::profile::profile_adjustment`).

use crate::pool::Detach;
use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use stripecal::model::ProfileDataset;
use stripecal::pipeline::profile::{prepare, profile_inputs};

use stripecal::calib::joint::profile::{
    profile_adjustment, ProfileOptions, ProfileStart, ProfileViewObs,
};

use crate::convert::{fixed, iso_to_py, isos_to_py, nd, py_to_iso, rows_of};
use crate::errors::{invalid_input, map_err, quality_error, ResultExt};
use crate::profile_py::PyProfileDataset;

/// The closed-form start of a profile dataset's calibration and the points it starts
/// from: a dict with `views` (views.csv rows kept), `flanges` (N, 4, 4: `T_base_hand`
/// of their readings, mm), `points` (N arrays (M_i, 2): each kept view's arc points
/// `x_mm, z_mm` in the profiler frame), `hand_sensor` (4, 4), `centre_mm` (3,, base
/// frame), `diameter_mm` (declared, or the start's), `diameter_free` (bool) and
/// `warnings` (the views left out, named). Raises as `calibrate` does for a dataset
/// the calibration cannot start from.
#[pyfunction]
pub fn profiler_start<'py>(
    py: Python<'py>,
    dataset: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let ds = if let Ok(d) = dataset.cast::<PyProfileDataset>() {
        d.get().inner.clone()
    } else {
        let path: PathBuf = dataset.extract()?;
        py.detach_pool(|| ProfileDataset::load(&path)).py_err(py)?
    };
    let result = py.detach_pool(|| prepare(&profile_inputs(&ds)?, &ds.rig));
    let p = match result {
        Ok(p) => p,
        Err(stripecal::Error::Quality(f)) => return Err(quality_error(py, &f, None)),
        Err(e) => return Err(map_err(py, e)),
    };
    let out = PyDict::new(py);
    out.set_item("views", p.views.iter().map(|v| v.view).collect::<Vec<_>>())?;
    let flanges: Vec<_> = p.views.iter().map(|v| v.a).collect();
    out.set_item("flanges", isos_to_py(py, &flanges)?)?;
    let points = PyList::empty(py);
    for v in &p.views {
        let data: Vec<f64> = v.arc.iter().flat_map(|&i| v.points[i]).collect();
        points.append(nd(py, &[v.arc.len(), 2], data)?)?;
    }
    out.set_item("points", points)?;
    out.set_item("hand_sensor", iso_to_py(py, &p.start.hand_sensor)?)?;
    out.set_item(
        "centre_mm",
        nd(py, &[3], p.start.centre.iter().copied().collect())?,
    )?;
    out.set_item("diameter_mm", p.start.diameter)?;
    out.set_item("diameter_free", p.start.diameter_free)?;
    out.set_item("warnings", p.warnings)?;
    Ok(out)
}

/// A key of the start dict, named in the error when missing.
fn item<'py>(start: &Bound<'py, PyDict>, key: &str) -> PyResult<Bound<'py, PyAny>> {
    start.get_item(key)?.ok_or_else(|| {
        invalid_input(
            start.py(),
            format!("start has no {key:?} (a dict as stripecal.profiler_start returns)"),
        )
    })
}

/// The one-stage adjustment alone (step 3 of a profiler's calibration, without the
/// checks, the mirror test and the leave-one-out) from `start`, a dict as
/// `profiler_start` returns (or one of the same keys: `flanges`, `points`,
/// `hand_sensor`, `centre_mm`, `diameter_mm`, `diameter_free`), over its points (the
/// arcs'), re-selected after each solve; flange poses as given (no robot block).
/// Returns a dict with `hand_sensor` (4, 4), `centre_mm` (3,), `diameter_mm`,
/// `rms_mm`, `points_used`, `iterations`, `converged`, `view_variance_factor` and
/// `sigma` (one-sigma per estimated number, the calibration file's names).
#[pyfunction]
pub fn profiler_adjust<'py>(
    py: Python<'py>,
    start: &Bound<'py, PyDict>,
) -> PyResult<Bound<'py, PyDict>> {
    let flanges = item(start, "flanges")?;
    let points = item(start, "points")?;
    let n: usize = flanges.len()?;
    if points.len()? != n {
        return Err(invalid_input(
            py,
            format!(
                "start has {n} flanges and {} point arrays: one per view",
                points.len()?
            ),
        ));
    }
    let mut views = Vec::with_capacity(n);
    for i in 0..n {
        let a = py_to_iso(&flanges.get_item(i)?, &format!("flanges[{i}]"))?;
        let (pts, _) = rows_of::<2>(&points.get_item(i)?, &format!("points[{i}]"))?;
        views.push(ProfileViewObs {
            view: i,
            a,
            q: None,
            arc: (0..pts.len()).collect(),
            points: pts,
        });
    }
    let c = fixed::<3>(&item(start, "centre_mm")?, "centre_mm")?;
    let st = ProfileStart {
        hand_sensor: py_to_iso(&item(start, "hand_sensor")?, "hand_sensor")?,
        centre: nalgebra::Vector3::from(c),
        diameter: item(start, "diameter_mm")?.extract()?,
        diameter_free: item(start, "diameter_free")?.extract()?,
    };
    let fit = py
        .detach_pool(|| profile_adjustment(&views, &st, &ProfileOptions::default()))
        .py_err(py)?;
    let out = PyDict::new(py);
    out.set_item("hand_sensor", iso_to_py(py, &fit.hand_sensor)?)?;
    out.set_item(
        "centre_mm",
        nd(py, &[3], fit.centre.iter().copied().collect())?,
    )?;
    out.set_item("diameter_mm", fit.diameter)?;
    out.set_item("rms_mm", fit.rms_mm())?;
    out.set_item("points_used", fit.points_used())?;
    out.set_item("iterations", fit.iterations)?;
    out.set_item("converged", fit.converged)?;
    out.set_item("view_variance_factor", fit.view_variance_factor)?;
    let sigma = PyDict::new(py);
    for (k, name) in fit.covariance.parameters.iter().enumerate() {
        sigma.set_item(name, fit.covariance.matrix[(k, k)].max(0.0).sqrt())?;
    }
    out.set_item("sigma", sigma)?;
    Ok(out)
}
