//! Flange-pose columns in controller conventions (spec/DATASET.md, views.csv): every
//! convention against an independent construction, round trips on many random poses
//! (gimbal lock, half turns, column permutations), views.csv / scan.csv in every
//! convention and column order, the writers, and every malformed header or row as a
//! typed error naming the line.
//!
//! Round trips compare ROTATION MATRICES (entries to 1e-12) and translations (1e-12
//! relative), never angles or quaternion signs: q and -q are one rotation, and at gimbal
//! lock only a sum or difference of two angles is defined.

use std::f64::consts::PI;
use std::fs;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Translation3, UnitQuaternion, Vector3};
use stripecal::io::{
    convention_columns, convention_names, matrix_to_pose, pose_to_matrix, read_scan_csv,
    read_views_csv, write_scan_csv_with, write_views_csv, write_views_csv_with, PoseColumns,
};
use stripecal::model::{RobotReading, ScanFrame, View};
use stripecal::{Error, Iso3, Robot};

// ---------------------------------------------------------------- helpers

/// SplitMix64: a small deterministic generator (no dependency).
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.unit()
    }
    fn normal(&mut self) -> f64 {
        let u = self.unit().max(1e-300);
        (-2.0 * u.ln()).sqrt() * (2.0 * PI * self.unit()).cos()
    }
    /// A uniformly distributed rotation and a translation within +-2 m.
    fn pose(&mut self) -> Iso3 {
        let q =
            nalgebra::Quaternion::new(self.normal(), self.normal(), self.normal(), self.normal());
        let t = Vector3::new(
            self.range(-2000.0, 2000.0),
            self.range(-2000.0, 2000.0),
            self.range(-2000.0, 2000.0),
        );
        Iso3::from_parts(Translation3::from(t), UnitQuaternion::from_quaternion(q))
    }
    /// A random permutation of 0..n.
    fn permutation(&mut self, n: usize) -> Vec<usize> {
        let mut p: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            let j = (self.next_u64() % (i as u64 + 1)) as usize;
            p.swap(i, j);
        }
        p
    }
}

fn rot(t: &Iso3) -> Matrix3<f64> {
    t.rotation.to_rotation_matrix().into_inner()
}

/// Rotation matrices equal entry by entry to `tol`, translations to `tol` relative.
#[track_caller]
fn assert_same_pose(a: &Iso3, b: &Iso3, tol: f64, what: &str) {
    let dr = (rot(a) - rot(b)).abs().max();
    let ta = a.translation.vector;
    let tb = b.translation.vector;
    let dt = (ta - tb).norm() / ta.norm().max(tb.norm()).max(1.0);
    assert!(
        dr <= tol && dt <= tol,
        "{what}: |dR| = {dr:e}, |dt|/|t| = {dt:e}\n{a:?}\n{b:?}"
    );
}

fn rx(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

fn ry(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

fn rz(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Rodrigues' formula, written out.
fn rodrigues(r: [f64; 3]) -> Matrix3<f64> {
    let v = Vector3::from(r);
    let theta = v.norm();
    if theta == 0.0 {
        return Matrix3::identity();
    }
    let k = v / theta;
    let kx = Matrix3::new(0.0, -k.z, k.y, k.z, 0.0, -k.x, -k.y, k.x, 0.0);
    Matrix3::identity() + kx * theta.sin() + kx * kx * (1.0 - theta.cos())
}

/// The quaternion-to-matrix formula (unit quaternion), written out.
fn quat_matrix(w: f64, x: f64, y: f64, z: f64) -> Matrix3<f64> {
    Matrix3::new(
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        1.0 - 2.0 * (x * x + y * y),
    )
}

fn cols(spec: &str) -> Vec<&str> {
    spec.split(',').collect()
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    fs::write(&p, text).unwrap();
    p
}

/// Asserts `e` is `Error::Format` on `file` at a location containing `loc`, with a
/// message containing every one of `msgs`.
#[track_caller]
fn assert_format(e: Error, file: &str, loc: &str, msgs: &[&str]) {
    let text = e.to_string();
    match &e {
        Error::Format {
            path,
            location,
            message,
        } => {
            assert!(path.ends_with(file), "{text}");
            assert!(
                location.contains(loc),
                "location {location:?} !~ {loc:?}: {text}"
            );
            for m in msgs {
                assert!(message.contains(m), "message {message:?} !~ {m:?}");
            }
        }
        other => panic!("expected Error::Format, got {other:?}"),
    }
}

#[track_caller]
fn assert_invalid(e: Error, msgs: &[&str]) {
    match &e {
        Error::InvalidInput(m) => {
            for s in msgs {
                assert!(m.contains(s), "{m:?} !~ {s:?}");
            }
        }
        other => panic!("expected Error::InvalidInput, got {other:?}"),
    }
}

/// Every shorthand's columns, plus the same conventions with other units / orders.
fn all_layouts() -> Vec<Vec<&'static str>> {
    let mut out: Vec<Vec<&'static str>> = convention_names()
        .into_iter()
        .map(|n| convention_columns(n).unwrap())
        .collect();
    out.push(cols("qx,qy,qz,qw,x_mm,y_mm,z_mm"));
    out.push(cols("z_m,rx_deg,y_m,ry_deg,x_m,rz_deg"));
    out.push(cols("c_deg,b_deg,a_deg,x_m,y_m,z_m"));
    out.push(cols("r_deg,p_deg,w_deg,z_mm,y_mm,x_mm"));
    out.push(cols("r33,r32,r31,r23,r22,r21,r13,r12,r11,x_m,y_m,z_m"));
    out
}

// ---------------------------------------------------------------- independent constructions

#[test]
fn every_convention_matches_its_independent_construction() {
    let mut rng = Rng(7);
    for _ in 0..200 {
        let t = [
            rng.range(-1500.0, 1500.0),
            rng.range(-1500.0, 1500.0),
            rng.range(-1500.0, 1500.0),
        ];
        let (a, b, c) = (
            rng.range(-180.0, 180.0),
            rng.range(-90.0, 90.0),
            rng.range(-180.0, 180.0),
        );
        let zyx = rz(a.to_radians()) * ry(b.to_radians()) * rx(c.to_radians());
        let check = |values: &[f64], columns: &str, want: &Matrix3<f64>, scale: f64| {
            let got = pose_to_matrix(values, &cols(columns)).unwrap();
            let dr = (rot(&got) - want).abs().max();
            assert!(dr < 1e-12, "{columns}: |dR| = {dr:e}");
            let dt = (got.translation.vector - Vector3::from(t)).norm();
            assert!(
                dt < 1e-12 * 1500.0,
                "{columns}: dt = {dt:e} (scale {scale})"
            );
        };
        // KUKA: R = Rz(A) Ry(B) Rx(C).
        check(
            &[t[0], t[1], t[2], a, b, c],
            "x_mm,y_mm,z_mm,a_deg,b_deg,c_deg",
            &zyx,
            1.0,
        );
        // Fanuc: R = Rz(R) Ry(P) Rx(W), the same product with W = C, P = B, R = A.
        check(
            &[t[0], t[1], t[2], c, b, a],
            "x_mm,y_mm,z_mm,w_deg,p_deg,r_deg",
            &zyx,
            1.0,
        );
        // Metres are millimetres / 1000.
        check(
            &[t[0] / 1000.0, t[1] / 1000.0, t[2] / 1000.0, a, b, c],
            "x_m,y_m,z_m,a_deg,b_deg,c_deg",
            &zyx,
            1000.0,
        );
        // Rotation vector (Rodrigues), radians and degrees, up to a little over a turn.
        let r = [
            rng.range(-4.0, 4.0),
            rng.range(-4.0, 4.0),
            rng.range(-4.0, 4.0),
        ];
        let want = rodrigues(r);
        check(
            &[t[0], t[1], t[2], r[0], r[1], r[2]],
            "x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad",
            &want,
            1.0,
        );
        check(
            &[
                t[0],
                t[1],
                t[2],
                r[0].to_degrees(),
                r[1].to_degrees(),
                r[2].to_degrees(),
            ],
            "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg",
            &want,
            1.0,
        );
        // Quaternion, scalar first and ROS's x, y, z, w.
        let q = [rng.normal(), rng.normal(), rng.normal(), rng.normal()];
        let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        let q = q.map(|x| x / n);
        let want = quat_matrix(q[0], q[1], q[2], q[3]);
        check(
            &[t[0], t[1], t[2], q[0], q[1], q[2], q[3]],
            "x_mm,y_mm,z_mm,qw,qx,qy,qz",
            &want,
            1.0,
        );
        check(
            &[
                t[0] / 1000.0,
                t[1] / 1000.0,
                t[2] / 1000.0,
                q[1],
                q[2],
                q[3],
                q[0],
            ],
            "x_m,y_m,z_m,qx,qy,qz,qw",
            &want,
            1000.0,
        );
        // The matrix itself, row by row.
        let m = zyx;
        let mut v = t.to_vec();
        v.extend((0..9).map(|i| m[(i / 3, i % 3)]));
        check(
            &v,
            "x_mm,y_mm,z_mm,r11,r12,r13,r21,r22,r23,r31,r32,r33",
            &m,
            1.0,
        );
    }
}

#[test]
fn textbook_cases_of_each_convention() {
    // A quarter turn about z: x -> y, y -> -x.
    let quarter_z = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    let h = std::f64::consts::FRAC_1_SQRT_2;
    for (values, columns) in [
        (
            vec![0.0, 0.0, 0.0, h, 0.0, 0.0, h],
            "x_mm,y_mm,z_mm,qw,qx,qy,qz",
        ),
        (
            vec![0.0, 0.0, 0.0, 0.0, 0.0, h, h],
            "x_m,y_m,z_m,qx,qy,qz,qw",
        ),
        (
            vec![0.0, 0.0, 0.0, 0.0, 0.0, PI / 2.0],
            "x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad",
        ),
        (
            vec![0.0, 0.0, 0.0, 0.0, 0.0, 90.0],
            "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg",
        ),
        (
            vec![0.0, 0.0, 0.0, 90.0, 0.0, 0.0],
            "x_mm,y_mm,z_mm,a_deg,b_deg,c_deg",
        ),
        (
            vec![0.0, 0.0, 0.0, 0.0, 0.0, 90.0],
            "x_mm,y_mm,z_mm,w_deg,p_deg,r_deg",
        ),
        (
            vec![0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            "x_mm,y_mm,z_mm,r11,r12,r13,r21,r22,r23,r31,r32,r33",
        ),
    ] {
        let t = pose_to_matrix(&values, &cols(columns)).unwrap();
        assert!((rot(&t) - quarter_z).abs().max() < 1e-15, "{columns}");
    }
    // KUKA's A = 0, B = 90, C = 0 turns the hand's x onto base -z (Ry(90): x -> -z).
    let t = pose_to_matrix(
        &[0.0, 0.0, 0.0, 0.0, 90.0, 0.0],
        &cols("x_mm,y_mm,z_mm,a_deg,b_deg,c_deg"),
    )
    .unwrap();
    assert!((rot(&t) * Vector3::x() - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-15);
    // Fanuc's W = 180 (a half turn about x) points the hand's z down.
    let t = pose_to_matrix(
        &[0.0, 0.0, 0.0, 180.0, 0.0, 0.0],
        &cols("x_mm,y_mm,z_mm,w_deg,p_deg,r_deg"),
    )
    .unwrap();
    assert!(
        (rot(&t) - Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0)))
            .abs()
            .max()
            < 1e-15
    );
    // Metres: 0.5 m is 500 mm.
    let t = pose_to_matrix(
        &[0.5, -0.25, 1.0, 0.0, 0.0, 0.0, 1.0],
        &cols("x_m,y_m,z_m,qx,qy,qz,qw"),
    )
    .unwrap();
    assert_eq!(t.translation.vector, Vector3::new(500.0, -250.0, 1000.0));
}

// ---------------------------------------------------------------- round trips

#[test]
fn every_convention_round_trips_random_poses() {
    let mut rng = Rng(11);
    for columns in all_layouts() {
        for _ in 0..500 {
            let t = rng.pose();
            let v = matrix_to_pose(&t, &columns).unwrap();
            assert_eq!(v.len(), columns.len());
            let back = pose_to_matrix(&v, &columns).unwrap();
            assert_same_pose(&back, &t, 1e-12, &columns.join(","));
            // And values -> pose -> values -> pose (the values need not come back, the
            // pose must).
            let again =
                pose_to_matrix(&matrix_to_pose(&back, &columns).unwrap(), &columns).unwrap();
            assert_same_pose(&again, &t, 1e-12, &columns.join(","));
        }
    }
}

#[test]
fn euler_angles_round_trip_at_and_near_gimbal_lock() {
    let mut rng = Rng(3);
    let kuka = cols("x_mm,y_mm,z_mm,a_deg,b_deg,c_deg");
    let fanuc = cols("x_mm,y_mm,z_mm,w_deg,p_deg,r_deg");
    for middle in [
        90.0,
        -90.0,
        90.0 - 1e-9,
        -90.0 + 1e-9,
        90.0 - 1e-6,
        -90.0 + 1e-4,
        89.999,
        -89.99,
        0.0,
    ] {
        for _ in 0..200 {
            let (first, last) = (rng.range(-180.0, 180.0), rng.range(-180.0, 180.0));
            let t = [
                rng.range(-900.0, 900.0),
                rng.range(-900.0, 900.0),
                rng.range(0.0, 900.0),
            ];
            // KUKA [A, B, C] and Fanuc [W, P, R] with the middle angle at/near +-90.
            for (columns, angles, want) in [
                (
                    &kuka,
                    [first, middle, last],
                    rz(first.to_radians()) * ry(middle.to_radians()) * rx(last.to_radians()),
                ),
                (
                    &fanuc,
                    [first, middle, last],
                    rz(last.to_radians()) * ry(middle.to_radians()) * rx(first.to_radians()),
                ),
            ] {
                let values = [t[0], t[1], t[2], angles[0], angles[1], angles[2]];
                let pose = pose_to_matrix(&values, columns).unwrap();
                assert!(
                    (rot(&pose) - want).abs().max() < 1e-12,
                    "{columns:?} {angles:?}"
                );
                let v = matrix_to_pose(&pose, columns).unwrap();
                assert!(
                    v[4].abs() <= 90.0 + 1e-12,
                    "middle angle {} out of [-90, 90]",
                    v[4]
                );
                let back = pose_to_matrix(&v, columns).unwrap();
                assert_same_pose(
                    &back,
                    &pose,
                    1e-12,
                    &format!("{columns:?} {angles:?} -> {v:?}"),
                );
            }
        }
    }
}

#[test]
fn rotation_vectors_round_trip_near_a_half_turn() {
    let mut rng = Rng(5);
    for columns in [
        cols("x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad"),
        cols("x_m,y_m,z_m,rx_rad,ry_rad,rz_rad"),
        cols("x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg"),
    ] {
        let deg = columns[3].ends_with("deg");
        for angle in [
            PI,
            PI - 1e-12,
            PI - 1e-9,
            PI - 1e-6,
            PI + 1e-9,
            1e-9,
            1e-5,
            0.0,
        ] {
            for _ in 0..100 {
                let axis = Vector3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
                let r = axis * angle;
                let want = rodrigues([r.x, r.y, r.z]);
                let k = if deg { 180.0 / PI } else { 1.0 };
                let values = [1.0, 2.0, 3.0, r.x * k, r.y * k, r.z * k];
                let pose = pose_to_matrix(&values, &columns).unwrap();
                assert!((rot(&pose) - want).abs().max() < 1e-12, "angle {angle}");
                let v = matrix_to_pose(&pose, &columns).unwrap();
                let back_angle = Vector3::new(v[3], v[4], v[5]).norm() / k;
                assert!(back_angle <= PI + 1e-12, "written angle {back_angle} > pi");
                let back = pose_to_matrix(&v, &columns).unwrap();
                assert_same_pose(&back, &pose, 1e-12, &format!("angle {angle}"));
            }
        }
    }
}

#[test]
fn quaternion_columns_in_every_order_give_the_same_pose() {
    let mut rng = Rng(13);
    let base = cols("x_mm,y_mm,z_mm,qw,qx,qy,qz");
    for _ in 0..50 {
        let t = rng.pose();
        let v = matrix_to_pose(&t, &base).unwrap();
        // Every one of the 24 orders of the quaternion columns after the translation.
        for p in permutations(4) {
            let columns: Vec<&str> = base[..3]
                .iter()
                .copied()
                .chain(p.iter().map(|&i| base[3 + i]))
                .collect();
            let values: Vec<f64> = v[..3]
                .iter()
                .copied()
                .chain(p.iter().map(|&i| v[3 + i]))
                .collect();
            assert_same_pose(
                &pose_to_matrix(&values, &columns).unwrap(),
                &t,
                1e-12,
                &columns.join(","),
            );
            assert_eq!(matrix_to_pose(&t, &columns).unwrap(), values);
        }
        // And random orders of all seven columns, -q for q.
        for _ in 0..10 {
            let p = rng.permutation(7);
            let columns: Vec<&str> = p.iter().map(|&i| base[i]).collect();
            let values: Vec<f64> = p
                .iter()
                .map(|&i| if i >= 3 { -v[i] } else { v[i] })
                .collect();
            assert_same_pose(
                &pose_to_matrix(&values, &columns).unwrap(),
                &t,
                1e-12,
                &columns.join(","),
            );
        }
    }
}

fn permutations(n: usize) -> Vec<Vec<usize>> {
    if n == 0 {
        return vec![vec![]];
    }
    let mut out = Vec::new();
    for p in permutations(n - 1) {
        for i in 0..n {
            let mut q = p.clone();
            q.insert(i, n - 1);
            out.push(q);
        }
    }
    out
}

#[test]
fn shorthands_and_specs() {
    assert_eq!(
        convention_names(),
        [
            "quaternion",
            "ros",
            "rotvec",
            "rotvec_deg",
            "ur",
            "kuka",
            "fanuc",
            "matrix"
        ]
    );
    assert_eq!(
        convention_columns("ros").unwrap(),
        cols("x_m,y_m,z_m,qx,qy,qz,qw")
    );
    assert_eq!(
        convention_columns("ur").unwrap(),
        cols("x_m,y_m,z_m,rx_rad,ry_rad,rz_rad")
    );
    assert_eq!(
        convention_columns("kuka").unwrap(),
        cols("x_mm,y_mm,z_mm,a_deg,b_deg,c_deg")
    );
    assert_eq!(
        convention_columns("fanuc").unwrap(),
        cols("x_mm,y_mm,z_mm,w_deg,p_deg,r_deg")
    );
    assert!(convention_columns("abb").is_none());
    assert_eq!(
        PoseColumns::default().names(),
        cols("x_mm,y_mm,z_mm,qw,qx,qy,qz")
    );
    // A shorthand, a header string and the names one by one are the same layout.
    let a = PoseColumns::from_spec(&["ros"]).unwrap();
    let b = PoseColumns::from_spec(&["x_m, y_m,z_m,qx,qy,qz,qw"]).unwrap();
    let c = PoseColumns::from_spec(&cols("x_m,y_m,z_m,qx,qy,qz,qw")).unwrap();
    assert_eq!((&a, &b), (&c, &c));
    let t = Rng(1).pose();
    assert_eq!(
        matrix_to_pose(&t, &["ros"]).unwrap(),
        matrix_to_pose(&t, &cols("x_m,y_m,z_m,qx,qy,qz,qw")).unwrap()
    );
    assert_invalid(
        pose_to_matrix(&[0.0; 7], &["abb"]).unwrap_err(),
        &["unknown pose convention \"abb\"", "ros"],
    );
    assert_invalid(
        pose_to_matrix(&[0.0; 6], &["ros"]).unwrap_err(),
        &["6 values given for the 7 columns"],
    );
    assert_invalid(
        pose_to_matrix(&[0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0, 1.0], &["ros"]).unwrap_err(),
        &["z_m = NaN is not a finite number"],
    );
}

// ---------------------------------------------------------------- malformed poses

#[test]
fn malformed_headers_are_typed_errors_naming_the_problem() {
    let bad = [
        (
            "x_mm,y_mm,z_mm,qw,qx,qy,qz,a_deg,b_deg,c_deg",
            vec![
                "2 rotation conventions",
                "qw, qx, qy, qz (a unit quaternion)",
                "a_deg, b_deg, c_deg (KUKA's A, B, C)",
            ],
        ),
        (
            "x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad,rx_deg",
            vec![
                "2 rotation conventions",
                "rx_rad, ry_rad, rz_rad (a rotation vector in radians)",
                "rx_deg (a rotation vector in degrees)",
            ],
        ),
        (
            "x_mm,y_mm,z_mm,qw,qx,qy",
            vec!["header has qw, qx, qy but not qz"],
        ),
        (
            "qx,qy,qz,qw,x_m,z_m",
            vec!["header has x_m, z_m but not y_m"],
        ),
        (
            "x_mm,y_mm,z_mm,r11,r12,r13,r21,r22,r23,r31,r32",
            vec!["but not r33"],
        ),
        ("qw,qx,qy,qz", vec!["no translation columns"]),
        ("x_mm,y_mm,z_mm", vec!["no rotation columns"]),
        (
            "x_mm,y_mm,z_mm,x_m,y_m,z_m,qw,qx,qy,qz",
            vec!["translation in x_mm, y_mm, z_mm (millimetres) and x_m, y_m, z_m (metres)"],
        ),
        (
            "x_mm,y_mm,z_mm,qw,qx,qx,qy,qz",
            vec!["column `qx` appears twice"],
        ),
        ("x_mm,y_mm,z_mm,qw,qi,qj,qk", vec!["unknown column `qi`"]),
        (
            "x_mm,y_mm,z_mm,yaw,pitch,roll",
            vec!["unknown column `yaw`", "a_deg,b_deg,c_deg"],
        ),
        ("x_mm,y_mm,z_mm,A,B,C", vec!["unknown column `A`"]),
    ];
    let d = tmp();
    for (header, msgs) in &bad {
        // The API.
        let names = cols(header);
        let e = pose_to_matrix(&vec![0.0; names.len()], &names).unwrap_err();
        assert_invalid(e, msgs);
        // views.csv and scan.csv: line 1.
        let values = vec!["0"; names.len()].join(",");
        let p = write(
            d.path(),
            "views.csv",
            &format!("board_image,laser_image,{header}\na.png,,{values}\n"),
        );
        assert_format(
            read_views_csv(&p, None).unwrap_err(),
            "views.csv",
            "line 1",
            msgs,
        );
        let p = write(
            d.path(),
            "scan.csv",
            &format!("image,{header}\na.png,{values}\n"),
        );
        assert_format(
            read_scan_csv(&p, None).unwrap_err(),
            "scan.csv",
            "line 1",
            msgs,
        );
    }
    // Joint columns mixed with pose columns, either way round.
    let p = write(
        d.path(),
        "views.csv",
        "board_image,laser_image,q1,q2,x_mm\na.png,,1,2,3\n",
    );
    assert_format(
        read_views_csv(&p, None).unwrap_err(),
        "views.csv",
        "line 1",
        &["header column 5 is `x_mm`, expected `q3`", "not both"],
    );
    let p = write(
        d.path(),
        "views.csv",
        "board_image,laser_image,x_mm,y_mm,z_mm,q1\na.png,,1,2,3,4\n",
    );
    assert_format(
        read_views_csv(&p, None).unwrap_err(),
        "views.csv",
        "line 1",
        &["expected `q1`", "not both"],
    );
}

#[test]
fn malformed_rows_are_typed_errors_naming_the_line() {
    let d = tmp();
    let views = |header: &str, rows: &[&str]| {
        let text = format!("board_image,laser_image,{header}\n{}\n", rows.join("\n"));
        read_views_csv(write(d.path(), "views.csv", &text), None)
    };
    let ok = "a.png,,1,2,3,0,0,0,1";
    // A quaternion whose norm is not 1, in ROS order, on line 3.
    let e = views("x_m,y_m,z_m,qx,qy,qz,qw", &[ok, "b.png,,1,2,3,0,0,0,0.5"]).unwrap_err();
    assert_format(
        e,
        "views.csv",
        "line 3",
        &[
            "(qw, qx, qy, qz) = (0.5, 0, 0, 0)",
            "has norm 0.5",
            "expected 1 (within 0.001)",
        ],
    );
    let e = views("x_m,y_m,z_m,qx,qy,qz,qw", &["b.png,,1,2,3,0,0,0.1,1.01"]).unwrap_err();
    assert_format(
        e,
        "views.csv",
        "line 2, columns qw, qx, qy, qz",
        &["has norm 1.01"],
    );
    // Within 1e-3 it is normalised.
    let v = views("x_m,y_m,z_m,qx,qy,qz,qw", &["b.png,,1,2,3,0,0,0,1.0009"]).unwrap();
    assert_eq!(
        v[0].reading,
        RobotReading::FlangePose(Iso3::translation(1000.0, 2000.0, 3000.0))
    );
    // A matrix that is not a rotation: scaled, a reflection, a shear.
    let m = "x_mm,y_mm,z_mm,r11,r12,r13,r21,r22,r23,r31,r32,r33";
    let e = views(
        m,
        &[
            "a.png,,0,0,0,1,0,0,0,1,0,0,0,1",
            "a.png,,0,0,0,1.01,0,0,0,1.01,0,0,0,1.01",
        ],
    )
    .unwrap_err();
    assert_format(
        e,
        "views.csv",
        "line 3",
        &[
            "[[1.01, 0, 0], [0, 1.01, 0], [0, 0, 1.01]] is not a rotation",
            "det = 1.03",
        ],
    );
    let e = views(m, &["a.png,,0,0,0,1,0,0,0,1,0,0,0,-1"]).unwrap_err();
    assert_format(e, "views.csv", "line 2", &["is not a rotation", "det = -1"]);
    let e = views(m, &["a.png,,0,0,0,1,0.1,0,0,1,0,0,0,1"]).unwrap_err();
    assert_format(
        e,
        "views.csv",
        "line 2, columns r11",
        &["is not a rotation", "max |R^T R - I| = 1.000e-1"],
    );
    // Within 1e-3 it is replaced by the nearest rotation.
    let v = views(m, &["a.png,,0,0,0,1,0.0004,0,-0.0004,1,0,0,0,1.0002"]).unwrap();
    let RobotReading::FlangePose(t) = v[0].reading else {
        panic!()
    };
    assert!((rot(&t) - Matrix3::identity()).abs().max() < 5e-4);
    assert!(
        (rot(&t).transpose() * rot(&t) - Matrix3::identity())
            .abs()
            .max()
            < 1e-14
    );
    // Empty and non-finite cells name the line and the column.
    let ok2 = "a.png,,0,0,0,1,1,2,3";
    let e = views(
        "qz,qy,qx,qw,x_mm,y_mm,z_mm",
        &[ok2, ok2, "c.png,,0,0,,1,1,2,3"],
    )
    .unwrap_err();
    assert_format(
        e,
        "views.csv",
        "line 4, column qx",
        &["qx = \"\" is not a finite number"],
    );
    let e = views(
        "a_deg,b_deg,c_deg,x_mm,y_mm,z_mm",
        &["c.png,,0,inf,0,1,2,3"],
    )
    .unwrap_err();
    assert_format(
        e,
        "views.csv",
        "line 2, column b_deg",
        &["not a finite number"],
    );
    // scan.csv likewise.
    let p = write(
        d.path(),
        "scan.csv",
        "image,qw,qx,qy,qz,x_mm,y_mm,z_mm\ns0.png,1,0,0,0,0,0,0\ns1.png,2,0,0,0,0,0,0\n",
    );
    assert_format(
        read_scan_csv(&p, None).unwrap_err(),
        "scan.csv",
        "line 3",
        &["has norm 2"],
    );
    // The API says the same, without a line.
    assert_invalid(
        pose_to_matrix(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5], &["ros"]).unwrap_err(),
        &["has norm 0.5"],
    );
}

// ---------------------------------------------------------------- views.csv / scan.csv

#[test]
fn views_and_scan_csv_read_every_convention_in_any_column_order() {
    let mut rng = Rng(17);
    let d = tmp();
    for columns in all_layouts() {
        for order in 0..3 {
            // The layout as given, reversed, and a random order.
            let p: Vec<usize> = match order {
                0 => (0..columns.len()).collect(),
                1 => (0..columns.len()).rev().collect(),
                _ => rng.permutation(columns.len()),
            };
            let names: Vec<&str> = p.iter().map(|&i| columns[i]).collect();
            let poses: Vec<Iso3> = (0..4).map(|_| rng.pose()).collect();
            let rows: Vec<String> = poses
                .iter()
                .map(|t| {
                    let v = matrix_to_pose(t, &names).unwrap();
                    v.iter()
                        .map(|x| format!("{x}"))
                        .collect::<Vec<_>>()
                        .join(",")
                })
                .collect();
            let header = names.join(",");
            let text: String = rows
                .iter()
                .enumerate()
                .map(|(i, r)| format!("img/{i}.png,img/{i}_laser.png,{r}\n"))
                .collect();
            let views = read_views_csv(
                write(
                    d.path(),
                    "views.csv",
                    &format!("board_image,laser_image,{header}\n{text}"),
                ),
                Some(&Robot::hp3()),
            )
            .unwrap();
            let scan_text: String = rows
                .iter()
                .enumerate()
                .map(|(i, r)| format!("s{i}.png,{r}\n"))
                .collect();
            let frames = read_scan_csv(
                write(
                    d.path(),
                    "scan.csv",
                    &format!("image,{header}\n{scan_text}"),
                ),
                None,
            )
            .unwrap();
            for (i, t) in poses.iter().enumerate() {
                let RobotReading::FlangePose(a) = &views[i].reading else {
                    panic!()
                };
                let RobotReading::FlangePose(b) = &frames[i].reading else {
                    panic!()
                };
                assert_same_pose(a, t, 1e-12, &header);
                assert_same_pose(b, t, 1e-12, &header);
                assert_eq!(views[i].line, i + 2);
                assert_eq!(frames[i].image, PathBuf::from(format!("s{i}.png")));
            }
        }
    }
    // The brief's example header.
    let h = "board_image,laser_image,qx,qy,qz,qw,x_m,y_m,z_m";
    let v = read_views_csv(
        write(
            d.path(),
            "views.csv",
            &format!("{h}\nb.png,l.png,0,0,1,0,0.1,0.2,0.3\n"),
        ),
        None,
    )
    .unwrap();
    let RobotReading::FlangePose(t) = v[0].reading else {
        panic!()
    };
    assert!((rot(&t) - rz(PI)).abs().max() < 1e-15);
    assert!((t.translation.vector - Vector3::new(100.0, 200.0, 300.0)).norm() < 1e-12);
}

#[test]
fn writers_round_trip_every_convention() {
    let mut rng = Rng(23);
    let d = tmp();
    let p = d.path().join("views.csv");
    let s = d.path().join("scan.csv");
    for columns in all_layouts() {
        let pose = PoseColumns::parse(&columns).unwrap();
        let views: Vec<View> = (0..5)
            .map(|i| View {
                line: i + 2,
                board_image: format!("images/{i}.png").into(),
                laser_image: (i % 2 == 0).then(|| format!("images/{i}_l.png").into()),
                reading: RobotReading::FlangePose(rng.pose()),
            })
            .collect();
        write_views_csv_with(&p, &views, &pose).unwrap();
        let text = fs::read_to_string(&p).unwrap();
        assert!(
            text.starts_with(&format!("board_image,laser_image,{}\n", columns.join(","))),
            "{text}"
        );
        let back = read_views_csv(&p, None).unwrap();
        for (a, b) in back.iter().zip(&views) {
            assert_eq!(
                (a.line, &a.board_image, &a.laser_image),
                (b.line, &b.board_image, &b.laser_image)
            );
            let (RobotReading::FlangePose(ta), RobotReading::FlangePose(tb)) =
                (&a.reading, &b.reading)
            else {
                panic!()
            };
            assert_same_pose(ta, tb, 1e-12, &columns.join(","));
        }
        let frames: Vec<ScanFrame> = views
            .iter()
            .map(|v| ScanFrame {
                line: v.line,
                image: v.board_image.clone(),
                reading: v.reading.clone(),
            })
            .collect();
        write_scan_csv_with(&s, &frames, &pose).unwrap();
        assert!(fs::read_to_string(&s)
            .unwrap()
            .starts_with(&format!("image,{}\n", columns.join(","))));
        for (a, b) in read_scan_csv(&s, None).unwrap().iter().zip(&frames) {
            let (RobotReading::FlangePose(ta), RobotReading::FlangePose(tb)) =
                (&a.reading, &b.reading)
            else {
                panic!()
            };
            assert_same_pose(ta, tb, 1e-12, &columns.join(","));
        }
    }
    // The default writer keeps x_mm,y_mm,z_mm,qw,qx,qy,qz; joint readings are written as
    // they are whatever pose columns are asked for.
    let views = vec![View {
        line: 2,
        board_image: "a.png".into(),
        laser_image: None,
        reading: RobotReading::Joints(vec![0.5, -1.0 / 3.0, 90.0]),
    }];
    write_views_csv_with(&p, &views, &PoseColumns::from_spec(&["kuka"]).unwrap()).unwrap();
    assert_eq!(
        fs::read_to_string(&p).unwrap(),
        format!(
            "board_image,laser_image,q1,q2,q3\na.png,,0.5,{},90\n",
            -1.0 / 3.0
        )
    );
    assert_eq!(read_views_csv(&p, None).unwrap(), views);
    let posed = vec![View {
        reading: RobotReading::FlangePose(Iso3::translation(1.0, 2.0, 3.0)),
        ..views[0].clone()
    }];
    write_views_csv(&p, &posed).unwrap();
    assert_eq!(
        fs::read_to_string(&p).unwrap(),
        "board_image,laser_image,x_mm,y_mm,z_mm,qw,qx,qy,qz\na.png,,1,2,3,1,0,0,0\n"
    );
    // Joints and flange poses in one table cannot be written.
    let mixed = vec![views[0].clone(), posed[0].clone()];
    assert!(matches!(
        write_views_csv(&p, &mixed),
        Err(Error::InvalidInput(_))
    ));
}

// ---------------------------------------------------------------- the twin

#[test]
fn twin_reports_the_nominal_robots_flange_pose_in_the_asked_columns() {
    use stripecal_sim::config::SimConfig;
    use stripecal_sim::dataset::Twin;

    let base = SimConfig::hp3_paper();
    let joints = Twin::new(base.clone()).unwrap();
    let q = base.poses.home_q_deg.clone();
    assert_eq!(joints.reading(&q).unwrap(), RobotReading::Joints(q.clone()));
    for spec in ["ros", "kuka", "qx,qy,qz,qw,x_m,y_m,z_m"] {
        let cfg = base
            .with_overrides(&serde_json::json!({ "pose_columns": spec }))
            .unwrap();
        let twin = Twin::new(cfg).unwrap();
        let RobotReading::FlangePose(t) = twin.reading(&q).unwrap() else {
            panic!("{spec}: not a flange pose")
        };
        // The controller's pose is the NOMINAL robot's kinematics (rig.json's robot).
        assert_eq!(t, twin.robot_nominal.forward(&q).unwrap());
    }
    let e = base
        .with_overrides(&serde_json::json!({ "pose_columns": "abb" }))
        .unwrap_err();
    assert!(
        e.to_string()
            .contains("pose_columns: unknown pose convention"),
        "{e}"
    );
    let e = base
        .with_overrides(&serde_json::json!({ "pose_columns": "x_mm,y_mm,z_mm,qw,qx,qy" }))
        .unwrap_err();
    assert!(e.to_string().contains("but not qz"), "{e}");
}

/// A views.csv without pose columns is a bench dataset (every reading
/// `RobotReading::Fixed`), a scan.csv with `image` alone a fixed-sensor scan; with pose
/// columns in the header, a row whose pose cells are empty is an error naming its line
/// (a dataset is a bench dataset as a whole or not at all); both round-trip through the
/// writers.
#[test]
fn views_without_pose_columns_are_a_bench_dataset() {
    let d = tmp();
    let p = write(
        d.path(),
        "views.csv",
        "board_image,laser_image\na.png,b.png\nc.png,\n",
    );
    let views = read_views_csv(&p, None).unwrap();
    assert_eq!(views.len(), 2);
    assert!(views.iter().all(|v| v.reading == RobotReading::Fixed));
    assert_eq!(views[1].laser_image, None);
    let out = d.path().join("back.csv");
    write_views_csv(&out, &views).unwrap();
    assert_eq!(read_views_csv(&out, None).unwrap(), views);
    let s = write(d.path(), "scan.csv", "image\nf0.png\nf1.png\n");
    let frames = read_scan_csv(&s, None).unwrap();
    assert!(frames.iter().all(|f| f.reading == RobotReading::Fixed));
    let mixed = write(
        d.path(),
        "mixed.csv",
        "board_image,laser_image,x_mm,y_mm,z_mm,qw,qx,qy,qz\n\
         a.png,b.png,1,2,3,1,0,0,0\n\
         c.png,d.png,,,,,,,\n",
    );
    assert_format(
        read_views_csv(&mixed, None).unwrap_err(),
        "mixed.csv",
        "line 3",
        &["pose cells", "bench dataset"],
    );
}
