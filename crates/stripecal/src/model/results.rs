//! What calibration, simulation and measurement produce: the calibration, the twin's
//! truth, sphere fits and point clouds. Reading and writing them is `io`'s job.

use nalgebra::{DMatrix, Vector3};

use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::kinematics::Robot;
use crate::model::{BoardScaleCheck, LeaveOneOut, Mount};

/// One of a calibration's numbers by its contract name (the names of
/// [`NamedCovariance`]): the camera's, the laser plane's, and `hand_cam`'s and
/// `base_board`'s rotation vectors and translations; `None` for other names (the board
/// scale, the DH values: their owners read those) and for a plane that is absent.
pub(crate) fn calibration_number(
    camera: &Camera,
    plane: Option<&Plane>,
    hand_cam: &Iso3,
    base_board: &Iso3,
    name: &str,
) -> Option<f64> {
    let index = |prefix: &str| -> Option<usize> {
        name.strip_prefix(prefix)?
            .strip_prefix('[')?
            .strip_suffix(']')?
            .parse()
            .ok()
    };
    let params = camera.params();
    if let Some(k) = index("camera.distortion").filter(|&k| k < 5) {
        return Some(params[4 + k]);
    }
    if let Some(k) = name.strip_prefix("camera.").and_then(|p| {
        crate::model::camera::PARAM_NAMES[..4]
            .iter()
            .position(|&x| x == p)
    }) {
        return Some(params[k]);
    }
    if let Some(k) = index("laser_plane.normal").filter(|&k| k < 3) {
        return plane.map(|p| p.normal[k]);
    }
    if name == "laser_plane.d_mm" {
        return plane.map(|p| p.d);
    }
    for (key, t) in [("hand_cam", hand_cam), ("base_board", base_board)] {
        if let Some(k) = index(&format!("{key}.rotation_vector")).filter(|&k| k < 3) {
            return Some(crate::model::geometry::iso_to_rotvec(t).0[k]);
        }
        if let Some(k) = index(&format!("{key}.translation_mm")).filter(|&k| k < 3) {
            return Some(t.translation.vector[k]);
        }
    }
    None
}

/// The covariance of a calibration's estimated numbers (calibration.json `covariance`):
/// `parameters` names them by their keys (`camera.fu`, `laser_plane.normal[0]`,
/// `hand_cam.rotation_vector[2]`, ...; vectors indexed), `matrix` is their covariance
/// in that order (units of the numbers: px, mm, rad).
#[derive(Debug, Clone, PartialEq)]
pub struct NamedCovariance {
    pub parameters: Vec<String>,
    pub matrix: DMatrix<f64>,
}

impl NamedCovariance {
    /// The index of a number.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.parameters.iter().position(|p| p == name)
    }

    /// One-sigma of a number (`None` when it is not in the covariance, or the matrix
    /// has no row for it).
    pub fn sigma(&self, name: &str) -> Option<f64> {
        self.index(name)
            .and_then(|i| self.matrix.get((i, i)))
            .map(|v| v.max(0.0).sqrt())
    }

    /// The covariance of the numbers whose names start with `prefix` (a block, e.g.
    /// `camera.`), with their names (names the matrix has no row for are left out).
    pub fn block(&self, prefix: &str) -> NamedCovariance {
        let n = self.matrix.nrows().min(self.matrix.ncols());
        let idx: Vec<usize> = (0..self.parameters.len().min(n))
            .filter(|&i| self.parameters[i].starts_with(prefix))
            .collect();
        NamedCovariance {
            parameters: idx.iter().map(|&i| self.parameters[i].clone()).collect(),
            matrix: DMatrix::from_fn(idx.len(), idx.len(), |r, c| self.matrix[(idx[r], idx[c])]),
        }
    }
}

/// Quality figures of a calibration (calibration.json `quality`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Quality {
    /// RMS target-point residual, px (circle centres or chessboard corners): the
    /// contract's `circle_rms_px`, written beside it as `target_rms_px` too.
    pub circle_rms_px: f64,
    pub stripe_rms_px: f64,
    pub views_used: usize,
    /// The quality gates' verdicts (`quality.checks`; empty in files written before
    /// the gates existed).
    pub checks: Vec<super::QualityCheck>,
    /// A calibration that failed a gate and was kept anyway (`--accept-poor`).
    pub accepted_poor: bool,
}

/// A calibration result (`calibration.json`).
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    pub camera: Camera,
    /// `None`: not estimated (a calibration from views without laser images; written
    /// as `"laser_plane": null`, refused by reconstruction).
    pub laser_plane: Option<Plane>,
    /// How the sensor was held: on a robot (`hand_cam`, `base_board` estimated) or on
    /// the bench (both the identity, absent from the file).
    pub mount: Mount,
    /// `T_hand_cam` (the paper's X; the identity on the bench).
    pub hand_cam: Iso3,
    /// `T_base_board` (the paper's Z; the identity on the bench).
    pub base_board: Iso3,
    /// DH rows used (refined if the robot was calibrated); `None` for flange-pose rigs.
    pub robot: Option<Robot>,
    pub quality: Quality,
    /// One-sigma values mirroring the estimated values' structure (free-form JSON).
    pub uncertainty: serde_json::Map<String, serde_json::Value>,
    /// The full covariance of the estimated numbers (`None` in files written before
    /// the contract asked for it).
    pub covariance: Option<NamedCovariance>,
    /// What the calibration did and checked (calibration.json's keys beyond the
    /// contract's fixed ones that this version knows).
    pub records: CalibrationRecords,
    /// Any other top-level keys (those this version does not know, or a known key that
    /// does not read as its record), kept on load and written back on save.
    pub extra: serde_json::Map<String, serde_json::Value>,
}

impl Calibration {
    /// A bench calibration (from a dataset without poses): camera and laser plane only,
    /// no `hand_cam`, `base_board` or `robot` in its file; `hand_cam` and `base_board`
    /// hold the identity ([`Mount::Bench`]).
    pub fn is_bench(&self) -> bool {
        self.mount == Mount::Bench
    }
}

/// calibration.json's records beyond the contract's fixed keys, each `None` (or empty)
/// when the calibration did not make it (or a file does not hold it).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CalibrationRecords {
    /// How the calibration was made (`method`, `centre_model`, ...).
    pub summary: Option<AdjustmentSummary>,
    /// What the calibration did with each view (`views`).
    pub views: Option<Vec<ViewRecord>>,
    /// What the user should know (`warnings`; empty: the file has none).
    pub warnings: Vec<String>,
    /// The board's scale against the robot (`board_scale`).
    pub board_scale: Option<BoardScaleCheck>,
    /// The leave-one-view-out figures (`leave_one_out`).
    pub leave_one_out: Option<LeaveOneOut>,
    /// The robot-pose noise (`robot_pose_noise`).
    pub robot_pose_noise: Option<RobotPoseNoise>,
    /// What the robot calibration did (`robot_calibration`; its `robot` is the
    /// calibration's).
    pub robot_calibration: Option<RobotCalibration>,
    /// The blocks held at a prior calibration's values (`held_blocks`, `--from`; `None`:
    /// none held).
    pub held_blocks: Option<Vec<String>>,
    /// The signal the stripes were found in, when not gray (`stripe_channel`,
    /// `stripe_channel_scores`).
    pub stripe_channel: Option<StripeChannelChoice>,
}

/// The signal a calibration's stripes were found in (calibration.json's
/// `stripe_channel`, written when rig.json's `stripe.channel` is not gray), and with
/// `stripe.channel: auto` each signal's score (`stripe_channel_scores`: the summed
/// stripe peak-to-noise ratio over the laser images looked at).
#[derive(Debug, Clone, PartialEq)]
pub struct StripeChannelChoice {
    /// The signal used (never [`StripeChannel::Auto`]: what `auto` chose).
    ///
    /// [`StripeChannel::Auto`]: super::StripeChannel::Auto
    pub channel: super::StripeChannel,
    /// `(signal, score)` in the order written, when `auto` chose the signal.
    pub scores: Option<Vec<(super::StripeChannel, f64)>>,
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

impl SphereFit {
    /// The fit's one-sigma of the diameter (mm; the fit's random part only): the extra
    /// key `fit_diameter_sigma_mm`, or `diameter_sigma_mm` of files written before it
    /// was named for what it is. `None` when neither is a number.
    pub fn fit_diameter_sigma_mm(&self) -> Option<f64> {
        ["fit_diameter_sigma_mm", "diameter_sigma_mm"]
            .iter()
            .find_map(|k| self.extra.get(*k).and_then(|v| v.as_f64()))
    }

    /// The fit's one-sigma of the centre's coordinates (mm; random part only):
    /// `fit_center_sigma_mm`, or an older file's `center_sigma_mm`. `None` when neither
    /// is an array of 3 numbers.
    pub fn fit_center_sigma_mm(&self) -> Option<[f64; 3]> {
        ["fit_center_sigma_mm", "center_sigma_mm"]
            .iter()
            .find_map(|k| {
                let a = self.extra.get(*k)?.as_array()?;
                match a.iter().map(|x| x.as_f64()).collect::<Option<Vec<f64>>>()?[..] {
                    [x, y, z] => Some([x, y, z]),
                    _ => None,
                }
            })
    }
}

/// A point cloud: xyz in mm (base frame) plus optional per-point properties.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Cloud {
    pub points: Vec<[f64; 3]>,
    /// Named per-point properties (e.g. `view`, `u`, `v`, `intensity`), each as long as
    /// `points`.
    pub properties: Vec<(String, Vec<f64>)>,
}

/// One-sigma of a camera's parameters (calibration.json `uncertainty.camera`); a
/// non-finite value (an unobservable parameter) is written as `null`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraSigma {
    pub fu: f64,
    pub fv: f64,
    pub u0: f64,
    pub v0: f64,
    /// In OpenCV order `[k1, k2, p1, p2, k3]`.
    pub distortion: [f64; 5],
}

impl CameraSigma {
    /// From the nine camera parameters' sigmas in [`crate::model::camera::PARAM_NAMES`]
    /// order.
    pub fn from_params(s: &[f64; 9]) -> Self {
        CameraSigma {
            fu: s[0],
            fv: s[1],
            u0: s[2],
            v0: s[3],
            distortion: [s[4], s[5], s[6], s[7], s[8]],
        }
    }
}

/// One-sigma of a laser plane (`uncertainty.laser_plane`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneSigma {
    /// Of each component of the unit normal.
    pub normal: [f64; 3],
    pub d_mm: f64,
}

/// One-sigma of a rigid transform (`uncertainty.hand_cam`, `uncertainty.base_board`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSigma {
    /// Of the rotation vector's components, radians.
    pub rotation_vector: [f64; 3],
    pub translation_mm: [f64; 3],
}

/// The `uncertainty` block of calibration.json: one-sigma of every estimated value under
/// the value's own key. A block is `None` when the method does not estimate it (the
/// paper's stages give only the camera's and the laser plane's).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Uncertainty {
    pub camera: Option<CameraSigma>,
    pub laser_plane: Option<PlaneSigma>,
    pub hand_cam: Option<PoseSigma>,
    pub base_board: Option<PoseSigma>,
}

/// What a calibration did with one view (an entry of calibration.json `views`).
#[derive(Debug, Clone, PartialEq)]
pub struct ViewRecord {
    /// Row in views.csv (0-based).
    pub view: usize,
    /// Whether the adjustment used it.
    pub used: bool,
    /// Target points detected.
    pub circles: usize,
    /// Stripe points on the board the adjustment used.
    pub stripe_points: usize,
    /// Stripe points rejected as off the board plane (beyond a depth step, on
    /// something behind).
    pub stripe_off_plane: usize,
    /// RMS target residual of the view, px (`None` when not adjusted or not finite).
    pub circle_rms_px: Option<f64>,
    /// RMS stripe residual of the view, px.
    pub stripe_rms_px: Option<f64>,
    /// Whether the adjustment flagged the view as an outlier (`None` when not adjusted).
    pub outlier: Option<bool>,
    /// Why it was left out, if it was.
    pub note: Option<String>,
    /// What the stripe extraction found and left out (`None` without a laser image).
    pub stripe_extraction: Option<super::StripeExtraction>,
}

/// The robot-pose noise a one-stage calibration estimated (calibration.json
/// `robot_pose_noise`): the standard deviations of the flange pose's translation and
/// rotation (per component, flange frame) that the robot's poses carry beyond the model,
/// and per view the correction its images asked of its pose with a test of it.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotPoseNoise {
    /// One-sigma of a flange translation component, mm.
    pub sigma_translation_mm: f64,
    /// One-sigma of a flange rotation component, degrees.
    pub sigma_rotation_deg: f64,
    /// Whether the translation's sigma sits at its floor (the estimate is below it).
    pub translation_at_floor: bool,
    /// Whether the rotation's sigma sits at its floor.
    pub rotation_at_floor: bool,
    /// The floors, mm and degrees: the robot's figures (rig.json) when given, never less
    /// than the adjustment's own resolution floor.
    pub floor_translation_mm: f64,
    pub floor_rotation_deg: f64,
    /// The factor `k` of the part of each view's pose error its own image makes (its
    /// covariance `k^2` times the image's own uncertainty of the view's pose, beyond the
    /// image residuals' white noise; `calib::joint`'s `robot_noise` docs); `None` when
    /// not modelled.
    pub image_factor: Option<f64>,
    /// Whether that factor sits at its floor (the images are as good as their
    /// residuals say).
    pub image_factor_at_floor: bool,
    /// With joint readings and rig.json's DH table: the size of DH errors (one-sigma of
    /// a length, mm; angles alike at the flange) the robot-pose noise is consistent with,
    /// whose effect on `X` and `Z` (a common error of every pose, which no view can
    /// show) the covariance carries; `None` otherwise.
    pub kinematic_mm: Option<f64>,
    /// The same for the DH angles, degrees.
    pub kinematic_deg: Option<f64>,
    /// Per view used.
    pub views: Vec<RobotPoseView>,
    /// Views named and left out because their test exceeded
    /// [`ROBOT_POSE_TEST_LIMIT`], with their figures from the adjustment that found
    /// them (DECISIONS 1: a view whose pose is off by far more than the others is not
    /// absorbed into the noise estimate).
    pub left_out: Vec<RobotPoseView>,
}

/// A view whose robot-pose test exceeds this disagrees with the noise model (a one-sided
/// normal tail of 3e-5: one false alarm in about 1000 calibrations of 30 views).
pub const ROBOT_POSE_TEST_LIMIT: f64 = 4.0;

/// One view's robot-pose correction (an entry of `robot_pose_noise.views`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotPoseView {
    /// Row in views.csv (0-based).
    pub view: usize,
    /// Length of the flange-frame translation correction, mm.
    pub translation_mm: f64,
    /// Angle of the rotation correction, degrees.
    pub rotation_deg: f64,
    /// The view's test value: its correction against its own predicted covariance,
    /// as a standard normal deviate (about N(0, 1) for a view that agrees with the
    /// noise model; above about 4 it disagrees). NaN when not computable.
    pub test: f64,
}

/// How a calibration was made and its residual figures (calibration.json's `method`,
/// `centre_model`, `base_board_orientation`, `stripe_rms_mm`, `residual_sigma_px`,
/// `stripe_off_plane`).
#[derive(Debug, Clone, PartialEq)]
pub struct AdjustmentSummary {
    /// `one-stage` or `paper`.
    pub method: String,
    /// The circle-centre model's name.
    pub centre_model: String,
    /// `Some("first view")` when no view's image fixed the board frame's orientation
    /// and the first view's labelling did.
    pub base_board_orientation: Option<String>,
    /// RMS of the stripe points' distance to the laser plane, mm.
    pub stripe_rms_mm: f64,
    /// Residual standard deviations `(circle, stripe)` px estimated from the fit.
    pub residual_sigma_px: (f64, f64),
    /// Stripe points rejected as off the board plane, all views.
    pub stripe_off_plane: usize,
}

/// One DH correction a calibration estimated (calibration.json `robot_calibration`).
#[derive(Debug, Clone, PartialEq)]
pub struct DhCorrection {
    /// `robot.joints[i].theta0_deg` style name (0-based row).
    pub name: String,
    /// The refined value minus rig.json's nominal one (deg or mm).
    pub correction: f64,
    /// Its one-sigma.
    pub sigma: f64,
}

/// What the robot calibration did (`--robot`): the mode, the corrections estimated and
/// the candidates left fixed with why (the identifiability rule).
#[derive(Debug, Clone, PartialEq)]
pub struct RobotCalibration {
    /// `fixed`, `offsets`, `full` or `auto`.
    pub mode: String,
    /// The refined robot (rig.json's nominal one plus the corrections).
    pub robot: crate::model::kinematics::Robot,
    pub estimated: Vec<DhCorrection>,
    /// `(name, why)` of every candidate held at its nominal value.
    pub fixed: Vec<(String, String)>,
}
