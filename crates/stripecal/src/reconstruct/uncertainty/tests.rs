//! The propagation against finite differences of the whole chain and against a Monte
//! Carlo over calibration draws.

use nalgebra::{DMatrix, Matrix3, Vector3};

use super::*;
use crate::model::geometry::{iso_from_rotvec, Plane};
use crate::model::kinematics::Robot;
use crate::model::{NamedCovariance, Quality};
use crate::numerics::rng::SplitMix64;
use crate::reconstruct::Triangulator;

pub(crate) const Q: [f64; 6] = [5.0, -15.0, 25.0, 10.0, -80.0, 30.0];

/// The paper-like rig with strong distortion, a robot and a covariance over every
/// number that moves a point (plus two that do not).
pub(crate) fn calibration() -> Calibration {
    let camera = crate::reconstruct::triangulate::tests::camera([-0.2, 0.1, 0.001, -0.002, 0.01]);
    let names: Vec<String> = [
        "camera.fu",
        "camera.fv",
        "camera.u0",
        "camera.v0",
        "camera.distortion[0]",
        "camera.distortion[1]",
        "camera.distortion[2]",
        "camera.distortion[3]",
        "camera.distortion[4]",
        "laser_plane.normal[0]",
        "laser_plane.normal[1]",
        "laser_plane.normal[2]",
        "laser_plane.d_mm",
        "hand_cam.rotation_vector[0]",
        "hand_cam.rotation_vector[1]",
        "hand_cam.rotation_vector[2]",
        "hand_cam.translation_mm[0]",
        "hand_cam.translation_mm[1]",
        "hand_cam.translation_mm[2]",
        "base_board.translation_mm[0]",
        "board.scale",
        "robot.joints[1].theta0_deg",
        "robot.joints[2].a_mm",
        "robot.joints[2].beta_deg",
        "robot.joints[4].d_mm",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let sig = [
        2.0, 2.0, 1.5, 1.5, 0.01, 0.02, 1e-4, 1e-4, 0.01, 2e-3, 2e-3, 2e-3, 0.05, 1e-3, 1e-3, 1e-3,
        0.1, 0.1, 0.1, 0.1, 1e-4, 0.01, 0.05, 0.005, 0.05,
    ];
    // A correlated covariance: D (I + 0.3 sym(random)) D, made positive definite.
    let n = names.len();
    let mut rng = SplitMix64(11);
    let a = DMatrix::from_fn(n, n, |_, _| 0.3 * rng.normal());
    let mut corr = &a * a.transpose() / n as f64 + DMatrix::identity(n, n);
    let dn = corr.diagonal().map(|x| 1.0 / x.sqrt());
    corr = DMatrix::from_fn(n, n, |r, c| corr[(r, c)] * dn[r] * dn[c]);
    let matrix = DMatrix::from_fn(n, n, |r, c| corr[(r, c)] * sig[r] * sig[c]);
    let plane = Plane::new(Vector3::new(0.629, -0.0492, 0.7759).normalize(), 79.87).unwrap();
    let hand_cam = iso_from_rotvec(
        &Vector3::new(-0.3087, 0.2362, 3.0369),
        &Vector3::new(29.19, 5.37, 62.64),
    );
    Calibration {
        camera,
        laser_plane: Some(plane),
        mount: crate::model::Mount::Robot,
        hand_cam,
        base_board: iso_from_rotvec(&Vector3::zeros(), &Vector3::new(400.0, 0.0, 0.0)),
        robot: Some(Robot::hp3()),
        quality: Quality {
            circle_rms_px: 0.05,
            stripe_rms_px: 0.1,
            views_used: 5,
            checks: vec![],
            accepted_poor: false,
        },
        uncertainty: Default::default(),
        covariance: Some(NamedCovariance {
            parameters: names,
            matrix,
        }),
        records: Default::default(),
        extra: Default::default(),
    }
}

/// Pixels on a stripe across the image (direction Cols: one u per row).
fn pixels() -> Vec<[f64; 2]> {
    (0..9)
        .map(|i| [300.0 + 15.0 * i as f64, 40.0 + 60.0 * i as f64])
        .collect()
}

/// The base point of a pixel with a calibration, through the reconstruction's own code.
fn point(c: &Calibration, uv: [f64; 2]) -> Vector3<f64> {
    let tri = Triangulator::from_calibration(c, 0.0).unwrap();
    let bh = c.robot.as_ref().unwrap().forward(&Q).unwrap();
    let (mut out, mut idx) = (Vec::new(), Vec::new());
    tri.triangulate_into(&bh, &[uv], &mut out, &mut idx);
    Vector3::from(out[0])
}

/// Every column `R_bc J_c M_f` against central differences of the reconstruction with
/// the number moved; the stripe column against moving the pixel.
#[test]
fn jacobian_matches_finite_differences() {
    let cal = calibration();
    let model = UncertaintyModel::new(&cal, &UncertaintyOptions::default()).unwrap();
    assert_eq!(
        model.names().len(),
        23,
        "base_board and board.scale move no point"
    );
    let frame = model.frame(&RobotReading::Joints(Q.to_vec())).unwrap();
    for uv in pixels() {
        let l = frame.local(uv[0], uv[1]).unwrap();
        assert!((l.p_base - point(&cal, uv)).norm() < 1e-9);
        let j = frame.rotation() * l.j_eta * frame.map();
        for (k, name) in model.names().iter().enumerate() {
            let h = 1e-6 * cal.covariance.as_ref().unwrap().sigma(name).unwrap() * 100.0;
            let at = |e: f64| {
                let c = perturbed_calibration(&cal, std::slice::from_ref(name), &[e]).unwrap();
                point(&c, uv)
            };
            let fd = (at(h) - at(-h)) / (2.0 * h);
            let an = j.column(k);
            let e = (fd - an).norm();
            assert!(
                e < 1e-5 * (1.0 + fd.norm()),
                "pixel {uv:?}, {name}: analytic {an:?} vs finite differences {fd:?}"
            );
        }
        let h = 1e-4;
        let fd = (point(&cal, [uv[0] + h, uv[1]]) - point(&cal, [uv[0] - h, uv[1]])) / (2.0 * h);
        let an = frame.rotation() * l.j_px;
        assert!(
            (fd - an).norm() < 1e-6 * (1.0 + fd.norm()),
            "{fd:?} vs {an:?}"
        );
    }
}

/// Draws of the calibration from its covariance, each reconstructing the same pixels:
/// the sample covariance of the points against the propagated one, every one-sigma
/// within 4 % (2000 draws: the sample sigma's own scatter is 1.6 %), the correlations
/// within 0.05.
#[test]
fn covariance_matches_monte_carlo() {
    let cal = calibration();
    let opts = UncertaintyOptions {
        stripe_sigma_px: Some(0.0),
        ..Default::default()
    };
    let model = UncertaintyModel::new(&cal, &opts).unwrap();
    let frame = model.frame(&RobotReading::Joints(Q.to_vec())).unwrap();
    let named = cal.covariance.as_ref().unwrap();
    let chol = named.matrix.clone().cholesky().unwrap();
    let px = pixels();
    let draws = 2000;
    let mut rng = SplitMix64(5);
    let mut sums = vec![(Vector3::<f64>::zeros(), Matrix3::<f64>::zeros()); px.len()];
    for _ in 0..draws {
        let z = DMatrix::from_fn(named.parameters.len(), 1, |_, _| rng.normal());
        let delta = chol.l() * z;
        let c = perturbed_calibration(&cal, &named.parameters, delta.as_slice()).unwrap();
        for (s, uv) in sums.iter_mut().zip(&px) {
            let p = point(&c, *uv);
            s.0 += p;
            s.1 += p * p.transpose();
        }
    }
    for (s, uv) in sums.iter().zip(&px) {
        let m = s.0 / draws as f64;
        let mc = (s.1 - m * m.transpose() * draws as f64) / (draws - 1) as f64;
        let c = frame.point_covariance(uv[0], uv[1]);
        let an = Matrix3::new(c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5]);
        for k in 0..3 {
            let (a, b) = (an[(k, k)].sqrt(), mc[(k, k)].sqrt());
            assert!(
                (a / b - 1.0).abs() < 0.04,
                "pixel {uv:?} axis {k}: {a} vs {b}"
            );
            for l in 0..k {
                let ra = an[(k, l)] / (an[(k, k)] * an[(l, l)]).sqrt();
                let rb = mc[(k, l)] / (mc[(k, k)] * mc[(l, l)]).sqrt();
                assert!(
                    (ra - rb).abs() < 0.05,
                    "pixel {uv:?} corr {k}{l}: {ra} vs {rb}"
                );
            }
        }
    }
}

/// The stripe and robot figures: a frame's covariance without the calibration is the
/// stripe part plus the robot's, each as the chain says.
#[test]
fn stripe_and_robot_parts() {
    let cal = calibration();
    let q = RobotReading::Joints(Q.to_vec());
    let only = |stripe: f64, rep: Option<f64>, enc: Option<f64>| {
        let o = UncertaintyOptions {
            calibration: false,
            stripe_sigma_px: Some(stripe),
            repeatability_mm: rep,
            encoder_sigma_deg: enc,
            ..Default::default()
        };
        let m = UncertaintyModel::new(&cal, &o).unwrap();
        m.frame(&q).unwrap().point_covariance(320.0, 200.0)
    };
    // Repeatability alone: sigma^2 I.
    let c = only(0.0, Some(0.02), None);
    for (k, v) in c.iter().enumerate() {
        let want = if [0, 3, 5].contains(&k) { 4e-4 } else { 0.0 };
        assert!((v - want).abs() < 1e-12, "{k}: {v}");
    }
    // The stripe alone: 0.2 px along u moves the point by 0.2 |dp/du|.
    let c = only(0.2, None, None);
    let h = 1e-4;
    let du = (point(&cal, [320.0 + h, 200.0]) - point(&cal, [320.0 - h, 200.0])) / (2.0 * h);
    assert!(((c[0] + c[3] + c[5]).sqrt() - 0.2 * du.norm()).abs() < 1e-9);
    // Encoders alone: a Monte Carlo over joint readings.
    let c = only(0.0, None, Some(0.01));
    let robot = cal.robot.as_ref().unwrap();
    let tri = Triangulator::from_calibration(&cal, 0.0).unwrap();
    let mut rng = SplitMix64(3);
    let (mut s1, mut s2) = (Vector3::zeros(), Matrix3::zeros());
    let n = 3000;
    for _ in 0..n {
        let qn: Vec<f64> = Q.iter().map(|x| x + 0.01 * rng.normal()).collect();
        let (mut out, mut idx) = (Vec::new(), Vec::new());
        tri.triangulate_into(
            &robot.forward(&qn).unwrap(),
            &[[320.0, 200.0]],
            &mut out,
            &mut idx,
        );
        let p = Vector3::from(out[0]);
        s1 += p;
        s2 += p * p.transpose();
    }
    let m = s1 / n as f64;
    let mc = (s2 - m * m.transpose() * n as f64) / (n - 1) as f64;
    for (k, d) in [0, 3, 5].iter().enumerate() {
        let r = (c[*d] / mc[(k, k)]).sqrt();
        assert!((r - 1.0).abs() < 0.06, "axis {k}: ratio {r}");
    }
}

#[test]
fn bad_options_and_files() {
    let mut cal = calibration();
    let bad = UncertaintyOptions {
        stripe_sigma_px: Some(-1.0),
        ..Default::default()
    };
    assert!(UncertaintyModel::new(&cal, &bad).is_err());
    let flange = RobotReading::FlangePose(cal.robot.as_ref().unwrap().forward(&Q).unwrap());
    let m = UncertaintyModel::new(&cal, &UncertaintyOptions::default()).unwrap();
    let e = m.frame(&flange).unwrap_err().to_string();
    assert!(e.contains("flange pose"), "{e}");
    cal.covariance = None;
    let e = UncertaintyModel::new(&cal, &UncertaintyOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("no covariance"), "{e}");
}

/// The calibration's estimated robot-pose noise where rig.json gives no figures: its
/// translation as the repeatability, its rotation as the flange's; a figure given is used
/// instead (never both), and the image part of the pose noise does not enter. The flange
/// rotation's part against a Monte Carlo over flange rotations.
#[test]
fn estimated_pose_noise_stands_in_for_missing_figures() {
    use crate::model::RobotPoseNoise;
    let mut cal = calibration();
    let noise = RobotPoseNoise {
        sigma_translation_mm: 0.03,
        sigma_rotation_deg: 0.01,
        translation_at_floor: false,
        rotation_at_floor: false,
        floor_translation_mm: 1e-3,
        floor_rotation_deg: 1e-4,
        image_factor: Some(20.0),
        image_factor_at_floor: false,
        kinematic_mm: None,
        kinematic_deg: None,
        views: Vec::new(),
        left_out: Vec::new(),
    };
    cal.records.robot_pose_noise = Some(noise.clone());
    let base = UncertaintyOptions {
        calibration: false,
        stripe_sigma_px: Some(0.0),
        ..Default::default()
    };
    let o = base.clone().with_pose_noise(&cal);
    assert_eq!(o.repeatability_mm, Some(0.03));
    assert_eq!(o.flange_rotation_deg, Some(0.01));
    // Figures given win, each on its own.
    let given = UncertaintyOptions {
        repeatability_mm: Some(0.05),
        encoder_sigma_deg: Some(0.002),
        ..base.clone()
    }
    .with_pose_noise(&cal);
    assert_eq!(given.repeatability_mm, Some(0.05));
    assert_eq!(given.flange_rotation_deg, None);
    // Without an estimate nothing changes; nor with one at its floors.
    assert_eq!(base.clone().with_pose_noise(&calibration()), base);
    let mut at_floor = calibration();
    at_floor.records.robot_pose_noise = Some(RobotPoseNoise {
        translation_at_floor: true,
        rotation_at_floor: true,
        ..noise.clone()
    });
    assert_eq!(base.clone().with_pose_noise(&at_floor), base);
    // The flange rotation's part: a Monte Carlo over iso flange rotations of 0.01 deg.
    let rot_only = UncertaintyOptions {
        flange_rotation_deg: Some(0.01),
        ..base.clone()
    };
    let q = RobotReading::Joints(Q.to_vec());
    let m = UncertaintyModel::new(&cal, &rot_only).unwrap();
    let c = m.frame(&q).unwrap().point_covariance(320.0, 200.0);
    let robot = cal.robot.as_ref().unwrap();
    let a = robot.forward(&Q).unwrap();
    let tri = Triangulator::from_calibration(&cal, 0.0).unwrap();
    let mut rng = SplitMix64(5);
    let (mut s1, mut s2) = (Vector3::zeros(), Matrix3::zeros());
    let n = 3000;
    for _ in 0..n {
        let w = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * 0.01f64.to_radians();
        let d = iso_from_rotvec(&w, &Vector3::zeros());
        let (mut out, mut idx) = (Vec::new(), Vec::new());
        tri.triangulate_into(&(a * d), &[[320.0, 200.0]], &mut out, &mut idx);
        let p = Vector3::from(out[0]);
        s1 += p;
        s2 += p * p.transpose();
    }
    let mean = s1 / n as f64;
    let mc = (s2 - mean * mean.transpose() * n as f64) / (n - 1) as f64;
    for (k, d) in [0, 3, 5].iter().enumerate() {
        let r = (c[*d] / mc[(k, k)]).sqrt();
        assert!((r - 1.0).abs() < 0.06, "axis {k}: ratio {r}");
    }
}
