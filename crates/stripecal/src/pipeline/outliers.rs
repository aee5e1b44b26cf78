//! Step 4: `AX = ZB` over the views with a robot pose, with leave-one-out rejection of
//! views whose robot pose disagrees with their board pose far beyond the others (a
//! swapped or mistyped joint reading).

use super::{CalibrateOptions, ViewStatus};
use crate::calib::axzb::{solve_axzb, AxzbSolution};
use crate::calib::ViewObs;
use crate::error::Result;
use crate::model::geometry::Iso3;
use crate::numerics::robust::median;

/// Rotation (deg) and translation (mm) errors.
type Errors = (f64, f64);

/// Leave-one-out candidate: score, view, its error, the others' median error.
type Candidate = (f64, usize, Errors, Errors);

/// Rotation (deg) and translation (mm) disagreement of `A X` and `Z B`.
fn axzb_error(a: &Iso3, x: &Iso3, z: &Iso3, b: &Iso3) -> (f64, f64) {
    let l = a * x;
    let r = z * b;
    (
        l.rotation.angle_to(&r.rotation).to_degrees(),
        (l.translation.vector - r.translation.vector).norm(),
    )
}

/// `AX = ZB` from the views marked in `keep` (`A` = `T_base_hand`, `B` = `T_board_cam`).
fn solve(obs: &[ViewObs], poses: &[Iso3], keep: &[bool]) -> Result<AxzbSolution> {
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for ((v, cb), k) in obs.iter().zip(poses).zip(keep) {
        if let (true, Some(bh)) = (*k, v.base_hand) {
            a.push(bh);
            b.push(cb.inverse());
        }
    }
    solve_axzb(&a, &b)
}

/// Solves `AX = ZB` for `obs` (with `T_cam_board` `poses`), leaving out views without a
/// robot pose and, one at a time, the view whose removal lets the others agree best
/// while its own disagreement is far beyond theirs (see
/// [`CalibrateOptions::outlier_factor`]). Returns the solution and which views it used;
/// every view left out gets a warning and its status note.
pub(super) fn solve_with_outliers(
    obs: &[ViewObs],
    poses: &[Iso3],
    opts: &CalibrateOptions,
    warnings: &mut Vec<String>,
    status: &mut [ViewStatus],
) -> Result<(AxzbSolution, Vec<bool>)> {
    let mut keep: Vec<bool> = obs.iter().map(|v| v.base_hand.is_some()).collect();
    for (v, k) in obs.iter().zip(&keep) {
        if !k {
            warnings.push(format!("view {}: left out, no robot pose", v.view));
        }
    }
    let standoff = {
        let mut d: Vec<f64> = poses.iter().map(|p| p.translation.vector.norm()).collect();
        median(&mut d).unwrap_or(0.0)
    };
    let mut axzb = solve(obs, poses, &keep)?;
    while let Some((i, (er, et), (mr, mt))) = worst_view(obs, poses, &keep, opts, standoff) {
        keep[i] = false;
        let msg = format!(
            "view {}: left out as an outlier: its robot pose disagrees with its board pose by \
             {er:.3} deg / {et:.3} mm (others: median {mr:.4} deg / {mt:.4} mm); check its \
             joint readings",
            obs[i].view
        );
        warnings.push(msg.clone());
        if let Some(s) = status.iter_mut().find(|s| s.view == obs[i].view) {
            s.note = Some(msg);
        }
        axzb = solve(obs, poses, &keep)?;
    }
    Ok((axzb, keep))
}

/// The leave-one-out candidate when it is an outlier: `(index, its error, the others'
/// median error)`; `None` when no view stands out or 3 or fewer are left.
fn worst_view(
    obs: &[ViewObs],
    poses: &[Iso3],
    keep: &[bool],
    opts: &CalibrateOptions,
    standoff: f64,
) -> Option<(usize, Errors, Errors)> {
    let active: Vec<usize> = (0..obs.len()).filter(|&i| keep[i]).collect();
    if active.len() <= 3 {
        return None;
    }
    // Leave one out: the view whose removal lets the others agree best is the
    // candidate; it is an outlier when its own disagreement under the others'
    // solution is far beyond theirs.
    let mut best: Option<Candidate> = None;
    for &i in &active {
        let mut k2 = keep.to_vec();
        k2[i] = false;
        let Ok(s) = solve(obs, poses, &k2) else {
            continue;
        };
        let err_of = |j: usize| {
            axzb_error(
                &obs[j].base_hand.unwrap_or_else(Iso3::identity),
                &s.x,
                &s.z,
                &poses[j].inverse(),
            )
        };
        let mut rot: Vec<f64> = Vec::new();
        let mut tr: Vec<f64> = Vec::new();
        for &j in active.iter().filter(|&&j| j != i) {
            let e = err_of(j);
            rot.push(e.0);
            tr.push(e.1);
        }
        let (mr, mt) = (
            median(&mut rot).unwrap_or(0.0),
            median(&mut tr).unwrap_or(0.0),
        );
        let score = mr / opts.outlier_min_deg + mt / (opts.outlier_min_rel * standoff);
        if best.is_none_or(|b| score < b.0) {
            best = Some((score, i, err_of(i), (mr, mt)));
        }
    }
    best.and_then(|(_, i, (er, et), (mr, mt))| {
        let lim_r = (opts.outlier_factor * mr).max(opts.outlier_min_deg);
        let lim_t = (opts.outlier_factor * mt).max(opts.outlier_min_rel * standoff);
        (er > lim_r || et > lim_t).then_some((i, (er, et), (mr, mt)))
    })
}
