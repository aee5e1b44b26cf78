//! Python bindings of stripecal (`stripecal._core`): conversions, GIL release and error
//! mapping only; every number is computed by the `stripecal` crate.
//!
//! Array arguments accept array-likes of real numbers (copied to Rust memory before the
//! GIL is released); array results are new float64 numpy arrays. Core errors map to
//! Python exceptions as described in [`errors`].

mod args;
mod board;
mod calib_py;
mod camera;
mod convert;
mod errors;
mod files;
mod flatness_py;
mod geometry;
mod imageview;
mod measure_py;
mod plan_py;
mod pool;
mod poses;
mod profile_py;
mod profile_start_py;
mod reconstruct_py;
mod record_keys;
mod results;
mod rig;
mod robot;
mod sim;
mod sphere_fit;
mod truth;
mod vision_circles;
mod vision_stripe;
mod vision_target;

use pyo3::prelude::*;

pub use board::PyBoard;
pub use camera::PyCamera;
pub use errors::{map_err, map_err_at};
pub use results::PyCalibration;
pub use rig::{PyDataset, PyRig, PyScan};
pub use robot::PyRobot;
pub use sphere_fit::PySphereFit;
pub use truth::PyTruth;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.setattr("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    m.add(
        "CAMERA_PARAM_NAMES",
        pyo3::types::PyTuple::new(m.py(), stripecal::model::camera::PARAM_NAMES)?,
    )?;

    m.add_class::<PyCamera>()?;
    m.add_class::<PyRobot>()?;
    m.add_class::<PyBoard>()?;
    m.add_class::<PyRig>()?;
    m.add_class::<PyDataset>()?;
    m.add_class::<PyScan>()?;
    m.add_class::<PyCalibration>()?;
    m.add_class::<PyTruth>()?;
    m.add_class::<PySphereFit>()?;

    m.add_function(wrap_pyfunction!(record_keys::record_keys, m)?)?;
    m.add_function(wrap_pyfunction!(files::load_rig, m)?)?;
    m.add_function(wrap_pyfunction!(files::save_rig, m)?)?;
    m.add_function(wrap_pyfunction!(files::load_dataset, m)?)?;
    m.add_function(wrap_pyfunction!(files::load_scan, m)?)?;
    m.add_function(wrap_pyfunction!(files::load_calibration, m)?)?;
    m.add_function(wrap_pyfunction!(files::save_calibration, m)?)?;
    m.add_function(wrap_pyfunction!(files::load_truth, m)?)?;
    m.add_function(wrap_pyfunction!(files::save_truth, m)?)?;
    m.add_function(wrap_pyfunction!(files::load_sphere_fit, m)?)?;
    m.add_function(wrap_pyfunction!(files::save_sphere_fit, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_ply_py, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_ply_py, m)?)?;
    m.add_function(wrap_pyfunction!(files::load_image, m)?)?;
    m.add_function(wrap_pyfunction!(files::save_image, m)?)?;
    m.add_class::<profile_py::PyProfile>()?;
    m.add_class::<profile_py::PyProfileDataset>()?;
    m.add_class::<profile_py::PyProfilerCalibration>()?;
    m.add_function(wrap_pyfunction!(profile_py::read_profile_py, m)?)?;
    m.add_function(wrap_pyfunction!(profile_py::load_profile_dataset, m)?)?;
    m.add_function(wrap_pyfunction!(profile_py::read_profiler_calibration, m)?)?;
    m.add_function(wrap_pyfunction!(profile_py::write_profiler_calibration, m)?)?;
    m.add_function(wrap_pyfunction!(profile_start_py::profiler_start, m)?)?;
    m.add_function(wrap_pyfunction!(profile_start_py::profiler_adjust, m)?)?;
    m.add_function(wrap_pyfunction!(poses::pose_to_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(poses::matrix_to_pose, m)?)?;

    m.add_function(wrap_pyfunction!(geometry::rotvec_to_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(geometry::matrix_to_rotvec, m)?)?;
    m.add_function(wrap_pyfunction!(geometry::nearest_rotation, m)?)?;

    m.add_class::<sim::PyTwin>()?;
    m.add_function(wrap_pyfunction!(sim::sim_presets, m)?)?;
    m.add_function(wrap_pyfunction!(sim::sim_config, m)?)?;
    m.add_function(wrap_pyfunction!(sim::sim_surface_errors, m)?)?;

    m.add_function(wrap_pyfunction!(vision_circles::detect_circles, m)?)?;
    m.add_function(wrap_pyfunction!(vision_circles::detect_circles_full, m)?)?;
    m.add_class::<vision_target::PyTargetDetection>()?;
    m.add_function(wrap_pyfunction!(vision_target::detect_target, m)?)?;

    m.add_class::<vision_stripe::PyStripe>()?;
    m.add_class::<vision_stripe::PyLineFit>()?;
    m.add_function(wrap_pyfunction!(vision_stripe::extract_stripe, m)?)?;
    m.add_function(wrap_pyfunction!(vision_stripe::fit_line, m)?)?;

    m.add_function(wrap_pyfunction!(calib_py::solve_axzb, m)?)?;
    m.add_function(wrap_pyfunction!(calib_py::solve_axzb_full, m)?)?;
    m.add_function(wrap_pyfunction!(calib_py::fit_laser_plane, m)?)?;
    m.add_function(wrap_pyfunction!(flatness_py::board_flatness, m)?)?;
    m.add_function(wrap_pyfunction!(calib_py::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(calib_py::calibrate_camera, m)?)?;
    m.add_function(wrap_pyfunction!(plan_py::plan_poses, m)?)?;

    m.add_class::<reconstruct_py::PyCloud>()?;
    m.add_class::<reconstruct_py::PyPlaneFit>()?;
    m.add_function(wrap_pyfunction!(reconstruct_py::reconstruct, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct_py::reconstruct_scan, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct_py::triangulate, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct_py::fit_sphere, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct_py::fit_plane, m)?)?;
    m.add_function(wrap_pyfunction!(measure_py::measure_sphere, m)?)?;
    m.add_function(wrap_pyfunction!(measure_py::measure_ball_bar, m)?)?;
    m.add_function(wrap_pyfunction!(measure_py::measure_plane, m)?)?;
    m.add_function(wrap_pyfunction!(measure_py::verify, m)?)?;
    Ok(())
}
