//! The robot pipeline: from a robot dataset's observations to a calibration, as a
//! sequence of stages: camera, labellings, stripe points on the board, robot poses
//! against images (`AX = ZB` from the views that agree), laser plane, adjustment (views
//! left out once), the board's stripe bias corrected, self-checks, report; the quality
//! gates' checks beside it.

use super::board_scale::gate as board_scale_gate;
use super::board_stripe::correct_stripes;
use super::gates::{converged, determined, pose_outliers, view_residuals};
use super::held::Held;
use super::labels::{resolve_labellings, Labelled};
use super::leave_out::{adjust_leaving_out_once, Adjusted, UsedViews};
use super::pairing::check_pairing;
use super::report::{build_report, Stage};
use super::stages::{camera_stage, joint_options, self_checks};
use super::stripe_select::select_stripes;
use super::views::{check_usable, kept, mark_used, median_standoff};
use super::{CalibrateOptions, CalibrationReport, Method, ViewStatus};
use crate::calib::joint::{joint_adjustment, JointResult, JointStart, RobotMode};
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::{QualityCheck, Rig, RobotPoseView};

/// The robot pipeline (module docs) without the final verdict: the calibration and the
/// gates' checks; `held` the blocks `--from` holds (not the whole chain).
pub(super) fn calibrate_robot(
    views: &[ViewObs],
    rig: &Rig,
    opts: &CalibrateOptions,
    held: Option<&Held<'_>>,
) -> Result<(CalibrationReport, Vec<QualityCheck>)> {
    check_robot_mode(rig, opts)?;
    let board = &rig.board;
    let mut warnings = Vec::new();
    let mut status: Vec<ViewStatus> = views.iter().map(ViewStatus::observed).collect();
    // 2. Camera.
    let camcal = camera_stage(views, rig, opts)?;
    opts.cancel.check()?;
    warnings.extend(camcal.warnings.iter().cloned());
    // Labellings the images leave open, from the robot poses.
    let (labelled, frame_note) = resolve_labellings(views, &camcal.poses, board, &mut warnings);
    let earlier = note_unlabelled(&labelled, views, &mut status);
    // 3. Stripe points on the board plane.
    let (obs, poses) = select_stripes(&labelled, &camcal.camera, &mut status)?;
    opts.cancel.check()?;
    // 4. Robot poses against images; AX = ZB from the views that agree.
    let paired = check_pairing(&obs, &poses, &earlier, opts, &mut warnings, &mut status)?;
    warnings.extend(paired.axzb.warnings.iter().cloned());
    let total = obs.iter().filter(|v| v.base_hand.is_some()).count() + earlier.len();
    let (obs, poses) = kept(&obs, &poses, &paired.keep);
    let mut used = UsedViews { obs, poses };
    check_usable(&used.obs, &warnings)?;
    let jopts = joint_options(opts, rig);
    let standoff = median_standoff(&used.poses);
    // 5. Laser plane and the adjustment (evaluated only, for the paper's method); views
    // whose residuals are far above the others', or whose robot pose is off by far more
    // than the others' (the robot-pose test), are left out once when enough remain.
    let mut first_pose_bad = Vec::new();
    let adjust = |used: &UsedViews, plane| {
        let mut start = JointStart {
            camera: camcal.camera.clone(),
            plane,
            hand_cam: paired.axzb.x,
            base_board: paired.axzb.z,
        };
        if let Some(h) = held {
            h.apply(&mut start);
        }
        opts.cancel.check()?;
        let adj = joint_adjustment(&used.obs, board, &start, &jopts)?;
        Ok((start, adj))
    };
    let outliers = |adj: &_, first_pass: bool, warnings: &mut Vec<String>| {
        let (bad, msg, pose_bad) = robot_outliers(adj, camcal.rms_px, first_pass, warnings);
        if first_pass {
            first_pose_bad = pose_bad;
        }
        (bad, msg)
    };
    let Adjusted {
        plane,
        start,
        adjustment: adj,
        views_check,
        left_out,
    } = adjust_leaving_out_once(
        &mut used,
        &camcal.camera,
        total,
        &mut warnings,
        &mut status,
        adjust,
        outliers,
    )?;
    // the robot poses left out (the first pass's pose outliers, when views were left out)
    let pose_left_out = if left_out { first_pose_bad } else { Vec::new() };
    let UsedViews {
        obs: used_obs,
        poses: used_poses,
    } = used;
    opts.cancel.check()?;
    let (mut adj, used_obs, board_stripe) =
        correct_stripes(adj, used_obs, &used_poses, board, &jopts, opts)?;
    if let Some(Err(why)) = &board_stripe {
        warnings.push(format!("board stripe-bias correction not applied: {why}"));
    }
    if let Some(n) = adj.robot_noise.as_mut() {
        n.left_out = pose_left_out;
    }
    warnings.extend(adj.warnings.iter().cloned());
    if let Some(w) = super::kinematics::diagnose(&adj, camcal.rms_px, rig, &used_obs, opts) {
        warnings.push(w);
    }
    mark_used(&mut status, &used_obs);
    let checks = self_checks(&used_obs, board, &adj, &jopts, opts, &mut warnings)?;
    let mut gate_checks = vec![
        paired.check,
        views_check,
        determined(&adj, &adj.camera, standoff),
        converged(&adj, opts.method),
    ];
    if let Some(g) = checks
        .board_scale
        .as_ref()
        .and_then(|c| board_scale_gate(c, board))
    {
        gate_checks.push(g);
    }
    let stage = Stage {
        board_stripe,
        camera: Some(camcal),
        plane,
        axzb: Some(paired.axzb),
        start,
        adjustment: adj,
        frame_note,
        views_used: used_obs.len(),
        checks,
        held,
    };
    Ok((
        build_report(stage, rig, opts, status, warnings),
        gate_checks,
    ))
}

/// An error when `--robot` asks for DH corrections the one-stage adjustment cannot
/// estimate: rig.json has no robot.
fn check_robot_mode(rig: &Rig, opts: &CalibrateOptions) -> Result<()> {
    if opts.robot != RobotMode::Fixed && opts.method == Method::OneStage && rig.robot.is_none() {
        return Err(Error::InvalidInput(format!(
            "--robot {} calibrates the robot's DH rows: rig.json has no robot (and views.csv \
             must give joint readings q1..qN, not flange poses)",
            opts.robot.name()
        )));
    }
    Ok(())
}

/// The views whose labelling the robot poses refused, their reason noted in `status`;
/// those with a robot pose returned (the pairing stage counts them as left out earlier).
fn note_unlabelled(
    labelled: &[Labelled],
    views: &[ViewObs],
    status: &mut [ViewStatus],
) -> Vec<usize> {
    let mut earlier = Vec::new();
    for (view, note) in labelled.iter().filter_map(|l| l.as_ref().err()) {
        if let Some(s) = status.iter_mut().find(|s| s.view == *view) {
            s.note = Some(note.clone());
        }
        if views
            .iter()
            .any(|v| v.view == *view && v.base_hand.is_some())
        {
            earlier.push(*view);
        }
    }
    earlier
}

/// The views to leave out after a pass: those whose residuals are far above the
/// others' and, on the first pass, those whose robot pose fails the robot-pose test
/// (on a later pass they are kept, with a warning); the message saying why, and the
/// robot-pose test's outliers.
fn robot_outliers(
    adj: &JointResult,
    rms_px: f64,
    first_pass: bool,
    warnings: &mut Vec<String>,
) -> (Vec<usize>, String, Vec<RobotPoseView>) {
    let (mut bad, mut msg) = view_residuals(adj, rms_px);
    let (pose_bad, pose_msg) = pose_outliers(adj);
    if !pose_bad.is_empty() {
        if !first_pass {
            warnings.push(format!("{pose_msg}: kept (views are left out once)"));
        } else {
            let extra: Vec<usize> = pose_bad
                .iter()
                .map(|v| v.view)
                .filter(|v| !bad.contains(v))
                .collect();
            bad.extend(extra);
            bad.sort_unstable();
            msg = if msg.starts_with("every view") {
                pose_msg
            } else {
                format!("{msg}; {pose_msg}")
            };
        }
    }
    (bad, msg, pose_bad)
}
