//! From a dataset (or from observations) to a calibration: the paper's multi-stage
//! pipeline and the one-stage adjustment on top of it.
//!
//! ## Steps
//!
//! 1. Observations ([`observe_dataset`]): per view, circles detected in the board image;
//!    the stripe extracted from the laser image (the rig's stripe direction), points
//!    whose support shows a reflectance edge in the board image dropped (single-image
//!    views, where the laser image is the board image, use the single-image edge test);
//!    `T_base_hand` from the joints by forward kinematics of the rig's (nominal) robot,
//!    or the reported flange pose. A view whose board is not found is left out with a
//!    warning naming it; images and joints stay paired by row.
//! 2. Camera ([`crate::calib::camera`]): Zhang, then LM with the bias-free centre model.
//! 3. Stripe points on the board plane ([`stripe_select`]): each is intersected with its
//!    view's board plane and kept when it is consistent with one laser plane over all
//!    views, wherever it lies on that plane (the printed pattern, the sheet or plate
//!    around it); points off the plane (beyond a depth step where the sheet ends, on
//!    something behind) are rejected and counted per view.
//! 4. Robot poses against images (`calibrate/pairing.rs`, by the consensus of
//!    [`crate::calib::consensus::pairing`]): views whose robot pose does not fit their
//!    image (a swapped pair, a mistyped joint reading) are named and left out when the
//!    rest is consistent and large enough; `AX = ZB` ([`crate::calib::axzb`]) from the
//!    views that agree; the laser plane ([`crate::calib::laser_plane`]).
//! 5. `Method::Paper` stops here; `Method::OneStage` (default) runs
//!    [`crate::calib::joint`] from these values.
//! 6. The quality gates ([`gates`]): a calibration that fails one is an
//!    [`Error::Quality`] (unless [`CalibrateOptions::accept_poor`]).
//!
//! ## Folders
//!
//! `calibrate/` the calibration (`dispatch.rs` chooses the prior, bench, laser-only or
//! robot pipeline; one file per stage), `measure/` scans measured with full budgets and
//! the acceptance test (`verify`), `plan/` pose plans, `profile/` a profiler's
//! calibration; `emitter_carry` carries the emitter found on a measured sphere back into
//! the calibration. The public paths (`pipeline::gates`, `pipeline::verify`, ...) are
//! re-exported here.

mod calibrate;
pub mod emitter_carry;
pub mod measure;
mod plan;
pub mod profile;

pub use calibrate::{board_stripe, gates, stripe_select};
pub use measure::verify;

use std::path::Path;

use crate::calib::axzb::AxzbSolution;
use crate::calib::camera::CameraCalibration;
use crate::calib::conic::CentreModel;
use crate::calib::joint::{FreeBlocks, JointResult};
use crate::calib::laser_plane::LaserPlaneFit;
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::camera::DistortionModel;
use crate::model::{
    AdjustmentSummary, BoardScaleCheck, Calibration, Dataset, LeaveOneOut, ViewRecord,
};
use crate::vision::stripe::{EdgeOptions, StripeOptions};
use crate::vision::target::TargetOptions;

pub use calibrate::calibrate_observations;
pub use calibrate::held_out_laser_board;
pub use calibrate::BENCH_KEY;
pub use calibrate::{dataset_channel, observe_dataset};
#[doc(hidden)]
pub use calibrate::{leave_one_out_refits, leave_one_out_with, FoldMethod, FoldsSolved};
use calibrate::{observe, Observed};
pub use plan::{
    nominal_from_truth, plan_poses, read_nominal, read_plan_rig, PlanOptions, PlannedPose,
    PointSigma, PosePlan, SigmaEntry,
};
pub use stripe_select::{select_on_board_plane, StripeSelection};

/// Which pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// The paper's: camera, then plane, then linear AX = ZB.
    Paper,
    /// The paper's stages, then the one-stage adjustment of everything.
    #[default]
    OneStage,
}

impl Method {
    /// `paper` or `one-stage`.
    pub fn name(self) -> &'static str {
        match self {
            Method::Paper => "paper",
            Method::OneStage => "one-stage",
        }
    }
    /// Parses [`Method::name`].
    pub fn from_name(s: &str) -> Result<Method> {
        match s {
            "paper" => Ok(Method::Paper),
            "one-stage" => Ok(Method::OneStage),
            o => Err(Error::InvalidInput(format!(
                "unknown calibration method {o:?}: expected \"paper\" or \"one-stage\""
            ))),
        }
    }
}

/// Options of the calibration pipeline.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateOptions {
    /// Distortion model (default: the rig's).
    pub distortion: Option<DistortionModel>,
    /// The camera's projection model (default brown5, the contract's; another
    /// registered one, [`crate::model::camera::register`], is calibrated through its
    /// trait; rig.json does not name one yet).
    pub camera_model: crate::model::camera::Projection,
    pub method: Method,
    /// Huber loss in the one-stage adjustment.
    pub robust: bool,
    pub centre_model: CentreModel,
    /// Target detection (every kind).
    pub target: TargetOptions,
    pub stripe: StripeOptions,
    pub edges: EdgeOptions,
    /// Leave-one-out AX = ZB consistency: a view is an outlier when its rotation error
    /// exceeds `max(outlier_factor * median, outlier_min_deg)` or its translation error
    /// `max(outlier_factor * median, outlier_min_rel * stand-off)`.
    pub outlier_factor: f64,
    pub outlier_min_deg: f64,
    pub outlier_min_rel: f64,
    /// The calibration to start from (`--from`): the blocks `free` holds keep its
    /// values (and its uncertainty).
    pub from: Option<Calibration>,
    /// The blocks estimated (default: all but the board scale; `--fix`,
    /// `--laser-only`, `--estimate-board-scale`).
    pub free: FreeBlocks,
    /// Compute the leave-one-view-out figure (default true; one-stage only).
    pub leave_one_out: bool,
    /// The board-scale check's tolerance on `|s - 1|` (default 0.01).
    pub board_scale_tolerance: f64,
    /// Return a calibration that failed a quality gate ([`gates`]) instead of an
    /// [`Error::Quality`], marked `quality.accepted_poor` (default false).
    pub accept_poor: bool,
    /// Correct every view's robot pose by its own small transform and estimate the
    /// robot-pose noise ([`crate::calib::joint::JointOptions::robot_noise`]; default
    /// true whenever the poses come from a robot; `--no-robot-pose-noise` turns it off:
    /// the robot poses exact, the paper's rigid model).
    pub robot_pose_noise: bool,
    /// Widen the covariance to the views' own scatter where that is larger
    /// ([`crate::calib::clustered`]; default true). Off: the noise model's covariance
    /// alone (for studies of effects the views share, which the widening would count as
    /// scatter).
    pub clustered_covariance: bool,
    /// The robot's DH corrections to estimate (`--robot`; default fixed: rig.json's DH
    /// table is exact). Needs rig.json's robot and joint readings in views.csv.
    pub robot: crate::calib::joint::RobotMode,
    /// Correct the stripe's bias on the board before the final adjustment
    /// ([`board_stripe`]; default true; one-stage method only).
    pub board_stripe_bias: bool,
    /// On the bench: views whose board sags by more than this (mm, and by more than 3
    /// sigma) are named and left out (`calibrate/flat_views.rs`; default 0.02).
    pub max_board_sag_mm: f64,
    /// Checked between the pipeline's steps (each view's detection, each stage, each
    /// adjustment): once set, the run returns [`Error::Cancelled`] at the next check
    /// (within about a second) and nothing else. Not a setting: never compared.
    pub cancel: crate::cancel::Cancel,
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        CalibrateOptions {
            distortion: None,
            camera_model: crate::model::camera::Projection::Brown5,
            method: Method::OneStage,
            robust: false,
            centre_model: CentreModel::ConicExact,
            target: TargetOptions::default(),
            stripe: StripeOptions::default(),
            edges: EdgeOptions::default(),
            outlier_factor: 8.0,
            outlier_min_deg: 0.1,
            outlier_min_rel: 0.005,
            from: None,
            free: FreeBlocks::default(),
            leave_one_out: true,
            board_scale_tolerance: 0.01,
            accept_poor: false,
            robot_pose_noise: true,
            clustered_covariance: true,
            robot: crate::calib::joint::RobotMode::Fixed,
            board_stripe_bias: true,
            max_board_sag_mm: 0.02,
            cancel: crate::cancel::Cancel::default(),
        }
    }
}

/// What the pipeline did with one view.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewStatus {
    /// Row in views.csv (0-based).
    pub view: usize,
    pub circles: usize,
    /// Stripe points extracted / used on the board.
    pub stripe_points: usize,
    pub stripe_used: usize,
    /// Stripe points rejected as off the board plane ([`stripe_select`]).
    pub stripe_off_plane: usize,
    /// What the stripe extraction found and left out (`None` without a laser image).
    pub stripe_extraction: Option<crate::model::StripeExtraction>,
    pub used: bool,
    /// Why it was left out, if it was.
    pub note: Option<String>,
}

impl ViewStatus {
    /// A view as observed, before the calibration decides on it.
    fn observed(v: &ViewObs) -> Self {
        ViewStatus {
            view: v.view,
            circles: v.circles.len(),
            stripe_points: v.stripe.len(),
            stripe_used: 0,
            stripe_off_plane: 0,
            stripe_extraction: v.stripe_shape.as_ref().map(|s| s.extraction),
            used: false,
            note: None,
        }
    }

    /// A view whose board was not found.
    fn left_out(view: usize, note: Option<String>) -> Self {
        ViewStatus {
            view,
            circles: 0,
            stripe_points: 0,
            stripe_used: 0,
            stripe_off_plane: 0,
            stripe_extraction: None,
            used: false,
            note,
        }
    }
}

/// The paper's stages (`None`: the stage did not run: no laser, or its blocks were held
/// from `--from`).
#[derive(Debug, Clone)]
pub struct Stages {
    pub camera: Option<CameraCalibration>,
    pub plane: Option<LaserPlaneFit>,
    pub axzb: Option<AxzbSolution>,
}

/// The result of the pipeline.
#[derive(Debug, Clone)]
pub struct CalibrationReport {
    /// The calibration (spec's calibration.json content, with quality and uncertainty).
    pub calibration: Calibration,
    pub method: Method,
    pub stages: Stages,
    /// The adjustment's figures (the one-stage result, or the paper result evaluated
    /// with the same residuals for `Method::Paper`).
    pub adjustment: JointResult,
    /// How the calibration was made and its residual figures (in calibration.json).
    pub summary: AdjustmentSummary,
    /// calibration.json's `views` entries.
    pub records: Vec<ViewRecord>,
    /// The board's scale against the robot (`None` for the paper's method).
    pub board_scale: Option<BoardScaleCheck>,
    /// The leave-one-view-out figures (`None`: fewer than 4 views, the paper's method,
    /// or not asked for).
    pub leave_one_out: Option<LeaveOneOut>,
    pub views: Vec<ViewStatus>,
    pub warnings: Vec<String>,
}

impl crate::model::QualityFailure {
    /// The calibration of the views that agree, for inspection, when the pipeline could
    /// still compute one.
    pub fn report(&self) -> Option<&CalibrationReport> {
        self.inspection()
    }
}

/// Loads a dataset folder, observes it and calibrates it ([`calibrate_dataset_loaded`]).
pub fn calibrate_dataset(
    root: impl AsRef<Path>,
    opts: &CalibrateOptions,
) -> Result<CalibrationReport> {
    calibrate_dataset_loaded(&Dataset::load(root)?, opts)
}

/// Observes and calibrates a loaded dataset: [`observe_dataset`], then
/// [`calibrate_observations`]; views left out by the detection are listed in the
/// report's views and warnings.
pub fn calibrate_dataset_loaded(
    ds: &Dataset,
    opts: &CalibrateOptions,
) -> Result<CalibrationReport> {
    // before the images are looked at: a --from of another camera is refused at once
    calibrate::check_from_size(&ds.rig, opts)?;
    let Observed {
        obs,
        mut warnings,
        left_out,
        channel,
    } = observe(ds, opts)?;
    if obs.len() < 3 && obs.len() < ds.views.len() {
        // Not an input the adjustment could start from because views were refused: say
        // which views and why.
        let why: Vec<&String> = left_out.iter().map(|(_, w)| w).collect();
        return Err(Error::Detection(format!(
            "the board ({} x {} {}) was found in {} of {} views, at least 3 are needed: {}",
            ds.rig.board.rows,
            ds.rig.board.cols,
            ds.rig.board.kind.name(),
            obs.len(),
            ds.views.len(),
            why.iter()
                .map(|w| w.as_str())
                .collect::<Vec<_>>()
                .join("; ")
        )));
    }
    let (mut rep, checks) = calibrate::calibrate_unjudged(&obs, &ds.rig, opts)?;
    for (v, why) in left_out {
        if !rep.views.iter().any(|s| s.view == v) {
            rep.views.push(ViewStatus::left_out(v, Some(why)));
        }
    }
    rep.views.sort_by_key(|s| s.view);
    if ds.rig.stripe_channel != crate::model::StripeChannel::Gray {
        // the signal the stripes were found in (rig.json's, or what `auto` chose)
        rep.calibration.records.stripe_channel = Some(crate::model::StripeChannelChoice {
            channel: channel.0,
            scores: channel.1.map(|scores| {
                crate::vision::stripe::colour::SCORED
                    .iter()
                    .zip(scores)
                    .map(|(c, s)| (*c, s.round()))
                    .collect()
            }),
        });
    }
    warnings.append(&mut rep.warnings);
    rep.warnings = warnings;
    if !rep.warnings.is_empty() {
        rep.calibration.records.warnings.clone_from(&rep.warnings);
    }
    gates::judge(rep, checks, opts)
}
