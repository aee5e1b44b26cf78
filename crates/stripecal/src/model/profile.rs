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
use crate::model::{NamedCovariance, QualityCheck, RobotCalibration};

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
    /// What the calibration reports about itself (views, adjustment, mirror test,
    /// diameter check, leave-one-out, robot calibration, warnings).
    pub records: ProfilerRecords,
    /// Any other top-level keys (ones this version does not know), kept on load and
    /// written back on save.
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// What a profiler calibration reports about itself: calibration.json's keys after the
/// fixed ones, in the order written (`robot_calibration`, `sphere_diameter_estimated`,
/// `adjustment`, `views`, `mirror`, `diameter_check`, `leave_one_out`, `warnings`).
/// Each is `None` (or empty) when the file has none.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ProfilerRecords {
    /// What the robot calibration did (`robot_calibration`).
    pub robot_calibration: Option<RobotCalibration>,
    /// rig.json's diameter was `null`, so the adjustment estimated it
    /// (`sphere_diameter_estimated`).
    pub sphere_diameter_estimated: Option<bool>,
    /// The adjustment's figures (`adjustment`).
    pub adjustment: Option<ProfilerAdjustmentRecord>,
    /// Every view of the dataset, used or not (`views`).
    pub views: Option<Vec<ProfilerViewRecord>>,
    /// The mirror test (`mirror`).
    pub mirror: Option<MirrorRecord>,
    /// The declared diameter against the profiles' (`diameter_check`).
    pub diameter_check: Option<DiameterCheckRecord>,
    /// The leave-one-view-out figures (`leave_one_out`).
    pub leave_one_out: Option<ProfilerLooRecord>,
    /// What the user should know (`warnings`; empty: none written).
    pub warnings: Vec<String>,
}

/// A profiler calibration's `adjustment`.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfilerAdjustmentRecord {
    /// The a-posteriori sigma of a point's distance from the sphere, mm.
    pub sigma_mm: f64,
    pub points_used: usize,
    pub iterations: usize,
    /// The view-clustered variance factor the sigmas carry (>= 1).
    pub view_variance_factor: f64,
}

/// One view of a profiler calibration's `views`.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfilerViewRecord {
    pub view: usize,
    /// The line of views.csv.
    pub line: usize,
    /// The profile file (`profile`).
    pub profile: String,
    pub used: bool,
    pub points: usize,
    pub gaps: usize,
    pub arc_points: usize,
    pub sphere_points: usize,
    pub rejected: usize,
    /// RMS distance from the sphere, mm (`None`: not used).
    pub rms_mm: Option<f64>,
    /// The side of the laser plane the sphere's centre was on (+1 / -1).
    pub side: Option<f64>,
    /// The sphere's centre in the sensor frame, mm (`centre_in_sensor_mm`).
    pub centre_in_sensor_mm: Option<[f64; 3]>,
    /// Why the view was not used.
    pub note: Option<String>,
}

/// A profiler calibration's `mirror`: the fit against its mirror image through the
/// laser plane.
#[derive(Debug, Clone, PartialEq)]
pub struct MirrorRecord {
    pub ssr_chosen_mm2: f64,
    pub ssr_mirror_mm2: f64,
    pub delta_chi2: f64,
    pub passed: bool,
    /// The sphere centres' spread in the sensor frame, mm: x, y, z, across the plane
    /// (`centre_spread_mm`).
    pub centre_spread_mm: [f64; 4],
}

/// A profiler calibration's `diameter_check`.
#[derive(Debug, Clone, PartialEq)]
pub struct DiameterCheckRecord {
    pub declared_mm: f64,
    pub estimate_mm: f64,
    pub sigma_mm: f64,
    pub disagrees: bool,
}

/// A profiler calibration's `leave_one_out`.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfilerLooRecord {
    pub median_rms_mm: f64,
    pub views: Vec<ProfilerLooView>,
}

/// One view of a profiler's `leave_one_out.views`.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfilerLooView {
    pub view: usize,
    pub points: usize,
    /// Held-out RMS distance from the sphere the other views predict, mm.
    pub rms_mm: f64,
    pub disagrees: bool,
}
