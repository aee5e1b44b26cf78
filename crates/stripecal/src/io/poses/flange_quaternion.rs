//! The flange pose `x_mm,y_mm,z_mm,qw,qx,qy,qz`: `T_base_hand` as a translation in mm
//! and a unit quaternion (scalar first). A quaternion whose norm is within
//! [`QUATERNION_TOL`] of 1 is normalised; any other is an error.

use nalgebra::{Quaternion, Translation3, UnitQuaternion};

use super::PoseConvention;
use crate::model::geometry::Iso3;
use crate::model::kinematics::Robot;
use crate::model::RobotReading;

/// The flange-pose columns.
const POSE_COLUMNS: [&str; 7] = ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"];

/// How far from 1 the norm of a flange-pose quaternion may be; it is then normalised.
const QUATERNION_TOL: f64 = 1e-3;

pub(super) struct FlangeQuaternion;

impl PoseConvention for FlangeQuaternion {
    fn first_column(&self) -> &'static str {
        POSE_COLUMNS[0]
    }

    fn header_hint(&self) -> String {
        POSE_COLUMNS.join(",")
    }

    fn columns(&self, _n: usize) -> Vec<String> {
        POSE_COLUMNS.iter().map(|s| s.to_string()).collect()
    }

    fn check_header(&self, n: usize, _robot: Option<&Robot>) -> Option<String> {
        (n != POSE_COLUMNS.len()).then(|| {
            format!(
                "flange-pose header has {n} columns after the image columns, expected {} (`{}`)",
                POSE_COLUMNS.len(),
                POSE_COLUMNS.join(",")
            )
        })
    }

    fn reading(&self, v: Vec<f64>) -> Result<RobotReading, (String, String)> {
        let q = Quaternion::new(v[3], v[4], v[5], v[6]);
        let norm = q.norm();
        if (norm - 1.0).abs() > QUATERNION_TOL {
            return Err((
                "columns qw..qz".into(),
                format!(
                    "quaternion (qw, qx, qy, qz) = ({}, {}, {}, {}) has norm {norm}, expected 1 (within {QUATERNION_TOL})",
                    v[3], v[4], v[5], v[6]
                ),
            ));
        }
        Ok(RobotReading::FlangePose(Iso3::from_parts(
            Translation3::new(v[0], v[1], v[2]),
            UnitQuaternion::from_quaternion(q),
        )))
    }

    fn values(&self, r: &RobotReading) -> Option<Vec<f64>> {
        match r {
            RobotReading::FlangePose(t) => {
                let v = t.translation.vector;
                let q = t.rotation.quaternion();
                Some(vec![v.x, v.y, v.z, q.w, q.i, q.j, q.k])
            }
            _ => None,
        }
    }

    fn describe(&self, _n: usize) -> String {
        "a flange pose".into()
    }
}
