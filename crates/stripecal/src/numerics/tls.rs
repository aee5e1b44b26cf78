//! Total least squares: the centroid and principal axes of a point set, the one plane
//! (and line) fit of the crate. The plane through the points with the least sum of
//! squared orthogonal distances passes through the centroid, with the normal along the
//! axis of least spread.
//!
//! ## Maths
//!
//! With the centred points as the rows of `M` (n x 3) and `M = U S V^T` its thin SVD,
//! the columns of `V` are the principal axes and `s_k^2` the sums of squared distances
//! along them. The SVD of `M` itself (not an eigen-decomposition of `M^T M`) keeps the
//! small singular value, the plane's residual, accurate to `eps * s_max` rather than
//! `sqrt(eps) * s_max`.

use faer::Mat;
use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};

/// Centroid and principal axes of a 3D point set.
#[derive(Debug, Clone, Copy)]
pub struct PrincipalAxes {
    /// Mean of the points.
    pub centroid: Vector3<f64>,
    /// Unit axes as columns, by decreasing spread: column 2 is a fitted plane's normal,
    /// column 0 a fitted line's direction.
    pub axes: Matrix3<f64>,
    /// Singular values of the centred points, decreasing: `sqrt(sum of squared
    /// distances)` along each axis.
    pub singular: [f64; 3],
}

/// Principal axes of `points` (at least one; fewer than three give zero singular values).
pub fn principal_axes<'a, I>(points: I) -> Result<PrincipalAxes>
where
    I: IntoIterator<Item = &'a Vector3<f64>>,
    I::IntoIter: Clone,
{
    let it = points.into_iter();
    let n = it.clone().count();
    if n == 0 {
        return Err(Error::Degenerate("principal axes of no points".into()));
    }
    let c = it.clone().fold(Vector3::zeros(), |a, p| a + p) / n as f64;
    // At least 3 rows (zero rows change nothing) so the SVD has 3 singular values.
    let mut m = Mat::<f64>::zeros(n.max(3), 3);
    for (i, p) in it.enumerate() {
        let d = p - c;
        for k in 0..3 {
            m[(i, k)] = d[k];
        }
    }
    let svd = m
        .thin_svd()
        .map_err(|e| Error::Degenerate(format!("SVD of the points failed: {e:?}")))?;
    let s = svd.S().column_vector();
    let v = svd.V();
    let mut axes = Matrix3::zeros();
    for r in 0..3 {
        for k in 0..3 {
            axes[(r, k)] = v[(r, k)];
        }
    }
    Ok(PrincipalAxes {
        centroid: c,
        axes,
        singular: [s[0], s[1], s[2]],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_normal_and_spreads() {
        // A 4 x 3 grid on the plane z = 0.5 x, spread 3 mm along x, 2 mm along y.
        let mut pts = Vec::new();
        for i in 0..4 {
            for j in 0..3 {
                let (x, y) = (i as f64, j as f64);
                pts.push(Vector3::new(x, y, 0.5 * x + 1.0));
            }
        }
        let pa = principal_axes(&pts).unwrap();
        let n = pa.axes.column(2).into_owned();
        let truth = Vector3::new(-0.5, 0.0, 1.0).normalize();
        assert!(n.dot(&truth).abs() > 1.0 - 1e-14);
        assert!(pa.singular[2] < 1e-12);
        assert!(pa.singular[0] >= pa.singular[1]);
        assert!((pa.centroid - Vector3::new(1.5, 1.0, 1.75)).norm() < 1e-14);
        assert!(principal_axes(&[]).is_err());
    }
}
