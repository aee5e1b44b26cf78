//! calibration.json files written by the code before the typed result records (issue
//! 40; `crates/stripecal/tests/data/*_v1.json`: tiny hp3-paper twins calibrated with
//! held blocks and robot-pose noise, with `--robot offsets`, and on the bench) load into
//! the typed records with every field, keep only the keys this version does not know in
//! `extra`, and are written back with the same keys and values.

use std::path::PathBuf;

use serde_json::Value;
use stripecal::io::{calibration_to_json, read_calibration};
use stripecal::model::{Calibration, Mount};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// The file's JSON and the calibration read from it.
fn load(name: &str) -> (Value, Calibration) {
    let p = data(name);
    let json = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    (json, read_calibration(&p).unwrap())
}

/// A number of the file (`null`: NaN).
fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn same(a: f64, b: &Value) -> bool {
    a == f(b) || (a.is_nan() && b.is_null())
}

/// The records every calibration of the pipeline holds: summary, views, warnings,
/// leave-one-out, field by field against the file.
fn check_common_records(j: &Value, c: &Calibration) {
    let r = &c.records;
    let s = r.summary.as_ref().expect("summary");
    assert_eq!(s.method, j["method"]);
    assert_eq!(s.centre_model, j["centre_model"]);
    assert_eq!(
        s.base_board_orientation.as_deref(),
        j["base_board_orientation"].as_str()
    );
    assert!(same(s.stripe_rms_mm, &j["stripe_rms_mm"]));
    assert!(same(
        s.residual_sigma_px.0,
        &j["residual_sigma_px"]["circle"]
    ));
    assert!(same(
        s.residual_sigma_px.1,
        &j["residual_sigma_px"]["stripe"]
    ));
    assert_eq!(
        s.stripe_off_plane as u64,
        j["stripe_off_plane"].as_u64().unwrap()
    );
    let views = r.views.as_ref().expect("views");
    let jv = j["views"].as_array().unwrap();
    assert_eq!(views.len(), jv.len());
    for (v, o) in views.iter().zip(jv) {
        assert_eq!(v.view as u64, o["view"].as_u64().unwrap());
        assert_eq!(v.used, o["used"].as_bool().unwrap());
        assert_eq!(v.circles as u64, o["circles"].as_u64().unwrap());
        assert_eq!(v.stripe_points as u64, o["stripe_points"].as_u64().unwrap());
        assert_eq!(
            v.stripe_off_plane as u64,
            o["stripe_off_plane"].as_u64().unwrap()
        );
        assert_eq!(v.circle_rms_px, o["circle_rms_px"].as_f64());
        assert_eq!(v.stripe_rms_px, o["stripe_rms_px"].as_f64());
        assert_eq!(v.outlier, o["outlier"].as_bool());
        assert_eq!(v.note.as_deref(), o["note"].as_str());
        let e = v.stripe_extraction.expect("stripe_extraction");
        let je = &o["stripe_extraction"];
        assert_eq!(e.lines as u64, je["scan_lines"].as_u64().unwrap());
        assert_eq!(e.found as u64, je["found"].as_u64().unwrap());
        assert_eq!(
            e.at_edge as u64,
            je["left_out"]["at_edge"].as_u64().unwrap()
        );
        assert_eq!(
            e.rejected.no_peak as u64,
            je["scan_lines_without_point"]["no_peak"].as_u64().unwrap()
        );
        assert_eq!(
            e.rejected.reflections as u64,
            je["reflections_left_out"].as_u64().unwrap()
        );
        assert!(same(e.width_px, &je["width_px"]));
        assert!(same(e.saturated_share(), &je["saturated_share"]));
    }
    let w: Vec<&str> = j["warnings"].as_array().map_or(Vec::new(), |a| {
        a.iter().map(|x| x.as_str().unwrap()).collect()
    });
    assert_eq!(r.warnings, w);
    let l = r.leave_one_out.as_ref().expect("leave_one_out");
    let jl = &j["leave_one_out"];
    assert!(same(l.median_board_rms_px, &jl["median_board_rms_px"]));
    assert!(same(l.median_board_rms_mm, &jl["median_board_rms_mm"]));
    assert_eq!(l.median_stripe_rms_mm, jl["median_stripe_rms_mm"].as_f64());
    let lb = l.laser_board.expect("laser_board");
    assert!(same(lb.median_mm, &jl["laser_board"]["median_mm"]));
    assert!(same(lb.p95_mm, &jl["laser_board"]["p95_mm"]));
    assert_eq!(
        lb.points as u64,
        jl["laser_board"]["points"].as_u64().unwrap()
    );
    for (v, o) in l.views.iter().zip(jl["views"].as_array().unwrap()) {
        assert_eq!(v.view as u64, o["view"].as_u64().unwrap());
        assert_eq!(v.points as u64, o["points"].as_u64().unwrap());
        assert!(same(v.board_rms_px, &o["board_rms_px"]));
        assert!(same(v.board_rms_mm, &o["board_rms_mm"]));
        assert_eq!(v.stripe_points as u64, o["stripe_points"].as_u64().unwrap());
        assert_eq!(v.stripe_rms_mm, o["stripe_rms_mm"].as_f64());
        assert_eq!(v.disagrees, o["disagrees"].as_bool().unwrap());
        let fold = v.fold.as_ref().expect("fold");
        assert_eq!(fold.camera.fu, f(&o["fold"]["camera"]["fu"]));
        assert!((fold.plane.d - f(&o["fold"]["laser_plane"]["d_mm"])).abs() < 1e-12);
    }
    assert_eq!(l.views.len(), jl["views"].as_array().unwrap().len());
}

/// The first place where `a` and `b` differ (numbers to 1e-12 relative: the reader
/// renormalises planes and turns rotation vectors into rotations), `None` when nowhere.
fn differ(a: &Value, b: &Value, at: &str) -> Option<String> {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            ((x - y).abs() > 1e-12 * x.abs().max(y.abs()).max(1e-3))
                .then(|| format!("{at}: {x} != {y}"))
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (x, y))| differ(x, y, &format!("{at}[{i}]"))),
        (Value::Object(x), Value::Object(y)) => {
            let mut kx: Vec<&String> = x.keys().collect();
            let mut ky: Vec<&String> = y.keys().collect();
            kx.sort();
            ky.sort();
            if kx != ky {
                return Some(format!("{at}: keys {kx:?} != {ky:?}"));
            }
            x.iter()
                .find_map(|(k, v)| differ(v, &y[k], &format!("{at}.{k}")))
        }
        _ => (a != b).then(|| format!("{at}: {a} != {b}")),
    }
}

/// Written back: the same keys with the same values (key order aside), and
/// `quality.target_rms_px` beside the contract's `circle_rms_px`.
fn check_written_back(j: &Value, c: &Calibration) {
    let mut back: Value = serde_json::from_str(&calibration_to_json(c)).unwrap();
    let q = back["quality"].as_object_mut().unwrap();
    assert_eq!(
        q.shift_remove("target_rms_px"),
        Some(q["circle_rms_px"].clone())
    );
    if let Some(d) = differ(&back, j, "") {
        panic!("written back differs at {d}");
    }
}

fn check_board_scale(j: &Value, c: &Calibration) {
    let b = c.records.board_scale.as_ref().expect("board_scale");
    let jb = &j["board_scale"];
    for (x, k) in [
        (b.scale, "scale"),
        (b.sigma, "sigma"),
        (b.declared_mm, "declared_mm"),
        (b.implied_mm, "implied_mm"),
        (b.tolerance, "tolerance"),
    ] {
        assert!(same(x, &jb[k]), "board_scale.{k}");
    }
    assert_eq!(b.estimated, jb["estimated"].as_bool().unwrap());
    assert_eq!(b.disagrees, jb["disagrees"].as_bool().unwrap());
}

#[test]
fn a_robot_calibration_with_held_blocks_and_robot_pose_noise_loads_every_record() {
    let (j, c) = load("held_v1.json");
    assert_eq!(c.mount, Mount::Robot);
    check_common_records(&j, &c);
    check_board_scale(&j, &c);
    let n = c
        .records
        .robot_pose_noise
        .as_ref()
        .expect("robot_pose_noise");
    let jn = &j["robot_pose_noise"];
    assert!(same(n.sigma_translation_mm, &jn["translation_mm"]));
    assert!(same(n.sigma_rotation_deg, &jn["rotation_deg"]));
    assert_eq!(n.image_factor, jn["image_factor"].as_f64());
    assert_eq!(n.kinematic_mm, jn["kinematic_mm"].as_f64());
    assert_eq!(n.kinematic_deg, jn["kinematic_deg"].as_f64());
    assert_eq!(
        n.translation_at_floor,
        jn["at_floor"]["translation"].as_bool().unwrap()
    );
    assert_eq!(
        n.rotation_at_floor,
        jn["at_floor"]["rotation"].as_bool().unwrap()
    );
    assert_eq!(
        n.image_factor_at_floor,
        jn["at_floor"]["image"].as_bool().unwrap()
    );
    assert!(same(n.floor_translation_mm, &jn["floor"]["translation_mm"]));
    assert!(same(n.floor_rotation_deg, &jn["floor"]["rotation_deg"]));
    assert_eq!(n.views.len(), jn["views"].as_array().unwrap().len());
    for (v, o) in n.views.iter().zip(jn["views"].as_array().unwrap()) {
        assert_eq!(v.view as u64, o["view"].as_u64().unwrap());
        assert!(same(v.translation_mm, &o["translation_mm"]));
        assert!(same(v.rotation_deg, &o["rotation_deg"]));
        assert!(same(v.test, &o["test"]));
    }
    assert_eq!(n.left_out.len(), jn["left_out"].as_array().unwrap().len());
    assert_eq!(
        c.records.held_blocks.as_deref(),
        Some(&["camera".to_string()][..])
    );
    assert!(c.records.robot_calibration.is_none());
    // only the keys this version has no record for
    let extra: Vec<&str> = c.extra.keys().map(|k| k.as_str()).collect();
    assert_eq!(extra, ["board_stripe_bias"]);
    check_written_back(&j, &c);
}

#[test]
fn a_robot_calibration_with_dh_corrections_loads_them() {
    let (j, c) = load("robot_v1.json");
    assert_eq!(c.mount, Mount::Robot);
    check_common_records(&j, &c);
    check_board_scale(&j, &c);
    let rc = c
        .records
        .robot_calibration
        .as_ref()
        .expect("robot_calibration");
    let jr = &j["robot_calibration"];
    assert_eq!(rc.mode, jr["mode"]);
    assert_eq!(Some(&rc.robot), c.robot.as_ref());
    let est = jr["estimated"].as_array().unwrap();
    assert!(!est.is_empty());
    assert_eq!(rc.estimated.len(), est.len());
    for (e, o) in rc.estimated.iter().zip(est) {
        assert_eq!(e.name, o["name"]);
        assert!(same(e.correction, &o["correction"]));
        assert!(same(e.sigma, &o["sigma"]));
    }
    let fixed = jr["fixed"].as_array().unwrap();
    assert_eq!(rc.fixed.len(), fixed.len());
    for ((name, why), o) in rc.fixed.iter().zip(fixed) {
        assert_eq!(name, &o["name"]);
        assert_eq!(why, &o["reason"]);
    }
    assert!(c.records.robot_pose_noise.is_none() && c.records.held_blocks.is_none());
    let extra: Vec<&str> = c.extra.keys().map(|k| k.as_str()).collect();
    assert_eq!(extra, ["board_stripe_bias"]);
    check_written_back(&j, &c);
}

#[test]
fn a_bench_calibration_loads_as_the_bench_mount() {
    let (j, c) = load("bench_v1.json");
    assert_eq!(c.mount, Mount::Bench);
    assert!(c.is_bench() && c.robot.is_none());
    assert!(j.get("hand_cam").is_none() && j["bench"] == Value::Bool(true));
    check_common_records(&j, &c);
    assert!(c.records.board_scale.is_none() && c.records.robot_pose_noise.is_none());
    let extra: Vec<&str> = c.extra.keys().map(|k| k.as_str()).collect();
    assert_eq!(extra, ["board_flatness"]);
    check_written_back(&j, &c);
}

#[test]
fn a_colour_calibrations_stripe_channel_loads_as_its_record_and_keeps_its_place() {
    // the keys as the code before the typed record wrote them: after the other extra keys
    let (mut j, _) = load("held_v1.json");
    let m = j.as_object_mut().unwrap();
    m.insert(
        "board_stripe_bias".into(),
        serde_json::json!({"applied": false, "reason": "a test"}),
    );
    m.insert("stripe_channel".into(), "red".into());
    m.insert(
        "stripe_channel_scores".into(),
        serde_json::json!({"gray": 12.0, "red": 340.0, "green": 5.0, "blue": 0.0}),
    );
    let text = serde_json::to_string_pretty(&j).unwrap();
    let c = stripecal::io::calibration_from_json(std::path::Path::new("t.json"), &text).unwrap();
    let s = c.records.stripe_channel.as_ref().expect("stripe_channel");
    assert_eq!(s.channel, stripecal::model::StripeChannel::Red);
    let names: Vec<(&str, f64)> = s
        .scores
        .as_ref()
        .expect("scores")
        .iter()
        .map(|(c, x)| (c.name(), *x))
        .collect();
    assert_eq!(
        names,
        [
            ("gray", 12.0),
            ("red", 340.0),
            ("green", 5.0),
            ("blue", 0.0)
        ]
    );
    assert!(!c.extra.contains_key("stripe_channel"));
    assert!(!c.extra.contains_key("stripe_channel_scores"));
    check_written_back(&j, &c);
    let back: Value = serde_json::from_str(&calibration_to_json(&c)).unwrap();
    let keys: Vec<&str> = back
        .as_object()
        .unwrap()
        .keys()
        .map(|k| k.as_str())
        .collect();
    assert_eq!(
        keys[keys.len() - 3..],
        [
            "board_stripe_bias",
            "stripe_channel",
            "stripe_channel_scores"
        ]
    );
    // a channel this version does not know stays in `extra`, as the file has it
    let mut odd = j.clone();
    odd["stripe_channel"] = "purple".into();
    let text = serde_json::to_string_pretty(&odd).unwrap();
    let c = stripecal::io::calibration_from_json(std::path::Path::new("t.json"), &text).unwrap();
    assert!(c.records.stripe_channel.is_none());
    assert_eq!(c.extra["stripe_channel"], "purple");
    assert!(c.extra.contains_key("stripe_channel_scores"));
}
