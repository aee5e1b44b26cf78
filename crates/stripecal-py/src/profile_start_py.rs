//! `stripecal.profiler_start`: the first two steps of a profiler's calibration alone
//! (each profile's arc of the sphere, the consensus and its closed-form start;
//! `stripecal::pipeline::profile::prepare`), so that another solver can start from the
//! same start over the same points (scripts/bench_profiler_scipy.py).

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use stripecal::model::ProfileDataset;
use stripecal::pipeline::profile::{prepare, profile_inputs};

use crate::convert::{iso_to_py, isos_to_py, nd};
use crate::errors::{map_err, quality_error, ResultExt};
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
        py.detach(|| ProfileDataset::load(&path)).py_err(py)?
    };
    let result = py.detach(|| prepare(&profile_inputs(&ds)?, &ds.rig));
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
