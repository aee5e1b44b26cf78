//! `stripecal.Robot`.

use crate::pool::Detach;
use pyo3::prelude::*;
use stripecal::model::kinematics::{DhJoint, IkOptions, Robot};
use stripecal::Error;

use crate::convert::{f64_array, fmt_shape, iso_to_py, isos_to_py, nd, py_to_iso};
use crate::errors::{invalid_input, map_err_at, ResultExt};

/// A serial robot from its DH table: `A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)
/// Ry(beta_i)` with `theta_i = q_i - theta0_i` (degrees), `T_base_hand = A_1 ... A_N`;
/// rows `(theta0_deg, alpha_deg, a_mm, d_mm)` or with Hayati's `beta_deg` fifth (0 when
/// absent: standard DH);
/// optionally the maker's figures `repeatability_mm` and `encoder_sigma_deg` (rig.json),
/// lower bounds of the robot-pose noise the calibration estimates.
#[pyclass(name = "Robot", module = "stripecal", frozen, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyRobot {
    pub inner: Robot,
}

impl PyRobot {
    pub fn new_py(inner: Robot) -> Self {
        PyRobot { inner }
    }

    /// Joint readings `(dof,)` (single) or `(M, dof)`.
    fn readings(&self, py: Python<'_>, q: &Bound<'_, PyAny>) -> PyResult<(Vec<Vec<f64>>, bool)> {
        let a = f64_array(q, "q")?;
        let dof = self.inner.dof();
        match a.shape() {
            [n] if *n == dof => Ok((vec![a.iter().copied().collect()], true)),
            [_, n] if *n == dof => Ok((
                a.outer_iter()
                    .map(|r| r.iter().copied().collect())
                    .collect(),
                false,
            )),
            s => Err(invalid_input(
                py,
                format!(
                    "q must have shape ({dof},) or (M, {dof}) for robot {:?}, got {}",
                    self.inner.name,
                    fmt_shape(s)
                ),
            )),
        }
    }
}

#[pymethods]
impl PyRobot {
    #[new]
    #[pyo3(signature = (joints, name = "robot", *, repeatability_mm = None, encoder_sigma_deg = None))]
    fn new(
        py: Python<'_>,
        joints: &Bound<'_, PyAny>,
        name: &str,
        repeatability_mm: Option<f64>,
        encoder_sigma_deg: Option<f64>,
    ) -> PyResult<Self> {
        let a = f64_array(joints, "joints")?;
        if a.ndim() != 2 || !(a.shape()[1] == 4 || a.shape()[1] == 5) {
            return Err(invalid_input(
                py,
                format!(
                    "joints must have shape (N, 4) or (N, 5): rows (theta0_deg, alpha_deg, a_mm, d_mm[, beta_deg]), got {}",
                    fmt_shape(a.shape())
                ),
            ));
        }
        let rows = a
            .outer_iter()
            .map(|r| DhJoint {
                theta0_deg: r[0],
                alpha_deg: r[1],
                a_mm: r[2],
                d_mm: r[3],
                beta_deg: r.get(4).copied().unwrap_or(0.0),
            })
            .collect();
        Robot::new(name, rows)
            .and_then(|r| r.with_figures(repeatability_mm, encoder_sigma_deg))
            .py_err(py)
            .map(PyRobot::new_py)
    }

    /// The MOTOMAN HP3 of the paper (Table 1 as corrected in ERRATA.md).
    #[staticmethod]
    fn hp3() -> Self {
        PyRobot::new_py(Robot::hp3())
    }

    /// The robot's name.
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }

    /// The maker's pose repeatability, mm, or None.
    #[getter]
    fn repeatability_mm(&self) -> Option<f64> {
        self.inner.repeatability_mm
    }

    /// One-sigma of a joint reading, degrees, or None.
    #[getter]
    fn encoder_sigma_deg(&self) -> Option<f64> {
        self.inner.encoder_sigma_deg
    }

    /// Number of joints.
    #[getter]
    fn dof(&self) -> usize {
        self.inner.dof()
    }

    /// The DH table, shape (N, 4): `theta0_deg, alpha_deg, a_mm, d_mm` per joint.
    #[getter]
    fn dh<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let data = self
            .inner
            .joints
            .iter()
            .flat_map(|j| [j.theta0_deg, j.alpha_deg, j.a_mm, j.d_mm])
            .collect();
        nd(py, &[self.inner.dof(), 4], data)
    }

    /// Hayati's tilt of each row about its new y axis, shape (N,), degrees (0 for a
    /// standard DH row).
    #[getter]
    fn beta_deg<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let data = self.inner.joints.iter().map(|j| j.beta_deg).collect();
        nd(py, &[self.inner.dof()], data)
    }

    /// `T_base_hand` for encoder readings in degrees: q `(dof,)` -> `(4, 4)`,
    /// q `(M, dof)` -> `(M, 4, 4)`.
    fn forward<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let (qs, single) = self.readings(py, q)?;
        let robot = &self.inner;
        let ts: Result<Vec<_>, (usize, Error)> = py.detach_pool(|| {
            qs.iter()
                .enumerate()
                .map(|(i, q)| robot.forward(q).map_err(|e| (i, e)))
                .collect()
        });
        let ts = ts.map_err(|(i, e)| {
            let ctx = if single {
                "q".to_string()
            } else {
                format!("q[{i}]")
            };
            map_err_at(py, e, &ctx)
        })?;
        if single {
            iso_to_py(py, &ts[0])
        } else {
            isos_to_py(py, &ts)
        }
    }

    /// The geometric Jacobian at q `(dof,)`: shape (6, dof), rows `[v; w]` of the flange
    /// origin (mm/rad, rad/rad) per radian of encoder reading.
    fn jacobian<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let (qs, single) = self.readings(py, q)?;
        if !single {
            return Err(invalid_input(
                py,
                format!("q must have shape ({},)", self.inner.dof()),
            ));
        }
        let j = self.inner.jacobian(&qs[0]).py_err(py)?;
        let n = j.ncols();
        nd(py, &[6, n], (0..6 * n).map(|i| j[(i / n, i % n)]).collect())
    }

    /// Encoder readings (degrees, shape (dof,)) that put the flange at `T_base_hand`
    /// (4, 4), by damped least squares from `q0` (staying on its branch). Raises
    /// ConvergenceError when the pose is not reached.
    fn inverse<'py>(
        &self,
        py: Python<'py>,
        t_base_hand: &Bound<'py, PyAny>,
        q0: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let target = py_to_iso(t_base_hand, "T_base_hand")?;
        let (q0s, single) = self.readings(py, q0)?;
        if !single {
            return Err(invalid_input(
                py,
                format!("q0 must have shape ({},)", self.inner.dof()),
            ));
        }
        let robot = &self.inner;
        let q = py
            .detach_pool(|| robot.inverse(&target, &q0s[0], &IkOptions::default()))
            .py_err(py)?;
        nd(py, &[q.len()], q)
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot(name={}, dof={})",
            crate::convert::quote(&self.inner.name),
            self.inner.dof()
        )
    }
}
