//! `brown5`: the pinhole with OpenCV's five-coefficient Brown-Conrady distortion (the
//! contract's camera, spec/DATASET.md), the default [`super::CameraModel`].
//!
//! For normalised coordinates `(x, y)` and `r2 = x^2 + y^2`:
//!
//! ```text
//! radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
//! xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
//! yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y
//! ```
//!
//! Coefficients `[k1, k2, p1, p2, k3]` (OpenCV's order); [`super::DistortionModel`]
//! (`radial1`, `radial2`, `opencv5`) says which of them a calibration estimates.
//!
//! Besides the trait, the formula is here generic over the scalar (f64 for values, dual
//! numbers for the Jacobians of the camera calibration, the circle-centre models and the
//! joint adjustment): the one implementation of this model's distortion.

use nalgebra::{Matrix2, Matrix2xX, SMatrix};

use super::{CameraModel, DistortionModel};
use crate::numerics::dual::Scalar;

/// The model (registered as `brown5`).
#[derive(Debug, Clone, Copy, Default)]
pub struct Brown5;

/// Names of the distortion coefficients, in storage order.
pub const DISTORTION_NAMES: [&str; 5] = ["k1", "k2", "p1", "p2", "k3"];

impl CameraModel for Brown5 {
    fn name(&self) -> &'static str {
        "brown5"
    }

    fn distortion_names(&self) -> &'static [&'static str] {
        &DISTORTION_NAMES
    }

    fn distort(&self, k: &[f64], x: f64, y: f64) -> ((f64, f64), Matrix2<f64>) {
        let (d, j) = distort_generic(&coefficients(k), x, y);
        (
            (d[0], d[1]),
            Matrix2::new(j[0][0], j[0][1], j[1][0], j[1][1]),
        )
    }

    fn distortion_jacobian(&self, _k: &[f64], x: f64, y: f64) -> Matrix2xX<f64> {
        let dk = distortion_coefficient_jacobian(x, y);
        Matrix2xX::from_fn(5, |r, c| dk[(r, c)])
    }

    fn free_coefficients(&self, choice: DistortionModel) -> Vec<bool> {
        choice.free_coefficients().to_vec()
    }
}

/// The five coefficients of a slice (missing ones 0).
#[inline]
fn coefficients(k: &[f64]) -> [f64; 5] {
    std::array::from_fn(|i| k.get(i).copied().unwrap_or(0.0))
}

/// Distortion `[k1, k2, p1, p2, k3]` of normalised `(x, y)` and its Jacobian
/// `[[dxd/dx, dxd/dy], [dyd/dx, dyd/dy]]` (module docs for the formula).
///
/// With `k2 = p1 = p2 = k3 = 0` exactly (value and derivatives) it takes a k1-only path
/// that performs the same operations minus the vanishing terms: the same values bit for
/// bit, at a fraction of the cost for dual numbers.
#[inline(always)]
pub fn distort_generic<T: Scalar>(k: &[T; 5], x: T, y: T) -> ([T; 2], [[T; 2]; 2]) {
    if k[1].is_zero() && k[2].is_zero() && k[3].is_zero() && k[4].is_zero() {
        distort_k1(k[0], x, y)
    } else {
        distort_full(k, x, y)
    }
}

/// [`distort_generic`] with `k2 = p1 = p2 = k3 = 0` (`radial1`): the same operations
/// without the terms that vanish, so the same values bit for bit.
#[inline(always)]
fn distort_k1<T: Scalar>(k1: T, x: T, y: T) -> ([T; 2], [[T; 2]; 2]) {
    let one = T::from_f64(1.0);
    let r2 = x * x + y * y;
    let radial = one + r2 * k1;
    let dradial = k1;
    let xy = x * y;
    let xd = x * radial;
    let yd = y * radial;
    let cross = (xy * dradial).scale(2.0);
    let j00 = radial + (x * x * dradial).scale(2.0);
    let j11 = radial + (y * y * dradial).scale(2.0);
    ([xd, yd], [[j00, cross], [cross, j11]])
}

/// The full five-coefficient formula of [`distort_generic`].
#[inline(always)]
fn distort_full<T: Scalar>(k: &[T; 5], x: T, y: T) -> ([T; 2], [[T; 2]; 2]) {
    let [k1, k2, p1, p2, k3] = *k;
    let one = T::from_f64(1.0);
    let r2 = x * x + y * y;
    let radial = one + r2 * (k1 + r2 * (k2 + r2 * k3));
    let dradial = k1 + r2 * (k2.scale(2.0) + k3.scale(3.0) * r2);
    let xy = x * y;
    let xd = x * radial + p1.scale(2.0) * xy + p2 * (r2 + (x * x).scale(2.0));
    let yd = y * radial + p1 * (r2 + (y * y).scale(2.0)) + p2.scale(2.0) * xy;
    let cross = (xy * dradial + p1 * x + p2 * y).scale(2.0);
    let j00 = radial + (x * x * dradial).scale(2.0) + (p1 * y).scale(2.0) + (p2 * x).scale(6.0);
    let j11 = radial + (y * y * dradial).scale(2.0) + (p1 * y).scale(6.0) + (p2 * x).scale(2.0);
    ([xd, yd], [[j00, cross], [cross, j11]])
}

/// `d(xd, yd) / d(k1, k2, p1, p2, k3)` at normalised `(xn, yn)` (the distortion is
/// linear in its coefficients, so this does not depend on them).
#[inline]
pub fn distortion_coefficient_jacobian(xn: f64, yn: f64) -> SMatrix<f64, 2, 5> {
    let r2 = xn * xn + yn * yn;
    let r4 = r2 * r2;
    SMatrix::<f64, 2, 5>::new(
        xn * r2,
        xn * r4,
        2.0 * xn * yn,
        r2 + 2.0 * xn * xn,
        xn * r4 * r2,
        yn * r2,
        yn * r4,
        r2 + 2.0 * yn * yn,
        2.0 * xn * yn,
        yn * r4 * r2,
    )
}

/// The distortion coefficients of a parameter vector in [`super::PARAM_NAMES`] order.
#[inline]
pub fn distortion_of<T: Scalar>(cam: &[T; 9]) -> [T; 5] {
    [cam[4], cam[5], cam[6], cam[7], cam[8]]
}

/// Pixel of distorted normalised coordinates `d`: `(fu xd + u0, fv yd + v0)`, `cam` in
/// [`super::PARAM_NAMES`] order.
#[inline]
pub fn to_pixel_generic<T: Scalar>(cam: &[T; 9], d: [T; 2]) -> [T; 2] {
    [cam[0] * d[0] + cam[2], cam[1] * d[1] + cam[3]]
}

/// Pinhole projection with distortion of a camera-frame point `p` (no check that it is
/// in front: see [`super::Camera::normalize`]), `cam` in [`super::PARAM_NAMES`] order.
#[inline]
pub fn project_generic<T: Scalar>(cam: &[T; 9], p: &[T; 3]) -> [T; 2] {
    let x = p[0] / p[2];
    let y = p[1] / p[2];
    let (d, _) = distort_generic(&distortion_of(cam), x, y);
    to_pixel_generic(cam, d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::dual::Dual;

    #[test]
    fn k1_only_distortion_equals_the_full_formula_bit_for_bit() {
        for k1 in [-0.31, 0.0, 0.05] {
            for (x, y) in [(0.0, 0.0), (0.3, -0.2), (-0.45, 0.37), (1e-9, 2.0)] {
                let k = [k1, 0.0, 0.0, 0.0, 0.0];
                assert_eq!(distort_generic(&k, x, y), distort_full(&k, x, y));
                // Duals: a varying k1, constant zero others, varying point.
                type D = Dual<3>;
                let kd = [
                    D::var(k1, 0),
                    D::cst(0.0),
                    D::cst(0.0),
                    D::cst(0.0),
                    D::cst(0.0),
                ];
                let (xd, yd) = (D::var(x, 1), D::var(y, 2));
                assert_eq!(distort_generic(&kd, xd, yd), distort_full(&kd, xd, yd));
            }
        }
        // A varying zero coefficient is not "absent": the full formula is used.
        let kd = [
            Dual::<2>::var(0.1, 0),
            Dual::var(0.0, 1),
            Dual::cst(0.0),
            Dual::cst(0.0),
            Dual::cst(0.0),
        ];
        let (d, _) = distort_generic(&kd, Dual::cst(0.3), Dual::cst(0.4));
        assert!(d[0].d[1] != 0.0, "d xd / d k2 must be r^4 x");
    }
}
