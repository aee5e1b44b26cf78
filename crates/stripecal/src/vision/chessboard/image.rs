//! Float images for the detector: conversion from 8/16-bit views, 2 x 2 binning for
//! the pyramid, bilinear sampling and a robust noise estimate.

use crate::model::image::{ImageView, Pixel};

/// A gray image of `f32` values in the source's units (0-255 or 0-65535).
#[derive(Debug, Clone)]
pub(crate) struct Gray {
    pub w: usize,
    pub h: usize,
    pub px: Vec<f32>,
}

impl Gray {
    /// Copies a view; also returns the smallest and largest value.
    pub fn from_view<T: Pixel>(v: &ImageView<'_, T>) -> (Gray, f32, f32) {
        let (w, h) = (v.width(), v.height());
        let mut px: Vec<f32> = Vec::with_capacity(w * h);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for y in 0..h {
            let start = px.len();
            px.extend(v.row(y).iter().map(|p| p.to_f32()));
            // written so that it vectorises (no NaN in pixel values)
            for &f in &px[start..] {
                lo = if f < lo { f } else { lo };
                hi = if f > hi { f } else { hi };
            }
        }
        (Gray { w, h, px }, lo, hi)
    }

    /// Value at integer `(x, y)`; 0 outside (callers stay inside).
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        if x < self.w && y < self.h {
            self.px[y * self.w + x]
        } else {
            0.0
        }
    }

    /// Bilinear value at `(x, y)` (pixel centres at integers); `None` outside
    /// `[0, w - 1] x [0, h - 1]` or for non-finite coordinates.
    #[inline]
    pub fn bilinear(&self, x: f64, y: f64) -> Option<f32> {
        if !(x >= 0.0 && y >= 0.0 && x <= (self.w - 1) as f64 && y <= (self.h - 1) as f64) {
            return None;
        }
        // not negative here: truncation is the floor (without a call to `floor`)
        let (x0, y0) = (x as usize, y as usize);
        let (x1, y1) = ((x0 + 1).min(self.w - 1), (y0 + 1).min(self.h - 1));
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let r0 = self.px[y0 * self.w + x0] * (1.0 - fx) + self.px[y0 * self.w + x1] * fx;
        let r1 = self.px[y1 * self.w + x0] * (1.0 - fx) + self.px[y1 * self.w + x1] * fx;
        Some(r0 * (1.0 - fy) + r1 * fy)
    }

    /// The next pyramid level: the mean of each 2 x 2 block (odd last row/column
    /// dropped). Pixel `(x, y)` of the result is centred on `(2x + 0.5, 2y + 0.5)` here.
    pub fn half(&self) -> Gray {
        let (w, h) = (self.w / 2, self.h / 2);
        let mut px = vec![0f32; w * h];
        for y in 0..h {
            let r0 = &self.px[2 * y * self.w..2 * y * self.w + 2 * w];
            let r1 = &self.px[(2 * y + 1) * self.w..(2 * y + 1) * self.w + 2 * w];
            let out = &mut px[y * w..(y + 1) * w];
            for (x, o) in out.iter_mut().enumerate() {
                *o = 0.25 * (r0[2 * x] + r0[2 * x + 1] + r1[2 * x] + r1[2 * x + 1]);
            }
        }
        Gray { w, h, px }
    }
}

/// Robust standard deviation of the image noise (Immerkaer's Laplacian-difference
/// operator, median instead of mean so that edges do not count), on a sparse set of
/// pixels; at least `floor`.
pub(crate) fn noise_sigma(g: &Gray, floor: f32) -> f32 {
    if g.w < 3 || g.h < 3 {
        return floor;
    }
    let step = if g.w * g.h > 200_000 { 3 } else { 1 };
    let mut v: Vec<f32> = Vec::with_capacity((g.w / step + 1) * (g.h / step + 1));
    let w = g.w;
    for y in (1..g.h - 1).step_by(step) {
        let (a, b, c) = (
            &g.px[(y - 1) * w..y * w],
            &g.px[y * w..(y + 1) * w],
            &g.px[(y + 1) * w..(y + 2) * w],
        );
        for x in (1..w - 1).step_by(step) {
            let l = (a[x - 1] + a[x + 1] + c[x - 1] + c[x + 1])
                - 2.0 * (a[x] + c[x] + b[x - 1] + b[x + 1])
                + 4.0 * b[x];
            v.push(l.abs());
        }
    }
    if v.is_empty() {
        return floor;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f32::total_cmp);
    // The operator's output has standard deviation 6 sigma; median |N(0, 1)| = 0.6745.
    (*m / (6.0 * 0.6745)).max(floor)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_and_half() {
        let g = Gray {
            w: 4,
            h: 2,
            px: vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0],
        };
        assert_eq!(g.bilinear(0.5, 0.5), Some(2.5));
        assert_eq!(g.bilinear(3.0, 1.0), Some(7.0));
        assert_eq!(g.bilinear(3.01, 1.0), None);
        assert_eq!(g.bilinear(f64::NAN, 0.0), None);
        let h = g.half();
        assert_eq!((h.w, h.h), (2, 1));
        assert_eq!(h.px, vec![2.5, 4.5]);
    }

    #[test]
    fn noise_estimate_is_close() {
        let (w, h) = (200, 150);
        let mut s = 1u64;
        let mut px = Vec::with_capacity(w * h);
        for k in 0..w * h {
            // sum of 12 uniforms - 6: approximately N(0, 1)
            let mut acc = 0.0f32;
            for _ in 0..12 {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                acc += (s >> 40) as f32 / (1u64 << 24) as f32;
            }
            px.push(100.0 + if k % w < w / 2 { 50.0 } else { 0.0 } + 2.0 * (acc - 6.0));
        }
        let g = Gray { w, h, px };
        let n = noise_sigma(&g, 0.1);
        assert!((n - 2.0).abs() < 0.2, "{n}");
    }
}
