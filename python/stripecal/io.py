"""Files: the dataset, scan, calibration, truth and sphere-fit records and their
readers and writers, images and PLY point clouds.

- Records: :class:`Rig` (rig.json), :class:`Dataset` (a calibration folder: rig.json,
  views.csv, images), :class:`Scan` (a scan folder: scan.csv, images), :class:`Truth`
  (truth.json written by simulators).
- ``load_*`` / ``save_*`` for rig.json, datasets, scans, calibration.json, truth.json and
  sphere-fit JSON (the ``Calibration`` and ``SphereFit`` records live with what makes
  them: :mod:`stripecal.calib`, :mod:`stripecal.reconstruction`).
- A calibrated line profiler's files: :class:`Profile` (``read_profile``: one profile
  file's points and gaps), :class:`ProfileDataset` (``load_profile_dataset``: a
  profiler's rig.json and views.csv with a ``profile`` column),
  ``read_profiler_calibration`` / ``write_profiler_calibration`` (its calibration.json;
  the record :class:`ProfilerCalibration` lives in :mod:`stripecal.calib`).
- ``load_image`` / ``save_image`` (PNG or TIFF, 8 or 16 bit gray), ``read_ply`` /
  ``write_ply``.
- ``pose_to_matrix`` / ``matrix_to_pose``: a robot controller's flange pose (the pose
  columns views.csv and scan.csv may carry: ROS's ``x_m,y_m,z_m,qx,qy,qz,qw``, Universal
  Robots' rotation vector, KUKA's A, B, C, Fanuc's W, P, R, a quaternion, a matrix) to
  and from a 4x4 ``T_base_hand`` in mm.

Writers are atomic (a temporary file, then a rename). File formats and conventions:
docs/conventions.md; typed records of the dicts returned here: :mod:`stripecal.types`.
"""

from stripecal._core import Dataset as Dataset
from stripecal._core import load_calibration as load_calibration
from stripecal._core import load_dataset as load_dataset
from stripecal._core import load_image as load_image
from stripecal._core import load_profile_dataset as load_profile_dataset
from stripecal._core import load_rig as load_rig
from stripecal._core import load_scan as load_scan
from stripecal._core import load_sphere_fit as load_sphere_fit
from stripecal._core import load_truth as load_truth
from stripecal._core import matrix_to_pose as matrix_to_pose
from stripecal._core import pose_to_matrix as pose_to_matrix
from stripecal._core import Profile as Profile
from stripecal._core import ProfileDataset as ProfileDataset
from stripecal._core import read_ply as read_ply
from stripecal._core import read_profile as read_profile
from stripecal._core import read_profiler_calibration as read_profiler_calibration
from stripecal._core import record_keys as record_keys
from stripecal._core import Rig as Rig
from stripecal._core import save_calibration as save_calibration
from stripecal._core import save_image as save_image
from stripecal._core import save_rig as save_rig
from stripecal._core import save_sphere_fit as save_sphere_fit
from stripecal._core import save_truth as save_truth
from stripecal._core import Scan as Scan
from stripecal._core import Truth as Truth
from stripecal._core import write_ply as write_ply
from stripecal._core import write_profiler_calibration as write_profiler_calibration

__all__ = [
    "Dataset",
    "load_calibration",
    "load_dataset",
    "load_image",
    "load_profile_dataset",
    "load_rig",
    "load_scan",
    "load_sphere_fit",
    "load_truth",
    "matrix_to_pose",
    "pose_to_matrix",
    "Profile",
    "ProfileDataset",
    "read_ply",
    "read_profile",
    "read_profiler_calibration",
    "record_keys",
    "Rig",
    "save_calibration",
    "save_image",
    "save_rig",
    "save_sphere_fit",
    "save_truth",
    "Scan",
    "Truth",
    "write_ply",
    "write_profiler_calibration",
]
