//! The views' bookkeeping: the views (and poses) kept, whether enough remain, and each
//! view's status once the calibration has decided on it.

use super::ViewStatus;
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::numerics::robust::median;

/// The views (and poses) marked in `keep`.
pub(super) fn kept(obs: &[ViewObs], poses: &[Iso3], keep: &[bool]) -> (Vec<ViewObs>, Vec<Iso3>) {
    let used_obs = obs
        .iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(v, _)| v.clone())
        .collect();
    let used_poses = poses
        .iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(p, _)| *p)
        .collect();
    (used_obs, used_poses)
}

/// An error naming the warnings when fewer than 3 views remain.
pub(super) fn check_usable(used_obs: &[ViewObs], warnings: &[String]) -> Result<()> {
    if used_obs.len() < 3 {
        return Err(Error::InvalidInput(format!(
            "calibration needs at least 3 usable views, {} left ({})",
            used_obs.len(),
            warnings.join("; ")
        )));
    }
    Ok(())
}

/// Each view's status: used (with its stripe points kept) or, without a reason yet, left
/// out by the camera calibration.
pub(super) fn mark_used(status: &mut [ViewStatus], used_obs: &[ViewObs]) {
    for s in status.iter_mut() {
        if let Some(v) = used_obs.iter().find(|v| v.view == s.view) {
            s.used = true;
            s.stripe_used = v.stripe.len();
        } else if s.note.is_none() {
            s.note = Some("left out by the camera calibration".into());
        }
    }
}

/// The median stand-off of the board poses (mm; `None` without poses): the scale the
/// `determined` gate reads translations against.
pub(super) fn median_standoff(poses: &[Iso3]) -> Option<f64> {
    let mut d: Vec<f64> = poses.iter().map(|p| p.translation.vector.norm()).collect();
    median(&mut d)
}
