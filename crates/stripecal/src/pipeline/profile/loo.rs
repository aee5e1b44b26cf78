//! A profiler's leave-one-view-out figure (DECISIONS 3): the adjustment without view k
//! (warm-started at the full solution, the same points, the robot held at the refined
//! one), then view k's sphere points against the sphere it predicts from view k's robot
//! pose: the RMS of their distances from that sphere, mm. It measures the data (noise,
//! the robot's own errors), not the fit: a view's own points do not pull the sphere
//! they are compared with.

use nalgebra::Point3;
use rayon::prelude::*;

use super::checks::{held, kept_only, start_at};
use crate::calib::joint::profile::{
    profile_adjustment, ProfileFit, ProfileOptions, ProfileViewObs,
};
use crate::error::Result;

/// A view whose held-out RMS exceeds this many times the median disagrees.
pub const LOO_DISAGREE_FACTOR: f64 = 3.0;

/// One view's held-out figure.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileLooView {
    /// Row in views.csv (0-based).
    pub view: usize,
    /// Sphere points compared.
    pub points: usize,
    /// Their RMS distance from the predicted sphere, mm.
    pub rms_mm: f64,
    /// Beyond [`LOO_DISAGREE_FACTOR`] times the median.
    pub disagrees: bool,
}

/// The leave-one-view-out figures.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileLoo {
    pub views: Vec<ProfileLooView>,
    pub median_rms_mm: f64,
}

/// RMS distance of `points[sel]` of a view at flange pose `a` from the sphere of `fit`.
pub fn held_out_rms(
    points: &[[f64; 2]],
    sel: &[usize],
    a: &crate::model::geometry::Iso3,
    hand_sensor: &crate::model::geometry::Iso3,
    centre: &nalgebra::Vector3<f64>,
    diameter: f64,
) -> f64 {
    let t = a * hand_sensor;
    let ss: f64 = sel
        .iter()
        .map(|&i| {
            let p = t * Point3::new(points[i][0], 0.0, points[i][1]);
            ((p.coords - centre).norm() - 0.5 * diameter).powi(2)
        })
        .sum();
    (ss / sel.len().max(1) as f64).sqrt()
}

/// The figures of every view of `obs` (module docs).
pub(super) fn leave_one_out(
    obs: &[ProfileViewObs],
    fit: &ProfileFit,
    popts: &ProfileOptions,
) -> Result<ProfileLoo> {
    let o = kept_only(popts);
    let start = start_at(fit, fit.covariance.index("sphere.diameter_mm").is_some());
    let held = held(obs, fit, 1);
    let mut views: Vec<ProfileLooView> = (0..held.len())
        .into_par_iter()
        .map(|k| -> Result<ProfileLooView> {
            let others: Vec<ProfileViewObs> = held
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != k)
                .map(|(_, v)| v.clone())
                .collect();
            let f = profile_adjustment(&others, &start, &o)?;
            let v = &held[k];
            Ok(ProfileLooView {
                view: v.view,
                points: v.arc.len(),
                rms_mm: held_out_rms(
                    &v.points,
                    &v.arc,
                    &v.a,
                    &f.hand_sensor,
                    &f.centre,
                    f.diameter,
                ),
                disagrees: false,
            })
        })
        .collect::<Result<_>>()?;
    let mut r: Vec<f64> = views.iter().map(|v| v.rms_mm).collect();
    r.sort_by(f64::total_cmp);
    let median = r.get(r.len() / 2).copied().unwrap_or(0.0);
    for v in &mut views {
        v.disagrees = v.rms_mm > LOO_DISAGREE_FACTOR * median;
    }
    Ok(ProfileLoo {
        views,
        median_rms_mm: median,
    })
}
