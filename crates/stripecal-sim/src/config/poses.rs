//! The twin's calibration-pose knobs, and the pose columns views.csv and scan.csv give
//! the robot's poses in.

use serde::{Deserialize, Serialize};

use super::{bad, SimConfig};
use crate::SimError;

/// How calibration poses are chosen.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PosesCfg {
    /// Number of calibration views.
    pub count: usize,
    /// Encoder readings (deg) of the home pose around which poses are sampled.
    pub home_q_deg: Vec<f64>,
    /// Stand-off range: distance from the camera centre to the board plane along the
    /// optical axis, mm.
    pub standoff_mm: [f64; 2],
    /// Largest angle between the optical axis and the board normal, degrees.
    pub max_tilt_deg: f64,
    /// Largest rotation about the optical axis away from the board's upright view, deg.
    pub max_roll_deg: f64,
    /// Largest joint excursion from home, degrees.
    pub max_joint_delta_deg: f64,
    /// Every circle must be at least this far inside the image, px.
    pub margin_px: f64,
    /// Largest angle of incidence of the laser sheet on the board (at the stripe's
    /// middle), degrees: a grazing stripe is wide and faint.
    pub max_laser_incidence_deg: f64,
    /// Explicit encoder readings (deg) per view; when given, no sampling happens.
    pub explicit_q_deg: Option<Vec<Vec<f64>>>,
    /// Poses with the stripe BESIDE the printed pattern: mostly on the plate around it
    /// and crossing the plate's edge onto the table ([`crate::poses::StripeLayout`]),
    /// instead of across the pattern (default `false`).
    #[serde(default)]
    pub stripe_beside_pattern: bool,
    /// One-sigma (degrees) of Gaussian noise added to every joint reading of the
    /// calibration views as views.csv gives them (and [`crate::Twin::exact_observations`]'s
    /// robot poses), drawn per view from the seed; the images are rendered at the true
    /// readings: a robot whose readings are off (repeatability, encoder noise), the
    /// robot-pose noise the calibration estimates. truth.json's `images` then hold the
    /// reported readings too (`q_reading_deg`). The scan's readings stay exact. Default 0.
    #[serde(default)]
    pub reading_noise_deg: f64,
    /// How sampled poses spread: `local` (the default: around the home pose, diverse in
    /// orientation) or `wide` (many feasible candidates over the allowed joint
    /// excursions, then the `count` farthest apart in joint space, each joint's
    /// excursion normalised by `max_joint_delta_deg`: [`crate::poses_wide`]).
    #[serde(default = "default_spread")]
    pub spread: String,
}

pub(super) fn default_spread() -> String {
    "local".into()
}

impl PosesCfg {
    /// The readings against the robot's `joints`, the count, the reading noise and the
    /// spread.
    pub(super) fn validate(&self, joints: usize) -> Result<(), SimError> {
        if self.home_q_deg.len() != joints {
            return bad(
                "poses.home_q_deg",
                format!(
                    "{} values given, robot has {} joints",
                    self.home_q_deg.len(),
                    joints
                ),
            );
        }
        if let Some(ex) = &self.explicit_q_deg {
            if let Some((i, q)) = ex.iter().enumerate().find(|(_, q)| q.len() != joints) {
                return bad(
                    "poses.explicit_q_deg",
                    format!(
                        "view {i} has {} values, robot has {} joints",
                        q.len(),
                        joints
                    ),
                );
            }
        } else if self.count < 1 {
            return bad("poses.count", "must be at least 1".into());
        }
        let rn = self.reading_noise_deg;
        if !(rn.is_finite() && rn >= 0.0) {
            return bad(
                "poses.reading_noise_deg",
                format!("{rn} must be finite and >= 0"),
            );
        }
        if !matches!(self.spread.as_str(), "local" | "wide") {
            return bad(
                "poses.spread",
                format!("{:?} (expected \"local\" or \"wide\")", self.spread),
            );
        }
        Ok(())
    }

    /// The stand-off range.
    pub(super) fn validate_standoff(&self) -> Result<(), SimError> {
        let [a, b] = self.standoff_mm;
        if !(a > 0.0 && b >= a) {
            return bad(
                "poses.standoff_mm",
                format!("[{a}, {b}] is not a range of positive distances"),
            );
        }
        Ok(())
    }
}

impl SimConfig {
    /// The flange-pose columns of views.csv and scan.csv, `None` for joint readings.
    pub fn pose_columns_model(&self) -> Result<Option<stripecal::io::PoseColumns>, SimError> {
        self.pose_columns
            .as_deref()
            .map(|spec| {
                stripecal::io::PoseColumns::from_spec(&[spec])
                    .map_err(|e| SimError::Config(format!("pose_columns: {e}")))
            })
            .transpose()
    }
}
