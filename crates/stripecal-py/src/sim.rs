//! Bindings of the digital twin (`stripecal-sim`): configurations as JSON text (the
//! Python side turns them into dicts), a `Twin` class, images as numpy arrays.

use crate::pool::Detach;
use std::path::PathBuf;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use serde_json::Value;

use stripecal::model::image::{AnyGray, AnyRgb};
use stripecal_sim::profiler_write::{ProfileCounts, ProfilerSummary};
use stripecal_sim::{SimConfig, SimError, Twin, ViewRender};

use crate::convert::{f64_array, iso_to_py, json_to_py, nd, rows_of};
use crate::errors::{invalid_input, map_err};
use crate::{PyBoard, PyCamera, PyRobot, PyTruth};

fn sim_err(py: Python<'_>, e: SimError) -> PyErr {
    match e {
        SimError::Core(e) => map_err(py, e),
        SimError::Render(m) => map_err(py, stripecal::Error::Degenerate(m)),
        other => invalid_input(py, other.to_string()),
    }
}

fn parse_json(py: Python<'_>, text: &str, what: &str) -> PyResult<Value> {
    serde_json::from_str(text)
        .map_err(|e| invalid_input(py, format!("{what} is not valid JSON: {e}")))
}

/// Names of the built-in presets.
#[pyfunction]
pub fn sim_presets() -> Vec<String> {
    stripecal_sim::PRESETS
        .iter()
        .map(|s| s.to_string())
        .collect()
}

/// The full configuration of `preset` with `overrides_json` (a partial JSON object)
/// merged over it, as JSON text.
#[pyfunction]
#[pyo3(signature = (preset, overrides_json=None))]
pub fn sim_config(py: Python<'_>, preset: &str, overrides_json: Option<&str>) -> PyResult<String> {
    let mut cfg = SimConfig::preset(preset).map_err(|e| sim_err(py, e))?;
    if let Some(o) = overrides_json {
        let v = parse_json(py, o, "overrides")?;
        cfg = cfg.with_overrides(&v).map_err(|e| sim_err(py, e))?;
    }
    serde_json::to_string_pretty(&cfg).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// Signed distances (mm) of base-frame points `(N, 3)` (or one `(3,)`) to the nearest
/// true surface of `truth` (the sphere if any, the plate, the table plane):
/// `stripecal_sim::surface_errors`; `(N,)` (a float for one point).
#[pyfunction]
pub fn sim_surface_errors<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    truth: PyRef<'py, PyTruth>,
) -> PyResult<Bound<'py, PyAny>> {
    let (rows, single) = rows_of::<3>(points, "points")?;
    let pts: Vec<nalgebra::Vector3<f64>> =
        rows.iter().map(|r| nalgebra::Vector3::from(*r)).collect();
    let e = stripecal_sim::surface_errors(&truth.inner, &pts).map_err(|e| sim_err(py, e))?;
    if single {
        Ok(e[0].into_pyobject(py)?.into_any())
    } else {
        nd(py, &[e.len()], e)
    }
}

fn gray_to_py<'py>(py: Python<'py>, img: &AnyGray) -> PyResult<Bound<'py, PyAny>> {
    match img {
        AnyGray::U8(i) => nd(py, &[i.height, i.width], i.data.clone()),
        AnyGray::U16(i) => nd(py, &[i.height, i.width], i.data.clone()),
    }
}

/// An RGB image as a (rows, cols, 3) array.
fn rgb_to_py<'py>(py: Python<'py>, img: &AnyRgb) -> PyResult<Bound<'py, PyAny>> {
    match img {
        AnyRgb::U8(i) => nd(py, &[i.height, i.width, 3], i.data.clone()),
        AnyRgb::U16(i) => nd(py, &[i.height, i.width, 3], i.data.clone()),
    }
}

/// The image as rendered: RGB for a colour twin, else gray.
fn image_to_py<'py>(
    py: Python<'py>,
    rgb: &Option<AnyRgb>,
    gray: &Option<AnyGray>,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    match (rgb, gray) {
        (Some(c), _) => rgb_to_py(py, c).map(Some),
        (None, Some(g)) => gray_to_py(py, g).map(Some),
        (None, None) => Ok(None),
    }
}

fn render_to_py<'py>(py: Python<'py>, r: &ViewRender) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item(
        "board_image",
        image_to_py(py, &r.board_rgb, &r.board_image)?,
    )?;
    d.set_item(
        "laser_image",
        image_to_py(py, &r.laser_rgb, &r.laser_image)?,
    )?;
    let idx: Vec<i64> = r
        .circles
        .iter()
        .flat_map(|c| [c.row as i64, c.col as i64])
        .collect();
    let ctr: Vec<f64> = r.circles.iter().flat_map(|c| [c.u, c.v]).collect();
    let ctr_proj: Vec<f64> = r
        .circles
        .iter()
        .flat_map(|c| [c.u_center_proj, c.v_center_proj])
        .collect();
    // The imaged target points (circle centres or chessboard corners) under the
    // historical circle names and the kind-neutral ones (the same data).
    d.set_item(
        "circle_indices",
        nd(py, &[r.circles.len(), 2], idx.clone())?,
    )?;
    d.set_item(
        "circle_centers",
        nd(py, &[r.circles.len(), 2], ctr.clone())?,
    )?;
    d.set_item("target_indices", nd(py, &[r.circles.len(), 2], idx)?)?;
    d.set_item("target_points", nd(py, &[r.circles.len(), 2], ctr)?)?;
    d.set_item(
        "circle_centers_projected",
        nd(py, &[r.circles.len(), 2], ctr_proj)?,
    )?;
    let n = r.stripe.len();
    d.set_item(
        "stripe_points",
        nd(
            py,
            &[n, 2],
            r.stripe.iter().flat_map(|p| [p.u, p.v]).collect(),
        )?,
    )?;
    d.set_item(
        "stripe_points_cam",
        nd(py, &[n, 3], r.stripe.iter().flat_map(|p| p.p_cam).collect())?,
    )?;
    d.set_item(
        "stripe_surface",
        r.stripe.iter().map(|p| p.surface).collect::<Vec<_>>(),
    )?;
    d.set_item(
        "stripe_incidence_deg",
        nd(py, &[n], r.stripe.iter().map(|p| p.incidence_deg).collect())?,
    )?;
    d.set_item(
        "stripe_view_deg",
        nd(py, &[n], r.stripe.iter().map(|p| p.view_deg).collect())?,
    )?;
    d.set_item(
        "stripe_edge_mm",
        nd(py, &[n], r.stripe.iter().map(|p| p.edge_mm).collect())?,
    )?;
    d.set_item(
        "stripe_slope",
        nd(py, &[n], r.stripe.iter().map(|p| p.slope).collect())?,
    )?;
    d.set_item("base_cam", iso_to_py(py, &r.base_cam)?)?;
    Ok(d)
}

fn counts_json(c: &ProfileCounts) -> Value {
    serde_json::json!({
        "points": c.points, "sphere": c.sphere, "table": c.table, "stand": c.stand,
        "gaps": c.gaps, "dropouts": c.dropouts, "spikes": c.spikes,
    })
}

/// The profiler mode's part of `Twin.write`'s summary: per view and per scan frame the
/// point counts, per view the sphere centre in the sensor frame, and the totals.
fn profiler_summary_to_py<'py>(
    py: Python<'py>,
    p: &ProfilerSummary,
) -> PyResult<Bound<'py, PyAny>> {
    let all = p.views.iter().chain(&p.scan);
    let total = |f: fn(&ProfileCounts) -> usize| all.clone().map(f).sum::<usize>();
    let v = serde_json::json!({
        "views": p.views.iter().zip(&p.centers_sensor_mm).map(|(c, x)| {
            let mut o = counts_json(c);
            o["sphere_center_sensor_mm"] = serde_json::json!(x);
            o
        }).collect::<Vec<_>>(),
        "scan": p.scan.iter().map(counts_json).collect::<Vec<_>>(),
        "points": total(|c| c.points),
        "sphere_points": total(|c| c.sphere),
        "gaps": total(|c| c.gaps),
        "spikes": total(|c| c.spikes),
    });
    json_to_py(py, &v)
}

fn joints(py: Python<'_>, q: &Bound<'_, PyAny>, dof: usize) -> PyResult<Vec<f64>> {
    let a = f64_array(q, "q")?;
    if a.shape() != [dof] {
        return Err(invalid_input(
            py,
            format!("q must have shape ({dof},), got {:?}", a.shape()),
        ));
    }
    Ok(a.iter().copied().collect())
}

/// The digital twin of one rig, built from a configuration (JSON text).
#[pyclass(name = "Twin", module = "stripecal._core", frozen)]
pub struct PyTwin {
    inner: Twin,
}

#[pymethods]
impl PyTwin {
    #[new]
    fn new(py: Python<'_>, config_json: &str) -> PyResult<Self> {
        let v = parse_json(py, config_json, "config")?;
        let cfg: SimConfig = serde_json::from_value(v)
            .map_err(|e| invalid_input(py, format!("invalid twin configuration: {e}")))?;
        let inner = py
            .detach_pool(|| Twin::new(cfg))
            .map_err(|e| sim_err(py, e))?;
        Ok(PyTwin { inner })
    }

    /// The configuration as JSON text.
    #[getter]
    fn config_json(&self) -> PyResult<String> {
        serde_json::to_string_pretty(&self.inner.cfg)
            .map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// The true camera.
    #[getter]
    fn camera(&self) -> PyCamera {
        PyCamera::new_py(self.inner.camera.clone())
    }

    /// The board.
    #[getter]
    fn board(&self) -> PyBoard {
        PyBoard::new_py(self.inner.board.clone())
    }

    /// The nominal robot (what rig.json holds).
    #[getter]
    fn robot_nominal(&self) -> PyRobot {
        PyRobot::new_py(self.inner.robot_nominal.clone())
    }

    /// The true robot (nominal plus DH errors).
    #[getter]
    fn robot_true(&self) -> PyRobot {
        PyRobot::new_py(self.inner.robot_true.clone())
    }

    /// True `T_hand_cam`, (4, 4).
    #[getter]
    fn hand_cam<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        iso_to_py(py, &self.inner.hand_cam)
    }

    /// True `T_base_board`, (4, 4).
    #[getter]
    fn base_board<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        iso_to_py(py, &self.inner.base_board)
    }

    /// True laser plane `(normal (3,), d_mm)` in the camera frame.
    #[getter]
    fn laser_plane<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, f64)> {
        let p = self.inner.laser_plane;
        Ok((nd(py, &[3], vec![p.normal.x, p.normal.y, p.normal.z])?, p.d))
    }

    /// `rows` or `cols`: how the stripe runs in the images.
    #[getter]
    fn stripe_direction(&self) -> &'static str {
        self.inner.direction.name()
    }

    /// The true parameters (scan truth includes the sphere).
    #[pyo3(signature = (with_sphere=true))]
    fn truth(&self, with_sphere: bool) -> PyTruth {
        PyTruth {
            inner: self.inner.truth(with_sphere),
        }
    }

    /// Calibration poses: a list of dicts `{q_deg, standoff_mm, tilt_deg, stripe_chord_mm}`.
    fn calibration_poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let poses = py
            .detach_pool(|| self.inner.calibration_poses())
            .map_err(|e| sim_err(py, e))?;
        let out = PyList::empty(py);
        for p in poses {
            let d = PyDict::new(py);
            d.set_item("q_deg", nd(py, &[p.q_deg.len()], p.q_deg.clone())?)?;
            d.set_item("standoff_mm", p.standoff_mm)?;
            d.set_item("tilt_deg", p.tilt_deg)?;
            d.set_item("stripe_chord_mm", p.stripe_chord_mm)?;
            out.append(d)?;
        }
        Ok(out)
    }

    /// The bench mode's board poses (`bench.*`): a list of dicts `{cam_board (4, 4),
    /// standoff_mm, tilt_deg, partial, sag_mm, bow_axis_deg (None when flat),
    /// floor_normal ((3,) or None), floor_d_mm (or None)}`.
    fn bench_views<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let views = py
            .detach_pool(|| self.inner.bench_views())
            .map_err(|e| sim_err(py, e))?;
        let axis = self.inner.cfg.bench.bow.axis_deg;
        let out = PyList::empty(py);
        for v in views {
            let d = PyDict::new(py);
            d.set_item("cam_board", iso_to_py(py, &v.cam_board)?)?;
            d.set_item("standoff_mm", v.standoff_mm)?;
            d.set_item("tilt_deg", v.tilt_deg)?;
            d.set_item("partial", v.partial)?;
            d.set_item("sag_mm", v.bow.map_or(0.0, |b| b.sag_mm))?;
            d.set_item("bow_axis_deg", v.bow.map(|_| axis))?;
            d.set_item(
                "floor_normal",
                v.floor
                    .map(|(n, _)| nd(py, &[3], vec![n.x, n.y, n.z]))
                    .transpose()?,
            )?;
            d.set_item("floor_d_mm", v.floor.map(|(_, dd)| dd))?;
            out.append(d)?;
        }
        Ok(out)
    }

    /// Encoder readings of the scan sweep, (N, J).
    fn scan_poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let qs = py
            .detach_pool(|| self.inner.scan_poses())
            .map_err(|e| sim_err(py, e))?;
        let dof = self.inner.robot_true.dof();
        nd(py, &[qs.len(), dof], qs.into_iter().flatten().collect())
    }

    /// Encoder readings of the bare-table sweep (`scan.table`), (N, J); (0, J) without.
    fn table_scan_poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let qs = py
            .detach_pool(|| self.inner.table_scan_poses())
            .map_err(|e| sim_err(py, e))?;
        let dof = self.inner.robot_true.dof();
        nd(py, &[qs.len(), dof], qs.into_iter().flatten().collect())
    }

    /// The verification scans (`verify.*`, written to `verify/` when enabled): one dict
    /// per scan with `name`, `artefact`, `poses` (N, J), `spheres` (bars: A and B,
    /// `center_mm` and `diameter_mm`, base frame) and `plane` (plates: `normal`, `d_mm`,
    /// base frame; None for bars).
    fn verify_scans<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let scans = py
            .detach_pool(|| self.inner.verify_scans())
            .map_err(|e| sim_err(py, e))?;
        let dof = self.inner.robot_true.dof();
        let out = PyList::empty(py);
        for s in scans {
            let d = PyDict::new(py);
            d.set_item("name", &s.name)?;
            d.set_item("artefact", &s.artefact)?;
            d.set_item("poses", nd(py, &[s.poses.len(), dof], s.poses.concat())?)?;
            let sph: Vec<Value> = s
                .spheres
                .iter()
                .map(|p| serde_json::json!({"center_mm": [p.center_mm.x, p.center_mm.y, p.center_mm.z], "diameter_mm": p.diameter_mm}))
                .collect();
            d.set_item("spheres", json_to_py(py, &Value::Array(sph))?)?;
            d.set_item(
                "plane",
                s.plane
                    .map(|p| json_to_py(py, &serde_json::json!({"normal": [p.normal.x, p.normal.y, p.normal.z], "d_mm": p.d})))
                    .transpose()?,
            )?;
            out.append(d)?;
        }
        Ok(out)
    }

    /// Renders a calibration view at encoder readings `q` (degrees): a dict with
    /// `board_image`, `laser_image` (None in single-image mode), circle and stripe truth.
    #[pyo3(signature = (q, index=0))]
    fn render_view<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        index: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        let q = joints(py, q, self.inner.robot_true.dof())?;
        let r = py
            .detach_pool(|| self.inner.render_view(&q, index))
            .map_err(|e| sim_err(py, e))?;
        render_to_py(py, &r)
    }

    /// Renders a scan frame (stripe image with the sphere) at `q`.
    #[pyo3(signature = (q, index=0))]
    fn render_scan_frame<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        index: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        let q = joints(py, q, self.inner.robot_true.dof())?;
        let r = py
            .detach_pool(|| self.inner.render_scan_frame(&q, index))
            .map_err(|e| sim_err(py, e))?;
        render_to_py(py, &r)
    }

    /// Renders and writes `out/calib` (and `out/scan`). `progress(stage, done, total)`
    /// is called between images. Returns a summary dict.
    #[pyo3(signature = (out, progress=None))]
    fn write<'py>(
        &self,
        py: Python<'py>,
        out: PathBuf,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mut cb_err: Option<PyErr> = None;
        // on this thread (not the pool's), as every call with a progress callback
        let result = py.detach(|| {
            let mut cb = |stage: &str, done: usize, total: usize| {
                if let (Some(f), None) = (&progress, &cb_err) {
                    Python::attach(|py| {
                        if let Err(e) = f.call1(py, (stage, done, total)) {
                            cb_err = Some(e);
                        }
                    });
                }
            };
            self.inner.write(&out, &mut cb)
        });
        if let Some(e) = cb_err {
            return Err(e);
        }
        let s = result.map_err(|e| sim_err(py, e))?;
        let d = PyDict::new(py);
        d.set_item("calib_dir", s.calib_dir)?;
        d.set_item("scan_dir", s.scan_dir)?;
        let views = PyList::empty(py);
        for (i, v) in s.views.iter().enumerate() {
            let vd = PyDict::new(py);
            vd.set_item("q_deg", nd(py, &[v.q_deg.len()], v.q_deg.clone())?)?;
            vd.set_item("standoff_mm", v.standoff_mm)?;
            vd.set_item("tilt_deg", v.tilt_deg)?;
            vd.set_item("stripe_chord_mm", v.stripe_chord_mm)?;
            vd.set_item("circles_visible", s.view_circles[i])?;
            vd.set_item("stripe_points_on_board", s.view_stripe_points[i])?;
            views.append(vd)?;
        }
        d.set_item("views", views)?;
        d.set_item("circles_total", self.inner.board.len())?;
        d.set_item("board_kind", self.inner.board.kind.name())?;
        d.set_item("scan_frames", s.scan_frames)?;
        d.set_item("scan_sphere_points", s.scan_sphere_points)?;
        d.set_item("table_dir", s.table_dir)?;
        d.set_item("table_frames", s.table_frames)?;
        d.set_item("verify_dir", s.verify_dir)?;
        d.set_item("verify_frames", s.verify_frames)?;
        d.set_item("stripe_direction", s.direction.name())?;
        d.set_item(
            "profiler",
            s.profiler
                .as_ref()
                .map(|p| profiler_summary_to_py(py, p))
                .transpose()?,
        )?;
        d.set_item(
            "sphere",
            self.inner
                .sphere
                .map(|sp| json_to_py(py, &serde_json::json!({"center_mm": [sp.center_mm.x, sp.center_mm.y, sp.center_mm.z], "diameter_mm": sp.diameter_mm})))
                .transpose()?,
        )?;
        Ok(d)
    }
}
