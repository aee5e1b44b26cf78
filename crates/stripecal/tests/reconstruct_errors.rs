//! Bad input to the reconstruction: typed errors that name the frame (and the scan.csv
//! line / image), and nothing appended or written on failure. Tiny synthetic images
//! (64 x 48, one bright vertical stripe), no rendering.

use std::path::Path;

use nalgebra::Vector3;
use stripecal::io::{save_gray_png, write_scan_csv};
use stripecal::model::camera::{Camera, DistortionModel};
use stripecal::model::geometry::{iso_from_rotvec, Plane};
use stripecal::model::image::{AnyGray, GrayImage};
use stripecal::model::image::{AnyView, ImageView};
use stripecal::model::{Calibration, RobotReading, Scan, ScanFrame};
use stripecal::reconstruct::{
    load_scan, reconstruct_frames, reconstruct_scan, ReconstructOptions, Reconstructor, ScanPoints,
};
use stripecal::{Error, Robot};

const W: usize = 64;
const H: usize = 48;

fn calibration() -> Calibration {
    Calibration {
        camera: Camera::new(
            W as u32,
            H as u32,
            120.0,
            120.0,
            31.5,
            23.5,
            DistortionModel::Radial1,
            [0.01, 0.0, 0.0, 0.0, 0.0],
        )
        .unwrap(),
        laser_plane: Some(Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap()),
        hand_cam: iso_from_rotvec(
            &Vector3::new(-0.3087, 0.2362, 3.0369),
            &Vector3::new(29.19, 5.37, 62.64),
        ),
        base_board: Default::default(),
        robot: Some(Robot::hp3()),
        quality: Default::default(),
        uncertainty: Default::default(),
        covariance: None,
        extra: Default::default(),
    }
}

#[test]
fn a_calibration_without_a_laser_plane_is_refused_saying_why() {
    let c = Calibration {
        laser_plane: None,
        ..calibration()
    };
    let Err(e) = Reconstructor::new(&c, &ReconstructOptions::default()) else {
        panic!("expected an error: {}", "no laser plane")
    };
    let msg = e.to_string();
    assert!(
        msg.contains("no laser plane") && msg.contains("--laser-only --from"),
        "{msg}"
    );
}

/// A dark image with a Gaussian stripe along the columns at `u = col`.
fn stripe_image(w: usize, h: usize, col: f64) -> GrayImage<u8> {
    let mut img = GrayImage::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let d = x as f64 - col;
            img.data[y * w + x] = (10.0 + 200.0 * (-d * d / (2.0 * 1.2 * 1.2)).exp()) as u8;
        }
    }
    img
}

const Q: [f64; 6] = [0.0, 0.0, 0.0, 0.0, -90.0, 0.0];

fn view(img: &GrayImage<u8>) -> AnyView<'_> {
    AnyView::U8(ImageView::from_slice(&img.data, img.width, img.height).unwrap())
}

#[test]
fn good_frame_gives_points() {
    let cal = calibration();
    let mut rec = Reconstructor::new(&cal, &ReconstructOptions::default()).unwrap();
    let img = stripe_image(W, H, 30.3);
    let mut out = ScanPoints::default();
    let n = rec.frame_joints(view(&img), &Q, 0, &mut out).unwrap();
    assert!(n > 30, "{n} points");
    assert!(out.u_px.iter().all(|u| (u - 30.3).abs() < 0.05));
}

/// A flange-pose reading (controllers that report `T_base_hand`) gives the same points
/// as the joint readings it comes from; so does a calibration without a robot.
#[test]
fn flange_pose_equals_joints() {
    let cal = calibration();
    let img = stripe_image(W, H, 28.6);
    let mut rec = Reconstructor::new(&cal, &ReconstructOptions::default()).unwrap();
    let (mut a, mut b) = (ScanPoints::default(), ScanPoints::default());
    rec.frame_reading(view(&img), &RobotReading::Joints(Q.to_vec()), 3, &mut a)
        .unwrap();
    let pose = Robot::hp3().forward(&Q).unwrap();
    let mut no_robot = cal.clone();
    no_robot.robot = None;
    let mut rec2 = Reconstructor::new(&no_robot, &ReconstructOptions::default()).unwrap();
    rec2.frame_reading(view(&img), &RobotReading::FlangePose(pose), 3, &mut b)
        .unwrap();
    assert!(!a.is_empty());
    assert_eq!(a, b);
}

#[test]
fn per_frame_errors_name_the_frame_and_append_nothing() {
    let cal = calibration();
    let mut rec = Reconstructor::new(&cal, &ReconstructOptions::default()).unwrap();
    let img = stripe_image(W, H, 30.0);
    let mut out = ScanPoints::default();
    rec.frame_joints(view(&img), &Q, 0, &mut out).unwrap();
    let before = out.clone();

    let e = rec
        .frame_joints(view(&img), &Q[..5], 7, &mut out)
        .unwrap_err();
    assert!(matches!(e, Error::InvalidInput(_)), "{e}");
    assert!(
        e.to_string().contains("frame 7") && e.to_string().contains("5 joint readings"),
        "{e}"
    );

    let mut q = Q;
    q[2] = f64::NAN;
    let e = rec.frame_joints(view(&img), &q, 2, &mut out).unwrap_err();
    assert!(matches!(e, Error::InvalidInput(_)), "{e}");
    assert!(
        e.to_string().contains("frame 2") && e.to_string().contains("q3"),
        "{e}"
    );

    let small = stripe_image(32, H, 20.0);
    let e = rec.frame_joints(view(&small), &Q, 1, &mut out).unwrap_err();
    assert!(matches!(e, Error::InvalidInput(_)), "{e}");
    assert!(
        e.to_string().contains("frame 1") && e.to_string().contains("32 x 48"),
        "{e}"
    );

    let pose = stripecal::Iso3::translation(f64::NAN, 0.0, 0.0);
    let e = rec.frame_pose(view(&img), &pose, 4, &mut out).unwrap_err();
    assert!(e.to_string().contains("frame 4"), "{e}");

    assert_eq!(out, before, "a failed frame appended points");

    // No robot in the calibration: joints cannot be used.
    let mut cal2 = cal.clone();
    cal2.robot = None;
    let mut rec2 = Reconstructor::new(&cal2, &ReconstructOptions::default()).unwrap();
    let e = rec2.frame_joints(view(&img), &Q, 5, &mut out).unwrap_err();
    assert!(
        e.to_string().contains("frame 5") && e.to_string().contains("no robot"),
        "{e}"
    );
}

#[test]
fn batch_errors_name_the_first_bad_frame() {
    let cal = calibration();
    let good = stripe_image(W, H, 30.0);
    let small = stripe_image(40, H, 20.0);
    let views = [view(&good), view(&good), view(&small), view(&good)];
    let mut readings = vec![RobotReading::Joints(Q.to_vec()); 4];
    readings[3] = RobotReading::Joints(vec![0.0; 3]);
    let e =
        reconstruct_frames(&cal, &views, &readings, &ReconstructOptions::default()).unwrap_err();
    assert!(e.to_string().contains("frame 2"), "{e}");
    let e = reconstruct_frames(&cal, &views[..3], &readings, &ReconstructOptions::default())
        .unwrap_err();
    assert!(e.to_string().contains("3 images but 4"), "{e}");
    let ok = reconstruct_frames(
        &cal,
        &views[..2],
        &readings[..2],
        &ReconstructOptions::default(),
    )
    .unwrap();
    assert_eq!(ok.frame.iter().filter(|&&f| f == 1).count() * 2, ok.len());
}

/// A `W` x `h` stripe image (stripe at column 30) written as PNG to `path`.
fn write_frame(path: &Path, h: usize) {
    save_gray_png(path, &AnyGray::U8(stripe_image(W, h, 30.0))).unwrap();
}

fn write_scan(dir: &Path, frames: &[(&str, Vec<f64>)]) {
    std::fs::create_dir_all(dir.join("images")).unwrap();
    let rows: Vec<ScanFrame> = frames
        .iter()
        .enumerate()
        .map(|(i, (name, q))| ScanFrame {
            line: i + 2,
            image: name.into(),
            reading: RobotReading::Joints(q.clone()),
        })
        .collect();
    write_scan_csv(dir.join("scan.csv"), &rows).unwrap();
}

#[test]
fn scan_folder_errors() {
    let cal = calibration();
    let tmp = tempfile::tempdir().unwrap();
    let noop = &mut |_: usize, _: usize, _: usize| {};

    // Empty folder: no scan.csv.
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let e = load_scan(&empty, &cal).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
    assert!(e.to_string().contains("scan.csv"), "{e}");

    // A row naming a missing image.
    let d = tmp.path().join("missing");
    write_scan(
        &d,
        &[("images/a.png", Q.to_vec()), ("images/b.png", Q.to_vec())],
    );
    write_frame(&d.join("images/a.png"), H);
    let e = load_scan(&d, &cal).unwrap_err();
    assert!(matches!(e, Error::Format { .. }), "{e}");
    assert!(
        e.to_string().contains("line 3") && e.to_string().contains("b.png"),
        "{e}"
    );

    // Joint columns that do not match the calibration's robot.
    let d = tmp.path().join("joints");
    write_scan(&d, &[("images/a.png", vec![0.0; 5])]);
    write_frame(&d.join("images/a.png"), H);
    let e = load_scan(&d, &cal).unwrap_err();
    assert!(matches!(e, Error::Format { .. }), "{e}");

    // An image of the wrong size: the error names the frame, the line and the image.
    let d = tmp.path().join("size");
    write_scan(
        &d,
        &[("images/a.png", Q.to_vec()), ("images/b.png", Q.to_vec())],
    );
    write_frame(&d.join("images/a.png"), H);
    write_frame(&d.join("images/b.png"), 40);
    let scan = load_scan(&d, &cal).unwrap();
    let e = reconstruct_scan(&cal, &scan, &ReconstructOptions::default(), noop).unwrap_err();
    let m = e.to_string();
    assert!(matches!(e, Error::InvalidInput(_)), "{e}");
    assert!(
        m.contains("frame 1") && m.contains("line 3") && m.contains("b.png"),
        "{m}"
    );

    // An image that is not an image.
    std::fs::write(d.join("images/b.png"), b"not a png").unwrap();
    let e = reconstruct_scan(&cal, &scan, &ReconstructOptions::default(), noop).unwrap_err();
    assert!(
        matches!(e, Error::Image { .. } | Error::Format { .. }),
        "{e}"
    );
    assert!(e.to_string().contains("b.png"), "{e}");

    // The good scan works and reports progress.
    save_gray_png(
        d.join("images/b.png"),
        &AnyGray::U8(stripe_image(W, H, 31.0)),
    )
    .unwrap();
    let scan: Scan = load_scan(&d, &cal).unwrap();
    let mut calls = Vec::new();
    let sp = reconstruct_scan(
        &cal,
        &scan,
        &ReconstructOptions::default(),
        &mut |a, b, c| calls.push((a, b, c)),
    )
    .unwrap();
    assert_eq!(calls.first(), Some(&(0, 2, 0)));
    assert_eq!(calls.last().map(|c| (c.0, c.2)), Some((2, sp.len())));
    assert!(sp.frame.contains(&0) && sp.frame.contains(&1));
}
