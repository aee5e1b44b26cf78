//! `stripecal.SphereFit` (a sphere fit's JSON).

use std::path::PathBuf;

use nalgebra::Vector3;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use stripecal::io::write_sphere_fit;
use stripecal::model::SphereFit;

use crate::convert::{fixed, map_to_py, nd, opt_dict_to_map};
use crate::errors::ResultExt;
use crate::pool::Detach;

/// A sphere fit: diameter, centre, RMS residual (mm), inliers used and outliers.
#[pyclass(name = "SphereFit", module = "stripecal", frozen, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PySphereFit {
    pub inner: SphereFit,
}

#[pymethods]
impl PySphereFit {
    #[new]
    #[pyo3(signature = (diameter_mm, center_mm, rms_mm, points, outliers, extra = None))]
    fn new(
        diameter_mm: f64,
        center_mm: &Bound<'_, PyAny>,
        rms_mm: f64,
        points: usize,
        outliers: usize,
        extra: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        Ok(PySphereFit {
            inner: SphereFit {
                diameter_mm,
                center_mm: Vector3::from(fixed::<3>(center_mm, "center_mm")?),
                rms_mm,
                points,
                outliers,
                extra: opt_dict_to_map(extra, "extra")?,
            },
        })
    }

    /// Fitted diameter, mm.
    #[getter]
    fn diameter_mm(&self) -> f64 {
        self.inner.diameter_mm
    }

    /// Fitted centre, shape (3,), mm.
    #[getter]
    fn center_mm<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let c = self.inner.center_mm;
        nd(py, &[3], vec![c.x, c.y, c.z])
    }

    /// RMS of the radial residuals of the inliers, mm.
    #[getter]
    fn rms_mm(&self) -> f64 {
        self.inner.rms_mm
    }

    /// Number of inliers the fit used.
    #[getter]
    fn points(&self) -> usize {
        self.inner.points
    }

    /// Number of points rejected as outliers.
    #[getter]
    fn outliers(&self) -> usize {
        self.inner.outliers
    }

    /// Other keys (JSON-like dict).
    #[getter]
    fn extra<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        map_to_py(py, &self.inner.extra)
    }

    /// The fit's one-sigma of the diameter, mm: its random part only (the points'
    /// scatter; calibration and robot errors are not in it, `measure_sphere` has the
    /// measurement's uncertainty). The file's `fit_diameter_sigma_mm`, or an older file's
    /// `diameter_sigma_mm`; None when absent.
    #[getter]
    fn fit_diameter_sigma_mm(&self) -> Option<f64> {
        self.inner.fit_diameter_sigma_mm()
    }

    /// The fit's one-sigma of the centre, shape (3,), mm: its random part only (as
    /// `fit_diameter_sigma_mm`). The file's `fit_center_sigma_mm`, or an older file's
    /// `center_sigma_mm`; None when absent.
    #[getter]
    fn fit_center_sigma_mm<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        match self.inner.fit_center_sigma_mm() {
            Some(s) => Ok(Some(nd(py, &[3], s.to_vec())?)),
            None => Ok(None),
        }
    }

    /// The former name of `fit_diameter_sigma_mm` (the same value: the fit's random part
    /// only).
    #[getter]
    fn diameter_sigma_mm(&self) -> Option<f64> {
        self.inner.fit_diameter_sigma_mm()
    }

    /// The former name of `fit_center_sigma_mm` (the same value).
    #[getter]
    fn center_sigma_mm<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.fit_center_sigma_mm(py)
    }

    /// Writes the sphere fit JSON (atomically).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let s = &self.inner;
        py.detach_pool(|| write_sphere_fit(&path, s)).py_err(py)
    }

    fn __repr__(&self) -> String {
        let s = &self.inner;
        format!(
            "SphereFit(diameter_mm={:?}, center_mm=[{:?}, {:?}, {:?}], rms_mm={:?}, points={}, outliers={})",
            s.diameter_mm, s.center_mm.x, s.center_mm.y, s.center_mm.z, s.rms_mm, s.points, s.outliers
        )
    }
}
