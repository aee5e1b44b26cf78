//! A profiler calibration's records ([`ProfilerRecords`]) to and from calibration.json:
//! `robot_calibration`, `sphere_diameter_estimated`, `adjustment`, `views`, `mirror`,
//! `diameter_check`, `leave_one_out` and `warnings`, written after the fixed keys in
//! that order (where the code before their types wrote them as extra keys, so a file
//! keeps its bytes).
//!
//! ## Conventions
//!
//! - A non-finite number is written as `null`; a `null` number reads as NaN (or `None`
//!   where the record has an option).
//! - A known key that does not read as its record stays in `extra`.

use serde_json::{json, Map, Value};

use super::json::Obj;
use super::records::{robot_calibration_to_json, warnings_to_json};
use super::records_read::{num, opt_num, robot_calibration_from, strings};
use crate::error::Result;
use crate::model::kinematics::Robot;
use crate::model::{
    DiameterCheckRecord, MirrorRecord, ProfilerAdjustmentRecord, ProfilerLooRecord,
    ProfilerLooView, ProfilerRecords, ProfilerViewRecord,
};

/// The keys of a profiler's records, in the order written.
pub const PROFILER_RECORD_KEYS: [&str; 8] = [
    "robot_calibration",
    "sphere_diameter_estimated",
    "adjustment",
    "views",
    "mirror",
    "diameter_check",
    "leave_one_out",
    "warnings",
];

/// A number, `null` when not finite (`Value::from` does that).
fn n(x: f64) -> Value {
    Value::from(x)
}

/// `adjustment`.
pub fn profiler_adjustment_to_json(a: &ProfilerAdjustmentRecord) -> Value {
    json!({"sigma_mm": n(a.sigma_mm), "points_used": a.points_used,
           "iterations": a.iterations, "view_variance_factor": n(a.view_variance_factor)})
}

/// One entry of `views`.
pub fn profiler_view_to_json(s: &ProfilerViewRecord) -> Value {
    json!({
        "view": s.view, "line": s.line, "profile": s.profile, "used": s.used,
        "points": s.points, "gaps": s.gaps, "arc_points": s.arc_points,
        "sphere_points": s.sphere_points, "rejected": s.rejected,
        "rms_mm": s.rms_mm.map_or(Value::Null, n),
        "side": s.side.map_or(Value::Null, n),
        "centre_in_sensor_mm": s.centre_in_sensor_mm
            .map_or(Value::Null, |c| Value::Array(c.iter().map(|x| n(*x)).collect())),
        "note": s.note,
    })
}

/// `mirror`.
pub fn mirror_to_json(m: &MirrorRecord) -> Value {
    let [x, y, z, a] = m.centre_spread_mm.map(n);
    json!({"ssr_chosen_mm2": n(m.ssr_chosen_mm2), "ssr_mirror_mm2": n(m.ssr_mirror_mm2),
           "delta_chi2": n(m.delta_chi2), "passed": m.passed,
           "centre_spread_mm": {"x": x, "y": y, "z": z, "across_plane": a}})
}

/// `diameter_check`.
pub fn diameter_check_to_json(d: &DiameterCheckRecord) -> Value {
    json!({"declared_mm": n(d.declared_mm), "estimate_mm": n(d.estimate_mm),
           "sigma_mm": n(d.sigma_mm), "disagrees": d.disagrees})
}

/// `leave_one_out`.
pub fn profiler_loo_to_json(l: &ProfilerLooRecord) -> Value {
    json!({"median_rms_mm": n(l.median_rms_mm),
           "views": l.views.iter().map(|v| json!({"view": v.view, "points": v.points,
               "rms_mm": n(v.rms_mm), "disagrees": v.disagrees})).collect::<Vec<_>>()})
}

/// The records' keys (those present), in the order calibration.json holds them.
pub fn profiler_records_to_json(r: &ProfilerRecords) -> Map<String, Value> {
    let mut m = Map::new();
    if let Some(rc) = &r.robot_calibration {
        m.insert("robot_calibration".into(), robot_calibration_to_json(rc));
    }
    if let Some(e) = r.sphere_diameter_estimated {
        m.insert("sphere_diameter_estimated".into(), Value::Bool(e));
    }
    if let Some(a) = &r.adjustment {
        m.insert("adjustment".into(), profiler_adjustment_to_json(a));
    }
    if let Some(v) = &r.views {
        let views = v.iter().map(profiler_view_to_json).collect();
        m.insert("views".into(), Value::Array(views));
    }
    if let Some(x) = &r.mirror {
        m.insert("mirror".into(), mirror_to_json(x));
    }
    if let Some(d) = &r.diameter_check {
        m.insert("diameter_check".into(), diameter_check_to_json(d));
    }
    if let Some(l) = &r.leave_one_out {
        m.insert("leave_one_out".into(), profiler_loo_to_json(l));
    }
    if !r.warnings.is_empty() {
        m.insert("warnings".into(), warnings_to_json(&r.warnings));
    }
    m
}

/// The record when the key holds an object that reads as the record.
fn record<T>(root: &Obj<'_>, key: &str, f: impl Fn(&Obj<'_>) -> Result<T>) -> Option<T> {
    root.opt_obj(key).ok().flatten().and_then(|o| f(&o).ok())
}

fn adjustment_from(o: &Obj<'_>) -> Result<ProfilerAdjustmentRecord> {
    Ok(ProfilerAdjustmentRecord {
        sigma_mm: num(o, "sigma_mm")?,
        points_used: o.count("points_used")?,
        iterations: o.count("iterations")?,
        view_variance_factor: num(o, "view_variance_factor")?,
    })
}

fn view_from(o: &Obj<'_>) -> Result<ProfilerViewRecord> {
    Ok(ProfilerViewRecord {
        view: o.count("view")?,
        line: o.count("line")?,
        profile: o.req("profile")?.str()?.to_string(),
        used: o.req("used")?.bool()?,
        points: o.count("points")?,
        gaps: o.count("gaps")?,
        arc_points: o.count("arc_points")?,
        sphere_points: o.count("sphere_points")?,
        rejected: o.count("rejected")?,
        rms_mm: opt_num(o, "rms_mm")?,
        side: opt_num(o, "side")?,
        centre_in_sensor_mm: o
            .opt("centre_in_sensor_mm")
            .map(|v| v.f64_array::<3>())
            .transpose()?,
        note: o.opt_str("note")?.map(str::to_string),
    })
}

fn mirror_from(o: &Obj<'_>) -> Result<MirrorRecord> {
    let s = o.obj("centre_spread_mm")?;
    Ok(MirrorRecord {
        ssr_chosen_mm2: num(o, "ssr_chosen_mm2")?,
        ssr_mirror_mm2: num(o, "ssr_mirror_mm2")?,
        delta_chi2: num(o, "delta_chi2")?,
        passed: o.req("passed")?.bool()?,
        centre_spread_mm: [
            num(&s, "x")?,
            num(&s, "y")?,
            num(&s, "z")?,
            num(&s, "across_plane")?,
        ],
    })
}

fn diameter_check_from(o: &Obj<'_>) -> Result<DiameterCheckRecord> {
    Ok(DiameterCheckRecord {
        declared_mm: num(o, "declared_mm")?,
        estimate_mm: num(o, "estimate_mm")?,
        sigma_mm: num(o, "sigma_mm")?,
        disagrees: o.req("disagrees")?.bool()?,
    })
}

fn loo_from(o: &Obj<'_>) -> Result<ProfilerLooRecord> {
    let mut views = Vec::new();
    for item in o.req("views")?.arr()? {
        let v = item.obj()?;
        views.push(ProfilerLooView {
            view: v.count("view")?,
            points: v.count("points")?,
            rms_mm: num(&v, "rms_mm")?,
            disagrees: v.req("disagrees")?.bool()?,
        });
    }
    Ok(ProfilerLooRecord {
        median_rms_mm: num(o, "median_rms_mm")?,
        views,
    })
}

/// The records of a profiler calibration.json's root and the keys read into them (a
/// known key that does not read as its record is not among them: it stays in
/// `extra`). `robot` is the calibration's (a robot calibration's refined table).
pub(super) fn profiler_records_from(
    root: &Obj<'_>,
    robot: Option<&Robot>,
) -> (ProfilerRecords, Vec<&'static str>) {
    let robot_calibration = match (root.opt_obj("robot_calibration").ok().flatten(), robot) {
        (Some(o), Some(r)) => robot_calibration_from(&o, r).ok(),
        _ => None,
    };
    let views = root.opt("views").and_then(|v| {
        v.arr()
            .ok()?
            .iter()
            .map(|x| view_from(&x.obj()?))
            .collect::<Result<Vec<_>>>()
            .ok()
    });
    let warnings = root.opt("warnings").and_then(|v| strings(&v));
    let r = ProfilerRecords {
        robot_calibration,
        sphere_diameter_estimated: root.opt_bool("sphere_diameter_estimated").ok().flatten(),
        adjustment: record(root, "adjustment", adjustment_from),
        views,
        mirror: record(root, "mirror", mirror_from),
        diameter_check: record(root, "diameter_check", diameter_check_from),
        leave_one_out: record(root, "leave_one_out", loo_from),
        warnings: warnings.unwrap_or_default(),
    };
    let present = [
        r.robot_calibration.is_some(),
        r.sphere_diameter_estimated.is_some(),
        r.adjustment.is_some(),
        r.views.is_some(),
        r.mirror.is_some(),
        r.diameter_check.is_some(),
        r.leave_one_out.is_some(),
        !r.warnings.is_empty(),
    ];
    let read = PROFILER_RECORD_KEYS
        .iter()
        .zip(present)
        .filter_map(|(k, p)| p.then_some(*k))
        .collect();
    (r, read)
}

/// Splits a map of calibration.json's top-level keys (a `ProfilerCalibration(extra=...)`)
/// into the records it holds and the keys left (unknown, or not reading as their
/// record). `robot` as in [`profiler_records_from`].
pub fn profiler_records_split(
    map: &Map<String, Value>,
    robot: Option<&Robot>,
) -> (ProfilerRecords, Map<String, Value>) {
    let v = Value::Object(map.clone());
    let Ok(root) = Obj::root(std::path::Path::new("<extra>"), &v) else {
        return (ProfilerRecords::default(), map.clone());
    };
    let (r, read) = profiler_records_from(&root, robot);
    (r, root.extra(&read))
}
