//! The model's diagnostics on a scan (for the unit tests; the studies that once used
//! them are in `studies/stripe_bias`): each point's modelled profile for a given sphere
//! and sigmas, and the extractor's predicted bias on it.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::Result;
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::StripeDirection;
use crate::reconstruct::{stripe_direction_from_plane, ScanPoints};
use crate::stripe_model::{extractor_response, point_profile, PointProfile, Rig};

use super::points::point_geo;
use super::StripeBiasOptions;

/// The model's predicted stripe bias per point (px along the scan line: the extractor's
/// centre minus the image of the sheet's centre plane), for the sphere `(centre,
/// radius)` in the base frame and given sheet (mm) and PSF (px) sigmas; `None` where
/// the model fails. For diagnostics against a twin's true stripe; arguments as
/// [`super::correct_sphere_bias`].
#[allow(clippy::too_many_arguments)]
pub(crate) fn predicted_bias_px(
    points: &ScanPoints,
    base_cam: &[Iso3],
    camera: &Camera,
    plane: &Plane,
    sphere: (&Vector3<f64>, f64),
    sheet_sigma_mm: f64,
    psf_sigma_px: f64,
    opts: &StripeBiasOptions,
) -> Result<Vec<Option<f64>>> {
    per_modelled_point(
        (points, base_cam, camera, plane, opts),
        sphere,
        (sheet_sigma_mm, psf_sigma_px),
        |rig, _, prof, buf: &mut Vec<f64>| {
            extractor_response(prof, psf_sigma_px, rig.stripe, buf).map(|x| x.0)
        },
    )
}

/// The scan, its poses and the model's setting: `(points, base_cam, camera, plane, opts)`.
pub(crate) type ModelInputs<'a> = (
    &'a ScanPoints,
    &'a [Iso3],
    &'a Camera,
    &'a Plane,
    &'a StripeBiasOptions,
);

/// `f(rig, i, profile, scratch)` on each point's modelled profile for the sphere
/// `(centre, radius)` (base frame) and the sigmas `(sheet mm, PSF px)`, in parallel;
/// `None` where the point is saturated or the model fails. What the diagnostics
/// ([`predicted_bias_px`], [`super::noise::predicted_noise_shift_px`]) share.
pub(crate) fn per_modelled_point<T: Send, S: Default + Send>(
    (points, base_cam, camera, plane, opts): ModelInputs<'_>,
    sphere: (&Vector3<f64>, f64),
    (sigma, psf): (f64, f64),
    f: impl Fn(&Rig<'_>, usize, &PointProfile, &mut S) -> Option<T> + Sync + Send,
) -> Result<Vec<Option<T>>> {
    let mut stripe = opts.stripe.clone();
    if stripe.direction == StripeDirection::Auto {
        stripe.direction = stripe_direction_from_plane(camera, plane);
    }
    let rig = super::sphere_rig(camera, plane, &stripe, opts)?;
    let cam_base: Vec<Iso3> = base_cam.iter().map(|t| t.inverse()).collect();
    let geo = (0..points.len())
        .map(|i| point_geo(points, &cam_base, rig.along, i))
        .collect::<Result<Vec<_>>>()?;
    Ok(geo
        .par_iter()
        .enumerate()
        .map_init(
            || (PointProfile::default(), S::default()),
            |(prof, scratch), (i, (g, fr))| {
                if g.saturated {
                    return None;
                }
                let c = (cam_base[*fr] * nalgebra::Point3::from(*sphere.0)).coords;
                if !point_profile(&rig, &c, sphere.1, g.line, &g.p_cam, sigma, psf, prof) {
                    return None;
                }
                f(&rig, i, prof, scratch)
            },
        )
        .collect())
}
