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
use crate::stripe_model::{extractor_response, point_profile, PointProfile, Rig, SphereSurface};

use super::points::point_geo;
use super::StripeBiasOptions;

/// The model's predicted stripe bias per point (px along the scan line: the extractor's
/// centre minus the image of the sheet's centre plane), for the sphere `(centre,
/// radius)` in the base frame and given sigmas `(sheet mm, PSF px)`; `None` where the
/// model fails. For diagnostics against a twin's true stripe.
pub(crate) fn predicted_bias_px(
    inputs: &ModelInputs<'_>,
    sphere: (&Vector3<f64>, f64),
    (sigma, psf): (f64, f64),
) -> Result<Vec<Option<f64>>> {
    per_modelled_point(
        inputs,
        sphere,
        (sigma, psf),
        |rig, _, prof, buf: &mut Vec<f64>| {
            extractor_response(prof, psf, rig.stripe, buf).map(|x| x.0)
        },
    )
}

/// The scan, its poses and the model's setting, as [`super::correct_sphere_bias`] takes
/// them.
pub(crate) struct ModelInputs<'a> {
    pub points: &'a ScanPoints,
    /// `T_base_cam` per frame.
    pub base_cam: &'a [Iso3],
    pub camera: &'a Camera,
    pub plane: &'a Plane,
    pub opts: &'a StripeBiasOptions,
}

/// `f(rig, i, profile, scratch)` on each point's modelled profile for the sphere
/// `(centre, radius)` (base frame) and the sigmas `(sheet mm, PSF px)`, in parallel;
/// `None` where the point is saturated or the model fails. What the diagnostics
/// ([`predicted_bias_px`], [`super::noise::predicted_noise_shift_px`]) share.
pub(crate) fn per_modelled_point<T: Send, S: Default + Send>(
    inputs: &ModelInputs<'_>,
    sphere: (&Vector3<f64>, f64),
    (sigma, psf): (f64, f64),
    f: impl Fn(&Rig<'_>, usize, &PointProfile, &mut S) -> Option<T> + Sync + Send,
) -> Result<Vec<Option<T>>> {
    let (points, base_cam, camera, plane, opts) = (
        inputs.points,
        inputs.base_cam,
        inputs.camera,
        inputs.plane,
        inputs.opts,
    );
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
                let surf = SphereSurface { c: &c, r: sphere.1 };
                if !point_profile(&rig, &surf, g.line, &g.p_cam, sigma, psf, prof) {
                    return None;
                }
                f(&rig, i, prof, scratch)
            },
        )
        .collect())
}
