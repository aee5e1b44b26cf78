//! The twin's robot knobs: the nominal DH table (rig.json's) and the true robot (its
//! DH errors, given and drawn).

use serde::{Deserialize, Serialize};

use stripecal::{DhJoint, Robot};

use super::{bad, SimConfig};
use crate::SimError;

/// One DH row.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DhCfg {
    pub theta0_deg: f64,
    pub alpha_deg: f64,
    pub a_mm: f64,
    pub d_mm: f64,
    /// Hayati's tilt about the new y axis (spec/DATASET.md, "Robot (DH)"); default 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub beta_deg: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// The robot's nominal DH table (written to rig.json).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotCfg {
    pub name: String,
    pub joints: Vec<DhCfg>,
}

impl SimConfig {
    /// `dh_errors`: none, or one row per joint.
    pub(super) fn validate_dh_errors(&self) -> Result<(), SimError> {
        if !self.dh_errors.is_empty() && self.dh_errors.len() != self.robot.joints.len() {
            return bad(
                "dh_errors",
                format!(
                    "{} rows given, robot has {} joints",
                    self.dh_errors.len(),
                    self.robot.joints.len()
                ),
            );
        }
        Ok(())
    }

    /// The nominal robot (rig.json).
    pub fn robot_nominal(&self) -> Result<Robot, SimError> {
        let joints = self
            .robot
            .joints
            .iter()
            .map(|j| DhJoint {
                theta0_deg: j.theta0_deg,
                alpha_deg: j.alpha_deg,
                a_mm: j.a_mm,
                d_mm: j.d_mm,
                beta_deg: j.beta_deg,
            })
            .collect();
        Robot::new(self.robot.name.clone(), joints)
            .map_err(|e| SimError::Config(format!("robot: {e}")))
    }

    /// The true robot: nominal plus `dh_errors` plus the random errors of
    /// `robot_error` drawn from the seed ([`crate::robot_error::draw`]).
    pub fn robot_true(&self) -> Result<Robot, SimError> {
        let mut r = self.robot_nominal()?;
        for (j, e) in r.joints.iter_mut().zip(&self.dh_errors) {
            j.theta0_deg += e[0];
            j.alpha_deg += e[1];
            j.a_mm += e[2];
            j.d_mm += e[3];
        }
        if !self.robot_error.is_zero() {
            let nominal = self.robot_nominal()?;
            let draws = crate::robot_error::draw(&self.robot_error, &nominal, self.seed);
            for (j, e) in r.joints.iter_mut().zip(&draws) {
                j.theta0_deg += e.theta0_deg;
                j.alpha_deg += e.alpha_deg;
                j.a_mm += e.a_mm;
                j.d_mm += e.d_mm;
                j.beta_deg += e.beta_deg;
            }
            Robot::new(r.name.clone(), r.joints.clone())
                .map_err(|e| SimError::Config(format!("robot_error: {e}")))?;
        }
        Ok(r)
    }
}
