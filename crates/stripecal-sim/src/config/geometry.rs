//! The twin's geometry knobs: the camera, the laser plane and rigid poses (the hand-eye,
//! the board), with the stripecal models they stand for.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use stripecal::model::geometry::{iso_from_rotvec, iso_to_rotvec, Iso3, Plane};
use stripecal::{Camera, DistortionModel, Intrinsics};

use super::SimConfig;
use crate::SimError;

/// The camera (true values).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraCfg {
    pub width: u32,
    pub height: u32,
    pub fu: f64,
    pub fv: f64,
    pub u0: f64,
    pub v0: f64,
    /// `radial1`, `radial2` or `opencv5`: the model written to rig.json.
    pub distortion_model: String,
    /// `[k1, k2, p1, p2, k3]`; another `model`'s coefficients first, the rest 0.
    pub distortion: [f64; 5],
    /// The projection model by its registered name
    /// ([`stripecal::model::camera::projection`]); absent: `brown5`. Another model
    /// renders the twin through it (rig.json still says `distortion_model`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
}

/// A rigid transform as in the spec's files.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseCfg {
    /// Radians.
    pub rotation_vector: [f64; 3],
    pub translation_mm: [f64; 3],
}

/// The laser plane `n . p = d` in the camera frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneCfg {
    pub normal: [f64; 3],
    pub d_mm: f64,
}

impl SimConfig {
    /// The true camera.
    pub fn camera_model(&self) -> Result<Camera, SimError> {
        let c = &self.camera;
        let model = DistortionModel::from_name(&c.distortion_model)
            .map_err(|e| SimError::Config(format!("camera.distortion_model: {e}")))?;
        let cam = Camera::new(
            c.width,
            c.height,
            Intrinsics {
                fu: c.fu,
                fv: c.fv,
                u0: c.u0,
                v0: c.v0,
            },
            model,
            c.distortion,
        )
        .map_err(|e| SimError::Config(format!("camera: {e}")))?;
        let Some(name) = &c.model else {
            return Ok(cam);
        };
        let p = stripecal::model::camera::projection(name)
            .map_err(|e| SimError::Config(format!("camera.model: {e}")))?;
        if p.is_brown5() {
            return Ok(cam);
        }
        let n = p.model().distortion_count();
        cam.with_projection(p, &c.distortion[..n])
            .map_err(|e| SimError::Config(format!("camera.model: {e}")))
            .and_then(|cam| {
                if c.distortion[n..].iter().any(|&k| k != 0.0) {
                    Err(SimError::Config(format!(
                        "camera.distortion: model {name} has {n} coefficients, the others must be 0"
                    )))
                } else {
                    Ok(cam)
                }
            })
    }

    /// The true laser plane (camera frame).
    pub fn laser_plane_model(&self) -> Result<Plane, SimError> {
        let p = &self.laser_plane;
        Plane::new(Vector3::from(p.normal), p.d_mm)
            .map_err(|e| SimError::Config(format!("laser_plane: {e}")))
    }

    /// The true hand-eye `T_hand_cam`.
    pub fn hand_cam_model(&self) -> Iso3 {
        pose_model(&self.hand_cam)
    }
}

/// A pose from its file form.
pub fn pose_model(p: &PoseCfg) -> Iso3 {
    iso_from_rotvec(
        &Vector3::from(p.rotation_vector),
        &Vector3::from(p.translation_mm),
    )
}

/// The file form of a pose.
pub fn pose_cfg(t: &Iso3) -> PoseCfg {
    let (r, tr) = iso_to_rotvec(t);
    PoseCfg {
        rotation_vector: [r.x, r.y, r.z],
        translation_mm: [tr.x, tr.y, tr.z],
    }
}
