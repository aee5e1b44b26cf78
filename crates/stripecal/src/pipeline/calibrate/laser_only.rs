//! A calibration whose camera, `X` and `Z` are held from an earlier one (`--laser-only`,
//! or `--fix camera,hand_cam,base_board`): every view's board pose follows from its
//! robot pose, `T_cam_board = (A X)^-1 Z`, so no camera stage is needed and a few laser
//! views suffice. A symmetric board's labelling is the one whose points the predicted
//! pose images closest to the detections. The laser plane starts from its fit on these
//! poses and is refined by the adjustment with everything else held.

use super::held::Held;
use super::labels::{relabel, Labelled};
use super::report::{build_report, Stage};
use super::stages::{joint_options, self_checks};
use super::stripe_select::select_stripes;
use super::views::mark_used;
use super::{CalibrateOptions, CalibrationReport, ViewStatus};
use crate::calib::conic::predict_centre;
use crate::calib::joint::{joint_adjustment, JointStart};
use crate::calib::laser_plane::fit_laser_plane;
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::camera::Camera;
use crate::model::geometry::Iso3;
use crate::model::Rig;

/// The pipeline with the chain held (module docs); `views`' robot poses are already
/// checked finite by the caller.
pub(super) fn calibrate_held_chain(
    views: &[ViewObs],
    rig: &Rig,
    opts: &CalibrateOptions,
    held: &Held<'_>,
) -> Result<CalibrationReport> {
    let board = &rig.board;
    let from = held.from;
    let mut warnings = Vec::new();
    let mut status: Vec<ViewStatus> = views.iter().map(ViewStatus::observed).collect();
    let labelled: Vec<Labelled> = views
        .iter()
        .map(|v| predicted_labelling(v, board, &from.camera, &from.hand_cam, &from.base_board))
        .collect();
    for (view, note) in labelled.iter().filter_map(|l| l.as_ref().err()) {
        warnings.push(note.clone());
        if let Some(s) = status.iter_mut().find(|s| s.view == *view) {
            s.note = Some(note.clone());
        }
    }
    let (obs, poses) = select_stripes(&labelled, &from.camera, &mut status)?;
    let pv: Vec<(Iso3, Vec<[f64; 2]>)> = poses
        .iter()
        .zip(&obs)
        .filter(|(_, v)| !v.stripe.is_empty())
        .map(|(p, v)| (*p, v.stripe.clone()))
        .collect();
    if pv.len() < 2 {
        let why = if pv.is_empty() {
            format!(": {}", super::stages::no_stripe_reason(&obs))
        } else {
            String::new()
        };
        return Err(Error::InvalidInput(format!(
            "the laser plane needs stripe points on the board in at least 2 views, got {} \
             (of {} views whose board was found){why}",
            pv.len(),
            obs.len()
        )));
    }
    let plane = fit_laser_plane(&pv, &from.camera)?;
    warnings.extend(plane.warnings.iter().cloned());
    let mut start = JointStart {
        camera: from.camera.clone(),
        plane: Some(plane.plane),
        hand_cam: from.hand_cam,
        base_board: from.base_board,
    };
    held.apply(&mut start);
    let jopts = joint_options(opts, rig);
    let adj = joint_adjustment(&obs, board, &start, &jopts)?;
    warnings.extend(adj.warnings.iter().cloned());
    mark_used(&mut status, &obs);
    let checks = self_checks(&obs, board, &adj, &jopts, opts, &mut warnings)?;
    let stage = Stage {
        board_stripe: None,
        camera: None,
        plane: Some(plane),
        axzb: None,
        start,
        adjustment: adj,
        frame_note: None,
        views_used: obs.len(),
        checks,
        held: Some(held),
    };
    Ok(build_report(stage, rig, opts, status, warnings))
}

/// View `v` with its board pose predicted from its robot pose and, for a symmetric
/// board, the labelling whose points that pose images closest to the detections.
fn predicted_labelling(
    v: &ViewObs,
    board: &Board,
    camera: &Camera,
    x: &Iso3,
    z: &Iso3,
) -> Labelled {
    let Some(a) = v.base_hand else {
        return Err((v.view, format!("view {}: left out, no robot pose", v.view)));
    };
    let cb = (a * x).inverse() * z;
    let mut best: Option<(f64, ViewObs)> = None;
    let candidates = std::iter::once(None).chain(v.alternatives.iter().copied().map(Some));
    for sym in candidates {
        let relabelled = relabel(v, board, sym);
        let rms = image_rms(&relabelled, board, camera, &cb);
        if best.as_ref().is_none_or(|(b, _)| rms < *b) {
            best = Some((rms, relabelled));
        }
    }
    match best {
        Some((rms, v2)) if rms.is_finite() => Ok((v2, cb)),
        _ => Err((
            v.view,
            format!(
                "view {}: left out: the board pose its robot pose predicts does not image the board",
                v.view
            ),
        )),
    }
}

/// RMS image distance between the view's points and their projections at `cb`.
fn image_rms(v: &ViewObs, board: &Board, camera: &Camera, cb: &Iso3) -> f64 {
    let mut ss = 0.0;
    for c in &v.circles {
        let Ok(uv) = predict_centre(
            camera,
            cb,
            &board.center(c.row, c.col),
            0.0,
            crate::calib::conic::CentreModel::Naive,
        ) else {
            return f64::INFINITY;
        };
        ss += (uv.x - c.u).powi(2) + (uv.y - c.v).powi(2);
    }
    (ss / v.circles.len().max(1) as f64).sqrt()
}
