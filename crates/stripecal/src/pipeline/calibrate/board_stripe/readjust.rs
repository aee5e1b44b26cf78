//! The adjustment run again on the board's corrected stripe points, its covariance
//! widened by what the correction leaves (the emitter's assumed range among it).

use super::{correct_board_stripes, BoardStripeCorrection};
use crate::calib::joint::{joint_adjustment, stepped_from, JointOptions, JointResult, JointStart};
use crate::calib::ViewObs;
use crate::error::Result;
use crate::model::board::Board;
use crate::model::geometry::Iso3;
use crate::pipeline::emitter_carry::EmitterResponse;
use crate::pipeline::{CalibrateOptions, Method};

/// Gauss-Newton steps from the corrected solution to the emitter-moved one (the first
/// settles the robot-pose corrections, the second the rest to second order).
const EMITTER_STEPS: usize = 2;

/// What became of the board stripe-bias correction: applied, or why not.
pub(in crate::pipeline::calibrate) type BoardStripeOutcome =
    std::result::Result<BoardStripeCorrection, String>;

/// The stripe's bias on the board corrected ([`super`]) and the adjustment
/// run again from its own solution on the corrected points, its covariance widened by
/// what the correction leaves; the input as it is when the correction is off or cannot
/// be made (the paper's method, no widths, a sheet the widths do not determine).
///
/// What the correction leaves (the module docs of [`super`]): the model's
/// neglected terms, `u^2 D D^T` along the change `D` the correction made; the emitter,
/// whose position the calibration does not know, uniform within the assumed range along
/// each of the plane's two axes: the solution moved to the biases predicted for the
/// emitter at each end of a range (Gauss-Newton steps from the corrected solution:
/// [`EMITTER_STEPS`]), `d_+` and `d_-` its changes, each axis adding
/// `(d_+ d_+^T + d_- d_-^T) / 6` (a uniform distribution's variance, `a^2 / 3`, read at
/// both ends).
pub(in crate::pipeline::calibrate) fn correct_stripes(
    adj: JointResult,
    used_obs: Vec<ViewObs>,
    used_poses: &[Iso3],
    board: &Board,
    jopts: &JointOptions,
    opts: &CalibrateOptions,
) -> Result<(JointResult, Vec<ViewObs>, Option<BoardStripeOutcome>)> {
    let Some(plane) = adj
        .plane
        .filter(|_| opts.board_stripe_bias && opts.method == Method::OneStage)
    else {
        return Ok((adj, used_obs, None));
    };
    if !adj.camera.projection.is_brown5() {
        // the stripe-bias model projects through brown5's formula
        let why = format!(
            "the stripe-bias model knows brown5 cameras only (this camera's model is '{}')",
            adj.camera.projection.name()
        );
        return Ok((adj, used_obs, Some(Err(why))));
    }
    let corr = match correct_board_stripes(&used_obs, used_poses, &adj.camera, &plane, &opts.stripe)
    {
        Ok(c) => c,
        Err(why) => return Ok((adj, used_obs, Some(Err(why)))),
    };
    let start_of = |r: &JointResult| JointStart {
        camera: r.camera.clone(),
        plane: r.plane,
        hand_cam: r.hand_cam,
        base_board: r.base_board,
    };
    let jopts = &jopts.continuing(&adj);
    opts.cancel.check()?;
    let mut again = joint_adjustment(&corr.corrected, board, &start_of(&adj), jopts)?;
    let mut terms = vec![(
        again.named_difference(&adj),
        corr.summary.neglected_share.powi(2),
    )];
    let from = start_of(&again);
    // The emitter moved: +e1, -e1, +e2, -e2 (`emitter_moved`'s order). The same points
    // moved by other biases (thousandths of a pixel): Gauss-Newton steps from `again`
    // give the change to first order, without an adjustment each (its re-weighting
    // rounds and covariance); the adjustment where they do not apply.
    let mut moved = Vec::with_capacity(4);
    for views in &corr.emitter_moved {
        opts.cancel.check()?;
        let alt = match stepped_from(views, board, &again, jopts, EMITTER_STEPS)? {
            Some(alt) => alt,
            None => joint_adjustment(views, board, &from, jopts)?,
        };
        moved.push(alt.named_difference(&again));
    }
    terms.extend(moved.iter().map(|d| (d.clone(), 1.0 / 6.0)));
    again.add_systematic_terms(&terms);
    let mut summary = corr.summary;
    if let [p1, m1, p2, m2] = &moved[..] {
        summary.emitter_response = Some(EmitterResponse {
            origin_cam_mm: corr.emitter_origin_cam_mm,
            axes_cam: corr.emitter_axes_cam,
            range_mm: summary.emitter_range_mm,
            parameters: again.named_covariance.parameters.clone(),
            plus: [p1.clone(), p2.clone()],
            minus: [m1.clone(), m2.clone()],
            covariance_trace: again.named_covariance.matrix.trace(),
        });
    }
    Ok((again, corr.corrected, Some(Ok(summary))))
}
