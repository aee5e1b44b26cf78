//! The plane fit: total least squares with trimming and the uncertainty of the normal
//! and offset (the "Plane" part of the [`super`] docs).

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::model::geometry::Plane;
use crate::numerics::tls;

use super::trim::{check_points, sigma_floor, trim_loop};
use super::FitOptions;

/// A plane fit with its uncertainty.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneFit {
    /// `n . p = d`, `|n| = 1`, `d >= 0` (mm).
    pub plane: Plane,
    /// Centroid of the inliers, mm.
    pub centroid_mm: Vector3<f64>,
    /// RMS of the inliers' residuals, mm.
    pub rms_mm: f64,
    /// Largest minus smallest residual of the inliers, mm.
    pub flatness_mm: f64,
    /// One-sigma of the normal's components.
    pub normal_sigma: Vector3<f64>,
    /// One-sigma of `d`, mm.
    pub d_sigma_mm: f64,
    /// One-sigma of the offset at the centroid (along the normal), mm.
    pub offset_sigma_mm: f64,
    /// One-sigma of the normal's direction (largest of the two tilt angles), degrees.
    pub tilt_sigma_deg: f64,
    pub points: usize,
    pub outliers: usize,
    pub inlier: Vec<bool>,
}

/// Smallest ratio of the points' second in-plane spread (standard deviation) to their
/// spread off the plane for a plane fit.
const PLANE_MIN_SPREAD_RATIO: f64 = 5.0;

struct PlaneParams {
    n: Vector3<f64>,
    c: Vector3<f64>,
    e1: Vector3<f64>,
    e2: Vector3<f64>,
}

fn plane_tls(points: &[[f64; 3]], mask: &[bool]) -> Result<PlaneParams> {
    let sel: Vec<Vector3<f64>> = points
        .iter()
        .zip(mask)
        .filter(|(_, &m)| m)
        .map(|(p, _)| Vector3::from(*p))
        .collect();
    let k = sel.len() as f64;
    let pa = tls::principal_axes(&sel)?;
    let c = pa.centroid;
    let (l0, l1, l2) = (
        pa.singular[2].powi(2),
        pa.singular[1].powi(2),
        pa.singular[0].powi(2),
    );
    // The points must spread in two directions well beyond their spread off the plane:
    // a single stripe on a plane is a line, and a line does not fix a plane.
    if !(l1 > PLANE_MIN_SPREAD_RATIO * PLANE_MIN_SPREAD_RATIO * l0.max(0.0) && l1 > 1e-12 * l2) {
        return Err(Error::Degenerate(format!(
            "plane fit: the points lie along a line (spread across it {:.3e} mm, off the \
             plane {:.3e} mm): a plane needs points spread in two directions",
            (l1 / k).sqrt(),
            (l0.max(0.0) / k).sqrt()
        )));
    }
    let n = pa.axes.column(2).into_owned();
    let e1 = pa.axes.column(0).into_owned();
    let e2 = n.cross(&e1);
    Ok(PlaneParams { n, c, e1, e2 })
}

/// Fits a plane to points (mm) by total least squares with trimming and one-sigma
/// uncertainties (module docs). Needs at least 4 points not on one line.
pub fn fit_plane(points: &[[f64; 3]], opts: &FitOptions) -> Result<PlaneFit> {
    opts.validate()?;
    check_points(points, 4, "plane")?;
    let n_all = points.len();
    let fit = |mask: &[bool], _prev: Option<&Vector3<f64>>| {
        let pp = plane_tls(points, mask)?;
        let res: Vec<f64> = points
            .iter()
            .map(|p| pp.n.dot(&(Vector3::from(*p) - pp.c)))
            .collect();
        Ok((pp.n, res))
    };
    let (_, _, mask, _) = trim_loop(n_all, 4, opts, "plane", None, sigma_floor(points), fit)?;
    let pp = plane_tls(points, &mask)?;
    let k = mask.iter().filter(|&&m| m).count();
    let (mut ss, mut lo, mut hi, mut s1, mut s2) =
        (0.0, f64::INFINITY, f64::NEG_INFINITY, 0.0, 0.0);
    for (p, _) in points.iter().zip(&mask).filter(|(_, &m)| m) {
        let q = Vector3::from(*p) - pp.c;
        let r = pp.n.dot(&q);
        ss += r * r;
        lo = lo.min(r);
        hi = hi.max(r);
        s1 += pp.e1.dot(&q).powi(2);
        s2 += pp.e2.dot(&q).powi(2);
    }
    let sigma2 = ss / (k.saturating_sub(3).max(1)) as f64;
    let (va, vb, vdelta) = (sigma2 / s1, sigma2 / s2, sigma2 / k as f64);
    let cov_n = pp.e1 * pp.e1.transpose() * va + pp.e2 * pp.e2.transpose() * vb;
    let plane = Plane::new(pp.n, pp.n.dot(&pp.c))?;
    let vd = vdelta + va * pp.e1.dot(&pp.c).powi(2) + vb * pp.e2.dot(&pp.c).powi(2);
    Ok(PlaneFit {
        plane,
        centroid_mm: pp.c,
        rms_mm: (ss / k as f64).sqrt(),
        flatness_mm: hi - lo,
        normal_sigma: Vector3::new(
            cov_n[(0, 0)].sqrt(),
            cov_n[(1, 1)].sqrt(),
            cov_n[(2, 2)].sqrt(),
        ),
        d_sigma_mm: vd.sqrt(),
        offset_sigma_mm: vdelta.sqrt(),
        tilt_sigma_deg: va.max(vb).sqrt().to_degrees(),
        points: k,
        outliers: n_all - k,
        inlier: mask,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::numerics::rng::SplitMix64 as Rng;

    #[test]
    fn plane_sigma_coverage_and_flatness() {
        let sigma = 0.01;
        let n_true = Vector3::new(0.1, -0.2, 1.0).normalize();
        let d_true = 42.0;
        let e1 = n_true.cross(&Vector3::x()).normalize();
        let e2 = n_true.cross(&e1);
        let seeds = 300;
        let (mut in_d, mut z2_d, mut z2_n) = (0, 0.0, 0.0);
        for s in 0..seeds {
            let mut rng = Rng(5000 + s);
            let mut pts: Vec<[f64; 3]> = (0..800)
                .map(|_| {
                    let p = n_true * (d_true + sigma * rng.normal())
                        + e1 * (40.0 * rng.uniform() - 20.0)
                        + e2 * (10.0 * rng.uniform() - 5.0);
                    [p.x, p.y, p.z]
                })
                .collect();
            pts[3] = [pts[3][0] + 1.0, pts[3][1], pts[3][2]];
            let f = fit_plane(&pts, &FitOptions::default()).unwrap();
            assert!(f.outliers >= 1 && !f.inlier[3]);
            let zd = (f.plane.d - d_true) / f.d_sigma_mm;
            let zn = (f.plane.normal.x - n_true.x) / f.normal_sigma.x;
            in_d += (zd.abs() <= 1.0) as usize;
            z2_d += zd * zd;
            z2_n += zn * zn;
            assert!((f.rms_mm - sigma).abs() < 0.15 * sigma);
            assert!(f.flatness_mm > 4.0 * sigma && f.flatness_mm < 9.0 * sigma);
        }
        let n = seeds as f64;
        eprintln!(
            "plane: coverage d {:.3}, mean z^2 d {:.3}, normal x {:.3}",
            in_d as f64 / n,
            z2_d / n,
            z2_n / n
        );
        assert!((in_d as f64 / n - 0.683).abs() < 0.095);
        assert!((z2_d / n - 1.0).abs() < 0.29);
        assert!((z2_n / n - 1.0).abs() < 0.29);
    }
}
