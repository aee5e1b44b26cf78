//! Options of the reconstruction and the stripe direction a laser plane gives.

use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::Plane;
use crate::model::{StripeChannel, StripeDirection};
use crate::vision::stripe::StripeOptions;

/// Default smallest angle between a viewing ray and the laser plane, degrees.
pub const DEFAULT_MIN_RAY_PLANE_ANGLE_DEG: f64 = 2.0;

/// What [`super::reconstruct_scan`] does with a frame whose image cannot be used: the
/// file is missing or unreadable, cannot be decoded (truncated, corrupted, not an image
/// of a supported format), is not the calibrated camera's size, or has another bit
/// depth (8 or 16) than the scan's other frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BadImage {
    /// The run stops with [`Error::BadImage`] naming the frame, its scan.csv line, the
    /// file and what is wrong; nothing is returned (the default).
    #[default]
    Stop,
    /// The frame is left out and listed, with the reason, in
    /// [`super::ScanPoints::skipped`]; the other frames are reconstructed.
    Skip,
}

impl BadImage {
    /// `"stop"` or `"skip"`.
    pub fn from_name(s: &str) -> Result<BadImage> {
        match s {
            "stop" => Ok(BadImage::Stop),
            "skip" => Ok(BadImage::Skip),
            other => Err(Error::InvalidInput(format!(
                "on_bad_image {other:?}: expected \"stop\" or \"skip\""
            ))),
        }
    }

    /// The name [`BadImage::from_name`] reads.
    pub fn name(self) -> &'static str {
        match self {
            BadImage::Stop => "stop",
            BadImage::Skip => "skip",
        }
    }
}

/// Options of the reconstruction.
#[derive(Debug, Clone, PartialEq)]
pub struct ReconstructOptions {
    /// Stripe extraction. `direction: Auto` is replaced by the direction the laser plane
    /// gives in the image ([`stripe_direction_from_plane`]): a scan's rig.json hint, when
    /// there is one, should be set here.
    pub stripe: StripeOptions,
    /// Rays meeting the laser plane at a smaller angle are dropped, degrees (0..90).
    pub min_ray_plane_angle_deg: f64,
    /// Stripe points with any of these `FLAG_*` bits are dropped (0 = keep all; the
    /// flags are reported per point).
    pub drop_flags: u8,
    /// Scan folders only: stop at a frame whose image cannot be used, or skip it
    /// ([`BadImage`]; default [`BadImage::Stop`]).
    pub on_bad_image: BadImage,
    /// Scan folders only: the signal of colour frames the stripe is found in
    /// ([`crate::vision::stripe::colour`]); `None` (the default): the scan's rig.json
    /// `stripe.channel`, gray without one.
    pub channel: Option<StripeChannel>,
}

impl Default for ReconstructOptions {
    fn default() -> Self {
        ReconstructOptions {
            stripe: StripeOptions::default(),
            min_ray_plane_angle_deg: DEFAULT_MIN_RAY_PLANE_ANGLE_DEG,
            drop_flags: 0,
            on_bad_image: BadImage::Stop,
            channel: None,
        }
    }
}

impl ReconstructOptions {
    /// Checks the values.
    pub fn validate(&self) -> Result<()> {
        self.stripe.validate()?;
        let a = self.min_ray_plane_angle_deg;
        if !(a.is_finite() && (0.0..90.0).contains(&a)) {
            return Err(Error::InvalidInput(format!(
                "min_ray_plane_angle_deg = {a} must be in [0, 90)"
            )));
        }
        Ok(())
    }
}

/// The direction the stripe runs in the image, from the laser plane alone.
///
/// On a surface facing the camera (`z = const`) the stripe is the image line
/// `n_x xn + n_y yn = const`, whose normal in pixels is `(n_x / fu, n_y / fv)`: when that
/// normal is mostly along `u` the stripe runs along the columns ([`StripeDirection::Cols`],
/// one point per row), otherwise along the rows ([`StripeDirection::Rows`]). Depth changes
/// move the stripe along the normal, so the direction holds for any object.
pub fn stripe_direction_from_plane(camera: &Camera, plane: &Plane) -> StripeDirection {
    let gu = plane.normal.x / camera.fu;
    let gv = plane.normal.y / camera.fv;
    if gu.abs() >= gv.abs() {
        StripeDirection::Cols
    } else {
        StripeDirection::Rows
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::triangulate::tests::camera;
    use nalgebra::Vector3;

    #[test]
    fn direction_from_plane() {
        let cam = camera([0.0; 5]);
        let p = |n: [f64; 3]| Plane::new(Vector3::from(n), 80.0).unwrap();
        assert_eq!(
            stripe_direction_from_plane(&cam, &p([0.629, -0.0492, 0.7759])),
            StripeDirection::Cols
        );
        assert_eq!(
            stripe_direction_from_plane(&cam, &p([0.05, 0.6, 0.8])),
            StripeDirection::Rows
        );
    }
}
