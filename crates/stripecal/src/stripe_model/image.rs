//! The modelled profile in the image: how densely the sheet offsets are sampled
//! ([`sheet_offsets`], [`sample_spacing_px`]), the neighbouring scan lines the blur mixes
//! in ([`sub_lines`]), the pixel kernel that spreads each sample over the scan line's
//! pixels, and what the extractor measures on the result ([`extractor_response`],
//! [`scan_line_values`]).

use crate::vision::stripe::{profile_centre, StripeOptions};

use super::profile::{PointProfile, GH5};
use super::HALF_SAMPLES;

/// The sheet offsets sampled on each side of the plane: `(M, dt)`, `t_k = k dt`,
/// `k = -M..=M` over `+-4 sigma`, at least [`HALF_SAMPLES`], and more where they would
/// lie more than [`sample_spacing_px`] apart in the image (`|da/dt| = g` px / mm).
pub(crate) fn sheet_offsets(sigma: f64, g: f64, psf: f64) -> (usize, f64) {
    let m = ((4.0 * sigma * g / sample_spacing_px(psf)).ceil() as usize).clamp(HALF_SAMPLES, 400);
    (m, 4.0 * sigma / m as f64)
}

/// The largest image spacing of the sheet-offset samples (px) for a PSF of sigma `psf`
/// px: the samples, each spread with the pixel kernel `K` (the pixel box convolved with
/// the PSF's Gaussian, sigma `s = sqrt(psf^2 + 1/12)`), sum to the profile's integral
/// over the sheet but for aliases of relative size `|K^(1 / h)| <= exp(-2 pi^2 psf^2 /
/// h^2)` at spacing `h` (Poisson summation; the box's `sinc` only lowers it). The
/// spacing is the one where that bound is 1e-6 (`h = 1.196 psf`; 0.84 px for the twin's
/// 0.7 px PSF), at least `0.5 s` (the spacing before this bound, the floor) below
/// 0.13 px, where a sharper kernel needs denser samples than the bound alone gives (the
/// box's edges). On the twin ball (hp3-paper, seed 1) the bound itself instead of a cap
/// at `0.75 s` (a third fewer samples) moved the corrected diameter by +3.1e-7 mm (its
/// standard uncertainty 4.2e-4 mm), the centre by at most 1.6e-7 mm and the sheet sigma
/// by +5.4e-7 mm; the cap at `0.75 s` instead of `0.5 s` had moved them by 1.9e-7 and
/// 8e-8 mm.
pub(crate) fn sample_spacing_px(psf: f64) -> f64 {
    let s = (psf * psf + 1.0 / 12.0).sqrt();
    // exp(-2 pi^2 psf^2 / h^2) = 1e-6: h = pi psf sqrt(2 / ln 1e6).
    let alias = std::f64::consts::PI * psf * (2.0 / 1e6f64.ln()).sqrt();
    alias.max(0.5 * s)
}

/// The neighbouring scan lines (offsets px, weights summing to 1) the across-line blur
/// mixes in: the pixel box convolved with the PSF's Gaussian (`psf` px). Where the stripe
/// shifts little between them (`|slope| sqrt(psf^2 + 1/12)` below half the profile's
/// width) 5-point Gauss-Hermite with the kernel's variance; otherwise a uniform grid of
/// the exact kernel, fine enough that the stripe moves by at most a quarter of its
/// width (`width0` the sheet's part, px) from one line to the next.
pub(crate) fn sub_lines(psf: f64, width0: f64, slope: f64, out: &mut Vec<(f64, f64)>) {
    out.clear();
    let sl = (psf * psf + 1.0 / 12.0).sqrt();
    let w = (width0 * width0 + sl * sl).sqrt();
    let shift = slope.abs();
    if shift * sl <= 0.5 * w {
        out.extend(GH5.iter().map(|&(x, om)| (x * sl, om)));
        return;
    }
    let reach = 0.5 + 4.0 * psf;
    let n_side = ((reach * shift / (0.25 * w)).ceil() as usize).clamp(2, 64);
    let h = reach / n_side as f64;
    let inv = if psf > 1e-6 {
        1.0 / (std::f64::consts::SQRT_2 * psf)
    } else {
        0.0
    };
    let mut sum = 0.0;
    for j in 0..=2 * n_side {
        let x = -reach + j as f64 * h;
        let k = if inv > 0.0 {
            0.5 * (erf((x + 0.5) * inv) - erf((x - 0.5) * inv))
        } else {
            // The box alone: the cell's overlap with [-1/2, 1/2].
            ((x + 0.5 * h).min(0.5) - (x - 0.5 * h).max(-0.5)).max(0.0) / h
        };
        if k > 0.0 {
            out.push((x, k));
            sum += k;
        }
    }
    for o in out.iter_mut() {
        o.1 /= sum;
    }
}

/// `erf` (Abramowitz & Stegun 7.1.26, |error| < 1.5e-7).
#[inline]
pub(crate) fn erf(x: f64) -> f64 {
    let a = x.abs();
    if a > 6.0 {
        return x.signum();
    }
    let t = 1.0 / (1.0 + 0.3275911 * a);
    let poly = ((((1.061405429 * t - 1.453152027) * t + 1.421413741) * t - 0.284496736) * t
        + 0.254829592)
        * t;
    let y = 1.0 - poly * (-a * a).exp();
    if x < 0.0 {
        -y
    } else {
        y
    }
}

/// `x.floor()` without the library call the baseline x86-64 target makes of it (no
/// SSE4.1 rounding instruction): the same value for every finite `x` (`-0.0` aside, which
/// gives `0.0`; every use here adds it to or compares it with another number).
#[inline]
pub(crate) fn floor(x: f64) -> f64 {
    if x.is_nan() || x.abs() >= 4.0e15 {
        return x.floor();
    }
    let t = x as i64 as f64;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

/// What the extractor measures on a modelled profile: `(centre - a0, width, peak)`
/// (px, px, the model's radiance units).
pub(crate) fn extractor_response(
    prof: &PointProfile,
    psf_sigma_px: f64,
    stripe: &StripeOptions,
    buf: &mut Vec<f64>,
) -> Option<(f64, f64, f64)> {
    let x0 = scan_line_values(prof, psf_sigma_px, stripe, buf)?;
    let (c, width, peak) = profile_centre(buf, stripe)?;
    Some((c + x0 - prof.a0, width as f64, peak))
}

/// The modelled profile's pixel values on its scan line into `buf` (pixel `k` at the
/// along-line coordinate `x0 + k`, returned): each sample's weight spread over the pixel
/// box convolved with the PSF, with room for the extractor's window and flanks either
/// side. `None` when the profile is empty or implausibly long.
pub(crate) fn scan_line_values(
    prof: &PointProfile,
    psf_sigma_px: f64,
    stripe: &StripeOptions,
    buf: &mut Vec<f64>,
) -> Option<f64> {
    let sb = psf_sigma_px;
    let var = sb * sb;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let wmax = prof.samples.iter().map(|s| s.1).fold(0.0, f64::max);
    if wmax.is_nan() || wmax <= 0.0 {
        return None;
    }
    let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
    for &(a, w) in &prof.samples {
        if w > 1e-6 * wmax {
            lo = lo.min(a);
            hi = hi.max(a);
            s0 += w;
            s1 += w * a;
            s2 += w * a * a;
        }
    }
    let mean = s1 / s0;
    let sd = (s2 / s0 - mean * mean).max(0.0).sqrt();
    let fwhm = 2.3548 * (sd * sd + var + 1.0 / 12.0).sqrt();
    let pad = (stripe.window_fwhm as f64 * fwhm).max(1.5)
        + 2.0 * fwhm
        + (stripe.flank_px + stripe.ridge_px) as f64
        + 6.0
        + 4.0 * sb;
    let x0 = (lo - pad).floor();
    let x1 = (hi + pad).ceil();
    let len = (x1 - x0) as usize + 1;
    if len > 4096 {
        return None;
    }
    buf.clear();
    buf.resize(len, 0.0);
    // Only pixels within reach of the kernel.
    let reach = 0.5 + 6.0 * sb + 1.0;
    KERNEL.with(|cell| {
        let mut cached = cell.borrow_mut();
        if cached.as_ref().is_none_or(|k| k.sigma_px != sb) {
            *cached = Some(PixelKernel::new(sb, reach + 1.0));
        }
        let kernel = cached.as_ref().expect("set above");
        for &(a, w) in &prof.samples {
            if w <= 0.0 {
                continue;
            }
            let k0 = (floor(a - reach - x0).max(0.0)) as usize;
            let k1 = ((-floor(-(a + reach - x0))) as usize).min(len - 1);
            kernel.spread(x0 + k0 as f64 - a, w, &mut buf[k0..=k1]);
        }
    });
    Some(x0)
}

thread_local! {
    /// The last PSF's pixel kernel on this thread (the profiles of one correction share
    /// their PSF; a fit that varies it rebuilds the table, ~3,000 `erf`s, per value).
    static KERNEL: std::cell::RefCell<Option<PixelKernel>> = const { std::cell::RefCell::new(None) };
}

/// The pixel box convolved with the PSF's Gaussian (sigma `b` px), `K(s) = (erf((s + 1/2)
/// / (sqrt 2 b)) - erf((s - 1/2) / (sqrt 2 b))) / 2`, tabulated with its derivative every
/// [`PixelKernel::STEP`] px over `|s| <= reach` and read by cubic Hermite interpolation
/// (error below `1e-8`, under the 1.5e-7 of [`erf`] itself); the direct formula outside
/// the table and for PSFs under [`PixelKernel::MIN_TABULATED_PX`], whose edges are too
/// steep for the step.
struct PixelKernel {
    sigma_px: f64,
    inv: f64,
    reach: f64,
    /// `(K, K')` at `-reach + i STEP`.
    table: Vec<(f64, f64)>,
}

impl PixelKernel {
    const STEP: f64 = 1.0 / 128.0;
    const MIN_TABULATED_PX: f64 = 0.2;

    fn new(sigma_px: f64, reach: f64) -> PixelKernel {
        let inv = if sigma_px > 1e-6 {
            1.0 / (std::f64::consts::SQRT_2 * sigma_px)
        } else {
            0.0
        };
        let n = (2.0 * reach / Self::STEP).ceil() as usize + 1;
        let table = if sigma_px >= Self::MIN_TABULATED_PX {
            let dk = inv / std::f64::consts::PI.sqrt();
            (0..n)
                .map(|i| {
                    let s = -reach + i as f64 * Self::STEP;
                    let (a, b) = ((s + 0.5) * inv, (s - 0.5) * inv);
                    (
                        0.5 * (erf(a) - erf(b)),
                        dk * ((-a * a).exp() - (-b * b).exp()),
                    )
                })
                .collect()
        } else {
            Vec::new()
        };
        PixelKernel {
            sigma_px,
            inv,
            reach,
            table,
        }
    }

    /// `out[j] += w K(s0 + j)`: the pixels share the phase of `s0` within the table's
    /// step, so the interpolation's weights are computed once.
    #[inline]
    fn spread(&self, s0: f64, w: f64, out: &mut [f64]) {
        let per_px = (1.0 / Self::STEP) as usize;
        let x = (s0 + self.reach) / Self::STEP;
        let i = floor(x);
        let last = (i as usize).saturating_add(per_px * out.len().saturating_sub(1));
        if self.table.is_empty() || i < 0.0 || last + 1 >= self.table.len() {
            for (j, v) in out.iter_mut().enumerate() {
                *v += w * self.at(s0 + j as f64);
            }
            return;
        }
        let t = x - i;
        let (t2, t3) = (t * t, t * t * t);
        let h = Self::STEP * w;
        let (c0, c1) = ((2.0 * t3 - 3.0 * t2 + 1.0) * w, (t3 - 2.0 * t2 + t) * h);
        let (c2, c3) = ((-2.0 * t3 + 3.0 * t2) * w, (t3 - t2) * h);
        for (j, v) in out.iter_mut().enumerate() {
            let i = i as usize + j * per_px;
            let ((y0, d0), (y1, d1)) = (self.table[i], self.table[i + 1]);
            *v += c0 * y0 + c1 * d0 + c2 * y1 + c3 * d1;
        }
    }

    /// `K(s)`; for a PSF of zero width the pixel box alone.
    #[inline]
    fn at(&self, s: f64) -> f64 {
        if self.inv <= 0.0 {
            return if s.abs() < 0.5 { 1.0 } else { 0.0 };
        }
        let x = (s + self.reach) / Self::STEP;
        let i = floor(x);
        if !(i >= 0.0 && (i as usize) + 1 < self.table.len()) {
            return 0.5 * (erf((s + 0.5) * self.inv) - erf((s - 0.5) * self.inv));
        }
        let (t, i) = (x - i, i as usize);
        let ((y0, d0), (y1, d1)) = (self.table[i], self.table[i + 1]);
        let (t2, t3) = (t * t, t * t * t);
        let h = Self::STEP;
        (2.0 * t3 - 3.0 * t2 + 1.0) * y0
            + (t3 - 2.0 * t2 + t) * h * d0
            + (-2.0 * t3 + 3.0 * t2) * y1
            + (t3 - t2) * h * d1
    }
}

#[cfg(test)]
mod kernel_tests {
    use super::{erf, PixelKernel};

    /// The table reads the direct formula within 1e-8 over and beyond its range.
    #[test]
    fn the_tabulated_pixel_kernel_reads_the_direct_formula() {
        for sb in [0.05, 0.3, 0.7, 1.5, 3.0] {
            let reach = 2.5 + 6.0 * sb;
            let k = PixelKernel::new(sb, reach);
            let inv = 1.0 / (std::f64::consts::SQRT_2 * sb);
            let mut worst: f64 = 0.0;
            for i in 0..20_000 {
                let s = -reach - 1.0 + i as f64 * (2.0 * reach + 2.0) / 20_000.0;
                let direct = 0.5 * (erf((s + 0.5) * inv) - erf((s - 0.5) * inv));
                worst = worst.max((k.at(s) - direct).abs());
            }
            assert!(worst < 1e-8, "PSF {sb} px: {worst:e}");
            for s0 in [-reach - 0.3, -reach + 0.37, -1.5, 0.123] {
                let mut out = vec![0.0; 7];
                k.spread(s0, 2.0, &mut out);
                for (j, v) in out.iter().enumerate() {
                    let direct = 2.0 * k.at(s0 + j as f64);
                    assert!((v - direct).abs() < 1e-12, "spread at {s0} + {j}");
                }
            }
        }
        let boxed = PixelKernel::new(0.0, 2.0);
        assert_eq!((boxed.at(0.49), boxed.at(0.51)), (1.0, 0.0));
    }
}
