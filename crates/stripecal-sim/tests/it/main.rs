//! The twin crate's integration tests, one test binary: each file is a module, as it
//! was a binary of its own (`cargo test -p stripecal-sim --test it stripe_bias::` runs
//! one file's tests).

mod bench_twin;
mod board_stripe;
mod colour;
mod dataset;
mod fidelity;
mod profiler_calibration;
mod robot_calib_twin;
mod stripe_bias;
mod verify_artefacts;
