//! A look at the image's line before extraction: how wide it is across, whether it is
//! saturated, and how much its brightness jumps from one scan line to the next
//! (speckle). The ridge distance and the smoothing along the line follow from it.
//!
//! ## Method
//!
//! Every [`STEP`]-th row and column is sampled. On each, the brightest pixel is the
//! line's candidate when it stands at least `4 * min_contrast` above the line's median
//! (a rough background); its width is the run of pixels around it above the level
//! halfway between that median and the maximum (full width at half maximum, whole
//! pixels). The line runs along the axis whose samples cross it narrowly: the width
//! across the line is the median over the rows' runs or the columns' runs, whichever is
//! smaller (a column cut along a near-vertical line gives a long run).
//!
//! A sampled row (column) and its neighbour are compared where both hold the line
//! (their brightest pixels within 2 px plus the width; when fewer than half of the
//! samples do, there is no line to measure and the index is 0): `|m_a - m_b| / ((m_a + m_b) /
//! 2)` of their heights above the median. Its median over the pairs is the speckle
//! index: about `sqrt(2) * 0.67 * noise / height` for a line with white noise alone
//! (below 0.02 for a line 100 gray levels over a noise of 2, 0.035 for one 40 over
//! 1.5), and about 0.09 for the twin's speckle of contrast 0.3 and 2 px grain (the
//! grain decorrelates the heights within a few scan lines).
//!
//! ## What follows
//!
//! - The widths accepted: up to `max(max_width_px, 1.5 * width + 4)` (at most
//!   [`MAX_WIDTH_PX`]), and on a wide saturated line plateaus up to the same
//!   `max(max_saturated_px, 1.5 * width + 4)` (a plateau is narrower than its line),
//!   `width` the median width, or on a wide saturated line the wide end of its widths
//!   (below).
//! - The ridge distance: `ridge_px` while `ceil(width / 2) <= ridge_px` (at that
//!   distance from its peak the line is at or below half its height: the ridge test
//!   finds it), else `ceil(width / 2) + 3` (at most [`MAX_RIDGE_PX`]). On a wide
//!   saturated line `width` is the wide end of its widths, the 90th percentile of the
//!   samples (at most twice the median): a line widens along its length, and a
//!   plateau wider than twice the ridge distance gives no ridge at all (from the median
//!   width such a line lost its widest scan lines). An unsaturated line has no flat top:
//!   the ridge test finds it at any distance, and its centres (whose first background
//!   guess is read at the ridge distance) stay those of its median width. A line up to
//!   twice the ridge distance wide keeps `ridge_px`, and its extraction is what it
//!   always was (a wider distance also widens the window the centre is taken over,
//!   which moved the twin's ball diameter by 0.0015 mm on 7-9 px saturated lines).
//! - Smoothing along the line ([`StripeOptions::along_line`] `0`, auto): on for a wide
//!   saturated line (more than [`SATURATED_SHARE`] of the sampled lines' peaks at full
//!   scale, at least [`WIDE_PX`] wide: its edges carry the speckle its clipped top
//!   hides) or when the speckle index exceeds [`SPECKLE_INDEX`].

use super::ridge::RidgePixel;
use super::{StripeDirection, StripeOptions};
use crate::model::image::{ImageView, Pixel};

/// Every `STEP`-th row and column is sampled.
const STEP: usize = 8;
/// The largest ridge distance the survey sets, px (a line up to about 58 px wide).
pub const MAX_RIDGE_PX: usize = 32;
/// The widest line the survey lets the extractor accept, px.
pub const MAX_WIDTH_PX: f32 = 64.0;
/// Smoothing is on when more than this share of the sampled peaks are saturated.
pub const SATURATED_SHARE: f64 = 0.25;
/// A saturated line at least this wide (px) is a wide saturated line.
pub const WIDE_PX: f64 = 10.0;
/// Smoothing is on when the speckle index exceeds this.
pub const SPECKLE_INDEX: f64 = 0.06;
/// Scan lines averaged along the line when smoothing is on (auto).
pub const AUTO_ALONG_LINE: usize = 5;

/// What the survey saw.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Survey {
    /// The line's width across (FWHM, whole pixels; 0: no line seen).
    pub width_px: f64,
    /// The wide end of the line's widths: the 90th percentile of the sampled widths,
    /// at most twice [`Survey::width_px`] (px; 0: no line seen). A wide saturated
    /// line's ridge distance follows it (module docs): a line widens along its length
    /// (obliquely lit, nearer the camera, a brighter surface), and the widest parts of
    /// its plateau must still be found.
    pub wide_px: f64,
    /// Share of the sampled peaks at full scale.
    pub saturated_share: f64,
    /// The speckle index (module docs; 0 without pairs).
    pub speckle_index: f64,
    /// Whether the line runs along the columns (the rows cross it narrowly).
    pub along_columns: bool,
}

impl Survey {
    /// The ridge distance for `opts` (module docs).
    pub fn ridge_px(&self, opts: &StripeOptions) -> usize {
        Self::ridge_for(self.followed_px(), opts)
    }

    /// The width the ridge distance and the widths accepted follow: the wide end of a
    /// wide saturated line's widths, else the median (module docs).
    fn followed_px(&self) -> f64 {
        if self.saturated_wide() {
            self.wide_px.max(self.width_px)
        } else {
            self.width_px
        }
    }

    /// The ridge distance for the line's median width (the scan direction's decision
    /// uses it: a majority of the scan lines decides, as before the wide end of a
    /// saturated line was taken).
    pub fn typical_ridge_px(&self, opts: &StripeOptions) -> usize {
        Self::ridge_for(self.width_px, opts)
    }

    fn ridge_for(width_px: f64, opts: &StripeOptions) -> usize {
        let w = width_px.min(f64::from(MAX_WIDTH_PX));
        let half = (0.5 * w).ceil() as usize;
        if half <= opts.ridge_px {
            // the ridge test finds this line as it is: at the distance its neighbours
            // are compared from, the line is at or below half its height
            return opts.ridge_px;
        }
        (half + 3).clamp(opts.ridge_px, MAX_RIDGE_PX.max(opts.ridge_px))
    }

    /// A wide saturated line: more than [`SATURATED_SHARE`] of the peaks at full scale
    /// and at least [`WIDE_PX`] wide (a narrow line that touches full scale keeps the
    /// extraction of narrow lines).
    pub fn saturated_wide(&self) -> bool {
        self.saturated_share > SATURATED_SHARE && self.width_px >= WIDE_PX
    }

    /// `opts` adapted to the line (module docs): the ridge distance, the widths accepted
    /// and, on a saturated line, the plateau trusted; never below their values.
    pub fn adapt(&self, opts: &mut StripeOptions) {
        opts.ridge_px = self.ridge_px(opts);
        let wide = (1.5 * self.followed_px() + 4.0) as f32;
        opts.max_width_px = opts.max_width_px.max(wide.min(MAX_WIDTH_PX));
        if self.saturated_wide() {
            // a plateau is narrower than its line, whose widths the accepted widths
            // bound: the line widens along its length, and a bound at the median width
            // rejected its wider part (172 scan lines of a twin view of a saturated
            // line with a reflection beside it: 7 trusted board points before, 148 now)
            let plateau = wide.min(MAX_WIDTH_PX).ceil() as usize;
            opts.max_saturated_px = opts.max_saturated_px.max(plateau);
        }
    }

    /// Scan lines to average along the line: `opts.along_line` when set, else
    /// [`AUTO_ALONG_LINE`] for a saturated or speckled line and 1 (none) otherwise.
    pub fn along_line(&self, opts: &StripeOptions) -> usize {
        match opts.along_line {
            0 => {
                if self.saturated_wide() || self.speckle_index > SPECKLE_INDEX {
                    AUTO_ALONG_LINE
                } else {
                    1
                }
            }
            n => n,
        }
    }
}

/// Reusable buffers of the survey (kept by the extractor between images), and the state
/// of a survey of the rows fused into the extractor's pass over them
/// ([`SurveyScratch::rows_begin`]).
#[derive(Debug, Clone, Default)]
pub(crate) struct SurveyScratch {
    /// A gathered column.
    line: Vec<u16>,
    /// The median of the line sampled last (where the next one's search starts).
    guess: u32,
    /// Per axis (rows, columns): the sampled lines' widths and the speckle ratios.
    rows: Samples,
    cols: Samples,
    /// The fused survey's settings: `(min_height, limit, sat_level, lines)`.
    fused: (f32, usize, f32, usize),
}

/// The peak of a sampled line: `(position, height above the median, width, saturated)`.
type Peak = (usize, f32, usize, bool);

/// Widths, saturated count and speckle ratios of one axis's sampled lines.
#[derive(Debug, Clone, Default)]
struct Samples {
    widths: Vec<usize>,
    sat: usize,
    ratios: Vec<f64>,
    /// The peak of the line sampled last (its neighbour is compared with it).
    last: Option<Peak>,
}

impl Samples {
    fn clear(&mut self) {
        self.widths.clear();
        self.ratios.clear();
        self.sat = 0;
        self.last = None;
    }

    /// A sampled line's peak.
    #[inline]
    fn sampled(&mut self, p: Option<Peak>) {
        if let Some((_, _, w, sat)) = p {
            self.widths.push(w);
            self.sat += sat as usize;
        }
        self.last = p;
    }

    /// The peak of the neighbour of the line sampled last (asked for only where that
    /// one held a peak): a speckle ratio where both hold the line.
    #[inline]
    fn neighbour(&mut self, p: Option<Peak>) {
        if let (Some((pa, ha, wa, sa)), Some((pb, hb, _, sb))) = (self.last, p) {
            if pa.abs_diff(pb) <= 2 + wa && !sa && !sb {
                self.ratios
                    .push(f64::from((ha - hb).abs() / (0.5 * (ha + hb))));
            }
        }
    }
}

impl SurveyScratch {
    /// Starts a survey of the rows of an image of `h` rows, fused into a pass over its
    /// rows in order ([`SurveyScratch::row`] for every row, then
    /// [`SurveyScratch::rows_finish`]): the survey [`survey`] makes with `Cols`.
    pub(crate) fn rows_begin<T: RidgePixel>(&mut self, opts: &StripeOptions, h: usize) {
        self.rows.clear();
        self.fused = (
            4.0 * opts.min_contrast * T::SCALE,
            4 * opts.max_width_px.ceil() as usize,
            <T as Pixel>::MAX,
            h,
        );
    }

    /// Row `y` (rows in increasing order): looked at where the survey samples it.
    #[inline]
    pub(crate) fn row<T: RidgePixel>(&mut self, y: usize, row: &[T]) {
        let (min_height, limit, sat_level, h) = self.fused;
        if y < STEP / 2 || y >= h {
            return;
        }
        let k = (y - STEP / 2) % STEP;
        // a sampled row (below the last row), or the neighbour of one that held a peak
        let sampled = k == 0 && y + 1 < h;
        if !(sampled || (k == 1 && self.rows.last.is_some())) {
            return;
        }
        let p = line_peak_dispatch(row, &mut self.guess, min_height, limit, sat_level);
        if sampled {
            self.rows.sampled(p);
        } else {
            self.rows.neighbour(p);
        }
    }

    /// The survey of the rows seen since [`SurveyScratch::rows_begin`].
    pub(crate) fn rows_finish(&mut self) -> Survey {
        summary(&mut self.rows, true)
    }
}

/// [`line_peak`], with AVX2 where the CPU has it (the same result).
#[inline]
fn line_peak_dispatch<P: RidgePixel>(
    vals: &[P],
    guess: &mut u32,
    min_height: f32,
    limit: usize,
    sat_level: f32,
) -> Option<Peak> {
    #[cfg(target_arch = "x86_64")]
    if crate::vision::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
        // calling a `#[target_feature(enable = "avx2")]` function.
        return unsafe { line_peak_avx2(vals, guess, min_height, limit, sat_level) };
    }
    line_peak(vals, guess, min_height, limit, sat_level)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn line_peak_avx2<P: RidgePixel>(
    vals: &[P],
    guess: &mut u32,
    min_height: f32,
    limit: usize,
    sat_level: f32,
) -> Option<Peak> {
    line_peak(vals, guess, min_height, limit, sat_level)
}

/// How many of `vals` are at most `t` (vectorised: byte counters per block of 128).
#[inline(always)]
fn count_le<P: RidgePixel>(vals: &[P], t: P) -> usize {
    let mut n = 0usize;
    let mut blocks = vals.chunks_exact(128);
    for b in &mut blocks {
        n += b.iter().fold(0u8, |a, &v| a.wrapping_add((v <= t) as u8)) as usize;
    }
    n + blocks.remainder().iter().filter(|&&v| v <= t).count()
}

/// The element at index `mid` of `vals` sorted (what `select_nth_unstable(mid)` puts
/// there; `vmax` the largest value): the smallest `t` with more than `mid` values at most
/// `t`, found by counting, first outwards from `guess` (the median of the line sampled
/// before: neighbouring lines share their background) and then by bisection. `guess`
/// changes the work, never the result.
#[inline(always)]
fn nth_value<P: RidgePixel>(vals: &[P], mid: usize, vmax: u32, guess: u32) -> u32 {
    // whether the value sought is at most `t`
    let le = |t: u32| count_le(vals, P::from_u32_clamped(t)) > mid;
    let g = guess.min(vmax);
    // the value lies in lo..=hi
    let (mut lo, mut hi);
    if le(g) {
        (lo, hi) = (0, g);
        let mut step = 1u32;
        while hi > 0 {
            let c = hi.saturating_sub(step);
            if le(c) {
                hi = c;
                step = step.saturating_mul(2);
            } else {
                lo = c + 1;
                break;
            }
        }
    } else {
        // (le(vmax) holds: every value is at most vmax)
        (lo, hi) = (g + 1, vmax);
        let mut step = 1u32;
        while lo < hi {
            let c = lo.saturating_add(step - 1).min(hi);
            if le(c) {
                hi = c;
                break;
            }
            lo = c + 1;
            step = step.saturating_mul(2);
        }
    }
    while lo < hi {
        let m = lo + (hi - lo) / 2;
        if le(m) {
            hi = m;
        } else {
            lo = m + 1;
        }
    }
    lo
}

/// The peak of one sampled line: `(position, height above the median, width,
/// saturated)`, or `None` without a clear peak. `sat_level`: full scale of the image.
#[inline(always)]
fn line_peak<P: RidgePixel>(
    vals: &[P],
    guess: &mut u32,
    min_height: f32,
    limit: usize,
    sat_level: f32,
) -> Option<Peak> {
    if vals.len() < 3 {
        return None;
    }
    // the brightest value (lane-wise maxima over blocks of 32, vectorised, one
    // reduction at the end) and its first pixel: the first block that holds it (a
    // vectorised equality test per block), then the pixel in it
    let mut lanes = [P::ZERO; 32];
    let mut blocks = vals.chunks_exact(32);
    for b in &mut blocks {
        for (m, &v) in lanes.iter_mut().zip(b) {
            *m = (*m).max(v);
        }
    }
    let vmax = blocks
        .remainder()
        .iter()
        .chain(&lanes)
        .fold(P::ZERO, |a, &v| a.max(v));
    let mut pk = None;
    for (k, b) in vals.chunks(32).enumerate() {
        if b.iter().fold(false, |a, &v| a | (v == vmax)) {
            pk = b.iter().position(|&v| v == vmax).map(|i| 32 * k + i);
            break;
        }
    }
    let pk = pk?;
    let vmax = vmax.as_u32();
    let med = nth_value(vals, vals.len() / 2, vmax, *guess);
    *guess = med;
    let height = vmax as f32 - med as f32;
    if height < min_height {
        return None;
    }
    let half = med as f32 + 0.5 * height;
    let at = |i: usize| vals[i].as_u32() as f32;
    let mut a = pk;
    while a > 0 && at(a - 1) >= half && pk - a < limit {
        a -= 1;
    }
    let mut b = pk;
    while b + 1 < vals.len() && at(b + 1) >= half && b - pk < limit {
        b += 1;
    }
    let sat = vmax as f32 >= sat_level;
    // the middle of the run (a plateau's argmax is its first pixel)
    Some(((a + b) / 2, height, b - a + 1, sat))
}

/// Peaks of the sampled lines and of their neighbours into `s`: widths, saturated
/// count, speckle ratios of the pairs that both hold the line. `get(l, scratch)` is the
/// peak of line `l`.
#[inline(always)]
fn sample<S>(
    n_lines: usize,
    s: &mut Samples,
    scratch: &mut S,
    mut get: impl FnMut(usize, &mut S) -> Option<Peak>,
) {
    s.clear();
    for l in (STEP / 2..n_lines.saturating_sub(1)).step_by(STEP) {
        let p = get(l, scratch);
        s.sampled(p);
        if p.is_some() {
            s.neighbour(get(l + 1, scratch));
        }
    }
}

/// The `q`-quantile (nearest rank) of values already sorted.
fn quantile_sorted(v: &[usize], q: f64) -> Option<f64> {
    let n = v.len();
    (n > 0).then(|| v[((q * n as f64).ceil() as usize).clamp(1, n) - 1] as f64)
}

fn median_usize(v: &mut [usize]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_unstable();
    let n = v.len();
    Some(0.5 * (v[(n - 1) / 2] + v[n / 2]) as f64)
}

/// Surveys the line of `img` (module docs); `dir` is the scan direction when known
/// (`Cols`: the rows cross the line), `Auto` to decide it here too. `scratch` holds the
/// buffers between images. Compiled a second time with AVX2, chosen at run time where
/// the CPU has it (the same results: integer counts and the same `f32` arithmetic).
pub(crate) fn survey<T: RidgePixel>(
    img: &ImageView<'_, T>,
    opts: &StripeOptions,
    dir: StripeDirection,
    scratch: &mut SurveyScratch,
) -> Survey {
    #[cfg(target_arch = "x86_64")]
    if crate::vision::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
        // calling a `#[target_feature(enable = "avx2")]` function.
        return unsafe { survey_avx2(img, opts, dir, scratch) };
    }
    survey_generic(img, opts, dir, scratch)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn survey_avx2<T: RidgePixel>(
    img: &ImageView<'_, T>,
    opts: &StripeOptions,
    dir: StripeDirection,
    scratch: &mut SurveyScratch,
) -> Survey {
    survey_generic(img, opts, dir, scratch)
}

#[inline(always)]
fn survey_generic<T: RidgePixel>(
    img: &ImageView<'_, T>,
    opts: &StripeOptions,
    dir: StripeDirection,
    scratch: &mut SurveyScratch,
) -> Survey {
    let (w, h) = (img.width(), img.height());
    let min_height = 4.0 * opts.min_contrast * T::SCALE;
    let limit = 4 * opts.max_width_px.ceil() as usize;
    let sat_level = <T as Pixel>::MAX;
    let SurveyScratch {
        line,
        guess,
        rows: sr,
        cols: sc,
        ..
    } = scratch;
    let rows = |s: &mut Samples, guess: &mut u32| {
        sample(h, s, guess, |y, guess| {
            line_peak(img.row(y), guess, min_height, limit, sat_level)
        })
    };
    let cols = |s: &mut Samples, line: &mut Vec<u16>, guess: &mut u32| {
        let mut st = (line, guess);
        sample(w, s, &mut st, |x, (line, guess)| {
            line.clear();
            line.extend((0..h).map(|y| img.get(x, y).as_u32() as u16));
            line_peak(line, guess, min_height, limit, sat_level)
        })
    };
    let (along_columns, picked) = match dir {
        StripeDirection::Cols => {
            rows(sr, guess);
            (true, &mut *sr)
        }
        StripeDirection::Rows => {
            cols(sc, line, guess);
            (false, &mut *sc)
        }
        StripeDirection::Auto => {
            rows(sr, guess);
            cols(sc, line, guess);
            // the axis that crosses the line on more of its samples; at a like rate
            // (a diagonal line) the one that crosses it more narrowly
            let rate_r = sr.widths.len() as f64 / (h / STEP).max(1) as f64;
            let rate_c = sc.widths.len() as f64 / (w / STEP).max(1) as f64;
            // (the medians sort the widths in place: the median taken below is the same)
            let narrower_rows = match (median_usize(&mut sr.widths), median_usize(&mut sc.widths)) {
                (Some(a), Some(b)) => a <= b,
                (a, _) => a.is_some(),
            };
            if rate_r > 1.5 * rate_c || (rate_c <= 1.5 * rate_r && narrower_rows) {
                (true, &mut *sr)
            } else {
                (false, &mut *sc)
            }
        }
    };
    summary(picked, along_columns)
}

/// The survey from one axis's samples (the median width, the saturated share, the
/// speckle index).
fn summary(picked: &mut Samples, along_columns: bool) -> Survey {
    let Samples {
        widths,
        sat,
        ratios,
        ..
    } = picked;
    let n = widths.len();
    let Some(width) = median_usize(widths) else {
        return Survey {
            along_columns,
            ..Survey::default()
        };
    };
    ratios.sort_by(f64::total_cmp);
    // a line holds the same place on neighbouring scan lines: without that on most
    // samples there is no line to measure speckle on
    let speckle_index = if ratios.len() >= 5 && 2 * ratios.len() >= n {
        let k = ratios.len();
        0.5 * (ratios[(k - 1) / 2] + ratios[k / 2])
    } else {
        0.0
    };
    // (the median sorted the widths)
    let wide = quantile_sorted(widths, 0.9).map_or(width, |q| q.min(2.0 * width));
    Survey {
        width_px: width,
        wide_px: wide,
        saturated_share: *sat as f64 / n.max(1) as f64,
        speckle_index,
        along_columns,
    }
}
