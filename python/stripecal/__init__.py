"""stripecal: calibration and measurement for a robot-mounted laser-stripe sensor.

One camera and one laser plane carried by a 6-axis robot: calibrate the camera, the laser
plane, the hand-eye transform ``T_hand_cam`` and the robot-world transform
``T_base_board`` from images of a circle board, then turn stripe images and joint
readings into 3D points in the robot base frame.

All numerics run in the Rust core (``stripecal._core``); this package re-exports its
API. Conventions (frames, units, pixel centres, camera model, laser plane, DH): see
docs/conventions.md. In short: lengths in mm, angles in degrees (rotation vectors in
radians), ``T_a_b`` maps frame b to frame a, the top-left pixel's centre is (0, 0).

Errors: ``StripecalError`` is the base class of the library's own errors;
``FormatError`` (bad file), ``InvalidInputError`` (bad argument) and
``DegenerateError`` (impossible geometry) and ``DetectionError`` (no target found in an
image, or not indexable without guessing) are also ``ValueError``;
``ConvergenceError`` is also ``RuntimeError``; ``CalibrationQualityError`` (a
calibration that failed its quality gates, carrying it for inspection) is also
``ValueError``; ``BadImageError`` (a scan frame's image that cannot be used, naming the
frame and the file) is a ``FormatError``. File-system failures raise the builtin
``OSError`` subclasses (``FileNotFoundError``...). Array arguments of the wrong type
raise ``TypeError``.

The API is grouped in submodules, each re-exported here (a name lives in exactly one):
``stripecal.model`` (Camera, Robot, Board, rotations), ``stripecal.io`` (records, file
readers and writers), ``stripecal.vision`` (target detection, stripe extraction),
``stripecal.calib`` (calibration and its stages), ``stripecal.reconstruction`` (point
clouds, sphere and plane fits), ``stripecal.sim`` (the digital twin) and
``stripecal.errors``. ``stripecal.types`` declares the dicts the library returns as
TypedDicts. The pure-Python modules are typed inline (``py.typed``); only the extension
has a stub (``_core.pyi``).
"""

from stripecal._core import __version__ as __version__
from stripecal.errors import (
    BadImageError,
    CalibrationQualityError,
    ConvergenceError,
    DegenerateError,
    DetectionError,
    FormatError,
    InvalidInputError,
    StripecalError,
)
from stripecal.model import (
    CAMERA_PARAM_NAMES,
    Board,
    Camera,
    Robot,
    matrix_to_rotvec,
    nearest_rotation,
    rotvec_to_matrix,
)
from stripecal.io import (
    Dataset,
    Profile,
    ProfileDataset,
    Rig,
    Scan,
    Truth,
    load_calibration,
    load_dataset,
    load_image,
    load_profile_dataset,
    load_rig,
    load_scan,
    load_sphere_fit,
    load_truth,
    matrix_to_pose,
    pose_to_matrix,
    record_keys,
    read_ply,
    read_profile,
    read_profiler_calibration,
    save_calibration,
    save_image,
    save_rig,
    save_sphere_fit,
    save_truth,
    write_ply,
    write_profiler_calibration,
)
from stripecal.vision import (
    LineFit,
    Stripe,
    TargetDetection,
    detect_circles,
    detect_circles_full,
    detect_target,
    extract_stripe,
    fit_line,
)
from stripecal.calib import (
    Calibration,
    board_flatness,
    calibrate,
    calibrate_camera,
    fit_laser_plane,
    plan_poses,
    ProfilerCalibration,
    profiler_adjust,
    profiler_start,
    solve_axzb,
    solve_axzb_full,
)

# The area module is ``reconstruction``: ``stripecal.reconstruct`` is the function.
from stripecal.reconstruction import (
    Cloud,
    PlaneFit,
    SphereFit,
    fit_plane,
    fit_sphere,
    measure_ball_bar,
    measure_plane,
    measure_sphere,
    reconstruct,
    reconstruct_scan,
    triangulate,
    verify,
)
from stripecal import calib, errors, io, model, reconstruction, sim, types, vision

__all__ = [
    "BadImageError",
    "CAMERA_PARAM_NAMES",
    "Board",
    "Calibration",
    "Camera",
    "Cloud",
    "CalibrationQualityError",
    "ConvergenceError",
    "Dataset",
    "DegenerateError",
    "DetectionError",
    "FormatError",
    "InvalidInputError",
    "LineFit",
    "PlaneFit",
    "Rig",
    "Robot",
    "Scan",
    "SphereFit",
    "Stripe",
    "StripecalError",
    "TargetDetection",
    "Truth",
    "__version__",
    "board_flatness",
    "calibrate",
    "calibrate_camera",
    "detect_circles",
    "detect_circles_full",
    "detect_target",
    "extract_stripe",
    "fit_laser_plane",
    "fit_line",
    "fit_plane",
    "fit_sphere",
    "load_calibration",
    "load_dataset",
    "load_image",
    "load_profile_dataset",
    "load_rig",
    "load_scan",
    "load_sphere_fit",
    "load_truth",
    "matrix_to_pose",
    "matrix_to_rotvec",
    "measure_ball_bar",
    "measure_plane",
    "measure_sphere",
    "nearest_rotation",
    "plan_poses",
    "Profile",
    "ProfileDataset",
    "ProfilerCalibration",
    "profiler_adjust",
    "profiler_start",
    "pose_to_matrix",
    "read_ply",
    "read_profile",
    "read_profiler_calibration",
    "reconstruct",
    "reconstruct_scan",
    "record_keys",
    "rotvec_to_matrix",
    "save_calibration",
    "save_image",
    "save_rig",
    "save_sphere_fit",
    "save_truth",
    "sim",
    "solve_axzb",
    "solve_axzb_full",
    "triangulate",
    "verify",
    "write_ply",
    "write_profiler_calibration",
]
