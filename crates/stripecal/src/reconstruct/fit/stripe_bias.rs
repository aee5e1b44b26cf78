//! The curved-surface stripe bias of a sphere scan: a model of what the stripe extractor
//! measures on a sphere lit by a laser sheet of Gaussian thickness, and the sphere fit
//! corrected by it ([`correct_sphere_bias`]).
//!
//! ## Why the stripe centre is biased on a curved surface
//!
//! The sheet's irradiance falls off as `exp(-t^2 / (2 sigma^2))` with the distance `t` of
//! a point from the calibrated (centre) plane `n . p = d` (camera frame). On a flat surface
//! the surface point lit at offset `t` moves linearly along the scan line with `t` and its
//! brightness is the same on both sides: the profile is symmetric about the image of the
//! centre plane's intersection and any symmetric estimator finds it. On a sphere the point
//! at offset `t` moves non-linearly (the section circle shrinks as `t` grows towards the
//! far side), the incidence of the sheet and the distance to the emitter change, so the
//! profile is skewed: its windowed centroid is not the image of the `t = 0` point, and
//! triangulating it with the `t = 0` plane puts the point off the sphere (outwards on the
//! paper's rig: the diameter comes out ~+0.005 mm with the true calibration).
//!
//! ## The model of one stripe point
//!
//! For a stripe point on scan line `l` (the row `v = l` for [`StripeDirection::Cols`], the
//! column `u = l` for `Rows`) of a frame with camera pose `T_base_cam`, the sphere
//! `(c, R)` is taken to the camera frame. For sheet offsets `t_k = k 4 sigma / M`,
//! `k = -M..=M` (`M` = [`HALF_SAMPLES`]):
//!
//! - the section circle of the sphere with the plane `n . p = d + t`: centre `c - h n`,
//!   `h = n . c - d - t`, radius `rho = sqrt(R^2 - h^2)`, points
//!   `P(phi) = c - h n + rho (cos phi e1 + sin phi e2)` (`e1, e2` a fixed basis of the
//!   plane);
//! - the point of the circle imaged on scan line `l`: Newton's method on `phi` for
//!   `proj(P(phi))_line = l` through the calibrated camera (distortion included), started
//!   at the measured point for `t = 0` and continued outwards in `t`; its coordinate
//!   along the scan line `a_k`;
//! - its weight `w_k = exp(-t_k^2 / (2 sigma^2)) * cos(incidence) / r * |da/dt|`: the
//!   Lambertian radiance of the twin's (and a real) emitter at distance `r`, and the
//!   Jacobian of the change of variable from `t` to the image coordinate (`da/dt` from the
//!   implicit function theorem, analytic); zero where the point faces away from the camera
//!   or the emitter (the continuation stops there);
//! - pixel `x` of the scan line then receives
//!   `V(x) = sum_j omega_j sum_k w_k(l + x_j) K(x - a_k(l + x_j))` (trapezoid rule in
//!   `t`, spectrally accurate for this smooth Gaussian-weighted integrand), with `K` the
//!   unit pixel box convolved with the PSF's Gaussian (sigma `s_psf`), and the
//!   neighbouring scan lines `l + x_j` the same kernel mixes across the line (weights
//!   `omega_j`: 5-point Gauss-Hermite of variance `s_psf^2 + 1/12`, or a finer grid of
//!   the exact kernel where the stripe is steep). This across-line term is not small: a
//!   curved stripe (the ellipse of a sphere's section) is shifted by about
//!   `a'' (s_psf^2 + 1/12) / 2` whatever the sheet's thickness (on the paper's rig it is
//!   half of the whole effect);
//! - the extractor's own sub-pixel code runs on `V` (background flanks, half-maximum
//!   width, iterated window centroid of `+-window_fwhm` widths, or the Gaussian fit:
//!   [`StripeOptions`]), at the point's actual pixel phase. Its centre minus `a_0` is the
//!   predicted bias `delta` (px) along the scan line; the PSF is symmetric, so it would not
//!   move a full centroid of one line, but it does move the windowed one, which the
//!   extractor uses.
//!
//! Checked against a brute-force integration (rays cast through a fine grid of the image,
//! shaded, integrated over the pixel box and the PSF in both directions): agreement to
//! 1e-4 px on spheres and a flat surface (unit tests).
//!
//! The measured point is moved back to the pixel `a_meas - delta` on its scan line and
//! triangulated with the same plane: the 3D correction (base frame) is the difference.
//! The sphere is refitted to the corrected points (no trimming: the same points every
//! round) and the model re-evaluated with the new sphere until the sphere moves by less
//! than 1e-5 mm (two to four rounds).
//!
//! The sheet thickness `sigma` and the PSF's sigma are not in a calibration: they are
//! estimated from the stripe's widths ([`super::sheet_sigma`]) unless given.
//!
//! ## The emitter
//!
//! No calibration file holds the laser emitter's position. It enters through `cos`
//! (incidence) and `1 / r`, and it matters: on the paper's rig, moving it by +-30 mm
//! within the plane changes the diameter correction by up to ~0.004 mm (the
//! incidence near the emitter's terminator changes by ~15 deg, where the shading's
//! gradient across the sheet is steep). So it is estimated from the stripe's brightness
//! along the sphere ([`super::emitter`]; on the twin within 0.3-0.9 mm of the truth);
//! when that is refused or switched off the plane's point nearest the camera centre,
//! `n d` (the twin's default), is assumed. Points lit at more than `max_incidence_deg`
//! (default 75 deg) are not modelled: near the terminator the bias depends steeply on
//! the emitter and on the neglected terms.
//!
//! ## The systematic uncertainty reported
//!
//! Root sum of squares of, for the diameter and each centre coordinate:
//! - the emitter: estimated, half the change between `+-1` standard uncertainty of its
//!   two in-plane coordinates, in quadrature; assumed, the largest change for
//!   `+-emitter_range_mm` (default 30 mm) along the two in-plane axes as the half width
//!   of a uniform distribution (`/ sqrt 3`);
//! - the sheet sigma's and the PSF sigma's standard uncertainties (from their fit,
//!   [`super::sheet_sigma`]) propagated by recomputing the correction at
//!   `sigma +- u(sigma)` (half the difference);
//! - the model's residual error: what remains after the correction is taken to lie within
//!   `+-`[`NEGLECTED_FRACTION`] (50 %) of the correction, uniformly (a GUM type B
//!   evaluation: standard uncertainty `0.5 |correction| / sqrt 3`, 29 %): the twin (3
//!   seeds, sheet sigma 0.12 and 0.2 mm, balls of 44.86 and 25.4 mm, two rigs) leaves
//!   17-52 % of the correction, always an under-correction (+0.0006 to +0.0017 mm on the
//!   diameter) although the per-point biases agree with the twin's true stripe
//!   to ~0.0005 px in every incidence bin up to 70 deg. It comes with the image noise: a
//!   noise-free twin goes from +0.0031 to +0.0003 mm (the noise adds +0.0017 mm to the
//!   uncorrected diameter), but a read-noise Monte Carlo through the extractor on the
//!   modelled profiles does not reproduce it (the noise-free images also lose ~5 % of the
//!   scan lines, so the point sets differ). This part is an empirical bound, not derived.
//!
//! The sensitivity terms are computed on a subsample of at most [`SENSITIVITY_POINTS`]
//! points, as differences from the nominal model on the same subsample and points.
//!
//! ## Assumptions and what is neglected
//!
//! - The surface is the fitted sphere, Lambertian with uniform reflectance; the stripe
//!   image has a locally flat background (the extractor removes a linear one).
//! - The sheet's profile is Gaussian in the distance from the plane, its thickness the
//!   same everywhere (a real sheet's waist varies along and across; the estimate is a
//!   mean over the scan's points); the emitter is a point source.
//! - The PSF is an isotropic Gaussian, the pixel a uniform box; vignetting, speckle
//!   and noise (zero-mean on the centroid to first order; the windowed centroid's
//!   non-linearity makes noise bias it a little), sensor non-linearity. The pixel-locking
//!   of the centroid is modelled (the point's actual pixel phase), so it is corrected too.
//! - Points where the model fails (the scan line misses the section circle, the
//!   synthetic profile is rejected by the extractor's own tests, incidence beyond the
//!   limit) are left out of the corrected fit ([`SphereBiasCorrection::modelled`]).

use nalgebra::{Matrix2x3, Vector3};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::StripeDirection;
use crate::reconstruct::triangulate::Triangulator;
use crate::reconstruct::{stripe_direction_from_plane, ScanPoints};
use crate::vision::stripe::{profile_centre, StripeOptions};

use super::emitter::{estimate_emitter, EmitterEstimate};
use super::sheet_sigma::{estimate_sheet_sigma, SheetSigmaEstimate};
use super::{fit_sphere, FitOptions, SphereFitResult};

/// Sheet offsets sampled on each side of the plane, at least (`2 M + 1` samples over
/// `+-4 sigma`; more where they would lie more than half the pixel kernel's sigma apart
/// in the image).
pub const HALF_SAMPLES: usize = 10;
/// Points used for the sensitivity (systematic) terms, at most.
pub const SENSITIVITY_POINTS: usize = 4000;
/// The neglected terms (module docs): the half width of their uniform distribution, as
/// a fraction of the correction.
pub const NEGLECTED_FRACTION: f64 = 0.5;

/// The standard uncertainty of the neglected terms per unit correction (uniform over
/// `+-NEGLECTED_FRACTION`).
pub fn neglected_share() -> f64 {
    NEGLECTED_FRACTION / 3f64.sqrt()
}
/// Largest number of correct-and-refit rounds.
const MAX_ROUNDS: usize = 8;

/// Options of [`correct_sphere_bias`].
#[derive(Debug, Clone, PartialEq)]
pub struct StripeBiasOptions {
    /// The stripe extractor's options the points were extracted with (window, method,
    /// direction; `Auto` is resolved from the plane as the reconstruction does).
    pub stripe: StripeOptions,
    /// The sheet's Gaussian sigma, mm; `None`: estimated from the stripe widths.
    pub sheet_sigma_mm: Option<f64>,
    /// The PSF's Gaussian sigma, px; `None`: estimated with the sheet sigma.
    pub psf_sigma_px: Option<f64>,
    /// Emitter position in the camera frame, mm; `None`: `n d` (module docs).
    pub emitter_cam_mm: Option<[f64; 3]>,
    /// With no `emitter_cam_mm`: estimate the emitter from the stripe's brightness
    /// ([`super::emitter`]; `false`: assume `n d`).
    pub estimate_emitter: bool,
    /// The emitter's assumed position range within the plane, +- mm (systematic term when
    /// the emitter is assumed, not estimated).
    pub emitter_range_mm: f64,
    /// Points lit at a larger incidence (from the assumed emitter, degrees) are not
    /// modelled and left out of the corrected fit: near the emitter's terminator the
    /// shading, and so the bias, depends steeply on where the emitter is.
    pub max_incidence_deg: f64,
    /// The sphere fits (the first one of the given points, and the refits).
    pub fit: FitOptions,
}

impl Default for StripeBiasOptions {
    fn default() -> Self {
        StripeBiasOptions {
            stripe: StripeOptions::default(),
            sheet_sigma_mm: None,
            psf_sigma_px: None,
            emitter_cam_mm: None,
            estimate_emitter: true,
            emitter_range_mm: 30.0,
            max_incidence_deg: 75.0,
            fit: FitOptions::default(),
        }
    }
}

/// The corrected sphere fit and what the correction did.
#[derive(Debug, Clone, PartialEq)]
pub struct SphereBiasCorrection {
    /// The sphere fitted to the corrected points (the modelled ones).
    pub fit: SphereFitResult,
    /// The sphere fitted to the points as given.
    pub uncorrected: SphereFitResult,
    /// Per input point: the bias subtracted (measured - corrected), base frame, mm
    /// (zero where not modelled).
    pub corrections_mm: Vec<[f64; 3]>,
    /// Per input point: the model gave a correction (the others are left out of `fit`).
    pub modelled: Vec<bool>,
    /// The sheet and PSF sigmas used (estimated or given).
    pub sheet: SheetSigmaEstimate,
    /// The emitter position used (camera frame, mm).
    pub emitter_cam_mm: Vector3<f64>,
    /// The emitter's estimate from the brightness, when made and accepted.
    pub emitter_estimate: Option<EmitterEstimate>,
    /// `fit.diameter_mm - uncorrected.diameter_mm`.
    pub diameter_change_mm: f64,
    /// `fit.center_mm - uncorrected.center_mm`.
    pub center_change_mm: Vector3<f64>,
    /// Systematic standard uncertainty of the corrected diameter, mm (module docs).
    pub diameter_systematic_mm: f64,
    /// Systematic standard uncertainty of the corrected centre coordinates, mm.
    pub center_systematic_mm: Vector3<f64>,
    /// Its parts `[emitter, sheet and PSF sigmas, neglected terms]` for the diameter.
    pub diameter_systematic_parts_mm: [f64; 3],
    /// Correct-and-refit rounds made.
    pub rounds: usize,
}

/// The rig as the model sees it (camera frame).
#[derive(Debug, Clone)]
pub(super) struct Rig<'a> {
    pub camera: &'a Camera,
    pub n: Vector3<f64>,
    pub d: f64,
    pub emitter: Vector3<f64>,
    /// Index of the coordinate along the scan line (0: u, for `Cols`; 1: v, for `Rows`).
    pub along: usize,
    pub stripe: &'a StripeOptions,
    /// Points whose `t = 0` incidence from the emitter has a smaller cosine are not
    /// modelled.
    pub min_cos: f64,
    /// In-plane basis.
    e1: Vector3<f64>,
    e2: Vector3<f64>,
}

impl<'a> Rig<'a> {
    pub(super) fn new(
        camera: &'a Camera,
        plane: &Plane,
        emitter: Vector3<f64>,
        direction: StripeDirection,
        stripe: &'a StripeOptions,
        max_incidence_deg: f64,
    ) -> Rig<'a> {
        let n = plane.normal;
        let (e1, e2) = plane_basis(&n);
        Rig {
            camera,
            n,
            d: plane.d,
            emitter,
            along: if direction == StripeDirection::Rows {
                1
            } else {
                0
            },
            stripe,
            min_cos: max_incidence_deg.to_radians().cos(),
            e1,
            e2,
        }
    }
}

/// Two unit vectors orthogonal to `n` and to each other.
pub(super) fn plane_basis(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let a = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = (a - n * n.dot(&a)).normalize();
    (e1, n.cross(&e1))
}

/// The pixel of a camera-frame point and its 2x3 Jacobian.
fn project_jac(cam: &Camera, p: &Vector3<f64>) -> Option<([f64; 2], Matrix2x3<f64>)> {
    if p.z.is_nan() || p.z <= 1e-9 {
        return None;
    }
    let iz = 1.0 / p.z;
    let (xn, yn) = (p.x * iz, p.y * iz);
    let ((xd, yd), jd) = cam.distort_with_jacobian(xn, yn);
    let jn = Matrix2x3::new(iz, 0.0, -xn * iz, 0.0, iz, -yn * iz);
    let mut j = jd * jn;
    for c in 0..3 {
        j[(0, c)] *= cam.fu;
        j[(1, c)] *= cam.fv;
    }
    let uv = [cam.fu * xd + cam.u0, cam.fv * yd + cam.v0];
    (uv[0].is_finite() && uv[1].is_finite()).then_some((uv, j))
}

/// The sphere point on the plane `n . p = d + t` imaged on scan line `line`, by Newton's
/// method on the section circle's angle from `phi0`: `(phi, point, along coordinate,
/// d along / dt, stripe slope d along / d line)`.
struct Section {
    phi: f64,
    p: Vector3<f64>,
    a: f64,
    da_dt: f64,
    slope: f64,
}

fn section_point(
    rig: &Rig<'_>,
    c: &Vector3<f64>,
    r: f64,
    t: f64,
    line: f64,
    phi0: f64,
) -> Option<Section> {
    let (al, li) = (rig.along, 1 - rig.along);
    let h = rig.n.dot(c) - rig.d - t;
    let rho2 = r * r - h * h;
    if rho2 <= 0.0 {
        return None;
    }
    let rho = rho2.sqrt();
    let c0 = c - rig.n * h;
    let mut phi = phi0;
    for it in 0..30 {
        let (s, co) = phi.sin_cos();
        let radial = rig.e1 * co + rig.e2 * s;
        let p = c0 + radial * rho;
        let (uv, j) = project_jac(rig.camera, &p)?;
        let dp_dphi = (rig.e2 * co - rig.e1 * s) * rho;
        let jl = j.row(li);
        let ja = j.row(al);
        let f = uv[li] - line;
        let df = jl.dot(&dp_dphi.transpose());
        if df.is_nan() || df.abs() <= 1e-12 {
            return None;
        }
        if f.abs() < 1e-10 || it == 29 {
            if f.abs() > 1e-6 {
                return None;
            }
            // dP/dt at fixed phi: n + (h / rho) radial; then d phi / dt from the line
            // constraint.
            let dp_dt = rig.n + radial * (h / rho);
            let dphi_dt = -jl.dot(&dp_dt.transpose()) / df;
            let da_dt = ja.dot(&(dp_dt + dp_dphi * dphi_dt).transpose());
            let slope = ja.dot(&dp_dphi.transpose()) / df;
            return Some(Section {
                phi,
                p,
                a: uv[al],
                da_dt,
                slope,
            });
        }
        let step = (f / df).clamp(-0.2, 0.2);
        phi -= step;
    }
    None
}

/// The modelled profile of one stripe point: samples `(a_k, w_k)`, and the `t = 0`
/// quantities.
#[derive(Debug, Clone, Default)]
pub(super) struct PointProfile {
    /// Along-line coordinate and weight per sheet offset sample (weight 0: not lit or
    /// not seen).
    pub samples: Vec<(f64, f64)>,
    /// `a(t = 0)`, px.
    pub a0: f64,
    /// `|da/dt|` at `t = 0`, px / mm.
    pub g: f64,
    /// The stripe's slope `d a / d line` at `t = 0`.
    pub slope: f64,
    /// Scratch: the neighbouring scan lines `(offset px, weight)`.
    lines: Vec<(f64, f64)>,
}

/// Is point `p` of the sphere `(c, r)` seen by the camera and lit by the emitter, and
/// its shading `cos(incidence) / r_emitter`.
#[inline]
fn shading(rig: &Rig<'_>, c: &Vector3<f64>, r: f64, p: &Vector3<f64>) -> f64 {
    let nrm = (p - c) / r;
    if nrm.dot(&(-p)) <= 0.0 {
        return 0.0;
    }
    let to_e = rig.emitter - p;
    let re = to_e.norm();
    let cos = nrm.dot(&to_e) / re;
    if cos <= 0.0 {
        return 0.0;
    }
    cos / re
}

/// Gauss-Hermite nodes and weights (5 points, standard normal): the neighbouring scan
/// lines the PSF and the pixel's extent across the scan line mix into one.
const GH5: [(f64, f64); 5] = [
    (0.0, 0.533_333_333_333_333_3),
    (-1.355_626_179_974_266, 0.222_075_922_005_612_6),
    (1.355_626_179_974_266, 0.222_075_922_005_612_6),
    (-2.856_970_013_872_806, 0.011_257_411_327_720_69),
    (2.856_970_013_872_806, 0.011_257_411_327_720_69),
];

/// The samples of one stripe point on scan line `line`, near the camera-frame point
/// `p_near` (the measured point), for sheet sigma `sigma` (mm) and PSF sigma `psf` (px):
/// the scan line itself and its neighbours at `line + x sqrt(psf^2 + 1/12)` (`x` the
/// 5-point Gauss-Hermite nodes; the across-line blur of the PSF and of the pixel box,
/// with their second moment), weighted. `false` when the scan line itself cannot be
/// modelled.
#[allow(clippy::too_many_arguments)]
pub(super) fn point_profile(
    rig: &Rig<'_>,
    c: &Vector3<f64>,
    r: f64,
    line: f64,
    p_near: &Vector3<f64>,
    sigma: f64,
    psf: f64,
    out: &mut PointProfile,
) -> bool {
    out.samples.clear();
    let q = p_near - c;
    let phi0 = q.dot(&rig.e2).atan2(q.dot(&rig.e1));
    // The scan line itself: the t = 0 quantities.
    let Some(s0) = section_point(rig, c, r, 0.0, line, phi0) else {
        return false;
    };
    let to_e = rig.emitter - s0.p;
    if shading(rig, c, r, &s0.p) <= 0.0 || (s0.p - c).dot(&to_e) < rig.min_cos * r * to_e.norm() {
        return false;
    }
    out.a0 = s0.a;
    out.g = s0.da_dt.abs();
    out.slope = s0.slope;
    sub_lines(psf, out.g * sigma, out.slope, &mut out.lines);
    // Samples at most half the kernel's sigma apart in the image.
    let sl = (psf * psf + 1.0 / 12.0).sqrt();
    let m = ((4.0 * sigma * out.g / (0.5 * sl)).ceil() as usize).clamp(HALF_SAMPLES, 400);
    let dt = 4.0 * sigma / m as f64;
    for &(x, om) in &out.lines {
        let Some(s0) = section_point(rig, c, r, 0.0, line + x, phi0) else {
            continue;
        };
        let w0 = shading(rig, c, r, &s0.p);
        if w0 <= 0.0 {
            continue;
        }
        // (dt: the trapezoid rule's step, so that the peak height is comparable between
        // points sampled differently)
        out.samples.push((s0.a, dt * om * w0 * s0.da_dt.abs()));
        for dir in [-1.0f64, 1.0] {
            let mut phi = s0.phi;
            for k in 1..=m {
                let t = dir * k as f64 * dt;
                let Some(s) = section_point(rig, c, r, t, line + x, phi) else {
                    break;
                };
                let w = shading(rig, c, r, &s.p);
                if w <= 0.0 {
                    break;
                }
                phi = s.phi;
                let z = t / sigma;
                out.samples
                    .push((s.a, dt * om * w * s.da_dt.abs() * (-0.5 * z * z).exp()));
            }
        }
    }
    true
}

/// The neighbouring scan lines (offsets px, weights summing to 1) the across-line blur
/// mixes in: the pixel box convolved with the PSF's Gaussian (`psf` px). Where the stripe
/// shifts little between them (`|slope| sqrt(psf^2 + 1/12)` below half the profile's
/// width) 5-point Gauss-Hermite with the kernel's variance; otherwise a uniform grid of
/// the exact kernel, fine enough that the stripe moves by at most a quarter of its
/// width (`width0` the sheet's part, px) from one line to the next.
fn sub_lines(psf: f64, width0: f64, slope: f64, out: &mut Vec<(f64, f64)>) {
    out.clear();
    let sl = (psf * psf + 1.0 / 12.0).sqrt();
    let w = (width0 * width0 + sl * sl).sqrt();
    let shift = slope.abs();
    if shift * sl <= 0.5 * w {
        out.extend(GH5.iter().map(|&(x, om)| (x * sl, om)));
        return;
    }
    let reach = 0.5 + 4.0 * psf;
    let n_side = ((reach * shift / (0.25 * w)).ceil() as usize).clamp(2, 64);
    let h = reach / n_side as f64;
    let inv = if psf > 1e-6 {
        1.0 / (std::f64::consts::SQRT_2 * psf)
    } else {
        0.0
    };
    let mut sum = 0.0;
    for j in 0..=2 * n_side {
        let x = -reach + j as f64 * h;
        let k = if inv > 0.0 {
            0.5 * (erf((x + 0.5) * inv) - erf((x - 0.5) * inv))
        } else {
            // The box alone: the cell's overlap with [-1/2, 1/2].
            ((x + 0.5 * h).min(0.5) - (x - 0.5 * h).max(-0.5)).max(0.0) / h
        };
        if k > 0.0 {
            out.push((x, k));
            sum += k;
        }
    }
    for o in out.iter_mut() {
        o.1 /= sum;
    }
}

/// `erf` (Abramowitz & Stegun 7.1.26, |error| < 1.5e-7).
#[inline]
fn erf(x: f64) -> f64 {
    let a = x.abs();
    if a > 6.0 {
        return x.signum();
    }
    let t = 1.0 / (1.0 + 0.3275911 * a);
    let poly = ((((1.061405429 * t - 1.453152027) * t + 1.421413741) * t - 0.284496736) * t
        + 0.254829592)
        * t;
    let y = 1.0 - poly * (-a * a).exp();
    if x < 0.0 {
        -y
    } else {
        y
    }
}

/// What the extractor measures on a modelled profile: `(centre - a0, width, peak)`
/// (px, px, the model's radiance units).
pub(super) fn extractor_response(
    prof: &PointProfile,
    psf_sigma_px: f64,
    stripe: &StripeOptions,
    buf: &mut Vec<f64>,
) -> Option<(f64, f64, f64)> {
    let sb = psf_sigma_px;
    let var = sb * sb;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let wmax = prof.samples.iter().map(|s| s.1).fold(0.0, f64::max);
    if wmax.is_nan() || wmax <= 0.0 {
        return None;
    }
    let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
    for &(a, w) in &prof.samples {
        if w > 1e-6 * wmax {
            lo = lo.min(a);
            hi = hi.max(a);
            s0 += w;
            s1 += w * a;
            s2 += w * a * a;
        }
    }
    let mean = s1 / s0;
    let sd = (s2 / s0 - mean * mean).max(0.0).sqrt();
    let fwhm = 2.3548 * (sd * sd + var + 1.0 / 12.0).sqrt();
    let pad = (stripe.window_fwhm as f64 * fwhm).max(1.5)
        + 2.0 * fwhm
        + (stripe.flank_px + stripe.ridge_px) as f64
        + 6.0
        + 4.0 * sb;
    let x0 = (lo - pad).floor();
    let x1 = (hi + pad).ceil();
    let len = (x1 - x0) as usize + 1;
    if len > 4096 {
        return None;
    }
    buf.clear();
    buf.resize(len, 0.0);
    let inv = if sb > 1e-6 {
        1.0 / (std::f64::consts::SQRT_2 * sb)
    } else {
        0.0
    };
    for &(a, w) in &prof.samples {
        if w <= 0.0 {
            continue;
        }
        // Only pixels within reach of the kernel.
        let reach = 0.5 + 6.0 * sb + 1.0;
        let k0 = ((a - reach - x0).floor().max(0.0)) as usize;
        let k1 = (((a + reach - x0).ceil()) as usize).min(len - 1);
        for (k, v) in buf.iter_mut().enumerate().take(k1 + 1).skip(k0) {
            let s = x0 + k as f64 - a;
            let kv = if inv > 0.0 {
                0.5 * (erf((s + 0.5) * inv) - erf((s - 0.5) * inv))
            } else if s.abs() < 0.5 {
                1.0
            } else {
                0.0
            };
            *v += w * kv;
        }
    }
    let (c, width, peak) = profile_centre(buf, stripe)?;
    Some((c + x0 - prof.a0, width as f64, peak))
}

/// Everything per point the correction needs: the camera-frame point, the sphere in
/// the camera frame, the scan line and the measured along-line coordinate.
struct PointGeo {
    p_cam: Vector3<f64>,
    line: f64,
    a_meas: f64,
}

fn point_geo(
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
        },
        f,
    ))
}

/// The 3D corrections (base frame) of the points `idx` for a sphere (base frame) and
/// model parameters; `None` per point where the model fails.
#[allow(clippy::too_many_arguments)]
fn corrections(
    rig: &Rig<'_>,
    tri: &Triangulator,
    geo: &[(PointGeo, usize)],
    cam_base: &[Iso3],
    idx: &[usize],
    sphere: (&Vector3<f64>, f64),
    sigma: f64,
    psf: f64,
) -> Vec<Option<[f64; 3]>> {
    idx.par_iter()
        .map_init(
            || (PointProfile::default(), Vec::new()),
            |(prof, buf), &i| {
                let (g, f) = &geo[i];
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
fn corrected_points(
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
    let mut stripe = opts.stripe.clone();
    if stripe.direction == StripeDirection::Auto {
        stripe.direction = stripe_direction_from_plane(camera, plane);
    }
    let emitter = opts
        .emitter_cam_mm
        .map_or(plane.normal * plane.d, Vector3::from);
    let rig = Rig::new(
        camera,
        plane,
        emitter,
        stripe.direction,
        &stripe,
        opts.max_incidence_deg,
    );
    let cam_base: Vec<Iso3> = base_cam.iter().map(|t| t.inverse()).collect();
    let geo = (0..points.len())
        .map(|i| point_geo(points, &cam_base, rig.along, i))
        .collect::<Result<Vec<_>>>()?;
    Ok(geo
        .par_iter()
        .map_init(
            || (PointProfile::default(), Vec::new()),
            |(prof, buf), (g, f)| {
                let c = (cam_base[*f] * nalgebra::Point3::from(*sphere.0)).coords;
                if !point_profile(
                    &rig,
                    &c,
                    sphere.1,
                    g.line,
                    &g.p_cam,
                    sheet_sigma_mm,
                    psf_sigma_px,
                    prof,
                ) {
                    return None;
                }
                extractor_response(prof, psf_sigma_px, rig.stripe, buf).map(|x| x.0)
            },
        )
        .collect())
}

/// The curved-surface bias correction of a sphere scan (module docs).
///
/// `points`: the stripe points of the sphere (e.g. a first fit's inliers), with their
/// pixels and frames; `base_cam[f]`: `T_base_cam` of frame `f` (`T_base_hand(reading) *
/// T_hand_cam`); `camera` and `plane`: the calibration the points were triangulated
/// with. Errors: too few points, frames without a pose, a sheet thickness that cannot
/// be estimated ([`super::sheet_sigma`]), a model that fails on most points.
pub fn correct_sphere_bias(
    points: &ScanPoints,
    base_cam: &[Iso3],
    camera: &Camera,
    plane: &Plane,
    opts: &StripeBiasOptions,
) -> Result<SphereBiasCorrection> {
    let n = points.len();
    if points.u_px.len() != n || points.v_px.len() != n || points.frame.len() != n {
        return Err(Error::InvalidInput(
            "ScanPoints vectors of different lengths".into(),
        ));
    }
    let mut stripe = opts.stripe.clone();
    stripe.validate()?;
    if stripe.direction == StripeDirection::Auto {
        stripe.direction = stripe_direction_from_plane(camera, plane);
    }
    let emitter = match opts.emitter_cam_mm {
        Some(e) => Vector3::from(e),
        None => plane.normal * plane.d,
    };
    if !(opts.emitter_range_mm.is_finite() && opts.emitter_range_mm >= 0.0) {
        return Err(Error::InvalidInput(format!(
            "emitter_range_mm = {} must be finite and >= 0",
            opts.emitter_range_mm
        )));
    }
    let mut rig = Rig::new(
        camera,
        plane,
        emitter,
        stripe.direction,
        &stripe,
        opts.max_incidence_deg,
    );
    let tri = Triangulator::new(camera, plane, &Iso3::identity(), 0.0)?;
    let cam_base: Vec<Iso3> = base_cam.iter().map(|t| t.inverse()).collect();
    let geo = (0..n)
        .map(|i| point_geo(points, &cam_base, rig.along, i))
        .collect::<Result<Vec<_>>>()?;
    let uncorrected = fit_sphere(&points.points_mm, &opts.fit)?;
    // Refits of the corrected points: the same point set every round (the caller's
    // points, less the unmodelled), no trimming, started from the algebraic fit.
    let refit_opts = FitOptions {
        robust_start: false,
        trim_sigma: 0.0,
        ..opts.fit
    };
    let all: Vec<usize> = (0..n).collect();
    // The sheet and PSF sigmas.
    let geo3: Vec<(Vector3<f64>, f64, usize)> =
        geo.iter().map(|(g, f)| (g.p_cam, g.line, *f)).collect();
    let sphere0 = (&uncorrected.center_mm, 0.5 * uncorrected.diameter_mm);
    // The sheet and PSF sigmas (widths) and the emitter (brightness) depend on each
    // other a little: two passes, the second with the first's emitter.
    let estimate_e = opts.emitter_cam_mm.is_none() && opts.estimate_emitter;
    let mut emitter_estimate = None;
    let mut sheet;
    let mut pass = 0;
    loop {
        sheet = estimate_sheet_sigma(
            &rig,
            points,
            &geo3,
            &cam_base,
            sphere0,
            opts.sheet_sigma_mm,
            opts.psf_sigma_px,
        )?;
        pass += 1;
        if !estimate_e || pass > 2 {
            break;
        }
        let (sigma, psf) = (sheet.sheet_sigma_mm, sheet.psf_sigma_px);
        emitter_estimate = estimate_emitter(&rig, points, &geo3, &cam_base, sphere0, sigma, psf);
        match &emitter_estimate {
            Some(e) => rig.emitter = e.emitter_cam_mm,
            None => break,
        }
        if pass == 2 {
            break;
        }
    }
    let (sigma, psf) = (sheet.sheet_sigma_mm, sheet.psf_sigma_px);
    let emitter = rig.emitter;
    // Correct, refit, repeat.
    let mut sphere = (uncorrected.center_mm, 0.5 * uncorrected.diameter_mm);
    let mut fit = uncorrected.clone();
    let mut corr = Vec::new();
    let mut rounds = 0;
    while rounds < MAX_ROUNDS {
        rounds += 1;
        corr = corrections(
            &rig,
            &tri,
            &geo,
            &cam_base,
            &all,
            (&sphere.0, sphere.1),
            sigma,
            psf,
        );
        let good = corr.iter().filter(|c| c.is_some()).count();
        if good < n / 2 || good < 10 {
            return Err(Error::Degenerate(format!(
                "stripe bias: the model holds for {good} of {n} points only"
            )));
        }
        fit = fit_sphere(&corrected_points(points, &all, &corr), &refit_opts)?;
        let moved = (fit.diameter_mm - 2.0 * sphere.1)
            .abs()
            .max((fit.center_mm - sphere.0).norm());
        sphere = (fit.center_mm, 0.5 * fit.diameter_mm);
        if moved < 1e-5 {
            break;
        }
    }
    // Systematic parts on a subsample, as differences from the nominal model on the
    // points both model.
    let step = n.div_ceil(SENSITIVITY_POINTS).max(1);
    let sub: Vec<usize> = (0..n).step_by(step).collect();
    let corr_sub = |rig: &Rig<'_>, sigma: f64, psf: f64| {
        corrections(
            rig,
            &tri,
            &geo,
            &cam_base,
            &sub,
            (&sphere.0, sphere.1),
            sigma,
            psf,
        )
    };
    let nominal = corr_sub(&rig, sigma, psf);
    // (diameter, centre) of the alternative minus the nominal.
    let compare = |alt: &[Option<[f64; 3]>]| -> Option<(f64, Vector3<f64>)> {
        let (mut pa, mut pb) = (Vec::new(), Vec::new());
        for ((&i, a), b) in sub.iter().zip(&nominal).zip(alt) {
            if let (Some(a), Some(b)) = (a, b) {
                let p = points.points_mm[i];
                pa.push([p[0] - a[0], p[1] - a[1], p[2] - a[2]]);
                pb.push([p[0] - b[0], p[1] - b[1], p[2] - b[2]]);
            }
        }
        let fa = fit_sphere(&pa, &refit_opts).ok()?;
        let fb = fit_sphere(&pb, &refit_opts).ok()?;
        Some((fb.diameter_mm - fa.diameter_mm, fb.center_mm - fa.center_mm))
    };
    // Emitter. Assumed: +-range along e1 and e2, the largest change as a uniform half
    // width. Estimated: half the change between +-1 standard uncertainty along each axis,
    // in quadrature.
    let mut em = (0.0f64, Vector3::<f64>::zeros());
    match &emitter_estimate {
        None => {
            for dir in [rig.e1, rig.e2] {
                for s in [-1.0, 1.0] {
                    let mut r2 = rig.clone();
                    r2.emitter = emitter + dir * (s * opts.emitter_range_mm);
                    if let Some((dd, dc)) = compare(&corr_sub(&r2, sigma, psf)) {
                        em.0 = em.0.max(dd.abs());
                        em.1 = em.1.sup(&dc.abs());
                    }
                }
            }
            em = (em.0 / 3f64.sqrt(), em.1 / 3f64.sqrt());
        }
        Some(e) => {
            for (dir, sd) in [(rig.e1, e.sd_mm[0]), (rig.e2, e.sd_mm[1])] {
                let mut ra = rig.clone();
                ra.emitter = emitter + dir * sd;
                let mut rb = rig.clone();
                rb.emitter = emitter - dir * sd;
                let a = compare(&corr_sub(&ra, sigma, psf));
                let b = compare(&corr_sub(&rb, sigma, psf));
                if let (Some(a), Some(b)) = (a, b) {
                    let dd = 0.5 * (a.0 - b.0).abs();
                    let dc = 0.5 * (a.1 - b.1).abs();
                    em.0 = (em.0 * em.0 + dd * dd).sqrt();
                    em.1 = (em.1.component_mul(&em.1) + dc.component_mul(&dc)).map(f64::sqrt);
                }
            }
        }
    }
    // Sheet and PSF sigmas: half the change between +-u, in quadrature.
    let mut sg = (0.0f64, Vector3::<f64>::zeros());
    for (ds, dp) in [(sheet.sheet_sigma_sd_mm, 0.0), (0.0, sheet.psf_sigma_sd_px)] {
        if ds == 0.0 && dp == 0.0 {
            continue;
        }
        let a = compare(&corr_sub(&rig, sigma + ds, psf + dp));
        let b = compare(&corr_sub(&rig, (sigma - ds).max(1e-6), (psf - dp).max(0.0)));
        if let (Some(a), Some(b)) = (a, b) {
            let dd = 0.5 * (a.0 - b.0).abs();
            let dc = 0.5 * (a.1 - b.1).abs();
            sg.0 = (sg.0 * sg.0 + dd * dd).sqrt();
            sg.1 = (sg.1.component_mul(&sg.1) + dc.component_mul(&dc)).map(f64::sqrt);
        }
    }
    let diameter_change_mm = fit.diameter_mm - uncorrected.diameter_mm;
    let center_change_mm = fit.center_mm - uncorrected.center_mm;
    let neg = (
        neglected_share() * diameter_change_mm.abs(),
        center_change_mm.abs() * neglected_share(),
    );
    let rss3 = |a: f64, b: f64, c: f64| (a * a + b * b + c * c).sqrt();
    let diameter_systematic_mm = rss3(em.0, sg.0, neg.0);
    let center_systematic_mm = Vector3::from_fn(|k, _| rss3(em.1[k], sg.1[k], neg.1[k]));
    let modelled: Vec<bool> = corr.iter().map(|c| c.is_some()).collect();
    let corrections_mm = corr.iter().map(|c| c.unwrap_or([0.0; 3])).collect();
    Ok(SphereBiasCorrection {
        fit,
        uncorrected,
        corrections_mm,
        modelled,
        sheet,
        emitter_cam_mm: emitter,
        emitter_estimate,
        diameter_change_mm,
        center_change_mm,
        diameter_systematic_mm,
        center_systematic_mm,
        diameter_systematic_parts_mm: [em.0, sg.0, neg.0],
        rounds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::triangulate::tests::camera;

    fn plane() -> Plane {
        Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 80.0).unwrap()
    }

    /// The modelled bias (px) and width of the point `p` of the sphere of radius `r`
    /// whose outward normal there is `nrm`, for sheet sigma `s` and PSF `b`.
    fn bias_at(p: Vector3<f64>, nrm: Vector3<f64>, r: f64, s: f64, b: f64) -> (f64, f64) {
        let cam = camera([0.0; 5]);
        let pl = plane();
        let so = StripeOptions::default();
        let rig = Rig::new(
            &cam,
            &pl,
            pl.normal * pl.d,
            StripeDirection::Cols,
            &so,
            89.0,
        );
        let c = p - nrm.normalize() * r;
        let line = cam.project(&p).unwrap().y;
        let mut prof = PointProfile::default();
        assert!(point_profile(&rig, &c, r, line, &p, s, b, &mut prof));
        let (d, w, _) = extractor_response(&prof, b, &so, &mut Vec::new()).unwrap();
        (d, w)
    }

    /// A point of the plane on the optical axis.
    fn p0() -> Vector3<f64> {
        let pl = plane();
        Vector3::new(0.0, 0.0, pl.d / pl.normal.z)
    }

    /// The extractor's centre minus the t = 0 image on the scan line through `p`, by
    /// brute force: rays cast through a fine grid of the image around the scan line,
    /// each shaded as the twin does (Gaussian sheet, cos / r from the emitter, seen and
    /// lit), integrated over the pixel box and the Gaussian PSF in both directions.
    fn brute_force_bias(p: Vector3<f64>, nrm: Vector3<f64>, r: f64, s: f64, b: f64) -> f64 {
        let cam = camera([0.0; 5]);
        let pl = plane();
        let e = pl.normal * pl.d;
        let c = p - nrm.normalize() * r;
        let uv = cam.project(&p).unwrap();
        let (u_p, line) = (uv.x, uv.y);
        let hit = |u: f64, v: f64| -> Option<Vector3<f64>> {
            let d = cam.unproject(&nalgebra::Vector2::new(u, v)).ok()?;
            let a = d.norm_squared();
            let bb = d.dot(&c);
            let disc = bb * bb - a * (c.norm_squared() - r * r);
            (disc >= 0.0).then(|| d * ((bb - disc.sqrt()) / a))
        };
        let radiance = |u: f64, v: f64| -> f64 {
            let Some(q) = hit(u, v) else { return 0.0 };
            let n = (q - c) / r;
            let to_e = e - q;
            let cos = n.dot(&to_e) / to_e.norm();
            if cos <= 0.0 || n.dot(&(-q)) <= 0.0 {
                return 0.0;
            }
            let z = pl.signed_distance(&q) / s;
            cos / to_e.norm() * (-0.5 * z * z).exp()
        };
        let kern = |x: f64| {
            let k = 1.0 / (std::f64::consts::SQRT_2 * b);
            0.5 * (erf((x + 0.5) * k) - erf((x - 0.5) * k))
        };
        // The t = 0 image on the scan line: bisection of the signed distance.
        let dist = |u: f64| hit(u, line).map_or(f64::NAN, |q| pl.signed_distance(&q));
        let (mut lo, mut hi) = (u_p - 3.0, u_p + 3.0);
        assert!(dist(lo) * dist(hi) < 0.0);
        for _ in 0..60 {
            let m = 0.5 * (lo + hi);
            if dist(m) * dist(lo) > 0.0 {
                lo = m;
            } else {
                hi = m;
            }
        }
        let a0 = 0.5 * (lo + hi);
        let x0 = (a0 - 60.0).floor();
        let reach = 0.5 + 5.0 * b;
        let (hu, hl) = (0.02, 0.05);
        let nl = (2.0 * reach / hl) as i64;
        let nu = (120.0 / hu) as i64;
        let mut vals = vec![0.0; 121];
        for j in 0..=nl {
            let dl = -reach + j as f64 * hl;
            let kl = kern(dl);
            for i in 0..=nu {
                let uu = x0 + i as f64 * hu;
                let l = radiance(uu, line + dl);
                if l == 0.0 {
                    continue;
                }
                for (k, v) in vals.iter_mut().enumerate() {
                    let du = x0 + k as f64 - uu;
                    if du.abs() < reach {
                        *v += l * kl * kern(du);
                    }
                }
            }
        }
        let (cc, _, _) = profile_centre(&vals, &StripeOptions::default()).unwrap();
        cc + x0 - a0
    }

    #[test]
    fn model_matches_brute_force_integration() {
        // On the ball (convex, several orientations) and on a flat surface (a sphere of
        // 100 m radius: only the perspective and the shading's slow change remain).
        for (nrm, r) in [
            (Vector3::new(0.3, 0.1, -1.0), 22.43),
            (Vector3::new(-0.1, 0.3, -1.0), 22.43),
            (Vector3::new(0.9, -0.3, -1.0), 22.43),
            (Vector3::new(1.5, 0.0, -1.0), 12.7),
            (Vector3::new(1.5, 0.0, -1.0), 1e5),
        ] {
            for (s, b) in [(0.12, 0.7), (0.25, 1.0)] {
                let (m, _) = bias_at(p0(), nrm, r, s, b);
                let bf = brute_force_bias(p0(), nrm, r, s, b);
                eprintln!(
                    "nrm {:?} r {r} s {s} b {b}: model {m:+.5} brute force {bf:+.5} px",
                    nrm.as_slice()
                );
                assert!(
                    (m - bf).abs() < 5e-4 + 0.01 * bf.abs(),
                    "model {m} brute force {bf}"
                );
            }
        }
    }

    #[test]
    fn scan_bias_has_a_part_independent_of_the_sheet() {
        // Not second order in sigma alone: the PSF and the pixel's extent across the scan
        // line average neighbouring scan lines of the curved stripe, a shift of about
        // a'' (b^2 + 1/12) / 2 whatever the sheet's thickness.
        let cam = camera([0.0; 5]);
        let d0 = |s: f64, b: f64| {
            let (sp, poses, _) = synthetic_scan(22.43, s, b);
            let opts = StripeBiasOptions {
                sheet_sigma_mm: Some(s),
                psf_sigma_px: Some(b),
                ..Default::default()
            };
            let res = correct_sphere_bias(&sp, &poses, &cam, &plane(), &opts).unwrap();
            -res.diameter_change_mm
        };
        let (thin, thin_sharp, thick) = (d0(0.03, 0.7), d0(0.03, 0.3), d0(0.12, 0.7));
        assert!(thin > 0.001 && thick > thin, "{thin} {thick}");
        assert!(
            thin_sharp < 0.5 * thin,
            "PSF 0.3 px: {thin_sharp}, 0.7 px: {thin}"
        );
    }

    /// A synthetic scan: the sphere swept through the plane (camera translated along the
    /// plane normal), each row's stripe point at the t = 0 image plus the model's bias,
    /// triangulated. Returns the points, the frame poses, the sphere centre and radius.
    fn synthetic_scan(r: f64, s: f64, b: f64) -> (ScanPoints, Vec<Iso3>, Vector3<f64>) {
        let cam = camera([0.0; 5]);
        let pl = plane();
        let so = StripeOptions::default();
        let rig = Rig::new(
            &cam,
            &pl,
            pl.normal * pl.d,
            StripeDirection::Cols,
            &so,
            75.0,
        );
        let tri = Triangulator::new(&cam, &pl, &Iso3::identity(), 0.0).unwrap();
        let c_mid = p0() + Vector3::new(0.0, 0.0, 0.3 * r);
        let h_mid = pl.normal.dot(&c_mid) - pl.d;
        let mut sp = ScanPoints::default();
        let mut poses = Vec::new();
        let (mut prof, mut buf) = (PointProfile::default(), Vec::new());
        for k in 0..15 {
            let shift = -h_mid + (k as f64 / 14.0 * 1.8 - 0.9) * r;
            let c = c_mid + pl.normal * shift;
            // T_base_cam: the sphere fixed at c_mid in the base frame.
            let t = c_mid - c;
            poses.push(Iso3::translation(t.x, t.y, t.z));
            let (e1, e2) = (rig.e1, rig.e2);
            let h = pl.normal.dot(&c) - pl.d;
            let rho = (r * r - h * h).sqrt();
            let ctr = c - pl.normal * h;
            let pt = |phi: f64| ctr + (e1 * phi.cos() + e2 * phi.sin()) * rho;
            let m = 4000;
            let mut prev: Option<(f64, f64)> = None;
            for j in 0..=m {
                let phi = std::f64::consts::TAU * j as f64 / m as f64;
                let p = pt(phi);
                let seen = shading(&rig, &c, r, &p) > 0.0;
                let v = cam.project(&p).unwrap().y;
                if let (true, Some((pv, pphi))) = (seen, prev) {
                    if pv.floor() != v.floor() {
                        let line = pv.max(v).floor();
                        let Some(s0) = section_point(&rig, &c, r, 0.0, line, pphi) else {
                            continue;
                        };
                        if point_profile(&rig, &c, r, line, &s0.p, s, b, &mut prof) {
                            if let Some((d, w, peak)) = extractor_response(&prof, b, &so, &mut buf)
                            {
                                let u = prof.a0 + d;
                                let q = tri.point_cam_mm(u, line).unwrap() + t;
                                sp.points_mm.push([q.x, q.y, q.z]);
                                sp.frame.push(k);
                                sp.u_px.push(u);
                                sp.v_px.push(line);
                                sp.intensity.push((1e4 * peak) as f32);
                                sp.width_px.push(w as f32);
                                sp.flags.push(0);
                            }
                        }
                    }
                }
                prev = seen.then_some((v, phi));
            }
        }
        (sp, poses, c_mid)
    }

    #[test]
    fn synthetic_scan_bias_is_outward_and_corrected() {
        let (r, s, b) = (22.43, 0.12, 0.7);
        let (sp, poses, c) = synthetic_scan(r, s, b);
        assert!(sp.len() > 1000, "{} points", sp.len());
        let cam = camera([0.0; 5]);
        let res = correct_sphere_bias(&sp, &poses, &cam, &plane(), &Default::default()).unwrap();
        let d0 = res.uncorrected.diameter_mm - 2.0 * r;
        let d1 = res.fit.diameter_mm - 2.0 * r;
        let c1 = (res.fit.center_mm - c).norm();
        // Outward: the uncorrected sphere is too large.
        assert!(d0 > 0.002, "uncorrected diameter error {d0}");
        assert!(d1.abs() < 2e-4, "corrected diameter error {d1} (from {d0})");
        assert!(c1 < 2e-4, "corrected centre error {c1}");
        let sh = &res.sheet;
        assert!((sh.sheet_sigma_mm / s - 1.0).abs() < 0.03, "{sh:?}");
        assert!((sh.psf_sigma_px - b).abs() < 0.05, "{sh:?}");
        let e = res.emitter_estimate.expect("emitter estimated");
        let de = (e.emitter_cam_mm - plane().normal * plane().d).norm();
        assert!(de < 2.0, "emitter off by {de} mm");
        // The systematic part: mostly the model-error share of the correction.
        let sys = res.diameter_systematic_mm;
        let share = neglected_share() * res.diameter_change_mm.abs();
        assert!(sys >= share && sys < share + 2e-4, "{sys} vs {share}");
    }
}
