//! Blob stage: adaptive threshold, connected components (run-length, 8-connected) and
//! shape filters that depend on the image size, never on fixed pixel sizes.
//!
//! The threshold compares each pixel with the mean of a square window whose side is a
//! fixed fraction of the shorter image side ([`super::CircleOptions::window_frac`]): a
//! pixel belongs to a blob when its "darkness" is below `threshold_ratio` times the
//! window mean. For light circles the image is inverted first (`MAX - I`), so the same
//! rule applies. A ratio (not a difference) keeps the rule independent of exposure and
//! of smooth illumination fall-off (vignetting).

use super::CircleOptions;

/// A grayscale image as `f32` intensities (row-major), plus what the stages need.
pub(crate) struct Img {
    pub w: usize,
    pub h: usize,
    pub px: Vec<f32>,
    /// Largest value of the pixel type (255 or 65535).
    pub max: f32,
}

impl Img {
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.px[y * self.w + x]
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
        let i = yi * self.w + xi;
        let (a, b) = (self.px[i] as f64, self.px[i + 1] as f64);
        let (c, d) = (self.px[i + self.w] as f64, self.px[i + self.w + 1] as f64);
        Some((a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy)
    }
}

/// A connected component that passed the filters.
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

/// Whether a blob is darker than its surroundings on every side: 16 samples on its
/// moment ellipse scaled by 1.6 must all be brighter than the midpoint between the
/// blob's centre and the samples' median, and the centre darker than `k` times that
/// median.
#[allow(clippy::too_many_arguments)]
fn surrounded(
    img: &Img,
    dv: &dyn Fn(f32) -> f32,
    cx: f64,
    cy: f64,
    sxx: f64,
    syy: f64,
    sxy: f64,
    ea: f64,
    eb: f64,
    k: f32,
) -> bool {
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let (ct, st) = (theta.cos(), theta.sin());
    let (xi, yi) = (cx.round() as usize, cy.round() as usize);
    let mut centre = 0.0f32;
    let mut n = 0.0f32;
    for y in yi.saturating_sub(1)..=(yi + 1).min(img.h - 1) {
        for x in xi.saturating_sub(1)..=(xi + 1).min(img.w - 1) {
            centre += dv(img.at(x, y));
            n += 1.0;
        }
    }
    let centre = centre / n;
    let mut ring: Vec<f32> = Vec::with_capacity(16);
    for q in 0..16 {
        let phi = std::f64::consts::TAU * q as f64 / 16.0;
        let (p, r) = (1.6 * ea * phi.cos(), 1.6 * eb * phi.sin());
        let (x, y) = (cx + p * ct - r * st, cy + p * st + r * ct);
        let (x, y) = (x.round(), y.round());
        if x >= 0.0 && y >= 0.0 && (x as usize) < img.w && (y as usize) < img.h {
            ring.push(dv(img.at(x as usize, y as usize)));
        }
    }
    if ring.len() < 12 {
        return false;
    }
    let mut sorted = ring.clone();
    sorted.sort_by(f32::total_cmp);
    let med = sorted[sorted.len() / 2];
    let mid = 0.5 * (centre + med);
    centre < k * med && ring.iter().all(|&v| v > mid)
}

#[derive(Clone, Copy)]
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

/// Finds the blobs: adaptive threshold, components, filters.
pub(crate) fn find_blobs(img: &Img, dark: bool, opts: &CircleOptions) -> (Vec<Blob>, BlobStats) {
    let (w, h) = (img.w, img.h);
    let short = w.min(h);
    let r = ((short as f64 * opts.window_frac * 0.5).round() as usize).max(3);
    let k = opts.threshold_ratio as f32;
    // "Darkness" value: circles are dark in it (branch-free: off + sgn * p).
    let (off, sgn) = if dark { (0.0, 1.0) } else { (img.max, -1.0) };
    let dv = move |p: f32| off + sgn * p;

    // Box mean: column sums over rows [y - r, y + r] (clamped, updated row by row), then
    // window sums along the row from their prefix sums.
    let mut col = vec![0f64; w];
    let top = r.min(h - 1);
    for y in 0..=top {
        for (c, &p) in col.iter_mut().zip(&img.px[y * w..(y + 1) * w]) {
            *c += dv(p) as f64;
        }
    }
    // Per column: the window's column range and k / its width.
    let lo: Vec<usize> = (0..w).map(|x| x.saturating_sub(r)).collect();
    let hi: Vec<usize> = (0..w).map(|x| (x + r + 1).min(w)).collect();
    let kx: Vec<f64> = (0..w).map(|x| k as f64 / (hi[x] - lo[x]) as f64).collect();
    let mut pre = vec![0f64; w + 1];
    let mut mask = vec![false; w];
    let mut runs: Vec<Run> = Vec::new();
    let mut row_start: Vec<usize> = Vec::with_capacity(h + 1);
    for y in 0..h {
        if y > 0 {
            if y + r < h {
                for (c, &p) in col.iter_mut().zip(&img.px[(y + r) * w..(y + r + 1) * w]) {
                    *c += dv(p) as f64;
                }
            }
            if y > r {
                let yo = y - r - 1;
                for (c, &p) in col.iter_mut().zip(&img.px[yo * w..(yo + 1) * w]) {
                    *c -= dv(p) as f64;
                }
            }
        }
        let rows_in = ((y + r).min(h - 1) - y.saturating_sub(r) + 1) as f64;
        let k_row = 1.0 / rows_in;
        // Prefix sums of the column sums: window sums by two look-ups. All values are
        // integers far below 2^53, so the sums are exact.
        for x in 0..w {
            pre[x + 1] = pre[x] + col[x];
        }
        let line = &img.px[y * w..(y + 1) * w];
        // dv < k * mean, without a division; the full-width middle part of the row in
        // a form the compiler vectorises
        let n = 2 * r + 1;
        let (a, b) = if w > n { (r, w - r) } else { (w, w) };
        for x in (0..a).chain(b..w) {
            mask[x] = (dv(line[x]) as f64) < (pre[hi[x]] - pre[lo[x]]) * kx[x] * k_row;
        }
        if a < b {
            let km = k as f64 / n as f64 * k_row;
            for (((m, &p), &h1), &l1) in mask[a..b]
                .iter_mut()
                .zip(&line[a..b])
                .zip(&pre[n..])
                .zip(&pre[..b - a])
            {
                *m = (dv(p) as f64) < (h1 - l1) * km;
            }
        }
        row_start.push(runs.len());
        let mut x = 0;
        while let Some(start) = mask[x..].iter().position(|&m| m) {
            let x0 = x + start;
            let len = mask[x0..].iter().position(|&m| !m).unwrap_or(w - x0);
            runs.push(Run {
                y: y as u32,
                x0: x0 as u32,
                x1: (x0 + len - 1) as u32,
            });
            x = x0 + len;
            if x >= w {
                break;
            }
        }
    }
    row_start.push(runs.len());

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
        let a = &mut acc[root];
        let (x0, x1, y) = (run.x0 as f64, run.x1 as f64, run.y as f64);
        let n = x1 - x0 + 1.0;
        let sx = (x0 + x1) * n * 0.5;
        // sum of x^2 for x in x0..=x1
        let sq = |t: f64| t * (t + 1.0) * (2.0 * t + 1.0) / 6.0;
        let sxx = sq(x1) - if x0 > 0.0 { sq(x0 - 1.0) } else { 0.0 };
        if a.n == 0.0 {
            roots.push(root as u32);
            a.x0 = run.x0;
            a.x1 = run.x1;
            a.y0 = run.y;
            a.y1 = run.y;
        }
        a.n += n;
        a.sx += sx;
        a.sy += y * n;
        a.sxx += sxx;
        a.syy += y * y * n;
        a.sxy += y * sx;
        a.x0 = a.x0.min(run.x0);
        a.x1 = a.x1.max(run.x1);
        a.y0 = a.y0.min(run.y);
        a.y1 = a.y1.max(run.y);
        if run.x0 == 0 || run.x1 as usize == w - 1 || run.y == 0 || run.y as usize == h - 1 {
            a.border = true;
        }
    }

    let mut stats = BlobStats {
        components: roots.len(),
        ..Default::default()
    };
    let max_diam = 0.5 * short as f64;
    let max_area = std::f64::consts::FRAC_PI_4 * max_diam * max_diam;
    let mut blobs = Vec::new();
    for &root in &roots {
        let a = acc[root as usize];
        if a.border {
            stats.touching_border += 1;
            continue;
        }
        if a.n < opts.min_area_px {
            stats.too_small += 1;
            continue;
        }
        if a.n > max_area {
            stats.too_large += 1;
            continue;
        }
        let (cx, cy) = (a.sx / a.n, a.sy / a.n);
        let sxx = a.sxx / a.n - cx * cx;
        let syy = a.syy / a.n - cy * cy;
        let sxy = a.sxy / a.n - cx * cy;
        let tr = 0.5 * (sxx + syy);
        let det = sxx * syy - sxy * sxy;
        let disc = (tr * tr - det).max(0.0).sqrt();
        let (l1, l2) = (tr + disc, tr - disc);
        if l2 <= 0.0 {
            stats.bad_shape += 1;
            continue;
        }
        let (ea, eb) = (2.0 * l1.sqrt(), 2.0 * l2.sqrt());
        let fill = a.n / (std::f64::consts::PI * ea * eb);
        // Bounding box of the moment ellipse (half widths), vs the component's.
        let hw = 2.0 * sxx.sqrt();
        let hh = 2.0 * syy.sqrt();
        let bw = (a.x1 - a.x0 + 1) as f64;
        let bh = (a.y1 - a.y0 + 1) as f64;
        let box_ok = (bw - 2.0 * hw).abs() <= 0.2 * 2.0 * hw + 2.0
            && (bh - 2.0 * hh).abs() <= 0.2 * 2.0 * hh + 2.0;
        if eb / ea < opts.min_axis_ratio || !(0.8..=1.2).contains(&fill) || !box_ok {
            stats.bad_shape += 1;
            continue;
        }
        if !surrounded(img, &dv, cx, cy, sxx, syy, sxy, ea, eb, k) {
            stats.not_surrounded += 1;
            continue;
        }
        blobs.push(Blob {
            cx,
            cy,
            area: a.n,
            sxx,
            syy,
            sxy,
            a: ea,
            b: eb,
        });
    }
    (blobs, stats)
}
