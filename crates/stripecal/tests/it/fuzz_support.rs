//! Shared by the fault campaign's tests (`fuzz_readers.rs`, `fuzz_mutation.rs`,
//! `fuzz_public_api.rs`; docs/robustness.md): the case budget, a deterministic random
//! source, running one case under a deadline with panics caught, valid seed files of
//! every kind, the mutation operators, and the checks every reader result must pass.

#![allow(dead_code)]

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use stripecal::io::{self, PlyFormat, PoseColumns};
use stripecal::model::camera::Projection;
use stripecal::model::image::{AnyGray, GrayImage};
use stripecal::model::{
    Calibration, Cloud, NamedCovariance, Quality, RobotReading, ScanFrame, View,
};
use stripecal::numerics::rng::SplitMix64;
use stripecal::{Camera, DistortionModel, Error, Iso3, Plane, Robot};

/// The fixed seed of the campaign (`STRIPECAL_FUZZ_SEED` overrides it).
pub const DEFAULT_SEED: u64 = 0x5712_CA1F_0013_u64;

/// The seed: `STRIPECAL_FUZZ_SEED` (decimal or 0x-hex) or [`DEFAULT_SEED`].
pub fn seed() -> u64 {
    match std::env::var("STRIPECAL_FUZZ_SEED") {
        Ok(s) => {
            let s = s.trim();
            let parsed = match s.strip_prefix("0x") {
                Some(h) => u64::from_str_radix(h, 16),
                None => s.parse(),
            };
            parsed.unwrap_or_else(|_| panic!("STRIPECAL_FUZZ_SEED={s:?} is not an integer"))
        }
        Err(_) => DEFAULT_SEED,
    }
}

/// The campaign's budget: `STRIPECAL_FUZZ_CASES` (default 1) is a multiplier of each
/// test's default case count, so `STRIPECAL_FUZZ_CASES=20` runs twenty times as many.
pub fn scale() -> usize {
    match std::env::var("STRIPECAL_FUZZ_CASES") {
        Ok(s) => s
            .trim()
            .parse::<usize>()
            .ok()
            .filter(|&n| n > 0)
            .unwrap_or_else(|| panic!("STRIPECAL_FUZZ_CASES={s:?} is not a positive integer")),
        Err(_) => 1,
    }
}

/// `default` cases times [`scale`].
pub fn cases(default: usize) -> usize {
    default.saturating_mul(scale())
}

/// A deterministic random source for one test, mixed from the campaign seed and a
/// per-test stream so tests do not share sequences.
pub fn rng(stream: u64) -> SplitMix64 {
    let mut r = SplitMix64(seed() ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    r.next_u64();
    r
}

/// How long one reader case may take before it counts as a hang (dev profile, a busy
/// 2-core machine: readers of files of a few kB take milliseconds).
pub const READER_DEADLINE: Duration = Duration::from_secs(20);

/// Runs `f` on a worker thread with panics caught; fails the test, naming `case`, when
/// it panics or does not finish within `deadline` (the hung thread is left behind: the
/// test has failed anyway).
pub fn guarded<T: Send + 'static>(
    case: &str,
    deadline: Duration,
    f: impl FnOnce() -> T + Send + 'static,
) -> T {
    let (tx, rx) = mpsc::channel();
    let worker = std::thread::Builder::new()
        .name(format!("fuzz case {case}"))
        .stack_size(8 << 20)
        .spawn(move || {
            let r = catch_unwind(AssertUnwindSafe(f));
            let _ = tx.send(r);
        })
        .expect("spawn a worker thread");
    match rx.recv_timeout(deadline) {
        Ok(Ok(v)) => {
            let _ = worker.join();
            v
        }
        Ok(Err(p)) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            panic!("PANIC in {case}: {msg}")
        }
        Err(_) => panic!("HANG in {case}: no result after {deadline:?}"),
    }
}

/// A reader's error must be typed and name the file it read: [`Error::Format`],
/// [`Error::Image`] or [`Error::Io`] whose path is `file`.
pub fn assert_names_file(case: &str, e: &Error, file: &Path) {
    let path = match e {
        Error::Format { path, .. } | Error::Image { path, .. } | Error::Io { path, .. } => path,
        other => panic!("{case}: a reader returned {other:?}, expected an error naming the file"),
    };
    assert!(
        path == file || file.starts_with(path) || path.starts_with(file.parent().unwrap_or(file)),
        "{case}: error {e} names {}, expected {}",
        path.display(),
        file.display()
    );
    let text = e.to_string();
    assert!(!text.trim().is_empty(), "{case}: empty error message");
}

/// A Format error's location must be non-empty (a line, column or key).
pub fn assert_located(case: &str, e: &Error) {
    if let Error::Format { location, .. } = e {
        assert!(
            !location.is_empty(),
            "{case}: format error without a location: {e}"
        );
    }
}

// ---------------------------------------------------------------- seed data

pub fn camera() -> Camera {
    Camera {
        width: 768,
        height: 576,
        fu: 1271.65,
        fv: 1322.52,
        u0: 346.14,
        v0: 262.6,
        model: DistortionModel::Radial1,
        distortion: [0.0002, 0.0, 0.0, 0.0, 0.0],
        projection: Projection::Brown5,
    }
}

pub fn pose(r: [f64; 3], t: [f64; 3]) -> Iso3 {
    stripecal::model::geometry::iso_from_rotvec(&Vector3::from(r), &Vector3::from(t))
}

/// A complete calibration (robot, covariance, uncertainty, extra keys).
pub fn calibration() -> Calibration {
    let names: Vec<String> = ["camera.fu", "camera.fv", "laser_plane.d_mm"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let matrix =
        nalgebra::DMatrix::from_row_slice(3, 3, &[4.0, 0.5, 0.1, 0.5, 9.0, -0.2, 0.1, -0.2, 0.01]);
    let mut extra = serde_json::Map::new();
    extra.insert("method".into(), serde_json::json!("one-stage"));
    extra.insert(
        "views".into(),
        serde_json::json!([{"view": 0, "used": true}]),
    );
    let mut uncertainty = serde_json::Map::new();
    uncertainty.insert("camera".into(), serde_json::json!({"fu": 2.0, "fv": 3.0}));
    Calibration {
        camera: camera(),
        laser_plane: Some(
            Plane::new(Vector3::new(0.629, -0.0492, 0.7759).normalize(), 79.87).unwrap(),
        ),
        mount: stripecal::model::Mount::Robot,
        hand_cam: pose([-0.3087, 0.2362, 3.0369], [29.19, 5.37, 62.64]),
        base_board: pose([0.01, -0.02, 0.3], [400.0, -20.0, -300.0]),
        robot: Some(Robot::hp3()),
        quality: Quality {
            circle_rms_px: 0.05,
            stripe_rms_px: 0.08,
            views_used: 5,
            checks: Vec::new(),
            accepted_poor: false,
        },
        uncertainty,
        covariance: Some(NamedCovariance {
            parameters: names,
            matrix,
        }),
        records: Default::default(),
        extra,
    }
}

pub const RIG_JSON: &str = r#"{
  "format": "stripecal/rig@1",
  "camera": {"width": 768, "height": 576, "distortion_model": "radial1"},
  "board": {"rows": 8, "cols": 11, "pitch_mm": 5.0, "circle_diameter_mm": 2.5,
            "marker_diameter_mm": 3.5, "markers": [[0,0],[0,1],[1,0]],
            "dark_circles": true},
  "robot": {"name": "MOTOMAN HP3",
            "joints": [{"theta0_deg": 0, "alpha_deg": -90, "a_mm": 100, "d_mm": 0},
                       {"theta0_deg": 90, "alpha_deg": 180, "a_mm": 370, "d_mm": 0},
                       {"theta0_deg": 0, "alpha_deg": -90, "a_mm": 85, "d_mm": 0},
                       {"theta0_deg": 0, "alpha_deg": 90, "a_mm": 0, "d_mm": -380},
                       {"theta0_deg": -180, "alpha_deg": 90, "a_mm": 0, "d_mm": 0},
                       {"theta0_deg": -180, "alpha_deg": 180, "a_mm": 0, "d_mm": -90}]},
  "stripe": {"direction": "auto"}
}
"#;

pub const RIG_CHESS_JSON: &str = r#"{"format": "stripecal/rig@1",
 "camera": {"width": 640, "height": 480},
 "board": {"kind": "chessboard", "rows": 6, "cols": 9, "square_mm": 4.0},
 "stripe": {"direction": "rows"}}
"#;

pub const RIG_ASYM_JSON: &str = r#"{"format": "stripecal/rig@1",
 "camera": {"width": 640, "height": 480, "distortion_model": "opencv5"},
 "board": {"kind": "asymmetric_circles", "rows": 11, "cols": 4, "pitch_mm": 6.0,
           "circle_diameter_mm": 2.0, "dark_circles": false},
 "robot": {"joints": [{"theta0_deg": 0, "alpha_deg": 0, "a_mm": 1, "d_mm": 2}]},
 "stripe": {"direction": "cols"}}
"#;

/// Every named pose convention, plus a few hand-made orders.
pub fn pose_specs() -> Vec<String> {
    let mut v: Vec<String> = io::convention_names()
        .iter()
        .map(|s| s.to_string())
        .collect();
    v.push("qx,qy,qz,qw,z_mm,y_mm,x_mm".into());
    v.push("rx_deg,ry_deg,rz_deg,x_m,y_m,z_m".into());
    v.push("r33,r32,r31,r23,r22,r21,r13,r12,r11,x_mm,y_mm,z_mm".into());
    v
}

pub fn pose_columns(spec: &str) -> PoseColumns {
    PoseColumns::from_spec(&[spec]).unwrap_or_else(|e| panic!("{spec}: {e}"))
}

/// A flange pose from 6 uniform numbers.
pub fn random_pose(r: &mut SplitMix64) -> Iso3 {
    let axis = Vector3::new(r.normal(), r.normal(), r.normal());
    let angle = (r.uniform() * 2.0 - 1.0) * std::f64::consts::PI;
    let q = if axis.norm() > 1e-9 {
        UnitQuaternion::from_scaled_axis(axis.normalize() * angle)
    } else {
        UnitQuaternion::identity()
    };
    let t = Vector3::new(
        (r.uniform() - 0.5) * 2000.0,
        (r.uniform() - 0.5) * 2000.0,
        (r.uniform() - 0.5) * 2000.0,
    );
    Iso3::from_parts(Translation3::from(t), q)
}

pub fn joint_views(n: usize) -> Vec<View> {
    (0..n)
        .map(|i| View {
            line: i + 2,
            board_image: format!("images/view_{i:03}_board.png").into(),
            laser_image: (i % 3 != 2).then(|| format!("images/view_{i:03}_laser.png").into()),
            reading: RobotReading::Joints(vec![
                i as f64 * 1.5,
                -2.0,
                3.25,
                0.5,
                -88.0 + i as f64,
                4.0,
            ]),
        })
        .collect()
}

pub fn flange_views(n: usize, r: &mut SplitMix64) -> Vec<View> {
    (0..n)
        .map(|i| View {
            line: i + 2,
            board_image: format!("images/b{i}.png").into(),
            laser_image: Some(format!("images/l{i}.png").into()),
            reading: RobotReading::FlangePose(random_pose(r)),
        })
        .collect()
}

pub fn scan_frames(n: usize, r: &mut SplitMix64, joints: bool) -> Vec<ScanFrame> {
    (0..n)
        .map(|i| ScanFrame {
            line: i + 2,
            image: format!("images/frame_{i:04}.png").into(),
            reading: if joints {
                RobotReading::Joints(vec![0.0, i as f64 * 0.1, 0.0, 0.0, -90.0, 0.0])
            } else {
                RobotReading::FlangePose(random_pose(r))
            },
        })
        .collect()
}

/// The text a writer produces for `f(path)`, read back from a temporary folder.
pub fn written(name: &str, f: impl FnOnce(&Path) -> stripecal::Result<()>) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    f(&p).unwrap_or_else(|e| panic!("writing the seed {name}: {e}"));
    std::fs::read(&p).unwrap()
}

pub fn cloud(n: usize, extra: bool) -> Cloud {
    let points = (0..n)
        .map(|i| {
            let t = i as f64 * 0.37;
            [t.cos() * 20.0, t.sin() * 20.0 - 0.5, 100.0 + t]
        })
        .collect();
    let properties = if extra {
        vec![
            ("view".to_string(), (0..n).map(|i| (i / 3) as f64).collect()),
            ("u".to_string(), (0..n).map(|i| i as f64 * 1.25).collect()),
        ]
    } else {
        Vec::new()
    };
    Cloud { points, properties }
}

/// A big-endian PLY with a face element, a uchar property and a list, as other tools
/// write them.
pub fn ply_other_writer() -> Vec<u8> {
    let mut out = b"ply\nformat binary_big_endian 1.0\ncomment made by hand\nobj_info x\n\
element vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty uchar intensity\n\
element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        .to_vec();
    for (i, p) in [[0.0f32, 1.0, 2.0], [3.0, 4.0, 5.0], [6.0, 7.0, 8.5]]
        .iter()
        .enumerate()
    {
        for v in p {
            out.extend_from_slice(&v.to_be_bytes());
        }
        out.push(i as u8 * 100);
    }
    out.push(3);
    for k in 0..3i32 {
        out.extend_from_slice(&k.to_be_bytes());
    }
    out
}

pub fn ply_ascii_other() -> Vec<u8> {
    b"ply\r\nformat ascii 1.0\r\nelement vertex 2\r\nproperty double x\r\nproperty double y\r\n\
property double z\r\nproperty int view\r\nelement edge 1\r\nproperty int vertex1\r\n\
property int vertex2\r\nend_header\r\n1 2 3 0\r\n4.5 -5e3 6 1\r\n0 1\r\n"
        .to_vec()
}

/// A small gray gradient with a few dark disks (something for decoders to chew on).
pub fn gray8(w: usize, h: usize) -> GrayImage<u8> {
    let mut data = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let d =
                ((x as f64 - w as f64 / 2.0).powi(2) + (y as f64 - h as f64 / 2.0).powi(2)).sqrt();
            data.push(if d < w as f64 / 5.0 {
                20
            } else {
                (x * 7 + y * 3) as u8 | 0x80
            });
        }
    }
    GrayImage {
        width: w,
        height: h,
        data,
    }
}

pub fn gray16(w: usize, h: usize) -> GrayImage<u16> {
    let g = gray8(w, h);
    GrayImage {
        width: w,
        height: h,
        data: g.data.iter().map(|&v| v as u16 * 257 + 3).collect(),
    }
}

/// Encoded image files of every kind the readers take: (name, bytes).
pub fn image_seeds() -> Vec<(String, Vec<u8>)> {
    use image::{ImageBuffer, ImageFormat, Luma, Rgb};
    let (w, h) = (13u32, 9u32);
    let g8 = gray8(w as usize, h as usize);
    let g16 = gray16(w as usize, h as usize);
    let l8: ImageBuffer<Luma<u8>, Vec<u8>> = ImageBuffer::from_raw(w, h, g8.data.clone()).unwrap();
    let l16: ImageBuffer<Luma<u16>, Vec<u16>> =
        ImageBuffer::from_raw(w, h, g16.data.clone()).unwrap();
    let rgb: ImageBuffer<Rgb<u8>, Vec<u8>> = ImageBuffer::from_fn(w, h, |x, y| {
        Rgb([(x * 19) as u8, (y * 23) as u8, ((x + y) * 5) as u8])
    });
    let enc = |img: &image::DynamicImage, f: ImageFormat| {
        let mut buf = std::io::Cursor::new(Vec::new());
        img.write_to(&mut buf, f).unwrap();
        buf.into_inner()
    };
    let d8 = image::DynamicImage::ImageLuma8(l8);
    let d16 = image::DynamicImage::ImageLuma16(l16);
    let drgb = image::DynamicImage::ImageRgb8(rgb);
    vec![
        ("gray8.png".into(), enc(&d8, ImageFormat::Png)),
        ("gray16.png".into(), enc(&d16, ImageFormat::Png)),
        ("rgb8.png".into(), enc(&drgb, ImageFormat::Png)),
        ("gray8.tif".into(), enc(&d8, ImageFormat::Tiff)),
        ("gray16.tif".into(), enc(&d16, ImageFormat::Tiff)),
        ("rgb8.bmp".into(), enc(&drgb, ImageFormat::Bmp)),
        ("gray8.bmp".into(), enc(&d8, ImageFormat::Bmp)),
        ("gray8.jpg".into(), enc(&d8, ImageFormat::Jpeg)),
        ("rgb8.jpg".into(), enc(&drgb, ImageFormat::Jpeg)),
    ]
}

// ---------------------------------------------------------------- checks of results

/// Covariances equal entry by entry, NaN (a number not determined) equal to NaN.
pub fn same_covariance(a: &Option<NamedCovariance>, b: &Option<NamedCovariance>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            a.parameters == b.parameters
                && a.matrix.shape() == b.matrix.shape()
                && a.matrix
                    .iter()
                    .zip(b.matrix.iter())
                    .all(|(x, y)| x == y || (x.is_nan() && y.is_nan()))
        }
        _ => false,
    }
}

pub fn finite_iso(t: &Iso3) -> bool {
    t.translation.vector.iter().all(|x| x.is_finite())
        && t.rotation.coords.iter().all(|x| x.is_finite())
        && (t.rotation.coords.norm() - 1.0).abs() < 1e-9
}

pub fn reading_is_valid(r: &RobotReading) -> bool {
    match r {
        RobotReading::Joints(q) => !q.is_empty() && q.iter().all(|x| x.is_finite()),
        RobotReading::FlangePose(t) => finite_iso(t),
        RobotReading::Fixed => true,
    }
}

/// An image a reader returned: a positive size and as many pixels.
pub fn image_is_valid(g: &AnyGray) -> bool {
    let (w, h) = g.size();
    let n = match g {
        AnyGray::U8(i) => i.data.len(),
        AnyGray::U16(i) => i.data.len(),
    };
    w > 0 && h > 0 && w.checked_mul(h) == Some(n)
}

/// Files left in `dir` whose name marks a writer's temporary (`.NAME.tmp-...`).
pub fn temporaries(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| {
                    p.file_name()
                        .and_then(|n| n.to_str())
                        .is_some_and(|n| n.contains(".tmp-"))
                })
                .collect()
        })
        .unwrap_or_default()
}

/// Writes `PlyFormat` values both ways for loops.
pub const PLY_FORMATS: [PlyFormat; 2] = [PlyFormat::BinaryLittleEndian, PlyFormat::Ascii];

// ---------------------------------------------------------------- mutations

/// Numbers that break naive parsers.
pub const HOSTILE_NUMBERS: [&str; 22] = [
    "NaN",
    "nan",
    "inf",
    "-inf",
    "Infinity",
    "1e308",
    "-1e308",
    "1e309",
    "-0",
    "-0.0",
    "0",
    "-1",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999",
    "-9223372036854775808",
    "1e-320",
    "0x10",
    "1_000",
    "",
    "9007199254740993",
];

/// One mutation operator applied to `b` at random; returns what it did.
pub fn mutate_once(b: &mut Vec<u8>, r: &mut SplitMix64) -> String {
    let n = b.len();
    let at = |r: &mut SplitMix64, n: usize| if n == 0 { 0 } else { r.below(n + 1).min(n) };
    match r.below(16) {
        0 if n > 0 => {
            let i = r.below(n);
            let bit = r.below(8);
            b[i] ^= 1 << bit;
            format!("flip bit {bit} of byte {i}")
        }
        1 => {
            let i = at(r, n);
            let v = (r.next_u64() & 0xff) as u8;
            b.insert(i, v);
            format!("insert byte {v:#04x} at {i}")
        }
        2 if n > 0 => {
            let i = r.below(n);
            let k = 1 + r.below(8.min(n - i));
            b.drain(i..i + k);
            format!("delete {k} bytes at {i}")
        }
        3 => {
            let i = at(r, n);
            b.truncate(i);
            format!("truncate at {i}")
        }
        4 | 5 => replace_number(b, r),
        6 => line_op(b, r),
        7 => {
            // CRLF line ends (or back)
            if b.windows(2).any(|w| w == b"\r\n") {
                let s: Vec<u8> = String::from_utf8_lossy(b)
                    .replace("\r\n", "\n")
                    .into_bytes();
                *b = s;
                "CRLF -> LF".into()
            } else {
                let mut out = Vec::with_capacity(n + n / 8);
                for &c in b.iter() {
                    if c == b'\n' {
                        out.push(b'\r');
                    }
                    out.push(c);
                }
                *b = out;
                "LF -> CRLF".into()
            }
        }
        8 => {
            // UTF-8 breakage: a lone continuation, an overlong form, a cut sequence
            let bad: &[&[u8]] = &[
                b"\xff",
                b"\xc3",
                b"\x80",
                b"\xe2\x82",
                b"\xc0\xaf",
                b"\xed\xa0\x80",
            ];
            let s = bad[r.below(bad.len())];
            let i = at(r, n);
            b.splice(i..i, s.iter().copied());
            format!("insert invalid UTF-8 {s:?} at {i}")
        }
        9 => field_op(b, r),
        10 => {
            let i = at(r, n);
            b.splice(i..i, "\u{feff}".bytes());
            format!("insert a BOM at {i}")
        }
        11 if n > 0 => {
            // a run of one byte repeated (long lines, huge numbers)
            let i = at(r, n);
            let c = [b'9', b',', b'[', b'{', b'"', b' ', b'\n', b'0'][r.below(8)];
            let k = [16, 300, 5000][r.below(3)];
            b.splice(i..i, std::iter::repeat_n(c, k));
            format!("insert {k} x {:?} at {i}", c as char)
        }
        12 if n > 8 => {
            // overwrite 1..8 bytes with random ones (headers, lengths)
            let i = r.below(n);
            let k = 1 + r.below(8.min(n - i));
            for x in &mut b[i..i + k] {
                *x = (r.next_u64() & 0xff) as u8;
            }
            format!("randomise {k} bytes at {i}")
        }
        13 if n > 8 => {
            // a 32-bit field set to an extreme (binary headers: sizes, offsets)
            let i = r.below(n - 4);
            let v: u32 = [0, 1, 0xffff_ffff, 0x7fff_ffff, 0x8000_0000, 0xffff][r.below(6)];
            let bytes = if r.below(2) == 0 {
                v.to_le_bytes()
            } else {
                v.to_be_bytes()
            };
            b[i..i + 4].copy_from_slice(&bytes);
            format!("set u32 at {i} to {v:#x}")
        }
        14 if n > 0 => {
            // duplicate a chunk
            let i = r.below(n);
            let k = 1 + r.below(64.min(n - i));
            let chunk: Vec<u8> = b[i..i + k].to_vec();
            let j = at(r, n);
            b.splice(j..j, chunk);
            format!("copy {k} bytes from {i} to {j}")
        }
        _ => {
            let i = at(r, n);
            b.truncate(i);
            format!("truncate at {i}")
        }
    }
}

/// 1 to 3 mutations; the description lists them.
pub fn mutate(seed: &[u8], r: &mut SplitMix64) -> (Vec<u8>, String) {
    let mut b = seed.to_vec();
    let k = 1 + r.below(3);
    let ops: Vec<String> = (0..k).map(|_| mutate_once(&mut b, r)).collect();
    (b, ops.join("; "))
}

/// Byte ranges of the numeric tokens of `b` (digits with sign, dot, exponent).
fn number_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            || ((b[i] == b'-' || b[i] == b'.') && b.get(i + 1).is_some_and(|c| c.is_ascii_digit()));
        if starts && (i == 0 || !b[i - 1].is_ascii_alphanumeric() && b[i - 1] != b'_') {
            let s = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_digit()
                    || b[i] == b'.'
                    || b[i] == b'e'
                    || b[i] == b'E'
                    || ((b[i] == b'-' || b[i] == b'+') && matches!(b[i - 1], b'e' | b'E')))
            {
                i += 1;
            }
            spans.push((s, i));
        } else {
            i += 1;
        }
    }
    spans
}

fn replace_number(b: &mut Vec<u8>, r: &mut SplitMix64) -> String {
    replace_number_with(b, r, &HOSTILE_NUMBERS)
}

/// Numbers a file could plausibly hold instead of the right one (the file stays
/// syntactically valid: the mutation reaches the numerics).
pub const PLAUSIBLE_NUMBERS: [&str; 14] = [
    "0", "1", "2", "3", "7", "12", "4.9", "0.5", "-90", "180", "1000", "2.5", "-0.001", "45",
];

/// Replaces one numeric token of `b` by one of `choices`; returns what it did.
pub fn replace_number_with(b: &mut Vec<u8>, r: &mut SplitMix64, choices: &[&str]) -> String {
    let spans = number_spans(b);
    if spans.is_empty() {
        return "no number to replace".into();
    }
    let (s, e) = spans[r.below(spans.len())];
    let new = choices[r.below(choices.len())];
    let old = String::from_utf8_lossy(&b[s..e]).to_string();
    b.splice(s..e, new.bytes());
    format!("number {old:?} at {s} -> {new:?}")
}

fn line_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut s = 0;
    for (i, &c) in b.iter().enumerate() {
        if c == b'\n' {
            spans.push((s, i + 1));
            s = i + 1;
        }
    }
    if s < b.len() {
        spans.push((s, b.len()));
    }
    spans
}

fn line_op(b: &mut Vec<u8>, r: &mut SplitMix64) -> String {
    let lines = line_spans(b);
    if lines.is_empty() {
        return "no line".into();
    }
    let i = r.below(lines.len());
    let (s, e) = lines[i];
    match r.below(4) {
        0 => {
            let l = b[s..e].to_vec();
            b.splice(e..e, l);
            format!("duplicate line {}", i + 1)
        }
        1 => {
            b.drain(s..e);
            format!("delete line {}", i + 1)
        }
        2 if lines.len() > 1 => {
            let j = r.below(lines.len());
            let (a, c) = if i < j { (i, j) } else { (j, i) };
            if a == c {
                return "swap a line with itself".into();
            }
            let mut ls: Vec<Vec<u8>> = lines.iter().map(|&(s, e)| b[s..e].to_vec()).collect();
            if !ls[a].ends_with(b"\n") {
                ls[a].push(b'\n');
            }
            if !ls[c].ends_with(b"\n") {
                ls[c].push(b'\n');
            }
            ls.swap(a, c);
            *b = ls.concat();
            format!("swap lines {} and {}", a + 1, c + 1)
        }
        _ => {
            let k = e - s;
            if k > 1 {
                let cut = s + r.below(k);
                b.truncate(cut);
                format!("cut in line {} at byte {cut}", i + 1)
            } else {
                "empty line".into()
            }
        }
    }
}

fn field_op(b: &mut Vec<u8>, r: &mut SplitMix64) -> String {
    // a field (between commas) removed or an extra one added
    let commas: Vec<usize> = b
        .iter()
        .enumerate()
        .filter(|(_, &c)| c == b',')
        .map(|(i, _)| i)
        .collect();
    if commas.is_empty() {
        return "no field".into();
    }
    let i = commas[r.below(commas.len())];
    if r.below(2) == 0 {
        let mut e = i + 1;
        while e < b.len() && !matches!(b[e], b',' | b'\n' | b'\r' | b'}' | b']') {
            e += 1;
        }
        b.drain(i..e);
        format!("remove the field after byte {i}")
    } else {
        let extra: &[&[u8]] = &[
            b",1.5",
            b",",
            b",x",
            b", \"k\": 1",
            b",[]",
            b",{}",
            b",null",
        ];
        let s = extra[r.below(extra.len())];
        b.splice(i..i, s.iter().copied());
        format!("add field {:?} at byte {i}", String::from_utf8_lossy(s))
    }
}
