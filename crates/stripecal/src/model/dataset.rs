//! The dataset records of spec/DATASET.md: the rig, the calibration views and the scan
//! frames with their robot readings. Reading and writing them is `io`'s job.

use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::camera::DistortionModel;
use crate::model::geometry::Iso3;
use crate::model::kinematics::Robot;

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

/// The `stripe.channel` of rig.json: which representation of a laser image the stripe
/// is found in (spec/DATASET.md; how a colour's contrast is formed:
/// [`crate::vision::stripe::colour`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum StripeChannel {
    /// The image converted to gray by BT.601 luma (gray images as they are).
    #[default]
    Gray,
    /// The red channel's contrast (a red laser).
    Red,
    /// The green channel's contrast (a green laser).
    Green,
    /// The blue channel's contrast (a blue or violet laser).
    Blue,
    /// Decided once per dataset from its laser images (may pick `Gray`).
    Auto,
}

impl StripeChannel {
    /// The names rig.json and the APIs use, in [`StripeChannel::ALL`]'s order.
    pub const NAMES: [&'static str; 5] = ["gray", "red", "green", "blue", "auto"];
    /// Every value.
    pub const ALL: [StripeChannel; 5] = [
        StripeChannel::Gray,
        StripeChannel::Red,
        StripeChannel::Green,
        StripeChannel::Blue,
        StripeChannel::Auto,
    ];

    /// `gray`, `red`, `green`, `blue` or `auto`.
    pub fn name(self) -> &'static str {
        match self {
            StripeChannel::Gray => "gray",
            StripeChannel::Red => "red",
            StripeChannel::Green => "green",
            StripeChannel::Blue => "blue",
            StripeChannel::Auto => "auto",
        }
    }

    /// Parses `gray`, `red`, `green`, `blue` or `auto` ([`Error::InvalidInput`] naming
    /// the accepted names otherwise).
    pub fn from_name(s: &str) -> Result<Self> {
        StripeChannel::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| {
                Error::InvalidInput(format!(
                    "unknown stripe channel {s:?}: expected \"gray\", \"red\", \"green\", \"blue\" \
                     or \"auto\""
                ))
            })
    }

    /// The colour's index in an RGB pixel (0, 1, 2); `None` for `Gray` and `Auto`.
    pub fn rgb_index(self) -> Option<usize> {
        match self {
            StripeChannel::Red => Some(0),
            StripeChannel::Green => Some(1),
            StripeChannel::Blue => Some(2),
            StripeChannel::Gray | StripeChannel::Auto => None,
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
    /// The laser's colour in colour laser images (`stripe.channel`, default gray).
    pub stripe_channel: StripeChannel,
}

/// What the robot reported for one pose.
#[derive(Debug, Clone, PartialEq)]
pub enum RobotReading {
    /// Encoder readings q1..qN in degrees.
    Joints(Vec<f64>),
    /// `T_base_hand` reported by the controller.
    FlangePose(Iso3),
    /// No pose at all: the sensor is fixed (a bench dataset, whose views.csv has no
    /// pose columns; a scan of a fixed sensor, whose scan.csv has the image column
    /// alone).
    Fixed,
}

impl RobotReading {
    /// `T_base_hand` for this reading: forward kinematics of `robot` for joints, the
    /// pose itself for flange poses. Errors when joints are given without a robot, when
    /// a flange pose is not finite, and for [`RobotReading::Fixed`] (there is no pose).
    pub fn base_hand(&self, robot: Option<&Robot>) -> Result<Iso3> {
        match self {
            RobotReading::Fixed => Err(Error::InvalidInput(
                "no robot pose: the sensor is fixed (no pose columns)".into(),
            )),
            RobotReading::FlangePose(t) => {
                let finite = t.translation.vector.iter().all(|x| x.is_finite())
                    && t.rotation.coords.iter().all(|x| x.is_finite());
                if finite {
                    Ok(*t)
                } else {
                    Err(Error::InvalidInput(
                        "the flange pose T_base_hand is not finite".into(),
                    ))
                }
            }
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
    /// Joint readings, the flange pose, or [`RobotReading::Fixed`] in a bench dataset.
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
    /// A bench dataset: views.csv has no pose columns (the sensor calibrated on its
    /// own, the board moved by hand; spec/DATASET.md).
    pub fn is_bench(&self) -> bool {
        self.views
            .first()
            .is_some_and(|v| v.reading == RobotReading::Fixed)
    }
}

impl Scan {
    /// A scan of a fixed sensor: scan.csv has the image column alone; its points are
    /// in the sensor frame.
    pub fn is_fixed(&self) -> bool {
        self.frames
            .first()
            .is_some_and(|f| f.reading == RobotReading::Fixed)
    }
}

/// A scan folder: scan.csv (+ images, optional rig.json).
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    pub root: PathBuf,
    pub rig: Option<Rig>,
    pub frames: Vec<ScanFrame>,
}
