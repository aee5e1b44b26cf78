//! The laser plane's chart: its unit normal `n = normalize(n0 + a e1 + b e2)` around
//! the starting normal `n0`, `(e1, e2)` completing it to an orthonormal basis.

use nalgebra::Vector3;

/// The local chart of the laser plane's normal: `n = normalize(n0 + a e1 + b e2)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(in crate::calib::joint) struct PlaneChart {
    pub n0: Vector3<f64>,
    pub e1: Vector3<f64>,
    pub e2: Vector3<f64>,
}

impl PlaneChart {
    /// The chart around the unit normal `n0`.
    pub fn around(n0: Vector3<f64>) -> PlaneChart {
        let (e1, e2) = tangent_basis(&n0);
        PlaneChart { n0, e1, e2 }
    }

    /// The raw (unnormalised) normal `n0 + a e1 + b e2`.
    pub fn raw_normal(&self, a: f64, b: f64) -> Vector3<f64> {
        self.n0 + self.e1 * a + self.e2 * b
    }
}

/// Two unit vectors completing `n` to an orthonormal basis.
fn tangent_basis(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if n.x.abs() < 0.6 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = n.cross(&helper).normalize();
    let e2 = n.cross(&e1);
    (e1, e2)
}
