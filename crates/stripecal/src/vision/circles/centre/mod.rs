//! Sub-pixel centres of one blob: the gravity method and an ellipse fit to edge points.
//!
//! Both work in a window around the blob built from its moment ellipse (semi-axes
//! `a >= b`): the *region* is that ellipse grown by `delta = edge_margin_px + 0.1 b` px
//! (the blob and its blurred edge), the *ring* the band `delta + 1 .. 2 delta + 1`
//! outside it (the plate around the circle).
//!
//! - Background: a plane `bg(x) = p0 + p1 dx + p2 dy` fitted to the ring by least
//!   squares with two rounds of outlier rejection (3.5 robust sigmas): a vignetted
//!   or unevenly lit plate is modelled locally, neighbouring circles' edges and a laser
//!   stripe are rejected. A ring of more than 400 pixels is sampled on a checkerboard.
//! - Illumination: light falls off multiplicatively (vignetting), so the circle/plate
//!   contrast at `x` is proportional to `bg(x)`; weights are divided by `bg(x) / bg(c)`,
//!   which keeps the weight constant inside the circle. When the circles are the
//!   brighter surface (light circles on a dark plate) the illumination's slope comes
//!   from a plane fitted to the circle's core instead.
//! - Gravity: `w(x) = s (I(x) - bg(x)) / illum(x)` with `s = -1` for dark circles,
//!   summed over the region without clipping (clipping noise at 0 would bias the
//!   centroid towards the window centre); the centre is the `w`-weighted mean of the
//!   pixel centres. Blur (a symmetric PSF) does not move an intensity centroid. Where
//!   the illumination changes by less than 2 % across a row of the window, `1 /
//!   illum` is its cubic series (relative error below 2e-7), with no division per
//!   pixel.
//! - Ellipse: along rays from the gravity centre, the normalised profile
//!   `w / contrast` (1 inside, 0 outside) is sampled by bilinear interpolation on a
//!   0.5 px grid from the moment ellipse outwards or inwards until it crosses 0.5 (within
//!   the blob's edge allowance), and the crossing found by linear interpolation; a conic
//!   is fitted to
//!   these edge points (algebraic, with the Euclidean-invariant constraint
//!   `A + C = 1`, re-weighted by the gradient norm twice, which approximates the
//!   geometric fit), rays farther than 3 RMS are dropped once; the centre is the
//!   conic's. The RMS geometric residual is the blob's quality figure in both methods.
//! - Stripe: ring pixels far brighter than the background plane (more than
//!   `max(6 sigma, 0.2 contrast)`) mark a laser stripe (single-image views) crossing
//!   the window.

mod background;
mod edge;
mod ellipse;
mod gravity;
mod window;

use super::blobs::{Blob, Img};
use crate::model::image::Pixel;
use crate::numerics::robust::median;

use background::Signal;
pub(crate) use ellipse::Ellipse;
pub(crate) use window::Shape;
use window::Window;

/// What was measured for one blob.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Measure {
    pub gravity: [f64; 2],
    pub ellipse: Option<Ellipse>,
    /// Bright ring pixels (a stripe) found.
    pub stripe_px: usize,
    /// Area estimated from the ink, px^2.
    pub area_px: f64,
}

/// Why a blob could not be measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Fail {
    /// Its window (blob and edge) leaves the image.
    Border,
    /// Not enough background around it, or no contrast.
    Background,
}

impl Fail {
    pub fn reason(self) -> &'static str {
        match self {
            Fail::Border => "window leaves the image",
            Fail::Background => "no usable background ring",
        }
    }
}

/// Measures one blob. `edge_margin` is the edge allowance in px (blur); `others` are
/// the shapes of nearby blobs, left out of the background ring.
pub(crate) fn measure<T: Pixel>(
    img: &Img<'_, T>,
    blob: &Blob,
    dark: bool,
    edge_margin: f64,
    others: &[Shape],
    ellipse_centre: bool,
) -> Result<Measure, Fail> {
    let win = Window::of(blob, edge_margin, img.w, img.h)?;
    let background::Samples {
        ring,
        mut core,
        core_pts,
    } = background::sample(img, &win, others)?;
    let (bg, sigma) = background::fit_plane(&ring)?;

    // Contrast, stripe and illumination.
    let core_n = core.len();
    let fg = median(&mut core).unwrap_or(f64::NAN);
    let s = if dark { -1.0 } else { 1.0 };
    let contrast = s * (fg - bg[0]);
    if contrast.is_nan() || contrast <= 4.0 * sigma.max(0.0) || contrast <= 0.0 {
        return Err(Fail::Background);
    }
    let stripe_lim = (6.0 * sigma).max(0.2 * contrast);
    let stripe_px = ring
        .iter()
        .filter(|&&(x, y, z)| z - (bg[0] + bg[1] * x + bg[2] * y) > stripe_lim)
        .count();
    let illum = background::illumination(&bg, fg, &core_pts, core_n);
    let sig = Signal { bg, illum, s };

    // Gravity.
    let (sw, sx, sy) = gravity::weighted_sums(img, &win, &sig);
    if sw.is_nan() || sw <= 0.0 {
        return Err(Fail::Background);
    }
    let (gx, gy) = (sx / sw, sy / sw);
    let gravity = [win.cx + gx, win.cy + gy];
    let area_px = sw / contrast;

    // Ellipse: edge points along rays from the gravity centre.
    // the gravity method needs the fit for its quality figure only: 20 rays do
    let nrays = if ellipse_centre {
        ((std::f64::consts::PI * (win.a + win.b) / 1.5).round() as usize).clamp(32, 96)
    } else {
        20
    };
    let pts = edge::edge_points(img, &win, &sig, (gx, gy), contrast, nrays);
    // the ellipse method's centre gets the full re-weighting; the gravity method's
    // quality figure two rounds (the outlier removal included)
    let ellipse = ellipse::fit_ellipse(&pts, if ellipse_centre { 4 } else { 2 });
    Ok(Measure {
        gravity,
        ellipse,
        stripe_px,
        area_px,
    })
}
