//! No panic reachable from user input in the core crate's public API (issue 13,
//! acceptance 5; docs/robustness.md).
//!
//! Every public function and method the core crate exports (walked from `src/lib.rs`
//! and the modules' re-exports; the list is below, one section per module) is driven
//! with hostile inputs: empty slices, NaN and infinities, zero, negative and huge sizes,
//! mismatched lengths, out-of-range indices, zero-size and 1 x 1 images, degenerate
//! geometry (every pose the same, collinear points, points at the camera centre). Each
//! call runs under `catch_unwind` and a deadline ([`probe`]) and must give a typed
//! error or a valid result: a fallible function's `Ok` value must be finite where the
//! function promises numbers, and a total function must return without panicking
//! (garbage in, garbage out is allowed only for the plain arithmetic helpers that
//! return numbers, listed as such).
//!
//! Not driven with out-of-range arguments, by design (documented preconditions, like
//! slice indexing; the crate never passes them user-chosen indices and the readers
//! check sizes before building images): `GrayImage::get`, `ImageView::get`,
//! `ImageView::row` (pixel and row indices), `JacobianRows::row` (row index) and the
//! allocation sizes of `GrayImage::new` / `JacobianRows::new` (whose products must fit
//! a `usize`, checked with a clear panic). They are driven in range.
//!
//! Coverage (each name is called below):
//!
//! - `Error`: `format`, `io`.
//! - `model::board` (`Board`, `BoardKind`, `Symmetry`): `circles`, `asymmetric_circles`,
//!   `chessboard`, `hp3_paper`, `default_markers`, `validate`, `neighbour_distance_mm`,
//!   `len`, `is_empty`, `is_marker`, `diameter`, `lattice_unit_mm`, `lattice`,
//!   `from_lattice`, `center`, `indices`, `circle_at`, `square_is_dark`, `ink_at`,
//!   `ink_edge_distance`, `pattern_extent`, `symmetries`; `BoardKind::{name, from_name,
//!   is_circles}`; `Symmetry::{apply_lattice, apply, angle_deg}`.
//! - `model::camera` (`Camera`, `DistortionModel`, `UndistortTrack`): `new`, `validate`,
//!   `params`, `with_params`, `distort`, `distort_with_jacobian`, `normalize`,
//!   `to_pixel`, `from_pixel`, `project`, `undistort`, `undistort_from`, `unproject`,
//!   `project_with_jacobians`, `contains`, `undistort_tracked`,
//!   `undistort_radial_scale`; `UndistortTrack::{new, is_radial_only}`;
//!   `DistortionModel::{name, from_name, free_coefficients}`; `distort_generic`,
//!   `distortion_of`, `project_generic`, `to_pixel_generic`.
//! - `model::geometry` (`Plane`): `rotvec_to_matrix`, `matrix_to_rotvec`,
//!   `quaternion_to_rotvec`, `quaternion_from_matrix`, `nearest_rotation`,
//!   `iso_from_rotvec`, `iso_to_rotvec`, `iso_from_parts`, `iso_to_matrix`,
//!   `iso_from_matrix`; `Plane::{new, signed_distance, intersect_ray, transformed}`.
//! - `model::image`: `GrayImage::{new, get}`, `AnyGray::{size, view}`,
//!   `ImageView::{new, from_slice, width, height, row, get}`, `AnyView::size`,
//!   `luma_bt601`, `gray_from_interleaved`, `Pixel::{to_f32, to_u32}`.
//! - `model::kinematics` (`Robot`, `DhJoint`): `new`, `validate`, `hp3`, `dof`,
//!   `forward`, `forward_unchecked`, `jacobian`, `inverse`;
//!   `DhJoint::{rotation_translation, transform}`.
//! - `model` (dataset, results): `Dataset::{load, image_path}`, `Scan::{load,
//!   image_path}`, `RobotReading::base_hand`, `StripeDirection::{name, from_name}`,
//!   `NamedCovariance::{index, sigma, block}`, `CameraSigma::from_params`.
//! - `numerics`: `dual::Dual::{cst, var}`, `dual::Scalar::{from_f64, is_zero, scale,
//!   sqrt, value}`, `homography::{apply, dlt, dlt_residuals}`, `lm::{covariance,
//!   dense_jacobian_from_rows, levenberg_marquardt}`, `lm::JacobianRows::{new, width,
//!   is_dense, len, is_empty, clear, parts_mut, row}`, `lm::LeastSquares` (a test
//!   problem), `mat3::{m3, matmul, transpose, matvec, cross, dot,
//!   rot_times_exp_first_order, rows_f64}`, `rng::SplitMix64::{next_u64, below,
//!   uniform, normal}`, `robust::{median, median_mean, robust_sigma}`,
//!   `robust::TotalOrd::total_order`, `tls::principal_axes`.
//! - `calib`: `axzb::{solve_axzb, solve_axzb_with}`, `camera::calibrate_camera`,
//!   `conic::{centre_generic, centre_generic_n, centroid_offset, predict_centre,
//!   predict_centre_with_jacobians, quadrature_nodes}`, `conic::CentreModel::name`,
//!   `conic::CentreScalar::centroid_offset`, `consensus::{choose, symmetry_motion}`,
//!   `homography::{apply, dlt, fit_homography}`, `joint::{joint_adjustment}`,
//!   `joint::FreeBlocks::{hold, laser_only}`, `laser_plane::{fit_laser_plane,
//!   board_plane_in_cam, backproject_to_board, stripe_line_in_view}`,
//!   `laser_plane::StripeLine::signed_distance_px`, `zhang::{zhang_intrinsics,
//!   pose_from_homography}`, `zhang::Intrinsics::k`.
//! - `io`: every reader and writer (driven by `fuzz_readers.rs` and `fuzz_mutation.rs`;
//!   here with impossible paths: a folder, a missing file, an empty path) and
//!   `PoseColumns::{parse, from_spec, names, len, is_empty, rotation_columns, to_iso,
//!   to_values, describe}`, `convention_columns`, `convention_names`, `pose_to_matrix`,
//!   `matrix_to_pose`, `calibration_extra`, `self_checks_extra`, `uncertainty_to_json`,
//!   `view_record_to_json`, `warnings_to_json`, `write_atomic`.
//! - `pipeline`: `calibrate_dataset`, `calibrate_dataset_loaded`,
//!   `calibrate_observations`, `observe_dataset`, `select_on_board_plane`,
//!   `Method::{name, from_name}`.
//! - `reconstruct`: `Triangulator::{new, from_calibration, camera, point_cam_mm,
//!   triangulate_into}`, `triangulate`, `Reconstructor::{new, direction, triangulator,
//!   base_hand, frame_joints, frame_pose, frame_reading}`, `reconstruct_frames`,
//!   `reconstruct_scan`, `load_scan`, `fit_sphere`, `fit_plane`,
//!   `SphereFitResult::to_sphere_fit`, `ScanPoints::{len, is_empty, clear, append,
//!   to_cloud}`, `DropCounts::{add, total}`, `at_frame`,
//!   `ReconstructOptions::validate`, `stripe_direction_from_plane`.
//! - `vision`: `stripe::{extract_stripe, fit_line, fit_line_with, flag_reflectance_edges,
//!   resolve_direction}`, `stripe::StripeExtractor::{new, options, rejected,
//!   extract_into}`, `stripe::StripeOptions::validate`, `stripe::StripePoint::{near_edge,
//!   trusted}`, `stripe::LineFit::distance`, `stripe::{StripeMethod,
//!   StripeDirection}::{name, from_name}`, `circles::detect_circles`,
//!   `circles::CentreMethod::{name, from_name}`, `chessboard::detect_chessboard`,
//!   `target::{detect_target, homography_residuals}`,
//!   `target::TargetDetection::from_circles`, `target::PointFlags::has`.

use crate::fuzz_support;

use std::fmt::Debug;
use std::path::Path;
use std::sync::OnceLock;
use std::time::Duration;

use fuzz_support::{calibration, guarded, pose};
use nalgebra::{DMatrix, Matrix3, Matrix4, Quaternion, UnitQuaternion, Vector2, Vector3};
use stripecal::calib::{self, CircleObs, ViewObs};
use stripecal::io;
use stripecal::model::board::Symmetry;
use stripecal::model::image::{AnyGray, AnyView, GrayImage, ImageView};
use stripecal::model::{self, RobotReading};
use stripecal::numerics;
use stripecal::pipeline;
use stripecal::reconstruct::{self, FitOptions, ReconstructOptions, ScanPoints, Triangulator};
use stripecal::vision;
use stripecal::{
    Board, BoardKind, Camera, DhJoint, DistortionModel, Error, Intrinsics, Iso3, Plane, Robot,
};

// ---------------------------------------------------------------- harness

const DEADLINE: Duration = Duration::from_secs(120);

/// Floats that break arithmetic.
const BAD: [f64; 9] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    0.0,
    -0.0,
    -1.0,
    1e308,
    -1e308,
    5e-324,
];

/// Runs `f` with panics caught and a deadline; returns its value.
fn probe<T: Send + 'static>(name: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    guarded(name, DEADLINE, f)
}

/// Whether the debug text of a value holds a NaN or an infinity.
fn has_non_finite<T: Debug>(v: &T) -> bool {
    let s = format!("{v:?}");
    s.split(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
        .any(|t| matches!(t, "NaN" | "inf" | "-inf"))
}

/// A fallible call: an error (typed by construction, with a message), or an `Ok` value
/// whose numbers are all finite.
fn finite_or_err<T: Debug, E: std::fmt::Display>(name: &str, r: &Result<T, E>) {
    match r {
        Ok(v) => assert!(
            !has_non_finite(v),
            "{name}: Ok with a non-finite value: {v:?}"
        ),
        Err(e) => assert!(
            !e.to_string().trim().is_empty(),
            "{name}: empty error message"
        ),
    }
}

/// A fallible call on hostile input that must be refused.
fn must_err<T: Debug>(name: &str, r: &stripecal::Result<T>) {
    assert!(r.is_err(), "{name}: accepted hostile input: {r:?}");
}

/// Calls a fallible function under [`probe`] and checks [`finite_or_err`].
fn check<T: Debug + Send + 'static>(
    name: &str,
    f: impl FnOnce() -> stripecal::Result<T> + Send + 'static,
) {
    let _ = check_value(name, f);
}

/// [`check`], returning the result.
fn check_value<T: Debug + Send + 'static>(
    name: &str,
    f: impl FnOnce() -> stripecal::Result<T> + Send + 'static,
) -> stripecal::Result<T> {
    let r = probe(name, f);
    finite_or_err(name, &r);
    r
}

fn camera() -> Camera {
    fuzz_support::camera()
}

fn iso_bad(x: f64) -> Iso3 {
    Iso3::from_parts(
        nalgebra::Translation3::new(x, 0.0, 0.0),
        UnitQuaternion::new_unchecked(Quaternion::new(x, 0.0, 0.0, 0.0)),
    )
}

/// A small twin (half-size camera, 5 poses) and its rendered board and laser images
/// and exact observations, shared by the tests of this binary.
struct Fixture {
    twin: stripecal_sim::Twin,
    board_img: AnyGray,
    laser_img: AnyGray,
    obs: Vec<ViewObs>,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let cfg = stripecal_sim::SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({
                "camera": {"width": 384, "height": 288, "fu": 635.825, "fv": 661.26,
                           "u0": 172.82, "v0": 131.05},
                "poses": {"count": 5}, "seed": 3, "scan": {"enabled": false}
            }))
            .unwrap();
        let twin = stripecal_sim::Twin::new(cfg).unwrap();
        let poses = twin.calibration_poses().unwrap();
        let r = twin.render_view(&poses[0].q_deg, 0).unwrap();
        let obs = twin.exact_observations().unwrap();
        Fixture {
            board_img: r.board_image.unwrap(),
            laser_img: r.laser_image.unwrap(),
            obs,
            twin,
        }
    })
}

/// Hostile images: 1 x 1, one row, one column, constant black and white, noise,
/// 16-bit full range, and the twin's real ones.
fn hostile_images() -> Vec<(String, AnyGray)> {
    let mut r = numerics::rng::SplitMix64(9);
    let g8 = |w: usize, h: usize, f: &mut dyn FnMut() -> u8| {
        AnyGray::U8(GrayImage {
            width: w,
            height: h,
            data: (0..w * h).map(|_| f()).collect(),
        })
    };
    let f = fixture();
    vec![
        ("1x1".into(), g8(1, 1, &mut || 0)),
        ("1x1 white".into(), g8(1, 1, &mut || 255)),
        ("row".into(), g8(384, 1, &mut || 200)),
        ("column".into(), g8(1, 288, &mut || 200)),
        ("3x2".into(), g8(3, 2, &mut || 7)),
        ("black".into(), g8(64, 48, &mut || 0)),
        ("white".into(), g8(64, 48, &mut || 255)),
        (
            "noise".into(),
            g8(96, 72, &mut || (r.next_u64() & 0xff) as u8),
        ),
        (
            "16-bit ramp".into(),
            AnyGray::U16(GrayImage {
                width: 70,
                height: 50,
                data: (0..3500).map(|i| (i * 37 % 65536) as u16).collect(),
            }),
        ),
        ("twin board".into(), f.board_img.clone()),
        ("twin laser".into(), f.laser_img.clone()),
    ]
}

// ---------------------------------------------------------------- Error, board

#[test]
fn error_constructors() {
    let e = Error::format("", "", "");
    assert!(!e.to_string().is_empty());
    let e = Error::io("/nonexistent", std::io::Error::other("x"));
    assert!(e.to_string().contains("nonexistent"));
}

#[test]
fn board_constructors_and_methods_take_hostile_values() {
    for &x in &BAD {
        for (rows, cols) in [(0, 0), (1, 5), (2, 2), (usize::MAX, 3), (1001, 2), (8, 11)] {
            must_err_or_finite(
                "Board::circles",
                probe("Board::circles", move || {
                    Board::circles(rows, cols, x, x, x)
                }),
            );
            probe("Board::asymmetric_circles", move || {
                let r = Board::asymmetric_circles(rows, cols, x, 1.0);
                finite_or_err("Board::asymmetric_circles", &r);
            });
            probe("Board::chessboard", move || {
                let r = Board::chessboard(rows, cols, x);
                finite_or_err("Board::chessboard", &r);
            });
        }
    }
    let mut boards = vec![
        Board::hp3_paper(),
        Board::chessboard(6, 9, 4.0).unwrap(),
        Board::asymmetric_circles(11, 4, 6.0, 2.0).unwrap(),
        Board::circles(7, 7, 5.0, 2.0, 3.0).unwrap(),
    ];
    let mut no_markers = Board::circles(4, 4, 5.0, 2.0, 2.0).unwrap();
    no_markers.markers.clear();
    boards.push(no_markers);
    assert_eq!(Board::default_markers().len(), 3);
    // a board whose public fields were set by hand to hostile values
    let mut broken = Board::hp3_paper();
    broken.markers.push([500, 500]);
    broken.pitch_mm = f64::NAN;
    must_err("Board::validate (hand-made)", &broken.validate());
    for b in boards {
        let b2 = b.clone();
        probe("Board methods", move || {
            let b = b2;
            b.validate().unwrap();
            assert!(b.neighbour_distance_mm() > 0.0 && b.lattice_unit_mm() > 0.0);
            assert_eq!(b.len(), b.rows * b.cols);
            assert!(!b.is_empty());
            assert_eq!(b.indices().count(), b.len());
            for (r, c) in [
                (0, 0),
                (b.rows, b.cols),
                (usize::MAX, usize::MAX),
                (1, usize::MAX),
            ] {
                let _ = b.is_marker(r, c);
                let _ = b.diameter(r, c);
                let _ = b.lattice(r, c);
                let _ = b.center(r, c);
            }
            for (i, j) in [
                (0, 0),
                (-1, -1),
                (i64::MAX, i64::MIN),
                (i64::MIN, 0),
                (1 << 40, 3),
            ] {
                let _ = b.from_lattice(i, j);
                let _ = b.square_is_dark(i, j);
            }
            for &x in &BAD {
                for y in [x, 0.0, 2.5] {
                    let _ = b.circle_at(x, y);
                    let _ = b.ink_at(x, y);
                    let _ = b.ink_edge_distance(x, y);
                }
            }
            assert!(!has_non_finite(&b.pattern_extent()));
            for s in b.symmetries() {
                let _ = s.angle_deg();
                for p in [(0, 0), (i64::MAX, i64::MAX), (i64::MIN, i64::MIN)] {
                    let _ = s.apply_lattice(p);
                }
                for (r, c) in [(0, 0), (usize::MAX, 0), (b.rows, b.cols)] {
                    let _ = s.apply(&b, r, c);
                }
            }
            let hostile = Symmetry {
                quarter_turns: 255,
                shift: (i64::MAX, i64::MIN),
            };
            let _ = hostile.apply_lattice((i64::MAX, 1));
            let _ = hostile.apply(&b, usize::MAX, usize::MAX);
            let _ = hostile.angle_deg();
        });
    }
    for s in [
        "circles",
        "chessboard",
        "asymmetric_circles",
        "",
        "x\0",
        "CIRCLES",
    ] {
        if let Ok(k) = BoardKind::from_name(s) {
            assert_eq!(k.name(), s);
            let _ = k.is_circles();
        }
    }
}

fn must_err_or_finite<T: Debug>(name: &str, r: stripecal::Result<T>) {
    finite_or_err(name, &r);
}

// ---------------------------------------------------------------- camera

#[test]
fn camera_methods_take_hostile_values() {
    for &x in &BAD {
        let r = probe("Camera::new", move || {
            Camera::new(
                768,
                576,
                Intrinsics {
                    fu: x,
                    fv: 1.0,
                    u0: x,
                    v0: 0.0,
                },
                DistortionModel::Radial1,
                [x; 5],
            )
        });
        finite_or_err("Camera::new", &r);
        if !x.is_finite() || x <= 0.0 {
            must_err("Camera::new", &r);
        }
    }
    must_err(
        "Camera::new 0x0",
        &Camera::new(
            0,
            0,
            Intrinsics {
                fu: 1.0,
                fv: 1.0,
                u0: 0.0,
                v0: 0.0,
            },
            DistortionModel::Radial1,
            [0.0; 5],
        ),
    );
    let mut cams = vec![camera()];
    for k in [
        [-0.9, 0.5, 0.1, -0.1, 0.3],
        [5.0, -20.0, 0.0, 0.0, 100.0],
        [0.0, 0.0, 1.0, 1.0, 0.0],
        [1e6; 5],
    ] {
        let mut c = camera();
        c.model = DistortionModel::OpenCv5;
        c.distortion = k;
        cams.push(c);
    }
    let tiny = Camera::new(
        1,
        1,
        Intrinsics {
            fu: 1e-3,
            fv: 1e-3,
            u0: 0.0,
            v0: 0.0,
        },
        DistortionModel::Radial2,
        [0.0; 5],
    )
    .unwrap();
    cams.push(tiny);
    for cam in cams {
        probe("Camera methods", move || {
            let c = &cam;
            let _ = c.validate();
            let p = c.params();
            let _ = c.with_params(&p);
            let _ = c.with_params(&[f64::NAN; 9]).validate().unwrap_err();
            let mut track = model::camera::UndistortTrack::new(c);
            let _ = track.is_radial_only();
            let pts = [0.0, 1.0, -1.0, 1e3, 1e154, 1e308, f64::NAN, f64::INFINITY];
            for &a in &pts {
                for &b in &[0.0, a, -a] {
                    let _ = c.distort(a, b);
                    let _ = c.distort_with_jacobian(a, b);
                    let _ = c.to_pixel(a, b);
                    let _ = c.from_pixel(&Vector2::new(a, b));
                    let _ = c.contains(&Vector2::new(a, b), a);
                    finite_or_err("undistort", &c.undistort(a, b));
                    finite_or_err("undistort_from", &c.undistort_from(a, b, b, a));
                    finite_or_err("unproject", &c.unproject(&Vector2::new(a, b)));
                    if let Some((x, y)) = c.undistort_tracked(a, b, &mut track) {
                        assert!(
                            x.is_finite() && y.is_finite(),
                            "undistort_tracked({a}, {b})"
                        );
                    }
                    if let Some(s) = c.undistort_radial_scale(a, b, a) {
                        assert!(s.is_finite(), "undistort_radial_scale({a}, {b})");
                    }
                    for z in [0.0, -1.0, 1.0, a, 1e-300] {
                        let p3 = Vector3::new(a, b, z);
                        finite_or_err("normalize", &Camera::normalize(&p3));
                        finite_or_err("project", &c.project(&p3));
                        finite_or_err("project_with_jacobians", &c.project_with_jacobians(&p3));
                    }
                }
            }
            // the generic forms
            let p = c.params();
            let _ = model::camera::distortion_of(&p);
            let _ = model::camera::to_pixel_generic(&p, [f64::NAN, 1.0]);
            let _ = model::camera::project_generic(&p, &[0.0, 0.0, 0.0]);
            let _ = model::camera::distort_generic(&[f64::INFINITY; 5], 1e300, -1e300);
        });
    }
    for m in [
        DistortionModel::Radial1,
        DistortionModel::Radial2,
        DistortionModel::OpenCv5,
    ] {
        assert_eq!(DistortionModel::from_name(m.name()).unwrap(), m);
        let _ = m.free_coefficients();
    }
    assert!(DistortionModel::from_name("fisheye").is_err());
}

// ---------------------------------------------------------------- geometry

#[test]
fn geometry_takes_hostile_values() {
    use model::geometry::*;
    let mats = [
        Matrix3::zeros(),
        Matrix3::from_element(f64::NAN),
        Matrix3::from_element(f64::INFINITY),
        Matrix3::from_element(1e308),
        Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0),
        Matrix3::identity() * 1e-300,
        Matrix3::new(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0),
    ];
    for m in mats {
        probe("geometry of a matrix", move || {
            let _ = nearest_rotation(&m);
            let _ = matrix_to_rotvec(&m);
            let _ = quaternion_from_matrix(&m);
            let _ = iso_from_parts(&m, &Vector3::new(f64::NAN, 0.0, 0.0));
            let mut m4 = Matrix4::identity();
            m4.fixed_view_mut::<3, 3>(0, 0).copy_from(&m);
            for tol in [0.0, -1.0, f64::NAN, 1e-3, f64::INFINITY] {
                finite_or_err("iso_from_matrix", &iso_from_matrix(&m4, tol));
            }
        });
    }
    for &x in &BAD {
        probe("rotvec", move || {
            let r = Vector3::new(x, -x, 0.5);
            let m = rotvec_to_matrix(&r);
            let _ = iso_from_rotvec(&r, &r);
            let t = iso_bad(x);
            let _ = iso_to_rotvec(&t);
            let _ = iso_to_matrix(&t);
            let _ = quaternion_to_rotvec(&t.rotation);
            let _ = m;
        });
        probe("Plane", move || {
            for n in [
                Vector3::new(x, 0.0, 1.0),
                Vector3::zeros(),
                Vector3::new(1e-300, 0.0, 0.0),
            ] {
                let r = Plane::new(n, x);
                finite_or_err("Plane::new", &r);
            }
            let p = Plane::new(Vector3::z(), 100.0).unwrap();
            let _ = p.signed_distance(&Vector3::new(x, x, x));
            if let Some(s) = p.intersect_ray(&Vector3::zeros(), &Vector3::new(x, 0.0, 0.0)) {
                assert!(s.is_finite(), "intersect_ray gave {s}");
            }
            let _ = p.intersect_ray(&Vector3::new(x, x, x), &Vector3::z());
            let _ = p.transformed(&iso_bad(x));
        });
    }
}

// ---------------------------------------------------------------- images

#[test]
fn images_take_hostile_sizes() {
    let data = vec![1u8; 12];
    for (w, h, s) in [
        (0, 0, 0),
        (4, 3, 4),
        (4, 3, 3),
        (5, 3, 5),
        (usize::MAX, 2, usize::MAX),
        (2, usize::MAX, 2),
        (1, 12, 1),
        (12, 1, 12),
        (4, 0, 4),
    ] {
        let d = data.clone();
        probe("ImageView::new", move || {
            let r = ImageView::new(&d, w, h, s);
            if let Ok(v) = &r {
                // every pixel of an accepted view is readable
                for y in 0..v.height() {
                    assert_eq!(v.row(y).len(), v.width());
                    for x in 0..v.width() {
                        let _ = v.get(x, y);
                    }
                }
            }
            let _ = ImageView::from_slice(&d, w, h).is_ok();
        });
    }
    let g = GrayImage::<u16>::new(3, 2);
    assert_eq!(g.get(2, 1), 0);
    for bad in [
        AnyGray::U8(GrayImage {
            width: 5,
            height: 5,
            data: vec![0; 3],
        }),
        AnyGray::U16(GrayImage {
            width: 0,
            height: 0,
            data: vec![],
        }),
        AnyGray::U8(GrayImage {
            width: usize::MAX,
            height: 2,
            data: vec![0; 3],
        }),
    ] {
        let _ = bad.size();
        must_err(
            "AnyGray::view of an inconsistent image",
            &bad.view().map(|v| v.size()),
        );
    }
    // GrayImage::new: a size whose product overflows is a clear panic, not a wrong image
    let r = std::panic::catch_unwind(|| GrayImage::<u8>::new(usize::MAX, 3));
    assert!(r.is_err());
    for ch in [0usize, 1, 2, 3, 4, 5, usize::MAX] {
        let samples = vec![200u16; 12];
        let out = probe("gray_from_interleaved", move || {
            model::image::gray_from_interleaved(&samples, ch)
        });
        if let Some(v) = out {
            assert!(
                ch > 0 && v.len() == 12 / ch,
                "channels {ch}: {} values",
                v.len()
            );
        }
    }
    assert_eq!(
        model::image::luma_bt601(u32::MAX, u32::MAX, u32::MAX),
        u32::MAX
    );
    use stripecal::model::image::Pixel;
    assert_eq!(7u8.to_u32(), 7);
    assert_eq!(65535u16.to_f32(), 65535.0);
}

// ---------------------------------------------------------------- kinematics

#[test]
fn kinematics_take_hostile_values() {
    must_err("Robot::new no joints", &Robot::new("x", vec![]));
    let j = |x: f64| DhJoint {
        theta0_deg: x,
        alpha_deg: 0.0,
        a_mm: x,
        d_mm: 1.0,
        beta_deg: 0.0,
    };
    for &x in &BAD {
        finite_or_err(
            "Robot::new",
            &probe("Robot::new", move || Robot::new("x", vec![j(x)])),
        );
        probe("DhJoint", move || {
            let _ = j(1.0).rotation_translation(x);
            let _ = j(x).transform(x);
        });
    }
    let robot = Robot::hp3();
    assert_eq!(robot.dof(), 6);
    robot.validate().unwrap();
    let qs: Vec<Vec<f64>> = vec![
        vec![],
        vec![0.0; 5],
        vec![0.0; 7],
        vec![f64::NAN; 6],
        vec![f64::INFINITY, 0.0, 0.0, 0.0, 0.0, 0.0],
        vec![1e308; 6],
        vec![0.0, 0.0, 0.0, 0.0, -90.0, 0.0],
    ];
    for q in qs {
        let r = robot.clone();
        probe("Robot::forward/jacobian/inverse", move || {
            finite_or_err("forward", &r.forward(&q));
            finite_or_err("jacobian", &r.jacobian(&q));
            if q.len() == 6 {
                let _ = r.forward_unchecked(&q);
            }
            let home = r.forward(&[0.0, 0.0, 0.0, 0.0, -90.0, 0.0]).unwrap();
            let mut opts = model::kinematics::IkOptions::default();
            finite_or_err("inverse", &r.inverse(&home, &q, &opts));
            // unreachable and non-finite targets, hostile options
            let far = pose([0.0, 0.0, 0.0], [1e6, 0.0, 0.0]);
            finite_or_err("inverse (unreachable)", &r.inverse(&far, &[0.0; 6], &opts));
            finite_or_err(
                "inverse (NaN)",
                &r.inverse(&iso_bad(f64::NAN), &[0.0; 6], &opts),
            );
            opts.max_iter = 0;
            opts.damping = f64::NAN;
            opts.tol_mm = -1.0;
            finite_or_err("inverse (options)", &r.inverse(&home, &[0.0; 6], &opts));
        });
    }
    // a robot whose public joints were set by hand
    let hand_made = Robot {
        name: String::new(),
        joints: vec![],
        repeatability_mm: None,
        encoder_sigma_deg: None,
    };
    // an empty chain is the identity: a valid result; a reading of the wrong length is not
    finite_or_err("forward of a robot without joints", &hand_made.forward(&[]));
    must_err(
        "forward of a robot without joints",
        &hand_made.forward(&[1.0]),
    );
    let _ = hand_made.forward_unchecked(&[]);
    finite_or_err("jacobian", &hand_made.jacobian(&[]));
}

// ---------------------------------------------------------------- model: dataset, results

#[test]
fn model_records_take_hostile_values() {
    use model::{CameraSigma, NamedCovariance, StripeDirection};
    for r in [
        RobotReading::Joints(vec![]),
        RobotReading::Joints(vec![f64::NAN; 6]),
        RobotReading::Joints(vec![0.0; 3]),
        RobotReading::FlangePose(iso_bad(f64::NAN)),
        RobotReading::FlangePose(Iso3::identity()),
    ] {
        finite_or_err("base_hand(None)", &r.base_hand(None));
        finite_or_err("base_hand(hp3)", &r.base_hand(Some(&Robot::hp3())));
    }
    for s in ["auto", "rows", "cols", "", "ROWS"] {
        if let Ok(d) = StripeDirection::from_name(s) {
            assert_eq!(d.name(), s);
        }
    }
    let cov = NamedCovariance {
        parameters: vec!["a".into(), "b".into(), "a.c".into()],
        // a matrix smaller than its names (public fields, set by hand)
        matrix: DMatrix::from_element(2, 2, -1.0),
    };
    probe("NamedCovariance", move || {
        for n in ["a", "b", "a.c", "", "zz"] {
            let _ = cov.index(n);
            if let Some(s) = cov.sigma(n) {
                assert!(!s.is_nan() || n == "a" || n == "b", "{n}: {s}");
            }
        }
        for p in ["a", "", "zz"] {
            let b = cov.block(p);
            assert_eq!(b.parameters.len(), b.matrix.nrows());
        }
    });
    let _ = CameraSigma::from_params(&[f64::NAN; 9]);
    for p in [
        Path::new("/nonexistent/stripecal"),
        Path::new(""),
        Path::new("/"),
    ] {
        let p2 = p.to_path_buf();
        let r = probe("Dataset::load", move || model::Dataset::load(&p2));
        must_err("Dataset::load", &r.map(|d| d.views.len()));
        let p2 = p.to_path_buf();
        let r = probe("Scan::load", move || {
            model::Scan::load(&p2, Some(&Robot::hp3()))
        });
        must_err("Scan::load", &r.map(|d| d.frames.len()));
    }
}

// ---------------------------------------------------------------- numerics

struct Toy {
    n: usize,
    m: usize,
    nan_at: Option<usize>,
    fail: bool,
}

impl numerics::lm::LeastSquares for Toy {
    fn num_params(&self) -> usize {
        self.n
    }
    fn num_residuals(&self) -> usize {
        self.m
    }
    fn residuals(&self, p: &[f64], r: &mut [f64]) -> stripecal::Result<()> {
        if self.fail {
            return Err(Error::Degenerate("toy".into()));
        }
        for (i, ri) in r.iter_mut().enumerate() {
            *ri = p.get(i % self.n.max(1)).copied().unwrap_or(0.0) - i as f64;
            if Some(i) == self.nan_at {
                *ri = f64::NAN;
            }
        }
        Ok(())
    }
    fn residuals_and_jacobian(
        &self,
        p: &[f64],
        r: &mut [f64],
        mut jac: faer::MatMut<'_, f64>,
    ) -> stripecal::Result<()> {
        self.residuals(p, r)?;
        for i in 0..self.m {
            for j in 0..self.n {
                jac[(i, j)] = if j == i % self.n.max(1) { 1.0 } else { 0.0 };
            }
        }
        Ok(())
    }
}

#[test]
fn numerics_take_hostile_values() {
    use numerics::homography as h;
    use numerics::lm;
    // homographies
    let sq = vec![
        Vector2::new(0.0, 0.0),
        Vector2::new(1.0, 0.0),
        Vector2::new(1.0, 1.0),
        Vector2::new(0.0, 1.0),
    ];
    let line: Vec<Vector2<f64>> = (0..6)
        .map(|i| Vector2::new(i as f64, 2.0 * i as f64))
        .collect();
    let nan: Vec<Vector2<f64>> = vec![Vector2::new(f64::NAN, 0.0); 5];
    let same: Vec<Vector2<f64>> = vec![Vector2::new(1.0, 1.0); 5];
    for (a, b) in [
        (vec![], vec![]),
        (sq.clone(), sq[..3].to_vec()),
        (sq[..3].to_vec(), sq[..3].to_vec()),
        (line.clone(), line.clone()),
        (nan.clone(), nan.clone()),
        (same.clone(), same.clone()),
        (sq.clone(), vec![Vector2::new(1e308, -1e308); 4]),
    ] {
        probe("homography", move || {
            finite_or_err("dlt", &h::dlt(&a, &b));
            if let Some((x, y)) = h::dlt_residuals(&a, &b) {
                assert!(!x.is_nan() && !y.is_nan(), "dlt_residuals");
            }
            finite_or_err("fit_homography", &calib::homography::fit_homography(&a, &b));
            finite_or_err("calib::homography::dlt", &calib::homography::dlt(&a, &b));
        });
    }
    for m in [
        Matrix3::zeros(),
        Matrix3::from_element(f64::NAN),
        Matrix3::identity(),
    ] {
        let _ = h::apply(&m, &Vector2::new(1.0, f64::INFINITY));
        let _ = calib::homography::apply(&m, &Vector2::new(0.0, 0.0));
    }
    // covariance of hostile normal matrices
    for (jtj, s2, tol) in [
        (DMatrix::<f64>::zeros(0, 0), 1.0, 1e-12),
        (DMatrix::from_element(3, 3, f64::NAN), 1.0, 1e-12),
        (DMatrix::from_element(3, 3, 1.0), f64::NAN, -1.0),
        (DMatrix::identity(4, 4), 0.0, f64::INFINITY),
        (DMatrix::from_element(2, 3, 1.0), 1.0, 1e-12),
    ] {
        let r = probe("lm::covariance", move || {
            std::panic::catch_unwind(|| lm::covariance(&jtj, s2, tol)).map(|_| ())
        });
        // a non-square matrix is a programmer error (documented): either way no abort
        let _ = r;
    }
    // Levenberg-Marquardt on toy problems: zero parameters, zero residuals, NaN
    // residuals, failing residuals, hostile options and starts
    for (n, m, nan_at, fail) in [
        (0, 3, None, false),
        (3, 0, None, false),
        (2, 5, Some(1), false),
        (2, 4, None, true),
        (3, 6, None, false),
    ] {
        for p0 in [
            vec![0.0; n],
            vec![f64::NAN; n],
            vec![1e308; n],
            vec![0.0; n + 1],
        ] {
            let mut opts = lm::LmOptions::default();
            for variant in 0..3 {
                match variant {
                    1 => {
                        opts.max_iterations = 0;
                        opts.ftol = f64::NAN;
                        opts.initial_lambda = -1.0;
                    }
                    2 => {
                        opts.scaling = Some(vec![0.0; n + 2]);
                        opts.huber = Some(f64::NAN);
                        opts.rank_tol = f64::INFINITY;
                    }
                    _ => {}
                }
                let toy = Toy { n, m, nan_at, fail };
                let p = p0.clone();
                let o = opts.clone();
                let r = probe("levenberg_marquardt", move || {
                    lm::levenberg_marquardt(&toy, &p, &o).map(|r| (r.params.clone(), r.cost))
                });
                if let Ok((params, cost)) = &r {
                    assert!(
                        params.iter().all(|x| x.is_finite()) && cost.is_finite(),
                        "levenberg_marquardt n {n} m {m} p0 {p0:?} variant {variant}: Ok({params:?}, {cost})"
                    );
                }
                let toy = Toy { n, m, nan_at, fail };
                let p = p0.clone();
                probe("dense_jacobian_from_rows", move || {
                    let mut r = vec![0.0; m];
                    let mut jac = faer::Mat::<f64>::zeros(m, n);
                    let _ = lm::dense_jacobian_from_rows(&toy, &p, &mut r, jac.as_mut());
                });
            }
        }
    }
    // the trait's default methods
    use lm::LeastSquares;
    let toy = Toy {
        n: 2,
        m: 3,
        nan_at: None,
        fail: false,
    };
    let mut out = [0.0; 2];
    toy.retract(&[1.0, f64::NAN], &[f64::INFINITY], &mut out);
    assert!(
        toy.reweight(&[f64::NAN], &mut |_| None).is_none() && toy.jacobian_row_width().is_none()
    );
    let mut rows = lm::JacobianRows::new(3, 2, 2);
    must_err(
        "residuals_and_jacobian_rows (default)",
        &toy.residuals_and_jacobian_rows(&[0.0; 2], &mut [0.0; 3], &mut rows),
    );
    let r = std::panic::catch_unwind(|| lm::JacobianRows::new(usize::MAX, 2, 5));
    assert!(r.is_err(), "an overflowing size is a clear panic");
    let mut rows = lm::JacobianRows::new(3, 2, 5);
    assert_eq!(
        (rows.width(), rows.len(), rows.is_dense(), rows.is_empty()),
        (2, 3, false, false)
    );
    rows.clear();
    let _ = rows.parts_mut();
    let _ = rows.row(2);
    let mut dense = lm::JacobianRows::new(0, 4, 4);
    assert!(dense.is_empty() && dense.is_dense());
    let _ = dense.parts_mut();
    // mat3, rng, robust, tls, dual
    use numerics::mat3::*;
    let a = m3::<f64>(&Matrix3::from_element(f64::NAN));
    let _ = (
        matmul(&a, &a),
        transpose(&a),
        matvec(&a, &[1.0; 3]),
        cross(&[1.0; 3], &[f64::INFINITY; 3]),
        dot(&[1e308; 3], &[1e308; 3]),
    );
    let _ = rot_times_exp_first_order(&Matrix3::identity(), &[f64::NAN; 3]);
    let _ = rows_f64(&Matrix3::identity());
    let mut rng = numerics::rng::SplitMix64(0);
    let _ = (
        rng.next_u64(),
        rng.uniform(),
        rng.normal(),
        rng.below(1),
        rng.below(usize::MAX),
    );
    assert_eq!(probe("SplitMix64::below(0)", move || rng.below(0)), 0);
    use numerics::robust::{median, median_mean, robust_sigma, TotalOrd};
    for v in [
        vec![],
        vec![f64::NAN],
        vec![f64::NAN, 1.0, f64::INFINITY, -0.0, 0.0],
        vec![1e308, -1e308],
    ] {
        let mut a = v.clone();
        let mut b = v.clone();
        probe("robust", move || {
            let _ = median(&mut a);
            let _ = median_mean(&mut b);
            let mut buf = Vec::new();
            let _ = robust_sigma(&v, &mut buf);
            if let (Some(x), Some(y)) = (v.first(), v.last()) {
                let _ = x.total_order(y);
            }
        });
    }
    for pts in [
        vec![],
        vec![Vector3::new(1.0, 2.0, 3.0)],
        vec![Vector3::new(1.0, 2.0, 3.0); 10],
        (0..10).map(|i| Vector3::new(i as f64, 0.0, 0.0)).collect(),
        vec![Vector3::new(f64::NAN, 0.0, 0.0); 4],
        vec![
            Vector3::new(1e308, -1e308, 1e308),
            Vector3::new(-1e308, 1e308, 0.0),
        ],
    ] {
        check("principal_axes", move || {
            numerics::tls::principal_axes(pts.iter()).map(|p| p.singular)
        });
    }
    use numerics::dual::{Dual, Scalar};
    let d = Dual::<3>::var(f64::NAN, 7);
    let _ = (
        Dual::<2>::cst(1.0),
        d.value(),
        d.is_zero(),
        d.scale(f64::INFINITY),
        Dual::<3>::from_f64(-1.0).sqrt(),
    );
}

// ---------------------------------------------------------------- calib

fn hostile_obs() -> Vec<(String, Vec<ViewObs>)> {
    let f = fixture();
    let good = f.obs.clone();
    let mut out = vec![
        ("good".to_string(), good.clone()),
        ("none".to_string(), vec![]),
    ];
    let mut one = good.clone();
    one.truncate(1);
    out.push(("one view".into(), one));
    let mut same = good.clone();
    for v in same.iter_mut() {
        *v = good[0].clone();
    }
    out.push(("every view the same".into(), same));
    let mut nan = good.clone();
    nan[1].circles[3].u = f64::NAN;
    nan[2].stripe.push([f64::INFINITY, 1.0]);
    out.push(("NaN pixel".into(), nan));
    let mut range = good.clone();
    range[0].circles[0].row = 10_000;
    range[1].circles[0].col = usize::MAX;
    out.push(("out-of-range circle".into(), range));
    let mut dup = good.clone();
    let c = dup[0].circles[0];
    dup[0].circles = vec![c; 40];
    out.push(("one circle 40 times".into(), dup));
    let mut line = good.clone();
    for v in line.iter_mut() {
        v.circles.retain(|c| c.row == 0);
    }
    out.push(("one row of circles (collinear)".into(), line));
    let mut few = good.clone();
    for v in few.iter_mut() {
        v.circles.truncate(3);
        v.stripe.clear();
    }
    out.push(("three circles, no stripe".into(), few));
    let mut nopose = good.clone();
    for v in nopose.iter_mut() {
        v.base_hand = None;
        v.reading = None;
    }
    out.push(("no robot poses".into(), nopose));
    let mut badpose = good.clone();
    badpose[2].base_hand = Some(iso_bad(f64::NAN));
    badpose[3].reading = Some(RobotReading::Joints(vec![1.0]));
    out.push(("NaN robot pose".into(), badpose));
    let mut huge = good;
    for v in huge.iter_mut() {
        for c in v.circles.iter_mut() {
            c.u *= 1e300;
        }
    }
    out.push(("huge pixels".into(), huge));
    out
}

#[test]
fn calibration_stages_take_hostile_observations() {
    use calib::camera::{calibrate_camera, CameraOptions};
    let f = fixture();
    let board = f.twin.board.clone();
    let rig = f.twin.rig().unwrap();
    for (what, obs) in hostile_obs() {
        let b = board.clone();
        let o = obs.clone();
        let name = format!("calibrate_camera ({what})");
        let cam = check_value(&name, move || {
            calibrate_camera(
                &o,
                &b,
                384,
                288,
                DistortionModel::Radial1,
                &CameraOptions::default(),
            )
            .map(|c| (c.camera, c.rms_px, c.poses))
        });
        for (w, h) in [(0, 0), (1, 1)] {
            let b = board.clone();
            let o = obs.clone();
            check(&format!("calibrate_camera {w}x{h} ({what})"), move || {
                calibrate_camera(
                    &o,
                    &b,
                    w,
                    h,
                    DistortionModel::OpenCv5,
                    &CameraOptions::default(),
                )
                .map(|c| c.camera)
            });
        }
        let r = rig.clone();
        let o = obs.clone();
        let name = format!("calibrate_observations ({what})");
        check(&name, move || {
            pipeline::calibrate_observations(&o, &r, &pipeline::CalibrateOptions::default()).map(
                |rep| {
                    let c = rep.calibration;
                    (c.camera, c.laser_plane, c.hand_cam, c.base_board, c.quality)
                },
            )
        });
        let mut opts = pipeline::CalibrateOptions {
            method: pipeline::Method::Paper,
            robust: true,
            outlier_factor: f64::NAN,
            board_scale_tolerance: -1.0,
            ..Default::default()
        };
        opts.free.camera = false;
        let r = rig.clone();
        let o = obs.clone();
        check(
            &format!("calibrate_observations, hostile options ({what})"),
            move || {
                pipeline::calibrate_observations(&o, &r, &opts).map(|rep| rep.calibration.camera)
            },
        );
        // the stripe stages with the camera of the good observations
        if let Ok((camera, _, poses)) = cam {
            let views: Vec<(Iso3, Vec<[f64; 2]>)> = poses
                .iter()
                .filter_map(|(i, t)| {
                    obs.iter()
                        .find(|v| v.view == *i)
                        .map(|v| (*t, v.stripe.clone()))
                })
                .collect();
            let (c2, v2) = (camera.clone(), views.clone());
            check(&format!("fit_laser_plane ({what})"), move || {
                calib::laser_plane::fit_laser_plane(&v2, &c2).map(|f| (f.plane, f.rms_mm))
            });
            let (c2, v2) = (camera.clone(), views.clone());
            check(&format!("select_on_board_plane ({what})"), move || {
                pipeline::select_on_board_plane(&v2, &c2).map(|s| s.off_plane)
            });
            // AX = ZB from the views' robot poses and board poses
            let a: Vec<Iso3> = poses
                .iter()
                .filter_map(|(i, _)| obs.iter().find(|v| v.view == *i).and_then(|v| v.base_hand))
                .collect();
            let b: Vec<Iso3> = poses.iter().map(|(_, t)| *t).collect();
            check(&format!("solve_axzb ({what})"), move || {
                calib::axzb::solve_axzb(&a, &b).map(|s| (s.x, s.z))
            });
        }
    }
    // the stripe stages and AX = ZB on their own
    let cam = camera();
    let t = pose([0.1, -0.2, 0.05], [0.0, 0.0, 120.0]);
    for views in [
        vec![],
        vec![(t, vec![])],
        vec![(t, vec![[1.0, 1.0]; 50]); 3],
        vec![(t, (0..50).map(|i| [i as f64 * 10.0, 200.0]).collect()); 4],
        vec![(iso_bad(f64::NAN), vec![[1.0, 2.0], [3.0, 4.0]]); 3],
        vec![(t, vec![[f64::NAN, 0.0], [1e308, -1e308]]); 3],
    ] {
        let (c2, v2) = (cam.clone(), views.clone());
        check("fit_laser_plane", move || {
            calib::laser_plane::fit_laser_plane(&v2, &c2).map(|f| (f.plane, f.rms_mm))
        });
        let (c2, v2) = (cam.clone(), views);
        check("select_on_board_plane", move || {
            pipeline::select_on_board_plane(&v2, &c2).map(|s| s.off_plane)
        });
    }
    let id = Iso3::identity();
    for (a, b) in [
        (vec![], vec![]),
        (vec![id; 3], vec![id; 2]),
        (vec![id; 5], vec![id; 5]),
        (vec![t; 4], vec![t; 4]),
        (vec![iso_bad(f64::NAN); 3], vec![id; 3]),
        (vec![iso_bad(1e308); 3], vec![iso_bad(-1e308); 3]),
    ] {
        let (a2, b2) = (a.clone(), b.clone());
        check("solve_axzb", move || {
            calib::axzb::solve_axzb(&a2, &b2).map(|s| (s.x, s.z))
        });
        check("solve_axzb_with", move || {
            calib::axzb::solve_axzb_with(&a, &b, &calib::axzb::AxzbOptions { refine: true })
                .map(|s| (s.x, s.z))
        });
    }
    // board plane, back projection and stripe lines of hostile poses and pixels
    for &x in &BAD {
        probe("laser_plane helpers", move || {
            let cam = camera();
            for tb in [
                iso_bad(x),
                pose([0.0, 0.0, 0.0], [0.0, 0.0, x]),
                pose([std::f64::consts::FRAC_PI_2, 0.0, 0.0], [0.0, 0.0, 100.0]),
            ] {
                let _ = calib::laser_plane::board_plane_in_cam(&tb);
                finite_or_err(
                    "backproject_to_board",
                    &calib::laser_plane::backproject_to_board(&cam, &tb, &[x, 1.0]),
                );
                let plane = Plane::new(Vector3::new(0.6, 0.0, 0.8), 80.0).unwrap();
                let line = calib::laser_plane::stripe_line_in_view(&plane, &tb, &cam);
                finite_or_err("stripe_line_in_view", &line.as_ref().map(|_| ()));
                if let Ok(l) = line {
                    finite_or_err("signed_distance_px", &l.signed_distance_px(&cam, &[x, x]));
                }
                // a board plane through the camera centre
                let through = calib::laser_plane::stripe_line_in_view(
                    &plane,
                    &pose([std::f64::consts::FRAC_PI_2, 0.0, 0.0], [0.0, 0.0, 0.0]),
                    &cam,
                );
                finite_or_err(
                    "stripe_line_in_view (through the centre)",
                    &through.map(|_| ()),
                );
            }
        });
    }
    // Zhang and homography poses
    for hs in [
        vec![],
        vec![Matrix3::identity()],
        vec![Matrix3::zeros(); 3],
        vec![Matrix3::from_element(f64::NAN); 4],
        vec![Matrix3::identity(); 5],
    ] {
        for pp in [None, Some((f64::NAN, 0.0)), Some((100.0, 100.0))] {
            for scale in [0.0, -1.0, f64::NAN, 1.0] {
                let h2 = hs.clone();
                check("zhang_intrinsics", move || {
                    calib::zhang::zhang_intrinsics(&h2, pp, scale).map(|i| (i.fu, i.fv, i.u0, i.v0))
                });
            }
        }
        for h in hs.iter().chain([Matrix3::identity()].iter()) {
            let h = *h;
            check("pose_from_homography", move || {
                calib::zhang::pose_from_homography(&h, &Matrix3::identity())
            });
            check("pose_from_homography (singular K)", move || {
                calib::zhang::pose_from_homography(&h, &Matrix3::zeros())
            });
        }
    }
    let i = calib::zhang::Intrinsics {
        fu: f64::NAN,
        fv: 1.0,
        u0: 0.0,
        v0: 0.0,
    };
    let _ = i.k();
}

#[test]
fn conic_consensus_and_joint_take_hostile_values() {
    use calib::conic::*;
    let cam = camera();
    let p = cam.params();
    for model in [
        CentreModel::Naive,
        CentreModel::Conic,
        CentreModel::ConicExact,
    ] {
        let _ = model.name();
        for &x in &BAD {
            let c2 = cam.clone();
            probe("conic", move || {
                for t in [
                    pose([0.0, 0.0, 0.0], [0.0, 0.0, 100.0]),
                    iso_bad(x),
                    pose([0.0, 0.0, 0.0], [0.0, 0.0, -100.0]),
                    pose([std::f64::consts::FRAC_PI_2, 0.0, 0.0], [0.0, 0.0, 0.0]),
                ] {
                    for radius in [x, 1.0, 0.0, -1.0] {
                        let centre = Vector3::new(x, 0.0, 0.0);
                        finite_or_err(
                            "predict_centre",
                            &predict_centre(&c2, &t, &centre, radius, model),
                        );
                        finite_or_err(
                            "predict_centre_with_jacobians",
                            &predict_centre_with_jacobians(&c2, &t, &centre, radius, model)
                                .map(|_| ()),
                        );
                    }
                }
                let rot = [[x, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
                for nodes in [0usize, 1, 2, 1000] {
                    let r = centre_generic_n(&p, &rot, &[0.0, 0.0, x], (x, 0.0), x, model, nodes);
                    finite_or_err("centre_generic_n", &r);
                }
                finite_or_err(
                    "centre_generic",
                    &centre_generic(&p, &rot, &[0.0, 0.0, 100.0], (0.0, 0.0), 1.0, model),
                );
                let _ = centroid_offset(&[x; 5], &[x; 5], &[x; 2], &[]);
                let _ = centroid_offset(&[0.0; 5], &[1.0; 5], &[0.0; 2], &[(x, x); 3]);
                let _ = <f64 as CentreScalar>::centroid_offset(
                    &[x; 5],
                    &[0.0; 5],
                    &[0.0; 2],
                    &[(1.0, 1.0)],
                );
            });
        }
    }
    for m in [
        DistortionModel::Radial1,
        DistortionModel::Radial2,
        DistortionModel::OpenCv5,
    ] {
        assert!(quadrature_nodes(m) > 0);
    }
    // consensus
    use calib::consensus::{choose, symmetry_motion, Candidates};
    let t = pose([0.1, 0.2, 0.3], [1.0, 2.0, 3.0]);
    for views in [
        vec![],
        vec![Candidates { a: t, b: vec![] }],
        vec![Candidates { a: t, b: vec![t] }; 3],
        vec![
            Candidates {
                a: t,
                b: vec![t, t, t]
            };
            4
        ],
        vec![
            Candidates {
                a: iso_bad(f64::NAN),
                b: vec![iso_bad(f64::NAN), t]
            };
            3
        ],
        vec![
            Candidates { a: t, b: vec![t] },
            Candidates { a: t, b: vec![] },
            Candidates {
                a: t,
                b: vec![t; 4],
            },
        ],
    ] {
        let d = probe("consensus::choose", move || choose(&views));
        for x in d {
            if let calib::consensus::Decision::Chosen { margin, .. } = x {
                assert!(!margin.is_nan());
            }
        }
    }
    for b in [Board::hp3_paper(), Board::chessboard(4, 4, 1.0).unwrap()] {
        for s in b.symmetries().into_iter().chain([Symmetry {
            quarter_turns: 200,
            shift: (i64::MAX, 3),
        }]) {
            let b2 = b.clone();
            probe("symmetry_motion", move || symmetry_motion(&b2, &s));
        }
    }
    // the joint adjustment from the twin's truth, with hostile observations and starts
    use calib::joint::{joint_adjustment, FreeBlocks, JointOptions, JointStart};
    let mut fb = FreeBlocks::laser_only();
    for n in ["camera", "laser_plane", "hand_cam", "base_board", "robot"] {
        fb.hold(n).unwrap();
    }
    assert!(fb.hold("").is_err() && fb.hold("CAMERA").is_err());
    let f = fixture();
    let truth = f.twin.true_calibration();
    let start = JointStart {
        camera: truth.camera.clone(),
        plane: truth.laser_plane,
        hand_cam: truth.hand_cam,
        base_board: truth.base_board,
    };
    let mut starts = vec![("true start", start.clone())];
    let mut s = start.clone();
    s.camera.fu = f64::NAN;
    starts.push(("NaN focal length", s));
    let mut s = start.clone();
    s.hand_cam = iso_bad(f64::NAN);
    starts.push(("NaN hand-eye", s));
    let mut s = start;
    s.plane = None;
    starts.push(("no plane", s));
    for (what, obs) in hostile_obs() {
        for (sw, st) in &starts {
            let (o, b, st) = (obs.clone(), f.twin.board.clone(), st.clone());
            let name = format!("joint_adjustment ({what}, {sw})");
            let n2 = name.clone();
            let r = probe(&name, move || {
                joint_adjustment(&o, &b, &st, &JointOptions::default())
                    .map(|j| (j.camera, j.plane, j.hand_cam, j.base_board))
            });
            finite_or_err(&n2, &r);
        }
    }
    let mut opts = JointOptions {
        board_scale: f64::NAN,
        outlier_sigmas: -1.0,
        initial_sigma_px: (0.0, f64::INFINITY),
        ..Default::default()
    };
    opts.lm.max_iterations = 0;
    let (o, b) = (f.obs.clone(), f.twin.board.clone());
    let st = JointStart {
        camera: truth.camera.clone(),
        plane: truth.laser_plane,
        hand_cam: truth.hand_cam,
        base_board: truth.base_board,
    };
    check("joint_adjustment (hostile options)", move || {
        joint_adjustment(&o, &b, &st, &opts).map(|j| (j.camera, j.hand_cam))
    });
    let _ = CircleObs {
        row: 0,
        col: 0,
        u: 0.0,
        v: 0.0,
    };
}

// ---------------------------------------------------------------- io (paths, records)

#[test]
fn io_functions_take_impossible_paths_and_hostile_records() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().to_path_buf();
    let missing = dir.path().join("missing.file");
    for p in [folder.clone(), missing.clone(), Path::new("").to_path_buf()] {
        let p2 = p.clone();
        let writable = p == missing;
        probe("readers on impossible paths", move || {
            let p = p2;
            assert!(matches!(io::read_rig(&p), Err(Error::Io { .. })));
            assert!(matches!(io::read_calibration(&p), Err(Error::Io { .. })));
            assert!(matches!(io::read_truth(&p), Err(Error::Io { .. })));
            assert!(matches!(io::read_sphere_fit(&p), Err(Error::Io { .. })));
            assert!(matches!(io::read_ply(&p), Err(Error::Io { .. })));
            assert!(matches!(
                io::read_views_csv(&p, None),
                Err(Error::Io { .. })
            ));
            assert!(matches!(io::read_scan_csv(&p, None), Err(Error::Io { .. })));
            assert!(io::load_gray(&p).is_err());
            assert!(io::load_gray_info(&p).is_err());
        });
        let p2 = p.clone();
        if writable {
            continue;
        }
        probe("writers on impossible paths", move || {
            let p = p2;
            let c = calibration();
            assert!(io::write_calibration(&p, &c).is_err());
            assert!(
                io::write_ply(&p, &fuzz_support::cloud(3, false), io::PlyFormat::Ascii).is_err()
            );
            assert!(io::write_atomic(&p, b"x").is_err());
            let img = AnyGray::U8(GrayImage {
                width: 1,
                height: 1,
                data: vec![1],
            });
            assert!(io::save_gray_png(&p, &img).is_err());
        });
    }
    assert!(fuzz_support::temporaries(dir.path()).is_empty());
    // images the PNG writer cannot write
    for img in [
        AnyGray::U8(GrayImage {
            width: 0,
            height: 0,
            data: vec![],
        }),
        AnyGray::U8(GrayImage {
            width: 3,
            height: 3,
            data: vec![0; 8],
        }),
        AnyGray::U16(GrayImage {
            width: usize::MAX,
            height: 2,
            data: vec![0; 2],
        }),
        AnyGray::U16(GrayImage {
            width: 1 << 33,
            height: 1,
            data: vec![],
        }),
    ] {
        let p = dir.path().join("x.png");
        let r = probe("save_gray_png", move || io::save_gray_png(&p, &img));
        assert!(matches!(r, Err(Error::InvalidInput(_))), "{r:?}");
    }
    // pose columns
    for spec in [
        vec![],
        vec![""],
        vec!["ros"],
        vec!["kuka", "ros"],
        vec!["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"],
        vec!["x_mm,y_mm"],
        vec!["q1"],
        vec!["x_mm", "x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"],
        vec!["nonsense"],
    ] {
        let r = probe("PoseColumns::from_spec", move || {
            io::PoseColumns::from_spec(&spec)
        });
        if let Ok(c) = r {
            assert!(!c.is_empty() && c.len() == c.names().len());
            let _ = (c.rotation_columns(), c.describe());
            for values in [
                vec![],
                vec![f64::NAN; c.len()],
                vec![0.0; c.len()],
                vec![1e308; c.len()],
            ] {
                if let Ok(t) = c.to_iso(&values) {
                    assert!(fuzz_support::finite_iso(&t), "{c:?} {values:?}");
                    assert!(c.to_values(&t).iter().all(|x| x.is_finite()));
                }
            }
            let _ = c.to_values(&iso_bad(f64::NAN));
        }
        let _ = io::PoseColumns::parse(&["qw"]);
    }
    assert!(io::convention_columns("").is_none());
    assert!(!io::convention_names().is_empty());
    // the records' JSON of hostile values (NaN must become null, never a panic)
    use model::{AdjustmentSummary, CameraSigma, PlaneSigma, PoseSigma, Uncertainty, ViewRecord};
    let nan = f64::NAN;
    let u = Uncertainty {
        camera: Some(CameraSigma::from_params(&[nan; 9])),
        laser_plane: Some(PlaneSigma {
            normal: [nan; 3],
            d_mm: f64::INFINITY,
        }),
        hand_cam: Some(PoseSigma {
            rotation_vector: [nan; 3],
            translation_mm: [nan; 3],
        }),
        base_board: None,
    };
    let m = io::uncertainty_to_json(&u);
    assert!(serde_json::to_string(&m).is_ok());
    let rec = ViewRecord {
        view: usize::MAX,
        used: true,
        circles: 0,
        stripe_points: 0,
        stripe_off_plane: 0,
        circle_rms_px: Some(nan),
        stripe_rms_px: Some(f64::INFINITY),
        outlier: None,
        note: Some("\u{0}".into()),
        stripe_extraction: Some(stripecal::model::StripeExtraction {
            width_px: f64::NAN,
            ..Default::default()
        }),
    };
    assert!(serde_json::to_string(&io::view_record_to_json(&rec)).is_ok());
    assert!(serde_json::to_string(&io::warnings_to_json(&["".into(), "\u{0}".into()])).is_ok());
    // rig.json text of a rig whose public fields were set by hand: the text is made,
    // and write_rig refuses what the reader would refuse
    let mut rig = fuzz_support_rig();
    rig.board.pitch_mm = f64::NAN;
    let _ = io::rig_to_json(&rig);
    assert!(matches!(
        io::write_rig(dir.path().join("rig.json"), &rig),
        Err(Error::InvalidInput(_))
    ));
    let summary = AdjustmentSummary {
        method: String::new(),
        centre_model: "\u{feff}".into(),
        base_board_orientation: None,
        stripe_rms_mm: nan,
        residual_sigma_px: (f64::INFINITY, nan),
        stripe_off_plane: usize::MAX,
    };
    let extra = io::calibration_extra(&summary, &[rec], &[]);
    assert!(serde_json::to_string(&extra).is_ok());
    let _ = io::self_checks_extra(None, None);
}

fn fuzz_support_rig() -> model::Rig {
    io::rig_from_json(Path::new("rig.json"), fuzz_support::RIG_JSON).unwrap()
}

// ---------------------------------------------------------------- pipeline

#[test]
fn pipeline_takes_hostile_datasets() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("twin");
    f.twin.write(&out, &mut |_, _, _| {}).unwrap();
    let root = out.join("calib");
    let ds = model::Dataset::load(&root).unwrap();
    assert!(!ds
        .image_path(Path::new("images/x.png"))
        .as_os_str()
        .is_empty());
    // hand-made datasets: no views, missing images, a 1 x 1 image, every view the same
    let mut variants = vec![];
    let mut none = ds.clone();
    none.views.clear();
    variants.push(("no views", none));
    let mut missing = ds.clone();
    missing.views[1].board_image = "images/nope.png".into();
    variants.push(("missing image", missing));
    let tiny = dir.path().join("tiny.png");
    io::save_gray_png(
        &tiny,
        &AnyGray::U8(GrayImage {
            width: 1,
            height: 1,
            data: vec![9],
        }),
    )
    .unwrap();
    let mut one_px = ds.clone();
    one_px.views[2].laser_image = Some(tiny.clone());
    variants.push(("1x1 laser image", one_px));
    let mut same = ds.clone();
    let v0 = same.views[0].clone();
    for v in same.views.iter_mut() {
        *v = v0.clone();
    }
    variants.push(("every view the same", same));
    let mut wrong_joints = ds.clone();
    wrong_joints.views[0].reading = RobotReading::Joints(vec![0.0; 2]);
    variants.push(("two joint readings", wrong_joints));
    let mut no_robot = ds.clone();
    no_robot.rig.robot = None;
    variants.push(("joints without a robot", no_robot));
    let mut tiny_rig = ds.clone();
    tiny_rig.rig.width = 1;
    tiny_rig.rig.height = 1;
    variants.push(("rig says 1x1", tiny_rig));
    variants.push(("the twin", ds));
    for (what, d) in variants {
        let d2 = d.clone();
        check(&format!("observe_dataset ({what})"), move || {
            pipeline::observe_dataset(&d2, &pipeline::CalibrateOptions::default())
                .map(|(o, w)| (o.len(), w))
        });
        check(&format!("calibrate_dataset_loaded ({what})"), move || {
            pipeline::calibrate_dataset_loaded(&d, &pipeline::CalibrateOptions::default()).map(
                |rep| {
                    let c = rep.calibration;
                    (c.camera, c.laser_plane, c.hand_cam, c.base_board)
                },
            )
        });
    }
    must_err(
        "calibrate_dataset (missing)",
        &pipeline::calibrate_dataset(dir.path().join("none"), &Default::default()).map(|_| ()),
    );
    for m in [pipeline::Method::Paper, pipeline::Method::OneStage] {
        assert_eq!(pipeline::Method::from_name(m.name()).unwrap(), m);
    }
    assert!(pipeline::Method::from_name("").is_err());
}

// ---------------------------------------------------------------- reconstruct

#[test]
fn reconstruction_takes_hostile_values() {
    let f = fixture();
    let truth = f.twin.true_calibration();
    let cam = truth.camera.clone();
    let plane = truth.laser_plane.unwrap();
    for &x in &BAD {
        let (c2, p2) = (cam.clone(), plane);
        probe("Triangulator::new", move || {
            for hc in [Iso3::identity(), iso_bad(x)] {
                for angle in [x, 0.0, 90.0, 1e3] {
                    let r = Triangulator::new(&c2, &p2, &hc, angle);
                    finite_or_err("Triangulator::new", &r.as_ref().map(|t| t.camera().clone()));
                    if let Ok(t) = r {
                        if let Some(p) = t.point_cam_mm(x, x) {
                            assert!(p.iter().all(|v| v.is_finite()), "point_cam_mm({x})");
                        }
                        let mut out = vec![];
                        let mut idx = vec![];
                        let uv = vec![[x, 1.0], [100.0, 100.0], [f64::NAN, f64::NAN]];
                        let drops = t.triangulate_into(&iso_bad(x), &uv, &mut out, &mut idx);
                        let _ = drops.total();
                        assert_eq!(out.len(), idx.len());
                        assert!(
                            out.iter().all(|p| p.iter().all(|v| v.is_finite())),
                            "triangulate_into({x})"
                        );
                    }
                }
            }
            let mut bad_plane = p2;
            bad_plane.normal = Vector3::new(x, 0.0, 0.0);
            bad_plane.d = x;
            finite_or_err(
                "Triangulator::new (hand-made plane)",
                &Triangulator::new(&c2, &bad_plane, &Iso3::identity(), 5.0).map(|_| ()),
            );
        });
    }
    let mut no_plane = truth.clone();
    no_plane.laser_plane = None;
    must_err(
        "Triangulator::from_calibration (no plane)",
        &Triangulator::from_calibration(&no_plane, 5.0).map(|_| ()),
    );
    for uv in [vec![], vec![[f64::NAN, 0.0]], vec![[1e308, -1e308]; 3]] {
        let t = truth.clone();
        check("triangulate", move || {
            reconstruct::triangulate(&t, &iso_bad(f64::NAN), &uv)
        });
    }
    let mut d = reconstruct::DropCounts::default();
    d.add(&reconstruct::DropCounts::default());
    // the reconstructor on hostile images, poses and options
    let mut optss = vec![ReconstructOptions::default()];
    let mut o = ReconstructOptions {
        min_ray_plane_angle_deg: f64::NAN,
        ..Default::default()
    };
    optss.push(o.clone());
    o.min_ray_plane_angle_deg = 5.0;
    o.stripe.max_width_px = 1e30;
    o.stripe.ridge_px = usize::MAX;
    optss.push(o.clone());
    o.stripe = Default::default();
    o.stripe.min_chain = usize::MAX;
    o.stripe.max_width_px = f32::NAN;
    optss.push(o);
    for opts in optss {
        let _ = opts.validate();
        let t = truth.clone();
        probe("Reconstructor", move || {
            let r = reconstruct::Reconstructor::new(&t, &opts);
            finite_or_err("Reconstructor::new", &r.as_ref().map(|r| r.direction()));
            let Ok(mut rec) = r else { return };
            let _ = rec.triangulator().camera();
            let mut out = ScanPoints::default();
            for (what, img) in hostile_images() {
                let v = img.view();
                let Ok(v) = v else { continue };
                let n = format!("frame_joints ({what})");
                for q in [
                    vec![0.0, 0.0, 0.0, 0.0, -90.0, 0.0],
                    vec![],
                    vec![f64::NAN; 6],
                ] {
                    finite_or_err(&n, &rec.frame_joints(v, &q, 0, &mut out));
                }
                finite_or_err(
                    "frame_pose",
                    &rec.frame_pose(v, &iso_bad(f64::NAN), u32::MAX, &mut out),
                );
                finite_or_err(
                    "frame_pose",
                    &rec.frame_pose(v, &Iso3::identity(), 1, &mut out),
                );
                finite_or_err(
                    "frame_reading",
                    &rec.frame_reading(v, &RobotReading::Joints(vec![1.0]), 2, &mut out),
                );
                finite_or_err(
                    "base_hand",
                    &rec.base_hand(&RobotReading::FlangePose(iso_bad(f64::INFINITY))),
                );
            }
            assert!(out
                .points_mm
                .iter()
                .all(|p| p.iter().all(|v| v.is_finite())));
            let mut all = ScanPoints::default();
            all.append(&out);
            assert_eq!(all.len(), out.len());
            let cloud = all.to_cloud();
            assert_eq!(cloud.points.len(), all.len());
            all.clear();
            assert!(all.is_empty());
        });
    }
    // reconstruct_frames: mismatched lengths, no frames, 1 x 1 images
    let imgs = hostile_images();
    let views: Vec<AnyView<'_>> = imgs.iter().filter_map(|(_, g)| g.view().ok()).collect();
    let readings = vec![RobotReading::Joints(vec![0.0, 0.0, 0.0, 0.0, -90.0, 0.0]); views.len()];
    let opts = ReconstructOptions::default();
    for (k, nr) in [
        (0, 0),
        (views.len(), views.len() - 1),
        (views.len(), views.len()),
        (1, 1),
    ] {
        let r = reconstruct::reconstruct_frames(&truth, &views[..k], &readings[..nr], &opts)
            .map(|p| p.points_mm);
        finite_or_err("reconstruct_frames", &r);
    }
    let e = reconstruct::at_frame(
        Error::InvalidInput("x".into()),
        usize::MAX,
        Some(usize::MAX),
    );
    assert!(!e.to_string().is_empty());
    let _ = reconstruct::stripe_direction_from_plane(
        &cam,
        &Plane {
            normal: Vector3::new(f64::NAN, 0.0, 0.0),
            d: 0.0,
        },
    );
    let _ = reconstruct::stripe_direction_from_plane(&cam, &Plane::new(Vector3::z(), 1.0).unwrap());
    // scans from folders that do not hold one
    let dir = tempfile::tempdir().unwrap();
    must_err(
        "load_scan (empty folder)",
        &reconstruct::load_scan(dir.path(), &truth).map(|s| s.frames.len()),
    );
    let scan = model::Scan {
        root: dir.path().to_path_buf(),
        rig: None,
        frames: vec![],
    };
    check("reconstruct_scan (no frames)", move || {
        reconstruct::reconstruct_scan(
            &truth,
            &scan,
            &ReconstructOptions::default(),
            &mut |_, _, _| std::ops::ControlFlow::Continue(()),
        )
        .map(|p| p.points_mm)
    });
}

#[test]
fn fits_take_hostile_points() {
    let sphere: Vec<[f64; 3]> = (0..200)
        .map(|i| {
            let (a, b) = (i as f64 * 0.7, (i % 17) as f64 * 0.15);
            [
                20.0 * a.cos() * b.cos(),
                20.0 * a.sin() * b.cos(),
                20.0 * b.sin() + 100.0,
            ]
        })
        .collect();
    let clouds: Vec<(&str, Vec<[f64; 3]>)> = vec![
        ("empty", vec![]),
        ("one", vec![[1.0, 2.0, 3.0]]),
        (
            "four",
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
        ),
        ("same point", vec![[1.0, 1.0, 1.0]; 50]),
        (
            "collinear",
            (0..50).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect(),
        ),
        (
            "coplanar",
            (0..100)
                .map(|i| [(i % 10) as f64, (i / 10) as f64, 5.0])
                .collect(),
        ),
        ("NaN", vec![[f64::NAN, 0.0, 0.0]; 20]),
        ("one NaN", {
            let mut s = sphere.clone();
            s[3] = [f64::NAN, 1.0, 1.0];
            s
        }),
        (
            "huge",
            vec![
                [1e308, -1e308, 1e308],
                [-1e308, 1e308, 0.0],
                [0.0, 0.0, 1e308],
                [1e308, 0.0, 0.0],
                [0.0, 1e308, 0.0],
            ],
        ),
        ("sphere", sphere),
    ];
    let mut optss = vec![FitOptions::default()];
    optss.push(FitOptions {
        trim_sigma: f64::NAN,
        max_trim_rounds: usize::MAX,
        max_iterations: 0,
        robust_start: true,
        robust_quantile: 2.0,
        diameter_range_mm: Some([f64::NAN, -1.0]),
    });
    optss.push(FitOptions {
        trim_sigma: -1.0,
        robust_quantile: f64::NAN,
        diameter_range_mm: Some([40.0, 10.0]),
        ..FitOptions::default()
    });
    for (what, pts) in clouds {
        for opts in &optss {
            let (p, o) = (pts.clone(), *opts);
            let name = format!("fit_sphere ({what}, {opts:?})");
            check(&name, move || {
                reconstruct::fit_sphere(&p, &o).map(|s| {
                    let fit = s.to_sphere_fit();
                    (fit.diameter_mm, fit.center_mm, fit.rms_mm)
                })
            });
            let (p, o) = (pts.clone(), *opts);
            check(&format!("fit_plane ({what})"), move || {
                reconstruct::fit_plane(&p, &o).map(|f| format!("{f:?}"))
            });
        }
    }
}

// ---------------------------------------------------------------- vision

#[test]
fn vision_takes_hostile_images_and_options() {
    use vision::stripe::*;
    let f = fixture();
    let boards = vec![
        f.twin.board.clone(),
        Board::chessboard(6, 9, 4.0).unwrap(),
        Board::asymmetric_circles(11, 4, 6.0, 2.0).unwrap(),
        Board::circles(2, 2, 5.0, 2.0, 3.0).unwrap(),
    ];
    let mut sopts = vec![StripeOptions::default()];
    for dir in [StripeDirection::Rows, StripeDirection::Cols] {
        sopts.push(StripeOptions {
            direction: dir,
            method: StripeMethod::Centroid,
            ..Default::default()
        });
    }
    let hostile_stripe = StripeOptions {
        ridge_px: usize::MAX,
        min_contrast: f32::NAN,
        max_width_px: 1e30,
        min_width_px: -1.0,
        window_fwhm: f32::INFINITY,
        flank_px: usize::MAX,
        min_chain: 0,
        max_jump_px: f32::NAN,
        ..Default::default()
    };
    let zero_stripe = StripeOptions {
        ridge_px: 0,
        max_width_px: 0.0,
        min_width_px: 0.0,
        window_fwhm: 0.0,
        max_saturated_px: 0,
        ..Default::default()
    };
    for o in [&hostile_stripe, &zero_stripe] {
        let o2 = o.clone();
        let valid = probe("StripeOptions::validate", move || o2.validate().is_ok());
        assert!(!valid, "hostile stripe options accepted: {o:?}");
    }
    sopts.push(hostile_stripe);
    sopts.push(zero_stripe);
    for (what, img) in hostile_images() {
        for opts in &sopts {
            let (i, o) = (img.clone(), opts.clone());
            let name = format!("stripe ({what})");
            probe(&name, move || {
                let Ok(v) = i.view() else { return };
                let s = extract_stripe(v, &o);
                finite_or_err("extract_stripe", &s.as_ref().map(|s| s.points.len()));
                if let Ok(s) = &s {
                    for p in &s.points {
                        assert!(p.u.is_finite() && p.v.is_finite(), "extract_stripe: {p:?}");
                        let _ = (p.near_edge(), p.trusted());
                    }
                    let mut s2 = s.clone();
                    for edges in [
                        vision::stripe::EdgeOptions::default(),
                        vision::stripe::EdgeOptions {
                            lines: usize::MAX,
                            margin_px: f32::NAN,
                            single_image: true,
                            ..Default::default()
                        },
                    ] {
                        let _ = flag_reflectance_edges(&mut s2, v, &edges);
                    }
                    let pts: Vec<[f64; 2]> = s.points.iter().map(|p| [p.u, p.v]).collect();
                    if let Ok(l) = fit_line(&pts) {
                        assert!(l.distance([0.0, 0.0]).is_finite());
                    }
                }
                finite_or_err("resolve_direction", &resolve_direction(v, &o));
                if let Ok(mut ex) = StripeExtractor::new(o.clone()) {
                    let _ = (ex.options(), ex.rejected());
                    let mut out = vec![];
                    finite_or_err("extract_into", &ex.extract_into(v, &mut out));
                }
            });
            // flag_reflectance_edges with a board image of another size
            let (i, o) = (img.clone(), opts.clone());
            let bi = f.board_img.clone();
            probe("flag_reflectance_edges (other size)", move || {
                let (Ok(v), Ok(b)) = (i.view(), bi.view()) else {
                    return;
                };
                if let Ok(mut s) = extract_stripe(v, &o) {
                    let _ =
                        flag_reflectance_edges(&mut s, b, &vision::stripe::EdgeOptions::default());
                }
            });
        }
        for b in &boards {
            let (i, b2) = (img.clone(), b.clone());
            probe(&format!("detect ({what})"), move || {
                let Ok(v) = i.view() else { return };
                let t = vision::target::detect_target(
                    v,
                    &b2,
                    &vision::target::TargetOptions::default(),
                );
                finite_or_err("detect_target", &t.as_ref().map(|t| t.points.len()));
                if let Ok(t) = &t {
                    for p in &t.points {
                        assert!(
                            p.u.is_finite()
                                && p.v.is_finite()
                                && p.row < b2.rows
                                && p.col < b2.cols
                        );
                        let _ = p.flags.has(0xff);
                    }
                }
                let c = vision::circles::detect_circles(v, &b2, &Default::default());
                finite_or_err("detect_circles", &c.as_ref().map(|c| c.circles.len()));
                if let Ok(g) = c {
                    let t = vision::target::TargetDetection::from_circles(&b2, g);
                    let pts: Vec<(usize, usize, f64, f64)> =
                        t.points.iter().map(|p| (p.row, p.col, p.u, p.v)).collect();
                    let _ = vision::target::homography_residuals(&b2, &pts);
                }
                let c = vision::chessboard::detect_chessboard(v, &b2, &Default::default());
                finite_or_err("detect_chessboard", &c.as_ref().map(|c| c.points.len()));
                // hostile detector options
                let mut o = vision::target::TargetOptions::default();
                o.circles.window_frac = f64::NAN;
                o.circles.min_area_px = -1.0;
                o.circles.threshold_ratio = f64::INFINITY;
                o.chessboard.pyramid_levels = usize::MAX;
                o.chessboard.max_window_radius_px = 1e300;
                finite_or_err(
                    "detect_target (options)",
                    &vision::target::detect_target(v, &b2, &o).map(|t| t.points.len()),
                );
            });
        }
    }
    // homography residuals of out-of-range labels, line fits of hostile points
    for b in &boards {
        let _ = vision::target::homography_residuals(b, &[]);
        let _ =
            vision::target::homography_residuals(b, &[(usize::MAX, usize::MAX, f64::NAN, 0.0); 5]);
        let _ = vision::target::homography_residuals(b, &[(0, 0, 1.0, 1.0); 6]);
    }
    for pts in [
        vec![],
        vec![[1.0, 1.0]],
        vec![[1.0, 1.0]; 10],
        vec![[f64::NAN, 0.0]; 5],
        vec![[1e308, -1e308], [-1e308, 1e308], [0.0, 0.0]],
    ] {
        for opts in [
            LineFitOptions::default(),
            LineFitOptions {
                inlier_px: f64::NAN,
                iterations: 0,
                seed: 1,
            },
            LineFitOptions {
                inlier_px: -1.0,
                iterations: 100_000,
                seed: 2,
            },
        ] {
            let p = pts.clone();
            check("fit_line_with", move || {
                fit_line_with(&p, &opts).map(|l| l.distance([0.0, 0.0]))
            });
        }
        check("fit_line", move || {
            fit_line(&pts).map(|l| l.distance([1.0, 1.0]))
        });
    }
    for m in [StripeMethod::Centroid, StripeMethod::Gaussian] {
        assert_eq!(StripeMethod::from_name(m.name()).unwrap(), m);
    }
    for d in [
        StripeDirection::Auto,
        StripeDirection::Rows,
        StripeDirection::Cols,
    ] {
        assert_eq!(StripeDirection::from_name(d.name()).unwrap(), d);
    }
    use vision::circles::CentreMethod;
    for m in [CentreMethod::Gravity, CentreMethod::Ellipse] {
        assert_eq!(CentreMethod::from_name(m.name()).unwrap(), m);
    }
    assert!(CentreMethod::from_name("").is_err() && StripeMethod::from_name("x").is_err());
}

// ---------------------------------------------------------------- added on main meanwhile

/// The public functions the quality-gate and scan-fault work added while this campaign
/// ran: `consensus::{find_consensus, find_shift, pairing::pose_error}`, `Consensus::{agreeing,
/// members, outliers, swapped_pairs}`, `QualityCheck::{pass, fail}`,
/// `pipeline::gates::{determined, converged}`, `reconstruct::BadImage::{name,
/// from_name}`, `ScanPoints::ply_comments`, `io::write_ply_with_comments`, `Scan::read`.
#[test]
fn functions_added_with_the_gates_take_hostile_values() {
    use calib::consensus::pairing::pose_error;
    use calib::consensus::{find_consensus, find_shift, PairingOptions};
    let f = fixture();
    let t = f.twin.true_calibration();
    let poses = f.twin.calibration_poses().unwrap();
    let robot = f.twin.rig().unwrap().robot.unwrap();
    let a: Vec<Iso3> = poses
        .iter()
        .map(|p| robot.forward(&p.q_deg).unwrap())
        .collect();
    let b: Vec<Iso3> = a
        .iter()
        .map(|ai| (ai * t.hand_cam).inverse() * t.base_board)
        .collect();
    let id = Iso3::identity();
    let mut sets = vec![
        ("the twin", a.clone(), b.clone()),
        ("empty", vec![], vec![]),
        ("mismatched", a.clone(), b[..2].to_vec()),
        ("identical", vec![id; 6], vec![id; 6]),
        ("NaN", vec![iso_bad(f64::NAN); 5], b.clone()),
        ("huge", vec![iso_bad(1e308); 5], vec![iso_bad(-1e308); 5]),
    ];
    let mut swapped = (a.clone(), b.clone());
    swapped.0.swap(1, 3);
    sets.push(("two rows swapped", swapped.0, swapped.1));
    for (what, a, b) in sets {
        for opts in [
            PairingOptions::default(),
            PairingOptions {
                factor: f64::NAN,
                min_deg: -1.0,
                min_rel: f64::INFINITY,
                max_subsets: 0,
                coherence: -1.0,
            },
        ] {
            let (a2, b2, o2) = (a.clone(), b.clone(), opts);
            let name = format!("find_consensus ({what})");
            probe(&name, move || {
                if let Ok(c) = find_consensus(&a2, &b2, &o2) {
                    let n = a2.len();
                    assert!(c.members().iter().chain(&c.outliers()).all(|&i| i < n));
                    assert!(c.agreeing() <= n);
                    for (i, j) in c.swapped_pairs() {
                        assert!(i < n && j < n);
                    }
                }
                for rows in [vec![], vec![0, 1, 2], vec![usize::MAX, 7, 1 << 40]] {
                    for agree in [0, 3, usize::MAX] {
                        if let Some(s) = find_shift(&rows, &a2, &b2, agree, &o2) {
                            let _ = format!("{s:?}");
                        }
                    }
                }
                if let (Some(x), Some(y)) = (a2.first(), b2.first()) {
                    let _ = pose_error(x, &iso_bad(f64::NAN), y, y);
                }
            });
        }
    }
    // quality checks and the gates of an adjustment
    let pass = stripecal::model::QualityCheck::pass("", "");
    let fail = stripecal::model::QualityCheck::fail("\u{0}", "x", vec![usize::MAX]);
    assert!(pass.passed && !fail.passed);
    use calib::joint::{joint_adjustment, JointOptions, JointStart};
    let start = JointStart {
        camera: t.camera.clone(),
        plane: t.laser_plane,
        hand_cam: t.hand_cam,
        base_board: t.base_board,
    };
    let adj = joint_adjustment(&f.obs, &f.twin.board, &start, &JointOptions::default()).unwrap();
    let mut nan_cam = t.camera.clone();
    nan_cam.fu = f64::NAN;
    for cam in [t.camera.clone(), nan_cam] {
        for standoff in [None, Some(f64::NAN), Some(-1.0), Some(0.0), Some(1e308)] {
            let c = probe("gates::determined", {
                let (adj, cam) = (adj.clone(), cam.clone());
                move || pipeline::gates::determined(&adj, &cam, standoff)
            });
            assert!(!c.message.is_empty());
        }
    }
    for m in [pipeline::Method::Paper, pipeline::Method::OneStage] {
        let _ = pipeline::gates::converged(&adj, m);
    }
    // scan faults: names, comments, the scan reader without image checks
    for s in ["stop", "skip", "", "STOP"] {
        if let Ok(b) = reconstruct::BadImage::from_name(s) {
            assert_eq!(b.name(), s);
        }
    }
    let mut pts = ScanPoints::default();
    pts.skipped.push(stripecal::BadFrame {
        frame: usize::MAX,
        line: 0,
        path: "a\nb\u{7f}.png".into(),
        reason: "line\r\nbreak\u{0}".into(),
    });
    let comments = pts.ply_comments();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("c.ply");
    // the comments of a skipped frame with control characters still make a valid file
    io::write_ply_with_comments(
        &p,
        &fuzz_support::cloud(4, true),
        io::PlyFormat::Ascii,
        &comments,
    )
    .unwrap();
    assert_eq!(io::read_ply(&p).unwrap().points.len(), 4);
    for bad in ["a\nb", "\r", "end_header\nelement vertex 9", "\u{0}"] {
        let r = io::write_ply_with_comments(
            &p,
            &fuzz_support::cloud(2, false),
            io::PlyFormat::BinaryLittleEndian,
            &[bad.to_string()],
        );
        assert!(matches!(r, Err(Error::InvalidInput(_))), "{bad:?}");
        assert_eq!(
            io::read_ply(&p).unwrap().points.len(),
            4,
            "a refused write changed the file"
        );
    }
    for ok in ["end_header", "element vertex 1", "", "é ü \u{feff}"] {
        io::write_ply_with_comments(
            &p,
            &fuzz_support::cloud(3, false),
            io::PlyFormat::Ascii,
            &[ok.to_string()],
        )
        .unwrap();
        assert_eq!(io::read_ply(&p).unwrap().points.len(), 3, "comment {ok:?}");
    }
    assert!(fuzz_support::temporaries(dir.path()).is_empty());
    must_err(
        "Scan::read (empty folder)",
        &model::Scan::read(dir.path(), None).map(|s| s.frames.len()),
    );
}
