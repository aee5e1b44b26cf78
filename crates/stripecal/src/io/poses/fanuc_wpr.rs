//! `w_deg,p_deg,r_deg`: Fanuc's (and Yaskawa's Rx, Ry, Rz) W, P, R in degrees: rotations
//! about the FIXED x, y and z axes, in that order, so `R = Rz(R) * Ry(P) * Rx(W)`. It is
//! the product of KUKA's A, B, C with the angles named the other way round (W = C,
//! P = B, R = A); see [`super::euler_zyx`]. Written back, P is in `[-90, 90]` and W, R
//! in `[-180, 180]`; at P = ±90 (gimbal lock) only R - W or R + W is defined.

use nalgebra::UnitQuaternion;

use super::{euler_zyx, RotationConvention};

pub(super) struct FanucWpr;

impl RotationConvention for FanucWpr {
    fn columns(&self) -> &'static [&'static str] {
        &["w_deg", "p_deg", "r_deg"]
    }

    fn describe(&self) -> &'static str {
        "Fanuc's W, P, R"
    }

    fn to_rotation(&self, v: &[f64]) -> Result<UnitQuaternion<f64>, String> {
        let (w, p, r) = (v[0].to_radians(), v[1].to_radians(), v[2].to_radians());
        Ok(euler_zyx::to_rotation(r, p, w))
    }

    fn values(&self, q: &UnitQuaternion<f64>) -> Vec<f64> {
        let (r, p, w) = euler_zyx::from_rotation(q);
        vec![w.to_degrees(), p.to_degrees(), r.to_degrees()]
    }
}
