//! The quality gates (DECISIONS 1): a calibration that is not trustworthy is an error,
//! not a warning.
//!
//! | gate         | fails when                                                          |
//! |--------------|---------------------------------------------------------------------|
//! | `pairing`    | views whose robot pose does not fit their image cannot be left out  |
//! |              | ([`super::pairing`]); no consensus at all is an error before this   |
//! | `views`      | views whose residuals in the adjustment are far above the others'   |
//! |              | and the detector's cannot be left out ([`view_residuals`])          |
//! | `determined` | an estimated number's one-sigma is NaN, or above 5 % of its natural |
//! |              | scale ([`determined`])                                              |
//! | `converged`  | the adjustment stopped at its iteration limit                       |
//! | `board_scale`| the board scale the robot implies is more than 5 honest sigmas and  |
//! |              | the tolerance off rig.json's (DECISIONS 5; [`super::board_scale`])   |
//!
//! Every limit comes from the data: residuals against the median view's and against the
//! detector's own scatter (the camera stage's residual with free board poses); pose
//! disagreement against the agreeing views' scatter. A robot that is off everywhere
//! raises every view alike: that is robot-pose noise, reported, not failed.
//!
//! A failed gate makes the calibration an [`Error::Quality`] carrying it for inspection;
//! with [`CalibrateOptions::accept_poor`] it is returned instead, marked
//! `quality.accepted_poor`. Either way `quality.checks` lists every gate's verdict.

use super::pairing::{enough_left, name_views};
use super::{CalibrateOptions, CalibrationReport, Method};
use crate::calib::joint::JointResult;
use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::{QualityCheck, QualityFailure, RobotPoseView, ROBOT_POSE_TEST_LIMIT};
use crate::numerics::lm::StopReason;
use crate::numerics::robust::median;

/// A number is undetermined when its one-sigma exceeds this fraction of its natural
/// scale (focal length, image size, stand-off, one radian).
pub const UNDETERMINED_FRACTION: f64 = 0.05;

/// A view's circle residual RMS disagrees when above this many times both the median
/// view's and the detector's (the camera stage's RMS with free board poses).
pub const VIEW_RESIDUAL_FACTOR: f64 = 8.0;

/// The `views` gate's suspects: views whose circle residual RMS in the adjustment is
/// above [`VIEW_RESIDUAL_FACTOR`] times the median view's and the detector's RMS
/// `detector_rms_px` (dataset rows, and the message).
pub(super) fn view_residuals(adj: &JointResult, detector_rms_px: f64) -> (Vec<usize>, String) {
    let mut rms: Vec<f64> = adj
        .views
        .iter()
        .map(|v| v.circle_rms_px)
        .filter(|x| x.is_finite())
        .collect();
    let med = median(&mut rms).unwrap_or(0.0);
    let limit = VIEW_RESIDUAL_FACTOR * med.max(detector_rms_px);
    let bad: Vec<usize> = adj
        .views
        .iter()
        .filter(|v| v.circle_rms_px.is_finite() && v.circle_rms_px > limit)
        .map(|v| v.view)
        .collect();
    let figs: Vec<String> = adj
        .views
        .iter()
        .filter(|v| bad.contains(&v.view))
        .map(|v| format!("view {} {:.3} px", v.view, v.circle_rms_px))
        .collect();
    let msg = if bad.is_empty() {
        format!(
            "every view's circle residual is within {limit:.4} px RMS ({VIEW_RESIDUAL_FACTOR} \
             x the median view's {med:.4} px and the detector's {detector_rms_px:.4} px)"
        )
    } else {
        format!(
            "{} far above the others ({}; limit {limit:.4} px = {VIEW_RESIDUAL_FACTOR} x the \
             median view's {med:.4} px and the detector's {detector_rms_px:.4} px RMS with \
             free board poses)",
            name_views(&bad),
            figs.join(", ")
        )
    };
    (bad, msg)
}

/// The views whose robot-pose test exceeds [`ROBOT_POSE_TEST_LIMIT`] (a pose off by far
/// more than the others': DECISIONS 1), with the message naming them and their figures;
/// none without the robot-pose noise, and none when both robot components sit at their
/// floors (no robot error beyond what the views resolve: on exact observations the test
/// compares round-off with round-off). A view's correction must also exceed three times
/// a floor (translation or rotation) to be off.
pub(super) fn pose_outliers(adj: &JointResult) -> (Vec<RobotPoseView>, String) {
    let Some(n) = &adj.robot_noise else {
        return (Vec::new(), String::new());
    };
    if n.translation_at_floor && n.rotation_at_floor {
        return (Vec::new(), String::new());
    }
    let bad: Vec<RobotPoseView> = n
        .views
        .iter()
        .filter(|v| {
            v.test > ROBOT_POSE_TEST_LIMIT
                && (v.translation_mm > 3.0 * n.floor_translation_mm
                    || v.rotation_deg > 3.0 * n.floor_rotation_deg)
        })
        .copied()
        .collect();
    let figs: Vec<String> = bad
        .iter()
        .map(|v| {
            format!(
                "view {} corrected by {:.3} mm, {:.4} deg, test {:.1}",
                v.view, v.translation_mm, v.rotation_deg, v.test
            )
        })
        .collect();
    let views: Vec<usize> = bad.iter().map(|v| v.view).collect();
    let msg = format!(
        "the robot pose of {} is off by far more than the others' (robot-pose noise {:.3} mm, \
         {:.4} deg; {}; limit {ROBOT_POSE_TEST_LIMIT})",
        name_views(&views),
        n.sigma_translation_mm,
        n.sigma_rotation_deg,
        figs.join(", ")
    );
    (bad, msg)
}

/// The `views` gate's verdict for `suspects` among `total` views, `dropped` whether they
/// were left out.
pub(super) fn views_check(
    suspects: &[usize],
    msg: &str,
    kept: usize,
    total: usize,
) -> QualityCheck {
    if suspects.is_empty() {
        return QualityCheck::pass("views", msg);
    }
    if enough_left(kept, total) {
        return QualityCheck {
            name: "views".into(),
            passed: true,
            message: format!("left out: {msg}; {kept} of {total} views remain"),
            views: suspects.to_vec(),
        };
    }
    QualityCheck::fail(
        "views",
        format!(
            "{msg}; only {kept} of {total} views would remain without them, too few (at least \
             4 and two thirds)"
        ),
        suspects.to_vec(),
    )
}

/// The `determined` gate: every estimated number's one-sigma is finite and at most
/// [`UNDETERMINED_FRACTION`] of its natural scale: focal lengths of themselves, the
/// principal point of the image size, the plane offset of itself, unit normals and
/// rotation vectors of one radian, translations of the stand-off `standoff_mm` (when
/// known), the board scale of 1.
pub fn determined(adj: &JointResult, camera: &Camera, standoff_mm: Option<f64>) -> QualityCheck {
    let f = UNDETERMINED_FRACTION;
    let s = &adj.sigma;
    let mut bad: Vec<String> = adj
        .unobservable
        .iter()
        .map(|n| format!("{n} (no sigma: not observable)"))
        .collect();
    let mut test = |name: &str, sigma: f64, scale: f64| {
        if !sigma.is_finite() || sigma > f * scale {
            bad.push(format!("{name} +- {sigma:.4e} (limit {:.4e})", f * scale));
        }
    };
    if adj.free.camera {
        test("fu", s.camera[0], camera.fu);
        test("fv", s.camera[1], camera.fv);
        test("u0", s.camera[2], camera.width as f64);
        test("v0", s.camera[3], camera.height as f64);
    }
    if adj.free.laser_plane {
        if let Some(p) = &adj.plane {
            for k in 0..3 {
                test(&format!("laser_plane.normal[{k}]"), s.plane_normal[k], 1.0);
            }
            test("laser_plane.d_mm", s.plane_d_mm, p.d);
        }
    }
    for (name, free, t) in [
        ("hand_cam", adj.free.hand_cam, &s.hand_cam),
        ("base_board", adj.free.base_board, &s.base_board),
    ] {
        if !free {
            continue;
        }
        for k in 0..3 {
            test(
                &format!("{name}.rotation_vector[{k}]"),
                t.rotation_vector[k],
                1.0,
            );
            if let Some(d) = standoff_mm {
                test(
                    &format!("{name}.translation_mm[{k}]"),
                    t.translation_mm[k],
                    d,
                );
            }
        }
    }
    if adj.free.board_scale {
        test("board_scale", s.board_scale, 1.0);
    }
    if bad.is_empty() {
        QualityCheck::pass(
            "determined",
            format!(
                "every estimated number's one-sigma is within {:.0} % of its scale",
                100.0 * f
            ),
        )
    } else {
        QualityCheck::fail(
            "determined",
            format!(
                "undetermined by these views: {}; add views with more varied orientations \
                 (tilts of 20-45 deg about both board axes, several distances), or hold the \
                 block from an earlier calibration (--from FILE --fix BLOCK)",
                bad.join(", ")
            ),
            Vec::new(),
        )
    }
}

/// The `converged` gate (the one-stage adjustment only: the paper's method evaluates
/// its stages without iterating).
pub fn converged(adj: &JointResult, method: Method) -> QualityCheck {
    if method == Method::OneStage && adj.stop_reason == StopReason::MaxIterations {
        return QualityCheck::fail(
            "converged",
            format!(
                "the adjustment did not converge in {} iterations",
                adj.iterations
            ),
            Vec::new(),
        );
    }
    QualityCheck::pass(
        "converged",
        format!("converged in {} iterations", adj.iterations),
    )
}

/// Applies the gates: records every verdict in `quality.checks`; a failed one makes the
/// calibration an [`Error::Quality`] unless `opts.accept_poor` (then it is returned
/// marked `quality.accepted_poor`).
pub(in crate::pipeline) fn judge(
    mut rep: CalibrationReport,
    checks: Vec<QualityCheck>,
    opts: &CalibrateOptions,
) -> Result<CalibrationReport> {
    let failed: Vec<QualityCheck> = checks.iter().filter(|c| !c.passed).cloned().collect();
    rep.calibration.quality.checks = checks;
    if failed.is_empty() {
        return Ok(rep);
    }
    if opts.accept_poor {
        rep.calibration.quality.accepted_poor = true;
        return Ok(rep);
    }
    Err(Error::Quality(Box::new(QualityFailure::with_inspection(
        failed, rep,
    ))))
}
