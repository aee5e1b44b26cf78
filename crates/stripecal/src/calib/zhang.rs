//! Zhang's closed-form intrinsics (zero skew) from plane homographies, and board poses
//! from a homography and `K`.
//!
//! With `B = K^-T K^-1 = [[B11, 0, B13], [0, B22, B23], [B13, B23, B33]]` (zero skew),
//! each homography `H = [h1 h2 h3]` (board -> pixels) gives `h1^T B h2 = 0` and
//! `h1^T B h1 = h2^T B h2`: two linear equations in the 5 entries of `b`. `b` is
//! defined up to scale (4 unknowns), so 2 views in general position are the minimum
//! and 3 or more give redundancy. With the principal point fixed (e.g. at the image
//! centre, the usual choice for 1 or 2 views), `B13 = B23 = 0` after moving the origin
//! to it, and one view suffices (fu, fv only).
//!
//! Pixels are conditioned (origin at the mean principal-point guess, unit ~ image
//! size) before solving. The homographies should come from undistorted points for an
//! exact answer; with distortion ignored they are an initial guess.

use nalgebra::{DMatrix, Matrix3, Vector3};

use crate::error::{Error, Result};
use crate::model::geometry::{iso_from_parts, nearest_rotation, Iso3};

/// Pinhole intrinsics without skew.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub fu: f64,
    pub fv: f64,
    pub u0: f64,
    pub v0: f64,
}

impl Intrinsics {
    /// `K`.
    pub fn k(&self) -> Matrix3<f64> {
        Matrix3::new(self.fu, 0.0, self.u0, 0.0, self.fv, self.v0, 0.0, 0.0, 1.0)
    }
}

/// Zhang's closed form. `hs`: homographies board -> pixels. `principal_point`: `Some`
/// fixes `(u0, v0)` (1 view suffices), `None` estimates it (>= 2 views; 3 or more
/// recommended). `scale`: a typical image size in pixels for conditioning (e.g.
/// `(width + height) / 2`).
///
/// Errors: [`Error::InvalidInput`] for too few homographies or non-finite entries;
/// [`Error::Degenerate`] when the views do not determine `K` (e.g. parallel boards) or
/// the solution is not a valid `K`.
pub fn zhang_intrinsics(
    hs: &[Matrix3<f64>],
    principal_point: Option<(f64, f64)>,
    scale: f64,
) -> Result<Intrinsics> {
    let need = if principal_point.is_some() { 1 } else { 2 };
    if hs.len() < need {
        return Err(Error::InvalidInput(format!(
            "Zhang's method needs at least {need} homographies{}, got {}",
            if principal_point.is_some() {
                ""
            } else {
                " (or a fixed principal point)"
            },
            hs.len()
        )));
    }
    if hs.iter().any(|h| h.iter().any(|x| !x.is_finite())) || !(scale.is_finite() && scale > 0.0) {
        return Err(Error::InvalidInput(
            "Zhang: non-finite homography or bad scale".into(),
        ));
    }
    let (c0, c1) = principal_point.unwrap_or((0.0, 0.0));
    // conditioning: pixels -> (pix - c) / scale
    let t = Matrix3::new(
        1.0 / scale,
        0.0,
        -c0 / scale,
        0.0,
        1.0 / scale,
        -c1 / scale,
        0.0,
        0.0,
        1.0,
    );
    let fixed = principal_point.is_some();
    let nb = if fixed { 3 } else { 5 };
    let mut a = DMatrix::<f64>::zeros(2 * hs.len(), nb);
    for (k, h) in hs.iter().enumerate() {
        let h = t * h;
        let h = h / h.norm();
        let v = |i: usize, j: usize| -> [f64; 5] {
            let (hi, hj) = (h.column(i), h.column(j));
            [
                hi[0] * hj[0],
                hi[1] * hj[1],
                hi[0] * hj[2] + hi[2] * hj[0],
                hi[1] * hj[2] + hi[2] * hj[1],
                hi[2] * hj[2],
            ]
        };
        let v12 = v(0, 1);
        let v11 = v(0, 0);
        let v22 = v(1, 1);
        let cols: &[usize] = if fixed { &[0, 1, 4] } else { &[0, 1, 2, 3, 4] };
        for (c, &j) in cols.iter().enumerate() {
            a[(2 * k, c)] = v12[j];
            a[(2 * k + 1, c)] = v11[j] - v22[j];
        }
    }
    let ata = a.transpose() * &a;
    let eig = ata.symmetric_eigen();
    let mut idx: Vec<usize> = (0..nb).collect();
    idx.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let emax = eig.eigenvalues[idx[nb - 1]];
    let e1 = eig.eigenvalues[idx[1]];
    if e1.is_nan() || e1 <= 1e-12 * emax {
        return Err(Error::Degenerate(
            "Zhang: the views do not determine the intrinsics (too similar board orientations)"
                .into(),
        ));
    }
    let bvec = eig.eigenvectors.column(idx[0]);
    let b: [f64; 5] = if fixed {
        [bvec[0], bvec[1], 0.0, 0.0, bvec[2]]
    } else {
        [bvec[0], bvec[1], bvec[2], bvec[3], bvec[4]]
    };
    let [mut b11, mut b22, mut b13, mut b23, mut b33] = b;
    if b11 < 0.0 {
        b11 = -b11;
        b22 = -b22;
        b13 = -b13;
        b23 = -b23;
        b33 = -b33;
    }
    let bad = || {
        Error::Degenerate(format!(
            "Zhang: the homographies give no valid camera matrix (b = {b:?})"
        ))
    };
    if !(b11 > 0.0 && b22 > 0.0) {
        return Err(bad());
    }
    let u0 = -b13 / b11;
    let v0 = -b23 / b22;
    let lambda = b33 - b13 * b13 / b11 - b23 * b23 / b22;
    let fu2 = lambda / b11;
    let fv2 = lambda / b22;
    if !(fu2 > 0.0 && fv2 > 0.0) {
        return Err(bad());
    }
    let out = Intrinsics {
        fu: fu2.sqrt() * scale,
        fv: fv2.sqrt() * scale,
        u0: u0 * scale + c0,
        v0: v0 * scale + c1,
    };
    if [out.fu, out.fv, out.u0, out.v0]
        .iter()
        .any(|x| !x.is_finite())
    {
        return Err(bad());
    }
    Ok(out)
}

/// The board pose `T_cam_board` from a homography (board mm -> pixels) and `K`:
/// `[r1 r2 t] ~ K^-1 H`, scale from `|r1|`, sign so the board is in front, rotation
/// made orthonormal with [`nearest_rotation`].
pub fn pose_from_homography(h: &Matrix3<f64>, k: &Matrix3<f64>) -> Result<Iso3> {
    let kinv = k
        .try_inverse()
        .ok_or_else(|| Error::InvalidInput("singular camera matrix".into()))?;
    let m = kinv * h;
    let (c1, c2, c3) = (m.column(0), m.column(1), m.column(2));
    let s = 2.0 / (c1.norm() + c2.norm());
    if !s.is_finite() {
        return Err(Error::Degenerate("homography has zero columns".into()));
    }
    let s = if c3[2] < 0.0 { -s } else { s };
    let r1: Vector3<f64> = c1 * s;
    let r2: Vector3<f64> = c2 * s;
    let r3 = r1.cross(&r2);
    let r = nearest_rotation(&Matrix3::from_columns(&[r1, r2, r3]));
    let t: Vector3<f64> = c3 * s;
    Ok(iso_from_parts(&r, &t))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::iso_from_rotvec;

    fn hom(k: &Matrix3<f64>, t: &Iso3) -> Matrix3<f64> {
        let r = t.rotation.to_rotation_matrix().into_inner();
        let tr = t.translation.vector;
        k * Matrix3::from_columns(&[r.column(0).into(), r.column(1).into(), tr])
    }

    #[test]
    fn exact_intrinsics_and_poses() {
        let kk = Intrinsics {
            fu: 1271.65,
            fv: 1322.52,
            u0: 346.14,
            v0: 262.6,
        };
        let k = kk.k();
        let poses = [
            iso_from_rotvec(
                &Vector3::new(0.3, 0.1, 0.2),
                &Vector3::new(-20.0, -15.0, 100.0),
            ),
            iso_from_rotvec(
                &Vector3::new(-0.2, 0.35, -0.1),
                &Vector3::new(-25.0, -10.0, 110.0),
            ),
            iso_from_rotvec(
                &Vector3::new(0.1, -0.3, 1.2),
                &Vector3::new(-15.0, -20.0, 95.0),
            ),
        ];
        let hs: Vec<_> = poses.iter().map(|t| -hom(&k, t) * 0.37).collect();
        for n in [2, 3] {
            let est = zhang_intrinsics(&hs[..n], None, 672.0).unwrap();
            assert!((est.fu - kk.fu).abs() < 1e-6 * kk.fu, "{est:?}");
            assert!((est.fv - kk.fv).abs() < 1e-6 * kk.fv);
            assert!((est.u0 - kk.u0).abs() < 1e-5);
            assert!((est.v0 - kk.v0).abs() < 1e-5);
        }
        let est = zhang_intrinsics(&hs[..1], Some((kk.u0, kk.v0)), 672.0).unwrap();
        assert!((est.fu - kk.fu).abs() < 1e-6 * kk.fu);
        for (h, t) in hs.iter().zip(&poses) {
            let p = pose_from_homography(h, &k).unwrap();
            assert!((p.translation.vector - t.translation.vector).norm() < 1e-9);
            assert!(p.rotation.angle_to(&t.rotation) < 1e-10);
        }
        assert!(zhang_intrinsics(&hs[..1], None, 672.0).is_err());
        // identical views: degenerate
        assert!(matches!(
            zhang_intrinsics(&[hs[0], hs[0], hs[0]], None, 672.0),
            Err(Error::Degenerate(_))
        ));
    }
}
