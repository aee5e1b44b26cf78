//! The stages the robot, bench, laser-only and prior pipelines share: the camera, the
//! laser plane's first estimate, the adjustment's options and the self-checks (board
//! scale, leave-one-view-out).

use super::board_scale::{check_board_scale, warning as board_scale_warning};
use super::loo::leave_one_out;
use super::report::SelfChecks;
use super::{CalibrateOptions, Method};
use crate::calib::camera::{calibrate_camera_model, CameraCalibration, CameraOptions};
use crate::calib::conic::CentreModel;
use crate::calib::joint::{JointOptions, JointResult, RobotMode, RobotOptions};
use crate::calib::laser_plane::{fit_laser_plane, LaserPlaneFit};
use crate::calib::ViewObs;
use crate::error::Result;
use crate::model::board::Board;
use crate::model::camera::Camera;
use crate::model::geometry::Iso3;
use crate::model::Rig;

/// The camera calibration. The one-stage adjustment refines the camera with the
/// requested centre model; its starting camera only needs the first-order conic model
/// (much cheaper) and looser tolerances.
pub(super) fn camera_stage(
    views: &[ViewObs],
    rig: &Rig,
    opts: &CalibrateOptions,
) -> Result<CameraCalibration> {
    let model = opts.distortion.unwrap_or(rig.distortion_model);
    let one_stage = opts.method == Method::OneStage;
    let mut cam_opts = CameraOptions {
        centre_model: if one_stage && opts.centre_model == CentreModel::ConicExact {
            CentreModel::Conic
        } else {
            opts.centre_model
        },
        clustered_covariance: opts.clustered_covariance,
        ..Default::default()
    };
    if one_stage {
        // A starting point: the joint adjustment converges from it.
        cam_opts.lm.ftol = 1e-8;
        cam_opts.lm.xtol = 1e-8;
    }
    calibrate_camera_model(
        views,
        &rig.board,
        rig.width,
        rig.height,
        opts.camera_model,
        model,
        &cam_opts,
    )
}

/// The laser plane's first estimate from the views' stripe points (`None` when no view
/// has any: a calibration without a laser).
pub(super) fn laser_plane_stage(
    used_obs: &[ViewObs],
    used_poses: &[Iso3],
    camera: &Camera,
    warnings: &mut Vec<String>,
) -> Result<Option<LaserPlaneFit>> {
    if used_obs.iter().all(|v| v.stripe.is_empty()) {
        warnings.push(format!(
            "no view has stripe points on the board ({}): the laser plane is not estimated \
             (\"laser_plane\": null); add it later with `stripecal calibrate --laser-only \
             --from CALIBRATION.json LASER_DATASET`",
            no_stripe_reason(used_obs)
        ));
        return Ok(None);
    }
    let pv: Vec<(Iso3, Vec<[f64; 2]>)> = used_poses
        .iter()
        .zip(used_obs)
        .map(|(p, v)| (*p, v.stripe.clone()))
        .collect();
    let plane = fit_laser_plane(&pv, camera)?;
    warnings.extend(plane.warnings.iter().cloned());
    Ok(Some(plane))
}

/// Why no view has stripe points on the board: no laser images at all, or laser images
/// whose line was not found (the views named) or not on the board.
pub(super) fn no_stripe_reason(obs: &[ViewObs]) -> String {
    let shapes: Vec<(usize, usize)> = obs
        .iter()
        .filter_map(|v| {
            v.stripe_shape
                .as_ref()
                .map(|s| (v.view, s.extraction.found))
        })
        .collect();
    if shapes.is_empty() {
        return "no laser images".into();
    }
    let none: Vec<usize> = shapes.iter().filter(|s| s.1 == 0).map(|s| s.0).collect();
    let off: Vec<usize> = shapes.iter().filter(|s| s.1 > 0).map(|s| s.0).collect();
    let mut parts = Vec::new();
    if !none.is_empty() {
        parts.push(format!(
            "no laser line found in the laser image of {}",
            super::pairing::name_views(&none)
        ));
    }
    if !off.is_empty() {
        parts.push(format!(
            "the laser line of {} is not on the board",
            super::pairing::name_views(&off)
        ));
    }
    format!(
        "{} laser images, {}: check the exposure, the laser and rig.json's stripe.direction",
        shapes.len(),
        parts.join("; ")
    )
}

/// The adjustment's options: the pipeline's, with the robot's figures (rig.json) as
/// floors of the robot-pose noise; for the paper's method, zero iterations (the stages'
/// values evaluated with the same residuals) and the robot poses exact (its rigid
/// model).
pub(super) fn joint_options(opts: &CalibrateOptions, rig: &Rig) -> JointOptions {
    let mut jopts = JointOptions {
        centre_model: opts.centre_model,
        robust: opts.robust,
        free: opts.free,
        robot_noise: opts.robot_pose_noise,
        clustered_covariance: opts.clustered_covariance,
        kinematics: rig.robot.clone(),
        robot_floor: rig
            .robot
            .as_ref()
            .map_or((None, None), |r| r.pose_noise_floor()),
        ..Default::default()
    };
    if let (Some(r), true) = (&rig.robot, opts.robot != RobotMode::Fixed) {
        jopts.robot = Some(RobotOptions {
            nominal: r.clone(),
            mode: opts.robot,
        });
    }
    if opts.method == Method::Paper {
        jopts.robot = None;
        jopts.lm.max_iterations = 0;
        jopts.robust = false;
        jopts.robot_noise = false;
    }
    jopts
}

/// The board-scale check and the leave-one-view-out figure of the one-stage
/// calibration `adj` over `used` (none for the paper's method); a warning when the
/// board's scale disagrees with the robot.
pub(super) fn self_checks(
    used: &[ViewObs],
    board: &Board,
    adj: &JointResult,
    jopts: &JointOptions,
    opts: &CalibrateOptions,
    warnings: &mut Vec<String>,
) -> Result<SelfChecks> {
    if opts.method == Method::Paper {
        return Ok(SelfChecks::default());
    }
    opts.cancel.check()?;
    let chain_free = adj.free.camera || adj.free.hand_cam || adj.free.base_board;
    let board_scale = if chain_free || adj.free.board_scale {
        let c = check_board_scale(used, board, adj, jopts, opts.board_scale_tolerance)?;
        if c.disagrees
            && !c.estimated
            && super::board_scale::gate(&c, board).is_some_and(|g| g.passed)
        {
            warnings.push(board_scale_warning(&c, board));
        }
        Some(c)
    } else {
        None
    };
    opts.cancel.check()?;
    let leave_one_out = if opts.leave_one_out {
        leave_one_out(used, board, adj, jopts)?
    } else {
        None
    };
    Ok(SelfChecks {
        board_scale,
        leave_one_out,
    })
}
