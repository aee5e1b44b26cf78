//! The normalised DLT homography (Hartley): `H` with `image ~ H plane` from point
//! correspondences, its application to a point, and the residuals of the fit.
//!
//! `H` maps plane points `(x, y, 1)` to image points `w (u, v, 1)`; either side may be
//! pixels, millimetres, lattice units or normalised coordinates, the code does not care.
//! `H` is returned with `|H|_F = 1` and `H[(2, 2)] >= 0`. The calibration refines it
//! ([`crate::calib::homography::fit_homography`]); the detectors use it as is.

use nalgebra::{DMatrix, Matrix3, Vector2, Vector3};

use crate::error::{Error, Result};

/// Applies `h` to a plane point; `None` when it maps to infinity.
pub fn apply(h: &Matrix3<f64>, p: &Vector2<f64>) -> Option<Vector2<f64>> {
    let q = h * Vector3::new(p.x, p.y, 1.0);
    if q.z.abs() < 1e-300 {
        return None;
    }
    Some(Vector2::new(q.x / q.z, q.y / q.z))
}

/// Similarity that moves the centroid to 0 and the mean distance to sqrt(2).
fn normaliser(pts: &[Vector2<f64>]) -> Result<Matrix3<f64>> {
    let n = pts.len() as f64;
    let c = pts.iter().fold(Vector2::zeros(), |a, p| a + p) / n;
    let md = pts.iter().map(|p| (p - c).norm()).sum::<f64>() / n;
    if !(md > 0.0 && md.is_finite()) {
        return Err(Error::Degenerate("homography: all points coincide".into()));
    }
    let s = std::f64::consts::SQRT_2 / md;
    Ok(Matrix3::new(
        s,
        0.0,
        -s * c.x,
        0.0,
        s,
        -s * c.y,
        0.0,
        0.0,
        1.0,
    ))
}

fn check(plane: &[Vector2<f64>], image: &[Vector2<f64>]) -> Result<()> {
    if plane.len() != image.len() {
        return Err(Error::InvalidInput(format!(
            "homography: {} plane points but {} image points",
            plane.len(),
            image.len()
        )));
    }
    if plane.len() < 4 {
        return Err(Error::InvalidInput(format!(
            "homography needs at least 4 points, got {}",
            plane.len()
        )));
    }
    if plane
        .iter()
        .chain(image)
        .any(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return Err(Error::InvalidInput(
            "homography: non-finite point coordinates".into(),
        ));
    }
    // Collinearity of either set: the smaller eigenvalue of the scatter matrix.
    for (name, pts) in [("plane", plane), ("image", image)] {
        let n = pts.len() as f64;
        let c = pts.iter().fold(Vector2::zeros(), |a, p| a + p) / n;
        let s = pts.iter().fold(nalgebra::Matrix2::zeros(), |a, p| {
            a + (p - c) * (p - c).transpose()
        });
        let e = s.symmetric_eigenvalues();
        let (lo, hi) = (e.min(), e.max());
        if !(hi > 0.0 && lo > 1e-10 * hi) {
            return Err(Error::Degenerate(format!(
                "homography: the {name} points are collinear or coincident"
            )));
        }
    }
    Ok(())
}

/// Normalised DLT: `H` with `image ~ H plane`, from >= 4 correspondences, no three
/// collinear in general position. Errors: [`Error::InvalidInput`] for fewer than 4
/// points, mismatched lengths or non-finite values; [`Error::Degenerate`] for collinear
/// point sets or an ill-posed system.
pub fn dlt(plane: &[Vector2<f64>], image: &[Vector2<f64>]) -> Result<Matrix3<f64>> {
    check(plane, image)?;
    let tp = normaliser(plane)?;
    let ti = normaliser(image)?;
    let n = plane.len();
    let mut a = DMatrix::<f64>::zeros(2 * n, 9);
    for k in 0..n {
        let p = tp * Vector3::new(plane[k].x, plane[k].y, 1.0);
        let q = ti * Vector3::new(image[k].x, image[k].y, 1.0);
        let (x, y) = (p.x, p.y);
        let (u, v) = (q.x, q.y);
        let r0 = [-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u];
        let r1 = [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v];
        for j in 0..9 {
            a[(2 * k, j)] = r0[j];
            a[(2 * k + 1, j)] = r1[j];
        }
    }
    let ata = a.transpose() * &a;
    let eig = ata.symmetric_eigen();
    let mut idx: Vec<usize> = (0..9).collect();
    idx.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let (e0, e1) = (eig.eigenvalues[idx[0]], eig.eigenvalues[idx[1]]);
    let emax = eig.eigenvalues[idx[8]];
    if e1.is_nan() || e1 <= 1e-14 * emax || !e0.is_finite() {
        return Err(Error::Degenerate(format!(
            "homography: the DLT system is rank deficient (eigenvalues {e0:.2e}, {e1:.2e} of {emax:.2e})"
        )));
    }
    let h = eig.eigenvectors.column(idx[0]);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let ti_inv = ti
        .try_inverse()
        .ok_or_else(|| Error::Degenerate("homography: singular normalisation".into()))?;
    Ok(normalise(ti_inv * hn * tp))
}

/// `h` scaled to `|h|_F = 1` with `h[(2, 2)] >= 0`.
pub(crate) fn normalise(h: Matrix3<f64>) -> Matrix3<f64> {
    let mut h = h / h.norm();
    if h[(2, 2)] < 0.0 {
        h = -h;
    }
    h
}

/// RMS and largest distance between `image` and `plane` mapped by the [`dlt`]
/// homography fitted to them (image units); `None` when the fit fails or maps a point
/// to infinity.
pub fn dlt_residuals(plane: &[Vector2<f64>], image: &[Vector2<f64>]) -> Option<(f64, f64)> {
    let h = dlt(plane, image).ok()?;
    let (mut ss, mut mx) = (0.0f64, 0.0f64);
    for (p, q) in plane.iter().zip(image) {
        let x = apply(&h, p)?;
        let e = (x - q).norm();
        ss += e * e;
        mx = mx.max(e);
    }
    Some(((ss / plane.len() as f64).sqrt(), mx))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn residuals_of_an_exact_homography_vanish() {
        let h = Matrix3::new(12.0, 1.5, 300.0, -0.8, 13.1, 250.0, 1e-3, -2e-3, 1.0);
        let plane: Vec<_> = (0..20)
            .map(|k| Vector2::new((k % 5) as f64 * 4.0, (k / 5) as f64 * 3.0))
            .collect();
        let image: Vec<_> = plane.iter().map(|p| apply(&h, p).unwrap()).collect();
        let (rms, max) = dlt_residuals(&plane, &image).unwrap();
        assert!(rms < 1e-9 && max < 1e-9, "{rms} {max}");
        assert!(dlt_residuals(&plane[..3], &image[..3]).is_none());
    }
}
