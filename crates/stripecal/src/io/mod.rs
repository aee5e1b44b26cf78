//! Files of spec/DATASET.md: rig.json, views.csv, scan.csv, calibration.json,
//! truth.json, sphere fits, PLY point clouds and grayscale images; and a calibrated
//! line profiler's: its rig.json, views.csv / scan.csv with a `profile` column, profile
//! files and calibration.json ([`sensor_kind`] / [`calibration_sensor_kind`] tell which
//! kind of sensor a rig or calibration describes).
//!
//! ## Conventions
//!
//! - Readers follow the spec exactly and reject anything else with [`Error::Format`]
//!   naming the file, the line / column or JSON key, and what was expected. Unknown JSON
//!   keys are ignored (and kept in `extra` where a struct has one).
//! - Writers never leave a half-written file: they write a temporary file in the
//!   target's folder and rename it over the target ([`write_atomic`]).
//! - Angles in files are degrees except rotation vectors (radians); lengths in mm.
//! - Image paths in views.csv / scan.csv are kept as written (relative to the dataset
//!   folder); [`Dataset::image_path`] resolves them.

mod artefacts;
mod atomic;
mod calibration;
mod csv;
mod dataset;
mod imageio;
mod json;
mod ply;
mod poses;
mod profile;
mod profile_dataset;
mod profile_rig;
mod profiler_calibration;
mod profiler_records;
mod records;
mod records_read;
mod rig;
mod sensor;
mod sphere_fit;

pub use artefacts::read_artefacts;
pub use atomic::{file_problem, write_atomic};
pub use calibration::{
    calibration_extra_keys, calibration_from_json, calibration_to_json, read_calibration,
    read_truth, take_bench_flag, truth_from_json, truth_to_json, write_calibration, write_truth,
    BENCH_KEY,
};
pub use csv::{
    read_scan_csv, read_views_csv, write_scan_csv, write_scan_csv_with, write_views_csv,
    write_views_csv_with,
};
pub use imageio::{
    image_size, load_gray, load_gray_info, load_image, load_image_info, save_gray_png, save_png,
    save_rgb_png, ImageInfo, MAX_IMAGE_BYTES, MAX_IMAGE_SIDE,
};
pub use ply::{read_ply, write_ply, write_ply_with_comments, PlyFormat};
pub use poses::{
    convention_columns, convention_names, matrix_to_pose, pose_to_matrix, PoseColumns, MATRIX_TOL,
    QUATERNION_TOL,
};
pub use profile::{parse_profile, read_profile, INVALID_Z_REL_TOL};
pub use profile_dataset::{is_profile_dataset, is_profile_scan};
pub use profile_rig::{
    profile_rig_from_json, profile_rig_to_json, read_profile_rig, write_profile_rig,
};
pub use profiler_calibration::{
    profiler_calibration_extra_keys, profiler_calibration_from_json, profiler_calibration_to_json,
    read_profiler_calibration, write_profiler_calibration,
};
pub use profiler_records::{
    diameter_check_to_json, mirror_to_json, profiler_adjustment_to_json, profiler_loo_to_json,
    profiler_records_split, profiler_records_to_json, profiler_view_to_json, PROFILER_RECORD_KEYS,
};
pub use records::{
    board_scale_to_json, calibration_extra, leave_one_out_to_json, robot_calibration_extra,
    robot_calibration_to_json, robot_pose_noise_extra, robot_pose_noise_to_json, robot_uncertainty,
    self_checks_extra, summary_to_json, uncertainty_to_json, view_record_to_json, warnings_to_json,
};
pub use records_read::{
    calibration_leave_one_out, calibration_records_from, calibration_robot_pose_noise,
};
pub use rig::{read_rig, rig_from_json, rig_to_json, write_rig};
pub use sensor::{calibration_sensor_kind, sensor_kind};
pub use sphere_fit::{read_sphere_fit, sphere_fit_to_json, write_sphere_fit};
