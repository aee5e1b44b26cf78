//! The leave-one-view-out's refits as one Gauss-Newton step each (DECISIONS 3: "a
//! one-step update whose held-out figures agree with the full refit's within 5 %").
//!
//! Every row of the adjustment belongs to one view (its circles, its stripe points, its
//! robot-pose prior), and a view's own columns (its robot-pose correction, or its board
//! pose on the bench) appear in no other view's rows. Each view's share of the normal
//! equations, reduced to the global columns by eliminating its own (`M_v`, `s_v`:
//! [`JointProblem::view_shares`]), is therefore all that view contributes; the problem
//! without view `k` has the reduced normal equations `sum_{v != k} M_v` and gradient
//! `sum_{v != k} s_v`. At the full solution the sum over all views has zero gradient, so
//! the refit without `k` is one Gauss-Newton step away:
//! `dg_k = -(M - M_k)^-1 (s - s_k)`, a small dense solve per view (the global columns
//! only) after one evaluation of the Jacobian: linear in the number of views, where a
//! refit per view costs a whole adjustment over `n - 1` views (and its dense factorisation
//! of the per-view columns).
//!
//! On the bench the weights (variance components) are the full solution's, not
//! re-estimated without the view, and the step is linear; both are second order in one
//! view's share of the data. On a robot the variance components are re-estimated
//! without the view as the refit re-estimates them ([`reweighted_folds`]: each view's
//! share kept per residual group, the fold's groups' sums of squares and redundancies
//! from its linear solution, the adjustment's floors and dead band) until they settle.
//! The held-out figures are compared with the refits' in the integration tests
//! (`crates/stripecal/tests/it/calib_loo_step.rs`): on a robot the image part's factor
//! of the robot-pose noise, barely determined, ends elsewhere in some refits, and the
//! pipeline refits there.
//!
//! The same steps move a solution to slightly moved observations ([`stepped_from`]: the
//! board's stripe points under another emitter's biases, whose change of the numbers is
//! the emitter's part of the covariance).
//!
//! With a robot calibration (its DH rows and selection rounds) or Huber weights the
//! refits are run instead ([`one_step_folds`] returns `None`).

use nalgebra::{DMatrix, DVector};

use super::finish;
use super::layout::ParamLayout;
use super::residuals::{robot_sigma_update, Group, GroupShare, JointProblem, Terms, GROUPS};
use super::robot_noise::IMAGE_FACTOR_FLOOR;
use super::{FreeBlocks, JointOptions, JointResult, JointStart, RobotMode};
use crate::calib::ViewObs;
use crate::error::Result;
use crate::model::board::Board;
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};

/// Gauss-Newton steps that settle the per-view columns (the robot-pose corrections,
/// which a [`JointResult`] does not carry) at the full solution before the folds' steps.
const SETTLE_STEPS: usize = 2;

/// What a fold (the calibration without one view) determined: the numbers the
/// leave-one-out predicts the view from.
#[derive(Debug, Clone)]
pub struct FoldSolution {
    pub camera: Camera,
    pub plane: Option<Plane>,
    pub hand_cam: Iso3,
    pub base_board: Iso3,
    pub board_scale: f64,
}

/// The solution without each of `views` in turn (in their order), each one Gauss-Newton
/// step from `full` (the adjustment of `views` with `opts`; module docs). `None` when
/// the step does not apply: a robot calibration, Huber weights, a view the adjustment
/// skipped, fewer than 4 views, or normal equations that are singular without a view
/// (the caller then refits).
pub fn one_step_folds(
    views: &[ViewObs],
    board: &Board,
    full: &JointResult,
    opts: &JointOptions,
) -> Result<Option<Vec<FoldSolution>>> {
    if views.len() < 4 {
        return Ok(None);
    }
    let Some(mut at) = Linearised::new(views, board, full, opts)? else {
        return Ok(None);
    };
    // The per-view columns at the full solution: Gauss-Newton steps of the whole problem
    // (the global columns barely move: the full solution is their optimum).
    if at.layout.per_view_len() > 0 && !at.bench {
        for _ in 0..SETTLE_STEPS {
            if !at.step()? {
                return Ok(None);
            }
        }
    }
    if !at.bench && at.opts.variance_components {
        return reweighted_folds(&at, full.free);
    }
    let Some(reduced) = at.problem().view_shares(&at.p)? else {
        return Ok(None);
    };
    let ng = at.layout.num_global();
    let (m, s) = summed(&reduced, ng);
    let mut folds = Vec::with_capacity(views.len());
    for (mk, sk) in &reduced {
        let Some(dg) = solve(&m - mk, &(&s - sk)) else {
            return Ok(None);
        };
        let mut dp = vec![0.0; at.layout.num_params()];
        dp[..ng].copy_from_slice(dg.as_slice());
        let mut q = at.p.clone();
        at.layout.retract(&at.p, &dp, &mut q);
        folds.push(fold_solution(&at.layout, &at.start, full.free, &q)?);
    }
    Ok(Some(folds))
}

/// `base` (an adjustment with `opts`) with its numbers moved to the solution for
/// `views`, the same views and points with their observations moved slightly (the
/// board's stripe points by another emitter's biases), by `steps` Gauss-Newton steps
/// from `base` at `base`'s weights: the change of the numbers to first order in the
/// observations' change, without a whole adjustment's iterations and covariance.
/// `None` when it does not apply ([`one_step_folds`]' conditions).
pub fn stepped_from(
    views: &[ViewObs],
    board: &Board,
    base: &JointResult,
    opts: &JointOptions,
    steps: usize,
) -> Result<Option<JointResult>> {
    let Some(mut at) = Linearised::new(views, board, base, opts)? else {
        return Ok(None);
    };
    for _ in 0..steps {
        if !at.step()? {
            return Ok(None);
        }
    }
    let f = fold_solution(&at.layout, &at.start, base.free, &at.p)?;
    let mut r = base.clone();
    r.camera = f.camera;
    r.plane = f.plane;
    r.hand_cam = f.hand_cam;
    r.base_board = f.base_board;
    r.board_scale = f.board_scale;
    Ok(Some(r))
}

/// The adjustment's problem over `views` linearised at a solution `full` of it (the
/// per-view corrections at 0: a [`JointResult`] does not carry them), at its weights.
struct Linearised {
    layout: ParamLayout,
    terms: Terms,
    start: JointStart,
    opts: JointOptions,
    bench: bool,
    p: Vec<f64>,
}

impl Linearised {
    /// `None` when the steps do not apply: a robot calibration, Huber weights, a view
    /// the adjustment skips.
    fn new(
        views: &[ViewObs],
        board: &Board,
        full: &JointResult,
        opts: &JointOptions,
    ) -> Result<Option<Linearised>> {
        let calibrating_robot = opts
            .robot
            .as_ref()
            .is_some_and(|r| r.mode != RobotMode::Fixed);
        if calibrating_robot || full.robot.is_some() || opts.robust {
            return Ok(None);
        }
        let bench = !full.board_poses.is_empty();
        let mut warnings = Vec::new();
        let terms = if bench {
            Terms::collect_bench(views, board, &mut warnings)?
        } else {
            Terms::collect(views, board, &mut warnings)?
        };
        if terms.used.len() != views.len()
            || views.iter().zip(&terms.used).any(|(v, u)| v.view != *u)
        {
            return Ok(None);
        }
        let mut o = opts.continuing(full);
        let start = if bench {
            o.robot_noise = false;
            o.robot = None;
            o.board_scale = 1.0;
            JointStart {
                camera: full.camera.clone(),
                plane: full.plane,
                hand_cam: Iso3::identity(),
                base_board: Iso3::identity(),
            }
        } else {
            o.board_scale = full.board_scale;
            JointStart {
                camera: full.camera.clone(),
                plane: full.plane,
                hand_cam: full.hand_cam,
                base_board: full.base_board,
            }
        };
        let layout = if bench {
            let poses: Option<Vec<Iso3>> = views
                .iter()
                .map(|v| {
                    full.board_poses
                        .iter()
                        .find(|(i, _)| *i == v.view)
                        .map(|p| p.1)
                })
                .collect();
            let Some(poses) = poses else {
                return Ok(None);
            };
            ParamLayout::bench(&start, &full.free, &terms.used, &poses)
        } else {
            ParamLayout::of(&start, &full.free, &o, &terms.used, None)
        };
        if layout.num_global() == 0 {
            return Ok(None);
        }
        let p = layout.encode();
        Ok(Some(Linearised {
            layout,
            terms,
            start,
            opts: o,
            bench,
            p,
        }))
    }

    /// The problem at the solution's weights (its Jacobian the exact centre model's).
    fn problem(&self) -> JointProblem<'_> {
        JointProblem::new(
            &self.start.camera,
            &self.layout,
            self.terms.clone(),
            &self.opts,
        )
    }

    /// One Gauss-Newton step of the whole problem (global and per-view columns, the
    /// latter eliminated view by view); `false` when the normal equations are singular.
    fn step(&mut self) -> Result<bool> {
        let ng = self.layout.num_global();
        let own_cols = self.layout.per_view_len();
        let shares = self.problem().view_normals_by_view(&self.p)?;
        let Some(reduced) = reduce(&shares) else {
            return Ok(false);
        };
        let (m, s) = summed(&reduced, ng);
        let Some(dg) = solve(m, &s) else {
            return Ok(false);
        };
        let mut dp = vec![0.0; self.layout.num_params()];
        dp[..ng].copy_from_slice(dg.as_slice());
        for (v, share) in shares.iter().enumerate() {
            let Some(dd) = share.own_step(&dg) else {
                return Ok(false);
            };
            dp[ng + v * own_cols..ng + (v + 1) * own_cols].copy_from_slice(dd.as_slice());
        }
        let mut next = self.p.clone();
        self.layout.retract(&self.p, &dp, &mut next);
        self.p = next;
        Ok(true)
    }
}

/// Every view's share reduced to the global columns; `None` when one's own block is
/// singular.
fn reduce(
    shares: &[crate::calib::clustered::ViewShare],
) -> Option<Vec<(DMatrix<f64>, DVector<f64>)>> {
    shares.iter().map(|s| s.clone().reduced()).collect()
}

/// The sums of the reduced shares.
fn summed(shares: &[(DMatrix<f64>, DVector<f64>)], ng: usize) -> (DMatrix<f64>, DVector<f64>) {
    shares.iter().fold(
        (DMatrix::zeros(ng, ng), DVector::zeros(ng)),
        |(m, s), (mv, sv)| (m + mv, s + sv),
    )
}

/// The Gauss-Newton step `-M^-1 s`; `None` when `M` is not positive definite.
fn solve(m: DMatrix<f64>, s: &DVector<f64>) -> Option<DVector<f64>> {
    Some(-m.cholesky()?.solve(s))
}

/// The numbers of parameter vector `q` (the held blocks as `start` has them, as the
/// adjustment returns them).
fn fold_solution(
    layout: &ParamLayout,
    start: &JointStart,
    free: FreeBlocks,
    q: &[f64],
) -> Result<FoldSolution> {
    let s = layout.decode(q);
    let (camera, plane) = finish::camera_and_plane(start, free, &s)?;
    let (hand_cam, base_board) = finish::estimated_transforms(layout, q, start, free);
    Ok(FoldSolution {
        camera,
        plane,
        hand_cam,
        base_board,
        board_scale: s.scale,
    })
}

/// Re-estimations of the variance components per fold at most (each a linear solve of
/// the fold), as many as one of the adjustment's solves makes with the robot-pose noise
/// (its fixed-point iteration is slow where a component is barely determined).
const FOLD_REWEIGHTS: usize = 30;

/// Relative change of every image sigma below which a fold's variance components have
/// settled (the robot-pose sigmas settle by their dead band).
const FOLD_SIGMA_TOL: f64 = 1e-4;

/// The folds with the variance components re-estimated without the view, as the refit
/// does (module docs): the problem linearised once at the full solution, each view's
/// share kept per residual group, and per fold the linear least-squares solution
/// without the view at the fold's weights, its groups' sums of squares and
/// redundancies (`m_g - tr(N^-1 N_g)`), the sigmas re-estimated from them (floors and
/// dead band as in the adjustment), until they settle.
fn reweighted_folds(at: &Linearised, free: FreeBlocks) -> Result<Option<Vec<FoldSolution>>> {
    let problem = at.problem();
    let shares = problem.view_group_normals(&at.p)?;
    let w0 = problem.all_weights();
    let info = problem.robot_state().info;
    let robot = problem.robot_noise();
    let image = robot && problem.robot_weights().image.is_some();
    let ng = at.layout.num_global();
    let pv = at.layout.per_view_len();
    let nv = shares.len();
    let folds: Vec<Option<FoldSolution>> = {
        use rayon::prelude::*;
        (0..nv)
            .into_par_iter()
            .map(|k| -> Result<Option<FoldSolution>> {
                let others: Vec<usize> = (0..nv).filter(|&v| v != k).collect();
                let info_k: Vec<_> = others
                    .iter()
                    .filter_map(|&v| info.get(v).copied())
                    .collect();
                let mut w = w0;
                let mut sol = None;
                for _ in 0..FOLD_REWEIGHTS {
                    let c: [f64; GROUPS] = std::array::from_fn(|g| (w[g] / w0[g]).powi(2));
                    let Some(f) = FoldSystem::solve(&shares, &others, &c, ng, pv) else {
                        return Ok(None);
                    };
                    let sig = f.group_sigmas(&shares, &others, &c, &w0);
                    let mut next = w;
                    for g in [Group::Circle as usize, Group::Stripe as usize] {
                        if let Some(s) = sig[g] {
                            next[g] = 1.0 / s.max(1e-9);
                        }
                    }
                    if robot {
                        let sigma_px = (1.0 / next[0], 1.0 / next[1]);
                        let floors = problem.robot_floors(&info_k, sigma_px);
                        let groups = [
                            (Group::RobotRotation, floors.rotation_rad),
                            (Group::RobotTranslation, floors.translation_mm),
                            (Group::ImagePose, IMAGE_FACTOR_FLOOR),
                        ];
                        for (g, floor) in groups.into_iter().take(if image { 3 } else { 2 }) {
                            let g = g as usize;
                            let s = robot_sigma_update(1.0 / w[g], sig[g], floor);
                            if s > 0.0 && s.is_finite() {
                                next[g] = 1.0 / s;
                            }
                        }
                    }
                    let settled =
                        (0..GROUPS).all(|g| (next[g] / w[g] - 1.0).abs() < FOLD_SIGMA_TOL);
                    sol = Some(f);
                    if settled {
                        break;
                    }
                    w = next;
                }
                let Some(f) = sol else { return Ok(None) };
                let mut dp = vec![0.0; at.layout.num_params()];
                dp[..ng].copy_from_slice(f.dg.as_slice());
                let mut q = at.p.clone();
                at.layout.retract(&at.p, &dp, &mut q);
                Ok(Some(fold_solution(&at.layout, &at.start, free, &q)?))
            })
            .collect::<Result<_>>()?
    };
    Ok(folds.into_iter().collect())
}

/// The linear least-squares solution of a fold at group weights `c` (squared, relative
/// to the shares'): the global step, each view's own step, and what the leverages need.
struct FoldSystem {
    /// `M^-1`, the reduced normal equations' inverse (the global columns' cofactor).
    m_inv: DMatrix<f64>,
    dg: DVector<f64>,
    /// Per view of the fold: `A_dd^-1`, `X = A_dd^-1 A_dg`, its own step.
    own: Vec<(DMatrix<f64>, DMatrix<f64>, DVector<f64>)>,
}

impl FoldSystem {
    fn solve(
        shares: &[Vec<GroupShare>],
        others: &[usize],
        c: &[f64; GROUPS],
        ng: usize,
        pv: usize,
    ) -> Option<FoldSystem> {
        let mut m = DMatrix::zeros(ng, ng);
        let mut s = DVector::zeros(ng);
        let mut parts = Vec::with_capacity(others.len());
        for &v in others {
            let (a, b) = weighted(&shares[v], c);
            let agg = a.view((0, 0), (ng, ng));
            let bg = b.rows(0, ng);
            if pv == 0 {
                m += agg;
                s += bg;
                parts.push((
                    DMatrix::zeros(0, 0),
                    DMatrix::zeros(0, ng),
                    DVector::zeros(0),
                    b,
                ));
                continue;
            }
            let agd = a.view((0, ng), (ng, pv));
            let add_inv = a
                .view((ng, ng), (pv, pv))
                .into_owned()
                .cholesky()?
                .inverse();
            let x = &add_inv * agd.transpose();
            let y = &add_inv * b.rows(ng, pv);
            m += agg - agd * &x;
            s += bg - agd * &y;
            parts.push((add_inv, x, y, b));
        }
        let m_inv = m.cholesky()?.inverse();
        let dg = -(&m_inv * s);
        let own = parts
            .into_iter()
            .map(|(add_inv, x, y, _)| {
                let dd = -(y + &x * &dg);
                (add_inv, x, dd)
            })
            .collect();
        Some(FoldSystem { m_inv, dg, own })
    }

    /// Each group's sigma re-estimated at this solution (the shares' units divided by
    /// their weights `w0`): `sqrt(SSR_g / r_g)`, `None` without redundancy.
    fn group_sigmas(
        &self,
        shares: &[Vec<GroupShare>],
        others: &[usize],
        c: &[f64; GROUPS],
        w0: &[f64; GROUPS],
    ) -> [Option<f64>; GROUPS] {
        let mut acc = [(0usize, 0.0f64, 0.0f64); GROUPS];
        for (&v, (add_inv, x, dd)) in others.iter().zip(&self.own) {
            let dx = DVector::from_iterator(
                self.dg.len() + dd.len(),
                self.dg.iter().chain(dd.iter()).copied(),
            );
            // The view's block of N^-1: [[M^-1, -M^-1 X^T], [-X M^-1, A_dd^-1 + X M^-1 X^T]].
            let ng = self.dg.len();
            let pv = dd.len();
            let mut cv = DMatrix::zeros(ng + pv, ng + pv);
            cv.view_mut((0, 0), (ng, ng)).copy_from(&self.m_inv);
            if pv > 0 {
                let mx = &self.m_inv * x.transpose();
                cv.view_mut((0, ng), (ng, pv)).copy_from(&(-&mx));
                cv.view_mut((ng, 0), (pv, ng)).copy_from(&(-mx.transpose()));
                cv.view_mut((ng, ng), (pv, pv))
                    .copy_from(&(add_inv + x * &mx));
            }
            for (g, sh) in shares[v].iter().enumerate() {
                if sh.rows == 0 {
                    continue;
                }
                let a = &mut acc[g];
                a.0 += sh.rows;
                a.1 += sh.ss + 2.0 * dx.dot(&sh.b) + dx.dot(&(&sh.a * &dx));
                a.2 += c[g] * cv.dot(&sh.a);
            }
        }
        std::array::from_fn(|g| {
            let (rows, ss, lev) = acc[g];
            let mg = rows as f64;
            let red = mg - lev;
            (rows > 0 && red > 1e-9 * mg).then(|| (ss.max(0.0) / (w0[g] * w0[g]) / red).sqrt())
        })
    }
}

/// A view's share at group weights `c` (squared, relative to the shares').
fn weighted(share: &[GroupShare], c: &[f64; GROUPS]) -> (DMatrix<f64>, DVector<f64>) {
    let n = share[0].b.len();
    share.iter().zip(c).fold(
        (DMatrix::zeros(n, n), DVector::zeros(n)),
        |(a, b), (sh, &cg)| (a + &sh.a * cg, b + &sh.b * cg),
    )
}
