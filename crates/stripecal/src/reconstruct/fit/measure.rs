//! Measurements with full budgets: a sphere (diameter, centre, probing form), a plane
//! (flatness, tilt, offset) and the distance of two spheres, each quantity a
//! [`LinearForm`] over the sources of [`super::budget`], reported as a GUM [`Budget`].
//!
//! A measurement is made from a fit of a scan's points (their pixels and frames tell
//! the calibration and robot parts) and the coordinates the fit used (the
//! reconstructed points, or the points after a bias correction). `systematic` adds the
//! documented systematic standard uncertainties a model leaves (the curved-surface
//! stripe-bias correction's parts) as the coefficients of unit sources
//! ([`SphereSystematic`]), each shared as its cause is: the model's relative error
//! ([`MODEL_SOURCE`]) and an assumed emitter's position ([`assumed_emitter_source`])
//! by every sphere, so their effect on a ball bar's length (two spheres corrected alike)
//! largely cancels, as it does in reality; what a scan estimates from its own stripe
//! (emitter, sheet and PSF sigmas) by nothing else, so two spheres' parts add.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix4, Vector3};

use crate::error::{Error, Result};
use crate::reconstruct::ScanPoints;

use super::budget::{
    new_source_id, range_random_sigma, Budget, FitRow, LinearForm, ScanFrames, Sensitivity,
};
use super::{PlaneFit, SphereFitResult};

/// A sphere measured with its budgets.
#[derive(Debug, Clone)]
pub struct SphereMeasurement {
    pub diameter: Budget,
    pub center: [Budget; 3],
    /// Probing form: the range of the radial residuals (largest minus smallest).
    pub form: Budget,
    /// The forms of the centre coordinates (combine them for distances).
    pub center_forms: [LinearForm; 3],
    /// The form of the diameter.
    pub diameter_form: LinearForm,
    /// The form of the probing form (its two extreme points).
    pub probing_form: LinearForm,
}

impl SphereMeasurement {
    /// The measurement with the calibration's numbers moved by `shift` and their
    /// covariance `cov` (both over the measurement's numbers): each value moves by its
    /// calibration gradient times `shift` (first order), each calibration part is read
    /// from `cov` ([`crate::pipeline::emitter_carry`]).
    pub fn recalibrated(&mut self, shift: &DVector<f64>, cov: &DMatrix<f64>) {
        let moved = |f: &LinearForm, b: &Budget| {
            let dv = if f.calibration.len() == shift.len() {
                f.calibration.dot(shift)
            } else {
                0.0
            };
            f.budget(b.value + dv, cov)
        };
        self.diameter = moved(&self.diameter_form, &self.diameter);
        for k in 0..3 {
            self.center[k] = moved(&self.center_forms[k], &self.center[k]);
        }
        self.form = moved(&self.probing_form, &self.form);
    }
}

/// Systematic standard uncertainties a model leaves on a sphere fit, mm, SIGNED: per
/// unit source, its coefficients; a sign says in which direction the quantity moves when
/// the source errs one way (for a correction whose error is a fraction of it: the sign
/// of the correction). Sources shared by several spheres are the same key in each.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SphereSystematic {
    pub parts: Vec<SystematicSource>,
}

/// One unit source's coefficients on a sphere's centre and diameter, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SystematicSource {
    pub source: super::budget::Source,
    pub center_mm: [f64; 3],
    pub diameter_mm: f64,
}

/// The unit source of the stripe-bias model's error, shared by every sphere (owner 0:
/// [`super::budget::new_source_id`] never gives it).
pub const MODEL_SOURCE: super::budget::Source = (0, 1, 0);

/// The unit source of an assumed emitter's position along in-plane axis `k`, shared by
/// every sphere (owner 0).
pub fn assumed_emitter_source(k: u32) -> super::budget::Source {
    (0, 2, k)
}

/// The budgets of a sphere fit of `points` (the fit's inlier mask selects them; `coords`
/// are the coordinates it used, one per point).
pub fn measure_sphere(
    frames: &mut ScanFrames<'_>,
    points: &ScanPoints,
    coords: &[[f64; 3]],
    fit: &SphereFitResult,
    systematic: &SphereSystematic,
) -> Result<SphereMeasurement> {
    check_lengths(points, coords, &fit.inlier)?;
    let c = fit.center_mm;
    let r = 0.5 * fit.diameter_mm;
    let idx: Vec<usize> = (0..points.len()).filter(|&i| fit.inlier[i]).collect();
    if idx.len() < 5 {
        return Err(Error::Degenerate(format!(
            "sphere budget: {} inliers (at least 5)",
            idx.len()
        )));
    }
    let mut normals = Vec::with_capacity(idx.len());
    let mut res = Vec::with_capacity(idx.len());
    let mut n = Matrix4::zeros();
    for &i in &idx {
        let d = Vector3::from(coords[i]) - c;
        let dist = d.norm();
        let u = if dist > 0.0 { d / dist } else { Vector3::z() };
        let j = nalgebra::Vector4::new(-u.x, -u.y, -u.z, -1.0);
        n += j * j.transpose();
        normals.push((u, [-u.x, -u.y, -u.z, -1.0]));
        res.push(dist - r);
    }
    let n_d = DMatrix::from_fn(4, 4, |a, b| n[(a, b)]);
    let rows = idx.iter().zip(&normals).map(|(&i, (u, j))| FitRow {
        u: points.u_px[i],
        v: points.v_px[i],
        frame: points.frame[i],
        a: *u,
        j,
    });
    let mut sens = Sensitivity::new(frames, &n_d, rows)?;
    let id = new_source_id();
    let s2 = res.iter().map(|x| x * x).sum::<f64>() / (idx.len() - 4) as f64;
    // The trimmed fit's bread: N less the points at the trimming threshold (a skipped
    // fit moves less with its inliers than N says: [`trimmed_bread`]).
    let cut = fit.trim_threshold_mm;
    let near_cut = coords.iter().map(|p| {
        let d = Vector3::from(*p) - c;
        let dist = d.norm();
        let u = if dist > 0.0 { d / dist } else { Vector3::z() };
        (nalgebra::Vector4::new(-u.x, -u.y, -u.z, -1.0), dist - r)
    });
    let bread = trimmed_bread(&n, cut, near_cut);
    let random = sandwich(&bread, normals.iter().map(|x| &x.1[..]).zip(&res));
    add_random(&mut sens.params, &random, id);
    for part in &systematic.parts {
        let sys = [
            part.center_mm[0],
            part.center_mm[1],
            part.center_mm[2],
            0.5 * part.diameter_mm,
        ];
        for (p, s) in sens.params.iter_mut().zip(sys) {
            if s != 0.0 {
                *p.systematic.entry(part.source).or_insert(0.0) += s;
            }
        }
    }
    // Probing form: the range of the radial residuals.
    let form = range_form(
        frames,
        &sens,
        points,
        &Residuals {
            idx: &idx,
            res: &res,
            s2,
        },
        id,
        |k| (normals[k].0, &normals[k].1[..]),
    )?;
    let cov = frames.model().covariance().clone();
    let mut diameter_form = LinearForm::default();
    diameter_form.add_scaled(&sens.params[3], 2.0);
    let center_forms = [
        sens.params[0].clone(),
        sens.params[1].clone(),
        sens.params[2].clone(),
    ];
    Ok(SphereMeasurement {
        diameter: diameter_form.budget(fit.diameter_mm, &cov),
        center: std::array::from_fn(|k| center_forms[k].budget(c[k], &cov)),
        form: form.0.budget(form.1, &cov),
        center_forms,
        diameter_form,
        probing_form: form.0,
    })
}

/// The distance of two measured spheres' centres with its budget (their calibration and
/// robot parts correlated as their forms say).
pub fn sphere_distance(
    a: &SphereMeasurement,
    b: &SphereMeasurement,
    cov: &DMatrix<f64>,
) -> (Budget, LinearForm) {
    let ca = Vector3::from_fn(|k, _| a.center[k].value);
    let cb = Vector3::from_fn(|k, _| b.center[k].value);
    let d = ca - cb;
    let l = d.norm();
    let g = if l > 0.0 { d / l } else { Vector3::zeros() };
    let mut f = LinearForm::default();
    for k in 0..3 {
        f.add_scaled(&a.center_forms[k], g[k]);
        f.add_scaled(&b.center_forms[k], -g[k]);
    }
    (f.budget(l, cov), f)
}

/// A plane measured with its budgets.
#[derive(Debug, Clone)]
pub struct PlaneMeasurement {
    /// Flatness: the range of the residuals.
    pub flatness: Budget,
    /// The offset along the normal at the centroid (value: the plane's `d`), mm.
    pub offset: Budget,
    /// The normal's tilts about the two in-plane axes, degrees (value 0).
    pub tilt_deg: [Budget; 2],
}

/// The budgets of a plane fit of `points` (inlier mask of `fit`; `coords` as fitted).
pub fn measure_plane(
    frames: &mut ScanFrames<'_>,
    points: &ScanPoints,
    coords: &[[f64; 3]],
    fit: &PlaneFit,
) -> Result<PlaneMeasurement> {
    check_lengths(points, coords, &fit.inlier)?;
    let nrm = fit.plane.normal;
    let c = fit.centroid_mm;
    let helper = if nrm.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = nrm.cross(&helper).normalize();
    let e2 = nrm.cross(&e1);
    let idx: Vec<usize> = (0..points.len()).filter(|&i| fit.inlier[i]).collect();
    if idx.len() < 4 {
        return Err(Error::Degenerate(format!(
            "plane budget: {} inliers (at least 4)",
            idx.len()
        )));
    }
    let mut jrows = Vec::with_capacity(idx.len());
    let mut res = Vec::with_capacity(idx.len());
    let mut n = Matrix3::zeros();
    for &i in &idx {
        let q = Vector3::from(coords[i]) - c;
        let j = Vector3::new(e1.dot(&q), e2.dot(&q), -1.0);
        n += j * j.transpose();
        jrows.push([j.x, j.y, j.z]);
        res.push(nrm.dot(&q));
    }
    let n_d = DMatrix::from_fn(3, 3, |a, b| n[(a, b)]);
    let rows = idx.iter().zip(&jrows).map(|(&i, j)| FitRow {
        u: points.u_px[i],
        v: points.v_px[i],
        frame: points.frame[i],
        a: nrm,
        j,
    });
    let mut sens = Sensitivity::new(frames, &n_d, rows)?;
    let id = new_source_id();
    let s2 = res.iter().map(|x| x * x).sum::<f64>() / (idx.len() - 3) as f64;
    let random = sandwich(&sens.ninv, jrows.iter().map(|x| &x[..]).zip(&res));
    add_random(&mut sens.params, &random, id);
    let form = range_form(
        frames,
        &sens,
        points,
        &Residuals {
            idx: &idx,
            res: &res,
            s2,
        },
        id,
        |k| (nrm, &jrows[k][..]),
    )?;
    let cov = frames.model().covariance().clone();
    let deg = |f: &LinearForm| {
        let mut out = LinearForm::default();
        out.add_scaled(f, 1f64.to_degrees());
        out
    };
    Ok(PlaneMeasurement {
        flatness: form.0.budget(form.1, &cov),
        offset: sens.params[2].budget(fit.plane.d, &cov),
        tilt_deg: [
            deg(&sens.params[0]).budget(0.0, &cov),
            deg(&sens.params[1]).budget(0.0, &cov),
        ],
    })
}

/// The residuals of a fit: `idx` its inliers (indices into the points), `res` their
/// residuals and `s2` the residual variance.
struct Residuals<'a> {
    idx: &'a [usize],
    res: &'a [f64],
    s2: f64,
}

/// The form and value of a range of residuals (largest minus smallest): first order in
/// its two extreme points, its random part the extremes' scatter ([`range_random_sigma`]).
/// `row(k)`: inlier `k`'s `(a, J)`.
fn range_form<'r>(
    frames: &mut ScanFrames<'_>,
    sens: &Sensitivity,
    points: &ScanPoints,
    resid: &Residuals<'_>,
    id: u64,
    row: impl Fn(usize) -> (Vector3<f64>, &'r [f64]),
) -> Result<(LinearForm, f64)> {
    let Residuals { idx, res, s2 } = *resid;
    let (imax, imin) = extremes(res);
    let mut form = LinearForm::default();
    for (k, sign) in [(imax, 1.0), (imin, -1.0)] {
        let i = idx[k];
        let (a, j) = row(k);
        let r = FitRow {
            u: points.u_px[i],
            v: points.v_px[i],
            frame: points.frame[i],
            a,
            j,
        };
        form.add_scaled(&sens.residual_form(frames, &r)?, sign);
    }
    form.random.clear();
    form.random
        .insert((id, 2, 0), range_random_sigma(s2.sqrt(), idx.len()));
    Ok((form, res[imax] - res[imin]))
}

/// The inverse bread of a trimmed (skipped) least-squares fit. Its estimating equation
/// `sum_i J_i psi(r_i) = 0` has `psi(r) = r 1{|r| <= c}`, whose expected derivative is
/// `P(|r| <= c) - c (f(c) + f(-c))` (`f` the residuals' density): the points that cross
/// the threshold as the fit moves make it move less, so the bread is
/// `A = N - c sum_i J_i J_i^T (f_i(c) + f_i(-c))`, estimated with a box of half width
/// `h = 0.1 c` around `|r| = c`: `A = N - (c / 2h) sum_{||r_i| - c| < h} J_i J_i^T`.
/// Without it the sandwich treats the trimmed fit as if its point set were fixed, and
/// understates the scatter of a fit whose residuals have heavy tails (a stripe
/// extractor's, where a few percent of the centres lie beyond four sigmas). `n`: the
/// inliers' `J^T J`; `rows`: `(J_i, r_i)` of every point the fit was given; `cut`: the
/// trimming threshold (0: untrimmed, `N^-1`). Where the correction would leave `A` with
/// less than half of `N`'s smallest eigenvalue (too few points near the cut to say), the
/// bread is `N / 2` (twice the variance: the conservative end).
fn trimmed_bread(
    n: &Matrix4<f64>,
    cut: f64,
    rows: impl Iterator<Item = (nalgebra::Vector4<f64>, f64)>,
) -> DMatrix<f64> {
    let to_d = |m: &Matrix4<f64>| DMatrix::from_fn(4, 4, |a, b| m[(a, b)]);
    let inv = |m: &Matrix4<f64>| m.try_inverse().map(|x| to_d(&x));
    let Some(ninv) = inv(n) else {
        return to_d(n);
    };
    if cut.is_nan() || cut <= 0.0 {
        return ninv;
    }
    let h = 0.1 * cut;
    let mut k = Matrix4::zeros();
    for (j, r) in rows {
        if (r.abs() - cut).abs() < h {
            k += j * j.transpose();
        }
    }
    let a = n - k * (cut / (2.0 * h));
    let min_n = n.symmetric_eigen().eigenvalues.min();
    let min_a = a.symmetric_eigen().eigenvalues.min();
    match inv(&a) {
        Some(ainv) if min_a >= 0.5 * min_n => ainv,
        _ => ninv * 2.0,
    }
}

/// Random sources of a fit's parameters: `L` with `L L^T = cov` (eigen, may be singular).
/// The fit's random covariance from its rows `(J_i, r_i)`, robust to points of unequal
/// noise (heteroscedasticity-consistent, "HC1"): `m / (m - p) N^-1 (sum_i J_i^T r_i^2
/// J_i) N^-1`. A scan's points are not equally noisy: weak and oblique profiles (a
/// sphere's rim, a plate seen at a slant) scatter more, and they are the points that
/// decide a diameter or a tilt, so the textbook `s^2 N^-1` (one variance for all)
/// understates the fit's scatter. On the twin's 25.4 mm spheres `s^2 N^-1` gave 0.13 um
/// for a diameter whose scatter over 20 seeds was 0.18 um (this: 1.2 times larger);
/// equal to `s^2 N^-1` when the residuals are equally spread.
fn sandwich<'a>(
    ninv: &DMatrix<f64>,
    rows: impl Iterator<Item = (&'a [f64], &'a f64)>,
) -> DMatrix<f64> {
    let p = ninv.nrows();
    let mut meat = DMatrix::<f64>::zeros(p, p);
    let mut m = 0usize;
    for (j, r) in rows {
        let r2 = r * r;
        for a in 0..p {
            let ja = j[a] * r2;
            for b in 0..p {
                meat[(a, b)] += ja * j[b];
            }
        }
        m += 1;
    }
    let scale = m as f64 / (m.saturating_sub(p).max(1)) as f64;
    ninv * meat * ninv * scale
}

fn add_random(params: &mut [LinearForm], cov: &DMatrix<f64>, id: u64) {
    let e = cov.clone().symmetric_eigen();
    for (r, p) in params.iter_mut().enumerate() {
        for k in 0..cov.ncols() {
            let v = e.eigenvectors[(r, k)] * e.eigenvalues[k].max(0.0).sqrt();
            if v != 0.0 {
                p.random.insert((id, 0, k as u32), v);
            }
        }
    }
}

/// Indices of the largest and smallest value.
fn extremes(x: &[f64]) -> (usize, usize) {
    let mut hi = 0;
    let mut lo = 0;
    for (i, v) in x.iter().enumerate() {
        if *v > x[hi] {
            hi = i;
        }
        if *v < x[lo] {
            lo = i;
        }
    }
    (hi, lo)
}

fn check_lengths(points: &ScanPoints, coords: &[[f64; 3]], inlier: &[bool]) -> Result<()> {
    if coords.len() != points.len() || inlier.len() != points.len() {
        return Err(Error::InvalidInput(format!(
            "measurement: {} points, {} coordinates, {} inlier flags (one each)",
            points.len(),
            coords.len(),
            inlier.len()
        )));
    }
    Ok(())
}
