//! The model of one stripe point ([`super`] docs): the rig as the model sees it, the
//! sphere's section at a sheet offset on the point's scan line, its shading, and the
//! profile the camera sees, on which the extractor's own centroid runs.

use nalgebra::{Matrix2x3, Vector3};

use crate::model::camera::Camera;
use crate::model::geometry::Plane;
use crate::model::StripeDirection;
use crate::vision::stripe::StripeOptions;

use super::image::{sheet_offsets, sub_lines};

/// The rig as the model sees it (camera frame).
#[derive(Debug, Clone)]
pub(crate) struct Rig<'a> {
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
    /// Points seen by the camera at a smaller cosine between the surface normal and the
    /// line of sight (`t = 0`) are not modelled (sphere only; 0: all that face it).
    pub min_cos_view: f64,
    /// Points whose extractor support (window and flanks, for the modelled width), plus
    /// this many pixels, reaches the sphere's outline on their scan line are not modelled
    /// (sphere only; `None`: no such test).
    pub outline_margin_px: Option<f64>,
    /// In-plane basis.
    pub e1: Vector3<f64>,
    pub e2: Vector3<f64>,
}

impl<'a> Rig<'a> {
    pub(crate) fn new(
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
            min_cos_view: 0.0,
            outline_margin_px: None,
            e1,
            e2,
        }
    }
}

/// Two unit vectors orthogonal to `n` and to each other.
pub(crate) fn plane_basis(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let a = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = (a - n * n.dot(&a)).normalize();
    (e1, n.cross(&e1))
}

/// The pixel of a camera-frame point and its 2x3 Jacobian.
pub(crate) fn project_jac(cam: &Camera, p: &Vector3<f64>) -> Option<([f64; 2], Matrix2x3<f64>)> {
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

/// A surface the sheet lights, as the profile model sees it: the point at sheet offset
/// `t` imaged on scan line `line` (Newton's method from the surface parameter `hint`:
/// the section circle's angle of a sphere, the position along a board's line), and its
/// shading (0 where the camera or the emitter does not see it).
pub(crate) trait Surface {
    fn section(&self, rig: &Rig<'_>, t: f64, line: f64, hint: f64) -> Option<Section>;
    fn shading(&self, rig: &Rig<'_>, p: &Vector3<f64>) -> f64;
}

/// A sphere (camera frame): centre and radius.
pub(crate) struct SphereSurface<'c> {
    pub c: &'c Vector3<f64>,
    pub r: f64,
}

impl Surface for SphereSurface<'_> {
    fn section(&self, rig: &Rig<'_>, t: f64, line: f64, hint: f64) -> Option<Section> {
        section_point(rig, self.c, self.r, t, line, hint)
    }
    fn shading(&self, rig: &Rig<'_>, p: &Vector3<f64>) -> f64 {
        shading(rig, self.c, self.r, p)
    }
}

/// The surface point at a sheet offset imaged on a scan line ([`Surface::section`]): its
/// surface parameter, point, along-line coordinate and their derivatives in the sheet
/// offset `t` along the scan line, and the stripe's slope `d along / d line`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Section {
    /// The surface parameter ([`Surface::section`]'s `hint` for the next offset).
    pub phi: f64,
    pub dphi_dt: f64,
    pub p: Vector3<f64>,
    pub dp_dt: Vector3<f64>,
    pub a: f64,
    pub da_dt: f64,
    pub slope: f64,
}

impl Section {
    /// The section halfway between `self` (at `t`) and `next` (at `t + h`) by cubic
    /// Hermite interpolation in `t` of the surface parameter, the point and the along-line
    /// coordinate, from their values and derivatives at the two ends: `y = (y0 + y1) / 2 +
    /// h (y0' - y1') / 8`, `y' = 3 (y1 - y0) / (2 h) - (y0' + y1') / 4`. The error is `h^4
    /// / 384` times the fourth derivative: for a sphere of radius `R` seen at `|da/dt| =
    /// g`, of the order of `g h^4 / (384 R^3)` px, below 1e-9 px at the sheet offsets
    /// sampled here (`h` a tenth of a millimetre or less, `R` a millimetre or more).
    pub(crate) fn halfway(&self, next: &Section, h: f64) -> Section {
        let mid = |y0: f64, d0: f64, y1: f64, d1: f64| {
            (
                0.5 * (y0 + y1) + 0.125 * h * (d0 - d1),
                1.5 * (y1 - y0) / h - 0.25 * (d0 + d1),
            )
        };
        let (phi, dphi_dt) = mid(self.phi, self.dphi_dt, next.phi, next.dphi_dt);
        let (a, da_dt) = mid(self.a, self.da_dt, next.a, next.da_dt);
        let p = (self.p + next.p) * 0.5 + (self.dp_dt - next.dp_dt) * (0.125 * h);
        let dp_dt = (next.p - self.p) * (1.5 / h) - (self.dp_dt + next.dp_dt) * 0.25;
        Section {
            phi,
            dphi_dt,
            p,
            dp_dt,
            a,
            da_dt,
            slope: 0.5 * (self.slope + next.slope),
        }
    }
}

/// Newton's method on the scan line stops when the point is this close to it (px) and
/// takes its last step linearly. What the linear step leaves is of the order of the
/// step's square over the section's image radius (hundreds of pixels): below 1e-10 px,
/// and the derivatives taken at the iterate are within ~1e-7 of their value at the
/// solution (it was 1e-6 px, which cost a second projection at most offsets).
pub(crate) const NEWTON_LAST_STEP_PX: f64 = 1e-4;

pub(crate) fn section_point(
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
        if f.abs() < NEWTON_LAST_STEP_PX {
            // The last Newton step taken linearly (its square is below 1e-8 px), the
            // derivatives at this iterate. dP/dt at fixed phi: n + (h / rho) radial; then
            // d phi / dt from the line constraint.
            let last = -f / df;
            let dp_dt = rig.n + radial * (h / rho);
            let dphi_dt = -jl.dot(&dp_dt.transpose()) / df;
            let dp_total = dp_dt + dp_dphi * dphi_dt;
            let da_dt = ja.dot(&dp_total.transpose());
            let da_dphi = ja.dot(&dp_dphi.transpose());
            return Some(Section {
                phi: phi + last,
                dphi_dt,
                p: p + dp_dphi * last,
                dp_dt: dp_total,
                a: uv[al] + da_dphi * last,
                da_dt,
                slope: da_dphi / df,
            });
        }
        if it == 29 {
            return None;
        }
        let step = (f / df).clamp(-0.2, 0.2);
        phi -= step;
    }
    None
}

/// The modelled profile of one stripe point: samples `(a_k, w_k)`, and the `t = 0`
/// quantities.
#[derive(Debug, Clone, Default)]
pub(crate) struct PointProfile {
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

/// How far from its centre the extractor reads a stripe of width `width` px along the
/// scan line: the centroid window (`window_fwhm` widths, at least 1.5 px), the pixel of
/// slack and the half pixel of rounding beyond it, and the background flanks.
pub(crate) fn support_px(stripe: &StripeOptions, width: f64) -> f64 {
    (stripe.window_fwhm as f64 * width).max(1.5) + 1.5 + stripe.flank_px as f64
}

/// Are the pixels `reach` px either side of `a` on scan line `line` still on the image of
/// the sphere `(c, r)` (camera frame)? The sphere's outline is convex, so the two ends
/// decide for the whole stretch. `false` where a pixel cannot be unprojected.
pub(crate) fn clear_of_outline(
    rig: &Rig<'_>,
    c: &Vector3<f64>,
    r: f64,
    line: f64,
    a: f64,
    reach: f64,
) -> bool {
    [-reach, reach].iter().all(|&x| {
        let mut uv = nalgebra::Vector2::zeros();
        uv[rig.along] = a + x;
        uv[1 - rig.along] = line;
        match rig.camera.unproject(&uv) {
            Ok(ray) => {
                let d = ray.normalize();
                d.dot(c) > 0.0 && (c - d * d.dot(c)).norm() < r
            }
            Err(_) => false,
        }
    })
}

/// Is point `p` of the sphere `(c, r)` seen by the camera and lit by the emitter, and
/// its shading `cos(incidence) / r_emitter`.
#[inline]
pub(crate) fn shading(rig: &Rig<'_>, c: &Vector3<f64>, r: f64, p: &Vector3<f64>) -> f64 {
    // cos / r_e = ((p - c) / r . (E - p) / r_e) / r_e: one division, no square root.
    let q = p - c;
    if q.dot(p) >= 0.0 {
        return 0.0;
    }
    let to_e = rig.emitter - p;
    let num = q.dot(&to_e);
    if num <= 0.0 {
        return 0.0;
    }
    num / (r * to_e.norm_squared())
}

/// Gauss-Hermite nodes and weights (5 points, standard normal): the neighbouring scan
/// lines the PSF and the pixel's extent across the scan line mix into one.
pub(crate) const GH5: [(f64, f64); 5] = [
    (0.0, 0.533_333_333_333_333_3),
    (-1.355_626_179_974_266, 0.222_075_922_005_612_6),
    (1.355_626_179_974_266, 0.222_075_922_005_612_6),
    (-2.856_970_013_872_806, 0.011_257_411_327_720_69),
    (2.856_970_013_872_806, 0.011_257_411_327_720_69),
];

/// The samples of one stripe point of the sphere `sphere` on scan line `line`, near the
/// camera-frame point `p_near` (the measured point), for sheet sigma `sigma` (mm) and PSF
/// sigma `psf` (px):
/// the scan line itself and its neighbours at `line + x sqrt(psf^2 + 1/12)` (`x` the
/// 5-point Gauss-Hermite nodes; the across-line blur of the PSF and of the pixel box,
/// with their second moment), weighted. `false` when the scan line itself cannot be
/// modelled.
pub(crate) fn point_profile(
    rig: &Rig<'_>,
    sphere: &SphereSurface<'_>,
    line: f64,
    p_near: &Vector3<f64>,
    sigma: f64,
    psf: f64,
    out: &mut PointProfile,
) -> bool {
    out.samples.clear();
    let Some(s0) = point_section(rig, sphere, line, p_near, sigma, psf) else {
        return false;
    };
    out.a0 = s0.a;
    out.g = s0.da_dt.abs();
    out.slope = s0.slope;
    sample_lines(rig, sphere, line, s0.phi, sigma, psf, out);
    true
}

/// Whether the extractor's support for the width modelled at the `t = 0` section `s0`,
/// widened by the rig's outline margin, stays clear of the sphere's outline (always, when
/// the rig sets no margin).
fn support_clear(
    rig: &Rig<'_>,
    c: &Vector3<f64>,
    r: f64,
    line: f64,
    s0: &Section,
    sigma: f64,
    psf: f64,
) -> bool {
    let Some(margin) = rig.outline_margin_px else {
        return true;
    };
    let width = 2.3548 * ((s0.da_dt * sigma).powi(2) + psf * psf + 1.0 / 12.0).sqrt();
    clear_of_outline(
        rig,
        c,
        r,
        line,
        s0.a,
        support_px(rig.stripe, width) + margin,
    )
}

/// [`point_profile`]'s `t = 0` section of the point, `None` where it is not modelled (the
/// section fails, the point is unlit, lit or seen beyond the limits, or the extractor's
/// support for the modelled width reaches the outline): its `g = |da/dt|` and slope
/// without the profile's samples.
pub(crate) fn point_section(
    rig: &Rig<'_>,
    sphere: &SphereSurface<'_>,
    line: f64,
    p_near: &Vector3<f64>,
    sigma: f64,
    psf: f64,
) -> Option<Section> {
    let (c, r) = (sphere.c, sphere.r);
    let q = p_near - c;
    let phi0 = q.dot(&rig.e2).atan2(q.dot(&rig.e1));
    // The scan line itself: the t = 0 quantities.
    let s0 = section_point(rig, c, r, 0.0, line, phi0)?;
    let to_e = rig.emitter - s0.p;
    if shading(rig, c, r, &s0.p) <= 0.0
        || (s0.p - c).dot(&to_e) < rig.min_cos * r * to_e.norm()
        || (c - s0.p).dot(&s0.p) < rig.min_cos_view * r * s0.p.norm()
    {
        return None;
    }
    if !support_clear(rig, c, r, line, &s0, sigma, psf) {
        return None;
    }
    Some(s0)
}

/// The part of a sphere point's modelled profile that does not depend on the emitter
/// ([`point_geometry`]): the `t = 0` point and quantities, and per neighbouring scan line
/// its sections at the sheet offsets of [`sample_lines`] (continued until the section
/// fails or faces away from the camera), each with its weight but for the shading. The
/// emitter's fit and its sensitivity terms model the same points, sphere and sigmas
/// under several emitters: [`profile_for_emitter`] builds each one's profile from this
/// without solving a section again, the same samples in the same order as
/// [`point_profile`].
#[derive(Debug, Clone, Default)]
pub(crate) struct PointGeometry {
    p0: Vector3<f64>,
    a0: f64,
    g: f64,
    slope: f64,
    /// The sections: `(a, p, dt omega, |da/dt|, the sheet's Gaussian; 1 at t = 0)`.
    samples: Vec<GeoSample>,
    /// Per neighbouring scan line: the index of its `t = 0` section and the ends of its
    /// two runs outwards (`[t0 + 1, mid)` towards `-t`, `[mid, end)` towards `+t`).
    lines: Vec<(usize, usize, usize)>,
}

#[derive(Debug, Clone, Copy)]
struct GeoSample {
    a: f64,
    p: Vector3<f64>,
    dt_om: f64,
    da: f64,
    gauss: f64,
}

/// [`point_profile`]'s emitter-independent part into `out` (module docs of
/// [`PointGeometry`]); `false` when the point cannot be modelled whatever the emitter.
#[allow(clippy::too_many_arguments)]
pub(crate) fn point_geometry(
    rig: &Rig<'_>,
    sphere: &SphereSurface<'_>,
    line: f64,
    p_near: &Vector3<f64>,
    sigma: f64,
    psf: f64,
    scratch: &mut Vec<(f64, f64)>,
    out: &mut PointGeometry,
) -> bool {
    out.samples.clear();
    out.lines.clear();
    let (c, r) = (sphere.c, sphere.r);
    let q = p_near - c;
    let phi0 = q.dot(&rig.e2).atan2(q.dot(&rig.e1));
    let Some(s0) = section_point(rig, c, r, 0.0, line, phi0) else {
        return false;
    };
    if !facing(c, &s0.p) || (c - s0.p).dot(&s0.p) < rig.min_cos_view * r * s0.p.norm() {
        return false;
    }
    if !support_clear(rig, c, r, line, &s0, sigma, psf) {
        return false;
    }
    out.p0 = s0.p;
    out.a0 = s0.a;
    out.g = s0.da_dt.abs();
    out.slope = s0.slope;
    // As `sample_lines`, the shading left out (the sections' continuation stops where
    // the point no longer faces the camera; the emitter's side is decided per emitter).
    sub_lines(psf, out.g * sigma, out.slope, scratch);
    let (m, dt) = sheet_offsets(sigma, out.g, psf);
    for &(x, om) in scratch.iter() {
        let Some(z0) = section_point(rig, c, r, 0.0, line + x, s0.phi) else {
            continue;
        };
        if !facing(c, &z0.p) {
            continue;
        }
        let dt_om = dt * om;
        let start = out.samples.len();
        out.samples.push(GeoSample {
            a: z0.a,
            p: z0.p,
            dt_om,
            da: z0.da_dt.abs(),
            gauss: 1.0,
        });
        let mut mid = start + 1;
        for dir in [-1.0f64, 1.0] {
            run_outwards(rig, sphere, line + x, &z0, (dir, m, dt), |t, s| {
                if !facing(c, &s.p) {
                    return false;
                }
                let z = t / sigma;
                out.samples.push(GeoSample {
                    a: s.a,
                    p: s.p,
                    dt_om,
                    da: s.da_dt.abs(),
                    gauss: (-0.5 * z * z).exp(),
                });
                true
            });
            if dir < 0.0 {
                mid = out.samples.len();
            }
        }
        out.lines.push((start, mid, out.samples.len()));
    }
    true
}

/// The profile of a point whose emitter-independent part is `geo` ([`point_geometry`])
/// for `rig`'s emitter: what [`point_profile`] gives for the same inputs. `false` when
/// the point cannot be modelled (its `t = 0` point unlit or lit beyond the incidence
/// limit).
pub(crate) fn profile_for_emitter(
    rig: &Rig<'_>,
    sphere: &SphereSurface<'_>,
    geo: &PointGeometry,
    out: &mut PointProfile,
) -> bool {
    out.samples.clear();
    let (c, r) = (sphere.c, sphere.r);
    let to_e = rig.emitter - geo.p0;
    if shading(rig, c, r, &geo.p0) <= 0.0 || (geo.p0 - c).dot(&to_e) < rig.min_cos * r * to_e.norm()
    {
        return false;
    }
    out.a0 = geo.a0;
    out.g = geo.g;
    out.slope = geo.slope;
    for &(start, mid, end) in &geo.lines {
        let z0 = &geo.samples[start];
        let w0 = shading(rig, c, r, &z0.p);
        if w0 <= 0.0 {
            continue;
        }
        out.samples.push((z0.a, z0.dt_om * w0 * z0.da));
        for run in [start + 1..mid, mid..end] {
            for s in &geo.samples[run] {
                let w = shading(rig, c, r, &s.p);
                if w <= 0.0 {
                    break;
                }
                out.samples.push((s.a, s.dt_om * w * s.da * s.gauss));
            }
        }
    }
    true
}

/// Does the sphere's point `p` (centre `c`) face the camera ([`shading`]'s first test)?
#[inline]
fn facing(c: &Vector3<f64>, p: &Vector3<f64>) -> bool {
    (p - c).dot(p) < 0.0
}

/// The samples of a stripe point whose `t = 0` quantities (`a0`, `g`, `slope`) are in
/// `out`: on the scan line and the neighbouring ones the blur mixes in ([`sub_lines`]),
/// sheet offsets at most [`super::image::sample_spacing_px`] apart in the image ([`sheet_offsets`]), each weighted
/// by the Gaussian sheet, the shading and `|da/dt|`, continued outwards in `t` from the
/// surface parameter `hint` until the surface is no longer seen or lit.
pub(crate) fn sample_lines<S: Surface>(
    rig: &Rig<'_>,
    surf: &S,
    line: f64,
    hint: f64,
    sigma: f64,
    psf: f64,
    out: &mut PointProfile,
) {
    sub_lines(psf, out.g * sigma, out.slope, &mut out.lines);
    let (m, dt) = sheet_offsets(sigma, out.g, psf);
    for &(x, om) in &out.lines {
        let Some(s0) = surf.section(rig, 0.0, line + x, hint) else {
            continue;
        };
        let w0 = surf.shading(rig, &s0.p);
        if w0 <= 0.0 {
            continue;
        }
        // (dt: the trapezoid rule's step, so that the peak height is comparable between
        // points sampled differently)
        out.samples.push((s0.a, dt * om * w0 * s0.da_dt.abs()));
        for dir in [-1.0f64, 1.0] {
            run_outwards(rig, surf, line + x, &s0, (dir, m, dt), |t, s| {
                let w = surf.shading(rig, &s.p);
                if w <= 0.0 {
                    return false;
                }
                let z = t / sigma;
                out.samples
                    .push((s.a, dt * om * w * s.da_dt.abs() * (-0.5 * z * z).exp()));
                true
            });
        }
    }
}

/// The sections of one run outwards from the `t = 0` section `s0` of scan line `line`:
/// `steps = (dir, m, dt)`, sheet offsets `t_k = dir k dt` for `k = 1..=m`, handed to
/// `visit` in order until it returns `false` or a section fails. Every second offset is
/// solved, by Newton's method from the surface parameter extrapolated from the last solved
/// sections and their derivatives (within [`NEWTON_LAST_STEP_PX`] of the scan line at most
/// offsets: one projection), and the offset between two solved ones is read from them
/// ([`Section::halfway`]); the run's last offset, and one whose next section fails, is
/// solved itself. Half the sections of a run are solved: on the twin ball, the samples
/// moved by at most ~1e-9 px against all of them solved.
/// [`run_outwards`] reads a section between two solved ones where the trapezoid rule's
/// defect on the along-line coordinate over the two steps (`h^3 / 12` times its third
/// derivative in `t`) is at most this (px), and solves it otherwise.
const MAX_DEFECT_PX: f64 = 1e-5;

pub(crate) fn run_outwards<S: Surface>(
    rig: &Rig<'_>,
    surf: &S,
    line: f64,
    s0: &Section,
    (dir, m, dt): (f64, usize, f64),
    mut visit: impl FnMut(f64, &Section) -> bool,
) {
    // The last solved section and its offset, and the derivative of the surface
    // parameter at the one before (the extrapolation's second-order term).
    let (mut prev, mut t_prev) = (*s0, 0.0);
    let mut before: Option<(f64, f64)> = None;
    let predict = |t: f64, prev: &Section, t_prev: f64, before: Option<(f64, f64)>| {
        let h = t - t_prev;
        let curv = before.map_or(0.0, |(tb, db)| (prev.dphi_dt - db) / (t_prev - tb));
        prev.phi + h * (prev.dphi_dt + 0.5 * h * curv)
    };
    let mut k = 1;
    while k <= m {
        let t1 = dir * k as f64 * dt;
        if k < m {
            let t2 = dir * (k + 1) as f64 * dt;
            let hint = predict(t2, &prev, t_prev, before);
            if let Some(s2) = surf.section(rig, t2, line, hint) {
                let h = t2 - t_prev;
                // The trapezoid rule's defect on `a` over the two steps: where the
                // stripe's image bends this sharply (near the outline) the offset
                // between is solved.
                let defect = (s2.a - prev.a) - 0.5 * h * (prev.da_dt + s2.da_dt);
                let mut mid = prev.halfway(&s2, h);
                if defect.abs() > MAX_DEFECT_PX {
                    let Some(solved) = surf.section(rig, t1, line, mid.phi) else {
                        return;
                    };
                    mid = solved;
                }
                if !visit(t1, &mid) || !visit(t2, &s2) {
                    return;
                }
                before = Some((t_prev, prev.dphi_dt));
                (prev, t_prev) = (s2, t2);
                k += 2;
                continue;
            }
        }
        let hint = predict(t1, &prev, t_prev, before);
        if let Some(s1) = surf.section(rig, t1, line, hint) {
            visit(t1, &s1);
        }
        return;
    }
}
