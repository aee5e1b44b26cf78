//! The fixed-robot diagnosis (issue 14): a robot whose DH rows differ from rig.json's
//! forces wrong flange poses into every board pose. With the robot-pose noise (the
//! default) that shows as pose noise above its floors; with the rigid model
//! (`--no-robot-pose-noise`) the circle residuals rise far above what the detector
//! achieves with free board poses. That is said, with the figure, and `--robot auto`
//! suggested; it is a warning, not a failed calibration (DECISIONS 1: every real robot is
//! off by something).

use super::{CalibrateOptions, Method};
use crate::calib::joint::{JointResult, RobotMode};
use crate::calib::ViewObs;
use crate::model::{Rig, RobotReading};

/// The adjustment's circle RMS above this many times the detector's (the camera stage
/// with free board poses) says the robot's poses do not fit the images.
pub const KINEMATICS_FACTOR: f64 = 3.0;

/// The warning, when the robot was held (`--robot fixed`) and its poses do not fit.
pub(super) fn diagnose(
    adj: &JointResult,
    detector_rms_px: f64,
    rig: &Rig,
    used: &[ViewObs],
    opts: &CalibrateOptions,
) -> Option<String> {
    if opts.method != Method::OneStage || adj.robot.is_some() || opts.robot != RobotMode::Fixed {
        return None;
    }
    let joints = used
        .iter()
        .all(|v| matches!(v.reading, Some(RobotReading::Joints(_))));
    let figure = if let Some(n) = &adj.robot_noise {
        if n.translation_at_floor && n.rotation_at_floor {
            return None;
        }
        format!(
            "the robot-pose noise is {:.3} mm, {:.4} deg, above its floors ({:.3} mm, {:.4} \
             deg)",
            n.sigma_translation_mm,
            n.sigma_rotation_deg,
            n.floor_translation_mm,
            n.floor_rotation_deg
        )
    } else {
        let ratio = adj.circle_rms_px / detector_rms_px;
        if !(ratio.is_finite() && ratio > KINEMATICS_FACTOR) {
            return None;
        }
        format!(
            "the adjustment's circle residuals are {:.4} px RMS, {ratio:.0} x the detector's \
             {detector_rms_px:.4} px with free board poses",
            adj.circle_rms_px
        )
    };
    Some(if joints && rig.robot.is_some() {
        format!(
            "{figure}: the robot's poses do not fit the images (its DH rows differ from \
             rig.json's nominal ones, as every real arm's do); calibrate the robot with \
             `--robot auto`"
        )
    } else {
        format!(
            "{figure}: the controller's flange poses do not fit the images exactly (an \
             inaccurate robot); the robot-pose noise models their error (robot calibration \
             needs joint readings)"
        )
    })
}
