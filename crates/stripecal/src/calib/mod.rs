//! Calibration: camera (Zhang + adjustment with a bias-free circle-centre model), laser
//! plane, hand-eye / robot-world (AX = ZB by Kronecker least squares), and the
//! one-stage adjustment of everything together.
//!
//! ## Conventions
//!
//! - Per view i: `A_i = T_base_hand(q_i)`, `X = T_hand_cam`, `Z = T_base_board`,
//!   `B_i = T_board_cam(i) = inverse(T_cam_board(i))`, and `A_i X = Z B_i`.
//! - Observations are in pixels (spec convention: top-left pixel centre at (0, 0)).
//! - Camera parameter vectors follow [`crate::model::camera::PARAM_NAMES`].
//! - Views keep their dataset row index (`ViewObs::view`) through every stage: a view
//!   that fails is dropped whole, never shifted.

pub mod axzb;
pub mod camera;
pub mod clustered;
pub mod conic;
pub mod consensus;
pub mod flatness;
pub mod homography;
pub mod joint;
pub mod laser_plane;
pub mod profile;
pub mod zhang;

use crate::model::geometry::Iso3;
use crate::model::RobotReading;

/// One detected circle: grid index and imaged centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleObs {
    pub row: usize,
    pub col: usize,
    /// Imaged centre (centroid of the imaged outline), px.
    pub u: f64,
    pub v: f64,
}

/// Everything one calibration view contributes.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewObs {
    /// The view's row in views.csv (0-based), for messages and reports.
    pub view: usize,
    /// Detected circles.
    pub circles: Vec<CircleObs>,
    /// Stripe points on the board `(u, v)` px (points flagged at reflectance edges
    /// already removed); empty when the view has no laser image.
    pub stripe: Vec<[f64; 2]>,
    /// What the robot reported for this view.
    pub reading: Option<RobotReading>,
    /// `T_base_hand` for the reading (forward kinematics of the nominal robot, or the
    /// reported flange pose).
    pub base_hand: Option<Iso3>,
    /// Board symmetries the view's image cannot decide: the circles could equally be
    /// labelled by any of them ([`crate::vision::target::TargetDetection::alternatives`]);
    /// the calibration chooses from the robot poses ([`consensus`]).
    pub alternatives: Vec<crate::model::board::Symmetry>,
    /// How the stripe was extracted, when known: the scan lines' direction and each
    /// point's width (index-aligned with `stripe`), for the model of the stripe's bias on
    /// the board ([`crate::pipeline`]'s stripe correction); `None`: not corrected.
    pub stripe_shape: Option<StripeShape>,
}

pub use crate::model::StripeExtraction;

/// The items of `v` where `keep` holds (index-aligned).
pub(crate) fn kept<T: Copy>(v: &[T], keep: &[bool]) -> Vec<T> {
    v.iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(x, _)| *x)
        .collect()
}

impl StripeShape {
    /// The points where `keep` holds (`keep` index-aligned with the points).
    pub fn subset(&self, keep: &[bool]) -> StripeShape {
        StripeShape {
            direction: self.direction,
            width_px: kept(&self.width_px, keep),
            saturated: kept(&self.saturated, keep),
            along_line: self.along_line,
            extraction: self.extraction,
        }
    }
}

/// The extraction behind a view's stripe points ([`ViewObs::stripe_shape`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StripeShape {
    /// The scan lines the extractor searched (`Rows` or `Cols`, never `Auto`).
    pub direction: crate::model::StripeDirection,
    /// The stripe's width (FWHM along the scan line) at each point, px.
    pub width_px: Vec<f64>,
    /// Each point's profile holds a saturated pixel (clipped: its width and skew are not
    /// the bias model's).
    pub saturated: Vec<bool>,
    /// Scan lines averaged along the line before the centres (1: none; more for a
    /// saturated or speckled line: not the bias model's single profile).
    pub along_line: usize,
    /// What the extraction found and left out.
    pub extraction: StripeExtraction,
}
