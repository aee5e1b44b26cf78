//! Honest sigmas on real robots (issue 38): split-half honesty on the shared real sets
//! and on a twin with a known robot error, and the twin's DH error held fixed against its
//! truth.
//!
//! Split half: the even and the odd views calibrated apart, `z = (a - b) / sqrt(s_a^2 +
//! s_b^2)` for fu, u0, v0 and the hand-eye translation (the plane's d with a laser), as
//! `../shared/tools/split_half.py` does with the CLI. Honest sigmas give an RMS z near 1;
//! a calibration that claims several times the precision it has gives RMS z of several
//! (rosi_10x10 before issue 38: 6.9 with the rigid model, 3.8 with the opt-in pose
//! noise). The real sets live in `../shared/realdata` beside the repository; those tests
//! are skipped with a note when it is absent.
//!
//! `cargo test -p stripecal --test it calib_honesty:: -- --nocapture` prints the figures.

use crate::common::realdata;
use stripecal::calib::joint::RobotMode;
use stripecal::calib::ViewObs;
use stripecal::model::geometry::iso_to_rotvec;
use stripecal::model::Dataset;
use stripecal::pipeline::{
    calibrate_dataset_loaded, calibrate_observations, CalibrateOptions, CalibrationReport,
};
use stripecal_sim::rng::Rng;
use stripecal_sim::{noisy_observations, SimConfig, Twin};

fn no_loo() -> CalibrateOptions {
    CalibrateOptions {
        leave_one_out: false,
        ..CalibrateOptions::default()
    }
}

/// The numbers split-half compares: `(name, value, sigma)`.
fn numbers(rep: &CalibrationReport) -> Vec<(String, f64, f64)> {
    let (c, s) = (&rep.calibration, &rep.adjustment.sigma);
    let mut out = vec![
        ("fu".to_string(), c.camera.fu, s.camera[0]),
        ("u0".to_string(), c.camera.u0, s.camera[2]),
        ("v0".to_string(), c.camera.v0, s.camera[3]),
    ];
    for k in 0..3 {
        out.push((
            format!("X t{k}"),
            c.hand_cam.translation.vector[k],
            s.hand_cam.translation_mm[k],
        ));
    }
    if let Some(p) = &c.laser_plane {
        out.push(("plane d".into(), p.d, s.plane_d_mm));
    }
    out
}

/// The z of every number between two calibrations, printed.
fn split_z(name: &str, a: &CalibrationReport, b: &CalibrationReport) -> Vec<f64> {
    let (na, nb) = (numbers(a), numbers(b));
    let z: Vec<f64> = na
        .iter()
        .zip(&nb)
        .map(|(x, y)| (x.1 - y.1) / x.2.hypot(y.2))
        .collect();
    let rms = (z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64).sqrt();
    let each: Vec<String> = na
        .iter()
        .zip(&z)
        .map(|(x, z)| format!("{} {z:+.1}", x.0))
        .collect();
    println!("{name}: split-half RMS z {rms:.2} | {}", each.join("  "));
    z
}

fn rms(z: &[f64]) -> f64 {
    (z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64).sqrt()
}

/// The even (`parity` 0) or odd views of a dataset.
fn half(ds: &Dataset, parity: usize) -> Dataset {
    Dataset {
        views: ds
            .views
            .iter()
            .enumerate()
            .filter(|(i, _)| i % 2 == parity)
            .map(|(_, v)| v.clone())
            .collect(),
        ..ds.clone()
    }
}

fn real_split(name: &str) -> Option<Vec<f64>> {
    let root = realdata()?.join(name);
    let ds = Dataset::load(&root).unwrap();
    let a = calibrate_dataset_loaded(&half(&ds, 0), &no_loo()).unwrap();
    let b = calibrate_dataset_loaded(&half(&ds, 1), &no_loo()).unwrap();
    Some(split_z(name, &a, &b))
}

/// The twin's views with noisy joint readings (`poses.reading_noise_deg`, one-sigma per
/// joint): the robot's pose error random, as a repeatability.
fn noisy_reading_views(seed: u64) -> (Twin, Vec<ViewObs>) {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({
            "seed": seed,
            "poses": {"count": 16, "reading_noise_deg": 0.015}
        }))
        .unwrap();
    let t = Twin::new(cfg).unwrap();
    let views = noisy_observations(
        &t.exact_observations().unwrap(),
        0.02,
        0.05,
        &mut Rng::new(seed, 11),
    );
    (t, views)
}

fn twin_split(name: &str, t: &Twin, views: &[ViewObs]) -> Vec<f64> {
    let rig = t.rig().unwrap();
    let even: Vec<ViewObs> = views.iter().step_by(2).cloned().collect();
    let odd: Vec<ViewObs> = views.iter().skip(1).step_by(2).cloned().collect();
    let a = calibrate_observations(&even, &rig, &no_loo()).unwrap();
    let b = calibrate_observations(&odd, &rig, &no_loo()).unwrap();
    split_z(name, &a, &b)
}

/// Acceptance 1 and 5 of issue 38: rosi_10x10 (15 views, 640 x 480, a 10 x 10 dot grid,
/// an arm off by about a millimetre; RMS z 6.9 before), etna_calib3 and etna_calib4 (with
/// the laser plane's d) and twins whose joint readings are
/// off by 0.015 deg (a random robot error) split into halves that agree within their
/// stated sigmas (RMS z at most 2 each), and, pooled, the sigmas are not inflated out of
/// use (RMS z at least 0.5).
#[test]
fn split_halves_are_honest_on_real_data_and_twins() {
    let mut pooled = Vec::new();
    if let Some(z) = real_split("rosi_10x10") {
        assert!(rms(&z) <= 2.0, "rosi_10x10: RMS z {}", rms(&z));
        pooled.extend(z);
    }
    // the laser cell: a saturated 18 px line, 10 views (RMS z 6.5 before; its halves
    // did not calibrate before the real-laser-lines issue)
    if let Some(z) = real_split("etna_calib3") {
        assert!(rms(&z) <= 2.0, "etna_calib3: RMS z {}", rms(&z));
        pooled.extend(z);
    }
    // its other session, 9 views: halves of 5 and 4 (the pairing gate refused two views
    // of the 5 before its limits counted 3 members' residuals as the prediction errors
    // they stand for); RMS z 1.99, at the acceptance's bound
    if let Some(z) = real_split("etna_calib4") {
        assert!(rms(&z) <= 2.0, "etna_calib4: RMS z {}", rms(&z));
        pooled.extend(z);
    }
    for seed in [2, 3] {
        let (t, views) = noisy_reading_views(seed);
        let z = twin_split(
            &format!("twin, readings 0.015 deg, seed {seed}"),
            &t,
            &views,
        );
        assert!(rms(&z) <= 2.0, "seed {seed}: RMS z {}", rms(&z));
        pooled.extend(z);
    }
    let r = rms(&pooled);
    println!("pooled RMS z {r:.2} over {} numbers", pooled.len());
    assert!((0.5..=2.0).contains(&r), "pooled RMS z {r}");
}

/// A twin whose rig.json has joint 2's link 2 mm short of the arm's (`--robot fixed`):
/// hand-eye and robot-world within 3 of their stated sigmas of the truth (the rigid
/// model was up to 205 sigmas off), the pose noise reports it and the DH error size the
/// covariance carries; its split halves are honest; with `--robot auto` the link is
/// found (and the poses are the calibrated robot's).
#[test]
fn a_dh_error_held_fixed_is_within_the_stated_sigmas() {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({
            "seed": 1,
            "poses": {"count": 16},
            "dh_errors": [[0, 0, 0, 0], [0, 0, 2.0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]]
        }))
        .unwrap();
    let t = Twin::new(cfg).unwrap();
    let rig = t.rig().unwrap();
    let mut views = noisy_observations(
        &t.exact_observations().unwrap(),
        0.02,
        0.05,
        &mut Rng::new(4, 11),
    );
    // The flange poses as the controller computes them: rig.json's (nominal) DH table.
    let nominal = rig.robot.clone().unwrap();
    for v in &mut views {
        let Some(stripecal::model::RobotReading::Joints(q)) = &v.reading else {
            panic!("joint readings")
        };
        v.base_hand = Some(nominal.forward(q).unwrap());
    }
    let rep = calibrate_observations(&views, &rig, &no_loo()).unwrap();
    let n = rep.adjustment.robot_noise.clone().unwrap();
    println!(
        "fixed: pose noise {:.4} mm {:.5} deg, DH errors {:?} mm {:?} deg",
        n.sigma_translation_mm, n.sigma_rotation_deg, n.kinematic_mm, n.kinematic_deg
    );
    assert!(n.sigma_translation_mm > 0.05 && n.kinematic_mm.is_some_and(|k| k > 0.1));
    let s = &rep.adjustment.sigma;
    let mut worst: f64 = 0.0;
    for (name, est, truth, sig) in [
        ("X", &rep.calibration.hand_cam, &t.hand_cam, &s.hand_cam),
        (
            "Z",
            &rep.calibration.base_board,
            &t.base_board,
            &s.base_board,
        ),
    ] {
        let (mut re, te) = iso_to_rotvec(est);
        let (rt, tt) = iso_to_rotvec(truth);
        if (re - rt).norm() > std::f64::consts::PI {
            re *= 1.0 - std::f64::consts::TAU / re.norm();
        }
        for k in 0..3 {
            let zr = (re[k] - rt[k]) / sig.rotation_vector[k];
            let zt = (te[k] - tt[k]) / sig.translation_mm[k];
            println!(
                "  {name} r{k} z {zr:+.2}  t{k} z {zt:+.2} ({:+.3} mm)",
                te[k] - tt[k]
            );
            worst = worst.max(zr.abs()).max(zt.abs());
        }
    }
    assert!(worst <= 3.0, "worst {worst}");
    // The halves see the same DH error: they agree (RMS z 0.13 here, their sigmas
    // carrying an error common to both that no split can show).
    let z = twin_split("twin, a_2 2 mm off", &t, &views);
    assert!(rms(&z) <= 2.0, "{z:?}");
    // --robot auto finds the link.
    let auto = CalibrateOptions {
        robot: RobotMode::Auto,
        ..no_loo()
    };
    let rep = calibrate_observations(&views, &rig, &auto).unwrap();
    let rc = rep.adjustment.robot.clone().unwrap();
    let a2 = rc
        .estimated
        .iter()
        .find(|e| e.name == "robot.joints[1].a_mm")
        .expect("a_2 estimated");
    println!(
        "auto: a_2 {:+.4} +- {:.4} mm, circles {:.4} px",
        a2.correction, a2.sigma, rep.calibration.quality.circle_rms_px
    );
    assert!((a2.correction - 2.0).abs() < 3.0 * a2.sigma, "{a2:?}");
    // The robot calibrated, its poses are the calibrated robot's (the rigid model of
    // wave two): no pose noise; the circles fit to their noise.
    assert!(rep.adjustment.robot_noise.is_none());
    assert!(rep.calibration.quality.circle_rms_px < 0.03);
}
