//! From observations to a calibration, dispatched four ways by what the options and the
//! views hold: `--from` alone (a prior, [`super::prior`]), a bench dataset
//! ([`super::bench`]), a held camera and chain (`--laser-only`, [`super::laser_only`]),
//! or the robot pipeline ([`super::robot`]); then the quality gates.

use super::gates::{converged, determined, judge};
use super::held::held;
use super::laser_only::calibrate_held_chain;
use super::robot::calibrate_robot;
use super::{CalibrateOptions, CalibrationReport};
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::{QualityCheck, Rig};

/// Runs the pipeline on observations (see [`crate::pipeline`]'s module docs) and its quality gates
/// ([`super::gates`]). `views` are the views whose board was found; `rig` gives the
/// board, image size, distortion model and robot.
///
/// Errors: [`Error::Quality`] when a gate fails (unless `opts.accept_poor`), carrying
/// the calibration when one could be computed; the stages' errors.
pub fn calibrate_observations(
    views: &[ViewObs],
    rig: &Rig,
    opts: &CalibrateOptions,
) -> Result<CalibrationReport> {
    let (rep, checks) = calibrate_unjudged(views, rig, opts)?;
    judge(rep, checks, opts)
}

/// The pipeline without the final verdict: the calibration and the gates' checks.
pub(in crate::pipeline) fn calibrate_unjudged(
    views: &[ViewObs],
    rig: &Rig,
    opts: &CalibrateOptions,
) -> Result<(CalibrationReport, Vec<QualityCheck>)> {
    check_poses_finite(views)?;
    super::held::check_from_size(rig, opts)?;
    opts.cancel.check()?;
    // `--from` without `--fix`: the file's camera and plane as a prior.
    if let Some(from) = opts
        .from
        .as_ref()
        .filter(|_| super::held::holds_nothing(opts) && !super::bench::is_bench(views))
    {
        return super::prior::calibrate_with_prior(opts, from, |held| {
            calibrate_unjudged(views, rig, held)
        });
    }
    let held = held(opts)?;
    if super::bench::is_bench(views) {
        return super::bench::calibrate_bench(views, rig, opts, held.as_ref());
    }
    if let Some(h) = held.as_ref().filter(|h| h.chain_held()) {
        let rep = calibrate_held_chain(views, rig, opts, h)?;
        let checks = vec![
            determined(&rep.adjustment, &rep.calibration.camera, None),
            converged(&rep.adjustment, opts.method),
        ];
        return Ok((rep, checks));
    }
    calibrate_robot(views, rig, opts, held.as_ref())
}

/// An error naming the first view whose robot pose is not finite.
fn check_poses_finite(views: &[ViewObs]) -> Result<()> {
    for v in views {
        if let Some(t) = v.base_hand {
            if !t.to_homogeneous().iter().all(|x| x.is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "view {}: the robot pose is not finite",
                    v.view
                )));
            }
        }
    }
    Ok(())
}
