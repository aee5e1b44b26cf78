//! The adjustment's residuals and their Jacobian rows: circle terms (detected minus
//! predicted imaged centre), stripe terms (signed image distance to the imaged line
//! where the laser plane meets the view's board) and, with the robot-pose noise, each
//! view's prior rows ([`super::robot_noise`]), as a [`LeastSquares`] problem with
//! variance-component re-weighting (module docs of [`super`]).
//!
//! Residual order: circles (2 each), stripe points, then the prior rows per view (the
//! robot's rotation and translation, 3 each; with the image part its 6). Jacobian rows:
//! dense (every column) without the robot-pose noise; with it, each row holds the global
//! columns and its view's per-view columns (the correction's six, the image part's six;
//! sparse rows: a view's rows share their columns, so the solver sums them per view
//! before the scatter).

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Mutex;

use faer::MatMut;
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Vector3};

use crate::calib::clustered::ViewShare;
use rayon::prelude::*;

use super::chain::cam_board;
use super::layout::{Block, JointParams, ParamLayout, SLOTS};
use super::robot_noise::{
    self, Floors, PriorWeights, RobotNoiseState, ABSOLUTE_FLOOR_DEG, ABSOLUTE_FLOOR_MM,
    IMAGE_FACTOR_FLOOR, RESOLUTION_CAP,
};
use super::{JointOptions, MAX_REWEIGHTS, MAX_REWEIGHTS_POSE_NOISE};
use crate::calib::conic::{centre_generic_n, quadrature_nodes, CentreModel};
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::camera::{distort_generic, project_generic, Camera};
use crate::model::geometry::Iso3;
use crate::numerics::dual::{Dual, Scalar};
use crate::numerics::lm::{dense_jacobian_from_rows, JacobianRows, LeastSquares, Leverages};
use crate::numerics::mat3::{cross, dot, rot_times_exp_first_order};

/// Dual numbers over every parameter slot ([`ParamLayout`]).
type DSlots = Dual<SLOTS>;

/// One circle observation.
#[derive(Debug, Clone, Copy)]
pub(super) struct CircleTerm {
    /// Index of the view among the views used.
    pub view: usize,
    pub row: usize,
    pub col: usize,
    /// Centre on the board, mm.
    pub centre: (f64, f64),
    pub radius: f64,
    /// Detected imaged centre, px.
    pub u: f64,
    pub v: f64,
}

/// One stripe point.
#[derive(Debug, Clone, Copy)]
pub(super) struct StripeTerm {
    /// Index of the view among the views used.
    pub view: usize,
    pub u: f64,
    pub v: f64,
}

/// The observations of the views used.
#[derive(Debug, Clone, Default)]
pub(super) struct Terms {
    /// `T_base_hand` of each used view.
    pub a: Vec<Iso3>,
    /// Dataset row (`ViewObs::view`) of each used view.
    pub used: Vec<usize>,
    /// The joint readings of each used view (`None`: the controller reported the
    /// flange pose).
    pub q: Vec<Option<Vec<f64>>>,
    pub circles: Vec<CircleTerm>,
    pub stripes: Vec<StripeTerm>,
}

impl Terms {
    /// The terms of the views with a robot pose and an observation (the others skipped
    /// with a warning); errors on a non-finite observation or a circle off the board.
    pub fn collect(views: &[ViewObs], board: &Board, warnings: &mut Vec<String>) -> Result<Terms> {
        Self::collect_views(views, board, false, warnings)
    }

    /// The terms of the views with an observation, on the bench: no robot pose is
    /// needed (`a` holds the identity for each; the board poses are estimated).
    pub fn collect_bench(
        views: &[ViewObs],
        board: &Board,
        warnings: &mut Vec<String>,
    ) -> Result<Terms> {
        Self::collect_views(views, board, true, warnings)
    }

    fn collect_views(
        views: &[ViewObs],
        board: &Board,
        bench: bool,
        warnings: &mut Vec<String>,
    ) -> Result<Terms> {
        let mut t = Terms::default();
        for v in views {
            let bh = if bench {
                Iso3::identity()
            } else if let Some(bh) = v.base_hand {
                bh
            } else {
                warnings.push(format!("view {}: left out, no robot pose", v.view));
                continue;
            };
            if v.circles.is_empty() && v.stripe.is_empty() {
                warnings.push(format!("view {}: left out, no observation", v.view));
                continue;
            }
            let vi = t.a.len();
            t.a.push(bh);
            t.used.push(v.view);
            t.q.push(match &v.reading {
                Some(crate::model::RobotReading::Joints(q)) => Some(q.clone()),
                _ => None,
            });
            for c in &v.circles {
                if !(c.u.is_finite() && c.v.is_finite())
                    || c.row >= board.rows
                    || c.col >= board.cols
                {
                    return Err(Error::InvalidInput(format!(
                        "view {}: circle ({}, {}) at ({}, {}) is not a valid observation",
                        v.view, c.row, c.col, c.u, c.v
                    )));
                }
                let ctr = board.center(c.row, c.col);
                t.circles.push(CircleTerm {
                    view: vi,
                    row: c.row,
                    col: c.col,
                    centre: (ctr.x, ctr.y),
                    radius: 0.5 * board.diameter(c.row, c.col),
                    u: c.u,
                    v: c.v,
                });
            }
            for s in &v.stripe {
                if !(s[0].is_finite() && s[1].is_finite()) {
                    return Err(Error::InvalidInput(format!(
                        "view {}: stripe point ({}, {}) is not finite",
                        v.view, s[0], s[1]
                    )));
                }
                t.stripes.push(StripeTerm {
                    view: vi,
                    u: s[0],
                    v: s[1],
                });
            }
        }
        Ok(t)
    }
}

/// The residual groups, each with its own standard deviation (variance component).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Group {
    /// Circle-centre coordinates, px.
    Circle,
    /// Stripe-point distances, px.
    Stripe,
    /// The robot-pose corrections' rotation-vector components, rad.
    RobotRotation,
    /// The robot-pose corrections' translation components, mm.
    RobotTranslation,
    /// The image part of the corrections (whitened by the image's own information:
    /// unit-free, its sigma the factor `k`).
    ImagePose,
}

/// A view's reduced share of the normal equations `(M_v, s_v)`
/// ([`JointProblem::view_shares`]).
pub(super) type ReducedShare = (DMatrix<f64>, DVector<f64>);

/// Number of residual groups ([`Group`]).
pub(super) const GROUPS: usize = 5;

/// Floor of the image groups' sigmas, px (round-off of exact data).
const IMAGE_SIGMA_FLOOR_PX: f64 = 1e-9;

/// Relative change of a robot-pose sigma below which its re-estimate is not applied:
/// half the standard error of a variance component from ~50 prior rows (1 / sqrt(2 r),
/// r ~ 3 views - 6, is 11 % for 15 views).
const ROBOT_SIGMA_DEAD_BAND: f64 = 0.05;

/// The adjustment as a least-squares problem.
pub(super) struct JointProblem<'a> {
    pub base: &'a Camera,
    pub layout: &'a ParamLayout,
    /// Centre model of the residuals.
    pub model: CentreModel,
    /// Centre model whose derivatives the Jacobian takes (`model` for the exact
    /// Jacobian; the first-order `Conic` while the exact model's solve is under way:
    /// an inexact Jacobian only changes the path, the last solve's is exact).
    pub jacobian_model: CentreModel,
    pub terms: Terms,
    /// Weights `1 / sigma` of the groups ([`Group`] order; f64 bits; re-estimated during
    /// the solve when `variance_components` is set).
    weights: [AtomicU64; GROUPS],
    /// Whether the robot-pose corrections are estimated (prior rows, sparse rows).
    robot: bool,
    /// Whether their image part is estimated too.
    image_pose: bool,
    /// The image part's prior factors are computed from the next Jacobian evaluation's
    /// image information (set by [`Self::prepare_solve`]).
    freeze_pending: AtomicBool,
    /// The bench: every view's board pose estimated (sparse rows, no prior rows).
    bench: bool,
    /// The robot's figures as floors of the robot-pose sigmas.
    robot_figures: Floors,
    /// What the robot-pose groups keep between evaluations.
    robot_state: Mutex<RobotNoiseState>,
    /// The runs of consecutive residual rows of one view: `(view, first, end)`.
    view_runs: Vec<(usize, usize, usize)>,
    /// Re-estimate the weights (variance components) in [`LeastSquares::reweight`].
    variance_components: bool,
    /// MAD instead of RMS for the sigmas (robust).
    robust_sigma: bool,
    /// Re-estimations left in the current solve (see [`MAX_REWEIGHTS`],
    /// [`MAX_REWEIGHTS_POSE_NOISE`]).
    reweights_left: AtomicUsize,
    /// The last foot-point parameter of each stripe point (f64 bits; NaN: none): the
    /// next evaluation starts there (a warm start; the result does not depend on it
    /// beyond the 1e-11 px convergence tolerance).
    foot_cache: Vec<AtomicU64>,
}

impl<'a> JointProblem<'a> {
    /// The problem over `terms` with the options' centre model, weights and sigma
    /// estimation.
    pub fn new(
        base: &'a Camera,
        layout: &'a ParamLayout,
        terms: Terms,
        opts: &JointOptions,
    ) -> JointProblem<'a> {
        let foot_cache = (0..terms.stripes.len())
            .map(|_| AtomicU64::new(f64::NAN.to_bits()))
            .collect();
        let (t0, r0) = opts.initial_robot_sigma;
        let k0 = opts.initial_image_factor;
        let w = |sigma: f64| AtomicU64::new((1.0 / sigma).to_bits());
        let robot_figures = Floors {
            rotation_rad: opts.robot_floor.1.unwrap_or(0.0).to_radians(),
            translation_mm: opts.robot_floor.0.unwrap_or(0.0),
        };
        let robot_state = RobotNoiseState {
            floors: robot_figures,
            ..Default::default()
        };
        let prior_rows = if !layout.per_view_free(Block::RobotPose) {
            0
        } else if layout.per_view_free(Block::ImagePose) {
            12
        } else {
            6
        };
        let view_runs = view_runs(&terms, prior_rows);
        JointProblem {
            base,
            layout,
            model: opts.centre_model,
            jacobian_model: opts.centre_model,
            terms,
            weights: [
                w(opts.initial_sigma_px.0),
                w(opts.initial_sigma_px.1),
                w(r0.to_radians()),
                w(t0),
                w(k0),
            ],
            robot: layout.per_view_free(Block::RobotPose),
            image_pose: layout.per_view_free(Block::ImagePose),
            freeze_pending: AtomicBool::new(true),
            bench: layout.per_view_free(Block::BoardPose),
            robot_figures,
            robot_state: Mutex::new(robot_state),
            view_runs,
            variance_components: opts.variance_components,
            robust_sigma: opts.robust,
            reweights_left: AtomicUsize::new(if layout.per_view_free(Block::RobotPose) {
                MAX_REWEIGHTS_POSE_NOISE
            } else {
                MAX_REWEIGHTS
            }),
            foot_cache,
        }
    }

    /// Sets the centre models of the next solve, re-arms the re-weighting and has the
    /// image part's prior factors computed afresh at its first evaluation.
    pub fn prepare_solve(&mut self, model: CentreModel, jacobian_model: CentreModel) {
        self.model = model;
        self.jacobian_model = jacobian_model;
        self.reweights_left.store(
            if self.robot {
                MAX_REWEIGHTS_POSE_NOISE
            } else {
                MAX_REWEIGHTS
            },
            Ordering::Relaxed,
        );
        self.freeze_pending.store(true, Ordering::Relaxed);
    }

    /// Every group's weight ([`Group`] order).
    pub fn all_weights(&self) -> [f64; GROUPS] {
        std::array::from_fn(|g| f64::from_bits(self.weights[g].load(Ordering::Relaxed)))
    }

    /// Sets every group's weight (a later solve of the same observations).
    pub fn set_all_weights(&mut self, w: &[f64; GROUPS]) {
        for (a, w) in self.weights.iter().zip(w) {
            a.store(w.to_bits(), Ordering::Relaxed);
        }
    }

    /// Starts where `earlier`, a solve of the same observations, ended: its image
    /// groups' weights and its stripe foot points.
    pub fn continue_from(&mut self, earlier: &JointProblem<'_>) {
        for g in [Group::Circle, Group::Stripe] {
            self.weights[g as usize] = AtomicU64::new(earlier.weight(g).to_bits());
        }
        for (a, b) in self.foot_cache.iter().zip(&earlier.foot_cache) {
            a.store(b.load(Ordering::Relaxed), Ordering::Relaxed);
        }
    }

    /// Weight (`1 / sigma`) of a group.
    pub fn weight(&self, g: Group) -> f64 {
        f64::from_bits(self.weights[g as usize].load(Ordering::Relaxed))
    }

    /// Weight of the circle residuals.
    pub fn wc(&self) -> f64 {
        self.weight(Group::Circle)
    }

    /// Weight of the stripe residuals.
    pub fn ws(&self) -> f64 {
        self.weight(Group::Stripe)
    }

    /// Weights of the robot-pose prior rows.
    pub fn robot_weights(&self) -> PriorWeights {
        PriorWeights {
            rotation: self.weight(Group::RobotRotation),
            translation: self.weight(Group::RobotTranslation),
            image: self.image_pose.then(|| self.weight(Group::ImagePose)),
        }
    }

    /// Prior rows per view (0 without the robot-pose noise).
    pub fn prior_rows_per_view(&self) -> usize {
        if self.robot {
            self.robot_weights().rows()
        } else {
            0
        }
    }

    /// Whether the robot-pose corrections are estimated.
    pub fn robot_noise(&self) -> bool {
        self.robot
    }

    /// The robot-pose groups' state (floors in force, at-floor flags).
    pub fn robot_state(&self) -> RobotNoiseState {
        self.robot_state
            .lock()
            .map(|s| s.clone())
            .unwrap_or_default()
    }

    /// First prior row (after the circles and the stripe points).
    fn prior_offset(&self) -> usize {
        2 * self.terms.circles.len() + self.terms.stripes.len()
    }

    /// The group of each residual.
    fn groups(&self) -> Vec<Group> {
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

    /// Values per Jacobian row: every column (dense) without the robot-pose noise, the
    /// global columns and the view's per-view columns with it.
    pub(super) fn row_width(&self) -> usize {
        if self.robot || self.bench {
            self.layout.num_global() + self.layout.per_view_len()
        } else {
            self.num_params()
        }
    }

    /// The row ranges of the groups ([`Group`] order; the robot-pose groups' rows
    /// interleave, view by view, within the last range).
    fn group_ranges(&self) -> [std::ops::Range<usize>; 3] {
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
    fn group_sigmas(&self, r: &[f64], leverages: &mut Leverages<'_>) -> [Option<f64>; GROUPS] {
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

    fn decode(&self, p: &[f64]) -> JointParams {
        self.layout.decode(p)
    }

    /// Keeps each view's information on its correction from its circles and from its
    /// stripe points (unit weight: the rows' values divided by the group's weight), for
    /// the resolution floor ([`super::robot_noise`]): `D^T D` of each run of the view's
    /// rows, `D` their six correction values (at `ng` in rows of `w` values).
    fn store_image_information(&self, vals: &[f64], w: usize, ng: usize) {
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
    /// the robot's figure and the adjustment's own ([`super::robot_noise`]); a group
    /// without redundancy, or whose
    /// sigma moves less than [`ROBOT_SIGMA_DEAD_BAND`], keeps its sigma, floored. A sigma
    /// within the dead band of its floor is at its floor.
    fn reweight_robot(&self, sig: &[Option<f64>; GROUPS], new: &mut [f64; GROUPS]) {
        let Ok(mut st) = self.robot_state.lock() else {
            return;
        };
        let sigma_px = (
            1.0 / new[Group::Circle as usize],
            1.0 / new[Group::Stripe as usize],
        );
        let (res_r, res_t) = robot_noise::resolution(&st.info, sigma_px).unwrap_or((0.0, 0.0));
        let own = |absolute: f64, res: f64| {
            if res > 0.0 {
                absolute.min(RESOLUTION_CAP * res)
            } else {
                absolute
            }
        };
        let floors = Floors {
            rotation_rad: self
                .robot_figures
                .rotation_rad
                .max(own(ABSOLUTE_FLOOR_DEG.to_radians(), res_r)),
            translation_mm: self
                .robot_figures
                .translation_mm
                .max(own(ABSOLUTE_FLOOR_MM, res_t)),
        };
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
            let old = 1.0 / new[g as usize];
            let mut s = sig[g as usize].unwrap_or(old).max(floor);
            // A change within the dead band is below what the component resolves: the
            // sigma stays (floored), and the solver is not kept from stopping by a sigma
            // creeping near its floor.
            if (s / old - 1.0).abs() <= ROBOT_SIGMA_DEAD_BAND {
                s = old.max(floor);
            }
            if s > 0.0 && s.is_finite() {
                at_floor[k] = s <= floor * (1.0 + ROBOT_SIGMA_DEAD_BAND);
                new[g as usize] = 1.0 / s;
            }
        }
        st.floors = floors;
        st.at_floor = (at_floor[0], at_floor[1]);
        st.image_at_floor = at_floor[2];
    }

    /// The image part's prior factors from the views' image information just stored
    /// and the image groups' current weights ([`super::robot_noise`] module docs).
    fn freeze_image_prior(&self) {
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
    fn image_prior(&self) -> Vec<Matrix6<f64>> {
        self.robot_state
            .lock()
            .map(|s| s.image_prior.clone())
            .unwrap_or_default()
    }

    /// Each view's share of the normal equations at `p`, reduced to the global columns
    /// by eliminating its own per-view columns: `(M_v, s_v)` with `M_v = A_gg - A_gd
    /// A_dd^-1 A_dg` and `s_v = g_g - A_gd A_dd^-1 g_d` over its rows (its image rows
    /// and prior rows, weighted; `A = J^T J`, `g = J^T r`). Their sums are the reduced
    /// normal equations; `None` when a view's own block is singular.
    pub fn view_shares(&self, p: &[f64]) -> Result<Option<Vec<ReducedShare>>> {
        let (n, m) = (self.num_params(), self.num_residuals());
        let ng = self.layout.num_global();
        let pv = self.layout.per_view_len();
        let w = self.row_width();
        let mut r = vec![0.0; m];
        let mut rows = JacobianRows::new(m, w, n);
        self.residuals_and_jacobian_rows(p, &mut r, &mut rows)?;
        let nv = self.terms.a.len();
        let mut acc: Vec<ViewShare> = (0..nv)
            .map(|v| ViewShare::new(ng, ng + v * pv..ng + (v + 1) * pv))
            .collect();
        for &(view, i0, i1) in &self.view_runs {
            for (i, ri) in r.iter().enumerate().take(i1).skip(i0) {
                let (cols, vals) = rows.row(i);
                acc[view].add_row(cols, vals, *ri);
            }
        }
        Ok(acc.into_iter().map(ViewShare::reduced).collect())
    }

    /// `J^T J_k` (n x p) at `p`: the gradient of the weighted image rows' sum of squares'
    /// linear term along each of `p` flange motions, `twists[view][k]` the view's flange
    /// perturbation `(w, v)` per unit of motion `k` in its correction's frame (the image
    /// rows reach them through the view's correction columns). `None` without the
    /// robot-pose corrections.
    pub fn flange_response(
        &self,
        p: &[f64],
        twists: &[Vec<[f64; 6]>],
    ) -> Result<Option<DMatrix<f64>>> {
        if !self.robot {
            return Ok(None);
        }
        let (n, m) = (self.num_params(), self.num_residuals());
        let ng = self.layout.num_global();
        let pv = self.layout.per_view_len();
        let w = self.row_width();
        let k = twists.first().map_or(0, |t| t.len());
        let mut r = vec![0.0; m];
        let mut rows = JacobianRows::new(m, w, n);
        self.residuals_and_jacobian_rows(p, &mut r, &mut rows)?;
        let mut g = DMatrix::zeros(n, k);
        let po = self.prior_offset();
        for &(view, i0, i1) in self.view_runs.iter().filter(|r| r.1 < po) {
            let Some(tw) = twists.get(view) else { continue };
            let own = ng + view * pv;
            for i in i0..i1 {
                let (cols, vals) = rows.row(i);
                // The row's value along each motion: its correction columns times the
                // motion's twist.
                let dcols: Vec<usize> = (0..6).map(|q| own + q).collect();
                let along: Vec<f64> = (0..k)
                    .map(|j| {
                        cols.iter()
                            .zip(vals)
                            .filter_map(|(c, v)| {
                                dcols.iter().position(|d| d == c).map(|q| v * tw[j][q])
                            })
                            .sum()
                    })
                    .collect();
                for (c, v) in cols.iter().zip(vals) {
                    if *v == 0.0 {
                        continue;
                    }
                    for (j, a) in along.iter().enumerate() {
                        g[(*c, j)] += v * a;
                    }
                }
            }
        }
        Ok(Some(g))
    }

    /// Stripe foot point from the warm-start cache, which it updates.
    fn cached_foot_point(
        &self,
        k: usize,
        cam: &[f64; 9],
        p0: &[f64; 3],
        dir: &[f64; 3],
    ) -> Result<(f64, [f64; 2])> {
        let (st, cache) = (&self.terms.stripes[k], &self.foot_cache[k]);
        let start = f64::from_bits(cache.load(Ordering::Relaxed));
        let (sf, normal) = foot_point(cam, p0, dir, [st.u, st.v], start)?;
        cache.store(sf.to_bits(), Ordering::Relaxed);
        Ok((sf, normal))
    }

    /// f64 residuals (unweighted): circles (2 each) then stripe points.
    /// The robot's flange pose of every used view: from the corrected robot when it is
    /// calibrated, else as given.
    pub fn flanges(&self, s: &JointParams) -> std::borrow::Cow<'_, [Iso3]> {
        match &self.layout.robot {
            Some(rb) => std::borrow::Cow::Owned(rb.flanges(&s.robot)),
            None => std::borrow::Cow::Borrowed(&self.terms.a),
        }
    }

    fn raw_residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        let s = self.decode(p);
        let a = self.flanges(&s);
        let poses = s.view_poses(&a);
        let board_poses = s.circle_poses(&a);
        let n1 = [s.plane_n.x, s.plane_n.y, s.plane_n.z];
        let lines: Vec<Option<_>> = poses
            .iter()
            .map(|(rot, t)| stripe_line(&n1, s.plane_d, rot, t).ok())
            .collect();
        let nc = self.terms.circles.len();
        let (rc, rs) = r.split_at_mut(2 * nc);
        rc.par_chunks_mut(2)
            .zip(self.terms.circles.par_iter())
            .try_for_each(|(out, c)| -> Result<()> {
                let (rot, t) = &board_poses[c.view];
                let uv = centre_generic_n(
                    &s.cam,
                    rot,
                    t,
                    c.centre,
                    c.radius,
                    self.model,
                    quadrature_nodes(self.base.model),
                )?;
                out[0] = uv[0] - c.u;
                out[1] = uv[1] - c.v;
                Ok(())
            })?;
        rs.par_iter_mut()
            .enumerate()
            .try_for_each(|(k, out)| -> Result<()> {
                let st = &self.terms.stripes[k];
                let Some((p0, dir)) = lines[st.view] else {
                    return Err(parallel_error(st.view));
                };
                let (sf, normal) = self.cached_foot_point(k, &s.cam, &p0, &dir)?;
                let pt: [f64; 3] = std::array::from_fn(|i| p0[i] + sf * dir[i]);
                let uv = project_generic(&s.cam, &pt);
                *out = normal[0] * (uv[0] - st.u) + normal[1] * (uv[1] - st.v);
                Ok(())
            })?;
        Ok(())
    }
}

/// The slots after `X`'s first that a view's board pose depends on: `X`, `Z`, the board
/// scale.
const CHAIN: usize = 13;

/// Per-view quantities of a Jacobian evaluation: the pose each view's board points are
/// imaged with (`T_cam_board` with its translation divided by the board scale, values),
/// the chain of its increment to the `X`, `Z` and scale slots, and its stripe line with
/// derivatives over every slot.
struct ViewLinearisation {
    board_poses: Vec<([[f64; 3]; 3], [f64; 3])>,
    /// `d(w, v) / d(X, Z, scale slots)`: rows `(w, v)` of the board pose's increment.
    chains: Vec<[[f64; CHAIN]; 6]>,
    lines: Vec<Option<([DSlots; 3], [DSlots; 3])>>,
    /// With the robot-pose noise: each view's map from its correction to `X`'s
    /// increment ([`robot_noise::correction_map`]).
    maps: Vec<Matrix6<f64>>,
    /// With the robot block: the map from the flange's own perturbation to `X`'s
    /// increment, and each view's flange perturbation per DH correction.
    robot: Option<RobotLinearisation>,
    /// The bench: the derivatives along `Z`'s slots are the view's board-pose columns.
    bench: bool,
}

/// The map from the flange's own perturbation to `X`'s increment, and each view's
/// flange perturbation per DH correction.
type RobotLinearisation = (Matrix6<f64>, Vec<Vec<[f64; 6]>>);

/// The robot block's columns of a row from its derivatives `gx` over `X`'s six slots.
#[inline]
fn robot_columns(
    robot: &Option<RobotLinearisation>,
    view: usize,
    gx: &[f64; 6],
    weight: f64,
    out: &mut [f64],
) {
    if let Some((m, jac)) = robot {
        let gf = robot_noise::correction_columns(gx, m);
        for (o, col) in out.iter_mut().zip(&jac[view]) {
            *o = weight * (0..6).map(|k| gf[k] * col[k]).sum::<f64>();
        }
    }
}

impl JointProblem<'_> {
    /// The views' poses and stripe lines as duals over every slot, and the chains.
    fn linearise_views(&self, p: &[f64], s: &JointParams) -> ViewLinearisation {
        let layout = self.layout;
        let (sp, sx, sz, ss) = (
            layout.slots(Block::Plane).start,
            layout.slots(Block::HandCam).start,
            layout.slots(Block::BaseBoard).start,
            layout.slots(Block::BoardScale).start,
        );
        debug_assert_eq!(ss, sx + CHAIN - 1);
        let v = layout.full(p);
        let chart = &layout.chart;
        let a = DSlots::var(v[sp], sp);
        let b = DSlots::var(v[sp + 1], sp + 1);
        let nn: [DSlots; 3] = std::array::from_fn(|i| {
            DSlots::cst(chart.n0[i]) + a.scale(chart.e1[i]) + b.scale(chart.e2[i])
        });
        let len = dot(&nn, &nn).sqrt();
        let n1: [DSlots; 3] = std::array::from_fn(|i| nn[i] / len);
        let d1 = DSlots::var(v[sp + 2], sp + 2);
        let wx: [DSlots; 3] = std::array::from_fn(|i| DSlots::var(0.0, sx + i));
        let wz: [DSlots; 3] = std::array::from_fn(|i| DSlots::var(0.0, sz + i));
        let xr = rot_times_exp_first_order(&s.x_rot, &wx);
        let zr = rot_times_exp_first_order(&s.z_rot, &wz);
        let xt: [DSlots; 3] = std::array::from_fn(|i| DSlots::var(s.x_t[i], sx + 3 + i));
        let zt: [DSlots; 3] = std::array::from_fn(|i| DSlots::var(s.z_t[i], sz + 3 + i));
        let poses: Vec<_> = if s.board_poses.is_empty() {
            s.flange_poses(&self.flanges(s))
                .iter()
                .map(|a| cam_board(a, &xr, &xt, &zr, &zt))
                .collect()
        } else {
            // The bench: `A_i` and `X` the identity, each view's board pose in `Z`'s
            // slots (their derivatives are the view's board-pose columns).
            s.board_poses
                .iter()
                .map(|(r, t)| {
                    let zr = rot_times_exp_first_order(r, &wz);
                    let zt: [DSlots; 3] = std::array::from_fn(|i| DSlots::var(t[i], sz + 3 + i));
                    cam_board(&Iso3::identity(), &xr, &xt, &zr, &zt)
                })
                .collect()
        };
        let maps = s
            .corrections
            .iter()
            .map(|(rd, _)| robot_noise::correction_map(&s.x_rot, &s.x_t, rd))
            .collect();
        // Chain of each view's board-pose increment (w, v) w.r.t. the X, Z and scale
        // slots: dw = vee(R0^T dR), dv = d(t / s) = dt / s - t ds / s^2.
        let inv_s = 1.0 / s.scale;
        let chains = poses
            .iter()
            .map(|(rot, t)| {
                let r0 = Matrix3::from_fn(|i, j| rot[i][j].v);
                let mut m = [[0.0; CHAIN]; 6];
                #[allow(clippy::needless_range_loop)]
                for k in 0..CHAIN - 1 {
                    let slot = sx + k;
                    let dr = Matrix3::from_fn(|i, j| rot[i][j].d[slot]);
                    let sk = r0.transpose() * dr;
                    m[0][k] = 0.5 * (sk[(2, 1)] - sk[(1, 2)]);
                    m[1][k] = 0.5 * (sk[(0, 2)] - sk[(2, 0)]);
                    m[2][k] = 0.5 * (sk[(1, 0)] - sk[(0, 1)]);
                    for i in 0..3 {
                        m[3 + i][k] = t[i].d[slot] * inv_s;
                    }
                }
                for i in 0..3 {
                    m[3 + i][CHAIN - 1] = -t[i].v * inv_s * inv_s;
                }
                m
            })
            .collect();
        let board_poses = poses
            .iter()
            .map(|(rot, t)| {
                (
                    std::array::from_fn(|i| std::array::from_fn(|j| rot[i][j].v)),
                    std::array::from_fn(|i| t[i].v * inv_s),
                )
            })
            .collect();
        let lines = poses
            .iter()
            .map(|(rot, t)| stripe_line(&n1, d1, rot, t).ok())
            .collect();
        let robot = self.layout.robot.as_ref().map(|rb| {
            (
                robot_noise::correction_map(&s.x_rot, &s.x_t, &Matrix3::identity()),
                rb.flange_jacobians(&s.robot, &s.corrections),
            )
        });
        ViewLinearisation {
            board_poses,
            chains,
            lines,
            maps,
            robot,
            bench: self.bench,
        }
    }

    /// Weighted circle residuals `rc` and their Jacobian rows `vc` (2 rows of
    /// [`Self::row_width`] values per circle): duals over (camera 9, pose increment 6),
    /// chained to `X`, `Z` and the board scale, and through `X`'s to the view's
    /// correction.
    fn circle_rows(
        &self,
        s: &JointParams,
        views: &ViewLinearisation,
        rc: &mut [f64],
        vc: &mut [f64],
    ) -> Result<()> {
        type D15 = Dual<15>;
        let w = self.row_width();
        let ng = self.layout.num_global();
        let col_of = self.layout.columns();
        let sx = self.layout.slots(Block::HandCam).start;
        // Fixed camera parameters are constants (zero coefficients then cost nothing).
        let c15: [D15; 9] = std::array::from_fn(|i| {
            if col_of[i].is_some() {
                D15::var(s.cam[i], i)
            } else {
                D15::cst(s.cam[i])
            }
        });
        let w15: [D15; 3] = std::array::from_fn(|i| D15::var(0.0, 9 + i));
        let rcols = self.layout.robot_columns();
        let wc = self.wc();
        let nodes = quadrature_nodes(self.base.model);
        rc.par_chunks_mut(2)
            .zip(vc.par_chunks_mut(2 * w))
            .zip(self.terms.circles.par_iter())
            .try_for_each(|((out, jrow), c)| -> Result<()> {
                let (rot, t) = &views.board_poses[c.view];
                let r0 = Matrix3::from_fn(|i, j| rot[i][j]);
                let rd = rot_times_exp_first_order(&r0, &w15);
                let td: [D15; 3] = std::array::from_fn(|i| D15::var(t[i], 12 + i));
                let uv = centre_generic_n(
                    &c15,
                    &rd,
                    &td,
                    c.centre,
                    c.radius,
                    self.jacobian_model,
                    nodes,
                )?;
                let value = if self.jacobian_model == self.model {
                    [uv[0].v, uv[1].v]
                } else {
                    centre_generic_n(&s.cam, rot, t, c.centre, c.radius, self.model, nodes)?
                };
                out[0] = wc * (value[0] - c.u);
                out[1] = wc * (value[1] - c.v);
                let ch = &views.chains[c.view];
                for (a, ua) in uv.iter().enumerate() {
                    let row = &mut jrow[a * w..(a + 1) * w];
                    for (slot, col) in col_of.iter().enumerate().take(9) {
                        if let Some(col) = col {
                            row[*col] = wc * ua.d[slot];
                        }
                    }
                    let (mut gx, mut gz) = ([0.0; 6], [0.0; 6]);
                    for kk in 0..CHAIN {
                        let acc: f64 = (0..6).map(|q| ua.d[9 + q] * ch[q][kk]).sum();
                        if kk < 6 {
                            gx[kk] = acc;
                        } else if kk < 12 {
                            gz[kk - 6] = acc;
                        }
                        if let Some(col) = col_of[sx + kk] {
                            row[col] = wc * acc;
                        }
                    }
                    if let Some(m) = views.maps.get(c.view) {
                        let d = robot_noise::correction_columns(&gx, m);
                        for (o, v) in row[ng..ng + 6].iter_mut().zip(d) {
                            *o = wc * v;
                        }
                    }
                    robot_columns(&views.robot, c.view, &gx, wc, &mut row[rcols.clone()]);
                    if views.bench {
                        for (o, v) in row[ng..ng + 6].iter_mut().zip(gz) {
                            *o = wc * v;
                        }
                    }
                }
                Ok(())
            })
    }

    /// Weighted stripe residuals `rs` and their Jacobian rows `vs` ([`Self::row_width`]
    /// values each).
    ///
    /// Chain rule: `d res = n^T (d pi/d P (d p0 + s d dir) + d pi/d camera)`, the line's
    /// derivatives (plane, `X`, `Z` slots) from the per-view duals, the projection's by
    /// a small dual over `(x, y, k1..k3)` at the point.
    fn stripe_rows(
        &self,
        s: &JointParams,
        views: &ViewLinearisation,
        rs: &mut [f64],
        vs: &mut [f64],
    ) -> Result<()> {
        type D7 = Dual<7>;
        let w = self.row_width();
        let ng = self.layout.num_global();
        let col_of = self.layout.columns();
        let sp = self.layout.slots(Block::Plane).start;
        let sx = self.layout.slots(Block::HandCam).start;
        let sz = self.layout.slots(Block::BaseBoard).start;
        let rcols = self.layout.robot_columns();
        let ws = self.ws();
        rs.par_iter_mut()
            .zip(vs.par_chunks_mut(w))
            .enumerate()
            .try_for_each(|(k, (out, row))| -> Result<()> {
                let st = &self.terms.stripes[k];
                let Some((p0, dir)) = views.lines[st.view] else {
                    return Err(parallel_error(st.view));
                };
                let p0f = [p0[0].v, p0[1].v, p0[2].v];
                let dirf = [dir[0].v, dir[1].v, dir[2].v];
                let (sf, normal) = self.cached_foot_point(k, &s.cam, &p0f, &dirf)?;
                let pf: [f64; 3] = std::array::from_fn(|i| p0f[i] + sf * dirf[i]);
                let (x, y) = (pf[0] / pf[2], pf[1] / pf[2]);
                let kd: [D7; 5] = std::array::from_fn(|i| {
                    if col_of[4 + i].is_some() {
                        D7::var(s.cam[4 + i], 2 + i)
                    } else {
                        D7::cst(s.cam[4 + i])
                    }
                });
                let (d, _) = distort_generic(&kd, D7::var(x, 0), D7::var(y, 1));
                let (fu, fv) = (s.cam[0], s.cam[1]);
                let res = normal[0] * (fu * d[0].v + s.cam[2] - st.u)
                    + normal[1] * (fv * d[1].v + s.cam[3] - st.v);
                let (g0, g1) = (normal[0] * fu, normal[1] * fv);
                let drx = g0 * d[0].d[0] + g1 * d[1].d[0];
                let dry = g0 * d[0].d[1] + g1 * d[1].d[1];
                let dp = [drx / pf[2], dry / pf[2], -(drx * x + dry * y) / pf[2]];
                let mut full = [0.0; SLOTS];
                full[0] = normal[0] * d[0].v;
                full[1] = normal[1] * d[1].v;
                full[2] = normal[0];
                full[3] = normal[1];
                for i in 0..5 {
                    full[4 + i] = g0 * d[0].d[2 + i] + g1 * d[1].d[2 + i];
                }
                for (slot, o) in full.iter_mut().enumerate().skip(sp) {
                    *o = (0..3)
                        .map(|i| dp[i] * (p0[i].d[slot] + sf * dir[i].d[slot]))
                        .sum();
                }
                *out = ws * res;
                for (slot, v) in full.iter().enumerate() {
                    if let Some(col) = col_of[slot] {
                        row[col] = ws * v;
                    }
                }
                let gx: [f64; 6] = std::array::from_fn(|k| full[sx + k]);
                robot_columns(&views.robot, st.view, &gx, ws, &mut row[rcols.clone()]);
                if let Some(m) = views.maps.get(st.view) {
                    let d = robot_noise::correction_columns(&gx, m);
                    for (o, v) in row[ng..ng + 6].iter_mut().zip(d) {
                        *o = ws * v;
                    }
                }
                if views.bench {
                    for (o, v) in row[ng..ng + 6].iter_mut().zip(&full[sz..sz + 6]) {
                        *o = ws * v;
                    }
                }
                Ok(())
            })
    }
}

impl LeastSquares for JointProblem<'_> {
    fn num_params(&self) -> usize {
        self.layout.num_params()
    }
    fn num_residuals(&self) -> usize {
        self.prior_offset() + self.prior_rows_per_view() * self.terms.a.len()
    }
    fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        let (image, prior) = r.split_at_mut(self.prior_offset());
        self.raw_residuals(p, image)?;
        let nc = 2 * self.terms.circles.len();
        let (wc, ws) = (self.wc(), self.ws());
        for (i, x) in image.iter_mut().enumerate() {
            *x *= if i < nc { wc } else { ws };
        }
        if self.robot {
            let u = self.image_prior();
            robot_noise::prior_residuals(&self.decode(p), &self.robot_weights(), &u, prior);
        }
        Ok(())
    }
    fn residuals_and_jacobian(&self, p: &[f64], r: &mut [f64], jac: MatMut<'_, f64>) -> Result<()> {
        dense_jacobian_from_rows(self, p, r, jac)
    }
    fn jacobian_row_width(&self) -> Option<usize> {
        // Every image residual depends on (nearly) every global parameter, and on its
        // view's correction.
        Some(self.row_width())
    }
    fn residuals_and_jacobian_rows(
        &self,
        p: &[f64],
        r: &mut [f64],
        rows: &mut JacobianRows,
    ) -> Result<()> {
        let s = self.decode(p);
        let views = self.linearise_views(p, &s);
        let w = self.row_width();
        let nc = self.terms.circles.len();
        let (image, rp) = r.split_at_mut(self.prior_offset());
        let (rc, rs) = image.split_at_mut(2 * nc);
        // Dense rows: values of columns 0..n; sparse: the global columns, then the
        // view's per-view columns.
        {
            let (_, vals) = rows.parts_mut();
            let (vimage, _) = vals.split_at_mut(self.prior_offset() * w);
            let (vc, vs) = vimage.split_at_mut(2 * nc * w);
            self.circle_rows(&s, &views, rc, vc)?;
            self.stripe_rows(&s, &views, rs, vs)?;
        }
        if self.robot || self.bench {
            let ng = self.layout.num_global();
            if self.robot {
                let (_, vals) = rows.parts_mut();
                // The image information of this evaluation first: the image part's
                // prior factors are computed from it at a solve's first evaluation.
                self.store_image_information(vals, w, ng);
                if self.image_pose && self.freeze_pending.swap(false, Ordering::Relaxed) {
                    self.freeze_image_prior();
                }
                let u = self.image_prior();
                let vp = &mut vals[self.prior_offset() * w..];
                robot_noise::prior_rows(&s, &self.robot_weights(), &u, rp, vp, w, ng);
            }
            let (cols, _) = rows.parts_mut();
            let block = if self.robot {
                Block::RobotPose
            } else {
                Block::BoardPose
            };
            let mut template: Vec<usize> = (0..w).collect();
            let po = self.prior_offset();
            // Without the robot-pose noise there are no prior rows; rows as wide as the
            // vector (the bench's single view with everything else held) are dense and
            // store no columns.
            let runs = if cols.is_empty() {
                &[][..]
            } else {
                &self.view_runs[..]
            };
            for &(view, i0, i1) in runs.iter().filter(|r| self.robot || r.1 < po) {
                if let Some(vc) = self.layout.view_columns(block, view) {
                    // The view's per-view columns are contiguous: the block's first.
                    let vc = vc.start..vc.start + self.layout.per_view_len();
                    template[ng..].iter_mut().zip(vc).for_each(|(c, v)| *c = v);
                }
                for row in cols[i0 * w..i1 * w].chunks_exact_mut(w) {
                    row.copy_from_slice(&template);
                }
            }
        }
        Ok(())
    }
    fn reweight(&self, r: &[f64], leverages: &mut Leverages<'_>) -> Option<Vec<f64>> {
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
    fn retract(&self, p: &[f64], dp: &[f64], out: &mut [f64]) {
        self.layout.retract(p, dp, out);
    }
}

/// The runs of consecutive residual rows of one view and one kind, `(view, first,
/// end)`: circles (2 rows each), stripe points, then `prior_rows` prior rows per view.
fn view_runs(t: &Terms, prior_rows: usize) -> Vec<(usize, usize, usize)> {
    let (nc, po) = (2 * t.circles.len(), 2 * t.circles.len() + t.stripes.len());
    let circles = t.circles.iter().flat_map(|c| [c.view, c.view]);
    let stripes = t.stripes.iter().map(|s| s.view);
    let priors = (0..t.a.len()).flat_map(|v| std::iter::repeat_n(v, prior_rows));
    let mut runs: Vec<(usize, usize, usize)> = Vec::new();
    for (i, v) in circles.chain(stripes).chain(priors).enumerate() {
        match runs.last_mut() {
            Some(r) if r.0 == v && i != nc && i != po => r.2 = i + 1,
            _ => runs.push((v, i, i + 1)),
        }
    }
    runs
}

fn parallel_error(view: usize) -> Error {
    Error::Degenerate(format!(
        "the laser plane is parallel to the board plane of view {view} (of the views used)"
    ))
}

/// The line where the laser plane `(n1, d1)` meets the board plane (third column of
/// `rot`, through `t`): a point and a unit direction, camera frame.
fn stripe_line<T: Scalar>(
    n1: &[T; 3],
    d1: T,
    rot: &[[T; 3]; 3],
    t: &[T; 3],
) -> Result<([T; 3], [T; 3])> {
    let n2 = [rot[0][2], rot[1][2], rot[2][2]];
    let d2 = dot(&n2, t);
    let dir = cross(n1, &n2);
    let s2 = dot(&dir, &dir);
    if s2.value().is_nan() || s2.value() <= 1e-18 {
        return Err(Error::Degenerate(
            "the laser plane is parallel to a view's board plane".into(),
        ));
    }
    let a = cross(&n2, &dir);
    let b = cross(&dir, n1);
    let p: [T; 3] = std::array::from_fn(|i| (a[i] * d1 + b[i] * d2) / s2);
    let s = s2.sqrt();
    let u: [T; 3] = std::array::from_fn(|i| dir[i] / s);
    Ok((p, u))
}

/// Foot point of `target` on the image of the 3D line `p0 + s dir`: `s*`, and the unit
/// normal of the image curve there. Gauss-Newton along the line from the distortion-free
/// closest point.
fn foot_point(
    cam: &[f64; 9],
    p0: &[f64; 3],
    dir: &[f64; 3],
    target: [f64; 2],
    start: f64,
) -> Result<(f64, [f64; 2])> {
    // Start: closest point of the 3D line to the distortion-free viewing ray.
    let r = Vector3::new(
        (target[0] - cam[2]) / cam[0],
        (target[1] - cam[3]) / cam[1],
        1.0,
    )
    .normalize();
    let (pv, dv) = (Vector3::from(*p0), Vector3::from(*dir));
    let b = dv.dot(&r);
    let den = 1.0 - b * b;
    let mut s = if start.is_finite() {
        start
    } else if den > 1e-12 {
        (b * r.dot(&pv) - dv.dot(&pv)) / den
    } else {
        0.0
    };
    let cd: [Dual<1>; 9] = std::array::from_fn(|i| Dual::cst(cam[i]));
    let mut normal = [0.0, 0.0];
    for it in 0..30 {
        let sd = Dual::<1>::var(s, 0);
        let p: [Dual<1>; 3] = std::array::from_fn(|i| Dual::cst(p0[i]) + sd.scale(dir[i]));
        if p[2].v <= 0.0 {
            return Err(Error::Degenerate(
                "a view's stripe line passes behind the camera".into(),
            ));
        }
        let uv = project_generic(&cd, &p);
        let res = [uv[0].v - target[0], uv[1].v - target[1]];
        let j = [uv[0].d[0], uv[1].d[0]];
        let jj = j[0] * j[0] + j[1] * j[1];
        if jj.is_nan() || jj <= 1e-300 || !jj.is_finite() {
            return Err(Error::Degenerate(
                "a view's stripe line images as a point".into(),
            ));
        }
        let jn = jj.sqrt();
        normal = [-j[1] / jn, j[0] / jn];
        let step = -(j[0] * res[0] + j[1] * res[1]) / jj;
        s += step;
        if (step * jn).abs() < 1e-11 || it == 29 {
            break;
        }
    }
    Ok((s, normal))
}
