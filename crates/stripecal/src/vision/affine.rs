//! The least-squares affine map from lattice coordinates to the image,
//! `(u, v) = A (i, j) + b`, accumulated point by point in its normal equations (both
//! target detectors use it: the grid's handedness, a node's position predicted from its
//! neighbours), its conditioning test, and the lattice neighbourhood such fits use.

use nalgebra::{Matrix3, Vector3};

/// Normal equations of the (weighted) affine fit `(u, v) = A (i, j) + b`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AffineFit {
    /// `sum w f f^T` with `f = (i, j, 1)`.
    pub n: Matrix3<f64>,
    bu: Vector3<f64>,
    bv: Vector3<f64>,
}

impl AffineFit {
    pub fn new() -> AffineFit {
        AffineFit {
            n: Matrix3::zeros(),
            bu: Vector3::zeros(),
            bv: Vector3::zeros(),
        }
    }

    /// Adds lattice point `(i, j)` seen at image point `(u, v)`.
    #[inline]
    pub fn add(&mut self, (i, j): (f64, f64), (u, v): (f64, f64)) {
        let f = Vector3::new(i, j, 1.0);
        self.n += f * f.transpose();
        self.bu += f * u;
        self.bv += f * v;
    }

    /// Adds lattice point `(i, j)` seen at image point `(u, v)` with weight `w`.
    #[inline]
    pub fn add_weighted(&mut self, (i, j): (f64, f64), (u, v): (f64, f64), w: f64) {
        let f = Vector3::new(i, j, 1.0);
        self.n += f * f.transpose() * w;
        self.bu += f * (w * u);
        self.bv += f * (w * v);
    }

    /// The rows of `[A | b]` for `u` and for `v`: `u = pu[0] i + pu[1] j + pu[2]`;
    /// `None` when the points do not fix the map.
    pub fn solve(&self) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let inv = self.n.try_inverse()?;
        Some((inv * self.bu, inv * self.bv))
    }
}

/// Whether the lattice points behind the normal matrix `n` (of `f = (i, j, 1)`) span
/// the plane: the Schur complement of the constant term (the 2x2 lattice part) is not
/// near singular relative to its scale. Collinear support fails.
#[inline]
pub(crate) fn spans_plane(n: &Matrix3<f64>) -> bool {
    let scale = n[(0, 0)] + n[(1, 1)];
    let det2 = {
        let s = n[(2, 2)];
        let a = n[(0, 0)] - n[(0, 2)] * n[(0, 2)] / s;
        let b = n[(0, 1)] - n[(0, 2)] * n[(1, 2)] / s;
        let d = n[(1, 1)] - n[(1, 2)] * n[(1, 2)] / s;
        a * d - b * b
    };
    !(det2.is_nan() || det2 <= 1e-3 * scale * scale)
}

/// The lattice offsets `(di, dj)` within Chebyshev radius `rad` of a site, the site
/// itself excluded, `di` major.
#[inline]
pub(crate) fn neighbourhood(rad: i32) -> impl Iterator<Item = (i32, i32)> {
    (-rad..=rad)
        .flat_map(move |di| (-rad..=rad).map(move |dj| (di, dj)))
        .filter(|&(di, dj)| !(di == 0 && dj == 0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_an_affine_map_and_refuses_a_line() {
        let map = |i: f64, j: f64| (2.0 * i - 0.5 * j + 7.0, 0.3 * i + 1.5 * j - 2.0);
        let mut fit = AffineFit::new();
        let mut line = AffineFit::new();
        for (i, j) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (2.0, 3.0)] {
            fit.add_weighted((i, j), map(i, j), 1.0 + i);
            line.add((i, i), map(i, i));
        }
        let (pu, pv) = fit.solve().unwrap();
        for (got, want) in pu
            .iter()
            .chain(pv.iter())
            .zip([2.0, -0.5, 7.0, 0.3, 1.5, -2.0])
        {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
        assert!(line.solve().is_none());
        assert!(spans_plane(&fit.n) && !spans_plane(&line.n));
    }

    #[test]
    fn neighbourhood_is_the_ring_without_the_centre() {
        let v: Vec<_> = neighbourhood(1).collect();
        assert_eq!(v.len(), 8);
        assert_eq!(v[0], (-1, -1));
        assert_eq!((v[3], v[4]), ((0, -1), (0, 1)));
        assert!(!v.contains(&(0, 0)));
        assert_eq!(neighbourhood(2).count(), 24);
    }
}
