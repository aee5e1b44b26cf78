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
//!
//! One file per part: [`terms`] (the observations), [`values`] (the residuals in f64),
//! [`jacobian`] (the Jacobian rows), [`line`](mod@line) (the stripe line and foot point),
//! [`variance`] (the groups' weights), [`shares`] (per-view shares of the normal
//! equations); here the problem itself and its [`LeastSquares`] implementation.

mod jacobian;
mod line;
mod shares;
mod terms;
mod values;
mod variance;

pub(super) use terms::Terms;
#[cfg(test)]
pub(super) use terms::{CircleTerm, StripeTerm};

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Mutex;

use faer::MatMut;
use nalgebra::{DMatrix, DVector};

use super::layout::{Block, JointParams, ParamLayout, SLOTS};
use super::robot_noise::{self, Floors, PriorWeights, RobotNoiseState};
use super::{JointOptions, MAX_REWEIGHTS, MAX_REWEIGHTS_POSE_NOISE};
use crate::calib::conic::CentreModel;
use crate::error::Result;
use crate::model::camera::Camera;
use crate::model::geometry::Iso3;
use crate::numerics::dual::Dual;
use crate::numerics::lm::{dense_jacobian_from_rows, JacobianRows, LeastSquares, Leverages};

/// Dual numbers over every parameter slot ([`ParamLayout`]).
type DSlots = Dual<SLOTS>;

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

    /// Values per Jacobian row: every column (dense) without the robot-pose noise, the
    /// global columns and the view's per-view columns with it.
    pub(super) fn row_width(&self) -> usize {
        if self.robot || self.bench {
            self.layout.num_global() + self.layout.per_view_len()
        } else {
            self.num_params()
        }
    }

    fn decode(&self, p: &[f64]) -> JointParams {
        self.layout.decode(p)
    }

    /// The robot's flange pose of every used view: from the corrected robot when it is
    /// calibrated, else as given.
    pub fn flanges(&self, s: &JointParams) -> std::borrow::Cow<'_, [Iso3]> {
        match &self.layout.robot {
            Some(rb) => std::borrow::Cow::Owned(rb.flanges(&s.robot)),
            None => std::borrow::Cow::Borrowed(&self.terms.a),
        }
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
    fn view_blocks(&self) -> Option<(usize, usize)> {
        // Sparse rows: a row holds the global columns and its view's per-view columns
        // (the blocks `ng + v pv..`, [`JointProblem::view_normals_by_view`]).
        (self.robot || self.bench).then(|| (self.layout.num_global(), self.layout.per_view_len()))
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
            let written = rows.columns_written();
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
            // store no columns. The columns are the layout's, the same at every
            // evaluation: written once into the same rows.
            let runs = if cols.is_empty() || written {
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
            rows.set_columns_written();
        }
        Ok(())
    }
    fn reweight(&self, r: &[f64], leverages: &mut Leverages<'_>) -> Option<Vec<f64>> {
        self.reestimate_weights(r, leverages)
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
