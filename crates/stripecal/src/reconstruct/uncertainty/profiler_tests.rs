//! A profiler's point chain ([`UncertaintyModel::profiler`]) against a Monte Carlo over
//! draws of its calibration's numbers, and its own noise along the sensor's z.

use nalgebra::{DMatrix, Matrix3, Vector3};

use super::tests::Q;
use super::*;
use crate::model::geometry::iso_from_rotvec;
use crate::model::kinematics::Robot;
use crate::model::{NamedCovariance, Profile, ProfilerCalibration, ProfilerQuality};
use crate::numerics::rng::SplitMix64;
use crate::reconstruct::profile_scan_points;

/// A profiler on the HP3 with a correlated covariance over the hand-eye, four DH numbers
/// and the sphere (which moves no point).
pub(crate) fn profiler_calibration() -> ProfilerCalibration {
    let names: Vec<String> = [
        "hand_cam.rotation_vector[0]",
        "hand_cam.rotation_vector[1]",
        "hand_cam.rotation_vector[2]",
        "hand_cam.translation_mm[0]",
        "hand_cam.translation_mm[1]",
        "hand_cam.translation_mm[2]",
        "sphere.center_mm[0]",
        "sphere.center_mm[1]",
        "sphere.center_mm[2]",
        "sphere.diameter_mm",
        "robot.joints[1].theta0_deg",
        "robot.joints[2].a_mm",
        "robot.joints[2].beta_deg",
        "robot.joints[4].d_mm",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let sig = [
        1e-3, 1e-3, 2e-3, 0.1, 0.1, 0.2, 0.05, 0.05, 0.05, 0.01, 0.01, 0.05, 0.005, 0.05,
    ];
    let n = names.len();
    let mut rng = SplitMix64(17);
    let a = DMatrix::from_fn(n, n, |_, _| 0.3 * rng.normal());
    let mut corr = &a * a.transpose() / n as f64 + DMatrix::identity(n, n);
    let dn = corr.diagonal().map(|x| 1.0 / x.sqrt());
    corr = DMatrix::from_fn(n, n, |r, c| corr[(r, c)] * dn[r] * dn[c]);
    let matrix = DMatrix::from_fn(n, n, |r, c| corr[(r, c)] * sig[r] * sig[c]);
    ProfilerCalibration {
        hand_sensor: iso_from_rotvec(
            &Vector3::new(0.2, -0.1, 3.0),
            &Vector3::new(25.0, -10.0, 90.0),
        ),
        robot: Some(Robot::hp3()),
        sphere_center_mm: Vector3::new(600.0, 0.0, 100.0),
        sphere_diameter_mm: 50.0,
        quality: ProfilerQuality {
            profile_rms_mm: 0.01,
            views_used: 20,
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

/// Profile points across the measuring range, `(x, z)` mm.
fn profile() -> Profile {
    Profile {
        points: (0..7)
            .map(|i| [-30.0 + 10.0 * i as f64, 80.0 + 8.0 * i as f64])
            .collect(),
        gaps: 0,
    }
}

/// The base points of the profile with a calibration, through the scan's own code.
fn points(c: &ProfilerCalibration) -> Vec<Vector3<f64>> {
    let sp = profile_scan_points(&[(RobotReading::Joints(Q.to_vec()), profile())], c).unwrap();
    sp.points_mm.iter().map(|p| Vector3::from(*p)).collect()
}

/// Draws of the calibration from its covariance (hand-eye, DH and sphere numbers), each
/// giving the profile's base points: the sample covariance against the propagated one,
/// every one-sigma within 5 % (the brief asks 10 %; 2000 draws leave the sample sigma a
/// scatter of 1.6 %), the correlations within 0.05; and the model's numbers are the
/// hand-eye and DH ones (the sphere moves no point).
#[test]
fn profiler_covariance_matches_monte_carlo() {
    let cal = profiler_calibration();
    let opts = UncertaintyOptions {
        profile_sigma_mm: Some(0.0),
        ..Default::default()
    };
    let model = UncertaintyModel::profiler(&cal, &opts).unwrap();
    assert!(model.is_profiler() && model.calibration().is_none());
    assert_eq!(model.names().len(), 10, "{:?}", model.names());
    assert!(model.names().iter().all(|n| !n.starts_with("sphere.")));
    let frame = model.frame(&RobotReading::Joints(Q.to_vec())).unwrap();
    let named = cal.covariance.as_ref().unwrap();
    let chol = named.matrix.clone().cholesky().unwrap();
    let prof = profile();
    let nominal = points(&cal);
    let draws = 2000;
    let mut rng = SplitMix64(23);
    let mut sums = vec![(Vector3::<f64>::zeros(), Matrix3::<f64>::zeros()); prof.points.len()];
    for _ in 0..draws {
        let z = DMatrix::from_fn(named.parameters.len(), 1, |_, _| rng.normal());
        let delta = chol.l() * z;
        let c = perturbed_profiler_calibration(&cal, &named.parameters, delta.as_slice()).unwrap();
        for (s, p) in sums.iter_mut().zip(points(&c)) {
            s.0 += p;
            s.1 += p * p.transpose();
        }
    }
    for ((s, xz), p0) in sums.iter().zip(&prof.points).zip(&nominal) {
        let l = frame.local(xz[0], xz[1]).unwrap();
        assert!((l.p_base - p0).norm() < 1e-9, "{:?} vs {p0:?}", l.p_base);
        let m = s.0 / draws as f64;
        let mc = (s.1 - m * m.transpose() * draws as f64) / (draws - 1) as f64;
        let c = frame.point_covariance(xz[0], xz[1]);
        let an = Matrix3::new(c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5]);
        for k in 0..3 {
            let (a, b) = (an[(k, k)].sqrt(), mc[(k, k)].sqrt());
            println!("profile point {xz:?} axis {k}: propagated {a:.5} mm, Monte Carlo {b:.5} mm");
            assert!(
                (a / b - 1.0).abs() < 0.05,
                "point {xz:?} axis {k}: {a} vs {b}"
            );
            for l in 0..k {
                let ra = an[(k, l)] / (an[(k, k)] * an[(l, l)]).sqrt();
                let rb = mc[(k, l)] / (mc[(k, k)] * mc[(l, l)]).sqrt();
                assert!(
                    (ra - rb).abs() < 0.05,
                    "point {xz:?} corr {k}{l}: {ra} vs {rb}"
                );
            }
        }
    }
}

/// Without the calibration part a point's covariance is its own noise along the
/// sensor's z, `sigma^2 R e_z e_z^T R^T`, the default sigma the calibration's
/// `profile_rms_mm`; the camera-only options are not read; bad figures are refused.
#[test]
fn profiler_point_noise_is_along_z() {
    let cal = profiler_calibration();
    let q = RobotReading::Joints(Q.to_vec());
    for (sigma, want) in [(None, 0.01), (Some(0.03), 0.03)] {
        let o = UncertaintyOptions {
            calibration: false,
            profile_sigma_mm: sigma,
            stripe_sigma_px: Some(5.0),
            ..Default::default()
        };
        let m = UncertaintyModel::profiler(&cal, &o).unwrap();
        let f = m.frame(&q).unwrap();
        let ez = f.rotation().column(2).into_owned();
        let c = f.point_covariance(3.0, 95.0);
        let e = want * want * ez * ez.transpose();
        let got = Matrix3::new(c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5]);
        assert!((got - e).norm() < 1e-15, "{got} vs {e}");
        assert!(matches!(f.chain(), SensorChain::Profiler));
        assert!(f.point_covariance(f64::NAN, 95.0)[0].is_nan());
        assert!(f.local(f64::INFINITY, 95.0).is_err());
    }
    let bad = UncertaintyOptions {
        profile_sigma_mm: Some(-0.1),
        ..Default::default()
    };
    assert!(UncertaintyModel::profiler(&cal, &bad).is_err());
    let mut none = cal.clone();
    none.covariance = None;
    let e = UncertaintyModel::profiler(&none, &UncertaintyOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("no covariance"), "{e}");
    // DH numbers need joint readings.
    let flange = RobotReading::FlangePose(cal.robot.as_ref().unwrap().forward(&Q).unwrap());
    let m = UncertaintyModel::profiler(&cal, &UncertaintyOptions::default()).unwrap();
    assert!(m.frame(&flange).is_err());
}
