//! The background around a blob: the ring and core pixels, a plane fitted to the ring
//! with robust outlier rejection, and the multiplicative illumination correction.

use super::super::blobs::Img;
use super::window::{cols, Shape, Window};
use super::Fail;
use crate::model::image::Pixel;
use crate::numerics::robust::median;

/// Least-squares plane `z = p0 + p1 x + p2 y` through the kept points (the 3x3 normal
/// equations from nine scalar sums).
fn plane_fit(pts: &[(f64, f64, f64)], keep: impl Fn(usize) -> bool) -> Option<[f64; 3]> {
    let (mut sn, mut sx, mut sy, mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut sz, mut sxz, mut syz) = (0.0, 0.0, 0.0);
    for (k, &(x, y, z)) in pts.iter().enumerate() {
        if !keep(k) {
            continue;
        }
        sn += 1.0;
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        sz += z;
        sxz += x * z;
        syz += y * z;
    }
    let n = nalgebra::Matrix3::new(sn, sx, sy, sx, sxx, sxy, sy, sxy, syy);
    let s = n.try_inverse()? * nalgebra::Vector3::new(sz, sxz, syz);
    Some([s[0], s[1], s[2]])
}

/// Pixels sampled around one blob, as offsets `(dx, dy, value)` from its centroid.
pub(super) struct Samples {
    /// The background ring, without the pixels covered by neighbouring blobs.
    pub ring: Vec<(f64, f64, f64)>,
    /// The core's values (at least one: the centre pixel of a tiny blob).
    pub core: Vec<f64>,
    /// The core's pixels (empty for a tiny blob).
    pub core_pts: Vec<(f64, f64, f64)>,
}

/// Collects the ring and core pixels of `win`; [`Fail::Background`] when less than a
/// quarter of the ring (or fewer than 12 pixels) is usable.
pub(super) fn sample<T: Pixel>(
    img: &Img<'_, T>,
    win: &Window,
    others: &[Shape],
) -> Result<Samples, Fail> {
    let (cx, cy, a, b) = (win.cx, win.cy, win.a, win.b);
    let ((oa, ob), (ia, ib)) = (win.outer_axes, win.inner_axes);
    // capacities from the areas of the ring band and the core (no regrowth)
    let band = std::f64::consts::PI * (oa * ob - ia * ib) + 4.0 * (oa + ob) + 16.0;
    let mut ring: Vec<(f64, f64, f64)> = Vec::with_capacity(band as usize);
    let core_area = std::f64::consts::PI * 0.25 * a * b + 2.0 * (a + b) + 4.0;
    let mut core: Vec<f64> = Vec::with_capacity(core_area as usize);
    let mut core_pts: Vec<(f64, f64, f64)> = Vec::with_capacity(core_area as usize);
    let mut expected_ring = 0usize;
    // Ring area of the full (unclipped) band, to judge how much is missing; large rings
    // are sampled on a checkerboard (every other pixel, evenly over the band: 300 and
    // more pixels still fit the background plane to a small fraction of the noise).
    let full_ring = (std::f64::consts::PI * (oa * ob - ia * ib)) as usize;
    let decimate = full_ring > 400;
    let mut spans: Vec<(f64, f64)> = Vec::with_capacity(others.len());
    for y in win.rows.0..=win.rows.1 {
        let dy = y as f64 - cy;
        let row = img.row(y);
        let outer = cols(cx, win.outer.span(dy, 1.0), img.w);
        let inner = cols(cx, win.inner.span(dy, 1.0), img.w);
        // the neighbours' shapes on this row: pixels inside them are not background
        spans.clear();
        spans.extend(others.iter().filter_map(|o| o.row_span(y as f64)));
        // the band: the outer span minus the inner one (two segments, or the whole
        // outer span where the inner ellipse does not reach this row)
        let (left, right) = if inner.is_empty() {
            (outer.clone(), 0..0)
        } else {
            (
                outer.start..inner.start.max(outer.start),
                inner.end.min(outer.end)..outer.end,
            )
        };
        for x in left.chain(right) {
            if decimate && (x + y) % 2 == 1 {
                continue;
            }
            expected_ring += 1;
            let xf = x as f64;
            if !spans.iter().any(|&(lo, hi)| xf >= lo && xf <= hi) {
                ring.push((xf - cx, dy, row[x].to_f32() as f64));
            }
        }
        for x in cols(cx, win.core.span(dy, 0.25), img.w) {
            let z = row[x].to_f32() as f64;
            core.push(z);
            core_pts.push((x as f64 - cx, dy, z));
        }
    }
    expected_ring = expected_ring.max(if decimate { full_ring / 2 } else { full_ring });
    if ring.len() < 12.max(expected_ring / 4) {
        return Err(Fail::Background);
    }
    if core.is_empty() {
        // tiny blob: the centre pixel
        let (xi, yi) = (cx.round() as usize, cy.round() as usize);
        core.push(img.at(xi.min(img.w - 1), yi.min(img.h - 1)) as f64);
    }
    Ok(Samples {
        ring,
        core,
        core_pts,
    })
}

/// The background plane `[p0, p1, p2]` of the ring and the robust sigma of its
/// residuals: from the median level, two rounds of a plane fit with outlier rejection
/// (3.5 robust sigmas).
pub(super) fn fit_plane(ring: &[(f64, f64, f64)]) -> Result<([f64; 3], f64), Fail> {
    let mut keep = vec![true; ring.len()];
    // Start from the median level (robust), then planes with outlier rejection.
    // every other ring pixel is enough for the robust start and scale
    let step = if ring.len() > 200 { 2 } else { 1 };
    let mut bg = {
        let mut z: Vec<f64> = ring.iter().step_by(step).map(|r| r.2).collect();
        [median(&mut z).unwrap_or(f64::NAN), 0.0, 0.0]
    };
    let mut sigma = 0.0;
    let mut res: Vec<f64> = Vec::with_capacity(ring.len());
    let mut absr: Vec<f64> = Vec::with_capacity(ring.len());
    for _ in 0..2 {
        res.clear();
        res.extend(
            ring.iter()
                .map(|&(x, y, z)| z - (bg[0] + bg[1] * x + bg[2] * y)),
        );
        absr.clear();
        absr.extend(res.iter().step_by(step).map(|r| r.abs()));
        sigma = 1.4826 * median(&mut absr).unwrap_or(f64::NAN);
        let lim = 3.5 * sigma.max(0.3);
        for (k, r) in keep.iter_mut().zip(&res) {
            *k = r.abs() <= lim;
        }
        if keep.iter().filter(|&&k| k).count() < 12 {
            return Err(Fail::Background);
        }
        bg = plane_fit(ring, |k| keep[k]).ok_or(Fail::Background)?;
    }
    Ok((bg, sigma))
}

/// Multiplicative illumination `[1, r1, r2]` (relative slopes): from the background
/// plane `bg` when the plate is the brighter surface, else from a plane fitted to the
/// circle's core (light circles on a dark plate, core level `fg`), else none.
pub(super) fn illumination(
    bg: &[f64; 3],
    fg: f64,
    core_pts: &[(f64, f64, f64)],
    core_n: usize,
) -> [f64; 3] {
    let bg_c = bg[0];
    if bg_c > 0.0 && bg_c >= fg {
        [1.0, bg[1] / bg_c, bg[2] / bg_c]
    } else if fg > 0.0 && core_n >= 12 {
        match plane_fit(core_pts, |_| true) {
            Some(p) if p[0] > 0.0 => [1.0, p[1] / p[0], p[2] / p[0]],
            _ => [1.0, 0.0, 0.0],
        }
    } else {
        [1.0, 0.0, 0.0]
    }
}

/// The circle's signal at a pixel: `s (I - bg) / illum` with `s = -1` for dark circles
/// (positive inside a circle of either polarity).
#[derive(Debug, Clone, Copy)]
pub(super) struct Signal {
    pub bg: [f64; 3],
    pub illum: [f64; 3],
    pub s: f64,
}

impl Signal {
    /// The weight of value `z` at offset `(dx, dy)` from the blob's centroid.
    #[inline]
    pub(super) fn weight(&self, dx: f64, dy: f64, z: f64) -> f64 {
        let (bg, illum) = (&self.bg, &self.illum);
        let b = bg[0] + bg[1] * dx + bg[2] * dy;
        let r = (illum[0] + illum[1] * dx + illum[2] * dy).max(1e-3);
        self.s * (z - b) / r
    }
}
