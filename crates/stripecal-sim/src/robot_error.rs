//! Random robot errors: the true DH table differs from the nominal one (rig.json) by a
//! Gaussian draw per joint from the configuration's seed (`robot_error`).
//!
//! Every row draws five standard normals in a fixed order (theta0, alpha, a, d, beta)
//! from a stream of its own ([`ROBOT_ERROR_STREAM`]), so poses, images and noise draw
//! the same numbers whether the knob is set or not, and a seed gives the same robot on
//! every platform. beta (Hayati's tilt, spec/DATASET.md "Robot (DH)") is applied only
//! on rows whose NOMINAL alpha is within [`PARALLEL_ALPHA_TOL_DEG`] of 0 or +-180 deg
//! (the joint's axis nearly parallel to the previous one), never on the last row.

use serde::{Deserialize, Serialize};

use stripecal::{DhJoint, Robot};

use crate::rng::Rng;
use crate::SimError;

/// The random stream of the robot errors (independent of every other draw).
pub const ROBOT_ERROR_STREAM: u64 = 0x726f_626f_7445;

/// A row is "parallel" (beta drawn) when its nominal alpha is this close to 0 or +-180.
pub const PARALLEL_ALPHA_TOL_DEG: f64 = 1.0;

/// One-sigma of each DH quantity's random error (every key optional, default 0).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobotErrorCfg {
    pub theta0_deg: f64,
    pub alpha_deg: f64,
    pub a_mm: f64,
    pub d_mm: f64,
    /// Drawn only on nearly parallel rows (see the module docs).
    pub beta_deg: f64,
}

impl RobotErrorCfg {
    /// All sigmas zero: the true robot is nominal plus `dh_errors`.
    pub fn is_zero(&self) -> bool {
        self.sigmas().iter().all(|(_, s)| *s == 0.0)
    }

    fn sigmas(&self) -> [(&'static str, f64); 5] {
        [
            ("theta0_deg", self.theta0_deg),
            ("alpha_deg", self.alpha_deg),
            ("a_mm", self.a_mm),
            ("d_mm", self.d_mm),
            ("beta_deg", self.beta_deg),
        ]
    }

    /// Every sigma finite and >= 0; the message names the knob.
    pub fn validate(&self) -> Result<(), SimError> {
        for (k, v) in self.sigmas() {
            if !(v.is_finite() && v >= 0.0) {
                return Err(SimError::Config(format!(
                    "robot_error.{k}: {v} must be finite and >= 0 (a one-sigma)"
                )));
            }
        }
        Ok(())
    }
}

/// Whether Hayati's beta is drawn on row `i` of `nominal` (alpha within
/// [`PARALLEL_ALPHA_TOL_DEG`] of 0 or +-180, not the last row).
pub fn beta_row(nominal: &Robot, i: usize) -> bool {
    if i + 1 >= nominal.joints.len() {
        return false;
    }
    let a = nominal.joints[i].alpha_deg.rem_euclid(180.0);
    a.min(180.0 - a) <= PARALLEL_ALPHA_TOL_DEG
}

/// The random errors per row (true minus nominal, on top of `dh_errors`) for `seed`.
pub fn draw(cfg: &RobotErrorCfg, nominal: &Robot, seed: u64) -> Vec<DhJoint> {
    let mut rng = Rng::new(seed, ROBOT_ERROR_STREAM);
    (0..nominal.joints.len())
        .map(|i| {
            let z: [f64; 5] = std::array::from_fn(|_| rng.normal());
            DhJoint {
                theta0_deg: cfg.theta0_deg * z[0],
                alpha_deg: cfg.alpha_deg * z[1],
                a_mm: cfg.a_mm * z[2],
                d_mm: cfg.d_mm * z[3],
                beta_deg: if beta_row(nominal, i) {
                    cfg.beta_deg * z[4]
                } else {
                    0.0
                },
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beta_only_on_the_hp3_parallel_row() {
        let r = Robot::hp3();
        let rows: Vec<usize> = (0..r.dof()).filter(|&i| beta_row(&r, i)).collect();
        assert_eq!(rows, vec![1], "row 2 (alpha 180); row 6 is last");
    }

    #[test]
    fn draws_are_reproducible_and_scaled() {
        let cfg = RobotErrorCfg {
            theta0_deg: 0.05,
            alpha_deg: 0.02,
            a_mm: 0.3,
            d_mm: 0.3,
            beta_deg: 0.02,
        };
        let r = Robot::hp3();
        assert_eq!(draw(&cfg, &r, 3), draw(&cfg, &r, 3));
        assert_ne!(draw(&cfg, &r, 3), draw(&cfg, &r, 4));
        let zero = draw(&RobotErrorCfg::default(), &r, 3);
        assert!(zero.iter().all(|j| j.theta0_deg == 0.0 && j.a_mm == 0.0));
        let bad = RobotErrorCfg { a_mm: -1.0, ..cfg };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("robot_error.a_mm"));
    }
}
