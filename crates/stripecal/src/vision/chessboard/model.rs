//! The blurred X-junction model of [`super::refine`] (see there): its value and
//! gradient, the window of pixels it is fitted to, and the normal equations.
//!
//! The passes over a window run on lanes of [`L`] pixels: loops over a lane index
//! that the compiler turns into SIMD instructions (hence the index loops).
#![allow(clippy::needless_range_loop)]

use nalgebra::{SMatrix, SVector};

use super::image::Gray;
use super::lattice::CoordSet;

pub(crate) const NP: usize = 11;
pub(crate) type Mat = SMatrix<f64, NP, NP>;
pub(crate) type Vec11 = SVector<f64, NP>;

const TWO_OVER_SQRT_PI: f64 = std::f64::consts::FRAC_2_SQRT_PI;

/// `exp(y)` for `y <= 0` (below -700 taken as -700), relative error below 3e-10:
/// `y = n ln 2 + r`, `|r| <= ln 2 / 2`, `exp(r)` by its Taylor polynomial of degree 8,
/// `2^n` written into the exponent bits. Branch-free, so that a loop over a lane of
/// pixels compiles to SIMD instructions (`f64::exp` is a call per value).
#[inline(always)]
fn exp_neg(y: f64) -> f64 {
    // 1.5 * 2^52: adding it rounds to an integer, held in the low bits of the sum
    const ROUND: f64 = 6_755_399_441_055_744.0;
    const LN2_HI: f64 = 6.931_471_803_691_238e-1;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    let y = y.max(-700.0);
    let t = y * std::f64::consts::LOG2_E + ROUND;
    let n = t - ROUND;
    let r = (y - n * LN2_HI) - n * LN2_LO;
    let mut p = 1.0 / 40320.0;
    for c in [
        1.0 / 5040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
        1.0,
        1.0,
    ] {
        p = p * r + c;
    }
    // n in [-1010, 0]: the exponent field of 2^n is n + 1023
    let n_bits = t.to_bits().wrapping_sub(ROUND.to_bits());
    p * f64::from_bits(n_bits.wrapping_add(1023) << 52)
}

/// `erf(x)` (Abramowitz & Stegun 7.1.26, |error| < 1.5e-7, odd like `erf`) and
/// `exp(-x^2)` (from [`exp_neg`]), branch-free for the lanes of the passes below.
#[inline(always)]
pub(crate) fn erf_exp(x: f64) -> (f64, f64) {
    let a = x.abs();
    let e = exp_neg(-a * a);
    let t = 1.0 / (1.0 + 0.327_591_1 * a);
    let poly = ((((1.061_405_429 * t - 1.453_152_027) * t + 1.421_413_741) * t - 0.284_496_736)
        * t
        + 0.254_829_592)
        * t;
    ((1.0 - poly * e).copysign(x), e)
}

/// `erf(x)` and `exp(-x^2)` for `x >= 0` to about 1e-15 (the series
/// `erf x = 2/sqrt(pi) exp(-x^2) sum_n 2^n x^(2n+1) / (1 3 5 .. (2n+1))`, all terms
/// positive): the reference of [`erf_exp`]'s test.
#[cfg(test)]
fn erf_series(x: f64) -> (f64, f64) {
    let e = (-x * x).exp();
    let (mut term, mut sum) = (x, x);
    let mut n = 0u32;
    while term > 1e-18 * sum && n < 1000 {
        n += 1;
        term *= 2.0 * x * x / f64::from(2 * n + 1);
        sum += term;
    }
    ((TWO_OVER_SQRT_PI * e * sum).min(1.0), e)
}

/// Window pixels: `(dx, dy, value, weight)` relative to the centre.
pub(crate) fn window(g: &Gray, c: [f64; 2], r: f64, mask: &CoordSet, out: &mut Vec<[f64; 4]>) {
    out.clear();
    let (x0, x1) = (
        (c[0] - r - 0.5).ceil() as i64,
        (c[0] + r + 0.5).floor() as i64,
    );
    let (y0, y1) = (
        (c[1] - r - 0.5).ceil() as i64,
        (c[1] + r + 0.5).floor() as i64,
    );
    // (r - 0.5 - 1e-9)^2: below it, r + 0.5 - d > 1 with margin for rounding
    let inner2 = (r - 0.5 - 1e-9).max(0.0).powi(2);
    for y in y0.max(0)..=y1.min(g.h as i64 - 1) {
        for x in x0.max(0)..=x1.min(g.w as i64 - 1) {
            let (dx, dy) = (x as f64 - c[0], y as f64 - c[1]);
            let d2 = dx * dx + dy * dy;
            // well inside the disc the weight is exactly 1 (no square root needed)
            let w = if d2 < inner2 {
                1.0
            } else {
                (r + 0.5 - d2.sqrt()).clamp(0.0, 1.0)
            };
            if w <= 0.0 {
                continue;
            }
            if !mask.is_empty() {
                let (mx, my) = (
                    (2.0 * c[0] - x as f64).round(),
                    (2.0 * c[1] - y as f64).round(),
                );
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
pub(crate) struct Model {
    th: Vec11,
    s1a: f64,
    c1a: f64,
    s2a: f64,
    c2a: f64,
    k: f64,
    inv_r: f64,
}

impl Model {
    pub fn new(th: &Vec11, inv_r: f64) -> Model {
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
    pub fn value(&self, dx: f64, dy: f64) -> (f64, f64) {
        let th = &self.th;
        let s1 = -self.s1a * dx + self.c1a * dy;
        let s2 = -self.s2a * dx + self.c2a * dy;
        let m = erf_exp(self.k * s1).0 * erf_exp(self.k * s2).0;
        let (ux, uy) = (dx * self.inv_r, dy * self.inv_r);
        (
            th[5] + th[6] * m + (th[7] + th[8] * m) * ux + (th[9] + th[10] * m) * uy,
            m,
        )
    }

    /// Model value and its gradient with respect to the 11 parameters (one pixel: the
    /// reference of [`Model::eval_lanes`], which the passes use).
    #[cfg(test)]
    pub fn eval(&self, dx: f64, dy: f64) -> (f64, Vec11) {
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

/// Pixels per step of the passes below: the model (its `erf`s included), its gradient
/// and the sums run on lanes of this many pixels (arrays the compiler maps to SIMD
/// registers).
const L: usize = 8;
type Lane = [f64; L];

impl Model {
    /// [`Model::eval`] of `L` pixels: the values and the 11 gradients, lane by lane.
    #[inline(always)]
    fn eval_lanes(&self, dx: &Lane, dy: &Lane) -> (Lane, [Lane; NP]) {
        let (th, k, inv_r) = (&self.th, self.k, self.inv_r);
        let (s1a, c1a, s2a, c2a) = (self.s1a, self.c1a, self.s2a, self.c2a);
        let mut s1 = [0.0; L];
        let mut s2 = [0.0; L];
        for l in 0..L {
            s1[l] = -s1a * dx[l] + c1a * dy[l];
            s2[l] = -s2a * dx[l] + c2a * dy[l];
        }
        let (mut e1, mut g1, mut e2, mut g2) = ([0.0; L], [0.0; L], [0.0; L], [0.0; L]);
        for l in 0..L {
            (e1[l], g1[l]) = erf_exp(k * s1[l]);
            (e2[l], g2[l]) = erf_exp(k * s2[l]);
        }
        let mut f = [0.0; L];
        let mut j = [[0.0; L]; NP];
        for l in 0..L {
            let (g1, g2) = (TWO_OVER_SQRT_PI * g1[l], TWO_OVER_SQRT_PI * g2[l]);
            let m = e1[l] * e2[l];
            let (ux, uy) = (dx[l] * inv_r, dy[l] * inv_r);
            f[l] = th[5] + th[6] * m + (th[7] + th[8] * m) * ux + (th[9] + th[10] * m) * uy;
            let a = th[6] + th[8] * ux + th[10] * uy;
            let dm_ds1 = k * g1 * e2[l];
            let dm_ds2 = k * g2 * e1[l];
            j[0][l] = a * (dm_ds1 * s1a + dm_ds2 * s2a) - (th[7] + th[8] * m) * inv_r;
            j[1][l] = a * (-dm_ds1 * c1a - dm_ds2 * c2a) - (th[9] + th[10] * m) * inv_r;
            j[2][l] = a * dm_ds1 * -(c1a * dx[l] + s1a * dy[l]);
            j[3][l] = a * dm_ds2 * -(c2a * dx[l] + s2a * dy[l]);
            j[4][l] = -a * (s1[l] * dm_ds1 + s2[l] * dm_ds2);
            j[5][l] = 1.0;
            j[6][l] = m;
            j[7][l] = ux;
            j[8][l] = m * ux;
            j[9][l] = uy;
            j[10][l] = m * uy;
        }
        (f, j)
    }

    /// [`Model::value`] of `L` pixels: the values and `M`.
    #[inline(always)]
    fn value_lanes(&self, dx: &Lane, dy: &Lane) -> (Lane, Lane) {
        let (th, k, inv_r) = (&self.th, self.k, self.inv_r);
        let mut s1 = [0.0; L];
        let mut s2 = [0.0; L];
        for l in 0..L {
            s1[l] = k * (-self.s1a * dx[l] + self.c1a * dy[l]);
            s2[l] = k * (-self.s2a * dx[l] + self.c2a * dy[l]);
        }
        let mut m = [0.0; L];
        for l in 0..L {
            m[l] = erf_exp(s1[l]).0 * erf_exp(s2[l]).0;
        }
        let mut f = [0.0; L];
        for l in 0..L {
            let (ux, uy) = (dx[l] * inv_r, dy[l] * inv_r);
            f[l] =
                th[5] + th[6] * m[l] + (th[7] + th[8] * m[l]) * ux + (th[9] + th[10] * m[l]) * uy;
        }
        (f, m)
    }
}

/// The window's pixels `L` at a time (offsets shifted by `-shift`, values, weights),
/// the last step padded with pixels of weight 0 (they add nothing to any sum).
fn lanes(px: &[[f64; 4]], shift: [f64; 2]) -> impl Iterator<Item = [Lane; 4]> + '_ {
    px.chunks(L).map(move |c| {
        let mut q = [[0.0; L]; 4];
        for (l, p) in c.iter().enumerate() {
            q[0][l] = p[0] - shift[0];
            q[1][l] = p[1] - shift[1];
            q[2][l] = p[2];
            q[3][l] = p[3];
        }
        q
    })
}

/// Half a lane: the running sums keep four partial sums each (one register of AVX2, two
/// of SSE2), added up at the end.
type Half = [f64; L / 2];

/// Adds a lane's values to the partial sums `s` (its two halves added first).
#[inline(always)]
fn accumulate(s: &mut Half, p: &Lane) {
    for l in 0..L / 2 {
        s[l] += p[l] + p[l + L / 2];
    }
}

/// The total of the partial sums.
#[inline(always)]
fn total(h: &Half) -> f64 {
    (h[0] + h[2]) + (h[1] + h[3])
}

/// Running sums of the normal equations, each as four partial sums.
struct Sums {
    /// Upper triangle of `J^T W J`, row by row.
    tri: [Half; NP * (NP + 1) / 2],
    b: [Half; NP],
    cost: Half,
    wsum: Half,
}

impl Sums {
    fn new() -> Sums {
        Sums {
            tri: [[0.0; L / 2]; NP * (NP + 1) / 2],
            b: [[0.0; L / 2]; NP],
            cost: [0.0; L / 2],
            wsum: [0.0; L / 2],
        }
    }

    /// `L` pixels of weights `w`, residuals `r`, model gradients `j`.
    #[inline(always)]
    fn add(&mut self, w: &Lane, r: &Lane, j: &[Lane; NP]) {
        let mut wj = [[0.0; L]; NP];
        for a in 0..NP {
            for l in 0..L {
                wj[a][l] = w[l] * j[a][l];
            }
        }
        let mut k = 0;
        for a in 0..NP {
            for c in a..NP {
                let mut p = [0.0; L];
                for l in 0..L {
                    p[l] = wj[a][l] * j[c][l];
                }
                accumulate(&mut self.tri[k], &p);
                k += 1;
            }
            let mut p = [0.0; L];
            for l in 0..L {
                p[l] = wj[a][l] * r[l];
            }
            accumulate(&mut self.b[a], &p);
        }
        let (mut pc, mut pw) = ([0.0; L], [0.0; L]);
        for l in 0..L {
            pc[l] = w[l] * r[l] * r[l];
            pw[l] = w[l];
        }
        accumulate(&mut self.cost, &pc);
        accumulate(&mut self.wsum, &pw);
    }

    fn finish(self) -> (Mat, Vec11, f64, f64) {
        let mut h = Mat::zeros();
        let mut k = 0;
        for a in 0..NP {
            for c in a..NP {
                let t = total(&self.tri[k]);
                h[(a, c)] = t;
                h[(c, a)] = t;
                k += 1;
            }
        }
        let b = Vec11::from_fn(|a, _| total(&self.b[a]));
        (h, b, total(&self.cost), total(&self.wsum))
    }
}

/// Normal equations of the window: `(J^T W J, J^T W r, cost, weight sum)`.
pub(crate) fn normal(th: &Vec11, px: &[[f64; 4]], inv_r: f64) -> (Mat, Vec11, f64, f64) {
    #[cfg(target_arch = "x86_64")]
    if crate::vision::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
        // calling a `#[target_feature(enable = "avx2")]` function.
        return unsafe { normal_avx2(th, px, inv_r) };
    }
    normal_lanes(th, px, inv_r)
}

/// [`normal_lanes`] compiled for AVX2 (four `f64` lanes per register instead of two;
/// no fused multiply-adds, so the results are the same bit for bit).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn normal_avx2(th: &Vec11, px: &[[f64; 4]], inv_r: f64) -> (Mat, Vec11, f64, f64) {
    normal_lanes(th, px, inv_r)
}

/// [`normal`] on any CPU.
#[inline(always)]
fn normal_lanes(th: &Vec11, px: &[[f64; 4]], inv_r: f64) -> (Mat, Vec11, f64, f64) {
    let mut s = Sums::new();
    let md = Model::new(th, inv_r);
    for [dx, dy, v, w] in lanes(px, [0.0, 0.0]) {
        let (f, j) = md.eval_lanes(&dx, &dy);
        let mut r = [0.0; L];
        for l in 0..L {
            r[l] = v[l] - f[l];
        }
        s.add(&w, &r, &j);
    }
    s.finish()
}

/// A Levenberg-Marquardt trial: [`normal`] of `th` over `new` (the window centred on
/// `th`'s centre) and the cost of `th` over `old` (the window of the previous estimate,
/// centred on `c_old`, every offset shifted by `c - c_old`), the trial's test.
pub(crate) fn normal_trial(
    th: &Vec11,
    old: &[[f64; 4]],
    c_old: [f64; 2],
    new: &[[f64; 4]],
    inv_r: f64,
) -> ((Mat, Vec11, f64, f64), f64) {
    let shift = [th[0] - c_old[0], th[1] - c_old[1]];
    (normal(th, new, inv_r), cost_of(th, old, inv_r, shift))
}

/// The model's value and `M` ([`Model::value`]) at every pixel of the window `px`, into
/// `out` (cleared first; sized here).
pub(crate) fn values(th: &Vec11, px: &[[f64; 4]], inv_r: f64, out: &mut Vec<[f64; 2]>) {
    #[cfg(target_arch = "x86_64")]
    if crate::vision::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
        // calling a `#[target_feature(enable = "avx2")]` function.
        return unsafe { values_avx2(th, px, inv_r, out) };
    }
    values_lanes(th, px, inv_r, out)
}

/// [`values_lanes`] compiled for AVX2 (the same results bit for bit, see [`normal_avx2`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn values_avx2(th: &Vec11, px: &[[f64; 4]], inv_r: f64, out: &mut Vec<[f64; 2]>) {
    values_lanes(th, px, inv_r, out)
}

/// [`values`] on any CPU.
#[inline(always)]
fn values_lanes(th: &Vec11, px: &[[f64; 4]], inv_r: f64, out: &mut Vec<[f64; 2]>) {
    let md = Model::new(th, inv_r);
    out.clear();
    // the last lane's padding is written too, then cut off
    out.reserve(px.len() + L);
    for [dx, dy, _, _] in lanes(px, [0.0, 0.0]) {
        let (f, m) = md.value_lanes(&dx, &dy);
        out.extend((0..L).map(|l| [f[l], m[l]]));
    }
    out.truncate(px.len());
}

/// The linear block of [`normal`] alone (rows and columns 5..11: contrast and
/// illumination), for the start of a fit: the same sums, without the derivatives of
/// the edges.
pub(crate) fn normal_linear(
    th: &Vec11,
    px: &[[f64; 4]],
    inv_r: f64,
) -> (SMatrix<f64, 6, 6>, SVector<f64, 6>) {
    let mut tri = [0f64; 21];
    let mut b = SVector::<f64, 6>::zeros();
    let mut fm = Vec::new();
    values(th, px, inv_r, &mut fm);
    for (q, &[f, m]) in px.iter().zip(&fm) {
        let r = q[2] - f;
        let (ux, uy) = (q[0] * inv_r, q[1] * inv_r);
        let j = [1.0, m, ux, m * ux, uy, m * uy];
        let mut k = 0;
        for (a, &ja) in j.iter().enumerate() {
            let wa = q[3] * ja;
            for &jc in &j[a..] {
                tri[k] += wa * jc;
                k += 1;
            }
            b[a] += q[3] * r * ja;
        }
    }
    let mut h = SMatrix::<f64, 6, 6>::zeros();
    let mut k = 0;
    for a in 0..6 {
        for c in a..6 {
            h[(a, c)] = tri[k];
            h[(c, a)] = tri[k];
            k += 1;
        }
    }
    (h, b)
}

/// The weighted squared residual of the window `px` for `th`, with every offset
/// shifted by `-shift` (the window re-centred on a trial centre).
pub(crate) fn cost_of(th: &Vec11, px: &[[f64; 4]], inv_r: f64, shift: [f64; 2]) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if crate::vision::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
        // calling a `#[target_feature(enable = "avx2")]` function.
        return unsafe { cost_avx2(th, px, inv_r, shift) };
    }
    cost_lanes(th, px, inv_r, shift)
}

/// [`cost_lanes`] compiled for AVX2 (the same results bit for bit, see [`normal_avx2`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn cost_avx2(th: &Vec11, px: &[[f64; 4]], inv_r: f64, shift: [f64; 2]) -> f64 {
    cost_lanes(th, px, inv_r, shift)
}

/// [`cost_of`] on any CPU.
#[inline(always)]
fn cost_lanes(th: &Vec11, px: &[[f64; 4]], inv_r: f64, shift: [f64; 2]) -> f64 {
    let md = Model::new(th, inv_r);
    let mut cost = [0.0; L / 2];
    for [dx, dy, v, w] in lanes(px, shift) {
        let (f, _) = md.value_lanes(&dx, &dy);
        let mut p = [0.0; L];
        for l in 0..L {
            p[l] = w[l] * (v[l] - f[l]) * (v[l] - f[l]);
        }
        accumulate(&mut cost, &p);
    }
    total(&cost)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erf_is_accurate() {
        let mut worst = (0f64, 0f64);
        for k in -9000..=9000 {
            let x = k as f64 * 0.000_873_1;
            let (e, g) = erf_exp(x);
            let (er, gr) = erf_series(x.abs());
            let er = if x < 0.0 { -er } else { er };
            worst = (
                worst.0.max((e - er).abs()),
                worst.1.max((g - gr).abs() / gr),
            );
        }
        assert!(worst.0 < 1.5e-7 && worst.1 < 3e-10, "{worst:?}");
        for (x, want) in [(0.5, 0.5204998778130465), (1.0, 0.8427007929497149)] {
            assert!((erf_series(x).0 - want).abs() < 1e-15);
        }
        // far out, and not a number
        assert_eq!(erf_exp(40.0), (1.0, exp_neg(-700.0)));
        assert_eq!(erf_exp(-1e300).0, -1.0);
        assert!(erf_exp(f64::NAN).0.is_nan());
        assert!((exp_neg(-700.0) / (-700f64).exp() - 1.0).abs() < 3e-10);
    }

    /// The lane passes against plain per-pixel sums (a window of 113 pixels: the last
    /// lane padded), and the AVX2 build of them against the portable one bit for bit.
    #[test]
    fn lane_passes_match_per_pixel_sums() {
        let th =
            Vec11::from_column_slice(&[0.2, -0.1, 0.5, 2.0, -0.3, 90.0, 70.0, 2.0, -3.0, 1.5, 0.7]);
        let inv_r = 1.0 / 6.0;
        let px: Vec<[f64; 4]> = (-6..=6)
            .flat_map(|y| (-6..=6).map(move |x| (x, y)))
            .filter(|&(x, y)| x * x + y * y <= 36)
            .map(|(x, y)| {
                let (dx, dy) = (x as f64 - 0.3, y as f64 + 0.2);
                let v =
                    100.0 + 60.0 * (0.37 * dx - 0.61 * dy).tanh() + (x * 7 + y * 3) as f64 % 5.0;
                [dx, dy, v, if x * x + y * y > 30 { 0.5 } else { 1.0 }]
            })
            .collect();
        assert_eq!(px.len() % L, 113 % L);
        let md = Model::new(&th, inv_r);
        let (mut h, mut b, mut cost, mut wsum) = (Mat::zeros(), Vec11::zeros(), 0.0, 0.0);
        let mut cost_s = 0.0;
        for q in &px {
            let (f, j) = md.eval(q[0], q[1]);
            let r = q[2] - f;
            h += q[3] * j * j.transpose();
            b += q[3] * r * j;
            cost += q[3] * r * r;
            wsum += q[3];
            let fs = md.value(q[0] - 0.25, q[1] + 0.125).0;
            cost_s += q[3] * (q[2] - fs).powi(2);
        }
        let (hl, bl, cl, wl) = normal(&th, &px, inv_r);
        assert!((hl - h).norm() <= 1e-12 * h.norm() && (bl - b).norm() <= 1e-12 * b.norm());
        assert!((cl - cost).abs() <= 1e-12 * cost && (wl - wsum).abs() <= 1e-12 * wsum);
        let cs = cost_of(&th, &px, inv_r, [0.25, -0.125]);
        assert!((cs - cost_s).abs() <= 1e-12 * cost_s, "{cs} {cost_s}");
        // the dispatched build (AVX2 where the CPU has it) and the portable one agree
        // bit for bit (no fused multiply-adds)
        let (hp, bp, cp, wp) = normal_lanes(&th, &px, inv_r);
        assert!(hp == hl && bp == bl && cp == cl && wp == wl);
        assert_eq!(cost_lanes(&th, &px, inv_r, [0.25, -0.125]), cs);
        // the values of every pixel: those of the per-pixel model, in both builds
        let (mut v, mut vp) = (Vec::new(), Vec::new());
        values(&th, &px, inv_r, &mut v);
        values_lanes(&th, &px, inv_r, &mut vp);
        assert!(v.len() == px.len() && v == vp);
        for (q, fm) in px.iter().zip(&v) {
            let (f, m) = md.value(q[0], q[1]);
            assert!((fm[0] - f).abs() <= 1e-12 * f.abs() && (fm[1] - m).abs() <= 1e-15);
        }
    }

    #[test]
    fn model_gradient_matches_finite_differences() {
        let th =
            Vec11::from_column_slice(&[0.3, -0.2, 0.4, 1.9, 0.1, 100.0, 60.0, 3.0, -2.0, 1.0, 0.5]);
        let inv_r = 1.0 / 6.0;
        for &(x, y) in &[(1.2, 0.7), (-2.0, 1.5), (0.1, -0.3)] {
            let (dx, dy) = (x - th[0], y - th[1]);
            let (f, j) = Model::new(&th, inv_r).eval(dx, dy);
            // the lanes give the same (the point in lane 5, others elsewhere)
            let md = Model::new(&th, inv_r);
            let mut lx: Lane = std::array::from_fn(|l| l as f64 - 3.0);
            let mut ly: Lane = std::array::from_fn(|l| 0.5 * l as f64 - 1.0);
            (lx[5], ly[5]) = (dx, dy);
            let ((fl, jl), (vl, _)) = (md.eval_lanes(&lx, &ly), md.value_lanes(&lx, &ly));
            assert!((fl[5] - f).abs() < 1e-12 && (vl[5] - f).abs() < 1e-12);
            assert!((0..NP).all(|k| (jl[k][5] - j[k]).abs() < 1e-12));
            for k in 0..NP {
                let h = 1e-6;
                let mut tp = th;
                tp[k] += h;
                let mut tm = th;
                tm[k] -= h;
                let fp = Model::new(&tp, inv_r).value(x - tp[0], y - tp[1]).0;
                let fm = Model::new(&tm, inv_r).value(x - tm[0], y - tm[1]).0;
                let fd = (fp - fm) / (2.0 * h);
                assert!(
                    (fd - j[k]).abs() < 1e-4 * (1.0 + fd.abs()),
                    "param {k}: {fd} vs {}",
                    j[k]
                );
            }
        }
    }
}
