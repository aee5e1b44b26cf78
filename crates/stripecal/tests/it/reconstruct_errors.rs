//! Bad input to the reconstruction: typed errors that name the frame (and the scan.csv
//! line / image), and nothing appended or written on failure. Tiny synthetic images
//! (64 x 48, one bright vertical stripe), no rendering.

use std::ops::ControlFlow;
use std::path::Path;

use nalgebra::Vector3;
use stripecal::io::{save_gray_png, write_scan_csv};
use stripecal::model::camera::{Camera, DistortionModel, Intrinsics};
use stripecal::model::geometry::{iso_from_rotvec, Plane};
use stripecal::model::image::{AnyGray, GrayImage};
use stripecal::model::image::{AnyView, ImageView};
use stripecal::model::{Calibration, RobotReading, Scan, ScanFrame};
use stripecal::reconstruct::{
    load_scan, reconstruct_frames, reconstruct_scan, BadImage, ReconstructOptions, Reconstructor,
    ScanPoints,
};
use stripecal::{Error, Robot};

const W: usize = 64;
const H: usize = 48;

fn calibration() -> Calibration {
    Calibration {
        camera: Camera::new(
            W as u32,
            H as u32,
            Intrinsics {
                fu: 120.0,
                fv: 120.0,
                u0: 31.5,
                v0: 23.5,
            },
            DistortionModel::Radial1,
            [0.01, 0.0, 0.0, 0.0, 0.0],
        )
        .unwrap(),
        laser_plane: Some(Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap()),
        mount: stripecal::model::Mount::Robot,
        hand_cam: iso_from_rotvec(
            &Vector3::new(-0.3087, 0.2362, 3.0369),
            &Vector3::new(29.19, 5.37, 62.64),
        ),
        base_board: Default::default(),
        robot: Some(Robot::hp3()),
        quality: Default::default(),
        uncertainty: Default::default(),
        covariance: None,
        records: Default::default(),
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

fn noop(_: usize, _: usize, _: usize) -> ControlFlow<()> {
    ControlFlow::Continue(())
}

#[test]
fn scan_folder_errors() {
    let cal = calibration();
    let tmp = tempfile::tempdir().unwrap();
    let opts = ReconstructOptions::default();

    // Empty folder: no scan.csv.
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let e = load_scan(&empty, &cal).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
    assert!(e.to_string().contains("scan.csv"), "{e}");

    // A row naming a missing image: the reconstruction stops before any work.
    let d = tmp.path().join("missing");
    write_scan(
        &d,
        &[("images/a.png", Q.to_vec()), ("images/b.png", Q.to_vec())],
    );
    write_frame(&d.join("images/a.png"), H);
    let scan = load_scan(&d, &cal).unwrap();
    let mut calls = 0;
    let e = reconstruct_scan(&cal, &scan, &opts, &mut |_, _, _| {
        calls += 1;
        ControlFlow::Continue(())
    })
    .unwrap_err();
    let Error::BadImage(b) = &e else {
        panic!("expected BadImage, got {e:?}")
    };
    assert_eq!(
        (b.frame, b.line, b.reason.as_str()),
        (1, 3, "does not exist")
    );
    assert!(b.path.ends_with("images/b.png"), "{e}");
    assert!(
        e.to_string().contains("frame 1 (scan.csv line 3)") && e.to_string().contains("b.png"),
        "{e}"
    );
    assert_eq!(calls, 0, "work started before the missing image was found");
    // Scan::load (the Python load_scan) still checks every image.
    let e = Scan::load(&d, cal.robot.as_ref()).unwrap_err();
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
    let e = reconstruct_scan(&cal, &scan, &opts, &mut noop).unwrap_err();
    let m = e.to_string();
    assert!(matches!(e, Error::BadImage(_)), "{e}");
    assert!(
        m.contains("frame 1")
            && m.contains("line 3")
            && m.contains("b.png")
            && m.contains("64 x 40"),
        "{m}"
    );

    // An image that is not an image.
    std::fs::write(d.join("images/b.png"), b"not a png").unwrap();
    let e = reconstruct_scan(&cal, &scan, &opts, &mut noop).unwrap_err();
    assert!(matches!(e, Error::BadImage(_)), "{e}");
    assert!(
        e.to_string().contains("b.png") && e.to_string().contains("cannot be decoded"),
        "{e}"
    );

    // The good scan works and reports progress.
    save_gray_png(
        d.join("images/b.png"),
        &AnyGray::U8(stripe_image(W, H, 31.0)),
    )
    .unwrap();
    let scan: Scan = load_scan(&d, &cal).unwrap();
    let mut calls = Vec::new();
    let sp = reconstruct_scan(&cal, &scan, &opts, &mut |a, b, c| {
        calls.push((a, b, c));
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(calls.first(), Some(&(0, 2, 0)));
    assert_eq!(calls.last().map(|c| (c.0, c.2)), Some((2, sp.len())));
    assert!(sp.frame.contains(&0) && sp.frame.contains(&1));
    assert!(sp.skipped.is_empty());
}

/// `N_FRAMES` frames, each with its stripe at another column, in `dir`; frame `k`'s
/// points are then told apart by their `u`.
const N_FRAMES: usize = 7;

fn write_good_scan(dir: &Path) {
    let names: Vec<String> = (0..N_FRAMES).map(|k| format!("images/f{k}.png")).collect();
    let rows: Vec<(&str, Vec<f64>)> = names.iter().map(|n| (n.as_str(), Q.to_vec())).collect();
    write_scan(dir, &rows);
    for (k, name) in names.iter().enumerate() {
        let img = stripe_image(W, H, 20.0 + 3.0 * k as f64);
        save_gray_png(dir.join(name), &AnyGray::U8(img)).unwrap();
    }
}

/// A baseline JPEG of `img` (quality 90).
fn jpeg_of(img: &GrayImage<u8>) -> Vec<u8> {
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90)
        .encode(
            &img.data,
            img.width as u32,
            img.height as u32,
            image::ExtendedColorType::L8,
        )
        .unwrap();
    out
}

/// The offset of the first byte after a JPEG's start-of-scan segment.
fn scan_start(b: &[u8]) -> usize {
    let mut i = 2;
    while i + 4 <= b.len() {
        let len = u16::from_be_bytes([b[i + 2], b[i + 3]]) as usize;
        if b[i + 1] == 0xDA {
            return i + 2 + len;
        }
        i += 2 + len;
    }
    panic!("no start of scan")
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xedb8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// `png` with a byte of its compressed image data changed (the 6th byte of the first
/// IDAT's zlib stream: inside the first rows) and every chunk's CRC recomputed, so only
/// the zlib checksum can tell.
fn damaged_png(png: &[u8]) -> Vec<u8> {
    let mut b = png.to_vec();
    let mut pos = 8;
    while pos + 12 <= b.len() {
        let len = u32::from_be_bytes([b[pos], b[pos + 1], b[pos + 2], b[pos + 3]]) as usize;
        if &b[pos + 4..pos + 8] == b"IDAT" {
            b[pos + 8 + 6.min(len - 1)] ^= 0x10;
            let crc = crc32(&b[pos + 4..pos + 8 + len]);
            b[pos + 8 + len..pos + 12 + len].copy_from_slice(&crc.to_be_bytes());
            break;
        }
        pos += 12 + len;
    }
    b
}

/// A PNG whose header says `w x h` (8-bit gray) with almost no data.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut b = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        b.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut c = kind.to_vec();
        c.extend_from_slice(data);
        b.extend_from_slice(&c);
        b.extend_from_slice(&crc32(&c).to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(
        b"IDAT",
        &[0x78, 0x9c, 0x63, 0x00, 0x00, 0x00, 0x01, 0x00, 0x01],
    );
    chunk(b"IEND", &[]);
    b
}

fn opts_with(on_bad_image: BadImage) -> ReconstructOptions {
    ReconstructOptions {
        on_bad_image,
        ..ReconstructOptions::default()
    }
}

/// The clean scan's points without frame `k`'s.
fn without_frame(sp: &ScanPoints, k: u32) -> Vec<[f64; 3]> {
    sp.points_mm
        .iter()
        .zip(&sp.frame)
        .filter(|(_, &f)| f != k)
        .map(|(p, _)| *p)
        .collect()
}

/// Each kind of bad image in the middle of a scan: `Stop` names it (frame, line, file,
/// what is wrong) and returns nothing; `Skip` gives the other frames' points exactly and
/// lists the frame.
#[test]
fn bad_image_in_the_middle_stops_or_is_skipped() {
    let cal = calibration();
    let tmp = tempfile::tempdir().unwrap();
    let clean_dir = tmp.path().join("clean");
    write_good_scan(&clean_dir);
    let clean = reconstruct_scan(
        &cal,
        &load_scan(&clean_dir, &cal).unwrap(),
        &ReconstructOptions::default(),
        &mut noop,
    )
    .unwrap();
    for k in 0..N_FRAMES as u32 {
        assert!(clean.frame.contains(&k), "frame {k} has no points");
    }

    let k = 3usize; // the bad frame; scan.csv line k + 2
    let png = std::fs::read(clean_dir.join("images/f3.png")).unwrap();
    let png2 = png.clone();
    type Spoil = Box<dyn Fn(&Path)>;
    let cases: Vec<(&str, Spoil, &str)> = vec![
        (
            "truncated",
            Box::new(move |p: &Path| std::fs::write(p, &png[..png.len() / 2]).unwrap()),
            "cannot be decoded",
        ),
        (
            "random bytes",
            Box::new(|p: &Path| {
                let mut x = 0x2545_f491_4f6c_dd1du64;
                let bytes: Vec<u8> = (0..3000)
                    .map(|_| {
                        x ^= x << 13;
                        x ^= x >> 7;
                        x ^= x << 17;
                        x as u8
                    })
                    .collect();
                std::fs::write(p, bytes).unwrap()
            }),
            "cannot be decoded",
        ),
        (
            "empty file",
            Box::new(|p: &Path| std::fs::write(p, b"").unwrap()),
            "cannot be decoded",
        ),
        (
            "missing",
            Box::new(|p: &Path| std::fs::remove_file(p).unwrap()),
            "does not exist",
        ),
        (
            "a folder",
            Box::new(|p: &Path| {
                std::fs::remove_file(p).unwrap();
                std::fs::create_dir(p).unwrap()
            }),
            "is a folder, not a file",
        ),
        // issue 39, fault 6: a truncated JPEG decoded with its missing rows made up
        (
            "truncated JPEG",
            Box::new(|p: &Path| {
                // cut inside the image data: the decoder alone makes up the rest
                let jpeg = jpeg_of(&stripe_image(W, H, 29.0));
                let data = scan_start(&jpeg);
                std::fs::write(p, &jpeg[..data + (jpeg.len() - data) / 2]).unwrap()
            }),
            "truncated JPEG",
        ),
        // issue 39, fault 7: compressed data damaged under intact chunk CRCs
        (
            "damaged PNG",
            Box::new(move |p: &Path| std::fs::write(p, damaged_png(&png2)).unwrap()),
            "damaged PNG",
        ),
        // refused from its header, never decoded
        (
            "huge header",
            Box::new(|p: &Path| std::fs::write(p, png_header_only(30000, 30000)).unwrap()),
            "is 30000 x 30000 pixels, the calibrated camera is 64 x 48",
        ),
        (
            "wrong size",
            Box::new(|p: &Path| write_frame(p, H - 8)),
            "is 64 x 40 pixels, the calibrated camera is 64 x 48",
        ),
        (
            "16-bit among 8-bit",
            Box::new(|p: &Path| {
                let i = stripe_image(W, H, 29.0);
                let wide = GrayImage {
                    width: i.width,
                    height: i.height,
                    data: i.data.iter().map(|&v| v as u16 * 257).collect(),
                };
                save_gray_png(p, &AnyGray::U16(wide)).unwrap()
            }),
            "is 16-bit, but 6 of the scan's 7 readable frames are 8-bit",
        ),
    ];
    for (name, spoil, reason) in &cases {
        let d = tmp.path().join(name.replace(' ', "_"));
        write_good_scan(&d);
        spoil(&d.join("images/f3.png"));
        let scan = load_scan(&d, &cal).unwrap();

        let e =
            reconstruct_scan(&cal, &scan, &opts_with(BadImage::Stop), &mut noop).expect_err(name);
        let Error::BadImage(b) = &e else {
            panic!("{name}: expected BadImage, got {e:?}")
        };
        assert_eq!((b.frame, b.line), (k, k + 2), "{name}: {e}");
        assert_eq!(b.path, d.join("images/f3.png"), "{name}");
        assert!(b.reason.contains(reason), "{name}: {e}");
        let m = e.to_string();
        assert!(
            m.starts_with("frame 3 (scan.csv line 5): image ") && m.contains("f3.png"),
            "{name}: {m}"
        );

        let sp = reconstruct_scan(&cal, &scan, &opts_with(BadImage::Skip), &mut noop)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(sp.skipped.len(), 1, "{name}");
        assert_eq!(&sp.skipped[0], b, "{name}: skip and stop disagree");
        assert!(!sp.frame.contains(&(k as u32)), "{name}");
        assert_eq!(sp.points_mm, without_frame(&clean, k as u32), "{name}");
        let comments = sp.ply_comments();
        assert_eq!(comments[0], "skipped_frames 1", "{name}");
        assert!(
            comments[1].starts_with("skipped frame 3 (scan.csv line 5): image "),
            "{name}: {comments:?}"
        );
    }
}

/// Several bad frames are all skipped, in frame order; a scan whose frames are all bad
/// gives no points and lists them all.
#[test]
fn skip_lists_every_bad_frame() {
    let cal = calibration();
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().join("scan");
    write_good_scan(&d);
    std::fs::write(d.join("images/f6.png"), b"GIF89a").unwrap();
    std::fs::remove_file(d.join("images/f0.png")).unwrap();
    write_frame(&d.join("images/f4.png"), 10);
    let scan = load_scan(&d, &cal).unwrap();
    let sp = reconstruct_scan(&cal, &scan, &opts_with(BadImage::Skip), &mut noop).unwrap();
    let frames: Vec<usize> = sp.skipped.iter().map(|b| b.frame).collect();
    assert_eq!(frames, [0, 4, 6]);
    let mut got: Vec<u32> = sp.frame.clone();
    got.dedup();
    assert_eq!(got, [1, 2, 3, 5]);
    // Stop reports the missing file first (looked for before any work).
    let e = reconstruct_scan(&cal, &scan, &opts_with(BadImage::Stop), &mut noop).unwrap_err();
    assert!(
        e.to_string().starts_with("frame 0 (scan.csv line 2)"),
        "{e}"
    );

    for k in 0..N_FRAMES {
        std::fs::write(d.join(format!("images/f{k}.png")), b"").unwrap();
    }
    let sp = reconstruct_scan(&cal, &scan, &opts_with(BadImage::Skip), &mut noop).unwrap();
    assert!(sp.is_empty());
    assert_eq!(sp.skipped.len(), N_FRAMES);
}

/// A progress callback that breaks stops the run at once with `Cancelled`.
#[test]
fn progress_can_cancel() {
    let cal = calibration();
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().join("scan");
    write_good_scan(&d);
    let scan = load_scan(&d, &cal).unwrap();
    for stop_after in [0, 1] {
        let mut calls = 0;
        let e = reconstruct_scan(
            &cal,
            &scan,
            &ReconstructOptions::default(),
            &mut |_, _, _| {
                calls += 1;
                if calls > stop_after {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            },
        )
        .unwrap_err();
        assert!(matches!(e, Error::Cancelled), "{e}");
        assert_eq!(calls, stop_after + 1);
    }
}

#[test]
fn on_bad_image_names() {
    assert_eq!(BadImage::default(), BadImage::Stop);
    for b in [BadImage::Stop, BadImage::Skip] {
        assert_eq!(BadImage::from_name(b.name()).unwrap(), b);
    }
    let e = BadImage::from_name("ignore").unwrap_err();
    assert!(
        matches!(e, Error::InvalidInput(_)) && e.to_string().contains("\"skip\""),
        "{e}"
    );
}

/// The skipped frames go into the PLY header as comments that readers skip; a comment
/// with a line break is refused.
#[test]
fn skipped_frames_in_the_ply_header() {
    use stripecal::io::{read_ply, write_ply_with_comments, PlyFormat};
    let cal = calibration();
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().join("scan");
    write_good_scan(&d);
    std::fs::write(d.join("images/f2.png"), b"\x89PNG\r\n\x1a\n").unwrap();
    let scan = load_scan(&d, &cal).unwrap();
    let sp = reconstruct_scan(&cal, &scan, &opts_with(BadImage::Skip), &mut noop).unwrap();
    let ply = tmp.path().join("cloud.ply");
    for f in [PlyFormat::BinaryLittleEndian, PlyFormat::Ascii] {
        write_ply_with_comments(&ply, &sp.to_cloud(), f, &sp.ply_comments()).unwrap();
        let bytes = std::fs::read(&ply).unwrap();
        let end = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap();
        let header = String::from_utf8(bytes[..end].to_vec()).unwrap();
        assert!(header.contains("\ncomment skipped_frames 1\n"), "{header}");
        assert!(
            header.contains("\ncomment skipped frame 2 (scan.csv line 4): image "),
            "{header}"
        );
        assert_eq!(read_ply(&ply).unwrap().points, sp.points_mm);
    }
    let e = write_ply_with_comments(&ply, &sp.to_cloud(), PlyFormat::Ascii, &["a\nb".into()])
        .unwrap_err();
    assert!(matches!(e, Error::InvalidInput(_)), "{e}");
}
