//! The profiler's calibration (issue 18) on the twin's profiler mode, in memory (the
//! twin's profiles handed over as read, no files): the hand-eye against the truth, the
//! leave-one-out figure against the same figure with the truth, the robot's DH
//! corrections on the robot-error twin.

use nalgebra::{Point3, Vector3};
use serde_json::json;

use stripecal::calib::joint::RobotMode;
use stripecal::model::{ProfileRig, RobotReading};
use stripecal::pipeline::profile::{
    calibrate_profiles, ProfileCalibrateOptions, ProfileInput, ProfileReport,
};
use stripecal_sim::{SimConfig, Twin};

/// The twin's profiles as the calibration's inputs, its rig, and the twin.
fn twin(seed: u64, overrides: serde_json::Value) -> (Twin, Vec<ProfileInput>, ProfileRig) {
    let mut cfg = SimConfig::hp3_profiler()
        .with_overrides(&overrides)
        .unwrap();
    cfg.seed = seed;
    let twin = Twin::new(cfg).unwrap();
    let (inputs, rig) = twin.profiler_inputs().unwrap();
    (twin, inputs, rig)
}

fn errors(rep: &ProfileReport, twin: &Twin) -> (f64, f64) {
    let e = rep.calibration.hand_sensor.inverse() * twin.hand_sensor();
    (e.rotation.angle().to_degrees(), e.translation.vector.norm())
}

/// Item 1 (three seeds here; scripts/profiler_acceptance.py runs ten): the hand-eye
/// within 0.005 deg and 0.01 mm, its 3-sigma covering the truth; with the diameter
/// estimated, the diameter within 0.01 mm. Item 2: the leave-one-out figure within 1.5x
/// of the same figure with the true hand-eye, sphere and robot.
#[test]
fn hand_eye_from_the_twins_profiles() {
    for seed in 1..=3 {
        for declared in [true, false] {
            let (twin, inputs, rig) =
                twin(seed, json!({"profiler": {"diameter_declared": declared}}));
            let rep = calibrate_profiles(&inputs, &rig, &ProfileCalibrateOptions::default())
                .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            let (deg, mm) = errors(&rep, &twin);
            let truth_centre = Vector3::from(twin.cfg.profiler.sphere_center_mm);
            let d_true = twin.cfg.profiler.sphere_diameter_mm;
            let c = &rep.calibration;
            eprintln!(
                "seed {seed} declared {declared}: {deg:.5} deg {mm:.5} mm, centre {:.5} mm, \
                 diameter {:+.5} mm, rms {:.4}, k {:.2}",
                (c.sphere_center_mm - truth_centre).norm(),
                c.sphere_diameter_mm - d_true,
                c.quality.profile_rms_mm,
                rep.fit.view_variance_factor
            );
            assert!(deg < 0.005 && mm < 0.01, "seed {seed}: {deg} deg {mm} mm");
            assert!((c.sphere_diameter_mm - d_true).abs() < 0.01);
            // 3 sigma on every estimated number of X and the sphere
            let cov = c.covariance.as_ref().unwrap();
            let (rv, t) = stripecal::model::geometry::iso_to_rotvec(&c.hand_sensor);
            let (rv0, t0) = stripecal::model::geometry::iso_to_rotvec(&twin.hand_sensor());
            for k in 0..3 {
                let s = cov.sigma(&format!("hand_cam.translation_mm[{k}]")).unwrap();
                assert!(
                    (t[k] - t0[k]).abs() < 3.0 * s + 1e-12,
                    "t[{k}] {} > 3 x {s}",
                    t[k] - t0[k]
                );
                let s = cov
                    .sigma(&format!("hand_cam.rotation_vector[{k}]"))
                    .unwrap();
                assert!((rv[k] - rv0[k]).abs() < 3.0 * s + 1e-12, "r[{k}]");
                let s = cov.sigma(&format!("sphere.center_mm[{k}]")).unwrap();
                assert!(
                    (c.sphere_center_mm[k] - truth_centre[k]).abs() < 3.0 * s,
                    "c[{k}]"
                );
            }
            // item 2: the same figure with the truth, over the same points
            let loo = rep.leave_one_out.as_ref().unwrap();
            let robot = twin.cfg.robot_true().unwrap();
            let x = twin.hand_sensor();
            let mut truth_rms = Vec::new();
            for (v, st) in loo.views.iter().zip(rep.views.iter().filter(|s| s.used)) {
                let inp = &inputs[v.view];
                let RobotReading::Joints(q) = &inp.reading else {
                    unreachable!()
                };
                let a = robot.forward(q).unwrap() * x;
                let d: Vec<f64> = inp
                    .profile
                    .points
                    .iter()
                    .map(|p| {
                        let pb = a * Point3::new(p[0], 0.0, p[1]);
                        (pb.coords - truth_centre).norm() - 0.5 * d_true
                    })
                    .filter(|e| e.abs() < 0.1)
                    .collect();
                assert_eq!(st.view, v.view);
                truth_rms.push((d.iter().map(|e| e * e).sum::<f64>() / d.len() as f64).sqrt());
            }
            truth_rms.sort_by(f64::total_cmp);
            let truth_median = truth_rms[truth_rms.len() / 2];
            let ratio = loo.median_rms_mm / truth_median;
            eprintln!(
                "  loo {:.5} truth {truth_median:.5} ratio {ratio:.3}",
                loo.median_rms_mm
            );
            assert!((1.0 / 1.5..1.5).contains(&ratio), "ratio {ratio}");
        }
    }
}

/// Item 4 (one seed here): with joint readings and the robot-error twin, `--robot auto`
/// lowers the held-out sphere-surface RMS at least 3x against `--robot fixed`.
#[test]
fn robot_auto_lowers_the_held_out_rms() {
    let (_, inputs, rig) = twin(
        5,
        json!({
            "robot_error": {"theta0_deg": 0.05, "a_mm": 0.3, "d_mm": 0.3, "alpha_deg": 0.02},
            "profiler": {"views": 40}
        }),
    );
    let run = |mode: RobotMode| {
        let opts = ProfileCalibrateOptions {
            robot: mode,
            ..Default::default()
        };
        calibrate_profiles(&inputs, &rig, &opts).unwrap_or_else(|e| panic!("{mode:?}: {e}"))
    };
    let fixed = run(RobotMode::Fixed);
    let auto = run(RobotMode::Auto);
    let (f, a) = (
        fixed.leave_one_out.as_ref().unwrap().median_rms_mm,
        auto.leave_one_out.as_ref().unwrap().median_rms_mm,
    );
    let rc = auto.fit.robot.as_ref().unwrap();
    eprintln!(
        "held-out RMS fixed {f:.4} mm, auto {a:.4} mm ({:.1}x); estimated {:?}",
        f / a,
        rc.estimated
            .iter()
            .map(|e| e.name.clone())
            .collect::<Vec<_>>()
    );
    assert!(f / a >= 3.0, "fixed {f} auto {a}");
}
