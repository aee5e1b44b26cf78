//! Every knob of the twin, as one serialisable configuration.
//!
//! A configuration is plain data (JSON from Python or the CLI): a preset gives all
//! values, and [`SimConfig::with_overrides`] merges a partial JSON object over it, so
//! `{"imaging": {"noise_gray": 2.0}}` changes one knob and keeps the rest. Unknown keys
//! are an error (a misspelt knob must not be silently ignored).
//!
//! Units: mm, degrees (angles in files), radians for rotation vectors, pixels,
//! gray levels of the 8-bit scale for noise (scaled by 257 for 16-bit images).
//!
//! One file per section, each with its validation and the stripecal model it makes:
//! `geometry` (camera, laser plane, poses), `robot`, `board`, `poses`, `imaging`,
//! `scan`; `presets` holds the built-in configurations.

mod board;
mod geometry;
mod imaging;
mod poses;
mod presets;
mod robot;
mod scan;

use serde::{Deserialize, Serialize};

pub use board::BoardCfg;
pub use geometry::{pose_cfg, pose_model, CameraCfg, PlaneCfg, PoseCfg};
pub use imaging::ImagingCfg;
pub use poses::PosesCfg;
pub use presets::PRESETS;
pub use robot::{DhCfg, RobotCfg};
pub use scan::ScanCfg;

use crate::bench::BenchCfg;
use crate::profiler::ProfilerCfg;
use crate::robot_error::RobotErrorCfg;
use crate::verify::VerifyCfg;
use crate::SimError;

/// Everything the twin needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    pub preset: String,
    pub seed: u64,
    pub camera: CameraCfg,
    pub laser_plane: PlaneCfg,
    pub hand_cam: PoseCfg,
    /// `T_base_board`; `None` places the board on the table where the home pose sees
    /// it at the middle of the stand-off range.
    pub base_board: Option<PoseCfg>,
    /// Nominal robot (rig.json).
    pub robot: RobotCfg,
    /// True-minus-nominal DH errors per joint `[d_theta0_deg, d_alpha_deg, d_a_mm, d_d_mm]`;
    /// empty = none.
    pub dh_errors: Vec<[f64; 4]>,
    /// One-sigma of random DH errors drawn per joint from the seed and added to the
    /// true robot (on top of `dh_errors`); default none ([`crate::robot_error`]).
    #[serde(default)]
    pub robot_error: RobotErrorCfg,
    pub board: BoardCfg,
    pub poses: PosesCfg,
    pub imaging: ImagingCfg,
    pub scan: ScanCfg,
    /// Stand-offs the rig is meant for (truth.json `working_range_mm`).
    pub working_range_mm: [f64; 2],
    /// rig.json `stripe.direction` hint: `auto`, `rows` or `cols`.
    pub stripe_direction: String,
    /// rig.json `stripe.channel`: `gray`, `red`, `green`, `blue` or `auto`; `None` (the
    /// default): the laser's colour for colour images (`imaging.colour`), gray otherwise.
    #[serde(default)]
    pub stripe_channel: Option<String>,
    /// How views.csv and scan.csv give the robot poses: `None` (the default) writes the
    /// encoder readings `q1..qN`; a pose convention writes the flange pose a controller
    /// would report instead, the NOMINAL robot's forward kinematics of the readings, in
    /// those columns: a shorthand (`ros`, `ur`, `kuka`, `fanuc`, `quaternion`, `rotvec`,
    /// `rotvec_deg`, `matrix`) or a header such as `"qx,qy,qz,qw,x_m,y_m,z_m"`
    /// (`stripecal::io::PoseColumns::from_spec`). rig.json keeps the robot either way.
    #[serde(default)]
    pub pose_columns: Option<String>,
    /// Verification artefacts: ball bar and plate scans with their certificate
    /// (`verify/`, default off; [`crate::verify`]).
    #[serde(default)]
    pub verify: VerifyCfg,
    /// The bench mode: a fixed sensor, the board placed by hand, no robot (default off;
    /// [`crate::bench`]).
    #[serde(default)]
    pub bench: BenchCfg,
    /// The profiler mode: a calibrated line profiler measuring a reference sphere
    /// (default off; [`crate::profiler`]).
    #[serde(default)]
    pub profiler: ProfilerCfg,
}

impl SimConfig {
    /// Merges a partial JSON object over this configuration (nested objects merge,
    /// everything else replaces); unknown keys are an error.
    pub fn with_overrides(&self, overrides: &serde_json::Value) -> Result<SimConfig, SimError> {
        let mut base = serde_json::to_value(self).map_err(|e| SimError::Config(e.to_string()))?;
        // A knob written only when set (truth.json as before it existed) is a knob too.
        if let Some(c) = base.get_mut("camera").and_then(|c| c.as_object_mut()) {
            c.entry("model").or_insert(serde_json::Value::Null);
        }
        merge(&mut base, overrides, "")?;
        let cfg: SimConfig = serde_json::from_value(base)
            .map_err(|e| SimError::Config(format!("invalid configuration: {e}")))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Checks every value; the message names the knob.
    pub fn validate(&self) -> Result<(), SimError> {
        self.camera_model()?;
        self.board_model()?;
        self.robot_nominal()?;
        self.laser_plane_model()?;
        self.validate_dh_errors()?;
        self.poses.validate(self.robot.joints.len())?;
        self.robot_error.validate()?;
        self.poses.validate_standoff()?;
        self.imaging.validate()?;
        self.board.validate_thickness()?;
        self.scan.validate()?;
        stripecal::model::StripeDirection::from_name(&self.stripe_direction)
            .map_err(|e| SimError::Config(format!("stripe_direction: {e}")))?;
        self.stripe_channel_model()?;
        self.imaging.validate_colours()?;
        self.pose_columns_model()?;
        self.verify.validate()?;
        self.bench.validate()?;
        if self.profiler.enabled {
            if self.bench.enabled {
                return bad(
                    "profiler.enabled",
                    "the profiler and bench modes exclude each other".into(),
                );
            }
            self.profiler.validate()?;
        }
        Ok(())
    }
}

/// The error of a bad value: the knob's name and what is wrong.
fn bad<T>(knob: &str, m: String) -> Result<T, SimError> {
    Err(SimError::Config(format!("{knob}: {m}")))
}

fn merge(
    base: &mut serde_json::Value,
    over: &serde_json::Value,
    path: &str,
) -> Result<(), SimError> {
    match (base, over) {
        (serde_json::Value::Object(b), serde_json::Value::Object(o)) => {
            for (k, v) in o {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                match b.get_mut(k) {
                    Some(slot) if slot.is_object() && v.is_object() => merge(slot, v, &p)?,
                    Some(slot) => *slot = v.clone(),
                    None => {
                        return Err(SimError::Config(format!(
                            "unknown knob `{p}`; known keys here: {}",
                            b.keys().cloned().collect::<Vec<_>>().join(", ")
                        )))
                    }
                }
            }
            Ok(())
        }
        (_, _) => Err(SimError::Config(format!(
            "overrides must be a JSON object{}",
            if path.is_empty() {
                String::new()
            } else {
                format!(" at `{path}`")
            }
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_validate_and_overrides_merge() {
        for p in PRESETS {
            SimConfig::preset(p).unwrap().validate().unwrap();
        }
        let c = SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({"imaging": {"noise_gray": 2.5}, "seed": 9}))
            .unwrap();
        assert_eq!(c.imaging.noise_gray, 2.5);
        assert_eq!(c.seed, 9);
        assert_eq!(c.imaging.psf_sigma_px, 0.7);
        let e = SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({"imaging": {"nosie": 1}}))
            .unwrap_err();
        assert!(e.to_string().contains("imaging.nosie"), "{e}");
        let e = SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({"imaging": {"bit_depth": 12}}))
            .unwrap_err();
        assert!(e.to_string().contains("bit_depth"), "{e}");
    }
}
