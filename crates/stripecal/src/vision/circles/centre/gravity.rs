//! The gravity method: the signal-weighted centroid of the pixel centres over a blob's
//! region (no clipping of the weights, so noise does not pull towards the window's
//! centre).

use super::super::blobs::Img;
use super::background::Signal;
use super::window::{cols, Window};
use crate::model::image::Pixel;

/// Sums of the weights `w`, `w dx` and `w dy` over the region of `win` (offsets from
/// the blob's centroid).
pub(super) fn weighted_sums<T: Pixel>(
    img: &Img<'_, T>,
    win: &Window,
    sig: &Signal,
) -> (f64, f64, f64) {
    let (cx, cy) = (win.cx, win.cy);
    let rhy = win.region_half_h;
    let (bg, illum, s) = (&sig.bg, &sig.illum, sig.s);
    let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
    let ry0 = (cy - rhy).floor() as usize;
    let ry1 = ((cy + rhy).ceil() as usize).min(img.h - 1);
    for y in ry0..=ry1 {
        let dy = y as f64 - cy;
        let row = img.row(y);
        let (b0, r0) = (bg[0] + bg[2] * dy, illum[0] + illum[2] * dy);
        let xs = cols(cx, win.region.span(dy, 1.0), img.w);
        if xs.is_empty() {
            continue;
        }
        let dx0 = xs.start as f64 - cx;
        let dx1 = (xs.end - 1) as f64 - cx;
        // relative illumination change per px along the row
        let rate = illum[1] / r0;
        let (rw, rx) = if r0 > 1e-3 && rate.abs() * dx0.abs().max(dx1.abs()) < 0.02 {
            row_sums_series(&row[xs], dx0, b0, bg[1], s / r0, rate)
        } else {
            let (mut rw, mut rx) = (0.0, 0.0);
            for x in xs {
                let dx = x as f64 - cx;
                let r = (r0 + illum[1] * dx).max(1e-3);
                let wgt = s * (row[x].to_f32() as f64 - (b0 + bg[1] * dx)) / r;
                rw += wgt;
                rx += wgt * dx;
            }
            (rw, rx)
        };
        sw += rw;
        sx += rx;
        sy += rw * dy;
    }
    (sw, sx, sy)
}

/// One row's `(sum w, sum w dx)` for the pixels `px` at offsets `dx0, dx0 + 1, ...`, with
/// background `b0 + b1 dx` and `1 / illum` as its cubic series in `e = rate dx` (relative
/// error 1.6e-7 at `|e| < 0.02`): no division per pixel; two accumulator pairs (no long
/// chain of dependent additions). `g0` is `s / illum` at `dx = 0`.
#[inline]
fn row_sums_series<T: Pixel>(
    px: &[T],
    dx0: f64,
    b0: f64,
    b1: f64,
    g0: f64,
    rate: f64,
) -> (f64, f64) {
    let (mut rw, mut rx) = (0.0, 0.0);
    let (mut w2, mut x2) = (0.0, 0.0);
    let term = |k: usize| {
        let dx = dx0 + k as f64;
        let e = rate * dx;
        let g = g0 * (1.0 - e * (1.0 - e * (1.0 - e)));
        let wgt = (px[k].to_f32() as f64 - (b0 + b1 * dx)) * g;
        (wgt, wgt * dx)
    };
    let mut k = 0;
    while k + 1 < px.len() {
        let (a0, a1) = term(k);
        let (c0, c1) = term(k + 1);
        rw += a0;
        rx += a1;
        w2 += c0;
        x2 += c1;
        k += 2;
    }
    if k < px.len() {
        let (a0, a1) = term(k);
        rw += a0;
        rx += a1;
    }
    (rw + w2, rx + x2)
}
