//! The robot-pose columns of views.csv and scan.csv, one file per convention.
//!
//! A convention names its value columns, checks a header's (their count, the robot's
//! joint count), turns a row's numbers into a [`RobotReading`] and back. The readers
//! tell the convention from the first value column of the header; the writers use the
//! convention of the rows' readings. A new convention is one file here and one entry in
//! [`CONVENTIONS`].

mod flange_quaternion;
mod joints;

use crate::error::{Error, Result};
use crate::model::kinematics::Robot;
use crate::model::RobotReading;

/// One convention of robot-pose columns.
pub(super) trait PoseConvention: Sync {
    /// The first value column's name: it tells the convention from a header.
    fn first_column(&self) -> &'static str;
    /// The header's value columns as the contract writes them (`q1,...,qN`).
    fn header_hint(&self) -> String;
    /// The value column names of a header with `n` value columns.
    fn columns(&self, n: usize) -> Vec<String>;
    /// What is wrong with a header of `n` value columns beyond their names, if anything.
    fn check_header(&self, n: usize, robot: Option<&Robot>) -> Option<String>;
    /// The reading of one row's (finite) values; an error names the columns at fault and
    /// says what is wrong.
    fn reading(&self, values: Vec<f64>) -> std::result::Result<RobotReading, (String, String)>;
    /// The values of `r` in this convention's columns, or `None` when `r` is not written
    /// in this convention.
    fn values(&self, r: &RobotReading) -> Option<Vec<f64>>;
    /// How a row with `n` values is described in messages ("6 joint readings").
    fn describe(&self, n: usize) -> String;
}

/// Every convention, in the order the header hint names them.
pub(super) static CONVENTIONS: [&dyn PoseConvention; 2] =
    [&joints::Joints, &flange_quaternion::FlangeQuaternion];

/// A table's value columns: a convention and how many columns it has.
#[derive(Clone, Copy)]
pub(super) struct Layout {
    pub convention: &'static dyn PoseConvention,
    pub n: usize,
}

impl PartialEq for Layout {
    fn eq(&self, other: &Self) -> bool {
        self.convention.first_column() == other.convention.first_column() && self.n == other.n
    }
}

impl Layout {
    /// The layout of a header whose value columns are `rest`, when a convention knows it.
    pub fn of_header(rest: &[&str]) -> Option<Layout> {
        let first = *rest.first()?;
        CONVENTIONS
            .iter()
            .find(|c| c.first_column() == first)
            .map(|&convention| Layout {
                convention,
                n: rest.len(),
            })
    }

    /// The layout a reading is written in, with its values; an error when no
    /// convention writes it (a reading variant without a registered convention).
    pub fn of_reading(r: &RobotReading) -> Result<(Layout, Vec<f64>)> {
        CONVENTIONS
            .iter()
            .find_map(|&convention| {
                convention.values(r).map(|v| {
                    (
                        Layout {
                            convention,
                            n: v.len(),
                        },
                        v,
                    )
                })
            })
            .ok_or_else(|| {
                Error::InvalidInput(format!("no pose convention writes the reading {r:?}"))
            })
    }

    pub fn column_names(self) -> Vec<String> {
        self.convention.columns(self.n)
    }

    pub fn describe(self) -> String {
        self.convention.describe(self.n)
    }
}

/// The contract's headers for image columns `names`: "`n,q1,...,qN` or `n,x_mm,...`".
pub(super) fn expected_header(names: &[&str]) -> String {
    let n = names.join(",");
    CONVENTIONS
        .iter()
        .map(|c| format!("`{n},{}`", c.header_hint()))
        .collect::<Vec<_>>()
        .join(" or ")
}

/// The first value columns the conventions start with: "`q1` or `x_mm`".
pub(super) fn first_columns() -> String {
    CONVENTIONS
        .iter()
        .map(|c| format!("`{}`", c.first_column()))
        .collect::<Vec<_>>()
        .join(" or ")
}
