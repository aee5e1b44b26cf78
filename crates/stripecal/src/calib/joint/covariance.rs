//! One-sigma of every estimated number from the solver's covariance of the parameter
//! vector: the camera's directly, the laser plane's normal through its chart
//! (`n = normalize(n0 + a e1 + b e2)`), and the transforms' rotation vectors through
//! the inverse right Jacobian of SO(3) (the solver's increment is `R Exp(w)`).

use nalgebra::{DMatrix, Matrix3, Vector3};

use super::layout::{Block, JointParams, ParamLayout};
use super::{JointSigma, TransformSigma};

/// The sigmas at the solution `p` (decoded `s`) from the covariance `cov` of `p`.
pub(super) fn joint_sigma(
    layout: &ParamLayout,
    p: &[f64],
    s: &JointParams,
    cov: &DMatrix<f64>,
) -> JointSigma {
    let mut cam_sigma = [0.0; 9];
    for (k, i) in layout.free_camera().into_iter().enumerate() {
        cam_sigma[i] = cov[(k, k)].sqrt();
    }
    let o = layout.first_column(Block::Plane);
    JointSigma {
        camera: cam_sigma,
        plane_normal: plane_normal_sigma(layout, p, s, cov),
        plane_d_mm: cov[(o + 2, o + 2)].sqrt(),
        hand_cam: transform_sigma(p, cov, layout.first_column(Block::HandCam)),
        base_board: transform_sigma(p, cov, layout.first_column(Block::BaseBoard)),
    }
}

/// Sigmas of the plane normal's components: `dn/d(a, b)` at the solution applied to
/// the covariance of `(a, b)`.
fn plane_normal_sigma(
    layout: &ParamLayout,
    p: &[f64],
    s: &JointParams,
    cov: &DMatrix<f64>,
) -> Vector3<f64> {
    let o = layout.first_column(Block::Plane);
    let chart = &layout.chart;
    let nraw = chart.raw_normal(p[o], p[o + 1]);
    let l = nraw.norm();
    let proj = (Matrix3::identity() - s.plane_n * s.plane_n.transpose()) / l;
    let jn = nalgebra::Matrix3x2::from_columns(&[proj * chart.e1, proj * chart.e2]);
    let cab = nalgebra::Matrix2::new(
        cov[(o, o)],
        cov[(o, o + 1)],
        cov[(o + 1, o)],
        cov[(o + 1, o + 1)],
    );
    let cn = jn * cab * jn.transpose();
    // A normal flipped by Plane::new (d < 0) has the same sigmas.
    Vector3::new(cn[(0, 0)].sqrt(), cn[(1, 1)].sqrt(), cn[(2, 2)].sqrt())
}

/// Sigmas of the transform whose rotation vector and translation start at column `b`.
fn transform_sigma(p: &[f64], cov: &DMatrix<f64>, b: usize) -> TransformSigma {
    let rv = Vector3::new(p[b], p[b + 1], p[b + 2]);
    let jr = inverse_right_jacobian(&rv);
    let cw = Matrix3::from_fn(|i, j| cov[(b + i, b + j)]);
    let crv = jr * cw * jr.transpose();
    TransformSigma {
        rotation_vector: Vector3::new(crv[(0, 0)].sqrt(), crv[(1, 1)].sqrt(), crv[(2, 2)].sqrt()),
        translation_mm: Vector3::new(
            cov[(b + 3, b + 3)].sqrt(),
            cov[(b + 4, b + 4)].sqrt(),
            cov[(b + 5, b + 5)].sqrt(),
        ),
    }
}

/// `d rotvec / d w` for `rotvec(R Exp(w))` at `w = 0`: the inverse right Jacobian of SO(3)
/// at `r`.
fn inverse_right_jacobian(r: &Vector3<f64>) -> Matrix3<f64> {
    let th = r.norm();
    let k = r.cross_matrix();
    let c = if th < 1e-6 {
        1.0 / 12.0 + th * th / 720.0
    } else {
        (1.0 / (th * th)) - (1.0 + th.cos()) / (2.0 * th * th.sin())
    };
    Matrix3::identity() + k * 0.5 + k * k * c
}
