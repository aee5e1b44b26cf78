//! The laser emitter's position within the laser plane, estimated from the stripe's
//! brightness along a sphere scan, for the bias model of [`super::stripe_bias`].
//!
//! No calibration file holds the emitter, but the stripe's peak height on a Lambertian
//! sphere follows `cos(incidence) / r` from it (and the geometry's foreshortening, which
//! the bias model computes): the incidence changes by tens of degrees over the sphere, so
//! the brightness pattern locates the emitter. With `E = E0 + x e1 + y e2` (`E0 = n d`,
//! `e1, e2` a basis of the plane), Gauss-Newton on `(x, y)` minimises
//! `sum (ln I_i - ln P_i(E) - k)^2` over a subsample of at most [`EMITTER_POINTS`] points
//! (`I_i` the extractor's peak height, `P_i` the modelled profile's peak read by the same
//! code, `k` the unknown power x reflectance x gain, eliminated as the mean), with
//! numerical derivatives (1 mm steps; the emitter moves only the shading, so each point's
//! sections are solved once for the whole fit; each iteration tries the step with the
//! previous iteration's derivatives first, and where that step is below the tolerance,
//! 0.05 mm, it is the last and the derivative runs at the solution are saved). Saturated
//! points are left out. Standard
//! uncertainties from `s^2 (J^T J)^-1` (`s^2` the residual variance).
//!
//! Neglected: vignetting and a non-uniform reflectance or sheet power along the line (they
//! change the brightness but not the incidence pattern; their slow variation over the
//! sphere's image shifts the estimate), speckle (noise). The estimate is refused (the
//! default `n d` is kept) when fewer than 50 points are modelled or it moves more than
//! 200 mm from `n d`.

use nalgebra::{Matrix2, Vector2, Vector3};
use rayon::prelude::*;

use crate::model::geometry::Iso3;
use crate::reconstruct::ScanPoints;

use crate::stripe_model::{
    extractor_response, point_geometry, profile_for_emitter, PointGeometry, PointProfile, Rig,
    SphereSurface,
};

/// Points used for the emitter fit, at most.
pub const EMITTER_POINTS: usize = 1500;

/// The emitter estimate: the position (camera frame, mm) and the standard uncertainties
/// of its two in-plane coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmitterEstimate {
    pub emitter_cam_mm: Vector3<f64>,
    pub sd_mm: [f64; 2],
    /// RMS of the log-brightness residuals.
    pub rms_log: f64,
    pub points: usize,
}

/// Per point of the emitter fit, its profile's emitter-independent part (`None` where it
/// cannot be modelled): the fit's emitters then need no section solved again.
fn geometries(
    rig: &Rig<'_>,
    pts: &[(Vector3<f64>, Vector3<f64>, f64)],
    r: f64,
    sigma: f64,
    psf: f64,
) -> Vec<Option<PointGeometry>> {
    pts.par_iter()
        .map_init(Vec::new, |scratch, (c, p, line)| {
            let mut geo = PointGeometry::default();
            point_geometry(
                rig,
                &SphereSurface { c, r },
                *line,
                p,
                sigma,
                psf,
                scratch,
                &mut geo,
            )
            .then_some(geo)
        })
        .collect()
}

/// Log peak heights of the model for `rig`'s emitter, from the points' geometries.
fn log_peaks(
    rig: &Rig<'_>,
    pts: &[(Vector3<f64>, Vector3<f64>, f64)],
    geo: &[Option<PointGeometry>],
    r: f64,
    psf: f64,
) -> Vec<Option<f64>> {
    pts.par_iter()
        .zip(geo)
        .map_init(
            || (PointProfile::default(), Vec::new()),
            |(prof, buf), ((c, _, _), geo)| {
                let geo = geo.as_ref()?;
                if !profile_for_emitter(rig, &SphereSurface { c, r }, geo, prof) {
                    return None;
                }
                let pk = extractor_response(prof, psf, rig.stripe, buf)?.2;
                (pk > 0.0).then(|| pk.ln())
            },
        )
        .collect()
}

/// Estimates the emitter (module docs); `None` when refused.
pub(super) fn estimate_emitter(
    rig: &Rig<'_>,
    points: &ScanPoints,
    geo: &[(Vector3<f64>, f64, usize)],
    cam_base: &[Iso3],
    sphere: (&Vector3<f64>, f64),
    sigma: f64,
    psf: f64,
) -> Option<EmitterEstimate> {
    let n = points.len();
    if points.intensity.len() != n {
        return None;
    }
    let step = n.div_ceil(EMITTER_POINTS).max(1);
    let mut pts = Vec::new();
    let mut obs = Vec::new();
    for i in (0..n).step_by(step) {
        let li = (points.intensity[i] as f64).ln();
        if points.saturated(i) || !li.is_finite() {
            continue;
        }
        let (p, line, f) = geo[i];
        let c = (cam_base[f] * nalgebra::Point3::from(*sphere.0)).coords;
        pts.push((c, p, line));
        obs.push(li);
    }
    let e0 = rig.emitter;
    let (e1, e2) = crate::stripe_model::plane_basis(&rig.n);
    let geo = geometries(rig, &pts, sphere.1, sigma, psf);
    let at = |x: &Vector2<f64>| {
        let mut r2 = rig.clone();
        r2.emitter = e0 + e1 * x[0] + e2 * x[1];
        log_peaks(&r2, &pts, &geo, sphere.1, psf)
    };
    let mut x = Vector2::zeros();
    let h = 1.0;
    let mut cov = Matrix2::zeros();
    let mut rms = 0.0;
    let mut used = 0;
    // The last iteration's derivative columns per point (`None`: not modelled).
    let mut last_j: Option<Vec<Option<(f64, f64)>>> = None;
    for _ in 0..10 {
        let f0 = at(&x);
        // With the last iteration's derivatives first (module docs): where that step is
        // below the tolerance it is the last, and the derivative runs are saved.
        if let Some(j) = &last_j {
            let rows: Vec<(f64, f64, f64)> = (0..pts.len())
                .filter_map(|k| {
                    let (a, (ja, jb)) = (f0[k]?, j[k]?);
                    Some((obs[k] - a, ja, jb))
                })
                .collect();
            if let Some(st) = gn_step(&rows).filter(|st| st.dx.norm() < 0.05) {
                (cov, rms, used) = (st.cov, st.rms, rows.len());
                x += st.dx;
                break;
            }
        }
        let fa = at(&(x + Vector2::new(h, 0.0)));
        let fb = at(&(x + Vector2::new(0.0, h)));
        let j: Vec<Option<(f64, f64)>> = (0..pts.len())
            .map(|k| Some(((fa[k]? - f0[k]?) / h, (fb[k]? - f0[k]?) / h)))
            .collect();
        // Residuals with the mean removed, over the points all three model.
        let rows: Vec<(f64, f64, f64)> = (0..pts.len())
            .filter_map(|k| {
                let (a, (ja, jb)) = (f0[k]?, j[k]?);
                Some((obs[k] - a, ja, jb))
            })
            .collect();
        let st = gn_step(&rows)?;
        (cov, rms, used) = (st.cov, st.rms, rows.len());
        x += st.dx;
        if x.norm() > 200.0 {
            return None;
        }
        if st.dx.norm() < 0.05 {
            break;
        }
        last_j = Some(j);
    }
    Some(EmitterEstimate {
        emitter_cam_mm: e0 + e1 * x[0] + e2 * x[1],
        sd_mm: [cov[(0, 0)].max(0.0).sqrt(), cov[(1, 1)].max(0.0).sqrt()],
        rms_log: rms,
        points: used,
    })
}

/// One Gauss-Newton step of the emitter fit.
struct Step {
    dx: Vector2<f64>,
    cov: Matrix2<f64>,
    rms: f64,
}

/// The step (clamped to 20 mm per axis) for the rows `(residual, d/dx, d/dy)`, the
/// mean (the unknown `k`) removed from each column; `None` with fewer than 50 rows or a
/// singular normal matrix.
fn gn_step(rows: &[(f64, f64, f64)]) -> Option<Step> {
    if rows.len() < 50 {
        return None;
    }
    let m = rows.len() as f64;
    let mr = rows.iter().map(|r| r.0).sum::<f64>() / m;
    let ma = rows.iter().map(|r| r.1).sum::<f64>() / m;
    let mb = rows.iter().map(|r| r.2).sum::<f64>() / m;
    let mut jtj = Matrix2::zeros();
    let mut jtr = Vector2::zeros();
    let mut ss = 0.0;
    for r in rows {
        let j = Vector2::new(r.1 - ma, r.2 - mb);
        let res = r.0 - mr;
        jtj += j * j.transpose();
        jtr += j * res;
        ss += res * res;
    }
    let inv = jtj.try_inverse()?;
    let var = ss / (m - 3.0).max(1.0);
    Some(Step {
        dx: (inv * jtr).map(|v| v.clamp(-20.0, 20.0)),
        cov: inv * var,
        rms: (ss / m).sqrt(),
    })
}
