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

use super::blobs::{Blob, Img};
use crate::model::image::Pixel;
use crate::numerics::robust::median;

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

#[derive(Debug, Clone, Copy)]
pub(crate) struct Ellipse {
    pub centre: [f64; 2],
    /// Semi-axes (major, minor), px.
    pub axes: [f64; 2],
    /// Angle of the major axis from +u towards +v, radians.
    pub angle: f64,
    /// RMS geometric residual of the edge points, px.
    pub rms: f64,
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

/// A blob's moment ellipse grown by its edge allowance, as an obstacle for the
/// background rings of its neighbours.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Shape {
    cx: f64,
    cy: f64,
    ea: f64,
    q: Quad,
}

/// The quadratic form `a dx^2 + b dx dy + c dy^2` of an ellipse (value 1 on it).
#[derive(Debug, Clone, Copy)]
struct Quad {
    a: f64,
    b: f64,
    c: f64,
    /// `1 / (2 a)`, for the row spans.
    inv2a: f64,
}

impl Quad {
    #[inline]
    fn eval(&self, dx: f64, dy: f64) -> f64 {
        self.a * dx * dx + self.b * dx * dy + self.c * dy * dy
    }

    /// The `dx` interval where `eval(dx, dy) <= level` on the row `dy`, if any.
    #[inline]
    fn span(&self, dy: f64, level: f64) -> Option<(f64, f64)> {
        let (bb, cc) = (self.b * dy, self.c * dy * dy - level);
        let disc = bb * bb - 4.0 * self.a * cc;
        if disc < 0.0 {
            return None;
        }
        let r = disc.sqrt();
        Some(((-bb - r) * self.inv2a, (-bb + r) * self.inv2a))
    }
}

/// Integer columns `x` with `cx + lo <= x <= cx + hi`, clipped to `0..w`.
#[inline]
fn cols(cx: f64, span: Option<(f64, f64)>, w: usize) -> std::ops::Range<usize> {
    match span {
        Some((lo, hi)) => {
            // ceil / floor by truncation of non-negative values (no libm call: the
            // baseline x86-64 has no rounding instruction)
            let (a, b) = (cx + lo, cx + hi);
            if b.is_nan() || b < 0.0 || a.is_nan() || w == 0 {
                return 0..0;
            }
            let x0 = if a <= 0.0 {
                0
            } else {
                let t = a.min(w as f64) as usize;
                if (t as f64) < a {
                    t + 1
                } else {
                    t
                }
            };
            let x1 = (b.min(w as f64) as usize).min(w - 1);
            if x1 < x0 {
                0..0
            } else {
                x0..x1 + 1
            }
        }
        None => 0..0,
    }
}

/// The quadratic form of an ellipse with semi-axes `(ea, eb)`, the first along
/// `(ct, st)`.
fn quad(ct: f64, st: f64, ea: f64, eb: f64) -> Quad {
    let (ia, ib) = (1.0 / (ea * ea), 1.0 / (eb * eb));
    let a = ct * ct * ia + st * st * ib;
    Quad {
        a,
        b: 2.0 * ct * st * (ia - ib),
        c: st * st * ia + ct * ct * ib,
        inv2a: 0.5 / a,
    }
}

impl Shape {
    pub fn of(blob: &Blob, edge_margin: f64) -> Shape {
        let theta = 0.5 * (2.0 * blob.sxy).atan2(blob.sxx - blob.syy);
        let grow = edge_margin + 0.1 * blob.b;
        Shape {
            cx: blob.cx,
            cy: blob.cy,
            ea: blob.a + grow,
            q: quad(theta.cos(), theta.sin(), blob.a + grow, blob.b + grow),
        }
    }

    pub fn cx(&self) -> f64 {
        self.cx
    }

    pub fn cy(&self) -> f64 {
        self.cy
    }

    /// Radius of a circle that contains the shape.
    pub fn reach(&self) -> f64 {
        self.ea
    }

    /// The closed `x` interval the shape covers on row `y`, if any.
    #[inline]
    fn row_span(&self, y: f64) -> Option<(f64, f64)> {
        let dy = y - self.cy;
        if dy.abs() > self.ea {
            return None;
        }
        self.q
            .span(dy, 1.0)
            .map(|(lo, hi)| (self.cx + lo, self.cx + hi))
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
    let (w, h) = (img.w as f64, img.h as f64);
    let theta = 0.5 * (2.0 * blob.sxy).atan2(blob.sxx - blob.syy);
    let (ct, st) = (theta.cos(), theta.sin());
    let (a, b) = (blob.a, blob.b);
    let delta = edge_margin + 0.1 * b;
    let ring_w = delta;
    let (cx, cy) = (blob.cx, blob.cy);
    // rho^2 of offset (dx, dy) for an ellipse with semi-axes (A, B).
    let rho2 = |dx: f64, dy: f64, ea: f64, eb: f64| quad(ct, st, ea, eb).eval(dx, dy);
    let (ra, rb) = (a + delta, b + delta);
    let (oa, ob) = (a + delta + 1.0 + ring_w, b + delta + 1.0 + ring_w);
    let (ia, ib) = (a + delta + 1.0, b + delta + 1.0);
    let (q_outer, q_inner, q_core) = (
        quad(ct, st, oa, ob),
        quad(ct, st, ia, ib),
        quad(ct, st, a, b),
    );
    let q_region = quad(ct, st, ra, rb);
    let half = |ea: f64, eb: f64| {
        (
            ((ea * ct).powi(2) + (eb * st).powi(2)).sqrt(),
            ((ea * st).powi(2) + (eb * ct).powi(2)).sqrt(),
        )
    };
    let (rhx, rhy) = half(ra, rb);
    if cx - rhx < 0.0 || cy - rhy < 0.0 || cx + rhx > w - 1.0 || cy + rhy > h - 1.0 {
        return Err(Fail::Border);
    }
    let (_, ohy) = half(oa, ob);
    let y0 = (cy - ohy).floor().max(0.0) as usize;
    let y1 = ((cy + ohy).ceil() as usize).min(img.h - 1);

    // Ring pixels (offsets from the blob centroid) and the core's values.
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
    for y in y0..=y1 {
        let dy = y as f64 - cy;
        let row = img.row(y);
        let outer = cols(cx, q_outer.span(dy, 1.0), img.w);
        let inner = cols(cx, q_inner.span(dy, 1.0), img.w);
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
        for x in cols(cx, q_core.span(dy, 0.25), img.w) {
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
        bg = plane_fit(&ring, |k| keep[k]).ok_or(Fail::Background)?;
    }
    let core_n = core.len();
    let fg = median(&mut core).unwrap_or(f64::NAN);
    let bg_c = bg[0];
    let s = if dark { -1.0 } else { 1.0 };
    let contrast = s * (fg - bg_c);
    if contrast.is_nan() || contrast <= 4.0 * sigma.max(0.0) || contrast <= 0.0 {
        return Err(Fail::Background);
    }
    let stripe_lim = (6.0 * sigma).max(0.2 * contrast);
    let stripe_px = ring
        .iter()
        .filter(|&&(x, y, z)| z - (bg[0] + bg[1] * x + bg[2] * y) > stripe_lim)
        .count();
    // Multiplicative illumination correction: from the background plane when the
    // plate is the brighter surface, else from a plane fitted to the circle's core
    // (light circles on a dark plate), else none.
    let illum: [f64; 3] = if bg_c > 0.0 && bg_c >= fg {
        [1.0, bg[1] / bg_c, bg[2] / bg_c]
    } else if fg > 0.0 && core_n >= 12 {
        match plane_fit(&core_pts, |_| true) {
            Some(p) if p[0] > 0.0 => [1.0, p[1] / p[0], p[2] / p[0]],
            _ => [1.0, 0.0, 0.0],
        }
    } else {
        [1.0, 0.0, 0.0]
    };
    let weight = |dx: f64, dy: f64, z: f64| {
        let b = bg[0] + bg[1] * dx + bg[2] * dy;
        let r = (illum[0] + illum[1] * dx + illum[2] * dy).max(1e-3);
        s * (z - b) / r
    };

    // Gravity.
    let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
    let ry0 = (cy - rhy).floor() as usize;
    let ry1 = ((cy + rhy).ceil() as usize).min(img.h - 1);
    for y in ry0..=ry1 {
        let dy = y as f64 - cy;
        let row = img.row(y);
        let (b0, r0) = (bg[0] + bg[2] * dy, illum[0] + illum[2] * dy);
        let xs = cols(cx, q_region.span(dy, 1.0), img.w);
        let (mut rw, mut rx) = (0.0, 0.0);
        if xs.is_empty() {
            continue;
        }
        let dx0 = xs.start as f64 - cx;
        let dx1 = (xs.end - 1) as f64 - cx;
        // relative illumination change per px along the row
        let rate = illum[1] / r0;
        if r0 > 1e-3 && rate.abs() * dx0.abs().max(dx1.abs()) < 0.02 {
            // 1 / (r0 (1 + e)) = (1 - e + e^2 - e^3) / r0 to a relative 1.6e-7 at
            // |e| < 0.02: no division per pixel; two accumulator pairs (no long chain
            // of dependent additions)
            let g0 = s / r0;
            let (mut w2, mut x2) = (0.0, 0.0);
            let px = &row[xs];
            let term = |k: usize| {
                let dx = dx0 + k as f64;
                let e = rate * dx;
                let g = g0 * (1.0 - e * (1.0 - e * (1.0 - e)));
                let wgt = (px[k].to_f32() as f64 - (b0 + bg[1] * dx)) * g;
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
            rw += w2;
            rx += x2;
        } else {
            for x in xs {
                let dx = x as f64 - cx;
                let r = (r0 + illum[1] * dx).max(1e-3);
                let wgt = s * (row[x].to_f32() as f64 - (b0 + bg[1] * dx)) / r;
                rw += wgt;
                rx += wgt * dx;
            }
        }
        sw += rw;
        sx += rx;
        sy += rw * dy;
    }
    if sw.is_nan() || sw <= 0.0 {
        return Err(Fail::Background);
    }
    let (gx, gy) = (sx / sw, sy / sw);
    let gravity = [cx + gx, cy + gy];
    let area_px = sw / contrast;

    // Ellipse: edge points along rays from the gravity centre.
    // the gravity method needs the fit for its quality figure only: 20 rays do
    let nrays = if ellipse_centre {
        ((std::f64::consts::PI * (a + b) / 1.5).round() as usize).clamp(32, 96)
    } else {
        20
    };
    let mut pts: Vec<[f64; 2]> = Vec::with_capacity(nrays);
    // ray directions by rotation from (1, 0): one sin / cos pair per blob
    let (step_s, step_c) = (std::f64::consts::TAU / nrays as f64).sin_cos();
    let (mut ux, mut uy) = (1.0f64, 0.0f64);
    for _ in 0..nrays {
        let (ux_k, uy_k) = (ux, uy);
        (ux, uy) = (ux_k * step_c - uy_k * step_s, ux_k * step_s + uy_k * step_c);
        let (ux, uy) = (ux_k, uy_k);
        let re = 1.0 / rho2(ux, uy, a, b).sqrt();
        let (t0, t1) = ((re - 2.0 * delta).max(0.5 * re), re + delta);
        let q = |t: f64| -> Option<f64> {
            let (dx, dy) = (gx + t * ux, gy + t * uy);
            let z = img.bilinear(cx + dx, cy + dy)?;
            Some(weight(dx, dy, z) / contrast)
        };
        // The edge lies near the moment ellipse: bracket the profile's 0.5 crossing
        // from there on a 0.5 px grid within [t0, t1] (outwards while the profile is
        // at or above 0.5, inwards while below), then interpolate linearly.
        let Some(at_re) = q(re) else { continue };
        let bracket = if at_re >= 0.5 {
            // outwards to the first sample below 0.5
            let (mut t, mut prev) = (re, at_re);
            loop {
                let tn = t + 0.5;
                if tn > t1 {
                    break None;
                }
                let Some(cur) = q(tn) else { break None };
                if cur < 0.5 {
                    break Some((t, prev, tn, cur));
                }
                (t, prev) = (tn, cur);
            }
        } else {
            // inwards to the first sample at or above 0.5
            let (mut t, mut cur) = (re, at_re);
            loop {
                let tp = t - 0.5;
                if tp < t0 {
                    break None;
                }
                let Some(prev) = q(tp) else { break None };
                if prev >= 0.5 {
                    break Some((tp, prev, t, cur));
                }
                (t, cur) = (tp, prev);
            }
        };
        if let Some((ta, va, tb, vb)) = bracket {
            let f = (va - 0.5) / (va - vb);
            let te = ta + f * (tb - ta);
            pts.push([gravity[0] + te * ux, gravity[1] + te * uy]);
        }
    }
    // the ellipse method's centre gets the full re-weighting; the gravity method's
    // quality figure two rounds (the outlier removal included)
    let ellipse = fit_ellipse(&pts, if ellipse_centre { 4 } else { 2 });
    Ok(Measure {
        gravity,
        ellipse,
        stripe_px,
        area_px,
    })
}

/// Conic `A x^2 + B xy + C y^2 + D x + E y + F = 0` in normalised coordinates.
type Conic = [f64; 6];

fn conic_eval(c: &Conic, x: f64, y: f64) -> (f64, f64) {
    let f = c[0] * x * x + c[1] * x * y + c[2] * y * y + c[3] * x + c[4] * y + c[5];
    let gx = 2.0 * c[0] * x + c[1] * y + c[3];
    let gy = c[1] * x + 2.0 * c[2] * y + c[4];
    (f, (gx * gx + gy * gy).sqrt())
}

/// Weighted algebraic fit with `A + C = 1`.
fn conic_fit(p: &[[f64; 2]], wts: &[f64]) -> Option<Conic> {
    let mut n = nalgebra::SMatrix::<f64, 5, 5>::zeros();
    let mut r = nalgebra::SVector::<f64, 5>::zeros();
    for (q, &wt) in p.iter().zip(wts) {
        if wt <= 0.0 {
            continue;
        }
        let (x, y) = (q[0], q[1]);
        let f = nalgebra::SVector::<f64, 5>::from([x * x - y * y, x * y, x, y, 1.0]);
        n += f * f.transpose() * wt;
        r += f * (-y * y) * wt;
    }
    let s = n.cholesky()?.solve(&r);
    Some([s[0], s[1], 1.0 - s[0], s[2], s[3], s[4]])
}

/// Fits an ellipse to edge points (px) with `rounds` (at least 2) of gradient
/// re-weighting, the second with outlier removal; `None` if too few points or not an
/// ellipse.
pub(crate) fn fit_ellipse(pts: &[[f64; 2]], rounds: usize) -> Option<Ellipse> {
    if pts.len() < 10 {
        return None;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p[0]).sum::<f64>() / n;
    let my = pts.iter().map(|p| p[1]).sum::<f64>() / n;
    let scale = (pts
        .iter()
        .map(|p| (p[0] - mx).powi(2) + (p[1] - my).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    if scale.is_nan() || scale <= 1e-9 {
        return None;
    }
    let q: Vec<[f64; 2]> = pts
        .iter()
        .map(|p| [(p[0] - mx) / scale, (p[1] - my) / scale])
        .collect();
    let mut wts = vec![1.0; q.len()];
    let mut c = conic_fit(&q, &wts)?;
    let mut dropped = false;
    for it in 0..rounds.max(2) {
        // gradient re-weighting (Sampson-like), and one round of outlier removal
        let mut res = Vec::with_capacity(q.len());
        for (p, wt) in q.iter().zip(wts.iter_mut()) {
            let (f, g) = conic_eval(&c, p[0], p[1]);
            if *wt > 0.0 {
                *wt = 1.0 / (g * g).max(1e-12);
                res.push((f / g.max(1e-12)).abs());
            } else {
                res.push(f64::INFINITY);
            }
        }
        if it == 1 && !dropped {
            let used: Vec<f64> = res.iter().copied().filter(|r| r.is_finite()).collect();
            let rms = (used.iter().map(|r| r * r).sum::<f64>() / used.len() as f64).sqrt();
            let lim = 3.0 * rms.max(0.05 / scale);
            for (wt, r) in wts.iter_mut().zip(&res) {
                if *r > lim {
                    *wt = 0.0;
                }
            }
            dropped = true;
            if wts.iter().filter(|&&w| w > 0.0).count() < 10 {
                return None;
            }
        }
        c = conic_fit(&q, &wts)?;
    }
    let disc = 4.0 * c[0] * c[2] - c[1] * c[1];
    if disc.is_nan() || disc <= 0.0 {
        return None;
    }
    // centre: [2A B; B 2C] x = -[D; E]
    let xc = (c[1] * c[4] - 2.0 * c[2] * c[3]) / disc;
    let yc = (c[1] * c[3] - 2.0 * c[0] * c[4]) / disc;
    // axes: translate to the centre, F' = F + (D xc + E yc) / 2
    let f0 = c[5] + 0.5 * (c[3] * xc + c[4] * yc);
    let m = nalgebra::Matrix2::new(c[0], 0.5 * c[1], 0.5 * c[1], c[2]);
    let eig = m.symmetric_eigen();
    let (l0, l1) = (eig.eigenvalues[0], eig.eigenvalues[1]);
    if !(-f0 / l0 > 0.0 && -f0 / l1 > 0.0) {
        return None;
    }
    let (s0, s1) = ((-f0 / l0).sqrt(), (-f0 / l1).sqrt());
    let (major, minor, k) = if s0 >= s1 { (s0, s1, 0) } else { (s1, s0, 1) };
    let v = eig.eigenvectors.column(k);
    let mut angle = v[1].atan2(v[0]);
    if angle < -std::f64::consts::FRAC_PI_2 {
        angle += std::f64::consts::PI;
    } else if angle > std::f64::consts::FRAC_PI_2 {
        angle -= std::f64::consts::PI;
    }
    let mut ss = 0.0;
    let mut cnt = 0.0;
    for (p, &wt) in q.iter().zip(&wts) {
        if wt > 0.0 {
            let (f, g) = conic_eval(&c, p[0], p[1]);
            ss += (f / g.max(1e-12)).powi(2);
            cnt += 1.0;
        }
    }
    Some(Ellipse {
        centre: [mx + xc * scale, my + yc * scale],
        axes: [major * scale, minor * scale],
        angle,
        rms: (ss / cnt).sqrt() * scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `cols` against ceil / floor, clipped to the image.
    #[test]
    fn cols_is_the_integer_range_of_a_span() {
        let w = 50;
        let reference = |cx: f64, lo: f64, hi: f64| {
            let x0 = (cx + lo).ceil().max(0.0);
            let x1 = (cx + hi).floor().min(w as f64 - 1.0);
            if x1 < x0 {
                0..0
            } else {
                x0 as usize..x1 as usize + 1
            }
        };
        for cx in [-3.0, -0.5, 0.0, 0.25, 3.0, 7.5, 48.9, 49.0, 55.0] {
            for (lo, hi) in [
                (-2.0, 2.0),
                (-0.3, 0.3),
                (-10.5, 4.0),
                (0.1, 0.2),
                (-60.0, 60.0),
                (2.0, 1.0),
            ] {
                let got = cols(cx, Some((lo, hi)), w);
                let want = reference(cx, lo, hi);
                assert!(
                    got == want || (got.is_empty() && want.is_empty()),
                    "cx {cx} span ({lo}, {hi}): {got:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn ellipse_fit_recovers_a_rotated_ellipse() {
        let (cx, cy, a, b, th) = (31.3, -7.25, 12.0, 5.5, 0.6f64);
        let pts: Vec<[f64; 2]> = (0..60)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / 60.0;
                let (x, y) = (a * t.cos(), b * t.sin());
                [
                    cx + x * th.cos() - y * th.sin(),
                    cy + x * th.sin() + y * th.cos(),
                ]
            })
            .collect();
        let e = fit_ellipse(&pts, 4).unwrap();
        assert!((e.centre[0] - cx).abs() < 1e-9 && (e.centre[1] - cy).abs() < 1e-9);
        assert!((e.axes[0] - a).abs() < 1e-9 && (e.axes[1] - b).abs() < 1e-9);
        assert!((e.angle - th).abs() < 1e-9, "{}", e.angle);
        assert!(e.rms < 1e-9);
        assert!(fit_ellipse(&pts[..5], 4).is_none());
    }
}
