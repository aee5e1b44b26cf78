//! The residual groups' weights (variance components): each group's sigma re-estimated
//! from its weighted residuals and redundancy, the robot-pose groups' floored
//! ([`super::super::robot_noise`]), and the image information the floors and the image
//! part's prior factors come from.

use std::sync::atomic::Ordering;

use nalgebra::Matrix6;

use super::{Group, JointProblem, GROUPS};
use crate::calib::joint::robot_noise::{
    self, Floors, ABSOLUTE_FLOOR_DEG, ABSOLUTE_FLOOR_MM, IMAGE_FACTOR_FLOOR, RESOLUTION_CAP,
};
use crate::numerics::lm::{LeastSquares, Leverages};

/// Floor of the image groups' sigmas, px (round-off of exact data).
const IMAGE_SIGMA_FLOOR_PX: f64 = 1e-9;

/// Relative change of a robot-pose sigma below which its re-estimate is not applied:
/// half the standard error of a variance component from ~50 prior rows (1 / sqrt(2 r),
/// r ~ 3 views - 6, is 11 % for 15 views).
const ROBOT_SIGMA_DEAD_BAND: f64 = 0.05;

impl JointProblem<'_> {
    /// The group of each residual.
    pub(super) fn groups(&self) -> Vec<Group> {
        let mut g = vec![Group::Circle; 2 * self.terms.circles.len()];
        g.resize(self.prior_offset(), Group::Stripe);
        if self.robot {
            for _ in 0..self.terms.a.len() {
                g.extend([Group::RobotRotation; 3]);
                g.extend([Group::RobotTranslation; 3]);
                if self.image_pose {
                    g.extend([Group::ImagePose; 6]);
                }
            }
        }
        g
    }

    /// The row ranges of the groups ([`Group`] order; the robot-pose groups' rows
    /// interleave, view by view, within the last range).
    pub(super) fn group_ranges(&self) -> [std::ops::Range<usize>; 3] {
        let (nc, po) = (2 * self.terms.circles.len(), self.prior_offset());
        let np = self.prior_rows_per_view() * self.terms.a.len();
        [0..nc, nc..po, po..po + np]
    }

    /// The re-estimated standard deviation of each group behind the weighted residuals
    /// `r`: `sqrt(SSR_g / r_g)`, the redundancy `r_g = m_g - sum_g h_i` from the
    /// leverages (Förstner; the largest group's sum taken as `n` less the others'), or
    /// `m_g - n m_g / m` when they are not available; for the image groups 1.4826 MAD
    /// instead when robust. `None` for a group without residuals or without redundancy
    /// (its weight stays).
    pub(super) fn group_sigmas(
        &self,
        r: &[f64],
        leverages: &mut Leverages<'_>,
    ) -> [Option<f64>; GROUPS] {
        let (n, m) = (self.num_params() as f64, r.len() as f64);
        let ranges = self.group_ranges();
        let largest = (0..3).max_by_key(|&k| ranges[k].len()).unwrap_or(0);
        let wanted: Vec<_> = (0..3)
            .filter(|&k| k != largest)
            .map(|k| ranges[k].clone())
            .collect();
        let h = leverages(&wanted);
        // Per group: count, weighted sum of squares, sum of leverages.
        let mut acc = [(0usize, 0.0, 0.0); GROUPS];
        for (i, g) in self.groups().into_iter().enumerate() {
            let a = &mut acc[g as usize];
            a.0 += 1;
            a.1 += r[i] * r[i];
            a.2 += h.as_ref().map_or(0.0, |h| h[i]);
        }
        let group_of_range = [Group::Circle, Group::Stripe, Group::RobotRotation];
        if h.is_some() {
            let rest: f64 = acc.iter().map(|a| a.2).sum();
            acc[group_of_range[largest] as usize].2 = n - rest;
        }
        std::array::from_fn(|gi| {
            let g = [
                Group::Circle,
                Group::Stripe,
                Group::RobotRotation,
                Group::RobotTranslation,
                Group::ImagePose,
            ][gi];
            let (count, ss, lev) = acc[gi];
            if count == 0 {
                return None;
            }
            let w = self.weight(g);
            let mg = count as f64;
            let red = if h.is_some() {
                mg - lev
            } else {
                mg - n * mg / m
            };
            if matches!(g, Group::Circle | Group::Stripe) && self.robust_sigma {
                let range = &ranges[gi];
                let mut a: Vec<f64> = r[range.clone()].iter().map(|x| (x / w).abs()).collect();
                a.sort_by(f64::total_cmp);
                return Some(1.4826 * a[a.len() / 2]);
            }
            // A group the rest of the adjustment explains entirely has no redundancy to
            // estimate its sigma from. A small one is kept: a prior much tighter than
            // the images (a robot-pose sigma at its floor) has a redundancy of about
            // (sigma / image precision)^2 per row, and so has its sum of squares, so
            // their ratio still moves the sigma where the data put it.
            (red > 1e-9 * mg).then(|| (ss / (w * w) / red).sqrt())
        })
    }

    /// Keeps each view's information on its correction from its circles and from its
    /// stripe points (unit weight: the rows' values divided by the group's weight), for
    /// the resolution floor ([`super::super::robot_noise`]): `D^T D` of each run of the view's
    /// rows, `D` their six correction values (at `ng` in rows of `w` values).
    pub(super) fn store_image_information(&self, vals: &[f64], w: usize, ng: usize) {
        let mut info = vec![[Matrix6::<f64>::zeros(); 2]; self.terms.a.len()];
        let (nc, po) = (2 * self.terms.circles.len(), self.prior_offset());
        let (wc, ws) = (self.wc(), self.ws());
        let mut m = faer::Mat::<f64>::zeros(6, 6);
        for &(view, i0, i1) in self.view_runs.iter().filter(|r| r.1 < po) {
            let d = faer::MatRef::from_column_major_slice_with_stride(
                &vals[i0 * w + ng..(i1 - 1) * w + ng + 6],
                6,
                i1 - i0,
                w,
            );
            faer::linalg::matmul::matmul(
                m.as_mut(),
                faer::Accum::Replace,
                d,
                d.transpose(),
                1.0,
                faer::Par::Seq,
            );
            let (k, wg) = if i0 < nc { (0, wc) } else { (1, ws) };
            info[view][k] += Matrix6::from_fn(|a, b| m[(a, b)] / (wg * wg));
        }
        if let Ok(mut st) = self.robot_state.lock() {
            st.info = info;
        }
    }

    /// The robot-pose groups' new weights from their sigmas `sig` ([`Group`] order;
    /// the image groups' already in `new`): each sigma at least its floor, the larger of
    /// the robot's figure and the adjustment's own ([`super::super::robot_noise`]); a group
    /// without redundancy, or whose
    /// sigma moves less than [`ROBOT_SIGMA_DEAD_BAND`], keeps its sigma, floored. A sigma
    /// within the dead band of its floor is at its floor.
    pub(super) fn reweight_robot(&self, sig: &[Option<f64>; GROUPS], new: &mut [f64; GROUPS]) {
        let Ok(mut st) = self.robot_state.lock() else {
            return;
        };
        let sigma_px = (
            1.0 / new[Group::Circle as usize],
            1.0 / new[Group::Stripe as usize],
        );
        let floors = self.robot_floors(&st.info, sigma_px);
        let mut at_floor = [false; 3];
        let groups = if self.image_pose { 3 } else { 2 };
        for (k, (g, floor)) in [
            (Group::RobotRotation, floors.rotation_rad),
            (Group::RobotTranslation, floors.translation_mm),
            (Group::ImagePose, IMAGE_FACTOR_FLOOR),
        ]
        .into_iter()
        .take(groups)
        .enumerate()
        {
            let s = robot_sigma_update(1.0 / new[g as usize], sig[g as usize], floor);
            if s > 0.0 && s.is_finite() {
                at_floor[k] = s <= floor * (1.0 + ROBOT_SIGMA_DEAD_BAND);
                new[g as usize] = 1.0 / s;
            }
        }
        st.floors = floors;
        st.at_floor = (at_floor[0], at_floor[1]);
        st.image_at_floor = at_floor[2];
    }

    /// The robot-pose sigmas' floors in force (the robot's figures and the adjustment's
    /// own, capped by the images' resolution; [`super::super::robot_noise`]) with the
    /// views' image information `info` and the image groups' sigmas `sigma_px`.
    fn robot_floors(&self, info: &[[Matrix6<f64>; 2]], sigma_px: (f64, f64)) -> Floors {
        let (res_r, res_t) = robot_noise::resolution(info, sigma_px).unwrap_or((0.0, 0.0));
        let own = |absolute: f64, res: f64| {
            if res > 0.0 {
                absolute.min(RESOLUTION_CAP * res)
            } else {
                absolute
            }
        };
        Floors {
            rotation_rad: self
                .robot_figures
                .rotation_rad
                .max(own(ABSOLUTE_FLOOR_DEG.to_radians(), res_r)),
            translation_mm: self
                .robot_figures
                .translation_mm
                .max(own(ABSOLUTE_FLOOR_MM, res_t)),
        }
    }

    /// The image part's prior factors from the views' image information just stored
    /// and the image groups' current weights ([`super::super::robot_noise`] module docs).
    pub(super) fn freeze_image_prior(&self) {
        let (wc, ws) = (self.wc(), self.ws());
        if let Ok(mut st) = self.robot_state.lock() {
            st.image_prior = st
                .info
                .iter()
                .map(|[c, s]| robot_noise::image_prior_factor(&(c * (wc * wc) + s * (ws * ws))))
                .collect();
        }
    }

    /// The image part's prior factors (empty before the first Jacobian evaluation).
    pub(super) fn image_prior(&self) -> Vec<Matrix6<f64>> {
        self.robot_state
            .lock()
            .map(|s| s.image_prior.clone())
            .unwrap_or_default()
    }

    /// Re-estimates the groups' weights (variance components) from the weighted
    /// residuals `r` while re-estimations are left: the image groups' sigmas floored at
    /// [`IMAGE_SIGMA_FLOOR_PX`], the robot-pose groups' by [`Self::reweight_robot`].
    /// Returns each residual's new weight over its old one (`None`: weights kept).
    pub(super) fn reestimate_weights(
        &self,
        r: &[f64],
        leverages: &mut Leverages<'_>,
    ) -> Option<Vec<f64>> {
        if !self.variance_components
            || self
                .reweights_left
                .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |k| k.checked_sub(1))
                .is_err()
        {
            return None;
        }
        let sig = self.group_sigmas(r, leverages);
        let old: [f64; GROUPS] =
            std::array::from_fn(|g| f64::from_bits(self.weights[g].load(Ordering::Relaxed)));
        let mut new = old;
        for g in [Group::Circle, Group::Stripe] {
            if let Some(s) = sig[g as usize] {
                new[g as usize] = 1.0 / s.max(IMAGE_SIGMA_FLOOR_PX);
            }
        }
        if self.robot {
            self.reweight_robot(&sig, &mut new);
        }
        for (a, w) in self.weights.iter().zip(&new) {
            a.store(w.to_bits(), Ordering::Relaxed);
        }
        Some(
            self.groups()
                .iter()
                .map(|&g| new[g as usize] / old[g as usize])
                .collect(),
        )
    }
}

/// A robot-pose group's new sigma from its re-estimate `sig` (`None`: no redundancy)
/// and its sigma `old`: at least `floor`; a change within [`ROBOT_SIGMA_DEAD_BAND`] is
/// below what the component resolves: the sigma stays (floored), and the solver is not
/// kept from stopping by a sigma creeping near its floor.
fn robot_sigma_update(old: f64, sig: Option<f64>, floor: f64) -> f64 {
    let s = sig.unwrap_or(old).max(floor);
    if (s / old - 1.0).abs() <= ROBOT_SIGMA_DEAD_BAND {
        old.max(floor)
    } else {
        s
    }
}
