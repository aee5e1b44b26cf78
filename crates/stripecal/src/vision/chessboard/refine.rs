//! Sub-pixel saddle points: a blurred X-junction model fitted in a window that is
//! re-centred on the estimate at every step.
//!
//! ## Model
//!
//! Two straight edges through the corner `c` at angles `a1`, `a2` (a projective image of
//! a chessboard corner is exactly that, whatever the tilt), blurred by a Gaussian of
//! width `s` (PSF and pixel area together):
//!
//! `M(x) = erf(n1 . (x - c) / (sqrt 2 s)) erf(n2 . (x - c) / (sqrt 2 s))`,
//!
//! and the image `I(x) = p0 + p1 M + (p2 + p3 M) dx / R + (p4 + p5 M) dy / R` with
//! `(dx, dy) = x - c` and `R` the window radius. The `p2, p4` terms are an additive
//! linear illumination gradient (ambient light), `p3, p5` a multiplicative one (the
//! light on the board times its reflectance): a plain model without them is biased by
//! a gradient across the window. All eleven parameters are fitted by
//! Levenberg-Marquardt with the window (a disc of radius `R`, a one-pixel linear taper
//! at its rim) centred on the current `c`.
//!
//! ## Why the window is symmetric
//!
//! Near its centre the model's blur of an oblique junction is only approximately a
//! Gaussian blur, but both the image of the junction and the model family are point
//! symmetric about their centre. With the window symmetric about `c` the cost is then
//! symmetric under the point reflection about the true corner, so the fitted centre has
//! no bias from the model's approximation (only the pixel grid breaks the symmetry, a
//! small effect that averages out). The window radius stays below the distance to the
//! neighbouring squares' far edges (from the local lattice vectors), so the model's two
//! edges are all the window sees.
//!
//! ## Start
//!
//! The grid gives positions within a few pixels (coarse pyramid levels). A few steps of
//! the gradient-orthogonality estimate (each gradient is orthogonal to the direction
//! from the corner, solved in closed form) bring the start within a fraction of a pixel
//! before the model fit.
//!
//! ## Quality and stripes
//!
//! The reported quality is the formal standard deviation of the position,
//! `sqrt((C_uu + C_vv) / 2)` from `s^2 (J^T W J)^-1` with `s` the residual RMS: it
//! grows with noise, blur, low contrast and any misfit. Pixels far brighter than the
//! fitted model (by more than half the contrast) are a bright stripe crossing the
//! window.

use std::collections::HashSet;

use nalgebra::{SMatrix, SVector};

use super::image::Gray;
use super::lattice::{cross, norm};

const NP: usize = 11;
type Mat = SMatrix<f64, NP, NP>;
type Vec11 = SVector<f64, NP>;

/// A measured corner.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Saddle {
    pub u: f64,
    pub v: f64,
    /// Formal standard deviation of the position, px.
    pub sigma_px: f64,
    /// Fitted contrast (light minus dark), image units.
    pub contrast: f64,
    /// The window had to be shrunk to fit, or ends within 2 px of the image border.
    pub near_border: bool,
    /// A bright stripe crosses the window (kept: the stripe pixels and their mirror
    /// images were left out of the fit).
    pub stripe: bool,
}

/// Why a corner could not be measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Fail {
    Stripe,
    Border,
    NotCorner(&'static str),
}

impl Fail {
    pub fn reason(self) -> &'static str {
        match self {
            Fail::Stripe => "crossed by a bright stripe",
            Fail::Border => "too close to the image border for a measuring window",
            Fail::NotCorner(r) => r,
        }
    }
}

/// Settings of one refinement.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Settings {
    pub max_radius: f64,
    pub keep_stripe: bool,
    /// Image noise sigma, image units.
    pub noise: f64,
}

/// `erf` (Abramowitz & Stegun 7.1.26, |error| < 1.5e-7) and `exp(-x^2)`.
#[inline]
fn erf_exp(x: f64) -> (f64, f64) {
    let a = x.abs();
    if a > 6.0 {
        // erf within 3e-17 of +-1, exp(-36) below 3e-16
        return (x.signum(), 0.0);
    }
    let t = 1.0 / (1.0 + 0.3275911 * a);
    let e = (-a * a).exp();
    let poly =
        ((((1.061405429 * t - 1.453152027) * t + 1.421413741) * t - 0.284496736) * t + 0.254829592) * t;
    let y = 1.0 - poly * e;
    (if x < 0.0 { -y } else { y }, e)
}

const TWO_OVER_SQRT_PI: f64 = std::f64::consts::FRAC_2_SQRT_PI;

/// Window pixels: `(dx, dy, value, weight)` relative to the centre.
fn window(g: &Gray, c: [f64; 2], r: f64, mask: &HashSet<(i32, i32)>, out: &mut Vec<[f64; 4]>) {
    out.clear();
    let (x0, x1) = ((c[0] - r - 0.5).ceil() as i64, (c[0] + r + 0.5).floor() as i64);
    let (y0, y1) = ((c[1] - r - 0.5).ceil() as i64, (c[1] + r + 0.5).floor() as i64);
    for y in y0.max(0)..=y1.min(g.h as i64 - 1) {
        for x in x0.max(0)..=x1.min(g.w as i64 - 1) {
            let (dx, dy) = (x as f64 - c[0], y as f64 - c[1]);
            let w = (r + 0.5 - (dx * dx + dy * dy).sqrt()).clamp(0.0, 1.0);
            if w <= 0.0 {
                continue;
            }
            if !mask.is_empty() {
                let (mx, my) = ((2.0 * c[0] - x as f64).round(), (2.0 * c[1] - y as f64).round());
                if mask.contains(&(x as i32, y as i32)) || mask.contains(&(mx as i32, my as i32)) {
                    continue;
                }
            }
            out.push([dx, dy, g.at(x as usize, y as usize) as f64, w]);
        }
    }
}

/// The model for one parameter vector (`th = [cx, cy, a1, a2, ln s, p0..p5]`), with
/// the per-vector constants computed once.
struct Model {
    th: Vec11,
    s1a: f64,
    c1a: f64,
    s2a: f64,
    c2a: f64,
    k: f64,
    inv_r: f64,
}

impl Model {
    fn new(th: &Vec11, inv_r: f64) -> Model {
        let (s1a, c1a) = th[2].sin_cos();
        let (s2a, c2a) = th[3].sin_cos();
        Model {
            th: *th,
            s1a,
            c1a,
            s2a,
            c2a,
            k: std::f64::consts::FRAC_1_SQRT_2 * (-th[4]).exp(),
            inv_r,
        }
    }

    /// Model value and `M` at offset `(dx, dy)` from the centre.
    #[inline]
    fn value(&self, dx: f64, dy: f64) -> (f64, f64) {
        let th = &self.th;
        let s1 = -self.s1a * dx + self.c1a * dy;
        let s2 = -self.s2a * dx + self.c2a * dy;
        let m = erf_exp(self.k * s1).0 * erf_exp(self.k * s2).0;
        let (ux, uy) = (dx * self.inv_r, dy * self.inv_r);
        (th[5] + th[6] * m + (th[7] + th[8] * m) * ux + (th[9] + th[10] * m) * uy, m)
    }

    /// Model value and its gradient with respect to the 11 parameters.
    #[inline]
    fn eval(&self, dx: f64, dy: f64) -> (f64, Vec11) {
        let (th, k, inv_r) = (&self.th, self.k, self.inv_r);
        let (s1a, c1a, s2a, c2a) = (self.s1a, self.c1a, self.s2a, self.c2a);
        let s1 = -s1a * dx + c1a * dy;
        let s2 = -s2a * dx + c2a * dy;
        let (e1, g1) = erf_exp(k * s1);
        let (e2, g2) = erf_exp(k * s2);
        let (g1, g2) = (TWO_OVER_SQRT_PI * g1, TWO_OVER_SQRT_PI * g2);
        let m = e1 * e2;
        let (ux, uy) = (dx * inv_r, dy * inv_r);
        let f = th[5] + th[6] * m + (th[7] + th[8] * m) * ux + (th[9] + th[10] * m) * uy;
        let a = th[6] + th[8] * ux + th[10] * uy;
        let dm_ds1 = k * g1 * e2;
        let dm_ds2 = k * g2 * e1;
        let mut j = Vec11::zeros();
        // s1 = n1 . (x - c): ds1/dcx = s1a, ds1/dcy = -c1a
        j[0] = a * (dm_ds1 * s1a + dm_ds2 * s2a) - (th[7] + th[8] * m) * inv_r;
        j[1] = a * (-dm_ds1 * c1a - dm_ds2 * c2a) - (th[9] + th[10] * m) * inv_r;
        // ds1/da1 = -(c1a dx + s1a dy)
        j[2] = a * dm_ds1 * -(c1a * dx + s1a * dy);
        j[3] = a * dm_ds2 * -(c2a * dx + s2a * dy);
        j[4] = -a * (s1 * dm_ds1 + s2 * dm_ds2);
        j[5] = 1.0;
        j[6] = m;
        j[7] = ux;
        j[8] = m * ux;
        j[9] = uy;
        j[10] = m * uy;
        (f, j)
    }
}

/// Normal equations of the window: `(J^T W J, J^T W r, cost, weight sum)`.
fn normal(th: &Vec11, px: &[[f64; 4]], inv_r: f64) -> (Mat, Vec11, f64, f64) {
    // upper triangle of J^T W J, row by row
    let mut tri = [0f64; NP * (NP + 1) / 2];
    let mut b = Vec11::zeros();
    let (mut cost, mut wsum) = (0.0, 0.0);
    let md = Model::new(th, inv_r);
    for q in px {
        let (f, j) = md.eval(q[0], q[1]);
        let r = q[2] - f;
        let mut k = 0;
        for a in 0..NP {
            let wa = q[3] * j[a];
            for c in a..NP {
                tri[k] += wa * j[c];
                k += 1;
            }
        }
        b.axpy(q[3] * r, &j, 1.0);
        cost += q[3] * r * r;
        wsum += q[3];
    }
    let mut h = Mat::zeros();
    let mut k = 0;
    for a in 0..NP {
        for c in a..NP {
            h[(a, c)] = tri[k];
            h[(c, a)] = tri[k];
            k += 1;
        }
    }
    (h, b, cost, wsum)
}

fn cost_of(th: &Vec11, px: &[[f64; 4]], inv_r: f64) -> f64 {
    let md = Model::new(th, inv_r);
    px.iter()
        .map(|q| {
            let (f, _) = md.value(q[0], q[1]);
            q[3] * (q[2] - f).powi(2)
        })
        .sum()
}

/// Gradient-orthogonality estimate (a few closed-form steps).
fn orthogonality_start(g: &Gray, start: [f64; 2], r: f64, mask: &HashSet<(i32, i32)>) -> Option<[f64; 2]> {
    let mut c = start;
    let s2 = 2.0 * (0.5 * r).powi(2);
    for _ in 0..10 {
        let (mut a, mut b, mut d, mut bx, mut by) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let (x0, x1) = ((c[0] - r).ceil() as i64, (c[0] + r).floor() as i64);
        let (y0, y1) = ((c[1] - r).ceil() as i64, (c[1] + r).floor() as i64);
        for y in y0.max(1)..=y1.min(g.h as i64 - 2) {
            for x in x0.max(1)..=x1.min(g.w as i64 - 2) {
                if !mask.is_empty() {
                    let (mx, my) = ((2.0 * c[0] - x as f64).round(), (2.0 * c[1] - y as f64).round());
                    if mask.contains(&(x as i32, y as i32)) || mask.contains(&(mx as i32, my as i32)) {
                        continue;
                    }
                }
                let (xu, yu) = (x as usize, y as usize);
                let gx = 0.5 * (g.at(xu + 1, yu) - g.at(xu - 1, yu)) as f64;
                let gy = 0.5 * (g.at(xu, yu + 1) - g.at(xu, yu - 1)) as f64;
                let (dx, dy) = (x as f64 - c[0], y as f64 - c[1]);
                let w = (-(dx * dx + dy * dy) / s2).exp();
                let (gxx, gxy, gyy) = (w * gx * gx, w * gx * gy, w * gy * gy);
                a += gxx;
                b += gxy;
                d += gyy;
                bx += gxx * x as f64 + gxy * y as f64;
                by += gxy * x as f64 + gyy * y as f64;
            }
        }
        let det = a * d - b * b;
        if !(det > 1e-12 * (a + d) * (a + d)) {
            return None;
        }
        let n = [(d * bx - b * by) / det, (a * by - b * bx) / det];
        let step = norm([n[0] - c[0], n[1] - c[1]]);
        c = n;
        if !(step.is_finite()) {
            return None;
        }
        if step < 0.02 {
            break;
        }
    }
    Some(c)
}

/// Angle difference modulo pi, in [0, pi/2].
fn line_angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::PI);
    d.min(std::f64::consts::PI - d)
}

/// The fit itself: returns the parameters, the final window and its normal equations.
fn fit(
    g: &Gray,
    c0: [f64; 2],
    angles: [f64; 2],
    r: f64,
    mask: &HashSet<(i32, i32)>,
) -> Option<(Vec11, Vec<[f64; 4]>, Mat, f64, f64)> {
    let inv_r = 1.0 / r;
    let mut th = Vec11::zeros();
    th[0] = c0[0];
    th[1] = c0[1];
    th[2] = angles[0];
    th[3] = angles[1];
    th[4] = 0.0;
    let mut px = Vec::with_capacity(512);
    window(g, c0, r, mask, &mut px);
    if px.len() < 20 {
        return None;
    }
    // linear part first: contrast and illumination for the starting geometry
    {
        let (h, b, _, _) = normal(&th, &px, inv_r);
        let hl = h.fixed_view::<6, 6>(5, 5).into_owned();
        let bl = b.fixed_rows::<6>(5).into_owned();
        let sol = hl.cholesky()?.solve(&bl);
        for k in 0..6 {
            th[5 + k] = sol[k];
        }
    }
    let mut lambda = 1e-3;
    for _ in 0..40 {
        window(g, [th[0], th[1]], r, mask, &mut px);
        if px.len() < 20 {
            return None;
        }
        // the parameters are relative to the centre: shifting the window keeps them
        let (h, b, cost, _) = normal(&th, &px, inv_r);
        let mut accepted = None;
        for _ in 0..8 {
            let mut ha = h;
            for k in 0..NP {
                ha[(k, k)] += lambda * h[(k, k)].max(1e-12);
            }
            let Some(ch) = ha.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let delta = ch.solve(&b);
            let mut t2 = th + delta;
            // the centre moved: keep the offsets relative to the trial centre
            t2[4] = t2[4].clamp(-3.0, 3.0);
            let trial: Vec<[f64; 4]> = px
                .iter()
                .map(|q| [q[0] - delta[0], q[1] - delta[1], q[2], q[3]])
                .collect();
            let c2 = cost_of(&t2, &trial, inv_r);
            if c2.is_finite() && c2 <= cost {
                lambda = (lambda / 3.0).max(1e-9);
                accepted = Some((t2, delta));
                break;
            }
            lambda *= 4.0;
        }
        let Some((t2, delta)) = accepted else {
            break;
        };
        th = t2;
        if delta[0].hypot(delta[1]) < 2e-4 && delta[2].abs() < 2e-4 && delta[3].abs() < 2e-4 {
            break;
        }
    }
    window(g, [th[0], th[1]], r, mask, &mut px);
    let (h, _, cost, wsum) = normal(&th, &px, inv_r);
    th.iter().all(|v| v.is_finite()).then_some((th, px, h, cost, wsum))
}

/// The four squares around a corner at `c` (medians over their central parts): the
/// diagonal pairs must agree within `ratio` times their difference from each other
/// (an X-junction, not an L or a T where a board ends: there the ratio is 2), the pair
/// between `+i` and `+j` light iff `light_ij`.
/// Returns the light and dark levels; [`Fail::Border`] when a square is not in the
/// image even near the corner.
fn quadrants(
    g: &Gray,
    c: [f64; 2],
    di: [f64; 2],
    dj: [f64; 2],
    light_ij: Option<bool>,
    noise: f64,
    ratio: f64,
) -> Result<(f64, f64), Fail> {
    // the central part of each square, or of its part nearest the corner when the
    // square leaves the image
    let cell = |a: f64, b: f64| {
        [(0.5, 0.25), (0.3, 0.12)].iter().find_map(|&(at, half)| {
            let e1 = [a * di[0], a * di[1]];
            let e2 = [b * dj[0], b * dj[1]];
            let m = [c[0] + at * (e1[0] + e2[0]), c[1] + at * (e1[1] + e2[1])];
            super::cells::patch_median(g, m, e1, e2, half, 4).map(f64::from)
        })
    };
    let q = [cell(1.0, 1.0), cell(-1.0, -1.0), cell(-1.0, 1.0), cell(1.0, -1.0)];
    let [Some(a0), Some(a1), Some(b0), Some(b1)] = q else {
        return Err(Fail::Border);
    };
    let (ma, mb) = (0.5 * (a0 + a1), 0.5 * (b0 + b1));
    let diff = (ma - mb).abs();
    if diff < 4.0 * noise || (a0 - a1).abs() > ratio * diff || (b0 - b1).abs() > ratio * diff {
        return Err(Fail::NotCorner("the four squares around it are not a chessboard corner"));
    }
    if light_ij.is_some_and(|l| l != (ma > mb)) {
        return Err(Fail::NotCorner("the square colours around the corner are swapped"));
    }
    Ok((ma.max(mb), ma.min(mb)))
}

/// A bright stripe in the window around `c`: the pixels brighter than the light
/// squares by half the contrast (and 8 noise sigmas), see [`stripe_of`].
fn stripe_mask(g: &Gray, c: [f64; 2], r: f64, light: f64, dark: f64, noise: f64) -> HashSet<(i32, i32)> {
    if !(light.is_finite() && dark.is_finite()) {
        return HashSet::new();
    }
    let thr = light + (0.5 * (light - dark)).max(8.0 * noise);
    let mut px = Vec::new();
    window(g, c, r + 1.0, &HashSet::new(), &mut px);
    let bright: Vec<(i32, i32)> = px
        .iter()
        .filter(|q| q[2] > thr)
        .map(|q| ((q[0] + c[0]).round() as i32, (q[1] + c[1]).round() as i32))
        .collect();
    stripe_of(bright, r)
}

/// A stripe over the dark squares: pixels of the window around `c` inside a dark
/// sector (more than 3.5 px from the edges along the lattice directions `di`, `dj`)
/// brighter than the middle of the dark and light levels, see [`stripe_of`]. The dark
/// squares are the quietest part of the window (no grain, no glare reaches half the
/// contrast there), so a stripe no brighter than the light squares shows here.
#[allow(clippy::too_many_arguments)]
fn dark_sector_stripe(
    g: &Gray,
    c: [f64; 2],
    r: f64,
    di: [f64; 2],
    dj: [f64; 2],
    light_ij: Option<bool>,
    light: f64,
    dark: f64,
) -> HashSet<(i32, i32)> {
    let det = cross(di, dj);
    let (Some(light_ij), true) = (light_ij, light.is_finite() && dark.is_finite() && det.abs() > 1e-9) else {
        return HashSet::new();
    };
    let thr = 0.5 * (light + dark);
    let (ni, nj) = (norm(di), norm(dj));
    let mut px = Vec::new();
    window(g, c, r, &HashSet::new(), &mut px);
    let bright: Vec<(i32, i32)> = px
        .iter()
        .filter(|q| {
            // lattice coordinates of the offset, and distances to the two edges
            let a = cross([q[0], q[1]], dj) / det;
            let b = cross(di, [q[0], q[1]]) / det;
            let (to_i_edge, to_j_edge) = ((b * det / ni).abs(), (a * det / nj).abs());
            // the sectors of (+i, +j) and (-i, -j) have the colour of light_ij
            let like_ij = (a > 0.0) == (b > 0.0);
            let in_dark = like_ij != light_ij;
            to_i_edge > 3.5 && to_j_edge > 3.5 && in_dark && q[2] > thr
        })
        .map(|q| ((q[0] + c[0]).round() as i32, (q[1] + c[1]).round() as i32))
        .collect();
    stripe_of(bright, 0.5 * r)
}

/// A stripe seen in the fit's residuals: pixels brighter than the fitted model by 3/4
/// of the contrast (a stripe over the dark squares that is no brighter than the light
/// ones), see [`stripe_of`].
fn residual_stripe(th: &Vec11, px: &[[f64; 4]], r: f64, noise: f64) -> HashSet<(i32, i32)> {
    let thr = (1.5 * th[6].abs()).max(8.0 * noise);
    let md = Model::new(th, 1.0 / r);
    let bright: Vec<(i32, i32)> = px
        .iter()
        .filter(|q| q[2] - md.value(q[0], q[1]).0 > thr)
        .map(|q| ((q[0] + th[0]).round() as i32, (q[1] + th[1]).round() as i32))
        .collect();
    stripe_of(bright, r)
}

/// Size of the largest 8-connected component of a pixel set.
fn largest_component(px: &[(i32, i32)]) -> usize {
    let set: HashSet<(i32, i32)> = px.iter().copied().collect();
    let mut seen: HashSet<(i32, i32)> = HashSet::new();
    let mut best = 0;
    let mut stack = Vec::new();
    for &p in px {
        if !seen.insert(p) {
            continue;
        }
        stack.push(p);
        let mut n = 0;
        while let Some((x, y)) = stack.pop() {
            n += 1;
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let q = (x + dx, y + dy);
                    if set.contains(&q) && seen.insert(q) {
                        stack.push(q);
                    }
                }
            }
        }
        best = best.max(n);
    }
    best
}

/// The pixels grown by one pixel when their largest connected part has at least
/// `max(8, r)` pixels (a stripe crossing the window has about `4 r`; bright grain,
/// a few in small clumps); empty otherwise.
fn stripe_of(px: Vec<(i32, i32)>, r: f64) -> HashSet<(i32, i32)> {
    let mut out = HashSet::new();
    if (largest_component(&px) as f64) < r.max(8.0) {
        return out;
    }
    for (x, y) in px {
        for dy in -1..=1 {
            for dx in -1..=1 {
                out.insert((x + dx, y + dy));
            }
        }
    }
    out
}

/// Measures the corner near `start` with local lattice steps `di`, `dj` (image
/// vectors to the `+i` and `+j` neighbours). `light_ij`: whether the square between the
/// `+i` and `+j` edges is light, when known. `strict`: a site the candidates did not
/// show (grid extension, holes), whose squares must agree closely (0.6, against 1.2 for
/// a grid corner whose links were checked; glare on one square stays below 1).
pub(crate) fn refine(
    g: &Gray,
    start: [f64; 2],
    di: [f64; 2],
    dj: [f64; 2],
    light_ij: Option<bool>,
    strict: bool,
    s: &Settings,
) -> Result<Saddle, Fail> {
    let (li, lj) = (norm(di), norm(dj));
    let area = cross(di, dj).abs();
    if !(li > 1.0 && lj > 1.0 && area > 1.0 && start[0].is_finite() && start[1].is_finite()) {
        return Err(Fail::NotCorner("degenerate local lattice"));
    }
    let d_far = area / li.max(lj);
    let mut r = (0.75 * d_far - 1.5).clamp(2.5, s.max_radius.max(2.5));
    let border = |c: [f64; 2]| {
        let (w, h) = ((g.w - 1) as f64, (g.h - 1) as f64);
        c[0].min(c[1]).min(w - c[0]).min(h - c[1]) - 1.5
    };
    let mut near_border = false;
    let mut shrink = |c: [f64; 2], r: &mut f64| {
        let rb = border(c);
        if rb < *r {
            if rb < 2.5 {
                return Err(Fail::Border);
            }
            *r = rb;
            near_border = true;
        }
        Ok(())
    };
    shrink(start, &mut r)?;
    let ratio = if strict { 0.6 } else { 1.2 };
    let (light, dark) = quadrants(g, start, di, dj, light_ij, s.noise, ratio)?;
    let mask = stripe_mask(g, start, r, light, dark, s.noise);
    let stripe = !mask.is_empty();
    if stripe && !s.keep_stripe {
        return Err(Fail::Stripe);
    }
    let tol = (0.35 * li.min(lj)).max(2.0);
    let c0 = orthogonality_start(g, start, r, &mask).ok_or(Fail::NotCorner("no gradient structure"))?;
    if norm([c0[0] - start[0], c0[1] - start[1]]) > tol {
        return Err(Fail::NotCorner("the saddle point is far from the predicted position"));
    }
    shrink(c0, &mut r)?;
    let on_dark = dark_sector_stripe(g, c0, r, di, dj, light_ij, light, dark);
    let stripe = stripe || !on_dark.is_empty();
    if stripe && !s.keep_stripe {
        return Err(Fail::Stripe);
    }
    let mask: HashSet<(i32, i32)> = mask.union(&on_dark).copied().collect();
    let angles = [di[1].atan2(di[0]), dj[1].atan2(dj[0])];
    let (mut th, mut px, mut h, mut cost, mut wsum) =
        fit(g, c0, angles, r, &mask).ok_or(Fail::NotCorner("the saddle fit failed"))?;
    let more = residual_stripe(&th, &px, r, s.noise);
    let stripe = stripe || !more.is_empty();
    if !more.is_empty() {
        if !s.keep_stripe {
            return Err(Fail::Stripe);
        }
        let all: HashSet<(i32, i32)> = mask.union(&more).copied().collect();
        (th, px, h, cost, wsum) = fit(g, c0, angles, r, &all).ok_or(Fail::Stripe)?;
    }
    validate(&th, start, angles, r, tol, light_ij, s, di, dj)?;
    if worst_sector(&th, &px, r) > 0.25 * 2.0 * th[6].abs() {
        return Err(Fail::NotCorner("one of its four squares does not fit a corner model"));
    }
    let rms = (cost / wsum.max(1.0)).sqrt();
    if rms > 0.25 * 2.0 * th[6].abs() + 2.0 * s.noise {
        return Err(Fail::NotCorner("the image does not fit a corner model"));
    }
    let c = [th[0], th[1]];
    near_border |= border(c) - r < 2.0;
    let dof = (wsum - NP as f64).max(1.0);
    let s2 = cost / dof;
    let sigma_px = h
        .try_inverse()
        .map(|inv| (0.5 * s2 * (inv[(0, 0)] + inv[(1, 1)]).max(0.0)).sqrt())
        .unwrap_or(f64::NAN);
    Ok(Saddle {
        u: c[0],
        v: c[1],
        sigma_px,
        contrast: 2.0 * th[6].abs(),
        near_border,
        stripe,
    })
}

/// Largest absolute mean residual over the four sectors between the fitted edges
/// (pixels more than two blur widths from both edges): about zero at an X-junction,
/// half the contrast where one square is not what the model says (the tip of a
/// square cut by a stripe, an L where the board ends).
fn worst_sector(th: &Vec11, px: &[[f64; 4]], r: f64) -> f64 {
    let (s1a, c1a) = th[2].sin_cos();
    let (s2a, c2a) = th[3].sin_cos();
    let away = (2.0 * th[4].exp() + 0.5).min(0.4 * r);
    let md = Model::new(th, 1.0 / r);
    let mut acc = [[0f64; 2]; 4];
    for q in px {
        let s1 = -s1a * q[0] + c1a * q[1];
        let s2 = -s2a * q[0] + c2a * q[1];
        if s1.abs() < away || s2.abs() < away {
            continue;
        }
        let k = (s1 > 0.0) as usize * 2 + (s2 > 0.0) as usize;
        let (f, _) = md.value(q[0], q[1]);
        acc[k][0] += q[3] * (q[2] - f);
        acc[k][1] += q[3];
    }
    acc.iter()
        .map(|a| if a[1] >= 3.0 { (a[0] / a[1]).abs() } else { f64::INFINITY })
        .fold(0.0, f64::max)
}

/// Checks the fitted model: position, contrast, blur, edge directions, polarity.
#[allow(clippy::too_many_arguments)]
fn validate(
    th: &Vec11,
    start: [f64; 2],
    angles: [f64; 2],
    r: f64,
    tol: f64,
    light_ij: Option<bool>,
    s: &Settings,
    di: [f64; 2],
    dj: [f64; 2],
) -> Result<(), Fail> {
    let c = [th[0], th[1]];
    if norm([c[0] - start[0], c[1] - start[1]]) > tol {
        return Err(Fail::NotCorner("the saddle point is far from the predicted position"));
    }
    let contrast = 2.0 * th[6].abs();
    if contrast < 4.0 * s.noise {
        return Err(Fail::NotCorner("too little contrast for a corner"));
    }
    let blur = th[4].exp();
    if !(0.15..=0.7 * r + 0.5).contains(&blur) {
        return Err(Fail::NotCorner("the corner is too blurred for its window"));
    }
    let lim = 30f64.to_radians();
    if line_angle_diff(th[2], angles[0]) > lim || line_angle_diff(th[3], angles[1]) > lim {
        return Err(Fail::NotCorner("the edges do not follow the grid"));
    }
    if line_angle_diff(th[2], th[3]) < 15f64.to_radians() {
        return Err(Fail::NotCorner("the edges do not follow the grid"));
    }
    if let Some(light) = light_ij {
        // model sign half-way into the square between +i and +j
        let (ui, uj) = (norm(di), norm(dj));
        let d = [0.25 * r * (di[0] / ui + dj[0] / uj), 0.25 * r * (di[1] / ui + dj[1] / uj)];
        let (_, m) = Model::new(th, 1.0 / r).value(d[0], d[1]);
        if (th[6] * m > 0.0) != light {
            return Err(Fail::NotCorner("the square colours around the corner are swapped"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erf_is_accurate() {
        // reference values of erf
        for (x, want) in [(0.0, 0.0), (0.5, 0.5204998778), (1.0, 0.8427007929), (-2.0, -0.9953222650)] {
            let (e, ex) = erf_exp(x);
            assert!((e - want).abs() < 3e-7, "{x}: {e}");
            assert!((ex - (-x * x).exp()).abs() < 1e-15);
        }
    }

    #[test]
    fn model_gradient_matches_finite_differences() {
        let th = Vec11::from_column_slice(&[
            0.3, -0.2, 0.4, 1.9, 0.1, 100.0, 60.0, 3.0, -2.0, 1.0, 0.5,
        ]);
        let inv_r = 1.0 / 6.0;
        for &(x, y) in &[(1.2, 0.7), (-2.0, 1.5), (0.1, -0.3)] {
            let (dx, dy) = (x - th[0], y - th[1]);
            let (_, j) = Model::new(&th, inv_r).eval(dx, dy);
            for k in 0..NP {
                let h = 1e-6;
                let mut tp = th;
                tp[k] += h;
                let mut tm = th;
                tm[k] -= h;
                let fp = Model::new(&tp, inv_r).value(x - tp[0], y - tp[1]).0;
                let fm = Model::new(&tm, inv_r).value(x - tm[0], y - tm[1]).0;
                let fd = (fp - fm) / (2.0 * h);
                assert!((fd - j[k]).abs() < 1e-4 * (1.0 + fd.abs()), "param {k}: {fd} vs {}", j[k]);
            }
        }
    }
}
