//! What calibration, simulation and measurement produce: the calibration, the twin's
//! truth, sphere fits and point clouds. Reading and writing them is `io`'s job.

use nalgebra::Vector3;

use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::kinematics::Robot;

/// Quality figures of a calibration (calibration.json `quality`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Quality {
    pub circle_rms_px: f64,
    pub stripe_rms_px: f64,
    pub views_used: usize,
}

/// A calibration result (`calibration.json`).
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    pub camera: Camera,
    pub laser_plane: Plane,
    /// `T_hand_cam` (the paper's X).
    pub hand_cam: Iso3,
    /// `T_base_board` (the paper's Z).
    pub base_board: Iso3,
    /// DH rows used (refined if the robot was calibrated); `None` for flange-pose rigs.
    pub robot: Option<Robot>,
    pub quality: Quality,
    /// One-sigma values mirroring the estimated values' structure (free-form JSON).
    pub uncertainty: serde_json::Map<String, serde_json::Value>,
    /// Any other top-level keys, kept on load and written back on save.
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// A sphere (truth of a scan).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    pub center_mm: Vector3<f64>,
    pub diameter_mm: f64,
}

/// Ground truth written by simulators (`truth.json`).
#[derive(Debug, Clone, PartialEq)]
pub struct Truth {
    pub camera: Camera,
    pub laser_plane: Plane,
    pub hand_cam: Iso3,
    pub base_board: Iso3,
    /// The robot's TRUE DH rows.
    pub robot: Option<Robot>,
    pub sphere: Option<Sphere>,
    pub working_range_mm: Option<[f64; 2]>,
    /// Simulator-specific keys (per-image truth, emitter position...).
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// A sphere fit result (spec "The sphere fit").
#[derive(Debug, Clone, PartialEq)]
pub struct SphereFit {
    pub diameter_mm: f64,
    pub center_mm: Vector3<f64>,
    pub rms_mm: f64,
    /// Inliers used by the fit.
    pub points: usize,
    pub outliers: usize,
    /// Other keys (uncertainties...).
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// A point cloud: xyz in mm (base frame) plus optional per-point properties.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Cloud {
    pub points: Vec<[f64; 3]>,
    /// Named per-point properties (e.g. `view`, `u`, `v`, `intensity`), each as long as
    /// `points`.
    pub properties: Vec<(String, Vec<f64>)>,
}
