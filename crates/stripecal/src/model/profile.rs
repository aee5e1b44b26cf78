//! The records of a calibrated line profiler (spec/DATASET.md, "A profile dataset"):
//! its rig, its views and scans (a profile file and a robot reading each), a profile's
//! points, and the calibration a profiler gets (`T_hand_sensor`, the sphere, the robot).
//! Reading and writing them is `io`'s job.
//!
//! ## Conventions
//!
//! The profiler frame `sensor`: x along the laser line, z along the measuring range,
//! y = z x x; every profile point lies in the plane y = 0. A point in the base frame is
//! `p_base = T_base_hand(q) * T_hand_sensor * (x, 0, z)`. Millimetres throughout.

use std::path::PathBuf;

use nalgebra::Vector3;

use crate::model::dataset::RobotReading;
use crate::model::geometry::Iso3;
use crate::model::kinematics::Robot;
use crate::model::{NamedCovariance, QualityCheck};

/// The `sensor.kind` of rig.json.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SensorKind {
    /// A camera and a laser plane (everything of the contract before profilers).
    #[default]
    Camera,
    /// A calibrated line profiler: profiles in mm, no images.
    Profiler,
}

impl SensorKind {
    /// `camera` or `profiler`.
    pub fn name(self) -> &'static str {
        match self {
            SensorKind::Camera => "camera",
            SensorKind::Profiler => "profiler",
        }
    }
}

/// The rig of a profile dataset (rig.json with `sensor.kind = "profiler"`).
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileRig {
    /// The robot's nominal DH table; `None` when the views carry flange poses.
    pub robot: Option<Robot>,
    /// The vendor's sentinel for "no point" (`sensor.invalid_z`), if any.
    pub invalid_z: Option<f64>,
    /// The reference sphere's declared diameter (`artefact.diameter_mm`); `None`: the
    /// calibration estimates it.
    pub diameter_mm: Option<f64>,
}

/// One row of a profile dataset's views.csv, or of a profile scan's scan.csv.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileView {
    /// The 1-based line of the row in its CSV (the header is line 1).
    pub line: usize,
    /// The profile file, relative to the folder as written.
    pub profile: PathBuf,
    /// Joint readings or the flange pose.
    pub reading: RobotReading,
}

/// A profile dataset folder: rig.json + views.csv (+ profile files).
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileDataset {
    pub root: PathBuf,
    pub rig: ProfileRig,
    pub views: Vec<ProfileView>,
}

/// A profile scan folder: scan.csv with a `profile` column (+ profile files, optional
/// rig.json).
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileScan {
    pub root: PathBuf,
    pub rig: Option<ProfileRig>,
    pub frames: Vec<ProfileView>,
}

/// One profile as read: its points `(x, z)` in mm in the sensor frame, gaps skipped.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Profile {
    pub points: Vec<[f64; 2]>,
    /// Points reported as gaps (empty or non-finite z, or the vendor's `invalid_z`).
    pub gaps: usize,
}

/// A profiler's quality figures (calibration.json `quality`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ProfilerQuality {
    /// RMS distance of the sphere points used from the fitted sphere, mm.
    pub profile_rms_mm: f64,
    pub views_used: usize,
    /// The quality gates' verdicts.
    pub checks: Vec<QualityCheck>,
    /// A calibration that failed a gate and was kept anyway (`--accept-poor`).
    pub accepted_poor: bool,
}

/// A profiler's calibration (calibration.json with `"sensor": {"kind": "profiler"}`).
#[derive(Debug, Clone, PartialEq)]
pub struct ProfilerCalibration {
    /// `T_hand_sensor` (written as `hand_cam`).
    pub hand_sensor: Iso3,
    /// The DH rows used (refined when the robot was calibrated); `None` for flange
    /// poses.
    pub robot: Option<Robot>,
    /// The sphere's centre in the base frame, mm.
    pub sphere_center_mm: Vector3<f64>,
    /// The sphere's diameter, mm (declared, or estimated when the rig gave `null`).
    pub sphere_diameter_mm: f64,
    pub quality: ProfilerQuality,
    /// One-sigma values mirroring the estimated values' structure (`hand_cam`,
    /// `sphere`, `robot`).
    pub uncertainty: serde_json::Map<String, serde_json::Value>,
    /// The covariance of the estimated numbers (names `hand_cam.rotation_vector[0]`,
    /// `sphere.center_mm[0]`, `sphere.diameter_mm`, the DH corrections' names).
    pub covariance: Option<NamedCovariance>,
    /// Any other top-level keys (views, leave-one-out, warnings...), kept on load and
    /// written back on save.
    pub extra: serde_json::Map<String, serde_json::Value>,
}
