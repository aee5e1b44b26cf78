//! The laser sheet's thickness (and the image blur) estimated from the stripe widths of a
//! scan of a known surface (the fitted sphere), for the bias model of
//! [`super::stripe_bias`].
//!
//! ## The model
//!
//! Across the scan line the stripe's profile is the sheet's Gaussian (sigma `s`, mm)
//! mapped to the image through the surface: at a point where the image coordinate moves
//! by `g = |da/dt|` px per mm of sheet offset `t` (from the sphere and the calibration,
//! [`super::stripe_bias`]), the profile's variance is about
//! `s^2 g^2 + b^2 (1 + m^2) + (1 + m^2) / 12`: the PSF's Gaussian `b` (px) and the pixel
//! box (`1 / 12`), both widened along the scan line by the stripe's slope `m`. The
//! extractor's width `W` (FWHM, px) gives `(W / 2.3548)^2`.
//!
//! - Start: linear least squares of `(W / 2.3548)^2 - (1 + m^2) / 12` on
//!   `[g^2, 1 + m^2]` for `(s^2, b^2)`.
//! - Refinement: Gauss-Newton on `(s, b)` of `W_i - W_model_i(s, b)`, where `W_model` is
//!   the width the extractor's own code measures on the modelled profile
//!   ([`super::stripe_bias`]: the real profile is not Gaussian, and a half-maximum width
//!   read on pixels is not `2.3548` sigmas), with numerical derivatives; residuals
//!   beyond 4 robust sigmas are dropped after the first pass. Each iteration tries the
//!   step with the previous iteration's derivatives first: where that step is below the
//!   tolerance (`1e-5 s`, `1e-4` px) it is the last one, and the two derivative runs of
//!   the model at the solution are saved (the covariance then comes from the previous
//!   iterate's derivatives, one step of the converging fit away). A warm start (the
//!   sphere correction's second pass, from its first pass's sigmas) starts there instead
//!   of the linear start and drops the gross outliers at its first iteration: it is
//!   already near the solution, where the cold start is after one step.
//! - Standard uncertainties: `sigma_W^2 (J^T J)^-1` at the solution (`sigma_W^2` the
//!   residual variance), over a subsample of at most [`WIDTH_POINTS`] points (the
//!   subsample makes them conservative).
//!
//! ## Credibility
//!
//! The two parameters separate only when `g` varies over the points: a sphere scan sees
//! the surface from the top (`g` small) to the flanks (`g` large). The estimate is refused
//! ([`Error::Degenerate`]) when fewer than 30 points give widths, when `s^2` comes out
//! <= 0, or when the standard uncertainty of `s` exceeds 30 % of it; a negative `b^2`
//! falls back to `b = 0` (no PSF), `s` alone. Pass a known thickness
//! ([`super::StripeBiasOptions::sheet_sigma_mm`]) then.

use nalgebra::{Matrix2, Vector2, Vector3};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::reconstruct::ScanPoints;

use crate::stripe_model::{
    extractor_response, point_profile, point_section, PointProfile, Rig, SphereSurface,
};

/// Points used for the width fit, at most.
pub const WIDTH_POINTS: usize = 2500;
/// Gauss-Newton iterations of the refinement.
const GN_ITERATIONS: usize = 8;

/// The sheet's and the PSF's sigmas used by the bias model.
#[derive(Debug, Clone, PartialEq)]
pub struct SheetSigmaEstimate {
    /// The sheet's Gaussian sigma, mm.
    pub sheet_sigma_mm: f64,
    /// Its standard uncertainty, mm (0 when given).
    pub sheet_sigma_sd_mm: f64,
    /// The PSF's Gaussian sigma, px.
    pub psf_sigma_px: f64,
    /// Its standard uncertainty, px (0 when given).
    pub psf_sigma_sd_px: f64,
    /// The linear (Gaussian-width) start of the sheet sigma, mm (the given one when given).
    pub sheet_sigma_linear_mm: f64,
    /// Points of the width fit (0 when both were given).
    pub points: usize,
    /// RMS of the width residuals, px.
    pub width_rms_px: f64,
    /// Range of `g = |da/dt|` over the points, px / mm.
    pub g_range: [f64; 2],
}

/// Per point of the width fit: the geometry's profile (at unit sheet sigma the samples
/// are rescaled on each call) and the observed width.
struct WidthPoint {
    c: Vector3<f64>,
    p: Vector3<f64>,
    line: f64,
    w: f64,
    g: f64,
    m: f64,
}

/// The model widths of `pts` for `(s, b)`; `None` where the extractor rejects.
fn model_widths(rig: &Rig<'_>, r: f64, pts: &[WidthPoint], s: f64, b: f64) -> Vec<Option<f64>> {
    pts.par_iter()
        .map_init(
            || (PointProfile::default(), Vec::new()),
            |(prof, buf), q| {
                if !point_profile(rig, &SphereSurface { c: &q.c, r }, q.line, &q.p, s, b, prof) {
                    return None;
                }
                extractor_response(prof, b, rig.stripe, buf).map(|x| x.1)
            },
        )
        .collect()
}

/// Estimates (or takes) the sheet and PSF sigmas from the widths of `points` on the
/// sphere `(centre, radius)` (base frame); `geo[i]`: the point in the camera frame, its
/// scan line and frame. See the module docs.
#[allow(clippy::too_many_arguments)]
pub(super) fn estimate_sheet_sigma(
    rig: &Rig<'_>,
    points: &ScanPoints,
    geo: &[(Vector3<f64>, f64, usize)],
    cam_base: &[Iso3],
    sphere: (&Vector3<f64>, f64),
    sheet_sigma_mm: Option<f64>,
    psf_sigma_px: Option<f64>,
    max_points: usize,
    start: Option<(f64, f64)>,
) -> Result<SheetSigmaEstimate> {
    check_given(sheet_sigma_mm, psf_sigma_px)?;
    if let (Some(s), Some(b)) = (sheet_sigma_mm, psf_sigma_px) {
        return Ok(SheetSigmaEstimate {
            sheet_sigma_mm: s,
            sheet_sigma_sd_mm: 0.0,
            psf_sigma_px: b,
            psf_sigma_sd_px: 0.0,
            sheet_sigma_linear_mm: s,
            points: 0,
            width_rms_px: 0.0,
            g_range: [0.0, 0.0],
        });
    }
    let pts = width_points(rig, points, geo, cam_base, sphere, max_points)?;
    if pts.len() < 30 {
        return Err(refusal(format!(
            "{} points with widths (30 needed)",
            pts.len()
        )));
    }
    let g_range = pts.iter().fold([f64::INFINITY, 0.0f64], |a, q| {
        [a[0].min(q.g), a[1].max(q.g)]
    });
    let (x, psf_free) = linear_start(&pts, sheet_sigma_mm, psf_sigma_px);
    let s_lin = sheet_sigma_mm.unwrap_or_else(|| x[0].max(0.0).sqrt());
    if s_lin.is_nan() || s_lin <= 0.0 {
        return Err(refusal("the widths do not grow with g (s^2 <= 0)".into()));
    }
    let b = psf_sigma_px.unwrap_or_else(|| x[1].max(0.0).sqrt());
    let sheet_free = sheet_sigma_mm.is_none();
    // A warm start (a fit of the same sphere's widths before): from there, and the gross
    // outliers dropped at once (module docs, "Refinement").
    let (x0, drop_at) = match start {
        Some((s0, b0)) if s0 > 0.0 && b0 >= 0.0 => (
            (
                if sheet_free { s0 } else { s_lin },
                if psf_free { b0 } else { b },
            ),
            0,
        ),
        _ => ((s_lin, b), 1),
    };
    let WidthFit {
        s,
        b,
        cov,
        rms,
        used,
    } = gauss_newton(rig, sphere.1, &pts, x0, (sheet_free, psf_free), drop_at)?;
    let sd_s = if sheet_free {
        cov[(0, 0)].max(0.0).sqrt()
    } else {
        0.0
    };
    let sd_b = if psf_free {
        cov[(1, 1)].max(0.0).sqrt()
    } else {
        0.0
    };
    if sheet_free && sd_s > 0.3 * s {
        return Err(refusal(format!(
            "s = {s:.4} +- {sd_s:.4} mm is not resolved (g from {:.2} to {:.2} px/mm)",
            g_range[0], g_range[1]
        )));
    }
    Ok(SheetSigmaEstimate {
        sheet_sigma_mm: s,
        sheet_sigma_sd_mm: sd_s,
        psf_sigma_px: b,
        psf_sigma_sd_px: sd_b,
        sheet_sigma_linear_mm: s_lin,
        points: used,
        width_rms_px: rms,
        g_range,
    })
}

/// Errors unless each given sigma is finite and >= 0 (the sheet's > 0).
fn check_given(sheet_sigma_mm: Option<f64>, psf_sigma_px: Option<f64>) -> Result<()> {
    for (k, v) in [
        ("sheet_sigma_mm", sheet_sigma_mm),
        ("psf_sigma_px", psf_sigma_px),
    ] {
        if let Some(v) = v {
            if !(v.is_finite() && v >= 0.0) || (k == "sheet_sigma_mm" && v <= 0.0) {
                return Err(Error::InvalidInput(format!(
                    "{k} = {v} must be finite and > 0"
                )));
            }
        }
    }
    Ok(())
}

/// The width fit's points: every `n / WIDTH_POINTS`-th point of `points` with a width
/// and not saturated, with its geometry's profile on the sphere `(centre, radius)`.
fn width_points(
    rig: &Rig<'_>,
    points: &ScanPoints,
    geo: &[(Vector3<f64>, f64, usize)],
    cam_base: &[Iso3],
    sphere: (&Vector3<f64>, f64),
    max_points: usize,
) -> Result<Vec<WidthPoint>> {
    let n = points.len();
    if points.width_px.len() != n {
        return Err(Error::InvalidInput(
            "ScanPoints without widths: the sheet thickness cannot be estimated".into(),
        ));
    }
    let step = n.div_ceil(max_points.max(1)).max(1);
    let r = sphere.1;
    let mut pts = Vec::new();
    for i in (0..n).step_by(step) {
        let w = points.width_px[i] as f64;
        let (p, line, f) = geo[i];
        // A saturated profile is clipped: its width is not the model's.
        if points.saturated(i) || !(w.is_finite() && w > 0.0) {
            continue;
        }
        let c = (cam_base[f] * nalgebra::Point3::from(*sphere.0)).coords;
        // The geometry at t = 0 does not depend on the sheet sigma.
        let Some(s0) = point_section(rig, &SphereSurface { c: &c, r }, line, &p, 0.1, 0.0) else {
            continue;
        };
        pts.push(WidthPoint {
            c,
            p,
            line,
            w,
            g: s0.da_dt.abs(),
            m: s0.slope,
        });
    }
    Ok(pts)
}

/// The refusal to estimate the sheet thickness, saying why (`m`).
fn refusal(m: String) -> Error {
    Error::Degenerate(format!(
        "sheet thickness: {m}; give StripeBiasOptions::sheet_sigma_mm"
    ))
}

/// The linear (Gaussian-width) start `(s^2, b^2)` of the sigmas not given, and whether
/// the PSF sigma stays free (not given, and resolved: `b^2 >= 0`).
fn linear_start(
    pts: &[WidthPoint],
    sheet_sigma_mm: Option<f64>,
    psf_sigma_px: Option<f64>,
) -> (Vector2<f64>, bool) {
    let mut ata = Matrix2::zeros();
    let mut atb = Vector2::zeros();
    for q in pts {
        let k = 1.0 + q.m * q.m;
        let y = (q.w / 2.3548).powi(2) - k / 12.0;
        let (a0, a1) = (
            if sheet_sigma_mm.is_some() {
                0.0
            } else {
                q.g * q.g
            },
            if psf_sigma_px.is_some() { 0.0 } else { k },
        );
        let y = y
            - sheet_sigma_mm.map_or(0.0, |s| s * s * q.g * q.g)
            - psf_sigma_px.map_or(0.0, |b| b * b * k);
        let a = Vector2::new(a0, a1);
        ata += a * a.transpose();
        atb += a * y;
    }
    let mut x = solve(&ata, &atb);
    let mut psf_free = psf_sigma_px.is_none();
    if psf_free && x[1] < 0.0 {
        // No blur resolved: s alone.
        psf_free = false;
        let mut a2 = ata;
        a2[(0, 1)] = 0.0;
        a2[(1, 0)] = 0.0;
        a2[(1, 1)] = 0.0;
        let mut b2 = atb;
        b2[1] = 0.0;
        x = solve(&a2, &b2);
        x[1] = 0.0;
    }
    (x, psf_free)
}

/// `ata^-1 atb` with the unknowns whose diagonal is 0 (held) set to 0; zeros when
/// singular.
fn solve(ata: &Matrix2<f64>, atb: &Vector2<f64>) -> Vector2<f64> {
    let mut m = *ata;
    let mut v = *atb;
    for k in 0..2 {
        if m[(k, k)] == 0.0 {
            m[(k, k)] = 1.0;
            v[k] = 0.0;
        }
    }
    m.try_inverse()
        .map(|i| i * v)
        .unwrap_or_else(Vector2::zeros)
}

/// The Gauss-Newton fit's result: the sigmas, their covariance, the RMS of the width
/// residuals (px) and the points used.
struct WidthFit {
    s: f64,
    b: f64,
    cov: Matrix2<f64>,
    rms: f64,
    used: usize,
}

/// Gauss-Newton on the extractor's widths of `pts` on the sphere of radius `r` from
/// `(s, b)`, the free ones `(sheet_free, psf_free)` estimated (gross outliers dropped
/// once, at iteration `drop_at`: the second from the linear start, the first from a warm
/// one).
fn gauss_newton(
    rig: &Rig<'_>,
    r: f64,
    pts: &[WidthPoint],
    (mut s, mut b): (f64, f64),
    (sheet_free, psf_free): (bool, bool),
    drop_at: usize,
) -> Result<WidthFit> {
    let mut keep: Vec<bool> = vec![true; pts.len()];
    let mut cov = Matrix2::zeros();
    let mut rms = 0.0;
    let mut used = 0;
    // The last iteration's per-point Jacobian rows (`None`: not modelled).
    let mut last_j: Option<Vec<Option<Vector2<f64>>>> = None;
    for it in 0..GN_ITERATIONS {
        let w0 = model_widths(rig, r, pts, s, b);
        let res: Vec<Option<f64>> = pts
            .iter()
            .zip(&w0)
            .map(|(q, m)| m.map(|m| q.w - m))
            .collect();
        if it == drop_at {
            // Drop gross outliers once (4 robust sigmas).
            let mut a: Vec<f64> = res.iter().flatten().map(|x| x.abs()).collect();
            if !a.is_empty() {
                a.sort_by(f64::total_cmp);
                let rs = 1.4826 * a[a.len() / 2];
                for (k, r) in keep.iter_mut().zip(&res) {
                    *k = r.is_some_and(|r| r.abs() <= 4.0 * rs.max(1e-6));
                }
            }
        }
        // With the last iteration's Jacobian first (module docs, "Refinement"): where
        // that step is below the tolerance it is the last, and the derivative runs at
        // this iterate are not needed.
        if let Some(j) = &last_j {
            let step = gn_step(&res, j, &keep, (sheet_free, psf_free));
            if let Some(st) = step.filter(|st| converged(st, s)) {
                (cov, rms, used) = (st.cov, st.rms, st.used);
                s = (s + st.dx[0]).max(0.5 * s);
                b = (b + st.dx[1]).max(0.0);
                break;
            }
        }
        let hs = 0.01 * s;
        let hb = 0.01 * b.max(0.1);
        let ws = if sheet_free {
            model_widths(rig, r, pts, s + hs, b)
        } else {
            vec![None; pts.len()]
        };
        let wb = if psf_free {
            model_widths(rig, r, pts, s, b + hb)
        } else {
            vec![None; pts.len()]
        };
        let j: Vec<Option<Vector2<f64>>> = (0..pts.len())
            .map(|i| {
                let m = w0[i]?;
                let js = match (sheet_free, ws[i]) {
                    (true, Some(a)) => (a - m) / hs,
                    (true, None) => return None,
                    _ => 0.0,
                };
                let jb = match (psf_free, wb[i]) {
                    (true, Some(a)) => (a - m) / hb,
                    (true, None) => return None,
                    _ => 0.0,
                };
                Some(Vector2::new(js, jb))
            })
            .collect();
        let Some(st) = gn_step(&res, &j, &keep, (sheet_free, psf_free)) else {
            return Err(refusal(format!(
                "{} points with modelled widths (30 needed)",
                (0..pts.len())
                    .filter(|&i| keep[i] && res[i].is_some() && j[i].is_some())
                    .count()
            )));
        };
        (cov, rms, used) = (st.cov, st.rms, st.used);
        s = (s + st.dx[0]).max(0.5 * s);
        b = (b + st.dx[1]).max(0.0);
        if converged(&st, s) {
            break;
        }
        last_j = Some(j);
    }
    Ok(WidthFit {
        s,
        b,
        cov,
        rms,
        used,
    })
}

/// One Gauss-Newton step of the width fit: the step, the covariance, the RMS of the
/// residuals and the points used.
struct GnStep {
    dx: Vector2<f64>,
    cov: Matrix2<f64>,
    rms: f64,
    used: usize,
}

/// The Gauss-Newton step for the residuals `res` and Jacobian rows `j` over the `keep`
/// points both have; `None` with fewer than 30 such points.
fn gn_step(
    res: &[Option<f64>],
    j: &[Option<Vector2<f64>>],
    keep: &[bool],
    (sheet_free, psf_free): (bool, bool),
) -> Option<GnStep> {
    let mut jtj = Matrix2::zeros();
    let mut jtr = Vector2::zeros();
    let (mut ss, mut k) = (0.0, 0usize);
    for i in 0..res.len() {
        let (Some(ri), Some(ji), true) = (res[i], j[i], keep[i]) else {
            continue;
        };
        jtj += ji * ji.transpose();
        jtr += ji * ri;
        ss += ri * ri;
        k += 1;
    }
    if k < 30 {
        return None;
    }
    let dx = solve(&jtj, &jtr);
    let nfree = sheet_free as usize + psf_free as usize;
    let var = ss / (k - nfree).max(1) as f64;
    let mut jj = jtj;
    for q in 0..2 {
        if jj[(q, q)] == 0.0 {
            jj[(q, q)] = 1.0;
        }
    }
    Some(GnStep {
        dx,
        cov: jj.try_inverse().unwrap_or_else(Matrix2::zeros) * var,
        rms: (ss / k as f64).sqrt(),
        used: k,
    })
}

/// Is the step `st` below the fit's tolerance (`s` the sheet sigma after it)?
fn converged(st: &GnStep, s: f64) -> bool {
    st.dx[0].abs() < 1e-5 * s && st.dx[1].abs() < 1e-4
}
