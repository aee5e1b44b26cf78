//! The ridge search: `r(x) = I(x) - max(I(x - d), I(x + d))` over whole scan lines in
//! integer arithmetic, vectorised by blocks (and compiled again for AVX2), and the peak
//! candidates of each scan line (the strongest run above the threshold and the strength
//! of the next).

use crate::model::image::{ImageView, Pixel};
use crate::vision::has_avx2;

/// Pixels of a ridge-test block: the vectorised pass tests this many pixels at once, and
/// only a block holding a response above the threshold is looked at further.
const CHUNK: usize = 64;
/// Candidate runs closer than this (pixels between them) are one run.
const MERGE_GAP: u32 = 2;

/// The merge gap for the ridge distance `d`.
#[inline]
fn merge_gap(_d: usize) -> u32 {
    MERGE_GAP
}

/// Integer pixel operations of the ridge pass.
pub(crate) trait RidgePixel: Pixel + Ord {
    const ZERO: Self;
    /// Gray levels per 8-bit gray level (1 or 257).
    const SCALE: f32;
    fn sat_sub(self, o: Self) -> Self;
    fn as_u32(self) -> u32;
    fn from_u32_clamped(x: u32) -> Self;
}

/// `RidgePixel` for an unsigned pixel type `$t` with `$scale` gray levels per 8-bit one.
macro_rules! ridge_pixel {
    ($t:ty, $scale:expr) => {
        impl RidgePixel for $t {
            const ZERO: Self = 0;
            const SCALE: f32 = $scale;
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
                x.min(<$t>::MAX as u32) as $t
            }
        }
    };
}

ridge_pixel!(u8, 1.0);
ridge_pixel!(u16, 257.0);

/// A run of consecutive ridge responses above the threshold.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Run {
    last: u32,
    /// The largest ridge response of the run.
    strength: u32,
    vmax: u32,
    pfirst: u32,
    plast: u32,
}

impl Run {
    /// The run's peak pixel: the middle of its brightest pixels.
    #[inline]
    pub(crate) fn peak(&self) -> usize {
        ((self.pfirst + self.plast) / 2) as usize
    }

    /// The run's weight when lines compete, within the run alone: its brightest value
    /// times the pixels at that value ([`super::chains`] measures a saturated plateau on
    /// the scan line itself).
    #[cfg(test)]
    pub(crate) fn weight(&self) -> u32 {
        self.vmax.saturating_mul(self.plast - self.pfirst + 1)
    }

    /// The run's brightest value.
    #[inline]
    pub(crate) fn vmax(&self) -> u32 {
        self.vmax
    }

    /// The run's largest ridge response.
    #[inline]
    pub(crate) fn strength_f32(&self) -> f32 {
        self.strength as f32
    }
}

/// Runs a scan line keeps for the continuity decision between comparable peaks.
pub(crate) const MAX_RUNS: usize = 4;

/// Peak candidates of one scan line: the strongest runs (at most [`MAX_RUNS`], strongest
/// first) and the strength of the strongest run not kept.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct LineCand {
    cur: Run,
    active: bool,
    runs: [Run; MAX_RUNS],
    n: u8,
    /// The strongest response among the runs that were not kept.
    dropped: u32,
}

impl LineCand {
    #[inline]
    fn push(&mut self, pos: u32, r: u32, v: u32, gap: u32) {
        if self.active && pos <= self.cur.last + 1 + gap {
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

    /// Files the current run among the strongest (the first of equal strengths stays
    /// ahead).
    fn close(&mut self) {
        if !self.active {
            return;
        }
        self.active = false;
        let c = self.cur;
        let n = self.n as usize;
        let at = self.runs[..n]
            .iter()
            .position(|r| c.strength > r.strength)
            .unwrap_or(n);
        if at >= MAX_RUNS {
            self.dropped = self.dropped.max(c.strength);
            return;
        }
        if n == MAX_RUNS {
            self.dropped = self.dropped.max(self.runs[MAX_RUNS - 1].strength);
        }
        let end = n.min(MAX_RUNS - 1);
        self.runs.copy_within(at..end, at + 1);
        self.runs[at] = c;
        self.n = (end + 1) as u8;
    }

    /// Whether any run was found (for the tests).
    #[cfg(test)]
    pub(super) fn has_peak(&self) -> bool {
        self.n > 0
    }

    /// The kept runs, strongest first.
    #[inline]
    pub(crate) fn runs(&self) -> &[Run] {
        &self.runs[..self.n as usize]
    }

    /// The strength of the second strongest run (0 with one run).
    #[inline]
    fn second(&self) -> u32 {
        if self.n > 1 {
            self.runs[1].strength
        } else {
            self.dropped
        }
    }

    /// The peak pixel of the single trustworthy run, or why there is none.
    pub(super) fn verdict(&self, ratio: f32) -> std::result::Result<usize, LineReject> {
        if self.n == 0 {
            return Err(LineReject::NoPeak);
        }
        let best = &self.runs[0];
        if self.second() as f32 >= ratio * best.strength as f32 {
            return Err(LineReject::Multiple);
        }
        Ok(best.peak())
    }
}

/// Why a scan line gives no point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum LineReject {
    NoPeak,
    Multiple,
    /// The only peak continues a chain that is a reflection ([`super::chains`]).
    Reflection,
    Shape,
    Saturated,
    Border,
}

/// The ridge response `m - max(a, b)` (saturating at 0).
#[inline(always)]
fn response<T: RidgePixel>(a: T, m: T, b: T) -> T {
    m.sat_sub(a.max(b))
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
        out[i] = response(a[i], m[i], b[i]);
    }
}

/// Largest ridge response of a block (the coarse test: almost every block of an image
/// is below the threshold and is done after this).
#[inline(always)]
fn block_max<T: RidgePixel>(a: &[T; CHUNK], m: &[T; CHUNK], b: &[T; CHUNK]) -> T {
    let mut mx = T::ZERO;
    for i in 0..CHUNK {
        mx = mx.max(response(a[i], m[i], b[i]));
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
            let r = response(a[i], m[i], b[i]);
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
pub(super) fn scan_line_generic<T: RidgePixel>(line: &[T], d: usize, thr: T, cand: &mut LineCand) {
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
        |i, r, v| cand.push((d + i) as u32, r, v, merge_gap(d)),
    );
    cand.close();
}

/// The ridge test down every column at once, row by row (cache friendly): column `x`'s
/// candidates go to `cands[x]` (`cands.len() == img.width()`). The same blocks, responses
/// and candidate order as [`scan_line_generic`] on the transposed image.
#[inline(always)]
pub(super) fn scan_columns_generic<T: RidgePixel>(
    img: &ImageView<'_, T>,
    d: usize,
    thr: T,
    cands: &mut [LineCand],
) {
    let h = img.height();
    if h < 2 * d + 1 {
        return;
    }
    let gap = merge_gap(d);
    for y in d..h - d {
        let (ra, rm, rb) = (img.row(y - d), img.row(y), img.row(y + d));
        ridge_blocks(ra, rm, rb, thr, |i, r, v| {
            if let Some(c) = cands.get_mut(i) {
                c.push(y as u32, r, v, gap);
            }
        });
    }
    for c in cands.iter_mut() {
        c.close();
    }
}

/// [`scan_line_generic`], with AVX2 where the CPU has it (the same results).
#[inline]
pub(super) fn scan_line<T: RidgePixel>(line: &[T], d: usize, thr: T, cand: &mut LineCand) {
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
pub(super) fn scan_columns<T: RidgePixel>(
    img: &ImageView<'_, T>,
    d: usize,
    thr: T,
    cands: &mut [LineCand],
) {
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
