//! Phase 1 of a plan: what a perfect sensor would observe at each pose (the module docs
//! of [`super`]): the target points imaged inside the image with a margin, the laser
//! line on the plate; a pose with too few target points is unusable.

use nalgebra::{Vector2, Vector3};

use super::{Nominal, PlanOptions, PlannedPose};
use crate::calib::conic::predict_centre;
use crate::calib::laser_plane::stripe_line_in_view;
use crate::calib::{CircleObs, ViewObs};
use crate::error::{Error, Result};
use crate::model::board::{Board, BoardKind};
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::kinematics::Robot;
use crate::model::RobotReading;

/// The poses as predicted: one entry per joint vector, the usable ones' observations,
/// and every pose's flange pose `A_i`.
pub(super) struct PredictedPoses {
    pub poses: Vec<PlannedPose>,
    pub views: Vec<ViewObs>,
    pub flange: Vec<Iso3>,
}

/// Each joint vector's flange pose by `robot`, the board pose `(A_i X)^-1 Z` and what a
/// perfect sensor would observe there; an error for a joint vector of the wrong length
/// or non-finite values.
pub(super) fn predict_poses(
    nominal: &Nominal<'_>,
    robot: &Robot,
    board: &Board,
    joints: &[Vec<f64>],
    opts: &PlanOptions,
) -> Result<PredictedPoses> {
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
        let cb = (a * nominal.hand_cam).inverse() * nominal.base_board;
        let pr = predict_view(nominal.camera, board, nominal.plane, &cb, opts);
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
    Ok(PredictedPoses {
        poses,
        views,
        flange,
    })
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

/// What a perfect sensor would observe with the board at `cb` (camera frame), and why
/// the pose is unusable if it is.
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
