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

use std::path::Path;

use nalgebra::{Matrix3, Vector2, Vector3};
use serde::Serialize;

use crate::calib::conic::predict_centre;
use crate::calib::joint::{
    camera_name, dh_point_gradients, predicted_covariance, FreeBlocks, JointOptions, JointStart,
    RobotMode, RobotOptions, IMAGE_FACTOR_FLOOR, POSE_NOISE_FLOOR,
};
use crate::calib::laser_plane::stripe_line_in_view;
use crate::calib::{CircleObs, ViewObs};
use crate::error::{Error, Result};
use crate::model::board::{Board, BoardKind};
use crate::model::camera::Camera;
use crate::model::geometry::{iso_from_rotvec, iso_to_rotvec, Iso3, Plane};
use crate::model::{Calibration, NamedCovariance, Rig, RobotReading, Truth};

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
        hand_cam: t.hand_cam,
        base_board: t.base_board,
        robot: t.robot,
        quality: Default::default(),
        uncertainty: Default::default(),
        covariance: None,
        extra: Default::default(),
    }
}

/// What a perfect sensor would observe at one pose.
struct Predicted {
    circles: Vec<CircleObs>,
    stripe: Vec<[f64; 2]>,
    standoff_mm: Option<f64>,
    tilt_deg: Option<f64>,
    reason: Option<String>,
}

/// The target points' bounding box grown by `margin` (board frame, mm).
fn plate(board: &Board, margin: f64) -> [f64; 4] {
    let last = board.center(board.rows - 1, board.cols - 1);
    let mut x1 = last.x;
    if board.kind == BoardKind::AsymmetricCircles && board.rows > 1 {
        x1 = x1.max(board.center(1, board.cols - 1).x);
    }
    [-margin, x1 + margin, -margin, last.y + margin]
}

fn predict_view(
    cam: &Camera,
    board: &Board,
    plane: Option<&Plane>,
    cb: &Iso3,
    opts: &PlanOptions,
) -> Predicted {
    let nb = cb.rotation * Vector3::z();
    let ob = cb.translation.vector;
    let standoff_mm = (nb.z.abs() > 1e-9)
        .then(|| nb.dot(&ob) / nb.z)
        .filter(|s| *s > 0.0);
    let tilt_deg = Some(nb.z.abs().min(1.0).acos().to_degrees());
    let mut out = Predicted {
        circles: Vec::new(),
        stripe: Vec::new(),
        standoff_mm,
        tilt_deg,
        reason: None,
    };
    // The printed side faces the camera: the board's z axis points away from it.
    if nb.dot(&ob) <= 0.0 {
        out.reason = Some("the camera sees the board from behind or edge-on".into());
        return out;
    }
    let model = opts.adjustment.centre_model;
    for (r, c) in board.indices() {
        let ctr = board.center(r, c);
        if (cb * nalgebra::Point3::from(ctr)).z <= 1e-3 {
            continue;
        }
        let Ok(uv) = predict_centre(cam, cb, &ctr, 0.5 * board.diameter(r, c), model) else {
            continue;
        };
        if uv.iter().all(|x| x.is_finite()) && cam.contains(&uv, opts.margin_px) {
            out.circles.push(CircleObs {
                row: r,
                col: c,
                u: uv.x,
                v: uv.y,
            });
        }
    }
    if let Some(pl) = plane {
        out.stripe = stripe_points(cam, board, pl, cb, opts);
    }
    if out.circles.len() < opts.min_points {
        out.reason = Some(format!(
            "{} target points in the image (at least {} needed)",
            out.circles.len(),
            opts.min_points
        ));
    }
    out
}

/// The laser line on the plate, one point every `stripe_step_px` along its major image
/// axis (module docs).
fn stripe_points(
    cam: &Camera,
    board: &Board,
    pl: &Plane,
    cb: &Iso3,
    opts: &PlanOptions,
) -> Vec<[f64; 2]> {
    let Ok(line) = stripe_line_in_view(pl, cb, cam) else {
        return Vec::new();
    };
    let margin = opts.plate_margin_mm.unwrap_or(board.pitch_mm);
    let [x0, x1, y0, y1] = plate(board, margin);
    let (p, d) = (line.point_board, line.direction_board);
    // Clip p + t d to the plate (slabs).
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for (pk, dk, lo, hi) in [(p.x, d.x, x0, x1), (p.y, d.y, y0, y1)] {
        if dk.abs() < 1e-12 {
            if pk < lo || pk > hi {
                return Vec::new();
            }
            continue;
        }
        let (a, b) = ((lo - pk) / dk, (hi - pk) / dk);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    if t0.partial_cmp(&t1) != Some(std::cmp::Ordering::Less) {
        return Vec::new();
    }
    let samples = 4 * (cam.width + cam.height) as usize;
    let pts: Vec<Vector2<f64>> = (0..=samples)
        .filter_map(|k| {
            let t = t0 + (t1 - t0) * k as f64 / samples as f64;
            let q = p + d * t;
            let pc = cb * nalgebra::Point3::new(q.x, q.y, 0.0);
            if pc.z <= 1e-3 {
                return None;
            }
            cam.project(&pc.coords)
                .ok()
                .filter(|uv| cam.contains(uv, opts.margin_px))
        })
        .collect();
    if pts.len() < 2 {
        return Vec::new();
    }
    let (first, last) = (pts[0], pts[pts.len() - 1]);
    let axis = usize::from((last.y - first.y).abs() > (last.x - first.x).abs());
    let step = opts.stripe_step_px.max(1e-3);
    let mut out = vec![[first.x, first.y]];
    let mut at = first[axis];
    for uv in &pts[1..] {
        if (uv[axis] - at).abs() >= step {
            out.push([uv.x, uv.y]);
            at = uv[axis];
        }
    }
    out
}

/// The point where the pixel `uv`'s ray meets the plane `n . P = d` (`n` need not be
/// unit length: the derivatives w.r.t. its components are taken that way).
pub(crate) fn triangulate_raw(
    cam: &Camera,
    n: &Vector3<f64>,
    d: f64,
    uv: &Vector2<f64>,
) -> Result<Vector3<f64>> {
    let ray = cam.unproject(uv)?;
    let den = n.dot(&ray);
    if den.abs() < 1e-12 {
        return Err(Error::Degenerate(
            "the ray is parallel to the laser plane".into(),
        ));
    }
    Ok(ray * (d / den))
}

/// The point triangulated from `uv` on `plane` (camera frame) and in the base frame
/// through `a x` (`T_base_hand T_hand_cam`), with the derivatives of both w.r.t. the
/// numbers of calibration.json they depend on: `(name, d P_cam, d P_base)`. Camera and
/// plane: the implicit-function Jacobian of `project(P) = uv, n . P = d`; `X`'s rotation
/// vector: central differences (step 1e-6 rad); its translation: `R_A`.
#[allow(clippy::type_complexity)]
pub(crate) fn point_jacobian(
    cam: &Camera,
    plane: &Plane,
    x: &Iso3,
    a: &Iso3,
    uv: &Vector2<f64>,
) -> Result<(
    Vector3<f64>,
    Vector3<f64>,
    Vec<(String, Vector3<f64>, Vector3<f64>)>,
)> {
    let p = triangulate_raw(cam, &plane.normal, plane.d, uv)?;
    let (_, jp, jc) = cam.project_with_jacobians(&p)?;
    let m = Matrix3::from_rows(&[
        jp.row(0).into_owned(),
        jp.row(1).into_owned(),
        plane.normal.transpose(),
    ]);
    let mi = m
        .try_inverse()
        .ok_or_else(|| Error::Degenerate("the viewing ray is tangent to the laser plane".into()))?;
    let ra = a.rotation.to_rotation_matrix().into_inner();
    let rx = x.rotation.to_rotation_matrix().into_inner();
    let to_base = ra * rx;
    let mut out = Vec::new();
    for i in 0..9 {
        let dp = mi * Vector3::new(-jc[(0, i)], -jc[(1, i)], 0.0);
        out.push((camera_name(i), dp, to_base * dp));
    }
    for k in 0..3 {
        let dp = mi * Vector3::new(0.0, 0.0, -p[k]);
        out.push((format!("laser_plane.normal[{k}]"), dp, to_base * dp));
    }
    let dp = mi * Vector3::new(0.0, 0.0, 1.0);
    out.push(("laser_plane.d_mm".into(), dp, to_base * dp));
    let (rv, tv) = iso_to_rotvec(x);
    let h = 1e-6;
    for k in 0..3 {
        let mut e = Vector3::zeros();
        e[k] = h;
        let xp = iso_from_rotvec(&(rv + e), &tv);
        let xm = iso_from_rotvec(&(rv - e), &tv);
        let db = ra * (xp.rotation * p - xm.rotation * p) / (2.0 * h);
        out.push((
            format!("hand_cam.rotation_vector[{k}]"),
            Vector3::zeros(),
            db,
        ));
    }
    for k in 0..3 {
        out.push((
            format!("hand_cam.translation_mm[{k}]"),
            Vector3::zeros(),
            ra.column(k).into_owned(),
        ));
    }
    let pb = a * (x * nalgebra::Point3::from(p));
    Ok((p, pb.coords, out))
}

/// The covariance `G C G^T` of a 3-vector whose derivatives w.r.t. named numbers are
/// `grads` (numbers not in `cov` are held: no contribution).
fn propagate(cov: &NamedCovariance, grads: &[(String, Vector3<f64>)]) -> Matrix3<f64> {
    let idx: Vec<(usize, Vector3<f64>)> = grads
        .iter()
        .filter_map(|(n, g)| cov.index(n).map(|i| (i, *g)))
        .collect();
    let mut c = Matrix3::zeros();
    for (i, gi) in &idx {
        for (j, gj) in &idx {
            c += gi * gj.transpose() * cov.matrix[(*i, *j)];
        }
    }
    c
}

fn sigmas(c: &Matrix3<f64>) -> ([f64; 3], f64) {
    (
        [0, 1, 2].map(|k| c[(k, k)].max(0.0).sqrt()),
        c.trace().max(0.0).sqrt(),
    )
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
    let (x, z) = (nominal.hand_cam, nominal.base_board);
    let plane = nominal.laser_plane.as_ref();
    let mut poses = Vec::new();
    let mut views = Vec::new();
    let mut flange = Vec::new();
    for (i, q) in joints.iter().enumerate() {
        if q.len() != robot.dof() || q.iter().any(|v| !v.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "pose {i}: expected {} finite joint values (degrees), got {:?}",
                robot.dof(),
                q
            )));
        }
        let a = robot.forward(q)?;
        let cb = (a * x).inverse() * z;
        let pr = predict_view(cam, &rig.board, plane, &cb, opts);
        let usable = pr.reason.is_none();
        poses.push(PlannedPose {
            pose: i,
            joints_deg: q.clone(),
            usable,
            reason: pr.reason,
            points: pr.circles.len(),
            stripe_points: pr.stripe.len(),
            standoff_mm: pr.standoff_mm,
            tilt_deg: pr.tilt_deg,
        });
        flange.push(a);
        if usable {
            views.push(ViewObs {
                view: i,
                circles: pr.circles,
                stripe: pr.stripe,
                reading: Some(RobotReading::Joints(joints[i].clone())),
                base_hand: Some(a),
                alternatives: Vec::new(),
                stripe_shape: None,
            });
        }
    }
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
    let mut jopts = JointOptions {
        free: opts.free,
        ..opts.adjustment.clone()
    };
    // The calibration's noise model: the robot-pose noise as planned, never below
    // rig.json's figures; the images' own part at its floor. Without any figure the
    // robot is planned exact (the poses without corrections: what an exact robot's
    // calibration, its pose noise at the floors, gives).
    let floors = rig
        .robot
        .as_ref()
        .map_or((None, None), |r| r.pose_noise_floor());
    let planned = opts
        .pose_noise
        .or_else(|| {
            crate::io::calibration_robot_pose_noise(nominal)
                .ok()
                .flatten()
                .map(|n| (n.sigma_translation_mm, n.sigma_rotation_deg))
                .filter(|(t, r)| t.is_finite() && r.is_finite())
        })
        .or_else(|| {
            (floors.0.is_some() || floors.1.is_some())
                .then(|| (floors.0.unwrap_or(0.0), floors.1.unwrap_or(0.0)))
        });
    let pose_noise = planned.map(|p| {
        (
            p.0.max(floors.0.unwrap_or(0.0)).max(POSE_NOISE_FLOOR.0),
            p.1.max(floors.1.unwrap_or(0.0)).max(POSE_NOISE_FLOOR.1),
        )
    });
    match pose_noise {
        Some(p) if jopts.robot_noise => {
            jopts.robot_floor = floors;
            jopts.initial_robot_sigma = p;
            jopts.initial_image_factor = IMAGE_FACTOR_FLOOR;
        }
        _ => jopts.robot_noise = false,
    }
    if opts.robot != RobotMode::Fixed {
        let nominal = rig.robot.clone().ok_or_else(|| {
            Error::InvalidInput("planning a robot calibration needs rig.json's robot".into())
        })?;
        jopts.robot = Some(RobotOptions {
            nominal,
            mode: opts.robot,
        });
    }
    let pred = predicted_covariance(&views, &rig.board, &start, &jopts, opts.sigma_px)?;
    warnings.extend(pred.warnings.iter().cloned());
    let named = &pred.named_covariance;
    let parameters = named
        .parameters
        .iter()
        .enumerate()
        .map(|(i, n)| SigmaEntry {
            name: n.clone(),
            sigma: named.matrix[(i, i)].max(0.0).sqrt(),
        })
        .collect();
    let covariance = (0..named.matrix.nrows())
        .map(|r| named.matrix.row(r).iter().copied().collect())
        .collect();
    let state = pred
        .param_names
        .iter()
        .enumerate()
        .map(|(i, n)| SigmaEntry {
            name: n.clone(),
            sigma: pred.covariance[(i, i)].max(0.0).sqrt(),
        })
        .collect();
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
            match point_sigma(cam, pl, &x, &z, base.map(|i| (i, flange[i])), s, named, &dh) {
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

/// The point on the laser plane at depth `s` nearest the optical axis, and its sigma.
/// The base-frame point's derivatives per DH correction, from its flange-frame position.
type DhGradients<'a> = dyn Fn(&Vector3<f64>) -> Vec<(String, Vector3<f64>)> + 'a;

#[allow(clippy::too_many_arguments)]
fn point_sigma(
    cam: &Camera,
    pl: &Plane,
    x: &Iso3,
    z: &Iso3,
    base: Option<(usize, Iso3)>,
    s: f64,
    cov: &NamedCovariance,
    dh: &DhGradients<'_>,
) -> Result<PointSigma> {
    let n = pl.normal;
    let h2 = n.x * n.x + n.y * n.y;
    if !(s.is_finite() && s > 0.0) {
        return Err(Error::InvalidInput(format!(
            "the stand-off must be positive, got {s}"
        )));
    }
    if h2 < 1e-12 {
        return Err(Error::Degenerate(
            "the laser plane is perpendicular to the optical axis".into(),
        ));
    }
    let k = (pl.d - n.z * s) / h2;
    let p0 = Vector3::new(n.x * k, n.y * k, s);
    let uv = cam.project(&p0)?;
    let a = base.map_or(Iso3::identity(), |b| b.1);
    let (p, pb, grads) = point_jacobian(cam, pl, x, &a, &uv)?;
    let gc: Vec<(String, Vector3<f64>)> = grads.iter().map(|(n, c, _)| (n.clone(), *c)).collect();
    let (sc, nc) = sigmas(&propagate(cov, &gc));
    let (base_mm, sigma_base_mm, sigma_base_norm_mm, gz) = if base.is_some() {
        let mut gb: Vec<(String, Vector3<f64>)> =
            grads.iter().map(|(n, _, b)| (n.clone(), *b)).collect();
        gb.extend(dh(&(x * nalgebra::Point3::from(p)).coords));
        let (sb, nb) = sigmas(&propagate(cov, &gb));
        (
            Some([pb.x, pb.y, pb.z]),
            Some(sb),
            Some(nb),
            Some(board_frame(z, &pb, &gb)),
        )
    } else {
        (None, None, None, None)
    };
    let (board_mm, sigma_board_mm, sigma_board_norm_mm) = match gz {
        Some((pz, g)) => {
            let (s, n) = sigmas(&propagate(cov, &g));
            (Some([pz.x, pz.y, pz.z]), Some(s), Some(n))
        }
        None => (None, None, None),
    };
    Ok(PointSigma {
        standoff_mm: s,
        pixel: [uv.x, uv.y],
        camera_mm: [p.x, p.y, p.z],
        sigma_camera_mm: sc,
        sigma_camera_norm_mm: nc,
        base_pose: base.map(|b| b.0),
        base_mm,
        sigma_base_mm,
        sigma_base_norm_mm,
        board_mm,
        sigma_board_mm,
        sigma_board_norm_mm,
    })
}

/// The board-frame point `Z^-1 p_b` and its derivatives: the base point's rotated by
/// `R_Z^T`, and `Z`'s own (its rotation vector by central differences, its translation
/// `-R_Z^T e_k`).
fn board_frame(
    z: &Iso3,
    pb: &Vector3<f64>,
    gb: &[(String, Vector3<f64>)],
) -> (Vector3<f64>, Vec<(String, Vector3<f64>)>) {
    let rzt = z.rotation.to_rotation_matrix().into_inner().transpose();
    let at = |zz: &Iso3| (zz.inverse() * nalgebra::Point3::from(*pb)).coords;
    let mut g: Vec<(String, Vector3<f64>)> = gb.iter().map(|(n, v)| (n.clone(), rzt * v)).collect();
    let (rv, tv) = iso_to_rotvec(z);
    let h = 1e-6;
    for k in 0..3 {
        let mut e = Vector3::zeros();
        e[k] = h;
        let d = (at(&iso_from_rotvec(&(rv + e), &tv)) - at(&iso_from_rotvec(&(rv - e), &tv)))
            / (2.0 * h);
        g.push((format!("base_board.rotation_vector[{k}]"), d));
    }
    for k in 0..3 {
        g.push((
            format!("base_board.translation_mm[{k}]"),
            -rzt.column(k).into_owned(),
        ));
    }
    (at(z), g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::camera::DistortionModel;

    /// The triangulation's Jacobian against central differences of the whole map
    /// (unprojection with undistortion, intersection, `A X`), every named number.
    #[test]
    fn point_jacobian_matches_central_differences() {
        let cam = Camera::new(
            1024,
            768,
            1500.0,
            1490.0,
            515.0,
            380.0,
            DistortionModel::OpenCv5,
            [-0.2, 0.1, 1e-3, -1e-3, 0.02],
        )
        .unwrap();
        let plane = Plane::new(Vector3::new(0.6, -0.05, 0.78), 80.0).unwrap();
        let x = iso_from_rotvec(
            &Vector3::new(-0.3, 0.24, 2.9),
            &Vector3::new(29.0, 5.0, 62.0),
        );
        let a = iso_from_rotvec(
            &Vector3::new(0.1, 3.0, 0.2),
            &Vector3::new(480.0, 20.0, 300.0),
        );
        let uv = Vector2::new(640.0, 300.0);
        let (p, pb, grads) = point_jacobian(&cam, &plane, &x, &a, &uv).unwrap();
        // value: the pixel reprojects, the point is on the plane
        assert!((cam.project(&p).unwrap() - uv).norm() < 1e-8);
        assert!(plane.signed_distance(&p).abs() < 1e-9);
        let eval = |name: &str, h: f64| -> (Vector3<f64>, Vector3<f64>) {
            let mut cp = cam.params();
            let (mut n, mut d) = (plane.normal, plane.d);
            let (mut rv, mut tv) = iso_to_rotvec(&x);
            if let Some(i) = (0..9).find(|&i| camera_name(i) == name) {
                cp[i] += h;
            } else if let Some(k) = (0..3).find(|&k| name == format!("laser_plane.normal[{k}]")) {
                n[k] += h;
            } else if name == "laser_plane.d_mm" {
                d += h;
            } else if let Some(k) =
                (0..3).find(|&k| name == format!("hand_cam.rotation_vector[{k}]"))
            {
                rv[k] += h;
            } else if let Some(k) =
                (0..3).find(|&k| name == format!("hand_cam.translation_mm[{k}]"))
            {
                tv[k] += h;
            } else {
                panic!("{name}");
            }
            let c = cam.with_params(&cp);
            let q = triangulate_raw(&c, &n, d, &uv).unwrap();
            let xx = iso_from_rotvec(&rv, &tv);
            // The base point less the nominal one (the same derivative, no cancellation
            // against the flange's metres).
            let rel = (xx * nalgebra::Point3::from(q)) - (x * nalgebra::Point3::from(p));
            (q, a.rotation * rel)
        };
        let mut worst = 0.0f64;
        for (name, gc, gb) in &grads {
            let h = if name.starts_with("camera.distortion") || name.contains("normal") {
                1e-5
            } else if name.contains("rotation_vector") {
                1e-6
            } else {
                1e-3
            };
            let (cp, bp) = eval(name, h);
            let (cm, bm) = eval(name, -h);
            let (fc, fb) = ((cp - cm) / (2.0 * h), (bp - bm) / (2.0 * h));
            let scale = fc.norm().max(fb.norm()).max(1e-3);
            let err = (fc - gc).norm().max((fb - gb).norm()) / scale;
            println!(
                "{name:32} |dP_cam| {:10.4e} |dP_base| {:10.4e} rel. FD diff {err:.1e}",
                gc.norm(),
                gb.norm()
            );
            assert!(err < 1e-5, "{name}: {gc:?} {gb:?} vs {fc:?} {fb:?}");
            worst = worst.max(err);
        }
        assert_eq!(grads.len(), 19);
        assert!(pb.iter().all(|v| v.is_finite()));
        println!("largest relative FD difference {worst:.1e}");
    }
}
