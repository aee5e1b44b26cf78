//! Sub-pixel saddle points: a blurred X-junction model fitted in a window that is
//! re-centred on the estimate at every step.
//!
//! ## Model
//!
//! Two straight edges through the corner `c` at angles `a1`, `a2` (a projective image of
//! a chessboard corner is exactly that, whatever the tilt), blurred by a Gaussian of
//! width `s` (PSF and pixel area together):
//!
//! `M(x) = erf(n1 . (x - c) / (sqrt 2 s)) erf(n2 . (x - c) / (sqrt 2 s))`,
//!
//! and the image `I(x) = p0 + p1 M + (p2 + p3 M) dx / R + (p4 + p5 M) dy / R` with
//! `(dx, dy) = x - c` and `R` the window radius. The `p2, p4` terms are an additive
//! linear illumination gradient (ambient light), `p3, p5` a multiplicative one (the
//! light on the board times its reflectance): a plain model without them is biased by
//! a gradient across the window. All eleven parameters are fitted by
//! Levenberg-Marquardt with the window (a disc of radius `R`, a one-pixel linear taper
//! at its rim) centred on the current `c`.
//!
//! ## Why the window is symmetric
//!
//! Near its centre the model's blur of an oblique junction is only approximately a
//! Gaussian blur, but both the image of the junction and the model family are point
//! symmetric about their centre. With the window symmetric about `c` the cost is then
//! symmetric under the point reflection about the true corner, so the fitted centre has
//! no bias from the model's approximation (only the pixel grid breaks the symmetry, a
//! small effect that averages out). The window radius stays below the distance to the
//! neighbouring squares' far edges (from the local lattice vectors), so the model's two
//! edges are all the window sees.
//!
//! ## Start
//!
//! The grid gives positions within a few pixels (coarse pyramid levels). A few steps of
//! the gradient-orthogonality estimate (each gradient is orthogonal to the direction
//! from the corner, solved in closed form) bring the start within a fraction of a pixel
//! before the model fit.
//!
//! ## Quality and stripes
//!
//! The reported quality is the formal standard deviation of the position,
//! `sqrt((C_uu + C_vv) / 2)` from `s^2 (J^T W J)^-1` with `s` the residual RMS: it
//! grows with noise, blur, low contrast and any misfit.
//!
//! ## Checks
//!
//! Before the fit, the four squares around the start must look like a chessboard
//! corner and a bright stripe across the window is looked for (`stripe`); after it,
//! the position, contrast, blur, edge directions, square colours, residual RMS and the
//! residual of each of the four sectors are checked (`checks`). A stripe drops the
//! corner ([`Fail::Stripe`]) or, when kept, its pixels and their mirror images about
//! the centre (so the window stays symmetric) are left out of the fit.

use super::checks::{quadrants, validate, worst_sector};
use super::image::Gray;
use super::lattice::{cross, norm, CoordSet, Local};
use super::model::{cost_of, normal, normal_linear, normal_trial, window, Mat, Vec11, NP};
use super::stripe::{dark_sector_stripe, faint_line, residual_stripe, stripe_mask};

/// A converged fit: parameters, final window pixels, normal matrix, cost, weight sum.
type Fitted = (Vec11, Vec<[f64; 4]>, Mat, f64, f64);

/// A measured corner.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Saddle {
    pub u: f64,
    pub v: f64,
    /// Formal standard deviation of the position, px.
    pub sigma_px: f64,
    /// Fitted contrast (light minus dark), image units.
    pub contrast: f64,
    /// The window had to be shrunk to fit, or ends within 2 px of the image border.
    pub near_border: bool,
    /// A bright stripe crosses the window (kept: the stripe pixels and their mirror
    /// images were left out of the fit).
    pub stripe: bool,
    /// Fitted blur, `ln s` (s in px): the start of the neighbours' fits.
    pub ln_blur: f64,
}

/// Why a corner could not be measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Fail {
    Stripe,
    Border,
    NotCorner(&'static str),
}

impl Fail {
    pub fn reason(self) -> &'static str {
        match self {
            Fail::Stripe => "crossed by a bright stripe",
            Fail::Border => "too close to the image border for a measuring window",
            Fail::NotCorner(r) => r,
        }
    }
}

/// Settings of one refinement.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Settings {
    pub max_radius: f64,
    pub keep_stripe: bool,
    /// Image noise sigma, image units.
    pub noise: f64,
    /// Start of the fit's blur, `ln s` (s in px): the neighbours' fitted blur where
    /// known (the blur changes slowly across an image; the start only shortens the
    /// path to the same minimum), else 0. Not used for the fits of a window with
    /// stripe pixels left out.
    pub ln_blur0: f64,
}

/// Gradient-orthogonality estimate (a few closed-form steps).
fn orthogonality_start(g: &Gray, start: [f64; 2], r: f64, mask: &CoordSet) -> Option<[f64; 2]> {
    let mut c = start;
    let s2 = 2.0 * (0.5 * r).powi(2);
    let mut wx: Vec<f64> = Vec::with_capacity(2 * r as usize + 3);
    for _ in 0..10 {
        let (mut a, mut b, mut d, mut bx, mut by) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let (x0, x1) = ((c[0] - r).ceil() as i64, (c[0] + r).floor() as i64);
        let (y0, y1) = ((c[1] - r).ceil() as i64, (c[1] + r).floor() as i64);
        let (xa, xb) = (x0.max(1), x1.min(g.w as i64 - 2));
        // the Gaussian weight is separable: one exp per column and one per row
        wx.clear();
        wx.extend((xa..=xb).map(|x| {
            let dx = x as f64 - c[0];
            (-(dx * dx) / s2).exp()
        }));
        for y in y0.max(1)..=y1.min(g.h as i64 - 2) {
            let dy = y as f64 - c[1];
            let wy = (-(dy * dy) / s2).exp();
            for (x, &wxx) in (xa..=xb).zip(&wx) {
                if !mask.is_empty() {
                    let (mx, my) = (
                        (2.0 * c[0] - x as f64).round(),
                        (2.0 * c[1] - y as f64).round(),
                    );
                    if mask.contains(&(x as i32, y as i32))
                        || mask.contains(&(mx as i32, my as i32))
                    {
                        continue;
                    }
                }
                let (xu, yu) = (x as usize, y as usize);
                let gx = 0.5 * (g.at(xu + 1, yu) - g.at(xu - 1, yu)) as f64;
                let gy = 0.5 * (g.at(xu, yu + 1) - g.at(xu, yu - 1)) as f64;
                let w = wxx * wy;
                let (gxx, gxy, gyy) = (w * gx * gx, w * gx * gy, w * gy * gy);
                a += gxx;
                b += gxy;
                d += gyy;
                bx += gxx * x as f64 + gxy * y as f64;
                by += gxy * x as f64 + gyy * y as f64;
            }
        }
        let det = a * d - b * b;
        if det.is_nan() || det <= 1e-12 * (a + d) * (a + d) {
            return None;
        }
        let n = [(d * bx - b * by) / det, (a * by - b * bx) / det];
        let step = norm([n[0] - c[0], n[1] - c[1]]);
        c = n;
        if !(step.is_finite()) {
            return None;
        }
        if step < 0.02 {
            break;
        }
    }
    Some(c)
}

/// The fit itself: returns the parameters, the final window and its normal equations.
fn fit(
    g: &Gray,
    c0: [f64; 2],
    angles: [f64; 2],
    ln_blur0: f64,
    r: f64,
    mask: &CoordSet,
) -> Option<Fitted> {
    let inv_r = 1.0 / r;
    let mut th = Vec11::zeros();
    th[0] = c0[0];
    th[1] = c0[1];
    th[2] = angles[0];
    th[3] = angles[1];
    th[4] = ln_blur0.clamp(-3.0, 3.0);
    let mut px = Vec::with_capacity(512);
    window(g, c0, r, mask, &mut px);
    if px.len() < 20 {
        return None;
    }
    // linear part first: contrast and illumination for the starting geometry
    {
        let (hl, bl) = normal_linear(&th, &px, inv_r);
        let sol = hl.cholesky()?.solve(&bl);
        for k in 0..6 {
            th[5 + k] = sol[k];
        }
    }
    let mut lambda = 1e-3;
    // the window is centred on the start (th's centre): its normal equations; each
    // trial's pass gives those of the window re-centred on it with its cost test
    // (the parameters are relative to the centre: shifting the window keeps them)
    let (mut h, mut b, mut cost, mut wsum) = normal(&th, &px, inv_r);
    let mut px2 = Vec::with_capacity(px.capacity());
    let converged = |d: &Vec11| d[0].hypot(d[1]) < 2e-4 && d[2].abs() < 2e-4 && d[3].abs() < 2e-4;
    'lm: for _ in 0..40 {
        if px.len() < 20 {
            return None;
        }
        let mut accepted = None;
        for _ in 0..8 {
            let mut ha = h;
            for k in 0..NP {
                ha[(k, k)] += lambda * h[(k, k)].max(1e-12);
            }
            let Some(ch) = ha.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let delta = ch.solve(&b);
            let mut t2 = th + delta;
            t2[4] = t2[4].clamp(-3.0, 3.0);
            if converged(&delta) {
                // the last step (below 2e-4 px and rad): its cost over the window
                // shifted with it; the normal equations stay those of the previous
                // estimate (for the covariance, 2e-4 px away)
                let c2 = cost_of(&t2, &px, inv_r, [delta[0], delta[1]]);
                if c2.is_finite() && c2 <= cost {
                    for q in px.iter_mut() {
                        q[0] -= delta[0];
                        q[1] -= delta[1];
                    }
                    th = t2;
                    cost = c2;
                    break 'lm;
                }
                lambda *= 4.0;
                continue;
            }
            window(g, [t2[0], t2[1]], r, mask, &mut px2);
            let (nrm, c2) = normal_trial(&t2, &px, [th[0], th[1]], &px2, inv_r);
            if c2.is_finite() && c2 <= cost {
                lambda = (lambda / 3.0).max(1e-9);
                accepted = Some((t2, nrm));
                break;
            }
            lambda *= 4.0;
        }
        let Some((t2, nrm)) = accepted else {
            break;
        };
        th = t2;
        std::mem::swap(&mut px, &mut px2);
        (h, b, cost, wsum) = nrm;
    }
    th.iter()
        .all(|v| v.is_finite())
        .then_some((th, px, h, cost, wsum))
}

/// Measures the corner near `start` with local lattice steps `di`, `dj` (image
/// vectors to the `+i` and `+j` neighbours). `light_ij`: whether the square between the
/// `+i` and `+j` edges is light, when known. `strict`: a site the candidates did not
/// show (grid extension, holes), whose squares must agree closely (0.6, against 1.2 for
/// a grid corner whose links were checked; glare on one square stays below 1).
pub(crate) fn refine(
    g: &Gray,
    start: [f64; 2],
    di: [f64; 2],
    dj: [f64; 2],
    light_ij: Option<bool>,
    strict: bool,
    s: &Settings,
) -> Result<Saddle, Fail> {
    let (li, lj) = (norm(di), norm(dj));
    let area = cross(di, dj).abs();
    if !(li > 1.0 && lj > 1.0 && area > 1.0 && start[0].is_finite() && start[1].is_finite()) {
        return Err(Fail::NotCorner("degenerate local lattice"));
    }
    let d_far = area / li.max(lj);
    let mut r = (0.75 * d_far - 1.5).clamp(2.5, s.max_radius.max(2.5));
    let border = |c: [f64; 2]| {
        let (w, h) = ((g.w - 1) as f64, (g.h - 1) as f64);
        c[0].min(c[1]).min(w - c[0]).min(h - c[1]) - 1.5
    };
    let mut near_border = false;
    let mut shrink = |c: [f64; 2], r: &mut f64| {
        let rb = border(c);
        if rb < *r {
            if rb < 2.5 {
                return Err(Fail::Border);
            }
            *r = rb;
            near_border = true;
        }
        Ok(())
    };
    shrink(start, &mut r)?;
    let ratio = if strict { 0.6 } else { 1.2 };
    let (light, dark) = quadrants(g, start, di, dj, light_ij, s.noise, ratio)?;
    let mask = stripe_mask(g, start, r, light, dark, s.noise);
    let stripe = !mask.is_empty();
    if stripe && !s.keep_stripe {
        return Err(Fail::Stripe);
    }
    let tol = (0.35 * li.min(lj)).max(2.0);
    let c0 =
        orthogonality_start(g, start, r, &mask).ok_or(Fail::NotCorner("no gradient structure"))?;
    if norm([c0[0] - start[0], c0[1] - start[1]]) > tol {
        return Err(Fail::NotCorner(
            "the saddle point is far from the predicted position",
        ));
    }
    shrink(c0, &mut r)?;
    let on_dark = dark_sector_stripe(g, &Local { p: c0, di, dj }, r, light_ij, light, dark);
    let stripe = stripe || !on_dark.is_empty();
    if stripe && !s.keep_stripe {
        return Err(Fail::Stripe);
    }
    let mask: CoordSet = mask.union(&on_dark).copied().collect();
    let angles = [di[1].atan2(di[0]), dj[1].atan2(dj[0])];
    // a window with stripe pixels left out starts from 0 (a part of the window is
    // missing: the neighbours' blur can lead such a fit to another minimum)
    let blur0 = if mask.is_empty() { s.ln_blur0 } else { 0.0 };
    let (mut th, mut px, mut h, mut cost, mut wsum) =
        fit(g, c0, angles, blur0, r, &mask).ok_or(Fail::NotCorner("the saddle fit failed"))?;
    let more: CoordSet = residual_stripe(&th, &px, r, s.noise)
        .union(&faint_line(g, [th[0], th[1]], r, light, dark, s.noise))
        .copied()
        .collect();
    let stripe = stripe || !more.is_empty();
    if !more.is_empty() {
        if !s.keep_stripe {
            return Err(Fail::Stripe);
        }
        let all: CoordSet = mask.union(&more).copied().collect();
        (th, px, h, cost, wsum) = fit(g, c0, angles, 0.0, r, &all).ok_or(Fail::Stripe)?;
    }
    validate(
        &th,
        &Local { p: start, di, dj },
        angles,
        r,
        tol,
        light_ij,
        s,
    )?;
    if worst_sector(&th, &px, r) > 0.25 * 2.0 * th[6].abs() {
        return Err(Fail::NotCorner(
            "one of its four squares does not fit a corner model",
        ));
    }
    let rms = (cost / wsum.max(1.0)).sqrt();
    if rms > 0.25 * 2.0 * th[6].abs() + 2.0 * s.noise {
        return Err(Fail::NotCorner("the image does not fit a corner model"));
    }
    let c = [th[0], th[1]];
    near_border |= border(c) - r < 2.0;
    let dof = (wsum - NP as f64).max(1.0);
    let s2 = cost / dof;
    let sigma_px = h
        .try_inverse()
        .map(|inv| (0.5 * s2 * (inv[(0, 0)] + inv[(1, 1)]).max(0.0)).sqrt())
        .unwrap_or(f64::NAN);
    Ok(Saddle {
        u: c[0],
        v: c[1],
        sigma_px,
        contrast: 2.0 * th[6].abs(),
        near_border,
        stripe,
        ln_blur: th[4],
    })
}
