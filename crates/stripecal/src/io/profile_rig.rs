//! rig.json of a calibrated line profiler (spec/DATASET.md "A profile dataset"):
//!
//! ```json
//! {"format": "stripecal/rig@1",
//!  "sensor": {"kind": "profiler", "invalid_z": -99999.9999},
//!  "artefact": {"kind": "sphere", "diameter_mm": 80.0},
//!  "robot": {"name": "...", "joints": [...]}}
//! ```
//!
//! `sensor.kind` must be `"profiler"`; `sensor.invalid_z` (optional, a number) is the
//! vendor's sentinel for "no point". `artefact` is required: a sphere whose
//! `diameter_mm` is a positive number, or `null` (the calibration estimates it; the key
//! may not be left out, so that "estimate it" is always said). `robot` is the camera
//! rig's (the same parser), needed when the views carry joint readings. `camera`,
//! `board`, `stripe` and any other key are ignored, as for a camera rig.

use std::path::Path;

use serde_json::{Map, Value};

use super::atomic::{read_text, write_atomic};
use super::json::{num, parse, to_pretty, Obj};
use super::rig::{robot_from, robot_value, RIG_FORMAT};
use super::sensor::sensor_kind_of;
use crate::error::{Error, Result};
use crate::model::{ProfileRig, SensorKind};

/// Parses a profiler's rig.json text; `path` is used in error messages only.
pub fn profile_rig_from_json(path: &Path, text: &str) -> Result<ProfileRig> {
    let doc = parse(path, text)?;
    let root = Obj::root(path, &doc)?;
    root.check_format(RIG_FORMAT)?;
    if sensor_kind_of(&root)? != SensorKind::Profiler {
        return Err(Error::format(
            path,
            "sensor.kind",
            "rig.json describes a camera (sensor.kind absent or \"camera\"); a profile dataset's \
             rig has \"sensor\": {\"kind\": \"profiler\"}",
        ));
    }
    let sensor = root.obj("sensor")?;
    let invalid_z = sensor.opt("invalid_z").map(|v| v.f64()).transpose()?;

    let artefact = root.obj("artefact")?;
    let kind = artefact.req("kind")?;
    match kind.str()? {
        "sphere" => {}
        other => {
            return Err(kind.err(format!(
                "unknown artefact kind {other:?}: expected \"sphere\""
            )))
        }
    }
    if !artefact.map().contains_key("diameter_mm") {
        return Err(artefact
            .err("missing key `artefact.diameter_mm` (a positive number, or null: estimate it)"));
    }
    let diameter_mm = artefact.opt_positive_f64("diameter_mm")?;

    let robot = root.opt_obj("robot")?.map(|r| robot_from(&r)).transpose()?;
    Ok(ProfileRig {
        robot,
        invalid_z,
        diameter_mm,
    })
}

/// Reads and checks a profiler's `rig.json`.
pub fn read_profile_rig(p: impl AsRef<Path>) -> Result<ProfileRig> {
    let path = p.as_ref();
    profile_rig_from_json(path, &read_text(path)?)
}

/// A profiler's rig.json text (pretty-printed, final newline); `robot` is left out when
/// the rig has none, `sensor.invalid_z` when it is `None`.
pub fn profile_rig_to_json(r: &ProfileRig) -> String {
    let mut sensor = Map::new();
    sensor.insert("kind".into(), Value::from(SensorKind::Profiler.name()));
    if let Some(z) = r.invalid_z {
        sensor.insert("invalid_z".into(), num(z));
    }
    let mut artefact = Map::new();
    artefact.insert("kind".into(), Value::from("sphere"));
    artefact.insert("diameter_mm".into(), r.diameter_mm.map_or(Value::Null, num));
    let mut m = Map::new();
    m.insert("format".into(), Value::from(RIG_FORMAT));
    m.insert("sensor".into(), Value::Object(sensor));
    m.insert("artefact".into(), Value::Object(artefact));
    if let Some(robot) = &r.robot {
        m.insert("robot".into(), robot_value(robot));
    }
    to_pretty(&Value::Object(m))
}

/// Writes a profiler's rig.json atomically, after checking it can be read back (a
/// finite `invalid_z`, a positive diameter, a valid robot).
pub fn write_profile_rig(p: impl AsRef<Path>, r: &ProfileRig) -> Result<()> {
    if let Some(z) = r.invalid_z.filter(|z| !z.is_finite()) {
        return Err(Error::InvalidInput(format!(
            "profile rig: invalid_z {z} must be finite"
        )));
    }
    if let Some(d) = r.diameter_mm.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(Error::InvalidInput(format!(
            "profile rig: sphere diameter {d} must be finite and positive"
        )));
    }
    if let Some(robot) = &r.robot {
        robot.validate()?;
    }
    write_atomic(p, profile_rig_to_json(r).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::rig_from_json;
    use crate::model::kinematics::Robot;

    const P: &str = "rig.json";

    fn read(text: &str) -> Result<ProfileRig> {
        profile_rig_from_json(Path::new(P), text)
    }

    fn location(e: Error) -> (String, String) {
        match e {
            Error::Format {
                location, message, ..
            } => (location, message),
            other => panic!("expected a format error, got {other:?}"),
        }
    }

    #[test]
    fn reads_the_contract_example_and_ignores_camera_keys() {
        let r = read(
            r#"{"format": "stripecal/rig@1",
                "sensor": {"kind": "profiler", "invalid_z": -99999.9999},
                "artefact": {"kind": "sphere", "diameter_mm": 80.0},
                "camera": {"width": 1}, "board": "anything", "stripe": 3, "note": "x",
                "robot": {"name": "r", "joints": [
                    {"theta0_deg": 0, "alpha_deg": -90, "a_mm": 100, "d_mm": 0},
                    {"theta0_deg": 90, "alpha_deg": 0, "a_mm": 250, "d_mm": 0}]}}"#,
        )
        .unwrap();
        assert_eq!(r.invalid_z, Some(-99999.9999));
        assert_eq!(r.diameter_mm, Some(80.0));
        let robot = r.robot.unwrap();
        assert_eq!(robot.dof(), 2);
        assert_eq!(robot.joints[1].a_mm, 250.0);
    }

    #[test]
    fn null_diameter_is_estimate_and_missing_is_an_error() {
        let r = read(
            r#"{"format": "stripecal/rig@1", "sensor": {"kind": "profiler"},
                "artefact": {"kind": "sphere", "diameter_mm": null}}"#,
        )
        .unwrap();
        assert_eq!(r.diameter_mm, None);
        assert_eq!(r.invalid_z, None);
        assert!(r.robot.is_none());
        let (loc, msg) = location(
            read(
                r#"{"format": "stripecal/rig@1", "sensor": {"kind": "profiler"},
                    "artefact": {"kind": "sphere"}}"#,
            )
            .unwrap_err(),
        );
        assert_eq!(loc, "artefact");
        assert!(msg.contains("artefact.diameter_mm"), "{msg}");
        let (loc, _) = location(
            read(
                r#"{"format": "stripecal/rig@1", "sensor": {"kind": "profiler"},
                    "artefact": {"kind": "sphere", "diameter_mm": -2}}"#,
            )
            .unwrap_err(),
        );
        assert_eq!(loc, "artefact.diameter_mm");
        let (loc, _) = location(
            read(r#"{"format": "stripecal/rig@1", "sensor": {"kind": "profiler"}}"#).unwrap_err(),
        );
        assert_eq!(loc, "top level");
    }

    #[test]
    fn other_artefacts_and_bad_sentinels_are_refused() {
        let (loc, msg) = location(
            read(
                r#"{"format": "stripecal/rig@1", "sensor": {"kind": "profiler"},
                    "artefact": {"kind": "cube", "diameter_mm": 3}}"#,
            )
            .unwrap_err(),
        );
        assert_eq!(loc, "artefact.kind");
        assert!(
            msg.contains("\"cube\"") && msg.contains("\"sphere\""),
            "{msg}"
        );
        let (loc, _) = location(
            read(
                r#"{"format": "stripecal/rig@1", "sensor": {"kind": "profiler",
                    "invalid_z": "none"}, "artefact": {"kind": "sphere", "diameter_mm": 3}}"#,
            )
            .unwrap_err(),
        );
        assert_eq!(loc, "sensor.invalid_z");
    }

    #[test]
    fn camera_and_profiler_readers_refuse_each_other() {
        let profiler = r#"{"format": "stripecal/rig@1", "sensor": {"kind": "profiler"},
                           "artefact": {"kind": "sphere", "diameter_mm": 25}}"#;
        let e = rig_from_json(Path::new(P), profiler).unwrap_err();
        let (loc, msg) = location(e);
        assert_eq!(loc, "sensor.kind");
        assert!(
            msg.starts_with("rig.json describes a profiler (sensor.kind = \"profiler\");"),
            "{msg}"
        );
        let camera = r#"{"format": "stripecal/rig@1", "sensor": {"kind": "camera"},
            "camera": {"width": 64, "height": 48},
            "board": {"rows": 3, "cols": 4, "pitch_mm": 5, "circle_diameter_mm": 2,
                      "marker_diameter_mm": 3}}"#;
        // the camera reader accepts the optional key
        let rig = rig_from_json(Path::new(P), camera).unwrap();
        assert_eq!((rig.width, rig.height), (64, 48));
        let (loc, msg) = location(read(camera).unwrap_err());
        assert_eq!(loc, "sensor.kind");
        assert!(msg.contains("describes a camera"), "{msg}");
    }

    #[test]
    fn writes_what_it_reads() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rig.json");
        for rig in [
            ProfileRig {
                robot: Some(Robot::hp3()),
                invalid_z: Some(-99999.9999),
                diameter_mm: Some(25.4012),
            },
            ProfileRig {
                robot: None,
                invalid_z: None,
                diameter_mm: None,
            },
        ] {
            write_profile_rig(&path, &rig).unwrap();
            assert_eq!(read_profile_rig(&path).unwrap(), rig);
        }
        let bad = ProfileRig {
            robot: None,
            invalid_z: None,
            diameter_mm: Some(0.0),
        };
        assert!(matches!(
            write_profile_rig(&path, &bad),
            Err(Error::InvalidInput(_))
        ));
    }
}
