"""The models every stage shares: the camera, the robot, the calibration target and
rotations.

- :class:`Camera`: pinhole camera with a distortion model (``radial1``, ``radial2``,
  ``opencv5``); ``CAMERA_PARAM_NAMES`` names its parameter vector.
- :class:`Robot`: a serial arm as a DH table (forward and inverse kinematics).
- :class:`Board`: the calibration target (circle grid, asymmetric circle grid,
  chessboard): its geometry and symmetries.
- ``rotvec_to_matrix``, ``matrix_to_rotvec``, ``nearest_rotation``: rotation helpers.

Conventions (frames, units, pixel centres, camera model, DH): docs/conventions.md. In
short: lengths in mm, angles in degrees (rotation vectors in radians), ``T_a_b`` maps
frame b to frame a, the top-left pixel's centre is (0, 0).
"""

from stripecal._core import Board as Board
from stripecal._core import Camera as Camera
from stripecal._core import CAMERA_PARAM_NAMES as CAMERA_PARAM_NAMES
from stripecal._core import matrix_to_rotvec as matrix_to_rotvec
from stripecal._core import nearest_rotation as nearest_rotation
from stripecal._core import Robot as Robot
from stripecal._core import rotvec_to_matrix as rotvec_to_matrix

__all__ = [
    "Board",
    "Camera",
    "CAMERA_PARAM_NAMES",
    "matrix_to_rotvec",
    "nearest_rotation",
    "Robot",
    "rotvec_to_matrix",
]
