//! Robot kinematic calibration inside the one-stage adjustment (issue 14) against the
//! twin's truth: a TRUE robot whose DH rows differ from rig.json's nominal ones by the
//! amounts real arms show; observations are the twin's exact ones plus Gaussian noise
//! (no rendering), the robot poses the NOMINAL robot's forward kinematics of the
//! readings (what the pipeline computes from rig.json).
//!
//! `cargo test -p stripecal --test calib_robot -- --nocapture` prints the figures.

use stripecal::calib::joint::{
    joint_adjustment, JointOptions, JointResult, JointStart, RobotMode, RobotOptions,
};
use stripecal::calib::ViewObs;
use stripecal::model::geometry::Iso3;
use stripecal::model::RobotReading;
use stripecal_sim::rng::Rng;
use stripecal_sim::{noisy_observations, SimConfig, Twin};

const CIRCLE_PX: f64 = 0.02;
const STRIPE_PX: f64 = 0.05;

/// DH errors drawn like real arms': theta0 N(0, 0.05 deg), alpha N(0, 0.02 deg), a and d
/// N(0, 0.3 mm) per row.
fn dh_errors(dof: usize, seed: u64) -> Vec<[f64; 4]> {
    let mut rng = Rng::new(seed, 97);
    (0..dof)
        .map(|_| {
            [
                0.05 * rng.normal(),
                0.02 * rng.normal(),
                0.3 * rng.normal(),
                0.3 * rng.normal(),
            ]
        })
        .collect()
}

fn twin(count: usize, seed: u64, errors: bool) -> Twin {
    let mut cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"seed": seed, "poses": {"count": count}}))
        .unwrap();
    if errors {
        cfg.dh_errors = dh_errors(cfg.robot.joints.len(), seed);
    }
    Twin::new(cfg).unwrap()
}

/// Noisy observations with the nominal robot's flange poses.
fn views(t: &Twin, seed: u64) -> Vec<ViewObs> {
    let mut v = noisy_observations(
        &t.exact_observations().unwrap(),
        CIRCLE_PX,
        STRIPE_PX,
        &mut Rng::new(seed, 11),
    );
    for o in &mut v {
        let Some(RobotReading::Joints(q)) = &o.reading else {
            panic!("the twin reports joint readings");
        };
        o.base_hand = Some(t.robot_nominal.forward(q).unwrap());
    }
    v
}

fn run(t: &Twin, v: &[ViewObs], mode: RobotMode) -> JointResult {
    let start = JointStart {
        camera: t.camera.clone(),
        plane: Some(t.laser_plane),
        hand_cam: t.hand_cam,
        base_board: t.base_board,
    };
    let opts = JointOptions {
        robot: Some(RobotOptions {
            nominal: t.robot_nominal.clone(),
            mode,
        }),
        ..JointOptions::default()
    };
    joint_adjustment(v, &t.board, &start, &opts).unwrap()
}

/// RMS error (mm) of a point 100 mm in front of the camera at the poses `qs` (not used
/// in calibration), the estimated robot, X and Z against the truth, in the board's frame
/// (the base frame itself is known only up to what Z absorbs: the first row's theta0 and
/// d).
fn point_error(t: &Twin, r: &JointResult, qs: &[Vec<f64>]) -> f64 {
    let robot = r
        .robot
        .as_ref()
        .map_or(t.robot_nominal.clone(), |c| c.robot.clone());
    let p = nalgebra::Point3::new(0.0, 0.0, 100.0);
    let ss: f64 = qs
        .iter()
        .map(|q| {
            let est = r.base_board.inverse() * robot.forward(q).unwrap() * r.hand_cam * p;
            let tru = t.base_board.inverse() * t.robot_true.forward(q).unwrap() * t.hand_cam * p;
            (est - tru).norm_squared()
        })
        .sum();
    (ss / qs.len() as f64).sqrt()
}

fn pose_err(a: &Iso3, b: &Iso3) -> (f64, f64) {
    let d = a.inverse() * b;
    (d.rotation.angle().to_degrees(), d.translation.vector.norm())
}

#[test]
fn auto_recovers_the_robot_and_the_hand_eye() {
    let t = twin(15, 1, true);
    let v = views(&t, 1);
    // Poses of another draw of the pose generator: not used in calibration.
    let mut other = t.cfg.clone();
    other.seed = 1001;
    other.poses.count = 20;
    let qs: Vec<Vec<f64>> = Twin::new(other)
        .unwrap()
        .calibration_poses()
        .unwrap()
        .into_iter()
        .map(|p| p.q_deg)
        .collect();
    for mode in [
        RobotMode::Fixed,
        RobotMode::Offsets,
        RobotMode::Full,
        RobotMode::Auto,
    ] {
        let r = run(&t, &v, mode);
        let (xr, xt) = pose_err(&r.hand_cam, &t.hand_cam);
        let (zr, zt) = pose_err(&r.base_board, &t.base_board);
        println!(
            "{:8} point at new poses {:.4} mm RMS  circles {:.4} px  X {:.4} deg {:.4} mm  Z {:.4} deg {:.4} mm  iterations {}",
            mode.name(),
            point_error(&t, &r, &qs),
            r.circle_rms_px,
            xr,
            xt,
            zr,
            zt,
            r.iterations
        );
        if let Some(rc) = &r.robot {
            for e in &rc.estimated {
                println!("   {:32} {:+.4} +- {:.4}", e.name, e.correction, e.sigma);
            }
            for (n, why) in &rc.fixed {
                println!("   fixed {n}: {why}");
            }
        }
    }
}
