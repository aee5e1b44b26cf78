//! The stripe model of [`super`] on a FLAT surface (a calibration board): the same
//! profile (sheet offsets, shading, pixel box, PSF, neighbouring scan lines) with the
//! sphere's section circle replaced by the straight line where the board plane meets the
//! plane `n . p = d + t`.
//!
//! On a plane the profile is symmetric only to first order: across the sheet's thickness
//! the incidence and the distance to the emitter change (the shading's gradient), and the
//! perspective maps equal steps of `t` to unequal steps in the image. Both skew the
//! profile by a few thousandths of a pixel on the paper's rig, and the skew has the same
//! sign in every view: the board's stripe points lie ~0.3-0.6 um off the sheet's centre
//! plane, which a one-stage adjustment turns into a ~1 um error of the hand-eye
//! translation ([`crate::pipeline`]'s stripe correction removes it).
//!
//! For sheet offset `t` the board's line is `P(s) = p0(t) + s e`, `e = n x n_b`
//! normalised, `p0(t) = alpha n + beta n_b` with `[1 c; c 1] [alpha beta]^T = [d + t,
//! d_b]^T` (`c = n . n_b`); Newton's method on `s` puts its image on the scan line, and
//! `d a / d t` follows from the implicit function theorem as for the sphere.

use nalgebra::Vector3;

use crate::model::geometry::Plane;

use super::profile::{
    project_jac, sample_lines, PointProfile, Rig, Section, Surface, NEWTON_LAST_STEP_PX,
};

/// The board (camera frame) as the model sees it: its plane, the direction of its line
/// with the sheet and `d p0 / d t`.
pub(crate) struct Board<'b> {
    plane: &'b Plane,
    e: Vector3<f64>,
    dp0_dt: Vector3<f64>,
    c: f64,
}

impl<'b> Board<'b> {
    /// `None` when the sheet is (nearly) parallel to the board.
    pub(crate) fn new(rig: &Rig<'_>, plane: &'b Plane) -> Option<Board<'b>> {
        let c = rig.n.dot(&plane.normal);
        let e = rig.n.cross(&plane.normal);
        if e.norm() < 1e-3 {
            return None;
        }
        let det = 1.0 - c * c;
        let dp0_dt = (rig.n - plane.normal * c) / det;
        Some(Board {
            plane,
            e: e.normalize(),
            dp0_dt,
            c,
        })
    }

    fn p0(&self, rig: &Rig<'_>, t: f64) -> Vector3<f64> {
        let (a, b) = (rig.d + t, self.plane.d);
        let det = 1.0 - self.c * self.c;
        rig.n * ((a - self.c * b) / det) + self.plane.normal * ((b - self.c * a) / det)
    }

    /// The board point on the sheet's centre plane imaged on scan line `line`, started at
    /// the point nearest `p_near`.
    fn on_line(&self, rig: &Rig<'_>, line: f64, p_near: &Vector3<f64>) -> Option<Section> {
        let s_near = (p_near - self.p0(rig, 0.0)).dot(&self.e);
        self.point(rig, 0.0, line, s_near)
    }

    /// The board point on the sheet offset `t` imaged on scan line `line`, by Newton's
    /// method along the board's line from `s0`.
    fn point(&self, rig: &Rig<'_>, t: f64, line: f64, s0: f64) -> Option<Section> {
        let (al, li) = (rig.along, 1 - rig.along);
        let p0 = self.p0(rig, t);
        let mut s = s0;
        for it in 0..30 {
            let p = p0 + self.e * s;
            let (uv, j) = project_jac(rig.camera, &p)?;
            let jl = j.row(li);
            let ja = j.row(al);
            let f = uv[li] - line;
            let df = jl.dot(&self.e.transpose());
            if df.is_nan() || df.abs() <= 1e-12 {
                return None;
            }
            if f.abs() < NEWTON_LAST_STEP_PX {
                // The last step taken linearly (as the sphere's section does).
                let last = -f / df;
                let ds_dt = -jl.dot(&self.dp0_dt.transpose()) / df;
                let dp_dt = self.dp0_dt + self.e * ds_dt;
                let da_dt = ja.dot(&dp_dt.transpose());
                let da_ds = ja.dot(&self.e.transpose());
                return Some(Section {
                    phi: s + last,
                    dphi_dt: ds_dt,
                    p: p + self.e * last,
                    dp_dt,
                    a: uv[al] + da_ds * last,
                    da_dt,
                    slope: da_ds / df,
                });
            }
            if it == 29 {
                return None;
            }
            s -= (f / df).clamp(-50.0, 50.0);
        }
        None
    }
}

impl Surface for Board<'_> {
    fn section(&self, rig: &Rig<'_>, t: f64, line: f64, hint: f64) -> Option<Section> {
        self.point(rig, t, line, hint)
    }

    /// Seen by the camera, lit by the emitter: `cos(incidence) / r_emitter`; else 0.
    fn shading(&self, rig: &Rig<'_>, p: &Vector3<f64>) -> f64 {
        // The normal on the camera's side.
        let nrm = if self.plane.normal.dot(p) > 0.0 {
            -self.plane.normal
        } else {
            self.plane.normal
        };
        let to_e = rig.emitter - p;
        let re = to_e.norm();
        let cos = nrm.dot(&to_e) / re;
        if cos <= 0.0 {
            return 0.0;
        }
        cos / re
    }
}

/// The local scale `|d a / d t|` (px per mm of sheet offset) and the stripe's slope
/// against the scan line at the point of scan line `line` near `p_near` (`None` where
/// the line cannot be followed).
pub(crate) fn board_point_scale(
    rig: &Rig<'_>,
    board: &Board<'_>,
    line: f64,
    p_near: &Vector3<f64>,
) -> Option<(f64, f64)> {
    let l0 = board.on_line(rig, line, p_near)?;
    Some((l0.da_dt.abs(), l0.slope))
}

/// The samples of one stripe point of a board ([`super::profile::point_profile`]'s
/// counterpart): scan line `line`, near the camera-frame point `p_near`, sheet sigma
/// `sigma` (mm), PSF sigma `psf` (px). `false` when the scan line cannot be modelled.
pub(crate) fn board_point_profile(
    rig: &Rig<'_>,
    board: &Board<'_>,
    line: f64,
    p_near: &Vector3<f64>,
    sigma: f64,
    psf: f64,
    out: &mut PointProfile,
) -> bool {
    out.samples.clear();
    let Some(l0) = board.on_line(rig, line, p_near) else {
        return false;
    };
    let w00 = board.shading(rig, &l0.p);
    if w00 <= 0.0 || w00 * (rig.emitter - l0.p).norm() < rig.min_cos {
        return false;
    }
    out.a0 = l0.a;
    out.g = l0.da_dt.abs();
    out.slope = l0.slope;
    sample_lines(rig, board, line, l0.phi, sigma, psf, out);
    true
}
