//! Which profiles belong to their robot poses (DECISIONS 2's consensus, for a profiler):
//! the closed-form start over the views with an arc; when a view's misfit stands out
//! ([`SUSPECT_FACTOR`] times the median) or the median itself is beyond
//! [`REMOVE_FLOOR_MM`], the largest set of views that agree is found by RANSAC over
//! subsets of views (each solved in closed form with its own sides: a view that does not
//! belong can pull every side of a solution over all views), and the views their
//! solution places far beyond their own misfits are named and left out.

use crate::calib::joint::profile::ProfileViewObs;
use crate::calib::profile::arc::Arc;
use crate::calib::profile::start::{closed_form, CircleView, Starts, MIN_VIEWS};
use crate::error::{Error, Result};
use crate::numerics::rng::SplitMix64;

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

/// The median of `v` ([`crate::numerics::robust::median`]; 0 when empty).
fn median(v: &[f64]) -> f64 {
    crate::numerics::robust::median(&mut v.to_vec()).unwrap_or(0.0)
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
    let views: Vec<CircleView> = obs
        .iter()
        .zip(arcs)
        .map(|(o, arc)| CircleView {
            a: o.a,
            centre: arc.centre,
            radius: arc.radius,
        })
        .collect();
    let starts = closed_form(&views, radius)?;
    let m = &starts.chosen.misfit_mm;
    let med = median(m);
    let worst = m.iter().copied().fold(0.0, f64::max);
    if worst <= (SUSPECT_FACTOR * med).max(CONSENSUS_FLOOR_MM) && med <= REMOVE_FLOOR_MM {
        return Ok(Consensus {
            starts,
            left_out: Vec::new(),
        });
    }
    // Views that do not belong pull the solution, and its sides, and inflate every
    // misfit: find the largest set of views that agree (RANSAC over subsets of
    // SAMPLE_VIEWS views, each solved in closed form with its own sides), then solve
    // those and leave out the views it places far beyond their own misfits.
    let inliers = agreeing_views(&views, radius);
    let kept: Vec<usize> = match &inliers {
        Some(k) if k.len() >= MIN_VIEWS && k.len() < views.len() => k.clone(),
        _ => {
            return Ok(Consensus {
                starts,
                left_out: Vec::new(),
            })
        }
    };
    let sub: Vec<CircleView> = kept.iter().map(|&i| views[i]).collect();
    let agreed = closed_form(&sub, radius)?;
    let med = median(&agreed.chosen.misfit_mm);
    let limit = (SUSPECT_FACTOR * med).max(REMOVE_FLOOR_MM);
    let mut left_out = Vec::new();
    for (i, v) in views.iter().enumerate() {
        if kept.contains(&i) {
            continue;
        }
        let pred = agreed
            .chosen
            .misfit_of(v, 1.0)
            .min(agreed.chosen.misfit_of(v, -1.0));
        if pred > limit {
            let row = obs[i].view;
            left_out.push((
                row,
                format!(
                    "view {row}: its profile puts the sphere {pred:.2} mm from where the other \
                     views' robot poses put it (their median {med:.3} mm): its pose does not \
                     belong to this profile (a swapped or mistyped pose?); left out"
                ),
            ));
        }
    }
    if left_out.is_empty() {
        return Ok(Consensus { starts, left_out });
    }
    let keep: Vec<CircleView> = views
        .iter()
        .zip(obs)
        .filter(|(_, o)| !left_out.iter().any(|(r, _)| *r == o.view))
        .map(|(v, _)| *v)
        .collect();
    let starts = closed_form(&keep, radius)?;
    Ok(Consensus { starts, left_out })
}

/// Views in each RANSAC sample.
const SAMPLE_VIEWS: usize = 7;
/// RANSAC samples.
const SAMPLES: usize = 40;

/// The largest set of views one sample's closed-form solution places within
/// [`REMOVE_FLOOR_MM`] plus [`SUSPECT_FACTOR`] times the sample's own median misfit
/// (ties: the smaller sum of misfits), over the samples that agree with themselves (their
/// own median misfit within [`REMOVE_FLOOR_MM`]); `None` with too few views to sample.
fn agreeing_views(views: &[CircleView], radius: Option<f64>) -> Option<Vec<usize>> {
    let n = views.len();
    if n <= SAMPLE_VIEWS {
        return None;
    }
    let mut rng = SplitMix64(0x5eed ^ n as u64);
    let mut best: Option<(usize, f64, Vec<usize>)> = None;
    for _ in 0..SAMPLES {
        let mut pick: Vec<usize> = Vec::with_capacity(SAMPLE_VIEWS);
        while pick.len() < SAMPLE_VIEWS {
            let k = rng.below(n);
            if !pick.contains(&k) {
                pick.push(k);
            }
        }
        let sample: Vec<CircleView> = pick.iter().map(|&i| views[i]).collect();
        let Ok(st) = closed_form(&sample, radius) else {
            continue;
        };
        let own = median(&st.chosen.misfit_mm);
        if own > REMOVE_FLOOR_MM {
            // the sample disagrees with itself: it holds a view that does not belong
            continue;
        }
        let thr = REMOVE_FLOOR_MM + SUSPECT_FACTOR * own;
        let mis: Vec<f64> = views
            .iter()
            .map(|v| {
                st.chosen
                    .misfit_of(v, 1.0)
                    .min(st.chosen.misfit_of(v, -1.0))
            })
            .collect();
        let inl: Vec<usize> = (0..n).filter(|&i| mis[i] < thr).collect();
        let sum: f64 = inl.iter().map(|&i| mis[i]).sum();
        let better = match &best {
            None => true,
            Some((c, s, _)) => inl.len() > *c || (inl.len() == *c && sum < *s),
        };
        if better {
            best = Some((inl.len(), sum, inl));
        }
    }
    best.map(|(_, _, inl)| inl)
}
