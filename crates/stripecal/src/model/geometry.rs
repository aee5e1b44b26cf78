//! Rigid-body geometry: rotation vectors, rigid transforms, nearest rotation, planes.
//!
//! ## Conventions
//!
//! A rotation vector `r` is the rotation axis times the angle in radians
//! (Rodrigues). `rotvec_to_matrix` and `matrix_to_rotvec` are inverse of each other
//! for angles in `[0, pi]`, and both stay accurate near 0 (Taylor series) and near pi
//! (the axis is taken from the quaternion, not from the antisymmetric part).
//!
//! Rigid transforms are [`Iso3`] (nalgebra's `Isometry3<f64>`): `T_a_b * p_b = p_a`.

use nalgebra::{Matrix3, Matrix4, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::error::{Error, Result};

/// A rigid transform (rotation then translation), `p_a = T_a_b * p_b`.
pub type Iso3 = nalgebra::Isometry3<f64>;

/// The largest rotation-vector angle the file readers accept (radians): far beyond any
/// real rotation vector (a controller's, a calibration's), and small enough for the
/// angle and the axis to be computed without overflow (`norm` squares the components,
/// which overflows beyond ~1e154 and turns the axis into NaN).
pub(crate) const MAX_ROTVEC_ANGLE_RAD: f64 = 1e6;

/// The rotation matrix of a rotation vector (axis times angle, radians).
pub fn rotvec_to_matrix(r: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = r.norm_squared();
    let theta = theta2.sqrt();
    let k = r.cross_matrix();
    // R = I + a K + b K^2 with a = sin(t)/t, b = (1 - cos(t))/t^2.
    let (a, b) = if theta < 1e-4 {
        (
            1.0 - theta2 / 6.0 + theta2 * theta2 / 120.0,
            0.5 - theta2 / 24.0 + theta2 * theta2 / 720.0,
        )
    } else {
        (theta.sin() / theta, (1.0 - theta.cos()) / theta2)
    };
    Matrix3::identity() + k * a + k * k * b
}

/// The rotation vector (angle in `[0, pi]`) of a rotation matrix.
///
/// The matrix is assumed orthonormal with determinant +1; use [`nearest_rotation`]
/// first on a noisy matrix.
pub fn matrix_to_rotvec(m: &Matrix3<f64>) -> Vector3<f64> {
    let q = quaternion_from_matrix(m);
    quaternion_to_rotvec(&q)
}

/// Rotation vector of a unit quaternion, angle in `[0, pi]`.
pub fn quaternion_to_rotvec(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let (mut w, mut v) = (q.w, q.imag());
    if w < 0.0 {
        w = -w;
        v = -v;
    }
    let s = v.norm();
    if s < 1e-12 {
        // angle = 2 atan2(s, w) ~ 2 s / w: scale 2/w (w ~ 1 here).
        return v * (2.0 / w);
    }
    let angle = 2.0 * s.atan2(w);
    v * (angle / s)
}

/// Unit quaternion of a rotation matrix (Shepperd's method: accurate for every angle).
pub fn quaternion_from_matrix(m: &Matrix3<f64>) -> UnitQuaternion<f64> {
    let tr = m[(0, 0)] + m[(1, 1)] + m[(2, 2)];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        Quaternion::new(
            0.25 * s,
            (m[(2, 1)] - m[(1, 2)]) / s,
            (m[(0, 2)] - m[(2, 0)]) / s,
            (m[(1, 0)] - m[(0, 1)]) / s,
        )
    } else if m[(0, 0)] > m[(1, 1)] && m[(0, 0)] > m[(2, 2)] {
        let s = (1.0 + m[(0, 0)] - m[(1, 1)] - m[(2, 2)]).sqrt() * 2.0;
        Quaternion::new(
            (m[(2, 1)] - m[(1, 2)]) / s,
            0.25 * s,
            (m[(0, 1)] + m[(1, 0)]) / s,
            (m[(0, 2)] + m[(2, 0)]) / s,
        )
    } else if m[(1, 1)] > m[(2, 2)] {
        let s = (1.0 + m[(1, 1)] - m[(0, 0)] - m[(2, 2)]).sqrt() * 2.0;
        Quaternion::new(
            (m[(0, 2)] - m[(2, 0)]) / s,
            (m[(0, 1)] + m[(1, 0)]) / s,
            0.25 * s,
            (m[(1, 2)] + m[(2, 1)]) / s,
        )
    } else {
        let s = (1.0 + m[(2, 2)] - m[(0, 0)] - m[(1, 1)]).sqrt() * 2.0;
        Quaternion::new(
            (m[(1, 0)] - m[(0, 1)]) / s,
            (m[(0, 2)] + m[(2, 0)]) / s,
            (m[(1, 2)] + m[(2, 1)]) / s,
            0.25 * s,
        )
    };
    UnitQuaternion::from_quaternion(q)
}

/// The rotation closest to `m` in the Frobenius norm (SVD, determinant forced to +1).
pub fn nearest_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    // Both factors are requested above, so they are present.
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    let d = (u * vt).determinant().signum();
    let s = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, if d == 0.0 { 1.0 } else { d }));
    u * s * vt
}

/// A rigid transform from a rotation vector (radians) and a translation.
pub fn iso_from_rotvec(r: &Vector3<f64>, t: &Vector3<f64>) -> Iso3 {
    let rot = Rotation3::from_matrix_unchecked(rotvec_to_matrix(r));
    Iso3::from_parts(
        Translation3::from(*t),
        UnitQuaternion::from_rotation_matrix(&rot),
    )
}

/// The rotation vector (radians) and translation of a rigid transform.
pub fn iso_to_rotvec(t: &Iso3) -> (Vector3<f64>, Vector3<f64>) {
    (quaternion_to_rotvec(&t.rotation), t.translation.vector)
}

/// A rigid transform from a rotation matrix and a translation.
pub fn iso_from_parts(r: &Matrix3<f64>, t: &Vector3<f64>) -> Iso3 {
    Iso3::from_parts(Translation3::from(*t), quaternion_from_matrix(r))
}

/// The homogeneous 4x4 matrix of a rigid transform.
pub fn iso_to_matrix(t: &Iso3) -> Matrix4<f64> {
    t.to_homogeneous()
}

/// A rigid transform from a homogeneous 4x4 matrix; errors when the matrix is not rigid
/// (rotation part not orthonormal to `tol`, determinant not +1, last row not `0 0 0 1`)
/// or `tol` is not a finite non-negative number.
pub fn iso_from_matrix(m: &Matrix4<f64>, tol: f64) -> Result<Iso3> {
    if !(tol.is_finite() && tol >= 0.0) {
        return Err(Error::InvalidInput(format!(
            "tolerance {tol} must be finite and non-negative"
        )));
    }
    if m.iter().any(|x| !x.is_finite()) {
        return Err(Error::InvalidInput(
            "transform has non-finite entries".into(),
        ));
    }
    let last = [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]];
    if (last[0].abs() + last[1].abs() + last[2].abs() + (last[3] - 1.0).abs()) > tol {
        return Err(Error::InvalidInput(format!(
            "transform's last row is {last:?}, expected [0, 0, 0, 1]"
        )));
    }
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let err = (r.transpose() * r - Matrix3::identity()).abs().max();
    // det > 0 also refuses the zero matrix, whose rotation would be NaN
    if err > tol || r.determinant() <= 0.0 {
        return Err(Error::InvalidInput(format!(
            "transform's rotation part is not a rotation (|R^T R - I| = {err:.2e}, det = {:.6})",
            r.determinant()
        )));
    }
    let t = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
    Ok(iso_from_parts(&r, &t))
}

/// A plane `n . p = d` with `|n| = 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// Unit normal.
    pub normal: Vector3<f64>,
    /// Signed distance of the plane from the origin along `normal`, in mm.
    pub d: f64,
}

impl Plane {
    /// A plane from any non-zero normal and offset (`normal . p = d`); the normal is
    /// normalised and, if `d < 0`, both are negated so that `d >= 0`.
    pub fn new(normal: Vector3<f64>, d: f64) -> Result<Plane> {
        let n = normal.norm();
        if !(n.is_finite() && d.is_finite()) || n < 1e-12 {
            return Err(Error::InvalidInput(format!(
                "plane normal {normal:?} / offset {d} is not a valid plane"
            )));
        }
        let (mut normal, mut d) = (normal / n, d / n);
        if d < 0.0 {
            normal = -normal;
            d = -d;
        }
        Ok(Plane { normal, d })
    }

    /// Signed distance of `p` from the plane (positive on the side the normal points to).
    pub fn signed_distance(&self, p: &Vector3<f64>) -> f64 {
        self.normal.dot(p) - self.d
    }

    /// The ray parameter `s` with `n . (o + s dir) = d`, or `None` when the ray is
    /// parallel to the plane (|cos| below `1e-12`) or `s` is not finite (a non-finite
    /// origin or direction).
    pub fn intersect_ray(&self, o: &Vector3<f64>, dir: &Vector3<f64>) -> Option<f64> {
        let den = self.normal.dot(dir);
        if den.is_nan() || den.abs() < 1e-12 {
            return None;
        }
        let s = (self.d - self.normal.dot(o)) / den;
        s.is_finite().then_some(s)
    }

    /// This plane expressed in another frame: given `T_b_a` and the plane in frame a,
    /// the plane in frame b.
    pub fn transformed(&self, t_b_a: &Iso3) -> Plane {
        let n = t_b_a.rotation * self.normal;
        let d = self.d + n.dot(&t_b_a.translation.vector);
        // Keep the orientation of n (do not renormalise the sign here).
        Plane { normal: n, d }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rv(x: f64, y: f64, z: f64) -> Vector3<f64> {
        Vector3::new(x, y, z)
    }

    #[test]
    fn rotvec_round_trip_small_medium_and_near_pi() {
        let axes = [rv(1.0, 0.0, 0.0), rv(0.3, -0.5, 0.8), rv(-0.2, 0.9, 0.1)];
        let angles = [
            0.0,
            1e-12,
            1e-8,
            1e-5,
            1e-3,
            0.5,
            2.0,
            3.0,
            std::f64::consts::PI - 1e-9,
        ];
        for a in axes {
            let a = a.normalize();
            for &t in &angles {
                let r = a * t;
                let m = rotvec_to_matrix(&r);
                // orthonormal
                assert!((m.transpose() * m - Matrix3::identity()).abs().max() < 1e-14);
                let back = matrix_to_rotvec(&m);
                assert!(
                    (back - r).norm() < 1e-9 * (1.0 + t),
                    "angle {t}: {back:?} vs {r:?}"
                );
                // agrees with nalgebra's own construction
                let nal = Rotation3::new(r);
                assert!((nal.matrix() - m).abs().max() < 1e-14);
            }
        }
    }

    #[test]
    fn rotvec_at_exactly_pi_gives_the_axis_up_to_sign() {
        let a = rv(0.6, 0.0, 0.8);
        let m = rotvec_to_matrix(&(a * std::f64::consts::PI));
        let back = matrix_to_rotvec(&m);
        assert!((back.norm() - std::f64::consts::PI).abs() < 1e-12);
        assert!((back.normalize().dot(&a).abs() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn nearest_rotation_repairs_noise_and_reflection() {
        let r = rotvec_to_matrix(&rv(0.2, -0.4, 1.1));
        let noisy = r + Matrix3::new(1e-3, -2e-3, 0.0, 5e-4, 0.0, 1e-3, -1e-3, 0.0, 2e-3);
        let n = nearest_rotation(&noisy);
        assert!((n.determinant() - 1.0).abs() < 1e-12);
        assert!((n - r).abs().max() < 5e-3);
        let refl = -r;
        let n = nearest_rotation(&refl);
        assert!((n.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn matrix_round_trip_and_rejects_non_rigid() {
        let t = iso_from_rotvec(&rv(0.1, 0.2, -0.3), &rv(10.0, -5.0, 2.0));
        let m = iso_to_matrix(&t);
        let back = iso_from_matrix(&m, 1e-9).unwrap();
        assert!((iso_to_matrix(&back) - m).abs().max() < 1e-12);
        let mut bad = m;
        bad[(0, 0)] *= 1.1;
        assert!(iso_from_matrix(&bad, 1e-6).is_err());
        let mut bad = m;
        bad[(3, 0)] = 1.0;
        assert!(iso_from_matrix(&bad, 1e-6).is_err());
    }

    #[test]
    fn plane_transform_keeps_points_on_it() {
        let p = Plane::new(rv(0.629, -0.0492, 0.7759), 79.87).unwrap();
        let t = iso_from_rotvec(&rv(0.3, -0.1, 2.0), &rv(5.0, 1.0, -3.0));
        let q = p.transformed(&t);
        let x = p.normal * p.d + p.normal.cross(&rv(0.0, 0.0, 1.0)) * 7.0;
        assert!(p.signed_distance(&x).abs() < 1e-12);
        assert!(
            q.signed_distance(&(t * nalgebra::Point3::from(x)).coords)
                .abs()
                < 1e-12
        );
    }
}
