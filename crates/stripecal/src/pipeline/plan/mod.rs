//! Pose planning: the one-sigma of every calibration parameter, and of a reconstructed
//! point, that a list of robot poses would give, predicted BEFORE any image is taken.
//!
//! For each joint vector `q_i`: the flange pose `A_i` from the rig's robot, the board
//! pose `T_cam_board = (A_i X)^-1 Z` from the NOMINAL `X = T_hand_cam` and
//! `Z = T_base_board`, and the observations a perfect sensor would make: every target
//! point of the board (circle centres with the adjustment's centre model, chessboard
//! corners) in front of the camera that images inside the image with a margin, and
//! stripe points where the nominal laser plane meets the board's plate, one every
//! [`PlanOptions::stripe_step_px`] px along the imaged line's major image axis (about
//! a real view's count: one per image column or row). A pose with fewer than
//! [`PlanOptions::min_points`] target points is reported unusable and left out.
//!
//! The covariance is [`crate::calib::joint::predicted_covariance`] of those
//! observations at the nominal values (the adjustment's Jacobian, fixed weights
//! `1 / sigma`). A point on the laser plane at the stand-off is triangulated from its
//! pixel, and the parameters' covariance propagated through the triangulation (the
//! implicit-function Jacobian of `project(P) = uv, n . P = d`), in the camera frame and,
//! through the nominal `X` at the median pose, in the base frame.

mod figures;
mod noise;
mod observe;
mod point;

use std::path::Path;

use nalgebra::Vector3;
use serde::Serialize;

use crate::calib::joint::{
    dh_point_gradients, predicted_covariance, FreeBlocks, JointOptions, JointStart, RobotMode,
};
use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::kinematics::Robot;
use crate::model::{Calibration, Rig, Truth};
use figures::parameter_figures;
use noise::adjustment_options;
use observe::{predict_poses, PredictedPoses};
use point::point_sigma;

/// Options of [`plan_poses`].
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOptions {
    /// One-sigma noise of the detections (circle centre coordinate, stripe point), px.
    pub sigma_px: (f64, f64),
    /// The blocks the calibration will estimate (default: the adjustment's).
    pub free: FreeBlocks,
    /// Stand-off of the point whose sigma is predicted, mm along the optical axis
    /// (default: the median stand-off of the usable poses).
    pub standoff_mm: Option<f64>,
    /// Target points and stripe points closer than this to the image border are not
    /// counted, px (default 10).
    pub margin_px: f64,
    /// Spacing of the predicted stripe points along the imaged line's major axis, px
    /// (default 1: one per image column or row, like the extractor).
    pub stripe_step_px: f64,
    /// How far the plate reaches beyond the outer target points, mm (the stripe is
    /// sampled on it; default: one pitch).
    pub plate_margin_mm: Option<f64>,
    /// Fewest target points of a usable pose (default 4).
    pub min_points: usize,
    /// The adjustment's other options (centre model, robot-pose noise, board scale...);
    /// its `free` is replaced by [`Self::free`] and its weights by [`Self::sigma_px`].
    pub adjustment: JointOptions,
    /// The robot's DH corrections the calibration will estimate (`--robot`; default
    /// fixed). `auto` is planned as `full` (which corrections the data show is not known
    /// before the images); the identifiability rule's held ones are in
    /// [`PosePlan::robot_held`].
    pub robot: RobotMode,
    /// The robot-pose noise to plan with, one-sigma per flange component (translation
    /// mm, rotation deg); `None` (default): the nominal calibration's estimate
    /// (calibration.json `robot_pose_noise`), else rig.json's robot figures, else none
    /// (an exact robot: the poses without corrections). Never below rig.json's figures
    /// (the calibration's floors). The images are planned as good as `sigma_px` says
    /// (their own part of the pose error at its floor).
    pub pose_noise: Option<(f64, f64)>,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            sigma_px: (0.05, 0.1),
            free: FreeBlocks::default(),
            standoff_mm: None,
            margin_px: 10.0,
            stripe_step_px: 1.0,
            plate_margin_mm: None,
            min_points: 4,
            adjustment: JointOptions::default(),
            robot: RobotMode::Fixed,
            pose_noise: None,
        }
    }
}

/// One planned pose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlannedPose {
    /// Index in the list given (0-based).
    pub pose: usize,
    pub joints_deg: Vec<f64>,
    /// Whether the pose enters the prediction.
    pub usable: bool,
    /// Why it does not (`None` when usable).
    pub reason: Option<String>,
    /// Target points imaged inside the margin.
    pub points: usize,
    pub stripe_points: usize,
    /// Where the optical axis meets the board plane, mm from the camera (`None`: it
    /// does not, in front of the camera).
    pub standoff_mm: Option<f64>,
    /// Angle between the optical axis and the board's normal, deg.
    pub tilt_deg: Option<f64>,
}

/// A one-sigma by name.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SigmaEntry {
    pub name: String,
    pub sigma: f64,
}

/// The predicted uncertainty of a point triangulated on the laser plane.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PointSigma {
    /// The point's depth, mm.
    pub standoff_mm: f64,
    /// Its pixel.
    pub pixel: [f64; 2],
    /// The point, camera frame, mm.
    pub camera_mm: [f64; 3],
    /// One-sigma of x, y, z (camera frame), mm, and of the position (root of the
    /// covariance's trace).
    pub sigma_camera_mm: [f64; 3],
    pub sigma_camera_norm_mm: f64,
    /// The pose (index in the list) at which it is expressed in the base frame: the
    /// usable pose of median stand-off (`None`: `X` and `Z` both held).
    pub base_pose: Option<usize>,
    pub base_mm: Option<[f64; 3]>,
    pub sigma_base_mm: Option<[f64; 3]>,
    pub sigma_base_norm_mm: Option<f64>,
    /// The same point in the board's frame (`Z^-1` of the base point) and its
    /// one-sigma: relative to the world the board is fixed in, the figure a measurement
    /// of a part on the table has (the base frame is itself defined only through the
    /// robot's first axis, which the board observes through `Z` and the DH rows).
    pub board_mm: Option<[f64; 3]>,
    pub sigma_board_mm: Option<[f64; 3]>,
    pub sigma_board_norm_mm: Option<f64>,
}

/// The result of [`plan_poses`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PosePlan {
    pub poses: Vec<PlannedPose>,
    /// Usable poses.
    pub usable: usize,
    /// The detection noise assumed (circle, stripe), px.
    pub sigma_px: [f64; 2],
    /// Target points and stripe points of the usable poses.
    pub points: usize,
    pub stripe_points: usize,
    /// One-sigma of every estimated number under calibration.json's names
    /// (`camera.fu`, `laser_plane.normal[0]`, `hand_cam.rotation_vector[2]`, ...).
    pub parameters: Vec<SigmaEntry>,
    /// Their covariance, rows in [`Self::parameters`] order.
    pub covariance: Vec<Vec<f64>>,
    /// One-sigma of every entry of the adjustment's state vector (its own names and
    /// units: every block the adjustment estimates, per-view ones included).
    pub state: Vec<SigmaEntry>,
    /// The point at the stand-off (`None` without a laser plane, or when the plane does
    /// not reach that depth near the image centre).
    pub point: Option<PointSigma>,
    pub warnings: Vec<String>,
    /// With `--robot`: the DH corrections the identifiability rule holds, with why.
    pub robot_held: Vec<HeldEntry>,
    /// The robot-pose noise planned with (one-sigma per flange component: translation
    /// mm, rotation deg; [`PlanOptions::pose_noise`]), `None` when the robot is planned
    /// exact.
    pub pose_noise_mm_deg: Option<[f64; 2]>,
}

/// A DH correction held, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeldEntry {
    pub name: String,
    pub reason: String,
}

/// The rig of a rig.json file or of a dataset folder (its rig.json; the images need
/// not exist).
pub fn read_plan_rig(path: &Path) -> Result<Rig> {
    if path.is_dir() {
        crate::io::read_rig(path.join("rig.json"))
    } else {
        crate::io::read_rig(path)
    }
}

/// A nominal calibration from calibration.json or truth.json (told apart by their
/// `format`).
pub fn read_nominal(path: &Path) -> Result<Calibration> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let is_truth = serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| v.get("format").and_then(|f| f.as_str()).map(str::to_owned))
        .is_some_and(|f| f.starts_with("stripecal/truth"));
    if is_truth {
        Ok(nominal_from_truth(crate::io::truth_from_json(path, &text)?))
    } else {
        crate::io::calibration_from_json(path, &text)
    }
}

/// A truth as the nominal calibration (its camera, laser plane, `X`, `Z` and robot).
pub fn nominal_from_truth(t: Truth) -> Calibration {
    Calibration {
        camera: t.camera,
        laser_plane: Some(t.laser_plane),
        mount: crate::model::Mount::Robot,
        hand_cam: t.hand_cam,
        base_board: t.base_board,
        robot: t.robot,
        quality: Default::default(),
        uncertainty: Default::default(),
        covariance: None,
        records: Default::default(),
        extra: Default::default(),
    }
}

/// The nominal sensor a plan is predicted around: its camera, laser plane,
/// `X = T_hand_cam` and `Z = T_base_board`.
struct Nominal<'a> {
    camera: &'a Camera,
    plane: Option<&'a Plane>,
    hand_cam: Iso3,
    base_board: Iso3,
}

/// Predicts the calibration's uncertainty for the robot poses `joints` (degrees, one
/// vector per pose) of `rig`'s robot, around the `nominal` calibration (module docs).
///
/// Errors: [`Error::InvalidInput`] for a joint vector of the wrong length or non-finite
/// values, no robot in the rig or the nominal calibration, bad options, fewer than 3
/// usable poses (naming why each unusable one is); [`Error::Degenerate`] naming the
/// parameters the usable poses do not determine.
pub fn plan_poses(
    rig: &Rig,
    nominal: &Calibration,
    joints: &[Vec<f64>],
    opts: &PlanOptions,
) -> Result<PosePlan> {
    let (robot, mut warnings) = checked_inputs(rig, nominal, opts)?;
    let cam = &nominal.camera;
    let (x, z) = (nominal.hand_cam, nominal.base_board);
    let plane = nominal.laser_plane.as_ref();
    let nominal_chain = Nominal {
        camera: cam,
        plane,
        hand_cam: x,
        base_board: z,
    };
    let PredictedPoses {
        poses,
        views,
        flange,
    } = predict_poses(&nominal_chain, robot, &rig.board, joints, opts)?;
    if views.len() < 3 {
        let why: Vec<String> = poses
            .iter()
            .filter_map(|p| p.reason.as_ref().map(|r| format!("pose {}: {r}", p.pose)))
            .collect();
        return Err(Error::InvalidInput(format!(
            "only {} of {} poses are usable, at least 3 are needed{}{}",
            views.len(),
            joints.len(),
            if why.is_empty() { "" } else { "; " },
            why.join("; ")
        )));
    }
    let start = JointStart {
        camera: cam.clone(),
        plane: nominal.laser_plane,
        hand_cam: x,
        base_board: z,
    };
    let (jopts, pose_noise) = adjustment_options(rig, nominal, opts)?;
    let pred = predicted_covariance(&views, &rig.board, &start, &jopts, opts.sigma_px)?;
    warnings.extend(pred.warnings.iter().cloned());
    let (parameters, covariance, state) = parameter_figures(&pred);
    let named = &pred.named_covariance;
    // The usable poses by stand-off; the median one.
    let mut usable: Vec<(f64, usize)> = poses
        .iter()
        .filter(|p| p.usable)
        .filter_map(|p| p.standoff_mm.map(|s| (s, p.pose)))
        .collect();
    usable.sort_by(|a, b| a.0.total_cmp(&b.0));
    let median = usable.get(usable.len() / 2).copied();
    let standoff = opts.standoff_mm.or(median.map(|m| m.0));
    let point = match (plane, standoff) {
        (Some(pl), Some(s)) => {
            let base = (pred.free.hand_cam || pred.free.base_board)
                .then(|| median.map(|m| m.1))
                .flatten();
            // With the robot calibrated, its corrections move the base point too.
            let dh = |p_f: &Vector3<f64>| -> Vec<(String, Vector3<f64>)> {
                match (base, &rig.robot) {
                    (Some(i), Some(r)) if opts.robot != RobotMode::Fixed => {
                        dh_point_gradients(r, &joints[i], &named.parameters, p_f)
                    }
                    _ => Vec::new(),
                }
            };
            match point_sigma(
                &nominal_chain,
                pl,
                base.map(|i| (i, flange[i])),
                s,
                named,
                &dh,
            ) {
                Ok(p) => Some(p),
                Err(e) => {
                    warnings.push(format!("no point sigma at {s:.1} mm: {e}"));
                    None
                }
            }
        }
        _ => None,
    };
    Ok(PosePlan {
        usable: views.len(),
        poses,
        sigma_px: [opts.sigma_px.0, opts.sigma_px.1],
        points: pred.circles,
        stripe_points: pred.stripe_points,
        parameters,
        covariance,
        state,
        point,
        warnings,
        pose_noise_mm_deg: pose_noise.filter(|_| jopts.robot_noise).map(|p| [p.0, p.1]),
        robot_held: pred
            .robot_fixed
            .iter()
            .map(|(name, reason)| HeldEntry {
                name: name.clone(),
                reason: reason.clone(),
            })
            .collect(),
    })
}

/// The robot the poses are planned for (the rig's, else the nominal calibration's), and
/// a warning when the nominal camera's size is not the rig's; an error for no robot, a
/// bad margin, an invalid camera or board.
fn checked_inputs<'a>(
    rig: &'a Rig,
    nominal: &'a Calibration,
    opts: &PlanOptions,
) -> Result<(&'a Robot, Vec<String>)> {
    let robot = rig
        .robot
        .as_ref()
        .or(nominal.robot.as_ref())
        .ok_or_else(|| {
            Error::InvalidInput("pose planning needs a robot: the rig has none".into())
        })?;
    if !(opts.margin_px.is_finite() && opts.margin_px >= 0.0) {
        return Err(Error::InvalidInput(format!(
            "the image margin must be a non-negative number of pixels, got {}",
            opts.margin_px
        )));
    }
    let cam = &nominal.camera;
    cam.validate()?;
    rig.board.validate()?;
    let mut warnings = Vec::new();
    if (cam.width, cam.height) != (rig.width, rig.height) {
        warnings.push(format!(
            "the nominal camera is {}x{} px, the rig's {}x{}: the nominal's is used",
            cam.width, cam.height, rig.width, rig.height
        ));
    }
    Ok((robot, warnings))
}
