//! Plane-to-image homographies: normalised DLT (Hartley) and Levenberg-Marquardt
//! refinement of the image reprojection error.
//!
//! `H` maps board-plane points `(x, y, 1)` to image points `w (u, v, 1)`; the image
//! points may be pixels or undistorted normalised coordinates, the code does not care.
//! `H` is returned with `|H|_F = 1` and `H[(2, 2)] >= 0`.

use faer::MatMut;
use nalgebra::{DMatrix, Matrix3, Vector2, Vector3};

use crate::error::{Error, Result};
use crate::numerics::lm::{levenberg_marquardt, LeastSquares, LmOptions};

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

fn normalise(h: Matrix3<f64>) -> Matrix3<f64> {
    let mut h = h / h.norm();
    if h[(2, 2)] < 0.0 {
        h = -h;
    }
    h
}

struct Refine<'a> {
    plane: &'a [Vector2<f64>],
    image: &'a [Vector2<f64>],
    /// The fixed unit direction of the parameter-free scale: the 9 entries are
    /// parameterised as h = h0 + B p (B spans the orthogonal complement of h0).
    h0: [f64; 9],
    basis: [[f64; 9]; 8],
}

impl Refine<'_> {
    fn h(&self, p: &[f64]) -> [f64; 9] {
        let mut h = self.h0;
        for (k, b) in self.basis.iter().enumerate() {
            for j in 0..9 {
                h[j] += p[k] * b[j];
            }
        }
        h
    }
}

impl LeastSquares for Refine<'_> {
    fn num_params(&self) -> usize {
        8
    }
    fn num_residuals(&self) -> usize {
        2 * self.plane.len()
    }
    fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        let h = self.h(p);
        for (k, (a, b)) in self.plane.iter().zip(self.image).enumerate() {
            let w = h[6] * a.x + h[7] * a.y + h[8];
            if w.abs() < 1e-300 {
                return Err(Error::Degenerate(
                    "homography maps a point to infinity".into(),
                ));
            }
            r[2 * k] = (h[0] * a.x + h[1] * a.y + h[2]) / w - b.x;
            r[2 * k + 1] = (h[3] * a.x + h[4] * a.y + h[5]) / w - b.y;
        }
        Ok(())
    }
    fn residuals_and_jacobian(
        &self,
        p: &[f64],
        r: &mut [f64],
        mut jac: MatMut<'_, f64>,
    ) -> Result<()> {
        self.residuals(p, r)?;
        let h = self.h(p);
        for (k, a) in self.plane.iter().enumerate() {
            let w = h[6] * a.x + h[7] * a.y + h[8];
            let u = (h[0] * a.x + h[1] * a.y + h[2]) / w;
            let v = (h[3] * a.x + h[4] * a.y + h[5]) / w;
            // d(u)/dh, d(v)/dh
            let du = [
                a.x / w,
                a.y / w,
                1.0 / w,
                0.0,
                0.0,
                0.0,
                -u * a.x / w,
                -u * a.y / w,
                -u / w,
            ];
            let dv = [
                0.0,
                0.0,
                0.0,
                a.x / w,
                a.y / w,
                1.0 / w,
                -v * a.x / w,
                -v * a.y / w,
                -v / w,
            ];
            for (c, b) in self.basis.iter().enumerate() {
                let (mut su, mut sv) = (0.0, 0.0);
                for j in 0..9 {
                    su += du[j] * b[j];
                    sv += dv[j] * b[j];
                }
                jac[(2 * k, c)] = su;
                jac[(2 * k + 1, c)] = sv;
            }
        }
        Ok(())
    }
}

/// [`dlt`] refined by Levenberg-Marquardt on the image reprojection error.
/// Returns `H` and the RMS reprojection error (image units).
pub fn fit_homography(
    plane: &[Vector2<f64>],
    image: &[Vector2<f64>],
) -> Result<(Matrix3<f64>, f64)> {
    let h0 = dlt(plane, image)?;
    // Basis orthogonal to h0 (unit): the 8 eigenvectors of I - h0 h0^T with eigenvalue 1.
    let hv = nalgebra::SVector::<f64, 9>::from_iterator(h0.transpose().iter().cloned());
    let proj = nalgebra::SMatrix::<f64, 9, 9>::identity() - hv * hv.transpose();
    let eig = proj.symmetric_eigen();
    let mut idx: Vec<usize> = (0..9).collect();
    idx.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let basis: [[f64; 9]; 8] =
        std::array::from_fn(|k| std::array::from_fn(|j| eig.eigenvectors[(j, idx[k])]));
    let h0a: [f64; 9] = std::array::from_fn(|j| hv[j]);
    let pr = Refine {
        plane,
        image,
        h0: h0a,
        basis,
    };
    let opts = LmOptions {
        max_iterations: 50,
        ..Default::default()
    };
    let res = levenberg_marquardt(&pr, &[0.0; 8], &opts)?;
    let h = pr.h(&res.params);
    let hm = normalise(Matrix3::new(
        h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8],
    ));
    let rms = (res.ssr / plane.len() as f64).sqrt();
    Ok((hm, rms))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth() -> Matrix3<f64> {
        Matrix3::new(12.0, 1.5, 300.0, -0.8, 13.1, 250.0, 1e-3, -2e-3, 1.0)
    }

    fn grid() -> Vec<Vector2<f64>> {
        let mut v = Vec::new();
        for r in 0..8 {
            for c in 0..11 {
                v.push(Vector2::new(c as f64 * 5.0, r as f64 * 5.0));
            }
        }
        v
    }

    #[test]
    fn recovers_exact_homography() {
        let h = truth();
        let pl = grid();
        let im: Vec<_> = pl.iter().map(|p| apply(&h, p).unwrap()).collect();
        let (est, rms) = fit_homography(&pl, &im).unwrap();
        let est = est / est[(2, 2)];
        assert!((est - h).abs().max() < 1e-9 * h.abs().max(), "{est}");
        assert!(rms < 1e-9);
        let d = dlt(&pl, &im).unwrap();
        let d = d / d[(2, 2)];
        assert!((d - h).abs().max() < 1e-8 * h.abs().max());
    }

    #[test]
    fn degenerate_inputs_are_typed_errors() {
        let h = truth();
        let line: Vec<_> = (0..10)
            .map(|i| Vector2::new(i as f64, 2.0 * i as f64))
            .collect();
        let im: Vec<_> = line.iter().map(|p| apply(&h, p).unwrap()).collect();
        assert!(matches!(
            fit_homography(&line, &im),
            Err(Error::Degenerate(_))
        ));
        let pl = grid();
        let im: Vec<_> = pl.iter().map(|p| apply(&h, p).unwrap()).collect();
        assert!(matches!(
            fit_homography(&pl[..3], &im[..3]),
            Err(Error::InvalidInput(_))
        ));
        let mut bad = im.clone();
        bad[5].x = f64::NAN;
        assert!(matches!(
            fit_homography(&pl, &bad),
            Err(Error::InvalidInput(_))
        ));
        assert!(fit_homography(&pl, &im[..10]).is_err());
    }
}
