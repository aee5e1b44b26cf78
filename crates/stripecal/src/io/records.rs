//! calibration.json's typed records as JSON: the `uncertainty` block, the per-view
//! `views` entries and the adjustment summary keys (`method`, `centre_model`,
//! `base_board_orientation`, `stripe_rms_mm`, `residual_sigma_px`, `warnings`).
//!
//! Non-finite numbers (an unobservable parameter's sigma, a view without residuals) are
//! written as `null`; key order is the contract's.

use serde_json::{Map, Value};

use crate::model::{
    AdjustmentSummary, CameraSigma, PlaneSigma, PoseSigma, Uncertainty, ViewRecord,
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
    let opt = |x: Option<f64>| x.map_or(Value::Null, finite_or_null);
    m.insert("circle_rms_px".into(), opt(r.circle_rms_px));
    m.insert("stripe_rms_px".into(), opt(r.stripe_rms_px));
    m.insert("outlier".into(), r.outlier.map_or(Value::Null, Value::from));
    m.insert(
        "note".into(),
        r.note.as_deref().map_or(Value::Null, Value::from),
    );
    Value::Object(m)
}

/// The calibration's keys beyond the contract's fixed ones, in this order: the summary,
/// `views`, and `warnings` when there are any.
pub fn calibration_extra(
    summary: &AdjustmentSummary,
    views: &[ViewRecord],
    warnings: &[String],
) -> Map<String, Value> {
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
        "views".into(),
        Value::Array(views.iter().map(view_record_to_json).collect()),
    );
    if !warnings.is_empty() {
        m.insert("warnings".into(), warnings_to_json(warnings));
    }
    m
}

/// The `warnings` array.
pub fn warnings_to_json(warnings: &[String]) -> Value {
    Value::Array(warnings.iter().map(|w| Value::from(w.as_str())).collect())
}
