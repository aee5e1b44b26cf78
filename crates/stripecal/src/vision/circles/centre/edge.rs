//! Sub-pixel edge points of a blob: along rays from its gravity centre, where the
//! normalised signal profile crosses 0.5.

use super::super::blobs::Img;
use super::background::Signal;
use super::window::Window;
use crate::model::image::Pixel;

/// Edge points (px) on `nrays` rays from the gravity centre, at offset `(gx, gy)` from
/// the blob's centroid; `contrast` normalises the signal (1 inside, 0 outside).
pub(super) fn edge_points<T: Pixel>(
    img: &Img<'_, T>,
    win: &Window,
    sig: &Signal,
    (gx, gy): (f64, f64),
    contrast: f64,
    nrays: usize,
) -> Vec<[f64; 2]> {
    let (cx, cy, delta) = (win.cx, win.cy, win.delta);
    let gravity = [cx + gx, cy + gy];
    let mut pts: Vec<[f64; 2]> = Vec::with_capacity(nrays);
    // ray directions by rotation from (1, 0): one sin / cos pair per blob
    let (step_s, step_c) = (std::f64::consts::TAU / nrays as f64).sin_cos();
    let (mut ux, mut uy) = (1.0f64, 0.0f64);
    for _ in 0..nrays {
        let (ux_k, uy_k) = (ux, uy);
        (ux, uy) = (ux_k * step_c - uy_k * step_s, ux_k * step_s + uy_k * step_c);
        let (ux, uy) = (ux_k, uy_k);
        // the moment ellipse along the ray
        let re = 1.0 / win.core.eval(ux, uy).sqrt();
        let (t0, t1) = ((re - 2.0 * delta).max(0.5 * re), re + delta);
        let profile = |t: f64| -> Option<f64> {
            let (dx, dy) = (gx + t * ux, gy + t * uy);
            let z = img.bilinear(cx + dx, cy + dy)?;
            Some(sig.weight(dx, dy, z) / contrast)
        };
        if let Some((ta, va, tb, vb)) = bracket_half(profile, re, (t0, t1)) {
            let f = (va - 0.5) / (va - vb);
            let te = ta + f * (tb - ta);
            pts.push([gravity[0] + te * ux, gravity[1] + te * uy]);
        }
    }
    pts
}

/// The profile's 0.5 crossing near `re`, bracketed on a 0.5 px grid within `[t0, t1]`
/// (outwards while the profile is at or above 0.5, inwards while below):
/// `(t_a, q(t_a), t_b, q(t_b))` with `q(t_a) >= 0.5 > q(t_b)`.
#[inline]
fn bracket_half(
    q: impl Fn(f64) -> Option<f64>,
    re: f64,
    (t0, t1): (f64, f64),
) -> Option<(f64, f64, f64, f64)> {
    let at_re = q(re)?;
    if at_re >= 0.5 {
        // outwards to the first sample below 0.5
        let (mut t, mut prev) = (re, at_re);
        loop {
            let tn = t + 0.5;
            if tn > t1 {
                return None;
            }
            let cur = q(tn)?;
            if cur < 0.5 {
                return Some((t, prev, tn, cur));
            }
            (t, prev) = (tn, cur);
        }
    } else {
        // inwards to the first sample at or above 0.5
        let (mut t, mut cur) = (re, at_re);
        loop {
            let tp = t - 0.5;
            if tp < t0 {
                return None;
            }
            let prev = q(tp)?;
            if prev >= 0.5 {
                return Some((tp, prev, t, cur));
            }
            (t, cur) = (tp, prev);
        }
    }
}
