//! Plane-to-image homographies for calibration: the normalised DLT
//! ([`crate::numerics::homography::dlt`]) refined by Levenberg-Marquardt on the image
//! reprojection error.
//!
//! `H` maps board-plane points `(x, y, 1)` to image points `w (u, v, 1)`; the image
//! points may be pixels or undistorted normalised coordinates, the code does not care.
//! `H` is returned with `|H|_F = 1` and `H[(2, 2)] >= 0`.

use faer::MatMut;
use nalgebra::{Matrix3, Vector2};

use crate::error::{Error, Result};
use crate::numerics::homography::normalise;
pub use crate::numerics::homography::{apply, dlt};
use crate::numerics::lm::{levenberg_marquardt, LeastSquares, LmOptions};

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
