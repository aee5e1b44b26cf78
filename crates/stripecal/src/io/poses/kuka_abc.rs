//! `a_deg,b_deg,c_deg`: KUKA's A, B, C in degrees (the `A`, `B`, `C` of a KRL `FRAME`
//! or `POS`, e.g. `$POS_ACT`): `R = Rz(A) * Ry(B) * Rx(C)`, i.e. A about z, then B
//! about the new y, then C about the newest x (see [`super::euler_zyx`] for the
//! product and its inverse). Written back, B is in `[-90, 90]` and A, C in
//! `[-180, 180]`; at B = ±90 (gimbal lock) only A - C or A + C is defined, and the
//! writer's split of it is as good as any.

use nalgebra::UnitQuaternion;

use super::{euler_zyx, RotationConvention};

pub(super) struct KukaAbc;

impl RotationConvention for KukaAbc {
    fn columns(&self) -> &'static [&'static str] {
        &["a_deg", "b_deg", "c_deg"]
    }

    fn describe(&self) -> &'static str {
        "KUKA's A, B, C"
    }

    fn to_rotation(&self, v: &[f64]) -> Result<UnitQuaternion<f64>, String> {
        Ok(euler_zyx::to_rotation(
            v[0].to_radians(),
            v[1].to_radians(),
            v[2].to_radians(),
        ))
    }

    fn values(&self, r: &UnitQuaternion<f64>) -> Vec<f64> {
        let (a, b, c) = euler_zyx::from_rotation(r);
        vec![a.to_degrees(), b.to_degrees(), c.to_degrees()]
    }
}
