//! # stripecal
//!
//! Calibration and measurement for a laser-stripe (line triangulation) sensor carried by
//! an industrial robot: one camera, one laser plane, a 6-axis arm.
//!
//! ## Conventions
//!
//! The contract is `spec/DATASET.md`; in short:
//!
//! - Lengths in millimetres, angles in degrees in files and in the public API where a
//!   name ends in `_deg`; rotation vectors (axis times angle) are in radians.
//! - `T_a_b` maps coordinates in frame b to frame a: `p_a = T_a_b * p_b`.
//!   Frames: `base` (robot base), `hand` (flange), `cam` (x right, y down, z forward),
//!   `board` (the target; z points into the plate).
//! - Pixel coordinates: `u` along columns, `v` along rows, the centre of the top-left
//!   pixel is `(0, 0)`.
//! - Camera: `u = fu * xd + u0`, `v = fv * yd + v0`, distortion in OpenCV order
//!   `[k1, k2, p1, p2, k3]`.
//! - Laser plane in the camera frame: `n . p = d`, `|n| = 1`, `d > 0`.
//! - Robot: standard DH, `A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)` with
//!   `theta_i = q_i - theta0_i`.
//!
//! Data flows one way: images -> vision -> calib -> calibration.json -> reconstruct.

pub mod calib;
pub mod cancel;
pub mod error;
pub mod io;
pub mod model;
pub mod numerics;
pub mod pipeline;
pub mod reconstruct;
pub(crate) mod stripe_model;
pub mod vision;

pub use cancel::Cancel;
pub use error::{BadFrame, Error, Result};
pub use model::board::{Board, BoardKind};
pub use model::camera::{Camera, DistortionModel, Intrinsics};
pub use model::geometry::{Iso3, Plane};
pub use model::kinematics::{DhJoint, Robot};
