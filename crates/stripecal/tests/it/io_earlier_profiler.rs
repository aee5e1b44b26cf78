//! A profiler's calibration.json written by the code before its typed records (issue 40;
//! `crates/stripecal/tests/data/profiler_v1.json`: a 10-view hp3-profiler twin, seed 5,
//! calibrated with `robot="offsets"`) loads into `ProfilerRecords` with every field,
//! keeps nothing in `extra`, and writes the records back byte for byte in their place; a key this version does
//! not know, or a known key that does not read as its record, stays in `extra`.

use std::path::{Path, PathBuf};

use serde_json::Value;
use stripecal::io::{profiler_calibration_from_json, profiler_calibration_to_json};
use stripecal::model::ProfilerCalibration;

fn text() -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/profiler_v1.json");
    std::fs::read_to_string(p).unwrap()
}

fn parse(text: &str) -> ProfilerCalibration {
    profiler_calibration_from_json(Path::new("profiler_v1.json"), text).unwrap()
}

/// A number of the file (`null`: NaN).
fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn u(v: &Value) -> usize {
    v.as_u64().unwrap() as usize
}

#[test]
fn an_earlier_profiler_calibration_loads_as_its_records_and_keeps_its_bytes() {
    let text = text();
    let j: Value = serde_json::from_str(&text).unwrap();
    let c = parse(&text);
    let r = &c.records;
    assert!(c.extra.is_empty(), "{:?}", c.extra.keys());
    let rc = r.robot_calibration.as_ref().expect("robot_calibration");
    assert_eq!(rc.mode, j["robot_calibration"]["mode"]);
    assert_eq!(
        rc.estimated.len(),
        j["robot_calibration"]["estimated"]
            .as_array()
            .unwrap()
            .len()
    );
    assert_eq!(r.sphere_diameter_estimated, Some(false));
    let a = r.adjustment.as_ref().expect("adjustment");
    assert_eq!(a.sigma_mm, f(&j["adjustment"]["sigma_mm"]));
    assert_eq!(a.points_used, u(&j["adjustment"]["points_used"]));
    assert_eq!(a.iterations, u(&j["adjustment"]["iterations"]));
    let views = r.views.as_ref().expect("views");
    let jv = j["views"].as_array().unwrap();
    assert_eq!(views.len(), jv.len());
    for (v, w) in views.iter().zip(jv) {
        assert_eq!(v.view, u(&w["view"]));
        assert_eq!(v.line, u(&w["line"]));
        assert_eq!(v.profile, w["profile"]);
        assert_eq!(v.used, w["used"]);
        assert_eq!(v.points, u(&w["points"]));
        assert_eq!(v.sphere_points, u(&w["sphere_points"]));
        assert_eq!(v.rms_mm, w["rms_mm"].as_f64());
        assert_eq!(v.side, w["side"].as_f64());
        assert_eq!(
            v.centre_in_sensor_mm.unwrap()[2],
            f(&w["centre_in_sensor_mm"][2])
        );
    }
    let m = r.mirror.as_ref().expect("mirror");
    assert_eq!(m.delta_chi2, f(&j["mirror"]["delta_chi2"]));
    assert_eq!(m.passed, j["mirror"]["passed"]);
    assert_eq!(
        m.centre_spread_mm[3],
        f(&j["mirror"]["centre_spread_mm"]["across_plane"])
    );
    let d = r.diameter_check.as_ref().expect("diameter_check");
    assert_eq!(d.estimate_mm, f(&j["diameter_check"]["estimate_mm"]));
    assert_eq!(d.disagrees, j["diameter_check"]["disagrees"]);
    let l = r.leave_one_out.as_ref().expect("leave_one_out");
    assert_eq!(l.median_rms_mm, f(&j["leave_one_out"]["median_rms_mm"]));
    assert_eq!(
        l.views.len(),
        j["leave_one_out"]["views"].as_array().unwrap().len()
    );
    assert!(r.warnings.is_empty());
    // written back: the records' bytes the same, in the same place (the pose's rotation
    // vector is not: it goes through a rotation matrix, as before the records)
    let back = profiler_calibration_to_json(&c);
    let from = |t: &str| t[t.find("\n  \"robot_calibration\"").unwrap()..].to_string();
    assert_eq!(from(&back), from(&text));
    let keys = |t: &str| -> Vec<String> {
        let v: Value = serde_json::from_str(t).unwrap();
        v.as_object().unwrap().keys().cloned().collect()
    };
    assert_eq!(keys(&back), keys(&text));
}

#[test]
fn unknown_profiler_keys_and_odd_records_stay_in_extra() {
    let mut j: Value = serde_json::from_str(&text()).unwrap();
    j["warnings"] = serde_json::json!(["a warning"]);
    j["mirror"] = "not a record".into();
    j["a_later_key"] = serde_json::json!({"x": 1});
    let c = parse(&serde_json::to_string_pretty(&j).unwrap());
    assert_eq!(c.records.warnings, ["a warning"]);
    assert!(c.records.mirror.is_none());
    assert_eq!(c.extra["mirror"], "not a record");
    assert_eq!(c.extra["a_later_key"], j["a_later_key"]);
    let mut back: Value = serde_json::from_str(&profiler_calibration_to_json(&c)).unwrap();
    // (the pose's rotation vector goes through a rotation matrix: its last digits move)
    for v in [&mut back, &mut j] {
        v.as_object_mut().unwrap().remove("hand_cam");
    }
    assert_eq!(back, j);
}
