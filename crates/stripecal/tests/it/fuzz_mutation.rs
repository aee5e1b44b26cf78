//! Deterministic mutation fuzz with a bounded budget (issue 13, acceptance 4;
//! docs/robustness.md), run by `cargo test` in CI.
//!
//! From valid seed files of every kind the readers take (rig.json in three board kinds,
//! views.csv with joint readings and in every pose convention, scan.csv,
//! calibration.json, truth.json, a sphere fit, PLY from this writer and from others,
//! PNG / TIFF / BMP / JPEG images in 8 and 16 bits, gray and colour), each case applies
//! 1 to 3 seeded mutations (bit flips, byte insertion and deletion, truncation, line
//! duplication / deletion / swap, numbers replaced by NaN / inf / 1e308 / -0 / huge
//! integers, fields removed or added, broken UTF-8, CRLF, a BOM, long runs, extreme
//! 32-bit header fields; PNG chunks get their CRC fixed half the time so the mutation
//! reaches the decoder) and asserts:
//!
//! - the reader returns a typed error naming the file (and a line, column or key for
//!   format errors), or a valid value (finite poses, images whose size matches their
//!   pixels, PLY properties as long as the points);
//! - no panic (caught) and no hang (a deadline per case);
//! - a value the reader accepted goes through its writer, which writes over an older
//!   valid file: the destination is then complete and reads back to the same value,
//!   and no temporary file is left; a writer that refuses leaves the old file as it was.
//!
//! Whole dataset folders (a tiny twin rendered once: rig.json, views.csv, images) with
//! one mutated file are loaded with `Dataset::load` and calibrated with
//! `calibrate_dataset` for a few cases (slow: bounded separately).
//!
//! Budget: `STRIPECAL_FUZZ_CASES` (default 1) multiplies every test's default case
//! count; `STRIPECAL_FUZZ_SEED` changes the seed. A failure prints the seed, the case
//! number, the seed file and the mutations, so `STRIPECAL_FUZZ_SEED=... cargo test
//! --test it fuzz_mutation::` reproduces it.

mod fuzz_faults;
use crate::fuzz_support;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use fuzz_support::*;
use stripecal::io::{self, PlyFormat};
use stripecal::model::{Calibration, Cloud, Dataset, Scan};
use stripecal::numerics::rng::SplitMix64;
use stripecal::pipeline::{calibrate_dataset, CalibrateOptions};
use stripecal::{Error, Robot};

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Rig,
    Views,
    Scan,
    Calibration,
    Truth,
    SphereFit,
    Ply,
    Image,
}

struct SeedFile {
    kind: Kind,
    name: String,
    bytes: Vec<u8>,
}

fn seed_files() -> Vec<SeedFile> {
    let mut r = rng(1);
    let mut out = Vec::new();
    let mut add = |kind, name: &str, bytes: Vec<u8>| {
        out.push(SeedFile {
            kind,
            name: name.to_string(),
            bytes,
        })
    };
    add(Kind::Rig, "rig.json", RIG_JSON.as_bytes().to_vec());
    add(Kind::Rig, "rig.json", RIG_CHESS_JSON.as_bytes().to_vec());
    add(Kind::Rig, "rig.json", RIG_ASYM_JSON.as_bytes().to_vec());
    add(
        Kind::Views,
        "views.csv",
        written("views.csv", |p| io::write_views_csv(p, &joint_views(4))),
    );
    for spec in pose_specs() {
        let views = flange_views(3, &mut r);
        let cols = pose_columns(&spec);
        add(
            Kind::Views,
            "views.csv",
            written("views.csv", |p| io::write_views_csv_with(p, &views, &cols)),
        );
    }
    let frames = scan_frames(4, &mut r, true);
    add(
        Kind::Scan,
        "scan.csv",
        written("scan.csv", |p| io::write_scan_csv(p, &frames)),
    );
    let frames = scan_frames(3, &mut r, false);
    let ros = pose_columns("ros");
    add(
        Kind::Scan,
        "scan.csv",
        written("scan.csv", |p| io::write_scan_csv_with(p, &frames, &ros)),
    );
    add(
        Kind::Calibration,
        "calibration.json",
        io::calibration_to_json(&calibration()).into_bytes(),
    );
    let mut no_plane = calibration();
    no_plane.laser_plane = None;
    no_plane.robot = None;
    no_plane.covariance = None;
    add(
        Kind::Calibration,
        "calibration.json",
        io::calibration_to_json(&no_plane).into_bytes(),
    );
    let c = calibration();
    let truth = stripecal::model::Truth {
        camera: c.camera.clone(),
        laser_plane: c.laser_plane.unwrap(),
        hand_cam: c.hand_cam,
        base_board: c.base_board,
        robot: c.robot.clone(),
        sphere: Some(stripecal::model::Sphere {
            center_mm: nalgebra::Vector3::new(1.0, 2.0, 3.0),
            diameter_mm: 44.8614,
        }),
        working_range_mm: Some([80.0, 130.0]),
        extra: serde_json::Map::new(),
    };
    add(
        Kind::Truth,
        "truth.json",
        io::truth_to_json(&truth).into_bytes(),
    );
    let fit = stripecal::model::SphereFit {
        diameter_mm: 44.86,
        center_mm: nalgebra::Vector3::new(1.0, 2.0, 3.0),
        rms_mm: 0.01,
        points: 100,
        outliers: 2,
        extra: serde_json::Map::new(),
    };
    add(
        Kind::SphereFit,
        "sphere.json",
        io::sphere_fit_to_json(&fit).into_bytes(),
    );
    for (f, name) in [
        (PlyFormat::BinaryLittleEndian, "cloud.ply"),
        (PlyFormat::Ascii, "cloud.ply"),
    ] {
        add(
            Kind::Ply,
            name,
            written(name, |p| io::write_ply(p, &cloud(6, true), f)),
        );
    }
    add(Kind::Ply, "cloud.ply", ply_other_writer());
    add(Kind::Ply, "cloud.ply", ply_ascii_other());
    for (name, bytes) in image_seeds() {
        add(Kind::Image, &name, bytes);
    }
    out
}

// ---------------------------------------------------------------- PNG CRC

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

/// Recomputes the CRC of every complete PNG chunk, so a mutation inside a chunk
/// reaches the decoder instead of failing the checksum.
fn fix_png_crcs(b: &mut [u8]) {
    let mut pos = 8;
    while pos + 12 <= b.len() {
        let len = u32::from_be_bytes([b[pos], b[pos + 1], b[pos + 2], b[pos + 3]]) as usize;
        let Some(end) = (pos + 8).checked_add(len) else {
            return;
        };
        if end + 4 > b.len() {
            return;
        }
        let crc = crc32(&b[pos + 4..end]);
        b[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        pos = end + 4;
    }
}

// ---------------------------------------------------------------- one case

/// Reads `path` as `kind`; on success checks the value and sends it through its writer
/// (over an older valid file); returns a short outcome for the statistics.
fn run_case(case: &str, kind: Kind, path: &Path, writer_dir: &Path) -> &'static str {
    let p = path.to_path_buf();
    let wd = writer_dir.to_path_buf();
    let c = case.to_string();
    let outcome = guarded(case, READER_DEADLINE, move || -> Result<(), Error> {
        match kind {
            Kind::Rig => {
                let rig = io::read_rig(&p)?;
                rewrite(
                    &c,
                    &wd,
                    "rig.json",
                    RIG_JSON.as_bytes(),
                    |d| io::write_rig(d, &rig),
                    |d| {
                        assert_eq!(io::read_rig(d).unwrap(), rig, "{c}: rig re-read");
                    },
                );
            }
            Kind::Views => {
                let robot = Robot::hp3();
                let views = match io::read_views_csv(&p, Some(&robot)) {
                    Ok(v) => v,
                    Err(_) => io::read_views_csv(&p, None)?,
                };
                for v in &views {
                    assert!(
                        reading_is_valid(&v.reading),
                        "{c}: invalid reading {:?}",
                        v.reading
                    );
                }
                if !views.is_empty() {
                    rewrite(
                        &c,
                        &wd,
                        "views.csv",
                        b"old",
                        |d| io::write_views_csv(d, &views),
                        |d| {
                            let back = io::read_views_csv(d, None).unwrap();
                            assert_eq!(back.len(), views.len(), "{c}");
                        },
                    );
                }
            }
            Kind::Scan => {
                let frames = io::read_scan_csv(&p, None)?;
                for f in &frames {
                    assert!(
                        reading_is_valid(&f.reading),
                        "{c}: invalid reading {:?}",
                        f.reading
                    );
                }
                if !frames.is_empty() {
                    rewrite(
                        &c,
                        &wd,
                        "scan.csv",
                        b"old",
                        |d| io::write_scan_csv(d, &frames),
                        |d| {
                            assert_eq!(
                                io::read_scan_csv(d, None).unwrap().len(),
                                frames.len(),
                                "{c}"
                            );
                        },
                    );
                }
            }
            Kind::Calibration => {
                let cal = io::read_calibration(&p)?;
                check_calibration(&c, &cal);
                let old = io::calibration_to_json(&calibration());
                rewrite(
                    &c,
                    &wd,
                    "calibration.json",
                    old.as_bytes(),
                    |d| io::write_calibration(d, &cal),
                    |d| {
                        let back = io::read_calibration(d).unwrap();
                        assert_eq!(back.camera, cal.camera, "{c}: calibration re-read");
                        assert!(same_covariance(&back.covariance, &cal.covariance), "{c}");
                    },
                );
            }
            Kind::Truth => {
                let t = io::read_truth(&p)?;
                assert!(finite_iso(&t.hand_cam) && finite_iso(&t.base_board), "{c}");
                rewrite(
                    &c,
                    &wd,
                    "truth.json",
                    b"{}",
                    |d| io::write_truth(d, &t),
                    |d| {
                        assert_eq!(io::read_truth(d).unwrap().camera, t.camera, "{c}");
                    },
                );
            }
            Kind::SphereFit => {
                let f = io::read_sphere_fit(&p)?;
                rewrite(
                    &c,
                    &wd,
                    "sphere.json",
                    b"{}",
                    |d| io::write_sphere_fit(d, &f),
                    |d| {
                        assert_eq!(io::read_sphere_fit(d).unwrap(), f, "{c}");
                    },
                );
            }
            Kind::Ply => {
                let cl = io::read_ply(&p)?;
                for (n, v) in &cl.properties {
                    assert_eq!(v.len(), cl.points.len(), "{c}: property {n}");
                }
                rewrite(
                    &c,
                    &wd,
                    "out.ply",
                    b"ply\n",
                    |d| io::write_ply(d, &cl, PlyFormat::BinaryLittleEndian),
                    |d| {
                        let back = io::read_ply(d).unwrap();
                        assert_eq!(back.points.len(), cl.points.len(), "{c}");
                        assert!(same_cloud(&back, &cl), "{c}: PLY re-read differs");
                    },
                );
            }
            Kind::Image => {
                let g = io::load_gray(&p)?;
                assert!(image_is_valid(&g), "{c}: image size and pixels disagree");
                rewrite(
                    &c,
                    &wd,
                    "out.png",
                    b"old",
                    |d| io::save_gray_png(d, &g),
                    |d| {
                        assert_eq!(io::load_gray(d).unwrap(), g, "{c}: PNG re-read");
                    },
                );
            }
        }
        Ok(())
    });
    match outcome {
        Ok(()) => "ok",
        Err(e) => {
            assert_names_file(case, &e, path);
            assert_located(case, &e);
            "error"
        }
    }
}

fn same_cloud(a: &Cloud, b: &Cloud) -> bool {
    let same = |x: f64, y: f64| x.to_bits() == y.to_bits();
    a.points.len() == b.points.len()
        && a.points
            .iter()
            .zip(&b.points)
            .all(|(p, q)| (0..3).all(|k| same(p[k], q[k])))
        && a.properties.len() == b.properties.len()
        && a.properties
            .iter()
            .zip(&b.properties)
            .all(|((n, v), (m, w))| n == m && v.iter().zip(w).all(|(x, y)| same(*x, *y)))
}

fn check_calibration(case: &str, c: &Calibration) {
    c.camera
        .validate()
        .unwrap_or_else(|e| panic!("{case}: accepted an invalid camera: {e}"));
    assert!(finite_iso(&c.hand_cam), "{case}: non-finite hand_cam");
    assert!(finite_iso(&c.base_board), "{case}: non-finite base_board");
    if let Some(p) = &c.laser_plane {
        assert!(
            p.d.is_finite() && p.d > 0.0 && (p.normal.norm() - 1.0).abs() < 1e-12,
            "{case}"
        );
    }
}

/// Writes over an older file `old` at `dir/name` with `write`. Success: the file is
/// complete (`check` reads it back). Failure: a typed error and the old file as it was.
/// Either way no temporary is left in `dir`.
fn rewrite(
    case: &str,
    dir: &Path,
    name: &str,
    old: &[u8],
    write: impl FnOnce(&Path) -> stripecal::Result<()>,
    check: impl FnOnce(&Path),
) {
    let dest = dir.join(name);
    std::fs::write(&dest, old).unwrap();
    match write(&dest) {
        Ok(()) => check(&dest),
        Err(e) => {
            assert_eq!(
                std::fs::read(&dest).unwrap(),
                old,
                "{case}: a refused write changed {name} ({e})"
            );
        }
    }
    let tmp = temporaries(dir);
    assert!(tmp.is_empty(), "{case}: temporaries left: {tmp:?}");
}

// ---------------------------------------------------------------- the file campaign

#[test]
fn mutated_files_give_typed_errors_or_valid_values() {
    let seeds = seed_files();
    let n = cases(12000);
    let master = seed();
    let mut r = rng(2);
    let dir = tempfile::tempdir().unwrap();
    let wdir = tempfile::tempdir().unwrap();
    let started = Instant::now();
    let mut ok = 0usize;
    let mut per_kind = std::collections::BTreeMap::<String, (usize, usize)>::new();
    for i in 0..n {
        // round robin over the seeds, so every kind gets its share
        let s = &seeds[i % seeds.len()];
        let (mut bytes, what) = mutate(&s.bytes, &mut r);
        let png = s.name.ends_with(".png");
        let fixed = png && r.below(2) == 0;
        if fixed {
            fix_png_crcs(&mut bytes);
        }
        let path = dir.path().join(&s.name);
        std::fs::write(&path, &bytes).unwrap();
        let case = format!(
            "STRIPECAL_FUZZ_SEED={master:#x} case {i} of {n}: {} seed #{} ({:?}), mutations [{what}]{}",
            s.name,
            i % seeds.len(),
            s.kind,
            if fixed { ", PNG CRCs fixed" } else { "" }
        );
        let outcome = run_case(&case, s.kind, &path, wdir.path());
        let e = per_kind.entry(format!("{:?}", s.kind)).or_default();
        if outcome == "ok" {
            ok += 1;
            e.0 += 1;
        } else {
            e.1 += 1;
        }
    }
    println!(
        "{n} mutated files in {:.1} s: {ok} read, {} refused; per kind (read, refused): {per_kind:?}",
        started.elapsed().as_secs_f64(),
        n - ok
    );
    // A campaign where every mutation is refused (or accepted) tests little.
    assert!(ok > 0 && ok < n, "{ok} of {n} accepted");
}

/// Every seed is valid as it is (so the mutations start from files the readers take).
#[test]
fn unmutated_seeds_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let wdir = tempfile::tempdir().unwrap();
    for (i, s) in seed_files().iter().enumerate() {
        let path = dir.path().join(&s.name);
        std::fs::write(&path, &s.bytes).unwrap();
        let case = format!("seed #{i} {}", s.name);
        assert_eq!(run_case(&case, s.kind, &path, wdir.path()), "ok", "{case}");
    }
}

// ---------------------------------------------------------------- hostile image headers

/// Builds a PNG whose IHDR says `w x h` (CRC correct) followed by a tiny IDAT.
fn png_with_size(w: u32, h: u32, depth: u8, colour: u8) -> Vec<u8> {
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
    ihdr.extend_from_slice(&[depth, colour, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(
        b"IDAT",
        &[0x78, 0x9c, 0x63, 0x00, 0x00, 0x00, 0x01, 0x00, 0x01],
    );
    chunk(b"IEND", &[]);
    b
}

fn bmp_with_size(w: i32, h: i32, bpp: u16) -> Vec<u8> {
    let mut b = b"BM".to_vec();
    b.extend_from_slice(&(54u32 + 16).to_le_bytes());
    b.extend_from_slice(&[0; 4]);
    b.extend_from_slice(&54u32.to_le_bytes());
    b.extend_from_slice(&40u32.to_le_bytes());
    b.extend_from_slice(&w.to_le_bytes());
    b.extend_from_slice(&h.to_le_bytes());
    b.extend_from_slice(&1u16.to_le_bytes());
    b.extend_from_slice(&bpp.to_le_bytes());
    b.extend_from_slice(&[0; 24]);
    b.extend_from_slice(&[0x55; 16]);
    b
}

fn tiff_with_size(w: u32, h: u32, bits: u16) -> Vec<u8> {
    // little-endian TIFF, one IFD: width, height, bits, compression 1, photometric 1,
    // strip offsets, rows per strip, strip byte counts
    let mut b = b"II*\0".to_vec();
    b.extend_from_slice(&8u32.to_le_bytes());
    let entries: [(u16, u16, u32); 8] = [
        (256, 4, w),
        (257, 4, h),
        (258, 3, bits as u32),
        (259, 3, 1),
        (262, 3, 1),
        (273, 4, 200),
        (278, 4, h),
        (279, 4, 16),
    ];
    b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, ty, v) in entries {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&1u32.to_le_bytes());
        if ty == 3 {
            b.extend_from_slice(&(v as u16).to_le_bytes());
            b.extend_from_slice(&[0, 0]);
        } else {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b.extend_from_slice(&0u32.to_le_bytes());
    b.resize(216, 0x80);
    b
}

fn jpeg_with_size(w: u16, h: u16) -> Vec<u8> {
    let mut b = vec![0xff, 0xd8];
    // SOF0: 8-bit, h x w, one component
    b.extend_from_slice(&[0xff, 0xc0, 0x00, 0x0b, 0x08]);
    b.extend_from_slice(&h.to_be_bytes());
    b.extend_from_slice(&w.to_be_bytes());
    b.extend_from_slice(&[0x01, 0x01, 0x11, 0x00]);
    b.extend_from_slice(&[0xff, 0xd9]);
    b
}

/// Headers that claim huge (or zero, or negative) sizes: an error, never an attempt to
/// allocate what the header says (an allocation failure would abort the process).
#[test]
fn huge_and_empty_image_headers_are_errors() {
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    for (w, h) in [
        (0x7fff_ffff, 0x7fff_ffff),
        (0xffff_ffff, 1),
        (1, 0xffff_ffff),
        (100_000, 100_000),
        (32768, 32768),
        (32769, 1),
        (0, 0),
        (0, 5),
    ] {
        for (depth, colour) in [(8, 0), (16, 0), (8, 2), (16, 6), (1, 0), (8, 3)] {
            files.push((
                format!("png {w}x{h} d{depth} c{colour}"),
                png_with_size(w, h, depth, colour),
            ));
        }
        files.push((format!("tiff {w}x{h}"), tiff_with_size(w, h, 8)));
        files.push((format!("tiff16 {w}x{h}"), tiff_with_size(w, h, 16)));
    }
    for (w, h) in [
        (i32::MAX, i32::MAX),
        (i32::MIN, 1),
        (1, i32::MIN),
        (65535, -65535),
        (0, 0),
        (40000, 40000),
    ] {
        for bpp in [8, 24, 32, 1, 16] {
            files.push((format!("bmp {w}x{h} {bpp}bpp"), bmp_with_size(w, h, bpp)));
        }
    }
    for (w, h) in [(65535, 65535), (0, 0), (0, 1), (65535, 1)] {
        files.push((format!("jpeg {w}x{h}"), jpeg_with_size(w, h)));
    }
    let dir = tempfile::tempdir().unwrap();
    for (i, (what, bytes)) in files.into_iter().enumerate() {
        let p = dir.path().join(format!("img{i}.bin"));
        std::fs::write(&p, &bytes).unwrap();
        let p2 = p.clone();
        let case = format!("header {what}");
        match guarded(&case, READER_DEADLINE, move || io::load_gray(&p2)) {
            Ok(g) => {
                // a header this small cannot carry a large image
                assert!(image_is_valid(&g), "{case}");
                let (w, h) = g.size();
                assert!(
                    w * h <= 1 << 16,
                    "{case}: decoded {w}x{h} from {} bytes",
                    bytes.len()
                );
            }
            Err(e) => {
                assert_names_file(&case, &e, &p);
                assert!(matches!(e, Error::Image { .. }), "{case}: {e:?}");
            }
        }
    }
}

// ---------------------------------------------------------------- writers

/// Writers given invalid values (NaN, bad names, mismatched lengths, empty sets) or an
/// impossible destination (a folder, a missing folder) refuse with a typed error and
/// leave the destination as it was; writers given valid values leave a complete file.
#[test]
fn writers_refuse_cleanly_or_write_completely() {
    let mut r = rng(3);
    let n = cases(200);
    let dir = tempfile::tempdir().unwrap();
    let hostile = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        -1.0,
        0.0,
        -0.0,
        1e308,
        5e-324,
    ];
    for i in 0..n {
        let case = format!("STRIPECAL_FUZZ_SEED={:#x} writer case {i}", seed());
        let x = hostile[r.below(hostile.len())];
        // a calibration with one field made hostile
        let mut c = calibration();
        match r.below(9) {
            0 => c.camera.fu = x,
            1 => c.camera.u0 = x,
            2 => c.camera.distortion[r.below(5)] = x,
            3 => c.quality.circle_rms_px = x,
            4 => {
                if let Some(p) = c.laser_plane.as_mut() {
                    p.d = x;
                }
            }
            5 => {
                if let Some(rb) = c.robot.as_mut() {
                    rb.joints[r.below(6)].a_mm = x;
                }
            }
            6 => c.hand_cam.translation.vector[r.below(3)] = x,
            7 => {
                if let Some(cov) = c.covariance.as_mut() {
                    cov.matrix[(r.below(3), r.below(3))] = x;
                }
            }
            _ => c.camera.width = 0,
        }
        let old = io::calibration_to_json(&calibration());
        rewrite(
            &case,
            dir.path(),
            "calibration.json",
            old.as_bytes(),
            |d| io::write_calibration(d, &c),
            |d| {
                let back = io::read_calibration(d).unwrap_or_else(|e| {
                    panic!("{case}: the writer wrote what the reader refuses: {e}")
                });
                assert_eq!(back.camera, c.camera, "{case}");
            },
        );
        // a cloud with a hostile value, name or length
        let mut cl = cloud(5, true);
        match r.below(5) {
            0 => cl.points[r.below(5)][r.below(3)] = x,
            1 => cl.properties[0].0 = ["", "x", "a b", "u", "é"][r.below(5)].to_string(),
            2 => cl.properties[1].1.pop().map(|_| ()).unwrap_or(()),
            3 => cl.points.clear(),
            _ => cl.properties[1].1[0] = x,
        }
        for f in PLY_FORMATS {
            rewrite(
                &case,
                dir.path(),
                "cloud.ply",
                b"ply\nold",
                |d| io::write_ply(d, &cl, f),
                |d| {
                    let back = io::read_ply(d).unwrap_or_else(|e| {
                        panic!("{case}: the writer wrote what the reader refuses: {e}")
                    });
                    assert_eq!(back.points.len(), cl.points.len(), "{case}");
                },
            );
        }
        // views with a hostile reading or name
        let mut views = joint_views(3);
        match r.below(4) {
            0 => {
                if let stripecal::model::RobotReading::Joints(q) = &mut views[1].reading {
                    q[r.below(6)] = x;
                }
            }
            1 => {
                views[2].board_image =
                    ["a,b.png", "a\"b", " lead.png", "", "x\ny"][r.below(5)].into()
            }
            2 => views[0].reading = stripecal::model::RobotReading::Joints(vec![1.0]),
            _ => views.clear(),
        }
        rewrite(
            &case,
            dir.path(),
            "views.csv",
            b"old,views\n",
            |d| io::write_views_csv(d, &views),
            |d| {
                let back = io::read_views_csv(d, None).unwrap_or_else(|e| {
                    panic!("{case}: the writer wrote what the reader refuses: {e}")
                });
                assert_eq!(back.len(), views.len(), "{case}");
            },
        );
    }
    // impossible destinations: a folder, a missing folder, an empty name
    let c = calibration();
    let folder = dir.path().join("a_folder");
    std::fs::create_dir(&folder).unwrap();
    std::fs::write(folder.join("keep.txt"), b"kept").unwrap();
    let e = io::write_calibration(&folder, &c).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
    assert_eq!(std::fs::read(folder.join("keep.txt")).unwrap(), b"kept");
    assert!(
        temporaries(dir.path()).is_empty(),
        "a temporary was left beside a folder target"
    );
    let missing = dir.path().join("no/such/folder/calibration.json");
    assert!(matches!(
        io::write_calibration(&missing, &c),
        Err(Error::Io { .. })
    ));
    assert!(!dir.path().join("no").exists());
    assert!(matches!(
        io::write_atomic(Path::new(""), b"x"),
        Err(Error::Io { .. })
    ));
    assert!(matches!(
        io::write_atomic(dir.path().join(".."), b"x"),
        Err(Error::Io { .. })
    ));
}

/// Concurrent writers of one file and a concurrent reader: the reader only ever sees
/// one complete version (never a mix or a prefix), and no temporary is left.
#[test]
fn concurrent_atomic_writes_are_never_seen_half_written() {
    let dir = tempfile::tempdir().unwrap();
    let dest = dir.path().join("cloud.ply");
    let versions: Vec<Cloud> = (0..4).map(|k| cloud(200 + 50 * k, k % 2 == 0)).collect();
    io::write_ply(&dest, &versions[0], PlyFormat::Ascii).unwrap();
    let rounds = cases(15);
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    std::thread::scope(|s| {
        for (k, v) in versions.iter().enumerate() {
            let dest = dest.clone();
            s.spawn(move || {
                for _ in 0..rounds {
                    let f = if k % 2 == 0 {
                        PlyFormat::Ascii
                    } else {
                        PlyFormat::BinaryLittleEndian
                    };
                    io::write_ply(&dest, v, f).unwrap();
                }
            });
        }
        let done2 = done.clone();
        let dest2 = dest.clone();
        let versions2 = &versions;
        let reader = s.spawn(move || {
            let mut reads = 0;
            while !done2.load(std::sync::atomic::Ordering::Relaxed) || reads < 5 {
                let c = io::read_ply(&dest2).unwrap_or_else(|e| panic!("read {reads}: {e}"));
                assert!(
                    versions2.iter().any(|v| v.points.len() == c.points.len()),
                    "read {reads}: {} points is no version written",
                    c.points.len()
                );
                reads += 1;
            }
            reads
        });
        // writers finish first (scope joins them at the end; signal after a while)
        std::thread::sleep(Duration::from_millis(50));
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        assert!(reader.join().unwrap() >= 5);
    });
    assert!(temporaries(dir.path()).is_empty());
}

// ---------------------------------------------------------------- whole datasets

/// A tiny twin (half-size camera, `poses` poses, no scan) written to a temporary
/// folder: the folder and its calibration dataset.
fn tiny_twin(poses: usize, seed: u64) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let cfg = stripecal_sim::SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({
            "camera": {"width": 384, "height": 288, "fu": 635.825, "fv": 661.26,
                       "u0": 172.82, "v0": 131.05},
            "poses": {"count": poses},
            "seed": seed,
            "scan": {"enabled": false}
        }))
        .unwrap();
    let twin = stripecal_sim::Twin::new(cfg).unwrap();
    twin.write(dir.path(), &mut |_, _, _| {}).unwrap();
    let calib = dir.path().join("calib");
    (dir, calib)
}

/// A tiny twin (half-size camera, 5 poses, no scan) rendered once per test binary.
fn twin_dataset() -> &'static PathBuf {
    static DIR: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &DIR.get_or_init(|| tiny_twin(5, 7)).1
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let t = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &t);
        } else {
            std::fs::copy(e.path(), &t).unwrap();
        }
    }
}

/// How long one calibration of the tiny twin may take (dev profile, busy machine).
const CALIBRATION_DEADLINE: Duration = Duration::from_secs(120);

/// The errors of a dataset-level call must be typed; file errors must name a file of
/// the dataset.
fn check_dataset_error(case: &str, e: &Error, root: &Path) {
    match e {
        Error::Format { path, .. } | Error::Image { path, .. } | Error::Io { path, .. } => {
            assert!(
                path.starts_with(root),
                "{case}: {e} names a file outside the dataset"
            );
        }
        Error::BadImage(f) => {
            assert!(
                f.path.starts_with(root),
                "{case}: {e} names a file outside the dataset"
            );
        }
        Error::Cancelled => panic!("{case}: cancelled, but nothing asked to stop"),
        // a quality gate refused the calibration: a typed error that says why
        Error::Quality(_)
        | Error::InvalidInput(_)
        | Error::Degenerate(_)
        | Error::Detection(_)
        | Error::NotConverged { .. } => {}
    }
    assert_located(case, e);
}

/// Rewrites the PNG at `p` with hostile but decodable content; returns what it did.
fn mutate_pixels(p: &Path, r: &mut SplitMix64) -> String {
    use stripecal::model::image::{AnyGray, GrayImage};
    let AnyGray::U8(mut g) = io::load_gray(p).unwrap() else {
        panic!("the twin writes 8-bit images");
    };
    let (w, h) = (g.width, g.height);
    let (x0, y0) = (r.below(w), r.below(h));
    let (x1, y1) = ((x0 + 1 + r.below(w)).min(w), (y0 + 1 + r.below(h)).min(h));
    let what = match r.below(8) {
        0 => {
            g.data.fill(0);
            "all black".to_string()
        }
        1 => {
            g.data.fill(255);
            "all white".to_string()
        }
        2 => {
            for v in g.data.iter_mut() {
                *v = (r.next_u64() & 0xff) as u8;
            }
            "uniform noise".to_string()
        }
        3 => {
            for y in y0..y1 {
                g.data[y * w + x0..y * w + x1].fill(if r.below(2) == 0 { 0 } else { 255 });
            }
            format!("rectangle {x0}..{x1} x {y0}..{y1} filled")
        }
        4 => {
            // another size than the rig says
            let (nw, nh) = (1 + r.below(w * 2), 1 + r.below(h * 2));
            let data = (0..nw * nh)
                .map(|k| g.data[(k / nw % h) * w + k % nw % w])
                .collect();
            g = GrayImage {
                width: nw,
                height: nh,
                data,
            };
            format!("resized to {nw} x {nh}")
        }
        5 => {
            g = GrayImage {
                width: 1,
                height: 1,
                data: vec![128],
            };
            "1 x 1".to_string()
        }
        6 => {
            // rows shifted (a torn frame)
            let k = r.below(w);
            for y in y0..y1 {
                g.data[y * w..(y + 1) * w].rotate_left(k);
            }
            format!("rows {y0}..{y1} shifted by {k}")
        }
        _ => {
            let deep = AnyGray::U16(GrayImage {
                width: w,
                height: h,
                data: g.data.iter().map(|&v| v as u16 * 257).collect(),
            });
            io::save_gray_png(p, &deep).unwrap();
            return "as 16-bit".to_string();
        }
    };
    io::save_gray_png(p, &AnyGray::U8(g)).unwrap();
    what
}

/// Half the time byte-level mutations, half the time 1 to 3 numbers replaced by
/// plausible ones (the file stays valid and the change reaches the calibration).
fn mutate_text(b: &[u8], r: &mut SplitMix64) -> (Vec<u8>, String) {
    if r.below(2) == 0 {
        return mutate(b, r);
    }
    let mut out = b.to_vec();
    let k = 1 + r.below(3);
    let ops: Vec<String> = (0..k)
        .map(|_| replace_number_with(&mut out, r, &PLAUSIBLE_NUMBERS))
        .collect();
    (out, ops.join("; "))
}

#[test]
fn mutated_dataset_folders_load_and_calibrate_or_fail_typed() {
    let src = twin_dataset();
    // the unmutated twin calibrates (the seed is valid)
    let base = calibrate_dataset(src, &CalibrateOptions::default())
        .unwrap_or_else(|e| panic!("the unmutated tiny twin does not calibrate: {e}"));
    assert!(base.calibration.quality.circle_rms_px < 0.5);

    let views_text = std::fs::read(src.join("views.csv")).unwrap();
    let rig_text = std::fs::read(src.join("rig.json")).unwrap();
    let mut images: Vec<PathBuf> = std::fs::read_dir(src.join("images"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    images.sort();
    let mut r = rng(4);
    let n = cases(48);
    for i in 0..n {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("calib");
        copy_dir(src, &root);
        let (what, target): (String, PathBuf) = match i % 4 {
            3 => {
                // a decodable image with hostile content
                let img = &images[r.below(images.len())];
                let t = root.join("images").join(img.file_name().unwrap());
                let m = mutate_pixels(&t, &mut r);
                (
                    format!("image {}: {m}", img.file_name().unwrap().to_string_lossy()),
                    t,
                )
            }
            0 => {
                let img = &images[r.below(images.len())];
                let (mut b, m) = mutate(&std::fs::read(img).unwrap(), &mut r);
                if r.below(2) == 0 {
                    fix_png_crcs(&mut b);
                }
                let t = root.join("images").join(img.file_name().unwrap());
                std::fs::write(&t, b).unwrap();
                (
                    format!("image {}: {m}", img.file_name().unwrap().to_string_lossy()),
                    t,
                )
            }
            1 => {
                let (b, m) = mutate_text(&views_text, &mut r);
                std::fs::write(root.join("views.csv"), b).unwrap();
                (format!("views.csv: {m}"), root.join("views.csv"))
            }
            _ => {
                let (b, m) = mutate_text(&rig_text, &mut r);
                std::fs::write(root.join("rig.json"), b).unwrap();
                (format!("rig.json: {m}"), root.join("rig.json"))
            }
        };
        let case = format!(
            "STRIPECAL_FUZZ_SEED={:#x} dataset case {i} of {n}: {what}",
            seed()
        );
        let root2 = root.clone();
        let loaded = guarded(&case, READER_DEADLINE, move || Dataset::load(&root2));
        let _ = target;
        match loaded {
            Err(e) => {
                println!("{case}: load refused: {e}");
                check_dataset_error(&case, &e, &root)
            }
            Ok(ds) => {
                for v in &ds.views {
                    assert!(reading_is_valid(&v.reading), "{case}");
                }
                let started = Instant::now();
                let root3 = root.clone();
                let rep = guarded(&case, CALIBRATION_DEADLINE, move || {
                    calibrate_dataset(&root3, &CalibrateOptions::default())
                });
                let took = started.elapsed().as_secs_f64();
                match rep {
                    Err(e) => {
                        println!("{case}: calibration refused in {took:.1} s: {e}");
                        check_dataset_error(&case, &e, &root)
                    }
                    Ok(rep) => {
                        println!(
                            "{case}: calibrated in {took:.1} s, {} warnings",
                            rep.warnings.len()
                        );
                        let c = &rep.calibration;
                        check_calibration(&case, c);
                        // the result can be saved and read back
                        let out = dir.path().join("calibration.json");
                        io::write_calibration(&out, c)
                            .unwrap_or_else(|e| panic!("{case}: the result cannot be saved: {e}"));
                        io::read_calibration(&out).unwrap();
                    }
                }
            }
        }
        // a scan folder made of the same files loads or fails typed too
        let scan_root = dir.path().join("scan");
        std::fs::create_dir_all(scan_root.join("images")).unwrap();
        let frames = "image,q1,q2,q3,q4,q5,q6\nimages/a.png,0,0,0,0,-90,0\n";
        std::fs::write(scan_root.join("scan.csv"), frames).unwrap();
        std::fs::copy(root.join("rig.json"), scan_root.join("rig.json")).unwrap();
        std::fs::write(scan_root.join("images/a.png"), b"x").unwrap();
        let s2 = scan_root.clone();
        match guarded(&case, READER_DEADLINE, move || Scan::load(&s2, None)) {
            Ok(scan) => assert_eq!(scan.frames.len(), 1, "{case}"),
            Err(e) => check_dataset_error(&case, &e, &scan_root),
        }
    }
}

/// An element without properties and a count of 2^64 - 1 holds no data: read at once
/// (a loop over the count would only finish because an optimiser removes it).
#[test]
fn ply_element_without_properties_and_a_huge_count_is_read_at_once() {
    let dir = tempfile::tempdir().unwrap();
    for enc in ["ascii", "binary_little_endian"] {
        let head = format!(
            "ply\nformat {enc} 1.0\nelement vertex 1\nproperty double x\nproperty double y\n\
             property double z\nelement nothing 18446744073709551615\nend_header\n"
        );
        let mut b = head.into_bytes();
        if enc == "ascii" {
            b.extend_from_slice(b"1 2 3\n");
        } else {
            for v in [1.0f64, 2.0, 3.0] {
                b.extend_from_slice(&v.to_le_bytes());
            }
        }
        let p = dir.path().join(format!("{enc}.ply"));
        std::fs::write(&p, b).unwrap();
        let c = guarded(enc, Duration::from_secs(5), move || io::read_ply(&p)).unwrap();
        assert_eq!(c.points, vec![[1.0, 2.0, 3.0]]);
    }
}

/// write_calibration wrote covariances the reader refuses (asymmetric, negative or
/// infinite, the wrong size): found by the writer campaign, refused now and the old
/// file kept.
#[test]
fn write_calibration_refuses_a_covariance_the_reader_would_refuse() {
    let dir = tempfile::tempdir().unwrap();
    let old = io::calibration_to_json(&calibration());
    for (what, edit) in [
        ("asymmetric", (1usize, 2usize, 1e300)),
        ("negative variance", (0, 0, -1.0)),
        ("infinite", (2, 0, f64::INFINITY)),
        ("NaN without its mirror", (2, 0, f64::NAN)),
    ] {
        let mut c = calibration();
        c.covariance.as_mut().unwrap().matrix[(edit.0, edit.1)] = edit.2;
        let mut refused = false;
        rewrite(
            what,
            dir.path(),
            "calibration.json",
            old.as_bytes(),
            |d| {
                let r = io::write_calibration(d, &c);
                refused = matches!(r, Err(Error::InvalidInput(_)));
                r
            },
            |_| {},
        );
        assert!(refused, "{what}: written");
    }
    // a number the adjustment did not determine (its row and column NaN, as
    // calibrate_dataset reports it) is written as null and read back: found by the
    // dataset campaign, whose calibration of a twin with three joint readings changed
    // could not be saved
    let mut c = calibration();
    let cov = c.covariance.as_mut().unwrap();
    cov.matrix.row_mut(1).fill(f64::NAN);
    cov.matrix.column_mut(1).fill(f64::NAN);
    let p = dir.path().join("nan.json");
    io::write_calibration(&p, &c).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.contains("null"), "{text}");
    let back = io::read_calibration(&p).unwrap();
    assert!(same_covariance(&back.covariance, &c.covariance));
    let mut c = calibration();
    c.covariance.as_mut().unwrap().parameters.pop();
    assert!(matches!(
        io::write_calibration(dir.path().join("c.json"), &c),
        Err(Error::InvalidInput(_))
    ));
}
