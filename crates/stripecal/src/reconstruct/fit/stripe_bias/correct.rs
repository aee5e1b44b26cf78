//! The curved-surface bias correction of a sphere scan ([`correct_sphere_bias`]), by
//! phase: the points' geometry and the uncorrected fit, the sheet and PSF sigmas with
//! the emitter, the correct-and-refit rounds, the systematic parts.

use nalgebra::Vector3;

use super::points::{
    corrected_points, corrections, corrections_for_emitters, corrections_from_deltas, deltas,
    point_geo, ScanGeometry,
};
use super::systematic::{assumed_emitter_part, estimate_part, model_part, rss};
use super::{
    neglected_share, sphere_rig, SphereBiasCorrection, StripeBiasOptions, SystematicKind,
    SystematicPart, CANDIDATE_SIGMAS, NEGLECTED_FRACTION, SENSITIVITY_POINTS,
};
use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::StripeDirection;
use crate::reconstruct::fit::emitter::{estimate_emitter, EmitterEstimate};
use crate::reconstruct::fit::sheet_sigma::{
    estimate_sheet_sigma, SheetSigmaEstimate, WIDTH_POINTS,
};
use crate::reconstruct::fit::{fit_sphere, FitOptions, SphereFitResult};
use crate::reconstruct::triangulate::Triangulator;
use crate::reconstruct::{stripe_direction_from_plane, ScanPoints};
use crate::stripe_model::Rig;
use crate::vision::stripe::StripeOptions;

/// Fewest modelled points the corrected fit is made on.
const MIN_MODELLED: usize = 10;

/// Largest number of correct-and-refit rounds.
const MAX_ROUNDS: usize = 8;

/// The predictor's subsample ([`super`] docs, "The rounds started from a predicted
/// sphere"): every this many-th candidate.
const PREDICT_STEP: usize = 8;

/// The predictor is not used on fewer candidates than this.
const PREDICT_MIN_POINTS: usize = 400;

/// The predicted contraction of the rounds at most (else no prediction is used), and at
/// least (the estimate's floor in the stopping rule).
const MAX_CONTRACTION: f64 = 0.5;
const MIN_CONTRACTION: f64 = 0.02;

/// The rounds stop when the sphere moves by less than this (mm), or lies within this of
/// their fixed point by the predicted contraction.
const CONVERGED_MM: f64 = 1e-5;

/// The width fit's points in the first of the sheet's two passes when the emitter is
/// estimated ([`super`] docs, "The model on subsamples"): that pass only starts the
/// emitter's fit; the second pass, whose sigmas are used, takes
/// [`WIDTH_POINTS`].
const FIRST_PASS_WIDTH_POINTS: usize = WIDTH_POINTS / 4;

/// The curved-surface bias correction of a sphere scan (module docs).
///
/// `points`: the stripe points of the sphere (e.g. a first fit's inliers), with their
/// pixels and frames; `base_cam[f]`: `T_base_cam` of frame `f` (`T_base_hand(reading) *
/// T_hand_cam`); `camera` and `plane`: the calibration the points were triangulated
/// with. Errors: too few points, frames without a pose, a sheet thickness that cannot
/// be estimated ([`super::sheet_sigma`]), a model that fails on most points, fewer than 10
/// points that are not saturated.
pub fn correct_sphere_bias(
    points: &ScanPoints,
    base_cam: &[Iso3],
    camera: &Camera,
    plane: &Plane,
    opts: &StripeBiasOptions,
) -> Result<SphereBiasCorrection> {
    let n = points.len();
    if points.u_px.len() != n || points.v_px.len() != n || points.frame.len() != n {
        return Err(Error::InvalidInput(
            "ScanPoints vectors of different lengths".into(),
        ));
    }
    let stripe = resolved_stripe(camera, plane, opts)?;
    let mut rig = sphere_rig(camera, plane, &stripe, opts)?;
    let tri = Triangulator::new(camera, plane, &Iso3::identity(), 0.0)?;
    let cam_base: Vec<Iso3> = base_cam.iter().map(|t| t.inverse()).collect();
    let geo = (0..n)
        .map(|i| point_geo(points, &cam_base, rig.along, i))
        .collect::<Result<Vec<_>>>()?;
    let saturated = geo.iter().filter(|(g, _)| g.saturated).count();
    if n - saturated < MIN_MODELLED {
        return Err(Error::Degenerate(format!(
            "stripe bias: {} of {n} points are not saturated{}",
            n - saturated,
            saturated_hint(saturated)
        )));
    }
    let uncorrected = fit_sphere(&points.points_mm, &opts.fit)?;
    // Which points are corrected and which fitted (module docs): the candidates are the
    // points near the uncorrected sphere, the fit trims the corrected residuals.
    let cand = candidates(&points.points_mm, &uncorrected);
    let scan = SphereScan {
        points,
        geometry: ScanGeometry {
            tri: &tri,
            geo: &geo,
            cam_base: &cam_base,
        },
        cand,
        uncorrected: &uncorrected,
        saturated,
    };
    // Refits of the corrected points: trimmed as the caller's fit is (on the corrected
    // residuals), started from the algebraic fit; the sensitivity fits of the same
    // points untrimmed.
    let refit_opts = FitOptions {
        robust_start: false,
        ..opts.fit
    };
    let sens_opts = FitOptions {
        trim_sigma: 0.0,
        ..refit_opts
    };
    let (sheet, emitter_estimate) = scan.sheet_and_emitter(&mut rig, opts)?;
    let (sigma, psf) = (sheet.sheet_sigma_mm, sheet.psf_sigma_px);
    let emitter = rig.emitter;
    let refit = scan.correct_and_refit(&rig, (sigma, psf), &refit_opts)?;
    let mut parts = scan.systematic_parts(
        &rig,
        &refit,
        &sheet,
        emitter_estimate.as_ref(),
        (opts.emitter_range_mm, &sens_opts),
    );
    let Refit {
        fit,
        corr,
        used,
        rounds,
        ..
    } = refit;
    let diameter_change_mm = fit.diameter_mm - uncorrected.diameter_mm;
    let center_change_mm = fit.center_mm - uncorrected.center_mm;
    parts.push(model_part(
        neglected_share(NEGLECTED_FRACTION),
        diameter_change_mm,
        &center_change_mm,
    ));
    let is_emitter = |k: &SystematicKind| {
        matches!(
            k,
            SystematicKind::AssumedEmitter(_) | SystematicKind::Estimate(0 | 1)
        )
    };
    let is_sigma = |k: &SystematicKind| matches!(k, SystematicKind::Estimate(2 | 3));
    let diameter = |p: &SystematicPart| p.diameter_mm;
    let diameter_systematic_mm = rss(&parts, |_| true, diameter);
    let center_systematic_mm =
        Vector3::from_fn(|k, _| rss(&parts, |_| true, |p: &SystematicPart| p.center_mm[k]));
    let diameter_systematic_parts_mm = [
        rss(&parts, is_emitter, diameter),
        rss(&parts, is_sigma, diameter),
        rss(&parts, |k| *k == SystematicKind::Model, diameter),
    ];
    let (modelled, corrections_mm) = scan.per_point(&corr);
    Ok(SphereBiasCorrection {
        fit,
        uncorrected,
        corrections_mm,
        modelled,
        used,
        saturated,
        sheet,
        emitter_cam_mm: emitter,
        emitter_estimate,
        diameter_change_mm,
        center_change_mm,
        diameter_systematic_mm,
        center_systematic_mm,
        diameter_systematic_parts_mm,
        systematic_parts: parts,
        rounds,
    })
}

/// The extractor's options checked, with `Auto` resolved from the plane as the
/// reconstruction does; errors on an emitter range that is not a finite number >= 0.
fn resolved_stripe(
    camera: &Camera,
    plane: &Plane,
    opts: &StripeBiasOptions,
) -> Result<StripeOptions> {
    let mut stripe = opts.stripe.clone();
    stripe.validate()?;
    if stripe.direction == StripeDirection::Auto {
        stripe.direction = stripe_direction_from_plane(camera, plane);
    }
    if !(opts.emitter_range_mm.is_finite() && opts.emitter_range_mm >= 0.0) {
        return Err(Error::InvalidInput(format!(
            "emitter_range_mm = {} must be finite and >= 0",
            opts.emitter_range_mm
        )));
    }
    Ok(stripe)
}

/// A sphere scan under correction: its points, their geometry, the candidates (the
/// points modelled), the uncorrected fit and the saturated points left out.
struct SphereScan<'a> {
    points: &'a ScanPoints,
    geometry: ScanGeometry<'a>,
    cand: Vec<usize>,
    uncorrected: &'a SphereFitResult,
    saturated: usize,
}

/// What the correct-and-refit rounds end with: the last fit, the candidates'
/// corrections, which points the fit used, the rounds made and the last fit's sphere
/// `(centre, radius)`.
struct Refit {
    fit: SphereFitResult,
    corr: Vec<Option<[f64; 3]>>,
    used: Vec<bool>,
    rounds: usize,
    sphere: (Vector3<f64>, f64),
}

impl SphereScan<'_> {
    /// Per input point: whether the model gave a correction, and the correction (zero
    /// where not), from the candidates' corrections `corr`.
    fn per_point(&self, corr: &[Option<[f64; 3]>]) -> (Vec<bool>, Vec<[f64; 3]>) {
        let n = self.points.len();
        let mut modelled = vec![false; n];
        let mut corrections_mm = vec![[0.0; 3]; n];
        for (&i, c) in self.cand.iter().zip(corr) {
            if let Some(c) = c {
                modelled[i] = true;
                corrections_mm[i] = *c;
            }
        }
        (modelled, corrections_mm)
    }

    /// The corrections of the points `idx` for the sphere `(centre, radius)` and the
    /// sigmas `(sheet mm, PSF px)`.
    fn corrections(
        &self,
        rig: &Rig<'_>,
        idx: &[usize],
        sphere: (&Vector3<f64>, f64),
        (sigma, psf): (f64, f64),
    ) -> Vec<Option<[f64; 3]>> {
        corrections(rig, &self.geometry, idx, sphere, sigma, psf)
    }

    /// [`Self::corrections`] for each of the `emitters` (camera frame) in turn.
    fn corrections_for_emitters(
        &self,
        rig: &Rig<'_>,
        idx: &[usize],
        sphere: (&Vector3<f64>, f64),
        (sigma, psf): (f64, f64),
        emitters: &[Vector3<f64>],
    ) -> Vec<Vec<Option<[f64; 3]>>> {
        corrections_for_emitters(rig, &self.geometry, idx, sphere, sigma, psf, emitters)
    }

    /// The sheet and PSF sigmas (widths) and the emitter (brightness), from the
    /// uncorrected fit's inliers; the emitter estimate is `rig`'s emitter when made and
    /// accepted.
    fn sheet_and_emitter(
        &self,
        rig: &mut Rig<'_>,
        opts: &StripeBiasOptions,
    ) -> Result<(SheetSigmaEstimate, Option<EmitterEstimate>)> {
        let (points, uncorrected, saturated) = (self.points, self.uncorrected, self.saturated);
        let (geo, cam_base) = (self.geometry.geo, self.geometry.cam_base);
        let n = points.len();
        let est: Vec<usize> = (0..n).filter(|&i| uncorrected.inlier[i]).collect();
        let est_points = points.subset(&est);
        let geo3: Vec<(Vector3<f64>, f64, usize)> = est
            .iter()
            .map(|&i| (geo[i].0.p_cam, geo[i].0.line, geo[i].1))
            .collect();
        let sphere0 = (&uncorrected.center_mm, 0.5 * uncorrected.diameter_mm);
        // The sheet and PSF sigmas (widths) and the emitter (brightness) depend on each
        // other a little: two passes, the second with the first's emitter.
        let estimate_e = opts.emitter_cam_mm.is_none() && opts.estimate_emitter;
        let mut emitter_estimate = None;
        let mut sheet;
        let mut start = None;
        let mut pass = 0;
        loop {
            sheet = estimate_sheet_sigma(
                rig,
                &est_points,
                &geo3,
                cam_base,
                sphere0,
                opts.sheet_sigma_mm,
                opts.psf_sigma_px,
                if estimate_e && pass == 0 {
                    FIRST_PASS_WIDTH_POINTS
                } else {
                    WIDTH_POINTS
                },
                // The second pass from the first's sigmas.
                start,
            )
            .map_err(|e| match e {
                Error::Degenerate(m) => {
                    Error::Degenerate(format!("{m}{}", saturated_hint(saturated)))
                }
                other => other,
            })?;
            pass += 1;
            start = Some((sheet.sheet_sigma_mm, sheet.psf_sigma_px));
            if !estimate_e || pass > 2 {
                break;
            }
            let (sigma, psf) = (sheet.sheet_sigma_mm, sheet.psf_sigma_px);
            emitter_estimate =
                estimate_emitter(rig, &est_points, &geo3, cam_base, sphere0, sigma, psf);
            match &emitter_estimate {
                Some(e) => rig.emitter = e.emitter_cam_mm,
                None => break,
            }
            if pass == 2 {
                break;
            }
        }
        Ok((sheet, emitter_estimate))
    }

    /// The rounds' fixed point and their contraction predicted on a subsample of the
    /// candidates (every [`PREDICT_STEP`]-th; [`super`] docs, "The rounds started from
    /// a predicted sphere"): two correct-and-refit rounds of the subsample from
    /// `sphere0`, the second's sphere and the ratio of the second's move to the first's.
    /// `None` where the subsample holds fewer than [`PREDICT_MIN_POINTS`] candidates, a
    /// fit fails or the rounds do not contract below [`MAX_CONTRACTION`].
    fn predicted(
        &self,
        rig: &Rig<'_>,
        sphere0: (Vector3<f64>, f64),
        (sigma, psf): (f64, f64),
        refit_opts: &FitOptions,
    ) -> Option<((Vector3<f64>, f64), f64)> {
        let sub: Vec<usize> = self.cand.iter().copied().step_by(PREDICT_STEP).collect();
        if sub.len() < PREDICT_MIN_POINTS {
            return None;
        }
        let round = |s: (Vector3<f64>, f64)| {
            let d = deltas(rig, &self.geometry, &sub, (&s.0, s.1), sigma, psf);
            let corr = corrections_from_deltas(rig, &self.geometry, &sub, &d);
            let pts = corrected_points(self.points, &sub, &corr);
            if pts.len() < MIN_MODELLED {
                return None;
            }
            let f = fit_sphere(&pts, refit_opts).ok()?;
            Some((f.center_mm, 0.5 * f.diameter_mm))
        };
        let s1 = round(sphere0)?;
        let s2 = round(s1)?;
        let (m1, m2) = (sphere_move(&sphere0, &s1), sphere_move(&s1, &s2));
        let q = if m1 > 0.0 { m2 / m1 } else { 0.0 };
        (q < MAX_CONTRACTION).then_some((s2, q))
    }

    /// Correct, refit, repeat (at most [`MAX_ROUNDS`] times), from the sphere
    /// [`Self::predicted`] gives (else the uncorrected one), until the sphere moves less
    /// than [`CONVERGED_MM`] or lies within it of the rounds' fixed point by the
    /// predicted contraction; errors when the model holds for fewer than half the
    /// uncorrected fit's unsaturated inliers or fewer than [`MIN_MODELLED`] points.
    fn correct_and_refit(
        &self,
        rig: &Rig<'_>,
        (sigma, psf): (f64, f64),
        refit_opts: &FitOptions,
    ) -> Result<Refit> {
        let (points, uncorrected, saturated) = (self.points, self.uncorrected, self.saturated);
        let (cand, geo) = (&self.cand, self.geometry.geo);
        let n = points.len();
        // The model's sanity check counts the uncorrected fit's inliers (the band's extra
        // points lie at the rim, where the model's limits leave many out).
        let inliers_unsaturated = (0..n)
            .filter(|&i| uncorrected.inlier[i] && !geo[i].0.saturated)
            .count();
        let sphere0 = (uncorrected.center_mm, 0.5 * uncorrected.diameter_mm);
        let predicted = self.predicted(rig, sphere0, (sigma, psf), refit_opts);
        let (mut sphere, contraction) = match predicted {
            Some((s, q)) => (s, Some(q.max(MIN_CONTRACTION))),
            None => (sphere0, None),
        };
        let mut fit = uncorrected.clone();
        let mut corr = Vec::new();
        let mut used = vec![false; n];
        let mut rounds = 0;
        while rounds < MAX_ROUNDS {
            rounds += 1;
            let d = deltas(rig, &self.geometry, cand, (&sphere.0, sphere.1), sigma, psf);
            corr = corrections_from_deltas(rig, &self.geometry, cand, &d);
            let good: Vec<usize> = cand
                .iter()
                .zip(&corr)
                .filter_map(|(&i, c)| c.map(|_| i))
                .collect();
            let good_inliers = good.iter().filter(|&&i| uncorrected.inlier[i]).count();
            if good_inliers < inliers_unsaturated / 2 || good.len() < MIN_MODELLED {
                return Err(Error::Degenerate(format!(
                    "stripe bias: the model holds for {good_inliers} of the uncorrected fit's {} \
                     inliers only{}",
                    uncorrected.points,
                    saturated_hint(saturated)
                )));
            }
            fit = fit_sphere(&corrected_points(points, cand, &corr), refit_opts)?;
            used.fill(false);
            for (&i, &k) in good.iter().zip(&fit.inlier) {
                used[i] = k;
            }
            let next = (fit.center_mm, 0.5 * fit.diameter_mm);
            let moved = sphere_move(&sphere, &next);
            sphere = next;
            // The fixed point lies about q / (1 - q) of the last move beyond it.
            let near = contraction.is_some_and(|q| q / (1.0 - q) * moved < CONVERGED_MM);
            if moved < CONVERGED_MM || near {
                break;
            }
        }
        Ok(Refit {
            fit,
            corr,
            used,
            rounds,
            sphere,
        })
    }

    /// The systematic parts, signed, one per source ([`super::systematic`]): the
    /// emitter's (its assumed range `+-range_mm`, or its estimate's standard
    /// uncertainty, along each axis) and the sheet and PSF sigmas' (+-1 standard
    /// uncertainty each), as differences from the nominal model on a subsample of the
    /// points the refit used, fitted untrimmed with `sens_opts`.
    fn systematic_parts(
        &self,
        rig: &Rig<'_>,
        refit: &Refit,
        sheet: &SheetSigmaEstimate,
        emitter_estimate: Option<&EmitterEstimate>,
        (range_mm, sens_opts): (f64, &FitOptions),
    ) -> Vec<SystematicPart> {
        let points = self.points;
        let (used, sphere) = (&refit.used, refit.sphere);
        let (sigma, psf) = (sheet.sheet_sigma_mm, sheet.psf_sigma_px);
        let emitter = rig.emitter;
        let n = points.len();
        // Systematic parts on a subsample, as differences from the nominal model on the
        // points both model.
        let fitted: Vec<usize> = (0..n).filter(|&i| used[i]).collect();
        let step = fitted.len().div_ceil(SENSITIVITY_POINTS).max(1);
        let sub: Vec<usize> = fitted.into_iter().step_by(step).collect();
        let corr_sub = |rig: &Rig<'_>, sigma: f64, psf: f64| {
            self.corrections(rig, &sub, (&sphere.0, sphere.1), (sigma, psf))
        };
        // The nominal model and the emitter's alternatives (its assumed range's ends, or
        // +-1 standard uncertainty of its estimate, along each in-plane axis): one
        // section solve per point for all five.
        let axes = [rig.e1, rig.e2];
        let ends = emitter_estimate.map_or([range_mm; 2], |e| e.sd_mm);
        let mut emitters = vec![emitter];
        for (dir, end) in axes.iter().zip(ends) {
            emitters.push(emitter + dir * end);
            emitters.push(emitter + dir * (-end));
        }
        let mut by_emitter = self
            .corrections_for_emitters(rig, &sub, (&sphere.0, sphere.1), (sigma, psf), &emitters)
            .into_iter();
        let nominal = by_emitter.next().expect("the nominal emitter");
        // (diameter, centre) of the alternative minus the nominal.
        let compare = |alt: &[Option<[f64; 3]>]| -> Option<(f64, Vector3<f64>)> {
            let (mut pa, mut pb) = (Vec::new(), Vec::new());
            for ((&i, a), b) in sub.iter().zip(&nominal).zip(alt) {
                if let (Some(a), Some(b)) = (a, b) {
                    let p = points.points_mm[i];
                    pa.push([p[0] - a[0], p[1] - a[1], p[2] - a[2]]);
                    pb.push([p[0] - b[0], p[1] - b[1], p[2] - b[2]]);
                }
            }
            let fa = fit_sphere(&pa, sens_opts).ok()?;
            let fb = fit_sphere(&pb, sens_opts).ok()?;
            Some((fb.diameter_mm - fa.diameter_mm, fb.center_mm - fa.center_mm))
        };
        // The systematic parts, signed, one per source ([`systematic`]).
        let mut parts = Vec::new();
        for k in 0..2u32 {
            let plus = compare(&by_emitter.next().expect("plus end"));
            let minus = compare(&by_emitter.next().expect("minus end"));
            parts.extend(match emitter_estimate {
                // Assumed: the two ends of +-range along each axis.
                None => assumed_emitter_part(k, plus, minus),
                // Estimated: +-1 standard uncertainty along each axis.
                Some(_) => estimate_part(k, plus, minus),
            });
        }
        // Sheet and PSF sigmas: +-1 standard uncertainty each.
        for (k, (ds, dp)) in [(sheet.sheet_sigma_sd_mm, 0.0), (0.0, sheet.psf_sigma_sd_px)]
            .into_iter()
            .enumerate()
        {
            if ds == 0.0 && dp == 0.0 {
                continue;
            }
            let a = compare(&corr_sub(rig, sigma + ds, psf + dp));
            let b = compare(&corr_sub(rig, (sigma - ds).max(1e-6), (psf - dp).max(0.0)));
            parts.extend(estimate_part(2 + k as u32, a, b));
        }
        parts
    }
}

/// How far the sphere `b` lies from `a` (both `(centre, radius)`): the larger of the
/// diameter's and the centre's change, mm.
fn sphere_move(a: &(Vector3<f64>, f64), b: &(Vector3<f64>, f64)) -> f64 {
    (2.0 * (b.1 - a.1)).abs().max((b.0 - a.0).norm())
}

/// The points within [`CANDIDATE_SIGMAS`] robust sigmas of the uncorrected sphere (at least
/// its inliers).
fn candidates(points: &[[f64; 3]], fit: &SphereFitResult) -> Vec<usize> {
    let lim = CANDIDATE_SIGMAS * fit.robust_sigma_mm;
    let r = 0.5 * fit.diameter_mm;
    (0..points.len())
        .filter(|&i| {
            fit.inlier[i] || ((Vector3::from(points[i]) - fit.center_mm).norm() - r).abs() <= lim
        })
        .collect()
}

/// What an error adds when points were left out as saturated.
fn saturated_hint(saturated: usize) -> String {
    if saturated == 0 {
        return String::new();
    }
    format!(
        " ({saturated} points left out as saturated: the model has no clipping; lower the \
         laser power or the exposure)"
    )
}
