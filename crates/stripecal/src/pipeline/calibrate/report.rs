//! The last stage: the calibration and its typed records (uncertainty, per-view records,
//! the adjustment summary) from the stages' results. JSON is the io layer's job.

use super::held::Held;
use super::{CalibrateOptions, CalibrationReport, Method, Stages, ViewStatus};
use crate::calib::axzb::AxzbSolution;
use crate::calib::camera::CameraCalibration;
use crate::calib::joint::{JointResult, JointStart};
use crate::calib::laser_plane::LaserPlaneFit;
use crate::io::{robot_uncertainty, uncertainty_to_json};
use crate::model::{
    AdjustmentSummary, BoardScaleCheck, Calibration, CalibrationRecords, CameraSigma, LeaveOneOut,
    Mount, PlaneSigma, PoseSigma, Quality, Rig, Uncertainty, ViewRecord,
};

/// What the calibration says about itself (see [`super::stages::self_checks`]).
#[derive(Debug, Clone, Default)]
pub(super) struct SelfChecks {
    pub board_scale: Option<BoardScaleCheck>,
    pub leave_one_out: Option<LeaveOneOut>,
}

/// What the stages produced.
pub(super) struct Stage<'a> {
    pub camera: Option<CameraCalibration>,
    pub plane: Option<LaserPlaneFit>,
    pub axzb: Option<AxzbSolution>,
    /// The adjustment's starting values (the paper's result).
    pub start: JointStart,
    pub adjustment: JointResult,
    /// `Some("first view")` when the first view's labelling fixed the board frame.
    pub frame_note: Option<String>,
    pub views_used: usize,
    pub checks: SelfChecks,
    /// The blocks held from `--from`.
    pub held: Option<&'a Held<'a>>,
    /// The stripe's bias on the board: `None` when not attempted (switched off, the
    /// paper's method, no laser plane); `Err` with the reason when the model did not
    /// apply.
    pub board_stripe:
        Option<std::result::Result<super::board_stripe::BoardStripeCorrection, String>>,
}

/// The one-sigmas of the estimated blocks: the adjustment's covariance for the
/// one-stage method; the camera calibration's and the plane fit's for the paper's.
fn uncertainty(st: &Stage<'_>, method: Method) -> Uncertainty {
    match method {
        Method::OneStage => {
            let s = &st.adjustment.sigma;
            let free = &st.adjustment.free;
            let pose = |t: &crate::calib::joint::TransformSigma| PoseSigma {
                rotation_vector: t.rotation_vector.into(),
                translation_mm: t.translation_mm.into(),
            };
            Uncertainty {
                camera: free.camera.then(|| CameraSigma::from_params(&s.camera)),
                laser_plane: free.laser_plane.then(|| PlaneSigma {
                    normal: s.plane_normal.into(),
                    d_mm: s.plane_d_mm,
                }),
                hand_cam: free.hand_cam.then(|| pose(&s.hand_cam)),
                base_board: free.base_board.then(|| pose(&s.base_board)),
            }
        }
        Method::Paper => Uncertainty {
            camera: st
                .camera
                .as_ref()
                .map(|c| CameraSigma::from_params(&c.camera_sigma)),
            laser_plane: st.plane.as_ref().map(|p| PlaneSigma {
                normal: p.sigma.normal.into(),
                d_mm: p.sigma.d_mm,
            }),
            hand_cam: None,
            base_board: None,
        },
    }
}

/// calibration.json's `views` entries: each view's status with its adjustment figures.
fn view_records(status: &[ViewStatus], adj: &JointResult) -> Vec<ViewRecord> {
    let figures: Vec<(usize, f64, f64, bool)> = adj
        .views
        .iter()
        .map(|r| (r.view, r.circle_rms_px, r.stripe_rms_px, r.outlier))
        .collect();
    view_records_from(status, &figures)
}

/// [`view_records`] from per-view `(view, circle rms px, stripe rms px, outlier)`; a
/// non-finite figure is `None`.
pub(super) fn view_records_from(
    status: &[ViewStatus],
    figures: &[(usize, f64, f64, bool)],
) -> Vec<ViewRecord> {
    let finite = |x: f64| x.is_finite().then_some(x);
    status
        .iter()
        .map(|s| {
            let r = figures.iter().find(|r| r.0 == s.view);
            ViewRecord {
                view: s.view,
                used: s.used,
                circles: s.circles,
                stripe_points: s.stripe_used,
                stripe_off_plane: s.stripe_off_plane,
                circle_rms_px: r.and_then(|r| finite(r.1)),
                stripe_rms_px: r.and_then(|r| finite(r.2)),
                outlier: r.map(|r| r.3),
                note: s.note.clone(),
                stripe_extraction: s.stripe_extraction,
            }
        })
        .collect()
}

/// The report: the calibration (the adjusted values, or the paper's stages' values)
/// with its records, and the stages.
pub(super) fn build_report(
    st: Stage<'_>,
    rig: &Rig,
    opts: &CalibrateOptions,
    status: Vec<ViewStatus>,
    warnings: Vec<String>,
) -> CalibrationReport {
    let adj = &st.adjustment;
    let (camera, laser_plane, hand_cam, base_board) = match opts.method {
        Method::Paper => (
            st.start.camera.clone(),
            st.start.plane,
            st.start.hand_cam,
            st.start.base_board,
        ),
        Method::OneStage => (adj.camera.clone(), adj.plane, adj.hand_cam, adj.base_board),
    };
    let summary = AdjustmentSummary {
        method: opts.method.name().into(),
        centre_model: opts.centre_model.name().into(),
        base_board_orientation: st.frame_note.clone(),
        stripe_rms_mm: adj.stripe_rms_mm,
        residual_sigma_px: adj.sigma_px,
        stripe_off_plane: status.iter().map(|s| s.stripe_off_plane).sum(),
    };
    let records = view_records(&status, adj);
    let mut unc = uncertainty_to_json(&uncertainty(&st, opts.method));
    let mut extra = serde_json::Map::new();
    let mut recs = CalibrationRecords {
        summary: Some(summary.clone()),
        views: Some(records.clone()),
        warnings: warnings.clone(),
        board_scale: st.checks.board_scale.clone(),
        leave_one_out: st.checks.leave_one_out.clone(),
        ..Default::default()
    };
    match &st.board_stripe {
        Some(Ok(c)) => {
            extra.insert("board_stripe_bias".into(), board_stripe_extra(c));
        }
        Some(Err(why)) => {
            extra.insert(
                "board_stripe_bias".into(),
                serde_json::json!({"applied": false, "reason": why}),
            );
        }
        None => {}
    }
    if let (Method::OneStage, Some(n)) = (opts.method, &adj.robot_noise) {
        recs.robot_pose_noise = Some(n.clone());
    }
    let refined = match (opts.method, &adj.robot) {
        (Method::OneStage, Some(rc)) => {
            recs.robot_calibration = Some(rc.clone());
            if !rc.estimated.is_empty() {
                unc.insert("robot".into(), robot_uncertainty(rc));
            }
            Some(rc.robot.clone())
        }
        _ => None,
    };
    let covariance = match (opts.method, st.held) {
        (Method::Paper, _) => None,
        (Method::OneStage, None) => Some(adj.named_covariance.clone()),
        (Method::OneStage, Some(h)) => {
            h.add_uncertainty(&mut unc);
            recs.held_blocks = Some(h.names().iter().map(|n| n.to_string()).collect());
            h.covariance(&adj.named_covariance)
        }
    };
    let robot = refined.or_else(|| {
        rig.robot
            .clone()
            .or_else(|| st.held.and_then(|h| h.from.robot.clone()))
    });
    let calibration = Calibration {
        camera,
        laser_plane,
        mount: Mount::Robot,
        hand_cam,
        base_board,
        robot,
        quality: Quality {
            circle_rms_px: adj.circle_rms_px,
            stripe_rms_px: if adj.stripe_rms_px.is_finite() {
                adj.stripe_rms_px
            } else {
                0.0
            },
            views_used: st.views_used,
            ..Default::default()
        },
        uncertainty: unc,
        covariance,
        records: recs,
        extra,
    };
    CalibrationReport {
        calibration,
        method: opts.method,
        summary,
        records,
        board_scale: st.checks.board_scale,
        leave_one_out: st.checks.leave_one_out,
        stages: Stages {
            camera: st.camera,
            plane: st.plane,
            axzb: st.axzb,
        },
        adjustment: st.adjustment,
        views: status,
        warnings,
    }
}

/// calibration.json's `board_stripe_bias`: what the correction of the stripe's bias on
/// the board did ([`super::board_stripe`]).
fn board_stripe_extra(c: &super::board_stripe::BoardStripeCorrection) -> serde_json::Value {
    let mut v = serde_json::json!({
        "applied": true,
        "sheet_sigma_mm": c.sheet_sigma_mm,
        "psf_sigma_px": c.psf_sigma_px,
        "points_corrected": c.corrected,
        "points_left_out": c.dropped,
        "points_saturated": c.saturated,
        "mean_px": c.mean_px,
        "rms_px": c.rms_px,
        "neglected_share": c.neglected_share,
        "emitter_range_mm": c.emitter_range_mm,
    });
    if let Some(r) = &c.emitter_response {
        v["emitter_response"] = r.to_json();
    }
    v
}
