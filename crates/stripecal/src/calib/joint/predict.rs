//! The covariance the adjustment WOULD give, before any image is taken (pose planning).
//!
//! [`predicted_covariance`] builds the same [`JointProblem`] as [`super::joint_adjustment`]
//! over the given (predicted, noise-free) observations, with FIXED weights `1 / sigma`
//! (circle, stripe; no variance components, no Huber loss), evaluates its Jacobian at
//! the start values without solving (the observations are the predicted ones, so the
//! residuals are zero) and returns `(J^T W J)^-1`: the covariance of the estimated
//! parameters to first order when the detections have the stated noise. It is generic
//! over the parameter layout: every column the layout estimates (a new block included)
//! appears in [`Prediction::param_names`] and [`Prediction::covariance`].

use faer::Mat;
use nalgebra::DMatrix;

use super::layout::ParamLayout;
use super::residuals::{JointProblem, Terms};
use super::{covariance, free_blocks, FreeBlocks, JointOptions, JointStart};
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::NamedCovariance;
use crate::numerics::lm::{covariance as lm_covariance, dense_jacobian_from_rows};

/// The predicted covariance of the adjustment's parameters.
#[derive(Debug, Clone)]
pub struct Prediction {
    /// Names of the state vector's entries ([`ParamLayout::names`]: the global blocks',
    /// then the per-view ones, e.g. the robot-pose corrections).
    pub param_names: Vec<String>,
    /// Their covariance `(J^T W J)^-1` (units of the state vector).
    pub covariance: DMatrix<f64>,
    /// The covariance of the estimated numbers under calibration.json's names (as
    /// [`super::JointResult::named_covariance`]).
    pub named_covariance: NamedCovariance,
    /// The blocks estimated (the options', the laser plane held without stripe points).
    pub free: FreeBlocks,
    /// Circle (target point) residuals and stripe points used.
    pub circles: usize,
    pub stripe_points: usize,
    /// Views used (dataset rows).
    pub views: Vec<usize>,
    pub warnings: Vec<String>,
    /// With the robot calibrated ([`JointOptions::robot`]): the DH corrections the
    /// identifiability rule holds, with why.
    pub robot_fixed: Vec<(String, String)>,
}

/// The covariance [`super::joint_adjustment`] would report for observations with
/// one-sigma noise `sigma_px = (circle, stripe)` px at the poses of `views`, linearised
/// at `start` (module docs). The views' observations should be the predicted ones at
/// `start` (their residuals do not enter).
///
/// Errors: those of the adjustment's set-up (too few views, nothing to estimate...);
/// [`Error::InvalidInput`] for a non-positive sigma; [`Error::Degenerate`] naming the
/// parameters the views do not determine.
pub fn predicted_covariance(
    views: &[ViewObs],
    board: &Board,
    start: &JointStart,
    opts: &JointOptions,
    sigma_px: (f64, f64),
) -> Result<Prediction> {
    for (what, s) in [("circle", sigma_px.0), ("stripe", sigma_px.1)] {
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::InvalidInput(format!(
                "the {what} noise must be a positive number of pixels, got {s}"
            )));
        }
    }
    board.validate()?;
    start.camera.validate()?;
    let mut warnings = Vec::new();
    let terms = Terms::collect(views, board, &mut warnings)?;
    let free = free_blocks(&terms, start, opts)?;
    let fixed_weights = JointOptions {
        variance_components: false,
        robust: false,
        initial_sigma_px: sigma_px,
        ..opts.clone()
    };
    let (robot, robot_fixed) =
        super::robot_solve::structural_block(start, &free, &fixed_weights, &terms)?;
    let layout = ParamLayout::of(start, &free, opts, &terms.used, robot);
    if layout.num_global() == 0 {
        return Err(Error::InvalidInput(
            "nothing to predict: every block is held".into(),
        ));
    }
    let fixed = JointOptions {
        variance_components: false,
        robust: false,
        initial_sigma_px: sigma_px,
        ..opts.clone()
    };
    let (circles, stripe_points, used) =
        (terms.circles.len(), terms.stripes.len(), terms.used.clone());
    let mut problem = JointProblem::new(&start.camera, &layout, terms, &fixed);
    problem.prepare_solve(fixed.centre_model, fixed.centre_model);
    let p = layout.encode();
    let (m, n) = (
        crate::numerics::lm::LeastSquares::num_residuals(&problem),
        layout.num_params(),
    );
    let mut r = vec![0.0; m];
    let mut jac = Mat::<f64>::zeros(m, n);
    dense_jacobian_from_rows(&problem, &p, &mut r, jac.as_mut())?;
    let jtj_f = jac.transpose() * &jac;
    let jtj = DMatrix::from_fn(n, n, |a, b| jtj_f[(a, b)]);
    if jtj.iter().any(|x| !x.is_finite()) {
        return Err(Error::Degenerate(
            "the predicted normal matrix is not finite".into(),
        ));
    }
    let (cov, unobservable) = lm_covariance(&jtj, 1.0, fixed.lm.rank_tol);
    let names = layout.names();
    if !unobservable.is_empty() {
        let which: Vec<&str> = unobservable.iter().map(|&i| names[i].as_str()).collect();
        return Err(Error::Degenerate(format!(
            "the poses do not determine {}: add poses with more rotation or translation \
             variety, or hold those blocks",
            which.join(", ")
        )));
    }
    let s = layout.decode(&p);
    let named_covariance = covariance::named_covariance(&layout, &p, &s, &cov, 1.0);
    Ok(Prediction {
        param_names: names,
        covariance: cov,
        named_covariance,
        free,
        circles,
        stripe_points,
        views: used,
        warnings,
        robot_fixed,
    })
}
