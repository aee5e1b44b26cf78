//! From observations to a calibration: the stages of the robot, bench, laser-only and
//! prior pipelines (observations, camera, labellings, stripe points on the board plane,
//! robot poses against images, laser plane, adjustment, self-checks, report, quality
//! gates), one file per stage; [`pipeline`](super)'s module docs give the steps.

// The stages name the pipeline's options and records as their parent's (`super::`).
use super::{emitter_carry, CalibrateOptions, CalibrationReport, Method, Stages, ViewStatus};

mod bench;
mod board_scale;
pub mod board_stripe;
mod dispatch;
mod flat_views;
pub mod gates;
mod held;
mod kinematics;
mod labels;
mod laser_only;
mod leave_out;
mod loo;
mod observe;
mod pairing;
mod prior;
mod report;
mod robot;
mod stages;
pub mod stripe_select;
#[cfg(test)]
mod tests;
mod views;

pub use bench::BENCH_KEY;
pub use dispatch::calibrate_observations;
pub(super) use dispatch::calibrate_unjudged;
pub(super) use held::check_from_size;
pub use loo::{
    held_out_laser_board, leave_one_out_refits, leave_one_out_with, FoldMethod, FoldsSolved,
};
pub use observe::{dataset_channel, observe_dataset};
pub(super) use observe::{observe, Observed};
