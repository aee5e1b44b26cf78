//! Which profiles belong to their robot poses: the closed-form start over the views with
//! an arc, the view whose sphere centre the others' solution places worst left out while
//! it is far beyond the others' misfits and enough views remain (DECISIONS 2's
//! consensus, for a profiler).

use crate::calib::joint::profile::ProfileViewObs;
use crate::calib::profile::arc::Arc;
use crate::calib::profile::start::{closed_form, CircleView, Starts, MIN_VIEWS};
use crate::error::{Error, Result};

/// A view disagrees when its misfit exceeds this many times the median...
pub const CONSENSUS_FACTOR: f64 = 10.0;
/// ... and this many mm (the robot's own errors stay below it).
pub const CONSENSUS_FLOOR_MM: f64 = 1.0;

/// The start from the views that agree, and the views left out with why.
pub(super) struct Consensus {
    pub starts: Starts,
    /// `(views.csv row, note)`.
    pub left_out: Vec<(usize, String)>,
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
        let (k, worst) = m
            .iter()
            .enumerate()
            .fold((0, 0.0), |b, (k, &e)| if e > b.1 { (k, e) } else { b });
        let limit = (CONSENSUS_FACTOR * med).max(CONSENSUS_FLOOR_MM);
        if worst <= limit {
            return Ok(Consensus { starts, left_out });
        }
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
