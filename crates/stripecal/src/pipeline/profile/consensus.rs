//! Which profiles belong to their robot poses: the closed-form start over the views with
//! an arc; while one view's misfit stands out ([`SUSPECT_FACTOR`] times the median), the
//! view whose removal leaves the others most consistent is left out when their solution
//! places it far beyond their own misfits ([`REMOVE_FLOOR_MM`]) and enough views remain
//! (DECISIONS 2's consensus, for a profiler).

use crate::calib::joint::profile::ProfileViewObs;
use crate::calib::profile::arc::Arc;
use crate::calib::profile::start::{closed_form, with_sides, CircleView, Start, Starts, MIN_VIEWS};
use crate::error::{Error, Result};

/// Misfits below this many mm never make the solution suspect (noise and a robot's own
/// pose errors).
/// A view whose misfit exceeds this many times the median (and the floor) makes the
/// solution suspect: the view whose removal leaves the others most consistent is then
/// judged against the others' own misfits (a view that does not
/// belong pulls the solution and inflates every misfit, so the median alone hides it).
pub const SUSPECT_FACTOR: f64 = 3.0;
/// A suspect view is left out when the others place it beyond [`SUSPECT_FACTOR`] times
/// their own median misfit and beyond this many mm (a robot's own pose errors stay
/// below it; one of two swapped views still sees the other in the others' solution).
pub const REMOVE_FLOOR_MM: f64 = 2.0;
pub const CONSENSUS_FLOOR_MM: f64 = 1.0;

/// The start from the views that agree, and the views left out with why.
pub(super) struct Consensus {
    pub starts: Starts,
    /// `(views.csv row, note)`.
    pub left_out: Vec<(usize, String)>,
}

/// The view whose removal leaves the others' solution (sides held) with the smallest
/// RMS misfit: `(its index, the others' median misfit, its own misfit predicted by them)`.
fn most_inconsistent(views: &[CircleView], start: &Start) -> Option<(usize, f64, f64)> {
    let mut best: Option<(f64, usize, f64, f64)> = None;
    for k in 0..views.len() {
        let others: Vec<CircleView> = views
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != k)
            .map(|(_, v)| *v)
            .collect();
        let sides: Vec<f64> = start
            .sides
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != k)
            .map(|(_, s)| *s)
            .collect();
        let Some(s) = with_sides(&others, start.radius, &sides) else {
            continue;
        };
        let rms = s.rms_mm();
        // the view may sit on either side of the others' solution
        let pred = s
            .misfit_of(&views[k], 1.0)
            .min(s.misfit_of(&views[k], -1.0));
        if best.is_none_or(|b| rms < b.0) {
            best = Some((rms, k, median(&s.misfit_mm), pred));
        }
    }
    best.map(|(_, k, med, pred)| (k, med, pred))
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    if s.is_empty() {
        return 0.0;
    }
    s[s.len() / 2]
}

/// The consensus (module docs) of `obs` (with their arcs `arcs`); `radius` the declared
/// sphere radius.
pub(super) fn consensus(
    obs: &[ProfileViewObs],
    arcs: &[Arc],
    radius: Option<f64>,
) -> Result<Consensus> {
    if obs.len() < MIN_VIEWS {
        return Err(Error::Degenerate(format!(
            "the sphere was found in {} profiles; a profiler's calibration needs at least \
             {MIN_VIEWS} (views: {})",
            obs.len(),
            obs.iter()
                .map(|o| o.view.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let mut idx: Vec<usize> = (0..obs.len()).collect();
    let mut left_out = Vec::new();
    loop {
        let views: Vec<CircleView> = idx
            .iter()
            .map(|&i| CircleView {
                a: obs[i].a,
                centre: arcs[i].centre,
                radius: arcs[i].radius,
            })
            .collect();
        let starts = closed_form(&views, radius)?;
        let m = &starts.chosen.misfit_mm;
        let med = median(m);
        let worst = m.iter().copied().fold(0.0, f64::max);
        if worst <= (SUSPECT_FACTOR * med).max(CONSENSUS_FLOOR_MM) {
            return Ok(Consensus { starts, left_out });
        }
        // A view that does not belong pulls the solution and inflates every misfit:
        // find the view whose removal leaves the others most consistent (the others'
        // sides as they are), and leave it out when the others' solution places it far
        // beyond their own misfits.
        let (k, others_med, pred) = match most_inconsistent(&views, &starts.chosen) {
            Some(x) => x,
            None => return Ok(Consensus { starts, left_out }),
        };
        if pred <= (SUSPECT_FACTOR * others_med).max(REMOVE_FLOOR_MM) {
            return Ok(Consensus { starts, left_out });
        }
        let (worst, med) = (pred, others_med);
        let row = obs[idx[k]].view;
        if idx.len() <= MIN_VIEWS {
            return Err(Error::Quality(Box::new(crate::model::QualityFailure {
                failed: vec![crate::model::QualityCheck::fail(
                    "pairing",
                    format!(
                        "view {row}'s profile puts the sphere {worst:.2} mm from where the \
                         other views' robot poses put it (median {med:.3} mm), and with \
                         {} views none can be left out",
                        idx.len()
                    ),
                    vec![row],
                )],
                report: None,
            })));
        }
        left_out.push((
            row,
            format!(
                "view {row}: its profile puts the sphere {worst:.2} mm from where the other \
                 views' robot poses put it (median {med:.3} mm): its pose does not belong to \
                 this profile (a swapped or mistyped pose?); left out"
            ),
        ));
        idx.remove(k);
    }
}
