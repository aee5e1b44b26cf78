//! The last stage: the calibration and its typed records (uncertainty, per-view records,
//! the adjustment summary) from the stages' results. JSON is the io layer's job.

use super::{CalibrateOptions, CalibrationReport, Method, Stages, ViewStatus};
use crate::calib::axzb::AxzbSolution;
use crate::calib::camera::CameraCalibration;
use crate::calib::joint::{JointResult, JointStart};
use crate::calib::laser_plane::LaserPlaneFit;
use crate::io::{calibration_extra, uncertainty_to_json};
use crate::model::{
    AdjustmentSummary, Calibration, CameraSigma, PlaneSigma, PoseSigma, Quality, Rig, Uncertainty,
    ViewRecord,
};

/// What the stages produced.
pub(super) struct Stage {
    pub camera: CameraCalibration,
    pub plane: LaserPlaneFit,
    pub axzb: AxzbSolution,
    /// The adjustment's starting values (the paper's result).
    pub start: JointStart,
    pub adjustment: JointResult,
    /// `Some("first view")` when the first view's labelling fixed the board frame.
    pub frame_note: Option<String>,
    pub views_used: usize,
}

/// The one-sigmas: the adjustment's covariance for the one-stage method; the camera
/// calibration's and the plane fit's for the paper's.
fn uncertainty(st: &Stage, method: Method) -> Uncertainty {
    match method {
        Method::OneStage => {
            let s = &st.adjustment.sigma;
            let pose = |t: &crate::calib::joint::TransformSigma| PoseSigma {
                rotation_vector: t.rotation_vector.into(),
                translation_mm: t.translation_mm.into(),
            };
            Uncertainty {
                camera: Some(CameraSigma::from_params(&s.camera)),
                laser_plane: Some(PlaneSigma {
                    normal: s.plane_normal.into(),
                    d_mm: s.plane_d_mm,
                }),
                hand_cam: Some(pose(&s.hand_cam)),
                base_board: Some(pose(&s.base_board)),
            }
        }
        Method::Paper => Uncertainty {
            camera: Some(CameraSigma::from_params(&st.camera.camera_sigma)),
            laser_plane: Some(PlaneSigma {
                normal: st.plane.sigma.normal.into(),
                d_mm: st.plane.sigma.d_mm,
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
            }
        })
        .collect()
}

/// The report: the calibration (the adjusted values, or the paper's stages' values)
/// with its records, and the stages.
pub(super) fn build_report(
    st: Stage,
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
    let calibration = Calibration {
        camera,
        laser_plane,
        hand_cam,
        base_board,
        robot: rig.robot.clone(),
        quality: Quality {
            circle_rms_px: adj.circle_rms_px,
            stripe_rms_px: adj.stripe_rms_px,
            views_used: st.views_used,
        },
        uncertainty: uncertainty_to_json(&uncertainty(&st, opts.method)),
        extra: calibration_extra(&summary, &records, &warnings),
    };
    CalibrationReport {
        calibration,
        method: opts.method,
        summary,
        records,
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
