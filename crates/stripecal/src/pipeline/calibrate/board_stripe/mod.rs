//! The stripe's bias on the calibration board, corrected before the final adjustment.
//!
//! ## Why
//!
//! The sub-pixel centre of a laser stripe is not the image of the sheet's centre plane
//! even on a flat board: across the sheet's thickness the shading (incidence and distance
//! to the emitter) and the perspective change, so the profile along the scan line is
//! skewed and its windowed centroid moves by a few thousandths of a pixel
//! ([`crate::reconstruct::fit::stripe_bias`], its plane variant). The shift has the same
//! sign in every view. On the paper's rig (twin, noise-free images, true geometry) the
//! board's stripe points lie +0.02 to +0.65 um off the sheet's centre plane, view by view;
//! the one-stage adjustment reads that as geometry and moves the hand-eye translation by
//! ~-1.3 um (4 sigma of its own covariance) and the plane offset by ~-0.5 um, on every
//! seed; without the laser images the same views give 0.1 um. The reconstruction then
//! carries that error into every measured point, and no random uncertainty covers it.
//!
//! ## What is done
//!
//! After the adjustment, with its camera and laser plane and each view's board pose from
//! its own circles (the camera stage's `T_cam_board`):
//! 1. the sheet's Gaussian sigma `s` (mm) and the PSF's sigma `b` (px) from the stripe
//!    widths: at a point whose image moves by `g = |da/dt|` px per mm of sheet offset, with
//!    the stripe's slope `m` against the scan line, `(W / 2.3548)^2 - (1 + m^2) / 12 =
//!    s^2 g^2 + b^2 (1 + m^2)` by linear least squares over the points (the board's tilt
//!    differs between views, so `g` varies and the two separate; refused, and nothing
//!    corrected, when it does not: `s^2 <= 0` or fewer than [`MIN_POINTS`] points);
//! 2. per stripe point, the profile the camera sees (the stripe-bias model's
//!    `board_point_profile`, [`bias::predicted_biases`]) and the extractor's own
//!    centroid on it: the predicted bias `delta` px along the scan line;
//!    the point is moved to `a - delta` (points the model cannot follow are left out and
//!    counted);
//! 3. the adjustment is run again from its own solution on the corrected points.
//!
//! Points whose profile holds a saturated pixel are clipped, so neither their width nor
//! their skew is the model's: they are kept as measured, left out of steps 1 and 2 and
//! counted (a clipped profile on a plane stays nearly symmetric; the sphere's correction
//! leaves its saturated points out of the fit instead, where the clipped skew is large).
//!
//! The emitter is not in a calibration: it is assumed at the plane's point nearest the
//! camera centre, `n d`.
//!
//! ## Its uncertainty
//!
//! The correction moves the calibration's numbers by `D` (corrected minus uncorrected).
//! What the model leaves is a systematic error shared by all views, added to the
//! covariance in two parts (`readjust.rs`):
//! - the model's neglected terms: `u^2 D D^T` (rank one, the same direction as the
//!   correction), `u` uniform within +-[`BOARD_NEGLECTED_FRACTION`] (10 %) of the
//!   correction (`0.058`; on the twin the correction leaves ~5 % of the hand-eye's bias,
//!   noise-free). The board's own bound: the sphere's
//!   ([`crate::reconstruct::fit::stripe_bias::NEGLECTED_FRACTION`], 8 %) comes from
//!   curved profiles at several rigs, sheets and noise levels;
//! - the emitter, which no calibration holds: taken as uniform within
//!   +-[`EMITTER_RANGE_MM`] of `n d` along each of the plane's two in-plane axes. The
//!   same points are moved by the biases predicted for the emitter at each end of each
//!   range ([`BoardStripeViews::emitter_moved`]) and the corrected solution is moved to
//!   theirs by two Gauss-Newton steps (`calib::joint::stepped_from`: the points move by
//!   thousandths of a pixel, so the change is linear in them; the whole adjustment
//!   where the steps do not apply); with `d_+`, `d_-` the changes of the numbers, each axis adds
//!   `(d_+ d_+^T + d_- d_-^T) / 6` (the variance `a^2 / 3` of a uniform distribution,
//!   read at both ends, the response not being quite linear). The emitter's effect is
//!   not along `D`: on the paper's twin it moves the plane's offset and the hand-eye's
//!   z more, and its x less, than a share of `D` would say. On the twin with the emitter
//!   moved 25 mm the hand-eye x error is -0.64 um against a sigma of 0.40 um
//!   (`crates/stripecal-sim/tests/it/board_stripe.rs`).
//!
//! The covariance of the DH corrections (robot calibration) is not augmented (their part
//! of the changes is not read).

mod readjust;

pub(super) use readjust::correct_stripes;

mod applicable;
mod bias;
mod moved;
mod points;
mod sheet;

use nalgebra::Vector3;

use crate::calib::ViewObs;
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::stripe_model::{neglected_share, Rig};
use crate::vision::stripe::StripeOptions;
use applicable::modelled_direction;
use bias::{moved_biases, predicted_biases};
use moved::moved_views;
use points::{board_planes, stripe_points, surfaces};
use sheet::sheet_sigmas;

/// Fewest stripe points with a width for the sheet's sigma.
pub const MIN_POINTS: usize = 50;
/// Points used for the width fit, at most.
const WIDTH_POINTS: usize = 1500;
/// The emitter's assumed position range within the plane, +- mm.
pub const EMITTER_RANGE_MM: f64 = 30.0;
/// The board model's neglected terms: the half width of their uniform distribution, as a
/// fraction of the correction (module docs).
pub const BOARD_NEGLECTED_FRACTION: f64 = 0.10;
/// Points lit at a larger incidence are not modelled.
const MAX_INCIDENCE_DEG: f64 = 80.0;

/// What the correction did.
#[derive(Debug, Clone)]
pub struct BoardStripeCorrection {
    /// The sheet's Gaussian sigma, mm, and the PSF's, px, from the widths.
    pub sheet_sigma_mm: f64,
    pub psf_sigma_px: f64,
    /// Points corrected, and left out.
    pub corrected: usize,
    pub dropped: usize,
    /// Saturated points: kept as measured, neither corrected nor in the width fit.
    pub saturated: usize,
    /// Mean and RMS of the predicted bias, px along the scan line.
    pub mean_px: f64,
    pub rms_px: f64,
    /// The standard uncertainty of the model's neglected terms per unit correction
    /// (module docs).
    pub neglected_share: f64,
    /// The emitter's assumed position range within the plane about `n d`, +- mm.
    pub emitter_range_mm: f64,
    /// The calibration's response to the emitter's position (set by the caller that
    /// ran the adjustments: [`super::emitter_carry`]).
    pub emitter_response: Option<super::emitter_carry::EmitterResponse>,
}

/// The corrected views and what the correction did.
#[derive(Debug, Clone)]
pub struct BoardStripeViews {
    /// The views with their stripe points moved by the predicted bias (points the model
    /// cannot follow left out).
    pub corrected: Vec<ViewObs>,
    /// The same points moved by the biases predicted with the emitter moved by
    /// `+-emitter_range_mm` along the plane's two in-plane axes, in the order `+e1, -e1,
    /// +e2, -e2` (the emitter's part of the uncertainty, module docs).
    pub emitter_moved: Vec<Vec<ViewObs>>,
    /// The assumed emitter `n d` and the plane's two in-plane axes it is moved along
    /// (camera frame).
    pub emitter_origin_cam_mm: Vector3<f64>,
    pub emitter_axes_cam: [Vector3<f64>; 2],
    pub summary: BoardStripeCorrection,
}

/// One stripe point's geometry.
struct Pt {
    view: usize,
    idx: usize,
    p: Vector3<f64>,
    line: f64,
    a: f64,
    width: f64,
    saturated: bool,
}

/// The share of saturated stripe points above which the correction is off: the
/// model is an unsaturated Gaussian sheet, and a line that is mostly clipped is not
/// (module docs).
pub const MAX_SATURATED_SHARE: f64 = 0.5;

/// The correction (module docs): the views with their stripe points moved by the
/// predicted bias (points the model cannot follow left out), and what it did; `Err`
/// with the reason when nothing is corrected (no view with widths, a line the model
/// does not describe: mostly saturated, or smoothed along the line for speckle; too
/// few points, a sheet sigma that the widths do not determine).
pub fn correct_board_stripes(
    views: &[ViewObs],
    cam_board: &[Iso3],
    camera: &Camera,
    plane: &Plane,
    stripe: &StripeOptions,
) -> std::result::Result<BoardStripeViews, String> {
    let direction = modelled_direction(views)?;
    let mut sopts = stripe.clone();
    sopts.direction = direction;
    let rig = Rig::new(
        camera,
        plane,
        plane.normal * plane.d,
        direction,
        &sopts,
        MAX_INCIDENCE_DEG,
    );
    let along = rig.along;
    let boards = board_planes(cam_board);
    let pts = stripe_points(views, cam_board, camera, along);
    // Saturated points are kept as measured and not modelled (module docs).
    let clear: Vec<&Pt> = pts.iter().filter(|q| !q.saturated).collect();
    if clear.len() < MIN_POINTS {
        return Err(format!(
            "{} unsaturated stripe points with a width, fewer than {MIN_POINTS}",
            clear.len()
        ));
    }
    // 1. Sheet and PSF sigmas from the widths (g and the slope do not depend on them).
    let (sigma, psf) = sheet_sigmas(&rig, &surfaces(&rig, &boards), &clear)?;
    // 2. The predicted bias per point, for the emitter at `n d` and moved.
    let delta = predicted_biases(&rig, &boards, &clear, sigma, psf, rig.emitter);
    // 3. The corrected views: points the model cannot follow left out, the others moved.
    let keep: Vec<bool> = delta.iter().map(Option::is_some).collect();
    let corrected = keep.iter().filter(|k| **k).count();
    if corrected < MIN_POINTS {
        return Err(format!(
            "the model follows {corrected} stripe points, fewer than {MIN_POINTS}"
        ));
    }
    // The views with every kept point moved by `d[k]` (the points of `clear` in order).
    let moved = |d: &[Option<f64>]| moved_views(views, &clear, &keep, d, along);
    // The emitter moved by +-EMITTER_RANGE_MM along the plane's two in-plane axes: the
    // same points moved by the biases predicted there (the change from the nominal
    // bias modelled on every 4th point of a view and interpolated, none where the
    // moved emitter's model fails, so that only the biases differ: `moved_biases`).
    let emitter_moved: Vec<Vec<ViewObs>> = [rig.e1, rig.e2]
        .iter()
        .flat_map(|dir| [1.0, -1.0].map(|s| rig.emitter + dir * (s * EMITTER_RANGE_MM)))
        .map(|e| moved_biases(&rig, &boards, &clear, &delta, (sigma, psf), e))
        .map(|alt| moved(&alt))
        .collect();
    let (sum, sum2) = delta
        .iter()
        .flatten()
        .fold((0.0, 0.0), |(s, s2), d| (s + d, s2 + d * d));
    let nc = corrected as f64;
    let summary = BoardStripeCorrection {
        sheet_sigma_mm: sigma,
        psf_sigma_px: psf,
        corrected,
        dropped: clear.len() - corrected,
        saturated: pts.len() - clear.len(),
        mean_px: sum / nc,
        rms_px: (sum2 / nc).sqrt(),
        neglected_share: neglected_share(BOARD_NEGLECTED_FRACTION),
        emitter_range_mm: EMITTER_RANGE_MM,
        emitter_response: None,
    };
    Ok(BoardStripeViews {
        corrected: moved(&delta),
        emitter_moved,
        emitter_origin_cam_mm: rig.emitter,
        emitter_axes_cam: [rig.e1, rig.e2],
        summary,
    })
}
