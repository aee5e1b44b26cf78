//! Encoder readings `q1,...,qN` in degrees, in that order: the pose is the robot's
//! forward kinematics (rig.json's DH table), computed after reading.

use crate::model::kinematics::Robot;

/// Whether `name` is a joint column: `q` followed by digits (`q1`, `q12`).
pub(super) fn is_joint_column(name: &str) -> bool {
    name.len() > 1 && name.starts_with('q') && name[1..].bytes().all(|b| b.is_ascii_digit())
}

/// `q1..qN`.
pub(super) fn columns(n: usize) -> Vec<String> {
    (1..=n).map(|i| format!("q{i}")).collect()
}

/// The number of joint columns of a header whose value columns are `rest` (the first of
/// which is header column `first`, 1-based); they must be exactly `q1,...,qN`.
pub(super) fn check_header(rest: &[&str], first: usize) -> Result<usize, String> {
    for (i, got) in rest.iter().enumerate() {
        let want = format!("q{}", i + 1);
        if *got == want {
            continue;
        }
        return Err(if is_joint_column(got) {
            format!("header column {} is `{got}`, expected `{want}`", first + i)
        } else {
            format!(
                "header column {} is `{got}`, expected `{want}`: a header has joint readings \
                 `q1,...,qN` or pose columns, not both",
                first + i
            )
        });
    }
    Ok(rest.len())
}

/// What is wrong with `n` joint columns for `robot`, if anything.
pub(super) fn check_robot(n: usize, robot: Option<&Robot>) -> Option<String> {
    let r = robot?;
    (n != r.dof()).then(|| format!("header has {n} joint columns, robot has {} joints", r.dof()))
}
