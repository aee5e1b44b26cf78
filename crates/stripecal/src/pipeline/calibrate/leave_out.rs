//! The adjustment, then the views whose residuals (or robot poses) stand far above the
//! others' left out once and the adjustment run again, when enough views remain: the
//! one loop of the robot and the bench pipelines.

use super::gates::views_check;
use super::stages::laser_plane_stage;
use super::views::{check_usable, kept};
use super::ViewStatus;
use crate::calib::joint::{JointResult, JointStart};
use crate::calib::laser_plane::LaserPlaneFit;
use crate::calib::ViewObs;
use crate::error::Result;
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::QualityCheck;

/// The views an adjustment uses and their board poses (the camera stage's), row by row.
pub(super) struct UsedViews {
    pub obs: Vec<ViewObs>,
    pub poses: Vec<Iso3>,
}

/// The outcome of [`adjust_leaving_out_once`]: the last pass's laser plane (first
/// estimate), start and adjustment, the `views` gate's check, and whether views were
/// left out.
pub(super) struct Adjusted {
    pub plane: Option<LaserPlaneFit>,
    pub start: JointStart,
    pub adjustment: JointResult,
    pub views_check: QualityCheck,
    pub left_out: bool,
}

/// Laser plane and adjustment (`adjust`: the start from the plane, and the adjustment
/// from the start) over `used`; the views `outliers` names (from the adjustment and
/// whether this is the first pass; it may add warnings) are left out once
/// ([`leave_out`]) and the pass repeated, unless none is named or the `views` gate (of
/// `total` views) fails. The plane stage's warnings of the last pass only are added to
/// `warnings` (a refit repeats them).
pub(super) fn adjust_leaving_out_once(
    used: &mut UsedViews,
    camera: &Camera,
    total: usize,
    warnings: &mut Vec<String>,
    status: &mut [ViewStatus],
    mut adjust: impl FnMut(&UsedViews, Option<Plane>) -> Result<(JointStart, JointResult)>,
    mut outliers: impl FnMut(&JointResult, bool, &mut Vec<String>) -> (Vec<usize>, String),
) -> Result<Adjusted> {
    let mut first_pass = true;
    loop {
        let mut plane_warnings = Vec::new();
        let plane = laser_plane_stage(&used.obs, &used.poses, camera, &mut plane_warnings)?;
        let (start, adjustment) = adjust(used, plane.as_ref().map(|p| p.plane))?;
        let (bad, msg) = outliers(&adjustment, first_pass, warnings);
        let kept_n = used.obs.len() - bad.len();
        let check = views_check(&bad, &msg, kept_n, total);
        if bad.is_empty() || !check.passed || !first_pass {
            warnings.extend(plane_warnings);
            return Ok(Adjusted {
                plane,
                start,
                adjustment,
                views_check: check,
                left_out: !first_pass,
            });
        }
        first_pass = false;
        leave_out(&bad, &msg, &mut used.obs, &mut used.poses, warnings, status)?;
    }
}

/// The views `bad` (residuals far above the others', `msg` says how) named in
/// `warnings` and `status` and left out of `used_obs` and `used_poses`; an error when too
/// few remain ([`check_usable`]).
pub(super) fn leave_out(
    bad: &[usize],
    msg: &str,
    used_obs: &mut Vec<ViewObs>,
    used_poses: &mut Vec<Iso3>,
    warnings: &mut Vec<String>,
    status: &mut [ViewStatus],
) -> Result<()> {
    for &v in bad {
        let note = format!("view {v}: left out: {msg}");
        warnings.push(note.clone());
        if let Some(s) = status.iter_mut().find(|s| s.view == v) {
            s.note = Some(note);
        }
    }
    let keep: Vec<bool> = used_obs.iter().map(|v| !bad.contains(&v.view)).collect();
    (*used_obs, *used_poses) = kept(used_obs, used_poses, &keep);
    check_usable(used_obs, warnings)
}
