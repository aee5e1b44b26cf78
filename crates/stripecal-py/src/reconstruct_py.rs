//! `stripecal.reconstruct`, `stripecal.reconstruct_scan`, `stripecal.triangulate`,
//! `stripecal.fit_sphere`, `stripecal.fit_plane`, `stripecal.Cloud`,
//! `stripecal.PlaneFit`: stripe images + joints -> points in the robot base frame, and
//! measurements in them. Conversions only; the GIL is released while Rust works.

use crate::pool::Detach;
use std::path::PathBuf;

use nalgebra::Vector3;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PySequence, PyTuple};

use crate::args::{bind_as, Params};

use stripecal::io::{write_ply_with_comments, PlyFormat};
use stripecal::model::image::AnyImage;
use stripecal::model::RobotReading;
use stripecal::pipeline::measure::{scan_readings, scan_uncertainty_model};
use stripecal::reconstruct::{
    self as core, BadImage, FitOptions, PlaneFit, ReconstructOptions, ScanPoints,
    UncertaintyOptions,
};
use stripecal::vision::stripe::{colour, StripeChannel, StripeDirection};

use crate::convert::{f64_array, fmt_shape, nd, progress_step, py_to_iso};
use crate::errors::{invalid_input, ResultExt};
use crate::imageview::image_from_py;
use crate::profile_py::PyProfilerCalibration;
use crate::results::PyCalibration;
use crate::sphere_fit::PySphereFit;

/// Reconstructed points: `points` (M, 3) float64 mm in the robot base frame, and per
/// point the frame index, the image position `u`, `v` (px) and the stripe `intensity`
/// (peak above the local background, gray levels) and its `flags` (`Stripe` flag bits).
#[pyclass(name = "Cloud", module = "stripecal", frozen)]
pub struct PyCloud {
    pub inner: ScanPoints,
}

#[pymethods]
impl PyCloud {
    /// `(M, 3)` float64: points in the robot base frame, mm.
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = &self.inner.points_mm;
        nd(py, &[p.len(), 3], p.iter().flatten().copied().collect())
    }

    /// The frame of the points: `"cam"` for a fixed-sensor scan (no poses), else
    /// `"base"` (the PLY header's `comment frame ...`).
    #[getter]
    fn coordinate_frame(&self) -> &'static str {
        if self.inner.camera_frame {
            "cam"
        } else {
            "base"
        }
    }

    /// `(M,)` int64: index of the frame (image) each point comes from.
    #[getter]
    fn frame<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let f = &self.inner.frame;
        nd(py, &[f.len()], f.iter().map(|&x| x as i64).collect())
    }

    /// `(M,)` float64: image column of the stripe point, px.
    #[getter]
    fn u<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(py, &[self.inner.u_px.len()], self.inner.u_px.clone())
    }

    /// `(M,)` float64: image row of the stripe point, px.
    #[getter]
    fn v<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(py, &[self.inner.v_px.len()], self.inner.v_px.clone())
    }

    /// `(M,)` float64: stripe peak above the local background, gray levels.
    #[getter]
    fn intensity<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let i = &self.inner.intensity;
        nd(py, &[i.len()], i.iter().map(|&x| x as f64).collect())
    }

    /// `(M,)` float64: the stripe's full width at half maximum across the line, px.
    #[getter]
    fn width<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let w = &self.inner.width_px;
        nd(py, &[w.len()], w.iter().map(|&x| x as f64).collect())
    }

    /// `(M, 3, 3)` float64: each point's covariance in the base frame, mm^2 (`None` unless
    /// the scan was reconstructed with `covariance=True`).
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let c = &self.inner.covariance_mm2;
        if c.is_empty() || c.len() != self.inner.len() {
            return Ok(None);
        }
        let data = c
            .iter()
            .flat_map(|v| [v[0], v[1], v[2], v[1], v[3], v[4], v[2], v[4], v[5]])
            .collect();
        nd(py, &[c.len(), 3, 3], data).map(Some)
    }

    /// `(M,)` uint8: the stripe point's flag bits (`Stripe.SATURATED`, ...).
    #[getter]
    fn flags<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(py, &[self.inner.flags.len()], self.inner.flags.clone())
    }

    /// Points dropped, by reason: `grazing` (rays meeting the laser plane at less than
    /// the angle threshold, or behind the camera), `undistort` (outside the distortion
    /// model's valid zone), `flagged` (by `drop_flags`).
    #[getter]
    fn dropped<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let c = self.inner.dropped;
        d.set_item("grazing", c.grazing)?;
        d.set_item("undistort", c.undistort)?;
        d.set_item("flagged", c.flagged)?;
        Ok(d)
    }

    /// Frames left out because their image could not be used (`reconstruct_scan` with
    /// `on_bad_image="skip"`), in frame order: a list of dicts with `frame` (index, from
    /// 0), `line` (its scan.csv line), `path` (the image file) and `reason`.
    #[getter]
    fn skipped_frames<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let out = PyList::empty(py);
        for b in &self.inner.skipped {
            let d = PyDict::new(py);
            d.set_item("frame", b.frame)?;
            d.set_item("line", b.line)?;
            d.set_item("path", b.path.display().to_string())?;
            d.set_item("reason", b.reason.as_str())?;
            out.append(d)?;
        }
        Ok(out)
    }

    /// Writes a PLY file (binary little-endian, or ASCII with `ascii=True`): double
    /// `x y z` (mm) and the properties `view` (frame index), `u`, `v`, `intensity`,
    /// `flags`. The header records the skipped frames: `comment skipped_frames N`, then
    /// one `comment skipped frame ...` line each. Written atomically (a temporary file in
    /// the same folder renamed over `path`): `path` is complete or untouched.
    #[pyo3(signature = (path, ascii = false))]
    fn save(&self, py: Python<'_>, path: PathBuf, ascii: bool) -> PyResult<()> {
        let f = if ascii {
            PlyFormat::Ascii
        } else {
            PlyFormat::BinaryLittleEndian
        };
        let inner = &self.inner;
        py.detach_pool(|| {
            write_ply_with_comments(&path, &inner.to_cloud(), f, &inner.ply_comments())
        })
        .py_err(py)
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        let frames = self
            .inner
            .frame
            .iter()
            .max()
            .map(|&m| m as usize + 1)
            .unwrap_or(0);
        format!(
            "Cloud(points={}, frames={frames}, dropped={}, skipped_frames={})",
            self.inner.len(),
            self.inner.dropped.total(),
            self.inner.skipped.len()
        )
    }
}

fn options(
    py: Python<'_>,
    direction: &str,
    min_ray_plane_angle_deg: f64,
    drop_flags: u8,
) -> PyResult<ReconstructOptions> {
    let mut o = ReconstructOptions {
        min_ray_plane_angle_deg,
        drop_flags,
        ..ReconstructOptions::default()
    };
    o.stripe.direction = StripeDirection::from_name(direction).py_err(py)?;
    o.validate().py_err(py)?;
    Ok(o)
}

/// Reconstructs stripe images taken at joint readings: `images` (N, H, W) uint8/uint16
/// (or (N, H, W, 3) colour, or a sequence of N 2D or (H, W, 3 or 4) arrays), `joints`
/// (N, J) encoder readings in degrees (J = the calibration robot's joints). Every image
/// must have the calibrated camera's size. `direction`: "auto" (from the laser plane),
/// "rows" or "cols". `channel`: the signal the stripe is found in ("gray", "red",
/// "green", "blue", or "auto": decided once from at most 5 of the images; see
/// `extract_stripe`). Rays meeting the laser plane at less than
/// `min_ray_plane_angle_deg` are dropped; so are stripe points with any of the
/// `drop_flags` bits. Runs in parallel with the GIL released. Errors name the frame.
#[pyfunction]
#[pyo3(signature = (calibration, images, joints, direction = "auto", min_ray_plane_angle_deg = 2.0, drop_flags = 0, channel = "gray"))]
pub fn reconstruct(
    calibration: &Bound<'_, PyCalibration>,
    images: &Bound<'_, PyAny>,
    joints: &Bound<'_, PyAny>,
    direction: &str,
    min_ray_plane_angle_deg: f64,
    drop_flags: u8,
    channel: &str,
) -> PyResult<PyCloud> {
    let py = calibration.py();
    let opts = options(py, direction, min_ray_plane_angle_deg, drop_flags)?;
    let channel = StripeChannel::from_name(channel).py_err(py)?;
    let q = f64_array(joints, "joints")?;
    if q.ndim() != 2 {
        return Err(invalid_input(
            py,
            format!(
                "joints must have shape (N, J), got {}",
                fmt_shape(q.shape())
            ),
        ));
    }
    let n = q.shape()[0];
    let seq = images.cast::<PySequence>().ok();
    let len = match (images.getattr("shape"), &seq) {
        (Ok(s), _) => {
            let s: Vec<usize> = s.extract()?;
            if !(s.len() == 3 || s.len() == 4) {
                return Err(invalid_input(
                    py,
                    format!(
                        "images must have shape (N, H, W) or (N, H, W, 3), got {}",
                        fmt_shape(&s)
                    ),
                ));
            }
            s[0]
        }
        (Err(_), Some(s)) => s.len()?,
        _ => {
            return Err(pyo3::exceptions::PyTypeError::new_err(
                "images must be a (N, H, W) uint8/uint16 array or a sequence of 2D arrays",
            ))
        }
    };
    if len != n {
        return Err(invalid_input(
            py,
            format!("{len} images but {n} rows of joints: images and joints pair by row"),
        ));
    }
    let mut imgs: Vec<AnyImage> = Vec::with_capacity(n);
    for i in 0..n {
        let item = images.get_item(i)?;
        let img = image_from_py(&item, &format!("images[{i}]"))?;
        if !img.is_colour() && channel.rgb_index().is_some() {
            return Err(invalid_input(
                py,
                format!(
                    "channel {:?} needs colour images (H, W, 3 or 4): images[{i}] is gray \
                     (2D); use channel=\"gray\" or \"auto\"",
                    channel.name()
                ),
            ));
        }
        imgs.push(img);
    }
    let readings: Vec<RobotReading> = q
        .rows()
        .into_iter()
        .map(|r| RobotReading::Joints(r.to_vec()))
        .collect();
    let cal = &calibration.get().inner;
    let sp = py
        .detach_pool(|| -> stripecal::Result<ScanPoints> {
            let channel = if channel == StripeChannel::Auto {
                let scores = colour::auto_sample(imgs.len())
                    .into_iter()
                    .map(|i| colour::channel_scores(&imgs[i], &opts.stripe))
                    .collect::<stripecal::Result<Vec<_>>>()?;
                colour::choose_channel(&scores)
            } else {
                channel
            };
            let signals = imgs
                .iter()
                .map(|i| colour::stripe_signal(i, channel, &opts.stripe))
                .collect::<stripecal::Result<Vec<_>>>()?;
            let views = signals
                .iter()
                .map(|i| i.view())
                .collect::<stripecal::Result<Vec<_>>>()?;
            core::reconstruct_frames(cal, &views, &readings, &opts)
        })
        .py_err(py)?;
    Ok(PyCloud { inner: sp })
}

/// `reconstruct_scan`'s parameters (see [`bind_as`]).
const RECONSTRUCT_SCAN: Params = Params {
    name: "reconstruct_scan",
    positional: &[
        "calibration",
        "scan_dir",
        "direction",
        "min_ray_plane_angle_deg",
        "drop_flags",
        "progress",
        "on_bad_image",
        "covariance",
        "stripe_sigma_px",
        "repeatability_mm",
        "encoder_sigma_deg",
        "channel",
    ],
    required: 2,
    keyword: &[],
};

/// `reconstruct_scan`'s arguments, with their defaults.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct ScanArgs<'py> {
    calibration: Bound<'py, PyAny>,
    scan_dir: PathBuf,
    #[pyo3(default = "auto".into())]
    direction: String,
    #[pyo3(default = 2.0)]
    min_ray_plane_angle_deg: f64,
    #[pyo3(default)]
    drop_flags: u8,
    #[pyo3(default)]
    progress: Option<Py<PyAny>>,
    #[pyo3(default = "stop".into())]
    on_bad_image: String,
    #[pyo3(default)]
    covariance: bool,
    #[pyo3(default)]
    stripe_sigma_px: Option<f64>,
    #[pyo3(default)]
    repeatability_mm: Option<f64>,
    #[pyo3(default)]
    encoder_sigma_deg: Option<f64>,
    #[pyo3(default)]
    channel: Option<String>,
}

/// Reconstructs a scan folder (scan.csv + images, spec/DATASET.md) with a calibration.
/// `direction` "auto" takes the scan's rig.json hint, else the laser plane's.
///
/// `on_bad_image`: what to do with a frame whose image cannot be used (missing or
/// unreadable, truncated or corrupted, not the calibrated camera's size, or another bit
/// depth than most of the scan's frames). `"stop"` (default): raise `BadImageError`
/// (a `FormatError`) naming the frame, its scan.csv line, the file and what is wrong;
/// nothing is returned. `"skip"`: leave the frame out and list it in the cloud's
/// `skipped_frames`. A frame that shows no stripe is not a bad image (it gives no
/// points).
///
/// `progress(frames_done, frames_total, points)` is called before the first chunk of
/// frames and after each one. Between chunks the run also checks for signals: Ctrl-C
/// (or an exception raised by `progress`) stops it there and propagates
/// (`KeyboardInterrupt`); nothing is returned. The GIL is released while frames are
/// processed.
///
/// `channel`: the signal of colour frames the stripe is found in ("gray", "red",
/// "green", "blue" or "auto", see `extract_stripe`); None (default): the scan's rig.json
/// `stripe.channel`, gray without one. A colour name with a gray frame is a
/// `FormatError` naming the file.
///
/// `covariance=True` also computes each point's 3x3 covariance in the base frame
/// (`Cloud.covariance`, (M, 3, 3) mm^2) from the calibration's covariance, the stripe's
/// noise (`stripe_sigma_px`; default the calibration's `quality.stripe_rms_px`) and the
/// robot's figures (`repeatability_mm`, `encoder_sigma_deg`; default those of the
/// calibration's robot, if any).
#[pyfunction]
#[pyo3(signature = (*args, **kwargs), text_signature = "(calibration, scan_dir, direction=\"auto\", min_ray_plane_angle_deg=2.0, drop_flags=0, progress=None, on_bad_image=\"stop\", covariance=False, stripe_sigma_px=None, repeatability_mm=None, encoder_sigma_deg=None, channel=None)")]
pub fn reconstruct_scan(
    py: Python<'_>,
    args: &Bound<'_, PyTuple>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<PyCloud> {
    let ScanArgs {
        calibration,
        scan_dir,
        direction,
        min_ray_plane_angle_deg,
        drop_flags,
        progress,
        on_bad_image,
        covariance,
        stripe_sigma_px,
        repeatability_mm,
        encoder_sigma_deg,
        channel,
    } = bind_as(&RECONSTRUCT_SCAN, args, kwargs)?;
    let (calibration, direction, on_bad_image, channel) = (
        &calibration,
        direction.as_str(),
        on_bad_image.as_str(),
        channel.as_deref(),
    );
    let unc = UncertaintyOptions {
        stripe_sigma_px,
        repeatability_mm,
        encoder_sigma_deg,
        ..Default::default()
    };
    if let Ok(pc) = calibration.cast::<PyProfilerCalibration>() {
        // A line profiler's scan: points from the profiles (no stripe options apply).
        let cal = &pc.get().inner;
        let on_bad = BadImage::from_name(on_bad_image).py_err(py)?;
        let result = py.detach_pool(|| -> stripecal::Result<(ScanPoints, usize)> {
            let ropts = stripecal::reconstruct::ProfileReconstructOptions {
                on_bad_frame: on_bad,
                ..Default::default()
            };
            // the cloud's frame numbers are scan.csv's rows: skipped frames keep their
            // places as empty profiles
            let (all, summary) =
                stripecal::reconstruct::load_profile_frames(&scan_dir, cal.robot.as_ref(), &ropts)?;
            let mut points = stripecal::reconstruct::profile_scan_points(&all, cal)?;
            points.skipped = summary.skipped;
            if covariance {
                let model = stripecal::pipeline::measure::profiler_uncertainty_model(cal, &unc)?;
                let readings: Vec<_> = all.iter().map(|f| f.0.clone()).collect();
                points.covariance_mm2 = model.scan_covariances(&readings, &points)?;
            }
            Ok((points, all.len()))
        });
        let (inner, n) = result.py_err(py)?;
        if let Some(cb) = &progress {
            cb.call1(py, (n, n, inner.len()))?;
        }
        py.check_signals()?;
        return Ok(PyCloud { inner });
    }
    let calibration = calibration
        .cast::<PyCalibration>()
        .map_err(|_| crate::convert::not_a_calibration(calibration))?;
    let mut opts = options(py, direction, min_ray_plane_angle_deg, drop_flags)?;
    opts.on_bad_image = BadImage::from_name(on_bad_image).py_err(py)?;
    opts.channel = channel
        .map(|c| StripeChannel::from_name(c).py_err(py))
        .transpose()?;
    let cal = &calibration.get().inner;
    // The first error of the callback (an exception of `progress`, or the pending
    // KeyboardInterrupt of a signal); it stops the run and is what is raised.
    let mut cb_err: Option<PyErr> = None;
    // on this thread (not the pool's): the callback checks for signals, which Python
    // delivers to its main thread only
    let result = py.detach(|| {
        let scan = core::load_scan(&scan_dir, cal)?;
        let mut cb = |done: usize, total: usize, points: usize| {
            progress_step(&progress, &mut cb_err, (done, total, points))
        };
        let mut points = core::reconstruct_scan(cal, &scan, &opts, &mut cb)?;
        if covariance {
            let model = scan_uncertainty_model(cal, &scan, &unc)?;
            points.covariance_mm2 = model.scan_covariances(&scan_readings(&scan), &points)?;
        }
        Ok(points)
    });
    if let Some(e) = cb_err {
        return Err(e);
    }
    let inner = result.py_err(py)?;
    // A signal that arrived after the last check is not lost: nothing is returned.
    py.check_signals()?;
    Ok(PyCloud { inner })
}

fn points_from_py(py: Python<'_>, points: &Bound<'_, PyAny>) -> PyResult<Vec<[f64; 3]>> {
    let a = f64_array(points, "points")?;
    if a.ndim() != 2 || a.shape()[1] != 3 {
        return Err(invalid_input(
            py,
            format!(
                "points must have shape (N, 3), got {}",
                fmt_shape(a.shape())
            ),
        ));
    }
    Ok(a.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

/// Triangulates stripe pixels `uv` (N, 2) of one frame taken at `base_hand` (4, 4)
/// (`T_base_hand`): `(points (M, 3) mm base frame, index (M,) into uv)`; pixels whose ray
/// meets the laser plane at less than 2 degrees (or behind the camera) are dropped.
#[pyfunction]
pub fn triangulate<'py>(
    py: Python<'py>,
    calibration: &Bound<'py, PyCalibration>,
    uv: &Bound<'py, PyAny>,
    base_hand: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let a = f64_array(uv, "uv")?;
    if a.ndim() != 2 || a.shape()[1] != 2 {
        return Err(invalid_input(
            py,
            format!("uv must have shape (N, 2), got {}", fmt_shape(a.shape())),
        ));
    }
    let uv: Vec<[f64; 2]> = a.rows().into_iter().map(|r| [r[0], r[1]]).collect();
    let t = py_to_iso(base_hand, "base_hand")?;
    let cal = &calibration.get().inner;
    let (pts, idx) = py
        .detach_pool(|| core::triangulate(cal, &t, &uv))
        .py_err(py)?;
    Ok((
        nd(py, &[pts.len(), 3], pts.iter().flatten().copied().collect())?,
        nd(py, &[idx.len()], idx.iter().map(|&i| i as i64).collect())?,
    ))
}

fn fit_options(
    py: Python<'_>,
    trim_sigma: f64,
    diameter_range_mm: Option<(f64, f64)>,
) -> PyResult<FitOptions> {
    let o = FitOptions {
        trim_sigma,
        diameter_range_mm: diameter_range_mm.map(|(a, b)| [a, b]),
        ..FitOptions::default()
    };
    // Validated by the fit; reject obviously bad values early with the same error type.
    if !trim_sigma.is_finite() {
        return Err(invalid_input(py, "trim_sigma must be finite"));
    }
    Ok(o)
}

/// Fits a sphere to `points` (N, 3) mm: robust start (so other surfaces in the cloud,
/// e.g. the table, are ignored), geometric least squares, outliers beyond `trim_sigma`
/// robust sigmas trimmed (0: no trimming). `diameter_range_mm` (min, max) limits the
/// candidate spheres of the robust start. The result's `extra` holds the fit's one-sigma
/// `fit_diameter_sigma_mm` and `fit_center_sigma_mm`: its random part only (the points'
/// scatter), with `sigma_note` saying so; `measure_sphere` gives the measurement's
/// uncertainty (calibration and robot included).
#[pyfunction]
#[pyo3(signature = (points, trim_sigma = 3.0, diameter_range_mm = None))]
pub fn fit_sphere(
    py: Python<'_>,
    points: &Bound<'_, PyAny>,
    trim_sigma: f64,
    diameter_range_mm: Option<(f64, f64)>,
) -> PyResult<PySphereFit> {
    let pts = points_from_py(py, points)?;
    let o = fit_options(py, trim_sigma, diameter_range_mm)?;
    let f = py.detach_pool(|| core::fit_sphere(&pts, &o)).py_err(py)?;
    Ok(PySphereFit {
        inner: f.to_sphere_fit(),
    })
}

/// A plane fit: `normal . p = d_mm` (|normal| = 1, d_mm >= 0) with RMS, flatness and
/// one-sigma uncertainties.
#[pyclass(name = "PlaneFit", module = "stripecal", frozen)]
pub struct PyPlaneFit {
    inner: PlaneFit,
}

fn v3<'py>(py: Python<'py>, v: &Vector3<f64>) -> PyResult<Bound<'py, PyAny>> {
    nd(py, &[3], vec![v.x, v.y, v.z])
}

#[pymethods]
impl PyPlaneFit {
    /// `(3,)`: unit normal.
    #[getter]
    fn normal<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        v3(py, &self.inner.plane.normal)
    }
    /// Offset of the plane from the origin along the normal, mm (>= 0).
    #[getter]
    fn d_mm(&self) -> f64 {
        self.inner.plane.d
    }
    /// `(3,)`: centroid of the inliers, mm.
    #[getter]
    fn centroid_mm<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        v3(py, &self.inner.centroid_mm)
    }
    /// RMS distance of the inliers from the plane, mm.
    #[getter]
    fn rms_mm(&self) -> f64 {
        self.inner.rms_mm
    }
    /// Largest minus smallest signed distance of the inliers, mm.
    #[getter]
    fn flatness_mm(&self) -> f64 {
        self.inner.flatness_mm
    }
    /// `(3,)`: one-sigma of the normal's components.
    #[getter]
    fn normal_sigma<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        v3(py, &self.inner.normal_sigma)
    }
    /// One-sigma of d_mm, mm.
    #[getter]
    fn d_sigma_mm(&self) -> f64 {
        self.inner.d_sigma_mm
    }
    /// One-sigma of the normal's direction (the larger of the two tilts), degrees.
    #[getter]
    fn tilt_sigma_deg(&self) -> f64 {
        self.inner.tilt_sigma_deg
    }
    /// Inliers used.
    #[getter]
    fn points(&self) -> usize {
        self.inner.points
    }
    /// Points trimmed as outliers.
    #[getter]
    fn outliers(&self) -> usize {
        self.inner.outliers
    }
    /// `(N,)` bool: the points the fit used.
    #[getter]
    fn inliers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(py, &[self.inner.inlier.len()], self.inner.inlier.clone())
    }

    fn __repr__(&self) -> String {
        let f = &self.inner;
        let n = f.plane.normal;
        format!(
            "PlaneFit(normal=[{:.6}, {:.6}, {:.6}], d_mm={:.4}, rms_mm={:.4}, flatness_mm={:.4}, points={}, outliers={})",
            n.x, n.y, n.z, f.plane.d, f.rms_mm, f.flatness_mm, f.points, f.outliers
        )
    }
}

/// Fits a plane to `points` (N, 3) mm by total least squares, outliers beyond
/// `trim_sigma` robust sigmas trimmed (0: no trimming). Points along one line (a single
/// stripe) are a `DegenerateError`.
#[pyfunction]
#[pyo3(signature = (points, trim_sigma = 3.0))]
pub fn fit_plane(
    py: Python<'_>,
    points: &Bound<'_, PyAny>,
    trim_sigma: f64,
) -> PyResult<PyPlaneFit> {
    let pts = points_from_py(py, points)?;
    let o = fit_options(py, trim_sigma, None)?;
    let f = py.detach_pool(|| core::fit_plane(&pts, &o)).py_err(py)?;
    Ok(PyPlaneFit { inner: f })
}
