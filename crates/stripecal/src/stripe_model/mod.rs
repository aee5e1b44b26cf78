//! The stripe-bias model: what the stripe extractor measures on a curved or flat surface
//! lit by a laser sheet of Gaussian thickness, one stripe point at a time (the rig as the
//! model sees it, the surface's section at each sheet offset, its shading, the profile
//! the camera sees and the extractor's response on it; the maths in
//! [`crate::reconstruct::fit::stripe_bias`]'s docs, "The model of one stripe point").
//!
//! Two users: the measurement's sphere correction
//! ([`crate::reconstruct::fit::correct_sphere_bias`], [`profile`]'s sphere) and the
//! calibration's board correction (`pipeline/calibrate/board_stripe/`, [`plane`]'s
//! board). It uses only `model/` and `vision::stripe`'s extractor, so it sits with
//! `calib/`, below both.

pub(crate) mod image;
mod plane;
pub(crate) mod profile;

pub(crate) use image::extractor_response;
pub(crate) use plane::{board_point_profile, board_point_scale, Board as BoardSurface};
pub(crate) use profile::{
    plane_basis, point_geometry, point_profile, point_section, profile_for_emitter, PointGeometry,
    PointProfile, Rig, SphereSurface,
};

/// Sheet offsets sampled on each side of the plane, at least (`2 M + 1` samples over
/// `+-4 sigma`; more where they would lie more than [`image::sample_spacing_px`] apart
/// in the image).
pub const HALF_SAMPLES: usize = 10;

/// The standard uncertainty of neglected terms per unit correction when they are
/// uniform within `+-fraction` of it: the sphere's is `neglected_share(NEGLECTED_FRACTION)`
/// (`reconstruct::fit::stripe_bias`), the board's `neglected_share(BOARD_NEGLECTED_FRACTION)`
/// (`pipeline/calibrate/board_stripe/`).
pub fn neglected_share(fraction: f64) -> f64 {
    fraction / 3f64.sqrt()
}
