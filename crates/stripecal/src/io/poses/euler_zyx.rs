//! The product `R = Rz(a) * Ry(b) * Rx(c)` of elementary rotations about the fixed base
//! axes (x by `c` first, then y by `b`, then z by `a`; equivalently z, then the new y,
//! then the newest x), shared by KUKA's A, B, C and Fanuc's W, P, R, which differ only in
//! what they call the three angles:
//!
//! ```text
//!     | ca cb   ca sb sc - sa cc   ca sb cc + sa sc |
//! R = | sa cb   sa sb sc + ca cc   sa sb cc - ca sc |
//!     | -sb     cb sc              cb cc            |
//! ```
//!
//! Back from a matrix (as the KRL routine `mat_to_rot` quoted on robot-forum.com does):
//! `a = atan2(r21, r11)`, then `M = Rz(-a) R = Ry(b) Rx(c)` gives
//! `b = atan2(-r31, ca r11 + sa r21)` in `[-90, 90]` deg and
//! `c = atan2(sa r13 - ca r23, ca r22 - sa r12)`. Taking `c` from `a` (rather than
//! `atan2(r32, r33)` on its own) keeps the angles consistent near the gimbal lock
//! `b = ±90` deg, where only `c - a` (`b = 90`) or `c + a` (`b = -90`) is defined: there
//! `r11 = r21 = 0`, `a` comes out as whatever `atan2` makes of the rounding (often 0) and
//! `c` takes the rest, so the matrix always round-trips.

use nalgebra::{UnitQuaternion, Vector3};

/// `Rz(a) * Ry(b) * Rx(c)`, angles in radians.
pub(super) fn to_rotation(a: f64, b: f64, c: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a)
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), b)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), c)
}

/// `(a, b, c)` in radians with `R = Rz(a) * Ry(b) * Rx(c)`, `b` in `[-pi/2, pi/2]`,
/// `a` and `c` in `[-pi, pi]`.
pub(super) fn from_rotation(q: &UnitQuaternion<f64>) -> (f64, f64, f64) {
    let m = q.to_rotation_matrix().into_inner();
    let a = m[(1, 0)].atan2(m[(0, 0)]);
    let (sa, ca) = a.sin_cos();
    let b = (-m[(2, 0)]).atan2(ca * m[(0, 0)] + sa * m[(1, 0)]);
    let c = (sa * m[(0, 2)] - ca * m[(1, 2)]).atan2(ca * m[(1, 1)] - sa * m[(0, 1)]);
    (a, b, c)
}
