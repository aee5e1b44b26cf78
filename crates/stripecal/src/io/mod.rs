//! Files of spec/DATASET.md: rig.json, views.csv, scan.csv, calibration.json,
//! truth.json, sphere fits, PLY point clouds and grayscale images.
//!
//! ## Conventions
//!
//! - Readers follow the spec exactly and reject anything else with [`Error::Format`]
//!   naming the file, the line / column or JSON key, and what was expected. Unknown JSON
//!   keys are ignored (and kept in `extra` where a struct has one).
//! - Writers never leave a half-written file: they write a temporary file in the
//!   target's folder and rename it over the target ([`write_atomic`]).
//! - Angles in files are degrees except rotation vectors (radians); lengths in mm.
//! - Image paths in views.csv / scan.csv are kept as written (relative to the dataset
//!   folder); [`Dataset::image_path`] resolves them.

mod atomic;
mod calibration;
mod csv;
mod imageio;
mod json;
mod ply;
mod rig;

pub use atomic::write_atomic;
pub use calibration::{
    calibration_from_json, calibration_to_json, read_calibration, read_sphere_fit, read_truth,
    sphere_fit_to_json, truth_from_json, truth_to_json, write_calibration, write_sphere_fit,
    write_truth,
};
pub use csv::{read_scan_csv, read_views_csv, write_scan_csv, write_views_csv};
pub use imageio::{
    load_gray, load_gray_info, save_gray_png, ImageInfo, MAX_IMAGE_BYTES, MAX_IMAGE_SIDE,
};
pub use ply::{read_ply, write_ply, PlyFormat};
pub use rig::{read_rig, rig_from_json, rig_to_json, write_rig};

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use crate::board::Board;
use crate::camera::{Camera, DistortionModel};
use crate::error::{Error, Result};
use crate::geometry::{Iso3, Plane};
use crate::kinematics::Robot;

/// The `stripe.direction` hint of rig.json.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StripeDirection {
    /// Decide from the image.
    #[default]
    Auto,
    /// The stripe runs roughly along image rows: one stripe point per column.
    Rows,
    /// The stripe runs roughly along image columns: one stripe point per row.
    Cols,
}

impl StripeDirection {
    /// `auto`, `rows` or `cols`.
    pub fn name(self) -> &'static str {
        match self {
            StripeDirection::Auto => "auto",
            StripeDirection::Rows => "rows",
            StripeDirection::Cols => "cols",
        }
    }

    /// Parses `auto`, `rows` or `cols`.
    pub fn from_name(s: &str) -> Result<Self> {
        match s {
            "auto" => Ok(StripeDirection::Auto),
            "rows" => Ok(StripeDirection::Rows),
            "cols" => Ok(StripeDirection::Cols),
            other => Err(Error::InvalidInput(format!(
                "unknown stripe direction {other:?}: expected \"auto\", \"rows\" or \"cols\""
            ))),
        }
    }
}

/// The rig description (`rig.json`).
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    /// Image width (pixels).
    pub width: u32,
    /// Image height (pixels).
    pub height: u32,
    /// Distortion model calibration uses unless told otherwise (default `radial1`).
    pub distortion_model: DistortionModel,
    /// The calibration target.
    pub board: Board,
    /// The robot's nominal DH table; `None` when the controller reports flange poses.
    pub robot: Option<Robot>,
    /// Stripe direction hint.
    pub stripe_direction: StripeDirection,
}

/// What the robot reported for one pose.
#[derive(Debug, Clone, PartialEq)]
pub enum RobotReading {
    /// Encoder readings q1..qN in degrees.
    Joints(Vec<f64>),
    /// `T_base_hand` reported by the controller.
    FlangePose(Iso3),
}

impl RobotReading {
    /// `T_base_hand` for this reading: forward kinematics of `robot` for joints, the
    /// pose itself for flange poses. Errors when joints are given without a robot.
    pub fn base_hand(&self, robot: Option<&Robot>) -> Result<Iso3> {
        match self {
            RobotReading::FlangePose(t) => Ok(*t),
            RobotReading::Joints(q) => match robot {
                Some(r) => r.forward(q),
                None => Err(Error::InvalidInput(
                    "joint readings given but the rig has no robot (DH table)".into(),
                )),
            },
        }
    }
}

/// One row of views.csv.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// The 1-based line of the row in views.csv (the header is line 1).
    pub line: usize,
    /// The board image (laser off), relative to the dataset folder as written.
    pub board_image: PathBuf,
    /// The laser image, `None` when the column is empty. May equal `board_image`.
    pub laser_image: Option<PathBuf>,
    /// Joint readings or the flange pose.
    pub reading: RobotReading,
}

/// One row of scan.csv.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanFrame {
    /// The 1-based line of the row in scan.csv.
    pub line: usize,
    /// The stripe image, relative to the scan folder as written.
    pub image: PathBuf,
    /// Joint readings or the flange pose.
    pub reading: RobotReading,
}

/// A calibration dataset folder: rig.json + views.csv (+ images).
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    pub root: PathBuf,
    pub rig: Rig,
    pub views: Vec<View>,
}

impl Dataset {
    /// Loads `root/rig.json` and `root/views.csv` and checks that every image named
    /// exists and that joint columns match the robot. Never reads truth.json.
    pub fn load(root: impl AsRef<Path>) -> Result<Dataset> {
        let root = root.as_ref().to_path_buf();
        let rig = read_rig(root.join("rig.json"))?;
        let views_path = root.join("views.csv");
        let views = read_views_csv(&views_path, rig.robot.as_ref())?;
        if views.is_empty() {
            return Err(Error::format(
                &views_path,
                "line 2",
                "views.csv has no views",
            ));
        }
        if rig.robot.is_none() && matches!(views[0].reading, RobotReading::Joints(_)) {
            return Err(Error::format(
                &views_path,
                "line 1",
                "joint columns q1..qN need a robot (DH table) in rig.json; \
                 without one, use the flange-pose columns x_mm,y_mm,z_mm,qw,qx,qy,qz",
            ));
        }
        for v in &views {
            check_image_exists(&root, &views_path, v.line, &v.board_image)?;
            if let Some(l) = &v.laser_image {
                check_image_exists(&root, &views_path, v.line, l)?;
            }
        }
        Ok(Dataset { root, rig, views })
    }

    /// The full path of an image named in the dataset.
    pub fn image_path(&self, rel: &Path) -> PathBuf {
        self.root.join(rel)
    }
}

/// A scan folder: scan.csv (+ images, optional rig.json).
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    pub root: PathBuf,
    pub rig: Option<Rig>,
    pub frames: Vec<ScanFrame>,
}

impl Scan {
    /// Loads `root/scan.csv` (and `root/rig.json` when present), checking images exist.
    /// `robot` is used to check the joint count when the scan has no rig.json.
    pub fn load(root: impl AsRef<Path>, robot: Option<&Robot>) -> Result<Scan> {
        let root = root.as_ref().to_path_buf();
        let rig_path = root.join("rig.json");
        let rig = if rig_path.exists() {
            Some(read_rig(&rig_path)?)
        } else {
            None
        };
        let robot = rig.as_ref().and_then(|r| r.robot.as_ref()).or(robot);
        let csv_path = root.join("scan.csv");
        let frames = read_scan_csv(&csv_path, robot)?;
        if frames.is_empty() {
            return Err(Error::format(&csv_path, "line 2", "scan has no frames"));
        }
        for f in &frames {
            check_image_exists(&root, &csv_path, f.line, &f.image)?;
        }
        Ok(Scan { root, rig, frames })
    }

    /// The full path of an image named in the scan.
    pub fn image_path(&self, rel: &Path) -> PathBuf {
        self.root.join(rel)
    }
}

fn check_image_exists(root: &Path, csv: &Path, line: usize, rel: &Path) -> Result<()> {
    let p = root.join(rel);
    if !p.is_file() {
        return Err(Error::format(
            csv,
            format!("line {line}"),
            format!("image {} does not exist", p.display()),
        ));
    }
    Ok(())
}

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
