//! Reflectance-edge flagging with the board image of the same pose.
//!
//! Where the surface reflectance changes inside the stripe's footprint (a circle's
//! border, the plate's edge), the imaged stripe profile is the laser profile times a
//! step, and its centre is biased, on a real sensor as in the twin. The board image
//! (laser off, same pose) shows those steps directly: a point is flagged [`FLAG_EDGE`]
//! when the board image's gray range over the point's support (the scan-line segment
//! its centre depends on: window and background flanks, `support_px` each side, plus
//! `margin_px`), on its own scan line and `lines` neighbours each side (and the scan
//! lines the extractor averaged along the line, [`Stripe::along_line`]), exceeds
//! `min_gray + rel * max` (a step, not noise or shading).
//!
//! Single-image views (board lit and stripe on, one image): the image holds the stripe
//! too, so the stripe's own footprint (`+- exclude_fwhm * width_px` around the stripe on
//! each examined line) is left out and `single_image_lines` neighbours are examined
//! instead: a reflectance edge under the stripe continues beside it. The stripe
//! extractor's own [`FLAG_UNEVEN_BACKGROUND`](super::FLAG_UNEVEN_BACKGROUND) test
//! covers the rest.

use super::{Stripe, StripeDirection, FLAG_EDGE};
use crate::error::{Error, Result};
use crate::model::image::{AnyView, ImageView, Pixel};

/// Options of [`flag_reflectance_edges`]. Gray levels on the 8-bit scale (x257 for
/// 16-bit images).
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeOptions {
    /// Neighbouring scan lines examined on each side.
    pub lines: usize,
    /// Extra length beyond each point's support, px (covers the PSF's reach).
    pub margin_px: f32,
    /// A range above `min_gray + rel * max` over the region is an edge.
    pub min_gray: f32,
    pub rel: f32,
    /// The board image is the stripe image itself (single-image views).
    pub single_image: bool,
    /// Single-image views: the stripe's footprint left out, in stripe widths each side.
    pub exclude_fwhm: f32,
    /// Single-image views: neighbouring scan lines examined on each side.
    pub single_image_lines: usize,
}

impl Default for EdgeOptions {
    fn default() -> Self {
        EdgeOptions {
            lines: 1,
            margin_px: 1.5,
            min_gray: 10.0,
            rel: 0.1,
            single_image: false,
            exclude_fwhm: 1.5,
            single_image_lines: 4,
        }
    }
}

/// Flags [`FLAG_EDGE`] on the stripe points whose support shows a reflectance edge in
/// `board` (the board image of the same pose, same size as the stripe image). Returns
/// the number of points flagged (including ones already flagged).
pub fn flag_reflectance_edges(
    stripe: &mut Stripe,
    board: AnyView<'_>,
    opts: &EdgeOptions,
) -> Result<usize> {
    if board.size() != stripe.size {
        return Err(Error::InvalidInput(format!(
            "board image is {} x {}, the stripe image {} x {}",
            board.size().0,
            board.size().1,
            stripe.size.0,
            stripe.size.1
        )));
    }
    for (k, v) in [
        ("margin_px", opts.margin_px),
        ("min_gray", opts.min_gray),
        ("rel", opts.rel),
        ("exclude_fwhm", opts.exclude_fwhm),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(Error::InvalidInput(format!(
                "edge options: {k} = {v} must be finite and >= 0"
            )));
        }
    }
    Ok(match board {
        AnyView::U8(v) => flag(stripe, &v, opts, 1.0),
        AnyView::U16(v) => flag(stripe, &v, opts, 257.0),
    })
}

fn flag<T: Pixel>(
    stripe: &mut Stripe,
    img: &ImageView<'_, T>,
    o: &EdgeOptions,
    scale: f32,
) -> usize {
    let per_col = stripe.direction == StripeDirection::Rows;
    let (w, h) = (img.width() as isize, img.height() as isize);
    let (n_lines, n_pos) = if per_col { (w, h) } else { (h, w) };
    let get = |line: isize, pos: isize| -> f32 {
        if per_col {
            img.get(line as usize, pos as usize).to_f32()
        } else {
            img.get(pos as usize, line as usize).to_f32()
        }
    };
    // a stripe smoothed along the line over `along_line` scan lines depends on the
    // board over that many lines too
    let lines = if o.single_image {
        o.single_image_lines
    } else {
        o.lines
    } as isize
        + (stripe.along_line / 2) as isize;
    let n = stripe.points.len();
    let mut flagged = 0;
    for i in 0..n {
        let p = stripe.points[i];
        let (line, pos) = if per_col { (p.u, p.v) } else { (p.v, p.u) };
        // local slope (position change per scan line) from the neighbouring points
        let slope = {
            let at = |j: usize| {
                let q = stripe.points[j];
                if per_col {
                    (q.u, q.v)
                } else {
                    (q.v, q.u)
                }
            };
            let a = if i > 0 { at(i - 1) } else { (line, pos) };
            let b = if i + 1 < n { at(i + 1) } else { (line, pos) };
            if b.0 - a.0 > 0.5 && b.0 - a.0 <= 4.0 {
                (b.1 - a.1) / (b.0 - a.0)
            } else {
                0.0
            }
        };
        let reach = p.support_px.max(0.0) + o.margin_px;
        let excl = o.exclude_fwhm * p.width_px;
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let l0 = line.round() as isize;
        for k in -lines..=lines {
            let l = l0 + k;
            if l < 0 || l >= n_lines {
                continue;
            }
            let c = pos + slope * k as f64;
            let a = ((c - reach as f64).floor() as isize).max(0);
            let b = ((c + reach as f64).ceil() as isize).min(n_pos - 1);
            for x in a..=b {
                if o.single_image && ((x as f64 - c).abs() as f32) < excl {
                    continue;
                }
                let v = get(l, x);
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        if hi > lo && hi - lo > o.min_gray * scale + o.rel * hi {
            stripe.points[i].flags |= FLAG_EDGE;
        }
        if stripe.points[i].flags & FLAG_EDGE != 0 {
            flagged += 1;
        }
    }
    flagged
}
