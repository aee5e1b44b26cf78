//! `calibration.json` (`stripecal/calibration@1`) and `truth.json`
//! (`stripecal/truth@1`).

use std::path::Path;

use serde_json::{Map, Value};

use super::atomic::{read_text, write_atomic};
use super::json::{
    append_extra, invalid_message, num, parse, pose_value, to_pretty, vec3_value, Obj,
};
use super::records::{records_after_extra, records_value};
use super::records_read::records_from;
use super::rig::{distortion_model_from, robot_from, robot_value};
use super::sensor::sensor_kind_of;
use crate::error::{Error, Result};
use crate::model::camera::{Camera, Projection};
use crate::model::geometry::{Iso3, Plane};
use crate::model::kinematics::Robot;
use crate::model::{
    Calibration, Mount, NamedCovariance, Quality, QualityCheck, SensorKind, Sphere, Truth,
};

/// The top-level key that marks a bench calibration or a bench twin's truth
/// (`"bench": true`; such a file has no `hand_cam`, `base_board` or `robot`).
pub const BENCH_KEY: &str = "bench";

/// Takes the bench flag out of a calibration's unknown keys: `true` when `extra` held
/// `"bench": true` (the flag a writer adds to a bench file, read as the mount).
pub fn take_bench_flag(extra: &mut serde_json::Map<String, Value>) -> bool {
    let flagged = extra.get(BENCH_KEY) == Some(&Value::Bool(true));
    if flagged {
        extra.shift_remove(BENCH_KEY);
    }
    flagged
}

/// The `format` value of calibration.json.
pub(super) const CALIBRATION_FORMAT: &str = "stripecal/calibration@1";
/// The `format` value of truth.json.
pub(super) const TRUTH_FORMAT: &str = "stripecal/truth@1";

/// How far from 1 the norm of a laser-plane normal in a file may be (files written
/// with rounded numbers); the normal is renormalised on reading.
const NORMAL_TOL: f64 = 1e-3;

const CALIBRATION_KEYS: [&str; 9] = [
    "format",
    "camera",
    "laser_plane",
    "hand_cam",
    "base_board",
    "robot",
    "quality",
    "uncertainty",
    "covariance",
];

const TRUTH_KEYS: [&str; 8] = [
    "format",
    "camera",
    "laser_plane",
    "hand_cam",
    "base_board",
    "robot",
    "sphere",
    "working_range_mm",
];

// ---------------------------------------------------------------- shared parts

pub(super) fn camera_from(c: &Obj<'_>) -> Result<Camera> {
    let width = c.positive_u32("width")?;
    let height = c.positive_u32("height")?;
    let fu = c.positive_f64("fu")?;
    let fv = c.positive_f64("fv")?;
    let u0 = c.f64("u0")?;
    let v0 = c.f64("v0")?;
    // `camera.model` (absent: brown5, as every file written so far): this version reads
    // and writes brown5's five coefficients only; another model is refused by name
    // rather than read as brown5 (docs/architecture.md, "camera model").
    if let Some(m) = c.opt("model") {
        let name = m.str()?;
        if name != "brown5" {
            return Err(m.err(format!(
                "camera model '{name}' is not one this version reads (brown5 only)"
            )));
        }
    }
    let model = distortion_model_from(&c.req("distortion_model")?)?;
    let distortion = c.req("distortion")?.f64_array::<5>()?;
    let cam = Camera {
        width,
        height,
        fu,
        fv,
        u0,
        v0,
        model,
        distortion,
        projection: Projection::Brown5,
    };
    cam.validate().map_err(|e| c.err(invalid_message(e)))?;
    Ok(cam)
}

pub(super) fn camera_value(c: &Camera) -> Value {
    let mut m = Map::new();
    if !c.projection.is_brown5() {
        // never written as brown5 (a reader refuses the name it does not know)
        m.insert("model".into(), Value::from(c.projection.name()));
    }
    m.insert("width".into(), Value::from(c.width));
    m.insert("height".into(), Value::from(c.height));
    m.insert("fu".into(), num(c.fu));
    m.insert("fv".into(), num(c.fv));
    m.insert("u0".into(), num(c.u0));
    m.insert("v0".into(), num(c.v0));
    m.insert("distortion_model".into(), Value::from(c.model.name()));
    m.insert(
        "distortion".into(),
        Value::Array(c.distortion.iter().map(|&k| num(k)).collect()),
    );
    Value::Object(m)
}

pub(super) fn plane_from(p: &Obj<'_>) -> Result<Plane> {
    let nv = p.req("normal")?;
    let n = nv.vec3()?;
    if (n.norm() - 1.0).abs() > NORMAL_TOL {
        return Err(nv.err(format!(
            "expected a unit vector, got one of norm {}",
            n.norm()
        )));
    }
    let dv = p.req("d_mm")?;
    let d = dv.f64()?;
    if d <= 0.0 {
        return Err(dv.err(format!(
            "expected a positive distance (n . p = d with d > 0: the plane is in front of the camera), got {d}"
        )));
    }
    Plane::new(n, d).map_err(|e| p.err(invalid_message(e)))
}

/// `laser_plane`: required, `null` when the calibration did not estimate it.
fn opt_plane_from(root: &Obj<'_>) -> Result<Option<Plane>> {
    if !root.map().contains_key("laser_plane") {
        return Err(root.err("missing key `laser_plane` (null when not estimated)"));
    }
    root.opt_obj("laser_plane")?
        .map(|p| plane_from(&p))
        .transpose()
}

pub(super) fn plane_value(p: &Plane) -> Value {
    let mut m = Map::new();
    m.insert("normal".into(), vec3_value(&p.normal));
    m.insert("d_mm".into(), num(p.d));
    Value::Object(m)
}

/// The parts calibration.json and truth.json share.
struct Common {
    camera: Camera,
    laser_plane: Option<Plane>,
    hand_cam: Iso3,
    base_board: Iso3,
    robot: Option<Robot>,
}

fn common_from(root: &Obj<'_>) -> Result<Common> {
    Ok(Common {
        camera: camera_from(&root.obj("camera")?)?,
        laser_plane: opt_plane_from(root)?,
        hand_cam: root.obj("hand_cam")?.pose()?,
        base_board: root.obj("base_board")?.pose()?,
        robot: root.opt_obj("robot")?.map(|r| robot_from(&r)).transpose()?,
    })
}

fn common_value(
    m: &mut Map<String, Value>,
    camera: &Camera,
    plane: Option<&Plane>,
    hand_cam: &Iso3,
    base_board: &Iso3,
    robot: Option<&Robot>,
) {
    m.insert("camera".into(), camera_value(camera));
    m.insert("laser_plane".into(), plane.map_or(Value::Null, plane_value));
    m.insert("hand_cam".into(), pose_value(hand_cam));
    m.insert("base_board".into(), pose_value(base_board));
    if let Some(r) = robot {
        m.insert("robot".into(), robot_value(r));
    }
}

/// Checks what a writer is about to write can be read back (finite, valid values).
fn check_common(
    what: &str,
    camera: &Camera,
    plane: Option<&Plane>,
    poses: [(&str, &Iso3); 2],
    robot: Option<&Robot>,
) -> Result<()> {
    let bad = |m: String| Error::InvalidInput(format!("{what}: {m}"));
    camera.validate().map_err(|e| bad(invalid_message(e)))?;
    if let Some(plane) = plane {
        let n = plane.normal.norm();
        if !(plane.d.is_finite() && plane.d > 0.0 && (n - 1.0).abs() <= NORMAL_TOL) {
            return Err(bad(format!(
                "laser plane normal {:?} (norm {n}) / d {} must be a unit vector and a positive distance",
                plane.normal, plane.d
            )));
        }
    }
    check_poses_and_robot(what, &poses, robot)
}

/// The poses are finite and the robot valid (a writer's check; errors `what: ...`).
pub(super) fn check_poses_and_robot(
    what: &str,
    poses: &[(&str, &Iso3)],
    robot: Option<&Robot>,
) -> Result<()> {
    let bad = |m: String| Error::InvalidInput(format!("{what}: {m}"));
    for (name, t) in poses {
        let finite = t.translation.vector.iter().all(|x| x.is_finite())
            && t.rotation.coords.iter().all(|x| x.is_finite());
        if !finite {
            return Err(bad(format!("{name} has non-finite values")));
        }
    }
    if let Some(r) = robot {
        r.validate().map_err(|e| bad(invalid_message(e)))?;
    }
    Ok(())
}

// ---------------------------------------------------------------- calibration.json

/// `covariance`: `parameters` (names) and a symmetric `matrix` of that size with a
/// non-negative diagonal. `null` entries (the rows and columns of a number the data did
/// not determine, which the adjustment reports as NaN, as `uncertainty` does) are read
/// as NaN.
pub(super) fn covariance_from(c: &Obj<'_>) -> Result<NamedCovariance> {
    let names: Vec<String> = c
        .req("parameters")?
        .arr()?
        .iter()
        .map(|v| v.str().map(str::to_string))
        .collect::<Result<_>>()?;
    let mv = c.req("matrix")?;
    let rows = mv.arr()?;
    let n = names.len();
    if rows.len() != n {
        return Err(mv.err(format!(
            "expected {n} rows (one per parameter), got {}",
            rows.len()
        )));
    }
    let mut matrix = nalgebra::DMatrix::<f64>::zeros(n, n);
    for (i, row) in rows.iter().enumerate() {
        let vals = row.arr()?;
        if vals.len() != n {
            return Err(row.err(format!("expected {n} values, got {}", vals.len())));
        }
        for (j, v) in vals.iter().enumerate() {
            matrix[(i, j)] = if v.is_null() { f64::NAN } else { v.f64()? };
        }
    }
    let cov = NamedCovariance {
        parameters: names,
        matrix,
    };
    check_covariance(&cov).map_err(|m| mv.err(m))?;
    Ok(cov)
}

/// What the reader requires of a covariance (and so the writer checks): one row and
/// column per parameter, finite values or NaN (`null` in the file: not determined), a
/// non-negative diagonal, symmetry (to 1e-9 of the standard deviations' product; NaN
/// where its mirror is NaN).
pub(super) fn check_covariance(c: &NamedCovariance) -> std::result::Result<(), String> {
    let (n, m) = (c.parameters.len(), &c.matrix);
    if m.nrows() != n || m.ncols() != n {
        return Err(format!(
            "expected a {n} x {n} matrix (one row and column per parameter), got {} x {}",
            m.nrows(),
            m.ncols()
        ));
    }
    if let Some(x) = m.iter().find(|x| x.is_infinite()) {
        return Err(format!("the matrix has an infinite value {x}"));
    }
    for i in 0..n {
        if m[(i, i)] < 0.0 {
            return Err(format!("the variance of {} is negative", c.parameters[i]));
        }
        for j in 0..i {
            let (a, b) = (m[(i, j)], m[(j, i)]);
            if a.is_nan() && b.is_nan() {
                continue;
            }
            // at most one is NaN here: then a - b is NaN, which is asymmetric too
            let d = (a - b).abs();
            if d.is_nan() || d > 1e-9 * (m[(i, i)] * m[(j, j)]).sqrt().max(1e-300) {
                return Err(format!(
                    "the matrix is not symmetric: ({i}, {j}) = {a}, ({j}, {i}) = {b}"
                ));
            }
        }
    }
    Ok(())
}

pub(super) fn covariance_value(c: &NamedCovariance) -> Value {
    let mut m = Map::new();
    m.insert(
        "parameters".into(),
        Value::Array(
            c.parameters
                .iter()
                .map(|p| Value::from(p.as_str()))
                .collect(),
        ),
    );
    let rows = (0..c.matrix.nrows())
        .map(|i| {
            Value::Array(
                (0..c.matrix.ncols())
                    .map(|j| num(c.matrix[(i, j)]))
                    .collect(),
            )
        })
        .collect();
    m.insert("matrix".into(), Value::Array(rows));
    Value::Object(m)
}

/// The common keys, or a bench file's (neither `hand_cam` nor `base_board`: read as
/// identities, no robot); `true` for a bench file.
fn common_or_bench(root: &Obj<'_>) -> Result<(Common, bool)> {
    if root.opt("hand_cam").is_none() && root.opt("base_board").is_none() {
        let c = Common {
            camera: camera_from(&root.obj("camera")?)?,
            laser_plane: opt_plane_from(root)?,
            hand_cam: Iso3::identity(),
            base_board: Iso3::identity(),
            robot: None,
        };
        return Ok((c, true));
    }
    Ok((common_from(root)?, false))
}

/// Parses calibration.json text; `path` is used in error messages only.
///
/// Required: `format`, `camera` (all of `width, height, fu, fv, u0, v0,
/// distortion_model, distortion[5]`), `laser_plane` (`normal` of norm 1 within 1e-3,
/// renormalised; `d_mm > 0`), `hand_cam`, `base_board`, `quality`. A bench
/// calibration has neither `hand_cam` nor `base_board` (nor `robot`): both absent (or
/// `"bench": true`), it is read as [`Mount::Bench`] with the identity for them; one
/// without the other is an error. Optional: `robot`, `uncertainty` (any object), the
/// records ([`super::records_read`]: `robot_pose_noise` is checked, another known key
/// that does not read as its record stays in `extra` with the unknown top-level keys).
pub fn calibration_from_json(path: &Path, text: &str) -> Result<Calibration> {
    let doc = parse(path, text)?;
    let root = Obj::root(path, &doc)?;
    root.check_format(CALIBRATION_FORMAT)?;
    if sensor_kind_of(&root)? == SensorKind::Profiler {
        return Err(Error::format(
            path,
            "sensor.kind",
            "calibration.json is a profiler's (sensor.kind = \"profiler\"); this reader is for \
             a camera calibration: read it with read_profiler_calibration",
        ));
    }
    let (c, bench) = common_or_bench(&root)?;
    let q = root.obj("quality")?;
    let quality = Quality {
        // the contract's name; `target_rms_px` (the same figure for any target) in a
        // file that writes only that
        circle_rms_px: match (q.opt("circle_rms_px"), q.opt("target_rms_px")) {
            (None, Some(t)) => t.nonneg_f64()?,
            _ => q.nonneg_f64("circle_rms_px")?,
        },
        stripe_rms_px: q.nonneg_f64("stripe_rms_px")?,
        views_used: q.count("views_used")?,
        checks: quality_checks_from(&q)?,
        accepted_poor: q.opt_bool("accepted_poor")?.unwrap_or(false),
    };
    let uncertainty = root
        .opt_obj("uncertainty")?
        .map(|u| u.map().clone())
        .unwrap_or_default();
    let covariance = root
        .opt_obj("covariance")?
        .map(|c| covariance_from(&c))
        .transpose()?;
    let (records, mut extra) = records_from(&root, &CALIBRATION_KEYS, c.robot.as_ref())?;
    let flagged = take_bench_flag(&mut extra);
    Ok(Calibration {
        camera: c.camera,
        laser_plane: c.laser_plane,
        mount: if bench || flagged {
            Mount::Bench
        } else {
            Mount::Robot
        },
        hand_cam: c.hand_cam,
        base_board: c.base_board,
        robot: c.robot,
        quality,
        uncertainty,
        covariance,
        records,
        extra,
    })
}

/// calibration.json's keys beyond the contract's fixed ones, as the file holds them:
/// the records (in [`super::records`]' order), `"bench": true` for a bench calibration,
/// then `extra` (keys the records have are dropped from it).
pub fn calibration_extra_keys(c: &Calibration) -> Map<String, Value> {
    let mut m = Map::new();
    records_value(&mut m, &c.records);
    if c.is_bench() {
        m.insert(BENCH_KEY.into(), Value::Bool(true));
    }
    append_extra(&mut m, &c.extra);
    records_after_extra(&mut m, &c.records);
    m
}

/// calibration.json text (pretty-printed, 2-space indent, final newline). Keys of
/// `extra` that collide with the fixed keys are dropped.
pub fn calibration_to_json(c: &Calibration) -> String {
    let mut m = Map::new();
    m.insert("format".into(), Value::from(CALIBRATION_FORMAT));
    common_value(
        &mut m,
        &c.camera,
        c.laser_plane.as_ref(),
        &c.hand_cam,
        &c.base_board,
        c.robot.as_ref(),
    );
    let mut q = Map::new();
    q.insert("circle_rms_px".into(), num(c.quality.circle_rms_px));
    q.insert("target_rms_px".into(), num(c.quality.circle_rms_px));
    q.insert("stripe_rms_px".into(), num(c.quality.stripe_rms_px));
    q.insert("views_used".into(), Value::from(c.quality.views_used));
    q.insert("accepted_poor".into(), Value::from(c.quality.accepted_poor));
    if !c.quality.checks.is_empty() {
        q.insert("checks".into(), quality_checks_value(&c.quality.checks));
    }
    m.insert("quality".into(), Value::Object(q));
    m.insert("uncertainty".into(), Value::Object(c.uncertainty.clone()));
    if let Some(cov) = &c.covariance {
        m.insert("covariance".into(), covariance_value(cov));
    }
    append_extra(&mut m, &calibration_extra_keys(c));
    if c.is_bench() {
        for k in ["hand_cam", "base_board", "robot"] {
            m.remove(k);
        }
    }
    to_pretty(&Value::Object(m))
}

/// `quality.checks`: `[{"name", "passed", "message", "views": [...]}, ...]` (optional).
pub(super) fn quality_checks_from(q: &Obj<'_>) -> Result<Vec<QualityCheck>> {
    let Some(list) = q.opt("checks") else {
        return Ok(Vec::new());
    };
    list.arr()?
        .iter()
        .map(|v| {
            let o = v.obj()?;
            Ok(QualityCheck {
                name: o.req("name")?.str()?.to_string(),
                passed: o.req("passed")?.bool()?,
                message: o.req("message")?.str()?.to_string(),
                views: match o.opt("views") {
                    Some(vs) => vs.arr()?.iter().map(|x| x.count()).collect::<Result<_>>()?,
                    None => Vec::new(),
                },
            })
        })
        .collect()
}

pub(super) fn quality_checks_value(checks: &[QualityCheck]) -> Value {
    Value::Array(
        checks
            .iter()
            .map(|c| {
                let mut o = Map::new();
                o.insert("name".into(), Value::from(c.name.clone()));
                o.insert("passed".into(), Value::from(c.passed));
                o.insert("message".into(), Value::from(c.message.clone()));
                o.insert(
                    "views".into(),
                    Value::Array(c.views.iter().map(|&v| Value::from(v)).collect()),
                );
                Value::Object(o)
            })
            .collect(),
    )
}

/// Reads `calibration.json`.
pub fn read_calibration(p: impl AsRef<Path>) -> Result<Calibration> {
    let path = p.as_ref();
    calibration_from_json(path, &read_text(path)?)
}

/// Writes `calibration.json` atomically, after checking every value is valid and
/// finite (so the file can be read back).
pub fn write_calibration(p: impl AsRef<Path>, c: &Calibration) -> Result<()> {
    check_common(
        "calibration",
        &c.camera,
        c.laser_plane.as_ref(),
        [("hand_cam", &c.hand_cam), ("base_board", &c.base_board)],
        c.robot.as_ref(),
    )?;
    let q = &c.quality;
    if !(q.circle_rms_px.is_finite()
        && q.circle_rms_px >= 0.0
        && q.stripe_rms_px.is_finite()
        && q.stripe_rms_px >= 0.0)
    {
        return Err(Error::InvalidInput(format!(
            "calibration: quality RMS values {} / {} must be finite and non-negative",
            q.circle_rms_px, q.stripe_rms_px
        )));
    }
    if let Some(cov) = &c.covariance {
        check_covariance(cov)
            .map_err(|m| Error::InvalidInput(format!("calibration: covariance: {m}")))?;
    }
    write_atomic(p, calibration_to_json(c).as_bytes())
}

// ---------------------------------------------------------------- truth.json

/// `sphere`: `{"center_mm": [x, y, z], "diameter_mm": d > 0}` (truth.json, a profiler's
/// calibration.json).
pub(super) fn sphere_from(s: &Obj<'_>) -> Result<Sphere> {
    Ok(Sphere {
        center_mm: s.vec3("center_mm")?,
        diameter_mm: s.positive_f64("diameter_mm")?,
    })
}

/// The JSON of a sphere, as [`sphere_from`] reads it.
pub(super) fn sphere_value(s: &Sphere) -> Value {
    let mut m = Map::new();
    m.insert("center_mm".into(), vec3_value(&s.center_mm));
    m.insert("diameter_mm".into(), num(s.diameter_mm));
    Value::Object(m)
}

/// Whether a sphere can be written and read back: a finite centre, a finite positive
/// diameter.
pub(super) fn sphere_is_valid(s: &Sphere) -> bool {
    s.center_mm.iter().all(|x| x.is_finite()) && s.diameter_mm.is_finite() && s.diameter_mm > 0.0
}

/// Parses truth.json text; `path` is used in error messages only.
///
/// Same required keys as calibration.json except `quality`; optional `robot`,
/// `sphere {center_mm, diameter_mm > 0}`, `working_range_mm [near, far]`
/// (`0 <= near < far`). Other top-level keys (per-image truth...) are kept in `extra`.
pub fn truth_from_json(path: &Path, text: &str) -> Result<Truth> {
    let doc = parse(path, text)?;
    let root = Obj::root(path, &doc)?;
    root.check_format(TRUTH_FORMAT)?;
    // A bench twin's truth (no robot): the same keys as a bench calibration (the file's
    // `"bench": true` stays in `extra`, and the writer leaves them out again).
    let (c, _) = common_or_bench(&root)?;
    let laser_plane = c
        .laser_plane
        .ok_or_else(|| root.err("`laser_plane` is null: a truth has a laser plane"))?;
    let sphere = root
        .opt_obj("sphere")?
        .map(|s| sphere_from(&s))
        .transpose()?;
    let working_range_mm = match root.opt("working_range_mm") {
        None => None,
        Some(v) => {
            let [near, far] = v.f64_array::<2>()?;
            if !(near >= 0.0 && near < far) {
                return Err(v.err(format!(
                    "expected [near, far] with 0 <= near < far, got [{near}, {far}]"
                )));
            }
            Some([near, far])
        }
    };
    Ok(Truth {
        camera: c.camera,
        laser_plane,
        hand_cam: c.hand_cam,
        base_board: c.base_board,
        robot: c.robot,
        sphere,
        working_range_mm,
        extra: root.extra(&TRUTH_KEYS),
    })
}

/// truth.json text (pretty-printed, 2-space indent, final newline). Keys of `extra`
/// that collide with the fixed keys are dropped.
pub fn truth_to_json(t: &Truth) -> String {
    let mut m = Map::new();
    m.insert("format".into(), Value::from(TRUTH_FORMAT));
    common_value(
        &mut m,
        &t.camera,
        Some(&t.laser_plane),
        &t.hand_cam,
        &t.base_board,
        t.robot.as_ref(),
    );
    if let Some(s) = &t.sphere {
        m.insert("sphere".into(), sphere_value(s));
    }
    if let Some([near, far]) = t.working_range_mm {
        m.insert(
            "working_range_mm".into(),
            Value::Array(vec![num(near), num(far)]),
        );
    }
    append_extra(&mut m, &t.extra);
    if t.extra.get(BENCH_KEY) == Some(&Value::Bool(true)) {
        for k in ["hand_cam", "base_board", "robot"] {
            m.remove(k);
        }
    }
    to_pretty(&Value::Object(m))
}

/// Reads `truth.json`.
pub fn read_truth(p: impl AsRef<Path>) -> Result<Truth> {
    let path = p.as_ref();
    truth_from_json(path, &read_text(path)?)
}

/// Writes `truth.json` atomically, after checking every value is valid and finite.
pub fn write_truth(p: impl AsRef<Path>, t: &Truth) -> Result<()> {
    check_common(
        "truth",
        &t.camera,
        Some(&t.laser_plane),
        [("hand_cam", &t.hand_cam), ("base_board", &t.base_board)],
        t.robot.as_ref(),
    )?;
    if let Some(s) = &t.sphere {
        if !sphere_is_valid(s) {
            return Err(Error::InvalidInput(format!(
                "truth: sphere centre {:?} / diameter {} must be finite and positive",
                s.center_mm, s.diameter_mm
            )));
        }
    }
    if let Some([near, far]) = t.working_range_mm {
        if !(near >= 0.0 && near < far && far.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "truth: working range [{near}, {far}] must satisfy 0 <= near < far"
            )));
        }
    }
    write_atomic(p, truth_to_json(t).as_bytes())
}
