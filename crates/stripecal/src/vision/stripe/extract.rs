//! The extractor: the survey of the line (its width, saturation and speckle), the
//! smoothing along the line where it helps, the rows and columns drivers that run the
//! ridge search per scan line, the decision between comparable peaks by the line's
//! continuity, and the sub-pixel centre of the chosen peak; then the continuity filter
//! and the oblique flag; and the automatic choice of the scan direction.

use super::chains::{Chains, Decision};
use super::lanes::{lanes_apply, subpixel_lanes, Segments, LANES, SEG};
use super::peak::{line_subpixel, ColumnLine, Params, RowLine, Sub, SHORT_REACH};
use super::ridge::{scan_columns, scan_line, LineCand, LineReject, RidgePixel, Run};
use super::smooth::{scale_of, smooth_along};
use super::survey::{survey, Survey, SurveyScratch};
use super::{
    RejectCounts, StripeDirection, StripeOptions, StripePoint, FLAG_AMBIGUOUS, FLAG_OBLIQUE,
};
use crate::error::Result;
use crate::model::image::{AnyView, ImageView};

/// Where the ridge candidates of the scan lines come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Cands {
    /// The ridge pass over the image.
    Scan,
    /// The auto decision's: the columns' all, the rows' it sampled.
    FromAuto,
    /// Found already (the fused pass).
    Ready,
}

/// Auto direction: every `AUTO_STEP`-th row and column is sampled.
const AUTO_STEP: usize = 4;

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
    /// The smoothed image and its column sums.
    smooth: Vec<u16>,
    acc: Vec<u32>,
    chains: Chains,
    decisions: Vec<Decision>,
    /// The second points of ambiguous scan lines.
    alts: Vec<StripePoint>,
    /// Per scan line: the sub-pixel result the lanes found (its segment's first pixel
    /// and the result; `None`: the scalar code runs).
    found: Vec<Option<(usize, Sub)>>,
    rejected: RejectCounts,
    survey: Survey,
    /// The survey's buffers.
    surveyed: SurveyScratch,
    /// `Cols`: survey the rows in the ridge pass (the last image kept the options'
    /// ridge distance and was not smoothed).
    fuse: bool,
    along: usize,
    ridge: usize,
}

impl StripeExtractor {
    /// An extractor; errors on invalid options.
    pub fn new(opts: StripeOptions) -> Result<StripeExtractor> {
        opts.validate()?;
        Ok(StripeExtractor {
            ridge: opts.ridge_px,
            opts,
            cands: Vec::new(),
            rows: Vec::new(),
            seg: Vec::new(),
            col: Vec::new(),
            smooth: Vec::new(),
            acc: Vec::new(),
            chains: Chains::default(),
            decisions: Vec::new(),
            alts: Vec::new(),
            found: Vec::new(),
            rejected: RejectCounts::default(),
            survey: Survey::default(),
            surveyed: SurveyScratch::default(),
            fuse: true,
            along: 1,
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

    /// What the survey of the last image saw (its line's width, saturation, speckle).
    pub fn survey(&self) -> Survey {
        self.survey
    }

    /// The ridge distance and the scan lines averaged along the line for the last
    /// image (from the survey, or the options where they fix them).
    pub fn adapted(&self) -> (usize, usize) {
        (self.ridge, self.along)
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
        let cols = self.opts.direction == StripeDirection::Cols;
        let fused = cols && self.fuse;
        self.survey = if fused {
            self.fused_pass(img)
        } else {
            survey(img, &self.opts, self.opts.direction, &mut self.surveyed)
        };
        let mut opts = self.opts.clone();
        if self.opts.adapt_to_line {
            self.survey.adapt(&mut opts);
        }
        self.ridge = opts.ridge_px;
        self.along = self.survey.along_line(&self.opts);
        // the fused pass's candidates stand where the survey keeps the ridge distance and
        // asks for no smoothing; the next image is surveyed first where this one was not
        // like that
        let as_set = self.along == 1 && self.ridge == self.opts.ridge_px;
        if cols {
            self.fuse = as_set;
        }
        let (dir, cands) = match opts.direction {
            StripeDirection::Auto => {
                // decided with the ridge distance of the line's median width; its
                // candidates serve the extraction where that is the extraction's
                let mut decide = opts.clone();
                if self.opts.adapt_to_line {
                    decide.ridge_px = self.survey.typical_ridge_px(&self.opts);
                }
                let dir = auto_direction(img, &decide, &mut self.cands, &mut self.rows);
                let reuse = decide.ridge_px == opts.ridge_px;
                (dir, if reuse { Cands::FromAuto } else { Cands::Scan })
            }
            _ if fused && as_set => (opts.direction, Cands::Ready),
            d => (d, Cands::Scan),
        };
        if self.along > 1 {
            let mut sm = std::mem::take(&mut self.smooth);
            let mut acc = std::mem::take(&mut self.acc);
            let cands = if dir == StripeDirection::Cols {
                // each smoothed row's ridge candidates while the row is in the cache
                let p = Params::new::<u16>(&opts);
                let thr = u16::from_u32_clamped(p.min_contrast.ceil().max(1.0) as u32);
                self.cands.clear();
                self.cands.resize(img.height(), LineCand::default());
                let found = &mut self.cands;
                smooth_along(img, dir, self.along, &mut sm, &mut acc, |y, row| {
                    scan_line(row, p.d, thr, &mut found[y])
                });
                Cands::Ready
            } else {
                smooth_along(img, dir, self.along, &mut sm, &mut acc, |_, _| {});
                Cands::Scan
            };
            let view = ImageView::from_slice(&sm, img.width(), img.height())?;
            // the smoothed image is on the 16-bit scale: peaks back to the input's
            let back = 1.0 / scale_of::<T>() as f32;
            self.passes(&view, dir, cands, &opts, out, back);
            self.smooth = sm;
            self.acc = acc;
        } else {
            self.passes(img, dir, cands, &opts, out, 1.0);
        }
        Ok(dir)
    }

    /// `Cols` with the survey fused into the ridge pass: one pass over the rows, each
    /// row surveyed where the survey samples it ([`survey`]: the same survey) and its
    /// ridge candidates found with the options' ridge distance, while the row is in the
    /// cache. Returns the survey; the candidates are in `self.cands`.
    fn fused_pass<T: RidgePixel>(&mut self, img: &ImageView<'_, T>) -> Survey {
        let h = img.height();
        let p = Params::new::<T>(&self.opts);
        let thr = T::from_u32_clamped(p.min_contrast.ceil().max(1.0) as u32);
        self.cands.clear();
        self.cands.resize(h, LineCand::default());
        self.surveyed.rows_begin::<T>(&self.opts, h);
        for (y, cand) in self.cands.iter_mut().enumerate() {
            let row = img.row(y);
            self.surveyed.row(y, row);
            scan_line(row, p.d, thr, cand);
        }
        self.surveyed.rows_finish()
    }

    /// The ridge search, the decision per scan line and the sub-pixel centres on `img`
    /// (the image or its smoothed copy); peaks scaled by `back` into the input's gray
    /// levels.
    fn passes<T: RidgePixel>(
        &mut self,
        img: &ImageView<'_, T>,
        dir: StripeDirection,
        cands: Cands,
        opts: &StripeOptions,
        out: &mut Vec<StripePoint>,
        back: f32,
    ) {
        let p = Params::new::<T>(opts);
        let thr = T::from_u32_clamped(p.min_contrast.ceil().max(1.0) as u32);
        let mut rej = RejectCounts::default();
        let auto = cands == Cands::FromAuto;
        if cands == Cands::Ready {
            // (found by the fused pass)
        } else if dir == StripeDirection::Rows {
            if !auto {
                // (the auto decision leaves the column candidates in `cands`)
                self.cands.clear();
                self.cands.resize(img.width(), LineCand::default());
                scan_columns(img, p.d, thr, &mut self.cands);
            }
        } else {
            self.row_candidates(img, p.d, thr, auto);
        }
        // a wide line's peak pixel wanders within its top
        let slack = 0.5 * opts.ridge_px as f32;
        let limit = p.reach;
        let weight = |l: usize, r: &Run| -> u32 {
            // the brightest value times the plateau at it about the peak (module docs of
            // `chains`): walked on the scan line itself
            let v = r.vmax();
            let pk = r.peak();
            let at = |i: usize| -> u32 {
                if dir == StripeDirection::Rows {
                    img.get(l, i).as_u32()
                } else {
                    img.row(l)[i].as_u32()
                }
            };
            let n = if dir == StripeDirection::Rows {
                img.height()
            } else {
                img.width()
            };
            if pk >= n || at(pk) != v {
                return v;
            }
            let (mut a, mut b) = (pk, pk);
            while a > 0 && pk - a < limit && at(a - 1) == v {
                a -= 1;
            }
            while b + 1 < n && b - pk < limit && at(b + 1) == v {
                b += 1;
            }
            v.saturating_mul((b - a + 1) as u32)
        };
        self.chains.decide(
            &self.cands,
            opts.second_peak_ratio,
            opts.max_jump_px,
            slack,
            weight,
            &mut self.decisions,
        );
        self.alts.clear();
        self.lanes(img, dir, &p);
        for l in 0..self.decisions.len() {
            let (pk, alt, reflection) = match self.decisions[l] {
                Decision::Peak(pk, r) => (pk, None, r),
                Decision::Ambiguous(a, b) if opts.keep_ambiguous => (a, Some(b), false),
                Decision::Ambiguous(..) => {
                    count(&mut rej, LineReject::Multiple);
                    continue;
                }
                Decision::Reject(e) => {
                    count(&mut rej, e);
                    continue;
                }
            };
            rej.reflections += reflection as usize;
            rej.ambiguous += alt.is_some() as usize;
            let first = match self.found.get(l).copied().flatten() {
                Some((a, s)) if alt.is_none() => Ok(place(dir, l, a, &s, back)),
                _ => self.centre(img, dir, l, pk, &p, back),
            };
            let second = alt.map(|b| self.centre(img, dir, l, b, &p, back));
            match (first, second) {
                (Ok(mut a), Some(Ok(mut b))) => {
                    a.flags |= FLAG_AMBIGUOUS;
                    b.flags |= FLAG_AMBIGUOUS;
                    out.push(a);
                    self.alts.push(b);
                }
                // the scan line stays undecided: one peak failing its centre (a
                // plateau too long, a window off the image) does not make the other
                // the stripe
                (Ok(mut a), Some(Err(_))) => {
                    a.flags |= FLAG_AMBIGUOUS;
                    out.push(a)
                }
                (Ok(a), None) => out.push(a),
                (Err(_), Some(Ok(mut b))) => {
                    b.flags |= FLAG_AMBIGUOUS;
                    out.push(b)
                }
                (Err(e), _) => count(&mut rej, e),
            }
        }
        rej.isolated = continuity(out, dir, opts.min_chain, opts.max_jump_px);
        flag_oblique(out, dir, opts.max_slope);
        if !self.alts.is_empty() {
            rej.isolated += continuity(&mut self.alts, dir, opts.min_chain, opts.max_jump_px);
            flag_oblique(&mut self.alts, dir, opts.max_slope);
            out.extend_from_slice(&self.alts);
        }
        self.rejected = rej;
    }

    /// The stripe point of the peak at `pk` of scan line `l`, its peak scaled by `back`.
    fn centre<T: RidgePixel>(
        &mut self,
        img: &ImageView<'_, T>,
        dir: StripeDirection,
        l: usize,
        pk: usize,
        p: &Params,
        back: f32,
    ) -> std::result::Result<StripePoint, LineReject> {
        let (a, res) = if dir == StripeDirection::Rows {
            let mut line = ColumnLine {
                img,
                x: l,
                buf: &mut self.col,
            };
            line_subpixel(&mut line, &mut self.seg, img.height(), pk, p)
        } else {
            let w = img.width();
            line_subpixel(&mut RowLine(img.row(l)), &mut self.seg, w, pk, p)
        };
        Ok(place(dir, l, a, &res?, back))
    }

    /// The sub-pixel results of the scan lines with a single peak, eight at a time
    /// ([`super::lanes`]), into `self.found` (the scan lines the lanes leave undecided,
    /// and those near the ends of their line, are left to [`Self::centre`]).
    fn lanes<T: RidgePixel>(&mut self, img: &ImageView<'_, T>, dir: StripeDirection, p: &Params) {
        self.found.clear();
        if !lanes_apply(p) {
            return;
        }
        self.found.resize(self.decisions.len(), None);
        let rows = dir == StripeDirection::Rows;
        let n = if rows { img.height() } else { img.width() };
        let mut segs: Segments = [[0.0; LANES]; SEG];
        let mut at = [(0usize, 0usize); LANES];
        let mut k = 0;
        let mut out = [None; LANES];
        let mut flush = |k: usize,
                         segs: &Segments,
                         at: &[(usize, usize); LANES],
                         found: &mut [Option<(usize, Sub)>]| {
            subpixel_lanes(segs, p, &mut out);
            for (&(l, a), r) in at[..k].iter().zip(&out) {
                found[l] = r.map(|s| (a, s));
            }
        };
        for (l, d) in self.decisions.iter().enumerate() {
            let Decision::Peak(pk, _) = *d else { continue };
            if pk < SHORT_REACH || pk + SHORT_REACH >= n {
                continue;
            }
            let a = pk - SHORT_REACH;
            if rows {
                for (j, s) in segs.iter_mut().enumerate() {
                    s[k] = img.get(l, a + j).to_f32();
                }
            } else {
                for (s, v) in segs.iter_mut().zip(&img.row(l)[a..a + SEG]) {
                    s[k] = v.to_f32();
                }
            }
            at[k] = (l, a);
            k += 1;
            if k == LANES {
                flush(k, &segs, &at, &mut self.found);
                k = 0;
            }
        }
        if k > 0 {
            // (the lanes past k hold the last batch's lines, decided again and unused)
            flush(k, &segs, &at, &mut self.found);
        }
    }

    /// `Cols` direction: the candidates of every image row into `self.cands` (rows the
    /// auto decision sampled reuse its candidates in `self.rows`).
    fn row_candidates<T: RidgePixel>(
        &mut self,
        img: &ImageView<'_, T>,
        d: usize,
        thr: T,
        auto: bool,
    ) {
        self.cands.clear();
        self.cands.resize(img.height(), LineCand::default());
        for (y, cand) in self.cands.iter_mut().enumerate() {
            // rows that the auto decision sampled are scanned already
            let sampled = (auto && y % AUTO_STEP == AUTO_STEP / 2)
                .then(|| self.rows.get(y / AUTO_STEP).copied())
                .flatten();
            match sampled {
                Some(c) => *cand = c,
                None => scan_line(img.row(y), d, thr, cand),
            }
        }
    }
}

/// The stripe point of scan line `l` from the sub-pixel result `s` on its segment that
/// starts at pixel `a`, its peak scaled by `back`.
#[inline]
fn place(dir: StripeDirection, l: usize, a: usize, s: &Sub, back: f32) -> StripePoint {
    let pos = a as f64 + s.c;
    let mut pt = if dir == StripeDirection::Rows {
        point(l as f64, pos, s)
    } else {
        point(pos, l as f64, s)
    };
    pt.peak *= back;
    pt
}

/// The stripe point at `(u, v)` of a sub-pixel result.
#[inline]
fn point(u: f64, v: f64, s: &Sub) -> StripePoint {
    StripePoint {
        u,
        v,
        peak: s.peak,
        width_px: s.width,
        support_px: s.support,
        flags: s.flags,
    }
}

/// Counts a rejected scan line.
#[inline]
fn count(rej: &mut RejectCounts, r: LineReject) {
    match r {
        LineReject::NoPeak => rej.no_peak += 1,
        LineReject::Multiple => rej.multiple_peaks += 1,
        LineReject::Reflection => rej.reflection_only += 1,
        LineReject::Shape => rej.shape += 1,
        LineReject::Saturated => rej.saturated += 1,
        LineReject::Border => rej.border += 1,
    }
}

/// `(scan line, position along it)` of a point.
#[inline]
fn line_and_position(p: &StripePoint, dir: StripeDirection) -> (f64, f64) {
    if dir == StripeDirection::Rows {
        (p.u, p.v)
    } else {
        (p.v, p.u)
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
    let key = |p: &StripePoint| line_and_position(p, dir);
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
    let key = |p: &StripePoint| line_and_position(p, dir);
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

/// Whether a scan line looks like it crosses the line: one peak, or two comparable ones
/// (the line and a reflection).
#[inline]
fn holds_line(c: &LineCand, ratio: f32) -> bool {
    match c.verdict(ratio) {
        Ok(_) => true,
        Err(LineReject::Multiple) => {
            let runs = c.runs();
            runs.len() >= 2
                && runs
                    .get(2)
                    .is_none_or(|r| r.strength_f32() < ratio * runs[0].strength_f32())
        }
        Err(_) => false,
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
        rows_hit += holds_line(&c, ratio) as usize;
        rows.push(c);
    }
    // Columns: the row-wise (cache friendly) ridge test of every column.
    cands.clear();
    cands.resize(w, LineCand::default());
    scan_columns(img, d, thr, cands);
    let cols_hit = cands.iter().filter(|c| holds_line(c, ratio)).count();
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
    use super::super::ridge::{scan_columns_generic, scan_line_generic};
    use super::*;
    use crate::vision::stripe::{extract_stripe, StripeMethod, StripeOptions, FLAG_SATURATED};

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
            assert!(a.iter().any(|c| c.has_peak()));
            let mut a = vec![LineCand::default(); w];
            let mut b = a.clone();
            scan_columns(&v16, d, 6 * 257, &mut a);
            scan_columns_generic(&v16, d, 6 * 257, &mut b);
            assert_eq!(a, b);
        }
    }

    /// A saturated line (5x full scale) whose plateau widens along its length, from 8 px
    /// over most of it to 24 px at its end (a line nearer the camera there, or on a
    /// brighter surface): the survey's wide end sets the ridge distance, so the widest
    /// scan lines are found too (from the median width alone, a ridge distance of 10 px,
    /// the last 7 % of the line had no peak), each centre the middle of the plateau's
    /// edges.
    #[test]
    fn a_widening_saturated_line_is_found_where_it_is_widest() {
        let (w, h) = (160usize, 240usize);
        let centre = |y: f64| 60.3 + 0.1 * y;
        let plateau = |y: f64| 8.0 + 16.0 * (y / h as f64).powi(4);
        let mut img = vec![0u8; w * h];
        let mut seed = 12345u64;
        for y in 0..h {
            let (c, half) = (centre(y as f64), 0.5 * plateau(y as f64));
            for x in 0..w {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let noise = ((seed >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 3.0;
                let t = x as f64 - c;
                // a smooth box, symmetric about the centre: logistic edges 1.2 px wide
                let edge = |d: f64| 1.0 / (1.0 + (-d / 1.2).exp());
                let v = 20.0 + 5.0 * 255.0 * edge(t + half) * edge(half - t) + noise;
                img[y * w + x] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
        let v = ImageView::from_slice(&img, w, h).unwrap();
        let s = extract_stripe(AnyView::U8(v), &StripeOptions::default()).unwrap();
        assert_eq!(s.direction, StripeDirection::Cols);
        assert!(s.survey.wide_px > s.survey.width_px + 4.0, "{:?}", s.survey);
        // the widest sixth of the line (plateaus of about 15-24 px)
        let wide_rows = (200..h - 2).filter(|&y| s.points.iter().any(|p| p.v == y as f64));
        assert!(wide_rows.count() >= 36, "{:?} {:?}", s.survey, s.rejected);
        assert!(
            s.points.len() >= h - 8,
            "{} {:?}",
            s.points.len(),
            s.rejected
        );
        for p in &s.points {
            assert!(
                (p.u - centre(p.v)).abs() < 0.1,
                "row {}: {} vs {}",
                p.v,
                p.u,
                centre(p.v)
            );
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
