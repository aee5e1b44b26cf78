//! The one-stage adjustment: intrinsics, distortion, laser plane, hand-eye `X` and
//! robot-world `Z` refined together in ONE Levenberg-Marquardt, the board pose of each
//! view following from the robot.
//!
//! ## Model
//!
//! Per view i with `A_i = T_base_hand(q_i)` (from the robot):
//!
//! ```text
//! T_cam_board(i) = (A_i X)^-1 Z,   R_cb = R_X^T R_A^T R_Z,   t_cb = R_X^T (R_A^T (t_Z - t_A) - t_X)
//! ```
//!
//! The robot's poses are not exact: with [`JointOptions::robot_noise`] (the default)
//! each view's `A_i` is corrected, `A_i D_i`, by a small flange-frame transform `D_i`
//! whose prior is the robot-pose noise, two more variance components (translation mm,
//! rotation) estimated with the image's ([`robot_noise`]). Without it the poses are
//! taken as exact (the paper's rigid model).
//!
//! Residuals, in pixels:
//! - circles: detected imaged centre minus the predicted imaged centre of the circle
//!   (the bias-free conic model of [`crate::calib::conic`], default the exact area
//!   centroid);
//! - stripe points: signed image distance from the detected point to the image of the
//!   line where the laser plane meets view i's board plane. The distance is measured to
//!   the foot point `P(s*)` of the (distorted) image curve of the 3D line, found by
//!   Gauss-Newton along the line; its derivative w.r.t. the parameters is, by the
//!   envelope theorem, `n^T d pi(P(s*)) / d theta` at fixed `s*`, `n` the unit normal of
//!   the image curve at the foot point.
//!
//! ## Parameters (state vector)
//!
//! `[free camera parameters (PARAM_NAMES order)] [plane a, b, d] [X: w, v] [Z: w, v]
//! [board scale]`, then per view `[D_i: w, v]` with the robot-pose noise.
//! The laser plane's unit normal is `normalize(n0 + a e1 + b e2)` around the starting
//! normal `n0` (`e1`, `e2` orthonormal, perpendicular to it), its offset `d` mm. The
//! transforms are stored as rotation vector and translation; the solver's increment is
//! `R Exp(w)` (rotation about the transform's own axes) and `t + v` (mm).
//!
//! ## Weighting and uncertainty
//!
//! Circle residuals, stripe residuals and the robot-pose corrections' rotation and
//! translation have different noise. The adjustment estimates one standard deviation
//! per group (variance components): after every accepted step it re-estimates
//! `sigma_g^2 = SSR_g / r_g` with the group's redundancy `r_g = m_g - tr(N^-1 N_g)`
//! (Förstner; `N = J^T W J`, `N_g` the group's share, the trace the sum of its
//! residuals' leverages: a prior row whose correction the images determine has a
//! redundancy near 1, one they leave to the prior near 0) and re-weights (`1 /
//! sigma_g`); the solver does not stop while the weights still move (see
//! [`crate::numerics::lm::LeastSquares::reweight`]). The robot-pose sigmas have floors
//! ([`robot_noise`]). The covariance of the parameters is then `s^2 (J^T W J)^-1` with
//! `s^2` the a-posteriori variance factor of the weighted residuals (about 1); with the
//! robot-pose noise it is the covariance with the corrections estimated alongside, so
//! every block's sigma includes the robot's part. Optional Huber loss on the weighted
//! residuals (threshold 1.345 sigma). Jacobians by forward-mode automatic
//! differentiation ([`crate::numerics::dual::Dual`]), checked against central
//! differences in the tests.
//!
//! ## Files
//!
//! - `layout/`: the parameter vector (`ParamLayout`: blocks, slots, names,
//!   decoding, retraction; `build.rs` registers the blocks);
//! - `residuals/`: the circle and stripe terms, their values and Jacobian rows, the
//!   groups' weights (one file each);
//! - `robot_noise.rs`: the per-view robot-pose correction, its prior rows, floors and
//!   per-view test;
//! - `bench.rs`: the bench (no robot): each view's board pose a free per-view block;
//! - `profile.rs`, `profile_problem.rs`: a line profiler's adjustment (the sphere's
//!   blocks) and its problem (rows, normal equations formed without the Jacobian);
//! - `covariance.rs`: sigmas of the estimated numbers;
//! - `finish.rs`: the result from the final solve (its covariance widened, reports);
//! - `report.rs`: per-view figures;
//! - here: the public API and the solve schedule.

mod bench;
mod chain;
mod covariance;
mod finish;
mod fold;
mod kinematic;
mod layout;
mod predict;
pub mod profile;
mod profile_problem;
mod profile_rounds;
mod report;
mod residuals;
mod robot;
mod robot_noise;
mod robot_select;
mod robot_solve;

pub use self::bench::bench_adjustment;
pub(crate) use self::covariance::camera_name;
pub use self::fold::{
    one_step_folds, stepped_from, two_step_folds, CertifiedFold, FoldSolution, SMALL_PULL,
};
pub use self::robot::{
    flange_twists, point_gradients as dh_point_gradients, DhKind, DhParam, RobotMode,
};
pub use self::robot_solve::RobotOptions;

use nalgebra::{DMatrix, Vector3};

pub use self::predict::{predicted_covariance, Prediction};

use self::finish::{finish, FinalSolve};
use self::layout::{Block, ParamLayout};
use self::residuals::{JointProblem, Terms};
use crate::calib::conic::CentreModel;
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::{NamedCovariance, RobotCalibration, RobotPoseNoise};
use crate::numerics::lm::{levenberg_marquardt, LmOptions, LmResult, StopReason};

/// Variance-component re-estimations per solve: they settle in 2-3 on noisy data; a
/// residual type fitted exactly (noise-free data, or a model that fits one type
/// perfectly) would otherwise chase its sigma towards zero step after step.
const MAX_REWEIGHTS: usize = 5;

/// Variance-component re-estimations per solve with the robot-pose noise: its three
/// components share what the views disagree on, and the fixed-point iteration moves
/// that share between them slowly (rosi_10x10 needs about 15 from the start); the dead
/// band of the robot-pose sigmas ends it sooner when they settle.
const MAX_REWEIGHTS_POSE_NOISE: usize = 30;

/// The robot-pose noise's own floors (translation mm, rotation deg): what an exact robot
/// is estimated at ([`robot_noise`] module docs).
pub const POSE_NOISE_FLOOR: (f64, f64) = (
    robot_noise::ABSOLUTE_FLOOR_MM,
    robot_noise::ABSOLUTE_FLOOR_DEG,
);

pub use self::robot_noise::IMAGE_FACTOR_FLOOR;

/// Huber threshold on the weighted residuals (in units of the residual's sigma).
pub const HUBER_SIGMAS: f64 = 1.345;

/// Which blocks the adjustment estimates; the others are held at their starting values
/// (a calibration started from an earlier one, `--fix`, `--laser-only`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FreeBlocks {
    /// Intrinsics and the distortion model's coefficients.
    pub camera: bool,
    /// The laser plane (held anyway when there is no stripe point).
    pub laser_plane: bool,
    pub hand_cam: bool,
    pub base_board: bool,
    /// The board's printed scale (every board coordinate times `s`; the robot's
    /// translations fix it). Held at [`JointOptions::board_scale`] by default.
    pub board_scale: bool,
}

impl Default for FreeBlocks {
    fn default() -> Self {
        FreeBlocks {
            camera: true,
            laser_plane: true,
            hand_cam: true,
            base_board: true,
            board_scale: false,
        }
    }
}

impl FreeBlocks {
    /// Holds the block named `name` (DECISIONS 4's names: `camera`, `laser_plane`,
    /// `hand_cam`, `base_board`; `robot` is accepted and changes nothing: the robot is
    /// not estimated); an error for any other name.
    pub fn hold(&mut self, name: &str) -> Result<()> {
        match name {
            "camera" => self.camera = false,
            "laser_plane" => self.laser_plane = false,
            "hand_cam" => self.hand_cam = false,
            "base_board" => self.base_board = false,
            "robot" => {}
            o => {
                return Err(Error::InvalidInput(format!(
                    "unknown block {o:?} to hold: expected camera, laser_plane, hand_cam, \
                     base_board or robot"
                )))
            }
        }
        Ok(())
    }

    /// Only the laser plane.
    pub fn laser_only() -> Self {
        FreeBlocks {
            camera: false,
            laser_plane: true,
            hand_cam: false,
            base_board: false,
            board_scale: false,
        }
    }
}

/// Options of [`joint_adjustment`].
#[derive(Debug, Clone, PartialEq)]
pub struct JointOptions {
    /// Circle-centre model.
    pub centre_model: CentreModel,
    /// Solver options of each round.
    pub lm: LmOptions,
    /// Huber loss on the weighted residuals.
    pub robust: bool,
    /// Estimate one standard deviation per residual type (variance components) during
    /// the solve (default true); otherwise the weights stay `1 / initial_sigma_px`.
    pub variance_components: bool,
    /// A view whose RMS of weighted residuals exceeds this (in sigmas) is reported as an
    /// outlier (default 3).
    pub outlier_sigmas: f64,
    /// Starting standard deviations (circle, stripe), px.
    pub initial_sigma_px: (f64, f64),
    /// The blocks estimated.
    pub free: FreeBlocks,
    /// The board's scale: its starting value, or its value when held (default 1).
    pub board_scale: f64,
    /// Correct every view's robot pose by its own small transform, the robot-pose noise
    /// estimated as variance components (module docs; default true). False: the robot
    /// poses are exact (the paper's rigid model).
    pub robot_noise: bool,
    /// With the robot-pose noise: split each view's correction into the robot's part
    /// and the part its own image gets wrong, shaped like the image's uncertainty of the
    /// view's pose ([`robot_noise`] module docs; default true). False: the correction's
    /// prior is the robot's alone (isotropic in the flange frame).
    pub image_pose_noise: bool,
    /// The image part's starting factor `k` (default 1).
    pub initial_image_factor: f64,
    /// The robot's DH table when the poses come from its joint readings (rig.json's
    /// robot; default none): with the robot-pose noise, the covariance then carries what
    /// DH errors of the size the noise shows would do to the estimate ([`kinematic`]).
    pub kinematics: Option<crate::model::kinematics::Robot>,
    /// Widen the covariance to the views' own scatter where that is larger (a covariance
    /// clustered by view, [`crate::calib::clustered`]; default true).
    pub clustered_covariance: bool,
    /// Floors of the robot-pose noise from the robot's figures, one-sigma per component:
    /// translation mm, rotation deg ([`crate::Robot::pose_noise_floor`]; default none).
    pub robot_floor: (Option<f64>, Option<f64>),
    /// Starting standard deviations of the robot-pose noise (translation mm, rotation
    /// deg): the weights of the first evaluation, and throughout without variance
    /// components.
    pub initial_robot_sigma: (f64, f64),
    /// The robot's DH corrections to estimate (`None` or [`RobotMode::Fixed`]: the DH
    /// table is exact; module docs of `robot.rs`).
    pub robot: Option<RobotOptions>,
}

impl Default for JointOptions {
    fn default() -> Self {
        JointOptions {
            centre_model: CentreModel::ConicExact,
            // The weighted residuals have unit variance (variance components), so the
            // cost is about (m - n) / 2 and a step that lowers it by `ftol * cost`
            // moves the parameters by sqrt(2 ftol cost) sigmas: 1e-8 stops within
            // 0.01 sigma for m = 10^4 (and to round-off on exact data, where each step
            // gains orders of magnitude).
            lm: LmOptions {
                max_iterations: 100,
                ftol: 1e-8,
                xtol: 1e-10,
                ..Default::default()
            },
            robust: false,
            variance_components: true,
            outlier_sigmas: 3.0,
            initial_sigma_px: (0.02, 0.05),
            free: FreeBlocks::default(),
            board_scale: 1.0,
            robot_noise: true,
            image_pose_noise: true,
            initial_image_factor: 1.0,
            kinematics: None,
            clustered_covariance: true,
            robot_floor: (None, None),
            initial_robot_sigma: (0.05, 0.01),
            robot: None,
        }
    }
}

impl JointOptions {
    /// These options with the variance components starting where `earlier` (a solve
    /// of nearly the same observations: a refit without a view, with the board scale
    /// free, on corrected stripe points) ended.
    pub fn continuing(&self, earlier: &JointResult) -> JointOptions {
        let mut o = self.clone();
        let ok = |x: f64| x.is_finite() && x > 0.0;
        if ok(earlier.sigma_px.0) && ok(earlier.sigma_px.1) {
            o.initial_sigma_px = earlier.sigma_px;
        }
        if let Some(n) = &earlier.robot_noise {
            if ok(n.sigma_translation_mm) && ok(n.sigma_rotation_deg) {
                o.initial_robot_sigma = (n.sigma_translation_mm, n.sigma_rotation_deg);
            }
            if let Some(k) = n.image_factor.filter(|k| ok(*k)) {
                o.initial_image_factor = k;
            }
        }
        o
    }
}

/// Where the adjustment starts (the two-stage results).
#[derive(Debug, Clone, PartialEq)]
pub struct JointStart {
    pub camera: Camera,
    /// Laser plane, camera frame (`None`: no laser; the views then have no stripe
    /// points).
    pub plane: Option<Plane>,
    /// `X = T_hand_cam`.
    pub hand_cam: Iso3,
    /// `Z = T_base_board`.
    pub base_board: Iso3,
}

/// One-sigma of an estimated transform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransformSigma {
    /// Of the rotation-vector components, rad.
    pub rotation_vector: Vector3<f64>,
    /// Of the translation, mm.
    pub translation_mm: Vector3<f64>,
}

/// One-sigma of every estimated number.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSigma {
    /// Camera parameters over the camera block's nine slots: the model's parameters in
    /// its order (brown5: [`crate::model::camera::PARAM_NAMES`]), then unused slots (0
    /// for fixed ones and unused slots, NaN unobservable).
    pub camera: [f64; 9],
    /// Components of the plane's unit normal.
    pub plane_normal: Vector3<f64>,
    /// Plane offset, mm.
    pub plane_d_mm: f64,
    pub hand_cam: TransformSigma,
    pub base_board: TransformSigma,
    /// The board scale's (0 when held).
    pub board_scale: f64,
}

/// Per-view figures of the adjustment.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewReport {
    /// `ViewObs::view` (dataset row).
    pub view: usize,
    pub circles: usize,
    pub stripe_points: usize,
    /// RMS of the 2D circle residuals, px (NaN without circles).
    pub circle_rms_px: f64,
    /// RMS of the stripe distances, px (NaN without stripe points).
    pub stripe_rms_px: f64,
    /// RMS of the stripe points' distances from the laser plane's line on the board,
    /// mm (each point's image residual converted with its local scale).
    pub stripe_rms_mm: f64,
    /// Residuals far beyond the others' (see [`JointOptions::outlier_sigmas`]).
    pub outlier: bool,
}

/// The result of [`joint_adjustment`].
#[derive(Debug, Clone)]
pub struct JointResult {
    pub camera: Camera,
    /// The laser plane (`None` without a laser: no start and no stripe point).
    pub plane: Option<Plane>,
    pub hand_cam: Iso3,
    pub base_board: Iso3,
    /// The board's scale (estimated, or the held value).
    pub board_scale: f64,
    /// The blocks that were estimated.
    pub free: FreeBlocks,
    pub sigma: JointSigma,
    /// RMS of the 2D circle residuals over all views, px.
    pub circle_rms_px: f64,
    /// RMS of the stripe distances, px.
    pub stripe_rms_px: f64,
    /// RMS of the stripe residuals in mm on the board.
    pub stripe_rms_mm: f64,
    /// Estimated standard deviations of one residual coordinate (circle, stripe), px.
    pub sigma_px: (f64, f64),
    /// The robot-pose noise estimated with the corrections (`None` without them:
    /// [`JointOptions::robot_noise`] off).
    pub robot_noise: Option<RobotPoseNoise>,
    /// The robot calibration (`--robot` other than fixed): the refined robot, the
    /// corrections with their sigmas, the candidates fixed and why.
    pub robot: Option<RobotCalibration>,
    pub views: Vec<ViewReport>,
    /// Names of the state vector's global parameters (the calibration's; the per-view
    /// robot-pose corrections are in [`Self::robot_noise`]), and their covariance
    /// (weighted, scaled by the variance factor; with the corrections estimated
    /// alongside).
    pub param_names: Vec<String>,
    pub covariance: DMatrix<f64>,
    /// The covariance of the estimated numbers under calibration.json's names.
    pub named_covariance: NamedCovariance,
    /// How far the views' own scatter exceeds the noise model's covariance: the largest
    /// ratio of sigmas over every combination of the numbers ([`crate::calib::clustered`];
    /// 1: nowhere; the covariance is widened to it). `None` when not computed (four views or fewer, or
    /// [`JointOptions::clustered_covariance`] off).
    pub view_scatter: Option<f64>,
    pub iterations: usize,
    pub stop_reason: StopReason,
    pub unobservable: Vec<String>,
    /// Per-circle values: `(view, row, col, u, v, du, dv)`, the detected centre `(u, v)`
    /// and the residual predicted minus detected, px.
    pub circle_residuals: Vec<(usize, usize, usize, f64, f64, f64, f64)>,
    /// Stripe `(view, u, v, distance px)`.
    pub stripe_residuals: Vec<(usize, f64, f64, f64)>,
    /// On the bench ([`bench_adjustment`]): each used view's estimated board pose
    /// `T_cam_board`, `(ViewObs::view, pose)`; empty with a robot.
    pub board_poses: Vec<(usize, Iso3)>,
    pub warnings: Vec<String>,
}

/// The one-stage adjustment (module docs) over the views' circles and stripe points.
///
/// Every view used must carry `base_hand` (`T_base_hand`). Views without circles or
/// without `base_hand` are skipped with a warning. Errors: [`Error::InvalidInput`] for
/// fewer than 3 usable views, no stripe point at all, or non-finite observations;
/// [`Error::Degenerate`] when a view's stripe line cannot be formed; solver errors are
/// passed on.
pub fn joint_adjustment(
    views: &[ViewObs],
    board: &Board,
    start: &JointStart,
    opts: &JointOptions,
) -> Result<JointResult> {
    board.validate()?;
    start.camera.validate()?;
    let mut warnings = Vec::new();
    let terms = Terms::collect(views, board, &mut warnings)?;
    let free = free_blocks(&terms, start, opts)?;
    // A robot calibrated (`--robot offsets|full|auto`) is calibrated on the rigid model,
    // as in wave two: with the robot-pose corrections free a DH error's flange motion is
    // largely theirs to take, the selection would not see it, and the corrections'
    // estimates traded with the DH rows' (10-40 of their sigmas from the exact-data
    // estimates on the robot-error twin). Its poses are then the calibrated robot's.
    let calibrating_robot = opts
        .robot
        .as_ref()
        .is_some_and(|r| r.mode != RobotMode::Fixed);
    let rigid_opts;
    let opts = if calibrating_robot && opts.robot_noise {
        rigid_opts = JointOptions {
            robot_noise: false,
            ..opts.clone()
        };
        &rigid_opts
    } else {
        opts
    };
    let layout = ParamLayout::of(start, &free, opts, &terms.used, None);
    if layout.num_global() == 0 {
        return Err(Error::InvalidInput(
            "the one-stage adjustment has nothing to estimate: every block is held".into(),
        ));
    }
    let mut problem = JointProblem::new(&start.camera, &layout, terms.clone(), opts);
    let (mut res, mut iterations) = solve(&mut problem, layout.encode(), opts, false)?;
    if layout.per_view_free(Block::RobotPose) && !res.unobservable.is_empty() {
        // The corrections took up the starting values' error along the directions only
        // their prior determines (common to every view: X's and Z's own), and the
        // normal equations could not resolve them once the images fitted (exact
        // observations from a poor start). Again from the rigid model's solution (the
        // robot poses exact, the first solve of the schedule), where the corrections
        // hold only what the views disagree on.
        let rigid = ParamLayout::new(
            start,
            &free,
            opts.board_scale,
            &terms.used,
            layout::PoseNoise::Off,
            None,
        );
        let mut pre = JointProblem::new(&start.camera, &rigid, terms.clone(), opts);
        let (r, pre_iterations) = solve(&mut pre, rigid.encode(), opts, true)?;
        let mut p0 = layout.encode();
        p0[..rigid.num_params()].copy_from_slice(&r.params);
        problem = JointProblem::new(&start.camera, &layout, terms.clone(), opts);
        problem.continue_from(&pre);
        let (r, it) = solve(&mut problem, p0, opts, false)?;
        res = r;
        iterations += pre_iterations + it;
    }

    let outcome = robot_solve::robot_rounds(
        start,
        &free,
        opts,
        &terms,
        &layout,
        &res.params,
        problem.all_weights(),
    )?;
    if let Some(out) = &outcome {
        if out.block.is_some() {
            let lr = ParamLayout::of(start, &free, opts, &terms.used, out.block.clone());
            let p0 = robot_solve::transfer(&out.layout, &out.p, &lr);
            let mut pr = JointProblem::new(&start.camera, &lr, terms.clone(), opts);
            pr.set_all_weights(&out.weights);
            let (r, it) = solve(&mut pr, p0, opts, false)?;
            let solved = FinalSolve {
                layout: &lr,
                problem: &pr,
                res: r,
                iterations: iterations + it,
            };
            return finish(start, free, opts, solved, warnings, outcome.as_ref());
        }
    }
    let solved = FinalSolve {
        layout: &layout,
        problem: &problem,
        res,
        iterations,
    };
    finish(start, free, opts, solved, warnings, outcome.as_ref())
}

/// The blocks estimated: the options', with the laser plane held when there is no
/// stripe point. Errors when the views cannot determine what is asked: fewer than 3
/// views with a robot pose (2 with stripe points when only the laser plane is
/// estimated), stripe points without a starting laser plane.
fn free_blocks(terms: &Terms, start: &JointStart, opts: &JointOptions) -> Result<FreeBlocks> {
    let mut free = opts.free;
    if terms.stripes.is_empty() {
        free.laser_plane = false;
    } else if start.plane.is_none() {
        return Err(Error::InvalidInput(
            "the one-stage adjustment has stripe points but no starting laser plane".into(),
        ));
    }
    let chain = free.camera || free.hand_cam || free.base_board || free.board_scale;
    if chain && terms.a.len() < 3 {
        return Err(Error::InvalidInput(format!(
            "the one-stage adjustment needs at least 3 views with a robot pose, got {}",
            terms.a.len()
        )));
    }
    if opts.free.laser_plane && !chain {
        let mut with_stripe: Vec<usize> = terms.stripes.iter().map(|s| s.view).collect();
        with_stripe.dedup();
        if with_stripe.len() < 2 {
            return Err(Error::InvalidInput(format!(
                "the laser plane needs stripe points on the board in at least 2 views, got {}",
                with_stripe.len()
            )));
        }
    }
    Ok(free)
}

/// The solve schedule from `p`: the last solve's result and the iterations of all
/// (`first_only`: the first solve alone).
///
/// Solves (residual model, Jacobian model, Huber). With the exact centroid model the
/// steps are taken with the first-order conic model's Jacobian (the residuals are exact;
/// an inexact Jacobian only changes the path, at a sixth of the cost), and a last solve
/// with the exact Jacobian checks convergence (usually it stops at its first
/// evaluation) and gives the covariance (the earlier solves compute none). The variance components are re-estimated
/// after every accepted step. Huber, when robust, from the second solve on (the first,
/// least squares, gives it a start and scale).
fn solve(
    problem: &mut JointProblem<'_>,
    mut p: Vec<f64>,
    opts: &JointOptions,
    first_only: bool,
) -> Result<(LmResult, usize)> {
    let model = opts.centre_model;
    let step_model = if model == CentreModel::ConicExact {
        CentreModel::Conic
    } else {
        model
    };
    let mut solves = vec![(model, step_model, false)];
    if opts.robust {
        solves.push((model, step_model, true));
    }
    if step_model != model {
        solves.push((model, model, opts.robust));
    }
    if first_only {
        solves.truncate(1);
    }
    let mut res: Option<LmResult> = None;
    let mut iterations = 0;
    let last = solves.len().saturating_sub(1);
    for (i, (model, jacobian_model, huber)) in solves.into_iter().enumerate() {
        let mut lm = opts.lm.clone();
        if huber {
            lm.huber = Some(HUBER_SIGMAS);
        }
        // Only the last solve's covariance is kept: the others' results start it.
        lm.covariance &= i == last;
        problem.prepare_solve(model, jacobian_model);
        let r = levenberg_marquardt(&*problem, &p, &lm)?;
        iterations += r.iterations;
        p.clone_from(&r.params);
        res = Some(r);
    }
    let Some(res) = res else {
        return Err(Error::InvalidInput(
            "the one-stage adjustment did not run".into(),
        ));
    };
    Ok((res, iterations))
}

#[cfg(test)]
mod tests {
    use super::residuals::{CircleTerm, StripeTerm};
    use super::*;
    use crate::calib::conic::predict_centre;
    use crate::calib::laser_plane::stripe_line_in_view;
    use crate::calib::CircleObs;
    use crate::model::camera::DistortionModel;
    use crate::model::geometry::{iso_from_rotvec, iso_to_rotvec};

    struct Synth {
        cam: Camera,
        plane: Plane,
        x: Iso3,
        z: Iso3,
        views: Vec<ViewObs>,
    }

    fn synth(model: DistortionModel, k: [f64; 5]) -> Synth {
        let cam = Camera::new(
            768,
            576,
            crate::model::camera::Intrinsics {
                fu: 1270.0,
                fv: 1320.0,
                u0: 380.0,
                v0: 290.0,
            },
            model,
            k,
        )
        .unwrap();
        let plane = Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap();
        let x = iso_from_rotvec(
            &Vector3::new(-0.3087, 0.2362, 3.0369),
            &Vector3::new(29.19, 5.37, 62.64),
        );
        let board = Board::hp3_paper();
        // Board 110 mm in front of the camera at view 0; other views rotate the hand.
        let cb0 = iso_from_rotvec(
            &Vector3::new(3.1, 0.05, 0.0),
            &Vector3::new(-18.0, -12.0, 112.0),
        );
        let a0 = iso_from_rotvec(
            &Vector3::new(0.0, 3.1, 0.0),
            &Vector3::new(480.0, 0.0, 300.0),
        );
        let z = a0 * x * cb0;
        let mut views = Vec::new();
        for (i, d) in [
            [0.0, 0.0, 0.0],
            [0.15, 0.0, 0.05],
            [0.0, 0.18, -0.1],
            [-0.12, 0.1, 0.2],
            [0.1, -0.15, -0.2],
        ]
        .iter()
        .enumerate()
        {
            // Rotate the camera about a point on the board in front of it.
            let bc0 = cb0.inverse();
            let rot = iso_from_rotvec(&Vector3::new(d[0], d[1], d[2]), &Vector3::zeros());
            let centre = iso_from_rotvec(&Vector3::zeros(), &Vector3::new(20.0, 15.0, 0.0));
            let bc = centre * rot * centre.inverse() * bc0;
            let cb = bc.inverse();
            let a = z * cb.inverse() * x.inverse();
            let mut circles = Vec::new();
            for (r, c) in board.indices() {
                let uv = predict_centre(
                    &cam,
                    &cb,
                    &board.center(r, c),
                    0.5 * board.diameter(r, c),
                    CentreModel::ConicExact,
                )
                .unwrap();
                circles.push(CircleObs {
                    row: r,
                    col: c,
                    u: uv.x,
                    v: uv.y,
                });
            }
            let l = stripe_line_in_view(&plane, &cb, &cam).unwrap();
            let stripe = (-20..20)
                .map(|s| {
                    let uv = cam
                        .project(&(l.point_cam + l.direction_cam * (s as f64)))
                        .unwrap();
                    [uv.x, uv.y]
                })
                .collect();
            views.push(ViewObs {
                view: i,
                circles,
                stripe,
                reading: None,
                base_hand: Some(a),
                alternatives: Vec::new(),
                stripe_shape: None,
            });
        }
        Synth {
            cam,
            plane,
            x,
            z,
            views,
        }
    }

    fn iso_err(a: &Iso3, b: &Iso3) -> (f64, f64) {
        (
            a.rotation.angle_to(&b.rotation),
            (a.translation.vector - b.translation.vector).norm(),
        )
    }

    fn perturbed_start(s: &Synth) -> JointStart {
        let mut p = s.cam.params();
        p[0] += 3.0;
        p[1] -= 2.0;
        p[2] += 1.5;
        p[3] -= 1.0;
        let d = iso_from_rotvec(
            &Vector3::new(0.002, -0.001, 0.003),
            &Vector3::new(0.3, -0.2, 0.4),
        );
        JointStart {
            camera: s.cam.with_params(&p),
            plane: Some(
                Plane::new(
                    s.plane.normal + Vector3::new(0.01, -0.01, 0.005),
                    s.plane.d + 0.5,
                )
                .unwrap(),
            ),
            hand_cam: s.x * d,
            base_board: d * s.z,
        }
    }

    #[test]
    fn exact_observations_recover_every_parameter() {
        for (model, k) in [
            (DistortionModel::Radial1, [0.05, 0.0, 0.0, 0.0, 0.0]),
            (DistortionModel::OpenCv5, [-0.2, 0.1, 1e-3, -1e-3, 0.02]),
        ] {
            let s = synth(model, k);
            let start = perturbed_start(&s);
            let r = joint_adjustment(
                &s.views,
                &Board::hp3_paper(),
                &start,
                &JointOptions::default(),
            )
            .unwrap();
            let (p, t) = (r.camera.params(), s.cam.params());
            for i in 0..9 {
                assert!(
                    (p[i] - t[i]).abs() <= 1e-6 * t[i].abs().max(1e-3),
                    "{model:?} {i}: {} vs {}",
                    p[i],
                    t[i]
                );
            }
            let plane = r.plane.unwrap();
            assert!((plane.normal - s.plane.normal).norm() < 1e-9);
            assert!((plane.d - s.plane.d).abs() < 1e-7);
            let (xr, xt) = iso_err(&r.hand_cam, &s.x);
            let (zr, zt) = iso_err(&r.base_board, &s.z);
            assert!(
                xr < 1e-9 && xt < 1e-7 && zr < 1e-9 && zt < 1e-7,
                "{xr} {xt} {zr} {zt}"
            );
            assert!(r.circle_rms_px < 1e-7 && r.stripe_rms_px < 1e-7);
        }
    }

    /// Every 9th circle and 7th stripe point of `s`'s views, moved off their predictions
    /// (residuals away from zero), as the finite-difference tests' terms.
    fn fd_terms(s: &Synth) -> Terms {
        let mut circles = Vec::new();
        let mut stripes = Vec::new();
        let board = Board::hp3_paper();
        let mut a = Vec::new();
        for (vi, v) in s.views.iter().enumerate() {
            a.push(v.base_hand.unwrap());
            for c in v.circles.iter().step_by(9) {
                let ctr = board.center(c.row, c.col);
                circles.push(CircleTerm {
                    view: vi,
                    row: c.row,
                    col: c.col,
                    centre: (ctr.x, ctr.y),
                    radius: 0.5 * board.diameter(c.row, c.col),
                    u: c.u + 0.3,
                    v: c.v - 0.2,
                });
            }
            for p in v.stripe.iter().step_by(7) {
                stripes.push(StripeTerm {
                    view: vi,
                    u: p[0] + 0.4,
                    v: p[1] - 0.3,
                });
            }
        }
        Terms {
            a,
            used: (0..s.views.len()).collect(),
            circles,
            stripes,
            q: vec![None; s.views.len()],
        }
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let s = synth(DistortionModel::OpenCv5, [-0.2, 0.1, 1e-3, -1e-3, 0.02]);
        let start = perturbed_start(&s);
        let terms = fd_terms(&s);
        // Every block free, the board scale too (away from 1, so that `t / s` matters).
        let free = FreeBlocks {
            board_scale: true,
            ..FreeBlocks::default()
        };
        // Without and with the robot-pose corrections, these away from the identity
        // (the prior rows' inverse right Jacobian then matters); X held too, its slots'
        // derivatives still reach the corrections.
        // The robot's DH corrections too (every candidate of `full`, Hayati's beta on the
        // HP3's row 2 among them), alone and with the robot-pose corrections.
        let dh = {
            let mut reference = crate::model::kinematics::Robot::hp3();
            reference.joints[1].beta_deg = 0.1;
            let params = robot::candidates(&reference, RobotMode::Full);
            robot::RobotBlock {
                reference,
                params,
                readings: (0..terms.a.len())
                    .map(|k| {
                        let k = k as f64;
                        vec![2.0 * k, -k, 1.5 * k, 3.0 * k, -90.0 + k, -2.0 * k]
                    })
                    .collect(),
            }
        };
        // Z moved so that the robot's home pose sees the board as the first view does.
        let home = dh.reference.forward_unchecked(&dh.readings[0]);
        let start_dh = JointStart {
            base_board: home * terms.a[0].inverse() * start.base_board,
            ..start.clone()
        };
        use layout::PoseNoise;
        for (robot, x_free, with_dh) in [
            (PoseNoise::Off, true, false),
            (PoseNoise::Robot, true, false),
            (PoseNoise::RobotAndImage, true, false),
            (PoseNoise::Robot, false, false),
            (PoseNoise::RobotAndImage, false, false),
            (PoseNoise::Off, true, true),
            (PoseNoise::Robot, true, true),
            (PoseNoise::RobotAndImage, true, true),
        ] {
            let free = FreeBlocks {
                hand_cam: x_free,
                ..free
            };
            let block = with_dh.then(|| dh.clone());
            let start = if with_dh { &start_dh } else { &start };
            let layout = ParamLayout::new(start, &free, 1.03, &terms.used, robot, block);
            let opts = JointOptions {
                centre_model: CentreModel::ConicExact,
                variance_components: false,
                initial_sigma_px: (0.5, 2.0),
                initial_robot_sigma: (0.2, 0.05),
                ..JointOptions::default()
            };
            let pr = JointProblem::new(&start.camera, &layout, terms.clone(), &opts);
            let mut p: Vec<f64> = start.camera.params().to_vec();
            p.extend_from_slice(&[0.01, -0.02, start.plane.unwrap().d]);
            let held = [&start.hand_cam, &start.base_board];
            for t in held.iter().skip(usize::from(!x_free)) {
                let (rv, tr) = iso_to_rotvec(t);
                p.extend_from_slice(&[rv.x, rv.y, rv.z, tr.x, tr.y, tr.z]);
            }
            p.push(1.03);
            if with_dh {
                for k in 0..dh.params.len() {
                    p.push(0.01 * ((k % 5) as f64 - 2.0));
                }
            }
            if robot != PoseNoise::Off {
                for k in 0..terms.a.len() {
                    let k = k as f64;
                    p.extend_from_slice(&[0.02 * k, -0.01, 0.03, 0.3, -0.2 * k, 0.1]);
                    if robot == PoseNoise::RobotAndImage {
                        p.extend_from_slice(&[0.01, 0.02 * k, -0.01, -0.1 * k, 0.2, 0.05]);
                    }
                }
            }
            assert_eq!(p.len(), layout.num_params());
            let step = |j: usize| {
                if j < 9 {
                    1e-5 * p[j].abs().max(1e-2)
                } else {
                    1e-6
                }
            };
            let worst =
                crate::numerics::lm::assert_jacobian_matches_fd(&pr, &p, step, 1e-9, 1e-5, "joint");
            println!(
                "robot-pose corrections {robot:?}, X free {x_free}, DH {with_dh}: largest relative \
                 FD difference {worst:.2e}"
            );
        }
    }

    /// A one-coefficient division model, `(xd, yd) = (x, y) / (1 + lambda r^2)`, for the
    /// adjustment of a camera of another model than brown5.
    struct Division;

    impl crate::model::camera::CameraModel for Division {
        fn name(&self) -> &'static str {
            "joint-test-division"
        }
        fn distortion_names(&self) -> &'static [&'static str] {
            &["lambda"]
        }
        fn distort(&self, k: &[f64], x: f64, y: f64) -> ((f64, f64), nalgebra::Matrix2<f64>) {
            let s = 1.0 / (1.0 + k[0] * (x * x + y * y));
            let q = -2.0 * k[0] * s * s;
            let j = nalgebra::Matrix2::new(s + q * x * x, q * x * y, q * x * y, s + q * y * y);
            ((x * s, y * s), j)
        }
        fn distortion_jacobian(&self, k: &[f64], x: f64, y: f64) -> nalgebra::Matrix2xX<f64> {
            let r2 = x * x + y * y;
            let s = 1.0 / (1.0 + k[0] * r2);
            nalgebra::Matrix2xX::from_column_slice(&[-x * r2 * s * s, -y * r2 * s * s])
        }
    }

    static DIVISION: Division = Division;

    /// The rows of a camera of another model (through its trait: circles with the
    /// first-order conic centre, stripe points) match central differences, with the
    /// robot-pose corrections and their image part; the camera's columns are the model's
    /// five parameters.
    #[test]
    fn jacobian_of_another_camera_model_matches_central_differences() {
        let s = synth(DistortionModel::Radial1, [0.05, 0.0, 0.0, 0.0, 0.0]);
        let mut start = perturbed_start(&s);
        let model = crate::model::camera::register(&DIVISION).unwrap();
        start.camera = start.camera.with_projection(model, &[0.08]).unwrap();
        let terms = fd_terms(&s);
        let free = FreeBlocks {
            board_scale: true,
            ..FreeBlocks::default()
        };
        let noise = layout::PoseNoise::RobotAndImage;
        let layout = ParamLayout::new(&start, &free, 1.03, &terms.used, noise, None);
        let opts = JointOptions {
            centre_model: CentreModel::Conic,
            variance_components: false,
            initial_sigma_px: (0.5, 2.0),
            initial_robot_sigma: (0.2, 0.05),
            ..JointOptions::default()
        };
        let pr = JointProblem::new(&start.camera, &layout, terms.clone(), &opts);
        let mut p = start.camera.model_params();
        assert_eq!(p.len(), 5);
        p.extend_from_slice(&[0.01, -0.02, start.plane.unwrap().d]);
        for t in [&start.hand_cam, &start.base_board] {
            let (rv, tr) = iso_to_rotvec(t);
            p.extend_from_slice(&[rv.x, rv.y, rv.z, tr.x, tr.y, tr.z]);
        }
        p.push(1.03);
        for k in 0..terms.a.len() {
            let k = k as f64;
            p.extend_from_slice(&[0.02 * k, -0.01, 0.03, 0.3, -0.2 * k, 0.1]);
            p.extend_from_slice(&[0.01, 0.02 * k, -0.01, -0.1 * k, 0.2, 0.05]);
        }
        assert_eq!(p.len(), layout.num_params());
        let step = |j: usize| {
            if j < 5 {
                1e-5 * p[j].abs().max(1e-2)
            } else {
                1e-6
            }
        };
        let worst = crate::numerics::lm::assert_jacobian_matches_fd(
            &pr,
            &p,
            step,
            1e-9,
            1e-5,
            "joint, division model",
        );
        println!("division model: largest relative FD difference {worst:.2e}");
    }

    #[test]
    fn too_few_views_and_stripes_without_a_plane_are_typed_errors() {
        let s = synth(DistortionModel::Radial1, [0.05, 0.0, 0.0, 0.0, 0.0]);
        let start = perturbed_start(&s);
        let b = Board::hp3_paper();
        let Err(e) = joint_adjustment(&s.views[..2], &b, &start, &JointOptions::default()) else {
            panic!("expected an error: {}", "2 views are too few")
        };
        assert!(matches!(e, Error::InvalidInput(_)), "{e}");
        let no_plane = JointStart {
            plane: None,
            ..start.clone()
        };
        let Err(e) = joint_adjustment(&s.views, &b, &no_plane, &JointOptions::default()) else {
            panic!("expected an error: {}", "stripes without a plane")
        };
        assert!(e.to_string().contains("laser plane"), "{e}");
        let nothing = JointOptions {
            free: FreeBlocks {
                camera: false,
                laser_plane: false,
                hand_cam: false,
                base_board: false,
                board_scale: false,
            },
            ..JointOptions::default()
        };
        let Err(e) = joint_adjustment(&s.views, &b, &start, &nothing) else {
            panic!("expected an error: {}", "nothing to estimate")
        };
        assert!(e.to_string().contains("nothing to estimate"), "{e}");
    }

    #[test]
    fn blocks_are_held_by_their_contract_names() {
        let mut f = FreeBlocks::default();
        for n in ["camera", "hand_cam", "base_board", "robot"] {
            f.hold(n).unwrap();
        }
        assert_eq!(
            f,
            FreeBlocks {
                laser_plane: true,
                ..FreeBlocks::laser_only()
            }
        );
        let e = f.hold("plane").unwrap_err();
        assert!(e.to_string().contains("unknown block \"plane\""), "{e}");
    }

    /// Views without stripe points (no laser): camera, X and Z are recovered exactly,
    /// the plane is not estimated and has no covariance rows.
    #[test]
    fn without_a_laser_the_chain_is_recovered_and_the_plane_is_none() {
        let mut s = synth(DistortionModel::Radial2, [0.05, -0.02, 0.0, 0.0, 0.0]);
        for v in &mut s.views {
            v.stripe.clear();
        }
        let start = JointStart {
            plane: None,
            ..perturbed_start(&s)
        };
        // The rigid model (the default before the robot-pose noise was): round-off
        // recovery. With the pose noise the solver stops at its cost tolerance, 2e-7 mm
        // and 2e-9 rad from the truth here (exact_observations_recover_every_parameter
        // checks that default at its own tolerances).
        let rigid = JointOptions {
            robot_noise: false,
            ..JointOptions::default()
        };
        let r = joint_adjustment(&s.views, &Board::hp3_paper(), &start, &rigid).unwrap();
        assert!(r.plane.is_none() && !r.free.laser_plane);
        let (xr, xt) = iso_err(&r.hand_cam, &s.x);
        let (zr, zt) = iso_err(&r.base_board, &s.z);
        assert!(
            xr < 1e-9 && xt < 1e-7 && zr < 1e-9 && zt < 1e-7,
            "{xr} {xt} {zr} {zt}"
        );
        assert!((r.camera.fu - s.cam.fu).abs() < 1e-6);
        let names = &r.named_covariance.parameters;
        assert!(
            names.iter().all(|n| !n.starts_with("laser_plane")),
            "{names:?}"
        );
        assert!(names.contains(&"camera.distortion[1]".to_string()));
        assert_eq!(r.sigma.plane_d_mm, 0.0);
    }

    /// A board printed 2 % larger than declared: with the scale free the adjustment
    /// finds 1.02 exactly (and the chain), with it held the circles do not fit.
    #[test]
    fn a_free_board_scale_recovers_a_misprinted_board() {
        let s = synth(DistortionModel::Radial1, [0.05, 0.0, 0.0, 0.0, 0.0]);
        let board = Board::hp3_paper();
        // The same images, explained by a board 2 % larger: rig.json's board seen from
        // t / 1.02 (module docs of the layout) is what the true board gives at t.
        // The synthetic views rotate the camera about one point of the board, which
        // leaves the scale undetermined (it trades with X's translation): move the hand
        // too, and drop the stripes (their lines would move with it).
        let mut views = s.views.clone();
        let scale = 1.02;
        for (i, v) in views.iter_mut().enumerate() {
            let shift = [
                [0.0, 0.0, 0.0],
                [15.0, -5.0, 10.0],
                [-10.0, 12.0, -8.0],
                [5.0, 9.0, 14.0],
                [-12.0, -7.0, 4.0],
            ][i];
            let a =
                v.base_hand.unwrap() * iso_from_rotvec(&Vector3::zeros(), &Vector3::from(shift));
            v.base_hand = Some(a);
            v.stripe.clear();
            let cb = (a * s.x).inverse() * s.z;
            let cb_img = Iso3::from_parts((cb.translation.vector / scale).into(), cb.rotation);
            for c in &mut v.circles {
                let uv = predict_centre(
                    &s.cam,
                    &cb_img,
                    &board.center(c.row, c.col),
                    0.5 * board.diameter(c.row, c.col),
                    CentreModel::ConicExact,
                )
                .unwrap();
                (c.u, c.v) = (uv.x, uv.y);
            }
        }
        let opts = JointOptions {
            free: FreeBlocks {
                board_scale: true,
                ..FreeBlocks::default()
            },
            ..JointOptions::default()
        };
        let start = JointStart {
            plane: None,
            ..perturbed_start(&s)
        };
        let r = joint_adjustment(&views, &board, &start, &opts).unwrap();
        assert!(
            (r.board_scale - scale).abs() < 1e-9,
            "{} {} {} {:?} {:?}",
            r.board_scale,
            r.circle_rms_px,
            r.stripe_rms_px,
            r.stop_reason,
            r.sigma.board_scale
        );
        let (xr, xt) = iso_err(&r.hand_cam, &s.x);
        assert!(xr < 1e-9 && xt < 1e-6, "{xr} {xt}");
        assert!(r.named_covariance.index("board.scale").is_some());
        // Held at 1 with the robot poses exact, the circles do not fit; with the
        // robot-pose corrections they do, X and Z taking up most of the misprint and
        // each view's correction the rest (0.05-0.3 mm here), and the robot-pose noise
        // says so, far above its floor.
        let rigid = JointOptions {
            robot_noise: false,
            ..JointOptions::default()
        };
        let held = joint_adjustment(&views, &board, &start, &rigid).unwrap();
        assert!(held.circle_rms_px > 0.05, "{}", held.circle_rms_px);
        let noisy = JointOptions {
            robot_noise: true,
            ..JointOptions::default()
        };
        let held = joint_adjustment(&views, &board, &start, &noisy).unwrap();
        let noise = held.robot_noise.unwrap();
        assert!(
            noise.sigma_translation_mm > 0.05 && !noise.translation_at_floor,
            "{noise:?}"
        );
    }

    /// Only the laser plane free (`--laser-only`): it is recovered, the held blocks keep
    /// their values bit for bit.
    #[test]
    fn laser_only_refines_the_plane_and_holds_the_rest() {
        let s = synth(DistortionModel::Radial1, [0.05, 0.0, 0.0, 0.0, 0.0]);
        let start = JointStart {
            camera: s.cam.clone(),
            plane: perturbed_start(&s).plane,
            hand_cam: s.x,
            base_board: s.z,
        };
        let opts = JointOptions {
            free: FreeBlocks::laser_only(),
            ..JointOptions::default()
        };
        // Two views suffice for the plane.
        let r = joint_adjustment(&s.views[..2], &Board::hp3_paper(), &start, &opts).unwrap();
        let plane = r.plane.unwrap();
        assert!((plane.normal - s.plane.normal).norm() < 1e-9);
        assert!((plane.d - s.plane.d).abs() < 1e-7);
        assert_eq!(r.camera, s.cam);
        assert_eq!(r.hand_cam, s.x);
        assert_eq!(r.base_board, s.z);
        assert_eq!(r.param_names, ["plane_a", "plane_b", "plane_d_mm"]);
        let Err(e) = joint_adjustment(&s.views[..1], &Board::hp3_paper(), &start, &opts) else {
            panic!("expected an error: {}", "one view cannot give a plane")
        };
        assert!(e.to_string().contains("at least 2 views"), "{e}");
    }
}
