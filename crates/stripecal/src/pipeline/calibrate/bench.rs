//! The bench pipeline (a dataset without poses, spec/DATASET.md): the sensor calibrated
//! on its own, the board moved by hand. The stages of the robot pipeline
//! ([`super::robot`]) without the robot's: camera (Zhang's per-view board poses),
//! labellings (on the bench every view's labelling of a symmetric board is free: each
//! view has its own board pose, so nothing is refused for it), stripe points on the board
//! plane (points off it, e.g. the line continuing onto the floor under a standing board,
//! rejected and counted), laser plane, the bench adjustment ([`crate::calib::joint::bench_adjustment`]: camera, plane and a
//! free board pose per view), the leave-one-view-out figure, the report and the gates
//! (`views`, `determined`, `converged`; no robot gate).

use super::flat_views::{flatness_extra, leave_out_bent};
use super::gates::{converged, determined, view_residuals};
use super::held::Held;
use super::labels::resolve_labellings;
use super::leave_out::{adjust_leaving_out_once, Adjusted, UsedViews};
use super::loo::leave_one_out;
use super::report::{build_report, SelfChecks, Stage};
use super::stages::{camera_stage, joint_options};
use super::stripe_select::select_stripes;
use super::views::{check_usable, mark_used, median_standoff};
use super::{CalibrateOptions, CalibrationReport, Method, ViewStatus};
use crate::calib::joint::{bench_adjustment, JointStart};
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::{QualityCheck, Rig};

/// The extra key of a bench calibration (`"bench": true`): calibration.json then has no
/// `hand_cam`, `base_board` or `robot` (spec/DATASET.md); io's, which reads and writes it.
pub use crate::io::BENCH_KEY;

/// Whether `views` are bench views: none has a robot pose.
pub(super) fn is_bench(views: &[ViewObs]) -> bool {
    !views.is_empty() && views.iter().all(|v| v.base_hand.is_none())
}

/// The bench pipeline (module docs) without the final verdict.
pub(super) fn calibrate_bench(
    views: &[ViewObs],
    rig: &Rig,
    opts: &CalibrateOptions,
    held: Option<&Held<'_>>,
) -> Result<(CalibrationReport, Vec<QualityCheck>)> {
    if opts.method != Method::OneStage {
        return Err(Error::InvalidInput(
            "a bench dataset (no pose columns) is calibrated by the one-stage adjustment only"
                .into(),
        ));
    }
    let board = &rig.board;
    let mut warnings = Vec::new();
    let mut status: Vec<ViewStatus> = views.iter().map(ViewStatus::observed).collect();
    let camcal = camera_stage(views, rig, opts)?;
    warnings.extend(camcal.warnings.iter().cloned());
    // Views of a board that is not flat: named with their sag and left out.
    let (views, camcal, flatness) =
        leave_out_bent(views, camcal, rig, opts, &mut status, &mut warnings)?;
    let views = &views[..];
    // Without robot poses every view keeps the labelling its image gave.
    let (labelled, _) = resolve_labellings(views, &camcal.poses, board, &mut warnings);
    let (obs, poses) = select_stripes(&labelled, &camcal.camera, &mut status)?;
    let total = obs.len();
    let mut used = UsedViews { obs, poses };
    check_usable(&used.obs, &warnings)?;
    let mut jopts = joint_options(opts, rig);
    jopts.robot = None;
    jopts.robot_noise = false;
    let standoff = median_standoff(&used.poses);
    let adjust = |used: &UsedViews, plane| {
        let mut start = JointStart {
            camera: camcal.camera.clone(),
            plane,
            hand_cam: nalgebra::Isometry3::identity(),
            base_board: nalgebra::Isometry3::identity(),
        };
        if let Some(h) = held {
            h.apply(&mut start);
        }
        let adj = bench_adjustment(&used.obs, board, &start, &used.poses, &jopts)?;
        Ok((start, adj))
    };
    let Adjusted {
        plane,
        start,
        adjustment: adj,
        views_check: views_gate,
        ..
    } = adjust_leaving_out_once(
        &mut used,
        &camcal.camera,
        total,
        &mut warnings,
        &mut status,
        adjust,
        |adj, _, _| view_residuals(adj, camcal.rms_px),
    )?;
    let used_obs = used.obs;
    warnings.extend(adj.warnings.iter().cloned());
    mark_used(&mut status, &used_obs);
    let leave_one_out = if opts.leave_one_out {
        leave_one_out(&used_obs, board, &adj, &jopts)?
    } else {
        None
    };
    let gate_checks = vec![
        views_gate,
        determined(&adj, &adj.camera, standoff),
        converged(&adj, opts.method),
    ];
    let stage = Stage {
        board_stripe: None,
        camera: Some(camcal),
        plane,
        axzb: None,
        start,
        adjustment: adj,
        frame_note: None,
        views_used: used_obs.len(),
        checks: SelfChecks {
            board_scale: None,
            leave_one_out,
        },
        held,
    };
    let mut rep = build_report(stage, rig, opts, status, warnings);
    let c = &mut rep.calibration;
    c.robot = None;
    c.mount = crate::model::Mount::Bench;
    c.extra
        .insert("board_flatness".into(), flatness_extra(&flatness));
    Ok((rep, gate_checks))
}
