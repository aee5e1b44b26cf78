//! The core crate's integration tests, one test binary: each file is a module, as it
//! was a binary of its own (`cargo test -p stripecal --test it calib_honesty::` runs one
//! file's tests). One binary links once and compiles the crate's generic code once,
//! where 26 binaries did each (CI's fresh build), and its tests share the cores.

mod calib_axzb;
mod calib_camera;
mod calib_gates;
mod calib_honesty;
mod calib_joint;
mod calib_loo_step;
mod calib_real_cells;
mod calib_rendered;
mod calib_robot;
mod calib_robot_noise;
mod calib_sheet;
mod calib_targets;
mod camera_model_toy;
mod chessboard_real;
mod common;
mod fuzz_mutation;
mod fuzz_public_api;
mod fuzz_readers;
mod fuzz_support;
mod io_earlier_files;
mod io_earlier_profiler;
mod io_formats;
mod io_poses;
mod layers;
mod pipeline_cancel;
mod plan_poses;
mod reconstruct;
mod reconstruct_errors;
mod targets;
mod vision_circles;
mod vision_stripe;
mod vision_stripe_real;
mod vision_targets;
