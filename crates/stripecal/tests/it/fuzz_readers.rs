//! Property tests of every file reader (issue 13, acceptance 4; docs/robustness.md).
//!
//! (a) Arbitrary input — random bytes, random text, and documents that are valid except
//! for one random subtree, header or field — gives `Ok` or a typed error naming the
//! file, never a panic or a hang (each case runs under [`guarded`]).
//! (b) Round trips where a writer exists: calibration.json, truth.json, sphere fits,
//! rig.json, PLY (binary and ASCII), views.csv and scan.csv in every pose convention
//! (rotation MATRICES compared, not angles), `pose_to_matrix` / `matrix_to_pose`, and
//! 8/16-bit PNG images. Whatever a reader accepts, its writer writes back and the
//! reader reads again to the same value.
//!
//! Budget: each property runs its default number of cases times `STRIPECAL_FUZZ_CASES`
//! (default 1) from the fixed seed `STRIPECAL_FUZZ_SEED`; a failure prints the shrunk
//! input.

use crate::fuzz_support;

use std::path::{Path, PathBuf};

use fuzz_support::*;
use nalgebra::{DMatrix, Vector3};
use proptest::prelude::*;
use proptest::test_runner::{Config as ProptestConfig, RngSeed};
use serde_json::{Map, Value};
use stripecal::io::{self, PlyFormat};
use stripecal::model::camera::Projection;
use stripecal::model::image::{AnyGray, GrayImage};
use stripecal::model::{
    Calibration, Cloud, NamedCovariance, Quality, Rig, RobotReading, ScanFrame, Sphere, SphereFit,
    StripeDirection, Truth, View,
};
use stripecal::{Board, Camera, DhJoint, DistortionModel, Error, Iso3, Plane, Robot};

fn config(default_cases: usize) -> ProptestConfig {
    ProptestConfig {
        cases: cases(default_cases) as u32,
        failure_persistence: None,
        rng_seed: RngSeed::Fixed(seed()),
        max_shrink_time: 60_000,
        ..ProptestConfig::default()
    }
}

/// A scratch file for one property's cases (rewritten by each case).
struct Scratch {
    _dir: tempfile::TempDir,
    path: PathBuf,
}

impl Scratch {
    fn new(name: &str) -> Scratch {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        Scratch { _dir: dir, path }
    }

    fn write(&self, bytes: &[u8]) -> PathBuf {
        std::fs::write(&self.path, bytes).unwrap();
        self.path.clone()
    }
}

/// Runs a path reader on `bytes` under the deadline; errors must name the file.
fn read_file<T: Send + 'static>(
    case: &str,
    scratch: &Scratch,
    bytes: &[u8],
    reader: fn(&Path) -> stripecal::Result<T>,
) -> Option<T> {
    let p = scratch.write(bytes);
    let p2 = p.clone();
    match guarded(case, READER_DEADLINE, move || reader(&p2)) {
        Ok(v) => Some(v),
        Err(e) => {
            assert_names_file(case, &e, &p);
            assert_located(case, &e);
            None
        }
    }
}

// ---------------------------------------------------------------- strategies

/// Text that looks like a number to a parser, or nearly.
fn arb_number_text() -> impl Strategy<Value = String> {
    prop_oneof![
        prop::sample::select(HOSTILE_NUMBERS.to_vec()).prop_map(str::to_string),
        any::<f64>().prop_map(|x| x.to_string()),
        any::<i64>().prop_map(|x| x.to_string()),
        (-1000.0..1000.0f64).prop_map(|x| format!("{x}")),
        "[-+0-9.eE]{0,12}",
    ]
}

/// A JSON leaf: the values readers trip on.
fn arb_json_leaf() -> impl Strategy<Value = Value> {
    prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        prop::num::f64::NORMAL.prop_map(Value::from),
        prop::sample::select(vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            2.0,
            8.0,
            1e308,
            -1e308,
            5e-324,
            1e-3,
            4294967296.0,
            9007199254740993.0,
            1e20
        ])
        .prop_map(Value::from),
        prop::sample::select(vec![
            "",
            "circles",
            "chessboard",
            "asymmetric_circles",
            "radial1",
            "radial2",
            "opencv5",
            "auto",
            "rows",
            "cols",
            "stripecal/rig@1",
            "stripecal/calibration@1",
            "stripecal/truth@1",
            "x\u{0}y",
            "\u{feff}"
        ])
        .prop_map(Value::from),
        "\\PC{0,8}".prop_map(Value::from),
    ]
}

/// Keys the readers know, so random objects hit them.
const KEYS: &[&str] = &[
    "format",
    "camera",
    "width",
    "height",
    "fu",
    "fv",
    "u0",
    "v0",
    "distortion_model",
    "distortion",
    "board",
    "kind",
    "rows",
    "cols",
    "pitch_mm",
    "circle_diameter_mm",
    "marker_diameter_mm",
    "markers",
    "dark_circles",
    "square_mm",
    "robot",
    "name",
    "joints",
    "theta0_deg",
    "alpha_deg",
    "a_mm",
    "d_mm",
    "stripe",
    "direction",
    "laser_plane",
    "normal",
    "hand_cam",
    "base_board",
    "rotation_vector",
    "translation_mm",
    "quality",
    "circle_rms_px",
    "stripe_rms_px",
    "views_used",
    "uncertainty",
    "covariance",
    "parameters",
    "matrix",
    "sphere",
    "center_mm",
    "diameter_mm",
    "working_range_mm",
    "rms_mm",
    "points",
    "outliers",
];

fn arb_json() -> impl Strategy<Value = Value> {
    arb_json_leaf().prop_recursive(4, 48, 6, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..6).prop_map(Value::Array),
            prop::collection::vec((prop::sample::select(KEYS.to_vec()), inner), 0..6).prop_map(
                |kv| Value::Object(kv.into_iter().map(|(k, v)| (k.to_string(), v)).collect())
            ),
        ]
    })
}

/// Edits `doc` at a random place chosen by `path`: replace a subtree by `new`, delete
/// a key / item, or add a key.
fn edit_json(doc: &mut Value, path: &[u32], new: Value) {
    let Some((&sel, rest)) = path.split_first() else {
        *doc = new;
        return;
    };
    let last = rest.is_empty();
    let action = sel % 8;
    let pick = sel as usize / 8;
    match doc {
        Value::Object(m) if !m.is_empty() => {
            let k = m.keys().nth(pick % m.len()).cloned().unwrap_or_default();
            match action {
                _ if last => {
                    m.insert(k, new);
                }
                1 => {
                    m.remove(&k);
                }
                2 => {
                    m.insert(KEYS[pick % KEYS.len()].to_string(), new);
                }
                _ => {
                    if let Some(child) = m.get_mut(&k) {
                        edit_json(child, rest, new);
                    }
                }
            }
        }
        Value::Array(a) if !a.is_empty() => {
            let i = pick % a.len();
            match action {
                _ if last => a[i] = new,
                1 => {
                    a.remove(i);
                }
                2 => a.push(new),
                _ => edit_json(&mut a[i], rest, new),
            }
        }
        other => *other = new,
    }
}

fn arb_edit() -> impl Strategy<Value = (Vec<u32>, Value)> {
    (prop::collection::vec(any::<u32>(), 1..5), arb_json())
}

fn calibration_text() -> String {
    io::calibration_to_json(&calibration())
}

fn truth() -> Truth {
    let c = calibration();
    Truth {
        camera: c.camera,
        laser_plane: c.laser_plane.unwrap(),
        hand_cam: c.hand_cam,
        base_board: c.base_board,
        robot: c.robot,
        sphere: Some(Sphere {
            center_mm: Vector3::new(400.0, 0.0, -200.0),
            diameter_mm: 44.8614,
        }),
        working_range_mm: Some([80.0, 130.0]),
        extra: Map::new(),
    }
}

fn sphere_fit() -> SphereFit {
    SphereFit {
        diameter_mm: 44.86,
        center_mm: Vector3::new(1.0, 2.0, 3.0),
        rms_mm: 0.01,
        points: 1000,
        outliers: 3,
        extra: Map::new(),
    }
}

// ---------------------------------------------------------------- equality helpers

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

fn iso_close(a: &Iso3, b: &Iso3, tol: f64) -> bool {
    let (ra, rb) = (
        a.rotation.to_rotation_matrix().into_inner(),
        b.rotation.to_rotation_matrix().into_inner(),
    );
    ra.iter().zip(rb.iter()).all(|(x, y)| (x - y).abs() <= tol)
        && a.translation
            .vector
            .iter()
            .zip(b.translation.vector.iter())
            .all(|(x, y)| close(*x, *y, tol))
}

/// The first part of two calibrations that differs, if any.
fn calibration_diff(a: &Calibration, b: &Calibration) -> Option<String> {
    let plane = |c: &Calibration| c.laser_plane.map(|p| (p.normal, p.d));
    let planes_close = match (plane(a), plane(b)) {
        (Some((na, da)), Some((nb, db))) => (na - nb).norm() <= 1e-15 && close(da, db, 1e-15),
        (None, None) => true,
        _ => false,
    };
    let parts: [(&str, bool); 9] = [
        ("camera", a.camera == b.camera),
        ("laser_plane", planes_close),
        ("hand_cam", iso_close(&a.hand_cam, &b.hand_cam, 1e-12)),
        ("base_board", iso_close(&a.base_board, &b.base_board, 1e-12)),
        ("robot", a.robot == b.robot),
        ("quality", a.quality == b.quality),
        ("uncertainty", a.uncertainty == b.uncertainty),
        ("covariance", same_covariance(&a.covariance, &b.covariance)),
        ("extra", a.extra == b.extra),
    ];
    parts
        .iter()
        .find(|(_, same)| !same)
        .map(|(name, _)| format!("{name}: {:?} vs {:?}", a, b))
}

/// Whatever calibration.json the reader accepts is valid: the writer takes it and the
/// reader reads the written file back to the same values.
fn check_calibration_rewrites(case: &str, c: &Calibration) {
    assert!(
        finite_iso(&c.hand_cam),
        "{case}: accepted a non-finite hand_cam {:?}",
        c.hand_cam
    );
    assert!(
        finite_iso(&c.base_board),
        "{case}: accepted a non-finite base_board"
    );
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("calibration.json");
    io::write_calibration(&p, c)
        .unwrap_or_else(|e| panic!("{case}: the reader accepted what the writer refuses: {e}"));
    let back = io::read_calibration(&p).unwrap_or_else(|e| panic!("{case}: re-read: {e}"));
    if let Some(d) = calibration_diff(c, &back) {
        panic!("{case}: write -> read changed the calibration: {d}");
    }
    assert!(
        temporaries(dir.path()).is_empty(),
        "{case}: temporaries left"
    );
}

// ---------------------------------------------------------------- (a) arbitrary input

proptest! {
    #![proptest_config(config(256))]

    #[test]
    fn rig_json_arbitrary_text_is_ok_or_typed(text in "\\PC{0,400}") {
        let s = Scratch::new("rig.json");
        read_file("rig.json (text)", &s, text.as_bytes(), |p| io::read_rig(p));
    }

    #[test]
    fn rig_json_with_one_random_edit(edit in arb_edit(), seed in 0usize..3) {
        let seed_text = [RIG_JSON, RIG_CHESS_JSON, RIG_ASYM_JSON][seed];
        let mut doc: Value = serde_json::from_str(seed_text).unwrap();
        edit_json(&mut doc, &edit.0, edit.1);
        let text = serde_json::to_string(&doc).unwrap();
        let case = format!("rig.json edit {text}");
        let s = Scratch::new("rig.json");
        if let Some(rig) = read_file(&case, &s, text.as_bytes(), |p| io::read_rig(p)) {
            check_rig_rewrites(&case, &rig);
        }
    }

    #[test]
    fn calibration_json_arbitrary_text_is_ok_or_typed(text in "\\PC{0,400}") {
        let s = Scratch::new("calibration.json");
        read_file("calibration.json (text)", &s, text.as_bytes(), |p| io::read_calibration(p));
    }

    #[test]
    fn calibration_json_with_one_random_edit(edit in arb_edit()) {
        let mut doc: Value = serde_json::from_str(&calibration_text()).unwrap();
        edit_json(&mut doc, &edit.0, edit.1);
        let text = serde_json::to_string(&doc).unwrap();
        let case = format!("calibration.json edit {text}");
        let s = Scratch::new("calibration.json");
        if let Some(c) = read_file(&case, &s, text.as_bytes(), |p| io::read_calibration(p)) {
            check_calibration_rewrites(&case, &c);
        }
    }

    #[test]
    fn truth_and_sphere_fit_with_one_random_edit(edit in arb_edit(), which in 0usize..2) {
        let seed_text = if which == 0 {
            io::truth_to_json(&truth())
        } else {
            io::sphere_fit_to_json(&sphere_fit())
        };
        let mut doc: Value = serde_json::from_str(&seed_text).unwrap();
        edit_json(&mut doc, &edit.0, edit.1);
        let text = serde_json::to_string(&doc).unwrap();
        let case = format!("truth/sphere edit {text}");
        if which == 0 {
            let s = Scratch::new("truth.json");
            if let Some(t) = read_file(&case, &s, text.as_bytes(), |p| io::read_truth(p)) {
                let dir = tempfile::tempdir().unwrap();
                let p = dir.path().join("truth.json");
                io::write_truth(&p, &t).unwrap_or_else(|e| panic!("{case}: rewrite: {e}"));
                io::read_truth(&p).unwrap_or_else(|e| panic!("{case}: re-read: {e}"));
            }
        } else {
            let s = Scratch::new("sphere.json");
            if let Some(f) = read_file(&case, &s, text.as_bytes(), |p| io::read_sphere_fit(p)) {
                let dir = tempfile::tempdir().unwrap();
                let p = dir.path().join("sphere.json");
                io::write_sphere_fit(&p, &f).unwrap_or_else(|e| panic!("{case}: rewrite: {e}"));
                prop_assert_eq!(io::read_sphere_fit(&p).unwrap(), f);
            }
        }
    }

    #[test]
    fn json_parsers_take_arbitrary_text(text in "\\PC{0,300}", which in 0usize..3) {
        // the path-free parsers behind the readers
        let p = Path::new("in-memory.json");
        let t = text.clone();
        let r = guarded("json parsers", READER_DEADLINE, move || match which {
            0 => io::rig_from_json(Path::new("in-memory.json"), &t).err(),
            1 => io::calibration_from_json(Path::new("in-memory.json"), &t).err(),
            _ => io::truth_from_json(Path::new("in-memory.json"), &t).err(),
        });
        if let Some(e) = r {
            assert_names_file("json parsers", &e, p);
        }
    }

    #[test]
    fn views_and_scan_csv_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let s = Scratch::new("views.csv");
        read_file("views.csv (bytes)", &s, &bytes, |p| io::read_views_csv(p, None));
        let robot = Robot::hp3();
        let p = s.write(&bytes);
        match io::read_scan_csv(&p, Some(&robot)) {
            Ok(frames) => for f in &frames {
                prop_assert!(reading_is_valid(&f.reading));
            },
            Err(e) => assert_names_file("scan.csv (bytes)", &e, &p),
        }
    }

    #[test]
    fn views_csv_structured(
        header in arb_csv_header(),
        rows in prop::collection::vec(prop::collection::vec(arb_csv_field(), 0..16), 0..5),
        crlf in any::<bool>(),
        with_robot in any::<bool>(),
    ) {
        let mut text = header.join(",");
        for r in &rows {
            text.push('\n');
            text.push_str(&r.join(","));
        }
        if crlf {
            text = text.replace('\n', "\r\n");
        }
        let case = format!("views.csv {text:?}");
        let s = Scratch::new("views.csv");
        let p = s.write(text.as_bytes());
        let robot = Robot::hp3();
        let robot_ref = with_robot.then_some(&robot);
        let p2 = p.clone();
        let robot2 = robot_ref.cloned();
        let r = guarded(&case, READER_DEADLINE, move || io::read_views_csv(&p2, robot2.as_ref()));
        match r {
            Ok(views) => {
                for v in &views {
                    prop_assert!(reading_is_valid(&v.reading), "{}: invalid reading {:?}", case, v.reading);
                    prop_assert!(!v.board_image.as_os_str().is_empty());
                }
                // what was read can be written and read back
                if !views.is_empty() {
                    let dir = tempfile::tempdir().unwrap();
                    let out = dir.path().join("views.csv");
                    io::write_views_csv(&out, &views).unwrap_or_else(|e| panic!("{case}: rewrite: {e}"));
                    let back = io::read_views_csv(&out, robot_ref).unwrap();
                    prop_assert_eq!(back.len(), views.len());
                    for (a, b) in back.iter().zip(&views) {
                        prop_assert!(readings_close(&a.reading, &b.reading, 1e-9), "{}", case);
                    }
                }
            }
            Err(e) => {
                assert_names_file(&case, &e, &p);
                assert_located(&case, &e);
            }
        }
    }

    #[test]
    fn ply_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let s = Scratch::new("cloud.ply");
        read_file("cloud.ply (bytes)", &s, &bytes, |p| io::read_ply(p));
    }

    #[test]
    fn ply_structured_header(
        encoding in prop::sample::select(vec!["ascii", "binary_little_endian", "binary_big_endian", "binary_middle", ""]),
        elements in prop::collection::vec(arb_ply_element(), 0..4),
        data in prop::collection::vec(any::<u8>(), 0..200),
        ascii_data in prop::collection::vec(arb_number_text(), 0..30),
    ) {
        let mut h = format!("ply\nformat {encoding} 1.0\n");
        for (name, count, props) in &elements {
            h.push_str(&format!("element {name} {count}\n"));
            for p in props {
                h.push_str(p);
                h.push('\n');
            }
        }
        h.push_str("end_header\n");
        let mut bytes = h.clone().into_bytes();
        if encoding == "ascii" {
            bytes.extend_from_slice(ascii_data.join(" ").as_bytes());
        } else {
            bytes.extend_from_slice(&data);
        }
        let case = format!("PLY header {h:?}");
        let s = Scratch::new("cloud.ply");
        if let Some(c) = read_file(&case, &s, &bytes, |p| io::read_ply(p)) {
            for (name, values) in &c.properties {
                prop_assert_eq!(values.len(), c.points.len(), "{}: property {}", case, name);
            }
        }
    }

    #[test]
    fn images_arbitrary_bytes(
        magic in prop::sample::select(vec![
            &b""[..], b"\x89PNG\r\n\x1a\n", b"II*\0", b"MM\0*", b"BM", b"\xff\xd8\xff", b"GIF89a",
            b"P5\n", b"RIFF",
        ]),
        bytes in prop::collection::vec(any::<u8>(), 0..400),
    ) {
        let mut b = magic.to_vec();
        b.extend_from_slice(&bytes);
        let s = Scratch::new("image.png");
        if let Some(g) = read_file("image (bytes)", &s, &b, |p| io::load_gray(p)) {
            prop_assert!(image_is_valid(&g));
        }
    }
}

fn check_rig_rewrites(case: &str, rig: &Rig) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("rig.json");
    io::write_rig(&p, rig)
        .unwrap_or_else(|e| panic!("{case}: the writer refuses what was read: {e}"));
    let back = io::read_rig(&p).unwrap_or_else(|e| panic!("{case}: re-read: {e}"));
    assert_eq!(&back, rig, "{case}: write -> read changed the rig");
}

fn readings_close(a: &RobotReading, b: &RobotReading, tol: f64) -> bool {
    match (a, b) {
        (RobotReading::Joints(x), RobotReading::Joints(y)) => x == y,
        (RobotReading::FlangePose(x), RobotReading::FlangePose(y)) => iso_close(x, y, tol),
        _ => false,
    }
}

/// A views.csv header: the image columns (sometimes wrong), then joints or a random
/// choice, order and subset of pose columns.
fn arb_csv_header() -> impl Strategy<Value = Vec<String>> {
    let pose_names: Vec<&'static str> = vec![
        "x_mm", "y_mm", "z_mm", "x_m", "y_m", "z_m", "qw", "qx", "qy", "qz", "rx_rad", "ry_rad",
        "rz_rad", "rx_deg", "ry_deg", "rz_deg", "a_deg", "b_deg", "c_deg", "w_deg", "p_deg",
        "r_deg", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33", "q1", "q2", "q7",
        "q", "", " x_mm ", "\"x_mm\"",
    ];
    let conventions: Vec<String> = pose_specs();
    prop_oneof![
        // a valid convention, shuffled
        (prop::sample::select(conventions), any::<u64>()).prop_map(|(spec, k)| {
            let mut cols: Vec<String> = pose_columns(&spec)
                .names()
                .iter()
                .map(|s| s.to_string())
                .collect();
            let n = cols.len();
            cols.rotate_left((k as usize) % n);
            let mut h = vec!["board_image".to_string(), "laser_image".to_string()];
            h.extend(cols);
            h
        }),
        // joints
        (0usize..9).prop_map(|n| {
            let mut h = vec!["board_image".to_string(), "laser_image".to_string()];
            h.extend((1..=n).map(|i| format!("q{i}")));
            h
        }),
        // anything
        prop::collection::vec(prop::sample::select(pose_names), 0..14).prop_map(|cols| {
            let mut h = vec!["board_image".to_string(), "laser_image".to_string()];
            h.extend(cols.into_iter().map(str::to_string));
            h
        }),
    ]
}

fn arb_csv_field() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => arb_number_text(),
        1 => Just("images/a.png".to_string()),
        1 => Just(String::new()),
        1 => "\\PC{0,6}",
        1 => Just("0.7071067811865476".to_string()),
    ]
}

/// `(name, count, property lines)` of a PLY element.
fn arb_ply_element() -> impl Strategy<Value = (String, String, Vec<String>)> {
    let types = vec![
        "char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint8",
        "int16", "uint16", "int32", "uint32", "float32", "float64", "int64", "string",
    ];
    let names = vec!["x", "y", "z", "nx", "view", "u", "vertex_indices", "x"];
    let prop_line = (
        any::<bool>(),
        prop::sample::select(types.clone()),
        prop::sample::select(types),
        prop::sample::select(names),
    )
        .prop_map(|(list, t1, t2, n)| {
            if list {
                format!("property list {t1} {t2} {n}")
            } else {
                format!("property {t1} {n}")
            }
        });
    (
        prop::sample::select(vec!["vertex", "face", "edge", "vertex"]),
        prop_oneof![
            (0usize..5).prop_map(|n| n.to_string()),
            prop::sample::select(vec![
                "18446744073709551615",
                "18446744073709551616",
                "4294967295",
                "-1",
                "1e3",
                "",
                "1000000000000"
            ])
            .prop_map(str::to_string),
        ],
        prop::collection::vec(prop_line, 0..5),
    )
        .prop_map(|(n, c, p)| (n.to_string(), c, p))
}

// ---------------------------------------------------------------- (b) round trips

fn arb_unit() -> impl Strategy<Value = Vector3<f64>> {
    (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)
        .prop_filter("not zero", |(x, y, z)| x * x + y * y + z * z > 1e-6)
        .prop_map(|(x, y, z)| Vector3::new(x, y, z).normalize())
}

/// A rotation from an axis and an angle in `[-pi, pi]`, with the special angles (0, a
/// half turn, gimbal lock of the Euler conventions) over-represented.
fn arb_rotation() -> impl Strategy<Value = nalgebra::UnitQuaternion<f64>> {
    let pi = std::f64::consts::PI;
    (
        arb_unit(),
        prop_oneof![
            3 => -pi..pi,
            1 => prop::sample::select(vec![0.0, pi, -pi, pi / 2.0, -pi / 2.0, 1e-9, pi - 1e-9]),
        ],
        prop::sample::select(vec![
            None,
            Some(Vector3::y()),
            Some(Vector3::x()),
            Some(Vector3::z()),
        ]),
    )
        .prop_map(|(axis, angle, special)| {
            let axis = special.unwrap_or(axis);
            nalgebra::UnitQuaternion::from_scaled_axis(axis * angle)
        })
}

fn arb_pose() -> impl Strategy<Value = Iso3> {
    (
        arb_rotation(),
        prop::array::uniform3(prop_oneof![-5000.0..5000.0f64, Just(0.0), Just(-0.0)]),
    )
        .prop_map(|(q, t)| Iso3::from_parts(nalgebra::Translation3::from(Vector3::from(t)), q))
}

fn arb_camera() -> impl Strategy<Value = Camera> {
    (
        1u32..20000,
        1u32..20000,
        (1e-3..1e5f64, 1e-3..1e5f64),
        (-1e4..1e4f64, -1e4..1e4f64),
        prop::sample::select(vec![
            DistortionModel::Radial1,
            DistortionModel::Radial2,
            DistortionModel::OpenCv5,
        ]),
        prop::array::uniform5(-1.0..1.0f64),
    )
        .prop_map(|(w, h, (fu, fv), (u0, v0), model, distortion)| Camera {
            width: w,
            height: h,
            fu,
            fv,
            u0,
            v0,
            model,
            distortion,
            projection: Projection::Brown5,
        })
}

fn arb_robot() -> impl Strategy<Value = Robot> {
    (
        "\\PC{0,12}",
        prop::collection::vec(prop::array::uniform4(-1e4..1e4f64), 1..8),
    )
        .prop_map(|(name, rows)| Robot {
            name,
            joints: rows
                .into_iter()
                .map(|[t, a, am, d]| DhJoint {
                    theta0_deg: t,
                    alpha_deg: a,
                    a_mm: am,
                    d_mm: d,
                    beta_deg: 0.0,
                })
                .collect(),
            repeatability_mm: None,
            encoder_sigma_deg: None,
        })
}

/// A covariance; sometimes one number is not determined (its row and column NaN, as
/// the adjustment reports an unobservable parameter).
fn arb_covariance() -> impl Strategy<Value = NamedCovariance> {
    (1usize..6)
        .prop_flat_map(|n| {
            (
                prop::collection::vec(-10.0..10.0f64, n * n),
                proptest::option::of(0..n),
            )
                .prop_map(move |(v, k)| (n, v, k))
        })
        .prop_map(|(n, v, k)| {
            let a = DMatrix::from_vec(n, n, v);
            let mut matrix = &a * a.transpose();
            if let Some(k) = k {
                matrix.row_mut(k).fill(f64::NAN);
                matrix.column_mut(k).fill(f64::NAN);
            }
            NamedCovariance {
                parameters: (0..n).map(|i| format!("p[{i}]")).collect(),
                matrix,
            }
        })
}

fn arb_calibration() -> impl Strategy<Value = Calibration> {
    (
        arb_camera(),
        proptest::option::of((arb_unit(), 1e-3..1e4f64)),
        arb_pose(),
        arb_pose(),
        proptest::option::of(arb_robot()),
        (0.0..10.0f64, 0.0..10.0f64, 0usize..1000),
        proptest::option::of(arb_covariance()),
        prop::collection::vec(("[a-z_]{1,8}", arb_json_leaf()), 0..3),
    )
        .prop_map(
            |(camera, plane, hc, bb, robot, (c, s, n), cov, extra)| Calibration {
                camera,
                laser_plane: plane.map(|(n, d)| Plane::new(n, d).unwrap()),
                mount: stripecal::model::Mount::Robot,
                hand_cam: hc,
                base_board: bb,
                robot,
                quality: Quality {
                    circle_rms_px: c,
                    stripe_rms_px: s,
                    views_used: n,
                    checks: Vec::new(),
                    accepted_poor: false,
                },
                uncertainty: Map::new(),
                covariance: cov,
                records: Default::default(),
                extra: extra.into_iter().collect(),
            },
        )
}

fn arb_board() -> impl Strategy<Value = Board> {
    prop_oneof![
        (2usize..30, 2usize..30, 1.0..20.0f64).prop_map(|(r, c, p)| Board::circles(
            r,
            c,
            p,
            p * 0.4,
            p * 0.6
        )),
        (2usize..30, 2usize..30, 1.0..20.0f64).prop_map(|(r, c, p)| Board::chessboard(r, c, p)),
        (2usize..30, 2usize..30, 1.0..20.0f64).prop_map(|(r, c, p)| Board::asymmetric_circles(
            r,
            c,
            p,
            p * 0.3
        )),
    ]
    .prop_filter_map("a valid board", |b| b.ok())
}

/// Any f64 bit pattern in a cloud: NaN, infinities, -0 and subnormals included.
fn arb_cloud_value() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -1e6..1e6f64,
        1 => any::<f64>(),
        1 => prop::sample::select(vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.0, 5e-324, f64::MAX]),
    ]
}

fn arb_cloud() -> impl Strategy<Value = Cloud> {
    (0usize..40, 0usize..3).prop_flat_map(|(n, k)| {
        (
            prop::collection::vec(prop::array::uniform3(arb_cloud_value()), n),
            prop::collection::vec(prop::collection::vec(arb_cloud_value(), n), k),
        )
            .prop_map(|(points, props)| Cloud {
                points,
                properties: props
                    .into_iter()
                    .enumerate()
                    .map(|(i, v)| (format!("prop_{i}"), v))
                    .collect(),
            })
    })
}

fn same_f64(a: f64, b: f64, exact_bits: bool) -> bool {
    if exact_bits {
        a.to_bits() == b.to_bits()
    } else {
        a == b && a.is_sign_negative() == b.is_sign_negative() || (a.is_nan() && b.is_nan())
    }
}

proptest! {
    #![proptest_config(config(256))]

    #[test]
    fn calibration_round_trips(c in arb_calibration()) {
        check_calibration_rewrites("calibration round trip", &c);
    }

    #[test]
    fn rig_round_trips(
        w in 1u32..100_000, h in 1u32..100_000,
        board in arb_board(),
        robot in proptest::option::of(arb_robot()),
        dir in prop::sample::select(vec![StripeDirection::Auto, StripeDirection::Rows, StripeDirection::Cols]),
        model in prop::sample::select(vec![DistortionModel::Radial1, DistortionModel::Radial2, DistortionModel::OpenCv5]),
        channel in prop::sample::select(stripecal::model::StripeChannel::ALL.to_vec()),
    ) {
        let rig = Rig { width: w, height: h, distortion_model: model, board, robot, stripe_direction: dir, stripe_channel: channel };
        check_rig_rewrites("rig round trip", &rig);
    }

    #[test]
    fn ply_round_trips_both_encodings(c in arb_cloud()) {
        let dir = tempfile::tempdir().unwrap();
        for f in PLY_FORMATS {
            let p = dir.path().join("cloud.ply");
            io::write_ply(&p, &c, f).unwrap();
            let back = io::read_ply(&p).unwrap();
            let exact = f == PlyFormat::BinaryLittleEndian;
            prop_assert_eq!(back.points.len(), c.points.len());
            for (a, b) in back.points.iter().zip(&c.points) {
                for k in 0..3 {
                    prop_assert!(same_f64(a[k], b[k], exact), "{:?}: {:?} != {:?}", f, a, b);
                }
            }
            prop_assert_eq!(back.properties.len(), c.properties.len());
            for ((na, va), (nb, vb)) in back.properties.iter().zip(&c.properties) {
                prop_assert_eq!(na, nb);
                for (a, b) in va.iter().zip(vb) {
                    prop_assert!(same_f64(*a, *b, exact));
                }
            }
        }
        prop_assert!(temporaries(dir.path()).is_empty());
    }

    /// Every convention: values -> matrix -> values -> matrix gives the same MATRIX
    /// (angles may legitimately differ: q and -q, gimbal lock, a half turn).
    #[test]
    fn pose_conventions_round_trip_as_matrices(t in arb_pose(), spec in prop::sample::select(pose_specs())) {
        let cols = [spec.as_str()];
        let values = io::matrix_to_pose(&t, &cols).unwrap();
        prop_assert!(values.iter().all(|x| x.is_finite()));
        let back = io::pose_to_matrix(&values, &cols).unwrap();
        prop_assert!(iso_close(&back, &t, 1e-9), "{}: {:?} -> {:?} -> {:?}", spec, t, values, back);
        let again = io::matrix_to_pose(&back, &cols).unwrap();
        let back2 = io::pose_to_matrix(&again, &cols).unwrap();
        prop_assert!(iso_close(&back2, &t, 1e-9));
    }

    /// Arbitrary values in any convention: an error, or a finite rigid transform that
    /// converts back to the same matrix.
    #[test]
    fn pose_to_matrix_of_arbitrary_values(
        spec in prop::sample::select(pose_specs()),
        values in prop::collection::vec(arb_cloud_value(), 0..14),
        scale_to_unit in any::<bool>(),
    ) {
        let cols = [spec.as_str()];
        let mut values = values;
        let n = pose_columns(&spec).len();
        if scale_to_unit && values.len() >= n {
            values.truncate(n);
        }
        let v2 = values.clone();
        let s2 = spec.clone();
        let r = guarded("pose_to_matrix", READER_DEADLINE, move || io::pose_to_matrix(&v2, &[s2.as_str()]));
        match r {
            Ok(t) => {
                prop_assert!(finite_iso(&t), "{}: {:?} gave {:?}", spec, values, t);
                let again = io::matrix_to_pose(&t, &cols).unwrap();
                prop_assert!(again.iter().all(|x| x.is_finite()), "{}: {:?}", spec, again);
                let back = io::pose_to_matrix(&again, &cols).unwrap();
                prop_assert!(iso_close(&back, &t, 1e-9));
            }
            Err(e) => prop_assert!(matches!(e, Error::InvalidInput(_)), "{}", e),
        }
    }

    #[test]
    fn views_and_scan_csv_round_trip_every_convention(
        poses in prop::collection::vec(arb_pose(), 1..6),
        spec in prop::sample::select(pose_specs()),
    ) {
        let cols = pose_columns(&spec);
        let views: Vec<View> = poses.iter().enumerate().map(|(i, t)| View {
            line: i + 2,
            board_image: format!("images/b{i}.png").into(),
            laser_image: (i % 2 == 0).then(|| format!("images/l{i}.png").into()),
            reading: RobotReading::FlangePose(*t),
        }).collect();
        let frames: Vec<ScanFrame> = poses.iter().enumerate().map(|(i, t)| ScanFrame {
            line: i + 2,
            image: format!("f{i}.tif").into(),
            reading: RobotReading::FlangePose(*t),
        }).collect();
        let dir = tempfile::tempdir().unwrap();
        let vp = dir.path().join("views.csv");
        let sp = dir.path().join("scan.csv");
        io::write_views_csv_with(&vp, &views, &cols).unwrap();
        io::write_scan_csv_with(&sp, &frames, &cols).unwrap();
        let vb = io::read_views_csv(&vp, None).unwrap();
        let sb = io::read_scan_csv(&sp, None).unwrap();
        for (a, b) in vb.iter().zip(&views) {
            prop_assert_eq!(&a.board_image, &b.board_image);
            prop_assert_eq!(&a.laser_image, &b.laser_image);
            prop_assert!(readings_close(&a.reading, &b.reading, 1e-9), "{}: {:?} vs {:?}", spec, a.reading, b.reading);
        }
        for (a, b) in sb.iter().zip(&frames) {
            prop_assert_eq!(&a.image, &b.image);
            prop_assert!(readings_close(&a.reading, &b.reading, 1e-9));
        }
    }

    #[test]
    fn joint_csv_round_trips_exactly(
        q in prop::collection::vec(prop::collection::vec(prop_oneof![any::<f64>().prop_filter("finite", |x| x.is_finite()), -360.0..360.0f64], 6), 1..5),
    ) {
        let views: Vec<View> = q.iter().enumerate().map(|(i, q)| View {
            line: i + 2,
            board_image: format!("b{i}.png").into(),
            laser_image: None,
            reading: RobotReading::Joints(q.clone()),
        }).collect();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("views.csv");
        io::write_views_csv(&p, &views).unwrap();
        let back = io::read_views_csv(&p, Some(&Robot::hp3())).unwrap();
        prop_assert_eq!(back, views);
    }

    #[test]
    fn png_round_trips_8_and_16_bit(
        w in 1usize..40, h in 1usize..40, deep in any::<bool>(), salt in any::<u64>(),
    ) {
        let mut r = stripecal::numerics::rng::SplitMix64(salt);
        let img = if deep {
            AnyGray::U16(GrayImage { width: w, height: h, data: (0..w * h).map(|_| r.next_u64() as u16).collect() })
        } else {
            AnyGray::U8(GrayImage { width: w, height: h, data: (0..w * h).map(|_| r.next_u64() as u8).collect() })
        };
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("img.png");
        io::save_gray_png(&p, &img).unwrap();
        prop_assert_eq!(io::load_gray(&p).unwrap(), img);
    }
}

#[test]
fn every_seed_image_decodes() {
    // the seeds the mutation fuzz starts from are valid
    for (name, bytes) in image_seeds() {
        let s = Scratch::new(&name);
        let g = read_file(&name, &s, &bytes, |p| io::load_gray(p))
            .unwrap_or_else(|| panic!("seed {name} does not decode"));
        assert!(image_is_valid(&g), "{name}");
        assert_eq!(g.size(), (13, 9), "{name}");
    }
}

// ---------------------------------------------------------------- found by the campaign

/// Inputs the campaign found accepted as NaN / infinite poses (now typed errors).
#[test]
fn huge_pose_values_are_errors_not_nan_poses() {
    let bad: [(&str, Vec<f64>); 4] = [
        // a rotation vector whose norm overflows: the axis came out NaN
        (
            "rotvec",
            vec![0.0, 0.0, 0.0, 0.0, 7.237313330141215e166, 0.0],
        ),
        ("rotvec_deg", vec![0.0, 0.0, 0.0, 1e300, 1e300, 0.0]),
        // metres to millimetres overflows
        ("ur", vec![1e306, 0.0, 0.0, 0.0, 0.0, 0.0]),
        // huge entries: R^T R overflows (refused before and after: a control case)
        (
            "matrix",
            vec![
                0.0, 0.0, 0.0, 1e200, 1e200, 0.0, 1e200, -1e200, 0.0, 0.0, 0.0, 1.0,
            ],
        ),
    ];
    for (spec, values) in bad {
        let v = values.clone();
        let r = guarded(spec, READER_DEADLINE, move || {
            io::pose_to_matrix(&v, &[spec])
        });
        match r {
            Err(Error::InvalidInput(m)) => assert!(!m.is_empty()),
            other => panic!("{spec} {values:?}: expected an InvalidInput error, got {other:?}"),
        }
    }
    // the same through views.csv: an error naming the line
    let s = Scratch::new("views.csv");
    let p = s.write(
        b"board_image,laser_image,x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad\nb.png,,0,0,0,0,7.2e166,0\n",
    );
    let e = io::read_views_csv(&p, None).unwrap_err();
    assert!(
        matches!(&e, Error::Format { location, .. } if location.starts_with("line 2")),
        "{e}"
    );
    // and a NaN transform is not converted to NaN values
    let nan = Iso3::from_parts(
        nalgebra::Translation3::new(f64::NAN, 0.0, 0.0),
        nalgebra::UnitQuaternion::identity(),
    );
    assert!(matches!(
        io::matrix_to_pose(&nan, &["kuka"]),
        Err(Error::InvalidInput(_))
    ));
}

/// calibration.json whose pose has a huge rotation vector: was read as a NaN pose
/// (which the writer then refused).
#[test]
fn calibration_json_with_a_huge_rotation_vector_is_a_format_error() {
    let mut doc: Value = serde_json::from_str(&calibration_text()).unwrap();
    doc["hand_cam"]["rotation_vector"] = serde_json::json!([8.17136035848121e223, 0.2, 3.0]);
    let text = serde_json::to_string(&doc).unwrap();
    let e = io::calibration_from_json(Path::new("calibration.json"), &text).unwrap_err();
    assert!(
        matches!(&e, Error::Format { location, .. } if location == "hand_cam.rotation_vector"),
        "{e}"
    );
}

/// Numbers written to calibration.json read back bit for bit (serde_json's default
/// float parser was off by one unit in the last place for some values).
#[test]
fn json_numbers_read_back_exactly() {
    let mut c = calibration();
    c.camera.fu = 87651.20232759304;
    c.extra
        .insert("x".into(), serde_json::json!(1.885898662386554e-110));
    let text = io::calibration_to_json(&c);
    let back = io::calibration_from_json(Path::new("c.json"), &text).unwrap();
    assert_eq!(back.camera.fu.to_bits(), c.camera.fu.to_bits());
    assert_eq!(back.extra["x"], c.extra["x"]);
}
