//! `stripecal.extract_stripe`, `stripecal.Stripe`, `stripecal.fit_line`,
//! `stripecal.LineFit`: laser stripe extraction and the robust line fit.
//!
//! Images are 2D uint8/uint16 numpy arrays of any strides, or `(rows, columns, 3 or 4)`
//! colour ones (copied, then the GIL is released); other dtypes are a `TypeError`, other
//! shapes or empty arrays an `InvalidInputError`.

use crate::pool::Detach;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use stripecal::model::image::{AnyGray, AnyImage};
use stripecal::vision::stripe::{
    self as core, EdgeOptions, LineFit, Stripe, StripeChannel, StripeDirection, StripeMethod,
    StripeOptions,
};

use crate::convert::{f64_array, fmt_shape, nd};
use crate::errors::{invalid_input, ResultExt};
use crate::imageview::{gray_or_colour_from_py, image_from_py};

/// The stripe of one image: one point per scan line (rows for direction "cols", columns
/// for "rows"), in scan-line order.
#[pyclass(name = "Stripe", module = "stripecal", frozen)]
pub struct PyStripe {
    inner: Stripe,
}

impl PyStripe {
    fn flag_mask<'py>(&self, py: Python<'py>, bits: u8) -> PyResult<Bound<'py, PyAny>> {
        let v: Vec<bool> = self
            .inner
            .points
            .iter()
            .map(|p| p.flags & bits != 0)
            .collect();
        nd(py, &[v.len()], v)
    }
}

#[pymethods]
impl PyStripe {
    /// Flag bit: a saturated pixel in the point's support.
    #[classattr]
    const SATURATED: u8 = core::FLAG_SATURATED;
    /// Flag bit: weak peak (e.g. inside a dark circle): noisier, not biased.
    #[classattr]
    const LOW_SIGNAL: u8 = core::FLAG_LOW_SIGNAL;
    /// Flag bit: the board image shows a reflectance edge in the point's support.
    #[classattr]
    const EDGE: u8 = core::FLAG_EDGE;
    /// Flag bit: the stripe image's own background changes across the support.
    #[classattr]
    const UNEVEN_BACKGROUND: u8 = core::FLAG_UNEVEN_BACKGROUND;
    /// Flag bit: the stripe crosses the scan line at a shallow angle here.
    #[classattr]
    const OBLIQUE: u8 = core::FLAG_OBLIQUE;
    /// The flag bits that warn of a biased centre (EDGE | UNEVEN_BACKGROUND | OBLIQUE).
    #[classattr]
    const BIASED: u8 = core::FLAG_BIASED;

    /// `(M, 2)` float64: sub-pixel centres `(u, v)`, px (pixel centres at integers).
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = &self.inner.points;
        nd(
            py,
            &[p.len(), 2],
            p.iter().flat_map(|p| [p.u, p.v]).collect(),
        )
    }

    /// `(M,)` float64: peak height above the local background, gray levels of the image.
    #[getter]
    fn intensity<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = &self.inner.points;
        nd(py, &[p.len()], p.iter().map(|p| p.peak as f64).collect())
    }

    /// `(M,)` float64: stripe width (FWHM) along the scan line, px.
    #[getter]
    fn width<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = &self.inner.points;
        nd(
            py,
            &[p.len()],
            p.iter().map(|p| p.width_px as f64).collect(),
        )
    }

    /// `(M,)` uint8: flag bits (`Stripe.SATURATED`, `LOW_SIGNAL`, `EDGE`,
    /// `UNEVEN_BACKGROUND`, `OBLIQUE`).
    #[getter]
    fn flags<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = &self.inner.points;
        nd(py, &[p.len()], p.iter().map(|p| p.flags).collect())
    }

    /// `(M,)` bool: a reflectance change in the point's support (EDGE or
    /// UNEVEN_BACKGROUND).
    #[getter]
    fn edge<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.flag_mask(py, core::FLAG_EDGE | core::FLAG_UNEVEN_BACKGROUND)
    }

    /// `(M,)` bool: a saturated pixel in the point's support.
    #[getter]
    fn saturated<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.flag_mask(py, core::FLAG_SATURATED)
    }

    /// `(M,)` bool: a weak peak.
    #[getter]
    fn low_signal<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.flag_mask(py, core::FLAG_LOW_SIGNAL)
    }

    /// `(M,)` bool: no flag warns of a biased centre (none of `Stripe.BIASED`).
    #[getter]
    fn trusted<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v: Vec<bool> = self.inner.points.iter().map(|p| p.trusted()).collect();
        nd(py, &[v.len()], v)
    }

    /// `"rows"` (one point per column) or `"cols"` (one point per row): the direction
    /// used (`"auto"` resolved).
    #[getter]
    fn direction(&self) -> &'static str {
        self.inner.direction.name()
    }

    /// Scan lines examined.
    #[getter]
    fn lines(&self) -> usize {
        self.inner.lines
    }

    /// Why scan lines gave no point: counts by reason.
    #[getter]
    fn rejected<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = self.inner.rejected;
        let d = PyDict::new(py);
        d.set_item("no_peak", r.no_peak)?;
        d.set_item("multiple_peaks", r.multiple_peaks)?;
        d.set_item("saturated", r.saturated)?;
        d.set_item("shape", r.shape)?;
        d.set_item("border", r.border)?;
        d.set_item("isolated", r.isolated)?;
        Ok(d)
    }

    fn __len__(&self) -> usize {
        self.inner.points.len()
    }

    fn __repr__(&self) -> String {
        let n = self.inner.points.len();
        let biased = self.inner.points.iter().filter(|p| !p.trusted()).count();
        format!(
            "Stripe(direction={:?}, points={n}, biased={biased}, lines={})",
            self.inner.direction.name(),
            self.inner.lines
        )
    }
}

fn view<'a>(py: Python<'_>, img: &'a AnyGray) -> PyResult<stripecal::model::image::AnyView<'a>> {
    img.view().py_err(py)
}

/// Extracts the laser stripe of `image` (2D uint8/uint16 gray, or `(H, W, 3 or 4)`
/// uint8/uint16 RGB(A)): one sub-pixel point per scan line. `direction`: "auto" (decided
/// from the image), "rows" (the stripe runs along rows: one point per column) or "cols"
/// (one point per row). `method`: "centroid" (gray centroid over an adaptive window, the
/// paper's way) or "gaussian" (least-squares Gaussian fit). `channel`: the signal the
/// stripe is found in (rig.json's `stripe.channel`): "gray" (BT.601 gray of a colour
/// image), "red", "green" or "blue" (that colour's channel of a colour image: a colour
/// laser's stripe; a gray image is an `InvalidInputError`) or "auto" (chosen from this
/// image: the signal where the stripe has the highest peak-to-noise ratio).
/// `board_image`: the board image of the same pose (laser off, gray or colour); its
/// reflectance edges flag the points they bias (`Stripe.EDGE`). For single-image views
/// pass the same array as `image`: the stripe's own footprint is then left out of the
/// edge test (on the image's gray). Raises `DetectionError` when no scan line holds a
/// stripe.
#[pyfunction]
#[pyo3(signature = (image, direction = "auto", method = "centroid", board_image = None, channel = "gray"))]
pub fn extract_stripe(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    direction: &str,
    method: &str,
    board_image: Option<&Bound<'_, PyAny>>,
    channel: &str,
) -> PyResult<PyStripe> {
    let opts = StripeOptions {
        direction: StripeDirection::from_name(direction).py_err(py)?,
        method: StripeMethod::from_name(method).py_err(py)?,
        ..StripeOptions::default()
    };
    let channel = StripeChannel::from_name(channel).py_err(py)?;
    let any = image_from_py(image, "image")?;
    if !any.is_colour() && channel.rgb_index().is_some() {
        return Err(invalid_input(
            py,
            format!(
                "channel {:?} needs a colour image (rows, columns, 3 or 4): image is gray \
                 (2D); use channel=\"gray\" or \"auto\"",
                channel.name()
            ),
        ));
    }
    let signal = py
        .detach_pool(|| core::stripe_signal(&any, channel, &opts).map(|s| s.into_owned()))
        .py_err(py)?;
    // the image's own gray: the board's appearance in single-image views
    let img: AnyGray = match &any {
        AnyImage::Gray(g) => g.clone(),
        AnyImage::Rgb(c) => c.to_gray(),
    };
    let board = match board_image {
        None => None,
        Some(b) if b.is(image) => Some(None),
        Some(b) => Some(Some(gray_or_colour_from_py(b, "board_image")?)),
    };
    if let Some(Some(b)) = &board {
        if b.size() != img.size() {
            let (bw, bh) = b.size();
            let (w, h) = img.size();
            return Err(invalid_input(
                py,
                format!(
                    "board_image has shape {}, image {}: they must be the same pose's images",
                    fmt_shape(&[bh, bw]),
                    fmt_shape(&[h, w])
                ),
            ));
        }
    }
    let v = view(py, &img)?;
    let sv = view(py, &signal)?;
    let bv = match &board {
        Some(Some(b)) => Some(view(py, b)?),
        _ => None,
    };
    let single = matches!(board, Some(None)) || (bv.is_some() && board_equals(&board, &img));
    let stripe = py
        .detach_pool(|| -> stripecal::Result<Stripe> {
            let mut s = core::extract_stripe(sv, &opts)?;
            let eo = EdgeOptions {
                single_image: single,
                ..EdgeOptions::default()
            };
            match (&board, bv) {
                (Some(None), _) => {
                    core::flag_reflectance_edges(&mut s, v, &eo)?;
                }
                (Some(Some(_)), Some(b)) => {
                    core::flag_reflectance_edges(&mut s, b, &eo)?;
                }
                _ => {}
            }
            Ok(s)
        })
        .py_err(py)?;
    Ok(PyStripe { inner: stripe })
}

/// A separate board image with the same pixels as the stripe image is a single-image view.
fn board_equals(board: &Option<Option<AnyGray>>, img: &AnyGray) -> bool {
    matches!(board, Some(Some(b)) if b == img)
}

/// A robust straight-line fit: RANSAC (deterministic) then total least squares on the
/// inliers.
#[pyclass(name = "LineFit", module = "stripecal", frozen)]
pub struct PyLineFit {
    inner: LineFit,
}

#[pymethods]
impl PyLineFit {
    /// `(2,)`: a point on the line (the inliers' centroid), px.
    #[getter]
    fn point<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(py, &[2], self.inner.point.to_vec())
    }

    /// `(2,)`: unit direction (its larger component positive).
    #[getter]
    fn direction<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(py, &[2], self.inner.direction.to_vec())
    }

    /// `(2,)`: unit normal; the line is `normal . p = normal . point`.
    #[getter]
    fn normal<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(py, &[2], self.inner.normal.to_vec())
    }

    /// RMS orthogonal distance of the inliers, px.
    #[getter]
    fn rms_px(&self) -> f64 {
        self.inner.rms_px
    }

    /// Largest orthogonal distance of an inlier, px.
    #[getter]
    fn max_px(&self) -> f64 {
        self.inner.max_px
    }

    /// `(N,)` bool: the points the final fit used.
    #[getter]
    fn inliers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        nd(py, &[self.inner.inliers.len()], self.inner.inliers.clone())
    }

    /// Number of inliers.
    #[getter]
    fn inlier_count(&self) -> usize {
        self.inner.inlier_count
    }

    /// Signed orthogonal distances of `points` `(K, 2)` from the line, `(K,)`, px.
    fn distances<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let pts = points_from_py(py, points)?;
        nd(
            py,
            &[pts.len()],
            pts.iter().map(|p| self.inner.distance(*p)).collect(),
        )
    }

    fn __repr__(&self) -> String {
        let f = &self.inner;
        format!(
            "LineFit(point=[{:.3}, {:.3}], direction=[{:.5}, {:.5}], rms_px={:.4}, max_px={:.4}, inliers={}/{})",
            f.point[0],
            f.point[1],
            f.direction[0],
            f.direction[1],
            f.rms_px,
            f.max_px,
            f.inlier_count,
            f.inliers.len()
        )
    }
}

fn points_from_py(py: Python<'_>, points: &Bound<'_, PyAny>) -> PyResult<Vec<[f64; 2]>> {
    let a = f64_array(points, "points")?;
    if a.ndim() != 2 || a.shape()[1] != 2 {
        return Err(invalid_input(
            py,
            format!(
                "points must have shape (N, 2), got {}",
                fmt_shape(a.shape())
            ),
        ));
    }
    Ok(a.rows().into_iter().map(|r| [r[0], r[1]]).collect())
}

/// Fits a straight line to `points` `(N, 2)` (e.g. `Stripe.points` on the planar board):
/// RANSAC with a fixed seed (inliers within `inlier_px`), then total least squares on
/// the inliers, with residual statistics.
#[pyfunction]
#[pyo3(signature = (points, inlier_px = 1.0))]
pub fn fit_line(py: Python<'_>, points: &Bound<'_, PyAny>, inlier_px: f64) -> PyResult<PyLineFit> {
    let pts = points_from_py(py, points)?;
    let opts = core::LineFitOptions {
        inlier_px,
        ..core::LineFitOptions::default()
    };
    let fit = py
        .detach_pool(|| core::fit_line_with(&pts, &opts))
        .py_err(py)?;
    Ok(PyLineFit { inner: fit })
}
