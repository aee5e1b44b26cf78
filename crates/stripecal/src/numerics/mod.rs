//! Numerical building blocks with no knowledge of the sensor: each piece of maths
//! exists once here and the layers above call it.
//!
//! - `dual`: forward-mode dual numbers and the `Scalar` trait the generic models use;
//!   `mat3`: small 3-vector / 3x3 algebra over any `Scalar`.
//! - `lm`: the one Levenberg-Marquardt solver (problem, normal equations, solver,
//!   covariance).
//! - `homography`: the normalised DLT.
//! - `tls`: total least squares (principal axes; the plane fit).
//! - `robust`: median and MAD sigma.
//! - `rng`: SplitMix64.

pub mod dual;
pub mod homography;
pub mod lm;
pub mod mat3;
pub mod rng;
pub mod robust;
pub mod tls;
