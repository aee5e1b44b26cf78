//! calibration.json of a calibrated line profiler (spec/DATASET.md "A profile
//! dataset"):
//!
//! ```json
//! {"format": "stripecal/calibration@1",
//!  "sensor": {"kind": "profiler"},
//!  "hand_cam": {"rotation_vector": [...], "translation_mm": [...]},
//!  "robot": {"name": "...", "joints": [...]},
//!  "quality": {"profile_rms_mm": 0.012, "views_used": 12, "checks": [...],
//!              "accepted_poor": true},
//!  "uncertainty": {"hand_cam": {...}, "sphere": {...}},
//!  "covariance": {"parameters": [...], "matrix": [[...]]},
//!  "sphere": {"center_mm": [x, y, z], "diameter_mm": d}}
//! ```
//!
//! `hand_cam` holds `T_hand_sensor`; `sphere` is in the base frame. `robot` is there
//! only when the views carried joint readings; `quality.checks` only when there are
//! checks, `quality.accepted_poor` only when true (read as false when absent). The
//! `hand_cam`, `robot`, `quality.checks` and `covariance` JSON is the camera
//! calibration's (the same code). There is no `camera`, `laser_plane` or `base_board`:
//! the reader refuses a file with them, and the camera reader
//! ([`super::read_calibration`]) refuses a profiler's file. Other top-level keys are
//! kept in [`ProfilerCalibration::extra`] and written back.

use std::path::Path;

use serde_json::{Map, Value};

use super::atomic::{read_text, write_atomic};
use super::calibration::{
    check_covariance, check_poses_and_robot, covariance_from, covariance_value,
    quality_checks_from, quality_checks_value, sphere_from, sphere_is_valid, sphere_value,
    CALIBRATION_FORMAT,
};
use super::json::{append_extra, num, parse, pose_value, to_pretty, Obj};
use super::profiler_records::{profiler_records_from, profiler_records_to_json};
use super::rig::{robot_from, robot_value};
use super::sensor::sensor_kind_of;
use crate::error::{Error, Result};
use crate::model::{ProfilerCalibration, ProfilerQuality, SensorKind, Sphere};

/// The keys of a profiler's calibration.json this module reads; the rest is `extra`.
const KEYS: [&str; 8] = [
    "format",
    "sensor",
    "hand_cam",
    "robot",
    "quality",
    "uncertainty",
    "covariance",
    "sphere",
];

/// Keys of a camera calibration a profiler's never has.
const CAMERA_KEYS: [&str; 3] = ["camera", "laser_plane", "base_board"];

/// Parses a profiler's calibration.json text; `path` is used in error messages only.
///
/// Required: `format`, `sensor.kind = "profiler"`, `hand_cam`, `quality`
/// (`profile_rms_mm >= 0`, `views_used`), `sphere` (`center_mm`, `diameter_mm > 0`).
/// Optional: `robot`, `uncertainty` (any object), `covariance` (checked as a camera
/// calibration's), `quality.checks`, `quality.accepted_poor`.
pub fn profiler_calibration_from_json(path: &Path, text: &str) -> Result<ProfilerCalibration> {
    let doc = parse(path, text)?;
    let root = Obj::root(path, &doc)?;
    root.check_format(CALIBRATION_FORMAT)?;
    if sensor_kind_of(&root)? != SensorKind::Profiler {
        return Err(Error::format(
            path,
            "sensor.kind",
            "calibration.json is a camera's (sensor.kind absent or \"camera\"); this reader is \
             for a profiler's calibration (\"sensor\": {\"kind\": \"profiler\"}): read it with \
             read_calibration",
        ));
    }
    if let Some(k) = CAMERA_KEYS.iter().find(|k| root.map().contains_key(**k)) {
        return Err(root.err(format!(
            "a profiler's calibration has no `{k}` (only a camera's has camera, laser_plane \
             and base_board)"
        )));
    }
    let q = root.obj("quality")?;
    let quality = ProfilerQuality {
        profile_rms_mm: q.nonneg_f64("profile_rms_mm")?,
        views_used: q.count("views_used")?,
        checks: quality_checks_from(&q)?,
        accepted_poor: q.opt_bool("accepted_poor")?.unwrap_or(false),
    };
    let sphere = sphere_from(&root.obj("sphere")?)?;
    let robot = root.opt_obj("robot")?.map(|r| robot_from(&r)).transpose()?;
    let (records, read) = profiler_records_from(&root, robot.as_ref());
    let known: Vec<&str> = KEYS.iter().copied().chain(read).collect();
    Ok(ProfilerCalibration {
        hand_sensor: root.obj("hand_cam")?.pose()?,
        robot,
        sphere_center_mm: sphere.center_mm,
        sphere_diameter_mm: sphere.diameter_mm,
        quality,
        uncertainty: root
            .opt_obj("uncertainty")?
            .map(|u| u.map().clone())
            .unwrap_or_default(),
        covariance: root
            .opt_obj("covariance")?
            .map(|c| covariance_from(&c))
            .transpose()?,
        records,
        extra: root.extra(&known),
    })
}

/// A profiler's calibration.json text (pretty-printed, 2-space indent, final newline).
/// Keys of `extra` that collide with the fixed keys are dropped.
pub fn profiler_calibration_to_json(c: &ProfilerCalibration) -> String {
    let mut m = Map::new();
    m.insert("format".into(), Value::from(CALIBRATION_FORMAT));
    let mut sensor = Map::new();
    sensor.insert("kind".into(), Value::from(SensorKind::Profiler.name()));
    m.insert("sensor".into(), Value::Object(sensor));
    m.insert("hand_cam".into(), pose_value(&c.hand_sensor));
    if let Some(r) = &c.robot {
        m.insert("robot".into(), robot_value(r));
    }
    let mut q = Map::new();
    q.insert("profile_rms_mm".into(), num(c.quality.profile_rms_mm));
    q.insert("views_used".into(), Value::from(c.quality.views_used));
    if !c.quality.checks.is_empty() {
        q.insert("checks".into(), quality_checks_value(&c.quality.checks));
    }
    if c.quality.accepted_poor {
        q.insert("accepted_poor".into(), Value::Bool(true));
    }
    m.insert("quality".into(), Value::Object(q));
    m.insert("uncertainty".into(), Value::Object(c.uncertainty.clone()));
    if let Some(cov) = &c.covariance {
        m.insert("covariance".into(), covariance_value(cov));
    }
    m.insert("sphere".into(), sphere_value(&sphere_of(c)));
    append_extra(&mut m, &profiler_calibration_extra_keys(c));
    to_pretty(&Value::Object(m))
}

/// calibration.json's keys after a profiler calibration's fixed ones: its records
/// (`views`, `adjustment`, `mirror`, ...; see [`super::profiler_records`]), then the
/// keys of `extra` (a record wins over an `extra` key of its name).
pub fn profiler_calibration_extra_keys(c: &ProfilerCalibration) -> Map<String, Value> {
    let mut m = profiler_records_to_json(&c.records);
    append_extra(&mut m, &c.extra);
    m
}

fn sphere_of(c: &ProfilerCalibration) -> Sphere {
    Sphere {
        center_mm: c.sphere_center_mm,
        diameter_mm: c.sphere_diameter_mm,
    }
}

/// Reads a profiler's `calibration.json`.
pub fn read_profiler_calibration(p: impl AsRef<Path>) -> Result<ProfilerCalibration> {
    let path = p.as_ref();
    profiler_calibration_from_json(path, &read_text(path)?)
}

/// Writes a profiler's `calibration.json` atomically, after checking that it can be
/// read back: finite `T_hand_sensor`, a finite sphere with a positive diameter, a finite
/// non-negative RMS, a valid robot and covariance, no camera keys in `extra`.
pub fn write_profiler_calibration(p: impl AsRef<Path>, c: &ProfilerCalibration) -> Result<()> {
    let bad = |m: String| Error::InvalidInput(format!("profiler calibration: {m}"));
    check_poses_and_robot(
        "profiler calibration",
        &[("hand_sensor", &c.hand_sensor)],
        c.robot.as_ref(),
    )?;
    if !sphere_is_valid(&sphere_of(c)) {
        return Err(bad(format!(
            "sphere centre {:?} / diameter {} must be finite (diameter > 0)",
            c.sphere_center_mm, c.sphere_diameter_mm
        )));
    }
    let rms = c.quality.profile_rms_mm;
    if !(rms.is_finite() && rms >= 0.0) {
        return Err(bad(format!(
            "quality profile_rms_mm {rms} must be finite and non-negative"
        )));
    }
    if let Some(cov) = &c.covariance {
        check_covariance(cov).map_err(|m| bad(format!("covariance: {m}")))?;
    }
    if let Some(k) = CAMERA_KEYS.iter().find(|k| c.extra.contains_key(**k)) {
        return Err(bad(format!(
            "extra key `{k}` is a camera calibration's; a profiler's calibration has none"
        )));
    }
    write_atomic(p, profiler_calibration_to_json(c).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{calibration_from_json, read_calibration};
    use crate::model::geometry::{iso_from_rotvec, Iso3};
    use crate::model::kinematics::Robot;
    use crate::model::{NamedCovariance, QualityCheck};
    use nalgebra::{DMatrix, Vector3};

    fn sample() -> ProfilerCalibration {
        let mut uncertainty = Map::new();
        uncertainty.insert(
            "sphere".into(),
            serde_json::json!({"center_mm": [0.01, 0.02, 0.03], "diameter_mm": 0.004}),
        );
        let mut extra = Map::new();
        extra.insert(
            "views".into(),
            serde_json::json!([{"view": 0, "rms_mm": 0.01}]),
        );
        let names = ["hand_cam.rotation_vector[0]", "sphere.diameter_mm"];
        ProfilerCalibration {
            // a half turn and more: the rotation vector wraps, the matrix must not change
            hand_sensor: iso_from_rotvec(
                &Vector3::new(0.3, -2.9, 0.4),
                &Vector3::new(12.5, -3.25, 180.0),
            ),
            robot: Some(Robot::hp3()),
            sphere_center_mm: Vector3::new(600.125, -20.5, 310.0),
            sphere_diameter_mm: 80.0012,
            quality: ProfilerQuality {
                profile_rms_mm: 0.0123,
                views_used: 14,
                checks: vec![QualityCheck {
                    name: "leave_one_out".into(),
                    passed: false,
                    message: "view 3 disagrees".into(),
                    views: vec![3],
                }],
                accepted_poor: true,
            },
            uncertainty,
            covariance: Some(NamedCovariance {
                parameters: names.iter().map(|s| s.to_string()).collect(),
                matrix: DMatrix::from_row_slice(2, 2, &[1e-6, 2e-8, 2e-8, 1.6e-5]),
            }),
            records: Default::default(),
            extra,
        }
    }

    fn rotation_gap(a: &Iso3, b: &Iso3) -> f64 {
        (a.rotation.to_rotation_matrix().matrix() - b.rotation.to_rotation_matrix().matrix())
            .abs()
            .max()
    }

    #[test]
    fn round_trips_through_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("calibration.json");
        let c = sample();
        write_profiler_calibration(&path, &c).unwrap();
        let back = read_profiler_calibration(&path).unwrap();
        // rotation matrices compared (DECISIONS 7): the JSON holds 17 significant digits
        assert!(rotation_gap(&c.hand_sensor, &back.hand_sensor) < 1e-14);
        assert!(
            (c.hand_sensor.translation.vector - back.hand_sensor.translation.vector).norm() < 1e-12
        );
        assert_eq!(back.robot, c.robot);
        assert_eq!(back.sphere_center_mm, c.sphere_center_mm);
        assert_eq!(back.sphere_diameter_mm, c.sphere_diameter_mm);
        assert_eq!(back.quality, c.quality);
        assert_eq!(back.uncertainty, c.uncertainty);
        assert_eq!(back.covariance, c.covariance);
        assert_eq!(back.extra, c.extra);
        assert_eq!(
            calibration_sensor_kind(&path).unwrap(),
            SensorKind::Profiler
        );

        let text = std::fs::read_to_string(&path).unwrap();
        let doc: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(doc["sensor"]["kind"], "profiler");
        assert_eq!(doc["format"], "stripecal/calibration@1");
        for k in ["camera", "laser_plane", "base_board"] {
            assert!(doc.get(k).is_none(), "{k}");
        }
        // without a robot, checks and accepted_poor the keys are left out
        let mut c2 = sample();
        c2.robot = None;
        c2.quality.checks.clear();
        c2.quality.accepted_poor = false;
        let doc: Value = serde_json::from_str(&profiler_calibration_to_json(&c2)).unwrap();
        assert!(doc.get("robot").is_none());
        assert!(doc["quality"].get("checks").is_none());
        assert!(doc["quality"].get("accepted_poor").is_none());
        let back = profiler_calibration_from_json(&path, &profiler_calibration_to_json(&c2));
        assert_eq!(back.unwrap().quality, c2.quality);
    }

    use super::super::sensor::calibration_sensor_kind;

    #[test]
    fn camera_and_profiler_readers_refuse_each_other() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("calibration.json");
        write_profiler_calibration(&path, &sample()).unwrap();
        let e = read_calibration(&path).unwrap_err();
        match e {
            Error::Format {
                location, message, ..
            } => {
                assert_eq!(location, "sensor.kind");
                assert!(message.contains("read_profiler_calibration"), "{message}");
            }
            other => panic!("{other:?}"),
        }
        // a camera calibration (no sensor key) is refused by the profiler reader
        let camera = r#"{"format": "stripecal/calibration@1",
            "camera": {"width": 10, "height": 10, "fu": 1, "fv": 1, "u0": 5, "v0": 5,
                       "distortion_model": "radial1", "distortion": [0,0,0,0,0]},
            "laser_plane": null, "quality": {"circle_rms_px": 0, "stripe_rms_px": 0,
                                             "views_used": 1}}"#;
        assert!(calibration_from_json(&path, camera).is_ok());
        let e = profiler_calibration_from_json(&path, camera).unwrap_err();
        assert!(
            e.to_string().contains("calibration.json is a camera's"),
            "{e}"
        );
        // a profiler file with a camera key is refused, naming it
        let mut doc: Value =
            serde_json::from_str(&profiler_calibration_to_json(&sample())).unwrap();
        doc["laser_plane"] = Value::Null;
        let e = profiler_calibration_from_json(&path, &doc.to_string()).unwrap_err();
        assert!(e.to_string().contains("`laser_plane`"), "{e}");
    }

    #[test]
    fn bad_values_are_errors_naming_the_key() {
        let path = Path::new("calibration.json");
        let base: Value = serde_json::from_str(&profiler_calibration_to_json(&sample())).unwrap();
        for (key, edit, want) in [
            (
                "sphere.diameter_mm",
                serde_json::json!(-1.0),
                "sphere.diameter_mm",
            ),
            (
                "quality.profile_rms_mm",
                serde_json::json!("x"),
                "quality.profile_rms_mm",
            ),
            (
                "quality.views_used",
                serde_json::json!(1.5),
                "quality.views_used",
            ),
            (
                "sphere.center_mm",
                serde_json::json!([1, 2]),
                "sphere.center_mm",
            ),
        ] {
            let mut doc = base.clone();
            let (a, b) = key.split_once('.').unwrap();
            doc[a][b] = edit;
            let e = profiler_calibration_from_json(path, &doc.to_string()).unwrap_err();
            match e {
                Error::Format { location, .. } => assert_eq!(location, want, "{key}"),
                other => panic!("{key}: {other:?}"),
            }
        }
        let mut doc = base.clone();
        doc.as_object_mut().unwrap().remove("sphere");
        let e = profiler_calibration_from_json(path, &doc.to_string()).unwrap_err();
        assert!(e.to_string().contains("missing key `sphere`"), "{e}");
    }

    #[test]
    fn the_writer_refuses_what_could_not_be_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.json");
        let mut c = sample();
        c.sphere_diameter_mm = 0.0;
        assert!(matches!(
            write_profiler_calibration(&path, &c),
            Err(Error::InvalidInput(_))
        ));
        let mut c = sample();
        c.quality.profile_rms_mm = f64::NAN;
        assert!(write_profiler_calibration(&path, &c).is_err());
        let mut c = sample();
        c.extra.insert("camera".into(), Value::Null);
        assert!(write_profiler_calibration(&path, &c).is_err());
        assert!(!path.exists());
    }
}
