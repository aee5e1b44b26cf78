//! The elliptical windows around a blob: the quadratic form of an ellipse, its integer
//! column span on a row, a blob's window (region, background ring, core), and the grown
//! shapes of neighbouring blobs that the ring must avoid.

use super::super::blobs::Blob;
use super::Fail;

/// The quadratic form `a dx^2 + b dx dy + c dy^2` of an ellipse (value 1 on it).
#[derive(Debug, Clone, Copy)]
pub(super) struct Quad {
    a: f64,
    b: f64,
    c: f64,
    /// `1 / (2 a)`, for the row spans.
    inv2a: f64,
}

impl Quad {
    /// The quadratic form of an ellipse with semi-axes `(ea, eb)`, the first along
    /// `(ct, st)`.
    pub(super) fn new(ct: f64, st: f64, ea: f64, eb: f64) -> Quad {
        let (ia, ib) = (1.0 / (ea * ea), 1.0 / (eb * eb));
        let a = ct * ct * ia + st * st * ib;
        Quad {
            a,
            b: 2.0 * ct * st * (ia - ib),
            c: st * st * ia + ct * ct * ib,
            inv2a: 0.5 / a,
        }
    }

    #[inline]
    pub(super) fn eval(&self, dx: f64, dy: f64) -> f64 {
        self.a * dx * dx + self.b * dx * dy + self.c * dy * dy
    }

    /// The `dx` interval where `eval(dx, dy) <= level` on the row `dy`, if any.
    #[inline]
    pub(super) fn span(&self, dy: f64, level: f64) -> Option<(f64, f64)> {
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
pub(super) fn cols(cx: f64, span: Option<(f64, f64)>, w: usize) -> std::ops::Range<usize> {
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

/// The windows of one blob, all centred on its centroid `(cx, cy)` and aligned with its
/// moment ellipse (semi-axes `a >= b` along `(ct, st)`): the *region* grown by `delta`,
/// the background *ring* between the `inner` and `outer` ellipses, and the *core*
/// (half the moment ellipse).
#[derive(Debug, Clone, Copy)]
pub(super) struct Window {
    pub cx: f64,
    pub cy: f64,
    pub a: f64,
    pub b: f64,
    pub delta: f64,
    pub outer: Quad,
    pub inner: Quad,
    pub core: Quad,
    pub region: Quad,
    /// Semi-axes of the outer and inner ring ellipses.
    pub outer_axes: (f64, f64),
    pub inner_axes: (f64, f64),
    /// Half height of the region's bounding box.
    pub region_half_h: f64,
    /// Rows `y0..=y1` the ring covers (clipped to the image).
    pub rows: (usize, usize),
}

impl Window {
    /// The window of `blob` with edge allowance `edge_margin` in an image of
    /// `w x h` pixels; [`Fail::Border`] when the region leaves the image.
    pub(super) fn of(blob: &Blob, edge_margin: f64, w: usize, h: usize) -> Result<Window, Fail> {
        let (wf, hf) = (w as f64, h as f64);
        let theta = 0.5 * (2.0 * blob.sxy).atan2(blob.sxx - blob.syy);
        let (ct, st) = (theta.cos(), theta.sin());
        let (a, b) = (blob.a, blob.b);
        let delta = edge_margin + 0.1 * b;
        let ring_w = delta;
        let (cx, cy) = (blob.cx, blob.cy);
        let (ra, rb) = (a + delta, b + delta);
        let (oa, ob) = (a + delta + 1.0 + ring_w, b + delta + 1.0 + ring_w);
        let (ia, ib) = (a + delta + 1.0, b + delta + 1.0);
        let (outer, inner, core) = (
            Quad::new(ct, st, oa, ob),
            Quad::new(ct, st, ia, ib),
            Quad::new(ct, st, a, b),
        );
        let region = Quad::new(ct, st, ra, rb);
        let half = |ea: f64, eb: f64| {
            (
                ((ea * ct).powi(2) + (eb * st).powi(2)).sqrt(),
                ((ea * st).powi(2) + (eb * ct).powi(2)).sqrt(),
            )
        };
        let (rhx, rhy) = half(ra, rb);
        if cx - rhx < 0.0 || cy - rhy < 0.0 || cx + rhx > wf - 1.0 || cy + rhy > hf - 1.0 {
            return Err(Fail::Border);
        }
        let (_, ohy) = half(oa, ob);
        let y0 = (cy - ohy).floor().max(0.0) as usize;
        let y1 = ((cy + ohy).ceil() as usize).min(h - 1);
        Ok(Window {
            cx,
            cy,
            a,
            b,
            delta,
            outer,
            inner,
            core,
            region,
            outer_axes: (oa, ob),
            inner_axes: (ia, ib),
            region_half_h: rhy,
            rows: (y0, y1),
        })
    }
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

impl Shape {
    pub fn of(blob: &Blob, edge_margin: f64) -> Shape {
        let theta = 0.5 * (2.0 * blob.sxy).atan2(blob.sxx - blob.syy);
        let grow = edge_margin + 0.1 * blob.b;
        Shape {
            cx: blob.cx,
            cy: blob.cy,
            ea: blob.a + grow,
            q: Quad::new(theta.cos(), theta.sin(), blob.a + grow, blob.b + grow),
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
    pub(super) fn row_span(&self, y: f64) -> Option<(f64, f64)> {
        let dy = y - self.cy;
        if dy.abs() > self.ea {
            return None;
        }
        self.q
            .span(dy, 1.0)
            .map(|(lo, hi)| (self.cx + lo, self.cx + hi))
    }
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
}
