//! The imaged centre of a board circle: bias-free (conic) models and the naive one.
//!
//! ## Why
//!
//! A circle of radius `r` centred at `c` on the board plane images (before distortion,
//! on the normalised image plane) as an ellipse whose centre is NOT the projection of
//! `c`; distortion then bends the ellipse, and the centroid of the bent region is not the
//! distortion of the ellipse's centre either. Detectors measure the centroid of the
//! imaged region, so an adjustment that predicts the projected circle centre is biased.
//!
//! ## Models ([`CentreModel`])
//!
//! - `Naive`: distortion of the projected circle centre (for comparison).
//! - `Conic`: distortion of the centre `e` of the projected conic (first order).
//! - `ConicExact` (the default): the area centroid of the distorted ellipse
//!   `D(E)`, by Green's theorem on its boundary `D(e + L (cos t, sin t))`
//!   (`L L^T = Q`): `cx = (closed integral of x^2 dy) / (closed integral of x dy - y dx)`,
//!   `cy = -(closed integral of y^2 dx) / (same)`. The integrands are trigonometric
//!   polynomials (the distortion is polynomial, of degree <= 7), so the trapezoidal rule
//!   with [`QUADRATURE_POINTS`] = 32 nodes integrates them EXACTLY (up to round-off):
//!   this is the exact centroid of the model's imaged circle, with no series truncation.
//!   It includes the "second-order distortion curvature" correction
//!   `J Sigma grad(det J)/det J + 1/2 H:Sigma` and all higher terms.
//!
//! ## The projected conic
//!
//! With `R = [h1 h2 h3]`, `t` (`T_cam_board`) and the circle centre in the camera frame
//! `p = R c + t`, the dual conic of the image of the circle (normalised coordinates) is
//! `C* = r^2 (h1 h1^T + h2 h2^T) - p p^T`. Its centre is
//! `e = (C*_02, C*_12) / C*_22` and its shape `Q = -C*[0..2, 0..2] / C*_22 + e e^T`, i.e.
//! the ellipse `{x : (x - e)^T Q^-1 (x - e) <= 1}` (second-moment matrix `Q / 4`).
//!
//! ## Jacobians
//!
//! Computed by forward-mode automatic differentiation ([`Dual`]), exact to round-off:
//! - w.r.t. the camera parameters, in [`crate::model::camera::PARAM_NAMES`] order;
//! - w.r.t. the pose as the 6-vector `delta = (w, v)` of the local parameterisation
//!   `R = R0 Exp(w)` (rotation increment on the RIGHT, i.e. about the board axes) and
//!   `t = t0 + v` (translation increment in the camera frame, mm). To chain: for a
//!   parameter `s` that moves `T_cam_board`, `dw/ds = vee(R0^T dR/ds)` and
//!   `dv/ds = dt/ds`.

use nalgebra::{Matrix2xX, Matrix3, SMatrix, Vector2, Vector3};

use crate::error::{Error, Result};
use crate::model::camera::{
    distort_generic, distortion_of, to_pixel_generic, Camera, DistortionModel,
};
use crate::model::geometry::Iso3;
use crate::numerics::dual::{Dual, Scalar};
use crate::numerics::mat3::{rot_times_exp_first_order, rows_f64};

/// Trapezoidal nodes of the exact centroid (exact for trigonometric polynomials of
/// degree < 32; the integrands have degree <= 21).
pub const QUADRATURE_POINTS: usize = 32;

/// How the imaged centre of a circle is predicted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CentreModel {
    /// Projection (with distortion) of the circle's centre: biased, for comparison.
    Naive,
    /// Distortion of the projected conic's centre (bias-free up to distortion curvature).
    Conic,
    /// Exact area centroid of the distorted projected ellipse.
    #[default]
    ConicExact,
}

impl CentreModel {
    /// `naive`, `conic`, `conic-exact`.
    pub fn name(self) -> &'static str {
        match self {
            CentreModel::Naive => "naive",
            CentreModel::Conic => "conic",
            CentreModel::ConicExact => "conic-exact",
        }
    }
}

// ---------------------------------------------------------------------------------
// The exact centroid over f64 and dual numbers.

/// A [`Scalar`] the centre models run on: it knows how to take the exact centroid's
/// offset (see [`centroid_offset`]). Duals differentiate it through a small inner dual
/// over the inputs that vary (the five ellipse parameters and the varying distortion
/// coefficients), then chain: the quadrature loop runs on at most 10 derivatives
/// whatever `N`.
pub trait CentreScalar: Scalar {
    /// The exact centroid's offset from `d = D(e)`.
    fn centroid_offset(
        k: &[Self; 5],
        e: &[Self; 5],
        d: &[Self; 2],
        table: &[(f64, f64)],
    ) -> [Self; 2];
}

impl CentreScalar for f64 {
    fn centroid_offset(k: &[f64; 5], e: &[f64; 5], d: &[f64; 2], table: &[(f64, f64)]) -> [f64; 2] {
        centroid_offset(k, e, d, table)
    }
}

impl<const N: usize> CentreScalar for Dual<N> {
    /// `D(e)` is recomputed from the inner duals (so the offset's derivatives carry its
    /// dependence on the origin); the caller's `d` is not needed.
    fn centroid_offset(
        k: &[Self; 5],
        e: &[Self; 5],
        _d: &[Self; 2],
        table: &[(f64, f64)],
    ) -> [Self; 2] {
        // Inputs: the ellipse (always varying), then the coefficients that vary.
        let mut inputs: [Self; 10] = [Dual::cst(0.0); 10];
        inputs[..5].copy_from_slice(e);
        let mut q = 5;
        let mut k_var = [false; 5];
        for (i, ki) in k.iter().enumerate() {
            if ki.d.iter().any(|x| *x != 0.0) {
                k_var[i] = true;
                inputs[q] = *ki;
                q += 1;
            }
        }
        match q {
            5 => chained_offset::<N, 5>(k, &k_var, &inputs, table),
            6 => chained_offset::<N, 6>(k, &k_var, &inputs, table),
            7 => chained_offset::<N, 7>(k, &k_var, &inputs, table),
            8 => chained_offset::<N, 8>(k, &k_var, &inputs, table),
            9 => chained_offset::<N, 9>(k, &k_var, &inputs, table),
            _ => chained_offset::<N, 10>(k, &k_var, &inputs, table),
        }
    }
}

/// [`centroid_offset`] of dual inputs through an inner `Dual<M>` over the `M` varying
/// inputs (`inputs[..M]`: the ellipse, then the coefficients flagged in `k_var`).
fn chained_offset<const N: usize, const M: usize>(
    k: &[Dual<N>; 5],
    k_var: &[bool; 5],
    inputs: &[Dual<N>; 10],
    table: &[(f64, f64)],
) -> [Dual<N>; 2] {
    let e: [Dual<M>; 5] = std::array::from_fn(|i| Dual::var(inputs[i].v, i));
    let mut q = 5;
    let ki: [Dual<M>; 5] = std::array::from_fn(|i| {
        if k_var[i] {
            q += 1;
            Dual::var(k[i].v, q - 1)
        } else {
            Dual::cst(k[i].v)
        }
    });
    let (dc, _) = distort_generic(&ki, e[0], e[1]);
    let off = centroid_offset(&ki, &e, &dc, table);
    std::array::from_fn(|a| {
        let mut d = [0.0; N];
        for (j, inp) in inputs.iter().take(M).enumerate() {
            let g = off[a].d[j];
            for (o, x) in d.iter_mut().zip(&inp.d) {
                *o += g * x;
            }
        }
        Dual { v: off[a].v, d }
    })
}

// ---------------------------------------------------------------------------------
// Generic model.

/// Predicted imaged centre (pixels) of a circle, generic over the scalar type.
///
/// `cam`: `[fu, fv, u0, v0, k1, k2, p1, p2, k3]`; `rot`, `t`: `T_cam_board`;
/// `centre`: the circle centre on the board (z = 0), `radius` in mm; radius 0 is a
/// point target (a chessboard corner), predicted by its projection whatever `model`.
pub fn centre_generic<T: CentreScalar>(
    cam: &[T; 9],
    rot: &[[T; 3]; 3],
    t: &[T; 3],
    centre: (f64, f64),
    radius: f64,
    model: CentreModel,
) -> Result<[T; 2]> {
    centre_generic_n(cam, rot, t, centre, radius, model, QUADRATURE_POINTS)
}

/// Trapezoidal nodes that integrate the exact centroid's integrands exactly for a
/// distortion model: the distorted boundary has degree 3 (`radial1`: k1 and, at most,
/// the tangential terms), 5 (`radial2`) or 7 (`opencv5`, k3) in `(cos t, sin t)`, the
/// integrands `3 x` that, so `N > 9, 15, 21` nodes are exact: 12, 16, 24.
pub fn quadrature_nodes(model: DistortionModel) -> usize {
    match model {
        DistortionModel::Radial1 => 12,
        DistortionModel::Radial2 => 16,
        DistortionModel::OpenCv5 => 24,
    }
}

/// `(sin, cos)` of the `nodes` equally spaced angles (cached for the counts in use).
fn node_table(nodes: usize) -> std::borrow::Cow<'static, [(f64, f64)]> {
    use std::sync::OnceLock;
    fn make(nodes: usize) -> Vec<(f64, f64)> {
        (0..nodes)
            .map(|n| (std::f64::consts::TAU * n as f64 / nodes as f64).sin_cos())
            .collect()
    }
    static T12: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    static T16: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    static T24: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    static T32: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    let cell = match nodes {
        12 => &T12,
        16 => &T16,
        24 => &T24,
        32 => &T32,
        n => return std::borrow::Cow::Owned(make(n)),
    };
    std::borrow::Cow::Borrowed(cell.get_or_init(|| make(nodes)).as_slice())
}

/// Offset of the area centroid of the distorted ellipse `D(E)` from `d = D(e)`:
/// `E = {e + L (cos t, sin t)}`, `e = (e[0], e[1])`, `L = [[e[2], 0], [e[3], e[4]]]`, by
/// Green's theorem on the boundary with the trapezoidal nodes `table` of `(sin, cos)`
/// (module docs). Coordinates relative to `d` keep the round-off small.
pub fn centroid_offset<T: Scalar>(
    k: &[T; 5],
    e: &[T; 5],
    d: &[T; 2],
    table: &[(f64, f64)],
) -> [T; 2] {
    let [ex, ey, l00, l10, l11] = *e;
    let zero = T::from_f64(0.0);
    let (mut a, mut mx, mut my) = (zero, zero, zero);
    for &(s, c) in table.iter() {
        let x = ex + l00.scale(c);
        let y = ey + l10.scale(c) + l11.scale(s);
        // d(x, y)/dth
        let dx = l00.scale(-s);
        let dy = l10.scale(-s) + l11.scale(c);
        let (q, j) = distort_generic(k, x, y);
        let bx = q[0] - d[0];
        let by = q[1] - d[1];
        let tx = j[0][0] * dx + j[0][1] * dy;
        let ty = j[1][0] * dx + j[1][1] * dy;
        a = a + bx * ty - by * tx;
        mx = mx + bx * bx * ty;
        my = my - by * by * tx;
    }
    [mx / a, my / a]
}

/// [`centre_generic`] with `nodes` trapezoidal nodes for the exact centroid (see
/// [`quadrature_nodes`]: fewer than the model needs is inexact).
pub fn centre_generic_n<T: CentreScalar>(
    cam: &[T; 9],
    rot: &[[T; 3]; 3],
    t: &[T; 3],
    centre: (f64, f64),
    radius: f64,
    model: CentreModel,
    nodes: usize,
) -> Result<[T; 2]> {
    let k = distortion_of(cam);
    let (e, shape) = undistorted_image(rot, t, centre, radius, model)?;
    let (d, _) = distort_generic(&k, e[0], e[1]);
    let (xd, yd) = match shape {
        None => (d[0], d[1]),
        Some([l00, l10, l11]) => {
            let table = node_table(nodes);
            let off = T::centroid_offset(&k, &[e[0], e[1], l00, l10, l11], &d, &table);
            (d[0] + off[0], d[1] + off[1])
        }
    };
    let uv = to_pixel_generic(cam, [xd, yd]);
    if !(uv[0].value().is_finite() && uv[1].value().is_finite()) {
        let (cx, cy) = centre;
        return Err(Error::Degenerate(format!(
            "circle at board ({cx:.3}, {cy:.3}) images at a non-finite pixel"
        )));
    }
    Ok(uv)
}

/// The circle's image before distortion, in normalised coordinates: the projected
/// centre (`Naive`, and any point target: radius 0) or the projected conic's centre `e`
/// (`Conic`), with, for `ConicExact`, the factor `[l00, l10, l11]` of its shape
/// `Q = L L^T` (module docs). Errors as [`centre_generic_n`].
#[inline(always)]
#[allow(clippy::type_complexity)]
fn undistorted_image<T: Scalar>(
    rot: &[[T; 3]; 3],
    t: &[T; 3],
    centre: (f64, f64),
    radius: f64,
    model: CentreModel,
) -> Result<([T; 2], Option<[T; 3]>)> {
    // A point target (a chessboard corner, radius 0) images as its projection: no
    // perspective or distortion bias, and no conic to take the centre of.
    let model = if radius == 0.0 {
        CentreModel::Naive
    } else {
        model
    };
    let (cx, cy) = centre;
    // p = R c + t
    let p: [T; 3] = std::array::from_fn(|i| rot[i][0].scale(cx) + rot[i][1].scale(cy) + t[i]);
    if p[2].value().is_nan() || p[2].value() <= 0.0 {
        return Err(Error::Degenerate(format!(
            "circle at board ({cx:.3}, {cy:.3}) is not in front of the camera"
        )));
    }
    if model == CentreModel::Naive {
        return Ok(([p[0] / p[2], p[1] / p[2]], None));
    }
    let r2 = radius * radius;
    // dual conic entries
    let cs = |i: usize, j: usize| -> T {
        (rot[i][0] * rot[j][0] + rot[i][1] * rot[j][1]).scale(r2) - p[i] * p[j]
    };
    let c22 = cs(2, 2);
    if c22.value().is_nan() || c22.value() >= 0.0 {
        return Err(Error::Degenerate(format!(
            "circle at board ({cx:.3}, {cy:.3}) does not image as an ellipse \
             (it crosses the camera's focal plane)"
        )));
    }
    let ex = cs(0, 2) / c22;
    let ey = cs(1, 2) / c22;
    if model == CentreModel::Conic {
        return Ok(([ex, ey], None));
    }
    let q00 = -cs(0, 0) / c22 + ex * ex;
    let q01 = -cs(0, 1) / c22 + ex * ey;
    let q11 = -cs(1, 1) / c22 + ey * ey;
    if !(q00.value() > 0.0 && q00.value() * q11.value() - q01.value().powi(2) > 0.0) {
        return Err(Error::Degenerate(format!(
            "circle at board ({cx:.3}, {cy:.3}): projected conic is not an ellipse"
        )));
    }
    let l00 = q00.sqrt();
    let l10 = q01 / l00;
    let l11 = (q11 - l10 * l10).sqrt();
    Ok(([ex, ey], Some([l00, l10, l11])))
}

// ---------------------------------------------------------------------------------
// Any camera model: the model's distortion through its trait (f64).

/// [`centre_generic_n`] for a camera of any model ([`crate::model::camera::CameraModel`]:
/// its distortion and point Jacobian, in f64), `rot`, `t` being `T_cam_board`. The exact
/// centroid takes [`QUADRATURE_POINTS`] nodes (a model's distortion need not be
/// polynomial: the trapezoidal rule is then spectrally accurate, not exact).
pub fn centre_any_model(
    cam: &Camera,
    rot: &[[f64; 3]; 3],
    t: &[f64; 3],
    centre: (f64, f64),
    radius: f64,
    model: CentreModel,
) -> Result<[f64; 2]> {
    let (e, shape) = undistorted_image(rot, t, centre, radius, model)?;
    let ((dx, dy), _) = cam.distort_with_jacobian(e[0], e[1]);
    let (xd, yd) = match shape {
        None => (dx, dy),
        Some([l00, l10, l11]) => {
            let table = node_table(QUADRATURE_POINTS);
            let off = centroid_offset_any(cam, &[e[0], e[1], l00, l10, l11], &[dx, dy], &table);
            (dx + off[0], dy + off[1])
        }
    };
    let uv = cam.to_pixel(xd, yd);
    if !(uv.x.is_finite() && uv.y.is_finite()) {
        let (cx, cy) = centre;
        return Err(Error::Degenerate(format!(
            "circle at board ({cx:.3}, {cy:.3}) images at a non-finite pixel"
        )));
    }
    Ok([uv.x, uv.y])
}

/// [`centroid_offset`] through the camera's model (f64).
fn centroid_offset_any(cam: &Camera, e: &[f64; 5], d: &[f64; 2], table: &[(f64, f64)]) -> [f64; 2] {
    let [ex, ey, l00, l10, l11] = *e;
    let (mut a, mut mx, mut my) = (0.0, 0.0, 0.0);
    for &(s, c) in table.iter() {
        let x = ex + l00 * c;
        let y = ey + l10 * c + l11 * s;
        let dx = -l00 * s;
        let dy = -l10 * s + l11 * c;
        let ((qx, qy), j) = cam.distort_with_jacobian(x, y);
        let bx = qx - d[0];
        let by = qy - d[1];
        let tx = j[(0, 0)] * dx + j[(0, 1)] * dy;
        let ty = j[(1, 0)] * dx + j[(1, 1)] * dy;
        a += bx * ty - by * tx;
        mx += bx * bx * ty;
        my -= by * by * tx;
    }
    [mx / a, my / a]
}

/// [`centre_any_model`] with its Jacobians: d(u, v)/d(camera parameters) (2 x the
/// model's parameter count, [`crate::model::camera::CameraModel::param_names`] order)
/// and d(u, v)/d(delta) for the pose increment `delta = (w, v)` (module docs) at the pose
/// `(r0, t0)`. The `Naive` and `Conic` models, and point targets with any: the exact
/// centroid's derivatives need the model's second derivatives, which the trait does not
/// give ([`Error::InvalidInput`]).
pub fn centre_any_model_with_jacobians(
    cam: &Camera,
    r0: &Matrix3<f64>,
    t0: &[f64; 3],
    centre: (f64, f64),
    radius: f64,
    model: CentreModel,
) -> Result<(Vector2<f64>, Matrix2xX<f64>, SMatrix<f64, 2, 6>)> {
    type D = Dual<6>;
    let w: [D; 3] = std::array::from_fn(|i| D::var(0.0, i));
    let rot = rot_times_exp_first_order(r0, &w);
    let t: [D; 3] = std::array::from_fn(|i| D::var(t0[i], 3 + i));
    let (e, shape) = undistorted_image(&rot, &t, centre, radius, model)?;
    if shape.is_some() {
        return Err(Error::InvalidInput(format!(
            "the {} centre model needs brown5's camera (camera model {}): choose the conic \
             or naive centre model, or a target of points",
            model.name(),
            cam.projection.name()
        )));
    }
    let (xn, yn) = (e[0].v, e[1].v);
    let (uv, jp, jc) = cam.project_with_jacobians(&Vector3::new(xn, yn, 1.0))?;
    // d(u, v)/d(xn, yn) is d(u, v)/d(point) at z = 1 (its first two columns).
    let de = SMatrix::<f64, 2, 6>::from_fn(|a, i| e[a].d[i]);
    let d_pose = jp.fixed_view::<2, 2>(0, 0) * de;
    Ok((uv, jc, d_pose))
}

// ---------------------------------------------------------------------------------
// Public f64 API.

/// A predicted centre with its Jacobians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CentrePrediction {
    /// Predicted imaged centre, px.
    pub uv: Vector2<f64>,
    /// d(u, v)/d(camera parameters), columns in [`crate::model::camera::PARAM_NAMES`] order.
    pub d_camera: SMatrix<f64, 2, 9>,
    /// d(u, v)/d(delta), `delta = (w, v)`: `R = R0 Exp(w)`, `t = t0 + v` (module docs).
    pub d_pose: SMatrix<f64, 2, 6>,
}

/// Predicted imaged centre (px) of the board circle centred at `centre` (board frame,
/// z = 0) with `radius` mm, seen from the pose `cam_board` (`T_cam_board`).
pub fn predict_centre(
    cam: &Camera,
    cam_board: &Iso3,
    centre: &Vector3<f64>,
    radius: f64,
    model: CentreModel,
) -> Result<Vector2<f64>> {
    let r = cam_board.rotation.to_rotation_matrix().into_inner();
    let t = cam_board.translation.vector;
    if !cam.projection.is_brown5() {
        let uv = centre_any_model(
            cam,
            &rows_f64(&r),
            &[t.x, t.y, t.z],
            (centre.x, centre.y),
            radius,
            model,
        )?;
        return Ok(Vector2::new(uv[0], uv[1]));
    }
    let uv = centre_generic(
        &cam.params(),
        &rows_f64(&r),
        &[t.x, t.y, t.z],
        (centre.x, centre.y),
        radius,
        model,
    )?;
    Ok(Vector2::new(uv[0], uv[1]))
}

/// [`predict_centre`] with the Jacobians w.r.t. the camera parameters and the pose
/// increment `delta = (w, v)` (module docs).
pub fn predict_centre_with_jacobians(
    cam: &Camera,
    cam_board: &Iso3,
    centre: &Vector3<f64>,
    radius: f64,
    model: CentreModel,
) -> Result<CentrePrediction> {
    if !cam.projection.is_brown5() {
        return Err(Error::InvalidInput(format!(
            "predict_centre_with_jacobians takes brown5's 9 parameters, not camera model {}'s \
             (centre_any_model_with_jacobians does)",
            cam.projection.name()
        )));
    }
    type D = Dual<15>;
    let r0 = cam_board.rotation.to_rotation_matrix().into_inner();
    let t0 = cam_board.translation.vector;
    let p = cam.params();
    let camd: [D; 9] = std::array::from_fn(|i| D::var(p[i], i));
    let w: [D; 3] = std::array::from_fn(|i| D::var(0.0, 9 + i));
    let rot = rot_times_exp_first_order(&r0, &w);
    let t: [D; 3] = std::array::from_fn(|i| D::var(t0[i], 12 + i));
    let uv = centre_generic(&camd, &rot, &t, (centre.x, centre.y), radius, model)?;
    let mut d_camera = SMatrix::<f64, 2, 9>::zeros();
    let mut d_pose = SMatrix::<f64, 2, 6>::zeros();
    for a in 0..2 {
        for i in 0..9 {
            d_camera[(a, i)] = uv[a].d[i];
        }
        for i in 0..6 {
            d_pose[(a, i)] = uv[a].d[9 + i];
        }
    }
    Ok(CentrePrediction {
        uv: Vector2::new(uv[0].v, uv[1].v),
        d_camera,
        d_pose,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::camera::DistortionModel;
    use crate::model::geometry::{iso_from_rotvec, rotvec_to_matrix};

    fn cams() -> Vec<Camera> {
        let base = Camera::new(
            1024,
            768,
            crate::model::camera::Intrinsics {
                fu: 900.0,
                fv: 900.5,
                u0: 515.3,
                v0: 380.8,
            },
            DistortionModel::OpenCv5,
            [-0.25, 0.12, 1e-3, -2e-3, 0.01],
        )
        .unwrap();
        vec![
            base.clone(),
            Camera {
                distortion: [0.0002, 0.0, 0.0, 0.0, 0.0],
                ..base
            },
        ]
    }

    fn pose() -> Iso3 {
        iso_from_rotvec(
            &Vector3::new(0.3, -0.25, 0.4),
            &Vector3::new(-20.0, -10.0, 100.0),
        )
    }

    /// Exact centroid by brute force: dense polygon of the distorted outline.
    fn brute_centroid(cam: &Camera, t: &Iso3, c: &Vector3<f64>, r: f64) -> Vector2<f64> {
        let n = 20000;
        let pts: Vec<Vector2<f64>> = (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                let pb = nalgebra::Point3::new(c.x + r * a.cos(), c.y + r * a.sin(), 0.0);
                cam.project(&(t * pb).coords).unwrap()
            })
            .collect();
        let o = pts[0];
        let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
        for i in 0..n {
            let p = pts[i] - o;
            let q = pts[(i + 1) % n] - o;
            let cr = p.x * q.y - q.x * p.y;
            a += cr;
            cx += (p.x + q.x) * cr;
            cy += (p.y + q.y) * cr;
        }
        Vector2::new(o.x + cx / (3.0 * a), o.y + cy / (3.0 * a))
    }

    #[test]
    fn exact_model_matches_brute_force_centroid() {
        for cam in cams() {
            let t = pose();
            for c in [Vector3::new(0.0, 0.0, 0.0), Vector3::new(50.0, 35.0, 0.0)] {
                let want = brute_centroid(&cam, &t, &c, 1.75);
                let got = predict_centre(&cam, &t, &c, 1.75, CentreModel::ConicExact).unwrap();
                assert!((got - want).norm() < 2e-6, "{got} vs {want}");
                let naive = predict_centre(&cam, &t, &c, 1.75, CentreModel::Naive).unwrap();
                let conic = predict_centre(&cam, &t, &c, 1.75, CentreModel::Conic).unwrap();
                // the models differ by measurable amounts
                assert!((naive - want).norm() > 1e-3);
                assert!((conic - want).norm() < (naive - want).norm());
            }
        }
    }

    #[test]
    fn jacobians_match_central_differences() {
        for cam in cams() {
            let t0 = pose();
            let c = Vector3::new(35.0, 20.0, 0.0);
            for model in [
                CentreModel::Naive,
                CentreModel::Conic,
                CentreModel::ConicExact,
            ] {
                let pr = predict_centre_with_jacobians(&cam, &t0, &c, 1.25, model).unwrap();
                let f = |cm: &Camera, t: &Iso3| predict_centre(cm, t, &c, 1.25, model).unwrap();
                assert!((pr.uv - f(&cam, &t0)).norm() < 1e-12);
                let p = cam.params();
                for i in 0..9 {
                    let h = 1e-4 * p[i].abs().max(1.0);
                    let (mut a, mut b) = (p, p);
                    a[i] += h;
                    b[i] -= h;
                    let fd =
                        (f(&cam.with_params(&a), &t0) - f(&cam.with_params(&b), &t0)) / (2.0 * h);
                    let an = pr.d_camera.column(i);
                    let err = (fd - an).norm();
                    assert!(
                        err <= 1e-6 * an.norm().max(1.0),
                        "{model:?} param {i}: fd {fd} an {an}"
                    );
                }
                let r0 = t0.rotation.to_rotation_matrix().into_inner();
                for i in 0..6 {
                    let h = if i < 3 { 1e-6 } else { 1e-5 };
                    let step = |s: f64| {
                        let mut d = [0.0; 6];
                        d[i] = s;
                        let r = r0 * rotvec_to_matrix(&Vector3::new(d[0], d[1], d[2]));
                        let t = t0.translation.vector + Vector3::new(d[3], d[4], d[5]);
                        crate::model::geometry::iso_from_parts(&r, &t)
                    };
                    let fd = (f(&cam, &step(h)) - f(&cam, &step(-h))) / (2.0 * h);
                    let an = pr.d_pose.column(i);
                    let err = (fd - an).norm();
                    assert!(
                        err <= 1e-6 * an.norm().max(1.0),
                        "{model:?} pose {i}: fd {fd} an {an}"
                    );
                }
            }
        }
    }

    #[test]
    fn circle_behind_camera_is_an_error() {
        let cam = &cams()[0];
        let t = iso_from_rotvec(&Vector3::zeros(), &Vector3::new(0.0, 0.0, -5.0));
        for m in [
            CentreModel::Naive,
            CentreModel::Conic,
            CentreModel::ConicExact,
        ] {
            assert!(predict_centre(cam, &t, &Vector3::zeros(), 1.0, m).is_err());
        }
    }
}
