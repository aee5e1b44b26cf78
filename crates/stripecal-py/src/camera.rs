//! `stripecal.Camera`.

use crate::pool::Detach;
use nalgebra::{Vector2, Vector3};
use pyo3::prelude::*;
use stripecal::model::camera::{Camera, DistortionModel, Intrinsics};
use stripecal::Error;

use crate::convert::{fixed, nd, positive_u32, rows_of, rows_to_py};
use crate::errors::{map_err_at, ResultExt};

/// The camera model: pinhole without skew, distortion `[k1, k2, p1, p2, k3]` in OpenCV
/// order, pixel centres at integer coordinates (the top-left pixel's centre is (0, 0)).
#[pyclass(name = "Camera", module = "stripecal", frozen, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyCamera {
    pub inner: Camera,
}

impl PyCamera {
    pub fn new_py(inner: Camera) -> Self {
        PyCamera { inner }
    }
}

/// Runs `f` on every row without the GIL; the first failure names its row.
fn per_row<const K: usize, T: Send>(
    py: Python<'_>,
    rows: &[[f64; K]],
    name: &str,
    f: impl Fn(&[f64; K]) -> stripecal::Result<T> + Send + Sync,
) -> PyResult<Vec<T>> {
    let out: Result<Vec<T>, (usize, Error)> = py.detach_pool(|| {
        rows.iter()
            .enumerate()
            .map(|(i, r)| f(r).map_err(|e| (i, e)))
            .collect()
    });
    out.map_err(|(i, e)| map_err_at(py, e, &format!("{name}[{i}]")))
}

#[pymethods]
impl PyCamera {
    #[new]
    #[pyo3(signature = (width, height, fu, fv, u0, v0, distortion_model = "radial1", distortion = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        width: i64,
        height: i64,
        fu: f64,
        fv: f64,
        u0: f64,
        v0: f64,
        distortion_model: &str,
        distortion: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let width = positive_u32(py, width, "width")?;
        let height = positive_u32(py, height, "height")?;
        let model = DistortionModel::from_name(distortion_model).py_err(py)?;
        let distortion = match distortion {
            None => [0.0; 5],
            Some(d) => fixed::<5>(d, "distortion")?,
        };
        Camera::new(
            width,
            height,
            Intrinsics { fu, fv, u0, v0 },
            model,
            distortion,
        )
        .py_err(py)
        .map(PyCamera::new_py)
    }

    /// Image width in pixels (columns).
    #[getter]
    fn width(&self) -> u32 {
        self.inner.width
    }

    /// Image height in pixels (rows).
    #[getter]
    fn height(&self) -> u32 {
        self.inner.height
    }

    /// `(width, height)` in pixels.
    #[getter]
    fn size(&self) -> (u32, u32) {
        (self.inner.width, self.inner.height)
    }

    /// Focal length along u, pixels.
    #[getter]
    fn fu(&self) -> f64 {
        self.inner.fu
    }

    /// Focal length along v, pixels.
    #[getter]
    fn fv(&self) -> f64 {
        self.inner.fv
    }

    /// Principal point u, pixels.
    #[getter]
    fn u0(&self) -> f64 {
        self.inner.u0
    }

    /// Principal point v, pixels.
    #[getter]
    fn v0(&self) -> f64 {
        self.inner.v0
    }

    /// `"radial1"`, `"radial2"` or `"opencv5"`: which coefficients calibration estimates.
    #[getter]
    fn distortion_model(&self) -> &'static str {
        self.inner.model.name()
    }

    /// `[k1, k2, p1, p2, k3]`, shape (5,).
    #[getter]
    fn distortion<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(py, &[5], self.inner.distortion.to_vec())
    }

    /// `[fu, fv, u0, v0, k1, k2, p1, p2, k3]`, shape (9,) (the order of `CAMERA_PARAM_NAMES`).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(py, &[9], self.inner.params().to_vec())
    }

    /// A copy with parameters `[fu, fv, u0, v0, k1, k2, p1, p2, k3]`.
    fn with_params(&self, py: Python<'_>, params: &Bound<'_, PyAny>) -> PyResult<Self> {
        let p = fixed::<9>(params, "params")?;
        let cam = self.inner.with_params(&p);
        cam.validate().py_err(py)?;
        Ok(PyCamera::new_py(cam))
    }

    /// Pixels `(N, 2)` of points `(N, 3)` in the camera frame (or `(2,)` of `(3,)`).
    /// Raises DegenerateError naming the first point not in front of the camera.
    fn project<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (pts, single) = rows_of::<3>(points, "points")?;
        let cam = &self.inner;
        let uv = per_row(py, &pts, "points", |p| {
            cam.project(&Vector3::from(*p)).map(|uv| [uv.x, uv.y])
        })?;
        rows_to_py(py, &uv, single)
    }

    /// Viewing rays `(N, 3)` with z = 1 of pixels `(N, 2)` (or `(3,)` of `(2,)`).
    /// Raises DegenerateError / ConvergenceError naming the first pixel that cannot be
    /// undistorted.
    fn unproject<'py>(
        &self,
        py: Python<'py>,
        pixels: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (px, single) = rows_of::<2>(pixels, "pixels")?;
        let cam = &self.inner;
        let rays = per_row(py, &px, "pixels", |p| {
            cam.unproject(&Vector2::from(*p)).map(|r| [r.x, r.y, r.z])
        })?;
        rows_to_py(py, &rays, single)
    }

    /// `(uv (N, 2), d_uv/d_point (N, 2, 3), d_uv/d_params (N, 2, 9))`; parameter
    /// columns in `CAMERA_PARAM_NAMES` order. A single point `(3,)` gives `(2,)`,
    /// `(2, 3)`, `(2, 9)`.
    #[allow(clippy::type_complexity)]
    fn project_jacobians<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let (pts, single) = rows_of::<3>(points, "points")?;
        let cam = &self.inner;
        let rows = per_row(py, &pts, "points", |p| {
            cam.project_with_jacobians(&Vector3::from(*p))
        })?;
        let n = rows.len();
        let mut uv = Vec::with_capacity(2 * n);
        let mut jp = Vec::with_capacity(6 * n);
        let mut jc = Vec::with_capacity(18 * n);
        for (u, p, c) in &rows {
            uv.extend([u.x, u.y]);
            for r in 0..2 {
                jp.extend((0..3).map(|k| p[(r, k)]));
            }
            for r in 0..2 {
                jc.extend((0..9).map(|k| c[(r, k)]));
            }
        }
        if single {
            Ok((
                nd(py, &[2], uv)?,
                nd(py, &[2, 3], jp)?,
                nd(py, &[2, 9], jc)?,
            ))
        } else {
            Ok((
                nd(py, &[n, 2], uv)?,
                nd(py, &[n, 2, 3], jp)?,
                nd(py, &[n, 2, 9], jc)?,
            ))
        }
    }

    fn __repr__(&self) -> String {
        let c = &self.inner;
        format!(
            "Camera(width={}, height={}, fu={:?}, fv={:?}, u0={:?}, v0={:?}, distortion_model='{}', distortion={:?})",
            c.width,
            c.height,
            c.fu,
            c.fv,
            c.u0,
            c.v0,
            c.model.name(),
            c.distortion
        )
    }
}
