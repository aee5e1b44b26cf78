//! Encoder readings `q1,...,qN` in degrees: the pose is the robot's forward kinematics.

use super::PoseConvention;
use crate::model::kinematics::Robot;
use crate::model::RobotReading;

pub(super) struct Joints;

impl PoseConvention for Joints {
    fn first_column(&self) -> &'static str {
        "q1"
    }

    fn header_hint(&self) -> String {
        "q1,...,qN".into()
    }

    fn columns(&self, n: usize) -> Vec<String> {
        (1..=n).map(|i| format!("q{i}")).collect()
    }

    fn check_header(&self, n: usize, robot: Option<&Robot>) -> Option<String> {
        let r = robot?;
        (n != r.dof())
            .then(|| format!("header has {n} joint columns, robot has {} joints", r.dof()))
    }

    fn reading(&self, values: Vec<f64>) -> Result<RobotReading, (String, String)> {
        Ok(RobotReading::Joints(values))
    }

    fn values(&self, r: &RobotReading) -> Option<Vec<f64>> {
        match r {
            RobotReading::Joints(q) => Some(q.clone()),
            _ => None,
        }
    }

    fn describe(&self, n: usize) -> String {
        format!("{n} joint readings")
    }
}
