//! Blob stage: adaptive threshold, connected components (run-length, 8-connected) and
//! shape filters that depend on the image size, never on fixed pixel sizes.
//!
//! The threshold compares each pixel with the mean of a square window whose side is a
//! fixed fraction of the shorter image side ([`super::CircleOptions::window_frac`]): a
//! pixel belongs to a blob when its "darkness" is below `threshold_ratio` times the
//! window mean. For light circles the image is inverted first (`MAX - I`), so the same
//! rule applies. A ratio (not a difference) keeps the rule independent of exposure and
//! of smooth illumination fall-off (vignetting). Window sums are exact integers (column
//! sums updated row by row, then prefix sums along the row); the comparison is in `f32`.
//!
//! Components that touch the image border are cut circles: their centres cannot be
//! measured, but a cut *marker* may still be told from an ordinary circle by its visible
//! size, so they are returned separately ([`Blobs::cut`]) for the grid stage.

use super::CircleOptions;
use crate::model::image::{ImageView, Pixel};

/// A grayscale image borrowed for the circle stages.
#[derive(Clone, Copy)]
pub(crate) struct Img<'a, T> {
    pub view: ImageView<'a, T>,
    pub w: usize,
    pub h: usize,
    /// Largest value of the pixel type (255 or 65535).
    pub max: f32,
}

impl<'a, T: Pixel> Img<'a, T> {
    pub fn new(view: ImageView<'a, T>) -> Self {
        Img {
            view,
            w: view.width(),
            h: view.height(),
            max: T::MAX,
        }
    }

    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.view.get(x, y).to_f32()
    }

    #[inline]
    pub fn row(&self, y: usize) -> &'a [T] {
        self.view.row(y)
    }

    /// Bilinear sample at `(u, v)` (pixel centres at integers); `None` outside the
    /// area where all four neighbours exist.
    #[inline]
    pub fn bilinear(&self, u: f64, v: f64) -> Option<f64> {
        if !(u >= 0.0 && v >= 0.0) {
            return None;
        }
        // u, v >= 0: truncation is floor (and much cheaper than a libm call)
        let (xi, yi) = (u as usize, v as usize);
        if xi + 1 >= self.w || yi + 1 >= self.h {
            return None;
        }
        let (fx, fy) = (u - xi as f64, v - yi as f64);
        let (r0, r1) = (self.row(yi), self.row(yi + 1));
        let (a, b) = (r0[xi].to_f32() as f64, r0[xi + 1].to_f32() as f64);
        let (c, d) = (r1[xi].to_f32() as f64, r1[xi + 1].to_f32() as f64);
        Some((a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy)
    }

    /// Smallest and largest pixel value over every other row (a contrast check).
    pub fn range(&self) -> (f32, f32) {
        let (mut lo, mut hi) = (u32::MAX, 0u32);
        for y in (0..self.h).step_by(2) {
            // min / max in the pixel type reduce in vector registers
            let row = self.row(y);
            let (mut a, mut b) = (row[0], row[0]);
            for &p in row {
                a = if p < a { p } else { a };
                b = if p > b { p } else { b };
            }
            lo = lo.min(a.to_u32());
            hi = hi.max(b.to_u32());
        }
        (lo as f32, hi as f32)
    }
}

/// A connected component: its pixel moments and, for a blob that passed the filters,
/// its moment ellipse.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Blob {
    /// Centroid of the component's pixels.
    pub cx: f64,
    pub cy: f64,
    /// Pixel count.
    pub area: f64,
    /// Covariance of the pixel positions.
    pub sxx: f64,
    pub syy: f64,
    pub sxy: f64,
    /// Semi-axes (major, minor) of the moment ellipse: `2 sqrt(eigenvalue)`.
    pub a: f64,
    pub b: f64,
}

/// Counts of what the blob stage saw (for error messages).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct BlobStats {
    pub components: usize,
    pub touching_border: usize,
    pub too_small: usize,
    pub too_large: usize,
    pub bad_shape: usize,
    /// Dark regions not surrounded by a brighter background on every side (e.g. the
    /// part of the table next to the plate's edge).
    pub not_surrounded: usize,
}

/// What the blob stage found.
pub(crate) struct Blobs {
    /// Components that passed every filter.
    pub blobs: Vec<Blob>,
    /// Components touching the image border, of a plausible size (candidates for cut
    /// markers; their moments are of the visible part only).
    pub cut: Vec<Blob>,
    pub stats: BlobStats,
}

/// Whether a blob is darker than its surroundings: of 16 samples on its moment ellipse
/// scaled by 1.3 (plus 1.5 px of blur), at least 8 must be inside the image, at most a
/// quarter of those may fail to be brighter than the midpoint between the blob's centre
/// and the samples' median (a neighbouring circle close to a large marker, a cable), and
/// the centre must be darker than `k` times that median.
fn surrounded<T: Pixel>(
    img: &Img<'_, T>,
    dv: &dyn Fn(f32) -> f32,
    b: &Blob,
    k: f32,
    ring: &mut Vec<f32>,
) -> bool {
    let theta = 0.5 * (2.0 * b.sxy).atan2(b.sxx - b.syy);
    let (ct, st) = (theta.cos(), theta.sin());
    let (xi, yi) = (b.cx.round() as usize, b.cy.round() as usize);
    let mut centre = 0.0f32;
    let mut n = 0.0f32;
    for y in yi.saturating_sub(1)..=(yi + 1).min(img.h - 1) {
        for x in xi.saturating_sub(1)..=(xi + 1).min(img.w - 1) {
            centre += dv(img.at(x, y));
            n += 1.0;
        }
    }
    let centre = centre / n;
    ring.clear();
    for q in 0..16 {
        let phi = std::f64::consts::TAU * q as f64 / 16.0;
        let (p, r) = ((1.3 * b.a + 1.5) * phi.cos(), (1.3 * b.b + 1.5) * phi.sin());
        let (x, y) = (
            (b.cx + p * ct - r * st).round(),
            (b.cy + p * st + r * ct).round(),
        );
        if x >= 0.0 && y >= 0.0 && (x as usize) < img.w && (y as usize) < img.h {
            ring.push(dv(img.at(x as usize, y as usize)));
        }
    }
    if ring.len() < 8 {
        return false;
    }
    let m = ring.len() / 2;
    let med = *ring.select_nth_unstable_by(m, f32::total_cmp).1;
    let mid = 0.5 * (centre + med);
    let fails = ring.iter().filter(|&&v| v <= mid).count();
    centre < k * med && 4 * fails <= ring.len()
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Run {
    y: u32,
    x0: u32,
    x1: u32, // inclusive
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[i as usize];
        parent[i as usize] = parent[p as usize];
        i = p;
    }
    i
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        parent[hi as usize] = lo;
    }
}

#[derive(Clone, Copy, Default)]
struct Acc {
    n: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    syy: f64,
    sxy: f64,
    x0: u32,
    x1: u32,
    y0: u32,
    y1: u32,
    border: bool,
}

impl Acc {
    fn add(&mut self, run: Run, w: usize, h: usize) {
        let (x0, x1, y) = (run.x0 as f64, run.x1 as f64, run.y as f64);
        let n = x1 - x0 + 1.0;
        let sx = (x0 + x1) * n * 0.5;
        // sum of x^2 for x in x0..=x1
        let sq = |t: f64| t * (t + 1.0) * (2.0 * t + 1.0) / 6.0;
        let sxx = sq(x1) - if x0 > 0.0 { sq(x0 - 1.0) } else { 0.0 };
        if self.n == 0.0 {
            (self.x0, self.x1, self.y0, self.y1) = (run.x0, run.x1, run.y, run.y);
        }
        self.n += n;
        self.sx += sx;
        self.sy += y * n;
        self.sxx += sxx;
        self.syy += y * y * n;
        self.sxy += y * sx;
        self.x0 = self.x0.min(run.x0);
        self.x1 = self.x1.max(run.x1);
        self.y0 = self.y0.min(run.y);
        self.y1 = self.y1.max(run.y);
        if run.x0 == 0 || run.x1 as usize == w - 1 || run.y == 0 || run.y as usize == h - 1 {
            self.border = true;
        }
    }

    /// Centroid, covariance and moment-ellipse semi-axes; `None` for a degenerate
    /// (line-like) component.
    fn blob(&self) -> Option<Blob> {
        let (cx, cy) = (self.sx / self.n, self.sy / self.n);
        let sxx = self.sxx / self.n - cx * cx;
        let syy = self.syy / self.n - cy * cy;
        let sxy = self.sxy / self.n - cx * cy;
        let tr = 0.5 * (sxx + syy);
        let det = sxx * syy - sxy * sxy;
        let disc = (tr * tr - det).max(0.0).sqrt();
        let (l1, l2) = (tr + disc, tr - disc);
        if l2.is_nan() || l2 <= 0.0 {
            return None;
        }
        Some(Blob {
            cx,
            cy,
            area: self.n,
            sxx,
            syy,
            sxy,
            a: 2.0 * l1.sqrt(),
            b: 2.0 * l2.sqrt(),
        })
    }
}

/// The threshold mask as runs of blob pixels, row by row: `(runs, row_start)` with the
/// runs of row `y` in `runs[row_start[y]..row_start[y + 1]]`.
fn threshold_runs<T: Pixel>(
    img: &Img<'_, T>,
    dark: bool,
    opts: &CircleOptions,
) -> (Vec<Run>, Vec<usize>) {
    if dark {
        threshold_runs_as::<T, true>(img, opts)
    } else {
        threshold_runs_as::<T, false>(img, opts)
    }
}

/// [`threshold_runs`] for dark (`DARK`) or light circles.
///
/// Sums are `u32`: column sums over the window's rows updated row by row, then
/// wrapping prefix sums along the row, whose differences are the exact window sums as
/// long as a window's sum is below 2^31 (it then converts to `f32` in vector
/// registers, as an `i32`). For 16-bit images with very large windows the
/// darkness is shifted right first so that it is (a threshold does not need 16 bits).
fn threshold_runs_as<T: Pixel, const DARK: bool>(
    img: &Img<'_, T>,
    opts: &CircleOptions,
) -> (Vec<Run>, Vec<usize>) {
    let (w, h) = (img.w, img.h);
    let short = w.min(h);
    let r = ((short as f64 * opts.window_frac * 0.5).round() as usize).max(3);
    let k = opts.threshold_ratio as f32;
    let n = 2 * r + 1;
    let maxv = T::MAX as u32;
    let mut shift = 0u32;
    while (n as u64) * (n as u64) * ((maxv >> shift) as u64) >= 1 << 31 {
        shift += 1;
    }
    // "Darkness": circles are dark in it.
    let dark_row = |row: &[T], out: &mut [u32]| {
        for (o, p) in out.iter_mut().zip(row) {
            let v = p.to_u32();
            *o = (if DARK { v } else { maxv - v }) >> shift;
        }
    };
    let mut col = vec![0u32; w];
    let mut tmp = vec![0u32; w];
    let mut old = vec![0u32; w];
    for y in 0..=r.min(h - 1) {
        dark_row(img.row(y), &mut tmp);
        for (c, &d) in col.iter_mut().zip(&tmp) {
            *c += d;
        }
    }
    let lo: Vec<usize> = (0..w).map(|x| x.saturating_sub(r)).collect();
    let hi: Vec<usize> = (0..w).map(|x| (x + r + 1).min(w)).collect();
    let kx: Vec<f32> = (0..w).map(|x| k / (hi[x] - lo[x]) as f32).collect();
    let mut pre = vec![0u32; w + 1];
    let mut line = vec![0u32; w];
    let mut mask = vec![0u8; w];
    let mut runs: Vec<Run> = Vec::new();
    let mut row_start: Vec<usize> = Vec::with_capacity(h + 1);
    for y in 0..h {
        if y > 0 {
            match (y + r < h, y > r) {
                (true, true) => {
                    dark_row(img.row(y + r), &mut tmp);
                    dark_row(img.row(y - r - 1), &mut old);
                    for ((c, &d), &o) in col.iter_mut().zip(&tmp).zip(&old) {
                        *c = *c + d - o;
                    }
                }
                (true, false) => {
                    dark_row(img.row(y + r), &mut tmp);
                    for (c, &d) in col.iter_mut().zip(&tmp) {
                        *c += d;
                    }
                }
                (false, true) => {
                    dark_row(img.row(y - r - 1), &mut old);
                    for (c, &o) in col.iter_mut().zip(&old) {
                        *c -= o;
                    }
                }
                (false, false) => {}
            }
        }
        let rows_in = ((y + r).min(h - 1) - y.saturating_sub(r) + 1) as f32;
        let k_row = 1.0 / rows_in;
        let mut acc = 0u32;
        for (p, &c) in pre[1..].iter_mut().zip(&col) {
            acc = acc.wrapping_add(c);
            *p = acc;
        }
        dark_row(img.row(y), &mut line);
        // darkness < k * window mean, without a division: the edge columns with their
        // own window widths, the full-width middle of the row over contiguous slices
        // (window sums are below 2^31: as i32 they convert in vector registers)
        let (a, b) = if w > n { (r, w - r) } else { (w, w) };
        for x in (0..a).chain(b..w) {
            let sum = pre[hi[x]].wrapping_sub(pre[lo[x]]) as i32 as f32;
            mask[x] = ((line[x] as i32 as f32) < sum * kx[x] * k_row) as u8;
        }
        if a < b {
            let km = k / n as f32 * k_row;
            let (m, d) = (&mut mask[a..b], &line[a..b]);
            let (h1, l1) = (&pre[n..n + (b - a)], &pre[..b - a]);
            for x in 0..b - a {
                m[x] = ((d[x] as i32 as f32) < h1[x].wrapping_sub(l1[x]) as i32 as f32 * km) as u8;
            }
        }
        row_start.push(runs.len());
        push_runs(&mask, y as u32, &mut runs);
    }
    row_start.push(runs.len());
    (runs, row_start)
}

/// Appends the runs of set bytes (0 or 1) of one mask row. Eight bytes are read as
/// one word: all-zero and all-one words are skipped whole, the others are split by
/// bit scans.
fn push_runs(mask: &[u8], y: u32, runs: &mut Vec<Run>) {
    const ONES: u64 = 0x0101_0101_0101_0101;
    let w = mask.len();
    let mut start: Option<usize> = None;
    let close = |s0: usize, end: usize, runs: &mut Vec<Run>| {
        runs.push(Run {
            y,
            x0: s0 as u32,
            x1: (end - 1) as u32,
        })
    };
    let mut x = 0;
    while x + 8 <= w {
        let mut bytes = [0u8; 8];
        bytes.copy_from_slice(&mask[x..x + 8]);
        // little-endian: byte k of the row is bits 8k..8k+8
        let mut word = u64::from_le_bytes(bytes) & ONES;
        let mut pos = 0u32;
        while pos < 8 {
            if start.is_none() {
                if word == 0 {
                    break;
                }
                let k = word.trailing_zeros() / 8;
                start = Some(x + k as usize);
                pos = k;
            }
            // the run is open from byte `pos`: find the next zero byte
            let zeros = !word & ONES & (u64::MAX << (8 * pos));
            if zeros == 0 {
                break;
            }
            let k = zeros.trailing_zeros() / 8;
            if let Some(s0) = start.take() {
                close(s0, x + k as usize, runs);
            }
            pos = k;
            word &= u64::MAX.checked_shl(8 * (k + 1)).unwrap_or(0);
        }
        x += 8;
    }
    for (k, &m) in mask.iter().enumerate().skip(x) {
        match (m != 0, start) {
            (true, None) => start = Some(k),
            (false, Some(s0)) => {
                close(s0, k, runs);
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s0) = start {
        close(s0, w, runs);
    }
}

/// Finds the blobs: adaptive threshold, components, filters.
pub(crate) fn find_blobs<T: Pixel>(img: &Img<'_, T>, dark: bool, opts: &CircleOptions) -> Blobs {
    let (w, h) = (img.w, img.h);
    let (runs, row_start) = threshold_runs(img, dark, opts);

    // Union runs of consecutive rows that touch (8-connectivity).
    let mut parent: Vec<u32> = (0..runs.len() as u32).collect();
    for y in 1..h {
        let (pa, pb) = (row_start[y - 1], row_start[y]);
        let (ca, cb) = (row_start[y], row_start[y + 1]);
        let mut i = pa;
        for j in ca..cb {
            let cur = runs[j];
            while i < pb && runs[i].x1 + 1 < cur.x0 {
                i += 1;
            }
            let mut k2 = i;
            while k2 < pb && runs[k2].x0 <= cur.x1 + 1 {
                union(&mut parent, k2 as u32, j as u32);
                k2 += 1;
            }
        }
    }
    let mut acc: Vec<Acc> = vec![Acc::default(); runs.len()];
    let mut roots: Vec<u32> = Vec::new();
    for (i, &run) in runs.iter().enumerate() {
        let root = find(&mut parent, i as u32) as usize;
        if acc[root].n == 0.0 {
            roots.push(root as u32);
        }
        acc[root].add(run, w, h);
    }

    let mut stats = BlobStats {
        components: roots.len(),
        ..Default::default()
    };
    let short = w.min(h);
    let max_diam = 0.5 * short as f64;
    let max_area = std::f64::consts::FRAC_PI_4 * max_diam * max_diam;
    let (off, sgn) = if dark { (0.0, 1.0) } else { (img.max, -1.0) };
    let dvf = move |p: f32| off + sgn * p;
    let k = opts.threshold_ratio as f32;
    let mut ring = Vec::with_capacity(16);
    let mut blobs = Vec::new();
    let mut cut = Vec::new();
    for &root in &roots {
        let a = acc[root as usize];
        if a.n < opts.min_area_px {
            stats.too_small += 1;
            continue;
        }
        if a.n > max_area {
            stats.too_large += 1;
            continue;
        }
        if a.border {
            stats.touching_border += 1;
            if let Some(b) = a.blob() {
                cut.push(b);
            }
            continue;
        }
        let Some(b) = a.blob() else {
            stats.bad_shape += 1;
            continue;
        };
        let fill = a.n / (std::f64::consts::PI * b.a * b.b);
        // Bounding box of the moment ellipse (half widths), vs the component's.
        let hw = 2.0 * b.sxx.sqrt();
        let hh = 2.0 * b.syy.sqrt();
        let bw = (a.x1 - a.x0 + 1) as f64;
        let bh = (a.y1 - a.y0 + 1) as f64;
        let box_ok = (bw - 2.0 * hw).abs() <= 0.2 * 2.0 * hw + 2.0
            && (bh - 2.0 * hh).abs() <= 0.2 * 2.0 * hh + 2.0;
        if b.b / b.a < opts.min_axis_ratio || !(0.8..=1.2).contains(&fill) || !box_ok {
            stats.bad_shape += 1;
            continue;
        }
        if !surrounded(img, &dvf, &b, k, &mut ring) {
            stats.not_surrounded += 1;
            continue;
        }
        blobs.push(b);
    }
    Blobs { blobs, cut, stats }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The word-wise run extraction against a byte-by-byte reference.
    #[test]
    fn runs_match_a_byte_scan() {
        let mut state = 7u64;
        for len in [1usize, 7, 8, 9, 16, 23, 64, 100] {
            for density in [1u64, 3, 8, 13] {
                let mask: Vec<u8> = (0..len)
                    .map(|_| {
                        state = state
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        ((state >> 60) < density) as u8
                    })
                    .collect();
                let mut got = Vec::new();
                push_runs(&mask, 3, &mut got);
                let mut want = Vec::new();
                let mut x = 0;
                while x < len {
                    if mask[x] == 1 {
                        let s0 = x;
                        while x < len && mask[x] == 1 {
                            x += 1;
                        }
                        want.push(Run {
                            y: 3,
                            x0: s0 as u32,
                            x1: (x - 1) as u32,
                        });
                    } else {
                        x += 1;
                    }
                }
                assert_eq!(got, want, "{mask:?}");
            }
        }
    }
}
