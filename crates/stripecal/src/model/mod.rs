//! What the sensor and its world are: the camera, the calibration target, rigid
//! geometry, the robot's kinematics, images, and the records datasets and results are
//! made of. Everything else (vision, calib, reconstruct, pipeline, io) builds on these;
//! nothing here imports from those layers.

pub mod artefacts;
pub mod board;
pub mod camera;
mod checks;
mod dataset;
pub mod geometry;
pub mod image;
pub mod kinematics;
mod mount;
mod profile;
mod quality;
mod results;
mod stripe_extraction;

pub use checks::{
    BoardScaleCheck, LaserBoardFigure, LeaveOneOut, LooFold, LooView, LOO_DISAGREE_FACTOR,
};
pub use dataset::{
    Dataset, Rig, RobotReading, Scan, ScanFrame, StripeChannel, StripeDirection, View,
};
pub use mount::Mount;
pub use profile::{
    DiameterCheckRecord, MirrorRecord, Profile, ProfileDataset, ProfileRig, ProfileScan,
    ProfileView, ProfilerAdjustmentRecord, ProfilerCalibration, ProfilerLooRecord, ProfilerLooView,
    ProfilerQuality, ProfilerRecords, ProfilerViewRecord, SensorKind,
};
pub use quality::{QualityCheck, QualityFailure};
pub(crate) use results::calibration_number;
pub use results::{
    AdjustmentSummary, Calibration, CalibrationRecords, CameraSigma, Cloud, DhCorrection,
    NamedCovariance, PlaneSigma, PoseSigma, Quality, RobotCalibration, RobotPoseNoise,
    RobotPoseView, Sphere, SphereFit, StripeChannelChoice, Truth, Uncertainty, ViewRecord,
    ROBOT_POSE_TEST_LIMIT,
};
pub use stripe_extraction::{RejectCounts, StripeExtraction};
