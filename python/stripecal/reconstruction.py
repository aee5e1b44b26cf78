"""Reconstruction and measurement: stripe images + joint readings + a calibration ->
3D points in the robot base frame, and shapes fitted to them.

- ``reconstruct`` (images in memory), ``reconstruct_scan`` (a scan folder) ->
  :class:`Cloud`; ``triangulate`` (pixels -> points).
- ``fit_sphere`` -> :class:`SphereFit` (e.g. a reference ball, with one-sigmas),
  ``fit_plane`` -> :class:`PlaneFit`.
- ``measure_sphere``, ``measure_ball_bar``, ``measure_plane``: a scan's shapes with GUM
  budgets (random, calibration, robot, systematic; expanded k = 2), the sphere corrected
  for the curved-surface stripe bias; ``verify``: the VDI/VDE 2634-2 style acceptance
  test against artefacts.json (docs/measurement.md).

Named ``reconstruction`` (not ``reconstruct``) because ``stripecal.reconstruct`` is, and
stays, the function. Lengths in mm, base frame (docs/conventions.md).
"""

from stripecal._core import Cloud as Cloud
from stripecal._core import fit_plane as fit_plane
from stripecal._core import fit_sphere as fit_sphere
from stripecal._core import measure_ball_bar as measure_ball_bar
from stripecal._core import measure_plane as measure_plane
from stripecal._core import measure_sphere as measure_sphere
from stripecal._core import PlaneFit as PlaneFit
from stripecal._core import reconstruct as reconstruct
from stripecal._core import reconstruct_scan as reconstruct_scan
from stripecal._core import SphereFit as SphereFit
from stripecal._core import triangulate as triangulate
from stripecal._core import verify as verify

__all__ = [
    "Cloud",
    "fit_plane",
    "fit_sphere",
    "measure_ball_bar",
    "measure_plane",
    "measure_sphere",
    "PlaneFit",
    "reconstruct",
    "reconstruct_scan",
    "SphereFit",
    "triangulate",
    "verify",
]
