//! A profiler calibration's record: the numbers, their one-sigmas and the figures the
//! calibration reports about itself (views, mirror test, diameter check, leave-one-out:
//! its [`ProfilerRecords`]), as calibration.json writes them.

use serde_json::{json, Map, Value};

use super::checks::{centres_in_sensor, DiameterCheck, MirrorTest};
use super::loo::ProfileLoo;
use super::ProfileViewStatus;
use crate::calib::joint::profile::{ProfileFit, ProfileViewObs};
use crate::io::robot_uncertainty;
use crate::model::{
    DiameterCheckRecord, MirrorRecord, ProfileRig, ProfilerAdjustmentRecord, ProfilerCalibration,
    ProfilerLooRecord, ProfilerLooView, ProfilerQuality, ProfilerRecords, ProfilerViewRecord,
    QualityCheck,
};

/// A number, `null` when not finite (`Value::from` does that).
fn num(x: f64) -> Value {
    Value::from(x)
}

/// Fills each view's figures from the fit (`obs` the views used, in the fit's order).
pub(super) fn fill_status(
    status: &mut [ProfileViewStatus],
    obs: &[ProfileViewObs],
    fit: &ProfileFit,
) {
    let centres = centres_in_sensor(fit);
    for (k, o) in obs.iter().enumerate() {
        if let Some(s) = status.iter_mut().find(|s| s.view == o.view) {
            s.used = true;
            s.note = None;
            s.sphere_points = fit.selected[k].len();
            s.rejected = s.points - s.sphere_points;
            s.rms_mm = Some(fit.view_rms_mm[k]);
            s.centre_in_sensor = Some(centres[k]);
            s.side = Some(if centres[k].y < 0.0 { -1.0 } else { 1.0 });
        }
    }
}

/// What a profiler calibration reports about itself besides its gates' checks: the
/// mirror test, the diameter check and the leave-one-view-out figure.
pub(super) struct SelfChecks<'a> {
    pub mirror: &'a MirrorTest,
    pub diameter: Option<&'a DiameterCheck>,
    pub loo: Option<&'a ProfileLoo>,
}

/// The calibration.json record of a profiler (module docs).
pub(super) fn calibration(
    rig: &ProfileRig,
    fit: &ProfileFit,
    status: &[ProfileViewStatus],
    checks: &[QualityCheck],
    self_checks: SelfChecks<'_>,
    warnings: &[String],
    accepted_poor: bool,
) -> ProfilerCalibration {
    let SelfChecks {
        mirror,
        diameter,
        loo,
    } = self_checks;
    let cov = &fit.covariance;
    let sd = |n: &str| cov.sigma(n).unwrap_or(0.0);
    let v3 = |p: &str| Value::Array((0..3).map(|k| num(sd(&format!("{p}[{k}]")))).collect());
    let mut u = Map::new();
    u.insert(
        "hand_cam".into(),
        json!({"rotation_vector": v3("hand_cam.rotation_vector"),
               "translation_mm": v3("hand_cam.translation_mm")}),
    );
    let mut sphere = Map::new();
    sphere.insert("center_mm".into(), v3("sphere.center_mm"));
    if cov.index("sphere.diameter_mm").is_some() {
        sphere.insert("diameter_mm".into(), num(sd("sphere.diameter_mm")));
    }
    u.insert("sphere".into(), Value::Object(sphere));
    if let Some(rc) = &fit.robot {
        u.insert("robot".into(), robot_uncertainty(rc));
    }
    let views = status
        .iter()
        .map(|s| ProfilerViewRecord {
            view: s.view,
            line: s.line,
            profile: s.file.clone(),
            used: s.used,
            points: s.points,
            gaps: s.gaps,
            arc_points: s.arc_points,
            sphere_points: s.sphere_points,
            rejected: s.rejected,
            rms_mm: s.rms_mm,
            side: s.side,
            centre_in_sensor_mm: s.centre_in_sensor.map(|c| [c.x, c.y, c.z]),
            note: s.note.clone(),
        })
        .collect();
    let records = ProfilerRecords {
        robot_calibration: fit.robot.clone(),
        sphere_diameter_estimated: Some(rig.diameter_mm.is_none()),
        adjustment: Some(ProfilerAdjustmentRecord {
            sigma_mm: fit.sigma_mm,
            points_used: fit.points_used(),
            iterations: fit.iterations,
            view_variance_factor: fit.view_variance_factor,
        }),
        views: Some(views),
        mirror: Some(MirrorRecord {
            ssr_chosen_mm2: mirror.ssr_chosen_mm2,
            ssr_mirror_mm2: mirror.ssr_mirror_mm2,
            delta_chi2: mirror.delta_chi2,
            passed: mirror.passed,
            centre_spread_mm: mirror.spread_mm,
        }),
        diameter_check: diameter.map(|d| DiameterCheckRecord {
            declared_mm: d.declared_mm,
            estimate_mm: d.estimate_mm,
            sigma_mm: d.sigma_mm,
            disagrees: d.disagrees,
        }),
        leave_one_out: loo.map(|l| ProfilerLooRecord {
            median_rms_mm: l.median_rms_mm,
            views: l
                .views
                .iter()
                .map(|v| ProfilerLooView {
                    view: v.view,
                    points: v.points,
                    rms_mm: v.rms_mm,
                    disagrees: v.disagrees,
                })
                .collect(),
        }),
        warnings: warnings.to_vec(),
    };
    ProfilerCalibration {
        hand_sensor: fit.hand_sensor,
        robot: fit
            .robot
            .as_ref()
            .map(|r| r.robot.clone())
            .or_else(|| rig.robot.clone()),
        sphere_center_mm: fit.centre,
        sphere_diameter_mm: fit.diameter,
        quality: ProfilerQuality {
            profile_rms_mm: fit.rms_mm(),
            views_used: fit.selected.len(),
            checks: checks.to_vec(),
            accepted_poor,
        },
        uncertainty: u,
        covariance: Some(fit.covariance.clone()),
        records,
        extra: Map::new(),
    }
}
