//! calibration.json's typed records as JSON: the `uncertainty` block, the per-view
//! `views` entries, the adjustment summary keys (`method`, `centre_model`,
//! `base_board_orientation`, `stripe_rms_mm`, `residual_sigma_px`, `stripe_off_plane`,
//! `warnings`) and the robot-pose noise (`robot_pose_noise`).
//!
//! Non-finite numbers (an unobservable parameter's sigma, a view without residuals) are
//! written as `null`; key order is the contract's.

use serde_json::{Map, Value};

use crate::model::{
    AdjustmentSummary, BoardScaleCheck, CalibrationRecords, CameraSigma, LeaveOneOut, PlaneSigma,
    PoseSigma, RobotCalibration, RobotPoseNoise, StripeExtraction, Uncertainty, ViewRecord,
};

/// A number, or `null` when it is not finite.
fn finite_or_null(x: f64) -> Value {
    if x.is_finite() {
        Value::from(x)
    } else {
        Value::Null
    }
}

fn array(xs: &[f64]) -> Value {
    Value::Array(xs.iter().map(|x| finite_or_null(*x)).collect())
}

fn camera_sigma(s: &CameraSigma) -> Value {
    let mut m = Map::new();
    for (k, v) in [("fu", s.fu), ("fv", s.fv), ("u0", s.u0), ("v0", s.v0)] {
        m.insert(k.into(), finite_or_null(v));
    }
    m.insert("distortion".into(), array(&s.distortion));
    Value::Object(m)
}

fn plane_sigma(s: &PlaneSigma) -> Value {
    let mut m = Map::new();
    m.insert("normal".into(), array(&s.normal));
    m.insert("d_mm".into(), finite_or_null(s.d_mm));
    Value::Object(m)
}

fn pose_sigma(s: &PoseSigma) -> Value {
    let mut m = Map::new();
    m.insert("rotation_vector".into(), array(&s.rotation_vector));
    m.insert("translation_mm".into(), array(&s.translation_mm));
    Value::Object(m)
}

/// The `uncertainty` object: the blocks present, in the contract's order.
pub fn uncertainty_to_json(u: &Uncertainty) -> Map<String, Value> {
    let mut m = Map::new();
    if let Some(c) = &u.camera {
        m.insert("camera".into(), camera_sigma(c));
    }
    if let Some(p) = &u.laser_plane {
        m.insert("laser_plane".into(), plane_sigma(p));
    }
    for (k, t) in [("hand_cam", &u.hand_cam), ("base_board", &u.base_board)] {
        if let Some(t) = t {
            m.insert(k.into(), pose_sigma(t));
        }
    }
    m
}

/// One entry of `views`.
pub fn view_record_to_json(r: &ViewRecord) -> Value {
    let mut m = Map::new();
    m.insert("view".into(), Value::from(r.view));
    m.insert("used".into(), Value::from(r.used));
    m.insert("circles".into(), Value::from(r.circles));
    m.insert("stripe_points".into(), Value::from(r.stripe_points));
    m.insert("stripe_off_plane".into(), Value::from(r.stripe_off_plane));
    let opt = |x: Option<f64>| x.map_or(Value::Null, finite_or_null);
    m.insert("circle_rms_px".into(), opt(r.circle_rms_px));
    m.insert("stripe_rms_px".into(), opt(r.stripe_rms_px));
    m.insert("outlier".into(), r.outlier.map_or(Value::Null, Value::from));
    m.insert(
        "note".into(),
        r.note.as_deref().map_or(Value::Null, Value::from),
    );
    if let Some(e) = &r.stripe_extraction {
        m.insert("stripe_extraction".into(), stripe_extraction_to_json(e));
    }
    Value::Object(m)
}

/// A view's `stripe_extraction`: what the extractor found and left out, the line's
/// width and saturation.
pub fn stripe_extraction_to_json(e: &StripeExtraction) -> Value {
    let r = &e.rejected;
    serde_json::json!({
        "scan_lines": e.lines,
        "found": e.found,
        "left_out": {
            "at_edge": e.at_edge,
            "uneven_background": e.uneven_background,
            "oblique": e.oblique,
        },
        "saturated": e.saturated,
        "saturated_share": finite_or_null(e.saturated_share()),
        "width_px": finite_or_null(e.width_px),
        "along_line": e.along_line,
        "scan_lines_without_point": {
            "no_peak": r.no_peak,
            "multiple_peaks": r.multiple_peaks,
            "saturated": r.saturated,
            "shape": r.shape,
            "border": r.border,
            "isolated": r.isolated,
            "reflection_only": r.reflection_only,
        },
        "reflections_left_out": r.reflections,
        "ambiguous_scan_lines": r.ambiguous,
    })
}

/// The calibration's keys beyond the contract's fixed ones, in this order: the summary,
/// `views`, and `warnings` when there are any.
pub fn calibration_extra(
    summary: &AdjustmentSummary,
    views: &[ViewRecord],
    warnings: &[String],
) -> Map<String, Value> {
    let mut m = summary_to_json(summary);
    m.insert(
        "views".into(),
        Value::Array(views.iter().map(view_record_to_json).collect()),
    );
    if !warnings.is_empty() {
        m.insert("warnings".into(), warnings_to_json(warnings));
    }
    m
}

/// The summary's keys: `method`, `centre_model`, `base_board_orientation` (when set),
/// `stripe_rms_mm`, `residual_sigma_px` (`circle`, `stripe`), `stripe_off_plane`.
pub fn summary_to_json(summary: &AdjustmentSummary) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("method".into(), Value::from(summary.method.as_str()));
    m.insert(
        "centre_model".into(),
        Value::from(summary.centre_model.as_str()),
    );
    if let Some(o) = &summary.base_board_orientation {
        m.insert("base_board_orientation".into(), Value::from(o.as_str()));
    }
    m.insert(
        "stripe_rms_mm".into(),
        finite_or_null(summary.stripe_rms_mm),
    );
    let mut s = Map::new();
    s.insert("circle".into(), finite_or_null(summary.residual_sigma_px.0));
    s.insert("stripe".into(), finite_or_null(summary.residual_sigma_px.1));
    m.insert("residual_sigma_px".into(), Value::Object(s));
    m.insert(
        "stripe_off_plane".into(),
        Value::from(summary.stripe_off_plane),
    );
    m
}

/// Appends a calibration's records to calibration.json's root `m`, in this order: the
/// summary, `views`, `warnings` (when any), `board_scale`, `leave_one_out`,
/// `robot_pose_noise`, `robot_calibration`, `held_blocks` (each when present).
pub(super) fn records_value(m: &mut Map<String, Value>, r: &CalibrationRecords) {
    if let Some(s) = &r.summary {
        m.extend(summary_to_json(s));
    }
    if let Some(v) = &r.views {
        m.insert(
            "views".into(),
            Value::Array(v.iter().map(view_record_to_json).collect()),
        );
    }
    if !r.warnings.is_empty() {
        m.insert("warnings".into(), warnings_to_json(&r.warnings));
    }
    m.extend(self_checks_extra(
        r.board_scale.as_ref(),
        r.leave_one_out.as_ref(),
    ));
    if let Some(n) = &r.robot_pose_noise {
        m.extend(robot_pose_noise_extra(n));
    }
    if let Some(rc) = &r.robot_calibration {
        m.extend(robot_calibration_extra(rc));
    }
    if let Some(h) = &r.held_blocks {
        m.insert("held_blocks".into(), Value::from(h.clone()));
    }
}

/// Appends the records calibration.json holds after the keys of a calibration's
/// `extra` (where the code before their types wrote them, so a file keeps its bytes):
/// `stripe_channel` and `stripe_channel_scores` (when present; a record replaces an
/// `extra` key of its name).
pub(super) fn records_after_extra(m: &mut Map<String, Value>, r: &CalibrationRecords) {
    if let Some(s) = &r.stripe_channel {
        m.insert("stripe_channel".into(), Value::from(s.channel.name()));
        if let Some(scores) = &s.scores {
            m.insert(
                "stripe_channel_scores".into(),
                Value::Object(
                    scores
                        .iter()
                        .map(|(c, x)| (c.name().to_string(), finite_or_null(*x)))
                        .collect(),
                ),
            );
        }
    }
}

/// calibration.json's `board_scale` and `leave_one_out` keys (extra keys) of the checks
/// that ran.
pub fn self_checks_extra(
    board_scale: Option<&BoardScaleCheck>,
    loo: Option<&LeaveOneOut>,
) -> Map<String, Value> {
    let mut m = Map::new();
    if let Some(c) = board_scale {
        m.insert("board_scale".into(), board_scale_to_json(c));
    }
    if let Some(l) = loo {
        m.insert("leave_one_out".into(), leave_one_out_to_json(l));
    }
    m
}

/// `board_scale`: `scale`, `sigma`, `declared_mm`, `implied_mm`, `estimated`,
/// `disagrees`, `tolerance`.
pub fn board_scale_to_json(c: &BoardScaleCheck) -> Value {
    let mut b = Map::new();
    b.insert("scale".into(), finite_or_null(c.scale));
    b.insert("sigma".into(), finite_or_null(c.sigma));
    b.insert("declared_mm".into(), finite_or_null(c.declared_mm));
    b.insert("implied_mm".into(), finite_or_null(c.implied_mm));
    b.insert("estimated".into(), Value::from(c.estimated));
    b.insert("disagrees".into(), Value::from(c.disagrees));
    b.insert("tolerance".into(), finite_or_null(c.tolerance));
    Value::Object(b)
}

/// `leave_one_out`: per view `views` (`view`, `points`, `board_rms_px`, `board_rms_mm`,
/// `stripe_points`, `stripe_rms_mm`, `disagrees`, `fold` when kept), the medians and
/// `laser_board` when scored.
pub fn leave_one_out_to_json(l: &LeaveOneOut) -> Value {
    let opt = |x: Option<f64>| x.map_or(Value::Null, finite_or_null);
    let views = l
        .views
        .iter()
        .map(|v| {
            let mut o = Map::new();
            o.insert("view".into(), Value::from(v.view));
            o.insert("points".into(), Value::from(v.points));
            o.insert("board_rms_px".into(), finite_or_null(v.board_rms_px));
            o.insert("board_rms_mm".into(), finite_or_null(v.board_rms_mm));
            o.insert("stripe_points".into(), Value::from(v.stripe_points));
            o.insert("stripe_rms_mm".into(), opt(v.stripe_rms_mm));
            o.insert("disagrees".into(), Value::from(v.disagrees));
            if let Some(f) = &v.fold {
                let mut fo = Map::new();
                fo.insert("camera".into(), super::calibration::camera_value(&f.camera));
                fo.insert(
                    "laser_plane".into(),
                    super::calibration::plane_value(&f.plane),
                );
                fo.insert("cam_board".into(), super::json::pose_value(&f.cam_board));
                o.insert("fold".into(), Value::Object(fo));
            }
            Value::Object(o)
        })
        .collect();
    let mut o = Map::new();
    o.insert("views".into(), Value::Array(views));
    o.insert(
        "median_board_rms_px".into(),
        finite_or_null(l.median_board_rms_px),
    );
    o.insert(
        "median_board_rms_mm".into(),
        finite_or_null(l.median_board_rms_mm),
    );
    o.insert("median_stripe_rms_mm".into(), opt(l.median_stripe_rms_mm));
    if let Some(f) = &l.laser_board {
        let mut lb = Map::new();
        lb.insert("median_mm".into(), finite_or_null(f.median_mm));
        lb.insert("p95_mm".into(), finite_or_null(f.p95_mm));
        lb.insert("points".into(), Value::from(f.points));
        o.insert("laser_board".into(), Value::Object(lb));
    }
    Value::Object(o)
}

/// calibration.json's `robot_pose_noise` key (an extra key): `translation_mm` and
/// `rotation_deg` (one-sigma per component), `image_factor` (the factor of the part of
/// each view's pose error its own image makes; `null` when not modelled),
/// `kinematic_mm`, `kinematic_deg` (the DH error sizes whose effect the covariance carries; `null` without
/// joint readings), `at_floor`
/// (`translation`, `rotation`, `image`), `floor` (`translation_mm`, `rotation_deg`) and
/// `views` (`view`, `translation_mm`, `rotation_deg`, `test`; a non-finite test is
/// `null`), `left_out` (the same for the views left out by their test). Read back by
/// [`super::calibration_robot_pose_noise`].
pub fn robot_pose_noise_extra(n: &RobotPoseNoise) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("robot_pose_noise".into(), robot_pose_noise_to_json(n));
    m
}

/// The value of `robot_pose_noise` (see [`robot_pose_noise_extra`]).
pub fn robot_pose_noise_to_json(n: &RobotPoseNoise) -> Value {
    let mut o = Map::new();
    o.insert(
        "translation_mm".into(),
        finite_or_null(n.sigma_translation_mm),
    );
    o.insert("rotation_deg".into(), finite_or_null(n.sigma_rotation_deg));
    o.insert(
        "image_factor".into(),
        n.image_factor.map_or(Value::Null, finite_or_null),
    );
    o.insert(
        "kinematic_mm".into(),
        n.kinematic_mm.map_or(Value::Null, finite_or_null),
    );
    o.insert(
        "kinematic_deg".into(),
        n.kinematic_deg.map_or(Value::Null, finite_or_null),
    );
    let mut f = Map::new();
    f.insert("translation".into(), Value::from(n.translation_at_floor));
    f.insert("rotation".into(), Value::from(n.rotation_at_floor));
    f.insert("image".into(), Value::from(n.image_factor_at_floor));
    o.insert("at_floor".into(), Value::Object(f));
    let mut f = Map::new();
    f.insert(
        "translation_mm".into(),
        finite_or_null(n.floor_translation_mm),
    );
    f.insert("rotation_deg".into(), finite_or_null(n.floor_rotation_deg));
    o.insert("floor".into(), Value::Object(f));
    let views = |vs: &[crate::model::RobotPoseView]| {
        vs.iter()
            .map(|v| {
                let mut m = Map::new();
                m.insert("view".into(), Value::from(v.view));
                m.insert("translation_mm".into(), finite_or_null(v.translation_mm));
                m.insert("rotation_deg".into(), finite_or_null(v.rotation_deg));
                m.insert("test".into(), finite_or_null(v.test));
                Value::Object(m)
            })
            .collect()
    };
    o.insert("views".into(), Value::Array(views(&n.views)));
    o.insert("left_out".into(), Value::Array(views(&n.left_out)));
    Value::Object(o)
}

/// The `warnings` array.
pub fn warnings_to_json(warnings: &[String]) -> Value {
    Value::Array(warnings.iter().map(|w| Value::from(w.as_str())).collect())
}

/// calibration.json's extra key `robot_calibration` (`--robot`): `{"mode", "estimated":
/// [{"name", "correction", "sigma"}], "fixed": [{"name", "reason"}]}`; names are the
/// covariance's (`robot.joints[i].theta0_deg`, 0-based rows), corrections the refined
/// value minus rig.json's (deg or mm).
pub fn robot_calibration_extra(rc: &RobotCalibration) -> Map<String, Value> {
    let mut out = Map::new();
    out.insert("robot_calibration".into(), robot_calibration_to_json(rc));
    out
}

/// The value of `robot_calibration` (see [`robot_calibration_extra`]).
pub fn robot_calibration_to_json(rc: &RobotCalibration) -> Value {
    let mut o = Map::new();
    o.insert("mode".into(), Value::from(rc.mode.clone()));
    let est = rc
        .estimated
        .iter()
        .map(|e| {
            let mut m = Map::new();
            m.insert("name".into(), Value::from(e.name.clone()));
            m.insert("correction".into(), finite_or_null(e.correction));
            m.insert("sigma".into(), finite_or_null(e.sigma));
            Value::Object(m)
        })
        .collect();
    o.insert("estimated".into(), Value::Array(est));
    let fixed = rc
        .fixed
        .iter()
        .map(|(n, why)| {
            let mut m = Map::new();
            m.insert("name".into(), Value::from(n.clone()));
            m.insert("reason".into(), Value::from(why.clone()));
            Value::Object(m)
        })
        .collect();
    o.insert("fixed".into(), Value::Array(fixed));
    Value::Object(o)
}

/// `uncertainty.robot`: `{"joints": [{"theta0_deg": sigma, ...}, ...]}`, one object per
/// DH row with the one-sigma of its estimated quantities (empty for a row held).
pub fn robot_uncertainty(rc: &RobotCalibration) -> Value {
    let rows = (0..rc.robot.joints.len())
        .map(|i| {
            let prefix = format!("robot.joints[{i}].");
            let mut m = Map::new();
            for e in &rc.estimated {
                if let Some(key) = e.name.strip_prefix(&prefix) {
                    m.insert(key.into(), finite_or_null(e.sigma));
                }
            }
            Value::Object(m)
        })
        .collect();
    let mut o = Map::new();
    o.insert("joints".into(), Value::Array(rows));
    Value::Object(o)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uncertainty_blocks_in_contract_order_with_null_for_unobservable() {
        let u = Uncertainty {
            camera: Some(CameraSigma {
                fu: 0.5,
                fv: 0.25,
                u0: f64::NAN,
                v0: 1.0,
                distortion: [1e-4, 0.0, 0.0, 0.0, f64::INFINITY],
            }),
            laser_plane: Some(PlaneSigma {
                normal: [1e-5, 2e-5, 3e-5],
                d_mm: 0.001,
            }),
            hand_cam: None,
            base_board: Some(PoseSigma {
                rotation_vector: [1e-6; 3],
                translation_mm: [0.1, 0.2, 0.3],
            }),
        };
        let text = serde_json::to_string(&Value::Object(uncertainty_to_json(&u))).unwrap();
        assert_eq!(
            text,
            r#"{"camera":{"fu":0.5,"fv":0.25,"u0":null,"v0":1.0,"distortion":[0.0001,0.0,0.0,0.0,null]},"laser_plane":{"normal":[0.00001,0.00002,0.00003],"d_mm":0.001},"base_board":{"rotation_vector":[1e-6,1e-6,1e-6],"translation_mm":[0.1,0.2,0.3]}}"#
        );
    }

    #[test]
    fn summary_views_and_warnings_in_order() {
        let s = AdjustmentSummary {
            method: "one-stage".into(),
            centre_model: "conic-exact".into(),
            base_board_orientation: Some("first view".into()),
            stripe_rms_mm: 0.002,
            residual_sigma_px: (0.004, f64::NAN),
            stripe_off_plane: 7,
        };
        let v = ViewRecord {
            view: 2,
            used: false,
            circles: 88,
            stripe_points: 0,
            stripe_off_plane: 3,
            circle_rms_px: None,
            stripe_rms_px: Some(0.02),
            outlier: None,
            note: Some("left out".into()),
            stripe_extraction: None,
        };
        let m = calibration_extra(&s, &[v], &[]);
        let keys: Vec<&str> = m.keys().map(|k| k.as_str()).collect();
        assert_eq!(
            keys,
            [
                "method",
                "centre_model",
                "base_board_orientation",
                "stripe_rms_mm",
                "residual_sigma_px",
                "stripe_off_plane",
                "views"
            ]
        );
        assert_eq!(m["residual_sigma_px"]["stripe"], Value::Null);
        assert_eq!(m["stripe_off_plane"], Value::from(7));
        assert_eq!(
            serde_json::to_string(&m["views"][0]).unwrap(),
            r#"{"view":2,"used":false,"circles":88,"stripe_points":0,"stripe_off_plane":3,"circle_rms_px":null,"stripe_rms_px":0.02,"outlier":null,"note":"left out"}"#
        );
        let w = calibration_extra(&s, &[], &["a".into()]);
        assert_eq!(w["warnings"], serde_json::json!(["a"]));
    }
}
