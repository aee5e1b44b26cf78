//! The kinematic chain of a view, generic over the scalar: the board pose in the camera
//! frame from the robot's flange pose `A = T_base_hand` and the estimated
//! `X = T_hand_cam`, `Z = T_base_board`: `T_cam_board = (A X)^-1 Z`. The parameter
//! layout evaluates it on values, the residuals on dual numbers.

use crate::model::geometry::Iso3;
use crate::numerics::dual::Scalar;
use crate::numerics::mat3::{m3, matmul, matvec, transpose};

/// `T_cam_board = (A X)^-1 Z` from the parts.
pub(super) fn cam_board<T: Scalar>(
    a: &Iso3,
    xr: &[[T; 3]; 3],
    xt: &[T; 3],
    zr: &[[T; 3]; 3],
    zt: &[T; 3],
) -> ([[T; 3]; 3], [T; 3]) {
    let ra = a.rotation.to_rotation_matrix().into_inner();
    let rat: [[T; 3]; 3] = m3(&ra.transpose());
    let ta = a.translation.vector;
    let xrt = transpose(xr);
    let rot = matmul(&xrt, &matmul(&rat, zr));
    let dz: [T; 3] = std::array::from_fn(|i| zt[i] - T::from_f64(ta[i]));
    let inner = matvec(&rat, &dz);
    let inner2: [T; 3] = std::array::from_fn(|i| inner[i] - xt[i]);
    (rot, matvec(&xrt, &inner2))
}
