//! The sphere fit: algebraic (Kasa) or robust (least quantile of squares) start,
//! geometric Levenberg-Marquardt, trimming and the Gauss-Markov uncertainty (the
//! "Sphere" part of the [`super`] docs).

use faer::MatMut;
use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};

use crate::error::{Error, Result};
use crate::model::SphereFit;
use crate::numerics::lm::{levenberg_marquardt, LeastSquares, LmOptions};
use crate::numerics::rng::SplitMix64;

use super::trim::{bounding_box, check_points, sigma_floor, trim_loop};
use super::FitOptions;

/// sphere.json's key of the fit's one-sigma of the diameter (mm).
pub const FIT_DIAMETER_SIGMA_KEY: &str = "fit_diameter_sigma_mm";
/// sphere.json's key of the fit's one-sigma of the centre's coordinates (mm).
pub const FIT_CENTER_SIGMA_KEY: &str = "fit_center_sigma_mm";
/// What sphere.json says its one-sigmas are.
pub const FIT_SIGMA_NOTE: &str = "fit_diameter_sigma_mm and fit_center_sigma_mm are the \
    sphere fit's random part only (the points' scatter about the sphere); errors every point \
    shares (the calibration, the robot, the stripe's bias) are not in them. The measurement's \
    uncertainty (a GUM budget, expanded U at k = 2): stripecal measure";

/// A sphere fit with its uncertainty.
#[derive(Debug, Clone, PartialEq)]
pub struct SphereFitResult {
    pub center_mm: Vector3<f64>,
    pub diameter_mm: f64,
    /// RMS of the inliers' radial residuals, mm.
    pub rms_mm: f64,
    /// One-sigma of the diameter, mm.
    pub diameter_sigma_mm: f64,
    /// One-sigma of the centre coordinates, mm.
    pub center_sigma_mm: Vector3<f64>,
    /// Inliers used.
    pub points: usize,
    /// Points trimmed as outliers.
    pub outliers: usize,
    /// Robust sigma of the residuals at the last trimming round, mm.
    pub robust_sigma_mm: f64,
    /// Largest |residual| of an inlier, mm.
    pub max_residual_mm: f64,
    /// The last round's trimming threshold (`trim_sigma` robust sigmas), mm: points with
    /// a larger |residual| are outliers; 0 when the fit does not trim.
    pub trim_threshold_mm: f64,
    /// Inlier mask (same order as the input points).
    pub inlier: Vec<bool>,
}

impl SphereFitResult {
    /// The spec's sphere-fit record; the fit's one-sigmas go to the extra keys
    /// `fit_diameter_sigma_mm` and `fit_center_sigma_mm` (spec/DATASET.md has no keys for
    /// them), named for what they are: the fit's random part only, with `sigma_note`
    /// saying so and where the measurement's uncertainty comes from. (Files written
    /// before this named them `diameter_sigma_mm` and `center_sigma_mm`, which read as
    /// the measurement's; readers accept both: [`SphereFit::fit_diameter_sigma_mm`].)
    pub fn to_sphere_fit(&self) -> SphereFit {
        let mut extra = serde_json::Map::new();
        extra.insert(
            FIT_DIAMETER_SIGMA_KEY.into(),
            serde_json::json!(self.diameter_sigma_mm),
        );
        extra.insert(
            FIT_CENTER_SIGMA_KEY.into(),
            serde_json::json!([
                self.center_sigma_mm.x,
                self.center_sigma_mm.y,
                self.center_sigma_mm.z
            ]),
        );
        extra.insert("sigma_note".into(), serde_json::json!(FIT_SIGMA_NOTE));
        extra.insert(
            "robust_sigma_mm".into(),
            serde_json::json!(self.robust_sigma_mm),
        );
        extra.insert(
            "max_residual_mm".into(),
            serde_json::json!(self.max_residual_mm),
        );
        SphereFit {
            diameter_mm: self.diameter_mm,
            center_mm: self.center_mm,
            rms_mm: self.rms_mm,
            points: self.points,
            outliers: self.outliers,
            extra,
        }
    }
}

/// Kåsa's algebraic sphere through the masked points: `(centre, radius)`.
fn sphere_algebraic(points: &[[f64; 3]], mask: &[bool]) -> Result<(Vector3<f64>, f64)> {
    let sel = || points.iter().zip(mask).filter(|(_, &m)| m).map(|(p, _)| p);
    let k = sel().count() as f64;
    let mean = sel().fold(Vector3::zeros(), |a, p| a + Vector3::from(*p)) / k;
    let scale = (sel()
        .map(|p| (Vector3::from(*p) - mean).norm_squared())
        .sum::<f64>()
        / k)
        .sqrt();
    if scale.is_nan() || scale <= 0.0 {
        return Err(Error::Degenerate("sphere fit: all points coincide".into()));
    }
    // |q|^2 + D qx + E qy + F qz + G = 0 with q = (p - mean) / scale.
    let mut ata = Matrix4::zeros();
    let mut atb = Vector4::zeros();
    for p in sel() {
        let q = (Vector3::from(*p) - mean) / scale;
        let a = Vector4::new(q.x, q.y, q.z, 1.0);
        ata += a * a.transpose();
        atb -= a * q.norm_squared();
    }
    let x = ata
        .cholesky()
        .map(|c| c.solve(&atb))
        .ok_or_else(|| Error::Degenerate("sphere fit: points are coplanar or collinear".into()))?;
    let c = Vector3::new(-0.5 * x[0], -0.5 * x[1], -0.5 * x[2]);
    let r2 = c.norm_squared() - x[3];
    if !(r2 > 0.0 && r2.is_finite()) {
        return Err(Error::Degenerate(
            "sphere fit: the points do not determine a sphere (algebraic fit failed)".into(),
        ));
    }
    Ok((mean + c * scale, r2.sqrt() * scale))
}

/// The geometric sphere fit as a least-squares problem: parameters `(cx, cy, cz, R)`,
/// residuals `r_i = |p_i - c| - R` over the selected points, Jacobian rows
/// `[-(p_i - c)^T / |p_i - c|, -1]` (`[0, 0, 0, -1]` for a point at the centre).
struct SphereDistances {
    points: Vec<Vector3<f64>>,
}

impl SphereDistances {
    /// The problem over the masked points.
    fn new(points: &[[f64; 3]], mask: &[bool]) -> SphereDistances {
        SphereDistances {
            points: points
                .iter()
                .zip(mask)
                .filter(|(_, &m)| m)
                .map(|(p, _)| Vector3::from(*p))
                .collect(),
        }
    }
}

impl LeastSquares for SphereDistances {
    fn num_params(&self) -> usize {
        4
    }
    fn num_residuals(&self) -> usize {
        self.points.len()
    }
    fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        let c = Vector3::new(p[0], p[1], p[2]);
        for (ri, q) in r.iter_mut().zip(&self.points) {
            *ri = (q - c).norm() - p[3];
        }
        Ok(())
    }
    fn residuals_and_jacobian(
        &self,
        p: &[f64],
        r: &mut [f64],
        mut jac: MatMut<'_, f64>,
    ) -> Result<()> {
        let c = Vector3::new(p[0], p[1], p[2]);
        for (i, (ri, q)) in r.iter_mut().zip(&self.points).enumerate() {
            let dv = q - c;
            let dist = dv.norm();
            *ri = dist - p[3];
            if dist > 0.0 {
                for k in 0..3 {
                    jac[(i, k)] = -dv[k] / dist;
                }
            }
            jac[(i, 3)] = -1.0;
        }
        Ok(())
    }
}

/// Geometric fit over the masked points from `(c, r)` by the crate's Levenberg-Marquardt
/// ([`levenberg_marquardt`], at most `max_iter` iterations); returns `(c, r, J^T J)`.
fn sphere_lm(
    points: &[[f64; 3]],
    mask: &[bool],
    c0: Vector3<f64>,
    r0: f64,
    max_iter: usize,
) -> Result<(Vector3<f64>, f64, Matrix4<f64>)> {
    let problem = SphereDistances::new(points, mask);
    let opts = LmOptions {
        max_iterations: max_iter,
        ..Default::default()
    };
    let sol = levenberg_marquardt(&problem, &[c0.x, c0.y, c0.z, r0], &opts)?;
    let (c, r) = (
        Vector3::new(sol.params[0], sol.params[1], sol.params[2]),
        sol.params[3],
    );
    if !(r.is_finite() && r > 0.0 && c.iter().all(|x| x.is_finite())) {
        return Err(Error::Degenerate(format!(
            "sphere fit: no sphere (radius {r})"
        )));
    }
    Ok((c, r.abs(), Matrix4::from_fn(|i, j| sol.jtj[(i, j)])))
}

/// A sphere's centre and radius, mm.
type SphereParams = (Vector3<f64>, f64);

/// The sphere through 4 points, or `None` when they are (nearly) coplanar.
fn sphere_through(p: [Vector3<f64>; 4]) -> Option<(Vector3<f64>, f64)> {
    // 2 (p_i - p_0) . c = |p_i|^2 - |p_0|^2, i = 1..3 (relative to p_0 for conditioning).
    let a = Matrix3::from_rows(&[
        (p[1] - p[0]).transpose() * 2.0,
        (p[2] - p[0]).transpose() * 2.0,
        (p[3] - p[0]).transpose() * 2.0,
    ]);
    let b = Vector3::new(
        (p[1] - p[0]).norm_squared(),
        (p[2] - p[0]).norm_squared(),
        (p[3] - p[0]).norm_squared(),
    );
    let c = a.lu().solve(&b)?;
    let r = c.norm();
    (r.is_finite() && r > 0.0).then_some((p[0] + c, r))
}

/// Number of random 4-point samples of the robust start.
const ROBUST_SAMPLES: usize = 1500;
/// Points scored per candidate (an evenly strided subset of larger clouds).
const ROBUST_SCORE_POINTS: usize = 3000;

/// Robust start (least quantile of squares): spheres through random 4-point samples
/// (a fixed seed: the result is deterministic), with diameters in the accepted range,
/// scored by the `robust_quantile` quantile of |residual| over (a subset of) the
/// points; the best one gives the initial inliers `|r| <= trim_sigma * s0` with
/// `s0 = quantile / 0.2533` (0.2533 = the 60 % point of the normal distribution: the
/// 20 % quantile of |r| of a normal sample), which the trimming then refines.
fn sphere_robust_start(
    points: &[[f64; 3]],
    opts: &FitOptions,
) -> Result<(Vec<bool>, SphereParams)> {
    let n = points.len();
    let range = match opts.diameter_range_mm {
        Some(r) => r,
        None => {
            let (lo, hi) = bounding_box(points);
            [0.0, (hi - lo).norm()]
        }
    };
    let stride = n.div_ceil(ROBUST_SCORE_POINTS).max(1);
    let subset: Vec<Vector3<f64>> = points
        .iter()
        .step_by(stride)
        .map(|p| Vector3::from(*p))
        .collect();
    let k =
        ((opts.robust_quantile * subset.len() as f64).ceil() as usize).clamp(1, subset.len()) - 1;
    let mut rng = SplitMix64(0x5EED);
    let mut buf = Vec::with_capacity(subset.len());
    let mut best: Option<(f64, Vector3<f64>, f64)> = None;
    for _ in 0..ROBUST_SAMPLES {
        let idx = [rng.below(n), rng.below(n), rng.below(n), rng.below(n)];
        let Some((c, r)) = sphere_through(idx.map(|i| Vector3::from(points[i]))) else {
            continue;
        };
        if !(2.0 * r >= range[0] && 2.0 * r <= range[1]) {
            continue;
        }
        buf.clear();
        buf.extend(subset.iter().map(|p| ((p - c).norm() - r).abs()));
        let (_, q, _) = buf.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
        let q = *q;
        if best.is_none_or(|b| q < b.0) {
            best = Some((q, c, r));
        }
    }
    let Some((q, c, r)) = best else {
        return Err(Error::Degenerate(format!(
            "sphere fit: no sphere with a diameter in [{:.3}, {:.3}] mm through the points",
            range[0], range[1]
        )));
    };
    let s0 = (q / 0.2533).max(sigma_floor(points));
    let thr = if opts.trim_sigma > 0.0 {
        opts.trim_sigma * s0
    } else {
        3.0 * s0
    };
    let mask: Vec<bool> = points
        .iter()
        .map(|p| ((Vector3::from(*p) - c).norm() - r).abs() <= thr)
        .collect();
    let inl = mask.iter().filter(|&&m| m).count();
    if inl < 5 {
        return Err(Error::Degenerate(format!(
            "sphere fit: the best candidate sphere has only {inl} points near it"
        )));
    }
    Ok((mask, (c, r)))
}

/// Fits a sphere to points (mm) with trimming and one-sigma uncertainties (module docs).
/// Needs at least 5 points not on one plane.
pub fn fit_sphere(points: &[[f64; 3]], opts: &FitOptions) -> Result<SphereFitResult> {
    opts.validate()?;
    check_points(points, 5, "sphere")?;
    let n = points.len();
    let mut last_jtj = Matrix4::zeros();
    let fit = |mask: &[bool], prev: Option<&(Vector3<f64>, f64)>| {
        let (c0, r0) = match prev {
            Some(&(c, r)) => (c, r),
            None => sphere_algebraic(points, mask)?,
        };
        let (c, r, jtj) = sphere_lm(points, mask, c0, r0, opts.max_iterations)?;
        last_jtj = jtj;
        let res: Vec<f64> = points
            .iter()
            .map(|p| (Vector3::from(*p) - c).norm() - r)
            .collect();
        Ok(((c, r), res))
    };
    let init = if opts.robust_start {
        Some(sphere_robust_start(points, opts)?)
    } else {
        None
    };
    let ((c, r), res, mask, robust) =
        trim_loop(n, 5, opts, "sphere", init, sigma_floor(points), fit)?;
    let k = mask.iter().filter(|&&m| m).count();
    let ss: f64 = res
        .iter()
        .zip(&mask)
        .filter(|(_, &m)| m)
        .map(|(r, _)| r * r)
        .sum();
    let max_res = res
        .iter()
        .zip(&mask)
        .filter(|(_, &m)| m)
        .fold(0.0f64, |a, (r, _)| a.max(r.abs()));
    let dof = k.saturating_sub(4).max(1) as f64;
    let s2 = ss / dof;
    let cov = last_jtj.try_inverse().ok_or_else(|| {
        Error::Degenerate("sphere fit: the points do not determine the sphere".into())
    })? * s2;
    Ok(SphereFitResult {
        center_mm: c,
        diameter_mm: 2.0 * r,
        rms_mm: (ss / k as f64).sqrt(),
        diameter_sigma_mm: 2.0 * cov[(3, 3)].max(0.0).sqrt(),
        center_sigma_mm: Vector3::new(
            cov[(0, 0)].max(0.0).sqrt(),
            cov[(1, 1)].max(0.0).sqrt(),
            cov[(2, 2)].max(0.0).sqrt(),
        ),
        points: k,
        outliers: n - k,
        robust_sigma_mm: robust,
        max_residual_mm: max_res,
        trim_threshold_mm: opts.trim_sigma * robust,
        inlier: mask,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::numerics::rng::SplitMix64 as Rng;

    const D_TRUE: f64 = 44.8614;

    /// Points on the cap of a sphere within `cap_deg` of its top (+z), as a stripe
    /// scan sees a ball on a table, with radial Gaussian noise `sigma`.
    fn cap_points(
        rng: &mut Rng,
        c: Vector3<f64>,
        n: usize,
        cap_deg: f64,
        sigma: f64,
    ) -> Vec<[f64; 3]> {
        let r = 0.5 * D_TRUE;
        let zmin = cap_deg.to_radians().cos();
        (0..n)
            .map(|_| {
                let z = zmin + (1.0 - zmin) * rng.uniform();
                let phi = std::f64::consts::TAU * rng.uniform();
                let s = (1.0 - z * z).sqrt();
                let u = Vector3::new(s * phi.cos(), s * phi.sin(), z);
                let p = c + u * (r + sigma * rng.normal());
                [p.x, p.y, p.z]
            })
            .collect()
    }

    #[test]
    fn sphere_exact_points_recovered() {
        let mut rng = Rng(1);
        let c = Vector3::new(480.0, 90.0, -12.0);
        let pts = cap_points(&mut rng, c, 200, 70.0, 0.0);
        let f = fit_sphere(&pts, &FitOptions::default()).unwrap();
        assert!((f.diameter_mm - D_TRUE).abs() < 1e-9, "{f:?}");
        assert!((f.center_mm - c).norm() < 1e-9);
        assert_eq!(f.outliers, 0);
    }

    /// The one-sigma of diameter and centre is honest: over many noise seeds about 68 %
    /// of the errors fall within one sigma, and the mean squared z-score is about 1.
    #[test]
    fn sphere_sigma_coverage() {
        let seeds = 300;
        let sigma = 0.02;
        let c = Vector3::new(480.0, 90.0, -12.0);
        let (mut in_d, mut in_z, mut z2_d, mut z2_x) = (0, 0, 0.0, 0.0);
        for s in 0..seeds {
            let mut rng = Rng(1000 + s);
            let pts = cap_points(&mut rng, c, 1500, 60.0, sigma);
            let f = fit_sphere(&pts, &FitOptions::default()).unwrap();
            let zd = (f.diameter_mm - D_TRUE) / f.diameter_sigma_mm;
            let zz = (f.center_mm.z - c.z) / f.center_sigma_mm.z;
            let zx = (f.center_mm.x - c.x) / f.center_sigma_mm.x;
            in_d += (zd.abs() <= 1.0) as usize;
            in_z += (zz.abs() <= 1.0) as usize;
            z2_d += zd * zd;
            z2_x += zx * zx;
            assert!((f.rms_mm - sigma).abs() < 0.1 * sigma, "rms {}", f.rms_mm);
        }
        let n = seeds as f64;
        let (cov_d, cov_z) = (in_d as f64 / n, in_z as f64 / n);
        let (m_d, m_x) = (z2_d / n, z2_x / n);
        eprintln!("coverage of 1 sigma: diameter {cov_d:.3}, centre z {cov_z:.3}; mean z^2: diameter {m_d:.3}, centre x {m_x:.3}");
        // Binomial sd of a 0.683 fraction over 300 seeds: 0.027; allow 3.5 sd.
        for cov in [cov_d, cov_z] {
            assert!((cov - 0.683).abs() < 0.095, "coverage {cov}");
        }
        // Mean of 300 chi^2(1) values: sd sqrt(2/300) = 0.082; allow 3.5 sd.
        for m in [m_d, m_x] {
            assert!((m - 1.0).abs() < 0.29, "mean z^2 {m}");
        }
    }

    /// Gross outliers (5 %, 0.3 to 3 mm off the surface, both sides) are trimmed and the
    /// fit stays within 4 sigma of the truth.
    #[test]
    fn sphere_outliers_trimmed() {
        let sigma = 0.02;
        let c = Vector3::new(-30.0, 5.0, 100.0);
        for s in 0..20 {
            let mut rng = Rng(77 + s);
            let mut pts = cap_points(&mut rng, c, 1000, 60.0, sigma);
            let n_out = 50;
            for i in 0..n_out {
                let k = (i * 19) % pts.len();
                let p = Vector3::from(pts[k]);
                let dir = (p - c).normalize();
                let off =
                    (0.3 + 2.7 * rng.uniform()) * if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                let q = p + dir * off;
                pts[k] = [q.x, q.y, q.z];
            }
            let f = fit_sphere(&pts, &FitOptions::default()).unwrap();
            assert!(
                f.outliers >= n_out && f.outliers <= n_out + 20,
                "outliers {}",
                f.outliers
            );
            assert!(
                (f.diameter_mm - D_TRUE).abs() < 4.0 * f.diameter_sigma_mm,
                "diameter {} sigma {}",
                f.diameter_mm,
                f.diameter_sigma_mm
            );
            assert!((f.rms_mm - sigma).abs() < 0.15 * sigma);
            // Without trimming the outliers pull the fit off.
            let g = fit_sphere(
                &pts,
                &FitOptions {
                    trim_sigma: 0.0,
                    ..Default::default()
                },
            )
            .unwrap();
            assert_eq!(g.outliers, 0);
            assert!(g.rms_mm > 5.0 * sigma);
        }
    }

    /// A ball on a table: 35 % of the points on the ball's upper cap, 65 % on the
    /// table (z = c.z - r). The robust start finds the ball; the table is trimmed.
    #[test]
    fn sphere_found_among_table_points() {
        let sigma = 0.02;
        let c = Vector3::new(400.0, 50.0, 22.0);
        let r = 0.5 * D_TRUE;
        let mut rng = Rng(9);
        let mut pts = cap_points(&mut rng, c, 700, 75.0, sigma);
        for _ in 0..1300 {
            let x = c.x + 80.0 * rng.uniform() - 40.0;
            let y = c.y + 60.0 * rng.uniform() - 30.0;
            if (x - c.x).hypot(y - c.y) < r + 1.0 {
                continue;
            }
            pts.push([x, y, c.z - r + sigma * rng.normal()]);
        }
        let f = fit_sphere(&pts, &FitOptions::default()).unwrap();
        eprintln!(
            "ball among table points: {f:?}",
            f = (f.diameter_mm, f.points, f.outliers)
        );
        assert!((f.diameter_mm - D_TRUE).abs() < 4.0 * f.diameter_sigma_mm);
        assert!((f.center_mm - c).norm() < 0.02);
        assert!(f.points >= 690 && f.points <= 700 + 5, "{}", f.points);
    }
}
