//! Round trips and malformed-input errors of every file format of spec/DATASET.md.

use std::fs;
use std::path::{Path, PathBuf};

use nalgebra::{UnitQuaternion, Vector3};
use serde_json::json;
use stripecal::io::*;
use stripecal::model::geometry::iso_from_rotvec;
use stripecal::model::image::{AnyGray, GrayImage};
use stripecal::model::{
    Calibration, Cloud, Dataset, NamedCovariance, Quality, Rig, RobotReading, Scan, ScanFrame,
    Sphere, SphereFit, StripeChannel, StripeDirection, Truth, View,
};
use stripecal::{Board, BoardKind, Camera, DistortionModel, Error, Intrinsics, Iso3, Plane, Robot};

// ---------------------------------------------------------------- helpers

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

/// Asserts `e` is `Error::Format` whose location contains `loc` and whose Display
/// contains the file name, the location and `msg`.
#[track_caller]
fn assert_format(e: Error, file: &str, loc: &str, msg: &str) {
    let text = e.to_string();
    match &e {
        Error::Format {
            path,
            location,
            message,
        } => {
            assert!(
                path.ends_with(file),
                "path {} should end with {file}: {text}",
                path.display()
            );
            assert!(
                location.contains(loc),
                "location {location:?} !~ {loc:?}: {text}"
            );
            assert!(
                message.contains(msg),
                "message {message:?} !~ {msg:?}: {text}"
            );
        }
        other => panic!("expected Error::Format, got {other:?}"),
    }
    assert!(
        text.contains(file) && text.contains(loc) && text.contains(msg),
        "{text}"
    );
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    if let Some(parent) = p.parent() {
        fs::create_dir_all(parent).unwrap();
    }
    fs::write(&p, text).unwrap();
    p
}

fn rig(robot: Option<Robot>) -> Rig {
    Rig {
        width: 768,
        height: 576,
        distortion_model: DistortionModel::Radial2,
        board: Board::hp3_paper(),
        robot,
        stripe_direction: StripeDirection::Cols,
        stripe_channel: StripeChannel::Red,
    }
}

fn pose(r: [f64; 3], t: [f64; 3]) -> Iso3 {
    iso_from_rotvec(&Vector3::from(r), &Vector3::from(t))
}

fn assert_iso_close(a: &Iso3, b: &Iso3, tol: f64) {
    assert!(
        (a.translation.vector - b.translation.vector).norm() < tol,
        "{a:?} vs {b:?}"
    );
    assert!(a.rotation.angle_to(&b.rotation) < tol, "{a:?} vs {b:?}");
}

fn camera() -> Camera {
    Camera::new(
        768,
        576,
        Intrinsics {
            fu: 1271.6543210987,
            fv: 1322.52,
            u0: 346.14,
            v0: 262.6,
        },
        DistortionModel::Radial1,
        [0.00021, 0.0, 0.0, 0.0, 0.0],
    )
    .unwrap()
}

fn plane() -> Plane {
    Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap()
}

const RIG_JSON: &str = r#"{
  "format": "stripecal/rig@1",
  "camera": {"width": 768, "height": 576},
  "board": {"rows": 8, "cols": 11, "pitch_mm": 5.0, "circle_diameter_mm": 2.5,
            "marker_diameter_mm": 3.5},
  "robot": {"name": "R", "joints": [
    {"theta0_deg": 0, "alpha_deg": -90, "a_mm": 100, "d_mm": 0},
    {"theta0_deg": 0, "alpha_deg": 0, "a_mm": 50, "d_mm": 0},
    {"theta0_deg": 0, "alpha_deg": 90, "a_mm": 0, "d_mm": 10}]},
  "unknown": {"ignored": true}
}"#;

// ---------------------------------------------------------------- rig.json

#[test]
fn rig_round_trips_with_and_without_robot() {
    let d = tmp();
    for r in [rig(Some(Robot::hp3())), rig(None)] {
        let p = d.path().join("rig.json");
        write_rig(&p, &r).unwrap();
        assert_eq!(read_rig(&p).unwrap(), r);
        let text = fs::read_to_string(&p).unwrap();
        assert!(
            text.contains("\n  \"format\": \"stripecal/rig@1\""),
            "{text}"
        );
        assert_eq!(text.contains("\"robot\""), r.robot.is_some());
    }
    // the other target kinds (spec/DATASET.md, "Target kinds"), and a circle grid
    // with no markers (marker_diameter_mm is then not written and not needed)
    let mut no_markers = Board::hp3_paper();
    no_markers.markers.clear();
    no_markers.marker_diameter_mm = no_markers.circle_diameter_mm;
    for board in [
        Board::chessboard(6, 9, 7.5).unwrap(),
        Board::asymmetric_circles(4, 11, 20.0, 8.0).unwrap(),
        no_markers,
    ] {
        let mut r = rig(None);
        r.board = board;
        let p = d.path().join("other.json");
        write_rig(&p, &r).unwrap();
        assert_eq!(read_rig(&p).unwrap(), r);
    }
}

#[test]
fn rig_defaults_and_unknown_keys() {
    let r = rig_from_json(Path::new("rig.json"), RIG_JSON).unwrap();
    assert_eq!(r.distortion_model, DistortionModel::Radial1);
    assert_eq!(r.stripe_direction, StripeDirection::Auto);
    assert_eq!(r.board, Board::hp3_paper());
    let robot = r.robot.unwrap();
    assert_eq!(robot.dof(), 3);
    assert_eq!(robot.joints[2].d_mm, 10.0);

    let chess = r#"{"format": "stripecal/rig@1", "camera": {"width": 10, "height": 10},
        "board": {"kind": "chessboard", "rows": 6, "cols": 9, "square_mm": 4}}"#;
    let r = rig_from_json(Path::new("rig.json"), chess).unwrap();
    assert_eq!(r.board.kind, BoardKind::Chessboard);
    assert_eq!(r.board.pitch_mm, 4.0);
    assert!(r.robot.is_none());
    assert_eq!(r.stripe_channel, StripeChannel::Gray);
}

/// `stripe.channel` (spec/DATASET.md): every name read and written back, gray (the
/// default) not written, an unknown colour a format error naming rig.json and the key.
#[test]
fn rig_stripe_channel() {
    let d = tmp();
    let p = d.path().join("rig.json");
    for c in StripeChannel::ALL {
        let mut r = rig(None);
        r.stripe_channel = c;
        write_rig(&p, &r).unwrap();
        assert_eq!(read_rig(&p).unwrap(), r);
        let text = fs::read_to_string(&p).unwrap();
        assert_eq!(
            text.contains("\"channel\""),
            c != StripeChannel::Gray,
            "{text}"
        );
        let given = RIG_JSON.replacen(
            "\"format\"",
            &format!("\"stripe\": {{\"channel\": \"{}\"}}, \"format\"", c.name()),
            1,
        );
        assert_eq!(
            rig_from_json(Path::new("rig.json"), &given)
                .unwrap()
                .stripe_channel,
            c
        );
    }
    for bad in ["\"purple\"", "\"Red\"", "3"] {
        let text = RIG_JSON.replacen(
            "\"format\"",
            &format!("\"stripe\": {{\"direction\": \"rows\", \"channel\": {bad}}}, \"format\""),
            1,
        );
        let e = rig_from_json(Path::new("some/rig.json"), &text).unwrap_err();
        let Error::Format { path, location, .. } = &e else {
            panic!("{e:?}")
        };
        assert_eq!(path, Path::new("some/rig.json"));
        assert_eq!(location, "stripe.channel", "{e}");
        assert!(
            e.to_string().starts_with("some/rig.json: stripe.channel: "),
            "{e}"
        );
    }
}

/// The robot's optional figures (spec, section Robot): read, written back, absent by
/// default, refused when negative; the floors they put on the robot-pose noise.
#[test]
fn rig_robot_figures_round_trip() {
    let r = rig_from_json(Path::new("rig.json"), RIG_JSON).unwrap();
    let robot = r.robot.unwrap();
    assert_eq!(
        (robot.repeatability_mm, robot.encoder_sigma_deg),
        (None, None)
    );
    assert_eq!(robot.pose_noise_floor(), (None, None));
    let with = RIG_JSON.replacen(
        "\"name\": \"R\",",
        "\"name\": \"R\", \"repeatability_mm\": 0.02, \"encoder_sigma_deg\": 0.005,",
        1,
    );
    let r = rig_from_json(Path::new("rig.json"), &with).unwrap();
    let robot = r.robot.clone().unwrap();
    assert_eq!(robot.repeatability_mm, Some(0.02));
    assert_eq!(robot.encoder_sigma_deg, Some(0.005));
    // 3 joints: sigma_q sqrt(3 / 3) per component of the flange rotation.
    assert_eq!(robot.pose_noise_floor(), (Some(0.02), Some(0.005)));
    let six = Robot::hp3().with_figures(None, Some(0.01)).unwrap();
    assert!((six.pose_noise_floor().1.unwrap() - 0.01 * 2f64.sqrt()).abs() < 1e-15);
    let d = tmp();
    let p = d.path().join("rig.json");
    write_rig(&p, &r).unwrap();
    assert_eq!(read_rig(&p).unwrap(), r);
    let bad = with.replacen("0.02", "-0.02", 1);
    assert_format(
        rig_from_json(Path::new("rig.json"), &bad).unwrap_err(),
        "rig.json",
        "robot.repeatability_mm",
        "expected a non-negative number",
    );
    assert!(Robot::hp3().with_figures(Some(f64::NAN), None).is_err());
}

#[test]
fn rig_errors_name_the_key() {
    let p = Path::new("/data/set/rig.json");
    let bad = |from: &str, to: &str| {
        let t = RIG_JSON.replacen(from, to, 1);
        assert_ne!(t, RIG_JSON, "{from}");
        rig_from_json(p, &t).unwrap_err()
    };
    assert_format(
        bad("\"pitch_mm\": 5.0, ", ""),
        "rig.json",
        "board",
        "missing key `board.pitch_mm`",
    );
    assert_format(
        bad("\"rows\": 8", "\"rows\": \"abc\""),
        "rig.json",
        "board.rows",
        "expected a positive integer, got \"abc\"",
    );
    assert_format(
        bad("\"rows\": 8", "\"rows\": 2.5"),
        "rig.json",
        "board.rows",
        "expected a positive integer",
    );
    assert_format(
        bad("\"a_mm\": 0, \"d_mm\": 10", "\"a_mm\": \"x\", \"d_mm\": 10"),
        "rig.json",
        "robot.joints[2].a_mm",
        "expected a number, got \"x\"",
    );
    assert_format(
        bad("stripecal/rig@1", "stripecal/rig@2"),
        "rig.json",
        "format",
        "expected \"stripecal/rig@1\", got \"stripecal/rig@2\"",
    );
    assert_format(
        bad("\"width\": 768", "\"width\": -768"),
        "rig.json",
        "camera.width",
        "positive integer",
    );
    assert_format(
        bad("\"circle_diameter_mm\": 2.5", "\"circle_diameter_mm\": 6"),
        "rig.json",
        "board",
        "smaller than the pitch",
    );
    assert_format(
        bad(
            "\"height\": 576}",
            "\"height\": 576, \"distortion_model\": \"fisheye\"}",
        ),
        "rig.json",
        "camera.distortion_model",
        "\"fisheye\"",
    );
    assert_format(
        bad(
            "\"unknown\"",
            "\"stripe\": {\"direction\": \"diag\"}, \"u\"",
        ),
        "rig.json",
        "stripe.direction",
        "\"diag\"",
    );
    assert_format(
        bad("\"joints\": [", "\"joints\": 3, \"x\": ["),
        "rig.json",
        "robot.joints",
        "expected an array, got 3",
    );
    // JSON syntax errors name the line.
    assert_format(
        rig_from_json(p, "{\n  \"format\": ,\n}").unwrap_err(),
        "rig.json",
        "line 2",
        "invalid JSON",
    );
    assert_format(
        rig_from_json(p, "[1, 2]").unwrap_err(),
        "rig.json",
        "top level",
        "expected an object",
    );
}

#[test]
fn missing_rig_file_is_an_io_error() {
    let d = tmp();
    let e = read_rig(d.path().join("rig.json")).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
    assert!(e.to_string().contains("rig.json"));
}

// ---------------------------------------------------------------- views.csv / scan.csv

fn joint_views() -> Vec<View> {
    vec![
        View {
            line: 2,
            board_image: "images/view_000_board.png".into(),
            laser_image: Some("images/view_000_laser.png".into()),
            reading: RobotReading::Joints(vec![0.0, 1.5, -2.0, 0.1 + 0.2, -88.0, 1e-7]),
        },
        View {
            line: 3,
            board_image: "images/view_001.png".into(),
            laser_image: Some("images/view_001.png".into()),
            reading: RobotReading::Joints(vec![
                std::f64::consts::PI,
                -1.0 / 3.0,
                123456.789,
                0.0,
                -90.0,
                5.0,
            ]),
        },
        View {
            line: 4,
            board_image: "images/view_002.png".into(),
            laser_image: None,
            reading: RobotReading::Joints(vec![1.0; 6]),
        },
    ]
}

#[test]
fn views_csv_round_trips_joints_exactly() {
    let d = tmp();
    let p = d.path().join("views.csv");
    let views = joint_views();
    write_views_csv(&p, &views).unwrap();
    let text = fs::read_to_string(&p).unwrap();
    assert!(
        text.starts_with("board_image,laser_image,q1,q2,q3,q4,q5,q6\n"),
        "{text}"
    );
    assert!(
        text.contains("images/view_002.png,,1,1,1,1,1,1\n"),
        "{text}"
    );
    assert_eq!(read_views_csv(&p, Some(&Robot::hp3())).unwrap(), views);
    assert_eq!(read_views_csv(&p, None).unwrap(), views);
}

#[test]
fn views_csv_round_trips_flange_poses() {
    let d = tmp();
    let p = d.path().join("views.csv");
    let views: Vec<View> = (0..3)
        .map(|i| View {
            line: i + 2,
            board_image: format!("img/{i}.png").into(),
            laser_image: None,
            reading: RobotReading::FlangePose(pose(
                [0.1 * i as f64, -0.2, 2.9],
                [400.0 + i as f64, -12.25, 300.125],
            )),
        })
        .collect();
    write_views_csv(&p, &views).unwrap();
    let text = fs::read_to_string(&p).unwrap();
    assert!(text.starts_with("board_image,laser_image,x_mm,y_mm,z_mm,qw,qx,qy,qz\n"));
    // A robot is not needed (nor checked) for pose columns.
    let back = read_views_csv(&p, Some(&Robot::hp3())).unwrap();
    assert_eq!(back.len(), 3);
    for (a, b) in back.iter().zip(&views) {
        assert_eq!(
            (a.line, &a.board_image, &a.laser_image),
            (b.line, &b.board_image, &b.laser_image)
        );
        let (RobotReading::FlangePose(ta), RobotReading::FlangePose(tb)) = (&a.reading, &b.reading)
        else {
            panic!("not a pose");
        };
        assert_iso_close(ta, tb, 1e-12);
    }
}

#[test]
fn views_csv_tolerates_whitespace_crlf_bom_and_trailing_lines() {
    let d = tmp();
    let p = write(
        d.path(),
        "views.csv",
        "\u{feff} board_image , laser_image ,q1, q2\r\n a.png , ,1.5, -2\r\nb.png,b.png,+3,4e1\r\n\r\n  \n",
    );
    let v = read_views_csv(&p, None).unwrap();
    assert_eq!(v.len(), 2);
    assert_eq!(v[0].board_image, PathBuf::from("a.png"));
    assert_eq!(v[0].laser_image, None);
    assert_eq!(v[0].reading, RobotReading::Joints(vec![1.5, -2.0]));
    assert_eq!(v[1].line, 3);
    assert_eq!(v[1].laser_image, Some(PathBuf::from("b.png")));
    assert_eq!(v[1].reading, RobotReading::Joints(vec![3.0, 40.0]));

    // A pose quaternion slightly off unit norm is normalised.
    let p = write(
        d.path(),
        "pose.csv",
        "board_image,laser_image,x_mm,y_mm,z_mm,qw,qx,qy,qz\na.png,,1,2,3,1.0004,0,0,0\n",
    );
    let v = read_views_csv(&p, None).unwrap();
    let RobotReading::FlangePose(t) = &v[0].reading else {
        panic!()
    };
    assert_eq!(t.rotation, UnitQuaternion::identity());
    assert_eq!(t.translation.vector, Vector3::new(1.0, 2.0, 3.0));
}

#[test]
fn views_csv_errors_name_the_line_and_column() {
    let d = tmp();
    let header = "board_image,laser_image,q1,q2,q3\n";
    let read = |body: &str| {
        let p = write(d.path(), "views.csv", &format!("{header}{body}"));
        read_views_csv(&p, None).unwrap_err()
    };
    assert_format(
        read("a.png,,1,2,3\nb.png,,1,2\n"),
        "views.csv",
        "line 3",
        "expected 5 columns, found 4",
    );
    assert_format(
        read("a.png,,1,abc,3\n"),
        "views.csv",
        "line 2, column q2",
        "q2 = \"abc\" is not a finite number",
    );
    assert_format(
        read("a.png,,1,2,NaN\n"),
        "views.csv",
        "line 2, column q3",
        "q3 = \"NaN\" is not a finite number",
    );
    assert_format(
        read("a.png,,inf,2,3\n"),
        "views.csv",
        "line 2, column q1",
        "not a finite number",
    );
    assert_format(
        read("a.png,,1,,3\n"),
        "views.csv",
        "line 2, column q2",
        "q2 = \"\" is not a finite number",
    );
    assert_format(
        read(" ,b.png,1,2,3\n"),
        "views.csv",
        "line 2, column board_image",
        "board_image is empty",
    );
    assert_format(
        read("\"a,b.png\",,1,2,3\n"),
        "views.csv",
        "line 2",
        "quoted fields are not supported",
    );
    assert_format(
        read("a.png,,1,2,3\n\nb.png,,1,2,3\n"),
        "views.csv",
        "line 3",
        "empty line",
    );

    let with_header = |h: &str, robot: Option<&Robot>| {
        let p = write(d.path(), "views.csv", &format!("{h}\na.png,,1,2,3,4,5\n"));
        read_views_csv(&p, robot).unwrap_err()
    };
    assert_format(
        with_header(
            "board_image,laser_image,q1,q2,q3,q4,q5",
            Some(&Robot::hp3()),
        ),
        "views.csv",
        "line 1",
        "header has 5 joint columns, robot has 6 joints",
    );
    assert_format(
        with_header("image,laser_image,q1,q2,q3,q4,q5", None),
        "views.csv",
        "line 1",
        "header column 1 is `image`, expected `board_image`",
    );
    assert_format(
        with_header("board_image,laser_image,q1,q2,q4,q3,q5", None),
        "views.csv",
        "line 1",
        "header column 5 is `q4`, expected `q3`",
    );
    assert_format(
        with_header("board_image,laser_image,x_mm,y_mm,z_mm,qw,qx", None),
        "views.csv",
        "line 1",
        "header has qw, qx but not qy, qz",
    );
    assert_format(
        with_header("board_image,laser_image,j1,j2,j3,j4,j5", None),
        "views.csv",
        "line 1",
        "unknown column `j1`: expected joint readings `q1,...,qN` or pose columns",
    );
    let p = write(d.path(), "views.csv", "");
    assert_format(
        read_views_csv(&p, None).unwrap_err(),
        "views.csv",
        "line 1",
        "empty header",
    );
    let p = write(
        d.path(),
        "views.csv",
        "board_image,laser_image,x_mm,y_mm,z_mm,qw,qx,qy,qz\na.png,,1,2,3,0.5,0,0,0\n",
    );
    assert_format(
        read_views_csv(&p, None).unwrap_err(),
        "views.csv",
        "line 2",
        "has norm 0.5",
    );
    fs::write(&p, b"board_image,laser_image,q1\na\xff.png,,1\n").unwrap();
    assert_format(
        read_views_csv(&p, None).unwrap_err(),
        "views.csv",
        "line 2",
        "not valid UTF-8",
    );
}

#[test]
fn views_csv_writer_rejects_what_it_cannot_write() {
    let d = tmp();
    let p = d.path().join("views.csv");
    let mut v = joint_views();
    v[1].reading = RobotReading::Joints(vec![0.0; 5]);
    assert!(matches!(
        write_views_csv(&p, &v),
        Err(Error::InvalidInput(_))
    ));
    let mut v = joint_views();
    v[0].board_image = "a,b.png".into();
    assert!(matches!(
        write_views_csv(&p, &v),
        Err(Error::InvalidInput(_))
    ));
    let mut v = joint_views();
    v[2].reading = RobotReading::Joints(vec![f64::NAN; 6]);
    assert!(matches!(
        write_views_csv(&p, &v),
        Err(Error::InvalidInput(_))
    ));
    assert!(matches!(
        write_views_csv(&p, &[]),
        Err(Error::InvalidInput(_))
    ));
    assert!(!p.exists());
}

#[test]
fn scan_csv_round_trips_and_checks() {
    let d = tmp();
    let p = d.path().join("scan.csv");
    let frames: Vec<ScanFrame> = (0..4)
        .map(|i| ScanFrame {
            line: i + 2,
            image: format!("images/scan_{i:03}.png").into(),
            reading: RobotReading::Joints(vec![0.5 * i as f64, 0.1, 0.2, 0.3, -90.0, 0.0]),
        })
        .collect();
    write_scan_csv(&p, &frames).unwrap();
    assert!(fs::read_to_string(&p)
        .unwrap()
        .starts_with("image,q1,q2,q3,q4,q5,q6\n"));
    assert_eq!(read_scan_csv(&p, Some(&Robot::hp3())).unwrap(), frames);

    let posed = vec![ScanFrame {
        line: 2,
        image: "s.png".into(),
        reading: RobotReading::FlangePose(pose([1.0, 2.0, 0.5], [1.0, 2.0, 3.0])),
    }];
    write_scan_csv(&p, &posed).unwrap();
    let back = read_scan_csv(&p, None).unwrap();
    let (RobotReading::FlangePose(a), RobotReading::FlangePose(b)) =
        (&back[0].reading, &posed[0].reading)
    else {
        panic!()
    };
    assert_iso_close(a, b, 1e-12);

    let p = write(d.path(), "scan.csv", "image,q1,q2\ns.png,1,2,3\n");
    assert_format(
        read_scan_csv(&p, None).unwrap_err(),
        "scan.csv",
        "line 2",
        "expected 3 columns, found 4",
    );
}

// ---------------------------------------------------------------- Dataset / Scan

fn make_dataset(dir: &Path, views_csv: &str) {
    write_rig(dir.join("rig.json"), &rig(Some(Robot::hp3()))).unwrap();
    write(dir, "views.csv", views_csv);
    let img = AnyGray::U8(GrayImage::new(4, 3));
    fs::create_dir_all(dir.join("images")).unwrap();
    save_gray_png(dir.join("images/a.png"), &img).unwrap();
    save_gray_png(dir.join("images/b.png"), &img).unwrap();
    save_gray_png(dir.join("images/c.png"), &img).unwrap();
}

#[test]
fn dataset_loads_and_reports_missing_images() {
    let d = tmp();
    let h = "board_image,laser_image,q1,q2,q3,q4,q5,q6\n";
    make_dataset(
        d.path(),
        &format!("{h}images/a.png,images/b.png,0,0,0,0,-90,0\nimages/c.png,,1,0,0,0,-90,0\n"),
    );
    let ds = Dataset::load(d.path()).unwrap();
    assert_eq!(ds.views.len(), 2);
    assert_eq!(ds.rig.robot, Some(Robot::hp3()));
    assert!(ds.image_path(&ds.views[0].board_image).is_file());

    make_dataset(
        d.path(),
        &format!("{h}images/a.png,images/b.png,0,0,0,0,-90,0\nimages/c.png,images/missing.png,1,0,0,0,-90,0\n"),
    );
    let e = Dataset::load(d.path()).unwrap_err();
    assert_format(e, "views.csv", "line 3", "missing.png does not exist");

    // Joint columns that do not match the rig's robot.
    make_dataset(
        d.path(),
        "board_image,laser_image,q1,q2\nimages/a.png,,0,0\n",
    );
    assert_format(
        Dataset::load(d.path()).unwrap_err(),
        "views.csv",
        "line 1",
        "header has 2 joint columns, robot has 6 joints",
    );

    // Joint columns without a robot in rig.json.
    make_dataset(d.path(), &format!("{h}images/a.png,,0,0,0,0,-90,0\n"));
    write_rig(d.path().join("rig.json"), &rig(None)).unwrap();
    assert_format(
        Dataset::load(d.path()).unwrap_err(),
        "views.csv",
        "line 1",
        "need a robot",
    );
}

#[test]
fn scan_loads_with_optional_rig() {
    let d = tmp();
    let img = AnyGray::U16(GrayImage::new(2, 2));
    save_gray_png(d.path().join("s0.png"), &img).unwrap();
    write(
        d.path(),
        "scan.csv",
        "image,q1,q2,q3,q4,q5,q6\ns0.png,0,0,0,0,-90,0\n",
    );
    let s = Scan::load(d.path(), Some(&Robot::hp3())).unwrap();
    assert!(s.rig.is_none());
    assert_eq!(s.frames.len(), 1);
    write(
        d.path(),
        "scan.csv",
        "image,q1,q2,q3,q4,q5,q6\ns1.png,0,0,0,0,-90,0\n",
    );
    assert_format(
        Scan::load(d.path(), None).unwrap_err(),
        "scan.csv",
        "line 2",
        "does not exist",
    );
}

// ---------------------------------------------------------------- calibration / truth

fn calibration() -> Calibration {
    let mut uncertainty = serde_json::Map::new();
    uncertainty.insert("camera".into(), json!({"fu": 0.25, "fv": 0.3}));
    uncertainty.insert(
        "laser_plane".into(),
        json!({"normal": [1e-4, 2e-4, 3e-4], "d_mm": 0.01}),
    );
    let mut extra = serde_json::Map::new();
    extra.insert(
        "software".into(),
        json!({"name": "stripecal", "version": "0.1.0"}),
    );
    extra.insert("per_view_rms_px".into(), json!([0.1, 0.2]));
    Calibration {
        camera: camera(),
        laser_plane: Some(plane()),
        mount: stripecal::model::Mount::Robot,
        hand_cam: pose([-0.3087, 0.2362, 3.0369], [29.19, 5.37, 62.64]),
        base_board: pose([0.01, -0.02, 1.5], [600.0, -20.0, -150.0]),
        robot: Some(Robot::hp3()),
        quality: Quality {
            circle_rms_px: 0.0712345678901,
            stripe_rms_px: 0.1,
            views_used: 12,
            checks: vec![
                stripecal::model::QualityCheck::pass("pairing", "all agree"),
                stripecal::model::QualityCheck::fail("views", "view 3 \"far\" off", vec![3, 7]),
            ],
            accepted_poor: true,
        },
        uncertainty,
        covariance: Some(NamedCovariance {
            parameters: vec!["camera.fu".into(), "laser_plane.d_mm".into()],
            matrix: nalgebra::DMatrix::from_row_slice(2, 2, &[0.0625, -1.5e-3, -1.5e-3, 1e-4]),
        }),
        records: Default::default(),
        extra,
    }
}

fn assert_calibration_close(a: &Calibration, b: &Calibration) {
    assert_eq!(a.camera, b.camera);
    let (pa, pb) = (a.laser_plane.unwrap(), b.laser_plane.unwrap());
    assert!((pa.normal - pb.normal).norm() < 1e-15);
    assert!((pa.d - pb.d).abs() < 1e-12);
    assert_eq!(a.covariance, b.covariance);
    assert_iso_close(&a.hand_cam, &b.hand_cam, 1e-13);
    assert_iso_close(&a.base_board, &b.base_board, 1e-12);
    assert_eq!(a.robot, b.robot);
    assert_eq!(a.quality, b.quality);
    assert_eq!(a.uncertainty, b.uncertainty);
    assert_eq!(a.extra, b.extra);
}

#[test]
fn calibration_round_trips() {
    let d = tmp();
    let p = d.path().join("calibration.json");
    let c = calibration();
    write_calibration(&p, &c).unwrap();
    let back = read_calibration(&p).unwrap();
    assert_calibration_close(&back, &c);
    let text = fs::read_to_string(&p).unwrap();
    assert!(
        text.contains("\n  \"camera\": {\n    \"width\": 768,"),
        "{text}"
    );
    assert!(text.contains("1271.6543210987"), "{text}");

    let mut no_robot = c.clone();
    no_robot.robot = None;
    no_robot.uncertainty.clear();
    no_robot.extra.clear();
    write_calibration(&p, &no_robot).unwrap();
    assert_calibration_close(&read_calibration(&p).unwrap(), &no_robot);
}

/// `robot_pose_noise` (an extra key): written from the record, read back typed (a NaN
/// test as `null`), absent from files without it, and a malformed one is a format
/// error naming the key.
#[test]
fn calibration_robot_pose_noise_round_trips() {
    use stripecal::model::{RobotPoseNoise, RobotPoseView};
    let n = RobotPoseNoise {
        sigma_translation_mm: 0.05,
        sigma_rotation_deg: 0.012,
        translation_at_floor: false,
        rotation_at_floor: true,
        floor_translation_mm: 0.02,
        floor_rotation_deg: 0.012,
        image_factor: Some(12.5),
        image_factor_at_floor: false,
        kinematic_mm: Some(0.3),
        kinematic_deg: Some(0.01),
        views: vec![
            RobotPoseView {
                view: 0,
                translation_mm: 0.07,
                rotation_deg: 0.01,
                test: -0.4,
            },
            RobotPoseView {
                view: 3,
                translation_mm: 0.9,
                rotation_deg: 0.2,
                test: f64::NAN,
            },
        ],
        left_out: vec![RobotPoseView {
            view: 5,
            translation_mm: 4.1,
            rotation_deg: 0.9,
            test: 9.5,
        }],
    };
    let mut c = calibration();
    assert!(calibration_robot_pose_noise(&c).unwrap().is_none());
    c.extra.extend(robot_pose_noise_extra(&n));
    let d = tmp();
    let p = d.path().join("calibration.json");
    write_calibration(&p, &c).unwrap();
    let text = fs::read_to_string(&p).unwrap();
    assert!(
        text.contains("\"robot_pose_noise\": {\n    \"translation_mm\": 0.05,"),
        "{text}"
    );
    let back = calibration_robot_pose_noise(&read_calibration(&p).unwrap())
        .unwrap()
        .unwrap();
    assert!(back.views[1].test.is_nan());
    let mut same = back.clone();
    same.views[1].test = 0.0;
    let mut expect = n.clone();
    expect.views[1].test = 0.0;
    assert_eq!(same, expect);
    let bad = text.replacen("\"rotation\": true", "\"rotation\": 1", 1);
    assert_format(
        calibration_from_json(Path::new("calibration.json"), &bad).unwrap_err(),
        "calibration.json",
        "robot_pose_noise.at_floor.rotation",
        "expected",
    );
}

#[test]
fn calibration_reads_the_spec_example() {
    let text = r#"{
  "format": "stripecal/calibration@1",
  "camera": {"width": 768, "height": 576, "fu": 1271.65, "fv": 1322.52,
             "u0": 346.14, "v0": 262.60, "distortion_model": "radial1",
             "distortion": [0.0002, 0, 0, 0, 0]},
  "laser_plane": {"normal": [0.629, -0.0492, 0.7759], "d_mm": 79.87},
  "hand_cam": {"rotation_vector": [-0.3087, 0.2362, 3.0369],
               "translation_mm": [29.19, 5.37, 62.64]},
  "base_board": {"rotation_vector": [0, 0, 0], "translation_mm": [0, 0, 0]},
  "quality": {"circle_rms_px": 0.0, "stripe_rms_px": 0.0, "views_used": 5},
  "uncertainty": {"camera": {"fu": 0.0}}
}"#;
    let c = calibration_from_json(Path::new("calibration.json"), text).unwrap();
    assert_eq!(c.camera.fu, 1271.65);
    assert!((c.laser_plane.unwrap().normal.norm() - 1.0).abs() < 1e-15);
    assert_eq!(c.quality.views_used, 5);
    assert_eq!(c.base_board, Iso3::identity());
    assert!(c.robot.is_none() && c.extra.is_empty() && c.covariance.is_none());
}

#[test]
fn calibration_without_a_laser_plane_writes_null_and_reads_back() {
    let d = tmp();
    let p = d.path().join("calibration.json");
    let c = Calibration {
        laser_plane: None,
        ..calibration()
    };
    write_calibration(&p, &c).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.contains("\"laser_plane\": null"), "{text}");
    let back = read_calibration(&p).unwrap();
    assert!(back.laser_plane.is_none());
    assert_eq!(back.covariance, c.covariance);
    // The key itself stays required.
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut m = v.as_object().unwrap().clone();
    m.remove("laser_plane");
    let Err(e) = calibration_from_json(
        Path::new("c.json"),
        &serde_json::Value::Object(m).to_string(),
    ) else {
        panic!("expected an error: {}", "laser_plane missing")
    };
    assert!(e.to_string().contains("laser_plane"), "{e}");
}

#[test]
fn a_malformed_covariance_is_a_typed_error_naming_the_key() {
    let base = calibration_to_json(&calibration());
    for (bad, what) in [
        (
            r#"{"parameters": ["camera.fu"], "matrix": [[1.0, 0.0]]}"#,
            "expected 1 values",
        ),
        (
            r#"{"parameters": ["a", "b"], "matrix": [[1.0, 0.5], [0.2, 1.0]]}"#,
            "not symmetric",
        ),
        (r#"{"parameters": ["a"], "matrix": [[-1.0]]}"#, "negative"),
        (
            r#"{"parameters": ["a", "b"], "matrix": [[1.0, 0.0]]}"#,
            "expected 2 rows",
        ),
    ] {
        let mut v: serde_json::Value = serde_json::from_str(&base).unwrap();
        v["covariance"] = serde_json::from_str(bad).unwrap();
        let Err(e) = calibration_from_json(Path::new("c.json"), &v.to_string()) else {
            panic!("expected an error: {}", what)
        };
        let msg = e.to_string();
        assert!(msg.contains("covariance") && msg.contains(what), "{msg}");
    }
}

#[test]
fn calibration_errors_name_the_key() {
    let p = Path::new("out/calibration.json");
    let good = calibration_to_json(&calibration());
    let bad = |from: &str, to: &str| {
        let t = good.replacen(from, to, 1);
        assert_ne!(t, good, "{from}");
        calibration_from_json(p, &t).unwrap_err()
    };
    assert_format(
        bad("stripecal/calibration@1", "stripecal/truth@1"),
        "calibration.json",
        "format",
        "expected \"stripecal/calibration@1\"",
    );
    assert_format(
        bad("\"fu\": ", "\"focal\": "),
        "calibration.json",
        "camera",
        "missing key `camera.fu`",
    );
    assert_format(
        bad("\"fv\": 1322.52", "\"fv\": \"1322.52\""),
        "calibration.json",
        "camera.fv",
        "expected a positive number, got \"1322.52\"",
    );
    assert_format(
        bad("\"views_used\": 12", "\"views_used\": -1"),
        "calibration.json",
        "quality.views_used",
        "non-negative integer",
    );
    assert_format(
        bad("\"d_mm\": 79.", "\"d_mm\": -79."),
        "calibration.json",
        "laser_plane.d_mm",
        "positive distance",
    );
    assert_format(
        bad("\"rotation_vector\": [", "\"rotation_vector\": [1, "),
        "calibration.json",
        "hand_cam.rotation_vector",
        "expected an array of 3 numbers",
    );
    assert_format(
        bad("\"uncertainty\": {", "\"uncertainty\": 3, \"u\": {"),
        "calibration.json",
        "uncertainty",
        "expected an object, got 3",
    );
    assert!(matches!(
        write_calibration(
            Path::new("x.json"),
            &Calibration {
                quality: Quality {
                    circle_rms_px: f64::NAN,
                    ..Quality::default()
                },
                ..calibration()
            }
        ),
        Err(Error::InvalidInput(_))
    ));
}

#[test]
fn truth_round_trips_with_sphere_and_extra_keys() {
    let d = tmp();
    let p = d.path().join("truth.json");
    let mut extra = serde_json::Map::new();
    extra.insert(
        "images".into(),
        json!([{"image": "images/a.png", "T_cam_board": [[1, 0, 0, 0]]}]),
    );
    extra.insert("emitter_mm".into(), json!([1.5, 2.5, 3.5]));
    let t = Truth {
        camera: camera(),
        laser_plane: plane(),
        hand_cam: pose([0.1, 0.2, 3.0], [30.0, 5.0, 60.0]),
        base_board: pose([0.0, 0.0, 0.3], [500.0, 0.0, -100.0]),
        robot: Some(Robot::hp3()),
        sphere: Some(Sphere {
            center_mm: Vector3::new(480.25, -3.5, 12.0),
            diameter_mm: 25.4,
        }),
        working_range_mm: Some([60.0, 110.0]),
        extra,
    };
    write_truth(&p, &t).unwrap();
    let back = read_truth(&p).unwrap();
    assert_eq!(back.camera, t.camera);
    assert!((back.laser_plane.normal - t.laser_plane.normal).norm() < 1e-15);
    assert_iso_close(&back.hand_cam, &t.hand_cam, 1e-13);
    assert_iso_close(&back.base_board, &t.base_board, 1e-12);
    assert_eq!(back.robot, t.robot);
    assert_eq!(back.sphere, t.sphere);
    assert_eq!(back.working_range_mm, t.working_range_mm);
    assert_eq!(back.extra, t.extra);

    let minimal = Truth {
        robot: None,
        sphere: None,
        working_range_mm: None,
        extra: serde_json::Map::new(),
        ..t.clone()
    };
    write_truth(&p, &minimal).unwrap();
    let back = read_truth(&p).unwrap();
    assert!(back.sphere.is_none() && back.robot.is_none() && back.extra.is_empty());

    let text = truth_to_json(&t).replace("\"diameter_mm\": 25.4", "\"diameter_mm\": 0");
    assert_format(
        truth_from_json(Path::new("truth.json"), &text).unwrap_err(),
        "truth.json",
        "sphere.diameter_mm",
        "expected a positive number, got 0",
    );
    let text = truth_to_json(&t).replace("stripecal/truth@1", "stripecal/calibration@1");
    assert_format(
        truth_from_json(Path::new("truth.json"), &text).unwrap_err(),
        "truth.json",
        "format",
        "expected \"stripecal/truth@1\"",
    );
}

#[test]
fn sphere_fit_round_trips() {
    let d = tmp();
    let p = d.path().join("sphere.json");
    let mut extra = serde_json::Map::new();
    extra.insert("diameter_sigma_mm".into(), json!(0.004));
    let s = SphereFit {
        diameter_mm: 25.401234567,
        center_mm: Vector3::new(1.0 / 3.0, -2.0, 1e-9),
        rms_mm: 0.0123,
        points: 12345,
        outliers: 17,
        extra,
    };
    write_sphere_fit(&p, &s).unwrap();
    assert_eq!(read_sphere_fit(&p).unwrap(), s);
    let text = fs::read_to_string(&p).unwrap();
    assert!(
        text.starts_with("{\n  \"diameter_mm\": 25.401234567,"),
        "{text}"
    );

    write(
        d.path(),
        "sphere.json",
        r#"{"diameter_mm": 25, "center_mm": [0, 0, 0], "rms_mm": 0.1, "points": 10}"#,
    );
    assert_format(
        read_sphere_fit(&p).unwrap_err(),
        "sphere.json",
        "top level",
        "missing key `outliers`",
    );
}

// ---------------------------------------------------------------- PLY

fn cloud() -> Cloud {
    let n = 50;
    let points: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let t = i as f64 * 0.1;
            [t.sin() * 100.0 + 1e-9, t.cos() / 3.0, 400.0 - t]
        })
        .collect();
    Cloud {
        points,
        properties: vec![
            ("view".into(), (0..n).map(|i| (i / 10) as f64).collect()),
            (
                "u".into(),
                (0..n).map(|i| 100.25 + i as f64 / 7.0).collect(),
            ),
            ("intensity".into(), (0..n).map(|i| (i * 5) as f64).collect()),
        ],
    }
}

#[test]
fn ply_round_trips_binary_and_ascii() {
    let d = tmp();
    for (f, name) in [
        (PlyFormat::BinaryLittleEndian, "b.ply"),
        (PlyFormat::Ascii, "a.ply"),
    ] {
        let p = d.path().join(name);
        let c = cloud();
        write_ply(&p, &c, f).unwrap();
        assert_eq!(read_ply(&p).unwrap(), c, "{f:?}");
        let empty = Cloud::default();
        write_ply(&p, &empty, f).unwrap();
        assert_eq!(read_ply(&p).unwrap(), empty);
    }
    let text = fs::read(d.path().join("a.ply")).unwrap();
    assert!(text.starts_with(b"ply\nformat ascii 1.0\n"));
}

#[test]
fn ply_reads_other_writers_files() {
    let d = tmp();
    // Big-endian floats, a uchar property, a vertex list and a face element.
    let mut bytes =
        b"ply\r\nformat binary_big_endian 1.0\r\ncomment made elsewhere\r\nobj_info x\r\n\
element vertex 2\r\nproperty float x\r\nproperty float y\r\nproperty float z\r\n\
property uchar red\r\nproperty list uchar int tags\r\nelement face 1\r\n\
property list uchar int vertex_indices\r\nend_header\r\n"
            .to_vec();
    for (xyz, red, tags) in [
        ([1.5f32, -2.0, 3.25], 200u8, vec![7i32]),
        ([0.0, 1.0, 2.0], 3, vec![]),
    ] {
        for v in xyz {
            bytes.extend_from_slice(&v.to_be_bytes());
        }
        bytes.push(red);
        bytes.push(tags.len() as u8);
        for t in tags {
            bytes.extend_from_slice(&t.to_be_bytes());
        }
    }
    bytes.push(3);
    for i in [0i32, 1, 0] {
        bytes.extend_from_slice(&i.to_be_bytes());
    }
    let p = d.path().join("be.ply");
    fs::write(&p, &bytes).unwrap();
    let c = read_ply(&p).unwrap();
    assert_eq!(c.points, vec![[1.5, -2.0, 3.25], [0.0, 1.0, 2.0]]);
    assert_eq!(c.properties, vec![("red".to_string(), vec![200.0, 3.0])]);

    // ASCII with a face element before the vertices and int properties.
    let p = write(
        d.path(),
        "a.ply",
        "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n\
element vertex 3\nproperty int16 i\nproperty double z\nproperty float32 x\nproperty float64 y\nend_header\n\
3 0 1 2\n-1 3 1 2\n2 6 4 5\n7 9 7 8\n",
    );
    let c = read_ply(&p).unwrap();
    assert_eq!(
        c.points,
        vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]
    );
    assert_eq!(c.properties, vec![("i".to_string(), vec![-1.0, 2.0, 7.0])]);
}

#[test]
fn ply_errors_name_the_place() {
    let d = tmp();
    let p = d.path().join("c.ply");
    write_ply(&p, &cloud(), PlyFormat::BinaryLittleEndian).unwrap();
    let bytes = fs::read(&p).unwrap();
    // Cut in the middle of vertex 37 (6 doubles per vertex).
    let header_len = bytes.len() - 50 * 6 * 8;
    fs::write(&p, &bytes[..header_len + 37 * 48 + 20]).unwrap();
    assert_format(
        read_ply(&p).unwrap_err(),
        "c.ply",
        "vertex 37",
        "file ends early",
    );

    write_ply(&p, &cloud(), PlyFormat::Ascii).unwrap();
    let text = fs::read_to_string(&p).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    fs::write(&p, lines[..lines.len() - 3].join("\n")).unwrap();
    assert_format(
        read_ply(&p).unwrap_err(),
        "c.ply",
        "vertex 47",
        "file ends early",
    );

    // Replace the first value (vertex 0's x) on the first data line, line 12.
    let (head, data) = text.split_once("end_header\n").unwrap();
    let (_, rest) = data.split_once(' ').unwrap();
    fs::write(&p, format!("{head}end_header\nabc {rest}")).unwrap();
    assert_format(
        read_ply(&p).unwrap_err(),
        "c.ply",
        "line 12",
        "vertex 0, property x: expected a number, got \"abc\"",
    );

    let p = write(d.path(), "noz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n");
    assert_format(
        read_ply(&p).unwrap_err(),
        "noz.ply",
        "header",
        "no `z` property",
    );
    let p = write(
        d.path(),
        "nohead.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\n",
    );
    assert_format(
        read_ply(&p).unwrap_err(),
        "nohead.ply",
        "line 4",
        "no `end_header`",
    );
    let p = write(d.path(), "notply.ply", "solid cube\nfacet\n");
    assert_format(
        read_ply(&p).unwrap_err(),
        "notply.ply",
        "line 1",
        "not a PLY file",
    );
    let p = write(
        d.path(),
        "type.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty half x\nend_header\n",
    );
    assert_format(
        read_ply(&p).unwrap_err(),
        "type.ply",
        "line 4",
        "unknown property type \"half\"",
    );
    let p = write(d.path(), "extra.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 5 6\n");
    assert_format(
        read_ply(&p).unwrap_err(),
        "extra.ply",
        "line 9",
        "after the last element",
    );

    // Hostile counts do not allocate: a billion vertices declared, none present.
    let p = write(d.path(), "huge.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty double x\nproperty double y\nproperty double z\nend_header\n");
    assert_format(
        read_ply(&p).unwrap_err(),
        "huge.ply",
        "vertex 0",
        "file ends early",
    );

    let bad = Cloud {
        points: vec![[0.0; 3]],
        properties: vec![("u".into(), vec![])],
    };
    assert!(matches!(
        write_ply(d.path().join("x.ply"), &bad, PlyFormat::Ascii),
        Err(Error::InvalidInput(_))
    ));
    let bad = Cloud {
        points: vec![[0.0; 3]],
        properties: vec![("has space".into(), vec![1.0])],
    };
    assert!(matches!(
        write_ply(d.path().join("x.ply"), &bad, PlyFormat::Ascii),
        Err(Error::InvalidInput(_))
    ));
}

// ---------------------------------------------------------------- images

#[test]
fn png_round_trips_8_and_16_bit() {
    let d = tmp();
    let (w, h) = (37usize, 21usize);
    let img8 = AnyGray::U8(GrayImage {
        width: w,
        height: h,
        data: (0..w * h).map(|i| (i * 7 % 256) as u8).collect(),
    });
    let img16 = AnyGray::U16(GrayImage {
        width: w,
        height: h,
        data: (0..w * h).map(|i| (i * 2731 % 65536) as u16).collect(),
    });
    for (img, name) in [(img8, "a8.png"), (img16, "a16.png")] {
        let p = d.path().join(name);
        save_gray_png(&p, &img).unwrap();
        assert_eq!(load_gray(&p).unwrap(), img);
    }
    let bad = AnyGray::U8(GrayImage {
        width: 3,
        height: 3,
        data: vec![0; 8],
    });
    assert!(matches!(
        save_gray_png(d.path().join("bad.png"), &bad),
        Err(Error::InvalidInput(_))
    ));
}

#[test]
fn colour_images_become_gray_and_tiff_is_read() {
    let d = tmp();
    let mut rgb = image::RgbImage::new(3, 2);
    rgb.put_pixel(1, 0, image::Rgb([255, 255, 255]));
    rgb.put_pixel(2, 1, image::Rgb([0, 255, 0]));
    let p = d.path().join("rgb.png");
    rgb.save(&p).unwrap();
    let AnyGray::U8(g) = load_gray(&p).unwrap() else {
        panic!("expected 8-bit")
    };
    assert_eq!((g.width, g.height), (3, 2));
    assert_eq!(g.get(0, 0), 0);
    assert_eq!(g.get(1, 0), 255);
    assert!(g.get(2, 1) > 100 && g.get(2, 1) < 255);

    let rgba16 = image::ImageBuffer::<image::Rgba<u16>, _>::from_pixel(
        2,
        2,
        image::Rgba([65535, 65535, 65535, 0]),
    );
    let p = d.path().join("rgba16.png");
    rgba16.save(&p).unwrap();
    assert_eq!(
        load_gray(&p).unwrap(),
        AnyGray::U16(GrayImage {
            width: 2,
            height: 2,
            data: vec![65535; 4]
        })
    );

    let gray16 = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(4, 3, |x, y| {
        image::Luma([(x * 1000 + y) as u16])
    });
    // The extension does not decide the format: the content does.
    let p = d.path().join("g16.png.tif");
    gray16
        .save_with_format(&p, image::ImageFormat::Tiff)
        .unwrap();
    let AnyGray::U16(g) = load_gray(&p).unwrap() else {
        panic!("expected 16-bit")
    };
    assert_eq!(g.get(3, 2), 3002);

    let f32img = image::Rgb32FImage::from_pixel(2, 2, image::Rgb([0.5, 0.5, 0.5]));
    let p = d.path().join("float.tif");
    f32img
        .save_with_format(&p, image::ImageFormat::Tiff)
        .unwrap();
    let e = load_gray(&p).unwrap_err();
    assert!(matches!(e, Error::Image { .. }), "{e:?}");
    assert!(
        e.to_string().contains("float.tif") && e.to_string().contains("Rgb32F"),
        "{e}"
    );
}

/// BMP and JPEG are read (JPEG flagged lossy), and colour becomes gray by the
/// contract's BT.601 luma `0.299 R + 0.587 G + 0.114 B`, rounded (not the Rec. 709
/// weights of the image crate's own conversion).
#[test]
fn bmp_and_jpeg_and_bt601_luma() {
    let d = tmp();
    let colours: [[u8; 3]; 5] = [
        [255, 0, 0],
        [0, 255, 0],
        [0, 0, 255],
        [200, 100, 50],
        [255, 255, 255],
    ];
    let mut rgb = image::RgbImage::new(5, 1);
    for (x, c) in colours.iter().enumerate() {
        rgb.put_pixel(x as u32, 0, image::Rgb(*c));
    }
    let want: Vec<u8> = colours
        .iter()
        .map(|c| (0.299 * c[0] as f64 + 0.587 * c[1] as f64 + 0.114 * c[2] as f64).round() as u8)
        .collect();
    assert_eq!(want, vec![76, 150, 29, 124, 255]);
    for (name, fmt) in [
        ("c.bmp", image::ImageFormat::Bmp),
        ("c.png", image::ImageFormat::Png),
    ] {
        let p = d.path().join(name);
        rgb.save_with_format(&p, fmt).unwrap();
        let (g, info) = stripecal::io::load_gray_info(&p).unwrap();
        let AnyGray::U8(g) = g else { panic!("8-bit") };
        assert_eq!(g.data, want, "{name}");
        assert!(info.colour && !info.lossy, "{name}: {info:?}");
    }
    // 16-bit colour keeps its depth
    let rgb16 = image::ImageBuffer::<image::Rgb<u16>, _>::from_pixel(
        1,
        1,
        image::Rgb([60000, 1000, 30000]),
    );
    let p = d.path().join("c16.png");
    rgb16.save(&p).unwrap();
    let AnyGray::U16(g) = load_gray(&p).unwrap() else {
        panic!("16-bit")
    };
    assert_eq!(
        g.data[0],
        (0.299f64 * 60000.0 + 0.587 * 1000.0 + 0.114 * 30000.0).round() as u16
    );
    // JPEG: gray and colour, flagged lossy
    let gray = image::GrayImage::from_fn(32, 16, |x, y| image::Luma([(x * 8 + y) as u8]));
    let p = d.path().join("g.jpg");
    gray.save_with_format(&p, image::ImageFormat::Jpeg).unwrap();
    let (g, info) = stripecal::io::load_gray_info(&p).unwrap();
    assert_eq!(g.size(), (32, 16));
    assert_eq!(
        (info.format, info.colour, info.lossy),
        ("jpeg", false, true)
    );
    let p = d.path().join("c.jpeg");
    image::RgbImage::from_pixel(16, 16, image::Rgb([200, 100, 50]))
        .save_with_format(&p, image::ImageFormat::Jpeg)
        .unwrap();
    let (g, info) = stripecal::io::load_gray_info(&p).unwrap();
    let AnyGray::U8(g) = g else { panic!("8-bit") };
    assert!(info.colour && info.lossy);
    assert!(
        (g.data[8 * 16 + 8] as i32 - 124).abs() <= 3,
        "{}",
        g.data[8 * 16 + 8]
    );
}

#[test]
fn corrupt_and_missing_images_are_errors() {
    let d = tmp();
    let p = d.path().join("good.png");
    save_gray_png(&p, &AnyGray::U8(GrayImage::new(64, 64))).unwrap();
    let bytes = fs::read(&p).unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("trunc.png", bytes[..bytes.len() / 2].to_vec()),
        ("garbage.png", b"this is not an image at all".to_vec()),
        ("empty.png", vec![]),
        ("flipped.png", {
            let mut b = bytes.clone();
            let n = b.len();
            b[n - 20] ^= 0xff;
            b[40] ^= 0xff;
            b
        }),
    ];
    for (name, data) in cases {
        let p = d.path().join(name);
        fs::write(&p, data).unwrap();
        let e = load_gray(&p).unwrap_err();
        assert!(matches!(e, Error::Image { .. }), "{name}: {e:?}");
        assert!(e.to_string().contains(name), "{e}");
    }
    // A header claiming a huge image is refused by the limits, not allocated.
    let mut huge = bytes.clone();
    huge[16..20].copy_from_slice(&100_000u32.to_be_bytes());
    huge[20..24].copy_from_slice(&100_000u32.to_be_bytes());
    let crc = crc32(&huge[12..29]);
    huge[29..33].copy_from_slice(&crc.to_be_bytes());
    let p = d.path().join("huge.png");
    fs::write(&p, &huge).unwrap();
    let e = load_gray(&p).unwrap_err();
    assert!(matches!(e, Error::Image { .. }), "{e:?}");
    assert!(e.to_string().contains("limit"), "{e}");
    // Within the side limit but over the memory limit (32000^2 16-bit = 2 GB).
    huge[16..20].copy_from_slice(&32_000u32.to_be_bytes());
    huge[20..24].copy_from_slice(&32_000u32.to_be_bytes());
    huge[24] = 16;
    let crc = crc32(&huge[12..29]);
    huge[29..33].copy_from_slice(&crc.to_be_bytes());
    fs::write(&p, &huge).unwrap();
    let e = load_gray(&p).unwrap_err();
    assert!(matches!(e, Error::Image { .. }), "{e:?}");
    assert!(e.to_string().contains("limit"), "{e}");

    let e = load_gray(d.path().join("missing.png")).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
    assert!(e.to_string().contains("missing.png"));
}

/// CRC-32 (IEEE) as PNG chunks use it.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

// ---------------------------------------------------------------- atomic writes

#[test]
fn write_atomic_replaces_and_leaves_no_temporaries() {
    let d = tmp();
    let p = d.path().join("f.txt");
    write_atomic(&p, b"one").unwrap();
    write_atomic(&p, b"two").unwrap();
    assert_eq!(fs::read(&p).unwrap(), b"two");
    let names: Vec<_> = fs::read_dir(d.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("f.txt")]);

    let e = write_atomic(d.path().join("no/such/dir/f.txt"), b"x").unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
    let text = e.to_string();
    assert!(
        text.contains("f.txt") && text.contains("no/such/dir"),
        "{text}"
    );

    // Renaming over a directory fails; the temporary file is removed.
    fs::create_dir(d.path().join("sub")).unwrap();
    fs::write(d.path().join("sub/inner"), b"").unwrap();
    let e = write_atomic(d.path().join("sub"), b"x").unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
    let count = fs::read_dir(d.path()).unwrap().count();
    assert_eq!(count, 2, "a temporary file was left behind");
}
