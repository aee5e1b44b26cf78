//! Pose planning against the twin: the sigmas `plan_poses` predicts from the poses alone
//! agree with a Monte Carlo of the real adjustment over noisy observations of the same
//! poses.
//!
//! The Monte Carlo: the twin's exact observations (`Twin::exact_observations`) plus
//! Gaussian noise of the planned sigmas (`noisy_observations`), STRIPECAL_PLAN_DRAWS
//! draws (default 50), each through `joint_adjustment` from the truth with the case's
//! options: the adjustment's defaults (variance components ON, robust OFF, the robot
//! poses exact), the same `FreeBlocks` as the plan. Every estimated number's empirical
//! standard deviation must be within a factor 1.5 of the predicted one (the standard
//! error of a standard deviation from 50 draws is 10 %).
//!
//! `cargo test -p stripecal --test it plan_poses:: -- --nocapture` prints the table.

use stripecal::calib::joint::{
    joint_adjustment, FreeBlocks, JointOptions, JointResult, JointStart, RobotMode, RobotOptions,
};
use stripecal::model::geometry::iso_to_rotvec;
use stripecal::model::Calibration;
use stripecal::pipeline::{plan_poses, PlanOptions};
use stripecal::reconstruct::Triangulator;
use stripecal::Error;
use stripecal_sim::rng::Rng;
use stripecal_sim::{noisy_observations, SimConfig, Twin};

const POSES: usize = 15;

fn twin() -> Twin {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"seed": 7, "poses": {"count": POSES}}))
        .unwrap();
    Twin::new(cfg).unwrap()
}

fn nominal(t: &Twin) -> Calibration {
    t.true_calibration()
}

/// The value of a calibration.json number in an adjustment's result; rotation vectors
/// on the branch nearest the truth's `t` (a rotation by nearly pi has two).
fn value(t: &Twin, r: &JointResult, name: &str) -> f64 {
    let idx = |s: &str| -> usize {
        let a = s.find('[').unwrap();
        s[a + 1..s.len() - 1].parse().unwrap()
    };
    let p = r.camera.params();
    match name {
        "camera.fu" => p[0],
        "camera.fv" => p[1],
        "camera.u0" => p[2],
        "camera.v0" => p[3],
        n if n.starts_with("camera.distortion[") => p[4 + idx(n)],
        n if n.starts_with("laser_plane.normal[") => r.plane.unwrap().normal[idx(n)],
        "laser_plane.d_mm" => r.plane.unwrap().d,
        "board.scale" => r.board_scale,
        n if n.starts_with("robot.joints[") => {
            let rc = r.robot.as_ref().expect("a robot calibration");
            rc.estimated
                .iter()
                .find(|e| e.name == n)
                .unwrap_or_else(|| panic!("{n} was not estimated"))
                .correction
        }
        n => {
            let (key, rest) = n.split_once('.').unwrap();
            let (est, truth) = match key {
                "hand_cam" => (&r.hand_cam, &t.hand_cam),
                "base_board" => (&r.base_board, &t.base_board),
                _ => panic!("no value for {n}: add it here with its block"),
            };
            let (rv, tv) = iso_to_rotvec(est);
            let (rt, _) = iso_to_rotvec(truth);
            let other = rv - rv.normalize() * std::f64::consts::TAU;
            let rv = if (other - rt).norm() < (rv - rt).norm() {
                other
            } else {
                rv
            };
            if rest.starts_with("rotation_vector") {
                rv[idx(rest)]
            } else {
                tv[idx(rest)]
            }
        }
    }
}

/// One case of the comparison: the adjustment's options (a new block, e.g. the robot's
/// DH corrections, is another case).
struct Case {
    name: &'static str,
    adjustment: JointOptions,
    free: FreeBlocks,
    robot: RobotMode,
}

fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "defaults (camera, plane, X, Z; rigid robot)",
            adjustment: JointOptions::default(),
            free: FreeBlocks::default(),
            robot: RobotMode::Fixed,
        },
        Case {
            name: "with the robot's DH corrections (--robot full)",
            adjustment: JointOptions::default(),
            free: FreeBlocks::default(),
            robot: RobotMode::Full,
        },
    ]
}

#[test]
fn predicted_sigmas_agree_with_a_monte_carlo_of_the_adjustment() {
    let draws: usize = std::env::var("STRIPECAL_PLAN_DRAWS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(50);
    let t = twin();
    let poses = t.calibration_poses().unwrap();
    let joints: Vec<Vec<f64>> = poses.iter().map(|p| p.q_deg.clone()).collect();
    let mut rig = t.rig().unwrap();
    // The poses the exact observations were made at (the true robot's).
    rig.robot = Some(t.robot_true.clone());
    let exact = t.exact_observations().unwrap();
    let nominal = nominal(&t);
    let start = JointStart {
        camera: t.camera.clone(),
        plane: Some(t.laser_plane),
        hand_cam: t.hand_cam,
        base_board: t.base_board,
    };
    for case in cases() {
        let opts = PlanOptions {
            free: case.free,
            adjustment: case.adjustment.clone(),
            plate_margin_mm: Some(t.cfg.board.plate_margin_mm),
            margin_px: 0.0,
            robot: case.robot,
            ..PlanOptions::default()
        };
        let plan = plan_poses(&rig, &nominal, &joints, &opts).unwrap();
        assert_eq!(plan.usable, POSES, "{:?}", plan.poses);
        // The predicted views are the twin's: counts, stand-off and tilt.
        for ((p, info), v) in plan.poses.iter().zip(&poses).zip(&exact) {
            println!(
                "pose {:2}: points {:3} (twin {:3}), stripe {:4} (twin {:4}), stand-off {:6.1} (twin {:6.1}) mm, tilt {:5.1} (twin {:5.1}) deg",
                p.pose,
                p.points,
                v.circles.len(),
                p.stripe_points,
                v.stripe.len(),
                p.standoff_mm.unwrap(),
                info.standoff_mm,
                p.tilt_deg.unwrap(),
                info.tilt_deg
            );
            assert!((p.standoff_mm.unwrap() - info.standoff_mm).abs() < 1e-6);
            assert!((p.tilt_deg.unwrap() - info.tilt_deg).abs() < 1e-6);
            assert_eq!(p.points, v.circles.len());
            let (a, b) = (p.stripe_points as f64, v.stripe.len() as f64);
            assert!((a - b).abs() <= 0.1 * b + 5.0, "{a} vs {b}");
        }
        let jopts = JointOptions {
            free: case.free,
            robot: (case.robot != RobotMode::Fixed).then(|| RobotOptions {
                nominal: rig.robot.clone().unwrap(),
                mode: case.robot,
            }),
            ..case.adjustment.clone()
        };
        for h in &plan.robot_held {
            println!("held {}: {}", h.name, h.reason);
        }
        let mut samples: Vec<Vec<f64>> = vec![Vec::new(); plan.parameters.len()];
        // The plan's point in the board's frame, from each draw's calibration: its pixel
        // triangulated, put in the base frame at the plan's pose, then Z^-1.
        let pt = plan.point.clone().unwrap();
        let pose_q = &joints[pt.base_pose.unwrap()];
        let mut board_points: Vec<nalgebra::Vector3<f64>> = Vec::new();
        for k in 0..draws {
            let noisy = noisy_observations(
                &exact,
                opts.sigma_px.0,
                opts.sigma_px.1,
                &mut Rng::new(1000 + k as u64, 11),
            );
            let r = joint_adjustment(&noisy, &t.board, &start, &jopts).unwrap();
            let robot = r
                .robot
                .as_ref()
                .map_or(rig.robot.clone().unwrap(), |c| c.robot.clone());
            let tri = Triangulator::new(&r.camera, &r.plane.unwrap(), &r.hand_cam, 0.0).unwrap();
            let pc = tri.point_cam_mm(pt.pixel[0], pt.pixel[1]).unwrap();
            let a = robot.forward(pose_q).unwrap();
            let pb = r.base_board.inverse() * (a * (r.hand_cam * nalgebra::Point3::from(pc)));
            board_points.push(pb.coords);
            for (s, e) in samples.iter_mut().zip(&plan.parameters) {
                s.push(value(&t, &r, &e.name));
            }
        }
        println!("{}: {draws} draws", case.name);
        println!(
            "{:32} {:>12} {:>12} {:>7}",
            "parameter", "predicted", "Monte Carlo", "ratio"
        );
        let mut worst: f64 = 1.0;
        for (s, e) in samples.iter().zip(&plan.parameters) {
            let m = s.iter().sum::<f64>() / s.len() as f64;
            let sd =
                (s.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (s.len() - 1) as f64).sqrt();
            let ratio = e.sigma / sd;
            println!("{:32} {:12.4e} {:12.4e} {:7.3}", e.name, e.sigma, sd, ratio);
            worst = worst.max(ratio).max(1.0 / ratio);
        }
        let point = plan.point.as_ref().unwrap();
        println!(
            "point at {:.1} mm: sigma camera {:?} (norm {:.4} mm), base {:?} (norm {:.4} mm)",
            point.standoff_mm,
            point.sigma_camera_mm,
            point.sigma_camera_norm_mm,
            point.sigma_base_mm,
            point.sigma_base_norm_mm.unwrap()
        );
        let n = board_points.len() as f64;
        let mean = board_points.iter().sum::<nalgebra::Vector3<f64>>() / n;
        let mc: Vec<f64> = (0..3)
            .map(|k| {
                (board_points
                    .iter()
                    .map(|p| (p[k] - mean[k]).powi(2))
                    .sum::<f64>()
                    / (n - 1.0))
                    .sqrt()
            })
            .collect();
        let pred = pt.sigma_board_mm.unwrap();
        println!("board-frame point: predicted {pred:?} mm, Monte Carlo {mc:?} mm");
        for k in 0..3 {
            let ratio = pred[k] / mc[k];
            worst = worst.max(ratio).max(1.0 / ratio);
        }
        println!("largest factor {worst:.3}");
        assert!(worst < 1.5, "{}: a sigma is off by {worst:.3}", case.name);
    }
}

/// Poses that do not see the board are reported and left out; fewer than 3 usable ones
/// is a typed error naming them; a joint vector of the wrong length is one too.
#[test]
fn unusable_poses_are_reported_and_too_few_is_an_error() {
    let t = twin();
    let rig = t.rig().unwrap();
    let nominal = nominal(&t);
    let mut joints: Vec<Vec<f64>> = t
        .calibration_poses()
        .unwrap()
        .iter()
        .take(4)
        .map(|p| p.q_deg.clone())
        .collect();
    // Looking away: joint 1 turned by 90 degrees.
    let mut away = joints[0].clone();
    away[0] += 90.0;
    joints.push(away.clone());
    let plan = plan_poses(&rig, &nominal, &joints, &PlanOptions::default()).unwrap();
    assert_eq!(plan.usable, 4);
    let last = plan.poses.last().unwrap();
    assert!(!last.usable && last.reason.is_some(), "{last:?}");
    println!("{:?}", last.reason);
    let s = serde_json::to_value(&plan).unwrap();
    for key in [
        "poses",
        "parameters",
        "covariance",
        "state",
        "point",
        "usable",
    ] {
        assert!(s.get(key).is_some(), "{key}");
    }
    let Err(e) = plan_poses(
        &rig,
        &nominal,
        &[joints[0].clone(), joints[1].clone(), away],
        &PlanOptions::default(),
    ) else {
        panic!("two usable poses are too few")
    };
    assert!(matches!(e, Error::InvalidInput(_)), "{e}");
    assert!(e.to_string().contains("pose 2"), "{e}");
    // The same pose three times: X and Z cannot be told apart, and are named.
    let same = vec![joints[0].clone(); 3];
    let Err(e) = plan_poses(&rig, &nominal, &same, &PlanOptions::default()) else {
        panic!("one pose repeated determines nothing of the chain")
    };
    assert!(matches!(e, Error::Degenerate(_)), "{e}");
    assert!(e.to_string().contains("hand_cam"), "{e}");
    println!("{e}");
    let Err(e) = plan_poses(&rig, &nominal, &[vec![0.0; 3]], &PlanOptions::default()) else {
        panic!("3 joints for a 6-axis robot")
    };
    assert!(e.to_string().contains("pose 0"), "{e}");
}
