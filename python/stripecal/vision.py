"""Image measurements: the calibration target's points and the laser stripe.

- ``detect_target`` (any target kind, gray or RGB images) -> :class:`TargetDetection`;
  ``detect_circles`` / ``detect_circles_full`` (circle grids, with diagnostics).
- ``extract_stripe`` -> :class:`Stripe` (sub-pixel stripe points with quality flags);
  ``fit_line`` -> :class:`LineFit` (robust 2D line through stripe points).

Images are 2D uint8/uint16 numpy arrays (rows, cols); pixel coordinates ``(u, v)`` with
the top-left pixel's centre at (0, 0) (docs/conventions.md). The target itself is
:class:`stripecal.model.Board`.
"""

from stripecal._core import detect_circles as detect_circles
from stripecal._core import detect_circles_full as detect_circles_full
from stripecal._core import detect_target as detect_target
from stripecal._core import extract_stripe as extract_stripe
from stripecal._core import fit_line as fit_line
from stripecal._core import LineFit as LineFit
from stripecal._core import Stripe as Stripe
from stripecal._core import TargetDetection as TargetDetection

__all__ = [
    "detect_circles",
    "detect_circles_full",
    "detect_target",
    "extract_stripe",
    "fit_line",
    "LineFit",
    "Stripe",
    "TargetDetection",
]
