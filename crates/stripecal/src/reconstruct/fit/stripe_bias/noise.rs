//! The model's response to image noise (a diagnostic): what the extractor's mean centre
//! does when white Gaussian noise is added to each point's modelled scan line.
//!
//! The curved-surface model ([`super`]) is noise-free. The windowed centroid is not
//! linear in the pixel values (the half-maximum width sets the window, the peak pixel
//! is the largest of noisy values, the window's ends move), so on a skewed profile the
//! noise has a mean effect too. Here each point's modelled profile is scaled to the
//! point's measured peak height, a flat background of `8 noise` is added (so that no
//! pixel is clipped at zero) and the extractor runs on `pairs` antithetic pairs
//! (`+e`, `-e`) of noisy copies: the mean centre minus the noise-free centre, px along
//! the scan line. Antithetic pairs cancel the response's odd (linear) part exactly, so
//! what is left is its even part, the bias, at a fraction of the draws.

use nalgebra::Vector3;

use crate::error::Result;
use crate::numerics::rng::SplitMix64;
use crate::vision::stripe::profile_centre;

use super::diagnostics::{per_modelled_point, ModelInputs};
use crate::stripe_model::image::scan_line_values;

/// The noise the model's profiles are drawn with: white Gaussian noise of `gray`
/// (standard deviation, in the units of [`ScanPoints::intensity`]) over `pairs`
/// antithetic pairs seeded by `seed`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct NoiseDraws {
    pub gray: f64,
    pub pairs: usize,
    pub seed: u64,
}

/// The model's mean noise-induced centre shift per point (px along the scan line), for
/// the noise `draws`; `None` where the model fails or the extractor rejects every noisy
/// copy. The scan, the sphere and the sigmas as
/// [`super::diagnostics::predicted_bias_px`].
pub(crate) fn predicted_noise_shift_px(
    inputs: &ModelInputs<'_>,
    sphere: (&Vector3<f64>, f64),
    (sigma, psf): (f64, f64),
    draws: NoiseDraws,
) -> Result<Vec<Option<NoiseShift>>> {
    let NoiseDraws {
        gray: noise_gray,
        pairs,
        seed,
    } = draws;
    let points = inputs.points;
    per_modelled_point(
        inputs,
        sphere,
        (sigma, psf),
        |rig, i, prof, (buf, noisy): &mut (Vec<f64>, Vec<f64>)| {
            scan_line_values(prof, psf, rig.stripe, buf)?;
            let (_, _, peak) = profile_centre(buf, rig.stripe)?;
            let measured = points.intensity.get(i).copied().unwrap_or(0.0) as f64;
            if !(measured > 0.0 && peak > 0.0) {
                return None;
            }
            // Model units per gray level of the image.
            let sd = noise_gray * peak / measured;
            let floor = 8.0 * sd;
            buf.iter_mut().for_each(|v| *v += floor);
            let (c0, _, _) = profile_centre(buf, rig.stripe)?;
            let mut rng = SplitMix64(seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let mut d: Vec<f64> = Vec::with_capacity(2 * pairs);
            for _ in 0..pairs {
                let e: Vec<f64> = buf.iter().map(|_| sd * rng.normal()).collect();
                for sign in [1.0, -1.0] {
                    noisy.clear();
                    noisy.extend(buf.iter().zip(&e).map(|(v, e)| v + sign * e));
                    if let Some((c1, _, _)) = profile_centre(noisy, rig.stripe) {
                        d.push(c1 - c0);
                    }
                }
            }
            NoiseShift::of(&mut d)
        },
    )
}

/// A point's centre shifts under noise, px: their mean, median, and their mean within
/// three robust sigmas (`1.4826` median absolute deviations) of the median, as a robust
/// fit that trims its residuals keeps them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct NoiseShift {
    pub mean: f64,
    pub median: f64,
    pub trimmed: f64,
    /// The shifts' standard deviation.
    pub sd: f64,
}

impl NoiseShift {
    /// The figures of the shifts `d` (sorted in place); `None` when empty.
    pub fn of(d: &mut [f64]) -> Option<NoiseShift> {
        if d.is_empty() {
            return None;
        }
        d.sort_by(f64::total_cmp);
        let n = d.len() as f64;
        let mean = d.iter().sum::<f64>() / n;
        let sd = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
        let median = d[d.len() / 2];
        let mut dev: Vec<f64> = d.iter().map(|x| (x - median).abs()).collect();
        dev.sort_by(f64::total_cmp);
        let lim = 3.0 * 1.4826 * dev[dev.len() / 2];
        let kept: Vec<f64> = d
            .iter()
            .copied()
            .filter(|x| (x - median).abs() <= lim)
            .collect();
        let trimmed = if kept.is_empty() {
            median
        } else {
            kept.iter().sum::<f64>() / kept.len() as f64
        };
        Some(NoiseShift {
            mean,
            median,
            trimmed,
            sd,
        })
    }
}
