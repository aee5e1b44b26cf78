//! Robust straight-line fit of stripe points on a planar surface: RANSAC (deterministic
//! seed) for the inlier set, then total least squares (orthogonal distances) on the
//! inliers, re-classified once with the refined line.

use crate::error::{Error, Result};
use crate::numerics::rng::SplitMix64;

/// Options of [`fit_line_with`].
#[derive(Debug, Clone, PartialEq)]
pub struct LineFitOptions {
    /// Largest orthogonal distance of an inlier, px.
    pub inlier_px: f64,
    /// RANSAC samples (pairs of points) at most.
    pub iterations: usize,
    /// Seed of the sampler (results are reproducible).
    pub seed: u64,
}

impl Default for LineFitOptions {
    fn default() -> Self {
        LineFitOptions {
            inlier_px: 1.0,
            iterations: 300,
            seed: 0x5eed_11e5,
        }
    }
}

/// A fitted line `normal . p = normal . point`.
#[derive(Debug, Clone, PartialEq)]
pub struct LineFit {
    /// A point on the line: the centroid of the inliers, px.
    pub point: [f64; 2],
    /// Unit direction; its larger component is positive.
    pub direction: [f64; 2],
    /// Unit normal `(-direction[1], direction[0])`.
    pub normal: [f64; 2],
    /// RMS and largest orthogonal distance of the inliers, px.
    pub rms_px: f64,
    pub max_px: f64,
    /// Per input point: used by the final fit.
    pub inliers: Vec<bool>,
    pub inlier_count: usize,
}

impl LineFit {
    /// Signed orthogonal distance of `p` from the line, px.
    pub fn distance(&self, p: [f64; 2]) -> f64 {
        self.normal[0] * (p[0] - self.point[0]) + self.normal[1] * (p[1] - self.point[1])
    }
}

/// The largest pixel coordinate [`fit_line_with`] takes.
const MAX_COORD_PX: f64 = 1e100;

/// [`fit_line_with`] with default options (inliers within 1 px).
pub fn fit_line(points: &[[f64; 2]]) -> Result<LineFit> {
    fit_line_with(points, &LineFitOptions::default())
}

/// Total least squares over the selected points: `(centroid, unit direction)`.
fn tls(points: &[[f64; 2]], sel: &[bool]) -> Option<([f64; 2], [f64; 2])> {
    let (mut n, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for (p, _) in points.iter().zip(sel).filter(|(_, &s)| s) {
        n += 1.0;
        cx += p[0];
        cy += p[1];
    }
    if n < 2.0 {
        return None;
    }
    cx /= n;
    cy /= n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for (p, _) in points.iter().zip(sel).filter(|(_, &s)| s) {
        let (dx, dy) = (p[0] - cx, p[1] - cy);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    if sxx + syy <= 0.0 {
        return None;
    }
    // Major eigenvector of [[sxx, sxy], [sxy, syy]].
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    Some(([cx, cy], canonical([theta.cos(), theta.sin()])))
}

fn canonical(d: [f64; 2]) -> [f64; 2] {
    let flip = if d[0].abs() >= d[1].abs() {
        d[0] < 0.0
    } else {
        d[1] < 0.0
    };
    if flip {
        [-d[0], -d[1]]
    } else {
        d
    }
}

/// Robust line fit (see the module docs). Errors: fewer than 2 points or a non-finite
/// coordinate (or one beyond 1e100 px) ([`Error::InvalidInput`]); all points at one place, or fewer than 2
/// inliers ([`Error::Degenerate`]).
pub fn fit_line_with(points: &[[f64; 2]], opts: &LineFitOptions) -> Result<LineFit> {
    let n = points.len();
    if n < 2 {
        return Err(Error::InvalidInput(format!(
            "a line fit needs at least 2 points, got {n}"
        )));
    }
    // Beyond 1e100 px the sums of squares overflow (and no image is that large).
    if let Some(i) = points
        .iter()
        .position(|p| p.iter().any(|x| !x.is_finite() || x.abs() > MAX_COORD_PX))
    {
        return Err(Error::InvalidInput(format!(
            "point {i} is not finite or beyond {MAX_COORD_PX:e} px: {:?}",
            points[i]
        )));
    }
    if !(opts.inlier_px.is_finite() && opts.inlier_px > 0.0) {
        return Err(Error::InvalidInput(format!(
            "inlier_px = {} must be finite and > 0",
            opts.inlier_px
        )));
    }
    let thr = opts.inlier_px;
    // RANSAC on pairs: most inliers, then smallest residual sum.
    let mut rng = SplitMix64(opts.seed);
    let mut best: Option<(usize, f64, [f64; 2], [f64; 2])> = None;
    let iters = if n == 2 { 1 } else { opts.iterations.max(1) };
    for _ in 0..iters {
        let (i, j) = if n == 2 {
            (0, 1)
        } else {
            let i = rng.below(n);
            let mut j = rng.below(n - 1);
            if j >= i {
                j += 1;
            }
            (i, j)
        };
        let (a, b) = (points[i], points[j]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dy);
        if len.is_nan() || len <= 1e-12 {
            continue;
        }
        let nrm = [-dy / len, dx / len];
        let (mut cnt, mut sum) = (0usize, 0.0);
        for p in points {
            let r = (nrm[0] * (p[0] - a[0]) + nrm[1] * (p[1] - a[1])).abs();
            if r <= thr {
                cnt += 1;
                sum += r;
            }
        }
        let better = match best {
            None => true,
            Some((c, s, _, _)) => cnt > c || (cnt == c && sum < s),
        };
        if better {
            best = Some((cnt, sum, a, nrm));
            if cnt == n {
                break;
            }
        }
    }
    let Some((_, _, a, nrm)) = best else {
        return Err(Error::Degenerate(format!(
            "all {n} points are at the same place: no line"
        )));
    };
    let mut inliers: Vec<bool> = points
        .iter()
        .map(|p| (nrm[0] * (p[0] - a[0]) + nrm[1] * (p[1] - a[1])).abs() <= thr)
        .collect();
    let mut line = None;
    for _ in 0..3 {
        let Some((c, d)) = tls(points, &inliers) else {
            break;
        };
        let nr = [-d[1], d[0]];
        let new: Vec<bool> = points
            .iter()
            .map(|p| (nr[0] * (p[0] - c[0]) + nr[1] * (p[1] - c[1])).abs() <= thr)
            .collect();
        line = Some((c, d));
        if new == inliers || new.iter().filter(|&&s| s).count() < 2 {
            break;
        }
        inliers = new;
    }
    let Some((c, d)) = line else {
        return Err(Error::Degenerate(format!(
            "fewer than 2 of {n} points lie on a common line within {thr} px"
        )));
    };
    let nr = [-d[1], d[0]];
    let (mut cnt, mut ss, mut mx) = (0usize, 0.0, 0.0f64);
    for (p, _) in points.iter().zip(&inliers).filter(|(_, &s)| s) {
        let r = (nr[0] * (p[0] - c[0]) + nr[1] * (p[1] - c[1])).abs();
        cnt += 1;
        ss += r * r;
        mx = mx.max(r);
    }
    Ok(LineFit {
        point: c,
        direction: d,
        normal: nr,
        rms_px: (ss / cnt.max(1) as f64).sqrt(),
        max_px: mx,
        inliers,
        inlier_count: cnt,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_line_with_outliers() {
        let mut pts: Vec<[f64; 2]> = (0..200)
            .map(|i| {
                let t = i as f64;
                let e = 0.05 * ((i * 7919 % 13) as f64 / 6.0 - 1.0);
                [100.0 + 0.3 * t + e * 0.95, t - e * 0.3]
            })
            .collect();
        for k in 0..40 {
            pts[k * 5] = [300.0 + k as f64, 20.0 * k as f64 % 170.0];
        }
        let f = fit_line(&pts).unwrap();
        assert_eq!(f.inlier_count, 160);
        let want = [0.3 / 1.09f64.sqrt(), 1.0 / 1.09f64.sqrt()];
        assert!((f.direction[0] - want[0]).abs() < 1e-3, "{:?}", f.direction);
        assert!((f.direction[1] - want[1]).abs() < 1e-3, "{:?}", f.direction);
        assert!(
            f.rms_px < 0.06 && f.max_px < 0.1,
            "{} {}",
            f.rms_px,
            f.max_px
        );
        assert!(f.distance([100.0, 0.0]).abs() < 0.05);
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        assert!(matches!(fit_line(&[]), Err(Error::InvalidInput(_))));
        assert!(matches!(
            fit_line(&[[1.0, 2.0]]),
            Err(Error::InvalidInput(_))
        ));
        assert!(matches!(
            fit_line(&[[1.0, 2.0], [f64::NAN, 0.0]]),
            Err(Error::InvalidInput(_))
        ));
        assert!(matches!(
            fit_line(&[[1.0, 2.0], [1.0, 2.0], [1.0, 2.0]]),
            Err(Error::Degenerate(_))
        ));
        let f = fit_line(&[[0.0, 0.0], [2.0, 2.0]]).unwrap();
        assert_eq!(f.inlier_count, 2);
        assert!(f.rms_px < 1e-12);
    }
}
