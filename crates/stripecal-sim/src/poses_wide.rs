//! Wide-excursion calibration pose sets (`poses.spread = "wide"`), for robot kinematic
//! calibration: every joint should move as far as the views' constraints allow.
//!
//! The candidates are the local sampler's ([`PoseProblem::sample`]: the wide set spans at
//! least their range) and many more, sampled over the whole allowed range (look point
//! within half a pitch of the pattern's centre, anywhere over the plate for a stripe
//! beside the pattern; any tilt up to `max_tilt_deg` in any direction, roll up to
//! `max_roll_deg`, any stand-off), each solved by inverse kinematics from the home pose
//! or, one attempt in four, from a random start within the joint excursions (other
//! branches of the arm), and kept when [`PoseProblem::check`] accepts it (board in view
//! with margin, stand-off, tilt, laser incidence, stripe across the pattern, joint
//! excursions). Then `count` of
//! them are picked: each joint's lowest and highest candidate first (the set spans each
//! joint's whole feasible excursion), then greedy farthest-point selection in joint
//! space with each joint's excursion from home divided by `max_joint_delta_deg`.

use nalgebra::{UnitQuaternion, Vector3};

use stripecal::model::geometry::Iso3;

use crate::poses::{axis_spread, PoseInfo, PoseProblem};
use crate::rng::Rng;
use crate::target;
use crate::SimError;

/// The random stream of the wide sampler (the local sampler's is another).
const WIDE_STREAM: u64 = 0x905e_3a1d;

/// Candidates kept before selection: this many per requested pose, at least
/// [`MIN_POOL`].
pub const POOL_PER_POSE: usize = 40;
/// Smallest candidate pool.
pub const MIN_POOL: usize = 400;

impl PoseProblem<'_> {
    /// `count` poses spread wide in joint space, deterministic by `seed` (see the
    /// module docs).
    pub fn sample_wide(&self, count: usize, seed: u64) -> Result<Vec<PoseInfo>, SimError> {
        let scene0 = (self.scene)(&Iso3::identity());
        let board = scene0.board().clone();
        let want = (POOL_PER_POSE * count).max(MIN_POOL);
        let max_attempts = 30 * want;
        // Look points as the local sampler's (the pattern must stay in view: near its
        // centre; beside it: anywhere over the plate), the same.
        let center = target::points_center(&board);
        let spread = if self.stripe_beside_pattern {
            let [x0, x1, y0, y1] = scene0.plate_extent();
            Vector3::new(0.5 * (x1 - x0), 0.5 * (y1 - y0), 0.0)
        } else {
            Vector3::new(1.0, 1.0, 0.0) * board.pitch_mm * 0.5
        };
        let mut rng = Rng::new(seed, WIDE_STREAM);
        // The local sampler's candidates first: the wide set spans at least their range.
        let (mut pool, mut last_reason, local_attempts) = self.local_candidates(count, seed);
        let want = want + pool.len();
        let dmax = self.max_joint_delta_deg;
        for attempt in 0..max_attempts {
            if pool.len() >= want {
                break;
            }
            let tilt = self.max_tilt_deg.to_radians() * rng.uniform().sqrt();
            let az = rng.range(0.0, std::f64::consts::TAU);
            let roll = rng.range(-1.0, 1.0) * self.max_roll_deg.to_radians();
            let s = rng.range(self.standoff[0], self.standoff[1]);
            let look = center
                + Vector3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0)
                    .component_mul(&spread);
            // One attempt in four starts the IK away from home: other arm branches.
            let start: Vec<f64> = if attempt % 4 != 3 {
                self.home_q.to_vec()
            } else {
                self.home_q
                    .iter()
                    .map(|h| h + rng.range(-dmax, dmax))
                    .collect()
            };
            match self.try_pose(&look, tilt, az, roll, s, &start) {
                Ok(found) => pool.push(found),
                Err(e) => last_reason = e,
            }
        }
        if pool.len() < count {
            return Err(SimError::Poses(format!(
                "wide poses: found {} valid poses of the {count} requested after {} \
                 attempts (last rejection: {last_reason}); widen poses.standoff_mm / \
                 max_tilt_deg or reduce margin_px",
                pool.len(),
                max_attempts + local_attempts
            )));
        }
        let coords: Vec<Vec<f64>> = pool
            .iter()
            .map(|(p, _)| {
                p.q_deg
                    .iter()
                    .zip(self.home_q)
                    .map(|(q, h)| (q - h) / dmax.max(1e-9))
                    .collect()
            })
            .collect();
        let chosen = farthest_points(&coords, count);
        let rots: Vec<UnitQuaternion<f64>> = chosen.iter().map(|&i| pool[i].1).collect();
        if count >= 3 {
            let spread = axis_spread(&rots);
            if spread < 0.05 {
                return Err(SimError::Poses(format!(
                    "the wide poses rotate about nearly parallel axes (axis spread {spread:.3}); \
                     increase poses.max_tilt_deg or max_roll_deg"
                )));
            }
        }
        Ok(chosen.into_iter().map(|i| pool[i].0.clone()).collect())
    }
}

/// Selection of `count` of `points` (Euclidean): first each coordinate's lowest and
/// highest point in turn (so the set spans every coordinate's whole range: the pool's
/// extreme excursion of every joint), as long as `count` allows, then greedy
/// farthest-point selection; ties go to the lower index.
pub fn farthest_points(points: &[Vec<f64>], count: usize) -> Vec<usize> {
    let d2 = |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum() };
    let count = count.min(points.len());
    if count == 0 {
        return vec![];
    }
    let mut chosen: Vec<usize> = Vec::new();
    'extremes: for j in 0..points[0].len() {
        let lo = (0..points.len()).min_by(|&a, &b| points[a][j].total_cmp(&points[b][j]));
        let hi = (0..points.len())
            .max_by(|&a, &b| points[a][j].total_cmp(&points[b][j]).then(b.cmp(&a)));
        for i in [lo, hi].into_iter().flatten() {
            if chosen.len() >= count {
                break 'extremes;
            }
            if !chosen.contains(&i) {
                chosen.push(i);
            }
        }
    }
    let mut dmin: Vec<f64> = points
        .iter()
        .map(|p| {
            chosen
                .iter()
                .map(|&c| d2(p, &points[c]))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    while chosen.len() < count {
        let mut best = (usize::MAX, -1.0f64);
        for (i, &d) in dmin.iter().enumerate() {
            if d > best.1 && !chosen.contains(&i) {
                best = (i, d);
            }
        }
        chosen.push(best.0);
        for (i, d) in dmin.iter_mut().enumerate() {
            *d = d.min(d2(&points[i], &points[best.0]));
        }
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn farthest_points_picks_the_extremes() {
        let pts: Vec<Vec<f64>> = [0.0, 0.1, -1.0, 0.5, 0.9, 1.0]
            .iter()
            .map(|&x| vec![x])
            .collect();
        let c = farthest_points(&pts, 3);
        assert_eq!(c[..2], [2, 5]); // the extremes
        assert_eq!(c[2], 0); // 0.0 is 1 from both; 0.1 only 0.9 from 1.0
        let pts2: Vec<Vec<f64>> = vec![vec![0.0, 0.0], vec![1.0, 0.0], vec![0.0, 1.0]];
        assert_eq!(farthest_points(&pts2, 1), vec![0]);
        assert_eq!(farthest_points(&pts2, 5).len(), 3);
    }
}
