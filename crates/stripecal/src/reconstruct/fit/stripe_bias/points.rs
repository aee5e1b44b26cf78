//! Per point: its geometry in the camera frame, its correction (re-triangulated at the
//! modelled centre) and the corrected points ([`super`] docs).

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::reconstruct::triangulate::Triangulator;
use crate::reconstruct::ScanPoints;

use crate::stripe_model::{
    extractor_response, point_geometry, point_profile, profile_for_emitter, PointGeometry,
    PointProfile, Rig, SphereSurface,
};

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
    corrections_from_deltas(rig, scan, idx, &deltas(rig, scan, idx, sphere, sigma, psf))
}

/// The corrections of the points `idx` as [`corrections`] gives them, for each of the
/// `emitters` in turn (`rig`'s own emitter replaced; camera frame): each point's sections
/// are solved once for all of them ([`point_geometry`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn corrections_for_emitters(
    rig: &Rig<'_>,
    scan: &ScanGeometry<'_>,
    idx: &[usize],
    sphere: (&Vector3<f64>, f64),
    sigma: f64,
    psf: f64,
    emitters: &[Vector3<f64>],
) -> Vec<Vec<Option<[f64; 3]>>> {
    let (tri, geo, cam_base) = (scan.tri, scan.geo, scan.cam_base);
    let rigs: Vec<Rig<'_>> = emitters
        .iter()
        .map(|e| {
            let mut r2 = rig.clone();
            r2.emitter = *e;
            r2
        })
        .collect();
    let per_point: Vec<Vec<Option<[f64; 3]>>> = idx
        .par_iter()
        .map_init(
            || {
                (
                    PointGeometry::default(),
                    Vec::new(),
                    PointProfile::default(),
                    Vec::new(),
                )
            },
            |(pg, scratch, prof, buf), &i| {
                let (g, f) = &geo[i];
                let t = &cam_base[*f];
                let c = (t * nalgebra::Point3::from(*sphere.0)).coords;
                let surf = SphereSurface { c: &c, r: sphere.1 };
                if g.saturated
                    || !point_geometry(rig, &surf, g.line, &g.p_cam, sigma, psf, scratch, pg)
                {
                    return vec![None; rigs.len()];
                }
                rigs.iter()
                    .map(|r2| {
                        if !profile_for_emitter(r2, &surf, pg, prof) {
                            return None;
                        }
                        correction(r2, tri, g, t, prof, psf, buf)
                    })
                    .collect()
            },
        )
        .collect();
    (0..emitters.len())
        .map(|k| per_point.iter().map(|v| v[k]).collect())
        .collect()
}

/// The predicted biases (px along the scan line) of the points `idx` for a sphere (base
/// frame) and model parameters, as [`corrections`] takes them; `None` per point where the
/// model fails.
pub(crate) fn deltas(
    rig: &Rig<'_>,
    scan: &ScanGeometry<'_>,
    idx: &[usize],
    sphere: (&Vector3<f64>, f64),
    sigma: f64,
    psf: f64,
) -> Vec<Option<f64>> {
    let (geo, cam_base) = (scan.geo, scan.cam_base);
    idx.par_iter()
        .map_init(
            || (PointProfile::default(), Vec::new()),
            |(prof, buf), &i| {
                let (g, f) = &geo[i];
                if g.saturated {
                    return None;
                }
                let c = (cam_base[*f] * nalgebra::Point3::from(*sphere.0)).coords;
                let surf = SphereSurface { c: &c, r: sphere.1 };
                if !point_profile(rig, &surf, g.line, &g.p_cam, sigma, psf, prof) {
                    return None;
                }
                extractor_response(prof, psf, rig.stripe, buf).map(|x| x.0)
            },
        )
        .collect()
}

/// The 3D corrections (base frame) of the points `idx` whose predicted biases are
/// `deltas` (px along the scan line; `None`: not modelled).
pub(crate) fn corrections_from_deltas(
    rig: &Rig<'_>,
    scan: &ScanGeometry<'_>,
    idx: &[usize],
    deltas: &[Option<f64>],
) -> Vec<Option<[f64; 3]>> {
    idx.iter()
        .zip(deltas)
        .map(|(&i, d)| {
            let (g, f) = &scan.geo[i];
            shifted(rig, scan.tri, g, &scan.cam_base[*f], (*d)?)
        })
        .collect()
}

/// The 3D correction (base frame) of point `g` of the frame `T_cam_base = t` from its
/// modelled profile `prof`: the extractor's response on it, the measured pixel moved back
/// by it and both triangulated.
fn correction(
    rig: &Rig<'_>,
    tri: &Triangulator,
    g: &PointGeo,
    t: &Iso3,
    prof: &PointProfile,
    psf: f64,
    buf: &mut Vec<f64>,
) -> Option<[f64; 3]> {
    let (delta, _, _) = extractor_response(prof, psf, rig.stripe, buf)?;
    shifted(rig, tri, g, t, delta)
}

/// The 3D correction (base frame) of point `g` of the frame `T_cam_base = t` whose
/// predicted bias along its scan line is `delta` px: the measured pixel moved back by it
/// and both triangulated.
fn shifted(
    rig: &Rig<'_>,
    tri: &Triangulator,
    g: &PointGeo,
    t: &Iso3,
    delta: f64,
) -> Option<[f64; 3]> {
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
