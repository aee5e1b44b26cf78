//! Steps 1 and 2 of a profiler's calibration (the module docs of
//! [`super`]): each profile's arc of the sphere, then the consensus over the views with
//! an arc and its closed-form start. [`calibrate_profiles`](super::calibrate_profiles)
//! runs them before its adjustment; [`prepare`] returns what they found, so that another
//! solver can be started from the same start over the same points (the scipy comparison
//! of BENCHMARKS.md, "Profiler calibration").
//!
//! A view's sphere points here are its arc's inliers (indices into its profile's
//! points); the adjustment starts from them and re-selects them after each solve.

use crate::calib::joint::profile::{ProfileStart, ProfileViewObs};
use crate::calib::profile::arc::{find_arc, Arc, ArcOptions};
use crate::calib::profile::start::Starts;
use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::model::{ProfileRig, RobotReading};

use super::{arc_options, consensus, status_of, view_name, ProfileInput, ProfileViewStatus};

/// What the arcs and the consensus found.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The views kept (an arc, and in the consensus), in views.csv order: their flange
    /// poses `a` (`T_base_hand` of the readings), points and arc inliers.
    pub views: Vec<ProfileViewObs>,
    /// The closed-form start the adjustment starts from (`diameter` declared or the
    /// start's, `diameter_free` when rig.json's `diameter_mm` is null).
    pub start: ProfileStart,
    /// The mirrored start (the mirror test's).
    pub mirror: ProfileStart,
    /// Every view's status so far (`arc_points`, the note of a view left out).
    pub status: Vec<ProfileViewStatus>,
    /// The views left out, named, and why.
    pub warnings: Vec<String>,
}

/// Rejects what no profiler calibration can start from: no profiles, or views without
/// robot poses.
pub(super) fn check_inputs(inputs: &[ProfileInput]) -> Result<()> {
    if inputs.is_empty() {
        return Err(Error::Degenerate("no profiles to calibrate from".into()));
    }
    if inputs.iter().any(|i| i.reading == RobotReading::Fixed) {
        return Err(Error::InvalidInput(
            "a profiler is calibrated from robot poses: views.csv needs joint readings or \
             flange-pose columns beside the profile column"
                .into(),
        ));
    }
    Ok(())
}

/// The adjustment's start from a closed-form one, the rig's diameter when declared.
pub(super) fn start_of(rig: &ProfileRig, s: &crate::calib::profile::start::Start) -> ProfileStart {
    ProfileStart {
        hand_sensor: s.hand_sensor,
        centre: s.centre,
        diameter: rig.diameter_mm.unwrap_or(2.0 * s.radius),
        diameter_free: rig.diameter_mm.is_none(),
    }
}

/// Steps 1 and 2 (module docs): the views kept and the closed-form starts; `status` and
/// `warnings` get the views left out.
pub(super) fn arcs_and_consensus(
    inputs: &[ProfileInput],
    rig: &ProfileRig,
    status: &mut [ProfileViewStatus],
    warnings: &mut Vec<String>,
) -> Result<(Vec<ProfileViewObs>, Starts)> {
    // The arcs' side (which way z counts) is the profiler's, one for all views: a view
    // whose best arc says otherwise is searched again on the majority's side.
    let aopts = arc_options(rig);
    let mut found: Vec<Option<(Iso3, Arc)>> = Vec::with_capacity(inputs.len());
    for (k, inp) in inputs.iter().enumerate() {
        let a = inp
            .reading
            .base_hand(rig.robot.as_ref())
            .map_err(|e| Error::InvalidInput(format!("{}: {e}", view_name(inp))))?;
        match find_arc(&inp.profile.points, &aopts, inp.view as u64) {
            Ok(arc) => found.push(Some((a, arc))),
            Err(why) => {
                let note = format!("{}: {why}; left out", view_name(inp));
                warnings.push(note.clone());
                status[k].note = Some(note);
                found.push(None);
            }
        }
    }
    let up = found
        .iter()
        .flatten()
        .filter(|(_, arc)| arc.side > 0.0)
        .count();
    let side = if 2 * up >= found.iter().flatten().count() {
        1.0
    } else {
        -1.0
    };
    let forced = ArcOptions {
        side: Some(side),
        ..aopts
    };
    let mut obs: Vec<ProfileViewObs> = Vec::new();
    let mut arcs = Vec::new();
    for (k, (inp, f)) in inputs.iter().zip(found).enumerate() {
        let Some((a, mut arc)) = f else { continue };
        if arc.side != side {
            match find_arc(&inp.profile.points, &forced, inp.view as u64) {
                Ok(again) => arc = again,
                Err(why) => {
                    let note = format!(
                        "{}: its best arc bulges the other way from the other profiles', and \
                         on their side {why}; left out",
                        view_name(inp)
                    );
                    warnings.push(note.clone());
                    status[k].note = Some(note);
                    continue;
                }
            }
        }
        status[k].arc_points = arc.inliers.len();
        obs.push(ProfileViewObs {
            view: inp.view,
            a,
            q: match &inp.reading {
                RobotReading::Joints(q) => Some(q.clone()),
                _ => None,
            },
            points: inp.profile.points.clone(),
            arc: arc.inliers.clone(),
        });
        arcs.push(arc);
    }
    let cons = consensus::consensus(&obs, &arcs, rig.diameter_mm.map(|d| 0.5 * d))?;
    for (row, note) in &cons.left_out {
        if let Some(s) = status.iter_mut().find(|s| s.view == *row) {
            s.note = Some(note.clone());
        }
        warnings.push(note.clone());
    }
    let obs: Vec<ProfileViewObs> = obs
        .into_iter()
        .filter(|o| !cons.left_out.iter().any(|(r, _)| *r == o.view))
        .collect();
    Ok((obs, cons.starts))
}

/// Steps 1 and 2 of [`calibrate_profiles`](super::calibrate_profiles) alone: the views
/// kept, their arcs' points and the closed-form start (module docs).
pub fn prepare(inputs: &[ProfileInput], rig: &ProfileRig) -> Result<Prepared> {
    check_inputs(inputs)?;
    let mut warnings = Vec::new();
    let mut status: Vec<ProfileViewStatus> = inputs.iter().map(status_of).collect();
    let (views, starts) = arcs_and_consensus(inputs, rig, &mut status, &mut warnings)?;
    Ok(Prepared {
        views,
        start: start_of(rig, &starts.chosen),
        mirror: start_of(rig, &starts.mirror),
        status,
        warnings,
    })
}
