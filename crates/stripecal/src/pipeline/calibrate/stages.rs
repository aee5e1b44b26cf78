//! From observations to a calibration, as a sequence of stages: camera, labellings,
//! stripe points on the board, robot poses against images (`AX = ZB` from the views that
//! agree), laser plane, adjustment, report, quality gates.

use super::board_scale::{
    check_board_scale, gate as board_scale_gate, warning as board_scale_warning,
};
use super::board_stripe::{correct_board_stripes, BoardStripeCorrection};
use super::emitter_carry::EmitterResponse;
use super::gates::{converged, determined, judge, pose_outliers, view_residuals, views_check};
use super::held::held;
use super::labels::resolve_labellings;
use super::laser_only::calibrate_held_chain;
use super::loo::leave_one_out;
use super::pairing::check_pairing;
use super::report::{build_report, SelfChecks, Stage};
use super::stripe_select::select_stripes;
use super::{CalibrateOptions, CalibrationReport, Method, ViewStatus};
use crate::calib::camera::{calibrate_camera, CameraCalibration, CameraOptions};
use crate::calib::conic::CentreModel;
use crate::calib::joint::{
    joint_adjustment, JointOptions, JointResult, JointStart, RobotMode, RobotOptions,
};
use crate::calib::laser_plane::{fit_laser_plane, LaserPlaneFit};
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::camera::Camera;
use crate::model::geometry::Iso3;
use crate::model::{QualityCheck, Rig};
use crate::numerics::robust::median;

/// Runs the pipeline on observations (see the module docs) and its quality gates
/// ([`super::gates`]). `views` are the views whose board was found; `rig` gives the
/// board, image size, distortion model and robot.
///
/// Errors: [`Error::Quality`] when a gate fails (unless `opts.accept_poor`), carrying
/// the calibration when one could be computed; the stages' errors.
pub fn calibrate_observations(
    views: &[ViewObs],
    rig: &Rig,
    opts: &CalibrateOptions,
) -> Result<CalibrationReport> {
    let (rep, checks) = calibrate_unjudged(views, rig, opts)?;
    judge(rep, checks, opts)
}

/// The pipeline without the final verdict: the calibration and the gates' checks.
pub(in crate::pipeline) fn calibrate_unjudged(
    views: &[ViewObs],
    rig: &Rig,
    opts: &CalibrateOptions,
) -> Result<(CalibrationReport, Vec<QualityCheck>)> {
    check_poses_finite(views)?;
    super::held::check_from_size(rig, opts)?;
    // `--from` without `--fix`: the file's camera and plane as a prior.
    if let Some(from) = opts
        .from
        .as_ref()
        .filter(|_| super::held::holds_nothing(opts) && !super::bench::is_bench(views))
    {
        return super::prior::calibrate_with_prior(views, rig, opts, from);
    }
    let held = held(opts)?;
    if super::bench::is_bench(views) {
        return super::bench::calibrate_bench(views, rig, opts, held.as_ref());
    }
    if let Some(h) = held.as_ref().filter(|h| h.chain_held()) {
        let rep = calibrate_held_chain(views, rig, opts, h)?;
        let checks = vec![
            determined(&rep.adjustment, &rep.calibration.camera, None),
            converged(&rep.adjustment, opts.method),
        ];
        return Ok((rep, checks));
    }
    if opts.robot != RobotMode::Fixed && opts.method == Method::OneStage && rig.robot.is_none() {
        return Err(Error::InvalidInput(format!(
            "--robot {} calibrates the robot's DH rows: rig.json has no robot (and views.csv \
             must give joint readings q1..qN, not flange poses)",
            opts.robot.name()
        )));
    }
    let board = &rig.board;
    let mut warnings = Vec::new();
    let mut status: Vec<ViewStatus> = views.iter().map(ViewStatus::observed).collect();
    // 2. Camera.
    let camcal = camera_stage(views, rig, opts)?;
    warnings.extend(camcal.warnings.iter().cloned());
    // Labellings the images leave open, from the robot poses.
    let (labelled, frame_note) = resolve_labellings(views, &camcal.poses, board, &mut warnings);
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
    // 3. Stripe points on the board plane.
    let (obs, poses) = select_stripes(&labelled, &camcal.camera, &mut status)?;
    // 4. Robot poses against images; AX = ZB from the views that agree.
    let paired = check_pairing(&obs, &poses, &earlier, opts, &mut warnings, &mut status)?;
    warnings.extend(paired.axzb.warnings.iter().cloned());
    let total = obs.iter().filter(|v| v.base_hand.is_some()).count() + earlier.len();
    let (mut used_obs, mut used_poses) = kept(&obs, &poses, &paired.keep);
    check_usable(&used_obs, &warnings)?;
    let jopts = joint_options(opts, rig);
    let standoff = {
        let mut d: Vec<f64> = used_poses
            .iter()
            .map(|p| p.translation.vector.norm())
            .collect();
        median(&mut d)
    };
    // 5. Laser plane and the adjustment (evaluated only, for the paper's method); views
    // whose residuals are far above the others', or whose robot pose is off by far more
    // than the others' (the robot-pose test), are left out once when enough remain.
    let mut first_pass = true;
    let mut pose_left_out = Vec::new();
    let (plane, start, adj, views_check, plane_warnings) = loop {
        // the plane stage's warnings of the last pass only (a refit repeats them)
        let mut plane_warnings = Vec::new();
        let plane = laser_plane_stage(&used_obs, &used_poses, &camcal.camera, &mut plane_warnings)?;
        let mut start = JointStart {
            camera: camcal.camera.clone(),
            plane: plane.as_ref().map(|p| p.plane),
            hand_cam: paired.axzb.x,
            base_board: paired.axzb.z,
        };
        if let Some(h) = &held {
            h.apply(&mut start);
        }
        let adj = joint_adjustment(&used_obs, board, &start, &jopts)?;
        let (mut bad, mut msg) = view_residuals(&adj, camcal.rms_px);
        let (pose_bad, pose_msg) = pose_outliers(&adj);
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
        let kept_n = used_obs.len() - bad.len();
        let check = views_check(&bad, &msg, kept_n, total);
        if bad.is_empty() || !check.passed || !first_pass {
            break (plane, start, adj, check, plane_warnings);
        }
        first_pass = false;
        pose_left_out = pose_bad;
        leave_out(
            &bad,
            &msg,
            &mut used_obs,
            &mut used_poses,
            &mut warnings,
            &mut status,
        )?;
    };
    warnings.extend(plane_warnings);
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
        held: held.as_ref(),
    };
    Ok((
        build_report(stage, rig, opts, status, warnings),
        gate_checks,
    ))
}

/// What became of the board stripe-bias correction: applied, or why not.
type BoardStripeOutcome = std::result::Result<BoardStripeCorrection, String>;

/// The stripe's bias on the board corrected ([`super::board_stripe`]) and the adjustment
/// run again from its own solution on the corrected points, its covariance widened by
/// what the correction leaves; the input as it is when the correction is off or cannot
/// be made (the paper's method, no widths, a sheet the widths do not determine).
///
/// What the correction leaves (the module docs of [`super::board_stripe`]): the model's
/// neglected terms, `u^2 D D^T` along the change `D` the correction made; the emitter,
/// whose position the calibration does not know, uniform within the assumed range along
/// each of the plane's two axes: the adjustment run again with the biases predicted for
/// the emitter at each end of a range, `d_+` and `d_-` its changes, each axis adding
/// `(d_+ d_+^T + d_- d_-^T) / 6` (a uniform distribution's variance, `a^2 / 3`, read at
/// both ends).
fn correct_stripes(
    adj: JointResult,
    used_obs: Vec<ViewObs>,
    used_poses: &[Iso3],
    board: &Board,
    jopts: &JointOptions,
    opts: &CalibrateOptions,
) -> Result<(JointResult, Vec<ViewObs>, Option<BoardStripeOutcome>)> {
    let Some(plane) = adj
        .plane
        .filter(|_| opts.board_stripe_bias && opts.method == Method::OneStage)
    else {
        return Ok((adj, used_obs, None));
    };
    let corr = match correct_board_stripes(&used_obs, used_poses, &adj.camera, &plane, &opts.stripe)
    {
        Ok(c) => c,
        Err(why) => return Ok((adj, used_obs, Some(Err(why)))),
    };
    let start_of = |r: &JointResult| JointStart {
        camera: r.camera.clone(),
        plane: r.plane,
        hand_cam: r.hand_cam,
        base_board: r.base_board,
    };
    let jopts = &jopts.continuing(&adj);
    let mut again = joint_adjustment(&corr.corrected, board, &start_of(&adj), jopts)?;
    let mut terms = vec![(
        again.named_difference(&adj),
        corr.summary.neglected_share.powi(2),
    )];
    let from = start_of(&again);
    // The emitter moved: +e1, -e1, +e2, -e2 (`emitter_moved`'s order).
    let mut moved = Vec::with_capacity(4);
    for views in &corr.emitter_moved {
        let alt = joint_adjustment(views, board, &from, jopts)?;
        moved.push(alt.named_difference(&again));
    }
    terms.extend(moved.iter().map(|d| (d.clone(), 1.0 / 6.0)));
    again.add_systematic_terms(&terms);
    let mut summary = corr.summary;
    if let [p1, m1, p2, m2] = &moved[..] {
        summary.emitter_response = Some(EmitterResponse {
            origin_cam_mm: corr.emitter_origin_cam_mm,
            axes_cam: corr.emitter_axes_cam,
            range_mm: summary.emitter_range_mm,
            parameters: again.named_covariance.parameters.clone(),
            plus: [p1.clone(), p2.clone()],
            minus: [m1.clone(), m2.clone()],
            covariance_trace: again.named_covariance.matrix.trace(),
        });
    }
    Ok((again, corr.corrected, Some(Ok(summary))))
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

fn check_poses_finite(views: &[ViewObs]) -> Result<()> {
    for v in views {
        if let Some(t) = v.base_hand {
            if !t.to_homogeneous().iter().all(|x| x.is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "view {}: the robot pose is not finite",
                    v.view
                )));
            }
        }
    }
    Ok(())
}

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
    calibrate_camera(views, &rig.board, rig.width, rig.height, model, &cam_opts)
}

/// The board-frame rectangle the stripe points had to fall in before the selection by
/// the board plane ([`super::stripe_select`]): a circle grid's centres grown by half a
/// pitch, a chessboard's squares.
#[cfg(test)]
pub(super) fn grid_extent(board: &Board) -> (nalgebra::Vector2<f64>, nalgebra::Vector2<f64>) {
    use crate::model::board::BoardKind;
    use nalgebra::Vector2;
    if board.kind == BoardKind::Chessboard {
        let e = board.pattern_extent();
        return (Vector2::new(e[0], e[2]), Vector2::new(e[1], e[3]));
    }
    let (mut lo, mut hi) = (
        Vector2::new(f64::INFINITY, f64::INFINITY),
        Vector2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for (r, c) in board.indices() {
        let p = board.center(r, c);
        lo = lo.inf(&Vector2::new(p.x, p.y));
        hi = hi.sup(&Vector2::new(p.x, p.y));
    }
    let m = 0.5 * board.pitch_mm;
    (lo.add_scalar(-m), hi.add_scalar(m))
}

/// The views `bad` (residuals far above the others', `msg` says how) named in
/// `warnings` and `status` and left out of `used_obs` and `used_poses`; an error when too
/// few remain ([`check_usable`]).
pub(super) fn leave_out(
    bad: &[usize],
    msg: &str,
    used_obs: &mut Vec<ViewObs>,
    used_poses: &mut Vec<Iso3>,
    warnings: &mut Vec<String>,
    status: &mut [ViewStatus],
) -> Result<()> {
    for &v in bad {
        let note = format!("view {v}: left out: {msg}");
        warnings.push(note.clone());
        if let Some(s) = status.iter_mut().find(|s| s.view == v) {
            s.note = Some(note);
        }
    }
    let keep: Vec<bool> = used_obs.iter().map(|v| !bad.contains(&v.view)).collect();
    (*used_obs, *used_poses) = kept(used_obs, used_poses, &keep);
    check_usable(used_obs, warnings)
}

/// The views (and poses) marked in `keep`.
pub(super) fn kept(obs: &[ViewObs], poses: &[Iso3], keep: &[bool]) -> (Vec<ViewObs>, Vec<Iso3>) {
    let used_obs = obs
        .iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(v, _)| v.clone())
        .collect();
    let used_poses = poses
        .iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(p, _)| *p)
        .collect();
    (used_obs, used_poses)
}

pub(super) fn check_usable(used_obs: &[ViewObs], warnings: &[String]) -> Result<()> {
    if used_obs.len() < 3 {
        return Err(Error::InvalidInput(format!(
            "calibration needs at least 3 usable views, {} left ({})",
            used_obs.len(),
            warnings.join("; ")
        )));
    }
    Ok(())
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

pub(super) fn mark_used(status: &mut [ViewStatus], used_obs: &[ViewObs]) {
    for s in status.iter_mut() {
        if let Some(v) = used_obs.iter().find(|v| v.view == s.view) {
            s.used = true;
            s.stripe_used = v.stripe.len();
        } else if s.note.is_none() {
            s.note = Some("left out by the camera calibration".into());
        }
    }
}
