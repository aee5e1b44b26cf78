"""Calibration: the camera, the laser plane, hand-eye ``X = T_hand_cam`` and
robot-world ``Z = T_base_board``.

- ``calibrate`` (a dataset folder -> :class:`Calibration`, one-stage adjustment or the
  paper's stages), with one-sigma uncertainties and per-view figures (typed in
  :mod:`stripecal.types`: ``CalibrationQuality``, ``CalibrationUncertainty``,
  ``CalibrationView``, ``CalibrationExtra``).
- ``plan_poses`` (robot joint vectors + a nominal calibration -> the one-sigma each
  parameter and a measured point would have, before any image is taken; a
  :class:`~stripecal.types.PosePlan`).
- ``board_flatness`` (one view's detections and pose -> the sag of the best-fitting
  cylinder with its sigma, a :class:`~stripecal.types.Flatness`; docs/flatness.md).
- :class:`ProfilerCalibration`: a calibrated line profiler's result (``T_hand_sensor``,
  the reference sphere, the robot; calibration.json with ``"sensor": {"kind":
  "profiler"}``, read and written by ``stripecal.io``); ``profiler_start`` (a profile
  dataset -> the closed-form start and the arcs' points its adjustment starts from, to
  start another solver from the same place); ``profiler_adjust`` (such a start -> the
  one-stage adjustment alone, without the calibration's checks).
- The stages on their own: ``calibrate_camera``, ``fit_laser_plane``, ``solve_axzb`` /
  ``solve_axzb_full`` (``A_i X = Z B_i``).

Conventions (frames, units, laser plane ``n . p = d`` in the camera frame):
docs/conventions.md.
"""

from stripecal._core import calibrate as calibrate
from stripecal._core import calibrate_camera as calibrate_camera
from stripecal._core import Calibration as Calibration
from stripecal._core import board_flatness as board_flatness
from stripecal._core import fit_laser_plane as fit_laser_plane
from stripecal._core import plan_poses as plan_poses
from stripecal._core import ProfilerCalibration as ProfilerCalibration
from stripecal._core import profiler_adjust as profiler_adjust
from stripecal._core import profiler_start as profiler_start
from stripecal._core import solve_axzb as solve_axzb
from stripecal._core import solve_axzb_full as solve_axzb_full

__all__ = [
    "board_flatness",
    "calibrate",
    "calibrate_camera",
    "Calibration",
    "fit_laser_plane",
    "plan_poses",
    "ProfilerCalibration",
    "profiler_adjust",
    "profiler_start",
    "solve_axzb",
    "solve_axzb_full",
]
