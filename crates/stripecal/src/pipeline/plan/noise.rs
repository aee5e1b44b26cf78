//! Phase 2 of a plan: the adjustment's options the covariance is predicted with: the
//! calibration's noise model (the robot-pose noise as planned, never below rig.json's
//! figures; the images' own part at its floor) and the robot's corrections estimated.

use super::PlanOptions;
use crate::calib::joint::{
    JointOptions, RobotMode, RobotOptions, IMAGE_FACTOR_FLOOR, POSE_NOISE_FLOOR,
};
use crate::error::{Error, Result};
use crate::model::{Calibration, Rig};

/// The adjustment's options for the plan of `rig` around `nominal`, and the robot-pose
/// noise planned (`(mm, deg)`; `None`: the robot planned exact).
pub(super) fn adjustment_options(
    rig: &Rig,
    nominal: &Calibration,
    opts: &PlanOptions,
) -> Result<(JointOptions, Option<(f64, f64)>)> {
    let mut jopts = JointOptions {
        free: opts.free,
        ..opts.adjustment.clone()
    };
    // The calibration's noise model: the robot-pose noise as planned, never below
    // rig.json's figures; the images' own part at its floor. Without any figure the
    // robot is planned exact (the poses without corrections: what an exact robot's
    // calibration, its pose noise at the floors, gives).
    let floors = rig
        .robot
        .as_ref()
        .map_or((None, None), |r| r.pose_noise_floor());
    let planned = opts
        .pose_noise
        .or_else(|| {
            crate::io::calibration_robot_pose_noise(nominal)
                .ok()
                .flatten()
                .map(|n| (n.sigma_translation_mm, n.sigma_rotation_deg))
                .filter(|(t, r)| t.is_finite() && r.is_finite())
        })
        .or_else(|| {
            (floors.0.is_some() || floors.1.is_some())
                .then(|| (floors.0.unwrap_or(0.0), floors.1.unwrap_or(0.0)))
        });
    let pose_noise = planned.map(|p| {
        (
            p.0.max(floors.0.unwrap_or(0.0)).max(POSE_NOISE_FLOOR.0),
            p.1.max(floors.1.unwrap_or(0.0)).max(POSE_NOISE_FLOOR.1),
        )
    });
    match pose_noise {
        Some(p) if jopts.robot_noise => {
            jopts.robot_floor = floors;
            jopts.initial_robot_sigma = p;
            jopts.initial_image_factor = IMAGE_FACTOR_FLOOR;
        }
        _ => jopts.robot_noise = false,
    }
    if opts.robot != RobotMode::Fixed {
        let nominal = rig.robot.clone().ok_or_else(|| {
            Error::InvalidInput("planning a robot calibration needs rig.json's robot".into())
        })?;
        jopts.robot = Some(RobotOptions {
            nominal,
            mode: opts.robot,
        });
    }
    Ok((jopts, pose_noise))
}
