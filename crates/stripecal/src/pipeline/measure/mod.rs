//! Measuring a reconstructed scan with full budgets: a sphere (the reference ball), two
//! spheres (a ball bar) or a plane, from the scan's points, the frames' robot readings
//! and the calibration ([`crate::reconstruct::fit::budget`] for the budgets).
//!
//! Spheres are fitted with the robust start, then (by default) corrected for the
//! curved-surface stripe bias ([`crate::reconstruct::fit::stripe_bias`]); what the
//! correction leaves goes into the budget's systematic part; the emitter it estimates
//! from the stripe's brightness is carried into the calibration's board correction
//! ([`super::emitter_carry`]: the values move to it, the calibration part loses the
//! assumed emitter's range; a ball bar's two estimates averaged). A ball bar's two spheres
//! are found one after the other: the first robust fit takes the sphere with more
//! points, its points (within a margin of its surface) are set aside, the second fit
//! takes the other.
//!
//! ## Profilers
//!
//! The same functions measure a line profiler's scan: a model from
//! [`UncertaintyModel::profiler`] (or [`profiler_uncertainty_model`]) and the points of
//! [`crate::reconstruct::profile_scan_points`]. The curved-surface stripe-bias correction
//! is the camera's (it models how a camera's stripe extraction shifts on a curved
//! surface); a profiler's extraction is its maker's and is not modelled, so for a
//! profiler's model [`MeasureOptions::correct_bias`] is ignored: no correction, no
//! systematic part, `bias: None` (`stripe_bias: null` in the JSON).

#[cfg(test)]
mod profiler_tests;
pub mod verify;

use nalgebra::{DMatrix, Vector3};
use serde_json::{json, Value};

use super::emitter_carry::{CarryInfo, EmitterResponse, EmitterSample};
use crate::error::{Error, Result};
use crate::model::{Calibration, ProfilerCalibration, RobotReading, Scan, StripeDirection};
use crate::reconstruct::fit::stripe_bias::{correct_sphere_bias, StripeBiasOptions};
use crate::reconstruct::fit::{
    assumed_emitter_source, fit_plane, fit_sphere, measure_plane, measure_sphere, new_source_id,
    sphere_distance, Budget, FitOptions, PlaneFit, PlaneMeasurement, ScanFrames, SphereFitResult,
    SphereMeasurement, SphereSystematic, SystematicKind, SystematicSource, MODEL_SOURCE,
};
use crate::reconstruct::{ScanPoints, UncertaintyModel, UncertaintyOptions};
use crate::stripe_model::plane_basis;

/// Options of a measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasureOptions {
    /// What goes into the points' uncertainty (calibration, stripe, robot figures).
    pub uncertainty: UncertaintyOptions,
    /// The fits (trimming, robust start, the accepted diameters of a sphere).
    pub fit: FitOptions,
    /// Correct spheres for the curved-surface stripe bias (default true). Ignored for a
    /// profiler's model (module docs, "Profilers").
    pub correct_bias: bool,
}

impl Default for MeasureOptions {
    fn default() -> Self {
        MeasureOptions {
            uncertainty: UncertaintyOptions::default(),
            fit: FitOptions::default(),
            correct_bias: true,
        }
    }
}

/// What the stripe-bias correction did to a sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasInfo {
    /// The laser sheet's Gaussian sigma (thickness) estimated from the stripe's width, mm.
    pub sheet_sigma_mm: f64,
    /// Diameter after minus before the correction, mm.
    pub diameter_change_mm: f64,
    /// The sphere's points left out of the corrected fit because their stripe is
    /// saturated (the model has no clipping).
    pub points_saturated: usize,
}

/// A measured sphere: the final fit and its budgets.
#[derive(Debug, Clone)]
pub struct SphereReport {
    pub fit: SphereFitResult,
    pub measurement: SphereMeasurement,
    /// `None` when the correction was not asked for.
    pub bias: Option<BiasInfo>,
    /// The emitter the correction estimated from the stripe's brightness (`None`:
    /// assumed, or no correction).
    pub emitter: Option<EmitterSample>,
    /// What carrying the emitter estimate into the calibration did
    /// ([`super::emitter_carry`]; `None`: no estimate, or a calibration without the
    /// board correction's response).
    pub calibration_emitter: Option<CarryInfo>,
}

/// A measured plane: the fit and its budgets.
#[derive(Debug, Clone)]
pub struct PlaneReport {
    pub fit: PlaneFit,
    pub measurement: PlaneMeasurement,
}

/// A measured ball bar: both spheres and their centres' distance.
#[derive(Debug, Clone)]
pub struct BallBarReport {
    pub spheres: [SphereReport; 2],
    pub distance: Budget,
}

/// The readings of a scan's frames, by frame index.
pub fn scan_readings(scan: &Scan) -> Vec<RobotReading> {
    scan.frames.iter().map(|f| f.reading.clone()).collect()
}

/// The model of the points' uncertainty for a scan: the stripe direction from the
/// scan's rig.json when the options leave it `Auto`, the robot's figures from the
/// calibration's robot where the options leave them unset, and the robot-pose noise the
/// calibration estimated where neither gives one
/// ([`UncertaintyOptions::with_pose_noise`]).
pub fn scan_uncertainty_model(
    calibration: &Calibration,
    scan: &Scan,
    opts: &UncertaintyOptions,
) -> Result<UncertaintyModel> {
    let mut o = opts
        .clone()
        .with_robot_figures(calibration.robot.as_ref())
        .with_pose_noise(calibration);
    if o.direction == StripeDirection::Auto {
        if let Some(rig) = &scan.rig {
            o.direction = rig.stripe_direction;
        }
    }
    UncertaintyModel::new(calibration, &o)
}

/// The model of a profiler's points' uncertainty ([`UncertaintyModel::profiler`]), the
/// robot's figures from the calibration's robot where the options leave them unset.
pub fn profiler_uncertainty_model(
    calibration: &ProfilerCalibration,
    opts: &UncertaintyOptions,
) -> Result<UncertaintyModel> {
    let o = opts.clone().with_robot_figures(calibration.robot.as_ref());
    UncertaintyModel::profiler(calibration, &o)
}

/// Measures the sphere in `points` (all of a scan's points, or a subset).
pub fn measure_scan_sphere(
    model: &UncertaintyModel,
    readings: &[RobotReading],
    points: &ScanPoints,
    opts: &MeasureOptions,
) -> Result<SphereReport> {
    let mut frames = ScanFrames::new(model, readings);
    let fit = fit_sphere(&points.points_mm, &opts.fit)?;
    let mut report = [sphere_report(
        &mut frames,
        model,
        readings,
        points,
        fit,
        opts,
    )?];
    carry_emitter(model, &mut report)?;
    let [report] = report;
    Ok(report)
}

fn sphere_report(
    frames: &mut ScanFrames<'_>,
    model: &UncertaintyModel,
    readings: &[RobotReading],
    points: &ScanPoints,
    fit: SphereFitResult,
    opts: &MeasureOptions,
) -> Result<SphereReport> {
    // A camera's bias model: a profiler's calibration has none (module docs).
    if let (true, Some(cal)) = (opts.correct_bias, model.calibration()) {
        let (fit, used, coords, systematic, info, emitter) =
            correct_bias(model, cal, readings, points, &opts.fit)?;
        let measurement = measure_sphere(frames, &used, &coords, &fit, &systematic)?;
        return Ok(SphereReport {
            fit,
            measurement,
            bias: Some(info),
            emitter,
            calibration_emitter: None,
        });
    }
    let measurement = measure_sphere(
        frames,
        points,
        &points.points_mm,
        &fit,
        &SphereSystematic::default(),
    )?;
    Ok(SphereReport {
        fit,
        measurement,
        bias: None,
        emitter: None,
        calibration_emitter: None,
    })
}

/// Carries the spheres' emitter estimates into the calibration
/// ([`super::emitter_carry`]): their mean (weighted by the floored variances; its
/// standard uncertainty the smallest of theirs, their errors being mostly shared) moves
/// every report's values and calibration parts. Returns the calibration's covariance the
/// reports now use (the model's where nothing was carried).
fn carry_emitter(model: &UncertaintyModel, reports: &mut [SphereReport]) -> Result<DMatrix<f64>> {
    let cov = model.covariance().clone();
    let Some(cal) = model.calibration() else {
        return Ok(cov);
    };
    let Some(response) = EmitterResponse::of(cal)? else {
        return Ok(cov);
    };
    let offsets: Vec<([f64; 2], [f64; 2])> = reports
        .iter()
        .filter_map(|r| r.emitter.as_ref())
        .map(|e| response.offsets(e))
        .collect();
    if offsets.is_empty() {
        return Ok(cov);
    }
    let mut x = [0.0; 2];
    let mut sd = [f64::INFINITY; 2];
    for k in 0..2 {
        let w: f64 = offsets.iter().map(|o| o.1[k].powi(-2)).sum();
        x[k] = offsets
            .iter()
            .map(|o| o.0[k] * o.1[k].powi(-2))
            .sum::<f64>()
            / w;
        sd[k] = offsets.iter().map(|o| o.1[k]).fold(f64::INFINITY, f64::min);
    }
    let carried = response.carry(cal, model.names(), &cov, x, sd);
    let info = CarryInfo {
        offset_mm: x,
        sd_mm: sd,
        reason: carried.as_ref().err().cloned(),
    };
    let out = match carried {
        Ok(c) => {
            for r in reports.iter_mut() {
                r.measurement.recalibrated(&c.shift, &c.covariance);
                let m = &r.measurement;
                r.fit.diameter_mm = m.diameter.value;
                r.fit.center_mm = Vector3::from_fn(|k, _| m.center[k].value);
            }
            c.covariance
        }
        Err(_) => cov,
    };
    for r in reports.iter_mut() {
        r.calibration_emitter = Some(info.clone());
    }
    Ok(out)
}

/// Measures the two spheres of a ball bar in `points` and their centres' distance.
/// `diameter_range_mm` (in `opts.fit`) should bracket both spheres' diameters.
pub fn measure_scan_ball_bar(
    model: &UncertaintyModel,
    readings: &[RobotReading],
    points: &ScanPoints,
    opts: &MeasureOptions,
) -> Result<BallBarReport> {
    let mut frames = ScanFrames::new(model, readings);
    let first = fit_sphere(&points.points_mm, &opts.fit)?;
    // Set aside everything near the first sphere (its inliers and the points within a
    // tenth of its radius of its surface), then find the second in the rest.
    let margin = 0.1 * 0.5 * first.diameter_mm;
    let near = |p: &[f64; 3]| {
        ((Vector3::from(*p) - first.center_mm).norm() - 0.5 * first.diameter_mm).abs() <= margin
    };
    let keep: Vec<usize> = (0..points.len())
        .filter(|&i| !first.inlier[i] && !near(&points.points_mm[i]))
        .collect();
    let rest = points.subset(&keep);
    if rest.len() < 20 {
        return Err(Error::Degenerate(format!(
            "ball bar: after the first sphere ({} points) only {} points are left for the \
             second",
            first.points,
            rest.len()
        )));
    }
    let second = fit_sphere(&rest.points_mm, &opts.fit)
        .map_err(|e| Error::Degenerate(format!("ball bar: the second sphere: {e}")))?;
    if (second.center_mm - first.center_mm).norm() < 0.5 * (first.diameter_mm + second.diameter_mm)
    {
        return Err(Error::Degenerate(format!(
            "ball bar: the two spheres found overlap (centres {:.3} mm apart, diameters \
             {:.3} and {:.3} mm): the scan does not show two separate spheres",
            (second.center_mm - first.center_mm).norm(),
            first.diameter_mm,
            second.diameter_mm
        )));
    }
    // The first sphere's own points only (so the second's do not pull it).
    let own: Vec<usize> = (0..points.len())
        .filter(|&i| near(&points.points_mm[i]))
        .collect();
    let mine = points.subset(&own);
    let first = fit_sphere(&mine.points_mm, &opts.fit)?;
    let a = sphere_report(&mut frames, model, readings, &mine, first, opts)?;
    let b = sphere_report(&mut frames, model, readings, &rest, second, opts)?;
    let mut spheres = [a, b];
    let cov = carry_emitter(model, &mut spheres)?;
    let (distance, _) = sphere_distance(&spheres[0].measurement, &spheres[1].measurement, &cov);
    Ok(BallBarReport { spheres, distance })
}

/// Measures the plane in `points`.
pub fn measure_scan_plane(
    model: &UncertaintyModel,
    readings: &[RobotReading],
    points: &ScanPoints,
    opts: &MeasureOptions,
) -> Result<PlaneReport> {
    let mut frames = ScanFrames::new(model, readings);
    let fit = fit_plane(&points.points_mm, &opts.fit)?;
    let measurement = measure_plane(&mut frames, points, &points.points_mm, &fit)?;
    Ok(PlaneReport { fit, measurement })
}

/// The curved-surface stripe bias correction of a sphere fit
/// ([`crate::reconstruct::fit::stripe_bias`]) of the sphere's points: the corrected fit,
/// the points it corrected (the modelled ones; the fit's inlier mask keeps its trimmed
/// ones) with their corrected coordinates, the
/// systematic part it leaves and what it did.
fn correct_bias(
    model: &UncertaintyModel,
    cal: &Calibration,
    readings: &[RobotReading],
    points: &ScanPoints,
    opts: &FitOptions,
) -> Result<BiasCorrected> {
    let plane = crate::reconstruct::laser_plane_of(cal)?;
    let base_cam = readings
        .iter()
        .map(|r| Ok(r.base_hand(cal.robot.as_ref())? * cal.hand_cam))
        .collect::<Result<Vec<_>>>()?;
    // All the sphere's points: the correction picks the ones it corrects and fits
    // itself, by the corrected residuals (a choice by the uncorrected fit's trimming
    // would keep the points whose noise hides their bias: module docs of
    // `stripe_bias`, "Which points are fitted").
    let sphere_pts = points;
    let mut o = StripeBiasOptions {
        fit: *opts,
        ..Default::default()
    };
    o.stripe.direction = model.direction();
    let c = correct_sphere_bias(sphere_pts, &base_cam, &cal.camera, plane, &o).map_err(|e| {
        let hint = "measure without it: correct_bias=False / --no-bias-correction";
        match e {
            Error::Degenerate(m) => {
                Error::Degenerate(format!("stripe-bias correction: {m} ({hint})"))
            }
            Error::InvalidInput(m) => {
                Error::InvalidInput(format!("stripe-bias correction: {m} ({hint})"))
            }
            other => other,
        }
    })?;
    // The modelled points, in order: the corrected fit's inlier mask is over them.
    let used: Vec<usize> = (0..sphere_pts.len()).filter(|&i| c.modelled[i]).collect();
    let kept = sphere_pts.subset(&used);
    let coords: Vec<[f64; 3]> = used
        .iter()
        .map(|&i| {
            let (p, d) = (sphere_pts.points_mm[i], c.corrections_mm[i]);
            [p[0] - d[0], p[1] - d[1], p[2] - d[2]]
        })
        .collect();
    // Each part a unit source shared as its cause is ([`SystematicKind`]): the model's
    // error and an assumed emitter with every sphere, this scan's estimates with none.
    let own = new_source_id();
    let systematic = SphereSystematic {
        parts: c
            .systematic_parts
            .iter()
            .map(|p| SystematicSource {
                source: match p.kind {
                    SystematicKind::Model => MODEL_SOURCE,
                    SystematicKind::AssumedEmitter(k) => assumed_emitter_source(k),
                    SystematicKind::Estimate(k) => (own, 3, k),
                },
                center_mm: p.center_mm.into(),
                diameter_mm: p.diameter_mm,
            })
            .collect(),
    };
    let info = BiasInfo {
        sheet_sigma_mm: c.sheet.sheet_sigma_mm,
        diameter_change_mm: c.diameter_change_mm,
        points_saturated: c.saturated,
    };
    let emitter = c.emitter_estimate.map(|e| {
        let (e1, e2) = plane_basis(&plane.normal);
        EmitterSample {
            emitter_cam_mm: e.emitter_cam_mm,
            sd_mm: e.sd_mm,
            basis: [e1, e2],
        }
    });
    Ok((c.fit, kept, coords, systematic, info, emitter))
}

/// A corrected fit, the points it used, their corrected coordinates, the systematic
/// part, what the correction did and its emitter estimate ([`SphereReport::emitter`]).
type BiasCorrected = (
    SphereFitResult,
    ScanPoints,
    Vec<[f64; 3]>,
    SphereSystematic,
    BiasInfo,
    Option<EmitterSample>,
);

/// A budget as JSON: `value_mm`, `expanded_mm` (the headline, `k` = 2), `k`,
/// `combined_mm` and the parts `random_mm`, `calibration_mm`, `robot_mm`,
/// `systematic_mm` (standard uncertainties).
pub fn budget_to_json(b: &Budget) -> Value {
    json!({"value_mm": b.value, "expanded_mm": b.expanded, "k": b.k, "combined_mm": b.combined,
           "random_mm": b.random, "calibration_mm": b.calibration, "robot_mm": b.robot,
           "systematic_mm": b.systematic})
}

impl SphereReport {
    /// The spec's sphere-fit record of the final fit plus `uncertainty` (the budgets of
    /// `diameter`, `center` [x, y, z] and `form`) and `stripe_bias`
    /// (`sheet_sigma_mm`, `diameter_change_mm`, `points_saturated`; null without the
    /// correction) and `calibration_emitter` (the emitter estimate carried into the
    /// calibration: `offset_mm`, `sd_mm`, `applied`, `reason`; null when there was
    /// none to carry).
    pub fn to_json(&self) -> Value {
        let m = &self.measurement;
        let bias = match &self.bias {
            Some(b) => json!({"sheet_sigma_mm": b.sheet_sigma_mm,
                              "diameter_change_mm": b.diameter_change_mm,
                              "points_saturated": b.points_saturated}),
            None => Value::Null,
        };
        let c = self.fit.center_mm;
        let carried = self
            .calibration_emitter
            .as_ref()
            .map_or(Value::Null, CarryInfo::to_json);
        json!({"diameter_mm": self.fit.diameter_mm, "center_mm": [c.x, c.y, c.z],
               "rms_mm": self.fit.rms_mm, "points": self.fit.points, "outliers": self.fit.outliers,
               "uncertainty": {"diameter": budget_to_json(&m.diameter),
                               "center": m.center.iter().map(budget_to_json).collect::<Vec<_>>(),
                               "form": budget_to_json(&m.form)},
               "stripe_bias": bias, "calibration_emitter": carried})
    }
}

impl PlaneReport {
    /// The plane (`normal`, `d_mm`), `rms_mm`, `flatness_mm`, `points`, `outliers` and
    /// `uncertainty` (budgets of `flatness`, `offset` and the two `tilt_deg`).
    pub fn to_json(&self) -> Value {
        let n = self.fit.plane.normal;
        let m = &self.measurement;
        json!({"normal": [n.x, n.y, n.z], "d_mm": self.fit.plane.d, "rms_mm": self.fit.rms_mm,
               "flatness_mm": self.fit.flatness_mm, "points": self.fit.points,
               "outliers": self.fit.outliers,
               "uncertainty": {"flatness": budget_to_json(&m.flatness),
                               "offset": budget_to_json(&m.offset),
                               "tilt_deg": m.tilt_deg.iter().map(budget_to_json).collect::<Vec<_>>()}})
    }
}

impl BallBarReport {
    /// Both spheres ([`SphereReport::to_json`]) and the `distance` budget.
    pub fn to_json(&self) -> Value {
        json!({"spheres": [self.spheres[0].to_json(), self.spheres[1].to_json()],
               "distance": budget_to_json(&self.distance)})
    }
}
