//! The sub-pixel peak of one scan line: local background from two flanks, width at half
//! maximum, saturation and uneven-background flags, and the centre by the iterated
//! window centroid (or the Gaussian fit started from it). Rows and columns hand their
//! segments in through [`ScanLine`], so both compute bit for bit the same.

use super::gauss::gauss_fit;
use super::ridge::{LineReject, RidgePixel};
use super::{StripeMethod, StripeOptions, FLAG_LOW_SIGNAL, FLAG_SATURATED, FLAG_UNEVEN_BACKGROUND};
use crate::model::image::{ImageView, Pixel};

/// Half length of the segment first copied around a peak, px (enough for stripes up to
/// about 6 px wide; wider ones get a second, longer copy).
pub(super) const SHORT_REACH: usize = 16;
/// Rounds of window sizing and background estimation.
pub(super) const ROUNDS: usize = 2;
/// A saturated run at least this long is a plateau: the centre comes from its edges.
pub(super) const PLATEAU_PX: usize = 2;
/// A plateau's background counts as uneven beyond this share of its height.
const PLATEAU_UNEVEN_REL: f32 = 0.25;

/// Options converted to the image's gray scale.
#[derive(Debug, Clone, Copy)]
pub(super) struct Params {
    pub d: usize,
    pub min_contrast: f32,
    pub min_width: f32,
    pub max_width: f32,
    pub window: f32,
    pub flank: usize,
    pub max_sat: usize,
    pub sat_level: f32,
    pub low_signal: f32,
    pub uneven: f32,
    pub uneven_rel: f32,
    pub method: StripeMethod,
    /// Longest half-width walk, px.
    pub limit: usize,
    /// Half length of the segment around the peak that sub-pixel work may read.
    pub reach: usize,
}

impl Params {
    pub(super) fn new<T: RidgePixel>(o: &StripeOptions) -> Params {
        Params {
            d: o.ridge_px,
            min_contrast: o.min_contrast * T::SCALE,
            min_width: o.min_width_px,
            max_width: o.max_width_px,
            window: o.window_fwhm,
            flank: o.flank_px,
            max_sat: o.max_saturated_px,
            sat_level: T::MAX,
            low_signal: o.low_signal_gray * T::SCALE,
            uneven: o.uneven_gray * T::SCALE,
            uneven_rel: o.uneven_rel,
            method: o.method,
            limit: o.max_width_px.ceil() as usize + 1,
            reach: {
                let h = (o.window_fwhm * o.max_width_px).ceil() as usize + 2;
                (h + 2 + o.flank_px).max(o.ridge_px + 1) + (o.max_width_px.ceil() as usize)
            },
        }
    }
}

/// A scan line that hands out segments of itself for the sub-pixel work.
pub(super) trait ScanLine {
    type Px: Pixel;
    /// Pixels `a..b` of the scan line.
    fn segment(&mut self, a: usize, b: usize) -> &[Self::Px];
}

/// A contiguous scan line (an image row): segments are sub-slices.
pub(super) struct RowLine<'a, T>(pub &'a [T]);

impl<T: Pixel> ScanLine for RowLine<'_, T> {
    type Px = T;
    #[inline]
    fn segment(&mut self, a: usize, b: usize) -> &[T] {
        &self.0[a..b]
    }
}

/// An image column: segments are gathered into `buf` (as `u16`, which holds both pixel
/// types exactly).
pub(super) struct ColumnLine<'a, 'b, T: RidgePixel> {
    pub img: &'a ImageView<'a, T>,
    pub x: usize,
    pub buf: &'b mut Vec<u16>,
}

impl<T: RidgePixel> ScanLine for ColumnLine<'_, '_, T> {
    type Px = u16;
    #[inline]
    fn segment(&mut self, a: usize, b: usize) -> &[u16] {
        let (img, x) = (self.img, self.x);
        self.buf.clear();
        self.buf
            .extend((a..b).map(|y| img.get(x, y).as_u32() as u16));
        self.buf
    }
}

/// Sub-pixel centre of the peak at `pk` of a scan line of `n` pixels: works on the
/// segment `pk +- reach` (clipped to the line), a short one first and a long one only
/// when the short one was too short. Returns the line position of the segment's first
/// pixel and the result. Rows and columns both come here with the same segments, so
/// `Rows` on a transposed image computes bit for bit what `Cols` computes on the image.
#[inline]
pub(super) fn line_subpixel<L: ScanLine>(
    line: &mut L,
    res: &mut Vec<f32>,
    n: usize,
    pk: usize,
    p: &Params,
) -> (usize, std::result::Result<Sub, LineReject>) {
    let short = (p.d + 1).max(SHORT_REACH);
    for reach in [short, p.reach] {
        let a = pk.saturating_sub(reach);
        let b = (pk + reach + 1).min(n);
        let out = subpixel(line.segment(a, b), pk - a, p, res);
        let cut = a > 0 || b < n;
        if reach == short && cut && matches!(out, Err(LineReject::Border)) && p.reach > short {
            continue;
        }
        return (a, out);
    }
    (0, Err(LineReject::Border))
}

/// Sub-pixel result on a segment.
#[derive(Debug, Clone, Copy)]
pub(super) struct Sub {
    pub c: f64,
    pub peak: f32,
    pub width: f32,
    pub support: f32,
    pub flags: u8,
}

/// Position (fractional index) where `y` falls to `half` walking from `pk` by `step`.
#[inline]
fn crossing<T: Pixel>(
    seg: &[T],
    pk: usize,
    step: isize,
    bg: &Background,
    half: f32,
    limit: usize,
) -> std::result::Result<f32, LineReject> {
    let mut x = pk as isize;
    let n = seg.len() as isize;
    let mut walked = 0;
    loop {
        let nx = x + step;
        if nx < 0 || nx >= n {
            return Err(LineReject::Border);
        }
        if walked > limit {
            return Err(LineReject::Shape);
        }
        let yn = seg[nx as usize].to_f32() - bg.at(nx as f32);
        if yn <= half {
            let yx = seg[x as usize].to_f32() - bg.at(x as f32);
            let t = if yx > yn {
                (yx - half) / (yx - yn)
            } else {
                0.5
            };
            return Ok(x as f32 + step as f32 * t.clamp(0.0, 1.0));
        }
        x = nx;
        walked += 1;
    }
}

/// Mean, min and max of `seg[a..b]`.
#[inline]
fn flank_stats<T: Pixel>(seg: &[T]) -> (f32, f32, f32) {
    let mut s = 0.0;
    let mut lo = f32::INFINITY;
    let mut hi = f32::NEG_INFINITY;
    for v in seg.iter().map(|v| v.to_f32()) {
        s += v;
        lo = lo.min(v);
        hi = hi.max(v);
    }
    (s / seg.len() as f32, lo, hi)
}

/// Linear background through the flank means.
#[derive(Debug, Clone, Copy)]
struct Background {
    xl: f32,
    bl: f32,
    slope: f32,
}

impl Background {
    #[inline]
    fn at(&self, x: f32) -> f32 {
        self.bl + self.slope * (x - self.xl)
    }
}

/// The peak's centre window after the background rounds (segment coordinates).
#[derive(Debug, Clone, Copy)]
struct PeakWindow {
    /// The peak pixel's value.
    vpk: f32,
    /// Peak height above the background.
    a: f32,
    bg: Background,
    /// Half width of the centroid window.
    h: f32,
    /// First pixel of the left flank, first pixel of the right flank.
    flanks: (usize, usize),
    /// The flanks disagree or are not flat.
    uneven: bool,
    /// The largest of the flanks' disagreement and their own ranges, gray.
    unevenness: f32,
    /// Half-maximum crossings left and right, and the width between them.
    l: f32,
    r: f32,
    w: f32,
}

/// Width and local background of the peak at `pk`: from the ridge test's own flank
/// pixels, then `ROUNDS` of window sizing and flank background (steps 3 and 4 of the
/// module docs).
#[inline]
fn peak_window<T: Pixel>(
    seg: &[T],
    pk: usize,
    p: &Params,
) -> std::result::Result<PeakWindow, LineReject> {
    let n = seg.len();
    let d = p.d;
    if pk < d || pk + d >= n {
        return Err(LineReject::Border);
    }
    // First guess of the background: the ridge test's own flank pixels.
    let vpk = seg[pk].to_f32();
    let b0 = 0.5 * (seg[pk - d].to_f32() + seg[pk + d].to_f32());
    let mut a = vpk - b0;
    if a < p.min_contrast {
        return Err(LineReject::Shape);
    }
    let limit = p.limit;
    let flat = Background {
        xl: 0.0,
        bl: b0,
        slope: 0.0,
    };
    let mut l = crossing(seg, pk, -1, &flat, 0.5 * a, limit)?;
    let mut r = crossing(seg, pk, 1, &flat, 0.5 * a, limit)?;
    let mut bg = flat;
    let mut h = 0.0;
    let mut flanks = (0usize, 0usize);
    let mut uneven = false;
    let mut unevenness = 0.0f32;
    for _ in 0..ROUNDS {
        let w = r - l;
        if !(w >= p.min_width && w <= p.max_width) {
            return Err(LineReject::Shape);
        }
        let cen = 0.5 * (l + r);
        h = (p.window * w).max(1.5);
        // Window pixels: round(cen - h) ..= round(cen + h) (plus a pixel of slack each side
        // for the centroid's moves); flanks beyond.
        // (x + 0.5) as i32 rounds for x > -0.5; lower values fail the border test anyway.
        // Integer bounds from here (no float round trip on the critical path).
        let lo = ((cen - h + 0.5) as i32) as i64 - 2;
        let hi = ((cen + h + 0.5) as i32) as i64 + 2;
        if lo < p.flank as i64 || hi + p.flank as i64 >= n as i64 {
            return Err(LineReject::Border);
        }
        let (lo, hi) = (lo as usize, hi as usize);
        if (lo + 1 - p.flank, hi) == flanks {
            // The same window as the last round: the same flanks, background, peak and
            // crossings follow (they depend on the window only), so l and r stand.
            continue;
        }
        flanks = (lo + 1 - p.flank, hi);
        let (ml, minl, maxl) = flank_stats(&seg[lo + 1 - p.flank..=lo]);
        let (mr, minr, maxr) = flank_stats(&seg[hi..hi + p.flank]);
        let xl = lo as f32 - 0.5 * (p.flank - 1) as f32;
        let xr = hi as f32 + 0.5 * (p.flank - 1) as f32;
        bg = Background {
            xl,
            bl: ml,
            slope: (mr - ml) / (xr - xl),
        };
        a = vpk - bg.at(pk as f32);
        if a < p.min_contrast {
            return Err(LineReject::Shape);
        }
        let tol = p.uneven + p.uneven_rel * a;
        unevenness = (mr - ml).abs().max(maxl - minl).max(maxr - minr);
        uneven = unevenness > tol;
        l = crossing(seg, pk, -1, &bg, 0.5 * a, limit)?;
        r = crossing(seg, pk, 1, &bg, 0.5 * a, limit)?;
    }
    let w = r - l;
    if !(w >= p.min_width && w <= p.max_width) {
        return Err(LineReject::Shape);
    }
    Ok(PeakWindow {
        vpk,
        a,
        bg,
        h,
        flanks,
        uneven,
        unevenness,
        l,
        r,
        w,
    })
}

/// The longest run of saturated pixels in the support (flanks included); 0 when the
/// peak itself is not saturated.
#[inline]
fn longest_saturated_run<T: Pixel>(seg: &[T], win: &PeakWindow, p: &Params) -> usize {
    let (f0, f1) = (win.flanks.0, (win.flanks.1 + p.flank).min(seg.len()));
    let mut run = 0usize;
    let mut longest = 0usize;
    let sat_seg = if win.vpk >= p.sat_level {
        &seg[f0..f1]
    } else {
        &seg[0..0]
    };
    for v in sat_seg.iter().map(|v| v.to_f32()) {
        if v >= p.sat_level {
            run += 1;
            longest = longest.max(run);
        } else {
            run = 0;
        }
    }
    longest
}

/// The background-free residuals of the window pixels `px` (the first at segment index
/// `x0`), and their prefix sums of `y` and of `y * k`, all in `res`: the window's
/// interior sums are O(1) in every centroid iteration.
#[inline]
fn residual_sums<'r, T: Pixel>(
    px: &[T],
    bg: &Background,
    x0: usize,
    res: &'r mut Vec<f32>,
) -> (&'r [f32], &'r [f32], &'r [f32]) {
    let m = px.len();
    // (every entry is written below: no clearing)
    if res.len() < 3 * m + 2 {
        res.resize(3 * m + 2, 0.0);
    }
    let (vals, pre) = res[..3 * m + 2].split_at_mut(m);
    let (pre0, pre1) = pre.split_at_mut(m + 1);
    pre0[0] = 0.0;
    pre1[0] = 0.0;
    for (k, (o, v)) in vals.iter_mut().zip(px).enumerate() {
        *o = v.to_f32() - bg.at((x0 + k) as f32);
    }
    // (kf counts 0, 1, 2, ... exactly: the same products as y * k as f32)
    let (mut a0, mut a1, mut kf) = (0.0f32, 0.0f32, 0.0f32);
    for ((&y, s0), s1) in vals.iter().zip(&mut pre0[1..]).zip(&mut pre1[1..]) {
        a0 += y;
        a1 += y * kf;
        kf += 1.0;
        *s0 = a0;
        *s1 = a1;
    }
    (vals, pre0, pre1)
}

/// The gray centroid of the residuals `res` over `c +- h` with fractional end weights,
/// iterated to a fixed point from `c0` (the middle of the half-maximum crossings, `w`
/// apart); `pre0`, `pre1` are the prefix sums of [`residual_sums`], `last` the last index.
#[inline]
fn window_centroid(
    (res, pre0, pre1): (&[f32], &[f32], &[f32]),
    c0: f32,
    h: f32,
    w: f32,
    last: usize,
) -> std::result::Result<f32, LineReject> {
    let mut c = c0;
    for _ in 0..6 {
        let (lo, hi) = (c - h, c + h);
        // `as` truncation rounds for lo + 0.5 >= 0; below that it is clamped to 0 (the
        // window is clipped to the residuals either way).
        let i0 = ((lo + 0.5) as i32).max(0) as usize;
        let i1 = (((hi + 0.5) as i32).max(0) as usize).min(last);
        if i1 <= i0 {
            return Err(LineReject::Shape);
        }
        // interior pixels i0 + 1 .. i1 from the prefix sums
        let mut s = pre0[i1] - pre0[i0 + 1];
        let mut sx = (pre1[i1] - pre1[i0 + 1]) - c * s;
        let w0 = (i0 as f32 + 0.5 - lo).clamp(0.0, 1.0) * res[i0];
        let w1 = (hi - (i1 as f32 - 0.5)).clamp(0.0, 1.0) * res[i1];
        s += w0 + w1;
        sx += w0 * (i0 as f32 - c) + w1 * (i1 as f32 - c);
        if s <= 0.0 {
            return Err(LineReject::Shape);
        }
        let dc = sx / s;
        c += dc;
        if (c - c0).abs() > w {
            return Err(LineReject::Shape);
        }
        if dc.abs() < 1e-3 {
            break;
        }
    }
    Ok(c)
}

/// The sub-pixel centre of the peak at `pk` (index into the scan line `seg`); `res` is
/// scratch space for the background-free residuals.
pub(super) fn subpixel<T: Pixel>(
    seg: &[T],
    pk: usize,
    p: &Params,
    res: &mut Vec<f32>,
) -> std::result::Result<Sub, LineReject> {
    let win = peak_window(seg, pk, p)?;
    // Saturation: any saturated pixel in the support flags; a long plateau rejects.
    let mut flags = 0u8;
    let longest = longest_saturated_run(seg, &win, p);
    if longest > 0 {
        flags |= FLAG_SATURATED;
        if longest > p.max_sat {
            return Err(LineReject::Saturated);
        }
    }
    // A plateau's centre comes from its steep edges, which a background step moves by
    // far less than it moves a centroid: only a step of a good part of its height counts
    // (the halo and speckle around a saturated line are not one).
    let uneven = if longest >= PLATEAU_PX {
        win.unevenness > PLATEAU_UNEVEN_REL * win.a
    } else {
        win.uneven
    };
    if uneven {
        flags |= FLAG_UNEVEN_BACKGROUND;
    }
    if win.a < p.low_signal {
        flags |= FLAG_LOW_SIGNAL;
    }
    let (flanks, w, h) = (win.flanks, win.w, win.h);
    // Residuals over the pixels the window may use; res[k] is pixel xmin + k.
    // Coordinates relative to xmin from here.
    let (xmin, xmax) = (flanks.0 + p.flank, flanks.1 - 1);
    let (l, r) = (win.l - xmin as f32, win.r - xmin as f32);
    let last = xmax - xmin;
    if longest >= PLATEAU_PX {
        // A saturated plateau: its top is clipped, so its middle is where the two
        // edges' half-maximum crossings put it (as line profilers take it).
        let c = 0.5 * (l + r) + xmin as f32;
        return Ok(Sub {
            c: c as f64,
            peak: win.a,
            width: w,
            support: (c - flanks.0 as f32 + 0.5).max(flanks.1 as f32 + p.flank as f32 - 0.5 - c),
            flags,
        });
    }
    let sums = residual_sums(&seg[xmin..=xmax], &win.bg, xmin, res);
    let c = window_centroid(sums, 0.5 * (l + r), h, w, last)?;
    let mut cf = c as f64;
    if p.method == StripeMethod::Gaussian {
        if let Some(g) = gauss_fit(sums.0, c, win.a, w, h, 0, last) {
            cf = g;
        }
    }
    let c = c + xmin as f32;
    let cf = cf + xmin as f64;
    Ok(Sub {
        c: cf,
        peak: win.a,
        width: w,
        support: (c - flanks.0 as f32 + 0.5).max(flanks.1 as f32 + p.flank as f32 - 0.5 - c),
        flags,
    })
}
