//! The extractor: ridge search per scan line, then the sub-pixel centre of the chosen peak.

use super::{
    RejectCounts, StripeDirection, StripeMethod, StripeOptions, StripePoint, FLAG_LOW_SIGNAL,
    FLAG_OBLIQUE, FLAG_SATURATED, FLAG_UNEVEN_BACKGROUND,
};
use crate::error::Result;
use crate::model::image::{AnyView, ImageView, Pixel};

/// Pixels of a ridge-test block: the vectorised pass tests this many pixels at once, and
/// only a block holding a response above the threshold is looked at further.
const CHUNK: usize = 64;
/// Candidate runs closer than this (pixels between them) are one run.
const MERGE_GAP: u32 = 2;
/// Half length of the segment first copied around a peak, px (enough for stripes up to
/// about 6 px wide; wider ones get a second, longer copy).
const SHORT_REACH: usize = 16;
/// Rounds of window sizing and background estimation.
const ROUNDS: usize = 2;
/// Auto direction: every `AUTO_STEP`-th row and column is sampled.
const AUTO_STEP: usize = 4;

/// Integer pixel operations of the ridge pass.
pub(crate) trait RidgePixel: Pixel + Ord {
    const ZERO: Self;
    /// Gray levels per 8-bit gray level (1 or 257).
    const SCALE: f32;
    fn sat_sub(self, o: Self) -> Self;
    fn as_u32(self) -> u32;
    fn from_u32_clamped(x: u32) -> Self;
}

impl RidgePixel for u8 {
    const ZERO: Self = 0;
    const SCALE: f32 = 1.0;
    #[inline(always)]
    fn sat_sub(self, o: Self) -> Self {
        self.saturating_sub(o)
    }
    #[inline(always)]
    fn as_u32(self) -> u32 {
        self as u32
    }
    #[inline(always)]
    fn from_u32_clamped(x: u32) -> Self {
        x.min(u8::MAX as u32) as u8
    }
}

impl RidgePixel for u16 {
    const ZERO: Self = 0;
    const SCALE: f32 = 257.0;
    #[inline(always)]
    fn sat_sub(self, o: Self) -> Self {
        self.saturating_sub(o)
    }
    #[inline(always)]
    fn as_u32(self) -> u32 {
        self as u32
    }
    #[inline(always)]
    fn from_u32_clamped(x: u32) -> Self {
        x.min(u16::MAX as u32) as u16
    }
}

/// A run of consecutive ridge responses above the threshold.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Run {
    last: u32,
    strength: u32,
    vmax: u32,
    pfirst: u32,
    plast: u32,
}

/// Peak candidates of one scan line: the strongest run and the strength of the next.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct LineCand {
    cur: Run,
    active: bool,
    best: Run,
    has_best: bool,
    second: u32,
}

impl LineCand {
    #[inline]
    fn push(&mut self, pos: u32, r: u32, v: u32) {
        if self.active && pos <= self.cur.last + 1 + MERGE_GAP {
            let c = &mut self.cur;
            c.last = pos;
            c.strength = c.strength.max(r);
            if v > c.vmax {
                c.vmax = v;
                c.pfirst = pos;
                c.plast = pos;
            } else if v == c.vmax {
                c.plast = pos;
            }
        } else {
            self.close();
            self.cur = Run {
                last: pos,
                strength: r,
                vmax: v,
                pfirst: pos,
                plast: pos,
            };
            self.active = true;
        }
    }

    fn close(&mut self) {
        if !self.active {
            return;
        }
        self.active = false;
        let c = self.cur;
        if !self.has_best {
            self.best = c;
            self.has_best = true;
        } else if c.strength > self.best.strength {
            self.second = self.second.max(self.best.strength);
            self.best = c;
        } else {
            self.second = self.second.max(c.strength);
        }
    }

    /// The peak pixel of the single trustworthy run, or why there is none.
    fn verdict(&self, ratio: f32) -> std::result::Result<usize, LineReject> {
        if !self.has_best {
            return Err(LineReject::NoPeak);
        }
        if self.second as f32 >= ratio * self.best.strength as f32 {
            return Err(LineReject::Multiple);
        }
        Ok(((self.best.pfirst + self.best.plast) / 2) as usize)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LineReject {
    NoPeak,
    Multiple,
    Shape,
    Saturated,
    Border,
}

/// Ridge responses of one block of `CHUNK` positions: `m[i] - max(a[i], b[i])`
/// (saturating). Fixed width, so the compiler unrolls and vectorises it (`u8`: 16 lanes
/// per SSE2 register) without bounds checks.
#[inline(always)]
fn block_response<T: RidgePixel>(
    a: &[T; CHUNK],
    m: &[T; CHUNK],
    b: &[T; CHUNK],
    out: &mut [T; CHUNK],
) {
    for i in 0..CHUNK {
        out[i] = m[i].sat_sub(a[i].max(b[i]));
    }
}

/// Largest ridge response of a block (the coarse test: almost every block of an image
/// is below the threshold and is done after this).
#[inline(always)]
fn block_max<T: RidgePixel>(a: &[T; CHUNK], m: &[T; CHUNK], b: &[T; CHUNK]) -> T {
    let mut mx = T::ZERO;
    for i in 0..CHUNK {
        mx = mx.max(m[i].sat_sub(a[i].max(b[i])));
    }
    mx
}

/// The responses of a block that passed the coarse test: those `>= thr` at block
/// offsets `>= skip` go to `f(offset, r, value)` in increasing offset. The threshold test
/// is vectorised into 0/1 bytes; the set ones are found eight at a time.
#[inline(always)]
fn block_detail<T: RidgePixel>(
    a: &[T; CHUNK],
    m: &[T; CHUNK],
    b: &[T; CHUNK],
    thr: T,
    skip: usize,
    mut f: impl FnMut(usize, u32, u32),
) {
    let mut r = [T::ZERO; CHUNK];
    block_response(a, m, b, &mut r);
    let mut hit = [0u8; CHUNK];
    for i in 0..CHUNK {
        hit[i] = (r[i] >= thr) as u8;
    }
    for (k, word) in hit.chunks_exact(8).enumerate() {
        let mut bits = u64::from_le_bytes([
            word[0], word[1], word[2], word[3], word[4], word[5], word[6], word[7],
        ]);
        while bits != 0 {
            let i = 8 * k + (bits.trailing_zeros() / 8) as usize;
            bits &= bits - 1;
            if i >= skip {
                f(i, r[i].as_u32(), m[i].as_u32());
            }
        }
    }
}

/// The ridge test `r(i) = m[i] - max(a[i], b[i])` over three aligned lines (the first
/// `len` pixels, `len` the shortest of the three); responses `>= thr` go to
/// `f(i, r, m[i])` in increasing `i`. Full blocks of `CHUNK` come from `chunks_exact`
/// (no bounds checks); a last partial block is taken as the full block ending at `len`,
/// overlapping the one before (positions already seen are skipped), so every block is
/// full width. Lines shorter than a block go pixel by pixel.
#[inline(always)]
fn ridge_blocks<T: RidgePixel>(
    a: &[T],
    m: &[T],
    b: &[T],
    thr: T,
    mut f: impl FnMut(usize, u32, u32),
) {
    let len = m.len().min(a.len()).min(b.len());
    let (a, m, b) = (&a[..len], &m[..len], &b[..len]);
    if len < CHUNK {
        for i in 0..len {
            let r = m[i].sat_sub(a[i].max(b[i]));
            if r >= thr {
                f(i, r.as_u32(), m[i].as_u32());
            }
        }
        return;
    }
    let blocks = a
        .chunks_exact(CHUNK)
        .zip(m.chunks_exact(CHUNK))
        .zip(b.chunks_exact(CHUNK));
    for (k, ((ca, cm), cb)) in blocks.enumerate() {
        let (Ok(ca), Ok(cm), Ok(cb)) = (ca.try_into(), cm.try_into(), cb.try_into()) else {
            continue;
        };
        if block_max(ca, cm, cb) >= thr {
            let base = k * CHUNK;
            block_detail(ca, cm, cb, thr, 0, |i, r, v| f(base + i, r, v));
        }
    }
    let full = len / CHUNK * CHUNK;
    if full < len {
        let start = len - CHUNK;
        let (ca, cm, cb) = (&a[start..], &m[start..], &b[start..]);
        if let (Ok(ca), Ok(cm), Ok(cb)) = (ca.try_into(), cm.try_into(), cb.try_into()) {
            if block_max(ca, cm, cb) >= thr {
                block_detail(ca, cm, cb, thr, full - start, |i, r, v| f(start + i, r, v));
            }
        }
    }
}

/// `r(x) = I(x) - max(I(x - d), I(x + d))` over a contiguous scan line; runs above `thr`
/// go to `cand`.
#[inline(always)]
fn scan_line_generic<T: RidgePixel>(line: &[T], d: usize, thr: T, cand: &mut LineCand) {
    let n = line.len();
    if n < 2 * d + 1 {
        return;
    }
    // position x = d + i compares line[x] with line[x - d] and line[x + d]
    ridge_blocks(
        &line[..n - 2 * d],
        &line[d..n - d],
        &line[2 * d..],
        thr,
        |i, r, v| cand.push((d + i) as u32, r, v),
    );
    cand.close();
}

/// The ridge test down every column at once, row by row (cache friendly): column `x`'s
/// candidates go to `cands[x]` (`cands.len() == img.width()`). The same blocks, responses
/// and candidate order as [`scan_line_generic`] on the transposed image.
#[inline(always)]
fn scan_columns_generic<T: RidgePixel>(
    img: &ImageView<'_, T>,
    d: usize,
    thr: T,
    cands: &mut [LineCand],
) {
    let h = img.height();
    if h < 2 * d + 1 {
        return;
    }
    for y in d..h - d {
        let (ra, rm, rb) = (img.row(y - d), img.row(y), img.row(y + d));
        ridge_blocks(ra, rm, rb, thr, |i, r, v| {
            if let Some(c) = cands.get_mut(i) {
                c.push(y as u32, r, v);
            }
        });
    }
    for c in cands.iter_mut() {
        c.close();
    }
}

/// Whether the CPU runs AVX2 (std detects it once and caches it). The library is built
/// for the x86-64 baseline (SSE2); the ridge passes are compiled a second time with AVX2
/// enabled (32 byte lanes) and chosen here at run time.
#[inline]
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// [`scan_line_generic`], with AVX2 where the CPU has it (the same results).
#[inline]
fn scan_line<T: RidgePixel>(line: &[T], d: usize, thr: T, cand: &mut LineCand) {
    #[cfg(target_arch = "x86_64")]
    if has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
        // calling a `#[target_feature(enable = "avx2")]` function.
        unsafe { scan_line_avx2(line, d, thr, cand) };
        return;
    }
    scan_line_generic(line, d, thr, cand)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn scan_line_avx2<T: RidgePixel>(line: &[T], d: usize, thr: T, cand: &mut LineCand) {
    scan_line_generic(line, d, thr, cand)
}

/// [`scan_columns_generic`], with AVX2 where the CPU has it (the same results).
fn scan_columns<T: RidgePixel>(img: &ImageView<'_, T>, d: usize, thr: T, cands: &mut [LineCand]) {
    #[cfg(target_arch = "x86_64")]
    if has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
        // calling a `#[target_feature(enable = "avx2")]` function.
        unsafe { scan_columns_avx2(img, d, thr, cands) };
        return;
    }
    scan_columns_generic(img, d, thr, cands)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn scan_columns_avx2<T: RidgePixel>(
    img: &ImageView<'_, T>,
    d: usize,
    thr: T,
    cands: &mut [LineCand],
) {
    scan_columns_generic(img, d, thr, cands)
}

/// Options converted to the image's gray scale.
#[derive(Debug, Clone, Copy)]
struct Params {
    d: usize,
    min_contrast: f32,
    min_width: f32,
    max_width: f32,
    window: f32,
    flank: usize,
    max_sat: usize,
    sat_level: f32,
    low_signal: f32,
    uneven: f32,
    uneven_rel: f32,
    method: StripeMethod,
    /// Longest half-width walk, px.
    limit: usize,
    /// Half length of the segment around the peak that sub-pixel work may read.
    reach: usize,
}

impl Params {
    fn new<T: RidgePixel>(o: &StripeOptions) -> Params {
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
trait ScanLine {
    type Px: Pixel;
    /// Pixels `a..b` of the scan line.
    fn segment(&mut self, a: usize, b: usize) -> &[Self::Px];
}

/// A contiguous scan line (an image row): segments are sub-slices.
struct RowLine<'a, T>(&'a [T]);

impl<T: Pixel> ScanLine for RowLine<'_, T> {
    type Px = T;
    #[inline]
    fn segment(&mut self, a: usize, b: usize) -> &[T] {
        &self.0[a..b]
    }
}

/// An image column: segments are gathered into `buf` (as `u16`, which holds both pixel
/// types exactly).
struct ColumnLine<'a, 'b, T: RidgePixel> {
    img: &'a ImageView<'a, T>,
    x: usize,
    buf: &'b mut Vec<u16>,
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
fn line_subpixel<L: ScanLine>(
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
struct Sub {
    c: f64,
    peak: f32,
    width: f32,
    support: f32,
    flags: u8,
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

/// The sub-pixel centre of the peak at `pk` (index into the scan line `seg`); `res` is
/// scratch space for the background-free residuals.
fn subpixel<T: Pixel>(
    seg: &[T],
    pk: usize,
    p: &Params,
    res: &mut Vec<f32>,
) -> std::result::Result<Sub, LineReject> {
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
        uneven = (mr - ml).abs() > tol || maxl - minl > tol || maxr - minr > tol;
        l = crossing(seg, pk, -1, &bg, 0.5 * a, limit)?;
        r = crossing(seg, pk, 1, &bg, 0.5 * a, limit)?;
    }
    let w = r - l;
    if !(w >= p.min_width && w <= p.max_width) {
        return Err(LineReject::Shape);
    }
    // Saturation: any saturated pixel in the support flags; a long plateau rejects.
    let mut flags = 0u8;
    let (f0, f1) = (flanks.0, (flanks.1 + p.flank).min(n));
    let mut run = 0usize;
    let mut longest = 0usize;
    let sat_seg = if vpk >= p.sat_level {
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
    if longest > 0 {
        flags |= FLAG_SATURATED;
        if longest > p.max_sat {
            return Err(LineReject::Saturated);
        }
    }
    if uneven {
        flags |= FLAG_UNEVEN_BACKGROUND;
    }
    if a < p.low_signal {
        flags |= FLAG_LOW_SIGNAL;
    }
    // Residuals over the pixels the window may use; res[k] is pixel xmin + k.
    // Coordinates relative to xmin from here.
    let (xmin, xmax) = (flanks.0 + p.flank, flanks.1 - 1);
    let (l, r) = (l - xmin as f32, r - xmin as f32);
    let last = xmax - xmin;
    let m = last + 1;
    // The residuals, then their prefix sums of y and of y * k: the window's interior sums
    // are O(1) in every centroid iteration.
    res.clear();
    res.resize(3 * m + 2, 0.0);
    let (vals, pre) = res.split_at_mut(m);
    let (pre0, pre1) = pre.split_at_mut(m + 1);
    for (k, (o, v)) in vals.iter_mut().zip(&seg[xmin..=xmax]).enumerate() {
        *o = v.to_f32() - bg.at((xmin + k) as f32);
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
    let (res, pre0, pre1) = (&*vals, &*pre0, &*pre1);
    let mut c = 0.5 * (l + r);
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
        if (c - 0.5 * (l + r)).abs() > w {
            return Err(LineReject::Shape);
        }
        if dc.abs() < 1e-3 {
            break;
        }
    }
    let mut cf = c as f64;
    if p.method == StripeMethod::Gaussian {
        if let Some(g) = gauss_fit(res, c, a, w, h, 0, last) {
            cf = g;
        }
    }
    let c = c + xmin as f32;
    let cf = cf + xmin as f64;
    Ok(Sub {
        c: cf,
        peak: a,
        width: w,
        support: (c - flanks.0 as f32 + 0.5).max(flanks.1 as f32 + p.flank as f32 - 0.5 - c),
        flags,
    })
}

/// Gauss-Newton fit of `A exp(-(x - c)^2 / 2 s^2)` to the residuals `res` over
/// `c +- (h + 1)`.
fn gauss_fit(
    res: &[f32],
    c0: f32,
    a0: f32,
    w: f32,
    h: f32,
    xmin: usize,
    xmax: usize,
) -> Option<f64> {
    let i0 = ((c0 - h - 1.0).round().max(xmin as f32)) as usize;
    let i1 = ((c0 + h + 1.0).round().min(xmax as f32)) as usize;
    if i1 < i0 + 3 {
        return None;
    }
    let (mut amp, mut c, mut s) = (a0 as f64, c0 as f64, (w / 2.3548).max(0.3) as f64);
    for _ in 0..10 {
        let mut jtj = [[0.0f64; 3]; 3];
        let mut jtr = [0.0f64; 3];
        for (i, &v) in res.iter().enumerate().take(i1 + 1).skip(i0) {
            let x = i as f64;
            let y = v as f64;
            let t = (x - c) / s;
            let e = (-0.5 * t * t).exp();
            let f = amp * e;
            let j = [e, f * t / s, f * t * t / s];
            let res = y - f;
            for r in 0..3 {
                jtr[r] += j[r] * res;
                for q in 0..3 {
                    jtj[r][q] += j[r] * j[q];
                }
            }
        }
        let delta = solve3(&jtj, &jtr)?;
        amp += delta[0];
        c += delta[1];
        s += delta[2];
        if !(amp > 0.0 && s > 0.2 && s < w as f64 && (c - c0 as f64).abs() < 0.5 * w as f64) {
            return None;
        }
        if delta[1].abs() < 1e-5 {
            return Some(c);
        }
    }
    Some(c)
}

/// Solves a 3x3 symmetric system (Cramer's rule); `None` when singular.
fn solve3(a: &[[f64; 3]; 3], b: &[f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if !d.is_finite() || d.abs() <= 1e-12 {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut m = *a;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        *o = det(&m) / d;
    }
    Some(out)
}

/// A reusable stripe extractor: keeps its buffers between images, so line software
/// that calls [`StripeExtractor::extract_into`] per frame allocates nothing after the
/// first frame of a given size.
#[derive(Debug, Clone)]
pub struct StripeExtractor {
    opts: StripeOptions,
    cands: Vec<LineCand>,
    /// Candidates of the rows sampled by the auto decision.
    rows: Vec<LineCand>,
    seg: Vec<f32>,
    col: Vec<u16>,
    rejected: RejectCounts,
}

impl StripeExtractor {
    /// An extractor; errors on invalid options.
    pub fn new(opts: StripeOptions) -> Result<StripeExtractor> {
        opts.validate()?;
        Ok(StripeExtractor {
            opts,
            cands: Vec::new(),
            rows: Vec::new(),
            seg: Vec::new(),
            col: Vec::new(),
            rejected: RejectCounts::default(),
        })
    }

    /// The options in use.
    pub fn options(&self) -> &StripeOptions {
        &self.opts
    }

    /// Why scan lines of the last image gave no point.
    pub fn rejected(&self) -> RejectCounts {
        self.rejected
    }

    /// Extracts the stripe of `img` into `out` (cleared first), in scan-line order, and
    /// returns the direction used. An image without a stripe gives no points (not an
    /// error). No panics for any image content.
    pub fn extract_into(
        &mut self,
        img: AnyView<'_>,
        out: &mut Vec<StripePoint>,
    ) -> Result<StripeDirection> {
        out.clear();
        self.rejected = RejectCounts::default();
        match img {
            AnyView::U8(v) => self.run(&v, out),
            AnyView::U16(v) => self.run(&v, out),
        }
    }

    fn run<T: RidgePixel>(
        &mut self,
        img: &ImageView<'_, T>,
        out: &mut Vec<StripePoint>,
    ) -> Result<StripeDirection> {
        let (dir, auto) = match self.opts.direction {
            StripeDirection::Auto => (
                auto_direction(img, &self.opts, &mut self.cands, &mut self.rows),
                true,
            ),
            d => (d, false),
        };
        let p = Params::new::<T>(&self.opts);
        let thr = T::from_u32_clamped(p.min_contrast.ceil().max(1.0) as u32);
        let (w, h) = (img.width(), img.height());
        let ratio = self.opts.second_peak_ratio;
        let mut rej = RejectCounts::default();
        let mut count = |r: LineReject| match r {
            LineReject::NoPeak => rej.no_peak += 1,
            LineReject::Multiple => rej.multiple_peaks += 1,
            LineReject::Shape => rej.shape += 1,
            LineReject::Saturated => rej.saturated += 1,
            LineReject::Border => rej.border += 1,
        };
        match dir {
            StripeDirection::Rows => {
                if !auto {
                    self.cands.clear();
                    self.cands.resize(w, LineCand::default());
                    scan_columns(img, p.d, thr, &mut self.cands);
                }
                for x in 0..w {
                    let pk = match self.cands[x].verdict(ratio) {
                        Ok(pk) => pk,
                        Err(e) => {
                            count(e);
                            continue;
                        }
                    };
                    let mut line = ColumnLine {
                        img,
                        x,
                        buf: &mut self.col,
                    };
                    let (y0, res) = line_subpixel(&mut line, &mut self.seg, h, pk, &p);
                    match res {
                        Ok(s) => out.push(StripePoint {
                            u: x as f64,
                            v: y0 as f64 + s.c,
                            peak: s.peak,
                            width_px: s.width,
                            support_px: s.support,
                            flags: s.flags,
                        }),
                        Err(e) => count(e),
                    }
                }
            }
            _ => {
                for y in 0..h {
                    let row = img.row(y);
                    // rows that the auto decision sampled are scanned already
                    let sampled = (auto && y % AUTO_STEP == AUTO_STEP / 2)
                        .then(|| self.rows.get(y / AUTO_STEP).copied())
                        .flatten();
                    let cand = sampled.unwrap_or_else(|| {
                        let mut cand = LineCand::default();
                        scan_line(row, p.d, thr, &mut cand);
                        cand
                    });
                    let pk = match cand.verdict(ratio) {
                        Ok(pk) => pk,
                        Err(e) => {
                            count(e);
                            continue;
                        }
                    };
                    let (x0, res) = line_subpixel(&mut RowLine(row), &mut self.seg, w, pk, &p);
                    match res {
                        Ok(s) => out.push(StripePoint {
                            u: x0 as f64 + s.c,
                            v: y as f64,
                            peak: s.peak,
                            width_px: s.width,
                            support_px: s.support,
                            flags: s.flags,
                        }),
                        Err(e) => count(e),
                    }
                }
            }
        }
        let dir = if dir == StripeDirection::Rows {
            StripeDirection::Rows
        } else {
            StripeDirection::Cols
        };
        rej.isolated = continuity(out, dir, self.opts.min_chain, self.opts.max_jump_px);
        flag_oblique(out, dir, self.opts.max_slope);
        self.rejected = rej;
        Ok(dir)
    }
}

/// Drops points that are not part of a chain of `min_chain` neighbouring scan lines;
/// returns how many were dropped.
fn continuity(
    pts: &mut Vec<StripePoint>,
    dir: StripeDirection,
    min_chain: usize,
    max_jump: f32,
) -> usize {
    if min_chain <= 1 || pts.is_empty() {
        return 0;
    }
    let key = |p: &StripePoint| {
        if dir == StripeDirection::Rows {
            (p.u, p.v)
        } else {
            (p.v, p.u)
        }
    };
    let n = pts.len();
    let mut start = 0;
    let mut dropped = 0;
    for i in 1..=n {
        let linked = i < n && {
            let (la, pa) = key(&pts[i - 1]);
            let (lb, pb) = key(&pts[i]);
            let gap = lb - la;
            gap <= 2.0 && (pb - pa).abs() <= max_jump as f64 * gap
        };
        if !linked {
            if i - start < min_chain {
                for p in &mut pts[start..i] {
                    p.support_px = -1.0;
                }
                dropped += i - start;
            }
            start = i;
        }
    }
    if dropped > 0 {
        pts.retain(|p| p.support_px >= 0.0);
    }
    dropped
}

/// Flags [`FLAG_OBLIQUE`] where the slope from the neighbouring points (within 2 scan
/// lines) exceeds `max_slope`.
fn flag_oblique(pts: &mut [StripePoint], dir: StripeDirection, max_slope: f32) {
    let key = |p: &StripePoint| {
        if dir == StripeDirection::Rows {
            (p.u, p.v)
        } else {
            (p.v, p.u)
        }
    };
    let n = pts.len();
    for i in 0..n {
        let (l, x) = key(&pts[i]);
        let near = |j: usize| {
            let (lj, xj) = key(&pts[j]);
            ((lj - l).abs() <= 2.0).then_some((lj, xj))
        };
        let a = if i > 0 { near(i - 1) } else { None }.unwrap_or((l, x));
        let b = if i + 1 < n { near(i + 1) } else { None }.unwrap_or((l, x));
        if b.0 > a.0 && ((b.1 - a.1) / (b.0 - a.0)).abs() > max_slope as f64 {
            pts[i].flags |= FLAG_OBLIQUE;
        }
    }
}

/// Decides the scan direction of an image: the ridge test on every 4th row and on every
/// column; the direction that yields more single-peak scan lines wins (the rows found,
/// scaled by 4, against the columns found); ties and images without any stripe give
/// `Cols`.
pub fn resolve_direction(img: AnyView<'_>, opts: &StripeOptions) -> Result<StripeDirection> {
    opts.validate()?;
    let (mut cands, mut rows) = (Vec::new(), Vec::new());
    Ok(match img {
        AnyView::U8(v) => auto_direction(&v, opts, &mut cands, &mut rows),
        AnyView::U16(v) => auto_direction(&v, opts, &mut cands, &mut rows),
    })
}

/// The auto decision; leaves the column candidates of the whole image in `cands` (the
/// work a `Rows` extraction needs anyway) and those of the sampled rows in `rows` (row
/// `AUTO_STEP / 2 + k * AUTO_STEP` at `k`: a `Cols` extraction reuses them).
fn auto_direction<T: RidgePixel>(
    img: &ImageView<'_, T>,
    opts: &StripeOptions,
    cands: &mut Vec<LineCand>,
    rows: &mut Vec<LineCand>,
) -> StripeDirection {
    let (w, h) = (img.width(), img.height());
    let thr = T::from_u32_clamped((opts.min_contrast * T::SCALE).ceil().max(1.0) as u32);
    let ratio = opts.second_peak_ratio;
    let d = opts.ridge_px;
    let (mut rows_hit, mut rows_n) = (0usize, 0usize);
    rows.clear();
    for y in (AUTO_STEP / 2..h).step_by(AUTO_STEP) {
        let mut c = LineCand::default();
        scan_line(img.row(y), d, thr, &mut c);
        rows_n += 1;
        rows_hit += c.verdict(ratio).is_ok() as usize;
        rows.push(c);
    }
    // Columns: the row-wise (cache friendly) ridge test of every column.
    cands.clear();
    cands.resize(w, LineCand::default());
    scan_columns(img, d, thr, cands);
    let cols_hit = cands.iter().filter(|c| c.verdict(ratio).is_ok()).count();
    let per_row = if rows_n > 0 {
        rows_hit as f64 / rows_n as f64 * h as f64
    } else {
        0.0
    };
    if cols_hit as f64 > per_row {
        StripeDirection::Rows
    } else {
        StripeDirection::Cols
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vision::stripe::{extract_stripe, StripeOptions};

    /// A synthetic Gaussian stripe `u = u0 + slope * v` on a flat background.
    fn synth(w: usize, h: usize, u0: f64, slope: f64, sigma: f64, amp: f64, bg: f64) -> Vec<u8> {
        let mut img = vec![0u8; w * h];
        for y in 0..h {
            let c = u0 + slope * y as f64;
            for x in 0..w {
                let t = (x as f64 - c) / sigma;
                let v = bg + amp * (-0.5 * t * t).exp();
                img[y * w + x] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
        img
    }

    #[test]
    fn finds_a_synthetic_stripe_in_both_directions() {
        let (w, h) = (120, 90);
        let img = synth(w, h, 40.3, 0.2, 1.6, 180.0, 12.0);
        let v = ImageView::from_slice(&img, w, h).unwrap();
        let s = extract_stripe(AnyView::U8(v), &StripeOptions::default()).unwrap();
        assert_eq!(s.direction, StripeDirection::Cols);
        assert!(s.points.len() > 80, "{}", s.points.len());
        for p in &s.points {
            let c = 40.3 + 0.2 * p.v;
            assert!((p.u - c).abs() < 0.05, "{} vs {c}", p.u);
            assert!((p.width_px - 3.77).abs() < 0.3, "{}", p.width_px);
        }
        // transposed: one point per column
        let mut t = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                t[x * h + y] = img[y * w + x];
            }
        }
        let v = ImageView::from_slice(&t, h, w).unwrap();
        let s2 = extract_stripe(AnyView::U8(v), &StripeOptions::default()).unwrap();
        assert_eq!(s2.direction, StripeDirection::Rows);
        assert_eq!(s2.points.len(), s.points.len());
        for (a, b) in s.points.iter().zip(&s2.points) {
            assert!((a.u - b.v).abs() < 1e-4 && (a.v - b.u).abs() < 1e-9);
        }
    }

    /// A curved stripe of varying width and brightness (saturated in places) over a
    /// textured, shaded background with pseudo-random noise: a stand-in for a laser image.
    fn textured(w: usize, h: usize) -> Vec<u8> {
        let mut s = 987654321u64;
        let mut img = vec![0u8; w * h];
        for y in 0..h {
            let yf = y as f64;
            let c = 0.37 * w as f64 + 9.0 * (yf / 37.0).sin() + 0.05 * yf;
            let sigma = 1.1 + 0.6 * (yf / 23.0).cos().abs();
            let amp = 60.0 + 260.0 * (0.5 + 0.5 * (yf / 41.0).sin());
            for x in 0..w {
                let xf = x as f64;
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let noise = ((s >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 3.0;
                let board = if ((x / 13) + (y / 17)) % 2 == 0 {
                    40.0
                } else {
                    15.0
                };
                let t = (xf - c) / sigma;
                let v = board + 0.02 * xf + amp * (-0.5 * t * t).exp() + noise;
                img[y * w + x] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
        img
    }

    fn transposed<T: Copy + Default>(img: &[T], w: usize, h: usize) -> Vec<T> {
        let mut t = vec![T::default(); w * h];
        for y in 0..h {
            for x in 0..w {
                t[x * h + y] = img[y * w + x];
            }
        }
        t
    }

    /// `Rows` (and `Auto`) on the transposed image compute bit for bit what `Cols`
    /// computes on the image: the same candidates, segments and arithmetic.
    #[test]
    fn rows_on_the_transposed_image_equal_cols_bit_for_bit() {
        let (w, h) = (203, 157); // not multiples of the ridge block
        let img = textured(w, h);
        let img16: Vec<u16> = img.iter().map(|&v| v as u16 * 257).collect();
        let t = transposed(&img, w, h);
        let t16 = transposed(&img16, w, h);
        for method in [StripeMethod::Centroid, StripeMethod::Gaussian] {
            let cols = StripeOptions {
                direction: StripeDirection::Cols,
                method,
                ..StripeOptions::default()
            };
            let rows = StripeOptions {
                direction: StripeDirection::Rows,
                ..cols.clone()
            };
            let auto = StripeOptions {
                direction: StripeDirection::Auto,
                ..cols.clone()
            };
            let views = [
                (
                    AnyView::U8(ImageView::from_slice(&img, w, h).unwrap()),
                    AnyView::U8(ImageView::from_slice(&t, h, w).unwrap()),
                ),
                (
                    AnyView::U16(ImageView::from_slice(&img16, w, h).unwrap()),
                    AnyView::U16(ImageView::from_slice(&t16, h, w).unwrap()),
                ),
            ];
            for (v, vt) in views {
                let a = extract_stripe(v, &cols).unwrap();
                assert!(a.points.len() > 120, "{}", a.points.len());
                // Auto reuses the candidates of the rows it sampled: the same result
                assert_eq!(extract_stripe(v, &auto).unwrap(), a);
                assert!(a.points.iter().any(|p| p.flags & FLAG_SATURATED != 0));
                for opts in [&rows, &auto] {
                    let b = extract_stripe(vt, opts).unwrap();
                    assert_eq!(b.direction, StripeDirection::Rows);
                    assert_eq!(b.rejected, a.rejected);
                    assert_eq!(b.points.len(), a.points.len());
                    for (p, q) in a.points.iter().zip(&b.points) {
                        let swapped = StripePoint {
                            u: q.v,
                            v: q.u,
                            ..*q
                        };
                        assert_eq!(*p, swapped);
                    }
                }
            }
        }
    }

    /// The AVX2 build of the ridge passes (where the CPU has it) finds exactly the
    /// candidates of the baseline build, on 8- and 16-bit lines of every length mod 64.
    #[test]
    fn ridge_pass_dispatch_equals_the_baseline_build() {
        let (w, h) = (203, 157);
        let img = textured(w, h);
        let img16: Vec<u16> = img.iter().map(|&v| v as u16 * 257).collect();
        let v8 = ImageView::from_slice(&img, w, h).unwrap();
        let v16 = ImageView::from_slice(&img16, w, h).unwrap();
        for d in [1usize, 5, 9] {
            for y in 0..h {
                for len in [w, 140, 75, 64, 63, 20] {
                    let (mut a, mut b) = (LineCand::default(), LineCand::default());
                    scan_line(&v8.row(y)[..len], d, 6, &mut a);
                    scan_line_generic(&v8.row(y)[..len], d, 6, &mut b);
                    assert_eq!(a, b);
                    let (mut a, mut b) = (LineCand::default(), LineCand::default());
                    scan_line(&v16.row(y)[..len], d, 6 * 257, &mut a);
                    scan_line_generic(&v16.row(y)[..len], d, 6 * 257, &mut b);
                    assert_eq!(a, b);
                }
            }
            let mut a = vec![LineCand::default(); w];
            let mut b = a.clone();
            scan_columns(&v8, d, 6, &mut a);
            scan_columns_generic(&v8, d, 6, &mut b);
            assert_eq!(a, b);
            assert!(a.iter().any(|c| c.has_best));
            let mut a = vec![LineCand::default(); w];
            let mut b = a.clone();
            scan_columns(&v16, d, 6 * 257, &mut a);
            scan_columns_generic(&v16, d, 6 * 257, &mut b);
            assert_eq!(a, b);
        }
    }

    #[test]
    fn no_panic_on_degenerate_images() {
        for (w, h) in [(1usize, 1usize), (1, 50), (50, 1), (3, 3), (11, 11)] {
            for val in [0u8, 255, 7] {
                let img = vec![val; w * h];
                let v = ImageView::from_slice(&img, w, h).unwrap();
                assert!(extract_stripe(AnyView::U8(v), &StripeOptions::default()).is_err());
            }
        }
        // pseudo-random noise of full range: ambiguous everywhere, no stripe
        let (w, h) = (200, 150);
        let mut s = 12345u64;
        let img: Vec<u16> = (0..w * h)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 48) as u16
            })
            .collect();
        let v = ImageView::from_slice(&img, w, h).unwrap();
        let r = extract_stripe(AnyView::U16(v), &StripeOptions::default());
        assert!(r.is_err(), "{:?}", r.map(|s| s.points.len()));
    }
}
