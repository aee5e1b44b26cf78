//! The adjustment's result from its final solve: the estimated sensor, its covariance
//! (widened to the views' scatter, with the kinematic term), the per-view reports and
//! the robot's figures.

use nalgebra::DMatrix;

use super::layout::{Block, JointParams, ParamLayout};
use super::residuals::JointProblem;
use super::{covariance, kinematic, report, robot_noise, robot_solve};
use super::{FreeBlocks, JointOptions, JointResult, JointStart};
use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::{iso_from_parts, Iso3, Plane};
use crate::numerics::lm::LmResult;

/// The final solve of an adjustment: its problem (over `layout`), its result and the
/// iterations of every solve that led to it.
pub(super) struct FinalSolve<'a> {
    pub layout: &'a ParamLayout,
    pub problem: &'a JointProblem<'a>,
    pub res: LmResult,
    pub iterations: usize,
}

/// The result of the final solve, with the robot rounds' outcome when the robot was
/// calibrated.
pub(super) fn finish(
    start: &JointStart,
    free: FreeBlocks,
    opts: &JointOptions,
    solved: FinalSolve<'_>,
    mut warnings: Vec<String>,
    robot: Option<&robot_solve::RobotOutcome>,
) -> Result<JointResult> {
    let FinalSolve {
        layout,
        problem,
        res,
        iterations,
    } = solved;
    let s = layout.decode(&res.params);
    let (camera, plane) = estimated_sensor(start, free, &s)?;
    let plane_sign = plane.map_or(1.0, |pl| pl.normal.dot(&s.plane_n).signum());
    let ng = layout.num_global();
    let FullCovariance {
        matrix: cov,
        view_scatter,
        kinematic_sigma,
    } = full_covariance(problem, layout, &res, &s, opts)?;
    let named = covariance::named_covariance(layout, &res.params, &s, &cov, plane_sign);
    let sigma = covariance::joint_sigma(&named);
    let n_image = res.residuals.len() - problem.prior_rows_per_view() * s.corrections.len();
    let reports = report::build(
        problem,
        &s,
        &res.residuals[..n_image],
        opts.outlier_sigmas,
        &mut warnings,
    );
    let robot = robot.map(|out| robot_solve::report(out, layout, &res.params, &res.covariance));
    let robot_noise = problem.robot_noise().then(|| {
        let mut n = robot_noise::report(
            layout,
            &s,
            &res.covariance,
            res.sigma2,
            &problem.robot_weights(),
            &problem.robot_state(),
            &problem.terms.used,
        );
        n.kinematic_mm = kinematic_sigma.map(|k| k.0);
        n.kinematic_deg = kinematic_sigma.map(|k| k.1);
        n
    });
    let all_names = layout.names();
    let unobservable = res
        .unobservable
        .iter()
        .map(|&i| all_names[i].clone())
        .collect::<Vec<_>>();
    let param_names = all_names[..ng].to_vec();
    if !unobservable.is_empty() {
        warnings.push(format!(
            "unobservable parameters (their sigma is NaN): {}",
            unobservable.join(", ")
        ));
    }
    let (hand_cam, base_board) = estimated_transforms(layout, &res.params, start, free);
    Ok(JointResult {
        camera,
        plane,
        hand_cam,
        base_board,
        board_scale: s.scale,
        free,
        sigma,
        circle_rms_px: reports.circle_rms_px,
        stripe_rms_px: reports.stripe_rms_px,
        stripe_rms_mm: reports.stripe_rms_mm,
        sigma_px: reports.sigma_px,
        robot_noise,
        robot,
        views: reports.views,
        param_names,
        covariance: cov.view((0, 0), (ng, ng)).into_owned(),
        named_covariance: named,
        view_scatter,
        iterations,
        stop_reason: res.reason,
        unobservable,
        circle_residuals: reports.circle_residuals,
        stripe_residuals: reports.stripe_residuals,
        board_poses: problem
            .terms
            .used
            .iter()
            .zip(&s.board_poses)
            .map(|(&v, (r, t))| (v, iso_from_parts(r, t)))
            .collect(),
        warnings,
    })
}

/// The estimated camera (validated) and laser plane (the starting one when held);
/// errors when the board scale is not a positive number.
fn estimated_sensor(
    start: &JointStart,
    free: FreeBlocks,
    s: &JointParams,
) -> Result<(Camera, Option<Plane>)> {
    let (camera, plane) = camera_and_plane(start, free, s)?;
    if !(s.scale.is_finite() && s.scale > 0.0) {
        return Err(Error::Degenerate(format!(
            "the board scale went to {} in the adjustment",
            s.scale
        )));
    }
    Ok((camera, plane))
}

/// The camera (validated) and laser plane of decoded parameters `s` (the starting plane
/// when held).
pub(super) fn camera_and_plane(
    start: &JointStart,
    free: FreeBlocks,
    s: &JointParams,
) -> Result<(Camera, Option<Plane>)> {
    let camera = start.camera.with_params(&s.cam);
    camera.validate()?;
    let plane = if free.laser_plane {
        Some(Plane::new(s.plane_n, s.plane_d)?)
    } else {
        start.plane
    };
    Ok((camera, plane))
}

/// `(hand_cam, base_board)` of parameter vector `q`; held transforms are returned as
/// given (not through their rotation vectors).
pub(super) fn estimated_transforms(
    layout: &ParamLayout,
    q: &[f64],
    start: &JointStart,
    free: FreeBlocks,
) -> (Iso3, Iso3) {
    let transform = |free: bool, block: Block, held: &Iso3| {
        if free {
            layout.transform(q, block)
        } else {
            *held
        }
    };
    (
        transform(free.hand_cam, Block::HandCam, &start.hand_cam),
        transform(free.base_board, Block::BaseBoard, &start.base_board),
    )
}

/// The covariance of an adjustment's parameters as reported.
struct FullCovariance {
    matrix: DMatrix<f64>,
    /// The views' scatter over the model's covariance when it was widened to it.
    view_scatter: Option<f64>,
    /// The kinematic term's sigmas (mm, deg) when it was added.
    kinematic_sigma: Option<(f64, f64)>,
}

/// The solve's covariance widened to the views' own scatter (covariance module docs)
/// and with the kinematic term added ([`super::kinematic`]).
fn full_covariance(
    problem: &JointProblem<'_>,
    layout: &ParamLayout,
    res: &LmResult,
    s: &JointParams,
    opts: &JointOptions,
) -> Result<FullCovariance> {
    let ng = layout.num_global();
    let mut cov = res.covariance.clone();
    let mut view_scatter = None;
    if opts.clustered_covariance && res.unobservable.is_empty() && ng > 0 {
        let shares = problem.view_shares(&res.params)?;
        let model = res.covariance.view((0, 0), (ng, ng)).into_owned();
        if let Some((wide, ratio)) = shares
            .as_deref()
            .and_then(|s| crate::calib::clustered::widened(&model, s))
        {
            cov.view_mut((0, 0), (ng, ng)).copy_from(&wide);
            view_scatter = Some(ratio);
        }
    }
    let mut kinematic_sigma = None;
    if let Some((term, sigma)) = kinematic::term(problem, layout, res, s, opts)? {
        let mut g = cov.view_mut((0, 0), (ng, ng));
        g += term;
        kinematic_sigma = Some(sigma);
    }
    Ok(FullCovariance {
        matrix: cov,
        view_scatter,
        kinematic_sigma,
    })
}
