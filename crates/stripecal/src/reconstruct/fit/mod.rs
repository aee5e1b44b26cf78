//! Measurements in point clouds: sphere and plane fits with outlier trimming and
//! one-sigma uncertainties. Points in mm (any frame); results in the same frame.
//!
//! ## Sphere
//!
//! 1. Algebraic start (Kåsa): `|p|^2 + D x + E y + F z + G = 0` by linear least squares
//!    over centred, scaled points; centre `-(D, E, F) / 2`, `R^2 = |c|^2 - G`.
//! 2. Geometric fit: the crate's Levenberg-Marquardt
//!    ([`crate::numerics::lm::levenberg_marquardt`], default tolerances: it stops at the
//!    cost's round-off floor) on the residuals `r_i = |p_i - c| - R` (Jacobian row
//!    `[-(p_i - c)^T / |p_i - c|, -1]`).
//! 3. Trimming (when `trim_sigma > 0`): the robust sigma of the current inliers'
//!    residuals (every point's in the first round, or the robust start's inliers') is
//!    `s = 1.4826 * median |r_i|`; points with `|r_i| > trim_sigma * s` are outliers;
//!    the fit is redone on the inliers (from the previous solution) until the inlier set
//!    stops changing (at most `max_trim_rounds`). The outlier count is reported.
//! 4. Uncertainty: `sigma^2 = sum r_i^2 / (n - 4)` over the inliers and
//!    `cov = sigma^2 (J^T J)^-1` at the solution (the usual Gauss-Markov estimate, valid
//!    for independent equal-variance residuals): `diameter_sigma_mm = 2 sqrt(cov_RR)`,
//!    `center_sigma_mm = sqrt(diag cov_cc)`. Correlated errors (e.g. a calibration error
//!    shared by all points) are not in it.
//!
//! ## Plane
//!
//! Total least squares: the centroid `c` and the normal `n` = the eigenvector of the
//! smallest eigenvalue of the scatter matrix; `d = n . c` (the [`Plane`] convention, `d >=
//! 0`). Residuals `r_i = n . p_i - d`; `rms_mm`, `flatness_mm = max r - min r` over the
//! inliers. Trimming as for the sphere. Uncertainty: with `n` tilted by angles `a, b`
//! about the two in-plane axes `e1, e2` and the offset `delta` at the centroid, the
//! residuals are `n . (p - c) - delta`, whose normal matrix is diagonal:
//! `var a = sigma^2 / sum (e1 . (p - c))^2`, `var b` likewise, `var delta = sigma^2 / n`;
//! `normal_sigma = sqrt(diag(var a e1 e1^T + var b e2 e2^T))`, and `d = n . c + delta`
//! gives `var d = var delta + var a (e1 . c)^2 + var b (e2 . c)^2`.
//!
//! ## The curved-surface stripe bias of a sphere
//!
//! A laser sheet of finite thickness on a sphere gives a skewed stripe profile whose
//! (windowed) centroid is not the image of the sheet's centre plane: the points lie off
//! the sphere and the diameter is biased (+0.005 mm on the paper's rig with the true
//! calibration). [`correct_sphere_bias`] models the profile each point's scan line sees
//! (the sphere's points at each sheet offset, their shading and the extractor's own
//! centroid code), subtracts the predicted bias and refits ([`stripe_bias`]); the sheet's
//! thickness is estimated from the stripe widths ([`sheet_sigma`]).

pub mod budget;
pub mod emitter;
mod measure;
mod plane;
pub mod sheet_sigma;
mod sphere;
pub mod stripe_bias;
mod trim;

use crate::error::{Error, Result};

pub use budget::{new_source_id, Budget, LinearForm, ScanFrames};
pub use emitter::EmitterEstimate;
pub use measure::{
    assumed_emitter_source, measure_plane, measure_sphere, sphere_distance, PlaneMeasurement,
    SphereMeasurement, SphereSystematic, SystematicSource, MODEL_SOURCE,
};
pub use plane::{fit_plane, PlaneFit};
pub use sheet_sigma::SheetSigmaEstimate;
pub use sphere::{fit_sphere, SphereFitResult};
pub use stripe_bias::{
    correct_sphere_bias, SphereBiasCorrection, StripeBiasOptions, SystematicKind, SystematicPart,
};

/// Options of the fits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Outlier threshold in robust sigmas (`1.4826 * median |r|`); 0 disables trimming.
    pub trim_sigma: f64,
    /// Largest number of trim-and-refit rounds.
    pub max_trim_rounds: usize,
    /// Largest number of Levenberg-Marquardt iterations per fit.
    pub max_iterations: usize,
    /// Sphere: start from a robust search (module docs) instead of the algebraic fit of
    /// all points, so a cloud that also holds other surfaces (the table the ball lies on)
    /// gives the sphere.
    pub robust_start: bool,
    /// Sphere, robust start: the fraction of points assumed to lie on the sphere at
    /// least (the quantile of |residual| minimised), in (0, 1].
    pub robust_quantile: f64,
    /// Sphere, robust start: accepted diameters `[min, max]` mm of candidate spheres;
    /// `None`: up to the diagonal of the points' bounding box.
    pub diameter_range_mm: Option<[f64; 2]>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            trim_sigma: 3.0,
            max_trim_rounds: 20,
            max_iterations: 100,
            robust_start: true,
            robust_quantile: 0.2,
            diameter_range_mm: None,
        }
    }
}

impl FitOptions {
    fn validate(&self) -> Result<()> {
        if !(self.trim_sigma.is_finite() && (self.trim_sigma == 0.0 || self.trim_sigma >= 1.0)) {
            return Err(Error::InvalidInput(format!(
                "trim_sigma = {} must be 0 (no trimming) or >= 1",
                self.trim_sigma
            )));
        }
        if !(self.robust_quantile > 0.0 && self.robust_quantile <= 1.0) {
            return Err(Error::InvalidInput(format!(
                "robust_quantile = {} must be in (0, 1]",
                self.robust_quantile
            )));
        }
        if let Some([a, b]) = self.diameter_range_mm {
            if !(a.is_finite() && b.is_finite() && a >= 0.0 && b > a) {
                return Err(Error::InvalidInput(format!(
                    "diameter_range_mm [{a}, {b}] must be finite with 0 <= min < max"
                )));
            }
        }
        if self.max_iterations == 0 {
            return Err(Error::InvalidInput("max_iterations must be >= 1".into()));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::numerics::rng::SplitMix64 as Rng;

    #[test]
    fn bad_points_are_typed_errors() {
        let e = fit_sphere(&[[0.0; 3]; 3], &FitOptions::default()).unwrap_err();
        assert!(matches!(e, Error::InvalidInput(_)), "{e}");
        let mut pts = vec![[1.0, 2.0, 3.0]; 10];
        pts[4][1] = f64::NAN;
        let e = fit_sphere(&pts, &FitOptions::default()).unwrap_err();
        assert!(e.to_string().contains("point 4"), "{e}");
        // Coplanar points: no sphere.
        let flat: Vec<[f64; 3]> = (0..50)
            .map(|i| [i as f64, (i * i % 7) as f64, 0.0])
            .collect();
        let e = fit_sphere(&flat, &FitOptions::default()).unwrap_err();
        assert!(matches!(e, Error::Degenerate(_)), "{e}");
        let line: Vec<[f64; 3]> = (0..50).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
        let e = fit_plane(&line, &FitOptions::default()).unwrap_err();
        assert!(matches!(e, Error::Degenerate(_)), "{e}");
        // A noisy line (one stripe on a plane) is no plane either.
        let mut rng = Rng(3);
        let line: Vec<[f64; 3]> = (0..500)
            .map(|i| [i as f64 * 0.1, 0.02 * rng.normal(), 0.02 * rng.normal()])
            .collect();
        let e = fit_plane(&line, &FitOptions::default()).unwrap_err();
        assert!(matches!(e, Error::Degenerate(_)), "{e}");
    }
}

#[cfg(test)]
mod measure_tests;
