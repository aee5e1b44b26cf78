//! The curved-surface stripe bias of a sphere scan: a model of what the stripe extractor
//! measures on a sphere lit by a laser sheet of Gaussian thickness, and the sphere fit
//! corrected by it ([`correct_sphere_bias`]).
//!
//! ## Why the stripe centre is biased on a curved surface
//!
//! The sheet's irradiance falls off as `exp(-t^2 / (2 sigma^2))` with the distance `t` of
//! a point from the calibrated (centre) plane `n . p = d` (camera frame). On a flat surface
//! the surface point lit at offset `t` moves linearly along the scan line with `t` and its
//! brightness is the same on both sides: the profile is symmetric about the image of the
//! centre plane's intersection and any symmetric estimator finds it. On a sphere the point
//! at offset `t` moves non-linearly (the section circle shrinks as `t` grows towards the
//! far side), the incidence of the sheet and the distance to the emitter change, so the
//! profile is skewed: its windowed centroid is not the image of the `t = 0` point, and
//! triangulating it with the `t = 0` plane puts the point off the sphere (outwards on the
//! paper's rig: the diameter comes out ~+0.005 mm with the true calibration).
//!
//! ## The model of one stripe point
//!
//! For a stripe point on scan line `l` (the row `v = l` for [`StripeDirection::Cols`], the
//! column `u = l` for `Rows`) of a frame with camera pose `T_base_cam`, the sphere
//! `(c, R)` is taken to the camera frame. For sheet offsets `t_k = k 4 sigma / M`,
//! `k = -M..=M` (`M` = [`HALF_SAMPLES`]):
//!
//! - the section circle of the sphere with the plane `n . p = d + t`: centre `c - h n`,
//!   `h = n . c - d - t`, radius `rho = sqrt(R^2 - h^2)`, points
//!   `P(phi) = c - h n + rho (cos phi e1 + sin phi e2)` (`e1, e2` a fixed basis of the
//!   plane);
//! - the point of the circle imaged on scan line `l`: Newton's method on `phi` for
//!   `proj(P(phi))_line = l` through the calibrated camera (distortion included), started
//!   at the measured point for `t = 0` and continued outwards in `t`; its coordinate
//!   along the scan line `a_k`;
//! - its weight `w_k = exp(-t_k^2 / (2 sigma^2)) * cos(incidence) / r * |da/dt|`: the
//!   Lambertian radiance of the twin's (and a real) emitter at distance `r`, and the
//!   Jacobian of the change of variable from `t` to the image coordinate (`da/dt` from the
//!   implicit function theorem, analytic); zero where the point faces away from the camera
//!   or the emitter (the continuation stops there);
//! - pixel `x` of the scan line then receives
//!   `V(x) = sum_j omega_j sum_k w_k(l + x_j) K(x - a_k(l + x_j))` (trapezoid rule in
//!   `t`, spectrally accurate for this smooth Gaussian-weighted integrand), with `K` the
//!   unit pixel box convolved with the PSF's Gaussian (sigma `s_psf`), and the
//!   neighbouring scan lines `l + x_j` the same kernel mixes across the line (weights
//!   `omega_j`: 5-point Gauss-Hermite of variance `s_psf^2 + 1/12`, or a finer grid of
//!   the exact kernel where the stripe is steep). This across-line term is not small: a
//!   curved stripe (the ellipse of a sphere's section) is shifted by about
//!   `a'' (s_psf^2 + 1/12) / 2` whatever the sheet's thickness (on the paper's rig it is
//!   half of the whole effect);
//! - the extractor's own sub-pixel code runs on `V` (background flanks, half-maximum
//!   width, iterated window centroid of `+-window_fwhm` widths, or the Gaussian fit:
//!   [`StripeOptions`]), at the point's actual pixel phase. Its centre minus `a_0` is the
//!   predicted bias `delta` (px) along the scan line; the PSF is symmetric, so it would not
//!   move a full centroid of one line, but it does move the windowed one, which the
//!   extractor uses.
//!
//! Checked against a brute-force integration (rays cast through a fine grid of the image,
//! shaded, integrated over the pixel box and the PSF in both directions): agreement to
//! 1e-4 px on spheres and a flat surface (unit tests).
//!
//! The measured point is moved back to the pixel `a_meas - delta` on its scan line and
//! triangulated with the same plane: the 3D correction (base frame) is the difference.
//! The sphere is refitted to the corrected points (no trimming: the same points every
//! round) and the model re-evaluated with the new sphere until the sphere moves by less
//! than 1e-5 mm, or lies within 1e-5 mm of the rounds' fixed point by their predicted
//! contraction ("The rounds started from a predicted sphere" below).
//!
//! The sheet thickness `sigma` and the PSF's sigma are not in a calibration: they are
//! estimated from the stripe's widths ([`super::sheet_sigma`]) unless given.
//!
//! ## The emitter
//!
//! No calibration file holds the laser emitter's position. It enters through `cos`
//! (incidence) and `1 / r`, and it matters: on the paper's rig, moving it by +-30 mm
//! within the plane changes the diameter correction by up to ~0.004 mm (the
//! incidence near the emitter's terminator changes by ~15 deg, where the shading's
//! gradient across the sheet is steep). So it is estimated from the stripe's brightness
//! along the sphere ([`super::emitter`]; on the twin within 0.3-0.9 mm of the truth);
//! when that is refused or switched off the plane's point nearest the camera centre,
//! `n d` (the twin's default), is assumed. Points lit at more than `max_incidence_deg`
//! (default 75 deg) are not modelled: near the terminator the bias depends steeply on
//! the emitter and on the neglected terms.
//!
//! ## Points seen at grazing angles
//!
//! Points seen at more than `max_view_deg` (default 75 deg, as for the incidence) between
//! the surface normal and the line of sight are not modelled either, and so left out of
//! the corrected fit. Near the sphere's outline the sheet's thickness is foreshortened in
//! the image (`|da/dt|` falls below ~3 px/mm, against up to 45 elsewhere on the paper's
//! rig), so the profile is little more than the PSF cut by the extractor's window, and
//! the image noise moves its windowed centroid outwards, which the noise-free model does
//! not contain. On the twin (hp3-paper, noise 1, true calibration) these points, 8-15 %
//! of a scan, carried the whole remainder: corrected, they lay +0.6 um outside the sphere
//! on average while every other group of points (by incidence, by view angle, by
//! position on the ball) was within 0.15 um; lying at the rim of the seen cap, they lever
//! the fitted diameter by +1 um and the centre along the cap's axis by -0.6 um. With
//! them left out, the corrected diameter is within 0.1 um of the truth on three seeds.
//!
//! ## Points near the outline
//!
//! Points whose extractor support on their scan line (the centroid window for the
//! modelled width, its pixel of slack and the background flanks, [`StripeOptions`]) plus
//! `outline_margin_px` (default [`OUTLINE_MARGIN_PX`], 8 px) reaches the sphere's
//! outline in the image are not modelled either. There the extractor's flanks and window
//! read the ball's limb, where the ambient light falls off or steps to what lies behind,
//! while the model has a flat background; and the profiles there are weak and
//! foreshortened, so the image noise biases their windowed centroid. On the twin's wide
//! rig (a ball smaller in the image) the stripe points 6-20 px from the outline, still
//! inside the 75 deg view limit, measured +0.001 to +0.003 px more than the model
//! predicted (true calibration, sigmas and emitter; +0.0012 px at 8-10 px noise-free,
//! +0.0034 px at noise 1; +0.0015 px with noise and no ambient light). Tiny in pixels,
//! but these points sit at the rim of the seen cap and lever the diameter: the wide rig
//! kept 8.5-11.8 % of its diameter correction (seeds 1 and 2, noise 2) with them and
//! 2.8-7.4 % without. On the paper's rig, where the ball fills more of the image, the
//! test leaves out 6 % of the points and changes the corrected diameter by at most 0.09 um.
//!
//! ## Which points are fitted
//!
//! The caller gives the sphere's points, outliers and all (the ball's surroundings
//! too). The uncorrected fit ([`FitOptions`], trimmed) gives the starting sphere, and
//! its inliers the sheet sigma, the PSF sigma and the emitter. The points corrected are
//! those within [`CANDIDATE_SIGMAS`] (8) of its robust sigmas of the uncorrected sphere
//! (gross outliers out, the bias pattern in); the corrected fit trims the CORRECTED
//! residuals as the caller's fit would (`trim_sigma`, default 3), every round.
//!
//! Trimming the uncorrected residuals instead, as a first fit's inliers would, biases
//! the result under noise: those residuals carry the bias pattern, so the trim cuts
//! where the bias is large (the rim of the seen cap, whose points lever the diameter
//! most), and near that cut a point stays when its noise pulls it towards the sphere and
//! goes when its noise pushes it away. The kept points' noise is then not zero-mean
//! there, and no noise-free model contains that. On the twin's wide rig at noise 2
//! (true calibration, sheet sigma, PSF sigma and emitter, seeds 1 and 2) the corrected
//! diameter was +0.62 and +0.80 um off with the first fit's 3-sigma inliers, and is
//! +0.04 and +0.47 um off with this choice (the same scans, sigmas and emitter
//! estimated: +0.75 and +0.90 before, +0.21 and +0.51 um now). The extractor's own
//! mean response to the noise on the modelled rows is nil on the same scans: the
//! rendered rows' mean noisy-minus-clean centre is -0.0014 to +0.0007 px per 10-degree
//! bin of view angle, and the model's profiles with the same noise give -0.0001 to
//! +0.0008 px, their medians +0.001 to +0.005 px alike (the `noise_response` study of
//! `studies/stripe_bias`; the model's side, `noise.rs`, is now crate-private).
//!
//! ## Saturated points
//!
//! A stripe whose profile holds a pixel at full scale ([`FLAG_SATURATED`]) is clipped:
//! its top is flat and its centroid and width are not what the model predicts (the model
//! has no clipping, and the stripe's true peak is not known there). Such points are not
//! modelled: left out of the sheet-sigma fit, the emitter fit and the corrected fit
//! ([`SphereBiasCorrection::saturated`] counts them; the emitter fit always skipped
//! them). On the twin with the emitter moved 25 mm within the plane, 70 % of the ball's
//! points saturate. Modelled as if unclipped (true calibration, sigmas and emitter,
//! every third frame) they left +0.0027 mm of the +0.0100 mm diameter bias and 0.0019 mm
//! of the centre's, and the clipped widths pushed the sheet sigma's estimate to 0.141 mm
//! (truth 0.120); without them the full scan's corrected diameter is within 0.0001 mm and
//! its centre within 0.0002 mm (sigmas and emitter estimated: 0.1205 mm). The correction is refused when fewer than 10 points are not
//! saturated, or when the model holds for fewer than half of those that are not.
//!
//! [`FLAG_SATURATED`]: crate::vision::stripe::FLAG_SATURATED
//!
//! ## The systematic uncertainty reported
//!
//! Root sum of squares of, for the diameter and each centre coordinate (each part kept
//! signed, with what it is shared with, in [`SphereBiasCorrection::systematic_parts`]:
//! [`systematic`]):
//! - the emitter: estimated, half the change between `+-1` standard uncertainty of each
//!   of its two in-plane coordinates; assumed, per in-plane axis the larger change at the
//!   two ends of `+-emitter_range_mm` (default 30 mm) as the half width of a uniform
//!   distribution (`/ sqrt 3`);
//! - the sheet sigma's and the PSF sigma's standard uncertainties (from their fit,
//!   [`super::sheet_sigma`]) propagated by recomputing the correction at
//!   `sigma +- u(sigma)` (half the difference);
//! - the model's residual error: what remains after the correction is taken to lie within
//!   `+-`[`NEGLECTED_FRACTION`] (8 %) of the correction, uniformly (a GUM type B
//!   evaluation: standard uncertainty `0.08 |correction| / sqrt 3`, 4.6 %). This is an
//!   empirical bound from the twin with the true calibration (sigmas and emitter
//!   estimated), the whole scan, six seeds per condition, the remainder read as the mean
//!   over the seeds (each seed's value also holds the fit's random error, which the random
//!   part covers). Mean +- its standard error, % of the diameter's correction: hp3-paper
//!   at noise 1 -0.1 +- 1.0, noise 2 +1.0 +- 1.6, sheet sigma 0.2 mm **-4.9 +- 0.8**
//!   (-3.6 +- 1.6 with the true sigmas and emitter, three seeds: the model's own), a
//!   25.4 mm ball +0.9 +- 2.0, PSF 1 px -0.5 +- 0.5; the hp3-wide rig at noise 1
//!   +1.7 +- 1.0 and at noise 2 +3.2 +- 0.9 (of 9.0 um). Of the centre's z correction:
//!   -3.7 +- 1.7 with the 25.4 mm ball and -3.3 +- 1.7 on the paper's rig at noise 2 (the
//!   largest with two standard errors: 7.1 %), -3.6 +- 1.0 on the wide rig at noise 2;
//!   x: -4.0 +- 0.2 with the 0.2 mm sheet, -3.0 +- 0.3 on the paper's rig at noise 1. The
//!   bound covers every mean by two standard errors (at most 7.1 %); single seeds reach
//!   9.9 % (z, noise 2) and 8.9 % (diameter, the 25.4 mm ball), random error included
//!   (`studies/stripe_bias`'s `sweep` and `remainders.py` run these scans and print the
//!   table).
//!   The centre's y coordinate, which the correction hardly moves (0.44 um at most),
//!   keeps up to 0.11 um (one seed; 0.05 um on average): far below its random and
//!   calibration parts, but not within 8 % of its own correction.
//!   History: with the points fitted as the first fit's 3-sigma inliers (before
//!   "Which points are fitted") the same scans left up to 9.3 +- 0.5 % of the diameter's
//!   correction and 9.9 +- 0.7 % of centre z's (the wide rig at noise 2), and the bound
//!   was 12 %; before the points near the outline were left out, up to 11.8 and 12.2 %
//!   (one seed); before the grazing and the saturated points were, 9-61 % of the
//!   diameter's, and the moved emitter 23 % of the centre's. The twin's sheet is Gaussian
//!   and its ball Lambertian, as the model assumes; a real sheet or surface that is not
//!   can leave more than the twin can show (see the assumptions).
//!
//! The sensitivity terms are computed on a subsample of at most [`SENSITIVITY_POINTS`]
//! points, as differences from the nominal model on the same subsample and points.
//!
//! ## The model on subsamples
//!
//! What the model costs is its profiles (each point's sections at every sheet offset on
//! five scan lines, then the extractor). Where a subsample or fewer model runs give the
//! same figures, the correction uses them:
//! - the sheet's first width pass (its sigmas only start the emitter's fit; the second
//!   pass, with the emitter estimated, gives the sigmas used) on a quarter of the width
//!   points, and the second pass started from the first's sigmas (4 model runs instead
//!   of 10 on the twin; the sheet sigma moved by 2.4e-5 mm, 0.6 of its standard
//!   uncertainty, the diameter by -1.9e-6 mm: the gross outliers are dropped at the warm
//!   start, not one step from the linear one);
//! - the sensitivity terms on [`SENSITIVITY_POINTS`] (was 4,000): they are differences
//!   of two corrections of the same points, smooth over the sphere;
//! - the width fit's and the emitter fit's Gauss-Newton iterations try the step with the
//!   previous iteration's derivatives first and stop there when it is below their
//!   tolerance (saving the derivative runs at the solution).
//!
//! On the twin's ball (hp3-paper seed 1, 44,387 points, diameter standard uncertainty
//! 4.1e-4 mm), against the code before: the diameter moved by +2.3e-8 mm, the centre by
//! at most 1.6e-8 mm, the diameter's systematic uncertainty by +2.1e-8 mm, the sheet
//! sigma by +1.4e-7 mm. The refit's rounds model every candidate: the bias holds the
//! windowed centroid's pixel locking, which changes from one scan line to the next
//! (interpolating the bias between every second point along a frame's stripe moved the
//! diameter by -5.5e-5 mm and raised the fit's random part by 2 %; interpolating the
//! second round's change between every eighth, -2.7e-6 mm, +1 %).
//!
//! ## The rounds started from a predicted sphere
//!
//! The correct-and-refit rounds are a fixed-point iteration that contracts strongly: the
//! sphere the model is evaluated at moves the result by about 2e-3 of its own change on
//! the twin's ball (hp3-paper seed 1: the first round from the uncorrected sphere moves
//! the diameter by -5.0e-3 mm, the second by 5.9e-6 mm). So the rounds start from a
//! sphere predicted on every eighth candidate (two rounds of the subsample from the
//! uncorrected sphere: within 3e-4 mm of the fixed point on the twin, the subsample's
//! own random error), and the ratio of those two rounds' moves estimates the
//! contraction `q` (2.1e-3 on the twin; at least 0.02 is taken). The full rounds stop
//! when the sphere moves by less than 1e-5 mm, as before, or when it lies within 1e-5 mm
//! of the fixed point by that estimate (`q / (1 - q)` times its last move). On the twin
//! one full round instead of two: the corrected diameter moved by -2.2e-6 mm and the
//! centre by at most 9e-7 mm against the two full rounds from the uncorrected sphere
//! (its standard uncertainty 4.1e-4 mm), the refit's model runs 1.25 rounds' worth
//! instead of 2. Where the subsample is small (fewer than 400 candidates), a fit of it
//! fails or its rounds do not contract (`q >= 0.5`), the rounds start from the
//! uncorrected sphere.
//!
//! ## Assumptions and what is neglected
//!
//! - The surface is the fitted sphere, Lambertian with uniform reflectance; the stripe
//!   image has a locally flat background (the extractor removes a linear one).
//! - The sheet's profile is Gaussian in the distance from the plane, its thickness the
//!   same everywhere (a real sheet's waist varies along and across; the estimate is a
//!   mean over the scan's points); the emitter is a point source.
//! - The PSF is an isotropic Gaussian, the pixel a uniform box; vignetting, speckle
//!   and noise (zero-mean on the centroid to first order; the windowed centroid's
//!   non-linearity makes noise bias it a little), sensor non-linearity. The pixel-locking
//!   of the centroid is modelled (the point's actual pixel phase), so it is corrected too.
//! - Points where the model fails (the scan line misses the section circle, the
//!   synthetic profile is rejected by the extractor's own tests, incidence or view angle
//!   beyond its limit, the extractor's support near the outline, a saturated stripe) are
//!   left out of the corrected fit ([`SphereBiasCorrection::modelled`]).

mod correct;
#[cfg(test)]
mod diagnostics;
#[cfg(test)]
mod noise;
mod points;
mod systematic;

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::Plane;
use crate::stripe_model::Rig;
use crate::vision::stripe::StripeOptions;

use super::emitter::EmitterEstimate;
use super::sheet_sigma::SheetSigmaEstimate;
use super::{FitOptions, SphereFitResult};

pub use correct::correct_sphere_bias;
#[cfg(test)]
pub(crate) use diagnostics::{predicted_bias_px, ModelInputs};
#[cfg(test)]
pub(crate) use noise::{predicted_noise_shift_px, NoiseDraws, NoiseShift};
pub use systematic::{SystematicKind, SystematicPart};

pub use crate::stripe_model::{neglected_share, HALF_SAMPLES};
/// Points used for the sensitivity (systematic) terms, at most.
pub const SENSITIVITY_POINTS: usize = 1000;
/// The points corrected: those within this many of the uncorrected fit's robust sigmas of
/// its sphere (module docs, "Which points are fitted").
pub const CANDIDATE_SIGMAS: f64 = 8.0;
/// The default [`StripeBiasOptions::outline_margin_px`], px (module docs).
pub const OUTLINE_MARGIN_PX: f64 = 8.0;
/// The neglected terms (module docs): the half width of their uniform distribution, as
/// a fraction of the correction.
pub const NEGLECTED_FRACTION: f64 = 0.08;

/// The sphere model's rig for `opts`: the emitter given or `n d`, the incidence and
/// view limits (`max_view_deg` checked: within 0..=90); `stripe` with its direction
/// resolved.
fn sphere_rig<'a>(
    camera: &'a Camera,
    plane: &Plane,
    stripe: &'a StripeOptions,
    opts: &StripeBiasOptions,
) -> Result<Rig<'a>> {
    let deg = opts.max_view_deg;
    if !(0.0..=90.0).contains(&deg) {
        return Err(Error::InvalidInput(format!(
            "max_view_deg = {deg} must be within 0..=90"
        )));
    }
    let emitter = opts
        .emitter_cam_mm
        .map_or(plane.normal * plane.d, Vector3::from);
    let mut rig = Rig::new(
        camera,
        plane,
        emitter,
        stripe.direction,
        stripe,
        opts.max_incidence_deg,
    );
    rig.min_cos_view = deg.to_radians().cos().max(0.0);
    let margin = opts.outline_margin_px;
    if !(margin >= 0.0 && margin.is_finite()) {
        return Err(Error::InvalidInput(format!(
            "outline_margin_px = {margin} must be finite and at least 0"
        )));
    }
    rig.outline_margin_px = Some(margin);
    Ok(rig)
}

/// Options of [`correct_sphere_bias`].
#[derive(Debug, Clone, PartialEq)]
pub struct StripeBiasOptions {
    /// The stripe extractor's options the points were extracted with (window, method,
    /// direction; `Auto` is resolved from the plane as the reconstruction does).
    pub stripe: StripeOptions,
    /// The sheet's Gaussian sigma, mm; `None`: estimated from the stripe widths.
    pub sheet_sigma_mm: Option<f64>,
    /// The PSF's Gaussian sigma, px; `None`: estimated with the sheet sigma.
    pub psf_sigma_px: Option<f64>,
    /// Emitter position in the camera frame, mm; `None`: `n d` (module docs).
    pub emitter_cam_mm: Option<[f64; 3]>,
    /// With no `emitter_cam_mm`: estimate the emitter from the stripe's brightness
    /// ([`super::emitter`]; `false`: assume `n d`).
    pub estimate_emitter: bool,
    /// The emitter's assumed position range within the plane, +- mm (systematic term when
    /// the emitter is assumed, not estimated).
    pub emitter_range_mm: f64,
    /// Points lit at a larger incidence (from the assumed emitter, degrees) are not
    /// modelled and left out of the corrected fit: near the emitter's terminator the
    /// shading, and so the bias, depends steeply on where the emitter is.
    pub max_incidence_deg: f64,
    /// Points seen at a larger angle between the surface normal and the line of sight
    /// (degrees) are not modelled and left out of the corrected fit (module docs).
    pub max_view_deg: f64,
    /// Points whose extractor support (centroid window and background flanks, for the
    /// modelled stripe width) comes within this many pixels of the sphere's outline on
    /// their scan line are not modelled and left out of the corrected fit (module docs).
    pub outline_margin_px: f64,
    /// The sphere fits (the first one of the given points, and the refits).
    pub fit: FitOptions,
}

impl Default for StripeBiasOptions {
    fn default() -> Self {
        StripeBiasOptions {
            stripe: StripeOptions::default(),
            sheet_sigma_mm: None,
            psf_sigma_px: None,
            emitter_cam_mm: None,
            estimate_emitter: true,
            emitter_range_mm: 30.0,
            max_incidence_deg: 75.0,
            max_view_deg: 75.0,
            outline_margin_px: OUTLINE_MARGIN_PX,
            fit: FitOptions::default(),
        }
    }
}

/// The corrected sphere fit and what the correction did.
#[derive(Debug, Clone, PartialEq)]
pub struct SphereBiasCorrection {
    /// The sphere fitted to the corrected points: the modelled ones, in input order, its
    /// `inlier` mask over them (the trim of the corrected residuals; [`Self::used`]
    /// per input point).
    pub fit: SphereFitResult,
    /// The sphere fitted to the points as given.
    pub uncorrected: SphereFitResult,
    /// Per input point: the bias subtracted (measured - corrected), base frame, mm
    /// (zero where not modelled).
    pub corrections_mm: Vec<[f64; 3]>,
    /// Per input point: the model gave a correction (the others are left out of `fit`);
    /// only the points within [`CANDIDATE_SIGMAS`] of the uncorrected sphere are modelled.
    pub modelled: Vec<bool>,
    /// Per input point: in `fit` (modelled, and kept by the fit's trimming of the
    /// corrected residuals).
    pub used: Vec<bool>,
    /// Input points left out because their stripe profile holds a saturated pixel
    /// ([`crate::vision::stripe::FLAG_SATURATED`]; module docs).
    pub saturated: usize,
    /// The sheet and PSF sigmas used (estimated or given).
    pub sheet: SheetSigmaEstimate,
    /// The emitter position used (camera frame, mm).
    pub emitter_cam_mm: Vector3<f64>,
    /// The emitter's estimate from the brightness, when made and accepted.
    pub emitter_estimate: Option<EmitterEstimate>,
    /// `fit.diameter_mm - uncorrected.diameter_mm`.
    pub diameter_change_mm: f64,
    /// `fit.center_mm - uncorrected.center_mm`.
    pub center_change_mm: Vector3<f64>,
    /// Systematic standard uncertainty of the corrected diameter, mm (module docs).
    pub diameter_systematic_mm: f64,
    /// Systematic standard uncertainty of the corrected centre coordinates, mm.
    pub center_systematic_mm: Vector3<f64>,
    /// Its parts `[emitter, sheet and PSF sigmas, neglected terms]` for the diameter.
    pub diameter_systematic_parts_mm: [f64; 3],
    /// The systematic parts one by one, signed, with what each is shared with
    /// ([`systematic`]); the three figures above are their root sums of squares.
    pub systematic_parts: Vec<SystematicPart>,
    /// Correct-and-refit rounds made.
    pub rounds: usize,
}

#[cfg(test)]
mod tests;
