//! Outlier trimming shared by the fits: input checks, the robust-sigma floor and the
//! trim-and-refit loop (step 3 of the [`super`] docs).

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::numerics::robust::{median, robust_sigma};

use super::FitOptions;

pub(super) fn check_points(points: &[[f64; 3]], min: usize, what: &str) -> Result<()> {
    if points.len() < min {
        return Err(Error::InvalidInput(format!(
            "{what} fit needs at least {min} points, {} given",
            points.len()
        )));
    }
    if let Some(i) = points.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
        return Err(Error::InvalidInput(format!(
            "point {i} ({:?}) is not finite",
            points[i]
        )));
    }
    Ok(())
}

/// Smallest robust sigma used for trimming: 1e-9 of the points' extent (exact data must
/// not have rounding errors trimmed).
pub(super) fn sigma_floor(points: &[[f64; 3]]) -> f64 {
    let (lo, hi) = bounding_box(points);
    1e-9 * (hi - lo).norm().max(1e-300)
}

/// The corners `(min, max)` of the points' axis-aligned bounding box.
pub(super) fn bounding_box(points: &[[f64; 3]]) -> (Vector3<f64>, Vector3<f64>) {
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    for p in points {
        let v = Vector3::from(*p);
        lo = lo.inf(&v);
        hi = hi.sup(&v);
    }
    (lo, hi)
}

/// Generic trim loop: `fit(mask) -> (params, residuals of all points)`.
pub(super) fn trim_loop<P: Clone>(
    n: usize,
    min_inliers: usize,
    opts: &FitOptions,
    what: &str,
    init: Option<(Vec<bool>, P)>,
    sigma_floor: f64,
    mut fit: impl FnMut(&[bool], Option<&P>) -> Result<(P, Vec<f64>)>,
) -> Result<(P, Vec<f64>, Vec<bool>, f64)> {
    let (mut mask, start) = match init {
        // Without trimming every point is used; the robust start only seeds the fit.
        Some((_, p)) if opts.trim_sigma == 0.0 => (vec![true; n], Some(p)),
        Some((m, p)) => (m, Some(p)),
        None => (vec![true; n], None),
    };
    let (mut p, mut res) = fit(&mask, start.as_ref())?;
    let mut buf = Vec::with_capacity(n);
    let mut sigma = robust_sigma(&res, &mut buf);
    if opts.trim_sigma == 0.0 {
        return Ok((p, res, mask, sigma));
    }
    for _ in 0..opts.max_trim_rounds {
        // Robust sigma over the current inliers' residuals.
        buf.clear();
        buf.extend(
            res.iter()
                .zip(&mask)
                .filter(|(_, &m)| m)
                .map(|(r, _)| r.abs()),
        );
        sigma = (1.4826 * median(&mut buf).unwrap_or(0.0)).max(sigma_floor);
        let thr = opts.trim_sigma * sigma;
        let new: Vec<bool> = res.iter().map(|r| r.abs() <= thr).collect();
        if new == mask {
            break;
        }
        let k = new.iter().filter(|&&m| m).count();
        if k < min_inliers {
            return Err(Error::Degenerate(format!(
                "{what} fit: only {k} of {n} points within {:.3} mm ({} robust sigmas) of the fit",
                thr, opts.trim_sigma
            )));
        }
        mask = new;
        let (p2, r2) = fit(&mask, Some(&p))?;
        p = p2;
        res = r2;
    }
    Ok((p, res, mask, sigma))
}
