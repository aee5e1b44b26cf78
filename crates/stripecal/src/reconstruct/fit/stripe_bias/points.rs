//! Per point: its geometry in the camera frame, its correction (re-triangulated at the
//! modelled centre) and the corrected points ([`super`] docs).

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::StripeDirection;
use crate::reconstruct::triangulate::Triangulator;
use crate::reconstruct::{stripe_direction_from_plane, ScanPoints};

use super::StripeBiasOptions;
use crate::stripe_model::{extractor_response, point_profile, PointProfile, Rig};

/// Everything per point the correction needs: the camera-frame point, the scan line,
/// the measured along-line coordinate, and whether its stripe profile holds a saturated
/// pixel ([`ScanPoints::saturated`]: clipped at full scale, which the model does not contain,
/// so the point is not modelled).
pub(crate) struct PointGeo {
    pub p_cam: Vector3<f64>,
    pub line: f64,
    pub a_meas: f64,
    pub saturated: bool,
}

pub(crate) fn point_geo(
    points: &ScanPoints,
    cam_base: &[Iso3],
    along: usize,
    i: usize,
) -> Result<(PointGeo, usize)> {
    let f = points.frame[i] as usize;
    let t = cam_base.get(f).ok_or_else(|| {
        Error::InvalidInput(format!(
            "point {i} is of frame {f}, but only {} frame poses were given",
            cam_base.len()
        ))
    })?;
    let p_cam = (t * nalgebra::Point3::from(Vector3::from(points.points_mm[i]))).coords;
    let uv = [points.u_px[i], points.v_px[i]];
    Ok((
        PointGeo {
            p_cam,
            line: uv[1 - along],
            a_meas: uv[along],
            saturated: points.saturated(i),
        },
        f,
    ))
}

/// What a scan's points are corrected with besides the model: the triangulator, each
/// point's geometry and frame ([`point_geo`]), each frame's `T_cam_base`.
pub(crate) struct ScanGeometry<'a> {
    pub tri: &'a Triangulator,
    pub geo: &'a [(PointGeo, usize)],
    pub cam_base: &'a [Iso3],
}

/// The 3D corrections (base frame) of the points `idx` for a sphere (base frame) and
/// model parameters; `None` per point where the model fails.
pub(crate) fn corrections(
    rig: &Rig<'_>,
    scan: &ScanGeometry<'_>,
    idx: &[usize],
    sphere: (&Vector3<f64>, f64),
    sigma: f64,
    psf: f64,
) -> Vec<Option<[f64; 3]>> {
    let (tri, geo, cam_base) = (scan.tri, scan.geo, scan.cam_base);
    idx.par_iter()
        .map_init(
            || (PointProfile::default(), Vec::new()),
            |(prof, buf), &i| {
                let (g, f) = &geo[i];
                if g.saturated {
                    return None;
                }
                let t = &cam_base[*f];
                let c = (t * nalgebra::Point3::from(*sphere.0)).coords;
                if !point_profile(rig, &c, sphere.1, g.line, &g.p_cam, sigma, psf, prof) {
                    return None;
                }
                let (delta, _, _) = extractor_response(prof, psf, rig.stripe, buf)?;
                let uv = |a: f64| {
                    if rig.along == 0 {
                        (a, g.line)
                    } else {
                        (g.line, a)
                    }
                };
                let (u1, v1) = uv(g.a_meas);
                let (u2, v2) = uv(g.a_meas - delta);
                let p1 = tri.point_cam_mm(u1, v1)?;
                let p2 = tri.point_cam_mm(u2, v2)?;
                let b = t.inverse_transform_vector(&(p1 - p2));
                Some([b.x, b.y, b.z])
            },
        )
        .collect()
}

/// The points `idx` minus their corrections (skipping the unmodelled).
pub(crate) fn corrected_points(
    points: &ScanPoints,
    idx: &[usize],
    corr: &[Option<[f64; 3]>],
) -> Vec<[f64; 3]> {
    idx.iter()
        .zip(corr)
        .filter_map(|(&i, c)| {
            c.map(|c| {
                let p = points.points_mm[i];
                [p[0] - c[0], p[1] - c[1], p[2] - c[2]]
            })
        })
        .collect()
}

/// The model's predicted stripe bias per point (px along the scan line: the extractor's
/// centre minus the image of the sheet's centre plane), for the sphere `(centre,
/// radius)` in the base frame and given sheet (mm) and PSF (px) sigmas; `None` where
/// the model fails. For diagnostics against a twin's true stripe; arguments as
/// [`correct_sphere_bias`].
#[allow(clippy::too_many_arguments)]
pub fn predicted_bias_px(
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
/// ([`predicted_bias_px`], [`super::predicted_noise_shift_px`]) share.
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
