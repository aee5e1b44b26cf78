//! calibration.json's records read back from JSON (what `records.rs` writes): the
//! adjustment summary keys, `views`, `warnings`, `board_scale`, `leave_one_out`,
//! `robot_pose_noise`, `robot_calibration` and `held_blocks`.
//!
//! ## Conventions
//!
//! - A `null` number reads as NaN (the writers write a non-finite number as `null`).
//! - A known key that does not read as its record stays in `extra` (files of other
//!   tools may use the name differently), except `robot_pose_noise`, which is an error
//!   (uncertainty propagation reads it).

use std::path::Path;

use serde_json::{Map, Value};

use super::calibration::{camera_from, plane_from};
use super::json::Obj;
use crate::error::Result;
use crate::model::kinematics::Robot;
use crate::model::Calibration;
use crate::model::{
    AdjustmentSummary, BoardScaleCheck, CalibrationRecords, DhCorrection, LaserBoardFigure,
    LeaveOneOut, LooFold, LooView, RejectCounts, RobotCalibration, RobotPoseNoise, RobotPoseView,
    StripeChannel, StripeChannelChoice, StripeExtraction, ViewRecord,
};

/// The top-level keys of the adjustment summary ([`AdjustmentSummary`]).
const SUMMARY_KEYS: [&str; 6] = [
    "method",
    "centre_model",
    "base_board_orientation",
    "stripe_rms_mm",
    "residual_sigma_px",
    "stripe_off_plane",
];

/// A number, NaN when `null` or absent.
pub(super) fn num(o: &Obj<'_>, key: &str) -> Result<f64> {
    Ok(o.opt(key).map(|v| v.f64()).transpose()?.unwrap_or(f64::NAN))
}

/// A number, `None` when `null`, absent or not finite.
pub(super) fn opt_num(o: &Obj<'_>, key: &str) -> Result<Option<f64>> {
    Ok(o.opt(key)
        .map(|v| v.f64())
        .transpose()?
        .filter(|x| x.is_finite()))
}

/// The records of a calibration.json's root, and the root's keys beyond `fixed` that
/// are not read into them (unknown keys, or a known key that does not read as its
/// record), in file order. `robot` is the calibration's (a robot calibration's refined
/// table).
pub(super) fn records_from(
    root: &Obj<'_>,
    fixed: &[&str],
    robot: Option<&Robot>,
) -> Result<(CalibrationRecords, Map<String, Value>)> {
    let mut read: Vec<&str> = Vec::new();
    let mut take = |keys: &[&'static str], ok: bool| {
        if ok {
            read.extend_from_slice(keys);
        }
    };
    let summary = root.opt("method").and_then(|_| summary_from(root).ok());
    take(&SUMMARY_KEYS, summary.is_some());
    let views = root.opt("views").and_then(|v| {
        v.arr()
            .ok()?
            .iter()
            .map(|x| view_record_from(&x.obj()?))
            .collect::<Result<Vec<_>>>()
            .ok()
    });
    take(&["views"], views.is_some());
    let warnings = root.opt("warnings").and_then(|v| strings(&v));
    take(&["warnings"], warnings.is_some());
    let board_scale = root
        .opt_obj("board_scale")
        .ok()
        .flatten()
        .and_then(|o| board_scale_from(&o).ok());
    take(&["board_scale"], board_scale.is_some());
    let leave_one_out = root
        .opt_obj("leave_one_out")
        .ok()
        .flatten()
        .and_then(|o| leave_one_out_from(&o).ok());
    take(&["leave_one_out"], leave_one_out.is_some());
    let robot_pose_noise = root
        .opt_obj("robot_pose_noise")?
        .map(|n| robot_pose_noise_from(&n))
        .transpose()?;
    take(&["robot_pose_noise"], robot_pose_noise.is_some());
    let robot_calibration = match (root.opt_obj("robot_calibration").ok().flatten(), robot) {
        (Some(o), Some(r)) => robot_calibration_from(&o, r).ok(),
        _ => None,
    };
    take(&["robot_calibration"], robot_calibration.is_some());
    let held_blocks = root.opt("held_blocks").and_then(|v| strings(&v));
    take(&["held_blocks"], held_blocks.is_some());
    let stripe_channel = root
        .opt("stripe_channel")
        .and_then(|_| stripe_channel_from(root).ok());
    if let Some(c) = &stripe_channel {
        take(&["stripe_channel"], true);
        take(&["stripe_channel_scores"], c.scores.is_some());
    }
    let records = CalibrationRecords {
        summary,
        views,
        warnings: warnings.unwrap_or_default(),
        board_scale,
        leave_one_out,
        robot_pose_noise,
        robot_calibration,
        held_blocks,
        stripe_channel,
    };
    let known: Vec<&str> = fixed.iter().copied().chain(read).collect();
    Ok((records, root.extra(&known)))
}

/// The records among keys beyond calibration.json's fixed ones (a caller's `extra`
/// map, e.g. the Python constructor's), read as [`calibration_from_json`] reads them,
/// and the keys left over. Errors name `extra.<key>` (a malformed `robot_pose_noise`).
///
/// [`calibration_from_json`]: super::calibration_from_json
pub fn calibration_records_from(
    extra: Map<String, Value>,
    robot: Option<&Robot>,
) -> Result<(CalibrationRecords, Map<String, Value>)> {
    let v = Value::Object(extra);
    let root = Obj::root(Path::new("extra"), &v)?;
    records_from(&root, &[], robot)
}

/// An array of strings, `None` when it is not one.
pub(super) fn strings(v: &super::json::Val<'_>) -> Option<Vec<String>> {
    v.arr()
        .ok()?
        .iter()
        .map(|s| s.str().ok().map(str::to_string))
        .collect()
}

/// The summary keys (see [`super::calibration_extra`]).
fn summary_from(root: &Obj<'_>) -> Result<AdjustmentSummary> {
    let s = root.obj("residual_sigma_px")?;
    Ok(AdjustmentSummary {
        method: root.req("method")?.str()?.to_string(),
        centre_model: root.req("centre_model")?.str()?.to_string(),
        base_board_orientation: root.opt_str("base_board_orientation")?.map(str::to_string),
        stripe_rms_mm: num(root, "stripe_rms_mm")?,
        residual_sigma_px: (num(&s, "circle")?, num(&s, "stripe")?),
        stripe_off_plane: root.count("stripe_off_plane")?,
    })
}

/// `stripe_channel` and `stripe_channel_scores` (see [`super::records::records_after_extra`]).
fn stripe_channel_from(root: &Obj<'_>) -> Result<StripeChannelChoice> {
    let channel = StripeChannel::from_name(root.req("stripe_channel")?.str()?)?;
    let scores = root
        .opt_obj("stripe_channel_scores")?
        .map(|o| {
            o.map()
                .iter()
                .map(|(k, v)| {
                    let score = v
                        .as_f64()
                        .ok_or_else(|| o.err(format!("{k}: expected a number")))?;
                    Ok((StripeChannel::from_name(k)?, score))
                })
                .collect::<Result<Vec<_>>>()
        })
        .transpose()?;
    Ok(StripeChannelChoice { channel, scores })
}

/// One entry of `views` (see [`super::view_record_to_json`]).
fn view_record_from(o: &Obj<'_>) -> Result<ViewRecord> {
    Ok(ViewRecord {
        view: o.count("view")?,
        used: o.req("used")?.bool()?,
        circles: o.count("circles")?,
        stripe_points: o.count("stripe_points")?,
        stripe_off_plane: o.count("stripe_off_plane")?,
        circle_rms_px: opt_num(o, "circle_rms_px")?,
        stripe_rms_px: opt_num(o, "stripe_rms_px")?,
        outlier: o.opt_bool("outlier")?,
        note: o.opt_str("note")?.map(str::to_string),
        stripe_extraction: o
            .opt_obj("stripe_extraction")?
            .map(|e| stripe_extraction_from(&e))
            .transpose()?,
    })
}

/// A view's `stripe_extraction` (see [`super::stripe_extraction_to_json`];
/// `saturated_share` follows from the counts).
fn stripe_extraction_from(e: &Obj<'_>) -> Result<StripeExtraction> {
    let l = e.obj("left_out")?;
    let r = e.obj("scan_lines_without_point")?;
    Ok(StripeExtraction {
        lines: e.count("scan_lines")?,
        rejected: RejectCounts {
            no_peak: r.count("no_peak")?,
            multiple_peaks: r.count("multiple_peaks")?,
            saturated: r.count("saturated")?,
            shape: r.count("shape")?,
            border: r.count("border")?,
            isolated: r.count("isolated")?,
            reflections: e.count("reflections_left_out")?,
            reflection_only: r.count("reflection_only")?,
            ambiguous: e.count("ambiguous_scan_lines")?,
        },
        found: e.count("found")?,
        at_edge: l.count("at_edge")?,
        uneven_background: l.count("uneven_background")?,
        oblique: l.count("oblique")?,
        saturated: e.count("saturated")?,
        width_px: num(e, "width_px")?,
        along_line: e.count("along_line")?,
    })
}

/// `board_scale` (see [`super::self_checks_extra`]).
fn board_scale_from(b: &Obj<'_>) -> Result<BoardScaleCheck> {
    Ok(BoardScaleCheck {
        scale: num(b, "scale")?,
        sigma: num(b, "sigma")?,
        declared_mm: num(b, "declared_mm")?,
        implied_mm: num(b, "implied_mm")?,
        estimated: b.req("estimated")?.bool()?,
        disagrees: b.req("disagrees")?.bool()?,
        tolerance: num(b, "tolerance")?,
    })
}

/// `robot_calibration` (see [`super::robot_calibration_extra`]) with the calibration's
/// refined `robot`.
pub(super) fn robot_calibration_from(o: &Obj<'_>, robot: &Robot) -> Result<RobotCalibration> {
    let mut estimated = Vec::new();
    for item in o.req("estimated")?.arr()? {
        let e = item.obj()?;
        estimated.push(DhCorrection {
            name: e.req("name")?.str()?.to_string(),
            correction: num(&e, "correction")?,
            sigma: num(&e, "sigma")?,
        });
    }
    let mut fixed = Vec::new();
    for item in o.req("fixed")?.arr()? {
        let f = item.obj()?;
        fixed.push((
            f.req("name")?.str()?.to_string(),
            f.req("reason")?.str()?.to_string(),
        ));
    }
    Ok(RobotCalibration {
        mode: o.req("mode")?.str()?.to_string(),
        robot: robot.clone(),
        estimated,
        fixed,
    })
}

/// `robot_pose_noise` (see [`super::robot_pose_noise_extra`]); a `null` (or absent)
/// number reads as NaN.
fn robot_pose_noise_from(o: &Obj<'_>) -> Result<RobotPoseNoise> {
    let f = o.obj("at_floor")?;
    let floor = o.opt_obj("floor")?;
    let floor_num = |key: &str| floor.as_ref().map_or(Ok(f64::NAN), |f| num(f, key));
    let read_views = |key: &str| -> Result<Vec<RobotPoseView>> {
        let mut views = Vec::new();
        let Some(list) = o.opt(key) else {
            return Ok(views);
        };
        for item in list.arr()? {
            let v = item.obj()?;
            views.push(RobotPoseView {
                view: v.count("view")?,
                translation_mm: num(&v, "translation_mm")?,
                rotation_deg: num(&v, "rotation_deg")?,
                test: num(&v, "test")?,
            });
        }
        Ok(views)
    };
    o.req("views")?;
    let views = read_views("views")?;
    let left_out = read_views("left_out")?;
    Ok(RobotPoseNoise {
        sigma_translation_mm: num(o, "translation_mm")?,
        sigma_rotation_deg: num(o, "rotation_deg")?,
        translation_at_floor: f.req("translation")?.bool()?,
        rotation_at_floor: f.req("rotation")?.bool()?,
        floor_translation_mm: floor_num("translation_mm")?,
        floor_rotation_deg: floor_num("rotation_deg")?,
        image_factor: match o.opt("image_factor") {
            Some(v) if !v.is_null() => Some(v.f64()?),
            _ => None,
        },
        kinematic_mm: match o.opt("kinematic_mm") {
            Some(v) if !v.is_null() => Some(v.f64()?),
            _ => None,
        },
        kinematic_deg: match o.opt("kinematic_deg") {
            Some(v) if !v.is_null() => Some(v.f64()?),
            _ => None,
        },
        image_factor_at_floor: match f.opt("image") {
            Some(v) => v.bool()?,
            None => false,
        },
        views,
        left_out,
    })
}

/// The robot-pose noise a calibration holds (its record `robot_pose_noise`), `None`
/// when it has none (the paper's method, files written before it existed; the reader
/// refuses a malformed one).
pub fn calibration_robot_pose_noise(c: &Calibration) -> Result<Option<RobotPoseNoise>> {
    Ok(c.records.robot_pose_noise.clone())
}

/// `leave_one_out` (see [`super::self_checks_extra`]); a `null` number reads as NaN,
/// a view without `fold` (files written before it existed) has none.
fn leave_one_out_from(o: &Obj<'_>) -> Result<LeaveOneOut> {
    let mut views = Vec::new();
    for item in o.req("views")?.arr()? {
        let v = item.obj()?;
        let fold = v
            .opt_obj("fold")?
            .map(|f| -> Result<LooFold> {
                Ok(LooFold {
                    camera: camera_from(&f.obj("camera")?)?,
                    plane: plane_from(&f.obj("laser_plane")?)?,
                    cam_board: f.obj("cam_board")?.pose()?,
                })
            })
            .transpose()?;
        views.push(LooView {
            view: v.count("view")?,
            points: v.count("points")?,
            board_rms_px: num(&v, "board_rms_px")?,
            board_rms_mm: num(&v, "board_rms_mm")?,
            stripe_points: v.count("stripe_points")?,
            stripe_rms_mm: opt_num(&v, "stripe_rms_mm")?,
            disagrees: v.req("disagrees")?.bool()?,
            fold,
        });
    }
    let laser_board = o
        .opt_obj("laser_board")?
        .map(|l| -> Result<LaserBoardFigure> {
            Ok(LaserBoardFigure {
                median_mm: num(&l, "median_mm")?,
                p95_mm: num(&l, "p95_mm")?,
                points: l.count("points")?,
            })
        })
        .transpose()?;
    Ok(LeaveOneOut {
        views,
        median_board_rms_px: num(o, "median_board_rms_px")?,
        median_board_rms_mm: num(o, "median_board_rms_mm")?,
        median_stripe_rms_mm: opt_num(o, "median_stripe_rms_mm")?,
        laser_board,
    })
}

/// The leave-one-view-out figures a calibration holds (its record `leave_one_out`),
/// `None` when it has none.
pub fn calibration_leave_one_out(c: &Calibration) -> Result<Option<LeaveOneOut>> {
    Ok(c.records.leave_one_out.clone())
}
